"""The polyhedral gauge one point at a time, compiled: the kernel the skeleton
(:mod:`metasheet.cells.skeleton`) and the printed walls (:mod:`metasheet.sheet.printed_walls`)
share. ``N(v) = max_i g_i . v`` over the facets ``g`` (m, 3) of the unit ball
(:class:`metasheet.cells.metrics.FacetGauge` is the vectorised form)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def polyhedral_gauge(facets, vx, vy, vz):
    """``(N(v), i)``: the gauge of v = (vx, vy, vz) [mm] over ``facets`` (m, 3) [1/mm] and the
    index of the active facet (the first of equal ones)."""
    best, arg = -np.inf, 0
    for i in range(facets.shape[0]):
        g = facets[i, 0] * vx + facets[i, 1] * vy + facets[i, 2] * vz
        if g > best:
            best, arg = g, i
    return best, arg
