"""The robot stage end to end on a coarse orient-like input, and the goto helper."""

import json

import meshio
import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.goto import format_result, goto_robot
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.pipeline.artefacts import write_material
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import robot as robot_stage
from metasheet.robot.inverse import InverseController, InverseSettings
from metasheet.sheet.fibers import spiral_fibers
from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet


def _write_orient(d, mesh_size=15.0):
    s = tripod_sheet(SheetParams(mesh_size=mesh_size))
    m = mirror_sheet(s)
    consts = {k: np.full(len(s.tets), v) for k, v in PAPER_FOAM.to_dict().items()}
    for name, sh, mir in (("sheet.vtu", s, False), ("sheet_mirrored.vtu", m, True)):
        fib = spiral_fibers(sh.centroids(), mirrored=mir)
        meshio.write(d / name, meshio.Mesh(sh.points, [("tetra", sh.tets)], point_data={"attach": sh.attach},
                                           cell_data={"fiber": [fib], **{k: [v] for k, v in consts.items()}}))
    (d / "sheet.json").write_text(json.dumps({"arm_angles_deg": [0.0, 120.0, 240.0]}))


@pytest.fixture(scope="module")
def orient_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("orient")
    _write_orient(d)
    return d


def test_stage_writes_jacobian_vtu_and_picture(orient_dir, tmp_path):
    mat = tmp_path / "material"
    mat.mkdir()
    write_material(mat / "material.json", PAPER_FOAM, density=FOAM_DENSITY, source="config")
    work = tmp_path / "work"
    work.mkdir()
    ctx = StageContext("robot", robot_stage.RobotParams(delta_deg=-10.0), work,
                       {"orient": orient_dir, "material": mat}, tmp_path)
    summary = robot_stage.run(ctx)
    json.dumps(summary)
    assert summary["rest_angles_deg"] == [60.0] * 6  # the design rest angle, whatever the mesh
    # derived servo circle: tip box (~59-66 mm out on this mesh) + 25 cos 60 = 12.5 mm
    assert 70.0 < summary["servo_radius_mm_derived"] < 80.0
    bad = StageContext("robot", robot_stage.RobotParams(rest_angle=95.0), work, ctx.inputs, tmp_path)
    with pytest.raises(ConfigError, match="rest_angle"):
        robot_stage.run(bad)
    data = json.loads((work / "jacobian.json").read_text())
    foam, sil = data["materials"]["foam"], data["materials"]["silicone"]
    assert np.array(foam["J_mm_per_rad_and_rad_per_rad"]).shape == (6, 6)
    assert abs(foam["rod_rotation_deg_per_deg"]) > 10 * abs(sil["rod_rotation_deg_per_deg"])
    m = meshio.read(work / "rest.vtu")
    assert m.points.shape[1] == 3 and "displacement" in m.point_data
    assert m.point_data["displacement"][:, 2].mean() < 0  # gravity sag
    from PIL import Image

    img = np.asarray(Image.open(work / "robot.png").convert("L"), float)
    assert img.shape[0] > 500 and img.std() > 10  # written and not blank


def test_goto_helper_reaches_a_small_offset(orient_dir):
    rob = goto_robot(orient_dir)
    res = InverseController(rob).goto([0.0, 0.0, 1.0, 2.0, 0.0, 0.0])
    assert res.status == "reached", format_result(res)
    assert "motor angles" in format_result(res) and "certified by" in format_result(res)
    assert res.residual <= InverseSettings().eq_tol * res.reference
    assert np.all(res.angles_deg >= 0) and np.all(res.angles_deg <= 90)


def test_published_case_added_when_the_material_is_not_the_papers(orient_dir, tmp_path):
    """A homogenised material adds a 'published' robot; here the sheets carry the published
    constants per element, so the two cases are one robot built two ways: equal Jacobians."""
    from dataclasses import replace

    mat = tmp_path / "material"
    mat.mkdir()
    write_material(mat / "material.json", replace(PAPER_FOAM, E_t=2.0), density=FOAM_DENSITY, source="homogenize")
    work = tmp_path / "work"
    work.mkdir()
    ctx = StageContext("robot", robot_stage.RobotParams(picture=False), work,
                       {"orient": orient_dir, "material": mat}, tmp_path)
    summary = robot_stage.run(ctx)
    assert set(summary) >= {"foam", "silicone", "published"}
    data = json.loads((work / "jacobian.json").read_text())["materials"]
    np.testing.assert_allclose(data["published"]["J_mm_per_rad_and_rad_per_rad"],
                               data["foam"]["J_mm_per_rad_and_rad_per_rad"], rtol=1e-7, atol=1e-9)


def test_anisotropy_end_point_with_the_published_constants(orient_dir, tmp_path):
    """A homogenised material: the Fig. 7 stage adds the end point of the published set, at the
    published alpha (93.2 %), computed on the published robot (not the pipeline's)."""
    from dataclasses import replace

    from metasheet.runtime.executor import Executor
    from metasheet.pipeline.stages import anisotropy

    mat = tmp_path / "material"
    mat.mkdir()
    soft = replace(PAPER_FOAM, E_l=0.05)
    write_material(mat / "material.json", soft, density=FOAM_DENSITY, source="homogenize")
    work = tmp_path / "work"
    work.mkdir()
    p = anisotropy.AnisotropyParams(model="robot", n_alpha=2, pull_deg=5.0, push_deg=5.0, resume=False)
    s = anisotropy.run(StageContext("anisotropy", p, work, {"orient": orient_dir, "material": mat}, tmp_path,
                                    executor=Executor(workers=1)))
    end = s["published_end_point"]
    assert end["alpha_percent"] == pytest.approx(PAPER_FOAM.alpha, abs=1e-3)
    assert s["alpha_percent"][-1] == pytest.approx(soft.alpha, abs=1e-3)
    assert end["rod_rotation_deg"]["pull"] != pytest.approx(s["rod_rotation_deg"]["pull"][-1], rel=1e-3)


def test_pipeline_runs_the_robot_stage_without_its_picture(tmp_path):
    """``[robot] picture = false`` runs through the runner (it once failed the stage's
    declared-outputs check on the missing robot.png)."""
    from metasheet.cli import main

    toml = tmp_path / "nopic.toml"
    toml.write_text('[pipeline]\nname = "nopic"\nstages = ["material", "orient", "robot"]\n'
                    '[material]\nsource = "config"\n[orient]\nelement = "p1"\nmesh_size = 16.0\npicture = false\n'
                    '[robot]\npicture = false\n')
    with pytest.raises(SystemExit) as exit_info:
        main(["run", str(toml), "--out", str(tmp_path / "out")])
    assert exit_info.value.code in (0, None)
    robot = tmp_path / "out" / "nopic" / "robot"
    assert (robot / "jacobian.json").is_file() and not (robot / "robot.png").exists()
