"""The equilibrium surface (issue 16, real time): polynomial fit, SO(3) bookkeeping, the robot
interface the controller runs on, and the fit against a real robot's equilibria."""

from math import comb
from types import SimpleNamespace

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.robot.inverse import InverseController, InverseSettings
from metasheet.robot.kinematics import jacobian_from_schur
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.rom.surface import (EquilibriumData, choose_degree, errors, exponents, fit_surface,
                                   left_jacobian, monomials)
from metasheet.rom.surface_robot import SurfaceRobot, equilibrium_data
from metasheet.mechanics.rotations import rotation_matrix, rotation_vector

NA = 3
LO, HI = np.radians([-10.0, -8.0, -12.0]), np.radians([10.0, 12.0, 8.0])
REST = np.zeros(NA)
B = np.random.default_rng(4).normal(size=(6, NA))  # a fixed linear response [mm/rad, rad/rad]


def _map(q):
    """An analytic 'robot': pose (6,) with a cubic position and a quadratic rotation vector,
    and its Jacobian (6, NA) in the controller's convention (rotation increments w)."""
    q = np.asarray(q, float)
    p = 10 * B[:3] @ q + 3 * q[0] * q[1] * np.array([1.0, -2.0, 0.5]) + 5 * q[2] ** 3 * np.array([0.0, 1.0, 1.0])
    dp = 10 * B[:3].copy()
    dp[:, 0] += 3 * q[1] * np.array([1.0, -2.0, 0.5])
    dp[:, 1] += 3 * q[0] * np.array([1.0, -2.0, 0.5])
    dp[:, 2] += 15 * q[2] ** 2 * np.array([0.0, 1.0, 1.0])
    rv = B[3:] @ q + 0.5 * q[1] ** 2 * np.array([1.0, 0.0, -1.0])
    drv = B[3:].copy()
    drv[:, 1] += q[1] * np.array([1.0, 0.0, -1.0])
    return np.r_[np.array([1.0, 2.0, 3.0]) + p, rv], np.vstack([dp, left_jacobian(rv) @ drv])


def _data(angles):
    poses, Js, Ss = [], [], []
    for q in angles:
        pose, J = _map(q)
        See = np.diag([2.0, 3.0, 4.0, 50.0, 60.0, 70.0]) * (1 + 0.1 * q.sum())
        M = np.eye(NA) * 5.0
        Sea = -See @ J
        poses.append(pose)
        Js.append(J)
        Ss.append(np.block([[See, Sea], [Sea.T, M + J.T @ See @ J]]))
    return EquilibriumData(np.array(angles), np.array(poses), np.array(Js), np.array(Ss))


def _sobol(n, seed):
    from metasheet.rom.training import motor_design

    return motor_design(LO, HI, n, seed, corners=False)


def test_monomials_count_and_derivatives():
    E = exponents(4, 3)
    assert len(E) == comb(4 + 3, 3) and E.sum(axis=1).max() == 3
    u = np.array([[0.3, -0.7, 0.2, 0.9]])
    phi, dphi = monomials(u, E, grad=True)
    h = 1e-6
    for i in range(4):
        du = np.zeros(4)
        du[i] = h
        fd = (monomials(u + du, E) - monomials(u - du, E)) / (2 * h)
        np.testing.assert_allclose(dphi[:, i], fd, atol=1e-8)


def test_left_jacobian_matches_the_rotation_increment():
    phi = np.array([0.3, -0.2, 0.4])
    d = np.array([1e-6, -2e-6, 0.5e-6])
    w = rotation_vector(rotation_matrix(phi + d) @ rotation_matrix(phi).T)
    np.testing.assert_allclose(w, left_jacobian(phi) @ d, rtol=1e-5)


def test_a_polynomial_map_is_reproduced_and_its_tangent_has_the_fitted_jacobian():
    train = _data(_sobol(40, 1))
    check = _data(_sobol(10, 2))
    rest = _data([REST])
    # cubic positions: degree 3 is exact there; the rotation vector is a quadratic
    s = fit_surface(train, rest, LO, HI, 3)
    e = errors(s, check)
    assert e["position_mm"].max() < 1e-9
    assert e["orientation_deg"].max() < 1e-7
    assert e["jacobian_rel"].max() < 1e-8
    p, R, J, S = s.evaluate(check.angles[3])
    np.testing.assert_allclose(jacobian_from_schur(S)[1], J, atol=1e-9)  # eq. 7 of the rebuilt S
    np.testing.assert_allclose(S, S.T, atol=1e-9)
    # a too-low degree is not chosen when a higher one meets the targets
    chosen = choose_degree(train, check, rest, LO, HI, {"position_mm": 1e-6, "orientation_deg": 1e-6,
                                                        "jacobian_rel": 1e-6})
    assert chosen.info["degree"] == 3 and chosen.info["met"]
    assert [t["degree"] for t in chosen.info["tried"]] == [2, 3]
    with pytest.raises(ConfigError, match="equilibria"):
        fit_surface(_data(_sobol(4, 1)), rest, LO, HI, 4)


def test_the_degree_is_chosen_on_check_equilibria_within_the_strain_limit():
    """A check equilibrium beyond the strain limit (here: one whose pose is off by 1 mm, as a
    model outside its domain would be) does not count when the limit is given."""
    train, rest = _data(_sobol(40, 1)), _data([REST])
    check = _data(_sobol(10, 2))
    pose = check.pose.copy()
    pose[0, 0] += 1.0
    strain = np.full(10, 0.1)
    strain[0] = 0.5
    check = EquilibriumData(check.angles, pose, check.J, check.S, strain)
    targets = {"position_mm": 1e-6, "orientation_deg": 1e-6, "jacobian_rel": 1e-6}
    within = choose_degree(train, check, rest, LO, HI, targets, strain_limit=0.3)
    assert within.info["degree"] == 3 and within.info["met"] and within.info["check_equilibria"] == 9
    every = choose_degree(train, check, rest, LO, HI, targets)
    assert not every.info["met"] and every.info["check_equilibria"] == 10
    assert every.info["check_worst"]["position_mm"] == pytest.approx(1.0, abs=1e-6)
    none_within = EquilibriumData(check.angles, pose, check.J, check.S, np.full(10, 0.5))
    assert choose_degree(train, none_within, rest, LO, HI, targets, strain_limit=0.3).info["check_strain_limit"] is None


def _robot(surface):
    coupling = SimpleNamespace(n_act=NA, rest_angles=REST.copy(), length_scale=50.0)
    full = SimpleNamespace(coupling=coupling, angle_min=np.radians([-90.0] * NA), angle_max=np.radians([90.0] * NA),
                           name="toy")
    return SurfaceRobot(surface, full, force_scale=1.0)


def test_the_controller_runs_on_the_surface_and_finds_the_motors():
    train = _data(_sobol(40, 1))
    robot = _robot(fit_surface(train, _data([REST]), LO, HI, 3))
    eq = solve_equilibrium(robot, np.radians([4.0, -3.0, 2.0]))  # from rest: increments and Newton
    np.testing.assert_allclose(eq.state.pose, _map(np.radians([4.0, -3.0, 2.0]))[0], atol=1e-9)
    q_star = np.radians([5.0, 6.0, -4.0])
    pose, _ = _map(q_star)
    goal = np.r_[pose[:3], np.degrees(pose[3:])]
    # only 3 motors: a 6-DOF goal is reachable because it lies on the surface
    ctrl = InverseController(robot, settings=InverseSettings(pos_tol=1e-4, rot_tol_deg=1e-4, max_steps=200))
    r = ctrl.goto(goal)
    assert r.reached
    np.testing.assert_allclose(r.angles_deg, np.degrees(q_star), atol=1e-3)
    assert ctrl.linearizer.factorizations == 0  # nothing to factorise: no refresh in a step


def test_the_robot_keeps_its_last_evaluation_and_only_that():
    surface = fit_surface(_data(_sobol(40, 1)), _data([REST]), LO, HI, 3)
    robot = _robot(surface)
    a, b = np.radians([4.0, -3.0, 2.0]), np.radians([-1.0, 5.0, 0.5])
    first = robot.evaluate(a)
    assert robot.evaluate(a.copy()) is first  # the same angles: kept
    for q in (b, a):  # other angles: evaluated anew, equal to the surface's own evaluation
        for mine, ref in zip(robot.evaluate(q), surface.evaluate(q)):
            np.testing.assert_array_equal(mine, ref)
    np.testing.assert_allclose(robot.equilibrium(b).p, surface.evaluate(b)[0])


def test_angles_outside_the_box_are_refused():
    robot = _robot(fit_surface(_data(_sobol(40, 1)), _data([REST]), LO, HI, 2))
    np.testing.assert_allclose(robot.angle_max, HI)  # the QP's bounds: the box within the motor range
    with pytest.raises(ConfigError, match="holds within its box"):
        robot.equilibrium(np.radians([11.0, 0.0, 0.0]))


def test_fitted_on_a_coarse_robot_it_matches_the_robot_on_unseen_angles():
    """The surface of a real (coarse, full-model) robot over rest +- 3 deg: errors on held-out
    equilibria far below the certificate's targets (0.1 mm, 0.1 deg, 2 %)."""
    from metasheet.published import paper
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.rom.training import motor_design
    from metasheet.sheet.geometry import SheetParams

    rob = six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=14)), paper.PAPER_FOAM, density=paper.FOAM_DENSITY)
    lo, hi = rob.coupling.rest_angles - np.radians(3), rob.coupling.rest_angles + np.radians(3)
    lz = rob.linearizer()
    rest = equilibrium_data(rob, rob.coupling.rest_angles[None], linearizer=lz)
    train = equilibrium_data(rob, motor_design(lo, hi, 40, 11), linearizer=lz)
    check = equilibrium_data(rob, motor_design(lo, hi, 8, 12, corners=False), linearizer=lz)
    s = fit_surface(train, rest, lo, hi, 2)
    e = errors(s, check)
    assert e["position_mm"].max() < 0.01 and e["orientation_deg"].max() < 0.01 and e["jacobian_rel"].max() < 0.01
    sr = SurfaceRobot(s, rob, force_scale=1.0)
    q = check.angles[0]
    np.testing.assert_allclose(sr.equilibrium(q).p, check.pose[0, :3], atol=0.01)
