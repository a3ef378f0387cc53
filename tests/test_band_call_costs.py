"""The bands' cheaper forms against the forms they replaced, bit for bit: the initial edge of
section 3.2 in one compiled call (the numpy search kept as ``_initial_edge_reference``) and the
packed rings of the bridge search (offsets summed in Python).  Random rings, rings on a coarse grid
(ties), and the bands of a small volume's mesh."""

from __future__ import annotations

import numpy as np
import pytest

import contourmesh
from contourmesh.bands import bridges as B
from contourmesh.bands.wiederhold import (
    _initial_edge_kernel,
    _initial_edge_reference,
    initial_edge,
)


def _ring3(rs, n, z, grid=None):
    P = np.c_[rs.normal(size=(n, 2)) * rs.uniform(0.5, 20), np.full(n, z)]
    if grid:
        P[:, :2] = np.round(P[:, :2] * grid) / grid
    return P


def test_initial_edge_kernel_equals_the_numpy_search():
    rs = np.random.default_rng(120)
    routes = {"window": 0, "full": 0}
    for t in range(3000):
        n = int(rs.integers(1, 12))
        m = int(rs.integers(1, 200))
        grid = [None, 1, 2][t % 3]  # on a grid: many equal distances (ties)
        c1 = _ring3(rs, n, 0.0, grid)
        c2 = _ring3(rs, m, float(rs.choice([0.5, 1.0, 3.0, 40.0])), grid)
        if t % 5 == 0:  # C(2) near C(1)'s start: the window's answer is taken
            c2[:, :2] = c1[0, :2] + np.round(rs.normal(size=(m, 2)) * 4) / 2
        window = int(rs.choice([0, 1, 3, 32]))
        want = _initial_edge_reference(c1, c2, window)
        got = _initial_edge_kernel(c1, c2, np.int64(window))
        assert got == want and initial_edge(c1, c2, window) == want
        routes["window" if m > 2 * window + 1 else "full"] += 1
    assert min(routes.values()) > 200, routes
    # not finite (the public function takes any arrays): the first NaN, as np.argmin gives it
    c1 = _ring3(rs, 4, 0.0)
    c2 = _ring3(rs, 90, 1.0)
    c2[[7, 40]] = np.nan
    for w in (3, 32):
        assert _initial_edge_kernel(c1, c2, np.int64(w)) == _initial_edge_reference(c1, c2, w)
    c2[0, 2] = np.inf
    assert _initial_edge_kernel(c1, c2, np.int64(3)) == _initial_edge_reference(c1, c2, 3)


def test_initial_edge_keeps_the_numpy_search_for_other_arguments():
    rs = np.random.default_rng(121)
    c1 = _ring3(rs, 5, 0.0)
    c2 = _ring3(rs, 300, 1.0)
    # a radius given, integer or Fortran-ordered arrays: the reference (the same answer)
    for args in ((c1, c2, 32, 0.5), (c1.astype(np.float32), c2, 32, None), (c1, np.asfortranarray(c2), 5, None)):
        assert initial_edge(*args) == _initial_edge_reference(*args)


def test_packed_rings_offsets():
    rs = np.random.default_rng(124)
    for t in range(50):
        rings = [rs.normal(size=(int(rs.integers(1, 9)), 2)) for _ in range(int(rs.integers(1, 6)))]
        pts, off, lens = B._packed_rings(rings)
        assert off.dtype == np.int64 and lens.dtype == np.int64
        assert np.array_equal(lens, [len(r) for r in rings])
        assert np.array_equal(off, np.concatenate([[0], np.cumsum(lens)[:-1]]))
        for r, a, k in zip(rings, off, lens):
            assert np.array_equal(pts[a:a + k], r)


@pytest.fixture
def recorded(monkeypatch):
    """Every initial edge of a mesh call compared with the numpy search (the count of them)."""
    from contourmesh.bands import greedy, wiederhold

    seen = {"initial": 0}
    real_initial = wiederhold.initial_edge

    def initial(c1, c2, window=32, radius=None):
        got = real_initial(c1, c2, window, radius)
        assert got == _initial_edge_reference(c1, c2, window, radius)
        seen["initial"] += 1
        return got

    monkeypatch.setattr(wiederhold, "initial_edge", initial)
    monkeypatch.setattr(greedy, "initial_edge", initial)
    return seen


def test_a_mesh_with_bridged_joins_sees_the_same_initial_edges(recorded):
    # a fork (one ring parts into two) and a hole closing: bridged joins with least-area bands
    z, y, x = np.mgrid[:10, :40, :40]
    r = np.hypot(y - 20, x - 20)
    vol = (r < 14) & ((z < 5) | (np.abs(x - 20) > 1 + (z - 5)))
    vol &= ~((r < 4) & (z > 2) & (z < 7))
    contourmesh.mesh(vol, spacing=(1.0, 1.0, 1.0), triangulation="greedy")
    assert recorded["initial"] > 5
