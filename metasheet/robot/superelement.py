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
coordinates; the gradient and Hessian are central differences of the energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError
from ..mechanics.rotations import rotation_vector
from .condensed import _check_robot
from .robots import Q_A, Q_B
from .voxel_robot import sheet_grip_poses


@dataclass(frozen=True)
class SuperPose:
    """The superelement robot's equilibrium: effector ``dp`` (3,) [mm] and rotation vector
    ``theta`` (3,) [rad] from rest, ``energy`` [mJ], Newton ``iterations``."""

    dp: np.ndarray
    theta: np.ndarray
    energy: float
    iterations: int


def local_motions(references, rotations, translations) -> np.ndarray:
    """(18,) the three arm grips' motions in the centre grip's frame (module docstring), from the
    four grips' poses (rotation vectors (4, 3) [rad], translations (4, 3) [mm] of their reference
    points, in the sheet's frame) and rest ``references`` (4, 3) [mm]."""
    from ..mechanics.rotations import rotation_matrix

    r = np.asarray(references, float)
    R = [rotation_matrix(v) for v in np.asarray(rotations, float)]
    x = r + np.asarray(translations, float)
    q = np.empty((3, 6))
    for b in range(1, 4):
        q[b - 1, :3] = R[0].T @ (x[b] - x[0]) - (r[b] - r[0])
        q[b - 1, 3:] = rotation_vector(R[0].T @ R[b])
    return q.ravel()


class SuperelementRobot:
    """The six-DOF ``robot``'s geometry with two corotational sheets of grip stiffness ``K_a``,
    ``K_b`` (24, 24, each in its sheet's frame, :mod:`metasheet.sheet.grips` conventions) and
    grip ``references`` (4, 3) [mm]."""

    def __init__(self, robot, K_a, K_b, references):
        c, centres = _check_robot(robot)
        self.K = [np.asarray(K, float)[6:, 6:] for K in (K_a, K_b)]
        if any(K.shape != (18, 18) for K in self.K):
            raise ConfigError("K_a, K_b: expected (24, 24) grip stiffnesses")
        self.refs = np.asarray(references, float)
        self.frames = ((Q_A, centres[0], list(c.servos[:3])), (Q_B, centres[1], list(c.servos[3:])))
        self.origin = np.asarray(c.origin, float)
        self.rest_angles = np.asarray([s.rest_angle for s in c.servos], float)

    def energy(self, q, motors_rad) -> float:
        """The two sheets' strain energy [mJ] at effector motion ``q`` = (dp [mm], theta [rad])."""
        dphi = np.asarray(motors_rad, float) - self.rest_angles
        e = 0.0
        for s, (Q, centre, servos) in enumerate(self.frames):
            rot, trans = sheet_grip_poses(Q, centre, self.refs, self.origin, servos, q[:3], q[3:], dphi[3 * s:3 * s + 3])
            m = local_motions(self.refs, rot, trans)
            e += 0.5 * m @ self.K[s] @ m
        return float(e)

    def equilibrium(self, motors_deg, q0=None, max_iterations: int = 50) -> SuperPose:
        """The rod's pose minimising the energy at ``motors_deg`` (6,) [deg]: Newton on central
        differences of the energy (steps 1e-4 mm / rad; the gradient to fourth order), until a step
        is below 1e-10 (mm, rad)."""
        motors = np.radians(np.asarray(motors_deg, float))
        if motors.shape != (6,) or not np.all(np.isfinite(motors)):
            raise ConfigError(f"motors_deg: {np.asarray(motors_deg).tolist()}: six finite angles [deg]")
        q = np.zeros(6) if q0 is None else np.asarray(q0, float).copy()
        d, eye = 1e-4, np.eye(6) * 1e-4
        f = lambda v: self.energy(v, motors)  # noqa: E731
        for it in range(max_iterations):
            e0 = f(q)
            ep = np.array([f(q + eye[k]) for k in range(6)])
            em = np.array([f(q - eye[k]) for k in range(6)])
            # fourth order: the energy's cubic terms (finite rotations) would leave a d^2 error
            g = (8 * (ep - em) - np.array([f(q + 2 * eye[k]) - f(q - 2 * eye[k]) for k in range(6)])) / (12 * d)
            H = np.diag((ep - 2 * e0 + em) / d**2)
            for i in range(6):
                for j in range(i + 1, 6):
                    H[i, j] = H[j, i] = (f(q + eye[i] + eye[j]) - f(q + eye[i] - eye[j]) - f(q - eye[i] + eye[j])
                                         + f(q - eye[i] - eye[j])) / (4 * d**2)
            step = -np.linalg.solve(H, g) if np.any(g != 0) else np.zeros(6)
            q = q + step
            if float(np.abs(step).max()) <= 1e-10 * (1.0 + float(np.abs(q).max())):
                return SuperPose(q[:3].copy(), q[3:].copy(), f(q), it)
        raise ConvergenceError(f"superelement robot: no equilibrium at motors {np.degrees(motors).round(3).tolist()} "
                               f"deg after {max_iterations} Newton steps")
