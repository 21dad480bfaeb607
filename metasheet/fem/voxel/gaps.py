"""Where the walls of a deformed voxel body come together: the closest approach of two surface
points that were apart (issue 62, item 4: self-contact, the physics the paper names as the
printed foam's limit at large strain, Section VI).

The surface is the nodes the solid shares with the void inside the grid. Two surface nodes that
were at least ``separation`` apart at rest (default two voxel edges: across a void, or around a
wall's end, never two neighbours of one face) and are now within ``reach`` of each other close a
gap; the smallest such deformed distance is the body's closest approach, and a gap counts as
closed when it falls below ``touch`` (default a quarter of the smallest voxel edge: the voxel
surface's own staircase error). The solver does not model contact: past the first touch the
walls pass through each other, so the motion at which it happens is the model's limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...errors import ConfigError
from .operator import touched_nodes


@dataclass(frozen=True)
class Approach:
    """The closest approach of two formerly separate surface points: ``distance`` [mm] now
    (inf: none within ``reach``), ``rest_distance`` [mm] theirs at rest, ``nodes`` (2,) flat grid
    nodes, ``position`` (3,) [mm] their midpoint now, ``closed``: ``distance <= touch``."""

    distance: float
    rest_distance: float
    nodes: tuple
    position: np.ndarray
    closed: bool


def surface_nodes(solid: np.ndarray) -> np.ndarray:
    """Flat indices of the nodes touched by both a solid and a void voxel of ``solid`` (nx, ny, nz) bool."""
    s = np.asarray(solid, bool)
    return np.flatnonzero((touched_nodes(np.where(s, 0, -1), False) & touched_nodes(np.where(s, -1, 0), False)).ravel())


def closest_approach(solid, h, displacement, *, separation: float | None = None, reach: float | None = None,
                     touch: float | None = None) -> Approach:
    """The closest approach on the deformed ``solid`` (nx, ny, nz) bool with voxel edges ``h`` (3,)
    [mm] under nodal ``displacement`` (nx + 1, ny + 1, nz + 1, 3) [mm] (module docstring);
    ``separation``, ``reach``, ``touch`` [mm] default to 2, 1 and 1/4 of the smallest edge."""
    s = np.asarray(solid, bool)
    h = np.asarray(h, float).reshape(-1)
    N = tuple(n + 1 for n in s.shape)
    u = np.asarray(displacement, float)
    if u.shape != N + (3,):
        raise ConfigError(f"displacement: shape {u.shape}: must be {N + (3,)}")
    if h.shape != (3,) or not np.all(h > 0):
        raise ConfigError(f"h: {h.tolist()}: three voxel edges > 0 [mm]")
    hmin = float(h.min())
    separation = 2.0 * hmin if separation is None else float(separation)
    reach = hmin if reach is None else float(reach)
    touch = 0.25 * hmin if touch is None else float(touch)
    if not 0 < touch <= reach < separation:
        raise ConfigError(f"touch, reach, separation: {touch:g}, {reach:g}, {separation:g} mm: need "
                          "0 < touch <= reach < separation (a closed gap must have been open)")
    nodes = surface_nodes(s)
    X = np.stack(np.unravel_index(nodes, N), 1) * h
    x = X + u.reshape(-1, 3)[nodes]
    pairs = cKDTree(x).query_pairs(reach, output_type="ndarray")
    none = Approach(float("inf"), float("nan"), (), np.full(3, np.nan), False)
    if not len(pairs):
        return none
    rest = np.linalg.norm(X[pairs[:, 0]] - X[pairs[:, 1]], axis=1)
    keep = rest >= separation
    if not keep.any():
        return none
    pairs, rest = pairs[keep], rest[keep]
    now = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    k = int(np.lexsort((pairs[:, 1], pairs[:, 0], now))[0])  # the smallest, ties by node: the same on any run
    a, b = pairs[k]
    return Approach(float(now[k]), float(rest[k]), (int(nodes[a]), int(nodes[b])), 0.5 * (x[a] + x[b]),
                    bool(now[k] <= touch))
