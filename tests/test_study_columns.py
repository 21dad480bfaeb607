"""The two columns of every study (metasheet/pipeline/column.py): the reproduction runs on the
published constants under the authors' force field without a strain stop, the prediction on
the material stage's; each writes its own folder and names its column in its JSON."""

import json

import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline

from test_studies_stages import project, skip_pictures


STANDIN = """[pipeline]
name = "cols"
stages = ["workspace", "ranges", "report"]
[workspace]
model = "standin"
columns = ["prediction", "reproduction"]
stop_beyond_strain = true
continuity = false
n_azimuth = 4
n_elevation = 2
n_steps = 4
[ranges]
model = "standin"
columns = ["reproduction"]
n_azimuth = 4
n_elevation = 2
n_steps = 4
"""


@pytest.fixture(scope="module")
def cols_run(tmp_path_factory):
    """The stand-in pipeline's two columns, run once for the tests that read them (the ranges
    picture skipped: not read here; the workspace's are, drawn for real)."""
    root = tmp_path_factory.mktemp("cols")
    with pytest.MonkeyPatch.context() as m:
        skip_pictures(m, "ranges")
        run_pipeline(load_pipeline(project(root, STANDIN, "cols")))
    return root / "outputs" / "cols"


def test_each_column_writes_its_folder_and_names_itself(cols_run):
    out = cols_run
    pred = json.loads((out / "workspace" / "workspace.json").read_text())
    rep = json.loads((out / "workspace" / "reproduction" / "workspace.json").read_text())
    assert pred["column"] == "prediction" and rep["column"] == "reproduction"
    # the paper's protocol: no strain stop in the reproduction, whatever the prediction's
    assert pred["stop_beyond_strain"] is True and rep["stop_beyond_strain"] is False
    for f in ("workspace.csv", "workspace.vtp", "workspace.png"):
        assert (out / "workspace" / "reproduction" / f).stat().st_size > 0
    # a study run for the reproduction alone writes it into the stage's own folder
    assert json.loads((out / "ranges" / "ranges.json").read_text())["column"] == "reproduction"
    # only the reproduction's units stay (a rerun after another cell reuses them)
    assert sorted(d.name for d in out.glob(".*.units")) == [".ranges.units", ".workspace-reproduction.units"]
    report = (out / "report" / "report.md").read_text()
    section = report.split("## The paper, reproduced and predicted")[1].split("\n## ")[0]
    row = next(line for line in section.splitlines() if line.startswith("| workspace |"))
    n3 = rep["counts"].get("3 rotations", 0)
    assert f"{n3} of {rep['reachable']} reachable points pass all three rotations" in row
    verdict = row.strip().strip("|").split("|")[-1].strip()
    near, at_rest = rep["near_rest"], rep["rest_rotations"]["ok"]
    held = all(at_rest.values()) and near["reachable"] > 0 and near["full_control"] > near["reachable"] / 2
    assert verdict == ("reproduced" if held else "not reproduced")
    assert "| ranges |" in section and "| not run |" in section  # ranges ran the reproduction alone
    assert (out / "report" / "workspace_reproduction.png").stat().st_size > 0
    timings = json.loads((out / "workspace" / "manifest.json").read_text())["timings_s"]
    assert {"prediction", "reproduction"} <= set(timings)  # each column's time, not the last one's alone


@pytest.mark.parametrize("extra, match", [
    ('columns = ["prediction", "prediction"]', "a column at most once"),
    ('columns = []', "columns"),
    ('reproduction = { n_steps = 0 }', r"reproduction\.n_steps"),
    ('reproduction = { no_such_key = 1 }', "no_such_key"),
    ('reproduction = { columns = ["prediction"] }', "columns"),
])
def test_bad_column_settings_name_the_field(tmp_path, extra, match):
    text = f'[pipeline]\nname = "bad"\nstages = ["workspace"]\n[workspace]\nmodel = "standin"\n{extra}\n'
    with pytest.raises(ConfigError, match=match):
        load_pipeline(project(tmp_path, text, "bad"))


ROBOT = """[pipeline]
name = "rc"
stages = ["material", "orient", "anisotropy"]
[material]
source = "config"
E_l = 0.3                          # not the published set: the columns must differ
model = "ours"
[orient]
mesh_size = 16
element = "p1"
[anisotropy]
model = "robot"
n_alpha = 2
compare_models = false
columns = ["prediction", "reproduction"]
"""


@pytest.mark.slow
def test_the_reproduction_robot_is_the_published_foam_under_the_authors_force_field(tmp_path):
    """Default-selection sibling: test_the_reproduction_robot_on_coarse_sheets."""
    _reproduction_robot(tmp_path, ROBOT)


def test_the_reproduction_robot_on_coarse_sheets(tmp_path, monkeypatch):
    """The slow test's checks with both columns on orient's 20 mm sheets (the reproduction's
    mesh overridden: not the authors' 5 mm); orient's and the sweeps' pictures skipped (not read
    here; :func:`test_studies_stages.skip_pictures`)."""
    calls = skip_pictures(monkeypatch, "orient", "anisotropy")
    text = ROBOT.replace("mesh_size = 16", "mesh_size = 20") + "reproduction = { mesh_size = 20.0 }\n"
    _reproduction_robot(tmp_path, text)
    assert calls == ["orient", "anisotropy", "anisotropy"]  # a sweep per column


def _reproduction_robot(tmp_path, text):
    from metasheet.published import paper
    from metasheet.pipeline.stages._studies import build_spec
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages.anisotropy import AnisotropyParams

    run_pipeline(load_pipeline(project(tmp_path, text, "rc")))
    out = tmp_path / "outputs" / "rc"
    inputs = {"orient": out / "orient", "material": out / "material"}
    p = AnisotropyParams(model="robot")
    pred = build_spec(StageContext("anisotropy", p, tmp_path, inputs, tmp_path))
    rep = build_spec(StageContext("anisotropy", p, tmp_path, inputs, tmp_path, column="reproduction"))
    assert pred.model == "ours" and pred.design[1] == pytest.approx(0.3)
    assert rep.model == "authors" and rep.design == pytest.approx(paper.PAPER_FOAM.as_tuple())
    a = json.loads((out / "anisotropy" / "anisotropy.json").read_text())
    b = json.loads((out / "anisotropy" / "reproduction" / "anisotropy.json").read_text())
    assert a["column"] == "prediction" and b["column"] == "reproduction"
    assert "published_end_point" in a and "published_end_point" not in b  # the reproduction is the published set
    # the published foam (alpha 93 %) turns the rod further than the stiffer E_l = 0.3 (alpha 78 %)
    assert abs(b["rod_rotation_deg"]["push"][-1]) > abs(a["rod_rotation_deg"]["push"][-1])


REDUCED = """[pipeline]
name = "rr"
stages = ["material", "orient", "reduce", "workspace", "report"]
[material]
source = "config"
[orient]
mesh_size = 16
element = "p1"
[reduce]
snapshots = 8
held_out = 2
adapt_rounds = 1  # the columns' bases, not their certificates (tests/test_reduce_adapt.py)
surface_equilibria = 16
surface_check = 8
columns = ["prediction", "reproduction"]
reproduction = { box_deg = 12.0 }
[workspace]
model = "reduced"
columns = ["prediction", "reproduction"]
rotations = false
continuity = false
certify = 0
n_azimuth = 3
n_elevation = 1
n_steps = 3
extent_axial = 4
extent_lateral = 4
"""


@pytest.mark.slow
def test_the_reduce_stage_trains_one_basis_per_column_and_each_study_column_runs_on_its_own(tmp_path):
    """Default-selection sibling: test_one_basis_per_column_on_coarse_sheets."""
    tets = _one_basis_per_column(tmp_path, REDUCED)
    assert tets[1] > 2 * tets[0]  # the reproduction on the authors' mesh kind: P1, 5 mm (orient's: 16 mm)


def test_one_basis_per_column_on_coarse_sheets(tmp_path, monkeypatch):
    """The slow test's pipeline and checks with the reproduction column on 12 mm sheets (not
    the authors' 5 mm: its own mesh all the same) and the prediction on orient's 20 mm; 4
    training snapshots a column (the least allowed), one held-out pose, 4 surface checks; the
    prediction trained on rest +- 10 deg (a box 20 deg wide: the check that the reproduction's
    box, 24 deg, is its own then tells the two apart; the study's motors stay inside it); the
    element sample fitted to 0.1 mm and 5 % instead of 0.02 mm and 1 % (its halvings were two
    thirds of the time, and the held-out worst position error stays what the 4-snapshot basis
    makes it: 0.37 mm against 0.39 at the tighter targets). The full model still certifies every
    reachable point of both columns within the study's 1 mm. Orient's and the workspace's
    pictures are skipped (not read here)."""
    calls = skip_pictures(monkeypatch, "orient", "workspace")
    text = REDUCED.replace("mesh_size = 16", "mesh_size = 20").replace(
        "reproduction = { box_deg = 12.0 }", "reproduction = { box_deg = 12.0, mesh_size = 12.0 }").replace(
        "extent_lateral = 4\n", "extent_lateral = 4\nreproduction = { mesh_size = 12.0 }\n").replace(
        "snapshots = 8\nheld_out = 2\n", "snapshots = 4\nheld_out = 1\nbox_deg = 10.0\n").replace(
        "surface_check = 8\n", "surface_check = 4\nfit_tol_mm = 0.1\nfit_jacobian_tol = 0.05\n")
    assert text.count("mesh_size = 12.0") == 2 and "box_deg = 10.0" in text and "fit_tol_mm = 0.1" in text
    tets = _one_basis_per_column(tmp_path, text)
    assert calls == ["orient", "workspace", "workspace"]
    assert tets[1] > tets[0]  # the reproduction on its own, finer mesh


def _one_basis_per_column(tmp_path, text):
    from metasheet.pipeline.stages._studies import basis_file
    from metasheet.rom.coordinates import ReducedBasis

    run_pipeline(load_pipeline(project(tmp_path, text, "rr")))
    out = tmp_path / "outputs" / "rr"
    pred, rep = basis_file(out / "reduce", "prediction", "k"), basis_file(out / "reduce", "reproduction", "k")
    assert pred == out / "reduce" / "basis.npz" and rep == out / "reduce" / "reproduction" / "basis.npz"
    a, b = ReducedBasis.load(pred), ReducedBasis.load(rep)
    assert a.robot_key != b.robot_key  # another material model: another robot
    assert json.loads((out / "reduce" / "reproduction" / "reduce.json").read_text())["column"] == "reproduction"
    box = json.loads((out / "reduce" / "reproduction" / "reduce.json").read_text())["box_deg"]
    assert max(h - lo for lo, h in zip(*box)) > 20.0  # the reproduction's own (wider) box
    for folder, col, basis in ((out / "workspace", "prediction", a), (out / "workspace" / "reproduction",
                                                                       "reproduction", b)):
        w = json.loads((folder / "workspace.json").read_text())
        assert w["column"] == col and w["model_info"]["robot_key"] == basis.robot_key
        # the full model of the column's own robot agrees with every reachable point of its basis
        cert = w["certification"]
        assert cert["certified"] == w["reachable"] > 0 and cert["disagree"] == 0
    tets = [json.loads((f / "workspace.json").read_text())["n_tets_per_sheet"]
            for f in (out / "workspace", out / "workspace" / "reproduction")]
    report = (out / "report" / "report.md").read_text()
    assert report.count("## Reduced-order robot") == 2 and "the reproduction column's basis" in report
    return tets


def test_rest_rotations_are_the_papers_test_at_rest(cols_run):
    w = json.loads((cols_run / "workspace" / "workspace.json").read_text())
    t = w["rest_rotations"]
    assert t["rot_deg"] == 10.0 and t["tol_rot_deg"] == 2.0
    for axis in "xyz":
        errs = [(t["error_mm"][s + axis], t["error_deg"][s + axis]) for s in "+-"]
        within = all(mm is not None and mm <= t["tol_mm"] and deg <= t["tol_rot_deg"] for mm, deg in errs)
        assert t["ok"][axis] == within


def test_scene_facts_section_judges_each_fact_from_the_numbers():
    from metasheet.report.columns import scene_facts_section

    scene = {"name": "authors", "values": {"angle_min": 0.0, "angle_max": 90.0}}
    robot = {"rest_angles_deg": [73.3] * 6}
    errs = {k: 1.5 for k in ("+x", "-x", "+y", "-y", "+z", "-z")}
    ws = {"rest_rotations": {"ok": {"x": True, "y": True, "z": False}, "error_deg": errs, "error_mm": errs}}
    ranges = {"reachable": {"0-90": 30, "10-80": 20, "20-70": 10}, "nested": True}
    maze = {"segments": 4, "foam_impossible_segments": [], "silicone_impossible_segments": [2], "tilt_deg": 5.0}
    cols = {"workspace": {"reproduction": ws}, "ranges": {"reproduction": ranges}, "maze": {"reproduction": maze}}
    rows = [line for line in scene_facts_section(scene, robot, cols) if line.startswith("| (")]
    holds = [line.rstrip(" |").rsplit("|", 1)[1].strip() for line in rows]
    # (i) 0-90; (ii) room 16.7 / 73.3; (iii) z failed; (iv) nested and shrinking; (v) foam solves, silicone not
    assert holds == ["yes", "yes", "no", "yes", "yes"]
    robot_far = {"rest_angles_deg": [80.0] * 6}  # 10 deg of pull room only
    rows = [line for line in scene_facts_section(scene, robot_far, {}) if line.startswith("| (")]
    assert [line.rstrip(" |").rsplit("|", 1)[1].strip() for line in rows] == ["yes", "no", "-", "-", "-"]


def test_near_rest_control_counts_the_reachable_points_within_the_radius():
    from metasheet.studies.workspace import near_rest_control

    goals = [[1, 0, 0], [0, 2, 0], [0, 0, 2.9], [3.1, 0, 0], [0, 1, 0], [0, 0, 0.5]]
    cls = [3, 3, 1, 3, 3, 0]
    reached = [True, True, True, True, True, False]  # the last is within the radius but unreachable
    got = near_rest_control(goals, cls, reached, [0, 0, 0], 3.0)
    assert got == {"radius_mm": 3.0, "reachable": 4, "full_control": 3, "share": 0.75}
    assert near_rest_control(goals, cls, reached, [10, 10, 10], 3.0)["share"] is None


@pytest.mark.parametrize("rest_ok, full, verdict", [
    ({"x": True, "y": True, "z": True}, 46, "reproduced"),
    ({"x": True, "y": True, "z": True}, 31, "not reproduced"),   # half of them: not "a whole area"
    ({"x": True, "y": False, "z": True}, 62, "not reproduced"),  # the rest pose itself fails one axis
])
def test_the_fig5_verdict_needs_the_rest_pose_and_most_points_near_it(rest_ok, full, verdict):
    from metasheet.report.columns import columns_section

    ws = {"counts": {"3 rotations": 47}, "reachable": 609, "rest_rotations": {"ok": rest_ok},
          "near_rest": {"radius_mm": 3.0, "reachable": 62, "full_control": full, "share": full / 62}}
    row = next(line for line in columns_section({"workspace": {"reproduction": ws}}, {})
               if line.startswith("| workspace |"))
    assert f"within 3 mm of rest {full} of 62 reachable points do" in row
    assert row.strip().strip("|").split("|")[-1].strip() == verdict
