"""The least-area band's programme run only within a bound (``bands.optimal._annulus_dp_within``)
against the whole programme (``_annulus_dp``), and the band search that uses it
(``_best_band(..., bounded=True)``) against the search with whole programmes (``bounded=False``,
the form before it): bit for bit, on random rings, on rings whose points lie on a coarse grid
(bands that tie in area, floating-point sums deciding), on rings with repeated points (triangles
of no area, as the bridged rings' bridge ends give) and on the least-area bands of a real build.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from contourmesh.bands import optimal
from contourmesh.bands.optimal import (
    N_LAYERS,
    _annulus_dp,
    _annulus_dp_within,
    _best_band,
    _no_nan_areas,
    _step_areas,
    _trace_back,
)


def _ring(rs, n, z, grid=None, repeats=0):
    t = np.sort(rs.uniform(0, 2 * np.pi, n))
    r = rs.uniform(0.3, 2) * (1 + 0.25 * rs.standard_normal(n))
    P = np.c_[r * np.cos(t), r * np.sin(t) * rs.uniform(0.5, 1.5), np.full(n, z)]
    if grid:
        P[:, :2] = np.round(P[:, :2] * grid) / grid
    for _ in range(repeats):  # a point visited twice (as a bridge end), or two neighbours at one place
        i, j = rs.integers(n), rs.integers(n)
        P[j] = P[i]
    return P


def _pair(rs, kind):
    n = int(rs.integers(2, 25))
    m = int(rs.integers(n, 40))
    grid = {"plain": None, "grid": 2, "repeats": None}[kind]
    rep = 2 if kind == "repeats" else 0
    return _ring(rs, n, 0.0, grid, rep), _ring(rs, m, rs.uniform(0.2, 2), grid, rep)


def _compare(A1, A2, s, B):
    """The bounded programme against the whole one at bound ``B``: the same total where the total
    is within ``B`` (and the same band read back from the steps), a number above ``B`` otherwise."""
    n, m = A1.shape
    D = np.empty((2, N_LAYERS, m + 1))
    steps = np.full((n + 1, m + 1), -1, np.int8)
    want = _annulus_dp(A1, A2, s, D, steps, np.bool_(True))
    D2 = np.full((2, N_LAYERS, m + 1), -7.0)  # (its rolling rows need no filling)
    steps2 = np.full((n + 1, m + 1), 77, np.int8)  # (nor its steps: the cells it passes are written)
    got = _annulus_dp_within(A1, A2, s, D2, steps2, np.bool_(True), B)
    cost = _annulus_dp_within(A1, A2, s, D2, np.empty((1, 1), np.int8), np.bool_(False), B)
    assert cost == got or (np.isinf(cost) and np.isinf(got))
    if want <= B:
        assert got == want, (want, got, B)
        if np.isfinite(want):
            assert np.array_equal(_trace_back(steps2, n, m), _trace_back(steps, n, m))
        return True
    assert got > B, (want, got, B)
    return False


@pytest.mark.parametrize("kind", ["plain", "grid", "repeats"])
def test_the_bounded_programme_is_the_whole_programme_within_its_bound(kind):
    rs = np.random.default_rng({"plain": 31, "grid": 32, "repeats": 33}[kind])
    within = above = 0
    for _ in range(60):
        c1, c2 = _pair(rs, kind)
        A1, A2 = _step_areas(c1, c2)
        n = len(c1)
        D = np.empty((2, N_LAYERS, len(c2) + 1))
        totals = [_annulus_dp(A1, A2, s, D, np.empty((1, 1), np.int8), np.bool_(False)) for s in range(n)]
        finite = [t for t in totals if np.isfinite(t)]
        for s in rs.choice(n, size=min(n, 4), replace=False):
            t = totals[s]
            bounds = [np.inf, t, np.nextafter(t, 0.0), np.nextafter(t, np.inf), t * 0.9, t * 1.1, 0.0]
            bounds += [min(finite), max(finite)] if finite else []
            for B in bounds:
                if np.isnan(B):
                    continue
                if _compare(A1, A2, np.int64(s), float(B)):
                    within += 1
                else:
                    above += 1
    assert within > 300 and above > 100, (within, above)


@pytest.mark.parametrize("seed", [51, 52])
def test_the_bounded_programme_on_any_costs_that_are_not_negative(seed):
    """Costs of a few values, many of them large (cells within the bound in runs with gaps between
    them, rows whose run from column 0 leaves the bound before the columns the row before holds),
    many zero (ties): the same totals and bands within every bound."""
    rs = np.random.default_rng(seed)
    within = 0
    for _ in range(150):
        n = int(rs.integers(2, 14))
        m = int(rs.integers(n, 30))
        vals = np.array([0.0, 0.5, 1.0, 3.0, 50.0])
        p = rs.dirichlet(np.ones(len(vals)))
        A1 = rs.choice(vals, size=(n, m), p=p)
        A2 = rs.choice(vals, size=(n, m), p=p)
        for s in range(n):
            D = np.empty((2, N_LAYERS, m + 1))
            t = _annulus_dp(A1, A2, np.int64(s), D, np.empty((1, 1), np.int8), np.bool_(False))
            for B in (t, t + 0.5, t - 0.5, rs.uniform(0, 60), np.inf):
                within += _compare(A1, A2, np.int64(s), float(B))
    assert within > 1000, within


@pytest.mark.parametrize("kind", ["plain", "grid", "repeats"])
def test_the_search_within_bounds_is_the_search_with_whole_programmes(kind):
    rs = np.random.default_rng({"plain": 41, "grid": 42, "repeats": 43}[kind])
    for t in range(80):
        c1, c2 = _pair(rs, kind)
        n, m = len(c1), len(c2)
        k = [2, 3, 5, n][t % 4]  # (one programme each below four start points; the strips from four)
        a = int(rs.integers(n))
        starts = np.sort((a + np.arange(min(k, n))) % n).astype(np.int64)
        A1, A2 = _step_areas(c1, c2)
        D = np.empty((2, N_LAYERS, m + 1))
        out = []
        for bounded in (False, True):
            steps = np.full((n + 1, m + 1), 5, np.int8)
            s, total = _best_band(A1, A2, starts, D, steps, np.bool_(bounded))
            out.append((s, total, _trace_back(steps, n, m)))
        assert out[0][:2] == out[1][:2] and np.array_equal(out[0][2], out[1][2])


@pytest.mark.parametrize("kind", ["plain", "grid", "repeats"])
def test_the_band_either_side_of_the_bounded_size_is_the_band_of_both_searches(kind):
    """``_optimal_edges_in`` runs bounded programmes from ``_BOUNDED_MIN_CELLS`` cells on and whole
    ones below (whole ones are quicker on small grids): on grids just below and above that size,
    its edges, start point and total are those of the search with whole programmes and of the
    search within bounds alike."""
    rs = np.random.default_rng({"plain": 51, "grid": 52, "repeats": 53}[kind])
    cells = optimal._BOUNDED_MIN_CELLS
    assert 100 < cells < 10**6
    sides = {False: 0, True: 0}
    for t in range(24):
        n = int(rs.integers(20, 90))
        m = max(n, int(round(cells / n)) + int(rs.integers(-3, 4)))
        grid = {"plain": None, "grid": 2, "repeats": None}[kind]
        rep = 2 if kind == "repeats" else 0
        c1, c2 = _ring(rs, n, 0.0, grid, rep), _ring(rs, m, rs.uniform(0.2, 2), grid, rep)
        k = [3, 5, n][t % 3]
        a = int(rs.integers(n))
        starts = np.sort((a + np.arange(min(k, n))) % n).astype(np.int64)
        edges, s, total = optimal._optimal_edges_in(c1, c2, starts, np.empty(2 * n * m), np.empty((n + 1) * (m + 1), np.int8))
        A1, A2 = _step_areas(c1, c2)
        for bounded in (False, True):
            steps = np.full((n + 1, m + 1), 5, np.int8)
            got = _best_band(A1, A2, starts, np.empty((2, N_LAYERS, m + 1)), steps, np.bool_(bounded))
            assert got == (s, total) and np.array_equal(_trace_back(steps, n, m), edges)
        sides[n * m >= cells] += 1
    assert min(sides.values()) > 3, sides


def test_huge_coordinates_take_the_whole_programmes():
    """Coordinates whose products could overflow (a NaN area) are not bounded: there a NaN offer
    would stop cheaper ones, which a bounded programme does not see."""
    c1 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert _no_nan_areas(c1, c1 + 1.0)
    assert not _no_nan_areas(c1, c1 * 1e200)
    assert not _no_nan_areas(c1 * np.nan, c1)


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
def test_real_bands_are_the_bands_of_whole_programmes(monkeypatch):
    """Every least-area band of a lobster build: the same start point, total and edges with the
    bounded programmes as with whole ones."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import volume_speed as vs

        vol, sp = vs.make_input("lobster")
    except Exception as exc:  # pragma: no cover - data missing
        pytest.skip(f"lobster not available: {exc}")
    import contourmesh

    calls = []
    orig = optimal._optimal_edges_in

    def wrap(c1, c2, starts, fbuf, bbuf):
        got = orig(c1, c2, starts, fbuf, bbuf)
        calls.append((c1.copy(), c2.copy(), starts.copy(), got[0].copy(), got[1], got[2]))
        return got

    monkeypatch.setattr(optimal, "_optimal_edges_in", wrap)
    optimal._SEEN.clear()
    contourmesh.mesh(vol, spacing=sp)
    monkeypatch.setattr(optimal, "_optimal_edges_in", orig)
    assert len(calls) > 100
    several = 0
    for c1, c2, starts, edges, s, total in calls:
        n, m = len(c1), len(c2)
        assert _no_nan_areas(c1, c2)
        A1, A2 = _step_areas(c1, c2)
        steps = np.empty((n + 1, m + 1), np.int8)
        got = _best_band(A1, A2, starts, np.empty((2, N_LAYERS, m + 1)), steps, np.bool_(False))
        assert got == (s, total) and np.array_equal(_trace_back(steps, n, m), edges)
        several += len(starts) > 1
    assert several > 50
