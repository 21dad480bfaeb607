"""A fast model of the printed robot: each sheet a corotational superelement of its four grips
(issue 62, item 3, the first candidate).

A sheet enters the robot only through its grips (:mod:`.condensed`). Here its strain energy is
the linear DNS's condensed stiffness applied in the centre grip's frame: with the centre ring at
rotation ``R_0`` and position ``x_0``, arm grip ``b`` has the local motion

    t_b = R_0^T (x_b - x_0) - (X_b - X_0),      theta_b = log(R_0^T R_b)

(``X`` at rest, ``log`` the rotation vector) and the energy is ``1/2 q^T K_rel q`` over the three
arms' local motions ``q`` (18,), ``K_rel`` the grip stiffness with the centre held (the linear
DNS's ``K[6:, 6:]``). So a rigid motion of the whole sheet costs nothing, exactly, and at rest
the model is the linear DNS's, to first order. What it leaves out is what the finite-strain DNS
(:mod:`.voxel_robot`) holds: the stiffness changing with the arms' own large bending and
twisting. How much that costs is measured against it (``benchmarks/bench_printed_robot.py``,
tests/test_robot_superelement.py).

The rod's pose at given motor angles minimises the two sheets' energy over the rod's six
coordinates ``(dp [mm], theta [rad])``. Its gradient and Hessian are central differences of the
energy, evaluated for all the stencil's points at once (:meth:`SuperelementRobot.energies`, a
batch of rotations), so that one Newton step costs one vectorised evaluation: about a
millisecond. The pose's derivative in the motors follows from the implicit function theorem,
``dq/dphi = -H_qq^-1 H_qphi``, with the mixed block by central differences too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import ConfigError, ConvergenceError
from ..mechanics.rotations import rotation_vector, skew
from .condensed import _check_robot
from .robots import Q_A, Q_B

#: central-difference step of the energy's derivatives [mm, rad]; the gradient is fourth order
FD_STEP = 3e-4
#: Newton stops after a step below this, relative to the pose (mm, rad)
STEP_TOL = 1e-10


@dataclass(frozen=True)
class SuperPose:
    """The superelement robot's equilibrium: effector ``dp`` (3,) [mm] and rotation vector
    ``theta`` (3,) [rad] from rest, ``energy`` [mJ], Newton ``iterations``."""

    dp: np.ndarray
    theta: np.ndarray
    energy: float
    iterations: int

    @property
    def q(self) -> np.ndarray:
        """(6,) ``(dp, theta)``."""
        return np.concatenate([self.dp, self.theta])


def local_motions(references, rotations, translations) -> np.ndarray:
    """(18,) the three arm grips' motions in the centre grip's frame (module docstring), from the
    four grips' poses (rotation vectors (4, 3) [rad], translations (4, 3) [mm] of their reference
    points, in the sheet's frame) and rest ``references`` (4, 3) [mm]."""
    r = np.asarray(references, float)
    R0 = Rotation.from_rotvec(np.asarray(rotations, float)[0])
    x = r + np.asarray(translations, float)
    q = np.empty((3, 6))
    for b in range(1, 4):
        q[b - 1, :3] = R0.inv().apply(x[b] - x[0]) - (r[b] - r[0])
        q[b - 1, 3:] = rotation_vector(R0.inv().as_matrix() @ Rotation.from_rotvec(np.asarray(rotations, float)[b]).as_matrix())
    return q.ravel()


def left_jacobian(theta) -> np.ndarray:
    """(3, 3) the spatial angular velocity per rate of the rotation vector ``theta`` (3,) [rad]:
    ``I + (1 - cos t)/t^2 K + (t - sin t)/t^3 K^2``, ``K = skew(theta)``."""
    th = np.asarray(theta, float)
    t = float(np.linalg.norm(th))
    K = skew(th)
    if t < 1e-6:
        return np.eye(3) + 0.5 * K + K @ K / 6.0
    return np.eye(3) + (1 - np.cos(t)) / t**2 * K + (t - np.sin(t)) / t**3 * K @ K


def _rodrigues(V) -> tuple[np.ndarray, np.ndarray]:
    """(sin t / t, (1 - cos t) / t^2), each (B,), of rotation vectors ``V`` (B, 3), series below 1e-4 rad."""
    t2 = np.einsum("bi,bi->b", V, V)
    t = np.sqrt(t2)
    small = t < 1e-4
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, np.sin(ts) / ts)
    half = np.sin(0.5 * ts) / ts  # 1 - cos t = 2 sin^2(t/2): no cancellation at small angles
    b = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, 2.0 * half * half)
    return a, b


def rotate(V, x) -> np.ndarray:
    """(B, 3) the vectors ``x`` ((3,) or (B, 3)) turned by the rotation vectors ``V`` (B, 3) [rad]."""
    a, b = _rodrigues(V)
    x = np.broadcast_to(np.asarray(x, float), V.shape)
    kx = np.cross(V, x)
    return x + a[:, None] * kx + b[:, None] * np.cross(V, kx)


def _quaternions(V) -> np.ndarray:
    """(B, 4) unit quaternions (w, x, y, z) of rotation vectors ``V`` (B, 3) [rad]."""
    t2 = np.einsum("bi,bi->b", V, V)
    t = np.sqrt(t2)
    small = t < 1e-4
    ts = np.where(small, 1.0, t)
    s = np.where(small, 0.5 - t2 / 48.0 + t2 * t2 / 3840.0, np.sin(0.5 * ts) / ts)
    return np.concatenate([np.cos(0.5 * t)[:, None], s[:, None] * V], axis=1)


def relative_rotations(V0, V1) -> np.ndarray:
    """(B, 3) the rotation vectors of ``R(V0)^T R(V1)`` [rad], |.| <= pi (quaternions)."""
    p, q = _quaternions(V0), _quaternions(V1)
    pw, pv, qw, qv = p[:, 0], -p[:, 1:], q[:, 0], q[:, 1:]  # the conjugate of p, times q
    w = pw * qw - np.einsum("bi,bi->b", pv, qv)
    v = pw[:, None] * qv + qw[:, None] * pv + np.cross(pv, qv)
    sign = np.where(w < 0, -1.0, 1.0)  # the shorter way round
    w, v = w * sign, v * sign[:, None]
    n = np.sqrt(np.einsum("bi,bi->b", v, v))
    small = n < 1e-8
    ns = np.where(small, 1.0, n)
    f = np.where(small, 2.0 / np.where(w > 0, w, 1.0), 2.0 * np.arctan2(n, w) / ns)
    return f[:, None] * v


class SuperelementRobot:
    """The six-DOF ``robot``'s geometry with two corotational sheets of grip stiffness ``K_a``,
    ``K_b`` (24, 24, each in its sheet's frame, :mod:`metasheet.sheet.grips` conventions) and
    grip ``references`` (4, 3) [mm]. Only plain arrays are kept (the model pickles small)."""

    def __init__(self, robot, K_a, K_b, references):
        c, centres = _check_robot(robot)
        self.K = np.stack([np.asarray(K, float)[6:, 6:] for K in (K_a, K_b)])
        if self.K.shape != (2, 18, 18) or not np.all(np.isfinite(self.K)):
            raise ConfigError("K_a, K_b: expected finite (24, 24) grip stiffnesses")
        self.refs = np.asarray(references, float)
        if self.refs.shape != (4, 3):
            raise ConfigError(f"references: shape {self.refs.shape}: expected (4, 3) [mm]")
        self.Q = np.stack([Q_A, Q_B])
        # the grips' reference points at rest in the world, per sheet (2, 4, 3)
        self.world = np.stack([self.refs @ Q.T + centres[s] for s, Q in enumerate(self.Q)])
        self.axes = np.array([np.asarray(s.axis, float) for s in c.servos])
        self.pivots = np.array([np.asarray(s.pivot, float) for s in c.servos])
        self.origin = np.asarray(c.origin, float)
        self.rest_angles = np.asarray([s.rest_angle for s in c.servos], float)

    # ------------------------------------------------------------------ energy
    def energies(self, Z) -> np.ndarray:
        """(B,) the two sheets' strain energy [mJ] at each row of ``Z`` (B, 12): the effector's
        ``dp`` (3) [mm] and ``theta`` (3) [rad], the six motors' change from rest (6) [rad]."""
        Z = np.atleast_2d(np.asarray(Z, float))
        B = len(Z)
        dp, th, dphi = Z[:, :3], Z[:, 3:6], Z[:, 6:]
        sheet = np.repeat([0, 1], 3)  # arm j (motor j) belongs to sheet j // 3
        # the centre grips move with the effector: in each sheet's frame (B, 2, 3)
        c = np.repeat(th, 2, axis=0)
        x0 = self.refs[0] + np.einsum("bsi,sij->bsj", (self.origin + dp[:, None] - self.world[:, 0]).reshape(B, 2, 3)
                                      + rotate(c, np.tile(self.world[:, 0] - self.origin, (B, 1))).reshape(B, 2, 3),
                                      self.Q)
        th0 = np.einsum("bi,sij->bsj", th, self.Q)  # the centres' rotation vectors, sheet frames
        # the horns turn the arm grips about the servos' axes (B, 6, 3), world
        turn = dphi[:, :, None] * self.axes
        arm_world = self.world[sheet, np.tile([1, 2, 3], 2)]  # (6, 3) the arm grips at rest
        moved = self.pivots + rotate(turn.reshape(-1, 3), np.tile(arm_world - self.pivots, (B, 1))).reshape(B, 6, 3)
        Qa = self.Q[sheet]  # (6, 3, 3)
        xk = self.refs[np.tile([1, 2, 3], 2)] + np.einsum("bji,jik->bjk", moved - arm_world, Qa)
        c0 = th0[:, sheet].reshape(-1, 3)
        m = np.empty((B, 6, 6))
        m[:, :, :3] = (rotate(-c0, (xk - x0[:, sheet]).reshape(-1, 3)).reshape(B, 6, 3)
                       - (self.refs[np.tile([1, 2, 3], 2)] - self.refs[0]))
        m[:, :, 3:] = relative_rotations(c0, np.einsum("bji,jik->bjk", turn, Qa).reshape(-1, 3)).reshape(B, 6, 3)
        m = m.reshape(B, 2, 18)
        return 0.5 * np.einsum("bsi,sij,bsj->b", m, self.K, m)

    def energy(self, q, motors_rad) -> float:
        """The two sheets' strain energy [mJ] at effector motion ``q`` = (dp [mm], theta [rad])
        and absolute motor angles ``motors_rad`` (6,) [rad]."""
        z = np.concatenate([np.asarray(q, float), np.asarray(motors_rad, float) - self.rest_angles])
        return float(self.energies(z[None])[0])

    def _derivatives(self, z) -> tuple[float, np.ndarray, np.ndarray]:
        """(energy, gradient (6,), Hessian (6, 6)) in the effector's coordinates at ``z`` (12,):
        central differences, one batch (the gradient fourth order, the Hessian second)."""
        d, eye = FD_STEP, np.eye(12)[:6] * FD_STEP
        ii, jj = np.triu_indices(6, 1)
        rows = [z[None], z + eye, z - eye, z + 2 * eye, z - 2 * eye,
                z + eye[ii] + eye[jj], z + eye[ii] - eye[jj], z - eye[ii] + eye[jj], z - eye[ii] - eye[jj]]
        e = self.energies(np.concatenate(rows))
        e0, ep, em, e2p, e2m = e[0], e[1:7], e[7:13], e[13:19], e[19:25]
        n = len(ii)
        pp, pm, mp, mm = (e[25 + n * k:25 + n * (k + 1)] for k in range(4))
        g = (8 * (ep - em) - (e2p - e2m)) / (12 * d)
        H = np.diag((ep - 2 * e0 + em) / d**2)
        H[ii, jj] = H[jj, ii] = (pp - pm - mp + mm) / (4 * d * d)
        return float(e0), g, H

    # ------------------------------------------------------------------ equilibrium
    def equilibrium(self, motors_deg, q0=None, max_iterations: int = 50) -> SuperPose:
        """The rod's pose minimising the energy at ``motors_deg`` (6,) [deg], from ``q0`` (6,)
        (None: rest): Newton on the central differences (a step that raises the energy is
        halved, found at the next step's own evaluation), until a step is below
        :data:`STEP_TOL` (mm, rad) relative to the pose."""
        motors = np.radians(np.asarray(motors_deg, float))
        if motors.shape != (6,) or not np.all(np.isfinite(motors)):
            raise ConfigError(f"motors_deg: {np.asarray(motors_deg).tolist()}: six finite angles [deg]")
        dphi = motors - self.rest_angles
        q = np.zeros(6) if q0 is None else np.asarray(q0, float).copy()
        last, step, halved, previous = np.inf, np.zeros(6), 0, np.inf
        for it in range(max_iterations):
            e0, g, H = self._derivatives(np.concatenate([q, dphi]))
            if e0 > last + 1e-12 * abs(last) and halved < 30:  # the last step raised the energy: half of it
                step, halved = 0.5 * step, halved + 1
                q = q - step
                continue
            last, halved = e0, 0
            try:
                step = -np.linalg.solve(H, g) if np.any(g != 0) else np.zeros(6)
            except np.linalg.LinAlgError:
                step = np.zeros(6)
            if not np.all(np.isfinite(step)) or g @ step > 0:  # not a descent direction: gradient
                step = -g / max(float(np.abs(np.diag(H)).max()), 1e-30)
            q = q + step
            # the differenced gradient's round-off keeps steps at ~1e-10 to 1e-9 mm: stop below
            # STEP_TOL, or once small steps stop contracting (round-off, not convergence, moves q)
            size, scale = float(np.abs(step).max()), 1.0 + float(np.abs(q).max())
            if size <= STEP_TOL * scale or (size <= 1e-6 * scale and size > 0.5 * previous):
                return SuperPose(q[:3].copy(), q[3:].copy(), self.energy(q, motors), it)
            previous = size
        raise ConvergenceError(f"superelement robot: no equilibrium at motors {np.degrees(motors).round(3).tolist()} "
                               f"deg after {max_iterations} Newton steps")

    def jacobian(self, pose: SuperPose, motors_deg) -> np.ndarray:
        """(6, 6) the effector's motion per motor [mm/rad, rad/rad] at the equilibrium ``pose`` of
        ``motors_deg``: position rows ``d dp / d phi``, rotation rows the spatial angular
        velocity (the rate of ``theta`` through :func:`left_jacobian`), as the inverse model's
        pose error measures a rotation."""
        z = np.concatenate([pose.q, np.radians(np.asarray(motors_deg, float)) - self.rest_angles])
        _, _, H = self._derivatives(z)
        d, eye = FD_STEP, np.eye(12) * FD_STEP
        a, b = np.repeat(np.arange(6), 6), np.tile(np.arange(6, 12), 6)  # (q_i, phi_j) pairs
        e = self.energies(np.concatenate([z + eye[a] + eye[b], z + eye[a] - eye[b], z - eye[a] + eye[b],
                                          z - eye[a] - eye[b]]))
        n = 36
        Hqp = ((e[:n] - e[n:2 * n] - e[2 * n:3 * n] + e[3 * n:]) / (4 * d * d)).reshape(6, 6)
        dq = -np.linalg.solve(H, Hqp)
        dq[3:] = left_jacobian(pose.theta) @ dq[3:]
        return dq


def pose_errors_against(reference, model: SuperelementRobot, motors_deg) -> list[dict]:
    """The superelement ``model`` against a ``reference`` robot (the finite-strain voxel robot,
    :class:`.voxel_robot.PrintedRobot`, or anything whose ``equilibrium(motors_deg)`` returns a
    pose with ``dp`` and ``theta``) at each row of ``motors_deg`` (n, 6) [deg]: per pose the
    reference's motion (``move_mm``, ``turn_deg``) and the model's errors (``error_mm``, the
    distance of the rod's centres; ``error_deg``, the angle of the rotation between them)."""
    out = []
    for m in np.atleast_2d(np.asarray(motors_deg, float)):
        ref, got = reference.equilibrium(m), model.equilibrium(m)
        R = Rotation.from_rotvec(np.asarray(ref.theta, float)) * Rotation.from_rotvec(got.theta).inv()
        out.append({"motors_deg": m.tolist(), "move_mm": float(np.linalg.norm(ref.dp)),
                    "turn_deg": float(np.degrees(np.linalg.norm(ref.theta))),
                    "error_mm": float(np.linalg.norm(np.asarray(ref.dp, float) - got.dp)),
                    "error_deg": float(np.degrees(R.magnitude()))})
    return out
