"""Compact vectors and fused kernels of the voxel solver (metasheet.fem.voxel.compact, .vectors).

The solver keeps its vectors on the active nodes only and updates them in fused numba loops.
Each kernel must give the bits of the full-grid path it replaced (the operator with its own
per-voxel sums, the transfers, the numpy expressions of CG and Chebyshev), except the BLAS
sweep of one-matrix levels (to rounding), and the same bits on one and two numba threads.
"""

import numba
import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from metasheet.fem.voxel import vectors as vec
from metasheet.fem.voxel.coarsen import (
    coarse_operator,
    prolong,
    prolong_add_compact,
    restrict,
    restrict_compact,
)
from metasheet.fem.voxel.compact import compact
from metasheet.fem.voxel.element import phase_table
from metasheet.fem.voxel.operator import VoxelOperator, touched_nodes
from metasheet.mechanics.material import Isotropic

TPU = Isotropic(12.0, 0.3)
CASES = [((7, 6, 5), True), ((8, 5, 6), True), ((6, 5, 4), False)]


def _op(shape, periodic, seed=4, fixed_fraction=0.0):
    rng = np.random.default_rng(seed)
    index = np.where(rng.random(shape) < 0.6, 0, -1).astype(np.int64)
    table = phase_table(TPU.stiffness(), np.array([0.5, 0.4, 0.3]))
    touched = touched_nodes(index, periodic)
    fixed = (rng.random(touched.shape) < fixed_fraction)[..., None] & np.ones(3, bool)
    free = (touched[..., None] & ~fixed).astype(float)
    return VoxelOperator(index, table.K, rng.uniform(0.5, 2.0, shape), periodic, free, table.h), fixed


def _both_thread_counts(f):
    """f() on 1 then 2 numba threads (skip when numba has one)."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with one thread")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = f()
        numba.set_num_threads(2)
        two = f()
    finally:
        numba.set_num_threads(before)
    return one, two


@pytest.mark.parametrize("shape, periodic", CASES)
def test_compact_apply_has_the_operator_bits(shape, periodic):
    op, fixed = _op(shape, periodic, fixed_fraction=0.0 if periodic else 0.2)
    u = np.random.default_rng(1).standard_normal(op.free.shape + (6,))
    full = op.apply(u)
    own = compact(op, gemm=False)
    assert np.array_equal(own.to_full(own.apply(own.to_compact(u))), full)
    # the BLAS sweep of a one-matrix level: same product to rounding
    with threadpool_limits(1, "blas"):
        blas = compact(op)
        assert blas.gemm
        np.testing.assert_allclose(blas.to_full(blas.apply(blas.to_compact(u))), full, rtol=0,
                                   atol=1e-13 * np.abs(full).max())
    # a Galerkin coarse level (one matrix per voxel) never takes the BLAS path
    coarse, _, _ = coarse_operator(op, fixed, (True, True, False))
    cc = compact(coarse)
    uc = np.random.default_rng(2).standard_normal(coarse.free.shape + (6,))
    assert not cc.gemm and np.array_equal(cc.to_full(cc.apply(cc.to_compact(uc))), coarse.apply(uc))


@pytest.mark.parametrize("shape, periodic", CASES)
def test_compact_transfers_have_the_full_bits(shape, periodic):
    op, fixed = _op(shape, periodic, fixed_fraction=0.0 if periodic else 0.2)
    coarse, _, transfer = coarse_operator(op, fixed, (True, True, True))
    f, c = compact(op), compact(coarse)
    rng = np.random.default_rng(3)
    r = op.free[..., None] * rng.standard_normal(op.free.shape + (6,))
    want = coarse.free[..., None] * restrict(r, transfer, coarse.node_shape)
    got = restrict_compact(f.to_compact(r), transfer, f.node_map, op.node_shape, c.node_map, coarse.node_shape, c.free)
    assert np.array_equal(c.to_full(got), want)
    xc = coarse.free[..., None] * rng.standard_normal(coarse.free.shape + (6,))
    x = op.free[..., None] * rng.standard_normal(op.free.shape + (6,))
    want = x + op.free[..., None] * prolong(xc, transfer, op.node_shape)
    xcomp = f.to_compact(x)
    prolong_add_compact(xcomp, f.free, c.to_compact(xc), transfer, f.node_map, op.node_shape, c.node_map,
                        coarse.node_shape)
    assert np.array_equal(f.to_full(xcomp), want)


def test_fused_updates_equal_numpy():
    rng = np.random.default_rng(5)
    x, r, d, p, q = (rng.standard_normal((5000, 3, 6)) for _ in range(5))
    dinv = rng.uniform(0.1, 1.0, (5000, 3))
    alpha, beta = rng.standard_normal(6), rng.standard_normal(6)
    a, b, theta = 0.7, 1.3, 2.9
    x1, d1 = x.copy(), vec.chebyshev_first(xx := x.copy(), r, dinv, theta)
    assert np.array_equal(d1, dinv[..., None] * r / theta) and np.array_equal(xx, x1 + d1)
    dd, xx = d.copy(), x.copy()
    vec.chebyshev_next(xx, dd, r, dinv, a, b)
    want = a * d + b * (dinv[..., None] * r)
    assert np.array_equal(dd, want) and np.array_equal(xx, x + want)
    xx, rr = x.copy(), r.copy()
    vec.cg_step(xx, rr, p, q, alpha)
    assert np.array_equal(xx, x + alpha * p) and np.array_equal(rr, r - alpha * q)
    pp = p.copy()
    vec.cg_direction(pp, q, beta)
    assert np.array_equal(pp, q + beta * p)
    assert np.array_equal(vec.residual(r, q), r - q)
    rr = r.copy()
    vec.subtract(rr, q)
    assert np.array_equal(rr, r - q)
    xx = x.copy()
    dx = vec.jacobi_step(xx, r, dinv, 0.4)
    assert np.array_equal(dx, 0.4 * (dinv[..., None] * r)) and np.array_equal(xx, x + dx)
    np.testing.assert_allclose(vec.dots(r, q), np.einsum("icl,icl->l", r, q), rtol=1e-12)
    np.testing.assert_allclose(vec.column_sums(r), r.sum(axis=0), rtol=1e-10, atol=1e-10)


def test_kernels_same_bits_on_one_and_two_threads():
    rng = np.random.default_rng(6)
    big = rng.standard_normal((3 * vec.BLOCK + 17, 3, 6))  # several reduction blocks
    other = rng.standard_normal(big.shape)
    op, _ = _op((9, 8, 7), True)
    u = rng.standard_normal(op.free.shape + (6,))

    def run():
        with threadpool_limits(1, "blas"):
            c = compact(op)
            return [vec.dots(big, other), vec.column_sums(big), c.apply(c.to_compact(u))]

    one, two = _both_thread_counts(run)
    assert all(np.array_equal(a, b) for a, b in zip(one, two))
