"""Which stiffness tensor the five constants make: ours, or the authors' SOFA force field's.

``"ours"`` (default): :meth:`metasheet.mechanics.material.TransverseIsotropic.stiffness`, the inverse of
the compliance written with all five constants (S44 = S55 = 1 / mu_l).

``"authors"``: the tensor of the authors' ``TetrahedronAnisotropicForceField`` (VannesteFelix/
anisotropy, ``src/Anisotropy/component/forcefield/TetrahedronAnisotropicForceField.inl``,
``computeKelvinModesForElts``, transverse-isotropic branch, lines 457-475; axis 3 = their
anisotropy direction ``n`` = our soft axis l)::

    nu_lt = nu_tl E_l / E_t
    gamma = 1 / (1 - nu_t^2 - 2 nu_lt nu_tl - 2 nu_t nu_lt nu_tl)
    c11 = c22 = E_t gamma (1 - nu_lt nu_tl)          (= ours)
    c33       = E_l gamma (1 - nu_t^2)               (= ours)
    c12       = E_t gamma (nu_t + nu_lt nu_tl)       (= ours)
    c13 = c23 = E_t gamma (nu_lt + nu_t nu_tl)       (ours: E_t gamma nu_lt (1 + nu_t))
    c44 = c55 = E_t / (2 (1 + nu_t))                 (ours: mu_l; their mu_l is read, unused)
    c66       = (c11 - c12) / 2                      (= ours, the Kelvin eigenvalue c11 - c12)

Voigt order 11, 22, 33, 23, 13, 12 with engineering shear. Their Kelvin decomposition
(lines 482-578) reproduces exactly these entries. Two entries differ from ours: the
longitudinal shear (not mu_l: 34x the paper's mu_l for the published set) and c13, which
their line 449 marks "STABLE" against the consistent "UNSTABLE BUT CORRECT FORMULATION"
(line 451, commented out); both coincide only when E_l = E_t. Their tensor can be
indefinite where ours is not (large nu_tl): :func:`authors_stiffness` then raises.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from .material import Isotropic, TransverseIsotropic

#: The material models, in the order of every table: ours first.
MATERIAL_MODELS = ("ours", "authors")


def check_model(model: str, field: str = "material.model") -> str:
    """``model`` when it is one of :data:`MATERIAL_MODELS`, else a ConfigError naming ``field``."""
    if model not in MATERIAL_MODELS:
        raise ConfigError(f"{field}: {model!r}: allowed values are {', '.join(repr(m) for m in MATERIAL_MODELS)}")
    return model


def other_model(model: str) -> str:
    """The other one of the two :data:`MATERIAL_MODELS`."""
    return MATERIAL_MODELS[1 - MATERIAL_MODELS.index(check_model(model))]


def authors_entries(m: TransverseIsotropic) -> dict[str, float]:
    """The authors' c11, c12, c13, c33, c44, c66 [MPa] for ``m`` (module docstring formulas)."""
    E_t, E_l, nu_t, nu_tl = m.E_t, m.E_l, m.nu_t, m.nu_tl
    nu_lt = nu_tl * E_l / E_t
    gamma = 1.0 / (1.0 - nu_t**2 - 2.0 * nu_lt * nu_tl - 2.0 * nu_t * nu_lt * nu_tl)
    c11 = E_t * gamma * (1.0 - nu_lt * nu_tl)
    c12 = E_t * gamma * (nu_t + nu_lt * nu_tl)
    return {"c11": c11, "c12": c12, "c13": E_t * gamma * (nu_lt + nu_t * nu_tl),
            "c33": E_l * gamma * (1.0 - nu_t**2), "c44": E_t / (2.0 * (1.0 + nu_t)), "c66": 0.5 * (c11 - c12)}


def authors_stiffness(m: TransverseIsotropic) -> np.ndarray:
    """(6, 6) Voigt stiffness [MPa] of the authors' force field for ``m``, axis 3 = l.

    Raises ConfigError when it is not positive definite (c11 > |c12| and
    (c11 + c12) c33 > 2 c13^2 are the conditions; c44 > 0 always holds).
    """
    c = authors_entries(m)
    C = np.zeros((6, 6))
    C[0, 0] = C[1, 1] = c["c11"]
    C[0, 1] = C[1, 0] = c["c12"]
    C[0, 2] = C[2, 0] = C[1, 2] = C[2, 1] = c["c13"]
    C[2, 2] = c["c33"]
    C[3, 3] = C[4, 4] = c["c44"]
    C[5, 5] = c["c66"]
    det = (c["c11"] + c["c12"]) * c["c33"] - 2.0 * c["c13"] ** 2
    if not (c["c11"] > abs(c["c12"]) and c["c33"] > 0 and det > 0):
        raise ConfigError(
            f"material.model: 'authors': the authors' tensor is not positive definite for E_t={m.E_t:g}, "
            f"E_l={m.E_l:g}, nu_t={m.nu_t:g}, nu_tl={m.nu_tl:g} (condition (c11 + c12) c33 > 2 c13^2: "
            f"{(c['c11'] + c['c12']) * c['c33']:.4g} vs {2 * c['c13'] ** 2:.4g}); use model 'ours'")
    return C


def model_stiffness(material, model: str = "ours") -> np.ndarray:
    """(6, 6) Voigt stiffness [MPa] of ``material`` under ``model`` (:data:`MATERIAL_MODELS`).

    An :class:`~metasheet.mechanics.material.Isotropic` material is the same under both (their isotropic
    branch is Lame's, ``TetrahedronAnisotropicForceField.inl`` lines 671-697).
    """
    check_model(model, "model")
    if isinstance(material, Isotropic) or model == "ours":
        return material.stiffness()
    return authors_stiffness(material)


def authors_effective(m: TransverseIsotropic) -> TransverseIsotropic:
    """The five constants the authors' tensor for ``m`` really has (read off its compliance)."""
    return TransverseIsotropic.from_compliance(np.linalg.inv(authors_stiffness(m)))
