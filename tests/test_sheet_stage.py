"""The ``sheet`` stage end to end on a small sheet (cell -> ... -> robot -> sheet -> report), and
``[material] source = "sheet"`` driving the robot with its apparent constants.

The sheet is a 10 mm-wide tripod reaching 20 mm, 2 mm thick, printed with a 0.8 mm bead at
0.5 mm voxels (seconds); the physics of the DNS is validated in tests/test_sheet_dns.py.

The upstream stages leave out what the sheet stage does not read (the cell's surface and
picture, the homogenisation's fields and picture: a fifth of the run; their own tests check
them); the sheet stage itself runs whole.
"""

import json

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline
from metasheet.studies.grid import star_grid

DESIGN = """
kind = "polyfoam"
name = "small_polyfoam"
infill_percentage = 30.0
kgon_x_shrink = 0.5
bead_width = 0.8
voxel_mm = 0.5
[seeds]
sampler = "poisson"
count = 4
seed = 1
[material]
name = "TPU"
E = 12.0
nu = 0.3
"""

SHEET = """
[orient]
scene = "metasheet"
arm_width = 10.0
reach = 20.0
thickness = 2.0
hole_radius = 1.0
fillet_radius = 1.0
tip_box = [5.0, 15.0, 10.0]
centre_radius = 3.0
mesh_size = 4.0
element = "p1"
picture = false
"""

ROBOT = """
[robot]
compare_published = false
compare_models = false
uncertainty = false
picture = false
"""

PIPELINE = """
[pipeline]
name = "s"
stages = ["cell", "homogenize", "material", "orient", "printmap", "robot", "sheet", "printed", "report"]

[cell]
design = "{design}"
surface = false
picture = false

[homogenize]
picture = false
fields = false
plate_thickness = 2.0
plate_slabs = 2

[printmap]
picture = false

[material]
source = "homogenize"
{sheet}
{robot}
[sheet]
voxel_mm = 0.5
realisations = 2

[printed]
map_rays = true
n_azimuth = 4
n_elevation = 1
n_steps = 4
extent_mm = 6.0
ranges = [[0.0, 90.0], [10.0, 80.0]]
ladder = [0.7, 0.6]
other_gauge = true
"""

APPARENT = """
[pipeline]
name = "a"
stages = {stages}

[material]
source = "sheet"
sheet_file = "{sheet_file}"
{sheet}
{robot}"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sheet")
    (tmp / "design.toml").write_text(DESIGN)
    f = tmp / "p.toml"
    f.write_text(PIPELINE.format(design=tmp / "design.toml", sheet=SHEET, robot=ROBOT))
    run_pipeline(load_pipeline(f), out_root=tmp / "out")
    return tmp, tmp / "out" / "s"


def test_stage_writes_the_comparison_and_the_report(run):
    _, out = run
    d = json.loads((out / "sheet" / "sheet_dns.json").read_text())
    assert d["seeds"] == [1, 2] and len(d["realisations"]) == 2
    for row in d["realisations"]:
        for label in ("normal", "mirrored"):
            s = row["sheets"][label]
            assert len(s["eigen_ratios"]) == 18 and min(s["eigen_ratios"]) > 0
            assert s["kept_share"] > 0.9 and s["n_dof"] > 0
        assert np.isfinite(row["robot"]["rod_rotation_deg_per_deg"])
        assert row["apparent"]["rms_log_ratio"] >= 0
    assert d["verdict"].startswith(("agrees", "differs"))
    sp = d["spread"]["rod_rotation_deg_per_deg"]
    assert sp["min"] <= sp["mean"] <= sp["max"] and sp["std"] is not None
    for f in ("sheet_normal.npz", "printed_sheet.png", "sheet_dns.png"):
        assert (out / "sheet" / f).stat().st_size > 0
    report = (out / "report" / "report.md").read_text()
    assert "The printed sheet against the homogenised sheet" in report and d["verdict"] in report
    # ``picture = false`` in [orient] and [printmap]: the stages complete without their pictures
    for stage, png in (("orient", "sheet.png"), ("printmap", "printmap.png")):
        assert (out / stage / "manifest.json").is_file() and not (out / stage / png).exists()


def test_homogenised_robot_matches_the_robot_stage(run):
    """The condensed homogenised robot (linear, no gravity) against the robot stage's own rest
    Jacobian (corotational FEM, with the sheets' weight): the same rod roll within the sag's effect
    (0.36 % on this small, light sheet; 1e-5 on the paper's robot: -2.81209 against -2.812)."""
    _, out = run
    d = json.loads((out / "sheet" / "sheet_dns.json").read_text())
    jac = json.loads((out / "robot" / "jacobian.json").read_text())
    foam = jac["materials"]["foam"]
    roll = sum(foam["per_degree_mm_or_deg"][3 + 0][k] for k in range(6))  # about the rod (world x)
    assert d["homogenised_robot"]["rod_rotation_deg_per_deg"] == pytest.approx(roll, rel=1e-2)


@pytest.mark.parametrize("robot", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_material_source_sheet_drives_the_robot(run, tmp_path, robot):
    """The material stage takes the sheet's apparent constants (their mean over the realisations).
    The slow case runs orient and the robot on them too (5 s: orient and its picture again; the
    robot stage reads any material the same way); its default-selection sibling is the case
    without them (robot = False)."""
    _, out = run
    f = tmp_path / "a.toml"
    stages = '["material", "orient", "robot"]' if robot else '["material"]'
    f.write_text(APPARENT.format(stages=stages, sheet_file=out / "sheet" / "sheet_dns.json", sheet=SHEET,
                                 robot=ROBOT))
    run_pipeline(load_pipeline(f), out_root=tmp_path / "out")
    m = json.loads((tmp_path / "out" / "a" / "material" / "material.json").read_text())
    app = json.loads((out / "sheet" / "sheet_dns.json").read_text())["spread"]["apparent"]
    assert m["source"] == "sheet"
    for k, v in app.items():
        assert m["constants"][k] == pytest.approx(v["mean"], rel=1e-12)
    assert (tmp_path / "out" / "a" / "robot" / "jacobian.json").exists() == robot


def test_bad_sheet_settings_are_named(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(APPARENT.format(stages='["material"]', sheet_file="", sheet=SHEET, robot=ROBOT)
                 .replace('sheet_file = ""\n', ""))
    with pytest.raises(ConfigError, match="sheet_file"):
        load_pipeline(f)
    bad = PIPELINE.format(design="x.toml", sheet=SHEET, robot=ROBOT)
    f.write_text(bad.replace("realisations = 2", "realisations = 0"))
    with pytest.raises(ConfigError, match="realisations"):
        load_pipeline(f)


@pytest.mark.slow
@pytest.mark.bytes
def test_two_workers_give_the_same_bytes(run):
    """Each sheet of each realisation is a work unit: on a pool of two the stage writes the serial
    run's sheet_dns.json and voxel file, byte for byte (wall times live in the manifest only);
    the printed stage's walls' units and studies too (printed.json).
    Default-selection sibling: test_stage_writes_the_comparison_and_the_report (the serial run;
    no cheaper pool-of-two run exists yet: the stage's whole pipeline is the cost)."""
    from metasheet.runtime.executor import Executor

    tmp, out = run
    names = ("sheet_dns.json", "sheet_normal.npz")
    serial = {name: (out / "sheet" / name).read_bytes() for name in names}
    printed = (out / "printed" / "printed.json").read_bytes()
    run_pipeline(load_pipeline(tmp / "p.toml"), out_root=tmp / "out", only="printed", force=True,
                 executor=Executor(workers=2))  # the sheet stage too (printed needs it), then the printed
    for name in names:
        assert (out / "sheet" / name).read_bytes() == serial[name]
    assert (out / "printed" / "printed.json").read_bytes() == printed  # the walls' units on the pool


@pytest.mark.slow
def test_the_printed_stage_takes_the_walls_the_sheet_stage_kept(run, tmp_path):
    """``sheet.walls``: the sheet stage keeps each print's walls' fields and the printed stage's walls'
    units take them instead of solving each sheet again: the same sheet_dns.json and printed.json,
    byte for byte (the units solve the same relative columns and round them alike).
    Default-selection sibling: tests/test_wall_fields.py (the fields against all 24 solved)."""
    import shutil

    tmp, out = run
    shutil.copytree(tmp / "out", tmp_path / "out")
    f = tmp_path / "p.toml"
    f.write_text((tmp / "p.toml").read_text().replace("[sheet]\n", "[sheet]\nwalls = true\n"))
    run_pipeline(load_pipeline(f), out_root=tmp_path / "out", only="printed")
    kept = tmp_path / "out" / "s"
    assert sorted(p.name for p in (kept / "sheet" / "walls").iterdir()) == sorted(
        f"{lab}-seed{k}.npz" for k in (1, 2) for lab in ("mirrored", "normal"))
    for name in ("sheet/sheet_dns.json", "printed/printed.json"):
        assert (kept / name).read_bytes() == (out / name).read_bytes(), name


def test_stage_compares_the_prints_with_the_plate_continuum(run):
    _, out = run
    d = json.loads((out / "sheet" / "sheet_dns.json").read_text())
    plate = json.loads((out / "homogenize" / "plate.json").read_text())
    assert d["plate"]["thickness_mm"] == pytest.approx(plate["thickness_mm"]) == pytest.approx(2.0, rel=0.01)
    for variant in ("membrane", "bending"):
        v = d["plate"][variant]
        assert all(v["constants"][k] > 0 for k in ("E_t", "E_l", "mu_l"))
        for row, dns in zip(v["realisations"], d["realisations"]):
            # the roll ratio is the prints' roll over the plate continuum's, as written
            assert row["rod_roll_ratio"] * v["robot"]["rod_rotation_deg_per_deg"] == pytest.approx(
                dns["robot"]["rod_rotation_deg_per_deg"], rel=1e-12)
            assert row["geometric_mean_ratio_normal"] > 0 and row["log_ratio_rms_normal"] >= 0
    # the plate's membrane constants are not the bulk's (the faces cut the cells)
    assert d["plate"]["membrane"]["constants"] != d["material"]["constants"]
    report = (out / "report" / "report.md").read_text()
    gm = d["plate"]["membrane"]["spread"]["geometric_mean_ratio_normal"]["mean"]
    assert "| the plate's membrane moduli |" in report and f"{gm:.3g}" in report


def test_the_printed_robot_stage_states_each_claim_from_its_prints(run):
    """The ``printed`` stage on the same prints: the walls' limit is the first contact over the
    directions searched, the superelement robot's rest roll is the sheet stage's linear one (two
    codes: the condensed Schur complement and the superelement's differenced energy), each status
    follows its numbers, and the report states the claims."""
    _, out = run
    d = json.loads((out / "printed" / "printed.json").read_text())
    dns = json.loads((out / "sheet" / "sheet_dns.json").read_text())
    assert d["seeds"] == dns["seeds"] and len(d["realisations"]) == 2
    for r, row in zip(d["realisations"], dns["realisations"]):
        lim = r["limits"]
        found = [v["contact_deg"] for v in lim["directions"].values() if v["contact_deg"] is not None]
        assert lim["valid_deg"] == min(found) and lim["directions"][lim["binding"]]["contact_deg"] == lim["valid_deg"]
        assert len(lim["strain_per_deg"]) == 6 and min(min(s) for s in lim["strain_per_deg"]) >= 0
        # the validity map: 16 directions around the plane of the common modes, the rays of the study's grid
        vm = r["map"]
        assert len(vm["plane"]) == 16 and {x["name"] for x in vm["plane"]} >= {"roll up", "roll down", "A up"}
        grid_rays = star_grid(n_azimuth=4, n_elevation=1, n_steps=4, extent_axial=6.0, extent_lateral=6.0).directions
        assert len(vm["rays"]) == len(grid_rays)
        for x, e in zip(vm["rays"], grid_rays):
            assert x["direction"] == pytest.approx(e.tolist()) and x["mm_per_deg"] > 0
            assert x["contact_deg"] == lim["directions"][x["name"]]["contact_deg"]
            if x["contact_deg"] is not None:
                assert x["contact_mm"] == pytest.approx(x["contact_deg"] * x["mm_per_deg"], rel=1e-12)
                assert x["contact_deg"] >= lim["valid_deg"]
        for x in vm["plane"] + vm["rays"]:
            c, s_ = (np.inf if v is None else v for v in (x["contact_deg"], x["strain_deg"]))
            assert x["binds"] == (None if c == s_ == np.inf else ("contact" if c <= s_ else "strain"))
        rot = r["rotations"]
        assert rot["rest_rod_roll_deg_per_deg"] == pytest.approx(row["robot"]["rod_rotation_deg_per_deg"], rel=1e-6)
        roll = r["roll"]
        at = roll["rod_rotation_within_limits_deg"]
        rolled = at["pull"] * at["push"] < 0 and min(abs(at["pull"]), abs(at["push"])) >= 1.0
        assert (roll["status"] != "not predicted") == rolled
        for name in ("pull", "push"):
            path = np.asarray(roll[name]["path"])
            assert path[0].tolist() == [0.0, 0.0] and path[-1, 0] == roll[name]["travel_deg"]
        goals = rot["goals"].values()
        assert (rot["status"] == "predicted") == all(g["reached"] for g in goals)
        st = r["studies"]
        grid = star_grid(n_azimuth=4, n_elevation=1, n_steps=4, extent_axial=6.0, extent_lateral=6.0)
        assert st["workspace"]["points"] == len(grid) and st["workspace"]["left_domain"] >= 0
        assert (st["maze"]["verdict"]["status"] == "predicted") == (not st["maze"]["foam_impossible_segments"])
        assert list(st["ranges"]["reachable"]) == ["[0, 90]", "[10, 80]"]
    order = ("predicted", "predicted up to the walls' limit", "not predicted")
    for key in ("workspace", "ranges", "maze"):
        assert d["claims"][key] == max((r["studies"][key]["verdict"]["status"] for r in d["realisations"]),
                                       key=order.index)
    for key in ("roll", "rotations"):
        assert d["claims"][key] == max((r[key]["status"] for r in d["realisations"]), key=order.index)
    # the first print converged in the voxel size (0.7, 0.6 and the sheet stage's 0.5 mm) and under the other gauge
    lad = d["ladder"]
    assert [r["voxel_mm"] for r in lad["rows"]] == [0.7, 0.6, 0.5] and lad["seed"] == dns["seeds"][0]
    own = dns["realisations"][0]
    assert lad["rows"][-1]["rod_roll"] == own["robot"]["rod_rotation_deg_per_deg"]
    assert lad["rows"][-1]["geometric_mean_ratio"][0] == own["sheets"]["normal"]["geometric_mean_ratio"]
    assert set(lad["richardson"]) >= {"geometric mean, normal", "rod roll [deg/deg]"}
    for f in lad["richardson"].values():
        assert f["h"] == [0.7, 0.6, 0.5] and np.isfinite(f["limit"])
    og = d["other_gauge"]
    assert og["gauge"] == "point" and og["row"]["gauge"] == "point"
    assert og["ratio"]["rod_roll"] == pytest.approx(og["row"]["rod_roll"] / own["robot"]["rod_rotation_deg_per_deg"])
    assert (out / "printed" / "printed_robot.png").stat().st_size > 0
    report = (out / "report" / "report.md").read_text()
    assert "The printed robot against the paper's robot" in report and d["claims"]["roll"] in report
    assert "Under the other gauge (`point`" in report and "| 0.7 |" in report
    assert "rays of Fig. 5, orientation held" in report


@pytest.mark.slow
def test_the_printed_stage_searches_the_first_prints_box_again_on_the_finite_strain_robot(run, tmp_path):
    """``printed.touch = 1``: the first print's binding direction searched on the finite-strain
    voxel robot; its first touch replaces the first-order one there, the box is the first contact
    over the directions again, the other print keeps its first-order limits, and the report says
    both. Default-selection sibling: tests/test_nonlinear_touch.py (the search on a notched arm)."""
    import shutil

    tmp, out = run
    shutil.copytree(tmp / "out", tmp_path / "out")
    f = tmp_path / "p.toml"
    f.write_text((tmp / "p.toml").read_text().replace("[printed]\n", "[printed]\ntouch = 1\ntouch_tol_deg = 0.05\n"))
    run_pipeline(load_pipeline(f), out_root=tmp_path / "out", only="report")
    before = json.loads((out / "printed" / "printed.json").read_text())["realisations"]
    after = json.loads((tmp_path / "out" / "s" / "printed" / "printed.json").read_text())["realisations"]
    lim, first = after[0]["limits"], before[0]["limits"]
    t = lim["touch"]
    assert t["direction"] == first["binding"] and t["first_order_deg"] == first["valid_deg"]
    assert lim["first_order_valid_deg"] == first["valid_deg"]
    row = lim["directions"][t["direction"]]
    assert row["first_order_contact_deg"] == first["valid_deg"] and row["contact_deg"] == t["touch_deg"]
    found = [v["contact_deg"] for v in lim["directions"].values() if v["contact_deg"] is not None]
    assert lim["valid_deg"] == min(found)
    poses = lim["touch_poses"]
    assert poses and t["converged"]
    if t["touch_deg"] is not None:  # the bracket's ends on their sides of the touch
        lo, hi = t["bracket_deg"]
        d = {p["travel"]: min(p["approach_mm"]) for p in poses}
        assert d[hi] <= t["touch_mm"] < (d[lo] if lo > 0 else np.inf) and hi - lo <= 0.05
    assert after[1]["limits"] == before[1]["limits"]
    report = (tmp_path / "out" / "s" / "report" / "report.md").read_text()
    assert "the finite-strain voxel robot found" in report
