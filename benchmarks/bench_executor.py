"""Process-pool workers with their BLAS threads limited (cores // workers) against the
libraries' default (every worker as many threads as cores), on the paper's workspace rays.

Run (the pipeline's orient, material, robot and reduce outputs must exist, e.g. after
``metasheet run pipelines/paper.toml``; no thread variables set, so the workers start with
the libraries' defaults):

    python benchmarks/bench_executor.py [pipelines/paper.toml] [--out ROOT] [--rays 6] [--repeats 2]

Each repeat maps the same ``--rays`` workspace rays (reduced model, rotation tests, the full
model past the box: :func:`metasheet.studies.workspace.explore_ray`) over a fresh 2-worker
pool, limited then default, interleaved; prints the medians and their ratio.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path
from types import SimpleNamespace

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]


def ray_tasks(pipeline: str, out: str | None, n_rays: int) -> list:
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.stages import _studies
    from metasheet.pipeline.stages.workspace import settings_from
    from metasheet.serve.loading import find_outputs
    from metasheet.studies.model import MODELS
    from metasheet.studies.workspace import RayTask, domain_spec

    outputs = find_outputs(pipeline, out)
    p = load_pipeline(pipeline).params["workspace"]
    ctx = SimpleNamespace(params=p, name="workspace",
                          inputs={s: outputs.directory / s for s in ("orient", "material", "robot", "reduce")})
    settings = settings_from(p)
    spec = domain_spec(_studies.build_spec(ctx), settings)
    grid = _studies.grid_from(p)
    rest = MODELS.get(spec).rest_pose()
    rays = range(0, len(grid.directions), max(1, len(grid.directions) // n_rays))[:n_rays]
    return [RayTask(spec, settings, rest[:3] + grid.points[grid.ray_points(r)]) for r in rays]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pipeline", nargs="?", default=str(ROOT / "pipelines" / "paper.toml"))
    ap.add_argument("--out", default=None, help="output root the pipeline ran with")
    ap.add_argument("--rays", type=int, default=6)
    ap.add_argument("--repeats", type=int, default=2)
    add_save_option(ap)
    args = ap.parse_args()
    from metasheet.runtime.executor import THREAD_VARS, UNIT_THREADS, Executor
    from metasheet.studies.workspace import explore_ray

    set_vars = [v for v in THREAD_VARS if v in os.environ]
    if set_vars:
        raise SystemExit(f"unset {', '.join(set_vars)}: the default workers must start with the libraries' defaults")
    tasks = ray_tasks(args.pipeline, args.out, args.rays)
    cores = os.cpu_count() or 1
    runs = {"limited": [], "default": []}
    for _ in range(args.repeats):
        for name, threads in (("limited", None), ("default", cores)):
            t = time.perf_counter()
            Executor(workers=2, worker_threads=threads).map(explore_ray, tasks)
            runs[name].append(time.perf_counter() - t)
    lim, dft = statistics.median(runs["limited"]), statistics.median(runs["default"])
    with saved_output(__file__, args.save):
        print(f"\n{len(tasks)} workspace rays of {args.pipeline}, 2 workers, {cores} cores; medians of {args.repeats}\n")
        print("| workers' BLAS threads | wall [s] | ratio to limited |")
        print("|---|---|---|")
        print(f"| limited: {UNIT_THREADS} each | {lim:.1f} | 1.00 |")
        print(f"| default: {cores} each | {dft:.1f} | {dft / lim:.2f} |")


if __name__ == "__main__":
    main()
