"""Benchmark: the grips' condensed stiffness on printed foam, trilinear against split coarsening.

The printed Polyfoam of ``cells/paper_polyfoam.toml`` (uniform fields: infill 15 %, shrink 0.2,
angle 0; :func:`metasheet.sheet.printed_foam.printed_foam`) at 0.3 mm voxels, its solid brush tied
to rigid grips, condensed onto their 6 B rigid dofs by
:func:`metasheet.sheet.voxel_grips.rigid_bodies_stiffness` (nothing clamped: 6 (B - 1) columns).

- patch (default): ``box_region`` of ``--patch-mm`` x ``--patch-mm`` x 5 mm, its 3 mm ends solid
  brush, one grip each (B = 2);
- sheet (``--sheet``): the paper's tripod sheet, 373 x 431 x 17 voxels, four grips: the arm-end
  tabs (tags 1 to 3 of ``geometry.attach_tags``, bodies 0 to 2) and the centre ring (tag 4, body 3),
  each about its nominal centre.

Measured (one numba thread, 2 shared cores, rtol 1e-8): the patch 523 CG iterations and 102 s
trilinear, 31 and 5.8 s split (K within 3e-10); the sheet (787,224 unknowns, 18 columns) 51
iterations, 208 s, 2.1 GB split, while trilinear stalled at a relative residual of 1.1e-6 after 450
iterations (1,497 s, 2.4 GB): the sheet's default row is split only (``--sheet-coarsenings``).

Every row runs in a fresh subprocess, so its peak memory (ru_maxrss, the foam's build included)
is its own. "K vs trilinear": relative Frobenius distance of K to the trilinear row's.

    python benchmarks/bench_voxel_grips.py                 # the 30 mm patch, both coarsenings (~1 min)
    python benchmarks/bench_voxel_grips.py --sheet [--save]
"""

import metasheet  # noqa: F401  (before numpy: it pins numpy's CPU code paths, metasheet.runtime.cpu)

# isort: split
import argparse
import json
import os
import resource
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "cells" / "paper_polyfoam.toml"


def _design():
    from metasheet.cells.catalogue import parse_design

    data = tomllib.loads(DESIGN.read_text())
    return parse_design(data, overrides={}, source=str(DESIGN)), data["material"]


class _Ends:
    """The patch's solid brush: x within ``grip`` [mm] of either end of [lo, hi] (picklable)."""

    def __init__(self, lo: float, hi: float, grip: float):
        self.lo, self.hi, self.grip = lo, hi, grip

    def __call__(self, points):
        x = np.asarray(points)[:, 0]
        return (x <= self.lo + self.grip) | (x >= self.hi - self.grip)


def grip_bodies(tags: np.ndarray) -> np.ndarray:
    """(nx + 1, ny + 1, nz + 1) int bodies of the nodes from voxel tags (nx, ny, nz) int (0: none,
    b >= 1: grip b): every node of a tagged voxel takes its tag."""
    nx, ny, nz = tags.shape
    bodies = np.zeros((nx + 1, ny + 1, nz + 1), np.int64)
    for a in range(8):
        o = (a & 1, (a >> 1) & 1, (a >> 2) & 1)
        view = bodies[o[0]:o[0] + nx, o[1]:o[1] + ny, o[2]:o[2] + nz]
        np.maximum(view, tags, out=view)
    return bodies


def build(case: str, patch_mm: float):
    """(foam, bodies (N) int, references (B, 3) [mm, grid frame])."""
    from metasheet.sheet import printed_foam as pf
    from metasheet.sheet.geometry import ARM_ANGLES, SheetParams, attach_tags

    design, _ = _design()
    fields = pf.FoamFields(15.0, 0.2, 0.0)
    if case == "patch":
        lo, hi = np.array([0.0, 0.0, -2.5]), np.array([patch_mm, patch_mm, 2.5])
        foam = pf.printed_foam(pf.box_region(lo, hi, _Ends(0.0, patch_mm, 3.0)), fields, design, voxel_mm=0.3)
        brush = foam.region == pf.BRUSH
        tags = np.where(brush, 1 + (foam.centres(0) > 0.5 * patch_mm)[:, None, None], 0)
        bodies = grip_bodies(tags)
        h = foam.voxel_mm
        refs = np.array([np.argwhere(bodies == b).mean(axis=0) * h for b in (1, 2)])
        return foam, bodies, refs
    params = SheetParams()
    foam = pf.printed_foam(pf.tripod_region(params), fields, design, voxel_mm=0.3)
    brush = foam.region == pf.BRUSH
    centres = np.stack(np.meshgrid(*(foam.centres(d) for d in range(3)), indexing="ij"), -1)[brush]
    tags = np.zeros(foam.phases.shape, np.int64)
    tags[brush] = attach_tags(centres, params)
    nominal = [[params.reach * np.cos(a), params.reach * np.sin(a), 0.0] for a in ARM_ANGLES] + [[0.0, 0.0, 0.0]]
    return foam, grip_bodies(tags), np.array(nominal) - foam.origin


def one(case: str, coarsening: str, rtol: float, patch_mm: float, relative: bool) -> dict:
    """Child process: build the foam, condense onto the grips, return the row."""
    from metasheet.sheet.voxel_grips import rigid_bodies_stiffness
    from metasheet.mechanics.material import Isotropic

    t = time.perf_counter()
    foam, bodies, refs = build(case, patch_mm)
    built = time.perf_counter() - t
    mat = _design()[1]
    ph = foam.phases.astype(np.int64)
    r = rigid_bodies_stiffness(ph, foam.size, {1: Isotropic(float(mat["E"]), float(mat["nu"])).stiffness()},
                               bodies=bodies, references=refs, rtol=rtol, coarsening=coarsening, relative=relative)
    return {"grid": list(ph.shape), "solid": int((ph > 0).sum()), "kept": r.kept_share, "dofs": r.n_dof,
            "columns": len(r.iterations), "iters": max(r.iterations), "build": built, "setup": r.setup_seconds,
            "solve": r.seconds - r.setup_seconds, "levels": len(r.levels), "asym": r.asymmetry,
            "coarsening": r.coarsening, "K": r.K.tolist(),
            "peak_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


def run_child(case, coarsening, args) -> dict:
    cmd = [sys.executable, __file__, "--one", case, coarsening, "--rtol", str(args.rtol), "--patch-mm",
           str(args.patch_mm)] + (["--all-columns"] if args.all_columns else [])
    try:
        p = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=args.timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout {args.timeout:.0f} s"}
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["?"])[-1][:90]}
    return json.loads(p.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sheet", action="store_true", help="add the full tripod sheet at 0.3 mm (four grips)")
    ap.add_argument("--only-sheet", action="store_true", help="the sheet rows only")
    ap.add_argument("--coarsenings", nargs="*", default=["trilinear", "split"], help="the patch's rows")
    ap.add_argument("--sheet-coarsenings", nargs="*", default=["split"],
                    help="the sheet's rows (trilinear: residual 1.1e-6 after 450 iterations, 25 min; see the doc)")
    ap.add_argument("--patch-mm", type=float, default=30.0, help="the patch's side [mm]")
    ap.add_argument("--rtol", type=float, default=1e-8)
    ap.add_argument("--all-columns", action="store_true", help="solve all 6 B columns (default 6 (B - 1))")
    ap.add_argument("--timeout", type=float, default=3600.0, help="per row [s]")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    add_save_option(ap)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one[0], args.one[1], args.rtol, args.patch_mm, not args.all_columns)))
        return
    cases = ([] if args.only_sheet else ["patch"]) + (["sheet"] if args.sheet or args.only_sheet else [])
    with saved_output(__file__, args.save):
        print(f"cores={os.cpu_count()} NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', '-')} "
              f"rtol={args.rtol:g} columns={'6 B' if args.all_columns else '6 (B - 1)'}\n")
        print("| case | coarsening | grid | solid voxels | kept | unknowns | columns | levels | CG iterations "
              "| build s | setup s | solve s | peak GB | K vs trilinear |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for case in cases:
            ref = None
            name = f"patch {args.patch_mm:g} mm" if case == "patch" else "tripod sheet"
            for c in (args.coarsenings if case == "patch" else args.sheet_coarsenings):
                r = run_child(case, c, args)
                if "error" in r:
                    print(f"| {name} | {c} | failed: {r['error']} |" + " |" * 11, flush=True)
                    continue
                K = np.array(r["K"])
                ref = K if r["coarsening"] == "trilinear" and ref is None else ref
                err = f"{np.linalg.norm(K - ref) / np.linalg.norm(ref):.1e}" if ref is not None else "-"
                print(f"| {name} | {r['coarsening']} | {' x '.join(map(str, r['grid']))} | {r['solid']:,} | "
                      f"{r['kept']:.4f} | {r['dofs']:,} | {r['columns']} | {r['levels']} | {r['iters']} | "
                      f"{r['build']:.1f} | {r['setup']:.1f} | {r['solve']:.1f} | {r['peak_gb']:.2f} | {err} |",
                      flush=True)
        print("\nCG iterations: the most over the solved columns (one block PCG). setup: pieces, hierarchy, "
              "right-hand sides; solve: CG and reactions. peak GB: the row's process (foam build included).")


if __name__ == "__main__":
    main()
