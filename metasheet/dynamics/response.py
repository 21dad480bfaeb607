"""The robot's response in time to a motor program: playback, the quasi-static path it is
compared with, step responses and the fastest playback that stays on the quasi-static path.

A motor program is a table of times [s] and motor angles [rad]; between its samples the
commanded angles are joined linearly (a position-controlled servo ramping to each new command).
The servos are position-controlled: their horns follow the program exactly (prescribed
motion); their torques are an output.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from ..mechanics.rotations import rotation_matrix, rotation_vector
from .robot import DynamicRobot, DynamicState


@dataclass(frozen=True)
class Playback:
    """A run of the robot in time.

    t : (T,) [s]; angles : (T, na) [rad] the horns'; p : (T, 3) [mm] and R : (T, 3, 3) the rod's
    pose; torques : (T, na) [N mm] the servos'; newton, tangents : (T,) iterations and fresh
    tangents per step (0 at the start).
    """

    t: np.ndarray
    angles: np.ndarray
    p: np.ndarray
    R: np.ndarray
    torques: np.ndarray
    newton: np.ndarray
    tangents: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """(T, 6) [mm, rad] the rod's position and rotation vector (NaN where not solved)."""
        rot = np.array([rotation_vector(R) if np.all(np.isfinite(R)) else np.full(3, np.nan) for R in self.R])
        return np.hstack([self.p, rot])

    @property
    def unsolved(self) -> int:
        """Samples whose equilibrium was not found (:func:`quasi_static_path`)."""
        return int(np.sum(~np.isfinite(self.p[:, 0])))


def check_program(times, angles, na: int) -> tuple[np.ndarray, np.ndarray]:
    """``times`` (T,) [s] strictly increasing from >= 0 and ``angles`` (T, na) [rad], finite;
    ConfigError naming the field otherwise."""
    t = np.asarray(times, float).reshape(-1)
    a = np.asarray(angles, float)
    if t.ndim != 1 or len(t) < 2:
        raise ConfigError(f"program.times: {len(t)} samples: need at least 2")
    if a.shape != (len(t), na):
        raise ConfigError(f"program.angles: shape is {a.shape} and should be ({len(t)}, {na})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
        raise ConfigError("program: contains non-finite values")
    if t[0] < 0 or np.any(np.diff(t) <= 0):
        raise ConfigError("program.times: must start at >= 0 s and increase strictly")
    return t, a


def program_at(times: np.ndarray, angles: np.ndarray, t) -> np.ndarray:
    """The commanded angles at time(s) ``t`` (linear between samples, held beyond the ends)."""
    t = np.atleast_1d(np.asarray(t, float))
    return np.stack([np.interp(t, times, angles[:, k]) for k in range(angles.shape[1])], axis=-1)


def play(dyn: DynamicRobot, start: DynamicState, times, angles, h: float, *, speed: float = 1.0,
         t_end: float | None = None, progress: Callable[[int, int], None] | None = None,
         record_every: int = 1, keep_x: list | None = None, keep_every: int = 1) -> tuple[Playback, DynamicState]:
    """Play the program (``times`` (T,) [s], ``angles`` (T, na) [rad]) ``speed`` times faster
    from ``start`` in steps of ``h`` [s] until ``t_end`` (default: the program's end), recording
    every ``record_every``-th step (and the node positions (n, 3) [mm] of the start and every
    ``keep_every``-th step into ``keep_x``, an animation's frames). Returns the :class:`Playback`
    and the last state."""
    check_range("h", h, 0.0, None, lo_open=True)
    check_range("speed", speed, 0.0, None, lo_open=True)
    tt, aa = check_program(times, angles, dyn.robot.coupling.n_act)
    tt = tt / speed
    end = float(tt[-1]) if t_end is None else float(t_end)
    n = max(1, int(np.ceil((end - start.kin.t) / h - 1e-9)))
    dyn.reset()  # the same run whatever ran on this robot before
    rows = [start]
    ds = start
    if keep_x is not None:
        keep_x.append(start.state.x.copy())
    for k in range(1, n + 1):
        t = start.kin.t + k * h
        ds = dyn.step(ds, program_at(tt, aa, t)[0], h)
        if k % record_every == 0 or k == n:
            rows.append(ds)
        if keep_x is not None and k % keep_every == 0:
            keep_x.append(ds.state.x.copy())
        if progress is not None:
            progress(k, n)
    return _playback(rows), ds


def _playback(rows: list[DynamicState]) -> Playback:
    return Playback(np.array([r.kin.t for r in rows]), np.array([r.state.angles for r in rows]),
                    np.array([r.state.p for r in rows]), np.array([r.state.R for r in rows]),
                    np.array([r.torques for r in rows]), np.array([r.newton for r in rows]),
                    np.array([r.tangents for r in rows]))


def quasi_static_path(qs: DynamicRobot, start: DynamicState, times, angles, *, substeps: int = 1,
                      keep_x: list | None = None) -> Playback:
    """The equilibria along the program (``qs`` a :class:`DynamicRobot` with the
    :class:`~.schemes.QuasiStatic` scheme and the same rigid body), at each sample, continued from
    one to the next (``substeps`` equal motor increments between samples). A sample whose
    equilibrium the solve does not find (soft sheets snapping under a large motor jump: the
    inertia that carries the dynamic run through is absent here) is NaN, and the next sample
    continues from the last one found (:attr:`Playback.unsolved` counts them). ``keep_x``: a list
    that receives each sample's node positions (n, 3) [mm] (the last found for a NaN sample)."""
    tt, aa = check_program(times, angles, qs.robot.coupling.n_act)
    qs.reset()
    rows, ds = [], start
    for i, t in enumerate(tt):
        prev = aa[i - 1] if i else ds.state.angles
        h = (t - tt[i - 1]) / substeps if i else 1.0
        try:
            for j in range(1, substeps + 1):
                ds = qs.step(ds, prev + (aa[i] - prev) * j / substeps, h)
        except ConvergenceError:
            nan = np.full(3, np.nan)
            lost = dataclasses.replace(ds.state, p=nan, R=np.full((3, 3), np.nan), angles=aa[i])
            rows.append(DynamicState(lost, dataclasses.replace(ds.kin, t=float(t)), ds.torques * np.nan, -1, 0))
            if keep_x is not None:
                keep_x.append(ds.state.x.copy())
            continue
        rows.append(DynamicState(ds.state, dataclasses.replace(ds.kin, t=float(t)), ds.torques, ds.newton,
                                 ds.tangents))
        if keep_x is not None:
            keep_x.append(ds.state.x.copy())
    return _playback(rows)


def pose_gap(run: Playback, reference: Playback) -> tuple[np.ndarray, np.ndarray]:
    """At each of ``run``'s steps, the distance [mm] and angle [deg] between its rod pose and the
    ``reference`` path's, joined linearly between the reference's samples (positions, and
    rotations by their rotation vectors); NaN beyond the reference's ends or next to a sample it
    did not solve."""
    t = run.t
    ref = reference.pose
    slack = 1e-9 * max(1.0, float(abs(reference.t[-1])))  # the run's clock sums its steps
    inside = (t >= reference.t[0] - slack) & (t <= reference.t[-1] + slack)
    q = np.stack([np.interp(t, reference.t, ref[:, k]) for k in range(6)], axis=1)
    q[~inside] = np.nan
    mm = np.linalg.norm(run.p - q[:, :3], axis=1)
    deg = np.full(len(t), np.nan)
    ok = np.all(np.isfinite(q), axis=1)
    for i in np.flatnonzero(ok):
        deg[i] = np.degrees(np.linalg.norm(rotation_vector(run.R[i] @ rotation_matrix(q[i, 3:]).T)))
    return mm, deg


@dataclass(frozen=True)
class StepMetrics:
    """A step response of one effector DOF: the change it settles to, rise time (10-90 %) [s],
    overshoot [% of the change], settling time (within ``band`` of the change for good) [s]."""

    final: float
    rise_s: float | None
    overshoot_pct: float
    settling_s: float | None
    band: float


def step_metrics(t, y, y0: float, y_final: float, *, band: float = 0.02) -> StepMetrics:
    """:class:`StepMetrics` of the signal ``y`` (T,) at times ``t`` (T,) [s] from ``y0`` towards
    ``y_final`` (the quasi-static value). None where the signal never reaches the level."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    d = y_final - y0
    if d == 0:
        raise ConfigError("step: the quasi-static change is zero: nothing to measure")
    u = (y - y0) / d  # normalised: 0 -> 1
    def first(level):
        i = np.flatnonzero(u >= level)
        return float(t[i[0]]) if len(i) else None
    t10, t90 = first(0.1), first(0.9)
    rise = None if t10 is None or t90 is None else t90 - t10
    over = max(0.0, float(u.max() - 1.0)) * 100.0
    out = np.flatnonzero(np.abs(u - 1.0) > band)
    settle = float(t[0]) if not len(out) else (float(t[out[-1] + 1]) if out[-1] + 1 < len(t) else None)
    return StepMetrics(float(d), rise, over, settle, band)


@dataclass(frozen=True)
class StepResponse:
    """The robot's answer to a step of the goal of one effector DOF.

    dof : 0-5 (x, y, z, rx, ry, rz); goal : (6,) the goal's change [mm, rad]; motors : (na,) the
    motors' change [rad] the rest Jacobian's inverse asks for; run : the dynamic
    :class:`Playback`; target : (6,) the quasi-static pose at the new angles; metrics : of the
    stepped DOF (:class:`StepMetrics`, rotations in rad)."""

    dof: int
    goal: np.ndarray
    motors: np.ndarray
    run: Playback
    target: np.ndarray
    metrics: StepMetrics


def step_response(dyn: DynamicRobot, qs: DynamicRobot, rest: DynamicState, jacobian: np.ndarray, dof: int, size: float,
                  *, duration: float = 0.5, h: float = 0.002, servo_speed: float = np.radians(600.0)) -> StepResponse:
    """Step the goal of effector DOF ``dof`` by ``size`` [mm or rad] from the equilibrium ``rest``:
    the motors move by ``J^-1`` of the step (``jacobian`` (6, na) the direct Jacobian at rest,
    least squares when it is not square) at the servos' speed ``servo_speed`` [rad/s] (the
    datasheets' 0.1 s / 60 deg: 600 deg/s), then hold; the rod's motion over ``duration`` [s]
    in steps of ``h``, against the quasi-static pose at the final angles."""
    if not 0 <= dof < 6:
        raise ConfigError(f"dof: {dof!r}: allowed 0 to 5 (x, y, z, rx, ry, rz)")
    goal = np.zeros(6)
    goal[dof] = size
    dq = np.linalg.lstsq(jacobian, goal, rcond=None)[0]
    a0 = rest.state.angles
    ramp = max(float(np.abs(dq).max()) / servo_speed, h)
    times = np.array([0.0, ramp, max(duration, 2 * ramp)])
    angles = np.array([a0, a0 + dq, a0 + dq])
    target = quasi_static_path(qs, rest, times[1:], angles[1:]).pose[-1]
    run, _ = play(dyn, rest, times, angles, h)
    y = run.pose[:, dof]
    return StepResponse(dof, goal, dq, run, target, step_metrics(run.t, y, float(y[0]), float(target[dof])))


def fastest_playback(dyn: DynamicRobot, start: DynamicState, reference: Playback, times, angles, h: float, *,
                     tol_mm: float = 1.0, speeds=(1.0, 2.0, 4.0, 8.0, 16.0), bisections: int = 2) -> dict:
    """The largest playback speed-up whose rod position stays within ``tol_mm`` [mm] of the
    quasi-static ``reference`` (its samples at the program's times) all along: the ``speeds``
    tried in order until one fails, then ``bisections`` halvings of the last interval.
    Returns {speed, gap_mm (at that speed), tried: [(speed, gap_mm, gap_deg)], duration_s}."""
    tried = []

    def gap(s):
        run, _ = play(dyn, start, times, angles, h / s if s > 1 else h, speed=s)
        ref = Playback(reference.t / s, *(getattr(reference, k) for k in ("angles", "p", "R", "torques", "newton",
                                                                          "tangents")))
        mm, deg = pose_gap(run, ref)
        tried.append((float(s), float(mm.max()), float(deg.max())))
        return float(mm.max())

    best, bad = None, None
    for s in speeds:
        if gap(s) <= tol_mm:
            best = s
        else:
            bad = s
            break
    if best is not None and bad is not None:
        for _ in range(bisections):
            mid = float(np.sqrt(best * bad))
            if gap(mid) <= tol_mm:
                best = mid
            else:
                bad = mid
    ok = [x for x in tried if best is not None and x[0] == best]
    duration = float(np.asarray(times, float)[-1]) / best if best else None
    return {"speed": best, "gap_mm": ok[0][1] if ok else None, "tried": tried, "duration_s": duration,
            "tol_mm": tol_mm}
