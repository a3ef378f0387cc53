"""Worker threads kept between calls (issue 16).

The fast path's slabs (:mod:`contourmesh.fastpath`) and the ranges of heights of the crossing
test (:mod:`contourmesh.intersect`) run compiled kernels that release the GIL on a few threads.
Starting those threads for every call cost more than a millisecond each on a loaded machine (the
caller waits until a new thread is scheduled), a tenth of the 512^3 ball's call on two threads;
the pools here are made once per thread count and process (a forked child makes its own: the
parent's threads do not exist there) and reused, and the calling thread works alongside them
(:func:`run_all`) instead of waiting: with another process on one of two cores, the ball's call
on two threads went from 0.93 times the one-thread speed (the caller idle while a worker waited
for the core) to 1.55 times.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_POOLS: dict = {}
_LOCK = threading.Lock()
_BUSY = [0]  # run_all calls in progress in this process (under _LOCK)
#: The name every kept worker thread starts with.
THREAD_PREFIX = "contourmesh-worker"


def worker_pool(threads: int) -> ThreadPoolExecutor:
    """This process's pool of ``threads`` worker threads (made at the first call that asks)."""
    key = (os.getpid(), int(threads))
    with _LOCK:
        pool = _POOLS.get(key)
        if pool is None:
            pool = _POOLS[key] = ThreadPoolExecutor(max_workers=int(threads), thread_name_prefix=THREAD_PREFIX)
        return pool


def run_all(fn, args, threads: int) -> list:
    """``[fn(*a) for a in args]`` on ``threads`` threads, in order: the calling thread and
    ``threads - 1`` workers of the pool take the calls one after another from a shared counter,
    so that where a worker is not scheduled (another process on the core) the caller goes on with
    the calls instead of waiting for it.  Where a call raises, no further call starts, the running
    ones finish, and the first exception goes on.  Called from one of the kept worker threads
    (a call that itself runs on the pool), it runs the calls there, in order: a helper submitted
    to the pool could wait behind the very call that waits for it."""
    n = len(args)
    if threads <= 1 or n <= 1 or threading.current_thread().name.startswith(THREAD_PREFIX):
        return [fn(*a) for a in args]
    results = [None] * n
    lock = threading.Lock()
    state = {"next": 0, "error": None}

    def take():
        while True:
            with lock:
                i = state["next"]
                if i >= n or state["error"] is not None:
                    return
                state["next"] = i + 1
            try:
                results[i] = fn(*args[i])
            except BaseException as e:  # (kept for the caller; the other threads stop taking)
                with lock:
                    if state["error"] is None:
                        state["error"] = e
                return

    pool = worker_pool(threads - 1)
    with _LOCK:
        _BUSY[0] += 1
    try:
        helpers = [pool.submit(take) for _ in range(min(threads - 1, n - 1))]
        take()
        for f in helpers:
            f.result()
    finally:
        with _LOCK:
            _BUSY[0] -= 1
    if state["error"] is not None:
        raise state["error"]
    return results


def kept_threads_idle(t: threading.Thread) -> bool:
    """Whether ``t`` is one of this module's kept worker threads and none of them has work: such a
    thread waits on its pool's queue holding no lock a forked child would need (a child makes its
    own pool, :func:`worker_pool` is keyed by the process id)."""
    if not t.name.startswith(THREAD_PREFIX):
        return False
    with _LOCK:
        return _BUSY[0] == 0
