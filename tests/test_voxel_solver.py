"""Matrix-free multigrid homogenisation (metasheet.fem.voxel) against independent answers.

The assembled path (:func:`metasheet.homogenize.homogenize_voxels`, direct solve) on the same
voxels; the exact laminate (Voigt in the layers' plane, Reuss across them, and Backus' full
tensor); the solid cube (C* = C); symmetry; bounded multigrid iteration counts under
refinement; the same bits on a second run.
"""

import functools

import numpy as np
import pytest
from homogenize_bounds import backus_laminate
from homogenize_samples import cubic_lattice, edge_foam, laminate

from metasheet.errors import ConfigError
from metasheet.fem import solvers
from metasheet.homogenize.voxel_correctors import solve_voxel_correctors
from metasheet.homogenize.voxel_periodic import periodic_stiffness
from metasheet.homogenize import homogenize_voxels
from metasheet.homogenize.percolation import percolating_solid
from metasheet.mechanics.material import Isotropic, TransverseIsotropic

TPU = Isotropic(12.0, 0.3)
SOFT = Isotropic(1.5, 0.45)
FIBRE = TransverseIsotropic(E_t=8.0, E_l=20.0, nu_t=0.35, nu_tl=0.3, mu_l=4.0)


def _rel(A, B) -> float:
    return float(np.linalg.norm(A - B) / np.linalg.norm(B))


def _percolating(ph: np.ndarray) -> np.ndarray:
    keep, _ = percolating_solid(ph > 0)
    return np.where(keep, ph, 0)


@pytest.mark.parametrize("n, density, seeds, rng_seed", [
    (8, 0.3, 4, 0),  # the default selection's case; the larger foams are slow
    pytest.param(12, 0.25, 6, 0, marks=pytest.mark.slow),
    pytest.param(14, 0.3, 5, 1, marks=pytest.mark.slow),
    pytest.param(16, 0.2, 8, 2, marks=pytest.mark.slow),
])
def test_matches_assembled_path_on_random_foams(n, density, seeds, rng_seed):
    """Slow cases' default-selection sibling: the (8, 0.3, 4, 0) case of this test."""
    ph = _percolating(edge_foam(n, density, seeds=seeds, rng_seed=rng_seed))
    ref = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct", rtol=1e-10, localise=False)
    r = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, rtol=1e-10)
    assert _rel(r.C, ref.C) < 1e-8
    assert max(r.residuals) <= 1e-9
    assert r.n_dof == ref.n_dof + 3  # one node pinned there (one part), translations projected here


@pytest.mark.parametrize("n, seeds", [(8, 3), pytest.param(12, 5, marks=pytest.mark.slow)])
def test_two_phases_anisotropic_material_and_elongated_voxels(n, seeds):
    """A TI phase and an isotropic one in a foam of 3:1 voxels (semi-coarsening) match too.
    The slow 12^3 case's default-selection sibling: the 8^3 case."""
    ph = _percolating(edge_foam(n, 0.35, seeds=seeds, rng_seed=3))
    ph[(ph == 1) & (np.indices(ph.shape)[0] % 3 == 0)] = 2
    size = (1.0, 1.0, 3.0)
    ref = homogenize_voxels(ph, size, {1: FIBRE, 2: SOFT}, solver="direct", rtol=1e-10, localise=False)
    r = periodic_stiffness(ph, size, {1: FIBRE.stiffness(), 2: SOFT.stiffness()}, rtol=1e-10)
    assert _rel(r.C, ref.C) < 1e-8


def test_solid_cube_is_the_material():
    for m in (TPU, FIBRE):
        r = periodic_stiffness(np.ones((6, 6, 6), np.int64), (2.0, 2.0, 2.0), {1: m.stiffness()})
        np.testing.assert_allclose(r.C, m.stiffness(), rtol=0, atol=1e-12 * np.abs(m.stiffness()).max())
        assert max(r.iterations) <= 1  # a uniform solid has no fluctuation: f = 0 up to rounding


@pytest.mark.parametrize("axis", [0, 2])
def test_exact_laminate(axis):
    """Layers normal to ``axis``: Reuss across (normal stiffness, transverse shear), Voigt along
    (in-plane shear), and the whole tensor equal to Backus' exact laminate."""
    ph = laminate(8, 0.25, axis=axis)
    r = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness(), 2: SOFT.stiffness()}, rtol=1e-10)
    f = np.array([0.25, 0.75])
    M = np.array([m.lam + 2 * m.mu for m in (TPU, SOFT)])  # P-wave modulus [MPa]
    mu = np.array([TPU.mu, SOFT.mu])
    shear = {0: (5, 4, 3), 2: (3, 4, 5)}[axis]  # (across, across, in-plane) Voigt shear indices
    assert r.C[axis, axis] == pytest.approx(1.0 / np.sum(f / M), rel=1e-10)
    assert r.C[shear[0], shear[0]] == pytest.approx(1.0 / np.sum(f / mu), rel=1e-10)
    assert r.C[shear[2], shear[2]] == pytest.approx(np.sum(f * mu), rel=1e-10)
    if axis == 2:
        exact = backus_laminate([TPU.stiffness(), SOFT.stiffness()], f)
        np.testing.assert_allclose(r.C, exact, rtol=0, atol=1e-10 * np.abs(exact).max())


@pytest.mark.parametrize("n, seeds", [(10, 4), pytest.param(12, 6, marks=pytest.mark.slow)])
def test_symmetric_and_positive(n, seeds):
    """The slow 12^3 case's default-selection sibling: the 10^3 case."""
    ph = _percolating(edge_foam(n, 0.25, seeds=seeds))
    r = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, rtol=1e-8)
    assert np.array_equal(r.C, r.C.T)
    assert np.linalg.norm(r.C_raw - r.C_raw.T) / np.linalg.norm(r.C_raw) < 1e-6
    assert np.linalg.eigvalsh(r.C)[0] > 0


def test_modulus_scale_is_linear():
    ph = _percolating(edge_foam(10, 0.3, seeds=4))
    one = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, rtol=1e-10)
    two = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, scale=np.full(ph.shape, 2.0), rtol=1e-10)
    assert _rel(two.C, 2.0 * one.C) < 1e-9


@functools.cache
def _lattice_assembled(tiles: int) -> np.ndarray:
    """The assembled path's C* of the lattice below: one direct solve serves both coarsenings."""
    ph = np.tile(cubic_lattice(7, 1), (tiles,) * 3)
    return homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct", rtol=1e-10, localise=False).C


@pytest.mark.parametrize("tiles, coarsening, levels, most", [
    (2, "trilinear", 2, 30),  # 8 cells (measured: two levels, 19 iterations, both coarsenings)
    (2, "split", 2, 30),
    pytest.param(3, "trilinear", 3, 80, marks=pytest.mark.slow),
    pytest.param(3, "split", 2, 40, marks=pytest.mark.slow),
])
def test_thin_struts_one_voxel_wide(tiles, coarsening, levels, most):
    """27 cells of a cubic lattice with 1-voxel struts (the thinnest wall a grid has) converge
    (measured at rtol 1e-10: trilinear 52-60 iterations, three levels; split 27, two levels)
    and match the assembled path. The slow 27-cell cases' default-selection siblings: the
    8-cell (tiles = 2) cases of this test."""
    ph = np.tile(cubic_lattice(7, 1), (tiles,) * 3)
    r = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, rtol=1e-10, coarsening=coarsening)
    assert len(r.levels) >= levels
    assert _rel(r.C, _lattice_assembled(tiles)) < 1e-8
    assert max(r.iterations) <= most


@pytest.mark.parametrize("coarse, seeds", [(10, 4), pytest.param(12, 6, marks=pytest.mark.slow)])
def test_iterations_bounded_under_refinement(coarse, seeds):
    """The same foam at 12^3 and 24^3 voxels: multigrid keeps CG's iterations flat (measured
    23 and 22 at rtol 1e-8). The slow 12/24 case's default-selection sibling: 10^3 and 20^3 (measured 17 and 15)."""
    its = []
    for n in (coarse, 2 * coarse):
        ph = _percolating(edge_foam(n, 0.25, seeds=seeds))
        r = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, rtol=1e-8)
        its.append(max(r.iterations))
    assert max(its) <= 40
    assert its[1] <= 1.3 * its[0] + 2


def test_same_bits_twice():
    ph = _percolating(edge_foam(10, 0.3, seeds=4))
    a = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()})
    b = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()})
    assert np.array_equal(a.C, b.C) and np.array_equal(a.U, b.U)


def test_solver_layer_names_voxel():
    ph = _percolating(edge_foam(10, 0.3, seeds=4))
    _C, _C_raw, U, report = solve_voxel_correctors(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()})
    assert report.solver == "voxel" and len(report.iterations) == 6 and U.shape == (3 * ph.size, 6)
    assert "voxel" in solvers.HOMOGENIZE_SOLVERS and "voxel" not in solvers.SPD_SOLVERS
    with pytest.raises(ConfigError, match="solver: 'voxel': matrix-free"):
        solvers.choose_solver("voxel", 100)
    with pytest.raises(ConfigError, match="solver: 'amg': allowed values are voxel"):
        solve_voxel_correctors(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()}, solver="amg")


@pytest.mark.parametrize("kwargs, match", [
    ({"phases": np.ones((4, 4))}, r"phases: shape is \(4, 4\)"),
    ({"phases": np.ones((4, 4, 4))}, "phases: dtype float64"),
    ({"phases": -np.ones((4, 4, 4), int)}, "phases: -1"),
    ({"phases": np.zeros((4, 4, 4), int)}, "phases: no solid voxel"),
    ({"phases": 2 * np.ones((4, 4, 4), int)}, r"stiffnesses: phases \[2\]"),
    ({"size": (1.0, -1.0, 1.0)}, "size:"),
    ({"rtol": 0.1}, "rtol: 0.1: allowed range"),
    ({"scale": np.ones((3, 3, 3))}, r"scale: shape is \(3, 3, 3\)"),
    ({"stiffnesses": {1: -np.eye(6)}}, r"stiffnesses\[0\]: not positive definite"),
    ({"smoother": "gauss-seidel"}, "smoother: 'gauss-seidel': allowed values are chebyshev, jacobi"),
])
def test_bad_input_names_the_field(kwargs, match):
    args = {"phases": np.ones((4, 4, 4), int), "size": (1.0, 1.0, 1.0), "stiffnesses": {1: TPU.stiffness()}}
    args.update(kwargs)
    with pytest.raises(ConfigError, match=match):
        periodic_stiffness(args.pop("phases"), args.pop("size"), args.pop("stiffnesses"), **args)
