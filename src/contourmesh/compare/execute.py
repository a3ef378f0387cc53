"""Running a comparison row under a time limit: in this thread, or in a fresh Python process.

One executor serves :func:`contourmesh.compare.methods.run_method` and the runner
(:mod:`contourmesh.compare.runner`):

* :func:`time_limit` raises :class:`RowTimeout` in the main thread after ``seconds`` (``SIGALRM``);
* :func:`call_in_subprocess` runs ``fn(*args)`` in a new interpreter (``subprocess``, not
  ``multiprocessing``, so it also works inside daemonic processes such as Dask's process
  workers and ``ProcessPoolExecutor`` workers).  The child applies the time limit itself (its
  main thread, :func:`time_limit`) and is killed ``grace`` seconds after it, when stuck in
  compiled code.  On Linux the child also dies with its parent (``PR_SET_PDEATHSIG``), so
  stopping a run never leaves a row running.

Failures are told apart: a method that raises or times out is the method's result; a child that
cannot start, or a broken pipe, is the executor's (:class:`ExecutorError`), and the runner neither
caches such a row nor exits 0.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

__all__ = ["RowTimeout", "ExecutorError", "time_limit", "call_in_subprocess", "die_with_parent", "HARD_GRACE"]

#: Extra seconds a child process gets past its time limit (and its start-up) before it is killed.
HARD_GRACE = 60.0

#: Exit status of a child that could not read its work or import what it needs.
_BOOT_FAILED = 70


class RowTimeout(BaseException):
    """The time limit passed (a BaseException, so a method's ``except Exception`` cannot swallow it)."""


class ExecutorError(RuntimeError):
    """The row could not be run for a reason that is not the method's (no process, broken pipe)."""


def _on_alarm(signum, frame):  # pragma: no cover - timing dependent
    raise RowTimeout("time limit reached")


@contextlib.contextmanager
def time_limit(seconds):
    """Raise :class:`RowTimeout` in this (main) thread when ``seconds`` pass; ``None``: no limit.

    Outside the main thread, or without ``setitimer``, this raises RuntimeError: use
    :func:`call_in_subprocess` there.
    """
    if seconds is None:
        yield
        return
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
        raise RuntimeError("time_limit works in the main thread only (SIGALRM); use call_in_subprocess")
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def die_with_parent() -> None:
    """Linux: have the kernel send SIGKILL to this process when its parent ends (no-op elsewhere)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - no prctl
        pass


def _child_env() -> dict:
    """The environment of a child: this one, with this contourmesh first on the path."""
    env = dict(os.environ)
    here = str(Path(__file__).resolve().parents[2])  # the folder that holds the contourmesh package
    parts = [here] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and p != here]
    env["PYTHONPATH"] = os.pathsep.join(parts)
    return env


_CHILD = "from contourmesh.compare.execute import _child_main; _child_main()"


def call_in_subprocess(fn, *args, timeout=None, kill_after=None):
    """Run ``fn(*args)`` in a fresh interpreter; ``fn`` must be importable (a module-level function).

    ``timeout``: seconds the child gives ``fn`` (:func:`time_limit` in its main thread, counted
    from when ``fn`` starts); ``kill_after``: seconds after which this process kills the child,
    start-up included (e.g. ``timeout + HARD_GRACE`` for a child stuck in compiled code).

    Returns ``("ok", value, seconds)``, ``("timeout", None, seconds)`` (the child's time limit
    passed, or it was killed at ``kill_after``) or ``("died", message, seconds)`` (the child was ended by a signal, e.g. a segmentation
    fault in a method's compiled code).  Raises :class:`ExecutorError` when the child cannot be
    started or reports that it could not boot.  ``seconds`` is the wall clock seen here.

    The work and the result travel as pickles between this process and its own child (never
    from a file or a peer).  The child's stdout goes to its stderr, which is discarded unless the
    child fails to boot.
    """
    payload = pickle.dumps((fn, args, timeout), protocol=pickle.HIGHEST_PROTOCOL)
    t0 = time.perf_counter()
    try:
        proc = subprocess.Popen([sys.executable, "-c", _CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, env=_child_env(), close_fds=True)
    except OSError as exc:
        raise ExecutorError(f"cannot start a Python process for the row: {exc}") from exc
    try:
        out, err = proc.communicate(payload, timeout=kill_after)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return "timeout", None, time.perf_counter() - t0
    except BaseException:  # Ctrl-C, SIGTERM: the child ends with the run
        proc.kill()
        proc.wait()
        raise
    seconds = time.perf_counter() - t0
    if proc.returncode == 0 and out:
        try:
            status, value = pickle.loads(out)
        except Exception as exc:  # noqa: BLE001 - a torn pipe
            raise ExecutorError(f"the row's process sent an unreadable result: {exc}") from exc
        return status, value, seconds
    if proc.returncode is not None and proc.returncode < 0:
        try:
            name = signal.Signals(-proc.returncode).name
        except ValueError:
            name = f"signal {-proc.returncode}"
        return "died", f"the row's process was ended by {name}", seconds
    tail = err.decode(errors="replace").strip().splitlines()[-3:]
    raise ExecutorError(f"the row's process failed (exit status {proc.returncode}): " + " | ".join(tail))


def _child_main() -> None:  # pragma: no cover - runs in the child
    die_with_parent()
    result_fd = os.dup(1)
    os.dup2(2, 1)  # a method's prints must not corrupt the result
    sys.stdout = sys.stderr
    try:
        fn, args, timeout = pickle.loads(sys.stdin.buffer.read())
    except BaseException as exc:  # noqa: BLE001
        print(f"contourmesh row process: cannot read its work: {type(exc).__name__}: {exc}", file=sys.stderr)
        os._exit(_BOOT_FAILED)
    try:
        with time_limit(timeout):
            result = ("ok", fn(*args))
    except RowTimeout:
        result = ("timeout", None)
    data = pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL)
    with os.fdopen(result_fd, "wb") as fh:
        fh.write(data)
