"""The Polyfoam as printed inside the sheet, voxel by voxel (issue 44, item 1).

The robot's sheets are a continuum with the homogenised constants of an unbounded periodic
foam; the print is that foam's walls clipped by a 5 mm sheet. :func:`printed_foam` builds
the print as a voxel phase grid from what IceSL is given: the sheet, its solid brush (the
centre ring and the arm-end tabs print solid) and the foam's fields in the print frame
(x, y the print plane, z the build axis = the sheet's thickness): ``infill_percentage``,
``kgon_x_shrink``, ``infill_angle``, each a number, a callable or a print-map texture
(:class:`TextureField`, read as the slicer reads it: 8-bit, trilinear, clamped).

The model (every step a named assumption, docs/printed-sheet.md):

- seeds over the sheet's box padded by two cell spacings, with the periodic cell's local
  density, so that each region has the cell size the periodic Polyfoam model gives for its
  infill and shrink (:mod:`.printed_seeds`; the foam is the unbounded foam clipped by the
  sheet: no skin, no perimeter, as the print map's foam brush says);
- walls one bead thick (``bead_width``, measured as the design's ``wall_measure``) between
  neighbouring seeds' cells under the k-gon gauge turned by the local ``infill_angle`` about
  z and shrunk along its local x; the gauge of a cell is the seed's (``gauge = "seed"``) or
  the evaluated point's (``gauge = "point"``) (:mod:`.printed_walls`);
- the solid brush is solid, outside the sheet is void.

Frame and grid: the region's box ``[lo, hi]`` [mm] is cut into ``round((hi - lo) / voxel_mm)``
voxels per axis, so the box, the sheet's thickness included, is met exactly and each edge
is within a few % of ``voxel_mm``; voxel (i, j, k) has its centre at
``origin + (i + 1/2, j + 1/2, k + 1/2) * voxel_mm``. The grid's bytes depend on the seed only.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..cells.foam import voxel_centres
from ..cells.polyfoam import PolyfoamDesign
from ..errors import ConfigError, check_range
from . import icesl
from .outline import SheetParams, outline_polygon
from .printed_fields import FieldLike, FoamFields, TextureField, printmap_fields
from .printed_seeds import (
    CellScaleTable,
    SeedSet,
    cell_scale_table,
    graded_seeds,
    table_shrinks,
)
from .printed_walls import gauge_facets, wall_tiles

__all__ = ["BRUSH", "FOAM", "GAUGES", "OUTSIDE", "FieldLike", "FoamFields", "PrintedFoam", "PrintedFoamReport",
           "SheetRegion", "TextureField", "box_region", "compare_gauges", "connected_share", "printed_foam",
           "printmap_fields", "tripod_region"]

GAUGES = ("seed", "point")
OUTSIDE, FOAM, BRUSH = 0, 1, 2  # region codes


# ------------------------------------------------------------------------------ the region

@dataclass(frozen=True)
class SheetRegion:
    """The part and its solid brush: ``lo``, ``hi`` (3,) [mm] its bounding box; ``inside`` and
    ``solid`` map points (n, 3) [mm] to (n,) bool (``solid`` None: no solid brush)."""

    lo: np.ndarray
    hi: np.ndarray
    inside: Callable[[np.ndarray], np.ndarray]
    solid: Callable[[np.ndarray], np.ndarray] | None = None
    name: str = "region"


def _in_polygon(xy: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd test of points (n, 2) against a closed polygon (k, 2)."""
    x, y = xy[:, 0], xy[:, 1]
    inside = np.zeros(len(xy), dtype=bool)
    for (x1, y1), (x2, y2) in zip(poly, np.roll(poly, -1, axis=0)):
        if y1 == y2:
            continue
        cross = (y1 > y) != (y2 > y)
        xint = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= cross & (x < xint)
    return inside


@dataclass(frozen=True)
class _TripodInside:  # picklable
    params: SheetParams
    polygon: np.ndarray

    def __call__(self, points):
        p = np.asarray(points, dtype=float)
        t = 0.5 * float(self.params.thickness)
        return (_in_polygon(p[:, :2], self.polygon) & (np.hypot(p[:, 0], p[:, 1]) >= self.params.hole_radius)
                & (np.abs(p[:, 2]) <= t))


@dataclass(frozen=True)
class _TripodSolid:
    params: SheetParams

    def __call__(self, points):
        return icesl.solid_mask(points, self.params)


def tripod_region(params: SheetParams | None = None, *, arc_segments: int = 16) -> SheetRegion:
    """The tripod sheet (outline, hole, thickness; :mod:`.outline`'s frame) and its solid brush
    (centre ring and arm-end tabs, :func:`metasheet.sheet.icesl.solid_mask`). Both are symmetric
    under y -> -y: the region serves the mirrored sheet too."""
    params = params or SheetParams()
    poly = outline_polygon(params, arc_segments)
    t = 0.5 * float(params.thickness)
    lo = np.array([poly[:, 0].min(), poly[:, 1].min(), -t])
    hi = np.array([poly[:, 0].max(), poly[:, 1].max(), t])
    return SheetRegion(lo, hi, _TripodInside(params, poly), _TripodSolid(params), "tripod sheet")


def voxel_grid(region: SheetRegion, voxel_mm: float, max_voxels: int) -> tuple[int, int, int]:
    """The voxel grid's shape over ``region``'s box at ``voxel_mm`` [mm]; ConfigError naming
    max_voxels when it has more voxels than that."""
    shape = tuple(int(v) for v in np.maximum(1, np.round((region.hi - region.lo) / float(voxel_mm))))
    count = int(np.prod(shape))
    if count > max_voxels:
        raise ConfigError(f"max_voxels: {max_voxels}: the grid {shape[0]} x {shape[1]} x {shape[2]} has "
                          f"{count} voxels at voxel_mm {voxel_mm:g}; raise max_voxels or voxel_mm")
    return shape


@dataclass(frozen=True)
class _Everywhere:
    def __call__(self, points):
        return np.ones(len(points), dtype=bool)


def box_region(lo, hi, solid: Callable[[np.ndarray], np.ndarray] | None = None) -> SheetRegion:
    """A slab ``[lo, hi]`` (3,) [mm], all of it part, with an optional solid brush."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if lo.shape != (3,) or hi.shape != (3,) or np.any(hi <= lo):
        raise ConfigError(f"box: lo {lo.tolist()}, hi {hi.tolist()}: expected (3,) each with hi > lo [mm]")
    return SheetRegion(lo, hi, _Everywhere(), solid, "box")


# ------------------------------------------------------------------------------ the result

@dataclass(frozen=True)
class PrintedFoamReport:
    """What :func:`printed_foam` built.

    shape : (nx, ny, nz); voxel_mm : (3,) voxel edges [mm]; voxels : nx ny nz.
    part_voxels, foam_voxels, brush_voxels : voxels inside the part, in the foam brush, in the
        solid brush.
    solid_fraction_foam : solid share of the foam brush's voxels [-].
    target_fraction : the mean of ``infill_percentage / 100`` over the foam's voxels [-].
    solid_fraction_part : solid share of the part's voxels (brush included) [-].
    seeds : seeds drawn (over the padded box); seeds_expected : the density's integral.
    cells_in_foam : seeds owning at least one foam voxel.
    cell_scale_mm : (min, max) of the periodic cell's L over the foam's voxels [mm].
    wall_voxels : bead width over the voxel edge (mean of x and y) [-].
    connected_share : share of the solid voxels (walls and brush) in the largest face-connected
        solid piece [-]: what a voxel solver sees as one body (thin walls on a coarse grid break).
    gauge : "seed" or "point"; seconds : wall-clock time of the build [s].
    """

    shape: tuple[int, int, int]
    voxel_mm: tuple[float, float, float]
    voxels: int
    part_voxels: int
    foam_voxels: int
    brush_voxels: int
    solid_fraction_foam: float
    target_fraction: float
    solid_fraction_part: float
    seeds: int
    seeds_expected: float
    cells_in_foam: int
    cell_scale_mm: tuple[float, float]
    wall_voxels: float
    connected_share: float
    gauge: str
    seconds: float

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class PrintedFoam:
    """The printed foam in the sheet.

    phases : (nx, ny, nz) uint8, 0 void, 1 solid.
    region : (nx, ny, nz) uint8, 0 outside the part, 1 foam brush, 2 solid brush.
    cell : (nx, ny, nz) int32, the seed owning each foam voxel (-1 elsewhere).
    origin : (3,) [mm] the grid's low corner; size : (3,) [mm] its extent; voxel_mm : (3,) [mm].
    seeds : the :class:`~metasheet.sheet.printed_seeds.SeedSet`; report : :class:`PrintedFoamReport`.
    """

    phases: np.ndarray
    region: np.ndarray
    cell: np.ndarray
    origin: np.ndarray
    size: np.ndarray
    voxel_mm: np.ndarray
    seeds: SeedSet
    report: PrintedFoamReport
    info: dict = field(default_factory=dict)

    def centres(self, axis: int) -> np.ndarray:
        """Voxel-centre coordinates along ``axis`` (n,) [mm]."""
        n = self.phases.shape[axis]
        return self.origin[axis] + (np.arange(n) + 0.5) * self.voxel_mm[axis]


def _check_field(name: str, v: np.ndarray, lo: float, hi: float, lo_open: bool = False) -> None:
    bad = ~np.isfinite(v) | (v <= lo if lo_open else v < lo) | (v > hi)
    if np.any(bad):
        left = "(" if lo_open else "["
        raise ConfigError(f"{name}: values in [{np.nanmin(v):g}, {np.nanmax(v):g}] over the foam "
                          f"({int(bad.sum())} voxels out of range): allowed range is {left}{lo:g}, {hi:g}]")


def _tiles(ijk: np.ndarray, shape, tile: int) -> tuple[np.ndarray, np.ndarray]:
    """(order (P,), ptr (T + 1,)): the points sorted by tile of ``tile`` x ``tile`` voxels x the
    whole z, and each tile's offsets."""
    ty = (shape[1] + tile - 1) // tile
    tid = (ijk[:, 0] // tile) * ty + ijk[:, 1] // tile
    order = np.argsort(tid, kind="stable")
    counts = np.bincount(tid, minlength=((shape[0] + tile - 1) // tile) * ty)
    return order, np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def printed_foam(region: SheetRegion, fields: FoamFields, design: PolyfoamDesign, *, voxel_mm: float,
                 gauge: str = "seed", seed: int | None = None, tile: int = 4, max_voxels: int = 20_000_000,
                 max_seeds: int = 200_000, table: CellScaleTable | None = None) -> PrintedFoam:
    """Generate the Polyfoam printed in ``region`` as a voxel phase grid (module docstring).

    Parameters
    ----------
    region : the part, its box and solid brush (:func:`tripod_region`, :func:`box_region`).
    fields : the foam's settings (:class:`FoamFields`, :func:`printmap_fields`).
    design : the Polyfoam design (bead width, k, min angle, wall measure, seed space, seeds:
        sampler "uniform" or "poisson", min distance; ``infill_percentage``, ``kgon_x_shrink``
        and ``infill_angle`` are the fields', not the design's).
    voxel_mm : wanted voxel edge [mm] in (0, bead_width].
    gauge : "seed" or "point" (:mod:`.printed_walls`).
    seed : RNG seed of the seeds (default the design's ``seeds.seed``).
    tile : tile width [voxels] of the candidate search (speed only: the result does not depend on it).
    max_voxels, max_seeds : refuse larger grids and seed sets (ConfigError naming the field).
    table : a :class:`~metasheet.sheet.printed_seeds.CellScaleTable` covering the fields' shrinks
        (default: built for them, 1 to 4 s per shrink node on one core). Seeds outside
        the foam whose fields leave the table's range take its end values.

    Raises
    ------
    ConfigError : a bad argument or a field out of range, naming it.
    """
    started = time.perf_counter()
    check_range("voxel_mm", voxel_mm, 0.0, float(design.bead_width), lo_open=True)
    if gauge not in GAUGES:
        raise ConfigError(f"gauge: {gauge!r}: expected one of {', '.join(GAUGES)}")
    if design.layer_model != "none":
        raise ConfigError(f"layer_model: {design.layer_model!r}: only 'none' is modelled in the sheet")
    check_range("tile", tile, 1, 256)
    rng_seed = design.seeds.seed if seed is None else int(check_range("seed", seed, 0, None))
    ext = region.hi - region.lo
    shape = voxel_grid(region, voxel_mm, max_voxels)
    count = int(np.prod(shape))
    h = ext / np.array(shape)
    centres = region.lo + voxel_centres(ext, np.array(shape))  # (count, 3), x slowest
    inside = np.asarray(region.inside(centres), dtype=bool)
    brush = inside & (np.asarray(region.solid(centres), dtype=bool) if region.solid is not None else False)
    foam = inside & ~brush
    pts = centres[foam]
    del centres
    if not len(pts):
        raise ConfigError(f"region: {region.name}: no voxel centre lies in the foam brush at voxel_mm {voxel_mm:g}")
    infill, shrink, angle = fields(pts)
    _check_field("infill_percentage", infill, 1.0, 90.0)
    _check_field("kgon_x_shrink", shrink, 0.0, 1.0, lo_open=True)
    _check_field("infill_angle", angle, -1e6, 1e6)
    s_lo, s_hi = float(shrink.min()), float(shrink.max())
    if table is None:
        table = cell_scale_table(design, table_shrinks(s_lo, s_hi))
    elif s_lo < table.shrinks[0] - 1e-9 or s_hi > table.shrinks[-1] + 1e-9:
        raise ConfigError(f"table: shrinks [{table.shrinks[0]:g}, {table.shrinks[-1]:g}] do not cover the foam's "
                          f"kgon_x_shrink [{s_lo:g}, {s_hi:g}]; build it with cell_scale_table over that range")
    L = table(infill, shrink)
    seeds = graded_seeds(design, fields, table, region.lo, region.hi, rng_seed, max_seeds=max_seeds)
    k, amin = int(design.kgon_sides), float(design.kgon_min_angle)
    seed_facets = gauge_facets(k, amin, seeds.shrink, seeds.angle_deg, 1.0 / seeds.cell_scale)
    ijk = np.argwhere(foam.reshape(shape))
    order, ptr = _tiles(ijk, shape, int(tile))
    t = float(design.bead_width)
    cap = 1.5 * t  # walls thresholded at t / 2 (normal) or t / 2 |n_xy| (horizontal, >= t / 2)
    wall, owner, nz = wall_tiles(np.ascontiguousarray(pts[order]), ptr, np.ascontiguousarray(seeds.seeds),
                                 seed_facets, k, amin, np.ascontiguousarray(shrink[order]),
                                 np.ascontiguousarray(angle[order]), np.ascontiguousarray(1.0 / L[order]),
                                 gauge == "point", cap)
    if design.wall_measure == "horizontal":  # the wall's width in a horizontal layer
        wall = wall / np.sqrt(np.clip(1.0 - nz**2, 1e-12, 1.0))
    solid_f = np.empty(len(pts), dtype=bool)
    solid_f[order] = wall < 0.5 * t
    cell_f = np.empty(len(pts), dtype=np.int32)
    cell_f[order] = owner
    phases = brush.astype(np.uint8)
    phases[foam] = solid_f
    reg = np.where(brush, BRUSH, np.where(foam, FOAM, OUTSIDE)).astype(np.uint8)
    cell = np.full(count, -1, dtype=np.int32)
    cell[foam] = cell_f
    n_foam, n_part = int(foam.sum()), int(inside.sum())
    report = PrintedFoamReport(
        shape=shape, voxel_mm=tuple(float(v) for v in h), voxels=count, part_voxels=n_part,
        foam_voxels=n_foam, brush_voxels=int(brush.sum()),
        solid_fraction_foam=float(solid_f.mean()) if n_foam else float("nan"),
        target_fraction=float(np.mean(infill) / 100.0) if n_foam else float("nan"),
        solid_fraction_part=float(phases.sum() / n_part) if n_part else float("nan"),
        seeds=len(seeds.seeds), seeds_expected=seeds.expected,
        cells_in_foam=len(np.unique(cell_f)),
        cell_scale_mm=(float(L.min()), float(L.max())) if n_foam else (float("nan"),) * 2,
        wall_voxels=float(t / np.mean(h[:2])), connected_share=connected_share(phases.reshape(shape)),
        gauge=gauge, seconds=time.perf_counter() - started,
    )
    info = {"region": region.name, "fields": fields.describe(), "design": design.name,
            "seed": rng_seed, "table_shrinks": table.shrinks.tolist()}
    return PrintedFoam(phases.reshape(shape), reg.reshape(shape), cell.reshape(shape), region.lo.copy(),
                       ext.copy(), h, seeds, report, info)


def connected_share(phases: np.ndarray) -> float:
    """Share of the solid voxels of ``phases`` (nx, ny, nz) in its largest face-connected piece."""
    from scipy import ndimage

    labels, n = ndimage.label(phases == 1)
    if n == 0:
        return float("nan")
    sizes = np.bincount(labels.ravel())[1:]
    return float(sizes.max() / sizes.sum())


def compare_gauges(a: PrintedFoam, b: PrintedFoam) -> dict:
    """Where two builds of the same region differ (the two gauges, say): their foam solid
    fractions, the share of foam voxels whose phase differs, and the share whose cell (owning
    seed) differs. Both must share the grid and the seeds."""
    if a.phases.shape != b.phases.shape or not np.array_equal(a.region, b.region):
        raise ConfigError("compare_gauges: the two foams have different grids or regions")
    if not np.array_equal(a.seeds.seeds, b.seeds.seeds):
        raise ConfigError("compare_gauges: the two foams have different seeds")
    foam = a.region == FOAM
    n = int(foam.sum())
    pa, pb = a.phases[foam], b.phases[foam]
    return {
        "foam_voxels": n,
        "solid_fraction": [float(pa.mean()), float(pb.mean())],
        "phase_differs": float(np.mean(pa != pb)),
        "solid_in_one_only": float(np.mean(pa != pb) / max(0.5 * (pa.mean() + pb.mean()), 1e-300)),
        "cell_differs": float(np.mean(a.cell[foam] != b.cell[foam])),
    }
