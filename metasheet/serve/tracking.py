"""One goal driven step by step: :meth:`InverseController.goto`'s loop, one step per call.

The page must show every control step (the robot moving to the goal) and drop a goal as
soon as a newer one arrives, so it cannot call ``goto``, which returns only at the end.
:class:`GoalRun` is the same loop cut into steps: each :meth:`GoalRun.advance` does what one
iteration of ``goto`` does (the reached test on a certified equilibrium, the stall test, one
control step of eq. 8), and the run ends as ``goto`` ends: "reached", or "stalled" /
"max_steps" on the certified closest pose. Started from the same state with the same
settings it takes the same steps and ends on the same pose as ``goto``
(tests/test_serve.py checks it).
"""

from __future__ import annotations

import reprlib
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from ..robot.qp import pose_error, weighted_norm
from ..mechanics.rotations import rotation_matrix, rotation_vector

#: :meth:`GoalRun.track` takes no step when the pose error is below this share of the tolerances
TRACK_FRACTION = 0.05


def within(e, settings) -> bool:
    """Pose error ``e`` (6,) [mm, rad] inside ``pos_tol`` [mm] and ``rot_tol_deg`` [deg]
    (the reached test of :meth:`InverseController.goto`)."""
    return bool(np.linalg.norm(e[:3]) <= settings.pos_tol
                and np.degrees(np.linalg.norm(e[3:])) <= settings.rot_tol_deg)


def check_pose(pose, name: str = "goal") -> np.ndarray:
    """``pose`` as a (6,) float array (x, y, z [mm], rotation vector [deg]), or ConfigError."""
    try:
        p = np.asarray(pose, dtype=float).reshape(-1)
    except (TypeError, ValueError):  # text, None, ragged lists: from a page, a malformed message
        p = np.zeros(0)
    if p.shape != (6,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"{name}: {reprlib.repr(pose)}: expected 6 finite numbers X Y Z [mm] RX RY RZ [deg]")
    return p


#: the pose components in order, with their units
POSE_NAMES = ("X [mm]", "Y [mm]", "Z [mm]", "RX [deg]", "RY [deg]", "RZ [deg]")
#: a goal component beyond +-these is refused [mm] x 3, [deg] x 3: 1 m is far beyond any reach
#: of the robot (rod 80 mm; the stroke moves its centre by tens of mm) and a turn bounds any
#: rotation vector's components (180 deg suffices): a larger value is a typo or a malformed
#: message, and would only send the solver far out for an "unreachable"
GOAL_LIMITS = (1000.0, 1000.0, 1000.0, 360.0, 360.0, 360.0)


def check_goal(pose) -> np.ndarray:
    """A goal from the page or a script: :func:`check_pose`, each component within
    :data:`GOAL_LIMITS` (the message names the component and the range), or ConfigError."""
    p = check_pose(pose)
    for name, v, limit in zip(POSE_NAMES, p, GOAL_LIMITS):
        check_range(f"goal {name}", float(v), -limit, limit)
    return p


def pose_of(state) -> np.ndarray:
    """(6,) effector pose of ``state``: position [mm] and rotation vector [deg]."""
    return np.concatenate([state.p, np.degrees(rotation_vector(state.R))])


@dataclass(frozen=True)
class Progress:
    """After one :meth:`GoalRun.advance`: ``done`` (the run ended), ``status`` ("moving", or
    at the end "reached" / "stalled" / "max_steps"), the pose error [mm], [deg] of the
    controller's state and ``step_time`` [s] of the control step taken (0 when none was)."""

    done: bool
    status: str
    pos_error: float
    rot_error: float
    step_time: float


class GoalRun:
    """Drive ``ctrl`` (an :class:`~metasheet.robot.inverse.InverseController`) to ``pose``
    (6,) = (x, y, z [mm], rotation vector [deg]) from its current state, one step per
    :meth:`advance`, with ``settings`` (default: the controller's)."""

    def __init__(self, ctrl, pose, settings=None, certify_settings=None):
        self.ctrl = ctrl
        self.settings = settings if settings is not None else ctrl.settings
        self.certify_settings = certify_settings if certify_settings is not None else self.settings
        self.goal = check_pose(pose)
        self.goal_p, self.goal_R = self.goal[:3], rotation_matrix(np.radians(self.goal[3:]))
        self.start = ctrl.state
        self.best, self.best_state, self.since = np.inf, ctrl.state, 0
        self.steps = 0
        self.status = "moving"
        self.step_times: list[float] = []

    @property
    def done(self) -> bool:
        return self.status != "moving"

    def near(self) -> bool:
        """Whether the controller's state is within the tolerances of the goal (the next
        :meth:`advance` then certifies it instead of taking a control step)."""
        return within(self._errors(self.ctrl.state)[0], self.settings)

    def _errors(self, state) -> tuple[np.ndarray, float, float]:
        e = pose_error(state.p, state.R, self.goal_p, self.goal_R)
        return e, float(np.linalg.norm(e[:3])), float(np.degrees(np.linalg.norm(e[3:])))

    def advance(self) -> Progress:
        """One iteration of ``goto``'s loop; at the end, the certified final state."""
        if self.done:
            raise ConfigError("GoalRun.advance: the run has ended; start a new one")
        c, s = self.ctrl, self.settings
        if self.steps >= s.max_steps:  # goto's loop ends here, without another test
            return self._finish("max_steps")
        e, _, _ = self._errors(c.state)
        if within(e, s):  # confirm on a certified equilibrium, not on the one-Newton-step state
            c.certify(self.start, settings=self.certify_settings)
            e, _, _ = self._errors(c.state)
            if within(e, s):
                return self._finish("reached", certified=True)
        err = weighted_norm(e, s.rot_weight)
        if err < self.best * (1.0 - 1e-3):
            self.best, self.best_state, self.since = err, c.state, 0
        else:
            self.since += 1
            if self.since >= s.stall_steps:
                return self._finish("stalled")
        return self._step()

    def track(self) -> Progress | None:
        """One control step towards the goal although the state may already be within the
        tolerances (no reached test, no certificate): while a drag streams goals, each new
        goal moves the robot, so it follows the pointer smoothly instead of in jumps of the
        tolerance. None when the pose error is below :data:`TRACK_FRACTION` of the
        tolerances (nothing to follow)."""
        if self.done:
            raise ConfigError("GoalRun.track: the run has ended; start a new one")
        _, pe, re = self._errors(self.ctrl.state)
        s = self.settings
        if pe <= TRACK_FRACTION * s.pos_tol and re <= TRACK_FRACTION * s.rot_tol_deg:
            return None
        return self._step()

    def _step(self) -> Progress:
        c, s = self.ctrl, self.settings
        info = c.step(self.goal_p, self.goal_R, settings=s)
        self.steps += 1
        self.step_times.append(info.time)
        _, pe, re = self._errors(c.state)
        return Progress(False, "moving", pe, re, info.time)

    def _finish(self, status: str, certified: bool = False) -> Progress:
        c, s = self.ctrl, self.settings
        if not certified:
            if status == "stalled":
                c.state = self.best_state
            c.certify(self.start, settings=self.certify_settings)
        e, pe, re = self._errors(c.state)
        # as goto: reached only when the certified pose is within the tolerances
        self.status = "reached" if within(e, s) else ("stalled" if status == "reached" else status)
        return Progress(True, self.status, pe, re, 0.0)
