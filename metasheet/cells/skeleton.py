"""Distances to the Voronoi skeleton of a periodic seed set: walls (faces) and struts (edges).

The foam's level set (:mod:`metasheet.cells.foam`) is built from the nearest seeds of each
point (periodic images included), but not as the usual ``d2 - d1`` or ``d3 - d1`` of seed
distances, which are not lengths (their slope across a wall varies with the seeds' spacing,
so a threshold on them gives walls and struts of uneven thickness). Instead the distances
here are true distances in mm to the Voronoi skeleton:

- the point ``x`` lies in the cell of its nearest seed ``s0``; every other candidate seed
  ``sk`` bounds that cell by the bisector ``{N(x - sk) = N(x - s0)}``, a plane for the
  (stretched) Euclidean metric. Its distance ``h_k = f_k / |grad f_k|`` with
  ``f_k = N_k^2 - N_0^2`` is exact (``f_k`` is affine in ``x``); for the polyhedral gauge
  ``f_k = N_k - N_0`` is affine within each piece of the piecewise-planar bisector;
- **wall** distance: ``a = min_k h_k`` is the exact distance to the cell boundary (the
  cell is convex);
- **strut** distance: the foot ``x' = x - a n_a`` of ``x`` on its nearest face lies in
  that face, a convex polygon bounded by the lines where the other bisectors cut it; its
  distance to the polygon's boundary is ``delta = min_k (h_k - a c_k) / sqrt(1 - c_k^2)``
  (``c_k = n_a . n_k``), so ``sqrt(a^2 + delta^2)`` is the distance from ``x`` to the edges
  of that face. The strut distance ``r`` is the smallest such value over the three nearest
  planes whose foot falls inside their face: exact along every edge, on the simple cubic
  lattice and wherever the nearest edge bounds one of those faces (all but rare points
  near nodes, where it can only overestimate).

Candidate seeds come from :class:`SkeletonIndex` (the seeds tiled with their 26 periodic
images: Delaunay neighbours for quadratic metrics, nearest images for polyhedral gauges);
the per-point geometry is compiled with numba (the kernels at the end of this module).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from scipy.spatial import Delaunay, cKDTree

from ..errors import ConfigError
from .gauge import polyhedral_gauge
from .metrics import Metric
from .seeds import periodic_images, wrap

_CHUNK = 32768  # points per vectorised block (memory ~ chunk * K * 3 * 8 bytes per array)


def _check_points(points) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ConfigError(f"points: shape is {p.shape} and should be (n, 3) [mm]")
    return p


@dataclass(frozen=True)
class SkeletonDistances:
    """Distances from points to the Voronoi skeleton, all (n,) [mm] but ``cell`` (n,) int.

    Attributes
    ----------
    wall : distance to the boundary of the point's Voronoi cell (its nearest face).
    strut : distance to the edges of that nearest face (the Voronoi 1-skeleton).
    cell : index of the nearest seed (the cell the point lies in).
    wall_nz : z component of the unit normal of that nearest face: ``sqrt(1 - wall_nz^2)`` is
        the sine of the face's angle from horizontal (0 where no face was found).
    """

    wall: np.ndarray
    strut: np.ndarray
    cell: np.ndarray
    wall_nz: np.ndarray | None = None


class SkeletonIndex:
    """Nearest-seed search for one periodic seed set under one metric.

    The seeds are tiled with their 26 periodic images and put in a k-d tree in the metric's
    scaled space (where the metric is, or is bounded by, a Euclidean norm).

    - Quadratic (stretched Euclidean) metrics: the faces of a cell come from its Delaunay
      neighbours in scaled space, so each point gets its nearest seed (one tree query) and
      that seed's Delaunay neighbours as candidates: exact, with the fewest candidates.
    - Polyhedral gauges: the ``k`` nearest images in scaled space, re-ranked with the gauge;
      ``k`` doubles for the points where a farther seed could still bound the skeleton
      within ``cap`` of them.

    Parameters
    ----------
    seeds : (N, 3) [mm]; size : (3,) [mm]; metric : a metric.
    """

    def __init__(self, seeds: np.ndarray, size: np.ndarray, metric: Metric):
        self.size = np.asarray(size, dtype=float)
        self.seeds = wrap(np.asarray(seeds, dtype=float), self.size)
        self.metric = metric
        self.images, self.owner = periodic_images(self.seeds, self.size)
        self.tree = cKDTree(self.images * metric.scale)
        # plane distance h_k >= (N_k - N_0) / plane_bound (|grad f_k| bound, see _point)
        if metric.quadratic:
            self.plane_bound = 2.0 * float(np.max(metric.scale))
            self.neighbours = self._delaunay_neighbours()
        else:
            self.plane_bound = 2.0 * float(np.max(np.linalg.norm(metric.facets, axis=1)))
            self.neighbours = None

    def _delaunay_neighbours(self) -> np.ndarray:
        """(N, m, 3) displacements [mm] from each seed to its Delaunay neighbours (NaN padded)."""
        n = len(self.seeds)
        tri = Delaunay(self.images * self.metric.scale)
        indptr, indices = tri.vertex_neighbor_vertices
        centre = 13 * n  # IMAGE_SHIFTS[13] == (0, 0, 0)
        lists = [indices[indptr[centre + o]:indptr[centre + o + 1]] for o in range(n)]
        m = max(len(nb) for nb in lists)
        rel = np.full((n, m, 3), np.nan)
        for o, nb in enumerate(lists):
            rel[o, : len(nb)] = self.images[nb] - self.images[centre + o]
        return rel

    def distances(self, points: np.ndarray, *, cap: float = np.inf, k: int = 24) -> SkeletonDistances:
        """Skeleton distances of ``points`` (n, 3) [mm] (folded into the box first).

        ``cap`` [mm] (polyhedral gauges only): distances above it may be overestimated (but
        stay above it), which saves candidates in the cells' interiors when only a thin
        solid matters. ``k``: initial number of candidates (polyhedral gauges only).
        """
        p = wrap(_check_points(points), self.size)
        n = len(p)
        wall = np.empty(n)
        strut = np.empty(n)
        cell = np.empty(n, dtype=np.int64)
        nz = np.empty(n)
        for lo in range(0, n, _CHUNK):
            sl = slice(lo, min(lo + _CHUNK, n))
            if self.neighbours is not None:
                wall[sl], strut[sl], cell[sl], nz[sl] = self._block_delaunay(p[sl])
            else:
                wall[sl], strut[sl], cell[sl], nz[sl] = self._block_knn(p[sl], cap, k)
        return SkeletonDistances(wall, strut, cell, nz)

    def _block_delaunay(self, x: np.ndarray):
        _, i0 = self.tree.query(x * self.metric.scale, k=1, workers=-1)
        owner = self.owner[i0]
        m = self.metric
        facets = np.zeros((1, 3)) if m.quadratic else m.facets
        a, strut, _, nz = _skeleton_delaunay(x, self.images[i0], owner, self.neighbours,
                                             m.quadratic, m.scale, facets)
        return a, strut, owner, nz

    def _block_knn(self, x: np.ndarray, cap: float, k: int):
        k = min(k, len(self.images))
        wall, strut, cell, e_k, d0, nz = self._knn(x, k)
        # A seed beyond the k-th candidate has N >= lower * e_k; it can bound the struts or
        # walls near x only if its bisector is within `strut` of x, i.e. N <= N_0 + bound * strut.
        need = self.metric.lower * e_k <= d0 + self.plane_bound * np.minimum(strut, cap)
        while np.any(need) and k < len(self.images):
            k = min(2 * k, len(self.images))
            idx = np.flatnonzero(need)
            w2, s2, c2, e2, d2, n2 = self._knn(x[idx], k)
            wall[idx], strut[idx], cell[idx], nz[idx] = w2, s2, c2, n2
            need_sub = self.metric.lower * e2 <= d2 + self.plane_bound * np.minimum(s2, cap)
            need = np.zeros(len(x), dtype=bool)
            need[idx[need_sub]] = True
        return wall, strut, cell, nz

    def _knn(self, x: np.ndarray, k: int):
        e, idx = self.tree.query(x * self.metric.scale, k=k, workers=-1)
        e = e.reshape(len(x), k)
        idx = idx.reshape(len(x), k)
        m = self.metric
        facets = np.zeros((1, 3)) if m.quadratic else m.facets
        a, strut, d0, j0, nz = _skeleton_knn(x, self.images, idx, m.quadratic, m.scale, facets)
        return a, strut, self.owner[idx[np.arange(len(x)), j0]], e[:, -1], d0, nz


# --- compiled kernels --------------------------------------------------------------------
# One point at a time: the nearest seed s0, then every candidate seed's bisector plane
# (distance h_k, unit normal n_k into the cell), the nearest face a, and the distance delta
# from the foot of x on face a to that face's edges (see the module docstring).


@njit(cache=True)
def _gauge(vx, vy, vz, quadratic, scale, facets):
    """Metric distance of v and (polyhedral) the index of the active facet."""
    if quadratic:
        wx, wy, wz = vx * scale[0], vy * scale[1], vz * scale[2]
        return np.sqrt(wx * wx + wy * wy + wz * wz), -1
    return polyhedral_gauge(facets, vx, vy, vz)


@njit(cache=True)
def _point(x, c0, cands, skip, quadratic, scale, facets, hs, ns):
    """(a, strut, d0, nz) of point x (3,) with own seed c0 (3,), candidates cands (m, 3) (NaN
    rows and row ``skip`` ignored), nz the z component of the nearest face's unit normal;
    hs (m,) and ns (m, 3) are scratch."""
    v0x, v0y, v0z = x[0] - c0[0], x[1] - c0[1], x[2] - c0[2]
    d0, i0 = _gauge(v0x, v0y, v0z, quadratic, scale, facets)
    best, ja = np.inf, -1
    for k in range(cands.shape[0]):
        hs[k] = np.inf
        if k == skip or np.isnan(cands[k, 0]):
            continue
        vx, vy, vz = x[0] - cands[k, 0], x[1] - cands[k, 1], x[2] - cands[k, 2]
        dk, ik = _gauge(vx, vy, vz, quadratic, scale, facets)
        if quadratic:
            f = dk * dk - d0 * d0
            gx = 2.0 * (vx - v0x) * scale[0] * scale[0]
            gy = 2.0 * (vy - v0y) * scale[1] * scale[1]
            gz = 2.0 * (vz - v0z) * scale[2] * scale[2]
        else:
            f = dk - d0
            gx = facets[ik, 0] - facets[i0, 0]
            gy = facets[ik, 1] - facets[i0, 1]
            gz = facets[ik, 2] - facets[i0, 2]
        gn = np.sqrt(gx * gx + gy * gy + gz * gz)
        if gn <= 1e-12 * (1.0 + abs(f)):
            continue
        hs[k] = f / gn
        ns[k, 0], ns[k, 1], ns[k, 2] = gx / gn, gy / gn, gz / gn
        if hs[k] < best:
            best, ja = hs[k], k
    if ja < 0:
        return np.inf, np.inf, d0, 0.0
    # The three nearest planes: the nearest is a face of the cell, so the foot of x on it
    # lies in that face; the others count when their foot lies in their face too (all
    # in-plane distances >= 0), which catches the nearest edge near a node.
    jb, jc = -1, -1
    for k in range(cands.shape[0]):
        if k == ja or hs[k] == np.inf:
            continue
        if jb < 0 or hs[k] < hs[jb]:
            jc, jb = jb, k
        elif jc < 0 or hs[k] < hs[jc]:
            jc = k
    a = max(best, 0.0)
    strut = np.inf
    for t in range(3):
        p = ja if t == 0 else (jb if t == 1 else jc)
        if p < 0:
            continue
        hp = max(hs[p], 0.0)
        delta = np.inf
        inside = True
        for k in range(cands.shape[0]):
            if k == p or hs[k] == np.inf:
                continue
            c = ns[k, 0] * ns[p, 0] + ns[k, 1] * ns[p, 1] + ns[k, 2] * ns[p, 2]
            s = np.sqrt(max(1.0 - c * c, 0.0))
            if s > 1e-9:
                dd = (hs[k] - hp * c) / s  # in-plane distance of the foot to the line p ^ k
                if dd < delta:
                    delta = dd
        if t > 0 and delta < -1e-9 * (1.0 + hp):
            inside = False  # the foot is outside face p: not a distance to its edges
        if inside:
            delta = max(delta, 0.0)
            r = np.sqrt(hp * hp + delta * delta)
            if r < strut:
                strut = r
    return a, strut, d0, ns[ja, 2]


#: points per block of the kernels' parallel loop: each block has its own scratch and writes
#: only its own points, so the result is the same on any number of threads
_BLOCK = 2048


@njit(cache=True, parallel=True)
def _skeleton_delaunay(x, y0, owner, rel, quadratic, scale, facets):
    n, m = x.shape[0], rel.shape[1]
    a = np.empty(n)
    strut = np.empty(n)
    d0 = np.empty(n)
    nz = np.empty(n)
    for blk in prange((n + _BLOCK - 1) // _BLOCK):
        cands = np.empty((m, 3))
        hs = np.empty(m)
        ns = np.empty((m, 3))
        for i in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            o = owner[i]
            for k in range(m):
                for j in range(3):
                    cands[k, j] = y0[i, j] + rel[o, k, j]
            a[i], strut[i], d0[i], nz[i] = _point(x[i], y0[i], cands, -1, quadratic, scale, facets, hs, ns)
    return a, strut, d0, nz


@njit(cache=True, parallel=True)
def _skeleton_knn(x, images, idx, quadratic, scale, facets):
    n, m = idx.shape
    a = np.empty(n)
    strut = np.empty(n)
    d0 = np.empty(n)
    nz = np.empty(n)
    j0 = np.empty(n, dtype=np.int64)
    for blk in prange((n + _BLOCK - 1) // _BLOCK):
        cands = np.empty((m, 3))
        hs = np.empty(m)
        ns = np.empty((m, 3))
        for i in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            best, jb = np.inf, 0
            for k in range(m):
                for j in range(3):
                    cands[k, j] = images[idx[i, k], j]
                d, _ = _gauge(x[i, 0] - cands[k, 0], x[i, 1] - cands[k, 1], x[i, 2] - cands[k, 2],
                              quadratic, scale, facets)
                if d < best:
                    best, jb = d, k
            j0[i] = jb
            a[i], strut[i], d0[i], nz[i] = _point(x[i], cands[jb].copy(), cands, jb, quadratic, scale,
                                                  facets, hs, ns)
    return a, strut, d0, j0, nz
