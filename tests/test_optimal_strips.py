"""The minimum-area band's start-point search by strips gives the answer of the full search.

``bands.optimal._best_start`` runs one programme per start point inside the strip that the
least paths of two other start points leave (``_best_start_strips``).  These tests hold it to the
search that runs the full programme for every start point (``_best_start_each``): the same start
point on random rings, on rings whose points lie on a coarse grid (where distinct bands tie in
area and floating-point sums decide), on the signed costs of the drawn-fidelity band, and on runs
of start points that wrap around the ring.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from contourmesh.bands.fidelity import _costs
from contourmesh.bands.optimal import (
    N_LAYERS,
    _best_start,
    _best_start_each,
    _best_start_strips,
    _cyclic_run,
    _step_areas,
    _strip_costs,
    _strip_dp,
    _strip_path,
    triangulate_band_optimal,
)


def _ring(rs, n, r, z, noise, turn=0.0, grid=None):
    t = np.sort(rs.uniform(0, 2 * np.pi, n)) + turn
    rr = r * (1 + noise * rs.standard_normal(n))
    P = np.c_[rr * np.cos(t), rr * np.sin(t) * rs.uniform(0.5, 1.5), np.full(n, z)]
    if grid:
        P[:, :2] = np.round(P[:, :2] * grid) / grid
    return P


def _both(A1, A2, starts):
    D2 = np.empty((2, N_LAYERS, A1.shape[1] + 1))
    return _best_start_each(A1, A2, starts, D2), _best_start(A1, A2, starts, D2)


@pytest.mark.parametrize("grid", [None, 2, 3])
def test_strips_pick_the_start_point_of_the_full_search(grid):
    rs = np.random.default_rng(11 + (grid or 0))
    declined = 0
    for _ in range(150):
        n = int(rs.integers(4, 40))
        m = int(rs.integers(n, 60))
        c1 = _ring(rs, n, rs.uniform(0.2, 2), 0.0, rs.uniform(0, 0.3), grid=grid)
        c2 = _ring(rs, m, rs.uniform(0.2, 2), 1.0, rs.uniform(0, 0.3), rs.uniform(0, 6), grid=grid)
        A1, A2 = _step_areas(c1, c2)
        each, strips = _both(A1, A2, np.arange(n, dtype=np.int64))
        assert each == strips
        D2 = np.empty((2, N_LAYERS, m + 1))
        declined += _best_start_strips(A1, A2, 0, n, D2) == -2
    assert declined <= 8   # the shortcut answers nearly always (else this test proves little)


def test_strips_on_signed_costs_and_wrapping_runs():
    rs = np.random.default_rng(5)
    for _ in range(150):
        n = int(rs.integers(4, 30))
        m = int(rs.integers(n, 45))
        c1 = _ring(rs, n, rs.uniform(0.2, 2), 0.0, 0.2, grid=3)
        c2 = _ring(rs, m, rs.uniform(0.2, 2), 1.0, 0.2, rs.uniform(0, 6), grid=3)
        A1, A2 = _costs(c1, c2, rs.uniform(0, 3), 1.0 if rs.random() < 0.5 else -1.0)
        k = int(rs.integers(4, n + 1))
        near = int(rs.integers(0, n))
        starts = np.sort((near - k // 2 + np.arange(k)) % n).astype(np.int64)
        each, strips = _both(A1, A2, starts)
        assert each == strips


def test_strip_costs_are_the_least_monotone_paths():
    """Each strip cost equals the least monotone path of its start point over the whole grid."""
    rs = np.random.default_rng(2)
    c1 = _ring(rs, 17, 1.0, 0.0, 0.2)
    c2 = _ring(rs, 23, 1.3, 1.0, 0.2, 1.0)
    A1, A2 = _step_areas(c1, c2)
    n, m = A1.shape
    costs, ok = _strip_costs(A1, A2, 0, n)
    assert ok
    for s in range(n):  # plain dynamic programme over the whole (n + 1) x (m + 1) grid
        D = np.full((n + 1, m + 1), np.inf)
        D[0, 0] = 0.0
        for i in range(n + 1):
            for j in range(m + 1):
                if i > 0:
                    D[i, j] = min(D[i, j], D[i - 1, j] + A1[(s + i - 1) % n, j % m])
                if j > 0:
                    D[i, j] = min(D[i, j], D[i, j - 1] + A2[(s + i) % n, (j - 1) % m])
        assert costs[s] == pytest.approx(D[n, m], rel=1e-12, abs=1e-12)


def test_strips_are_used_and_the_band_is_unchanged_on_long_rings():
    """On two long rings the strip search certifies its answer itself (no fallback), and the
    triangulation equals the one from the full search."""
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    lo = np.c_[10 * np.cos(t), 6 * np.sin(t), np.zeros_like(t)]
    u = np.linspace(0, 2 * np.pi, 230, endpoint=False) + 0.3
    hi = np.c_[10.5 * np.cos(u), 6.2 * np.sin(u), np.ones_like(u)]
    A1, A2 = _step_areas(lo, hi)
    D2 = np.empty((2, N_LAYERS, A1.shape[1] + 1))
    s = _best_start_strips(A1, A2, 0, 200, D2)
    assert s >= 0
    assert s == _best_start_each(A1, A2, np.arange(200, dtype=np.int64), D2)
    f = triangulate_band_optimal(lo, hi)
    assert f.shape == (430, 3)


def test_a_double_cone_sends_the_search_to_the_full_programme():
    """Costs under which the least monotone path is a double cone (every step along ``C(2)`` at
    one point of ``C(1)``: not an annulus).  The strip search cannot certify and declines (-2),
    and the full search's answer stands."""
    rs = np.random.default_rng(3)
    n, m = 9, 14
    A1 = rs.uniform(1, 2, (n, m))
    A2 = rs.uniform(1, 2, (n, m))
    A2[0, :] = 0.0   # start 0: along C(2) at C(1)'s point 0 for free ...
    A1[:, 0] = 0.0   # ... then down C(1) at C(2)'s point 0 for free
    D2 = np.empty((2, N_LAYERS, m + 1))
    starts = np.arange(n, dtype=np.int64)
    costs, ok = _strip_costs(A1, A2, 0, n)
    assert ok and costs[0] == 0.0
    assert _best_start_strips(A1, A2, 0, n, D2) == -2
    each, strips = _both(A1, A2, starts)
    assert each == strips


def _pixel_ring(rs, n, cx, r, z):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) + rs.uniform(0, 1)
    P = np.c_[cx + r * np.cos(t), r * np.sin(t) * rs.uniform(0.6, 1.4), np.full(n, z)]
    P[:, :2] = np.round(P[:, :2] * 2) / 2  # (half-pixel grid: many triangles of equal area)
    return P


def _bridged_pair(rs):
    """A ring and a bridged ring of three (each bridge end visited twice, as the mesher's bridged
    rings are: triangles of no area there), about five times longer, on a half-pixel grid."""
    n = int(rs.integers(20, 60))
    c1 = _pixel_ring(rs, n, 0, n / 6, 0.0)
    parts = [_pixel_ring(rs, int(rs.integers(n, 2 * n)), 8 * j, n / 6, 1.0) for j in range(3)]
    seq = [parts[0][:1]]
    for p in parts[1:]:
        seq += [p, p[:1], parts[0][:1]]
    return c1, np.concatenate(seq + [parts[0]])


def _strips_giving_up(A1, A2, a, k):
    """The strip search as it was before crossing paths were handled: False where the paths of two
    start points cross so that no path of the one between fits (the search then gave up)."""
    n, m = A1.shape
    D = np.empty((2, m + 1))
    move = np.zeros((n + 1, m + 1), dtype=np.int8)
    first = np.empty((k, n + 1), dtype=np.int32)
    lo = np.zeros(n + 1, dtype=np.int64)
    hi = np.full(n + 1, m, dtype=np.int64)
    for t in (0, k - 1):
        _strip_dp_branching(A1, A2, a + t, lo, hi, D, move)
        _strip_path(move, n, m, first[t])
    todo = [(0, k - 1)]
    while todo:
        t0, t1 = todo.pop()
        if t1 - t0 <= 1:
            continue
        t = (t0 + t1) // 2
        for i in range(n + 1):
            hi[i] = m if t + i - t0 >= n else first[t0, t + i - t0 + 1]
            lo[i] = first[t1, t + i - t1] if t + i - t1 >= 0 else 0
        if _strip_dp_branching(A1, A2, a + t, lo, hi, D, move) == np.inf:
            return False
        _strip_path(move, n, m, first[t])
        todo += [(t0, t), (t, t1)]
    return True


def test_crossing_paths_widen_the_strip():
    """Near-tied least paths of two start points can cross (floating-point sums of equal areas in
    different orders), leaving no room between them: the strip is then widened to the rightmost
    and leftmost of the two in each row.  Every strip cost stays the least monotone path of its
    start point over the whole grid, the search no longer gives up there, and its start point is
    the full search's."""
    rs = np.random.default_rng(0)
    crossed = 0
    for _ in range(300):
        c1, c2 = _bridged_pair(rs)
        A1, A2 = _step_areas(c1, c2)
        n, m = A1.shape
        k = int(rs.integers(4, 12))
        near = int(rs.integers(0, n))
        starts = np.sort((near - k // 2 + np.arange(k)) % n).astype(np.int64)
        a = _cyclic_run(starts, n)
        costs, ok = _strip_costs(A1, A2, a, k)
        assert ok
        crossed += not _strips_giving_up(A1, A2, a, k)
        D = np.empty((2, m + 1))
        ent, base = np.empty(n * (m + 1), np.int32), np.empty(n + 1, np.int64)
        for t in range(k):
            whole = _strip_dp(A1, A2, a + t, np.zeros(n + 1, np.int64), np.full(n + 1, m, np.int64), D, ent, base)
            assert costs[t] == pytest.approx(whole, rel=1e-12, abs=1e-12)
        each, strips = _both(A1, A2, starts)
        assert each == strips
    assert crossed >= 3  # (else this test proves little)


@pytest.mark.parametrize(
    ("starts", "n", "a"),
    [([0, 1, 2, 3], 4, 0), ([2, 3, 4], 9, 2), ([0, 1, 7, 8], 9, 7), ([0, 2, 3], 9, -1), ([0, 1, 5, 8], 9, -1)],
)
def test_cyclic_run(starts, n, a):
    assert _cyclic_run(np.array(starts, dtype=np.int64), n) == a


def _strip_dp_reference(A1, A2, s, lo, hi, D, move):
    """``_strip_dp`` as first written (columns taken modulo ``m``, each cell read back from ``D``)."""
    n, m = A1.shape
    inf = np.inf
    for j in range(m + 1):
        D[0, j] = inf
    D[0, 0] = 0.0
    for i in range(n + 1):
        r = i % 2
        ib = (s + i) % n
        for j in range(lo[i], hi[i]):
            d = D[r, j]
            if d != inf:
                c = d + A2[ib, j % m]
                if c < D[r, j + 1]:
                    D[r, j + 1] = c
                    move[i, j + 1] = 1
        if i == n:
            break
        rn = (i + 1) % 2
        for j in range(lo[i + 1], hi[i + 1] + 1):
            D[rn, j] = inf
        for j in range(max(lo[i], lo[i + 1]), min(hi[i], hi[i + 1]) + 1):
            d = D[r, j]
            if d != inf:
                c = d + A1[ib, j % m]
                if c < D[rn, j]:
                    D[rn, j] = c
                    move[i + 1, j] = 0
    return D[n % 2, m] if hi[n] == m else inf


def test_strip_programme_equals_its_first_form_bit_for_bit():
    """The compiled strip programme (no modulo, each cell's cost carried to the next) gives the
    same cost and the same moves as its first form, on random strips (some empty rows, some that
    end short of the last column, coarse-grid rings with tied areas); and so do the two
    programmes that run side by side on the whole grid."""
    from contourmesh.bands.optimal import _grid_dp_pair, _strip_cells, _strip_dp, _strip_entries_path

    rs = np.random.default_rng(12)
    finite = 0
    for t in range(300):
        n = int(rs.integers(2, 25))
        m = int(rs.integers(n, 40))
        c1 = _ring(rs, n, rs.uniform(0.2, 2), 0.0, 0.2, grid=3 if t % 2 else None)
        c2 = _ring(rs, m, rs.uniform(0.2, 2), 1.0, 0.2, rs.uniform(0, 6), grid=3 if t % 2 else None)
        A1, A2 = _step_areas(c1, c2)
        # a strip between two monotone paths: row i + 1 starts at or before row i ends
        hi = np.sort(rs.integers(0, m + 1, n + 1)).astype(np.int64)
        lo = np.minimum(np.sort(rs.integers(0, m + 1, n + 1)), hi).astype(np.int64)
        lo[0] = 0
        lo[1:] = np.minimum(lo[1:], hi[:-1])
        if t % 3:
            hi[n] = m
        if t % 7 == 0:
            lo[:] = 0
            hi[:] = m  # the whole grid
        s = int(rs.integers(0, n))
        D1, D2 = np.full((2, m + 1), 7.0), np.full((2, m + 1), 7.0)
        M1 = np.zeros((n + 1, m + 1), np.int8)
        ent, base = np.empty(_strip_cells(lo, hi), np.int32), np.empty(n + 1, np.int64)
        c_ref = _strip_dp_reference(A1, A2, s, lo, hi, D1, M1)
        c_new = _strip_dp(A1, A2, s, lo, hi, D2, ent, base)
        assert c_ref == c_new or (np.isinf(c_ref) and np.isinf(c_new))
        assert _strip_rows_equal(D1, D2, lo, hi)
        if np.isfinite(c_ref):  # the same path
            f1, f2 = np.empty(n + 1, np.int32), np.empty(n + 1, np.int32)
            _strip_path(M1, n, m, f1)
            _strip_entries_path(ent, base, n, m, f2)
            assert np.array_equal(f1, f2)
        finite += bool(np.isfinite(c_ref))
        # the first and last start points' programmes side by side (_strip_costs' _grid_dp_pair):
        # each the cost, moves and rows of the branching strip programme over the whole grid
        u = int(rs.integers(0, 2 * n))
        full_lo, full_hi = np.zeros(n + 1, np.int64), np.full(n + 1, m, np.int64)
        ref = []
        for v in (s, u):
            D, M = np.full((2, m + 1), 7.0), np.zeros((n + 1, m + 1), np.int8)
            ref.append((_strip_dp_branching(A1, A2, v, full_lo, full_hi, D, M), D, M))
        D, E = np.full((2, m + 1), 7.0), np.full((2, m + 1), 7.0)
        M, N = np.zeros((n + 1, m + 1), np.int8), np.zeros((n + 1, m + 1), np.int8)
        got = _grid_dp_pair(A1, A2, s, u, D, E, M, N)
        for (c, D_ref, M_ref), c_new, D_new, M_new in zip(ref, got, (D, E), (M, N)):
            assert c == c_new and np.array_equal(D_ref, D_new) and np.array_equal(M_ref, M_new)
    assert finite > 100  # most strips hold a path to the last column


@pytest.mark.parametrize("grid", [None, 2])
def test_one_near_start_records_its_tables_once_and_the_band_is_unchanged(grid):
    # optimal_edges_from records the moves in the programme of the one start point the strips
    # leave near the bound (or the one given) instead of running it again: the same start point,
    # total and edges as the search that runs each start point and then the best one with tables
    from contourmesh.bands.optimal import _annulus_dp, _best_band, _optimal_edges_in, _trace_back, optimal_edges_from

    rs = np.random.default_rng(23 + (grid or 0))
    kinds = {"one": 0, "several": 0}
    for t in range(120):
        n = int(rs.integers(3, 30))
        m = int(rs.integers(n, 50))
        c1 = _ring(rs, n, rs.uniform(0.2, 2), 0.0, rs.uniform(0, 0.3), grid=grid)
        c2 = _ring(rs, m, rs.uniform(0.2, 2), 1.0, rs.uniform(0, 0.3), rs.uniform(0, 6), grid=grid)
        k = [1, 2, 5, n][t % 4]
        a = int(rs.integers(n))
        starts = np.sort((a + np.arange(min(k, n))) % n).astype(np.int64)
        A1, A2 = _step_areas(c1, c2)
        D2 = np.empty((2, N_LAYERS, m + 1))
        s = _best_start_each(A1, A2, starts, D2)
        s = starts[0] if s < 0 else s
        steps = np.empty((n + 1, m + 1), dtype=np.int8)
        total = _annulus_dp(A1, A2, s, D2, steps, np.bool_(True))
        edges, s2, total2 = optimal_edges_from(c1, c2, starts)
        assert (s2, total2) == (s, total)
        assert np.array_equal(edges, _trace_back(steps, n, m))
        for bounded in (False, True):  # (whole programmes, and programmes within the bounds they know)
            steps2 = np.empty_like(steps)
            got = _best_band(A1, A2, starts, D2, steps2, np.bool_(bounded))
            assert got == (s, total)
            assert np.array_equal(_trace_back(steps2, n, m), edges)
        # the same through buffers left dirty by other bands (triangulate_band_optimal's, kept per thread)
        fbuf = rs.normal(size=2 * n * m + int(rs.integers(0, 9)))
        bbuf = rs.integers(-128, 128, size=(n + 1) * (m + 1) + int(rs.integers(0, 9))).astype(np.int8)
        e3, s3, total3 = _optimal_edges_in(c1, c2, starts, fbuf, bbuf)
        assert (s3, total3) == (s, total) and np.array_equal(e3, edges)
        if len(starts) >= 4:
            free, ok = _strip_costs(A1, A2, _cyclic_run(starts, n), len(starts))
            if ok:
                kinds["one" if (free <= free.min() + 1e-9 * (n + m) * max(A1.max(), A2.max()) * 2).sum() == 1
                      else "several"] += 1
    assert kinds["one"] >= 10 and kinds["several"] >= 3, kinds  # both routes are taken


# The strip programme and the two ends' programmes before each row became one pass without
# branches (the reference the compiled kernels are held to, bit for bit).

@njit
def _strip_dp_branching(A1, A2, s, lo, hi, D, move):
    """``_strip_dp`` as it was before one pass per row: a C(2)-pass and a C(1)-pass per row, each
    offer taken by a branch, the row's step costs found by a modulo."""
    n, m = A1.shape
    inf = np.inf
    for j in range(m + 1):
        D[0, j] = inf
    D[0, 0] = 0.0
    for i in range(n + 1):
        r = i % 2
        ib = (s + i) % n
        a2row = A2[ib]
        if lo[i] < hi[i]:
            d = D[r, lo[i]]  # the cell's final cost, carried to the next cell in a register
            for j in range(lo[i], hi[i]):  # j < hi[i] <= m: the column itself (no modulo)
                nxt = D[r, j + 1]
                if d != inf:
                    c = d + a2row[j]
                    if c < nxt:
                        nxt = c
                        D[r, j + 1] = c
                        move[i, j + 1] = 1
                d = nxt
        if i == n:
            break
        rn = (i + 1) % 2
        for j in range(lo[i + 1], hi[i + 1] + 1):
            D[rn, j] = inf
        a1row = A1[ib]
        for j in range(max(lo[i], lo[i + 1]), min(hi[i], hi[i + 1]) + 1):
            d = D[r, j]
            if d != inf:
                c = d + (a1row[0] if j == m else a1row[j])  # A1[ib, j % m], 0 <= j <= m
                if c < D[rn, j]:
                    D[rn, j] = c
                    move[i + 1, j] = 0
    return D[n % 2, m] if hi[n] == m else inf


@njit
def _grid_dp_pair_branching(A1, A2, s, u, D, E, move, move_u):
    """``_grid_dp_pair`` as it was before one pass per row (two passes per row, with branches)."""
    n, m = A1.shape
    inf = np.inf
    for j in range(m + 1):
        D[0, j] = inf
        E[0, j] = inf
    D[0, 0] = 0.0
    E[0, 0] = 0.0
    for i in range(n + 1):
        r = i % 2
        a2s = A2[(s + i) % n]
        a2u = A2[(u + i) % n]
        d = D[r, 0]
        e = E[r, 0]
        for j in range(m):
            nxt = D[r, j + 1]
            if d != inf:
                c = d + a2s[j]
                if c < nxt:
                    nxt = c
                    D[r, j + 1] = c
                    move[i, j + 1] = 1
            d = nxt
            nxt = E[r, j + 1]
            if e != inf:
                c = e + a2u[j]
                if c < nxt:
                    nxt = c
                    E[r, j + 1] = c
                    move_u[i, j + 1] = 1
            e = nxt
        if i == n:
            break
        rn = (i + 1) % 2
        a1s = A1[(s + i) % n]
        a1u = A1[(u + i) % n]
        for j in range(m + 1):
            D[rn, j] = inf
            E[rn, j] = inf
            jj = 0 if j == m else j  # A1[ib, j % m], 0 <= j <= m
            d = D[r, j]
            if d != inf:
                c = d + a1s[jj]
                if c < inf:
                    D[rn, j] = c
                    move[i + 1, j] = 0
            e = E[r, j]
            if e != inf:
                c = e + a1u[jj]
                if c < inf:
                    E[rn, j] = c
                    move_u[i + 1, j] = 0
    return D[n % 2, m], E[n % 2, m]



@njit
def _strip_costs_branching(A1, A2, a, k):
    """``_strip_costs`` with the branching programmes in it."""
    n, m = A1.shape
    D = np.empty((2, m + 1))
    move = np.zeros((n + 1, m + 1), dtype=np.int8)
    cost = np.full(k, np.inf)
    first = np.empty((k, n + 1), dtype=np.int32)   # per start, per row of its own: entry column
    lo = np.zeros(n + 1, dtype=np.int64)
    hi = np.full(n + 1, m, dtype=np.int64)
    # the two ends' programmes over the whole grid, side by side (_grid_dp_pair)
    move_b = np.zeros((n + 1, m + 1), dtype=np.int8)
    c0, c1 = _grid_dp_pair_branching(A1, A2, a, a + k - 1, D, np.empty((2, m + 1)), move, move_b)
    if c0 == np.inf:
        return cost, False
    cost[0] = c0
    _strip_path(move, n, m, first[0])
    if c1 == np.inf:
        return cost, False
    cost[k - 1] = c1
    _strip_path(move_b, n, m, first[k - 1])
    stack = np.empty((2 * k + 2, 2), dtype=np.int64)
    stack[0, 0] = 0
    stack[0, 1] = k - 1
    top = 1
    while top > 0:
        top -= 1
        t0 = stack[top, 0]
        t1 = stack[top, 1]
        if t1 - t0 <= 1:
            continue
        t = (t0 + t1) // 2
        for i in range(n + 1):
            u = t + i - t0          # this row among the rows of start t0: the path above
            hi[i] = m if u >= n else first[t0, u + 1]
            v = t + i - t1          # ... and of start t1: the path below
            lo[i] = first[t1, v] if v >= 0 else 0
        c = _strip_dp_branching(A1, A2, a + t, lo, hi, D, move)
        if c == np.inf:
            # no path fits: the two paths cross (least paths that tie, as on the liver's bridged
            # rings, whose repeated bridge ends give triangles of no area).  Exchanging their
            # pieces where they cross gives two least paths of the same two start points that do
            # not: the rightmost and the leftmost of the two in each row, between which a least
            # path of this start point lies
            for i in range(n + 1):
                v = t + i - t1
                if v >= 0:
                    hi[i] = max(hi[i], m if v >= n else first[t1, v + 1])  # (t1's, rightmost)
                u = t + i - t0
                if u <= n:
                    lo[i] = min(lo[i], first[t0, u])  # (t0's, leftmost)
            c = _strip_dp_branching(A1, A2, a + t, lo, hi, D, move)
            if c == np.inf:
                return cost, False
        cost[t] = c
        _strip_path(move, n, m, first[t])
        stack[top, 0] = t0
        stack[top, 1] = t
        stack[top + 1, 0] = t
        stack[top + 1, 1] = t1
        top += 2
    return cost, True


def _strip_rows_equal(D1, D2, lo, hi):
    """The last two rows' cells of a strip (``lo[i] .. hi[i]``) hold the same bytes in ``D1`` and
    ``D2``, where the strip has no empty row (``_strip_dp`` gives up at an empty row, and sets its
    two rows to infinity first, so only the strip's cells are compared)."""
    n = len(lo) - 1
    if (hi < lo).any():
        return True
    for i in (n - 1, n):
        if i >= 0 and D1[i % 2, lo[i]:hi[i] + 1].tobytes() != D2[i % 2, lo[i]:hi[i] + 1].tobytes():
            return False
    return True


@njit
def _strip_dp_loop_per_kind(A1, A2, s, lo, hi, D, ent, base):
    """``_strip_dp`` as it was before one loop per row: a loop per kind of cell in each row
    (C(2)-steps only before and after the row before's strip, both steps between, the last
    column apart), the cells of the row before outside its strip never read."""
    n, m = A1.shape
    inf = np.inf
    for j in range(m + 1):
        D[0, j] = inf
    D[0, 0] = 0.0
    a2row = A2[s % n]
    if lo[0] < hi[0]:
        d = D[0, lo[0]]
        for j in range(lo[0], hi[0]):
            nxt = D[0, j + 1]
            if d != inf:
                c = d + a2row[j]
                if c < nxt:
                    nxt = c
                    D[0, j + 1] = c
            d = nxt
    ib = s % n
    off = np.int64(0)
    for i in range(1, n + 1):
        r = i % 2
        q = 1 - r
        a1row = A1[ib]
        ib = ib + 1 if ib < n - 1 else 0
        a2row = A2[ib]
        plo = lo[i - 1]
        phi = hi[i - 1]
        j0 = lo[i]
        j1 = hi[i]
        b = off - j0
        base[i] = b
        if j1 < j0:
            continue
        off += j1 - j0 + 1
        d = inf
        if plo <= j0 and j0 <= phi:
            c = D[q, j0] + (a1row[0] if j0 == m else a1row[j0])
            d = c if c < inf else inf
        D[r, j0] = d
        e = j0
        ent[b + j0] = e
        ja = max(j0 + 1, plo)
        jb = min(j1, phi)
        jm = min(jb, m - 1)
        for j in range(j0 + 1, min(ja, j1 + 1)):
            c = d + a2row[j - 1]
            t = c < inf
            d = c if t else inf
            e = e if t else j
            D[r, j] = d
            ent[b + j] = e
        for j in range(ja, jm + 1):
            c = D[q, j] + a1row[j]
            v = c if c < inf else inf
            c = d + a2row[j - 1]
            t = c < v
            d = c if t else v
            e = e if t else j
            D[r, j] = d
            ent[b + j] = e
        for j in range(max(ja, jm + 1), jb + 1):
            c = D[q, j] + a1row[0]
            v = c if c < inf else inf
            c = d + a2row[j - 1]
            t = c < v
            d = c if t else v
            e = e if t else j
            D[r, j] = d
            ent[b + j] = e
        for j in range(max(ja, jb + 1), j1 + 1):
            c = d + a2row[j - 1]
            t = c < inf
            d = c if t else inf
            e = e if t else j
            D[r, j] = d
            ent[b + j] = e
    return D[n % 2, m] if hi[n] == m else inf


def test_strip_programme_in_one_loop_per_row_equals_a_loop_per_kind():
    """The strip programme in one loop per row (both rows of ``D`` set to infinity first, the cells
    right of the row before's strip read as infinity) gives the form with a loop per kind of cell
    bit for bit: the cost, the strip's last rows and the path read back from the entry columns,
    on the cases of the other forms' tests (signed, infinite and NaN costs, empty rows, the whole
    grid; the whole search is held to the branching programmes below)."""
    from contourmesh.bands.optimal import _strip_cells, _strip_dp, _strip_entries_path

    rs = np.random.default_rng(83)
    seen = {"finite": 0, "bad costs": 0, "signed": 0, "empty rows": 0}
    for t in range(900):
        A1, A2, lo, hi = _strip_case(rs, t)
        n, m = A1.shape
        s = int(rs.integers(0, 2 * n))
        cells = _strip_cells(lo, hi) + int(rs.integers(0, 5))
        got, want = [], []
        for f, out in ((_strip_dp_loop_per_kind, want), (_strip_dp, got)):
            D = rs.normal(size=(2, m + 1))  # (left by another strip)
            ent = rs.integers(-9, 9, cells).astype(np.int32)
            base = np.zeros(n + 1, np.int64)
            c = f(A1, A2, s, lo, hi, D, ent, base)
            path = None
            if np.isfinite(c):
                path = np.empty(n + 1, np.int32)
                _strip_entries_path(ent, base, n, m, path)
            out.append((np.float64(c).tobytes(), D, None if path is None else path.tobytes()))
        (c_ref, D_ref, p_ref), (c_new, D_new, p_new) = want[0], got[0]
        assert c_ref == c_new and p_ref == p_new
        assert _strip_rows_equal(D_ref, D_new, lo, hi)
        seen["finite"] += p_ref is not None
        seen["bad costs"] += not (np.isfinite(A1).all() and np.isfinite(A2).all())
        seen["signed"] += bool((A1 < 0).any() or (A2 < 0).any())
        seen["empty rows"] += bool((hi < lo).any())
    assert min(seen.values()) > 50, seen


def _strip_case(rs, t):
    """Step costs (areas of random or coarse-grid rings, the mesher's kind of bridged rings,
    signed fidelity costs, some with infinite or NaN costs) and a strip between two monotone
    paths (some rows empty or short of the last column, or the whole grid)."""
    kind = t % 4
    if kind == 3:
        c1, c2 = _bridged_pair(rs)
        c1, c2 = c1[:int(rs.integers(3, 20))], c2[:int(rs.integers(20, 45))]
    else:
        n = int(rs.integers(2, 25))
        m = int(rs.integers(n, 40))
        c1 = _ring(rs, n, rs.uniform(0.2, 2), 0.0, 0.2, grid=3 if kind else None)
        c2 = _ring(rs, m, rs.uniform(0.2, 2), 1.0, 0.2, rs.uniform(0, 6), grid=3 if kind else None)
    if kind == 2:
        A1, A2 = _costs(c1, c2, rs.uniform(0, 3), 1.0 if rs.random() < 0.5 else -1.0)
    else:
        A1, A2 = _step_areas(c1, c2)
    n, m = A1.shape
    if t % 5 == 0:  # a few infinite or NaN steps (coordinates past the safe range)
        for A in (A1, A2):
            A.ravel()[rs.integers(0, n * m, 3)] = rs.choice([np.inf, np.nan, -np.inf], 3)
    hi = np.sort(rs.integers(0, m + 1, n + 1)).astype(np.int64)
    lo = np.minimum(np.sort(rs.integers(0, m + 1, n + 1)), hi).astype(np.int64)
    lo[0] = 0
    lo[1:] = np.minimum(lo[1:], hi[:-1])
    if t % 3:
        hi[n] = m
    if t % 7 == 0:
        lo[:] = 0
        hi[:] = m
    if t % 6 == 1 and n > 2:  # a row with no cell (crossing paths)
        i = int(rs.integers(1, n))
        hi[i] = lo[i] - 1 if lo[i] > 0 else hi[i]
        lo[i] = hi[i] + 1
    return A1, A2, lo, hi


def test_strip_programme_in_one_pass_equals_the_branching_form():
    """The strip programme in one branch-free pass per row, its path read back from each row's
    entry columns, gives the branching form's cost, rows and path bit for bit (from moves left by
    other strips too); and the two ends' programmes side by side give its costs, rows and, from
    zeroed moves, its moves."""
    from contourmesh.bands.optimal import _grid_dp_pair, _strip_cells, _strip_dp, _strip_entries_path

    rs = np.random.default_rng(41)
    seen = {"finite": 0, "bad costs": 0, "signed": 0, "empty rows": 0}
    for t in range(600):
        A1, A2, lo, hi = _strip_case(rs, t)
        n, m = A1.shape
        s = int(rs.integers(0, 2 * n))
        D1, D2 = np.full((2, m + 1), 7.0), np.full((2, m + 1), 7.0)
        M1 = rs.integers(0, 2, (n + 1, m + 1)).astype(np.int8)  # (moves of another strip)
        ent = rs.integers(-9, 9, _strip_cells(lo, hi) + int(rs.integers(0, 5))).astype(np.int32)
        base = np.zeros(n + 1, np.int64)
        c_ref = _strip_dp_branching(A1, A2, s, lo, hi, D1, M1)
        c_new = _strip_dp(A1, A2, s, lo, hi, D2, ent, base)
        assert np.float64(c_ref).tobytes() == np.float64(c_new).tobytes()
        assert _strip_rows_equal(D1, D2, lo, hi)
        if np.isfinite(c_ref):
            f1, f2 = np.empty(n + 1, np.int32), np.empty(n + 1, np.int32)
            _strip_path(M1, n, m, f1)
            _strip_entries_path(ent, base, n, m, f2)
            assert np.array_equal(f1, f2)
            seen["finite"] += 1
        seen["bad costs"] += not (np.isfinite(A1).all() and np.isfinite(A2).all())
        seen["signed"] += bool((A1 < 0).any() or (A2 < 0).any())
        seen["empty rows"] += bool((hi < lo).any())
        # the two ends' programmes side by side
        u = int(rs.integers(0, 2 * n))
        got, want = [], []
        for f, out in ((_grid_dp_pair_branching, want), (_grid_dp_pair, got)):
            D, E = np.full((2, m + 1), 7.0), np.full((2, m + 1), 7.0)
            M, N = np.zeros((n + 1, m + 1), np.int8), np.zeros((n + 1, m + 1), np.int8)
            c = f(A1, A2, s, u, D, E, M, N)
            out.append((np.array(c).tobytes(), D.tobytes(), E.tobytes(), M.tobytes(), N.tobytes()))
        assert got == want
    assert min(seen.values()) > 50, seen


@pytest.mark.parametrize("seed", [0, 1])
def test_strip_search_with_the_branching_programmes_is_unchanged(seed):
    """The whole strip search (every start point's cost, on the mesher's kind of bridged rings and
    on random rings) is the same bit for bit as with the branching programmes in it."""
    rs = np.random.default_rng(70 + seed)
    for t in range(60):
        if t % 2:
            c1, c2 = _bridged_pair(rs)
        else:
            n = int(rs.integers(4, 40))
            c1 = _ring(rs, n, rs.uniform(0.2, 2), 0.0, 0.2, grid=3 if t % 4 else None)
            c2 = _ring(rs, int(rs.integers(n, 60)), rs.uniform(0.2, 2), 1.0, 0.2, rs.uniform(0, 6))
        A1, A2 = _step_areas(c1, c2)
        n = len(c1)
        k = int(rs.integers(4, n + 1))
        a = int(rs.integers(0, n))
        got = _strip_costs(A1, A2, a, k)
        want = _strip_costs_branching(A1, A2, a, k)
        assert got[1] == want[1] and got[0].tobytes() == want[0].tobytes()
