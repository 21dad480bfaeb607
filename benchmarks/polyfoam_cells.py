"""The paper's Polyfoam cell (``cells/paper_polyfoam.toml``) at other sizes and voxel edges, as files.

Writes, per ``CELLS@VOXEL`` argument, ``<out>/polyfoam_<cells>_<voxel>_s<seed>.npz`` with the percolating
``phases`` (uint8), the box ``size`` [mm] and the solid's ``E`` [MPa], ``nu``: the voxel solver
benchmark's cases (``bench_voxel_solver.py --voxels``), e.g. the 8, 27, 64 and 125-cell cells at
0.3 mm and the 8-cell one at 0.2 mm. More seeds at the same density make a larger box, not smaller
cells (the cell size L is set by the density).

    python benchmarks/polyfoam_cells.py 8@0.3 27@0.3 64@0.3 125@0.3 8@0.2 --out .devdata [--seed 2]
"""

import argparse
import time
import tomllib
from pathlib import Path

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def write_cell(cells: int, voxel_mm: float, out: Path, seed: int = 1) -> Path:
    """Build the cell, keep its percolating solid, write it (temporary name, then rename)."""
    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.homogenize.percolation import percolating_solid

    data = tomllib.loads((ROOT / "cells" / "paper_polyfoam.toml").read_text())
    data["seeds"] = dict(data["seeds"], count=cells, seed=seed)
    data.update(voxel_mm=voxel_mm, max_voxels=40_000_000)
    cell = design_cell(parse_design(data, source="polyfoam_cells"))
    keep, _ = percolating_solid(cell.phases > 0)
    (material,) = cell.materials.values()
    path = out / f"polyfoam_{cells}_{voxel_mm:g}_s{seed}.npz"
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, phases=np.where(keep, cell.phases, 0).astype(np.uint8), size=np.asarray(cell.size, float),
                        E=float(material.E), nu=float(material.nu))
    tmp.replace(path)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="+", help="CELLS@VOXEL_MM, e.g. 64@0.3")
    ap.add_argument("--out", type=Path, default=Path("."))
    ap.add_argument("--seed", type=int, default=1, help="the seeds' RNG seed (the cell stage's is 1)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for case in args.cases:
        cells, _, vox = case.partition("@")
        t = time.perf_counter()
        path = write_cell(int(cells), float(vox or 0.3), args.out, args.seed)
        ph = np.load(path)["phases"]
        print(f"{path}: {ph.shape} voxels, solid {ph.mean():.4f}, {time.perf_counter() - t:.1f} s", flush=True)


if __name__ == "__main__":
    main()
