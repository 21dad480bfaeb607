"""The multi-level split hierarchy (metasheet.fem.voxel.split_levels, .blocks, .split_hierarchy).

Every level's transfer keeps translations exact (rows sum to 1, so the product of the
prolongations maps 1 to 1), the block Galerkin operators equal explicit ``P^T K P`` products,
the solver's C* equals the trilinear default's, its bits do not depend on the thread count, and
walls a voxel apart need fewer iterations than with the trilinear hierarchy.
"""

import itertools

import numba
import numpy as np
import pytest
from homogenize_samples import edge_foam
from test_voxel_split import _cop, _walls
from test_voxel_split_solver import _close_walls, _percolating, _rel
from threadpoolctl import threadpool_limits

from metasheet.fem.voxel import split_hierarchy
from metasheet.homogenize.voxel_periodic import periodic_stiffness
from metasheet.fem.voxel.blocks import (
    bsr_apply,
    csr_apply,
    galerkin_blocks,
    galerkin_voxels,
    to_bsr,
)
from metasheet.fem.voxel.split import assemble, galerkin, split_prolongation
from metasheet.fem.voxel.split_hierarchy import build_split_hierarchy
from metasheet.fem.voxel.split_levels import (
    Copies,
    coarser_grid,
    copy_prolongation,
    fine_grid,
    split_parts,
)
from metasheet.mechanics.material import Isotropic

TPU = Isotropic(12.0, 0.3)
UNIT = (1.0, 1.0, 1.0)


def _foam_cop(n=16, density=0.12, seed=2):
    ph = _percolating(edge_foam(n, density, seeds=8, rng_seed=seed))
    return _cop(np.where(ph > 0, 0, -1).astype(np.int64), True)


def _levels(cop):
    """[(P_k, grid_k)] for k = 1.. as the hierarchy builds them, down to the last coarsenable grid."""
    op = cop.op
    occ = np.argwhere(op.index >= 0)
    s = split_prolongation(cop)
    grid = coarser_grid(fine_grid(occ, op.index.shape, op.h), True)
    out, copies = [(s.P, grid)], Copies(s.position, s.rep)
    while (nxt := coarser_grid(grid, True)) is not None:
        part, cf = split_parts(op.index, occ, nxt, True)
        P, copies = copy_prolongation(copies, grid, nxt, part, cf, True)
        out.append((P, nxt))
        grid = nxt
    return out


@pytest.mark.parametrize("sample", ["foam", "walls"])
def test_every_level_interpolates_translations_exactly(sample):
    cop = _foam_cop() if sample == "foam" else _cop(_walls(n=16, gap=1), True)
    levels = _levels(cop)
    assert len(levels) >= 3
    ones = np.ones((levels[-1][0].shape[1], 3, 1))
    for P, _ in levels:
        assert np.allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0, rtol=0, atol=1e-14)
    for P, _ in reversed(levels):  # P_1 ... P_L 1 = 1 on every fine node
        ones = csr_apply(P, ones)
    assert np.allclose(ones, 1.0, rtol=0, atol=1e-13)


def test_walls_one_voxel_apart_stay_split_on_coarse_levels():
    cop = _cop(_walls(n=16, gap=1), True)
    (_, _), (P2, g2) = _levels(cop)[:2]
    # walls at voxels x = 2 and 4, level-2 nodes at x = 0, 4, 8, 12: node 4's support holds both
    # walls (two copies), nodes 0 and 8 one wall each, node 12 none; 4 x 4 nodes in y and z
    assert g2.nodes == (4, 4, 4)
    assert P2.shape[1] == (1 + 2 + 1) * 16


def test_block_galerkin_equals_explicit_products():
    cop = _foam_cop(12, 0.2, 0)
    op = cop.op
    s = split_prolongation(cop)
    grid = coarser_grid(fine_grid(np.argwhere(op.index >= 0), op.index.shape, op.h), True)
    cflat = (grid.cell[:, 0] * grid.shape[1] + grid.cell[:, 1]) * grid.shape[2] + grid.cell[:, 2]
    A1 = galerkin_voxels(cop.nodes, op.sweep.matrix, op.sweep.scale, op.matrices, cop.free, cflat, s.P)
    ref = galerkin(assemble(cop), s).toarray()
    got = to_bsr(*A1).toarray()
    assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()
    _, (P2, _) = _levels(cop)[:2]
    A2 = galerkin_blocks(*A1, P2)
    P3 = s.__class__(P2, s.position, s.coarse_nodes, s.rep).P3.toarray()
    ref2 = P3.T @ got @ P3
    assert np.abs(to_bsr(*A2).toarray() - ref2).max() <= 1e-12 * np.abs(ref2).max()
    x = np.random.default_rng(0).standard_normal((P2.shape[1], 3, 2))
    y = bsr_apply(*A2, x)
    assert np.allclose(y.reshape(-1, 2), ref2 @ x.reshape(-1, 2), rtol=0, atol=1e-10 * np.abs(ref2).max())


@pytest.fixture
def many_levels(monkeypatch):
    """Factorise only below 150 unknowns: small cells get three or more split levels."""
    monkeypatch.setattr(split_hierarchy, "DIRECT_DOFS", 150)


@pytest.mark.parametrize("n, density, seed, levels", [
    (12, 0.2, 0, 3),  # measured: fine + two split levels
    pytest.param(16, 0.12, 2, 4, marks=pytest.mark.slow),
    pytest.param(16, 0.2, 0, 4, marks=pytest.mark.slow),
])
def test_multilevel_split_matches_trilinear(many_levels, n, density, seed, levels):
    """The slow 16^3 cases' default-selection sibling: the 12^3 case."""
    ph = _percolating(edge_foam(n, density, seeds=8, rng_seed=seed))
    ref = periodic_stiffness(ph, UNIT, {1: TPU.stiffness()}, rtol=1e-10, coarsening="trilinear")
    r = periodic_stiffness(ph, UNIT, {1: TPU.stiffness()}, rtol=1e-10, coarsening="split")
    assert len(r.levels) >= levels  # fine + at least (levels - 1) split levels
    assert _rel(r.C, ref.C) < 1e-10
    assert max(r.residuals) <= 1e-9


@pytest.mark.parametrize("n", [12, pytest.param(None, marks=pytest.mark.slow)])
def test_multilevel_split_fewer_iterations_on_close_walls(many_levels, n):
    """The slow case (_close_walls' default size)'s default-selection sibling: the n = 12 case
    (measured: split 19, trilinear 25 iterations)."""
    ph = _close_walls() if n is None else _close_walls(n)
    ref = periodic_stiffness(ph, UNIT, {1: TPU.stiffness()}, rtol=1e-10, coarsening="trilinear")
    r = periodic_stiffness(ph, UNIT, {1: TPU.stiffness()}, rtol=1e-10, coarsening="split")
    assert len(r.levels) >= 3
    assert _rel(r.C, ref.C) < 1e-10
    assert max(r.iterations) < max(ref.iterations)


def test_multilevel_split_same_bits_on_one_and_two_threads(many_levels):
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with one thread")
    ph = _close_walls(12)
    before = numba.get_num_threads()
    out = []
    try:
        for t in (1, 2):
            numba.set_num_threads(t)
            out.append(periodic_stiffness(ph, UNIT, {1: TPU.stiffness()}, coarsening="split"))
    finally:
        numba.set_num_threads(before)
    a, b = out
    assert np.array_equal(a.C, b.C) and np.array_equal(a.U, b.U) and a.iterations == b.iterations


def test_hierarchy_levels_shrink_to_the_direct_limit():
    cop = _foam_cop()
    with threadpool_limits(1, "blas"):
        H = build_split_hierarchy(cop, direct_dofs=150)
    u = H.unknowns
    assert len(u) >= 3 and all(b < a for a, b in itertools.pairwise(u))
    assert u[-2] > 150


def test_solve_voxel_correctors_passes_the_coarsening():
    from metasheet.errors import ConfigError
    from metasheet.homogenize.voxel_correctors import solve_voxel_correctors

    ph = _percolating(edge_foam(12, 0.25, seeds=6, rng_seed=0))
    C_split, _, _, rep_split = solve_voxel_correctors(ph, UNIT, {1: TPU.stiffness()}, rtol=1e-10)
    C_tri, _, _, rep_tri = solve_voxel_correctors(ph, UNIT, {1: TPU.stiffness()}, rtol=1e-10, coarsening="trilinear")
    assert _rel(C_split, C_tri) < 1e-10
    assert max(rep_split.iterations) < max(rep_tri.iterations)
    with pytest.raises(ConfigError, match="coarsening"):
        solve_voxel_correctors(ph, UNIT, {1: TPU.stiffness()}, coarsening="smoothed")


def test_stalled_coarsening_is_refused(monkeypatch):
    from metasheet.errors import ConfigError

    monkeypatch.setattr(split_hierarchy, "MAX_BOTTOM_DOFS", 100)
    with pytest.raises(ConfigError, match="trilinear"), threadpool_limits(1, "blas"):
        build_split_hierarchy(_foam_cop(), max_levels=1)
