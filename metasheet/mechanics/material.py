"""Linear elastic materials: isotropic and transverse-isotropic, in Voigt notation.

Conventions (see :mod:`metasheet.conventions`): stresses in MPa, Voigt order
11, 22, 33, 23, 13, 12 with engineering shear strains; the transverse-isotropic
longitudinal axis ``l`` is local axis 3.

Transverse isotropy about axis 3 (compliance, e.g. Jones, *Mechanics of Composite
Materials*, ch. 2)::

    S11 = S22 = 1/E_t        S33 = 1/E_l
    S12 = -nu_t/E_t          S13 = S23 = -nu_tl/E_t = -nu_lt/E_l
    S44 = S55 = 1/mu_l       S66 = 2 (1 + nu_t)/E_t

so ``nu_lt = nu_tl E_l / E_t`` is derived, never given: the compliance is
symmetric by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import voigt  # the Voigt/Mandel rotations live there only (not re-exported)
from ..conventions import VOIGT_PAIRS
from ..errors import ConfigError
from .voigt import MANDEL as _MANDEL


#: The five independent transverse-isotropic constants, in the order of every table and file.
CONSTANT_NAMES = ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")


def _finite_positive(name: str, value: float) -> float:
    v = float(value)
    if not np.isfinite(v) or v <= 0.0:
        raise ConfigError(f"{name}: {value!r}: must be a finite number > 0 [MPa]")
    return v


@dataclass(frozen=True)
class Isotropic:
    """Isotropic linear elastic material.

    Parameters
    ----------
    E : Young's modulus [MPa], > 0.
    nu : Poisson ratio [-], in (-1, 0.5).
    """

    E: float
    nu: float

    def __post_init__(self):
        _finite_positive("E", self.E)
        if not (-1.0 < float(self.nu) < 0.5):
            raise ConfigError(
                f"nu: {self.nu!r}: condition -1 < nu < 0.5 violated (positive-definite stiffness)"
            )

    @property
    def mu(self) -> float:
        """Shear modulus [MPa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lam(self) -> float:
        """First Lame parameter [MPa]."""
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    @property
    def bulk(self) -> float:
        """Bulk modulus [MPa]."""
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))

    def compliance(self) -> np.ndarray:
        """(6, 6) compliance [1/MPa], Voigt, engineering shear."""
        return self.as_transverse().compliance()

    def stiffness(self) -> np.ndarray:
        """(6, 6) stiffness [MPa], Voigt, engineering shear."""
        lam, mu = self.lam, self.mu
        C = np.zeros((6, 6))
        C[:3, :3] = lam
        C[np.arange(3), np.arange(3)] = lam + 2.0 * mu
        C[np.arange(3, 6), np.arange(3, 6)] = mu
        return C

    def as_transverse(self) -> "TransverseIsotropic":
        """The same material written as a (degenerate) transverse-isotropic one."""
        return TransverseIsotropic(self.E, self.E, self.nu, self.nu, self.mu)


@dataclass(frozen=True)
class TransverseIsotropic:
    """Transverse-isotropic material, longitudinal axis = local axis 3.

    Parameters
    ----------
    E_t : transverse Young's modulus (in the isotropy plane) [MPa].
    E_l : longitudinal Young's modulus (along the axis) [MPa].
    nu_t : transverse Poisson ratio (in-plane) [-].
    nu_tl : transverse-longitudinal Poisson ratio, S13 = -nu_tl / E_t [-].
    mu_l : longitudinal shear modulus (planes containing the axis) [MPa].

    Construction checks every condition for a positive-definite tensor and names
    the one that fails.
    """

    E_t: float
    E_l: float
    nu_t: float
    nu_tl: float
    mu_l: float

    def __post_init__(self):
        for name in ("E_t", "E_l", "mu_l"):  # the moduli among CONSTANT_NAMES
            _finite_positive(name, getattr(self, name))
        for name in ("nu_t", "nu_tl"):
            if not np.isfinite(float(getattr(self, name))):
                raise ConfigError(f"{name}: {getattr(self, name)!r}: must be finite")
        if not (-1.0 < self.nu_t < 1.0):
            raise ConfigError(
                f"nu_t: {self.nu_t!r}: condition -1 < nu_t < 1 violated (positive-definite stiffness)"
            )
        det = 1.0 - self.nu_t - 2.0 * self.nu_tl * self.nu_lt
        if det <= 0.0:
            raise ConfigError(
                "nu_tl: condition 1 - nu_t - 2 nu_tl nu_lt > 0 violated "
                f"(nu_t={self.nu_t:g}, nu_tl={self.nu_tl:g}, nu_lt={self.nu_lt:g}: "
                f"value {det:g}); allowed |nu_tl| < {np.sqrt((1 - self.nu_t) * self.E_t / (2 * self.E_l)):g}"
            )

    @property
    def nu_lt(self) -> float:
        """Longitudinal-transverse Poisson ratio, nu_tl E_l / E_t [-]."""
        return self.nu_tl * self.E_l / self.E_t

    @property
    def mu_t(self) -> float:
        """Transverse (in-plane) shear modulus, E_t / (2 (1 + nu_t)) [MPa]."""
        return self.E_t / (2.0 * (1.0 + self.nu_t))

    @property
    def alpha(self) -> float:
        """Anisotropy percentage of the paper's Fig. 7: 100 - 100 E_l / E_t [%]."""
        return 100.0 - 100.0 * self.E_l / self.E_t

    def compliance(self) -> np.ndarray:
        """(6, 6) compliance [1/MPa], Voigt, engineering shear, axis 3 = l."""
        S = np.zeros((6, 6))
        S[0, 0] = S[1, 1] = 1.0 / self.E_t
        S[2, 2] = 1.0 / self.E_l
        S[0, 1] = S[1, 0] = -self.nu_t / self.E_t
        S[0, 2] = S[2, 0] = S[1, 2] = S[2, 1] = -self.nu_tl / self.E_t
        S[3, 3] = S[4, 4] = 1.0 / self.mu_l
        S[5, 5] = 2.0 * (1.0 + self.nu_t) / self.E_t
        return S

    def stiffness(self) -> np.ndarray:
        """(6, 6) stiffness [MPa], Voigt, engineering shear, axis 3 = l."""
        C = np.linalg.inv(self.compliance())
        return 0.5 * (C + C.T)

    def to_dict(self) -> dict:
        """The five constants [MPa, -] as a plain dict."""
        return {k: float(getattr(self, k)) for k in CONSTANT_NAMES}

    def as_tuple(self) -> tuple[float, float, float, float, float]:
        """The five constants in :data:`CONSTANT_NAMES` order [MPa, -]."""
        return tuple(float(getattr(self, k)) for k in CONSTANT_NAMES)

    @classmethod
    def from_mapping(cls, data, *, where: str = "constants") -> "TransverseIsotropic":
        """From a mapping holding the five :data:`CONSTANT_NAMES` (a JSON table, a CSV row).

        ``where`` names the source in the error when a constant is missing.
        """
        missing = [k for k in CONSTANT_NAMES if k not in data]
        if missing:
            raise ConfigError(f"{where}: missing {', '.join(missing)}: expected the five constants "
                              f"{', '.join(CONSTANT_NAMES)}")
        return cls(*(float(data[k]) for k in CONSTANT_NAMES))

    @classmethod
    def from_compliance(cls, S: np.ndarray) -> "TransverseIsotropic":
        """Read the five constants off a (6, 6) transverse-isotropic compliance (axis 3)."""
        S = np.asarray(S, float)
        E_t = float(2.0 / (S[0, 0] + S[1, 1]))
        return cls(
            E_t=E_t,
            E_l=float(1.0 / S[2, 2]),
            nu_t=float(-S[0, 1] * E_t),
            nu_tl=float(-0.5 * (S[0, 2] + S[1, 2]) * E_t),
            mu_l=float(2.0 / (S[3, 3] + S[4, 4])),
        )

    @classmethod
    def fit(cls, C: np.ndarray, axis=None) -> "TransverseFit":
        """Closest transverse-isotropic tensor to a (6, 6) Voigt stiffness.

        Closeness is the Frobenius norm in Mandel notation (rotation invariant).
        For a given unit ``axis`` (3,) the answer is the orthogonal projection onto
        the transverse-isotropic tensors about that axis, i.e. the average of ``C``
        over rotations about it. With ``axis=None`` the axis minimising the misfit
        is searched over the sphere (coarse grid, then local refinement).

        Returns a :class:`TransverseFit` with ``.material``, ``.axis`` (3,) and the
        relative ``.misfit`` = ||C - C_fit|| / ||C||.
        """
        C = _check_stiffness("C", C)
        if axis is not None:
            a = _unit("axis", axis)
            return _fit_about(C, a)
        return _fit_axis_search(C)


@dataclass(frozen=True)
class TransverseFit:
    """Result of :meth:`TransverseIsotropic.fit`."""

    material: TransverseIsotropic
    axis: np.ndarray  # (3,) unit vector, the fitted longitudinal axis
    misfit: float  # ||C - C_fit||_F / ||C||_F in Mandel notation
    C_fit: np.ndarray  # (6, 6) the fitted tensor in the global frame [MPa]


# --------------------------------------------------------------------------- fitting


def _check_stiffness(name: str, C) -> np.ndarray:
    C = np.asarray(C, float)
    if C.shape != (6, 6):
        raise ConfigError(f"{name}: shape is {C.shape} and should be (6, 6)")
    if not np.all(np.isfinite(C)):
        raise ConfigError(f"{name}: contains non-finite values")
    return 0.5 * (C + C.T)


def _unit(name: str, v) -> np.ndarray:
    a = np.asarray(v, float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-12:
        raise ConfigError(f"{name}: {v!r}: must be a non-zero 3-vector")
    return a / np.linalg.norm(a)


def _ti_basis() -> np.ndarray:
    """(5, 6, 6) orthonormal (Frobenius) basis of Mandel TI tensors about axis 3."""
    mats = []
    # C11 = C22, C12, C13 = C23, C33, C44 = C55 (Mandel), C66 = C11 - C12 (Mandel).
    def m(entries):
        M = np.zeros((6, 6))
        for (i, j), v in entries:
            M[i, j] = M[j, i] = v
        return M

    mats.append(m([((0, 0), 1), ((1, 1), 1), ((5, 5), 1)]))  # a
    mats.append(m([((0, 1), 1), ((5, 5), -1)]))  # b
    mats.append(m([((0, 2), 1), ((1, 2), 1)]))  # c
    mats.append(m([((2, 2), 1)]))  # d
    mats.append(m([((3, 3), 1), ((4, 4), 1)]))  # e
    flat = np.array([M.ravel() for M in mats]).T
    q, _ = np.linalg.qr(flat)
    return q.T.reshape(5, 6, 6)


_TI = _ti_basis()


def _project_local(Cm_local: np.ndarray) -> np.ndarray:
    """Orthogonal projection of a Mandel tensor onto TI tensors about axis 3."""
    coeff = np.einsum("kij,ij->k", _TI, Cm_local)
    return np.einsum("k,kij->ij", coeff, _TI)


def _misfit_about(Cm: np.ndarray, axis: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    R = voigt.frames_from_axes(axis[None, :])
    Q = voigt.mandel_rotation(R)[0]
    local = Q.T @ Cm @ Q
    proj = _project_local(local)
    return float(np.linalg.norm(local - proj)), proj, Q


def _fit_about(C: np.ndarray, axis: np.ndarray) -> TransverseFit:
    Cm = C * _MANDEL
    err, proj_local, Q = _misfit_about(Cm, axis)
    norm = float(np.linalg.norm(Cm))
    C_local = proj_local / _MANDEL
    material = TransverseIsotropic.from_compliance(np.linalg.inv(C_local))
    C_fit = (Q @ proj_local @ Q.T) / _MANDEL
    return TransverseFit(material, axis, err / norm if norm > 0 else 0.0, C_fit)


def _sphere_grid(n: int) -> np.ndarray:
    """(n, 3) Fibonacci points on the upper hemisphere (axes are sign-free)."""
    k = np.arange(n) + 0.5
    z = 1.0 - k / n
    phi = np.pi * (1.0 + np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _invariant_axes(C: np.ndarray) -> list[np.ndarray]:
    """Eigenvectors (3, 3) of the dilatational and Voigt second-order tensors of ``C``."""
    C4 = np.zeros((3, 3, 3, 3))
    for I, (i, j) in enumerate(VOIGT_PAIRS):
        for J, (k, l) in enumerate(VOIGT_PAIRS):
            for a, b in {(i, j), (j, i)}:
                for c, d in {(k, l), (l, k)}:
                    C4[a, b, c, d] = C[I, J]
    dil = np.einsum("ijkk->ij", C4)
    voi = np.einsum("ikjk->ij", C4)
    return [np.linalg.eigh(dil)[1].T, np.linalg.eigh(voi)[1].T]


def _fit_axis_search(C: np.ndarray) -> TransverseFit:
    Cm = C * _MANDEL
    # The symmetry axis of a transverse-isotropic tensor is an eigenvector of its
    # dilatational (C_ijkk) and Voigt (C_ikjk) tensors: exact candidates, plus a grid.
    candidates = np.vstack([np.eye(3), *_invariant_axes(C), _sphere_grid(400)])
    errs = np.array([_misfit_about(Cm, a)[0] for a in candidates])

    def f(angles):
        th, ph = angles
        a = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
        return _misfit_about(Cm, a)[0]

    from scipy.optimize import minimize  # here: scipy.optimize costs every command 0.5 s to import

    best_err, a = np.inf, candidates[0]
    for start in candidates[np.argsort(errs)[:4]]:  # a few starts: the misfit has local minima
        th0 = np.arccos(np.clip(start[2], -1, 1))
        ph0 = np.arctan2(start[1], start[0])
        res = minimize(f, [th0, ph0], method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-15})
        if res.fun < best_err:
            th, ph = res.x
            best_err = res.fun
            a = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    # Snap to a coordinate axis when it is as good: cleaner numbers for users.
    for e in np.eye(3):
        if _misfit_about(Cm, e)[0] <= _misfit_about(Cm, a)[0] * (1 + 1e-9) + 1e-14:
            a = e.copy()
            break
    if a[np.argmax(np.abs(a))] < 0:
        a = -a
    return _fit_about(C, a)


# --------------------------------------------------------------------------- anisotropy family


def interpolate(material: TransverseIsotropic, alpha: float) -> TransverseIsotropic:
    """The anisotropy sweep's material at ``alpha`` [%] (paper Fig. 7).

    ``alpha = 100 - 100 E_l / E_t``. At ``alpha = 0`` the result is isotropic with
    ``E = E_t`` and ``nu = nu_t``; at ``alpha = material.alpha`` it is ``material``.
    In between, ``E_l`` follows the definition of alpha exactly and the minor Poisson ratio
    ``nu_lt = nu_tl E_l / E_t`` and the shear compliance ``1 / mu_l`` move linearly with
    ``s = alpha / material.alpha``.

    Why nu_lt and not nu_tl: the path must stay positive definite. The binding condition is
    ``1 - nu_t - 2 nu_lt^2 E_t / E_l > 0``; along the path ``nu_lt`` and ``E_l / E_t`` are
    affine in ``s`` and ``x^2 / y`` is convex for ``y > 0``, so ``nu_lt^2 E_t / E_l`` is
    convex in ``s`` and never exceeds its value at an end: both ends valid => the whole path
    valid. Moving nu_tl linearly instead breaks for very soft foams (nu_tl ~ 4, E_l / E_t
    ~ 0.004: the homogenised Polyfoam) half way along.
    """
    a_max = material.alpha
    if a_max <= 0:
        raise ConfigError(
            f"material: alpha = {a_max:g} %: interpolation needs E_l < E_t (alpha in (0, 100))"
        )
    if not (0.0 <= float(alpha) <= a_max + 1e-12):
        raise ConfigError(f"alpha: {alpha!r}: allowed range is [0, {a_max:g}] %")
    s = float(alpha) / a_max
    iso = Isotropic(material.E_t, material.nu_t)
    E_l = material.E_t * (1.0 - float(alpha) / 100.0)
    nu_lt = (1 - s) * iso.nu + s * material.nu_lt
    nu_tl = nu_lt * material.E_t / E_l
    inv_mu = (1 - s) / iso.mu + s / material.mu_l
    return TransverseIsotropic(material.E_t, E_l, material.nu_t, nu_tl, 1.0 / inv_mu)
