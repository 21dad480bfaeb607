"""The cost of the printed robot's validity map (issue 62, item 4; the `printed` stage's
`map_plane` and `map_rays`): the walls' first-contact search (metasheet.sheet.wall_limits.
first_contact, to `--search-deg`) along each family of motor directions, on one print's two
sheets, from `benchmarks/wall_limits.py`'s cache of their linear DNS fields.

Families: the six base directions, the plane of the common modes (`map_plane` directions, the
base ones left out), and the rays of Fig. 5 (every `--ray-stride`-th ray of the workspace grid:
the motor direction moving the rod along it, orientation held). Per family and sheet: the
directions searched, the median and largest time of a search, how many found a contact and
the earliest. The map's cost per sheet is the families' sums (the table's last column).

The peer, in the same process on the first `--peer` directions of each family: the search as it was
before 9a944eb, the pairs found at each step's start (twice the reach beyond the touch distance);
the two must find the same pair at the same travel (to rounding), the ratio is their median times'.
With `--unit`, a second table: the walls' unit's whole work per direction (contact and strain travel)
from the grid's fields as before 2026-12-01 against `MotorWalls` (the six motor fields kept where the
searches read them), in the same process, the same answers required.

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

#: the printed stage's default walls' strain limit [-]
STRAIN_LIMIT = 0.3


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
    ap.add_argument("--peer", type=int, default=3, help="time the step-start search on this many per family")
    ap.add_argument("--unit", type=int, default=3, help="time the walls' unit's whole work per direction (contact "
                    "and strain) on this many per family, from the grid's fields and from MotorWalls")
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
    rows, unit_rows = [], []
    for label, walls, G in (("normal", wa, Ga), ("mirrored", wb, Gb)):
        F = walls.per_motor(G)
        if args.unit:
            unit_rows.append((label, *_unit(walls, G, F, families, args.unit, np.radians(args.search_deg))))
        n_surface = len(surface_nodes(walls.solid))
        for fam, dirs in families.items():
            times, found, peer = [], [], []
            for i, d in enumerate(dirs.values()):
                field = np.einsum("...im,m->...i", F, np.asarray(d, float))
                t0 = time.perf_counter()
                t, pair = first_contact(walls.solid, walls.h, field, np.radians(args.search_deg))
                times.append(time.perf_counter() - t0)
                if np.isfinite(t):
                    found.append(float(np.degrees(t)))
                if i < args.peer:
                    t0 = time.perf_counter()
                    t_peer, pair_peer = _from_step_start(walls.solid, walls.h, field, np.radians(args.search_deg))
                    peer.append((time.perf_counter() - t0, times[-1]))
                    if pair_peer != pair or not np.isclose(t_peer, t, rtol=1e-9, atol=0.0):
                        raise SystemExit(f"the searches disagree: {t_peer!r} {pair_peer} against {t!r} {pair}")
            per_family = len(dirs) if fam != "rays" else n_rays
            ratio = float(np.median([a for a, _ in peer]) / np.median([b for _, b in peer])) if peer else np.nan
            rows.append((label, n_surface, fam, len(dirs), float(np.median(times)), max(times), len(found),
                         min(found) if found else None, float(np.mean(times)) * per_family, len(peer), ratio))
            print(f"  {label} {fam}: {len(dirs)} searches, median {np.median(times):.1f} s", file=sys.stderr,
                  flush=True)
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}) at {args.voxel:g} mm: the walls' first-contact search to "
              f"{args.search_deg:g} deg along each family of motor directions (rays: every {args.ray_stride}-th of "
              f"the grid's {n_rays}); one thread.\n")
        print("| sheet | surface nodes | family | searched | median [s] | largest [s] | contact found | earliest "
              "[deg] | the family's cost per sheet [s] | step-start peer: searched, times slower |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r[0]} | {r[1]:,} | {r[2]} | {r[3]} | {r[4]:.1f} | {r[5]:.1f} | {r[6]} | "
                  f"{'-' if r[7] is None else format(r[7], '.2f')} | {r[8]:.0f} | {r[9]}, {r[10]:.1f} |")
        print(f"\nThe cost column is the mean search times the family's size ({args.plane} plane directions less "
              f"the base ones, all {n_rays} rays). The peer, the search from each step's start (before 9a944eb), "
              f"ran on the first {args.peer} of each family and found the same pair at the same travel; its "
              f"column is its median time over the search's on those.")
        if unit_rows:
            print(f"\nThe walls' unit's work per direction (the contact search and the strain travel, limit "
                  f"{STRAIN_LIMIT:g}) on the first {args.unit} directions of each family: from the grid's fields "
                  "(each direction's field summed on the whole grid, its surface nodes found again, its voxel strains "
                  "computed on the whole grid; before 2026-12-01) and from `MotorWalls` (the six motor fields kept at "
                  "the surface nodes and solid voxels, built once per sheet); the same contact pair, travel and "
                  "strain travel on every direction.\n")
            print("| sheet | directions | MotorWalls built [s] | grid fields, median [s] | MotorWalls, median [s] "
                  "| times faster (median ratio) |")
            print("|---|---|---|---|---|---|")
            for r in unit_rows:
                print(f"| {r[0]} | {r[1]} | {r[2]:.1f} | {r[3]:.2f} | {r[4]:.2f} | {r[5]:.2f} |")



def _unit(walls, G, F, families, n: int, t_max: float):
    """(directions, build [s], grid median [s], MotorWalls median [s], median ratio) of the walls'
    unit's per-direction work both ways; exits non-zero if they disagree."""
    from metasheet.sheet.wall_limits import MotorWalls, first_contact, travel_to_strain

    t0 = time.perf_counter()
    motors = MotorWalls.from_fields(walls, G)
    build = time.perf_counter() - t0
    grid, kept = [], []
    dirs = [d for fam in families.values() for d in list(fam.values())[:n]]
    for d in dirs:
        t0 = time.perf_counter()
        field = np.einsum("...im,m->...i", F, np.asarray(d, float))
        want = first_contact(walls.solid, walls.h, field, t_max), travel_to_strain(field, walls.h, walls.solid,
                                                                                   STRAIN_LIMIT)[0]
        t1 = time.perf_counter()
        got = motors.contact(d, t_max), motors.strain_travel(d, STRAIN_LIMIT)
        t2 = time.perf_counter()
        grid.append(t1 - t0)
        kept.append(t2 - t1)
        if got[0][1] != want[0][1] or not np.allclose([got[0][0], got[1]], [want[0][0], want[1]], rtol=1e-9, atol=0):
            raise SystemExit(f"the unit's two ways disagree along {d}: {got} against {want}")
    return len(dirs), build, float(np.median(grid)), float(np.median(kept)), float(np.median(np.divide(grid, kept)))


def _from_step_start(solid, h, u_unit, t_max: float):
    """The peer: first_contact as it was before 9a944eb, each step's pairs found at its start within
    ``touch`` plus twice a node's largest motion in a step (the same exact travel, more pairs)."""
    from scipy.spatial import cKDTree

    from metasheet.sheet.wall_limits import WallPairs, contact_travel, surface_nodes

    h = np.asarray(h, float).reshape(3)
    hmin = float(h.min())
    separation, touch = 2.0 * hmin, 0.25 * hmin
    N = tuple(n + 1 for n in solid.shape)
    nodes = surface_nodes(solid)
    X = np.stack(np.unravel_index(nodes, N), 1) * h
    u = np.asarray(u_unit, float).reshape(-1, 3)[nodes]
    speed = float(np.sqrt(np.einsum("pi,pi->p", u, u).max()))
    n = max(1, int(np.ceil(t_max * speed / hmin)))
    dt = t_max / n
    reach = touch + 2.0 * speed * dt
    for i in range(n):
        Y = X + i * dt * u
        pairs = cKDTree(Y).query_pairs(reach, output_type="ndarray")
        rest = X[pairs[:, 0]] - X[pairs[:, 1]]
        pairs = pairs[np.einsum("pi,pi->p", rest, rest) >= separation**2]
        if not len(pairs):
            continue
        here = WallPairs(pairs[:, 0], pairs[:, 1], Y[pairs[:, 0]] - Y[pairs[:, 1]], separation, reach, touch)
        t, k = contact_travel(here, u)
        if t <= dt:
            return i * dt + t, (int(nodes[pairs[k, 0]]), int(nodes[pairs[k, 1]]))
    return np.inf, ()


if __name__ == "__main__":
    main()
