"""``metasheet robot path``: a path of poses sampled at a speed and a rate, solved by
continuation into motor angles that match ``robot goto`` point by point; the servo check
(stroke, speed) and the pulse map; bad inputs named; the command end to end on the tiny
pipeline outputs (15 mm P1 sheets)."""

import importlib.util
import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metasheet.errors import ConfigError
from metasheet.export import path as pth, program as prog
from metasheet.export.servo import MAX_SPEED_DEG_S, ServoPulse, check_program
from metasheet.robot.inverse_settings import InverseSettings

from serve_outputs import write_outputs


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """(pipeline file, output root, the full robot) of the tiny outputs."""
    from metasheet.goto import pipeline_robot

    toml, out = write_outputs(tmp_path_factory.mktemp("path"))
    return toml, out, pipeline_robot(toml, out)[0]


def _csv(path, rows, header="x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg"):
    path.write_text(header + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return path


# -- the solve against robot goto -----------------------------------------------------------------
def test_the_program_of_a_short_path_matches_robot_goto_point_by_point(tiny):
    from metasheet.robot.inverse import InverseController
    from metasheet.serve.models import goto

    _, _, robot = tiny
    s = InverseSettings(pos_tol=0.01, rot_tol_deg=0.02)
    rest = prog.rest_pose(InverseController(robot, settings=s).state)
    # three poses a few mm and degrees from rest, timed 1 s apart and sampled at 1 Hz: the samples are the poses
    poses = rest + np.array([[1.0, 0, 0, 0, 0, 0], [1.0, 1.0, 0, 2.0, 0, 0], [0, 1.0, 1.0, 2.0, 1.0, 0]])
    t, goals = pth.sample_path([0.0, 1.0, 2.0], poses, 1.0)
    np.testing.assert_allclose(goals, poses, atol=1e-12)
    p = prog.solve_program(robot, t, goals, s)
    assert p.status == ("reached",) * 3 and p.reason == ("",) * 3 and p.model == ("full",) * 3
    assert np.all(p.error_mm <= s.pos_tol) and np.all(p.error_deg <= s.rot_tol_deg)
    for i, goal in enumerate(goals):  # the reached pose, measured independently of the loop's own errors
        R = Rotation.from_rotvec(np.radians(p.poses[i, 3:])).inv() * Rotation.from_rotvec(np.radians(goal[3:]))
        assert np.linalg.norm(p.poses[i, :3] - goal[:3]) <= s.pos_tol
        assert np.degrees(R.magnitude()) <= s.rot_tol_deg
    # Both solutions put the effector within (pos_tol, rot_tol) of the same goal, so their poses differ by at
    # most twice that, |dx|_D <= 2 sqrt(pos_tol^2 + (w rot_tol)^2) in the loop's weighted norm (D = diag(1, 1,
    # 1, w, w, w), w the rotation weight [mm/rad]). With six motors for six DOF, D J is invertible and
    # |dq| <= |dx|_D / sigma_min(D J); a factor 2 covers J's change over that small gap.
    dx = 2.0 * np.hypot(s.pos_tol, s.rot_weight * np.radians(s.rot_tol_deg))
    for i, goal in enumerate(goals):
        ref, note = goto(robot, goal, s)  # robot goto: from rest, alone
        assert ref.reached and note == ""
        ctrl = InverseController(robot, p.states[i], settings=s)
        ctrl.refresh()
        sigma = np.linalg.svd(np.diag([1, 1, 1, *[s.rot_weight] * 3]) @ ctrl.tangent.J, compute_uv=False)[-1]
        bound = np.degrees(2.0 * dx / sigma)
        assert bound < 1.0  # a meaningful test: under a degree
        assert np.abs(p.angles_deg[i] - ref.angles_deg).max() <= bound, (i, p.angles_deg[i], ref.angles_deg, bound)


def test_a_held_goal_holds_the_motors_and_an_unreached_one_is_flagged_and_the_program_goes_on(tiny):
    from metasheet.robot.inverse import InverseController

    _, _, robot = tiny
    s = InverseSettings(max_steps=40, stall_steps=5)
    rest = prog.rest_pose(InverseController(robot, settings=s).state)
    far = rest + [0, 0, 0, 60.0, 0, 0]  # a 60 deg roll about the rod: far beyond the robot's reach
    goals = np.array([rest + [0.5, 0, 0, 0, 0, 0], rest + [0.5, 0, 0, 0, 0, 0], far, rest])
    p = prog.solve_program(robot, np.arange(4.0), goals, s)
    assert p.status[0] == p.status[1] == "reached" and p.status[3] == "reached"
    np.testing.assert_array_equal(p.angles_deg[0], p.angles_deg[1])
    assert p.status[2] in ("stalled", "max_steps") and p.reason[2]  # flagged with why
    assert p.error_deg[2] > 1.0 and list(p.reached) == [True, True, False, True]
    assert p.summary()["first_not_reached"] == 2 and p.summary()["not_reached"] == 1


# -- sampling ------------------------------------------------------------------------------------
def test_constant_speed_gives_the_expected_samples_and_times():
    poses = np.array([[0, 0, 0, 0, 0, 0], [10, 0, 0, 0, 0, 0], [10, 5, 0, 0, 0, 0]], float)  # 15 mm
    times = pth.path_times(poses, 5.0)
    np.testing.assert_allclose(times, [0.0, 2.0, 3.0])
    t, goals = pth.sample_path(times, poses, 10.0)
    assert len(t) == 31  # 3 s at 10 Hz, both ends
    np.testing.assert_allclose(t, np.arange(31) / 10.0, atol=1e-12)
    np.testing.assert_allclose(goals[0], poses[0], atol=1e-12)
    np.testing.assert_allclose(goals[-1], poses[-1], atol=1e-12)
    np.testing.assert_allclose(goals[10], [5, 0, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(goals[20], poses[1], atol=1e-12)
    np.testing.assert_allclose(goals[25], [10, 2.5, 0, 0, 0, 0], atol=1e-12)
    # a path whose end is between two samples: the last sample is the first past it, holding the end pose
    t, goals = pth.sample_path([0.0, 1.05], poses[:2], 10.0)
    assert len(t) == 12 and t[-1] == pytest.approx(1.1)
    np.testing.assert_allclose(goals[-1], poses[1], atol=1e-12)
    # a turn slower than its move sets the segment's time: 30 deg at 10 deg/s = 3 s > 1 mm at 5 mm/s
    turn = np.array([[0, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 30.0]])
    np.testing.assert_allclose(pth.path_times(turn, 5.0, 10.0), [0.0, 3.0])


def test_slerp_midpoints_are_on_the_geodesic():
    def rx(deg):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])

    def rz(deg):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    def rotvec_deg(R):  # the rotation vector of R, by the trace and skew part (|angle| < 180)
        a = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
        w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2 * np.sin(a))
        return np.degrees(a * w)

    # about one axis: the midpoint of 0 and 90 deg is 45 deg
    t, g = pth.sample_path([0.0, 1.0], [[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 90.0]], 2.0)
    np.testing.assert_allclose(g[1], [0, 0, 0, 0, 0, 45.0], atol=1e-9)
    # from Rx(90) to Rx(90) Rz(60): the geodesic passes Rx(90) Rz(30) halfway, Rx(90) Rz(15) a quarter in
    a, b = rotvec_deg(rx(90)), rotvec_deg(rx(90) @ rz(60))
    t, g = pth.sample_path([0.0, 1.0], [[0, 0, 0, *a], [4.0, 0, 0, *b]], 4.0)
    np.testing.assert_allclose(g[2], [2.0, 0, 0, *rotvec_deg(rx(90) @ rz(30))], atol=1e-9)
    np.testing.assert_allclose(g[1], [1.0, 0, 0, *rotvec_deg(rx(90) @ rz(15))], atol=1e-9)


def test_the_maze_path_is_the_maze_studys_commands_from_rest():
    from metasheet.pipeline.stages.maze import MazeParams
    from metasheet.studies.maze import MazeSettings, maze_commands

    rest = np.array([0.0, 0.0, -0.03, 0.0, 0.0, 0.0])
    p = MazeParams(path=[(0.0, 0.0), (10.0, 0.0)], speed=10.0, dt=0.2, ramp_s=0.4)
    times, poses = pth.maze_path(rest, p)
    c = maze_commands(p.path, rest, MazeSettings(tilt_deg=p.tilt_deg, speed=10.0, dt=0.2, ramp_s=0.4))
    np.testing.assert_allclose(times, [0.0, *c.time])
    np.testing.assert_allclose(poses[0], rest)
    np.testing.assert_allclose(np.radians(poses[1:, 3:]), c.poses[:, 3:], atol=1e-12)
    # rolling along +u (the rod, x) tilts the maze about y by the full tilt while it holds
    assert np.abs(poses[1:, 3:]).max() == pytest.approx(p.tilt_deg)


def test_a_ray_is_its_goals_outwards_from_rest_at_the_rest_orientation():
    from metasheet.studies.grid import star_grid

    grid = star_grid()
    rest = np.array([0.0, -0.01, -0.03, 0.1, 0.0, 0.0])
    poses = pth.ray_path(rest, grid, 3)
    sel = grid.ray_points(3)
    assert len(poses) == len(sel) + 1
    np.testing.assert_allclose(poses[0], rest)
    np.testing.assert_allclose(poses[1:, :3], rest[:3] + grid.points[sel])
    np.testing.assert_allclose(poses[1:, 3:], np.tile(rest[3:], (len(sel), 1)))
    assert np.all(np.diff(np.linalg.norm(poses[:, :3] - rest[:3], axis=1)) > 0)  # outwards
    with pytest.raises(ConfigError, match=r"--ray: 62: allowed range is \[0, 61\]"):
        pth.ray_path(rest, grid, 62)


# -- the servo check and the pulse map -------------------------------------------------------------
def test_every_sample_beyond_the_stroke_is_flagged_and_one_too_fast():
    t = np.arange(6) * 0.1  # at 600 deg/s a motor may move 60 deg a sample
    q = np.full((6, 6), 45.0)
    q[1, 1] = 90.0005  # at the stroke's end but for the CSV's rounding: within
    q[2, 1] = 92.0  # beyond 90 (47 deg in 0.1 s: within the speed)
    q[3, 4] = -0.5  # beyond 0
    q[4, 4] = 0.0
    q[5, 4] = 65.0  # 65 deg in 0.1 s: 650 deg/s
    c = check_program(q, t, 0.0, 90.0)
    assert c.beyond.any(axis=1).tolist() == [False, False, True, True, False, False]
    assert c.too_fast.any(axis=1).tolist() == [False] * 5 + [True]
    assert np.flatnonzero(c.flagged).tolist() == [2, 3, 5] and not c.ok
    assert c.speed[5, 4] == pytest.approx(650.0) and c.max_speed == MAX_SPEED_DEG_S
    lines = c.lines(t, q)
    assert "sample 2 (t = 0.200 s): motor 1 at 92.000 deg, beyond the stroke [0, 90] deg" == lines[0]
    assert "motor 4 at 650.0 deg/s, faster than 600 deg/s" in lines[2]
    # within both: passes; a per-motor stroke is honoured
    q = np.linspace(20.0, 70.0, 6)[:, None] * np.ones(6)
    assert check_program(q, t, 0.0, 90.0).ok
    assert not check_program(q, t, np.zeros(6), [90, 90, 90, 90, 90, 60.0]).ok
    with pytest.raises(ConfigError, match="times: sample 1 at 0 s does not follow"):
        check_program(q[:2], [0.0, 0.0], 0.0, 90.0)


def test_the_pulse_map_sends_the_stated_ends_and_reversed_servos_mirror():
    p = ServoPulse()
    angles = np.array([[0.0] * 6, [180.0] * 6, [90.0] * 6, [45.0] * 6])
    np.testing.assert_allclose(p.pulse_us(angles)[:, 0], [500.0, 2500.0, 1500.0, 1000.0])
    r = ServoPulse.with_reversed([2, 5])
    out = r.pulse_us(angles)
    np.testing.assert_allclose(out[:, 2], [2500.0, 500.0, 1500.0, 2000.0])
    np.testing.assert_allclose(out[:, [0, 1, 3, 4]], p.pulse_us(angles)[:, [0, 1, 3, 4]])
    np.testing.assert_allclose(out[:, 2] + p.pulse_us(angles)[:, 2], 3000.0)  # mirrored about the middle
    sg90 = ServoPulse(pulse_min_us=500.0, pulse_max_us=2400.0)
    np.testing.assert_allclose(sg90.pulse_us(angles)[:2, 0], [500.0, 2400.0])
    with pytest.raises(ConfigError, match="reversed motor: 6: allowed range is"):
        ServoPulse.with_reversed([6])
    with pytest.raises(ConfigError, match="pulse_max_us"):
        ServoPulse(pulse_min_us=2500.0, pulse_max_us=500.0)


# -- bad inputs ------------------------------------------------------------------------------------
def test_bad_paths_and_numbers_get_a_clear_error_naming_the_field(tmp_path):
    with pytest.raises(ConfigError, match="empty path: no pose under the header"):
        pth.read_path_csv(_csv(tmp_path / "a.csv", []))
    (tmp_path / "b.csv").write_text("")
    with pytest.raises(ConfigError, match="b.csv: empty: expected a header"):
        pth.read_path_csv(tmp_path / "b.csv")
    with pytest.raises(ConfigError, match="missing column.s. rz_deg: the header needs x_mm,y_mm"):
        pth.read_path_csv(_csv(tmp_path / "c.csv", [[0, 0, 0, 0, 0]], "x_mm,y_mm,z_mm,rx_deg,ry_deg"))
    with pytest.raises(ConfigError, match="data row 2, y_mm: 'nan': expected a finite number"):
        pth.read_path_csv(_csv(tmp_path / "d.csv", [[0] * 6, [0, "nan", 0, 0, 0, 0]]))
    with pytest.raises(ConfigError, match="data row 1, z_mm: 'abc': expected a number"):
        pth.read_path_csv(_csv(tmp_path / "e.csv", [[0, 0, "abc", 0, 0, 0]]))
    with pytest.raises(ConfigError, match=r"data row 3, t_s: 1 s: times must increase"):
        pth.read_path_csv(_csv(tmp_path / "f.csv", [[0] * 7, [1, 0, 0, 0, 0, 0, 1], [2, 0, 0, 0, 0, 0, 1]],
                                "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,t_s"))
    poses, times = pth.read_path_csv(_csv(tmp_path / "g.csv", [[0, 1, 2, 3, 4, 5, 0.5]],
                                           "t_s,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg"))  # any column order
    np.testing.assert_array_equal(poses, [[1, 2, 3, 4, 5, 0.5]])
    np.testing.assert_array_equal(times, [0])
    with pytest.raises(ConfigError, match=r"--rate: 0.0: allowed range is \(0, 1000\]"):
        pth.sample_path([0.0, 1.0], np.zeros((2, 6)), 0.0)
    with pytest.raises(ConfigError, match=r"--speed: 0.0: allowed range is \(0, 10000\]"):
        pth.path_times(np.zeros((2, 6)), 0.0)
    with pytest.raises(ConfigError, match=r"path: pose 2 \(x, y, z = 150, 0, 0 mm\) is 150.0 mm from the rest "
                                          r"position: allowed distance is at most 100 mm"):
        pth.check_reach([[0, 0, 0, 0, 0, 0], [150, 0, 0, 0, 0, 0]], np.zeros(6))


# -- the command -----------------------------------------------------------------------------------
def _cli(capsys, *args):
    from metasheet.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["robot", "path", *args])
    text = capsys.readouterr()
    return exc.value.code or 0, text.out + text.err


def test_the_command_writes_a_program_and_the_dry_run_writes_nothing(tiny, tmp_path, capsys):
    toml, out, _ = tiny
    path = _csv(tmp_path / "path.csv", [[0, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0], [1, 1, 0, 0, 0, 1]])
    to = tmp_path / "prog"
    # the ParaView series is another module's (metasheet.export.series): checked here only when it is there
    series = importlib.util.find_spec("metasheet.export.series") is not None
    rc, text = _cli(capsys, str(path), "--pipeline", str(toml), "--out", str(out), "--to", str(to), "--speed", "2",
                    "--rate", "2", "--reversed", "3", *(["--pvd"] if series else []))
    assert rc == 0, text
    names = sorted(f.name for f in to.iterdir())
    assert names == sorted(["program.csv", "program.json", "program.png", *(["path", "path.pvd"] if series else [])])
    if series:  # one step a sample, at the program's times
        steps = re.findall(r'timestep="([^"]+)"', (to / "path.pvd").read_text())
        assert sorted(set(map(float, steps))) == [0.0, 0.5, 1.0]
    rows = (to / "program.csv").read_text().splitlines()
    assert rows[0].split(",") == prog.HEADER and len(rows) == 1 + 3  # 1.0 s + 0.5 s at 2 mm/s, 2 Hz: 0, 0.5, 1
    meta = json.loads((to / "program.json").read_text())
    assert meta["summary"]["samples"] == 3 and meta["summary"]["reached"] == 3
    assert set(meta["columns"]) == set(prog.HEADER) and meta["columns"]["pulse0_us"].startswith("us")
    assert "0 deg: the horn horizontal" in meta["servo_zero"] and "90 deg: the horn vertical" in meta["servo_zero"]
    assert [m["sheet"] for m in meta["motors"]] == ["A", "A", "A", "B", "B", "B"]
    assert meta["pulse"]["reversed"] == [False, False, False, True, False, False]
    assert meta["rate_hz"] == 2.0 and meta["speed_mm_s"] == 2.0 and meta["tolerances"]["position_mm"] == 0.1
    assert list(meta) == sorted(meta)
    q, pulses = (np.array([r.split(",")[c] for r in rows[1:]], float) for c in (4, 10))  # motor 3, pulse 3
    np.testing.assert_allclose(pulses, 2500.0 - 2000.0 * q / 180.0, atol=0.006)  # reversed, 2 decimals
    # the dry run of the same path: the verdict, nothing written
    dry = tmp_path / "dry"
    rc, text = _cli(capsys, str(path), "--pipeline", str(toml), "--out", str(out), "--to", str(dry), "--speed", "2",
                    "--rate", "2", "--dry-run")
    assert rc == 0 and "ready to send" in text and "nothing written" in text, text
    assert not dry.exists()
    # a hand-edited program with a motor beyond the stroke: flagged, exit 4, nothing written
    before = sorted(p.name for p in to.iterdir())
    rows[2] = ",".join(["0.5", "95.0", *rows[2].split(",")[2:]])
    (to / "edited.csv").write_text("\n".join(rows) + "\n")
    rc, text = _cli(capsys, "--dry-run", "--program", str(to / "edited.csv"))
    assert rc == 4 and "sample 1 (t = 0.500 s): motor 0 at 95.000 deg, beyond the stroke [0, 90] deg" in text, text
    assert sorted(p.name for p in to.iterdir()) == sorted([*before, "edited.csv"])
    rc, text = _cli(capsys, "--dry-run", "--program", str(to / "program.csv"))
    assert rc == 0 and "ready to send" in text


def test_the_command_refuses_bad_options_before_solving(tmp_path, capsys):
    path = _csv(tmp_path / "p.csv", [[0] * 6])
    for args, message in (([str(path), "--maze", "--to", "x"], "give one of PATH.csv, --maze or --ray K (given: "
                                                               "PATH.csv, --maze)"),
                          ([str(path)], "--to: the folder to write the program into is needed"),
                          ([str(path), "--to", "x", "--rate", "0"], "--rate: 0.0: allowed range is (0, 1000]"),
                          ([str(path), "--to", "x", "--speed", "-1"], "--speed: -1.0: allowed range is (0, 10000]"),
                          (["--program", str(path)], "--program: checks an existing program.csv: give --dry-run"),
                          ([str(path), "--to", "x", "--model", "surface"], "--model: 'surface': allowed values"),
                          ([str(path), "--to", "x", "--tilt-deg", "5"], "--tilt-deg: only with --maze"),
                          (["--maze", "--to", "x", "--tilt-deg", "60"], "--tilt-deg: 60.0: allowed range is (0, 45]")):
        rc, text = _cli(capsys, *args)
        assert rc == 2 and message in text, (args, text)


def test_a_pose_outside_the_workspace_is_refused_naming_the_distance(tiny, tmp_path, capsys):
    toml, out, _ = tiny
    path = _csv(tmp_path / "far.csv", [[0] * 6, [0, 120, 0, 0, 0, 0]])
    rc, text = _cli(capsys, str(path), "--pipeline", str(toml), "--out", str(out), "--to", str(tmp_path / "o"))
    assert rc == 2 and "pose 2 (x, y, z = 0, 120, 0 mm) is 120.0 mm from the rest position: allowed distance is at " \
                       "most 100 mm" in text, text
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_the_same_inputs_write_the_same_bytes(tiny, tmp_path, capsys):
    toml, out, _ = tiny
    path = _csv(tmp_path / "path.csv", [[0, 0, 0, 0, 0, 0], [2, 1, 0, 1, 0, 0], [0, 2, 1, 0, 2, 0]])
    for d in ("a", "b"):
        rc, text = _cli(capsys, str(path), "--pipeline", str(toml), "--out", str(out), "--to", str(tmp_path / d),
                        "--rate", "5")
        assert rc == 0, text
    for name in ("program.csv", "program.json", "program.png"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
