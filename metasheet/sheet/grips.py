"""A sheet condensed onto its four rigid grips: the 24 x 24 stiffness the robot sees (issue 44).

The robot holds each sheet by four rigid bodies: the centre ring (tied to the rod) and the
three arm tip boxes (held by the servo horns). Everything the robot's statics needs from a
sheet at rest is the linear stiffness of the sheet condensed onto these bodies' rigid
coordinates. The same 24 x 24 matrix comes from two places: the homogenised sheet FEM
(:func:`fem_condensed`) and the printed foam's voxel DNS (another module); comparing them is
the point of issue 44, and :mod:`metasheet.robot.condensed` builds the robot from either.

Conventions (shared with the voxel side):

* Frame: the sheet's own (:mod:`.geometry`): mid-plane z = 0, centre at the origin, arm k along
  ``ARM_ANGLES[k]``. The mirrored sheet (tripod B) uses its own mesh's frame; since
  :func:`.geometry.mirror_sheet` swaps the tags of arms 1 and 2, its arm k also lies along
  ``ARM_ANGLES[k]``, so both sheets have the same reference points.
* Bodies (:data:`GRIPS`): 0 the centre ring (attach tag 4), 1 + k the tip box of arm k
  (tag k + 1). Reference points (:func:`grip_references`): the centre (0, 0, 0) and
  ``reach (cos a_k, sin a_k, 0)``, the middle of each arm's flat end.
* Coordinates: per body (t_x, t_y, t_z [mm], theta_x, theta_y, theta_z [rad]), a small rigid
  motion about its reference point r, ``u(x) = t + theta x (x - r)``; bodies in order, 24 in
  all. K is in N/mm, N (= N mm / mm) and N mm (per rad); forces conjugate: (F [N], M [N mm]).

A sheet's K annihilates the six global rigid motions (:func:`global_rigid_modes`): its
energy depends only on the arms' motions relative to the centre, which is why the three arms'
18 x 18 block with the centre held (:func:`relative_stiffness`) carries all of it
(:func:`full_from_relative`), and why two sheets are compared by the generalised eigenvalues
of that block (:func:`eigen_ratios`), which do not depend on units or coordinate scaling.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import ConfigError
from ..fem.assembly import SparsityPattern, submatrix_map
from ..fem.factor import SparseSolver
from ..fem.hex8 import strain_operator
from ..fem.tet10 import tet4_quadrature, tet10_quadrature
from ..mechanics.rotations import skew
from .elements import as_element
from .geometry import ATTACH_CENTRE
from .outline import ARM_ANGLES, SheetParams

#: the four rigid bodies, in coordinate order
GRIPS = ("centre", "arm 0", "arm 1", "arm 2")
#: the attach tag of each body's nodes (:mod:`.geometry`)
GRIP_TAGS = (ATTACH_CENTRE, 1, 2, 3)
N_GRIP_DOF = 6 * len(GRIPS)
#: elements per batch of the element stiffness products (bounds the temporaries)
_CHUNK = 4096


@dataclass(frozen=True, eq=False)
class CondensedSheet:
    """A sheet's stiffness condensed onto its four grips.

    Attributes
    ----------
    K : (24, 24) symmetric stiffness [N/mm, N, N mm] on the grip coordinates (module docstring).
    references : (4, 3) the bodies' reference points [mm], sheet frame.
    n_dof : displacement unknowns of the mesh the matrix was condensed from (3 n_nodes).
    seconds : wall time of the assembly and condensation [s].
    element : "p1" or "p2".
    """

    K: np.ndarray
    references: np.ndarray
    n_dof: int
    seconds: float
    element: str = "p2"


def grip_references(params: SheetParams) -> np.ndarray:
    """(4, 3) reference points [mm] of the bodies in :data:`GRIPS` order, sheet frame."""
    if not isinstance(params, SheetParams):
        raise ConfigError(f"params: {type(params).__name__}: expected SheetParams")
    r = float(params.reach)
    arms = np.stack([r * np.cos(ARM_ANGLES), r * np.sin(ARM_ANGLES), np.zeros(3)], axis=1)
    return np.vstack([np.zeros(3), arms])


def check_references(references, name: str = "references") -> np.ndarray:
    """``references`` as a finite (4, 3) float array, else ConfigError naming ``name``."""
    r = np.asarray(references, float)
    if r.shape != (4, 3) or not np.all(np.isfinite(r)):
        raise ConfigError(f"{name}: shape is {r.shape} and should be a finite (4, 3) [mm] "
                          "(centre, arm 0, arm 1, arm 2)")
    return r


def check_stiffness(K, name: str = "K", n: int = N_GRIP_DOF) -> np.ndarray:
    """``K`` as a finite (n, n) float array, else ConfigError naming ``name``."""
    A = np.asarray(K, float)
    if A.shape != (n, n) or not np.all(np.isfinite(A)):
        raise ConfigError(f"{name}: shape is {A.shape} and should be a finite ({n}, {n})")
    return A


def rigid_modes(points, references) -> np.ndarray:
    """(n, 3, 6) displacements [mm] of ``points`` (n, 3) under the six unit rigid motions
    (t_x, t_y, t_z = 1 mm; theta_x, theta_y, theta_z = 1 rad) about ``references``: (3,) one
    point for all, or (n, 3) each point's own body reference (e.g. ``refs[body_of_node]``).
    ``u = t + theta x (x - r)``: columns 3-5 are ``-skew(x - r)``."""
    x = np.asarray(points, float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ConfigError(f"points: shape is {x.shape} and should be (n, 3)")
    r = np.asarray(references, float)
    if r.shape not in ((3,), x.shape):
        raise ConfigError(f"references: shape is {r.shape} and should be (3,) or {x.shape}")
    out = np.zeros((len(x), 3, 6))
    out[:, :, :3] = np.eye(3)
    out[:, :, 3:] = -skew(x - r)
    return out


def transport(r_from, r_to) -> np.ndarray:
    """(6, 6) map of a rigid motion's coordinates about ``r_from`` (3,) to those about
    ``r_to`` (3,): ``t' = t + theta x (r_to - r_from)``, ``theta' = theta``."""
    T = np.eye(6)
    T[:3, 3:] = -skew(np.asarray(r_to, float) - np.asarray(r_from, float))
    return T


def global_rigid_modes(references) -> np.ndarray:
    """(24, 6) grip coordinates of the six global rigid motions about the origin (the columns
    every sheet K annihilates): body b moves by ``transport(0, r_b)``."""
    r = check_references(references)
    return np.vstack([transport(np.zeros(3), rb) for rb in r])


def _relative_map(references) -> np.ndarray:
    """(18, 24) D: the arms' motions relative to the centre, at their reference points,
    ``q_k - transport(r_0, r_k) q_0`` (zero exactly for the global rigid motions)."""
    r = check_references(references)
    D = np.zeros((18, N_GRIP_DOF))
    for k in range(3):
        D[6 * k:6 * k + 6, :6] = -transport(r[0], r[k + 1])
        D[6 * k:6 * k + 6, 6 * (k + 1):6 * (k + 2)] = np.eye(6)
    return D


def relative_stiffness(K, references) -> np.ndarray:
    """(18, 18) stiffness of the three arms with the centre held (its motion zero): the arm
    block of ``K`` (24, 24). With the centre held an arm's own coordinates are its motion
    relative to the centre, so this is the matrix of :func:`full_from_relative`."""
    K = check_stiffness(K, "K")
    check_references(references)
    return K[6:, 6:].copy()


def full_from_relative(K_rel, references) -> np.ndarray:
    """(24, 24) ``D^T K_rel D`` from the arms' block ``K_rel`` (18, 18): exact for a K with
    no stiffness against global rigid motions, whose energy depends only on the relative
    motions ``D q`` (:func:`_relative_map`)."""
    K_rel = check_stiffness(K_rel, "K_rel", 18)
    D = _relative_map(references)
    return D.T @ K_rel @ D


def rigid_defect(K, references) -> float:
    """Relative size of ``K``'s response to global rigid motions: ``|K G| / (|K| |G|)``
    (spectral norms, G = :func:`global_rigid_modes` with rotations scaled by the grips'
    radius so that both kinds count alike); round-off (~1e-13) for an exact condensation."""
    K = check_stiffness(K, "K")
    r = check_references(references)
    L = max(float(np.abs(r).max()), 1.0)
    G = global_rigid_modes(r) * np.r_[np.ones(3), np.full(3, 1.0 / L)]
    D = np.tile(np.r_[np.ones(3), np.full(3, L)], 4)  # rotations as arc lengths at radius L
    Ks = K / D[:, None] / D[None, :]
    return float(np.linalg.norm(Ks @ (D[:, None] * G), 2)
                 / max(np.linalg.norm(Ks, 2) * np.linalg.norm(D[:, None] * G, 2), 1e-300))


@dataclass(frozen=True, eq=False)
class EigenRatios:
    """Generalised eigenpairs of two sheets' relative stiffnesses, ``K_a v = lambda K_b v``.

    ratios : (18,) lambda ascending: the stiffness ratio a / b of each mode [-].
    modes : (18, 18) columns v (arms' motions relative to the centre, the coordinates of
        :func:`relative_stiffness`), normalised to ``v^T K_b,rel v = 1``.
    """

    ratios: np.ndarray
    modes: np.ndarray


def eigen_pairs(K_a, K_b, references) -> EigenRatios:
    """:class:`EigenRatios` of sheets a and b (24, 24 each, same grips). Scale-free: the
    eigenvalues do not change when a coordinate (e.g. rotations vs translations) is rescaled."""
    Ra = relative_stiffness(check_stiffness(K_a, "K_a"), references)
    Rb = relative_stiffness(check_stiffness(K_b, "K_b"), references)
    Ra, Rb = 0.5 * (Ra + Ra.T), 0.5 * (Rb + Rb.T)
    try:
        w, v = sla.eigh(Ra, Rb)
    except np.linalg.LinAlgError:
        raise ConfigError("K_b: its arms' block (centre held) is not positive definite: "
                          "allowed only a sheet held by its centre") from None
    return EigenRatios(w, v)


def eigen_ratios(K_a, K_b, references) -> np.ndarray:
    """(18,) ascending stiffness ratios a / b of the modes (:func:`eigen_pairs`): all 1 for
    equal sheets, all s for ``K_a = s K_b``; the spread says how unlike the two sheets are."""
    return eigen_pairs(K_a, K_b, references).ratios


def readable_compliances(K) -> dict:
    """The centre's compliances with the three arm tabs clamped, from ``K`` (24, 24).

    ``W = inv(K[:6, :6])`` (the centre ring's stiffness about the sheet centre, arms held);
    each number is a diagonal entry, the motion along a unit load with the other five
    coordinates free:

    * ``normal_mm_per_N``: along the sheet normal (local z), per N pushed along z.
    * ``in_plane_x_mm_per_N``, ``in_plane_y_mm_per_N``: in-plane translation (x along arm 0).
    * ``roll_rad_per_Nmm`` / ``roll_deg_per_Nmm``: twist about the normal per N mm of torque
      about it (the rod roll of the robot).
    * ``tilt_x_rad_per_Nmm``, ``tilt_y_rad_per_Nmm`` (and ``_deg_``): tilt about the in-plane
      axes per N mm (the tilt about y bends arm 0).
    """
    K = check_stiffness(K, "K")
    Kc = 0.5 * (K[:6, :6] + K[:6, :6].T)
    try:
        W = np.linalg.inv(Kc)
    except np.linalg.LinAlgError:
        raise ConfigError("K: the centre block K[:6, :6] is singular: allowed only a sheet held by its arms") from None
    d = np.diag(W)
    if np.any(d <= 0):
        raise ConfigError("K: the centre block is not positive definite: allowed only a sheet held by its arms")
    deg = 180.0 / np.pi
    return {"normal_mm_per_N": float(d[2]), "in_plane_x_mm_per_N": float(d[0]),
            "in_plane_y_mm_per_N": float(d[1]),
            "roll_rad_per_Nmm": float(d[5]), "roll_deg_per_Nmm": float(d[5] * deg),
            "tilt_x_rad_per_Nmm": float(d[3]), "tilt_x_deg_per_Nmm": float(d[3] * deg),
            "tilt_y_rad_per_Nmm": float(d[4]), "tilt_y_deg_per_Nmm": float(d[4] * deg)}


# -- the homogenised sheet FEM -----------------------------------------------------------------

def linear_stiffness(points, tets, C):
    """(3n, 3n) CSR small-strain stiffness [N/mm] of a P1 (m, 4) or P2 (m, 10) tet mesh,
    ``sum_e P_e^T (sum_q w_q B_q^T C_e B_q) P_e`` with ``C`` (m, 6, 6) Voigt [MPa] in the
    points' frame: the design model's rest stiffness (:func:`metasheet.design.adjoint.solve_rest`),
    on the project's cached-pattern assembly."""
    tets = np.asarray(tets, np.int64)
    quad = tet10_quadrature if tets.shape[1] == 10 else tet4_quadrature
    grads, w = quad(points, tets)
    nen = tets.shape[1]
    Ke = np.empty((len(tets), 3 * nen, 3 * nen))
    for s in range(0, len(tets), _CHUNK):  # the strain operators of a fine P2 mesh run to GBs
        e = slice(s, s + _CHUNK)
        B = strain_operator(grads[e])  # (c, nq, 6, 3 nen) [1/mm]
        CB = np.einsum("mij,mqjb->mqib", C[e], B)
        Ke[e] = np.einsum("mq,mqia,mqib->mab", w[e], B, CB)
    Ke = 0.5 * (Ke + np.transpose(Ke, (0, 2, 1)))
    return SparsityPattern.from_elements(tets, len(points)).assemble(Ke)


def grip_jacobian(points, attach, references) -> tuple[np.ndarray, np.ndarray]:
    """Rigid nodes and their Jacobian: ``(nodes (nr,), G (3 nr, 24))``, nodes of body 0
    (tag 4) first, then arms 0-2 (tags 1-3); ``G`` the node displacements [mm] per unit
    grip coordinate (:func:`rigid_modes` about each body's reference)."""
    att = np.asarray(attach)
    nodes, blocks = [], []
    for b, tag in enumerate(GRIP_TAGS):
        sel = np.flatnonzero(att == tag)
        if len(sel) == 0:
            raise ConfigError(f"sheet.attach: no node tagged {tag} ({GRIPS[b]})")
        nodes.append(sel)
        blocks.append((b, rigid_modes(points[sel], references[b])))
    nodes = np.concatenate(nodes)
    G = np.zeros((len(nodes), 3, N_GRIP_DOF))
    i = 0
    for b, m in blocks:
        G[i:i + len(m), :, 6 * b:6 * b + 6] = m
        i += len(m)
    return nodes, G.reshape(-1, N_GRIP_DOF)


def fem_condensed(sheet, C, element: str = "p2", *, references=None, solver: str = "superlu") -> CondensedSheet:
    """The sheet FEM's linear stiffness condensed onto the four grips.

    Parameters
    ----------
    sheet : a linear :class:`~.geometry.SheetMesh` (points [mm], tets (m, 4), attach tags).
    C : (m, 6, 6) or (6, 6) Voigt stiffness [MPa] in the sheet frame, per element of ``sheet``
        (e.g. :func:`metasheet.robot.builder.material_stiffness` or ``element_stiffness``).
    element : "p1" or "p2" (:func:`.elements.as_element`: the robot's element).
    references : (4, 3) [mm], default :func:`grip_references` of ``sheet.params``.
    solver : sparse solver of the free block (:data:`metasheet.fem.factor.FACTOR_SOLVERS`);
        SuperLU by default: a direct solve, where an iteratively refined one would leave its
        tolerance in S, which the condensation's cancellation (S << G^T K_rr G) magnifies.

    Every node of tag 4 moves with body 0, of tag k + 1 with body k + 1 (rigidly); the free
    nodes are condensed out exactly: ``K = G^T K_rr G - (K_fr G)^T K_ff^-1 (K_fr G)``.
    """
    t0 = time.perf_counter()
    pts = np.asarray(sheet.points, float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ConfigError(f"sheet.points: shape is {pts.shape} and should be (n, 3)")
    m = len(sheet.tets)
    Cs = np.asarray(C, float)
    if Cs.shape == (6, 6):
        Cs = np.broadcast_to(Cs, (m, 6, 6))
    if Cs.shape != (m, 6, 6) or not np.all(np.isfinite(Cs)):
        raise ConfigError(f"C: shape is {np.shape(C)} and should be finite (6, 6) or ({m}, 6, 6)")
    refs = grip_references(sheet.params) if references is None else check_references(references)
    mesh = as_element(sheet, element)
    pts = np.asarray(mesh.points, float)
    K = linear_stiffness(pts, mesh.tets, Cs)
    S = GripCondensation.of(K, pts, mesh.attach, refs).condense(K, solver)
    return CondensedSheet(S, refs, 3 * len(pts), time.perf_counter() - t0, element)


@dataclass(frozen=True, eq=False)
class GripCondensation:
    """The condensation onto the grips of stiffnesses on one mesh and sparsity pattern (a fit
    condenses many; the index work is done once).

    Attributes
    ----------
    G : (3 nr, 24) rigid node displacements [mm] per unit grip coordinate (:func:`grip_jacobian`).
    dof_r, dof_f : (3 nr,), (3 nf,) int64 dofs of the rigid and the free nodes.
    maps : {"rr", "fr", "ff"}: (sub, take) of :func:`metasheet.fem.assembly.submatrix_map`.
    """

    G: np.ndarray
    dof_r: np.ndarray
    dof_f: np.ndarray
    maps: dict

    @classmethod
    def of(cls, K, points, attach, references) -> GripCondensation:
        """For CSR ``K`` (3n, 3n) (its pattern only) on ``points`` (n, 3) tagged ``attach`` (n,)."""
        nodes, G = grip_jacobian(points, attach, check_references(references))
        free = np.setdiff1d(np.arange(len(points)), nodes)
        dof_r = (3 * nodes[:, None] + np.arange(3)).ravel()
        dof_f = (3 * free[:, None] + np.arange(3)).ravel()
        pairs = {"rr": (dof_r, dof_r), "fr": (dof_f, dof_r), "ff": (dof_f, dof_f)}
        return cls(G, dof_r, dof_f, {key: submatrix_map(K, a, b) for key, (a, b) in pairs.items()})

    def block(self, K, key: str):
        """Block ``key`` ("rr", "fr", "ff") of CSR ``K`` (this pattern), a new CSR matrix."""
        sub, take = self.maps[key]
        return sp.csr_matrix((K.data[take], sub.indices, sub.indptr), shape=sub.shape)

    def condense(self, K, solver: str = "superlu", *, fields: bool = False):
        """(24, 24) ``S = G^T K_rr G - (K_fr G)^T K_ff^-1 (K_fr G)`` of CSR ``K`` (this pattern);
        with ``fields``, ``(S, U)``: U (3n, 24) the full displacements [mm] of the unit grip
        motions, free nodes at equilibrium (``S = U^T K U``, and ``dS = U^T dK U`` to first order)."""
        G = self.G
        Kff = self.block(K, "ff")
        Bfr = np.asarray(self.block(K, "fr") @ G)  # (3 nf, 24)
        ss = SparseSolver(solver)
        Y, _ = ss.solve_exact(ss.factorize(Kff), Kff, Bfr)
        S = G.T @ np.asarray(self.block(K, "rr") @ G) - Bfr.T @ Y
        S = 0.5 * (S + S.T)  # symmetric in exact arithmetic
        if not fields:
            return S
        U = np.zeros((K.shape[0], N_GRIP_DOF))
        U[self.dof_r], U[self.dof_f] = G, -Y
        return S, U


def reflect_grip_stiffness(K) -> np.ndarray:
    """(24, 24) the grip stiffness of the reflection y -> -y of a sheet with stiffness ``K``,
    in the reflected sheet's own grips (:func:`.geometry.mirror_sheet`): translations flip
    t_y, rotations (axial vectors) flip theta_x and theta_z, and arms 1 and 2 trade places
    (the mirror swaps their tags, so arm k keeps its direction)."""
    K = check_stiffness(K, "K")
    s = np.tile([1.0, -1.0, 1.0, -1.0, 1.0, -1.0], 4)
    perm = np.concatenate([np.arange(6 * b, 6 * b + 6) for b in (0, 1, 3, 2)])
    Kr = s[:, None] * K * s[None, :]
    return Kr[np.ix_(perm, perm)]
