"""``robot goto --column reproduction`` drives the pipeline's mesh and scene with the published
constants under the authors' force field; ``--tol-mm`` / ``--tol-deg`` set the tolerances
(the paper's test: 1 mm, 2 deg)."""

import numpy as np
import pytest

from metasheet.published import paper
from metasheet.errors import ConfigError
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.serve.loading import find_outputs, load_robot

from serve_outputs import write_outputs


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    root = tmp_path_factory.mktemp("goto_columns")
    toml, out = write_outputs(root)
    return toml, out


def test_the_reproduction_robot_is_the_published_foam_under_the_authors_force_field(outputs):
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.sheet.outline import SheetParams

    toml, out = outputs
    outs = find_outputs(toml, out)
    robot, info = load_robot(outs, "full", "foam", "reproduction")
    assert "published" in info.description and "authors" in info.description and "p1 5 mm" in info.description
    # built independently: the authors' mesh kind (P1, 5 mm, uniform), the published set, their force field
    pair = SheetPair.spiral(SheetParams(mesh_size=5.0), "p1")
    direct = six_dof_robot(pair, paper.PAPER_FOAM, model="authors", density=paper.FOAM_DENSITY,
                           rod_length=paper.ROD_LENGTH)
    assert robot.body.n_elements == direct.body.n_elements > load_robot(outs, "full", "foam")[0].body.n_elements
    a = solve_equilibrium(robot, robot.coupling.rest_angles + np.radians(5.0)).state
    b = solve_equilibrium(direct, direct.coupling.rest_angles + np.radians(5.0)).state
    np.testing.assert_allclose(a.x, b.x, atol=1e-9)
    np.testing.assert_allclose(a.p, b.p, atol=1e-9)
    assert info.column == "reproduction" and info.material == "foam"
    with pytest.raises(ConfigError, match="the reproduction column is the paper's published foam"):
        load_robot(outs, "full", "silicone", "reproduction")
    with pytest.raises(ConfigError, match="--column: 'nope': allowed values are prediction, reproduction"):
        load_robot(outs, "full", "foam", "nope")


def _goto(capsys, toml, out, *args):
    from metasheet.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["robot", "goto", "--pipeline", str(toml), "--out", str(out), *args])
    text = capsys.readouterr()
    return exc.value.code, text.out + text.err


def _steps_and_errors(text):
    status = next(line for line in text.splitlines() if line.startswith("status:"))
    err = next(line for line in text.splitlines() if line.startswith("remaining error")).split(":")[1]
    mm, deg = (float(part.split()[0]) for part in err.split(","))
    return status, int(status.split(" after ")[1].split()[0]), mm, deg


def test_goto_tolerances_decide_when_it_stops(outputs, capsys):
    toml, out = outputs
    goal = ["--", "0", "0", "0", "0", "6", "0"]
    code_t, text_t = _goto(capsys, toml, out, "--column", "reproduction", "--tol-mm", "0.01", "--tol-deg", "0.01", *goal)
    code_l, text_l = _goto(capsys, toml, out, "--column", "reproduction", "--tol-mm", "1", "--tol-deg", "2", *goal)
    assert code_t in (0, None) and code_l in (0, None), text_t + text_l
    status_t, steps_t, mm_t, deg_t = _steps_and_errors(text_t)
    status_l, steps_l, mm_l, deg_l = _steps_and_errors(text_l)
    assert status_t.startswith("status: reached") and mm_t <= 0.01 and deg_t <= 0.01
    # the paper's tolerances stop the loop earlier, at a pose within them but not within the tight ones
    assert status_l.startswith("status: reached") and mm_l <= 1.0 and deg_l <= 2.0
    assert steps_l < steps_t and max(mm_l, deg_l) > 0.01


def test_the_reproduction_column_defaults_to_the_papers_tolerances(outputs, capsys):
    toml, out = outputs
    goal = ["--", "0", "0", "0", "0", "6", "0"]
    code_d, text_d = _goto(capsys, toml, out, "--column", "reproduction", *goal)
    code_l, text_l = _goto(capsys, toml, out, "--column", "reproduction", "--tol-mm", "1", "--tol-deg", "2", *goal)
    assert code_d in (0, None), text_d
    assert "reproduction, tolerance 1 mm, 2 deg" in text_d
    assert _steps_and_errors(text_d) == _steps_and_errors(text_l)  # the same loop, stopped at the same pose
    code_p, text_p = _goto(capsys, toml, out, *goal)
    assert "prediction, tolerance 0.1 mm, 0.2 deg" in text_p


def test_a_reduced_reproduction_without_its_basis_says_how_to_train_it(outputs):
    from metasheet.goto import pipeline_robot

    toml, out = outputs
    with pytest.raises(ConfigError, match=r"reproduction column .*add 'reproduction' to \[reduce\] columns"):
        pipeline_robot(toml, out, "reduced", None, "reproduction")


def test_bad_column_is_named(outputs, capsys):
    toml, out = outputs
    with pytest.raises(ConfigError, match="--column"):
        from metasheet.goto import pipeline_robot

        pipeline_robot(toml, out, column="silicone")
    with pytest.raises(ConfigError, match="--material-model"):
        from metasheet.goto import pipeline_robot

        pipeline_robot(toml, out, column="reproduction", material_model="ours")


@pytest.mark.parametrize("col", ["prediction", "reproduction"])
def test_a_columns_robot_is_the_same_for_the_studies_and_the_page(outputs, col):
    """One builder (:func:`metasheet.pipeline.column.column_robot`): the study's picklable recipe
    (the study stages' route, servos placed from the rest angle) and the page's robot (the robot
    stage's recorded servo geometry) are the same robot, byte for byte: a basis trained on one
    fits the other."""
    from metasheet.pipeline.artefacts import read_material, read_orient, read_robot_scene
    from metasheet.pipeline.column import column, column_robot
    from metasheet.rom.coordinates import robot_key

    toml, out = outputs
    d = find_outputs(toml, out).directory
    sc = read_robot_scene(d / "robot")
    parts = column_robot(read_orient(d / "orient"), read_material(d / "material"), column(col), sc.sheet_mass_g)
    study = parts.spec(rod_length=sc.rod_length, rest_angle=sc.rest_angle, horn_length=sc.horn_length).build()
    page = load_robot(find_outputs(toml, out), "full", "foam", col)[0]
    assert robot_key(study.robot) == robot_key(page)
    assert parts.model == ("authors" if col == "reproduction" else "ours")
    n = page.body.n_elements
    assert (n > load_robot(find_outputs(toml, out), "full", "foam")[0].body.n_elements) == (col == "reproduction")


def test_what_a_column_fixes():
    from metasheet.pipeline.column import COLUMNS, REPRODUCTION_MESH, column

    pred, rep = (column(c) for c in COLUMNS)
    assert not pred.fixes_material and pred.mesh == {} and pred.study_defaults == {} and not pred.keeps_units
    assert rep.material == paper.PAPER_FOAM and rep.model == "authors" and rep.mesh == REPRODUCTION_MESH
    assert rep.study_defaults == {"stop_beyond_strain": False, **REPRODUCTION_MESH} and rep.keeps_units
    assert rep.tolerances == (1.0, 2.0) and pred.tolerances == (0.1, 0.2)  # the paper's test; ours
    assert column("reproduction", "ours").model == "ours"
    with pytest.raises(ConfigError, match=r"--column: 'both': allowed values are prediction, reproduction"):
        column("both", field="--column")


def test_column_names_are_compared_only_where_a_column_is_defined_or_laid_out():
    """The column's facts live in metasheet/pipeline/column.py: elsewhere code asks a
    :class:`Column` (``fixes_material``, ``mesh``, ``tolerances``, ...) instead of comparing its
    name with a literal. Allowed: the report, which lays the two columns out side by side."""
    import ast
    from pathlib import Path

    import metasheet
    from metasheet.pipeline.column import COLUMNS

    root = Path(metasheet.__file__).parent
    allowed = {"pipeline/column.py", "report/columns.py"}
    found = []
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root).as_posix()
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Compare) and any(isinstance(c, ast.Constant) and c.value in COLUMNS
                                                     for c in [node.left, *node.comparators]):
                found.append(f"{rel}:{node.lineno}")
    assert [w for w in found if w.split(":")[0] not in allowed] == []
    assert any(w.startswith("pipeline/column.py") for w in found)  # the scan sees comparisons
