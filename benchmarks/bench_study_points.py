"""Study cost per workspace point, each column of a finished pipeline run: CPU s per point with
and without the memos of linearisations and strains (:mod:`metasheet.robot.memo`), interleaved in one process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_study_points.py --out /tmp/run_out \\
        [--pipeline pipelines/paper.toml] [--rays 0 1 24] [--repeats 3]

Builds each column's robot the way the workspace stage does (``build_spec`` on the run's
orient, material, robot and reduce outputs: the prediction through the reduced model within
the strain limit, the reproduction on the full P1 model), then runs ``explore_ray`` (the point
reach and the rotation tries of each point) on the ``--rays`` of the paper grid, on a fresh
model per repeat, memo off then on; the first ray listed only warms the model (numba, the
rest state) and is not timed. Prints the median CPU s per tried point, the fresh linearisations
per point (full and reduced model) and whether both modes gave the same records, bit for bit.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import metasheet  # noqa: F401  (pins the BLAS code paths before numpy)
import numpy as np

from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages._studies import build_spec, grid_from
from metasheet.pipeline.stages.workspace import settings_from
from metasheet.studies.model import MODELS
from metasheet.studies.workspace import PointRecords, RayTask, domain_spec, explore_ray

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]


def ray_tasks(pipeline: Path, out: Path, column: str) -> list[RayTask]:
    """The workspace stage's rays of ``column`` on the outputs in ``out`` (one per grid ray)."""
    pl = load_pipeline(pipeline)
    p = pl.params["workspace"].for_column(column)
    inputs = {k: out / pl.name / k for k in ("orient", "material", "robot", "reduce")}
    ctx = StageContext("workspace", p, out / ".bench", inputs, pipeline.parent, column=column)
    grid, settings = grid_from(p), settings_from(p)
    spec = domain_spec(build_spec(ctx), settings)
    rest = MODELS.get(spec).rest_pose()
    return [RayTask(spec, settings, rest[:3] + grid.points[grid.ray_points(r)]) for r in range(len(grid.directions))]


def linearizers(model) -> list:
    """The model's linearizers: its own, and the full model's behind a reduced one."""
    full = getattr(model, "full", None)
    return [model.lz] + ([full.lz] if full is not None else [])


def memos(model) -> list:
    """Every memo of the model: its linearizers' and its strains' (the full model's behind a reduced one)."""
    full = getattr(model, "full", None)
    return [lz.memo for lz in linearizers(model)] + [m._strains for m in (model, full) if m is not None]


def run(tasks: list[RayTask], rays: list[int], memo: bool) -> tuple[float, int, list, PointRecords | None]:
    """(CPU s, points tried, fresh linearisations per linearizer, records) of ``rays[1:]`` on a fresh model."""
    MODELS.clear()
    model = MODELS.get(tasks[0].spec)
    for m in memos(model):
        m.size = m.size if memo else 0
    explore_ray(tasks[rays[0]])  # warm-up
    lzs = linearizers(model)
    f0 = [lz.factorizations - lz.memo.hits for lz in lzs]
    t0 = time.process_time()
    recs = [explore_ray(tasks[r]) for r in rays[1:]]
    cpu = time.process_time() - t0
    n = sum(int(r.tried.sum()) for r in recs)
    fresh = [lz.factorizations - lz.memo.hits - f for lz, f in zip(lzs, f0)]
    return cpu, n, fresh, recs


def same(a: list[PointRecords], b: list[PointRecords]) -> bool:
    return all(np.array_equal(getattr(x, f), getattr(y, f), equal_nan=True)
               for x, y in zip(a, b) for f in PointRecords.__dataclass_fields__)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pipeline", default=str(ROOT / "pipelines" / "paper.toml"))
    ap.add_argument("--out", required=True, help="the finished run's outputs folder (its --out)")
    ap.add_argument("--columns", nargs="+", default=["prediction", "reproduction"])
    ap.add_argument("--rays", type=int, nargs="+", default=[2, 0, 1, 24], help="warm-up ray, then the timed ones")
    ap.add_argument("--repeats", type=int, default=3)
    add_save_option(ap)
    a = ap.parse_args()
    rows = []
    for col in a.columns:
        tasks = ray_tasks(Path(a.pipeline).resolve(), Path(a.out).resolve(), col)
        res = {False: [], True: []}
        for _ in range(a.repeats):
            for memo in (False, True):  # interleaved: the machine's load hits both alike
                res[memo].append(run(tasks, a.rays, memo))
        ident = all(same(res[False][0][3], r[3]) for r in res[False] + res[True])
        for memo in (False, True):
            cpu = statistics.median(r[0] for r in res[memo])
            n = res[memo][0][1]
            fresh = " + ".join(f"{f / n:.2f}" for f in res[memo][0][2])
            rows.append((col, "on" if memo else "off", n, cpu / n, fresh, ident))
    with saved_output(__file__, a.save):
        print(f"{os.cpu_count()} cpus, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
              f"load {os.getloadavg()[0]:.1f}; rays {a.rays[1:]} after warm-up ray {a.rays[0]}; "
              f"median of {a.repeats}, memo off / on interleaved")
        print("| column | memo | points | CPU s / point | fresh linearisations / point (model + full) | same records |")
        print("|---|---|---|---|---|---|")
        for col, memo, n, per, fresh, ident in rows:
            print(f"| {col} | {memo} | {n} | {per:.3f} | {fresh} | {ident} |")


if __name__ == "__main__":
    main()
