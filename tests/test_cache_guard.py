"""The guard on numba's on-disk cache (contourmesh._cache_guard).

Numba takes a cached kernel as fresh when its own source file is unchanged, even if a kernel of
another module that it calls (and holds compiled inside it) has changed.  The guard adds a
fingerprint of the package's compiled modules to the freshness stamp.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import textwrap

import pytest
from numba.core.registry import CPUDispatcher

import contourmesh
from contourmesh import _cache_guard

_PKG = os.path.dirname(os.path.abspath(contourmesh.__file__))
_SRC = os.path.dirname(_PKG)

_INNER = textwrap.dedent("""\
    from numba import njit


    @njit(no_cpython_wrapper=True, no_cfunc_wrapper=True)
    def inner(x):
        return x + {step}
    """)

_OUTER = textwrap.dedent("""\
    from numba import njit

    from .a import inner


    @njit(cache=True)
    def outer(x):
        return inner(x)
    """)

_RUN = textwrap.dedent("""\
    import os, sys
    sys.path.insert(0, {src!r})
    if os.environ.get("GUARD") == "1":
        from contourmesh import _cache_guard
        assert _cache_guard.install(os.path.join(os.getcwd(), "pkgx"))
    from pkgx.b import outer
    print(outer(1), sum(outer.stats.cache_hits.values()))
    """)


def _package(tmp_path, step):
    pkg = tmp_path / "pkgx"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(_INNER.format(step=step))
    (pkg / "b.py").write_text(_OUTER)
    (tmp_path / "run.py").write_text(_RUN.format(src=_SRC))


def _run(tmp_path, guard):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["GUARD"] = "1" if guard else "0"
    out = subprocess.run([sys.executable, "run.py"], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    value, hits = out.stdout.split()
    return int(value), int(hits)


def test_a_changed_callee_in_another_module_recompiles_the_cached_caller(tmp_path):
    _package(tmp_path, step=1)
    assert _run(tmp_path, guard=True) == (2, 0)  # compiled and cached
    assert _run(tmp_path, guard=True) == (2, 1)  # loaded from the cache
    _package(tmp_path, step=2)  # only the callee's module changes
    assert _run(tmp_path, guard=True) == (3, 0)  # compiled again: the new callee
    assert _run(tmp_path, guard=True) == (3, 1)  # and cached again


def test_fingerprint_covers_compiled_modules_only(tmp_path):
    pkg = tmp_path / "p"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "k.py").write_text("from numba import njit\n")
    (pkg / "sub" / "j.py").write_text("import numba\n")
    (pkg / "front.py").write_text("X = 1\n")
    first = _cache_guard.fingerprint(str(pkg))
    _cache_guard.fingerprint.cache_clear()
    (pkg / "front.py").write_text("X = 2\n")  # no compiled code: the cache stays fresh
    assert _cache_guard.fingerprint(str(pkg)) == first
    _cache_guard.fingerprint.cache_clear()
    (pkg / "sub" / "j.py").write_text("import numba\nY = 3\n")
    assert _cache_guard.fingerprint(str(pkg)) != first
    _cache_guard.fingerprint.cache_clear()


def test_guard_leaves_other_packages_alone(tmp_path):
    cls = _cache_guard.locator_for(_PKG)
    assert cls is not None
    assert cls.from_function(test_guard_leaves_other_packages_alone, __file__) is None


_KERNEL_MODULES = sorted(
    os.path.relpath(os.path.join(d, f), _SRC)[:-3].replace(os.sep, ".").removesuffix(".__init__")
    for d, _, files in os.walk(_PKG) for f in files
    if f.endswith(".py") and "numba" in open(os.path.join(d, f), encoding="utf-8").read())


@pytest.mark.parametrize("name", _KERNEL_MODULES)
def test_every_cached_kernel_of_the_package_goes_through_the_guard(name):
    module = importlib.import_module(name)
    cached = [v for v in vars(module).values()
              if isinstance(v, CPUDispatcher) and v.__module__ == name and v._cache.__class__.__name__ != "NullCache"]
    assert not cached or _cache_guard.installed()
    for kernel in cached:
        locator = kernel._cache._impl.locator
        assert getattr(locator, "guarded_root", None) == _PKG, f"{name}.{kernel.__name__} is cached unguarded"


def test_no_module_takes_njit_from_numba_directly():
    # (a module that did would define its kernels before the guard is in place if imported first)
    for name in _KERNEL_MODULES:
        path = os.path.join(_SRC, *name.split(".")) + ".py"
        if not os.path.exists(path):
            path = os.path.join(_SRC, *name.split("."), "__init__.py")
        text = open(path, encoding="utf-8").read()
        assert "from numba import njit" not in text or name == "contourmesh._kernels", name


def test_the_package_has_cached_kernels_to_guard():
    total = 0
    for name in _KERNEL_MODULES:
        module = importlib.import_module(name)
        total += sum(isinstance(v, CPUDispatcher) and v._cache.__class__.__name__ != "NullCache"
                     for v in vars(module).values())
    assert total > 50
