"""The printed robot's fast model (metasheet/robot/superelement.py) certified against the
finite-strain voxel robot (metasheet/robot/voxel_robot.py) at held-out poses of a coarse sheet,
against the issue's targets (the rod within 0.5 mm and 0.5 deg; issue 62, item 3). The sheet is
the small solid tripod of tests/test_robot_voxel.py at 1 mm voxels. (On it the superelement is
no closer than the linear rest model: 0.029 against 0.027 mm at 2 deg; its corotation does not
capture the arms' own bending, docs/printed-sheet.md.)"""

import numpy as np
import pytest

from metasheet.mechanics.material import Isotropic
from metasheet.robot.superelement import SuperelementRobot, pose_errors_against
from metasheet.robot.voxel_robot import PrintedRobot
from metasheet.sheet.grips import grip_references
from metasheet.sheet.voxel_grips import rigid_bodies_stiffness
from test_robot_voxel import SMALL, TPU, _printed

TARGET_MM, TARGET_DEG = 0.5, 0.5


@pytest.fixture(scope="module")
def pair():
    robot, sheet, S = _printed(1.0)
    K = rigid_bodies_stiffness(sheet.phases, sheet.size, {1: Isotropic(TPU.E, TPU.nu).stiffness()},
                               bodies=sheet.bodies, references=sheet.references - sheet.origin, rtol=1e-11).K
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    return (PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8), SuperelementRobot(robot, K, K, grip_references(SMALL)),
            rest)


def _check(pair, offsets):
    reference, model, rest = pair
    rows = pose_errors_against(reference, model, rest + np.asarray(offsets, float))
    for r in rows:
        assert r["error_mm"] <= TARGET_MM and r["error_deg"] <= TARGET_DEG, r
    return rows


def test_the_superelement_robot_meets_the_nonlinear_voxel_robot_near_rest(pair):
    """Motors 1 to 2 deg from rest (the rod moves 0.6 mm, turns 0.4 deg; walls strained 9 %):
    measured 0.029 mm and 0.007 deg off."""
    rows = _check(pair, [[2.0, -2.0, 1.0, 0.0, 1.5, -1.2]])
    assert rows[0]["move_mm"] > 0.3


@pytest.mark.slow
def test_the_superelement_robot_is_certified_over_five_degrees(pair):
    """Held-out poses up to 5 deg from rest, the rod's roll both ways included (measured: 0.10 mm
    and 0.057 deg at (5, -5, 2.5, 0, 4, -3), walls strained 24 %; 10 deg misses the orientation
    target: 0.25 mm, 0.54 deg). Default-selection sibling: the 2 deg pose above."""
    # all six motors alike first: the rod's Broyden Jacobian carried from that pose is poor in the
    # directions it never explored, and a full step from it turned the rod past a half turn (the
    # step is bounded now: metasheet.robot.voxel_robot.MAX_TURN)
    _check(pair, [[5.0] * 6, [-5.0] * 6, [5.0, -5.0, 2.5, 0.0, 4.0, -3.0], [-3.0, 4.0, 5.0, -2.0, 0.0, 3.0]])
