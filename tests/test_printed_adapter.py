"""The printed robot behind the study protocol (metasheet/studies/printed_adapter.py), on the
FEM-condensed sheets of a coarse robot: its Jacobian against central differences of its own
equilibria and, at rest, against the linear condensed model; the inverse model reaching poses
the forward model made; the walls' box and the motor limits; the strain bound; the workspace
study running on it."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.mechanics.rotations import rotation_matrix, rotation_vector
from metasheet.published import paper
from metasheet.robot.builder import SheetPair, material_stiffness, six_dof_robot
from metasheet.robot.condensed import condensed_robot_S
from metasheet.sheet.grips import fem_condensed, grip_references
from metasheet.sheet.outline import SheetParams
from metasheet.studies.grid import star_grid
from metasheet.studies.model import RobotModel
from metasheet.studies.printed_adapter import PrintedSpec, printed_spec
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace

MOVE = np.array([4.0, -3.0, 2.0, 1.0, -2.0, 3.0])  # [deg] from rest


@pytest.fixture(scope="module")
def coarse():
    params = SheetParams(mesh_size=15.0)
    sheets = SheetPair.spiral(params, pitch_deg=30.0)
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY, gravity=(0.0, 0.0, 0.0))
    Ka = fem_condensed(sheets.sheet, material_stiffness(paper.PAPER_FOAM, sheets.fibers), "p1").K
    Kb = fem_condensed(sheets.mirrored, material_stiffness(paper.PAPER_FOAM, sheets.fibers_mirrored), "p1").K
    refs = grip_references(params)
    return robot, Ka, Kb, refs, printed_spec(robot, Ka, Kb, refs, label="coarse", motor_range=(-60.0, 120.0))


def test_the_jacobian_is_the_linear_models_at_rest_and_its_own_equilibria_derivative_away(coarse):
    robot, Ka, Kb, refs, spec = coarse
    model = spec.build()
    assert isinstance(model, RobotModel)
    rest = model.rest_motors()
    _, st = model.equilibrium(rest)
    S = condensed_robot_S(Ka, Kb, robot, refs)
    J_lin = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    J = model.jacobian(st)
    assert np.abs(J - J_lin).max() <= 1e-6 * np.abs(J_lin).max()
    # away from rest: central differences of the equilibria, rotations as spatial angles
    m = rest + 5 * MOVE
    pose, st = model.equilibrium(m)
    J = model.jacobian(st)
    def central(k, d):  # [deg]; the rotation as the angle between the two rotations
        e = np.zeros(6)
        e[k] = d
        a, _ = model.equilibrium(m + e, state=st)
        b, _ = model.equilibrium(m - e, state=st)
        col = np.concatenate([(a[:3] - b[:3]), rotation_vector(rotation_matrix(a[3:]) @ rotation_matrix(b[3:]).T)])
        return col / (2 * np.radians(d))

    for k in range(6):
        # Richardson's step halving (the equilibria hold ~1e-9 mm: the differenced energy's round-off)
        col = (4 * central(k, 0.01) - central(k, 0.02)) / 3
        assert np.abs(col - J[:, k]).max() <= 1e-5 * np.abs(J).max(), k


def test_the_inverse_model_reaches_what_the_forward_model_made(coarse):
    model = coarse[4].build()
    goal, _ = model.equilibrium(model.rest_motors() + MOVE)
    r = model.reach(goal, tol_mm=0.01, tol_deg=0.01)
    assert r.reached and r.converged and not r.left_domain
    assert r.error_mm <= 0.01 and r.error_deg <= 0.01
    pose, _ = model.equilibrium(r.motors_deg)  # the reported pose is the equilibrium of its motors
    assert np.abs(pose - r.pose).max() < 1e-9


def test_the_walls_box_stops_a_reach_and_the_motor_limits_bound_it(coarse):
    spec = coarse[4]
    model = spec.build()
    rest = model.rest_motors()
    goal, _ = model.equilibrium(rest + 3 * MOVE)  # 12 deg of travel
    boxed = PrintedSpec(**{**spec.__dict__, "valid_deg": 4.0}).build()
    r = boxed.reach(goal, tol_mm=0.01, tol_deg=0.01)
    assert r.left_domain and not r.reached
    travel = np.abs(r.motors_deg - rest).max()
    assert 4.0 < travel <= 4.0 + spec.max_step_deg  # stopped by the first step past the box
    lo = rest.min() - 2.0  # the goal turns motor 1 by -9 deg
    limited = spec.with_motor_range(lo, 120.0).build()
    r = limited.reach(goal, tol_mm=0.01, tol_deg=0.01)
    assert r.motors_deg.min() >= lo - 1e-9 and not r.reached


def test_the_walls_strain_bound_adds_each_motors_share(coarse):
    spec = coarse[4]
    rates = np.array([[0.01, 0.02]] * 3 + [[0.03, 0.005]] * 3)
    model = PrintedSpec(**{**spec.__dict__, "wall_strain_per_deg": rates}).build()
    rest = model.rest_motors()
    _, st = model.equilibrium(rest + MOVE)
    expected = 4 * 0.01 + 3 * 0.02 + 2 * 0.01 + 1 * 0.03 + 2 * 0.005 + 3 * 0.03
    assert model.max_principal_strain(st) == pytest.approx(expected, rel=1e-12)
    assert np.isnan(spec.build().max_principal_strain(st))
    with pytest.raises(ConfigError, match="wall_strain_per_deg"):
        PrintedSpec(**{**spec.__dict__, "wall_strain_per_deg": -rates})


def test_the_spec_is_named_and_refuses_other_materials(coarse):
    spec = coarse[4]
    assert spec.key == printed_spec(*coarse[:4], label="coarse", motor_range=(-60.0, 120.0)).key
    assert spec.key != PrintedSpec(**{**spec.__dict__, "label": "another"}).key
    with pytest.raises(ConfigError, match="alpha"):
        spec.with_alpha(50.0)
    with pytest.raises(ConfigError, match="material"):
        spec.with_material(paper.PAPER_FOAM)
    with pytest.raises(ConfigError, match="valid_deg"):
        PrintedSpec(**{**spec.__dict__, "valid_deg": -1.0})


def test_the_workspace_study_runs_on_a_print(coarse):
    spec = PrintedSpec(**{**coarse[4].__dict__, "valid_deg": 20.0})
    grid = star_grid(n_azimuth=4, n_elevation=2, n_steps=3, extent_axial=6.0, extent_lateral=6.0)
    ws = explore_workspace(spec, grid, WorkspaceSettings(substeps=2, rot_axes="x", stop_beyond_strain=False))
    assert ws.records.reached.sum() >= 3 and np.all(ws.records.converged[ws.records.reached])
    again = explore_workspace(spec, grid, WorkspaceSettings(substeps=2, rot_axes="x", stop_beyond_strain=False))
    np.testing.assert_array_equal(ws.records.reached, again.records.reached)
