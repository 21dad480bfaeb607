"""Inverse model (paper eq. 8): a QP on the motor increments, in a SOFA-like control loop.

Each control step, at the current (nearly equilibrated) state:

1. linearise: tangent, condensation, ``J = W_ea W_aa^-1`` (eq. 6-7) and the effector motion
   ``dq_e^0`` that the pending equilibrium correction alone would cause;
2. solve the QP

       min_dq  1/2 |D (J dq - e)|^2 + 1/2 eps |dq|^2
       s.t.    max(q_min - q, -dq_max) <= dq <= min(q_max - q, dq_max)

   with ``e = (p* - p, log(R* R^T)) - dq_e^0`` the pose error (mm, rad) and
   ``D = diag(1, 1, 1, w, w, w)``: ``w = rot_weight`` [mm/rad] makes 1 rad of orientation
   error cost as much as ``w`` mm of position error (default 50 mm/rad, i.e. 1 degree ~
   0.87 mm, about the sheet's arm length). ``eps = regularization * max eig(J^T D^2 J)``
   keeps the problem strictly convex when J loses rank (5 controllable DOF with silicone);
3. move the motors by dq and re-equilibrate with one Newton step from the same
   linearisation (the predictor of :func:`.statics.Linearization.newton_step`).

This is eq. (8) with the change of variable ``dq_a = W_aa dlambda``: the same minimiser, but
the motor limits become simple bounds, which the dense solvers (daqp, quadprog, proxqp via
qpsolvers) handle directly.

Real time (issue 6): a fresh linearisation (tangent, factorisation, Schur complement) costs
several chord steps, so the controller keeps it across control steps and only re-evaluates
the forces and one solve with the cached factor (a chord / modified-Newton step). It is
never trusted blindly; a fresh one is taken when any of these holds (defaults in brackets):

* it is ``refactor_every`` steps old [20];
* the motors moved more than ``refresh_angle_deg`` from where it was taken [8 deg], or the
  state was set from outside (another goal, a reset);
* the pending equilibrium correction of the effector, ``dq_e^0`` (mm, with rotations
  weighted by ``rot_weight``), exceeds ``drift_tol * pos_tol`` [0.5 * 0.1 mm]: the chord
  iterate is then too far from equilibrium for the pose the QP sees;
* the reduced residual exceeds ``chord_tol`` times the force scale [1.0] (divergence guard).

The sparse solver is SuperLU by default: CHOLMOD of the symmetric part (``linear_solver=
"cholmod"``) factorises twice as fast, but on the deformed anisotropic tangent it is a poor
Newton matrix (pending corrections ~0.2 mm, a refresh nearly every step) and its exact
refinement often falls back to SuperLU; ``benchmarks/bench_robot.py`` prints both.

The loop stops "reached" when the position error is below
``pos_tol`` and the rotation error below ``rot_tol``, "stalled" when the weighted error has
not improved for ``stall_steps`` steps (an unreachable goal: the closest pose found is
returned, never an exception), or "max_steps".

The reported pose is always an equilibrium at the final motor angles within a stated
residual tolerance: the reduced residual (the norm of :attr:`.statics.Linearization.
residual_norm`) at most ``eq_tol`` times the force scale of :func:`.statics.solve_equilibrium`.
:meth:`InverseController.certify` gets there with the loop's own kept tangent: chord
(modified-Newton) corrections at fixed motor angles, each judged on the true residual, at
most ``polish_iters`` of them (a few ms each), and only when they fail with the full Newton
solve. The result records the residual reached and which path certified it. On the
6-DOF robot a relative residual of 1e-4 already puts the effector within ~2e-6 mm of the
1e-8 solution (and the loop's own one-Newton-step state within ~0.003 mm); the default
``eq_tol = 1e-5`` costs about one more correction (tests/test_robot_realtime.py checks the
certified pose against a 1e-10 solve).

Continuation (a study reaching goal after goal, or trying small moves from one point): a
state produced by this controller (a control step or a certification; the last
``OWN_STATES`` are remembered) may be set back as ``state`` without dropping the kept
tangent: the refresh tests above (angle moved since the tangent, residual, drift) still
run on it. Any other state set from outside forces a fresh linearisation.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import numpy as np
import qpsolvers

from ..errors import ConfigError, ConvergenceError, check_range
from .kinematics import jacobian_from_schur
from .linsolve import SOLVERS as LINEAR_SOLVERS
from .linsolve import resolve
from .rigid import rotation_matrix, rotation_vector
from .statics import Linearizer, RobotState, _reference, apply_step, solve_equilibrium

SOLVERS = ("daqp", "quadprog", "proxqp")  # QP solvers; sparse ones: LINEAR_SOLVERS
OWN_STATES = 16  # states a controller remembers as its own (continuation without a refresh)


@dataclass(frozen=True)
class InverseSettings:
    """Settings of the inverse loop (units in brackets)."""

    rot_weight: float = 50.0  # [mm/rad]
    regularization: float = 1e-6  # [-], relative to the largest eigenvalue of J^T D^2 J
    max_step_deg: float = 5.0  # [deg] per motor and control step
    pos_tol: float = 0.1  # [mm]
    rot_tol_deg: float = 0.2  # [deg]
    max_steps: int = 200
    stall_steps: int = 15
    solver: str = "daqp"
    refactor_every: int = 20  # 1: a fresh tangent + factor every step; n: keep them <= n steps
    chord_tol: float = 1.0  # [-] refresh a kept tangent when residual > chord_tol * force scale
    refresh_angle_deg: float = 8.0  # [deg] refresh when a motor moved this far since the tangent
    drift_tol: float = 0.5  # [-] refresh when the pending correction |dq_e0| > drift_tol * pos_tol
    linear_solver: str = "superlu"  # "cholmod" / "auto" (CHOLMOD if installed): slower here, see above
    eq_tol: float = 1e-5  # [-] reported pose: residual <= eq_tol * force scale (see the module doc)
    polish_iters: int = 20  # corrections tried before the full Newton solve certifies instead
    # a kept tangent must cut the residual by this factor per correction, else a fresh one; a
    # fresh tangent costs ~20 chord corrections on the paper's mesh (~200 vs ~9 ms), so slow
    # chord contraction (0.4-0.6 on a tangent a few steps old) is still the cheaper way
    polish_rate: float = 0.7

    def __post_init__(self):
        check_range("rot_weight", self.rot_weight, 0.0, None, lo_open=True)
        check_range("regularization", self.regularization, 0.0, 1.0)
        check_range("max_step_deg", self.max_step_deg, 0.0, 90.0, lo_open=True)
        check_range("pos_tol", self.pos_tol, 0.0, None, lo_open=True)
        check_range("rot_tol_deg", self.rot_tol_deg, 0.0, None, lo_open=True)
        check_range("max_steps", self.max_steps, 1, 100000)
        check_range("stall_steps", self.stall_steps, 1, 100000)
        check_range("refactor_every", self.refactor_every, 1, 1000)
        check_range("chord_tol", self.chord_tol, 0.0, 10.0, lo_open=True)
        check_range("refresh_angle_deg", self.refresh_angle_deg, 0.0, 90.0, lo_open=True)
        check_range("drift_tol", self.drift_tol, 0.0, 100.0, lo_open=True)
        check_range("eq_tol", self.eq_tol, 0.0, 1e-2, lo_open=True)
        check_range("polish_iters", self.polish_iters, 0, 1000)
        check_range("polish_rate", self.polish_rate, 0.0, 1.0, lo_open=True, hi_open=True)
        resolve(self.linear_solver)  # ConfigError naming linear_solver if unknown / not installed
        if self.solver not in SOLVERS:
            raise ConfigError(f"solver: {self.solver!r}: allowed {SOLVERS}")


@dataclass(frozen=True)
class StepInfo:
    """One control step: motor increment [rad], residual before it [N], QP status, time [s]."""

    dq_a: np.ndarray
    residual: float
    error: float
    qp_ok: bool
    time: float
    fresh: bool = True  # whether this step took a fresh linearisation


@dataclass(frozen=True)
class InverseResult:
    """Outcome of :meth:`InverseController.goto`.

    Attributes
    ----------
    status : "reached", "stalled" or "max_steps".
    state : equilibrium at the final motor angles.
    angles_deg : (na,) final motor angles [deg].
    pose : (6,) final effector pose (mm, deg: rotation vector).
    goal : (6,) the goal (mm, deg).
    pos_error : [mm]. rot_error : [deg].
    steps : control steps taken. step_times : [s] each. residuals : [N] before each step.
    residual : reduced residual at ``state`` [N]; reference : the force scale [N] it is
        relative to (``residual <= eq_tol * reference`` certifies ``state`` as an equilibrium).
    certified : "chord" (kept-tangent corrections) or "newton" (full solve) certified it.
    """

    status: str
    state: RobotState
    angles_deg: np.ndarray
    pose: np.ndarray
    goal: np.ndarray
    pos_error: float
    rot_error: float
    steps: int
    step_times: tuple
    residuals: tuple
    residual: float = float("nan")
    reference: float = float("nan")
    certified: str = ""

    @property
    def reached(self) -> bool:
        return self.status == "reached"

    def to_dict(self) -> dict:
        return {"status": self.status, "angles_deg": self.angles_deg.tolist(), "pose": self.pose.tolist(),
                "goal": self.goal.tolist(), "pos_error_mm": self.pos_error, "rot_error_deg": self.rot_error,
                "steps": self.steps, "median_step_ms": 1e3 * float(np.median(self.step_times or [0.0])),
                "residual_N": self.residual, "residual_rel": self.residual / max(self.reference, 1e-300),
                "certified": self.certified}


def pose_error(p, R, goal_p, goal_R) -> np.ndarray:
    """(6,) error (mm, rad) from (p, R) to the goal, rotation as a spatial rotation vector."""
    return np.concatenate([goal_p - p, rotation_vector(goal_R @ R.T)])


def solve_step_qp(J, e, q, q_min, q_max, settings: InverseSettings):
    """The QP of eq. (8) in motor increments; returns (dq (na,) [rad], solver_ok)."""
    D2 = np.array([1.0, 1.0, 1.0] + [settings.rot_weight**2] * 3)
    H = J.T @ (D2[:, None] * J)
    eps = settings.regularization * max(float(np.linalg.eigvalsh(H)[-1]), 1e-30)
    H = H + eps * np.eye(len(q))
    g = -J.T @ (D2 * e)
    dmax = np.radians(settings.max_step_deg)
    lb = np.maximum(q_min - q, -dmax)
    ub = np.minimum(q_max - q, dmax)
    lb = np.minimum(lb, 0.0)  # q may sit exactly on a limit
    ub = np.maximum(ub, 0.0)
    dq = qpsolvers.solve_qp(H, g, lb=lb, ub=ub, solver=settings.solver)
    if dq is None or not np.all(np.isfinite(dq)):
        return np.zeros_like(q), False
    return np.clip(dq, lb, ub), True  # clip: solver tolerances must not leave the stroke


class InverseController:
    """The control loop of eq. (8) on one robot, starting from ``state`` (an equilibrium)."""

    def __init__(self, robot, state: RobotState | None = None, settings: InverseSettings = InverseSettings()):
        self.robot = robot
        self.settings = settings
        self.linearizer = Linearizer(robot, solver=settings.linear_solver)
        self.state = state if state is not None else solve_equilibrium(
            robot, robot.coupling.rest_angles, linearizer=self.linearizer).state
        self.n_steps = 0
        self.total_steps = 0  # control steps over the controller's life (n_steps may be reset by callers)
        self.certified = {"chord": 0, "newton": 0}  # how :meth:`certify` got there, counted
        self.refreshes = 0  # fresh linearisations taken by :meth:`linearization`
        self.refresh_reasons: dict = {}  # why kept tangents were dropped: age, angle, residual, drift
        self._lin = None
        self._since = 0
        self._J = None
        self._own = deque(maxlen=OWN_STATES)  # states this controller produced: anything else was set from outside
        if state is None:
            self._own.append(self.state)  # our own rest equilibrium
        self._factor = None

    def _keep(self, lin) -> bool:
        """Whether the chord update ``lin`` (on a kept tangent) is still good enough (see module doc)."""
        s = self.settings
        moved = np.max(np.abs(self.state.angles - self._lin_angles), initial=0.0)
        why = None
        if self._since >= s.refactor_every:
            why = "age"
        elif moved > np.radians(s.refresh_angle_deg):
            why = "angle"
        elif lin.residual_norm > s.chord_tol * max(_reference(self.robot, lin), 1e-300):
            why = "residual"
        elif self._weighted(lin.newton_step(None)[0]) > s.drift_tol * s.pos_tol:
            why = "drift"
        if why is not None:
            self.refresh_reasons[why] = self.refresh_reasons.get(why, 0) + 1
        return why is None

    def linearization(self):
        """The step's linearisation: the chord update on the kept tangent, or a fresh one.

        The residual and the pending correction are evaluated at every step, never assumed.
        """
        if resolve(self.settings.linear_solver) != self.linearizer.solver_name:  # settings replaced
            self.linearizer = Linearizer(self.robot, solver=self.settings.linear_solver)
            self._lin = None
        lin = None
        # keep only our own: a state set from outside, or a factor replaced by another user of
        # the shared linearizer (solve_equilibrium, kinematics), forces a fresh linearisation
        if self._lin is not None and self.owns(self.state) and self.linearizer.factor is self._factor:
            lin = self.linearizer.update(self._lin, self.state)
            if not self._keep(lin):
                lin = None
        if lin is None:
            # modified Newton: the factor as it is (CHOLMOD: symmetric part), checked every step
            lin = self.linearizer.linearize(self.state, exact=False)
            self._J = jacobian_from_schur(lin.S)[1]
            self._since = 0
            self._lin_angles = self.state.angles.copy()
            self._factor = self.linearizer.factor
            self.refreshes += 1
        self._lin, self._last_res = lin, lin.residual_norm
        self._since += 1
        return lin

    def refresh(self, state: RobotState | None = None):
        """A fresh linearisation at ``state`` (default: the current one), kept for the next steps.

        For callers that need the tangent there anyway (a study's Jacobian at a reached point):
        the goals that follow from ``state`` then start on it instead of paying for another.
        """
        if state is not None:
            self.state = state
        self._own.append(self.state)  # linearised right here: safe to continue from
        self._lin = None
        return self.linearization()

    def owns(self, state) -> bool:
        """Whether ``state`` is one this controller produced recently (continuation keeps the tangent)."""
        return any(s is state for s in self._own)

    def _produce(self, state: RobotState) -> RobotState:
        self._own.append(state)
        self.state = state
        return state

    def _weighted(self, e) -> float:
        w = self.settings.rot_weight
        return float(np.sqrt(e[:3] @ e[:3] + w * w * (e[3:] @ e[3:])))

    def step(self, goal_p, goal_R) -> StepInfo:
        """One control step towards the goal (p* (3,) [mm], R* (3, 3)); updates ``self.state``."""
        t0 = time.perf_counter()
        s, rob = self.settings, self.robot
        lin = self.linearization()
        J = self._J
        dq_e0, _ = lin.newton_step(None)
        e = pose_error(self.state.p, self.state.R, goal_p, goal_R)
        dq, ok = solve_step_qp(J, e - dq_e0, self.state.angles, rob.angle_min, rob.angle_max, s)
        dq_e, dx_f = lin.newton_step(dq)
        self._produce(apply_step(rob, self.state, dq_e, dx_f, dq))
        self.n_steps += 1
        self.total_steps += 1
        return StepInfo(dq, lin.residual_norm, self._weighted(e), ok, time.perf_counter() - t0, lin.fresh)

    def certify(self, start: RobotState | None = None) -> tuple[RobotState, float, float, str]:
        """Bring ``self.state`` to equilibrium at its motor angles within ``eq_tol``.

        Corrections at fixed motor angles on the loop's own linearisation, each judged on the
        true residual: a kept tangent while each step cuts the residual by ``polish_rate``, a
        fresh one (a Newton step) when it does not; the full Newton solve with line search
        (:func:`.statics.solve_equilibrium`, from the current state or, failing that,
        ``start``) only when even a fresh step does not contract, or after ``polish_iters``.
        Returns (state, residual [N], force scale [N], "chord" | "newton").
        """
        s, rob = self.settings, self.robot
        prev, fresh_step = np.inf, False
        for _ in range(s.polish_iters + 1):
            lin = self.linearization()
            res, ref = lin.residual_norm, max(_reference(rob, lin), 1e-300)
            if res <= s.eq_tol * ref:
                self.certified["chord"] += 1
                return self.state, res, ref, "chord"
            if res > s.polish_rate * prev:  # the last correction did not contract enough
                if fresh_step:  # not even with a fresh tangent: needs the line search
                    break
                if not lin.fresh:
                    self._lin = None  # same state, fresh tangent: a Newton step
                    lin = self.linearization()
            prev, fresh_step = res, lin.fresh
            dq_e, dx_f = lin.newton_step(None)
            self._produce(apply_step(rob, self.state, dq_e, dx_f))
        self._lin = None
        # the line search's tangent is kept on the same terms as the polish's (polish_rate)
        kw = dict(tol=s.eq_tol, linearizer=self.linearizer, reuse_ratio=s.polish_rate)
        try:
            eq = solve_equilibrium(rob, self.state.angles, state=self.state, **kw)
        except ConvergenceError:  # the loop's state drifted too far: restart from the start pose
            if start is None:
                raise
            eq = solve_equilibrium(rob, self.state.angles, state=start, **kw)
        self._produce(eq.state)
        self.certified["newton"] += 1
        return eq.state, float(eq.residuals[-1]), eq.reference, "newton"

    def _within(self, e) -> bool:
        s = self.settings
        return bool(np.linalg.norm(e[:3]) <= s.pos_tol and np.degrees(np.linalg.norm(e[3:])) <= s.rot_tol_deg)

    def goto(self, pose, state: RobotState | None = None) -> InverseResult:
        """Drive the effector to ``pose`` (6,) = (x, y, z [mm], rotation vector [deg]).

        ``state`` : where to start (default: the current state); a state this controller
        produced keeps the kept tangent (see the module docstring on continuation).
        """
        pose = np.asarray(pose, dtype=float).reshape(-1)
        if pose.shape != (6,) or not np.all(np.isfinite(pose)):
            raise ConfigError(f"pose: {pose!r}: expected 6 finite numbers X Y Z [mm] RX RY RZ [deg]")
        if state is not None:
            self.state = state
        s = self.settings
        goal_p, goal_R = pose[:3], rotation_matrix(np.radians(pose[3:]))
        times, res = [], []
        start = self.state
        best, best_state, since = np.inf, self.state, 0
        status, cert = "max_steps", None
        for _ in range(s.max_steps):
            e = pose_error(self.state.p, self.state.R, goal_p, goal_R)
            if self._within(e):
                # confirm on a certified equilibrium, not on the one-Newton-step state
                cert = self.certify(start)
                e = pose_error(self.state.p, self.state.R, goal_p, goal_R)
                if self._within(e):
                    status = "reached"
                    break
            err = self._weighted(e)
            if err < best * (1.0 - 1e-3):
                best, best_state, since = err, self.state, 0
            else:
                since += 1
                if since >= s.stall_steps:
                    status = "stalled"
                    break
            info = self.step(goal_p, goal_R)
            times.append(info.time)
            res.append(info.residual)
        if status != "reached":
            if status == "stalled":
                self.state = best_state
            cert = self.certify(start)
        eq_state, r_norm, ref, how = cert
        e = pose_error(eq_state.p, eq_state.R, goal_p, goal_R)
        pos_err, rot_err = float(np.linalg.norm(e[:3])), float(np.degrees(np.linalg.norm(e[3:])))
        status = "reached" if self._within(e) else ("stalled" if status == "reached" else status)
        out_pose = np.concatenate([eq_state.p, np.degrees(rotation_vector(eq_state.R))])
        return InverseResult(status, eq_state, np.degrees(eq_state.angles), out_pose, pose, pos_err,
                             rot_err, len(times), tuple(times), tuple(res), r_norm, ref, how)
