"""Periodic isosurfaces: closed, manifold, exact volumes, matching caps."""

import numpy as np
import pytest

from metasheet.cells.surface import check_surface, periodic_isosurface
from metasheet.cells.tetmesh import periodic_mismatch
from metasheet.errors import ConfigError, MeshError

from cell_fields import (
    bcc_struts,
    gyroid,
    strut_lattice,
    strut_lattice_volume,
    voxel_fraction,
)

L = 1.0
BOX = np.array([L, L, L])


@pytest.mark.parametrize("name", ["struts", "gyroid", "bcc"])
def test_surface_is_closed_manifold_and_positive(name):
    field = {"struts": strut_lattice(BOX, 0.2), "gyroid": gyroid(L), "bcc": bcc_struts(L, 0.08)}[name]
    mesh = periodic_isosurface(field, BOX, 24)
    rep = check_surface(mesh)
    assert rep.watertight and rep.manifold and rep.volume > 0
    assert rep.n_components == 1
    # independent check with trimesh's own tests
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(rep.volume, rel=1e-12)
    # every vertex lies in the closed box
    assert np.all(mesh.vertices >= 0) and np.all(mesh.vertices <= L)


@pytest.mark.parametrize("r, n, tol", [(0.2, 32, 0.005), (0.3, 32, 0.005), (0.1, 32, 0.01)])
def test_strut_lattice_volume_matches_analytic(r, n, tol):
    mesh = periodic_isosurface(strut_lattice(BOX, r), BOX, n)
    exact = strut_lattice_volume(L, r)
    assert check_surface(mesh).volume == pytest.approx(exact, rel=tol)


def test_gyroid_fills_half_the_box():
    vol = check_surface(periodic_isosurface(gyroid(L), BOX, 32)).volume
    assert vol == pytest.approx(0.5, rel=2e-3)


def test_refinement_removes_the_thin_strut_shrinkage():
    # Linear interpolation of a convex distance shrinks struts ~2 cells thick; root refinement
    # on the true field puts the vertices on the surface. Analytic: r = 0.05 at n = 32.
    r, n = 0.05, 32
    exact = strut_lattice_volume(L, r)
    lin = check_surface(periodic_isosurface(strut_lattice(BOX, r), BOX, n, refine=0)).volume
    ref = check_surface(periodic_isosurface(strut_lattice(BOX, r), BOX, n)).volume
    assert abs(ref / exact - 1) < 0.02
    assert abs(ref / exact - 1) < 0.5 * abs(lin / exact - 1)


def test_volume_matches_voxel_fraction_at_64():
    # thin gyroid walls (~3 voxels thick, ~10 % solid, like a closed-cell foam), not aligned
    # with the grid (aligned struts alias in the voxel count by up to 10 %)
    g = gyroid(L)

    def field(p):
        return np.abs(g(p)) - 0.024

    vox = voxel_fraction(field, BOX, 64)
    rep = check_surface(periodic_isosurface(field, BOX, 64))
    assert rep.ok  # (the box cuts the sheet into several pieces: no single-component check)
    assert 0.05 < vox < 0.2
    assert rep.volume / L**3 == pytest.approx(vox, rel=0.03)


def test_aligned_thin_struts_match_analytic():
    # a 2 x 2 x 2 block of simple cubic cells with struts ~4 grid cells in radius, ~12 % solid
    r = 0.06
    vol = check_surface(periodic_isosurface(strut_lattice(BOX / 2, r), BOX, 64)).volume
    assert vol == pytest.approx(8 * strut_lattice_volume(L / 2, r), rel=0.01)


def test_foam_volume_matches_voxel_fraction_at_64():
    foam_mod = pytest.importorskip("metasheet.cells.foam")
    seeds_mod = pytest.importorskip("metasheet.cells.seeds")
    size = np.array([4.0, 4.0, 4.0])
    seeds = seeds_mod.make_seeds("poisson", 8, size, 3)
    foam = foam_mod.Foam(seeds, size, topology="open", thickness=0.3)
    field = foam_mod.foam_field(foam)
    vox = float(foam_mod.voxelize(foam, 64).mean())
    rep = check_surface(periodic_isosurface(field, size, 64))
    assert rep.watertight and rep.manifold
    assert rep.volume / size.prod() == pytest.approx(vox, rel=0.03)


def test_opposite_caps_match_exactly_on_a_non_cubic_box():
    size = np.array([1.0, 1.3, 0.7])
    mesh = periodic_isosurface(strut_lattice(size, 0.15), size, (20, 26, 14))
    assert check_surface(mesh).ok
    mismatch, pairs = periodic_mismatch(mesh.vertices, size)
    assert mismatch == 0.0
    for a in range(3):
        assert len(pairs[a]) > 0
        lo, hi = mesh.vertices[pairs[a][:, 0]], mesh.vertices[pairs[a][:, 1]]
        assert np.all(lo[:, a] == 0.0) and np.all(hi[:, a] == size[a])
    # the cap area on x = 0 is the strut's disc (pi r^2) to the resolution
    v = mesh.vertices[mesh.faces]
    on_x0 = np.all(v[:, :, 0] == 0.0, axis=1)
    area = 0.5 * np.linalg.norm(np.cross(v[on_x0, 1] - v[on_x0, 0], v[on_x0, 2] - v[on_x0, 0]), axis=1).sum()
    assert area == pytest.approx(np.pi * 0.15**2, rel=0.02)


def test_same_input_same_bytes():
    a = periodic_isosurface(gyroid(L), BOX, 16)
    b = periodic_isosurface(gyroid(L), BOX, 16)
    assert a.vertices.tobytes() == b.vertices.tobytes()
    assert a.faces.tobytes() == b.faces.tobytes()


def test_level_shifts_the_solid():
    # level = -0.05 on a distance field: struts of radius 0.15 instead of 0.2
    mesh = periodic_isosurface(strut_lattice(BOX, 0.2), BOX, 32, level=-0.05)
    assert check_surface(mesh).volume == pytest.approx(strut_lattice_volume(L, 0.15), rel=0.01)


def test_empty_solid_is_a_mesh_error():
    with pytest.raises(MeshError, match="empty"):
        periodic_isosurface(lambda p: np.ones(len(p)), BOX, 8)


def test_full_box_is_the_box():
    mesh = periodic_isosurface(lambda p: -np.ones(len(p)), BOX, 6)
    rep = check_surface(mesh)
    assert rep.ok and rep.volume == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"size": [1, 1]}, "size"),
        ({"size": [1, -1, 1]}, "size"),
        ({"n": 1}, "n"),
        ({"n": 2.5}, "n"),
        ({"refine": 11}, "refine"),
    ],
)
def test_bad_input_names_the_field(kwargs, match):
    args = {"size": BOX, "n": 8} | kwargs
    refine = args.pop("refine", 3)
    with pytest.raises(ConfigError, match=match):
        periodic_isosurface(gyroid(L), args["size"], args["n"], refine=refine)


def test_field_with_wrong_shape_is_a_config_error():
    with pytest.raises(ConfigError, match="field"):
        periodic_isosurface(lambda p: np.ones((len(p), 2)), BOX, 8)


def test_check_surface_sees_holes_and_flips():
    mesh = periodic_isosurface(gyroid(L), BOX, 12)
    rep = check_surface(mesh)  # a second method: trimesh's own checks
    assert rep.watertight == mesh.is_watertight and rep.manifold == mesh.is_winding_consistent is True
    assert rep.volume == pytest.approx(mesh.volume, rel=1e-12)
    holed = mesh.copy()
    holed.faces = holed.faces[1:]
    assert not check_surface(holed).watertight
    flipped = mesh.copy()
    f = flipped.faces.copy()
    f[0] = f[0, ::-1]
    flipped.faces = f
    rep = check_surface(flipped)
    assert rep.watertight and not rep.manifold
