"""Stage artefacts: what a writer writes its reader reads back; missing pieces are errors
naming the file, never a silent default."""

import json

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.pipeline import artefacts as art
from metasheet.sheet.fibers import spiral_fibers
from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet


def test_material_round_trip(tmp_path):
    art.write_material(tmp_path / "material.json", PAPER_FOAM, density=FOAM_DENSITY, source="config")
    m = art.read_material(tmp_path)
    assert m.material == PAPER_FOAM and m.density == FOAM_DENSITY and m.source == "config"
    data = json.loads((tmp_path / "material.json").read_text())
    assert data["units"] == {"E_t": "MPa", "E_l": "MPa", "nu_t": "-", "nu_tl": "-", "mu_l": "MPa",
                             "density": "t/mm^3"}
    del data["constants"]["mu_l"]
    (tmp_path / "material.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="material.json: constants: missing mu_l"):
        art.read_material(tmp_path)


def _orient(d, with_constants=True):
    s = tripod_sheet(SheetParams(mesh_size=15.0))
    m = mirror_sheet(s)
    for name, sh, mir in (("sheet.vtu", s, False), ("sheet_mirrored.vtu", m, True)):
        cd = {"fiber": spiral_fibers(sh.centroids(), mirrored=mir)}
        if with_constants:
            cd |= {k: np.full(len(sh.tets), v) for k, v in PAPER_FOAM.to_dict().items()}
        art.write_sheet(d / name, sh, cd)
    (d / "sheet.json").write_text(json.dumps({"arm_angles_deg": [0.0, 120.0, 240.0]}))
    return s


def test_orient_round_trip_and_no_silent_fallback(tmp_path):
    s = _orient(tmp_path)
    o = art.read_orient(tmp_path)
    pair = o.sheets()
    assert np.array_equal(pair.sheet.points, s.points) and np.array_equal(pair.sheet.tets, s.tets)
    assert np.array_equal(pair.sheet.attach, s.attach)
    assert np.allclose(pair.sheet.arm_angles, s.arm_angles, rtol=0, atol=1e-15)
    assert np.all(pair.constants == PAPER_FOAM.as_tuple())
    bare = tmp_path / "bare"
    bare.mkdir()
    _orient(bare, with_constants=False)
    with pytest.raises(ConfigError, match=r"bare/sheet.vtu: no per-element constants"):
        art.read_orient(bare).sheets()
    assert art.read_orient(bare).sheets(need_constants=False).constants is None
    with pytest.raises(ConfigError, match="sheet.json: missing"):
        art.read_orient(tmp_path / "nowhere")


def test_robot_scene_from_jacobian(tmp_path):
    geo = {"rod_length_mm": 80.0, "servo_geometry": {"rest_angle_deg": 55.0, "horn_length_mm": 25.0,
                                                     "angle_min_deg": 5.0, "angle_max_deg": 85.0}}
    art.write_jacobian(tmp_path / "jacobian.json", {"geometry": geo, "materials": {}})
    assert art.read_robot_scene(tmp_path) == art.RobotScene(80.0, 55.0, 25.0, 5.0, 85.0)
    del geo["servo_geometry"]["horn_length_mm"]
    art.write_jacobian(tmp_path / "jacobian.json", {"geometry": geo})
    with pytest.raises(ConfigError, match="horn_length_mm"):
        art.read_robot_scene(tmp_path)
