"""A foam cell and its homogenised transverse-isotropic constants.

Builds a periodic Voronoi strut foam from a catalogue design in ``cells/`` (its cells
flattened along the longitudinal axis l, so the foam is soft along l, like the paper's),
homogenises it on its voxels (six periodic corrector problems) and fits the closest
transverse-isotropic material: E_t, E_l, nu_t, nu_tl, mu_l, with the misfit of that fit
(the share of the stiffness, in the Frobenius norm, that is not transverse-isotropic).
Small case: ``cells/quick_foam.toml`` on 24^3 voxels (about a second); full case:
``cells/paper_foam.toml`` on its 64^3 voxels (about 15 s).

Run: python examples/cell_constants.py
"""

from __future__ import annotations

import io
import tomllib
import sys
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU)
import matplotlib

matplotlib.use("Agg")  # off screen: no display needed
import matplotlib.pyplot as plt

from metasheet.cells import design_cell, parse_design
from metasheet.homogenize import homogenize_voxels
from metasheet.viz import figure_png

ROOT = Path(__file__).resolve().parents[1]


def main(small: bool = False, out: Path | None = None) -> dict:
    name, overrides = ("quick_foam", {"resolution": 24}) if small else ("paper_foam", {})
    data = tomllib.loads((ROOT / "cells" / f"{name}.toml").read_text())
    design = parse_design(data, overrides=overrides, source=name)  # validated; errors name the field
    cell = design_cell(design)  # seeds -> Voronoi skeleton -> strut radius solved for the density

    # axis: fit the TI material about the design's l axis (None would search the best axis)
    result = homogenize_voxels(cell.phases, cell.size, cell.materials, axis=cell.axis_vector)
    m = result.fit.material
    numbers = {**m.to_dict(), "alpha": m.alpha, "relative_density": result.relative_density,
               "misfit": result.fit.misfit, "n_dof": result.n_dof}

    print(f"{name}: {'x'.join(map(str, cell.shape))} voxels, box {cell.size.tolist()} mm, {result.n_dof} dofs")
    units = {"E_t": "MPa", "E_l": "MPa", "mu_l": "MPa", "alpha": "%"}
    for key in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l", "alpha", "relative_density", "misfit"):
        print(f"  {key:17s} {numbers[key]:10.4f} {units.get(key, '-')}")

    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "cell_constants.png"
    picture(cell, numbers, f"{name}: {'x'.join(map(str, cell.shape))} voxels, {result.n_dof} dofs", out)
    return numbers


def picture(cell, numbers: dict, title: str, out: Path) -> None:
    """The voxels that were homogenised (pyvista, off screen) beside the fitted constants."""
    from metasheet.viz.cell import voxel_picture

    render = voxel_picture(cell.phases, cell.size, tiles=1, window=(600, 600))  # PNG bytes
    fig, (a0, a1, a2) = plt.subplots(1, 3, figsize=(13, 4.4), gridspec_kw={"width_ratios": [1.2, 1, 1]})
    a0.imshow(plt.imread(io.BytesIO(render)))
    a0.set_axis_off()
    a0.set_title(f"{title}\nl = {'xyz'[cell.axis]}, relative density {numbers['relative_density']:.3f}")
    moduli, ratios = ("E_t", "E_l", "mu_l"), ("nu_t", "nu_tl")
    a1.bar(moduli, [numbers[k] for k in moduli], color=["#1f5fbf", "#d62728", "#2ca02c"])
    a1.set(ylabel="modulus [MPa]", title=f"moduli (alpha = 1 - E_l / E_t = {numbers['alpha']:.1f} %)")
    a2.bar(ratios, [numbers[k] for k in ratios], color=["#7f7f7f", "#ff7f0e"])
    a2.set(ylabel="Poisson ratio [-]", title=f"Poisson ratios (TI misfit {numbers['misfit']:.3f})")
    for ax, keys in ((a1, moduli), (a2, ratios)):
        for i, k in enumerate(keys):
            ax.annotate(f"{numbers[k]:.3g}", (i, numbers[k]), ha="center", va="bottom")
    metasheet.write_file(out, figure_png(fig))  # never half a file


if __name__ == "__main__":  # python examples/NAME.py [PICTURE] (default: outputs/examples/NAME.png)
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
