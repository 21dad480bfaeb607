"""benchmarks/bench_pipeline_stages.py reads a run's manifests: each stage's wall and CPU, each
column's wall and CPU, and the critical path through the dependency graph (a longest path: checked
against every chain by brute force on a small pipeline)."""

import itertools
import json
import sys
from pathlib import Path

import pytest

from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline
from metasheet.pipeline.staleness import upstream

from test_study_columns import STANDIN
from test_studies_stages import project

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
bench = pytest.importorskip("bench_pipeline_stages")


def test_stage_rows_and_the_critical_path_of_a_two_column_run(tmp_path):
    pipeline = load_pipeline(project(tmp_path, STANDIN, "cols"))
    run_pipeline(pipeline)
    base = tmp_path / "outputs" / "cols"
    rows = {r["name"]: r for r in bench.stage_rows(pipeline, base)}
    assert set(rows) == set(pipeline.order)
    ws = json.loads((base / "workspace" / "manifest.json").read_text())
    assert rows["workspace"]["wall"] == pytest.approx(ws["wall_time_s"])
    assert set(rows["workspace"]["columns"]) == {"prediction", "reproduction"}
    cols = rows["workspace"]["columns"]
    assert sum(w for w, _ in cols.values()) <= rows["workspace"]["wall"] + 1e-3  # the manifest rounds to ms
    # each column's CPU: the stage thread's and its units' while it ran, within the stage's total
    assert all(cpu > 0 for _, cpu in cols.values())
    assert sum(cpu for _, cpu in cols.values()) <= ws["cpu_s"]["total"] + 0.01
    assert rows["ranges"]["columns"] == {}  # one column: no split
    # made-up walls, so that the longest chain is not the run order's
    walls = {n: float(i + 1) for i, n in enumerate(reversed(pipeline.order))}
    total, chain = bench.critical_path(pipeline, walls)
    assert total == sum(walls[n] for n in chain)
    for a, b in itertools.pairwise(chain):
        assert a in upstream(pipeline, b)
    every = [[n] for n in pipeline.order]  # every chain: brute force over the graph's paths
    for _ in pipeline.order:
        every += [c + [n] for c in every for n in pipeline.order if c[-1] in upstream(pipeline, n) and c + [n] not in every]
    assert total == max(sum(walls[n] for n in c) for c in every)
