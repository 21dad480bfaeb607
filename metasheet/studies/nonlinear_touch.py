"""The walls' first touch on the finite-strain printed robot (issue 62, item 4: self-contact
found on the nonlinear DNS).

:mod:`.printed_limits` finds where two walls first touch to first order: the linear DNS's
fields carried to the motors. The printed walls turn as they bend and close their voids sooner
than that (docs/printed-sheet.md: a gap of the mirrored sheet 80 % closed a degree from rest,
where its linear field closes 64 %). Here the travel along one motor direction at which two
walls first touch is found on :class:`metasheet.robot.voxel_robot.PrintedRobot` itself: both
sheets neo-Hookean voxel bodies, the rod balanced or held where the linear rest model puts it
(:class:`RobotDistance`), each pose's closest approach of two wall surfaces that were apart at
rest (:func:`metasheet.fem.voxel.gaps.closest_approach`; a touch is within a quarter voxel, the
rule the first-order search uses).

The search (:func:`first_touch`) needs only the closest approach as a function of the travel:
it walks out from the first-order guess until a pose is closed, then narrows the bracket, by
regula falsi (Illinois) on the distance where the open end's pair is within the gap search's
reach, by halving where it is not. Each pose is minutes of solves on a print, so
the search counts its solves and stops at ``max_solves``, reporting the bracket it reached.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range


@dataclass(frozen=True)
class Touch:
    """The first touch along one direction: ``travel`` the estimated travel at first touch (None:
    open up to ``max_travel``); ``bracket`` (open, closed) the travels last solved on either side
    (closed: inf when none); ``poses`` ((travel, distance [mm]), ...) in the order solved;
    ``touch`` [mm] the distance counted as touching; ``converged``: the bracket within ``tol``;
    ``info`` what the distance function said at the closed end (which sheet, which nodes)."""

    travel: float | None
    bracket: tuple
    poses: tuple
    touch: float
    converged: bool
    info: dict

    @property
    def solves(self) -> int:
        return len(self.poses)


def _root(lo, d_lo, hi, d_hi, touch) -> float:
    """Where the distance, linear between the bracket's ends, meets ``touch``."""
    return lo + (hi - lo) * (d_lo - touch) / (d_lo - d_hi)


def first_touch(distance, guess: float, touch: float, *, max_travel: float, tol: float,
                max_solves: int = 10) -> Touch:
    """The least travel ``t`` in (0, ``max_travel``] at which ``distance(t)`` (a function
    returning (closest approach [mm], info dict); inf when no pair is within reach) is at most
    ``touch`` [mm], to ``tol`` (module docstring). ``guess`` (0, max_travel]: the first-order
    travel, solved first; the walk then steps by half of it. The distance is assumed open (above
    ``touch``) at zero travel."""
    check_range("max_travel", max_travel, 0.0, None, lo_open=True)
    check_range("guess", guess, 0.0, max_travel, lo_open=True)
    check_range("tol", tol, 0.0, None, lo_open=True)
    check_range("touch", touch, 0.0, None, lo_open=True)
    check_range("max_solves", max_solves, 1, 1000)
    poses = []

    def solve(t):
        d, info = distance(float(t))
        d = float(d)
        if np.isnan(d):
            raise ConfigError(f"distance({t:g}): nan: the closest approach must be a distance or inf")
        poses.append((float(t), d))
        return d, info

    lo, d_lo, hi, d_hi, info = 0.0, np.inf, np.inf, np.inf, {}
    t = float(guess)
    while len(poses) < max_solves:  # walk out until a pose is closed
        d, i = solve(t)
        if d <= touch:
            hi, d_hi, info = t, d, i
            break
        lo, d_lo = t, d
        if t >= max_travel:
            return Touch(None, (lo, np.inf), tuple(poses), touch, True, {})
        t = min(t + 0.5 * guess, max_travel)
    # Illinois: the interpolation's weights; an end kept twice in a row has its weight halved
    f_lo, f_hi, kept = d_lo - touch, d_hi - touch, None
    while np.isfinite(hi) and hi - lo > tol and len(poses) < max_solves:
        if np.isfinite(f_lo):
            t = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            t = min(max(t, lo + 0.05 * (hi - lo)), hi - 0.05 * (hi - lo))  # never on an end
        else:
            t = 0.5 * (lo + hi)
        d, i = solve(t)
        if d <= touch:
            hi, d_hi, f_hi, info = t, d, d - touch, i
            f_lo, kept = (0.5 * f_lo if kept == "lo" else f_lo), "lo"
        else:
            lo, d_lo, f_lo = t, d, d - touch
            f_hi, kept = (0.5 * f_hi if kept == "hi" else f_hi), "hi"
    if not np.isfinite(hi):
        return Touch(None, (lo, np.inf), tuple(poses), touch, False, {})
    travel = _root(lo, d_lo, hi, d_hi, touch) if np.isfinite(d_lo) else 0.5 * (lo + hi)
    return Touch(float(travel), (lo, hi), tuple(poses), touch, bool(hi - lo <= tol), info)


class RobotDistance:
    """``distance(t)`` for :func:`first_touch` on a finite-strain printed robot: the closest
    approach over both sheets at motors ``rest_deg + t * direction`` (6,) [deg].

    ``rod_per_motor`` (6, 6) [mm, rad per rad]: the linear rest model's effector motion per motor.
    With ``balance`` the rod is in equilibrium
    (:meth:`metasheet.robot.voxel_robot.PrintedRobot.equilibrium`), its iteration started from the
    nearest travel solved before (rest at first), moved by ``rod_per_motor``'s prediction when
    given; without, the rod is held where ``rod_per_motor`` puts it
    (:meth:`~metasheet.robot.voxel_robot.PrintedRobot.held`: one solve per sheet, the rod's
    unbalanced wrench recorded). Balanced, the sheets start from the last pose solved; held, from
    rest (each pose then a function of its travel alone). ``records`` keeps
    every pose solved: travel, the rod's motion (dp [mm], rotation vector [rad]), its move [mm],
    turn [deg] and residual (held: ``rod_miss``, its first-order step to the balance, [mm, deg]),
    each sheet's closest approach [mm] and largest wall strain [-],
    whether each sheet's balance is stable, and the seconds; ``progress(record)`` is called with
    each. ``journal`` (a :class:`metasheet.runtime.journal.Journal`, keyed by everything the poses
    depend on): each pose is recorded there as it is solved, and one found there is replayed
    (``"replayed": True`` in its record), so a search killed part way resumes where it stopped.
    ``rod_tol_mm``: a balanced rod's step tolerance
    (:meth:`~metasheet.robot.voxel_robot.PrintedRobot.equilibrium`'s ``step_tol``; its last
    predicted step is then its ``rod_miss``)."""

    def __init__(self, printed, rest_deg, direction, rod_per_motor=None, balance: bool = True, progress=None,
                 journal=None, rod_tol_mm: float | None = None):
        self.printed, self.balance, self.progress, self.journal = printed, bool(balance), progress, journal
        self.rod_tol_mm = rod_tol_mm
        self.rod_per_motor = None if rod_per_motor is None else np.asarray(rod_per_motor, float)
        self.rest = np.asarray(rest_deg, float).reshape(-1)
        self.direction = np.asarray(direction, float).reshape(-1)
        if self.rest.shape != (6,) or self.direction.shape != (6,) or not np.isfinite(self.direction).all():
            raise ConfigError(f"rest_deg, direction: shapes {self.rest.shape}, {self.direction.shape}: "
                              "six motor angles and six finite offsets [deg per deg of travel]")
        if not np.abs(self.direction).max() > 0:
            raise ConfigError("direction: all six offsets zero: no travel")
        if not self.balance and (self.rod_per_motor is None or self.rod_per_motor.shape != (6, 6)):
            raise ConfigError("rod_per_motor: the (6, 6) effector motion per motor that holds the rod "
                              "(balance = False)")
        self.records, self._q = [], {}

    def __call__(self, t: float) -> tuple[float, dict]:
        kept = None if self.journal is None else self.journal.get(t)
        if kept is not None:
            rec, info = {**kept["record"], "replayed": True}, kept["info"]
            self._q[float(t)] = np.concatenate([rec["dp_mm"], rec["theta_rad"]])
        else:
            rec, info = self._solve(t)
            if self.journal is not None:
                self.journal.add(t, {"record": rec, "info": info})
        self.records.append(rec)
        if self.progress is not None:
            self.progress(rec)
        return float(rec["approach_mm"][info["sheet"]]), info

    def _solve(self, t: float) -> tuple[dict, dict]:
        t0 = time.perf_counter()
        motors = self.rest + t * self.direction
        if self.balance:
            near = min(self._q, key=lambda s: (abs(s - t), s)) if self._q else 0.0
            q0 = self._q.get(near, np.zeros(6))
            if self.rod_per_motor is not None:
                q0 = q0 + self.rod_per_motor @ np.radians((t - near) * self.direction)
            pose = self.printed.equilibrium(motors, q0=q0, step_tol=self.rod_tol_mm)
        else:
            # from rest: each held pose a function of its travel alone, so a resumed search is the same bits
            pose = self.printed.held(motors, self.rod_per_motor @ np.radians(t * self.direction), from_rest=True)
        self._q[float(t)] = np.concatenate([pose.dp, pose.theta])
        dist = [a.distance for a in pose.approach]
        s = int(np.argmin(dist))
        a = pose.approach[s]
        rec = {"travel": float(t), "dp_mm": pose.dp.tolist(), "theta_rad": pose.theta.tolist(),
               "move_mm": float(np.linalg.norm(pose.dp)), "turn_deg": float(np.degrees(np.linalg.norm(pose.theta))),
               "rod_residual": float(pose.residual), "approach_mm": [float(v) for v in dist],
               "rod_miss": None if pose.rod_step is None else
               [float(np.linalg.norm(pose.rod_step[:3])), float(np.degrees(np.linalg.norm(pose.rod_step[3:])))],
               "strain": [float(v) for v in pose.wall_strain], "stable": [bool(v) for v in pose.stable],
               "seconds": time.perf_counter() - t0}
        return rec, {"sheet": s, "nodes": [int(v) for v in a.nodes], "rest_distance_mm": float(a.rest_distance),
                     "position_mm": [float(v) for v in a.position]}


def robot_touch(printed, rest_deg, direction, guess_deg: float, *, max_deg: float, tol_deg: float = 0.02,
                max_solves: int = 10, touch_mm: float | None = None, rod_per_motor=None, balance: bool = True,
                progress=None, journal=None, rod_tol_mm: float | None = None) -> tuple[Touch, list]:
    """(the :class:`Touch` along ``direction`` (6,) [deg per deg of the largest motor's travel] of
    the finite-strain ``printed`` robot, in degrees of the largest motor; the poses' records).
    ``guess_deg``: the first-order first contact (:mod:`.printed_limits`); ``touch_mm``: the
    distance counted as touching (None: the first-order search's rule, a quarter of the smallest
    voxel edge); ``rod_per_motor``, ``balance``, ``progress``, ``journal``, ``rod_tol_mm``: as
    :class:`RobotDistance`'s."""
    d = np.asarray(direction, float)
    f = RobotDistance(printed, rest_deg, d / max(float(np.abs(d).max(initial=0.0)), 1e-300), rod_per_motor,
                      balance, progress, journal, rod_tol_mm)
    h = min(float(np.min(np.asarray(s.size, float) / np.asarray(s.phases.shape))) for s in printed.sheets)
    touch = 0.25 * h if touch_mm is None else touch_mm
    found = first_touch(f, guess_deg, touch, max_travel=max_deg, tol=tol_deg, max_solves=max_solves)
    return found, f.records


@dataclass(frozen=True)
class TouchUnit:
    """One print's first touch to search on its finite-strain robot (a `printed` stage unit):
    ``sheets`` its two :class:`~metasheet.sheet.dns.SheetPrint` (A, B); ``robot`` the six-DOF
    robot; ``S_rest`` (12, 12) the linear rest Schur complement (the rod's first Jacobian);
    ``name`` and ``direction`` (6,) the motor direction; ``guess_deg`` its first-order first
    contact; ``tol_deg``, ``max_solves``: the search's; ``rtol`` the sheets' Newton tolerance;
    ``balance``: the rod balanced at each pose (minutes of rod iterations on a print) or held
    where the linear rest model puts it (:class:`RobotDistance`)."""

    sheets: tuple
    robot: object
    S_rest: tuple
    name: str
    direction: tuple
    guess_deg: float
    tol_deg: float = 0.02
    max_solves: int = 8
    rtol: float = 1e-6
    balance: bool = False

    def __post_init__(self):
        check_range("guess_deg", self.guess_deg, 0.0, 90.0, lo_open=True)
        check_range("tol_deg", self.tol_deg, 0.0, None, lo_open=True)
        if np.shape(self.S_rest) != (12, 12):
            raise ConfigError(f"S_rest: shape {np.shape(self.S_rest)}: expected the (12, 12) rest Schur complement")


def touch_unit(u: TouchUnit, journal=None) -> dict:
    """The :class:`TouchUnit`'s first touch, searched to twice the first-order travel: the travel
    [deg] (None: open there), its bracket, whether it converged, the sheet that touches and every
    pose solved (:class:`RobotDistance`'s records). ``journal``: as :class:`RobotDistance`'s (the
    stage's unit cache gives one, so a killed search resumes at its last pose)."""
    from ..robot.voxel_robot import PrintedRobot, VoxelSheet

    sheets = tuple(VoxelSheet.from_print(s) for s in u.sheets)
    S = np.asarray(u.S_rest, float)
    printed = PrintedRobot(u.robot, sheets, S_rest=S, rtol=u.rtol)
    rest = np.degrees([s.rest_angle for s in u.robot.coupling.servos])
    try:
        found, records = robot_touch(printed, rest, u.direction, u.guess_deg, max_deg=2.0 * u.guess_deg,
                                     tol_deg=u.tol_deg, max_solves=u.max_solves,
                                     rod_per_motor=-np.linalg.solve(S[:6, :6], S[:6, 6:]), balance=u.balance,
                                     journal=journal)
    finally:
        printed.close()
    records = [{k: v for k, v in r.items() if k not in ("seconds", "replayed")} for r in records]  # same bytes
    return {"direction": u.name, "first_order_deg": float(u.guess_deg), "touch_deg": found.travel,
            "bracket_deg": [float(v) if np.isfinite(v) else None for v in found.bracket],
            "converged": found.converged, "touch_mm": found.touch,
            "sheet": u.sheets[found.info["sheet"]].label if found.info else None, "poses": records}


def refine(limits: dict, touch: dict) -> dict:
    """The :func:`~.printed_limits.combine`'d ``limits`` with the searched direction's first
    contact taken from the finite-strain robot's ``touch`` (:func:`touch_unit`; open: no contact
    within its search) and the box ``valid_deg`` the first contact over the directions again;
    the first-order value kept beside it."""
    dirs = {k: dict(v) for k, v in limits["directions"].items()}
    row = dirs[touch["direction"]]
    row["first_order_contact_deg"] = row["contact_deg"]
    row["contact_deg"], row["contact_sheet"] = touch["touch_deg"], touch["sheet"]
    row["finite_strain"] = True
    contacts = [(r["contact_deg"], n) for n, r in dirs.items() if r["contact_deg"] is not None]
    valid, binding = min(contacts) if contacts else (None, None)
    return {**limits, "directions": dirs, "valid_deg": valid, "binding": binding,
            "first_order_valid_deg": limits["valid_deg"], "touch": {k: v for k, v in touch.items() if k != "poses"},
            "touch_poses": touch["poses"]}
