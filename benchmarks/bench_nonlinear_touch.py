"""The walls' first touch on the finite-strain printed robot against the first-order search
(issue 62, item 4: self-contact found on the nonlinear DNS).

One print of a pipeline's outputs at a voxel size: per named motor direction, the first-order
first contact (the `printed` stage's search, metasheet.studies.printed_limits.wall_unit, on the
linear DNS's fields; both sheets solved side by side, one process each; kept in --cache) and the
first touch of the finite-strain voxel robot (metasheet.studies.nonlinear_touch.robot_touch:
both sheets neo-Hookean, each pose's stability probed; started at the first-order travel), with
the rod held where the linear rest model puts it (its miss to the balance recorded) or, with
--balance, balanced at each pose (then the superelement robot's and the rest model's errors at
those poses are reported beside them). Every pose the search solved is listed, with its time.
Each pose is journalled in --cache as it is solved (touch-*.jsonl): a rerun replays those and
goes on where a killed one stopped.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_nonlinear_touch.py --outputs OUT/printed-robot \
        --voxel 0.25 --directions 'roll up' --cache OUT/dns_ladder --processes --save

Several prints, each along its own binding direction (the printed stage's box), into one table:
``--print 1 'roll up' --print 2 'plane 315' --print 3 'plane 292.5'`` (the searches kept in the
journals are replayed, the others solved).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from bench_printed_certificate import _error, first_order_contact  # noqa: E402
from bench_printed_robot import voxel_sheets  # noqa: E402
from dns_convergence import LABELS, _inputs, _solved  # noqa: E402


def _arguments():
    from metasheet.studies.printed_limits import directions, plane_directions

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (through robot)")
    ap.add_argument("--voxel", type=float, default=0.25, help="voxel edge [mm]")
    ap.add_argument("--gauge", choices=("seed", "point"), default="seed")
    ap.add_argument("--seed", type=int, default=None, help="the print (default: the design's seed)")
    known = {**directions(True), **plane_directions(16)}
    ap.add_argument("--directions", nargs="+", default=["roll up"], choices=list(known),
                    help="motor directions by name (the printed stage's: the base ones, each motor alone, the "
                         "plane of the common modes at 16 directions)")
    ap.add_argument("--print", nargs=2, action="append", metavar=("SEED", "DIRECTION"), dest="prints",
                    help="a print and one direction, instead of --seed and --directions (repeat it: several "
                         "prints, each along its own binding direction, one after the other into one table)")
    ap.add_argument("--search-deg", type=float, default=10.0, help="the first-order search's travel [deg]")
    ap.add_argument("--tol", type=float, default=0.02, help="the nonlinear touch's bracket [deg]")
    ap.add_argument("--max-solves", type=int, default=8, help="robot poses per direction at most")
    ap.add_argument("--rtol", type=float, default=1e-6, help="the voxel robot's sheets' relative residual")
    ap.add_argument("--processes", action="store_true", help="the voxel robot's two sheets side by side")
    ap.add_argument("--balance", action="store_true", help="the rod balanced at each pose (rod iterations: tens of "
                    "minutes a pose at 0.25 mm) instead of held where the linear rest model puts it")
    ap.add_argument("--rod-tol", type=float, default=None, help="[mm] with --balance: the rod balanced once its "
                    "predicted step moves it and an arm's end by under this (default: to the sheets' rtol)")
    ap.add_argument("--cache", type=Path, required=True, help="dns_convergence.py's cache of linear solves")
    add_save_option(ap)
    args = ap.parse_args()
    todo = {}  # seed (None: the design's) -> direction names, in the order given
    for seed, name in args.prints or [(args.seed, n) for n in args.directions]:
        if name not in known:
            ap.error(f"--print: direction {name!r}: one of {', '.join(known)}")
        try:
            seed = None if seed is None else int(seed)
        except ValueError:
            ap.error(f"--print: seed {seed!r}: a whole number")
        todo.setdefault(seed, []).append(name)
    return args, known, todo


def _print_touches(args, known, seed, names) -> tuple:
    """(the print's seed, seconds of its first-order search, rows: (seed, direction, (first order deg,
    sheet), Touch, pose records, seconds)) of one print along ``names``."""
    from metasheet.robot.condensed import grip_motions_per_motor
    from metasheet.robot.superelement import SuperelementRobot
    from metasheet.robot.voxel_robot import PrintedRobot
    from metasheet.runtime.journal import Journal
    from metasheet.sheet.dns import SheetPrint
    from metasheet.studies.nonlinear_touch import robot_touch

    design, orient, _, robot, fields = _inputs(args.outputs)
    robot, sheets, S, seed = voxel_sheets(args.outputs, args.voxel, args.gauge, seed, args.cache)
    specs = [SheetPrint(lab, seed, args.gauge, args.voxel, design, orient.sheet_params, fields[lab],
                        design.material.material().stiffness()) for lab in LABELS]
    Ks = [_solved(args.cache, s).K for s in specs]
    dirs = {n: np.asarray(known[n], float) for n in names}
    t0 = time.perf_counter()  # each direction's first-order search kept in the cache: a rerun starts at the robot
    first = first_order_contact(specs, grip_motions_per_motor(Ks[0], Ks[1], robot, sheets[0].references)[:2], dirs,
                                args.cache, args.search_deg)
    t_first = time.perf_counter() - t0
    print(f"seed {seed}, first order: {first} ({t_first:.0f} s)", file=sys.stderr, flush=True)
    rest = np.degrees([s.rest_angle for s in robot.coupling.servos])
    model = SuperelementRobot(robot, Ks[0], Ks[1], sheets[0].references)
    J = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    say = lambda d, k, n: print(f"  {time.perf_counter() - t0:7.0f} s  {d} ({k}/{n})",  # noqa: E731
                                file=sys.stderr, flush=True)
    rows = []
    for name, d in dirs.items():
        guess = first[name][0]
        if guess is None:
            print(f"{name}: no first-order contact within {args.search_deg:g} deg: skipped", file=sys.stderr)
            continue
        printed = PrintedRobot(robot, sheets, S_rest=S, rtol=args.rtol, progress=say, processes=args.processes)
        mode = "balanced" if args.balance else "held"
        journal = Journal(args.cache / f"touch-{args.gauge}-{args.voxel:g}mm-seed{seed}-{name.replace(' ', '_')}-"
                          f"{mode}.jsonl", {"seed": seed, "gauge": args.gauge, "voxel": args.voxel, "rod": mode,
                                            "direction": d.tolist(), "first_order_deg": guess, "rtol": args.rtol,
                                            **({"rod_tol": args.rod_tol} if args.balance else {})})
        t1 = time.perf_counter()
        try:
            found, records = robot_touch(printed, rest, d, guess, max_deg=2.0 * guess, tol_deg=args.tol,
                                         max_solves=args.max_solves, rod_per_motor=J, balance=args.balance,
                                         progress=lambda r: print(f"  pose at {r['travel']:.4f} deg: closest walls "
                                                                  f"{r['approach_mm']} mm, rod residual "
                                                                  f"{r['rod_residual']:.2e}, {r['seconds']:.0f} s"
                                                                  + (" (journal)" if r.get("replayed") else ""),
                                                                  file=sys.stderr, flush=True),
                                         journal=journal, rod_tol_mm=args.rod_tol)
        finally:
            printed.close()
        rows.append((seed, name, first[name], found, records, time.perf_counter() - t1))
        for r in records if args.balance else ():  # balanced poses certify the fast model and the rest model
            m = np.radians(r["travel"] * d / np.abs(d).max())
            got = model.equilibrium(rest + np.degrees(m))
            lin = J @ m
            r["superelement"] = _error(r["dp_mm"], r["theta_rad"], got.dp, got.theta)
            r["linear"] = _error(r["dp_mm"], r["theta_rad"], lin[:3], lin[3:])
        print(f"  seed {seed}, {name}: {found.travel} deg, bracket {found.bracket}", file=sys.stderr, flush=True)
    return seed, t_first, rows


def main() -> None:
    args, known, todo = _arguments()
    args.cache.mkdir(parents=True, exist_ok=True)
    seeds, t_first, rows = [], [], []
    for seed, names in todo.items():  # one print at a time: its two sheets' grids freed before the next
        s, t, r = _print_touches(args, known, seed, names)
        seeds.append(s)
        t_first.append(t)
        rows += r
    with saved_output(__file__, args.save):
        prints = (f"One print (seed {seeds[0]}" if len(seeds) == 1
                  else f"{len(seeds)} prints (seeds {', '.join(map(str, seeds))}")
        print(f"{prints}, gauge {args.gauge!r}) of `{args.outputs}` at {args.voxel:g} mm voxels: the "
              "walls' first contact to first order (the linear DNS's fields, the `printed` stage's search; "
              f"{', '.join(f'{t:.0f}' for t in t_first)} s a print for both sheets side by side, 0 when kept from a "
              "previous run) against the first "
              "touch of the finite-strain voxel robot (both sheets neo-Hookean, "
              + ("the rod in equilibrium" if args.balance else "the rod held where the linear rest model puts it")
              + f", sheets to rtol {args.rtol:g}, each pose's "
              f"stability probed; two walls apart at rest within a quarter voxel), to {args.tol:g} deg of the "
              "largest motor.\n")
        print("| seed | direction | first order [deg] | sheet | finite strain [deg] | sheet | bracket [deg] | ratio | "
              "poses | time [s] |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for seed, name, (fo, lab), found, records, _ in rows:
            sheet = LABELS[found.info["sheet"]] if found.info else "-"
            ft = "open" if found.travel is None else f"{found.travel:.3f}"
            ratio = "-" if found.travel is None else f"{found.travel / fo:.2f}"
            spent = sum(r["seconds"] for r in records)  # the poses' own: a replayed search's as first solved
            replayed = " (journal)" if any(r.get("replayed") for r in records) else ""
            print(f"| {seed} | {name} | {fo:.3f} | {lab} | {ft} | {sheet} | {found.bracket[0]:.3f} to "
                  f"{found.bracket[1]:.3f} | {ratio} | {found.solves} | {spent:.0f}{replayed} |")
        print("\nThe poses solved, in order (held: the rod's first-order step to its balance; balanced: the "
              "superelement robot's and the linear rest model's errors against it, targets 0.5 mm, 0.5 deg):\n")
        print("| seed | direction | travel [deg] | rod move [mm] | rod turn [deg] | rod residual | closest walls A, B [mm] | "
              "walls' strain A, B | stable | rod off its balance [mm, deg] | superelement error [mm, deg] | "
              "linear rest model error [mm, deg] | time [s] |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")

        def pair(v):
            return "-" if v is None else f"{v[0]:.4f}, {v[1]:.4f}"
        for seed, name, _, _, records, _ in rows:
            for r in records:
                print(f"| {seed} | {name} | {r['travel']:.3f} | {r['move_mm']:.3f} | {r['turn_deg']:.3f} | "
                      f"{r['rod_residual']:.1e} | " + ", ".join(f"{v:.3f}" for v in r["approach_mm"]) + " | "
                      + ", ".join(f"{v:.3f}" for v in r["strain"]) + f" | {all(r['stable'])} | "
                      f"{pair(r['rod_miss'])} | {pair(r.get('superelement'))} | {pair(r.get('linear'))} | "
                      f"{r['seconds']:.0f}{' (journal)' if r.get('replayed') else ''} |")

if __name__ == "__main__":
    main()
