"""A design chart and its inverse look-up: which IceSL settings print a target foam.

Sweeps IceSL's two Polyfoam settings, ``infill_percentage`` x ``kgon_x_shrink``, over a
small chart: each point builds the modelled Polyfoam cell (``cells/quick_polyfoam.toml``
with those settings) and homogenises it. The chart is interpolated (log of the moduli) and
inverted for a target pair (E_t, E_l): the answer is two numbers the slicer takes. The cell
at those settings is then built and homogenised once more, an independent check of the
look-up (its gap is the interpolation's error plus the cell's own seed-to-seed scatter).
Small case: a 3 x 3 chart of coarse cells (0.4 mm voxels, about 10 s); full case: 5 x 5
settings, two seeds each, 0.3 mm voxels, on two worker processes (about 90 s).

Run: python examples/chart_lookup.py
"""

from __future__ import annotations

import tomllib
import sys
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU)
import matplotlib

matplotlib.use("Agg")  # off screen: no display needed
import matplotlib.pyplot as plt
import numpy as np

from metasheet.runtime.executor import Executor
from metasheet.homogenize.chart import ChartInterpolant, chart_points, evaluate_point, lookup
from metasheet.viz import figure_png

ROOT = Path(__file__).resolve().parents[1]
TARGET = {"E_t": 2.0, "E_l": 0.3}  # [MPa]: soft along l (alpha 85 %), inside both charts


def main(small: bool = False, out: Path | None = None) -> dict:
    design = tomllib.loads((ROOT / "cells" / "quick_polyfoam.toml").read_text())
    if small:
        infill, shrink, seeds, voxel_mm, workers = [20, 30, 40], [0.3, 0.6, 1.0], [1], 0.4, 1
    else:
        # 15 % would need 460k voxels at shrink 0.2, over the design's max_voxels (200k)
        infill, shrink, seeds, voxel_mm, workers = [20, 25, 30, 35, 40], [0.2, 0.4, 0.6, 0.8, 1.0], [1, 2], 0.3, 2
    items = chart_points(design, infill, shrink, seeds, voxel_mm=voxel_mm)  # one work unit per cell
    rows = Executor(workers=workers).map(evaluate_point, items)  # workers = 1 runs in this process
    chart = ChartInterpolant.from_table(rows)  # seed means on the settings grid

    found = lookup(chart, **TARGET)  # bounded least squares on log(E_t), log(E_l)
    settings = {k: found[k] for k in chart.axes}
    # the independent check: print-and-measure, i.e. build and homogenise the cell at the answer
    check = evaluate_point(chart_points(design, [settings["infill_percentage"]], [settings["kgon_x_shrink"]],
                                        seeds[:1], voxel_mm=voxel_mm)[0])
    numbers = {**settings, "residual": found["residual"],
               **{f"{k}_chart": found[k] for k in TARGET}, **{f"{k}_cell": check[k] for k in TARGET},
               **{f"{k}_error": check[k] / TARGET[k] - 1.0 for k in TARGET}, "points": len(rows)}

    print(f"chart: {len(infill)} x {len(shrink)} settings, {len(seeds)} seed(s), voxels {voxel_mm} mm")
    print(f"target E_t {TARGET['E_t']:g} MPa, E_l {TARGET['E_l']:g} MPa -> IceSL "
          f"infill_percentage {settings['infill_percentage']:.2f} %, kgon_x_shrink {settings['kgon_x_shrink']:.3f}")
    print(f"  {'':4s} {'target':>8s} {'chart':>8s} {'cell':>8s} {'cell/target-1':>14s}")
    for k in TARGET:
        print(f"  {k:4s} {TARGET[k]:8.3f} {found[k]:8.3f} {check[k]:8.3f} {numbers[k + '_error']:14.1%}")

    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "chart_lookup.png"
    picture(chart, rows, settings, out)
    return numbers


def picture(chart: ChartInterpolant, rows: list[dict], settings: dict, out: Path) -> None:
    """The chart's anisotropy with the two target iso-lines; the look-up is where they cross."""
    (a, b), (ga, gb) = chart.axes, chart.grid
    A, B = np.meshgrid(np.linspace(ga[0], ga[-1], 120), np.linspace(gb[0], gb[-1], 100))
    pts = np.stack([A.ravel(), B.ravel()], axis=1)
    E_t, E_l = (chart(k, pts).reshape(A.shape) for k in ("E_t", "E_l"))
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    im = ax.contourf(A, B, 100 - 100 * E_l / E_t, levels=20, cmap="viridis")
    fig.colorbar(im, ax=ax, label="alpha = 1 - E_l / E_t [%] (interpolated)")
    for field, colour in ((E_t, "white"), (E_l, "crimson")):
        name = "E_t" if field is E_t else "E_l"
        cs = ax.contour(A, B, field, levels=[TARGET[name]], colors=colour, linewidths=2)
        ax.clabel(cs, fmt={TARGET[name]: f"{name} = {TARGET[name]:g} MPa"}, fontsize=9)
    ax.plot([r[a] for r in rows], [r[b] for r in rows], "k.", ms=8, clip_on=False, label="homogenised cells")
    ax.plot(settings[a], settings[b], "*", color="gold", mec="k", ms=20, label="look-up")
    ax.set(xlabel=f"{a} [%]", ylabel=f"{b} [-]",
           title=f"IceSL Polyfoam design chart: {a} {settings[a]:.1f} %, {b} {settings[b]:.2f}")
    ax.legend(loc="lower right")
    metasheet.write_file(out, figure_png(fig))  # never half a file


if __name__ == "__main__":  # python examples/NAME.py [PICTURE] (default: outputs/examples/NAME.png)
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
