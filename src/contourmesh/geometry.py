"""Plane geometry shared by the meshers: even-odd point tests and fills, ring areas, grid maps.

Rings are ``(k, 2)`` arrays of ``(x, y)`` points, closed implicitly.  Nothing here knows about
sections, stacks or meshes.
"""

from __future__ import annotations

import numpy as np

from ._kernels import njit

__all__ = ["points_in_rings", "shoelace_area", "grid_to_xy", "slice_gap", "successor", "predecessor",
           "distinct_rows"]


def grid_to_xy(ox, oy, dx, dy):
    """Maps from pixel-centre and pixel-corner grid coordinates to physical ``(x, y)``.

    Pixel ``(i, j)`` has its centre at ``(ox + i dx, oy + j dy)``; corner ``(i, j)`` is its
    lower-left corner, half a pixel below and left of the centre.
    """
    # (columns written into one array: np.c_ and np.stack are slow on small arrays)
    def to_center(p):
        p = np.asarray(p, dtype=np.float64)
        out = np.empty((len(p), 2))
        out[:, 0] = ox + p[:, 0] * dx
        out[:, 1] = oy + p[:, 1] * dy
        return out

    def to_corner(p):
        p = np.asarray(p, dtype=np.float64)
        out = np.empty((len(p), 2))
        out[:, 0] = ox + (p[:, 0] - 0.5) * dx
        out[:, 1] = oy + (p[:, 1] - 0.5) * dy
        return out

    return to_center, to_corner


@njit(cache=True)
def _fill_evenodd(xs, ys, starts, x0, y0, pixel, out):
    """Scanline even-odd fill of one slice.

    For every pixel row ``j`` (centre height ``yc = y0 + j * pixel``) collect the abscissae where
    the ring edges cross the line ``y = yc`` (an edge ``a -> b`` crosses when exactly one of its
    ends has ``y <= yc``: the half-open rule, so a vertex on the line counts once), sort them, and
    fill the pixels whose centres ``xc`` satisfy ``c[2m] <= xc < c[2m + 1]``.
    """
    ny, nx = out.shape
    nring = len(starts) - 1
    ncross_max = len(xs)
    cross = np.empty(ncross_max, dtype=np.float64)
    for j in range(ny):
        yc = y0 + j * pixel
        n = 0
        for r in range(nring):
            s, e = starts[r], starts[r + 1]
            k = e - s
            for q in range(k):
                a = s + q
                b = s + (q + 1) % k
                ya, yb = ys[a], ys[b]
                if (ya <= yc) != (yb <= yc):
                    cross[n] = xs[a] + (yc - ya) * (xs[b] - xs[a]) / (yb - ya)
                    n += 1
        if n < 2:
            continue
        c = np.sort(cross[:n])
        for m in range(0, n - 1, 2):
            i0 = int(np.ceil((c[m] - x0) / pixel))
            i1 = int(np.ceil((c[m + 1] - x0) / pixel)) - 1
            if i0 < 0:
                i0 = 0
            if i1 > nx - 1:
                i1 = nx - 1
            for i in range(i0, i1 + 1):
                out[j, i] = True


@njit(cache=True)
def _points_in_ring(px, py, rx, ry):
    """Even-odd (crossing number) test of points against one closed ring, half-open rule."""
    n = len(px)
    k = len(rx)
    inside = np.zeros(n, dtype=np.bool_)
    for p in range(n):
        x, y = px[p], py[p]
        odd = False
        for q in range(k):
            a = q
            b = (q + 1) % k
            if (ry[a] <= y) != (ry[b] <= y):
                xc = rx[a] + (y - ry[a]) * (rx[b] - rx[a]) / (ry[b] - ry[a])
                if x < xc:
                    odd = not odd
        inside[p] = odd
    return inside


def points_in_rings(points, ring) -> np.ndarray:
    """Which of ``points`` ``(n, 2)`` lie inside the closed ``ring`` ``(k, 2)`` (even-odd rule).

    Parameters
    ----------
    points : array_like, shape (n, 2)
    ring : array_like, shape (k, 2)
        Closed implicitly; either winding.

    Returns
    -------
    numpy.ndarray of bool, shape (n,)
    """
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    r = np.ascontiguousarray(ring, dtype=np.float64).reshape(-1, 2)
    if len(r) < 3:
        return np.zeros(len(p), dtype=bool)
    return _points_in_ring(p[:, 0].copy(), p[:, 1].copy(), r[:, 0].copy(), r[:, 1].copy())


def successor(a) -> np.ndarray:
    """``np.roll(a, -1, axis=0)``: each row's successor round the ring (a new contiguous array;
    ``np.roll`` costs ten times more on the small arrays of the meshers)."""
    return np.concatenate((a[1:], a[:1]))


def predecessor(a) -> np.ndarray:
    """``np.roll(a, 1, axis=0)``: each row's predecessor round the ring (a new contiguous array)."""
    return np.concatenate((a[-1:], a[:-1]))


def shoelace_area(points: np.ndarray) -> float:
    """Signed area of a closed polygon given by ``(k, 2)`` points (positive = our outer orientation)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 3:
        return 0.0
    x, y = p[:, 0], p[:, 1]
    # the same two dot products of the same arrays as with np.roll (so the same rounding)
    return 0.5 * float(np.dot(x, successor(y)) - np.dot(successor(x), y))


@njit(cache=True, nogil=True)
def _distinct_rows(p):
    n = p.shape[0]
    if n < 2:
        return n
    # rows in (x, y) order: a stable sort by y, then a stable sort by x
    o = np.argsort(p[:, 1], kind="mergesort")
    xs = np.empty(n)
    for i in range(n):
        xs[i] = p[o[i], 0]
    o = o[np.argsort(xs, kind="mergesort")]
    count = 1
    for i in range(1, n):
        a, b = o[i - 1], o[i]
        if p[a, 0] != p[b, 0] or p[a, 1] != p[b, 1]:
            count += 1
    return count


def distinct_rows(points) -> int:
    """Number of distinct points of a ``(k, 2)`` array (``len(np.unique(points, axis=0))``: points
    are equal when both coordinates compare equal), compiled."""
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    return int(_distinct_rows(p))


def slice_gap(zs, k: int, up: bool) -> float:
    """The distance from slice ``k`` to its neighbour above (``up``) or below; at an end, the
    distance to the neighbour on the other side (1 for a single slice).  Half of it is where
    ``caps="half"`` puts an end cap."""
    nz = len(zs)
    if up:
        return zs[k + 1] - zs[k] if k + 1 < nz else (zs[k] - zs[k - 1] if k > 0 else 1.0)
    return zs[k] - zs[k - 1] if k > 0 else (zs[k + 1] - zs[k] if k + 1 < nz else 1.0)


@njit(cache=True, nogil=True)
def _row_deepest(f, y, w, v, z):
    """``(d2, y, x)``: the largest squared Euclidean distance to the background in row ``y`` and its
    first pixel, from the column distances ``f`` (not squared) by the lower envelope of parabolas
    (Felzenszwalb & Huttenlocher); ``v, z``: work arrays of ``w`` and ``w + 1``."""
    k = 0
    v[0] = 0
    z[0] = -np.inf
    z[1] = np.inf
    for q in range(1, w):
        fq = f[y, q] * f[y, q]
        while True:
            p = v[k]
            s = ((fq + q * q) - (f[y, p] * f[y, p] + p * p)) / (2.0 * (q - p))
            if s <= z[k] and k > 0:
                k -= 1
                continue
            if s <= z[k]:  # k == 0: q's parabola is lower everywhere to the right of -inf
                v[0] = q
                z[1] = np.inf
                break
            k += 1
            v[k] = q
            z[k] = s
            z[k + 1] = np.inf
            break
    best, bi = -1, 0
    k = 0
    for q in range(w):
        while z[k + 1] < q:
            k += 1
        p = v[k]
        d2 = (q - p) * (q - p) + f[y, p] * f[y, p]
        if d2 > best:
            best, bi = d2, q
    return best, y, bi


@njit(cache=True, nogil=True)
def _deepest(m):
    """Index ``(j, i)`` into ``m`` padded by one background pixel of the largest squared Euclidean
    distance to the background (the first in raster order among equals): columns by two scans,
    rows by the lower envelope of parabolas (:func:`_row_deepest`), all in integers.

    A pixel's distance is at most its distance to the background along its column or along its
    row, so each row's largest squared distance is at most the largest ``min(column, row)^2`` of its
    pixels; the rows are taken in decreasing order of that bound until it falls below the best
    distance found (those rows hold no pixel as deep), and among the rows that reach the best the
    first wins: the pixel of the full raster scan."""
    h0, w0 = m.shape
    h, w = h0 + 2, w0 + 2
    f = np.zeros((h, w), np.int64)  # distance along the column to the nearest background pixel
    run = np.zeros(w0, np.int64)
    for y in range(h0):
        for x in range(w0):
            run[x] = run[x] + 1 if m[y, x] else 0
            f[y + 1, x + 1] = run[x]
    run[:] = 0
    for y in range(h0 - 1, -1, -1):
        for x in range(w0):
            run[x] = run[x] + 1 if m[y, x] else 0
            if run[x] < f[y + 1, x + 1]:
                f[y + 1, x + 1] = run[x]
    bound = np.zeros(h, np.int64)  # per row: the largest min(column, row distance)^2 of its pixels
    left = np.empty(w, np.int64)
    for y in range(1, h - 1):
        r = 0
        for q in range(w):
            r = r + 1 if f[y, q] > 0 else 0
            left[q] = r
        r = 0
        top = 0
        for q in range(w - 1, -1, -1):
            r = r + 1 if f[y, q] > 0 else 0
            top = max(top, min(min(left[q], r), f[y, q]))
        bound[y] = top * top
    v = np.empty(w, np.int64)
    z = np.empty(w + 1)
    order = np.argsort(-bound, kind="mergesort")
    best, bj, bi = -1, 0, 0
    for t in range(h):
        if bound[order[t]] < best:
            break
        d2, j, i = _row_deepest(f, order[t], w, v, z)
        if d2 > best or (d2 == best and j < bj):
            best, bj, bi = d2, j, i
    return bj, bi


def deepest_pixel(mask) -> tuple[int, int]:
    """``np.unravel_index(np.argmax(scipy.ndimage.distance_transform_edt(np.pad(mask, 1))), ...)``:
    the pixel of a 2D mask, padded by one background pixel all round, furthest from the background
    (the first in raster order among equals), in compiled integer arithmetic."""
    m = np.ascontiguousarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2D array indexed [y, x]; got shape {m.shape}")
    j, i = _deepest(m)
    return int(j), int(i)
