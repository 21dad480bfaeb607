"""Voigt and Mandel tensor algebra: rotating (6, 6) stiffness tensors, batched.

Voigt order 11, 22, 33, 23, 13, 12 with engineering shear (see
:mod:`metasheet.conventions`). Rotations are done in Mandel form, where a rotation
of a symmetric tensor is an orthogonal (6, 6) matrix, then converted back.
"""

from __future__ import annotations

import numpy as np

from ..conventions import MANDEL_SCALE
from ..errors import ConfigError

#: Element-wise factor turning a Voigt (6, 6) stiffness into Mandel form.
MANDEL = np.outer(MANDEL_SCALE, MANDEL_SCALE)
#: Voigt rows of the in-plane stresses (11, 22, 12) in the order 11, 22, 33, 23, 13, 12.
IN_PLANE = np.array([0, 1, 5])
#: Voigt rows of the stresses a free face carries none of through a thin plate (33, 23, 13).
OUT_OF_PLANE = np.array([2, 3, 4])


def _symmetric_basis() -> np.ndarray:
    """(6, 3, 3) orthonormal Mandel basis of symmetric tensors, Voigt order."""
    B = np.zeros((6, 3, 3))
    r = 1.0 / np.sqrt(2.0)
    for I, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))):
        if i == j:
            B[I, i, i] = 1.0
        else:
            B[I, i, j] = B[I, j, i] = r
    return B


_BASIS = _symmetric_basis()


def mandel_rotation(R: np.ndarray) -> np.ndarray:
    """(n, 6, 6) orthogonal Mandel matrices of rotations ``R`` (n, 3, 3).

    For a symmetric tensor ``s`` with Mandel vector ``m``, ``Q @ m`` is the Mandel
    vector of ``R s R^T``.
    """
    R = np.asarray(R, float)
    RB = np.einsum("nik,Jkl,njl->nJij", R, _BASIS, R, optimize=True)
    return np.einsum("Iij,nJij->nIJ", _BASIS, RB, optimize=True)


def frames_from_axes(axes: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations whose third column is the unit vector ``axes`` (n, 3).

    The first two columns complete a right-handed orthonormal frame; which one does
    not matter for transverse isotropy.
    """
    a = np.asarray(axes, float)
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    # Cross with the global axis least aligned with a, for a well-conditioned e1.
    helper = np.zeros_like(a)
    helper[np.arange(len(a)), np.argmin(np.abs(a), axis=1)] = 1.0
    e1 = np.cross(helper, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(a, e1)
    return np.stack([e1, e2, a], axis=2)


def rotate_stiffness(C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Rotate a Voigt (6, 6) tensor from the local frame to global frames.

    Parameters
    ----------
    C : (6, 6) stiffness in the local frame [MPa], engineering-shear Voigt.
    R : (n, 3, 3) rotations, columns = local axes expressed in global coordinates.

    Returns
    -------
    (n, 6, 6) global Voigt stiffnesses [MPa].
    """
    Cm = np.asarray(C, float) * MANDEL
    Q = mandel_rotation(R)
    Cg = np.einsum("nIK,KL,nJL->nIJ", Q, Cm, Q, optimize=True)
    return Cg / MANDEL


def stiffness_along(C: np.ndarray, fibers: np.ndarray) -> np.ndarray:
    """(n, 6, 6) global stiffness of a material whose local axis 3 follows ``fibers`` (n, 3).

    A zero fibre is an error; fibres need not be unit length.
    """
    f = np.asarray(fibers, float)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ConfigError(f"fibers: shape is {f.shape} and should be (n, 3)")
    norms = np.linalg.norm(f, axis=1)
    if np.any(~np.isfinite(norms)) or np.any(norms < 1e-12):
        bad = int(np.flatnonzero(~(norms >= 1e-12))[0])
        raise ConfigError(f"fibers[{bad}]: {f[bad].tolist()}: must be a non-zero finite vector")
    return rotate_stiffness(C, frames_from_axes(f))
