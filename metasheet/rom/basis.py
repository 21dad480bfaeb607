"""The reduced basis of the sheets' free nodes (:mod:`.model`): static modes plus POD of snapshots.

Two parts, orthonormal together (Euclidean inner product on the free dofs, so ``a`` is in mm
and ``V^T r_f`` in N):

* static modes: the free nodes' linear response at the rest equilibrium to each rigid
  coordinate and to gravity (eq. 6's ``K_ff^-1 K_fr J_r`` columns and ``K_ff^-1 f_g``), so the
  reduced model's Schur complement at rest, hence its Jacobian there, is the full model's;
* proper orthogonal decomposition of the snapshot displacements (equilibria over the motor
  box) after the static modes are projected out: left singular vectors, as many as needed for
  every snapshot's worst nodal projection error to be at most ``tol_mm``;
* (:func:`add_sensitivities`) POD of the snapshots' own static responses (``K_ff^-1 K_fr J_r``
  at each snapshot), each scaled to a unit largest nodal norm, until every one is captured
  within a relative nodal error ``tol``. The Jacobian is a Schur complement of the tangent:
  it is exact where the basis spans that state's static responses. Measured on the 14 mm P1
  robot (rest +- 12 deg): without them the held-out Jacobian is 4.8 % off with every
  element; with them at tol 0.01 (k 35 -> 65) 1.4 %, at 0.003 (k 101) 0.5 %.
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


def smallest_rank(U, s, Zt, tol: float, max_modes: int) -> tuple[int, float]:
    """The fewest leading modes k of the SVD ``U diag(s) Zt`` (N, c) whose remainder has a
    worst nodal norm (:func:`nodal_error`) at most ``tol``, and that error; at most
    ``max_modes`` and none with ``s`` below 1e-12 of the largest. Bisection on k (the error
    of a truncated SVD shrinks with k), so a few remainders of (N, c) are formed, not c.
    """
    if s.size == 0:
        return 0, 0.0
    SZ = s[:, None] * Zt

    def err(k):
        return float(nodal_error(U[:, k:] @ SZ[k:]).max()) if k < len(s) else 0.0

    top = min(max_modes, int(np.sum(s > 1e-12 * s[0])))
    if err(0) <= tol:
        return 0, err(0)
    if err(top) > tol:
        return top, err(top)
    lo, hi = 0, top  # err(lo) > tol >= err(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if err(mid) <= tol else (mid, hi)
    return hi, err(hi)


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
    k, err = smallest_rank(U, s, Zt, tol_mm, max_modes)
    V = np.hstack([Q, U[:, :k]])
    return V, {"static_modes": int(Q.shape[1]), "pod_modes": int(k), "projection_error_mm": float(err),
               "target_mm": float(tol_mm), "singular_values": s[: min(len(s), 60)].round(6).tolist()}


def add_sensitivities(V: np.ndarray, sens: np.ndarray, tol: float, max_modes: int = 300):
    """``V`` (N, k) extended by POD modes of the static responses ``sens`` (N, c) (any
    scale: each column is scaled to a unit largest nodal norm) until every column's worst
    nodal projection error is at most ``tol`` (relative, in (0, 1)).

    Returns ``(V', record)``: V' (N, k + m) orthonormal, record with ``sensitivity_modes`` m
    and ``sensitivity_error`` (the worst relative error reached).
    """
    if not 0 < tol < 1:
        raise ConfigError(f"tangent_tol: {tol!r}: allowed range (0, 1)")
    if sens.ndim != 2 or sens.shape[0] != V.shape[0]:
        raise ConfigError(f"sensitivities: shape is {sens.shape} and should be ({V.shape[0]}, c)")
    scale = nodal_error(sens)
    S = sens[:, scale > 0] / scale[scale > 0]
    R = S - V @ (V.T @ S)
    R -= V @ (V.T @ R)  # twice: the columns are O(1), the basis must stay orthonormal to round-off
    U, s, Zt = np.linalg.svd(R, full_matrices=False)
    k, err = smallest_rank(U, s, Zt, tol, max_modes)
    return np.hstack([V, U[:, :k]]), {"sensitivity_modes": int(k), "sensitivity_error": float(err),
                                      "sensitivity_tol": float(tol)}
