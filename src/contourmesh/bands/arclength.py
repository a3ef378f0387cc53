"""Band triangulation by normalized arc length (Ganapathy & Dennehy 1982).

From the initial edge of section 3.2 of the paper, both contours are parametrized by their
normalized perimeter ``s in [0, 1)``; the band advances the contour whose next vertex has the
smaller parameter.  It never wraps one contour around a single point of the other, so it is
the robust reference against which the volume mesher checks the local rules (a band of another
rule much larger than this one is twisted).  ``O(n + m)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .greedy import band_from_edge_rule
from .wiederhold import INITIAL_EDGE_WINDOW

__all__ = ["triangulate_band_arclength", "arclength_edges"]


@njit(cache=True)
def arclength_edges(c1, c2):
    """Edge sequence ``(i, j)`` of the arc-length band from the initial edge ``(0, 0)``."""
    n, m = len(c1), len(c2)
    s1 = np.zeros(n + 1)
    s2 = np.zeros(m + 1)
    for i in range(n):
        d = c1[(i + 1) % n] - c1[i]
        s1[i + 1] = s1[i] + np.sqrt(d[0] * d[0] + d[1] * d[1])
    for j in range(m):
        d = c2[(j + 1) % m] - c2[j]
        s2[j + 1] = s2[j] + np.sqrt(d[0] * d[0] + d[1] * d[1])
    if s1[n] > 0:
        s1 /= s1[n]
    else:
        for i in range(n + 1):
            s1[i] = i / n
    if s2[m] > 0:
        s2 /= s2[m]
    else:
        for j in range(m + 1):
            s2[j] = j / m
    edges = np.empty((n + m, 2), dtype=np.int64)
    i = 0
    j = 0
    edges[0, 0] = 0
    edges[0, 1] = 0
    for k in range(1, n + m):
        if j >= m or (i < n and s1[i + 1] <= s2[j + 1]):
            i += 1
        else:
            j += 1
        edges[k, 0] = i % n
        edges[k, 1] = j % m
    return edges


def triangulate_band_arclength(lower, upper, *, window: int = INITIAL_EDGE_WINDOW, radius: float | None = None):
    """Triangulate a band by advancing both contours in proportion to their arc length.

    Same signature and result convention as :func:`contourmesh.bands.triangulate_band`.
    """
    return band_from_edge_rule(lower, upper, arclength_edges, window=window, radius=radius)
