"""Several rigid grips tied to a voxel body: its stiffness condensed onto their 6 B rigid dofs.

Body ``b`` (a grip of the printed sheet: the centre ring, an arm-end tab) moves its tied nodes as
``u_i = t_b + theta_b x (x_i - r_b)``, about its reference point ``r_b``; clamped nodes do not
move. For each unit motion ``q = e_k`` of the 6 B rigid dofs the free dofs solve

    K_ff u_f = -K_fp u_p,        u_p = R e_k on tied nodes, 0 on clamped ones,

all columns at once by one block PCG (:mod:`.pcg`) preconditioned by the multigrid of
:mod:`.multigrid`, and the condensed stiffness is the work-conjugate reaction

    K[j, k] = (R e_j) . K (u_p + u_f)_k                      (6 B, 6 B) [N/mm | N | N mm]

(the Schur complement of the free dofs), body by body in the order
(t_x, t_y, t_z, theta_x, theta_y, theta_z). It is evaluated in the energy form ``U_j . K U_k``
(the reaction plus the free dofs' residual work), whose error is second order in CG's; the
reactions' asymmetry is reported as the solver's error.

Floating pieces. Voxels that share only an edge or a corner are joined by a hinge (trilinear
elements: a zero-energy mechanism), and a piece of solid that reaches no prescribed node floats.
Both make ``K_ff`` singular. :func:`held_solid` keeps the face-connected pieces held by at least
three non-collinear prescribed nodes (fewer: the piece can turn about the line through them) and
drops the rest to void; the kept share of the solid is reported. Every kept piece is then held,
so the "split" coarsening factorises its bottom level without pinning (:mod:`.split_hierarchy`).

Columns. With nothing clamped, the 6 global rigid motions cost no energy, so
``K = T^T K_rel T`` exactly, where ``K_rel`` (6 (B - 1) square) is the stiffness of bodies
1..B-1 with body 0 held, and ``T`` (:func:`relative_motions`) maps the bodies' motions to the
motions of bodies 1..B-1 relative to body 0: 6 (B - 1) columns are solved instead of 6 B.

Memory. The rigid motions live on the tied nodes only, the right-hand sides and the reactions
on the voxels with a tied corner (:func:`_tie_operator`), the solve on the compact free nodes:
no (Nx, Ny, Nz, 3, 6 B) block (1.7 GB on the 0.3 mm sheet with four grips), unless
``displacements`` asks for it.

Measured (benchmarks/bench_voxel_grips.py; paper Polyfoam at 0.3 mm, rtol 1e-8, one numba
thread on a shared 2-core machine): the 30 x 30 x 5 mm patch with two end grips (122,553
unknowns, 6 columns) took 523 CG iterations and 102 s with the trilinear hierarchy, 31 and
5.8 s with the split one (K within 3e-10); the tripod sheet with its four grips (787,224
unknowns, 18 columns, 99.9 % of the solid kept) 51 split iterations, 10 s setup, 208 s solve,
2.1 GB peak, where the trilinear hierarchy stalled at a relative residual of 1.1e-6 after 450
iterations (1,497 s, 2.4 GB).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from threadpoolctl import threadpool_limits

from ..errors import ConfigError, ConvergenceError
from ..fem.voxel.compact import CompactOperator, compact
from ..fem.voxel.element import validate_grid, voxel_scale
from ..fem.voxel.multigrid import build_hierarchy
from ..fem.voxel.operator import VoxelOperator, node_shape, touched_nodes
from ..fem.voxel.pcg import pcg

#: Coarse spaces of :func:`rigid_bodies_stiffness` ("auto": "split", which now serves prescribed dofs).
COARSENINGS = ("auto", "trilinear", "split")

_CORNERS = tuple((a & 1, (a >> 1) & 1, (a >> 2) & 1) for a in range(8))


@dataclass(frozen=True)
class GripStiffness:
    """The condensed stiffness of B rigid grips tied to a voxel body.

    Attributes
    ----------
    K : (6 B, 6 B) float, symmetrised, body 0 (t_x, t_y, t_z, theta_x, theta_y, theta_z), body 1, ...:
        [N/mm] force-translation, [N] force-rotation and moment-translation, [N mm] moment-rotation.
    iterations : CG iterations of each solved column; residuals : their relative residuals.
    columns : "all" (6 B columns solved) or "relative" (6 (B - 1), body 0 held; K = T^T K_rel T).
    asymmetry : ||K_r - K_r^T|| / ||K_r|| of the solved block's reactions [-]: the solver's error
        (first order in it; K itself is the energy form ``U^T K U``, second order).
    n_dof : free unknowns; levels : multigrid grid shapes; unknowns : per level.
    coarsening : the coarse space used ("trilinear" or "split").
    kept_share : share of the solid voxels kept (held by prescribed nodes, :func:`held_solid`) [-].
    setup_seconds : pieces, hierarchy and right-hand sides [s]; seconds : wall time in all [s].
    U : (Nx, Ny, Nz, 3, 6 B) [mm per unit q] the displacement of each unit motion, or None
        (``displacements`` False).
    """

    K: np.ndarray
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    columns: str
    asymmetry: float
    n_dof: int
    levels: tuple[tuple[int, int, int], ...]
    unknowns: tuple[int, ...]
    coarsening: str
    kept_share: float
    setup_seconds: float
    seconds: float
    U: np.ndarray | None = None


def point_modes(r: np.ndarray) -> np.ndarray:
    """(n, 3, 6) unit rigid motions (t_x, t_y, t_z, theta_x, theta_y, theta_z) at points ``r`` (n, 3)
    [mm] relative to the reference point: ``t + theta x r``."""
    R = np.zeros((len(r), 3, 6))
    for c in range(3):
        R[:, c, c] = 1.0
    R[:, 1, 3], R[:, 2, 3] = -r[:, 2], r[:, 1]
    R[:, 0, 4], R[:, 2, 4] = r[:, 2], -r[:, 0]
    R[:, 0, 5], R[:, 1, 5] = -r[:, 1], r[:, 0]
    return R


def body_modes(x: np.ndarray, body: np.ndarray, references: np.ndarray) -> np.ndarray:
    """(n, 3, 6 B) the unit motions of B bodies at tied points ``x`` (n, 3) [mm] of body ``body`` (n,)
    int in 0..B-1, about ``references`` (B, 3) [mm]; zero in the other bodies' columns."""
    B = len(references)
    M = np.zeros((len(x), 3, 6 * B))
    cols = 6 * body[:, None, None] + np.arange(6)
    M[np.arange(len(x))[:, None, None], np.arange(3)[None, :, None], cols] = point_modes(x - references[body])
    return M


def relative_motions(references) -> np.ndarray:
    """(6 (B - 1), 6 B) ``T``: the B bodies' motions -> those of bodies 1..B-1 relative to body 0.

    Taking body 0's rigid motion off the whole body leaves body b with
    ``t'_b = t_b - t_0 + (r_b - r_0) x theta_0``, ``theta'_b = theta_b - theta_0`` about its own
    reference ``r_b`` (references (B, 3) [mm]); ``T`` maps every global rigid motion to zero."""
    r = np.asarray(references, float)
    B = len(r)
    T = np.zeros((6 * (B - 1), 6 * B))
    for b in range(1, B):
        d = r[b] - r[0]
        o = 6 * (b - 1)
        T[o:o + 6, 6 * b:6 * b + 6] = np.eye(6)
        T[o:o + 3, 0:3] = -np.eye(3)
        T[o:o + 3, 3:6] = [[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]]  # d x theta_0
        T[o + 3:o + 6, 3:6] = -np.eye(3)
    return T


def relative_fields(U_rel, x, references, Q) -> np.ndarray:
    """(n, 3, m) [mm] the displacement of the bodies' motions ``Q`` (6 B, m) at points ``x`` (n, 3)
    [mm, grid coordinates], from ``U_rel`` (n, 3, 6 (B - 1)) there, the fields of bodies 1..B-1's
    unit motions with body 0 held (``displacements="relative"``).

    A global rigid motion strains nothing, so its field is itself: the field of ``Q`` is body 0's
    rigid motion ``q_0`` carried by every point plus the relative fields of ``T Q``
    (:func:`relative_motions`), exactly what solving all 6 B columns gives (to the solver's
    tolerance)."""
    r = np.asarray(references, float)
    Q = np.asarray(Q, float)
    Q = Q.reshape(6 * len(r), -1)
    x = np.asarray(x, float).reshape(-1, 3)
    U_rel = np.asarray(U_rel, float)
    if U_rel.shape != (len(x), 3, 6 * (len(r) - 1)):
        raise ConfigError(f"U_rel: shape {U_rel.shape}: expected {(len(x), 3, 6 * (len(r) - 1))}")
    rigid = np.einsum("nic,cm->nim", point_modes(x - r[0]), Q[:6])  # einsum, not BLAS: fixed-order sums
    return rigid + np.einsum("nic,cm->nim", U_rel, np.einsum("rc,cm->rm", relative_motions(r), Q))


def held_solid(solid: np.ndarray, prescribed: np.ndarray) -> np.ndarray:
    """(nx, ny, nz) bool: the voxels of ``solid`` (nx, ny, nz) bool in face-connected pieces held by
    at least three non-collinear ``prescribed`` (nx + 1, ny + 1, nz + 1) bool nodes.

    A piece touching prescribed nodes at one node, or along one line, turns freely about it, and
    pieces joined to it through an edge or a corner only are separate pieces (hinges): both are
    dropped. Collinearity is tested exactly, on integer node indices."""
    label, n = ndimage.label(solid)  # the default structure: 6-connectivity
    held = np.zeros(n + 1, bool)
    nx, ny, nz = solid.shape
    pieces, points = [], []
    for o in _CORNERS:  # (piece, prescribed node) for every prescribed corner of a solid voxel
        ijk = np.nonzero(prescribed[o[0]:o[0] + nx, o[1]:o[1] + ny, o[2]:o[2] + nz] & solid)
        pieces.append(label[ijk])
        points.append(np.stack(ijk, 1) + np.array(o))
    piece = np.concatenate(pieces)
    if len(piece):
        x = np.concatenate(points).astype(np.int64)
        first = np.unique(piece, return_index=True)[1]
        anchor = np.zeros((n + 1, 3), np.int64)
        anchor[piece[first]] = x[first]
        d = x - anchor[piece]
        order = np.lexsort(((d * d).sum(1), piece))  # per piece, the node farthest from its anchor last
        last = order[np.r_[np.flatnonzero(np.diff(piece[order])), len(order) - 1]]
        far = np.zeros((n + 1, 3), np.int64)
        far[piece[last]] = d[last]
        off_line = np.cross(far[piece], d).any(axis=1)  # not on the line anchor -> farthest
        held[piece[off_line]] = True
    return held[label] & solid


def rigid_bodies_stiffness(phases, size, stiffnesses: dict, *, bodies, references, clamped=None, scale=None,
                           rtol: float = 1e-8, maxiter: int = 1000, coarsening: str = "auto",
                           relative: bool = True, displacements: bool | str = False,
                           progress: Callable[[str, int, int], None] | None = None) -> GripStiffness:
    """Condensed (6 B, 6 B) stiffness of B rigid bodies tied to nodes of a voxel body.

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = phase k.
    size : (3,) float [mm], the grid's edge lengths; node (i, j, k) sits at (i hx, j hy, k hz).
    stiffnesses : dict phase -> (6, 6) Voigt stiffness [MPa].
    bodies : (nx + 1, ny + 1, nz + 1) int nodes, 0 = not tied, b >= 1 = tied to body b - 1; each
        body must tie a node of the kept solid.
    references : (B, 3) [mm], each body's reference point (rotations are about it), grid coordinates.
    clamped : (nx + 1, ny + 1, nz + 1) bool nodes held fixed, disjoint from the tied ones (None: none).
    scale : (nx, ny, nz) per-voxel modulus factor (None: 1).
    rtol : CG tolerance per column, in (0, 1e-3); maxiter : CG iteration cap.
    coarsening : "auto" (= "split"), "split" or "trilinear" (:func:`~.multigrid.build_hierarchy`).
    relative : with nothing clamped, solve 6 (B - 1) columns with body 0 held (module doc);
        False: all 6 B columns. ``displacements=True`` solves all 6 B.
    displacements : also return U on the full grid: True, all 6 B columns (small grids: 6 B
        full-grid vectors); "relative", the 6 (B - 1) columns the relative solve has (body 0
        held, :func:`relative_fields` gives any motion's field from them), a quarter fewer.
    progress : called as ``progress(stage, done, total)`` before each of the 4 stages.

    Solid pieces not held by prescribed nodes are dropped (:func:`held_solid`). Raises ConfigError
    on bad input (naming the field), ConvergenceError when a column misses 10 rtol.
    """
    with threadpool_limits(limits=1, user_api="blas"):  # fixed-order BLAS sums: the same bits on any load
        return _stiffness(phases, size, stiffnesses, bodies, references, clamped, scale, rtol, maxiter,
                          coarsening, relative, displacements, progress or (lambda *_: None))


def _stiffness(phases, size, stiffnesses, bodies, references, clamped, scale, rtol, maxiter, coarsening,
               relative, displacements, progress) -> GripStiffness:
    t0 = time.perf_counter()
    progress("grips: solid", 0, 4)
    index, table, h, _ = validate_grid(phases, size, stiffnesses)
    N = node_shape(index.shape, False)
    body, B = _bodies(bodies, N)
    refs = _references(references, B)
    clamped = np.zeros(N, bool) if clamped is None else bool_nodes(clamped, "clamped", N)
    floating = not clamped.any()
    if np.any(clamped & (body > 0)):
        raise ConfigError(f"clamped, bodies: {int((clamped & (body > 0)).sum())} nodes are both clamped and tied "
                          "to a body; they must be disjoint")
    if not (0 < float(rtol) < 1e-3):
        raise ConfigError(f"rtol: {rtol!r}: allowed range is (0, 1e-3)")
    if int(maxiter) != maxiter or maxiter < 1:
        raise ConfigError(f"maxiter: {maxiter!r}: must be a positive integer")
    if coarsening not in COARSENINGS:
        raise ConfigError(f"coarsening: {coarsening!r}: allowed values are {', '.join(COARSENINGS)}")
    solid = index >= 0
    kept = held_solid(solid, clamped | (body > 0))
    index = np.where(kept, index, -1)
    touched = touched_nodes(index, False)
    tied = (body > 0) & touched
    missing = sorted(set(range(1, B + 1)) - set(np.unique(body[tied]).tolist()))
    if missing:
        raise ConfigError(f"bodies: body {missing[0] - 1} (value {missing[0]}) ties no node of the kept solid "
                          "(its nodes touch no solid voxel held by three non-collinear prescribed nodes)")
    fixed = np.repeat((clamped | tied)[..., None], 3, axis=3)
    op = VoxelOperator(index, table.K, voxel_scale(scale, index.shape), False,
                       (touched[..., None] & ~fixed).astype(float), h)
    progress("grips: hierarchy", 1, 4)
    H = build_hierarchy(op, fixed, coarsening="split" if coarsening == "auto" else coarsening) if op.n_free else None
    used = "split" if H is not None and H.sparse is not None else "trilinear"  # a small grid: one dense level
    # relative: body 0 held, its columns left out (with nothing clamped K = T^T K_rel T exactly)
    if displacements not in (False, True, "relative"):
        raise ConfigError(f"displacements: {displacements!r}: allowed values are False, True, 'relative'")
    if displacements == "relative" and not (relative and floating):
        raise ConfigError("displacements: 'relative' needs relative=True and nothing clamped")
    shortcut = bool(relative and floating and displacements is not True)
    cols = np.arange(6 if shortcut else 0, 6 * B)
    tflat = np.flatnonzero(tied.ravel())
    modes = body_modes(np.stack(np.unravel_index(tflat, N), 1) * h, body.ravel()[tflat] - 1, refs)
    tie = _tie_operator(op, tied)
    jt = tie.node_map[tflat]  # the tied nodes in the tie operator's numbering
    up = np.zeros((tie.size, 3, len(cols)))
    up[jt] = modes[..., cols]
    cop = H.fine if H is not None else None
    ft = tie.node_map[cop.active] if cop is not None else np.zeros(0, np.int64)  # fine -> tie node, -1: none
    on = ft >= 0
    t1 = time.perf_counter()
    progress("grips: solve", 2, 4)
    iters, res, x = (), (), None
    if cop is not None and len(cols):
        y = tie.apply(up)  # K u_p on every node it reaches: only voxels with a tied corner see u_p
        b = np.zeros((cop.size, 3, len(cols)))
        b[on] = -cop.free[on][..., None] * y[ft[on]]
        del y
        out = pcg(cop.apply, b, H.precondition, rtol=rtol, maxiter=int(maxiter), flexible=H.flexible)
        for k in np.flatnonzero(~out.converged):
            raise ConvergenceError(f"voxel grips: column {int(cols[k])}: relative residual {out.residual[k]:.2e} "
                                   f"after {out.iterations[k]} iterations, asked {rtol:g}",
                                   history=out.history[:, k].tolist())
        iters, res, x = tuple(out.iterations.tolist()), tuple(out.residual.tolist()), out.x
        # energy form: U^T K U = reactions + x^T (K_ff x - b), the CG residual's share; its error is
        # second order in the solver's (the reactions' alone first order: 3e-5 against 3e-10 at
        # rtol 1e-8 on the 30 mm printed patch, measured between the two coarsenings)
        gap = x.reshape(-1, len(cols)).T @ (cop.apply(x) - b).reshape(-1, len(cols))
        del b
        up[ft[on]] += x[on]  # u_p + u_f on the tie operator's nodes (tied nodes are never free)
    progress("grips: reactions", 3, 4)
    Ks = np.zeros((6 * B, 0))  # one floating body: its rigid motions cost nothing, K = 0
    if len(cols):
        f = tie.apply(up)[jt]  # (t, 3, m) [N] reactions K (u_p + u_f) at the tied nodes
        Ks = modes.reshape(-1, 6 * B).T @ f.reshape(-1, len(cols))  # (6 B, m): work-conjugate loads
    Ks = Ks[6:] if shortcut else Ks
    norm = float(np.linalg.norm(Ks))
    asym = float(np.linalg.norm(Ks - Ks.T)) / norm if norm > 0 else 0.0
    if x is not None:
        Ks = Ks + gap
    Ks = 0.5 * (Ks + Ks.T)
    T = relative_motions(refs) if shortcut else None
    K = T.T @ Ks @ T if shortcut else Ks
    U = _displacements(N, tflat, modes[..., cols], cop, x) if displacements else None
    return GripStiffness(0.5 * (K + K.T), iters, res, "relative" if shortcut else "all", asym, op.n_free,
                         H.shapes if H is not None else (), H.unknowns if H is not None else (), used, float(kept.sum() / solid.sum()),
                         t1 - t0, time.perf_counter() - t0, U)


def _tie_operator(op: VoxelOperator, tied: np.ndarray) -> CompactOperator:
    """``op`` on the voxels with a tied corner, every dof of their nodes active: ``K u`` at any node
    for a ``u`` that is rigid on the tied nodes only, and the reactions at the tied nodes."""
    nx, ny, nz = op.index.shape
    near = np.zeros(op.index.shape, bool)
    for o in _CORNERS:
        near |= tied[o[0]:o[0] + nx, o[1]:o[1] + ny, o[2]:o[2] + nz]
    index = np.where(near, op.index, -1)
    free = np.repeat(touched_nodes(index, False)[..., None], 3, axis=3).astype(float)
    return compact(VoxelOperator(index, op.matrices, op.scale, False, free, op.h))


def _displacements(N, tflat, modes, cop, x) -> np.ndarray:
    """(Nx, Ny, Nz, 3, 6 B) [mm]: the rigid motions on the tied nodes plus the free solution."""
    U = np.zeros((int(np.prod(N)), 3, modes.shape[2]))
    U[tflat] = modes
    if x is not None:
        U[cop.active] += x
    return U.reshape(tuple(N) + (3, modes.shape[2]))


def _bodies(bodies, shape) -> tuple[np.ndarray, int]:
    b = np.asarray(bodies)
    if b.shape != tuple(shape) or not np.issubdtype(b.dtype, np.integer):
        raise ConfigError(f"bodies: shape {b.shape}, dtype {b.dtype}: must be an integer array of the "
                          f"{tuple(shape)} grid nodes (0 = not tied, b >= 1 = tied to body b - 1)")
    if b.min() < 0:
        raise ConfigError(f"bodies: {int(b.min())}: allowed values are 0 (not tied) and b >= 1 (body b - 1)")
    if b.max() < 1:
        raise ConfigError("bodies: no node is tied (all 0): at least one body must tie a node")
    return b.astype(np.int64), int(b.max())


def _references(references, B: int) -> np.ndarray:
    r = np.asarray(references, float)
    if r.shape != (B, 3) or not np.all(np.isfinite(r)):
        raise ConfigError(f"references: shape {r.shape}: must be ({B}, 3) finite points [mm], one per body")
    return r


def bool_nodes(a, name: str, shape) -> np.ndarray:
    """``a`` as a bool array of the grid's nodes ``shape``, or ConfigError naming ``name``."""
    m = np.asarray(a)
    if m.shape != tuple(shape) or m.dtype != bool:
        raise ConfigError(f"{name}: shape {m.shape}, dtype {m.dtype}: must be a bool array of the "
                          f"{tuple(shape)} grid nodes (one more than voxels per direction)")
    return m
