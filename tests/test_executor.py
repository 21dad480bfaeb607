"""The local process pool: results in input order, and workers that share the cores."""

import os

import pytest

from metasheet.errors import ConfigError
from metasheet.executor import THREAD_VARS, Executor, threads_per_worker


def blas_threads(_):
    """(BLAS thread counts of the loaded libraries, the thread variables) in a worker."""
    import numpy  # noqa: F401 - loads OpenBLAS
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"], [os.environ[v] for v in THREAD_VARS]


def test_threads_per_worker_shares_the_cores():
    assert threads_per_worker(2, cores=2) == 1
    assert threads_per_worker(2, cores=8) == 4
    assert threads_per_worker(3, cores=8) == 2
    assert threads_per_worker(4, cores=2) == 1  # never 0


def test_pool_workers_limit_their_blas_threads():
    got = Executor(workers=2).map(blas_threads, range(4))
    n = threads_per_worker(2)
    for blas, env in got:
        assert blas and all(t == n for t in blas)
        assert env == [str(n)] * len(THREAD_VARS)
    # an explicit count (OpenBLAS cannot grow past the pool it loaded with: its variable is checked)
    got = Executor(workers=2, worker_threads=3).map(blas_threads, range(2))
    assert all(env == ["3"] * len(THREAD_VARS) and all(t <= 3 for t in blas) for blas, env in got)


def test_worker_threads_is_validated():
    with pytest.raises(ConfigError, match="worker_threads"):
        Executor(workers=2, worker_threads=0)
