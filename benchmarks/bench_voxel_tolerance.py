"""Benchmark: what the corrector tolerance costs and buys on a voxel cell (the voxel solver).

C* is computed in energy form, so its error is ``E^T K E / |Y|`` for a corrector error E:
second order in the residual and one-sided (tests/test_voxel_split_solver.py). This script
solves one cell at each tolerance of ``--rtol`` (the first is the reference) and prints, per
tolerance, the CG iterations (the largest of the six load cases), the solve time, the relative
Frobenius distance of C* to the reference's and the largest relative change of the five
transverse-isotropic constants (fitted about z). It chose the homogenise stage's default
(docs/voxel.md, "The corrector tolerance").

    python benchmarks/bench_voxel_tolerance.py .devdata/polyfoam_27_0.3_s1.npz --rtol 1e-8 1e-4 1e-5
"""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_voxel_solver import stage_voxels

from metasheet.homogenize.voxel_periodic import periodic_stiffness
from metasheet.mechanics.material import TransverseIsotropic


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("voxels", help="a cell stage's voxels.npz, or a file of benchmarks/polyfoam_cells.py")
    ap.add_argument("--rtol", type=float, nargs="+", default=[1e-10, 1e-8, 1e-6, 1e-5, 1e-4],
                    help="tolerances; the first is the reference")
    a = ap.parse_args()
    ph, size, mats = stage_voxels(a.voxels)
    st = {k: m.stiffness() for k, m in mats.items()}
    print(f"{Path(a.voxels).name}: {int((ph > 0).sum())} solid voxels; reference rtol {a.rtol[0]:g}")
    print(f"{'rtol':>8} {'iters':>6} {'solve s':>8} {'C* err':>9} {'constants err':>14}")
    ref = None
    for rtol in a.rtol:
        r = periodic_stiffness(ph, size, st, rtol=rtol)
        m = np.array(TransverseIsotropic.fit(r.C, axis=[0, 0, 1]).material.as_tuple())
        if ref is None:
            ref, mref = r.C, m
        err = np.linalg.norm(r.C - ref) / np.linalg.norm(ref)
        print(f"{rtol:8.0e} {max(r.iterations):6d} {r.solve_seconds:8.1f} {err:9.1e} "
              f"{float(np.max(np.abs(m - mref) / np.abs(mref))):14.1e}", flush=True)


if __name__ == "__main__":
    main()
