"""The tripod sheet, its spiral fibre field and the IceSL print map that prints it.

Meshes the Y-shaped sheet, gives every element the spiral fibre l (the foam's soft axis)
and a density graded along the radius, and turns each element's constants into IceSL
Polyfoam settings through a print model: here the point model of the paper's foam
(published constants, printed at infill 15 %, kgon_x_shrink 0.2), whose moduli scale as
infill^1.1 near that point. The settings and the fibre's in-plane angle are sampled on
IceSL's 64^3 texture grid, quantised to 8 bits as the slicer holds them, and read back at
every element (the printmap stage's round trip): what is printed is what was modelled.
Small case: 8 mm elements (a few seconds); full case: 5 mm (3,586 tetrahedra, seconds too).

Run: python examples/sheet_printmap.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU)
import matplotlib

matplotlib.use("Agg")  # off screen: no display needed
import matplotlib.pyplot as plt
import numpy as np

from metasheet.published import paper
from metasheet.pipeline.printsource import WALL_EXPONENT, PointModel
from metasheet.sheet import SheetParams, grade, spiral_fibers, tripod_sheet
from metasheet.sheet import icesl
from metasheet.sheet.consistency import round_trip
from metasheet.sheet.grading import element_constants, scaling_lookup
from metasheet.viz import figure_png

ROOT = Path(__file__).resolve().parents[1]
# [-] 13.5 % at the centre to ~17 % at the arm ends; gentle on purpose: each texel takes its element's
# value, so the read-back sees the steps between elements (0.12 + 0.06 r / 66 misses the 2 %)
DENSITY = "0.135 + 0.03 * r / 66"


def fibre(points):
    """The soft axis l (q, 3) at points (q, 3) [mm]: a log spiral at 45 deg to the circles."""
    return spiral_fibers(points, law="log", pitch_deg=45.0)


def main(small: bool = False, out: Path | None = None) -> dict:
    sp = SheetParams(mesh_size=8.0 if small else 5.0)  # the metasheet scene's sheet [mm]
    sheet = tripod_sheet(sp)  # gmsh, deterministic
    centroids = sheet.centroids()
    fibers = fibre(centroids)  # one per element: what the robot's FEM uses

    # the design: density graded along r; the moduli follow it with the print model's own
    # exponent, so that the printed infill is 100 x the designed density (a consistent pair)
    grading = grade(centroids, sp, density=paper.FOAM_RELATIVE_DENSITY, alpha=paper.PAPER_FOAM.alpha,
                    density_expr=DENSITY)
    lookup = scaling_lookup(paper.PAPER_FOAM, paper.FOAM_RELATIVE_DENSITY, WALL_EXPONENT)
    constants = element_constants(grading, lookup)  # name -> (m,) [MPa, -]
    model = PointModel(percent=100 * paper.FOAM_RELATIVE_DENSITY, shrink=0.2,
                       constants=paper.PAPER_FOAM.to_dict(), cell="paper foam (published)")

    solid = icesl.solid_mask(centroids, sp)  # centre ring and arm-end tabs print solid
    fields = icesl.print_fields(sheet.points, sheet.tets, element_settings=model.settings_for(constants),
                                fiber_fn=fibre, params=sp)  # at texel centres: the continuous field
    held = {k: icesl.quantise(t) for k, t in fields.textures.items()}  # tex3d_r8f: 8 bits a texel
    report = round_trip(box=fields.box, textures=held, constants_at=model.constants_at, centroids=centroids,
                        constants=constants, fibers=fibers, printed_solid=solid, volumes=sheet.volumes())

    infill = fields.values("infill_percentage")[fields.foam]
    numbers = {"tets": len(sheet.tets), "foam_elements": report.compared, "solid_elements": int(solid.sum()),
               "density_min": float(grading.density.min()), "density_max": float(grading.density.max()),
               "infill_min": float(infill.min()), "infill_max": float(infill.max()),
               "max_rel_difference": max(c.max for c in report.constants.values()),
               "max_axis_difference_deg": report.angle.max, "ok": report.ok}
    print(f"sheet: {numbers['tets']} tets ({numbers['solid_elements']} printed solid), texture box "
          f"{np.round(fields.box.lo, 1).tolist()} .. {np.round(fields.box.hi, 1).tolist()} mm, {icesl.N}^3")
    print(f"  designed density      {numbers['density_min']:.4f} .. {numbers['density_max']:.4f}")
    print(f"  infill_percentage     {numbers['infill_min']:.2f} .. {numbers['infill_max']:.2f} %")
    print(f"  round trip on {report.compared} foam elements: constants within "
          f"{numbers['max_rel_difference']:.2%}, soft axis within {report.angle.max:.2f} deg "
          f"({'ok' if report.ok else 'FAILS'})")

    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "sheet_printmap.png"
    picture(fields, out)
    return numbers


def picture(fields, out: Path) -> None:
    """Top view, mid-plane: the infill field under the fibre streaks, and IceSL's angle field."""
    mid = fields.box.n // 2
    x, y, z = fields.box.axes()
    inside, solid = fields.inside[:, :, mid], fields.solid[:, :, mid] & fields.inside[:, :, mid]
    X, Y = np.meshgrid(x, y, indexing="ij")
    fib = fibre(np.stack([X.ravel(), Y.ravel(), np.full(X.size, z[mid])], axis=1)).reshape(*X.shape, 3)
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.6))
    shown = {"infill_percentage [%] and fibre l": ("infill_percentage", "viridis", None),
             "infill_angle: soft axis in the print plane [deg], mod 180": ("infill_angle", "twilight", (0, 180))}
    for ax, (title, (name, cmap, rng)) in zip(axes, shown.items()):
        v = fields.values(name)[:, :, mid]
        v = np.mod(v, 180.0) if name == "infill_angle" else v  # an axis: only mod 180 matters
        v = np.where(inside & ~solid, v, np.nan)
        im = ax.imshow(v.T, origin="lower", extent=(x[0], x[-1], y[0], y[-1]), cmap=cmap,
                       vmin=rng and rng[0], vmax=rng and rng[1], interpolation="nearest")
        fig.colorbar(im, ax=ax, shrink=0.8)
        ax.contour(X, Y, inside.astype(float), levels=[0.5], colors="k", linewidths=1.2)
        ax.contourf(X, Y, solid.astype(float), levels=[0.5, 1.5], colors="0.75")  # printed solid
        ax.set(title=title, xlabel="x [mm]", ylabel="y [mm]", aspect="equal")
    U, V = (np.where(inside, fib[..., i], np.nan).T for i in (0, 1))
    axes[0].streamplot(x, y, U, V, density=1.6, color="k", linewidth=0.7, arrowstyle="-")
    fig.suptitle("IceSL print map of the tripod sheet, mid-plane (grey: solid parts, brush 1)")
    metasheet.write_file(out, figure_png(fig))  # never half a file


if __name__ == "__main__":  # python examples/NAME.py [PICTURE] (default: outputs/examples/NAME.png)
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
