"""Vectorised scatter of per-element matrices into global sparse matrices.

No Python loop over elements: the element dof map ``dofs`` (m, k) and the element
matrices ``(m, k, k)`` become one COO triplet list (int32 indices to halve the
memory) that scipy sums into CSR. When all elements share a few matrices (voxels:
one per phase) pass those and a per-element ``kind`` index instead of m copies.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _element_values(mats: np.ndarray, kind) -> np.ndarray:
    mats = np.asarray(mats, float)
    return mats if kind is None else mats[np.asarray(kind)]


def assemble_matrix(dofs: np.ndarray, mats: np.ndarray, ndof: int, kind=None) -> sp.csr_matrix:
    """Global matrix ``sum_e P_e^T M_e P_e``.

    Parameters
    ----------
    dofs : (m, k) int, global dof of each element's local dof.
    mats : (m, k, k) float, or (p, k, k) with ``kind`` (m,) int selecting one per element.
    ndof : number of global dofs.

    Returns
    -------
    (ndof, ndof) CSR matrix, duplicates summed.
    """
    dofs = np.asarray(dofs)
    m, k = dofs.shape
    idx = np.int32 if ndof < 2**31 - 1 else np.int64
    d = dofs.astype(idx, copy=False)
    rows = np.broadcast_to(d[:, :, None], (m, k, k)).ravel()
    cols = np.broadcast_to(d[:, None, :], (m, k, k)).ravel()
    vals = _element_values(mats, kind).ravel()
    A = sp.coo_matrix((vals, (rows, cols)), shape=(ndof, ndof)).tocsr()
    A.sum_duplicates()
    return A


def assemble_vectors(dofs: np.ndarray, vecs: np.ndarray, ndof: int, kind=None) -> np.ndarray:
    """Global right-hand sides ``sum_e P_e^T f_e``.

    Parameters
    ----------
    dofs : (m, k) int.
    vecs : (m, k, r) float, or (p, k, r) with ``kind`` (m,) int.
    ndof : number of global dofs.

    Returns
    -------
    (ndof, r) float.
    """
    dofs = np.asarray(dofs).ravel()
    v = _element_values(vecs, kind)
    r = v.shape[-1]
    v = v.reshape(-1, r)
    return np.stack([np.bincount(dofs, weights=v[:, j], minlength=ndof) for j in range(r)], axis=1)
