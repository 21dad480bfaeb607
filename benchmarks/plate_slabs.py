"""The paper's foam as sheets of several thicknesses: slabs of the cell homogenised as plates
(free faces) against the bulk continuum of the same cell (issue 63's first measurement).

    python benchmarks/plate_slabs.py OUT/paper [--thickness 2.5 5 10 20] [--slabs 8] [--shear]

OUT/paper is a paper pipeline's output folder (its cell and homogenize stages). Prints, per
thickness, the cells through the thickness and each diagonal entry's ratio to the bulk plate
(mean +- 95 % half-width over the slabs), with ``--shear`` the transverse shear's too (against
5/6 G t of the bulk), and the wall time per slab (median).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a pipeline's output folder holding cell/ and homogenize/")
    ap.add_argument("--thickness", type=float, nargs="+", default=[2.5, 5.0, 10.0, 20.0], help="[mm]")
    ap.add_argument("--slabs", type=int, default=8)
    ap.add_argument("--shear", action="store_true", help="also the transverse-shear stiffness (two more solves)")
    a = ap.parse_args()

    from metasheet.homogenize.plate_slabs import DIAGONAL, SHEAR_DIAGONAL, slab_study
    from metasheet.pipeline.artefacts import read_cell
    from metasheet.pipeline.stages.homogenize import materials_from_json

    cell = read_cell(a.run / "cell")
    C = np.array(json.loads((a.run / "homogenize" / "constants.json").read_text())["C"])
    materials = materials_from_json(cell.info["materials"])
    n_cells = int(cell.info["design"]["seeds"]["count"])
    print(f"cell {cell.info.get('name')}: {' x '.join(f'{s:.1f}' for s in cell.size)} mm, {n_cells} cells, "
          f"{cell.phases.shape} voxels; bulk C from {a.run / 'homogenize'}")
    shear_names = SHEAR_DIAGONAL if a.shear else ()
    share = " | Kirchhoff share of the 2nd-order energy (max xz / yz) | H's normalisation spread" if a.shear else ""
    print("| t [mm] | cell heights through t | " + " | ".join((*DIAGONAL, *shear_names))
          + f" | geometric mean{share} | s per slab |")
    print("|---" * (len(DIAGONAL) + len(shear_names) + 4 + 2 * a.shear) + "|")
    for t in a.thickness:
        times = []
        t0 = time.perf_counter()

        def tick(done, total):
            times.append(time.perf_counter() - t0 - sum(times))

        study = slab_study(cell.phases, cell.size, materials, t, C, slabs=a.slabs, shear=a.shear, progress=tick)
        doc = study.to_dict()
        d = {**doc["ratio_to_bulk"], **(doc["shear"]["ratio_to_bulk"] if a.shear else {})}
        cells = study.thickness / (cell.size[2] / round(n_cells ** (1 / 3)))
        row = [f"{d[n]['mean']:.3f} +- {d[n]['halfwidth']:.3f}" for n in (*DIAGONAL, *shear_names, "geometric_mean")]
        if a.shear:
            row.append(" / ".join(f"{v:.2f}" for v in doc["shear"]["kirchhoff_share_max"]))
            row.append(f"{doc['shear']['normalisation_spread_max']:.3f}")
        print(f"| {study.thickness:.2f} | {cells:.2f} | " + " | ".join(row) + f" | {np.median(times):.1f} |", flush=True)


if __name__ == "__main__":
    main()
