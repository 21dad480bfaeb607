"""The scene-facts study (metasheet.studies.scene_facts): each candidate's stroke facts are the
arithmetic of its definition, and the +-10 deg tilt test runs from its rest pose, naming what
limits a miss."""

import numpy as np
import pytest

from metasheet.studies.scene_facts import CANDIDATES, Candidate, authors_robot, candidate_robot, measure, stroke_facts, \
    table, tilt_goals


@pytest.fixture(scope="module")
def robot():
    return authors_robot(mesh_size=16.0)


def test_stroke_facts_follow_each_candidates_definition(robot):
    theta0 = np.degrees(robot.coupling.rest_angles)
    by = {c.name: c for c in CANDIDATES}
    rob, start = candidate_robot(robot, by["a"])  # absolute 0-90, start at the stress-free angle
    f = stroke_facts(rob, start)
    assert f["i_stroke_90"] and f["pull_room_deg"] == pytest.approx(90.0 - theta0.max())
    assert f["ii_pull_push"] == bool(90.0 - theta0.max() >= 15.0 and theta0.min() >= 35.0)
    f = stroke_facts(*candidate_robot(robot, by["d35"]))  # rest +- 35: a 70 deg stroke
    assert not f["i_stroke_90"] and f["stroke_deg"] == pytest.approx(70.0)
    assert f["ii_pull_push"] and f["push_room_deg"] == pytest.approx(35.0)
    f = stroke_facts(*candidate_robot(robot, by["e0"]))  # start at the stroke's end: no push room
    assert f["i_stroke_90"] and not f["ii_pull_push"] and f["push_room_deg"] == pytest.approx(0.0, abs=1e-9)


def test_tilt_goals_turn_the_rest_pose_by_ten_degrees_about_each_axis():
    from metasheet.robot.statics import RobotState
    from metasheet.mechanics.rotations import rotation_matrix, rotation_vector

    R0 = rotation_matrix(np.radians([3.0, -2.0, 5.0]))
    st = RobotState(p=np.array([1.0, 2.0, 3.0]), R=R0, angles=np.zeros(6), x=np.zeros(0))
    goals = tilt_goals(st)
    assert [g for g, _ in goals] == ["+x", "-x", "+y", "-y", "+z", "-z"]
    for (label, g), k in zip(goals, (0, 0, 1, 1, 2, 2)):
        assert np.allclose(g[:3], st.p)
        rel = rotation_vector(rotation_matrix(np.radians(g[3:])) @ R0.T)
        assert np.allclose(np.degrees(rel), (10.0 if label[0] == "+" else -10.0) * np.eye(3)[k], atol=1e-9)


def test_the_tilt_test_runs_and_names_what_limits_a_miss(robot):
    row = measure(robot, Candidate("x", 0.0, 90.0, 0.0, True, "test"))
    assert len(row["iii_tilts"]) == 6 and row["iii_reached"] == sum(t["reached"] for t in row["iii_tilts"])
    for t in row["iii_tilts"]:
        if t["reached"]:
            assert t["pos_error_mm"] <= 1.0 and t["rot_error_deg"] <= 2.0
        else:
            assert t["limited_by"]
    assert "| x: test | 90.0 | yes |" in table([row]) and len(table([row]).splitlines()[-1].split("|")) == 9


def test_the_authors_preset_reaches_the_papers_tilts_from_rest_under_the_authors_force_field():
    """Issue 41: the preset itself (its stroke and rest, not a candidate), on a coarse robot with
    the published constants and the authors' force field (the reproduction column), passes the
    paper's test: +-10 deg about x, y and z from rest, each within 2 deg and 1 mm. Measured
    margins on this mesh: y and z turn 8.8-9.0 deg (docs/paper.md)."""
    from metasheet.published import paper
    from metasheet.robot import SheetPair, six_dof_robot
    from metasheet.robot.scenes import AUTHORS as A
    from metasheet.studies.scene_facts import stroke_facts, tilt_facts

    pair = SheetPair.spiral(A.sheet_params(10.0), element="p1", **A.fiber_settings())
    robot = six_dof_robot(pair, paper.PAPER_FOAM, sheet_mass_g=A.sheet_mass_g, rod_length=A.rod_length,
                          geometry=A.servo_geometry(), gravity=A.gravity, model="authors")
    rest = robot.coupling.rest_angles
    facts = stroke_facts(robot, rest)
    assert facts["i_stroke_90"] and facts["ii_pull_push"]
    tilts = tilt_facts(robot, rest)
    assert tilts["iii_reached"] == 6, tilts["iii_tilts"]
    assert all(t["turned_deg"] >= 8.0 for t in tilts["iii_tilts"])
