"""Designing the sheet: a free-form in-plane fibre field, the objectives a design is judged on
at the rest pose, and their adjoint gradients (issue 45, item 3's core).

* :mod:`.fibre_field`: the fibre-angle field theta(x) = theta0(x) + sum_j c_j N_j(x) on a polar
  tensor B-spline basis, optionally tied to the sheet's 120 deg symmetry; sheet B is A's mirror.
* :mod:`.tensor`: the foam's tensor turned in the sheet plane and its exact angle derivative.
* :mod:`.objectives`: rod roll per degree [deg/deg], smallest scaled singular value [mm/rad],
  each with its derivative in J as a rank-one weight pair.
* :mod:`.adjoint`: the robot's linear rest problem as a function of the design, and the
  adjoint gradient (one objective evaluation plus element-wise products).
* :mod:`.strain`: the largest principal (linearised) strain at a stated set of motor goals.
* :mod:`.printability`: IceSL's setting ranges and the fibre axis' 8-bit print round trip.
* :mod:`.evaluation`: every objective of one design, and the chosen design against the spiral.
* :mod:`.constraints`: the KS aggregate of the strain at the goals and the other DOF's
  smallest singular value, with their adjoint gradients.
* :mod:`.optimise`: the free-form field by SLSQP under those constraints (or L-BFGS-B on the
  roll alone), and the roll-strain front.

The public names below load their module on first use.
"""

from importlib import import_module

_PUBLIC = {
    "PolarBSpline": "fibre_field", "FibreField": "fibre_field", "fibres_at": "fibre_field",
    "rod_roll_per_degree": "objectives", "min_singular_value": "objectives",
    "scaled_singular_values": "objectives", "RankOne": "objectives", "decoupling": "objectives",
    "Decoupling": "objectives",
    "RestProblem": "adjoint", "RestSolution": "adjoint", "Sensitivity": "adjoint",
    "rest_problem": "adjoint", "solve_rest": "adjoint", "roll_sensitivity": "adjoint",
    "min_singular_sensitivity": "adjoint", "gradient": "adjoint",
}
__all__ = [
    "Decoupling",
    "FibreField",
    "PolarBSpline",
    "RankOne",
    "RestProblem",
    "RestSolution",
    "Sensitivity",
    "decoupling",
    "fibres_at",
    "gradient",
    "min_singular_sensitivity",
    "min_singular_value",
    "rest_problem",
    "rod_roll_per_degree",
    "roll_sensitivity",
    "scaled_singular_values",
    "solve_rest",
]


def __getattr__(name):
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
