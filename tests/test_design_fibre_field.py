"""The designable fibre field (metasheet.sheet.fibre_field) and the turned tensor
(metasheet.design.tensor): no robot, milliseconds each."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.sheet.fibre_field import (
    FibreField,
    PolarBSpline,
    check_coefficients,
    fibres_at,
    open_bspline,
    periodic_bspline,
    rotate_points,
)
from metasheet.design.tensor import inplane_mandel, to_voigt
from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic
from metasheet.sheet.fibers import spiral_fibers
from metasheet.mechanics.voigt import stiffness_along

THIRD = 2.0 * np.pi / 3.0


def _annulus(n=400, seed=0):
    rng = np.random.default_rng(seed)
    r, t = rng.uniform(6.0, 69.0, n), rng.uniform(-np.pi, np.pi, n)
    return np.stack([r * np.cos(t), r * np.sin(t), rng.uniform(-2.5, 2.5, n)], axis=1)


def test_bases_are_partitions_of_unity():
    x = np.linspace(-5.0, 75.0, 301)
    for deg in (1, 2, 3):
        assert np.allclose(open_bspline(x, 0.0, 70.0, 5, deg).sum(axis=1), 1.0, atol=1e-14)
        assert np.allclose(periodic_bspline(np.linspace(-7, 7, 301), 9, deg).sum(axis=1), 1.0, atol=1e-14)
    B = open_bspline(np.array([0.0, 70.0]), 0.0, 70.0, 5, 3)  # clamped: the ends interpolate
    assert B[0, 0] == 1.0 and abs(B[1, -1] - 1.0) < 1e-9


def test_rotation_shifts_the_angular_basis_by_a_third():
    b = PolarBSpline(n_radial=4, n_angular=12, degree=3, r_max=70.0)
    p = _annulus()
    N = b.full_matrix(p).reshape(len(p), 4, 12)
    Nr = b.full_matrix(rotate_points(p, THIRD)).reshape(len(p), 4, 12)
    assert np.abs(Nr - np.roll(N, 4, axis=2)).max() < 1e-12


def test_symmetric_field_is_invariant_under_the_sheets_rotation():
    b = PolarBSpline(n_radial=4, n_angular=12, r_max=70.0, symmetric=True)
    assert b.n_coefficients == 16 and b.tie_matrix().sum(axis=0).tolist() == [3.0] * 16
    p = _annulus()
    c = np.random.default_rng(1).uniform(-1, 1, 16)
    d0 = b.design_matrix(p) @ c
    for k in (1, 2):
        assert np.abs(b.design_matrix(rotate_points(p, k * THIRD)) @ c - d0).max() < 1e-12
    assert np.array_equal(b.design_matrix(p), b.full_matrix(p) @ b.tie_matrix())


def test_field_starts_from_the_spiral_and_keeps_the_mirror():
    p = _annulus(50)
    fa = spiral_fibers(p, pitch_deg=30.0)
    field = FibreField.from_fibres(p, fa, PolarBSpline(r_max=70.0))
    a, b = field.fibres(np.zeros(field.n_coefficients))
    assert np.abs(a - fa).max() < 1e-14
    pm = p * np.array([1.0, -1.0, 1.0])  # the mirrored sheet's element i is the image of A's element i
    assert np.abs(b - spiral_fibers(pm, pitch_deg=30.0, mirrored=True)).max() < 1e-14
    c = np.full(field.n_coefficients, 0.1)  # a constant increment: every fibre turns by 0.1 rad
    assert np.allclose(field.angles(c) - field.theta0, 0.1, atol=1e-14)


def test_bad_input_names_the_field():
    field = FibreField.from_fibres(_annulus(20), spiral_fibers(_annulus(20)), PolarBSpline(r_max=70.0))
    with pytest.raises(ConfigError, match=r"^c: shape is \(47,\) and should be \(48,\)"):
        field.angles(np.zeros(47))
    bad = np.zeros(48)
    bad[5] = np.nan
    with pytest.raises(ConfigError, match=r"^c\[5\]: nan"):
        field.angles(bad)
    bad[5] = np.inf
    with pytest.raises(ConfigError, match=r"^c\[5\]: inf"):
        field.fibres(bad)
    with pytest.raises(ConfigError, match=r"^c: "):
        check_coefficients(["a"] * 48, 48)
    with pytest.raises(ConfigError, match="^n_angular: 10: must be a multiple of 3"):
        PolarBSpline(n_angular=10, symmetric=True)
    with pytest.raises(ConfigError, match=r"^n_radial: 3: allowed range is \[4, 32\]"):
        PolarBSpline(n_radial=3)
    with pytest.raises(ConfigError, match="^r_max"):
        PolarBSpline(r_max=float("nan"))
    with pytest.raises(ConfigError, match=r"^fibres\[0\]: .*out of the sheet plane"):
        FibreField.from_fibres(_annulus(5), spiral_fibers(_annulus(5), tilt_deg=5.0), PolarBSpline())


def test_turned_tensor_and_its_exact_angle_derivative():
    th = np.random.default_rng(2).uniform(-np.pi, np.pi, 32)
    C0 = paper.PAPER_FOAM.stiffness()
    C, dC = inplane_mandel(C0, th)
    assert np.abs(to_voigt(C) - stiffness_along(C0, fibres_at(th))).max() < 1e-14 * np.abs(C0).max()
    h = 1e-5
    fd = (inplane_mandel(C0, th + h)[0] - inplane_mandel(C0, th - h)[0]) / (2 * h)
    assert np.abs(fd - dC).max() < 1e-8 * np.abs(dC).max()
    assert np.array_equal(dC, np.transpose(dC, (0, 2, 1)))
    _, dCi = inplane_mandel(Isotropic(1.39, 0.26).stiffness(), th)  # fibres do not matter
    assert np.abs(dCi).max() < 1e-14
