"""Loading a pipeline (``metasheet validate`` as well as ``run``) reads the files it names and
checks what a later stage would, so a mistake costs no upstream stage. Before (issue 60): a cell
design of random bytes, invalid TOML, infill -5, voxel 0, kind "banana", NaN, 0 seeds or an
empty file all said "ok" (random bytes then failed the cell stage with a UnicodeDecodeError
without the file's name); ``sheet.voxel_mm`` above the bead was refused only when the sheet
stage ran; ``orient.element = "p2"`` passed for the design stage (P1 only); ``strain_front =
[-0.3]`` was reported as ``design.strain_limit``."""

import sys
from pathlib import Path

import pytest
from pipeline_files import refused_at

from metasheet.cli import main
from metasheet.pipeline.config import load_pipeline

ROOT = Path(__file__).resolve().parents[1]
POLYFOAM = (ROOT / "cells" / "paper_polyfoam.toml").read_text()


@pytest.fixture
def project(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    return tmp_path


def refused(project: Path, pipeline: str, design: bytes | str | None = None) -> str:
    """The message loading ``pipeline`` (with ``cells/d.toml`` = ``design``) raises; ``metasheet
    validate`` prints it after ``error:`` and exits 2."""
    if design is not None:
        (project / "cells" / "d.toml").write_bytes(design.encode() if isinstance(design, str) else design)
    path = project / "pipelines" / "q.toml"
    path.write_text(pipeline)
    return refused_at(path)


CELL = '[pipeline]\nname = "q"\nstages = ["cell"]\n[cell]\ndesign = "cells/d.toml"\n'


@pytest.mark.parametrize("design, message", [
    (bytes(range(256)) * 2, "cell.design: 'cells/d.toml': not a text file (not UTF-8)"),
    ("kind = \n", "cell.design: 'cells/d.toml': not valid TOML"),
    ("", "cells/d.toml.name: required key is missing"),
    ('kind = "banana"\n', "cells/d.toml.kind: 'banana': expected one of"),
    (POLYFOAM.replace("infill_percentage = 15.0", "infill_percentage = -5.0"), "cells/d.toml.infill_percentage: -5.0"),
    (POLYFOAM.replace("\nvoxel_mm = 0.3", "\nvoxel_mm = 0"), "cells/d.toml.voxel_mm: 0:"),
    (POLYFOAM.replace("\nvoxel_mm = 0.3", "\nvoxel_mm = nan"), "cells/d.toml.voxel_mm: nan: Input should be a finite"),
    (POLYFOAM.replace("\nvoxel_mm = 0.3", '\nvoxel_mm = "0.3"'), "cells/d.toml.voxel_mm: '0.3': expected a number"),
    (POLYFOAM.replace("\ncount = 8", "\ncount = 0"), "cells/d.toml.seeds.count: 0:"),
], ids=["bytes", "toml", "empty", "kind", "infill", "voxel0", "nan", "string", "seeds0"])
def test_the_cell_design_is_read_when_the_pipeline_loads(project, design, message):
    assert message in refused(project, CELL, design)


def test_the_papers_designs_pass(project):
    assert "\nvoxel_mm = 0.3" in POLYFOAM and "\ncount = 8" in POLYFOAM  # the replacements above bite
    (project / "cells" / "d.toml").write_text(POLYFOAM)
    (project / "pipelines" / "q.toml").write_text(CELL)
    assert load_pipeline(project / "pipelines" / "q.toml").order == ("cell",)


SHEET = ('[pipeline]\nname = "q"\nstages = ["cell", "homogenize", "material", "orient", "printmap", "robot", "sheet"]\n'
         '[cell]\ndesign = "cells/d.toml"\n[sheet]\n')


@pytest.mark.parametrize("sheet, message", [
    ("voxel_mm = 0.5\n", "sheet.voxel_mm: 0.5: allowed range (0, bead_width = 0.4] mm"),
    ("voxel_mm = 0.01\n", "sheet.max_voxels: 20000000: the grid"),
])
def test_the_sheet_stage_is_checked_against_the_design_before_any_stage_runs(project, sheet, message):
    assert message in refused(project, SHEET + sheet, POLYFOAM)


def test_the_design_stage_refuses_p2_sheets_and_names_the_strain_fronts_entry(project):
    base = '[pipeline]\nname = "q"\nstages = ["material", "orient", "design"]\n'
    msg = refused(project, base + '[orient]\nelement = "p2"\n')
    assert "orient.element: 'p2':" in msg and "allowed 'p1'" in msg
    msg = refused(project, base + '[orient]\nelement = "p1"\n[design]\nstrain_front = [0.2, -0.3]\n')
    assert "design.strain_front[1]: -0.3: allowed range is (0, 10]" in msg


def test_a_byte_order_mark_is_read_past(project):
    """Issue 60: an editor's UTF-8 BOM gave "Invalid statement (at line 1, column 1)"."""
    (project / "cells" / "d.toml").write_bytes(b"\xef\xbb\xbf" + POLYFOAM.encode())
    (project / "pipelines" / "q.toml").write_bytes(b"\xef\xbb\xbf" + CELL.encode())
    assert load_pipeline(project / "pipelines" / "q.toml").order == ("cell",)


def test_stage_given_twice_and_too_many_workers_are_refused(project, capsys):
    """Issue 60: ``--stage robot --stage orient`` silently kept the last; ``--workers 10000`` was
    accepted though the file caps workers at 256."""
    (project / "pipelines" / "q.toml").write_text('[pipeline]\nname = "q"\nstages = ["material"]\n')
    for argv, code, words in ((["--stage", "material", "--stage", "orient"], 2, "--stage: given 2 times"),
                              (["--workers", "10000"], 2, "--workers")):
        saved, sys.argv = sys.argv, ["metasheet", "run", str(project / "pipelines" / "q.toml"), *argv,
                                     "--out", str(project / "out")]
        try:
            with pytest.raises(SystemExit) as exc:
                main()
        finally:
            sys.argv = saved
        assert exc.value.code == code
        assert words in capsys.readouterr().err
    assert not (project / "out").exists()
