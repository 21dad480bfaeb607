"""Linear 4-node tetrahedron (constant strain): batched element matrices.

One quadrature point is exact for P1 elasticity (the strain is constant), so the
element matrices are closed-form products, batched with einsum.
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshError
from .hex8 import strain_operator


def tet4_gradients(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients and volumes.

    Parameters
    ----------
    points : (n, 3) float [mm]
    tets : (m, 4) int

    Returns
    -------
    grads : (m, 4, 3) float [1/mm]
    volumes : (m,) float [mm^3], positive; degenerate tets raise :class:`MeshError`.
    """
    X = np.asarray(points, float)[np.asarray(tets)]
    Dm = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=2)  # columns
    det = np.linalg.det(Dm)
    scale = np.abs(Dm).max() ** 3 if len(Dm) else 1.0
    bad = np.abs(det) <= 1e-12 * scale
    if np.any(bad):
        raise MeshError(f"tets: {int(bad.sum())} degenerate tetrahedra (first index {int(np.argmax(bad))})")
    inv = np.linalg.inv(Dm)  # rows = gradients of N1, N2, N3
    grads = np.empty((len(X), 4, 3))
    grads[:, 1:] = inv
    grads[:, 0] = -inv.sum(axis=1)
    return grads, np.abs(det) / 6.0


def tet4_matrices(points: np.ndarray, tets: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Batched P1 element matrices.

    Parameters
    ----------
    points : (n, 3) float [mm]
    tets : (m, 4) int
    C : (6, 6) or (m, 6, 6) float [MPa], Voigt stiffness per element.

    Returns
    -------
    K : (m, 12, 12) float [N/mm], ``V B^T C B``.
    F : (m, 12, 6) float [N], ``V B^T C`` (nodal forces of unit macro strains).
    B : (m, 6, 12) float [1/mm], the element's constant strain operator.
    volumes : (m,) float [mm^3].
    """
    grads, vol = tet4_gradients(points, tets)
    B = strain_operator(grads)
    Ce = np.broadcast_to(np.asarray(C, float), (len(B), 6, 6))
    CB = np.einsum("mij,mjk->mik", Ce, B)
    F = np.einsum("mji,mjk->mik", B, Ce) * vol[:, None, None]
    K = np.einsum("mji,mjk->mik", B, CB) * vol[:, None, None]
    return K, F, B, vol

