"""The printed robot at a motor pose (metasheet/robot/voxel_robot.py): two finite-strain voxel
sheets on the rod and the horns. At rest it is in equilibrium with no motion; its motor
derivatives at rest are the linear condensed model's Jacobian (a second method:
metasheet/robot/condensed.py on the linear voxel DNS, metasheet/sheet/voxel_grips.py)."""

import numpy as np
import pytest

from metasheet.fem.voxel.hyperelastic import NeoHookean
from metasheet.mechanics.material import Isotropic
from metasheet.published import paper
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.condensed import condensed_robot_S
from metasheet.robot.voxel_robot import PrintedRobot, VoxelSheet
from metasheet.sheet.dns import grip_labels
from metasheet.sheet.grips import grip_references
from metasheet.sheet.outline import SheetParams
from metasheet.sheet.printed_foam import tripod_region
from metasheet.sheet.voxel_grips import rigid_bodies_stiffness
from metasheet.cells.foam import voxel_centres

TPU = NeoHookean(12.0, 0.3)
SMALL = SheetParams(arm_width=10.0, reach=20.0, thickness=2.0, hole_radius=1.0, fillet_radius=1.0,
                    tip_box=(5.0, 15.0, 10.0), centre_radius=3.0, mesh_size=5.0)


def _printed(h: float, params: SheetParams = SMALL):
    """The small tripod (``params``), solid TPU voxels of edge ``h`` (both sheets: the region is
    symmetric), its robot, and the linear condensed model's rest Schur complement."""
    reg = tripod_region(params)
    ext = reg.hi - reg.lo
    shape = tuple(int(v) for v in np.maximum(1, np.round(ext / h)))
    phases = reg.inside(reg.lo + voxel_centres(ext, np.array(shape))).reshape(shape).astype(np.int64)
    bodies = grip_labels(shape, reg.lo, ext / np.array(shape), params)
    refs = grip_references(params)
    sheet = VoxelSheet(phases, ext, reg.lo, bodies, refs, TPU)
    robot = six_dof_robot(SheetPair.spiral(params), paper.PAPER_FOAM, density=paper.FOAM_DENSITY,
                          gravity=(0.0, 0.0, 0.0))
    K = rigid_bodies_stiffness(phases, ext, {1: Isotropic(TPU.E, TPU.nu).stiffness()}, bodies=bodies,
                               references=refs - reg.lo, rtol=1e-11).K
    return robot, sheet, condensed_robot_S(K, K, robot, refs)


def _motor_columns(h: float, motors, d: float = 1e-3):
    robot, sheet, S = _printed(h)
    printed = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-10)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    at_rest = printed.equilibrium(rest)
    # no motion, no force (the degrees' round trip leaves the motors 1e-16 rad from rest at most)
    assert at_rest.iterations == 0 and np.abs(at_rest.wrenches).max() < 1e-12
    assert max(at_rest.wall_strain) < 1e-12 and not any(a.closed for a in at_rest.approach)
    assert at_rest.stable == (True, True)  # the rest tangent is positive: the probe finds no saddle
    J_lin = -np.linalg.solve(S[:6, :6], S[:6, 6:])  # dq_e / dq_a of the linear rest model
    def central(k, step):
        e = np.zeros(6)
        e[k] = np.degrees(step)
        q = [np.concatenate([p.dp, p.theta]) for p in (printed.equilibrium(rest + e), printed.equilibrium(rest - e))]
        return (q[0] - q[1]) / (2 * step)

    # central differences with Richardson's step halving: the O(d^2) term (measured 5.6e-4 of 3.5
    # mm/rad at d = 1e-3 rad, scaling as d^2) cancels, O(d^4) is left
    cols = [(4 * central(k, d / 2) - central(k, d)) / 3 for k in motors]
    return np.array(cols).T, J_lin[:, motors]


def test_the_printed_robots_motor_derivatives_at_rest_are_the_linear_models():
    got, want = _motor_columns(1.0, [4])  # a motor of sheet B (the slow test: all six)
    scale = np.abs(want).max(axis=0)
    assert np.all(np.abs(got - want).max(axis=0) <= 1e-6 * scale)


@pytest.mark.slow
def test_the_printed_robots_jacobian_at_rest_on_finer_voxels():
    got, want = _motor_columns(0.5, range(6))
    assert np.abs(got - want).max() <= 1e-6 * np.abs(want).max()


def test_the_sheets_in_processes_of_their_own_give_the_same_bits():
    robot, sheet, S = _printed(1.0)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    motors = rest + np.array([3.0, -2.0, 0.0, 1.0, 0.0, -1.5])
    here = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8).equilibrium(motors)
    apart = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8, processes=True)
    try:
        there = apart.equilibrium(motors)
    finally:
        apart.close()
    assert there.iterations == here.iterations and there.newton == here.newton
    for a, b in ((there.dp, here.dp), (there.theta, here.theta), (there.wrenches, here.wrenches)):
        np.testing.assert_array_equal(a, b)
    assert there.stable == here.stable and there.wall_strain == here.wall_strain
    assert not apart.bodies[0]._proc.is_alive() and not apart.bodies[1]._proc.is_alive()


def test_a_step_tolerance_stops_the_rod_within_it_of_the_balance_in_fewer_iterations():
    robot, sheet, S = _printed(1.0)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    motors = rest + np.array([3.0, -2.0, 0.0, 1.0, 0.0, -1.5])
    tight = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8).equilibrium(motors)
    reach = float(np.linalg.norm(sheet.references[1]))
    for tol in (1e-2, 1e-3):
        loose = PrintedRobot(robot, (sheet, sheet), S_rest=S, rtol=1e-8).equilibrium(motors, step_tol=tol)
        predicted = max(np.linalg.norm(loose.rod_step[:3]), reach * np.linalg.norm(loose.rod_step[3:]))
        off = max(np.linalg.norm(loose.dp - tight.dp), reach * np.linalg.norm(loose.theta - tight.theta))
        assert predicted <= tol and off <= 2 * tol  # the step to the balance is first order: within 2x
        assert loose.iterations < tight.iterations and tight.rod_step is None
    with pytest.raises(Exception, match="step_tol"):
        PrintedRobot(robot, (sheet, sheet), S_rest=S).equilibrium(motors, step_tol=0.0)
