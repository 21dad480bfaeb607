"""The robot's rest linearisation from two condensed sheets (metasheet.robot.condensed, issue 44)
against the FEM robot's own, on coarse meshes (15 mm sheets, 1,178 tets; P1 and P2).

Second methods: the design module's linear rest problem (P1: its own assembly, world-frame
tensors, one condensation of both sheets) and the robot's Linearizer at the rest state with no
gravity (P2: the corotational tangent, which is the linear one at rest)."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.design.adjoint import rest_problem, solve_rest
from metasheet.errors import ConfigError
from metasheet.robot.builder import SheetPair, material_stiffness, six_dof_robot
from metasheet.robot.condensed import (
    condensed_kinematics,
    condensed_robot_S,
    rest_numbers_condensed,
)
from metasheet.robot.kinematics import kinematics
from metasheet.robot.robots import ServoGeometry
from metasheet.robot.uncertainty import rest_numbers
from metasheet.sheet.grips import fem_condensed
from metasheet.sheet.outline import SheetParams

RTOL = 1e-8
L = 50.0  # [mm] length scale of the singular values


def _condensed(sheets, element):
    Ca = material_stiffness(paper.PAPER_FOAM, sheets.fibers)
    Cb = material_stiffness(paper.PAPER_FOAM, sheets.fibers_mirrored)
    return fem_condensed(sheets.sheet, Ca, element), fem_condensed(sheets.mirrored, Cb, element)


@pytest.mark.parametrize("scene", ["default", "authors"])
def test_p1_condensed_sheets_give_the_design_rest_problem(scene):
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)
    kw = {} if scene == "default" else {
        "rod_length": 100.0, "geometry": ServoGeometry(rest_angle=None, servo_radius=66.0, servo_depth=30.0)}
    problem = rest_problem(sheets, paper.PAPER_FOAM, **kw)
    sol = solve_rest(problem, np.zeros(problem.n_coefficients))
    a, b = _condensed(sheets, "p1")
    S = condensed_robot_S(a.K, b.K, problem.robot, a.references)
    d = np.sqrt(np.diag(sol.S))
    assert np.all(np.abs(S - sol.S) <= RTOL * np.outer(d, d))
    kin = condensed_kinematics(a.K, b.K, problem.robot, a.references, length_scale=L)
    assert np.abs(kin.J - sol.J).max() <= RTOL * np.abs(sol.J).max()
    nums = rest_numbers_condensed(a.K, b.K, problem.robot, a.references, length_scale=L)
    assert abs(nums["rod_rotation_deg_per_deg"] - sol.roll) <= RTOL * abs(sol.roll)
    assert np.allclose(nums["singular_values"], sol.singular_values, rtol=RTOL, atol=0)
    assert abs(sol.roll) > 0.05  # the spiral rolls the rod: a number worth comparing


def test_p2_condensed_sheets_give_the_robots_rest_linearisation():
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0), element="p2", pitch_deg=30.0)
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY, gravity=(0.0, 0.0, 0.0))
    lin = robot.linearizer().linearize(robot.rest_state())
    ref = kinematics(lin, length_scale=L)
    a, b = _condensed(sheets, "p2")
    S = condensed_robot_S(a.K, b.K, robot, a.references)
    Sr = 0.5 * (lin.S + lin.S.T)
    d = np.sqrt(np.diag(Sr))
    assert np.all(np.abs(S - Sr) <= RTOL * np.outer(d, d))
    kin = condensed_kinematics(a.K, b.K, robot, a.references, length_scale=L)
    assert np.abs(kin.J - ref.J).max() <= RTOL * np.abs(ref.J).max()
    nums = rest_numbers_condensed(a.K, b.K, robot, a.references, length_scale=L)
    want = rest_numbers(robot, length_scale=L)  # its equilibrium solve: the rest state, no gravity
    assert abs(nums["rod_rotation_deg_per_deg"] - want["rod_rotation_deg_per_deg"]) \
        <= RTOL * abs(want["rod_rotation_deg_per_deg"])
    assert np.allclose(nums["singular_values"], want["singular_values"], rtol=RTOL, atol=0)


def test_bad_inputs_name_the_argument():
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY, gravity=(0.0, 0.0, 0.0))
    K, r = np.eye(24), np.zeros((4, 3))
    with pytest.raises(ConfigError, match="K_a"):
        condensed_robot_S(np.eye(18), K, robot, r)
    with pytest.raises(ConfigError, match="K_b"):
        condensed_robot_S(K, np.full((24, 24), np.nan), robot, r)
    with pytest.raises(ConfigError, match="references"):
        condensed_robot_S(K, K, robot, np.zeros((4, 2)))
    with pytest.raises(ConfigError, match="robot"):
        condensed_robot_S(K, K, object(), r)
