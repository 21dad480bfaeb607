"""Map a picklable function over work items: in process, a process pool, or dask.

The studies and the design chart hand their independent units (rays, sweep
points, grid cells) to an :class:`Executor`; results come back in input order.

Every unit computes with one BLAS / OpenMP thread (:data:`UNIT_THREADS`), in a local worker,
on a dask worker and in this process alike: a threaded BLAS splits a sum (a dot product, a
matrix-vector product) by its thread count, so the last bits of a result, and through a
Newton solve's iterates every digit below its tolerance, changed with ``OPENBLAS_NUM_THREADS``
and with the worker count (a pooled ``convergence.json`` differed from the serial one by
1e-11). One thread per unit also keeps two workers from oversubscribing a 2-core machine
(their default pools made the paper's workspace rays 2.5x slower, benchmarks/bench_executor.py).

Inside :meth:`Executor.session` every map goes to one pool kept for the block: a pipeline run
starts its workers once, not once per map (a spawned worker imports the package and builds
its robot models again: a few CPU seconds each time), and stages running at once share the
workers instead of oversubscribing the cores.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from typing import Any

from ..errors import ConfigError
from .priority_pool import PriorityPool, kill_workers


def _noop(done: int, total: int) -> None:
    pass


@dataclass(frozen=True)
class Executor:
    """Where work runs.

    Parameters
    ----------
    workers : number of local processes; 1 runs in this process.
    scheduler : address of a dask.distributed scheduler (``tcp://host:port``);
        when given, ``workers`` is ignored and the cluster's workers are used.
    worker_threads : BLAS / OpenMP threads of each local worker and, in a :meth:`session`, of
        this process; None: :data:`UNIT_THREADS` (1). More than one may speed up a dense
        factorisation but gives up the bytes promise: the last bits then depend on the count.
    pool : the shared pool of a :meth:`session` (set by it, not by hand).
    priority : in a session, this executor's units start before those of higher numbers.
    meter : adds up the CPU time of the units run in local worker processes (a pipeline
        stage's manifest reports it); None: not measured.
    """

    workers: int = 1
    scheduler: str | None = None
    worker_threads: int | None = None
    pool: PriorityPool | None = field(default=None, compare=False, repr=False)
    priority: int = field(default=0, compare=False)
    meter: "CpuMeter | None" = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if int(self.workers) < 1:
            raise ConfigError(f"workers: {self.workers!r}: allowed range is [1, inf)")
        if self.worker_threads is not None and int(self.worker_threads) < 1:
            raise ConfigError(f"worker_threads: {self.worker_threads!r}: allowed range is [1, inf) or None")
        if self.scheduler is not None and not str(self.scheduler).startswith(("tcp://", "tls://", "inproc://", "ws://")):
            raise ConfigError(
                f"scheduler: {self.scheduler!r}: expected an address like tcp://HOST:PORT"
            )

    @property
    def threads(self) -> int:
        """BLAS / OpenMP threads a unit computes with."""
        return int(self.worker_threads or UNIT_THREADS)

    @property
    def kind(self) -> str:
        """'dask', 'processes' or 'serial'."""
        if self.scheduler:
            return "dask"
        return "processes" if self.workers > 1 else "serial"

    @contextlib.contextmanager
    def session(self) -> Iterator["Executor"]:
        """This executor, its maps sharing one pool of local workers until the block ends (the
        pool is shut down then); a serial or dask executor, or one already in a session, as it is.

        For the block this process's BLAS / OpenMP pools get a worker's share of the cores too
        (:func:`own_threads`): the workers keep every core busy, and the idle threads of a
        library's default pool spin (the paper's robot stage alone: 75 user CPU s against 100, the
        same wall time)."""
        if self.kind != "processes" or self.pool is not None:
            yield self
            return
        threads = self.threads
        pool = PriorityPool(_pool(self.workers, threads), self.workers)
        try:
            with own_threads(threads):
                yield replace(self, pool=pool)
        except BaseException:  # a failure or an interrupt: what still runs is not wanted
            pool.shutdown(kill=True)
            raise
        pool.shutdown()

    def map(
        self,
        fn: Callable[[Any], Any],
        items: Iterable[Any],
        *,
        progress: Callable[[int, int], None] = _noop,
        on_result: Callable[[int, Any], None] = _noop,
    ) -> list[Any]:
        """``[fn(x) for x in items]``, possibly in parallel, results in input order.

        ``progress(0, total)`` first, then as each result arrives (in any order):
        ``on_result(index, value)`` (a resumable map stores it there), then ``progress(done, total)``.
        """
        items = list(items)
        total = len(items)
        if total == 0:
            return []
        progress(0, total)  # the work's start: a progress line's clock and its estimate run from here
        if self.kind == "serial":
            out = []
            with own_threads(self.threads):
                for i, x in enumerate(items):
                    out.append(fn(x))
                    on_result(i, out[-1])
                    progress(i + 1, total)
            return out
        if self.kind == "processes":
            if self.pool is not None:
                return _collect(lambda f, x: self.pool.submit(self.priority, f, x), fn, items, progress, on_result,
                                self.meter)
            return _map_pool(fn, items, self.workers, progress, on_result, self.threads, self.meter)
        return _map_dask(_Threads(fn, self.threads), items, self.scheduler, progress, on_result)


class CpuMeter:
    """A running total of CPU seconds [s] and units, safe to add to from several threads; also
    by unit function (``by_function``: name -> [seconds, units])."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.seconds = 0.0
        self.units = 0
        self.by_function: dict[str, list] = {}

    def add(self, seconds: float, function: str = "") -> None:
        with self._lock:
            self.seconds += float(seconds)
            self.units += 1
            entry = self.by_function.setdefault(function, [0.0, 0])
            entry[0] += float(seconds)
            entry[1] += 1


@dataclass(frozen=True)
class _Timed:
    """``fn`` run in a worker, returning ``(fn(x), CPU seconds of the worker process)``: a local
    worker runs one unit at a time, so its process time is the unit's, its BLAS threads included."""

    fn: Callable[[Any], Any]

    def __call__(self, x):
        t0 = time.process_time()
        value = self.fn(x)
        return value, time.process_time() - t0


#: The environment variables that size the thread pools of libraries a worker may load later
#: (MKL through pypardiso, OpenMP), read when the library loads.
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


#: BLAS / OpenMP threads of every unit and of a pipeline run's own process, unless an executor
#: names another count: one, so that no result depends on how a library splits a sum.
UNIT_THREADS = 1


@dataclass(frozen=True)
class _Threads:
    """``fn`` run with at most ``n`` BLAS / OpenMP threads (a dask worker's pools are the
    cluster's: each unit limits them for its own call)."""

    fn: Callable[[Any], Any]
    n: int

    def __call__(self, x):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=self.n):
            return self.fn(x)


#: How much lower a local worker's scheduling priority is than its parent's (Unix ``nice``).
WORKER_NICENESS = 5


@contextlib.contextmanager
def own_threads(n: int) -> Iterator[None]:
    """At most ``n`` threads in this process's BLAS and OpenMP pools for the block, those loaded
    (threadpoolctl) and those loaded during it (:data:`THREAD_VARS`); restored afterwards."""
    from threadpoolctl import ThreadpoolController

    saved = {var: os.environ.get(var) for var in THREAD_VARS}
    os.environ.update({var: str(n) for var in THREAD_VARS})
    try:
        with ThreadpoolController().limit(limits=n):
            yield
    finally:
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value


#: How often [s] a local worker checks that the process that started it is still there.
PARENT_CHECK_S = 1.0


def _init_worker(n: int) -> None:
    """Pool initializer: at most ``n`` threads in this worker's BLAS and OpenMP pools, those
    already loaded (threadpoolctl) and those loaded later (their environment variables); a
    niceness :data:`WORKER_NICENESS` above the parent's; Ctrl-C left to the parent (a
    terminal sends it to the whole process group); and an exit as soon as the parent is gone."""
    from threadpoolctl import ThreadpoolController

    for var in THREAD_VARS:
        os.environ[var] = str(n)
    ThreadpoolController().limit(limits=n)
    _limit_numba(n)
    # below the process that waits for them: when it has serial work (training a basis, the
    # next stage's set-up) it is the run's critical path, and the workers take what is left
    if hasattr(os, "nice"):
        os.nice(WORKER_NICENESS)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), name="parent-watch", daemon=True).start()


def _limit_numba(n: int) -> None:
    """At most ``n`` threads in numba's parallel kernels (the voxel solver's) in this thread.
    numba sizes its pool by ``NUMBA_NUM_THREADS`` (the cores), not by ``OMP_NUM_THREADS``: two
    workers each ran the voxel solver on two threads on a 2-core machine (the paper's four
    realisations: 174 s of wall against 152 s with one; the same bytes, the kernels' sums being
    split by blocks, not by threads)."""
    try:
        import numba
    except ImportError:
        return
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


def _exit_with_parent(parent: int) -> None:
    """Exit this worker once its parent has died (a SIGKILLed run cannot stop its workers, and an
    orphan would compute its unit to the end, then wait for work for ever): the orphan is
    re-parented (``os.getppid()`` changes)."""
    while os.getppid() == parent:
        time.sleep(PARENT_CHECK_S)
    os._exit(1)


def _pool(workers: int, threads: int) -> ProcessPoolExecutor:
    # "spawn", not fork: a forked child inherits the locks of BLAS, numba and gmsh threads
    # held at fork time and can hang forever (seen with the design chart).
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_init_worker, initargs=(threads,))


def _map_pool(fn, items: Sequence, workers: int, progress, on_result, threads: int = UNIT_THREADS,
              meter: CpuMeter | None = None) -> list:
    pool = _pool(min(workers, len(items)), threads)
    try:
        result = _collect(pool.submit, fn, items, progress, on_result, meter)
    except BaseException:
        kill_workers(pool)
        raise
    pool.shutdown(wait=True)
    return result


def _collect(submit: Callable, fn, items: Sequence, progress, on_result, meter: CpuMeter | None = None) -> list:
    results: list = [None] * len(items)
    futures = {submit(fn if meter is None else _Timed(fn), x): i for i, x in enumerate(items)}
    try:
        for done, fut in enumerate(as_completed(futures), 1):
            i = futures[fut]
            results[i] = fut.result()
            if meter is not None:
                results[i], seconds = results[i]
                meter.add(seconds, getattr(fn, "__qualname__", type(fn).__name__))
            on_result(i, results[i])
            progress(done, len(items))
    except BaseException:  # a unit failed: the others of this map are not wanted any more
        for fut in futures:
            fut.cancel()
        raise
    return results


def _map_dask(fn, items: Sequence, address: str, progress, on_result) -> list:
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError as exc:  # optional dependency
        raise ConfigError(
            "scheduler: running on a dask cluster needs the 'dist' extra: pip install 'metasheet[dist]'"
        ) from exc
    results: list = [None] * len(items)
    with Client(address) as client:
        futures = client.map(fn, items, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for done, fut in enumerate(dask_completed(futures), 1):
            i = index[fut.key]
            results[i] = fut.result()
            on_result(i, results[i])
            progress(done, len(items))
    return results
