"""A smooth in-plane fibre-angle field on the tripod sheet, spanned by a small basis.

Angle convention (that of :func:`metasheet.sheet.fibers.fiber_angles`): theta is the
in-plane fibre direction's angle from the sheet's +x axis (arm 0) [rad], counter-clockwise
seen from +z, so the fibre of angle theta is ``(cos theta, sin theta, 0)`` in the sheet frame.
The paper's spiral of pitch beta has ``theta = t + 90 deg - beta`` at polar angle t.

The field on sheet A's elements is

    theta_e = theta0_e + sum_j c_j N_j(x_e),          x_e the element's centroid,

with ``theta0`` a starting field (e.g. the spiral) and ``N_j`` a tensor B-spline in polar
coordinates (r, phi) over the disk r <= ``r_max``: an open uniform B-spline in r times a
periodic uniform B-spline in phi. Polar, not Cartesian, because a rotation of the sheet by
120 deg about its centre then shifts the phi basis by exactly ``n_angular / 3`` functions:
the symmetric option ties ``c[i, j] = c[i, j + n/3] = c[i, j + 2n/3]``, which makes the
increment invariant, ``delta(R120 x) = delta(x)``, so a 120-deg-symmetric ``theta0``
(the spiral) stays symmetric: ``theta(R120 x) = theta(x) + 120 deg``. The basis is singular
at r = 0 (every phi function meets there); the sheet's central hole and rigid centre disk
keep the elements away from it.

The second sheet (B) is the mirror image y -> -y of A, element i of B the image of element i
of A (:func:`metasheet.sheet.geometry.mirror_sheet`), and its fibres are the reflected field
``l_B(p) = M l_A(M p)`` (:func:`metasheet.sheet.fibers.spiral_fibers` with ``mirrored=True``):
a fibre at angle theta becomes one at -theta. So ``theta_B = -theta_A`` element by element,
and one coefficient vector designs both sheets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from .fibers import MIRROR


@dataclass(frozen=True)
class PolarBSpline:
    """The basis: a tensor B-spline in (r, phi) over the disk r <= ``r_max``.

    Attributes
    ----------
    n_radial : functions along r, in [degree + 1, 32] (open uniform knots on [0, r_max]).
    n_angular : functions along phi, in [degree + 1, 96] (periodic uniform knots); a multiple
        of 3 when ``symmetric``.
    degree : polynomial degree in both directions, in [1, 5] (3: cubic, C2 field).
    r_max : [mm] the disk's radius; points beyond it take the value at r_max.
    symmetric : tie the coefficients so that the increment is invariant under the sheet's
        120 deg rotation (n_radial * n_angular / 3 free coefficients instead of n_radial * n_angular).

    Coefficient order: ``c[i * n_phi + j]`` multiplies the i-th radial and j-th angular function
    (``n_phi`` = n_angular, or n_angular / 3 when symmetric); c_j is an angle [rad].
    """

    n_radial: int = 4
    n_angular: int = 12
    degree: int = 3
    r_max: float = 70.0
    symmetric: bool = False

    def __post_init__(self):
        for name in ("n_radial", "n_angular", "degree"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise ConfigError(f"{name}: {v!r}: expected an integer")
        check_range("degree", self.degree, 1, 5)
        check_range("n_radial", self.n_radial, self.degree + 1, 32)
        check_range("n_angular", self.n_angular, self.degree + 1, 96)
        check_range("r_max", self.r_max, 0.0, 1e4, lo_open=True)
        if self.symmetric and self.n_angular % 3:
            raise ConfigError(f"n_angular: {self.n_angular}: must be a multiple of 3 when symmetric "
                              "(the 120 deg rotation must map the phi basis onto itself)")

    @property
    def n_full(self) -> int:
        """Coefficients before tying: n_radial * n_angular."""
        return self.n_radial * self.n_angular

    @property
    def n_coefficients(self) -> int:
        """Free coefficients (the design vector's length)."""
        return self.n_full // 3 if self.symmetric else self.n_full

    def tie_matrix(self) -> np.ndarray:
        """(n_full, n_coefficients) 0/1 matrix: full coefficients = T @ free ones (identity
        when not symmetric). Its column sums are the multiplicity of each free coefficient."""
        if not self.symmetric:
            return np.eye(self.n_full)
        third = self.n_angular // 3
        i, j = np.divmod(np.arange(self.n_full), self.n_angular)
        T = np.zeros((self.n_full, self.n_coefficients))
        T[np.arange(self.n_full), i * third + j % third] = 1.0
        return T

    def full_matrix(self, points: np.ndarray) -> np.ndarray:
        """(m, n_full) untied basis values at ``points`` (m, 2 or 3) [mm] (sheet frame; z ignored)."""
        p = _as_points(points)
        r = np.hypot(p[:, 0], p[:, 1])
        phi = np.arctan2(p[:, 1], p[:, 0])
        Nr = open_bspline(r, 0.0, float(self.r_max), self.n_radial, self.degree)
        Np = periodic_bspline(phi, self.n_angular, self.degree)
        return (Nr[:, :, None] * Np[:, None, :]).reshape(len(p), self.n_full)

    def design_matrix(self, points: np.ndarray) -> np.ndarray:
        """(m, n_coefficients) basis values at ``points`` (m, 2 or 3) [mm], tied when symmetric:
        the increment of the field there is ``design_matrix(points) @ c`` [rad]."""
        N = self.full_matrix(points)
        return N @ self.tie_matrix() if self.symmetric else N


def _as_points(points) -> np.ndarray:
    p = np.asarray(points, float)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ConfigError(f"points: shape is {p.shape} and should be (m, 2) or (m, 3)")
    if not np.all(np.isfinite(p)):
        raise ConfigError("points: contains non-finite values")
    return p


def _cox_de_boor(x: np.ndarray, t: np.ndarray, degree: int) -> np.ndarray:
    """(m, len(t) - degree - 1) B-spline basis on knots ``t`` at ``x`` (m,), half-open spans."""
    x = x[:, None]
    N = ((t[:-1] <= x) & (x < t[1:])).astype(float)
    for k in range(1, degree + 1):
        d0 = t[k:-1] - t[:-k - 1]
        d1 = t[k + 1:] - t[1:-k]
        # repeated knots give 0/0 terms, which the recursion defines as 0
        a = np.divide(x - t[:-k - 1], d0, out=np.zeros((len(x), len(d0))), where=d0 > 0)
        b = np.divide(t[k + 1:] - x, d1, out=np.zeros((len(x), len(d1))), where=d1 > 0)
        N = a * N[:, :-1] + b * N[:, 1:]
    return N


def open_bspline(x: np.ndarray, lo: float, hi: float, n: int, degree: int) -> np.ndarray:
    """(m, n) open uniform (clamped) B-spline basis on [lo, hi] at ``x`` (m,); a partition of
    unity there. ``x`` outside [lo, hi] is clamped to it (the right end to just inside, where
    the half-open spans still see it)."""
    inner = np.linspace(lo, hi, n - degree + 1)
    t = np.concatenate([np.full(degree, lo), inner, np.full(degree, hi)])
    xc = np.clip(np.asarray(x, float), lo, np.nextafter(hi, lo))
    return _cox_de_boor(xc, t, degree)


def periodic_bspline(phi: np.ndarray, n: int, degree: int) -> np.ndarray:
    """(m, n) periodic uniform B-spline basis in the angle ``phi`` (m,) [rad], period 2 pi:
    ``N_j(phi) = b((phi / h - j) mod n)``, h = 2 pi / n, b the cardinal B-spline on knots
    0..degree+1. Shifting phi by k h shifts the basis by k functions; a partition of unity."""
    s = np.mod(np.asarray(phi, float)[:, None] * (n / (2.0 * np.pi)) - np.arange(n), n)
    b = _cox_de_boor(s.ravel(), np.arange(degree + 2, dtype=float), degree)
    return b[:, 0].reshape(s.shape)


def check_coefficients(c, n: int, field: str = "c") -> np.ndarray:
    """``c`` as a finite float vector of length ``n`` (else ConfigError naming ``field``)."""
    try:
        a = np.asarray(c, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{field}: {c!r}: expected a vector of real numbers") from None
    if a.shape != (n,):
        raise ConfigError(f"{field}: shape is {a.shape} and should be ({n},) (one coefficient per basis function)")
    bad = np.flatnonzero(~np.isfinite(a))
    if len(bad):
        raise ConfigError(f"{field}[{bad[0]}]: {float(a[bad[0]])!r}: expected a finite angle [rad]")
    return a


@dataclass(frozen=True, eq=False)
class FibreField:
    """The designable fibre field on sheet A's elements (sheet B's is its mirror).

    Attributes
    ----------
    basis : the :class:`PolarBSpline`.
    theta0 : (m,) starting angle per element [rad] (module convention).
    N : (m, n_coefficients) basis values at the element centroids [-].
    """

    basis: PolarBSpline
    theta0: np.ndarray
    N: np.ndarray

    @classmethod
    def from_fibres(cls, centroids: np.ndarray, fibres: np.ndarray, basis: PolarBSpline) -> FibreField:
        """The field starting from in-plane ``fibres`` (m, 3) at ``centroids`` (m, 3) [mm] of sheet A.

        The fibres must lie in the sheet plane (|l_z| <= 1e-9 |l|): the design rotates them in it.
        """
        p = _as_points(centroids)
        f = np.asarray(fibres, float)
        if f.shape != (len(p), 3):
            raise ConfigError(f"fibres: shape is {f.shape} and should be ({len(p)}, 3)")
        norm = np.linalg.norm(f, axis=1)
        if not np.all(np.isfinite(norm)) or np.any(norm < 1e-12):
            raise ConfigError("fibres: must be finite non-zero vectors")
        tilt = np.abs(f[:, 2]) / norm
        if tilt.max() > 1e-9:
            i = int(np.argmax(tilt))
            raise ConfigError(f"fibres[{i}]: {f[i].tolist()}: out of the sheet plane (|l_z| / |l| = "
                              f"{tilt[i]:.3g}); allowed <= 1e-9 (the design rotates fibres in the plane)")
        return cls(basis, np.arctan2(f[:, 1], f[:, 0]), basis.design_matrix(p))

    @property
    def n_coefficients(self) -> int:
        return self.basis.n_coefficients

    def check(self, c) -> np.ndarray:
        """``c`` validated (:func:`check_coefficients`, field name "c")."""
        return check_coefficients(c, self.n_coefficients)

    def angles(self, c) -> np.ndarray:
        """(m,) sheet A's fibre angles theta [rad] for coefficients ``c`` (n_coefficients,) [rad]."""
        return self.theta0 + self.N @ self.check(c)

    def fibres(self, c) -> tuple[np.ndarray, np.ndarray]:
        """Unit fibres (m, 3) of sheet A and of its mirror B for coefficients ``c``: the
        ``fibers`` and ``fibers_mirrored`` of a :class:`~metasheet.robot.builder.SheetPair`."""
        fa = fibres_at(self.angles(c))
        return fa, fa @ MIRROR


def fibres_at(theta: np.ndarray) -> np.ndarray:
    """(m, 3) unit in-plane fibres ``(cos theta, sin theta, 0)`` for angles ``theta`` (m,) [rad]."""
    th = np.asarray(theta, float)
    return np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=1)


#: The bases an ``[orient] fibre_field`` may name (its ``basis`` key).
BASES = ("polar_bspline",)


def basis_record(b: PolarBSpline) -> dict:
    """``b`` as the ``[orient] fibre_field`` table names it (without the coefficients):
    ``basis``, ``n_radial``, ``n_angular``, ``degree``, ``r_max`` [mm], ``symmetric``."""
    return {"basis": "polar_bspline", "n_radial": int(b.n_radial), "n_angular": int(b.n_angular),
            "degree": int(b.degree), "r_max": float(b.r_max), "symmetric": bool(b.symmetric)}


def field_on_sheet(centroids: np.ndarray, spiral_fibres: np.ndarray, basis: PolarBSpline,
                   c) -> tuple[np.ndarray, np.ndarray]:
    """Unit fibres (m, 3) of sheet A and of its mirror B for the field ``spiral + basis @ c``.

    ``centroids`` (m, 3) [mm] of sheet A's elements, ``spiral_fibres`` (m, 3) its in-plane
    starting field, ``c`` (n_coefficients,) [rad]. The same functions the design stage
    evaluates a design with (:meth:`FibreField.from_fibres`, :meth:`FibreField.fibres`), so a
    sheet built from a design's coefficients has the bytes its evaluation had; element i of
    B is the mirror image of element i of A (:func:`metasheet.sheet.geometry.mirror_sheet`).
    """
    field = FibreField.from_fibres(centroids, spiral_fibres, basis)
    return field.fibres(c)


def field_at(points: np.ndarray, spiral, basis: PolarBSpline, c, mirrored: bool = False) -> np.ndarray:
    """(q, 3) unit fibres of the field at any ``points`` (q, 3) [mm] (pictures, print maps):
    ``spiral(points)`` (q, 3) is sheet A's starting field there; ``mirrored``: sheet B's,
    ``l_B(p) = M l_A(M p)``."""
    p = _as_points(points)
    q = p @ MIRROR if mirrored else p
    fa = FibreField.from_fibres(q, spiral(q), basis).fibres(c)[0]
    return fa @ MIRROR if mirrored else fa


def rotate_points(points: np.ndarray, angle: float) -> np.ndarray:
    """``points`` (m, 3) [mm] turned by ``angle`` [rad] about the sheet normal (z)."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(points, float) @ R.T
