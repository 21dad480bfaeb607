"""``robot goto --column reproduction`` drives the pipeline's mesh and scene with the published
constants under the authors' force field; ``--tol-mm`` / ``--tol-deg`` set the tolerances
(the paper's test: 1 mm, 2 deg)."""

import numpy as np
import pytest

from metasheet import paper
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
