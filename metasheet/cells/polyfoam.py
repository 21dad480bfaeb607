"""The Polyfoam cell: its design (:class:`PolyfoamDesign`), density solve and level set.

One-bead walls, the cell size L set by the density; :func:`build_polyfoam` builds the cell
of a design (:func:`metasheet.cells.catalogue.design_cell` dispatches to it).

IceSL prints Polyfoam's Voronoi *walls* one bead thick (inferred, see ICESL.md); the infill
density then sets the cell size, not the wall thickness. The model here (the named
assumption ``density_model = "volume_fraction"``): ``infill_percentage / 100`` is the solid
volume fraction of the cell.

The seeds and the box are drawn once at unit scale (``seeds_unit``, ``unit_size``) and the
whole foam is scaled by a length ``L`` [mm]; the wall distance field scales with it,
``a_L(x) = L a_1(x / L)``, so the solid ``{a_L < t / 2}`` (``t`` the bead width) has the
volume fraction ``F(t / (2 L))``, ``F`` the distribution of the unit-scale wall distances
over the box. Hence ``L = t / (2 q)`` with ``q`` the quantile of those distances at the
target fraction:

1. ``q`` on a fine regular sample of the unit box (``sample_points``) gives a first ``L``;
2. the voxel grid ``(nx, ny, nz)``, edge ~ ``voxel_mm`` on the box ``L unit_size``, is
   chosen, the distances are recomputed at its voxel centres and ``L`` is solved again on
   it as an order statistic (so the voxel solid fraction hits the target to ``1 / n_voxels``);
   if ``L`` moved enough to change the grid, repeat (at most :data:`MAX_ITERATIONS` times).

The continuous fraction at the final ``L`` (the fine sample's) is reported as
``volume_estimate``; its difference to the voxel fraction is the voxelisation error.

Two candidate physical differences, each a named option (default: off):

- ``wall_measure``: ``"normal"`` (the bead width is the wall's thickness normal to it) or
  ``"horizontal"`` (the bead width is the wall's width in each horizontal layer, as a
  printer lays it; a wall at ``theta`` from horizontal is then ``t sin(theta)`` thick).
  The distance thresholded is then the horizontal distance to the nearest wall plane,
  ``a / |n_xy|``.
- ``layer_height`` (staircase): every layer ``[k h, (k + 1) h)`` is the horizontal slice of
  the walls at its mid-height, extruded over the layer (sloped walls become stairs). The
  box holds a whole number of layers (``h`` adjusted by a few %, reported) and the grid
  ``m = max(2, ceil(h / voxel_mm))`` voxels per layer along z (one voxel per layer would
  be the same as no staircase on a coarser grid).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator

from ..errors import ConfigError, InfeasibleError, check_range
from .connectivity import settle_phases
from .foam import Foam, voxel_centres
from .kgon import KgonMetric
from .measure import mean_chord_lengths
from .seeds import make_seeds
from .skeleton import SkeletonIndex
from .specs import MaterialSpec, SeedSpec, _Model

MAX_ITERATIONS = 4


@dataclass(frozen=True)
class PolyfoamSolution:
    """The solved scale of a Polyfoam cell.

    Attributes
    ----------
    cell_scale : L [mm], the length the unit-scale seeds and box are multiplied by.
    first_estimate : L [mm] from the fine sample, before the grid solve.
    size : (3,) [mm] the periodic box ``L * unit_size``.
    shape : (nx, ny, nz) the voxel grid.
    voxel_mm : (3,) [mm] the voxel edges ``size / shape``.
    wall_thickness : t [mm] (one bead).
    target : the asked solid fraction [-].
    relative_density : the voxel solid fraction at ``cell_scale`` [-].
    volume_estimate : the fine sample's solid fraction at ``cell_scale`` [-].
    iterations : grid solves done.
    wall_measure : "normal" or "horizontal" (see the module docstring).
    layers : number of printed layers in the box (staircase), else 0.
    layer_mm : the layer height used [mm] (``size_z / layers``), else 0.
    """

    cell_scale: float
    first_estimate: float
    size: np.ndarray
    shape: tuple[int, int, int]
    voxel_mm: np.ndarray
    wall_thickness: float
    target: float
    relative_density: float
    volume_estimate: float
    iterations: int
    wall_measure: str = "normal"
    layers: int = 0
    layer_mm: float = 0.0


WALL_MEASURES = ("normal", "horizontal")


def _layers(unit_size: np.ndarray, scale: float, layer_height: float | None) -> int:
    return 0 if layer_height is None else int(max(1, round(scale * unit_size[2] / layer_height)))


def _grid(unit_size: np.ndarray, scale: float, voxel_mm: float, layer_height: float | None):
    """((nx, ny, nz), layers) of the box ``scale * unit_size`` at edge ~ ``voxel_mm``."""
    n = [int(max(2, round(v))) for v in scale * unit_size / voxel_mm]
    layers = _layers(unit_size, scale, layer_height)
    if layers:
        n[2] = layers * int(max(2, np.ceil(layer_height / voxel_mm - 1e-6)))  # >= 2 voxels per layer
    return tuple(n), layers


def snap_to_layers(points: np.ndarray, period_z: float, layers: int) -> np.ndarray:
    """``points`` (n, 3) with z moved to the mid-height of its layer (``layers`` per ``period_z``)."""
    if not layers:
        return points
    h = period_z / layers
    out = np.array(points, dtype=float)
    out[:, 2] = (np.floor(np.mod(out[:, 2], period_z) / h) + 0.5) * h
    return out


def measured_wall(d, wall_measure: str) -> np.ndarray:
    """The wall distance thresholded at half the bead width: normal, or horizontal ``a / |n_xy|``."""
    if wall_measure == "normal":
        return d.wall
    sxy = np.sqrt(np.clip(1.0 - d.wall_nz**2, 1e-12, 1.0))
    return d.wall / sxy


def _order_statistic(d: np.ndarray, fraction: float, where: str) -> float:
    """The threshold between the m-th and (m+1)-th smallest of ``d``, ``m = round(fraction * len)``."""
    m = int(round(fraction * d.size))
    if not 1 <= m <= d.size - 1:
        raise InfeasibleError(
            f"infill_percentage: {100 * fraction:g}: {where} has {d.size} points: the fraction is "
            f"out of reach (needs at least one solid and one void point)"
        )
    part = np.partition(d, (m - 1, m))
    return 0.5 * (float(part[m - 1]) + float(part[m]))


def _walls(index: SkeletonIndex, points: np.ndarray, cap: float, wall_measure: str = "normal",
           layers: int = 0) -> np.ndarray:
    pts = snap_to_layers(points, float(index.size[2]), layers)
    return measured_wall(index.distances(pts, cap=cap), wall_measure)


def _fine_sample(index: SkeletonIndex, unit_size: np.ndarray, fraction: float, wall_measure: str,
                 sample_points: int) -> tuple[float, float, np.ndarray]:
    """Step 1 of :func:`solve_polyfoam`: the wall distance ``q`` [-] below which ``fraction`` of a
    fine sample of the unit box lies, the distance cap used, and the sample's distances."""
    n_s = np.maximum(2, np.round(unit_size * (sample_points / np.prod(unit_size)) ** (1 / 3))).astype(int)
    pts = voxel_centres(unit_size, n_s)
    # distances above `cap` may be overestimated: check the quantile is below it
    cap = 0.1 * float(np.min(unit_size))
    sample = _walls(index, pts, cap, wall_measure)
    q = _order_statistic(sample, fraction, "the fine sample")
    if q >= cap:
        cap = np.inf
        sample = _walls(index, pts, cap, wall_measure)
        q = _order_statistic(sample, fraction, "the fine sample")
    return q, cap, sample


def solve_polyfoam(seeds_unit: np.ndarray, unit_size, metric: KgonMetric, *, fraction: float,
                   wall_thickness: float, voxel_mm: float, max_voxels: int,
                   wall_measure: str = "normal", layer_height: float | None = None,
                   sample_points: int = 120_000) -> tuple[PolyfoamSolution, np.ndarray]:
    """Scale L of a one-bead-wall foam for a solid fraction, and its voxel grid.

    Parameters
    ----------
    seeds_unit : (N, 3) seeds at unit scale [-]; unit_size : (3,) their periodic box [-].
    metric : the :class:`~metasheet.cells.kgon.KgonMetric`.
    fraction : target solid volume fraction [-] in (0, 1).
    wall_thickness : t [mm] (the bead width); voxel_mm : wanted voxel edge [mm].
    max_voxels : largest allowed nx * ny * nz.
    wall_measure : "normal" or "horizontal"; layer_height : [mm] staircase layers, or None.
    sample_points : size of the fine sample of step 1.

    Returns
    -------
    (solution, phases) : :class:`PolyfoamSolution` and (nx, ny, nz) uint8, 1 solid.

    Raises
    ------
    ConfigError : the grid would exceed ``max_voxels``.
    InfeasibleError : the fraction is out of reach on the grid.
    """
    check_range("infill fraction", fraction, 0.0, 1.0, lo_open=True, hi_open=True)
    check_range("bead_width", wall_thickness, 0.0, None, lo_open=True)
    check_range("voxel_mm", voxel_mm, 0.0, None, lo_open=True)
    if wall_measure not in WALL_MEASURES:
        raise ConfigError(f"wall_measure: {wall_measure!r}: expected one of {', '.join(WALL_MEASURES)}")
    if layer_height is not None:
        check_range("layer_height", layer_height, 0.0, None, lo_open=True)
    unit_size = np.asarray(unit_size, dtype=float)
    index = SkeletonIndex(seeds_unit, unit_size, metric)
    t = float(wall_thickness)
    q, cap, sample = _fine_sample(index, unit_size, fraction, wall_measure, sample_points)
    L0 = t / (2.0 * q)  # [mm]
    # 2. the voxel grid, and L solved on it
    L, shape, layers, done = L0, None, 0, 0
    for done in range(1, MAX_ITERATIONS + 1):
        new, new_layers = _grid(unit_size, L, voxel_mm, layer_height)
        if new == shape and new_layers == layers:
            done -= 1
            break
        shape, layers = new, new_layers
        count = int(np.prod(shape))
        if count > max_voxels:
            raise ConfigError(
                f"max_voxels: {max_voxels}: the cell needs a {shape[0]} x {shape[1]} x {shape[2]} grid "
                f"({count} voxels; box {', '.join(f'{v:.3g}' for v in L * unit_size)} mm at voxel_mm "
                f"{voxel_mm:g}); raise max_voxels or voxel_mm, or use fewer seeds"
            )
        grid_cap = cap if np.isinf(cap) else max(cap, 3.0 * q)
        a = _walls(index, voxel_centres(unit_size, shape), grid_cap, wall_measure, layers)
        q = _order_statistic(a, fraction, f"the {shape[0]} x {shape[1]} x {shape[2]} voxel grid")
        if q >= grid_cap:
            a = _walls(index, voxel_centres(unit_size, shape), np.inf, wall_measure, layers)
            q = _order_statistic(a, fraction, "the voxel grid")
        L = t / (2.0 * q)
    phases = (a < q).astype(np.uint8).reshape(shape)
    size = L * unit_size
    sol = PolyfoamSolution(
        cell_scale=float(L), first_estimate=float(L0), size=size, shape=shape,
        voxel_mm=size / np.array(shape), wall_thickness=t, target=float(fraction),
        relative_density=float(phases.mean()), volume_estimate=float(np.mean(sample < q)),
        iterations=int(done), wall_measure=wall_measure, layers=int(layers),
        layer_mm=float(size[2] / layers) if layers else 0.0,
    )
    return sol, phases


class PolyfoamField:
    """The level set of a built polyfoam, a picklable callable ``(n, 3) [mm] -> (n,)``, < 0 in
    the solid: the measured wall distance (:func:`measured_wall`, staircase applied) minus
    half the bead width. Periodic with period ``foam.size``.
    """

    def __init__(self, foam, solution: PolyfoamSolution):
        self.foam = foam
        self.solution = solution
        self.index = SkeletonIndex(foam.seeds, foam.size, foam.metric)
        self.offset = 0.5 * foam.thickness
        self.cap = 4.0 * self.offset + 0.05 * float(np.min(foam.size))

    def __call__(self, points: np.ndarray) -> np.ndarray:
        pts = snap_to_layers(np.asarray(points, dtype=float), float(self.foam.size[2]), self.solution.layers)
        d = self.index.distances(pts, cap=self.cap)
        return measured_wall(d, self.solution.wall_measure) - self.offset


# ---------------------------------------------------------------------- the design

class PolyfoamDesign(_Model):
    """IceSL's Polyfoam (as modelled here); see ``cells/paper_polyfoam.toml`` for every field.

    IceSL's names: ``infill_percentage`` [%] (the solid volume fraction x 100 under
    ``density_model = "volume_fraction"``), ``kgon_x_shrink`` [-], ``kgon_min_angle`` [deg],
    ``kgon_norm_alpha`` [-] (only 0.5, IceSL's default: its effect is unpublished),
    ``infill_angle`` [deg] (recorded; applied by the sheet's orientation field),
    ``kgon_sides`` (k, an assumption), ``bead_width`` [mm] (the wall thickness),
    ``layer_height`` [mm] (recorded; modelled only with ``layer_model = "staircase"``).
    ``wall_measure`` ("normal" | "horizontal") says how the bead width is measured;
    ``seed_space`` where the seeds are spread evenly: "gauge" (the gauge's scaled space
    ``(1/s, 1, beta)``, as for foams: cells ``1/beta`` tall) or "print" (``(1/s, 1, 1)``:
    spacing along z as along y, only the shrink applied). The box
    follows from the seeds and the density; the grid from ``voxel_mm`` (default
    ``bead_width / 2``). ``axis`` is 1 (x).
    """

    kind: Literal["polyfoam"] = "polyfoam"
    name: str
    description: str = ""
    axis: Literal[1] = 1
    density_model: Literal["volume_fraction"] = "volume_fraction"
    infill_percentage: float = Field(20.0, ge=1.0, le=90.0)
    kgon_x_shrink: float = Field(1.0, gt=0.0, le=1.0)
    kgon_min_angle: float = Field(45.0, ge=10.0, le=80.0)
    kgon_norm_alpha: float = 0.5
    infill_angle: float = Field(0.0, ge=-360.0, le=360.0)
    kgon_sides: int = Field(6, ge=3, le=64)
    bead_width: float = Field(0.4, gt=0.0, le=5.0)
    layer_height: float = Field(0.3, gt=0.0, le=5.0)
    wall_measure: Literal["normal", "horizontal"] = "normal"
    layer_model: Literal["none", "staircase"] = "none"
    seed_space: Literal["gauge", "print"] = "gauge"
    voxel_mm: float | None = Field(None, gt=0.0, le=5.0)
    max_voxels: int = Field(4_000_000, ge=1000, le=100_000_000)
    tolerance: float = Field(0.005, gt=0.0, lt=1.0)
    max_island_fraction: float = Field(0.01, ge=0.0, le=1.0)
    seeds: SeedSpec = SeedSpec(count=16)
    material: MaterialSpec = MaterialSpec()

    @field_validator("kgon_norm_alpha")
    @classmethod
    def _alpha(cls, v: float) -> float:
        if v != 0.5:
            raise ValueError("only 0.5 (IceSL's default) is modelled: what kgon_norm_alpha does is unpublished")
        return v

    @property
    def voxel_edge(self) -> float:
        """The wanted voxel edge [mm]: ``voxel_mm``, default ``bead_width / 2``."""
        return self.bead_width / 2.0 if self.voxel_mm is None else float(self.voxel_mm)

    @property
    def fraction(self) -> float:
        """The target solid volume fraction [-] (``infill_percentage / 100``)."""
        return self.infill_percentage / 100.0

    def metric(self) -> KgonMetric:
        return KgonMetric(self.kgon_sides, self.kgon_x_shrink, self.kgon_min_angle)


def _seeds(design: PolyfoamDesign):
    """(metric, unit seeds (N, 3), unit box (3,)) of ``design``: a cube in the seeds' scaled space."""
    metric = design.metric()
    sd = design.seeds
    scale = metric.scale if design.seed_space == "gauge" else np.array([1.0 / design.kgon_x_shrink, 1.0, 1.0])
    unit_size = float(sd.count) ** (1.0 / 3.0) / scale
    seeds = make_seeds(sd.sampler, sd.count, unit_size, sd.seed, scale=scale, jitter=sd.jitter,
                       min_distance=sd.min_distance)
    return metric, seeds, unit_size


def cell_extent(design: PolyfoamDesign, sample_points: int = 40_000) -> np.ndarray:
    """(3,) one cell's extent [mm] along x, y, z (the box over the cube root of the seed count)
    from the first estimate of the foam's scale (:func:`solve_polyfoam`'s step 1, no voxel grid):
    within a few % of the built cell's, in about a second."""
    metric, seeds, unit_size = _seeds(design)
    q = _fine_sample(SkeletonIndex(seeds, unit_size, metric), unit_size, design.fraction, design.wall_measure,
                     sample_points)[0]
    return float(design.bead_width) / (2.0 * q) * unit_size / float(design.seeds.count) ** (1.0 / 3.0)


def build_polyfoam(design: PolyfoamDesign) -> dict[str, Any]:
    """Build the cell of ``design``: the fields of its :class:`~metasheet.cells.catalogue.CellResult`.

    The seeds are drawn at unit scale in the gauge's (``seed_space = "gauge"``) or the
    print's scaled space, the scale solved by :func:`solve_polyfoam`; the grid is
    (nx, ny, nz) of edge ~ ``voxel_edge`` [mm], the longitudinal axis x (0).

    Raises
    ------
    ConfigError : ``voxel_mm`` exceeds ``bead_width``, or the grid exceeds ``max_voxels``.
    InfeasibleError : the foam does not hold together or percolate, or misses the density.
    """
    t = float(design.bead_width)
    if design.voxel_edge > t:
        raise ConfigError(
            f"voxel_mm: {design.voxel_edge:g}: must not exceed bead_width {t:g} mm (walls at least one voxel thick)"
        )
    metric, seeds, unit_size = _seeds(design)
    sol, phases = solve_polyfoam(seeds, unit_size, metric, fraction=design.fraction, wall_thickness=t,
                                 voxel_mm=design.voxel_edge, max_voxels=design.max_voxels,
                                 wall_measure=design.wall_measure,
                                 layer_height=design.layer_height if design.layer_model == "staircase" else None)
    size = sol.size
    foam = Foam(seeds * sol.cell_scale, size, metric, "closed", t, 0)
    where = (f"design {design.name!r} (polyfoam, kgon_x_shrink {design.kgon_x_shrink:g}, grid "
             f"{'x'.join(map(str, sol.shape))})")
    phases, report, removed, rho = settle_phases(
        phases, target=design.fraction, tolerance=design.tolerance, max_island_fraction=design.max_island_fraction,
        setting=f"infill_percentage: {design.infill_percentage:g}", where=where,
        hints=("lower voxel_mm", "lower voxel_mm or use more seeds", "lower voxel_mm"))
    return dict(
        design=design, phases=phases, size=size, axis=0, materials={1: design.material.material()},
        relative_density=rho, foam=foam, solution=None, connectivity=report, removed_voxels=removed,
        chords=mean_chord_lengths(phases == 0, size), polyfoam=sol,
    )
