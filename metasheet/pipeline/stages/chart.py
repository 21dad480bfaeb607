"""Stage ``chart``: the design chart of a cell family over its two print settings.

Strut foams (``kind = "foam"``) sweep (relative density, stretch); IceSL Polyfoam cells
(``kind = "polyfoam"``) sweep IceSL's own ``infill_percentage`` x ``kgon_x_shrink``
(:data:`metasheet.homogenize.chart.FAMILY_AXES`). Each grid point (and seed) builds a cell
from the base ``design`` with :mod:`metasheet.cells.catalogue` and homogenises it; the points
run through ``ctx.executor.map``. Writes ``chart.csv`` (one row per point and seed, columns
:func:`metasheet.homogenize.chart.columns`, moduli in MPa) and ``chart.png`` (one panel per
constant; with ``seeds`` >= 2 the bars are 95 % intervals of each point's mean,
:mod:`metasheet.homogenize.chart_bars`, and the manifest's summary says how each constant's
were made). :func:`metasheet.homogenize.chart.lookup` inverts the chart.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field, model_validator

from ...errors import ConfigError
from ...homogenize.chart import FAMILY_AXES, chart_points, evaluate_point, to_csv
from ...homogenize.chart_bars import chart_bars
from ...mechanics.material import CONSTANT_NAMES
from ..registry import Params, Stage, StageContext, register
from .cell import read_design_toml


class ChartParams(Params):
    design: str = Field("cells/quick_foam.toml", description="base foam design, relative to the project root")
    density_min: float = Field(0.12, gt=0, lt=1, description="lowest target relative density [-]")
    density_max: float = Field(0.35, gt=0, lt=1, description="highest target relative density [-]")
    density_steps: int = Field(4, ge=2, le=50, description="densities in the sweep")
    stretch_min: float = Field(1.0, ge=1, le=20, description="lowest metric stretch [-]")
    stretch_max: float = Field(3.0, ge=1, le=20, description="highest metric stretch [-]")
    stretch_steps: int = Field(3, ge=2, le=50, description="stretches in the sweep")
    resolution: int = Field(24, ge=16, le=128, description="voxels per side of each cell (foam)")
    sweep: dict[str, list[float]] | None = Field(
        None, description="the family's two settings -> swept values, e.g. infill_percentage = [9, 18, 26, 34], "
        "kgon_x_shrink = [0.2, 0.6, 1.0] (polyfoam; foam default: the density_* and stretch_* ranges)")
    voxel_mm: float | None = Field(None, gt=0, le=2, description="voxel edge of each cell [mm] (polyfoam; "
                                   "default: the design's)")
    seeds: int = Field(1, ge=1, le=20, description="foam realisations per point (seeds base, base + 1, ...)")
    tolerance: float = Field(1e-5, gt=0, le=1e-4, description="relative residual of the corrector solves [-] "
                             "(as homogenize.tolerance: C* in energy form, its error second order in it)")
    seed_count: int | None = Field(None, ge=1, le=4096, description="seed points per cell (default: the "
                                   "design's); fewer make cheaper, noisier cells")

    @model_validator(mode="after")
    def _ranges(self):
        if self.density_max <= self.density_min:
            raise ValueError(f"density_max {self.density_max} must exceed density_min {self.density_min}")
        if self.stretch_max <= self.stretch_min:
            raise ValueError(f"stretch_max {self.stretch_max} must exceed stretch_min {self.stretch_min}")
        return self

    def check_files(self, table: str, params: dict, root: Path) -> None:
        """The base design is read and its family checked (as the stage will)."""
        base_design(root, self)


#: The default Polyfoam sweep: the authors' four measured densities (ICESL.md), their shrink
#: 0.2 up to no shrink (isotropic in the print plane).
POLYFOAM_SWEEP = {"infill_percentage": [9.0, 18.0, 26.0, 34.0], "kgon_x_shrink": [0.2, 0.5, 1.0]}


def sweep_values(p: ChartParams, family: str) -> tuple[list[float], list[float]]:
    """The two axes' values for ``family``, validated: >= 2 increasing values each."""
    a, b = FAMILY_AXES[family]
    sweep = p.sweep
    if sweep is None:
        if family == "foam":
            return (np.linspace(p.density_min, p.density_max, p.density_steps).tolist(),
                    np.linspace(p.stretch_min, p.stretch_max, p.stretch_steps).tolist())
        sweep = POLYFOAM_SWEEP
    if set(sweep) != {a, b}:
        raise ConfigError(f"chart.sweep: keys {sorted(sweep)}: a {family} chart sweeps exactly {a} and {b}")
    out = []
    for name in (a, b):
        v = [float(x) for x in sweep[name]]
        if len(v) < 2 or any(y <= x for x, y in zip(v, v[1:])) or not all(np.isfinite(v)):
            raise ConfigError(f"chart.sweep.{name}: {v!r}: expected >= 2 finite, strictly increasing values")
        out.append(v)
    return out[0], out[1]


def base_design(root: Path, p: ChartParams) -> tuple[dict, str]:
    """The base design's table and its family; ConfigError naming chart.design."""
    path = (root / p.design).resolve()
    if not path.is_file():
        raise ConfigError(f"chart.design: {p.design!r}: no such file under {root}")
    design = read_design_toml(path, f"chart.design: {p.design!r}")
    family = design.get("kind", "foam")
    if family not in FAMILY_AXES:
        raise ConfigError(f"chart.design: {p.design!r}: kind {family!r}: the chart needs one of "
                          f"{', '.join(FAMILY_AXES)}")
    return design, family


def run(ctx: StageContext) -> dict:
    p: ChartParams = ctx.params
    design, family = base_design(ctx.root, p)
    first, second = sweep_values(p, family)
    if p.seed_count is not None:
        design["seeds"] = {**design.get("seeds", {}), "count": p.seed_count}
    base_seed = int(design.get("seeds", {}).get("seed", 0))
    items = chart_points(design, first, second, [base_seed + k for k in range(p.seeds)],
                         resolution=p.resolution if family == "foam" else None,
                         voxel_mm=p.voxel_mm if family == "polyfoam" else None, rtol=p.tolerance)
    _check_corners(items, p.design)
    rows = ctx.executor.map(evaluate_point, items,
                            progress=lambda done, total: ctx.progress("chart: cells", done, total))
    ctx.path("chart.csv").write_text(to_csv(rows))
    from ...viz.homogenize import chart_picture

    grid = f"{p.resolution}^3 voxels" if family == "foam" else f"voxel {p.voxel_mm or design.get('voxel_mm')} mm"
    title = (f"design chart of {design.get('name', Path(p.design).stem)} ({grid}, {design.get('seeds', {}).get('count')} "
             f"cells, {p.seeds} realisation(s) per point" + (", bars: 95 % interval of the mean)" if p.seeds > 1 else ")"))
    ctx.path("chart.png").write_bytes(chart_picture(rows, title))
    out = {"points": len(rows), "E_t_range_MPa": [min(r["E_t"] for r in rows), max(r["E_t"] for r in rows)],
           "alpha_range_percent": [min(r["alpha"] for r in rows), max(r["alpha"] for r in rows)]}
    if p.seeds > 1:  # how the picture's bars were made, per constant
        axes = FAMILY_AXES[family]
        out["bars"] = {k: chart_bars(rows, k, *axes).to_json() for k in (*CONSTANT_NAMES, "alpha")}
    return out


def _check_corners(items: list[dict], source: str) -> None:
    """Validate the sweep's extreme settings up front: a bad range fails here, named, not in a worker."""
    from ...cells.catalogue import parse_design
    from ...homogenize.chart import item_design

    for item in (items[0], items[-1]):
        data, overrides = item_design(item)
        parse_design(data, overrides=overrides, source=f"chart.design ({source})")


register(
    Stage(
        name="chart",
        params=ChartParams,
        run=run,
        outputs=("chart.csv", "chart.png"),
        doc="design chart: five TI constants over a family's two settings -> chart.csv, chart.png",
    )
)
