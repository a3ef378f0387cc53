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


def test_run_all_inside_a_worker_runs_there():
    """A call on the pool that itself asks for threads (the area of a large mesh measured in a
    slab task, say) runs its calls on its own thread instead of waiting for a helper queued behind
    itself on a one-worker pool."""
    import threading

    from contourmesh._workers import run_all

    def outer(i):
        names = run_all(lambda j: threading.current_thread().name, [(j,) for j in range(4)], 2)
        return i, threading.current_thread().name, names

    got = run_all(outer, [(i,) for i in range(6)], 2)
    assert [i for i, _, _ in got] == list(range(6))
    for _, where, names in got:
        if where.startswith("contourmesh-worker"):
            assert names == [where] * 4
