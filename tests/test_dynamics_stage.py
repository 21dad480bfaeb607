"""The ``dynamics`` stage: the maze study's program played in time, on a coarse robot and a short
maze, its files, its verdict and the report's section; the program reader and the fastest
playback's rule on hand-made inputs."""

import json

import numpy as np
import pytest

from metasheet.pipeline.stages.dynamics import _fastest, read_program

PIPELINE = """
[pipeline]
name = "md"
stages = ["material", "orient", "maze", "dynamics", "report"]

[material]
source = "config"

[orient]
element = "p1"
mesh_size = 14.0

[maze]
path = [[0.0, 0.0], [18.0, 0.0], [18.0, 14.0]]
tilt_deg = 3.0
dt = 0.2
ramp_s = 0.4
speed = 30.0
silicone = true

[dynamics]
scheme = "implicit_euler"
dt = 0.01
speeds = [4.0]
n_modes = 3
step_s = 0.1
corridor = 10.0
frame_s = 0.2

[report]
title = "md"
"""


def test_the_program_reader_starts_at_rest_and_finds_the_holds(tmp_path):
    f = tmp_path / "maze.csv"
    f.write_text("time_s,motor0_deg,motor1_deg,segment,hold\n0.2,61,59,0,0\n0.4,62,58,0,1\n0.6,62,58,0,1\n"
                 "0.8,60,60,1,0\n1.0,59,61,1,1\n")
    t, a, ends = read_program(f, np.array([60.0, 60.0]))
    assert t.tolist() == [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    assert np.allclose(np.degrees(a[0]), 60) and np.allclose(np.degrees(a[-1]), [59, 61])
    assert ends == (0.6, 1.0)


def test_the_fastest_playback_is_the_last_speed_before_the_first_miss():
    def run(speed, gap, solved=True):
        return {"speed": speed, "gap_mm": np.array([0.0, gap, np.nan]), "gap_deg": np.array([0.0, gap / 10, np.nan]),
                "motor_speed_deg_s": 100.0 * speed, "solved": solved, "vertices": 2, "quasi_t": np.array([0, 12.0])}

    f = _fastest(run(1.0, 0.01), [run(2.0, 0.2), run(4.0, 1.5), run(8.0, 0.5)], 1.0, 600.0)
    assert f["speed"] == 2.0 and f["duration_s"] == 6.0  # 8x is within again, but 4x was not
    assert [t["within_servo_speed"] for t in f["tried"]] == [True, True, True, False]
    assert _fastest(run(1.0, 2.0), [], 1.0, 600.0)["speed"] is None


@pytest.mark.slow
def test_the_stage_plays_the_maze_and_the_report_shows_it(tmp_path):
    """Default-selection siblings: tests/test_dynamics_maze_played.py (the units on a coarse
    robot) and the two tests above."""
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    (tmp_path / "md.toml").write_text(PIPELINE)
    run_pipeline(load_pipeline(tmp_path / "md.toml"), out_root=tmp_path / "out")
    d = tmp_path / "out" / "md" / "dynamics"
    for f in ("dynamics.json", "modes.json", "steps.csv", "maze_played.csv", "marble.csv", "marble_silicone.csv",
              "maze_geometry.json", "modes.png", "steps.png", "maze_played.png", "marble.png", "maze_played.gif"):
        assert (d / f).stat().st_size > 0, f
    z = json.loads((d / "dynamics.json").read_text())
    assert z["maze"]["solved"] and z["maze"]["arrivals"] == [True, True]
    # silicone sheets cannot roll the rod: the maze study's program for them misses the corridor across it
    assert z["silicone"] is not None and not z["silicone"]["solved"]
    assert z["fastest"]["tried"][0]["speed"] == 1.0 and len(z["fastest"]["tried"]) == 2
    assert len(z["frequencies_hz"]) == 3 and len(z["steps"]) == 6
    report = (tmp_path / "out" / "md" / "report" / "report.md").read_text()
    assert "The maze, played" in report and "dynamics_prediction_maze_played.gif" in report


@pytest.mark.slow
@pytest.mark.bytes
def test_the_stage_gives_the_same_bytes_serially_and_on_two_workers(tmp_path):
    """Each unit builds its robots once per process and runs from a clean chord and damping
    stiffness (DynamicRobot.reset): the order units meet in a worker does not show."""
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    out = {}
    for workers in (1, 2):
        d = tmp_path / f"w{workers}"
        d.mkdir()
        (d / "md.toml").write_text(PIPELINE.replace('name = "md"', f'name = "md"\nworkers = {workers}'))
        run_pipeline(load_pipeline(d / "md.toml"), out_root=d / "out")
        folder = d / "out" / "md" / "dynamics"
        out[workers] = {f.name: f.read_bytes() for f in folder.iterdir() if f.is_file() and f.name != "manifest.json"}
    assert out[1].keys() == out[2].keys() and len(out[1]) >= 12
    for name in out[1]:
        assert out[1][name] == out[2][name], name
