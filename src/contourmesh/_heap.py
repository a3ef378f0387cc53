"""Freed heap memory given back to the system between the general mesher's large steps.

The general mesher's work arrays on a large volume are tens of MiB each, made and dropped step
after step.  glibc's allocator serves arrays below its (adaptive, up to 32 MiB) mmap threshold
from the heap, and memory freed there stays resident: by the next step the process holds the
last step's arrays as free heap beside the new ones (on the liver x2, 40-80 MiB of a 200 MiB
peak, varying from run to run).  ``malloc_trim(0)`` between the steps returns the free pages to
the system (a few milliseconds); the allocator's settings are not changed.  Elsewhere (another C
library, another system) :func:`release_free_heap` does nothing.
"""

from __future__ import annotations

import ctypes
import sys

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
