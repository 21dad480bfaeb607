"""Fused vector kernels of CG and the Chebyshev smoother, on compact blocks (a, 3, m).

numpy evaluates ``d = a d + b (dinv r); x = x + d`` as four passes with three temporaries; here
each is one numba loop that reads every vector once. All of them run over the nodes with
``prange`` and do each node's arithmetic exactly as the numpy expression they replace (same
operations, same order, no fastmath): element-wise results have the numpy bits on any thread
count.

Reductions (dot products, column sums) cut the nodes into fixed blocks of :data:`BLOCK`
nodes, sum each block in node order (in parallel), then add the block sums in block order:
the blocks do not depend on the thread count, so neither do the bits.
"""

from __future__ import annotations

import numba
import numpy as np

#: Nodes per block of a reduction (fixed: the summation order must not depend on the threads).
BLOCK = 2048


def dots(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m,) column dot products of two (n, 3, m) blocks, in a fixed order."""
    return _dots(a, b)


def column_sums(a: np.ndarray) -> np.ndarray:
    """(3, m) sums over the nodes of an (n, 3, m) block, in a fixed order."""
    return _column_sums(a)


@numba.njit(cache=True, parallel=True)
def _dots(a, b):
    n, _, m = a.shape
    nb = (n + BLOCK - 1) // BLOCK
    part = np.zeros((nb, m))
    for blk in numba.prange(nb):
        acc = np.zeros(m)
        for i in range(blk * BLOCK, min(n, (blk + 1) * BLOCK)):
            for c in range(3):
                for l in range(m):
                    acc[l] += a[i, c, l] * b[i, c, l]
        part[blk] = acc
    out = np.zeros(m)
    for blk in range(nb):
        out += part[blk]
    return out


@numba.njit(cache=True, parallel=True)
def _column_sums(a):
    n, _, m = a.shape
    nb = (n + BLOCK - 1) // BLOCK
    part = np.zeros((nb, 3, m))
    for blk in numba.prange(nb):
        acc = np.zeros((3, m))
        for i in range(blk * BLOCK, min(n, (blk + 1) * BLOCK)):
            for c in range(3):
                for l in range(m):
                    acc[c, l] += a[i, c, l]
        part[blk] = acc
    out = np.zeros((3, m))
    for blk in range(nb):
        out += part[blk]
    return out


@numba.njit(cache=True, parallel=True)
def subtract_mean(v, mean):
    """``v[i] -= mean`` for every node i: v (n, 3, m), mean (3, m); in place."""
    for i in numba.prange(v.shape[0]):
        for c in range(3):
            for l in range(v.shape[2]):
                v[i, c, l] -= mean[c, l]


@numba.njit(cache=True, parallel=True)
def cg_step(x, r, p, q, alpha):
    """``x += alpha p; r -= alpha q``, column l with its own alpha[l] (m,); in place."""
    for i in numba.prange(x.shape[0]):
        for c in range(3):
            for l in range(x.shape[2]):
                x[i, c, l] += alpha[l] * p[i, c, l]
                r[i, c, l] -= alpha[l] * q[i, c, l]


@numba.njit(cache=True, parallel=True)
def cg_direction(p, z, beta):
    """``p = z + beta p``, beta (m,); in place on p."""
    for i in numba.prange(p.shape[0]):
        for c in range(3):
            for l in range(p.shape[2]):
                p[i, c, l] = z[i, c, l] + beta[l] * p[i, c, l]


@numba.njit(cache=True, parallel=True)
def subtract(r, y):
    """``r -= y``; in place on r."""
    for i in numba.prange(r.shape[0]):
        for c in range(3):
            for l in range(r.shape[2]):
                r[i, c, l] -= y[i, c, l]


@numba.njit(cache=True, parallel=True)
def residual(b, y):
    """``b - y``, a new block."""
    out = np.empty_like(b)
    for i in numba.prange(b.shape[0]):
        for c in range(3):
            for l in range(b.shape[2]):
                out[i, c, l] = b[i, c, l] - y[i, c, l]
    return out


@numba.njit(cache=True, parallel=True)
def chebyshev_first(x, r, dinv, theta):
    """First Chebyshev step: ``d = dinv r / theta; x += d``; returns d (x: in place)."""
    d = np.empty_like(r)
    for i in numba.prange(r.shape[0]):
        for c in range(3):
            w = dinv[i, c]
            for l in range(r.shape[2]):
                t = w * r[i, c, l] / theta
                d[i, c, l] = t
                x[i, c, l] += t
    return d


@numba.njit(cache=True, parallel=True)
def chebyshev_next(x, d, r, dinv, a, b):
    """Next Chebyshev step: ``d = a d + b (dinv r); x += d``; in place on d and x."""
    for i in numba.prange(r.shape[0]):
        for c in range(3):
            w = dinv[i, c]
            for l in range(r.shape[2]):
                t = a * d[i, c, l] + b * (w * r[i, c, l])
                d[i, c, l] = t
                x[i, c, l] += t


@numba.njit(cache=True, parallel=True)
def jacobi_step(x, r, dinv, w0):
    """Damped Jacobi: ``dx = w0 (dinv r); x += dx``; returns dx (x: in place)."""
    dx = np.empty_like(r)
    for i in numba.prange(r.shape[0]):
        for c in range(3):
            w = dinv[i, c]
            for l in range(r.shape[2]):
                t = w0 * (w * r[i, c, l])
                dx[i, c, l] = t
                x[i, c, l] += t
    return dx
