"""Non-periodic voxel bodies: clamped nodes, nodes tied to a rigid body, its condensed stiffness.

A rigid body (a grip of the printed sheet) moves its tied nodes as
``u_i = t + theta x (x_i - x_0)``: 6 dofs ``q = (t, theta)``. Clamped nodes do not move.
For each of the six unit rigid motions ``q = e_k`` the free dofs solve

    K_ff u_f = -K_fp u_p,        u_p = R e_k on tied nodes, 0 on clamped ones,

by multigrid CG (prescribed dofs are removed from the hierarchy, :mod:`.coarsen`; the solve is
:func:`~.grips.rigid_bodies_stiffness` with one body), and the
condensed stiffness of the body is the work-conjugate reaction

    K_body[j, k] = (R e_j) . K (u_p + u_f)_k                 (6, 6), [N/mm | N | N mm]

in the order (t_x, t_y, t_z, theta_x, theta_y, theta_z): the Schur complement of the free
dofs, symmetric positive definite when the clamp holds the body.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .voxel_grips import bool_nodes, point_modes, rigid_bodies_stiffness
from ..fem.voxel.element import validate_grid
from ..fem.voxel.operator import node_shape, touched_nodes


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
    x = np.stack(np.indices(nodes.shape), axis=-1).reshape(-1, 3) * np.asarray(h, float)
    x = x - np.asarray(reference, float)
    return point_modes(x).reshape(nodes.shape + (3, 6)) * nodes[..., None, None]


def rigid_body_stiffness(phases, size, stiffnesses: dict, *, clamped, tied, reference=None, scale=None,
                         rtol: float = 1e-8, maxiter: int = 500, coarsening: str = "trilinear") -> RigidBodyStiffness:
    """Condensed 6 x 6 stiffness of a rigid body tied to nodes of a clamped voxel body: the one-body
    case of :func:`~.grips.rigid_bodies_stiffness` (solid pieces not held are dropped there too).

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = phase k.
    size : (3,) float [mm], the grid's edge lengths; node (i, j, k) sits at (i hx, j hy, k hz).
    stiffnesses : dict phase -> (6, 6) Voigt stiffness [MPa].
    clamped, tied : (nx + 1, ny + 1, nz + 1) bool nodes, disjoint; tied nodes must be solid.
    reference : (3,) [mm] point the rotations are about (default: centroid of the tied nodes).
    scale : (nx, ny, nz) per-voxel modulus factor (None: 1).
    rtol, maxiter : CG tolerance and cap per unit motion.
    coarsening : "trilinear" (default), "split" or "auto" (:func:`~.grips.rigid_bodies_stiffness`).
    """
    t0 = time.perf_counter()
    index, _, h, _ = validate_grid(phases, size, stiffnesses)
    N = node_shape(index.shape, False)
    clamped, tied = (bool_nodes(a, name, N) for a, name in ((clamped, "clamped"), (tied, "tied")))
    if np.any(clamped & tied):
        raise ConfigError("clamped, tied: a node is both clamped and tied to the rigid body")
    touched = touched_nodes(index, False)
    if not np.any(tied & touched):
        raise ConfigError("tied: no tied node touches a solid voxel")
    ref = (np.argwhere(tied & touched).mean(axis=0) * h if reference is None else np.asarray(reference, float))
    r = rigid_bodies_stiffness(phases, size, stiffnesses, bodies=tied.astype(np.int64), references=ref[None],
                               clamped=clamped, scale=scale, rtol=rtol, maxiter=maxiter, coarsening=coarsening,
                               displacements=True)
    return RigidBodyStiffness(r.K, r.U, r.iterations, r.residuals, r.n_dof, r.levels, time.perf_counter() - t0)
