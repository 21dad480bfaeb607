"""The reduced model's tangent evaluation in single against double precision (issue 16).

Run on a pipeline's robot and its reduce stage's basis (the robot and reduce stages must have
run, e.g. ``metasheet run pipelines/paper.toml``):

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_reduced_tangent.py [pipelines/paper.toml] [--out ROOT]

Times :meth:`~metasheet.rom.model.ReducedRobot.evaluate` with the tangent, on the same
states, with ``tangent_dtype`` float64 and float32 alternating in one process (medians of
``--repeats``), and compares what the precision changes: the equilibria (the forces are double
in both) and the Jacobians there (relative Frobenius), at rest and at ``--poses`` random motor
angles within the basis's box.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.robot.kinematics import kinematics

from _results import add_save_option, saved_output


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pipeline", nargs="?", default="pipelines/paper.toml")
    ap.add_argument("--out", default=None)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--poses", type=int, default=4)
    add_save_option(ap)
    args = ap.parse_args()
    from metasheet.serve.loading import find_outputs, load_robot

    red, _ = load_robot(find_outputs(args.pipeline, args.out), "reduced")
    rng = np.random.default_rng(0)
    lo, hi = red.basis.box_lo, red.basis.box_hi
    angles = [red.coupling.rest_angles] + [rng.uniform(lo, hi) for _ in range(args.poses)]
    rows, times = [], {np.float64: [], np.float32: []}
    for q in angles:
        out = {}
        for dtype in (np.float64, np.float32):
            red.tangent_dtype = np.dtype(dtype)
            lz = red.linearizer()
            st = solve_equilibrium(red, q, linearizer=lz).state
            for _ in range(args.repeats):
                t = time.perf_counter()
                red.evaluate(st, tangent=True)
                times[dtype].append(time.perf_counter() - t)
            out[dtype] = (st, kinematics(lz.linearize(st)).J)
        (s64, J64), (s32, J32) = out[np.float64], out[np.float32]
        rows.append((np.degrees(q - red.coupling.rest_angles).round(1), float(np.abs(s32.pose - s64.pose).max()),
                     float(np.linalg.norm(J32 - J64) / np.linalg.norm(J64))))
    m64, m32 = (1e3 * float(np.median(times[d])) for d in (np.float64, np.float32))
    with saved_output(__file__, args.save):
        print(f"reduced model: k {red.k}, {len(red.basis.elements)} sampled elements, {3 * len(red.sub_nodes)} sub-mesh dofs")
        print("\n| tangent_dtype | evaluate with tangent, median [ms] | ratio to float64 |\n|---|---|---|")
        print(f"| float64 | {m64:.1f} | 1.00 |\n| float32 | {m32:.1f} | {m32 / m64:.2f} |")
        print("\n| motors from rest [deg] | equilibrium pose, largest difference | Jacobian, relative difference |\n|---|---|---|")
        for d, dp, dj in rows:
            print(f"| {d.tolist()} | {dp:.1e} | {dj:.1e} |")


if __name__ == "__main__":
    main()
