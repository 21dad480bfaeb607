"""The voxel element: one trilinear hexahedron, its matrices per phase.

Every voxel of a grid is the same box, so the (24, 24) stiffness, the (24, 6) unit-strain
forces and the mean strain operator exist once per phase
(:func:`metasheet.fem.hex8.hex8_box_matrices`, 2 x 2 x 2 Gauss, exact for the box). A voxel
then stores only its phase index and, optionally, a modulus scale: the matrix-free operator
(:mod:`.operator`) multiplies the phase's matrix by the scale. A phase may be anisotropic
(a transversely isotropic material), so the table holds one full matrix per phase rather
than one unit-modulus matrix times a Young's modulus.

Local node ``a = ax + 2 ay + 4 az`` (``metasheet.fem.hex8``), local dof ``3 a + i``: the
same numbering as the assembled homogenisation path, so both see the same element.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ..hex8 import hex8_box_matrices


@dataclass(frozen=True)
class PhaseTable:
    """Element matrices of every phase on one box.

    Attributes
    ----------
    K : (p, 24, 24) float [N/mm], stiffness ``int B^T C B dV`` of each phase.
    F : (p, 24, 6) float [N], nodal forces of the six unit macro strains ``int B^T C dV``.
    C : (p, 6, 6) float [MPa], the phases' Voigt stiffnesses (order 11, 22, 33, 23, 13, 12,
        engineering shear: :mod:`metasheet.conventions`).
    h : (3,) float [mm], the voxel's edge lengths.
    """

    K: np.ndarray
    F: np.ndarray
    C: np.ndarray
    h: np.ndarray

    @property
    def volume(self) -> float:
        """Volume of one voxel [mm^3]."""
        return float(np.prod(self.h))


def phase_table(stiffnesses, h) -> PhaseTable:
    """Element matrices of phases with Voigt stiffnesses ``stiffnesses`` on a box ``h``.

    Parameters
    ----------
    stiffnesses : (p, 6, 6) float [MPa], symmetric positive definite, global axes.
    h : (3,) float [mm], > 0.

    Returns
    -------
    :class:`PhaseTable`.

    Raises
    ------
    ConfigError : wrong shapes, a non-finite or non-positive-definite stiffness, h <= 0.
    """
    C = np.asarray(stiffnesses, float)
    if C.ndim == 2:
        C = C[None]
    if C.ndim != 3 or C.shape[1:] != (6, 6) or len(C) == 0:
        raise ConfigError(f"stiffnesses: shape is {np.shape(stiffnesses)} and should be (p, 6, 6)")
    h = np.asarray(h, float).reshape(-1)
    if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ConfigError(f"h: {h.tolist()}: must be three finite voxel edge lengths > 0 [mm]")
    for p, Cp in enumerate(C):
        if not np.all(np.isfinite(Cp)) or np.abs(Cp - Cp.T).max() > 1e-9 * np.abs(Cp).max():
            raise ConfigError(f"stiffnesses[{p}]: must be a finite symmetric (6, 6) matrix [MPa]")
        if np.linalg.eigvalsh(Cp)[0] <= 0:
            raise ConfigError(f"stiffnesses[{p}]: not positive definite (eigenvalues "
                              f"{np.linalg.eigvalsh(Cp).round(6).tolist()} MPa)")
    mats = [hex8_box_matrices(Cp, h) for Cp in C]
    K = np.ascontiguousarray([m[0] for m in mats])
    F = np.ascontiguousarray([m[1] for m in mats])
    return PhaseTable(K=K, F=F, C=C, h=h)


def check_phases(phases, size, given, *, name: str = "stiffnesses", item: str = "stiffness",
                 integral_floats: bool = False) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """A voxel phase grid checked at the boundary, for every voxel problem and homogenisation.

    ``phases`` (nx, ny, nz) integers, 0 = void, k > 0 = phase k (``integral_floats``: other
    numbers holding integers accepted and converted); ``size`` (3,) [mm] the box; ``given`` the keys
    the phases must be among (a mapping named ``name``, whose values are each an ``item``).
    Returns (phases as integers, size (3,) [mm], the phases present, sorted). Raises
    :class:`ConfigError` naming the field and what is allowed.
    """
    ph = np.asarray(phases)
    if ph.ndim != 3:
        raise ConfigError(f"phases: shape is {ph.shape} and should be (nx, ny, nz)")
    if min(ph.shape) < 2:
        raise ConfigError(f"phases: shape {ph.shape}: every dimension must be >= 2 voxels")
    if not np.issubdtype(ph.dtype, np.integer):
        if not (integral_floats and np.all(np.mod(ph, 1) == 0)):
            raise ConfigError(f"phases: dtype {ph.dtype}: must hold integers (0 = void, k > 0 = phase k)")
        ph = ph.astype(np.int64)
    if ph.min() < 0:
        raise ConfigError(f"phases: {int(ph.min())}: allowed values are 0 (void) and keys of {name}")
    s = np.asarray(size, float).reshape(-1)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ConfigError(f"size: {size!r}: must be three finite lengths > 0 [mm]")
    present = [int(p) for p in np.unique(ph) if p != 0]
    missing = [p for p in present if p not in given]
    if missing:
        raise ConfigError(f"{name}: phases {missing} have no {item} (given: {sorted(given)})")
    return ph, s, present


def validate_grid(phases, size, stiffnesses: dict):
    """Check the grid and the phase map; returns (index (nx, ny, nz) int64 with -1 void,
    table :class:`~.element.PhaseTable`, h (3,) [mm], present phases)."""
    ph, s, present = check_phases(phases, size, stiffnesses)
    if not present:
        raise ConfigError("phases: no solid voxel (all 0 = void)")
    h = s / np.array(ph.shape)
    table = phase_table([stiffnesses[p] for p in present], h)
    lut = np.full(int(ph.max()) + 1, -1, np.int64)
    lut[present] = np.arange(len(present))
    return lut[ph], table, h, present


def voxel_scale(scale, shape) -> np.ndarray:
    """Each voxel's modulus factor: ``scale`` (``shape``, finite, > 0), or ones when None."""
    if scale is None:
        return np.ones(shape)
    s = np.asarray(scale, float)
    if s.shape != tuple(shape):
        raise ConfigError(f"scale: shape is {s.shape} and should be {tuple(shape)} (one factor per voxel)")
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ConfigError("scale: every voxel's modulus factor must be finite and > 0")
    return np.ascontiguousarray(s)
