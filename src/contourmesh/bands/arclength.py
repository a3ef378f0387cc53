"""Band triangulation by normalized arc length (Ganapathy & Dennehy 1982).

From the initial edge of section 3.2 of the paper, both contours are parametrized by their
normalized perimeter ``s in [0, 1)``; the band advances the contour whose next vertex has the
smaller parameter.  It never wraps one contour around a single point of the other, so it is
the robust reference against which the volume mesher checks the local rules (a band of another
rule much larger than this one is twisted).  ``O(n + m)``.
"""

from __future__ import annotations

import math

import numpy as np

from .._kernels import internal_kernel, njit
from .greedy import band_from_edge_rule
from .wiederhold import INITIAL_EDGE_WINDOW

__all__ = ["triangulate_band_arclength", "arclength_edges"]


@njit(cache=True, nogil=True)
def arclength_edges(c1, c2):
    """Edge sequence ``(i, j)`` of the arc-length band from the initial edge ``(0, 0)``: the
    cached Python entry of :func:`_arclength_edges`, which the fast path calls directly."""
    return _arclength_edges(c1, c2)


@internal_kernel
def _arclength_edges(c1, c2):
    """Edge sequence ``(i, j)`` of the arc-length band from the initial edge ``(0, 0)``."""
    n, m = len(c1), len(c2)
    s1 = np.empty(n + 1, np.float64)
    s2 = np.empty(m + 1, np.float64)
    s1[0] = 0.0
    s2[0] = 0.0
    for i in range(n):
        k = i + 1 if i + 1 < n else 0
        dx = c1[k, 0] - c1[i, 0]
        dy = c1[k, 1] - c1[i, 1]
        s1[i + 1] = s1[i] + math.sqrt(dx * dx + dy * dy)
    for j in range(m):
        k = j + 1 if j + 1 < m else 0
        dx = c2[k, 0] - c2[j, 0]
        dy = c2[k, 1] - c2[j, 1]
        s2[j + 1] = s2[j] + math.sqrt(dx * dx + dy * dy)
    # normalize to [0, 1] (scalar loops: no array expressions to compile)
    t1 = s1[n]
    for i in range(n + 1):
        s1[i] = s1[i] / t1 if t1 > 0 else i / n
    t2 = s2[m]
    for j in range(m + 1):
        s2[j] = s2[j] / t2 if t2 > 0 else j / m
    edges = np.empty((n + m, 2), np.int64)
    i = 0
    j = 0
    edges[0, 0] = 0
    edges[0, 1] = 0
    for k in range(1, n + m):
        if j >= m or (i < n and s1[i + 1] <= s2[j + 1]):
            i += 1
        else:
            j += 1
        edges[k, 0] = i if i < n else 0  # i % n (0 <= i <= n)
        edges[k, 1] = j if j < m else 0
    return edges


def triangulate_band_arclength(lower, upper, *, window: int = INITIAL_EDGE_WINDOW, radius: float | None = None):
    """Triangulate a band by advancing both contours in proportion to their arc length.

    Same signature and result convention as :func:`contourmesh.bands.triangulate_band`.
    """
    return band_from_edge_rule(lower, upper, arclength_edges, window=window, radius=radius)
