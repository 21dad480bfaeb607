"""Guards a test campaign found missing: every one is refused when the pipeline is loaded
(``metasheet validate`` as well as ``run``), as ``FILE: table.field: value: what is allowed``.

1. ``[pipeline] name`` is one safe folder name ("." and ".." made ``clean --all`` delete the parent);
2. no float parameter takes nan or +-inf (``Infinity`` reached material.json), and the five
   constants must give a positive-definite stiffness;
3. each ``[robot] convergence`` entry is checked field by field (a size of 0 divided by zero 30 s in);
4. a sheet whose estimated element count would exhaust the memory is refused before meshing;
5. ``robot goto``'s goal components are finite and within physical bounds.
"""

import math
import re
import sys
from pathlib import Path
from typing import get_args, get_origin

import pytest
from pipeline_files import refused_at
from pydantic import BaseModel

from metasheet.cli import main
from metasheet.errors import ConfigError
from metasheet.goto import parse_pose
from metasheet.pipeline.config import load_pipeline, validate_table
from metasheet.pipeline.registry import stages
from metasheet.pipeline.stages.orient import MAX_SHEET_TETS, OrientParams, sheet_params
from metasheet.sheet.geometry import SheetParams, estimated_tets, tripod_sheet

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def project(tmp_path, monkeypatch):
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def write(project: Path, text: str) -> Path:
    path = project / "pipelines" / "p.toml"
    path.write_text(text)
    return path


def pipeline(stage_list: str, tables: str = "", name: str = '"p"') -> str:
    return f"[pipeline]\nname = {name}\nstages = [{stage_list}]\n{tables}"


def refused(project: Path, text: str, capsys) -> str:
    """The ConfigError loading ``text`` raises, after checking ``metasheet validate`` prints it
    and exits 2."""
    return refused_at(write(project, text), capsys)


# 1. the run name ---------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["..", ".", ".hidden", "a/b", "a\\\\b", "", "run.", "x" * 65, "CON", "nul.txt",
                                  "../up", "a b"])
def test_unsafe_run_names_are_refused(project, capsys, name):
    """Before: "." and ".." passed, and ``clean --all`` deleted outputs/ or its parent."""
    msg = refused(project, pipeline('"material"', name=f'"{name}"'), capsys)
    assert f"pipeline.name: {name.replace(chr(92) * 2, chr(92))!r}: " in msg


@pytest.mark.parametrize("name", ["quick", "paper_v2", "run-1.5", "x" * 64, "_a", "console"])
def test_plain_run_names_are_accepted(project, name):
    assert load_pipeline(write(project, pipeline('"material"', name=f'"{name}"'))).name == name


# 2. non-finite numbers and unstable constants ----------------------------------------------------

def _float_fields(model: type[BaseModel], prefix: str = ""):
    """(dotted path, data with inf there) of every float field of ``model`` and its nested models."""
    for name, info in model.model_fields.items():
        kinds = get_args(info.annotation) or (info.annotation,)
        origin = get_origin(info.annotation)
        if origin is list and kinds == (float,):  # a list of floats: its first item
            yield f"{prefix}{name}[0]", {name: [math.inf]}
        elif origin is dict and kinds == (str, float):  # a table of floats: one entry
            yield f"{prefix}{name}.k", {name: {"k": math.inf}}
        elif float in kinds:
            yield prefix + name, {name: math.inf}
        for sub in kinds:
            if isinstance(sub, type) and issubclass(sub, BaseModel):
                for path, data in _float_fields(sub, f"{prefix}{name}."):
                    yield path, {name: data}


FLOAT_FIELDS = [(st.name, path, data) for st in stages().values() for path, data in _float_fields(st.params)]


def test_every_stage_has_float_fields_to_check():
    assert {"material", "orient", "robot", "reduce", "workspace"} <= {t for t, _, _ in FLOAT_FIELDS}
    assert ("orient", "constants.nu_tl", {"constants": {"nu_tl": math.inf}}) in FLOAT_FIELDS


@pytest.mark.parametrize("table, path, data", FLOAT_FIELDS, ids=[f"{t}.{p}" for t, p, _ in FLOAT_FIELDS])
def test_every_float_parameter_refuses_infinity(table, path, data):
    with pytest.raises(ConfigError, match=rf"(?m)^f\.toml: {table}\.{re.escape(path)}: inf: Input should be a finite number"):
        validate_table("f.toml", table, stages()[table].params, data)


@pytest.mark.parametrize("tables, message", [
    ('[material]\nsource = "config"\nnu_tl = nan\n', "material.nu_tl: nan: Input should be a finite number"),
    ('[material]\nsource = "config"\nE_t = inf\n',
     "material.E_t: inf: Input should be a finite number; allowed range is [1e-06, 2e+06]"),
    ("[material]\ndensity = inf\n", "material.density: inf: Input should be a finite number; allowed range is [1e-13, 1e-07]"),
    ("[material]\nnu_t = -inf\n", "material.nu_t: -inf: Input should be a finite number; allowed range is (-1, 1)"),
    ("[orient]\ntip_box = [15.0, inf, 30.0]\n", "orient.tip_box[1]: inf: Input should be a finite number"),
    ("[orient]\ngrading = { table = { hub = { density = nan } } }\n",
     "orient.grading.table.hub.density: nan: Input should be a finite number"),
    ("[orient]\nconstants = { E_l = inf }\n",
     "orient.constants.E_l: inf: Input should be a finite number; allowed range is [1e-06, 2e+06]"),
])
def test_nan_and_inf_in_tables_are_refused(project, capsys, tables, message):
    """Before: they passed, and material.json got ``Infinity`` (not JSON)."""
    assert message in refused(project, pipeline('"material", "orient"', tables), capsys)


@pytest.mark.parametrize("head, tables, message", [
    ("", '[orient]\nmesh_size = "8"\n', "orient.mesh_size: '8': expected a number, without quotes"),
    ("", "[orient]\nmesh_size = true\n", "orient.mesh_size: True: expected a number, without quotes"),
    ('workers = "2"\n', "", "pipeline.workers: '2': expected a whole number"),
    ("workers = 2.5\n", "", "pipeline.workers: 2.5: expected a whole number"),
    ("", '[orient]\nelement = "p2"\nmesh_size = 8\n', None),  # an integer is a number
])
def test_no_string_bool_or_decimal_is_coerced(project, capsys, head, tables, message):
    """Issue 60: "8", "2" and true (read as 1.0) passed ``validate``."""
    text = f'[pipeline]\nname = "p"\nstages = ["material", "orient"]\n{head}{tables}'
    if message is None:
        assert load_pipeline(write(project, text)).params["orient"].mesh_size == 8.0
    else:
        assert message in refused(project, text, capsys)


@pytest.mark.parametrize("tables, message", [
    ('[material]\nsource = "config"\ndensity = 1e300\n', "material.density: 1e+300:"),
    ('[material]\nsource = "config"\nmu_l = 1e-300\n', "material.mu_l: 1e-300:"),
    ('[material]\nsource = "config"\nE_l = 1e308\n', "material.E_l: 1e+308:"),
    ('[orient]\nconstants = { E_t = 1e9 }\n', "orient.constants.E_t: 1000000000.0:"),
])
def test_absurd_moduli_and_densities_are_refused(project, capsys, tables, message):
    """Issue 60: they passed and the run failed inside an SVD; E_l = 1e308 was reported as a
    range error of nu_tl "(-0, 0)"."""
    msg = refused(project, pipeline('"material", "orient"', tables), capsys)
    assert message in msg and "allowed range is [1e-" in msg and "nu_tl" not in msg


def test_nested_floats_in_lists_are_finite(project, capsys):
    msg = refused(project, pipeline('"material", "orient", "robot"', '[robot]\nconvergence = [["p1", 5.0, 0, nan]]\n'),
                  capsys)
    assert "robot.convergence[0].grip_size: nan: Input should be a finite number; allowed range is [0, 50]" in msg


@pytest.mark.parametrize("table", ["material", "orient.constants"])
def test_constants_without_a_positive_definite_stiffness_are_refused(project, capsys, table):
    """nu_tl had no bound at all: its range follows from the others (|nu_tl| < sqrt((1 - nu_t) E_t / (2 E_l)))."""
    body = "E_l = 1.0\nnu_tl = 0.8\n"
    tables = f"[material]\nsource = \"config\"\n{body}" if table == "material" else \
        "[orient]\nconstants = { E_l = 1.0, nu_tl = 0.8 }\n"
    msg = refused(project, pipeline('"material", "orient"', tables), capsys)
    assert f"{table}.nu_tl: 0.8: allowed range is (-0.716362, 0.716362) for E_t = 1.39, E_l = 1, nu_t = 0.26162" in msg
    edge = body.replace("0.8", "0.71")
    tables = tables.replace("0.8", "0.71") if table != "material" else f"[material]\nsource = \"config\"\n{edge}"
    load_pipeline(write(project, pipeline('"material", "orient"', tables)))


def test_authors_model_needs_a_positive_definite_tensor_for_the_given_constants(project, capsys):
    tables = '[material]\nsource = "config"\nmodel = "authors"\nnu_tl = 2.0\n'
    msg = refused(project, pipeline('"material"', tables), capsys)
    assert "material.model: 'authors': the authors' tensor is not positive definite" in msg
    load_pipeline(write(project, pipeline('"material"', tables.replace('model = "authors"', 'model = "ours"'))))


# 3. convergence entries --------------------------------------------------------------------------

@pytest.mark.parametrize("entry, message", [
    ('["p1", 0.0, 0, 0.0]', ("robot.convergence[0].mesh_size: 0.0: Input should be greater than or equal to 0.3; "
                             "allowed range is [0.3, 50]")),
    ('["p1", -5, 0, 0.0]', ("robot.convergence[0].mesh_size: -5: Input should be greater than or equal to 0.3; "
                            "allowed range is [0.3, 50]")),
    ('["p1", 5.0, 17, 0.0]', ("robot.convergence[0].layers: 17: Input should be less than or equal to 16; "
                              "allowed range is [0, 16]")),
    ('["p1", 5.0, 0, 6.0]', "robot.convergence[0].grip_size: 6.0: allowed range is [0.2, mesh_size = 5], or 0"),
    ('["p1", 5.0, 0, 0.1]', "robot.convergence[0].grip_size: 0.1: allowed range is [0.2, mesh_size = 5], or 0"),
    ('["p3", 5.0, 0, 0.0]', "robot.convergence[0].element: 'p3': Input should be 'p1' or 'p2'"),
])
def test_convergence_entries_are_checked_field_by_field(project, capsys, entry, message):
    """Before: a size of 0 was a raw ZeroDivisionError after 30 s, -5 named neither table nor file."""
    tables = f'[robot]\nconvergence = [["p1", 10.0, 0, 0.0], {entry}]\n'.replace("[0]", "[1]")
    msg = refused(project, pipeline('"material", "orient", "robot"', tables), capsys)
    assert message.replace("[0]", "[1]") in msg


# 4. the size guard -------------------------------------------------------------------------------

@pytest.mark.parametrize("kw", [{}, {"mesh_size": 2.5}])
def test_the_element_estimate_is_within_its_stated_factor_of_gmsh(kw):
    """The calibration stated in ``metasheet.sheet.geometry``: the default sheet and a finer one."""
    sp = SheetParams(**kw)
    n = len(tripod_sheet(sp).tets)
    assert 1 / 1.5 < estimated_tets(sp) / n < 1.5


def test_the_estimate_grows_with_the_sheet_and_the_grips():
    base = estimated_tets(SheetParams())
    assert estimated_tets(SheetParams(mesh_size=2.5)) > 3 * base
    assert estimated_tets(SheetParams(thickness=20.0, mesh_size=2.5)) > 2 * estimated_tets(SheetParams(mesh_size=2.5))
    assert estimated_tets(SheetParams(mesh_size=10.0, grip_size=0.7)) > 10 * estimated_tets(SheetParams(mesh_size=10.0))


def test_a_huge_sheet_is_refused_before_meshing(project, capsys):
    """The campaign's case: it passed validate and headed for the machine's memory."""
    tables = "[orient]\nmesh_size = 0.3\nreach = 1000\narm_width = 200\nthickness = 100\n"
    msg = refused(project, pipeline('"orient"', tables), capsys)
    assert "orient.mesh_size: 0.3: the sheet (reach 1000, arm_width 200, thickness 100 mm" in msg
    assert f"over the limit of {MAX_SHEET_TETS['mesh']:,} to mesh it" in msg
    assert "allowed range for this sheet is [5.89, 50]" in msg
    est = int(msg.split("makes about ")[1].split(" ")[0].replace(",", ""))
    assert est > 1e10


def test_the_suggested_mesh_size_passes(project):
    sp = sheet_params(OrientParams(reach=1000, arm_width=200, thickness=100, mesh_size=5.9))
    assert estimated_tets(sp) <= MAX_SHEET_TETS["mesh"]


def test_a_robot_limit_applies_only_where_a_robot_is_built(project, capsys):
    assert load_pipeline(write(project, pipeline('"orient"', "[orient]\nmesh_size = 1.0\n")))
    msg = refused(project, pipeline('"material", "orient", "robot"', "[orient]\nmesh_size = 1.0\n"), capsys)
    assert "orient.mesh_size: 1.0: " in msg and f"over the limit of {MAX_SHEET_TETS['p2']:,} for a robot of p2" in msg
    load_pipeline(write(project, pipeline('"material", "orient", "robot"', '[orient]\nmesh_size = 1.0\nelement = "p1"\n')))


@pytest.mark.parametrize("stage, tables, field", [
    ("robot", '[robot]\nconvergence = [["p1", 10.0, 0, 0.0], ["p2", 0.5, 0, 0.0]]\n', "robot.convergence[1].mesh_size"),
    ("robot", '[robot]\nconvergence = [["p2", 10.0, 0, 0.2]]\n', "robot.convergence[0].mesh_size"),
    ("workspace", "[workspace]\nmesh_size = 0.5\n", "workspace.mesh_size"),
])
def test_re_meshed_sheets_of_the_robot_and_studies_are_guarded_too(project, capsys, stage, tables, field):
    msg = refused(project, pipeline(f'"material", "orient", "{stage}"', tables), capsys)
    assert f"{field}: " in msg and "tetrahedra, over the limit of" in msg


def test_a_grip_size_finer_than_the_orient_mesh_allows_is_named(project, capsys):
    msg = refused(project, pipeline('"material", "orient", "workspace"', "[workspace]\nmesh_size = 4\ngrip_size = 5\n"),
                  capsys)
    assert "workspace.grip_size: 5" in msg and "allowed range is [0.2, 4]" in msg


def test_orient_geometry_across_fields_is_checked_at_load(project, capsys):
    msg = refused(project, pipeline('"orient"', "[orient]\narm_width = 60\nreach = 30\n"), capsys)
    assert "orient.reach: 30" in msg and "allowed range is [36.641, 1000]" in msg


@pytest.mark.parametrize("name", ["quick", "paper"])
def test_the_project_pipelines_still_validate(name):
    assert load_pipeline(ROOT / "pipelines" / f"{name}.toml").name == name


def test_a_pipeline_of_every_stage_with_defaults_validates(project):
    (project / "cells" / "quick_foam.toml").write_text("")
    paper = Path(__file__).resolve().parents[1] / "cells" / "paper_polyfoam.toml"  # scalemap's, printcheck's
    (project / "cells" / "paper_polyfoam.toml").write_text(paper.read_text())
    # cell needs a design (and sheet, cell; printed, sheet)
    names = [n for n in stages() if n not in ("cell", "homogenize", "sheet", "printed")]
    # the design stage's rest problem takes P1 sheets only (orient's default is P2)
    assert load_pipeline(write(project, pipeline(", ".join(f'"{n}"' for n in names), '[orient]\nelement = "p1"\n')))


# 5. robot goto's goal ----------------------------------------------------------------------------

@pytest.mark.parametrize("pose, message", [
    (["1e308", "0", "0", "0", "0", "0"], "pose component 1 of 6 (X [mm]): '1e308': allowed range is [-1000, 1000]"),
    (["0", "0", "-1001", "0", "0", "0"], "pose component 3 of 6 (Z [mm]): '-1001': allowed range is [-1000, 1000]"),
    (["0", "0", "0", "0", "0", "180.5"], "pose component 6 of 6 (RZ [deg]): '180.5': allowed range is [-180, 180]"),
    (["0", "0", "0", "-1e400", "0", "0"], "pose component 4 of 6 (RX [deg]): '-1e400': expected a finite number"),
])
def test_goal_components_out_of_physical_range_are_refused(capsys, pose, message):
    """Before: 1e308 reported ``inf mm`` / ``nan deg`` with numpy warnings."""
    with pytest.raises(ConfigError, match=r"^" + message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        parse_pose(pose)
    saved, sys.argv = sys.argv, ["metasheet", "robot", "goto", "--", *pose]
    try:
        with pytest.raises(SystemExit) as exc:
            main()
    finally:
        sys.argv = saved
    assert (exc.value.code, capsys.readouterr().err) == (2, f"error: {message}\n")


def test_goals_at_the_bounds_are_accepted():
    assert parse_pose(["1000", "-1000", "0", "180", "-180", "0.5"]) == [1000.0, -1000.0, 0.0, 180.0, -180.0, 0.5]
