"""A solid sphere rolling without slipping on the top face of a moving plate, between walls.

The ball: radius r [mm], mass m [t], I = 2/5 m r^2. The plate: sampled poses (plate frame ->
world), positions by cubic splines and rotations by scipy's ``RotationSpline`` (whose angular
rate and acceleration are plate-frame components). Everything below is in plate components:
n = e3 the top face's normal, x = (u, top + r) the centre, W = (u', 0) its velocity relative
to the plate, omega and alpha the plate's angular velocity and acceleration, p'' its origin's
acceleration, g gravity, sigma the ball's spin about n (world angular velocity . n).

Derivation (Newton-Euler with the rolling constraint). Contact force F at q = c - r n:
m c'' = m g + F, I Omega' = -r n x F. Rolling: the contact point moves with the plate,
c' - r Omega x n = v_plate(q), which fixes Omega's tangential part from W (Omega - omega)_t =
n x W / r, leaves sigma free, and differentiated with the two balance laws gives
F_t = 2/7 m (A - g)_t (A the constraint's kinematic terms) and N = F . n. Back in the plate
frame, with the apparent gravity at the centre a_app = g - p'' - alpha x x - omega x (omega x x)::

    u''      = 5/7 a_app,t - 12/7 (omega x W)_t - 2/7 r (alpha x n)_t + 2/7 r (sigma - omega_3) omega_t
    N / m    = 2 (omega x W)_3 - a_app,3
    sigma'   = -(omega_t . u') / r          (the contact torque has no normal part)

(fixed incline: 5/7 g sin(theta); turntable: the centre circles at 2/7 Omega in the inertial
frame; plate accelerating at A: u'' = -5/7 A). The ball starts with no spin relative to the
plate about n (sigma = omega_3).

Rolling resistance: a torque c_rr r N about the centre against the relative rolling, the same
moment about the contact point as a force c_rr N at the centre against u': for a rolling ball
it takes 5/7 c_rr N / m off |u''| (incline: 5/7 g (sin(theta) - c_rr cos(theta))), and holds
the ball at rest while the rest of u'' is below that (the step clamps u' at zero, no chatter).

Walls (:class:`.maze_geometry.MazeGeometry`, segments in the plate's xy) are tall faces: the
centre closer than r to a segment is a contact, with the normal from the closest point. The
impact law: the relative normal velocity is reversed times the restitution e, the tangential
kept, spin about n kept, rolling re-imposed (spin about the tangential axes follows u'); the
centre is put back at distance r. An approach slower than 2 |g| dt (what one step of forces
adds) is a resting contact: the inward velocity is removed without bounce, so a ball pressed
into a wall neither jitters nor tunnels. Only impacts are reported. (A wall lower than r
touches the ball at its top edge with a tilted normal; neglected.)

Time stepping: fixed dt, classical RK4 for the smooth motion, then rolling resistance and
walls at the end of each step (first order in them, exact for constant forces). Lift-off: the
run stops at the first sample with N <= 0 (``lifted_off``; free flight is not modelled).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, check_range
from .maze_geometry import MazeGeometry, centerline_progress, plate_bounds, segment_distances


@dataclass(frozen=True)
class MarbleSettings:
    """radius [mm]; mass [t]; c_rr [-] rolling resistance; restitution [-] at the walls; dt [s];
    g (3,) [mm/s^2] gravity in world axes. The defaults: a 16 mm steel ball."""

    radius: float = 8.0
    mass: float = 2.14e-6
    c_rr: float = 0.002
    restitution: float = 0.5
    dt: float = 1e-3
    g: tuple = (0.0, 0.0, -9810.0)

    def __post_init__(self):
        check_range("radius", self.radius, 0.0, None, lo_open=True)
        check_range("mass", self.mass, 0.0, None, lo_open=True)
        check_range("c_rr", self.c_rr, 0.0, 1.0)
        check_range("restitution", self.restitution, 0.0, 1.0)
        check_range("dt", self.dt, 0.0, 0.1, lo_open=True)
        g = np.asarray(self.g, float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"g: {self.g!r}: should be a finite 3-vector [mm/s^2]")


@dataclass(frozen=True, eq=False)
class PlateMotion:
    """times (T,) [s] increasing, T >= 2; p (T, 3) [mm] the plate frame's origin; R (T, 3, 3)
    plate frame -> world; top [mm] the top face's z in plate coordinates."""

    times: np.ndarray
    p: np.ndarray
    R: np.ndarray
    top: float = 0.0
    _pos: object = field(init=False, repr=False)
    _rot: object = field(init=False, repr=False)

    def __post_init__(self):
        from scipy.interpolate import CubicSpline
        from scipy.spatial.transform import Rotation, RotationSpline

        t = np.array(self.times, float)
        if t.ndim != 1 or len(t) < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ConfigError(f"motion.times: shape {t.shape}: should be (T,) with T >= 2, finite, "
                              "strictly increasing [s]")
        p = np.array(self.p, float)
        R = np.array(self.R, float)
        if p.shape != (len(t), 3) or not np.all(np.isfinite(p)):
            raise ConfigError(f"motion.p: shape is {p.shape} and should be ({len(t)}, 3), finite [mm]")
        if R.shape != (len(t), 3, 3) or not np.all(np.isfinite(R)):
            raise ConfigError(f"motion.R: shape is {R.shape} and should be ({len(t)}, 3, 3)")
        err = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max()
        if err > 1e-6 or np.any(np.linalg.det(R) <= 0):
            raise ConfigError(f"motion.R: not rotations (|R R^T - I| = {err:.2g}, allowed <= 1e-6, det > 0)")
        check_range("motion.top", self.top)
        for name, value in (("times", t), ("p", p), ("R", R)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_pos", CubicSpline(t, p, axis=0))
        object.__setattr__(self, "_rot", RotationSpline(t, Rotation.from_matrix(R)))

    @classmethod
    def still(cls, R=np.eye(3), p=(0.0, 0.0, 0.0), top: float = 0.0, duration: float = 1.0) -> PlateMotion:
        """A plate held at rotation ``R`` (3, 3) and origin ``p`` (3,) [mm] from 0 to ``duration`` [s]."""
        check_range("duration", duration, 0.0, None, lo_open=True)
        return cls(np.array([0.0, duration]), np.tile(np.asarray(p, float), (2, 1)),
                   np.tile(np.asarray(R, float), (2, 1, 1)), top)

    def _clip(self, t):  # RotationSpline does not extrapolate
        return np.clip(np.asarray(t, float), self.times[0], self.times[-1])

    def pose(self, t):
        """(p (..., 3) [mm], R (..., 3, 3)) at ``t`` [s] (scalar or (k,))."""
        t = self._clip(t)
        return self._pos(t), self._rot(t).as_matrix()

    def velocity(self, t):
        """(..., 3) [mm/s] the origin's velocity, world axes."""
        return self._pos(self._clip(t), 1)

    def acceleration(self, t):
        """(..., 3) [mm/s^2] the origin's acceleration, world axes."""
        return self._pos(self._clip(t), 2)

    def omega_plate(self, t):
        """(..., 3) [rad/s] angular velocity, plate axes."""
        return self._rot(self._clip(t), 1)

    def alpha_plate(self, t):
        """(..., 3) [rad/s^2] angular acceleration, plate axes."""
        return self._rot(self._clip(t), 2)

    def omega(self, t):
        """(..., 3) [rad/s] angular velocity, world axes."""
        return np.einsum("...ij,...j->...i", self.pose(t)[1], self.omega_plate(t))

    def alpha(self, t):
        """(..., 3) [rad/s^2] angular acceleration, world axes (d omega/dt)."""
        return np.einsum("...ij,...j->...i", self.pose(t)[1], self.alpha_plate(t))

    def point_acceleration(self, t, x):
        """(3,) [mm/s^2] world acceleration of the plate point at plate coordinates ``x`` (3,) [mm]."""
        p, R = self.pose(t)
        s = R @ np.asarray(x, float)
        w, a = self.omega(t), self.alpha(t)
        return self.acceleration(t) + np.cross(a, s) + np.cross(w, np.cross(w, s))


def plate_motion(times, poses, *, centre=(0.0, 0.0, 0.0), top: float = 0.0) -> PlateMotion:
    """The :class:`PlateMotion` of effector ``poses`` (T, 6) [mm, rad] (position, rotation vector
    from the rest orientation, where the plate's axes are the world's), the plate frame's origin
    at ``centre`` (3,) [mm] from the effector's reference point, in plate axes."""
    from scipy.spatial.transform import Rotation

    P = np.asarray(poses, float)
    if P.ndim != 2 or P.shape[1] != 6:
        raise ConfigError(f"poses: shape is {P.shape} and should be (T, 6) [mm, rad]")
    R = Rotation.from_rotvec(P[:, 3:]).as_matrix()
    return PlateMotion(times, P[:, :3] + R @ np.asarray(centre, float), R, top)


@dataclass(frozen=True)
class MarbleRun:
    """t (K,) [s]; u (K, 2) [mm] the centre in plate coordinates; v_rel (K, 2) [mm/s] its
    velocity relative to the plate; world (K, 3) [mm] the centre; normal_force (K,) [N];
    contacts: ((t [s], wall index, normal speed before [mm/s]), ...) the impacts; lifted_off:
    the run stopped at its last sample, where N <= 0; progress (K,) [mm] along the maze path
    (:func:`.maze_geometry.centerline_progress`, tracked) or None without a maze."""

    t: np.ndarray
    u: np.ndarray
    v_rel: np.ndarray
    world: np.ndarray
    normal_force: np.ndarray
    contacts: tuple
    lifted_off: bool
    progress: np.ndarray | None


def _kinematics(motion: PlateMotion, tt: np.ndarray, g: np.ndarray) -> list:
    """Per time of ``tt``: (omega (3), alpha (3), R^T (g - p'') (3)) in plate axes, as floats."""
    p, R = motion.pose(tt)
    gp = np.einsum("kji,kj->ki", R, g[None, :] - motion.acceleration(tt))
    return np.concatenate([motion.omega_plate(tt), motion.alpha_plate(tt), gp], axis=1).tolist()


def _rhs(u1, u2, w1, w2, sig, k, r, h):
    """(u1', u2', w1', w2', sigma'), N/m: the module doc's equations, plain floats (the hot loop)."""
    o1, o2, o3, a1, a2, a3, g1, g2, g3 = k
    wx1, wx2, wx3 = o2 * h - o3 * u2, o3 * u1 - o1 * h, o1 * u2 - o2 * u1  # omega x x
    app1 = g1 - (a2 * h - a3 * u2) - (o2 * wx3 - o3 * wx2)  # apparent gravity at the centre
    app2 = g2 - (a3 * u1 - a1 * h) - (o3 * wx1 - o1 * wx3)
    app3 = g3 - (a1 * u2 - a2 * u1) - (o1 * wx2 - o2 * wx1)
    c1, c2, c3 = -o3 * w2, o3 * w1, o1 * w2 - o2 * w1  # omega x W
    spin = 2.0 / 7.0 * r * (sig - o3)
    f1 = 5.0 / 7.0 * app1 - 12.0 / 7.0 * c1 - 2.0 / 7.0 * r * a2 + spin * o1
    f2 = 5.0 / 7.0 * app2 - 12.0 / 7.0 * c2 + 2.0 / 7.0 * r * a1 + spin * o2
    return (w1, w2, f1, f2, -(o1 * w1 + o2 * w2) / r), 2.0 * c3 - app3


def _check_start(geometry, start, r):
    if geometry is None:
        return
    if r >= geometry.width / 2:
        raise ConfigError(f"settings.radius: {r!r}: allowed range is (0, {geometry.width / 2:g}) "
                          "(below the corridor's half-width)")
    lo, hi = plate_bounds(geometry)
    if np.any(start < lo) or np.any(start > hi):
        raise ConfigError(f"start: {start.tolist()}: should lie on the plate, u in [{lo[0]:g}, {hi[0]:g}], "
                          f"v in [{lo[1]:g}, {hi[1]:g}] [mm]")
    if len(geometry.walls):
        d = segment_distances(start[None], geometry.walls)[0][0]
        i = int(np.argmin(d))
        if d[i] < r * (1 - 1e-9):
            raise ConfigError(f"start: {start.tolist()}: the ball overlaps wall {i} (centre {d[i]:.3g} mm "
                              f"from it); allowed: at least the radius {r:g} mm")


def roll(motion: PlateMotion, geometry: MazeGeometry | None, start, settings: MarbleSettings = MarbleSettings(),
         t_end: float | None = None, v0=(0.0, 0.0)) -> MarbleRun:
    """The ball released at ``start`` (2,) [mm] (plate coordinates, u v of the maze) with
    relative velocity ``v0`` (2,) [mm/s] at ``motion.times[0]``, rolled to ``t_end`` [s]
    (default the last time) in steps of ``settings.dt``, between ``geometry``'s walls if given."""
    s = settings
    start = np.asarray(start, float)
    v0 = np.asarray(v0, float)
    for name, value in (("start", start), ("v0", v0)):
        if value.shape != (2,) or not np.all(np.isfinite(value)):
            raise ConfigError(f"{name}: shape is {value.shape} and should be (2,), finite")
    t0, t1 = float(motion.times[0]), float(motion.times[-1])
    t_end = t1 if t_end is None else float(check_range("t_end", t_end, t0 + s.dt, t1))
    _check_start(geometry, start, s.radius)
    K = int(np.floor((t_end - t0) / s.dt + 1e-9))
    if K < 1:
        raise ConfigError(f"settings.dt: {s.dt!r}: allowed range is (0, {t_end - t0:g}] (the motion's span)")
    r, dt, e = float(s.radius), float(s.dt), float(s.restitution)
    h = motion.top + r
    kin = _kinematics(motion, t0 + 0.5 * dt * np.arange(2 * K + 1), np.asarray(s.g, float))
    v_rest = 2.0 * float(np.linalg.norm(s.g)) * dt
    walls = geometry.walls if geometry is not None else np.zeros((0, 2, 2))
    u1, u2, w1, w2 = float(start[0]), float(start[1]), float(v0[0]), float(v0[1])
    sig = kin[0][2]  # no spin relative to the plate about n
    f, n_m = _rhs(u1, u2, w1, w2, sig, kin[0], r, h)
    rec, contacts, lifted = [(u1, u2, w1, w2, n_m)], [], n_m <= 0
    for n in range(K if not lifted else 0):
        y = (u1, u2, w1, w2, sig)
        k1 = f
        k2, _ = _rhs(*(yi + 0.5 * dt * ki for yi, ki in zip(y, k1)), kin[2 * n + 1], r, h)
        k3, _ = _rhs(*(yi + 0.5 * dt * ki for yi, ki in zip(y, k2)), kin[2 * n + 1], r, h)
        k4, _ = _rhs(*(yi + dt * ki for yi, ki in zip(y, k3)), kin[2 * n + 2], r, h)
        u1, u2, w1, w2, sig = (yi + dt / 6.0 * (a + 2.0 * b + 2.0 * c + d) for yi, a, b, c, d in zip(y, k1, k2, k3, k4))
        b = 5.0 / 7.0 * s.c_rr * max(n_m, 0.0) * dt  # rolling resistance's speed loss this step
        if b > 0.0:
            speed = np.hypot(w1, w2)
            dv1, dv2 = (-w1, -w2) if speed <= b else (-b * w1 / speed, -b * w2 / speed)
            w1, w2 = w1 + dv1, w2 + dv2
            u1, u2 = u1 + 0.5 * dt * dv1, u2 + 0.5 * dt * dv2  # a constant deceleration over the step
        if np.hypot(u1 - y[0], u2 - y[1]) > 0.5 * r:  # contacts are found while penetration < r
            raise ConfigError(f"settings.dt: {dt!r}: the ball moved more than half its radius in one step "
                              f"at t = {t0 + (n + 1) * dt:g} s; use a smaller dt")
        if len(walls):
            u1, u2, w1, w2 = _walls(u1, u2, w1, w2, walls, r, e, v_rest, t0 + (n + 1) * dt, contacts)
        f, n_m = _rhs(u1, u2, w1, w2, sig, kin[2 * n + 2], r, h)
        rec.append((u1, u2, w1, w2, n_m))
        if n_m <= 0:
            lifted = True
            break
    out = np.array(rec)
    t = t0 + dt * np.arange(len(out))
    p, R = motion.pose(t)
    x = np.column_stack([out[:, :2], np.full(len(out), h)])
    world = p + np.einsum("kij,kj->ki", R, x)
    progress = centerline_progress(geometry, out[:, :2], track=True) if geometry is not None else None
    return MarbleRun(t, out[:, :2], out[:, 2:4], world, s.mass * out[:, 4], tuple(contacts), bool(lifted), progress)


def _walls(u1, u2, w1, w2, walls, r, e, v_rest, t, contacts):
    """The centre out of the walls it entered, deepest first (a few passes for corners), and the
    impact law (module doc); impacts appended to ``contacts``."""
    for _ in range(4):
        dist, par = segment_distances(np.array([[u1, u2]]), walls)
        i = int(np.argmin(dist[0]))
        d = float(dist[0, i])
        if d >= r:
            break
        q = walls[i, 0] + par[0, i] * (walls[i, 1] - walls[i, 0])
        n1, n2 = (u1 - q[0]) / d, (u2 - q[1]) / d  # d > r/2: the step guard keeps the centre off the wall
        u1, u2 = q[0] + r * n1, q[1] + r * n2
        vn = -(w1 * n1 + w2 * n2)  # approach speed
        if vn > v_rest:
            w1, w2 = w1 + (1.0 + e) * vn * n1, w2 + (1.0 + e) * vn * n2
            contacts.append((float(t), i, float(vn)))
        elif vn > 0.0:
            w1, w2 = w1 + vn * n1, w2 + vn * n2
    return float(u1), float(u2), w1, w2
