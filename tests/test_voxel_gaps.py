"""Self-contact on a deformed voxel body (metasheet/fem/voxel/gaps.py): a two-wall toy whose gap
closes at a displacement known by hand, solved by the finite-strain DNS."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.fem.voxel.gaps import closest_approach, surface_nodes
from metasheet.fem.voxel.hyperelastic import NeoHookean
from metasheet.fem.voxel.nonlinear import solve_hyperelastic

H = np.array([0.25, 0.25, 0.25])


def _two_walls():
    """Two walls 2 voxels thick across x, a gap of 4 voxels (1 mm) between them, joined by nothing."""
    ph = np.zeros((8, 3, 3), np.int64)
    ph[0:2] = 1
    ph[6:8] = 1
    return ph


def test_the_gap_between_two_walls_closes_when_they_have_moved_by_it():
    ph = _two_walls()
    N = tuple(n + 1 for n in ph.shape)
    gap = 4 * H[0]
    for d in (0.2, 0.45, 0.49):  # each wall's outer face moved inwards by d [mm]
        fixed = np.zeros(N + (3,), bool)
        values = np.zeros(N + (3,))
        fixed[0] = fixed[-1] = True
        values[0, ..., 0], values[-1, ..., 0] = d, -d
        sol = solve_hyperelastic(ph, ph.shape * H, NeoHookean(12.0, 0.3), prescribed=fixed, values=values)
        u = sol.full(sol.u)
        ap = closest_approach(ph > 0, H, u)
        # the walls' inner faces: pushed by their outer faces, they move by d too (a wall is free
        # across; its inner face keeps the outer's x-motion exactly: no load crosses the gap)
        if gap - 2 * d > H.min():  # beyond the search's reach (a voxel edge): no approach reported
            assert ap.distance == np.inf and not ap.closed
            continue
        assert ap.distance == pytest.approx(gap - 2 * d, abs=1e-9)
        assert ap.rest_distance == pytest.approx(gap) and ap.closed == (gap - 2 * d <= 0.25 * H.min())
    assert closest_approach(ph > 0, H, np.zeros(N + (3,))).distance == np.inf  # 1 mm apart: beyond reach


def test_neighbours_on_one_face_are_not_a_contact_and_the_surface_is_the_solids_border():
    ph = np.zeros((4, 4, 4), np.int64)
    ph[1:3, 1:3, 1:3] = 1
    assert len(surface_nodes(ph > 0)) == 26  # a 2 x 2 x 2 block: its 27 nodes but the centre
    N = (5, 5, 5)
    squeeze = np.zeros(N + (3,))
    squeeze[..., 0] = -0.5 * (np.arange(5)[:, None, None] - 2.0) * 0.2  # neighbours closer, none across a void
    assert not closest_approach(ph > 0, H, squeeze).closed
    with pytest.raises(ConfigError, match="touch, reach, separation"):
        closest_approach(ph > 0, H, squeeze, touch=0.3, reach=0.2)
