"""Both sheets of one print at one pose: the finite-strain voxel DNS's time against the issue's
target (issue 62: both sheets at one pose within 10 minutes at the default voxel size on 2 cores).

Each sheet of the print is held at its centre with its three horns turned by the same angle
(:mod:`bench_sheet_pose`'s pose), solved one after the other in this process. With ``--peer`` each
sheet is solved a second time with the rest multigrid only (the tangent's multigrid never rebuilt,
as before it existed), interleaved, and the table gives the ratio of the two in the same process.
With ``--processes`` the two sheets are solved at once, each in a process of its own with one
thread (:mod:`metasheet.robot.sheet_process`, as ``PrintedRobot(..., processes=True)`` solves them
at each of the rod's iterations; the same bits), after the in-process solves.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_pose_both.py --outputs outputs/printed-robot \
        --voxel 0.25 --deg 1 --save
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from bench_printed_robot import voxel_sheet  # noqa: E402
from bench_sheet_pose import horns_turned, solve  # noqa: E402
from dns_convergence import LABELS  # noqa: E402


def _one(gb, robot, sheet, k, deg, rtol, rebuild):
    """(wall s, CPU s, the solution, the grips' wrenches) of sheet k at ``deg``, the tangent's
    multigrid rebuilt (``rebuild``) or never."""
    from metasheet.fem.voxel import nonlinear

    kept = nonlinear.REBUILD_ITERATIONS
    nonlinear.REBUILD_ITERATIONS = kept if rebuild else 10**9
    try:
        c0 = time.process_time()
        W, wall, sol = solve(gb, robot, sheet, k, deg, rtol, None)
        return wall, time.process_time() - c0, sol, W
    finally:
        nonlinear.REBUILD_ITERATIONS = kept


def _processes(sheets, robot, deg, rtol):
    """(wall s of both sheets at once, set-up included; the solutions' GripWrenches) with each
    sheet in a process of its own."""
    from metasheet.robot.sheet_process import SheetProcess

    t0 = time.perf_counter()
    procs = [SheetProcess(sheet) for sheet in sheets]  # both bodies built at once
    try:
        for k, (p, sheet) in enumerate(zip(procs, sheets)):
            p.submit(*horns_turned(robot, sheet, k, deg), rtol=rtol)
        out = [p.result() for p in procs]
        return time.perf_counter() - t0, out
    finally:
        for p in procs:
            p.close()


def main() -> None:
    from metasheet.sheet.voxel_grips_nonlinear import GripBody

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (through printmap)")
    ap.add_argument("--voxel", type=float, default=0.25, help="voxel edge [mm]")
    ap.add_argument("--deg", type=float, default=1.0, help="every horn turned by [deg]")
    ap.add_argument("--rtol", type=float, default=1e-4, help="free residual over the reactions")
    ap.add_argument("--peer", action="store_true", help="also solve each sheet with the rest multigrid only")
    ap.add_argument("--processes", action="store_true",
                    help="also solve the two sheets at once, each in a process of its own")
    add_save_option(ap)
    args = ap.parse_args()
    rows, total, sheets = [], {True: 0.0, False: 0.0}, []
    for k, label in enumerate(LABELS):
        robot, sheet, seed = voxel_sheet(args.outputs, args.voxel, "seed", None, label)
        t0 = time.perf_counter()
        gb = GripBody(sheet.phases, sheet.size, sheet.law, bodies=sheet.bodies,
                      references=sheet.references - sheet.origin)
        setup = time.perf_counter() - t0
        runs = {}
        for rebuild in ((True, False) if args.peer else (True,)):
            runs[rebuild] = _one(gb, robot, sheet, k, args.deg, args.rtol, rebuild)
            total[rebuild] += setup + runs[rebuild][0]
            print(f"{label}: rebuild {rebuild}: {runs[rebuild][0]:.0f} s", file=sys.stderr, flush=True)
        rows.append((label, int((sheet.phases > 0).sum()), setup, runs))
        sheets.append(sheet)
        del gb
    apart = _processes(sheets, robot, args.deg, args.rtol) if args.processes else None
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}) of `{args.outputs}`, both sheets at {args.voxel:g} mm voxels, the "
              f"centre held and the horns turned by {args.deg:g} deg, rtol {args.rtol:g}, neo-Hookean walls; "
              "wall seconds on this machine, the stability probe included.\n")
        print("| sheet | solid voxels | set-up [s] | multigrid | Newton steps | CG iterations | solve [s] | CPU [s] "
              "| stable | largest wall strain |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for label, voxels, setup, runs in rows:
            for rebuild, (wall, cpu, sol, W) in runs.items():
                print(f"| {label} | {voxels:,} | {setup:.0f} | {'rebuilt on the tangent' if rebuild else 'rest only'} "
                      f"| {sol.newton} | {sum(sol.cg)} | {wall:.0f} | {cpu:.0f} | {sol.stable} | "
                      f"{float(np.nanmax(sol.strain)):.3f} |")
            if len(runs) == 2:
                a, b = runs[True][3], runs[False][3]
                print(f"| {label}: rest only / rebuilt | | | | | | {runs[False][0] / runs[True][0]:.2f} | "
                      f"{runs[False][1] / runs[True][1]:.2f} | | wrenches differ by "
                      f"{np.abs(a - b).max() / np.abs(b).max():.1e} of the largest |")
        print(f"\nBoth sheets at one pose, one after the other (set-up included): {total[True]:.0f} s "
              f"({total[True] / 60:.1f} min) with the tangent's multigrid"
              + (f", {total[False]:.0f} s ({total[False] / 60:.1f} min) with the rest multigrid only: "
                 f"{total[False] / total[True]:.2f} times." if args.peer else "."))
        if apart is not None:
            wall, got = apart
            same = all(np.array_equal(g.wrenches, runs[True][3]) for g, (_, _, _, runs) in zip(got, rows))
            print(f"Both sheets at once, each in a process of its own with one thread (set-up included): {wall:.0f} s "
                  f"({wall / 60:.1f} min), {total[True] / wall:.2f} times less than one after the other; the "
                  f"grips' wrenches {'the same bits' if same else 'DIFFERENT'} as in this process.")


if __name__ == "__main__":
    main()
