"""Compliance and direct Jacobian of the robot (paper eq. 6-7).

Eq. (6) is condensed onto the rigid coordinates q_r = (q_e (6), q_a (na)): with ``K_ff``
factorised once and solved with all 6 + na rigid columns at once (:class:`.statics.Linearizer`),
the Schur complement ``S = A_rr - C K_ff^-1 B`` is the stiffness seen by the rigid bodies and

    W = S^-1                                  compliance, (6 + na, 6 + na)
    dq_e = W_ea W_aa^-1 dq_a                  direct Jacobian (eq. 7)

(equal to ``-S_ee^-1 S_ea``: the effector's equilibrium with the motors held). Units: q_e in
(mm, rad), q_a in rad, so ``J[:3]`` is mm/rad and ``J[3:]`` rad/rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .statics import Linearization, RobotState

DOF_NAMES = ("x", "y", "z", "rx", "ry", "rz")


@dataclass(frozen=True)
class Kinematics:
    """Linear kinematics at one equilibrium.

    Attributes
    ----------
    W : (6 + na, 6 + na) compliance (mm/N, rad/(N mm), mixed) of eq. (6).
    J : (6, na) direct Jacobian dq_e / dq_a (mm/rad and rad/rad), eq. (7).
    singular_values : (min(6, na),) singular values [mm/rad] of diag(1, 1, 1, L, L, L) J,
        L = ``length_scale`` [mm/rad] (rotations counted as arc lengths at radius L).
    per_degree : (6, na) effector motion per degree of each motor, (mm, deg) per deg.
    all_together : (6,) effector motion per degree when every motor moves by +1 degree
        (mm and deg).
    """

    W: np.ndarray
    J: np.ndarray
    singular_values: np.ndarray
    length_scale: float
    per_degree: np.ndarray
    all_together: np.ndarray

    def authority(self) -> dict:
        """Per effector DOF, the largest motion per degree any single motor gives (mm or deg)."""
        return {n: float(np.max(np.abs(self.per_degree[i]))) for i, n in enumerate(DOF_NAMES)}

    def to_dict(self) -> dict:
        return {
            "J_mm_per_rad_and_rad_per_rad": self.J.tolist(),
            "W": self.W.tolist(),
            "singular_values": self.singular_values.tolist(),
            "singular_values_length_scale_mm": self.length_scale,
            "per_degree_mm_or_deg": self.per_degree.tolist(),
            "all_motors_plus_1deg_mm_or_deg": dict(zip(DOF_NAMES, self.all_together.tolist())),
            "authority_per_degree": self.authority(),
        }


def jacobian_from_schur(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(W, J) from the condensed matrix S (6 + na, 6 + na): W = S^-1, J = W_ea W_aa^-1."""
    W = np.linalg.inv(S)
    J = np.linalg.solve(W[6:, 6:].T, W[:6, 6:].T).T
    return W, J


def kinematics(lin: Linearization, *, length_scale: float = 50.0) -> Kinematics:
    """Compliance W, Jacobian J and derived numbers from a linearisation.

    ``length_scale`` [mm] turns rotations into lengths for the singular values
    (a rotation of 1 rad counts like a displacement of ``length_scale`` mm), so that
    translations and rotations are comparable; 50 mm ~ the sheet's arm length.
    """
    return kinematics_from_schur(lin.S, length_scale=length_scale)


def kinematics_from_schur(S: np.ndarray, *, length_scale: float = 50.0) -> Kinematics:
    """:func:`kinematics` from a condensed matrix S (6 + na, 6 + na) however it was obtained
    (e.g. from condensed sheets, :mod:`.condensed`)."""
    W, J = jacobian_from_schur(S)
    scale = np.array([1.0, 1.0, 1.0, length_scale, length_scale, length_scale])
    sv = np.linalg.svd(scale[:, None] * J, compute_uv=False)
    to_deg = np.array([1.0, 1.0, 1.0, 180.0 / np.pi, 180.0 / np.pi, 180.0 / np.pi])
    per_degree = (to_deg[:, None] * J) * (np.pi / 180.0)
    return Kinematics(W, J, sv, length_scale, per_degree, per_degree.sum(axis=1))


def kinematics_at(robot, state: RobotState, *, length_scale: float = 50.0) -> Kinematics:
    """:func:`kinematics` at ``state`` (which should be an equilibrium)."""
    return kinematics(robot.linearizer().linearize(state), length_scale=length_scale)
