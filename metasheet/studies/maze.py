"""Maze: a polyline path in the maze plane -> tilt commands -> motor angles -> replay.

The maze is fixed at the effector, its plane spanned by the world axes ``plane_axes`` at
rest (default: the rod axis x and y, normal z up; gravity is -z). A marble rolls along a
segment of unit direction ``d`` (in the plane) when the maze tilts so that ``d`` goes
downhill: the rotation vector ``tilt (n x d)`` with ``n`` the plane normal
(``exp([n x d] t) d = d cos t - n sin t``). A segment across the rod needs a rotation about
the rod itself, the sixth DOF that only anisotropic sheets provide.

Each segment is one work unit: the maze ramps from the previous tilt to the segment's
(``ramp_s``), holds it while the marble rolls (length / ``speed``), and the last segment
ramps back to level. The unit reaches its first command from rest, then every sample by
continuation (open loop, the inverse model alone), and replays the motor angles through the
forward model to measure the tracking error (a held sample's replay is the equilibrium it
holds: solved again at the same motors from itself, it would not move). While the command
holds, the motors hold: a sample whose command is the previous one's keeps its motor angles
(on an impossible segment the inverse loop would otherwise spend its ``max_steps`` again on
every held sample, and the motors would wander about the unreachable goal). A segment is impossible when a held sample
misses its pose by more than ``tol_mm`` or ``tol_deg``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from ..runtime.executor import Executor
from .model import MODELS, ModelSpec, pose_errors
from .resume import UnitCache


@dataclass(frozen=True)
class MazeSettings:
    """tilt_deg [deg]; speed [mm/s] of the marble; dt, ramp_s [s]; tolerances [mm], [deg]."""

    tilt_deg: float = 8.0
    speed: float = 20.0
    dt: float = 0.1
    ramp_s: float = 0.5
    tol_mm: float = 1.0
    tol_deg: float = 1.0
    max_steps: int = 60

    def __post_init__(self):
        check_range("tilt_deg", self.tilt_deg, 0.0, 45.0, lo_open=True)
        check_range("speed", self.speed, 0.0, None, lo_open=True)
        check_range("dt", self.dt, 0.0, None, lo_open=True)
        check_range("ramp_s", self.ramp_s, 0.0, None)
        check_range("tol_mm", self.tol_mm, 0.0, None, lo_open=True)
        check_range("tol_deg", self.tol_deg, 0.0, None, lo_open=True)


@dataclass(frozen=True)
class MazeCommands:
    """time : (T,) [s]; poses : (T, 6) [mm, rad]; segment : (T,) int; hold : (T,) bool, True
    while the segment's tilt is held (False on ramps); directions : (s, 3) unit."""

    time: np.ndarray
    poses: np.ndarray
    segment: np.ndarray
    hold: np.ndarray
    directions: np.ndarray


def maze_commands(path, rest_pose, settings: MazeSettings = MazeSettings(), *,
                  plane_axes=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))) -> MazeCommands:
    """Tilt commands for ``path`` (m, 2) [mm], a polyline in maze coordinates (see module doc)."""
    P = np.asarray(path, float)
    if P.ndim != 2 or P.shape[1] != 2 or len(P) < 2:
        raise ConfigError(f"path: shape is {P.shape} and should be (m, 2) with m >= 2")
    E = np.asarray(plane_axes, float)
    if E.shape != (2, 3) or abs(E[0] @ E[1]) > 1e-9 or not np.allclose(np.linalg.norm(E, axis=1), 1):
        raise ConfigError("plane_axes: expected two orthonormal 3-vectors")
    n = np.cross(E[0], E[1])
    seg = np.diff(P, axis=0)
    length = np.linalg.norm(seg, axis=1)
    if np.any(length <= 0):
        raise ConfigError(f"path: segment {int(np.argmin(length))} has zero length")
    d = (seg / length[:, None]) @ E  # (s, 3) world directions
    tilts = np.radians(settings.tilt_deg) * np.cross(n, d)  # (s, 3) rotation vectors
    rest = np.asarray(rest_pose, float)
    t_list, r_list, s_list, h_list = [], [], [], []
    t_now, prev = 0.0, np.zeros(3)
    for i, (w, L) in enumerate(zip(tilts, length)):
        n_ramp = int(np.ceil(settings.ramp_s / settings.dt))
        n_hold = max(1, int(np.ceil(L / settings.speed / settings.dt)))
        for k in range(1, n_ramp + 1):
            t_list.append(t_now + k * settings.dt)
            r_list.append(prev + k / n_ramp * (w - prev))
            s_list.append(i)
            h_list.append(False)
        t_now += n_ramp * settings.dt
        for k in range(1, n_hold + 1):
            t_list.append(t_now + k * settings.dt)
            r_list.append(w)
            s_list.append(i)
            h_list.append(True)
        t_now += n_hold * settings.dt
        prev = w
    n_ramp = max(1, int(np.ceil(settings.ramp_s / settings.dt)))
    for k in range(1, n_ramp + 1):  # back to level at the end
        t_list.append(t_now + k * settings.dt)
        r_list.append(prev * (1 - k / n_ramp))
        s_list.append(len(tilts) - 1)
        h_list.append(False)
    rots = np.array(r_list)
    poses = np.concatenate([np.broadcast_to(rest[:3], (len(rots), 3)), rest[3:] + rots], axis=1)
    return MazeCommands(np.array(t_list), poses, np.array(s_list), np.array(h_list), d)


@dataclass(frozen=True)
class SegmentTask:
    spec: ModelSpec
    settings: MazeSettings
    poses: np.ndarray  # (k, 6) the segment's commands


@dataclass(frozen=True)
class SegmentResult:
    """motors_deg (k, 6); inverse errors error_mm, error_deg (k,); replay errors track_mm,
    track_deg (k,) of the forward model's pose against the command; reached (k,) bool;
    strain (k,) the replayed equilibrium's largest principal strain [-] (NaN: not solved)."""

    motors_deg: np.ndarray
    error_mm: np.ndarray
    error_deg: np.ndarray
    track_mm: np.ndarray
    track_deg: np.ndarray
    reached: np.ndarray
    strain: np.ndarray


def solve_segment(task: SegmentTask) -> SegmentResult:
    """Work unit: open-loop inverse solution of a segment, then its forward replay."""
    model = MODELS.get(task.spec)
    s = task.settings
    rest = model.rest_pose()
    state = None
    for t in (0.5, 1.0):  # reach the first command from rest in two moves
        g = rest + t * (task.poses[0] - rest)
        state = model.reach(g, state=state, tol_mm=s.tol_mm, tol_deg=s.tol_deg, max_steps=s.max_steps).state
    k = len(task.poses)
    q = np.zeros((k, len(model.rest_motors())))
    e = np.zeros((k, 2))
    conv = np.ones(k, bool)
    for i, g in enumerate(task.poses):
        if i and np.array_equal(g, task.poses[i - 1]):  # a held command holds the motors
            q[i], e[i], conv[i] = q[i - 1], e[i - 1], conv[i - 1]
            continue
        r = model.reach(g, state=state, tol_mm=s.tol_mm, tol_deg=s.tol_deg, max_steps=s.max_steps)
        q[i], state, conv[i] = r.motors_deg, r.state, r.converged
        e[i] = pose_errors(g, r.pose)
    tr = np.full((k, 2), np.nan)
    strain = np.full(k, np.nan)
    q_prev, fstate, last = model.rest_motors(), None, None  # last: (pose, strain) of the replay at q_prev
    for i, g in enumerate(task.poses):
        if last is not None and np.array_equal(q[i], q_prev):  # held motors: the same equilibrium
            tr[i], strain[i] = pose_errors(g, last[0]), last[1]
            continue
        last = None
        # replay as the motors would move: from rest in ramps of at most 5 deg, then sample to sample
        n = max(1, int(np.ceil(np.abs(q[i] - q_prev).max() / 5.0)))
        try:
            for t in np.arange(1, n + 1) / n:
                pose, fstate = model.equilibrium(q_prev + t * (q[i] - q_prev), state=fstate, intermediate=t < 1)
        except ConvergenceError:  # reported as a NaN tracking error (and the sample as not reached)
            continue
        q_prev = q[i]
        tr[i] = pose_errors(g, pose)
        strain[i] = model.max_principal_strain(fstate)
        last = (pose, strain[i])
    ok = (e[:, 0] <= s.tol_mm) & (e[:, 1] <= s.tol_deg) & np.isfinite(tr[:, 0]) & conv
    return SegmentResult(q, e[:, 0], e[:, 1], tr[:, 0], tr[:, 1], ok, strain)


@dataclass(frozen=True)
class MazeResult:
    """commands : the :class:`MazeCommands`; motors_deg (T, 6); error_* and track_* (T,);
    reached (T,) bool; segment_ok (s,) bool: every held sample of the segment reached (the
    marble rolls the right way); motor_range (lo, hi) [deg]; strain (T,) the replayed
    equilibria's largest principal strain [-] (NaN: not solved)."""

    commands: MazeCommands
    motors_deg: np.ndarray
    error_mm: np.ndarray
    error_deg: np.ndarray
    track_mm: np.ndarray
    track_deg: np.ndarray
    reached: np.ndarray
    segment_ok: np.ndarray
    motor_range: tuple[float, float]
    strain: np.ndarray


def solve_maze(
    spec: ModelSpec,
    path,
    settings: MazeSettings = MazeSettings(),
    *,
    plane_axes=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    executor: Executor = Executor(),
    progress: Callable[[str, int, int], None] = lambda d, i, n: None,
    cache: UnitCache | None = None,
) -> MazeResult:
    """Commands, open-loop motor series and replay of ``path`` (m, 2) [mm] on ``spec``'s robot."""
    return solve_mazes([spec], path, settings, plane_axes=plane_axes, executor=executor, progress=progress,
                       cache=cache)[0]


def solve_mazes(specs, path, settings: MazeSettings = MazeSettings(), *, plane_axes=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
                executor: Executor = Executor(), progress: Callable[[str, int, int], None] = lambda d, i, n: None,
                cache: UnitCache | None = None) -> list[MazeResult]:
    """:func:`solve_maze` on each of ``specs`` (robots, materials), every segment of every robot
    in one map: a robot's impossible segment (its inverse loop runs to ``max_steps``) runs
    beside the others' segments. Put the slowest robot first: its units are submitted first."""
    models = [MODELS.get(spec) for spec in specs]
    cmds = [maze_commands(path, m.rest_pose(), settings, plane_axes=plane_axes) for m in models]
    tasks = [SegmentTask(spec, settings, cmd.poses[cmd.segment == i])
             for spec, cmd in zip(specs, cmds) for i in range(len(cmd.directions))]
    parts = (cache or UnitCache(None)).map(executor, solve_segment, tasks,
                                           progress=lambda d, n: progress("maze segments", d, n))
    out, start = [], 0
    for model, cmd in zip(models, cmds):
        n_seg = len(cmd.directions)
        out.append(_maze_result(model, cmd, parts[start:start + n_seg]))
        start += n_seg
    return out


def _maze_result(model, cmd: MazeCommands, parts: list[SegmentResult]) -> MazeResult:
    cat = lambda f: np.concatenate([getattr(p, f) for p in parts])  # noqa: E731
    reached = cat("reached")
    ok = np.array([bool(reached[(cmd.segment == i) & cmd.hold].all()) for i in range(len(parts))])
    return MazeResult(cmd, cat("motors_deg"), cat("error_mm"), cat("error_deg"), cat("track_mm"),
                      cat("track_deg"), reached, ok, tuple(model.motor_range), cat("strain"))
