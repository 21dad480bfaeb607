"""Why a goal was not reached: the limiting cause of a stalled inverse run, named.

A run of :meth:`~metasheet.robot.inverse.InverseController.goto` that ends short of its goal
stops for one of four reasons, and a user fixes each differently:

- **the stroke**: motors sit at an end of their stroke and the error would need them
  further (a wider ``[robot] angle_min/angle_max``, or another rest angle);
- **a near-singular Jacobian**: no motor is at a limit, but the Jacobian J (paper eq. 7) has
  nearly lost a rank, so the remaining error's direction costs huge motor motions (the
  pose is at the edge of what this robot can do; measured on the authors' scene: its
  smallest scaled singular value fell from 12.7 at rest to 1.5-2.7 mm/rad at a +-10 deg
  tilt's stall);
- **the equilibrium solver**: the final state is not a certified equilibrium;
- **the step rule**: none of the above; the QP's per-step limit (``max_step_deg``) and the
  stall rule (``stall_steps`` without progress) ended it: a larger ``max_steps`` or
  ``stall_steps`` may get further.

:func:`diagnose` returns them all, the first one the primary cause.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .inverse_settings import InverseSettings
from .kinematics import kinematics_at

#: A motor within this of a stroke end is at it [deg].
AT_STROKE_DEG = 0.05
#: The scaled Jacobian counts as near-singular when its smallest singular value is below this
#: fraction of its largest [-].
SINGULAR_RATIO = 0.15


@dataclass(frozen=True)
class StallDiagnosis:
    """What limited a run that did not reach its goal.

    Attributes
    ----------
    causes : the limiting causes, primary first: "stroke", "singular", "solver", "step rule".
    at_min, at_max : motor numbers (1-based) at the lower / upper end of their stroke.
    singular_values : (6,) the scaled Jacobian's singular values at the final state [mm/rad]
        (rotations counted at :data:`~metasheet.robot.kinematics` 's 50 mm).
    certified : whether the final state is a certified equilibrium.
    """

    causes: tuple[str, ...]
    at_min: tuple[int, ...]
    at_max: tuple[int, ...]
    singular_values: np.ndarray
    certified: bool

    def text(self) -> str:
        """One line per cause, the primary first."""
        lines = []
        for cause in self.causes:
            if cause == "stroke":
                ends = [f"motor {m} at its lower end" for m in self.at_min] + \
                       [f"motor {m} at its upper end" for m in self.at_max]
                lines.append("motors at their stroke: " + ", ".join(ends))
            elif cause == "singular":
                sv = self.singular_values
                lines.append(f"near-singular Jacobian: smallest singular value {sv[-1]:.3g} mm/rad, "
                             f"{sv[-1] / sv[0]:.2g} of the largest ({sv[0]:.3g}): the pose is at the edge of "
                             "what the motors can move")
            elif cause == "solver":
                lines.append("the equilibrium solver: the final state is not a certified equilibrium")
            else:
                lines.append("the step rule: the error stopped shrinking within the per-step motor limit "
                             "(max_step_deg) and stall_steps")
        return "\n".join(lines)


def diagnose(robot, result, *, eq_tol: float = InverseSettings.eq_tol) -> StallDiagnosis:
    """The :class:`StallDiagnosis` of ``result`` (an ``InverseResult`` of ``robot``); its final
    state counts as certified when its residual is within ``eq_tol`` of the force scale."""
    certified = result.certified != "none" and bool(result.residual <= eq_tol * max(result.reference, 1e-300))
    return diagnose_state(robot, result.state, certified=certified)


def diagnose_state(robot, state, *, certified: bool = True) -> StallDiagnosis:
    """The :class:`StallDiagnosis` of a run of ``robot`` that ended at ``state`` (its closest
    pose; ``certified``: a certified equilibrium): motors at their stroke, and the scaled
    Jacobian's singular values there (one linearisation)."""
    angles = np.degrees(np.asarray(state.angles, dtype=float))
    lo = np.degrees(np.broadcast_to(robot.angle_min, angles.shape))
    hi = np.degrees(np.broadcast_to(robot.angle_max, angles.shape))
    at_min = tuple(int(i) + 1 for i in np.flatnonzero(angles <= lo + AT_STROKE_DEG))
    at_max = tuple(int(i) + 1 for i in np.flatnonzero(angles >= hi - AT_STROKE_DEG))
    sv = kinematics_at(robot, state).singular_values
    causes = []
    if at_min or at_max:
        causes.append("stroke")
    if sv[-1] < SINGULAR_RATIO * sv[0]:
        causes.append("singular")
    if not certified:
        causes.append("solver")
    if not causes:
        causes.append("step rule")
    return StallDiagnosis(tuple(causes), at_min, at_max, sv, certified)
