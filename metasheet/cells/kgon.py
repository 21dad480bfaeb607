"""The k-gon trapezohedron gauge of IceSL's *Polyfoam* (a named model, see ICESL.md).

Martinez, Hornus, Song, Lefebvre, "Polyhedral Voronoi diagrams for additive manufacturing",
ACM TOG 37(4), 2018: Voronoi cells under a polyhedral distance whose unit ball is a k-gon
in the print plane (x, y) with sloped top and bottom facets, so that every Voronoi wall
is steeper than the printer's overhang limit. What is published is the idea and the
settings' names (``kgon_x_shrink``, ``kgon_min_angle``, ``kgon_norm_alpha``); the exact
polyhedron is not. The model here, :class:`KgonMetric`, is the assumption we make.

Frame: the print frame, x, y the print plane, z the build axis. The gauge is built in the
k-gon's local frame; ``infill_angle`` (a rotation about z) is applied by the sheet's
orientation field, not here. ``kgon_x_shrink`` scales the k-gon along local x, so cells are
flattened along x and x is the soft axis of the foam.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from .metrics import FacetGauge


def _in_plane(k: int, x_shrink: float, phase: float) -> np.ndarray:
    """(k, 2) in-plane facet parts ``(cos phi / (r s), sin phi / r)``, ``phi = (2j + 1) pi / k + phase``."""
    phi = (2 * np.arange(k) + 1) * np.pi / k + phase
    r_in = np.cos(np.pi / k)
    return np.stack([np.cos(phi) / (r_in * x_shrink), np.sin(phi) / r_in], axis=1)


def kgon_beta(k: int, x_shrink: float, min_angle: float) -> float:
    """The facets' vertical component ``beta`` [-] for walls at least ``min_angle`` [deg] steep.

    See :class:`KgonMetric` for the derivation: ``beta = min_ij |p_i - q_j| / (2 tan(min_angle))``.
    """
    p = _in_plane(k, x_shrink, 0.0)
    q = _in_plane(k, x_shrink, np.pi / k)
    gap = float(np.min(np.linalg.norm(p[:, None, :] - q[None, :, :], axis=-1)))
    return gap / (2.0 * np.tan(np.deg2rad(min_angle)))


@dataclass(frozen=True)
class KgonMetric(FacetGauge):
    """Gauge ``N(v) = max_i g_i . v`` of a k-gon trapezohedron (``2k`` facets), print frame.

    Facets (``r = cos(pi/k)`` the k-gon's inradius, ``s = x_shrink``):

    - top, ``j = 0..k-1``: ``g_j^+ = (cos phi_j / (r s), sin phi_j / r, +beta)``,
      ``phi_j = (2j + 1) pi / k``;
    - bottom: ``g_j^- = (cos psi_j / (r s), sin psi_j / r, -beta)``, ``psi_j = phi_j + pi / k``.

    The in-plane parts ``p_j`` (top) and ``q_j`` (bottom) are two k-gons (facet normals of a
    regular k-gon of circumradius 1, shrunk by ``s`` along x), the bottom one turned by
    ``pi / k`` so that no top and bottom facet share their in-plane part. The polar body
    (the hull of the ``g``) is an antiprism, so the unit ball is its dual, a k-gonal
    trapezohedron (two k-gonal pyramids of staggered facets); every facet is active.

    **Wall slopes and beta.** Where a point ``x`` is in the facet region ``a`` of seed ``A``
    and the region ``b`` of seed ``B``, their bisector ``g_a . (x - A) = g_b . (x - B)`` is
    the plane of normal ``g_a - g_b``; every Voronoi wall piece is such a plane (``a = b``
    gives no wall). Its angle ``theta`` from horizontal is the angle of that normal from z:

    - both top (or both bottom): the normal is horizontal, the wall vertical (90 deg);
    - top ``i`` / bottom ``j``: ``g_i^+ - g_j^- = (p_i - q_j, 2 beta)``, so
      ``tan(theta) = |p_i - q_j| / (2 beta)``.

    Every wall is at least ``min_angle`` steep iff ``beta <= min_ij |p_i - q_j| / (2 tan(min_angle))``;
    we take the largest such ``beta`` (equality: the least elongated unit ball along z),
    so the shallowest wall piece is exactly ``min_angle``. The staggering keeps
    ``min_ij |p_i - q_j| > 0`` (without it a top and a bottom facet with the same
    in-plane part would make horizontal walls). The unit ball reaches ``1 / beta`` along z and,
    in the plane, between ``r`` and 1 times ``(s, 1)`` along x, y.

    **Bounds** for the k-d tree search. With ``u = scale * v``, ``scale = (1/s, 1, beta)``:
    ``N = max(h_+(u_xy) + u_z, h_-(u_xy) - u_z)`` with ``h_+-`` the gauges of the two k-gons
    of inradius ``r`` in ``u``, each between ``|u_xy|`` and ``|u_xy| / r``. Hence
    ``|u| <= |u_xy| + |u_z| <= N <= |u_xy| / r + |u_z| <= sqrt(1 + 1 / r^2) |u|``:
    ``lower = 1``, ``upper = sqrt(1 + 1 / r^2)``.

    Parameters
    ----------
    k : number of k-gon sides ``kgon_sides`` (a named assumption: IceSL's k is not published), >= 3.
    x_shrink : IceSL's ``kgon_x_shrink`` [-] in (0, 1].
    min_angle : IceSL's ``kgon_min_angle`` [deg] in [10, 80], the shallowest wall from horizontal.
    """

    k: int = 6
    x_shrink: float = 1.0
    min_angle: float = 45.0

    def __post_init__(self):
        if int(self.k) != self.k or not 3 <= int(self.k) <= 64:
            raise ConfigError(f"kgon_sides: {self.k!r}: expected an integer in [3, 64]")
        check_range("kgon_x_shrink", self.x_shrink, 0.0, 1.0, lo_open=True)
        check_range("kgon_min_angle", self.min_angle, 10.0, 80.0)

    #: the longitudinal (soft) axis: x, fixed for this family (0-based)
    axis = 0
    quadratic = False
    lower = 1.0

    @property
    def upper(self) -> float:
        return float(np.sqrt(1.0 + 1.0 / np.cos(np.pi / int(self.k)) ** 2))

    @property
    def beta(self) -> float:
        """The facets' vertical component [-] (see the class docstring)."""
        return kgon_beta(int(self.k), float(self.x_shrink), float(self.min_angle))

    @property
    def facets(self) -> np.ndarray:
        """(2k, 3) facet vectors: rows ``0..k-1`` the top facets, ``k..2k-1`` the bottom ones."""
        k, s, b = int(self.k), float(self.x_shrink), self.beta
        top = np.column_stack([_in_plane(k, s, 0.0), np.full(k, b)])
        bottom = np.column_stack([_in_plane(k, s, np.pi / k), np.full(k, -b)])
        return np.vstack([top, bottom])

    @property
    def scale(self) -> np.ndarray:
        """(3,) ``(1/s, 1, beta)``: ``lower |scale v| <= N(v) <= upper |scale v|``."""
        return np.array([1.0 / float(self.x_shrink), 1.0, self.beta])

    @property
    def extent(self) -> np.ndarray:
        """(3,) ``1 / scale = (s, 1, 1/beta)``: the unit ball's half extents along x, y, z up to
        a factor in ``[cos(pi/k), 1]`` (exact along z)."""
        return 1.0 / self.scale

    def wall_angles(self) -> np.ndarray:
        """Angle from horizontal [deg] of every possible wall piece (all facet pairs a < b)."""
        g = self.facets
        i, j = np.triu_indices(len(g), 1)
        n = g[i] - g[j]
        return np.rad2deg(np.arctan2(np.hypot(n[:, 0], n[:, 1]), np.abs(n[:, 2])))

    def describe(self) -> dict:
        return {"kind": "kgon", "k": int(self.k), "x_shrink": float(self.x_shrink),
                "min_angle": float(self.min_angle), "beta": self.beta, "axis": int(self.axis) + 1,
                "extent": self.extent.tolist()}
