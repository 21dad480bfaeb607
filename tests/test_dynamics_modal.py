"""The modal model of the robot in time (metasheet.dynamics.modal) against an ODE solver on one
mode and against the full corotational robot in time on a fast motor program."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from metasheet.dynamics.mass import box_inertia
from metasheet.dynamics.modal import ModalModel, fastest_speed, modal_model, path_coordinates, respond, rod_gap
from metasheet.dynamics.response import play, quasi_static_path
from metasheet.dynamics.robot import DynamicRobot
from metasheet.dynamics.robot_modes import robot_modes
from metasheet.dynamics.schemes import GeneralizedAlpha, QuasiStatic
from metasheet.errors import ConfigError


def test_one_mode_against_an_ode_solver():
    """eta'' + 2 zeta w eta' + w^2 eta = -m'' - alpha m' for a piecewise linear m: integrated
    interval by interval with the impulses of m'' at the samples (another method)."""
    w, alpha, beta = 2 * np.pi * 7.0, 3.0, 0.004
    model = ModalModel(np.array([w]), np.array([alpha / (2 * w) + beta * w / 2]), np.ones((1, 6)), alpha, beta)
    times = np.array([0.0, 0.05, 0.13, 0.2, 0.5])
    m = np.array([[0.0], [0.4], [-0.1], [0.3], [0.3]])
    t, eta = respond(model, times, m, 1e-4, tail=0.3)
    rate = np.diff(m[:, 0]) / np.diff(times)
    y, prev, ref_t, ref = np.zeros(2), 0.0, [], []
    bounds = list(times) + [times[-1] + 0.3]
    for s in range(len(bounds) - 1):
        r = rate[s] if s < len(rate) else 0.0
        y[1] -= r - prev  # the impulse of m''
        prev = r
        z = model.zeta[0]
        sol = solve_ivp(lambda _, q: [q[1], -2 * z * w * q[1] - w * w * q[0] - alpha * r], (bounds[s], bounds[s + 1]), y,
                        rtol=1e-10, atol=1e-12, dense_output=True)
        inside = (t >= bounds[s]) & (t < bounds[s + 1])
        ref_t += list(t[inside])
        ref += list(sol.sol(t[inside])[0])
        y = sol.y[:, -1].copy()
    assert np.allclose(eta[:len(ref), 0], ref, atol=2e-3 * np.abs(ref).max())
    with pytest.raises(ConfigError, match="h, speed"):
        respond(model, times, m, 0.0)


def test_the_fastest_speed_is_where_the_gap_crosses_the_tolerance():
    w = 2 * np.pi * 5.0
    model = ModalModel(np.array([w]), np.array([0.1]), np.array([[1.0, 0, 0, 0, 0, 0]]), 0.0, 0.2 / w)
    times = np.array([0.0, 1.0, 2.0])
    m = np.array([[0.0], [1.0], [1.0]])
    f = fastest_speed(model, times, m, 0.01, 0.05, hi=256.0)
    s = f["speed"]
    assert 1.0 < s < 256.0
    assert rod_gap(model, times, m, 0.01, s) <= 0.05 < rod_gap(model, times, m, 0.01, s * 1.05)


@pytest.fixture(scope="module")
def robot_and_path(foam_robot_14):
    rigid = box_inertia(20e-6, (70, 60, 3), centre=foam_robot_14.coupling.origin + np.array([3.0, -2.0, 4.5]))
    qs = DynamicRobot(foam_robot_14, rigid, scheme=QuasiStatic())
    rest = qs.step(qs.start(foam_robot_14.rest_state()), foam_robot_14.coupling.rest_angles, 1.0, tol=1e-10)
    a0 = rest.state.angles
    d = np.radians([4, -3, 2, -1, 3, 0])
    times = np.array([0, 0.03, 0.06, 0.09, 0.25])
    angles = np.array([a0, a0 + d, a0 + 2 * d, a0 + 1.5 * d, a0 + 1.5 * d])
    xs = []
    quasi = quasi_static_path(qs, rest, times, angles, substeps=2, keep_x=xs)
    return rigid, qs, rest, times, angles, quasi, np.array(xs)


def test_the_modal_model_follows_the_full_robot_on_a_fast_program(foam_robot_14, robot_and_path):
    rigid, qs, rest, times, angles, quasi, xs = robot_and_path
    beta = 0.01
    modes = robot_modes(qs, rest.state, n=10)
    model = modal_model(modes, 0.0, beta)
    pts = np.array([qs.points(p, R) for p, R in zip(quasi.p, quasi.R)])
    m = path_coordinates(modes.shapes, modes.effector, qs.M, xs, pts, qs.m_pts, rest.state.p)
    t, eta = respond(model, times, m, 0.001)
    dyn = DynamicRobot(foam_robot_14, rigid, beta=beta, scheme=GeneralizedAlpha(0.9))
    run, _ = play(dyn, dyn.start(rest.state), times, angles, 0.001)
    qp = quasi.pose
    full = run.pose - np.stack([np.interp(run.t, times, qp[:, k]) for k in range(6)], axis=1)
    modal = eta @ model.effector
    n = min(len(t), len(run.t))
    pos_full, pos_modal = np.linalg.norm(full[:n, :3], axis=1), np.linalg.norm(modal[:n, :3], axis=1)
    assert pos_full.max() > 0.02  # a fast program: the rod lags its quasi-static path visibly
    assert pos_modal.max() == pytest.approx(pos_full.max(), rel=0.15)
    assert np.sqrt(np.mean((full[:n, :3] - modal[:n, :3]) ** 2)) < 0.1 * pos_full.max()
