"""Energy-conserving sampling and weighting (ECSW; Farhat, Avery, Chapman, Cortial 2014).

The reduced internal force is a sum over elements, ``G(q) = sum_e G_e(q)`` (:mod:`.model`).
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

import numba
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


def ecsw(A: np.ndarray, tol: float, *, b: np.ndarray | None = None, max_elements: int | None = None,
         batch: float = 0.0) -> Sample:
    """Sparse non-negative weights with ``|A w - b| <= tol |b|`` (see the module docstring);
    :func:`ecsw_path` at the single tolerance ``tol``."""
    return next(ecsw_path(A, [tol], b=b, max_elements=max_elements, batch=batch))


def ecsw_path(A: np.ndarray, tols, *, b: np.ndarray | None = None, max_elements: int | None = None,
              batch: float = 0.0):
    """Yields one :class:`Sample` per tolerance of the decreasing ``tols``, from one greedy
    run, each as soon as it is met (a caller content with a loose one stops there).

    Lawson and Hanson's active-set NNLS, stopped as soon as the residual meets the last
    tolerance: its outer step adds the element with the largest gradient ``A^T (b - A w)``,
    which is ECSW's greedy choice; the inner loop keeps the weights non-negative. The passive
    set's columns and the Cholesky factor of their Gram matrix live in buffers grown one
    column at a time (shifted only when the inner loop drops an element), so entering an
    element costs one ``A_P^T a`` and an O(s^2) factor update, and each outer step (one
    element, or a batch) one least-squares solve on the factor, O(s^2).

    Parameters
    ----------
    A : (rows, m) element contributions (scaled rows), b : (rows,) target (default ``A 1``).
    tols : relative residual targets, each in (0, 1), decreasing.
    max_elements : give up beyond this many selected elements (default m).
    batch : enter the ``max(1, batch * s)`` largest-gradient elements per outer step (s: the
        current sample size) before the gradient ``A^T r`` (rows x m, the cost on a large
        mesh) is formed again; 0 is the one-at-a-time greedy. The inner loop drops an entered
        element whose weight would go negative, so a batch only trades a slightly larger
        sample for fewer gradients.

    Raises :class:`ConvergenceError` when the last tolerance is not met with ``max_elements``.
    """
    tols = [float(t) for t in tols]
    if not tols or any(not 0 < t < 1 for t in tols) or sorted(tols, reverse=True) != tols:
        raise ConfigError(f"tol: {tols!r}: each in the allowed range (0, 1), decreasing")
    if not 0 <= batch < 1:
        raise ConfigError(f"batch: {batch!r}: allowed range [0, 1)")
    A = np.asfortranarray(A, dtype=float)  # columns contiguous: entering elements gathers columns
    m = A.shape[1]
    b = A.sum(axis=1) if b is None else np.asarray(b, float)
    nb = float(np.linalg.norm(b))
    if nb == 0:
        raise ConfigError("ecsw: the target b is zero: training states carry no force")
    limit = m if max_elements is None else min(int(max_elements), m)
    act = _Active(A, b)
    r = b.copy()
    history: list[float] = []
    met = 0
    err = 1.0
    while True:
        while met < len(tols) and err <= tols[met]:
            P, w = act.selection()
            order = np.argsort(P)
            met += 1
            yield Sample(P[order], w[order], err, tuple(history))
        if met == len(tols):
            return
        if act.n >= limit:
            raise ConvergenceError(f"ecsw: relative force error {err:.2e} > tol {tols[-1]:g} with "
                                   f"{act.n} elements (max_elements {limit})", history)
        grad = A.T @ r
        grad[act.P[:act.n]] = -np.inf
        grad[act.dependent] = -np.inf
        nb_enter = min(max(1, int(batch * act.n)), limit - act.n)
        cand = np.argpartition(-grad, nb_enter - 1)[:nb_enter] if nb_enter > 1 else [int(np.argmax(grad))]
        cand = [int(e) for e in cand if grad[e] > 1e-14 * nb * np.linalg.norm(A[:, e])]
        if not cand:
            raise ConvergenceError(f"ecsw: stalled at relative force error {err:.2e} > tol {tols[-1]:g}", history)
        act.enter(sorted(cand, key=lambda e: -grad[e]))
        r = b - act.columns() @ act.w[:act.n]
        err = float(np.linalg.norm(r)) / nb
        history.append(err)


class _Active:
    """The passive set of Lawson-Hanson's NNLS: element indices ``P``, weights ``w``, their
    columns of A (``cols``, rows x capacity) and the lower Cholesky factor ``L`` of the
    columns' Gram matrix, all in buffers of doubling capacity; ``n`` of them in use.
    ``dependent`` (m,) bool: columns refused for lying in the passive set's span (until an
    element leaves it)."""

    #: a column whose part outside the passive set's span has a squared norm below this
    #: fraction of its own (a norm below 1e-6 of it) is refused: entering it made the factor's
    #: new diagonal round-off and the weights NaN (a batch of twin elements crashed, issue 41)
    DEPENDENT = 1e-12

    def __init__(self, A: np.ndarray, b: np.ndarray):
        self.A, self.Atb, self.n = A, A.T @ b, 0
        self.dependent = np.zeros(A.shape[1], bool)
        self._grow(64)

    def _grow(self, cap: int) -> None:
        n, old = self.n, getattr(self, "L", None)
        L, cols = np.zeros((cap, cap)), np.zeros((self.A.shape[0], cap), order="F")
        P, w = np.zeros(cap, dtype=np.int64), np.zeros(cap)
        if old is not None:
            L[:n, :n], cols[:, :n], P[:n], w[:n] = old[:n, :n], self.cols[:, :n], self.P[:n], self.w[:n]
        self.L, self.cols, self.P, self.w = L, cols, P, w

    def columns(self) -> np.ndarray:
        return self.cols[:, :self.n]

    def selection(self):
        return self.P[:self.n].copy(), self.w[:self.n].copy()

    def enter(self, elements) -> None:
        """Lawson-Hanson's inner loop after ``elements`` (a list) enter together at weight 0:
        least-squares weights on the passive set, stepping back to the boundary (and
        dropping the element that reaches zero) while any would go negative. One solve for
        the batch, not one per element: the factor grows first, column by column."""
        from scipy.linalg import solve_triangular

        for e in elements:
            if self.n == len(self.P):
                self._grow(min(2 * len(self.P), self.A.shape[1]))  # never more columns than A has
            n, a = self.n, self.A[:, e]
            g = self.columns().T @ a
            l = solve_triangular(self.L[:n, :n], g, lower=True, check_finite=False) if n else np.zeros(0)
            aa = float(a @ a)
            d2 = aa - float(l @ l)  # squared norm of a's part outside the passive columns' span
            if not d2 > self.DEPENDENT * aa:
                # in the span of the passive set (an element's twin, or another of the batch):
                # it adds nothing the weights cannot already do, and would make the Gram singular
                self.dependent[e] = True
                continue
            self.L[n, :n] = l
            self.L[n, n] = np.sqrt(d2)
            self.cols[:, n], self.P[n], self.w[n] = a, e, 0.0
            self.n = n + 1
        while True:
            z = self._lsq()
            if not np.all(np.isfinite(z)):
                raise ConvergenceError("ecsw: the passive set's least squares lost precision (non-finite weights)")
            w = self.w[:self.n]
            if np.all(z > 0):
                w[:] = z
                return
            neg = np.flatnonzero(z <= 0)
            ratios = w[neg] / np.maximum(w[neg] - z[neg], 1e-300)
            w += float(np.min(ratios)) * (z - w)
            self._delete(int(neg[np.argmin(ratios)]))
            w = self.w[:self.n]
            w[w < 0] = 0.0

    def _lsq(self) -> np.ndarray:
        from scipy.linalg import cho_solve

        return cho_solve((self.L[:self.n, :self.n], True), self.Atb[self.P[:self.n]], check_finite=False)

    def _delete(self, i: int) -> None:
        """Drop entry ``i``: the factor of the Gram matrix without row and column ``i`` from
        the current one; the trailing block absorbs the removed column by a rank-one update
        (Givens form), O(s^2)."""
        n, L = self.n, self.L
        x = L[i + 1:n, i].copy()
        L[i:n - 1, :i] = L[i + 1:n, :i]
        L[i:n - 1, i:n - 1] = L[i + 1:n, i + 1:n]
        L[n - 1, :n] = 0.0
        L[:n, n - 1] = 0.0
        _givens_sweep(L[i:n - 1, i:n - 1], x)
        self.cols[:, i:n - 1] = self.cols[:, i + 1:n]
        self.P[i:n - 1], self.w[i:n - 1] = self.P[i + 1:n], self.w[i + 1:n]
        self.n = n - 1
        self.dependent[:] = False  # the span shrank: a refused column may be independent now


@numba.njit(cache=True)
def _givens_sweep(T, x):
    """Absorb ``x`` (m,) into the lower factor ``T`` (m, m) in place by Givens rotations, column
    by column: for each k, ``r = hypot(T_kk, x_k)``, ``c = r / T_kk``, ``s = x_k / T_kk``, then
    ``T_jk = (T_jk + s x_j) / c`` and ``x_j = c x_j - s T_jk`` below the diagonal. The same
    operations in the same order as the numpy loop it replaces (no fused multiply-add: numba
    contracts none without fastmath), so the same bits, without that loop's strided column
    slices of a C-ordered factor (12.8 of the reduce stage's 95 sampled seconds)."""
    m = T.shape[0]
    for k in range(m):
        tkk = T[k, k]
        xk = x[k]
        r = np.hypot(tkk, xk)
        c = r / tkk
        s = xk / tkk
        T[k, k] = r
        for j in range(k + 1, m):
            t = (T[j, k] + s * x[j]) / c
            T[j, k] = t
            x[j] = c * x[j] - s * t
