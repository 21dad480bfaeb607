"""The real servos: motor angles as hobby-servo pulse widths, and the check a program must pass
before it is sent to them (``metasheet robot path --dry-run``).

Angles are metasheet's (:mod:`metasheet.robot.robots`): 0 deg is a horizontal horn reaching
inwards, towards the sheet's centre, 90 deg a vertical one. A hobby servo takes a pulse every
20 ms whose width sets its angle, linearly over its range. :class:`ServoPulse` states that line
by its two ends in metasheet's convention: by default a common 180-degree servo, 500 us at
0 deg and 2500 us at 180 deg. That is a typical figure, not a datasheet's promise: the SG90 and
MG90S datasheets give 500-2400 us, and each servo differs by tens of microseconds, so calibrate
(the pulses that put the horn horizontal and vertical) before driving the sheets. A servo mounted
mirrored (its shaft facing the other way) turns the other way for the same pulse: its
``reversed`` flag mirrors the pulse about the middle of the range.

The check (:func:`check_program`) flags, per sample, a motor beyond the robot's stroke
(``robot.angle_min``/``angle_max``, the paper's 0-90 deg) and a motor that must turn faster
than the servo can: the speed from the previous sample, ``|dq| / dt``, against
:data:`MAX_SPEED_DEG_S`, the SG90 / MG90S datasheets' typical no-load speed, 0.1 s per 60 deg at
4.8 V (600 deg/s); under the sheets' load a servo is slower, so give yours (``--max-speed``).
The first sample has no previous one: the servos must be brought to it before the program starts.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, check_range

#: The SG90 / MG90S datasheets' typical operating speed: 0.1 s / 60 deg at 4.8 V, no load [deg/s].
MAX_SPEED_DEG_S = 600.0
#: A motor this far past a stroke end counts as beyond it [deg]: program.csv keeps 4 decimals.
STROKE_SLACK_DEG = 1e-3
#: Motors of the 6-DOF robot: sheet A's 0-2, sheet B's 3-5.
N_MOTORS = 6


def motors(robot) -> list[dict]:
    """Which motor is which: sheet A's 0-2, sheet B's 3-5, each servo's pivot, axis and rest angle."""
    return [{"motor": k, **sv} for k, sv in enumerate(robot.info.get("servos", []))]


def stroke_deg(robot) -> tuple[np.ndarray, np.ndarray]:
    """(lo (6,), hi (6,)) [deg] the motors' stroke (the robot's ``angle_min`` / ``angle_max``)."""
    return np.degrees(np.asarray(robot.angle_min, float)), np.degrees(np.asarray(robot.angle_max, float))


@dataclass(frozen=True)
class ServoPulse:
    """The linear map from a motor angle [deg] (metasheet's convention) to a pulse width [us].

    ``pulse_min_us`` is sent for ``angle_at_min_deg``, ``pulse_max_us`` for ``angle_at_max_deg``;
    ``reversed`` : one flag per motor, True for a servo mounted mirrored (its pulse mirrors about
    the middle of the range). Default: a 180-degree hobby servo, 500-2500 us over 0-180 deg.
    """

    pulse_min_us: float = 500.0
    pulse_max_us: float = 2500.0
    angle_at_min_deg: float = 0.0
    angle_at_max_deg: float = 180.0
    reversed: tuple[bool, ...] = field(default=(False,) * N_MOTORS)

    def __post_init__(self):
        check_range("pulse_min_us", self.pulse_min_us, 0.0, 20000.0, lo_open=True)
        check_range("pulse_max_us", self.pulse_max_us, self.pulse_min_us, 20000.0, lo_open=True)
        check_range("angle_at_min_deg", self.angle_at_min_deg, -360.0, 360.0)
        check_range("angle_at_max_deg", self.angle_at_max_deg, -360.0, 360.0)
        if self.angle_at_max_deg == self.angle_at_min_deg:
            raise ConfigError(f"angle_at_max_deg: {self.angle_at_max_deg!r}: must differ from angle_at_min_deg")
        if len(self.reversed) != N_MOTORS:
            raise ConfigError(f"reversed: {len(self.reversed)} flags given: expected {N_MOTORS}, one per motor")
        object.__setattr__(self, "reversed", tuple(bool(r) for r in self.reversed))

    @classmethod
    def with_reversed(cls, motors, **kw) -> "ServoPulse":
        """The map with the servos ``motors`` (indices 0-5) reversed."""
        flags = [False] * N_MOTORS
        for m in motors:
            check_range("reversed motor", m, 0, N_MOTORS - 1)
            flags[int(m)] = True
        return cls(reversed=tuple(flags), **kw)

    def pulse_us(self, angles_deg) -> np.ndarray:
        """(T, 6) pulse widths [us] of motor angles (T, 6) [deg]; angles beyond the stated range
        give pulses beyond it (the check flags them, nothing is clipped)."""
        a = np.asarray(angles_deg, float)
        if a.ndim != 2 or a.shape[1] != N_MOTORS:
            raise ConfigError(f"angles_deg: shape is {a.shape} and should be (T, {N_MOTORS})")
        f = (a - self.angle_at_min_deg) / (self.angle_at_max_deg - self.angle_at_min_deg)
        f = np.where(np.asarray(self.reversed), 1.0 - f, f)
        return self.pulse_min_us + f * (self.pulse_max_us - self.pulse_min_us)

    def to_dict(self) -> dict:
        return {"pulse_min_us": self.pulse_min_us, "pulse_max_us": self.pulse_max_us,
                "angle_at_min_deg": self.angle_at_min_deg, "angle_at_max_deg": self.angle_at_max_deg,
                "reversed": list(self.reversed),
                "formula": "pulse = pulse_min + (angle - angle_at_min) / (angle_at_max - angle_at_min) * "
                           "(pulse_max - pulse_min); a reversed servo: pulse_min + pulse_max - pulse",
                "note": "a typical 180-degree hobby servo; SG90 / MG90S datasheets give 500-2400 us: "
                        "calibrate each servo (the pulses of a horizontal and a vertical horn)"}


@dataclass(frozen=True)
class ProgramCheck:
    """The dry run's verdict on a program of T samples.

    beyond : (T, 6) bool, a motor past the stroke (by more than :data:`STROKE_SLACK_DEG`).
    too_fast : (T, 6) bool, a motor faster than ``max_speed`` [deg/s] since the previous sample.
    speed : (T, 6) [deg/s] each motor's speed since the previous sample (0 for the first).
    stroke : (lo (6,), hi (6,)) [deg]; max_speed : [deg/s].
    """

    beyond: np.ndarray
    too_fast: np.ndarray
    speed: np.ndarray
    stroke: tuple
    max_speed: float

    @property
    def flagged(self) -> np.ndarray:
        """(T,) bool: the samples with a motor beyond the stroke or too fast."""
        return self.beyond.any(axis=1) | self.too_fast.any(axis=1)

    @property
    def ok(self) -> bool:
        return not bool(self.flagged.any())

    def lines(self, times, angles_deg) -> list[str]:
        """One line per flagged sample, naming each motor and what is wrong."""
        lo, hi = self.stroke
        out = []
        for i in np.flatnonzero(self.flagged):
            what = [f"motor {k} at {angles_deg[i, k]:.3f} deg, beyond the stroke [{lo[k]:g}, {hi[k]:g}] deg"
                    for k in np.flatnonzero(self.beyond[i])]
            what += [f"motor {k} at {self.speed[i, k]:.1f} deg/s, faster than {self.max_speed:g} deg/s"
                     for k in np.flatnonzero(self.too_fast[i])]
            out.append(f"sample {i} (t = {times[i]:.3f} s): " + "; ".join(what))
        return out

    def summary(self) -> dict:
        return {"samples": int(len(self.beyond)), "flagged": int(self.flagged.sum()),
                "beyond_stroke": int(self.beyond.any(axis=1).sum()), "too_fast": int(self.too_fast.any(axis=1).sum()),
                "max_speed_deg_s": float(self.speed.max()) if self.speed.size else 0.0,
                "speed_limit_deg_s": self.max_speed, "stroke_deg": [list(map(float, s)) for s in self.stroke]}


def check_program(angles_deg, times, stroke_lo, stroke_hi, max_speed_deg_s: float = MAX_SPEED_DEG_S) -> ProgramCheck:
    """Check motor angles (T, 6) [deg] at ``times`` (T,) [s] against the stroke ``stroke_lo``,
    ``stroke_hi`` (scalars or (6,) [deg]) and the speed limit [deg/s]; see the module docstring."""
    a, t = np.asarray(angles_deg, float), np.asarray(times, float)
    if a.ndim != 2 or a.shape[1] != N_MOTORS or len(a) == 0:
        raise ConfigError(f"angles_deg: shape is {a.shape} and should be (T, {N_MOTORS}) with T >= 1")
    if t.shape != (len(a),):
        raise ConfigError(f"times: shape is {t.shape} and should be ({len(a)},)")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(t))):
        raise ConfigError("angles_deg, times: expected finite numbers")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise ConfigError(f"times: sample {i} at {t[i]:g} s does not follow sample {i - 1} at {t[i - 1]:g} s: "
                          "times must increase")
    check_range("max_speed_deg_s", max_speed_deg_s, 0.0, None, lo_open=True)
    lo = np.broadcast_to(np.asarray(stroke_lo, float), (N_MOTORS,))
    hi = np.broadcast_to(np.asarray(stroke_hi, float), (N_MOTORS,))
    if np.any(hi <= lo):
        raise ConfigError(f"stroke: [{lo.tolist()}, {hi.tolist()}] deg: each upper end must exceed its lower one")
    beyond = (a < lo - STROKE_SLACK_DEG) | (a > hi + STROKE_SLACK_DEG)
    speed = np.zeros_like(a)
    speed[1:] = np.abs(np.diff(a, axis=0)) / dt[:, None]
    return ProgramCheck(beyond, speed > max_speed_deg_s, speed, (lo.copy(), hi.copy()), float(max_speed_deg_s))
