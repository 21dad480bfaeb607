"""A transverse-isotropic stiffness turned in the sheet plane, and its derivative in the angle.

The material's local axis 3 (the soft l axis, :class:`~metasheet.mechanics.material.TransverseIsotropic`)
follows the in-plane fibre ``(cos theta, sin theta, 0)`` of the sheet frame
(:mod:`.fibre_field`'s convention). In Mandel form (where rotating a symmetric tensor is an
orthogonal 6 x 6 matrix, :mod:`metasheet.mechanics.voigt`)

    C(theta) = Q(theta) C_x Q(theta)^T,    Q(theta) = mandel_rotation(Rz(theta)) = exp(theta Omega),
    dC/dtheta = Omega C(theta) - C(theta) Omega,

with ``C_x`` the tensor whose l axis lies along sheet x and ``Omega`` (skew, 6 x 6) the
Mandel generator of rotations about z. Exact, no finite differences; a transverse-isotropic
tensor does not care about the frame's roll about l, so this is the same tensor
:func:`metasheet.mechanics.voigt.stiffness_along` builds (to round-off), and an isotropic one gives
``dC/dtheta = 0`` to round-off (it commutes with every rotation).
The robot's world frame is reached by one more fixed rotation per sheet
(:data:`metasheet.robot.robots.Q_A`, ``Q_B``), applied to C and dC/dtheta alike.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import skew
from ..mechanics.voigt import MANDEL, mandel_rotation

#: local -> sheet frame taking the material's axis 3 to sheet x (columns: local axes 1, 2, 3)
_L_ALONG_X = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _check_voigt(C) -> np.ndarray:
    C = np.asarray(C, float)
    if C.shape != (6, 6) or not np.all(np.isfinite(C)):
        raise ConfigError(f"stiffness: shape {C.shape}: expected a finite (6, 6) Voigt tensor [MPa]")
    return C


def mandel_generator(axis=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(6, 6) skew Mandel generator of rotations about the unit ``axis`` [-/rad]:
    ``d/dt mandel_rotation(Rot(axis, t)) = Omega mandel_rotation(Rot(axis, t))``.

    ``mandel_rotation(R)`` has entries ``B_I : (R B_J R^T)`` (B the orthonormal Mandel basis):
    quadratic in R, also for a matrix that is not a rotation. So with ``G = [axis]x`` the
    quadratic terms cancel in ``(Q(I + G) - Q(I - G)) / 2`` and what is left is exactly the
    derivative at R = I in the direction G (no finite-difference error, round-off only).
    """
    G = skew(np.asarray(axis, float))
    I3 = np.eye(3)
    return 0.5 * (mandel_rotation((I3 + G)[None])[0] - mandel_rotation((I3 - G)[None])[0])


_OMEGA_Z = mandel_generator((0.0, 0.0, 1.0))


def along_x_mandel(C_local) -> np.ndarray:
    """(6, 6) Mandel tensor [MPa] of ``C_local`` (Voigt, axis 3 = l) with l along sheet x."""
    Q = mandel_rotation(_L_ALONG_X[None])[0]
    return Q @ (_check_voigt(C_local) * MANDEL) @ Q.T


def inplane_mandel(C_local, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sheet-frame Mandel stiffness C(theta) and dC/dtheta, each (m, 6, 6) [MPa, MPa/rad], of
    ``C_local`` (6, 6) Voigt [MPa] (axis 3 = l) with l along ``(cos theta, sin theta, 0)``,
    ``theta`` (m,) [rad]."""
    th = np.asarray(theta, float)
    c, s = np.cos(th), np.sin(th)
    R = np.zeros((len(th), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    Q = mandel_rotation(R)
    Cx = along_x_mandel(C_local)
    C = np.matmul(np.matmul(Q, Cx), np.transpose(Q, (0, 2, 1)))
    C = 0.5 * (C + np.transpose(C, (0, 2, 1)))
    OC = np.matmul(_OMEGA_Z, C)
    # Omega C - C Omega, written as Omega C + (Omega C)^T (Omega is skew, C symmetric): exactly symmetric
    return C, OC + np.transpose(OC, (0, 2, 1))


def to_frame_mandel(C: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(m, 6, 6) Mandel tensors ``C`` re-expressed after the fixed rotation ``Q`` (3, 3)
    (sheet -> world): ``Qm C Qm^T``."""
    Qm = mandel_rotation(np.asarray(Q, float)[None])[0]
    return np.matmul(np.matmul(Qm, C), Qm.T)


def to_voigt(Cm: np.ndarray) -> np.ndarray:
    """Voigt (engineering shear) form of Mandel tensors ``Cm`` (..., 6, 6)."""
    return Cm / MANDEL
