"""Homogenised constants of the modelled IceSL Polyfoam (issue 13): convergence and density sweep.

Builds ``cells/paper_polyfoam.toml`` with overrides, homogenises it (``homogenize_voxels``,
solver "auto", fit about x, the soft axis) and prints one row per cell: E_t, E_l, nu_t, nu_tl,
mu_l [MPa], E_x, E_y, E_z / E_s, n_dof, seconds; then the paper's constants and the authors'
power laws for comparison.

    OPENBLAS_NUM_THREADS=1 python benchmarks/polyfoam_sweep.py                # everything below
    OPENBLAS_NUM_THREADS=1 python benchmarks/polyfoam_sweep.py --only paper --voxel 0.27 0.2
    OPENBLAS_NUM_THREADS=1 python benchmarks/polyfoam_sweep.py --only sweep --sweep-count 4 --sweep-voxel 0.3
    OPENBLAS_NUM_THREADS=1 python benchmarks/polyfoam_sweep.py --only variants --infill 26 --sweep-voxel 0.15

Costs grow fast: one-bead walls at low density mean large cells (voxels ~ count / rho^3).
"""

from __future__ import annotations

import argparse
import time
import tomllib
from pathlib import Path

import numpy as np

from metasheet.cells.catalogue import design_cell, parse_design
from metasheet.homogenize.voxels import homogenize_voxels

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]
E_S = 12.0
PAPER = {"E_t": 1.39, "E_l": 0.0942, "nu_t": 0.262, "nu_tl": 0.416, "mu_l": 0.0163}
HEADER = (f"{'case':<10}{'infill':>7}{'shrink':>7}{'vox':>6}{'cnt':>4}{'grid':>16}{'rho':>7}"
          f"{'E_t':>8}{'E_l':>8}{'nu_t':>7}{'nu_tl':>7}{'mu_l':>8}{'Ex/Es':>8}{'Ey/Es':>8}{'Ez/Es':>8}"
          f"{'n_dof':>9}{'t_cell':>7}{'t_hom':>7}")


VARIANTS = {"base": {}, "horizontal": {"wall_measure": "horizontal"}, "staircase": {"layer_model": "staircase"},
            "seeds_print": {"seed_space": "print"}}


def row(case: str, infill: float, shrink: float, voxel: float, count: int, seed: int, max_voxels: int,
        variant: str = "base") -> str:
    data = tomllib.loads((ROOT / "cells/paper_polyfoam.toml").read_text())
    data.update(VARIANTS[variant])
    data["max_voxels"] = max_voxels
    data["seeds"] = {**data["seeds"], "count": count}
    d = parse_design(data, overrides={"infill_percentage": infill, "kgon_x_shrink": shrink, "seed": seed,
                                      "voxel_mm": voxel})
    t0 = time.perf_counter()
    cell = design_cell(d)
    t1 = time.perf_counter()
    r = homogenize_voxels(cell.phases, cell.size, cell.materials, axis=cell.axis_vector, localise=False)
    t2 = time.perf_counter()
    m = r.fit.material
    E = 1.0 / np.diag(np.linalg.inv(r.C))[:3] / E_S
    grid = "x".join(map(str, cell.shape))
    return (f"{case:<10}{infill:>7g}{shrink:>7g}{voxel:>6g}{count:>4d}{grid:>16}{cell.relative_density:>7.3f}"
            f"{m.E_t:>8.4f}{m.E_l:>8.4f}{m.nu_t:>7.3f}{m.nu_tl:>7.3f}{m.mu_l:>8.4f}"
            f"{E[0]:>8.4f}{E[1]:>8.4f}{E[2]:>8.4f}{r.n_dof:>9d}{t1 - t0:>7.1f}{t2 - t1:>7.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("paper", "sweep", "variants"), default=None)
    ap.add_argument("--voxel", type=float, nargs="+", default=[0.27, 0.2], help="paper cell voxel sizes [mm]")
    ap.add_argument("--count", type=int, default=8, help="seeds per cell")
    ap.add_argument("--sweep-voxel", type=float, default=0.3)
    ap.add_argument("--sweep-count", type=int, default=4)
    ap.add_argument("--infill", type=float, nargs="+", default=[9, 18, 26, 34])
    ap.add_argument("--shrink", type=float, nargs="+", default=[0.2, 1.0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--max-voxels", type=int, default=8_000_000)
    add_save_option(ap)
    a = ap.parse_args()
    with saved_output(__file__, a.save, fenced=True):
        print(HEADER, flush=True)
        if a.only in (None, "paper"):
            for v in a.voxel:
                print(row("paper", 15.0, 0.2, v, a.count, a.seed, a.max_voxels), flush=True)
        if a.only in (None, "sweep"):
            for s in a.shrink:
                for p in a.infill:
                    print(row("sweep", p, s, a.sweep_voxel, a.sweep_count, a.seed, a.max_voxels), flush=True)
        if a.only in (None, "variants"):  # candidate physical differences, on the sweep's settings
            for variant in VARIANTS:
                for s in a.shrink:
                    print(row(variant, a.infill[-1], s, a.sweep_voxel, a.sweep_count, a.seed, a.max_voxels, variant),
                          flush=True)
        print("\npaper (rho 0.15): " + ", ".join(f"{k} {v:g}" for k, v in PAPER.items()) + " MPa")
        print("authors, transverse foam: E_y,z / E_s ~ 0.98 rho^1.1, E_x / E_s ~ 0.007-0.011")
        print("authors, isotropic foam:  E / E_s ~ 0.50 rho^1.24, nu 0.22-0.29")
        for rho in (0.09, 0.15, 0.18, 0.26, 0.34):
            print(f"  rho {rho:.2f}: 0.98 rho^1.1 = {0.98 * rho**1.1:.4f}, 0.50 rho^1.24 = {0.50 * rho**1.24:.4f}")


if __name__ == "__main__":
    main()
