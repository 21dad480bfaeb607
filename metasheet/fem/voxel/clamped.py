"""Non-periodic voxel bodies: clamped nodes, nodes tied to a rigid body, its condensed stiffness.

A rigid body (a grip of the printed sheet) moves its tied nodes as
``u_i = t + theta x (x_i - x_0)``: 6 dofs ``q = (t, theta)``. Clamped nodes do not move.
For each of the six unit rigid motions ``q = e_k`` the free dofs solve

    K_ff u_f = -K_fp u_p,        u_p = R e_k on tied nodes, 0 on clamped ones,

by multigrid CG (prescribed dofs are removed from the hierarchy, :mod:`.coarsen`), and the
condensed stiffness of the body is the work-conjugate reaction

    K_body[j, k] = (R e_j) . K (u_p + u_f)_k                 (6, 6), [N/mm | N | N mm]

in the order (t_x, t_y, t_z, theta_x, theta_y, theta_z): the Schur complement of the free
dofs, symmetric positive definite when the clamp holds the body.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ...errors import ConfigError, ConvergenceError
from .homogenize import _scale, validate_grid
from .multigrid import build_hierarchy
from .operator import VoxelOperator, apply_full, node_shape, touched_nodes
from .pcg import pcg


@dataclass(frozen=True)
class RigidBodyStiffness:
    """The condensed stiffness of a rigid body tied to a clamped voxel body.

    Attributes
    ----------
    K : (6, 6) float, rows/columns (t_x, t_y, t_z, theta_x, theta_y, theta_z): [N/mm] for
        force-translation, [N] for force-rotation and moment-translation, [N mm] for moment-rotation.
    U : (Nx, Ny, Nz, 3, 6) float [mm per unit q], the displacement of each unit rigid motion.
    iterations : (6,) CG iterations; residuals : (6,) relative residuals.
    n_dof : free unknowns; levels : multigrid grid shapes; seconds : wall time [s].
    """

    K: np.ndarray
    U: np.ndarray
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    n_dof: int
    levels: tuple[tuple[int, int, int], ...]
    seconds: float


def rigid_modes(nodes: np.ndarray, h, reference) -> np.ndarray:
    """(Nx, Ny, Nz, 3, 6) unit rigid motions about ``reference`` [mm], on the nodes where
    ``nodes`` (Nx, Ny, Nz) bool is True (node (i, j, k) at (i hx, j hy, k hz)), zero elsewhere."""
    x = np.stack(np.indices(nodes.shape), axis=-1) * np.asarray(h, float) - np.asarray(reference, float)
    R = np.zeros(nodes.shape + (3, 6))
    for c in range(3):
        R[..., c, c] = 1.0
    # theta x r for unit theta along axis a
    R[..., 1, 3], R[..., 2, 3] = -x[..., 2], x[..., 1]
    R[..., 0, 4], R[..., 2, 4] = x[..., 2], -x[..., 0]
    R[..., 0, 5], R[..., 1, 5] = -x[..., 1], x[..., 0]
    return R * nodes[..., None, None]


def rigid_body_stiffness(phases, size, stiffnesses: dict, *, clamped, tied, reference=None, scale=None,
                         rtol: float = 1e-8, maxiter: int = 500) -> RigidBodyStiffness:
    """Condensed 6 x 6 stiffness of a rigid body tied to nodes of a clamped voxel body.

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = phase k.
    size : (3,) float [mm], the grid's edge lengths; node (i, j, k) sits at (i hx, j hy, k hz).
    stiffnesses : dict phase -> (6, 6) Voigt stiffness [MPa].
    clamped, tied : (nx + 1, ny + 1, nz + 1) bool nodes, disjoint; tied nodes must be solid.
    reference : (3,) [mm] point the rotations are about (default: centroid of the tied nodes).
    scale : (nx, ny, nz) per-voxel modulus factor (None: 1).
    rtol, maxiter : CG tolerance and cap per unit motion.
    """
    with threadpool_limits(limits=1, user_api="blas"):
        t0 = time.perf_counter()
        index, table, h, _ = validate_grid(phases, size, stiffnesses)
        N = node_shape(index.shape, False)
        clamped, tied = (_nodes(a, name, N) for a, name in ((clamped, "clamped"), (tied, "tied")))
        if np.any(clamped & tied):
            raise ConfigError("clamped, tied: a node is both clamped and tied to the rigid body")
        touched = touched_nodes(index, False)
        if not np.any(tied & touched):
            raise ConfigError("tied: no tied node touches a solid voxel")
        if not (0 < float(rtol) < 1e-3):
            raise ConfigError(f"rtol: {rtol!r}: allowed range is (0, 1e-3)")
        tied = tied & touched
        ref = (np.argwhere(tied).mean(axis=0) * h if reference is None else np.asarray(reference, float))
        fixed = np.repeat((clamped | tied)[..., None], 3, axis=3)
        free = (touched[..., None] & ~fixed).astype(float)
        op = VoxelOperator(index, table.K, _scale(scale, index.shape), False, free, h)
        H = build_hierarchy(op, fixed)
        R = rigid_modes(tied, h, ref)
        cop = H.fine  # vectors on the nodes with unknowns only (:mod:`.compact`)
        out = pcg(cop.apply, -cop.to_compact(free[..., None] * apply_full(op, R)), H.precondition, rtol=rtol,
                  maxiter=maxiter)
        for k in np.flatnonzero(~out.converged):
            raise ConvergenceError(f"voxel: rigid motion {k}: relative residual {out.residual[k]:.2e} after "
                                   f"{out.iterations[k]} iterations, asked {rtol:g}", history=out.history[:, k].tolist())
        U = R + cop.to_full(out.x)
        iters, res = out.iterations.tolist(), out.residual.tolist()
        KU = apply_full(op, U)
        K = R.reshape(-1, 6).T @ KU.reshape(-1, 6)
        return RigidBodyStiffness(0.5 * (K + K.T), U, tuple(iters), tuple(res), op.n_free, H.shapes,
                                  time.perf_counter() - t0)


def _nodes(a, name: str, shape) -> np.ndarray:
    m = np.asarray(a)
    if m.shape != tuple(shape) or m.dtype != bool:
        raise ConfigError(f"{name}: shape {m.shape}, dtype {m.dtype}: must be a bool array of the "
                          f"{tuple(shape)} grid nodes (one more than voxels per direction)")
    return m
