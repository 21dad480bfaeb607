"""The maze, played: the open-loop motor program of the maze study fed to the robot in time,
the maze plate carried by the rod, and a marble rolled on it (paper Section V-B3: "make the
marble follow the whole path of the maze and come back at the initial position").

The maze is fixed on the rod: its plane the rod's x (u) and y (v) at rest, its top face
``top`` [mm] above the rod's axis. The plate, its walls and the rod are one rigid body of PLA
(:func:`maze_inertia`). The marble rides on the plate's motion and does not load it (its
weight, a few grams, against sheets of 10-32 g and a 10-20 g maze: stated, not modelled).

The verdict (:func:`path_verdict`): the marble passes the path's vertices in order, each
within a corridor's half width; a path that ends where it starts ("comes back") is then
travelled whole.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .marble import MarbleRun, MarbleSettings, plate_motion, roll
from .mass import RigidInertia, box_inertia, combine, cylinder_inertia
from .maze_geometry import MazeGeometry, plate_bounds
from .response import Playback, play, pose_gap, quasi_static_path

#: PLA's density [t/mm^3] (filament datasheets: 1.24 g/cm^3).
PLA_DENSITY = 1.24e-9


def maze_inertia(geometry: MazeGeometry, *, rod_length: float, rod_radius: float = 3.0, thickness: float = 3.0,
                 wall_thickness: float = 2.0, origin=(0.0, 0.0, 0.0), density: float = PLA_DENSITY) -> RigidInertia:
    """The rod (a solid cylinder along x through ``origin``) with the maze plate (a box of the
    geometry's plate size and ``thickness`` on top of the rod) and its walls (``wall_height`` x
    ``wall_thickness`` boxes along each wall segment, lumped as thin bars), all of ``density``
    [t/mm^3]; lengths [mm], in the robot's frame at rest (``origin`` the rod's reference point)."""
    o = np.asarray(origin, float)
    rod = cylinder_inertia(density * np.pi * rod_radius**2 * rod_length, rod_radius, rod_length, 0, o)
    lo, hi = plate_bounds(geometry)
    size = np.array([*(hi - lo), thickness])
    plate = box_inertia(density * np.prod(size), size, o + [*(0.5 * (lo + hi)), rod_radius + 0.5 * thickness])
    parts = [rod, plate]
    for a, b in geometry.walls:
        d = b - a
        length = float(np.linalg.norm(d))
        if length <= 0:
            continue
        m = density * length * wall_thickness * geometry.wall_height
        z = rod_radius + thickness + 0.5 * geometry.wall_height
        # a thin bar along d: m L^2 / 12 across it, its own section's terms neglected
        u = np.array([*(d / length), 0.0])
        inertia = m * length**2 / 12.0 * (np.eye(3) - np.outer(u, u))
        parts.append(RigidInertia(m, o + [*(0.5 * (a + b)), z], inertia))
    return combine(*parts)


def segment_arrivals(geometry: MazeGeometry, t: np.ndarray, u: np.ndarray, ends) -> np.ndarray:
    """Per path segment, whether the marble's centre (``u`` (K, 2) [mm] at times ``t`` (K,) [s])
    is within half a corridor width of the segment's end vertex at ``ends[i]`` [s], the end of
    the segment's hold (where the program turns to the next corridor)."""
    ends = np.asarray(ends, float)
    at = np.stack([np.interp(ends, t, u[:, k]) for k in range(2)], axis=1)
    return np.linalg.norm(at - geometry.path[1:len(ends) + 1], axis=1) <= 0.5 * geometry.width


def path_verdict(geometry: MazeGeometry, u: np.ndarray) -> tuple[int, bool]:
    """How many of the path's vertices after the first the marble's centre track ``u`` (K, 2)
    [mm] passed in order (within half a corridor width), and whether that is all of them."""
    reach = 0.5 * geometry.width
    targets = geometry.path[1:]
    j = 0
    for point in u:
        if j < len(targets) and np.linalg.norm(point - targets[j]) <= reach:
            j += 1
    return j, j == len(targets)


@dataclass(frozen=True)
class MazePlayed:
    """run : the robot in time (:class:`.response.Playback`); quasi : its quasi-static path at the
    program's samples; gap_mm, gap_deg : (steps,) the run's distance from it at each step (the
    path joined linearly between its samples); marble : the
    :class:`.marble.MarbleRun`; vertices : path vertices passed in order; solved : all of them;
    arrivals : per segment, the marble at its end vertex when the segment's hold ends (None
    without ``ends``)."""

    run: Playback
    quasi: Playback
    gap_mm: np.ndarray
    gap_deg: np.ndarray
    marble: MarbleRun
    vertices: int
    solved: bool
    arrivals: np.ndarray | None = None


def play_maze(dyn, qs, rest, times, angles, geometry: MazeGeometry, *, h: float, top: float,
              marble: MarbleSettings = MarbleSettings(), speed: float = 1.0, progress=None,
              keep_x: list | None = None, keep_every: int = 1, ends=None, quasi_x: list | None = None) -> MazePlayed:
    """Play the motor program (``times`` (T,) [s], ``angles`` (T, na) [rad]) on ``dyn`` from the
    equilibrium ``rest`` in steps of ``h`` [s], ``speed`` times faster; compare with ``qs``'s
    quasi-static path; roll the marble from the path's start on the plate whose top face is
    ``top`` [mm] above the rod's reference point (``keep_x``, ``keep_every``: :func:`.response.play`;
    ``ends`` [s] each segment's hold end in the program's time, for :func:`segment_arrivals`;
    ``quasi_x`` a list that receives the quasi-static path's node positions per sample)."""
    run, _ = play(dyn, rest, times, angles, h, speed=speed, progress=progress, keep_x=keep_x, keep_every=keep_every)
    quasi = quasi_static_path(qs, rest, np.asarray(times, float) / speed, angles, keep_x=quasi_x)
    mm, deg = pose_gap(run, quasi)
    motion = plate_motion(run.t, run.pose, top=top)
    m = roll(motion, geometry, geometry.path[0], marble)
    n, solved = path_verdict(geometry, m.u)
    arrivals = None if ends is None else segment_arrivals(geometry, m.t, m.u, np.asarray(ends, float) / speed)
    return MazePlayed(run, quasi, mm, deg, m, n, solved, arrivals)
