"""Design chart: inverse look-up against a synthetic chart with a known answer, and the stage."""

import numpy as np
import pytest
from scipy import stats

from metasheet.errors import ConfigError, InfeasibleError
from metasheet.homogenize.chart import COLUMNS, lookup, parse_csv, to_csv


def _synthetic_rows():
    """E_t = 12 rho^2 s^0.3, E_l = 12 rho^2 / s^2 (power laws, log-bilinear-friendly)."""
    rows = []
    for d in np.linspace(0.1, 0.4, 7):
        for s in np.linspace(1.0, 3.0, 9):
            E_t, E_l = 12 * d**2 * s**0.3, 12 * d**2 / s**2
            rows.append({"target_density": d, "stretch": s, "seed": 0, "relative_density": d, "E_t": E_t,
                         "E_l": E_l, "nu_t": 0.3, "nu_tl": 0.3, "mu_l": 0.1 * E_l, "alpha": 100 - 100 * E_l / E_t,
                         "misfit": 0.0, "n_dof": 1, "solver": "splu"})
    return rows


def test_lookup_inverts_a_known_chart():
    rows = _synthetic_rows()
    d, s = 0.23, 2.2
    E_t, E_l = 12 * d**2 * s**0.3, 12 * d**2 / s**2
    r = lookup(rows, E_t=E_t, E_l=E_l)
    assert r["target_density"] == pytest.approx(d, rel=0.03)
    assert r["stretch"] == pytest.approx(s, rel=0.03)
    alpha = 100 - 100 * E_l / E_t
    r2 = lookup(parse_csv(to_csv(rows)), relative_density=d, alpha=alpha)
    assert r2["target_density"] == pytest.approx(d, rel=1e-3)
    assert r2["stretch"] == pytest.approx(s, rel=0.03)
    assert r2["alpha"] == pytest.approx(alpha, abs=0.5)


def test_lookup_refuses_unreachable_and_bad_targets():
    rows = _synthetic_rows()
    with pytest.raises(InfeasibleError, match="outside the chart"):
        lookup(rows, E_t=100.0, E_l=0.01)
    with pytest.raises(ConfigError, match="either"):
        lookup(rows, E_t=1.0)
    with pytest.raises(ConfigError, match="alpha"):
        lookup(rows, relative_density=0.2, alpha=150.0)


def test_csv_round_trip_is_exact():
    rows = _synthetic_rows()
    text = to_csv(rows)
    assert text.splitlines()[0].split(",") == list(COLUMNS)
    back = parse_csv(text)
    np.testing.assert_array_equal(back["E_l"], [r["E_l"] for r in rows])


@pytest.mark.parametrize("seeds", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_chart_stage_small_sweep(tmp_path, seeds):
    """Four points at 16^3, one or two seeds each. The slow two-seed case's default-selection
    sibling: the one-seed case (no scatter: no bars; test_chart_bars_* check the bars' pooling)."""
    from pathlib import Path

    from metasheet.runtime.executor import Executor
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages import chart as stage

    root = Path(__file__).resolve().parents[1]
    p = stage.ChartParams(density_min=0.3, density_max=0.4, density_steps=2, stretch_min=1.0, stretch_max=2.5,
                          stretch_steps=2, resolution=16, seeds=seeds)
    ctx = StageContext("chart", p, tmp_path, {}, root, executor=Executor(workers=1))
    summary = stage.run(ctx)
    table = parse_csv((tmp_path / "chart.csv").read_text())
    assert len(table["E_t"]) == 4 * seeds and len(set(table["seed"])) == seeds
    # stretching the cells along l softens E_l: alpha grows with stretch at fixed density
    for d in (0.3, 0.4):
        sel = np.isclose(table["target_density"], d)
        a = [table["alpha"][sel & (table["stretch"] == s)].mean() for s in (1.0, 2.5)]
        assert a[1] > a[0] + 20
    if seeds == 1:
        assert "bars" not in summary  # one seed per point: no scatter to pool
    else:
        assert set(summary["bars"]) == {"E_t", "E_l", "nu_t", "nu_tl", "mu_l", "alpha"}
        assert all(b["dof"] == 4 and b["seeds_per_point"] == [2] for b in summary["bars"].values())
    assert (tmp_path / "chart.png").stat().st_size > 20_000
    with pytest.raises(ValueError):
        stage.ChartParams(density_min=0.3, density_max=0.2)


def _rows(values: dict, first="infill_percentage", second="kgon_x_shrink"):
    """Chart rows of one constant "E_l": values {(first, second): [seed values]}."""
    return [{first: a, second: b, "seed": i, "E_l": v} for (a, b), vs in values.items() for i, v in enumerate(vs)]


def test_chart_bars_pool_a_homogeneous_relative_scatter():
    from metasheet.homogenize.chart_bars import chart_bars

    # 8 points, 2 seeds, one coefficient of variation (5 %) at means spanning 100x: pooled
    rng = np.random.default_rng(4)
    means = {(a, b): 0.01 * a**2 * (1 + b) for a in (10.0, 18.0, 26.0, 34.0) for b in (0.2, 1.0)}
    vals = {p: m * (1 + 0.05 * rng.normal(size=2)) for p, m in means.items()}
    bars = chart_bars(_rows(vals), "E_l", "infill_percentage", "kgon_x_shrink")
    rel = np.concatenate([v / v.mean() - 1 for v in vals.values()])
    assert bars.pooled == "chart" and bars.dof == 8
    assert bars.rel_sd == pytest.approx(np.sqrt(rel @ rel / 8), rel=1e-12)  # the pooled formula, by hand
    order = sorted(vals, key=lambda p: (p[1], p[0]))
    m = np.array([vals[p].mean() for p in order])
    assert np.allclose(bars.means, m, rtol=1e-14)
    assert np.allclose(bars.halfwidths, stats.t.ppf(0.975, 8) * bars.rel_sd * m / np.sqrt(2), rtol=1e-12)
    # per point (k = 2) the bars would be t_1 / t_8 = 5.5 times wider on average
    per = np.array([stats.t.ppf(0.975, 1) * vals[p].std(ddof=1) / np.sqrt(2) for p in order])
    assert np.median(per / bars.halfwidths) > 2


def test_chart_bars_pool_along_lines_or_keep_per_point_intervals():
    from metasheet.homogenize.chart_bars import chart_bars

    # three seeds per point; the shrink-0.2 line scatters 10 % and the shrink-1 line 1 %, except
    # one shrink-1 point 20x noisier: the chart fails Bartlett, the 0.2 line pools, the 1 line not
    rng = np.random.default_rng(8)
    sd = {0.2: 0.1, 1.0: 0.01}
    vals = {(a, b): 1.0 + (0.2 if (a, b) == (10.0, 1.0) else sd[b]) * rng.normal(size=3)
            for a in (10.0, 18.0, 26.0) for b in (0.2, 1.0)}
    bars = chart_bars(_rows(vals), "E_l", "infill_percentage", "kgon_x_shrink")
    assert bars.pooled == "lines" and bars.bartlett_p < 0.05
    assert bars.lines[0.2][0] and not bars.lines[1.0][0] and bars.lines[0.2][2] == 6
    line = [vals[(a, 0.2)] for a in (10.0, 18.0, 26.0)]
    rel = np.concatenate([v / v.mean() - 1 for v in line])
    assert bars.lines[0.2][1] == pytest.approx(np.sqrt(rel @ rel / 6), rel=1e-12)
    assert np.allclose(bars.halfwidths[:3], stats.t.ppf(0.975, 6) * bars.lines[0.2][1]
                       * np.array([v.mean() for v in line]) / np.sqrt(3), rtol=1e-12)
    v = vals[(10.0, 1.0)]  # the first point of the shrink-1 line: its own interval
    assert bars.halfwidths[3] == pytest.approx(4.302652729749464 * np.std(v, ddof=1) / np.sqrt(3), rel=1e-12)
    assert bars.to_json()["lines"]["0.2"]["pooled"] is True
    one = chart_bars(_rows({p: v[:1] for p, v in vals.items()}), "E_l", "infill_percentage", "kgon_x_shrink")
    assert (one.halfwidths == 0).all() and one.dof == 0 and one.to_json()["rel_sd"] is None
    with pytest.raises(ConfigError, match="^name"):
        chart_bars(_rows(vals), "E_x", "infill_percentage", "kgon_x_shrink")
