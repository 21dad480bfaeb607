"""The QP of one control step (paper eq. 8), in motor increments, with its own checks.

Given the direct Jacobian ``J`` (6, na) of the effector w.r.t. the motors (eq. 7) and the pose
error ``e`` (6,) still to go, one control step moves the motors by

    dq* = argmin_dq  1/2 |D (J dq - e)|^2 + 1/2 eps |dq|^2
          s.t.       max(q_min - q, -dq_max) <= dq <= min(q_max - q, dq_max)

with ``D = diag(1, 1, 1, w, w, w)``, ``w = rot_weight`` [mm/rad] (1 rad of orientation error
costs as much as ``w`` mm of position error) and ``eps = regularization * max eig(J^T D^2 J)``
(strict convexity when J loses rank). This is eq. (8) with the change of variable
``dq_a = W_aa dlambda``: the same minimiser, but the motor limits are simple bounds, which the
dense solvers of qpsolvers (daqp, quadprog, proxqp) handle directly.

:func:`solve_step_qp` builds the problem, solves it and returns a :class:`QPStep` that carries
its diagnostics (status, residuals, objective), as qpsolvers' ``Solution`` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import qpsolvers

from ..mechanics.rotations import rotation_vector

SOLVERS = ("daqp", "quadprog", "proxqp")  # dense QP solvers (through qpsolvers)


class StepSettings(Protocol):
    """What :func:`solve_step_qp` reads of its settings. The control loop passes its
    :class:`.inverse_settings.InverseSettings`; naming only these four here keeps this module
    below the loop and its settings (both import the QP, never the other way round)."""

    @property
    def rot_weight(self) -> float: ...  # [mm/rad]

    @property
    def regularization(self) -> float: ...  # [-], relative to the largest eigenvalue of J^T D^2 J

    @property
    def max_step_deg(self) -> float: ...  # [deg] per motor and step

    @property
    def solver(self) -> str: ...  # one of SOLVERS


@dataclass(frozen=True)
class QPStep:
    """One step's QP solution and its checks.

    Attributes
    ----------
    dq : (na,) motor increment [rad]: the solver's answer clipped into [lb, ub] (solver
        tolerances must not leave the stroke); zeros when the solver failed.
    ok : the solver found a finite optimum (False: ``dq`` is zero, the motors hold).
    solver : the qpsolvers backend that ran.
    objective : 1/2 |D (J dq - e)|^2 + 1/2 eps |dq|^2 at ``dq`` [mm^2].
    primal_residual : largest bound violation of the solver's answer, before clipping [rad].
    dual_residual : stationarity |H x + g + z_box|_inf with the solver's multipliers [mm^2/rad].
    duality_gap : [mm^2]. The three residuals are inf when the solver failed.
    lb, ub : (na,) the bounds on ``dq`` [rad].
    """

    dq: np.ndarray
    ok: bool
    solver: str
    objective: float
    primal_residual: float
    dual_residual: float
    duality_gap: float
    lb: np.ndarray
    ub: np.ndarray

    def is_optimal(self, eps_abs: float) -> bool:
        """Found, and all three residuals at most ``eps_abs`` (as ``qpsolvers.Solution.is_optimal``)."""
        return bool(self.ok and max(self.primal_residual, self.dual_residual, self.duality_gap) <= eps_abs)


def pose_error(p, R, goal_p, goal_R) -> np.ndarray:
    """(6,) error from (p (3,) [mm], R (3, 3)) to the goal: position [mm], then the spatial
    rotation vector of ``goal_R R^T`` [rad]."""
    return np.concatenate([goal_p - p, rotation_vector(goal_R @ R.T)])


def weighted_norm(e, rot_weight: float) -> float:
    """|D e| [mm] of a pose error ``e`` (6,) [mm, rad], ``D = diag(1, 1, 1, w, w, w)``, ``w = rot_weight`` [mm/rad]."""
    w = rot_weight
    return float(np.sqrt(e[:3] @ e[:3] + w * w * (e[3:] @ e[3:])))


def solve_step_qp(J, e, q, q_min, q_max, settings: StepSettings) -> QPStep:
    """The QP of eq. (8) in motor increments (see the module docstring).

    Parameters
    ----------
    J : (6, na) direct Jacobian [mm/rad, rad/rad].
    e : (6,) pose error to remove [mm, rad].
    q, q_min, q_max : (na,) motor angles and their limits [rad].
    settings : ``rot_weight`` [mm/rad], ``regularization`` [-], ``max_step_deg`` [deg] and the QP
        ``solver`` (one of :data:`SOLVERS`) are read.
    """
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
    sol = qpsolvers.solve_problem(qpsolvers.Problem(H, g, lb=lb, ub=ub), solver=settings.solver)
    x = sol.x if sol.found else None
    if x is None or not np.all(np.isfinite(x)):
        dq, ok, checks = np.zeros_like(q), False, (np.inf, np.inf, np.inf)
    else:
        dq, ok = np.clip(x, lb, ub), True  # clip: solver tolerances must not leave the stroke
        checks = (float(sol.primal_residual()), float(sol.dual_residual()), float(sol.duality_gap()))
    r = np.sqrt(D2) * (J @ dq - e)
    objective = float(0.5 * (r @ r) + 0.5 * eps * (dq @ dq))
    return QPStep(dq, ok, settings.solver, objective, *checks, lb, ub)
