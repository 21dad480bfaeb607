"""``metasheet export sofa``: the scene builds on a stand-in of SOFA's API with the robot's own
numbers, and its files alone rebuild metasheet's robot (the same Jacobian)."""

import importlib.util
import json
import sys

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.export.sofa import KPA_PER_MPA, export_sofa, read_sofa_robot
from metasheet.robot.kinematics import kinematics_at
from metasheet.robot.robots import grip_centre

from sofa_standin import Node, install
from serve_outputs import write_outputs


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny pipeline tree (15 mm P1 sheets, the paper's foam, model 'ours') and its export."""
    root = tmp_path_factory.mktemp("tiny")
    _, out = write_outputs(root)
    outputs = out / "tiny"
    return outputs, export_sofa(outputs, root / "scene")


@pytest.fixture(scope="module")
def robots(tiny):
    """(metasheet's robot built directly with the authors' model, the robot read back from the files)."""
    from dataclasses import replace

    from metasheet.export.sofa import six_dof_robot_of
    from metasheet.pipeline.artefacts import read_material, read_orient, read_robot_scene
    from metasheet.pipeline.column import column, column_robot

    outputs, folder = tiny
    sc = read_robot_scene(outputs / "robot")
    parts = column_robot(read_orient(outputs / "orient"), read_material(outputs / "material"), column("prediction"))
    sheets = replace(parts.sheets, element="p1")
    direct = six_dof_robot_of(sheets, None if sheets.has_constants else parts.material, replace(parts, model="authors"),
                              sc)
    return direct, read_sofa_robot(folder)


def build(folder, monkeypatch, **switches):
    """The exported scene.py run on the stand-in (``switches``: its module constants); no
    bytecode cache is left in the export folder."""
    install(monkeypatch)
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    spec = importlib.util.spec_from_file_location("exported_scene", folder / "scene.py")
    scene = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(scene)
    for k, v in switches.items():
        setattr(scene, k, v)
    root = Node("root")
    scene.createScene(root)
    return root


def test_the_files_alone_rebuild_the_robot_with_the_same_jacobian(tiny, robots):
    direct, back = robots
    J0, J1 = kinematics_at(direct, direct.rest_state()).J, kinematics_at(back, back.rest_state()).J
    assert np.abs(J1 - J0).max() <= 1e-10 * np.abs(J0).max()
    # the tiny tree's model is 'ours': robot.json states how far the scene's robot (the authors'
    # force field, read back here) is from it
    gap = json.loads((tiny[1] / "robot.json").read_text())["model_gap"]
    s = kinematics_at(back, back.rest_state()).singular_values
    assert np.allclose(gap["singular_values_authors"], s, rtol=1e-10)
    s_ours = np.array(gap["singular_values_ours"])
    assert gap["largest_relative_difference"] == pytest.approx(np.max(np.abs(s - s_ours) / s_ours), rel=1e-9)
    assert gap["largest_relative_difference"] > 0.01  # the two tensors differ on this foam
    assert np.abs(back.coupling.rest - direct.coupling.rest).max() <= 1e-12
    for a, b in zip(direct.coupling.servos, back.coupling.servos):
        assert np.array_equal(a.nodes, b.nodes)
        assert np.abs(a.pivot - b.pivot).max() <= 1e-12 and a.rest_angle == pytest.approx(b.rest_angle, abs=1e-14)


def test_the_scene_builds_with_the_robots_numbers(tiny, robots, monkeypatch):
    _, folder = tiny
    direct, _ = robots
    root = build(folder, monkeypatch)
    assert "Anisotropy" in root.find("RequiredPlugin")[0].pluginName and root.gravity == list(direct.gravity)
    ff, = root.find("TetrahedronAnisotropicForceField")
    m = len(direct.body.tets)
    assert len(ff.youngModulus) == len(ff.anisotropyDirections) == len(ff.anisotropyParameters) == m
    from metasheet.published import paper

    foam = paper.PAPER_FOAM
    assert ff.youngModulus[0] == pytest.approx(foam.E_t * KPA_PER_MPA, rel=1e-15)
    assert ff.anisotropyParameters[0] == pytest.approx([2, foam.E_l * KPA_PER_MPA, foam.nu_tl, foam.mu_l * KPA_PER_MPA],
                                                       rel=1e-15)
    # the directions are the robot's fibres in the world frame (another path: the page's geometry)
    from metasheet.pipeline.artefacts import read_orient
    from metasheet.serve.loading import robot_geometry

    o = read_orient(tiny[0] / "orient")
    geo = robot_geometry(direct, (o.sheets(need_constants=False).fibers, o.sheets(need_constants=False).fibers_mirrored))
    d = np.asarray(ff.anisotropyDirections)
    assert np.abs(np.abs(np.sum(d * geo.fibers, axis=1)) - 1).max() <= 1e-12
    # servos: stroke, rest angle, masses; the effector on the rod
    acts = root.find("JointActuator")
    assert len(acts) == 6
    assert [a.minAngle for a in acts] == pytest.approx(direct.angle_min, abs=0)
    assert [a.maxAngle for a in acts] == pytest.approx(direct.angle_max, abs=0)
    eff, = root.find("PositionEffector")
    assert eff.node.parents[0].name == "Rod" and eff.useDirections == [1] * 6
    assert root.find("QPInverseProblemSolver") and not root.find("RestShapeSpringsForceField")


def test_the_rigid_split_gives_back_every_node_once(tiny, robots, monkeypatch):
    _, folder = tiny
    direct, _ = robots
    root = build(folder, monkeypatch)
    sheets = root.Simulation.RigidifiedStructure.DeformableParts.Sheets
    assert {p.name for p in sheets.parents} == {"DeformableParts", "RigidifiedParticles"}
    free = np.asarray(root.Simulation.RigidifiedStructure.DeformableParts.dofs.position)
    rigid = root.Simulation.RigidifiedStructure.RigidParts
    gripped = np.asarray(rigid.RigidifiedParticles.dofs.position)
    pairs = np.asarray(sheets.mapping.indexPairs).reshape(-1, 2)
    rebuilt = np.array([(free, gripped)[src][i] for src, i in pairs])
    assert len(pairs) == len(direct.coupling.rest) and np.array_equal(rebuilt, direct.coupling.rest)
    assert sorted(map(tuple, pairs)) == sorted({tuple(p) for p in pairs})  # no node twice
    owner = np.asarray(rigid.RigidifiedParticles.mapping.rigidIndexPerPoint)
    assert np.bincount(owner).tolist() == [len(s.nodes) for s in direct.coupling.servos] + \
        [len(direct.coupling.effector_nodes)]
    assert {p.name for p in rigid.parents} == {"RigidifiedStructure", "ServoWheel", "Rod"}


def test_each_servo_frame_turns_its_horn_onto_its_grip(tiny, robots):
    from scipy.spatial.transform import Rotation

    _, folder = tiny
    direct, _ = robots
    data = json.loads((folder / "robot.json").read_text())
    att = np.zeros(len(direct.coupling.rest), int)
    for k, s in enumerate(direct.coupling.servos):
        att[s.nodes] = 1
        body = Rotation.from_quat(data["servos"][k]["frame"][3:]).as_matrix()
        grip = Rotation.from_quat(data["servos"][k]["grip_frame"][3:]).as_matrix()
        assert np.allclose(body[:, 0], s.axis, atol=1e-12)  # the articulation turns about the servo axis
        tip = grip_centre(direct.coupling.rest, direct.body.tets, att, 1)
        att[s.nodes] = 0
        # the wheel at the rest angle points its local y from the pivot to the grip's centre
        assert np.allclose(s.pivot + s.horn_length * grip[:, 1], tip, atol=1e-9)


def test_the_fallback_and_the_direct_program(tiny, tmp_path, monkeypatch):
    outputs, _ = tiny
    program = tmp_path / "program.csv"
    program.write_text("time_s," + ",".join(f"motor{k}_deg" for k in range(6)) + "\n0.0,60,60,60,60,60,60\n")
    folder = export_sofa(outputs, tmp_path / "iso", anisotropic=False, inverse=False, program=program)
    root = build(folder, monkeypatch)
    assert not root.find("TetrahedronAnisotropicForceField") and "Anisotropy" not in root.find("RequiredPlugin")[0].pluginName
    ff, = root.find("TetrahedronFEMForceField")
    assert ff.method == "large" and len(ff.youngModulus) == sum(json.loads((folder / "robot.json").read_text())
                                                               ["n_tets_per_sheet"])
    assert len(root.find("RestShapeSpringsForceField")) == 6 and not root.find("JointActuator")
    assert [o.name for o in root.objects if not hasattr(o, "type")] == ["program"]
    with pytest.raises(ConfigError, match="direct scene"):
        export_sofa(outputs, tmp_path / "bad", program=program)
    (tmp_path / "short.csv").write_text("time_s,motor0_deg\n0,60\n")
    with pytest.raises(ConfigError, match=r"--program: .*motor1_deg"):
        export_sofa(outputs, tmp_path / "bad", inverse=False, program=tmp_path / "short.csv")
    assert not (tmp_path / "bad").exists() and not (tmp_path / "bad.partial").exists()


def test_same_outputs_same_bytes_and_a_clear_error(tiny, tmp_path):
    outputs, folder = tiny
    again = export_sofa(outputs, tmp_path / "again")
    again = export_sofa(outputs, again)  # replaced whole
    names = sorted(p.name for p in folder.iterdir())
    assert names == sorted(p.name for p in again.iterdir())
    for n in names:
        assert (folder / n).read_bytes() == (again / n).read_bytes(), n
    with pytest.raises(ConfigError, match=r"orient/sheet.json: missing"):
        export_sofa(tmp_path, tmp_path / "x")
    with pytest.raises(ConfigError, match=r"--column: 'nope': allowed"):
        export_sofa(outputs, tmp_path / "x", column="nope")


def test_the_reproduction_column_exports_the_published_foam(tiny, tmp_path):
    from metasheet.published import paper

    folder = export_sofa(tiny[0], tmp_path / "rep", column="reproduction", mesh_size=16.0)
    rows = np.loadtxt(folder / "elements.txt")
    foam = paper.PAPER_FOAM
    assert np.allclose(rows[:, 4:], [foam.E_t * 1e3, foam.E_l * 1e3, foam.nu_t, foam.nu_tl, foam.mu_l * 1e3], rtol=1e-15)
    data = json.loads((folder / "robot.json").read_text())
    assert data["material_model"] == "authors" and "model_gap" not in data  # the scene is the robot


def test_the_command_writes_the_folder(tiny, tmp_path):
    from typer.testing import CliRunner

    from metasheet.cli import app

    res = CliRunner().invoke(app, ["export", "sofa", str(tiny[0]), "--to", str(tmp_path / "cli")])
    assert res.exit_code == 0, res.output
    assert "runSofa" in res.output and "SOFA will differ" in res.output  # the tiny tree's model is 'ours'
    assert (tmp_path / "cli" / "scene.py").is_file()
    assert (tmp_path / "cli" / "scene.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_isotropic_sheet_exports_as_the_degenerate_five_constants(tiny, tmp_path):
    from dataclasses import replace

    from metasheet.export.sofa import export_robot
    from metasheet.mechanics.material import Isotropic
    from metasheet.pipeline.artefacts import read_orient
    from metasheet.robot.builder import six_dof_robot

    sheets = replace(read_orient(tiny[0] / "orient").sheets(need_constants=False), constants=None,
                     constants_mirrored=None)
    silicone = Isotropic(0.25, 0.45)
    robot = six_dof_robot(sheets, silicone, density=1.07e-9)
    rows = np.loadtxt(export_robot(robot, sheets, silicone, "ours", tmp_path / "sil") / "elements.txt")
    mu = 0.25 / (2 * 1.45)
    assert np.allclose(rows[:, 4:], [250.0, 250.0, 0.45, 0.45, mu * 1e3], rtol=1e-14)
