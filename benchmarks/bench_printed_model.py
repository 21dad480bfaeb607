"""The printed robot's fast model (issue 62, item 3): its step time beside the FEM robot's.

Each print's robot is two corotational superelements of their grips
(metasheet.robot.superelement, metasheet.studies.printed_adapter). This times, medians over
repeats in one process, one control step's parts: an equilibrium warm-started from the last
one a degree of motor travel away, the exact Jacobian there, one QP inverse step (equilibrium,
Jacobian and QP), a reach of a goal 5 deg of motor travel away; beside the peer, the FEM robot
(P1 sheets, 15 mm mesh, the same scene) solving the same warm equilibrium. The superelement
sheets here are the FEM sheets condensed on their grips; with ``--outputs`` (a pipeline's
folder with a ``sheet`` stage) they are the first print's voxel DNS, as the ``printed`` stage
builds them.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_printed_model.py --save
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import metasheet  # noqa: F401  (pins numpy's code path)

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402

MOVE = np.array([4.0, -3.0, 2.0, 1.0, -2.0, 3.0])  # [deg] from rest, the reach's goal


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    from metasheet.published import paper
    from metasheet.robot.builder import SheetPair, material_stiffness, six_dof_robot
    from metasheet.robot.equilibrium import solve_equilibrium
    from metasheet.sheet.grips import fem_condensed, grip_references
    from metasheet.sheet.outline import SheetParams
    from metasheet.studies.printed_adapter import printed_spec

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, default=None, help="a pipeline's output folder with a sheet stage")
    ap.add_argument("--repeats", type=int, default=20)
    add_save_option(ap)
    args = ap.parse_args()
    params = SheetParams(mesh_size=15.0)
    sheets = SheetPair.spiral(params, pitch_deg=30.0)
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY, gravity=(0.0, 0.0, 0.0))
    source = "the FEM sheets (P1, 15 mm) condensed on their grips"
    if args.outputs is None:
        Ka = fem_condensed(sheets.sheet, material_stiffness(paper.PAPER_FOAM, sheets.fibers), "p1").K
        Kb = fem_condensed(sheets.mirrored, material_stiffness(paper.PAPER_FOAM, sheets.fibers_mirrored), "p1").K
    else:
        row = json.loads((args.outputs / "sheet" / "sheet_dns.json").read_text())["realisations"][0]
        Ka, Kb = (np.asarray(row["sheets"][k]["K"]) for k in ("normal", "mirrored"))
        source = f"the voxel DNS of print seed {row['seed']} ({args.outputs})"
    model = printed_spec(robot, Ka, Kb, grip_references(params), motor_range=(-60.0, 150.0)).build()
    rest = model.rest_motors()
    _, near = model.equilibrium(rest + MOVE)
    step = rest + MOVE + 1.0
    goal, _ = model.equilibrium(rest + 2 * MOVE)
    rows = [
        ("equilibrium, 1 deg from the last", median_time(lambda: model.equilibrium(step, state=near), args.repeats)),
        ("Jacobian (exact, at an equilibrium)", median_time(lambda: model.jacobian(near), args.repeats)),
        ("inverse step (QP, equilibrium, Jacobian)",
         median_time(lambda: model.reach(goal, state=near, tol_mm=1e-9, max_steps=1), args.repeats)),
        ("reach of a goal 5 deg of travel away", median_time(lambda: model.reach(goal, state=near, tol_mm=0.01,
                                                                                  tol_deg=0.01), args.repeats)),
    ]
    # the peer: the FEM robot's equilibrium a degree from the last one, in the same process
    state = solve_equilibrium(robot, np.radians(rest + MOVE)).state
    peer = median_time(lambda: solve_equilibrium(robot, np.radians(step), state=state), max(3, args.repeats // 4))
    with saved_output(__file__, args.save):
        print(f"The printed robot's superelement model ({source}); medians of {args.repeats} repeats, one "
              "process; the peer is the FEM robot (P1, 15 mm, the same scene) solving the same warm "
              "equilibrium.\n")
        print("| step | median [ms] | FEM robot's equilibrium / this |")
        print("|---|---|---|")
        for name, t in rows:
            print(f"| {name} | {1e3 * t:.2f} | {peer / t:.1f} |")
        print(f"| FEM robot: equilibrium, 1 deg from the last (peer) | {1e3 * peer:.1f} | 1.0 |")


if __name__ == "__main__":
    main()
