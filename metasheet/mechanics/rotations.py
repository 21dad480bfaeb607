"""Rotations in 3D: cross-product matrices, Rodrigues' formula and its inverse.

The one place of the package for rotation vectors (the robot's effector and servo horns,
:mod:`metasheet.robot.rigid`; the studies' pose errors, :mod:`metasheet.studies.model`).
Needs numpy only, so any module may import it.

Conventions: a rotation vector ``w`` (3,) [rad] is the axis times the angle, ``|w| <= pi``
when it comes from :func:`rotation_vector`; ``R = exp([w]x)`` (3, 3) acts on column vectors.
"""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) cross-product matrices, ``skew(a) @ b = a x b``."""
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` for (..., 3) arrays (broadcast), the same bits as ``np.cross``.

    Each component is one product minus another, in ``np.cross``'s order
    (``a1 b2 - a2 b1``, ``a2 b0 - a0 b2``, ``a0 b1 - a1 b0``), without its axis handling:
    the robot's hot loops call it thousands of times a study point on small arrays, where
    ``np.cross`` spends ~0.3 ms in bookkeeping (9 % of a P1 study point).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


_EYE3 = np.eye(3)
_EYE3.flags.writeable = False


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation vector (3,) [rad] -> rotation matrix (3, 3).

    ``R = I + sin(t)/t K + (1 - cos(t))/t^2 K^2`` with ``K = skew(w)``, ``t = |w|``.
    """
    w = np.asarray(rotvec, dtype=float)
    t = float(np.sqrt(w @ w))  # np.linalg.norm's own sum for a vector
    w0, w1, w2 = w
    K = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])  # skew(w)
    if t < 1e-8:  # second-order series: exact to rounding for |w| < 1e-8
        return _EYE3 + K + 0.5 * K @ K
    return _EYE3 + np.sin(t) / t * K + (1.0 - np.cos(t)) / t**2 * K @ K


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rotation_matrix`: (3, 3) -> rotation vector (3,) [rad], |w| <= pi."""
    R = np.asarray(R, dtype=float)
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    t = float(np.arccos(c))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    if t < 1e-6:
        return v  # sin t ~ t
    if np.pi - t < 1e-4:  # near pi the skew part vanishes: use the symmetric part
        B = (R + np.eye(3)) / 2.0
        axis = np.sqrt(np.clip(np.diag(B), 0.0, None))
        i = int(np.argmax(axis))
        axis = B[i] / axis[i]
        axis /= np.linalg.norm(axis)
        if np.dot(axis, v) < 0:
            axis = -axis
        return axis * t
    return v * (t / np.sin(t))


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) about the unit ``axis`` (3,) by ``angle`` [rad]."""
    return rotation_matrix(np.asarray(axis, dtype=float) * angle)

