"""Graded sheets: the orient stage reads per-region constants off the homogenize design chart."""

from pathlib import Path

import meshio
import numpy as np
import pytest

from metasheet.errors import InfeasibleError
from metasheet.runtime.executor import Executor
from metasheet.homogenize.chart import lookup, parse_csv, to_csv
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import chart as chart_stage
from metasheet.pipeline.stages import orient as orient_stage

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def chart_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("chart")
    p = chart_stage.ChartParams(density_min=0.3, density_max=0.4, density_steps=2, stretch_min=1.0,
                                stretch_max=2.5, stretch_steps=2, resolution=16)
    chart_stage.run(StageContext("chart", p, d, {}, ROOT, executor=Executor()))
    return d


@pytest.fixture(scope="module")
def synthetic_chart(tmp_path_factory):
    """A chart stage's chart.csv written from known power laws (test_homogenize_chart's): the
    orient stage's look-up without homogenising a cell."""
    from test_homogenize_chart import _synthetic_rows

    d = tmp_path_factory.mktemp("synthetic_chart")
    (d / "chart.csv").write_text(to_csv(_synthetic_rows()))
    return d


def run_orient(tmp_path, chart_dir, table):
    p = orient_stage.OrientParams(mesh_size=10.0, grading={"table": table}, picture=False)
    ctx = StageContext("orient", p, tmp_path, {"chart": chart_dir}, ROOT)
    orient_stage.run(ctx)
    return meshio.read(tmp_path / "sheet.vtu")


@pytest.mark.parametrize("chart", ["synthetic_chart", pytest.param("chart_dir", marks=pytest.mark.slow)])
def test_graded_constants_come_from_the_chart(tmp_path, chart, request):
    """On the chart stage's own chart (slow: it homogenises four cells) and on a synthetic chart;
    the slow case's default-selection sibling: the synthetic_chart case."""
    chart_dir = request.getfixturevalue(chart)
    table = parse_csv((chart_dir / "chart.csv").read_text())
    a_lo, a_hi = np.percentile(table["alpha"], [30, 70])
    regions = {"hub": {"density": 0.38, "alpha": float(a_lo)}, "arms": {"density": 0.32, "alpha": float(a_hi)},
               "tips": {"density": 0.35, "alpha": float(a_lo)}}
    mesh = run_orient(tmp_path, chart_dir, regions)
    cd = {k: v[0] for k, v in mesh.cell_data.items()}
    for name, target in regions.items():
        sel = np.isclose(cd["density"], target["density"]) & np.isclose(cd["alpha"], target["alpha"])
        assert sel.any(), name
        expect = lookup(table, relative_density=target["density"], alpha=target["alpha"])
        for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l"):
            assert np.allclose(cd[k][sel], expect[k], rtol=1e-9), (name, k)
    assert not np.isclose(np.unique(cd["E_t"]), np.unique(cd["E_t"])[0]).all()  # regions differ


def test_target_outside_the_chart_is_an_error(tmp_path, synthetic_chart):
    with pytest.raises(InfeasibleError):
        run_orient(tmp_path, synthetic_chart, {r: {"density": 0.9, "alpha": 50.0} for r in ("hub", "arms", "tips")})
