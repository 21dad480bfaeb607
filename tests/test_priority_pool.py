"""The shared pool's queue: waiting units start by priority, then in submission order."""

import time
from concurrent.futures import ProcessPoolExecutor, wait

import pytest

from metasheet.runtime.priority_pool import PriorityPool


def started_at(x):
    """(x, when it started) after a short nap, so that later units queue behind it."""
    t = time.time()
    time.sleep(0.2)
    return x, t


def fails(x):
    raise ValueError(f"unit {x} fails")


def test_waiting_units_start_by_priority_then_in_order():
    pool = PriorityPool(ProcessPoolExecutor(1), slots=1)
    try:
        first = pool.submit(5, started_at, "late-0")  # runs at once: the only slot
        time.sleep(0.05)
        low = [pool.submit(5, started_at, f"late-{i}") for i in (1, 2)]
        high = [pool.submit(1, started_at, f"urgent-{i}") for i in (1, 2)]
        futures = [first, *low, *high]
        wait(futures, timeout=60)
        order = [x for x, _ in sorted((f.result() for f in futures), key=lambda r: r[1])]
        assert order == ["late-0", "urgent-1", "urgent-2", "late-1", "late-2"]
    finally:
        pool.shutdown()


def test_a_failing_unit_fails_its_future_and_the_pool_goes_on():
    pool = PriorityPool(ProcessPoolExecutor(2), slots=2)
    try:
        bad = pool.submit(0, fails, 3)
        good = [pool.submit(0, started_at, i) for i in range(3)]
        with pytest.raises(ValueError, match="unit 3"):
            bad.result(timeout=60)
        assert [f.result(timeout=60)[0] for f in good] == [0, 1, 2]
    finally:
        pool.shutdown()


def test_shutdown_cancels_what_waits():
    pool = PriorityPool(ProcessPoolExecutor(1), slots=1)
    running = pool.submit(0, started_at, "a")
    waiting = pool.submit(0, started_at, "b")
    time.sleep(0.05)
    pool.shutdown()
    assert running.result(timeout=60)[0] == "a" and waiting.cancelled()
