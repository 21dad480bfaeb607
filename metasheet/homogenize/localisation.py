"""Strain localisation: how much larger the local strain is than the macro strain.

A homogenised model is a small-strain model; if a unit macro strain produces a local
principal strain ``r`` times larger, the model leaves its validity once the macro
strain reaches (local strain limit) / r. The ratios below give that ``r`` per load case.
"""

from __future__ import annotations

import numpy as np

from .result import Localisation

#: Largest |principal strain| of each unit Voigt macro strain (engineering shear 1 -> 0.5).
_MACRO_PRINCIPAL = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])


def voigt_to_tensor(eps: np.ndarray) -> np.ndarray:
    """(..., 3, 3) strain tensors from (..., 6) Voigt strains with engineering shear."""
    e = np.asarray(eps, float)
    T = np.empty(e.shape[:-1] + (3, 3))
    T[..., 0, 0], T[..., 1, 1], T[..., 2, 2] = e[..., 0], e[..., 1], e[..., 2]
    T[..., 1, 2] = T[..., 2, 1] = 0.5 * e[..., 3]
    T[..., 0, 2] = T[..., 2, 0] = 0.5 * e[..., 4]
    T[..., 0, 1] = T[..., 1, 0] = 0.5 * e[..., 5]
    return T


def localisation(strain: np.ndarray, volumes: np.ndarray) -> Localisation:
    """Localisation measures from element strains.

    Parameters
    ----------
    strain : (m, 6, 6) float [-], element Voigt strain per unit macro load case.
    volumes : (m,) float [mm^3], element volumes (weights of the percentile).

    Returns
    -------
    :class:`~metasheet.homogenize.result.Localisation`.
    """
    strain = np.asarray(strain, float)
    principal = np.abs(np.linalg.eigvalsh(voigt_to_tensor(strain))).max(axis=-1)  # (m, 6)
    ratio_max = principal.max(axis=0) / _MACRO_PRINCIPAL
    p99 = np.array([_weighted_quantile(principal[:, j], volumes, 0.99) for j in range(6)])
    return Localisation(strain, principal, ratio_max, p99 / _MACRO_PRINCIPAL)


def _weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    order = np.argsort(values, kind="stable")
    cw = np.cumsum(np.asarray(weights, float)[order])
    return float(values[order][min(np.searchsorted(cw, q * cw[-1]), len(values) - 1)])
