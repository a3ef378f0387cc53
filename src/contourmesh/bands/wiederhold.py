"""Band triangulation between two consecutive polygons: Wiederhold & Villafuerte (2009), section 3.

The paper's algorithm ("Triangulation algorithm for two consecutive contours", section 3.4,
lines 01-32) walks the two contours ``C(1)`` (``n`` points) and ``C(2)`` (``m >= n`` points)
from an initial edge ``(p(1)_1, p(2)_1)`` (section 3.2).  Every step adds one edge
``(p(1)_i, p(2)_j)`` that advances exactly one of the two contours; two consecutive edges and
the polygon edge between them form a triangle.  The choice is made by comparisons of raw
``x`` and ``y`` coordinates only (steps of type A: "to the right, upwards, to the left,
downwards", with the paper's y axis pointing down; step B: advance ``C(2)``).

This module also holds the pieces that all band strategies share (input validation, the
initial edge, and the conversion of an edge sequence into oriented triangles), because the
greedy and optimal strategies start from the same conventions.

Conventions
-----------
A band is computed between ``lower`` (``(n, 3)``, height ``z1``) and ``upper`` (``(m, 3)``,
height ``z2 > z1``), both with the same orientation (positive shoelace area in raw ``(x, y)``
for outer contours, which is the paper's "clockwise with the y axis pointing down"; negative
for holes).  Faces index ``np.vstack([lower, upper])``.  A triangle on a lower edge is
``(a_i, a_{i+1}, b_j)`` and one on an upper edge is ``(a_i, b_{j+1}, b_j)``, which gives outward
normals for outer contours and for holes alike.

Faithfulness
------------
The pseudo-code is implemented literally (a ``line`` variable plays the role of its ``go to``
targets; the comments carry its line numbers).  As written it always terminates after
``n + m - 2`` steps plus the closing edge of line 26 and the closing triangle ``(e_{k+1}, e_0)``,
and uses every polygon edge exactly once: line 28 keeps ``j <= m``, line 30 never lets ``i``
pass ``n``, and lines 25-26 stop exactly at ``(n, m)``.  The property tests in
``tests/test_bands.py`` check this on many random convex, star-shaped, non-convex and
degenerate pairs; no deviation was needed.  The only additions are the ones the paper leaves
open: the swap that enforces ``n <= m`` (condition (i); the triangles are flipped back so the
orientation stays right), the initial-edge search of step 01 (see :func:`initial_edge`), and the
degenerate case where both polygons are single points (no surface: an empty face array).

Like any rule that walks the toroidal graph locally, the algorithm may, on very dissimilar
pairs (e.g. two thin triangles rotated against each other), advance all of ``C(2)`` at a single
point of ``C(1)``: the band is then a "double cone" whose diagonal at that point carries four
triangles (non-manifold), although every polygon edge is still used exactly once.  This is
the pseudo-code's own behaviour and is kept; ``"optimal"`` excludes such bands.
"""

from __future__ import annotations

import numpy as np

from .._kernels import internal_kernel, njit
from ..geometry import successor

__all__ = [
    "triangulate_band_wiederhold",
    "wiederhold_edges",
    "initial_edge",
    "validate_band_polygons",
    "edges_to_faces",
    "oriented_pair",
]

#: Half-width (in contour indices) of the window of ``C(2)`` searched for the initial edge.
INITIAL_EDGE_WINDOW = 32


# --------------------------------------------------------------------------------------------
# Validation shared by every strategy
# --------------------------------------------------------------------------------------------
def _as_polygon3(poly, name: str) -> np.ndarray:
    p = np.asarray(poly)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name} must be an (n, 3) array of (x, y, z) points; got shape {p.shape}")
    if len(p) == 0:
        raise ValueError(f"{name} must contain at least one point; got an empty array")
    if p.dtype != np.float64 and (not np.issubdtype(p.dtype, np.number)
                                  or np.issubdtype(p.dtype, np.complexfloating)):
        raise ValueError(f"{name} must hold real numbers; got dtype {p.dtype}")
    p = np.ascontiguousarray(p, dtype=np.float64)
    if _polygon3_ok(p):  # the three checks below, compiled, for the polygons that pass them
        return p
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must contain only finite coordinates; found NaN or inf")
    z = p[:, 2]
    if np.any(z != z[0]):
        raise ValueError(
            f"{name} must lie in one plane z = const; found z from {z.min()!r} to {z.max()!r}"
        )
    if len(p) >= 2:
        nxt = successor(p[:, :2])
        same = np.all(p[:, :2] == nxt, axis=1)
        if np.any(same):
            k = int(np.flatnonzero(same)[0])
            raise ValueError(
                f"{name} must not repeat a point at consecutive positions (closed implicitly, no "
                f"repeated end point); point {k} equals point {(k + 1) % len(p)}: {p[k, :2].tolist()}"
            )
    return p


@njit(cache=True)
def _polygon3_ok(p):
    """True when :func:`_as_polygon3`'s value checks all pass: finite coordinates, one ``z``, no
    point equal to the next one round the ring."""
    n = p.shape[0]
    for i in range(n):
        for d in range(3):
            if not np.isfinite(p[i, d]):
                return False
    for i in range(n):
        if p[i, 2] != p[0, 2]:
            return False
    if n >= 2:
        for i in range(n):
            j = (i + 1) % n
            if p[i, 0] == p[j, 0] and p[i, 1] == p[j, 1]:
                return False
    return True


def validate_band_polygons(lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """Check and convert the two polygons of a band.

    Parameters
    ----------
    lower, upper : array_like, shapes (n, 3) and (m, 3)
        Closed polygons (implicitly closed, no repeated end point), each in one plane
        ``z = const``, with ``z(upper) > z(lower)``.

    Returns
    -------
    lower, upper : ndarray of float64
        C-contiguous copies.

    Raises
    ------
    ValueError
        If a shape, a value or the height order is not as expected.
    """
    lo = _as_polygon3(lower, "lower")
    up = _as_polygon3(upper, "upper")
    if not up[0, 2] > lo[0, 2]:
        raise ValueError(
            f"upper must lie strictly above lower (z2 > z1); got z1 = {lo[0, 2]!r}, z2 = {up[0, 2]!r}"
        )
    return lo, up


def oriented_pair(lower: np.ndarray, upper: np.ndarray):
    """Return ``(c1, c2, swapped)`` with ``len(c1) <= len(c2)`` (the paper's condition (i))."""
    if len(lower) <= len(upper):
        return lower, upper, False
    return upper, lower, True


# --------------------------------------------------------------------------------------------
# Step 01: the initial edge (section 3.2)
# --------------------------------------------------------------------------------------------
def initial_edge(c1: np.ndarray, c2: np.ndarray, window: int = INITIAL_EDGE_WINDOW,
                 radius: float | None = None) -> int:
    """Index on ``c2`` of the initial edge ``(c1[0], c2[j])`` (paper, section 3.2).

    The point fixed on ``C(1)`` is its start point ``p = c1[0]``; its partner is the nearest
    point of ``C(2)`` in 3D, searched within a neighbourhood of ``p`` as the paper proposes.

    Neighbourhood used: the ``2 * window + 1`` points of ``C(2)`` around its own start point
    (cyclic indices ``-window .. window``).  Contours made by contour following start at the
    same canonical place (the first point in raster order, i.e. near the upper-left corner of
    the bounding rectangle, the paper's own guide), and polygonizers keep that start point, so
    this window normally contains the nearest point.  The local result is accepted when it lies
    inside the 3D ball of radius ``radius`` around ``p`` (default ``2 * |z2 - z1|``, "larger than
    the distance between the slices") and is not at either end of the window (so it is a local
    minimum of the distance along ``C(2)``).  Otherwise, and whenever the window covers all of
    ``C(2)``, the full ``O(m)`` nearest-point search is used.  Ties go to the smallest window
    offset (offset 0 first, then +1, -1, +2, ...) or, in the full search, to the smallest index.

    Parameters
    ----------
    c1, c2 : ndarray, shapes (n, 3) and (m, 3)
        The two polygons (``c1`` the one with fewer points).
    window : int, optional
        Half-width of the index window on ``C(2)``.
    radius : float, optional
        Radius of the 3D neighbourhood ball; default ``2 * |z2 - z1|``.

    Returns
    -------
    int
        Index ``j`` in ``c2``.
    """
    if radius is None and type(window) is int and _initial_edge_arrays_ok(c1, c2):
        return int(_initial_edge_kernel(c1, c2, np.int64(window)))
    return _initial_edge_reference(c1, c2, window, radius)


def _initial_edge_arrays_ok(c1, c2) -> bool:
    """Whether :func:`_initial_edge_kernel` takes ``c1`` and ``c2`` as they are: C-contiguous
    ``(k, 3)`` float64 arrays, none empty (as :func:`validate_band_polygons` gives them)."""
    return (type(c1) is np.ndarray and type(c2) is np.ndarray and c1.dtype == np.float64
            and c2.dtype == np.float64 and c1.ndim == 2 and c2.ndim == 2 and c1.shape[1] == 3
            and c2.shape[1] == 3 and len(c1) > 0 and len(c2) > 0 and c1.flags.c_contiguous
            and c2.flags.c_contiguous)


@njit(cache=True, nogil=True)
def _initial_edge_kernel(c1, c2, window):  # pragma: no cover (compiled)
    """:func:`initial_edge` with the default radius, compiled: the same squared distances
    (``(dx * dx + dy * dy) + dz * dz``, the order in which numpy's sum over a row of three adds
    them), the same window order (offsets 0, +1, -1, +2, ...), the first of equal minima (or the
    first NaN) taken in each search as ``np.argmin`` takes it, and the same acceptance test."""
    px, py, pz = c1[0, 0], c1[0, 1], c1[0, 2]
    m = c2.shape[0]
    radius = 2.0 * abs(c2[0, 2] - pz)
    if m > 2 * window + 1:
        bd = 0.0
        bj = np.int64(0)
        bo = np.int64(0)
        for q in range(2 * window + 1):
            off = 0 if q == 0 else ((q + 1) // 2 if q % 2 == 1 else -(q // 2))
            j = off % m
            dx = c2[j, 0] - px
            dy = c2[j, 1] - py
            dz = c2[j, 2] - pz
            d2 = dx * dx + dy * dy + dz * dz
            if q == 0 or d2 < bd or (d2 != d2 and bd == bd):  # (a NaN first, as np.argmin)
                bd = d2
                bj = j
                bo = off
        if bd <= radius * radius and abs(bo) < window:
            return bj
    bd = 0.0
    bj = np.int64(0)
    for j in range(m):
        dx = c2[j, 0] - px
        dy = c2[j, 1] - py
        dz = c2[j, 2] - pz
        d2 = dx * dx + dy * dy + dz * dz
        if j == 0 or d2 < bd or (d2 != d2 and bd == bd):
            bd = d2
            bj = j
    return bj


def _initial_edge_reference(c1, c2, window=INITIAL_EDGE_WINDOW, radius=None) -> int:
    """:func:`initial_edge` in numpy (any radius; the reference of :func:`_initial_edge_kernel`)."""
    p = c1[0]
    m = len(c2)
    if radius is None:
        radius = 2.0 * abs(float(c2[0, 2]) - float(p[2]))
    if m > 2 * window + 1:
        offs = np.empty(2 * window + 1, dtype=np.int64)
        offs[0] = 0
        offs[1::2] = np.arange(1, window + 1)
        offs[2::2] = -np.arange(1, window + 1)
        idx = offs % m
        d2 = np.sum((c2[idx] - p) ** 2, axis=1)
        best = int(np.argmin(d2))
        if d2[best] <= radius * radius and abs(int(offs[best])) < window:
            return int(idx[best])
    d2 = np.sum((c2 - p) ** 2, axis=1)
    return int(np.argmin(d2))


# --------------------------------------------------------------------------------------------
# Lines 02-32: the edge sequence
# --------------------------------------------------------------------------------------------
@njit(cache=True)
def wiederhold_edges(x1, y1, x2, y2):
    """Edge sequence of the paper's triangulation algorithm (section 3.4, lines 01-32): the
    cached Python entry of :func:`_wiederhold_edges`, which the fast path calls directly."""
    return _wiederhold_edges(x1, y1, x2, y2)


@internal_kernel
def _wiederhold_edges(x1, y1, x2, y2):
    """Edge sequence of the paper's triangulation algorithm (section 3.4, lines 01-32).

    Parameters
    ----------
    x1, y1 : ndarray of float64, shape (n,)
        ``C(1)``, starting at the initial edge's point ``p(1)_1``.
    x2, y2 : ndarray of float64, shape (m,), ``m >= n``
        ``C(2)``, starting at the initial edge's point ``p(2)_1``.

    Returns
    -------
    ndarray of int64, shape (n + m, 2), or (m, 2) for the fan of ``n = 1``
        The edges ``e_0 .. e_{n+m-1}`` as 0-based index pairs ``(i, j)`` into ``C(1)``, ``C(2)``
        (the paper's 1-based ``p_i`` is row ``i - 1``; ``p(1)_{n+1}`` is ``p(1)_1``).  Each pair of
        consecutive edges, and the closing pair ``(e_{n+m-1}, e_0)``, forms one triangle.
    """
    n = len(x1)
    m = len(x2)
    E = np.empty((n + m, 2), np.int64)
    # 02  i = 1, j = 1, k = 0, e_k = (p(1)_1, p(2)_1)
    i = 1
    j = 1
    k = 0
    E[0, 0] = 0
    E[0, 1] = 0
    # 03  n = 1: one-to-many-points-triangulation (connect p(1)_1 with each point of C(2))
    if n == 1:
        for t in range(m):
            E[t, 0] = 0
            E[t, 1] = t
        return E[:m]
    line = 4
    while True:
        # paper indices are 1-based and cyclic: p(1)_{n+1} = p(1)_1
        ip = i % n          # row of p(1)_{i+1}
        ic = i - 1          # row of p(1)_i
        if line == 4:
            # 04  if x(1)_{i+1} >= x(2)_j then j = j + 1, go to 05; else go to 24
            if x1[ip] >= x2[j - 1]:
                j += 1
                line = 5
            else:
                line = 24
        elif line == 5:
            jc = j - 1      # row of p(2)_j
            jp = j - 2      # row of p(2)_{j-1}
            # 05-06  to the right
            if x1[ip] > x1[ic] and x2[jc] >= x2[jp]:
                line = 22 if x1[ip] > x2[jc] else 23
            # 08-09  upwards (y axis points down)
            elif y1[ip] < y1[ic] and y2[jc] <= y2[jp]:
                line = 22 if y1[ip] < y2[jc] else 23
            # 11-12  to the left
            elif x1[ip] < x1[ic] and x2[jc] <= x2[jp]:
                line = 22 if x1[ip] < x2[jc] else 23
            # 14-15  downwards
            elif y1[ip] > y1[ic] and y2[jc] >= y2[jp]:
                line = 22 if y1[ip] > y2[jc] else 23
            # 17  step B: advance C(2)
            else:
                line = 22
        elif line == 22:
            # 22  e_{k+1} = (p(1)_i, p(2)_j), go to 25
            E[k + 1, 0] = i - 1
            E[k + 1, 1] = j - 1
            line = 25
        elif line == 23:
            # 23  j = j - 1
            j -= 1
            line = 24
        elif line == 24:
            # 24  e_{k+1} = (p(1)_{i+1}, p(2)_j); i = i + 1
            E[k + 1, 0] = ip
            E[k + 1, 1] = j - 1
            i += 1
            line = 25
        else:  # line == 25
            if i == n and j == m:
                # 26  k = k + 1; e_{k+1} = (p(1)_{i+1}, p(2)_j); (e_{k+1}, e_0) is the last triangle
                k += 1
                E[k + 1, 0] = i % n
                E[k + 1, 1] = j - 1
                return E
            # 27  k = k + 1; j = j + 1
            k += 1
            j += 1
            if j > m:
                line = 23       # 28
            elif i < n:
                line = 5        # 30
            else:
                line = 22       # 30
    return E  # pragma: no cover  (unreachable)


# --------------------------------------------------------------------------------------------
# Edge sequence -> triangles
# --------------------------------------------------------------------------------------------
def edges_to_faces(edges: np.ndarray, n1: int, n2: int, i0: int, j0: int,
                   n_lower: int, swapped: bool) -> np.ndarray:
    """Turn a cyclic edge sequence between ``C(1)`` and ``C(2)`` into oriented faces.

    Parameters
    ----------
    edges : ndarray of int64, shape (s, 2)
        Edges ``(i, j)`` relative to the start points ``i0`` of ``C(1)`` and ``j0`` of ``C(2)``;
        consecutive edges (cyclically) differ in exactly one index, advanced by one.
    n1, n2 : int
        Numbers of points of ``C(1)`` and ``C(2)``.
    i0, j0 : int
        Start indices of the edge sequence on ``C(1)`` and ``C(2)``.
    n_lower : int
        Number of points of the lower polygon (offset of the upper one in the stacked vertices).
    swapped : bool
        True if ``C(1)`` is the upper polygon (the contours were swapped to get ``n <= m``).

    Returns
    -------
    ndarray of int64, shape (s, 3)
        One triangle per consecutive pair: ``(c1_i, c1_{i+1}, c2_j)`` when ``C(1)`` advances and
        ``(c1_i, c2_{j+1}, c2_j)`` when ``C(2)`` advances, in vertex ids of
        ``np.vstack([lower, upper])``; flipped when ``swapped`` so that lower-edge triangles read
        ``(a_i, a_{i+1}, b_j)`` and upper-edge ones ``(a_i, b_{j+1}, b_j)``.
    """
    e = np.ascontiguousarray(edges, dtype=np.int64)
    return _edges_to_faces(e, n1, n2, i0, j0, n_lower, swapped)


@njit(cache=True)
def _edges_to_faces(e, n1, n2, i0, j0, n_lower, swapped):
    return _edges_to_faces_kernel(e, n1, n2, i0, j0, n_lower, swapped)


@internal_kernel
def _edges_to_faces_kernel(e, n1, n2, i0, j0, n_lower, swapped):
    s = len(e)
    off1 = n_lower if swapped else 0
    off2 = 0 if swapped else n_lower
    faces = np.empty((s, 3), np.int64)
    for t in range(s):
        u = (t + 1) % s
        g1 = (e[t, 0] + i0) % n1
        g2 = (e[t, 1] + j0) % n2
        h1 = (e[u, 0] + i0) % n1
        h2 = (e[u, 1] + j0) % n2
        # C(1) advanced (compared modulo n1: sequences may write i = n1 for i = 0)
        third = h1 + off1 if g1 != h1 else h2 + off2
        faces[t, 0] = g1 + off1
        if swapped:         # flip back: C(1) is the upper polygon
            faces[t, 1] = g2 + off2
            faces[t, 2] = third
        else:
            faces[t, 1] = third
            faces[t, 2] = g2 + off2
    return faces


def _pole_pair_faces() -> np.ndarray:
    return np.empty((0, 3), dtype=np.int64)


def triangulate_band_wiederhold(lower, upper, *, window: int = INITIAL_EDGE_WINDOW,
                                radius: float | None = None) -> np.ndarray:
    """Triangulate the band between two consecutive polygons (Wiederhold & Villafuerte 2009).

    Parameters
    ----------
    lower : array_like, shape (n, 3)
        Closed polygon at height ``z1`` (``(x, y)`` in the first two columns).
    upper : array_like, shape (m, 3)
        Closed polygon at height ``z2 > z1``, same orientation convention as ``lower``.
    window, radius : optional
        Neighbourhood of the initial-edge search, see :func:`initial_edge`.

    Returns
    -------
    faces : ndarray of int64, shape (n + m, 3)
        Triangles indexing ``np.vstack([lower, upper])``; every polygon edge is used exactly
        once.  A single point against a polygon gives the one-to-many fan (``max(n, m)`` faces,
        the point's own "edge" being degenerate); two single points give no faces.

    Examples
    --------
    >>> import numpy as np
    >>> lower = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)
    >>> upper = lower + [0, 0, 1]
    >>> triangulate_band_wiederhold(lower, upper).shape
    (8, 3)
    """
    lo, up = validate_band_polygons(lower, upper)
    if len(lo) == 1 and len(up) == 1:
        return _pole_pair_faces()
    c1, c2, swapped = oriented_pair(lo, up)
    j0 = initial_edge(c1, c2, window=window, radius=radius)
    r2 = np.concatenate((c2[j0:], c2[:j0]))  # (np.roll(c2, -j0, axis=0), cheaper)
    edges = wiederhold_edges(
        np.ascontiguousarray(c1[:, 0]), np.ascontiguousarray(c1[:, 1]),
        np.ascontiguousarray(r2[:, 0]), np.ascontiguousarray(r2[:, 1]),
    )
    # for n = 1 (one-to-many fan) the point's own "edge" (p, p) carries no triangle
    return edges_to_faces(edges, len(c1), len(c2), 0, j0, len(lo), swapped)
