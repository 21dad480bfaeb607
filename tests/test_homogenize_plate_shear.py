"""The plate cell's transverse-shear stiffness against exact answers: Reissner's 5/6 G t of a
homogeneous sheet (isotropic, with and without Poisson; transversely isotropic), Whitney's
equilibrium shear of an asymmetric laminate, both at second order in the voxel height; the bulk
limit of a lattice; and the symmetries a periodic cell's H must keep."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.homogenize import homogenize_voxels
from metasheet.homogenize.corrector import material_stiffness
from metasheet.homogenize.plate import homogenize_plate
from metasheet.homogenize.plate_shear import bulk_shear, shear_gradients
from metasheet.homogenize.plate_slabs import slab_study
from metasheet.mechanics.material import Isotropic, TransverseIsotropic


def second_order(values: dict, exact: float) -> tuple[float, float]:
    """(error ratio between the two coarsest, Richardson's limit of the two finest)."""
    n = sorted(values)
    e = [values[k] - exact for k in n]
    return e[0] / e[1], (4 * values[n[-1]] - values[n[-2]]) / 3


@pytest.mark.parametrize("nu", [0.0, 0.3])
def test_homogeneous_sheet_is_reissner(nu):
    m = Isotropic(2.0, nu)
    exact = bulk_shear(m.stiffness(), 2.0)
    assert exact[0, 0] == pytest.approx(5 / 6 * 2.0 * 2.0 / (2 * (1 + nu)))
    H = {}
    for nz in (4, 8, 16):
        r = homogenize_plate(np.ones((2, 3, nz), int), (1.0, 1.5, 2.0), {1: m}, shear=True)
        assert abs(r.shear.H[0, 1]) < 1e-12 and r.shear.H[0, 0] == pytest.approx(r.shear.H[1, 1], rel=1e-12)
        assert np.all(np.abs(r.shear.kirchhoff_share) < 1e-10) and r.shear.balance_error < 1e-12
        assert r.shear.normalisation_spread < 1e-10
        H[nz] = r.shear.H[0, 0]
    ratio, limit = second_order(H, exact[0, 0])
    assert H[4] > H[8] > H[16] > exact[0, 0]  # the voxels' linear shear strain through a layer is too stiff
    assert 3.8 < ratio < 4.2
    assert limit == pytest.approx(exact[0, 0], rel=2e-4)
    assert H[16] == pytest.approx(exact[0, 0], rel=0.006)


def test_transversely_isotropic_sheet_is_reissner_with_its_own_g():
    ti = TransverseIsotropic(E_t=2.0, E_l=5.0, nu_t=0.3, nu_tl=0.2, mu_l=0.7)
    exact = bulk_shear(material_stiffness(1, ti), 1.0)
    H = {nz: homogenize_plate(np.ones((3, 2, nz), int), (1.0, 1.0, 1.0), {1: ti}, shear=True).shear.H
         for nz in (4, 8, 16)}
    ratio, limit = second_order({k: v[0, 0] for k, v in H.items()}, exact[0, 0])
    assert 3.8 < ratio < 4.2 and limit == pytest.approx(exact[0, 0], rel=2e-4)
    assert H[16][1, 1] == pytest.approx(exact[1, 1], rel=0.005)


def whitney(E: np.ndarray, z: np.ndarray) -> float:
    """Transverse-shear stiffness [N/mm] of a nu = 0 laminate, E (n,) on the fine grid z (n,)
    [mm], in cylindrical bending: the shear stress from equilibrium through the thickness,
    ``tau(z) = -int_bottom^z E (eps' + zeta kappa') dzeta``, its complementary energy over Q^2."""
    trap = lambda f: np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(z))])
    A, B, D = trap(E)[-1], trap(E * z)[-1], trap(E * z * z)[-1]
    tau = -trap(E * (-B / A + z))  # kappa' = 1, eps' keeps N constant
    assert abs(tau[-1]) < 1e-9 * np.abs(tau).max()  # the top face is free
    Q = D - B * B / A
    return Q**2 / trap(tau**2 / (E / 2.0))[-1]


def test_asymmetric_laminate_is_whitney():
    # 3/4 of E = 1 under 1/4 of E = 5, nu = 0: the membrane gradient -A^-1 B keeps N constant
    z = np.linspace(-1.0, 1.0, 400001)
    exact = whitney(np.where(z < 0.5, 1.0, 5.0), z)
    H = {}
    for nz in (4, 8, 16):
        ph = np.ones((2, 2, nz), int)
        ph[:, :, 3 * nz // 4:] = 2
        r = homogenize_plate(ph, (1.0, 1.0, 2.0), {1: Isotropic(1.0, 0.0), 2: Isotropic(5.0, 0.0)}, shear=True)
        assert abs(r.B[0, 0]) > 0.1 * r.A[0, 0]  # the laminate couples
        assert r.shear.normalisation_spread < 1e-9
        H[nz] = r.shear.H[0, 0]
    ratio, limit = second_order(H, exact)
    assert 3.8 < ratio < 4.2 and limit == pytest.approx(exact, rel=2e-4)
    assert exact == pytest.approx(1.0009, abs=1e-4)  # not 5/6 G t of either layer


def test_lattice_sheet_tends_to_the_bulk_shear():
    # the cubic strut lattice of tests/test_homogenize_plate.py: H per 5/6 G t of the bulk
    cell = np.zeros((4, 4, 4), bool)
    cell[:2, :2, :] = cell[:2, :, :2] = cell[:, :2, :2] = True
    m = Isotropic(1.0, 0.3)
    bulk = homogenize_voxels(cell.astype(int), (4.0, 4.0, 4.0), {1: m}, localise=False).C
    ratio = []
    for n in (2, 4, 8):
        r = homogenize_plate(np.tile(cell, (1, 1, n)).astype(int), (4.0, 4.0, 4.0 * n), {1: m}, shear=True)
        ratio.append(r.shear.H[0, 0] / bulk_shear(bulk, 4.0 * n)[0, 0])
        assert r.shear.H[1, 1] == pytest.approx(r.shear.H[0, 0], rel=1e-9)  # the lattice's cubic symmetry
        assert r.shear.balance_error < 1e-12
    deficit = 1.0 - np.array(ratio)
    assert np.all(deficit > 0) and deficit[0] > 2 * deficit[1] > 4 * deficit[2]
    assert ratio[-1] == pytest.approx(1.0, abs=0.03)


def test_periodic_cell_symmetries():
    # H is a property of the periodic sheet: where the cell is cut does not change it; swapping
    # x and y swaps it; mirroring x flips the sign of the xz-yz coupling
    rng = np.random.default_rng(3)
    ph = (rng.random((6, 5, 4)) < 0.7).astype(int)
    ph[:, :, 1] = 1
    mats = {1: Isotropic(12.0, 0.3)}
    H = homogenize_plate(ph, (3.0, 2.5, 1.0), mats, shear=True).shear.H
    assert abs(H[0, 1]) > 1e-3 * H[0, 0] and np.all(np.linalg.eigvalsh(H) > 0)
    r = homogenize_plate(ph, (3.0, 2.5, 1.0), mats, shear=True).shear
    assert 0 < r.normalisation_spread < 0.05 and np.all(r.kirchhoff_share > 0)
    rolled = homogenize_plate(np.roll(ph, (2, 3), axis=(0, 1)), (3.0, 2.5, 1.0), mats, shear=True).shear.H
    swapped = homogenize_plate(ph.transpose(1, 0, 2), (2.5, 3.0, 1.0), mats, shear=True).shear.H
    mirrored = homogenize_plate(ph[::-1], (3.0, 2.5, 1.0), mats, shear=True).shear.H
    assert np.abs(rolled - H).max() < 1e-10 * H.max()
    assert np.abs(swapped[::-1, ::-1] - H).max() < 1e-10 * H.max()
    assert np.abs(mirrored - H * np.array([[1, -1], [-1, 1]])).max() < 1e-10 * H.max()


def test_shear_gradients_keep_n_constant_and_give_q():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(6, 6))
    ABD = X @ X.T + 6 * np.eye(6)
    g, Q = shear_gradients(ABD)
    NM = g @ ABD  # (2, 6): each case's gradient of (N, M)
    assert np.abs(NM[:, :3]).max() < 1e-12
    assert np.allclose(Q, [[NM[0, 3], NM[1, 5]], [NM[0, 5], NM[1, 4]]], rtol=1e-14)


def test_slab_study_reports_shear():
    m = Isotropic(2.0, 0.3)
    ph = np.ones((2, 2, 8), int)
    study = slab_study(ph, (1.0, 1.0, 4.0), {1: m}, 2.0, m.stiffness(), slabs=2, shear=True)
    d = study.to_dict()["shear"]
    assert d["strains"] == ["gamma_xz", "gamma_yz"] and max(d["kirchhoff_share_max"]) < 1e-10
    assert 1.0 < d["ratio_to_bulk"]["H_xz"]["mean"] < 1.06  # 4 layers: O(h^2) too stiff (5.4 %)
    assert "shear" not in slab_study(ph, (1.0, 1.0, 4.0), {1: m}, 2.0, m.stiffness(), slabs=2).to_dict()
    with pytest.raises(ConfigError, match="thickness"):
        bulk_shear(m.stiffness(), -1.0)
