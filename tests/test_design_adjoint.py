"""Adjoint gradients of the rest objectives (metasheet.design.adjoint) on the coarse robot
(15 mm P1 sheets, 1,178 tets each: one objective evaluation ~30 ms).

Finite differences: central, step h = 1e-4 rad on the coefficients. Measured (worst of the
three random designs and directions below): relative error 1.7e-7 for the roll and 1.3e-6
for the smallest singular value at h = 1e-4 (1.8e-5 and 1.3e-4 at 1e-3: truncation; 1.8e-9
and 1.5e-6 at 1e-5: round-off begins for the singular value). The tolerance is issue 45's
1e-5 relative.
"""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.design.adjoint import (
    min_singular_sensitivity,
    rest_problem,
    roll_sensitivity,
    solve_rest,
)
from metasheet.sheet.fibre_field import PolarBSpline, rotate_points
from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.kinematics import kinematics
from metasheet.sheet.fibers import spiral_fibers
from metasheet.sheet.geometry import SheetMesh, SheetParams, mirror_sheet

H = 1e-4  # [rad] central-difference step
RTOL = 1e-5
R_MAX = 68.0  # [mm] the basis' disk, fixed so that a turned sheet has the same basis


@pytest.fixture(scope="module")
def sheets():
    return SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)


@pytest.fixture(scope="module")
def problem(sheets):
    return rest_problem(sheets, paper.PAPER_FOAM, PolarBSpline(r_max=R_MAX))


@pytest.fixture(scope="module")
def symmetric(sheets):
    return rest_problem(sheets, paper.PAPER_FOAM, PolarBSpline(r_max=R_MAX, symmetric=True))


def _fd(problem, c, d, which):
    f = (lambda s: s.roll) if which == "roll" else (lambda s: s.singular_values[-1])
    return (f(solve_rest(problem, c + H * d)) - f(solve_rest(problem, c - H * d))) / (2 * H)


@pytest.mark.slow
def test_rest_model_is_the_robots_linearisation_without_gravity(sheets, problem):
    """At the spiral and at a designed field: the builder's robot from ``field.fibres(c)``
    (its own tensors, mirror and world frames), linearised at rest without gravity, has the
    rest model's J, roll and singular values.
    Default-selection sibling: test_rest_model_is_the_robots_linearisation_at_a_designed_field."""
    c1 = np.random.default_rng(8).uniform(-0.5, 0.5, problem.n_coefficients)
    _rest_model_check(sheets, problem, (np.zeros(problem.n_coefficients), c1))


def test_rest_model_is_the_robots_linearisation_at_a_designed_field(sheets, problem):
    """The slow test's check at its designed field alone (the spiral is the zero field)."""
    _rest_model_check(sheets, problem, (np.random.default_rng(8).uniform(-0.5, 0.5, problem.n_coefficients),))


def _rest_model_check(sheets, problem, designs):
    for c in designs:
        fa, fb = problem.field.fibres(c)
        pair = SheetPair(sheets.sheet, sheets.mirrored, fa, fb)
        robot = six_dof_robot(pair, paper.PAPER_FOAM, density=paper.FOAM_DENSITY, gravity=(0.0, 0.0, 0.0))
        kin = kinematics(robot.linearizer().linearize(robot.rest_state()))
        sol = solve_rest(problem, c)
        assert np.abs(sol.J - kin.J).max() < 1e-9 * np.abs(kin.J).max()
        assert abs(sol.roll - float(kin.all_together[3:] @ robot.axis)) < 1e-9 * abs(sol.roll)
        assert np.allclose(sol.singular_values, kin.singular_values, rtol=1e-9, atol=0)
        assert abs(sol.roll) > 0.5  # these fields roll the rod


@pytest.mark.parametrize("which", ["roll", "sv"])
def test_gradient_matches_central_differences(problem, which):
    rng = np.random.default_rng(45)
    sens = roll_sensitivity if which == "roll" else min_singular_sensitivity
    for _ in range(3):  # random designs, random directions
        c = rng.uniform(-0.4, 0.4, problem.n_coefficients)
        d = rng.standard_normal(problem.n_coefficients)
        s = sens(problem, c)
        assert s.gap > 0.01 * s.value  # a simple singular value (inf for the roll): differentiable
        fd = _fd(problem, c, d, which)
        assert abs(s.gradient @ d - fd) < RTOL * abs(fd), (s.gradient @ d, fd)


def test_gradient_component_by_component(symmetric):
    c = np.random.default_rng(7).uniform(-0.3, 0.3, symmetric.n_coefficients)
    g = roll_sensitivity(symmetric, c).gradient
    fd = np.array([_fd(symmetric, c, e, "roll") for e in np.eye(symmetric.n_coefficients)])
    assert np.abs(g - fd).max() < RTOL * np.abs(fd).max()


def test_symmetric_gradient_sums_the_tied_ones(problem, symmetric):
    c = np.random.default_rng(3).uniform(-0.3, 0.3, symmetric.n_coefficients)
    T = symmetric.field.basis.tie_matrix()
    full = roll_sensitivity(problem, T @ c)
    tied = roll_sensitivity(symmetric, c)
    assert abs(full.value - tied.value) < 1e-12 * abs(full.value)
    assert np.abs(tied.gradient - T.T @ full.gradient).max() < 1e-10 * np.abs(tied.gradient).max()


def _turned(sheet: SheetMesh) -> SheetMesh:
    """``sheet`` turned by 120 deg about its normal, arm k's grip now arm k + 1's."""
    att = sheet.attach.copy()
    for tag in (1, 2, 3):
        att[sheet.attach == tag] = tag % 3 + 1
    return SheetMesh(rotate_points(sheet.points, 2 * np.pi / 3), sheet.tets, att, sheet.arm_angles,
                     sheet.quality, sheet.params, False)


def test_turned_robot_has_the_same_roll_and_tied_gradients_equal(sheets, problem):
    """The robot turned by 120 deg about the rod is the same robot (its motors relabelled):
    the roll is unchanged and the gradient's angular index shifts by n_angular / 3. So on a
    120-deg-symmetric mesh the gradients of tied coefficients are equal; the coarse gmsh mesh
    is not symmetric, which is why the symmetric option sums them (previous test)."""
    a = _turned(sheets.sheet)
    b = mirror_sheet(a)
    turned = SheetPair(a, b, spiral_fibers(a.centroids(), pitch_deg=30.0),
                       spiral_fibers(b.centroids(), pitch_deg=30.0, mirrored=True))
    other = rest_problem(turned, paper.PAPER_FOAM, PolarBSpline(r_max=R_MAX))
    c = np.random.default_rng(11).uniform(-0.3, 0.3, (4, 12))
    s0 = roll_sensitivity(problem, c.ravel())
    s1 = roll_sensitivity(other, np.roll(c, 4, axis=1).ravel())
    assert abs(s1.value - s0.value) < 1e-9 * abs(s0.value)
    g0, g1 = s0.gradient.reshape(4, 12), s1.gradient.reshape(4, 12)
    assert np.abs(g1 - np.roll(g0, 4, axis=1)).max() < 1e-8 * np.abs(g0).max()


def test_isotropic_sheets_neither_roll_nor_care_about_fibres(sheets):
    iso = rest_problem(sheets, Isotropic(1.39, 0.26162), PolarBSpline(r_max=R_MAX))
    c = np.random.default_rng(5).uniform(-0.5, 0.5, iso.n_coefficients)
    s = roll_sensitivity(iso, c)
    assert abs(s.value) < 1e-3  # deg/deg; the foam spiral: ~1.05. Not 0: the mesh is not symmetric
    assert np.abs(s.gradient).max() < 1e-12
    assert np.abs(min_singular_sensitivity(iso, c).gradient).max() < 1e-10


def test_same_design_same_bits(problem):
    c = np.linspace(-0.2, 0.2, problem.n_coefficients)
    a, b = roll_sensitivity(problem, c), roll_sensitivity(problem, c)
    assert a.value == b.value and np.array_equal(a.gradient, b.gradient)


def test_bad_input_names_the_field(sheets, problem):
    with pytest.raises(ConfigError, match=r"^c: shape is \(5,\) and should be \(48,\)"):
        solve_rest(problem, np.zeros(5))
    c = np.zeros(48)
    c[2] = np.nan
    with pytest.raises(ConfigError, match=r"^c\[2\]: nan"):
        roll_sensitivity(problem, c)
    with pytest.raises(ConfigError, match="^material: str"):
        rest_problem(sheets, "foam")
    unmirrored = SheetPair(sheets.sheet, sheets.mirrored, sheets.fibers, sheets.fibers)
    with pytest.raises(ConfigError, match="^fibers_mirrored: not the mirror image"):
        rest_problem(unmirrored, paper.PAPER_FOAM)
    with pytest.raises(ConfigError, match="^length_scale"):
        rest_problem(sheets, paper.PAPER_FOAM, length_scale=0.0)
