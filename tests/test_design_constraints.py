"""The design's constraints (metasheet.design.constraints) and the constrained free-form
optimisation (metasheet.design.optimise) on the coarse robot (15 mm P1 sheets, the paper's
foam and spiral; one rest solve and strain aggregate ~0.1 s).

Finite differences: central, step h = 1e-4 rad on the coefficients. Measured (worst of the
random designs and directions below): relative error 4e-8 for the KS strain aggregate (rho 50,
200 and 1000: 1.2e-9 at 1000) and 1.1e-7 for the other DOF's smallest singular value. The tolerance is issue 45's
1e-5 relative.
"""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.design.adjoint import rest_problem, solve_rest
from metasheet.design.constraints import (
    ks_aggregate,
    other_min_sensitivity,
    principal_max,
    strain_sensitivity,
)
from metasheet.sheet.fibre_field import PolarBSpline
from metasheet.design.optimise import StrainSettings, free_form, reach_at_limit
from metasheet.design.search import other_five_min
from metasheet.design.strain import goal_strain, principal_strains
from metasheet.errors import ConfigError
from metasheet.robot.builder import SheetPair
from metasheet.sheet.geometry import SheetParams

H = 1e-4  # [rad] central-difference step
RTOL = 1e-5


@pytest.fixture(scope="module")
def problem():
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)
    return rest_problem(sheets, paper.PAPER_FOAM, PolarBSpline(r_max=68.0, symmetric=True))


def test_ks_aggregate_is_log_sum_exp_and_bounds_the_max():
    v = np.random.default_rng(3).uniform(0.0, 0.3, 500)
    for rho in (10.0, 200.0):
        ks, w = ks_aggregate(v, rho)
        assert abs(ks - np.log(np.exp(rho * v).sum()) / rho) < 1e-12
        assert v.max() <= ks <= v.max() + np.log(v.size) / rho
        assert abs(w.sum() - 1) < 1e-12 and w.min() >= 0


def test_principal_max_derivative_in_voigt_engineering_shear():
    """d lambda_max / d eps_Voigt against central differences of numpy's eigenvalues (the
    shear entries are engineering: 2 eps_ij)."""
    rng = np.random.default_rng(7)
    eps = rng.uniform(-0.2, 0.2, (20, 6))
    lam, d = principal_max(eps)
    assert np.allclose(lam, principal_strains(eps)[:, -1], rtol=0, atol=1e-14)
    h = 1e-6
    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        fd = (principal_strains(eps + e)[:, -1] - principal_strains(eps - e)[:, -1]) / (2 * h)
        assert np.abs(d[:, k] - fd).max() < 1e-7


@pytest.mark.parametrize("rho", [50.0, 200.0, 1000.0])
def test_strain_aggregate_gradient_matches_central_differences(problem, rho):
    rng = np.random.default_rng(45)
    for _ in range(2):
        c = rng.uniform(-0.4, 0.4, problem.n_coefficients)
        d = rng.standard_normal(problem.n_coefficients)
        s = strain_sensitivity(problem, c, rho=rho)
        fd = (strain_sensitivity(problem, c + H * d, rho=rho).value
              - strain_sensitivity(problem, c - H * d, rho=rho).value) / (2 * H)
        assert abs(s.gradient @ d - fd) < RTOL * abs(fd), (s.gradient @ d, fd)
        # the exact maximum is strain.py's own (a separate code path), and KS bounds it from above
        exact = goal_strain(problem, solve_rest(problem, c)).worst
        assert abs(s.exact - exact) < 1e-12
        assert exact <= s.value <= exact + np.log(s.points) / rho


def test_other_min_gradient_matches_central_differences(problem):
    rng = np.random.default_rng(46)
    axis = problem.robot.axis
    for _ in range(2):
        c = rng.uniform(-0.4, 0.4, problem.n_coefficients)
        d = rng.standard_normal(problem.n_coefficients)
        s = other_min_sensitivity(problem, c)
        assert abs(s.value - other_five_min(solve_rest(problem, c).J, axis)) < 1e-12 * s.value
        fd = (other_five_min(solve_rest(problem, c + H * d).J, axis)
              - other_five_min(solve_rest(problem, c - H * d).J, axis)) / (2 * H)
        assert abs(s.gradient @ d - fd) < RTOL * abs(fd), (s.gradient @ d, fd)


def test_constrained_optimum_keeps_the_strain_within_the_limit(problem):
    """SLSQP at limit 0.26 (the spiral's goal strain here is 0.231; the roll's optimum without
    the constraint strains far more): the strain at the goals, measured by strain.py's exact
    maximum, is within the limit (tolerance 1e-6: SLSQP's constraint violation), the constraint
    is active (the KS aggregate at the limit to 1e-4), the roll grows and the other DOF keep
    the spiral's singular value."""
    st = StrainSettings(limit=0.26)
    r = free_form(None, None, {}, problem.field.basis, 30.0, maxiter=40, bound_deg=45.0, strain=st, floor_ratio=1.0,
                  problem=problem)
    c = np.asarray(r["design"]["coefficients_rad"])
    sol = solve_rest(problem, c)
    spiral = solve_rest(problem, np.zeros_like(c))
    assert goal_strain(problem, spiral).worst < st.limit - 0.02  # the start is feasible, not on the limit
    assert goal_strain(problem, sol).worst <= st.limit + 1e-6
    assert abs(strain_sensitivity(problem, c, st.goal_deg, st.rho).value - st.limit) < 1e-4
    assert abs(sol.roll) > 1.2 * abs(spiral.roll)
    axis = problem.robot.axis
    assert other_five_min(sol.J, axis) >= other_five_min(spiral.J, axis) * (1 - 1e-6)
    assert r["record"]["constraints"]["strain"]["satisfied"]


def test_reach_at_limit_is_linear_in_the_goal():
    r = reach_at_limit(-2.0, 0.5, 10.0, 0.3)  # strain 0.5 at 10 deg: 0.3 at 6 deg, 12 deg of roll
    assert abs(r["motor_deg_at_limit"] - 6.0) < 1e-12 and abs(r["roll_deg_at_limit"] - 12.0) < 1e-12
    with pytest.raises(ConfigError, match="strain"):
        reach_at_limit(-2.0, 0.0, 10.0, 0.3)
    with pytest.raises(ConfigError, match="strain_limit"):
        StrainSettings(limit=0.0)


def test_choose_takes_the_feasible_design_of_most_roll():
    from metasheet.design.outputs import Candidate, choose

    sv = (1.0,) * 6
    spiral = Candidate("spiral", -1.6, 12.0, sv, {}, 0.31)  # beyond the strain limit
    cands = [spiral, Candidate("a", -3.8, 13.0, sv, {}, 0.50), Candidate("b", -1.4, 12.5, sv, {}, 0.29),
             Candidate("c", -2.0, 11.0, sv, {}, 0.20)]
    assert choose(cands, 12.0, 0.3).name == "b"  # less roll than the spiral, but the spiral strains too much
    assert choose(cands, 12.0).name == "a"  # without the strain limit: the most roll above the floor
    assert choose(cands, 20.0, 0.3).name == "spiral"  # none qualifies: the reference


def test_unconstrained_option_is_lbfgsb_on_the_roll(problem):
    """``strain=None``: L-BFGS-B on the roll alone gains more roll than the constrained run
    (measured 2.53x the spiral in 10 iterations here, goal strain 0.337; the constrained run at
    0.26: 2.40x, 0.259) and strains beyond 0.26."""
    r = free_form(None, None, {}, problem.field.basis, 30.0, maxiter=10, bound_deg=45.0, problem=problem)
    rec = r["record"]
    assert rec["method"].startswith("L-BFGS-B") and "constraints" not in rec
    assert rec["ratio_abs_roll"] > 1.5 and rec["after"]["goal_strain"] > 0.26


def test_other_singular_values_gradients_match_central_differences(problem):
    """Each of the five singular values other than the roll's, where it is simple (its gap to
    its neighbours at least 100 times the change a step makes): adjoint against central
    differences of numpy's SVD of the rest problem's J."""
    from metasheet.design.constraints import other_singular_sensitivities
    from metasheet.design.objectives import roll_index, scaled_singular_values

    rng = np.random.default_rng(47)
    checked = 0
    for _ in range(2):
        c = rng.uniform(-0.4, 0.4, problem.n_coefficients)
        d = rng.standard_normal(problem.n_coefficients)
        sol = solve_rest(problem, c)
        k_roll = roll_index(sol.J, problem.robot.axis)
        others = [k for k in range(6) if k != k_roll]
        sens = other_singular_sensitivities(problem, c, sol)
        assert np.allclose([s.value for s in sens], sol.singular_values[others], rtol=1e-12, atol=0)
        sp, sm = (scaled_singular_values(solve_rest(problem, c + t * H * d).J) for t in (1, -1))
        for s, k in zip(sens, others):
            fd = (sp[k] - sm[k]) / (2 * H)
            if s.gap > 100 * abs(fd) * H:
                assert abs(s.gradient @ d - fd) < RTOL * max(abs(fd), 1e-3 * s.value), (k, s.gradient @ d, fd)
                checked += 1
    assert checked >= 6


def test_roll_index_is_the_roll_direction(problem):
    """At the spiral the roll's singular value is the largest, its effector direction the rod
    axis; a Jacobian whose roll is made the smallest moves the index."""
    from metasheet.design.objectives import LENGTH_SCALE, roll_index

    J = solve_rest(problem, np.zeros(problem.n_coefficients)).J
    axis = problem.robot.axis
    assert roll_index(J, axis) == 0
    U = np.linalg.svd(np.array([1, 1, 1, LENGTH_SCALE, LENGTH_SCALE, LENGTH_SCALE])[:, None] * J)[0]
    assert abs(U[3:, 0] @ axis) > 0.99
    e = np.concatenate([np.zeros(3), axis])
    weak = J - 0.999 * np.outer(e, e @ J)  # the roll nearly gone
    assert roll_index(weak, axis) == 5


@pytest.mark.slow
def test_multi_start_keeps_the_best_feasible_run(problem):
    """Three starts (the spiral, two seeded random points): every run is recorded, the kept one
    is feasible with the largest roll among the feasible ones, and the same seed repeats it.
    Default-selection sibling: test_multi_start_on_two_short_runs."""
    _multi_start(problem, starts=3, maxiter=15)


def test_multi_start_on_two_short_runs(problem):
    """The slow test's checks on two starts of 5 SLSQP iterations."""
    _multi_start(problem, starts=2, maxiter=5)


def _multi_start(problem, starts, maxiter):
    st = StrainSettings(limit=0.26)
    kw = dict(maxiter=maxiter, bound_deg=90.0, strain=st, floor_ratio=1.0, problem=problem, starts=starts, seed=5)
    r = free_form(None, None, {}, problem.field.basis, 30.0, **kw)
    runs = r["record"]["starts"]["runs"]
    assert len(runs) == starts
    feasible = [x["ratio_abs_roll"] for x in runs if x["feasible"]]
    assert feasible and r["record"]["ratio_abs_roll"] == max(feasible)
    assert runs[r["record"]["starts"]["kept"]]["ratio_abs_roll"] == max(feasible)
    c = r["record"]["constraints"]
    assert c["strain"]["satisfied"] and c["other_min_satisfied"] and c["other_singular_values"]["satisfied"]
    assert all(v >= f for v, f in zip(c["other_singular_values"]["values_mm_per_rad"],
                                       c["other_singular_values"]["floors_mm_per_rad"]))
    again = free_form(None, None, {}, problem.field.basis, 30.0, **kw)
    assert again["design"] == r["design"]


def test_start_points_are_seeded_and_start_at_the_spiral():
    from metasheet.design.optimise import start_points

    a, b = start_points(16, 4, 1.0, seed=3), start_points(16, 4, 1.0, seed=3)
    assert a.shape == (4, 16) and np.array_equal(a, b) and not a[0].any()
    assert np.abs(a[1:]).max() <= 0.25 and not np.array_equal(a, start_points(16, 4, 1.0, seed=4))
    with pytest.raises(ConfigError, match="starts"):
        start_points(16, 0, 1.0, seed=3)


def test_choose_keeps_each_other_singular_value_above_its_floor():
    from metasheet.design.outputs import Candidate, choose

    sv = (1.0,) * 6
    cands = [Candidate("spiral", -1.6, 12.0, sv, {}, 0.29, (17.3, 15.1, 15.0, 12.8, 12.7)),
             Candidate("a", -2.5, 13.0, sv, {}, 0.29, (17.2, 15.9, 15.9, 13.4, 13.0)),  # the 2nd one lower
             Candidate("b", -2.4, 12.8, sv, {}, 0.29, (17.4, 15.2, 15.0, 12.9, 12.8))]
    floors = (17.3, 15.1, 15.0, 12.8, 12.7)
    assert choose(cands, 12.0, 0.3).name == "a"
    assert choose(cands, 12.0, 0.3, floors).name == "b"
