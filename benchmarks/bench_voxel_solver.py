"""Benchmark: matrix-free multigrid CG (solver "voxel") against PARDISO and AMG-CG on voxel foams.

One table, same run. Every row runs in a fresh subprocess so that its peak memory (ru_maxrss)
is its own; wall seconds are medians over ``--repeat`` runs inside it. The cell is the open-cell
15 % foam of ``cells/iso_foam.toml`` at resolution n, tiled ``--tile`` times per direction (more
cells at the same voxel size: the iteration count must stay flat). Every route gets the same
percolating voxels and rtol; "C err" is the relative Frobenius distance of C* to PARDISO's.

    python benchmarks/bench_voxel_solver.py --quick            # n = 40, one tile: a smoke test
    python benchmarks/bench_voxel_solver.py --sizes 48 64 --tile 1 2 --repeat 3 [--save]
    python benchmarks/bench_voxel_solver.py --solvers pardiso voxel voxel:1   # voxel on 1 numba thread
    python benchmarks/bench_voxel_solver.py --solvers pardiso voxel:1 voxel-trilinear:1   # both coarsenings
    python benchmarks/bench_voxel_solver.py --sizes 40 --voxels out/paper/cell/voxels.npz  # + a cell stage's voxels
    python benchmarks/bench_voxel_solver.py --sizes --voxels a.npz b.npz --solvers voxel voxel-gpu  # GPU beside CPU

``--voxels`` adds one case per file, listed as n = 0 with the file's name: the phases and size of
a cell stage's ``voxels.npz`` and the materials of the ``cell.json`` beside it (the paper's
Polyfoam cell: ``cells/paper_polyfoam.toml``), or a file holding ``phases``, ``size``, ``E`` and
``nu`` itself (``benchmarks/polyfoam_cells.py`` writes the paper's cell at other sizes), one tile.

"voxel-gpu" runs the same split multigrid CG on a CUDA GPU through CuPy
(:func:`metasheet.homogenize.voxel_periodic_gpu.periodic_stiffness_device`; set-up on the host), and adds
the GPU memory pool's high-water mark ("gpu GB"); "voxel-numpy" runs that array code on the host
(a check of the script, not a speed). The ratios and "C err" are against the first solver of
``--solvers`` that ran on the case (PARDISO by default).

"voxel" runs the default coarsening ("split": face-split coarse levels with K-cycles,
:mod:`metasheet.fem.voxel.split_hierarchy`); "voxel-split" and "voxel-trilinear" name the coarsening
(the trilinear hierarchy was the default before; 275 iterations on the paper cell); ":T" works on
them too.

"voxel:T" runs the voxel solver with T numba threads (NUMBA_NUM_THREADS in its child; plain
"voxel": numba's default, one per core). The six load cases run in lockstep, one operator
sweep for all six; its bits do not depend on T.
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

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]


def foam(n: int, tile: int):
    """(phases, size [mm], materials) of the iso foam at resolution n, tiled, percolating solid only."""
    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.homogenize.percolation import percolating_solid

    cell = design_cell(parse_design(tomllib.loads((ROOT / "cells" / "iso_foam.toml").read_text()),
                                    overrides={"resolution": n}))
    ph = np.tile(np.asarray(cell.phases, np.int64), (tile, tile, tile))
    keep, _ = percolating_solid(ph > 0)
    return np.where(keep, ph, 0), np.asarray(cell.size, float) * tile, cell.materials


def stage_voxels(path: str):
    """(phases, size [mm], materials) of a cell stage's voxels.npz (+ cell.json), percolating solid only."""
    from metasheet.homogenize.percolation import percolating_solid
    from metasheet.mechanics.material import Isotropic

    d = np.load(path)
    if "E" in d:  # a self-contained file: one solid phase
        mats = {1: Isotropic(E=float(d["E"]), nu=float(d["nu"]))}
    else:
        meta = json.loads((Path(path).parent / "cell.json").read_text())
        mats = {int(k): Isotropic(E=float(m["E"]), nu=float(m["nu"])) for k, m in meta["materials"].items()}
    ph = np.asarray(d["phases"], np.int64)
    keep, _ = percolating_solid(ph > 0)
    return np.where(keep, ph, 0), np.asarray(d["size"], float), mats


def one(n: int, tile: int, solver: str, repeat: int, rtol: float, voxels: str | None = None) -> dict:
    """Child process: homogenise one case with one solver, print JSON."""
    from metasheet.homogenize.voxel_periodic import periodic_stiffness
    from metasheet.homogenize.voxel_periodic_gpu import periodic_stiffness_device
    from metasheet.homogenize import homogenize_voxels

    ph, size, mats = stage_voxels(voxels) if n == 0 else foam(n, tile)
    rows = []
    for _ in range(repeat):
        t = time.perf_counter()
        gpu = 0.0
        if solver in ("voxel-gpu", "voxel-numpy"):
            r = periodic_stiffness_device(ph, size, {k: m.stiffness() for k, m in mats.items()}, rtol=rtol,
                                          device="cupy" if solver == "voxel-gpu" else "numpy")
            setup, solve, dofs, iters, C = r.setup_seconds, r.solve_seconds, r.n_dof, max(r.iterations), r.C
            gpu = r.device_bytes / 2**30
        elif solver.startswith("voxel"):
            coarsening = solver.partition("-")[2]
            r = periodic_stiffness(ph, size, {k: m.stiffness() for k, m in mats.items()}, rtol=rtol,
                                   **({"coarsening": coarsening} if coarsening else {}))
            setup, solve, dofs, iters, C = r.setup_seconds, r.solve_seconds, r.n_dof, max(r.iterations), r.C
        else:
            r = homogenize_voxels(ph, size, mats, solver=solver, rtol=rtol, localise=False)
            setup, solve, dofs, C = r.timings["setup"], r.timings["solve"], r.n_dof, r.C
            iters = max(lc.iterations for lc in r.load_cases)
        rows.append({"s": time.perf_counter() - t, "setup": setup, "solve": solve, "dofs": dofs, "iters": iters,
                     "gpu_gb": gpu, "C": C.tolist()})
    out = {k: statistics.median(x[k] for x in rows) if isinstance(rows[0][k], float) else rows[0][k]
           for k in rows[0]}
    out["peak_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    out["ti"] = ti_constants(np.array(out["C"]), axis=(1.0, 0.0, 0.0) if n == 0 else None)
    return out


def ti_constants(C: np.ndarray, axis) -> list[float]:
    """(E_t, E_l, nu_t, nu_tl, mu_l) of the transverse-isotropic fit of C (axis None: searched)."""
    from metasheet.mechanics.material import TransverseIsotropic

    m = TransverseIsotropic.fit(C, axis=axis).material
    return [m.E_t, m.E_l, m.nu_t, m.nu_tl, m.mu_l]


def run_child(n, tile, solver, repeat, rtol, timeout, voxels=None):
    solver, _, threads = solver.partition(":")
    env = dict(os.environ, **({"NUMBA_NUM_THREADS": threads} if threads else {}))
    cmd = [sys.executable, __file__, "--one", str(n), str(tile), solver, "--repeat", str(repeat), "--rtol", str(rtol)]
    cmd += ["--voxels", voxels] if voxels else []
    try:
        p = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout {timeout:.0f} s"}
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["?"])[-1][:70]}
    return json.loads(p.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="*", default=[48, 64], help="resolutions n of one cell")
    ap.add_argument("--tile", type=int, nargs="*", default=[1], help="cells per direction (1, 2, 3...)")
    ap.add_argument("--solvers", nargs="*", default=["pardiso", "voxel", "amg"])
    ap.add_argument("--quick", action="store_true", help="n = 40 (the coarsest feasible), one tile, one repeat: checks that it runs")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--rtol", type=float, default=1e-8)
    ap.add_argument("--timeout", type=float, default=1800.0, help="per row [s]")
    ap.add_argument("--voxels", nargs="*", default=[], help="cell files: a cell stage's voxels.npz (cell.json "
                    "beside it) or an npz with phases, size, E, nu; one case each (n = 0)")
    ap.add_argument("--constants", action="store_true", help="print each row's transverse-isotropic constants "
                    "(axis x for --voxels cases, the Polyfoam's soft axis; searched for the iso foam)")
    ap.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    add_save_option(ap)
    args = ap.parse_args()
    if args.one:
        n, tile, solver = args.one
        print(json.dumps(one(int(n), int(tile), solver, args.repeat, args.rtol, args.voxels[0] if args.voxels else None)))
        return
    if args.quick:
        args.sizes, args.tile, args.repeat = [40], [1], 1
    if 0 in args.sizes:
        ap.error("size 0 is a --voxels case: give --voxels FILE")
    cases = [(n, tile, None) for n in args.sizes for tile in args.tile] + [(0, 1, v) for v in args.voxels]
    from metasheet.fem.solvers import available

    solvers = [s for s in args.solvers if s != "pardiso" or available("pardiso")]
    with saved_output(__file__, args.save, fenced=True):
        print(f"cores={os.cpu_count()} load={os.getloadavg()[0]:.1f} repeat={args.repeat} rtol={args.rtol:g} "
              f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', '-')}")
        print(f"{'n':>4} {'tile':>4} {'solver':>13} {'dofs':>9} {'iters':>6} {'setup s':>8} {'solve s':>8} "
              f"{'median s':>9} {'peak GB':>8} {'gpu GB':>7} {'t/ref':>6} {'GB/ref':>6} {'C err':>9}")
        for n, tile, voxels in cases:
            ref = None
            if voxels:
                print(f"   0: {Path(voxels).name}")
            for solver in solvers:
                r = run_child(n, tile, solver, args.repeat, args.rtol, args.timeout, voxels)
                if "error" in r:
                    print(f"{n:>4} {tile:>4} {solver:>13} failed: {r['error']}", flush=True)
                    continue
                ref = ref or r
                C, Cref = np.array(r["C"]), np.array(ref["C"])
                err = np.linalg.norm(C - Cref) / np.linalg.norm(Cref)
                print(f"{n:>4} {tile:>4} {solver:>13} {r['dofs']:>9} {r['iters']:>6} {r['setup']:>8.2f} "
                      f"{r['solve']:>8.2f} {r['s']:>9.2f} {r['peak_gb']:>8.2f} {r['gpu_gb']:>7.2f} "
                      f"{r['s'] / ref['s']:>6.2f} {r['peak_gb'] / ref['peak_gb']:>6.2f} {err:>9.1e}", flush=True)
                if args.constants:
                    print("        E_t {:.4f}  E_l {:.5f}  nu_t {:.4f}  nu_tl {:.4f}  mu_l {:.5f} MPa".format(*r["ti"]))
        print("t/ref, GB/ref and C err: against the first solver that ran on the case (the first of --solvers); "
              "peak GB: host")


if __name__ == "__main__":
    main()
