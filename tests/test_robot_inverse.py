"""Inverse QP (eq. 8) and the control loop on a coarse tripod; isotropic vs foam on a coarse 6-DOF robot."""

from dataclasses import replace

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic
from metasheet.published.paper import PAPER_FOAM, SILICONE
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.compare import evaluate
from metasheet.robot.robots import tripod
from metasheet.robot.inverse import InverseController, InverseSettings
from metasheet.robot.qp import solve_step_qp
from metasheet.mechanics.rotations import rotation_vector
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.sheet.geometry import SheetParams, tripod_sheet


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
    D = np.array([1.0, 1.0, 1.0] + [s.rot_weight] * 3)
    for e in (rng.normal(size=6) * 1e4, rng.normal(size=6) * 1e-3):
        step = solve_step_qp(J, e, q, lo, hi, s)
        dq, ok = step.dq, step.ok
        assert ok
        assert np.all(q + dq >= lo - 1e-15) and np.all(q + dq <= hi + 1e-15)
        assert np.all(np.abs(dq) <= np.radians(3.0) + 1e-15)
        # the solution's own checks: feasible, and no worse than not moving (dq = 0 is feasible)
        assert step.solver == s.solver and step.primal_residual <= 1e-12
        assert step.objective <= 0.5 * np.sum((D * e) ** 2) * (1 + 1e-12)
    # an interior optimum is the regularised least-squares solution
    dq_true = np.radians([0.5, -0.3, 0.2])
    step = solve_step_qp(J, J @ dq_true, np.full(3, 0.7), lo, hi, InverseSettings(rot_weight=1.0))
    dq = step.dq
    assert np.allclose(dq, dq_true, atol=1e-6)
    eps = InverseSettings().regularization * np.linalg.eigvalsh(J.T @ J)[-1]  # D = I with rot_weight 1
    # optimal, and no worse than dq_true, whose cost is the regularisation's alone [mm^2]
    assert step.is_optimal(1e-8) and step.objective <= 0.5 * eps * (dq_true @ dq_true) * (1 + 1e-9)


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


def test_per_call_settings_leave_the_controller_unchanged(robot):
    """goto(settings=...) takes exactly the steps of a controller whose settings were replaced."""
    from dataclasses import replace

    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state
    goal_state = solve_equilibrium(robot, rest.angles + np.radians([-4.0, 3.0, -6.0]), state=rest).state
    goal = np.concatenate([goal_state.p, np.degrees(rotation_vector(goal_state.R))])
    base = InverseSettings()
    per_goal = replace(base, rot_weight=20.0, pos_tol=0.05, rot_tol_deg=0.1, max_steps=40)
    mutated = InverseController(robot, rest, base)
    mutated.settings = per_goal  # the old way: overwrite the controller's settings
    ref = mutated.goto(goal)
    ctl = InverseController(robot, rest, base)
    res = ctl.goto(goal, settings=per_goal)
    assert ctl.settings is base
    assert res.status == ref.status == "reached" and res.steps == ref.steps
    assert np.array_equal(res.state.x, ref.state.x) and res.residual == ref.residual
    assert ctl.refresh_reasons == mutated.refresh_reasons and ctl.refreshes == mutated.refreshes
    info = ctl.step(goal[:3], goal_state.R, settings=per_goal)
    assert info.qp is not None and info.qp.ok == info.qp_ok and np.array_equal(info.qp.dq, info.dq_a)
    with pytest.raises(ConfigError, match="settings"):
        ctl.goto(goal, settings={"pos_tol": 0.05})


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
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0))
    out = {}
    for name, mat in (("silicone", SILICONE), ("foam", PAPER_FOAM)):
        rob = six_dof_robot(sheets, mat, density=1.1e-9)
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


def _off_equilibrium(robot, state, target):
    """``state`` with the effector (and what it carries) moved rigidly onto ``target``'s pose and
    every free node left where it was: its pose is ``target``'s, its residual large."""
    from metasheet.robot.statics import apply_step

    dq_e = np.concatenate([target.p - state.p, rotation_vector(target.R @ state.R.T)])
    return apply_step(robot, state, dq_e, np.zeros(3 * len(robot.coupling.free)))


def test_a_pose_the_pending_correction_moves_out_is_not_certified_and_a_stop_there_is_not_reached(robot):
    """A state within the tolerance whose pending equilibrium correction takes the effector out of
    it is stepped on, not certified (a Newton solve only to step on); a run stopped there returns
    that uncertified state as "stopped", never "reached"."""
    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state
    target = solve_equilibrium(robot, rest.angles + np.radians([-1.5, -0.5, -2.5]), state=rest).state
    off = _off_equilibrium(robot, rest, target)  # target's pose, rest's sheets and motors
    goal = np.concatenate([target.p, np.degrees(rotation_vector(target.R))])
    ctl = InverseController(robot, rest, InverseSettings(pos_tol=0.5, rot_tol_deg=0.5))
    assert np.linalg.norm(ctl.refresh(off).newton_step(None)[0][:3]) > 2.0  # the correction moves it out
    res = ctl.goto(goal, state=off, stop=lambda st: True, certify_stop=False)
    assert res.status == "stopped" and res.steps == 1 and res.certified == "none"
    assert res.pos_error < 1e-9  # the uncertified state itself is on the goal: still not "reached"
    assert ctl.certified == {"chord": 0, "newton": 0}


def test_a_state_is_stepped_on_uncertified_only_while_its_residual_contracts(robot):
    """The skip is granted to the first state within the tolerance whose pending correction moves
    it out, and after that only to a state whose residual is below ``polish_rate`` times the last
    skipped one: a run drifting away from equilibrium is certified, not stepped on."""
    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state
    target = solve_equilibrium(robot, rest.angles + np.radians([-1.5, -0.5, -2.5]), state=rest).state
    off = _off_equilibrium(robot, rest, target)
    s = InverseSettings(pos_tol=0.5, rot_tol_deg=0.5)
    ctl = InverseController(robot, rest, s)
    ctl.state = off
    e = np.zeros(6)  # the state is on the goal
    r = ctl._skip_certify(e, s, None)
    assert r is not None and r == pytest.approx(ctl.linearization(s).residual_norm, rel=1e-12)
    assert ctl._skip_certify(e, s, r / s.polish_rate * 1.01) is not None  # contracted enough
    assert ctl._skip_certify(e, s, r / s.polish_rate * 0.99) is None  # not enough: certify
    # within the chord corrections' reach (residual 4.2 times the force scale here) certifying
    # is the cheap path: certify
    rel = r / ctl.linearizer.force_scale(ctl.linearization(s))
    assert 1.0 < rel < 9.0
    assert ctl._skip_certify(e, replace(s, chord_tol=1.1 * rel), None) is None
    ctl.state = rest  # at equilibrium the pending correction keeps it within: certify
    assert ctl._skip_certify(e, s, None) is None
