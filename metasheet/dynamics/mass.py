"""Inertia: consistent mass matrices of tetrahedral bodies, rigid bodies, Rayleigh damping.

* :func:`consistent_mass`: ``M = int rho N^T N dV`` on the body's own sparsity pattern, exact
  for straight-edged P1 and P2 tets (the integrand is a polynomial of degree 2 or 4 in the
  barycentric coordinates, integrated in closed form). The lumped ``ElasticBody.mass`` is
  the work-equivalent load vector; this is the matrix the kinetic energy ``v^T M v / 2`` needs.
* :class:`RigidInertia` and :func:`box_inertia`, :func:`cylinder_inertia`,
  :func:`sphere_inertia`, :func:`combine`: mass, centre of mass and inertia tensor of rigid
  parts (servo horns, the marble), combined with the parallel-axis theorem.
* :func:`rayleigh_damping`: ``C = alpha M + beta K``, SOFA's ``rayleighMass`` and
  ``rayleighStiffness``.

Units: mm, t, s; inertia in t mm^2 (1 t mm^2 = 1e-3 kg m^2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations_with_replacement
from math import factorial

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError, check_range
from ..fem.tet10 import TET10_EDGES, tet10_shape_values

# --------------------------------------------------------------------------- element matrices

#: (4, 4) P1 ``int N_p N_q dV / V = (1 + delta_pq) / 20``.
P1_REFERENCE = (np.ones((4, 4)) + np.eye(4)) / 20.0


def barycentric_integral(exponents) -> float:
    """``int L0^a L1^b L2^c L3^d dV / V = 6 a! b! c! d! / (a + b + c + d + 3)!`` (exact)."""
    e = [int(k) for k in exponents]
    return 6.0 * np.prod([factorial(k) for k in e]) / factorial(sum(e) + 3)


def _p2_reference() -> np.ndarray:
    """(10, 10) ``int N_p N_q dV / V`` of the P2 tet in :mod:`metasheet.fem.tet10`'s node order.

    Every P2 function is a homogeneous quadratic ``sum_{i<=j} c_ij L_i L_j`` (``L_a = L_a sum L``);
    the coefficients are read off :func:`tet10_shape_values` at the 10 nodes (an interpolation,
    so the node order is the module's own), and the products integrated monomial by monomial.
    """
    pairs = list(combinations_with_replacement(range(4), 2))  # the 10 quadratic monomials
    nodes = np.vstack([np.eye(4), 0.5 * (np.eye(4)[TET10_EDGES[:, 0]] + np.eye(4)[TET10_EDGES[:, 1]])])
    basis = np.stack([nodes[:, i] * nodes[:, j] for i, j in pairs], axis=1)  # (10 nodes, 10 monomials)
    coef = np.linalg.solve(basis, tet10_shape_values(nodes))  # (monomial, shape function)
    gram = np.empty((10, 10))
    for r, (i, j) in enumerate(pairs):
        for s, (k, l) in enumerate(pairs):
            gram[r, s] = barycentric_integral(np.bincount([i, j, k, l], minlength=4))
    M = coef.T @ gram @ coef
    return 0.5 * (M + M.T)


#: (10, 10) P2 ``int N_p N_q dV / V`` (vertices 6/420 on the diagonal, midside nodes 32/420...).
P2_REFERENCE = _p2_reference()


def element_mass_blocks(volumes: np.ndarray, density: float, nen: int) -> np.ndarray:
    """(m, 3 nen, 3 nen) element mass matrices [t], node-major ``(3p+i, 3q+j) = M_pq delta_ij``.

    volumes : (m,) [mm^3] of straight-edged tets (affine: one reference matrix times each volume);
    density [t/mm^3]; nen : 4 (P1) or 10 (P2).
    """
    if nen not in (4, 10):
        raise ConfigError(f"nen: {nen}: allowed 4 (P1) or 10 (P2)")
    ref = np.kron(P1_REFERENCE if nen == 4 else P2_REFERENCE, np.eye(3))
    return (density * np.abs(np.asarray(volumes, float)))[:, None, None] * ref


def consistent_mass(body) -> sp.csr_matrix:
    """(3n, 3n) CSR consistent mass matrix [t] of ``body`` on ``body.pattern`` (node-major dofs).

    ``body``: an :class:`~metasheet.robot.body.ElasticBody` (or anything with ``volumes`` (m,),
    ``density``, ``tets`` (m, 4 | 10) and ``pattern``). Symmetric positive definite on the used
    nodes; ``u^T M u = int rho |u|^2 dV`` exactly for any field of the element's space.
    """
    blocks = element_mass_blocks(body.volumes, float(body.density), np.asarray(body.tets).shape[1])
    return body.pattern.matrix(body.pattern.assemble_data(blocks))


# --------------------------------------------------------------------------- rigid bodies


def _vec3(name: str, v) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name}: {np.asarray(v).tolist()!r}: should be a finite 3-vector [mm]")
    return a


@dataclass(frozen=True)
class RigidInertia:
    """A rigid body's inertia in its body frame.

    mass [t] > 0; com (3,) [mm] centre of mass; inertia (3, 3) [t mm^2] about the com:
    symmetric, positive semidefinite, principal moments obeying ``I1 + I2 >= I3`` (any physical
    mass distribution does; a point mass or a rod sits on the bounds).
    """

    mass: float
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self):
        check_range("mass", self.mass, 0.0, None, lo_open=True)
        com = _vec3("com", self.com)
        I = np.asarray(self.inertia, dtype=float)
        if I.shape != (3, 3) or not np.all(np.isfinite(I)):
            raise ConfigError(f"inertia: shape is {I.shape} and should be (3, 3), finite [t mm^2]")
        scale = max(np.abs(I).max(), 1e-300)
        tol = 1e-9 * scale
        if np.abs(I - I.T).max() > tol:
            raise ConfigError(f"inertia: asymmetry {np.abs(I - I.T).max():.3g} t mm^2, allowed <= {tol:.3g}")
        I = 0.5 * (I + I.T)
        p = np.linalg.eigvalsh(I)  # ascending
        if p[0] < -tol:
            raise ConfigError(f"inertia: principal moment {p[0]:.4g} t mm^2, allowed >= 0 (positive semidefinite)")
        if p[0] + p[1] < p[2] - tol:
            raise ConfigError(f"inertia: principal moments {p.tolist()} t mm^2 break I1 + I2 >= I3 "
                              "(no mass distribution has them)")
        com.flags.writeable = False
        I.flags.writeable = False
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "inertia", I)

    def about(self, point) -> np.ndarray:
        """(3, 3) inertia [t mm^2] about ``point`` (3,) [mm] (parallel-axis theorem)."""
        d = self.com - _vec3("point", point)
        return self.inertia + self.mass * (d @ d * np.eye(3) - np.outer(d, d))


def box_inertia(mass: float, size, centre=(0.0, 0.0, 0.0)) -> RigidInertia:
    """Solid box of side lengths ``size`` (3,) [mm] along the body axes, centred at ``centre``:
    ``I_xx = m (b^2 + c^2) / 12`` and cyclically."""
    s = _vec3("size", size)
    if np.any(s < 0):
        raise ConfigError(f"size: {s.tolist()}: allowed lengths >= 0 [mm]")
    s2 = s**2
    return RigidInertia(mass, centre, np.diag(mass * (s2.sum() - s2) / 12.0))


def cylinder_inertia(mass: float, radius: float, length: float, axis: int = 0,
                     centre=(0.0, 0.0, 0.0)) -> RigidInertia:
    """Solid cylinder of ``radius`` and ``length`` [mm] along body axis ``axis`` (0, 1, 2):
    ``m r^2 / 2`` about its axis, ``m (3 r^2 + L^2) / 12`` about the transverse ones."""
    check_range("radius", radius, 0.0, None)
    check_range("length", length, 0.0, None)
    if axis not in (0, 1, 2):
        raise ConfigError(f"axis: {axis!r}: allowed 0, 1 or 2")
    d = np.full(3, mass * (3.0 * radius**2 + length**2) / 12.0)
    d[axis] = 0.5 * mass * radius**2
    return RigidInertia(mass, centre, np.diag(d))


def sphere_inertia(mass: float, radius: float, centre=(0.0, 0.0, 0.0)) -> RigidInertia:
    """Solid sphere of ``radius`` [mm]: ``2 m r^2 / 5`` about every axis."""
    check_range("radius", radius, 0.0, None)
    return RigidInertia(mass, centre, np.eye(3) * 0.4 * mass * radius**2)


def combine(*parts: RigidInertia) -> RigidInertia:
    """The rigid union of ``parts`` (in one body frame): total mass, its com, and the sum of
    the parts' inertias carried to that com (parallel-axis theorem)."""
    if not parts:
        raise ConfigError("parts: none given: allowed one or more RigidInertia")
    for i, p in enumerate(parts):
        if not isinstance(p, RigidInertia):
            raise ConfigError(f"parts[{i}]: {type(p).__name__}: expected RigidInertia")
    m = sum(p.mass for p in parts)
    com = sum(p.mass * p.com for p in parts) / m
    return RigidInertia(m, com, sum(p.about(com) for p in parts))


# --------------------------------------------------------------------------- damping


def rayleigh_damping(M, K, alpha: float, beta: float):
    """Rayleigh damping matrix ``C = alpha M + beta K`` (sparse if both are, else dense).

    M [t], K [N/mm]: (N, N); alpha [1/s] (SOFA ``rayleighMass``), beta [s] (SOFA
    ``rayleighStiffness``), both >= 0. Returns C [N s/mm]. A mode of circular frequency
    ``w`` [rad/s] gets the damping ratio ``zeta = alpha / (2 w) + beta w / 2``.
    """
    check_range("alpha", alpha, 0.0, None)
    check_range("beta", beta, 0.0, None)
    if M.shape != K.shape or len(M.shape) != 2 or M.shape[0] != M.shape[1]:
        raise ConfigError(f"M, K: shapes {M.shape} and {K.shape} should be the same (N, N)")
    if sp.issparse(M) and sp.issparse(K):
        return (alpha * M + beta * K).tocsr()
    return alpha * _dense(M) + beta * _dense(K)


def _dense(A) -> np.ndarray:
    return A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)
