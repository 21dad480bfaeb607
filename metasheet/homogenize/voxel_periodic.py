"""Periodic homogenisation on a voxel grid, matrix-free: the six corrector problems by MG-CG.

The same problem as :mod:`metasheet.homogenize.corrector` (u = E x + u~, u~ periodic):

    K u~_I = -f_I,        f_I = int_Y_s B^T C E_I dV                               (corrector)
    C*_IJ = (C_vol + f_I . u_J + u_I . f_J + u_I . K u_J)_IJ / |Y|                  (energy form)

with ``K`` applied voxel by voxel (:mod:`.operator`), CG preconditioned by one geometric
multigrid V-cycle (:mod:`.multigrid`), and each part's free translation projected out
(:mod:`.pcg`) instead of pinned. Void voxels carry no unknowns, as in the assembled path;
the caller removes the solid that does not percolate
(:func:`metasheet.homogenize.percolation.percolating_solid`), as the assembled path does,
since a floating island would add rotations to the null space.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..errors import ConfigError, ConvergenceError
from ..fem.voxel.components import components
from ..fem.voxel.element import validate_grid, voxel_scale
from ..fem.voxel.multigrid import build_hierarchy
from ..fem.voxel.operator import VoxelOperator, node_shape, scatter_compact, touched_nodes
from ..fem.voxel.pcg import pcg, translation_projector


@dataclass(frozen=True)
class VoxelHomogenization:
    """Effective stiffness of a periodic voxel cell and how the solver got it.

    Attributes
    ----------
    C : (6, 6) float [MPa], energy-form effective stiffness (symmetrised), Voigt 11, 22, 33,
        23, 13, 12 with engineering shear.
    C_raw : (6, 6) float [MPa], first-order form ``(C_vol + U^T f) / |Y|`` (its asymmetry
        measures the solver error).
    U : (nx, ny, nz, 3, 6) float [mm per unit strain], corrector displacements per grid node
        (zero where no unknowns), flat dof ``3 node + i`` as in the assembled path.
    iterations : (6,) CG iterations per load case.
    residuals : (6,) relative residuals ``||K u + f|| / ||f||``.
    setup_seconds : hierarchy build [s]; solve_seconds : six solves and C [s].
    n_dof : unknowns (3 per node touched by a solid voxel).
    levels : voxel grid shape of each multigrid level, finest first.
    device : what ran the CG: "cpu", or the device's name (:mod:`.device_solve`: the GPU, or "host"
        for the numpy back-end); device_bytes : the device's memory pool high-water mark [B] (0: none).
    """

    C: np.ndarray
    C_raw: np.ndarray
    U: np.ndarray
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    setup_seconds: float
    solve_seconds: float
    n_dof: int
    levels: tuple[tuple[int, int, int], ...]
    device: str = "cpu"
    device_bytes: int = 0


def node_parts(index: np.ndarray, periodic: bool) -> tuple[np.ndarray, int]:
    """(Nx, Ny, Nz) int part of each node (-1: no voxel) over node-sharing voxels, and the count."""
    N = node_shape(index.shape, periodic)
    occ = np.argwhere(index >= 0)
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])
    nodes = (occ[:, None, :] + corners[None]) % np.array(N)
    flat = (nodes[..., 0] * N[1] + nodes[..., 1]) * N[2] + nodes[..., 2]
    n = int(np.prod(N))
    lab = components(n, np.repeat(flat[:, :1], 7, axis=1).ravel(), flat[:, 1:].ravel())
    touched = touched_nodes(index, periodic).ravel()
    used, lab = np.unique(np.where(touched, lab, -1), return_inverse=True)
    lab = lab.reshape(-1) - (1 if used[0] == -1 else 0)
    return lab.reshape(N), int((used >= 0).sum())


def periodic_stiffness(phases, size, stiffnesses: dict, *, scale=None, rtol: float = 1e-8, maxiter: int = 500,
                       smoother: str = "chebyshev", degree: int = 2,
                       coarsening: str = "split", direct_dofs: int | None = None) -> VoxelHomogenization:
    """Effective stiffness of a periodic voxel cell by matrix-free multigrid CG.

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = phase k; only solid that percolates.
    size : (3,) float [mm], the box's edge lengths (voxel h = size / shape).
    stiffnesses : dict phase -> (6, 6) Voigt stiffness [MPa].
    scale : (nx, ny, nz) float > 0, a per-voxel modulus factor (None: 1).
    rtol : relative residual of each load case, in (0, 1e-3).
    maxiter : CG iteration cap per load case.
    smoother, degree : the multigrid smoother (:func:`~.multigrid.build_hierarchy`).
    coarsening : "split" (default: split coarse levels with K-cycles, flexible CG; far fewer
        iterations on thin walls, measured in docs/voxel.md) or "trilinear"
        (:func:`~.multigrid.build_hierarchy`).
    direct_dofs : "split": factorise the first split level with at most this many unknowns (None:
        :data:`~.split_hierarchy.DIRECT_DOFS`; smaller values give deeper hierarchies on small cells).

    Returns
    -------
    :class:`VoxelHomogenization`.

    Raises
    ------
    ConfigError : bad input. ConvergenceError : a load case missed 10 rtol in maxiter iterations.
    """
    if not (0 < float(rtol) < 1e-3):
        raise ConfigError(f"rtol: {rtol!r}: allowed range is (0, 1e-3)")
    if int(maxiter) != maxiter or maxiter < 1:
        raise ConfigError(f"maxiter: {maxiter!r}: must be a positive integer")
    # One BLAS thread: the dense coarsest solve and the dot products then have the same bits on
    # every machine load and thread count (and, measured on 2 busy cores, a threaded eigh of
    # 648 unknowns took 5 s instead of 0.05 s).
    with threadpool_limits(limits=1, user_api="blas"):
        return _periodic_stiffness(phases, size, stiffnesses, scale, rtol, maxiter, smoother, degree,
                                   coarsening, direct_dofs)


@dataclass(frozen=True)
class CellProblem:
    """The six corrector problems of a cell, set up on the host (shared by the CPU and device solves).

    index (nx, ny, nz) int64 phase row (-1 void); table: the phases' matrices; sc (nx, ny, nz)
    modulus factors; op: the fine operator; H: its multigrid hierarchy; labels (a,) the compact
    nodes' parts, n_parts their count; F (a, 3, 6) [N] the compact unit-strain forces;
    setup_seconds [s].
    """

    index: np.ndarray
    table: object
    sc: np.ndarray
    op: VoxelOperator
    H: object
    labels: np.ndarray
    n_parts: int
    F: np.ndarray
    setup_seconds: float


def prepare_cell(phases, size, stiffnesses, scale=None, smoother: str = "chebyshev", degree: int = 2,
                 coarsening: str = "split", direct_dofs: int | None = None) -> CellProblem:
    """Validate the cell, build its operator and hierarchy, and the six right-hand sides."""
    t0 = time.perf_counter()
    index, table, h, _ = validate_grid(phases, size, stiffnesses)
    sc = voxel_scale(scale, index.shape)
    free = np.repeat(touched_nodes(index, True)[..., None], 3, axis=3).astype(float)
    op = VoxelOperator(index, table.K, sc, True, free, h)
    labels, n_parts = node_parts(index, True)
    H = build_hierarchy(op, smoother=smoother, degree=degree, coarsening=coarsening, direct_dofs=direct_dofs)
    cop = H.fine  # vectors on the nodes with unknowns only (:mod:`.compact`)
    # (a, 3, 6) [N] on the active nodes: only U, the result, is kept on the full grid (each full
    # (Nx, Ny, Nz, 3, 6) array is 130 MB on the paper cell, void nodes included)
    F = scatter_compact(index, table.F, sc, True, cop.node_map) * cop.free[..., None]
    return CellProblem(index, table, sc, op, H, cop.to_compact(labels), n_parts, F, time.perf_counter() - t0)


def energy_form(cell: CellProblem, size, X: np.ndarray, KX: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C, C_raw) (6, 6) [MPa] from the compact correctors X (a, 3, 6) [mm] and K X [N]:
    ``C_raw = (C_vol + X^T f) / |Y|``, ``C = (C_vol + f^T X + X^T f + X^T K X) / |Y|`` (not symmetrised)."""
    volume = float(np.prod(size))
    index, sc, table = cell.index, cell.sc, cell.table
    occ = index >= 0
    c_vol = np.einsum("e,eij->ij", sc[occ] * table.volume, table.C[index[occ]])  # [N mm]
    f, u, ku = (a.reshape(-1, 6) for a in (cell.F, X, KX))
    return (c_vol + f.T @ u + u.T @ f + u.T @ ku) / volume, (c_vol + u.T @ f) / volume


def check_converged(out, rtol: float) -> None:
    """Raise ConvergenceError naming the first load case that missed rtol."""
    for I in np.flatnonzero(~out.converged):
        raise ConvergenceError(f"voxel: load case {I}: relative residual {out.residual[I]:.2e} after "
                               f"{out.iterations[I]} iterations, asked {rtol:g}", history=out.history[:, I].tolist())


def _periodic_stiffness(phases, size, stiffnesses, scale, rtol, maxiter, smoother, degree, coarsening,
                        direct_dofs=None):
    cell = prepare_cell(phases, size, stiffnesses, scale, smoother, degree, coarsening, direct_dofs)
    t1 = time.perf_counter()
    cop = cell.H.fine
    project = translation_projector(cell.labels, cell.n_parts)
    # the six load cases in lockstep: one sweep of the voxels and one V-cycle serve all six
    out = pcg(cop.apply, -cell.F, cell.H.precondition, rtol=rtol, maxiter=maxiter, project=project,
              flexible=cell.H.flexible)
    check_converged(out, rtol)
    C, C_raw = energy_form(cell, size, out.x, cop.apply(out.x))
    t2 = time.perf_counter()
    return VoxelHomogenization(0.5 * (C + C.T), C_raw, cop.to_full(out.x), tuple(out.iterations.tolist()),
                               tuple(out.residual.tolist()), cell.setup_seconds, t2 - t1, cell.op.n_free,
                               cell.H.shapes)
