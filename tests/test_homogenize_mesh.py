"""Tet route (explicit periodic projection P) against exact answers and the voxel route."""

import numpy as np
import pytest

from metasheet.errors import ConfigError, InfeasibleError, MeshError
from metasheet.homogenize import homogenize_mesh, homogenize_voxels, voxels_to_tets
from metasheet.homogenize.periodic import periodic_masters, projection
from metasheet.mechanics.material import Isotropic, TransverseIsotropic

from homogenize_bounds import backus_laminate
from homogenize_samples import cubic_lattice, edge_foam, laminate

TPU = Isotropic(12.0, 0.3)
SOFT = Isotropic(1.5, 0.45)
TI = TransverseIsotropic(E_t=10.0, E_l=3.0, nu_t=0.3, nu_tl=0.25, mu_l=1.2)


def test_projection_identifies_opposite_faces():
    pts, tets, _ = voxels_to_tets(np.ones((3, 3, 3), int), (3.0, 3.0, 3.0))
    master, shift, m = periodic_masters(pts, (3.0, 3.0, 3.0))
    assert m == 27 and len(pts) == 64  # 4^3 grid nodes -> 3^3 independent ones
    corners = np.flatnonzero(np.all((pts == 0) | (pts == 3.0), axis=1))
    assert len(set(master[corners])) == 1  # the 8 corners are one node
    P = projection(master, m)
    assert P.shape == (192, 81) and np.all(P.sum(axis=1) == 1)


@pytest.mark.parametrize("material", [TPU, TI], ids=["iso", "ti"])
def test_solid_tet_mesh_returns_base_material(material):
    pts, tets, ph = voxels_to_tets(np.ones((3, 4, 3), int), (1.0, 2.0, 1.5))
    r = homogenize_mesh(pts + 5.0, tets, {1: material}, ph, size=(1.0, 2.0, 1.5))
    assert np.abs(r.C - material.stiffness()).max() <= 1e-10 * np.abs(material.stiffness()).max()
    assert r.relative_density == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("solver", ["direct", "amg"])
def test_tet_laminate_equals_backus(solver):
    ph = laminate(6, 0.5, axis=2)
    pts, tets, phase = voxels_to_tets(ph, (1.0, 1.0, 1.0))
    r = homogenize_mesh(pts, tets, {1: TI, 2: SOFT}, phase, size=(1.0, 1.0, 1.0), solver=solver, rtol=1e-10)
    C_ex = backus_laminate([TI.stiffness(), SOFT.stiffness()], [0.5, 0.5])
    assert np.abs(r.C - C_ex).max() <= 1e-6 * np.abs(C_ex).max()


def test_voxel_and_tet_routes_agree_on_a_lattice():
    """Stretch-dominated constants agree within 5 % on the same geometry; P1 tets are
    stiffer in bending (shear of the lattice), the voxel route is the reference."""
    ph = cubic_lattice(12, 4)
    a = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU})
    pts, tets, phase = voxels_to_tets(ph, (1.0, 1.0, 1.0))
    b = homogenize_mesh(pts, tets, {1: TPU}, phase, size=(1.0, 1.0, 1.0))
    assert b.relative_density == pytest.approx(a.relative_density, abs=1e-12)
    for ij in [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2)]:
        assert b.C[ij] == pytest.approx(a.C[ij], rel=0.05)
    assert b.fit.material.E_t == pytest.approx(a.fit.material.E_t, rel=0.05)
    assert b.C[3, 3] >= a.C[3, 3]  # P1 locks more in bending, never softer here


@pytest.mark.slow
def test_voxel_and_tet_routes_converge_together_on_a_foam():
    """Refining the same voxel foam (each voxel split s^3 times), both routes approach one
    limit and their gap shrinks; printed numbers go to the report."""
    ph0 = edge_foam(10, 0.3, seeds=4, rng_seed=2)
    gaps = []
    for s in (1, 2, 3):
        ph = ph0.repeat(s, 0).repeat(s, 1).repeat(s, 2)
        a = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, localise=False)
        pts, tets, phase = voxels_to_tets(ph, (1.0, 1.0, 1.0))
        b = homogenize_mesh(pts, tets, {1: TPU}, phase, size=(1.0, 1.0, 1.0), localise=False)
        gaps.append(b.fit.material.E_t / a.fit.material.E_t - 1.0)
        print(f"s={s}: E_t voxel {a.fit.material.E_t:.4f} tet {b.fit.material.E_t:.4f} gap {gaps[-1]:.3%}")
    assert gaps[0] > gaps[1] > gaps[2] > 0
    assert gaps[2] < 0.10


def test_tet_islands_removed_and_non_percolating_refused():
    ph = cubic_lattice(8, 2)
    pts, tets, phase = voxels_to_tets(ph, (1.0, 1.0, 1.0))
    base = homogenize_mesh(pts, tets, {1: TPU}, phase, size=(1.0, 1.0, 1.0))
    ph2 = ph.copy()
    ph2[1, 1, 1] = 1
    pts2, tets2, phase2 = voxels_to_tets(ph2, (1.0, 1.0, 1.0))
    r = homogenize_mesh(pts2, tets2, {1: TPU}, phase2, size=(1.0, 1.0, 1.0))
    assert r.removed_fraction > 0
    assert np.abs(r.C - base.C).max() < 1e-9 * np.abs(base.C).max()
    layer = np.ones((4, 4, 4), int)
    layer[:, :, 1] = 0
    pts3, tets3, phase3 = voxels_to_tets(layer, (1.0, 1.0, 1.0))
    with pytest.raises(InfeasibleError, match="percolate"):
        homogenize_mesh(pts3, tets3, {1: TPU}, phase3, size=(1.0, 1.0, 1.0))


def test_bad_mesh_input():
    pts, tets, phase = voxels_to_tets(np.ones((2, 2, 2), int), (1.0, 1.0, 1.0))
    with pytest.raises(MeshError, match="outside the box"):
        homogenize_mesh(pts * 2.0, tets, {1: TPU}, size=(1.0, 1.0, 1.0))
    with pytest.raises(ConfigError, match="tets"):
        homogenize_mesh(pts, tets[:, :3], {1: TPU}, size=(1.0, 1.0, 1.0))
    with pytest.raises(ConfigError, match="materials"):
        homogenize_mesh(pts, tets, {2: TPU}, size=(1.0, 1.0, 1.0))
    bad = tets.copy()
    bad[0, 3] = bad[0, 2]
    with pytest.raises(MeshError, match="degenerate"):
        homogenize_mesh(pts, bad, {1: TPU}, size=(1.0, 1.0, 1.0))
