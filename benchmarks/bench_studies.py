"""Workspace-study timing: time per goal point, and the speed-up of 2 workers against 1.

    python benchmarks/bench_studies.py [--mesh-size 14] [--rays 8] [--steps 4] [--repeats 1]

Runs the workspace study (reach + 6 rotations per point, continuity off) on the analytic
stand-in and on the FEM robot (the paper's sheet at ``--mesh-size``), serially and on a
process pool of 2, in this process; prints medians and the ratio. The full Fig. 5 study
(1,798 points) is extrapolated from the per-point time; its target is 15 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time


from metasheet.executor import Executor
from metasheet.studies.adapter import paper_robot_spec
from metasheet.studies.grid import star_grid
from metasheet.studies.standin import StandInSpec
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace


def timed(spec, grid, settings, executor, repeats):
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = explore_workspace(spec, grid, settings, executor=executor)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh-size", type=float, default=14.0, help="sheet tet size [mm]")
    ap.add_argument("--rays", type=int, default=8, help="azimuth directions (one elevation ring + 2 rod rays)")
    ap.add_argument("--steps", type=int, default=4, help="points per ray")
    ap.add_argument("--repeats", type=int, default=1)
    a = ap.parse_args()
    grid = star_grid(n_azimuth=a.rays, n_elevation=1, n_steps=a.steps, extent_axial=8.0, extent_lateral=10.0,
                     thin_below=0.0)
    s = WorkspaceSettings(continuity=False, max_steps=30)
    print(f"python {platform.python_version()}, {os.cpu_count()} cpus, OPENBLAS_NUM_THREADS="
          f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, load average {os.getloadavg()[0]:.1f}; grid: {len(grid)} points on "
          f"{len(grid.directions)} rays; rotations on, continuity off")
    fem = paper_robot_spec(mesh_size=a.mesh_size, rest_deg=75.0)
    print(f"FEM robot: {len(fem.tets)} tets per sheet (mesh size {a.mesh_size} mm)")
    print(f"| robot | workers | median wall [s] | per point [ms] | points reached | speed-up vs 1 |")
    print("|---|---|---|---|---|---|")
    for name, spec in (("stand-in", StandInSpec()), ("FEM", fem)):
        base = None
        for workers in (1, 2):
            t, res = timed(spec, grid, s, Executor(workers=workers), a.repeats)
            base = base or t
            print(f"| {name} | {workers} | {t:.2f} | {1e3 * t / len(grid):.1f} | {int(res.records.reached.sum())} "
                  f"| {base / t:.2f} |")
            if name == "FEM" and workers == 2:
                full = 1798 * t / len(grid) / 60
                print(f"\nextrapolated full Fig. 5 study (1,798 points, 2 workers): {full:.1f} min "
                      f"(target 15 min); note: per-point cost grows with the points' distance (stalls)")


if __name__ == "__main__":
    main()
