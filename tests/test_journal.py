"""The journal of expensive evaluations (metasheet/runtime/journal.py) and the finite-strain touch
search resumed from it (metasheet/studies/nonlinear_touch.py): a search killed part way and run
again retraces the same poses, solving only those it had not reached."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.runtime.journal import Journal
from metasheet.studies.nonlinear_touch import robot_touch

KEY = {"seed": 1, "voxel": 0.25}


def test_entries_come_back_at_their_exact_floats_and_other_inputs_are_refused(tmp_path):
    path = tmp_path / "j.jsonl"
    j = Journal(path, KEY)
    x = 0.1 + 0.2  # not 0.3: the key is the float itself
    j.add(x, {"d": [1.0, np.inf]})
    j.add(2 / 3, {"d": [0.5]})
    again = Journal(path, KEY)
    assert len(again) == 2 and again.get(x) == {"d": [1.0, np.inf]} and again.get(0.3) is None
    assert again.get(2 / 3) == {"d": [0.5]}
    with pytest.raises(ConfigError, match="other inputs"):
        Journal(path, {**KEY, "voxel": 0.2})
    (tmp_path / "bad.jsonl").write_text("not json\n")
    with pytest.raises(ConfigError, match="not a journal"):
        Journal(tmp_path / "bad.jsonl", KEY)


def test_a_line_cut_short_by_a_kill_is_dropped_and_the_next_entry_starts_afresh(tmp_path):
    path = tmp_path / "j.jsonl"
    Journal(path, KEY).add(1.5, {"d": 1})
    with open(path, "a") as f:
        f.write('{"x": 2.5, "entry": {"d"')  # the kill came mid-write
    j = Journal(path, KEY)
    assert len(j) == 1 and j.get(2.5) is None
    j.add(2.5, {"d": 2})
    lines = path.read_text().splitlines()
    assert json.loads(lines[-1]) == {"x": 2.5, "entry": {"d": 2}} and len(lines) == 4
    assert Journal(path, KEY).get(2.5) == {"d": 2} and Journal(path, KEY).get(1.5) == {"d": 1}


class _GapRobot:
    """A stand-in for PrintedRobot whose walls close as 1 - t^2 / 2 [mm] at motor travel t [deg]
    along motor 0, counting its poses (each a held rod)."""

    sheets = (SimpleNamespace(size=(4.0, 4.0, 4.0), phases=np.zeros((16, 16, 16))),) * 2

    def __init__(self):
        self.solved = []

    def held(self, motors_deg, q, from_rest=False):
        t = float(motors_deg[0])
        self.solved.append(t)
        gap = SimpleNamespace(distance=1.0 - 0.5 * t * t, nodes=(3, 4), rest_distance=1.0, position=(0.0, 1.0, 2.0))
        far = SimpleNamespace(distance=2.0, nodes=(5, 6), rest_distance=2.0, position=(0.0, 0.0, 0.0))
        return SimpleNamespace(dp=np.asarray(q[:3]), theta=np.asarray(q[3:]), residual=1e-3, rod_step=np.zeros(6),
                               approach=(far, gap), wall_strain=(0.1, 0.2), stable=(True, True))


def test_a_search_killed_part_way_resumes_from_its_journal_and_ends_as_an_uninterrupted_one(tmp_path):
    d, J = np.eye(6)[0], 0.01 * np.eye(6)
    args = dict(max_deg=4.0, tol_deg=1e-3, touch_mm=0.0625, rod_per_motor=J, balance=False)
    whole_robot = _GapRobot()
    whole, whole_records = robot_touch(whole_robot, np.zeros(6), d, 0.5, max_solves=20, **args)
    path = tmp_path / "touch.jsonl"
    cut = robot_touch(_GapRobot(), np.zeros(6), d, 0.5, max_solves=4, journal=Journal(path, KEY), **args)[0]
    assert not cut.converged and cut.solves == 4
    robot = _GapRobot()
    resumed, records = robot_touch(robot, np.zeros(6), d, 0.5, max_solves=20, journal=Journal(path, KEY), **args)
    assert resumed.poses == whole.poses and resumed.travel == whole.travel and resumed.info == whole.info
    assert robot.solved == whole_robot.solved[4:]  # only the poses the killed run had not reached
    assert [r.get("replayed", False) for r in records] == [True] * 4 + [False] * (len(records) - 4)
    strip = lambda r: {k: v for k, v in r.items() if k not in ("seconds", "replayed")}  # noqa: E731
    assert [strip(r) for r in records] == [strip(r) for r in whole_records]
    assert resumed.travel == pytest.approx(np.sqrt(2.0 * (1.0 - 0.0625)), abs=1e-3)


class _Killed(Exception):
    pass


def _steps(n, journal=None, kill_at=None, done=None):
    """A unit of ``n`` expensive steps (each the square of its index), journalled; raises at step
    ``kill_at`` as a killed run would stop; ``done`` collects the steps computed."""
    out = []
    for i in range(n):
        kept = None if journal is None else journal.get(i)
        if kept is None:
            if i == kill_at:
                raise _Killed
            kept = {"v": i * i}
            done.append(i)
            if journal is not None:
                journal.add(i, kept)
        out.append(kept["v"])
    return out


def test_a_cached_unit_killed_inside_resumes_within_it_and_its_journal_goes_once_it_is_stored(tmp_path):
    from functools import partial

    from metasheet.runtime.executor import Executor
    from metasheet.studies.resume import UnitCache, keep_only_used, unit_key

    d, done = tmp_path / "units", []
    with pytest.raises(_Killed):
        UnitCache(d).map(Executor(), partial(_steps, kill_at=3, done=done), [5], journal=True)
    assert done == [0, 1, 2] and (d / f"{unit_key(5)}.jsonl").is_file()
    assert UnitCache(d).map(Executor(), partial(_steps, done=done), [5], journal=True) == [[0, 1, 4, 9, 16]]
    assert done == [0, 1, 2, 3, 4]  # the rerun computed only the steps the killed one had not reached
    assert sorted(f.name for f in d.iterdir()) == [f"{unit_key(5)}.pkl"]
    (d / f"{unit_key(6)}.jsonl").write_text("")  # a journal of a unit no run asks for any more
    assert keep_only_used(d) == 1 and sorted(f.name for f in d.iterdir()) == [f"{unit_key(5)}.pkl"]
    assert UnitCache(None).map(Executor(), partial(_steps, done=[]), [2], journal=True) == [[0, 1]]
