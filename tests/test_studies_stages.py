"""The study stages end to end through the pipeline runner (stand-in robot, and a coarse FEM robot)."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from metasheet.errors import StageError
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline

GRID = """n_azimuth = 6
n_elevation = 3
n_steps = 6
extent_axial = 40
extent_lateral = 50
"""

STANDIN = f"""[pipeline]
name = "st"
stages = ["workspace", "ranges", "anisotropy", "maze", "report"]
[workspace]
model = "standin"
substeps = 2
{GRID}
[ranges]
model = "standin"
ranges = [[0, 90], [10, 80], [20, 70]]
{GRID}
[anisotropy]
model = "standin"
n_alpha = 4
[maze]
model = "standin"
path = [[0, 0], [20, 0], [20, 15], [0, 0]]
"""


def project(tmp_path: Path, text: str, name: str) -> Path:
    (tmp_path / "cells").mkdir(exist_ok=True)
    (tmp_path / "pipelines").mkdir(exist_ok=True)
    p = tmp_path / "pipelines" / f"{name}.toml"
    p.write_text(text)
    return p


def read_csv(path: Path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(f))


def non_blank_png(path: Path) -> None:
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 200
    assert img[..., :3].std() > 0.05  # not a flat picture


def _png_1x1() -> bytes:
    """A valid one-pixel PNG (what a skipped picture writes)."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00\x00")) + chunk(b"IEND", b""))


#: the pictures a test may skip: (module, function) of each stage's picture maker
PICTURES = {"workspace": ("metasheet.viz.studies", "workspace_picture"),
            "ranges": ("metasheet.viz.studies", "ranges_picture"),
            "anisotropy": ("metasheet.viz.studies", "anisotropy_picture"),
            "maze": ("metasheet.viz.studies", "maze_picture"),
            "orient": ("metasheet.viz.sheet", "sheet_picture")}


def skip_pictures(monkeypatch, *stages: str) -> list[str]:
    """Replace the named stages' picture makers by a one-pixel PNG, in a test that reads none
    of those pictures: each costs 1-4 CPU seconds of matplotlib (the workspace's 3 x 3 panels,
    orient's streamlines) and was most of a small study's time. Every one of them is still drawn
    and checked non-blank in the default selection: the studies' by
    test_stage_outputs_written_and_pictures_non_blank (and maze.png by the FEM stages test),
    orient's sheet.png by tests/test_printmap_lua.py. Returns the stages whose picture was asked
    for, in order (the stage still reached its picture)."""
    import importlib

    calls = []
    for stage in stages:
        module, name = PICTURES[stage]
        monkeypatch.setattr(importlib.import_module(module), name,
                            lambda *a, _stage=stage, **k: calls.append(_stage) or _png_1x1())
    return calls


@pytest.fixture(scope="module")
def standin_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("st")
    run_pipeline(load_pipeline(project(root, STANDIN, "st")))
    return root / "outputs" / "st"


def test_stage_outputs_written_and_pictures_non_blank(standin_run):
    for stage, files in {"workspace": ("workspace.csv", "workspace.vtp", "workspace.png"),
                         "ranges": ("ranges.csv", "ranges.png"), "anisotropy": ("anisotropy.csv", "anisotropy.png"),
                         "maze": ("maze.csv", "maze_silicone.csv", "maze.png"), "report": ("report.md",)}.items():
        for f in files:
            assert (standin_run / stage / f).stat().st_size > 0, f
    for png in standin_run.glob("*/*.png"):
        non_blank_png(png)
    assert not list(standin_run.glob(".*.units"))  # the resume cache is dropped after success


def test_workspace_csv_classes_match_errors(standin_run):
    rows = read_csv(standin_run / "workspace" / "workspace.csv")
    assert len(rows) == 20 * 4  # 20 rays x 4 of 6 steps (t >= 0.35; no multiple of 3 below)
    for r in rows:
        reached = r["error_mm"] != "nan" and float(r["error_mm"]) <= 1.0
        reached = reached and r["converged"] == "1"
        assert int(r["reached"]) == int(reached)
        if not reached:
            assert r["class"] == "-1" and r["component"] == "-1"
            continue
        n_ok = 0
        for ax in "xyz":
            ok = all(float(r[f"rot{s}{ax}_error_deg"]) <= 2.0 and float(r[f"rot{s}{ax}_error_mm"]) <= 1.0
                     for s in "+-")
            assert int(r[f"rot_{ax}_ok"]) == int(ok)
            n_ok += ok
        assert int(r["class"]) == n_ok
    import pyvista as pv

    cloud = pv.read(standin_run / "workspace" / "workspace.vtp")
    assert cloud.n_points == len(rows)
    assert np.array_equal(cloud.point_data["class"], [int(r["class"]) for r in rows])


def test_report_labels_figures_and_links_pictures(standin_run):
    text = (standin_run / "report" / "report.md").read_text()
    for label in ("Fig. 5", "Fig. 6", "Fig. 7", "Maze", "Differences from the paper", "stand-in"):
        assert label in text
    for pic in ("workspace.png", "ranges.png", "anisotropy.png", "maze.png"):
        assert f"]({pic})" in text and (standin_run / "report" / pic).exists()


def test_maze_and_anisotropy_csv(standin_run):
    rows = read_csv(standin_run / "maze" / "maze.csv")
    q = np.array([[float(r[f"motor{k}_deg"]) for k in range(6)] for r in rows])
    assert q.min() >= 0 and q.max() <= 90
    assert list(rows[0])[:7] == ["time_s"] + [f"motor{k}_deg" for k in range(6)]
    # csv, json and report agree on the strain along the path
    strain = np.array([float(r["strain"]) for r in rows])
    z = json.loads((standin_run / "maze" / "maze.json").read_text())
    assert z["max_strain"] == pytest.approx(strain.max(), rel=1e-5)  # the csv keeps 6 digits
    assert z["samples_beyond_strain"] == int((strain > z["strain_limit"]).sum())
    report = (standin_run / "report" / "report.md").read_text()
    assert f"| foam: samples beyond the strain limit {z['strain_limit']:g} | {z['samples_beyond_strain']} |" in report
    a = read_csv(standin_run / "anisotropy" / "anisotropy.csv")
    assert float(a[0]["alpha_percent"]) == 0 and abs(float(a[0]["push_rod_rotation_deg"])) < 1e-9
    assert abs(float(a[-1]["push_rod_rotation_deg"])) > 1.0


def test_fresh_run_is_byte_identical(standin_run, tmp_path, monkeypatch):
    skip_pictures(monkeypatch, "ranges", "anisotropy", "maze")  # the pictures it does not compare
    out = run_pipeline(load_pipeline(project(tmp_path, STANDIN, "st")))
    assert all(o.status == "ran" for o in out)
    for f in ("workspace/workspace.csv", "ranges/ranges.csv", "maze/maze.csv", "anisotropy/anisotropy.csv",
              "workspace/workspace.png"):
        assert (tmp_path / "outputs" / "st" / f).read_bytes() == (standin_run / f).read_bytes(), f


def test_interrupted_stage_resumes(tmp_path, standin_run, monkeypatch):
    calls = skip_pictures(monkeypatch, "workspace")  # the csv is compared, not the picture
    text = STANDIN.replace('stages = ["workspace", "ranges", "anisotropy", "maze", "report"]', 'stages = ["workspace"]')
    pipe = load_pipeline(project(tmp_path, text, "st"))

    def factory(stage):
        def update(desc, done, total):
            if desc == "workspace rays" and done >= 10:
                raise KeyboardInterrupt

        return update

    with pytest.raises(KeyboardInterrupt):
        run_pipeline(pipe, progress_factory=factory)
    units = tmp_path / "outputs" / "st" / ".workspace.units"
    stored = len(list(units.glob("*.pkl")))
    assert 0 < stored < 20
    seen = []
    run_pipeline(pipe, progress_factory=lambda s: (lambda d, i, n: seen.append((d, i))))
    assert seen[0] == ("workspace rays", stored)  # the finished rays were loaded, not recomputed
    a = (tmp_path / "outputs" / "st" / "workspace" / "workspace.csv").read_bytes()
    assert a == (standin_run / "workspace" / "workspace.csv").read_bytes()
    assert calls == ["workspace"]  # the interrupted run stopped before its picture


def test_robot_model_needs_orient(tmp_path):
    text = '[pipeline]\nname = "bad"\nstages = ["anisotropy"]\n[anisotropy]\nmodel = "robot"\n'
    with pytest.raises(StageError, match="orient"):
        run_pipeline(load_pipeline(project(tmp_path, text, "bad")))


ROBOT = """[pipeline]
name = "rb"
stages = ["material", "orient", "anisotropy", "maze", "report"]
[material]
source = "config"
[orient]
mesh_size = 14
[anisotropy]
model = "robot"
n_alpha = 3
[maze]
model = "robot"
path = [[0, 0], [10, 0], [10, 10]]
tilt_deg = 5
dt = 0.5
ramp_s = 0.5
speed = 10
"""


@pytest.mark.slow
def test_stages_on_coarse_fem_robot(tmp_path):
    """Default-selection sibling: test_stages_on_a_coarser_fem_robot."""
    _check_fem_stages(tmp_path, ROBOT)


def test_stages_on_a_coarser_fem_robot(tmp_path, monkeypatch):
    """The slow test's pipeline and checks on 20 mm sheets. The sweep stays on orient's P2
    elements (P1 sheets this coarse turn the rod by 8 % of the design's rotation at alpha = 0,
    where the exact answer is 0), with two fibre angles (0 and 90 deg), without the other
    material model's end points (tests/test_model_comparison.py runs those), a 5 deg pull (only
    the push is checked) and 12 deg ramps (the same rotations to the csv's 6 digits as 5 deg
    ones: the equilibrium does not depend on the path). The maze re-meshes the sheets with P1
    elements (``element = "p1"``: a fifth of P2's time; its checks are the robot's tracking
    within 1 mm and silicone's failure across the rod, not a mesh-converged number). Orient's
    and the sweep's pictures are skipped (:func:`skip_pictures`); the maze's is drawn and checked."""
    calls = skip_pictures(monkeypatch, "orient", "anisotropy")
    text = (ROBOT.replace("mesh_size = 14", "mesh_size = 20")
            .replace("n_alpha = 3", "n_alpha = 2\ncompare_models = false\npull_deg = 5\nramp_deg = 12")
            .replace('model = "robot"\npath', 'model = "robot"\nelement = "p1"\npath'))
    assert text.count("ramp_deg = 12") == text.count('element = "p1"') == 1
    _check_fem_stages(tmp_path, text)
    assert calls == ["orient", "anisotropy"]


def _check_fem_stages(tmp_path, text):
    run_pipeline(load_pipeline(project(tmp_path, text, "rb")))
    out = tmp_path / "outputs" / "rb"
    a = read_csv(out / "anisotropy" / "anisotropy.csv")
    rot = np.array([abs(float(r["push_rod_rotation_deg"])) for r in a])
    # alpha = 0: isotropic sheets, no rod rotation but the mesh's asymmetry (0.9 % on 20 mm P2)
    assert rot[0] < 0.03 * rot[-1] and np.all(np.diff(rot) > 0)
    m = read_csv(out / "maze" / "maze.csv")
    q = np.array([[float(r[f"motor{k}_deg"]) for k in range(6)] for r in m])
    assert q.min() >= 0 and q.max() <= 90
    assert max(float(r["track_mm"]) for r in m) <= 1.0
    s = read_csv(out / "maze" / "maze_silicone.csv")
    held = [r for r in s if r["hold"] == "1" and r["segment"] == "1"]
    assert held and not all(r["reached"] == "1" for r in held)  # silicone cannot tilt across the rod
    non_blank_png(out / "maze" / "maze.png")
    assert "Fig. 7" in (out / "report" / "report.md").read_text()


def test_bad_study_params_name_the_field(tmp_path):
    from metasheet.errors import ConfigError

    text = '[pipeline]\nname = "bad"\nstages = ["workspace"]\n[workspace]\nmodel = "standin"\nn_steps = 0\n'
    with pytest.raises(ConfigError, match="n_steps"):
        load_pipeline(project(tmp_path, text, "bad"))


def test_report_lists_differences_from_the_numbers():
    from metasheet.report.build import build_report

    ranges = {"reachable": {"0-90": 10, "20-70": 12}, "nested": False,
              "violations": [{"wide": "0-90", "narrow": "20-70", "points": 2}], "model": "robot"}
    maze = {"segments": 2, "samples": 10, "duration_s": 2.0, "foam_impossible_segments": [1],
            "silicone_impossible_segments": [], "motor_min_deg": 10.0, "motor_max_deg": 80.0,
            "within_motor_limits": True, "max_track_mm": 0.1, "max_track_deg": 0.1, "model": "robot"}
    text = build_report({"ranges": ranges, "maze": maze}, {"ranges": "ranges.png"})
    diffs = text.split("## Differences from the paper")[1]
    assert "do not nest" in diffs and "infeasible even with the foam" in diffs and "silicone sheets solved" in diffs
    assert "stand-in" not in diffs
    clean = dict(ranges, nested=True, violations=[])
    assert "none found" in build_report({"ranges": clean}, {}).split("## Differences from the paper")[1]


def test_study_mesh_size_remeshes_the_orient_sheet(tmp_path, monkeypatch):
    """``mesh_size`` rebuilds the sheet for the study only: same rest angle, far fewer tets,
    and the per-element constants carried over from the orient mesh."""
    skip_pictures(monkeypatch, "orient")  # sheet.png: most of this test's time, not read
    from metasheet.pipeline.artefacts import read_orient
    from metasheet.pipeline.remesh import remesh

    text = '[pipeline]\nname = "om"\nstages = ["material", "orient"]\n[material]\nsource = "config"\n[orient]\nmesh_size = 10\n'
    run_pipeline(load_pipeline(project(tmp_path, text, "om")))
    o = tmp_path / "outputs" / "om" / "orient"
    orient = read_orient(o)
    a, ca = orient.normal.mesh, orient.normal.constants
    pair = remesh(orient, 16.0)
    a2, fa2, ca2, b2 = pair.sheet, pair.fibers, pair.constants, pair.mirrored
    assert len(a2.tets) < 0.7 * len(a.tets) and len(b2.tets) == len(a2.tets)
    assert np.allclose(np.linalg.norm(fa2, axis=1), 1.0) and fa2.shape == (len(a2.tets), 3)
    # uniform design: every carried-over constant is one of the orient mesh's
    assert ca2.shape == (len(a2.tets), 5) and np.allclose(ca2, ca[0])
    assert set(np.unique(a2.attach)) == {0, 1, 2, 3, 4}


def test_workspace_within_the_strain_limit_counts_its_stops_in_the_csv_json_and_report(tmp_path, monkeypatch):
    skip_pictures(monkeypatch, "workspace")  # the numbers are checked, not the picture

    text = f"""[pipeline]
name = "sl"
stages = ["workspace", "report"]
[workspace]
model = "standin"
continuity = false
stop_beyond_strain = true
strain_limit = 0.04
{GRID}
"""
    run_pipeline(load_pipeline(project(tmp_path, text, "sl")))
    out = tmp_path / "outputs" / "sl"
    rows = read_csv(out / "workspace" / "workspace.csv")
    w = json.loads((out / "workspace" / "workspace.json").read_text())
    beyond = sum(int(r["rot_beyond_strain"]) for r in rows)
    assert beyond > 0 and w["rotations_beyond_strain"] == beyond  # the stand-in's limit is low: some fail
    # every reached point within the limit (at most the last of a ray beyond) and its failed tries
    for r in rows:
        if int(r["rot_beyond_strain"]):
            assert r["reached"] in ("1", "True") and float(r["max_principal_strain"]) <= 0.04
    text = (out / "report" / "report.md").read_text()
    assert f"| rotation tries failed beyond the strain limit | {beyond} |" in text
    assert "a rotation try counts only within it" in text


def test_maze_without_silicone_writes_the_foam_only(tmp_path, monkeypatch):
    """[maze] silicone = false: the foam's series as with it, no silicone file, its entries null,
    and the report says the comparison did not run."""
    text = STANDIN.replace('stages = ["workspace", "ranges", "anisotropy", "maze", "report"]',
                           'stages = ["maze", "report"]')
    for d in ("with", "without"):
        (tmp_path / d).mkdir()
    with monkeypatch.context() as m:  # the picture checked is the one without silicone
        skip_pictures(m, "maze")
        run_pipeline(load_pipeline(project(tmp_path / "with", text, "m")))
    run_pipeline(load_pipeline(project(tmp_path / "without", text + "silicone = false\n", "m")))
    with_, without = (tmp_path / d / "outputs" / "st" / "maze" for d in ("with", "without"))
    assert (with_ / "maze.csv").read_bytes() == (without / "maze.csv").read_bytes()
    assert (with_ / "maze_silicone.csv").is_file() and not (without / "maze_silicone.csv").exists()
    z = json.loads((without / "maze.json").read_text())
    assert z["silicone_segments_ok"] is None and z["silicone_impossible_segments"] is None
    assert json.loads((with_ / "maze.json").read_text())["silicone_impossible_segments"]  # a list: it ran
    non_blank_png(without / "maze.png")
    report = (tmp_path / "without" / "outputs" / "st" / "report" / "report.md").read_text()
    assert "not run in this column (silicone = false)" in report


def test_workspace_rotation_stop_is_counted_in_the_csv_and_json(tmp_path, monkeypatch):
    skip_pictures(monkeypatch, "workspace")  # the csv and json are checked, not the picture
    text = f"""[pipeline]
name = "ws"
stages = ["workspace"]
[workspace]
model = "standin"
continuity = false
rot_deg = 30
rot_stop_after = 2
{GRID.replace("n_azimuth = 6", "n_azimuth = 4").replace("n_elevation = 3", "n_elevation = 2").replace(
        "n_steps = 6", "n_steps = 12")}"""  # 4 x 2 rays of 12 steps: 4 reached points left untried
    run_pipeline(load_pipeline(project(tmp_path, text, "ws")))
    out = tmp_path / "outputs" / "ws" / "workspace"
    rows = read_csv(out / "workspace.csv")
    left = sum(r["reached"] == "1" and r["rot_tried"] == "0" for r in rows)
    z = json.loads((out / "workspace.json").read_text())
    assert z["rot_stop_after"] == 2 and z["rotations_left_out"] == left > 0
    assert all(r["class"] == "0" for r in rows if r["reached"] == "1" and r["rot_tried"] == "0")
