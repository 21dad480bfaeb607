"""Periodic homogenisation on node-matched periodic tetrahedral meshes (P1).

The mesh is assembled as a plain (non-periodic) mesh, then made periodic with the
explicit projection P of :mod:`.periodic`: ``K_p = P^T K P``, ``f_p = P^T f``. Parts
that do not wrap around the box in every direction are dropped (they carry no
macroscopic stress). The corrector problem is in :mod:`.corrector`.

:func:`voxels_to_tets` builds such a mesh from a voxel grid (Kuhn split of each
voxel into 6 tets), the independent geometry used to cross-check the voxel route.
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from ..errors import ConfigError, InfeasibleError
from ..fem.assembly import SparsityPattern
from ..fem.tet4 import tet4_matrices
from .corrector import check_and_fit, material_stiffness, solve_correctors, symmetry_error
from .localisation import localisation
from .periodic import periodic_masters, projection, wrapping_parts
from .result import LOAD_CASES, HomogenizationResult, LoadCase


def homogenize_mesh(points, tets, materials: dict, phase=None, *, size, origin=None,
                    solver: str = "auto", rtol: float = 1e-8, axis=None, localise: bool = True,
                    tol: float | None = None) -> HomogenizationResult:
    """Effective stiffness of a node-matched periodic tet mesh of the solid.

    Parameters
    ----------
    points : (n, 3) float [mm], inside the box ``[origin, origin + size]``; nodes on
        opposite faces must match.
    tets : (m, 4) int, linear tetrahedra of the solid (no void elements).
    materials : dict phase -> Isotropic / TransverseIsotropic (axis 3 = global z).
    phase : (m,) int phase of each tet, default all 1.
    size : (3,) float [mm], the periodic box (voids included in |Y|).
    origin : (3,) float [mm], default ``points.min(axis=0)``.
    solver, rtol, axis, localise : as :func:`~metasheet.homogenize.homogenize_voxels`.
    tol : node-matching tolerance [mm], default 1e-6 max(size).

    Returns
    -------
    :class:`~metasheet.homogenize.result.HomogenizationResult`; its
    ``relative_density`` is the tet volume over the box volume.
    """
    p = np.asarray(points, float)
    t = np.asarray(tets)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ConfigError(f"points: shape is {p.shape} and should be (n, 3)")
    if t.ndim != 2 or t.shape[1] != 4 or not np.issubdtype(t.dtype, np.integer):
        raise ConfigError(f"tets: shape {t.shape}, dtype {t.dtype}: expected (m, 4) int")
    if len(t) == 0 or t.min() < 0 or t.max() >= len(p):
        raise ConfigError(f"tets: indices must lie in [0, {len(p) - 1}] and m > 0")
    ph = np.ones(len(t), np.int64) if phase is None else np.asarray(phase).astype(np.int64)
    if ph.shape != (len(t),):
        raise ConfigError(f"phase: shape is {ph.shape} and should be ({len(t)},)")
    present = [int(k) for k in np.unique(ph)]
    missing = [k for k in present if k not in materials]
    if missing:
        raise ConfigError(f"materials: phases {missing} have no material (given: {sorted(materials)})")
    L = np.asarray(size, float).reshape(-1)
    if L.shape != (3,) or not np.all(np.isfinite(L)) or np.any(L <= 0):
        raise ConfigError(f"size: {size!r}: must be three finite lengths > 0 [mm]")

    t0 = time.perf_counter()
    master, shift, n_master = periodic_masters(p, L, origin, tol)
    keep, _ = wrapping_parts(t, len(p), master, shift)
    if not keep.any():
        raise InfeasibleError("tets: the solid does not percolate: no part wraps around the box in x, y and z")
    volume = float(np.prod(L))
    Cs = np.array([material_stiffness(k, materials[k]) for k in present])
    kind_all = np.searchsorted(present, ph)
    _, _, _, vol_all = tet4_matrices(p, t, Cs[kind_all])
    elements = np.flatnonzero(keep)
    tk, kind = t[elements], kind_all[elements]
    Ke, Fe, B, vol = tet4_matrices(p, tk, Cs[kind])
    pattern = SparsityPattern.from_elements(tk, len(p))
    dofs = pattern.dofs
    K = pattern.assemble(Ke)
    F = pattern.assemble_vector(Fe)
    P = projection(master, n_master)
    Kp = (P.T @ K @ P).tocsr()
    Fp = P.T @ F
    # drop masters no kept tet touches (isolated or removed nodes)
    used = np.zeros(n_master, bool)
    used[master[tk.ravel()]] = True
    ud = (3 * np.flatnonzero(used)[:, None] + np.arange(3)).ravel()
    Kp, Fp = Kp[ud][:, ud], Fp[ud]
    coords = np.zeros((n_master, 3))
    coords[master] = p - shift * L
    c_vol = np.einsum("m,mij->ij", vol, Cs[kind])
    t1 = time.perf_counter()
    C, C_raw, Up, report = solve_correctors(Kp, Fp, c_vol, volume, coords=coords[used], solver=solver, rtol=rtol)
    t2 = time.perf_counter()
    fit = check_and_fit(C, axis)
    loc = None
    if localise:
        U = np.zeros((3 * n_master, 6))
        U[ud] = Up
        U = P @ U
        strain = np.eye(6)[None] + np.einsum("mij,mjI->mIi", B, U[dofs])
        loc = localisation(strain, vol)
    t3 = time.perf_counter()
    cases = tuple(
        LoadCase(name, report.solver, it, res)
        for name, it, res in zip(LOAD_CASES, report.iterations, report.residuals)
    )
    return HomogenizationResult(
        C=C, C_raw=C_raw, fit=fit,
        relative_density=float(vol_all.sum() / volume),
        removed_fraction=float(1.0 - vol.sum() / vol_all.sum()),
        symmetry_error=symmetry_error(C_raw),
        load_cases=cases, solver=report.solver, n_dof=report.n_dof, n_elements=len(elements),
        resolution=(len(t),), localisation=loc, element_ids=elements,
        timings={"assembly": t1 - t0, "setup": report.setup_seconds, "solve": report.solve_seconds,
                 "post": t3 - t2},
    )


#: Kuhn split of the unit cube into 6 tets along the diagonal 0 -> 7 (local node
#: a = ax + 2 ay + 4 az); neighbouring cubes split this way are conforming.
KUHN_TETS = np.array([
    [0, 1 << s[0], (1 << s[0]) | (1 << s[1]), 7] for s in itertools.permutations(range(3))
])


def voxels_to_tets(phases, size) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node-matched periodic tet mesh of the solid voxels (6 Kuhn tets per voxel).

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void.
    size : (3,) float [mm].

    Returns
    -------
    points : (n, 3) float [mm] in [0, size]; tets : (m, 4) int; phase : (m,) int.
    """
    ph = np.asarray(phases)
    shape = np.array(ph.shape)
    h = np.asarray(size, float) / shape
    elements = np.flatnonzero(ph.ravel() > 0)
    ijk = np.stack(np.unravel_index(elements, ph.shape), axis=1)
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])
    node_ijk = ijk[:, None, :] + corners[None]  # (m, 8, 3) on the (n+1)^3 grid
    flat = (node_ijk[..., 0] * (shape[1] + 1) + node_ijk[..., 1]) * (shape[2] + 1) + node_ijk[..., 2]
    grid, inv = np.unique(flat, return_inverse=True)
    inv = inv.reshape(-1, 8)
    tets = inv[:, KUHN_TETS].reshape(-1, 4)
    points = np.stack(np.unravel_index(grid, tuple(shape + 1)), axis=1) * h
    phase = np.repeat(ph.ravel()[elements], len(KUHN_TETS))
    return points, tets, phase
