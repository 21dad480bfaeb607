"""The polyfoam cell family: IceSL's Polyfoam as modelled (issue 13, item 1)."""

import itertools
import tomllib
from pathlib import Path

import numpy as np
import pytest

from metasheet.cells.catalogue import design_cell, parse_design
from metasheet.cells.foam import Foam, voxel_centres
from metasheet.cells.kgon import KgonMetric
from metasheet.cells.polyfoam import PolyfoamDesign
from metasheet.errors import ConfigError
from metasheet.homogenize.voxels import homogenize_voxels

CELLS = Path(__file__).resolve().parents[1] / "cells"


def _data(name="quick_polyfoam"):
    return tomllib.loads((CELLS / f"{name}.toml").read_text())


def _load(name="quick_polyfoam", **overrides):
    return parse_design(_data(name), overrides=overrides, source=f"cells/{name}.toml")


@pytest.fixture(scope="module")
def quick():
    return design_cell(_load())


def _homogenize(cell):
    return homogenize_voxels(cell.phases, cell.size, cell.materials, axis=cell.axis_vector, localise=False)


@pytest.fixture(scope="module")
def quick_homogenized(quick):
    """The quick cell homogenised as the chart does it (axis given, no localisation), once."""
    return _homogenize(quick)


def _moduli(r):
    return 1.0 / np.diag(np.linalg.inv(r.C))[:3]


# --- the gauge --------------------------------------------------------------------------------

@pytest.mark.parametrize("k, shrink, angle", [(6, 1.0, 45.0), (6, 0.2, 45.0), (5, 0.5, 30.0),
                                              (8, 0.1, 60.0), (3, 1.0, 70.0)])
def test_every_wall_piece_is_at_least_min_angle_steep(k, shrink, angle):
    m = KgonMetric(k, shrink, angle)
    g = m.facets
    assert g.shape == (2 * k, 3)
    steep = []
    for a, b in itertools.combinations(range(2 * k), 2):  # a wall piece has normal g_a - g_b
        n = g[a] - g[b]
        steep.append(np.degrees(np.arctan2(np.hypot(n[0], n[1]), abs(n[2]))))
    steep = np.array(steep)
    assert steep.min() >= angle - 1e-9
    assert steep.min() == pytest.approx(angle, abs=1e-9)  # beta is the largest that keeps it
    assert np.allclose(np.sort(steep), np.sort(m.wall_angles()))


@pytest.mark.parametrize("k, shrink, angle", [(6, 1.0, 45.0), (6, 0.2, 45.0), (4, 0.5, 20.0), (7, 0.05, 80.0)])
def test_gauge_bounds_hold_on_random_vectors(k, shrink, angle):
    m = KgonMetric(k, shrink, angle)
    v = np.random.default_rng(k).normal(size=(20000, 3)) * np.array([shrink, 1.0, 1.0 / m.beta])
    ratio = m.distance(v) / np.linalg.norm(v * m.scale, axis=1)
    assert ratio.min() >= m.lower * (1 - 1e-12)
    assert ratio.max() <= m.upper * (1 + 1e-12)
    assert np.all(m.distance(2.5 * v) == pytest.approx(2.5 * m.distance(v)))  # positively homogeneous
    assert np.array_equal(m.gradient(v)[0], m.facets[np.argmax(m.facets @ v[0])])


def test_gauge_is_convex_and_every_facet_active():
    from scipy.spatial import ConvexHull

    for k in (3, 6, 7):
        g = KgonMetric(k, 0.3, 45.0).facets
        # the polar body is the hull of the g_i (an antiprism): every g_i a vertex means every
        # facet shapes the unit ball; the origin inside it means the ball is bounded
        hull = ConvexHull(g)
        assert sorted(hull.vertices) == list(range(2 * k))
        assert np.all(hull.equations[:, -1] < 0)


# --- the cell ----------------------------------------------------------------------------------

def test_quick_polyfoam_meets_its_density_percolates_and_is_non_cubic(quick):
    d = quick.design
    assert isinstance(d, PolyfoamDesign) and quick.axis == 0
    assert quick.axis_vector.tolist() == [1.0, 0.0, 0.0]
    assert abs(quick.relative_density - d.infill_percentage / 100) <= d.tolerance
    assert quick.connectivity.ok and all(quick.connectivity.percolates)
    nx, ny, nz = quick.shape
    assert nx < ny < nz and quick.phases.dtype == np.uint8
    assert np.allclose(quick.voxel_mm, d.voxel_mm, rtol=0.15)
    sol = quick.polyfoam
    assert np.allclose(quick.size, sol.cell_scale * quick.size / sol.cell_scale)
    assert abs(sol.volume_estimate - sol.target) < 0.02  # continuous fraction close to the voxel one
    s = quick.summary()
    assert s["wall_thickness_mm"] == 0.4 and s["grid_shape"] == [nx, ny, nz]
    assert s["icesl"]["kgon_x_shrink"] == 0.5 and s["icesl"]["layer_height"] == 0.3
    assert s["seed_count"] == 4 and s["metric"]["kind"] == "kgon"
    assert s["cell_scale_mm"] == pytest.approx(sol.cell_scale)
    assert s["resolution"] == [nx, ny, nz]


@pytest.mark.parametrize("infill", [20.0, pytest.param(40.0, marks=pytest.mark.slow)])
def test_density_solve_hits_other_targets(infill):
    """Default-selection sibling of the slow 40 % case: test_density_solve_hits_other_targets[20.0]
    (the quick cell, built by every run, is 30 %)."""
    cell = design_cell(_load(infill_percentage=infill, voxel_mm=0.3))
    assert abs(cell.relative_density - infill / 100) <= 0.005
    assert cell.connectivity.ok


def test_level_set_is_periodic_and_matches_the_voxels(quick):
    f = quick.field
    rng = np.random.default_rng(0)
    x = rng.random((2000, 3)) * quick.size
    for shift in np.eye(3):
        assert np.allclose(f(x), f(x + shift * quick.size), atol=1e-9)
    inside = f(voxel_centres(quick.size, quick.shape)).reshape(quick.shape) < 0
    agree = np.mean(inside == (quick.phases > 0))
    assert agree > 0.999  # equal up to the dropped islands and rounding at the threshold
    assert isinstance(quick.foam, Foam) and quick.foam.topology == "closed"
    assert quick.foam.thickness == 0.4


def test_same_seed_same_bytes_other_seed_other_bytes(quick):
    again = design_cell(_load())
    other = design_cell(_load(seed=7))
    assert quick.phases.tobytes() == again.phases.tobytes()
    assert quick.size.tobytes() == again.size.tobytes()
    assert quick.phases.tobytes() != other.phases.tobytes()


# --- the homogenised symmetry ------------------------------------------------------------------

def test_shrink_makes_x_the_soft_axis(quick_homogenized):
    Ex, Ey, Ez = _moduli(quick_homogenized)
    assert Ex < 0.3 * min(Ey, Ez)  # measured 0.27, 1.52, 2.87 MPa


# Measured E_x / E_y over seeds 1..6 at these settings: 0.83-1.08 (4 seeds), 0.94-1.09
# (8 seeds). E_z is about 3x E_x, E_y: the trapezohedron's cells are taller than wide
# (1 / beta = 3.3 along z), their walls mostly vertical.
def _in_plane_ratio(seed: int) -> float:
    """E_x / E_y of the unshrunk quick cell at ``seed``, each seed within the measured spread."""
    Ex, Ey, Ez = _moduli(_homogenize(design_cell(_load(kgon_x_shrink=1.0, seed=seed))))
    assert 0.8 < Ex / Ey < 1.25
    assert Ez > 2.0 * max(Ex, Ey)
    return Ex / Ey


def test_no_shrink_is_isotropic_in_the_print_plane_at_one_seed():
    _in_plane_ratio(1)


@pytest.mark.slow
def test_no_shrink_is_isotropic_in_the_print_plane():
    """Default-selection sibling: test_no_shrink_is_isotropic_in_the_print_plane_at_one_seed (the
    per-seed bounds at seed 1; the mean over seeds here)."""
    assert 0.9 < np.mean([_in_plane_ratio(seed) for seed in (1, 2, 3)]) < 1.1


# --- the interface -----------------------------------------------------------------------------

def test_overrides():
    d = _load(infill_percentage=22, kgon_x_shrink=0.3, seed=5, voxel_mm=0.25)
    assert (d.infill_percentage, d.kgon_x_shrink, d.seeds.seed, d.voxel_mm) == (22, 0.3, 5, 0.25)
    assert _load(relative_density=0.18).infill_percentage == pytest.approx(18.0)
    assert _load(voxel_mm=None).voxel_mm == 0.3  # None is ignored
    assert parse_design({"kind": "polyfoam", "name": "x"}).voxel_edge == 0.2  # bead_width / 2
    with pytest.raises(ConfigError, match="resolution.*voxel_mm"):
        _load(resolution=32)
    with pytest.raises(ConfigError, match="relative_density"):
        _load(relative_density=0.2, infill_percentage=30)
    with pytest.raises(ConfigError, match="infill_percentage"):
        parse_design(tomllib.loads((CELLS / "quick_foam.toml").read_text()), overrides={"infill_percentage": 20})


@pytest.mark.parametrize("field, value, where", [
    ("kgon_norm_alpha", 0.7, "kgon_norm_alpha"),
    ("kgon_x_shrink", 0.0, "kgon_x_shrink"),
    ("kgon_x_shrink", 1.2, "kgon_x_shrink"),
    ("infill_percentage", 0.5, "infill_percentage"),
    ("infill_percentage", 95.0, "infill_percentage"),
    ("kgon_min_angle", 5.0, "kgon_min_angle"),
    ("axis", 3, "axis"),
])
def test_bad_settings_name_the_field(field, value, where):
    data = {**_data(), field: value}
    with pytest.raises(ConfigError, match=where):
        parse_design(data, source="cells/quick_polyfoam.toml")


def test_too_many_voxels_and_too_coarse_voxels_are_refused():
    with pytest.raises(ConfigError, match="max_voxels"):
        design_cell(parse_design({**_data(), "max_voxels": 5000}))
    with pytest.raises(ConfigError, match="voxel_mm"):
        design_cell(_load(voxel_mm=0.5))
    with pytest.raises(ConfigError, match="resolution"):
        design_cell(_load(), resolution=32)


def test_chart_call_sequence_works(quick, quick_homogenized):
    # what the chart code does (metasheet.homogenize.chart.evaluate_point): parse with the
    # point's overrides, build, homogenise. This point's overrides are the quick cell's own
    # values, so the build and the homogenisation are the module's (one design gives one cell:
    # test_same_seed_same_bytes_other_seed_other_bytes)
    design = parse_design(_data(), overrides={"infill_percentage": 30, "kgon_x_shrink": 0.5, "seed": 1,
                                              "voxel_mm": 0.3})
    assert design == quick.design
    r = quick_homogenized
    assert r.resolution == quick.shape and r.fit.material.E_l < r.fit.material.E_t


def test_cell_stage_writes_a_polyfoam(tmp_path):
    import json

    import matplotlib.image as mpimg
    import trimesh

    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages.cell import CellParams, run

    root = Path(__file__).resolve().parents[1]
    summary = run(StageContext("cell", CellParams(design="cells/quick_polyfoam.toml"), tmp_path, {}, root))
    assert summary["percolates"] is True and "wall_thickness_mm" in summary
    info = json.loads((tmp_path / "cell.json").read_text())
    with np.load(tmp_path / "voxels.npz") as z:
        shape = z["phases"].shape
        assert list(shape) == info["grid_shape"] and len(set(shape)) == 3
        assert z["axis"].tolist() == [1.0, 0.0, 0.0]
        assert np.allclose(z["size"], info["size_mm"])
    assert info["icesl"]["infill_percentage"] == 30.0 and info["cell_scale_mm"] > 0
    mesh = trimesh.load(tmp_path / "cell.stl")
    assert mesh.is_watertight
    box = float(np.prod(info["size_mm"]))
    # marching on the voxel grid with walls ~1.3 voxels thick: within 10 % of the voxel fraction
    assert mesh.volume / box == pytest.approx(info["relative_density"], rel=0.1)
    img = mpimg.imread(tmp_path / "cell.png")
    assert img.shape[0] > 400 and img.std() > 0.05
    with pytest.raises(ConfigError, match="resolution"):
        run(StageContext("cell", CellParams(design="cells/quick_polyfoam.toml", resolution=32), tmp_path, {}, root))


def test_the_built_walls_are_steep(quick):
    # every nearest-wall normal of the actual foam: |n_z| <= cos(kgon_min_angle)
    from metasheet.cells.skeleton import SkeletonIndex

    f = quick.foam
    d = SkeletonIndex(f.seeds, f.size, f.metric).distances(voxel_centres(f.size, quick.shape))
    assert np.all(np.abs(d.wall_nz) <= np.cos(np.radians(quick.design.kgon_min_angle)) + 1e-9)
    assert np.abs(d.wall_nz).max() > 0.5  # and sloped walls exist (45 deg: |n_z| up to 0.707)


def test_candidate_physics_options(quick):
    base = quick  # design_cell(_load()), built once for the module
    horizontal = design_cell(parse_design({**_data(), "wall_measure": "horizontal"}))
    # the bead is the wall's horizontal width: sloped walls thinner, so smaller cells for 30 %
    assert abs(horizontal.relative_density - 0.3) <= 0.005 and horizontal.connectivity.ok
    assert horizontal.polyfoam.cell_scale < base.polyfoam.cell_scale
    stairs = design_cell(parse_design({**_data(), "layer_model": "staircase", "voxel_mm": 0.2}))
    pf = stairs.polyfoam
    assert abs(stairs.relative_density - 0.3) <= 0.005 and stairs.connectivity.ok
    assert pf.layers > 0 and pf.layer_mm == pytest.approx(0.3, rel=0.1)
    m = stairs.shape[2] // pf.layers
    assert m * pf.layers == stairs.shape[2] and m == 2  # ceil(0.3 / 0.2) voxels per layer
    ph = stairs.phases.reshape(*stairs.shape[:2], pf.layers, m)
    assert np.all(ph == ph[..., :1])  # every layer is one extruded slice
    assert stairs.summary()["layer_model"] == "staircase"
    with pytest.raises(ConfigError, match="wall_measure"):
        parse_design({**_data(), "wall_measure": "diagonal"})
