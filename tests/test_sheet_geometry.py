"""Tripod sheet geometry and mesh: tagged sets, orientation, volume, mirror."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.sheet.geometry import (
    ARM_ANGLES, SheetParams, mirror_sheet, outline_polygon, tet_volumes, tripod_sheet,
)


@pytest.fixture(scope="module")
def sheet():
    return tripod_sheet(SheetParams())


def _area(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def test_default_size_and_no_inverted_elements(sheet):
    assert 2500 <= len(sheet.tets) <= 5000
    vol = tet_volumes(sheet.points, sheet.tets)
    assert vol.min() > 0
    assert sheet.quality.min_volume == pytest.approx(vol.min())
    assert sheet.quality.worst_aspect < 10.0  # no slivers (regular tet = 1)


def test_volume_matches_outline_area(sheet):
    p = sheet.params
    # independent: area of the finely sampled outline minus the hole, times the thickness
    area = _area(outline_polygon(p, n_arc=400)) - np.pi * p.hole_radius**2
    # the mesh's straight chords on the 5 mm hole cut a little: allow 0.5 %
    assert sheet.quality.volume == pytest.approx(area * p.thickness, rel=5e-3)


def test_frame_and_extent(sheet):
    p = sheet.params
    assert np.allclose(sheet.points[:, 2].min(), -p.thickness / 2)
    assert np.allclose(sheet.points[:, 2].max(), p.thickness / 2)
    assert np.isclose(sheet.points[:, 0].max(), p.reach)  # arm 0 ends on x = reach
    assert np.allclose(sheet.arm_angles, np.deg2rad([0, 120, 240]))
    r = np.hypot(sheet.points[:, 0], sheet.points[:, 1])
    assert r.min() >= p.hole_radius - 1e-6


def test_tagged_sets_at_the_arm_ends_and_centre(sheet):
    p = sheet.params
    for k, a in enumerate(ARM_ANGLES):
        nodes = sheet.points[sheet.attach == k + 1]
        assert len(nodes) >= 10
        s = nodes[:, 0] * np.cos(a) + nodes[:, 1] * np.sin(a)  # along arm k
        assert s.min() >= p.reach - p.tip_box[0] / 2 - 1e-9
        assert s.max() == pytest.approx(p.reach)
        # the box spans the full width and thickness at the tip
        q = -nodes[:, 0] * np.sin(a) + nodes[:, 1] * np.cos(a)
        assert q.max() - q.min() == pytest.approx(p.arm_width, abs=1e-6)
    centre = sheet.points[sheet.attach == 4]
    assert len(centre) >= 10
    assert np.hypot(centre[:, 0], centre[:, 1]).max() <= p.centre_radius + 1e-9
    assert np.all(np.hypot(*sheet.points[sheet.attach == 0][:, :2].T) > p.centre_radius)


def test_the_centre_set_is_the_cylinder_the_mesh_conforms_to(sheet):
    """Every node on the border circle is tied, on both faces too: a sphere (the authors'
    wording) cuts the faces inside the circle, so its node set changes with the mesh."""
    p, pts = sheet.params, sheet.points
    r = np.hypot(pts[:, 0], pts[:, 1])
    on = np.abs(r - p.centre_radius) < 1e-6
    faces = on & (np.abs(np.abs(pts[:, 2]) - 0.5 * p.thickness) < 1e-9)
    assert on.sum() >= 20 and faces.sum() >= 10
    assert np.all(sheet.attach[on] == 4)


def test_mirror_is_the_reflection(sheet):
    m = mirror_sheet(sheet)
    assert np.allclose(m.points, sheet.points * [1, -1, 1])
    assert m.volumes().min() > 0
    assert np.isclose(m.quality.volume, sheet.quality.volume)
    # tag k + 1 still names the arm along 120 deg * k
    for k, a in enumerate(ARM_ANGLES):
        c = m.points[m.attach == k + 1].mean(axis=0)
        off = (np.degrees(np.arctan2(c[1], c[0]) - a) + 180.0) % 360.0 - 180.0
        assert abs(off) < 3.0  # node means of an unsymmetric mesh; a wrong tag is 120 deg off
    assert np.array_equal(mirror_sheet(m).attach, sheet.attach)


def test_same_params_same_mesh(sheet):
    again = tripod_sheet(SheetParams())
    assert np.array_equal(again.points, sheet.points) and np.array_equal(again.tets, sheet.tets)


def test_mesh_size_controls_the_count():
    coarse = tripod_sheet(SheetParams(mesh_size=8.0))
    fine = tripod_sheet(SheetParams(mesh_size=5.0))
    assert len(coarse.tets) < 2500 and coarse.quality.min_volume > 0
    assert len(fine.tets) > 1.5 * len(coarse.tets)


@pytest.mark.parametrize(
    "kw, field",
    [({"arm_width": -1}, "arm_width"), ({"hole_radius": 20}, "hole_radius"),
     ({"mesh_size": 0.0}, "mesh_size"), ({"centre_radius": 4.0}, "centre_radius"),
     ({"tip_box": (1, 2)}, "tip_box"), ({"reach": 10}, "reach")],
)
def test_bad_params_name_the_field(kw, field):
    with pytest.raises(ConfigError, match=field):
        SheetParams(**kw)
