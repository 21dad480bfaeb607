"""One printed sheet beyond rest: the finite-strain voxel DNS of one sheet of a print, its centre
held and its three horns turned by the same angle about the servo axes (issue 62, item 2).

It prints the trust-region Newton method's residual after each step with the time, then the
four grips' wrenches at that angle against the same solve at a thousandth of it scaled up (the
linear DNS): how far the printed sheet is from its linearisation.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sheet_pose.py --outputs outputs/paper \
        --voxel 0.3 --deg 1 --save
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
from dns_convergence import LABELS  # noqa: E402

GRIPS = ("centre", "arm 0", "arm 1", "arm 2")


def horns_turned(robot, sheet, sheet_index: int, deg: float):
    """(rotations, translations) (4, 3) of the sheet's grips: the centre held, the horns turned ``deg``."""
    from metasheet.robot.robots import Q_A, Q_B
    from metasheet.robot.voxel_robot import sheet_grip_poses

    c = robot.coupling
    centres = np.asarray(robot.info["sheet_centres_mm"], float)
    servos = list(c.servos[3 * sheet_index:3 * sheet_index + 3])
    return sheet_grip_poses((Q_A, Q_B)[sheet_index], centres[sheet_index], sheet.references,
                            np.asarray(c.origin, float), servos, np.zeros(3), np.zeros(3), np.radians([deg] * 3))


def solve(gb, robot, sheet, sheet_index: int, deg: float, rtol: float, history: list | None):
    """The grips' wrenches (4, 6) and the solve's wall time [s] with the horns turned ``deg``."""
    rot, trans = horns_turned(robot, sheet, sheet_index, deg)
    t0 = time.perf_counter()

    def say(msg, k, n):
        if history is not None and "residual" in msg:
            history.append((float(msg.split("residual ")[1].split()[0].rstrip(",")), time.perf_counter() - t0))
        print(f"  {time.perf_counter() - t0:7.1f} s  {msg}", file=sys.stderr, flush=True)

    w = gb.wrenches(rot, trans, rtol=rtol, progress=say)
    return np.asarray(w.wrenches, float), time.perf_counter() - t0, w.solution


def _contact(args, sheet):
    """The walls' contact of the command line: the defaults, or the stiffness and ramp asked."""
    from dataclasses import replace

    from metasheet.fem.voxel.contact import Contact

    h = np.asarray(sheet.size, float) / np.asarray(sheet.phases.shape)
    c = Contact.default(h, sheet.law.E)
    if args.contact_stiffness is not None:
        c = replace(c, stiffness=args.contact_stiffness * sheet.law.E / float(h.min()))
    if args.contact_ramp is not None:
        c = replace(c, ramp=args.contact_ramp * c.gap)
    return c


def main() -> None:
    from metasheet.fem.voxel.gaps import closest_approach
    from metasheet.sheet.voxel_grips_nonlinear import GripBody

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (through printmap)")
    ap.add_argument("--voxel", type=float, default=0.3, help="voxel edge [mm]")
    ap.add_argument("--gauge", choices=("seed", "point"), default="seed")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--sheet", choices=LABELS, default="normal")
    ap.add_argument("--deg", type=float, default=1.0, help="every horn turned by [deg]")
    ap.add_argument("--rtol", type=float, default=1e-4, help="free residual over the reactions")
    ap.add_argument("--contact", action="store_true",
                    help="penalty contact between the walls (metasheet.fem.voxel.contact, its defaults)")
    ap.add_argument("--contact-stiffness", type=float, default=None,
                    help="with --contact: the penalty's stiffness as a multiple of E / h (default 10)")
    ap.add_argument("--contact-ramp", type=float, default=None,
                    help="with --contact: the overlap over which a pair's stiffness ramps in, as a share of the "
                         "gap (default 0.5; 0: none)")
    add_save_option(ap)
    args = ap.parse_args()
    robot, sheet, seed = voxel_sheet(args.outputs, args.voxel, args.gauge, args.seed, args.sheet)
    gb = GripBody(sheet.phases, sheet.size, sheet.law, bodies=sheet.bodies, references=sheet.references - sheet.origin,
                  contact=_contact(args, sheet) if args.contact else None)
    index = LABELS.index(args.sheet)
    history: list = []
    W, wall, sol = solve(gb, robot, sheet, index, args.deg, args.rtol, history)
    W_lin, wall_lin, _ = solve(gb, robot, sheet, index, args.deg / 1000, args.rtol, None)
    W_lin *= 1000.0
    gap = closest_approach(~np.isnan(sol.strain), sol.h, sol.full(sol.u))
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}, gauge {args.gauge!r}) of `{args.outputs}`, the {args.sheet} sheet at "
              f"{args.voxel:g} mm voxels ({int((sheet.phases > 0).sum()):,} solid voxels), neo-Hookean walls; the "
              f"centre held, the horns turned by {args.deg:g} deg; rtol {args.rtol:g}.\n")
        print("| Newton step | " + " | ".join(str(k) for k in range(len(history))) + " |")
        print("|---|" + "---|" * len(history))
        print("| free residual / reactions | " + " | ".join(f"{r:.2g}" for r, _ in history) + " |")
        print("| time [s] | " + " | ".join(f"{t:.0f}" for _, t in history) + " |")
        print(f"\nThe solve: {wall:.0f} s wall, {sol.newton} Newton steps, CG {sum(sol.cg)} iterations "
              f"(per step: {', '.join(str(c) for c in sol.cg)}), stable: {sol.stable}. The solve at "
              f"{args.deg / 1000:g} deg: {wall_lin:.0f} s. The walls: largest principal Green-Lagrange "
              f"strain {float(np.nanmax(sol.strain)):.3f}; closest approach of two surfaces apart at rest "
              f"{gap.distance:.3f} mm (from {gap.rest_distance:.3f} mm; closed: {gap.closed}); wall pairs in "
              f"contact: {sol.contact if sol.contact is not None else 'no contact modelled'}.\n")
        print(f"| grip | force, {args.deg:g} deg / linear | moment, {args.deg:g} deg / linear |")
        print("|---|---|---|")
        for k, name in enumerate(GRIPS):
            print(f"| {name} | {np.linalg.norm(W[k, :3]) / np.linalg.norm(W_lin[k, :3]):.3f} | "
                  f"{np.linalg.norm(W[k, 3:]) / np.linalg.norm(W_lin[k, 3:]):.3f} |")
        print(f"| all four | {np.linalg.norm(W[:, :3]) / np.linalg.norm(W_lin[:, :3]):.3f} | "
              f"{np.linalg.norm(W[:, 3:]) / np.linalg.norm(W_lin[:, 3:]):.3f} |")


if __name__ == "__main__":
    main()
