"""Mesh convergence of the 6-DOF robot, P1 vs P2 sheets (issue 14).

Run: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_convergence.py [--material published]
         [--p1 10 7 5 3.5 2.5] [--p2 14 10 7 5 3.5 2.5] [--graded 3 2 1.4 1 0.7]
         [--graded-h 10] [--layers 0] [--json out.json]

Builds the paper's robot (spiral 45 deg, the published foam or another material) on each
mesh, measures singular values, rod rotation per degree, rod compliance and gravity sag at
the rest equilibrium (:mod:`metasheet.robot.convergence`), fits ``q = q_inf + c h^p`` per
element, and prints one table: each mesh's figures, its seconds (build + solve) and its
errors against the P2 limit. ``--json`` keeps the raw results (with wall times: a benchmark
file, not a pipeline artefact).
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np

from metasheet.published import paper
from metasheet.mechanics.material import Isotropic
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.convergence import Level, convergence_summary, run_levels
from metasheet.sheet.geometry import SheetParams

from _results import add_save_option, saved_output

MATERIALS = {"published": paper.PAPER_FOAM, "silicone": paper.SILICONE,
             "isotropic-foam": Isotropic(paper.PAPER_FOAM.E_t, paper.PAPER_FOAM.nu_t)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--material", choices=sorted(MATERIALS), default="published")
    ap.add_argument("--p1", type=float, nargs="*", default=[10.0, 7.0, 5.0, 3.5, 2.5])
    ap.add_argument("--p2", type=float, nargs="*", default=[14.0, 10.0, 7.0, 5.0, 3.5, 2.5])
    ap.add_argument("--graded", type=float, nargs="*", default=[3.0, 2.0, 1.4, 1.0, 0.7],
                    help="grip sizes [mm] of the P2 sequence graded towards the grips")
    ap.add_argument("--graded-h", type=float, default=10.0, help="mesh size away from the grips [mm]")
    ap.add_argument("--layers", type=int, default=0, help="elements through the thickness (0: free mesh)")
    ap.add_argument("--pitch", type=float, default=45.0)
    ap.add_argument("--json", default=None)
    add_save_option(ap)
    a = ap.parse_args()
    mat = MATERIALS[a.material]

    def build(lev: Level):
        sheets = SheetPair.spiral(SheetParams(mesh_size=lev.mesh_size, layers=lev.layers,
                                              grip_size=lev.grip_size), lev.element,
                                  pitch_deg=a.pitch)
        return six_dof_robot(sheets, mat, density=paper.FOAM_DENSITY)

    levels = ([Level("p1", h, a.layers) for h in a.p1] + [Level("p2", h, a.layers) for h in a.p2]
              + [Level("p2", a.graded_h, a.layers, g) for g in a.graded])
    results = run_levels(build, levels, progress=lambda d, i, n: print(f"[{i + 1}/{n}] {d}", flush=True))
    with saved_output(__file__, a.save, fenced=True):
        summary = convergence_summary(results)
        print(f"\nmaterial {a.material}, load {os.getloadavg()[0]:.1f}, OPENBLAS_NUM_THREADS="
              f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; errors against the "
              f"{summary['reference']} limit\n")
        head = ("mesh", "tets", "dofs", "s", "sv max", "sv min", "rod deg/deg", "rod mm/N", "sag mm",
                "err J", "err W_rod")
        print(" | ".join(f"{h:>12}" for h in head))
        for r, row in zip(results, summary["levels"]):
            e = row["errors"]
            cells = (r.level.label, r.tets, r.dofs, f"{r.seconds:.1f}", f"{r.singular_values[0]:.3f}",
                     f"{r.singular_values[-1]:.3f}", f"{r.rod_rotation_deg_per_deg:.4f}",
                     f"{r.rod_compliance_mm_per_N:.3f}", f"{r.gravity_sag_mm:.4f}",
                     f"{100 * e['jacobian']:.2f} %", f"{100 * e['rod_compliance']:.2f} %")
            print(" | ".join(f"{c:>12}" for c in cells))
        for fam, lim in summary["limits"].items():
            v = lim["limits"]
            print(f"\n{fam} limit: sv {np.round(v['singular_values'], 3).tolist()}, rod {v['rod_rotation_deg_per_deg']:.4f} "
                  f"deg/deg, W_rod {v['rod_compliance_mm_per_N']:.3f} mm/N, sag {v['gravity_sag_mm']:.4f} mm; "
                  f"orders {({k: round(o, 2) for k, o in lim['fitted_orders'].items()})}")
    if a.json:
        for row, r in zip(summary["levels"], results):
            row["seconds"] = r.seconds
        with open(a.json, "w") as fh:
            json.dump(summary, fh, indent=1)


if __name__ == "__main__":
    main()
