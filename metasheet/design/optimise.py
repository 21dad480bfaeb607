"""The free-form fibre field optimised for rod roll: L-BFGS-B with the adjoint gradient
(issue 45, item 3), from the orient stage's spiral (all coefficients 0).

Maximises |rod roll per degree| [deg/deg] in the spiral's own sense over the coefficients of
a :class:`~.fibre_field.PolarBSpline`, each in the box [-bound_deg, bound_deg] [deg]; one
objective evaluation and one adjoint product per iteration (:func:`.adjoint.roll_sensitivity`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import outputs as out
from .adjoint import rest_problem, roll_sensitivity
from .fibre_field import PolarBSpline
from .search import scores


def basis_dict(b: PolarBSpline) -> dict:
    """``b``'s constructor keywords (JSON-able; ``PolarBSpline(**basis_dict(b))`` rebuilds it)."""
    return {"n_radial": b.n_radial, "n_angular": b.n_angular, "degree": b.degree, "r_max": b.r_max,
            "symmetric": b.symmetric}


def free_form(sheets, material, kw: dict, basis: PolarBSpline, pitch0: float, *, maxiter: int, bound_deg: float,
              progress: Callable[[int], None] = lambda i: None) -> dict:
    """L-BFGS-B on |rod roll per degree| with the adjoint gradient, from the spiral (c = 0) of
    pitch ``pitch0`` [deg] on ``sheets`` of ``material`` (``kw``: :func:`.adjoint.rest_problem`'s
    keywords). Returns ``{"scores": Scores after, "design": dict, "record": JSON-able dict}``;
    ``progress(iterations done)`` after each iteration."""
    from scipy.optimize import minimize

    problem = rest_problem(sheets, material, basis, **kw)
    c0 = np.zeros(problem.n_coefficients)
    before = scores(problem, c0)
    sign = 1.0 if before.roll >= 0 else -1.0  # more roll in the spiral's own sense
    history, count = [], [0]

    def f(c):
        s = roll_sensitivity(problem, c)
        count[0] += 1
        return -sign * s.value, -sign * s.gradient

    def step(intermediate_result):
        history.append(round(-sign * float(intermediate_result.fun), 6))
        progress(len(history))

    b = np.radians(bound_deg)
    res = minimize(f, c0, jac=True, method="L-BFGS-B", bounds=[(-b, b)] * len(c0), callback=step,
                   options={"maxiter": maxiter})
    after = scores(problem, res.x)
    design = {"pitch_deg": pitch0, "basis": basis_dict(basis), "coefficients_rad": [float(v) for v in res.x]}
    record = {"method": "L-BFGS-B, adjoint gradient of the rod roll per degree", "start": "the orient stage's spiral",
              "n_coefficients": len(c0), "bound_deg": bound_deg, "basis": basis_dict(basis),
              "iterations": int(res.nit), "evaluations": int(count[0]), "message": str(res.message),
              "at_bounds": int(np.sum(np.abs(np.abs(res.x) - b) < 1e-9)),
              "roll_per_iteration": history,
              "before": out.scores_record(before.roll, before.other_min, before.singular_values),
              "after": out.scores_record(after.roll, after.other_min, after.singular_values),
              "ratio_abs_roll": round(abs(after.roll) / abs(before.roll), 6)}
    return {"scores": after, "design": design, "record": record}
