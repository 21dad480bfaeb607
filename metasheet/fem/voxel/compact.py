"""Vectors on the active nodes only: the node map and ``K u`` on compact blocks.

At 15 % solid about three grid nodes in four carry no unknown. A full-grid block
(Nx, Ny, Nz, 3, m) then spends most of its memory and element-wise work on zeros. The solver
keeps its vectors compact instead: (a, 3, m) on the ``a`` active nodes (a node is active when
at least one of its dofs is free), in grid (C) order. The operator's sweep is the same as
:mod:`.operator`'s with its corner nodes renumbered through the node map (-1: an inactive
corner, read as zero, never written), so it visits the voxels and adds their contributions in
the same order: on the active dofs ``apply`` has the bits of :meth:`.VoxelOperator.apply`, except
that a level whose voxels share one matrix (the finest, one phase) multiplies chunks of voxels
by BLAS (twice as fast; bits set by the BLAS kernel, still independent of the thread count).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .operator import VoxelOperator


@dataclass(frozen=True)
class CompactOperator:
    """``op`` on compact vectors.

    Attributes
    ----------
    op : the full-grid operator.
    active : (a,) int64, flat grid node ``(i Ny + j) Nz + k`` of each compact node, increasing.
    node_map : (Nx Ny Nz,) int64, compact index of each grid node, -1 where inactive.
    free : (a, 3) float in {0, 1}, the unknowns.
    nodes : (v, 8) int64, the sweep's corner nodes in compact numbering (-1: inactive).
    gemm : all voxels share one matrix (one phase): the sweep multiplies by BLAS, chunk by chunk.
    """

    op: VoxelOperator
    active: np.ndarray
    node_map: np.ndarray
    free: np.ndarray
    nodes: np.ndarray
    gemm: bool

    @property
    def size(self) -> int:
        """Number of active nodes a."""
        return len(self.active)

    def apply(self, u: np.ndarray) -> np.ndarray:
        """``free * K (free * u)``: (a, 3, m) [mm] -> (a, 3, m) [N]."""
        if u.ndim != 3 or u.shape[:2] != (self.size, 3):
            raise ValueError(f"u: shape is {u.shape} and should be {(self.size, 3, 'm')}")
        y = np.zeros(u.shape)
        sw = self.op.sweep
        _apply(np.ascontiguousarray(u, dtype=float), self.free, self.nodes, sw.matrix, sw.matrices_t, sw.scale,
               sw.start, sw.wrap_odd, self.gemm, y)
        return y

    def to_compact(self, v: np.ndarray) -> np.ndarray:
        """(Nx, Ny, Nz, 3[, m]) -> (a, 3[, m]): the active nodes' values."""
        return np.ascontiguousarray(v.reshape((-1,) + v.shape[3:])[self.active])

    def to_full(self, v: np.ndarray) -> np.ndarray:
        """(a, 3[, m]) -> (Nx, Ny, Nz, 3[, m]), zero on inactive nodes."""
        out = np.zeros((len(self.node_map),) + v.shape[1:])
        out[self.active] = v
        return out.reshape(self.op.node_shape + v.shape[1:])


def compact(op: VoxelOperator, *, gemm: bool = True) -> CompactOperator:
    """The :class:`CompactOperator` of ``op``: active nodes = nodes with a free dof.
    gemm: use BLAS when every voxel has the same matrix (False: the operator's own bits)."""
    free = op.free.reshape(-1, 3)
    active = np.flatnonzero(free.any(axis=1)).astype(np.int64)
    node_map = np.full(len(free), -1, np.int64)
    node_map[active] = np.arange(len(active))
    return CompactOperator(op, active, node_map, np.ascontiguousarray(free[active]), node_map[op.sweep.nodes],
                           bool(len(op.matrices) == 1 and gemm))


# --------------------------------------------------------------------------- kernels
# As operator._slab/_apply, with compact corner numbers: -1 reads zero and is not written.

#: Voxels per GEMM of a one-matrix sweep: bounds its gathered block to CHUNK * m * 24 floats.
CHUNK = 2048


@numba.njit(cache=True)
def _gather(v, nodes, u, free, ue, row):
    """ue[row + l, 3 a + c] = free * u at corner a of voxel v, for the m columns l."""
    for a in range(8):
        n = nodes[v, a]
        for c in range(3):
            for l in range(u.shape[2]):
                ue[row + l, 3 * a + c] = free[n, c] * u[n, c, l] if n >= 0 else 0.0


@numba.njit(cache=True)
def _scatter(v, nodes, s, ye, row, y):
    """y at corner a of voxel v += s * ye[row + l, 3 a + c]."""
    for a in range(8):
        n = nodes[v, a]
        if n < 0:
            continue
        for c in range(3):
            for l in range(y.shape[2]):
                y[n, c, l] += s * ye[row + l, 3 * a + c]


@numba.njit(cache=True)
def _slab(v0, v1, u, free, nodes, matrix, mats_t, scale, y):
    """Voxels v0:v1 with their own matrices: y_e = sum_q K_e[:, q] u_q in order q = 0..23
    (the bits of operator._slab), one column l at a time so y_e stays in registers."""
    m = u.shape[2]
    ue = np.empty((m, 24))
    ye = np.empty((m, 24))
    for v in range(v0, v1):
        _gather(v, nodes, u, free, ue, 0)
        Ke = mats_t[matrix[v]]
        for l in range(m):
            yl = ye[l]
            ul = ue[l]
            for r in range(24):
                yl[r] = 0.0
            for q in range(24):
                uq = ul[q]
                for r in range(24):
                    yl[r] += Ke[q, r] * uq
        _scatter(v, nodes, scale[v], ye, 0, y)


@numba.njit(cache=True)
def _slab_gemm(v0, v1, u, free, nodes, mats_t, scale, y):
    """Voxels v0:v1 sharing one matrix (the finest level of one phase): gather CHUNK voxels'
    (m, 24) blocks, one BLAS product with K_e^T, scatter. About twice the speed of _slab;
    the bits depend on the BLAS kernel but not on the thread count (chunks are fixed)."""
    m = u.shape[2]
    K = mats_t[0].astype(np.float64)  # a float32 table (a preconditioner's) meets float64 vectors
    for c0 in range(v0, v1, CHUNK):
        c1 = min(v1, c0 + CHUNK)
        ue = np.empty(((c1 - c0) * m, 24))
        for v in range(c0, c1):
            _gather(v, nodes, u, free, ue, (v - c0) * m)
        ye = np.dot(ue, K)  # row (v, l): sum_q u_q K_e[:, q]
        for v in range(c0, c1):
            _scatter(v, nodes, scale[v], ye, (v - c0) * m, y)


@numba.njit(cache=True)
def _one_slab(i, u, free, nodes, matrix, mats_t, scale, start, gemm, y):
    if gemm:
        _slab_gemm(start[i], start[i + 1], u, free, nodes, mats_t, scale, y)
    else:
        _slab(start[i], start[i + 1], u, free, nodes, matrix, mats_t, scale, y)


@numba.njit(cache=True, parallel=True)
def _apply(u, free, nodes, matrix, mats_t, scale, start, wrap_odd, gemm, y):
    nx = len(start) - 1
    n_pair = nx - 1 if wrap_odd else nx
    for parity in range(2):  # slabs of one parity share no node: parallel, order-free
        for t in numba.prange((n_pair - parity + 1) // 2):
            _one_slab(parity + 2 * t, u, free, nodes, matrix, mats_t, scale, start, gemm, y)
    if wrap_odd:
        _one_slab(nx - 1, u, free, nodes, matrix, mats_t, scale, start, gemm, y)
    for n in numba.prange(y.shape[0]):
        for c in range(3):
            f = free[n, c]
            for l in range(y.shape[2]):
                y[n, c, l] *= f
