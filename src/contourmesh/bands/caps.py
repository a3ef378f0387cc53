"""Flat caps: triangulate a planar polygon with holes (ear clipping, via ``mapbox_earcut``).

An end section whose polygon encloses area is closed by a flat cap in its own plane; the
cap's triangles use the polygon's own vertices, so the cap's boundary is exactly the polygon
and the band + caps mesh is closed.  The ear clipping is mapbox's earcut (Held's FIST-style
ear clipping with hole bridging), ``mapbox_earcut.triangulate_float64(vertices, ring_ends)``.

Runs of (nearly) collinear points, common in planning-system exports (many points along a
straight edge), are taken out of each ring before ear clipping and put back afterwards by
splitting every triangle edge that spans a run into a fan through the run's points: ear clipping
alone makes zero-area slivers along such runs when round-off puts a point a hair off the line,
and those slivers cannot be repaired into a consistent cap.
"""

from __future__ import annotations

import math

import numpy as np

from .._kernels import njit

__all__ = ["cap_faces", "CapError"]


from ..errors import CapError  # noqa: F401  (re-exported: raised here)


def _as_ring(poly, name: str) -> np.ndarray:
    p = np.asarray(poly)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ValueError(f"{name} must be a (k, 2) or (k, 3) array of points; got shape {p.shape}")
    if p.dtype != np.float64 and (not np.issubdtype(p.dtype, np.number)
                                  or np.issubdtype(p.dtype, np.complexfloating)):
        raise ValueError(f"{name} must hold real numbers; got dtype {p.dtype}")
    p = np.ascontiguousarray(p[:, :2], dtype=np.float64)
    if not np.isfinite(p).all():
        raise ValueError(f"{name} must contain only finite coordinates; found NaN or inf")
    return p


def _signed_area(p: np.ndarray) -> float:
    if len(p) < 3:
        return 0.0
    x, y = p[:, 0], p[:, 1]
    # (np.roll(a, -1) as one concatenation: the same contiguous copy, at a fraction of the cost)
    return 0.5 * float(np.dot(x, np.concatenate([y[1:], y[:1]])) - np.dot(np.concatenate([x[1:], x[:1]]), y))


#: A point is on the straight line between its neighbours when its distance from their chord is at
#: most this fraction of the chord's length (and it projects strictly inside the chord).
COLLINEAR_TOL = 1e-9


def _straight(ax, ay, vx, vy, bx, by, tol=COLLINEAR_TOL) -> bool:
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    if L2 == 0.0:
        return False
    ex, ey = vx - ax, vy - ay
    t = (ex * dx + ey * dy) / L2
    return 0.0 < t < 1.0 and abs(ex * dy - ey * dx) <= tol * L2


def collinear_runs(ring: np.ndarray, tol: float = COLLINEAR_TOL) -> np.ndarray:
    """Boolean mask of the ring's points to keep: False for a point lying strictly inside the straight
    segment from the last kept point to the next point (a run of collinear points keeps its ends).

    A point that doubles back (a zero-width spike) is not straight and is kept: that ring really
    touches itself.

    Compiled (:func:`_collinear_kernel`, the same arithmetic step by step) for an ``(n, 2)`` ring;
    :func:`_collinear_runs_reference` is the numpy form it is tested against.
    """
    p = np.asarray(ring, dtype=np.float64)
    if p.ndim == 2 and p.shape[1] == 2:
        return _collinear_kernel(np.ascontiguousarray(p), float(tol))
    return _collinear_runs_reference(p, tol)


@njit(cache=True, nogil=True)
def _collinear_kernel(p, tol):  # pragma: no cover (compiled)
    """:func:`collinear_runs` of an ``(n, 2)`` float64 ring: each point's test against its two
    neighbours (``local``), then the walk from the first corner, as the reference does them."""
    n = p.shape[0]
    keep = np.ones(n, np.bool_)
    if n < 4:
        return keep
    local = np.zeros(n, np.bool_)
    s0 = -1
    any_local = False
    for i in range(n):
        a = (i - 1) % n
        b = (i + 1) % n
        d0, d1 = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
        L2 = d0 * d0 + d1 * d1
        e0, e1 = p[i, 0] - p[a, 0], p[i, 1] - p[a, 1]
        if L2 > 0:
            t = (e0 * d0 + e1 * d1) / L2
            local[i] = t > 0 and t < 1 and abs(e0 * d1 - e1 * d0) <= tol * L2
        if local[i]:
            any_local = True
        elif s0 < 0:
            s0 = i
    if not any_local or s0 < 0:
        return keep
    prev = s0
    for step in range(1, n):
        j = (s0 + step) % n
        nxt = (j + 1) % n
        straight = False
        if local[j]:
            dx, dy = p[nxt, 0] - p[prev, 0], p[nxt, 1] - p[prev, 1]
            L2 = dx * dx + dy * dy
            if L2 != 0.0:
                ex, ey = p[j, 0] - p[prev, 0], p[j, 1] - p[prev, 1]
                t = (ex * dx + ey * dy) / L2
                straight = 0.0 < t < 1.0 and abs(ex * dy - ey * dx) <= tol * L2
        if straight:
            keep[j] = False
        else:
            prev = j
    kept = 0
    for i in range(n):
        kept += keep[i]
    if kept < 3:
        return np.ones(n, np.bool_)
    return keep


def _collinear_runs_reference(ring: np.ndarray, tol: float = COLLINEAR_TOL) -> np.ndarray:
    """:func:`collinear_runs` in numpy and Python (the reference of the compiled kernel)."""
    p = np.asarray(ring, dtype=np.float64)
    n = len(p)
    keep = np.ones(n, dtype=bool)
    if n < 4:
        return keep
    a, b = np.roll(p, 1, axis=0), np.roll(p, -1, axis=0)
    d = b - a
    L2 = (d * d).sum(axis=1)
    e = p - a
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (e * d).sum(axis=1) / L2
    cross = np.abs(e[:, 0] * d[:, 1] - e[:, 1] * d[:, 0])
    local = (L2 > 0) & (t > 0) & (t < 1) & (cross <= tol * L2)
    if not local.any():
        return keep
    corners = np.flatnonzero(~local)
    if len(corners) == 0:  # no corner at all: nothing to anchor a run on (encloses no area)
        return keep
    s0 = int(corners[0])
    xs, ys = p[:, 0].tolist(), p[:, 1].tolist()
    prev = s0
    for step in range(1, n):
        j = (s0 + step) % n
        nxt = (j + 1) % n
        if local[j] and _straight(xs[prev], ys[prev], xs[j], ys[j], xs[nxt], ys[nxt], tol):
            keep[j] = False
        else:
            prev = j
    if keep.sum() < 3:
        return np.ones(n, dtype=bool)
    return keep


def _reinsert_runs(tris: np.ndarray, runs: dict) -> np.ndarray:
    """Split every triangle edge ``(a, b)`` that spans a collinear run into a fan through the run's points."""
    out = []
    for t in tris.tolist():
        pending = [tuple(t)]
        while pending:
            a, b, c = pending.pop()
            for (p, q, r) in ((a, b, c), (b, c, a), (c, a, b)):
                inner = runs.get((p, q))
                if inner:
                    path = [p, *inner, q]
                    pending += [(path[i], path[i + 1], r) for i in range(len(path) - 1)]
                    break
            else:
                out.append((a, b, c))
    return np.asarray(out, dtype=np.int64).reshape(-1, 3)


def _drop_flat_triangles(verts: np.ndarray, tri: np.ndarray, tol: float = COLLINEAR_TOL) -> np.ndarray:
    """The triangles whose corners are not on one straight line (to ``tol`` of their longest edge).
    Compiled for float64 ``(n, 2)`` points and int64 triangles (:func:`_flat_kernel`, the arithmetic
    of :func:`_drop_flat_triangles_reference`)."""
    if (verts.dtype == np.float64 and verts.ndim == 2 and verts.shape[1] == 2 and tri.dtype == np.int64
            and tri.ndim == 2 and tri.shape[1] == 3 and len(tri) and tri.min() >= 0 and tri.max() < len(verts)):
        return tri[_flat_kernel(np.ascontiguousarray(verts), np.ascontiguousarray(tri), float(tol))]
    return _drop_flat_triangles_reference(verts, tri, tol)


@njit(cache=True, nogil=True)
def _flat_kernel(v, tri, tol):  # pragma: no cover (compiled)
    """Per triangle: whether :func:`_drop_flat_triangles_reference` keeps it (its arithmetic)."""
    out = np.empty(tri.shape[0], np.bool_)
    for t in range(tri.shape[0]):
        p0, p1 = v[tri[t, 0], 0], v[tri[t, 0], 1]
        q0, q1 = v[tri[t, 1], 0], v[tri[t, 1], 1]
        r0, r1 = v[tri[t, 2], 0], v[tri[t, 2], 1]
        s = abs((q0 - p0) * (r1 - p1) - (q1 - p1) * (r0 - p0))
        a0, a1 = q0 - p0, q1 - p1
        b0, b1 = r0 - q0, r1 - q1
        c0, c1 = p0 - r0, p1 - r1
        la = a0 * a0 + a1 * a1
        lb = b0 * b0 + b1 * b1
        lc = c0 * c0 + c1 * c1
        m = la if la >= lb else lb
        m = m if m >= lc else lc
        out[t] = s > tol * m
    return out


def _drop_flat_triangles_reference(verts: np.ndarray, tri: np.ndarray, tol: float = COLLINEAR_TOL) -> np.ndarray:
    """:func:`_drop_flat_triangles` in numpy (the reference of the compiled kernel)."""
    p, q, r = verts[tri[:, 0]], verts[tri[:, 1]], verts[tri[:, 2]]
    s = np.abs((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))
    longest = np.maximum.reduce([((q - p) ** 2).sum(1), ((r - q) ** 2).sum(1), ((p - r) ** 2).sum(1)])
    return tri[s > tol * longest]


def _on_segment(vertices, cand, a, b):
    """Candidates lying strictly inside segment ab (exactly collinear up to round-off)."""
    p, q = vertices[a], vertices[b]
    d = q - p
    L2 = float(d @ d)
    if L2 == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    e = vertices[cand] - p
    t = (e @ d) / L2
    off = e - t[:, None] * d
    dist = np.sqrt((off * off).sum(axis=1))
    ok = (t > 1e-12) & (t < 1 - 1e-12) & (dist <= 1e-9 * math.sqrt(L2))
    return cand[ok], t[ok]


@njit(cache=True)
def _busy_edges(vertices, e, cand):  # pragma: no cover (compiled)
    """For each edge ``e[i]``: whether a candidate point may lie strictly inside it (a slightly wider
    net than :func:`_on_segment`'s test, so round-off can only send an edge to the exact test)."""
    out = np.zeros(len(e), dtype=np.bool_)
    for i in range(len(e)):
        px, py = vertices[e[i, 0], 0], vertices[e[i, 0], 1]
        dx, dy = vertices[e[i, 1], 0] - px, vertices[e[i, 1], 1] - py
        L2 = dx * dx + dy * dy
        if L2 == 0.0:
            out[i] = True
            continue
        tol = 2e-9 * math.sqrt(L2)
        xlo, xhi = min(px, px + dx) - tol, max(px, px + dx) + tol
        ylo, yhi = min(py, py + dy) - tol, max(py, py + dy) + tol
        for j in range(len(cand)):
            cx, cy = vertices[cand[j], 0], vertices[cand[j], 1]
            if cx < xlo or cx > xhi or cy < ylo or cy > yhi:
                continue
            wx, wy = cx - px, cy - py
            t = (wx * dx + wy * dy) / L2
            if t <= 1e-13 or t >= 1 - 1e-13:
                continue
            ox, oy = wx - t * dx, wy - t * dy
            if math.sqrt(ox * ox + oy * oy) <= tol:
                out[i] = True
                break
    return out


def _edges_without_points(vertices, tris, cand) -> set:
    """The triangles' edges that no candidate point lies on, found for all edges at once, so that the
    splitting loop only runs the exact test on the few others."""
    if len(tris) == 0:
        return set()
    e = np.ascontiguousarray(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]))
    busy = _busy_edges(np.ascontiguousarray(vertices, dtype=np.float64), e, np.ascontiguousarray(cand))
    return set(map(tuple, e[~busy].tolist()))


@njit(cache=True, nogil=True)
def _closes_up(tri, boundary):  # pragma: no cover (compiled)
    """:func:`split_t_junctions`' two tests of its result for triangles none of whose edges is split:
    no directed edge twice, and each edge's opposite among the edges or the edge a loop edge
    (``boundary``'s rows).  Edges as integers ``p * n + q``, sorted, looked up by bisection."""
    n = 1
    for t in range(tri.shape[0]):
        for k in range(3):
            n = max(n, tri[t, k] + 1)
    for t in range(boundary.shape[0]):
        n = max(n, boundary[t, 0] + 1, boundary[t, 1] + 1)
    m = tri.shape[0]
    key = np.empty(3 * m, np.int64)
    for t in range(m):
        for k in range(3):
            key[3 * t + k] = tri[t, k] * n + tri[t, (k + 1) % 3]
    key.sort()
    for i in range(1, key.shape[0]):
        if key[i] == key[i - 1]:
            return False
    loop = np.empty(boundary.shape[0], np.int64)
    for i in range(boundary.shape[0]):
        loop[i] = boundary[i, 0] * n + boundary[i, 1]
    loop.sort()
    for i in range(key.shape[0]):
        p, q = key[i] // n, key[i] % n
        rev = q * n + p
        j = np.searchsorted(key, rev)
        if j < key.shape[0] and key[j] == rev:
            continue
        j = np.searchsorted(loop, key[i])
        if j < loop.shape[0] and loop[j] == key[i]:
            continue
        return False
    return True


def split_t_junctions(vertices, tris, boundary):
    """Split triangles whose edges pass through other boundary vertices (T-junctions).

    Ear clipping drops loop vertices lying on the straight line between their neighbours, and
    with hole bridges on grid-aligned data an edge may even pass through a vertex of another
    loop.  Every triangle ``(a, b, c)`` whose edge ``ab`` contains loop vertices ``v1 .. vk``
    (in order) is replaced by the fan ``(a, v1, c), ..., (vk, b, c)``.  Returns None unless
    afterwards every loop edge is used once and every other edge twice in opposite directions.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    boundary = np.asarray(boundary, dtype=np.int64).reshape(-1, 2)
    cand = np.unique(boundary)
    tri_arr = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    if len(tri_arr) and tri_arr.min() >= 0 and (not len(boundary) or boundary.min() >= 0):
        e = np.ascontiguousarray(np.concatenate([tri_arr[:, [0, 1]], tri_arr[:, [1, 2]], tri_arr[:, [2, 0]]]))
        busy = _busy_edges(np.ascontiguousarray(vertices, dtype=np.float64), e, np.ascontiguousarray(cand))
        if not busy.any():
            # no edge to split (the usual cap): the triangles as they are, if they close up (the
            # loop below would keep each one and then run these two tests on their edge sets)
            return tri_arr.copy() if _closes_up(tri_arr, np.ascontiguousarray(boundary)) else None
        clean = set(map(tuple, e[~busy].tolist()))
    else:
        clean = _edges_without_points(vertices, tri_arr, cand)
    loop_edges = set(map(tuple, boundary.tolist()))
    out = []
    # every split strictly shortens an edge, so a valid triangulation needs few; degenerate
    # triangles along a collinear run can re-split each other for ever: give up (None) instead
    budget = 20 * (len(tris) + len(cand)) + 1000
    for t in np.asarray(tris, dtype=np.int64).tolist():
        pending = [tuple(t)]
        while pending:
            budget -= 1
            if budget < 0:
                return None
            a, b, c = pending.pop()
            for (p, q, r) in ((a, b, c), (b, c, a), (c, a, b)):
                if (p, q) in loop_edges or (p, q) in clean:
                    continue
                inside, tt = _on_segment(vertices, cand, p, q)
                if len(inside):
                    path = [p] + inside[np.argsort(tt)].tolist() + [q]
                    pending += [(path[i], path[i + 1], r) for i in range(len(path) - 1)]
                    break
            else:
                out.append((a, b, c))
    edges = {(a, b) for a, b, c in out} | {(b, c) for a, b, c in out} | {(c, a) for a, b, c in out}
    if len(edges) != 3 * len(out):
        return None
    if any((q, p) not in edges and (p, q) not in loop_edges for p, q in edges):
        return None
    return np.asarray(out, dtype=np.int64).reshape(-1, 3)


def _cap_rings(polygon_xy, holes_xy):
    """:func:`cap_faces`' arguments checked: the outer ring and the holes, ``(k, 2)`` float64 each."""
    outer = _as_ring(polygon_xy, "polygon_xy")
    if isinstance(holes_xy, np.ndarray) and holes_xy.ndim == 2:
        raise ValueError("holes_xy must be a sequence of (h, 2) arrays, not a single array; "
                         "wrap a single hole in a list")
    return outer, [_as_ring(h, f"holes_xy[{k}]") for k, h in enumerate(holes_xy)]


def cap_faces(polygon_xy, holes_xy=(), upward: bool = True) -> np.ndarray:
    """Triangulate a flat polygon with holes into a cap.

    Parameters
    ----------
    polygon_xy : array_like, shape (k, 2) or (k, 3)
        Outer boundary, closed implicitly (only the first two columns are used).  Either
        orientation is accepted.
    holes_xy : sequence of array_like, optional
        Hole boundaries, each ``(h, 2)`` or ``(h, 3)``.  A hole with fewer than three points or
        zero area is ignored (its vertices keep their index range).
    upward : bool, optional
        Orient the triangles so that their normals point to ``+z`` (counter-clockwise in raw
        ``(x, y)``, i.e. positive shoelace area) if True, to ``-z`` otherwise.

    Returns
    -------
    faces : ndarray of int64, shape (t, 3)
        Triangles indexing ``np.vstack([polygon] + list(holes))``.  Empty ``(0, 3)`` if the outer
        polygon has fewer than three points or zero area.

    Examples
    --------
    >>> cap_faces([[0, 0], [2, 0], [2, 2], [0, 2]]).shape
    (2, 3)
    """
    outer, holes = _cap_rings(polygon_xy, holes_xy)
    empty = np.empty((0, 3), dtype=np.int64)
    if len(outer) < 3 or _signed_area(outer) == 0.0:
        return empty
    # (the steps of the tests' step-by-step reference with fewer numpy calls: most caps are a few points, where
    # the calls, not the arithmetic, cost; the checks after ear clipping in one compiled pass)
    if holes:
        used = [h for h in holes if len(h) >= 3 and _signed_area(h) != 0.0]
        rings = [outer] + used
        if len(used) < len(holes):  # global index of each vertex handed to earcut
            offsets = np.cumsum([0] + [len(r) for r in [outer] + holes])[:-1]
            glob = np.concatenate([np.arange(len(outer))] + [offsets[k + 1] + np.arange(len(h)) for k, h in
                                                             enumerate(holes) if len(h) >= 3 and _signed_area(h) != 0.0])
        else:
            glob = None  # (all rings used: the identity)
        verts = np.ascontiguousarray(np.vstack(rings))
        ends = np.cumsum([len(r) for r in rings])
    else:
        rings, glob, verts = [outer], None, outer
        ends = np.array([len(outer)])
    ends = ends.astype(np.int64)
    # take collinear runs out of each ring (kept: the runs' ends), ear-clip the rest, put them back
    kept_idx, runs, kept_ends, a = [], {}, [], 0
    for b, r in zip(ends.tolist(), rings):
        keep = collinear_runs(r)
        if keep.all():
            kept_idx.append(np.arange(a, b))
            kept_ends.append(b - a)
        else:
            k = a + np.flatnonzero(keep)
            kept_idx.append(k)
            kept_ends.append(len(k))
            _note_runs(keep, a, runs)
        a = b
    if runs:
        kept_idx = np.concatenate(kept_idx)
        tri = np.asarray(_earcut().triangulate_float64(np.ascontiguousarray(verts[kept_idx]),
                                                       np.cumsum(kept_ends).astype(np.uint32)),
                         dtype=np.int64).reshape(-1, 3)
        if len(tri) == 0:
            return empty
        tri = _reinsert_runs(kept_idx[tri], runs)
    else:
        tri = np.asarray(_earcut().triangulate_float64(verts, ends.astype(np.uint32)),
                         dtype=np.int64).reshape(-1, 3)
        if len(tri) == 0:
            return empty
    # flat ears dropped, then the T-junction test, the closing test and each triangle's signed area
    status, tri, s = _cap_tail(verts, np.ascontiguousarray(tri), ends, COLLINEAR_TOL)
    if status == 1:  # an edge with a ring vertex on it: the splitting loop
        starts = np.concatenate([[0], ends[:-1]])
        nxt = np.arange(1, len(verts) + 1, dtype=np.int64)
        nxt[ends - 1] = starts
        boundary = np.stack([np.arange(len(verts), dtype=np.int64), nxt], axis=1)
        tri = split_t_junctions(verts, tri, np.concatenate([boundary, boundary[:, ::-1]]))
        if tri is None:
            raise CapError("cannot triangulate the cap: its rings cross or touch each other")
        p, q, r = verts[tri[:, 0]], verts[tri[:, 1]], verts[tri[:, 2]]
        s = (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])
    elif status == 2:
        raise CapError("cannot triangulate the cap: its rings cross or touch each other")
    total = float(s.sum())
    if (total < 0) if upward else (total > 0):
        tri = tri[:, [0, 2, 1]]
    return np.ascontiguousarray(tri if glob is None else glob[tri])


def _note_runs(keep, a, runs) -> None:
    """Record in ``runs`` the collinear runs a ring (its points from ``a``, ``keep`` from
    :func:`collinear_runs`, some False) loses: ``runs[(p, q)]`` the points dropped between kept
    points ``p`` and ``q``, both ways round."""
    n = len(keep)
    first = int(np.flatnonzero(keep)[0])
    order = (first + np.arange(n)) % n  # ring order starting at a kept point
    anchor, inner = a + first, []
    for j in order[1:].tolist() + [first]:
        if keep[j]:
            if inner:
                runs[(anchor, a + j)] = inner
                runs[(a + j, anchor)] = inner[::-1]
            anchor, inner = a + j, []
        else:
            inner.append(a + j)


def _earcut():
    import mapbox_earcut

    return mapbox_earcut


@njit(cache=True, nogil=True)
def _cap_tail(verts, tri, ends, tol):  # pragma: no cover (compiled)
    """The step-by-step cap's checks after ear clipping (its reference is in the tests), for rings ending at ``ends`` in
    ``verts``: the triangles that are not flat (:func:`_flat_kernel`), then, where no edge may hold a
    ring vertex (:func:`_busy_edges`, every vertex a candidate), :func:`split_t_junctions`' closing
    test (:func:`_closes_up`) and each triangle's signed area (the reference's arithmetic).
    Returns ``(status, tri, s)``: 0 with the areas ``s``, 1 where an edge must be split (``tri``
    the triangles to split), 2 where the triangles do not close up."""
    keep = _flat_kernel(verts, tri, tol)
    m = 0
    for t in range(len(tri)):
        m += keep[t]
    out = np.empty((m, 3), np.int64)
    m = 0
    for t in range(len(tri)):
        if keep[t]:
            out[m, 0], out[m, 1], out[m, 2] = tri[t, 0], tri[t, 1], tri[t, 2]
            m += 1
    s = np.empty(m)
    if m == 0:
        return 0, out, s
    n = len(verts)
    e = np.empty((3 * m, 2), np.int64)
    for t in range(m):
        for k in range(3):
            e[k * m + t, 0] = out[t, k]
            e[k * m + t, 1] = out[t, (k + 1) % 3]
    cand = np.empty(n, np.int64)
    for i in range(n):
        cand[i] = i
    busy = _busy_edges(verts, e, cand)
    for i in range(len(busy)):
        if busy[i]:
            return 1, out, s
    boundary = np.empty((2 * n, 2), np.int64)
    a = 0
    for r in range(len(ends)):
        b = ends[r]
        for i in range(a, b):
            j = i + 1 if i + 1 < b else a
            boundary[i, 0], boundary[i, 1] = i, j
            boundary[n + i, 0], boundary[n + i, 1] = j, i
        a = b
    if not _closes_up(out, boundary):
        return 2, out, s
    for t in range(m):
        p0, p1 = verts[out[t, 0], 0], verts[out[t, 0], 1]
        q0, q1 = verts[out[t, 1], 0], verts[out[t, 1], 1]
        r0, r1 = verts[out[t, 2], 0], verts[out[t, 2], 1]
        s[t] = (q0 - p0) * (r1 - p1) - (q1 - p1) * (r0 - p0)
    return 0, out, s


@njit(cache=True)
def _orient(ax, ay, bx, by, cx, cy):  # pragma: no cover (compiled)
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True)
def _segments_meet(ax, ay, bx, by, cx, cy, dx, dy):  # pragma: no cover (compiled)
    """Do the closed segments ab and cd meet (cross or touch)?"""
    if max(ax, bx) < min(cx, dx) or max(cx, dx) < min(ax, bx):
        return False
    if max(ay, by) < min(cy, dy) or max(cy, dy) < min(ay, by):
        return False
    d1 = _orient(ax, ay, bx, by, cx, cy)
    d2 = _orient(ax, ay, bx, by, dx, dy)
    d3 = _orient(cx, cy, dx, dy, ax, ay)
    d4 = _orient(cx, cy, dx, dy, bx, by)
    return d1 * d2 <= 0.0 and d3 * d4 <= 0.0


@njit(cache=True)
def _edges_meet(xs, ys, starts) -> np.ndarray:
    """Per ring (``starts`` delimits the rings in ``xs, ys``): whether any of its edges meets an edge
    of itself (other than its neighbours) or of another ring.  Touching counts.  A sweep over
    the edges sorted by their smallest x."""
    n = len(xs)
    nr = len(starts) - 1
    ring = np.empty(n, np.int64)
    nxt = np.empty(n, np.int64)
    for r in range(nr):
        for i in range(starts[r], starts[r + 1]):
            ring[i] = r
            nxt[i] = i + 1 if i + 1 < starts[r + 1] else starts[r]
    lo = np.empty(n)
    for i in range(n):
        lo[i] = min(xs[i], xs[nxt[i]])
    order = np.argsort(lo)
    bad = np.zeros(nr, np.bool_)
    for oi in range(n):
        i = order[oi]
        ax, ay, bx, by = xs[i], ys[i], xs[nxt[i]], ys[nxt[i]]
        hi_x = max(ax, bx)
        ylo, yhi = min(ay, by), max(ay, by)
        for oj in range(oi + 1, n):
            j = order[oj]
            if lo[j] > hi_x:
                break
            cx, cy, dx, dy = xs[j], ys[j], xs[nxt[j]], ys[nxt[j]]
            if max(cy, dy) < ylo or min(cy, dy) > yhi:
                continue
            same = ring[i] == ring[j]
            if same and (nxt[i] == j or nxt[j] == i):
                # neighbours share a vertex: they meet elsewhere only when collinear and folding back
                u1, u2 = bx - ax, by - ay
                v1, v2 = dx - cx, dy - cy
                if u1 * v2 - u2 * v1 == 0 and u1 * v1 + u2 * v2 < 0:
                    bad[ring[i]] = True
                continue
            meet = _segments_meet(ax, ay, bx, by, cx, cy, dx, dy)
            if meet:
                bad[ring[i]] = True
                bad[ring[j]] = True
    return bad


def _rings_that_meet(rings) -> np.ndarray:
    if not rings:
        return np.zeros(0, dtype=bool)
    xy = np.concatenate(rings)
    starts = np.zeros(len(rings) + 1, dtype=np.int64)
    starts[1:] = np.cumsum([len(r) for r in rings])
    return _edges_meet(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]), starts)
