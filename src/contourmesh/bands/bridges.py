"""Bridging several contours of one slice into a single ring, for branching joins.

A slice pair where one contour below meets several contours above (a fork), or several below
meet one above (a merge), has no one-to-one band.  Joining the several contours into one ring by
*bridges* (Christiansen & Sederberg 1978; Bajaj, Coyle & Lin 1996) makes it one: each bridge is a
straight segment between two of the contours, in their plane, and the ring runs along it once
each way.  A band between the single contour and that ring uses each bridge edge twice, in
opposite directions, so the surface folds along the bridge (the crotch of the fork) and stays a
closed manifold: a band is an annulus, and gluing each bridge's two copies turns it into a
sphere with ``m + n`` boundary curves, the topology of the voxel object between the slices.

The bridges form a spanning tree of the contours, chosen shortest first (Kruskal) among a few
nearest vertex pairs per pair of contours, and each must keep off everything else in the plane:
it may touch only its two end vertices, it must not cross or touch any other edge of the slice
(every contour and hole passed as ``obstacles``) nor another bridge, and no vertex ends two
bridges.  Where no such tree exists the caller joins the slices another way.

Functions here are pure: arrays in, arrays out.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bridge_tree", "bridged_ring", "segments_cross"]

#: Candidate vertex pairs tried per pair of contours (nearest first).
CANDIDATES = 12


def _orient(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def segments_cross(p, q, a, b) -> np.ndarray:
    """For the segment ``p q`` and segments ``a[i] b[i]``: whether they share any point.

    Touching counts (an end on the other segment, collinear overlap).  ``p, q`` have shape (2,);
    ``a, b`` shape (k, 2).  Coordinates are expected on a grid of halves or reals; the tests use
    exact float arithmetic on the orientation determinants and count a zero as touching.
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 2)
    px, py, qx, qy = float(p[0]), float(p[1]), float(q[0]), float(q[1])
    d1 = _orient(px, py, qx, qy, a[:, 0], a[:, 1])
    d2 = _orient(px, py, qx, qy, b[:, 0], b[:, 1])
    d3 = _orient(a[:, 0], a[:, 1], b[:, 0], b[:, 1], px, py)
    d4 = _orient(a[:, 0], a[:, 1], b[:, 0], b[:, 1], qx, qy)
    proper = (((d1 > 0) & (d2 < 0)) | ((d1 < 0) & (d2 > 0))) & (((d3 > 0) & (d4 < 0)) | ((d3 < 0) & (d4 > 0)))

    def on(ox, oy, sx, sy, tx, ty, d):
        return (d == 0) & (np.minimum(sx, tx) <= ox) & (ox <= np.maximum(sx, tx)) \
            & (np.minimum(sy, ty) <= oy) & (oy <= np.maximum(sy, ty))

    touch = (on(a[:, 0], a[:, 1], px, py, qx, qy, d1) | on(b[:, 0], b[:, 1], px, py, qx, qy, d2)
             | on(px, py, a[:, 0], a[:, 1], b[:, 0], b[:, 1], d3) | on(qx, qy, a[:, 0], a[:, 1], b[:, 0], b[:, 1], d4))
    return proper | touch


def _candidates(ri: np.ndarray, rj: np.ndarray, k: int):
    """The ``k`` nearest vertex pairs ``(i, j, distance)`` between two rings."""
    from scipy.spatial import cKDTree

    kk = min(k, len(ri))
    d, idx = cKDTree(ri).query(rj, k=kk)
    d = np.asarray(d).reshape(len(rj), kk)
    idx = np.asarray(idx).reshape(len(rj), kk)
    jj = np.repeat(np.arange(len(rj)), kk)
    flat = np.argsort(d.ravel(), kind="stable")[:k]
    return idx.ravel()[flat], jj[flat], d.ravel()[flat]


def bridge_tree(rings, obstacles_a, obstacles_b, *, avoid=None):
    """Bridges joining ``rings`` into one tree, or None where none keeps clear of everything.

    Parameters
    ----------
    rings : list of (n_i, 2) arrays
        The contours to join (closed implicitly), in one plane.
    obstacles_a, obstacles_b : (e, 2) arrays
        Every edge of the slice (the rings' own edges included), as end points.
    avoid : list of ((2,), (2,)) segments, optional
        Segments already in the plane (bridges of another join) that the bridges must not touch.

    Returns
    -------
    list of (i, vi, j, vj)
        Ring ``i``'s vertex ``vi`` joined to ring ``j``'s vertex ``vj``; ``len(rings) - 1`` of them.
    """
    n = len(rings)
    if n < 2:
        return []
    cand = []
    for i in range(n):
        for j in range(i + 1, n):
            vi, vj, d = _candidates(rings[i], rings[j], CANDIDATES)
            cand.extend((float(dd), i, int(a), j, int(b)) for dd, a, b in zip(d, vi, vj))
    cand.sort()
    parent = list(range(n))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    used = set()
    chosen = []
    segs = [tuple(map(np.asarray, s)) for s in (avoid or [])]
    for _, i, vi, j, vj in cand:
        if find(i) == find(j) or (i, vi) in used or (j, vj) in used:
            continue
        p, q = rings[i][vi], rings[j][vj]
        if not _clear(p, q, rings[i], vi, rings[j], vj, obstacles_a, obstacles_b, segs):
            continue
        parent[find(i)] = find(j)
        used.update([(i, vi), (j, vj)])
        chosen.append((i, vi, j, vj))
        segs.append((p, q))
        if len(chosen) == n - 1:
            return chosen
    return None


def _clear(p, q, ri, vi, rj, vj, oa, ob, segs) -> bool:
    """The open segment p q meets no obstacle edge and no other segment; at its ends it meets only
    the two ring edges there, and leaves each ring on its outside."""
    if p[0] == q[0] and p[1] == q[1]:
        return False
    # the edges incident to p and q may touch the segment only at p and q
    inc = [(ri[vi - 1], ri[vi]), (ri[vi], ri[(vi + 1) % len(ri)]), (rj[vj - 1], rj[vj]), (rj[vj], rj[(vj + 1) % len(rj)])]
    keep = np.ones(len(oa), dtype=bool)
    for s, t in inc:
        keep &= ~(((oa == s).all(axis=1) & (ob == t).all(axis=1)) | ((oa == t).all(axis=1) & (ob == s).all(axis=1)))
    lo = np.minimum(p, q)
    hi = np.maximum(p, q)
    near = keep & (np.maximum(oa, ob) >= lo).all(axis=1) & (np.minimum(oa, ob) <= hi).all(axis=1)
    if segments_cross(p, q, oa[near], ob[near]).any():
        return False
    # another edge may pass through p or q only as one of the incident edges (a ring touching
    # itself there has two more): refuse those vertices
    for v in (p, q):
        if (keep & (((oa == v).all(axis=1)) | ((ob == v).all(axis=1)))).any():
            return False
    # leave each ring outward: the direction must not lie inside the ring's interior angle
    for r, v, d in ((ri, vi, q - p), (rj, vj, p - q)):
        a, c, b = r[v - 1], r[v], r[(v + 1) % len(r)]
        if not _outside_corner(a, c, b, d):
            return False
    if segs:
        sa = np.array([s[0] for s in segs], dtype=np.float64)
        sb = np.array([s[1] for s in segs], dtype=np.float64)
        if segments_cross(p, q, sa, sb).any():
            return False
    return True


def _outside_corner(a, c, b, d) -> bool:
    """Whether direction ``d`` from corner ``c`` (ring ... a, c, b ..., counter-clockwise, interior
    on the left) points strictly into the exterior."""
    u = a - c  # back along the incoming edge
    w = b - c  # along the outgoing edge
    cross_wu = w[0] * u[1] - w[1] * u[0]  # > 0: convex corner (interior angle < 180)
    s_w = w[0] * d[1] - w[1] * d[0]  # > 0: d left of w
    s_u = u[0] * d[1] - u[1] * d[0]  # < 0: d right of u
    if cross_wu > 0:
        inside = s_w >= 0 and s_u <= 0  # inside or along an edge
    elif cross_wu < 0:
        inside = not ((s_w < 0) and (s_u > 0))  # reflex: exterior is the convex wedge
    else:
        inside = s_w >= 0  # straight corner: interior is the left half-plane
    return not inside


def bridged_ring(lengths, bridges, root: int = 0):
    """The vertex sequence ``[(ring, vertex), ...]`` of the ring that runs round every contour and
    along every bridge once each way (an Euler tour of the bridge tree), starting on ``root``."""
    n = len(lengths)
    at = {}
    adj = [[] for _ in range(n)]
    for i, vi, j, vj in bridges:
        at[(i, vi)] = (j, vj)
        at[(j, vj)] = (i, vi)
        adj[i].append(j)
        adj[j].append(i)
    out = []

    def tour(r, e, parent, closing):
        # iterative over the ring, recursive over the tree (depth = number of contours, small)
        m = lengths[r]
        for t in range(m + (1 if closing else 0)):
            v = (e + t) % m
            out.append((r, v))
            if t == m:
                break
            other = at.get((r, v))
            if other is not None and other[0] != parent:
                tour(other[0], other[1], r, True)
                out.append((r, v))

    seen_start = next((v for v in range(lengths[root]) if (root, v) not in at), 0)
    tour(root, seen_start, -1, False)
    return out
