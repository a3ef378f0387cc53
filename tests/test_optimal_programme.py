"""The least-area band's dynamic programme (``bands.optimal._annulus_dp``) against the same
programme written plainly: every layer of every cell relaxed through the layer rules
``_after_c2`` / ``_after_c1`` below, skipping infinite cells.  The compiled kernel writes the layers'
transitions out per row kind and records each cell's steps in one byte; it must give the same cost
(bit for bit) and, read back into the plain tables (``_decode``), the same recorded moves at every
reachable cell, hence the same band, also where bands tie (points on a coarse grid) and on the
signed costs of the drawn-fidelity band.
"""

from __future__ import annotations

import numpy as np
import pytest

from contourmesh.bands.fidelity import _costs
from contourmesh.bands.optimal import (
    N_LAYERS,
    NONE,
    ROW0,
    ROW_HERE,
    ROW_PAST,
    TWO_ROWS,
    _annulus_dp,
    _step_areas,
    _trace_back,
)


def _after_c1(layer):
    """The layer after a C(1)-advance (a step along the smaller ring)."""
    return ROW_PAST if layer == ROW_HERE else layer


def _after_c2(layer, i, n):
    """The layer after a C(2)-advance at row ``i`` of ``0 .. n`` (rows 0 and ``n`` are one torus row)."""
    at_row0 = i == 0 or i == n
    if layer == NONE:
        return ROW0 if at_row0 else ROW_HERE
    if layer == ROW0:
        return ROW0 if at_row0 else TWO_ROWS
    if layer == ROW_HERE:
        return ROW_HERE
    return TWO_ROWS  # ROW_PAST or TWO_ROWS


def _plain_dp(A1, A2, s):
    """The programme as one loop over rows, cells and layers (the reference)."""
    after_c1, after_c2 = _after_c1, _after_c2
    n, m = A1.shape
    D = np.full((n + 1, N_LAYERS, m + 1), np.inf)
    move = np.zeros((n + 1, N_LAYERS, m + 1), np.int8)
    parent = np.zeros((n + 1, N_LAYERS, m + 1), np.int8)
    D[0, NONE, 0] = 0.0
    for i in range(n + 1):
        ib = (s + i) % n
        for j in range(m):
            for L in range(N_LAYERS):
                d = D[i, L, j]
                if d == np.inf:
                    continue
                L2 = after_c2(L, i, n)
                c = d + A2[ib, j]
                if c < D[i, L2, j + 1]:
                    D[i, L2, j + 1] = c
                    move[i, L2, j + 1], parent[i, L2, j + 1] = 1, L
        if i == n:
            break
        for j in range(m + 1):
            for L in range(N_LAYERS):
                d = D[i, L, j]
                if d == np.inf:
                    continue
                L1 = after_c1(L)
                c = d + A1[ib, j % m]
                if c < D[i + 1, L1, j]:
                    D[i + 1, L1, j] = c
                    move[i + 1, L1, j], parent[i + 1, L1, j] = 0, L
    return D[n, TWO_ROWS, m], D, move, parent


def _decode(steps):
    """The kernel's record of each cell (one byte: two bits per layer, see bands.optimal) as the plain
    programme's tables: per cell and layer, the step's move (0: along C(1), 1: along C(2)) and the
    layer it came from."""
    b = steps.astype(np.int64)
    move = np.zeros((b.shape[0], N_LAYERS, b.shape[1]), np.int8)
    parent = np.zeros_like(move)  # NONE: its C(1)-step from NONE (0, 0)
    x = (b >> 4) & 3  # ROW0: 0 its C(1)-step, 1 the C(2)-step from NONE, 2 from ROW0
    move[:, ROW0], parent[:, ROW0] = x != 0, np.where(x == 1, NONE, ROW0)
    move[:, ROW_HERE], parent[:, ROW_HERE] = 1, np.where((b >> 3) & 1, NONE, ROW_HERE)
    move[:, ROW_PAST], parent[:, ROW_PAST] = 0, np.where((b >> 2) & 1, ROW_HERE, ROW_PAST)
    x = b & 3  # TWO_ROWS: 0 its C(1)-step, else the C(2)-step from TWO_ROWS 1, ROW0 2, ROW_PAST 3
    move[:, TWO_ROWS], parent[:, TWO_ROWS] = x != 0, np.choose(x, [TWO_ROWS, TWO_ROWS, ROW0, ROW_PAST])
    return move, parent


def _plain_trace_back(move, parent, n, m):
    """The band's edges read back from the plain tables (the kernel's former reading)."""
    E = np.empty((n + m, 2), dtype=np.int64)
    i, j, L = n, m, TWO_ROWS
    for k in range(n + m - 1, -1, -1):
        mv, L = move[i, L, j], parent[i, L, j]
        if mv == 0:
            i -= 1
        else:
            j -= 1
        E[k] = i, j
    return E


def _ring(rs, n, z, grid):
    t = np.sort(rs.uniform(0, 2 * np.pi, n))
    r = rs.uniform(0.3, 2) * (1 + 0.2 * rs.standard_normal(n))
    P = np.c_[r * np.cos(t), r * np.sin(t) * rs.uniform(0.5, 1.5), np.full(n, z)]
    if grid:
        P[:, :2] = np.round(P[:, :2] * grid) / grid
    return P


@pytest.mark.parametrize("kind", ["areas", "grid", "signed"])
def test_the_kernel_is_the_plain_programme(kind):
    rs = np.random.default_rng({"areas": 1, "grid": 2, "signed": 3}[kind])
    compared = finite = 0
    for _ in range(40):
        n = int(rs.integers(2, 12))
        m = int(rs.integers(n, 18))
        grid = 2 if kind != "areas" else None
        c1, c2 = _ring(rs, n, 0.0, grid), _ring(rs, m, 1.0, grid)
        if kind == "signed":
            A1, A2 = _costs(c1, c2, rs.uniform(0, 3), 1.0 if rs.random() < 0.5 else -1.0)
        else:
            A1, A2 = _step_areas(c1, c2)
        for s in range(n):
            want, Dref, mref, pref = _plain_dp(A1, A2, s)
            D = np.empty((2, N_LAYERS, m + 1))
            steps = np.full((n + 1, m + 1), -1, np.int8)  # (every cell is written)
            got = _annulus_dp(A1, A2, s, D, steps, np.bool_(True))
            move, parent = _decode(steps)
            dummy = np.empty((1, 1), np.int8)
            cost = _annulus_dp(A1, A2, s, D, dummy, np.bool_(False))
            assert got == want or (np.isinf(got) and np.isinf(want)), (n, m, s)
            assert cost == got or (np.isinf(cost) and np.isinf(got))
            # the moves of every reachable cell, and so the band read back from them
            live = np.isfinite(Dref)
            assert np.array_equal(move[live], mref[live]) and np.array_equal(parent[live], pref[live])
            if np.isfinite(want):
                finite += 1
                assert np.array_equal(_trace_back(steps, n, m), _plain_trace_back(mref, pref, n, m))
            compared += 1
    assert finite > compared // 2  # most programmes reach the goal (else the comparison proves little)


def test_step_areas_are_the_triangle_areas():
    """``_step_areas`` (coordinates read as scalars, several cells of a row at once where the
    compiler can) gives ``_tri_area`` of every step's triangle, bit for bit."""
    from contourmesh.bands.optimal import _tri_area

    rs = np.random.default_rng(7)
    for t in range(30):
        n, m = int(rs.integers(1, 9)), int(rs.integers(1, 12) if t % 3 else rs.integers(12, 70))
        c1 = rs.normal(size=(n, 3)) * rs.uniform(0.1, 100)
        c2 = rs.normal(size=(m, 3)) * rs.uniform(0.1, 100)
        if rs.random() < 0.5:  # lattice points: zero-area (collinear) triangles too
            c1, c2 = np.round(c1), np.round(c2)
        A1, A2 = _step_areas(c1, c2)
        for i in range(n):
            for j in range(m):
                assert A1[i, j] == _tri_area(c1[i], c1[(i + 1) % n], c2[j])
                assert A2[i, j] == _tri_area(c1[i], c2[(j + 1) % m], c2[j])


def test_abs_max_is_the_largest_magnitude_in_any_order():
    """``_abs_max`` (four running maxima) is the plain loop's ``max(amax, |a|, |b|)`` from 0, bit for bit:
    NaNs passed over, signed costs by magnitude, rows of odd and even length."""
    from numba import njit

    from contourmesh.bands.optimal import _abs_max

    @njit
    def plain(A1, A2):
        amax = 0.0
        for i in range(A1.shape[0]):
            for j in range(A1.shape[1]):
                amax = max(amax, abs(A1[i, j]), abs(A2[i, j]))
        return amax

    rs = np.random.default_rng(11)
    for t in range(300):
        shape = (int(rs.integers(1, 7)), int(rs.integers(1, 9)))
        A1, A2 = rs.normal(size=shape) * 10.0 ** rs.integers(-3, 4), rs.normal(size=shape)
        for A in (A1, A2):
            if rs.random() < 0.3:
                A[rs.random(shape) < 0.3] = np.nan
            if rs.random() < 0.2:
                A[rs.random(shape) < 0.3] = -np.inf if rs.random() < 0.5 else 0.0
        want = plain(A1, A2)
        got = _abs_max(A1, A2)
        assert got == want or (np.isnan(got) and np.isnan(want)), (A1, A2)
    assert _abs_max(np.full((2, 3), np.nan), np.full((2, 3), np.nan)) == 0.0


def _abs_max_running(A1, A2):
    """``_abs_max`` as it was: four running maxima of the magnitudes, NaNs passed over."""
    n, m = A1.shape
    p0 = p1 = p2 = p3 = 0.0
    for i in range(n):
        a1 = A1[i]
        a2 = A2[i]
        for j in range(0, m - 1, 2):
            x = abs(a1[j])
            p0 = x if x > p0 else p0
            x = abs(a2[j])
            p1 = x if x > p1 else p1
            x = abs(a1[j + 1])
            p2 = x if x > p2 else p2
            x = abs(a2[j + 1])
            p3 = x if x > p3 else p3
        if m % 2:
            x = abs(a1[m - 1])
            p0 = x if x > p0 else p0
            x = abs(a2[m - 1])
            p1 = x if x > p1 else p1
    p0 = p1 if p1 > p0 else p0
    p2 = p3 if p3 > p2 else p2
    return p2 if p2 > p0 else p0


def test_abs_max_by_integers_is_the_running_maxima():
    """``_abs_max`` (the magnitudes' bits as integers) against its former float form, bit for bit:
    NaNs of either sign and payload, infinities, signed zeros, subnormal numbers, the least-area
    band's step areas and the drawn-fidelity band's signed costs."""
    from contourmesh.bands.optimal import _abs_max

    rs = np.random.default_rng(12)
    specials = np.array([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324, -5e-324, 1.7e308, -1.7e308])
    specials = np.r_[specials, np.frombuffer(np.array([0x7FF0000000000001, 0xFFF8000000000123], np.uint64).tobytes())]
    for t in range(400):
        shape = (int(rs.integers(1, 9)), int(rs.integers(1, 40)))
        A1, A2 = rs.normal(size=shape) * 10.0 ** rs.integers(-300, 300), rs.normal(size=shape)
        for A in (A1, A2):
            if rs.random() < 0.3:
                A[rs.random(shape) < 0.3] = 0.0
            pick = rs.random(shape) < rs.uniform(0, 0.5)
            A[pick] = rs.choice(specials, size=int(pick.sum()))
        want, got = _abs_max_running(A1, A2), _abs_max(A1, A2)
        assert np.array([got]).tobytes() == np.array([want]).tobytes(), (A1, A2)
    for c1, c2 in ((_ring(rs, 30, 0.0, None), _ring(rs, 70, 1.0, None)), (_ring(rs, 9, 0.0, 2), _ring(rs, 31, 1.0, 2))):
        for A1, A2 in (_step_areas(c1, c2), _costs(c1, c2, 1.5, -1.0)):
            assert _abs_max(A1, A2) == _abs_max_running(A1, A2) > 0
