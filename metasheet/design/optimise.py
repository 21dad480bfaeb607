"""The free-form fibre field optimised for rod roll with the adjoint gradient (issue 45, item 3),
from the orient stage's spiral (all coefficients 0).

Maximises |rod roll per degree| [deg/deg] in the spiral's own sense over the coefficients of
a :class:`~.fibre_field.PolarBSpline`, each in the box [-bound_deg, bound_deg] [deg]:

* constrained (default): SLSQP subject to the KS aggregate of the largest principal strain at
  the goals <= ``strain_limit``, the other five DOF's smallest singular value and each of the
  other five singular values of the scaled Jacobian >= the spiral's (:mod:`.constraints`; one
  rest solve, one adjoint product per function and one back-substitution for the strain's
  adjoint fields per iteration), from the spiral and optionally from seeded random starts (the
  problem has several local optima: docs/design.md);
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
from .constraints import KS_RHO, other_min_sensitivity, other_singular_sensitivities, strain_sensitivity
from ..sheet.fibre_field import PolarBSpline
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


#: relative margin of the singular-value floors inside SLSQP, so that its constraint tolerance
#: cannot leave a chosen value below the spiral's
FLOOR_MARGIN = 1e-6
#: the random starts' spread: a fraction of the coefficients' bound
START_SPREAD = 0.25


@dataclass(frozen=True)
class Floors:
    """The other DOF's floors [mm/rad]: ``other_min`` on the smallest singular value of the five
    directions other than the roll, ``others`` (5,) on each of the other five singular values of
    the scaled Jacobian (largest first; :func:`.objectives.roll_index` says which is the roll's)."""

    other_min: float
    others: tuple[float, ...]


def _optimise(problem, c0: np.ndarray, sign: float, bound: float, maxiter: int, strain: StrainSettings | None,
              floors: Floors | None, step: Callable[[np.ndarray], None], printable=None):
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
                          other_min_sensitivity(problem, c, sol) if floors else None,
                          other_singular_sensitivities(problem, c, sol) if floors else None)
        return cache[key]

    scale = abs(solve_rest(problem, np.zeros_like(c0)).roll)  # the spiral's roll: an O(1) objective for SLSQP
    cons = [{"type": "ineq", "fun": lambda c: (strain.limit - at(c)[1].value) / strain.limit,
             "jac": lambda c: -at(c)[1].gradient / strain.limit}]
    if floors:
        lo, los = floors.other_min * (1 + FLOOR_MARGIN), np.array(floors.others) * (1 + FLOOR_MARGIN)
        cons.append({"type": "ineq", "fun": lambda c: (at(c)[2].value - lo) / lo,
                     "jac": lambda c: at(c)[2].gradient / lo})
        cons.append({"type": "ineq", "fun": lambda c: np.array([s.value for s in at(c)[3]]) / los - 1.0,
                     "jac": lambda c: np.array([s.gradient for s in at(c)[3]]) / los[:, None]})
    if printable is not None:
        cons.append({"type": "ineq", "fun": printable.slack, "jac": printable.slack_jacobian})
    res = minimize(lambda c: -sign * at(c)[0].value / scale, c0, jac=lambda c: -sign * at(c)[0].gradient / scale,
                   method="SLSQP", bounds=[(-bound, bound)] * len(c0), constraints=cons, callback=step,
                   options={"maxiter": maxiter, "ftol": 1e-9})
    return res, count[0]


def start_points(n: int, n_starts: int, bound: float, seed: int, spread: float = START_SPREAD) -> np.ndarray:
    """(n_starts, n) starting coefficients [rad]: the spiral (zeros) first, then uniform draws in
    ``+-spread * bound`` [rad] from ``seed`` (the same points for the same arguments)."""
    check_range("starts", n_starts, 1, 1000)
    rng = np.random.default_rng(seed)
    return np.vstack([np.zeros((1, n)), rng.uniform(-spread * bound, spread * bound, (n_starts - 1, n))])


def free_form(sheets, material, kw: dict, basis: PolarBSpline, pitch0: float, *, maxiter: int, bound_deg: float,
              strain: StrainSettings | None = None, floor_ratio: float = 0.0,
              progress: Callable[[int], None] = lambda i: None, problem=None, start=None, printable=None,
              starts: int = 1, seed: int = 0) -> dict:
    """The free-form design from the spiral (c = 0) of pitch ``pitch0`` [deg] on ``sheets`` of
    ``material`` (``kw``: :func:`.adjoint.rest_problem`'s keywords; ``problem``: that rest
    problem when already built): SLSQP under ``strain`` and the other-DOF floors ``floor_ratio``
    x the spiral's (the five-direction minimum and each of the other five singular values; 0:
    none), or L-BFGS-B on the roll alone when ``strain`` is None. With ``starts`` > 1, SLSQP also
    runs from ``starts - 1`` seeded random points (:func:`start_points`) and keeps the feasible
    result of largest |roll| (the first on a tie; the spiral's run when none is feasible).
    Returns ``{"scores": Scores after, "design": dict, "record": JSON-able dict}``;
    ``progress(iterations done)`` after each iteration, over all starts."""
    problem = rest_problem(sheets, material, basis, **kw) if problem is None else problem
    check_range("floor_ratio", floor_ratio, 0.0, 10.0)
    c0 = np.zeros(problem.n_coefficients)
    goal = GOAL_DEG if strain is None else strain.goal_deg
    before = scores(problem, c0, goal)
    sign = 1.0 if before.roll >= 0 else -1.0  # more roll in the spiral's own sense
    done = [0]
    floors = Floors(floor_ratio * before.other_min, tuple(floor_ratio * v for v in before.others)) \
        if strain is not None and floor_ratio > 0 else None
    bound = np.radians(bound_deg)
    printable = printable if strain is not None else None  # a constraint: SLSQP's only
    if start is not None:
        points = np.clip(problem.field.check(start), -bound, bound)[None]
    else:
        points = start_points(len(c0), starts if strain is not None else 1, bound, seed)
    runs = []
    for x0 in points:
        history = []

        def step(x, history=history):
            history.append(round(float(solve_rest(problem, x).roll), 6))
            done[0] += 1
            progress(done[0])

        res, evaluations = _optimise(problem, x0, sign, bound, maxiter, strain, floors, step, printable)
        after = scores(problem, res.x, goal)
        runs.append((res, evaluations, after, history, _feasible(problem, res.x, after, strain, floors, printable)))
    best = _best_run(runs)
    res, evaluations, after, history, _ = runs[best]
    design = {"pitch_deg": pitch0, "basis": basis_dict(basis), "coefficients_rad": [float(v) for v in res.x]}
    record = {"method": ("SLSQP, adjoint gradients of the roll, the KS strain aggregate and the other DOF's "
                         "singular values" if strain else "L-BFGS-B, adjoint gradient of the rod roll per degree"),
              "start": ("the orient stage's spiral" if start is None else "the given coefficients")
              + (f", then {len(points) - 1} seeded random points within +-{START_SPREAD:g} x the bound "
                 f"(seed {seed}); the best feasible run is kept" if len(points) > 1 else ""),
              "n_coefficients": len(c0), "bound_deg": bound_deg,
              "basis": basis_dict(basis), "iterations": int(res.nit), "evaluations": int(evaluations),
              "converged": bool(res.success), "message": str(res.message),
              "at_bounds": int(np.sum(np.abs(np.abs(res.x) - bound) < 1e-9)),
              "roll_per_iteration": history,
              "before": {**out.scores_record(before.roll, before.other_min, before.singular_values),
                         "goal_strain": out._r(before.strain_max)},
              "after": {**out.scores_record(after.roll, after.other_min, after.singular_values),
                        "goal_strain": out._r(after.strain_max)},
              "ratio_abs_roll": round(abs(after.roll) / abs(before.roll), 6)}
    if len(points) > 1:
        record["starts"] = {"kept": best, "runs": [
            {"ratio_abs_roll": round(abs(a.roll) / abs(before.roll), 6), "feasible": ok, "iterations": int(r.nit),
             "converged": bool(r.success)} for r, _, a, _, ok in runs]}
    if strain is not None:
        record["constraints"] = _constraint_record(problem, res.x, after, strain, floors, printable)
    return {"scores": after, "design": design, "record": record}


def _feasible(problem, c, after, strain, floors, printable) -> bool:
    """Whether design ``c`` meets every constraint (exactly: the strain's true maximum, not its KS)."""
    if strain is None:
        return True
    ok = after.strain_max <= strain.limit * (1 + 1e-6)
    if floors is not None:
        ok = ok and after.other_min >= floors.other_min * (1 - 1e-6) and out.meets_floors(after.others, floors.others)
    if printable is not None:
        ok = ok and float(np.abs(printable.errors(c)).max()) <= printable.budget_deg * (1 + 1e-6)
    return bool(ok)


def _best_run(runs) -> int:
    """The index of the feasible run of largest |roll| (the first on a tie), else 0."""
    best = 0
    for i, (_, _, a, _, ok) in enumerate(runs):
        if ok and (not runs[best][4] or abs(a.roll) > abs(runs[best][2].roll)):
            best = i
    return best


def _constraint_record(problem, c, after, strain: StrainSettings, floors: Floors | None, printable) -> dict:
    """``record["constraints"]``: each constraint's value at design ``c`` and whether it holds."""
    ks = strain_sensitivity(problem, c, strain.goal_deg, strain.rho)
    rec = {"strain": {"limit": strain.limit, "goal_deg": strain.goal_deg, "aggregate": "KS over goals, elements "
                      "beyond the grip band and quadrature points (an upper bound of the maximum)",
                      "rho": strain.rho, "ks": out._r(ks.value), "exact_max": out._r(ks.exact),
                      "ks_minus_max": out._r(ks.overshoot), "satisfied": bool(ks.exact <= strain.limit + 1e-6)},
           "other_min_floor_mm_per_rad": None if floors is None else out._r(floors.other_min),
           "other_min_satisfied": None if floors is None else bool(after.other_min >= floors.other_min * (1 - 1e-6)),
           "other_singular_values": None if floors is None else {
               "floors_mm_per_rad": [out._r(v) for v in floors.others],
               "values_mm_per_rad": [out._r(v) for v in after.others],
               "satisfied": out.meets_floors(after.others, floors.others)}}
    if printable is not None:
        e = np.abs(printable.errors(c))
        rec["print_round_trip"] = {
            "what": "the fibre angle read back from the print map's texture, linear in the coefficients "
                    "(before the 8-bit rounding), within the tolerance less half an 8-bit step",
            "budget_deg": out._r(printable.budget_deg), "compared": printable.compared, "seam": printable.seam,
            "max_before_deg": out._r(float(np.abs(printable.e0).max())), "max_after_deg": out._r(float(e.max())),
            "satisfied": bool(e.max() <= printable.budget_deg * (1 + 1e-6))}
    return rec


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
