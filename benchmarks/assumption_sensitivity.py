"""What each modelling assumption of the printed Polyfoam does to its homogenised constants (issue 43).

The paper's Polyfoam (``cells/paper_polyfoam.toml``: infill 15 %, kgon_x_shrink 0.2, one
0.4 mm bead, 0.3 mm voxels) on a small cell (``--count`` cells, default 4), a few seeds
(``--seeds``, default 1 2), homogenised (``homogenize_voxels``, fit about x, the soft axis)
under one-at-a-time changes of the assumptions issue 43 names:

- infill -> geometry: the constants of a linear-elastic periodic cell do not depend on its
  scale, so the cell size L and the bead width t act only through t / L, i.e. through the
  solid fraction. Checked: bead 0.5 mm at the same infill (voxel scaled with it) gives the
  same voxels as bead 0.4 mm (``mapping check``). The sensitivity rows change t / L by
  x1.25 and x0.8 at fixed bead (infill 18.75 and 12: the cell 20 % smaller or 25 % larger;
  equivalently a 0.5 or 0.32 mm bead in the same cell); ``wall_measure = "horizontal"``
  (the bead width measured in the layer, not normal to the wall) and ``seed_space = "print"``
  (seeds spread evenly in print space: cells as tall as wide) are the model's other geometry
  options.
- walls vs struts: the same seeds, box and k-gon gauge, solid = the Voronoi EDGES (the
  catalogue's open-cell strut distance) thresholded to the same solid fraction.
- layer bonding: print direction z (the build axis; x is the shrunk soft axis, y the other
  print-plane axis). Each 0.3 mm layer is taken as bulk TPU plus an interface 10 % of the
  layer thick (0.03 mm) of modulus f E (f = 0.5, 0.1); the layers are thinner than the cells,
  so the printed solid is replaced by its exact laminate (Backus) average, transverse-
  isotropic about z, and the foam homogenised with it.
- TPU modulus: all moduli scale with E_s, Poisson ratios not (exact, not homogenised).

Per variant: the five constants (mean over the seeds), the factor vs the baseline (geometric
mean of the per-seed ratios, same seeds: paired), then per constant the share of the log gap
to the published value each assumption closes (100 % = reaches it, < 0 = moves away).

    OPENBLAS_NUM_THREADS=1 python benchmarks/assumption_sensitivity.py --save
"""

from __future__ import annotations  # noqa: I001 (metasheet is imported before numpy)

import metasheet  # noqa: F401  (before numpy: the package sets its thread environment)

import argparse
import time
import tomllib
from pathlib import Path

import numpy as np

from metasheet.cells.catalogue import design_cell, parse_design
from metasheet.cells.foam import voxel_centres
from metasheet.cells.skeleton import SkeletonIndex
from metasheet.homogenize.voxels import homogenize_voxels
from metasheet.mechanics.material import Isotropic, TransverseIsotropic

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")
PAPER = {"E_t": 1.39, "E_l": 0.0942, "nu_t": 0.262, "nu_tl": 0.416, "mu_l": 0.0163}
INTERFACE = 0.1  # interface thickness / layer height (layer bonding variants)

#: variant -> (what it assumes, design overrides, solid: "walls" | "struts", bonding factor or None)
VARIANTS = {
    "base": ("our model: 1 bead normal to the wall, L from the infill", {}, "walls", None),
    "t/L x1.25": ("cell 20 % smaller at fixed bead (= 0.5 mm bead, same cell)", {"infill_percentage": 18.75},
                  "walls", None),
    "t/L x0.8": ("cell 25 % larger at fixed bead (= 0.32 mm bead, same cell)", {"infill_percentage": 12.0},
                 "walls", None),
    "horizontal": ("bead width measured in the layer (sloped walls thinner)", {"wall_measure": "horizontal"},
                   "walls", None),
    "seeds print": ("seeds even in print space (cells as tall as wide)", {"seed_space": "print"}, "walls", None),
    "struts": ("open cell: Voronoi edges, same seeds, gauge and fraction", {}, "struts", None),
    "bond 0.5": ("interlayer 0.03 mm at 0.5 E every 0.3 mm along z", {}, "walls", 0.5),
    "bond 0.1": ("interlayer 0.03 mm at 0.1 E every 0.3 mm along z", {}, "walls", 0.1),
}


def bonded_solid(E: float, nu: float, factor: float, fraction: float = INTERFACE) -> TransverseIsotropic:
    """The printed solid as layers along z: bulk (E, nu) with an interface of ``fraction`` of the
    layer at ``factor`` E: its exact laminate average (a solid laminate homogenised), axis z."""
    phases = np.ones((2, 2, 10), dtype=np.uint8)
    phases[:, :, : round(10 * fraction)] = 2
    r = homogenize_voxels(phases, (0.2, 0.2, 1.0), {1: Isotropic(E, nu), 2: Isotropic(factor * E, nu)},
                          axis=(0.0, 0.0, 1.0), localise=False)
    return TransverseIsotropic.fit(r.C, axis=(0.0, 0.0, 1.0)).material


def struts_like(cell) -> np.ndarray:
    """Solid = the Voronoi edges of ``cell``'s foam (same seeds, box, gauge), at its solid fraction."""
    foam = cell.foam
    index = SkeletonIndex(foam.seeds, foam.size, foam.metric)
    d = index.distances(voxel_centres(foam.size, cell.shape)).strut
    m = round(cell.relative_density * d.size)
    q = float(np.partition(d, m)[m])
    return (d < q).astype(np.uint8).reshape(cell.shape)


def build(base: dict, overrides: dict, seed: int):
    data = {**base, **{k: v for k, v in overrides.items() if k != "infill_percentage"}}
    return design_cell(parse_design(data, overrides={"seed": seed,
                                                     "infill_percentage": overrides.get("infill_percentage")}))


def constants(cell, phases, bond):
    mat = cell.materials[1]
    materials = {1: mat if bond is None else bonded_solid(mat.E, mat.nu, bond)}
    r = homogenize_voxels(phases, cell.size, materials, axis=cell.axis_vector, localise=False)
    return np.array(r.fit.material.as_tuple())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=4, help="cells (seeds of the Voronoi diagram) per box")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="RNG seeds: realisations per variant")
    ap.add_argument("--voxel", type=float, default=0.3, help="voxel edge [mm]")
    ap.add_argument("--only", nargs="+", choices=tuple(VARIANTS), default=None, help="variants (base always)")
    add_save_option(ap)
    a = ap.parse_args()
    base = tomllib.loads((ROOT / "cells/paper_polyfoam.toml").read_text())
    base["seeds"] = {**base["seeds"], "count": a.count}
    base["voxel_mm"] = a.voxel
    names = ["base", *[v for v in VARIANTS if v != "base" and (a.only is None or v in a.only)]]
    cpu0 = time.process_time()
    results: dict[str, np.ndarray] = {}  # variant -> (n_seeds, 5)
    info: dict[str, str] = {}
    cells = {}
    for name in names:
        _, over, solid, bond = VARIANTS[name]
        rows, rhos, tl = [], [], []
        for s in a.seeds:
            key = tuple(sorted(over.items()))
            if (key, s) not in cells:
                cells[key, s] = build(base, over, s)
            cell = cells[key, s]
            phases = cell.phases if solid == "walls" else struts_like(cell)
            rows.append(constants(cell, phases, bond))
            rhos.append(float((phases > 0).mean()))
            tl.append(cell.polyfoam.wall_thickness / cell.polyfoam.cell_scale)
        results[name] = np.array(rows)
        info[name] = f"rho {np.mean(rhos):.3f}, t/L {np.mean(tl):.4f}, grid {'x'.join(map(str, cell.shape))}"
    # the mapping check: the same infill with a 0.5 mm bead (voxel scaled with it) gives the same voxels
    c1 = cells[(), a.seeds[0]]
    c2 = design_cell(parse_design({**base, "bead_width": 0.5, "voxel_mm": a.voxel * 1.25}, overrides={"seed": a.seeds[0]}))
    same = c1.phases.shape == c2.phases.shape and bool(np.array_equal(c1.phases, c2.phases))
    cpu = time.process_time() - cpu0

    with saved_output(__file__, a.save, fenced=True):
        print(f"paper_polyfoam, {a.count} cells, voxel {a.voxel:g} mm, seeds {' '.join(map(str, a.seeds))}; "
              f"constants: mean over the seeds [MPa]; factor: vs base, geometric mean of the per-seed ratios")
        print(f"\n{'variant':<12}{'E_t':>8}{'E_l':>9}{'nu_t':>7}{'nu_tl':>7}{'mu_l':>8}   "
              f"{'x E_t':>6}{'x E_l':>6}{'x nu_t':>7}{'x nu_tl':>8}{'x mu_l':>7}   cell")
        b = results["base"]
        for name in names:
            v = results[name]
            mean = v.mean(axis=0)
            fac = np.exp(np.mean(np.log(np.abs(v / b)), axis=0)) * np.sign(np.mean(v / b, axis=0))
            print(f"{name:<12}{mean[0]:>8.3f}{mean[1]:>9.4f}{mean[2]:>7.3f}{mean[3]:>7.2f}{mean[4]:>8.4f}   "
                  f"{fac[0]:>6.2f}{fac[1]:>6.2f}{fac[2]:>7.2f}{fac[3]:>8.2f}{fac[4]:>7.2f}   {info[name]}")
        pub = np.array([PAPER[k] for k in NAMES])
        bm = b.mean(axis=0)
        pf = pub / bm
        print(f"{'published':<12}{pub[0]:>8.3f}{pub[1]:>9.4f}{pub[2]:>7.3f}{pub[3]:>7.2f}{pub[4]:>8.4f}   "
              f"{pf[0]:>6.2f}{pf[1]:>6.2f}{pf[2]:>7.2f}{pf[3]:>8.2f}{pf[4]:>7.2f}   (factor: published / base)")
        s_fac = 1.39 / bm[0]
        print(f"{'TPU E x' + format(s_fac, '.2f'):<12}{'':>8}{'':>9}{'':>7}{'':>7}{'':>8}   "
              f"{s_fac:>6.2f}{s_fac:>6.2f}{1:>7.2f}{1:>8.2f}{s_fac:>7.2f}   "
              f"exact scaling: E_s {12 * s_fac:.1f} MPa puts E_t on the published value")
        print("\nvariants:")
        for name in names:
            bond = VARIANTS[name][3]
            extra = ""
            if bond is not None:
                m = bonded_solid(12.0, 0.3, bond)
                extra = f" (printed solid: E_z / E {m.E_l / 12.0:.2f}, E_xy / E {m.E_t / 12.0:.2f})"
            print(f"  {name:<12}{VARIANTS[name][0]}{extra}")
        print(f"mapping check: bead 0.5 mm, voxel {1.25 * a.voxel:g} mm, same infill, seed {a.seeds[0]}: "
              f"{'the same voxels' if same else 'DIFFERENT voxels'} as bead 0.4 mm, voxel {a.voxel:g} mm "
              f"(L {c2.polyfoam.cell_scale / c1.polyfoam.cell_scale:.3f}x): the constants depend on t / L only")
        print("\nshare of the log gap base -> published closed by each variant "
              "(100 % reaches it, > 100 % overshoots, < 0 moves away):")
        gap = np.log(pub / bm)
        for j, k in enumerate(NAMES):
            shares = []
            for name in names[1:]:
                mv = np.log(np.abs(results[name].mean(axis=0)[j] / bm[j]))
                shares.append((mv / gap[j], name))
            shares.sort(reverse=True)
            shown = ", ".join(f"{n} {100 * s:+.0f} %" for s, n in shares)
            toward = [n for s, n in shares if 0.1 < s <= 1.5]
            over = [n for s, n in shares if s > 1.5]
            verdict = [f"closes 10-150 %: {', '.join(toward)}"] if toward else []
            verdict += [f"overshoots: {', '.join(over)}"] if over else []
            print(f"  {k:<6} gap x{pub[j] / bm[j]:.2f}: {shown}; "
                  f"{'; '.join(verdict) if verdict else 'no variant closes 10 % of it'}")
        print(f"\nCPU {cpu:.0f} s ({len(names)} variants x {len(a.seeds)} seeds)")


if __name__ == "__main__":
    main()
