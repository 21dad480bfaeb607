"""The one check of a voxel phase grid (``metasheet.fem.voxel.element.check_phases``), shared by
the matrix-free voxel problems and the assembled homogenisation (issue 61: they were two copies)."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.fem.voxel.element import check_phases

GRID = np.array([[[0, 1], [2, 1]], [[1, 0], [0, 2]]])


def test_a_valid_grid_comes_back_with_its_phases():
    ph, s, present = check_phases(GRID, (1.0, 2, 3), {1: "a", 2: "b"})
    assert ph.dtype.kind == "i" and s.tolist() == [1.0, 2.0, 3.0] and present == [1, 2]
    ph, _, _ = check_phases(GRID.astype(float), (1, 1, 1), {1: 0, 2: 0}, integral_floats=True)
    assert ph.dtype == np.int64 and np.array_equal(ph, GRID)


@pytest.mark.parametrize(("phases", "size", "kw", "message"), [
    (GRID[0], (1, 1, 1), {}, r"phases: shape is \(2, 2\) and should be \(nx, ny, nz\)"),
    (GRID[:1], (1, 1, 1), {}, r"phases: shape \(1, 2, 2\): every dimension must be >= 2 voxels"),
    (GRID.astype(float), (1, 1, 1), {}, r"phases: dtype float64: must hold integers"),
    (GRID + 0.5, (1, 1, 1), {"integral_floats": True}, r"phases: dtype float64: must hold integers"),
    (GRID - 1, (1, 1, 1), {}, r"phases: -1: allowed values are 0 \(void\) and keys of stiffnesses"),
    (GRID, (1, 0, 1), {}, r"size: \(1, 0, 1\): must be three finite lengths > 0 \[mm\]"),
    (GRID, (1, np.nan, 1), {}, r"size: .*must be three finite lengths"),
    (GRID * 2, (1, 1, 1), {"name": "materials", "item": "material"},
     r"materials: phases \[4\] have no material \(given: \[1, 2\]\)"),
])
def test_each_bad_grid_names_its_field(phases, size, kw, message):
    with pytest.raises(ConfigError, match=message):
        check_phases(phases, size, {1: 0, 2: 0}, **kw)
