"""Slices -> closed digital 4-contours (contour following with hole nesting).

A slice is given by the set ``I`` of grid points strictly inside the cross-section (a boolean
mask).  Following the paper (Wiederhold & Villafuerte 2009, sect. 6: "all 4-contours together form
the Outer Jordan digitization of the object"), each contour is the boundary of

    ``U`` = union of the closed unit grid cells having at least one corner in ``I``

(equivalently: ``I`` dilated by the 2 x 2 block of cells around each point), written as the
closed sequence of *all* grid points met by unit steps along that boundary (a digital Jordan
4-curve).  The inner Jordan digitization ``V`` (cells whose four corners are all in ``I``) is not
traced here; the MLP polygonizer derives it from the contour.

Conventions (see :mod:`contourmesh.types`):

* a contour is a ``(k, 2)`` int64 array of grid points ``(x, y)``, closed implicitly, no
  repeated closing point, every step a unit 4-step;
* every contour is traversed with ``U`` on its **left** (x to the right, y up), so outer
  contours have positive shoelace area and holes negative;
* connectivity: the cells of ``U`` are taken **4-connected** (the background is 8-connected).
  Where two cells of ``U`` touch only at a corner (a *pinch*: ``I`` has two diagonal points two
  steps apart and nothing next to them), the boundary turns tightly around each cell, so the
  two sides become separate contours and the pinch corner belongs to both.  The only case in
  which a contour is not a simple curve is a component that touches *itself* at such a corner
  (an almost closed ring of ``I``); that contour then visits the pinch point twice (still every
  unit step exactly once).  It never happens for the digitization of a shape whose slices have
  no features thinner than the grid.
"""

from __future__ import annotations

import numpy as np

from ._kernels import internal_kernel, njit
from .geometry import predecessor, successor

__all__ = ["trace_contours", "rotate_start", "check_contour4", "overlap_groups"]

# Directions of a unit step, counter-clockwise with y up: 0 = +x, 1 = +y, 2 = -x, 3 = -y.
_DX = np.array([1, 0, -1, 0], dtype=np.int64)
_DY = np.array([0, 1, 0, -1], dtype=np.int64)


@njit(cache=True)
def _is_boundary_edge(cells, vx, vy, d):
    """Is the unit step from vertex ``(vx, vy)`` in direction ``d`` a boundary edge of ``U``
    with ``U`` on its left?  ``cells[r, c]`` is the cell whose lower-left corner is ``(c, r)``."""
    if d == 0:
        return cells[vy, vx] and not cells[vy - 1, vx]
    elif d == 1:
        return cells[vy, vx - 1] and not cells[vy, vx]
    elif d == 2:
        return cells[vy - 1, vx - 1] and not cells[vy, vx - 1]
    else:
        return cells[vy - 1, vx] and not cells[vy - 1, vx - 1]


@njit(cache=True, inline="always")
def _uniform(cells, vx, vy):
    """Whether the four cells around vertex ``(vx, vy)`` are all in ``U`` or all outside (no
    boundary edge starts there)."""
    a = cells[vy - 1, vx - 1]
    return a == cells[vy - 1, vx] and a == cells[vy, vx - 1] and a == cells[vy, vx]


@njit(cache=True, inline="always")
def _crack_step(vx, vy, d, a2):
    """One unit step of a crack walk from vertex ``(vx, vy)`` in direction ``d``: the next vertex
    and the running twice-signed area ``a2`` with the step's term added."""
    nx = vx + _DX[d]
    ny = vy + _DY[d]
    return nx, ny, a2 + vx * ny - nx * vy


@njit(cache=True)
def _follow_boundaries(cells):
    """Crack following on the cell image (every boundary edge of ``U`` exactly once).

    Scans the vertices row by row (y, then x) and starts a new contour at the first vertex that
    has an unvisited boundary edge; that vertex is the contour's lowest-then-leftmost point.
    At each vertex the walk takes the first boundary edge among *turn left, go straight, turn
    right* (turning left first keeps cells that touch only at a corner apart: 4-connected ``U``).

    Returns the concatenated points (vertex indices in ``cells``), the start offset of each
    contour, twice the signed area of each contour, and the cell on the left of its first edge.
    """
    h, w = cells.shape
    n_edges = 0
    for vy in range(1, h):
        for vx in range(1, w):
            if _uniform(cells, vx, vy):
                continue
            for d in range(4):
                if _is_boundary_edge(cells, vx, vy, d):
                    n_edges += 1
    pts = np.empty((n_edges, 2), dtype=np.int64)
    visited = np.zeros((h, w, 4), dtype=np.uint8)
    starts = np.empty(n_edges + 1, dtype=np.int64)
    area2 = np.empty(n_edges, dtype=np.int64)
    left_cell = np.empty((n_edges, 2), dtype=np.int64)
    n_cont = 0
    pos = 0
    for vy0 in range(1, h):
        for vx0 in range(1, w):
            if _uniform(cells, vx0, vy0):
                continue
            for d0 in range(4):
                if visited[vy0, vx0, d0] or not _is_boundary_edge(cells, vx0, vy0, d0):
                    continue
                starts[n_cont] = pos
                # the cell on the left of the first edge identifies the 4-component of U
                if d0 == 0:
                    left_cell[n_cont, 0], left_cell[n_cont, 1] = vy0, vx0
                elif d0 == 1:
                    left_cell[n_cont, 0], left_cell[n_cont, 1] = vy0, vx0 - 1
                elif d0 == 2:
                    left_cell[n_cont, 0], left_cell[n_cont, 1] = vy0 - 1, vx0 - 1
                else:
                    left_cell[n_cont, 0], left_cell[n_cont, 1] = vy0 - 1, vx0
                a2 = 0
                vx, vy, d = vx0, vy0, d0
                while True:
                    visited[vy, vx, d] = 1
                    pts[pos, 0] = vx
                    pts[pos, 1] = vy
                    pos += 1
                    vx, vy, a2 = _crack_step(vx, vy, d, a2)
                    # turn left, straight, turn right: the first boundary edge wins
                    for t in (1, 0, 3):
                        nd = (d + t) % 4
                        if _is_boundary_edge(cells, vx, vy, nd):
                            d = nd
                            break
                    if vx == vx0 and vy == vy0 and d == d0:
                        break
                area2[n_cont] = a2
                n_cont += 1
    starts[n_cont] = pos
    return pts, starts[: n_cont + 1], area2[:n_cont], left_cell[:n_cont]


def _as_mask(mask) -> np.ndarray:
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2D array indexed [y, x]; got an array with shape {m.shape}")
    if m.dtype != np.bool_:
        if not (np.issubdtype(m.dtype, np.integer) or np.issubdtype(m.dtype, np.floating)):
            raise ValueError(f"mask must be a boolean array; got dtype {m.dtype}")
        if m.size and not np.isin(m, (0, 1)).all():
            raise ValueError("mask must be boolean (or hold only 0 and 1); found other values")
        m = m.astype(bool)
    return m


def _cells_of_reference(m) -> np.ndarray:
    """The cells of ``U`` around the mask ``m`` in numpy: the mask padded with False (``p``), a cell
    set where any of its four corners is, and one background cell all around."""
    ny, nx = m.shape
    p = np.zeros((ny + 2, nx + 2), dtype=bool)
    p[1:-1, 1:-1] = m
    cells = np.zeros((ny + 3, nx + 3), dtype=np.bool_)
    cells[1:-1, 1:-1] = p[:-1, :-1] | p[1:, :-1] | p[:-1, 1:] | p[1:, 1:]
    return cells


@njit(cache=True)
def _cells_of(m):
    """:func:`_cells_of_reference` in one pass: ``cells[r, c]`` (``1 <= r <= ny + 1``, ``1 <= c <= nx
    + 1``) is set where a mask point ``m[j, i]`` with ``j in (r - 2, r - 1)``, ``i in (c - 2, c - 1)`` is."""
    ny, nx = m.shape
    cells = np.zeros((ny + 3, nx + 3), dtype=np.bool_)
    for j in range(ny):
        for i in range(nx):
            if m[j, i]:
                cells[j + 1, i + 1] = True
                cells[j + 1, i + 2] = True
                cells[j + 2, i + 1] = True
                cells[j + 2, i + 2] = True
    return cells


def trace_contours(mask, x0: int = 0, y0: int = 0) -> tuple[list[np.ndarray], list[int]]:
    """Closed 4-contours of the outer Jordan digitization of a slice, with hole nesting.

    Parameters
    ----------
    mask : (ny, nx) array_like of bool
        ``mask[j, i]`` is True when the grid point ``(x0 + i, y0 + j)`` belongs to ``I`` (strictly
        inside the cross-section).  Points outside the array count as False.
    x0, y0 : int
        Grid coordinates of ``mask[0, 0]``.

    Returns
    -------
    contours : list of (k, 2) int64 arrays
        The boundary components of ``U`` (the union of the closed unit cells with a corner in
        ``I``), each the full digital 4-curve: every unit step, no closing repeat.  ``U`` lies on
        the left of the traversal, so outer contours have positive shoelace area, holes negative.
        Each contour starts at its lowest-then-leftmost point (smallest y, then smallest x);
        contours are listed in the order of those points (y, then x).
    parents : list of int
        ``-1`` for an outer contour; for a hole, the index of the outer contour of the same
        (4-connected) component of ``U``, i.e. the contour directly enclosing it.

    Notes
    -----
    Contour following on the cell complex (crack following, cf. Klette & Rosenfeld 2004,
    ch. 2 and 8).  ``U``'s cells are 4-connected: cells touching only at a corner belong to
    separate contours (see the module docstring).  Runs in O(number of cells) with numba.

    Examples
    --------
    >>> import numpy as np
    >>> contours, parents = trace_contours(np.ones((1, 1), dtype=bool), x0=5, y0=7)
    >>> contours[0].tolist()
    [[4, 6], [5, 6], [6, 6], [6, 7], [6, 8], [5, 8], [4, 8], [4, 7]]
    >>> parents
    [-1]
    """
    m = _as_mask(mask)
    if int(x0) != x0 or int(y0) != y0:
        raise ValueError(f"x0 and y0 must be integers; got x0={x0!r}, y0={y0!r}")
    x0, y0 = int(x0), int(y0)
    if not m.any():
        return [], []
    # cells[r, c] = cell whose lower-left corner is the local grid point (c - 2, r - 2), i.e. cells
    # has one background cell all around U (:func:`_cells_of`, compiled; :func:`_cells_of_reference`)
    cells = _cells_of(np.ascontiguousarray(m))  # one compiled signature for every slice
    pts, starts, area2, left_cell = _follow_boundaries(cells)
    offset = np.array([x0 - 2, y0 - 2], dtype=np.int64)
    contours = [pts[starts[i] : starts[i + 1]] + offset for i in range(len(area2))]
    if not (area2 < 0).any():
        return contours, [-1] * len(contours)  # no hole: no parent to find, no labelling

    from scipy import ndimage

    labels, _ = ndimage.label(cells)  # default structure: 4-connectivity
    comp = labels[left_cell[:, 0], left_cell[:, 1]]
    outer_of = {int(c): i for i, c in enumerate(comp) if area2[i] > 0}
    parents = [-1 if area2[i] > 0 else outer_of[int(comp[i])] for i in range(len(area2))]
    return contours, parents


def rotate_start(contour, near) -> np.ndarray:
    """Cyclically rotate a contour so that it starts at its point nearest ``near``.

    The paper (sect. 6) starts each slice's contour near the start of the previous slice's.

    Parameters
    ----------
    contour : (k, 2) array_like
        Closed contour (no closing repeat).
    near : (2,) array_like
        The point to start near.

    Returns
    -------
    (k, 2) ndarray
        The same points, rotated; ties in distance go to the smallest index.
    """
    c = np.asarray(contour)
    q = np.asarray(near)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) == 0:
        raise ValueError(f"contour must be a non-empty (k, 2) array; got shape {c.shape}")
    if q.shape != (2,):
        raise ValueError(f"near must be a point (x, y); got shape {q.shape}")
    if np.issubdtype(c.dtype, np.integer) and np.issubdtype(q.dtype, np.integer):
        diff = c.astype(np.int64) - q.astype(np.int64)
    else:
        diff = c.astype(np.float64) - q.astype(np.float64)
    i = int(np.argmin((diff * diff).sum(axis=1)))
    return np.roll(c, -i, axis=0)


def check_contour4(contour, name: str = "contour") -> np.ndarray:
    """Validate a closed digital 4-contour and return it as a contiguous ``(k, 2)`` int64 array.

    Expected: integer coordinates (integral floats are accepted), at least 4 points, every step
    (including the closing one) a unit step along x or y, never reversing direction, no
    repeated closing point - as produced by :func:`trace_contours`.
    """
    c = np.asarray(contour)
    if c.ndim != 2 or c.shape[1] != 2:
        raise ValueError(f"{name} must be a (k, 2) array of grid points (x, y); got shape {c.shape}")
    if len(c) < 4:
        raise ValueError(f"{name} must be a closed digital 4-curve with at least 4 points; got {len(c)}")
    if not np.issubdtype(c.dtype, np.integer):
        if not np.issubdtype(c.dtype, np.floating) or not np.all(np.isfinite(c)) or np.any(c != np.round(c)):
            raise ValueError(f"{name} must hold integer grid coordinates; got dtype {c.dtype} with non-integer values")
    c = np.ascontiguousarray(c, dtype=np.int64)
    if _contour4_ok(c):  # the two checks below, compiled, for the contours that pass them
        return c
    steps = successor(c) - c
    l1 = np.abs(steps).sum(axis=1)
    if np.any(l1 != 1):
        bad = int(np.flatnonzero(l1 != 1)[0])
        what = "a repeated closing point" if (bad == len(c) - 1 and l1[bad] == 0) else "a step that is not a unit 4-step"
        raise ValueError(
            f"{name} must be a closed digital 4-curve (unit steps along x or y, closed implicitly); "
            f"found {what} from point {bad} {c[bad].tolist()} to {c[(bad + 1) % len(c)].tolist()}"
        )
    back = np.all(steps == -predecessor(steps), axis=1)
    if np.any(back):
        bad = int(np.flatnonzero(back)[0])
        raise ValueError(f"{name} reverses direction at point {bad} {c[bad].tolist()}; not a cell boundary")
    return c


@njit(cache=True, nogil=True)
def _contour4_ok(c):
    """True when every step of the closed curve ``c`` (the closing one too) is a unit step along x
    or y and no step reverses the one before it (:func:`check_contour4`'s step checks)."""
    n = c.shape[0]
    for i in range(n):
        j = (i + 1) % n
        if abs(c[j, 0] - c[i, 0]) + abs(c[j, 1] - c[i, 1]) != 1:
            return False
    for i in range(n):
        j, h = (i + 1) % n, (i - 1) % n
        if c[j, 0] - c[i, 0] == -(c[i, 0] - c[h, 0]) and c[j, 1] - c[i, 1] == -(c[i, 1] - c[h, 1]):
            return False
    return True


def _crack_contours(cells: np.ndarray):
    """Crack boundaries of a pixel mask (pixels = unit squares), in corner coordinates.

    Corner ``(i, j)`` is the lower-left corner of pixel ``[j, i]``.  Returns ``(contours,
    area2)``: the contours with the pixels on their left (outer positive, holes negative).
    """
    h, w = cells.shape
    padded = np.zeros((h + 2, w + 2), dtype=np.bool_)
    padded[1:-1, 1:-1] = cells
    pts, starts, area2, _ = _follow_boundaries(padded)
    return [pts[starts[i]: starts[i + 1]] - 1 for i in range(len(area2))], area2


@njit(cache=True, nogil=True, inline="always")
def _is_label(lab, y, x, v):
    """Whether pixel ``[y, x]`` of the label image ``lab`` is in range and has the label ``v``."""
    return 0 <= y < lab.shape[0] and 0 <= x < lab.shape[1] and lab[y, x] == v


@njit(cache=True, nogil=True, inline="always")
def _is_label_edge(lab, vx, vy, d, v):
    """:func:`_is_boundary_edge` of component ``v`` of ``lab`` without padding: the unit step
    from corner ``(vx, vy)`` in direction ``d`` has a pixel labelled ``v`` on its left and none on
    its right (corner ``(i, j)`` is the lower-left corner of pixel ``[j, i]``)."""
    if d == 0:
        return _is_label(lab, vy, vx, v) and not _is_label(lab, vy - 1, vx, v)
    elif d == 1:
        return _is_label(lab, vy, vx - 1, v) and not _is_label(lab, vy, vx, v)
    elif d == 2:
        return _is_label(lab, vy - 1, vx - 1, v) and not _is_label(lab, vy, vx - 1, v)
    else:
        return _is_label(lab, vy - 1, vx, v) and not _is_label(lab, vy - 1, vx - 1, v)


@njit(cache=True, nogil=True, inline="always")
def _label_turn(lab, vx, vy, d, v):
    """The direction leaving vertex ``(vx, vy)`` of a crack walk round component ``v`` entered in
    direction ``d``: of turn left, go straight, turn right the first boundary edge."""
    for t in (1, 0, 3):
        nd = (d + t) % 4
        if _is_label_edge(lab, vx, vy, nd, v):
            return nd
    return d  # pragma: no cover - a closed walk always has a way on


def _corner_tables():
    """Tables of the four pixels round a corner ``(vx, vy)``, as a 4-bit mask ``m`` (bit 0 pixel
    ``[vy - 1, vx - 1]``, bit 1 ``[vy - 1, vx]``, bit 2 ``[vy, vx - 1]``, bit 3 ``[vy, vx]`` in the
    component): ``edges[m]``, bit ``d`` set where the step from the corner in direction ``d`` is a
    boundary edge (:func:`_is_label_edge`, which reads only those four pixels), and ``turn[16 * d +
    m]``, the direction a walk entered in direction ``d`` leaves by (:func:`_label_turn`: of turn
    left, go straight, turn right the first boundary edge).  Built once with numpy at import."""
    edges = np.zeros(16, np.int64)
    turn = np.empty(64, np.int64)
    for m in range(16):
        a, b, c, e = bool(m & 1), bool(m & 2), bool(m & 4), bool(m & 8)
        on = [e and not b, c and not e, a and not c, b and not a]
        edges[m] = sum(1 << d for d in range(4) if on[d])
        for d in range(4):
            turn[16 * d + m] = next(((d + t) % 4 for t in (1, 0, 3) if on[(d + t) % 4]), d)
    return edges, turn


_CORNER_EDGES, _CORNER_TURN = _corner_tables()
#: The row and column offsets, from a corner, of the pixel on the left of its step in direction d.
_LEFT_DY = np.array([0, 0, -1, -1], dtype=np.int64)
_LEFT_DX = np.array([0, -1, -1, 0], dtype=np.int64)


@njit(cache=True, nogil=True, inline="always")
def _corner_mask(lab, vx, vy, v, h, w):
    """The 4-bit mask of the pixels of component ``v`` round corner ``(vx, vy)`` of ``lab`` (``h``
    rows, ``w`` columns; pixels outside it are not in the component), as :func:`_corner_tables`
    reads it."""
    a = vy - 1 >= 0 and vx - 1 >= 0 and lab[vy - 1, vx - 1] == v
    b = vy - 1 >= 0 and vx < w and lab[vy - 1, vx] == v
    c = vy < h and vx - 1 >= 0 and lab[vy, vx - 1] == v
    e = vy < h and vx < w and lab[vy, vx] == v
    # (the bits or-ed from the four tests: a chain of conditional ors took the walk longer)
    return np.int64(a) | (np.int64(b) << 1) | (np.int64(c) << 2) | (np.int64(e) << 3)


@njit(cache=True, nogil=True)
def _label_runs(lab):
    """The runs of equal non-zero labels of a label image, in raster order: ``(ry, rx0, rx1,
    rlab)``, run ``r`` the pixels ``[ry[r], rx0[r]: rx1[r]]``, all labelled ``rlab[r]``."""
    h, w = lab.shape
    n = 0
    for y in range(h):
        for x in range(w):
            if lab[y, x] != 0 and (x == 0 or lab[y, x - 1] != lab[y, x]):
                n += 1
    ry = np.empty(n, np.int64)
    rx0 = np.empty(n, np.int64)
    rx1 = np.empty(n, np.int64)
    rlab = np.empty(n, np.int64)
    r = 0
    for y in range(h):
        for x in range(w):
            if lab[y, x] != 0 and (x == 0 or lab[y, x - 1] != lab[y, x]):
                ry[r] = y
                rx0[r] = x
                rlab[r] = lab[y, x]
                r += 1
            if lab[y, x] != 0 and (x == w - 1 or lab[y, x + 1] != lab[y, x]):
                rx1[r - 1] = x + 1
    return ry, rx0, rx1, rlab


@njit(cache=True, nogil=True)
def _slice_cracks(lab, boxes, ry, rx0, rx1, rlab):
    """:func:`_crack_contours` of every component of a label image at once, in slice corner
    coordinates: component ``c`` (label ``c + 1``, inside ``boxes[c] = (y0, y1, x0, x1)``, stops
    exclusive) is traced on its box's corners in raster order, as :func:`_follow_boundaries` traces
    the component's cropped mask, so that its contours, their start points and their order are
    those of ``_crack_contours(lab[box] == c + 1)`` moved by ``(x0, y0)``.

    Returns the concatenated points, the start offset of each contour, twice its signed area and
    the first contour of each component (``first[c]: first[c + 1]``).  Every boundary edge is
    marked visited as a bit of the pixel on its left (the pixel and the direction name the edge;
    two components never share a pixel).

    The raster scan visits only the corners where a contour can start: the ends ``rx0`` and
    ``rx1`` of the component's runs (``ry, rx0, rx1, rlab``: :func:`_label_runs`) in pixel row
    ``vy`` of corner row ``vy``, in order.  A walk marks its whole contour, so a contour starts at
    its first vertex in raster order, ``P``, or nowhere: ``P`` has no contour vertex below it nor
    left of it on its row, so its two edges go right and up, and the pixel above right of ``P``
    is in the component where the pixels above left and below right are not, or the other way
    round: ``P`` is the first or the end column of a run in the row above it.  The same contours,
    from the same corners in the same order, as a scan of every corner of the box (until
    2026-12-06 the scan also took the run ends of the row below and each end plus one, some four
    times the corners, merged: this kernel took 20.5 ms on the rotated socket's 268 slices, now
    17.6, and 14.3 ms on the lobster's 372, now 11.2)."""
    h, w = lab.shape
    n = boxes.shape[0]
    nr = ry.shape[0]
    # the runs of each component, in raster order (a counting sort on the labels)
    rstart = np.zeros(n + 2, np.int64)
    for r in range(nr):
        rstart[rlab[r] + 1] += 1
    for v in range(n + 1):
        rstart[v + 1] += rstart[v]
    fill = rstart.copy()
    order = np.empty(nr, np.int64)
    for r in range(nr):
        v = rlab[r]
        order[fill[v]] = r
        fill[v] += 1
    visited = np.zeros((h, w), dtype=np.uint8)
    cap = 64
    pts = np.empty((cap, 2), dtype=np.int64)
    cs = 16
    starts = np.empty(cs + 1, dtype=np.int64)
    area2 = np.empty(cs, dtype=np.int64)
    first = np.empty(n + 1, dtype=np.int64)
    n_cont = 0
    pos = 0
    for comp in range(n):
        v = comp + 1
        first[comp] = n_cont
        y0, y1 = boxes[comp, 0], boxes[comp, 1]
        q0, q1 = rstart[v], rstart[v + 1]
        p = q0  # (the component's first run in row vy0 or later)
        for vy0 in range(y0, y1):
            while p < q1 and ry[order[p]] < vy0:
                p += 1
            pe = p
            while pe < q1 and ry[order[pe]] == vy0:
                pe += 1
            # (the run ends of the row above the corner row, increasing: a row's runs are apart)
            for t in range(2 * (pe - p)):
                r = order[p + (t >> 1)]
                vx0 = rx1[r] if t & 1 else rx0[r]
                # the four pixels around corner (vx0, vy0) in component v, and its boundary edges
                # (from tables: the same tests as _is_label_edge)
                bits = _CORNER_EDGES[_corner_mask(lab, vx0, vy0, v, h, w)]
                if bits == 0:
                    continue  # no boundary edge at this corner
                for d0 in range(4):
                    if not (bits >> d0) & 1:
                        continue
                    # the edge's left pixel
                    ly, lx = vy0 + _LEFT_DY[d0], vx0 + _LEFT_DX[d0]
                    if visited[ly, lx] & (1 << d0):
                        continue
                    if n_cont == cs:
                        cs *= 2
                        starts2 = np.empty(cs + 1, dtype=np.int64)
                        starts2[:n_cont] = starts[:n_cont]
                        starts = starts2
                        area2b = np.empty(cs, dtype=np.int64)
                        area2b[:n_cont] = area2[:n_cont]
                        area2 = area2b
                    starts[n_cont] = pos
                    a2 = 0
                    vx, vy, d = vx0, vy0, d0
                    while True:
                        if d == 0:
                            visited[vy, vx] |= 1
                        elif d == 1:
                            visited[vy, vx - 1] |= 2
                        elif d == 2:
                            visited[vy - 1, vx - 1] |= 4
                        else:
                            visited[vy - 1, vx] |= 8
                        if pos == cap:
                            cap *= 2
                            pts2 = np.empty((cap, 2), dtype=np.int64)
                            pts2[:pos] = pts[:pos]
                            pts = pts2
                        pts[pos, 0] = vx
                        pts[pos, 1] = vy
                        pos += 1
                        vx, vy, a2 = _crack_step(vx, vy, d, a2)
                        # (_corner_mask written out: inlined, it counted lab in and out at every
                        # step; the rotated socket's 233 slice passes 25.9 -> 23.7 ms, the lobster's
                        # 323 boxed ones 12.8 -> 11.9 ms)
                        ca = vy - 1 >= 0 and vx - 1 >= 0 and lab[vy - 1, vx - 1] == v
                        cb = vy - 1 >= 0 and vx < w and lab[vy - 1, vx] == v
                        cc = vy < h and vx - 1 >= 0 and lab[vy, vx - 1] == v
                        ce = vy < h and vx < w and lab[vy, vx] == v
                        cm = np.int64(ca) | (np.int64(cb) << 1) | (np.int64(cc) << 2) | (np.int64(ce) << 3)
                        d = _CORNER_TURN[16 * d + cm]  # (_label_turn)
                        if vx == vx0 and vy == vy0 and d == d0:
                            break
                    area2[n_cont] = a2
                    n_cont += 1
    first[n] = n_cont
    starts[n_cont] = pos
    # (a copy of the used points: the slice keeps views of them to the end, and a view would keep
    # the grown buffer, up to twice their size: the liver's peak +8 MiB)
    return pts[:pos].copy(), starts[: n_cont + 1], area2[:n_cont], first


@njit(cache=True, nogil=True)
def _hole_parts(lab, v, box, seeds):
    """The holes of component ``v`` of ``lab`` (inside ``box = (y0, y1, x0, x1)``) as pixel sets:
    for each seed pixel ``seeds[k] = (y, x)`` (a pixel of the hole, in box coordinates), the
    8-connected set of the pixels not labelled ``v`` that holds it, within the box.  Returns
    ``(meta, flat)``: hole ``k``'s cropped mask is ``flat[o: o + h * w]`` as ``(h, w)`` with
    ``meta[k] = (y, x, h, w, o)`` (its first row and column in the box, its size, its offset)."""
    y0, y1, x0, x1 = box[0], box[1], box[2], box[3]
    bh, bw = y1 - y0, x1 - x0
    seen = np.zeros((bh, bw), np.uint8)
    stack = np.empty((bh * bw, 2), np.int64)
    got = np.empty((bh * bw, 2), np.int64)
    k = seeds.shape[0]
    meta = np.empty((k, 5), np.int64)
    flat = np.zeros(0, np.uint8)
    used = 0
    for s in range(k):
        sy, sx = seeds[s, 0], seeds[s, 1]
        ng = 0
        top = 0
        if not seen[sy, sx]:
            seen[sy, sx] = 1
            stack[0, 0], stack[0, 1] = sy, sx
            top = 1
        while top > 0:
            top -= 1
            y, x = stack[top, 0], stack[top, 1]
            got[ng, 0], got[ng, 1] = y, x
            ng += 1
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < bh and 0 <= xx < bw and not seen[yy, xx] and lab[y0 + yy, x0 + xx] != v:
                        seen[yy, xx] = 1
                        stack[top, 0], stack[top, 1] = yy, xx
                        top += 1
        ly, lx, hy, hx = bh, bw, -1, -1
        for i in range(ng):
            ly, hy = min(ly, got[i, 0]), max(hy, got[i, 0])
            lx, hx = min(lx, got[i, 1]), max(hx, got[i, 1])
        hh, ww = hy - ly + 1, hx - lx + 1
        if used + hh * ww > flat.shape[0]:
            flat2 = np.zeros(max(2 * flat.shape[0], used + hh * ww), np.uint8)
            flat2[:used] = flat[:used]
            flat = flat2
        for i in range(ng):
            flat[used + (got[i, 0] - ly) * ww + got[i, 1] - lx] = 1
        meta[s, 0], meta[s, 1], meta[s, 2], meta[s, 3], meta[s, 4] = ly, lx, hh, ww, used
        used += hh * ww
    return meta, flat[:used]


@njit(cache=True, nogil=True)
def _hole_spans(lab, v, box, seeds):  # pragma: no cover (compiled)
    """:func:`_hole_parts` filled a row span at a time: the same ``(meta, flat)``.

    Each hole is found as maximal runs of pixels not labelled ``v`` (a run's 8-neighbours in the
    rows above and below lie over its columns and one more each side), so a hole costs a few
    integers per run instead of two stored coordinates per pixel, and its bytes are set a run at a
    time.  The pixel set is the same: a fill from the seed of every pixel not labelled ``v`` that
    is 8-connected to it within the box, those of an earlier seed's hole excepted (a hole is
    filled whole, so another seed in it finds nothing, as there).  The seeds are hole pixels (the
    pixel right of a hole contour's edge: not labelled ``v``), from which both fills start alike."""
    y0, y1, x0, x1 = box[0], box[1], box[2], box[3]
    bh, bw = y1 - y0, x1 - x0
    seen = np.zeros((bh, bw), np.uint8)
    k = seeds.shape[0]
    meta = np.empty((k, 5), np.int64)
    flat = np.zeros(0, np.uint8)
    used = 0
    cap = 64
    spans = np.empty((cap, 3), np.int64)  # (row, first column, end column) of each run of the hole
    for s in range(k):
        sy, sx = seeds[s, 0], seeds[s, 1]
        ns = 0
        top = 0  # (spans[top: ns] are the runs whose neighbour rows are still to be read)
        if not seen[sy, sx]:
            a, b = sx, sx + 1
            while a > 0 and not seen[sy, a - 1] and lab[y0 + sy, x0 + a - 1] != v:
                a -= 1
            while b < bw and not seen[sy, b] and lab[y0 + sy, x0 + b] != v:
                b += 1
            seen[sy, a: b] = 1
            spans[0, 0], spans[0, 1], spans[0, 2] = sy, a, b
            ns = 1
        while top < ns:
            y, a, b = spans[top, 0], spans[top, 1], spans[top, 2]
            top += 1
            for ny in (y - 1, y + 1):
                if ny < 0 or ny >= bh:
                    continue
                x = max(a - 1, 0)
                xe = min(b + 1, bw)
                row = y0 + ny
                while x < xe:
                    if seen[ny, x] or lab[row, x0 + x] == v:
                        x += 1
                        continue
                    l, r = x, x + 1
                    while l > 0 and not seen[ny, l - 1] and lab[row, x0 + l - 1] != v:
                        l -= 1
                    while r < bw and not seen[ny, r] and lab[row, x0 + r] != v:
                        r += 1
                    seen[ny, l: r] = 1
                    if ns == cap:
                        cap *= 2
                        sp2 = np.empty((cap, 3), np.int64)
                        sp2[:ns] = spans[:ns]
                        spans = sp2
                    spans[ns, 0], spans[ns, 1], spans[ns, 2] = ny, l, r
                    ns += 1
                    x = r + 1
        ly, lx, hy, hx = bh, bw, -1, -1
        for i in range(ns):
            ly, hy = min(ly, spans[i, 0]), max(hy, spans[i, 0])
            lx, hx = min(lx, spans[i, 1]), max(hx, spans[i, 2] - 1)
        hh, ww = hy - ly + 1, hx - lx + 1
        if used + hh * ww > flat.shape[0]:
            flat2 = np.zeros(max(2 * flat.shape[0], used + hh * ww), np.uint8)
            flat2[:used] = flat[:used]
            flat = flat2
        for i in range(ns):
            o = used + (spans[i, 0] - ly) * ww - lx
            flat[o + spans[i, 1]: o + spans[i, 2]] = 1
        meta[s, 0], meta[s, 1], meta[s, 2], meta[s, 3], meta[s, 4] = ly, lx, hh, ww, used
        used += hh * ww
    return meta, flat[:used]


def slice_boxes(objects) -> np.ndarray:
    """A slice's ``find_objects`` boxes as an ``(n, 4)`` int64 array of ``(y0, y1, x0, x1)``."""
    return np.array([(a.start, a.stop, b.start, b.stop) for a, b in objects], dtype=np.int64).reshape(-1, 4)


def slice_cracks(labels: np.ndarray, boxes: np.ndarray, runs=None) -> tuple:
    """The crack contours of every component of a slice's label image (``labels`` int32, ``c + 1``
    for component ``c``), in slice corner coordinates, in one
    compiled pass: ``(points, starts, area2, first)`` as :func:`_slice_cracks`.  Contour ``i`` is
    ``points[starts[i]: starts[i + 1]]``; component ``c``'s are ``first[c]: first[c + 1]``, the same
    contours in the same order as ``_crack_contours(labels[objects[c]] == c + 1)`` gives them, moved
    to the slice (``boxes``: :func:`slice_boxes` of ``objects``).  ``runs``: the labels' runs
    ``(ry, rx0, rx1, rlab)`` as :func:`_label_runs` gives them (int64; the labeller has them), else
    found here."""
    lab = np.ascontiguousarray(labels, dtype=np.int32)
    ry, rx0, rx1, rlab = _label_runs(lab) if runs is None else runs
    return _slice_cracks(lab, boxes, ry, rx0, rx1, rlab)


@njit(cache=True, nogil=True)
def _pair_groups(pa, pb, na, nb):
    """The connected sets of the bipartite graph whose edges are the pairs ``(pa[i], pb[i])``
    (nodes ``a`` and ``na + b``), by union-find: the group of each pair, groups numbered in the
    order of their first pair, and the number of groups."""
    parent = np.empty(na + nb, np.int64)
    for i in range(na + nb):
        parent[i] = i
    for i in range(len(pa)):
        r = pa[i]
        while parent[r] != r:
            parent[r] = parent[parent[r]]
            r = parent[r]
        s = na + pb[i]
        while parent[s] != s:
            parent[s] = parent[parent[s]]
            s = parent[s]
        if r != s:
            parent[max(r, s)] = min(r, s)
    number = np.full(na + nb, -1, np.int64)
    group = np.empty(len(pa), np.int64)
    ng = 0
    for i in range(len(pa)):
        r = pa[i]
        while parent[r] != r:
            r = parent[r]
        if number[r] < 0:
            number[r] = ng
            ng += 1
        group[i] = number[r]
    return group, ng


def unique_keys(keys: np.ndarray, bound: int) -> np.ndarray:
    """``np.unique(keys)`` for int64 keys in ``0 .. bound - 1``: where the range is small next to
    the number of keys, the nonzero places of their histogram (``np.bincount``, one pass and no
    sort or hash: the same sorted int64 values); otherwise ``np.unique`` itself."""
    keys = np.asarray(keys, dtype=np.int64)
    if bound <= 8 * len(keys) + 4096 and (len(keys) == 0 or keys.min() >= 0):
        return np.flatnonzero(np.bincount(keys)).astype(np.int64, copy=False)
    return np.unique(keys)


@njit(cache=True, nogil=True)
def missing_corners(ids, lx, ly):
    """The distinct places ``(lx[t], ly[t])`` where ``ids`` (a 2D int64 grid, indexed ``[ly, lx]``)
    holds a negative number, ordered by ``lx`` then ``ly``: ``(ux, uy)``, int64.  The same as
    ``unique_keys(lx[need] * h + ly[need], ...)`` split back into ``key // h`` and ``key % h``
    (``h = ids.shape[0]``, ``need = ids[ly, lx] < 0``).  Returns ``(ux, uy, ok)``; ``ok`` False (and
    nothing found) where a place lies outside the grid (numpy's indexing then decides)."""
    h = np.int64(ids.shape[0])
    w = np.int64(ids.shape[1])
    keys = np.empty(lx.shape[0], np.int64)
    nk = 0
    for t in range(lx.shape[0]):
        if lx[t] < 0 or ly[t] < 0 or lx[t] >= w or ly[t] >= h:
            return keys[:0], keys[:0], False
        if ids[ly[t], lx[t]] < 0:
            keys[nk] = np.int64(lx[t]) * h + np.int64(ly[t])
            nk += 1
    keys = np.sort(keys[:nk])
    nu = 0
    for t in range(nk):
        if t == 0 or keys[t] != keys[t - 1]:
            keys[nu] = keys[t]
            nu += 1
    ux = np.empty(nu, np.int64)
    uy = np.empty(nu, np.int64)
    for t in range(nu):
        ux[t] = keys[t] // h
        uy[t] = keys[t] % h
    return ux, uy, True


#: Largest table of label pairs :func:`_pair_table` marks (bytes).
_PAIR_TABLE_MAX = 1 << 24


def _pair_table_ok(la, lb, size) -> bool:
    """Whether :func:`overlap_groups` takes :func:`_pair_table`: two C-ordered uint8 label images
    of one shape (the volume mesher's; one compiled signature) and a table of at most
    :data:`_PAIR_TABLE_MAX` pairs."""
    return (isinstance(la, np.ndarray) and isinstance(lb, np.ndarray) and la.dtype == np.uint8
            and lb.dtype == np.uint8 and la.ndim == 2 and la.shape == lb.shape and la.flags.c_contiguous
            and lb.flags.c_contiguous and size <= _PAIR_TABLE_MAX)


@njit(cache=True, nogil=True)
def _pair_table(la, lb, nbk, size):
    """Which keys ``a * nbk + b`` occur where both labels are set (``a = la[y, x] > 0``, ``b =
    lb[y, x] > 0``): a table of ``size`` booleans, whose nonzero places are ``np.unique`` of the
    keys (sorted int64)."""
    seen = np.zeros(size, np.bool_)
    h, w = la.shape
    for y in range(h):
        for x in range(w):
            a = la[y, x]
            b = lb[y, x]
            if a > 0 and b > 0:
                seen[np.int64(a) * nbk + np.int64(b)] = True
    return seen


@njit(cache=True, nogil=True)
def _pair_table_runs(ra, rb, nbk, size):
    """:func:`_pair_table` from the two slices' runs rather than their pixels: ``ra``, ``rb`` are
    ``(4, n)`` int32 runs ``[row, first column, end column, component]`` (component ``c`` labelled
    ``c + 1``) in raster order, each row's runs apart and increasing.  Two runs of one row share a
    pixel exactly where their column ranges meet, and every pixel where both labels are set lies
    in one run of each, so the keys marked are those of the pixel scan: the same table.  The rows'
    runs are met in one merged sweep (as interval lists are intersected), a step per run."""
    seen = np.zeros(size, np.bool_)
    i, j = 0, 0
    n, m = ra.shape[1], rb.shape[1]
    while i < n and j < m:
        ya, yb = ra[0, i], rb[0, j]
        if ya < yb:
            i += 1
            continue
        if yb < ya:
            j += 1
            continue
        if ra[1, i] < rb[2, j] and rb[1, j] < ra[2, i]:
            seen[(np.int64(ra[3, i]) + 1) * nbk + np.int64(rb[3, j]) + 1] = True
        if ra[2, i] <= rb[2, j]:
            i += 1
        else:
            j += 1
    return seen


def overlap_groups(la: np.ndarray, lb: np.ndarray, na: int, nb: int):
    """The overlap groups of two slices' components: ``la``, ``lb`` are their label images (0 the
    background, component ``c`` labelled ``c + 1``; ``na``, ``nb`` components).  Two components
    overlap where both labels are set; a group is a connected set of overlaps.  Returns ``(pairs,
    groups)``: the overlapping ``(a, b)`` pairs (0-based, sorted) and the groups as ``(set of a,
    set of b)`` in the order of their first pair.  The groups are the connected sets of the pairs'
    bipartite graph, found by a compiled union-find (:func:`_pair_groups`)."""
    nbk = np.int64(nb + 1)  # (a, b) label pairs as one sortable key: same order as unique rows
    if _pair_table_ok(la, lb, (na + 1) * (nb + 1)):
        # (the mesher's label images: one compiled pass marks the keys present, in a table)
        keys = np.flatnonzero(_pair_table(la, lb, nbk, np.int64((na + 1) * (nb + 1))))
    else:
        both = (la > 0) & (lb > 0)
        keys = unique_keys(la[both].astype(np.int64) * nbk + lb[both], (na + 1) * (nb + 1))
    return _groups_of_keys(keys, nbk, na, nb)


def overlap_groups_runs(ra: np.ndarray, rb: np.ndarray, na: int, nb: int):
    """:func:`overlap_groups` of two slices given by their runs (``(4, n)`` int32 ``[row, first
    column, end column, component]``, raster order: what ``_Slice.kept_runs`` gives) rather than
    their label images, which are then not read: the same ``(pairs, groups)``, from one sweep over
    the runs (:func:`_pair_table_runs`).  None where the pairs' table would be larger than
    :data:`_PAIR_TABLE_MAX` (the caller then takes the label images)."""
    size = (na + 1) * (nb + 1)
    if size > _PAIR_TABLE_MAX:
        return None
    # (the table, its keys, the pairs and their groups in one compiled call, _pairs_of_runs: what
    # _groups_of_keys makes of np.flatnonzero of the table)
    pairs, group, ng = _pairs_of_runs(ra, rb, np.int64(nb + 1), np.int64(size), np.int64(na), np.int64(nb))
    return pairs, _groups_of_pairs(pairs, group, ng)


@njit(cache=True, nogil=True)
def _pairs_of_runs(ra, rb, nbk, size, na, nb):
    """:func:`overlap_groups_runs`' compiled part: the table of :func:`_pair_table_runs`, its keys
    in increasing order (``np.flatnonzero``), the pairs ``(key // nbk - 1, key % nbk - 1)`` and
    their groups (:func:`_pair_groups`): ``(pairs, group, ng)``, as :func:`_groups_of_keys` has them."""
    seen = _pair_table_runs(ra, rb, nbk, size)
    n = 0
    for i in range(size):
        if seen[i]:
            n += 1
    pairs = np.empty((n, 2), np.int64)
    pa = np.empty(n, np.int64)
    pb = np.empty(n, np.int64)
    n = 0
    for i in range(size):
        if seen[i]:
            pa[n] = i // nbk - 1
            pb[n] = i % nbk - 1
            pairs[n, 0] = pa[n]
            pairs[n, 1] = pb[n]
            n += 1
    group, ng = _pair_groups(pa, pb, na, nb)
    return pairs, group, ng


def _groups_of_keys(keys, nbk, na, nb):
    """:func:`overlap_groups`' pairs and groups from the sorted keys ``a * nbk + b`` of the label
    pairs found."""
    pairs = np.empty((len(keys), 2), dtype=np.int64)  # (np.c_[keys // nbk, keys % nbk] - 1, without np.c_'s cost)
    pairs[:, 0] = keys // nbk - 1
    pairs[:, 1] = keys % nbk - 1
    group, ng = _pair_groups(np.ascontiguousarray(pairs[:, 0]), np.ascontiguousarray(pairs[:, 1]),
                             np.int64(na), np.int64(nb))
    return pairs, _groups_of_pairs(pairs, group, ng)


def _groups_of_pairs(pairs, group, ng):
    """The groups ``(set of a, set of b)`` of the pairs, ``group`` the group of each (of ``ng``)."""
    groups = [(set(), set()) for _ in range(ng)]
    for (a, b), g in zip(pairs.tolist(), group.tolist()):
        groups[g][0].add(a)
        groups[g][1].add(b)
    return groups


@internal_kernel
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@internal_kernel
def _join(parent, a, b):
    """Union of the provisional labels a and b (the lower root wins); returns the root."""
    r = _root(parent, a)
    s = _root(parent, b)
    if r < s:
        parent[s] = r
        return r
    parent[r] = s
    return s


@njit(cache=True, inline="always", nogil=True, no_rewrites=True)
def _first_row_run(r, y):  # pragma: no cover (compiled)
    """The first of the runs ``r`` (``(4, n)`` or more rows, raster order, the row first) in row
    ``y`` or after it: the joins' reads of two slices' kept runs in a box's rows."""
    lo, hi = 0, r.shape[1]
    while lo < hi:
        mid = (lo + hi) // 2
        if r[0, mid] < y:
            lo = mid + 1
        else:
            hi = mid
    return lo


@internal_kernel
def _run_union(starts, x0, x1, h, corner):
    """The union-find parents of the runs ``[x0[r], x1[r])`` of ``h`` rows (row ``y``: runs
    ``starts[y] .. starts[y + 1] - 1``, in increasing x), two runs of neighbouring rows joined
    (:func:`_join`) where they share a column (``corner`` 0: 4-connected) or also where they touch
    at a corner (``corner`` 1: 8-connected); each pair of rows merged in one sweep."""
    n = starts[h]
    parent = np.empty(n, np.int64)
    for r in range(n):
        parent[r] = r
    for y in range(1, h):
        i, i1 = starts[y - 1], starts[y]
        j, j1 = starts[y], starts[y + 1]
        while i < i1 and j < j1:
            if x0[i] < x1[j] + corner and x0[j] < x1[i] + corner:
                _join(parent, i, j)
            if x1[i] <= x1[j]:
                i += 1
            else:
                j += 1
    return parent


def overlap_holes(o: np.ndarray):
    """The structure of an overlap mask ``o`` (2D boolean) that a bridged join needs: ``(n, blab,
    nb, n_out)``: ``n`` its 4-components (``ndimage.label(o, structure=_CROSS)``); ``blab``, ``nb``
    the 8-components of the background of ``o`` padded by one pixel of background
    (``ndimage.label(np.pad(~o, 1, constant_values=True), structure=_SQUARE)``, int64, the
    same labels); ``n_out`` how many of the ``n`` components have a pixel whose 3 x 3
    neighbourhood meets the padded background's first component (the outside).

    The joins read the labels only at a few pixels (:func:`overlap_hole_labels`); this is that
    read at every pixel of the padded mask, the whole image, for callers that want it."""
    o = np.ascontiguousarray(o, dtype=np.bool_)
    hp, wp = o.shape[0] + 2, o.shape[1] + 2
    ys, xs = np.divmod(np.arange(hp * wp, dtype=np.int64), wp)
    n, labels, nb, n_out, _ext = overlap_hole_labels(o, ys, xs)
    return n, labels.reshape(hp, wp), nb, n_out


def overlap_hole_labels(o: np.ndarray, ys, xs):
    """:func:`overlap_holes` of ``o`` read where it is needed: ``(n, labels, nb, n_out, ext)``
    with ``labels`` the padded background's labels at the pixels ``(ys[i], xs[i])`` of the padded
    mask (``blab[ys, xs]``, each in range) and ``ext`` its label at ``(0, 0)``, the outside.  The
    joins read the background's labels only there, so the labels are read off the background's
    runs and never painted (a box of int64 per overlap, most of the cost on large groups): the
    same numbers as ``ndimage.label`` gives (as the tests check).  ``ys``, ``xs`` are made
    contiguous: one compiled signature whatever the caller hands in."""
    return _overlap_hole_labels(np.ascontiguousarray(o, dtype=np.bool_), np.ascontiguousarray(ys, dtype=np.int64),
                                np.ascontiguousarray(xs, dtype=np.int64), np.int64(1))


@njit(cache=True, nogil=True)
def _overlap_hole_labels(o, ys, xs, one):
    """:func:`overlap_hole_labels` compiled (``one`` is 1): the runs of ``o``, row by row, handed to
    :func:`_runs_hole_labels`."""
    h, w = o.shape
    cap = h * ((w + 1) // 2)
    ox0 = np.empty(cap, np.int64)
    ox1 = np.empty(cap, np.int64)
    ors = np.empty(h + 1, np.int64)
    nr = 0
    for y in range(h):
        ors[y] = nr
        x = 0
        while x < w:
            if o[y, x]:
                s = x
                while x < w and o[y, x]:
                    x += 1
                ox0[nr] = s
                ox1[nr] = x
                nr += 1
            else:
                x += 1
    ors[h] = nr
    return _runs_hole_labels(ox0, ox1, ors, h, w, ys, xs, one)


@internal_kernel
def _runs_hole_labels(ox0, ox1, ors, h, w, ys, xs, one):
    """The structure :func:`overlap_hole_labels` gives, from the runs ``[ox0[r], ox1[r])`` of an
    ``h`` x ``w`` mask (row ``y``: runs ``ors[y] .. ors[y + 1] - 1``, in increasing x).

    The padded background's runs are the gaps between the mask's runs
    (its first and last rows whole), its components those of the runs 8-connected, numbered by
    their first run in raster order (``ndimage.label``'s numbers).  A pixel's label is that of the
    background run holding it (found by bisection in its row; 0 on the mask), and a component of
    the mask meets the outside where a run of the outside's label meets the 3 x 3 neighbourhoods
    of one of its runs (padded rows ``y .. y + 2``, columns ``x0 .. x1 + 1``): the pixel test
    (does a pixel's 3 x 3 neighbourhood meet the outside) run by run."""
    hp, wp = h + 2, w + 2
    nr = ors[h]
    nb = nr + hp
    bx0 = np.empty(nb, np.int64)
    bx1 = np.empty(nb, np.int64)
    brs = np.empty(hp + 1, np.int64)
    brs[0] = 0
    bx0[0] = 0
    bx1[0] = wp
    m = one
    for y in range(h):
        brs[y + 1] = m
        gap = 0
        for r in range(ors[y], ors[y + 1]):
            if ox0[r] + 1 > gap:
                bx0[m] = gap
                bx1[m] = ox0[r] + 1
                m += 1
            gap = ox1[r] + 1
        bx0[m] = gap
        bx1[m] = wp
        m += 1
    brs[h + 1] = m
    bx0[m] = 0
    bx1[m] = wp
    m += 1
    brs[hp] = m
    po = _run_union(ors, ox0, ox1, h, one - one)
    comp = np.empty(nr, np.int64)
    no = 0
    for r in range(nr):
        t = _root(po, r)
        if t == r:
            comp[r] = no
            no += 1
        else:
            comp[r] = comp[t]
    pb = _run_union(brs, bx0, bx1, hp, one)
    blab_r = np.empty(m, np.int64)
    nbl = 0
    for r in range(m):
        t = _root(pb, r)
        if t == r:
            nbl += 1
            blab_r[r] = nbl
        else:
            blab_r[r] = blab_r[t]
    ext = blab_r[0]  # (padded row 0 is one run, holding pixel (0, 0))
    labels = np.empty(ys.shape[0], np.int64)
    for i in range(ys.shape[0]):
        y, x = ys[i], xs[i]
        lo, hi = brs[y], brs[y + 1]  # the last run of row y starting at or before x
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if bx0[mid] <= x:
                lo = mid
            else:
                hi = mid
        labels[i] = blab_r[lo] if lo < brs[y + 1] and bx0[lo] <= x < bx1[lo] else 0
    seen = np.zeros(no, np.bool_)
    n_seen = 0
    for y in range(h):
        for r in range(ors[y], ors[y + 1]):
            c = comp[r]
            if seen[c]:
                continue
            near = False
            for yy in range(y, y + 3):
                # the background runs of padded row yy meeting columns ox0[r] .. ox1[r] + 1
                lo, hi = brs[yy], brs[yy + 1]  # (the first run ending after ox0[r])
                while lo < hi:
                    mid = (lo + hi) // 2
                    if bx1[mid] <= ox0[r]:
                        lo = mid + 1
                    else:
                        hi = mid
                j = lo
                while j < brs[yy + 1] and bx0[j] <= ox1[r] + 1:
                    if blab_r[j] == ext:
                        near = True
                        break
                    j += 1
                if near:
                    break
            if near:
                seen[c] = True
                n_seen += 1
    return no, labels, nbl, n_seen, ext


def label_mask(labels: np.ndarray, n: int, comps) -> np.ndarray:
    """``np.isin(labels, [c + 1 for c in comps])`` for a label image with labels ``0 .. n``: the
    pixels of components ``comps`` (0-based): one component or all of them by a comparison, others
    by a lookup table (np.isin sorts; this indexes).  A fresh array either way; on the mesher's
    boxes numpy's fancy indexing ``lut[labels]`` costs about 2 ns a pixel, ``np.take`` a third of
    that, a comparison a tenth."""
    cs = {int(c) for c in comps}
    if cs and min(cs) >= 0 and max(cs) < n:
        if len(cs) == 1:
            return np.asarray(labels) == max(cs) + 1
        if len(cs) == n:
            return np.asarray(labels) != 0
    lut = np.zeros(n + 1, dtype=bool)
    lut[np.asarray(list(comps), dtype=np.int64) + 1] = True
    return np.take(lut, labels)
