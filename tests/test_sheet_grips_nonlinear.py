"""Rigid grips at finite poses on a neo-Hookean voxel body (metasheet/sheet/voxel_grips_nonlinear.py):
its tangent at rest is the linear DNS's condensed stiffness (a second method,
metasheet/sheet/voxel_grips.py), every grip moved by one rigid motion carries no wrench, and the
wrenches balance (the body is in equilibrium)."""

import numpy as np
import pytest
from homogenize_samples import edge_foam

from metasheet.errors import ConfigError
from metasheet.fem.voxel.hyperelastic import NeoHookean
from metasheet.mechanics.material import Isotropic
from metasheet.mechanics.rotations import rotation_matrix
from metasheet.sheet.voxel_grips import rigid_bodies_stiffness
from metasheet.sheet.voxel_grips_nonlinear import grip_wrenches

TPU = NeoHookean(12.0, 0.3)


def _foam_bar():
    """A foam bar of walls (an edge foam), grip 0 on the x = 0 face, grip 1 on the x = L face."""
    ph = edge_foam(12, 0.35, rng_seed=4).astype(np.int64)[:, :8, :6]
    size = np.array(ph.shape) * 0.25
    bodies = np.zeros(tuple(n + 1 for n in ph.shape), np.int64)
    bodies[0] = 1
    bodies[-1] = 2
    h = size / np.array(ph.shape)
    refs = np.array([np.argwhere(bodies == b).mean(axis=0) * h for b in (1, 2)])
    return ph, size, bodies, refs


def test_the_tangent_at_rest_is_the_linear_dns_condensed_stiffness():
    ph, size, bodies, refs = _foam_bar()
    K = rigid_bodies_stiffness(ph, size, {1: Isotropic(TPU.E, TPU.nu).stiffness()}, bodies=bodies,
                               references=refs, rtol=1e-11, relative=False).K
    d = 1e-5  # central differences: O(d^2) from the nonlinearity
    cols = []
    for k in range(6, 12):  # grip 1's six motions, grip 0 held
        q = np.zeros((2, 6))
        q[1, k - 6] = d
        w = [grip_wrenches(ph, size, TPU, bodies=bodies, references=refs, rotations=s * q[:, 3:],
                           translations=s * q[:, :3], rtol=1e-10).wrenches.ravel() for s in (1, -1)]
        cols.append((w[0] - w[1]) / (2 * d))
    np.testing.assert_allclose(np.array(cols).T, K[:, 6:], rtol=0, atol=1e-6 * np.abs(K).max())


def test_one_rigid_motion_of_every_grip_carries_no_wrench_and_the_wrenches_balance():
    ph, size, bodies, refs = _foam_bar()
    theta = np.array([0.3, -0.5, 0.4])  # 41 deg
    R = rotation_matrix(theta)
    c = np.array([1.0, 2.0, -1.5])  # every grip turned about one point c and moved by s
    s = np.array([0.5, -1.0, 2.0])
    t = np.array([c + s + R @ (r - c) - r for r in refs])
    rigid = grip_wrenches(ph, size, TPU, bodies=bodies, references=refs, rotations=[theta, theta], translations=t)
    scale = TPU.E * size.prod() ** (2 / 3)
    assert np.abs(rigid.wrenches).max() < 1e-9 * scale
    # a deforming pose: the two grips' wrenches balance (no other load), moments about one point
    bent = grip_wrenches(ph, size, TPU, bodies=bodies, references=refs, rotations=[[0, 0, 0], [0.0, 0.25, 0.1]],
                         translations=[[0, 0, 0], [-0.3, 0.2, 0.4]])
    w = bent.wrenches
    assert np.abs(w).max() > 1e-3 * scale
    moved = refs + np.array([[0, 0, 0], [-0.3, 0.2, 0.4]])
    assert np.abs(w[0, :3] + w[1, :3]).max() < 1e-7 * np.abs(w[:, :3]).max()
    total = sum(w[b, 3:] + np.cross(moved[b], w[b, :3]) for b in range(2))  # about the origin
    assert np.abs(total).max() < 1e-7 * np.abs(w[:, 3:]).max()
    assert bent.solution.newton >= 2 and bent.kept_share > 0.9


def test_bad_poses_are_named():
    ph, size, bodies, refs = _foam_bar()
    with pytest.raises(ConfigError, match=r"rotations: shape \(3, 3\)"):
        grip_wrenches(ph, size, TPU, bodies=bodies, references=refs, rotations=np.zeros((3, 3)),
                      translations=np.zeros((2, 3)))
    with pytest.raises(ConfigError, match="longer than pi"):
        grip_wrenches(ph, size, TPU, bodies=bodies, references=refs, rotations=[[0, 0, 0], [0, 4.0, 0]],
                      translations=np.zeros((2, 3)))
