"""Statistics over realisations: homogenised constants with error bars (issue 43).

A stochastic foam's apparent constants are random variables: each realisation (an
independent seed) of a periodic volume of ``n`` cells gives one value. This module is the
library layer, pure functions over numpy arrays with no I/O:

- :func:`ensemble_stats`: per constant the mean, the sample standard deviation (ddof=1)
  and the half-width of the two-sided confidence interval of the mean with Student's t,
  ``h = t_{(1+c)/2, k-1} * s / sqrt(k)`` (c = 0.95).
- :func:`required_realisations` / :func:`plan_realisations`: the smallest k with
  ``t_{(1+c)/2, k-1} * cv / sqrt(k) <= target`` (cv = s / |mean|, measured on a pilot),
  and its cost at a measured time per realisation.
- :func:`size_trend`: the bias with the size of the volume, fitted by weighted least
  squares as ``mean(n) = a + b * n**(-1/3)``; ``a`` is the value extrapolated to an
  infinite volume. Why ``n**(-1/3)``: the apparent properties of a finite volume are biased
  by the layer of cells that feels the boundary (for periodic conditions, the imposed
  periodicity), whose volume fraction is the surface-to-volume ratio ~ ``l / L``; with a
  fixed cell size ``l`` and ``n`` cells, ``L = n**(1/3) * l``, so ``1 / L`` ~ ``n**(-1/3)``
  (Kanit et al., Int. J. Solids Struct. 40, 2003). It is a first-order model: the
  reduced chi-square says when the data disagree with it.

JSON schemas (all numbers plain floats; a non-finite number is written ``null``):

``ci95`` block for ``homogenize/constants.json`` (:func:`ci95_block`), beside the means::

    "ci95": {"confidence": 0.95, "k": 5, "n_cells": 8,
             "method": "Student t interval of the mean of k independent realisations",
             "halfwidth":     {"E_t": .., "E_l": .., "nu_t": .., "nu_tl": .., "mu_l": ..},
             "rel_halfwidth": {...},   # halfwidth / |mean| [-]
             "std":           {...},   # sample std, ddof = 1, same unit as the constant
             "C_halfwidth": [[..] * 6] * 6}   # only when C was given, [MPa]

``homogenize/convergence.json`` (:func:`convergence_summary`)::

    {"schema": "metasheet.convergence/1", "confidence": 0.95,
     "trend_model": "mean(n) = a + b * n**(-1/3)",
     "constants": ["E_t", ...],                    # the scalar constants, in order
     "sizes": [{"n_cells": 8, "k": 5, "seconds_per_realisation": 41.0 | null,
                "constants": {"E_t": {"mean", "std", "halfwidth", "rel_halfwidth", "k"}, ...}},
               ...],                               # ascending n_cells
     "trend_sizes": [4, 8, ...],                   # the sizes the trend is fitted over (>= trend_min_cells)
     "trend": {"E_t": {"a", "se_a", "halfwidth_a", "b", "se_b", "halfwidth_b",
                       "chi2_reduced" (null with 2 sizes), "significant",
                       "extrapolated" (a, or null when not significant),
                       "verdict": "size trend detected" | "no size trend detected"}, ...},
     "plan": {...} | null}                         # :func:`plan_to_json`, when given

Conventions: constants in MPa (moduli) or - (Poisson's ratios); ``C`` (6, 6) in MPa,
Voigt order 11, 22, 33, 23, 13, 12 with engineering shear.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as _st

from ..errors import ConfigError, InfeasibleError, check_range

SCHEMA = "metasheet.convergence/1"
TREND_MODEL = "mean(n) = a + b * n**(-1/3)"


@dataclass(frozen=True)
class ConstantStats:
    """One constant over k realisations.

    Attributes
    ----------
    name : the constant ("E_l", "C", ...).
    mean, std, halfwidth : float, or (6, 6) float for C; std has ddof=1; halfwidth is the
        half-width of the ``confidence`` interval of the mean; unit of the constant.
    rel_halfwidth : halfwidth / |mean| [-]; NaN where the mean is 0 and the half-width is not.
    k : number of realisations. confidence : e.g. 0.95.
    """

    name: str
    mean: float | np.ndarray
    std: float | np.ndarray
    halfwidth: float | np.ndarray
    rel_halfwidth: float | np.ndarray
    k: int
    confidence: float = 0.95


@dataclass(frozen=True)
class RealisationPlan:
    """Realisations needed for a relative half-width target, per constant and overall.

    ``rel_target``: half-width / |mean| [-]; ``k_required``: constant -> smallest k meeting it
    alone; ``governing``: the constant needing the most, ``k`` its k; ``cost_s`` [s] =
    ``k * seconds_per_realisation`` (the measured time of one realisation, NaN if not given).
    """

    rel_target: float
    confidence: float
    k_required: dict
    governing: str
    k: int
    seconds_per_realisation: float
    cost_s: float


@dataclass(frozen=True)
class SizeTrend:
    """Weighted least-squares fit ``mean(n) = a + b * n**(-1/3)`` over the sizes.

    Attributes
    ----------
    a, se_a : the value extrapolated to n -> inf and its standard error (unit of the constant).
    b, se_b : the slope in ``n**(-1/3)`` and its standard error.
    halfwidth_a, halfwidth_b : ``q * se``, q the two-sided quantile of ``confidence``.
    chi2_reduced : chi-square per degree of freedom of the fit (NaN with 2 sizes); above 1
        the standard errors are inflated by its square root (Birge ratio).
    significant : |b| > halfwidth_b, the slope's interval excludes 0. When False, report
        "no size trend detected" rather than the extrapolation.
    """

    a: float
    se_a: float
    b: float
    se_b: float
    halfwidth_a: float
    halfwidth_b: float
    chi2_reduced: float
    significant: bool
    confidence: float = 0.95

    def value_at(self, n_cells) -> np.ndarray:
        """The fitted mean at ``n_cells`` (array-like, > 0)."""
        return self.a + self.b * np.asarray(n_cells, float) ** (-1.0 / 3.0)


def t_quantile(k: int, confidence: float = 0.95) -> float:
    """Two-sided Student quantile ``t_{(1+c)/2, k-1}`` for the mean of k samples."""
    return float(_st.t.ppf(0.5 + 0.5 * confidence, k - 1))


def _finite(field: str, values) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{field}: expected numbers, got {values!r}") from None
    bad = ~np.isfinite(arr)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ConfigError(f"{field}: {arr[where]} at index {where}: expected finite numbers (no NaN or inf)")
    return arr


def constant_stats(name: str, values, *, confidence: float = 0.95) -> ConstantStats:
    """Statistics of one constant: ``values`` (k,) or (k, 6, 6) float, one row per realisation."""
    check_range("confidence", confidence, 0, 1, lo_open=True, hi_open=True)
    v = _finite(f"realisations[{name!r}]", values)
    if v.ndim == 0 or v.shape[0] < 2:
        k = 0 if v.ndim == 0 else v.shape[0]
        raise ConfigError(f"realisations[{name!r}]: k = {k} value(s): need k >= 2 realisations "
                          f"for a standard deviation (shape (k,) or (k, 6, 6))")
    k = v.shape[0]
    mean = v.mean(axis=0)
    std = v.std(axis=0, ddof=1)
    half = t_quantile(k, confidence) * std / math.sqrt(k)
    with np.errstate(divide="ignore", invalid="ignore"):
        # an exact zero with an exact zero spread (a laminate's C_14, say) is known to 0 %
        rel = np.where(half == 0, 0.0, half / np.abs(mean))
    rel = np.where(np.isinf(rel), np.nan, rel)
    conv = float if v.ndim == 1 else np.asarray
    return ConstantStats(name, conv(mean), conv(std), conv(half), conv(rel), int(k), float(confidence))


def ensemble_stats(realisations: Mapping[str, object], *, confidence: float = 0.95) -> dict[str, ConstantStats]:
    """Per-constant statistics over the realisations of one size.

    Parameters
    ----------
    realisations : name -> (k,) float (E_t, E_l, nu_t, nu_tl, mu_l [MPa, -]) or
        (k, 6, 6) float (C [MPa]); every constant must have the same k.
    confidence : of the interval of the mean, in (0, 1).

    Returns a dict name -> :class:`ConstantStats`, in the order given.
    """
    if not realisations:
        raise ConfigError("realisations: empty: expected at least one constant")
    out = {name: constant_stats(name, v, confidence=confidence) for name, v in realisations.items()}
    ks = {name: s.k for name, s in out.items()}
    if len(set(ks.values())) > 1:
        raise ConfigError(f"realisations: unequal numbers of realisations {ks}: every constant needs the same k")
    return out


def required_realisations(rel_target: float, std: float, mean: float, *, confidence: float = 0.95,
                          k_max: int = 100_000) -> int:
    """Smallest k >= 2 with ``t_{(1+c)/2, k-1} * (std / |mean|) / sqrt(k) <= rel_target``.

    ``std`` and ``mean`` are measured (on a pilot ensemble); the normal approximation
    ``k0 = (z * cv / target)**2`` is a lower bound (t > z), and k is stepped up from there.
    The half-width reached with k is itself random: with a small pilot it meets the target
    about half of the time; lower the target for a margin.
    """
    check_range("rel_target", rel_target, 0, None, lo_open=True)
    check_range("confidence", confidence, 0, 1, lo_open=True, hi_open=True)
    check_range("std", std, 0, None)
    check_range("mean", mean, None, None)
    if std == 0:
        return 2
    if mean == 0:
        raise ConfigError(f"mean: 0 with std {std:g}: a relative target needs a nonzero mean")
    cv = std / abs(mean)
    z = float(_st.norm.ppf(0.5 + 0.5 * confidence))
    meets = lambda k: t_quantile(k, confidence) * cv / math.sqrt(k) <= rel_target
    lo = max(2, math.ceil((z * cv / rel_target) ** 2))  # normal approximation: a lower bound
    hi = lo
    while not meets(hi):  # t_{k-1} / sqrt(k) falls with k: double, then bisect
        lo, hi = hi, 2 * hi
    while hi - lo > 1 and not meets(lo):  # invariant: meets(hi)
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if meets(mid) else (mid, hi)
    k = lo if meets(lo) else hi
    if k > k_max:
        raise InfeasibleError(f"rel_target: {rel_target:g} with cv {cv:.3g} needs {k} realisations, "
                              f"more than k_max = {k_max}")
    return int(k)


def plan_realisations(stats: Mapping[str, ConstantStats], rel_target: float, *,
                      seconds_per_realisation: float | None = None, names: Sequence[str] | None = None
                      ) -> RealisationPlan:
    """Realisations for every scalar constant of ``stats`` (or ``names``) to meet ``rel_target``.

    ``stats`` come from a pilot (:func:`ensemble_stats`); ``seconds_per_realisation`` [s] is
    the measured time of one realisation at that size. Array constants (C) are skipped.
    """
    names = list(names) if names is not None else [n for n, s in stats.items() if np.ndim(s.mean) == 0]
    missing = [n for n in names if n not in stats]
    if missing or not names:
        raise ConfigError(f"names: {names}: expected scalar constants of stats (has {list(stats)})")
    sec = float("nan")
    if seconds_per_realisation is not None:
        sec = float(check_range("seconds_per_realisation", seconds_per_realisation, 0, None))
    conf = stats[names[0]].confidence
    req = {n: required_realisations(rel_target, stats[n].std, stats[n].mean, confidence=conf) for n in names}
    governing = max(req, key=req.get)
    k = req[governing]
    return RealisationPlan(float(rel_target), conf, req, governing, k, sec, k * sec)


def size_trend(n_cells, means, halfwidths, k, *, confidence: float = 0.95) -> SizeTrend:
    """Fit ``mean(n) = a + b * n**(-1/3)`` over m >= 2 sizes by weighted least squares.

    Parameters
    ----------
    n_cells : (m,) number of cells of each volume, distinct and > 0.
    means, halfwidths : (m,) float, the mean and its half-width at each size (from
        :func:`ensemble_stats` at the same ``confidence``), unit of the constant.
    k : int or (m,) int >= 2, realisations per size: the standard error of mean i is
        ``halfwidths[i] / t_{(1+c)/2, k_i-1}`` and the weights are its inverse squares.

    The standard errors take those of the means as known; with m >= 3 sizes they are
    inflated by ``sqrt(chi2_reduced)`` when it exceeds 1 (the model misses the data). All
    half-widths 0 (a deterministic cell): unweighted fit, errors from the residuals.
    """
    check_range("confidence", confidence, 0, 1, lo_open=True, hi_open=True)
    n = _finite("n_cells", n_cells).ravel()
    y = _finite("means", means).ravel()
    hw = _finite("halfwidths", halfwidths).ravel()
    kk = np.broadcast_to(_finite("k", k), n.shape) if np.ndim(k) == 0 else _finite("k", k).ravel()
    m = n.size
    for field, arr in (("means", y), ("halfwidths", hw), ("k", kk)):
        if arr.size != m:
            raise ConfigError(f"{field}: {arr.size} values for {m} sizes (n_cells): expected one per size")
    if m < 2:
        raise ConfigError(f"n_cells: {m} size(s): need at least 2 distinct sizes for a trend")
    if (n <= 0).any():
        raise ConfigError(f"n_cells: {n.tolist()}: every size must be > 0")
    if np.unique(n).size != m:
        raise ConfigError(f"n_cells: {n.tolist()}: sizes must be distinct")
    if (hw < 0).any():
        raise ConfigError(f"halfwidths: {hw.tolist()}: must be >= 0")
    if (kk < 2).any() or (kk != np.round(kk)).any():
        raise ConfigError(f"k: {kk.tolist()}: realisations per size must be integers >= 2")
    x = n ** (-1.0 / 3.0)  # ~ 1 / L at a fixed cell size
    se = hw / np.array([t_quantile(int(ki), confidence) for ki in kk])
    exact = not (se > 0).any()
    if not exact and (se == 0).any():  # one exact size among noisy ones: nearly infinite weight
        se = np.where(se > 0, se, 1e-6 * se[se > 0].min())
    w = np.ones(m) if exact else 1.0 / se**2
    a, b, cov = _wls_line(x, y, w)
    dof = m - 2
    chi2 = float(np.sum(w * (y - a - b * x) ** 2))
    chi2_red = chi2 / dof if dof > 0 else float("nan")
    if exact:
        # unknown common variance: estimate it from the residuals, Student quantile
        cov = cov * (chi2_red if dof > 0 else 0.0)
        q = float(_st.t.ppf(0.5 + 0.5 * confidence, dof)) if dof > 0 else 0.0
    else:
        cov = cov * (max(1.0, chi2_red) if dof > 0 else 1.0)
        q = float(_st.norm.ppf(0.5 + 0.5 * confidence))
    se_a, se_b = (float(math.sqrt(max(cov[i, i], 0.0))) for i in (0, 1))
    significant = bool(abs(b) > q * se_b) and b != 0.0
    return SizeTrend(a, se_a, b, se_b, q * se_a, q * se_b, chi2_red, significant, float(confidence))


def _wls_line(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[float, float, np.ndarray]:
    """``y = a + b x`` weighted by ``w`` (m,): a, b and the unscaled covariance (2, 2)."""
    if np.ptp(y) == 0:  # a flat answer (a laminate): exactly zero slope, no rounding noise
        a, b = float(y[0]), 0.0
    else:
        xm, ym = np.average(x, weights=w), np.average(y, weights=w)
        b = float(np.sum(w * (x - xm) * (y - ym)) / np.sum(w * (x - xm) ** 2))
        a = float(ym - b * xm)
    X = np.stack([np.ones_like(x), x], axis=1)
    cov = np.linalg.inv(X.T @ (w[:, None] * X))
    return a, b, cov


def _num(v):
    """A float, or nested lists of floats, with non-finite values as None (strict JSON)."""
    if np.ndim(v) == 0:
        f = float(v)
        return f if math.isfinite(f) else None
    return [_num(e) for e in v]


def stats_to_json(s: ConstantStats) -> dict:
    """``{"mean", "std", "halfwidth", "rel_halfwidth", "k"}`` of one constant."""
    return {"mean": _num(s.mean), "std": _num(s.std), "halfwidth": _num(s.halfwidth),
            "rel_halfwidth": _num(s.rel_halfwidth), "k": s.k}


def trend_to_json(t: SizeTrend) -> dict:
    """One constant's entry of ``convergence.json``'s ``trend``."""
    return {"a": _num(t.a), "se_a": _num(t.se_a), "halfwidth_a": _num(t.halfwidth_a),
            "b": _num(t.b), "se_b": _num(t.se_b), "halfwidth_b": _num(t.halfwidth_b),
            "chi2_reduced": _num(t.chi2_reduced), "significant": t.significant,
            "extrapolated": _num(t.a) if t.significant else None,
            "verdict": "size trend detected" if t.significant else "no size trend detected"}


def plan_to_json(p: RealisationPlan) -> dict:
    """``{"rel_target", "confidence", "k_required", "governing", "k", "seconds_per_realisation", "cost_s"}``."""
    return {"rel_target": p.rel_target, "confidence": p.confidence, "k_required": dict(p.k_required),
            "governing": p.governing, "k": p.k, "seconds_per_realisation": _num(p.seconds_per_realisation),
            "cost_s": _num(p.cost_s)}


def ci95_block(stats: Mapping[str, ConstantStats], n_cells: int) -> dict:
    """The ``ci95`` block of ``constants.json`` (schema in the module docstring)."""
    check_range("n_cells", n_cells, 0, None, lo_open=True)
    first = next(iter(stats.values()), None)
    if first is None:
        raise ConfigError("stats: empty: expected at least one constant")
    scalars = {n: s for n, s in stats.items() if np.ndim(s.mean) == 0}
    block = {"confidence": first.confidence, "k": first.k, "n_cells": int(n_cells),
             "method": "Student t interval of the mean of k independent realisations",
             "halfwidth": {n: _num(s.halfwidth) for n, s in scalars.items()},
             "rel_halfwidth": {n: _num(s.rel_halfwidth) for n, s in scalars.items()},
             "std": {n: _num(s.std) for n, s in scalars.items()}}
    if "C" in stats:
        block["C_halfwidth"] = _num(stats["C"].halfwidth)
    return block


def convergence_summary(n_cells: Sequence[int], per_size: Sequence[Mapping[str, ConstantStats]], *,
                        seconds_per_realisation: Sequence[float | None] | None = None,
                        plan: RealisationPlan | None = None, trend_min_cells: int = 1) -> dict:
    """``convergence.json`` (schema in the module docstring) for a cell-size study.

    Parameters
    ----------
    n_cells : (m,) cells per volume; per_size : m dicts from :func:`ensemble_stats`, one per
        size, with the same constants. seconds_per_realisation : (m,) [s] or None.
    plan : a :class:`RealisationPlan` to record (at the chosen size), or None.
    trend_min_cells : the smallest size the trend is fitted over (smaller volumes stay in
        ``sizes``): below a few cells the bias is not yet ``~ n**(-1/3)`` and the smallest size,
        the most precise, would decide the extrapolation alone.
    The trend is fitted for every scalar constant when >= 2 sizes are >= ``trend_min_cells``.
    """
    check_range("trend_min_cells", trend_min_cells, 1, None)
    if len(per_size) != len(n_cells) or not per_size:
        raise ConfigError(f"per_size: {len(per_size)} entries for {len(n_cells)} sizes (n_cells): expected one per size, >= 1")
    secs = list(seconds_per_realisation) if seconds_per_realisation is not None else [None] * len(n_cells)
    if len(secs) != len(n_cells):
        raise ConfigError(f"seconds_per_realisation: {len(secs)} values for {len(n_cells)} sizes")
    names = [n for n, s in per_size[0].items() if np.ndim(s.mean) == 0]
    for i, st in enumerate(per_size):
        if [n for n in st if np.ndim(st[n].mean) == 0] != names:
            raise ConfigError(f"per_size[{i}]: constants {list(st)}: expected {names} as at the first size")
    order = np.argsort(np.asarray(n_cells, float), kind="stable")
    sizes = [{"n_cells": int(n_cells[i]), "k": next(iter(per_size[i].values())).k,
              "seconds_per_realisation": None if secs[i] is None else float(secs[i]),
              "constants": {n: stats_to_json(per_size[i][n]) for n in names}} for i in order]
    fitted = [i for i in order if n_cells[i] >= trend_min_cells]
    trend = {}
    if len(fitted) >= 2:
        for name in names:
            ss = [per_size[i][name] for i in fitted]
            t = size_trend([n_cells[i] for i in fitted], [s.mean for s in ss], [s.halfwidth for s in ss],
                           [s.k for s in ss], confidence=ss[0].confidence)
            trend[name] = trend_to_json(t)
    return {"schema": SCHEMA, "confidence": next(iter(per_size[0].values())).confidence,
            "trend_model": TREND_MODEL, "constants": names, "sizes": sizes,
            "trend_sizes": [int(n_cells[i]) for i in fitted] if trend else [], "trend": trend,
            "plan": None if plan is None else plan_to_json(plan)}
