"""The page's status panel as text: motors against their stroke, pose, error, validity, speed.

Pure functions of a :class:`.session.Snapshot` (and the page's own measurements), so the
panel is tested without a browser. The panel is markdown; its lines start with fixed words
("pose", "goal", "error", ...) a reader, or a test, can find.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np

from ..robot.validity import GRIP_BAND_MM

#: how a status reads on the page
STATUS_TEXT = {"moving": "moving", "reached": "reached", "unreachable": "unreachable", "holding": "holding",
               "playing": "playing the maze", "error": "error"}
#: a motor this close to a limit is marked "at limit" [deg]
AT_LIMIT_DEG = 0.5
#: the update rates benchmarks/bench_serve.py measured (--model both --repeats 3; the README's
#: serve section has the table), shown on the page next to its own live rate
MEASURED_RATE = ("measured (benchmarks/bench_serve.py --scale 0.3, the paper robot, 37k unknowns, 2 cores): "
                 "reduced model 52-62 updates/s while the goal is dragged inside its training box (35-41 with "
                 "the page open in headless chromium on the same cores), full model 26-32; 6.6-9.3 on drags "
                 "that leave the box (the full model solves there)")


def _vec(v, digits: int = 2) -> str:
    # + 0.0: a value that rounds to zero reads 0.00, not -0.00 (a pose round trip leaves -1e-17)
    return " ".join(f"{round(float(x), digits) + 0.0:.{digits}f}" for x in v)


def motor_table(angles_deg, lo_deg, hi_deg) -> str:
    """A markdown table: each motor's angle [deg], its stroke [deg] and whether it is at a limit."""
    rows = ["| motor | angle [deg] | stroke [deg] | |", "|---|---|---|---|"]
    for k, (a, lo, hi) in enumerate(zip(angles_deg, lo_deg, hi_deg)):
        flag = "at limit" if min(a - lo, hi - a) <= AT_LIMIT_DEG else ""
        rows.append(f"| {k} | {a:.2f} | {lo:g} to {hi:g} | {flag} |")
    return "\n".join(rows)


def status_markdown(snap, *, strain_max: float, strain_limit: float, rate: float, model: str) -> str:
    """The panel's markdown for snapshot ``snap``; ``strain_max`` [-] of the state drawn,
    ``rate`` [updates/s] the page measured, ``model`` "full" / "reduced": the one asked for
    (the snapshot's own model, and its note when the full model stands in, are shown)."""
    status = STATUS_TEXT.get(snap.status, snap.status)
    head = f"**{status.upper()}**" if snap.status in ("unreachable", "error") else f"**{status}**"
    valid = ("n/a" if not np.isfinite(strain_max) else
             ("valid" if strain_max <= strain_limit else "NOT VALID (beyond the homogenisation's domain)"))
    sv = snap.singular_values
    lines = [
        f"status: {head}: {snap.message}",
        "",
        f"material: {snap.material}, model: {snap.model}, mode: {snap.mode}",
        "",
        *([f"**{snap.note}**", ""] if snap.note else []),
        motor_table(snap.angles_deg, snap.angle_min_deg, snap.angle_max_deg),
        "",
        f"pose [mm, deg]: {_vec(snap.pose[:3])} | {_vec(snap.pose[3:])}",
        "",
        f"goal [mm, deg]: {_vec(snap.goal[:3])} | {_vec(snap.goal[3:])}",
        "",
        f"error: {snap.pos_error:.3f} mm, {snap.rot_error:.3f} deg",
        "",
        f"strain: max {strain_max:.3f} (beyond {GRIP_BAND_MM:g} mm of the grips), limit {strain_limit:g}: {valid}",
        "",
        (f"smallest singular value: {sv.min():.3f} mm/rad (of {len(sv)}: {_vec(sv, 1)})" if len(sv)
         else "smallest singular value: n/a"),
        "",
        f"solver step: {snap.step_ms:.1f} ms; updates: {rate:.1f} per s",
    ]
    return "\n".join(lines)


class RateMeter:
    """Visual updates per second, over the last ``window`` seconds in which updates came at
    least every ``gap`` seconds (a burst of motion): the rate while the robot moves, kept
    after it stops instead of decaying to zero."""

    def __init__(self, window: float = 3.0, gap: float = 2.0, clock=time.perf_counter):
        self.window, self.gap, self.clock = window, gap, clock
        self.times: deque = deque()

    def tick(self) -> None:
        now = self.clock()
        if self.times and now - self.times[-1] > self.gap:
            self.times.clear()  # a new burst
        self.times.append(now)
        while self.times and now - self.times[0] > self.window:
            self.times.popleft()

    def rate(self) -> float:
        """[1/s]; 0 before two updates of one burst."""
        if len(self.times) < 2:
            return 0.0
        return (len(self.times) - 1) / max(self.times[-1] - self.times[0], 1e-9)
