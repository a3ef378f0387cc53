"""Worker threads kept between calls (issue 16).

The fast path's slabs (:mod:`contourmesh.fastpath`) and the two ranges of the crossing test
(:mod:`contourmesh.intersect`) run compiled kernels that release the GIL on a few worker
threads.  Starting those threads for every call cost more than a millisecond each on a loaded
machine (the caller waits until a new thread is scheduled), a tenth of the 512^3 ball's call on
two threads; the pools here are made once per thread count and process (a forked child makes its
own: the parent's threads do not exist there) and reused.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_POOLS: dict = {}
_LOCK = threading.Lock()


def worker_pool(threads: int) -> ThreadPoolExecutor:
    """This process's pool of ``threads`` worker threads (made at the first call that asks)."""
    key = (os.getpid(), int(threads))
    with _LOCK:
        pool = _POOLS.get(key)
        if pool is None:
            pool = _POOLS[key] = ThreadPoolExecutor(max_workers=int(threads), thread_name_prefix="contourmesh")
        return pool


def run_all(fn, args, threads: int) -> list:
    """``[fn(*a) for a in args]`` on the pool of ``threads`` workers, in order.  Where a call
    raises, the calls not started yet are cancelled and the running ones waited for before the
    exception goes on (nothing of the failed call keeps running)."""
    pool = worker_pool(threads)
    futures = [pool.submit(fn, *a) for a in args]
    try:
        return [f.result() for f in futures]
    except BaseException:
        for f in futures:
            f.cancel()
        for f in futures:
            if not f.cancelled():
                try:
                    f.result()
                except BaseException:
                    pass
        raise
