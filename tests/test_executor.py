"""The local process pool: results in input order, and workers that share the cores."""

import contextlib
import os
from dataclasses import replace

import pytest

from metasheet.errors import ConfigError
from metasheet.runtime.executor import THREAD_VARS, UNIT_THREADS, Executor


def blas_threads(_):
    """(BLAS thread counts of the loaded libraries, the thread variables) in a worker."""
    import numpy  # noqa: F401 - loads OpenBLAS
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"], [os.environ[v] for v in THREAD_VARS]


def test_units_compute_with_one_thread_whatever_the_executor(monkeypatch):
    """A threaded BLAS splits sums by its thread count: every unit gets the same single thread,
    in this process (a serial map) as in a worker, whatever the environment asked for."""
    from threadpoolctl import threadpool_limits

    assert UNIT_THREADS == 1 and Executor(workers=2).threads == 1
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    with threadpool_limits(limits=2):
        for blas, env in Executor(workers=1).map(blas_threads, range(2)):
            assert blas and all(t == 1 for t in blas)
            assert env == ["1"] * len(THREAD_VARS)


def test_pool_workers_limit_their_blas_threads():
    got = Executor(workers=2).map(blas_threads, range(4))
    n = UNIT_THREADS
    for blas, env in got:
        assert blas and all(t == n for t in blas)
        assert env == [str(n)] * len(THREAD_VARS)
    # an explicit count (OpenBLAS cannot grow past the pool it loaded with: its variable is checked)
    got = Executor(workers=2, worker_threads=3).map(blas_threads, range(2))
    assert all(env == ["3"] * len(THREAD_VARS) and all(t <= 3 for t in blas) for blas, env in got)


def numba_threads(_):
    import numba

    return numba.get_num_threads(), numba.config.NUMBA_NUM_THREADS


def test_pool_workers_limit_numbas_threads():
    """numba sizes its pool by the cores, not by OMP_NUM_THREADS: the worker limits it itself."""
    got = Executor(workers=2).map(numba_threads, range(2))
    assert all(n == min(UNIT_THREADS, total) for n, total in got)


def test_worker_threads_is_validated():
    with pytest.raises(ConfigError, match="worker_threads"):
        Executor(workers=2, worker_threads=0)


def worker_pid(x):
    """(x, the worker's pid); a unit that waits a little so that both workers take some."""
    import time

    time.sleep(0.05)
    return x, os.getpid()


def failing_unit(x):
    if x == 2:
        raise ValueError("unit 2 fails")
    return x


def test_a_session_keeps_one_pool_for_every_map():
    plain = [{pid for _, pid in Executor(workers=2).map(worker_pid, range(6))} for _ in range(2)]
    assert not plain[0] & plain[1]  # without a session each map starts its own workers
    with Executor(workers=2).session() as ex:
        assert ex.pool is not None and ex == Executor(workers=2)
        runs = [ex.map(worker_pid, range(6)) for _ in range(2)]
        with pytest.raises(ValueError, match="unit 2"):
            ex.map(failing_unit, range(4))
        after = ex.map(worker_pid, range(4))  # a failed unit leaves the pool usable
    assert [x for x, _ in runs[0]] == list(range(6))  # input order
    pids = {pid for run in (*runs, after) for _, pid in run}
    assert 1 <= len(pids) <= 2
    serial = Executor(workers=1)
    with serial.session() as same:
        assert same is serial  # nothing to keep


def niceness(_):
    return os.nice(0)


def test_workers_run_below_their_parent():
    from metasheet.runtime.executor import WORKER_NICENESS

    assert Executor(workers=2).map(niceness, range(2)) == [os.nice(0) + WORKER_NICENESS] * 2


def test_a_session_gives_this_process_a_workers_share_of_the_cores(monkeypatch):
    """In a session the workers take the cores: this process's BLAS pools are cut to a worker's
    share (and libraries loaded meanwhile are told so), and restored when the session ends."""
    import numpy  # noqa: F401 - loads OpenBLAS
    from threadpoolctl import threadpool_info, threadpool_limits

    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "7")
    with threadpool_limits(limits=2):
        before = [i["num_threads"] for i in threadpool_info()]
        assert max(before) == 2
        with Executor(workers=2, worker_threads=1).session():
            assert blas_threads(None)[1] == ["1"] * len(THREAD_VARS)
            assert [i["num_threads"] for i in threadpool_info()] == [1] * len(before)
        assert [i["num_threads"] for i in threadpool_info()] == before
    assert "OMP_NUM_THREADS" not in os.environ and os.environ["MKL_NUM_THREADS"] == "7"


def burn(seconds):
    """Spin for ``seconds`` of this process's CPU time; return the CPU time it took [s]."""
    import time

    t0 = time.process_time()
    while time.process_time() - t0 < seconds:
        pass
    return time.process_time() - t0


def test_a_meter_adds_up_the_cpu_time_of_the_units_in_the_workers():
    """Each unit reports its own CPU time; the meter's total is their sum (the worker's wrapper
    measures a little more: the call around the unit), for a plain pool and a session's."""
    from metasheet.runtime.executor import CpuMeter

    for shared in (False, True):
        meter = CpuMeter()
        with Executor(workers=2).session() if shared else contextlib.nullcontext(Executor(workers=2)) as ex:
            got = replace(ex, meter=meter).map(burn, [0.1, 0.2, 0.15, 0.05])
        assert meter.units == 4
        assert sum(got) <= meter.seconds <= sum(got) + 0.05
        assert got == pytest.approx([0.1, 0.2, 0.15, 0.05], abs=0.02)  # results unwrapped, in order
    serial = CpuMeter()
    Executor(workers=1, meter=serial).map(burn, [0.05])
    assert serial.units == 0  # in this process: the stage thread's own CPU time counts it
