"""The printed robot beyond rest: one print's two sheets as finite-strain voxel bodies on the
rod and the horns (metasheet.robot.voxel_robot), at motor poses away from rest (issue 62, item 2).

For each pose (every motor moved by the same offset: the rod's roll, as the paper's Fig. 7
pulls and pushes) it reports the rod's motion from the nonlinear equilibrium beside the linear
rest model's prediction (the linear DNS's condensed sheets), the iterations (the rod's
quasi-Newton, the sheets' Newton) and the time. The linear grip stiffness of each sheet is read
from a ``benchmarks/dns_convergence.py`` cache when it holds this print at this voxel size, else
solved here (minutes per sheet).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_printed_robot.py --outputs outputs/paper \
        --voxel 0.3 --offsets 2 5 10 --cache outputs/dns_ladder --save
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from dns_convergence import LABELS, _inputs, _solved  # noqa: E402


def voxel_sheet(outputs: Path, voxel: float, gauge: str, seed: int | None, label: str):
    """(robot, VoxelSheet, the print's seed): one sheet (``label`` in LABELS) of a pipeline's
    outputs, printed at ``voxel`` [mm], its walls neo-Hookean with the cell design's material."""
    from metasheet.robot.voxel_robot import VoxelSheet
    from metasheet.sheet.dns import SheetPrint

    design, orient, material, robot, fields = _inputs(outputs)
    seed = design.seeds.seed if seed is None else seed
    spec = SheetPrint(label, seed, gauge, voxel, design, orient.sheet_params, fields[label],
                      design.material.material().stiffness())
    return robot, VoxelSheet.from_print(spec), seed


def voxel_sheets(outputs: Path, voxel: float, gauge: str, seed: int | None, cache: Path):
    """(robot, (VoxelSheet A, B), linear S at rest, the print's seed) of a pipeline's outputs."""
    from metasheet.robot.condensed import condensed_robot_S
    from metasheet.sheet.dns import SheetPrint

    design, orient, material, robot, fields = _inputs(outputs)
    seed = design.seeds.seed if seed is None else seed
    sheets, Ks = [], []
    for lab in LABELS:
        spec = SheetPrint(lab, seed, gauge, voxel, design, orient.sheet_params, fields[lab],
                          design.material.material().stiffness())
        Ks.append(_solved(cache, spec).K)
        sheets.append(voxel_sheet(outputs, voxel, gauge, seed, lab)[1])
    return robot, tuple(sheets), condensed_robot_S(Ks[0], Ks[1], robot, sheets[0].references), seed


def main() -> None:
    from metasheet.robot.voxel_robot import PrintedRobot

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True)
    ap.add_argument("--voxel", type=float, default=0.3, help="voxel edge [mm]")
    ap.add_argument("--gauge", choices=("seed", "point"), default="seed")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--offsets", type=float, nargs="+", default=[2.0, 5.0], help="every motor moved by [deg]")
    ap.add_argument("--cache", type=Path, required=True, help="dns_convergence.py's cache of linear solves")
    ap.add_argument("--processes", action="store_true",
                    help="the two sheets side by side, each in a process of its own (the same bits)")
    add_save_option(ap)
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    robot, sheets, S, seed = voxel_sheets(args.outputs, args.voxel, args.gauge, args.seed, args.cache)
    J = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    ax = np.asarray(robot.axis, float) / np.linalg.norm(robot.axis)
    t_start = time.perf_counter()
    printed = PrintedRobot(robot, sheets, S_rest=S, rtol=1e-6, progress=lambda d, k, n: print(
        f"  {time.perf_counter() - t_start:7.0f} s  {d} ({k}/{n})", file=sys.stderr, flush=True),
        processes=args.processes)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    rows = []
    for off in args.offsets:
        t0, c0 = time.perf_counter(), time.process_time()
        newton0 = printed.newton
        pose = printed.equilibrium(rest + off)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        linear = J @ np.full(6, np.radians(off))
        rows.append((off, float(np.degrees(pose.theta @ ax)), float(np.degrees(linear[3:] @ ax)),
                     float(np.linalg.norm(pose.dp)), float(np.linalg.norm(linear[:3])), pose.iterations,
                     printed.newton - newton0, wall, cpu, pose.residual, max(pose.wall_strain),
                     min(a.distance for a in pose.approach)))
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}, gauge {args.gauge!r}) of `{args.outputs}` at {args.voxel:g} mm voxels, both "
              "sheets neo-Hookean (the cell design's base material), every motor moved by the offset from rest; "
              "the linear column is the linear DNS's rest model.\n")
        print("| offset [deg] | rod roll [deg] | linear | rod travel [mm] | linear | rod iterations | sheet Newton "
              "iterations | wall [s] | CPU [s] | rod residual | wall strain | closest wall approach [mm] |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r[0]:g} | {r[1]:+.3f} | {r[2]:+.3f} | {r[3]:.3f} | {r[4]:.3f} | {r[5]} | {r[6]} | {r[7]:.0f} "
                  f"| {r[8]:.0f} | {r[9]:.1e} | {r[10]:.3f} | {r[11]:.3f} |")


if __name__ == "__main__":
    main()
