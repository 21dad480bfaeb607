"""A voxel cell's six periodic corrector problems solved matrix-free on the grid itself.

The homogenisation's own use of the voxel machinery (:mod:`metasheet.fem.voxel`): the solver
layer (:mod:`metasheet.fem.solvers`) names the grid solvers, this module runs them, and
:func:`metasheet.homogenize.voxels.homogenize_voxels` chooses between them and an assembled
solve (:data:`VOXEL_AUTO_DOFS`).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..fem.solvers import GRID_SOLVERS, SolveReport

#: "auto" homogenises a voxel cell matrix-free from this many unknowns (3 per grid node the
#: solid touches). Measured against PARDISO in the same run (docs/voxel.md, benchmarks/results/
#: bench_voxel_solver.md): a tie at 67k unknowns, 0.55 of its time at 154k, 0.36-0.52 at 754k
#: (the paper's cell), with 0.15-0.5 of its memory; PARDISO's fill grows as n^(4/3) and no
#: longer fits 24 GB at a few million.
VOXEL_AUTO_DOFS = 150_000


def solve_voxel_correctors(phases: np.ndarray, size, stiffnesses: dict, *, solver: str = "voxel",
                           rtol: float = 1e-8, maxiter: int = 500, coarsening: str = "split"):
    """The six periodic corrector problems of a voxel cell, matrix-free (:mod:`metasheet.fem.voxel`).

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = phase k; the percolating solid only.
    size : (3,) float [mm]; stiffnesses : dict phase -> (6, 6) Voigt stiffness [MPa].
    solver : a name in :data:`GRID_SOLVERS`: "voxel" (CPU) or "voxel-gpu" (the same split multigrid CG
        on a CUDA GPU through CuPy, :mod:`metasheet.homogenize.voxel_periodic_gpu`; a ConfigError when CuPy or
        the GPU is missing; never chosen by "auto"); rtol : relative residual per load case.
    coarsening : the multigrid's coarse spaces, "split" (default) or "trilinear"
        (:func:`metasheet.homogenize.voxel_periodic.periodic_stiffness`; a ConfigError names the allowed values).

    Returns
    -------
    C (6, 6) [MPa], C_raw (6, 6) [MPa], U (nx ny nz * 3, 6) corrector displacements on every
    grid node (flat dof ``3 ((i ny + j) nz + k) + c``, zero on nodes without solid), and the
    :class:`SolveReport` (solver "voxel", CG iterations per load case).
    """
    if solver not in GRID_SOLVERS:
        raise ConfigError(f"solver: {solver!r}: allowed values are {', '.join(GRID_SOLVERS)}")
    # imported here: its numba kernels are compiled (or loaded from cache) on first use only
    if solver == "voxel-gpu":
        from .voxel_periodic_gpu import periodic_stiffness_device

        if coarsening != "split":
            raise ConfigError(f"coarsening: {coarsening!r}: solver 'voxel-gpu' runs the split hierarchy only")
        r = periodic_stiffness_device(phases, size, stiffnesses, rtol=rtol, maxiter=maxiter)
    else:
        from .voxel_periodic import periodic_stiffness

        r = periodic_stiffness(phases, size, stiffnesses, rtol=rtol, maxiter=maxiter, coarsening=coarsening)
    report = SolveReport(solver, r.iterations, r.residuals, r.setup_seconds, r.solve_seconds, r.n_dof)
    return r.C, r.C_raw, r.U.reshape(-1, 6), report
