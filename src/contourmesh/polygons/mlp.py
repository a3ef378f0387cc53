"""Minimum-length polygon (MLP) of a closed 4-contour.

The paper (Wiederhold & Villafuerte 2009, sect. 5-6) represents each contour by its MLP, computed
"applying the algorithm due to Klette/Yip [14]".  Our setting: the contour is the boundary of
``U`` (union of the closed cells with a corner in ``I``, ``U`` on the left of the traversal); the
MLP is the shortest closed polygon in the band between the contour and ``V`` (the cells whose four
corners are in ``I``) going once around - equivalently the boundary of the relative convex hull
of ``I`` in ``U`` (Sklansky, Chazin & Hansen 1972; Klette & Rosenfeld 2004, sect. 12.2).

A contour determines ``U`` but not ``I``; the polygon is computed from the contour alone, with
``I'`` = the grid points interior to ``U`` (all four cells around them in ``U``) and ``V'`` the cells
with four corners in ``I'``.  ``I' = I`` for outer Jordan digitizations except where a point missing
from ``I`` has points of ``I`` on all four sides (features thinner than the grid).

Algorithm (string pulling after the "MLP algorithm" of Gonzalez & Woods, *Digital Image
Processing*, 3rd ed., sect. 11.1.3, and Klette & Yip 2000), as a funnel with one crawler per side:

1. walk the contour (``U`` on its left) and list, in order: **B** = its concave corners (the outer
   wall's reflex corners: the only places where the MLP turns right), **C** = its convex corners
   (outer wall; constraints only) and **W** = the points of ``I'`` next to the band (the inner
   wall; at a convex corner, the corner moved one unit diagonally into ``U``: the only places where
   the MLP turns left);
2. start at a candidate that is certainly an MLP vertex: the lowest-then-leftmost W for an outer
   contour (extreme in the convex hull of ``I'``), the lowest-then-leftmost B for a hole (extreme in
   the hole's convex hull).  From the last vertex ``VL`` the free directions form a cone bounded on
   the left by the *white crawler* WC (a W: W points must stay left of the path) and on the right by
   the *black crawler* BC (a B: B and C points must stay right of it).  A W right of BC, or a B or C
   left of WC, empties the cone: BC (a right turn) or WC (a left turn) is the next vertex, and the
   walk restarts after it.  Otherwise a W clockwise of WC (a B counter-clockwise of BC) becomes the
   new crawler.

All predicates are exact integer cross and dot products.
"""

from __future__ import annotations

import numpy as np

from .._kernels import internal_kernel, njit
from ..errors import ThinRegionError
from ..geometry import successor
from ..tracing import check_contour4

__all__ = ["mlp_polygon", "mlp_candidates"]


@njit(cache=True, nogil=True)
def _mlp(pts, colour):
    """The cached Python entry of :func:`_mlp_kernel` (the fast path calls the kernel directly)."""
    return _mlp_kernel(pts, colour)


@internal_kernel
def _mlp_kernel(pts, colour):
    """:func:`_mlp_grid` on grids of the contour's bounding box (plus a margin of two)."""
    n = len(pts)
    xmin, ymin = pts[0, 0], pts[0, 1]
    xmax, ymax = xmin, ymin
    for k in range(n):
        x, y = pts[k, 0], pts[k, 1]
        if x < xmin:
            xmin = x
        if x > xmax:
            xmax = x
        if y < ymin:
            ymin = y
        if y > ymax:
            ymax = y
    w, h = xmax - xmin + 5, ymax - ymin + 5
    on = np.empty(h * w, np.uint8)
    bg = np.empty(h * w, np.uint8)
    for q in range(h * w):
        on[q] = 0
        bg[q] = 0
    return _mlp_grid(pts, colour, on, bg, xmin - 2, ymin - 2, w)


@internal_kernel
def _mlp_grid(pts, colour, on, bg, ox, oy, w):
    """Steps 1 and 2 above for a closed 4-contour with ``U`` on its left, in one kernel.

    Returns ``(cand, kind, poly)``.  ``cand (m, 2)`` and ``kind (m,)`` are the candidates of step 1
    in contour order:

    * +1 = W: a grid point interior to ``U`` (its four cells in ``U``) next to the band, i.e. a
      corner of the cell on the left of a contour step that is not itself on the contour.  These
      are the inner wall; at a convex corner of the contour it is the point diagonally inside;
    * -1 = B: a concave corner of the contour (the outer wall's reflex corners);
    * 0 = C: a convex corner of the contour (outer wall; a constraint only, never a vertex).

    A W equal to the previous W is dropped.  ``poly (p, 2)`` is the MLP, starting at its vertex
    nearest ``pts[0]`` (ties: the first in MLP order), pulled from the lowest-then-leftmost
    candidate of kind ``colour`` (+1 for an outer contour, -1 for a hole); a single candidate
    W or B is the whole MLP.  ``poly`` is empty when ``colour`` is 0 (candidates only) or when
    there is no candidate of kind ``colour``.

    ``on`` and ``bg`` are flat ``uint8`` grids of width ``w`` whose cell ``(y - oy) * w + (x - ox)``
    stands for the grid point ``(x, y)``; they must cover the contour's bounding box with a margin
    of two, be zero on entry, and are zero again on return (only the cells the contour touches
    are written), so that a caller meshing many slices reuses one pair of slice-sized grids
    instead of allocating and clearing a pair per contour.

    (Explicit loops and one helper kernel, :func:`_mlp_pull` for everything after the candidates,
    which the fast path shares: each separately compiled kernel costs compile time.)
    """
    # ---- step 1: the candidates
    n = len(pts)
    # flat grids indexed (y - oy) * w + (x - ox), all zero on entry and again on return:
    # on = grid points of the contour, bg = cells (by lower-left corner) right of a contour step
    for k in range(n):
        x, y = pts[k, 0], pts[k, 1]
        kn = k + 1 if k + 1 < n else 0
        dx, dy = pts[kn, 0] - x, pts[kn, 1] - y
        on[(y - oy) * w + x - ox] = 1
        # the cell right of the step (x, y) -> (x + dx, y + dy) has lower-left corner:
        if dx > 0:
            cx, cy = x, y - 1
        elif dx < 0:
            cx, cy = x - 1, y
        elif dy > 0:
            cx, cy = x, y
        else:
            cx, cy = x - 1, y - 1
        bg[(cy - oy) * w + cx - ox] = 1
    cand = np.empty((3 * n, 2), np.int64)
    kind = np.empty(3 * n, np.int64)
    m = 0
    lastw_x, lastw_y, has_w = 0, 0, False
    for k in range(n):
        kp = k - 1 if k > 0 else n - 1
        kn = k + 1 if k + 1 < n else 0
        px, py = pts[kp, 0], pts[kp, 1]
        cx, cy = pts[k, 0], pts[k, 1]
        nx, ny = pts[kn, 0], pts[kn, 1]
        ix, iy = cx - px, cy - py  # incoming step
        sx, sy = nx - cx, ny - cy  # outgoing step
        turn = ix * sy - iy * sx
        if turn != 0:
            cand[m, 0] = cx
            cand[m, 1] = cy
            kind[m] = 0 if turn > 0 else -1
            m += 1
        # the inner corners of the cell left of the outgoing step: c + left, c + step + left
        lx, ly = -sy, sx
        for j in range(2):
            qx, qy = cx + lx + j * sx, cy + ly + j * sy
            q = (qy - oy) * w + qx - ox
            if on[q]:
                continue
            if bg[q] or bg[q - w] or bg[q - 1] or bg[q - w - 1]:
                continue  # a cell around q is not in U: q is not interior to U
            if has_w and qx == lastw_x and qy == lastw_y:
                continue
            cand[m, 0] = qx
            cand[m, 1] = qy
            kind[m] = 1
            m += 1
            lastw_x, lastw_y, has_w = qx, qy, True
    # the grids are not needed any more: back to zero, touching only what step 1 set
    for k in range(n):
        x, y = pts[k, 0], pts[k, 1]
        q = (y - oy) * w + x - ox
        on[q] = 0
        bg[q] = 0
        bg[q - 1] = 0
        bg[q - w] = 0
        bg[q - w - 1] = 0
    return _mlp_pull(pts, cand, kind, np.int64(m), colour)  # (int64: m may start as a literal)


@internal_kernel
def _mlp_pull(pts, cand, kind, m, colour):
    """The end of :func:`_mlp_grid` on its step 1 candidates ``cand[:m]``, ``kind[:m]`` (in contour
    order, consecutive equal W dropped): the last W dropped where it repeats the first, then step 2
    from the lowest-then-leftmost candidate of kind ``colour``; returns ``(cand, kind, poly)`` as
    :func:`_mlp_grid` does.  (The fast path makes the candidates of its stacks without the grids,
    :func:`contourmesh.fastpath._stack_candidates`, and pulls them here.)

    The returned ``cand`` and ``kind`` are views of the arrays passed in, whose contents the call
    may change: read the candidates from the returned views only."""
    # the last W may repeat the first W (cyclically consecutive): drop the later copy, the first
    # one, as above - the B/C candidates between the two copies (a convex corner is listed after
    # its diagonal W) must stay after the kept one, or a C is tested before its W is reached
    first = 0
    while first < m and kind[first] != 1:
        first += 1
    last = m - 1
    while last >= 0 and kind[last] != 1:
        last -= 1
    lo = 0
    if last > first and cand[last, 0] == cand[first, 0] and cand[last, 1] == cand[first, 1]:
        # candidate ``first`` leaves the list: the ``first`` candidates before it move up one
        # place and the list starts one place later.  The same list as moving the ones after it
        # down one place, but ``first`` is small (the contour's first W comes after at most a few
        # corners) where the ones after it are nearly all of them: on every slice of a ball the
        # copy repeats, and moving the tail was a fifth of the pull's time
        for i in range(first, 0, -1):
            cand[i, 0] = cand[i - 1, 0]
            cand[i, 1] = cand[i - 1, 1]
            kind[i] = kind[i - 1]
        lo = 1
    cand = cand[lo:m]
    kind = kind[lo:m]
    m -= lo
    empty = np.empty((0, 2), np.int64)
    if colour == 0:
        return cand, kind, empty
    nnz = 0
    last = -1
    for i in range(m):
        if kind[i] != 0:
            nnz += 1
            last = i
    if nnz == 1:
        # a single point of I (or a single concave corner): the MLP is that point
        poly = np.empty((1, 2), np.int64)
        poly[0, 0] = cand[last, 0]
        poly[0, 1] = cand[last, 1]
        p = 1
    else:
        # ---- step 2: string pulling from a candidate that is certainly an MLP vertex, the
        # lowest-then-leftmost W (outer contour) or B (hole)
        s = -1
        for i in range(m):
            if kind[i] == colour:
                if s < 0 or cand[i, 1] < cand[s, 1] or (cand[i, 1] == cand[s, 1] and cand[i, 0] < cand[s, 0]):
                    s = i
        if s < 0:
            return cand, kind, empty
        # Candidates are visited in the unrolled order s, s+1, ..., s+m (the last one is s
        # again); vl, wc, bc are positions in that order.  W candidates lie on the left of the
        # path, B and C candidates on its right; C candidates are never vertices.
        out = np.empty(m + 1, np.int64)
        nv = 0
        out[nv] = s
        nv += 1
        vl = s
        wc = s
        bc = s
        k = s + 1
        # (positions lie in [s, s + m] with s < m: position p is candidate p or p - m, taken
        # with a comparison rather than an integer division.)  VL's coordinates (lx, ly) and the
        # crawlers' offsets from VL (wx, wy), (bx, by) are kept in variables, set where vl, wc or
        # bc change, instead of read from cand for every candidate: the same values, so the same
        # path (tests/test_mlp_pull.py keeps the form that read them and compares)
        lx, ly = cand[s, 0], cand[s, 1]
        wx, wy, bx, by = 0, 0, 0, 0
        while k <= s + m:
            ik = k if k < m else k - m
            vx, vy = cand[ik, 0] - lx, cand[ik, 1] - ly
            new_vertex = -1
            w_set = wx != 0 or wy != 0
            b_set = bx != 0 or by != 0
            kk = kind[ik]
            if kk == 0:
                # a convex corner of the contour (the outer wall) must stay on the right of the path:
                # if it lies left of WC the path cannot go on straight and turns left at WC
                if w_set and wx * vy - wy * vx > 0:
                    new_vertex = wc
            elif vx == 0 and vy == 0:
                # back at VL's position: the path turned round at the pending crawler
                if kk > 0:
                    new_vertex = wc if w_set else (bc if b_set else -1)
                else:
                    new_vertex = bc if b_set else (wc if w_set else -1)
            elif kk > 0:
                # a W candidate must stay on the left: the free directions are clockwise of it
                if b_set and bx * vy - by * vx < 0:
                    new_vertex = bc  # right of BC: the cone is empty, the path turns right at BC
                elif w_set:
                    cw = wx * vy - wy * vx
                    if cw < 0:
                        wc, wx, wy = k, vx, vy  # a tighter left bound
                    elif cw == 0:
                        if wx * vx + wy * vy < wx * wx + wy * wy:
                            new_vertex = wc  # turns back along the ray: a U-turn at WC
                        else:
                            wc, wx, wy = k, vx, vy  # straight on through WC
                    elif k == s + m:
                        new_vertex = wc  # the closing vertex lies left of WC: turn left at WC
                else:
                    wc, wx, wy = k, vx, vy
            else:
                # a B candidate must stay on the right: the free directions are counter-clockwise of it
                if w_set and wx * vy - wy * vx > 0:
                    new_vertex = wc  # left of WC: the cone is empty, the path turns left at WC
                elif b_set:
                    cb = bx * vy - by * vx
                    if cb > 0:
                        bc, bx, by = k, vx, vy  # a tighter right bound
                    elif cb == 0:
                        if bx * vx + by * vy < bx * bx + by * by:
                            new_vertex = bc  # turns back along the ray: a U-turn at BC
                        else:
                            bc, bx, by = k, vx, vy
                    elif k == s + m:
                        new_vertex = bc  # the closing vertex lies right of BC: turn right at BC
                else:
                    bc, bx, by = k, vx, vy
            if new_vertex >= 0:
                iv = new_vertex if new_vertex < m else new_vertex - m
                out[nv] = iv
                nv += 1
                vl = new_vertex
                wc = vl
                bc = vl
                lx, ly = cand[iv, 0], cand[iv, 1]
                wx, wy, bx, by = 0, 0, 0, 0
                k = vl + 1
                continue
            k += 1
        # the path's vertices, without cyclically consecutive duplicates and vertices where it
        # goes straight on (one at a time, rescanning from the start after each removal)
        poly = np.empty((nv, 2), np.int64)
        for i in range(nv):
            poly[i, 0] = cand[out[i], 0]
            poly[i, 1] = cand[out[i], 1]
        p = nv
        changed = True
        while changed and p > 1:
            changed = False
            drop = -1
            for i in range(p):
                a = i - 1 if i > 0 else p - 1
                c = i + 1 if i + 1 < p else 0
                ax, ay = poly[a, 0], poly[a, 1]
                bx, by = poly[i, 0], poly[i, 1]
                cx, cy = poly[c, 0], poly[c, 1]
                if ax == bx and ay == by:
                    drop = i
                    break
                if p > 2:
                    ux, uy, vx, vy = bx - ax, by - ay, cx - bx, cy - by
                    if ux * vy - uy * vx == 0 and ux * vx + uy * vy > 0:
                        drop = i
                        break
            if drop >= 0:
                for i in range(drop, p - 1):
                    poly[i, 0] = poly[i + 1, 0]
                    poly[i, 1] = poly[i + 1, 1]
                p -= 1
                changed = True
    # ---- from the vertex nearest pts[0]
    best = 0
    bd = -1
    for i in range(p):
        dx = poly[i, 0] - pts[0, 0]
        dy = poly[i, 1] - pts[0, 1]
        d2 = dx * dx + dy * dy
        if bd < 0 or d2 < bd:
            bd = d2
            best = i
    out2 = np.empty((p, 2), np.int64)
    for i in range(p):
        k = i + best if i + best < p else i + best - p
        out2[i, 0] = poly[k, 0]
        out2[i, 1] = poly[k, 1]
    return cand, kind, out2


def mlp_candidates(contour) -> tuple[np.ndarray, np.ndarray]:
    """Candidates of a contour in order: W (+1, points of ``I``), B (-1, concave corners) and
    C (0, convex corners of the contour: constraints only)."""
    c = check_contour4(contour)
    cand, kind, _ = _mlp(c, 0)
    return cand, kind


def mlp_polygon(contour) -> np.ndarray:
    """Minimum-length polygon of a closed digital 4-contour (the relative convex hull of ``I`` in ``U``).

    Parameters
    ----------
    contour : (k, 2) array_like of int
        A closed digital 4-curve with ``U`` on its left, as returned by
        :func:`contourmesh.tracing.trace_contours`: an outer contour (positive area; the band is
        inside it) or a hole (negative area; the band is outside the hole).

    Returns
    -------
    (p, 2) int64 ndarray
        The MLP vertices in the contour's order (same orientation), starting at the vertex nearest
        ``contour[0]`` (ties: the first in MLP order).  Convex vertices are points of ``I'``
        (interior grid points of ``U``; equal to ``I`` unless ``I`` has one-point gaps), concave
        ones are concave corners of the contour.  Where ``V`` is empty or too thin the MLP
        degenerates to the shortest closed curve around ``I``: a single point (``p == 1``), a
        segment (its two end points) or a polygon with zero-area parts.  No two consecutive
        vertices coincide, and no vertex lies on a straight continuation of its neighbours.

    Examples
    --------
    >>> import numpy as np
    >>> from contourmesh.tracing import trace_contours
    >>> (c,), _ = trace_contours(np.ones((3, 6), dtype=bool))
    >>> mlp_polygon(c).tolist()
    [[0, 0], [5, 0], [5, 2], [0, 2]]
    >>> (c,), _ = trace_contours(np.ones((1, 4), dtype=bool))
    >>> mlp_polygon(c).tolist()
    [[0, 0], [3, 0]]
    """
    c = check_contour4(contour)
    x, y = c[:, 0], c[:, 1]  # integers: the sum is exact in any order
    twice_area = int(np.dot(x, successor(y)) - np.dot(successor(x), y))
    _, _, poly = _mlp(c, 1 if twice_area > 0 else -1)
    if len(poly) == 0:
        raise ThinRegionError(
            "contour is not the boundary of an outer Jordan digitization: it encloses no grid "
            "point whose four surrounding cells are all inside (e.g. a region one cell thin)"
        )
    return poly
