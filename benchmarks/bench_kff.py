"""The robot's free block K_ff: SuperLU (what the robot uses) against MKL PARDISO (pip).

Run (the pipeline's robot outputs must exist, e.g. ``metasheet run pipelines/paper.toml``):

    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/bench_kff.py [pipelines/paper.toml] [--out ROOT]

Takes the K_ff of the pipeline's full foam robot at its rest equilibrium (the matrix every
fresh linearisation factorises: structurally symmetric, values nearly symmetric), then
factorises and solves it with SuperLU in symmetric mode (:func:`metasheet.fem.solvers.superlu`)
and with PARDISO as a structurally symmetric (mtype 1) and a general (mtype 11) real matrix,
a refactorisation of the same pattern included (PARDISO may reuse its analysis there).
Solves: 13 right-hand sides (the Schur complement's rigid columns and the residual) and one
(a chord step). Prints medians of ``--repeats`` runs, the residuals and the ratios to SuperLU.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def capture_kff(pipeline: str, out: str | None):
    """K_ff (csr) of the pipeline's foam robot at its rest equilibrium."""
    from metasheet.fem import factor
    from metasheet.robot.inverse import InverseController
    from metasheet.serve.loading import find_outputs, load_robot

    seen = []
    orig = factor.SparseSolver.factorize

    def spy(self, A):
        seen.append(A.copy())
        return orig(self, A)

    factor.SparseSolver.factorize = spy
    try:
        robot, info = load_robot(find_outputs(pipeline, out), "full", "foam")
        InverseController(robot).refresh()
    finally:
        factor.SparseSolver.factorize = orig
    A = seen[-1].tocsr()
    A.sort_indices()
    return A, info.description


def median_time(fn, repeats: int):
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pipeline", nargs="?", default=str(ROOT / "pipelines" / "paper.toml"))
    ap.add_argument("--out", default=None, help="output root the pipeline ran with")
    ap.add_argument("--repeats", type=int, default=5)
    add_save_option(ap)
    args = ap.parse_args()

    import pypardiso

    from metasheet.fem.solvers import superlu

    A, description = capture_kff(args.pipeline, args.out)
    n = A.shape[0]
    B = np.random.default_rng(0).standard_normal((n, 13))
    A2 = A.copy()
    A2.data *= 1.0001  # same pattern, new values: a refactorisation
    rows = {}
    tf, lu = median_time(lambda: superlu(A, symmetric_mode=True), args.repeats)
    t13, x = median_time(lambda: lu.solve(B), args.repeats)
    t1, _ = median_time(lambda: lu.solve(B[:, 0].copy()), args.repeats)
    rows["superlu (symmetric mode)"] = (tf, tf, t13, t1, np.linalg.norm(A @ x - B) / np.linalg.norm(B))
    for mtype, name in ((1, "pardiso mtype 1"), (11, "pardiso mtype 11")):
        s = pypardiso.PyPardisoSolver(mtype=mtype)
        tf, _ = median_time(lambda: s.factorize(A), args.repeats)
        tr, _ = median_time(lambda: s.factorize(A2), args.repeats)
        t13, x = median_time(lambda: s.solve(A2, B), args.repeats)
        t1, _ = median_time(lambda: s.solve(A2, B[:, 0].copy()), args.repeats)
        rows[name] = (tf, tr, t13, t1, np.linalg.norm(A2 @ x - B) / np.linalg.norm(B))
        s.free_memory(everything=True)
    with saved_output(__file__, args.save):
        print(f"\nK_ff {n} x {n}, {A.nnz} non-zeros, of {description}")
        print(f"medians of {args.repeats}\n")
        print("| solver | factor [s] | refactor [s] | solve, 13 rhs [ms] | solve, 1 rhs [ms] | residual | factor / superlu | solve 13 / superlu |")
        print("|---|---|---|---|---|---|---|---|")
        base = rows["superlu (symmetric mode)"]
        for name, (tf, tr, t13, t1, res) in rows.items():
            print(f"| {name} | {tf:.3f} | {tr:.3f} | {1e3 * t13:.1f} | {1e3 * t1:.1f} | {res:.1e} | "
                  f"{tf / base[0]:.2f} | {t13 / base[2]:.2f} |")


if __name__ == "__main__":
    main()
