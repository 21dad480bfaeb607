"""Resumable maps: results of finished work units are kept on disk, so an interrupted study
picks up where it stopped.

The stage layer owns the directory (it lives next to the stage's outputs; once the stage
succeeds it is removed, or pruned to the units the run used, :func:`keep_only_used`); this
module only stores one pickle per unit, named by a hash of the unit itself and of metasheet's
code (:func:`code_digest`), so a changed unit (another robot, other tolerances) or changed
code never reuses a stale result. Files are written to a temporary name and renamed: a killed
run leaves no half-written unit. A unit that is itself a long search (an hour of finite-strain
robot poses) can keep a journal of its own steps beside it (``map(..., journal=True)``: the
function gets a :class:`metasheet.runtime.journal.Journal` named by the unit's key), so a run
killed inside that unit resumes within it too.
"""

from __future__ import annotations

import hashlib
import io
import os
import pickle
import threading
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

from ..runtime.executor import Executor
from ..runtime.journal import Journal
from ..runtime.provenance import code_digest

#: The keys each cache directory was asked for in this process (stages run in threads).
_USED: dict[Path, set[str]] = {}
_USED_LOCK = threading.Lock()


class _KeyPickler(pickle.Pickler):
    """A pickler for hashing only: a pydantic model is pickled as its class and its
    ``model_dump()`` (its own pickle holds the set of fields given, whose order follows the
    process's string hash seed: the same unit would get another key in another process)."""

    def reducer_override(self, obj):
        from pydantic import BaseModel

        if isinstance(obj, BaseModel):
            return _model_key, (f"{type(obj).__module__}.{type(obj).__qualname__}", obj.model_dump())
        return NotImplemented


def _model_key(name: str, fields: dict):  # never called: the reduction only has to hash the same
    raise TypeError(f"{name}: a unit key's pickle is for hashing, not for loading")


def unit_key(item: Any) -> str:
    """Content hash of a work unit (its pickle; numpy arrays and frozen dataclasses pickle stably,
    pydantic models as their fields: :class:`_KeyPickler`) and of the code that computes it
    (:func:`code_digest`): the same unit has the same key in any process."""
    buf = io.BytesIO()
    _KeyPickler(buf, protocol=4).dump(item)
    return hashlib.sha256(code_digest().encode() + buf.getvalue()).hexdigest()[:32]


def keep_only_used(directory: Path | str) -> int:
    """Remove the unit files (and temporary files) in ``directory`` that no :class:`UnitCache`
    of this process asked for; returns the number of units kept."""
    d = Path(directory).resolve()
    with _USED_LOCK:
        used = _USED.pop(d, set())
    if not d.is_dir():
        return 0
    for f in d.iterdir():
        if f.suffix == ".tmp" or (f.suffix in (".pkl", ".jsonl") and f.stem not in used):
            f.unlink(missing_ok=True)
    return sum(1 for f in d.glob("*.pkl"))


class UnitCache:
    """Per-unit result files in ``directory`` (None: no caching, a plain ``executor.map``)."""

    def __init__(self, directory: Path | str | None):
        self.directory = Path(directory) if directory is not None else None
        if self.directory is not None:
            self.directory.mkdir(parents=True, exist_ok=True)

    def _file(self, key: str) -> Path:
        return self.directory / f"{key}.pkl"

    def _used(self, keys) -> None:
        with _USED_LOCK:
            _USED.setdefault(self.directory.resolve(), set()).update(keys)

    def load(self, key: str) -> tuple[bool, Any]:
        if self.directory is None:
            return False, None
        self._used((key,))
        f = self._file(key)
        if not f.exists():
            return False, None
        try:
            return True, pickle.loads(f.read_bytes())
        except Exception:  # a corrupt file (foreign writer): recompute the unit
            return False, None

    def store(self, key: str, value: Any) -> None:
        if self.directory is None:
            return
        tmp = self.directory / f".{key}.{os.getpid()}.tmp"
        tmp.write_bytes(pickle.dumps(value, protocol=4))
        os.replace(tmp, self._file(key))
        (self.directory / f"{key}.jsonl").unlink(missing_ok=True)  # the unit's journal: done with

    def map(
        self,
        executor: Executor,
        fn: Callable[[Any], Any],
        items: Sequence[Any],
        *,
        progress: Callable[[int, int], None] = lambda d, n: None,
        journal: bool = False,
    ) -> list[Any]:
        """``[fn(x) for x in items]`` through ``executor``, skipping units already stored.

        The missing units go to the executor at once (no worker idles while another finishes
        a long unit) and each is stored as soon as it arrives: an interrupted map loses only
        the units under way. With ``journal`` the call is ``fn(x, journal=...)``: a
        :class:`~metasheet.runtime.journal.Journal` (None without a directory) that the
        function fills with its own steps and replays them from, kept until the unit is stored.
        """
        items = list(items)
        total = len(items)
        if self.directory is None:
            return executor.map(partial(fn, journal=None) if journal else fn, items, progress=progress)
        keys = [unit_key(x) for x in items]
        self._used(keys)
        results: list[Any] = [None] * total
        todo = []
        for i, k in enumerate(keys):
            ok, val = self.load(k)
            if ok:
                results[i] = val
            else:
                todo.append(i)
        done = total - len(todo)
        progress(done, total)
        if not todo:
            return results

        def keep(j: int, val: Any) -> None:
            results[todo[j]] = val
            self.store(keys[todo[j]], val)

        run = [items[i] for i in todo]
        if journal:
            fn, run = partial(_journalled, fn), [(x, str(self.directory / f"{keys[i]}.jsonl"), keys[i])
                                                 for x, i in zip(run, todo)]
        executor.map(fn, run, progress=lambda d, n: progress(done + d, total), on_result=keep)
        return results


def _journalled(fn: Callable, unit: tuple) -> Any:
    """``fn(x, journal=...)`` for a unit (x, the journal's path, the unit's key)."""
    x, path, key = unit
    return fn(x, journal=Journal(path, {"unit": key}))
