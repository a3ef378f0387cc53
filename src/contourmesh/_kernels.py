"""Internal numba kernels shared by the fast path and the public modules (compile time, issue 16).

A kernel made by :func:`internal_kernel` is compiled only as the callee of other compiled code:
without the Python and C call wrappers and without a cache file of its own (the cached entry
points that call it hold its code).  A module that also needs it from Python wraps it in a cached
``@njit`` function that only calls it, so that a process which reaches the kernel both from the
fast path and from the general mesher compiles it once instead of once per copy.  The rules that
keep each kernel at one signature (int64 values rather than literal constants, the same array
layouts at every call site) are those of :mod:`contourmesh.fastpath`.

Every module of the package takes ``njit`` from here rather than from numba, so that the cache
guard of :mod:`contourmesh._cache_guard` is in place before any of them defines a cached kernel
(``tests/test_cache_guard.py`` checks that every cached kernel goes through it).
"""

from __future__ import annotations

from . import _cache_guard

_cache_guard.install()  # before this import hands ``njit`` to the modules that define kernels

from numba import njit  # noqa: E402  (re-exported: the package's modules take njit from here)

#: ``no_rewrites``: numba's IR rewrite passes find nothing to do in these loops and only cost
#: compile time.
KERNEL_OPTIONS = dict(nogil=True, no_rewrites=True)


def internal_kernel(fn):
    """``fn`` as an internal numba kernel (see the module docstring)."""
    return njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, **KERNEL_OPTIONS)(fn)
