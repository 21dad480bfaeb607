"""metasheet serve without a browser: loading, the session's solver thread, the scene, the page.

The page in a real browser is tests/test_serve_browser.py (marker "system").
"""

import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.robot.inverse import InverseController
from metasheet.mechanics.rotations import rotation_vector
from metasheet.serve import scene
from metasheet.serve.app import SCALE, check_port
from metasheet.serve.loading import find_outputs, load_robot
from metasheet.serve.maze import maze_file, read_maze
from metasheet.serve.panel import RateMeter, status_markdown
from metasheet.serve.session import Session
from metasheet.serve.tracking import GoalRun

from serve_outputs import live_page, write_outputs

GOAL = [1.0, 1.0, -1.0, 0.0, 3.0, 0.0]  # reachable on the coarse robot: x, y, z [mm], rx, ry, rz [deg]
FAR = [0.0, 0.0, -3.0, 40.0, 0.0, 0.0]  # 40 deg about the rod: beyond the stroke


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    toml, out = write_outputs(tmp_path_factory.mktemp("serve"))
    return find_outputs(toml, out)


@pytest.fixture(scope="module")
def build(outputs):
    """load_robot bound to the outputs, each material built once for the module."""
    cache = {}

    def get(material):
        if material not in cache:
            cache[material] = load_robot(outputs, "full", material)
        return cache[material]

    return get


@pytest.fixture
def session(build):
    s = Session(build)
    s.start()
    yield s
    s.stop()


# -- loading ---------------------------------------------------------------------------------

def test_outputs_found_as_metasheet_run_writes_them(tmp_path):
    toml, out = write_outputs(tmp_path, pipeline='[pipeline]\nname = "tiny"\nstages = ["material", "orient", '
                              '"robot"]\n[robot]\nsilicone_E = 0.5\n')
    o = find_outputs(toml, out)
    assert o.directory == out / "tiny" and o.run_command == f"metasheet run {toml} --out {out}"
    assert o.silicone[0] == 0.5  # the pipeline's own silicone
    assert find_outputs(toml).directory == tmp_path / "outputs" / "tiny"  # default root: outputs/ of the project


@pytest.mark.parametrize("missing", ["robot/jacobian.json", "orient/sheet_mirrored.vtu", "material/material.json"])
def test_a_missing_output_names_the_file_and_the_command(tmp_path, missing):
    toml, out = write_outputs(tmp_path)
    (out / "tiny" / missing).unlink()
    with pytest.raises(ConfigError) as err:
        load_robot(find_outputs(toml, out))
    msg = str(err.value)
    assert missing in msg and f"metasheet run {toml} --out {out}" in msg and "\n" not in msg


def test_a_pipeline_without_a_robot_stage_is_a_clear_error(tmp_path):
    toml, out = write_outputs(tmp_path, pipeline='[pipeline]\nname = "tiny"\nstages = ["material", "orient"]\n')
    with pytest.raises(ConfigError, match="no 'robot' stage"):
        load_robot(find_outputs(toml, out))


def test_missing_reduce_outputs_and_bad_names_are_clear_errors(outputs):
    with pytest.raises(ConfigError, match=r"--model reduced: needs the reduce stage's outputs .*reduce"):
        load_robot(outputs, "reduced")
    with pytest.raises(ConfigError, match="--model: 'fast'"):
        load_robot(outputs, "fast")
    with pytest.raises(ConfigError, match="material: 'steel'"):
        load_robot(outputs, "full", "steel")


def test_geometry_matches_the_robot(build):
    robot, info = build("foam")
    g = info.geometry
    assert g.rest.shape == robot.coupling.rest.shape and len(g.fibers) == len(robot.body.tets)
    assert np.allclose(np.linalg.norm(g.fibers, axis=1), 1.0) and np.all((g.fiber_angle >= 0) & (g.fiber_angle < 180))
    assert g.rod_length == pytest.approx(80.0) and len(g.pivots) == 6
    assert set(np.unique(g.sheet)) == {0, 1}


def test_busy_port_is_a_clear_error():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(ConfigError, match=f"--port: {port}: 127.0.0.1:{port} is not available"):
            check_port("127.0.0.1", port)
    check_port("127.0.0.1", port)  # free again: no error


@pytest.mark.slow
def test_cli_serve_errors_are_one_line_with_status_2(tmp_path):
    """The real entry point, in a process of its own (5 CPU s: it imports the whole CLI).
    Default-selection sibling: test_serve_errors_are_one_line_with_status_2_in_process."""
    toml, out = write_outputs(tmp_path)
    (out / "tiny" / "robot" / "jacobian.json").unlink()
    r = subprocess.run([sys.executable, "-m", "metasheet.cli", "serve", str(toml), "--out", str(out), "--port", "8089"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("error: ") and "jacobian.json: missing" in r.stderr


def test_serve_errors_are_one_line_with_status_2_in_process(tmp_path, capsys):
    """The slow test's checks on ``metasheet.cli.main`` here: its parsing and errors, no new process."""
    from metasheet.cli import main

    toml, out = write_outputs(tmp_path)
    (out / "tiny" / "robot" / "jacobian.json").unlink()
    with pytest.raises(SystemExit) as exc:
        main(["serve", str(toml), "--out", str(out), "--port", "8089"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith("error: ") and "jacobian.json: missing" in err


# -- the session -----------------------------------------------------------------------------

def test_goal_run_takes_gotos_steps(build):
    robot, _ = build("foam")
    rest = InverseController(robot).state
    ref = InverseController(robot, rest).goto(GOAL)
    run = GoalRun(InverseController(robot, rest), GOAL)
    while not run.done:
        run.advance()
    assert run.status == ref.status == "reached" and run.steps == ref.steps
    np.testing.assert_array_equal(run.ctrl.state.angles, ref.state.angles)


def test_track_steps_towards_a_goal_within_the_tolerances(build):
    robot, _ = build("foam")
    ctrl = InverseController(robot)
    here = np.concatenate([ctrl.state.p, np.zeros(3)])  # the rest pose (rotation ~0 at rest)
    run = GoalRun(ctrl, here + [0.06, 0.0, 0.0, 0.0, 0.0, 0.0])  # 0.06 mm: inside pos_tol 0.1
    assert run.near()
    before = 0.06  # [mm] the goal's offset from the rest position
    p = run.track()
    assert p is not None and not p.done and run.steps == 1
    assert p.pos_error < 0.5 * before  # the step followed the goal
    exact = GoalRun(ctrl, np.concatenate([ctrl.state.p, np.degrees(rotation_vector(ctrl.state.R))]))
    assert exact.track() is None and exact.steps == 0  # nothing to follow


def test_a_slow_drag_moves_the_robot_at_every_goal(session):
    rest = session.snapshot()
    goals = [rest.pose + [0.0, 0.0, -0.04 * k, 0.0, 0.0, 0.0] for k in range(1, 9)]  # 0.04 mm apart
    poses = []
    for g in goals:
        last = session.snapshot().version
        session.set_goal(g)
        snap = session.wait(last, timeout=30)
        assert snap is not None and snap.status == "moving"
        poses.append(snap.pose[2])
    assert np.all(np.diff(poses) < 0)  # one update per goal, each one lower: the robot follows
    snap = session.wait_idle(60)
    assert snap.status == "reached" and abs(snap.pose[2] - goals[-1][2]) <= 0.1


def test_a_goal_moves_the_motors_as_goto_does(session, build):
    rest = session.snapshot()
    session.set_goal(GOAL)
    snap = session.wait_idle(60)
    assert snap.status == "reached" and snap.mode == "inverse", snap.message
    assert np.max(np.abs(snap.angles_deg - rest.angles_deg)) > 1.0  # the motors moved
    ref = InverseController(build("foam")[0]).goto(GOAL)
    # both within the loop's tolerances of the goal (0.1 mm, 0.2 deg), by different step paths
    assert snap.pos_error <= 0.1 and snap.rot_error <= 0.2
    np.testing.assert_allclose(snap.pose, ref.pose, atol=0.2)
    np.testing.assert_allclose(snap.angles_deg, ref.angles_deg, atol=0.5)


def test_the_latest_goal_wins(session):
    for dz in np.linspace(0.0, -1.0, 30):  # a drag, faster than the solver
        session.set_goal([0.0, 0.0, dz, 0.0, 0.0, 0.0])
    session.set_goal(GOAL)
    snap = session.wait_idle(60)
    assert snap.status == "reached" and np.allclose(snap.goal, GOAL)
    assert session.dropped > 0  # stale goals were dropped, not queued


def test_motor_sliders_give_the_forward_models_pose(session, build):
    angles = [50.0, 62.0, 58.0, 61.0, 55.0, 66.0]
    session.set_motors(angles)
    snap = session.wait_idle(60)
    assert snap.mode == "forward" and snap.status == "holding", snap.message
    robot = build("foam")[0]
    eq = solve_equilibrium(robot, np.radians(angles))
    np.testing.assert_allclose(snap.angles_deg, angles, atol=1e-9)
    np.testing.assert_allclose(snap.state.p, eq.state.p, atol=1e-3)
    np.testing.assert_allclose(snap.pose, snap.goal)  # the goal follows the robot
    assert snap.goal_version > 0  # ... and the page moves its gizmo there


def test_an_unreachable_goal_shows_the_closest_pose(session):
    session.set_goal(FAR)
    snap = session.wait_idle(60)
    assert snap.status == "unreachable" and "unreachable" in snap.message and "closest pose" in snap.message
    assert snap.pos_error + snap.rot_error > 1.0
    causes = ("motors at their stroke", "near-singular Jacobian", "the equilibrium solver", "the step rule")
    assert "limited by " in snap.message and any(c in snap.message for c in causes)  # why, as goto says
    # the closest pose pulls the sheets far beyond their strain limit, where the loop may not
    # find its way back (the model's, not the page's: goto from there stalls too); the reset
    # button's forward solve brings the robot back, and the worker is alive
    session.reset()
    assert session.wait_idle(60).status == "holding"
    session.set_goal(GOAL)
    assert session.wait_idle(60).status == "reached"


def test_a_solver_error_is_shown_and_the_worker_goes_on(session, monkeypatch):
    from metasheet.errors import ConvergenceError
    from metasheet.serve import models as models_module

    def fail(*a, **k):
        raise ConvergenceError("statics: no convergence (test)")

    monkeypatch.setattr(models_module, "solve_equilibrium", fail)
    before = session.snapshot()
    session.set_motors([40.0] * 6)
    snap = session.wait_idle(30)
    assert snap.status == "error" and "no convergence" in snap.message
    np.testing.assert_array_equal(snap.angles_deg, before.angles_deg)  # the last good state
    monkeypatch.undo()
    session.set_goal(GOAL)
    assert session.wait_idle(60).status == "reached"


def test_silicone_loses_the_sixth_dof(session):
    foam = session.snapshot()
    session.set_material("silicone")
    snap = session.wait_idle(60)
    assert snap.material == "silicone" and "silicone" in snap.description
    np.testing.assert_allclose(snap.angles_deg, foam.angles_deg, atol=1e-9)  # same motors, other sheets
    assert snap.singular_values.min() < 0.1 * foam.singular_values.min()  # the rod's roll is lost
    session.set_material("foam")
    assert session.wait_idle(60).singular_values.min() == pytest.approx(foam.singular_values.min(), rel=1e-3)


def test_bad_commands_are_refused_at_once(session):
    with pytest.raises(ConfigError, match="goal"):
        session.set_goal([0, 0, float("nan"), 0, 0, 0])
    with pytest.raises(ConfigError, match="material"):
        session.set_material("steel")
    with pytest.raises(ConfigError, match="maze"):
        session.play_maze(None)


# -- the maze path ---------------------------------------------------------------------------

def _maze_csv(path, times, motors):
    from metasheet.pipeline.stages.maze import HEADER

    rows = [",".join(HEADER)]
    for t, m in zip(times, motors):
        rows.append(",".join(str(v) for v in [t, *m, 0, 1, 0.0, 5.0, 0.0, 1, 0.1, 0.1, 0.1, 0.1]))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(rows) + "\n")


def test_maze_path_is_read_and_played(session, outputs):
    f = maze_file(outputs.directory, "foam")
    motors = [[60.0] * 6, [58.0, 62.0, 60.0, 60.0, 61.0, 59.0], [55.0, 64.0, 60.0, 60.0, 62.0, 58.0]]
    _maze_csv(f, [0.0, 0.05, 0.1], motors)
    play = read_maze(f)
    assert len(play) == 3 and play.motors_deg.shape == (3, 6) and np.allclose(play.command_deg[1], [0, 5, 0])
    session.play_maze(play)
    snap = session.wait_idle(60)
    assert snap.mode == "maze" and "played 3 samples" in snap.message
    np.testing.assert_allclose(snap.angles_deg, motors[-1], atol=1e-9)


def test_bad_maze_files_name_the_problem(tmp_path):
    with pytest.raises(ConfigError, match="missing: add the maze stage"):
        read_maze(tmp_path / "maze.csv")
    (tmp_path / "a.csv").write_text("time_s,motor0_deg\n0,1\n")
    with pytest.raises(ConfigError, match="no column 'motor1_deg'"):
        read_maze(tmp_path / "a.csv")
    _maze_csv(tmp_path / "b.csv", [0.0, 0.2, 0.1], [[60.0] * 6] * 3)
    with pytest.raises(ConfigError, match="time_s must increase: row 4 is not after row 3"):
        read_maze(tmp_path / "b.csv")


# -- what is drawn ---------------------------------------------------------------------------

def test_surface_of_one_tet_is_its_faces_wound_outwards():
    X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    s = scene.surface(np.array([[0, 1, 2, 3]]), X)
    assert s.faces.shape == (4, 3)
    tri = X[s.nodes][s.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ij,ij->i", normal, tri.mean(axis=1) - X.mean(axis=0)) > 0)
    two = scene.surface(np.array([[0, 1, 2, 3], [1, 2, 3, 4]]), np.vstack([X, [[1.0, 1, 1]]]))
    assert len(two.faces) == 6  # the shared face is inside


def test_quadratic_faces_split_in_four():
    from metasheet.fem.tet10 import elevate_to_p2

    X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    pts, t10 = elevate_to_p2(X, np.array([[0, 1, 2, 3]]))
    s = scene.surface(t10, pts)
    assert s.faces.shape == (16, 3) and len(s.nodes) == 10
    tri = pts[s.nodes][s.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.sum() == pytest.approx(1.5 + np.sqrt(3) / 2)  # the tet's surface


def test_bands_partition_the_faces_and_strain_beyond_the_limit_is_its_own(build):
    robot, info = build("foam")
    g = info.geometry
    s = scene.surface(g.tets, g.rest)
    x = g.rest + 0.01 * g.rest[:, [1, 2, 0]]
    strain = robot.body.max_principal_strain(x)
    for field in scene.FIELDS:
        v = scene.face_values(field, s, g, x, strain)
        lo, hi = scene.field_range(field, v, 0.3)
        meshes = scene.band_meshes(s, x, v, lo, hi, limit=0.01 if field == "strain" else None)
        assert sum(len(f) for _, f in meshes) == len(s.faces)
        assert all(len(f) == 0 or f.max() < len(vv) for vv, f in meshes)
    over = scene.band_meshes(s, x, np.full(len(s.faces), 0.5), 0.0, 0.3, limit=0.3)
    assert len(over[-1][1]) == len(s.faces)  # all beyond the limit: the last, red band
    assert scene.field_range("displacement", np.array([0.01]), 0.3) == (0.0, 1.0)
    assert scene.field_range("displacement", np.array([3.2]), 0.3) == (0.0, 5.0)
    seg = scene.fiber_segments(g, x)
    assert np.allclose(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1), scene.FIBER_LENGTH)
    assert scene.horn_segments(g, g.rest).shape == (6, 2, 3)


def test_panel_text_and_rate(session):
    snap = session.snapshot()
    text = status_markdown(snap, strain_max=0.5, strain_limit=0.3, rate=12.3, model="full")
    assert "| 0 | 60.00 | 0 to 90 |" in text and "NOT VALID" in text and "updates: 12.3 per s" in text
    from dataclasses import replace

    tiny = replace(snap, goal=np.array([-1e-17, 0.0, 0.5, -0.004, 0.0, -0.006]))
    assert "goal [mm, deg]: 0.00 0.00 0.50 | 0.00 0.00 -0.01" in status_markdown(
        tiny, strain_max=0.0, strain_limit=0.3, rate=1.0, model="full")  # no "-0.00"
    t = iter(np.arange(0.0, 10.0, 0.1))
    meter = RateMeter(window=2.0, gap=1.0, clock=lambda: next(t))
    for _ in range(30):
        meter.tick()
    assert meter.rate() == pytest.approx(10.0)


def wait_until(predicate, timeout=20.0):
    deadline = time.time() + timeout
    while not predicate():
        assert time.time() < deadline, "not within the timeout"
        time.sleep(0.02)


def test_page_draws_a_snapshot_for_every_tab(session, outputs):
    """The page on a real (browserless) viser server: what it sends is the snapshot."""
    with live_page(session, outputs, "full") as page:
        session.set_goal(GOAL)
        snap = session.wait_idle(60)
        wait_until(lambda: page.drawn == snap.version)  # the page's drawing thread
        np.testing.assert_allclose(page.effector.position, snap.state.p * SCALE, atol=1e-9)
        np.testing.assert_allclose([h.value for h in page.sliders], np.round(snap.angles_deg, 1))
        drawn = sum(len(h.faces) for h in page.bands if h.visible)
        assert drawn == len(page.surface.faces)
        assert "reached" in page.status.content and "pose [mm, deg]" in page.status.content
        page.color_by.value = "strain"  # as a tab would: the page redraws
        wait_until(lambda: "max principal strain" in page.legend.content)


def _from_a_tab(handle, value):
    """What viser does with a tab's GUI update message (``viser/_gui_api.py``,
    ``_handle_gui_updates``): cast the value to the widget's type (a menu takes any text, a
    number NaN), store it, then call the widget's callbacks with the tab as the client."""
    from viser import GuiEvent

    handle._impl.value = type(handle._impl.value)(value)
    for cb in handle._impl.update_cb:
        cb(GuiEvent(client=object(), client_id=1, target=handle))


def _from_the_browser(page, handle, value) -> None:
    """The GUI update message the page sends when ``handle`` takes ``value``, through the
    server's registered handler (where viser casts it)."""
    import asyncio

    from viser import _messages

    handlers = page.server.gui._websock_interface._incoming_handlers[_messages.GuiUpdateMessage]
    for h in handlers:
        asyncio.run(h(1, _messages.GuiUpdateMessage(uuid=handle._impl.uuid, updates={"value": value})))


def test_the_page_refuses_bad_values_and_keeps_drawing(session, outputs, caplog):
    """Before: "nonsense" in the colour menu raised at every redraw (no tab updated again),
    and a NaN goal moved the gizmo to NaN before the session refused it."""
    from types import SimpleNamespace

    from viser import GuiEvent

    def click(target=None):
        return GuiEvent(client=object(), client_id=1, target=target)

    with live_page(session, outputs, "full") as page:
        rest = session.snapshot()
        _from_a_tab(page.color_by, "nonsense")
        assert page.field == "displacement" and page.color_by.value == "displacement"  # the state as it was
        wait_until(lambda: "note: colour by: 'nonsense': allowed values are displacement" in page.status.content)
        for k, bad, why in ((2, float("nan"), "finite"), (0, 5e3, "allowed range is [-1000, 1000]")):
            _from_a_tab(page.goal_fields[k], bad)
            page._on_go(click())
            assert "goal" in page.notice and why in page.notice
            assert page.goal_fields[k].value == float(round(rest.goal[k], 2))  # the field shows the goal again
        page._on_gizmo(click(SimpleNamespace(position=(np.nan, 0.0, 0.0), wxyz=(1.0, 0.0, 0.0, 0.0))))
        assert page.notice.startswith("goal gizmo:")
        np.testing.assert_allclose(page.goal.position, rest.goal[:3] * SCALE)
        _from_a_tab(page.material, "steel")
        assert page.material.value == "foam" and "material: 'steel'" in page.notice
        _from_a_tab(page.sliders[0], float("nan"))
        assert "motor angles" in page.notice and page.sliders[0].value == float(round(rest.angles_deg[0], 1))
        caplog.clear()
        page._on_gizmo(click(object()))  # a malformed message: no pose at all
        assert "malformed" in page.notice
        assert len(caplog.records) == 1 and caplog.records[0].exc_info is None  # one line, no traceback
        caplog.clear()
        page.goal._impl.wxyz = np.array([1.0])  # as viser stores a client's 1-element quaternion (issue 60)
        page._on_gizmo(click(page.goal))
        assert page.notice.startswith("goal gizmo:") and page.goal.wxyz.shape == (4,)
        assert caplog.records == []  # refused with a note, the gizmo put back: no traceback
        _from_the_browser(page, page.goal_fields[0], "abc")  # viser cast it, before any callback (issue 60)
        assert page.notice == "goal X [mm]: 'abc': expected a number"
        _from_the_browser(page, page.goal_fields[1], None)
        assert page.notice == "goal Y [mm]: None: expected a number" and caplog.records == []
        assert session.snapshot().version == rest.version  # nothing reached the session
        for f, v in zip(page.goal_fields, GOAL):  # a valid goal still moves the robot, and is drawn
            _from_a_tab(f, v)
        page._on_go(click())
        assert page.notice == ""
        snap = session.wait_idle(60)
        assert snap.status == "reached", snap.message
        wait_until(lambda: page.drawn == snap.version and "reached" in page.status.content)
