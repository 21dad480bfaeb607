"""One material's robot on the page: the reduced model inside its training box, the full one outside.

A reduced-order robot (:class:`~metasheet.rom.model.ReducedRobot`) is trained on motor
angles in a box; outside it the model extrapolates, and the page must never show that as an
answer. :class:`RobotModels` keeps the reduced model's controller and, built on first need,
the full model's, and solves on the reduced one only where it was trained:

* a forward solve (motor sliders, the maze, reset) at angles inside the box runs on the
  reduced model, outside it on the full one (:meth:`RobotModels.solve`);
* a control step that would take the motors out of the box is undone before anything is
  evaluated there (a step only adds the QP's increments to the state), and the goal is
  driven on from the last state in the box by the full model (:meth:`RobotModels.step_left_box`,
  used by the session's goal loop);
* while the full model drives, :attr:`RobotModels.note` says so (the page's flag); a later
  motor command inside the box, or a goal whose start is :data:`RETURN_MARGIN` inside it
  (a margin: a drag along the box's edge does not switch models at every goal), goes back
  to the reduced model.

The state changes model through the same full-mesh positions: reduced to full by
:meth:`~metasheet.rom.model.ReducedRobot.full_state`, full to reduced by projection on
the basis (:meth:`~metasheet.rom.model.ReducedRobot.project`), each followed by an
equilibrium solve on the model it enters. A full robot alone (``--model full``, silicone)
is the trivial case: one controller, never a switch.
"""

from __future__ import annotations

import time

import numpy as np

from ..robot.equilibrium import solve_equilibrium
from ..robot.inverse import InverseController
from ..robot.inverse_settings import InverseSettings

#: the page's flag while the full model stands in for the reduced one
OUTSIDE_BOX = "outside the reduced model's training box: the full model solves here"
#: a goal goes back from the full to the reduced model when its start is this far inside the box [rad]
RETURN_MARGIN = np.radians(1.0)


def is_reduced(robot) -> bool:
    return hasattr(robot, "basis") and hasattr(robot, "full")


def positions(robot, state) -> np.ndarray:
    """(n, 3) [mm] every node of the full mesh at ``state`` (a reduced or a full state)."""
    x = getattr(state, "x", None)
    return np.asarray(x) if x is not None else robot.positions(state)


class RobotModels:
    """The controllers of one material's robot (see the module docstring).

    Parameters
    ----------
    robot : a full robot or a :class:`~metasheet.rom.model.ReducedRobot`.
    info : its :class:`.loading.RobotInfo`. settings : the inverse loop's settings.

    Attributes
    ----------
    reduced : the reduced robot or None. full : the full robot. active : "reduced" / "full",
    the model the current state is on. rest : the first rest equilibrium. note : the page's
    flag ("" while the model asked for solves).
    """

    def __init__(self, robot, info, settings: InverseSettings):
        self.info, self.settings = info, settings
        self.reduced = robot if is_reduced(robot) else None
        self.full = robot.full if self.reduced is not None else robot
        self._ctrl: dict[str, InverseController] = {}
        self.active = "reduced" if self.reduced is not None else "full"
        ctrl = self._controller(self.active)  # solves the rest equilibrium
        ctrl.refresh()  # the Jacobian at rest: singular values from the start
        self.rest = ctrl.state
        self.note = ""

    # -- the active model ---------------------------------------------------------------
    @property
    def robot(self):
        return self.reduced if self.active == "reduced" else self.full

    @property
    def ctrl(self) -> InverseController:
        return self._ctrl[self.active]

    @property
    def refreshes(self) -> int:
        """Fresh linearisations over both models."""
        return sum(c.refreshes for c in self._ctrl.values())

    def positions(self, state=None) -> np.ndarray:
        """(n, 3) [mm] the full mesh's nodes at ``state`` (default: the current state)."""
        return positions(self.robot, self.ctrl.state if state is None else state)

    def in_box(self, angles) -> bool:
        """Whether the reduced model may solve at ``angles`` (na,) [rad] (False without one)."""
        return self.reduced is not None and self.reduced.in_box(angles)

    def _controller(self, model: str) -> InverseController:
        if model not in self._ctrl:
            robot = self.reduced if model == "reduced" else self.full
            state = None
            if self._ctrl:  # built later: start from the current state carried over
                state = self._carried(model, self.ctrl.state)
                state = solve_equilibrium(robot, state.angles, state=state, tol=self.settings.eq_tol).state
            self._ctrl[model] = InverseController(robot, state, settings=self.settings)
        return self._ctrl[model]

    def _carried(self, model: str, state):
        """``state`` of the active model as a start state of ``model`` (same node positions)."""
        if model == self.active:
            return state
        if model == "full":
            return self.reduced.full_state(state)
        return self.reduced.project(state)

    # -- solves -------------------------------------------------------------------------
    def may_return(self) -> bool:
        """Whether a goal starting now should go back to the reduced model: the full one is
        active and the motors are :data:`RETURN_MARGIN` inside the box."""
        return (self.active == "full" and self.reduced is not None
                and self.reduced.in_box(self.ctrl.state.angles, tol=-RETURN_MARGIN))

    def model_for(self, angles) -> str:
        """The model that solves at motor ``angles`` [rad]: reduced inside its box, else full."""
        return "reduced" if self.in_box(angles) else "full"

    def enter(self, model: str) -> float:
        """Make ``model`` the active one at the current motor angles (an equilibrium solve on
        it from the carried-over state); [ms] spent (0 when it already is)."""
        if model == self.active:
            return 0.0
        t0 = time.perf_counter()
        fresh = model not in self._ctrl
        ctrl = self._controller(model)
        if not fresh:
            start = self._carried(model, self.ctrl.state)
            eq = solve_equilibrium(ctrl.robot, start.angles, state=start, linearizer=ctrl.linearizer,
                                   tol=self.settings.eq_tol, reuse_ratio=self.settings.polish_rate)
            ctrl.state = eq.state  # set from outside the loop: its next step takes a fresh tangent
        self.active = model
        self.note = OUTSIDE_BOX if model == "full" and self.reduced is not None else ""
        return 1e3 * (time.perf_counter() - t0)

    def solve(self, angles) -> float:
        """Forward model: the equilibrium at ``angles`` (na,) [rad] (clipped to the stroke) on
        the model :meth:`model_for` names, from the current state; [ms]."""
        lo, hi = self.full.angle_min, self.full.angle_max
        angles = np.clip(np.asarray(angles, float), lo, hi)
        t0 = time.perf_counter()
        model = self.model_for(angles)
        fresh = model not in self._ctrl
        ctrl = self._controller(model)  # built now: already at the current angles
        start = ctrl.state if (model == self.active or fresh) else self._carried(model, self.ctrl.state)
        s = self.settings
        eq = solve_equilibrium(ctrl.robot, angles, state=start, linearizer=ctrl.linearizer, tol=s.eq_tol,
                               reuse_ratio=s.polish_rate)
        ctrl.state = eq.state  # from outside the loop: its next step takes a fresh tangent
        self.active = model
        self.note = OUTSIDE_BOX if model == "full" and self.reduced is not None else ""
        return 1e3 * (time.perf_counter() - t0)

    def step_left_box(self, before) -> bool:
        """After a control step from ``before`` on the reduced model: when it took the motors
        out of the training box, undo it (back to ``before``, nothing was evaluated at the new
        angles) and make the full model the active one there; True when it did."""
        if self.active != "reduced" or self.reduced.in_box(self.ctrl.state.angles):
            return False
        self.ctrl.state = before
        self.enter("full")
        return True

    def restore(self, state) -> None:
        """Put back ``state`` (a snapshot's: reduced or full) as the current state."""
        model = "reduced" if (self.reduced is not None and not hasattr(state, "x")) else "full"
        self._controller(model).state = state
        self.active = model
        self.note = OUTSIDE_BOX if model == "full" and self.reduced is not None else ""


def goto(robot, pose, settings: InverseSettings | None = None):
    """``metasheet robot goto``: :meth:`InverseController.goto` from rest to ``pose`` (6,)
    (x, y, z [mm], rotation vector [deg]) on ``robot``; returns (InverseResult, note).

    On a reduced robot the loop runs with the motor limits cut to the training box, so it
    never evaluates the model outside it (the equilibrium surface's limits are its box
    already); when it does not reach the goal and ends with a motor on a bound of the box
    that is not the stroke's (the goal needs angles outside the box), the full model solves
    the goal from its own rest, and ``note`` says so (:data:`OUTSIDE_BOX`); otherwise
    ``note`` is "".
    """
    s = settings if settings is not None else InverseSettings()
    full = getattr(robot, "full", None)
    if full is None:
        return InverseController(robot, settings=s).goto(pose), ""
    if is_reduced(robot):
        b = robot.basis
        lo, hi = np.maximum(robot.angle_min, b.box_lo), np.minimum(robot.angle_max, b.box_hi)
        boxed = robot.with_limits(lo, hi)
    else:
        lo, hi, boxed = robot.angle_min, robot.angle_max, robot
    res = InverseController(boxed, settings=s).goto(pose)
    if res.reached:
        return res, ""
    a, tol = np.radians(res.angles_deg), np.radians(0.01)
    pressed = ((a <= lo + tol) & (lo > full.angle_min)) | ((a >= hi - tol) & (hi < full.angle_max))
    if not np.any(pressed):
        return res, ""
    return InverseController(full, settings=s).goto(pose), OUTSIDE_BOX
