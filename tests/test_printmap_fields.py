"""IceSL fields: scales, sampling accuracy, reflection, nearest-inside extension, layout."""

import numpy as np
import pytest
import trimesh

from metasheet.errors import ConfigError
from metasheet.sheet import icesl
from metasheet.sheet.fibers import fiber_angles, spiral_fibers
from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet


@pytest.fixture(scope="module")
def maps():
    sheet = tripod_sheet(SheetParams(mesh_size=6.0))
    mirrored = mirror_sheet(sheet)
    m = len(sheet.tets)
    rho = np.where(sheet.centroids()[:, 0] > 30, 0.30, 0.15)  # a graded design
    iso = np.where(sheet.centroids()[:, 0] > 30, 0.5, 0.0)
    out = {}
    for name, s, mir in (("normal", sheet, False), ("mirrored", mirrored, True)):
        out[name] = (s, icesl.print_fields(
            s.points, s.tets, fiber_fn=lambda q, mir=mir: spiral_fibers(q, pitch_deg=40.0, mirrored=mir),
            density=rho, iso=iso, gain=1.0, min_percent=0.0, max_percent=100.0))
    assert m == len(rho)
    return out


def test_values_in_unit_range_with_documented_scales(maps):
    sheet, pf = maps["normal"]
    for name, f in pf.fields.items():
        assert f.shape == (64, 64, 64), name
        assert f.min() >= 0.0 and f.max() <= 1.0, name
    inside = pf.cell >= 0
    # density = percentage / 100 = rho for gain 1
    assert set(np.unique(np.round(pf.fields["density"][inside], 12))) == {0.15, 0.30}
    assert np.allclose(pf.fields["phi"], 0.0)  # in-plane fibres
    assert pf.percent_range == (15.0, 30.0)


def test_density_mapping_clips():
    pct = icesl.density_percent(np.array([0.05, 0.15, 0.5]), gain=2.0, min_percent=20.0, max_percent=60.0)
    assert pct.tolist() == [20.0, 30.0, 60.0]
    with pytest.raises(ConfigError, match="max_percent"):
        icesl.density_percent(np.array([0.1]), min_percent=50.0, max_percent=40.0)


def _circ(a, b):
    """Distance between angles given as fractions of a turn, in radians."""
    d = np.mod(a - b + 0.5, 1.0) - 0.5
    return np.abs(d) * 2 * np.pi


@pytest.mark.parametrize("which", ["normal", "mirrored"])
def test_angle_field_at_centroids_gives_the_element_directions(maps, which):
    sheet, pf = maps[which]
    c = sheet.centroids()
    theta_e, _ = fiber_angles(spiral_fibers(c, pitch_deg=40.0, mirrored=(which == "mirrored")))
    i, j, k = pf.box.index_of(c).T
    got = pf.fields["theta"][i, j, k]
    # the texel (or its nearest inside neighbour) is within one texel diagonal of the
    # centroid; the spiral's direction turns at |grad psi| = 1 / r [rad/mm]
    r = np.hypot(c[:, 0], c[:, 1])
    tol = np.linalg.norm(pf.box.spacing) / r + 1e-9
    err = _circ(got, theta_e / (2 * np.pi))
    assert np.all(err <= tol), (err / tol).max()
    assert np.median(err) < 0.02  # [rad], about 1 deg


def test_mirrored_field_is_the_reflection(maps):
    _, a = maps["normal"]
    _, b = maps["mirrored"]
    M = np.array([1.0, -1.0, 1.0])
    assert np.allclose(b.box.lo, np.minimum(a.box.lo * M, a.box.hi * M))
    assert np.allclose(b.box.hi, np.maximum(a.box.lo * M, a.box.hi * M))
    flip = (slice(None), slice(None, None, -1), slice(None))  # texel j -> 63 - j is y -> -y
    assert np.mean(a.cell[flip] >= 0) == pytest.approx(np.mean(b.cell >= 0))
    assert np.mean((a.cell[flip] >= 0) == (b.cell >= 0)) > 0.999
    same = (a.cell[flip] >= 0) & (b.cell >= 0)
    # theta -> -theta under y -> -y; density and isotropy unchanged
    assert _circ(b.fields["theta"][same], -a.fields["theta"][flip][same]).max() < 1e-9
    # element i of the mirrored sheet is the image of element i: texels find the same
    # element except a few whose centre lies on a shared face (round-off picks either side)
    assert np.mean(b.cell[same] == a.cell[flip][same]) > 0.99
    for name in ("density", "iso"):
        assert np.mean(b.fields[name] == a.fields[name][flip]) > 0.999, name


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
    with pytest.raises(ConfigError, match="range"):
        icesl.field_text(v + 1.0)


def test_surface_is_watertight_and_outward(maps):
    sheet, _ = maps["normal"]
    verts, faces = icesl.surface(sheet.points, sheet.tets)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(sheet.quality.volume, rel=1e-9)  # > 0: normals point out
