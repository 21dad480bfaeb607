"""Periodic tet meshes: matched faces, positive tets, exact volumes, clean gmsh state."""

import gmsh
import numpy as np
import pytest

from metasheet.cells.surface import check_surface, periodic_isosurface
from metasheet.cells.tetmesh import periodic_mismatch, periodic_tet_mesh, tet_volumes
from metasheet.errors import ConfigError, MeshError

from cell_fields import gyroid, strut_lattice, strut_lattice_volume

L = 1.0
BOX = np.array([L, L, L])


@pytest.fixture(scope="module")
def gyroid_mesh():
    return periodic_tet_mesh(gyroid(L), BOX, 0.1)


def test_faces_match_to_1e9_of_the_cell(gyroid_mesh):
    m = gyroid_mesh
    assert m.max_mismatch < 1e-9 * L
    # independent recount: every node on a face has a partner on the opposite face
    for a in range(3):
        lo = np.flatnonzero(m.points[:, a] == 0.0)
        hi = np.flatnonzero(m.points[:, a] == L)
        assert len(lo) == len(hi) == len(m.pairs[a]) > 10
        p = m.pairs[a]
        shift = np.eye(3)[a] * L
        assert np.max(np.abs(m.points[p[:, 0]] + shift - m.points[p[:, 1]])) < 1e-9 * L
        assert len(np.unique(p[:, 1])) == len(p)  # one-to-one


def test_tets_are_positive_and_fill_the_surface(gyroid_mesh):
    m = gyroid_mesh
    vol = tet_volumes(m.points, m.tets)
    assert np.all(vol > 0)
    surf = check_surface(periodic_isosurface(gyroid(L), BOX, 10))
    assert m.volume == pytest.approx(surf.volume, rel=0.01)
    assert m.volume == pytest.approx(vol.sum(), rel=1e-12)
    assert m.volume == pytest.approx(0.5, rel=0.01)  # half the box, by symmetry
    assert m.n_components == 1
    assert m.tets.min() == 0 and m.tets.max() == len(m.points) - 1
    assert m.tets.dtype.kind == "i" and m.tets.shape[1] == 4


def test_gmsh_is_left_finalized(gyroid_mesh):
    assert not gmsh.isInitialized()


def test_non_cubic_strut_lattice():
    # struts of radius 0.12 along the axes of a 1 x 1.2 x 0.8 box
    size = np.array([1.0, 1.2, 0.8])
    m = periodic_tet_mesh(strut_lattice(size, 0.12), size, 0.04)  # radius: 3 cells
    assert m.max_mismatch < 1e-9 * size.max()
    assert np.all(tet_volumes(m.points, m.tets) > 0)
    r = 0.12
    exact = np.pi * r**2 * size.sum() - (16 / 3) * r**3 * 3 + 8 * (2 - np.sqrt(2)) * r**3
    assert m.volume == pytest.approx(exact, rel=0.015)  # chord sag: -0.9 % at h = 0.04
    assert m.relative_density == pytest.approx(m.volume / size.prod())
    # tets only in the struts: every centroid within r of an axis line, up to the chords that
    # bridge the concave creases where two struts meet (a fraction of the spacing h = 0.04)
    c = m.points[m.tets].mean(axis=1) - 0.5 * size
    d = np.min([np.hypot(c[:, 1], c[:, 2]), np.hypot(c[:, 0], c[:, 2]), np.hypot(c[:, 0], c[:, 1])], axis=0)
    assert d.max() < r + 0.25 * 0.04
    assert np.mean(d < r) > 0.99
    # cubic strut lattice matches its analytic volume too (cube of side 1)
    m2 = periodic_tet_mesh(strut_lattice(BOX, 0.2), BOX, 0.05)
    assert m2.volume == pytest.approx(strut_lattice_volume(L, 0.2), rel=0.01)


def test_finer_h_gives_more_tets():
    coarse = periodic_tet_mesh(gyroid(L), BOX, 0.2)
    fine = periodic_tet_mesh(gyroid(L), BOX, 0.1)
    assert len(fine.tets) > 4 * len(coarse.tets)


def test_caller_gmsh_session_is_kept():
    gmsh.initialize(argv=[], readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 7.0)
        gmsh.model.add("callers_model")
        m = periodic_tet_mesh(gyroid(L), BOX, 0.2)
        assert m.max_mismatch < 1e-9
        assert gmsh.isInitialized()
        assert gmsh.model.getCurrent() != ""
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 7.0
    finally:
        gmsh.finalize()


def test_no_solid_is_a_clear_mesh_error():
    with pytest.raises(MeshError, match="empty"):
        periodic_tet_mesh(lambda p: np.ones(len(p)), BOX, 0.2)
    assert not gmsh.isInitialized()


@pytest.mark.parametrize("h", [0.0, -1.0, 0.6, float("nan")])
def test_bad_h_is_a_config_error(h):
    with pytest.raises(ConfigError, match="h"):
        periodic_tet_mesh(gyroid(L), BOX, h)


def test_mismatch_detects_moved_and_missing_nodes():
    rng = np.random.default_rng(0)
    face = rng.random((20, 3))
    face[:, 0] = 0.0
    image = face + [L, 0, 0]
    inner = 0.1 + 0.8 * rng.random((30, 3))
    pts = np.concatenate([face, image, inner])
    mismatch, pairs = periodic_mismatch(pts, BOX)
    assert mismatch == 0.0
    assert np.array_equal(pairs[0][:, 1] - pairs[0][:, 0], np.full(20, 20))
    moved = pts.copy()
    moved[25, 1] += 1e-6
    assert periodic_mismatch(moved, BOX)[0] == pytest.approx(1e-6, rel=1e-6)
    assert periodic_mismatch(pts[:-31], BOX)[0] == np.inf  # one image node removed
    with pytest.raises(ConfigError, match="points"):
        periodic_mismatch(pts[:, :2], BOX)


def test_to_meshio(gyroid_mesh):
    mio = gyroid_mesh.to_meshio()
    assert mio.cells[0].type == "tetra"
    assert np.array_equal(mio.cells[0].data, gyroid_mesh.tets)


@pytest.mark.slow
def test_foam_mesh_of_200k_tets():
    from metasheet.cells import Foam, StretchedMetric, foam_field, solve_thickness
    from metasheet.cells.seeds import make_seeds

    size = np.array([10.0, 10.0, 10.0])
    seeds = make_seeds("poisson", 64, size, 0)
    sol = solve_thickness(seeds, size, StretchedMetric(), "open", 0.15, 64)
    foam = Foam(seeds, size, topology="open", thickness=sol.thickness)
    m = periodic_tet_mesh(foam_field(foam), size, 0.25)
    assert 1e5 < len(m.tets) < 4e5
    assert m.max_mismatch < 1e-9 * 10
    assert np.all(tet_volumes(m.points, m.tets) > 0)
    assert m.relative_density == pytest.approx(0.15, rel=0.05)
    assert m.n_components == 1
