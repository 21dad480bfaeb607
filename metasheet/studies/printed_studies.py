"""The paper's studies on one print's robot (issue 62, item 5): Fig. 5 (workspace with the
rotation test), Fig. 6 (nested motor ranges) and the maze, run by the same study code as the
continuum columns (:mod:`.workspace`, :mod:`.ranges`, :mod:`.maze`) on the print's
:class:`~.printed_adapter.PrintedSpec`, within its walls' box (a reach past it stops with
``left_domain``: the point, the range's point or the maze's sample counts as not reached).

:func:`print_studies` returns the summary the ``printed`` stage keeps per print, in the keys of the
study stages' own JSON that :func:`metasheet.report.columns.study_verdict` reads; the stage
states the spread over the prints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.executor import Executor
from .maze import MazeSettings, solve_maze
from .printed_adapter import PrintedSpec
from .ranges import motor_range_study
from .rest_rotations import rest_rotations
from .workspace import WorkspaceSettings, domain_spec, explore_workspace, near_rest_control


@dataclass(frozen=True)
class PrintStudies:
    """What to run on each print: the workspace ``grid`` (:class:`~.grid.StarGrid`) and its
    ``settings``; the motor ``ranges`` (r, 2) [deg] of Fig. 6 (None: not run); the ``maze``
    polyline (m, 2) [mm] with its :class:`~.maze.MazeSettings` (None: not run); ``near_rest_mm``
    the radius of the area around rest whose full control Fig. 5 claims [mm]."""

    grid: object
    settings: WorkspaceSettings
    ranges: tuple | None
    maze: tuple | None
    maze_settings: MazeSettings
    near_rest_mm: float = 3.0


def print_studies(spec: PrintedSpec, s: PrintStudies, *, executor: Executor = Executor(),
                  progress=lambda d, i, n: None) -> dict:
    """Fig. 5, Fig. 6 and the maze on one print (module docstring): counts, not arrays."""
    ws = explore_workspace(spec, s.grid, s.settings, executor=executor, progress=progress)
    r = ws.records
    rest = spec.build().rest_pose()
    out = {"workspace": {"points": int(len(s.grid)), "reachable": int(r.reached.sum()), "counts": ws.counts(),
                         "left_domain": int(r.left_domain.sum()), "components": int(ws.n_components),
                         "near_rest": near_rest_control(ws.goals, ws.cls, r.reached, rest[:3], s.near_rest_mm),
                         "rest_rotations": rest_rotations(domain_spec(spec, s.settings), s.settings),
                         "max_wall_strain": float(np.nanmax(r.strain[r.reached]))
                         if r.reached.any() and np.isfinite(r.strain[r.reached]).any() else None}}
    if s.ranges is not None:
        rr = motor_range_study(spec, s.grid, [tuple(x) for x in s.ranges], s.settings, executor=executor,
                               progress=progress)
        out["ranges"] = {"ranges_deg": np.asarray(rr.ranges).tolist(), "nested": bool(rr.nested),
                         "reachable": {f"[{lo:g}, {hi:g}]": n for (lo, hi), n in zip(rr.ranges, rr.counts())}}
    if s.maze is not None:
        mz = solve_maze(spec, np.asarray(s.maze, float), s.maze_settings, executor=executor, progress=progress)
        out["maze"] = {"tilt_deg": s.maze_settings.tilt_deg, "segments": int(len(mz.segment_ok)),
                       "foam_impossible_segments": np.flatnonzero(~mz.segment_ok).tolist(),
                       "silicone_impossible_segments": None,
                       "samples": int(len(mz.reached)), "samples_reached": int(mz.reached.sum())}
    return out
