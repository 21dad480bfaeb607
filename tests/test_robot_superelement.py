"""The corotational superelement robot (metasheet/robot/superelement.py): rigid motions cost
nothing, the rest pose is an equilibrium, and its Jacobian at rest is the linear condensed
model's (metasheet/robot/condensed.py), on the FEM-condensed sheets of a coarse robot."""

import numpy as np
import pytest

from metasheet.mechanics.rotations import rotation_matrix, rotation_vector
from metasheet.published import paper
from metasheet.robot.builder import SheetPair, material_stiffness, six_dof_robot
from metasheet.robot.condensed import condensed_robot_S
from metasheet.robot.superelement import SuperelementRobot, local_motions
from metasheet.sheet.grips import fem_condensed, grip_references
from metasheet.sheet.outline import SheetParams


@pytest.fixture(scope="module")
def coarse():
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY, gravity=(0.0, 0.0, 0.0))
    Ka = fem_condensed(sheets.sheet, material_stiffness(paper.PAPER_FOAM, sheets.fibers), "p1").K
    Kb = fem_condensed(sheets.mirrored, material_stiffness(paper.PAPER_FOAM, sheets.fibers_mirrored), "p1").K
    return robot, Ka, Kb, grip_references(SheetParams(mesh_size=15.0))


def test_a_rigid_motion_of_the_whole_sheet_has_no_local_motion(coarse):
    refs = coarse[3]
    theta = np.array([0.4, -1.1, 0.7])
    R = rotation_matrix(theta)
    c, s = np.array([3.0, -2.0, 1.0]), np.array([10.0, 4.0, -7.0])
    moved = (refs - c) @ R.T + c + s
    q = local_motions(refs, np.tile(theta, (4, 1)), moved - refs)
    assert np.abs(q).max() < 1e-12 * np.abs(refs).max()
    turned = np.tile(theta, (4, 1))
    turned[2] = rotation_vector(R @ rotation_matrix([0.0, 0.0, 0.1]))  # arm 1 turned 0.1 rad more, in its frame
    assert local_motions(refs, turned, moved - refs)[9:12] == pytest.approx([0.0, 0.0, 0.1], abs=1e-12)


def test_rest_is_an_equilibrium_and_the_jacobian_at_rest_is_the_linear_models(coarse):
    robot, Ka, Kb, refs = coarse
    se = SuperelementRobot(robot, Ka, Kb, refs)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    pose = se.equilibrium(rest)
    assert pose.energy < 1e-20 and np.abs(pose.dp).max() < 1e-12 and np.abs(pose.theta).max() < 1e-12
    S = condensed_robot_S(Ka, Kb, robot, refs)
    J = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    d = 1e-3  # rad; central differences with step halving (Richardson): O(d^4) left

    def central(k, step):
        e = np.zeros(6)
        e[k] = np.degrees(step)
        a, b = se.equilibrium(rest + e), se.equilibrium(rest - e)
        return (np.concatenate([a.dp, a.theta]) - np.concatenate([b.dp, b.theta])) / (2 * step)

    for k in (0, 4):
        col = (4 * central(k, d / 2) - central(k, d)) / 3
        assert np.abs(col - J[:, k]).max() <= 1e-6 * np.abs(J[:, k]).max()


def test_the_batched_rotations_are_scipys():
    """rotate and relative_rotations (plain numpy, over a batch) against scipy's Rotation, at
    small, ordinary and near-half-turn angles."""
    from scipy.spatial.transform import Rotation

    from metasheet.robot.superelement import relative_rotations, rotate

    rng = np.random.default_rng(5)
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    V = axes * np.array([1e-12, 3e-5, 2e-4, 0.7, 2.5, np.pi - 1e-6])[:, None]
    W = V[::-1] * 0.9
    x = rng.normal(size=3) * 50.0
    np.testing.assert_allclose(rotate(V, x), Rotation.from_rotvec(V).apply(x), rtol=0, atol=1e-13)
    ref = (Rotation.from_rotvec(V).inv() * Rotation.from_rotvec(W)).as_rotvec()
    np.testing.assert_allclose(relative_rotations(V, W), ref, rtol=0, atol=1e-12)
