"""Cell size and seeds of the Polyfoam printed in the sheet.

**Cell size.** The periodic Polyfoam (:func:`metasheet.cells.polyfoam.solve_polyfoam`) scales
unit seeds by a length L so that its one-bead walls fill ``infill_percentage`` of the cell:
``L = t / (2 q)``, q the quantile of the unit-scale wall distances at the fraction. The
distances depend on the shrink s only (through the gauge), so :func:`cell_scale_table` keeps,
for a few shrinks over the field's range, the sorted unit-scale wall distances of the
design's own periodic cell (its sampler, count and seed: the cell the homogenisation
used); L at any (infill, s) is the quantile at the infill, interpolated linearly between
the shrinks. It is the continuous (fine-sample) solution, not the voxel one: it does not
depend on the sheet's voxel edge.

**Seeds.** The periodic cell holds ``prod(scale) / L^3`` seeds per mm^3 (``scale`` the seed
space's: ``(1/s, 1, beta)`` for ``seed_space = "gauge"``, ``(1/s, 1, 1)`` for ``"print"``). In
the sheet the seeds are drawn over the sheet's bounding box padded by two cell spacings on
every side (IceSL's seeds fill space; those outside the part still shape the cells cut by its
faces: the print is the unbounded foam clipped by the sheet, no skin) with that local
density: ``round(integral)`` seeds, candidates thinned by the density (``"uniform"``: an
inhomogeneous Poisson process) and, for ``"poisson"``, kept only at least ``min_distance``
(the design's, in unit scaled space) from every kept seed, measured in the local scaled
space of both seeds ``A(x) = diag(scale) R(theta)^T / L`` (random sequential addition, as
the periodic sampler, with offsets periodic over the padded box so that no seeds pile up
against its faces). Uniform fields give the periodic cell's process; the walls themselves
are not periodic (the seeds across the padded box's faces are two spacings from the sheet).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..cells.foam import voxel_centres
from ..cells.kgon import KgonMetric
from ..cells.polyfoam import PolyfoamDesign, measured_wall
from ..cells.seeds import default_min_distance, make_seeds
from ..cells.skeleton import SkeletonIndex
from ..errors import ConfigError, InfeasibleError

#: shrink step of the table [-]: L changes by under 1 % between nodes for the paper's cell
SHRINK_STEP = 0.05
PAD_SPACINGS = 2.0  # seeds drawn this many cell spacings beyond the sheet's box


@dataclass(frozen=True)
class CellScaleTable:
    """L(infill, shrink) of the design's periodic cell.

    Attributes
    ----------
    shrinks : (m,) shrink nodes [-], ascending.
    distances : (m, n) sorted unit-scale wall distances at each node [-].
    bead_width : t [mm].
    """

    shrinks: np.ndarray
    distances: np.ndarray
    bead_width: float

    def __call__(self, infill_percentage, shrink) -> np.ndarray:
        """Cell scale L [mm] (n,) at infill [%] (n,) and shrink [-] (n,)."""
        f = np.atleast_1d(np.asarray(infill_percentage, dtype=float)) / 100.0
        s = np.atleast_1d(np.asarray(shrink, dtype=float))
        n = self.distances.shape[1]
        # empirical quantile: order statistic of rank f n, linearly between neighbours
        u = np.clip(f * n - 0.5, 0.0, n - 1.0)
        i0 = np.floor(u).astype(np.int64)
        i1 = np.minimum(i0 + 1, n - 1)
        w = u - i0
        q = (1.0 - w)[None, :] * self.distances[:, i0] + w[None, :] * self.distances[:, i1]  # (m, n)
        L = self.bead_width / (2.0 * q)
        if len(self.shrinks) == 1:
            return L[0]
        j = np.clip(np.searchsorted(self.shrinks, s, side="right") - 1, 0, len(self.shrinks) - 2)
        ws = np.clip((s - self.shrinks[j]) / (self.shrinks[j + 1] - self.shrinks[j]), 0.0, 1.0)
        cols = np.arange(len(s))
        return (1.0 - ws) * L[j, cols] + ws * L[j + 1, cols]


def seed_scale(design: PolyfoamDesign, shrink) -> np.ndarray:
    """(n, 3) the seed space's scale at shrinks (n,): ``(1/s, 1, beta(s))`` or ``(1/s, 1, 1)``."""
    s = np.atleast_1d(np.asarray(shrink, dtype=float))
    if design.seed_space == "gauge":  # beta depends on s only: once per distinct value
        u, inv = np.unique(s, return_inverse=True)
        beta = np.array([KgonMetric(design.kgon_sides, float(v), design.kgon_min_angle).beta for v in u])[inv]
    else:
        beta = np.ones_like(s)
    return np.stack([1.0 / s, np.ones_like(s), beta], axis=1)


def table_shrinks(lo: float, hi: float) -> np.ndarray:
    """Shrink nodes covering [lo, hi]: one node when the field is uniform."""
    if hi - lo <= 1e-12 * max(1.0, hi):
        return np.array([float(lo)])
    m = int(max(2, np.ceil((hi - lo) / SHRINK_STEP) + 1))
    return np.linspace(lo, hi, m)


def cell_scale_table(design: PolyfoamDesign, shrinks, *, sample_points: int = 100_000,
                     count: int | None = None) -> CellScaleTable:
    """The design's periodic cell's unit-scale wall distances at each shrink of ``shrinks`` (m,).

    The seeds are the design's (sampler, count, seed) in its seed space, as
    :func:`~metasheet.cells.polyfoam.build_polyfoam` draws them; the distances are measured
    as the design's ``wall_measure`` says, on a jittered sample of ``sample_points`` points.
    ``count``: another seed count for the cell (default the design's, the homogenised cell).
    An 8-seed cell is one realisation: at s = 0.2 and 15 % four seeds gave L = 18.9 to 20.0 mm,
    64-seed cells 19.9 and 20.0 mm.
    """
    sd = design.seeds if count is None else design.seeds.model_copy(update={"count": int(count)})
    out = []
    for s in np.atleast_1d(np.asarray(shrinks, dtype=float)):
        metric = KgonMetric(design.kgon_sides, float(s), design.kgon_min_angle)
        scale = seed_scale(design, s)[0]
        unit_size = float(sd.count) ** (1.0 / 3.0) / scale
        seeds = make_seeds(sd.sampler, sd.count, unit_size, sd.seed, scale=scale, jitter=sd.jitter,
                           min_distance=sd.min_distance)
        index = SkeletonIndex(seeds, unit_size, metric)
        # a jittered sample (one random point per sample voxel): a regular lattice aliases with
        # the walls of a flat cell (60k lattice points gave L 9 % below 120k at s = 0.2)
        n_s = np.maximum(2, np.round(unit_size * (sample_points / np.prod(unit_size)) ** (1 / 3))).astype(int)
        h = unit_size / n_s
        rng = np.random.default_rng(sd.seed)
        pts = voxel_centres(unit_size, n_s) + (rng.random((int(np.prod(n_s)), 3)) - 0.5) * h
        d = measured_wall(index.distances(pts), design.wall_measure)
        out.append(np.sort(d))
    n = min(len(d) for d in out)
    return CellScaleTable(np.atleast_1d(np.asarray(shrinks, dtype=float)),
                          np.stack([d[:n] for d in out]), float(design.bead_width))


def unit_min_distance(design: PolyfoamDesign) -> float:
    """The Poisson-disk distance in unit scaled space (seeds at unit density): the design's, or
    the default that fills a quarter of the space with disks."""
    if design.seeds.min_distance is not None:
        return float(design.seeds.min_distance)
    return default_min_distance(1, np.ones(3))


def seed_metric(scale: np.ndarray, angle_deg: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """(n, 3, 3) ``A = diag(scale) R(theta)^T / L``: world offsets [mm] to unit scaled space."""
    th = np.radians(np.asarray(angle_deg, dtype=float))
    c, s = np.cos(th), np.sin(th)
    rt = np.zeros((len(th), 3, 3))
    rt[:, 0, 0], rt[:, 0, 1], rt[:, 1, 0], rt[:, 1, 1], rt[:, 2, 2] = c, s, -s, c, 1.0
    return (scale / np.asarray(cell, dtype=float)[:, None])[:, :, None] * rt


@njit(cache=True)
def _rsa(cands, mats, accepted, amats, n_acc, count, r2, period):
    """Random sequential addition: append candidates (in order) whose scaled distance to every
    accepted seed, under both seeds' metrics, is at least sqrt(r2). Offsets are taken periodic
    over the box (``period`` (3,) [mm]): a bounded box would pack seeds against its faces (fewer
    neighbours there) and leave its inside too sparse, by 5 % in solid on the paper's sheet,
    whose padded box is only four cells tall. Returns the new count."""
    for c in range(cands.shape[0]):
        if n_acc >= count:
            break
        ok = True
        for j in range(n_acc):
            dx = cands[c, 0] - accepted[j, 0]
            dy = cands[c, 1] - accepted[j, 1]
            dz = cands[c, 2] - accepted[j, 2]
            dx -= period[0] * np.round(dx / period[0])
            dy -= period[1] * np.round(dy / period[1])
            dz -= period[2] * np.round(dz / period[2])
            for which in range(2):
                m = mats[c] if which == 0 else amats[j]
                ux = m[0, 0] * dx + m[0, 1] * dy + m[0, 2] * dz
                uy = m[1, 0] * dx + m[1, 1] * dy + m[1, 2] * dz
                uz = m[2, 0] * dx + m[2, 1] * dy + m[2, 2] * dz
                if ux * ux + uy * uy + uz * uz < r2:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            accepted[n_acc] = cands[c]
            amats[n_acc] = mats[c]
            n_acc += 1
    return n_acc


@dataclass(frozen=True)
class SeedSet:
    """Seeds of the sheet's foam.

    seeds : (N, 3) [mm]; shrink, angle_deg, cell_scale : (N,) the fields at each seed
    (s [-], theta [deg], L [mm]); lo, hi : (3,) [mm] the padded box they fill; expected : the
    density's integral over it (the count asked for).
    """

    seeds: np.ndarray
    shrink: np.ndarray
    angle_deg: np.ndarray
    cell_scale: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    expected: float


def graded_seeds(design: PolyfoamDesign, fields_at, table: CellScaleTable, lo, hi, rng_seed: int, *,
                 max_seeds: int = 200_000) -> SeedSet:
    """Seeds over the box ``[lo, hi]`` (3,) [mm] padded by :data:`PAD_SPACINGS` cell spacings,
    with the local density of the periodic cell (module docstring).

    ``fields_at(points (n, 3)) -> (infill [%], shrink, angle [deg])``, three (n,) arrays.
    """
    sampler = design.seeds.sampler
    if sampler not in ("uniform", "poisson"):
        raise ConfigError(f"seeds.sampler: {sampler!r}: in the sheet only 'uniform' and 'poisson' are "
                          "modelled (a jittered grid has no graded form)")
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    # the density on a coarse grid (~1 mm, at most 64 per axis) sets the count and the thinning bound
    n_g = np.clip(np.ceil((hi - lo) / 1.0), 2, 64).astype(int)
    g = lo + voxel_centres(hi - lo, n_g)
    inf_g, s_g, _ = fields_at(g)
    L_g = table(inf_g, s_g)
    sc = seed_scale(design, s_g)
    spacing = L_g[:, None] / sc  # world spacing of the seeds along the local axes [mm]
    pad = PAD_SPACINGS * np.array([spacing[:, :2].max(), spacing[:, :2].max(), spacing[:, 2].max()])
    plo, phi = lo - pad, hi + pad
    n_g = np.clip(np.ceil((phi - plo) / 1.0), 2, 64).astype(int)
    g = plo + voxel_centres(phi - plo, n_g)
    inf_g, s_g, _ = fields_at(g)
    dens = np.prod(seed_scale(design, s_g), axis=1) / table(inf_g, s_g) ** 3  # [1/mm^3]
    expected = float(dens.mean() * np.prod(phi - plo))
    count = round(expected)
    if count > max_seeds:
        raise ConfigError(f"max_seeds: {max_seeds}: the sheet needs {count} seeds (cells of "
                          f"{table(inf_g, s_g).min():.3g} mm and less); raise max_seeds")
    if count < 2:
        raise InfeasibleError(f"the sheet's box holds {expected:.3g} cells: too few for a foam")
    dmax = 1.05 * float(dens.max())  # the coarse grid may miss the peak: 5 % headroom
    rng = np.random.default_rng(rng_seed)
    r2 = unit_min_distance(design) ** 2 if sampler == "poisson" else -1.0
    accepted = np.empty((count, 3))
    amats = np.empty((count, 3, 3))
    n_acc, thrown = 0, 0
    max_thrown = 2000 * count
    while n_acc < count:
        if thrown > max_thrown:
            raise InfeasibleError(
                f"seeds.min_distance: placed {n_acc} of {count} seeds in {thrown} darts: lower min_distance")
        batch = max(4 * (count - n_acc), 1024)
        pts = plo + rng.random((batch, 3)) * (phi - plo)
        keep = rng.random(batch)
        infill, s, ang = fields_at(pts)
        L = table(infill, s)
        scale = seed_scale(design, s)
        d = np.prod(scale, axis=1) / L**3
        ok = keep * dmax < d
        thrown += batch
        mats = seed_metric(scale[ok], ang[ok], L[ok])
        n_acc = _rsa(np.ascontiguousarray(pts[ok]), mats, accepted, amats, n_acc, count, r2, phi - plo)
    seeds = accepted[:count]
    infill, s, ang = fields_at(seeds)
    return SeedSet(seeds, s, ang, table(infill, s), plo, phi, expected)
