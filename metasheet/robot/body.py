"""An elastic body meshed with tetrahedra: corotational anisotropic FEM (issue 6, eq. 1).

Linear tetrahedra (4 nodes, one rotation per element: :mod:`metasheet.fem.corotational.p1`) or
quadratic ones (10 nodes, one rotation per quadrature point: :mod:`metasheet.fem.corotational.p2`),
told apart by the connectivity's width. The cached CSR scatter is in
:mod:`metasheet.fem.assembly`; the static solve with fixed nodes in :mod:`.dirichlet`.
Sign convention: :meth:`ElasticBody.forces` returns the *internal* (restoring) force
``f(x)``, zero at rest, so equilibrium under external nodal loads ``l`` reads ``f(x) = l``
and ``K = df/dx`` is positive definite at rest (once rigid motions are fixed).
"""

from __future__ import annotations

import numpy as np

from ..conventions import GRAVITY, TPU_DENSITY
from ..errors import ConfigError, MeshError, check_range
from ..mechanics.material import Isotropic, TransverseIsotropic
from ..mechanics.voigt import stiffness_along
from ..fem import tet10
from ..fem.assembly import SparsityPattern
from ..fem.corotational import p1, p2


def _as_points(points) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 4:
        raise ConfigError(f"points: shape is {p.shape} and should be (n, 3) with n >= 4")
    if not np.all(np.isfinite(p)):
        raise ConfigError("points: contains non-finite values")
    return p


def _as_tets(tets, n: int) -> np.ndarray:
    t = np.asarray(tets)
    if t.ndim != 2 or t.shape[1] not in (4, 10) or len(t) == 0:
        raise ConfigError(f"tets: shape is {t.shape} and should be (m, 4) or (m, 10) with m >= 1")
    if not np.issubdtype(t.dtype, np.integer):
        raise ConfigError(f"tets: dtype is {t.dtype} and should be an integer type")
    if t.min() < 0 or t.max() >= n:
        raise ConfigError(f"tets: node indices span [{t.min()}, {t.max()}], allowed [0, {n - 1}]")
    return np.ascontiguousarray(t, dtype=np.int64)


def _as_stiffness(stiffness, m: int) -> np.ndarray:
    C = np.asarray(stiffness, dtype=float)
    if C.shape == (6, 6):
        C = np.broadcast_to(C, (m, 6, 6))
    if C.shape != (m, 6, 6):
        raise ConfigError(f"stiffness: shape is {C.shape} and should be (6, 6) or (m, 6, 6) with m = {m}")
    if not np.all(np.isfinite(C)):
        raise ConfigError("stiffness: contains non-finite values")
    asym = np.abs(C - np.transpose(C, (0, 2, 1))).max() / max(np.abs(C).max(), 1e-300)
    if asym > 1e-8:
        raise ConfigError(f"stiffness: relative asymmetry {asym:.3g}, allowed <= 1e-08")
    lo = np.linalg.eigvalsh(0.5 * (C + np.transpose(C, (0, 2, 1)))).min(axis=1)
    bad = np.flatnonzero(lo <= 0)
    if len(bad):
        raise ConfigError(
            f"stiffness[{bad[0]}]: smallest eigenvalue {lo[bad[0]]:.4g} MPa, allowed > 0 (positive definite)"
        )
    return C


class ElasticBody:
    """Corotational tetrahedral FEM body with per-element anisotropic stiffness.

    Parameters
    ----------
    points : (n, 3) float [mm] rest positions.
    tets : (m, 4) int node indices (linear, either orientation), or (m, 10) quadratic
        (straight-edged: the 4 vertices, then the midpoints of edges 01, 02, 03, 12, 13, 23,
        :mod:`metasheet.fem.tet10`).
    stiffness : (m, 6, 6) or (6, 6) float [MPa], Voigt stiffness in GLOBAL axes (11, 22, 33,
        23, 13, 12, engineering shear); see :func:`metasheet.mechanics.voigt.stiffness_along`.
    density : float [t/mm^3] for the lumped mass (TPU: 1.19e-9).
    backend : "numba" (fused compiled kernel, default) or "numpy" (batched reference).

    Attributes
    ----------
    n_nodes, n_elements : int
    element : "p1" or "p2".
    rest : (n, 3) [mm]; volumes : (m,) [mm^3]
    mass : (n,) nodal masses [t] for body loads: the work-equivalent integral of each shape
        function times the density (P1: a quarter of each element's mass per node; P2: -1/20
        at the vertices and 1/5 at the midside nodes, so vertex entries can be negative). Sums
        to the body's mass; gravity is ``mass * g`` and exact for a uniform field.
    quad_grads : (m, nq, nen, 3) [1/mm] shape-function gradients at the quadrature points;
        quad_weights : (m, nq) [mm^3] (P1: one point, the element volume).
    stiffness_scale : [N/mm] size of an element stiffness entry (round-off floors).
    pattern : :class:`~metasheet.fem.assembly.SparsityPattern` shared by every tangent.
    used : (n,) bool, nodes some element uses (the others have no stiffness).
    """

    def __init__(self, points, tets, stiffness, *, density: float = TPU_DENSITY, backend: str = "numba"):
        self.rest = _as_points(points)
        self.rest.flags.writeable = False
        self.tets = _as_tets(tets, len(self.rest))
        self.n_nodes = len(self.rest)
        self.n_elements = len(self.tets)
        check_range("density", density, 0.0, None, lo_open=True)
        if backend not in ("numba", "numpy"):
            raise ConfigError(f"backend: {backend!r}: allowed 'numba' or 'numpy'")
        self.backend = backend if p1.HAVE_NUMBA else "numpy"
        self.stiffness = _as_stiffness(stiffness, self.n_elements)
        nen = self.tets.shape[1]
        self.element = "p1" if nen == 4 else "p2"
        X = self.rest[self.tets[:, :4]]
        vol = np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / 6.0
        size = np.ptp(self.rest, axis=0).max()
        flat = np.flatnonzero(vol <= 1e-12 * size**3)
        if len(flat):
            raise MeshError(
                f"tets[{flat[0]}]: degenerate element (volume {vol[flat[0]]:.3g} mm^3); {len(flat)} such elements"
            )
        if self.element == "p1":
            self.grads, self.volumes, _ = p1.shape_gradients(self.rest, self.tets)
            self.Ke = p1.element_stiffness(self.grads, self.volumes, self.stiffness)
            self.X_e = np.ascontiguousarray(self.rest[self.tets])
            self.quad_grads, self.quad_weights = self.grads[:, None], self.volumes[:, None]
            self.stiffness_scale = float(np.abs(self.Ke).max())
        else:
            self.quad_grads, self.quad_weights = tet10.tet10_quadrature(self.rest, self.tets)
            self.volumes = self.quad_weights.sum(axis=1)
            # largest |K_ab,ij| bound: sum_q w |C| |g_a| |g_b| (the P1 scale is the exact max)
            g2 = np.einsum("mqai,mqai->mqa", self.quad_grads, self.quad_grads).max(axis=2)
            self.stiffness_scale = float((np.abs(self.stiffness).max(axis=(1, 2))
                                          * np.einsum("mq,mq->m", self.quad_weights, g2)).max())
        # round-off of f(x) near the rest shape [N]: no residual below it can be told from zero,
        # whichever BLAS or summation order computed it
        self.force_floor = 10 * np.finfo(float).eps * self.stiffness_scale \
            * float(np.abs(self.rest).max()) * np.sqrt(3 * self.n_nodes)
        self.pattern = SparsityPattern.from_elements(self.tets, self.n_nodes)
        if self.element == "p1":  # a quarter of each element's mass per node
            m_e = np.repeat(density * self.volumes / 4.0, 4)
        else:
            m_e = (density * tet10.nodal_volume_weights(self.volumes, nen)).ravel()
        self.mass = np.bincount(self.tets.ravel(), weights=m_e, minlength=self.n_nodes)
        self.density = float(density)
        self.used = np.bincount(self.tets.ravel(), minlength=self.n_nodes) > 0

    @classmethod
    def from_material(cls, points, tets, material, fibers=None, *, density: float = TPU_DENSITY, **kw):
        """Body of one material, or one per element, with transverse-isotropic axes along ``fibers``.

        material : Isotropic | TransverseIsotropic, or a sequence of m of them.
        fibers : (m, 3) float, element longitudinal axes (need not be unit); required as soon
            as one material is transverse-isotropic, ignored for isotropic ones.
        """
        tets_arr = np.asarray(tets)
        m = len(tets_arr)
        mats = [material] * m if isinstance(material, (Isotropic, TransverseIsotropic)) else list(material)
        if len(mats) != m:
            raise ConfigError(f"material: {len(mats)} materials given, expected 1 or m = {m}")
        for i, mat in enumerate(mats):
            if not isinstance(mat, (Isotropic, TransverseIsotropic)):
                raise ConfigError(f"material[{i}]: {type(mat).__name__}: expected Isotropic or TransverseIsotropic")
        anisotropic = any(isinstance(mat, TransverseIsotropic) for mat in mats)
        if anisotropic:
            if fibers is None:
                raise ConfigError("fibers: None: required (shape (m, 3)) for a TransverseIsotropic material")
            fibers = np.asarray(fibers, dtype=float)
            if fibers.shape != (m, 3):
                raise ConfigError(f"fibers: shape is {fibers.shape} and should be (m, 3) with m = {m}")
        C = np.empty((m, 6, 6))
        groups: dict = {}
        for i, mat in enumerate(mats):
            groups.setdefault(mat, []).append(i)
        for mat, idx in groups.items():
            idx = np.asarray(idx)
            if isinstance(mat, Isotropic):
                C[idx] = mat.stiffness()
            else:
                C[idx] = stiffness_along(mat.stiffness(), fibers[idx])
        return cls(points, tets, C, density=density, **kw)

    # ------------------------------------------------------------------ evaluation

    def check_positions(self, x) -> np.ndarray:
        """Positions ``x`` (n, 3) or (3n,) [mm] as a finite, C-contiguous (n, 3) array (else ConfigError)."""
        x = np.asarray(x, dtype=float)
        if x.shape == (3 * self.n_nodes,):
            x = x.reshape(self.n_nodes, 3)
        if x.shape != (self.n_nodes, 3):
            raise ConfigError(f"x: shape is {x.shape} and should be ({self.n_nodes}, 3)")
        if not np.all(np.isfinite(x)):
            raise ConfigError("x: contains non-finite values")
        return np.ascontiguousarray(x)

    def evaluate(self, x: np.ndarray, tangent: bool):
        """Unchecked hot path: forces (3n,) [N] and, if ``tangent``, the tangent's CSR data (nnz,)
        [N/mm] on :attr:`pattern` (else None) at ``x`` (n, 3) C-contiguous float [mm]."""
        if self.backend == "numba":
            f = np.empty(3 * self.n_nodes)
            data = np.empty(self.pattern.nnz if tangent else 0)
            if self.element == "p1":
                p1.corotational_numba(
                    x, self.tets, self.X_e, self.grads, self.Ke, self.pattern.block_map, f, data, tangent)
            else:
                p2.corotational_quadrature_numba(
                    x, self.tets, self.quad_grads, self.quad_weights, self.stiffness, self.pattern.block_map,
                    f, data, tangent)
            return f, (data if tangent else None)
        if self.element == "p1":
            fe, Kt = p1.corotational_numpy(x[self.tets], self.X_e, self.grads, self.Ke, tangent=tangent)
        else:
            fe, Kt = p2.corotational_quadrature_numpy(
                x[self.tets], self.quad_grads, self.quad_weights, self.stiffness, tangent=tangent)
        f = self.pattern.assemble_vector(fe)
        return f, (self.pattern.assemble_data(Kt) if tangent else None)

    def forces(self, x) -> np.ndarray:
        """(n, 3) internal forces [N] at positions ``x`` (n, 3) [mm]; zero at rest and under rigid motions."""
        f, _ = self.evaluate(self.check_positions(x), tangent=False)
        return f.reshape(self.n_nodes, 3)

    def forces_and_tangent(self, x, *, symmetric: bool = False):
        """Internal forces and their consistent tangent at ``x`` (n, 3) [mm].

        Returns
        -------
        f : (3n,) [N], node-major (x0, y0, z0, x1, ...).
        K : (3n, 3n) CSR [N/mm], ``K = df/dx`` including the derivative of the element
            rotations. Same ``indptr``/``indices`` on every call. Exactly symmetric for
            isotropic materials; for anisotropic ones it is non-symmetric away from rest
            (the polar-corotated force is not an energy gradient then). ``symmetric=True``
            returns ``(K + K^T) / 2`` instead (same pattern), e.g. for a Cholesky solver.
        """
        f, data = self.evaluate(self.check_positions(x), tangent=True)
        if symmetric:
            data = 0.5 * (data + data[self.pattern.transpose_map])
        return f, self.pattern.matrix(data)

    def gravity(self, g=(0.0, 0.0, -GRAVITY)) -> np.ndarray:
        """(n, 3) lumped nodal gravity forces [N] = mass [t] * g [mm/s^2]."""
        g = np.asarray(g, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"g: {g!r}: should be a finite 3-vector [mm/s^2]")
        return self.mass[:, None] * g[None, :]

    def deformation_gradients(self, x) -> np.ndarray:
        """(m, nq, 3, 3) deformation gradients at the quadrature points for positions ``x`` (n, 3) [mm]."""
        return p2.deformation_gradients(self.check_positions(x), self.tets, self.quad_grads)

    def max_principal_strain(self, x, elements: np.ndarray | None = None) -> np.ndarray:
        """(m,) largest principal Green-Lagrange strain [-] over each element's quadrature points;
        only those of ``elements`` ((m,) bool, None: all) when given, the same values as the
        full array's entries (each element's on its own), at a fraction of the cost."""
        if elements is None:
            return p2.max_principal_green_strain(self.check_positions(x), self.tets, self.quad_grads)
        key = np.asarray(elements, bool).tobytes()
        if getattr(self, "_strain_subset", (None,))[0] != key:  # the last mask's elements, kept
            e = np.asarray(elements, bool)
            self._strain_subset = (key, np.ascontiguousarray(self.tets[e]), np.ascontiguousarray(self.quad_grads[e]))
        _, tets, grads = self._strain_subset
        return p2.max_principal_green_strain(self.check_positions(x), tets, grads)

    def stresses(self, x) -> np.ndarray:
        """(m, 6) element stresses [MPa], Voigt in global axes: ``R C (S - I) R^T`` (corotated).

        ``x`` (n, 3) [mm]. Linear tetrahedra: constant per element; quadratic: the
        volume average over the element's quadrature points. Batched numpy (SVD), not meant
        for the hot loop.
        """
        Fq = self.deformation_gradients(x)
        m, nq = Fq.shape[:2]
        R, S = p1.polar_numpy(Fq.reshape(-1, 3, 3))
        E = S - np.eye(3)
        eps = np.stack([E[:, 0, 0], E[:, 1, 1], E[:, 2, 2], 2 * E[:, 1, 2], 2 * E[:, 0, 2], 2 * E[:, 0, 1]], 1)
        s = np.einsum("mij,mj->mi", np.repeat(self.stiffness, nq, axis=0), eps)
        sig = np.empty((len(s), 3, 3))
        for I, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))):
            sig[:, i, j] = sig[:, j, i] = s[:, I]
        g = R @ sig @ np.transpose(R, (0, 2, 1))
        v = np.stack([g[:, 0, 0], g[:, 1, 1], g[:, 2, 2], g[:, 1, 2], g[:, 0, 2], g[:, 0, 1]], 1).reshape(m, nq, 6)
        if nq == 1:
            return v[:, 0]
        return np.einsum("mqk,mq->mk", v, self.quad_weights) / self.volumes[:, None]

