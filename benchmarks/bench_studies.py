"""Workspace-study timing: time per goal point on the paper's mesh and a coarse one, 1 vs 2 workers.

    python benchmarks/bench_studies.py [--meshes 5 14] [--rays 6] [--steps 4] [--repeats 1]

Runs the workspace study (point reach + the six +-10 deg rotation trials per point,
continuity off) on the analytic stand-in and on the FEM robot (the paper's sheet at each
``--meshes`` size [mm]; 5 mm is the paper's 2 x 2,909 tets), serially and on a process pool
of 2, in this process; prints one table with medians, the speed-up of 2 workers against 1,
the FEM work per point (fresh linearisations, control steps) and the full Fig. 5 study
(1,798 points, 2 workers) extrapolated from the per-point time; the target is 15 minutes.
The grid is the default grid's inner part (points at 1/4 .. 4/4 of ``--extent`` mm); the
default study's outer points fail more often, and a failing point costs more (stalls).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

from metasheet.runtime.executor import Executor
from metasheet.studies.adapter import paper_robot_spec
from metasheet.studies.grid import star_grid
from metasheet.studies.model import MODELS
from metasheet.studies.standin import StandInSpec
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace

from _results import add_save_option, saved_output

FULL_POINTS = 1798


def timed(spec, grid, settings, executor, repeats):
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = explore_workspace(spec, grid, settings, executor=executor)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", type=float, nargs="+", default=[5.0, 14.0], help="sheet tet sizes [mm]")
    ap.add_argument("--rays", type=int, default=6, help="azimuth directions (one elevation ring + 2 rod rays)")
    ap.add_argument("--steps", type=int, default=4, help="points per ray")
    ap.add_argument("--extent", type=float, default=10.0, help="grid reach [mm]")
    ap.add_argument("--repeats", type=int, default=1)
    add_save_option(ap)
    a = ap.parse_args()
    grid = star_grid(n_azimuth=a.rays, n_elevation=1, n_steps=a.steps, extent_axial=0.8 * a.extent,
                     extent_lateral=a.extent, thin_below=0.0)
    s = WorkspaceSettings(continuity=False)
    n = len(grid)
    with saved_output(__file__, a.save):
        print(f"python {platform.python_version()}, {os.cpu_count()} cpus, OPENBLAS_NUM_THREADS="
              f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, load average {os.getloadavg()[0]:.1f}; grid: {n} points "
              f"on {len(grid.directions)} rays; rotations on, continuity off; max_steps {s.max_steps}")
        rows = []
        cases = [("stand-in", StandInSpec(), "")]
        for h in a.meshes:
            spec = paper_robot_spec(mesh_size=h)
            cases.append((f"FEM {h:g} mm", spec, f"{len(spec.tets)} tets/sheet"))
        print("| robot | mesh | workers | median wall [s] | per point [ms] | fresh lin. / point | steps / point "
              "| reached | rot. axes ok | speed-up vs 1 | full study, 2 workers [min] |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for name, spec, mesh in cases:
            base = None
            for workers in (1, 2):
                work = ""
                if workers == 1 and name != "stand-in":
                    m = MODELS.get(spec)  # serial runs use this process's model: count its work
                    f0, st0 = m.lz.factorizations, m.ctrl.total_steps
                t, res = timed(spec, grid, s, Executor(workers=workers), a.repeats)
                if workers == 1 and name != "stand-in":
                    work = (f"{(m.lz.factorizations - f0) / (n * a.repeats):.1f} | "
                            f"{(m.ctrl.total_steps - st0) / (n * a.repeats):.1f}")
                else:
                    work = "- | -"
                base = base or t
                full = FULL_POINTS * t / n / 60 if workers == 2 else float("nan")
                rows.append((name, workers, t))
                print(f"| {name} | {mesh} | {workers} | {t:.2f} | {1e3 * t / n:.0f} | {work} | "
                      f"{int(res.records.reached.sum())}/{n} | {int(res.records.rot_ok.sum())}/{3 * n} | {base / t:.2f} | "
                      + ("-" if workers == 1 else f"{full:.1f}") + " |")
        print(f"\nfull study = {FULL_POINTS} x (2-worker time per point); target 15 min. Per-point cost grows "
              "outwards (more failures, stalls), so the inner-grid figure is a lower bound.")


if __name__ == "__main__":
    main()
