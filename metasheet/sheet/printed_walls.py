"""Wall distances of a Polyfoam whose k-gon gauge varies in space (compiled kernels).

The periodic cell (:mod:`metasheet.cells.skeleton`) has one gauge ``N(v) = max_f g_f . v``
(:class:`~metasheet.cells.kgon.KgonMetric`). In the printed sheet the gauge changes from
place to place: ``kgon_x_shrink`` s and ``infill_angle`` theta are fields, and the cell size
L (from ``infill_percentage`` and s) too. The facets of the gauge at a place are those of
``KgonMetric(k, s, min_angle)`` turned by theta about z and divided by L,
``g_f = R(theta) g_f^0(s) / L``, so that the gauge counts local cell spacings.

How IceSL lets a varying gauge enter the distance is unpublished; two named assumptions:

- ``gauge = "seed"``: every seed keeps the gauge at its own position, ``D_i(x) = N_i(x - s_i)``
  (an anisotropic Voronoi diagram in the sense of Labelle and Shewchuk). The bisector of
  two seeds is piecewise planar (``D_k - D_0`` is affine where both active facets stay the
  same), so the wall distance ``h_k = (D_k - D_0) / |g_k - g_0|`` is exact within a piece, as
  in the periodic cell.
- ``gauge = "point"``: every point measures all seeds with the gauge at the point,
  ``D_i(x) = N_x(x - s_i)``: locally the ordinary polyhedral diagram of that gauge; the
  distance to its bisector planes is first-order exact while the fields vary slowly over a
  wall thickness.

With uniform fields both are the same formula on the same numbers: the phases agree bit
for bit.

Candidate seeds are chosen per tile of voxels (a few voxels wide, the whole thickness):
bounds of every seed's distance over the tile keep every seed that can own a point of the
tile or bound its cell within ``cap`` of it, so the result is the all-seeds result (no
nearest-neighbour heuristic); a seed outside the candidates provably changes nothing below
``cap``. Tiles are independent and processed in order: the result does not depend on the
thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..cells.gauge import polyhedral_gauge


@njit(cache=True)
def kgon_facets_into(k, shrink, min_angle_deg, angle_deg, inv_scale, out):
    """Facets (2k, 3) of the k-gon gauge with shrink s, turned by ``angle_deg`` about z and
    multiplied by ``inv_scale`` (1 / L [1/mm]), written into ``out``.

    Same construction as :class:`~metasheet.cells.kgon.KgonMetric` (top facets
    ``(cos phi / (r s), sin phi / r, +beta)``, bottom ones turned by pi / k with ``-beta``,
    beta the largest keeping every wall ``min_angle`` steep), computed with scalar libm calls
    so that equal inputs give equal bits whatever the array they come from.
    """
    r = math.cos(math.pi / k)
    gap = np.inf
    for i in range(k):
        phi = (2 * i + 1) * math.pi / k
        px, py = math.cos(phi) / (r * shrink), math.sin(phi) / r
        for j in range(k):
            psi = (2 * j + 1) * math.pi / k + math.pi / k
            qx, qy = math.cos(psi) / (r * shrink), math.sin(psi) / r
            d = math.sqrt((px - qx) ** 2 + (py - qy) ** 2)
            gap = min(gap, d)
    beta = gap / (2.0 * math.tan(math.radians(min_angle_deg)))
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    for i in range(2 * k):
        phase = 0.0 if i < k else math.pi / k
        phi = (2 * (i % k) + 1) * math.pi / k + phase
        gx, gy = math.cos(phi) / (r * shrink), math.sin(phi) / r
        out[i, 0] = (c * gx - s * gy) * inv_scale
        out[i, 1] = (s * gx + c * gy) * inv_scale
        out[i, 2] = (beta if i < k else -beta) * inv_scale


@njit(cache=True)
def gauge_facets(k, min_angle_deg, shrink, angle_deg, inv_scale):
    """(m, 2k, 3) facets of m gauges (each argument (m,)); see :func:`kgon_facets_into`."""
    m = shrink.shape[0]
    out = np.empty((m, 2 * k, 3))
    for i in range(m):
        kgon_facets_into(k, shrink[i], min_angle_deg, angle_deg[i], inv_scale[i], out[i])
    return out


@njit(cache=True)
def _norm_max(f):
    best = 0.0
    for i in range(f.shape[0]):
        n = math.sqrt(f[i, 0] ** 2 + f[i, 1] ** 2 + f[i, 2] ** 2)
        best = max(best, n)
    return best


@njit(cache=True)
def _box_bound(f, hx, hy, hz):
    """max_f sum_a |f_a| h_a: how much the gauge ``f`` can change over a box of half sides h."""
    best = 0.0
    for i in range(f.shape[0]):
        b = abs(f[i, 0]) * hx + abs(f[i, 1]) * hy + abs(f[i, 2]) * hz
        best = max(best, b)
    return best


@njit(cache=True)
def wall_tiles(pts, tile_ptr, seeds, seed_facets, k, min_angle_deg, shrink, angle_deg, inv_scale,
               point_mode, cap):
    """Wall distance, owner and wall normal's z of every point, tile by tile.

    Parameters
    ----------
    pts : (P, 3) [mm] points, grouped by tile; tile_ptr : (T + 1,) offsets of the tiles in pts.
    seeds : (N, 3) [mm].
    seed_facets : (N, 2k, 3) each seed's gauge (``gauge = "seed"``; unused in point mode).
    k, min_angle_deg : the k-gon; shrink, angle_deg, inv_scale : (P,) the fields at the points
        (``gauge = "point"``; unused in seed mode).
    point_mode : True for ``gauge = "point"``.
    cap : [mm] distances above it may be overestimated (but stay above it).

    Returns
    -------
    (wall (P,) [mm], owner (P,) int64, nz (P,)) : the distance to the nearest wall of the
    point's cell (inf when no other seed bounds it within cap), the owning seed, and the z
    component of that wall's unit normal.
    """
    P, N, F = pts.shape[0], seeds.shape[0], 2 * k
    wall = np.full(P, np.inf)
    owner = np.empty(P, dtype=np.int64)
    nzs = np.zeros(P)
    lo = np.empty(N)
    hi = np.empty(N)
    cand = np.empty(N, dtype=np.int64)
    dist = np.empty(N)
    arg = np.empty(N, dtype=np.int64)
    ref = np.empty((F, 3))
    gx = np.empty((F, 3))
    seed_norm = 0.0
    if not point_mode:
        for j in range(N):
            seed_norm = max(seed_norm, _norm_max(seed_facets[j]))
    for t in range(tile_ptr.shape[0] - 1):
        a, b = tile_ptr[t], tile_ptr[t + 1]
        if b <= a:
            continue
        # the tile's box: centre c, half sides h
        mn = pts[a].copy()
        mx = pts[a].copy()
        for p in range(a, b):
            for d in range(3):
                mn[d] = min(mn[d], pts[p, d])
                mx[d] = max(mx[d], pts[p, d])
        cx, cy, cz = 0.5 * (mn[0] + mx[0]), 0.5 * (mn[1] + mx[1]), 0.5 * (mn[2] + mx[2])
        hx, hy, hz = 0.5 * (mx[0] - mn[0]), 0.5 * (mx[1] - mn[1]), 0.5 * (mx[2] - mn[2])
        hr = math.sqrt(hx * hx + hy * hy + hz * hz)
        # bounds [lo_j, hi_j] of every seed's distance over the tile
        if point_mode:
            kgon_facets_into(k, shrink[a], min_angle_deg, angle_deg[a], inv_scale[a], ref)
            delta, gmax = 0.0, 0.0
            for p in range(a, b):  # delta: how far the tile's gauges stray from the reference
                kgon_facets_into(k, shrink[p], min_angle_deg, angle_deg[p], inv_scale[p], gx)
                gmax = max(gmax, _norm_max(gx))
                for f in range(F):
                    e = math.sqrt((gx[f, 0] - ref[f, 0]) ** 2 + (gx[f, 1] - ref[f, 1]) ** 2
                                  + (gx[f, 2] - ref[f, 2]) ** 2)
                    delta = max(delta, e)
            bref = _box_bound(ref, hx, hy, hz)
            margin = cap * 2.0 * gmax
            for j in range(N):
                vx, vy, vz = cx - seeds[j, 0], cy - seeds[j, 1], cz - seeds[j, 2]
                dj, _ = polyhedral_gauge(ref, vx, vy, vz)
                e = bref + delta * (math.sqrt(vx * vx + vy * vy + vz * vz) + hr)
                lo[j], hi[j] = dj - e, dj + e
        else:
            margin = cap * 2.0 * seed_norm
            for j in range(N):
                dj, _ = polyhedral_gauge(seed_facets[j], cx - seeds[j, 0], cy - seeds[j, 1], cz - seeds[j, 2])
                e = _box_bound(seed_facets[j], hx, hy, hz)
                lo[j], hi[j] = dj - e, dj + e
        m = np.inf
        for j in range(N):
            m = min(m, hi[j])
        K = 0
        for j in range(N):  # ascending seed index: ties go to the lowest index in both modes
            if lo[j] < m + margin:
                cand[K] = j
                K += 1
        for p in range(a, b):
            if point_mode:
                kgon_facets_into(k, shrink[p], min_angle_deg, angle_deg[p], inv_scale[p], gx)
            best, j0 = np.inf, -1
            for q in range(K):
                j = cand[q]
                f = gx if point_mode else seed_facets[j]
                dist[q], arg[q] = polyhedral_gauge(f, pts[p, 0] - seeds[j, 0], pts[p, 1] - seeds[j, 1],
                                         pts[p, 2] - seeds[j, 2])
                if dist[q] < best:
                    best, j0 = dist[q], q
            owner[p] = cand[j0]
            f0 = gx if point_mode else seed_facets[cand[j0]]
            i0 = arg[j0]
            for q in range(K):
                if q == j0:
                    continue
                fq = gx if point_mode else seed_facets[cand[q]]
                iq = arg[q]
                ux = fq[iq, 0] - f0[i0, 0]
                uy = fq[iq, 1] - f0[i0, 1]
                uz = fq[iq, 2] - f0[i0, 2]
                un = math.sqrt(ux * ux + uy * uy + uz * uz)
                if un <= 1e-12 * (1.0 + abs(dist[q] - best)):
                    continue
                h = max((dist[q] - best) / un, 0.0)
                if h < wall[p]:
                    wall[p] = h
                    nzs[p] = uz / un
    return wall, owner, nzs
