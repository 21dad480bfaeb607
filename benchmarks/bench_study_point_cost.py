"""A study point's cost (issue 59): where a workspace point's CPU goes, and the code before against now.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_study_point_cost.py --out OUT \\
        [--pipeline pipelines/paper.toml] [--columns prediction reproduction] [--rays 2 0 1 24] \\
        [--repeats 3] [--before DIR] [--profile] [--save]

``OUT`` is a finished run's outputs folder (its ``--out``; the robot and reduce stages at least:
``metasheet run pipelines/paper.toml --stage reduce --out OUT``); without ``--out``, a coarse robot
built here (16 mm P1 sheets; the prediction on a basis trained on rest +- 10 deg) with the
pipeline's settings and grid. The rays are the workspace
stage's (``benchmarks/bench_study_points.py``'s ``ray_tasks``, each column's robot as the stage
builds it); the first ray listed only warms the model (numba, the rest state) and is not timed.

``--profile`` runs each column once under cProfile with a CPU clock and prints where the time
goes: the reaches by kind (a point reach, a rotation try) and outcome, then the operations
(fresh linearisations, factorisations, chord updates, force kernels, QP solves,
certifications, Newton solves, strains), cumulative and overlapping (a certification contains
chord updates and may contain a Newton solve).

``--before DIR`` times the same rays with the package in ``DIR`` (the code before a change, e.g.
``git archive <rev> metasheet | tar -x -C DIR``) against this checkout's, each in its own
subprocess, interleaved ``--repeats`` times (the machine's load hits both alike), and prints the
median CPU s per tried point of each and whether both wrote the same records, bit for bit.
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import hashlib
import json
import os
import pstats
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Operations of the profile: (label, function names as cProfile lists them (file tail, name),
#: which figure: "cum" cumulative or "tot" own time).
OPERATIONS = (
    ("fresh linearisations, full model", [("robot/statics.py", "_linearize")], "cum"),
    ("  SuperLU factorisations (gstrf)",
     [("~", "<built-in method scipy.sparse.linalg._dsolve._superlu.gstrf>")], "tot"),
    ("  SuperLU solves (every one)", [("~", "<method 'solve' of 'SuperLU' objects>")], "tot"),
    ("fresh linearisations, reduced model", [("rom/linearizer.py", "_exact")], "cum"),
    ("chord updates (forces, one solve)", [("robot/statics.py", "update_within"), ("rom/linearizer.py", "update")],
     "cum"),
    ("element force kernels (with or without tangent)", [("robot/kernels.py", "corotational_numba"),
                                                          ("robot/quadrature.py", "corotational_quadrature_numba")],
     "tot"),
    ("QP solves", [("robot/qp.py", "solve_step_qp")], "cum"),
    ("certifications (polish, Newton fallback)", [("robot/inverse.py", "certify")], "cum"),
    ("Newton solves with line search", [("robot/equilibrium.py", "solve_equilibrium")], "cum"),
    ("strain checks (points, control states past the box)", [("robot/validity.py", "validity_strain")], "cum"),
    ("Jacobians at points (sigma_min)", [("studies/adapter.py", "min_singular_value")], "cum"),
)


def _tasks(pipeline: Path, out: Path | None, column: str):
    """The workspace stage's rays of ``column`` on the run in ``out``, or (``out`` None) on the
    coarse robot: 16 mm P1 sheets of the default scene, the prediction on a reduced basis trained
    on rest +- 10 deg from 12 equilibria (``tests/test_studies_reduced.py``'s), the reproduction
    on the full model; each with the pipeline's settings for that column and its grid."""
    if out is not None:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bench_study_points import ray_tasks

        return ray_tasks(pipeline, out, column)
    import tempfile

    import numpy as np

    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.stages._studies import grid_from
    from metasheet.pipeline.stages.workspace import settings_from
    from metasheet.studies.adapter import FemRobot, paper_robot_spec
    from metasheet.studies.model import MODELS
    from metasheet.studies.reduced_adapter import ReducedSpec
    from metasheet.studies.workspace import RayTask, domain_spec

    spec = paper_robot_spec(mesh_size=16.0)
    if column == "prediction":
        path = Path(tempfile.gettempdir()) / f"bench_study_point_cost_{spec.key}.npz"
        if not path.is_file():  # the same training gives the same file: a worker may find it made
            from metasheet.robot.equilibrium import solve_equilibrium
            from metasheet.rom.training import motor_design, train

            fem = FemRobot(spec)
            c = fem.robot.coupling
            lo, hi = c.rest_angles - np.radians(10), c.rest_angles + np.radians(10)
            snaps = [solve_equilibrium(fem.robot, a, state=fem.rest, linearizer=fem.lz).state
                     for a in motor_design(lo, hi, 12, 1)]
            train(fem.robot, snaps, fem.rest, box=(lo, hi), basis_tol_mm=0.005, fit_tol_mm=0.01).save(path)
        spec = ReducedSpec.from_file(spec, path)
    p = load_pipeline(pipeline).params["workspace"].for_column(column)
    grid, settings = grid_from(p), settings_from(p)
    spec = domain_spec(spec, settings)
    rest = MODELS.get(spec).rest_pose()
    return [RayTask(spec, settings, rest[:3] + grid.points[grid.ray_points(r)]) for r in range(len(grid.directions))]


def _digest(recs) -> str:
    from metasheet.studies.workspace import PointRecords

    h = hashlib.sha256()
    for r in recs:
        for f in PointRecords.__dataclass_fields__:
            h.update(f.encode())
            h.update(getattr(r, f).tobytes())
    return h.hexdigest()[:16]


def worker(pipeline: Path, out: Path, column: str, rays: list[int]) -> dict:
    """CPU s, points tried, class counts and the records' digest of ``rays[1:]`` on a fresh model."""
    import numpy as np

    from metasheet.studies.model import MODELS
    from metasheet.studies.workspace import classify, explore_ray

    tasks = _tasks(pipeline, out, column)
    MODELS.clear()
    explore_ray(tasks[rays[0]])  # warm-up
    t0 = time.process_time()
    recs = [explore_ray(tasks[r]) for r in rays[1:]]
    cpu = time.process_time() - t0
    cls = np.concatenate([classify(r.reached, r.rot_ok)[r.tried] for r in recs])
    return {"cpu": cpu, "points": int(sum(r.tried.sum() for r in recs)),
            "classes": {int(c): int((cls == c).sum()) for c in (3, 2, 1, 0, -1)}, "digest": _digest(recs)}


def profile(pipeline: Path, out: Path, column: str, rays: list[int]) -> None:
    """Print the reaches by kind and outcome, and the operations, of ``rays[1:]``."""
    from metasheet.studies.model import MODELS
    from metasheet.studies.workspace import explore_ray

    tasks = _tasks(pipeline, out, column)
    MODELS.clear()
    model = MODELS.get(tasks[0].spec)
    explore_ray(tasks[rays[0]])
    lzs = [model.lz] + ([model.full.lz] if getattr(model, "full", None) is not None else [])
    log = []
    cls = type(model)
    plain = cls.reach

    def reach(self, goal, **kw):  # one reach: kind, outcome, steps, CPU, fresh linearisations
        f0 = [lz.factorizations - lz.memo.hits for lz in lzs]
        fb0 = getattr(self, "fallbacks", 0)
        t0 = time.process_time()
        r = plain(self, goal, **kw)
        dt = time.process_time() - t0
        ok = (r.converged and not r.left_domain and r.error_mm <= kw["tol_mm"]
              and (kw.get("tol_deg") is None or r.error_deg <= kw["tol_deg"]))
        kind = "point reach" if kw.get("tol_deg") is None else "rotation try"
        past = " (full model past the box)" if getattr(self, "fallbacks", 0) > fb0 else ""
        log.append((kind + past, "reached" if ok else "failed", r.steps, dt,
                    [lz.factorizations - lz.memo.hits - a for lz, a in zip(lzs, f0)]))
        return r

    cls.reach = reach
    prof = cProfile.Profile(time.process_time)
    try:
        t0 = time.process_time()
        prof.enable()
        recs = [explore_ray(tasks[r]) for r in rays[1:]]
        prof.disable()
        cpu = time.process_time() - t0
    finally:
        cls.reach = plain
    n = int(sum(r.tried.sum() for r in recs))
    print(f"\n### {column}: rays {rays[1:]}, {n} points tried, {cpu:.2f} CPU s under the profiler "
          f"({cpu / n:.3f} per point)\n")
    print("| reach | outcome | runs | control steps | CPU s | share | fresh linearisations" +
          (" (reduced, full)" if len(lzs) > 1 else "") + " |\n|---|---|---|---|---|---|---|")
    g = collections.defaultdict(lambda: [0, 0, 0.0, [0] * len(lzs)])
    for kind, outcome, steps, dt, fresh in log:
        e = g[(kind, outcome)]
        e[0] += 1
        e[1] += steps
        e[2] += dt
        e[3] = [a + b for a, b in zip(e[3], fresh)]
    for (kind, outcome), (runs, steps, dt, fresh) in sorted(g.items()):
        print(f"| {kind} | {outcome} | {runs} | {steps} | {dt:.2f} | {dt / cpu:.0%} | {', '.join(map(str, fresh))} |")
    rest = cpu - sum(e[2] for e in g.values())
    print(f"| outside the reaches (strains, Jacobians at points) | | | | {rest:.2f} | {rest / cpu:.0%} | |")
    stats = pstats.Stats(prof).stats
    print("\n| operation | calls | CPU s | share |\n|---|---|---|---|")
    for label, names, which in OPERATIONS:
        calls = tot = 0.0
        for (file, _, func), (cc, nc, tt, ct, _) in stats.items():
            if any(file.endswith(f) and func == name or (f == "~" and func == name) for f, name in names):
                calls += nc
                tot += tt if which == "tot" else ct
        if calls:
            print(f"| {label} | {int(calls)} | {tot:.2f} | {tot / cpu:.0%} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pipeline", default=str(ROOT / "pipelines" / "paper.toml"))
    ap.add_argument("--out", default=None, help="the run's outputs folder (its --out); none: the coarse robot")
    ap.add_argument("--columns", nargs="+", default=["prediction", "reproduction"])
    ap.add_argument("--rays", type=int, nargs="+", default=[2, 0, 1, 24], help="warm-up ray, then the timed ones")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--before", default=None, help="a folder holding the package before (its metasheet/)")
    ap.add_argument("--profile", action="store_true", help="print where each column's time goes")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _results import add_save_option, saved_output

    add_save_option(ap)
    a = ap.parse_args()
    pipeline, out = Path(a.pipeline).resolve(), None if a.out is None else Path(a.out).resolve()
    if a.worker:  # one timed run in this process, as JSON on stdout's last line
        print(json.dumps(worker(pipeline, out, a.worker, a.rays)))
        return
    with saved_output(__file__, a.save):
        print(f"{os.cpu_count()} cpus, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
              f"load {os.getloadavg()[0]:.1f}; rays {a.rays[1:]} after warm-up ray {a.rays[0]}; "
              + ("the coarse robot (16 mm P1)" if out is None else f"the run in {a.out}"))
        if a.profile:
            for col in a.columns:
                profile(pipeline, out, col, a.rays)
        if a.before is None:
            return
        codes = {"before": Path(a.before).resolve(), "now": ROOT}
        rows = []
        for col in a.columns:
            res = {k: [] for k in codes}
            for _ in range(a.repeats):
                for name, code in codes.items():  # interleaved
                    env = {**os.environ, "PYTHONPATH": str(code)}
                    cmd = [sys.executable, __file__, "--pipeline", str(pipeline), "--worker", col,
                           "--rays", *map(str, a.rays)] + ([] if out is None else ["--out", str(out)])
                    done = subprocess.run(cmd, env=env, cwd=code, capture_output=True, text=True, check=True)
                    res[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
            same = len({r["digest"] for v in res.values() for r in v}) == 1
            for name in codes:
                cpu = statistics.median(r["cpu"] for r in res[name])
                n = res[name][0]["points"]
                rows.append((col, name, n, cpu / n, res[name][0]["classes"], same))
        print(f"\nmedian of {a.repeats}, before / now interleaved, each in its own process\n")
        print("| column | code | points | CPU s / point | classes 3 / 2 / 1 / 0 / -1 | same records |")
        print("|---|---|---|---|---|---|")
        for col, name, n, per, cls, same in rows:
            print(f"| {col} | {name} | {n} | {per:.3f} | {' / '.join(str(cls[str(c)]) for c in (3, 2, 1, 0, -1))} "
                  f"| {same} |")


if __name__ == "__main__":
    main()
