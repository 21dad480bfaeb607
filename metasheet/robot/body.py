"""An elastic body meshed with linear tetrahedra: corotational anisotropic FEM (issue 6, eq. 1).

Physics in :mod:`metasheet.robot.kernels`; the cached CSR scatter in :mod:`.assembly`.
Sign convention: :meth:`ElasticBody.forces` returns the *internal* (restoring) force
``f(x)``, zero at rest, so equilibrium under external nodal loads ``l`` reads ``f(x) = l``
and ``K = df/dx`` is positive definite at rest (once rigid motions are fixed).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla

from ..conventions import GRAVITY, TPU_DENSITY
from ..errors import ConfigError, ConvergenceError, MeshError, check_range
from ..material import Isotropic, TransverseIsotropic, stiffness_along
from . import kernels
from .assembly import SparsityPattern, submatrix_map


@dataclass(frozen=True)
class StaticResult:
    """Result of :meth:`ElasticBody.solve_static`.

    x : (n, 3) equilibrium positions [mm]; iterations : Newton iterations done;
    residuals : relative residual norm before each iteration and at the end [-];
    time : wall time of the solve [s].
    """

    x: np.ndarray
    iterations: int
    residuals: tuple[float, ...]
    time: float


def _as_points(points) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 4:
        raise ConfigError(f"points: shape is {p.shape} and should be (n, 3) with n >= 4")
    if not np.all(np.isfinite(p)):
        raise ConfigError("points: contains non-finite values")
    return p


def _as_tets(tets, n: int) -> np.ndarray:
    t = np.asarray(tets)
    if t.ndim != 2 or t.shape[1] != 4 or len(t) == 0:
        raise ConfigError(f"tets: shape is {t.shape} and should be (m, 4) with m >= 1")
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
    """Corotational linear-tetrahedron FEM body with per-element anisotropic stiffness.

    Parameters
    ----------
    points : (n, 3) float [mm] rest positions.
    tets : (m, 4) int node indices (either orientation).
    stiffness : (m, 6, 6) or (6, 6) float [MPa], Voigt stiffness in GLOBAL axes (11, 22, 33,
        23, 13, 12, engineering shear); see :func:`metasheet.material.stiffness_along`.
    density : float [t/mm^3] for the lumped mass (TPU: 1.19e-9).
    backend : "numba" (fused compiled kernel, default) or "numpy" (batched reference).

    Attributes
    ----------
    n_nodes, n_elements : int
    rest : (n, 3) [mm]; volumes : (m,) [mm^3]; mass : (n,) lumped nodal mass [t]
    pattern : :class:`SparsityPattern` shared by every tangent.

    Nodes no element uses have no stiffness; :meth:`solve_static` keeps them where they are.
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
        self.backend = backend if kernels.HAVE_NUMBA else "numpy"
        self.stiffness = _as_stiffness(stiffness, self.n_elements)
        X = self.rest[self.tets]
        vol = np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / 6.0
        size = np.ptp(self.rest, axis=0).max()
        flat = np.flatnonzero(vol <= 1e-12 * size**3)
        if len(flat):
            raise MeshError(
                f"tets[{flat[0]}]: degenerate element (volume {vol[flat[0]]:.3g} mm^3); {len(flat)} such elements"
            )
        self.grads, self.volumes, _ = kernels.shape_gradients(self.rest, self.tets)
        self.Ke = kernels.element_stiffness(self.grads, self.volumes, self.stiffness)
        self.X_e = np.ascontiguousarray(self.rest[self.tets])
        self.pattern = SparsityPattern.from_tets(self.tets, self.n_nodes)
        m_e = density * self.volumes / 4.0  # lumped: a quarter of each element's mass per node
        self.mass = np.bincount(self.tets.ravel(), weights=np.repeat(m_e, 4), minlength=self.n_nodes)
        self.density = float(density)
        self._used = np.bincount(self.tets.ravel(), minlength=self.n_nodes) > 0

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

    def _check_x(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape == (3 * self.n_nodes,):
            x = x.reshape(self.n_nodes, 3)
        if x.shape != (self.n_nodes, 3):
            raise ConfigError(f"x: shape is {x.shape} and should be ({self.n_nodes}, 3)")
        if not np.all(np.isfinite(x)):
            raise ConfigError("x: contains non-finite values")
        return np.ascontiguousarray(x)

    def _evaluate(self, x: np.ndarray, tangent: bool):
        if self.backend == "numba":
            f = np.empty(3 * self.n_nodes)
            data = np.empty(self.pattern.nnz if tangent else 0)
            kernels.corotational_numba(
                x, self.tets, self.X_e, self.grads, self.Ke, self.pattern.block_map, f, data, tangent
            )
            return f, (data if tangent else None)
        fe, Kt = kernels.corotational_numpy(x[self.tets], self.X_e, self.grads, self.Ke, tangent=tangent)
        f = self.pattern.assemble_vector(fe)
        return f, (self.pattern.assemble_data(Kt) if tangent else None)

    def forces(self, x) -> np.ndarray:
        """(n, 3) internal forces [N] at positions ``x`` (n, 3) [mm]; zero at rest and under rigid motions."""
        f, _ = self._evaluate(self._check_x(x), tangent=False)
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
        f, data = self._evaluate(self._check_x(x), tangent=True)
        if symmetric:
            data = 0.5 * (data + data[self._transpose_map()])
        return f, self.pattern.matrix(data)

    def _transpose_map(self) -> np.ndarray:
        """(nnz,) int: ``data[map]`` is the data of ``K^T`` on the (structurally symmetric) pattern."""
        if not hasattr(self, "_tmap"):
            marker = self.pattern.matrix(np.arange(1, self.pattern.nnz + 1, dtype=float)).T.tocsr()
            marker.sort_indices()
            self._tmap = marker.data.astype(np.int64) - 1
        return self._tmap

    def gravity(self, g=(0.0, 0.0, -GRAVITY)) -> np.ndarray:
        """(n, 3) lumped nodal gravity forces [N] = mass [t] * g [mm/s^2]."""
        g = np.asarray(g, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"g: {g!r}: should be a finite 3-vector [mm/s^2]")
        return self.mass[:, None] * g[None, :]

    # ------------------------------------------------------------------ static solve (eq. 1)

    def solve_static(
        self, fixed, *, x_fixed=None, loads=None, tol: float = 1e-8, max_iter: int = 50, x0=None
    ) -> StaticResult:
        """Static equilibrium ``f(x) = loads`` on the free nodes, Newton with a backtracking line search.

        Parameters
        ----------
        fixed : (k,) int node indices held at ``x_fixed``.
        x_fixed : (k, 3) float [mm], default their rest positions.
        loads : (n, 3) float [N] external nodal forces (add :meth:`gravity` for weight).
        tol : relative tolerance on the free residual norm, relative to the largest of the
            external load, the first residual and the fixed nodes' reactions.
        max_iter : Newton iterations allowed (the prescribed-motion predictor is not counted).
        x0 : (n, 3) float [mm] start (default rest), e.g. a previous solution to warm-start.

        The first step moves the fixed nodes to ``x_fixed`` and the free ones by the
        linearised response (tangent at ``x0``). Raises :class:`ConvergenceError` with the
        residual history if ``max_iter`` is reached or the line search stalls.
        """
        t0 = time.perf_counter()
        n = self.n_nodes
        fixed = np.asarray(fixed)
        if fixed.ndim != 1 or not np.issubdtype(fixed.dtype, np.integer):
            raise ConfigError(f"fixed: shape {fixed.shape} dtype {fixed.dtype}: should be (k,) int node indices")
        if len(fixed) and (fixed.min() < 0 or fixed.max() >= n):
            raise ConfigError(f"fixed: indices span [{fixed.min()}, {fixed.max()}], allowed [0, {n - 1}]")
        if len(np.unique(fixed)) != len(fixed):
            raise ConfigError("fixed: contains repeated node indices")
        check_range("tol", tol, 0.0, 1.0, lo_open=True)
        check_range("max_iter", max_iter, 1, None)
        x = self.rest.copy() if x0 is None else self._check_x(x0).copy()
        if x_fixed is None:
            x_fixed = self.rest[fixed]
        x_fixed = np.asarray(x_fixed, dtype=float)
        if x_fixed.shape != (len(fixed), 3) or not np.all(np.isfinite(x_fixed)):
            raise ConfigError(f"x_fixed: shape is {x_fixed.shape} and should be ({len(fixed)}, 3), finite")
        loads = np.zeros((n, 3)) if loads is None else np.asarray(loads, dtype=float)
        if loads.shape != (n, 3) or not np.all(np.isfinite(loads)):
            raise ConfigError(f"loads: shape is {loads.shape} and should be ({n}, 3), finite")

        free_nodes = np.ones(n, bool)
        free_nodes[fixed] = False
        orphans = free_nodes & ~self._used
        if np.any(loads[orphans] != 0):
            raise ConfigError(f"loads: node {np.flatnonzero(orphans & np.any(loads != 0, axis=1))[0]} "
                              "is in no element and cannot carry a load")
        free_nodes &= self._used
        free = (3 * np.flatnonzero(free_nodes)[:, None] + np.arange(3)).ravel()
        cons = (3 * fixed[:, None] + np.arange(3)).ravel()
        l = loads.reshape(-1)
        K_ff, take_ff = submatrix_map(self.pattern, free, free)
        K_fc, take_fc = submatrix_map(self.pattern, free, cons)

        def solve(data, rhs):
            K_ff.data[:] = data[take_ff]
            return spla.splu(K_ff.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(rhs)

        xf = x.reshape(-1)  # a view: updating xf updates x
        dc = (x_fixed - x[fixed]).reshape(-1)
        if len(free) == 0:
            x[fixed] = x_fixed
            return StaticResult(x, 0, (0.0,), time.perf_counter() - t0)
        if np.any(dc != 0):  # predictor: linearised response to the prescribed motion
            f, data = self._evaluate(x, tangent=True)
            K_fc.data[:] = data[take_fc]
            xf[free] += solve(data, -(f[free] - l[free]) - K_fc @ dc)
            x[fixed] = x_fixed

        f, data = self._evaluate(x, tangent=True)
        r = f[free] - l[free]
        # Reference force: loads, first residual and reactions, so tol is scale-free.
        ref = max(np.linalg.norm(l[free]), np.linalg.norm(r), np.linalg.norm(f[cons] - l[cons]))
        # Round-off floor of f: below it no residual can be trusted, whatever tol asks.
        floor = 10 * np.finfo(float).eps * np.abs(self.Ke).max() * np.abs(x).max() * np.sqrt(len(free))
        ref = max(ref, floor)
        hist = [np.linalg.norm(r) / ref]
        it = 0
        while hist[-1] > tol and np.linalg.norm(r) > floor:
            if it >= max_iter:
                raise ConvergenceError(
                    f"static solve: residual {hist[-1]:.3g} > tol {tol:g} after max_iter={max_iter} iterations",
                    hist,
                )
            it += 1
            dx = solve(data, -r)
            x_old = xf[free].copy()
            alpha = self._line_search(x, xf, free, l, x_old, dx, r)
            if alpha is None:
                xf[free] = x_old
                raise ConvergenceError(
                    f"static solve: line search failed at iteration {it} (residual {hist[-1]:.3g})", hist
                )
            f, data = self._evaluate(x, tangent=True)
            r = f[free] - l[free]
            hist.append(np.linalg.norm(r) / ref)
        return StaticResult(x, it, tuple(float(h) for h in hist), time.perf_counter() - t0)

    def _line_search(self, x, xf, free, l, x_old, dx, r):
        """Step length along ``dx`` (sets ``x``); None if no acceptable step.

        Not on the residual norm: along a slender body's Newton step the norm can grow
        a hundredfold while the step is right (stiff axial terms of the rotations). Instead
        the projected residual ``g(a) = dx . r(x + a dx)``, the energy slope for a
        conservative force, must shrink to 0.8 |g(0)| (Crisfield's criterion), with
        regula falsi steps otherwise and halving on non-finite or inverted states.
        """
        g0 = float(dx @ r)
        if not g0 < 0.0:  # not a descent direction of the energy-like merit: take Newton's step
            xf[free] = x_old + dx
            return 1.0
        lo, g_lo, hi, g_hi, alpha, g = 0.0, g0, None, None, 1.0, np.nan
        for _ in range(12):
            xf[free] = x_old + alpha * dx
            f, _ = self._evaluate(x, tangent=False)
            g = float(dx @ (f[free] - l[free]))
            if not np.isfinite(g):
                hi, g_hi = alpha, None
            elif abs(g) <= 0.8 * abs(g0) or (g < 0.0 and hi is None):
                return alpha  # slope small enough, or still descending at the full step
            elif g < 0.0:
                lo, g_lo = alpha, g
            else:
                hi, g_hi = alpha, g
            if g_hi is None:
                alpha = 0.5 * (lo + hi)
            else:  # regula falsi on the bracket, kept away from its ends
                new = lo - g_lo * (hi - lo) / (g_hi - g_lo)
                alpha = float(np.clip(new, lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo)))
        if np.isfinite(g) and abs(g) < abs(g0):
            return alpha
        return None

    def stresses(self, x) -> np.ndarray:
        """(m, 6) element stresses [MPa], Voigt in global axes: ``R C (S - I) R^T`` (corotated).

        ``x`` (n, 3) [mm]. Constant per element (linear tetrahedra). Batched numpy (SVD), not
        meant for the hot loop.
        """
        x = self._check_x(x)
        F = np.einsum("mai,maj->mij", x[self.tets], self.grads)
        R, S = kernels.polar_numpy(F)
        E = S - np.eye(3)
        eps = np.stack([E[:, 0, 0], E[:, 1, 1], E[:, 2, 2], 2 * E[:, 1, 2], 2 * E[:, 0, 2], 2 * E[:, 0, 1]], 1)
        s = np.einsum("mij,mj->mi", self.stiffness, eps)
        sig = np.empty((len(s), 3, 3))
        for I, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))):
            sig[:, i, j] = sig[:, j, i] = s[:, I]
        g = R @ sig @ np.transpose(R, (0, 2, 1))
        return np.stack([g[:, 0, 0], g[:, 1, 1], g[:, 2, 2], g[:, 1, 2], g[:, 0, 2], g[:, 0, 1]], 1)


def box_mesh(size, divisions, *, jitter: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A box [0, a] x [0, b] x [0, c] split into 6 conforming tets per cell (Kuhn subdivision).

    Parameters
    ----------
    size : (3,) float [mm]; divisions : (3,) int cells per axis.
    jitter : interior nodes move randomly by up to ``jitter`` times the cell size (< 0.3
        keeps every tet valid), giving an irregular mesh with a flat boundary.
    seed : for the jitter.

    Returns points (n, 3) [mm], tets (m, 4) int64 (positively oriented).
    """
    size = np.asarray(size, float)
    nd = np.asarray(divisions, int)
    if size.shape != (3,) or np.any(size <= 0):
        raise ConfigError(f"size: {size.tolist()}: should be three lengths > 0 [mm]")
    if nd.shape != (3,) or np.any(nd < 1):
        raise ConfigError(f"divisions: {nd.tolist()}: should be three integers >= 1")
    check_range("jitter", jitter, 0.0, 0.3)
    axes = [np.linspace(0.0, size[k], nd[k] + 1) for k in range(3)]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange(len(P)).reshape(nd + 1)
    if jitter > 0:
        interior = np.all((P > 1e-12 * size) & (P < size * (1 - 1e-12)), axis=1)
        rng = np.random.default_rng(seed)
        P[interior] += jitter * (size / nd) * rng.uniform(-1, 1, (interior.sum(), 3))
    corner = {}
    for b in range(8):
        i, j, k = (b >> 0) & 1, (b >> 1) & 1, (b >> 2) & 1
        corner[(i, j, k)] = idx[i : i + nd[0], j : j + nd[1], k : k + nd[2]].ravel()
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        path, v = [(0, 0, 0)], [0, 0, 0]
        for ax in perm:
            v[ax] = 1
            path.append(tuple(v))
        t = np.stack([corner[c] for c in path], 1)
        tets.append(t)
    tets = np.concatenate(tets)
    X = P[tets]
    det = np.linalg.det(X[:, 1:] - X[:, :1])
    tets[det < 0] = tets[det < 0][:, [0, 2, 1, 3]]
    return P, tets.astype(np.int64)
