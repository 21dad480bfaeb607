"""A path of effector poses for a motor program (:mod:`.program`): read, timed and sampled.

The path comes as poses (n, 6) (x, y, z [mm], rotation vector [deg], as ``robot goto`` takes
them) with their times (n,) [s], or without them, walked at constant speed: each segment takes
the longer of its length over ``speed`` [mm/s] and its rotation over ``rot_speed`` [deg/s]
(:func:`path_times`). It is sampled every ``1 / rate`` s from its start to the first sample at
or past its end, which holds the last pose (:func:`sample_path`): positions linearly, rotations
by slerp (the geodesic between the two orientations). The maze study's tilt commands
(:func:`metasheet.studies.maze.maze_commands`) and a workspace study ray (its goals outwards
from rest, at the rest orientation) are paths like any other (:func:`maze_path`, :func:`ray_path`).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import ConfigError, check_range
from ..goto import POSE_BOUNDS

#: The path CSV's pose columns, in order, and its optional time column.
POSE_COLUMNS = ("x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg")
TIME_COLUMN = "t_s"
#: A path's pose may lie at most this far from the rest position [mm]: a sheet's arms are ~60 mm
#: long, the paper's workspace spans +-20 mm; beyond this a pose is a mistake (a unit, a digit).
MAX_DISTANCE_MM = 100.0
#: The most samples one program holds (a typo in --rate should not start a day of solves).
MAX_SAMPLES = 100_000
#: Default rotation speed of a path without times [deg/s].
ROT_SPEED_DEG_S = 10.0


# -- the path ---------------------------------------------------------------------------------
def read_path_csv(file) -> tuple[np.ndarray, np.ndarray | None]:
    """(poses (n, 6) [mm, deg], times (n,) [s] or None) of a path CSV: a header naming
    :data:`POSE_COLUMNS` (any order) and optionally :data:`TIME_COLUMN`, one pose a row."""
    rows = csv_rows(file)
    if not rows:
        raise ConfigError(f"{file}: empty: expected a header ({','.join(POSE_COLUMNS)}[,{TIME_COLUMN}]) and poses")
    header = [c.strip() for c in rows[0]]
    missing = [c for c in POSE_COLUMNS if c not in header]
    unknown = [c for c in header if c not in (*POSE_COLUMNS, TIME_COLUMN)]
    if missing or unknown:
        what = (f"missing column(s) {', '.join(missing)}" if missing else "") + \
               ("; " if missing and unknown else "") + (f"unknown column(s) {', '.join(unknown)}" if unknown else "")
        raise ConfigError(f"{file}: {what}: the header needs {','.join(POSE_COLUMNS)}, optionally {TIME_COLUMN}")
    if len(rows) < 2:
        raise ConfigError(f"{file}: empty path: no pose under the header")
    cols = [*POSE_COLUMNS, *([TIME_COLUMN] if TIME_COLUMN in header else [])]
    bounds = dict(zip(POSE_COLUMNS, POSE_BOUNDS), **{TIME_COLUMN: 1e6})
    values = np.empty((len(rows) - 1, len(cols)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ConfigError(f"{file}: data row {i + 1}: {len(row)} values for {len(header)} columns")
        for j, c in enumerate(cols):
            text = row[header.index(c)].strip()
            lo = 0.0 if c == TIME_COLUMN else -bounds[c]
            values[i, j] = float(check_range(f"{file}: data row {i + 1}, {c}", text, lo, bounds[c]))
    times = values[:, 6] if len(cols) == 7 else None
    if times is not None and np.any(np.diff(times) <= 0):
        i = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 2
        raise ConfigError(f"{file}: data row {i}, {TIME_COLUMN}: {times[i - 1]:g} s: times must increase row by row")
    return values[:, :6], times


def csv_rows(file) -> list[list[str]]:
    """The non-blank rows of a CSV file (a spreadsheet's byte-order mark dropped)."""
    if not Path(file).is_file():
        raise ConfigError(f"{file}: no such file")
    with open(file, newline="", encoding="utf-8-sig") as fh:
        return [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]


def _checked(poses, times=None) -> tuple[np.ndarray, np.ndarray | None]:
    """``poses`` as an (n, 6) array, n >= 1, finite; ``times`` (n,) finite, non-decreasing."""
    P = np.asarray(poses, float)
    if P.ndim != 2 or P.shape[1] != 6 or len(P) == 0 or not np.all(np.isfinite(P)):
        raise ConfigError(f"path: poses of shape {P.shape}: expected (n, 6) finite numbers, n >= 1")
    if times is None:
        return P, None
    t = np.asarray(times, float)
    if t.shape != (len(P),) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise ConfigError(f"path: times of shape {t.shape}: expected ({len(P)},) finite, non-decreasing [s]")
    return P, t


def rotations(poses) -> Rotation:
    return Rotation.from_rotvec(np.radians(np.asarray(poses, float)[:, 3:]))


def path_times(poses, speed: float, rot_speed: float = ROT_SPEED_DEG_S) -> np.ndarray:
    """(n,) [s] times of the vertices ``poses`` (n, 6) [mm, deg] walked at ``speed`` [mm/s] and
    ``rot_speed`` [deg/s]: each segment takes the longer of the two; the first at 0."""
    check_range("--speed", speed, 0.0, 1e4, lo_open=True)
    check_range("--rot-speed", rot_speed, 0.0, 1e5, lo_open=True)
    P, _ = _checked(poses)
    if len(P) < 2:
        return np.zeros(len(P))
    R = rotations(P)
    turn = np.degrees(np.linalg.norm((R[:-1].inv() * R[1:]).as_rotvec(), axis=1))  # [deg]
    dur = np.maximum(np.linalg.norm(np.diff(P[:, :3], axis=0), axis=1) / speed, turn / rot_speed)
    return np.concatenate([[0.0], np.cumsum(dur)])


def sample_path(times, poses, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """(t (T,) [s], poses (T, 6) [mm, deg]) every ``1 / rate`` s [Hz] from ``times[0]`` to the
    first sample at or past ``times[-1]`` (which holds the last pose); positions linear,
    rotations by slerp between the vertices (n, 6) at ``times`` (n,), non-decreasing."""
    check_range("--rate", rate, 0.0, 1000.0, lo_open=True)
    P, tv = _checked(poses, times)
    span = float(tv[-1] - tv[0])
    n = int(np.ceil(span * rate - 1e-9)) if span > 0 else 0
    if n + 1 > MAX_SAMPLES:
        raise ConfigError(f"--rate: {rate:g} Hz over {span:g} s gives {n + 1} samples: allowed at most {MAX_SAMPLES}")
    t = tv[0] + np.arange(n + 1) / rate
    if len(P) == 1 or span == 0:
        return t, np.repeat(P[-1:], len(t), axis=0)
    tq = np.minimum(t, tv[-1])
    i = np.clip(np.searchsorted(tv, tq, side="right") - 1, 0, len(tv) - 2)
    dt = tv[i + 1] - tv[i]
    f = np.where(dt > 0, (tq - tv[i]) / np.where(dt > 0, dt, 1.0), 1.0)  # a zero-time segment: its end
    pos = P[i, :3] + f[:, None] * (P[i + 1, :3] - P[i, :3])
    R0, R1 = rotations(P[i]), rotations(P[i + 1])
    rot = (R0 * Rotation.from_rotvec(f[:, None] * (R0.inv() * R1).as_rotvec())).as_rotvec()
    return t, np.concatenate([pos, np.degrees(rot)], axis=1)


def check_reach(poses, rest, max_mm: float = MAX_DISTANCE_MM) -> None:
    """ConfigError naming the first pose (n, 6) farther than ``max_mm`` from the rest pose (6,)."""
    d = np.linalg.norm(np.asarray(poses, float)[:, :3] - np.asarray(rest, float)[:3], axis=1)
    if np.any(d > max_mm):
        i = int(np.flatnonzero(d > max_mm)[0])
        p = ", ".join(f"{v:g}" for v in np.asarray(poses)[i, :3])
        raise ConfigError(f"path: pose {i + 1} (x, y, z = {p} mm) is {d[i]:.1f} mm from the rest position: "
                          f"allowed distance is at most {max_mm:g} mm")


def maze_path(rest, params) -> tuple[np.ndarray, np.ndarray]:
    """(times (n,) [s], poses (n, 6) [mm, deg]) of the maze study's tilt commands
    (:func:`metasheet.studies.maze.maze_commands`) from the rest pose ``rest`` (6,) [mm, deg],
    with rest itself at 0 s; ``params``: a :class:`metasheet.pipeline.stages.maze.MazeParams`."""
    from ..studies.maze import MazeSettings, maze_commands

    rest = np.asarray(rest, float)
    s = MazeSettings(tilt_deg=params.tilt_deg, speed=params.speed, dt=params.dt, ramp_s=params.ramp_s)
    c = maze_commands(params.path, np.concatenate([rest[:3], np.radians(rest[3:])]), s)
    poses = np.concatenate([c.poses[:, :3], np.degrees(c.poses[:, 3:])], axis=1)
    return np.concatenate([[0.0], c.time]), np.concatenate([rest[None], poses])


def ray_path(rest, grid, ray: int) -> np.ndarray:
    """(n + 1, 6) [mm, deg] poses of ray ``ray`` of a :class:`metasheet.studies.grid.StarGrid`:
    rest, then the ray's goals from the centre outwards, at the rest orientation."""
    n_rays = len(grid.directions)
    if int(ray) != ray:
        raise ConfigError(f"--ray: {ray!r}: expected a whole number")
    check_range("--ray", ray, 0, n_rays - 1)
    rest = np.asarray(rest, float)
    pts = rest[:3] + grid.points[grid.ray_points(int(ray))]
    return np.concatenate([rest[None], np.column_stack([pts, np.tile(rest[3:], (len(pts), 1))])])
