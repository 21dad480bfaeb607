"""Issue 14 items 4-5: the robot and Fig. 7 end point under both material models, the report's
mu_l table, and the workspace study's two rotation tests (the paper's, the authors' code's)."""

import json
from dataclasses import replace

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.runtime.executor import Executor
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.pipeline.artefacts import write_material
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import anisotropy
from metasheet.pipeline.stages import robot as robot_stage
from metasheet.studies.grid import star_grid
from metasheet.report.model import model_section
from metasheet.report.build import build_report
from metasheet.studies.standin import StandInSpec
from metasheet.studies.workspace import (
    ROTATION_TESTS,
    WorkspaceSettings,
    explore_workspace,
)


@pytest.fixture(scope="module")
def orient_dir(tmp_path_factory):
    """An orient-like directory: a coarse sheet pair carrying the published constants per element."""
    import meshio

    from metasheet.sheet.fibers import spiral_fibers
    from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet

    d = tmp_path_factory.mktemp("orient")
    s = tripod_sheet(SheetParams(mesh_size=15.0))
    consts = {k: [np.full(len(s.tets), v)] for k, v in PAPER_FOAM.to_dict().items()}
    for name, sh, mir in (("sheet.vtu", s, False), ("sheet_mirrored.vtu", mirror_sheet(s), True)):
        meshio.write(d / name, meshio.Mesh(sh.points, [("tetra", sh.tets)], point_data={"attach": sh.attach},
                                           cell_data={"fiber": [spiral_fibers(sh.centroids(), mirrored=mir)],
                                                      **consts}))
    (d / "sheet.json").write_text(json.dumps({"arm_angles_deg": [0.0, 120.0, 240.0]}))
    return d


def _material(tmp_path, m, model="ours", source="config"):
    d = tmp_path / "material"
    d.mkdir()
    write_material(d / "material.json", m, density=FOAM_DENSITY, source=source, model=model)
    return d


def _robot(orient_dir, tmp_path, mat):
    work = tmp_path / "work"
    work.mkdir()
    ctx = StageContext("robot", robot_stage.RobotParams(picture=False), work, {"orient": orient_dir, "material": mat},
                       tmp_path)
    return robot_stage.run(ctx), json.loads((work / "jacobian.json").read_text())


def test_robot_stage_evaluates_the_other_model(orient_dir, tmp_path):
    summary, data = _robot(orient_dir, tmp_path, _material(tmp_path, PAPER_FOAM))
    assert summary["material_model"] == "ours" and summary["other_model"] == "authors"
    assert set(summary) >= {"foam", "silicone", "foam_authors"} and "published" not in summary
    assert data["material_model"] == "ours" and "foam_authors" in data["materials"]
    # the authors' force field ignores mu_l, which is tiny in the published set: a stiffer robot
    assert summary["foam_authors"]["singular_values"] != summary["foam"]["singular_values"]
    lines, _ = model_section(summary, None)
    text = "\n".join(lines)
    assert "Which results depend on the shear modulus mu_l" in text
    assert "pipeline, ours (all five constants)" in text and "pipeline, authors' force field" in text
    assert "controllable DOF" in text and "Fig. 8: rod rotation per motor degree" in text


def test_run_under_the_authors_model_compares_with_ours(orient_dir, tmp_path):
    soft = replace(PAPER_FOAM, E_t=2.0)  # not the published set: the published robots come too
    summary, _ = _robot(orient_dir, tmp_path, _material(tmp_path, soft, model="authors", source="homogenize"))
    assert summary["material_model"] == "authors"
    assert set(summary) >= {"foam", "foam_ours", "published", "published_ours"}
    # the sheets carry the published constants per element: published under a model = foam under it
    assert summary["published_ours"]["singular_values"] == pytest.approx(summary["foam_ours"]["singular_values"])
    lines, diffs = model_section(summary, None)
    head = next(line for line in lines if line.startswith("| claim"))
    assert head.count("|") == 6  # claim + pipeline ours / authors + published ours / authors
    assert any("Material model matters" in d for d in diffs)


def test_anisotropy_end_point_under_the_other_model(orient_dir, tmp_path):
    mat = _material(tmp_path, PAPER_FOAM)
    work = tmp_path / "work"
    work.mkdir()
    p = anisotropy.AnisotropyParams(model="robot", n_alpha=2, pull_deg=5.0, push_deg=5.0, resume=False)
    s = anisotropy.run(StageContext("anisotropy", p, work, {"orient": orient_dir, "material": mat}, tmp_path,
                                    executor=Executor(workers=1)))
    assert s["material_model"] == "ours" and set(s["model_end_points"]) == {"authors"}
    end = s["model_end_points"]["authors"]
    assert end["alpha_percent"] == pytest.approx(PAPER_FOAM.alpha, abs=1e-3)
    assert end["rod_rotation_deg"]["push"] != pytest.approx(s["rod_rotation_deg"]["push"][-1], rel=1e-3)
    robot = {"material_model": "ours", "other_model": "authors",
             "foam": {"singular_values": [2.0, 1.0], "rod_rotation_deg_per_deg": -0.6},
             "foam_authors": {"singular_values": [2.0, 1.0], "rod_rotation_deg_per_deg": -0.61},
             "silicone": {"singular_values": [2.0, 0.01], "rod_rotation_deg_per_deg": 0.0}}
    text = build_report({"robot": robot, "anisotropy": s}, {})
    table = text.split("## Which results depend on the shear modulus mu_l")[1].split("##")[0]
    assert "Fig. 7 end point: rod rotation, push [deg]" in table
    assert f"{end['rod_rotation_deg']['push']:.3g}" in table
    assert "| controllable DOF (singular value > 0.05 x largest) (silicone: 1) | 2 | 2 |" in table


def test_rotation_tests_are_the_documented_ones():
    paper = WorkspaceSettings.for_test("paper")
    assert (paper.rot_deg, paper.tol_rot_deg, paper.rot_axes, paper.jump_mm, paper.sequential) == (
        10.0, 2.0, "xyz", None, False)
    assert paper == WorkspaceSettings()  # the paper's test stays the default
    code = WorkspaceSettings.for_test("authors_code")
    assert (code.rot_deg, code.tol_rot_deg, code.rot_axes, code.tol_mm, code.jump_mm, code.sequential) == (
        5.0, 3.0, "y", 1.0, 1.0, True)
    assert WorkspaceSettings.for_test("authors_code", rot_deg=7.0, tol_rot_deg=None).rot_deg == 7.0
    assert set(ROTATION_TESTS) == {"paper", "authors_code"}
    with pytest.raises(ConfigError, match=r"workspace.test: 'sofa': allowed values are 'paper', 'authors_code'"):
        WorkspaceSettings.for_test("sofa")
    with pytest.raises(ConfigError, match="rot_axes"):
        WorkspaceSettings(rot_axes="xw")


def test_both_rotation_tests_run_on_a_small_grid():
    grid = star_grid(n_azimuth=4, n_elevation=2, n_steps=5, extent_axial=30.0, extent_lateral=40.0)
    paper = explore_workspace(StandInSpec(), grid, WorkspaceSettings.for_test("paper", continuity=False))
    code = explore_workspace(StandInSpec(), grid, WorkspaceSettings.for_test("authors_code", continuity=False))
    np.testing.assert_array_equal(paper.records.reached, code.records.reached)  # same point reaches
    r = code.records
    assert np.all(np.isnan(r.rot_error_deg[:, [0, 1, 4, 5]]))  # x and z never tried
    assert not r.rot_ok[:, [0, 2]].any() and set(np.unique(code.cls)) <= {-1, 0, 1}
    tried = r.reached & np.isfinite(r.rot_error_deg[:, 2])
    assert tried.any() and np.all(np.isfinite(r.rot_jump_mm[tried]))
    ok = (r.rot_error_deg[:, 2:4] <= 3.0).all(axis=1) & (r.rot_error_mm[:, 2:4] <= 1.0).all(axis=1) \
        & (r.rot_jump_mm <= 1.0)
    np.testing.assert_array_equal(r.rot_ok[:, 1], ok & r.reached)
    assert np.all(np.isnan(paper.records.rot_jump_mm))


def test_workspace_stage_records_the_rotation_test(tmp_path):
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    (tmp_path / "pipelines").mkdir()
    p = tmp_path / "pipelines" / "w.toml"
    p.write_text('[pipeline]\nname = "w"\nstages = ["workspace", "report"]\n[workspace]\nmodel = "standin"\n'
                 'test = "authors_code"\ncontinuity = false\nn_azimuth = 4\nn_elevation = 2\nn_steps = 4\n')
    run_pipeline(load_pipeline(p), out_root=tmp_path / "out")
    w = json.loads((tmp_path / "out" / "w" / "workspace" / "workspace.json").read_text())
    assert w["rotation_test"] == {"test": "authors_code", "rot_deg": 5.0, "tol_rot_deg": 3.0, "axes": "y",
                                  "tol_mm": 1.0, "jump_mm": 1.0, "sequential": True, "rotations": True}
    report = (tmp_path / "out" / "w" / "report" / "report.md").read_text()
    assert "authors_code (+-5 deg about y, in sequence, within 3 deg and 1 mm, no jump > 1 mm)" in report
    p.write_text('[pipeline]\nname = "w"\nstages = ["workspace"]\n[workspace]\nmodel = "standin"\ntest = "x"\n')
    with pytest.raises(ConfigError, match=r"workspace.test: 'x': Input should be 'paper' or 'authors_code'"):
        load_pipeline(p)
