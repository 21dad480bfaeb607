"""Cached sparsity pattern of a tet mesh's (3n, 3n) stiffness and its scatter maps.

The pattern is computed once (symbolically, from the connectivity); each assembly then only
computes the (m, 12, 12) element blocks and adds them into the CSR ``data`` array through
``block_map``. Every matrix built from one pattern shares the same ``indptr``/``indices``,
so callers can cache a symbolic factorisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class SparsityPattern:
    """CSR pattern of the node-major (3n, 3n) matrix of a tet mesh.

    Attributes
    ----------
    n_dofs : 3 n
    indptr : (3n + 1,) int32
    indices : (nnz,) int32, sorted within each row
    dofs : (m, 12) int64, global DOFs of each element, node-major (3 node + axis)
    block_map : (m, 144) int64, position in ``data`` of each element block entry (row-major 12x12)
    """

    n_dofs: int
    indptr: np.ndarray
    indices: np.ndarray
    dofs: np.ndarray
    block_map: np.ndarray

    @classmethod
    def from_tets(cls, tets: np.ndarray, n_nodes: int) -> "SparsityPattern":
        """Pattern of ``tets`` (m, 4) int on ``n_nodes`` nodes (unused nodes get empty rows)."""
        tets = np.asarray(tets, np.int64)
        n_dofs = 3 * int(n_nodes)
        dofs = (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)
        rows = np.repeat(dofs, 12, axis=1)  # (m, 144) row-major 12 x 12
        cols = np.tile(dofs, (1, 12))
        keys = (rows * n_dofs + cols).ravel()
        uniq, inverse = np.unique(keys, return_inverse=True)
        urows = uniq // n_dofs
        indptr = np.zeros(n_dofs + 1, np.int64)
        np.add.at(indptr, urows + 1, 1)
        indptr = np.cumsum(indptr)
        idx_dtype = np.int32 if len(uniq) < 2**31 - 1 else np.int64
        return cls(
            n_dofs=n_dofs,
            indptr=indptr.astype(idx_dtype),
            indices=(uniq % n_dofs).astype(idx_dtype),
            dofs=dofs,
            block_map=inverse.reshape(len(tets), 144).astype(np.int64),
        )

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def assemble_data(self, blocks: np.ndarray) -> np.ndarray:
        """(nnz,) CSR data from element blocks (m, 12, 12) (sums shared entries)."""
        return np.bincount(self.block_map.ravel(), weights=blocks.reshape(-1), minlength=self.nnz)

    def assemble_vector(self, fe: np.ndarray) -> np.ndarray:
        """(3n,) global vector from element vectors (m, 12)."""
        return np.bincount(self.dofs.ravel(), weights=fe.reshape(-1), minlength=self.n_dofs)

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


def submatrix_map(pattern: SparsityPattern, rows: np.ndarray, cols: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """Pattern of ``A[rows][:, cols]`` and the map from its data into ``A.data``.

    Returns ``(sub, take)`` with ``sub`` a CSR matrix and ``take`` (sub.nnz,) int64 such that
    ``sub.data[:] = A.data[take]`` gives the submatrix of any ``A`` on ``pattern``; this
    turns the slicing of every Newton iteration into one gather.
    """
    marker = pattern.matrix(np.arange(1, pattern.nnz + 1, dtype=float))
    sub = marker[np.asarray(rows)][:, np.asarray(cols)].tocsr()
    sub.sort_indices()
    take = sub.data.astype(np.int64) - 1  # exact: integers below 2**53
    return sub, take
