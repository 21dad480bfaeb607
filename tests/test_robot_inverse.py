"""Inverse QP (eq. 8) and the control loop on a coarse tripod; isotropic vs foam on a coarse 6-DOF robot."""

import numpy as np
import pytest

from metasheet.material import Isotropic
from metasheet.robot.assemblies import tripod
from metasheet.robot.compare import PAPER_FOAM, SILICONE, build_six_dof, evaluate
from metasheet.robot.inverse import InverseController, InverseSettings, solve_step_qp
from metasheet.robot.rigid import rotation_vector
from metasheet.robot.statics import solve_equilibrium
from metasheet.sheet.fibers import spiral_fibers
from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet


@pytest.fixture(scope="module")
def robot():
    return tripod(tripod_sheet(SheetParams(mesh_size=15.0)), Isotropic(0.25, 0.45).stiffness(), density=1.07e-9)


@pytest.mark.parametrize("seed", range(5))
def test_qp_stays_in_the_stroke_for_any_goal(seed):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(6, 3)) * 10
    q = rng.uniform(0, np.pi / 2, size=3)
    lo, hi = np.zeros(3), np.full(3, np.pi / 2)
    s = InverseSettings(max_step_deg=3.0)
    for e in (rng.normal(size=6) * 1e4, rng.normal(size=6) * 1e-3):
        dq, ok = solve_step_qp(J, e, q, lo, hi, s)
        assert ok
        assert np.all(q + dq >= lo - 1e-15) and np.all(q + dq <= hi + 1e-15)
        assert np.all(np.abs(dq) <= np.radians(3.0) + 1e-15)
    # an interior optimum is the regularised least-squares solution
    dq_true = np.radians([0.5, -0.3, 0.2])
    dq, _ = solve_step_qp(J, J @ dq_true, np.full(3, 0.7), lo, hi, InverseSettings(rot_weight=1.0))
    assert np.allclose(dq, dq_true, atol=1e-6)


def test_reaches_a_pose_the_forward_model_produced(robot):
    """Independent answer: solve statics at known angles, ask the inverse loop for that pose."""
    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state
    target_angles = rest.angles + np.radians([-6.0, -2.0, -10.0])
    goal_state = solve_equilibrium(robot, target_angles, state=rest).state
    goal = np.concatenate([goal_state.p, np.degrees(rotation_vector(goal_state.R))])
    ctl = InverseController(robot, rest, InverseSettings(pos_tol=0.02, rot_tol_deg=0.05))
    res = ctl.goto(goal)
    assert res.status == "reached", res.to_dict()
    assert res.pos_error <= 0.02 and res.rot_error <= 0.05
    assert np.allclose(res.angles_deg, np.degrees(target_angles), atol=0.5)


def test_unreachable_goal_returns_closest_pose_inside_limits(robot):
    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state
    ctl = InverseController(robot, rest, InverseSettings(max_step_deg=10.0, max_steps=60))
    goal = np.array([0.0, 0.0, 40.0, 0.0, 0.0, 0.0])  # 40 mm up: far beyond the stroke
    lo, hi = robot.angle_min, robot.angle_max
    for _ in range(8):  # every intermediate command stays in the stroke
        ctl.step(goal[:3], np.eye(3))
        assert np.all(ctl.state.angles >= lo - 1e-12) and np.all(ctl.state.angles <= hi + 1e-12)
    res = ctl.goto(goal)
    assert res.status in ("stalled", "max_steps")
    assert np.all(res.angles_deg >= np.degrees(lo) - 1e-9) and np.all(res.angles_deg <= np.degrees(hi) + 1e-9)
    start_err = np.linalg.norm(goal[:3] - rest.p)
    assert res.pos_error < start_err - 1.0  # it did get closer
    assert np.isclose(res.pos_error, np.linalg.norm(goal[:3] - res.pose[:3]))
    # pulling raises the centre: the closest pose has the motors at the top of the pull stroke
    assert np.all(res.angles_deg > np.degrees(rest.angles) - 1e-6)


@pytest.fixture(scope="module")
def six_dof_cases():
    sheet = tripod_sheet(SheetParams(mesh_size=15.0))
    mirrored = mirror_sheet(sheet)
    fa = spiral_fibers(sheet.centroids())
    fb = spiral_fibers(mirrored.centroids(), mirrored=True)
    out = {}
    for name, mat in (("silicone", SILICONE), ("foam", PAPER_FOAM)):
        rob = build_six_dof(sheet, mirrored, mat, fibers=fa, fibers_mirrored=fb, density=1.1e-9)
        out[name] = evaluate(rob, name, delta_deg=-5.0)
    return out


def test_silicone_does_not_twist_the_rod_and_foam_does(six_dof_cases):
    sil, foam = six_dof_cases["silicone"], six_dof_cases["foam"]
    assert abs(foam.rod_rotation_per_degree) > 0.2  # [deg/deg]
    assert abs(sil.rod_rotation_per_degree) < 0.05 * abs(foam.rod_rotation_per_degree)
    assert abs(sil.rod_rotation_finite) < 0.05 * abs(foam.rod_rotation_finite)
    # J's prediction agrees with the finite move in sign and roughly in size
    assert np.sign(foam.rod_rotation_finite) == np.sign(foam.rod_rotation_per_degree)
    assert abs(foam.rod_rotation_finite / foam.rod_rotation_per_degree - 1) < 0.3
    # 5 controllable DOF with silicone, 6 with foam (scaled singular values, mm)
    s_sil, s_foam = sil.kin.singular_values, foam.kin.singular_values
    assert s_sil[-1] < 0.05 * s_sil[0]
    assert s_foam[-1] > 0.3 * s_foam[0]
    # the foam's rotation comes without the effector leaving the rod axis
    assert foam.lateral_finite < 0.05 * abs(foam.rod_rotation_finite) * 50
