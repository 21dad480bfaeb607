"""Sparse assembly with a cached sparsity pattern, and index maps into CSR data.

A :class:`SparsityPattern` is computed once (symbolically, from the element connectivity);
each assembly then only adds element blocks into the CSR ``data`` array through
:attr:`SparsityPattern.block_map` (a ``bincount``, no Python loop over elements). Every
matrix built on one pattern shares the same ``indptr``/``indices``, so callers can cache
slices (:func:`submatrix_map`), transposes (:func:`transpose_map`) and symbolic
factorisations. Used by the robot (tets, 12 dofs per element, assembled at every Newton
step) and by homogenisation (hex8 voxels, 24 dofs, assembled once, one matrix per phase).

Dofs are node-major, ``3 * node + axis`` (:mod:`metasheet.fem`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError

DOFS_PER_NODE = 3
#: Entries per ``bincount`` when element blocks are gathered from a few shared matrices
#: (``kind``): bounds the temporary instead of materialising one block per element.
_CHUNK = 1 << 22


def element_dofs(elements: np.ndarray) -> np.ndarray:
    """(m, 3 a) int64 global dofs of elements (m, a) int, node-major (``3 node + axis``)."""
    e = np.asarray(elements, np.int64)
    return (DOFS_PER_NODE * e[:, :, None] + np.arange(DOFS_PER_NODE)).reshape(len(e), -1)


@dataclass(frozen=True, eq=False)
class SparsityPattern:
    """CSR pattern of the node-major (3n, 3n) matrix of a mesh, and its scatter map.

    Attributes
    ----------
    n_dofs : 3 n
    indptr : (3n + 1,) int32 (int64 beyond 2**31 entries)
    indices : (nnz,) same dtype, sorted within each row
    dofs : (m, k) int64, global dofs of each element, node-major (k = 3 a, see :func:`element_dofs`)
    block_map : (m, k * k) int64, position in ``data`` of each element block entry (row-major k x k)
    """

    n_dofs: int
    indptr: np.ndarray
    indices: np.ndarray
    dofs: np.ndarray
    block_map: np.ndarray

    @classmethod
    def from_elements(cls, elements: np.ndarray, n_nodes: int) -> "SparsityPattern":
        """Pattern of ``elements`` (m, a) int node indices on ``n_nodes`` nodes.

        Nodes no element uses get empty rows. The pattern is found on nodes (a x a pairs per
        element, 9x fewer than dof pairs) and every node pair becomes a dense 3 x 3 block.
        """
        e = np.asarray(elements, np.int64)
        if e.ndim != 2 or len(e) == 0:
            raise ConfigError(f"elements: shape is {e.shape} and should be (m, a) with m >= 1")
        n = int(n_nodes)
        if e.min() < 0 or e.max() >= n:
            raise ConfigError(f"elements: node indices span [{e.min()}, {e.max()}], allowed [0, {n - 1}]")
        b = DOFS_PER_NODE
        m, a = e.shape
        keys = (e[:, :, None] * n + e[:, None, :]).ravel()  # node pairs, row-major a x a
        pairs, pair_of = np.unique(keys, return_inverse=True)  # sorted by (row node, col node)
        row, col = pairs // n, pairs % n
        degree = np.bincount(row, minlength=n)
        start = np.concatenate([[0], np.cumsum(degree)])  # node-level indptr
        rank = np.arange(len(pairs)) - start[row]  # position of the pair within its node row
        # dof row 3 R + i holds, for each neighbour C of R in order, the dofs 3 C + 0..2, so
        # entry (3 R + i, 3 C + j) sits at 9 start[R] + 3 i deg(R) + 3 rank + j
        i = np.arange(b)
        base = b * b * start[row] + b * rank  # (P,)
        pos = base[:, None, None] + (b * degree[row])[:, None, None] * i[:, None] + i  # (P, 3, 3)
        nnz = b * b * len(pairs)
        idx_dtype = np.int32 if max(nnz, b * n) < 2**31 - 1 else np.int64
        indices = np.empty(nnz, idx_dtype)
        indices[pos.ravel()] = np.broadcast_to(b * col[:, None, None] + i, pos.shape).ravel()
        dof_degree = np.repeat(b * degree, b)  # entries per dof row
        indptr = np.concatenate([[0], np.cumsum(dof_degree)]).astype(idx_dtype)
        # element entry (3 p + i, 3 q + j) of local nodes p, q lies at pos[pair(p, q), i, j]
        block = pos[pair_of.reshape(m, a, a)]  # (m, a, a, 3, 3)
        block_map = block.transpose(0, 1, 3, 2, 4).reshape(m, (a * b) ** 2)
        return cls(n_dofs=b * n, indptr=indptr, indices=indices, dofs=element_dofs(e),
                   block_map=np.ascontiguousarray(block_map, np.int64))

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def assemble_data(self, blocks: np.ndarray, kind: np.ndarray | None = None) -> np.ndarray:
        """(nnz,) CSR data ``sum_e P_e^T K_e P_e`` (entries shared by elements summed).

        Parameters
        ----------
        blocks : (m, k, k) float, one block per element; or (p, k, k) with ``kind``.
        kind : (m,) int, which of the p blocks each element uses (voxels: one per phase).
        """
        if kind is None:
            return np.bincount(self.block_map.ravel(), weights=np.asarray(blocks).reshape(-1), minlength=self.nnz)
        flat = np.asarray(blocks, float).reshape(len(blocks), -1)
        kind = np.asarray(kind)
        data = np.zeros(self.nnz)
        step = max(1, max(self.nnz, _CHUNK) // flat.shape[1])
        for s in range(0, len(kind), step):
            data += np.bincount(self.block_map[s:s + step].ravel(), weights=flat[kind[s:s + step]].ravel(),
                                minlength=self.nnz)
        return data

    def assemble_vector(self, vectors: np.ndarray, kind: np.ndarray | None = None) -> np.ndarray:
        """Global vector(s) ``sum_e P_e^T f_e``.

        Parameters
        ----------
        vectors : (m, k) or (m, k, r) float; or (p, k) / (p, k, r) with ``kind``.
        kind : (m,) int, which of the p element vectors each element uses.

        Returns
        -------
        (3n,) or (3n, r) float.
        """
        v = np.asarray(vectors)
        dofs = self.dofs.ravel()
        if v.ndim == 2:
            w = v.reshape(-1) if kind is None else v[kind].reshape(-1)
            return np.bincount(dofs, weights=w, minlength=self.n_dofs)
        columns = [v[:, :, j] if kind is None else v[:, :, j][kind] for j in range(v.shape[2])]
        return np.stack([np.bincount(dofs, weights=c.reshape(-1), minlength=self.n_dofs) for c in columns], axis=1)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """A CSR matrix on this pattern with ``data`` (nnz,) (not copied).

        The index arrays are copied (cheap) so that in-place operations of a caller
        (``eliminate_zeros``...) can never corrupt the cached pattern.
        """
        A = sp.csr_matrix(
            (data, self.indices.copy(), self.indptr.copy()), shape=(self.n_dofs, self.n_dofs), copy=False
        )
        A.has_sorted_indices = True
        return A

    def assemble(self, blocks: np.ndarray, kind: np.ndarray | None = None) -> sp.csr_matrix:
        """(3n, 3n) CSR matrix of element blocks, as :meth:`assemble_data`."""
        return self.matrix(self.assemble_data(blocks, kind))

    def submatrix_map(self, rows: np.ndarray, cols: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
        """:func:`submatrix_map` of the matrices on this pattern."""
        return submatrix_map(self.matrix(np.empty(self.nnz)), rows, cols)

    @cached_property
    def transpose_map(self) -> np.ndarray:
        """(nnz,) int64: ``data[transpose_map]`` is the data of ``A^T`` (the pattern is symmetric)."""
        return transpose_map(self.matrix(np.empty(self.nnz)))


def _tagged(A: sp.csr_matrix) -> sp.csr_matrix:
    """``A``'s pattern with entry k (in ``data`` order) holding k + 1: slicing or transposing
    it and subtracting 1 tells where each entry of the result comes from (exact: integers
    below 2**53)."""
    return sp.csr_matrix((np.arange(1, A.nnz + 1, dtype=float), A.indices, A.indptr), shape=A.shape)


def submatrix_map(A: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """Pattern of ``A[rows][:, cols]`` and the map from its data into ``A.data``.

    Parameters
    ----------
    A : (n, n) CSR matrix (only its pattern is read).
    rows, cols : (r,), (c,) int indices.

    Returns
    -------
    ``(sub, take)``: ``sub`` an (r, c) CSR matrix with sorted indices and ``take``
    (sub.nnz,) int64 such that ``sub.data[:] = B.data[take]`` gives the submatrix of any
    ``B`` with ``A``'s pattern; this turns the slicing of every Newton iteration into one gather.
    """
    sub = _tagged(A)[np.asarray(rows)][:, np.asarray(cols)].tocsr()
    sub.sort_indices()
    take = sub.data.astype(np.int64) - 1
    return sub, take


def transpose_map(A: sp.csr_matrix, *, name: str = "matrix") -> np.ndarray:
    """(nnz,) int64 ``t`` with ``A.data[t]`` the data of ``A^T`` on ``A``'s own pattern.

    ``A`` : square CSR with sorted indices and a structurally symmetric pattern (else a
    :class:`ConfigError` naming ``name``).
    """
    t = _tagged(A).T.tocsr()
    t.sort_indices()
    if t.nnz != A.nnz or not np.array_equal(t.indices, A.indices):
        raise ConfigError(f"{name}: pattern is not structurally symmetric: allowed only symmetric patterns")
    return t.data.astype(np.int64) - 1
