"""The paper's foam as sheets of several thicknesses: slabs of the cell homogenised as plates
(free faces) against the bulk continuum of the same cell (issue 63's first measurement).

    python benchmarks/plate_slabs.py OUT/paper [--thickness 2.5 5 10 20] [--slabs 8]

OUT/paper is a paper pipeline's output folder (its cell and homogenize stages). Prints, per
thickness, the cells through the thickness and each diagonal entry's ratio to the bulk plate
(mean +- 95 % half-width over the slabs), and the wall time per slab (median).
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
    a = ap.parse_args()

    from metasheet.homogenize.plate_slabs import DIAGONAL, slab_study
    from metasheet.pipeline.artefacts import read_cell
    from metasheet.pipeline.stages.homogenize import materials_from_json

    cell = read_cell(a.run / "cell")
    C = np.array(json.loads((a.run / "homogenize" / "constants.json").read_text())["C"])
    materials = materials_from_json(cell.info["materials"])
    n_cells = int(cell.info["design"]["seeds"]["count"])
    print(f"cell {cell.info.get('name')}: {' x '.join(f'{s:.1f}' for s in cell.size)} mm, {n_cells} cells, "
          f"{cell.phases.shape} voxels; bulk C from {a.run / 'homogenize'}")
    print("| t [mm] | cell heights through t | " + " | ".join(DIAGONAL) + " | geometric mean | s per slab |")
    print("|---" * (len(DIAGONAL) + 4) + "|")
    for t in a.thickness:
        times = []
        t0 = time.perf_counter()

        def tick(done, total):
            times.append(time.perf_counter() - t0 - sum(times))

        study = slab_study(cell.phases, cell.size, materials, t, C, slabs=a.slabs, progress=tick)
        d = study.to_dict()["ratio_to_bulk"]
        cells = study.thickness / (cell.size[2] / round(n_cells ** (1 / 3)))
        row = [f"{d[n]['mean']:.3f} +- {d[n]['halfwidth']:.3f}" for n in (*DIAGONAL, "geometric_mean")]
        print(f"| {study.thickness:.2f} | {cells:.2f} | " + " | ".join(row) + f" | {np.median(times):.1f} |", flush=True)


if __name__ == "__main__":
    main()
