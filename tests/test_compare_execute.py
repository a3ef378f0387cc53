"""The one executor of compare/ (issue 11): time limits in a child process, reused per thread."""

from __future__ import annotations

import os
import threading
import time

import pytest

from contourmesh.compare.execute import ExecutorError, RowTimeout, call_in_subprocess, close_row_processes, time_limit


def test_a_reused_row_process_serves_calls_until_it_is_killed():
    try:
        _reuse_then_kill()
    finally:
        close_row_processes()
    psutil = pytest.importorskip("psutil")
    assert not psutil.Process().children()


def _reuse_then_kill():
    status, pid, _ = call_in_subprocess(os.getpid, reuse=True)
    assert status == "ok" and pid != os.getpid()
    assert call_in_subprocess(os.getpid, reuse=True)[:2] == ("ok", pid)  # the same child: no new start-up
    # the child's own time limit: a timeout row, and the child stays
    status, value, seconds = call_in_subprocess(time.sleep, 5, timeout=0.3, reuse=True)
    assert (status, value) == ("timeout", None) and seconds < 4
    assert call_in_subprocess(os.getpid, reuse=True)[:2] == ("ok", pid)
    # stuck past kill_after: killed, and the next call gets a new child
    status, _, seconds = call_in_subprocess(time.sleep, 5, kill_after=0.5, reuse=True)
    assert status == "timeout" and seconds < 4
    status, pid2, _ = call_in_subprocess(os.getpid, reuse=True)
    assert status == "ok" and pid2 != pid


def test_a_crash_is_the_rows_and_an_error_in_the_call_is_the_executors():
    status, message, _ = call_in_subprocess(os.abort)
    assert status == "died" and "SIGABRT" in message
    with pytest.raises(ExecutorError, match="invalid literal"):
        call_in_subprocess(int, "x")


def test_time_limit_is_for_the_main_thread():
    with pytest.raises(RowTimeout):
        with time_limit(0.2):
            time.sleep(3)
    errors = []

    def other():
        try:
            with time_limit(1):
                pass
        except RuntimeError as exc:
            errors.append(str(exc))

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert errors and "main thread" in errors[0]
