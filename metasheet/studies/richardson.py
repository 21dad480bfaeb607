"""Richardson extrapolation of a discretisation ladder: a quantity ``q(h)`` computed at several
grid sizes ``h`` modelled as ``q(h) = q0 + C h^p`` (one leading error term), giving the limit
``q0``, the observed order ``p`` and each level's error against the limit.

Three levels determine the model exactly: the order solves
``(q1 - q2) / (q2 - q3) = (h1^p - h2^p) / (h2^p - h3^p)``, monotone in ``p`` for
``h1 > h2 > h3`` (any ratios, not only a constant refinement). More levels: the order of every
consecutive triple is reported, and the fit is the least-squares one over all levels (``q0``
and ``C`` linear, ``p`` by a bounded scalar search). A ladder whose differences change sign is
not in its asymptotic range: no order is claimed (``order`` None), and the finest level stands
for the limit with the spread of the ladder as its error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: Orders outside this range are reported as not asymptotic (no extrapolation claimed).
ORDER_RANGE = (0.2, 6.0)


@dataclass(frozen=True)
class RichardsonFit:
    """The extrapolated ladder.

    h : (n,) grid sizes, coarse to fine; q : (n,) the quantity at each.
    limit : q0, the extrapolated h -> 0 value (the finest q when ``order`` is None).
    order : p, the observed order over all levels (None: not asymptotic).
    triple_orders : the order of each consecutive triple (None where it has none).
    errors : (n,) ``q - limit``; relative : (n,) ``(q - limit) / |limit|``.
    note : why no order was claimed, or "".
    """

    h: np.ndarray
    q: np.ndarray
    limit: float
    order: float | None
    triple_orders: tuple
    errors: np.ndarray
    relative: np.ndarray
    note: str = ""

    def to_dict(self) -> dict:
        return {"h": self.h.tolist(), "q": self.q.tolist(), "limit": self.limit, "order": self.order,
                "triple_orders": list(self.triple_orders), "errors": self.errors.tolist(),
                "relative_errors": self.relative.tolist(), "note": self.note}


def triple_order(h, q) -> float | None:
    """The order ``p`` of three levels (``h`` decreasing), or None when their two differences
    differ in sign or vanish, or the order falls outside :data:`ORDER_RANGE`."""
    h1, h2, h3 = (float(x) for x in h)
    q1, q2, q3 = (float(x) for x in q)
    d12, d23 = q1 - q2, q2 - q3
    if d12 == 0 or d23 == 0 or (d12 > 0) != (d23 > 0):
        return None
    target = d12 / d23

    def ratio(p):
        return (h1**p - h2**p) / (h2**p - h3**p)

    lo, hi = ORDER_RANGE
    if not min(ratio(lo), ratio(hi)) <= target <= max(ratio(lo), ratio(hi)):
        return None
    for _ in range(200):  # the ratio grows with p: bisection to round-off
        mid = 0.5 * (lo + hi)
        if ratio(mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _fit(h, q, p) -> tuple[float, float, float]:
    """(q0, C, residual sum of squares) of the least-squares fit at order ``p``."""
    A = np.column_stack([np.ones_like(h), h**p])
    coef, *_ = np.linalg.lstsq(A, q, rcond=None)
    r = q - A @ coef
    return float(coef[0]), float(coef[1]), float(r @ r)


def richardson(h, q) -> RichardsonFit:
    """Extrapolate ``q`` (n,) at grid sizes ``h`` (n,) [any unit, > 0], n >= 3 (module docstring).
    Raises :class:`ConfigError` for fewer than three levels, repeated or non-positive sizes, or
    non-finite values."""
    h = np.asarray(h, float).reshape(-1)
    q = np.asarray(q, float).reshape(-1)
    if h.shape != q.shape or len(h) < 3:
        raise ConfigError(f"richardson: {len(h)} sizes and {len(q)} values: need the same number, at least 3")
    if not (np.all(np.isfinite(h)) and np.all(np.isfinite(q)) and np.all(h > 0)):
        raise ConfigError("richardson: sizes must be finite and > 0, values finite")
    order_ = np.argsort(-h, kind="stable")
    h, q = h[order_], q[order_]
    if np.any(np.diff(h) == 0):
        raise ConfigError(f"richardson: sizes {h.tolist()}: each size once")
    triples = tuple(triple_order(h[i:i + 3], q[i:i + 3]) for i in range(len(h) - 2))
    if any(t is None for t in triples):
        spread = float(np.ptp(q))
        limit = float(q[-1])
        note = ("the ladder is not in its asymptotic range (its differences change sign, or an order falls "
                f"outside {ORDER_RANGE}): the finest level stands for the limit, within the ladder's spread "
                f"{spread:.3g}")
        err = q - limit
        return RichardsonFit(h, q, limit, None, triples, err, err / max(abs(limit), 1e-300), note)
    if len(h) == 3:
        p = float(triples[0])
    else:
        from scipy.optimize import minimize_scalar

        p = float(minimize_scalar(lambda s: _fit(h, q, s)[2], bounds=ORDER_RANGE, method="bounded",
                                  options={"xatol": 1e-10}).x)
    q0 = _fit(h, q, p)[0]
    err = q - q0
    return RichardsonFit(h, q, q0, p, triples, err, err / max(abs(q0), 1e-300))
