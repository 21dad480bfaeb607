"""Distances that shape Voronoi cells: a stretched Euclidean metric and a polyhedral (k-gon) gauge.

A metric here is a translation-invariant norm ``N(v)`` of the displacement ``v = x - s``
[mm] between a point and a seed. Translation invariance keeps the foam periodic: the
Voronoi diagram of periodic seeds under ``N`` is periodic with the same box.

Every metric offers the same small interface, used by :mod:`metasheet.cells.skeleton`:

- ``distance(v)``: ``(..., 3) -> (...)`` the norm;
- ``gradient(v)``: ``(..., 3) -> (..., 3)`` its gradient (for the polyhedral gauge, the
  active facet, piecewise constant);
- ``scale``: (3,) axis scaling ``D`` such that ``lower * |D v| <= N(v) <= upper * |D v|``,
  used to find candidate seeds with a Euclidean k-d tree in the scaled space;
- ``quadratic``: True when ``N(v)^2 = v^T M v`` (``M = diag(scale^2)``), whose bisectors are
  exact planes;
- ``axis``: index (0, 1, 2) of the longitudinal axis ``l`` it singles out;
- ``describe()``: a JSON-able dict of the parameters (``axis`` there 1-based, as in configs).

Axis numbering: ``axis`` is a 0-based index here (0 = x, 1 = y, 2 = z); configuration files
use the paper's 1-based numbering (``axis = 3`` is z).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range

MODES = ("axial", "transverse")


def _axis(axis) -> int:
    if axis not in (0, 1, 2):
        raise ConfigError(f"metric.axis: {axis!r}: expected 0, 1 or 2 (x, y, z; 0-based)")
    return int(axis)


def transverse_axes(axis: int) -> tuple[int, int]:
    """The two axes normal to ``axis``, in cyclic order (local x, local y)."""
    return (axis + 1) % 3, (axis + 2) % 3


@dataclass(frozen=True)
class StretchedMetric:
    """Euclidean distance with one or two axes stretched by ``stretch``.

    ``N(v) = |v / e|`` with per-axis extents ``e``:

    - ``mode = 'axial'``: ``e[axis] = stretch``, 1 elsewhere. Cells are elongated along the
      axis: a seed's cell reaches ``stretch`` times further along ``axis`` than across it
      (prolate cells, like a honeycomb's tubes when ``stretch`` is large).
    - ``mode = 'transverse'``: ``e = stretch`` on both axes normal to ``axis``, 1 on it.
      Cells are elongated in the transverse plane and short along the axis (oblate cells,
      stacked pancakes).

    With seeds drawn uniformly in the box (or regularly in the scaled space ``v / e``), the
    mean cell extent along each axis is proportional to ``e``: stretching by ``s`` scales the
    cell extents by ``s`` (see ``tests/test_cell_foam.py``). ``stretch = 1`` is the usual
    isotropic Voronoi foam, whatever the mode.

    Parameters
    ----------
    stretch : s [-], >= 1.
    axis : longitudinal axis index (0, 1, 2).
    mode : ``'axial'`` or ``'transverse'``.
    """

    stretch: float = 1.0
    axis: int = 2
    mode: str = "axial"

    def __post_init__(self):
        check_range("metric.stretch", self.stretch, 1.0, 1e3)
        _axis(self.axis)
        if self.mode not in MODES:
            raise ConfigError(f"metric.mode: {self.mode!r}: expected one of {', '.join(MODES)}")

    @property
    def extent(self) -> np.ndarray:
        """(3,) relative cell extent per axis [-]."""
        e = np.ones(3)
        if self.mode == "axial":
            e[self.axis] = self.stretch
        else:
            e[list(transverse_axes(self.axis))] = self.stretch
        return e

    @property
    def scale(self) -> np.ndarray:
        """(3,) ``1 / extent``: the metric is Euclidean in ``v * scale``."""
        return 1.0 / self.extent

    quadratic = True
    lower = 1.0
    upper = 1.0

    def distance(self, v: np.ndarray) -> np.ndarray:
        """``(..., 3) [mm] -> (...)``: ``|v * scale|``."""
        w = np.asarray(v) * self.scale
        return np.sqrt(np.einsum("...i,...i->...", w, w))

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """``(..., 3) -> (..., 3)``: ``M v / N(v)`` (zero at the seed)."""
        v = np.asarray(v)
        d = self.distance(v)[..., None]
        return np.divide(v * self.scale**2, d, out=np.zeros_like(v, dtype=float), where=d > 0)

    def describe(self) -> dict:
        return {"kind": "stretched", "stretch": float(self.stretch), "mode": self.mode,
                "axis": int(self.axis) + 1, "extent": self.extent.tolist()}


class FacetGauge:
    """A polyhedral gauge ``N(v) = max_i g_i . v`` over the ``facets`` (m, 3) of its unit ball
    (a mixin: the subclass defines ``facets``)."""

    def distance(self, v: np.ndarray) -> np.ndarray:
        """``(..., 3) [mm] -> (...)``: ``max_i g_i . v``."""
        return np.max(np.asarray(v) @ self.facets.T, axis=-1)

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """``(..., 3) -> (..., 3)``: the active facet vector ``g_i``."""
        g = self.facets
        return g[np.argmax(np.asarray(v) @ g.T, axis=-1)]


@dataclass(frozen=True)
class PolyhedralMetric(FacetGauge):
    """A polyhedral gauge in the spirit of IceSL's *Polyfoam* (Martinez et al., "Polyhedral
    Voronoi diagrams for additive manufacturing", ACM TOG 37(4), 2018).

    The unit ball is a right prism: in the plane normal to ``axis`` a regular k-gon of
    circumradius 1 (one vertex at ``angle`` from the local x axis), shrunk by ``x_shrink``
    along the local x axis; along ``axis`` it spans ``[-height, height]``. The distance is
    the gauge of that prism, ``N(v) = max_i g_i . v`` over its ``k + 2`` facets.

    What the parameters do to the cells:

    - ``k`` (>= 3): the number of wall directions around the axis. Voronoi walls between
      seeds side by side are vertical (parallel to ``axis``), as in IceSL, which prints
      without overhangs; large ``k`` approaches a round (cylindrical) gauge. IceSL uses
      small k-gons; the default 6 gives honeycomb-like sections.
    - ``height`` [-] (> 0): elongation of the cells along ``axis``; like
      :class:`StretchedMetric` in axial mode with ``stretch = height`` (below 1 it squashes).
    - ``x_shrink`` [-] in (0, 1]: cells shorter along the local x axis by this factor
      (IceSL's ``kgon_x_shrink``): orthotropy within the transverse plane.
    - ``angle`` [deg]: rotation of the k-gon about ``axis`` (IceSL's ``infill_angle``).
    - ``axis``: longitudinal axis index (0, 1, 2); local x, y are :func:`transverse_axes`.

    Bisectors of a polyhedral gauge are piecewise planar, so the foam's walls are flat
    pieces; :mod:`metasheet.cells.skeleton` measures distances to them with the
    local facet normals, exact within each planar piece.
    """

    k: int = 6
    height: float = 1.0
    x_shrink: float = 1.0
    angle: float = 0.0
    axis: int = 2

    def __post_init__(self):
        if int(self.k) != self.k or not 3 <= int(self.k) <= 64:
            raise ConfigError(f"metric.k: {self.k!r}: expected an integer in [3, 64]")
        check_range("metric.height", self.height, 0.0, 1e3, lo_open=True)
        check_range("metric.x_shrink", self.x_shrink, 0.0, 1.0, lo_open=True)
        check_range("metric.angle", self.angle, -360.0, 360.0)
        _axis(self.axis)

    @property
    def facets(self) -> np.ndarray:
        """(k + 2, 3) facet vectors ``g_i`` in global axes: ``N(v) = max_i g_i . v``."""
        k = int(self.k)
        theta = np.deg2rad(self.angle) + (2 * np.arange(k) + 1) * np.pi / k  # facet normals
        inradius = np.cos(np.pi / k)
        local = np.zeros((k + 2, 3))
        local[:k, 0] = np.cos(theta) / inradius / self.x_shrink
        local[:k, 1] = np.sin(theta) / inradius
        local[k, 2] = 1.0 / self.height
        local[k + 1, 2] = -1.0 / self.height
        tx, ty = transverse_axes(self.axis)
        g = np.zeros_like(local)
        g[:, tx], g[:, ty], g[:, self.axis] = local[:, 0], local[:, 1], local[:, 2]
        return g

    @property
    def scale(self) -> np.ndarray:
        """(3,) scaling making the prism lie between two Euclidean balls (see bounds)."""
        s = np.ones(3)
        tx, _ = transverse_axes(self.axis)
        s[tx] = 1.0 / self.x_shrink
        s[self.axis] = 1.0 / self.height
        return s

    quadratic = False
    #: In ``u = v * scale`` the k-gon lies between the circles of radius cos(pi/k) and 1,
    #: so ``max(|u_t|, |u_l|) <= N <= max(|u_t| / cos(pi/k), |u_l|)``.
    lower = 1.0 / np.sqrt(2.0)

    @property
    def upper(self) -> float:
        return 1.0 / np.cos(np.pi / int(self.k))

    def describe(self) -> dict:
        return {"kind": "polyhedral", "k": int(self.k), "height": float(self.height),
                "x_shrink": float(self.x_shrink), "angle": float(self.angle), "axis": int(self.axis) + 1}


Metric = StretchedMetric | PolyhedralMetric
