"""The robot in time (metasheet.dynamics.robot, robot_modes, response) against independent answers:
the static solver, the weight the servos carry, the modes' frequency seen in a free vibration,
the Rayleigh damping ratio, a slow ramp that stays quasi-static."""

import numpy as np
import pytest

from metasheet.dynamics.mass import RigidInertia, box_inertia, combine
from metasheet.dynamics.response import play, program_at, step_metrics, pose_gap, quasi_static_path
from metasheet.dynamics.robot import DynamicRobot, point_masses
from metasheet.dynamics.robot_modes import robot_modes
from metasheet.dynamics.schemes import GeneralizedAlpha, ImplicitEuler, QuasiStatic
from metasheet.errors import ConfigError
from metasheet.robot.equilibrium import solve_equilibrium

G = 9810.0


@pytest.fixture(scope="module")
def rigid(foam_robot_14):
    o = foam_robot_14.coupling.origin
    return combine(box_inertia(15e-6, (70, 60, 3), o + [2.0, -1.0, 4.5]), box_inertia(5e-6, (80, 6, 6), o))


@pytest.fixture(scope="module")
def qs_rest(foam_robot_14, rigid):
    qs = DynamicRobot(foam_robot_14, rigid, scheme=QuasiStatic())
    return qs, qs.step(qs.start(foam_robot_14.rest_state()), foam_robot_14.coupling.rest_angles, 1.0, tol=1e-10)


def test_six_point_masses_have_the_bodys_mass_centre_and_inertia(rigid):
    x, m = point_masses(rigid)
    assert m.sum() == pytest.approx(rigid.mass, rel=1e-14)
    assert np.allclose((m[:, None] * x).sum(axis=0) / m.sum(), rigid.com, atol=1e-12)
    d = x - rigid.com
    inertia = sum(mi * (di @ di * np.eye(3) - np.outer(di, di)) for mi, di in zip(m, d))
    assert np.allclose(inertia, rigid.inertia, rtol=0, atol=1e-12 * np.abs(rigid.inertia).max())
    thin = RigidInertia(1e-6, np.zeros(3), np.diag([0.0, 1e-3, 1e-3]))  # a rod: on the triangle bound
    x, m = point_masses(thin)
    d = x - thin.com
    assert np.allclose(sum(mi * (di @ di * np.eye(3) - np.outer(di, di)) for mi, di in zip(m, d)), thin.inertia,
                       atol=1e-15)


def test_a_quasi_static_step_is_the_static_solvers_equilibrium(foam_robot_14, foam_rest_14):
    qs = DynamicRobot(foam_robot_14, None, scheme=QuasiStatic())
    st = qs.step(qs.start(foam_robot_14.rest_state()), foam_robot_14.coupling.rest_angles, 1.0, tol=1e-10).state
    assert np.abs(st.x - foam_rest_14.state.x).max() < 1e-8  # [mm], against a sag of ~0.03 mm
    moved = foam_robot_14.coupling.rest_angles + np.radians([3, -2, 1, 0, 2, -1])
    st2 = qs.step(qs.start(st), moved, 1.0, tol=1e-10).state
    ref = solve_equilibrium(foam_robot_14, moved, state=foam_rest_14.state, tol=1e-10).state
    assert np.abs(st2.x - ref.x).max() < 1e-7


def test_the_horns_carry_the_weight_of_sheets_and_maze(foam_robot_14, rigid, qs_rest):
    qs, rest = qs_rest
    body = foam_robot_14.body
    f = body.forces(rest.state.x).reshape(-1, 3)  # internal forces: self-balanced over every element
    horns = np.concatenate([s.nodes for s in foam_robot_14.coupling.servos])
    # the horns push the sheets up by the whole weight (r = f - f_ext is the force they apply)
    up = f[horns].sum(axis=0) - foam_robot_14.f_ext[horns].sum(axis=0)
    total = (body.mass.sum() + rigid.mass) * G
    assert up == pytest.approx([0.0, 0.0, total], abs=1e-7 * total)


def test_held_at_its_equilibrium_the_robot_stays_put(foam_robot_14, rigid, qs_rest):
    _, rest = qs_rest
    for scheme in (ImplicitEuler(), GeneralizedAlpha(0.8)):
        dyn = DynamicRobot(foam_robot_14, rigid, scheme=scheme)
        ds = dyn.start(rest.state)
        for _ in range(5):
            ds = dyn.step(ds, foam_robot_14.coupling.rest_angles, 0.005)
        assert np.abs(ds.state.x - rest.state.x).max() < 1e-9


def _free_vibration(robot, rigid, rest, mode, scheme, h, n, beta=0.0, eps=0.05):
    dyn = DynamicRobot(robot, rigid, beta=beta, scheme=scheme)
    c = robot.coupling
    from metasheet.robot.statics import RobotState
    from metasheet.mechanics.rotations import rotation_matrix

    dp = eps * mode.effector[0][:3] / np.abs(mode.effector[0]).max()
    dth = eps * mode.effector[0][3:] / np.abs(mode.effector[0]).max()
    x = rest.state.x + eps * mode.shapes[0] / np.abs(mode.effector[0]).max()
    R = rotation_matrix(dth) @ rest.state.R
    p = rest.state.p + dp
    start = RobotState(p, R, rest.state.angles, c.positions(p, R, rest.state.angles, x[c.free]))
    ds = dyn.start(start)
    z = [ds.state.p.copy()]
    for _ in range(n):
        ds = dyn.step(ds, rest.state.angles, h, tol=1e-10)
        z.append(ds.state.p.copy())
    return np.array(z)


def test_a_free_vibration_swings_at_the_first_modes_frequency(foam_robot_14, rigid, qs_rest):
    qs, rest = qs_rest
    modes = robot_modes(qs, rest.state, n=3)
    f1 = modes.frequencies_hz[0]
    assert modes.asymmetry < 1e-3
    T = 1.0 / f1
    h = T / 60
    traj = _free_vibration(foam_robot_14, rigid, rest, modes, GeneralizedAlpha(1.0), h, 130)
    k = int(np.argmax(np.abs(modes.effector[0][:3])))
    y = traj[:, k] - rest.state.p[k]
    # zero crossings of the rod's motion along the mode's largest translation: half periods
    s = np.sign(y)
    idx = np.flatnonzero(s[1:] != s[:-1])
    tc = [(i + y[i] / (y[i] - y[i + 1])) * h for i in idx]
    period = 2 * np.mean(np.diff(tc))
    assert period == pytest.approx(T, rel=0.01)  # generalised-alpha's period error at 60 steps a period: ~0.1 %


def test_rayleigh_damping_decays_the_first_mode_at_its_ratio(foam_robot_14, rigid, qs_rest):
    qs, rest = qs_rest
    modes = robot_modes(qs, rest.state, n=2)
    w = 2 * np.pi * modes.frequencies_hz[0]
    beta = 0.1 / w  # damping ratio 5 %
    h = 1.0 / modes.frequencies_hz[0] / 60
    traj = _free_vibration(foam_robot_14, rigid, rest, modes, GeneralizedAlpha(1.0), h, 130, beta=beta)
    k = int(np.argmax(np.abs(modes.effector[0][:3])))
    y = traj[:, k] - rest.state.p[k]
    peaks = [i for i in range(1, len(y) - 1) if y[i] > y[i - 1] and y[i] >= y[i + 1] and y[i] > 0]
    delta = np.log(y[peaks[0]] / y[peaks[1]])
    zeta = delta / np.sqrt(4 * np.pi**2 + delta**2)
    assert zeta == pytest.approx(0.05, rel=0.1)  # higher modes, damped faster, leave a few %


def test_a_slow_ramp_stays_on_the_quasi_static_path(foam_robot_14, rigid, qs_rest):
    qs, rest = qs_rest
    dyn = DynamicRobot(foam_robot_14, rigid, scheme=ImplicitEuler())
    a0 = rest.state.angles
    times = np.array([0.0, 0.5, 1.0])
    angles = np.array([a0, a0 + np.radians([4, 4, 4, 0, 0, 0]), a0 + np.radians([4, 4, 4, -3, 0, 0])])
    run, _ = play(dyn, dyn.start(rest.state), times, angles, 0.01)
    ref = quasi_static_path(qs, rest, times, angles, substeps=2)
    mm, deg = pose_gap(run, ref)
    moved = np.linalg.norm(ref.p[-1] - ref.p[0])
    assert moved > 0.5 and mm.max() < 0.02 * moved and deg.max() < 0.05
    assert np.allclose(run.angles[-1], angles[-1])
    assert np.allclose(program_at(times, angles, 0.25)[0], 0.5 * (angles[0] + angles[1]))


def test_step_metrics_of_a_known_signal():
    t = np.linspace(0, 1, 1001)
    w, z = 2 * np.pi * 5, 0.2
    wd = w * np.sqrt(1 - z * z)
    y = 1 - np.exp(-z * w * t) * (np.cos(wd * t) + z / np.sqrt(1 - z * z) * np.sin(wd * t))
    m = step_metrics(t, 2 + 3 * y, 2.0, 5.0)
    assert m.overshoot_pct == pytest.approx(100 * np.exp(-z * np.pi / np.sqrt(1 - z * z)), abs=0.1)
    assert m.final == 3.0 and 0.02 < m.rise_s < 0.08
    assert m.settling_s == pytest.approx(4 / (z * w), rel=0.25)
    with pytest.raises(ConfigError, match="zero"):
        step_metrics(t, y, 1.0, 1.0)


def test_bad_inputs_name_the_field(foam_robot_14, rigid, qs_rest):
    _, rest = qs_rest
    with pytest.raises(ConfigError, match="mass"):
        DynamicRobot(foam_robot_14, rigid, mass="diagonal")
    with pytest.raises(ConfigError, match="beta"):
        DynamicRobot(foam_robot_14, rigid, beta=-1)
    dyn = DynamicRobot(foam_robot_14, rigid)
    with pytest.raises(ConfigError, match="h"):
        dyn.step(dyn.start(rest.state), rest.state.angles, 0.0)
    with pytest.raises(ConfigError, match="program.times"):
        play(dyn, dyn.start(rest.state), [0.0, 0.0], np.zeros((2, 6)), 0.01)


def test_a_run_gives_the_same_bits_whatever_ran_before(foam_robot_14, rigid, qs_rest):
    _, rest = qs_rest
    dyn = DynamicRobot(foam_robot_14, rigid, scheme=GeneralizedAlpha(0.8))
    a0 = rest.state.angles
    times = np.array([0.0, 0.02, 0.1])
    first = np.array([a0, a0 + np.radians([3, 0, 0, 0, 0, 0]), a0 + np.radians([3, 0, 0, 0, 0, 0])])
    second = np.array([a0, a0 + np.radians([0, -2, 2, 0, 1, 0]), a0])
    start = dyn.start(rest.state)
    fresh, _ = play(dyn, start, times, second, 0.005)
    play(dyn, start, times, first, 0.005)  # another run on the same robot, leaving its chord and damping
    again, _ = play(dyn, start, times, second, 0.005)
    assert np.array_equal(fresh.p, again.p) and np.array_equal(fresh.torques, again.torques)
