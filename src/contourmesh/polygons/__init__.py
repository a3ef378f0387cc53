"""Polygonizers: a closed digital 4-contour -> the polygon that represents it.

One signature, strategies by name (the paper, sect. 5: each contour is represented "by its
sequence of vertices of maximal digital straight segments (DSS), or by its minimal length polygon
(MLP)"):

* ``"dss"``  - :func:`~contourmesh.polygons.dss.dss_polygon`, greedy maximal DSS vertices;
* ``"mlp"``  - :func:`~contourmesh.polygons.mlp.mlp_polygon`, the minimum-length polygon;
* ``"none"`` - :func:`contour_polygon`, the contour itself (every point), the reference.

Every polygonizer maps a ``(k, 2)`` int64 contour to a ``(p, 2)`` int64 polygon that keeps the
contour's orientation and (as far as the algorithm allows) its start point.
"""

from __future__ import annotations

import numpy as np

from .dss import dss_polygon
from .mlp import mlp_polygon

__all__ = ["POLYGONIZERS", "polygonize", "contour_polygon", "dss_polygon", "mlp_polygon", "thin_part_polygon",
           "is_simple_polygon"]


def contour_polygon(contour) -> np.ndarray:
    """The contour itself as its polygon (every point kept): the reference polygonizer.

    Accepts any ``(k, 2)`` array of finite coordinates (also real-valued contours read from
    files) and returns a copy; integer input stays int64.
    """
    c = np.asarray(contour)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) == 0:
        raise ValueError(f"contour must be a non-empty (k, 2) array of points (x, y); got shape {c.shape}")
    if np.issubdtype(c.dtype, np.integer):
        return np.array(c, dtype=np.int64)
    if not np.issubdtype(c.dtype, np.floating) or not np.all(np.isfinite(c)):
        raise ValueError(f"contour must hold finite numbers; got dtype {c.dtype}")
    return np.array(c, dtype=np.float64)


POLYGONIZERS = {"dss": dss_polygon, "mlp": mlp_polygon, "none": contour_polygon}


def polygonize(contour, method: str = "mlp") -> np.ndarray:
    """Polygon of a closed 4-contour by the named method (``"dss"``, ``"mlp"`` or ``"none"``).

    Examples
    --------
    >>> import numpy as np
    >>> from contourmesh.tracing import trace_contours
    >>> (c,), _ = trace_contours(np.ones((2, 2), dtype=bool))
    >>> polygonize(c, "mlp").tolist()
    [[0, 0], [1, 0], [1, 1], [0, 1]]
    """
    try:
        fn = POLYGONIZERS[method]
    except (KeyError, TypeError):
        raise ValueError(f"unknown polygon method {method!r}; expected one of {sorted(POLYGONIZERS)}") from None
    return fn(contour)


def is_simple_polygon(poly) -> bool:
    """True when the closed polygon has distinct vertices and no two non-adjacent edges meet."""
    p = np.asarray(poly, dtype=np.float64)
    n = len(p)
    if n < 3 or len(np.unique(p, axis=0)) != n:
        return False
    a, b = p, np.roll(p, -1, axis=0)

    def orient(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    A, B = a[:, None], b[:, None]
    C, D = a[None, :], b[None, :]
    d1, d2 = orient(A, B, C), orient(A, B, D)
    d3, d4 = orient(C, D, A), orient(C, D, B)
    meet = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    i, j = np.indices((n, n))
    adjacent = (np.abs(i - j) <= 1) | (np.abs(i - j) == n - 1)
    return not (meet & ~adjacent).any()


def thin_part_polygon(contour) -> np.ndarray:
    """The polygon of a contour whose MLP degenerates (a part one pixel wide: the MLP is a segment
    or a point): the maximal-DSS polygon of the crack contour itself where that is a simple
    polygon of the same orientation, else the crack contour.  Both enclose the pixels, and the DSS
    polygon has no staircase along a thin diagonal part."""
    c = np.asarray(contour, dtype=np.int64)
    d = np.asarray(dss_polygon(c), dtype=np.int64)
    area = lambda q: float(np.dot(q[:, 0], np.roll(q[:, 1], -1)) - np.dot(np.roll(q[:, 0], -1), q[:, 1]))
    if len(d) >= 3 and area(d) * area(c) > 0 and is_simple_polygon(d):
        return d
    return c
