"""Will this foam behave like a continuum? The scale map's verdict on a design in a sheet
(metasheet.studies.continuum_check), where it is used (material auto, orient, validate), and
the choice on three designs chosen by hand."""

import json
import math
import tomllib
from pathlib import Path

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import pytest

from metasheet.cells.catalogue import parse_design
from metasheet.pipeline.stages.material import auto_choice
from metasheet.studies import continuum_check as cc

ROOT = Path(__file__).resolve().parents[1]
PAPER = tomllib.loads((ROOT / "cells" / "paper_polyfoam.toml").read_text())


def test_expected_ratio_and_cells_needed_are_the_fit_inverted():
    for model in ("bulk", "plate"):
        a, b, sign = cc.TRENDS[model]
        assert a > 0 and b > 0 and sign == -1.0  # the prints are softer and approach the continuum
        for band in (0.10, 0.25):
            n = cc.cells_needed(model, band)
            assert abs(math.log(cc.expected_ratio(model, n))) == pytest.approx(math.log1p(band), rel=1e-12)
        assert cc.expected_ratio(model, 0.5 * cc.cells_needed(model)) < 1 / 1.25 < cc.expected_ratio(
            model, 2 * cc.cells_needed(model))
    # the sheet-scale continuum is the nearer one wherever the bulk is off
    assert cc.cells_needed("plate") < cc.cells_needed("bulk")


def test_check_cells_sorts_sheets_into_bulk_plate_none():
    nb, npl = cc.cells_needed("bulk"), cc.cells_needed("plate")
    cell = (2.0, 2.0, 4.0)
    assert cc.check_cells(cell, 4.0 * nb * 1.01).holds == "bulk"
    assert cc.check_cells(cell, 4.0 * 0.5 * (nb + npl)).holds == "plate"
    none = cc.check_cells(cell, 4.0 * npl * 0.99)
    assert none.holds == "none" and none.cells_through == pytest.approx(npl * 0.99)
    msg = none.message()
    assert "no continuum holds within 25%" in msg and f"{none.bulk:.2f} x the bulk" in msg
    with pytest.raises(Exception, match="thickness"):
        cc.check_cells(cell, 0.0)


@pytest.mark.parametrize("infill, shrink, thickness, source", [
    (15.0, 0.2, 5.0, "plate"),    # the paper's sheet: 0.13 cell heights through it
    (50.0, 1.0, 45.0, "homogenize"),  # the densest roundest foam in a thick block: ~8.6 cell heights
    (30.0, 1.0, 2.5, "plate"),    # a mid foam in a thin sheet: ~0.26
])
def test_auto_choice_on_three_designs_chosen_by_hand(infill, shrink, thickness, source):
    design = parse_design(PAPER, overrides={"infill_percentage": infill, "kgon_x_shrink": shrink})
    chk = cc.check_design(design, thickness)
    plate = {"thickness_mm": thickness}
    got = auto_choice(plate, chk)
    assert got["source"] == source
    assert f"{chk.cells_through:.2f} cell heights" in got["why"] and f"{chk.bulk:.2f} x the bulk" in got["why"]
    if got["source"] == "homogenize":
        assert auto_choice(None, chk)["source"] == "homogenize"
    else:  # without a plate.json the bulk stays, saying what the map expects and how to get the plate
        assert "plate_thickness" in auto_choice(None, chk)["why"]


def test_orient_records_and_warns_and_validate_says_it(tmp_path, caplog):
    from typer.testing import CliRunner

    from metasheet.cli import app
    from metasheet.pipeline.stages.orient import continuum

    cell = tmp_path / "cell"
    cell.mkdir()
    (cell / "cell.json").write_text(json.dumps({"design": PAPER}))
    with caplog.at_level("WARNING"):
        d = continuum(cell, 5.0)
    assert d["holds"] != "bulk" and d["cells_through"] == pytest.approx(0.13, abs=0.01)
    assert "0.13 cell heights" in caplog.text
    r = CliRunner().invoke(app, ["validate", str(ROOT / "pipelines" / "printed-sheet.toml")])
    assert r.exit_code == 0 and "warning: cell: a 5 mm sheet of cells" in r.output and "0.13 cell heights" in r.output
