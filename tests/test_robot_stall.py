"""A goal that stalls says why: the motors at their stroke (which, which end), a near-singular
Jacobian (its smallest singular value), the solver, or the step rule. Before: `robot goto`
said "stalled" and the closest pose, nothing more."""

import numpy as np
import pytest

from metasheet.published import paper
from metasheet.robot import InverseController, SheetPair, six_dof_robot, solve_equilibrium
from metasheet.robot.stall import StallDiagnosis, diagnose
from metasheet.sheet import SheetParams


@pytest.fixture(scope="module")
def coarse():
    robot = six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=14.0)), paper.PAPER_FOAM, density=paper.FOAM_DENSITY)
    return robot, solve_equilibrium(robot, robot.coupling.rest_angles).state


def test_a_goal_beyond_the_stroke_names_the_motors_at_their_limit(coarse):
    robot, rest = coarse
    res = InverseController(robot, rest).goto([0.0, 0.0, -25.0, 0.0, 0.0, 0.0])  # 25 mm down: far beyond
    assert not res.reached
    d = diagnose(robot, res)
    assert d.causes[0] == "stroke"
    hi = np.degrees(robot.angle_max)
    assert d.at_max and all(res.angles_deg[m - 1] == pytest.approx(hi[m - 1], abs=0.05) for m in d.at_max)
    assert all(f"motor {m} at its upper end" in d.text() for m in d.at_max)
    assert d.certified


def test_a_rotation_far_beyond_reach_names_a_near_singular_jacobian(coarse):
    robot, rest = coarse
    res = InverseController(robot, rest).goto([0.0, 0.0, 0.0, 40.0, 0.0, 0.0])
    d = diagnose(robot, res)
    assert not res.reached and d.causes == ("singular",)
    assert d.singular_values[-1] < 0.15 * d.singular_values[0]
    assert "smallest singular value" in d.text()


def test_the_cli_prints_the_cause_before_exit_4(coarse, capsys):
    from metasheet.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["robot", "goto", "--mesh-size", "14", "--", "0", "0", "-25", "0", "0", "0"])
    assert exc.value.code == 4
    out, err = capsys.readouterr()
    assert "limited by: motors at their stroke: motor" in out
    assert "error: goal not reached" in err and "motors at their stroke" in err


def test_each_cause_reads_as_one_line():
    d = StallDiagnosis(("stroke", "singular", "solver", "step rule"), (2,), (5,), np.array([10.0, 5, 4, 3, 2, 0.5]),
                       False)
    lines = d.text().splitlines()
    assert lines[0] == "motors at their stroke: motor 2 at its lower end, motor 5 at its upper end"
    assert lines[1].startswith("near-singular Jacobian: smallest singular value 0.5 mm/rad, 0.05 of the largest")
    assert "not a certified equilibrium" in lines[2] and "max_step_deg" in lines[3]
