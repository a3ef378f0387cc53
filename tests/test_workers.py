"""The worker threads kept between calls (``contourmesh._workers``, issue 16): results in order,
the calling thread taking part, and a failing call stopping the calls not started."""

from __future__ import annotations

import threading
import time

import pytest

from contourmesh._workers import run_all, worker_pool


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_run_all_keeps_the_order_and_uses_the_caller(threads):
    names = []

    def f(i, j):
        names.append(threading.current_thread().name)
        time.sleep(0.002 * (i % 3))
        return i * 10 + j

    args = [(i, i + 1) for i in range(12)]
    assert run_all(f, args, threads) == [i * 10 + i + 1 for i in range(12)]
    assert threading.current_thread().name in names  # the caller took calls too
    assert len(names) == 12
    assert run_all(f, [], threads) == []


def test_run_all_stops_after_a_failure_and_raises_it():
    started = []

    def f(i):
        started.append(i)
        if i == 1:
            raise KeyError("slab 1")
        time.sleep(0.01)
        return i

    with pytest.raises(KeyError, match="slab 1"):
        run_all(f, [(i,) for i in range(40)], 2)
    assert len(started) < 40  # the calls after the failure did not start
    assert run_all(lambda i: i + 1, [(1,), (2,)], 2) == [2, 3]  # the pool still works


def test_one_pool_per_thread_count():
    assert worker_pool(2) is worker_pool(2) and worker_pool(2) is not worker_pool(3)
