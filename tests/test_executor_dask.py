"""The executor on a real dask.distributed cluster: scheduler + two worker processes on localhost."""

import pytest

from metasheet.runtime.executor import Executor

distributed = pytest.importorskip("distributed")


def cube(x):
    return x**3 - 2 * x


@pytest.mark.bytes
def test_dask_cluster_equals_serial():
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        items = list(range(20))
        got = Executor(scheduler=cluster.scheduler_address).map(cube, items)
    assert got == Executor().map(cube, items)
