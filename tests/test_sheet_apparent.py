"""Apparent constants of a target grip stiffness (metasheet.sheet.apparent, issue 44 item 4) on
the coarse 15 mm sheet of tests/test_sheet_grips.py (1,178 tets), P1 unless named."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.errors import ConfigError
from metasheet.mechanics.material import CONSTANT_NAMES, TransverseIsotropic
from metasheet.mechanics.material_model import model_stiffness
from metasheet.robot.builder import SheetPair, material_stiffness
from metasheet.sheet.apparent import (
    component_basis,
    fit_apparent,
    from_params,
    log_ratios,
    model_components,
    sheet_basis,
    to_params,
)
from metasheet.sheet.fibers import spiral_fibers
from metasheet.sheet.grips import fem_condensed
from metasheet.sheet.outline import SheetParams

FOAM = paper.PAPER_FOAM
#: known constants to recover: every one moved from the paper's foam
TRUTH = TransverseIsotropic(FOAM.E_t * 1.3, FOAM.E_l * 0.6, 0.2, 0.5, FOAM.mu_l * 1.5)


@pytest.fixture(scope="module")
def sheets():
    return SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)


@pytest.fixture(scope="module")
def basis(sheets):
    return sheet_basis(sheets.sheet, sheets.fibers, "p1")


@pytest.fixture(scope="module")
def other_fibres_target(sheets):
    """The FEM K of the same sheet with the fibres at another pitch: no TI material on the
    30 deg field reproduces it."""
    fib = spiral_fibers(sheets.sheet.centroids(), pitch_deg=60.0)
    return fem_condensed(sheets.sheet, material_stiffness(FOAM, fib), "p1").K


def _rel(fit, material):
    return {k: abs(fit.constants[k] / getattr(material, k) - 1.0) for k in CONSTANT_NAMES}


def test_components_span_both_models_and_the_basis_is_the_fem(sheets, basis):
    E = component_basis()
    for model in ("ours", "authors"):
        c = model_components(FOAM.as_tuple(), model)
        assert np.allclose(np.einsum("j,jab->ab", c, E), model_stiffness(FOAM, model), rtol=1e-12, atol=1e-15)
        K = fem_condensed(sheets.sheet, material_stiffness(FOAM, sheets.fibers, model), "p1").K
        assert np.abs(basis.condensed(c) - K).max() < 1e-11 * np.abs(K).max()
    x = np.array(TRUTH.as_tuple())
    assert np.allclose(from_params(to_params(x)), x, rtol=1e-13)
    # every p is a material: far out along each axis the constants stay valid
    for p in (np.full(5, 6.0), np.full(5, -6.0), np.array([0.0, 3.0, -4.0, 8.0, 1.0])):
        TransverseIsotropic(*from_params(p))


@pytest.mark.parametrize("element", ["p1", "p2"])
def test_recovers_known_constants(sheets, basis, element):
    if element == "p2":  # the robot's element (the coarse P2 sheet: ~6,600 dofs)
        basis = sheet_basis(sheets.sheet, sheets.fibers, "p2")
    K = basis.condensed(model_components(TRUTH.as_tuple(), "ours"))
    fit = fit_apparent(basis, K, FOAM)
    assert fit.converged, fit.message
    assert fit.fitted == CONSTANT_NAMES and list(fit.constants) == list(CONSTANT_NAMES)
    assert max(_rel(fit, TRUTH).values()) < 1e-4, fit.constants
    assert fit.rms_log < 1e-8 and fit.max_log < 1e-7
    assert np.abs(np.log(fit.ratios_start)).max() > 0.1  # the start was far
    assert np.allclose(fit.ratios_fit, 1.0, atol=1e-7)
    assert fit.singular_values.shape == (5,) and fit.singular_values.min() > 0
    assert 1 <= fit.evaluations <= 20 and fit.seconds > 0
    assert fit.pd_margin > 0.1  # an interior material
    assert fit.start == FOAM.to_dict() and fit.element == element


def test_authors_model_fits_four_and_keeps_mu_l(basis):
    truth = TransverseIsotropic(FOAM.E_t * 0.8, FOAM.E_l * 1.4, 0.3, 0.35, FOAM.mu_l)
    K = basis.condensed(model_components(truth.as_tuple(), "authors"))
    start = TransverseIsotropic(FOAM.E_t, FOAM.E_l, FOAM.nu_t, FOAM.nu_tl, 123.0)  # mu_l: unused
    fit = fit_apparent(basis, K, start, model="authors")
    assert fit.converged and fit.fitted == CONSTANT_NAMES[:4]
    assert fit.constants["mu_l"] == 123.0
    assert max(v for k, v in _rel(fit, truth).items() if k != "mu_l") < 1e-4, fit.constants
    assert fit.rms_log < 1e-8 and fit.singular_values.shape == (4,)


def test_analytic_jacobian_matches_central_differences(basis, other_fibres_target):
    c = model_components(FOAM.as_tuple(), "ours")
    r, J = log_ratios(basis, other_fibres_target, c, jacobian=True)
    assert r.shape == (18,) and J.shape == (18, 5)
    for j in range(5):
        h = 1e-5 * abs(c[j])
        e = np.zeros(5)
        e[j] = h
        fd = (log_ratios(basis, other_fibres_target, c + e) - log_ratios(basis, other_fibres_target, c - e)) / (2 * h)
        # in units of c_j (the relative sensitivity): scale-free comparison
        assert np.abs((J[:, j] - fd) * c[j]).max() < 1e-5 * max(np.abs(J * c).max(), 1.0), j


def test_doubled_target_doubles_the_moduli(basis):
    K = basis.condensed(model_components(FOAM.as_tuple(), "ours"))
    fit = fit_apparent(basis, 2.0 * K, FOAM)
    assert fit.converged and fit.rms_log < 1e-8
    for k in ("E_t", "E_l", "mu_l"):
        assert abs(fit.constants[k] / (2.0 * getattr(FOAM, k)) - 1.0) < 1e-6, k
    for k in ("nu_t", "nu_tl"):
        assert abs(fit.constants[k] - getattr(FOAM, k)) < 1e-6, k
    assert np.allclose(fit.ratios_start, 2.0, rtol=1e-9)


def test_unreachable_target_reports_its_residual(basis, other_fibres_target):
    fit = fit_apparent(basis, other_fibres_target, FOAM, max_evaluations=6)
    start_rms = float(np.sqrt(np.mean(np.log(fit.ratios_start) ** 2)))
    assert fit.rms_log > 0.05 and fit.max_log >= fit.rms_log  # no TI material on this field fits
    assert fit.rms_log < start_rms  # but the fit did improve on the start
    assert not fit.converged and "evaluations" in fit.message  # stopped short: said so
    assert fit.evaluations <= 6
    TransverseIsotropic.from_mapping(fit.constants)  # still a valid material
    assert 0.0 < fit.pd_margin <= 1.0


def test_bad_inputs_name_the_argument(sheets, basis):
    K = basis.condensed(model_components(FOAM.as_tuple(), "ours"))
    with pytest.raises(ConfigError, match="K_target:"):
        fit_apparent(basis, K[:, :20], FOAM)
    with pytest.raises(ConfigError, match="K_target:"):
        fit_apparent(basis, np.zeros((24, 24)), FOAM)
    with pytest.raises(ConfigError, match="start:"):
        fit_apparent(basis, K, [1.0, 2.0])
    with pytest.raises(ConfigError, match="start:"):
        fit_apparent(basis, K, [1.0, 1.0, 0.3, 5.0, 1.0])  # nu_tl: no positive-definite tensor
    with pytest.raises(ConfigError, match="model:"):
        fit_apparent(basis, K, FOAM, model="sofa")
    with pytest.raises(ConfigError, match="tol:"):
        fit_apparent(basis, K, FOAM, tol=0.0)
    with pytest.raises(ConfigError, match="fibers:"):
        sheet_basis(sheets.sheet, sheets.fibers[:-1], "p1")
    with pytest.raises(ConfigError, match="element"):
        sheet_basis(sheets.sheet, sheets.fibers, "p3")
    with pytest.raises(ConfigError, match="c:"):
        basis.matrix(np.ones(4))
