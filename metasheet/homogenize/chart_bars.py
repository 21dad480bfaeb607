"""The design chart's error bars: the 95 % interval of each grid point's mean over its seeds.

With k seeds at one point, the interval of that point's mean is ``t_{k-1} s / sqrt(k)``: at
k = 2, ``t_1 = 12.7`` makes it nine standard deviations wide, a bar that says nothing. The
chart's points share the family, the cell count and the voxel edge, so their scatter from seed
to seed, relative to the mean (the coefficient of variation), can be pooled over the points:

    s_rel^2 = sum_p sum_i (x_pi / m_p - 1)^2 / sum_p (k_p - 1),   dof = sum_p (k_p - 1)

and each point's half-width is ``t_dof s_rel |m_p| / sqrt(k_p)`` (8 points at k = 2: dof 8,
``t_8 = 2.31``). That assumes one coefficient of variation across the sweep. Bartlett's test
of equal variances of the relative deviations checks it per constant. Where it fails
(p < :data:`HOMOGENEITY_P`), the scatter is pooled along each line of the chart instead (the
points sharing the second setting: on the paper's Polyfoam the shrink 0.2 foam's E_l scatters
by ~10 times more than the unshrunk one's), each line tested the same way, and a line that
fails keeps its per-point intervals. The record says which.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: Below this p-value of Bartlett's test the relative scatter is not pooled.
HOMOGENEITY_P = 0.05
CONFIDENCE = 0.95


@dataclass(frozen=True)
class ChartBars:
    """One constant's means and 95 % half-widths at each grid point of a chart.

    Attributes
    ----------
    name : the constant (a chart.csv column).
    points : (p, 2) the two settings of each point (the family's axes, in chart order).
    means, halfwidths : (p,) unit of the constant; halfwidths 0 where a point has one seed.
    k : (p,) seeds per point.
    pooled : "chart" (the relative scatter pooled over every point), "lines" (over each line
        of the second setting; ``lines`` says which line pooled), or "points" (none pooled).
    rel_sd : the relative standard deviation pooled over the chart [-] (NaN below 2 seeds).
    dof : its degrees of freedom, sum of (k_p - 1).
    bartlett_p : p-value of the chart-wide homogeneity test (NaN where it cannot run: a point
        with zero scatter, or fewer than 2 points with seeds to compare).
    lines : with pooled "lines", per second-setting value: (pooled?, rel_sd, dof, bartlett_p).
    """

    name: str
    points: np.ndarray
    means: np.ndarray
    halfwidths: np.ndarray
    k: np.ndarray
    pooled: str
    rel_sd: float
    dof: int
    bartlett_p: float
    lines: dict | None = None

    def to_json(self) -> dict:
        """The record beside the chart (no per-point arrays: those are chart.csv's rows)."""
        out = {"bars": self.pooled, "rel_sd": _r(self.rel_sd), "dof": int(self.dof), "bartlett_p": _r(self.bartlett_p),
               "seeds_per_point": sorted({int(v) for v in self.k})}
        if self.lines is not None:
            out["lines"] = {f"{v:g}": {"pooled": bool(ok), "rel_sd": _r(sd), "dof": int(d), "bartlett_p": _r(pv)}
                            for v, (ok, sd, d, pv) in self.lines.items()}
        return out


def chart_bars(rows: Sequence[Mapping], name: str, first: str, second: str) -> ChartBars:
    """The bars of constant ``name`` over chart rows (one per point and seed, chart.csv's).

    ``first``, ``second``: the family's two axes (:data:`~.chart.FAMILY_AXES`); points are
    listed in ascending (second, first) order, as the picture draws them.
    """
    if not rows:
        raise ConfigError("rows: empty chart: nothing to put bars on")
    if name not in rows[0]:
        raise ConfigError(f"name: {name!r}: not a chart column ({', '.join(rows[0])})")
    groups: dict[tuple[float, float], list[float]] = {}
    for r in rows:
        groups.setdefault((float(r[first]), float(r[second])), []).append(float(r[name]))
    keys = sorted(groups, key=lambda p: (p[1], p[0]))
    vals = [np.asarray(groups[p]) for p in keys]
    if not all(np.isfinite(v).all() for v in vals):
        raise ConfigError(f"rows: column {name!r} has non-finite values")
    k = np.array([v.size for v in vals])
    means = np.array([v.mean() for v in vals])
    hw = np.array([_t(v.size - 1) * v.std(ddof=1) / np.sqrt(v.size) if v.size > 1 else 0.0 for v in vals])
    everywhere = np.ones(len(keys), bool)
    ok, rel_sd, dof, p = _pool(vals, means, everywhere)
    if ok:
        return ChartBars(name, np.array(keys), means, _pooled(means, k, rel_sd, dof), k, "chart", rel_sd, dof, p)
    if dof == 0:  # one seed everywhere: no bars
        return ChartBars(name, np.array(keys), means, hw, k, "points", rel_sd, dof, p)
    lines = {}
    for b in sorted({q[1] for q in keys}):
        on = np.array([q[1] == b for q in keys])
        lines[b] = _pool(vals, means, on)
        if lines[b][0]:
            hw[on] = _pooled(means[on], k[on], lines[b][1], lines[b][2])
    return ChartBars(name, np.array(keys), means, hw, k, "lines", rel_sd, dof, p, lines)


def _pool(vals: list[np.ndarray], means: np.ndarray, on: np.ndarray) -> tuple[bool, float, int, float]:
    """(poolable, relative sd, dof, Bartlett p) of the points ``on`` (mask over ``vals``).

    Poolable when the test does not reject (NaN, untestable, pools: zero scatter everywhere
    is exact) and there is something to pool (dof >= 1)."""
    rel = [v / m - 1.0 for v, m, o in zip(vals, means, on) if o and v.size > 1 and m != 0.0]
    dof = int(sum(r.size - 1 for r in rel))
    if dof == 0:
        return False, float("nan"), 0, float("nan")
    p = _bartlett(rel)
    return bool(not p < HOMOGENEITY_P), float(np.sqrt(sum(float(r @ r) for r in rel) / dof)), dof, p


def _pooled(means: np.ndarray, k: np.ndarray, rel_sd: float, dof: int) -> np.ndarray:
    return np.where(k > 1, _t(dof) * rel_sd * np.abs(means) / np.sqrt(k), 0.0)


def _t(dof: int) -> float:
    from scipy import stats  # here: scipy.stats costs every command 0.3 s to import

    return float(stats.t.ppf(0.5 + CONFIDENCE / 2, dof))


def _r(v: float):
    return None if not np.isfinite(v) else round(float(v), 6)


def _bartlett(rel: list[np.ndarray]) -> float:
    """Bartlett's p-value for equal variances of the groups, NaN where it cannot run."""
    if len(rel) < 2 or any(np.var(r, ddof=1) == 0.0 for r in rel):
        return float("nan")
    from scipy import stats

    return float(stats.bartlett(*rel).pvalue)
