"""The robot in time as work units (issue 64): its modes and step responses at rest, and the maze
study's motor program played with a marble on the maze (:mod:`metasheet.dynamics.maze_run`).

Each unit is picklable (a robot recipe, the settings, the program) and builds its robot once
per process (:func:`_robots`), so the foam and silicone runs and the faster playbacks spread
over the executor's workers.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..dynamics.marble import MarbleSettings
from ..dynamics.maze_geometry import MazeGeometry, maze_from_path
from ..dynamics.maze_run import maze_inertia, play_maze
from ..dynamics.modal import fastest_speed, modal_model, path_coordinates, rod_gap
from ..dynamics.response import step_response
from ..dynamics.robot import DynamicRobot
from ..dynamics.robot_modes import robot_modes
from ..dynamics.schemes import QuasiStatic, scheme
from ..errors import check_range
from ..robot.kinematics import DOF_NAMES, kinematics_at


@dataclass(frozen=True)
class DynamicsSettings:
    """scheme ("implicit_euler" | "generalized_alpha"), rho_inf [-], dt [s] the robot's step;
    alpha [1/s], beta [s] Rayleigh; marble; corridor, wall_height, plate_thickness, rod_radius
    [mm] the maze; n_modes; step_mm [mm], step_deg [deg], step_s [s], servo_speed [deg/s] the
    step responses; frame_s [s] the animation's frame period; fast_tol_mm [mm] the fastest
    playback's distance from the quasi-static path; speeds: the speed-ups the full model plays."""

    scheme: str = "generalized_alpha"
    rho_inf: float = 0.8
    dt: float = 0.005
    alpha: float = 0.0
    beta: float = 0.01
    marble: MarbleSettings = field(default_factory=lambda: MarbleSettings(radius=4.0, mass=2.1e-6))
    corridor: float = 12.0
    wall_height: float = 6.0
    plate_thickness: float = 3.0
    rod_radius: float = 3.0
    n_modes: int = 10
    step_mm: float = 1.0
    step_deg: float = 1.0
    step_s: float = 0.4
    servo_speed: float = 600.0
    frame_s: float = 0.2
    fast_tol_mm: float = 1.0
    speeds: tuple = ()

    def __post_init__(self):
        check_range("dt", self.dt, 0.0, 0.1, lo_open=True)
        check_range("corridor", self.corridor, 2 * self.marble.radius, None, lo_open=True)
        check_range("frame_s", self.frame_s, self.dt, None)

    @property
    def top(self) -> float:
        """The plate's top face above the rod's axis [mm]."""
        return self.rod_radius + self.plate_thickness


@dataclass(frozen=True)
class Unit:
    """One piece of work: ``kind`` "modes" or "maze"; ``spec`` the robot's recipe; ``path``
    the maze path ((u, v), ...) [mm]; ``times`` (T,) [s] and ``angles`` (T, na) [rad] the
    program ("maze"); ``speed`` its playback speed-up; ``frames`` whether to keep node
    positions for the animation."""

    kind: str
    spec: object
    settings: DynamicsSettings
    path: tuple
    times: tuple = ()
    angles: tuple = ()
    speed: float = 1.0
    frames: bool = False
    ends: tuple = ()
    main: bool = False


_CACHE: dict = {}


def _robots(unit: Unit):
    """(robot, dynamic robot, quasi-static robot, rest DynamicState, maze geometry) of ``unit``,
    built once per process and recipe."""
    key = (unit.spec.key, unit.settings, unit.path)
    if key not in _CACHE:
        s = unit.settings
        robot = unit.spec.build().robot
        path = np.asarray(unit.path, float)
        geo = maze_from_path(path - maze_offset(path), width=s.corridor, wall_height=s.wall_height, margin=2.0)
        rigid = maze_inertia(geo, rod_length=float(robot.info.get("rod_length_mm", 80.0)), rod_radius=s.rod_radius,
                             thickness=s.plate_thickness, origin=robot.coupling.origin)
        dyn = DynamicRobot(robot, rigid, alpha=s.alpha, beta=s.beta, scheme=scheme(s.scheme, s.rho_inf))
        qs = DynamicRobot(robot, rigid, scheme=QuasiStatic())
        rest = qs.step(qs.start(robot.rest_state()), robot.coupling.rest_angles, 1.0)
        _CACHE.clear()  # one robot per process at a time: they are big
        _CACHE[key] = (robot, dyn, qs, dyn.start(rest.state), geo)
    return _CACHE[key]


def maze_offset(path: np.ndarray) -> np.ndarray:
    """(2,) [mm] the centre of the path's bounding box: the maze is built around the rod (the
    path minus it), so that its plate stays between the sheets."""
    return 0.5 * (path.min(axis=0) + path.max(axis=0))


def run_unit(unit: Unit) -> dict:
    """The unit's result as a dict of arrays and numbers (see :func:`_modes`, :func:`_maze`)."""
    return _modes(unit) if unit.kind == "modes" else _maze(unit)


def _modes(unit: Unit) -> dict:
    robot, dyn, qs, rest, geo = _robots(unit)
    s = unit.settings
    m = robot_modes(qs, rest.state, n=s.n_modes)
    J = kinematics_at(robot, rest.state).J
    steps = []
    for dof in range(6 if unit.main else 0):
        size = s.step_mm if dof < 3 else np.radians(s.step_deg)
        r = step_response(dyn, qs, rest, J, dof, size, duration=s.step_s, h=min(s.dt, 0.002),
                          servo_speed=np.radians(s.servo_speed))
        y = r.run.pose[:, dof]
        steps.append({"dof": DOF_NAMES[dof], "size": size, "motors_deg": np.degrees(r.motors).tolist(),
                      "t": r.run.t, "y": y, "target": float(r.target[dof]), "cross": np.abs(r.run.pose - r.run.pose[0]),
                      "final": r.metrics.final, "rise_s": r.metrics.rise_s, "overshoot_pct": r.metrics.overshoot_pct,
                      "settling_s": r.metrics.settling_s, "band": r.metrics.band})
    return {"frequencies_hz": m.frequencies_hz, "shapes": m.shapes, "effector": m.effector, "asymmetry": m.asymmetry,
            "points": robot.body.rest, "tets": robot.body.tets, "rest_x": rest.state.x, "steps": steps,
            "sheets_g": float(robot.body.mass.sum() * 1e6), "maze_g": float(dyn.rigid.mass * 1e6),
            "rod_length": float(robot.info.get("rod_length_mm", 80.0))}


def _maze(unit: Unit) -> dict:
    robot, dyn, qs, rest, geo = _robots(unit)
    s = unit.settings
    times, angles = np.asarray(unit.times, float), np.asarray(unit.angles, float)
    every = max(1, int(round(s.frame_s / s.dt)))
    frames = [] if unit.frames else None
    quasi_x = [] if unit.main else None
    res = play_maze(dyn, qs, rest, times, angles, geo, h=s.dt, top=s.top, marble=s.marble, speed=unit.speed,
                    keep_x=frames, keep_every=every, ends=unit.ends or None, quasi_x=quasi_x)
    modal = None if quasi_x is None else _modal(unit, qs, rest, res.quasi, np.array(quasi_x))
    m = res.marble
    return {"speed": unit.speed, "t": res.run.t, "pose": res.run.pose, "angles": res.run.angles,
            "torques": res.run.torques, "newton": res.run.newton, "tangents": res.run.tangents,
            "quasi_t": res.quasi.t, "quasi_pose": res.quasi.pose, "quasi_unsolved": res.quasi.unsolved,
            "gap_mm": res.gap_mm, "gap_deg": res.gap_deg,
            "marble_t": m.t, "marble_u": m.u, "marble_world": m.world, "marble_progress": m.progress,
            "normal_force": m.normal_force, "contacts": [list(c) for c in m.contacts], "lifted_off": m.lifted_off,
            "vertices": res.vertices, "solved": res.solved,
            "arrivals": None if res.arrivals is None else res.arrivals.tolist(),
            "motor_speed_deg_s": float(np.degrees(np.abs(np.diff(angles, axis=0)) / np.diff(times)[:, None]).max()
                                       * unit.speed), "frames_x": None if frames is None else np.array(frames),
            "frames_every": every, "tets": robot.body.tets, "geometry": geo, "path_length": _length(geo),
            "path_in": unit.path,
            "modal": modal}


def _modal(unit: Unit, qs, rest, quasi, x_path: np.ndarray) -> dict | None:
    """The modal model (:mod:`metasheet.dynamics.modal`) on this program: its fastest playback
    within ``fast_tol_mm``, up to the speed-up at which the fastest motor reaches the servos'
    speed, and its gap at each speed the full model plays (the check)."""
    s = unit.settings
    if quasi.unsolved:
        return None
    modes = robot_modes(qs, rest.state, n=s.n_modes)
    model = modal_model(modes, s.alpha, s.beta)
    pts = np.array([qs.points(p, R) for p, R in zip(quasi.p, quasi.R)])
    m = path_coordinates(modes.shapes, modes.effector, qs.M, x_path, pts, qs.m_pts, rest.state.p)
    times = np.asarray(unit.times, float)
    t0 = time.perf_counter()
    angles = np.asarray(unit.angles, float)
    motor_speed = float(np.degrees(np.abs(np.diff(angles, axis=0)) / np.diff(times)[:, None]).max())  # [deg/s]
    servo_limit = s.servo_speed / motor_speed if motor_speed > 0 else 1024.0  # the servos' own limit
    fastest = fastest_speed(model, times, m, s.dt, s.fast_tol_mm, hi=max(1.0, servo_limit))
    per_run = (time.perf_counter() - t0) / max(1, len(fastest["evaluations"]))
    gaps = {str(v): rod_gap(model, times, m, s.dt, v) for v in (1.0, *s.speeds)}
    return {"fastest": fastest, "servo_limited_speed": servo_limit, "gaps_mm": gaps, "modes": len(model.omega),
            "seconds_per_playback": per_run}


def _length(geo: MazeGeometry) -> float:
    return float(np.linalg.norm(np.diff(geo.path, axis=0), axis=1).sum())

