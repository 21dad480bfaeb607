"""A process pool shared by several maps, its waiting units served by priority.

A pipeline run's stages share one pool of workers (:meth:`metasheet.runtime.executor.Executor.session`).
With the pool's own first-come queue, a stage that submitted first keeps every worker until
its units are done, whatever waits on the other: the anisotropy sweep, which nothing
downstream needs, held the workers while the reduce stage, which every study waits for,
queued behind it. Here the pool runs exactly ``slots`` units at a time (one per worker) and,
when one finishes, starts the waiting unit of lowest priority number (the stage's place in
the pipeline), first come first within a priority. A stage with nothing to run leaves the
workers to the next. :func:`kill_workers` stops a pool's workers at once (an interrupted run,
here and in :mod:`metasheet.runtime.executor`'s own pools).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import threading
from concurrent.futures import Future, ProcessPoolExecutor


class PriorityPool:
    """``pool`` (a :class:`ProcessPoolExecutor`) behind a priority queue, ``slots`` units at once."""

    def __init__(self, pool: ProcessPoolExecutor, slots: int):
        self.pool, self.slots = pool, max(1, int(slots))
        self._lock = threading.Lock()
        self._waiting: list = []  # heap of (priority, sequence, fn, item, future)
        self._running = 0
        self._sequence = itertools.count()

    def submit(self, priority: int, fn, item) -> Future:
        """A future of ``fn(item)``, started when a slot is free and no unit of a lower
        ``priority`` number waits."""
        future: Future = Future()
        with self._lock:
            heapq.heappush(self._waiting, (priority, next(self._sequence), fn, item, future))
        self._start()
        return future

    def _start(self) -> None:
        while True:
            with self._lock:
                if self._running >= self.slots or not self._waiting:
                    return
                _, _, fn, item, future = heapq.heappop(self._waiting)
                if not future.set_running_or_notify_cancel():  # cancelled while waiting
                    continue
                self._running += 1
            try:
                inner = self.pool.submit(fn, item)
            except BaseException as exc:  # the pool is shut down or broken: say so on the future
                self._finish(future, None, exc)
                continue
            inner.add_done_callback(lambda f, outer=future: self._done(outer, f))

    def _done(self, outer: Future, inner: Future) -> None:
        exc = inner.exception() if not inner.cancelled() else RuntimeError("unit cancelled by the pool")
        self._finish(outer, None if exc else inner.result(), exc)
        self._start()

    def _finish(self, future: Future, result, exc) -> None:
        with self._lock:
            self._running -= 1
        if exc is not None:
            future.set_exception(exc)
        else:
            future.set_result(result)

    def shutdown(self, *, kill: bool = False) -> None:
        """Cancel the waiting units and shut the pool down: waiting for the running ones, or
        with ``kill`` terminating its workers at once (an interrupted run)."""
        with self._lock:
            waiting, self._waiting = self._waiting, []
        for *_, future in waiting:
            future.cancel()
        if kill:
            kill_workers(self.pool)
        else:
            self.pool.shutdown(wait=True, cancel_futures=True)


def kill_workers(pool: ProcessPoolExecutor, grace: float = 5.0) -> None:
    """Terminate ``pool``'s worker processes now (their running units are lost) and shut it
    down without waiting for them; a worker still alive ``grace`` seconds later is killed."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for p in processes:
        with contextlib.suppress(Exception):
            p.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        with contextlib.suppress(Exception):
            p.join(grace)
            if p.is_alive():
                p.kill()
