"""Hinges and one-voxel walls of a voxel model (metasheet/fem/voxel/hinges.py), counted by hand."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.fem.voxel.hinges import edge_hinges, thin_share


def test_two_voxels_on_an_edge_are_one_hinge_and_a_bridge_removes_it():
    ph = np.zeros((3, 3, 3), int)
    ph[0, 0, 1] = ph[1, 1, 1] = 1  # diagonal in the xy plane: they share the edge along z
    assert edge_hinges(ph) == 1
    ph[1, 0, 1] = 1  # a voxel next to both: a face path
    assert edge_hinges(ph) == 0
    ph2 = np.zeros((3, 3, 3), int)
    ph2[0, 0, 0] = ph2[1, 1, 1] = 1  # a corner only: not an edge hinge
    assert edge_hinges(ph2) == 0


def _brute_force(ph):
    """Every pair of solid voxels: differing by 1 in two indices and equal in the third, with
    both voxels that would bridge them by faces void (or outside the grid)."""
    solid = [tuple(v) for v in np.argwhere(ph > 0)]
    S = set(solid)
    count = 0
    for i, a in enumerate(solid):
        for b in solid[i + 1:]:
            d = np.subtract(b, a)
            if sorted(np.abs(d)) != [0, 1, 1]:
                continue
            axes = np.flatnonzero(d)
            bridges = []
            for ax in axes:
                c = list(a)
                c[ax] += d[ax]
                bridges.append(tuple(c))
            count += not any(c in S for c in bridges)
    return count


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_plane_and_both_diagonals_against_a_brute_force_count(seed):
    ph = (np.random.default_rng(seed).random((6, 5, 4)) < 0.3).astype(int)
    assert edge_hinges(ph) == _brute_force(ph) > 0
    edge = np.zeros((3, 3, 3), int)
    edge[0, 0, 0] = edge[2, 2, 0] = 1  # opposite corners of the grid: no pair through the border
    assert edge_hinges(edge) == 0


def test_thin_share_of_a_plate_a_block_and_nothing():
    plate = np.zeros((5, 5, 3), int)
    plate[:, :, 1] = 1
    assert thin_share(plate) == 1.0
    block = np.zeros((5, 5, 5), int)
    block[1:4, 1:4, 1:4] = 1
    assert thin_share(block) == 0.0
    assert thin_share(np.zeros((2, 2, 2), int)) == 0.0
    with pytest.raises(ConfigError, match="phases"):
        thin_share(np.zeros((2, 2)))
