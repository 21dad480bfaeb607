"""The Polyfoam printed inside the sheet, voxel by voxel (issue 44, item 1)."""

import json

import numpy as np
import pytest

from metasheet.cells.kgon import KgonMetric
from metasheet.cells.measure import mean_chord_lengths
from metasheet.cells.polyfoam import PolyfoamDesign
from metasheet.cells.specs import SeedSpec
from metasheet.errors import ConfigError
from metasheet.sheet import icesl
from metasheet.sheet import printed_foam as pf
from metasheet.sheet.grid import GridBox
from metasheet.sheet.outline import SheetParams
from metasheet.sheet.printed_seeds import cell_scale_table
from metasheet.sheet.printed_walls import gauge_facets, wall_tiles
from metasheet.viz.printed_foam import printed_foam_npz, printed_foam_picture

BEAD = 0.4
SLAB = ([0.0, 0.0, 0.0], [10.0, 10.0, 3.0])  # 10 x 10 x 3 mm: about 60 cells at 40 %, s = 1


def _design(**kw):
    return PolyfoamDesign(name="test", bead_width=BEAD, seeds=SeedSpec(count=8, seed=1), **kw)


@pytest.fixture(scope="module")
def design():
    return _design()


@pytest.fixture(scope="module")
def table_1(design):
    return cell_scale_table(design, [1.0])


@pytest.fixture(scope="module")
def table_05(design):
    return cell_scale_table(design, [0.5])


@pytest.fixture(scope="module")
def uniform(design, table_1):
    """40 %, no shrink, angle 0 on the slab at 0.1 mm (four voxels per bead)."""
    return pf.printed_foam(pf.box_region(*SLAB), pf.FoamFields(40.0, 1.0, 0.0), design, voxel_mm=0.1,
                           table=table_1)


def _solid_runs(mask: np.ndarray, axis: int) -> np.ndarray:
    """Lengths [voxels] of the runs of True along ``axis`` that end inside the grid on both sides."""
    m = np.moveaxis(mask, axis, -1).reshape(-1, mask.shape[axis]).astype(np.int8)
    d = np.diff(np.pad(m, ((0, 0), (1, 1))), axis=1)
    _rows, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)  # same rows, same order: runs alternate start, end
    keep = (starts > 0) & (ends < m.shape[1])
    return (ends - starts)[keep]


# --- the uniform foam against the periodic cell ---------------------------------------------------

def test_uniform_fields_give_the_periodic_cells_solid_fraction(uniform):
    rep = uniform.report
    assert rep.foam_voxels == rep.voxels == 100 * 100 * 30
    assert rep.target_fraction == pytest.approx(0.40)
    # the cell size is the 8-seed periodic cell's for 40 %; the slab is another realisation of
    # ~70 cells cut by free faces: seeds 1, 2, 3 gave 0.418, 0.416, 0.405. Tolerance 0.025 (6 %).
    assert abs(rep.solid_fraction_foam - 0.40) < 0.025
    assert rep.cells_in_foam > 40
    assert rep.seeds == pytest.approx(rep.seeds_expected, abs=1)


def test_walls_are_one_bead_thick_in_voxels(uniform):
    # k = 6 with no shrink has vertical walls whose normal is x (facets at 30 and 150 deg):
    # the most frequent solid run along x is across those walls, bead / voxel = 4 voxels
    assert uniform.report.wall_voxels == pytest.approx(4.0)
    runs = _solid_runs(uniform.phases == 1, 0)
    assert np.bincount(runs).argmax() == 4
    assert 3.0 <= np.median(runs) <= 6.0  # sloped walls cut obliquely are longer


def test_the_two_gauges_agree_exactly_when_the_fields_are_uniform(design, table_05):
    args = (pf.box_region([0, 0, 0], [8, 8, 2.4]), pf.FoamFields(30.0, 0.5, 20.0), design)
    a = pf.printed_foam(*args, voxel_mm=0.2, gauge="seed", table=table_05)
    b = pf.printed_foam(*args, voxel_mm=0.2, gauge="point", table=table_05)
    assert np.array_equal(a.phases, b.phases)
    assert np.array_equal(a.cell, b.cell)
    assert pf.compare_gauges(a, b)["phase_differs"] == 0.0


def test_turning_the_angle_by_90_deg_swaps_the_chords_along_x_and_y(design, table_05):
    chords = []
    for angle in (0.0, 90.0):
        f = pf.printed_foam(pf.box_region([0, 0, 0], [12, 12, 3]), pf.FoamFields(40.0, 0.5, angle), design,
                            voxel_mm=0.15, table=table_05)
        chords.append(mean_chord_lengths(f.phases == 0, f.size))
    (x0, y0, z0), (x9, y9, z9) = chords
    assert y0 > 1.5 * x0  # shrunk along the soft axis x: flat cells
    # measured: 0.93 / 0.86 and 1.84 / 1.82 mm (two realisations of ~65 cells each)
    assert x0 == pytest.approx(y9, rel=0.15)
    assert y0 == pytest.approx(x9, rel=0.15)
    assert z0 == pytest.approx(z9, rel=0.15)


def test_solid_brush_voxels_are_solid_and_outside_is_void(design, table_1):
    def disk(p):
        return np.hypot(p[:, 0] - 4.0, p[:, 1] - 4.0) <= 2.0

    region = pf.SheetRegion(np.zeros(3), np.array([8.0, 8.0, 2.0]),
                            lambda p: np.hypot(p[:, 0] - 4.0, p[:, 1] - 4.0) <= 3.8, disk)
    f = pf.printed_foam(region, pf.FoamFields(40.0, 1.0, 0.0), design, voxel_mm=0.2, table=table_1)
    assert f.report.brush_voxels > 0
    assert np.all(f.phases[f.region == pf.BRUSH] == 1)
    assert np.all(f.phases[f.region == pf.OUTSIDE] == 0)
    assert np.all(f.cell[f.region != pf.FOAM] == -1)
    assert 0.0 < f.report.solid_fraction_foam < 1.0


def test_same_seed_same_bytes_another_seed_another_foam(design, table_1):
    args = (pf.box_region([0, 0, 0], [6, 6, 2]), pf.FoamFields(40.0, 1.0, 30.0), design)
    a = printed_foam_npz(pf.printed_foam(*args, voxel_mm=0.2, seed=5, table=table_1))
    b = printed_foam_npz(pf.printed_foam(*args, voxel_mm=0.2, seed=5, table=table_1))
    c = printed_foam_npz(pf.printed_foam(*args, voxel_mm=0.2, seed=6, table=table_1))
    assert a == b
    assert a != c


# --- the distance kernel ----------------------------------------------------------------------

@pytest.mark.parametrize("shrink, angle", [(1.0, 0.0), (0.2, 37.0), (0.6, -110.0)])
def test_gauge_facets_are_the_kgon_metrics_turned_and_scaled(shrink, angle):
    g = gauge_facets(6, 45.0, np.array([shrink]), np.array([angle]), np.array([0.5]))[0]
    c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(g, 0.5 * KgonMetric(6, shrink, 45.0).facets @ R.T, atol=1e-12)


@pytest.mark.parametrize("point_mode", [False, True])
def test_tiled_candidates_give_the_all_seeds_result(point_mode):
    rng = np.random.default_rng(3)
    seeds = rng.random((60, 3)) * [10.0, 10.0, 6.0] - [0.0, 0.0, 2.0]
    s_seed, a_seed = rng.uniform(0.3, 1.0, 60), rng.uniform(0, 180, 60)
    inv = np.full(60, 1 / 2.0)
    sf = gauge_facets(6, 45.0, s_seed, a_seed, inv)
    pts = rng.random((400, 3)) * [4.0, 4.0, 2.0] + [3.0, 3.0, 0.0]
    s_pt, a_pt, inv_pt = rng.uniform(0.3, 1.0, 400), rng.uniform(0, 180, 400), np.full(400, 0.5)
    tiled = wall_tiles(pts, np.array([0, 400]), seeds, sf, 6, 45.0, s_pt, a_pt, inv_pt, point_mode, 0.3)
    # one point per tile: its bounds are the tightest; then brute force over all seeds
    single = wall_tiles(pts, np.arange(401), seeds, sf, 6, 45.0, s_pt, a_pt, inv_pt, point_mode, 0.3)
    assert np.array_equal(tiled[1], single[1])
    for i, x in enumerate(pts):
        F = gauge_facets(6, 45.0, s_pt[i:i + 1], a_pt[i:i + 1], inv_pt[i:i + 1])[0]
        vals = np.einsum("nfc,nc->nf", np.broadcast_to(F, sf.shape) if point_mode else sf, x - seeds)
        D, act = vals.max(1), vals.argmax(1)
        G = (np.broadcast_to(F, sf.shape) if point_mode else sf)[np.arange(60), act]
        j0 = int(np.argmin(D))
        assert tiled[1][i] == j0
        un = np.linalg.norm(G - G[j0], axis=1)
        wall = un > 1e-12  # same active facet as the owner's: the difference is constant, no wall
        wall[j0] = False
        h = np.divide(np.maximum(D - D[j0], 0), un, out=np.full(60, np.inf), where=wall)
        if h.min() < 0.3:
            assert tiled[0][i] == pytest.approx(h.min(), abs=1e-12)
        else:
            assert tiled[0][i] >= 0.3 - 1e-12


# --- the print map's fields, the sheet, pictures ----------------------------------------------

def test_printmap_fields_read_values_textures_and_defaults():
    box = GridBox(np.array([-10.0, -10.0, -2.5]), np.array([10.0, 10.0, 2.5]), 4)
    tex = np.full((4, 4, 4), 90.0 / 360.0)
    info = {"grid": [4, 4, 4],
            "brushes": {"0": {"settings": {"infill_percentage_0": 15.0},
                              "fields": {"infill_angle_0": "infill_angle.txt"}}},
            "sheets": {"normal": {"box_lo_mm": box.lo.tolist(), "box_hi_mm": box.hi.tolist()}}}
    f = pf.printmap_fields(json.loads(json.dumps(info)), "normal", {"infill_angle.txt": icesl.field_text(tex)})
    infill, shrink, angle = f(np.zeros((3, 3)))
    assert np.all(infill == 15.0) and np.all(shrink == 1.0)  # shrink: IceSL's default
    assert np.allclose(angle, 360.0 * round(255 * 0.25) / 255)  # 8 bits, as IceSL holds it
    with pytest.raises(ConfigError, match="infill_angle"):
        pf.printmap_fields(info, "normal", {})


def test_the_tripod_sheet_region_has_its_outline_hole_and_brush():
    r = pf.tripod_region(SheetParams(fillet_radius=0.0, tip_box=(36.0, 45.0, 30.0)))
    p = np.array([[20.0, 0.0, 0.0], [3.0, 0.0, 0.0], [20.0, 0.0, 2.6], [0.0, 40.0, 0.0], [60.0, 0.0, 0.0],
                  [9.0, 0.0, -2.4]])
    assert r.inside(p).tolist() == [True, False, False, False, True, True]
    assert r.solid(p).tolist() == [False, True, False, False, True, False]
    assert r.hi[0] == pytest.approx(66.0) and r.lo[1] == pytest.approx(-r.hi[1])
    assert (r.lo[2], r.hi[2]) == (-2.5, 2.5)


def test_picture_and_voxel_file(uniform):
    png = printed_foam_picture(uniform.phases, uniform.region, uniform.origin, uniform.voxel_mm, title="slab")
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    import io

    data = np.load(io.BytesIO(printed_foam_npz(uniform)))
    assert np.array_equal(data["phases"], uniform.phases)
    assert data["phases"].dtype == np.uint8
    assert np.allclose(data["size"], [10.0, 10.0, 3.0]) and np.allclose(data["origin"], 0.0)


# --- bad inputs ------------------------------------------------------------------------------

@pytest.mark.parametrize("kw, field", [
    ({"voxel_mm": 0.0}, "voxel_mm"), ({"voxel_mm": -0.2}, "voxel_mm"), ({"voxel_mm": 0.5}, "voxel_mm"),
    ({"fields": pf.FoamFields(0.5, 1.0, 0.0)}, "infill_percentage"),
    ({"fields": pf.FoamFields(95.0, 1.0, 0.0)}, "infill_percentage"),
    ({"fields": pf.FoamFields(lambda p: np.where(p[:, 0] > 3, 91.0, 40.0), 1.0, 0.0)}, "infill_percentage"),
    ({"fields": pf.FoamFields(40.0, 0.0, 0.0)}, "kgon_x_shrink"),
    ({"fields": pf.FoamFields(40.0, 1.5, 0.0)}, "kgon_x_shrink"),
    ({"fields": pf.FoamFields(40.0, 1.0, float("nan"))}, "infill_angle"),
    ({"gauge": "cell"}, "gauge"), ({"max_voxels": 1000}, "max_voxels"),
    ({"fields": pf.FoamFields(40.0, 0.5, 0.0)}, "table"),  # a table built for shrink 1 only
])
def test_bad_inputs_raise_config_errors_naming_the_field(design, table_1, kw, field):
    args = {"region": pf.box_region([0, 0, 0], [4, 4, 2]), "fields": pf.FoamFields(40.0, 1.0, 0.0),
                "design": design, "voxel_mm": 0.2, "table": table_1}
    with pytest.raises(ConfigError, match=field):
        pf.printed_foam(**{**args, **kw})


def test_a_jittered_sampler_is_refused(table_1):
    d = PolyfoamDesign(name="j", bead_width=BEAD, seeds=SeedSpec(sampler="jittered", count=8, seed=1))
    with pytest.raises(ConfigError, match="seeds.sampler"):
        pf.printed_foam(pf.box_region([0, 0, 0], [4, 4, 2]), pf.FoamFields(40.0, 1.0, 0.0), d, voxel_mm=0.2,
                        table=table_1)


# --- graded fields ---------------------------------------------------------------------------

def test_seeds_follow_the_local_cell_size_of_a_graded_infill(design):
    from metasheet.sheet.printed_seeds import graded_seeds, seed_scale

    table = cell_scale_table(design, [1.0])

    def fields(p):  # 20 % for x < 0, 50 % for x >= 0: cells about twice as small on the right
        return np.where(p[:, 0] < 0.0, 20.0, 50.0), np.ones(len(p)), np.zeros(len(p))

    s = graded_seeds(design, fields, table, [-15.0, -15.0, -1.0], [15.0, 15.0, 1.0], 1)
    beta = seed_scale(design, [1.0])[0, 2]
    for lo, hi, infill in ((-20.0, -5.0, 20.0), (5.0, 20.0, 50.0)):  # away from the step
        inside = (s.seeds[:, 0] >= lo) & (s.seeds[:, 0] < hi)
        volume = (hi - lo) * (s.hi[1] - s.lo[1]) * (s.hi[2] - s.lo[2])
        want = volume * beta / float(table(infill, 1.0)[0]) ** 3  # prod(scale) / L^3 seeds per mm^3
        assert inside.sum() == pytest.approx(want, rel=0.12)
    assert len(s.seeds) == round(s.expected)


def test_a_turning_angle_separates_the_two_gauges(design, table_05):
    def spiral(p):  # the soft axis at 60 deg to the radius, as the paper's sheet
        return np.degrees(np.arctan2(p[:, 1], p[:, 0])) + 60.0

    region = pf.box_region([-12, -12, -1.5], [12, 12, 1.5])
    fields = pf.FoamFields(40.0, 0.5, spiral)
    a = pf.printed_foam(region, fields, design, voxel_mm=0.2, gauge="seed", table=table_05)
    b = pf.printed_foam(region, fields, design, voxel_mm=0.2, gauge="point", table=table_05)
    c = pf.compare_gauges(a, b)
    assert c["phase_differs"] > 0.02 and c["cell_differs"] > 0.02
    for f in (a, b):  # both keep the density: the gauge moves walls, it does not add them
        assert f.report.solid_fraction_foam == pytest.approx(0.40, rel=0.1)
