"""A pipeline run's time, stage by stage, from its manifests (issue 41: the paper pipeline with
both columns on 2 cores).

    python benchmarks/bench_pipeline_stages.py pipelines/paper.toml [--out OUT] [--save]

Reads each stage's ``manifest.json`` (``wall_time_s``, ``cpu_s``, ``timings_s``: what the
runner measured while the stage ran, nothing is rerun here) and prints one row per stage:
its wall and CPU seconds, and for a two-column study each column's wall and CPU seconds (the
CPU from the manifest's ``<column>.cpu``; "-" in older runs). Below the
table, two figures that do not depend on how the stages overlapped: the total CPU over the
cores, a lower bound of a run on that many cores, and the critical path (the longest chain of
stage walls through the dependency graph). A stage's wall includes its waits for workers that
other stages held, so the critical path is an upper estimate of what the chain alone would
take, not a bound.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from _results import add_save_option, saved_output

from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.staleness import upstream
from metasheet.pipeline.column import COLUMNS


def stage_rows(pipeline, base: Path) -> list[dict]:
    """Per stage in run order: name, wall [s], cpu [s], columns {column: (wall [s], cpu [s] or
    None)}, started."""
    rows = []
    for name in pipeline.order:
        path = base / name / "manifest.json"
        if not path.is_file():
            raise SystemExit(f"{path}: missing: stage {name!r} has not run (run the pipeline first)")
        m = json.loads(path.read_text())
        t = m.get("timings_s") or {}
        rows.append({"name": name, "wall": float(m["wall_time_s"]), "cpu": float(m["cpu_s"]["total"]),
                     "columns": {c: (float(t[c]), t.get(f"{c}.cpu")) for c in COLUMNS if c in t},
                     "started": m.get("started", "")})
    return rows


def critical_path(pipeline, walls: dict[str, float]) -> tuple[float, list[str]]:
    """The longest chain of stage walls [s] through the dependency graph, and its stages."""
    best: dict[str, tuple[float, list[str]]] = {}
    for name in pipeline.order:
        ups = [best[u] for u in upstream(pipeline, name) if u in best]
        t, chain = max(ups, key=lambda x: x[0], default=(0.0, []))
        best[name] = (t + walls[name], [*chain, name])
    return max(best.values(), key=lambda x: x[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pipeline", help="pipeline TOML file whose run to read")
    ap.add_argument("--out", default=None, help="output root it ran with (default: outputs/ of the project)")
    ap.add_argument("--cores", type=int, default=os.cpu_count() or 1, help="cores the bound divides the CPU by")
    add_save_option(ap)
    a = ap.parse_args()
    pipeline = load_pipeline(a.pipeline)
    base = (Path(a.out) if a.out else pipeline.root / "outputs") / pipeline.name
    rows = stage_rows(pipeline, base)
    path_s, chain = critical_path(pipeline, {r["name"]: r["wall"] for r in rows})
    cpu = sum(r["cpu"] for r in rows)
    with saved_output(__file__, a.save):
        print(f"Stages of `{a.pipeline}` ({base}), from their manifests:\n")
        print("| stage | started | wall [s] | CPU [s] | columns: wall / CPU [s] |")
        print("|---|---|---:|---:|---|")
        for r in rows:
            cols = ", ".join(f"{c} {w:.0f} / {'-' if u is None else f'{u:.0f}'}" for c, (w, u) in r["columns"].items())
            cols = cols or "-"
            print(f"| {r['name']} | {r['started']} | {r['wall']:.0f} | {r['cpu']:.0f} | {cols} |")
        print(f"\nCPU {cpu:.0f} s in all, {cpu / a.cores:.0f} s over {a.cores} cores: at least "
              f"{cpu / a.cores / 60:.1f} min on {a.cores} cores. Critical path {path_s:.0f} s "
              f"({' > '.join(chain)}; stage walls, their waits for workers included).")


if __name__ == "__main__":
    main()
