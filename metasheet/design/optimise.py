"""The free-form fibre field optimised for rod roll with the adjoint gradient (issue 45, item 3),
from the orient stage's spiral (all coefficients 0).

Maximises |rod roll per degree| [deg/deg] in the spiral's own sense over the coefficients of
a :class:`~.fibre_field.PolarBSpline`, each in the box [-bound_deg, bound_deg] [deg]:

* constrained (default): SLSQP subject to the KS aggregate of the largest principal strain at
  the goals <= ``strain_limit`` and the other five DOF's smallest singular value >= ``floor``
  (:mod:`.constraints`; one rest solve, one adjoint product per function and one back-substitution
  for the strain's adjoint fields per iteration);
* unconstrained: L-BFGS-B on the roll alone (:func:`.adjoint.roll_sensitivity`).

:func:`strain_front` repeats the constrained optimisation over a list of strain limits: the
roll the strain limit allows, the issue's "what it trades against".
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from . import outputs as out
from .adjoint import rest_problem, roll_sensitivity, solve_rest
from .constraints import KS_RHO, other_min_sensitivity, strain_sensitivity
from .fibre_field import PolarBSpline
from .search import scores
from .strain import GOAL_DEG, STRAIN_LIMIT


def basis_dict(b: PolarBSpline) -> dict:
    """``b``'s constructor keywords (JSON-able; ``PolarBSpline(**basis_dict(b))`` rebuilds it)."""
    return {"n_radial": b.n_radial, "n_angular": b.n_angular, "degree": b.degree, "r_max": b.r_max,
            "symmetric": b.symmetric}


@dataclass(frozen=True)
class StrainSettings:
    """The strain constraint: ``limit`` [-] on the KS aggregate (``rho`` [1/strain]) at the goals
    of amplitude ``goal_deg`` [deg]."""

    limit: float = STRAIN_LIMIT
    goal_deg: float = GOAL_DEG
    rho: float = KS_RHO

    def __post_init__(self):
        check_range("strain_limit", self.limit, 0.0, 10.0, lo_open=True)
        check_range("goal_deg", self.goal_deg, 0.0, 90.0, lo_open=True)
        check_range("ks_rho", self.rho, 0.0, 1e6, lo_open=True)


def reach_at_limit(roll: float, strain: float, goal_deg: float, limit: float) -> dict:
    """The motor angle [deg] at which the goal strain ``strain`` [-] (measured at ``goal_deg``
    [deg]) reaches ``limit`` [-] (the strain is linear in the goal), and the rod roll reached
    there [deg] (``|roll|`` [deg/deg] times it): the fair comparison of designs that strain
    differently."""
    if not strain > 0:
        raise ConfigError(f"strain: {strain!r}: expected a positive goal strain")
    a = goal_deg * limit / strain
    return {"motor_deg_at_limit": out._r(a), "roll_deg_at_limit": out._r(abs(roll) * a)}


def _optimise(problem, c0: np.ndarray, sign: float, bound: float, maxiter: int, strain: StrainSettings | None,
              floor: float | None, step: Callable[[np.ndarray], None], printable=None):
    """(the optimiser's result, evaluations): SLSQP with the constraints or L-BFGS-B without,
    from ``c0`` (n,) [rad]; ``printable``: a :class:`.print_constraint.PrintConstraint` (linear)."""
    from scipy.optimize import minimize

    count = [0]
    if strain is None:
        def f(c):
            s = roll_sensitivity(problem, c)
            count[0] += 1
            return -sign * s.value, -sign * s.gradient

        res = minimize(f, c0, jac=True, method="L-BFGS-B", bounds=[(-bound, bound)] * len(c0),
                       callback=step, options={"maxiter": maxiter})
        return res, count[0]

    cache = {}

    def at(c):  # SLSQP asks for f, f', g, g' separately at the same point: one solve for all
        key = c.tobytes()
        if key not in cache:
            cache.clear()
            sol = solve_rest(problem, c)
            count[0] += 1
            cache[key] = (roll_sensitivity(problem, c, sol),
                          strain_sensitivity(problem, c, strain.goal_deg, strain.rho, sol=sol),
                          other_min_sensitivity(problem, c, sol) if floor else None)
        return cache[key]

    scale = abs(at(np.zeros_like(c0))[0].value)  # the objective in units of the spiral's roll: O(1) for SLSQP
    cons = [{"type": "ineq", "fun": lambda c: (strain.limit - at(c)[1].value) / strain.limit,
             "jac": lambda c: -at(c)[1].gradient / strain.limit}]
    if floor:
        cons.append({"type": "ineq", "fun": lambda c: (at(c)[2].value - floor) / floor,
                     "jac": lambda c: at(c)[2].gradient / floor})
    if printable is not None:
        cons.append({"type": "ineq", "fun": printable.slack, "jac": printable.slack_jacobian})
    res = minimize(lambda c: -sign * at(c)[0].value / scale, c0, jac=lambda c: -sign * at(c)[0].gradient / scale,
                   method="SLSQP", bounds=[(-bound, bound)] * len(c0), constraints=cons, callback=step,
                   options={"maxiter": maxiter, "ftol": 1e-9})
    return res, count[0]


def free_form(sheets, material, kw: dict, basis: PolarBSpline, pitch0: float, *, maxiter: int, bound_deg: float,
              strain: StrainSettings | None = None, floor_ratio: float = 0.0,
              progress: Callable[[int], None] = lambda i: None, problem=None, start=None, printable=None) -> dict:
    """The free-form design from the spiral (c = 0) of pitch ``pitch0`` [deg] on ``sheets`` of
    ``material`` (``kw``: :func:`.adjoint.rest_problem`'s keywords; ``problem``: that rest
    problem when already built): SLSQP under ``strain`` and the other-DOF floor ``floor_ratio``
    x the spiral's (0: none), or L-BFGS-B on the roll alone when ``strain`` is None. Returns
    ``{"scores": Scores after, "design": dict, "record": JSON-able dict}``; ``progress(iterations
    done)`` after each iteration."""
    problem = rest_problem(sheets, material, basis, **kw) if problem is None else problem
    check_range("floor_ratio", floor_ratio, 0.0, 10.0)
    c0 = np.zeros(problem.n_coefficients)
    goal = GOAL_DEG if strain is None else strain.goal_deg
    before = scores(problem, c0, goal)
    sign = 1.0 if before.roll >= 0 else -1.0  # more roll in the spiral's own sense
    history = []

    def step(x):
        history.append(round(float(solve_rest(problem, x).roll), 6))
        progress(len(history))

    floor = floor_ratio * before.other_min if strain is not None and floor_ratio > 0 else None
    x0 = c0 if start is None else np.clip(problem.field.check(start), -np.radians(bound_deg), np.radians(bound_deg))
    printable = printable if strain is not None else None  # a constraint: SLSQP's only
    res, evaluations = _optimise(problem, x0, sign, np.radians(bound_deg), maxiter, strain, floor, step, printable)
    after = scores(problem, res.x, goal)
    design = {"pitch_deg": pitch0, "basis": basis_dict(basis), "coefficients_rad": [float(v) for v in res.x]}
    record = {"method": ("SLSQP, adjoint gradients of the roll, the KS strain aggregate and the other DOF's "
                         "singular value" if strain else "L-BFGS-B, adjoint gradient of the rod roll per degree"),
              "start": "the orient stage's spiral" if start is None else "the given coefficients",
              "n_coefficients": len(c0), "bound_deg": bound_deg,
              "basis": basis_dict(basis), "iterations": int(res.nit), "evaluations": int(evaluations),
              "converged": bool(res.success), "message": str(res.message),
              "at_bounds": int(np.sum(np.abs(np.abs(res.x) - np.radians(bound_deg)) < 1e-9)),
              "roll_per_iteration": history,
              "before": {**out.scores_record(before.roll, before.other_min, before.singular_values),
                         "goal_strain": out._r(before.strain_max)},
              "after": {**out.scores_record(after.roll, after.other_min, after.singular_values),
                        "goal_strain": out._r(after.strain_max)},
              "ratio_abs_roll": round(abs(after.roll) / abs(before.roll), 6)}
    if strain is not None:
        ks = strain_sensitivity(problem, res.x, strain.goal_deg, strain.rho)
        record["constraints"] = {
            "strain": {"limit": strain.limit, "goal_deg": strain.goal_deg, "aggregate": "KS over goals, elements "
                       "beyond the grip band and quadrature points (an upper bound of the maximum)",
                       "rho": strain.rho, "ks": out._r(ks.value), "exact_max": out._r(ks.exact),
                       "ks_minus_max": out._r(ks.overshoot), "satisfied": bool(ks.exact <= strain.limit + 1e-6)},
            "other_min_floor_mm_per_rad": None if floor is None else out._r(floor),
            "other_min_satisfied": None if floor is None else bool(after.other_min >= floor * (1 - 1e-6))}
        if printable is not None:
            e = np.abs(printable.errors(res.x))
            record["constraints"]["print_round_trip"] = {
                "what": "the fibre angle read back from the print map's texture, linear in the coefficients "
                        "(before the 8-bit rounding), within the tolerance less half an 8-bit step",
                "budget_deg": out._r(printable.budget_deg), "compared": printable.compared, "seam": printable.seam,
                "max_before_deg": out._r(float(np.abs(printable.e0).max())), "max_after_deg": out._r(float(e.max())),
                "satisfied": bool(e.max() <= printable.budget_deg * (1 + 1e-6))}
    return {"scores": after, "design": design, "record": record}


def strain_front(problem, pitch0: float, basis: PolarBSpline, limits: Sequence[float], base: StrainSettings, *,
                 maxiter: int, bound_deg: float, floor_ratio: float, printable=None) -> dict:
    """The constrained optimum at each strain limit of ``limits`` [-] (goals and rho of ``base``),
    each from the spiral: per limit, its roll [deg/deg], other_min [mm/rad], exact goal strain
    [-], whether that is within the limit (false: SLSQP found no feasible design in ``maxiter``,
    which suggests but does not prove that none exists), the ratio to the spiral's |roll| and
    the roll reached at ``base.limit`` (:func:`reach_at_limit`); JSON-able, ``rows`` one per limit."""
    rows = []
    for lim in limits:
        st = StrainSettings(float(lim), base.goal_deg, base.rho)
        r = free_form(None, None, {}, basis, pitch0, maxiter=maxiter, bound_deg=bound_deg, strain=st,
                      floor_ratio=floor_ratio, problem=problem, printable=printable)
        s, rec = r["scores"], r["record"]
        rows.append({"strain_limit": float(lim), "roll_deg_per_deg": out._r(s.roll),
                     "ratio_abs_roll": round(abs(s.roll) / abs(rec["before"]["roll_deg_per_deg"]), 6),
                     "other_min_mm_per_rad": out._r(s.other_min), "goal_strain": out._r(s.strain_max),
                     "satisfied": rec["constraints"]["strain"]["satisfied"], "iterations": rec["iterations"],
                     **reach_at_limit(s.roll, s.strain_max, base.goal_deg, base.limit)})
    return {"what": "the constrained optimum at each strain limit, from the spiral; its reach: the motor angle at "
            f"which its goal strain reaches {base.limit:g} and the rod roll there [deg]",
            "goal_deg": base.goal_deg, "reach_limit": base.limit, "rows": rows}
