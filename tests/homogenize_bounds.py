"""Analytic references: Voigt and Hashin-Shtrikman upper bounds, the exact laminate.

Independent answers the homogenisation tests compare against (a helper module, no tests
here; it lived in ``metasheet/homogenize/bounds.py``, which no library code used).

- Voigt (uniform strain): ``C_V = sum_k f_k C_k`` with void contributing 0; for any
  microstructure ``C_V - C*`` is positive semi-definite (energy bound).
- Hashin-Shtrikman upper bounds for an isotropic solid (K, G) of volume fraction
  ``f`` with void (Hashin & Shtrikman 1963; Torquato, *Random Heterogeneous
  Materials*, eq. 21.5)::

      K_HS = K + (1 - f) / (-1 / K + 3 f / (3 K + 4 G))
      G_HS = G + (1 - f) / (-1 / G + 6 f (K + 2 G) / (5 G (3 K + 4 G)))

  The bulk bound holds for any geometry in the form ``I:C*:I / 9 <= K_HS``
  (hydrostatic strain energy).
- Backus laminate, layers normal to axis 3: stresses 33, 23, 13 and strains 11, 22,
  12 are continuous across layers, which gives the exact effective tensor
  (Backus 1962; in block form e.g. Milton, *The Theory of Composites*, sec. 9.5).
"""

from __future__ import annotations

import numpy as np

from metasheet.mechanics.material import Isotropic

_T = [0, 1, 5]  # in-plane components (strain continuous)
_N = [2, 3, 4]  # out-of-plane components (stress continuous)


def voigt_bound(stiffnesses, fractions) -> np.ndarray:
    """(6, 6) Voigt average [MPa] of phase stiffnesses (k, 6, 6) with volume fractions (k,).

    Fractions may sum to less than 1: the rest is void.
    """
    return np.einsum("k,kij->ij", np.asarray(fractions, float), np.asarray(stiffnesses, float))


def hashin_shtrikman_upper(solid: Isotropic, fraction: float) -> tuple[float, float]:
    """Upper bounds (K_HS, G_HS) [MPa] on bulk and shear moduli of a porous isotropic solid.

    Parameters
    ----------
    solid : the solid phase; fraction : its volume fraction in (0, 1].
    """
    K, G, f = solid.bulk, solid.mu, float(fraction)
    if f >= 1.0:
        return K, G
    k_hs = K + (1 - f) / (-1.0 / K + 3 * f / (3 * K + 4 * G))
    g_hs = G + (1 - f) / (-1.0 / G + 6 * f * (K + 2 * G) / (5 * G * (3 * K + 4 * G)))
    return float(k_hs), float(g_hs)


def hydrostatic_modulus(C: np.ndarray) -> float:
    """``I:C:I / 9`` [MPa]: the bulk modulus seen by a hydrostatic strain."""
    return float(np.asarray(C)[:3, :3].sum() / 9.0)


def backus_laminate(stiffnesses, fractions) -> np.ndarray:
    """Exact (6, 6) stiffness [MPa] of a laminate of layers normal to axis 3.

    Parameters
    ----------
    stiffnesses : (k, 6, 6) Voigt stiffness of each layer in global axes [MPa].
    fractions : (k,) thickness fractions, summing to 1.
    """
    C = np.asarray(stiffnesses, float)
    f = np.asarray(fractions, float)
    f = f / f.sum()
    Cnn = C[:, _N][:, :, _N]
    Ctn = C[:, _T][:, :, _N]
    Ctt = C[:, _T][:, :, _T]
    inv = np.linalg.inv(Cnn)
    A = np.einsum("kij,kjl->kil", Ctn, inv)  # C_tn C_nn^-1
    nn = np.linalg.inv(np.einsum("k,kij->ij", f, inv))
    a = np.einsum("k,kij->ij", f, A)
    tt = np.einsum("k,kij->ij", f, Ctt - np.einsum("kij,klj->kil", A, Ctn)) + a @ nn @ a.T
    out = np.zeros((6, 6))
    out[np.ix_(_N, _N)] = nn
    out[np.ix_(_T, _N)] = a @ nn
    out[np.ix_(_N, _T)] = (a @ nn).T
    out[np.ix_(_T, _T)] = tt
    return out
