"""Issue 16 (round 28): ``_seg_seg_2d`` takes its four orientations from ``_o2_in``, ``_o2``
inlined, instead of four calls of ``_o2`` (each passing every array's fields).  The signs, and so
the answers, must be the same: ``_o2_in`` is compared with ``_o2`` sign for sign, and the form of
``_seg_seg_2d`` before (calls of ``_o2``, kept here compiled as the reference) with the one now,
on random segments on a small grid (many collinear and touching ones, exact in floats), the same
scaled off the grid (the error bound and the exact fallback decide), and on the edges of the
lobster's first build.

(``_fan_winds_once`` became a call instead of inlined in the same round, the same code: the
stars' own tests, ``test_intersect_star_fans.py``, compare it with the form before.)"""

import numpy as np
import pytest
from numba import njit

from contourmesh import intersect as I
from contourmesh.intersect import _o2, _o2_in, _seg_seg_2d
from test_intersect_grid_chunks import _first_build


@njit(cache=False)
def _seg_seg_2d_reference(V, ws, p1, p2, q1, q2, ax, ay):
    """``_seg_seg_2d`` as before round 28: four calls of ``_o2``."""
    d1 = _o2(V, ws, q1, q2, p1, ax, ay)
    d2 = _o2(V, ws, q1, q2, p2, ax, ay)
    d3 = _o2(V, ws, p1, p2, q1, ax, ay)
    d4 = _o2(V, ws, p1, p2, q2, ax, ay)
    if d1 * d2 > 0 or d3 * d4 > 0:
        return False
    if (d1 == 0 and d2 == 0) or (d3 == 0 and d4 == 0):
        for k in range(2):
            t = ax
            if k == 1:
                t = ay
            plo = min(V[p1, t], V[p2, t])
            phi = max(V[p1, t], V[p2, t])
            qlo = min(V[q1, t], V[q2, t])
            qhi = max(V[q1, t], V[q2, t])
            if phi < qlo or qhi < plo:
                return False
        return True
    return True


@njit(cache=False)
def _compare(V, ws, idx):
    """Per row of ``idx`` (four vertices, two axes): 1 where the inlined and the called
    orientations and both forms of the segment test agree, else 0; and how many rows met."""
    ok = np.ones(len(idx), np.int8)
    hits = 0
    for t in range(len(idx)):
        p1, p2, q1, q2, ax, ay = idx[t, 0], idx[t, 1], idx[t, 2], idx[t, 3], idx[t, 4], idx[t, 5]
        if _o2_in(V, ws, p1, p2, q1, ax, ay) != _o2(V, ws, p1, p2, q1, ax, ay):
            ok[t] = 0
        if _o2_in(V, ws, q1, q2, p2, ax, ay) != _o2(V, ws, q1, q2, p2, ax, ay):
            ok[t] = 0
        got = _seg_seg_2d(V, ws, p1, p2, q1, q2, ax, ay)
        if got != _seg_seg_2d_reference(V, ws, p1, p2, q1, q2, ax, ay):
            ok[t] = 0
        if got:
            hits += 1
    return ok, hits


def _rows(rng, nv, n):
    idx = np.empty((n, 6), np.int64)
    idx[:, :4] = rng.integers(0, nv, (n, 4))
    ax = rng.integers(0, 3, n)
    idx[:, 4] = ax
    idx[:, 5] = (ax + rng.integers(1, 3, n)) % 3
    return idx


def _ws(V):
    ws = np.zeros(1 + 3 * I._EXP_LEN, np.float64)
    ws[0] = 1.0 if I._on_small_dyadic_grid(V) else 0.0
    return ws


@pytest.mark.parametrize("scale", [1.0, 0.1, 1e-9 / 3.0])
def test_random_segments(scale):
    """Points of a 5^3 grid (collinear and touching segments everywhere), on it and scaled off it
    (0.1 and 1e-9/3: the float filter then leaves the zeros to the exact fallback)."""
    rng = np.random.default_rng(28)
    V = np.ascontiguousarray(rng.integers(0, 5, (200, 3)).astype(np.float64) * scale)
    ws = _ws(V)
    if scale == 1.0:
        assert ws[0] == 1.0
    else:
        assert ws[0] == 0.0
    ok, hits = _compare(V, ws, _rows(rng, len(V), 200_000))
    assert ok.all()
    assert 0 < hits < 200_000


def test_the_lobsters_first_build(shared_data):
    """Edges of nearby faces of the lobster's first build (the mesh whose pairs the whole-mesh test
    decides in a plane with ``_seg_seg_2d``), on its own coordinates."""
    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    V, F = _first_build(np.transpose(z["volume"], (2, 1, 0)) > 60)
    V = np.ascontiguousarray(V, dtype=np.float64)
    rng = np.random.default_rng(16)
    f = rng.integers(0, len(F) - 64, 300_000)
    g = f + rng.integers(1, 64, len(f))
    idx = np.empty((len(f), 6), np.int64)
    idx[:, 0] = F[f, 0]
    idx[:, 1] = F[f, 1]
    idx[:, 2] = F[g, 1]
    idx[:, 3] = F[g, 2]
    idx[:, 4] = rng.integers(0, 3, len(f))
    idx[:, 5] = (idx[:, 4] + 1 + rng.integers(0, 2, len(f))) % 3
    ok, hits = _compare(V, _ws(V), idx)
    assert ok.all()
    assert hits > 0
