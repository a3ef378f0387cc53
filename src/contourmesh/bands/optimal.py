"""Minimum-area band triangulation (Fuchs, Kedem & Uselton 1977).

Every valid band between ``C(1)`` (``n`` points) and ``C(2)`` (``m >= n`` points) is a closed
monotone path on the toroidal graph whose nodes are the edges ``(p(1)_i, p(2)_j)`` and whose
arcs advance one contour by one point (each arc is one triangle).  Such a path meets every
column: in particular it contains an edge at the fixed point ``p(2)_1`` of the larger contour,
paired with some start point ``p(1)_s``.  For each ``s`` a dynamic programme over the
``(n + 1) x (m + 1)`` grid finds the cheapest path from ``(s, 1)`` to ``(s + n, m + 1)``; the
minimum over ``s`` is the optimum.  Cost = total triangle area, so the result is the band of
least surface area.  Memory ``O(n m)``; time ``O(n^2 m)`` for one programme per start point (the
smaller contour is ``C(1)``), ``O(n m log n)`` plus one programme per start point tied with the best
where the start points are searched by strips (:func:`_best_start`, below): least paths from
different start points can be taken not to cross, so each start point's programme runs between the
paths of two others (Fuchs, Kedem and Uselton's own divide and conquer over the start points).

Valid band = a topological annulus.  A monotone path whose ``C(2)``-advances all happen at one
point of ``C(1)`` (equivalently, all ``C(1)``-advances at one point of ``C(2)``) visits one torus
node twice: the band is a "double cone" whose two fans share the diagonal of that node, an
edge with four triangles (non-manifold; for a segment polygon, a doubly covered triangle).
Such paths are excluded: the DP carries a small layer index recording at which torus rows
(points of ``C(1)``) the ``C(2)``-advances have happened so far (none / only row 0 / only one row
``0 < r < n``, still on it or already left / two or more rows), and only paths ending in the
"two or more rows" layer count.  This costs a constant factor of 5.  (Wiederhold and greedy
follow their own rules and can, on very dissimilar pairs, produce such a double cone.)

H. Fuchs, Z. M. Kedem and S. P. Uselton, "Optimal surface reconstruction from planar
contours", Communications of the ACM 20(10), 1977.

Ties are broken deterministically: within a DP, advancing ``C(1)`` wins on equal cost; among
start points, the smallest ``s`` with the minimum total wins.
"""

from __future__ import annotations

import threading

import numpy as np

from .._kernels import njit
from .._recent import Recent
from .wiederhold import edges_to_faces, oriented_pair, validate_band_polygons

__all__ = ["triangulate_band_optimal", "optimal_edges", "MAX_OPTIMAL_CELLS", "MAX_OPTIMAL_WORK"]

#: Largest ``n * m`` the optimal band accepts: its tables take 19 bytes per cell (about 290 MiB),
#: and the strip search 4 bytes per cell of its strips (:func:`_strip_dp`; narrow but for ties).
MAX_OPTIMAL_CELLS = 16_000_000
#: Largest ``min(n, m)^2 * max(n, m)`` it accepts (about 8 ns each here: about a minute).
MAX_OPTIMAL_WORK = 8_000_000_000


@njit(cache=True)
def _tri_area(p, q, r):
    ux = q[0] - p[0]
    uy = q[1] - p[1]
    uz = q[2] - p[2]
    vx = r[0] - p[0]
    vy = r[1] - p[1]
    vz = r[2] - p[2]
    cx = uy * vz - uz * vy
    cy = uz * vx - ux * vz
    cz = ux * vy - uy * vx
    return 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)


@njit(cache=True)
def _step_areas(c1, c2):
    """``A1[i, j]`` = area of ``(a_i, a_{i+1}, b_j)``; ``A2[i, j]`` = area of ``(a_i, b_{j+1}, b_j)``.

    The arithmetic of :func:`_tri_area` (the same operations in the same order, so the same
    numbers) on coordinates read as scalars: no array view per triangle.  ``c2``'s coordinates
    are first copied into three arrays with its first point again at the end, so that the inner
    loop has no modulo and the compiler does several cells at once (half the time on the liver's
    bridged rings; a square root is exact in either form)."""
    n = c1.shape[0]
    m = c2.shape[0]
    A1 = np.empty((n, m))
    A2 = np.empty((n, m))
    _step_areas_into(c1, c2, A1, A2)
    return A1, A2


@njit(cache=True)
def _step_areas_into(c1, c2, A1, A2):
    """:func:`_step_areas` written into ``A1`` and ``A2`` (``(n, m)`` each)."""
    n = c1.shape[0]
    m = c2.shape[0]
    bx = np.empty(m + 1)
    by = np.empty(m + 1)
    bz = np.empty(m + 1)
    for j in range(m + 1):
        jj = j % m
        bx[j] = c2[jj, 0]
        by[j] = c2[jj, 1]
        bz[j] = c2[jj, 2]
    for i in range(n):
        i1 = (i + 1) % n
        px, py, pz = c1[i, 0], c1[i, 1], c1[i, 2]
        ux, uy, uz = c1[i1, 0] - px, c1[i1, 1] - py, c1[i1, 2] - pz  # a_i -> a_{i+1}
        a1 = A1[i]
        a2 = A2[i]
        for j in range(m):
            vx = bx[j] - px  # a_i -> b_j
            vy = by[j] - py
            vz = bz[j] - pz
            cx = uy * vz - uz * vy
            cy = uz * vx - ux * vz
            cz = ux * vy - uy * vx
            a1[j] = 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
            wx = bx[j + 1] - px  # a_i -> b_{j+1}
            wy = by[j + 1] - py
            wz = bz[j + 1] - pz
            cx = wy * vz - wz * vy
            cy = wz * vx - wx * vz
            cz = wx * vy - wy * vx
            a2[j] = 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)


# Layers of the dynamic programme (see the module docstring): which torus rows (points of
# C(1)) the C(2)-advances seen so far were made at.
NONE = 0          # no C(2)-advance yet
ROW0 = 1          # only at row 0 (= row n on the torus)
ROW_HERE = 2      # only at one row 0 < r < n, and the path is still on that row
ROW_PAST = 3      # only at one row 0 < r < n, and the path has left it
TWO_ROWS = 4      # at two or more distinct rows: the band is an annulus (the goal layer)
N_LAYERS = 5

# The programme's record of a cell (:func:`_annulus_dp`'s ``steps``): one byte, the step into each
# layer of the cell but NONE's (always the C(1)-step from NONE) in its bits: TWO_ROWS's in bits 0-1
# (0 the C(1)-step from TWO_ROWS, else the C(2)-step from TWO_ROWS 1, ROW0 2 or ROW_PAST 3),
# ROW_PAST's in bit 2 (its C(1)-step from ROW_PAST 0 or ROW_HERE 1), ROW_HERE's in bit 3 (its
# C(2)-step from ROW_HERE 0 or NONE 1) and ROW0's in bits 4-5 (0 the C(1)-step from ROW0, else the
# C(2)-step from NONE 1 or ROW0 2)
_FROM_NONE = 1
_FROM_ROW0 = 2
_FROM_ROW_PAST = 3
_FROM_TWO_ROWS = 1
_FROM_ROW_HERE = 1
_PAST_BITS = 2
_HERE_BITS = 3
_ROW0_BITS = 4


@njit(cache=True, inline="always")
def _c2_offers(row0, a2, x0, x1, x2, x3, x4, y1, y2, y4, k1, k2, k4):
    """A cell's C(2)-step offers (from the cell before it in its row, whose layers' costs are
    ``x0 .. x4``, at step cost ``a2``) taken into the C(1)-step offers ``y1, y2, y4`` and their
    steps ``k1, k2, k4`` (see :func:`_annulus_dp`): from the layers in increasing order, an offer
    winning only where it is strictly less.  Returns the new ``y1, y2, y4, k1, k2, k4``.  Inlined
    into both programmes (:func:`_annulus_dp`, :func:`_annulus_dp_within`): the same operations in
    the same order as written out in each."""
    if row0:
        c = x0 + a2  # NONE -> ROW0
        if c < y1:
            y1 = c
            k1 = _FROM_NONE
        c = x1 + a2  # ROW0 -> ROW0
        if c < y1:
            y1 = c
            k1 = _FROM_ROW0
    else:
        c = x0 + a2  # NONE -> ROW_HERE
        if c < y2:
            y2 = c
            k2 = _FROM_NONE
        c = x1 + a2  # ROW0 -> TWO_ROWS
        if c < y4:
            y4 = c
            k4 = _FROM_ROW0
    c = x2 + a2  # ROW_HERE -> ROW_HERE
    if c < y2:
        y2 = c
        k2 = 0
    c = x3 + a2  # ROW_PAST -> TWO_ROWS
    if c < y4:
        y4 = c
        k4 = _FROM_ROW_PAST
    c = x4 + a2  # TWO_ROWS -> TWO_ROWS
    if c < y4:
        y4 = c
        k4 = _FROM_TWO_ROWS
    return y1, y2, y4, k1, k2, k4


@njit(cache=True)
def _annulus_dp(A1, A2, s, D, steps, keep):
    """Least total area of an annular path from edge ``(s, 0)`` to ``(s + n, m)``.

    One pass over the rows ``i = 0..n`` and in each row over the cells ``t = 0..m``: a cell takes
    the C(1)-advance from the row before (``(i - 1, t) -> (i, t)``), then the C(2)-advance from the
    cell before it in its row (``(i, t - 1) -> (i, t)``), whose costs are final and carried in
    registers.  ``D[r, layer, j]`` holds row ``i`` at ``r = i % 2`` (two rolling rows); if
    ``keep``, ``steps[i, t]`` (one byte per cell, every cell written) records the best step into
    each layer of the cell, for backtracking (:func:`_trace_back`; its bits are described above
    :func:`_annulus_dp`).  On equal cost the C(1)-advance (offered first) wins, and among the offers of one kind
    the one from the lower layer.  Callers pass ``keep`` as ``np.bool_``: a literal
    ``True``/``False`` would compile the programme once for each value (the version for the literal
    ``False`` ran a fifth faster on the liver's costly bands, 0.65 against 0.83 ms: about 20 ms of
    the liver's mesh, not worth a second compiled programme).

    The layers' transitions are written out per row kind (rows 0 and ``n``, where a
    C(2)-advance is at row 0, and the others): a C(2)-advance takes NONE to ROW0 at row 0 or
    ``n`` and to ROW_HERE elsewhere, ROW0 to itself at row 0 or ``n`` and to TWO_ROWS elsewhere,
    ROW_HERE to itself, ROW_PAST and TWO_ROWS to TWO_ROWS; a C(1)-advance takes ROW_HERE to
    ROW_PAST and keeps every other layer.  So a layer's step is one of at most four (NONE's
    always the C(1)-advance, ROW0's too except in rows 0 and ``n``, ROW_HERE's always a
    C(2)-advance, ROW_PAST's always a C(1)-advance).  Infinite cells offer infinity instead of
    being skipped (except NONE's, finite in column 0 only): the same winning offers in the same
    order as relaxing every layer of every cell by these rules, row by row (all C(2)-advances of
    a row, then its C(1)-advances to the next), so the same costs and, at every reachable cell,
    the same steps (``tests/test_optimal_programme.py`` compares it with that loop written
    plainly).
    """
    n, m = A1.shape
    inf = np.inf
    for L in range(N_LAYERS):
        for j in range(m + 1):
            D[1, L, j] = inf  # the row before row 0: nothing reached (its C(1)-steps cost 0 below)
    none_row = np.zeros(m)
    for i in range(n + 1):
        r = i % 2
        ib = (s + i) % n                      # the C(1) point of row i
        a2row = A2[ib]
        a1row = none_row if i == 0 else A1[(ib + n - 1) % n]  # the C(1)-steps into row i
        p1 = D[1 - r, ROW0]  # the row before
        p2 = D[1 - r, ROW_HERE]
        p3 = D[1 - r, ROW_PAST]
        p4 = D[1 - r, TWO_ROWS]
        d1 = D[r, ROW0]
        d2 = D[r, ROW_HERE]
        d3 = D[r, ROW_PAST]
        d4 = D[r, TWO_ROWS]
        row0 = i == 0 or i == n
        # NONE (no C(2)-step yet) is finite in column 0 only: elsewhere it would offer infinity
        # (or NaN), which wins no comparison
        x0 = 0.0 if i == 0 else D[1 - r, NONE, 0] + a1row[0]
        D[r, NONE, 0] = x0
        x1 = x2 = x3 = x4 = inf
        for t in range(m + 1):
            # cell (i, t): first the C(1)-step from (i - 1, t), where every layer keeps its own,
            # except ROW_HERE, which becomes ROW_PAST (offered before ROW_PAST's own) ...
            a1 = a1row[t] if t < m else a1row[0]
            y1 = p1[t] + a1
            ch = p2[t] + a1
            cp = p3[t] + a1
            y3 = cp if cp < ch else ch
            y4 = p4[t] + a1
            y2 = inf
            k1 = 0  # each layer's step (see _FROM_ROW0): the C(1)-step unless an offer below wins
            k2 = 0
            k4 = 0
            if t > 0:
                # ... then the C(2)-steps from (i, t - 1), whose costs are final (x0 .. x4), from
                # the layers in increasing order
                y1, y2, y4, k1, k2, k4 = _c2_offers(row0, a2row[t - 1], x0, x1, x2, x3, x4, y1, y2, y4, k1, k2, k4)
                x0 = inf
            if keep:
                steps[i, t] = (k1 << _ROW0_BITS) | (k2 << _HERE_BITS) | \
                    (0 if cp < ch else _FROM_ROW_HERE) << _PAST_BITS | k4
            d1[t] = y1
            d2[t] = y2
            d3[t] = y3
            d4[t] = y4
            x1 = y1
            x2 = y2
            x3 = y3
            x4 = y4
    return D[n % 2, TWO_ROWS, m]


@njit(cache=True)
def _annulus_dp_within(A1, A2, s, D, steps, keep, B):
    """:func:`_annulus_dp` where only a total of at most ``B`` matters, for step costs that are
    not negative and not NaN (the triangle areas of :func:`_step_areas` of coordinates whose
    products cannot overflow, see :func:`_no_nan_areas`): the same total where it is at most
    ``B`` (else a number above ``B``, or infinity), and where ``keep``, the same steps at every
    cell that the band traced back from such a total passes.

    Adding a cost that is not negative never makes a sum smaller, rounded or not, so a path
    through a cell whose cost exceeds ``B`` ends above ``B``: such cells (their every layer above
    ``B``) are not needed.  Each row is run only from the first column where the row before has a
    cell within ``B`` (or column 0, while the path down it is within ``B``) to where its C(2)-steps
    leave ``B`` past the last such column of the row before; the C(1)-steps from cells outside the
    row before's columns within ``B`` offer infinity instead of their cost above ``B``.  An offer
    above ``B`` wins no cell whose cost is at most ``B`` (it is larger than that cost; ties go to
    the first offer of the least cost either way), so such a cell gets the same cost and the same
    step from the same offers in the same order.  On the liver's bridged bands about a seventh of
    the cells have a cost within the band's total.

    The rolling rows are read and written as ``D[r, layer, t]`` and ``A2[ib, t - 1]``, not through
    a view of each layer's row taken at every row as :func:`_annulus_dp` does: here the row loop's
    exits left each view counted in and out (an atomic count and release) at every row, nine a row,
    a cost beside the few cells a row that lie within the bound (the lobster's least-area bands
    37.2 -> 35.5 ms, the liver's 62.2 -> 60.3, CPU; the same sums in the same order)."""
    n, m = A1.shape
    inf = np.inf
    none_row = np.zeros(m)
    plo = np.int64(-1)  # the columns of the row before with a cell within B: plo .. phi (-1: none)
    phi = np.int64(-1)
    got_m = False
    for i in range(n + 1):
        r = i % 2
        ib = (s + i) % n
        a1row = none_row if i == 0 else A1[(ib + n - 1) % n]
        rb = 1 - r  # (the row before: D is indexed whole, see the docstring's last paragraph)
        row0 = i == 0 or i == n
        x0 = 0.0 if i == 0 else D[1 - r, NONE, 0] + a1row[0]
        D[r, NONE, 0] = x0
        if x0 <= B:
            t = np.int64(0)
        elif plo >= 0:
            t = plo
            x0 = inf  # (its C(2)-step is above B)
        else:
            return inf  # no cell of this row within B, nor of the rows after it
        x1 = x2 = x3 = x4 = inf
        nlo = np.int64(-1)
        nhi = np.int64(-1)
        while t <= m:
            if plo <= t and t <= phi:
                a1 = a1row[t] if t < m else a1row[0]
                y1 = D[rb, ROW0, t] + a1
                ch = D[rb, ROW_HERE, t] + a1
                cp = D[rb, ROW_PAST, t] + a1
                y3 = cp if cp < ch else ch
                y4 = D[rb, TWO_ROWS, t] + a1
            else:
                if t > 0 and x0 > B and x1 > B and x2 > B and x3 > B and x4 > B:
                    if t > phi:
                        break  # nothing within B further right in this row
                    # (t < plo: a C(2)-run from column 0 that left B) on at plo; the cells
                    # passed over are above B, as infinity for the row after (which may read them)
                    for q in range(t, plo):
                        D[r, ROW0, q] = inf
                        D[r, ROW_HERE, q] = inf
                        D[r, ROW_PAST, q] = inf
                        D[r, TWO_ROWS, q] = inf
                    t = plo
                    x0 = x1 = x2 = x3 = x4 = inf
                    continue
                y1 = ch = cp = y3 = y4 = inf
            y2 = inf
            k1 = 0
            k2 = 0
            k4 = 0
            if t > 0:
                y1, y2, y4, k1, k2, k4 = _c2_offers(row0, A2[ib, t - 1], x0, x1, x2, x3, x4, y1, y2, y4, k1, k2, k4)
                x0 = inf
            if keep:
                steps[i, t] = (k1 << _ROW0_BITS) | (k2 << _HERE_BITS) | \
                    (0 if cp < ch else _FROM_ROW_HERE) << _PAST_BITS | k4
            D[r, ROW0, t] = y1
            D[r, ROW_HERE, t] = y2
            D[r, ROW_PAST, t] = y3
            D[r, TWO_ROWS, t] = y4
            x1 = y1
            x2 = y2
            x3 = y3
            x4 = y4
            if y1 <= B or y2 <= B or y3 <= B or y4 <= B:
                if nlo < 0:
                    nlo = t
                nhi = t
            if t == m and i == n:
                got_m = True
            t += 1
        plo = nlo
        phi = nhi
    return D[n % 2, TWO_ROWS, m] if got_m else inf


@njit(cache=True)
def _dp_to(A1, A2, s, D, steps, keep, B, bounded):
    """:func:`_annulus_dp_within` where ``bounded`` (the costs are known not negative and not NaN),
    else :func:`_annulus_dp` (the whole programme, whatever ``B``)."""
    if bounded:
        return _annulus_dp_within(A1, A2, s, D, steps, keep, B)
    return _annulus_dp(A1, A2, s, D, steps, keep)


#: Coordinates of at most this magnitude give triangle areas that are not NaN (:func:`_no_nan_areas`).
_AREA_SAFE = 1e150


@njit(cache=True)
def _no_nan_areas(c1, c2):
    """Whether every coordinate of ``c1`` and ``c2`` is at most :data:`_AREA_SAFE` in magnitude:
    then the differences and their products in :func:`_step_areas_into` stay finite (below
    ``8e300``), a square may overflow only to infinity, and no area is NaN (infinity at worst).
    The areas are then not negative and not NaN, as :func:`_annulus_dp_within` needs."""
    for i in range(c1.shape[0]):
        for d in range(c1.shape[1]):
            if not abs(c1[i, d]) <= _AREA_SAFE:
                return False
    for i in range(c2.shape[0]):
        for d in range(c2.shape[1]):
            if not abs(c2[i, d]) <= _AREA_SAFE:
                return False
    return True


@njit(cache=True)
def optimal_edges(c1, c2):
    """See :func:`optimal_edges_from`: every start point of ``c1`` is tried (the optimum)."""
    return optimal_edges_from(c1, c2, np.arange(c1.shape[0]))


@njit(cache=True)
def optimal_edges_from(c1, c2, starts):
    """Least-area annular edge sequence between ``c1`` (``n >= 2``) and ``c2`` (``m >= n``) among
    those whose edge at ``c2``'s first point starts at one of ``starts`` (increasing indices of
    ``c1``; all of them for the optimum).

    Returns
    -------
    edges : ndarray of int64, shape (n + m, 2)
        Edges ``(i, j)`` relative to the start ``(s, 0)``; consecutive pairs form triangles.
    s : int
        Start index on ``c1`` of the optimal band.
    total : float
        Its total triangle area.
    """
    n, m = c1.shape[0], c2.shape[0]
    return _optimal_edges_in(c1, c2, starts, np.empty(2 * n * m), np.empty((n + 1) * (m + 1), np.int8))


@njit(cache=True)
def _optimal_edges_in(c1, c2, starts, fbuf, bbuf):
    """:func:`optimal_edges_from` with its largest arrays in the buffers ``fbuf`` (float64, at least
    ``2 n m``: the step areas) and ``bbuf`` (int8, at least ``(n + 1) (m + 1)``: the programme's
    steps), whose contents do not matter: the same result."""
    n, m = c1.shape[0], c2.shape[0]
    A1 = fbuf[:n * m].reshape((n, m))
    A2 = fbuf[n * m:2 * n * m].reshape((n, m))
    _step_areas_into(c1, c2, A1, A2)
    steps = bbuf[:(n + 1) * (m + 1)].reshape((n + 1, m + 1))
    D2 = np.empty((2, N_LAYERS, m + 1))
    bounded = n * m >= _BOUNDED_MIN_CELLS and _no_nan_areas(c1, c2)
    best_s, total = _best_band(A1, A2, starts, D2, steps, bounded)
    return _trace_back(steps, n, m), best_s, total


#: Fewest cells ``n m`` for which the least-area band's programmes run only within their bound
#: (:func:`_best_band`'s ``bounded``; the same start point, total and steps either way).  On
#: smaller grids the whole programme is quicker: its one loop per row has no tests of the bound,
#: and there about a third of the cells are within it (the lobster's and the liver's bands under
#: 8 000 cells, most of the lobster's: 12.3 ms bounded, 9.2 ms whole per build; above some
#: 12 000 cells the bound wins, on the liver's costly bands twice over).
_BOUNDED_MIN_CELLS = 10_000


@njit(cache=True)
def _best_band(A1, A2, starts, D2, steps, bounded):
    """The start point :func:`_best_start` picks (``starts[0]`` where none is finite) and its
    programme's total; its steps recorded in ``steps``.

    ``bounded`` (the costs are not negative and not NaN, :func:`_no_nan_areas`): where a bound on
    the total that matters is known (the strip search's bound and margin, the best total so far,
    the best start point's own total when it runs again to record), the programmes run only over
    the cells within it (:func:`_annulus_dp_within`): the same start point, total and steps as
    with ``bounded`` False, which runs every programme over the whole grid (the liver's least-area
    bands' programmes 0.10 -> 0.03 s).

    Where one start point is given, or the strip search leaves one start point near the bound
    and certifies it, that start point's one programme records its steps: it is not run a second
    time for them (the same programme on the same numbers: the same cost and steps).  Where it
    leaves several, they run without recording and the best runs again recording (a programme
    that records costs about 1.5 programmes without; on the liver, recording all of two or three
    near start points saved nothing when it cost 1.7)."""
    n, m = A1.shape
    k = starts.shape[0]
    if k == 1:
        return starts[0], _annulus_dp(A1, A2, starts[0], D2, steps, np.bool_(True))
    best_s = -2
    bound = np.inf
    if k >= _STRIP_MIN_STARTS:
        a = _cyclic_run(starts, n)
        if a >= 0:
            near, low, tol = _near_starts(A1, A2, a, k)
            if low >= 0.0:
                n_near = 0
                for s in range(n):
                    if near[s]:
                        n_near += 1
                        only = s
                if n_near == 1:
                    c = _dp_to(A1, A2, only, D2, steps, np.bool_(True), low + tol, bounded)
                    if c <= low + tol:
                        return only, c
                else:
                    best_s, c, recorded = _near_best_kept(A1, A2, near, low, tol, D2, steps, bounded)
                    if recorded:  # (the best is the first near start point: its steps are in steps)
                        return best_s, c
                    bound = c  # (the best's own total, where best_s >= 0)
    if best_s == -2:
        best_s, bound = _best_start_each_within(A1, A2, starts, D2, bounded)
    if best_s < 0:
        return starts[0], _annulus_dp(A1, A2, starts[0], D2, steps, np.bool_(True))
    return best_s, _dp_to(A1, A2, best_s, D2, steps, np.bool_(True), bound, bounded)


@njit(cache=True)
def _best_start(A1, A2, starts, D2):
    """The start point of ``starts`` whose annular path costs least (-1 if none is finite).

    Where ``starts`` is a run of consecutive start points (cyclically) the programme runs once
    per start point only inside the strip that the paths of its neighbours leave
    (:func:`_best_start_strips`, ``O(n m log k)`` plus a full programme for each start point
    tied with the best) instead of ``O(n m k)``; same answer, and one full programme per start
    point where the shortcut cannot certify it.
    """
    if starts.shape[0] >= _STRIP_MIN_STARTS:
        a = _cyclic_run(starts, A1.shape[0])
        if a >= 0:
            s = _best_start_strips(A1, A2, a, starts.shape[0], D2)
            if s >= -1:
                return s
    return _best_start_each(A1, A2, starts, D2)


@njit(cache=True)
def _best_start_each(A1, A2, starts, D2):
    """:func:`_best_start` by one full programme per start point (``O(n m)`` each)."""
    dummy = np.empty((1, 1), dtype=np.int8)
    best_s = -1
    best = np.inf
    for s in starts:
        c = _annulus_dp(A1, A2, s, D2, dummy, np.bool_(False))
        if c < best:
            best = c
            best_s = s
    return best_s


@njit(cache=True)
def _best_start_each_within(A1, A2, starts, D2, bounded):
    """:func:`_best_start_each` and the best start point's total (-1 and infinity where none is
    finite); where ``bounded``, each programme runs only within the best total so far
    (:func:`_annulus_dp_within`): a start point's total is exact where it is at most that bound
    and above it otherwise, so the first start point of the least total wins as there, with its
    exact total."""
    dummy = np.empty((1, 1), dtype=np.int8)
    best_s = -1
    best = np.inf
    for s in starts:
        c = _dp_to(A1, A2, s, D2, dummy, np.bool_(False), best, bounded)
        if c < best:
            best = c
            best_s = s
    return best_s, best


#: Fewest start points for which the strip search is used (below it, one programme each).
_STRIP_MIN_STARTS = 4


@njit(cache=True)
def _cyclic_run(starts, n):
    """``a`` if the increasing ``starts`` are ``a, a + 1, ..., a + k - 1`` modulo ``n``, else -1."""
    k = starts.shape[0]
    if k == n:
        return 0
    if k > n:
        return -1
    gaps = 0
    a = starts[0]
    for t in range(k):
        nxt = starts[(t + 1) % k]
        cur = starts[t]
        if t == k - 1:
            nxt += n
        if nxt != cur + 1:
            gaps += 1
            a = starts[(t + 1) % k]
    return a if gaps == 1 else -1


@njit(cache=True)
def _strip_dp(A1, A2, s, lo, hi, D, ent, base):
    """Least cost of a monotone path (annulus or not) from start ``s`` over the cells
    ``lo[i] <= j <= hi[i]`` of each row ``i`` only, ``lo`` and ``hi`` not decreasing (a strip
    between two monotone paths).  ``D`` is two rolling rows.  For the path
    (:func:`_strip_entries_path`), each cell ``(i, j)`` of a row ``i >= 1`` gets in
    ``ent[base[i] + j]`` the column where its least path entered row ``i`` (its own column where
    the C(1)-step wins); ``base`` (``n + 1`` integers) is filled here, the rows' cells one after
    another in ``ent``, which must hold :func:`_strip_cells` of ``lo``, ``hi`` integers.  A row
    with no cell leaves no path: infinity at once (``ent`` and ``base`` then filled only so far).

    Each row after the first is one pass over its cells in one loop: a cell takes the C(1)-step
    from the row before, then the C(2)-step from the cell before it (carried in a register), the
    later winning only where strictly less, chosen without branches.  Both rows of ``D`` are set
    to infinity first, so a cell of the row before outside its strip reads infinity: such a cell
    is right of that strip (``lo`` does not decrease), where the row before wrote nothing (its
    own row of ``D`` was last written two rows up, left of its strip's end, as ``hi`` does not
    decrease either), and an offer from infinity (infinity, or NaN for a cost of minus infinity)
    wins no comparison, as the offers that the branching form skips (``tests/test_optimal_strips.py``
    holds it to that form and to the form with a loop per kind of cell, bit for bit).  Narrow
    strips are most of the search's (on the liver's bridged bands half of them are at most
    three cells wide), and there a loop per kind of cell (C(2)-steps only before the row
    before's strip and after it, both between, the last column apart) cost about three times
    one loop per row: its branches on each loop's length are not predictable (the liver's and
    the lobster's strip searches 53 -> 37 and 31 -> 22 ms)."""
    n, m = A1.shape
    inf = np.inf
    for j in range(m + 1):
        D[0, j] = inf
        D[1, j] = inf
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
    ib = s % n  # the C(1) point of the row before
    off = np.int64(0)
    for i in range(1, n + 1):
        q = 1 - i % 2
        dq = D[q]  # the row before
        dr = D[1 - q]
        a1row = A1[ib]  # the C(1)-steps into row i
        ib = ib + 1 if ib < n - 1 else 0
        a2row = A2[ib]
        j0 = lo[i]
        j1 = hi[i]
        b = off - j0
        base[i] = b
        if j1 < j0:
            return inf  # (an empty row: no path)
        off += j1 - j0 + 1
        # (the first cell: its C(2)-offer is from infinity, whatever cost it reads (column 0's
        # reads a2row[-1]), so it takes the C(1)-step, or infinity, and enters the row itself;
        # column m's C(1)-step is a1row[0])
        d = inf
        e = j0  # the column where the least path to the cell entered the row
        for j in range(j0, j1 + 1):
            c = dq[j] + a1row[j if j < m else 0]
            v = c if c < inf else inf
            c = d + a2row[j - 1]
            t = c < v
            d = c if t else v
            e = e if t else j
            dr[j] = d
            ent[b + j] = e
    return D[n % 2, m] if hi[n] == m else inf


@njit(cache=True)
def _strip_cells(lo, hi):
    """The cells of the rows ``1 .. n`` of a strip (:func:`_strip_dp`'s ``ent``)."""
    k = np.int64(0)
    for i in range(1, lo.shape[0]):
        if hi[i] >= lo[i]:
            k += hi[i] - lo[i] + 1
    return k


@njit(cache=True)
def _strip_entries_path(ent, base, n, m, first):
    """:func:`_strip_path` of a path that :func:`_strip_dp` found to ``(n, m)``: ``first[i]`` the
    column where it enters row ``i`` (0 for row 0, where it starts), one read per row."""
    j = m
    for i in range(n, 0, -1):
        j = ent[base[i] + j]
        first[i] = j
    first[0] = 0


@njit(cache=True)
def _grid_dp_pair(A1, A2, s, u, D, E, move, move_u):
    """The costs of :func:`_strip_dp` over the whole grid (``lo = 0``, ``hi = m`` in every row) for
    the start points ``s`` and ``u`` at once, each cell's move recorded for :func:`_strip_path`
    (1 where its C(2)-step wins, else 0): the same sums for each (``D``, ``move`` for ``s``;
    ``E``, ``move_u`` for ``u``), in one loop, so that the processor runs the two programmes'
    chains of additions side by side (on the liver's bridged rings the two ends' programmes took
    0.65 ms where one after the other took 1.4 ms).  Each row is one pass, the winning step chosen
    without branches, as in :func:`_strip_dp` (the same costs and, from zeroed ``move`` and
    ``move_u``, the same moves as the branching form with a C(2)-pass and a C(1)-pass per row:
    ``tests/test_optimal_strips.py``); about a third faster than that form.  Returns the two
    costs."""
    n, m = A1.shape
    inf = np.inf
    # row 0: C(2)-steps only, from (0, 0)
    a2s = A2[s % n]
    a2u = A2[u % n]
    d = 0.0
    e = 0.0
    D[0, 0] = d
    E[0, 0] = e
    for j in range(1, m + 1):
        c = d + a2s[j - 1]
        t = c < inf
        d = c if t else inf
        D[0, j] = d
        move[0, j] = np.int8(t)
        c = e + a2u[j - 1]
        t = c < inf
        e = c if t else inf
        E[0, j] = e
        move_u[0, j] = np.int8(t)
    for i in range(1, n + 1):
        r = i % 2
        q = 1 - r
        a2s = A2[(s + i) % n]
        a2u = A2[(u + i) % n]
        a1s = A1[(s + i - 1) % n]
        a1u = A1[(u + i - 1) % n]
        c = D[q, 0] + a1s[0]
        d = c if c < inf else inf
        c = E[q, 0] + a1u[0]
        e = c if c < inf else inf
        D[r, 0] = d
        E[r, 0] = e
        move[i, 0] = 0
        move_u[i, 0] = 0
        for j in range(1, m):
            c = D[q, j] + a1s[j]
            v = c if c < inf else inf
            c = d + a2s[j - 1]
            t = c < v
            d = c if t else v
            D[r, j] = d
            move[i, j] = np.int8(t)
            c = E[q, j] + a1u[j]
            v = c if c < inf else inf
            c = e + a2u[j - 1]
            t = c < v
            e = c if t else v
            E[r, j] = e
            move_u[i, j] = np.int8(t)
        # column m: its C(1)-steps are A1[., 0]
        c = D[q, m] + a1s[0]
        v = c if c < inf else inf
        c = d + a2s[m - 1]
        t = c < v
        D[r, m] = c if t else v
        move[i, m] = np.int8(t)
        c = E[q, m] + a1u[0]
        v = c if c < inf else inf
        c = e + a2u[m - 1]
        t = c < v
        E[r, m] = c if t else v
        move_u[i, m] = np.int8(t)
    return D[n % 2, m], E[n % 2, m]


@njit(cache=True)
def _strip_path(move, n, m, first):
    """Column where the path traced back through ``move`` (:func:`_grid_dp_pair`'s) enters each row
    ``i`` (``first[i]``, the row's smallest column)."""
    i = n
    j = m
    first[n] = m
    for _ in range(n + m):
        if move[i, j] == 0:
            i -= 1
        else:
            j -= 1
        first[i] = j


@njit(cache=True)
def _strip_costs(A1, A2, a, k):
    """Least cost of a monotone path (annulus or not) from each start point ``a .. a + k - 1``
    (cyclically).  Two least paths from different start points can be taken not to cross: where
    they meet, exchanging their tails leaves both least.  So each start point's programme runs
    only between the paths of two start points on either side of it, found first (bisection:
    ``O(n m log k)`` in all).  Returns the costs and whether every programme found a path."""
    n, m = A1.shape
    D = np.empty((2, m + 1))
    move = np.zeros((n + 1, m + 1), dtype=np.int8)
    ent = np.empty(4 * (n + m + 2), dtype=np.int32)  # the strips' entries (_strip_dp), grown as needed
    base = np.empty(n + 1, dtype=np.int64)
    cost = np.full(k, np.inf)
    first = np.empty((k, n + 1), dtype=np.int32)   # per start, per row of its own: entry column
    lo = np.zeros(n + 1, dtype=np.int64)
    hi = np.full(n + 1, m, dtype=np.int64)
    # the two ends' programmes over the whole grid, side by side (_grid_dp_pair)
    move_b = np.zeros((n + 1, m + 1), dtype=np.int8)
    c0, c1 = _grid_dp_pair(A1, A2, a, a + k - 1, D, np.empty((2, m + 1)), move, move_b)
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
        cells = np.int64(0)  # (_strip_cells of the strip, counted as it is made)
        for i in range(n + 1):
            u = t + i - t0          # this row among the rows of start t0: the path above
            hi[i] = m if u >= n else first[t0, u + 1]
            v = t + i - t1          # ... and of start t1: the path below
            lo[i] = first[t1, v] if v >= 0 else 0
            if i > 0 and hi[i] >= lo[i]:
                cells += hi[i] - lo[i] + 1
        if cells > ent.shape[0]:
            ent = np.empty(max(cells, 2 * ent.shape[0]), dtype=np.int32)
        c = _strip_dp(A1, A2, a + t, lo, hi, D, ent, base)
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
            if _strip_cells(lo, hi) > ent.shape[0]:
                ent = np.empty(max(_strip_cells(lo, hi), 2 * ent.shape[0]), dtype=np.int32)
            c = _strip_dp(A1, A2, a + t, lo, hi, D, ent, base)
            if c == np.inf:
                return cost, False
        cost[t] = c
        _strip_entries_path(ent, base, n, m, first[t])
        stack[top, 0] = t0
        stack[top, 1] = t
        stack[top + 1, 0] = t
        stack[top + 1, 1] = t1
        top += 2
    return cost, True


#: Relative margin (times ``(n + m) max |cost|``) within which start points count as tied.
_TIE = 1e-9


@njit(cache=True)
def _best_start_strips(A1, A2, a, k, D2):
    """:func:`_best_start` over the run ``a .. a + k - 1``, or -2 where it cannot be certified.

    The least monotone path of each start point (:func:`_strip_costs`) bounds its least annulus
    from below.  Every start point whose bound is within a margin of the least bound gets the
    full annulus programme, in increasing order as :func:`_best_start_each` takes them; where the
    best of these is itself within the margin, no other start point can beat it, and the answer
    is the one that function gives (floating-point ties broken alike).  Otherwise (a double cone
    is cheaper than every annulus near the bound) -2 sends the caller to the full search."""
    n, m = A1.shape
    near, low, tol = _near_starts(A1, A2, a, k)
    if low < 0.0:
        return -2
    return _near_best(A1, A2, near, low, tol, D2)


@njit(cache=True)
def _near_best(A1, A2, near, low, tol, D2):
    """The best of the start points ``near`` by their full programmes, taken in increasing order
    (the first of equal costs), or -2 where it is not within ``tol`` of the bound ``low``."""
    dummy = np.empty((1, 1), dtype=np.int8)
    best_s = -1
    best = np.inf
    for s in range(near.shape[0]):
        if near[s]:
            c = _annulus_dp(A1, A2, s, D2, dummy, np.bool_(False))
            if c < best:
                best = c
                best_s = s
    if best_s < 0 or best > low + tol:
        return -2
    return best_s


@njit(cache=True)
def _near_best_kept(A1, A2, near, low, tol, D2, steps, bounded):
    """:func:`_near_best` with the first near start point's programme recording its steps in
    ``steps``: ``(s, cost, recorded)``, ``s`` as :func:`_near_best` gives it, ``cost`` its
    programme's total and ``recorded`` whether ``s`` is that first start point (then its steps
    need no second run).

    The first of the near start points is the best in about two joins in three (the lobster's
    and the liver's bridged bands); a recording programme costs about 1.5 without, so recording
    it saves a programme there and costs half of one elsewhere.  The other start points run
    without recording, in increasing order (the first of equal costs wins, as there).

    Where ``bounded``, each programme runs only within ``low + tol`` and the best total so far
    (:func:`_annulus_dp_within`).  The first start point of the least total, where that total is
    within ``low + tol``, has every start point before it above its total, so their bounds (the
    best so far, above its total, or ``low + tol``) hold its total: it runs exactly and wins; no
    later one gets below it.  Where the least total exceeds ``low + tol``, every programme returns
    a number above ``low + tol`` or infinity, and the answer is -2 as with the whole programmes."""
    dummy = np.empty((1, 1), dtype=np.int8)
    best_s = -1
    best = np.inf
    first = -1
    for s in range(near.shape[0]):
        if near[s]:
            if first < 0:
                first = s
                c = _dp_to(A1, A2, s, D2, steps, np.bool_(True), low + tol, bounded)
            else:
                c = _dp_to(A1, A2, s, D2, dummy, np.bool_(False), min(best, low + tol), bounded)
            if c < best:
                best = c
                best_s = s
    if best_s < 0 or best > low + tol:
        return -2, best, False
    return best_s, best, best_s == first


@njit(cache=True)
def _near_starts(A1, A2, a, k):
    """:func:`_best_start_strips`' start points near the bound (a mask over the points of
    ``c1``), the least bound and the margin; a bound of -1 where the strip search found no path."""
    n, m = A1.shape
    free, ok = _strip_costs(A1, A2, a, k)
    near = np.zeros(n, dtype=np.bool_)
    if not ok:
        return near, -1.0, 0.0
    low = np.inf
    for t in range(k):
        low = min(low, free[t])
    tol = _TIE * (n + m) * _abs_max(A1, A2)
    for t in range(k):
        if free[t] <= low + 2.0 * tol:
            near[(a + t) % n] = True
    return near, low, tol


@njit(cache=True)
def _abs_max(A1, A2):
    """The largest ``|A1[i, j]|`` and ``|A2[i, j]|`` (NaNs passed over; 0 for none).

    Read as integers: the bits of a float without its sign bit order as the magnitudes do, from
    0 (zero) to ``0x7FF0...0`` (infinity), and NaNs lie above that.  So the largest such integer
    not above infinity's is the bits of the largest magnitude that is not NaN (a zero at worst,
    the start), the same number in any order; as integers the compiler takes several values at
    once (the float form's running maxima, a chain of comparisons each, took 0.33 ms of the
    liver's costly bands' programmes; ``tests/test_optimal_programme.py`` holds it)."""
    n, m = A1.shape
    sign_off = np.int64(0x7FFFFFFFFFFFFFFF)
    inf_bits = np.int64(0x7FF0000000000000)
    best = np.int64(0)
    for i in range(n):
        a1 = A1[i].view(np.int64)
        a2 = A2[i].view(np.int64)
        for j in range(m):
            x = a1[j] & sign_off
            y = a2[j] & sign_off
            x = x if x <= inf_bits else np.int64(0)
            y = y if y <= inf_bits else np.int64(0)
            x = x if x > y else y
            best = x if x > best else best
    out = np.empty(1, np.int64)
    out[0] = best
    return out.view(np.float64)[0]


@njit(cache=True)
def _trace_back(steps, n, m):
    """The band's edges ``(i, j)`` read back from the programme's steps, from the goal layer."""
    E = np.empty((n + m, 2), dtype=np.int64)
    i = n
    j = m
    L = TWO_ROWS
    for k in range(n + m - 1, -1, -1):
        b = steps[i, j]
        c2 = True  # whether the step into (i, L, j) is a C(2)-advance, and its layer L before it
        if L == TWO_ROWS:
            x = b & 3
            c2 = x != 0
            L = TWO_ROWS if x == 0 or x == _FROM_TWO_ROWS else (ROW0 if x == _FROM_ROW0 else ROW_PAST)
        elif L == ROW_PAST:
            c2 = False
            L = ROW_HERE if (b >> _PAST_BITS) & 1 else ROW_PAST
        elif L == ROW_HERE:
            L = NONE if (b >> _HERE_BITS) & 1 else ROW_HERE
        elif L == ROW0:
            x = (b >> _ROW0_BITS) & 3
            c2 = x != 0
            L = NONE if x == _FROM_NONE else ROW0
        else:
            c2 = False
        if c2:
            j -= 1
        else:
            i -= 1
        E[k, 0] = i
        E[k, 1] = j
    return E


#: Largest ``n m`` whose buffers (:func:`_buffers`) a thread keeps for its next band: 17 bytes per
#: cell, 8.5 MiB here; larger bands take fresh arrays.
_KEPT_CELLS = 1 << 19
_LOCAL = threading.local()


def _buffers(n, m):
    """``fbuf`` and ``bbuf`` for :func:`_optimal_edges_in` (``n <= m`` points): this thread's,
    grown as needed, where ``n m <= _KEPT_CELLS``.  Fresh arrays of these sizes cost the system
    about as much as the programmes that fill them (every page is zeroed at its first write:
    1 ms of the liver's costly bands' 8 before their steps took one byte per cell); kept ones are
    in place and often in cache."""
    nf, nb = 2 * n * m, (n + 1) * (m + 1)
    if n * m > _KEPT_CELLS:
        return np.empty(nf), np.empty(nb, np.int8)
    got = getattr(_LOCAL, "buffers", None)
    if got is None or len(got[0]) < nf or len(got[1]) < nb:
        got = np.empty(max(nf, 0 if got is None else len(got[0]))), \
            np.empty(max(nb, 0 if got is None else len(got[1])), np.int8)
        _LOCAL.buffers = got
    return got


def release_buffers() -> None:
    """Let go of this thread's kept buffers (:func:`_buffers`): the general mesher does so once its
    joins are built, so that their pages are not held through the steps after them."""
    _LOCAL.__dict__.pop("buffers", None)


def triangulate_band_optimal(lower, upper, max_work: float | None = None) -> np.ndarray:
    """Triangulate a band with the least total triangle area (Fuchs-Kedem-Uselton).

    Parameters
    ----------
    lower : array_like, shape (n, 3)
        Closed polygon at height ``z1``.
    upper : array_like, shape (m, 3)
        Closed polygon at height ``z2 > z1``, same orientation convention.

    Returns
    -------
    faces : ndarray of int64, shape (n + m, 3)
        Triangles indexing ``np.vstack([lower, upper])`` (``max(n, m)`` for a pole point,
        none for two points).  ``O(min(n, m)^2 max(n, m))`` time.

    ``max_work`` bounds that time: where ``n^2 m`` exceeds it (``n <= m``), only the
    ``max(1, max_work // (n m))`` start points of the smaller polygon nearest (in index) to the
    point closest to the larger polygon's first point are tried, so the band has the least area
    among those whose edge at that first point is nearly the shortest (not always the least area).
    """
    lo, up = validate_band_polygons(lower, upper)
    if len(lo) == 1 and len(up) == 1:
        return np.empty((0, 3), dtype=np.int64)
    n, m = sorted((len(lo), len(up)))  # (the smaller ring is C(1): oriented_pair)
    bounded = max_work is not None and n * n * m > max_work
    if n * m > MAX_OPTIMAL_CELLS or (n * n * m > MAX_OPTIMAL_WORK and not bounded):
        raise ValueError(
            f"the optimal band between polygons of {n} and {m} vertices needs {n * m:,} table cells (about "
            f"{19 * n * m / 2**20:,.0f} MiB) and {n * n * m:.2g} steps; the limits are {MAX_OPTIMAL_CELLS:,} cells and "
            f"{MAX_OPTIMAL_WORK:.2g} steps. Use triangulation='wiederhold' or 'greedy' (linear time), or "
            "polygon='mlp'/'dss' (fewer vertices)")
    key = (lo.shape, lo.dtype.str, lo.tobytes(), up.shape, up.dtype.str, up.tobytes(), max_work)
    got = _SEEN.get(key)
    if got is None:
        got = _optimal_faces(lo, up, max_work)
        _SEEN.put(key, got)
    return got.copy()


#: The last few bands of :func:`triangulate_band_optimal`, keyed by the bytes of its two validated
#: polygons and ``max_work``: the volume mesher asks for some bands again (a bridged join built
#: once more after a rebuild or inside intermediate sections, a band's rules tried twice), about
#: an eighth of the lobster's least-area programmes' time.  The faces depend on those only.
_SEEN_KEEP = 32
_SEEN = Recent(_SEEN_KEEP)


def _optimal_faces(lo, up, max_work):
    """:func:`triangulate_band_optimal` of the validated polygons ``lo`` and ``up`` (not both one
    point, within the size limits), without the memory of recent calls."""
    c1, c2, swapped = oriented_pair(lo, up)
    n, m = len(c1), len(c2)
    bounded = max_work is not None and n * n * m > max_work
    if len(c1) == 1:
        edges = np.stack([np.zeros(len(c2), np.int64), np.arange(len(c2), dtype=np.int64)], axis=1)
        s = 0
    else:
        if bounded:
            k = int(max(1, max_work // (n * m)))
            near = int(np.argmin(((c1 - c2[0]) ** 2).sum(axis=1)))
            starts = np.sort((near - k // 2 + np.arange(k)) % n).astype(np.int64)
        else:
            starts = np.arange(n, dtype=np.int64)  # (optimal_edges)
        edges, s, _ = _optimal_edges_in(c1, c2, starts, *_buffers(n, m))
    return edges_to_faces(edges, len(c1), len(c2), s, 0, len(lo), swapped)
