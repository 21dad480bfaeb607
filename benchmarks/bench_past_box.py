"""Past the reduced model's training box: the reduced model carrying a reach on (``past_box =
"reduced"``) against the full model from the box's edge (``"full"``), on a finished run's
prediction column.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_past_box.py --out OUT \\
        [--pipeline pipelines/paper.toml] [--studies workspace ranges] [--workers 2] [--save]

``OUT`` holds a run of the stages up to ``reduce`` (``metasheet run pipelines/paper.toml --stage
reduce --out OUT``). Every ray of the workspace and ranges studies' prediction column is run in
both modes, the two modes' tasks interleaved on a pool of ``--workers`` processes (the
machine's load hits both alike), each worker at one BLAS thread. Prints each mode's CPU s
(the sum of the rays' process CPU), their ratio, the reaches the reduced model carried past its
box (and, of those, the ones redone the full way), and whether the classes (workspace) or the
reached points (ranges) are the same at every point.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy, in the workers too (spawned)

import argparse  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import metasheet  # noqa: E402,F401  (pins the BLAS code paths before numpy)
import numpy as np  # noqa: E402

from _results import add_save_option, saved_output  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODES = ("full", "reduced")


def study_tasks(pipeline: Path, out: Path, study: str, past_box: str) -> list:
    """The ``study`` stage's prediction rays on the outputs in ``out``, with ``past_box``."""
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages._studies import build_spec, grid_from
    from metasheet.pipeline.stages.workspace import settings_from
    from metasheet.studies.model import MODELS
    from metasheet.studies.workspace import RayTask, WorkspaceSettings, domain_spec

    pl = load_pipeline(pipeline)
    p = pl.params[study].for_column("prediction")
    inputs = {k: out / pl.name / k for k in ("orient", "material", "robot", "reduce")}
    ctx = StageContext(study, p, out / ".bench", inputs, pipeline.parent, column="prediction")
    if study == "workspace":
        s = replace(settings_from(p), past_box=past_box)
    else:  # the ranges stage's settings (metasheet.studies.ranges.motor_range_study)
        s = WorkspaceSettings(tol_mm=p.tol_mm, max_steps=p.max_steps, stop_after=p.stop_after,
                              strain_limit=p.strain_limit, stop_beyond_strain=p.stop_beyond_strain,
                              past_box=past_box, rotations=False, continuity=False)
    spec = domain_spec(build_spec(ctx), s)
    grid = grid_from(p)
    rest = MODELS.get(spec).rest_pose()
    rays = [grid.ray_points(r) for r in range(len(grid.directions))]
    specs = [spec] if study == "workspace" else [spec.with_motor_range(lo, hi) for lo, hi in p.ranges]
    return [RayTask(sp, s, rest[:3] + grid.points[ids]) for sp in specs for ids in rays]


def one_ray(task):
    """(classes or reached (k,), process CPU s, reaches carried past the box, redone) of one ray."""
    from metasheet.studies.model import MODELS
    from metasheet.studies.workspace import classify, explore_ray

    model = MODELS.get(task.spec)
    before = (getattr(model, "past_box_reaches", 0), getattr(model, "redone", 0))
    t = time.process_time()
    rec = explore_ray(task)
    cpu = time.process_time() - t
    out = classify(rec.reached, rec.rot_ok) if task.settings.rotations else rec.reached.astype(int)
    return out, cpu, model.past_box_reaches - before[0], model.redone - before[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pipeline", default=str(ROOT / "pipelines" / "paper.toml"))
    ap.add_argument("--out", required=True, help="a run's outputs folder (its --out), up to the reduce stage")
    ap.add_argument("--studies", nargs="+", default=["workspace", "ranges"], choices=["workspace", "ranges"])
    ap.add_argument("--workers", type=int, default=2)
    add_save_option(ap)
    a = ap.parse_args()
    rows = []
    for study in a.studies:
        tasks = {m: study_tasks(Path(a.pipeline).resolve(), Path(a.out).resolve(), study, m) for m in MODES}
        order = [(m, i) for i in range(len(tasks["full"])) for m in MODES]  # interleaved
        with ProcessPoolExecutor(a.workers) as ex:
            res = dict(zip(order, ex.map(one_ray, [tasks[m][i] for m, i in order])))
        per = {m: [res[(m, i)] for i in range(len(tasks[m]))] for m in MODES}
        cpu = {m: sum(r[1] for r in per[m]) for m in MODES}
        same = all(np.array_equal(x[0], y[0]) for x, y in zip(per["full"], per["reduced"]))
        points = sum(len(r[0]) for r in per["full"])
        changed = sum(int((x[0] != y[0]).sum()) for x, y in zip(per["full"], per["reduced"]))
        past = sum(r[2] for r in per["reduced"])
        redone = sum(r[3] for r in per["reduced"])
        rows.append((study, len(per["full"]), points, cpu["full"], cpu["reduced"], past, redone, same, changed))
    with saved_output(__file__, a.save):
        print(f"{os.cpu_count()} cpus, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, "
              f"{a.workers} workers, load {os.getloadavg()[0]:.1f}; the prediction column, every ray, "
              "both modes interleaved")
        print("| study | rays | points | CPU s, full | CPU s, reduced | full / reduced | reaches past the box "
              "(reduced) | of those redone | same classes / reached | points changed |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for study, n, pts, cf, cr, past, redone, same, changed in rows:
            print(f"| {study} | {n} | {pts} | {cf:.1f} | {cr:.1f} | {cf / cr:.2f} | {past} | {redone} | {same} "
                  f"| {changed} |")


if __name__ == "__main__":
    main()
