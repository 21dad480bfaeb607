"""The inverse loop's settings (:mod:`.inverse`), checked where they are made.

Each one's meaning and the measurements behind its default are in :mod:`.inverse`'s
docstring; the step QP (:mod:`.qp`) reads four of them (its ``StepSettings``) and the kept
tangent (:mod:`.tangent`) its refresh thresholds. One concept per module: the settings and
their checks here, the loop that reads them in :mod:`.inverse`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError, check_range
from ..fem.factor import resolve
from .qp import SOLVERS as QP_SOLVERS


@dataclass(frozen=True)
class InverseSettings:
    """Settings of the inverse loop (units in brackets).

    ``solver``: the QP solver (:data:`.qp.SOLVERS`); ``linear_solver``: the sparse one
    (:data:`metasheet.fem.factor.FACTOR_SOLVERS`: "superlu", "cholmod", "auto").
    """

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
    linear_solver: str = "superlu"  # "cholmod" / "auto" (CHOLMOD if installed): slower, see :mod:`.inverse`
    eq_tol: float = 1e-5  # [-] reported pose: residual <= eq_tol * force scale (see :mod:`.inverse`)
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
        if self.solver not in QP_SOLVERS:
            raise ConfigError(f"solver: {self.solver!r}: allowed {QP_SOLVERS}")
