"""Design chart: inverse look-up against a synthetic chart with a known answer, and the stage."""

import numpy as np
import pytest

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


def test_chart_stage_small_sweep(tmp_path):
    from pathlib import Path

    from metasheet.executor import Executor
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages import chart as stage

    root = Path(__file__).resolve().parents[1]
    p = stage.ChartParams(density_min=0.3, density_max=0.4, density_steps=2, stretch_min=1.0, stretch_max=2.5,
                          stretch_steps=2, resolution=16)
    ctx = StageContext("chart", p, tmp_path, {}, root, executor=Executor(workers=1))
    stage.run(ctx)
    table = parse_csv((tmp_path / "chart.csv").read_text())
    assert len(table["E_t"]) == 4
    # stretching the cells along l softens E_l: alpha grows with stretch at fixed density
    for d in (0.3, 0.4):
        a = table["alpha"][np.isclose(table["target_density"], d)]
        assert a[1] > a[0] + 20
    assert (tmp_path / "chart.png").stat().st_size > 20_000
    with pytest.raises(ValueError):
        stage.ChartParams(density_min=0.3, density_max=0.2)


def test_chart_error_bars_are_the_95_percent_interval_of_the_mean():
    from metasheet.viz.homogenize import ci95_halfwidth

    v = np.array([1.0, 2.0, 4.0])
    assert ci95_halfwidth(v) == pytest.approx(4.302652729749464 * np.std(v, ddof=1) / np.sqrt(3), rel=1e-12)
    assert ci95_halfwidth(v[:1]) == 0.0
