"""The matrix-free voxel operator and its Galerkin coarsening, against explicit matrices.

``K u`` voxel by voxel must equal the assembled stiffness of the homogenisation path; the
coarse voxel matrices must equal ``P^T K P`` formed with the explicit prolongation, on
periodic and non-periodic grids, even and odd sizes, with prescribed dofs removed.
"""

import numpy as np
import pytest

from metasheet.fem.assembly import SparsityPattern
from metasheet.fem.voxel.coarsen import (
    choose_directions,
    coarse_operator,
    prolong,
    restrict,
)
from metasheet.fem.voxel.element import phase_table
from metasheet.fem.voxel.operator import (
    VoxelOperator,
    apply_full,
    diagonal,
    touched_nodes,
)
from metasheet.homogenize.voxels import voxel_elements
from metasheet.mechanics.material import Isotropic

TPU = Isotropic(12.0, 0.3)
SOFT = Isotropic(1.5, 0.45)


def _grid(shape, periodic, seed=0, fixed_fraction=0.0):
    rng = np.random.default_rng(seed)
    ph = (rng.random(shape) < 0.6).astype(np.int64) + (rng.random(shape) < 0.3)
    table = phase_table([TPU.stiffness(), SOFT.stiffness()], np.array([0.5, 0.4, 0.3]))
    index = ph - 1  # 0 void -> -1
    scale = rng.uniform(0.5, 2.0, shape)
    touched = touched_nodes(index, periodic)
    fixed = (rng.random(touched.shape + (3,)) < fixed_fraction) & touched[..., None]
    free = (touched[..., None] & ~fixed).astype(float)
    return VoxelOperator(index, table.K, scale, periodic, free, table.h), fixed, ph, table


def _dense(op: VoxelOperator) -> np.ndarray:
    n = op.free.size
    A = np.zeros((n, n))
    e = np.zeros(n)
    for j in range(n):
        e[j] = 1.0
        A[:, j] = apply_full(op, e.reshape(op.free.shape)).ravel()
        e[j] = 0.0
    return A


def test_apply_equals_the_assembled_stiffness():
    op, _, ph, table = _grid((4, 5, 3), True)
    keep = ph > 0
    elements, nodes, grid_nodes = voxel_elements(keep)
    pattern = SparsityPattern.from_elements(nodes, len(grid_nodes))
    Ke = table.K * 1.0
    kind = ph.ravel()[elements] - 1
    # per-voxel scale: assemble one scaled matrix per element
    K = pattern.assemble(Ke[kind] * op.scale.ravel()[elements][:, None, None], np.arange(len(elements)))
    dofs = (3 * grid_nodes[:, None] + np.arange(3)).ravel()
    u = np.random.default_rng(1).normal(size=op.free.shape)
    y = apply_full(op, u).reshape(-1)
    np.testing.assert_allclose(y[dofs], K @ u.reshape(-1)[dofs], rtol=0, atol=1e-12 * np.abs(y).max())
    np.testing.assert_allclose(diagonal(op).reshape(-1)[dofs], K.diagonal(), rtol=1e-14)


@pytest.mark.parametrize("shape, periodic", [
    ((6, 4, 5), True),
    ((3, 4, 5), False),  # the default selection's non-periodic, odd-sized case
    pytest.param((5, 4, 7), False, marks=pytest.mark.slow),
    ((4, 6, 4), True),
])
def test_galerkin_coarse_operator_is_ptkp(shape, periodic):
    """The slow (5, 4, 7) case's default-selection sibling: the (3, 4, 5) non-periodic case."""
    op, fixed, _, _ = _grid(shape, periodic, seed=2, fixed_fraction=0.0 if periodic else 0.15)
    dirs = choose_directions(op.index.shape, op.h, periodic)
    coarse, fixed_c, transfer = coarse_operator(op, fixed, dirs)
    nc = coarse.free.size
    P = np.zeros((op.free.size, nc))
    e = np.zeros(nc)
    for j in range(nc):
        e[j] = 1.0
        P[:, j] = prolong(e.reshape(coarse.free.shape), transfer, op.node_shape).ravel()
        e[j] = 0.0
    mf = (op.free.ravel() > 0).astype(float)
    free_c = coarse.free.ravel() > 0
    Pm = mf[:, None] * P * (~fixed_c.ravel())[None, :]
    expected = Pm.T @ _dense(op) @ Pm
    got = _dense(coarse)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(got[np.ix_(free_c, free_c)], expected[np.ix_(free_c, free_c)], rtol=0, atol=1e-12 * scale)
    # restriction is the transpose of prolongation
    r = np.random.default_rng(3).normal(size=op.free.shape)
    np.testing.assert_allclose(restrict(r, transfer, coarse.node_shape).ravel(), P.T @ r.ravel(), atol=1e-12)


def test_semi_coarsening_of_elongated_voxels():
    assert choose_directions((8, 8, 8), (0.1, 0.1, 0.3), True) == (True, True, False)
    assert choose_directions((8, 8, 8), (0.2, 0.2, 0.3), True) == (True, True, True)
    assert choose_directions((3, 8, 8), (0.1, 0.1, 0.1), True) == (False, True, True)
