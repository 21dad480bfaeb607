"""Energy-conserving sampling and weighting (ECSW; Farhat, Avery, Chapman, Cortial 2014).

The reduced internal force is a sum over elements, ``G(q) = sum_e G_e(q)`` (:mod:`.reduced`).
Given training states ``q_s``, ECSW looks for a sparse non-negative weight vector ``w`` with

    || sum_e w_e G_e(q_s) - G(q_s) ||  <=  tol || G(q_s) ||          over all s at once,

i.e. a non-negative least-squares problem ``min |A w - b|, w >= 0`` with the columns of ``A``
the elements' stacked contributions and ``b = A 1`` (w = 1 is the full model), solved
greedily: add the element most correlated with the residual, re-solve the NNLS on the
selected set, drop elements whose weight went to zero, until the relative residual is below
``tol``. Non-negative weights keep the sampled sum of element energies an energy (the
reduced tangent inherits the full one's definiteness where the full tangent has it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError


@dataclass(frozen=True)
class Sample:
    """ECSW result: ``elements`` (s,) int, ``weights`` (s,) > 0, the achieved relative
    residual ``error`` and the history of it per added element."""

    elements: np.ndarray
    weights: np.ndarray
    error: float
    history: tuple


def ecsw(A: np.ndarray, tol: float, *, b: np.ndarray | None = None, max_elements: int | None = None) -> Sample:
    """Sparse non-negative weights with ``|A w - b| <= tol |b|`` (see the module docstring);
    :func:`ecsw_path` at the single tolerance ``tol``."""
    return ecsw_path(A, [tol], b=b, max_elements=max_elements)[0]


def ecsw_path(A: np.ndarray, tols, *, b: np.ndarray | None = None, max_elements: int | None = None) -> list:
    """One :class:`Sample` per tolerance of the decreasing ``tols``, from one greedy run.

    Lawson and Hanson's active-set NNLS, stopped as soon as the residual meets the last
    tolerance: its outer step adds the element with the largest gradient ``A^T (b - A w)``,
    which is ECSW's greedy choice; the inner loop keeps the weights non-negative. The passive
    set's Gram matrix is kept as a Cholesky factor grown one row at a time (rebuilt only when
    the inner loop drops an element), so an iteration costs one ``A^T r`` and O(s^2).

    Parameters
    ----------
    A : (rows, m) element contributions (scaled rows), b : (rows,) target (default ``A 1``).
    tols : relative residual targets, each in (0, 1), decreasing.
    max_elements : give up beyond this many selected elements (default m).

    Raises :class:`ConvergenceError` when the last tolerance is not met with ``max_elements``.
    """
    tols = [float(t) for t in tols]
    if not tols or any(not 0 < t < 1 for t in tols) or sorted(tols, reverse=True) != tols:
        raise ConfigError(f"tol: {tols!r}: each in the allowed range (0, 1), decreasing")
    A = np.asfortranarray(A, dtype=float)  # columns contiguous: the selected set is gathered often
    m = A.shape[1]
    b = A.sum(axis=1) if b is None else np.asarray(b, float)
    nb = float(np.linalg.norm(b))
    if nb == 0:
        raise ConfigError("ecsw: the target b is zero: training states carry no force")
    Atb = A.T @ b
    limit = m if max_elements is None else min(int(max_elements), m)
    P = np.zeros(0, dtype=np.int64)  # passive set (weights > 0), in insertion order
    w = np.zeros(0)
    L = np.zeros((0, 0))  # Cholesky factor of A_P^T A_P
    r = b.copy()
    history: list[float] = []
    out: list[Sample] = []
    err = 1.0
    while True:
        while out.__len__() < len(tols) and err <= tols[len(out)]:
            order = np.argsort(P)
            out.append(Sample(P[order], w[order], err, tuple(history)))
        if len(out) == len(tols):
            return out
        if len(P) >= limit:
            raise ConvergenceError(f"ecsw: relative force error {err:.2e} > tol {tols[-1]:g} with "
                                   f"{len(P)} elements (max_elements {limit})", history)
        grad = A.T @ r
        grad[P] = -np.inf
        e = int(np.argmax(grad))
        if not grad[e] > 1e-14 * nb * np.linalg.norm(A[:, e]):
            raise ConvergenceError(f"ecsw: stalled at relative force error {err:.2e} > tol {tols[-1]:g}", history)
        P, w, L = _enter(A, Atb, P, w, L, e)
        r = b - A[:, P] @ w
        err = float(np.linalg.norm(r)) / nb
        history.append(err)


def _chol_append(L: np.ndarray, g: np.ndarray, d: float) -> np.ndarray:
    """The Cholesky factor of [[G, g], [g^T, d]] from that of G (``L``)."""
    from scipy.linalg import solve_triangular

    n = len(L)
    l = solve_triangular(L, g, lower=True) if n else np.zeros(0)
    out = np.zeros((n + 1, n + 1))
    out[:n, :n] = L
    out[n, :n] = l
    out[n, n] = np.sqrt(max(d - l @ l, 1e-300))
    return out


def _lsq(L: np.ndarray, h: np.ndarray) -> np.ndarray:
    from scipy.linalg import cho_solve

    return cho_solve((L, True), h)


def _enter(A, Atb, P, w, L, e):
    """Lawson-Hanson's inner loop after element ``e`` enters: least-squares weights on the
    passive set, stepping back to the boundary (and dropping the element that reaches zero)
    while any would go negative. ``Atb`` (m,) = A^T b. Returns the new (P, w, L)."""
    a = A[:, e]
    L = _chol_append(L, A[:, P].T @ a, float(a @ a))
    P = np.append(P, e)
    w = np.append(w, 0.0)
    while True:
        z = _lsq(L, Atb[P])
        if np.all(z > 0):
            return P, z, L
        neg = np.flatnonzero(z <= 0)
        ratios = w[neg] / np.maximum(w[neg] - z[neg], 1e-300)
        alpha = float(np.min(ratios))
        w = w + alpha * (z - w)
        out = neg[np.argmin(ratios)]
        L = _chol_delete(L, out)
        P, w = np.delete(P, out), np.delete(w, out)
        w[w < 0] = 0.0


def _chol_delete(L: np.ndarray, i: int) -> np.ndarray:
    """The Cholesky factor of G without row and column ``i`` from that of G (``L``, lower):
    the trailing block absorbs the removed column by a rank-one update, O(s^2)."""
    n = len(L)
    out = np.delete(np.delete(L, i, axis=0), i, axis=1)
    x = L[i + 1:, i].copy()
    T = out[i:, i:]  # a view: updated in place
    for k in range(n - 1 - i):  # rank-one update of T T^T + x x^T (Givens form)
        r = np.hypot(T[k, k], x[k])
        c, s = r / T[k, k], x[k] / T[k, k]
        T[k, k] = r
        T[k + 1:, k] = (T[k + 1:, k] + s * x[k + 1:]) / c
        x[k + 1:] = c * x[k + 1:] - s * T[k + 1:, k]
    return out
