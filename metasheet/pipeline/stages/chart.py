"""Stage ``chart``: the design chart of a foam family over (relative density, stretch).

Each grid point (and seed) builds a foam from the base ``design`` with
:mod:`metasheet.cells.design` and homogenises it; the points run through
``ctx.executor.map``. Writes ``chart.csv`` (one row per point and seed, columns
:data:`metasheet.homogenize.chart.COLUMNS`, moduli in MPa) and ``chart.png`` (one
panel per constant). :func:`metasheet.homogenize.chart.lookup` inverts the chart.
"""

from __future__ import annotations

import tomllib

import numpy as np
from pydantic import Field, model_validator

from ...errors import ConfigError
from ...homogenize.chart import chart_points, evaluate_point, to_csv
from ..registry import Params, Stage, StageContext, register


class ChartParams(Params):
    design: str = Field("cells/quick_foam.toml", description="base foam design, relative to the project root")
    density_min: float = Field(0.12, gt=0, lt=1, description="lowest target relative density [-]")
    density_max: float = Field(0.35, gt=0, lt=1, description="highest target relative density [-]")
    density_steps: int = Field(4, ge=2, le=50, description="densities in the sweep")
    stretch_min: float = Field(1.0, ge=1, le=20, description="lowest metric stretch [-]")
    stretch_max: float = Field(3.0, ge=1, le=20, description="highest metric stretch [-]")
    stretch_steps: int = Field(3, ge=2, le=50, description="stretches in the sweep")
    resolution: int = Field(24, ge=16, le=128, description="voxels per side of each cell")
    seeds: int = Field(1, ge=1, le=20, description="foam realisations per point (seeds base, base + 1, ...)")

    @model_validator(mode="after")
    def _ranges(self):
        if self.density_max <= self.density_min:
            raise ValueError(f"density_max {self.density_max} must exceed density_min {self.density_min}")
        if self.stretch_max <= self.stretch_min:
            raise ValueError(f"stretch_max {self.stretch_max} must exceed stretch_min {self.stretch_min}")
        return self


def run(ctx: StageContext) -> dict:
    p: ChartParams = ctx.params
    path = (ctx.root / p.design).resolve()
    if not path.exists():
        raise ConfigError(f"chart.design: {p.design!r}: no such file under {ctx.root}")
    design = tomllib.loads(path.read_text())
    if design.get("kind", "foam") != "foam":
        raise ConfigError(f"chart.design: {p.design!r}: kind {design.get('kind')!r}: the chart needs a foam")
    base_seed = int(design.get("seeds", {}).get("seed", 0))
    items = chart_points(design, np.linspace(p.density_min, p.density_max, p.density_steps),
                         np.linspace(p.stretch_min, p.stretch_max, p.stretch_steps),
                         [base_seed + k for k in range(p.seeds)], p.resolution)
    rows = ctx.executor.map(evaluate_point, items,
                            progress=lambda done, total: ctx.progress("chart: cells", done, total))
    ctx.path("chart.csv").write_text(to_csv(rows))
    from ...viz.homogenize import chart_picture

    title = f"design chart of {design.get('name', path.stem)} ({p.resolution}^3 voxels, {p.seeds} seed(s) per point)"
    ctx.path("chart.png").write_bytes(chart_picture(rows, title))
    return {"points": len(rows), "E_t_range_MPa": [min(r["E_t"] for r in rows), max(r["E_t"] for r in rows)],
            "alpha_range_percent": [min(r["alpha"] for r in rows), max(r["alpha"] for r in rows)]}


register(
    Stage(
        name="chart",
        params=ChartParams,
        run=run,
        outputs=("chart.csv", "chart.png"),
        doc="design chart: five TI constants over (relative density, stretch) -> chart.csv, chart.png",
    )
)
