"""The maze played on a coarse robot (metasheet.studies.maze_played, metasheet.dynamics.maze_run):
a short program tilts an L-shaped maze; the marble passes both corners in a short playback."""

import numpy as np
import pytest

from metasheet.dynamics.maze_geometry import maze_from_path
from metasheet.dynamics.maze_run import PLA_DENSITY, maze_inertia, path_verdict
from metasheet.studies.maze_played import DynamicsSettings, Unit, run_unit

PATH = ((0.0, 0.0), (18.0, 0.0), (18.0, 14.0))


@pytest.fixture(scope="module")
def spec():
    from metasheet.studies.adapter import paper_robot_spec

    return paper_robot_spec(mesh_size=14.0)


def _program(spec, tilt_deg=3.0, ramp=0.25, hold=0.5):
    """Tilt commands along the L through the rest Jacobian's inverse (small tilts)."""
    from metasheet.robot.kinematics import kinematics_at
    from metasheet.robot.equilibrium import solve_equilibrium

    robot = spec.build().robot
    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state
    J = kinematics_at(robot, rest).J
    a0 = rest.angles
    times, angles = [0.0], [a0]
    for d in np.diff(np.asarray(PATH), axis=0):
        d = np.array([*d / np.linalg.norm(d), 0.0])
        rot = np.radians(tilt_deg) * np.cross([0, 0, 1.0], d)  # d downhill
        a = a0 + np.linalg.solve(J, np.concatenate([np.zeros(3), rot]))
        times += [times[-1] + ramp, times[-1] + ramp + hold]
        angles += [a, a]
    times.append(times[-1] + ramp)
    angles.append(a0)
    return np.array(times), np.array(angles)


def test_the_marble_rolls_the_L_in_one_go(spec):
    times, angles = _program(spec)
    s = DynamicsSettings(scheme="implicit_euler", dt=0.01, corridor=10.0, frame_s=0.1, n_modes=4)
    r = run_unit(Unit("maze", spec, s, PATH, tuple(times), tuple(map(tuple, angles)), 1.0, True, main=True))
    assert r["solved"] and r["vertices"] == 2 and not r["lifted_off"]
    assert r["marble_progress"][-1] > 0.9 * r["path_length"]
    # slow tilts: the robot stays within a tenth of a millimetre of its quasi-static path
    assert r["gap_mm"].max() < 0.1
    assert len(r["frames_x"]) == len(r["t"][::r["frames_every"]])
    # the servos hold the sheets and the maze: their torques are the same order as the weight's moment
    assert 0 < np.abs(r["torques"]).max() < 100.0  # [N mm]
    # the modal model on the same program: slow tilts lag by micrometres, faster playbacks by more
    gaps = r["modal"]["gaps_mm"]
    assert gaps["1.0"] < 0.05 and r["modal"]["fastest"]["speed"] >= 1.0


def test_modes_and_step_responses_of_the_coarse_robot(spec):
    s = DynamicsSettings(scheme="implicit_euler", dt=0.004, step_s=0.08, n_modes=3)
    r = run_unit(Unit("modes", spec, s, PATH, main=True))
    f = r["frequencies_hz"]
    assert np.all(np.diff(f) >= 0) and 5 < f[0] < 100
    for st in r["steps"]:
        # every DOF settles to its quasi-static target (within 5 % of the step at the end)
        change = st["y"][-1] - st["y"][0]
        assert change == pytest.approx(st["final"], rel=0.05, abs=1e-4)


def test_the_verdict_counts_corners_in_order():
    geo = maze_from_path(PATH, width=10.0)
    track = np.array([[0, 0], [10, 0], [17, 1], [18, 7], [18, 13.5]])
    assert path_verdict(geo, track) == (2, True)
    assert path_verdict(geo, track[::-1]) == (1, False)  # backwards: the last corner first does not count
    assert path_verdict(geo, track[:3]) == (1, False)


def test_the_maze_bodys_mass_is_rod_plate_and_walls():
    geo = maze_from_path(PATH, width=10.0, wall_height=6.0)
    m = maze_inertia(geo, rod_length=80.0, rod_radius=3.0, thickness=3.0, wall_thickness=2.0)
    walls = sum(np.linalg.norm(b - a) for a, b in geo.walls)
    expect = PLA_DENSITY * (np.pi * 9 * 80 + np.prod(geo.plate) * 3 + walls * 2 * 6)
    assert m.mass == pytest.approx(expect, rel=1e-12)
