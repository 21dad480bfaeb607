"""The sheet-scale model's map of where the bulk continuum holds (issue 63, a first map).

For IceSL Polyfoams around the paper's (`cells/paper_polyfoam.toml`: infill and shrink varied,
the paper's bead, 0.3 mm voxels), each cell is built, homogenised in bulk, and cut into sheets of
several thicknesses (:mod:`metasheet.homogenize.plate_slabs`): the sheet's diagonal stiffnesses
over the bulk plate's, against the number of cell heights through the sheet. Not yet the printed
sheets' DNS (the issue's map): the plate model, which on the paper's design brought the continuum
to 0.59-1.00 of three prints (docs/plate.md).

    python benchmarks/plate_map.py [--infill 15 30 45] [--shrink 0.2 0.5 1.0] [--thickness 2.5 5 10]
                                   [--slabs 6] [--workers 2]

Prints one row per design and thickness: cell size, cell heights through the sheet, the mean
ratio of each diagonal entry and the furthest one from 1, and whether all six are within 10 %.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import tomllib  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def one_design(job):
    """(infill, shrink, thicknesses, slabs) -> rows (dicts) for each thickness."""
    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.errors import InfeasibleError
    from metasheet.homogenize import homogenize_voxels
    from metasheet.homogenize.plate_slabs import DIAGONAL, slab_study

    infill, shrink, thicknesses, slabs = job
    data = tomllib.loads((ROOT / "cells" / "paper_polyfoam.toml").read_text())
    t0 = time.perf_counter()
    cell = design_cell(parse_design(data, overrides={"infill_percentage": infill, "kgon_x_shrink": shrink}))
    t1 = time.perf_counter()
    C = homogenize_voxels(cell.phases, cell.size, cell.materials, localise=False).C
    t2 = time.perf_counter()
    n_cells = int(data["seeds"]["count"])
    height = float(cell.size[2]) / round(n_cells ** (1 / 3))  # the box holds about n^(1/3) cells along z
    rows = []
    for t in thicknesses:
        try:
            st = slab_study(cell.phases, cell.size, cell.materials, t, C, slabs=slabs)
        except InfeasibleError as exc:  # a slab that falls apart is a result of the map
            rows.append({"infill": infill, "shrink": shrink, "t": t, "size": cell.size.tolist(), "height": height,
                         "error": str(exc).split(":")[-1].strip()[:60]})
            continue
        r = st.to_dict()["ratio_to_bulk"]
        means = {n: r[n]["mean"] for n in DIAGONAL}
        worst = max(means, key=lambda n: abs(np.log(means[n])))
        rows.append({"infill": infill, "shrink": shrink, "t": st.thickness, "size": cell.size.tolist(),
                     "height": height, "through": st.thickness / height, "means": means, "worst": worst,
                     "gm": r["geometric_mean"]["mean"], "within10": bool(abs(np.log(means[worst])) <= np.log(1.1)),
                     "build_s": t1 - t0, "bulk_s": t2 - t1})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--infill", type=float, nargs="+", default=[15.0, 30.0, 45.0])
    ap.add_argument("--shrink", type=float, nargs="+", default=[0.2, 0.5, 1.0])
    ap.add_argument("--thickness", type=float, nargs="+", default=[2.5, 5.0, 10.0])
    ap.add_argument("--slabs", type=int, default=6)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    jobs = [(i, s, a.thickness, a.slabs) for i in a.infill for s in a.shrink]
    print("| infill [%] | shrink | cell [mm] | t [mm] | cell heights through t | A_11 | A_22 | A_66 | D_11 | D_22 | "
          "D_66 | furthest | within 10 % |")
    print("|---" * 13 + "|")
    with ProcessPoolExecutor(a.workers) as pool:
        for rows in pool.map(one_design, jobs):
            for r in rows:
                cell = " x ".join(f"{v:.1f}" for v in r["size"])
                if "error" in r:
                    print(f"| {r['infill']:g} | {r['shrink']:g} | {cell} | {r['t']:.2f} | - | " + "- | " * 6
                          + f"{r['error']} | no |", flush=True)
                    continue
                m = r["means"]
                print(f"| {r['infill']:g} | {r['shrink']:g} | {cell} | {r['t']:.2f} | {r['through']:.2f} | "
                      + " | ".join(f"{m[n]:.2f}" for n in m) + f" | {r['worst']} | {'yes' if r['within10'] else 'no'} |",
                      flush=True)


if __name__ == "__main__":
    main()
