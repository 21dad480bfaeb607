"""Connectivity-split trilinear prolongation: one coarse node copy per solid part of its support.

The trilinear coarse function of coarse node ``I`` is supported on the (up to) 2 x 2 x 2
coarse voxels around ``I``. On a thin-walled foam that support can hold two walls across a
1- or 2-voxel gap, or two walls that touch only along a voxel edge; one coarse function then
moves both together, and the coarse space cannot represent their independent motion (the
cause of 224 CG iterations on a 26 x 32 x 67 crop of the paper's Polyfoam cell, docs/voxel.md).

Here the fine solid voxels of each support are split into connected parts (voxels joined
through a shared face, or edge, or node: ``connectivity``), and coarse node ``I`` gets one copy
per part. Copy ``c`` of ``I`` interpolates with ``I``'s trilinear weight onto the fine nodes of
its part's voxels only (composite finite elements, Hackbusch and Sauter, Numer. Math. 1997).
A fine node that lies in two parts of one support (two voxels joined only by an edge, split by
face connectivity) gets the weight shared equally, so the copies of ``I`` still sum to ``I``'s
trilinear weight: rigid translations stay exactly interpolated.

The coarse level is no longer a voxel grid, so its operator is an assembled sparse Galerkin
product ``P3^T K P3`` (:func:`galerkin`). Measured on the crop (two-level, coarse level solved
exactly): face connectivity 25 iterations, node connectivity 48, unsplit trilinear 163.

It is the first level of the split hierarchy (:mod:`.split_hierarchy`, ``coarsening="split"`` in
:func:`~.multigrid.build_hierarchy`); the levels below split their supports by the same fine voxel
faces (:mod:`.split_levels`). Levels coarsened by the matrix graph alone had lost most of the
gain (89 iterations on the crop, docs/voxel.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ...errors import ConfigError
from .coarsen import cell_bounds, choose_directions, node_weights
from .compact import CompactOperator
from .components import first_member_labels, union
from .operator import node_shape

#: Voxel neighbourhoods that join two voxels of one support into one part.
CONNECTIVITY = {"face": (1, 1), "edge": (1, 2), "node": (1, 3)}

_CORNERS = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])


@dataclass(frozen=True)
class SplitProlongation:
    """Scalar prolongation from coarse node copies to a level's compact nodes.

    Attributes
    ----------
    P : (a, c) csr float [-], weight of copy ``j`` on compact fine node ``i`` (same weight for
        the 3 components: :attr:`P3`).
    position : (c, 3) int64, the coarse grid node of each copy.
    coarse_nodes : (Mx, My, Mz), the coarse node grid.
    rep : (c,) int64, a solid voxel of each copy's part (row of ``np.argwhere(index >= 0)``):
        where the next split level (:mod:`.split_levels`) finds the copy's part.
    """

    P: sp.csr_matrix
    position: np.ndarray
    coarse_nodes: tuple[int, int, int]
    rep: np.ndarray

    @property
    def P3(self) -> sp.csr_matrix:
        """(3 a, 3 c) prolongation of dofs, flat ``3 node + i`` as the compact (a, 3) blocks."""
        return sp.kron(self.P, sp.eye(3), format="csr")


def split_prolongation(cop: CompactOperator, *, connectivity: str = "face", coarsen=None) -> SplitProlongation:
    """Trilinear prolongation with each coarse node split by the connectivity of its support.

    cop : the fine level on compact vectors; connectivity : "face", "edge" or "node";
    coarsen : (3,) bool directions to coarsen (None: :func:`~.coarsen.choose_directions`).
    """
    if connectivity not in CONNECTIVITY:
        raise ConfigError(f"connectivity: {connectivity!r}: allowed values are {', '.join(CONNECTIVITY)}")
    op = cop.op
    dirs = choose_directions(op.index.shape, op.h, op.periodic) if coarsen is None else tuple(coarsen)
    bounds = [cell_bounds(n, c) for n, c in zip(op.index.shape, dirs)]
    cells = [np.repeat(np.arange(len(b) - 1), np.diff(b)) for b in bounds]
    Nc = np.array(node_shape(tuple(len(b) - 1 for b in bounds), op.periodic))
    Nf = np.array(op.node_shape)
    weights = [node_weights(b, int(n), op.periodic) for b, n in zip(bounds, Nf)]
    occ = np.argwhere(op.index >= 0)
    cnode = (np.stack([cells[d][occ[:, d]] for d in range(3)], 1)[:, None, :] + _CORNERS) % Nc  # (nv, 8, 3)
    cflat = (cnode[..., 0] * Nc[1] + cnode[..., 1]) * Nc[2] + cnode[..., 2]
    part = _parts(op.index, occ, cflat, op.periodic, CONNECTIVITY[connectivity])  # (nv, 8) part of (voxel, corner)
    fnode = (occ[:, None, :] + _CORNERS) % Nf  # (nv, 8, 3) the voxel's fine nodes
    fflat = cop.node_map[(fnode[..., 0] * Nf[1] + fnode[..., 1]) * Nf[2] + fnode[..., 2]]
    lo, hi, wl, wh = (np.stack([_pad(x[k], int(Nf.max())) for x in weights]) for k in range(4))
    R, C, V, I = _pairs(fnode, cnode, fflat, part, cflat, lo, hi, wl, wh)  # about 0.4 of the pairs stay
    # one entry per (fine node, copy); the pairs as one int64 key sort as the (R, C) columns would
    # (lexicographic), 10x faster than np.unique(axis=1) on the paper cell
    first = np.unique(R * (int(C.max()) + 1) + C, return_index=True)[1]
    R, C, V, I = R[first], C[first], V[first], I[first]
    _, which, count = np.unique(R * (int(I.max()) + 1) + I, return_inverse=True, return_counts=True)
    V = V / count[which.ravel()]  # a fine node in k copies of one coarse node: weight / k
    used, C = np.unique(C, return_inverse=True)
    P = sp.csr_matrix((V, (R, C.ravel())), (cop.size, len(used)))
    where = np.zeros(int(part.max()) + 1, np.int64)
    where[part.ravel()] = cflat.ravel()
    P, first = _merge_same_support(P)
    position = np.stack(np.unravel_index(where[used][first], tuple(Nc)), 1)
    rep = np.unique(part.ravel(), return_index=True)[1] // 8  # labels are 0..n-1: first voxel of each
    return SplitProlongation(P, position, tuple(int(n) for n in Nc), rep[used][first])


def _pad(a: np.ndarray, n: int) -> np.ndarray:
    return np.concatenate([a, np.zeros(n - len(a), a.dtype)])


@numba.njit(cache=True)
def _weight(fnode, cnode, v, f, a, lo, hi, wl, wh):
    w = 1.0
    for d in range(3):
        i, t = fnode[v, f, d], cnode[v, a, d]
        w *= (wl[d, i] if lo[d, i] == t else 0.0) + (wh[d, i] if hi[d, i] == t else 0.0)
    return w


@numba.njit(cache=True)
def _pairs(fnode, cnode, fflat, part, cflat, lo, hi, wl, wh):
    """(fine node, copy, trilinear weight, coarse node) of every (coarse corner a, voxel v, fine
    corner f) with a non-zero weight on an active fine node, in that order (a, then v, then f)."""
    nv = fnode.shape[0]
    n = 0
    for a in range(8):
        for v in range(nv):
            for f in range(8):
                if fflat[v, f] >= 0 and _weight(fnode, cnode, v, f, a, lo, hi, wl, wh) != 0.0:
                    n += 1
    R, C, I = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    V = np.empty(n)
    k = 0
    for a in range(8):
        for v in range(nv):
            for f in range(8):
                if fflat[v, f] < 0:
                    continue
                w = _weight(fnode, cnode, v, f, a, lo, hi, wl, wh)
                if w != 0.0:
                    R[k], C[k], V[k], I[k] = fflat[v, f], part[v, a], w, cflat[v, a]
                    k += 1
    return R, C, V, I


def _merge_same_support(P: sp.csr_matrix) -> tuple[sp.csr_matrix, np.ndarray]:
    """Sum the copies that act on the same fine nodes, returning (P merged, (c',) first copy of each).

    Two copies of neighbouring coarse nodes can both reach a single fine node only (a part
    touching their supports at one corner, measured on the 40^3 iso foam): their columns are
    parallel and ``P^T K P`` singular. The sum keeps the weights summing to the trilinear ones."""
    Pc = P.tocsc()
    Pc.sort_indices()
    seen, group = {}, np.empty(Pc.shape[1], np.int64)
    for j in range(Pc.shape[1]):
        key = Pc.indices[Pc.indptr[j]:Pc.indptr[j + 1]].tobytes()
        group[j] = seen.setdefault(key, len(seen))
    if len(seen) == Pc.shape[1]:
        return P, np.arange(Pc.shape[1])
    first = np.unique(group, return_index=True)[1]
    M = sp.csr_matrix((np.ones(len(group)), (np.arange(len(group)), group)), (len(group), len(seen)))
    return (P @ M).tocsr(), first


def _parts(index, occ, cflat, periodic: bool, reach) -> np.ndarray:
    """(nv, 8) label of the connected part of each (voxel, coarse corner) pair: two pairs are
    joined when their voxels are neighbours (``reach``: 1 to 3 offset components) and their
    coarse corners are the same coarse node. Labels are numbered by their smallest pair
    ``8 v + a``, as scipy's ``connected_components`` numbers them."""
    nv = len(occ)
    vid = np.full(index.shape, -1, np.int64)
    vid[tuple(occ.T)] = np.arange(nv)
    offsets = np.array([o for o in (tuple(int(x) - 1 for x in t) for t in np.ndindex(3, 3, 3))
                        if reach[0] <= sum(map(abs, o)) <= reach[1] and o > (0, 0, 0)], np.int64).reshape(-1, 3)
    # each unordered pair of neighbours once: the offsets after (0, 0, 0) in lexicographic order
    return _union_parts(vid, np.ascontiguousarray(occ, np.int64), np.ascontiguousarray(cflat, np.int64),
                        bool(periodic), offsets).reshape(nv, 8)


@numba.njit(cache=True)
def _union_parts(vid, occ, cflat, periodic, offsets):
    """Union-find over the 8 nv (voxel, corner) pairs; the labels in order of first member."""
    nv = occ.shape[0]
    S = vid.shape
    parent = np.arange(8 * nv)
    for k in range(offsets.shape[0]):
        for v in range(nv):
            x, y, z = occ[v, 0] + offsets[k, 0], occ[v, 1] + offsets[k, 1], occ[v, 2] + offsets[k, 2]
            if periodic:
                x, y, z = (x + S[0]) % S[0], (y + S[1]) % S[1], (z + S[2]) % S[2]
            elif x < 0 or y < 0 or z < 0 or x >= S[0] or y >= S[1] or z >= S[2]:
                continue
            w = vid[x, y, z]
            if w < 0:
                continue
            for a in range(8):
                for b in range(8):
                    if cflat[v, a] == cflat[w, b]:
                        union(parent, 8 * v + a, 8 * w + b)
    return first_member_labels(parent)


def assemble(cop: CompactOperator) -> sp.csr_matrix:
    """(3 a, 3 a) csr [N/mm]: ``free K free`` of ``cop`` assembled on its compact dofs."""
    op = cop.op
    occ = np.argwhere(op.index >= 0)
    N = np.array(op.node_shape)
    nodes = (occ[:, None, :] + _CORNERS) % N
    cn = cop.node_map[(nodes[..., 0] * N[1] + nodes[..., 1]) * N[2] + nodes[..., 2]]
    dofs = (3 * cn[..., None] + np.arange(3)).reshape(len(occ), 24)
    Ke = op.matrices[op.index[tuple(occ.T)]] * op.scale[tuple(occ.T)][:, None, None]
    n = 3 * cop.size
    K = sp.coo_matrix((Ke.ravel(), (np.repeat(dofs, 24, 1).ravel(), np.tile(dofs, (1, 24)).ravel())), (n, n))
    D = sp.diags(cop.free.ravel())
    return (D @ K.tocsr() @ D).tocsr()


def galerkin(K: sp.spmatrix, split: SplitProlongation) -> sp.csr_matrix:
    """The coarse operator ``P3^T K P3``: (3 c, 3 c) csr [N/mm]."""
    P3 = split.P3
    return (P3.T @ K @ P3).tocsr()


#: Diagonal shift of a factorised split level, relative to its diagonal [-].
REGULARIZE = 1e-10


def _unpinned(A: sp.csr_matrix) -> np.ndarray:
    """(k,) dofs of ``A`` (3 per copy) left after pinning the first copy of every connected part
    of its graph and every dof with a zero diagonal."""
    _, label = connected_components(A, directed=False)
    copy_label = label[::3]
    first = np.unique(copy_label, return_index=True)[1]
    pinned = np.zeros(A.shape[0], bool)
    pinned[(3 * first[:, None] + np.arange(3)).ravel()] = True
    pinned |= A.diagonal() <= 0
    return np.flatnonzero(~pinned)
