"""Map a picklable function over work items: in process, a process pool, or dask.

The studies and the design chart hand their independent units (rays, sweep
points, grid cells) to an :class:`Executor`; results come back in input order.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

from .errors import ConfigError


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
    """

    workers: int = 1
    scheduler: str | None = None

    def __post_init__(self):
        if int(self.workers) < 1:
            raise ConfigError(f"workers: {self.workers!r}: allowed range is [1, inf)")
        if self.scheduler is not None and not str(self.scheduler).startswith(("tcp://", "tls://", "inproc://", "ws://")):
            raise ConfigError(
                f"scheduler: {self.scheduler!r}: expected an address like tcp://HOST:PORT"
            )

    @property
    def kind(self) -> str:
        """'dask', 'processes' or 'serial'."""
        if self.scheduler:
            return "dask"
        return "processes" if self.workers > 1 else "serial"

    def map(
        self,
        fn: Callable[[Any], Any],
        items: Iterable[Any],
        *,
        progress: Callable[[int, int], None] = _noop,
        on_result: Callable[[int, Any], None] = _noop,
    ) -> list[Any]:
        """``[fn(x) for x in items]``, possibly in parallel, results in input order.

        As each result arrives (in any order): ``on_result(index, value)`` (a resumable map
        stores it there), then ``progress(done, total)``.
        """
        items = list(items)
        total = len(items)
        if total == 0:
            return []
        if self.kind == "serial":
            out = []
            for i, x in enumerate(items):
                out.append(fn(x))
                on_result(i, out[-1])
                progress(i + 1, total)
            return out
        if self.kind == "processes":
            return _map_pool(fn, items, self.workers, progress, on_result)
        return _map_dask(fn, items, self.scheduler, progress, on_result)


def _map_pool(fn, items: Sequence, workers: int, progress, on_result) -> list:
    results: list = [None] * len(items)
    # "spawn", not fork: a forked child inherits the locks of BLAS, numba and gmsh threads
    # held at fork time and can hang forever (seen with the design chart).
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=ctx) as pool:
        futures = {pool.submit(fn, x): i for i, x in enumerate(items)}
        for done, fut in enumerate(as_completed(futures), 1):
            i = futures[fut]
            results[i] = fut.result()
            on_result(i, results[i])
            progress(done, len(items))
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
