"""The printed robot behind the study protocol (issue 62, item 5): the two printed sheets as
corotational superelements of their grips (:mod:`metasheet.robot.superelement`, each sheet's
stiffness from the voxel DNS of one print), so that the paper's studies run on the print's own
model, print by print.

Its domain is the printed walls', not a continuum strain: ``valid_deg`` bounds every motor's
travel from rest (the first self-contact of two walls, :mod:`metasheet.sheet.wall_limits`); a
reach whose motors leave that box stops there with ``left_domain``, as a reduced model's reach
stops at its training box. The sheets are condensed on their grips, so the walls' strain is
carried as a bound: ``wall_strain_per_deg`` holds, per motor, the walls' largest principal
strain per degree turned up and down alone (the linear DNS's,
:func:`metasheet.sheet.wall_limits.principal_range`), and
:meth:`PrintedRobot.max_principal_strain` is ``sum_k max(d_k s+_k, -d_k s-_k)`` over the motors'
travels ``d_k`` [deg]: the largest eigenvalue of a sum is at most the sum of the largest
eigenvalues (Weyl), and a field's largest over the voxels at most the sum of each one's, so this
bounds the first-order walls' strain from above. Without it the strain is NaN (unknown).

The inverse model is the paper's QP (:func:`metasheet.robot.qp.solve_step_qp`) on the
superelement's exact Jacobian at each control step's equilibrium: a few milliseconds a step.
States are ``(motors_deg (6,), q (6,))`` tuples, ``q`` the rod's ``(dp [mm], theta [rad])``.
"""

from __future__ import annotations

import hashlib
import pickle
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from ..robot.inverse_settings import InverseSettings
from ..robot.qp import solve_step_qp, weighted_norm
from ..robot.superelement import SuperelementRobot, SuperPose
from .model import ReachResult, check_motor_range, pose_errors

#: a motor this far past the validity box [deg] counts as outside (round-off of the QP's bounds)
OUTSIDE_EPS_DEG = 1e-9


@dataclass(frozen=True, eq=False)
class PrintedSpec:
    """Picklable recipe of a :class:`PrintedRobot`.

    model : the :class:`~metasheet.robot.superelement.SuperelementRobot` of one print.
    rest_position : (3,) the effector's reference point at rest [mm]; rod_axis : its axis (0-2).
    label : which print (e.g. ``"seed 1"``).
    motor_range : (lo, hi) motor limits [deg]; valid_deg : the walls' box, the largest travel of
        any motor from rest [deg] (None: no limit).
    max_step_deg : largest motor change per control step [deg]; rot_weight : the QP's weight of
        rotation errors [mm/rad]; stall_steps : control steps without improvement before a
        reach stops.
    wall_strain_per_deg : None, or (6, 2) per motor the walls' largest principal strain per
        degree turned up (column 0) and down (column 1) [1/deg] (module docstring).
    """

    model: SuperelementRobot
    rest_position: tuple[float, float, float]
    rod_axis: int
    label: str = "print"
    motor_range: tuple[float, float] = (-180.0, 180.0)
    valid_deg: float | None = None
    max_step_deg: float = 5.0
    rot_weight: float = 50.0
    stall_steps: int = 15
    wall_strain_per_deg: tuple | None = None

    def __post_init__(self):
        if self.wall_strain_per_deg is not None:
            w = np.asarray(self.wall_strain_per_deg, float)
            if w.shape != (6, 2) or not np.all(np.isfinite(w)) or np.any(w < 0):
                raise ConfigError(f"wall_strain_per_deg: shape {w.shape}: six (up, down) finite strains >= 0 [1/deg]")
            object.__setattr__(self, "wall_strain_per_deg", tuple(map(tuple, w.tolist())))
        check_motor_range("motor_range", *self.motor_range)
        check_range("max_step_deg", self.max_step_deg, 0.0, 90.0, lo_open=True)
        check_range("rot_weight", self.rot_weight, 0.0, None, lo_open=True)
        if self.valid_deg is not None:
            check_range("valid_deg", self.valid_deg, 0.0, 360.0, lo_open=True)
        if self.rod_axis not in (0, 1, 2):
            raise ConfigError(f"rod_axis: {self.rod_axis!r}: allowed values 0, 1, 2")

    @property
    def key(self) -> str:
        m = self.model
        blob = pickle.dumps((m.K, m.refs, m.world, m.axes, m.pivots, m.origin, m.rest_angles, self.rest_position,
                             self.rod_axis, self.label, self.motor_range, self.valid_deg, self.max_step_deg,
                             self.rot_weight, self.stall_steps, self.wall_strain_per_deg), protocol=4)
        return "printed-" + hashlib.sha256(blob).hexdigest()[:16]

    @property
    def design_alpha(self) -> float:
        return float("nan")  # a print has no anisotropy knob

    def build(self) -> "PrintedRobot":
        return PrintedRobot(self)

    def with_motor_range(self, lo_deg: float, hi_deg: float) -> "PrintedSpec":
        return replace(self, motor_range=(float(lo_deg), float(hi_deg)))

    def with_alpha(self, alpha: float) -> "PrintedSpec":
        raise ConfigError("alpha: a printed robot's anisotropy is its print's: the anisotropy sweep runs on the "
                          "continuum columns")

    def with_material(self, material, density=None) -> "PrintedSpec":
        raise ConfigError("material: a printed robot's sheets are its prints' walls: another material runs on the "
                          "continuum columns")


class PrintedRobot:
    """The :class:`PrintedSpec`'s robot; its state is ``(motors_deg, q)`` (module docstring)."""

    pull_sign = 1.0  # as the FEM robot's: the same servos and horns

    def __init__(self, spec: PrintedSpec):
        self.spec = spec
        self.se = spec.model
        self.rod_axis = int(spec.rod_axis)
        self.motor_range = tuple(spec.motor_range)
        self._rest_motors = np.degrees(self.se.rest_angles)
        self._origin = np.asarray(spec.rest_position, float)
        self.settings = InverseSettings(rot_weight=spec.rot_weight, max_step_deg=spec.max_step_deg)

    def rest_pose(self) -> np.ndarray:
        return np.concatenate([self._origin, np.zeros(3)])

    def rest_motors(self) -> np.ndarray:
        return self._rest_motors.copy()

    def _pose(self, q) -> np.ndarray:
        return np.concatenate([self._origin + q[:3], q[3:]])

    def inside(self, motors_deg) -> bool:
        """Whether every motor is within the walls' box (``valid_deg`` from rest)."""
        v = self.spec.valid_deg
        return v is None or float(np.abs(np.asarray(motors_deg, float) - self._rest_motors).max()) <= v + OUTSIDE_EPS_DEG

    def _solve(self, motors_deg, state) -> SuperPose:
        """The equilibrium at ``motors_deg`` from ``state`` (None: rest), in halved motor
        increments while Newton does not converge from the last one (at most 2^6 pieces)."""
        m0, q0 = (self._rest_motors, np.zeros(6)) if state is None else (np.asarray(state[0], float), state[1])
        target = np.asarray(motors_deg, float)
        for cuts in range(7):
            n, q, m = 2**cuts, np.asarray(q0, float), m0
            try:
                for t in np.arange(1, n + 1) / n:
                    pose = self.se.equilibrium(m0 + t * (target - m0), q0=q)
                    q = pose.q
                return pose
            except ConvergenceError:
                continue
        raise ConvergenceError(f"printed robot ({self.spec.label}): no equilibrium at motors "
                               f"{np.round(target, 3).tolist()} deg from {np.round(m, 3).tolist()} deg")

    def equilibrium(self, motors_deg, *, state=None, intermediate: bool = False):
        m = np.asarray(motors_deg, float)
        pose = self._solve(m, state)
        return self._pose(pose.q), (m.copy(), pose.q)

    def jacobian(self, state) -> np.ndarray:
        """(6, 6) the effector's motion per motor at ``state`` [mm/rad, rad/rad] (spatial rotation)."""
        m, q = state
        return self.se.jacobian(SuperPose(q[:3], q[3:], 0.0, 0), m)

    def reach(self, goal, *, state=None, tol_mm=1.0, tol_deg=None, max_steps=50, rot_weight=None,
              stop=None) -> ReachResult:
        """The inverse model's QP steps towards ``goal`` (6,) [mm, rad] from ``state`` (None: rest),
        within the motor limits; stops reached, stalled (no improvement of the weighted error in
        ``stall_steps``), at ``max_steps``, at ``stop(state)``, or past the walls' box (``left_domain``)."""
        goal = np.asarray(goal, float)
        st = (self._rest_motors.copy(), np.zeros(6)) if state is None else (np.asarray(state[0], float), state[1])
        rw = self.settings.rot_weight if rot_weight is None else max(float(rot_weight), 1e-6)
        settings = replace(self.settings, rot_weight=rw)
        lo, hi = np.radians(self.motor_range[0]), np.radians(self.motor_range[1])
        best, since, steps, stopped, left = np.inf, 0, 0, False, False
        converged = True
        for steps in range(max_steps + 1):
            pose = self._pose(st[1])
            e_mm, e_deg = pose_errors(goal, pose)
            if e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg):
                break
            err = _pose_error(goal, pose)
            w = weighted_norm(err, rw)
            best, since = (w, 0) if w < best * (1 - 1e-9) else (best, since + 1)
            if steps == max_steps or since >= self.spec.stall_steps:
                break
            q_rad = np.radians(st[0])
            qp = solve_step_qp(self.jacobian(st), err, q_rad, np.full(6, lo), np.full(6, hi), settings)
            if not qp.ok or not np.any(qp.dq):
                break
            motors = np.degrees(q_rad + qp.dq)
            try:
                _, nxt = self.equilibrium(motors, state=st)
            except ConvergenceError:
                converged = False
                break
            if stop is not None and stop(nxt):
                stopped = True
                break
            st = nxt
            if not self.inside(st[0]):
                left = True
                break
        pose = self._pose(st[1])
        e_mm, e_deg = pose_errors(goal, pose)
        ok = converged and not left and e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg)
        return ReachResult(ok, pose, st[0].copy(), e_mm, e_deg, int(steps), st, converged, left_domain=left,
                           stopped=stopped)

    def max_principal_strain(self, state) -> float:
        """The first-order bound on the walls' largest principal strain at ``state`` [-] (module
        docstring); NaN without ``wall_strain_per_deg``."""
        if self.spec.wall_strain_per_deg is None:
            return float("nan")
        d = np.asarray(state[0], float) - self._rest_motors
        w = np.asarray(self.spec.wall_strain_per_deg, float)
        return float(np.sum(np.maximum(d * w[:, 0], -d * w[:, 1])))

    def min_singular_value(self, state) -> float:
        """Smallest singular value of the Jacobian scaled by diag(1, 1, 1, 50 mm) [mm/rad]."""
        scale = np.array([1.0, 1.0, 1.0, 50.0, 50.0, 50.0])
        return float(np.linalg.svd(scale[:, None] * self.jacobian(state), compute_uv=False).min())


def _pose_error(goal, pose) -> np.ndarray:
    """(6,) from ``pose`` to ``goal`` (both (6,) [mm, rad] rotation vectors from rest): position,
    then the spatial rotation vector of ``R_goal R^T`` (:func:`metasheet.robot.qp.pose_error`)."""
    from ..mechanics.rotations import rotation_matrix
    from ..robot.qp import pose_error

    return pose_error(pose[:3], rotation_matrix(pose[3:]), goal[:3], rotation_matrix(goal[3:]))


def printed_spec(robot, K_a, K_b, references, **kw) -> PrintedSpec:
    """The :class:`PrintedSpec` of the six-DOF ``robot``'s geometry with the two sheets' grip
    stiffnesses ``K_a``, ``K_b`` (24, 24) [N/mm, N, N mm] on grip ``references`` (4, 3) [mm];
    ``kw``: the spec's other fields."""
    se = SuperelementRobot(robot, K_a, K_b, references)
    rod_axis = int(np.argmax(np.abs(np.asarray(robot.axis, float))))
    return PrintedSpec(se, tuple(float(v) for v in se.origin), rod_axis, **kw)
