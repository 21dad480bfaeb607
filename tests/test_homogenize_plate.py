"""Plate (sheet-scale) homogenisation against exact answers: the homogeneous plate, classical
laminate theory, the discretisation's second order, and the bulk limit of a lattice."""

import numpy as np
import pytest

from metasheet.errors import ConfigError, InfeasibleError
from metasheet.homogenize import homogenize_voxels
from metasheet.homogenize.plate import (PLATE_STRAINS, bulk_plate, homogenize_plate, laminate_abd, plane_stress,
                                        plate_percolating)
from metasheet.mechanics.material import Isotropic, TransverseIsotropic


def rel(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(np.asarray(b)).max())


def test_plane_stress_of_isotropic_is_the_textbook_q():
    E, nu = 3.0, 0.3
    Q = plane_stress(Isotropic(E, nu).stiffness())
    exact = E / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    assert rel(Q, exact) < 1e-14


@pytest.mark.parametrize("nz", [2, 5])
def test_homogeneous_plate_without_poisson_is_exact(nz):
    # nu = 0: no fluctuation is needed, the voxels hold the plate's fields exactly
    m = Isotropic(2.0, 0.0)
    r = homogenize_plate(np.ones((2, 3, nz), int), (1.0, 1.5, 2.0), {1: m})
    t = 2.0
    assert rel(r.A, 2.0 * t * np.diag([1, 1, 0.5])) < 1e-10
    assert rel(r.D, 2.0 * t**3 / 12 * np.diag([1, 1, 0.5])) < 1e-10
    assert np.abs(r.B).max() < 1e-10 * np.abs(r.D).max()
    assert r.symmetry_error < 1e-10 and r.removed_fraction == 0.0


def test_homogeneous_plate_membrane_exact_bending_second_order():
    m = Isotropic(2.0, 0.3)
    exact = bulk_plate(m.stiffness(), 2.0)
    errs = {}
    for nz in (4, 8):
        r = homogenize_plate(np.ones((2, 2, nz), int), (1.0, 1.0, 2.0), {1: m})
        assert rel(r.A, exact[:3, :3]) < 1e-10  # w_z piecewise linear: held exactly
        assert np.abs(r.B).max() < 1e-10 * np.abs(r.D).max()
        errs[nz] = r.D - exact[3:, 3:]
        assert np.all(np.linalg.eigvalsh(r.ABD) > 0)
    # D is too stiff by O(hz^2) (the anticlastic w_z ~ z^2 is not trilinear): ratio 4, and
    # Richardson's extrapolation recovers the plate
    big = np.abs(errs[4]) > 1e-9 * np.abs(exact[3:, 3:]).max()
    assert big.sum() >= 4
    ratio = errs[4][big] / errs[8][big]
    assert np.allclose(ratio, 4.0, rtol=1e-3)
    D8 = exact[3:, 3:] + errs[8]
    D4 = exact[3:, 3:] + errs[4]
    assert rel((4 * D8 - D4) / 3, exact[3:, 3:]) < 1e-6
    assert 0 < rel(D8, exact[3:, 3:]) < 0.01


def test_asymmetric_laminate_is_classical_laminate_theory():
    # nu = 0 layers: CLT is the exact 3D answer; 3 voxels of E = 1 under 1 voxel of E = 5
    soft, stiff = Isotropic(1.0, 0.0), Isotropic(5.0, 0.0)
    ph = np.ones((2, 2, 4), int)
    ph[..., 3] = 2
    r = homogenize_plate(ph, (1.0, 1.0, 2.0), {1: soft, 2: stiff})
    clt = laminate_abd([(soft.stiffness(), -1.0, 0.5), (stiff.stiffness(), 0.5, 1.0)])
    assert rel(r.ABD, clt) < 1e-10
    assert np.abs(r.B).max() > 0.1 * np.abs(r.A).max()  # the coupling is there and right


def test_laminate_membrane_with_poisson_mismatch_is_exact():
    a, b = Isotropic(1.0, 0.2), Isotropic(4.0, 0.45)
    ph = np.ones((2, 2, 6), int)
    ph[..., :2] = 2
    r = homogenize_plate(ph, (1.0, 1.0, 3.0), {1: a, 2: b})
    clt = laminate_abd([(b.stiffness(), -1.5, -0.5), (a.stiffness(), -0.5, 1.5)])
    assert rel(r.A, clt[:3, :3]) < 1e-10
    assert rel(r.B, clt[:3, 3:]) < 0.05 and rel(r.D, clt[3:, 3:]) < 0.05  # O(h^2), checked above


def test_transversely_isotropic_membrane_is_its_plane_stress():
    ti = TransverseIsotropic(E_t=1.39, E_l=0.094, nu_t=0.26, nu_tl=0.42, mu_l=0.016)
    r = homogenize_plate(np.ones((3, 2, 3), int), (1.0, 1.0, 1.0), {1: ti})
    assert rel(r.A, plane_stress(ti.stiffness()) * 1.0) < 1e-10


def test_two_sheets_split_by_a_void_layer_add_up():
    # both parts wrap in x and y: kept, each with its own translations pinned
    m = Isotropic(1.0, 0.0)
    ph = np.ones((2, 2, 5), int)
    ph[..., 2] = 0
    r = homogenize_plate(ph, (1.0, 1.0, 5.0), {1: m})
    clt = laminate_abd([(m.stiffness(), -2.5, -0.5), (m.stiffness(), 0.5, 2.5)])
    assert rel(r.ABD, clt) < 1e-10 and r.removed_fraction == 0.0


def test_floating_island_is_removed():
    m = Isotropic(1.0, 0.25)
    ph = np.ones((4, 4, 5), int)
    ph[..., 2:] = 0
    ph[1, 1, 4] = 1  # a voxel floating above the sheet
    keep = plate_percolating(ph > 0)
    assert not keep[1, 1, 4] and keep[..., :2].all()
    r = homogenize_plate(ph, (2.0, 2.0, 2.5), {1: m})
    ref = homogenize_plate(np.where(keep, ph, 0), (2.0, 2.0, 2.5), {1: m})
    assert np.array_equal(r.ABD, ref.ABD)
    assert r.removed_fraction == pytest.approx(1 / 33)


def test_lattice_plate_tends_to_the_bulk_with_more_cells_through_the_thickness():
    # A cubic lattice of square struts (4-voxel cell, 2-voxel struts): the sheet's membrane
    # stiffness per thickness approaches the bulk's plane-stress one as cells stack up,
    # with a deficit that shrinks like 1 / cells (the cut cells at the faces).
    cell = np.zeros((4, 4, 4), bool)
    cell[:2, :2, :] = cell[:2, :, :2] = cell[:, :2, :2] = True
    m = Isotropic(1.0, 0.3)
    bulk = homogenize_voxels(cell.astype(int), (4.0, 4.0, 4.0), {1: m}, localise=False).C
    Q = plane_stress(bulk)
    deficit = []
    for n in (1, 2, 4):
        ph = np.tile(cell, (1, 1, n)).astype(int)
        r = homogenize_plate(ph, (4.0, 4.0, 4.0 * n), {1: m})
        deficit.append(1.0 - r.A[0, 0] / (Q[0, 0] * 4.0 * n))
    assert all(d > 0 for d in deficit)
    assert deficit[0] > deficit[1] > deficit[2]
    assert deficit[1] / deficit[2] == pytest.approx(2.0, rel=0.1)


def test_moduli_and_dict():
    m = Isotropic(2.0, 0.3)
    r = homogenize_plate(np.ones((2, 2, 2), int), (1.0, 1.0, 1.0), {1: m})
    mem = r.moduli()["membrane"]
    assert mem["E_x"] == pytest.approx(2.0, rel=1e-12) and mem["nu_xy"] == pytest.approx(0.3, rel=1e-12)
    assert mem["G_xy"] == pytest.approx(2.0 / 2.6, rel=1e-12)
    d = r.to_dict()
    assert d["strains"] == list(PLATE_STRAINS) and np.asarray(d["D_N_mm"]).shape == (3, 3)


def test_bad_input_is_named():
    m = Isotropic(1.0, 0.3)
    with pytest.raises(ConfigError, match="rtol"):
        homogenize_plate(np.ones((2, 2, 2), int), (1, 1, 1), {1: m}, rtol=0.5)
    with pytest.raises(ConfigError, match="materials"):
        homogenize_plate(np.full((2, 2, 2), 2), (1, 1, 1), {1: m})
    with pytest.raises(ConfigError, match="size"):
        homogenize_plate(np.ones((2, 2, 2), int), (1, -1, 1), {1: m})
    with pytest.raises(ConfigError, match="thickness"):
        bulk_plate(m.stiffness(), 0.0)
    column = np.zeros((3, 3, 3), int)
    column[1, 1, :] = 1  # wraps through the thickness only
    with pytest.raises(InfeasibleError, match="x and y"):
        homogenize_plate(column, (1, 1, 1), {1: m})


def test_equivalent_constants_make_the_plate_membrane():
    # a foam-like orthotropic slab: its membrane moduli as TI constants (l along x) give back A
    from metasheet.homogenize.plate import equivalent_constants
    from metasheet.mechanics.voigt import stiffness_along

    rng = np.random.default_rng(4)
    ph = (rng.random((6, 6, 4)) < 0.75).astype(int)
    ph[:, :, 1] = 1
    r = homogenize_plate(ph, (3.0, 2.0, 1.0), {1: Isotropic(12.0, 0.3)})
    bulk = TransverseIsotropic(E_t=1.39, E_l=0.094, nu_t=0.26, nu_tl=0.42, mu_l=0.016)
    eq = equivalent_constants(r.moduli()["membrane"], bulk)
    C = stiffness_along(eq.stiffness(), np.array([[1.0, 0.0, 0.0]]))[0]
    S = np.linalg.inv(r.A)
    S[[0, 1, 2, 2], [2, 2, 0, 1]] = 0.0  # the cell's in-plane shear coupling is dropped
    assert abs(np.linalg.inv(r.A)[0, 2]) > 1e-4 * S[0, 0]  # there was one to drop
    assert rel(plane_stress(C) * r.thickness, np.linalg.inv(S)) < 1e-10
    assert eq.nu_t == bulk.nu_t
    with pytest.raises(ConfigError, match="moduli"):
        equivalent_constants({"E_x": 1.0}, bulk)
    with pytest.raises(ConfigError, match="positive-definite"):
        equivalent_constants({"E_x": 1.0, "E_y": 1.0, "G_xy": 1.0, "nu_xy": 1.2}, bulk)


def test_equivalent_constants_move_nu_t_only_when_they_must():
    from metasheet.homogenize.plate import equivalent_constants

    bulk = TransverseIsotropic(E_t=1.39, E_l=0.094, nu_t=0.26, nu_tl=0.42, mu_l=0.016)
    kept = equivalent_constants({"E_x": 0.05, "E_y": 1.0, "G_xy": 0.01, "nu_xy": 0.02}, bulk)
    assert kept.nu_t == bulk.nu_t and kept.nu_tl == pytest.approx(0.4)
    # soft along x, stiff along y: nu_tl = 0.2 * 20 = 4, nu_tl nu_lt = 0.8: nu_t must be in (-1, -0.6)
    moved = equivalent_constants({"E_x": 0.05, "E_y": 1.0, "G_xy": 0.01, "nu_xy": 0.2}, bulk)
    assert moved.nu_t == pytest.approx(-0.8) and moved.E_l == 0.05 and moved.mu_l == 0.01
    assert np.all(np.linalg.eigvalsh(moved.stiffness()) > 0)
