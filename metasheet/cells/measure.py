"""Geometric measurements of periodic phase grids."""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError


def mean_chord_lengths(mask: np.ndarray, size) -> np.ndarray:
    """Mean length of the runs of ``True`` voxels along x, y and z, periodic: (3,) [mm].

    For the void of a foam (``phases == 0``) this is the mean intercept length of the cells
    along each axis, a direct measure of their extent; for an isotropic foam the three
    agree, and a metric stretched by ``s`` along an axis makes that one ``s`` times longer.
    A line with no interruption counts as one run of the whole period. Returns NaN along
    an axis with no ``True`` voxel.
    """
    mask = np.asarray(mask, dtype=bool)
    size = np.asarray(size, dtype=float)
    if mask.ndim != 3 or size.shape != (3,):
        raise ConfigError(f"mask: shape is {mask.shape} and should be (nx, ny, nz), with size (3,)")
    out = np.full(3, np.nan)
    for ax in range(3):
        starts = mask & ~np.roll(mask, 1, axis=ax)  # run starts, periodic
        runs = int(starts.sum())
        full_lines = int(np.all(mask, axis=ax).sum())  # lines without a start
        runs += full_lines
        if runs:
            out[ax] = mask.sum() * (size[ax] / mask.shape[ax]) / runs
    return out
