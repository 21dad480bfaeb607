"""Non-periodic voxel bodies: a clamped cantilever whose free end is tied to a rigid body.

Its condensed 6 x 6 stiffness (metasheet.sheet.voxel_clamped) against beam theory under
refinement: Timoshenko tip compliance (shear factor 5/6) and Saint-Venant torsion of a square
section. Trilinear voxels lock in bending, so the tip compliance approaches the beam's from
below (measured 0.69, 0.89, 0.96 of it with 2, 4, 8 voxels across the section).
"""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.sheet.voxel_clamped import rigid_body_stiffness
from metasheet.mechanics.material import Isotropic

TPU = Isotropic(12.0, 0.3)
L, B = 8.0, 1.0  # length and square side [mm]


def _cantilever(k: int):
    nx, ny = 8 * k, 2 * k
    ph = np.ones((nx, ny, ny), np.int64)
    N = (nx + 1, ny + 1, ny + 1)
    clamped = np.zeros(N, bool)
    clamped[0] = True
    tied = np.zeros(N, bool)
    tied[-1] = True
    return rigid_body_stiffness(ph, (L, B, B), {1: TPU.stiffness()}, clamped=clamped, tied=tied)


@pytest.mark.slow
def test_cantilever_converges_to_beam_theory():
    """Default-selection sibling: test_coarse_cantilever_against_beam_theory (2 voxels across)."""
    E, G, A, I = TPU.E, TPU.mu, B * B, B**4 / 12.0
    beam = L**3 / (3 * E * I) + L / (5.0 / 6.0 * G * A)  # tip deflection per tip force [mm/N]
    torsion = 0.1406 * G * B**4 / L  # Saint-Venant, square section [N mm]
    errors = []
    for k in (1, 2):
        r = _cantilever(k)
        K = r.K
        assert np.allclose(K, K.T) and np.linalg.eigvalsh(K)[0] > 0
        tip = np.linalg.inv(K[np.ix_([1, 5], [1, 5])])[0, 0]  # free end rotation, force only
        errors.append(abs(tip / beam - 1.0))
        # the clamp also blocks the Poisson contraction at the root: a little stiffer than EA / L
        assert 1.0 < K[0, 0] / (E * A / L) < 1.03
    assert errors[1] < 0.5 * errors[0] and errors[1] < 0.13
    assert K[3, 3] == pytest.approx(torsion, rel=0.08)
    assert max(r.iterations) <= 15


def test_coarse_cantilever_against_beam_theory():
    """2 voxels across the section: symmetric positive definite, the tip compliance locked at
    0.69 of Timoshenko's (the measured value, +-0.03), the axial stiffness 2.4 % above EA / L
    (the clamped root's Poisson contraction) and the torsion 19 % above Saint-Venant's."""
    E, G, A, I = TPU.E, TPU.mu, B * B, B**4 / 12.0
    beam = L**3 / (3 * E * I) + L / (5.0 / 6.0 * G * A)
    K = _cantilever(1).K
    assert np.allclose(K, K.T) and np.linalg.eigvalsh(K)[0] > 0
    tip = np.linalg.inv(K[np.ix_([1, 5], [1, 5])])[0, 0]
    assert tip / beam == pytest.approx(0.69, abs=0.03)
    assert 1.0 < K[0, 0] / (E * A / L) < 1.03
    assert K[3, 3] == pytest.approx(0.1406 * G * B**4 / L, rel=0.25)


def test_clamped_input_errors():
    ph = np.ones((4, 2, 2), np.int64)
    N = (5, 3, 3)
    both = np.zeros(N, bool)
    both[0] = True
    with pytest.raises(ConfigError, match="clamped, tied: a node is both"):
        rigid_body_stiffness(ph, (4, 1, 1), {1: TPU.stiffness()}, clamped=both, tied=both)
    with pytest.raises(ConfigError, match=r"tied: shape \(4, 3, 3\)"):
        rigid_body_stiffness(ph, (4, 1, 1), {1: TPU.stiffness()}, clamped=both, tied=np.zeros((4, 3, 3), bool))
