"""Periodic Voronoi foams as level sets: struts on the Voronoi edges, walls on its faces.

A :class:`Foam` is seeds, a metric, a topology and a thickness; its solid is a threshold on
the true distances to the Voronoi skeleton (:mod:`metasheet.cells.skeleton`):

- **walls** (closed cells): the wall distance ``a`` is the exact distance to the cell
  boundary, so the solid ``{a < t/2}`` has walls of thickness ``t``;
- **struts** (open cells): the solid ``{r < R}``, ``r`` the strut distance, is a union of
  round struts of radius ``R`` on the Voronoi edges, blended at the nodes.

Both fields are periodic (the seeds are tiled with their 26 images), continuous across
cell walls, and have unit slope near the solid, so ``field < 0`` is the solid, the
field is roughly the signed distance in mm, and marching cubes works on it directly.
The strut radius or wall thickness giving a relative density is solved in
:mod:`metasheet.cells.thickness`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, check_range
from .kgon import KgonMetric
from .metrics import Metric, PolyhedralMetric, StretchedMetric
from .seeds import wrap
from .skeleton import SkeletonIndex

TOPOLOGIES = ("open", "closed")


@dataclass(frozen=True, eq=False)
class Foam:
    """A periodic Voronoi foam in the box ``[0, size)``.

    Parameters
    ----------
    seeds : (N, 3) float [mm], folded into the box.
    size : (3,) float [mm], the period.
    metric : a :mod:`metasheet.cells.metrics` metric (default: Euclidean).
    topology : ``'open'`` (struts on the Voronoi edges) or ``'closed'`` (walls on its faces).
    thickness : [mm], the strut *radius* (open) or the full wall *thickness* (closed), >= 0.
    axis : longitudinal axis index (0, 1, 2); default the metric's axis.
    """

    seeds: np.ndarray
    size: np.ndarray
    metric: Metric = field(default_factory=StretchedMetric)
    topology: str = "open"
    thickness: float = 0.0
    axis: int | None = None

    def __post_init__(self):
        size = np.asarray(self.size, dtype=float)
        if size.shape != (3,) or np.any(~np.isfinite(size)) or np.any(size <= 0):
            raise ConfigError(f"size: {np.asarray(self.size).tolist()!r}: expected 3 numbers > 0 [mm]")
        seeds = np.asarray(self.seeds, dtype=float)
        if seeds.ndim != 2 or seeds.shape[1] != 3 or len(seeds) < 1:
            raise ConfigError(f"seeds: shape is {seeds.shape} and should be (N, 3), N >= 1 [mm]")
        if not np.all(np.isfinite(seeds)):
            raise ConfigError("seeds: non-finite coordinates")
        if not isinstance(self.metric, (StretchedMetric, PolyhedralMetric, KgonMetric)):
            raise ConfigError(f"metric: {self.metric!r}: expected a StretchedMetric, PolyhedralMetric or KgonMetric")
        if self.topology not in TOPOLOGIES:
            raise ConfigError(f"topology: {self.topology!r}: expected one of {', '.join(TOPOLOGIES)}")
        check_range("thickness", self.thickness, 0.0, float(size.max()))
        axis = self.metric.axis if self.axis is None else self.axis
        if axis not in (0, 1, 2):
            raise ConfigError(f"axis: {axis!r}: expected 0, 1 or 2 (x, y, z; 0-based)")
        seeds = wrap(seeds, size)
        seeds.setflags(write=False)
        size.setflags(write=False)
        object.__setattr__(self, "seeds", seeds)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "thickness", float(self.thickness))
        object.__setattr__(self, "axis", int(axis))

    @property
    def axis_vector(self) -> np.ndarray:
        """(3,) unit vector of the longitudinal axis."""
        return np.eye(3)[self.axis]

    def with_thickness(self, thickness: float) -> Foam:
        """The same foam with another strut radius / wall thickness [mm]."""
        return Foam(self.seeds, self.size, self.metric, self.topology, thickness, self.axis)


class FoamField:
    """The foam's level set, a picklable callable ``(n, 3) [mm] -> (n,)``: negative in the solid.

    ``open``: ``strut distance - radius``; ``closed``: ``wall distance - thickness / 2``.
    Periodic with period ``foam.size``.
    """

    def __init__(self, foam: Foam):
        self.foam = foam
        self.index = SkeletonIndex(foam.seeds, foam.size, foam.metric)
        self.offset = foam.thickness if foam.topology == "open" else 0.5 * foam.thickness
        # Exact within twice the offset (plus a voxel-ish margin); overestimated beyond.
        self.cap = 2.0 * self.offset + 0.05 * float(np.min(foam.size))

    def __call__(self, points: np.ndarray) -> np.ndarray:
        d = self.index.distances(points, cap=self.cap)
        base = d.strut if self.foam.topology == "open" else d.wall
        return base - self.offset


def foam_field(foam: Foam) -> Callable[[np.ndarray], np.ndarray]:
    """The periodic level set of ``foam``: ``field(points (n, 3) [mm]) -> (n,) [mm]``.

    Negative inside the solid, roughly the signed distance to its surface near it
    (unit slope), periodic with period ``foam.size``; the solid is ``{field < 0}``.
    """
    return FoamField(foam)


def voxel_centres(size, n) -> np.ndarray:
    """Centres of an ``n^3`` (or ``nx x ny x nz``) grid over the box, (n^3, 3) [mm], C order of ``(i, j, k)``.

    ``n`` : int, or (3,) ints for a non-cubic grid. Voxel ``(i, j, k)`` is centred at
    ``((i + 1/2) sx, (j + 1/2) sy, (k + 1/2) sz)`` with ``s = size / n``.
    """
    size = np.asarray(size, dtype=float)
    shape = np.broadcast_to(np.asarray(n, dtype=int), (3,))
    axes = [(np.arange(m) + 0.5) * (L / m) for L, m in zip(size, shape)]
    g = np.meshgrid(*axes, indexing="ij")
    return np.stack([c.ravel() for c in g], axis=1)


def check_resolution(n, field_name: str = "resolution", lo: int = 4, hi: int = 512) -> int:
    if int(n) != n or not lo <= int(n) <= hi:
        raise ConfigError(f"{field_name}: {n!r}: expected an integer in [{lo}, {hi}]")
    return int(n)


def voxelize(foam: Foam, n: int) -> np.ndarray:
    """Phase grid of ``foam``: (n, n, n) uint8, 1 where ``foam_field < 0`` at voxel centres, else 0.

    Index ``[i, j, k]`` runs along x, y, z (see :func:`voxel_centres`).
    """
    n = check_resolution(n)
    f = foam_field(foam)(voxel_centres(foam.size, n))
    return (f < 0.0).astype(np.uint8).reshape(n, n, n)


def cell_labels(seeds: np.ndarray, size, metric: Metric, n: int) -> np.ndarray:
    """Index of the nearest seed (the Voronoi cell) at each voxel centre, (n, n, n) int."""
    n = check_resolution(n)
    index = SkeletonIndex(seeds, size, metric)
    d = index.distances(voxel_centres(size, n), cap=0.0, k=8)
    return d.cell.reshape(n, n, n)
