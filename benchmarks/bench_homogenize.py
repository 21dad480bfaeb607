"""Benchmark: effective stiffness of the open-cell 15 % foam (cells/iso_foam.toml, 64 seeds).

One table, same run. Every row runs in a fresh subprocess so that its peak memory
(ru_maxrss) is its own; wall seconds are medians over ``--repeat`` runs inside it.

- "foam" rows: iso_foam at n = 48, 64 (96 with --large), with each fast direct back-end present
  (CHOLMOD when scikit-sparse is importable, PARDISO when pypardiso is) and with the iterative
  fallback ("amg": smoothed-aggregation AMG + CG), setup (factorisation / hierarchy) and solve
  (six load cases) apart.
- "sfepy" rows (--sfepy N, default 40, the coarsest grid where the foam is feasible): the
  same foam with its last voxel slices copied from the first ones (so SfePy's non-periodic
  mesh + periodic conditions is exactly our mesh), timed with our solvers and with SfePy's homogenisation (tests/sfepy_reference.py)
  using CHOLMOD (ls.cholesky) and its default direct solver; "vs ours" = SfePy / ours.

    python benchmarks/bench_homogenize.py [--large] [--repeat 3] [--sfepy 32] [--sizes 48 64]
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def foam(n: int, matched: bool = False):
    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.homogenize.percolation import percolating_solid

    cell = design_cell(parse_design(tomllib.loads((ROOT / "cells" / "iso_foam.toml").read_text()),
                                    overrides={"resolution": n}))
    ph = np.asarray(cell.phases, np.int64)
    if matched:
        ph[-1], ph[:, -1], ph[:, :, -1] = ph[0], ph[:, 0], ph[:, :, 0]
        keep, _ = percolating_solid(ph > 0)
        ph = keep.astype(np.int64)
    return ph, cell.size, cell.materials


def one(n: int, solver: str, repeat: int, matched: bool) -> dict:
    """Child process: time homogenize_voxels (or SfePy) on one case, print JSON."""
    from metasheet.homogenize import homogenize_voxels

    ph, size, mats = foam(n, matched)
    rows = []
    for _ in range(repeat):
        t = time.perf_counter()
        if solver.startswith("sfepy"):
            from sfepy_reference import sfepy_stiffness

            ls = "ls.cholesky" if solver == "sfepy-cholmod" else "ls.auto_direct"
            C, info = sfepy_stiffness(ph, size, {k: m.stiffness() for k, m in mats.items()}, ls=ls)
            rows.append({"s": info["seconds"], "wall": info["wall"], "setup": float("nan"), "solve": float("nan"),
                         "solver": f"sfepy:{info['solver']}", "dofs": info["n_dof"], "iters": 0, "C11": C[0, 0]})
        else:
            r = homogenize_voxels(ph, size, mats, solver=solver, localise=False)
            rows.append({"s": time.perf_counter() - t, "setup": r.timings["setup"], "solve": r.timings["solve"],
                         "solver": r.solver, "dofs": r.n_dof, "iters": max(lc.iterations for lc in r.load_cases),
                         "C11": r.C[0, 0]})
    out = {k: statistics.median(x[k] for x in rows) if isinstance(rows[0][k], float) else rows[0][k]
           for k in rows[0]}
    # SfePy runs in a grandchild process: its peak is in RUSAGE_CHILDREN
    who = (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
    out["peak_gb"] = max(resource.getrusage(w).ru_maxrss for w in who) / 2**20
    return out


def blas_info() -> str:
    try:
        from threadpoolctl import threadpool_info

        return ", ".join(f"{i['internal_api']}({i['num_threads']} thr)" for i in threadpool_info()
                         if i["user_api"] == "blas")
    except ImportError:
        return "threadpoolctl not installed"


def run_child(n, solver, repeat, matched, timeout):
    cmd = [sys.executable, __file__, "--one", str(n), solver, "--repeat", str(repeat)]
    cmd += ["--matched"] if matched else []
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout {timeout:.0f} s"}
    if p.returncode != 0:
        return {"error": p.stderr.strip().splitlines()[-1][:60]}
    return json.loads(p.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="*", default=[48, 64])
    ap.add_argument("--large", action="store_true", help="add n = 96 (CHOLMOD, or AMG without it)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--sfepy", type=int, default=40, help="resolution of the SfePy comparison (0: skip)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="per row [s]")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--matched", action="store_true", help=argparse.SUPPRESS)
    add_save_option(ap)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(int(args.one[0]), args.one[1], args.repeat, args.matched)))
        return
    from metasheet.fem.solvers import HAVE_CHOLMOD, available
    from sfepy_reference import sfepy_available

    with saved_output(__file__, args.save, fenced=True):
        print(f"cholmod={HAVE_CHOLMOD} pardiso={available('pardiso')} BLAS: {blas_info()} OPENBLAS_NUM_THREADS="
              f"{os.environ.get('OPENBLAS_NUM_THREADS', '-')} cores={os.cpu_count()} load={os.getloadavg()[0]:.1f} "
              f"repeat={args.repeat}")
        # every fast direct back-end present (SuperLU: 119 s / 6.5 GB at 105k dofs, not a contender)
        direct = [name for name in ("cholmod", "pardiso") if available(name)]
        cases = [("foam", n, s, False) for n in args.sizes for s in direct + ["amg"]]
        if args.large:
            cases.append(("foam", 96, direct[0] if direct else "amg", False))
        if args.sfepy and sfepy_available():
            cases += [("sfepy", args.sfepy, s, True) for s in direct + ["amg"]]
            theirs = (["sfepy-cholmod"] if HAVE_CHOLMOD else []) + ["sfepy-default"]
            cases += [("sfepy", args.sfepy, s, True) for s in theirs]
        print(f"{'case':>6} {'n':>4} {'solver':>22} {'dofs':>8} {'median s':>9} {'setup s':>8} {'solve s':>8} "
              f"{'iters':>6} {'C11 MPa':>9} {'peak GB':>8} {'vs ours':>8}")
        ours: dict = {}
        for case, n, solver, matched in cases:
            r = run_child(n, solver, args.repeat, matched, args.timeout)
            if "error" in r:
                print(f"{case:>6} {n:>4} {solver:>22} failed: {r['error']}", flush=True)
                continue
            key = (case, n)
            if not solver.startswith("sfepy"):
                ours[key] = min(ours.get(key, np.inf), r["s"])  # the faster of our routes
            ratio = r["s"] / ours[key] if solver.startswith("sfepy") and key in ours else float("nan")
            print(f"{case:>6} {n:>4} {r['solver']:>22} {r['dofs']:>8} {r['s']:>9.2f} {r['setup']:>8.2f} "
                  f"{r['solve']:>8.2f} {r['iters']:>6} {r['C11']:>9.5f} {r['peak_gb']:>8.2f} {ratio:>8.2f}", flush=True)
        print("sfepy 'median s' = its homogenisation app (assembly, factorisation, solves), imports excluded; "
              "'vs ours' = that / our fastest route on the identical mesh")


if __name__ == "__main__":
    main()
