"""Reduced tangents taken once and reused: the reduced model's control loop never waits for one.

A fresh reduced tangent (the sampled elements' stiffness projected on the basis, ``T^T K T``,
and its LU) costs several force evaluations (3.4 ms against 0.6 ms for a chord update on the
14 mm P1 robot, k 65, 1,419 sampled elements). A modified-Newton matrix may come from another
state: the control loop (:mod:`metasheet.robot.tangent`) and the equilibrium solver judge every step on the
true residual whatever tangent made it. So the reduced linearizer keeps each exact tangent it
takes in a :class:`TangentLibrary`, keyed by motor angles, and an inexact request
(``linearize(state, exact=False)``, the control loop's) is served by the nearest one:

* within ``near_deg`` of ``state``'s angles: used as it is;
* farther: used for now, and an exact tangent at ``state`` is computed on a background thread
  (one at a time; numba's kernels and LAPACK release the GIL), so the next request near
  there finds it;
* an empty library: an exact tangent now (the first request only).

The library holds at most ``capacity`` tangents, dropping the least recently used.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Tangent:
    """An exact reduced tangent, condensed (see :class:`.linearizer.ReducedLinearizer`).

    angles : (na,) motor angles it was taken at [rad]; S : (6 + na, 6 + na) Schur complement
    of ``a``; Y : (k, 6 + na) its solves; C : (6 + na, k) coupling block; factor : LU of the
    (k, k) block (scipy ``lu_factor``); state : the state it was taken at.
    """

    angles: np.ndarray
    S: np.ndarray
    Y: np.ndarray
    C: np.ndarray
    factor: tuple
    state: object = None


class TangentLibrary:
    """Exact tangents by motor angles, with one background worker (see the module docstring).

    Parameters
    ----------
    compute : callable(state) -> :class:`Tangent`, the exact tangent at a state.
    near_deg : a tangent within this many degrees (largest motor difference) is used without
        asking for a closer one [deg].
    capacity : tangents kept (least recently used dropped).
    background : False computes every missing tangent in the caller's thread (tests, studies
        that must not depend on timing: same inputs, same tangents, same results).
    """

    def __init__(self, compute, *, near_deg: float = 3.0, capacity: int = 256, background: bool = True):
        self.compute = compute
        self.near = np.radians(near_deg)
        self.capacity = int(capacity)
        self.background = background
        self._items: OrderedDict[int, Tangent] = OrderedDict()
        self._next = 0
        self._lock = threading.Lock()
        self._pool: ThreadPoolExecutor | None = None
        self._job: Future | None = None
        self.stats = {"hits": 0, "far": 0, "computed": 0, "background": 0}

    def __len__(self) -> int:
        return len(self._items)

    def add(self, t: Tangent) -> None:
        with self._lock:
            self._items[self._next] = t
            self._next += 1
            while len(self._items) > self.capacity:
                self._items.popitem(last=False)

    def nearest(self, angles) -> tuple[Tangent | None, float]:
        """The tangent nearest ``angles`` (na,) [rad] (largest motor difference) and that
        distance [rad]; (None, inf) when the library is empty. Marks it recently used."""
        with self._lock:
            if not self._items:
                return None, np.inf
            keys = list(self._items)
            A = np.array([self._items[k].angles for k in keys])
            d = np.abs(A - np.asarray(angles)).max(axis=1)
            i = int(np.argmin(d))
            self._items.move_to_end(keys[i])
            return self._items[keys[i]], float(d[i])

    def get(self, state) -> Tangent:
        """A tangent for a modified-Newton step at ``state`` (see the module docstring)."""
        self._collect()
        t, d = self.nearest(state.angles)
        if t is not None and d <= self.near:
            self.stats["hits"] += 1
            return t
        if t is None or not self.background:
            t = self.compute(state)
            self.stats["computed"] += 1
            self.add(t)
            return t
        self.stats["far"] += 1
        if self._job is None:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rom-tangent")
            self._job = self._pool.submit(self.compute, state)
        return t

    def _collect(self) -> None:
        """Adopt a finished background tangent."""
        job = self._job
        if job is not None and job.done():
            self._job = None
            try:
                t = job.result()
            except Exception:  # noqa: BLE001 - a failed tangent is asked for again in the caller's thread
                self.stats["failed"] = self.stats.get("failed", 0) + 1
                return
            self.add(t)
            self.stats["background"] += 1

    def wait(self) -> None:
        """Let a pending background tangent finish and adopt it (tests, benchmarks)."""
        if self._job is not None:
            self._job.exception()
            self._collect()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
        self._job = None
