"""The printed sheets' own limits at first order: wall strain and self-contact over the motors
(issue 62, item 4; metasheet/sheet/wall_limits.py).

One print (both sheets, one foam seed) of a pipeline's outputs is solved as the linear voxel DNS
with the displacement of each unit grip motion (:func:`metasheet.sheet.dns.dns_sheet_walls`),
kept in ``--cache`` (float32 fields, resumable). The linear printed robot (the two sheets'
condensed stiffnesses, :func:`metasheet.robot.condensed.grip_motions_per_motor`) turns each
motor direction into the walls' field per radian; along it the travel at which

* the walls' largest principal strain reaches ``--strain-limit`` (forward and backward), and
* two walls first touch (searched up to the strain limit's travel: past it the model is out of
  its range anyway; along each sheet's three motors together and all six, on the sheets those
  motors hold: a search costs about a minute on a print),

is found on each sheet. Directions: each motor alone, each sheet's three motors together, all six
(the paper's roll of the rod), and, given ``--workspace`` (a workspace stage's folder), the rays
of Fig. 5: the least-norm motor change moving the effector along each ray, with the continuum
prediction's and the reproduction's furthest reached point on it beside the walls' limits.

    OPENBLAS_NUM_THREADS=1 python benchmarks/wall_limits.py --outputs OUT/paper --voxel 0.25 \
        --cache OUT/walls --workspace OUT/paper/workspace --save
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from dns_convergence import LABELS, _inputs  # noqa: E402


def solved_walls(outputs: Path, voxel: float, gauge: str, seed: int | None, cache: Path, labels=LABELS):
    """(robot, references, [(K, SheetWalls, record)] per label of ``labels``, seed) from ``cache``
    or solved now (and kept there)."""
    from metasheet.sheet.dns import SheetPrint, dns_sheet_walls
    from metasheet.sheet.grips import grip_references
    from metasheet.sheet.wall_limits import SheetWalls

    design, orient, material, robot, fields = _inputs(outputs)
    seed = design.seeds.seed if seed is None else seed
    cache.mkdir(parents=True, exist_ok=True)
    out = []
    for lab in labels:
        path = cache / f"walls-{gauge}-{voxel:g}mm-{lab}-seed{seed}.npz"
        if not path.is_file():
            t0 = time.perf_counter()
            spec = SheetPrint(lab, seed, gauge, float(voxel), design, orient.sheet_params, fields[lab],
                              design.material.material().stiffness())
            sheet, walls = dns_sheet_walls(spec)
            print(f"  solved {path.name}: {sheet.n_dof:,} unknowns, {time.perf_counter() - t0:.0f} s",
                  file=sys.stderr, flush=True)
            tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}.npz")
            np.savez(tmp, K=sheet.K, solid=walls.solid, h=walls.h, U=walls.U.astype(np.float32),
                     seconds=sheet.build_s + sheet.solve_s, n_dof=sheet.n_dof)
            os.replace(tmp, path)
        with np.load(path) as d:
            out.append((d["K"], SheetWalls(d["solid"], d["h"], d["U"].astype(float)),
                        {"seconds": float(d["seconds"]), "n_dof": int(d["n_dof"])}))
    return robot, grip_references(orient.sheet_params), out, seed


def directions(J, workspace: Path | None) -> list[tuple[str, np.ndarray, float]]:
    """(name, motor direction (6,) [rad per unit], unit [deg or mm per unit]) to test."""
    out = []
    for k in range(6):
        out.append((f"motor {k}", np.eye(6)[k], np.degrees(1.0)))
    out.append(("sheet A's motors together", np.r_[np.ones(3), np.zeros(3)], np.degrees(1.0)))
    out.append(("sheet B's motors together", np.r_[np.zeros(3), np.ones(3)], np.degrees(1.0)))
    out.append(("all six together", np.ones(6), np.degrees(1.0)))
    if workspace is not None:
        for ray, e in ray_directions(workspace).items():
            # least-norm motors moving the effector by 1 mm along the ray, its rotation free
            out.append((f"Fig. 5 ray {ray}", np.linalg.pinv(J[:3]) @ e, 1.0))
    return out


def ray_directions(workspace: Path) -> dict[int, np.ndarray]:
    """ray -> its unit direction in the effector's position space, from the study's points."""
    pts: dict[int, list] = {}
    with open(workspace / "workspace.csv") as f:
        for row in csv.DictReader(f):
            pts.setdefault(int(row["ray"]), []).append((int(row["step"]), float(row["x_mm"]), float(row["y_mm"]),
                                                        float(row["z_mm"])))
    out = {}
    for ray, p in sorted(pts.items()):
        p = np.array(sorted(p))
        if len(p) >= 2:
            d = p[-1, 1:] - p[0, 1:]
            out[ray] = d / np.linalg.norm(d)
    return out


def furthest(workspace: Path) -> dict[str, dict[int, float]]:
    """column -> ray -> the furthest valid reached point's distance from rest [mm]
    (the prediction's ``workspace.csv`` and the reproduction's beside it)."""
    out = {}
    for col, path in (("prediction", workspace / "workspace.csv"),
                      ("reproduction", workspace / "reproduction" / "workspace.csv")):
        if not path.is_file():
            continue
        rays: dict[int, list] = {}
        with open(path) as f:
            for row in csv.DictReader(f):
                rays.setdefault(int(row["ray"]), []).append(row)
        far = {}
        for ray, rows in rays.items():
            x = np.array([[float(r["x_mm"]), float(r["y_mm"]), float(r["z_mm"])] for r in rows])
            ok = np.array([r["reached"] == "1" and r["valid"] == "1" for r in rows])
            # the goals are relative to the effector's rest position
            far[ray] = float(np.linalg.norm(x[ok], axis=1).max()) if ok.any() else 0.0
        out[col] = far
    return out


def limits(robot, refs, sheets, strain_limit: float, workspace: Path | None, ray_contact_every: int = 0) -> list[dict]:
    from metasheet.robot.condensed import grip_motions_per_motor
    from metasheet.sheet.wall_limits import first_contact, travel_to_strain

    (Ka, wa, _), (Kb, wb, _) = sheets
    Ga, Gb, J = grip_motions_per_motor(Ka, Kb, robot, refs)
    fields = [wa.per_motor(Ga), wb.per_motor(Gb)]
    rows = []
    for name, d, unit in directions(J, workspace):
        row = {"direction": name, "unit": "deg" if unit != 1.0 else "mm"}
        for sign, label in ((1.0, "forward"), (-1.0, "backward")):
            per = []
            for walls, F in zip((wa, wb), fields):
                u = np.einsum("...im,m->...i", F, sign * d)
                t_strain = travel_to_strain(u, walls.h, walls.solid, strain_limit)[0]
                # a contact search costs about a minute on a print: only along the map's axes
                # and the rod's roll, and on a sheet whose own motors move
                t_contact = np.nan
                own = {"sheet A's motors together": (0,), "sheet B's motors together": (1,),
                       "all six together": (0, 1)}.get(name, ())
                if (ray_contact_every and name.startswith("Fig. 5 ray ") and sign > 0
                        and int(name.rsplit(" ", 1)[1]) % ray_contact_every == 0):
                    own = (0, 1)  # a ray's backward direction is another ray
                if len(per) in own:
                    t_search = t_strain if np.isfinite(t_strain) else np.radians(30.0) / np.linalg.norm(d)
                    t_contact = first_contact(walls.solid, walls.h, u, t_search)[0]
                per.append((t_strain * unit, t_contact * unit))
            row[label] = {"strain": [p[0] for p in per], "contact": [p[1] for p in per]}
        rows.append(row)
        print(f"  {name}: {row['forward']} {row['backward']}", file=sys.stderr, flush=True)
    return rows


def horns_turned(robot, refs, sheets, deg: float = 1.0) -> list[dict]:
    """Each sheet with its centre held and its three horns turned by ``deg``: the linear walls'
    largest principal strain and closest approach there, and the travel to the first contact
    [deg]: the loading of the nonlinear DNS in docs/printed-sheet.md ("Beyond rest"), to compare
    first order with it."""
    from metasheet.fem.voxel.gaps import closest_approach
    from metasheet.robot.condensed import robot_grip_maps
    from metasheet.sheet.wall_limits import first_contact, principal_range

    Ea, Eb = robot_grip_maps(robot, refs)
    out = []
    for (_, w, _), E, motors, lab in zip(sheets, (Ea, Eb), ((6, 7, 8), (9, 10, 11)), LABELS):
        q = E[:, list(motors)].sum(axis=1)  # per radian of the three horns, the rod held
        u = w.field(q)
        a = closest_approach(w.solid, w.h, np.radians(deg) * u)
        t, _ = first_contact(w.solid, w.h, u, np.radians(5.0))
        out.append({"sheet": lab, "deg": deg, "wall_strain": principal_range(np.radians(deg) * u, w.h, w.solid)[0],
                    "approach_mm": a.distance, "approach_rest_mm": a.rest_distance,
                    "contact_deg": float(np.degrees(t))})
    return out


def slice_map(robot, sheets, refs, strain_limit: float, n: int = 72) -> dict:
    """The walls' strain limit over the plane of sheet A's three motors together (x) and sheet
    B's (y): per direction angle, the travel [deg of each motor] at which either sheet's walls
    reach the limit, and the motor box's edges from rest [deg]."""
    from metasheet.robot.condensed import grip_motions_per_motor
    from metasheet.sheet.wall_limits import travel_to_strain

    (Ka, wa, _), (Kb, wb, _) = sheets
    Ga, Gb, _ = grip_motions_per_motor(Ka, Kb, robot, refs)
    fa, fb = wa.per_motor(Ga), wb.per_motor(Gb)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    travel = []
    for p in phi:
        d = np.r_[np.full(3, np.cos(p)), np.full(3, np.sin(p))]
        t = [travel_to_strain(np.einsum("...im,m->...i", F, d), w.h, w.solid, strain_limit)[0]
             for w, F in ((wa, fa), (wb, fb))]
        travel.append(np.degrees(min(t)))
    rest = np.array([s.rest_angle for s in robot.coupling.servos])
    box = [np.degrees(robot.angle_min - rest).tolist(), np.degrees(robot.angle_max - rest).tolist()]
    return {"phi": phi.tolist(), "travel_deg": travel, "box_deg": box}


def map_picture(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = res["map"]
    phi, t = np.array(m["phi"]), np.array(m["travel_deg"])
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    lo, hi = np.array(m["box_deg"])
    ax.add_patch(plt.Rectangle((lo[:3].max(), lo[3:].max()), hi[:3].min() - lo[:3].max(),
                               hi[3:].min() - lo[3:].max(), fill=False, ls="--", color="0.5",
                               label="the motor box (from rest)"))
    x, y = np.r_[t * np.cos(phi), t[0]], np.r_[t * np.sin(phi), 0.0]
    ax.fill(x, y, alpha=0.25, color="C0")
    ax.plot(x, y, color="C0", label=f"wall strain {res['strain_limit']:g} reached (first order)")
    for r in res["rows"]:
        for label, sign in (("forward", 1), ("backward", -1)):
            c = np.nanmin(r[label]["contact"])
            if r["direction"].startswith("sheet A") and np.isfinite(c):
                ax.plot(sign * c, 0, "rx")
            if r["direction"].startswith("sheet B") and np.isfinite(c):
                ax.plot(0, sign * c, "rx")
            if r["direction"].startswith("all six") and np.isfinite(c):
                ax.plot(sign * c, sign * c, "rx")
    ax.plot([], [], "rx", label="two walls touch (first order)")
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    ax.set_xlabel("sheet A's three motors from rest [deg]")
    ax.set_ylabel("sheet B's three motors from rest [deg]")
    ax.set_title(f"Where the printed walls' limits bind\n(seed {res['seed']}, {res['voxel_mm']:g} mm voxels)")
    ax.set_aspect("equal")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


def table(res: dict) -> str:
    lines = [f"First-order limits of the print (seed {res['seed']}, gauge {res['gauge']}, {res['voxel_mm']} mm voxels; "
             f"wall strain limit {res['strain_limit']}): travel at which each limit binds, sheet A / B "
             "(contact searched up to the strain limit's travel, inf: not before it; nan: not searched)", "",
             "| direction | unit | strain, forward | contact, forward | strain, backward | contact, backward |"
             + (" prediction reached | reproduction reached |" if res.get("furthest") else ""),
             "|---|---|---|---|---|---|" + ("---|---|" if res.get("furthest") else "")]
    far = res.get("furthest") or {}
    for r in res["rows"]:
        f, b = r["forward"], r["backward"]
        cells = [r["direction"], r["unit"]] + [" / ".join(f"{v:.3g}" for v in x[k])
                                               for x in (f, b) for k in ("strain", "contact")]
        if far and r["direction"].startswith("Fig. 5 ray "):
            ray = r["direction"].rsplit(" ", 1)[1]
            cells += [f"{far.get('prediction', {}).get(ray, float('nan')):.3g}",
                      f"{far.get('reproduction', {}).get(ray, float('nan')):.3g}"]
        elif far:
            cells += ["", ""]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "Each sheet with its centre held and its three horns turned by 1 deg (the nonlinear DNS's "
              "loading in docs/printed-sheet.md), first order:", "",
              "| sheet | largest wall strain | closest approach [mm] (at rest) | first contact [deg] |",
              "|---|---|---|---|"]
    for h in res.get("horns_turned", []):
        lines.append(f"| {h['sheet']} | {h['wall_strain']:.3f} | {h['approach_mm']:.3g} ({h['approach_rest_mm']:.3g}) "
                     f"| {h['contact_deg']:.3g} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (its stages' parent)")
    ap.add_argument("--voxel", type=float, default=0.25, help="voxel edge [mm]")
    ap.add_argument("--gauge", default="seed")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--cache", type=Path, required=True, help="folder keeping each solved sheet's fields")
    ap.add_argument("--strain-limit", type=float, default=0.3, help="the walls' largest principal strain [-]")
    ap.add_argument("--workspace", type=Path, default=None, help="a workspace stage's folder: Fig. 5's rays")
    ap.add_argument("--ray-contact-every", type=int, default=0, help="search the first contact on every K-th ray "
                    "too (forward, both sheets; 0: none): minutes per ray on a print")
    ap.add_argument("--only", choices=LABELS, default=None, help="solve this sheet into the cache and stop "
                    "(two processes solve the two sheets side by side)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--picture", type=Path, default=None, help="PNG of the map over sheet A's and B's motors")
    add_save_option(ap)
    args = ap.parse_args()
    if args.only:
        solved_walls(args.outputs, args.voxel, args.gauge, args.seed, args.cache, (args.only,))
        return
    robot, refs, sheets, seed = solved_walls(args.outputs, args.voxel, args.gauge, args.seed, args.cache)
    t0 = time.perf_counter()
    rows = limits(robot, refs, sheets, args.strain_limit, args.workspace, args.ray_contact_every)
    res = {"outputs": str(args.outputs), "voxel_mm": args.voxel, "gauge": args.gauge, "seed": seed,
           "strain_limit": args.strain_limit, "rows": rows, "solve": [s[2] for s in sheets],
           "limits_seconds": time.perf_counter() - t0,
           "furthest": ({c: {str(k): v for k, v in f.items()} for c, f in furthest(args.workspace).items()}
                        if args.workspace else None)}
    res["map"] = slice_map(robot, sheets, refs, args.strain_limit)
    res["horns_turned"] = horns_turned(robot, refs, sheets)
    if args.picture:
        map_picture(res, args.picture)
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))
    with saved_output(__file__, args.save):
        print(table(res))


if __name__ == "__main__":
    main()
