"""Benchmark: effective stiffness of an open-cell 15 % foam at n = 32, 48, 64 (96 with --large).

One table, same run: median wall seconds of homogenize_voxels per solver, the ratio
to the AMG run, dofs, iterations and peak memory (ru_maxrss of this process).

    python benchmarks/bench_homogenize.py [--large] [--repeat 1]
"""

import argparse
import os
import resource
import statistics
import time

import numpy as np

from metasheet.homogenize import homogenize_voxels
from metasheet.homogenize.samples import edge_foam
from metasheet.homogenize.solvers import HAVE_CHOLMOD
from metasheet.material import Isotropic


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--large", action="store_true", help="add n = 96")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    sizes = [32, 48, 64] + ([96] if args.large else [])
    print(f"cholmod={HAVE_CHOLMOD} OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', '-')} "
          f"load={os.getloadavg()[0]:.1f}")
    print(f"{'n':>4} {'solver':>8} {'dofs':>8} {'median s':>9} {'vs amg':>7} {'iters':>6} {'E_t MPa':>9} {'peak GB':>8}")
    mat = {1: Isotropic(12.0, 0.3)}
    for n in sizes:
        ph = edge_foam(n, 0.15, seeds=8, rng_seed=0)
        times = {}
        for solver in ("amg", "direct"):
            if solver == "direct" and (n > 48 or not HAVE_CHOLMOD):
                continue  # SuperLU / CHOLMOD fill-in is out of budget beyond this
            ts = []
            for _ in range(args.repeat):
                t = time.perf_counter()
                r = homogenize_voxels(ph, (1.0, 1.0, 1.0), mat, solver=solver, localise=False)
                ts.append(time.perf_counter() - t)
            times[solver] = statistics.median(ts)
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
            it = max(lc.iterations for lc in r.load_cases)
            print(f"{n:>4} {r.solver:>8} {r.n_dof:>8} {times[solver]:>9.2f} {times[solver] / times['amg']:>7.2f} "
                  f"{it:>6} {r.fit.material.E_t:>9.4f} {peak:>8.2f}", flush=True)


if __name__ == "__main__":
    main()
