"""The reduced basis of the sheets' free nodes (:mod:`.reduced`): static modes plus POD of snapshots.

Two parts, orthonormal together (Euclidean inner product on the free dofs, so ``a`` is in mm
and ``V^T r_f`` in N):

* static modes: the free nodes' linear response at the rest equilibrium to each rigid
  coordinate and to gravity (eq. 6's ``K_ff^-1 K_fr J_r`` columns and ``K_ff^-1 f_g``), so the
  reduced model's Schur complement at rest, hence its Jacobian there, is the full model's;
* proper orthogonal decomposition of the snapshot displacements (equilibria over the motor
  box) after the static modes are projected out: left singular vectors, as many as needed for
  every snapshot's worst nodal projection error to be at most ``tol_mm``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError


def orthonormalize(M: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """(N, r) orthonormal basis of the column space of ``M`` (N, c) (SVD; directions with a
    singular value below ``rtol`` times the largest dropped)."""
    if M.size == 0:
        return np.zeros((M.shape[0], 0))
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, s > rtol * s[0]] if s[0] > 0 else U[:, :0]


def nodal_error(E: np.ndarray) -> np.ndarray:
    """(c,) the largest nodal norm [mm] of each column of ``E`` (3 n, c)."""
    return np.sqrt((E.reshape(-1, 3, E.shape[1]) ** 2).sum(axis=1)).max(axis=0)


def pod_basis(static: np.ndarray, snapshots: np.ndarray, tol_mm: float, max_modes: int = 200):
    """Basis ``V`` (N, k) = [static modes | POD modes], and a record of the choice.

    Parameters
    ----------
    static : (N, c) static responses (any scale: they are orthonormalised).
    snapshots : (N, s) displacements of the free dofs from rest [mm].
    tol_mm : target of the worst nodal projection error over the snapshots [mm] (> 0).
    max_modes : at most this many POD modes.

    Returns
    -------
    V : (N, k) orthonormal.
    record : dict with ``static_modes``, ``pod_modes``, ``projection_error_mm`` (the worst
        nodal error with the chosen basis) and ``singular_values`` of the POD step.
    """
    if not tol_mm > 0:
        raise ConfigError(f"tol_mm: {tol_mm!r}: allowed range (0, inf) mm")
    if snapshots.ndim != 2 or snapshots.shape[0] != static.shape[0]:
        raise ConfigError(f"snapshots: shape is {snapshots.shape} and should be ({static.shape[0]}, s)")
    Q = orthonormalize(static)
    R = snapshots - Q @ (Q.T @ snapshots)
    U, s, Zt = np.linalg.svd(R, full_matrices=False)
    SZ = s[:, None] * Zt
    k, err = 0, nodal_error(R).max() if R.size else 0.0
    # the worst nodal error after k modes: rebuild the remainder from the SVD, k by k
    while err > tol_mm and k < min(max_modes, len(s)) and s[k] > 1e-12 * s[0]:
        k += 1
        err = nodal_error(U[:, k:] @ SZ[k:]).max() if k < len(s) else 0.0
    V = np.hstack([Q, U[:, :k]])
    return V, {"static_modes": int(Q.shape[1]), "pod_modes": int(k), "projection_error_mm": float(err),
               "target_mm": float(tol_mm), "singular_values": s[: min(len(s), 60)].round(6).tolist()}
