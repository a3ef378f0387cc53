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

__all__ = ["POLYGONIZERS", "polygonize", "contour_polygon", "dss_polygon", "mlp_polygon"]


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
