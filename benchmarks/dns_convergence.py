"""The printed sheet's voxel DNS converged in the voxel size (issue 62, item 1).

One print (both sheets, one foam seed) of a pipeline's outputs (its ``cell`` (a Polyfoam
design), ``orient``, ``material``, ``printmap`` and ``robot`` stages: the paper pipeline's, or
printed-sheet.toml's) is built and solved on the robot's grips at each voxel size, as the
``sheet`` stage does (:func:`metasheet.sheet.dns.dns_sheet`). At each size: the 18 grip modes'
stiffness against the homogenised sheet (geometric mean, softest), the printed robot's rod roll
per motor degree and its six singular values (:func:`metasheet.studies.sheet_dns.dns_study`);
then each quantity's Richardson limit and observed order over the ladder
(:mod:`metasheet.studies.richardson`) and each size's error against that limit.

Each sheet at each size is kept in ``--cache`` (its 24 x 24 grip stiffness and the solve's
record) as soon as it is solved, so a stopped ladder resumes where it stopped; the finest
sizes take minutes to tens of minutes and GBs per sheet (docs/printed-sheet.md).

    OPENBLAS_NUM_THREADS=1 python benchmarks/dns_convergence.py --outputs outputs/paper \
        --voxels 0.3 0.25 0.2 0.175 --gauge seed --cache outputs/dns_ladder --json out.json --save

``--with-printed OUT/printed/printed.json`` takes the sizes the printed stage's ladder already solved
(the same seed and gauge) from its figures, so that only the finer sizes are solved here.
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

LABELS = ("normal", "mirrored")


def _inputs(outputs: Path):
    """(design, orient, material, robot, fields per label) of a pipeline's output folder."""
    from metasheet.cells.catalogue import parse_design
    from metasheet.pipeline.artefacts import read_cell_design, read_material, read_orient, read_robot_scene
    from metasheet.robot.builder import six_dof_robot
    from metasheet.sheet.printed_foam import printmap_fields

    design = parse_design(read_cell_design(outputs / "cell"), source="cell.json design")
    orient = read_orient(outputs / "orient")
    material = read_material(outputs / "material")
    sc = read_robot_scene(outputs / "robot")
    mass = {"sheet_mass_g": sc.sheet_mass_g} if sc.sheet_mass_g else {"density": material.density}
    robot = six_dof_robot(orient.sheets(), model=material.model, rod_length=sc.rod_length,
                          geometry=sc.servo_geometry(), gravity=sc.gravity, **mass)
    info = json.loads((outputs / "printmap" / "printmap.json").read_text())
    fields = {lab: printmap_fields(info, lab, {p.name: p.read_text()
                                               for p in sorted((outputs / "printmap" / lab).glob("*.txt"))})
              for lab in LABELS}
    return design, orient, material, robot, fields


def _solved(cache: Path, spec):
    """The :class:`~metasheet.sheet.dns.DnsSheet` of ``spec``: from ``cache`` when kept there,
    else solved now and kept (written to a temporary name, then renamed)."""
    from metasheet.sheet.dns import DnsSheet, dns_sheet

    path = cache / f"{spec.gauge}-{spec.voxel_mm:g}mm-{spec.label}-seed{spec.seed}.json"
    if path.is_file():
        d = json.loads(path.read_text())
        return DnsSheet(np.asarray(d.pop("K"), float), **{k: tuple(v) if isinstance(v, list) else v
                                                           for k, v in d.items()})
    t0 = time.perf_counter()
    s = dns_sheet(spec)
    print(f"  solved {path.name}: {s.n_dof:,} unknowns, {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(s.to_dict()))
    os.replace(tmp, path)
    return s


def ladder(outputs: Path, voxels, gauge: str, seed: int | None, cache: Path, length_scale: float = 50.0,
           labels=LABELS, extra_rows=(), max_voxels: int = 20_000_000) -> dict | None:
    """Per voxel size the print's numbers, and each quantity's Richardson fit over the sizes (and
    ``extra_rows``' sizes: rows already computed, the printed stage's ladder); None when
    ``labels`` is one sheet only (its solves are kept in ``cache`` for a later run)."""
    from threadpoolctl import threadpool_limits

    from metasheet.sheet.dns import SheetPrint
    from metasheet.studies.dns_ladder import ladder_fits, ladder_row
    from metasheet.studies.sheet_dns import homogenised_grips

    design, orient, material, robot, fields = _inputs(outputs)
    solid = design.material.material().stiffness()
    seed = design.seeds.seed if seed is None else seed
    with threadpool_limits(limits=1, user_api="blas"):
        hom = homogenised_grips(orient.sheets(), material.model)
    cache.mkdir(parents=True, exist_ok=True)
    rows = []
    for v in sorted(voxels, reverse=True):  # coarse first: the first numbers come soon
        sheets = [_solved(cache, SheetPrint(lab, seed, gauge, float(v), design, orient.sheet_params, fields[lab],
                                            solid, max_voxels=max_voxels)) for lab in labels]
        if tuple(labels) != LABELS:
            continue
        with threadpool_limits(limits=1, user_api="blas"):
            row = ladder_row(v, sheets, hom, robot, orient.sheet_params, length_scale=length_scale)
        rows.append({**row, "seconds": [s.build_s + s.solve_s for s in sheets]})
    if tuple(labels) != LABELS:
        return None
    rows = sorted(rows + [r for r in extra_rows if r["voxel_mm"] not in voxels], key=lambda r: -r["voxel_mm"])
    out = {"outputs": str(outputs), "gauge": gauge, "seed": seed, "rows": rows, "homogenised": rows[-1]["homogenised"]}
    fits = ladder_fits(rows)
    if fits:
        out["richardson"] = fits
    return out


def _seconds(row: dict) -> str:
    return ", ".join(f"{t:.0f}" for t in row["seconds"]) if "seconds" in row else "(the pipeline's)"


def _printed_rows(path: Path, gauge: str, seed: int | None) -> list[dict]:
    """The ladder rows of a printed stage's ``printed.json`` (its ``ladder``), checked for the gauge
    and the seed asked."""
    d = json.loads(path.read_text()).get("ladder")
    if not d:
        raise SystemExit(f"{path}: no ladder (the printed stage's ladder key was empty)")
    if d["gauge"] != gauge or (seed is not None and d["seed"] != seed):
        raise SystemExit(f"{path}: its ladder is seed {d['seed']}, gauge {d['gauge']!r}; asked seed {seed}, {gauge!r}")
    return d["rows"]


def table(res: dict) -> str:
    lines = [f"One print (seed {res['seed']}, gauge {res['gauge']!r}) of `{res['outputs']}`, both sheets at each "
             "voxel size; ratios printed over homogenised.", "",
             "| voxel [mm] | unknowns (normal, mirrored) | held by the grips | CG iterations | time [s] "
             "| geometric mean (n, m) | softest mode (n, m) | rod roll [deg/deg] | singular values [mm/deg] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        lines.append(f"| {r['voxel_mm']:g} | {r['unknowns'][0]:,}, {r['unknowns'][1]:,} "
                     f"| {r['kept_share'][0]:.4f}, {r['kept_share'][1]:.4f} | {r['iterations'][0]}, {r['iterations'][1]} "
                     f"| {_seconds(r)} "
                     f"| {r['geometric_mean_ratio'][0]:.3f}, {r['geometric_mean_ratio'][1]:.3f} "
                     f"| {r['softest_ratio'][0]:.4f}, {r['softest_ratio'][1]:.4f} | {r['rod_roll']:+.4f} "
                     f"| {' '.join(f'{s:.3g}' for s in r['singular_values'])} |")
    hom = res["homogenised"]
    lines.append(f"| homogenised | | | | | 1 | 1 | {hom['rod_roll']:+.4f} "
                 f"| {' '.join(f'{s:.3g}' for s in hom['singular_values'])} |")
    if "richardson" in res:
        sizes = ", ".join(f"{r['voxel_mm']:g}" for r in res["rows"])
        lines += ["", f"Richardson limit over the ladder; error of each size ({sizes} mm) against it:", "",
                  "| quantity | limit | order | orders of each triple | error at each size |", "|---|---|---|---|---|"]
        for k, f in res["richardson"].items():
            order = "-" if f["order"] is None else f"{f['order']:.2f}"
            triples = ", ".join("-" if t is None else f"{t:.2f}" for t in f["triple_orders"])
            errs = ", ".join(f"{100 * e:+.1f} %" for e in f["relative_errors"])
            lines.append(f"| {k} | {f['limit']:.4g} | {order} | {triples} | {errs} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (cell, orient, "
                    "material, printmap, robot)")
    ap.add_argument("--voxels", type=float, nargs="+", default=[0.3, 0.25, 0.2], help="voxel sizes [mm]")
    ap.add_argument("--gauge", choices=("seed", "point"), default="seed")
    ap.add_argument("--seed", type=int, default=None, help="foam seed (default: the cell design's)")
    ap.add_argument("--cache", type=Path, required=True, help="folder keeping each solved sheet (resume)")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers as JSON")
    ap.add_argument("--labels", nargs="+", choices=LABELS, default=list(LABELS),
                    help="solve these sheets only and keep them in --cache (two processes, one sheet each; "
                         "a run with both then reads them)")
    ap.add_argument("--with-printed", type=Path, default=None, help="a printed stage's printed.json: its ladder's "
                    "rows join the ones solved here (same seed and gauge), for the fits over both")
    ap.add_argument("--max-voxels", type=int, default=20_000_000, help="the grid's cap (0.15 mm: 21 million "
                    "voxels on the paper's sheet)")
    add_save_option(ap)
    args = ap.parse_args()
    extra = _printed_rows(args.with_printed, args.gauge, args.seed) if args.with_printed else ()
    res = ladder(args.outputs, args.voxels, args.gauge, args.seed, args.cache, labels=tuple(args.labels),
                 extra_rows=extra, max_voxels=args.max_voxels)
    if res is None:
        return
    if args.json is not None:
        args.json.write_text(json.dumps(res, indent=1))
    with saved_output(__file__, args.save):
        print(table(res))


if __name__ == "__main__":
    main()
