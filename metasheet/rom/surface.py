"""The equilibrium surface: a robot's equilibria as polynomials in its motor angles (issue 16).

A quasi-static robot driven by ``na`` motors has, on one branch, one equilibrium per motor
vector q: its effector pose P(q) and its condensed tangent S(q) (eq. 6) are smooth functions
on the motor box. Fitted once, on equilibria of the reduced model (:mod:`.model`), they give
an equilibrium and a Jacobian in microseconds: the real-time loop's model
(:mod:`.surface_robot`), a second level of reduction on top of the basis and sample.

The fit is gradient-enhanced least squares in the monomials of total degree <= ``degree`` of
the normalised angles u = (q - centre) / half (na,) in [-1, 1]: each training equilibrium
gives the pose (6 rows) and its Jacobian (6 na rows), so the fit reproduces the motion per
degree as well as the pose. The outputs are

* the pose change from the rest equilibrium: position (3,) [mm] and the rotation vector of
  R R_rest^T (3,) [rad]; the Jacobian's rotation rows (increments w with R' = exp(w) R) are
  mapped to and from the rotation vector's derivatives by the left Jacobian of SO(3);
* two symmetric blocks of S: the effector's stiffness S_ee and the motors' stiffness with the
  effector free, M = S_aa - S_ae S_ee^-1 S_ea. S is rebuilt with S_ea = -S_ee J from the fitted
  Jacobian, so that the Jacobian of S (eq. 7) is exactly the derivative of the fitted pose.

:func:`choose_degree` takes the lowest degree whose error on equilibria not used in the fit
is within a fraction of the certificate's targets.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from itertools import combinations_with_replacement
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import rotation_matrix, rotation_vector, skew


def exponents(n_vars: int, degree: int) -> np.ndarray:
    """(m, n_vars) int: the exponents of every monomial of total degree <= ``degree``."""
    rows = [np.zeros(n_vars, int)]
    for d in range(1, degree + 1):
        for combo in combinations_with_replacement(range(n_vars), d):
            e = np.zeros(n_vars, int)
            np.add.at(e, list(combo), 1)
            rows.append(e)
    return np.array(rows)


def monomials(u: np.ndarray, E: np.ndarray, *, grad: bool = False):
    """Monomials (s, m) at points ``u`` (s, n) for exponents ``E`` (m, n); with ``grad`` also
    their derivatives (s, n, m) with respect to each u_i."""
    u = np.atleast_2d(u)
    top = int(E.max(initial=0))
    powers = u[:, :, None] ** np.arange(top + 1)  # (s, n, top + 1)
    n = E.shape[1]
    factors = powers[:, np.arange(n)[:, None], E.T]  # (s, n, m): u_i ** e_i per monomial
    phi = factors.prod(axis=1)
    if not grad:
        return phi
    dphi = np.empty((u.shape[0], n, E.shape[0]))
    for i in range(n):
        d = E[:, i] * powers[:, i, np.maximum(E[:, i] - 1, 0)]  # d(u_i ** e) / du_i
        dphi[:, i] = d * np.delete(factors, i, axis=1).prod(axis=1)
    return phi, dphi


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """(3, 3) left Jacobian of SO(3) at the rotation vector ``phi`` (3,) [rad]: the increment w of
    exp(phi + dphi) = exp(w) exp(phi) is w = J_l(phi) dphi."""
    t = float(np.linalg.norm(phi))
    K = skew(phi)
    if t < 1e-6:
        return np.eye(3) + 0.5 * K + K @ K / 6.0
    return np.eye(3) + (1 - np.cos(t)) / t**2 * K + (t - np.sin(t)) / t**3 * K @ K


_TRIU = np.triu_indices(6)


def _sym(v: np.ndarray, n: int) -> np.ndarray:
    iu = np.triu_indices(n)
    out = np.zeros((n, n))
    out[iu] = v
    return out + np.triu(out, 1).T


@dataclass(frozen=True)
class EquilibriumData:
    """Equilibria of one robot: angles (s, na) [rad], pose (s, 6) (position [mm], rotation vector
    [rad]), J (s, 6, na) the direct Jacobian (eq. 7), S (s, 6 + na, 6 + na) the condensed tangent;
    strain (s,) or None."""

    angles: np.ndarray
    pose: np.ndarray
    J: np.ndarray
    S: np.ndarray
    strain: np.ndarray | None = None  # (s,) the largest principal strain [-], when known

    def take(self, rows) -> "EquilibriumData":
        """The equilibria ``rows`` (a slice, index array or bool mask)."""
        return EquilibriumData(self.angles[rows], self.pose[rows], self.J[rows], self.S[rows],
                               None if self.strain is None else self.strain[rows])

    @staticmethod
    def concat(parts) -> "EquilibriumData":
        parts = list(parts)
        strain = None if any(p.strain is None for p in parts) else np.concatenate([p.strain for p in parts])
        return EquilibriumData(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("angles", "pose", "J", "S")),
                               strain)


@dataclass(frozen=True)
class Surface:
    """The fitted surface (see the module docstring); build it with :func:`fit_surface`.

    centre, half : (na,) the motor box's centre and half-width [rad]; p0 (3,) [mm], R0 (3, 3):
    the rest equilibrium's pose; E (m, na) exponents; pose_coef (m, 6), see_coef (m, 21),
    m_coef (m, na (na + 1) / 2): coefficients; info: the fit's record (degree, errors).
    """

    centre: np.ndarray
    half: np.ndarray
    p0: np.ndarray
    R0: np.ndarray
    E: np.ndarray
    pose_coef: np.ndarray
    see_coef: np.ndarray
    m_coef: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def na(self) -> int:
        return len(self.centre)

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) (na,) [rad]: the motor box fitted on."""
        return self.centre - self.half, self.centre + self.half

    def in_box(self, angles, tol: float = 1e-9) -> bool:
        u = (np.asarray(angles, float) - self.centre) / self.half
        return bool(np.all(np.abs(u) <= 1.0 + tol))

    def evaluate(self, angles) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(p (3,) [mm], R (3, 3), J (6, na) [mm/rad, rad/rad], S (6 + na, 6 + na)) at motor
        ``angles`` (na,) [rad]."""
        u = (np.asarray(angles, float) - self.centre) / self.half
        phi, dphi = monomials(u[None], self.E, grad=True)
        y = phi[0] @ self.pose_coef  # (6,)
        dy = (dphi[0] @ self.pose_coef).T / self.half  # (6, na) per radian
        p = self.p0 + y[:3]
        R = rotation_matrix(y[3:]) @ self.R0
        J = np.vstack([dy[:3], left_jacobian(y[3:]) @ dy[3:]])
        See = _sym(phi[0] @ self.see_coef, 6)
        M = _sym(phi[0] @ self.m_coef, self.na)
        Sea = -See @ J
        S = np.block([[See, Sea], [Sea.T, M + J.T @ See @ J]])
        return p, R, J, S

    def pose_change(self, angles) -> np.ndarray:
        """(6,) the pose change from the rest equilibrium at ``angles`` (the fitted outputs)."""
        u = (np.asarray(angles, float) - self.centre) / self.half
        return monomials(u[None], self.E)[0] @ self.pose_coef

    def save(self, path: Path) -> None:
        """Write to ``path`` (.npz), atomically."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, centre=self.centre, half=self.half, p0=self.p0, R0=self.R0, E=self.E,
                 pose_coef=self.pose_coef, see_coef=self.see_coef, m_coef=self.m_coef,
                 info=np.array(json.dumps(self.info)))
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> "Surface":
        with np.load(path) as z:
            return cls(z["centre"], z["half"], z["p0"], z["R0"], z["E"], z["pose_coef"], z["see_coef"],
                       z["m_coef"], json.loads(str(z["info"])))


def _targets(data: EquilibriumData, R0: np.ndarray, p0: np.ndarray, half: np.ndarray):
    """The outputs and their u-derivatives: y (s, 6), dy (s, na, 6)."""
    s = len(data.angles)
    y = np.empty((s, 6))
    dy = np.empty((s, len(half), 6))
    for k in range(s):
        rv = rotation_vector(rotation_matrix(data.pose[k, 3:]) @ R0.T)
        y[k] = np.r_[data.pose[k, :3] - p0, rv]
        drv = np.linalg.solve(left_jacobian(rv), data.J[k, 3:])
        dy[k] = (np.vstack([data.J[k, :3], drv]) * half).T
    return y, dy


def _blocks(S: np.ndarray, na: int) -> tuple[np.ndarray, np.ndarray]:
    """(S_ee upper (21,), M upper (na (na + 1) / 2,)) of a condensed tangent, symmetrised."""
    S = 0.5 * (S + S.T)
    See, Sea, Saa = S[:6, :6], S[:6, 6:], S[6:, 6:]
    M = Saa - Sea.T @ np.linalg.solve(See, Sea)
    return See[_TRIU], M[np.triu_indices(na)]


def fit_surface(data: EquilibriumData, rest: EquilibriumData, box_lo, box_hi, degree: int) -> Surface:
    """Fit a :class:`Surface` of total ``degree`` to ``data`` on the box [lo, hi] (na,) [rad];
    ``rest`` holds the rest equilibrium (one row) the pose is measured from."""
    lo, hi = np.asarray(box_lo, float), np.asarray(box_hi, float)
    na = len(lo)
    if np.any(hi <= lo):
        raise ConfigError(f"surface box: {np.degrees(lo)}..{np.degrees(hi)} deg: need lo < hi")
    E = exponents(na, degree)
    if len(data.angles) * (1 + na) < 2 * len(E):
        raise ConfigError(f"surface degree {degree}: {len(E)} coefficients need at least "
                          f"{int(np.ceil(2 * len(E) / (1 + na)))} equilibria, got {len(data.angles)}")
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    p0, R0 = rest.pose[0, :3], rotation_matrix(rest.pose[0, 3:])
    y, dy = _targets(data, R0, p0, half)
    phi, dphi = monomials((data.angles - centre) / half, E, grad=True)
    A = np.vstack([phi, dphi.reshape(-1, len(E))])
    b = np.vstack([y, dy.reshape(-1, 6)])
    scale = np.linalg.norm(A, axis=0)  # column scaling: monomials of high degree are small
    pose_coef = np.linalg.lstsq(A / scale, b, rcond=None)[0] / scale[:, None]
    blocks = [_blocks(S, na) for S in data.S]
    see = np.array([b[0] for b in blocks])
    mm = np.array([b[1] for b in blocks])
    s_scale = np.linalg.norm(phi, axis=0)
    see_coef = np.linalg.lstsq(phi / s_scale, see, rcond=None)[0] / s_scale[:, None]
    m_coef = np.linalg.lstsq(phi / s_scale, mm, rcond=None)[0] / s_scale[:, None]
    info = {"degree": int(degree), "coefficients": int(len(E)), "equilibria": int(len(data.angles))}
    return Surface(centre, half, p0, R0, E, pose_coef, see_coef, m_coef, info)


def errors(surface: Surface, data: EquilibriumData) -> dict:
    """The surface against equilibria ``data``: position [mm], orientation [deg] and Jacobian
    (relative Frobenius) errors, each (s,)."""
    pos, rot, jac = [], [], []
    for q, pose, J in zip(data.angles, data.pose, data.J):
        p, R, Js, _ = surface.evaluate(q)
        pos.append(np.linalg.norm(p - pose[:3]))
        rot.append(np.degrees(np.linalg.norm(rotation_vector(R @ rotation_matrix(pose[3:]).T))))
        jac.append(np.linalg.norm(Js - J) / np.linalg.norm(J))
    return {"position_mm": np.array(pos), "orientation_deg": np.array(rot), "jacobian_rel": np.array(jac)}


def choose_degree(train: EquilibriumData, check: EquilibriumData, rest: EquilibriumData, box_lo, box_hi,
                  targets: dict, *, fraction: float = 0.5, degrees=(2, 3, 4, 5, 6),
                  strain_limit: float | None = None) -> Surface:
    """The lowest degree in ``degrees`` whose worst error on ``check`` (equilibria not fitted;
    with ``strain_limit`` and the check's strains, those within it, where the certificate's
    targets apply, if any is) is within ``fraction`` of each of ``targets`` ({"position_mm",
    "orientation_deg", "jacobian_rel"}); if none is, the one with the smallest worst error
    relative to its target, its record saying so (``info["met"]`` False)."""
    if strain_limit is not None and check.strain is not None and np.any(check.strain <= strain_limit):
        check = check.take(check.strain <= strain_limit)
    else:  # no strains, or none within: every check equilibrium counts
        strain_limit = None
    best, tried = None, []
    for d in degrees:
        try:
            s = fit_surface(train, rest, box_lo, box_hi, d)
        except ConfigError:  # too few equilibria for this degree
            break
        err = {k: float(v.max()) for k, v in errors(s, check).items()}
        tried.append({"degree": d, **err})
        met = all(err[k] <= fraction * targets[k] for k in err)
        score = max(err[k] / targets[k] for k in err)
        if best is None or score < best[0]:
            best = (score, s, err, met)
        if met:
            break
    if best is None:
        raise ConfigError(f"surface: {len(train.angles)} equilibria are too few for degree {degrees[0]}")
    _, s, err, met = best
    info = {**s.info, "check_equilibria": int(len(check.angles)), "check_strain_limit": strain_limit,
            "check_worst": err, "met": bool(met), "fraction_of_targets": fraction, "tried": tried}
    return Surface(s.centre, s.half, s.p0, s.R0, s.E, s.pose_coef, s.see_coef, s.m_coef, info)
