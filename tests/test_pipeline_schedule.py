"""The stage graph runner: independent stages at once, dependencies respected, failures raised."""

import threading
import time

import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline.schedule import run_graph

#: a -> (b, c) -> d, and e alone: b, c and e can run beside each other
NAMES = ("a", "b", "c", "e", "d")
DEPS = {"b": ["a"], "c": ["a"], "d": ["b", "c"], "e": []}


class Recorder:
    def __init__(self, fail: str | None = None, seconds: float = 0.05, slow: str = "e"):
        self.lock = threading.Lock()
        self.events: list[tuple[str, str]] = []
        self.now = self.peak = 0
        self.fail, self.seconds, self.slow = fail, seconds, slow

    def __call__(self, name: str) -> str:
        with self.lock:
            self.events.append(("start", name))
            self.now += 1
            self.peak = max(self.peak, self.now)
        time.sleep(self.seconds * (8 if name == self.slow else 1))  # e outlasts a: b and c run beside it
        with self.lock:
            self.now -= 1
            self.events.append(("end", name))
        if name == self.fail:
            raise RuntimeError(f"{name} failed")
        return name.upper()


def _index(events, kind, name):
    return events.index((kind, name))


@pytest.mark.parametrize("at_once", [1, 2, 3])
def test_every_stage_runs_once_after_its_upstream(at_once):
    rec = Recorder()
    out = run_graph(NAMES, DEPS, rec, at_once=at_once)
    assert out == {n: n.upper() for n in NAMES} and list(out) == list(NAMES)
    ev = rec.events
    assert sorted(n for k, n in ev if k == "start") == sorted(NAMES)
    for n, ups in DEPS.items():
        for u in ups:
            assert _index(ev, "end", u) < _index(ev, "start", n)
    assert rec.peak == min(at_once, 3)  # b, c and e are the widest layer


def test_one_at_a_time_keeps_the_given_order():
    rec = Recorder(seconds=0.0)
    run_graph(NAMES, DEPS, rec, at_once=1)
    assert [n for k, n in rec.events if k == "start"] == list(NAMES)


def test_a_failure_stops_new_stages_and_lets_running_ones_finish():
    rec = Recorder(fail="b")
    with pytest.raises(RuntimeError, match="b failed"):
        run_graph(NAMES, DEPS, rec, at_once=2)
    started = {n for k, n in rec.events if k == "start"}
    assert "d" not in started  # downstream of the failure: never started
    assert all(("end", n) in rec.events for n in started)  # the others under way finished


def test_bad_arguments_are_named():
    with pytest.raises(ConfigError, match="at_once"):
        run_graph(NAMES, DEPS, Recorder(), at_once=0)
    with pytest.raises(ConfigError, match="topological"):
        run_graph(("b", "a"), {"b": ["a"]}, Recorder())


def test_given_constants_do_not_wait_for_the_homogenisation():
    """``[material] source = "config"`` reads no homogenisation: ``--stage robot`` of the paper
    pipeline then runs no homogenisation (before: 3.5 minutes of it and the cell; the cell, about
    40 s, still runs: orient reads it for the scale map's verdict on its foam in the sheet)."""
    from pathlib import Path

    from metasheet.pipeline.config import load_pipeline, upstream
    from metasheet.pipeline.runner import plan

    paper = Path(__file__).resolve().parents[1] / "pipelines" / "paper.toml"
    given = load_pipeline(paper, ["material.source=config", "material.model=authors"])
    assert upstream(given, "material") == ()
    assert "homogenize" not in plan(given, "robot")
    computed = load_pipeline(paper)
    assert upstream(computed, "material") == ("homogenize",)
    assert {"cell", "homogenize", "material"} <= set(plan(computed, "robot"))
