"""Voxel homogenisation against exact answers: solid, laminate (Backus), bounds, lattice."""


import numpy as np
import pytest

from metasheet.errors import ConfigError, InfeasibleError
from metasheet.fem.hex8 import hex8_box_matrices
from metasheet.homogenize import homogenize_voxels
from metasheet.mechanics.material import Isotropic, TransverseIsotropic

from homogenize_bounds import (
    backus_laminate, hashin_shtrikman_upper, hydrostatic_modulus, voigt_bound,
)
from homogenize_samples import cubic_lattice, edge_foam, laminate

TPU = Isotropic(12.0, 0.3)
SOFT = Isotropic(1.5, 0.45)
TI = TransverseIsotropic(E_t=10.0, E_l=3.0, nu_t=0.3, nu_tl=0.25, mu_l=1.2)


def test_hex8_matches_scikit_fem():
    """The hand-written box element equals scikit-fem's ElementHex1 elasticity matrix."""
    skfem = pytest.importorskip("skfem")
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    h = np.array([0.7, 1.1, 0.4])
    m = skfem.MeshHex().scaled(h)
    basis = skfem.Basis(m, skfem.ElementVector(skfem.ElementHex1()), intorder=3)
    K_ref = skfem.asm(linear_elasticity(*lame_parameters(TPU.E, TPU.nu)), basis).toarray()
    K, F, _ = hex8_box_matrices(TPU.stiffness(), h)
    # map our local node a (offsets in {0,1}^3) to scikit-fem's node by coordinates
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)]) * h
    node = [int(np.argmin(np.linalg.norm(m.p.T - c, axis=1))) for c in corners]
    dofs = np.array([basis.nodal_dofs[:, n] for n in node]).ravel()
    np.testing.assert_allclose(K, K_ref[np.ix_(dofs, dofs)], rtol=0, atol=1e-12 * np.abs(K).max())
    # rigid translations give no force; a uniform strain's nodal forces are F
    assert np.abs(K @ np.tile(np.eye(3), 8).T).max() < 1e-12 * np.abs(K).max()
    x = corners
    for I in range(6):
        E = np.zeros(6); E[I] = 1.0
        Et = np.array([[E[0], E[5] / 2, E[4] / 2], [E[5] / 2, E[1], E[3] / 2], [E[4] / 2, E[3] / 2, E[2]]])
        u = (x @ Et.T).ravel()
        np.testing.assert_allclose(K @ u, F[:, I] - F[:, I].mean() * 0, atol=1e-12 * np.abs(F).max())


def _slow(*values, id):
    return pytest.param(*values, marks=pytest.mark.slow, id=id)


# each solver and each material once by default; the two other pairings are slow
@pytest.mark.parametrize("material, solver", [
    pytest.param(TPU, "direct", id="iso-direct"), pytest.param(TI, "amg", id="ti-amg"),
    _slow(TPU, "amg", id="iso-amg"), _slow(TI, "direct", id="ti-direct"),
])
def test_solid_cell_returns_base_material(solver, material):
    """Default-selection siblings of the slow cases: test_solid_cell_returns_base_material[iso-direct]
    and [ti-amg] (each solver and each material once)."""
    ph = np.ones((5, 4, 6), np.int64)
    r = homogenize_voxels(ph, (1.0, 2.0, 0.5), {1: material}, solver=solver)
    C0 = material.stiffness()
    assert np.abs(r.C - C0).max() <= 1e-10 * np.abs(C0).max()
    assert r.relative_density == 1.0 and r.removed_fraction == 0.0
    np.testing.assert_allclose(r.localisation.ratio_max, 1.0, atol=1e-10)


@pytest.mark.parametrize("mats, solver", [
    pytest.param((TPU, SOFT), "amg", id="iso-iso-amg"), pytest.param((TI, SOFT), "direct", id="ti-iso-direct"),
    _slow((TPU, SOFT), "direct", id="iso-iso-direct"), _slow((TI, SOFT), "amg", id="ti-iso-amg"),
])
def test_laminate_equals_backus(solver, mats):
    """Default-selection siblings of the slow cases: test_laminate_equals_backus[iso-iso-amg] and
    [ti-iso-direct] (each solver and each pair of materials once)."""
    ph = laminate(8, 0.375, axis=2)
    size = (1.0, 1.0, 2.0)
    r = homogenize_voxels(ph, size, {1: mats[0], 2: mats[1]}, solver=solver, rtol=1e-10)
    C_ex = backus_laminate([m.stiffness() for m in mats], [0.375, 0.625])
    assert np.abs(r.C - C_ex).max() <= 1e-6 * np.abs(C_ex).max()
    # both the fit and its constants are exact: a laminate is transversely isotropic about z
    assert r.fit.misfit < 1e-8 and abs(abs(r.fit.axis[2]) - 1) < 1e-8
    # the mean local strain is the macro strain (the fluctuation is periodic)
    np.testing.assert_allclose(r.localisation.strain.mean(axis=0), np.eye(6), atol=1e-8)


def test_laminate_along_x_is_the_rotated_backus():
    ph = laminate(6, 0.5, axis=0)
    r = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU, 2: SOFT}, solver="direct")
    C_ex = backus_laminate([TPU.stiffness(), SOFT.stiffness()], [0.5, 0.5])
    perm = [2, 1, 0, 5, 4, 3]  # swap axes 1 and 3: Voigt 11<->33, 23<->12
    assert np.abs(r.C - C_ex[np.ix_(perm, perm)]).max() <= 1e-6 * np.abs(C_ex).max()


@pytest.mark.parametrize("density,seed", [(0.15, 0), _slow(0.3, 1, id="0.3-1")])
def test_porous_cells_respect_voigt_and_hashin_shtrikman(density, seed):
    """Default-selection sibling of the slow 0.3 case:
    test_porous_cells_respect_voigt_and_hashin_shtrikman[0.15-0]."""
    ph = edge_foam(14, density, seeds=6, rng_seed=seed)
    r = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU})
    f = r.relative_density
    CV = voigt_bound([TPU.stiffness()], [f])
    assert np.linalg.eigvalsh(CV - r.C).min() > -1e-9 * np.abs(CV).max()
    k_hs, _ = hashin_shtrikman_upper(TPU, f)
    assert 0 < hydrostatic_modulus(r.C) < k_hs
    # open-cell foams are far below the bound (bending): Gibson-Ashby order of magnitude
    assert 0.1 * f**2 < r.fit.material.E_t / TPU.E < 3 * f**2 + f**3


def test_cubic_lattice_symmetry_and_stretch_estimate():
    n, w = 16, 2
    L = 2.0
    r = homogenize_voxels(cubic_lattice(n, w), (L, L, L), {1: TPU})
    C = r.C
    scale = np.abs(C).max()
    for a, b in [((0, 0), (1, 1)), ((0, 0), (2, 2)), ((0, 1), (0, 2)), ((0, 1), (1, 2)),
                 ((3, 3), (4, 4)), ((3, 3), (5, 5))]:
        assert abs(C[a] - C[b]) < 1e-8 * scale
    assert np.abs(C[:3, 3:]).max() < 1e-8 * scale
    E_axis = 1.0 / np.linalg.inv(C)[0, 0]
    A = (w * L / n) ** 2
    E_est = TPU.E * A / L**2  # one strut of area A per cell face of area L^2
    # bracket: the bare estimate below; the same strut with a rigid node block (free
    # length L - w h) above, since the crossing struts stiffen the junction
    assert E_est < E_axis < E_est * n / (n - w)
    assert E_axis == pytest.approx(E_est, rel=0.15)
    assert r.symmetry_error < 1e-6


def test_solvers_agree_on_a_foam():
    ph = edge_foam(12, 0.2, seeds=5, rng_seed=3)
    a = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct")
    b = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="amg", rtol=1e-9)
    assert a.solver in ("superlu", "pardiso", "cholmod") and b.solver == "amg-cg"
    assert np.abs(a.C - b.C).max() < 1e-9 * np.abs(a.C).max()
    assert all(lc.iterations > 0 and lc.residual < 1e-8 for lc in b.load_cases)


def test_islands_are_removed_and_void_layers_refused():
    ph = cubic_lattice(10, 4)
    base = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct")
    with_island = ph.copy()
    with_island[1, 1, 1] = 1  # a floating voxel, far from every strut
    r = homogenize_voxels(with_island, (1.0, 1.0, 1.0), {1: TPU}, solver="direct")
    assert r.removed_fraction > 0
    assert np.abs(r.C - base.C).max() < 1e-10 * np.abs(base.C).max()
    layer = np.ones((6, 6, 6), np.int64)
    layer[:, :, 2] = 0
    with pytest.raises(InfeasibleError, match="percolate.*z"):
        homogenize_voxels(layer, (1.0, 1.0, 1.0), {1: TPU})


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(phases=np.ones((4, 4)), size=(1, 1, 1), materials={1: TPU}), "phases"),
        (dict(phases=np.ones((4, 4, 4), int), size=(1, 0, 1), materials={1: TPU}), "size"),
        (dict(phases=np.full((4, 4, 4), 2), size=(1, 1, 1), materials={1: TPU}), "materials"),
        (dict(phases=np.ones((4, 4, 4), int), size=(1, 1, 1), materials={1: TPU}, solver="lu"), "solver"),
        (dict(phases=np.ones((4, 4, 4), int), size=(1, 1, 1), materials={1: 12.0}), "materials"),
    ],
)
def test_bad_input_names_the_field(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        homogenize_voxels(**kwargs)


def test_all_void_is_refused():
    with pytest.raises(InfeasibleError, match="no solid"):
        homogenize_voxels(np.zeros((4, 4, 4), int), (1, 1, 1), {1: TPU})
