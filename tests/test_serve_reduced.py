"""metasheet serve and robot goto on the reduced model (issue 16), without a browser.

The reduced robot is the reduce stage's own (its ``run`` on the serve tests' coarse
outputs: 8 training equilibria in the box rest +- 8 deg, a loose element sample, ~5 CPU s:
:func:`_reduce`), so these tests also check that the stage trains on the robot serve builds.
Independent answers: the full model's ``goto`` and ``solve_equilibrium``; the tolerances are
the reduced model's errors on this coarse basis, measured (at GOAL_IN: 0.07 deg of motor angle
reduced, 0.13 deg the surface; 0.025 mm of effector position, 0.027 mm of any node, in the box)
with a margin of two or more.
"""

import json
import shutil

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.robot.inverse import InverseController
from metasheet.rom.coordinates import robot_key
from metasheet.rom.model import ReducedRobot
from metasheet.serve.loading import find_outputs, load_robot
from metasheet.serve.models import OUTSIDE_BOX
from metasheet.serve.panel import status_markdown
from metasheet.serve.session import Session

from serve_outputs import REDUCE_PIPELINE, live_page, write_outputs

GOAL_IN = [0.0, 1.5, 0.0, 2.0, 0.0, 0.0]  # motors 53-62 deg: inside the box 52-68 deg
GOAL_OUT = [1.0, 1.0, -1.0, 0.0, 3.0, 0.0]  # needs motor 4 at ~48.5 deg: outside it
ANGLE_TOL = 0.3  # [deg] reduced against full motor angles for one goal
POS_TOL = 0.1  # [mm] reduced against full effector position at the same motor angles


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    root = tmp_path_factory.mktemp("serve_reduced")
    toml, out = write_outputs(root, pipeline=REDUCE_PIPELINE)
    _reduce(root, out)
    return find_outputs(toml, out)


#: the reduce stage's settings for a basis these tests serve, not certify (tests/test_reduce_adapt.py
#: certifies one): serve_outputs.write_reduce's (8 snapshots, rest +- 8 deg, 1 held-out pose, one
#: round) with the element sample fitted on 4 snapshots from a first ECSW tolerance of 4e-3 (352 of
#: 2,356 elements, not 840 after four halvings) and the smallest surface: half the CPU (4.9 s, not 9.6)
CHEAP_REDUCE = {"snapshots": 8, "box_deg": 8.0, "held_out": 1, "adapt_rounds": 1, "ecsw_tol": 4e-3,
                "ecsw_snapshots": 4, "fit_tol_mm": 0.1, "fit_jacobian_tol": 0.05, "surface_equilibria": 16,
                "surface_check": 8}


def _reduce(root, out):
    """The reduce stage itself on ``out/tiny`` with :data:`CHEAP_REDUCE`: ``out/tiny/reduce/``."""
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages import reduce as stage

    base = out / "tiny"
    (base / "reduce").mkdir()
    inputs = {name: base / name for name in ("orient", "material", "robot")}
    stage.run(StageContext("reduce", stage.ReduceParams(resume=False, **CHEAP_REDUCE), base / "reduce", inputs, root))


@pytest.fixture(scope="module")
def build(outputs):
    cache = {}

    def get(material, model="reduced"):
        if (material, model) not in cache:
            cache[material, model] = load_robot(outputs, model, material)
        return cache[material, model]

    return get


@pytest.fixture
def session(build):
    s = Session(build)
    s.start()
    published = []
    publish = s._publish

    def record(*a, **k):  # every snapshot the session publishes, not only those a reader sees
        publish(*a, **k)
        published.append(s._snap)

    s._publish = record
    s.published = published
    yield s
    s.stop()


def _in_box(red, snap) -> bool:
    return red.in_box(np.radians(snap.angles_deg), tol=1e-9)


@pytest.mark.slow
def test_the_reduce_stages_basis_fits_the_robot_serve_builds(build):
    """Default-selection siblings: test_reduced_session_reports_the_full_models_motor_angles
    (the basis's robot key is the full robot's) and test_silicone_runs_on_the_full_model_with_a_note."""
    red, info = build("foam")
    full, _ = build("foam", "full")
    assert isinstance(red, ReducedRobot) and red.basis.robot_key == robot_key(full)
    assert info.model == "reduced" and f"{red.basis.k} modes" in info.description and info.note == ""
    assert "; certificate " in info.description and "held-out errors" in info.description and " up to " in info.description  # reduce.json's
    sil, sinfo = build("silicone")
    assert not isinstance(sil, ReducedRobot) and sinfo.model == "full" and "does not fit silicone" in sinfo.note


def test_a_basis_of_another_robot_is_a_clear_error(outputs, tmp_path):
    d = tmp_path / "tiny"
    shutil.copytree(outputs.directory, d)
    jac = d / "robot" / "jacobian.json"
    data = json.loads(jac.read_text())
    data["geometry"]["rod_length_mm"] = 70.0  # the robot stage ran again with another rod
    jac.write_text(json.dumps(data))
    moved = type(outputs)(d, outputs.run_command, outputs.silicone, outputs.stages)
    with pytest.raises(ConfigError, match=r"basis.npz was trained on another robot .* or use --model full") as err:
        load_robot(moved, "reduced")
    assert "\n" not in str(err.value) and outputs.run_command in str(err.value)
    assert load_robot(moved, "full")[0].coupling is not None  # the full model still loads


def test_reduced_session_reports_the_full_models_motor_angles(session, build):
    red, full = build("foam")[0], build("foam", "full")[0]
    assert isinstance(red, ReducedRobot) and red.basis.robot_key == robot_key(full)  # the stage's basis fits
    session.set_goal(GOAL_IN)
    snap = session.wait_idle(60)
    assert snap.status == "reached" and snap.model == "reduced" and snap.note == "", snap.message
    assert all(s.model == "reduced" for s in session.published)  # never left the box
    ref = InverseController(full).goto(GOAL_IN)
    assert ref.reached
    np.testing.assert_allclose(snap.angles_deg, ref.angles_deg, atol=ANGLE_TOL)
    # what the page draws: the full mesh at the reduced state, against the full equilibrium there
    eq = solve_equilibrium(full, np.radians(snap.angles_deg)).state
    np.testing.assert_allclose(snap.x, red.positions(snap.state))
    assert np.linalg.norm(snap.state.p - eq.p) < POS_TOL and np.abs(snap.x - eq.x).max() < 2 * POS_TOL


def test_out_of_box_goal_falls_back_to_the_full_model_and_says_so(session, build):
    red, full = build("foam")[0], build("foam", "full")[0]
    session.set_goal(GOAL_OUT)
    snap = session.wait_idle(60)
    assert snap.status == "reached" and snap.model == "full" and snap.note == OUTSIDE_BOX, snap.message
    assert not _in_box(red, snap) and hasattr(snap.state, "x")  # a full state, outside the box
    # no reduced state was ever shown outside the box
    assert all(_in_box(red, s) for s in session.published if s.model == "reduced")
    assert any("leaves the reduced model's training box" in s.message for s in session.published)
    ref = InverseController(full).goto(GOAL_OUT)
    np.testing.assert_allclose(snap.angles_deg, ref.angles_deg, atol=0.5)  # two full solves, two step paths
    text = status_markdown(snap, strain_max=0.1, strain_limit=0.3, rate=5.0, model="reduced")
    assert "model: full" in text and f"**{OUTSIDE_BOX}**" in text
    # forward model outside the box: the full equilibrium, flagged
    out = [50.0, 62.0, 58.0, 61.0, 55.0, 66.0]
    session.set_motors(out)
    snap = session.wait_idle(60)
    assert snap.model == "full" and snap.note == OUTSIDE_BOX
    np.testing.assert_allclose(snap.state.p, solve_equilibrium(full, np.radians(out)).state.p, atol=1e-3)
    # back inside: the reduced model again, close to the full one
    inside = [56.0, 64.0, 60.0, 60.0, 62.0, 58.0]
    session.set_motors(inside)
    snap = session.wait_idle(60)
    assert snap.model == "reduced" and snap.note == "" and _in_box(red, snap)
    assert np.linalg.norm(snap.state.p - solve_equilibrium(full, np.radians(inside)).state.p) < POS_TOL


def test_silicone_runs_on_the_full_model_with_a_note(session):
    foam = session.snapshot()
    session.set_material("silicone")
    snap = session.wait_idle(60)
    assert snap.material == "silicone" and snap.model == "full" and "does not fit silicone" in snap.note
    np.testing.assert_allclose(snap.angles_deg, foam.angles_deg, atol=1e-9)
    session.set_material("foam")
    snap = session.wait_idle(60)
    assert snap.model == "reduced" and snap.note == ""


def _goto(capsys, outputs, model, goal):

    from metasheet.cli import main

    args = ["robot", "goto", "--pipeline", str(outputs.directory.parent.parent / "tiny.toml"),
            "--out", str(outputs.directory.parent), "--model", model, "--", *[f"{v:g}" for v in goal]]
    with pytest.raises(SystemExit) as exc:
        main(args)
    out, err = capsys.readouterr()
    assert exc.value.code in (0, None), out + err
    angles = np.array(next(line for line in out.splitlines() if line.startswith("motor angles")).split(":")[1].split(),
                      float)
    return out, angles


def test_robot_goto_reduced_matches_full(outputs, capsys):
    out_f, full = _goto(capsys, outputs, "full", GOAL_IN)
    out_r, red = _goto(capsys, outputs, "reduced", GOAL_IN)
    head = "; prediction, tolerance 0.1 mm, 0.2 deg\n"  # the first line names the model, column and tolerance
    assert out_f.startswith("model: full" + head) and out_r.startswith("model: reduced" + head)
    np.testing.assert_allclose(red, full, atol=ANGLE_TOL)
    # outside the box: the full model's own answer, said so
    out_o, beyond = _goto(capsys, outputs, "reduced", GOAL_OUT)
    _, beyond_full = _goto(capsys, outputs, "full", GOAL_OUT)
    assert out_o.startswith(f"model: full ({OUTSIDE_BOX})")
    np.testing.assert_array_equal(beyond, beyond_full)


def test_page_draws_reduced_states_and_the_flag(session, outputs):
    """The page on a real (browserless) viser server draws the full mesh at a reduced state."""
    from metasheet.serve.app import SCALE

    with live_page(session, outputs, "reduced") as page:
        session.set_goal(GOAL_IN)
        snap = session.wait_idle(60)
        wait_until(lambda: page.drawn == snap.version)
        assert snap.model == "reduced" and "model: reduced" in page.status.content
        np.testing.assert_allclose(page.effector.position, snap.state.p * SCALE, atol=1e-9)
        np.testing.assert_allclose(page.horns.points, scene_horns(session, snap) * SCALE, atol=1e-9)
        session.set_motors([50.0, 62.0, 58.0, 61.0, 55.0, 66.0])
        snap = session.wait_idle(60)
        wait_until(lambda: page.drawn == snap.version)
        assert f"**{OUTSIDE_BOX}**" in page.status.content and "model: full" in page.status.content


def wait_until(predicate, timeout=20.0):
    import time

    deadline = time.time() + timeout
    while not predicate():
        assert time.time() < deadline, "not within the timeout"
        time.sleep(0.02)


def scene_horns(session, snap):
    from metasheet.serve import scene

    return scene.horn_segments(session.robot_of(snap.material)[1].geometry, snap.x)


def test_robot_goto_surface_matches_full(outputs, capsys):
    """The reduce stage's equilibrium surface drives ``robot goto`` (the real-time model):
    same motor angles as the full model within the reduced model's tolerance; outside the
    box the full model's own answer, said so."""
    _, full = _goto(capsys, outputs, "full", GOAL_IN)
    out_s, surf = _goto(capsys, outputs, "surface", GOAL_IN)
    assert out_s.startswith("model: surface; prediction, tolerance 0.1 mm, 0.2 deg\n")
    np.testing.assert_allclose(surf, full, atol=ANGLE_TOL)
    out_o, beyond = _goto(capsys, outputs, "surface", GOAL_OUT)
    _, beyond_full = _goto(capsys, outputs, "full", GOAL_OUT)
    assert out_o.startswith(f"model: full ({OUTSIDE_BOX})")
    np.testing.assert_array_equal(beyond, beyond_full)


def test_surface_model_names_its_fit_and_certificate(build):
    surf, info = build("foam", "surface")
    assert info.model == "surface" and "equilibrium surface: degree " in info.description
    assert "; certificate " in info.description  # reduce.json's surface section
    with pytest.raises(ConfigError, match="the surface holds within its box"):
        surf.equilibrium(np.radians([40.0] * 6))
