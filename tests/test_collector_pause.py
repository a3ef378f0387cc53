"""The general mesher holds Python's cyclic garbage collector off while it builds a mesh
(``contourmesh._heap.collector_paused``) and gives it back as it found it."""

from __future__ import annotations

import gc
import threading

import numpy as np
import pytest

import contourmesh
from contourmesh import _heap, volumes


@pytest.fixture
def collector_on():
    was = gc.isenabled()
    gc.enable()
    yield
    if not was:
        gc.disable()


def _vol():
    vol = np.zeros((7, 9, 9), dtype=bool)
    vol[1:6, 1:8, 1:8] = True
    vol[3, 4, 2:7] = False  # (a slit: not the fast path's simple slices)
    return vol


def test_the_collector_is_off_during_a_volume_call_and_on_after(collector_on, monkeypatch):
    seen = []
    real = volumes._assemble

    def spy(*args, **kwargs):
        seen.append(gc.isenabled())
        return real(*args, **kwargs)

    monkeypatch.setattr(volumes, "_assemble", spy)
    m = contourmesh.mesh(_vol())
    assert seen and not any(seen)
    assert gc.isenabled()
    assert len(m.faces) > 0


def test_a_collector_turned_off_by_the_caller_stays_off(collector_on):
    gc.disable()
    contourmesh.mesh(_vol())
    assert not gc.isenabled()
    with _heap.collector_paused():
        assert not gc.isenabled()
    assert not gc.isenabled()


def test_an_error_inside_gives_the_collector_back(collector_on):
    with pytest.raises(ValueError):
        contourmesh.mesh(np.zeros((4, 4, 4), dtype=bool))  # an empty volume: refused
    assert gc.isenabled()
    with pytest.raises(RuntimeError), _heap.collector_paused():
        raise RuntimeError("inside")
    assert gc.isenabled()


def test_overlapping_pauses_end_with_the_last_one_whatever_the_order(collector_on):
    first, second = _heap.collector_paused(), _heap.collector_paused()
    first.__enter__()
    second.__enter__()
    first.__exit__(None, None, None)  # (the first to come in leaves first)
    assert not gc.isenabled()
    second.__exit__(None, None, None)
    assert gc.isenabled()


def test_calls_in_several_threads_leave_the_collector_on(collector_on):
    vol = _vol()
    want = contourmesh.mesh(vol)
    got, errors = [], []
    start = threading.Barrier(3)

    def run():
        try:
            start.wait()
            for _ in range(3):
                got.append(contourmesh.mesh(vol))
        except Exception as e:  # pragma: no cover - reported below
            errors.append(e)

    threads = [threading.Thread(target=run) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(got) == 9
    assert all(np.array_equal(m.faces, want.faces) and np.array_equal(m.vertices, want.vertices) for m in got)
    assert gc.isenabled()
