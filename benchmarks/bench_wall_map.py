"""The cost of the printed robot's validity map (issue 62, item 4; the `printed` stage's
`map_plane` and `map_rays`): the walls' first-contact search (metasheet.sheet.wall_limits.
first_contact, to `--search-deg`) along each family of motor directions, on one print's two
sheets, from `benchmarks/wall_limits.py`'s cache of their linear DNS fields.

Families: the six base directions, the plane of the common modes (`map_plane` directions, the
base ones left out), and the rays of Fig. 5 (every `--ray-stride`-th ray of the workspace grid:
the motor direction moving the rod along it, orientation held). Per family and sheet: the
directions searched, the median and largest time of a search, how many found a contact and
the earliest. The map's cost per sheet is the families' sums (the table's last column).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_wall_map.py --outputs OUT/paper --cache OUT/walls --save
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from wall_limits import solved_walls  # noqa: E402


def main() -> None:
    from metasheet.robot.condensed import grip_motions_per_motor
    from metasheet.sheet.wall_limits import first_contact, surface_nodes
    from metasheet.studies.grid import star_grid
    from metasheet.studies.printed_limits import BASE_DIRECTIONS, plane_directions, ray_directions

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (through printmap)")
    ap.add_argument("--cache", type=Path, required=True, help="benchmarks/wall_limits.py's cache of the fields")
    ap.add_argument("--voxel", type=float, default=0.25)
    ap.add_argument("--search-deg", type=float, default=10.0)
    ap.add_argument("--plane", type=int, default=16)
    ap.add_argument("--ray-stride", type=int, default=6, help="time every n-th ray of the grid's 62")
    add_save_option(ap)
    args = ap.parse_args()
    robot, refs, sheets, seed = solved_walls(args.outputs, args.voxel, "seed", None, args.cache)
    (Ka, wa, _), (Kb, wb, _) = sheets
    Ga, Gb, J = grip_motions_per_motor(Ka, Kb, robot, refs)
    rays, _ = ray_directions(J, star_grid().directions)
    n_rays = len(rays)
    families = {"base": dict(BASE_DIRECTIONS),
                "plane": {k: v for k, v in plane_directions(args.plane).items() if k not in BASE_DIRECTIONS},
                "rays": dict(list(rays.items())[::args.ray_stride])}
    rows = []
    for label, walls, G in (("normal", wa, Ga), ("mirrored", wb, Gb)):
        F = walls.per_motor(G)
        n_surface = len(surface_nodes(walls.solid))
        for fam, dirs in families.items():
            times, found = [], []
            for d in dirs.values():
                field = np.einsum("...im,m->...i", F, np.asarray(d, float))
                t0 = time.perf_counter()
                t, _ = first_contact(walls.solid, walls.h, field, np.radians(args.search_deg))
                times.append(time.perf_counter() - t0)
                if np.isfinite(t):
                    found.append(float(np.degrees(t)))
            per_family = len(dirs) if fam != "rays" else n_rays
            rows.append((label, n_surface, fam, len(dirs), float(np.median(times)), max(times), len(found),
                         min(found) if found else None, float(np.mean(times)) * per_family))
            print(f"  {label} {fam}: {len(dirs)} searches, median {np.median(times):.1f} s", file=sys.stderr,
                  flush=True)
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}) at {args.voxel:g} mm: the walls' first-contact search to "
              f"{args.search_deg:g} deg along each family of motor directions (rays: every {args.ray_stride}-th of "
              f"the grid's {n_rays}); one thread.\n")
        print("| sheet | surface nodes | family | searched | median [s] | largest [s] | contact found | earliest "
              "[deg] | the family's cost per sheet [s] |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r[0]} | {r[1]:,} | {r[2]} | {r[3]} | {r[4]:.1f} | {r[5]:.1f} | {r[6]} | "
                  f"{'-' if r[7] is None else format(r[7], '.2f')} | {r[8]:.0f} |")
        print(f"\nThe last column is the mean search times the family's size ({args.plane} plane directions less "
              f"the base ones, all {n_rays} rays).")


if __name__ == "__main__":
    main()
