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


# --- the environment merge (a cached caller loaded before its callee is called from Python) ---

_ENV_MODULE = textwrap.dedent("""\
    import numpy as np
    from numba import njit


    @njit(cache=True)
    def inner(n):
        return np.zeros(n, np.int64)


    @njit(cache=True)
    def outer(n):
        return inner(n).shape[0]
    """)

# Compiles and caches both; then, in a second process, loads the caller first and compiles the
# callee again under the name its copy in the caller has (as a process whose numbering of
# compiled functions matches an earlier one's does), so that the callee's own cache holds a
# longer list of constants than the caller's copy.
_ENV_SETUP = textwrap.dedent("""\
    import glob, itertools, os, re, sys
    from numba.core import bytecode
    from numba.core.environment import Environment
    import envmod
    envmod.outer(3)
    if sys.argv[1] == "again":
        for f in glob.glob(os.path.join("__pycache__", "envmod.inner-*")):
            os.remove(f)
        envmod.outer(3)
        name = next(k for k in Environment._memo if "5inner" in k)
        bytecode.FunctionIdentity._unique_ids = itertools.count(int(re.search(r"5innerB\\d+v(\\d+)", name).group(1)))
        envmod.inner(3)
        print(max(len(v.consts) for k, v in Environment._memo.items() if "5inner" in k))
    """)

_ENV_RUN = textwrap.dedent("""\
    import sys
    sys.path.insert(0, {src!r})
    if sys.argv[1] == "merge":
        from contourmesh import _cache_guard
        assert _cache_guard.install_environment_merge()
    import envmod
    envmod.outer(3)
    print(envmod.inner(3).tolist())
    """)


def _python(tmp_path, script, *args):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    return subprocess.run([sys.executable, script, *args], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)


def test_a_callee_called_from_python_after_its_cached_caller_loaded(tmp_path):
    (tmp_path / "envmod.py").write_text(_ENV_MODULE)
    (tmp_path / "setup_env.py").write_text(_ENV_SETUP)
    (tmp_path / "run_env.py").write_text(_ENV_RUN.format(src=_SRC))
    assert _python(tmp_path, "setup_env.py", "first").returncode == 0
    again = _python(tmp_path, "setup_env.py", "again")
    assert again.returncode == 0, again.stderr
    assert int(again.stdout.split()[-1]) == 2  # the callee's own copy is the longer one
    plain = _python(tmp_path, "run_env.py", "plain")  # numba's loading as it is: the fault
    assert plain.returncode != 0 and "descr" in plain.stderr
    merged = _python(tmp_path, "run_env.py", "merge")
    assert merged.returncode == 0, merged.stderr
    assert merged.stdout.split("\n")[0] == "[0, 0, 0]"


def test_environment_merge_is_in_place_and_extends_the_held_copy():
    import pickle

    import numpy as np
    from numba.core import environment

    import contourmesh._kernels  # noqa: F401  (installs the guard)

    assert _cache_guard.environment_merge_installed()
    name = "_contourmesh_test_env_merge"
    held = environment._rebuild_env("contourmesh", [np.dtype(np.int64)], name)
    assert environment._rebuild_env("contourmesh", [np.dtype(np.int64), np.dtype(np.float64)], name) is held
    assert held.consts == [np.dtype(np.int64), np.dtype(np.float64)]
    # a list that does not start with the held one is left alone (numba's behaviour)
    assert environment._rebuild_env("contourmesh", [np.dtype(np.int32), np.dtype(np.int8), 1], name) is held
    assert len(held.consts) == 2
    # numba's own function keeps the first copy as it is: the merge is what extends it
    other = environment._rebuild_env._original("contourmesh", [np.dtype(np.int64)], name + "_plain")
    assert environment._rebuild_env._original("contourmesh", [np.dtype(np.int64), 2], name + "_plain") is other
    assert len(other.consts) == 1
    # pickled environments still name numba's function, so caches load with or without the merge
    data = pickle.dumps(held)
    assert b"numba.core.environment" in data and b"_rebuild_env" in data
    assert pickle.loads(data) is held
    fn = environment._rebuild_env  # installing again keeps the one merge
    assert _cache_guard.install_environment_merge() and environment._rebuild_env is fn
