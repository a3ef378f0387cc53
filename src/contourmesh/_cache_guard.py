"""Numba's on-disk cache, kept in step with every module of the package.

Numba decides whether a cached kernel is still fresh from its own source file only.  A cached
kernel that calls a kernel of another module holds a compiled copy of that callee, and numba
does not look at the callee's file: after the callee changes, the caller's cache is still taken
as fresh and runs the old code.  In this package that gives wrong meshes, not an error (seen
once in development: a kernel moved in ``bands/caps.py`` left the cached joins of
``volumes.py`` calling the old one, and the mesh areas moved by up to 0.8 %).

The guard adds one cache locator in front of numba's own.  For a function defined under the
package it takes the locator numba would have used (same directory, same file names) and adds
to its freshness stamp a fingerprint of every package module that mentions numba: a change to
any of them makes every cached kernel of the package stale, so they compile again.  Modules
without compiled code (the front door, the readers, the comparison harness) are left out, so
editing them keeps the cache.  Functions of other packages are not touched.

The locator classes are a numba internal (``CacheImpl._locator_classes``).  Where a numba
release does not have them, :func:`install` leaves numba's cache as it is and says so in
:func:`installed`.

The guard also mends one fault of numba's cache loading (:func:`install_environment_merge`).
Each compiled function has an environment, found by name, whose list of constants the code
indexes; its Python entry reads the dtype of an array it returns from there.  A cached caller
stores its own pickled copy of each callee's environment, taken while it was compiled, and numba
keeps the first copy a process loads under each name.  When a caller is loaded before the callee
is called from Python, the callee's entry can find the caller's shorter copy and read past its
end (seen on the lobster after a warm cache: ``RuntimeError: In 'NRT_adapt_ndarray_to_python',
'descr' is NULL``).  The copies of one name are taken from one list that only grows, so the
shorter is a prefix of the longer; the merge extends the kept copy with the constants it lacks.
"""

from __future__ import annotations

import functools
import hashlib
import os

_ROOT = os.path.dirname(os.path.abspath(__file__))


@functools.lru_cache(maxsize=None)
def fingerprint(root: str) -> str:
    """A hash of the ``.py`` files under ``root`` (``__pycache__`` aside) that mention numba:
    their paths relative to ``root`` and their bytes."""
    h = hashlib.sha256()
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
        for name in sorted(filenames):
            if not name.endswith(".py"):
                continue
            path = os.path.join(dirpath, name)
            with open(path, "rb") as f:
                data = f.read()
            if b"numba" in data:
                h.update(os.path.relpath(path, root).replace(os.sep, "/").encode())
                h.update(b"\0")
                h.update(hashlib.sha256(data).digest())
    return h.hexdigest()


def _inside(path: str, root: str) -> bool:
    try:
        return os.path.commonpath([os.path.abspath(path), root]) == root
    except ValueError:  # another drive (Windows)
        return False


def _caching():
    """numba's caching module and its class that holds the locator classes, or ``None``."""
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover - numba is a dependency
        return None
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    if impl is None or not isinstance(getattr(impl, "_locator_classes", None), list) \
            or not hasattr(caching, "_CacheLocator"):
        return None
    return caching, impl


_LOCATORS: dict = {}


def locator_for(root: str):
    """The guard's locator class for the package under ``root`` (made once per root)."""
    root = os.path.abspath(root)
    if root in _LOCATORS:
        return _LOCATORS[root]
    found = _caching()
    if found is None:
        return None
    caching, impl = found

    class PackageStampLocator(caching._CacheLocator):
        """numba's own locator for a function of the package, with the package's fingerprint
        added to the source stamp."""

        guarded_root = root

        def __init__(self, inner):
            self._inner = inner

        def ensure_cache_path(self):
            self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            return (self._inner.get_source_stamp(), fingerprint(root))

        def get_disambiguator(self):
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _inside(py_file, root):
                return None
            for other in impl._locator_classes:
                if getattr(other, "guarded_root", None) is not None:
                    continue
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

    PackageStampLocator.__qualname__ = PackageStampLocator.__name__
    _LOCATORS[root] = PackageStampLocator
    return PackageStampLocator


def _same_constant(a, b) -> bool:
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    try:
        return bool(a == b)
    except Exception:  # arrays and other values without a plain equality
        return False


def install_environment_merge() -> bool:
    """Make numba's loading of a pickled environment extend the copy it already holds under the
    same name with the constants that copy lacks (see the module docstring).  The pickled files
    name the function as numba's own (``numba.core.environment._rebuild_env``), so caches
    written with the merge in place load in processes without it and the other way round.
    Returns whether the merge is in place; where numba does not have the function, nothing
    changes."""
    try:
        from numba.core import environment
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    original = getattr(environment, "_rebuild_env", None)
    if original is None or not callable(getattr(environment, "lookup_environment", None)):
        return False
    if getattr(original, "_contourmesh_merge", False):
        return True

    def _rebuild_env(modname, consts, env_name):
        env = original(modname, consts, env_name)
        held = env.consts
        if len(held) < len(consts) and all(_same_constant(a, b) for a, b in zip(held, consts)):
            held.extend(consts[len(held):])
        return env

    _rebuild_env.__module__ = original.__module__
    _rebuild_env.__qualname__ = original.__qualname__
    _rebuild_env.__name__ = original.__name__
    _rebuild_env._contourmesh_merge = True
    _rebuild_env._original = original
    environment._rebuild_env = _rebuild_env
    return True


def environment_merge_installed() -> bool:
    """Whether numba's environment loading goes through :func:`install_environment_merge`."""
    try:
        from numba.core import environment
    except ImportError:  # pragma: no cover
        return False
    return getattr(getattr(environment, "_rebuild_env", None), "_contourmesh_merge", False)


def install(root: str = _ROOT) -> bool:
    """Put the guard for the package under ``root`` in front of numba's cache locators (once),
    and the environment merge in numba's cache loading.  Returns whether the locator is in place;
    kernels decorated before the call are not guarded."""
    install_environment_merge()
    cls = locator_for(root)
    if cls is None:
        return False
    _, impl = _caching()
    if cls not in impl._locator_classes:
        impl._locator_classes.insert(0, cls)
    return True


def installed(root: str = _ROOT) -> bool:
    """Whether numba's cache lookup goes through the guard for the package under ``root``."""
    found = _caching()
    cls = _LOCATORS.get(os.path.abspath(root))
    return found is not None and cls is not None and cls in found[1]._locator_classes
