"""The general mesher's memory policy: freed heap memory given back to the system between its
large steps, and Python's cyclic garbage collector held off while it builds a mesh.

The general mesher's work arrays on a large volume are tens of MiB each, made and dropped step
after step.  glibc's allocator serves arrays below its (adaptive, up to 32 MiB) mmap threshold
from the heap, and memory freed there stays resident: by the next step the process holds the
last step's arrays as free heap beside the new ones (on the liver x2, 40-80 MiB of a 200 MiB
peak, varying from run to run).  ``malloc_trim(0)`` between the steps returns the free pages to
the system (a few milliseconds); the allocator's settings are not changed.  Elsewhere (another C
library, another system) :func:`release_free_heap` does nothing.

A mesh call makes and drops hundreds of thousands of small Python objects (per-join lists,
tuples and dicts); almost none of them outlive the call or form reference cycles, but they
trigger the cyclic collector all the same, and every few calls a full collection walks every
object the process holds (some 140k after importing the mesher's dependencies: 60-70 ms, charged
to whatever step runs then).  :func:`collector_paused` holds the collector off for the length of
a call and restores it after; what the call left in cycles goes at the next collection.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import sys
import threading

#: Meshes below this many faces are not worth a trim (their arrays are a few MiB).
RELEASE_FROM_FACES = 1 << 18

_trim = None  # the C function, False where there is none, None until looked up


def _malloc_trim():
    global _trim
    if _trim is None:
        fn = False
        if sys.platform.startswith("linux"):
            try:
                fn = ctypes.CDLL(None).malloc_trim  # glibc only
                fn.argtypes = [ctypes.c_size_t]
                fn.restype = ctypes.c_int
            except (OSError, AttributeError):
                fn = False
        _trim = fn
    return _trim


def release_free_heap(faces: int) -> bool:
    """Give the heap's free pages back to the system before a step of a mesh of ``faces`` faces
    (nothing below :data:`RELEASE_FROM_FACES`); True where it did."""
    if faces < RELEASE_FROM_FACES:
        return False
    fn = _malloc_trim()
    if not fn:
        return False
    fn(0)
    return True


_pause_lock = threading.Lock()
_pausers = 0  # calls inside collector_paused, in any thread
_resume = False  # whether the collector was on when the first of them came in


@contextlib.contextmanager
def collector_paused():
    """Python's cyclic garbage collector off inside the block (also a decorator), and back on after
    if it was on before.  Calls overlapping in several threads share one pause: the collector is
    turned back on when the last of them leaves, whatever order they leave in.  A collector the
    caller turned off stays off."""
    global _pausers, _resume
    with _pause_lock:
        if _pausers == 0:
            _resume = gc.isenabled()
            if _resume:
                gc.disable()
        _pausers += 1
    try:
        yield
    finally:
        with _pause_lock:
            _pausers -= 1
            if _pausers == 0 and _resume:
                _resume = False
                gc.enable()
