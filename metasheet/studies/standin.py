"""A cheap analytic robot with the paper's structure, to test the study logic without the FEM.

Six motors, two tripods on the rod axis x (tripod 0 at -x, tripod 1 at +x, turned 180 deg).
With ``d = q - q_rest`` [deg] the linear part is ``u = J d`` where motor k (tripod t,
side ``s = -1, +1``, azimuth ``phi_k``) moves the effector

* along the rod by ``-s c_ax`` [mm/deg] (a tripod pushes the effector away from itself),
* radially by ``-c_rad (0, cos phi, sin phi)`` [mm/deg],
* tilts it by ``c_tilt s (e_x x u_k)`` [rad/deg],
* rotates it about the rod by ``c_rod alpha / alpha_design`` [rad/deg], the same sign for all
  six motors (the mirrored spiral fibres): the anisotropic sheets' sixth DOF.

All six motors together give exactly a rod rotation (the other terms cancel), so at
``alpha = 0`` that column is null and the robot has 5 controllable DOF, as in the paper.
Isotropic sheets buckle sideways under a common push: ``y += c_buck (1 - alpha / alpha_design)
mean(d)^2``. Poses saturate smoothly, ``pose = L tanh(u / L)``, a mild nonlinearity that
bounds the workspace like the real sheets do.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace

import numpy as np
from qpsolvers import solve_qp

from ..errors import check_range
from .model import ReachResult, check_motor_range, pose_errors

_SAT = np.array([40.0, 40.0, 40.0, 0.6, 0.6, 0.6])  # saturation scales [mm, rad]


@dataclass(frozen=True)
class StandInSpec:
    """Picklable recipe of a :class:`StandInRobot` (all angles in degrees)."""

    alpha: float = 93.2  # sheet anisotropy [%]
    alpha_max: float = 93.2  # the design material's anisotropy [%]
    motor_range: tuple[float, float] = (0.0, 90.0)  # [deg]
    rest_deg: float = 30.0  # rest angle of every motor [deg]
    max_step_deg: float = 5.0  # largest motor change per control step [deg]
    rot_weight: float = 60.0  # weight of rotation errors in the QP [mm/rad]
    c_ax: float = 0.5  # [mm/deg]
    c_rad: float = 0.6  # [mm/deg]
    c_tilt: float = 0.012  # [rad/deg]
    c_rod: float = 0.01  # [rad/deg] at alpha = alpha_max
    c_buck: float = 0.02  # [mm/deg^2] lateral buckling of isotropic sheets
    strain_per_deg: float = 0.004  # max principal strain per degree of motor offset [-/deg]

    def __post_init__(self):
        check_range("alpha", self.alpha, 0.0, self.alpha_max + 1e-9)
        check_motor_range("motor_range", *self.motor_range)
        check_range("max_step_deg", self.max_step_deg, 0.0, 90.0, lo_open=True)

    @property
    def key(self) -> str:
        return "standin-" + hashlib.sha256(repr(self).encode()).hexdigest()[:16]

    @property
    def design_alpha(self) -> float:
        return self.alpha_max

    def build(self) -> "StandInRobot":
        return StandInRobot(self)

    def with_motor_range(self, lo_deg: float, hi_deg: float) -> "StandInSpec":
        return replace(self, motor_range=(float(lo_deg), float(hi_deg)))

    def with_alpha(self, alpha: float) -> "StandInSpec":
        return replace(self, alpha=float(alpha))

    def with_material(self, material, density=None) -> "StandInSpec":
        if hasattr(material, "as_transverse"):
            material = material.as_transverse()
        return replace(self, alpha=min(self.alpha_max, max(0.0, float(material.alpha))))


class StandInRobot:
    """The analytic robot of :class:`StandInSpec`; its state is the motor angles (6,) [deg]."""

    rod_axis = 0
    pull_sign = -1.0  # pulling lowers the motor angles

    def __init__(self, spec: StandInSpec):
        self.spec = spec
        self.motor_range = tuple(spec.motor_range)
        s_alpha = spec.alpha / spec.alpha_max if spec.alpha_max > 0 else 0.0
        self._s_alpha = s_alpha
        J = np.zeros((6, 6))
        for k in range(6):
            t = k // 3
            side = -1.0 if t == 0 else 1.0
            phi = np.pi / 2 + 2 * np.pi / 3 * (k % 3) + np.pi * t
            u = np.array([0.0, np.cos(phi), np.sin(phi)])
            J[:3, k] = -side * spec.c_ax * np.array([1.0, 0, 0]) - spec.c_rad * u
            J[3:, k] = spec.c_tilt * side * np.cross([1.0, 0, 0], u)
            J[3, k] += spec.c_rod * s_alpha
        self.J = J  # [mm/deg, rad/deg]
        self._q0 = np.full(6, float(spec.rest_deg))

    # ------------------------------------------------------------------ forward model
    def _linear(self, q: np.ndarray) -> np.ndarray:
        d = q - self._q0
        u = self.J @ d
        u[1] += self.spec.c_buck * (1.0 - self._s_alpha) * d.mean() ** 2
        return u

    def _pose(self, q: np.ndarray) -> np.ndarray:
        return _SAT * np.tanh(self._linear(q) / _SAT)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(6, 6) d pose / d q [mm/deg, rad/deg] at motor angles ``q``."""
        u = self._linear(q)
        Jl = self.J.copy()
        Jl[1] += 2.0 * self.spec.c_buck * (1.0 - self._s_alpha) * (q - self._q0).mean() / 6.0
        return (1.0 / np.cosh(u / _SAT) ** 2)[:, None] * Jl

    def rest_pose(self) -> np.ndarray:
        return np.zeros(6)

    def rest_motors(self) -> np.ndarray:
        return self._q0.copy()

    def equilibrium(self, motors_deg, *, state=None, intermediate: bool = False):
        q = np.asarray(motors_deg, float).copy()
        return self._pose(q), q

    # ------------------------------------------------------------------ inverse model (eq. 8 analogue)
    def reach(self, goal, *, state=None, tol_mm=1.0, tol_deg=None, max_steps=50, rot_weight=None) -> ReachResult:
        goal = np.asarray(goal, float)
        q = self._q0.copy() if state is None else np.asarray(state, float).copy()
        lo, hi = self.motor_range
        rw = self.spec.rot_weight if rot_weight is None else float(rot_weight)
        w = np.array([1, 1, 1, rw, rw, rw], float)
        step = self.spec.max_step_deg
        steps = 0
        for steps in range(1, max_steps + 1):
            pose = self._pose(q)
            e_mm, e_deg = pose_errors(goal, pose)
            if e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg):
                steps -= 1
                break
            A = np.vstack([w[:, None] * self.jacobian(q), 1e-3 * np.eye(6)])  # small regularisation
            b = np.concatenate([w * (goal - pose), np.zeros(6)])
            lb = np.maximum(lo - q, -step)
            ub = np.minimum(hi - q, step)
            dq = solve_qp(A.T @ A, -A.T @ b, lb=lb, ub=ub, solver="daqp")
            if dq is None:  # daqp failed (never seen on this tiny box QP): report it as a stall
                break
            q = np.clip(q + dq, lo, hi)
            if np.abs(dq).max() < 1e-6:  # stalled: the QP cannot improve any more
                break
        pose = self._pose(q)
        e_mm, e_deg = pose_errors(goal, pose)
        ok = e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg)
        return ReachResult(ok, pose, q.copy(), e_mm, e_deg, steps, q.copy())

    # ------------------------------------------------------------------ diagnostics
    def max_principal_strain(self, state) -> float:
        q = self._q0 if state is None else np.asarray(state, float)
        return float(self.spec.strain_per_deg * np.abs(q - self._q0).max())

    def min_singular_value(self, state) -> float:
        q = self._q0 if state is None else np.asarray(state, float)
        w = np.array([1, 1, 1, self.spec.rot_weight, self.spec.rot_weight, self.spec.rot_weight], float)
        return float(np.linalg.svd(w[:, None] * self.jacobian(q), compute_uv=False).min())
