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

import atexit
import contextlib
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

__all__ = ["RowTimeout", "ExecutorError", "time_limit", "call_in_subprocess", "close_row_processes", "die_with_parent",
           "HARD_GRACE"]

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


_CHILD = "from contourmesh.compare.execute import _serve; _serve()"
_LEN = 8  # bytes of the length that precedes each pickle on the pipes


#: Longest single wait (seconds) in :func:`_read_exact`, so that signal handlers run promptly.
_WAKE = 0.25


def _read_exact(fd: int, n: int, deadline) -> bytes | None:
    """``n`` bytes from ``fd``; None when ``deadline`` (``time.monotonic()``) passes first; fewer at EOF."""
    import selectors

    buf = bytearray()
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while len(buf) < n:
            wait = _WAKE if deadline is None else deadline - time.monotonic()
            if wait <= 0:
                return None
            # wake up regularly: a signal the kernel hands to another thread (tqdm's monitor, an
            # executor's) interrupts no system call here, and its handler runs only once we return
            if not sel.select(min(wait, _WAKE)):
                continue
            chunk = os.read(fd, n - len(buf))
            if not chunk:
                break
            buf += chunk
    return bytes(buf)


class _RowProcess:
    """A child interpreter that runs one call after another (:func:`_serve`), until it is closed or killed."""

    def __init__(self):
        self.err = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", _CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=self.err, env=_child_env(), close_fds=True)
        except OSError as exc:
            self.err.close()
            raise ExecutorError(f"cannot start a Python process for the row: {exc}") from exc

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout, self.err):
            try:
                f.close()
            except OSError:
                pass

    def close(self) -> None:
        """Let the child finish (end of its input), then reap it."""
        try:
            self.proc.stdin.close()
            self.proc.wait(5)
        except (OSError, subprocess.TimeoutExpired):
            pass
        self.kill()

    def _stderr_tail(self) -> str:
        try:
            self.err.seek(0)
            lines = self.err.read().decode(errors="replace").strip().splitlines()
        except OSError:
            lines = []
        return " | ".join(lines[-3:])

    def call(self, fn, args, timeout, kill_after):
        payload = pickle.dumps((fn, args, timeout), protocol=pickle.HIGHEST_PROTOCOL)
        t0 = time.perf_counter()
        deadline = None if kill_after is None else time.monotonic() + float(kill_after)
        try:
            try:
                self.proc.stdin.write(len(payload).to_bytes(_LEN, "little") + payload)
                self.proc.stdin.flush()
            except OSError:  # the child is gone: told below
                head = b""
            else:
                head = _read_exact(self.proc.stdout.fileno(), _LEN, deadline)
            if head is None:
                self.kill()
                return "timeout", None, time.perf_counter() - t0
            data = b""
            if len(head) == _LEN:
                data = _read_exact(self.proc.stdout.fileno(), int.from_bytes(head, "little"), deadline)
                if data is None:
                    self.kill()
                    return "timeout", None, time.perf_counter() - t0
        except BaseException:  # Ctrl-C, SIGTERM: the child ends with the run
            self.kill()
            raise
        seconds = time.perf_counter() - t0
        if len(head) == _LEN and data is not None and len(data) == int.from_bytes(head, "little"):
            try:
                status, value = pickle.loads(data)
            except Exception as exc:  # noqa: BLE001 - a torn pipe
                self.kill()
                raise ExecutorError(f"the row's process sent an unreadable result: {exc}") from exc
            if status == "error":  # the called function raised: the executor's caller has a bug
                raise ExecutorError(f"the row's process could not run the row: {value}")
            return status, value, seconds
        # end of file: the child died
        try:
            code = self.proc.wait(5)
        except subprocess.TimeoutExpired:
            code = None
        tail = self._stderr_tail()
        self.kill()
        if code is not None and code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            return "died", f"the row's process was ended by {name}", seconds
        raise ExecutorError(f"the row's process failed (exit status {code}): {tail}")


_LOCAL = threading.local()  # one reusable row process per thread (e.g. per Dask worker thread)


def close_row_processes() -> None:
    """End every row process this process keeps (also done at interpreter exit)."""
    for proc in list(_OPEN):
        proc.kill()
        _OPEN.discard(proc)
    _LOCAL.proc = None


def _close_all():  # pragma: no cover - at interpreter exit
    for proc in list(_OPEN):
        proc.kill()


_OPEN: "set[_RowProcess]" = set()
atexit.register(_close_all)


def call_in_subprocess(fn, *args, timeout=None, kill_after=None, reuse: bool = False):
    """Run ``fn(*args)`` in another Python process; ``fn`` must be importable (a module-level function).

    ``timeout``: seconds the child gives ``fn`` (:func:`time_limit` in its main thread, counted
    from when ``fn`` starts); ``kill_after``: seconds after which this process kills the child
    (e.g. ``timeout + HARD_GRACE`` for a child stuck in compiled code; with ``reuse=False`` the
    child's start-up counts too).  ``reuse=True`` keeps the child for this thread's next call
    (one interpreter start-up, about 2 s, per thread instead of per call); a child that was
    killed, or died, is replaced by the next call.

    Returns ``("ok", value, seconds)``, ``("timeout", None, seconds)`` (the child's time limit
    passed, or it was killed at ``kill_after``) or ``("died", message, seconds)`` (the child was
    ended by a signal, e.g. a segmentation fault in a method's compiled code).  Raises
    :class:`ExecutorError` when the child cannot be started, could not boot, or ``fn`` raised.
    ``seconds`` is the wall clock seen here.

    The work and the result travel as pickles between this process and its own child (never
    from a file or a peer).  The child's stdout goes to its stderr, which is kept in a temporary
    file for the error message of a child that fails.
    """
    proc = getattr(_LOCAL, "proc", None) if reuse else None
    if proc is None or not proc.alive():
        proc = _RowProcess()
        _OPEN.add(proc)
        if reuse:
            _LOCAL.proc = proc
    try:
        return proc.call(fn, args, timeout, kill_after)
    finally:
        if not reuse:
            proc.close()
        if not proc.alive():
            _OPEN.discard(proc)
            if getattr(_LOCAL, "proc", None) is proc:
                _LOCAL.proc = None


def _serve() -> None:  # pragma: no cover - runs in the child
    """The child's loop: read a call, run it under its time limit, send the result; stop at end of input."""
    die_with_parent()
    result_fd = os.dup(1)
    os.dup2(2, 1)  # a method's prints must not corrupt the results
    sys.stdout = sys.stderr
    inp = sys.stdin.buffer

    def send(obj):
        data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
        view = memoryview(len(data).to_bytes(_LEN, "little") + data)
        while view:
            view = view[os.write(result_fd, view):]

    while True:
        head = inp.read(_LEN)
        if len(head) < _LEN:
            os._exit(0)
        payload = inp.read(int.from_bytes(head, "little"))
        try:
            fn, args, timeout = pickle.loads(payload)
        except BaseException as exc:  # noqa: BLE001
            print(f"contourmesh row process: cannot read its work: {type(exc).__name__}: {exc}", file=sys.stderr)
            os._exit(_BOOT_FAILED)
        try:
            with time_limit(timeout):
                result = ("ok", fn(*args))
        except RowTimeout:
            result = ("timeout", None)
        except Exception as exc:  # noqa: BLE001 - reported to the parent as the executor's failure
            result = ("error", f"{type(exc).__name__}: {exc}")
        send(result)
