"""What a fibre design is judged on at the rest pose: functions of the direct Jacobian J (eq. 7).

J (6, na) is dq_e / dq_a: the effector's (x, y, z [mm], rx, ry, rz [rad]) motion per radian of
each motor (:mod:`metasheet.robot.kinematics`). Each objective here is a smooth function of J
(where it is defined) and comes with its derivative as a rank-one weight pair: for an
objective g, ``dg = alpha^T dJ beta`` with ``alpha`` (6,) and ``beta`` (na,), which is all the
adjoint (:mod:`.adjoint`) needs to turn dJ into a gradient over the design.

* :func:`rod_roll_per_degree` [deg/deg]: the 6th DOF's authority, the rotation about the rod
  axis per degree when every motor moves by +1 degree together; what
  :func:`metasheet.robot.compare.evaluate` reports as ``rod_rotation_per_degree`` (from
  ``Kinematics.all_together``). Linear in J.
* :func:`min_singular_value` [mm/rad]: the smallest singular value of ``diag(1, 1, 1, L, L, L) J``
  (L = ``length_scale`` [mm], rotations counted as arc lengths), the
  ``Kinematics.singular_values[-1]`` of the kinematics; how far the robot is from losing a DOF.
  Differentiable where it is simple (its gap to the next one is reported).
* :func:`decoupling`: what else the effector does during that roll (``J @ 1``): the parasitic
  translation [mm per motor degree] and tilt (rotation about axes perpendicular to the rod)
  [deg per motor degree], and both per degree of roll. Reported, not optimised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: [mm] the kinematics' default length scale (rotations as arc lengths at 50 mm ~ an arm)
LENGTH_SCALE = 50.0


def _check_jacobian(J) -> np.ndarray:
    J = np.asarray(J, float)
    if J.ndim != 2 or J.shape[0] != 6 or J.shape[1] < 1 or not np.all(np.isfinite(J)):
        raise ConfigError(f"J: shape {J.shape}: expected a finite (6, na) Jacobian")
    return J


def _unit_axis(axis) -> np.ndarray:
    a = np.asarray(axis, float)
    n = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
    if not np.isfinite(n) or n < 1e-12:
        raise ConfigError(f"axis: {np.asarray(axis).tolist()!r}: expected a finite non-zero 3-vector")
    return a / n


@dataclass(frozen=True)
class RankOne:
    """The derivative of an objective g of J as ``dg = alpha^T dJ beta``.

    Attributes
    ----------
    value : g(J), in the objective's unit.
    alpha : (6,) effector-side weight; beta : (na,) motor-side weight.
    gap : how far the value is from a point where g stops being differentiable, in its unit
        (inf for a linear objective; for a singular value its distance to the next one).
    """

    value: float
    alpha: np.ndarray
    beta: np.ndarray
    gap: float = float("inf")


def rod_roll_per_degree(J, axis) -> float:
    """Rotation about the rod ``axis`` (3,) per degree of all motors together [deg/deg]:
    ``axis . (J[3:] @ 1)`` (rad per rad is deg per deg)."""
    return rod_roll_weights(J, axis).value


def rod_roll_weights(J, axis) -> RankOne:
    """:func:`rod_roll_per_degree` and its weights: alpha = (0, 0, 0, axis), beta = 1."""
    J = _check_jacobian(J)
    alpha = np.concatenate([np.zeros(3), _unit_axis(axis)])
    beta = np.ones(J.shape[1])
    return RankOne(float(alpha @ J @ beta), alpha, beta)


def scaled_singular_values(J, length_scale: float = LENGTH_SCALE) -> np.ndarray:
    """(min(6, na),) singular values [mm/rad] of ``diag(1, 1, 1, L, L, L) J``, largest first."""
    J = _check_jacobian(J)
    return np.linalg.svd(_scale(length_scale)[:, None] * J, compute_uv=False)


def min_singular_value(J, length_scale: float = LENGTH_SCALE) -> float:
    """The smallest of :func:`scaled_singular_values` [mm/rad]."""
    return float(scaled_singular_values(J, length_scale)[-1])


def min_singular_weights(J, length_scale: float = LENGTH_SCALE) -> RankOne:
    """:func:`min_singular_value` and its weights: with ``D J = U s V^T`` and (u, v) the pair of
    the smallest s, ``ds = u^T D dJ v``, so alpha = D u, beta = v (valid where s is simple:
    ``gap`` is its distance to the next singular value [mm/rad]; the signs of u and v cancel)."""
    J = _check_jacobian(J)
    if J.shape[1] > 6:
        raise ConfigError(f"J: shape {J.shape}: the smallest singular value needs na <= 6 motors")
    return singular_weights(J, min(J.shape) - 1, length_scale)


def singular_weights(J, k: int, length_scale: float = LENGTH_SCALE) -> RankOne:
    """The ``k``-th (0-based, largest first) of :func:`scaled_singular_values` [mm/rad] and its
    weights alpha = D u_k, beta = v_k (as :func:`min_singular_weights`; ``gap`` is its distance
    to the nearer neighbour [mm/rad], where the sorted value stops being differentiable)."""
    J = _check_jacobian(J)
    D = _scale(length_scale)
    U, s, Vt = np.linalg.svd(D[:, None] * J, full_matrices=False)
    if not 0 <= k < len(s):
        raise ConfigError(f"k: {k!r}: allowed range is [0, {len(s) - 1}]")
    near = [abs(s[k] - s[j]) for j in (k - 1, k + 1) if 0 <= j < len(s)]
    return RankOne(float(s[k]), D * U[:, k], Vt[k].copy(), float(min(near)) if near else float("inf"))


def roll_index(J, axis, length_scale: float = LENGTH_SCALE) -> int:
    """The index (largest first) of the scaled singular value whose effector direction is the
    rod roll: the left singular vector of ``D J`` (6,) closest to ``(0, 0, 0, axis)``. The other
    five are "the other five singular values" that a design must not lower."""
    J = _check_jacobian(J)
    e = np.concatenate([np.zeros(3), _unit_axis(axis)])
    U = np.linalg.svd(_scale(length_scale)[:, None] * J, full_matrices=False)[0]
    return int(np.argmax(np.abs(e @ U)))


def other_five_weights(J, axis, length_scale: float = LENGTH_SCALE) -> RankOne:
    """The smallest singular value [mm/rad] of ``D J`` projected on the five effector directions
    orthogonal to the roll ``(0, 0, 0, axis)`` (``P = U^T D J``, U (6, 5) an orthonormal basis of
    the complement), and its weights: ``ds = u^T U^T D dJ v``, so alpha = D U u, beta = v (valid
    where s is simple: ``gap`` [mm/rad])."""
    J = _check_jacobian(J)
    D = _scale(length_scale)
    e = np.concatenate([np.zeros(3), _unit_axis(axis)])
    Uc = np.linalg.svd(e[:, None], full_matrices=True)[0][:, 1:]
    U, s, Vt = np.linalg.svd(Uc.T @ (D[:, None] * J), full_matrices=False)
    k = len(s) - 1
    gap = float(s[k - 1] - s[k]) if k > 0 else float("inf")
    return RankOne(float(s[k]), D * (Uc @ U[:, k]), Vt[k].copy(), gap)


@dataclass(frozen=True)
class Decoupling:
    """The effector's motion besides the roll while every motor moves by +1 degree together.

    Attributes
    ----------
    translation_mm_per_deg : |J[:3] @ 1| in mm per motor degree.
    tilt_deg_per_deg : |(I - a a^T) J[3:] @ 1|, the rotation about axes perpendicular to the
        rod axis a [deg per motor degree].
    roll_deg_per_deg : a . J[3:] @ 1 (signed) [deg/deg], as :func:`rod_roll_per_degree`.
    translation_per_roll : translation / |roll| [mm per degree of roll] (inf without roll).
    tilt_per_roll : tilt / |roll| [-] (inf without roll).
    """

    translation_mm_per_deg: float
    tilt_deg_per_deg: float
    roll_deg_per_deg: float
    translation_per_roll: float
    tilt_per_roll: float


def decoupling(J, axis) -> Decoupling:
    """The parasitic motion of the all-together move ``J @ 1`` (J (6, na): mm/rad, rad/rad) about
    the rod ``axis`` (3,): a motor degree is pi/180 rad, so translation [mm/deg] = |J[:3] 1| pi/180,
    and a rotation in rad/rad is one in deg/deg."""
    J = _check_jacobian(J)
    a = _unit_axis(axis)
    v = J @ np.ones(J.shape[1])
    roll = float(a @ v[3:])
    t = float(np.linalg.norm(v[:3])) * np.pi / 180.0
    tilt = float(np.linalg.norm(v[3:] - roll * a))
    per = (lambda x: x / abs(roll)) if roll != 0.0 else (lambda x: float("inf"))
    return Decoupling(t, tilt, roll, per(t), per(tilt))


def _scale(length_scale: float) -> np.ndarray:
    L = float(length_scale)
    if not np.isfinite(L) or L <= 0:
        raise ConfigError(f"length_scale: {length_scale!r}: allowed range is (0, inf) [mm]")
    return np.array([1.0, 1.0, 1.0, L, L, L])
