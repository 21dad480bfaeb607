"""The printed robot's fast model certified on a print (issue 62, item 3): the corotational
superelement robot (metasheet.robot.superelement, each sheet's linear DNS stiffness on its four
grips) against the finite-strain voxel robot of the same print (metasheet.robot.voxel_robot: both
sheets neo-Hookean voxel bodies, the rod in equilibrium), at held-out motor poses.

Poses: each named direction of metasheet.studies.printed_limits (the six base directions, or any
``--directions``) and ``--random`` seeded random directions, scaled so that the largest motor
moves by each ``--travel`` [deg], solved outwards from rest (each pose starts from the last one
of its direction). Per pose: the rod's move and turn in the voxel robot, the superelement's errors
(the issue's targets: 0.5 mm and 0.5 deg), the linear rest model's errors beside them, the walls'
largest strain and closest approach (the voxel robot has no contact: its walls pass through each
other; "closed" when two walls apart at rest come within a quarter voxel, the rule of
metasheet.fem.voxel.gaps), and the time of each. Per direction, the walls' first contact to
first order (metasheet.studies.printed_limits' search on the linear DNS's fields, the `printed`
stage's limit) stands beside it: the finite-strain robot's closed walls say where that limit
is early or late.

The voxel size is the reference's discretisation of the print's walls: the superelement takes
the linear DNS of the same grid, so the errors are the model's reduction, not the grid's. A
coarse grid (0.4 mm) keeps a pose to minutes; 0.25 mm (the product's) is an hour a pose.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_printed_certificate.py --outputs outputs/paper \
        --voxel 0.4 --travel 0.5 1 2 --random 1 --cache outputs/dns_ladder --save
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from bench_printed_robot import voxel_sheet  # noqa: E402
from dns_convergence import LABELS, _inputs, _solved  # noqa: E402


def _directions(names, n_random: int, seed: int) -> dict[str, np.ndarray]:
    from metasheet.studies.printed_limits import BASE_DIRECTIONS

    out = {}
    for n in names:
        if n not in BASE_DIRECTIONS:
            raise SystemExit(f"--directions: {n!r}: one of {', '.join(BASE_DIRECTIONS)}")
        out[n] = np.asarray(BASE_DIRECTIONS[n], float)
    rng = np.random.default_rng(seed)
    for k in range(n_random):
        d = rng.uniform(-1.0, 1.0, 6)
        out[f"random {k + 1}"] = d / np.abs(d).max()
    return out


def _error(a_dp, a_theta, b_dp, b_theta) -> tuple[float, float]:
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(np.asarray(a_theta, float)) * Rotation.from_rotvec(np.asarray(b_theta, float)).inv()
    return float(np.linalg.norm(np.asarray(a_dp, float) - b_dp)), float(np.degrees(R.magnitude()))


def first_order_contact(specs, G, dirs, cache: Path, search_deg: float = 10.0) -> dict:
    """Per direction, (the walls' first contact to first order [deg of the largest motor] over
    both sheets, None: none within ``search_deg``; the sheet's label): the `printed` stage's search
    (metasheet.studies.printed_limits.wall_unit) on the same print and grid, both sheets side by
    side (one process each). Each direction's is kept in ``cache``: a rerun searches only new
    ones."""
    from metasheet.runtime.executor import Executor
    from metasheet.studies.printed_limits import WallUnit, wall_unit

    s = specs[0]
    kept = cache / f"first-order-{s.gauge}-{s.voxel_mm:g}mm-seed{s.seed}-{search_deg:g}deg.json"
    out = json.loads(kept.read_text()) if kept.exists() else {}
    todo = {n: d for n, d in dirs.items() if n not in out}
    if todo:
        units = [WallUnit(spec, tuple(map(tuple, g)), tuple((n, tuple(d)) for n, d in todo.items()), search_deg, 0.3)
                 for spec, g in zip(specs, G)]
        found = Executor(workers=2).map(wall_unit, units)  # its workers exit with this process
        for n in todo:
            vals = [(f["directions"][n]["contact_deg"], f["label"]) for f in found
                    if f["directions"][n]["contact_deg"] is not None]
            out[n] = min(vals) if vals else (None, None)
        tmp = kept.with_name(f".{kept.name}.tmp-{os.getpid()}")
        tmp.write_text(json.dumps(out))
        os.replace(tmp, kept)
    return {n: tuple(out[n]) for n in dirs}


def main() -> None:
    from metasheet.robot.condensed import condensed_robot_S, grip_motions_per_motor
    from metasheet.robot.superelement import SuperelementRobot
    from metasheet.robot.voxel_robot import PrintedRobot
    from metasheet.sheet.dns import SheetPrint
    from metasheet.sheet.grips import grip_references

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (through printmap)")
    ap.add_argument("--voxel", type=float, default=0.4, help="voxel edge [mm]")
    ap.add_argument("--gauge", choices=("seed", "point"), default="seed")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--travel", type=float, nargs="+", default=[0.5, 1.0, 2.0],
                    help="the largest motor's travel from rest [deg], outwards")
    ap.add_argument("--directions", nargs="*", default=["roll up", "A down"])
    ap.add_argument("--random", type=int, default=1, help="seeded random directions besides")
    ap.add_argument("--random-seed", type=int, default=62)
    ap.add_argument("--rtol", type=float, default=1e-6, help="the voxel robot's sheets' relative residual")
    ap.add_argument("--start", choices=("rest", "model"), default="rest",
                    help="each pose's rod iteration started at rest (its sheets from the last pose solved) or at "
                         "the superelement robot's balance (fewer rod iterations; the same balance to its tolerance)")
    ap.add_argument("--rod-tol", type=float, default=None,
                    help="[mm] the rod balanced once its predicted step moves it and an arm's end by under this "
                         "(default: to the sheets' rtol on its wrench)")
    ap.add_argument("--processes", action="store_true",
                    help="the voxel robot's two sheets side by side, each in a process of its own (the same bits)")
    ap.add_argument("--cache", type=Path, required=True, help="dns_convergence.py's cache of linear solves")
    add_save_option(ap)
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    design, orient, _, robot, fields = _inputs(args.outputs)
    seed = design.seeds.seed if args.seed is None else args.seed
    Ks, sheets, specs = [], [], []
    for lab in LABELS:
        spec = SheetPrint(lab, seed, args.gauge, args.voxel, design, orient.sheet_params, fields[lab],
                          design.material.material().stiffness())
        Ks.append(_solved(args.cache, spec).K)
        specs.append(spec)
        sheets.append(voxel_sheet(args.outputs, args.voxel, args.gauge, seed, lab)[1])
    refs = grip_references(orient.sheet_params)
    dirs = _directions(args.directions, args.random, args.random_seed)
    first = first_order_contact(specs, grip_motions_per_motor(Ks[0], Ks[1], robot, refs)[:2], dirs, args.cache)
    S = condensed_robot_S(Ks[0], Ks[1], robot, refs)
    J = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    model = SuperelementRobot(robot, Ks[0], Ks[1], refs)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    t_start = time.perf_counter()
    say = lambda d, k, n: print(f"  {time.perf_counter() - t_start:7.0f} s  {d} ({k}/{n})",  # noqa: E731
                                file=sys.stderr, flush=True)
    rows = []
    for name, d in dirs.items():
        reference = PrintedRobot(robot, sheets, S_rest=S, rtol=args.rtol, progress=say,  # outwards from rest
                                 processes=args.processes)
        for t in sorted(args.travel):
            m = rest + t * d
            t0 = time.perf_counter()
            got = model.equilibrium(m)
            t_model = time.perf_counter() - t0
            t0 = time.perf_counter()
            q0 = np.concatenate([got.dp, got.theta]) if args.start == "model" else None
            ref = reference.equilibrium(m, q0=q0, step_tol=args.rod_tol)
            t_ref = time.perf_counter() - t0
            lin = J @ np.radians(t * d)
            e_mm, e_deg = _error(ref.dp, ref.theta, got.dp, got.theta)
            l_mm, l_deg = _error(ref.dp, ref.theta, lin[:3], lin[3:])
            rows.append((name, t, float(np.linalg.norm(ref.dp)), float(np.degrees(np.linalg.norm(ref.theta))),
                         e_mm, e_deg, l_mm, l_deg, max(ref.wall_strain), min(a.distance for a in ref.approach),
                         t_ref, 1e3 * t_model, any(a.closed for a in ref.approach)))
            print(f"  {name} {t:g} deg: error {e_mm:.4f} mm {e_deg:.4f} deg (linear {l_mm:.4f} mm {l_deg:.4f} deg), "
                  f"{t_ref:.0f} s", file=sys.stderr, flush=True)
        reference.close()  # its sheets' processes stopped before the next direction's start
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}, gauge {args.gauge!r}) of `{args.outputs}` at {args.voxel:g} mm voxels: the "
              "superelement robot (each sheet's linear DNS stiffness on its grips) against the finite-strain voxel "
              f"robot (neo-Hookean walls, no contact; sheets to rtol {args.rtol:g}), the largest motor moved by the "
              "travel along each direction. Targets (issue 62): 0.5 mm, 0.5 deg.\n")
        print("| direction | travel [deg] | rod move [mm] | rod turn [deg] | superelement error [mm] | [deg] | "
              "linear rest model error [mm] | [deg] | walls' strain | closest walls [mm] | walls closed | "
              "first-order first contact [deg] | voxel robot [s] | superelement [ms] |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            fc = first[r[0]][0]
            print(f"| {r[0]} | {r[1]:g} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.4f} | {r[5]:.4f} | {r[6]:.4f} | "
                  f"{r[7]:.4f} | {r[8]:.3f} | {r[9]:.3f} | {'yes' if r[12] else 'no'} | "
                  f"{'none' if fc is None else format(fc, '.2f')} | {r[10]:.0f} | {r[11]:.1f} |")
        worst = max(rows, key=lambda r: r[4])
        print(f"\nLargest superelement error: {worst[4]:.4f} mm, {max(r[5] for r in rows):.4f} deg "
              f"(targets 0.5 mm, 0.5 deg).")


if __name__ == "__main__":
    main()
