"""The printed sheets' own limits at first order: wall strain and self-contact over the motors
(issue 62, item 4; metasheet/sheet/wall_limits.py).

One print (both sheets, one foam seed) of a pipeline's outputs is solved as the linear voxel DNS
with the displacement of each unit grip motion (:func:`metasheet.sheet.dns.dns_sheet_walls`),
kept in ``--cache`` (float32 fields, resumable). The linear printed robot (the two sheets'
condensed stiffnesses, :func:`metasheet.robot.condensed.grip_motions_per_motor`) turns each
motor direction into the walls' field per radian; along it the travel at which

* the walls' largest principal strain reaches ``--strain-limit`` (forward and backward), and
* two walls first touch (searched up to the strain limit's travel: past it the model is out of
  its range anyway),

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


def solved_walls(outputs: Path, voxel: float, gauge: str, seed: int | None, cache: Path):
    """(robot, references, [(DnsSheet K, SheetWalls)] per label) from ``cache`` or solved now."""
    from metasheet.sheet.dns import SheetPrint, dns_sheet_walls
    from metasheet.sheet.grips import grip_references
    from metasheet.sheet.wall_limits import SheetWalls

    design, orient, material, robot, fields = _inputs(outputs)
    seed = design.seeds.seed if seed is None else seed
    cache.mkdir(parents=True, exist_ok=True)
    out = []
    for lab in LABELS:
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


def limits(robot, refs, sheets, strain_limit: float, workspace: Path | None) -> list[dict]:
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
                t_search = t_strain if np.isfinite(t_strain) else np.radians(30.0) / np.linalg.norm(d)
                t_contact = first_contact(walls.solid, walls.h, u, t_search)[0]
                per.append((t_strain * unit, t_contact * unit))
            row[label] = {"strain": [p[0] for p in per], "contact": [p[1] for p in per]}
        rows.append(row)
        print(f"  {name}: {row['forward']} {row['backward']}", file=sys.stderr, flush=True)
    return rows


def table(res: dict) -> str:
    lines = [f"First-order limits of the print (seed {res['seed']}, gauge {res['gauge']}, {res['voxel_mm']} mm voxels; "
             f"wall strain limit {res['strain_limit']}): travel at which each limit binds, sheet A / B "
             "(contact searched up to the strain limit's travel; inf: not before it)", "",
             "| direction | unit | strain, forward | contact, forward | strain, backward | contact, backward |"
             + (" | prediction reached | reproduction reached |" if res.get("furthest") else ""),
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
    ap.add_argument("--json", type=Path, default=None)
    add_save_option(ap)
    args = ap.parse_args()
    robot, refs, sheets, seed = solved_walls(args.outputs, args.voxel, args.gauge, args.seed, args.cache)
    t0 = time.perf_counter()
    rows = limits(robot, refs, sheets, args.strain_limit, args.workspace)
    res = {"outputs": str(args.outputs), "voxel_mm": args.voxel, "gauge": args.gauge, "seed": seed,
           "strain_limit": args.strain_limit, "rows": rows, "solve": [s[2] for s in sheets],
           "limits_seconds": time.perf_counter() - t0,
           "furthest": ({c: {str(k): v for k, v in f.items()} for c, f in furthest(args.workspace).items()}
                        if args.workspace else None)}
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))
    with saved_output(args, "wall_limits"):
        print(table(res))


if __name__ == "__main__":
    main()
