"""The matrix-free voxel stiffness operator ``y = K u``, for several right-hand sides at once.

A grid of ``(nx, ny, nz)`` voxels; voxel ``(i, j, k)`` holds the row ``index[i, j, k]`` of a
table of (24, 24) element matrices (-1: empty, no stiffness) times a scale. On the finest
level the table has one matrix per phase and the scale is the voxel's modulus factor; on
the Galerkin coarse levels of :mod:`.multigrid` each coarse voxel has its own matrix and the
scale is 1. Nothing is assembled: ``K u`` gathers the voxel's 8 nodes, multiplies, and
scatters back.

Vectors are (Nx, Ny, Nz, 3) arrays or, for ``m`` right-hand sides at once (the six load
cases), (Nx, Ny, Nz, 3, m): one pass over the voxels then reads each element matrix once for
all of them. Nodes: a periodic grid has ``(nx, ny, nz)`` nodes (voxel ``i`` uses nodes ``i``
and ``(i + 1) mod nx``, as :func:`metasheet.homogenize.voxels.voxel_elements`); a non-periodic
one ``(nx + 1, ny + 1, nz + 1)``. C order, so the flat dof ``3 ((i Ny + j) Nz + k) + c`` is the
assembled path's numbering.

Threads and bits. The voxels are swept slab by slab (a slab: one ``i``). A slab writes only
node planes ``i`` and ``i + 1``, so all even slabs can run in parallel, then all odd slabs
(numba ``prange``), then, on a periodic grid of odd ``nx``, the last slab, which shares plane 0
with slab 0. Every node therefore receives its contributions in one fixed order (the pass,
then the serial order inside its slab) whatever the number of threads: the same bits on 1 or
16 threads. The element product is written as 24 column updates ``y_e += K_e[:, q] u_q``,
which LLVM vectorises without reassociating a sum (no fastmath: the same bits on any CPU).

``free`` (Nx, Ny, Nz, 3) in {0, 1} marks the unknowns: a dof is not free when no non-empty
voxel touches it (void: it carries no unknown, exactly as in the assembled path, which
removes void voxels) or when it is prescribed (clamped or tied to a rigid body).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np


@dataclass(frozen=True)
class VoxelOperator:
    """One level's stiffness, matrix-free.

    Attributes
    ----------
    index : (nx, ny, nz) int64, row of ``matrices`` per voxel, -1 where empty.
    matrices : (q, 24, 24) float [N/mm], element stiffnesses.
    scale : (nx, ny, nz) float [-], factor on each voxel's matrix.
    periodic : bool, node ``n`` wraps to node 0 in every direction.
    free : (Nx, Ny, Nz, 3) float in {0, 1}, the unknowns.
    h : (3,) float [mm], voxel edge lengths (used to choose the coarsening).
    """

    index: np.ndarray
    matrices: np.ndarray
    scale: np.ndarray
    periodic: bool
    free: np.ndarray
    h: np.ndarray

    @property
    def node_shape(self) -> tuple[int, int, int]:
        return node_shape(self.index.shape, self.periodic)

    @property
    def n_free(self) -> int:
        """Number of unknowns."""
        return int(self.free.sum())

    @cached_property
    def sweep(self) -> Sweep:
        """The non-empty voxels in slab order, built on first use (:func:`voxel_sweep`)."""
        return voxel_sweep(self)

    def apply(self, u: np.ndarray) -> np.ndarray:
        """``free * K (free * u)``: (Nx, Ny, Nz, 3[, m]) [mm] -> same shape [N]."""
        return _apply_op(self, u, masked=True)


@dataclass(frozen=True)
class Sweep:
    """What the kernel walks: the non-empty voxels in slab order.

    Attributes
    ----------
    nodes : (v, 8) int64, flat node ``(i Ny + j) Nz + k`` of each corner ``a = ax + 2 ay + 4 az``.
    matrix : (v,) int64, row of ``matrices_t``; scale : (v,) float, factor on it.
    start : (nx + 1,) int64, voxels of slab ``i`` are ``start[i]:start[i + 1]``.
    matrices_t : (q, 24, 24) float, the element matrices transposed (column ``q`` contiguous).
    wrap_odd : a periodic grid of odd ``nx``: its last slab meets slab 0.
    """

    nodes: np.ndarray
    matrix: np.ndarray
    scale: np.ndarray
    start: np.ndarray
    matrices_t: np.ndarray
    wrap_odd: bool


def voxel_sweep(op: VoxelOperator) -> Sweep:
    """The :class:`Sweep` of ``op``: (v, 8) corner nodes etc. of its v non-empty voxels."""
    nodes, flat, start = _sweep(op.index, np.array(op.node_shape, np.int64))
    return Sweep(nodes, op.index.reshape(-1)[flat], np.ascontiguousarray(op.scale.reshape(-1)[flat]), start,
                 np.ascontiguousarray(op.matrices.transpose(0, 2, 1)),
                 bool(op.periodic and op.index.shape[0] % 2 == 1))


def node_shape(voxel_shape, periodic: bool) -> tuple[int, int, int]:
    """Nodes per direction of a voxel grid."""
    return tuple(int(n) if periodic else int(n) + 1 for n in voxel_shape)


def apply_full(op: VoxelOperator, u: np.ndarray) -> np.ndarray:
    """``K u`` with every dof (prescribed ones too): (Nx, Ny, Nz, 3[, m]) [mm] -> same shape [N]."""
    return _apply_op(op, u, masked=False)


def _apply_op(op: VoxelOperator, u: np.ndarray, masked: bool) -> np.ndarray:
    N = op.node_shape
    if u.shape[:4] != N + (3,) or u.ndim not in (4, 5):
        raise ValueError(f"u: shape is {u.shape} and should be {N + (3,)} or {N + (3, 'm')}")
    n = int(np.prod(N))
    m = 1 if u.ndim == 4 else u.shape[4]
    flat = np.ascontiguousarray(u, dtype=float).reshape(n, 3, m)
    y = np.zeros_like(flat)
    sw = op.sweep
    _apply(flat, op.free.reshape(n, 3), masked, sw.nodes, sw.matrix, sw.matrices_t, sw.scale, sw.start,
           sw.wrap_odd, y)
    return y.reshape(u.shape)


def diagonal(op: VoxelOperator) -> np.ndarray:
    """(Nx, Ny, Nz, 3) diagonal of ``K`` [N/mm] (0 where no voxel touches a node)."""
    d = np.zeros(op.node_shape + (3,))
    _diagonal(op.index, op.matrices, op.scale, d)
    return d


def scatter(index: np.ndarray, table: np.ndarray, scale: np.ndarray, periodic: bool) -> np.ndarray:
    """Assemble per-voxel nodal vectors ``scale * table[index]`` (q, 24, r) into (Nx, Ny, Nz, 3, r)."""
    N = node_shape(index.shape, periodic)
    return scatter_compact(index, table, scale, periodic, np.arange(int(np.prod(N)))).reshape(N + (3, table.shape[2]))


def scatter_compact(index: np.ndarray, table: np.ndarray, scale: np.ndarray, periodic: bool,
                    node_map: np.ndarray) -> np.ndarray:
    """:func:`scatter` onto the compact nodes of ``node_map`` (Nx Ny Nz,) -> compact index or -1:
    (a, 3, r), the same sums in the same order (the same bits), without the full grid."""
    out = np.zeros((int(node_map.max()) + 1, 3, table.shape[2]))
    N = node_shape(index.shape, periodic)
    _scatter_compact(index, np.ascontiguousarray(table), scale, node_map.reshape(N), out)
    return out


def touched_nodes(index: np.ndarray, periodic: bool) -> np.ndarray:
    """(Nx, Ny, Nz) bool: nodes of at least one non-empty voxel."""
    t = np.zeros(node_shape(index.shape, periodic), np.bool_)
    _touch(index, t)
    return t


# --------------------------------------------------------------------------- kernels
# Node a of voxel (i, j, k) is ((i + ax) mod Nx, ...): the modulo is the periodic wrap on a
# periodic grid (Nx = nx) and a no-op on a non-periodic one (Nx = nx + 1).


@numba.njit(cache=True)
def _nodes(i, j, k, Nx, Ny, Nz, out):
    for a in range(8):
        out[a, 0] = (i + (a & 1)) % Nx
        out[a, 1] = (j + ((a >> 1) & 1)) % Ny
        out[a, 2] = (k + ((a >> 2) & 1)) % Nz


@numba.njit(cache=True)
def _sweep(index, N):
    nx, ny, nz = index.shape
    count = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if index[i, j, k] >= 0:
                    count += 1
    nodes = np.empty((count, 8), np.int64)
    flat = np.empty(count, np.int64)
    start = np.zeros(nx + 1, np.int64)
    nd = np.empty((8, 3), np.int64)
    v = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if index[i, j, k] < 0:
                    continue
                _nodes(i, j, k, N[0], N[1], N[2], nd)
                for a in range(8):
                    nodes[v, a] = (nd[a, 0] * N[1] + nd[a, 1]) * N[2] + nd[a, 2]
                flat[v] = (i * ny + j) * nz + k
                v += 1
        start[i + 1] = v
    return nodes, flat, start


@numba.njit(cache=True)
def _slab(v0, v1, u, free, masked, nodes, matrix, mats_t, scale, y):
    """Voxels v0:v1 (one slab), in order: y += s K_e (free u)_e, for m right-hand sides."""
    m = u.shape[2]
    ue = np.empty((m, 24))
    ye = np.empty((m, 24))
    for v in range(v0, v1):
        e = matrix[v]
        for a in range(8):
            n = nodes[v, a]
            for c in range(3):
                f = free[n, c] if masked else 1.0
                for l in range(m):
                    ue[l, 3 * a + c] = f * u[n, c, l]
        ye[:] = 0.0
        for q in range(24):  # y_e += K_e[:, q] u_q: vectorised over the 24 rows, sum order q = 0..23
            kq = mats_t[e, q]
            for l in range(m):
                uq = ue[l, q]
                yl = ye[l]
                for r in range(24):
                    yl[r] += kq[r] * uq
        s = scale[v]
        for a in range(8):
            n = nodes[v, a]
            for c in range(3):
                for l in range(m):
                    y[n, c, l] += s * ye[l, 3 * a + c]


@numba.njit(cache=True, parallel=True)
def _apply(u, free, masked, nodes, matrix, mats_t, scale, start, wrap_odd, y):
    nx = len(start) - 1
    n_pair = nx - 1 if wrap_odd else nx
    for parity in range(2):  # slabs of one parity share no node: parallel, order-free
        for t in numba.prange((n_pair - parity + 1) // 2):
            i = parity + 2 * t
            _slab(start[i], start[i + 1], u, free, masked, nodes, matrix, mats_t, scale, y)
    if wrap_odd:
        _slab(start[nx - 1], start[nx], u, free, masked, nodes, matrix, mats_t, scale, y)
    if masked:
        for n in numba.prange(y.shape[0]):
            for c in range(3):
                f = free[n, c]
                for l in range(y.shape[2]):
                    y[n, c, l] *= f


@numba.njit(cache=True)
def _diagonal(index, mats, scale, d):
    nx, ny, nz = index.shape
    Nx, Ny, Nz = d.shape[0], d.shape[1], d.shape[2]
    nd = np.empty((8, 3), np.int64)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                e = index[i, j, k]
                if e < 0:
                    continue
                _nodes(i, j, k, Nx, Ny, Nz, nd)
                for a in range(8):
                    for c in range(3):
                        d[nd[a, 0], nd[a, 1], nd[a, 2], c] += scale[i, j, k] * mats[e, 3 * a + c, 3 * a + c]


@numba.njit(cache=True)
def _scatter_compact(index, table, scale, node_map, out):
    nx, ny, nz = index.shape
    Nx, Ny, Nz = node_map.shape
    r = table.shape[2]
    nd = np.empty((8, 3), np.int64)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                e = index[i, j, k]
                if e < 0:
                    continue
                _nodes(i, j, k, Nx, Ny, Nz, nd)
                for a in range(8):
                    n = node_map[nd[a, 0], nd[a, 1], nd[a, 2]]
                    if n < 0:
                        continue
                    for c in range(3):
                        for m in range(r):
                            out[n, c, m] += scale[i, j, k] * table[e, 3 * a + c, m]


@numba.njit(cache=True)
def _touch(index, t):
    nx, ny, nz = index.shape
    Nx, Ny, Nz = t.shape
    nd = np.empty((8, 3), np.int64)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if index[i, j, k] < 0:
                    continue
                _nodes(i, j, k, Nx, Ny, Nz, nd)
                for a in range(8):
                    t[nd[a, 0], nd[a, 1], nd[a, 2]] = True
