"""Scene presets (metasheet.robot.scenes): the authors' numbers, the robot they build, the stages."""

import json
from dataclasses import replace

import numpy as np
import pytest

from metasheet.conventions import GRAVITY
from metasheet.errors import ConfigError
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.pipeline.artefacts import RobotScene, read_orient, write_material
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import _studies
from metasheet.pipeline.stages import orient as orient_stage
from metasheet.pipeline.stages import robot as robot_stage
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.robots import Q_A, Q_B, ServoGeometry
from metasheet.robot.scenes import AUTHORS, METASHEET, PRESETS, ScenePreset, get_preset
from test_studies_stages import skip_pictures

# The authors' SOFA scene (VannesteFelix/anisotropy examples/Tripod/inverse_simu), as read there:
SERVO_FRAMES_Y = (-91.35, 88.65)  # utility/tripod.py:139 (bottom), :146 (top)
CENTRE_FRAMES_Y = (30.0 - 90.0, -30.0 + 90.0)  # the 4th frames of :139 and :146
OFFSET_TO_RADIUS_DEG = 60.0  # inverse_simu.pyscn:357-358, tetra_and_angle(offset=60)


def test_presets_hold_their_documented_numbers():
    a = AUTHORS
    assert (a.arm_width, a.reach, a.thickness, a.hole_radius, a.fillet_radius) == (30.0, 66.0, 5.0, 5.0, 0.0)
    assert a.rod_length == CENTRE_FRAMES_Y[1] - CENTRE_FRAMES_Y[0] == 120.0
    assert a.servo_radius == 66.0 and a.rest_angle is None
    assert a.servo_depth == pytest.approx(np.mean(np.abs(SERVO_FRAMES_Y)) - CENTRE_FRAMES_Y[1], abs=1e-12)
    assert a.law == "log" and a.pitch_deg == 90.0 - OFFSET_TO_RADIUS_DEG
    assert a.sheet_mass_g == 32.0  # inverse_simu.pyscn:253 totalMass=0.032 [kg]
    assert a.gravity == (0.0, 0.0, -GRAVITY) and GRAVITY == 9810.0  # inverse_simu.pyscn:220
    for key, where in (("servo_radius", "tripod.py:32"), ("rod_length", "tripod.py:139,146"),
                       ("pitch_deg", "inverse_simu.pyscn:357-358"), ("sheet_mass_g", "inverse_simu.pyscn:253"),
                       ("gravity", "inverse_simu.pyscn:220"), ("fillet_radius", "tripod_coarse_04.vtk")):
        assert where in a.sources[key], key
    m = METASHEET  # metasheet's own choices: the previous defaults, unchanged
    assert (m.rod_length, m.rest_angle, m.horn_length, m.fillet_radius, m.pitch_deg) == (80.0, 60.0, 25.0, 5.0, 45.0)
    assert m.sheet_mass_g is None and m.servo_radius is None
    assert set(PRESETS) == {"authors", "metasheet"}
    for p in PRESETS.values():
        assert set(p.to_dict()["sources"]) == set(p.to_dict()["values"])
    with pytest.raises(ConfigError, match="no source"):
        ScenePreset(**{**{f: getattr(a, f) for f in a.__dataclass_fields__}, "sources": {}})


def test_invalid_preset_name_names_the_key_and_the_choices(tmp_path):
    with pytest.raises(ConfigError, match=r"scene: 'tutorial': allowed values are \['authors', 'metasheet'\]"):
        get_preset("tutorial")
    f = tmp_path / "p.toml"
    f.write_text('[pipeline]\nname = "x"\nstages = ["orient"]\n[orient]\nscene = "tutorial"\n')
    with pytest.raises(ConfigError, match=r"orient\.scene: 'tutorial'.*'metasheet'.*'authors'"):
        load_pipeline(f)


def test_servo_geometry_on_a_circle_is_validated():
    with pytest.raises(ConfigError, match="rest_angle"):
        ServoGeometry(60.0, servo_radius=66.0, servo_depth=30.0)
    with pytest.raises(ConfigError, match="servo_radius/servo_depth"):
        ServoGeometry(None, servo_radius=66.0)
    with pytest.raises(ConfigError, match="servo_depth"):
        ServoGeometry(None, servo_radius=66.0, servo_depth=-1.0)


@pytest.fixture(scope="module")
def authors_pair():
    return SheetPair.spiral(AUTHORS.sheet_params(10.0), **AUTHORS.fiber_settings())


def test_authors_robot_geometry_mass_and_gravity(authors_pair):
    a = AUTHORS
    rob = six_dof_robot(authors_pair, PAPER_FOAM, sheet_mass_g=a.sheet_mass_g, rod_length=a.rod_length,
                        geometry=a.servo_geometry(), gravity=a.gravity)
    assert rob.info["sheet_centres_mm"] == [[-60.0, 0.0, 0.0], [60.0, 0.0, 0.0]]
    for k, s in enumerate(rob.coupling.servos):
        side = -1.0 if k < 3 else 1.0
        assert np.hypot(s.pivot[1], s.pivot[2]) == pytest.approx(66.0, abs=1e-9)  # from the rod axis
        assert s.pivot[0] == pytest.approx(side * 90.0, abs=1e-9)  # 30 mm behind its sheet
        assert 70.0 < np.degrees(s.rest_angle) < 82.0 and 29.0 < s.horn_length < 33.0
    assert np.allclose(rob.coupling.servos[0].pivot, [-90.0, 0.0, -66.0])  # arm 0 hangs down, as theirs
    n = len(authors_pair.sheet.points)
    mass_g = [rob.body.mass[:n].sum() * 1e6, rob.body.mass[n:].sum() * 1e6]  # [t] -> [g]
    assert mass_g == pytest.approx([32.0, 32.0], rel=1e-9, abs=0)
    assert np.array_equal(rob.gravity, [0.0, 0.0, -GRAVITY])
    with pytest.raises(ConfigError, match="give exactly one"):
        six_dof_robot(authors_pair, PAPER_FOAM, density=1e-9, sheet_mass_g=32.0)


def test_authors_fibres_make_60_deg_with_the_radius_everywhere(authors_pair):
    for mesh, fib in ((authors_pair.sheet, authors_pair.fibers), (authors_pair.mirrored, authors_pair.fibers_mirrored)):
        c = mesh.centroids()
        keep = np.hypot(c[:, 0], c[:, 1]) > 1.0
        radial = c[keep, :2] / np.hypot(c[keep, 0], c[keep, 1])[:, None]
        ang = np.degrees(np.arccos(np.abs(np.sum(radial * fib[keep, :2], axis=1))))
        assert np.allclose(ang, OFFSET_TO_RADIUS_DEG, atol=1e-9)  # = 90 - pitch: 30 deg to the circle


def test_mirrored_field_is_the_reflection_across_the_rod(authors_pair):
    # world frame: sheet B (x > 0) must be sheet A (x < 0) reflected through x = 0, fibres too
    half = 0.5 * AUTHORS.rod_length
    ca = authors_pair.sheet.centroids() @ Q_A.T + [-half, 0, 0]
    cb = authors_pair.mirrored.centroids() @ Q_B.T + [half, 0, 0]
    fa, fb = authors_pair.fibers @ Q_A.T, authors_pair.fibers_mirrored @ Q_B.T
    R = np.diag([-1.0, 1.0, 1.0])
    order = [int(np.argmin(np.linalg.norm(ca - p @ R, axis=1))) for p in cb]
    assert np.allclose(ca[order], cb @ R, atol=1e-9)
    assert np.allclose(np.abs(np.sum(fa[order] * (fb @ R), axis=1)), 1.0, atol=1e-12)
    # and not the rotation by 180 deg about z (which would turn the spiral the same way seen from +x)
    Rz = np.diag([-1.0, -1.0, 1.0])
    order_z = [int(np.argmin(np.linalg.norm(ca - p @ Rz, axis=1))) for p in cb]
    assert not np.allclose(np.abs(np.sum(fa[order_z] * (fb @ Rz), axis=1)), 1.0, atol=1e-3)


def test_scene_overrides():
    sc = RobotScene(120.0, None, 25.0, 0.0, 90.0, servo_radius=66.0, servo_depth=30.0, sheet_mass_g=32.0)
    assert sc.with_overrides(rod_length=None) == sc
    flat = sc.with_overrides(rest_angle=50.0)  # an explicit rest angle places the servos from it
    assert (flat.rest_angle, flat.servo_radius, flat.servo_depth) == (50.0, None, None)
    back = replace(flat, scene="x").with_overrides(servo_depth=25.0)
    assert back.rest_angle is None and back.servo_depth == 25.0 and back.servo_radius is None
    with pytest.raises(ConfigError, match="servo_radius/servo_depth"):
        back.servo_geometry()


def _orient(tmp_path, mesh_size=14.0, **kw):
    out = tmp_path / "orient"
    out.mkdir()
    p = orient_stage.OrientParams(mesh_size=mesh_size, **kw)
    orient_stage.run(StageContext("orient", p, out, {}, tmp_path))
    return out


@pytest.mark.slow
def test_orient_robot_and_studies_follow_the_scene(tmp_path):
    """Default-selection sibling: test_orient_robot_and_studies_follow_the_scene_on_coarse_sheets."""
    _scene_follows(tmp_path, 14.0)


def test_orient_robot_and_studies_follow_the_scene_on_coarse_sheets(tmp_path, monkeypatch):
    """The slow test's checks on 20 mm P1 sheets, the robot stage without its other-model cases
    (compare_models, uncertainty off): the scene's numbers are exact whatever the mesh and
    element (P1 makes the robot stage's four equilibria a tenth of P2's time). Orient's
    picture is skipped (not read here; see test_studies_stages.skip_pictures)."""
    calls = skip_pictures(monkeypatch, "orient")
    _scene_follows(tmp_path, 20.0, "p1", compare_models=False, uncertainty=False)
    assert calls == ["orient"]


def _scene_follows(tmp_path, mesh_size, element="p2", **robot_kw):
    # the authors' direct scene's fibres
    o = _orient(tmp_path, mesh_size, scene="authors", pitch_deg=-60.0, element=element)
    info = json.loads((o / "sheet.json").read_text())
    assert info["element"] == element
    assert info["geometry"]["fillet_radius"] == 0.0 and info["geometry"]["tip_box"] == [36.0, 45.0, 30.0]
    assert info["fibers"]["pitch_deg"] == -60.0 and info["scene"]["overridden_by_orient"] == ["pitch_deg"]
    assert info["scene"]["name"] == "authors" and info["scene"]["values"]["rod_length"] == 120.0
    scene = read_orient(o).scene
    assert (scene.rod_length, scene.servo_radius, scene.sheet_mass_g) == (120.0, 66.0, 32.0)
    mat = tmp_path / "material"
    mat.mkdir()
    write_material(mat / "material.json", PAPER_FOAM, density=FOAM_DENSITY, source="config")
    work = tmp_path / "robot"
    work.mkdir()
    inputs = {"orient": o, "material": mat}
    summary = robot_stage.run(StageContext("robot", robot_stage.RobotParams(picture=False, compare_published=False, **robot_kw),
                                           work, inputs, tmp_path))
    assert summary["scene"] == "authors" and summary["rod_length_mm"] == 120.0 and summary["sheet_mass_g"] == 32.0
    assert summary["servo_radius_mm_derived"] == pytest.approx(66.0, abs=1e-9)
    geo = json.loads((work / "jacobian.json").read_text())["geometry"]
    assert geo["servo_geometry"]["servo_depth_mm"] == 30.0 and 70 < geo["servo_geometry"]["rest_angle_deg_derived"] < 82
    # a study without the robot stage takes the orient scene, its mass -> density of its own mesh
    ctx = StageContext("workspace", _studies.StudyRobotParams(mesh_size=20.0), tmp_path / "w", inputs, tmp_path)
    spec = _studies.build_spec(ctx)
    vol = np.abs(spec.sheets().sheet.volumes()).sum()
    assert spec.density * vol * 1e6 == pytest.approx(32.0, rel=1e-12)
    assert (spec.rod_length, spec.servo_radius, spec.servo_depth, spec.rest_angle) == (120.0, 66.0, 30.0, None)
    # with the robot stage, its scene (here overriding the rod) is the studies'
    work2 = tmp_path / "robot2"
    work2.mkdir()
    robot_stage.run(StageContext("robot", robot_stage.RobotParams(rod_length=100.0, picture=False,
                                                                  compare_published=False, **robot_kw), work2, inputs, tmp_path))
    spec2 = _studies.build_spec(StageContext("ranges", _studies.StudyRobotParams(), tmp_path / "r",
                                             {**inputs, "robot": work2}, tmp_path))
    assert spec2.rod_length == 100.0 and spec2.servo_radius == 66.0
    rob = spec2.build().robot
    assert np.allclose([s.pivot[0] for s in rob.coupling.servos], [-80.0] * 3 + [80.0] * 3)
