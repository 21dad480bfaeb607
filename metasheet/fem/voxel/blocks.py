"""Sparse levels of the split hierarchy: 3 x 3 block matrices and scalar transfers, in numba.

Below the finest voxel level the split coarse spaces (:mod:`.split_levels`) are no voxel grids,
so their operators are assembled: block CSR (BSR) matrices with one (3, 3) block per pair of
coupled node copies, stored as ``indptr (n + 1,)``, ``indices (nnzb,)`` (sorted in each row) and
``data (nnzb, 3, 3)`` [N/mm]. Vectors are the solver's (n, 3, m) blocks, m right-hand sides.

Every kernel writes each output row from one iteration, summing its terms in the stored order,
so the bits do not depend on the thread count; no fastmath.

- :func:`bsr_apply`: ``y = A x``;
- :func:`csr_apply`: ``y (+)= w T x`` for a scalar CSR ``T`` (a prolongation or its transpose)
  acting on each of the 3 components;
- :func:`galerkin_voxels`: the first split level's ``P3^T K P3`` built from the fine voxels
  coarse cell by coarse cell, without assembling the fine ``K`` (which took 3 GB on the paper cell);
- :func:`galerkin_blocks`: ``P3^T A P3`` of a BSR ``A`` by a scalar CSR ``P`` (row-wise
  Gustavson product, two passes: pattern, then values).
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp


def bsr_apply(indptr, indices, data, x: np.ndarray) -> np.ndarray:
    """``A x`` for a BSR ``A`` (n, n) blocks of (3, 3) and x (n, 3, m): a new (n, 3, m) block."""
    y = np.zeros((len(indptr) - 1, 3, x.shape[2]), x.dtype)
    _bsr_apply(indptr, indices, data, np.ascontiguousarray(x), y)
    return y


def bsr_diagonal(indptr, indices, data) -> np.ndarray:
    """(n, 3) diagonal of a BSR matrix [N/mm] (0 where a row has no diagonal block)."""
    d = np.zeros((len(indptr) - 1, 3))
    _bsr_diag(indptr, indices, data, d)
    return d


def csr_apply(T: sp.csr_matrix, x: np.ndarray, out: np.ndarray | None = None,
              mask: np.ndarray | None = None) -> np.ndarray:
    """``T x`` per component for scalar CSR ``T`` (r, c) and x (c, 3, m); with ``out`` (r, 3, m),
    ``out += mask * T x`` in place (mask (r, 3) in {0, 1}, None: 1) and returned."""
    add = out is not None
    if out is None:
        out = np.zeros((T.shape[0], 3, x.shape[2]), x.dtype)
    m = np.ones((1, 3)) if mask is None else mask
    _csr_apply(T.indptr, T.indices, T.data, np.ascontiguousarray(x), add, m, mask is not None, out)
    return out


def to_bsr(indptr, indices, data) -> sp.bsr_matrix:
    """The scipy (3 n, 3 n) view of a BSR triple (for tests and the direct solve)."""
    n = len(indptr) - 1
    return sp.bsr_matrix((data, indices, indptr), shape=(3 * n, 3 * n))


# --------------------------------------------------------------------------- Galerkin products


def galerkin_voxels(nodes, matrix, scale, mats, free, cell, P: sp.csr_matrix):
    """``P3^T K P3`` as BSR, from the fine voxels without assembling ``K``.

    Parameters
    ----------
    nodes : (v, 8) int64, compact fine node of each voxel corner (-1: inactive, no stiffness).
    matrix : (v,) int64 row of ``mats``; scale : (v,) float; mats : (q, 24, 24) [N/mm].
    free : (a, 3) in {0, 1}; cell : (v,) int64, the coarse cell of each voxel (its copies are
        those of that cell's corners, so each cell's product is one small dense block).
    P : (a, c) csr, scalar prolongation of the copies.

    Returns
    -------
    (indptr, indices, data) of the (c, c) block matrix, data (nnzb, 3, 3) [N/mm].
    """
    order = np.argsort(cell, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(cell[order]) != 0, True])
    # pattern: copies coupled when they meet in one coarse cell
    Pv = P[nodes[order].ravel()] if nodes.min() >= 0 else P[np.maximum(nodes[order], 0).ravel()]
    cell_of = np.repeat(np.repeat(np.arange(len(starts) - 1), np.diff(starts)), 8)
    M = sp.csr_matrix((np.ones(Pv.nnz, np.int8), Pv.indices, Pv.indptr), Pv.shape)
    M = sp.csr_matrix((np.ones(M.nnz), (np.repeat(cell_of, np.diff(M.indptr)), M.indices)),
                      (len(starts) - 1, P.shape[1]))
    G = (M.T @ M).tocsr()
    G.sort_indices()
    indptr, indices = G.indptr.astype(np.int64), G.indices.astype(np.int64)
    data = np.zeros((len(indices), 3, 3))
    _galerkin_cells(order, starts, nodes, matrix, scale, mats, free, P.indptr, P.indices, P.data, indptr, indices,
                    data)
    return indptr, indices, data


def galerkin_blocks(indptr, indices, data, P: sp.csr_matrix):
    """``P3^T A P3`` for BSR ``A`` (n, n) and scalar csr ``P`` (n, c): BSR (c, c) triple."""
    R = P.T.tocsr()
    R.sort_indices()
    Pi, Pj, Pw = P.indptr, P.indices, P.data
    cptr = np.zeros(R.shape[0] + 1, np.int64)
    _spgemm_count(R.indptr, R.indices, indptr, indices, Pi, Pj, P.shape[1], cptr)
    cind = np.empty(cptr[-1], np.int64)
    cdat = np.zeros((cptr[-1], 3, 3))
    _spgemm_fill(R.indptr, R.indices, R.data, indptr, indices, data, Pi, Pj, Pw, P.shape[1], cptr, cind, cdat)
    return cptr, cind, cdat


# --------------------------------------------------------------------------- kernels


#: Rows per parallel task of the row-wise kernels (one accumulator allocation per task).
ROWS = 256


@numba.njit(cache=True, parallel=True)
def _bsr_apply(indptr, indices, data, x, y):
    n, m = len(indptr) - 1, x.shape[2]
    for t in numba.prange((n + ROWS - 1) // ROWS):
        acc = np.empty((3, m), x.dtype)  # the row's sums in registers, not in y
        for i in range(t * ROWS, min(n, (t + 1) * ROWS)):
            acc[:] = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                for c in range(3):
                    for d in range(3):
                        a = data[p, c, d]
                        for l in range(m):
                            acc[c, l] += a * x[j, d, l]
            for c in range(3):
                for l in range(m):
                    y[i, c, l] = acc[c, l]


@numba.njit(cache=True)
def _bsr_diag(indptr, indices, data, d):
    for i in range(len(indptr) - 1):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] == i:
                for c in range(3):
                    d[i, c] = data[p, c, c]


@numba.njit(cache=True, parallel=True)
def _csr_apply(indptr, indices, w, x, add, mask, masked, out):
    n, m = len(indptr) - 1, x.shape[2]
    for t in numba.prange((n + ROWS - 1) // ROWS):
        acc = np.empty((3, m), x.dtype)
        for i in range(t * ROWS, min(n, (t + 1) * ROWS)):
            acc[:] = 0.0
            for p in range(indptr[i], indptr[i + 1]):  # each (c, l) summed in entry order
                j, wp = indices[p], w[p]
                for c in range(3):
                    for l in range(m):
                        acc[c, l] += wp * x[j, c, l]
            for c in range(3):
                f = mask[i, c] if masked else 1.0
                for l in range(m):
                    if add:
                        out[i, c, l] += f * acc[c, l]
                    else:
                        out[i, c, l] = acc[c, l]


@numba.njit(cache=True)
def _find(indices, lo, hi, j):
    """Position of column j in the sorted indices[lo:hi] (binary search; j is there)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if indices[mid] <= j:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _galerkin_cells(order, starts, nodes, matrix, scale, mats, free, Pi, Pj, Pw, indptr, indices, data):
    """Per coarse cell (in order): local copies L, B = sum_e (P_e x I3)^T K_e (P_e x I3), scatter B."""
    loc = np.full(len(indptr) - 1, -1, np.int64)  # copy -> local index in the current cell
    L = np.empty(len(indptr) - 1, np.int64)
    Km = np.empty((24, 24))
    for g in range(len(starts) - 1):
        nl = 0
        for t in range(starts[g], starts[g + 1]):
            v = order[t]
            for a in range(8):
                n = nodes[v, a]
                if n < 0:
                    continue
                for p in range(Pi[n], Pi[n + 1]):
                    j = Pj[p]
                    if loc[j] < 0:
                        loc[j] = nl
                        L[nl] = j
                        nl += 1
        B = np.zeros((3 * nl, 3 * nl))
        T = np.empty((24, 3 * nl))
        for t in range(starts[g], starts[g + 1]):
            v = order[t]
            s = scale[v]
            e = matrix[v]
            for r in range(24):
                fr = free[nodes[v, r // 3], r % 3] if nodes[v, r // 3] >= 0 else 0.0
                for q in range(24):
                    fq = free[nodes[v, q // 3], q % 3] if nodes[v, q // 3] >= 0 else 0.0
                    Km[r, q] = s * mats[e, r, q] * fr * fq
            T[:] = 0.0  # T = Km (P_e x I3)
            for a in range(8):
                n = nodes[v, a]
                if n < 0:
                    continue
                for p in range(Pi[n], Pi[n + 1]):
                    col, w = loc[Pj[p]], Pw[p]
                    for c in range(3):
                        for r in range(24):
                            T[r, 3 * col + c] += w * Km[r, 3 * a + c]
            for a in range(8):  # B += (P_e x I3)^T T
                n = nodes[v, a]
                if n < 0:
                    continue
                for p in range(Pi[n], Pi[n + 1]):
                    row, w = loc[Pj[p]], Pw[p]
                    for c in range(3):
                        for q in range(3 * nl):
                            B[3 * row + c, q] += w * T[3 * a + c, q]
        for x in range(nl):
            i = L[x]
            for y in range(nl):
                p = _find(indices, indptr[i], indptr[i + 1], L[y])
                for c in range(3):
                    for d in range(3):
                        data[p, c, d] += B[3 * x + c, 3 * y + d]
        for x in range(nl):
            loc[L[x]] = -1


@numba.njit(cache=True)
def _spgemm_count(Ri, Rj, Ai, Aj, Pi, Pj, nc, cptr):
    mark = np.full(nc, -1, np.int64)
    for I in range(len(Ri) - 1):
        count = 0
        for p in range(Ri[I], Ri[I + 1]):
            i = Rj[p]
            for q in range(Ai[i], Ai[i + 1]):
                j = Aj[q]
                for s in range(Pi[j], Pi[j + 1]):
                    J = Pj[s]
                    if mark[J] != I:
                        mark[J] = I
                        count += 1
        cptr[I + 1] = cptr[I] + count


@numba.njit(cache=True)
def _spgemm_fill(Ri, Rj, Rw, Ai, Aj, Ad, Pi, Pj, Pw, nc, cptr, cind, cdat):
    """Row I of R A P: terms summed in the order (R entry, A entry, P entry); columns sorted after."""
    slot = np.full(nc, -1, np.int64)
    acc = np.zeros((nc, 3, 3))
    for I in range(len(Ri) - 1):
        k = cptr[I]
        for p in range(Ri[I], Ri[I + 1]):
            i, wr = Rj[p], Rw[p]
            for q in range(Ai[i], Ai[i + 1]):
                j = Aj[q]
                for s in range(Pi[j], Pi[j + 1]):
                    J, w = Pj[s], wr * Pw[s]
                    if slot[J] < 0:
                        slot[J] = k
                        cind[k] = J
                        k += 1
                    for c in range(3):
                        for d in range(3):
                            acc[J, c, d] += w * Ad[q, c, d]
        cols = np.sort(cind[cptr[I]:k])
        for t in range(len(cols)):
            J = cols[t]
            cind[cptr[I] + t] = J
            for c in range(3):
                for d in range(3):
                    cdat[cptr[I] + t, c, d] = acc[J, c, d]
                    acc[J, c, d] = 0.0
            slot[J] = -1

