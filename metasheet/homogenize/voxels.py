"""Periodic homogenisation on a voxel grid (trilinear hexahedra, void removed).

Every voxel is the same box, so the 24 x 24 element stiffness, the 24 x 6 unit-strain
forces and the mean strain operator are computed once per phase
(:func:`~metasheet.fem.hex8.hex8_box_matrices`) and scattered through the mesh's
sparsity pattern (:class:`~metasheet.fem.assembly.SparsityPattern`, given one matrix per
phase). The grid is periodic by construction: voxel (i, j, k) uses the nodes
((i + a) mod nx, ...), so no constraint is needed. Void voxels are removed (not made
soft), and so are solid islands that do not wrap around the box
(:mod:`.percolation`). The corrector problem is in :mod:`.corrector`.

Array axis 0 is x, axis 1 is y, axis 2 is z; voxel (i, j, k) spans
[i hx, (i + 1) hx] x [j hy, (j + 1) hy] x [k hz, (k + 1) hz] with h = size / shape.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import ConfigError
from ..fem.assembly import SparsityPattern, element_dofs
from ..fem.solvers import GRID_SOLVERS
from ..fem.hex8 import HEX8_CORNERS, hex8_box_matrices
from ..fem.voxel.element import check_phases
from .corrector import check_and_fit, material_stiffness, solve_correctors, symmetry_error
from .localisation import localisation
from .percolation import percolating_solid
from .result import LOAD_CASES, HomogenizationResult, LoadCase
from .voxel_correctors import VOXEL_AUTO_DOFS, solve_voxel_correctors


def _validate(phases, size, materials, rtol):
    ph, s, present = check_phases(phases, size, materials, name="materials", item="material", integral_floats=True)
    if not (0 < float(rtol) < 1e-3):
        raise ConfigError(f"rtol: {rtol!r}: allowed range is (0, 1e-3)")
    return ph, s, present


def voxel_elements(keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Periodic hex connectivity of the voxels in ``keep``.

    Parameters
    ----------
    keep : (nx, ny, nz) bool.

    Returns
    -------
    elements : (m,) int, flat (C-order) voxel index of each element.
    nodes : (m, 8) int, compact node index of each local node (see :mod:`metasheet.fem.hex8`).
    grid_nodes : (n,) int, flat grid index ``(i ny + j) nz + k`` of each compact node.
    """
    shape = np.array(keep.shape)
    elements = np.flatnonzero(keep.ravel())
    ijk = np.stack(np.unravel_index(elements, keep.shape), axis=1)  # (m, 3)
    corner = (ijk[:, None, :] + HEX8_CORNERS[None, :, :]) % shape  # (m, 8, 3)
    flat = (corner[..., 0] * shape[1] + corner[..., 1]) * shape[2] + corner[..., 2]
    grid_nodes, inv = np.unique(flat, return_inverse=True)
    return elements, inv.reshape(-1, 8), grid_nodes


def homogenize_voxels(phases, size, materials: dict, *, solver: str = "auto", rtol: float = 1e-8,
                      axis=None, localise: bool = True) -> HomogenizationResult:
    """Effective stiffness of a periodic voxel cell.

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = ``materials[k]``.
    size : (3,) float [mm], the box's edge lengths.
    materials : dict phase -> :class:`~metasheet.mechanics.material.Isotropic` or
        :class:`~metasheet.mechanics.material.TransverseIsotropic` (its axis 3 = global z).
    solver : "auto", "direct" or "amg" (:func:`metasheet.fem.solvers.solve_spd`), or "voxel"
        (matrix-free multigrid CG, :func:`metasheet.homogenize.voxel_correctors.solve_voxel_correctors`);
        "auto" takes "voxel" from :data:`~metasheet.homogenize.voxel_correctors.VOXEL_AUTO_DOFS` unknowns.
    rtol : relative residual asked of the linear solver; ``C`` is computed in energy
        form, so its relative error is of the order of rtol squared times the condition.
    axis : (3,) the transverse-isotropic fit's axis, or None to search the best one.
    localise : keep the element strain fields (:class:`.result.Localisation`).

    Returns
    -------
    :class:`~metasheet.homogenize.result.HomogenizationResult`.

    Raises
    ------
    ConfigError : bad input. InfeasibleError : no percolating solid.
    ConvergenceError : the linear solver missed ``rtol``.
    """
    ph, size, present = _validate(phases, size, materials, rtol)
    t0 = time.perf_counter()
    h = size / np.array(ph.shape)
    v_el = float(np.prod(h))
    solid = ph > 0
    keep, _ = percolating_solid(solid)
    elements, nodes, grid_nodes = voxel_elements(keep)
    kind = np.searchsorted(present, ph.ravel()[elements])
    Cs = np.array([material_stiffness(p, materials[p]) for p in present])
    mats = [hex8_box_matrices(C, h) for C in Cs]
    Ke = np.array([m[0] for m in mats])
    Fe = np.array([m[1] for m in mats])
    Bm = np.array([m[2] for m in mats])
    volume = float(np.prod(size))
    grid = solver in GRID_SOLVERS or (solver == "auto" and 3 * len(grid_nodes) >= VOXEL_AUTO_DOFS)
    if grid:  # matrix-free on the grid: nothing to assemble
        dofs = element_dofs(nodes)
        t1 = time.perf_counter()
        try:
            C, C_raw, U_grid, report = solve_voxel_correctors(np.where(keep, ph, 0), size, dict(zip(present, Cs)),
                                                              solver="voxel" if solver == "auto" else solver,
                                                              rtol=rtol)
            U = U_grid.reshape(-1, 3, 6)[grid_nodes].reshape(-1, 6)
        except ConfigError:  # a cell the split coarsening refuses: "auto" assembles instead
            if solver != "auto":
                raise
            grid = False
    if not grid:
        pattern = SparsityPattern.from_elements(nodes, len(grid_nodes))
        dofs = pattern.dofs
        K = pattern.assemble(Ke, kind)
        F = pattern.assemble_vector(Fe, kind)
        counts = np.bincount(kind, minlength=len(present))
        c_vol = np.einsum("p,pij->ij", counts * v_el, Cs)
        coords = np.stack(np.unravel_index(grid_nodes, ph.shape), axis=1) * h
        t1 = time.perf_counter()
        C, C_raw, U, report = solve_correctors(K, F, c_vol, volume, coords=coords, solver=solver, rtol=rtol)
    t2 = time.perf_counter()
    fit = check_and_fit(C, axis)
    loc = None
    if localise:
        strain = np.eye(6)[None] + np.einsum("mij,mjI->mIi", Bm[kind], U[dofs])
        loc = localisation(strain, np.full(len(elements), v_el))
    t3 = time.perf_counter()
    cases = tuple(
        LoadCase(name, report.solver, it, res)
        for name, it, res in zip(LOAD_CASES, report.iterations or (0,) * 6, report.residuals)
    )
    return HomogenizationResult(
        C=C,
        C_raw=C_raw,
        fit=fit,
        relative_density=float(solid.mean()),
        removed_fraction=float(1.0 - keep.sum() / solid.sum()),
        symmetry_error=symmetry_error(C_raw),
        load_cases=cases,
        solver=report.solver,
        n_dof=report.n_dof,
        n_elements=len(elements),
        resolution=tuple(int(n) for n in ph.shape),
        localisation=loc,
        element_ids=elements,
        timings={"assembly": t1 - t0, "setup": report.setup_seconds, "solve": report.solve_seconds,
                 "post": t3 - t2},
    )
