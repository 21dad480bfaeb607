"""The rotation helpers of the robot's hot loops give numpy's bits (issue 59: a study point's cost)."""

import numpy as np
import pytest

from metasheet.mechanics.rotations import cross, rotation_matrix, skew


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cross_is_numpys_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    a, b, v = rng.normal(size=(9, 3)), rng.normal(size=(9, 3)), rng.normal(size=3) * 1e3
    for x, y in ((a, b), (v, a), (a, v), (v, v[::-1]), (a[:, None], b[None]), (a * 1e-9, b * 1e9)):
        assert np.array_equal(cross(x, y), np.cross(x, y))


@pytest.mark.parametrize("scale", [0.0, 1e-12, 1e-9, 1e-4, 0.3, 2.0, 3.1])
def test_rotation_matrix_is_rodrigues_with_skew_bit_for_bit(scale):
    rng = np.random.default_rng(7)
    for _ in range(50):
        w = rng.normal(size=3) * scale
        t, K = float(np.linalg.norm(w)), skew(w)
        ref = (np.eye(3) + K + 0.5 * K @ K if t < 1e-8
               else np.eye(3) + np.sin(t) / t * K + (1.0 - np.cos(t)) / t**2 * K @ K)
        R = rotation_matrix(w)
        assert np.array_equal(R, ref)
        R[0, 0] = 5.0  # the result is the caller's: the identity inside stays the identity
    assert np.array_equal(rotation_matrix(np.zeros(3)), np.eye(3))
