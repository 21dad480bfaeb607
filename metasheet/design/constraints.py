"""The design's constraints and their adjoint gradients: the strain at the goals as one smooth
aggregate, and the other five DOF's smallest singular value (issue 45: the strain at the design
goals within the limit, the other DOF no lower than the spiral's).

Strain aggregate. The measure is :mod:`.strain`'s: the largest principal linearised strain
``lambda_max(eps)`` per checked element (beyond the grip band) and quadrature point, at each
goal of :func:`.strain.goals`. Their maximum is not differentiable, so the constraint is the
Kreisselmeier-Steinhauser aggregate over all goals, elements and points together,

    KS = max + (1/rho) log sum_i exp(rho (lambda_i - max)),   max <= KS <= max + log(N) / rho,

a smooth upper bound of the true maximum: ``KS <= limit`` implies the exact maximum is within
the limit (conservative by ``KS - max``, reported; N ~ 7,000 on the coarse robot, so at most
log(N) / rho = 0.0089 at the default rho = 1000, and in practice less because few points are
near the maximum: 0.0019 at the pipeline's constrained optimum, 0.0088 at rho = 200; a sharper
aggregate gains roll where the constraint binds, 1.33x the spiral's against 1.27x at rho = 200,
and its gradient still matches central differences to 1e-9).

Its gradient. For goal g (motors q_a [rad]) the displacement is ``u_g = E w_g``, ``w_g = (J q_a,
q_a)`` (:func:`.adjoint._field`), and ``dKS = sum_g r_g^T du_g`` with ``r_g = sum_i kappa_i
B_i^T dlambda_i/deps`` (kappa the KS weights, the softmax of rho lambda). For a simple eigenvalue
with unit eigenvector v, ``dlambda = v^T deps_tensor v``; in Voigt engineering shear (11, 22, 33,
2*23, 2*13, 2*12) that is ``dlambda/deps = (v1^2, v2^2, v3^2, v2 v3, v1 v3, v1 v2)``. ``du_g``
has two parts:

* through E at fixed w: the free nodes' equilibrium moves, ``du_f = -K_ff^-1 (dK u_g)_f``, so the
  term is ``-z_g^T dK u_g`` with the adjoint field ``z_g = (0 on rigid dofs, K_ff^-1 r_g,f)``:
  one adjoint solve per goal, all goals' right-hand sides in one back-substitution on the K_ff
  factor the rest solution already holds (:attr:`.adjoint.RestSolution.ff`), none per variable;
* through J: ``r_g^T E (dJ q_a, 0) = a_g^T dJ q_a`` with ``a_g = (E^T r_g)[:6] = (J_r^T r_r -
  Y^T r_f)[:6]``, a rank-one objective of J handled by :func:`.adjoint.angle_sensitivity`.

The other DOF: :func:`.objectives.other_five_weights` (rank one in J; exact where simple).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import check_range
from ..homogenize.localisation import voigt_to_tensor
from . import objectives as obj
from .adjoint import (
    RestProblem,
    RestSolution,
    Sensitivity,
    _field,
    angle_sensitivity,
    solve_rest,
    stiffness_product,
)
from .strain import GOAL_DEG, goals

#: [1/strain] default KS aggregation parameter
KS_RHO = 1000.0


def ks_aggregate(values: np.ndarray, rho: float) -> tuple[float, np.ndarray]:
    """The KS aggregate of ``values`` (N,) [-] at ``rho`` [1/unit of values] and its gradient
    (N,) (weights >= 0 summing to 1)."""
    v = np.asarray(values, float).ravel()
    top = float(v.max())
    e = np.exp(rho * (v - top))  # shifted by the maximum: no overflow
    s = float(e.sum())
    return top + float(np.log(s)) / rho, e / s


def principal_max(eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest principal strain (...,) [-] of Voigt strains ``eps`` (..., 6) (engineering shear)
    and its derivative in the Voigt components (..., 6) (module docstring; valid where the
    largest eigenvalue is simple)."""
    lam, V = np.linalg.eigh(voigt_to_tensor(eps))
    v = V[..., :, -1]
    d = np.stack([v[..., 0] ** 2, v[..., 1] ** 2, v[..., 2] ** 2, v[..., 1] * v[..., 2], v[..., 0] * v[..., 2],
                  v[..., 0] * v[..., 1]], axis=-1)
    return lam[..., -1], d


@dataclass(frozen=True)
class StrainAggregate:
    """The KS aggregate of the largest principal strain at the goals, and its gradient.

    Attributes
    ----------
    value : KS [-] (>= ``exact``); exact : the true maximum over goals, elements, points [-];
    gradient : (n,) d value / d c [1/rad]; per_element : (m,) d value / d theta_e on sheet A [1/rad];
    rho : [1/strain]; goal_deg : [deg]; points : N, the values aggregated.
    """

    value: float
    exact: float
    gradient: np.ndarray
    per_element: np.ndarray
    rho: float
    goal_deg: float
    points: int

    @property
    def overshoot(self) -> float:
        """``value - exact`` [-]: how conservative the aggregate is here."""
        return self.value - self.exact


def strain_sensitivity(problem: RestProblem, c, goal_deg: float = GOAL_DEG, rho: float = KS_RHO,
                       band_mm: float | None = None, sol: RestSolution | None = None) -> StrainAggregate:
    """KS aggregate of the largest principal strain of design ``c`` (n,) [rad] at
    :func:`.strain.goals` (``goal_deg`` [deg]) over the elements beyond ``band_mm`` [mm] of the
    grips (None: the studies' band), and its adjoint gradient (module docstring)."""
    from ..robot.validity import GRIP_BAND_MM, validity_elements

    check_range("rho", rho, 0.0, 1e6, lo_open=True)
    sol = solve_rest(problem, c) if sol is None else sol
    keep = validity_elements(problem.robot, GRIP_BAND_MM if band_mm is None else band_mm)
    dofs, na = problem.robot.body.pattern.dofs, sol.J.shape[1]
    gs = goals(na, goal_deg)
    qa = np.radians(np.array([g.motors_deg for g in gs], float))  # (G, na)
    U = [_field(problem, sol, np.concatenate([sol.J @ q, q])) for q in qa]
    Bk, dk = problem.B[keep], dofs[keep]
    lam, dlam = zip(*(principal_max(np.einsum("mqia,ma->mqi", Bk, u[dk])) for u in U))
    value, kappa = ks_aggregate(np.stack(lam), rho)
    kappa = kappa.reshape((len(gs),) + lam[0].shape)
    n_dof = problem.robot.body.n_nodes * 3
    # r_g = sum_i kappa_i B_i^T dlambda_i: d KS / d u_g, gathered onto the dofs
    R = np.stack([np.bincount(dk.ravel(), np.einsum("mq,mqi,mqia->ma", k, d, Bk).ravel(), minlength=n_dof)
                  for k, d in zip(kappa, dlam)], axis=1)  # (3 n, G)
    Z = np.zeros_like(R)
    Z[problem.dof_f] = sol.ff.solve(np.ascontiguousarray(R[problem.dof_f]))  # the adjoint solves
    A = (problem.Jr.T @ R[problem.dof_r] - sol.Y.T @ R[problem.dof_f])[:6]  # (6, G): (E^T r_g)[:6]
    per = np.zeros(problem.n_elements)
    for g in range(len(gs)):
        per += stiffness_product(problem, sol, Z[:, g], U[g])
        per += angle_sensitivity(problem, sol, obj.RankOne(0.0, A[:, g], qa[g]))
    exact = float(max(float(x.max()) for x in lam))
    return StrainAggregate(value, exact, problem.field.N.T @ per, per, float(rho), float(goal_deg),
                           int(sum(x.size for x in lam)))


def other_min_sensitivity(problem: RestProblem, c, sol: RestSolution | None = None) -> Sensitivity:
    """Smallest singular value of the five DOF other than the roll [mm/rad] (what
    :func:`.search.other_five_min` reports) at design ``c`` and its adjoint gradient."""
    sol = solve_rest(problem, c) if sol is None else sol
    wts = obj.other_five_weights(sol.J, problem.robot.axis, problem.length_scale)
    per = angle_sensitivity(problem, sol, wts)
    return Sensitivity("other_min", wts.value, problem.field.N.T @ per, per, wts.gap)


def other_singular_sensitivities(problem: RestProblem, c, sol: RestSolution | None = None,
                                 index: int | None = None) -> list[Sensitivity]:
    """The scaled singular values [mm/rad] other than the roll's (:func:`.objectives.roll_index`,
    or ``index``), largest first, each with its adjoint gradient (exact where it is simple: see
    each one's ``gap``; at a crossing the sorted value has a kink and this is one side's slope)."""
    sol = solve_rest(problem, c) if sol is None else sol
    axis, L = problem.robot.axis, problem.length_scale
    skip = obj.roll_index(sol.J, axis, L) if index is None else int(index)
    res = []
    for k in range(len(sol.singular_values)):
        if k == skip:
            continue
        w = obj.singular_weights(sol.J, k, L)
        per = angle_sensitivity(problem, sol, w)
        res.append(Sensitivity(f"singular_value_{k + 1}", w.value, problem.field.N.T @ per, per, w.gap))
    return res

