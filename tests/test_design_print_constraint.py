"""The print round trip as a linear constraint (metasheet.design.print_constraint).

Its derivative against central differences of the whole (unrounded) round trip; its prediction
against the round trip at another design; the 8-bit check within the model plus half a step.

Each round trip samples the field on IceSL's 64^3 texture and picks its angle branch (about
2 s of CPU whatever the mesh): the default tests share the spiral's round trip and take
forward differences, the slow ones repeat it on the finer sheet with central differences."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.design import printability as pr
from metasheet.sheet.fibre_field import PolarBSpline, fibres_at
from metasheet.design.print_constraint import QUANTUM_DEG, foam_centroids, print_constraint, read_back_errors
from metasheet.design.search import spiral_angles
from metasheet.errors import ConfigError
from metasheet.robot import SheetPair
from metasheet.sheet import SheetParams


def _case(mesh_size):
    params = SheetParams(mesh_size=mesh_size)
    mesh = SheetPair.spiral(params, pitch_deg=30.0).sheet
    basis = PolarBSpline(n_radial=2, n_angular=3, degree=1, r_max=68.0, symmetric=True)

    def spiral(q):
        return spiral_angles(q, pitch_deg=30.0, law="log", r_ref=33.0)

    pc = print_constraint(mesh.points, mesh.tets, params, spiral, basis.design_matrix)
    return params, mesh, basis, spiral, pc


def _spiral_round_trip(case):
    """(foam centroids, the spiral's signed errors, its seam mask): the round trip at c = 0."""
    params, mesh, _, spiral, _ = case
    cent = foam_centroids(mesh.points, mesh.tets, params)
    e0, seam0, _ = read_back_errors(mesh.points, mesh.tets, params, spiral, cent)
    return cent, e0, seam0


@pytest.fixture(scope="module")
def case():
    """The coarse robot's sheet (15 mm) for the slow tests."""
    return _case(15.0)


@pytest.fixture(scope="module")
def coarse_case():
    """A 24 mm sheet for their default-selection siblings."""
    return _case(24.0)


@pytest.fixture(scope="module")
def coarse_spiral(coarse_case):
    return _spiral_round_trip(coarse_case)


def _field(spiral, basis, c):
    return lambda q: spiral(q) + basis.design_matrix(q) @ c


@pytest.mark.slow
def test_derivative_equals_central_differences(case):
    """Default-selection sibling: test_derivative_equals_forward_differences_on_a_coarse_sheet."""
    _derivative_check(case, _spiral_round_trip(case), central=True)


def test_derivative_equals_forward_differences_on_a_coarse_sheet(coarse_case, coarse_spiral):
    """Off the seam the unrounded round trip is affine in c (a trilinear read of texels linear in
    c, less the design angle): a one-sided difference has no truncation error either, only
    round-off. Measured on this sheet: 1.6e-10 off G (central: 8e-11), against the bound's
    1e-6 x max |fd| = 5e-8."""
    _derivative_check(coarse_case, coarse_spiral, central=False)


def _derivative_check(case, spiral_round_trip, *, central: bool):
    params, mesh, basis, spiral, pc = case
    cent, e0, seam0 = spiral_round_trip
    assert pc.compared == int((~seam0).sum()) and pc.seam == int(seam0.sum()) and pc.G.shape[1] == 2
    assert np.array_equal(pc.e0, e0[~seam0])  # the model's e0 is the round trip's, off the seam
    h = 1e-3
    for j in range(2):
        step = np.zeros(2)
        step[j] = h
        hi, s_hi, _ = read_back_errors(mesh.points, mesh.tets, params, _field(spiral, basis, step), cent)
        assert np.array_equal(s_hi, seam0)
        if central:
            lo, s_lo, _ = read_back_errors(mesh.points, mesh.tets, params, _field(spiral, basis, -step), cent)
            assert np.array_equal(s_lo, seam0)
            fd = (hi - lo)[~seam0] / (2 * h)
        else:
            fd = (hi - e0)[~seam0] / h
        np.testing.assert_allclose(pc.G[:, j], fd, rtol=0, atol=1e-6 * np.abs(fd).max())


@pytest.mark.slow
def test_prediction_and_the_8_bit_check_at_another_design(case):
    """Default-selection sibling: test_prediction_and_the_8_bit_check_on_a_coarse_sheet."""
    _prediction_check(case, _spiral_round_trip(case))


def test_prediction_and_the_8_bit_check_on_a_coarse_sheet(coarse_case, coarse_spiral):
    _prediction_check(coarse_case, coarse_spiral)


def _prediction_check(case, spiral_round_trip):
    params, mesh, basis, spiral, pc = case
    c = np.array([0.3, -0.25])  # [rad], tens of degrees
    cent, _, seam0 = spiral_round_trip
    e, seam, _ = read_back_errors(mesh.points, mesh.tets, params, _field(spiral, basis, c), cent)
    same = ~seam[~seam0]  # elements off the seam in both designs
    np.testing.assert_allclose(pc.errors(c)[same], e[~seam0][same], rtol=0, atol=1e-9)
    rt = pr.angle_round_trip(mesh.points, mesh.tets, params, lambda q: fibres_at(_field(spiral, basis, c)(q)))
    assert rt.max_deg <= np.abs(e[~seam]).max() + QUANTUM_DEG + 1e-9  # rounding moves it by half a step at most
    slack = pc.slack(c)
    assert slack.shape == (2 * pc.compared,)
    assert np.allclose(pc.slack_jacobian(c) @ c, slack - pc.slack(np.zeros(2)))


def test_no_budget_is_refused(coarse_case):
    params, mesh, basis, spiral, _ = coarse_case
    with pytest.raises(ConfigError, match="angle_tolerance_deg"):
        print_constraint(mesh.points, mesh.tets, params, spiral, basis.design_matrix, tolerance_deg=0.5)
