"""Connectivity-split trilinear prolongation (metasheet.fem.voxel.split).

A coarse node whose support holds two solid parts gets one copy per part; the copies still sum
to the trilinear weight, so translations are interpolated exactly; the sparse coarse operator is
the explicit ``P3^T K P3``; and the split coarse space fixes the two-level convergence on walls
one voxel apart that the unsplit trilinear space ties together.
"""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from metasheet.fem.voxel.coarsen import cell_bounds, node_weights
from metasheet.fem.voxel.compact import compact
from metasheet.fem.voxel.element import phase_table
from metasheet.fem.voxel.operator import VoxelOperator, touched_nodes
from metasheet.fem.voxel.split import assemble, galerkin, split_prolongation
from metasheet.mechanics.material import Isotropic

TPU = Isotropic(12.0, 0.3)


def _cop(index, periodic, scale=None):
    table = phase_table(TPU.stiffness(), np.array([0.3, 0.3, 0.3]))
    free = np.repeat(touched_nodes(index, periodic)[..., None], 3, axis=3).astype(float)
    sc = np.ones(index.shape) if scale is None else scale
    return compact(VoxelOperator(index, table.K, sc, periodic, free, table.h))


def _walls(n=8, gap=1):
    """Two x-normal walls, one voxel thick, ``gap`` voxels apart, periodic in y and z."""
    index = np.full((n, n, n), -1, np.int64)
    index[2] = 0
    index[3 + gap] = 0
    return index


def _trilinear(cop):
    """(a, c) dense unsplit trilinear P on the active coarse nodes (periodic), for comparison."""
    op = cop.op
    bounds = [cell_bounds(n, True) for n in op.index.shape]
    W = [node_weights(b, n, True) for b, n in zip(bounds, op.node_shape)]
    Nc = [len(b) - 1 for b in bounds]
    P = np.zeros((cop.size, int(np.prod(Nc))))
    for i, flat in enumerate(cop.active):
        f = np.unravel_index(flat, op.node_shape)
        for a in range(8):
            w, idx = 1.0, []
            for d in range(3):
                lo, hi, wl, wh = W[d]
                bit = (a >> d) & 1
                w *= (wh if bit else wl)[f[d]]
                idx.append((hi if bit else lo)[f[d]])
            P[i, np.ravel_multi_index(idx, Nc)] += w
    return P[:, P.any(axis=0)]


def test_two_walls_one_voxel_apart_get_separate_copies():
    cop = _cop(_walls(gap=1), True)
    s = split_prolongation(cop)
    # every coarse x-plane between the walls sees both: one copy per wall there
    Pt = _trilinear(cop)
    assert s.P.shape[1] > Pt.shape[1]
    P = s.P.toarray()
    x = cop.active // (cop.op.node_shape[1] * cop.op.node_shape[2])
    wall_a, wall_b = np.isin(x, [2, 3]), np.isin(x, [4, 5])
    for j in range(P.shape[1]):  # no copy acts on both walls
        assert not (P[wall_a, j].any() and P[wall_b, j].any())


@pytest.mark.parametrize("connectivity", ["face", "edge", "node"])
@pytest.mark.parametrize("periodic", [True, False])
def test_copies_sum_to_trilinear_weight(connectivity, periodic):
    rng = np.random.default_rng(3)
    index = np.where(rng.random((7, 6, 8)) < 0.45, 0, -1).astype(np.int64)
    cop = _cop(index, periodic)
    s = split_prolongation(cop, connectivity=connectivity)
    assert np.allclose(s.P.sum(axis=1), 1.0)  # translations exactly interpolated
    assert s.position.shape == (s.P.shape[1], 3)


def test_galerkin_is_explicit_product():
    rng = np.random.default_rng(5)
    index = np.where(rng.random((6, 8, 7)) < 0.5, 0, -1).astype(np.int64)
    cop = _cop(index, True, rng.uniform(0.5, 2.0, index.shape))
    K = assemble(cop)
    u = rng.standard_normal((cop.size, 3, 1))
    assert np.allclose(K @ u.ravel(), cop.apply(u).ravel(), rtol=0, atol=1e-12 * np.abs(cop.apply(u)).max())
    s = split_prolongation(cop)
    P3 = np.kron(s.P.toarray(), np.eye(3))
    assert np.allclose(galerkin(K, s).toarray(), P3.T @ K.toarray() @ P3, rtol=0, atol=1e-12 * abs(K).max())


def _two_level_iterations(K, P3, rhs):
    """CG iterations with a two-level preconditioner: Jacobi pre/post, exact coarse solve."""
    Ac = (P3.T @ K @ P3).tocsc()
    keep = np.arange(3, Ac.shape[0])  # pin one coarse node: the walls' translations
    lu = spla.splu(Ac[keep][:, keep])
    dinv = 0.6 / K.diagonal()

    def prec(r):
        x = dinv * r
        rc = P3.T @ (r - K @ x)
        xc = np.zeros(Ac.shape[0])
        xc[keep] = lu.solve(rc[keep])
        x = x + P3 @ xc
        return x + dinv * (r - K @ x)

    count = [0]
    M = spla.LinearOperator(K.shape, prec)
    spla.cg(K, rhs, M=M, rtol=1e-8, maxiter=400, callback=lambda _: count.__setitem__(0, count[0] + 1))
    return count[0]


def test_split_space_converges_on_thin_walls():
    """Measured: 18 iterations split, 215 with the copies merged back (unsplit trilinear)."""
    index = _walls(n=12, gap=1)
    index[:, 5, :] = -1  # a cut across y: no periodic wrap, the walls clamped at z = 0
    cop = _cop(index, False)
    K = assemble(cop)
    z = cop.active % cop.op.node_shape[2]
    keep = np.flatnonzero(~np.repeat(z == 0, 3))
    K = K[keep][:, keep].tocsr()
    rhs = np.random.default_rng(0).standard_normal(len(keep))
    s = split_prolongation(cop)
    _, merge = np.unique(np.ravel_multi_index(s.position.T, s.coarse_nodes), return_inverse=True)
    merge = sp.csr_matrix((np.ones(len(merge)), (np.arange(len(merge)), merge.ravel())))
    unsplit = sp.kron(s.P @ merge, sp.eye(3), format="csr")
    n_split = _two_level_iterations(K, s.P3[keep].tocsr(), rhs)
    n_unsplit = _two_level_iterations(K, unsplit[keep].tocsr(), rhs)
    assert n_split <= 30
    assert n_unsplit > 4 * n_split


def _graph_parts(index, occ, cflat, periodic, reach):
    """The parts by an explicit graph of the (voxel, corner) pairs and scipy's connected
    components: the independent reference of split._parts' union-find."""
    from scipy.sparse.csgraph import connected_components

    nv, S = len(occ), np.array(index.shape)
    vid = np.full(index.shape, -1, np.int64)
    vid[tuple(occ.T)] = np.arange(nv)
    rows, cols = [], []
    for o in np.ndindex(3, 3, 3):
        o = np.array(o) - 1
        if not reach[0] <= np.abs(o).sum() <= reach[1]:
            continue  # both orders of each pair: the graph is undirected anyway
        nb = occ + o
        inside = np.ones(nv, bool) if periodic else np.all((nb >= 0) & (nb < S), axis=1)
        w = np.full(nv, -1, np.int64)
        w[inside] = vid[tuple((nb[inside] % S).T)]
        v1 = np.flatnonzero(w >= 0)
        for a in range(8):
            for b in range(8):
                same = cflat[v1, a] == cflat[w[v1], b]
                rows.append(8 * v1[same] + a)
                cols.append(8 * w[v1][same] + b)
    G = sp.coo_matrix((np.ones(sum(map(len, rows))), (np.concatenate(rows), np.concatenate(cols))), (8 * nv,) * 2)
    return connected_components(G, directed=False)[1].reshape(nv, 8)


def test_parts_union_find_equals_the_graph_components():
    """Random solids, periodic or not, each connectivity, coarse grids down to one node along an
    axis (a voxel's corners then repeat): the same labels, numbered alike."""
    from metasheet.fem.voxel.split import CONNECTIVITY, _parts

    rng = np.random.default_rng(0)
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])
    for _ in range(5):
        shape = tuple(int(n) for n in rng.integers(2, 12, 3))
        index = np.where(rng.random(shape) < rng.uniform(0.2, 0.7), 0, -1)
        occ = np.argwhere(index >= 0)
        Nc = np.maximum(np.array(shape) // 2, 1)
        cn = (occ[:, None, :] // 2 + corners) % Nc
        cflat = (cn[..., 0] * Nc[1] + cn[..., 1]) * Nc[2] + cn[..., 2]
        for periodic in (True, False):
            for reach in CONNECTIVITY.values():
                assert np.array_equal(_parts(index, occ, cflat, periodic, reach),
                                      _graph_parts(index, occ, cflat, periodic, reach))


def test_node_parts_equal_the_graph_components():
    """The homogenisation's node parts (union-find) against scipy's components of the explicit
    node graph (each voxel joins its 8 nodes), periodic or not, on solids with several pieces."""
    from scipy.sparse.csgraph import connected_components

    from metasheet.homogenize.voxel_periodic import node_parts
    from metasheet.fem.voxel.operator import node_shape

    rng = np.random.default_rng(1)
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])
    pieces = []
    for periodic in (True, False):
        for _ in range(4):
            index = np.where(rng.random(tuple(int(n) for n in rng.integers(3, 10, 3))) < 0.15, 0, -1)
            N = node_shape(index.shape, periodic)
            nodes = (np.argwhere(index >= 0)[:, None, :] + corners) % np.array(N)
            flat = (nodes[..., 0] * N[1] + nodes[..., 1]) * N[2] + nodes[..., 2]
            n = int(np.prod(N))
            G = sp.coo_matrix((np.ones(7 * len(flat)), (np.repeat(flat[:, 0], 7), flat[:, 1:].ravel())), (n, n))
            lab = connected_components(G, directed=False)[1]
            touched = np.zeros(n, bool)
            touched[flat.ravel()] = True
            used, want = np.unique(np.where(touched, lab, -1), return_inverse=True)
            want = want.reshape(-1) - (1 if used[0] == -1 else 0)
            got, count = node_parts(index, periodic)
            assert np.array_equal(got.ravel(), want) and count == int((used >= 0).sum())
            pieces.append(count)
    assert max(pieces) > 1  # several pieces are what the test is about
