"""The walls' first touch found on the finite-strain DNS (metasheet/studies/nonlinear_touch.py):
the search against a closing gap known in closed form, against the two-wall toy whose gap closes
at a displacement known by hand (solved by the finite-strain DNS), and on the finite-strain
printed robot, where a notched arm closes its notch, against poses solved afresh."""

import dataclasses

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.fem.voxel.gaps import closest_approach
from metasheet.fem.voxel.hyperelastic import NeoHookean
from metasheet.fem.voxel.nonlinear import solve_hyperelastic
from metasheet.robot.voxel_robot import PrintedRobot
from metasheet.studies.nonlinear_touch import RobotDistance, first_touch, robot_touch
from test_voxel_gaps import H, _two_walls


def _parabola(reach=0.25):
    """A gap of 1 closing as 1 - t^2 / 2, seen only within ``reach`` (as the KD-tree search)."""
    calls = []

    def distance(t):
        calls.append(t)
        g = 1.0 - 0.5 * t * t
        return (g if g <= reach else np.inf), {"t": t}
    return distance, calls


EXACT = np.sqrt(2.0 * (1.0 - 0.0625))  # 1 - t^2 / 2 = 1/16


@pytest.mark.parametrize("guess", [0.5, 1.3, 2.0, 4.0])
def test_the_first_touch_of_a_gap_known_in_closed_form_from_early_and_late_guesses(guess):
    distance, calls = _parabola()
    found = first_touch(distance, guess, 0.0625, max_travel=5.0, tol=1e-3, max_solves=30)
    lo, hi = found.bracket
    assert found.converged and lo < EXACT <= hi and hi - lo <= 1e-3
    assert found.travel == pytest.approx(EXACT, abs=1e-3)
    assert found.info == {"t": hi} and found.solves == len(calls) <= 14
    assert [p[0] for p in found.poses] == calls
    assert all((d <= 0.0625) == (t >= EXACT) for t, d in found.poses)  # each pose on its side


def test_a_gap_that_stays_open_and_a_search_cut_short_are_reported_as_such():
    distance, _ = _parabola()
    found = first_touch(distance, 0.4, 0.0625, max_travel=1.0, tol=1e-3)
    assert found.travel is None and found.bracket == (1.0, np.inf) and found.converged
    assert [p[0] for p in found.poses] == [0.4, 0.6000000000000001, 0.8, 1.0]
    short = first_touch(distance, 4.0, 0.0625, max_travel=5.0, tol=1e-6, max_solves=3)
    lo, hi = short.bracket
    assert not short.converged and short.solves == 3 and lo < EXACT <= hi  # the bracket it reached


def test_bad_searches_are_named():
    distance, _ = _parabola()
    with pytest.raises(ConfigError, match="guess"):
        first_touch(distance, 6.0, 0.0625, max_travel=5.0, tol=1e-3)
    with pytest.raises(ConfigError, match="tol"):
        first_touch(distance, 1.0, 0.0625, max_travel=5.0, tol=0.0)
    with pytest.raises(ConfigError, match="nan"):
        first_touch(lambda t: (np.nan, {}), 1.0, 0.0625, max_travel=5.0, tol=1e-3)


def test_the_two_walls_touch_when_they_have_moved_by_the_gap_less_a_quarter_voxel():
    """Each wall's outer face pushed inwards by t [mm]: the inner faces follow exactly (no load
    crosses the gap), so the 1 mm gap is 1 - 2 t and touches (a quarter voxel) at t = 0.46875."""
    ph = _two_walls()
    N = tuple(n + 1 for n in ph.shape)

    def distance(t):
        fixed = np.zeros(N + (3,), bool)
        values = np.zeros(N + (3,))
        fixed[0] = fixed[-1] = True
        values[0, ..., 0], values[-1, ..., 0] = t, -t
        sol = solve_hyperelastic(ph, ph.shape * H, NeoHookean(12.0, 0.3), prescribed=fixed, values=values)
        ap = closest_approach(ph > 0, H, sol.full(sol.u))
        return ap.distance, {"nodes": ap.nodes}

    found = first_touch(distance, 0.3, 0.25 * H.min(), max_travel=0.49, tol=1e-4)
    assert found.travel == pytest.approx((4 * H[0] - 0.25 * H.min()) / 2, abs=1e-7)
    assert found.converged and len(found.info["nodes"]) == 2


@pytest.fixture(scope="module")
def notched():
    """The small tripod of tests/test_robot_voxel.py 4 mm thick at 1 mm voxels, arm 0 notched
    from one edge (2 x 6 voxels through the thickness): sheet A's motors turned down push the arm
    in and the notch narrows (measured: 0.79 mm at 2 deg, 0.53 at 3, 0.37 at 4; each pose the same
    whether reached from rest at once or through the others: no buckling on the way)."""
    from test_robot_voxel import SMALL, _printed

    robot, sheet, S = _printed(1.0, dataclasses.replace(SMALL, thickness=4.0))
    ph = sheet.phases.copy()
    ph[20:22, 15:21, :] = 0
    sheet = dataclasses.replace(sheet, phases=ph)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    return robot, sheet, S, rest


A_DOWN = np.array([-1.0, -1.0, -1.0, 0.0, 0.0, 0.0])
TOUCH = 0.4  # [mm] the notch counted closed (a quarter voxel, 0.25, is not reached before 6 deg)


def test_the_finite_strain_robot_finds_its_notch_closing_and_a_fresh_pose_there_touches(notched):
    robot, sheet, S, rest = notched
    found, records = robot_touch(PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8), rest, 2 * A_DOWN, 2.0,
                                 max_deg=8.0, tol_deg=0.05, touch_mm=TOUCH)
    lo, hi = found.bracket
    assert found.converged and 3.0 < lo < found.travel < hi < 4.0 and hi - lo <= 0.05
    assert found.info["sheet"] == 0 and found.info["rest_distance_mm"] >= 2.0  # across the notch
    assert [r["travel"] for r in records] == [p[0] for p in found.poses]
    assert all(r["stable"] == [True, True] for r in records)
    # a second method: the pose at the found travel solved afresh, from rest, touches there
    # (the distance linear between the bracket's ends: within 0.01 mm of the touch)
    fresh = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8).equilibrium(rest + found.travel * A_DOWN)
    assert fresh.approach[0].distance == pytest.approx(TOUCH, abs=0.01)
    assert fresh.approach[1].distance == np.inf  # sheet B's motors held: its walls stay apart


def test_the_rod_held_at_a_balanced_pose_is_that_pose_and_held_elsewhere_it_says_how_far(notched):
    """:meth:`PrintedRobot.held` at the effector motion the balance found gives that balance again
    (the rod's residual at the balance's tolerance, the walls as close); the touch searched with
    the rod held where the linear rest model puts it records the rod's unbalanced wrench: on this
    sheet (its linear model the un-notched sheet's) it is far from zero and the touch is
    another (measured: residual 1.2 to 1.3, the rod 0.12 to 0.44 mm and 0.6 to 1.6 deg from its
    balance to first order; first touch 4.4 deg against 3.7 balanced), which is why the held
    search reports it."""
    robot, sheet, S, rest = notched
    m = rest + 3.0 * A_DOWN
    balanced = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8).equilibrium(m)
    held = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8).held(m, np.concatenate([balanced.dp, balanced.theta]))
    assert held.residual < 1e-5 and held.iterations == 0 and held.stable == (True, True)
    assert np.linalg.norm(held.rod_step) < 1e-6 and balanced.rod_step is None
    assert held.approach[0].distance == pytest.approx(balanced.approach[0].distance, abs=1e-5)
    J = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    found, records = robot_touch(PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8), rest, A_DOWN, 2.0,
                                 max_deg=8.0, tol_deg=0.05, touch_mm=TOUCH, rod_per_motor=J, balance=False)
    assert min(r["rod_residual"] for r in records) > 1.0 and found.travel > 4.0
    assert min(r["rod_miss"][0] for r in records) > 0.1  # the linear rod a tenth of a millimetre off
    for r in records:  # the rod where the linear model puts it
        assert np.allclose(r["dp_mm"] + r["theta_rad"], J @ np.radians(r["travel"] * A_DOWN), atol=1e-12)
    # each held pose a function of its travel alone: the search's last pose solved by itself is the same bits
    alone = RobotDistance(PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8), rest, A_DOWN, J, balance=False)
    alone(records[-1]["travel"])
    assert alone.records[0]["approach_mm"] == records[-1]["approach_mm"] and len(records) > 2
    assert alone.records[0]["rod_residual"] == records[-1]["rod_residual"]
    with pytest.raises(ConfigError, match="rod_per_motor"):
        robot_touch(PrintedRobot(robot, (sheet, sheet), S_rest=S), rest, A_DOWN, 2.0, max_deg=8.0, balance=False)
