"""The scale-separation map (issue 63): its statistics and trend against exact answers, and the
``scalemap`` stage end to end on a small sheet (orient -> scalemap -> report).

The sheet is the 10 mm-wide tripod of tests/test_sheet_stage.py printed with a 0.8 mm bead at
0.5 mm voxels (seconds); the DNS itself is validated in tests/test_sheet_dns.py, the plate cell
in tests/test_homogenize_plate.py, and the comparison they feed in tests/test_sheet_plate.py.
"""

import json
import math

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.homogenize.ensemble import t_quantile
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline
from metasheet.studies.scale_map import fit_trend, interval, log_interval, trends, verdict
from test_sheet_stage import DESIGN, SHEET


def test_fit_trend_recovers_an_exact_power_law():
    a, b = 0.17, 0.96
    n = np.array([0.1, 0.3, 0.8, 2.0])
    r = np.exp(-a * n ** -b)  # prints softer than the continuum
    tr = fit_trend(n, r)
    assert tr.a == pytest.approx(a, rel=1e-12) and tr.b == pytest.approx(b, rel=1e-12)
    assert tr.scatter == pytest.approx(0.0, abs=1e-12) and tr.points == 4
    for band, nb in tr.n_within.items():  # at n_band the fitted |log r| is exactly log(1 + band)
        assert a * nb ** -b == pytest.approx(math.log1p(band), rel=1e-12)
    stiffer = fit_trend(n, np.exp(a * n ** -b))  # prints stiffer: the same distance from 1
    assert stiffer.a == pytest.approx(a, rel=1e-12) and stiffer.b == pytest.approx(b, rel=1e-12)


def test_fit_trend_refuses_what_it_cannot_fit():
    with pytest.raises(ConfigError, match="need two at different cells"):
        fit_trend([0.5], [0.8])
    with pytest.raises(ConfigError, match="need two at different cells"):
        fit_trend([0.5, 0.5], [0.8, 0.7])
    with pytest.raises(ConfigError, match="finite and positive"):
        fit_trend([0.5, 1.0], [0.8, 0.0])
    flat = fit_trend([0.5, 1.0, 2.0], [0.5, 0.5, 0.5])  # no approach to 1: no n within a band
    assert flat.b == pytest.approx(0.0, abs=1e-12) and all(v is None for v in flat.n_within.values())


def test_intervals_are_student_intervals():
    v = [0.2, 0.3, 0.25]
    s = interval(v)
    sd = float(np.std(v, ddof=1))
    assert s["mean"] == pytest.approx(0.25) and s["std"] == pytest.approx(sd)
    assert s["halfwidth"] == pytest.approx(t_quantile(3, 0.95) * sd / math.sqrt(3))
    g = log_interval(v)
    lv = np.log(v)
    hw = t_quantile(3, 0.95) * np.std(lv, ddof=1) / math.sqrt(3)
    assert g["mean"] == pytest.approx(math.exp(lv.mean()), rel=1e-12)
    assert (g["lo"], g["hi"]) == pytest.approx((math.exp(lv.mean() - hw), math.exp(lv.mean() + hw)), rel=1e-12)
    assert log_interval([0.4])["lo"] is None and interval([0.4])["halfwidth"] is None
    with pytest.raises(ConfigError, match="must be positive"):
        log_interval([0.3, -0.1])


def _point(n, r, apart=False):
    s = {} if apart else {"bulk": {"modes": {"mean": r}}, "plate_membrane": {"modes": {"mean": r ** 0.3}}}
    return {"infill": 30.0, "shrink": 1.0, "thickness_mm": 5.0, "cells_through": n, "summary": s,
            **({"falls_apart": [1]} if apart else {})}


def test_trends_and_verdict_leave_out_a_sheet_that_falls_apart():
    pts = [_point(0.2, 0.3), _point(0.5, 0.6), _point(1.0, 0.95), _point(0.05, 0.0, apart=True)]
    tr = trends(pts)
    assert tr["bulk"]["points"] == 3 and tr["plate_membrane"]["points"] == 3
    assert "none" in tr["plate_bending"]
    line = verdict(pts, tr)
    assert "bulk: 1 / 1 of 3 within 10 / 25 %" in line and "plate (membrane): 1 / 2 of 3" in line
    assert "1 print(s) fall apart" in line and "softest print against the bulk: 0.30 x" in line


# the small Polyfoam and tripod of tests/test_sheet_stage.py
PIPELINE = """
[pipeline]
name = "m"
stages = ["orient", "scalemap", "report"]
{sheet}
[scalemap]
design = "{design}"
prints = 2
slabs = 2
"""

MAP = {"infill": "[45.0]", "shrink": "[1.0]", "thickness": "[2.0, 3.0]", "voxel_mm": "0.5"}


def pipeline(design, **keys) -> str:
    return PIPELINE.format(design=design, sheet=SHEET) + "".join(f"{k} = {v}\n" for k, v in {**MAP, **keys}.items())


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("scalemap")
    (tmp / "design.toml").write_text(DESIGN)
    f = tmp / "p.toml"
    f.write_text(pipeline(tmp / "design.toml"))
    run_pipeline(load_pipeline(f), out_root=tmp / "out")
    return tmp, tmp / "out" / "m"


def test_stage_writes_the_map_and_the_report(run):
    _, out = run
    d = json.loads((out / "scalemap" / "scale_map.json").read_text())
    assert [p["thickness_mm"] for p in d["points"]] == [2.0, 3.0] and d["prints"]["seeds"] == [1, 2]
    for p in d["points"]:
        assert p["cells_through"] == pytest.approx(p["thickness_mm"] / p["cell_mm"][2], rel=1e-12)
        assert p["cells_across"] == pytest.approx(10.0 / max(p["cell_mm"][:2]), rel=1e-12)
        # the summary is the prints' own numbers: both sheets' geometric mean, print by print
        per = [math.sqrt(q["sheets"]["normal"]["geometric_mean_ratio"] * q["sheets"]["mirrored"]["geometric_mean_ratio"])
               for q in p["prints"]]
        assert p["summary"]["bulk"]["modes"]["mean"] == pytest.approx(float(np.exp(np.mean(np.log(per)))), rel=1e-12)
        assert len(p["prints"]) == 2 and all(0 < r < 1 for r in per)  # cells taller than the sheet: softer
        # the plate of the cell cut at these faces is softer than the bulk, so the prints are nearer to it
        assert p["summary"]["plate_membrane"]["modes"]["mean"] > p["summary"]["bulk"]["modes"]["mean"]
        assert p["plate_ratio_to_bulk"]["mean"] < 1
    assert d["points"][1]["cells_through"] == pytest.approx(1.5 * d["points"][0]["cells_through"], rel=1e-12)
    assert d["trend"]["bulk"]["points"] == 2
    csv = (out / "scalemap" / "scale_map.csv").read_text().splitlines()
    assert len(csv) == 3 and csv[0].startswith("infill,shrink,thickness_mm")
    assert (out / "scalemap" / "scale_map.png").stat().st_size > 0
    report = (out / "report" / "report.md").read_text()
    assert "Where the continuum holds" in report and d["verdict"] in report and "scale_map.png" in report


def test_an_extended_map_reuses_the_finished_units(run):
    tmp, out = run
    units = out / ".scalemap.units"  # beside the stage folders, outside the run's workdir
    kept = sorted(f.name for f in units.glob("*.pkl"))
    assert len(kept) == 1 + 2 * 2 * 2  # the cell and 2 thicknesses x 2 prints x 2 sheets
    f = tmp / "p2.toml"
    f.write_text(pipeline(tmp / "design.toml", thickness="[3.0]"))
    run_pipeline(load_pipeline(f), out_root=tmp / "out")  # the cell differs (its slabs): 1 new unit
    d = json.loads((out / "scalemap" / "scale_map.json").read_text())
    assert [p["thickness_mm"] for p in d["points"]] == [3.0]
    after = sorted(f.name for f in units.glob("*.pkl"))
    assert len(after) == 1 + 2 * 2 and len(set(after) - set(kept)) == 1


@pytest.mark.parametrize("key, value, match", [
    ("infill", "[0.5]", "infill: 0.5: allowed range is \\[1, 90\\]"),
    ("shrink", "[0.0]", "shrink: 0.0: allowed range is \\(0, 1\\]"),
    ("thickness", "[2.0, 2.0]", "values must differ"),
    ("voxel_mm", "1.0", "scalemap.voxel_mm: 1: allowed range \\(0, bead_width = 0.8\\]"),
])
def test_bad_settings_are_named(tmp_path, key, value, match):
    (tmp_path / "design.toml").write_text(DESIGN)
    f = tmp_path / "p.toml"
    f.write_text(pipeline(tmp_path / "design.toml", **{key: value}))
    with pytest.raises(ConfigError, match=match):
        load_pipeline(f)


def test_a_strut_foam_design_is_refused(tmp_path):
    (tmp_path / "design.toml").write_text('kind = "foam"\nname = "f"\n')
    f = tmp_path / "p.toml"
    f.write_text(pipeline(tmp_path / "design.toml"))
    with pytest.raises(ConfigError, match="scalemap.design"):
        load_pipeline(f)


def test_cell_extent_estimates_the_built_cell():
    """The one-second estimate of a Polyfoam's cell (no voxel grid) against the cell built on its grid."""
    import tomllib

    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.cells.polyfoam import cell_extent

    design = parse_design(tomllib.loads(DESIGN))
    built = np.asarray(design_cell(design).size) / design.seeds.count ** (1 / 3)
    assert cell_extent(design) == pytest.approx(built, rel=0.05)
