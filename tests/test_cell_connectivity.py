"""Periodic connectivity and percolation of phase grids (issue 3, item 6)."""

import numpy as np
import pytest

from metasheet.cells.connectivity import check_percolation, keep_largest
from metasheet.errors import InfeasibleError


def _empty(n=10):
    return np.zeros((n, n, n), dtype=np.uint8)


def test_rod_along_x_percolates_along_x_only():
    g = _empty()
    g[:, 5, 5] = 1
    r = check_percolation(g)
    assert r.components == 1 and r.percolates == (True, False, False)
    assert not r.ok
    with pytest.raises(InfeasibleError, match="does not percolate along y, z"):
        r.require("homogenize")


def test_blob_across_the_boundary_is_one_piece_that_percolates_nowhere():
    g = _empty()
    g[8:, :2, :2] = 1
    g[:2, :2, :2] = 1  # joins the first part across x = 0 / x = L only
    r = check_percolation(g)
    assert r.components == 1
    assert r.percolates == (False, False, False)


def test_three_rods_make_a_percolating_frame():
    g = _empty()
    g[:, 5, 5] = g[5, :, 5] = g[5, 5, :] = 1
    r = check_percolation(g)
    assert r.ok and r.windings == ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    assert r.to_dict()["percolates"] == {"x": True, "y": True, "z": True}


def test_diagonal_staircase_winds_along_x_and_y():
    g = _empty()
    for i in range(10):
        g[i, i, 5] = g[i, (i + 1) % 10, 5] = 1  # face-connected staircase
    r = check_percolation(g)
    assert r.components == 1 and r.windings == ((1, 1, 0),)
    assert r.percolates == (True, True, False)


def test_edge_contact_is_not_a_connection():
    g = _empty()
    g[:, 2, 2] = 1
    g[:, 3, 3] = 1  # touches the first rod along edges only
    assert check_percolation(g).components == 2


def test_islands_are_counted_and_dropped():
    g = _empty()
    g[:, 5, 5] = g[5, :, 5] = g[5, 5, :] = 1
    g[0, 0, 0] = 2  # an island (phase 2 counts as solid)
    r = check_percolation(g)
    assert r.components == 2 and not r.ok
    assert "2 pieces" in r.problems()[0]
    kept, removed = keep_largest(g)
    assert removed == 1 and kept[0, 0, 0] == 0
    assert check_percolation(kept).ok


def test_empty_and_full_grids():
    assert check_percolation(_empty()).problems() == ["there is no solid"]
    full = check_percolation(np.ones((4, 4, 4), dtype=np.uint8))
    assert full.ok and full.solid_fraction == 1.0
