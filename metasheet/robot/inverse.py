"""Inverse model (paper eq. 8): a QP on the motor increments, in a SOFA-like control loop.

Each control step, at the current (nearly equilibrated) state:

1. linearise: tangent, condensation, ``J = W_ea W_aa^-1`` (eq. 6-7) and the effector motion
   ``dq_e^0`` that the pending equilibrium correction alone would cause (:mod:`.tangent`:
   the linearisation is kept across steps while it stays good enough);
2. solve the QP of eq. (8) (:func:`.qp.solve_step_qp`)

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
several chord steps, so the loop keeps it across control steps and only re-evaluates the
forces and one solve with the cached factor (a chord / modified-Newton step). It is never
trusted blindly: :class:`.tangent.TangentCache` takes a fresh one when it is
``refactor_every`` steps old [20], the motors moved more than ``refresh_angle_deg`` since it
was taken [8 deg] (or the state was set from outside: another goal, a reset), the pending
correction ``dq_e^0`` exceeds ``drift_tol * pos_tol`` [0.5 * 0.1 mm], or the reduced
residual exceeds ``chord_tol`` times the force scale [1.0] (defaults in brackets).

The sparse solver is SuperLU by default: CHOLMOD of the symmetric part (``linear_solver=
"cholmod"``) factorises twice as fast, but on the deformed anisotropic tangent it is a poor
Newton matrix (pending corrections ~0.2 mm, a refresh nearly every step) and its exact
refinement often falls back to SuperLU; ``benchmarks/bench_robot.py`` prints both.

The loop stops "reached" when the position error is below
``pos_tol`` and the rotation error below ``rot_tol``, "stalled" when the weighted error has
not improved for ``stall_steps`` steps (an unreachable goal: the closest pose found is
returned, never an exception), or "max_steps". "Reached" is judged on a certified
equilibrium (below), asked for when a step lands within the tolerance; a state whose pending
correction ``dq_e^0`` would move the pose out again, and whose residual is beyond the chord
corrections' reach, is stepped on instead, once, and again only while its residual contracts
(:meth:`InverseController._skip_certify`): after a large step where the sheets stiffen,
certifying (a Newton solve) only to step on cost ~3 s a time on the paper robot.

The reported pose is always an equilibrium at the final motor angles within a stated
residual tolerance: the reduced residual (the norm of :attr:`.statics.Linearization.
residual_norm`) at most ``eq_tol`` times the force scale of :func:`.statics.force_scale`.
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

Settings (:class:`.inverse_settings.InverseSettings`, with the defaults named above):
:attr:`InverseController.settings` are the defaults of every call; ``goto``,
``step`` and ``certify`` take a per-call ``settings`` override (a study's tolerances for one
goal) that leaves the controller's own unchanged.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError
from ..mechanics.rotations import rotation_matrix, rotation_vector
from .equilibrium import solve_equilibrium
from .inverse_settings import InverseSettings
from .qp import QPStep, pose_error, solve_step_qp, weighted_norm
from .statics import Linearizer, RobotState
from .tangent import TangentCache


@dataclass(frozen=True)
class StepInfo:
    """One control step: motor increment dq_a (na,) [rad], residual before it [N], weighted
    pose error before it [mm], QP status, time [s], and the QP's own diagnostics."""

    dq_a: np.ndarray
    residual: float
    error: float
    qp_ok: bool
    time: float
    fresh: bool = True  # whether this step took a fresh linearisation
    qp: QPStep | None = None  # the step's QP solution with its residuals and objective


@dataclass(frozen=True)
class InverseResult:
    """Outcome of :meth:`InverseController.goto`.

    Attributes
    ----------
    status : "reached", "stalled", "max_steps" or "stopped" (the caller's ``stop`` fired).
    state : equilibrium at the final motor angles.
    angles_deg : (na,) final motor angles [deg].
    pose : (6,) final effector pose (mm, deg: rotation vector).
    goal : (6,) the goal (mm, deg).
    pos_error : [mm]. rot_error : [deg].
    steps : control steps taken. step_times : [s] each. residuals : [N] before each step.
    residual : reduced residual at ``state`` [N]; reference : the force scale [N] it is
        relative to (``residual <= eq_tol * reference`` certifies ``state`` as an equilibrium).
    certified : "chord" (kept-tangent corrections) or "newton" (full solve) certified it; "none"
        for a stopped run asked not to (``certify_stop``): ``state`` is then its last control state.
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


def _within(e, s: InverseSettings) -> bool:
    """Pose error ``e`` (6,) [mm, rad] inside ``pos_tol`` [mm] and ``rot_tol_deg`` [deg]."""
    return bool(np.linalg.norm(e[:3]) <= s.pos_tol and np.degrees(np.linalg.norm(e[3:])) <= s.rot_tol_deg)


class InverseController:
    """The control loop of eq. (8) on one robot, starting from ``state`` (an equilibrium).

    Composes the kept linearisation (:attr:`tangent`, a :class:`.tangent.TangentCache` on its
    own :class:`.statics.Linearizer`) and the step QP (:func:`.qp.solve_step_qp`).

    Attributes
    ----------
    robot : the robot. settings : the defaults of every call (each call may override them).
    state : the current state. tangent : the kept linearisation and its refresh counts.
    n_steps, total_steps : control steps taken (both count the same; ``n_steps`` is the one
        a caller may reset). certified : how :meth:`certify` got there, counted.
    """

    def __init__(self, robot, state: RobotState | None = None, settings: InverseSettings = InverseSettings()):
        self.robot = robot
        self.settings = settings
        self.tangent = TangentCache(robot.linearizer(settings.linear_solver))
        self.state = state if state is not None else solve_equilibrium(
            robot, robot.coupling.rest_angles, linearizer=self.linearizer).state
        self.n_steps = 0
        self.total_steps = 0  # control steps over the controller's life
        self.certified = {"chord": 0, "newton": 0}  # how :meth:`certify` got there, counted
        if state is None:
            self.tangent.remember(self.state)  # our own rest equilibrium

    @property
    def linearizer(self) -> Linearizer:
        """The :class:`.statics.Linearizer` in use (shared: the studies' forward solves use it too)."""
        return self.tangent.linearizer

    @property
    def refreshes(self) -> int:
        """Fresh linearisations taken."""
        return self.tangent.refreshes

    @property
    def refresh_reasons(self) -> dict:
        """Why kept tangents were dropped, counted: "age", "angle", "residual", "drift"."""
        return self.tangent.reasons

    def _settings(self, settings: InverseSettings | None) -> InverseSettings:
        if settings is None:
            return self.settings
        if not isinstance(settings, InverseSettings):
            raise ConfigError(f"settings: {type(settings).__name__}: expected InverseSettings")
        return settings

    def linearization(self, settings: InverseSettings | None = None):
        """The step's linearisation: the chord update on the kept tangent, or a fresh one.

        A ``linear_solver`` (in ``settings``, default :attr:`settings`) other than the
        linearizer's rebuilds the linearizer. The residual and the pending correction are
        evaluated at every step, never assumed (:meth:`.tangent.TangentCache.linearization`).
        """
        s = self._settings(settings)
        if not self.linearizer.uses(s.linear_solver):  # another sparse solver asked for
            self.tangent.use(self.robot.linearizer(s.linear_solver))
        return self.tangent.linearization(self.state, s)

    def refresh(self, state: RobotState | None = None):
        """A fresh linearisation at ``state`` (default: the current one), kept for the next steps.

        For callers that need the tangent there anyway (a study's Jacobian at a reached point):
        the goals that follow from ``state`` then start on it instead of paying for another.
        """
        if state is not None:
            self.state = state
        self.tangent.remember(self.state)  # linearised right here: safe to continue from
        self.tangent.drop()
        return self.linearization()

    def owns(self, state) -> bool:
        """Whether ``state`` is one this controller produced recently (continuation keeps the tangent)."""
        return self.tangent.owns(state)

    def _produce(self, state: RobotState) -> RobotState:
        self.tangent.remember(state)
        self.state = state
        return state

    def step(self, goal_p, goal_R, *, settings: InverseSettings | None = None) -> StepInfo:
        """One control step towards the goal (p* (3,) [mm], R* (3, 3)); updates ``self.state``."""
        t0 = time.perf_counter()
        s, rob = self._settings(settings), self.robot
        lin = self.linearization(s)
        dq_e0, _ = lin.newton_step(None)
        e = pose_error(self.state.p, self.state.R, goal_p, goal_R)
        qp = solve_step_qp(self.tangent.J, e - dq_e0, self.state.angles, rob.angle_min, rob.angle_max, s)
        dq_e, dx_f = lin.newton_step(qp.dq)
        self._produce(self.linearizer.apply(self.state, dq_e, dx_f, qp.dq))
        self.n_steps += 1
        self.total_steps += 1
        return StepInfo(qp.dq, lin.residual_norm, weighted_norm(e, s.rot_weight), qp.ok,
                        time.perf_counter() - t0, lin.fresh, qp)

    def certify(self, start: RobotState | None = None, *,
                settings: InverseSettings | None = None) -> tuple[RobotState, float, float, str]:
        """Bring ``self.state`` to equilibrium at its motor angles within ``eq_tol``.

        Corrections at fixed motor angles on the loop's own linearisation, each judged on the
        true residual: a kept tangent while each step cuts the residual by ``polish_rate``, a
        fresh one (a Newton step) when it does not; the full Newton solve with line search
        (:func:`.equilibrium.solve_equilibrium`, from the current state or, failing that,
        ``start``) only when even a fresh step does not contract, or after ``polish_iters``.
        Returns (state, residual [N], force scale [N], "chord" | "newton").
        """
        s, rob = self._settings(settings), self.robot
        prev, fresh_step = np.inf, False
        for _ in range(s.polish_iters + 1):
            lin = self.linearization(s)
            res, ref = lin.residual_norm, max(self.linearizer.force_scale(lin), 1e-300)
            if res <= s.eq_tol * ref:
                self.certified["chord"] += 1
                return self.state, res, ref, "chord"
            if res > s.polish_rate * prev:  # the last correction did not contract enough
                if fresh_step:  # not even with a fresh tangent: needs the line search
                    break
                if not lin.fresh:
                    self.tangent.drop()  # same state, fresh tangent: a Newton step
                    lin = self.linearization(s)
            prev, fresh_step = res, lin.fresh
            dq_e, dx_f = lin.newton_step(None)
            self._produce(self.linearizer.apply(self.state, dq_e, dx_f))
        self.tangent.drop()
        # the line search's tangent is kept on the same terms as the polish's (polish_rate)
        kw = dict(tol=s.eq_tol, linearizer=self.linearizer, reuse_ratio=s.polish_rate)
        try:
            eq = solve_equilibrium(rob, self.state.angles, state=self.state, **kw)
        except ConvergenceError:  # the loop's state drifted too far: restart from the start pose
            if start is None:
                raise
            try:
                eq = solve_equilibrium(rob, self.state.angles, state=start, **kw)
            except ConvergenceError:  # no equilibrium path reaches these angles (a snap)
                eq = self._farthest_equilibrium(start, self.state.angles, kw)
        self._produce(eq.state)
        self.certified["newton"] += 1
        return eq.state, float(eq.residuals[-1]), eq.reference, "newton"

    def _farthest_equilibrium(self, start: RobotState, angles, kw: dict, bisections: int = 4):
        """The equilibrium farthest along the straight motor path from ``start`` to ``angles``
        [rad] that the line-searched Newton solve reaches (bisection on the path fraction):
        past a snap of the sheets the loop's angles have no equilibrium connected to the start,
        and the closest certified pose is the honest answer."""
        rob = self.robot
        good = solve_equilibrium(rob, start.angles, state=start, **kw)
        lo, hi = 0.0, 1.0
        for _ in range(bisections):
            mid = 0.5 * (lo + hi)
            try:
                good = solve_equilibrium(rob, start.angles + mid * (np.asarray(angles) - start.angles),
                                         state=good.state, **kw)
                lo = mid
            except ConvergenceError:
                hi = mid
        return good

    def _skip_certify(self, e, s: InverseSettings, skipped: float | None) -> float | None:
        """Whether a state within the tolerance (pose error ``e`` (6,)) is stepped on rather than
        certified: its residual [N] if so, else None.

        A large control step far from equilibrium (where the sheets stiffen or buckle) can land
        within the tolerance by chance while its pending equilibrium correction moves the pose
        out: certifying it (a Newton solve with line search, ~3 s on the paper robot, as the
        chord corrections do not reach that far) only to step on again is the costly path, and
        the next step makes that correction anyway. So such a state, with a residual beyond the
        chord's reach (above ``chord_tol`` times the force scale), is stepped on: the first
        time, and again only while the residual contracts (``polish_rate`` against the state
        skipped before, ``skipped`` [N]); otherwise the loop certifies, as always, so a run that
        drifts from equilibrium is brought back. Nearer equilibrium certifying is the cheap
        path (a few chord corrections) and stays.
        """
        lin = self.linearization(s)
        if not lin.residual_norm > s.chord_tol * self.linearizer.force_scale(lin):
            return None
        if skipped is not None and not lin.residual_norm < s.polish_rate * skipped:
            return None
        if _within(e - lin.newton_step(None)[0], s):
            return None
        return float(lin.residual_norm)

    def goto(self, pose, state: RobotState | None = None, *,
             settings: InverseSettings | None = None, stop=None, certify_stop: bool = True) -> InverseResult:
        """Drive the effector to ``pose`` (6,) = (x, y, z [mm], rotation vector [deg]).

        ``state`` : where to start (default: the current state); a state this controller
        produced keeps the kept tangent (see the module docstring on continuation).
        ``settings`` : this call's settings (default :attr:`settings`, which stay unchanged).
        ``stop`` : ``stop(state) -> bool`` asked after each step; True ends the run at the
        state before that step (status "stopped"): a caller's domain (a reduced model's box,
        a strain limit) is not crossed.
        ``certify_stop`` : False returns a stopped run's last control state as it is (one
        Newton step from equilibrium; ``residual`` NaN, ``certified`` "none"), for a caller that
        discards it: certifying it costs more than the run on the converged robot.
        """
        pose = np.asarray(pose, dtype=float).reshape(-1)
        if pose.shape != (6,) or not np.all(np.isfinite(pose)):
            raise ConfigError(f"pose: {pose!r}: expected 6 finite numbers X Y Z [mm] RX RY RZ [deg]")
        s = self._settings(settings)
        if state is not None:
            self.state = state
        goal_p, goal_R = pose[:3], rotation_matrix(np.radians(pose[3:]))
        times, res = [], []
        start = self.state
        best, best_state, since = np.inf, self.state, 0
        status, cert, skipped = "max_steps", None, None
        for _ in range(s.max_steps):
            e = pose_error(self.state.p, self.state.R, goal_p, goal_R)
            within = _within(e, s)
            skipped = self._skip_certify(e, s, skipped) if within else None
            if within and skipped is None:
                # confirm on a certified equilibrium, not on the one-Newton-step state
                cert = self.certify(start, settings=s)
                e = pose_error(self.state.p, self.state.R, goal_p, goal_R)
                if _within(e, s):
                    status = "reached"
                    break
            err = weighted_norm(e, s.rot_weight)
            if err < best * (1.0 - 1e-3):
                best, best_state, since = err, self.state, 0
            else:
                since += 1
                if since >= s.stall_steps:
                    status = "stalled"
                    break
            before = self.state
            info = self.step(goal_p, goal_R, settings=s)
            times.append(info.time)
            res.append(info.residual)
            if stop is not None and stop(self.state):
                self.state, status = before, "stopped"
                break
        if status == "stopped" and not certify_stop:
            cert = (self.state, float("nan"), float("nan"), "none")
        elif status != "reached":
            if status == "stalled":
                self.state = best_state
            cert = self.certify(start, settings=s)
        eq_state, r_norm, ref, how = cert
        e = pose_error(eq_state.p, eq_state.R, goal_p, goal_R)
        pos_err, rot_err = float(np.linalg.norm(e[:3])), float(np.degrees(np.linalg.norm(e[3:])))
        if how != "none":  # a stopped run's uncertified control state is never "reached"
            status = "reached" if _within(e, s) else ("stalled" if status == "reached" else status)
        out_pose = np.concatenate([eq_state.p, np.degrees(rotation_vector(eq_state.R))])
        return InverseResult(status, eq_state, np.degrees(eq_state.angles), out_pose, pose, pos_err,
                             rot_err, len(times), tuple(times), tuple(res), r_norm, ref, how)
