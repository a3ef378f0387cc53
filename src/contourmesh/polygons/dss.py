"""DSS polygon: vertices of greedy maximal digital straight segments of a closed 4-contour.

The paper (Wiederhold & Villafuerte 2009, sect. 5-6) represents each contour by "its sequence of
vertices of maximal digital straight segments (DSS)", computed with Kovalevsky's algorithm [16].
We use the equivalent arithmetical recognition of Debled-Rennesson & Reveilles (1995): a
4-connected DSS is a piece of a *standard* digital line

    mu <= a x - b y < mu + |a| + |b|,        gcd(a, b) = 1,

and a point is added in O(1) by updating ``(a, b, mu)`` from the leaning points, in exact integer
arithmetic.  The greedy segmentation (as DGtal's ``GreedySegmentation`` over an
``ArithmeticalDSSComputer``) starts at ``contour[0]``, extends each segment as far as it stays a DSS,
starts the next one at the last point of the previous one, and closes the last one at the start.
"""

from __future__ import annotations

import numpy as np

from .._kernels import njit
from ..tracing import check_contour4

__all__ = ["dss_polygon", "dss_vertex_indices"]


@njit(cache=True)
def _longest_dss(pts, i, n):
    """Largest ``j`` in ``(i, n]`` such that ``pts[i], pts[i+1], ..., pts[j]`` (indices mod n) is a
    4-connected DSS; the arithmetical recognition algorithm of Debled-Rennesson & Reveilles.

    The segment's two step directions are mapped to the first quadrant by the signs ``sx, sy``
    (fixed the first time a step along that axis occurs; before that every point has the same
    coordinate on that axis, so the choice does not matter).  In local coordinates
    ``(X, Y) = (sx (x - x_i), sy (y - y_i))`` the steps are (1, 0) and (0, 1), the line is
    ``mu <= a X - b Y < mu + a + b`` with ``a, b >= 0``, ``(b, a)`` its direction vector;
    ``Uf, Ul`` are its first/last upper leaning points (remainder ``mu``) and ``Lf, Ll`` its
    first/last lower leaning points (remainder ``mu + a + b - 1``).
    """
    x0 = pts[i, 0]
    y0 = pts[i, 1]
    sx = 0
    sy = 0
    a = 0
    b = 1
    mu = 0
    ufx = 0
    ufy = 0
    ulx = 0
    uly = 0
    lfx = 0
    lfy = 0
    llx = 0
    lly = 0
    j = i
    while j < n:
        k = (j + 1) % n
        dx = pts[k, 0] - pts[j % n, 0]
        dy = pts[k, 1] - pts[j % n, 1]
        # a 4-connected DSS uses at most two step directions, and never two opposite ones
        if dx != 0:
            if sx == 0:
                sx = dx
            elif dx != sx:
                return j
        if dy != 0:
            if sy == 0:
                sy = dy
            elif dy != sy:
                return j
        mx = (pts[k, 0] - x0) * (sx if sx != 0 else 1)
        my = (pts[k, 1] - y0) * (sy if sy != 0 else 1)
        r = a * mx - b * my
        if mu <= r and r < mu + a + b:
            # inside the current digital line: only leaning points may move
            if r == mu:
                ulx, uly = mx, my
            if r == mu + a + b - 1:
                llx, lly = mx, my
        elif r == mu - 1:
            # weakly exterior above: the slope increases; new line through Uf and M
            ulx, uly = mx, my
            lfx, lfy = llx, lly
            b = mx - ufx
            a = my - ufy
            mu = a * mx - b * my
        elif r == mu + a + b:
            # weakly exterior below: the slope decreases; new line through Lf and M
            llx, lly = mx, my
            ufx, ufy = ulx, uly
            b = mx - lfx
            a = my - lfy
            mu = a * ufx - b * ufy
        else:
            return j  # strongly exterior: not a DSS any more
        j += 1
    return j


@njit(cache=True)
def _greedy_segmentation(pts):
    """Indices of the DSS vertices: greedy maximal segments from index 0, the last one closing at 0."""
    n = pts.shape[0]
    out = np.empty(n, dtype=np.int64)
    nv = 0
    i = np.int64(0)  # not a literal 0: _longest_dss would be compiled once more for it
    while True:
        out[nv] = i
        nv += 1
        j = _longest_dss(pts, i, n)
        if j >= n:
            break
        i = j
    return out[:nv]


def dss_vertex_indices(contour) -> np.ndarray:
    """Indices into ``contour`` of the vertices of its greedy DSS segmentation.

    Segment ``s`` runs from ``contour[idx[s]]`` to ``contour[idx[s + 1]]`` (the last one back to
    ``contour[0]``); every segment except the last is maximal: adding the next contour point
    breaks it.
    """
    c = check_contour4(contour)
    return _greedy_segmentation(c)


def dss_polygon(contour) -> np.ndarray:
    """DSS polygon of a closed digital 4-contour (Kovalevsky 1990; Debled-Rennesson 1995).

    Parameters
    ----------
    contour : (k, 2) array_like of int
        A closed digital 4-curve as returned by :func:`contourmesh.tracing.trace_contours`
        (either orientation).

    Returns
    -------
    (p, 2) int64 ndarray
        The end points of the greedy maximal 4-connected DSSs, starting with ``contour[0]`` and in
        the contour's order (so the orientation is kept).  Segment end points are vertices by
        definition, even where two consecutive segments happen to be collinear.  A tiny contour
        can give a degenerate polygon (the 8-point contour of a single point of ``I`` gives 2
        vertices).

    Examples
    --------
    >>> import numpy as np
    >>> from contourmesh.tracing import trace_contours
    >>> (c,), _ = trace_contours(np.ones((3, 6), dtype=bool))
    >>> dss_polygon(c).tolist()
    [[-1, -1], [6, 0], [5, 3], [-1, 2]]
    """
    c = check_contour4(contour)
    return c[_greedy_segmentation(c)].copy()
