"""The marble rolling on the moving maze plate (metasheet.dynamics.marble) against closed-form
answers: the incline's 5/7 g sin(theta) and m g cos(theta), rolling resistance, the turntable's
2/7 Omega circle, a plate accelerating at A, rotation invariance, an independent world-frame
Newton-Euler integration, wall impacts, resting contact, lift-off, validation, determinism."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metasheet.dynamics.marble import MarbleSettings, PlateMotion, plate_motion, roll
from metasheet.dynamics.maze_geometry import maze_from_path
from metasheet.errors import ConfigError

G = 9810.0  # [mm/s^2]
M = 2.14e-6  # [t]
R_BALL = 8.0  # [mm]
FREE = MarbleSettings(c_rr=0.0)


def tilted(theta, spin=0.0):
    """Plate turned by ``theta`` [rad] about x (downhill along -v), then ``spin`` about world z."""
    return Rotation.from_rotvec([0, 0, spin]).as_matrix() @ Rotation.from_rotvec([theta, 0, 0]).as_matrix()


@pytest.mark.parametrize("theta", [0.05, 0.3])
def test_incline_rolls_at_five_sevenths_g_sin(theta):
    run = roll(PlateMotion.still(tilted(theta), top=1.5, duration=0.5), None, (3.0, 4.0), FREE)
    a = 5 / 7 * G * np.sin(theta)
    t = run.t - run.t[0]
    np.testing.assert_allclose(run.v_rel[:, 1], -a * t, rtol=0, atol=1e-9 * a)
    np.testing.assert_allclose(run.u[:, 1], 4.0 - a * t**2 / 2, rtol=0, atol=1e-9 * a)  # RK4: exact for constant a
    np.testing.assert_allclose(run.u[:, 0], 3.0, atol=1e-12)
    np.testing.assert_allclose(run.normal_force, M * G * np.cos(theta), rtol=1e-12)
    assert not run.lifted_off and run.contacts == ()


def test_rolling_resistance_takes_five_sevenths_c_rr_g_cos():
    theta, c = 0.2, 0.01
    run = roll(PlateMotion.still(tilted(theta), duration=0.5), None, (0.0, 0.0), MarbleSettings(c_rr=c))
    a = 5 / 7 * G * (np.sin(theta) - c * np.cos(theta))
    np.testing.assert_allclose(run.v_rel[:, 1], -a * run.t, rtol=0, atol=1e-9 * a)
    np.testing.assert_allclose(run.u[:, 1], -a * run.t**2 / 2, rtol=0, atol=1e-9 * a)
    # below tan(theta) = c_rr the ball stays put, exactly
    held = roll(PlateMotion.still(tilted(0.5 * c), duration=0.5), None, (1.0, 2.0), MarbleSettings(c_rr=c))
    np.testing.assert_allclose(held.u, [[1.0, 2.0]] * len(held.u), rtol=0, atol=1e-12)


def test_turntable_circle_at_two_sevenths_omega():
    """Horizontal plate spinning at Omega about the vertical through its origin, the ball released
    at rest relative to it at s0: in the inertial frame c'' = 2/7 Omega e3 x c', a circle at rate
    2/7 Omega through s0 with velocity Omega e3 x s0, so centre -5/2 s0 and radius 7/2 |s0|."""
    om = 2 * np.pi  # [rad/s]
    T = np.linspace(0.0, 10.5, 211)  # three periods of the ball (3.5 s)
    R = Rotation.from_rotvec(np.outer(om * T, [0, 0, 1])).as_matrix()
    run = roll(PlateMotion(T, np.zeros((len(T), 3)), R, top=0.0), None, (4.0, 0.0), FREE)
    s0 = np.array([4.0, 0.0])
    phi = 2 / 7 * om * run.t
    centre = -2.5 * s0
    rot = np.stack([np.cos(phi), -np.sin(phi), np.sin(phi), np.cos(phi)], axis=1).reshape(-1, 2, 2)
    expected = centre + np.einsum("kij,j->ki", rot, s0 - centre)
    np.testing.assert_allclose(run.world[:, :2], expected, rtol=0, atol=1e-7)
    np.testing.assert_allclose(run.world[:, 2], R_BALL, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(run.world[:, :2] - centre, axis=1), 3.5 * 4.0, atol=1e-7)


def test_plate_accelerating_leaves_the_ball_behind_at_five_sevenths():
    A = np.array([300.0, -150.0, 0.0])  # [mm/s^2] horizontal
    T = np.linspace(0.0, 0.5, 11)
    run = roll(PlateMotion(T, 0.5 * np.outer(T**2, A), np.tile(np.eye(3), (len(T), 1, 1))), None, (0.0, 0.0), FREE)
    np.testing.assert_allclose(run.v_rel, -5 / 7 * np.outer(run.t, A[:2]), rtol=0, atol=1e-9)


def _swaying(beta=0.0):
    """A plate tilting, turning and moving; the whole set-up turned by ``beta`` about the vertical."""
    T = np.linspace(0.0, 0.4, 21)
    rv = np.c_[0.15 * np.sin(6 * T), 0.1 * np.sin(4 * T + 0.3), 0.8 * T + 0.5 * T**2]
    p = np.c_[10 * np.sin(5 * T), 20 * T**2, 3 * np.cos(7 * T)]
    turn = Rotation.from_rotvec([0, 0, beta])
    R = (turn * Rotation.from_rotvec(rv)).as_matrix()
    return PlateMotion(T, turn.apply(p), R, top=1.5), turn


def test_turning_the_whole_set_up_about_the_vertical_changes_nothing_relative():
    a, _ = _swaying()
    b, turn = _swaying(0.7)
    ra, rb = roll(a, None, (5.0, -3.0), FREE), roll(b, None, (5.0, -3.0), FREE)
    np.testing.assert_allclose(rb.u, ra.u, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rb.v_rel, ra.v_rel, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rb.world, turn.apply(ra.world), rtol=0, atol=1e-9)


def test_agrees_with_world_frame_newton_euler():
    """An independent integration: world-frame centre and spin, the contact force solved at every
    stage from the differentiated rolling constraint, F/m + r^2/I (F - (F.n) n) = kinematic terms."""
    motion, _ = _swaying()
    run = roll(motion, None, (5.0, -3.0), FREE)
    dt, K, r, I = FREE.dt, len(run.t) - 1, R_BALL, 0.4 * M * R_BALL**2
    tt = motion.times[0] + 0.5 * dt * np.arange(2 * K + 1)
    p, R = motion.pose(tt)
    kin = list(zip(p, R[:, :, 2], motion.omega(tt), motion.alpha(tt), motion.velocity(tt), motion.acceleration(tt)))
    g = np.array([0.0, 0.0, -G])

    def f(i, c, cd, om):
        p, n, w, a, pd, pdd = kin[i]
        rhs = (r * np.cross(om, np.cross(w, n)) + pdd + np.cross(a, c - r * n - p)
               + np.cross(w, cd - r * np.cross(w, n) - pd)) - g
        F = np.linalg.solve(np.eye(3) / M + r * r / I * (np.eye(3) - np.outer(n, n)), rhs)
        return cd, g + F / M, -r / I * np.cross(n, F)

    c = run.world[0]
    cd = kin[0][4] + np.cross(kin[0][2], c - kin[0][0])
    om, out = kin[0][2].copy(), [c]
    for k in range(K):
        y = (c, cd, om)
        k1 = f(2 * k, *y)
        k2 = f(2 * k + 1, *(a + dt / 2 * b for a, b in zip(y, k1)))
        k3 = f(2 * k + 1, *(a + dt / 2 * b for a, b in zip(y, k2)))
        k4 = f(2 * k + 2, *(a + dt * b for a, b in zip(y, k3)))
        c, cd, om = (a + dt / 6 * (b1 + 2 * b2 + 2 * b3 + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4))
        out.append(c)
    assert np.ptp(run.world, axis=0).max() > 20.0  # it did roll
    np.testing.assert_allclose(run.world, np.array(out), rtol=0, atol=1e-8)


@pytest.fixture(scope="module")
def lane():
    """A straight corridor 40 mm wide: walls at v = +-20, end caps at u = -20 and u = 120."""
    return maze_from_path([(0.0, 0.0), (100.0, 0.0)], width=40.0)


@pytest.mark.parametrize("v0", [(200.0, 0.0), (200.0, 20.0)])
def test_impact_reverses_the_normal_velocity_times_e(lane, v0):
    run = roll(PlateMotion.still(duration=0.5), lane, (50.0, 0.0), FREE, v0=v0)
    assert len(run.contacts) == 1
    t_hit, wall, vn = run.contacts[0]
    assert vn == pytest.approx(200.0, rel=1e-12)
    assert np.allclose(lane.walls[wall, :, 0], 120.0)  # the end cap
    assert t_hit == pytest.approx(0.31, abs=2 * FREE.dt)  # the centre reaches u = 112
    after = run.t >= t_hit
    np.testing.assert_allclose(run.v_rel[after], [[-0.5 * 200.0, v0[1]]] * after.sum(), rtol=0, atol=1e-9)
    assert run.u[:, 0].max() <= 112.0 + 1e-12


def test_ball_resting_against_a_wall_stays_put(lane):
    run = roll(PlateMotion.still(tilted(0.3), duration=1.0), lane, (50.0, -12.0), MarbleSettings())
    np.testing.assert_allclose(run.u, [[50.0, -12.0]] * len(run.u), rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.abs(run.v_rel).max(), 0.0, atol=1e-12)
    assert run.contacts == ()
    # released 2 mm above the wall it bounces a few times lower and lower (each flight up and
    # down the same incline returns e times the speed), then settles without jitter
    drop = roll(PlateMotion.still(tilted(0.3), duration=1.0), lane, (50.0, -10.0), MarbleSettings())
    speeds = np.array([c[2] for c in drop.contacts])
    assert len(speeds) >= 2 and all(c[1] == drop.contacts[0][1] for c in drop.contacts)
    np.testing.assert_allclose(speeds[1:] / speeds[:-1], 0.5, atol=0.03)
    assert drop.contacts[-1][0] < 0.5
    late = drop.t > 0.5
    np.testing.assert_allclose(drop.u[late], [[50.0, -12.0]] * late.sum(), rtol=0, atol=1e-6)


def test_lift_off_when_the_plate_falls_faster_than_g():
    T = np.linspace(0.0, 0.3, 31)
    A = 9810.0  # p_z = -A t^3: the plate's downward acceleration 6 A t passes g at t = 1/6 s
    motion = PlateMotion(T, np.c_[0 * T, 0 * T, -A * T**3], np.tile(np.eye(3), (len(T), 1, 1)))
    run = roll(motion, None, (0.0, 0.0), FREE)
    assert run.lifted_off and run.normal_force[-1] <= 0 < run.normal_force[-2]
    assert run.t[-1] == pytest.approx(1 / 6, abs=FREE.dt)
    assert not roll(PlateMotion.still(duration=0.3), None, (0.0, 0.0), FREE).lifted_off


def test_same_inputs_same_bytes(lane):
    motion, _ = _swaying()
    a, b = roll(motion, lane, (50.0, 5.0)), roll(motion, lane, (50.0, 5.0))
    for name in ("t", "u", "v_rel", "world", "normal_force", "progress"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes()
    assert a.contacts == b.contacts


def test_motion_helpers():
    theta, om = 0.2, 3.0
    T = np.linspace(0.0, 1.0, 21)
    R = np.array([tilted(theta, om * t) for t in T])
    motion = PlateMotion(T, np.zeros((len(T), 3)), R, top=1.5)
    np.testing.assert_allclose(motion.omega(0.37), [0, 0, om], atol=1e-9)
    # a point at the top face 10 mm along the plate's x: centripetal acceleration om^2 * 10 inwards
    acc = motion.point_acceleration(0.5, (10.0, 0.0, 0.0))
    np.testing.assert_allclose(acc, -om**2 * motion.pose(0.5)[1] @ [10.0, 0.0, 0.0], atol=1e-6)
    poses = np.c_[np.zeros((len(T), 3)), np.outer(T, [0.1, 0, 0])]
    pm = plate_motion(T, poses, centre=(0.0, 0.0, 5.0))
    np.testing.assert_allclose(pm.pose(1.0)[0], [0.0, -5 * np.sin(0.1), 5 * np.cos(0.1)], atol=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda L: roll(PlateMotion.still(), L, (500.0, 0.0)), r"start: \[500.0, 0.0\]: should lie on the plate"),
    (lambda L: roll(PlateMotion.still(), L, (50.0, 19.0)), "start: .* overlaps wall"),
    (lambda L: roll(PlateMotion.still(), L, (50.0, 0.0), MarbleSettings(radius=20.0)),
     r"settings.radius: 20.0: allowed range is \(0, 20\)"),
    (lambda L: roll(PlateMotion.still(), None, (0.0,)), r"start: shape is \(1,\)"),
    (lambda L: roll(PlateMotion.still(duration=1.0), None, (0.0, 0.0), t_end=2.0), r"t_end: 2.0: allowed range"),
    (lambda L: PlateMotion([0.0, 1.0, 1.0], np.zeros((3, 3)), np.tile(np.eye(3), (3, 1, 1))),
     "motion.times: .* strictly increasing"),
    (lambda L: PlateMotion([0.0, 1.0], np.zeros((2, 2)), np.tile(np.eye(3), (2, 1, 1))),
     r"motion.p: shape is \(2, 2\)"),
    (lambda L: PlateMotion([0.0, 1.0], np.zeros((2, 3)), np.tile(2 * np.eye(3), (2, 1, 1))), "motion.R: not rotations"),
    (lambda L: MarbleSettings(restitution=1.5), r"restitution: 1.5: allowed range is \[0, 1\]"),
    (lambda L: MarbleSettings(mass=0.0), r"mass: 0.0: allowed range is \(0, inf\]"),
    (lambda L: MarbleSettings(g=(0.0, -9810.0)), "g: .* finite 3-vector"),
])
def test_validation(lane, call, match):
    with pytest.raises(ConfigError, match=match):
        call(lane)
