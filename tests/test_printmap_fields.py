"""IceSL fields: scales, the axis-angle branch and its seam, solid parts, sampling, layout."""

import numpy as np
import pytest
import trimesh

from metasheet.errors import ConfigError
from metasheet.sheet import angles, icesl
from metasheet.sheet.fibers import fiber_angles, spiral_fibers
from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet

PARAMS = SheetParams(mesh_size=6.0)


@pytest.fixture(scope="module")
def maps():
    sheet = tripod_sheet(PARAMS)
    mirrored = mirror_sheet(sheet)
    pct = np.where(sheet.centroids()[:, 0] > 30, 60.0, 40.0)  # a graded design [%]
    out = {}
    for name, s, mir in (("normal", sheet, False), ("mirrored", mirrored, True)):
        out[name] = (s, icesl.print_fields(
            s.points, s.tets, element_settings={"infill_percentage": pct}, params=PARAMS,
            fiber_fn=lambda q, mir=mir: spiral_fibers(q, pitch_deg=45.0, mirrored=mir)))
    return out


def test_values_in_unit_range_with_documented_scales(maps):
    sheet, pf = maps["normal"]
    assert set(pf.textures) == {"infill_percentage", "infill_angle"}
    for name, f in pf.textures.items():
        assert f.shape == (64, 64, 64), name
        assert f.min() >= 0.0 and f.max() <= 1.0, name
    assert set(np.unique(np.round(pf.textures["infill_percentage"][pf.inside], 12))) == {0.4, 0.6}
    with pytest.raises(ConfigError, match=r"infill_percentage: values in \[0, 120\] %"):
        icesl.to_texture("infill_percentage", np.array([0.0, 120.0]))


def _axis_diff(a, b):
    """Distance between axis angles [deg] (period 180)."""
    return np.abs(np.mod(a - b + 90.0, 180.0) - 90.0)


@pytest.mark.parametrize("which", ["normal", "mirrored"])
def test_angle_is_the_fibre_axis(maps, which):
    sheet, pf = maps[which]
    c = pf.box.centers()[pf.inside]
    theta, _ = fiber_angles(spiral_fibers(c, pitch_deg=45.0, mirrored=(which == "mirrored")))
    written = pf.values("infill_angle")[pf.inside]
    assert _axis_diff(written, np.degrees(theta)).max() < 1e-9
    assert written.min() >= 0.0 and written.max() < 360.0


@pytest.mark.parametrize("which", ["normal", "mirrored"])
def test_axis_angle_has_one_seam_in_the_hub_neck_between_two_arms(maps, which):
    """No jump between neighbouring texels larger than the field's own turn over a texel
    (the spiral turns at 1 / r [rad/mm]) except at the single seam; the seam crosses the
    foam only in the hub, between the centre ring and the concave corner of two arms."""
    _, pf = maps[which]
    w = pf.values("infill_angle")
    centres = pf.box.centers()
    r = np.hypot(centres[..., 0], centres[..., 1])
    foam = pf.foam
    seam = []
    for ax in range(3):
        sl_a = [slice(None)] * 3
        sl_b = [slice(None)] * 3
        sl_a[ax], sl_b[ax] = slice(0, -1), slice(1, None)
        a, b = tuple(sl_a), tuple(sl_b)
        touch = foam[a] | foam[b]
        jump = np.abs(w[a] - w[b])
        bound = np.degrees(pf.box.spacing[ax] / np.minimum(r[a], r[b])) * 1.01 + 1e-9
        big = touch & (jump > bound)
        assert np.all(jump[big] > 300.0)  # a seam of the vector branch: 360 deg apart, nothing in between
        mid = 0.5 * (centres[a] + centres[b])[big]
        seam.append(mid)
    seam = np.concatenate(seam)
    assert len(seam) > 0
    rep = angles.seam_report(w, foam, pf.box)
    assert rep["foam_texel_pairs"] == len(seam)
    assert pf.branch.period == 360.0  # one seam beats the two of the period-180 branch here
    t = np.mod(np.degrees(np.arctan2(seam[:, 1], seam[:, 0])), 360.0)
    rs = np.hypot(seam[:, 0], seam[:, 1])
    # the normal sheet's seam lies between arm 2 (240 deg) and arm 0 (360), the mirror's between 0 and 120
    lo, hi = (240.0, 360.0) if which == "normal" else (0.0, 120.0)
    assert np.all((t > lo) & (t < hi)), (t.min(), t.max())
    corner = PARAMS.arm_width / np.sqrt(3.0) + PARAMS.fillet_radius
    assert rs.min() >= PARAMS.centre_radius - np.linalg.norm(pf.box.spacing)
    assert rs.max() <= corner + np.linalg.norm(pf.box.spacing[:2])
    assert rep["radius_mm"][1] <= corner + np.linalg.norm(pf.box.spacing[:2])


def test_branches_write_the_axis():
    theta = np.linspace(-720.0, 720.0, 1001)
    for br in angles.branch_candidates(step=15.0):
        w = br.write(theta)
        assert np.all((w >= br.offset) & (w < br.offset + br.period))
        assert _axis_diff(w, theta).max() < 1e-9
    with pytest.raises(ConfigError, match="offset"):
        angles.AngleBranch(180.0, 200.0)
    # a radial axis field (turns 360 deg per loop) wins with one seam; a uniform one has none
    g = np.stack(np.meshgrid(*[np.arange(16) - 7.5] * 2, indexing="ij"), -1)
    t = np.degrees(np.arctan2(g[..., 1], g[..., 0]))[..., None] * np.ones(4)
    br, n = angles.choose_branch(t, np.ones(t.shape, bool))
    assert br.period == 360.0 and n == 8 * 4  # one ray of 8 texel pairs per layer
    br, n = angles.choose_branch(np.full((8, 8, 4), 170.0), np.ones((8, 8, 4), bool))
    assert n == 0


def test_the_one_pass_seam_counts_equal_writing_every_offset():
    """The period-180 counts of choose_branch, one pass of arcs, against writing each of the 180
    branches (the definition), on random pairs with whole-degree angles and 0 / 90 / 180 deg
    differences mixed in (the ties the pass hands back to writing)."""
    rng = np.random.default_rng(3)
    for spread in (1.0, 30.0, 120.0):
        ta = rng.uniform(-400.0, 400.0, 2000)
        tb = ta + rng.normal(0.0, spread, ta.size)
        k = rng.permutation(ta.size)[:600]
        ta[k[:200]] = np.round(ta[k[:200]])
        tb[k[200:300]] = ta[k[200:300]] + 90.0
        tb[k[300:400]] = ta[k[300:400]] + 180.0
        tb[k[400:500]] = ta[k[400:500]]
        tb[k[500:]] = np.round(tb[k[500:]])
        each = [np.count_nonzero(np.abs(angles.AngleBranch(180.0, float(c)).write(ta)
                                        - angles.AngleBranch(180.0, float(c)).write(tb)) > angles.SEAM_JUMP)
                for c in range(180)]
        assert angles._seam_counts_by_offset(ta, tb).tolist() == each


@pytest.mark.parametrize("which", ["normal", "mirrored"])
def test_solid_parts_cover_the_tied_nodes(maps, which):
    sheet, pf = maps[which]
    tied = sheet.attach > 0
    assert icesl.solid_mask(sheet.points[tied], PARAMS).all()
    # the foam is most of the sheet; the solid parts are the ring and three tabs
    free = icesl.solid_mask(sheet.centroids(), PARAMS)
    assert 0.05 < free.mean() < 0.4
    v, f = icesl.solid_parts_mesh(PARAMS)
    mesh = trimesh.Trimesh(v, f, process=False)
    parts = mesh.split(only_watertight=True)
    assert len(parts) == 4 and all(p.is_watertight and p.volume > 0 for p in parts)
    pts = sheet.points[tied] * [1, 1, 0.99]
    inside = np.zeros(len(pts), bool)
    for part in parts:  # convex shells: inside = behind every face plane
        n, o = part.face_normals, part.triangles[:, 0]
        inside |= np.all(np.einsum("fk,pfk->pf", n, pts[:, None, :] - o[None]) <= 1e-9, axis=1)
    assert inside.all()


def test_quantise_and_trilinear_sampling():
    v = np.random.default_rng(0).random((64, 64, 64))
    q = icesl.quantise(v)
    assert np.abs(q - v).max() <= 0.5 / 255 + 1e-12
    assert np.allclose(q * 255, np.round(q * 255))
    box = icesl.GridBox(np.array([-1.0, 0.0, 2.0]), np.array([3.0, 8.0, 3.0]))
    c = box.centers()
    # texel centres give texel values; a linear field is reproduced between them
    idx = np.array([[0, 0, 0], [5, 17, 63], [63, 63, 63]])
    assert np.allclose(icesl.sample(v, box, c[tuple(idx.T)]), v[tuple(idx.T)])
    lin = 0.3 * c[..., 0] - 0.1 * c[..., 1] + 2.0 * c[..., 2]
    pts = np.random.default_rng(1).uniform(c[0, 0, 0], c[-1, -1, -1], size=(50, 3))
    assert np.allclose(icesl.sample(lin, box, pts), 0.3 * pts[:, 0] - 0.1 * pts[:, 1] + 2.0 * pts[:, 2])


def test_nearest_inside_extension_matches_brute_force():
    rng = np.random.default_rng(3)
    inside = rng.random((8, 8, 8)) < 0.2
    values = rng.random((8, 8, 8))
    spacing = np.array([1.0, 2.0, 0.5])
    out = icesl.extend_nearest(values, inside, spacing)
    idx = np.argwhere(inside)
    for q in np.ndindex(8, 8, 8):
        d = np.linalg.norm((idx - q) * spacing, axis=1)
        best = np.flatnonzero(d <= d.min() + 1e-12)  # ties: any nearest is fine
        assert out[q] in values[tuple(idx[best].T)]
    assert np.array_equal(out[inside], values[inside])
    with pytest.raises(ConfigError):
        icesl.extend_nearest(values, np.zeros_like(inside), spacing)


def test_field_text_layout_round_trip():
    v = np.round(np.random.default_rng(1).random((64, 64, 64)), 4)
    flat = np.array(icesl.field_text(v).split(), dtype=float)
    assert flat.size == 64**3
    c = np.arange(64**3)
    assert np.array_equal(flat, v[c % 64, (c // 64) % 64, c // 4096])
    assert np.array_equal(icesl.parse_field_text(icesl.field_text(v)), v)
    with pytest.raises(ConfigError, match="range"):
        icesl.field_text(v + 1.0)


def test_surface_is_watertight_and_outward(maps):
    sheet, _ = maps["normal"]
    verts, faces = icesl.surface(sheet.points, sheet.tets)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(sheet.quality.volume, rel=1e-9)  # > 0: normals point out
