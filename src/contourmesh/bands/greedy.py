"""Band triangulation by the shortest-diagonal rule (Christiansen & Sederberg 1978).

From the initial edge ``(p(1)_1, p(2)_1)`` (chosen as in Wiederhold & Villafuerte, section 3.2,
see :func:`contourmesh.bands.wiederhold.initial_edge`), each step adds the shorter (in 3D) of the
two candidate diagonals ``(p(1)_{i+1}, p(2)_j)`` and ``(p(1)_i, p(2)_{j+1})``, i.e. it advances the
contour whose new diagonal is shorter; once a contour is exhausted the other one advances until
both are back at the initial edge.  H. N. Christiansen and T. W. Sederberg, "Conversion of
complex contour line definitions into polygonal element mosaics", SIGGRAPH 1978.
"""

from __future__ import annotations

import numpy as np

from .._kernels import njit
from .wiederhold import (
    INITIAL_EDGE_WINDOW,
    edges_to_faces,
    initial_edge,
    oriented_pair,
    validate_band_polygons,
)

__all__ = ["triangulate_band_greedy", "greedy_edges"]


@njit(cache=True)
def greedy_edges(c1, c2):
    """Edge sequence of the shortest-diagonal rule.

    Parameters
    ----------
    c1 : ndarray of float64, shape (n, 3)
        First contour, starting at the initial edge's point.
    c2 : ndarray of float64, shape (m, 3)
        Second contour, starting at the initial edge's point.

    Returns
    -------
    ndarray of int64, shape (n + m, 2)
        Edges ``(i, j)`` (0-based, ``i`` modulo ``n``, ``j`` modulo ``m``), ``e_0 = (0, 0)``;
        consecutive edges (cyclically) form the triangles.  Ties advance ``C(1)``.
    """
    n = c1.shape[0]
    m = c2.shape[0]
    E = np.empty((n + m, 2), dtype=np.int64)
    i = 0
    j = 0
    E[0, 0] = 0
    E[0, 1] = 0
    for k in range(1, n + m):
        if i == n:
            j += 1
        elif j == m:
            i += 1
        else:
            a_next = c1[(i + 1) % n]
            a_cur = c1[i % n]
            b_cur = c2[j % m]
            b_next = c2[(j + 1) % m]
            d1 = 0.0   # squared length of (p(1)_{i+1}, p(2)_j)
            d2 = 0.0   # squared length of (p(1)_i, p(2)_{j+1})
            for c in range(3):
                d1 += (a_next[c] - b_cur[c]) ** 2
                d2 += (a_cur[c] - b_next[c]) ** 2
            if d1 <= d2:
                i += 1
            else:
                j += 1
        E[k, 0] = i % n
        E[k, 1] = j % m
    return E


def triangulate_band_greedy(lower, upper, *, window: int = INITIAL_EDGE_WINDOW,
                            radius: float | None = None) -> np.ndarray:
    """Triangulate a band by always taking the shorter next diagonal.

    Parameters
    ----------
    lower : array_like, shape (n, 3)
        Closed polygon at height ``z1``.
    upper : array_like, shape (m, 3)
        Closed polygon at height ``z2 > z1``, same orientation convention.
    window, radius : optional
        Neighbourhood of the initial-edge search (see
        :func:`contourmesh.bands.wiederhold.initial_edge`).

    Returns
    -------
    faces : ndarray of int64, shape (n + m, 3)
        Triangles indexing ``np.vstack([lower, upper])`` (``max(n, m)`` for a pole point,
        none for two points).
    """
    return band_from_edge_rule(lower, upper, greedy_edges, window=window, radius=radius)


def band_from_edge_rule(lower, upper, rule, *, window: int = INITIAL_EDGE_WINDOW, radius: float | None = None):
    """A band from an edge-sequence rule ``rule(c1, c2) -> edges`` that starts at the initial edge
    ``(0, 0)``: validation, the paper's contour swap (n <= m) and initial edge (section 3.2), the
    one-to-many fan for a single point, and the conversion of the edges into oriented faces."""
    lo, up = validate_band_polygons(lower, upper)
    if len(lo) == 1 and len(up) == 1:
        return np.empty((0, 3), dtype=np.int64)
    c1, c2, swapped = oriented_pair(lo, up)
    j0 = initial_edge(c1, c2, window=window, radius=radius)
    if len(c1) == 1:
        edges = np.stack([np.zeros(len(c2), np.int64), np.arange(len(c2), dtype=np.int64)], axis=1)
    else:
        # (np.roll(c2, -j0, axis=0) as one concatenation: the same contiguous copy, cheaper)
        edges = rule(c1, np.concatenate((c2[j0:], c2[:j0])))
    return edges_to_faces(edges, len(c1), len(c2), 0, j0, len(lo), swapped)
