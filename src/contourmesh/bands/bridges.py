"""Bridging several contours of one slice into a single ring, for branching joins.

A slice pair where one contour below meets several contours above (a fork), or several below
meet one above (a merge), or where a hole runs out of the side of its component (a handle that
ends), has no one-to-one band.  Joining the several contours into one ring by
*bridges* (Christiansen & Sederberg 1978; Bajaj, Coyle & Lin 1996) makes it one: each bridge is a
straight segment between two of the contours, in their plane, and the ring runs along it once
each way (a bridge from a hole to its own outer contour runs through the material: a keyhole).
A band between the single contour and that ring uses each bridge edge twice, in
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

from functools import partial
from itertools import accumulate

import numpy as np

from .._kernels import njit
from .._recent import MISSING, Recent
from ..topology import _root  # the compiled union-find root (path halving), shared

__all__ = ["OverlapFree", "PreferCovered", "bridge_tree", "bridged_ring", "bridged_ring_arrays", "bridged_ring_ids", "keyhole_path", "keyhole_uncovered", "segments_cross"]

#: Candidate vertex pairs tried per pair of contours (nearest first).
CANDIDATES = 12


class _Coverage:
    """How much of a straight segment in one slice's plane lies over components ``comps`` (0-based)
    of the other slice's label image ``lab``.  ``grid = (ox, oy, dx, dy)`` maps pixel ``(i, j)`` to
    its centre ``(ox + i dx, oy + j dy)``; a segment is sampled 8 times per pixel, its ends left
    out.  Calling it is the keyhole test: ``True`` where none of the segment is covered.
    Compiled (:func:`_coverage_kernel`; :meth:`_hits_reference` is the numpy reference)."""

    def __init__(self, lab, comps, grid):
        self.lab, self.ids, self.grid = lab, np.asarray(comps) + 1, grid
        self._ids64 = np.ascontiguousarray(self.ids, dtype=np.int64)
        self._grid64 = tuple(float(g) for g in grid)

    def _counts(self, P, Q):
        """The covered samples and the samples of each segment ``P[s] Q[s]`` ((m, 2) arrays)."""
        P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 2)
        Q = np.ascontiguousarray(Q, dtype=np.float64).reshape(-1, 2)
        ox, oy, dx, dy = self._grid64
        return _coverage_kernel(P, Q, self.lab, self._ids64, ox, oy, dx, dy)

    def _hits_reference(self, p, q):
        """The samples of segment ``p q`` that are covered, in numpy (the kernel's reference)."""
        ox, oy, dx, dy = self.grid
        lab = self.lab
        steps = max(2, int(np.ceil(8 * max(abs(q[0] - p[0]) / dx, abs(q[1] - p[1]) / dy))))
        t = np.arange(1, steps)[:, None] / steps
        pt = p + t * (q - p)
        # the nearest pixel, halves rounded up (np.rint rounds them to even, which made the answer
        # depend on where the object sits in its array); beyond the array lies background
        i = np.floor((pt[:, 0] - ox) / dx + 0.5).astype(np.int64)
        j = np.floor((pt[:, 1] - oy) / dy + 0.5).astype(np.int64)
        inside = (i >= 0) & (i < lab.shape[1]) & (j >= 0) & (j < lab.shape[0])
        hit = np.zeros(len(pt), dtype=bool)
        hit[inside] = np.isin(lab[j[inside], i[inside]], self.ids)
        return hit

    def __call__(self, p, q) -> bool:
        return not self._counts(p, q)[0][0]

    def share(self, p, q) -> float:
        """The covered share of the segment's samples (0 to 1)."""
        return float(self.shares(p, q)[0])

    def shares(self, P, Q) -> np.ndarray:
        """:meth:`share` of every segment ``P[s] Q[s]`` ((m, 2) arrays) at once."""
        count, n = self._counts(P, Q)
        return count / n


@njit(cache=True, nogil=True)
def _sample_covered(px, py, qx, qy, t, lab, ids, ox, oy, dx, dy):  # pragma: no cover (compiled)
    """1 where the point ``t`` of the way from ``p`` to ``q`` falls on a pixel of ``lab`` whose label
    is in ``ids`` (the pixel whose centre is nearest, inside the image), else 0: one sample of
    :func:`_coverage_kernel` and :func:`_later_kernel`, which write it out in their loops (a helper
    with the arrays ``lab`` and ``ids`` as arguments counted both in and out on every sample, the
    larger part of a sample's cost).  Kept as the rule of one sample (the tests compare)."""
    ny, nx = lab.shape
    i = np.int64(np.floor((px + t * (qx - px) - ox) / dx + 0.5))
    j = np.int64(np.floor((py + t * (qy - py) - oy) / dy + 0.5))
    if i >= 0 and i < nx and j >= 0 and j < ny:
        v = lab[j, i]
        for w in range(ids.shape[0]):
            if v == ids[w]:
                return np.int64(1)
    return np.int64(0)


@njit(cache=True, nogil=True)
def _coverage_kernel(P, Q, lab, ids, ox, oy, dx, dy):
    """Per segment ``P[s] Q[s]``: how many of its samples (8 per pixel, ends left out) fall on a
    pixel of ``lab`` whose label is in ``ids``, and how many samples it has.  The arithmetic of
    :meth:`_Coverage._hits_reference`, sample by sample."""
    m = P.shape[0]
    count = np.zeros(m, np.int64)
    total = np.zeros(m, np.int64)
    ny, nx = lab.shape
    nid = ids.shape[0]
    for s in range(m):
        px, py, qx, qy = P[s, 0], P[s, 1], Q[s, 0], Q[s, 1]
        steps = max(2, int(np.ceil(8 * max(abs(qx - px) / dx, abs(qy - py) / dy))))
        c = 0
        for u in range(1, steps):  # (_sample_covered written out)
            t = u / steps
            i = np.int64(np.floor((px + t * (qx - px) - ox) / dx + 0.5))
            j = np.int64(np.floor((py + t * (qy - py) - oy) / dy + 0.5))
            if i >= 0 and i < nx and j >= 0 and j < ny:
                v = lab[j, i]
                for w in range(nid):
                    if v == ids[w]:
                        c += 1
                        break
        count[s] = c
        total[s] = steps - 1
    return count, total


@njit(cache=True, nogil=True)
def _later_kernel(px, py, qx, qy, lab, ids, ox, oy, dx, dy, share):  # pragma: no cover (compiled)
    """1 where less than ``share`` of segment ``p q``'s samples are covered, else 0: ``0 if count / n
    >= share else 1`` of :func:`_coverage_kernel`'s ``count, n`` for the segment, the same samples,
    but the sampling stops (at the end of each pixel's eight) once the answer is decided: where
    ``count / n`` so far already reaches ``share``, or where even every sample left covered would
    not (``x / n`` never decreases as ``x`` grows, in floating point too: the same answer)."""
    steps = max(2, int(np.ceil(8 * max(abs(qx - px) / dx, abs(qy - py) / dy))))
    n = steps - 1
    ny, nx = lab.shape
    nid = ids.shape[0]
    c = 0
    for u in range(1, steps):  # (_sample_covered written out)
        t = u / steps
        i = np.int64(np.floor((px + t * (qx - px) - ox) / dx + 0.5))
        j = np.int64(np.floor((py + t * (qy - py) - oy) / dy + 0.5))
        if i >= 0 and i < nx and j >= 0 and j < ny:
            v = lab[j, i]
            for w in range(nid):
                if v == ids[w]:
                    c += 1
                    break
        if u % 8 == 0:
            if c / n >= share:
                return np.int64(0)
            if (c + n - u) / n < share:
                return np.int64(1)
    return np.int64(0) if c / n >= share else np.int64(1)


def keyhole_uncovered(lab, comps, grid):
    """The test ``ok(p, q)`` that a straight keyhole from ``p`` to ``q`` runs where the label image
    ``lab`` (of the other slice) has none of the components ``comps`` (0-based): there the material
    ends between the slices and a band may come down to the keyhole.  ``grid = (ox, oy, dx, dy)``
    maps pixel ``(i, j)`` to its centre ``(ox + i dx, oy + j dy)``; the segment is sampled 8 times
    per pixel.  The test's ``share(p, q)`` is the covered share of a segment (see
    :func:`bridge_tree`'s ``prefer``)."""
    return _Coverage(lab, comps, grid)


def _orient(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True, nogil=True, inline="always")
def _on(ox, oy, sx, sy, tx, ty, d):
    """Point ``o`` on the closed segment ``s t`` given ``d``, the orientation of ``s t o``."""
    return d == 0 and min(sx, tx) <= ox <= max(sx, tx) and min(sy, ty) <= oy <= max(sy, ty)


@njit(cache=True, nogil=True, inline="always")
def _cross1(px, py, qx, qy, ax, ay, bx, by):
    """Whether the closed segments ``p q`` and ``a b`` share a point: :func:`segments_cross` for
    one segment, the same arithmetic (exact float signs, a zero counts as touching)."""
    d1 = (qx - px) * (ay - py) - (qy - py) * (ax - px)
    d2 = (qx - px) * (by - py) - (qy - py) * (bx - px)
    d3 = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    d4 = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
    if ((d1 > 0 and d2 < 0) or (d1 < 0 and d2 > 0)) and ((d3 > 0 and d4 < 0) or (d3 < 0 and d4 > 0)):
        return True
    return (_on(ax, ay, px, py, qx, qy, d1) or _on(bx, by, px, py, qx, qy, d2)
            or _on(px, py, ax, ay, bx, by, d3) or _on(qx, qy, ax, ay, bx, by, d4))


@njit(cache=True, nogil=True)
def _segments_cross_kernel(px, py, qx, qy, a, b):
    out = np.zeros(a.shape[0], np.bool_)
    for i in range(a.shape[0]):
        out[i] = _cross1(px, py, qx, qy, a[i, 0], a[i, 1], b[i, 0], b[i, 1])
    return out


def segments_cross(p, q, a, b) -> np.ndarray:
    """For the segment ``p q`` and segments ``a[i] b[i]``: whether they share any point.

    Touching counts (an end on the other segment, collinear overlap).  ``p, q`` have shape (2,);
    ``a, b`` shape (k, 2).  Coordinates are expected on a grid of halves or reals; the tests use
    exact float arithmetic on the orientation determinants and count a zero as touching.
    Compiled (:func:`_segments_cross_reference` is the vectorized reference it is tested against).
    """
    a = np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.ascontiguousarray(b, dtype=np.float64).reshape(-1, 2)
    return _segments_cross_kernel(float(p[0]), float(p[1]), float(q[0]), float(q[1]), a, b)


def _segments_cross_reference(p, q, a, b) -> np.ndarray:
    """:func:`segments_cross` in numpy (the reference of the compiled kernel, for the tests)."""
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


#: Largest ``len(ri) * len(rj)`` for which :func:`_candidates` measures every pair in compiled code
#: (:func:`_nearest_kernel`) rather than querying a k-d tree: faster up to some 400 000 pairs (two
#: rings of 400 and 1000 points: 0.56 ms each way), and the whole tree is then searched in one
#: compiled call (:func:`_candidate_columns`) instead of the Python loop.
_BRUTE_PAIRS = 200000


def _candidates(ri: np.ndarray, rj: np.ndarray, k: int):
    """The ``k`` nearest vertex pairs ``(i, j, distance, tie)`` between two rings, with every pair
    as near as the ``k``-th (so that a rotated or mirrored input sees the same set).  ``tie`` is
    the distance of the pair's midpoint from the centroid of both rings' vertices: it orders
    equally short pairs the same way whatever the orientation of the input.

    The pairs are those of a k-d tree query (:func:`_candidates_reference`: the ``min(k,
    len(ri))`` nearest vertices of ``ri`` to each vertex of ``rj``, those as near as the ``k``-th
    shortest of them all): for small rings measured all at once in compiled code, with the same
    distances (``sqrt(dx * dx + dy * dy)``, the tree's arithmetic), in another order (the caller
    sorts them).  Where a vertex of ``rj`` has more vertices of ``ri`` within the cut than the
    query returns (ties at its last place, which the tree breaks its own way), the tree decides."""
    ri = np.ascontiguousarray(ri, dtype=np.float64)
    rj = np.ascontiguousarray(rj, dtype=np.float64)
    if len(ri) * len(rj) > _BRUTE_PAIRS:
        return _candidates_reference(ri, rj, k)
    vi, vj, d, ok = _nearest_kernel(ri, rj, np.int64(k))
    if not ok:
        return _candidates_reference(ri, rj, k)
    return vi, vj, d, _tie_kernel(ri, rj, vi, vj)


@njit(cache=True, nogil=True)
def _tie_kernel(ri, rj, vi, vj):
    """The tie-break of :func:`_candidates`: ``np.hypot(*(0.5 * (ri[vi] + rj[vj]) - centre).T)`` with
    ``centre = np.concatenate([ri, rj]).mean(axis=0)`` (numpy adds the rows in order along that
    axis, then divides by their number), the same operations one by one."""
    c0 = 0.0
    c1 = 0.0
    for a in range(ri.shape[0]):
        c0 += ri[a, 0]
        c1 += ri[a, 1]
    for a in range(rj.shape[0]):
        c0 += rj[a, 0]
        c1 += rj[a, 1]
    c0 /= ri.shape[0] + rj.shape[0]
    c1 /= ri.shape[0] + rj.shape[0]
    tie = np.empty(vi.shape[0])
    for t in range(vi.shape[0]):
        tie[t] = np.hypot(0.5 * (ri[vi[t], 0] + rj[vj[t], 0]) - c0, 0.5 * (ri[vi[t], 1] + rj[vj[t], 1]) - c1)
    return tie


@njit(cache=True, nogil=True)
def _nearest_kernel(ri, rj, k):  # pragma: no cover (compiled)
    """:func:`_nearest_all` without the square root of every pair and without the table of all
    the distances: the same ``(vi, vj, d, ok)``, bit for bit.

    The ``q`` smallest squared distances ``dx * dx + dy * dy`` are kept instead of their roots: the
    root is monotone, so the root of the ``q``-th smallest square is the ``q``-th smallest root (the
    same cut).  The pairs are then measured again, the same arithmetic, and the root taken only
    where the square is within ``cut * cut`` (plus a margin far above the roots' rounding): a pair
    further out has a root above the cut.  The pairs come out in the same order (``j``, then
    ``i``); a NaN distance leaves everything to :func:`_nearest_all`."""
    ni, nj = ri.shape[0], rj.shape[0]
    kk = min(k, ni)
    q = min(k, nj * kk)
    best = np.empty(q)
    nb = 0
    for j in range(nj):
        for i in range(ni):
            dx = ri[i, 0] - rj[j, 0]
            dy = ri[i, 1] - rj[j, 1]
            v = dx * dx + dy * dy
            if v != v:
                return _nearest_all(ri, rj, k)
            # the q smallest so far, ascending (insertion)
            if nb < q:
                t = nb
                nb += 1
            elif v < best[q - 1]:
                t = q - 1
            else:
                continue
            while t > 0 and best[t - 1] > v:
                best[t] = best[t - 1]
                t -= 1
            best[t] = v
    cut = np.sqrt(best[q - 1]) * (1 + 1e-12)
    # squares above lim have roots above the cut (no pruning where cut * cut could under- or overflow)
    lim = cut * cut * (1 + 1e-9) if 1e-100 < cut < 1e100 else np.inf
    cap = nj * kk
    vi = np.empty(cap, np.int64)
    vj = np.empty(cap, np.int64)
    d = np.empty(cap)
    t = 0
    for j in range(nj):
        c = 0
        for i in range(ni):
            dx = ri[i, 0] - rj[j, 0]
            dy = ri[i, 1] - rj[j, 1]
            v = dx * dx + dy * dy
            if v > lim:
                continue
            v = np.sqrt(v)
            if v <= cut:
                c += 1
                if c > kk:
                    return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0), False
                vi[t] = i
                vj[t] = j
                d[t] = v
                t += 1
    return vi[:t].copy(), vj[:t].copy(), d[:t].copy(), True


@njit(cache=True, nogil=True)
def _nearest_all(ri, rj, k):  # pragma: no cover (compiled)
    """:func:`_candidates`' pairs by measuring every pair: ``(vi, vj, d, ok)``, ``ok`` False where
    a vertex of ``rj`` has more than ``min(k, len(ri))`` vertices within the cut (then the k-d
    tree's choice among equal distances would decide, see :func:`_candidates_reference`).

    The cut is the ``q``-th smallest of all the distances, ``q = min(k, len(rj) min(k, len(ri)))``
    (times ``1 + 1e-12``): the ``q``-th smallest of the tree's answers (each vertex of ``rj`` with
    its ``min(k, len(ri))`` nearest), which hold the ``q`` smallest distances.  It is kept as the
    ``q`` smallest so far, in one short ascending list, as the pairs are measured."""
    ni, nj = ri.shape[0], rj.shape[0]
    kk = min(k, ni)
    q = min(k, nj * kk)
    D = np.empty((nj, ni))
    best = np.empty(q)
    nb = 0
    for j in range(nj):
        for i in range(ni):
            dx = ri[i, 0] - rj[j, 0]
            dy = ri[i, 1] - rj[j, 1]
            v = np.sqrt(dx * dx + dy * dy)
            D[j, i] = v
            # the q smallest so far, ascending (insertion)
            if nb < q:
                t = nb
                nb += 1
            elif v < best[q - 1]:
                t = q - 1
            else:
                continue
            while t > 0 and best[t - 1] > v:
                best[t] = best[t - 1]
                t -= 1
            best[t] = v
    cut = best[q - 1] * (1 + 1e-12)
    count = 0
    for j in range(nj):
        c = 0
        for i in range(ni):
            if D[j, i] <= cut:
                c += 1
        if c > kk:
            return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0), False
        count += c
    vi = np.empty(count, np.int64)
    vj = np.empty(count, np.int64)
    d = np.empty(count)
    t = 0
    for j in range(nj):
        for i in range(ni):
            if D[j, i] <= cut:
                vi[t] = i
                vj[t] = j
                d[t] = D[j, i]
                t += 1
    return vi, vj, d, True


def _candidates_reference(ri: np.ndarray, rj: np.ndarray, k: int):
    """:func:`_candidates` by a k-d tree query (for large rings, and the reference of the
    compiled search)."""
    from scipy.spatial import cKDTree

    kk = min(k, len(ri))
    d, idx = cKDTree(ri).query(rj, k=kk)
    d = np.asarray(d).reshape(len(rj), kk).ravel()
    idx = np.asarray(idx).reshape(len(rj), kk).ravel()
    jj = np.repeat(np.arange(len(rj)), kk)
    cut = np.sort(d)[min(k, len(d)) - 1] * (1 + 1e-12)
    sel = d <= cut
    vi, vj, d = idx[sel], jj[sel], d[sel]
    centre = np.concatenate([ri, rj]).mean(axis=0)
    tie = np.hypot(*(0.5 * (ri[vi] + rj[vj]) - centre).T)
    return vi, vj, d, tie


def _near_pairs(rings, k: int = 6):
    """Pairs ``(i, j)``, ``i < j``, of rings worth bridging: with few rings every pair; with many,
    each ring with the ``k`` rings whose bounding boxes are nearest to its own (a spanning tree of
    shortest bridges almost always joins near neighbours)."""
    n = len(rings)
    if n <= k + 1:
        return [(i, j) for i in range(n) for j in range(i + 1, n)]
    lo = np.array([r.min(axis=0) for r in rings])
    hi = np.array([r.max(axis=0) for r in rings])
    gap = np.maximum(0.0, np.maximum(lo[:, None] - hi[None, :], lo[None, :] - hi[:, None]))
    d = np.hypot(gap[..., 0], gap[..., 1])
    np.fill_diagonal(d, np.inf)
    near = np.argsort(d, axis=1, kind="stable")[:, :k]
    return sorted({(min(i, int(j)), max(i, int(j))) for i in range(n) for j in near[i]})


def _round9(x) -> np.ndarray:
    """``round(v, 9)`` (Python's: the decimal rounding of the exact value, half to even) of every
    float ``v`` of ``x``, as an array.  ``rint(v * 1e9) / 1e9`` is that number wherever ``v * 1e9``
    lies clearly off a half (its rounding error, at most ``|v| 1e9 2^-53``, cannot move it across
    one) and below ``2^52``; the other values (halves, near-halves, huge or not finite) are
    rounded by Python.  The safe values are rounded in compiled code (:func:`_round9_kernel`, the
    same operations); :func:`_round9_reference` is the numpy form."""
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    out, unsafe = _round9_kernel(x)
    for t in unsafe.tolist():
        out[t] = round(float(x[t]), 9)
    return out


@njit(cache=True, nogil=True)
def _round9_kernel(x):
    """:func:`_round9`'s ``rint(v * 1e9) / 1e9`` of every value, and the places of the values that
    are not safe to round so (left to Python)."""
    out = np.empty(x.shape[0])
    unsafe = np.empty(x.shape[0], np.int64)
    nu = 0
    for t in range(x.shape[0]):
        y = x[t] * 1e9
        out[t] = np.rint(y) / 1e9
        if not (abs(y - np.floor(y) - 0.5) > abs(y) * 2.0 ** -50 and abs(y) < 2.0 ** 52):
            unsafe[nu] = t
            nu += 1
    return out, unsafe[:nu]


def _round9_reference(x) -> np.ndarray:
    """:func:`_round9` in numpy (the reference of the compiled kernel)."""
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    with np.errstate(over="ignore", invalid="ignore"):
        y = x * 1e9
        safe = (np.abs(y - np.floor(y) - 0.5) > np.abs(y) * 2.0 ** -50) & (np.abs(y) < 2.0 ** 52)
    out = np.rint(y) / 1e9
    for t in np.flatnonzero(~safe).tolist():
        out[t] = round(float(x[t]), 9)
    return out


def _sorted_candidates(parts) -> list:
    """The candidate bridges of :func:`bridge_tree`, ``(not preferred, round(length, 9),
    round(tie, 9), i, vi, j, vj)`` tuples of Python numbers, sorted: ``parts`` holds those fields
    as arrays, per pair of rings.  The same list as making each tuple and sorting them
    (:func:`_sorted_candidates_reference`): the lexicographic order of the same keys."""
    return _candidate_list(_candidate_arrays(parts))


def _candidate_list(cols) -> list:
    """The tuples of the columns of :func:`_candidate_arrays`."""
    return list(zip(*(a.tolist() for a in cols)))


def _candidate_arrays(parts):
    """:func:`_sorted_candidates` as seven sorted columns (int64, float64, float64 and four int64)."""
    if not parts:
        return tuple(np.zeros(0, dtype=np.float64 if f in (1, 2) else np.int64) for f in range(7))
    lt, d, tie, i, vi, j, vj = (np.concatenate([np.asarray(p[f]).reshape(-1) for p in parts]) for f in range(7))
    if np.isnan(d).any() or np.isnan(tie).any():  # (a NaN has no place in an order: as the tuples sort it)
        cand = _sorted_candidates_reference(parts)
        return tuple(np.array([c[f] for c in cand], dtype=np.float64 if f in (1, 2) else np.int64) for f in range(7))
    lt = lt.astype(np.int64)
    d, tie = _round9(d), _round9(tie)
    i, vi, j, vj = (np.asarray(a, dtype=np.int64) for a in (i, vi, j, vj))
    order = np.lexsort((vj, j, vi, i, tie, d, lt))
    return tuple(a[order] for a in (lt, d, tie, i, vi, j, vj))


def _sorted_candidates_reference(parts) -> list:
    """:func:`_sorted_candidates` tuple by tuple (the reference of the tests)."""
    cand = []
    for later, d, tie, i, vi, j, vj in parts:
        cand.extend((int(lt), round(dd, 9), round(t, 9), int(a_), int(a), int(b_), int(b))
                    for lt, dd, t, a_, a, b_, b in zip(np.asarray(later).tolist(), np.asarray(d, dtype=np.float64).tolist(),
                                                      np.asarray(tie, dtype=np.float64).tolist(), np.asarray(i).tolist(),
                                                      np.asarray(vi).tolist(), np.asarray(j).tolist(),
                                                      np.asarray(vj).tolist()))
    cand.sort()
    return cand


class PreferCovered:
    """A ``prefer`` test of :func:`bridge_tree`: the bridges of which at least ``share`` of the
    samples lie on the components of a :func:`keyhole_uncovered` test (``cover``), i.e. over the
    other slice's material.  Called, it gives that test's answer; :func:`bridge_tree` reads its
    data and orders the candidates in compiled code (:func:`_candidate_kernel`)."""

    def __init__(self, cover, share=0.5):
        self.cover, self.share = cover, float(share)

    def __call__(self, P, Q):
        return self.cover.shares(P, Q) >= self.share


def _packed_rings(rings):
    """``rings`` as the compiled kernels take them: ``(pts, off, lens)``, ring ``r`` in
    ``pts[off[r]: off[r] + lens[r]]`` (float64, one C array)."""
    rs = [np.ascontiguousarray(r, dtype=np.float64).reshape(-1, 2) for r in rings]
    sizes = [len(r) for r in rs]
    # (the offsets summed in Python: np.cumsum's call costs more than the few additions)
    off = list(accumulate(sizes[:-1], initial=0)) if sizes else []
    return np.concatenate(rs), np.array(off, dtype=np.int64), np.array(sizes, dtype=np.int64)


def _keyhole_test_arrays(allowed):
    """The label image, component ids and grid of a :func:`keyhole_uncovered` test (or a dummy for
    None), as :func:`_straight_kernel` takes them."""
    if allowed is None:
        return np.zeros((1, 1), dtype=np.uint8), np.zeros(0, dtype=np.int64), (0.0, 0.0, 1.0, 1.0)
    return allowed.lab, allowed._ids64, allowed._grid64


def _candidate_columns(rings, pairs, owners, prefer, straight=None, packed=None):
    """:func:`_candidate_arrays` of the candidates of ``pairs`` (rings to bridge, in order) as
    :func:`bridge_tree`'s loop makes them, for ``prefer`` None or a :class:`PreferCovered`: in one
    compiled call (:func:`_candidate_kernel`).  None where some pair is left to Python (rings
    too large for the compiled search, ties the k-d tree decides, NaN, or a length or tie-break
    that Python must round).

    ``straight``, where given, is ``(obstacles_a, obstacles_b, avoid, allowed)`` of
    :func:`bridge_tree`: then the result is ``(columns, chosen)``, with ``chosen`` the straight
    bridges of :func:`_straight_bridges` made in the same compiled call (:func:`_tree_kernel`)
    where ``allowed`` is None or a :func:`keyhole_uncovered` test, else None (still None overall
    where the candidates are left to Python).  The columns are None where ``chosen`` joins all
    the rings (:func:`bridge_tree` then reads no more; the kernel does not make them).

    ``packed``, where given, is :func:`_packed_rings` of ``rings`` as the caller already holds it
    (the same arrays: the kernels read those numbers only)."""
    if not pairs or any(len(r) == 0 for r in rings):
        return None
    pts, off, lens = _packed_rings(rings) if packed is None else packed
    sizes = lens.tolist()  # (Python ints: the products as int(lens[i]) * int(lens[j]))
    if max(sizes[i] * sizes[j] for i, j in pairs) > _BRUTE_PAIRS:
        return None
    pr = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    ask = np.array([prefer is not None and owners[i][0] != owners[j][0] for i, j in pairs], dtype=np.bool_)
    if prefer is None:
        lab, cids, grid, share = np.zeros((1, 1), dtype=np.uint8), np.zeros(0, dtype=np.int64), (0.0, 0.0, 1.0, 1.0), 0.5
    else:
        c = prefer.cover
        lab, cids, grid, share = c.lab, c._ids64, c._grid64, prefer.share
    if straight is None:
        cols = _candidate_kernel(pts, off, lens, pr, ask, np.int64(CANDIDATES), lab, cids, *grid, share)
        return cols[:7] if cols[7] else None
    oa, ob, avoid, allowed = straight
    if not (allowed is None or isinstance(allowed, _Coverage)):
        cols = _candidate_kernel(pts, off, lens, pr, ask, np.int64(CANDIDATES), lab, cids, *grid, share)
        return (cols[:7], None) if cols[7] else None
    ids = {}
    comp = np.array([ids.setdefault(o[0], len(ids)) for o in owners], dtype=np.int64)
    sa, sb = _segment_arrays([tuple(map(np.asarray, s_)) for s_ in avoid]) if avoid else (_NO_SEGMENTS, _NO_SEGMENTS)
    alab, acids, agrid = _keyhole_test_arrays(allowed)
    got = _tree_kernel(pts, off, lens, pr, ask, np.int64(CANDIDATES), lab, cids, *grid, share, comp,
                       np.ascontiguousarray(oa, dtype=np.float64), np.ascontiguousarray(ob, dtype=np.float64),
                       np.ascontiguousarray(sa, dtype=np.float64), np.ascontiguousarray(sb, dtype=np.float64),
                       alab, acids, *agrid, allowed is not None, np.int64(len(rings)))
    if not got[7]:
        return None
    return (None if got[9] else got[:7]), [tuple(row) for row in got[8].tolist()]


@njit(cache=True, nogil=True)
def _tree_kernel(pts, off, lens, pairs, ask, k, lab, cids, ox, oy, dx, dy, share, comp, oa, ob, sa0, sb0,
                 alab, acids, aox, aoy, adx, ady, use_allowed, n):  # pragma: no cover (compiled)
    """:func:`_candidate_kernel` and, where its candidates are all compiled (its eighth value),
    :func:`_straight_kernel` on them, in one call: :func:`bridge_tree`'s candidates and straight
    bridges without the trip through Python between the two.  Returns the candidate kernel's eight
    values and the straight bridges (rows ``i, vi, j, vj``; none where the eighth value is False),
    and whether those join all ``n`` rings: then the seven columns are not made (empty; nothing
    reads them).

    A candidate's preference (:func:`_later_kernel`, the costly part: it samples the label image
    along the bridge) is measured only where the straight loop reaches it.  The loop takes the
    preferred candidates in order, then the others: the rows sorted without the preference (the
    same order within each kind, as a stable sort keeps it) are walked twice, the preferred ones
    the first time, the others the second.  A row whose rings are already joined, or whose end
    is taken, is passed over unmeasured: it would be at its own turn too (the forest only merges,
    the ends only get taken).  Where the bridges do not join all the rings every preference is
    measured and the columns made as :func:`_candidate_kernel` makes them."""
    c_d, c_tie, c_i, c_vi, c_j, c_vj, c_p, ok = _pair_rows(pts, off, lens, pairs, k)
    total = c_d.shape[0]
    c_lt = np.zeros(total, np.int64)
    if not ok:
        for t in range(total):
            if ask[c_p[t]]:
                a, b = off[c_i[t]] + c_vi[t], off[c_j[t]] + c_vj[t]  # (_row_later written out)
                c_lt[t] = _later_kernel(pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1], lab, cids, ox, oy, dx, dy, share)
        return c_lt, c_d, c_tie, c_i, c_vi, c_j, c_vj, ok, np.empty((0, 4), np.int64), False
    for t in range(total):
        if ask[c_p[t]]:
            c_lt[t] = -1  # (not measured yet)
    order = _lexsort_order(np.zeros(total, np.int64), c_d, c_tie, c_i, c_vi, c_j, c_vj)
    parent = np.arange(n)
    used = np.zeros(pts.shape[0], np.bool_)
    out = np.empty((max(n - 1, 0), 4), np.int64)
    got = 0
    ns = sa0.shape[0]
    sa = np.empty((ns + n, 2))
    sb = np.empty((ns + n, 2))
    sa[:ns] = sa0
    sb[:ns] = sb0
    corners = np.empty((2, 3, 2))
    P1 = np.empty((1, 2))
    Q1 = np.empty((1, 2))
    for kind in range(2):  # the preferred candidates (c_lt 0), then the others
        for t in range(total):
            if got == n - 1:
                break
            r = order[t]
            i, vi, j, vj = c_i[r], c_vi[r], c_j[r], c_vj[r]
            if _root(parent, i) == _root(parent, j) or used[off[i] + vi] or used[off[j] + vj]:
                continue
            if c_lt[r] < 0:
                a, b = off[c_i[r]] + c_vi[r], off[c_j[r]] + c_vj[r]  # (_row_later written out)
                c_lt[r] = _later_kernel(pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1], lab, cids, ox, oy, dx, dy, share)
            if c_lt[r] != kind:
                continue
            # (_straight_ok written out: the helper, inlined, counted its arrays in and out per candidate)
            for end in range(2):
                rr, vv = (i, vi) if end == 0 else (j, vj)
                mr = lens[rr]
                for u in range(3):
                    w = off[rr] + (vv - 1 + u) % mr
                    corners[end, u, 0] = pts[w, 0]
                    corners[end, u, 1] = pts[w, 1]
            px, py = pts[off[i] + vi, 0], pts[off[i] + vi, 1]
            qx, qy = pts[off[j] + vj, 0], pts[off[j] + vj, 1]
            through = comp[i] == comp[j]
            if not _clear_kernel(px, py, qx, qy, corners, np.int64(1), np.int64(1), oa, ob, sa[:ns], sb[:ns], through):
                continue
            if through and use_allowed:
                P1[0, 0], P1[0, 1], Q1[0, 0], Q1[0, 1] = px, py, qx, qy
                count, _ = _coverage_kernel(P1, Q1, alab, acids, aox, aoy, adx, ady)
                if count[0] != 0:
                    continue
            parent[_root(parent, i)] = _root(parent, j)
            used[off[i] + vi] = True
            used[off[j] + vj] = True
            out[got, 0], out[got, 1], out[got, 2], out[got, 3] = i, vi, j, vj
            got += 1
            sa[ns, 0], sa[ns, 1] = pts[off[i] + vi, 0], pts[off[i] + vi, 1]
            sb[ns, 0], sb[ns, 1] = pts[off[j] + vj, 0], pts[off[j] + vj, 1]
            ns += 1
    if got == n - 1:
        e = np.empty(0, np.int64)
        return e, np.empty(0), np.empty(0), e, e, e, e, ok, out[:got], True
    # the columns as _candidate_kernel makes them: every preference measured; the order sorted by
    # the preference first, the rest as before (a stable partition of the order without it)
    for t in range(total):
        if c_lt[t] < 0:
            a, b = off[c_i[t]] + c_vi[t], off[c_j[t]] + c_vj[t]  # (_row_later written out)
            c_lt[t] = _later_kernel(pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1], lab, cids, ox, oy, dx, dy, share)
    full = np.empty(total, np.int64)
    m = 0
    for kind in range(2):
        for t in range(total):
            if c_lt[order[t]] == kind:
                full[m] = order[t]
                m += 1
    return (c_lt[full], c_d[full], c_tie[full], c_i[full], c_vi[full], c_j[full], c_vj[full], ok, out[:got],
            False)


@njit(cache=True, nogil=True)
def _candidate_kernel(pts, off, lens, pairs, ask, k, lab, cids, ox, oy, dx, dy, share):
    """The loop of :func:`bridge_tree` over the pairs of rings (``pts[off[r]: off[r] + lens[r]]``)
    and :func:`_candidate_arrays` in one: per pair :func:`_nearest_kernel` and :func:`_tie_kernel`
    (:func:`_pair_rows`), the preference where ``ask`` (:func:`_coverage_kernel`'s covered share at
    least ``share``), lengths and tie-breaks rounded (:func:`_round9_kernel`), and the rows sorted
    as ``np.lexsort`` sorts them (:func:`_lexsort_order`).  The eighth value is False where
    :func:`_candidates` or :func:`_round9` would hand something to Python: the caller then takes
    the Python loop."""
    c_d, c_tie, c_i, c_vi, c_j, c_vj, c_p, ok = _pair_rows(pts, off, lens, pairs, k)
    total = c_d.shape[0]
    c_lt = np.zeros(total, np.int64)
    for t in range(total):
        if ask[c_p[t]]:  # (the preference of each candidate: _later_kernel)
            a, b = off[c_i[t]] + c_vi[t], off[c_j[t]] + c_vj[t]  # (_row_later written out)
            c_lt[t] = _later_kernel(pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1], lab, cids, ox, oy, dx, dy, share)
    order = _lexsort_order(c_lt, c_d, c_tie, c_i, c_vi, c_j, c_vj) if ok else np.arange(total)
    return (c_lt[order], c_d[order], c_tie[order], c_i[order], c_vi[order], c_j[order], c_vj[order], ok)


@njit(cache=True, nogil=True)
def _pair_rows(pts, off, lens, pairs, k):  # pragma: no cover (compiled)
    """The candidates of :func:`_candidate_kernel` before their preference and their order: per
    pair of rings (rows of ``pairs``) :func:`_nearest_kernel` and :func:`_tie_kernel`, as columns
    ``d, tie, i, vi, j, vj`` and the pair of each row, lengths and tie-breaks rounded
    (:func:`_round9_kernel`); the last value False where :func:`_candidates` or :func:`_round9`
    would hand something to Python (then the rows stop at that pair, nothing rounded)."""
    np_ = pairs.shape[0]
    cap = 0  # (a pair has at most min(k, len(ri)) candidates per vertex of rj)
    for p in range(np_):
        cap += lens[pairs[p, 1]] * min(k, lens[pairs[p, 0]])
    c_d = np.empty(cap)
    c_tie = np.empty(cap)
    c_i = np.empty(cap, np.int64)
    c_vi = np.empty(cap, np.int64)
    c_j = np.empty(cap, np.int64)
    c_vj = np.empty(cap, np.int64)
    c_p = np.empty(cap, np.int64)
    total = 0
    ok = True
    for p in range(np_):
        i, j = pairs[p, 0], pairs[p, 1]
        ri = pts[off[i]: off[i] + lens[i]].copy()
        rj = pts[off[j]: off[j] + lens[j]].copy()
        vi, vj, d, found = _nearest_kernel(ri, rj, k)
        if not found:
            ok = False
            break
        tie = _tie_kernel(ri, rj, vi, vj)
        m = vi.shape[0]
        for t in range(m):
            c_d[total + t], c_tie[total + t] = d[t], tie[t]
            c_i[total + t], c_vi[total + t], c_j[total + t], c_vj[total + t] = i, vi[t], j, vj[t]
            c_p[total + t] = p
        total += m
    c_d, c_tie, c_i, c_vi, c_j, c_vj, c_p = c_d[:total], c_tie[:total], c_i[:total], c_vi[:total], \
        c_j[:total], c_vj[:total], c_p[:total]
    for t in range(total):
        if np.isnan(c_d[t]) or np.isnan(c_tie[t]):
            ok = False
    if ok:
        c_d, bad_d = _round9_kernel(c_d)
        c_tie, bad_tie = _round9_kernel(c_tie)
        ok = bad_d.shape[0] == 0 and bad_tie.shape[0] == 0
    return c_d, c_tie, c_i, c_vi, c_j, c_vj, c_p, ok


@njit(cache=True, nogil=True)
def _lexsort_order(c_lt, c_d, c_tie, c_i, c_vi, c_j, c_vj):  # pragma: no cover (compiled)
    """The order of ``np.lexsort((vj, j, vi, i, tie, d, lt))`` (no NaN): a stable merge sort on the
    seven keys."""
    total = c_d.shape[0]
    order = np.arange(total)
    tmp = np.empty(total, np.int64)
    width = 1
    while width < total:
        for lo in range(0, total, 2 * width):
            mid, hi = min(lo + width, total), min(lo + 2 * width, total)
            a, b, t = lo, mid, lo
            while a < mid and b < hi:
                x, y = order[a], order[b]
                # y before x only where its keys are smaller (equal keys keep their order)
                if _key_less(y, x, c_lt, c_d, c_tie, c_i, c_vi, c_j, c_vj):
                    tmp[t] = y
                    b += 1
                else:
                    tmp[t] = x
                    a += 1
                t += 1
            while a < mid:
                tmp[t] = order[a]
                a += 1
                t += 1
            while b < hi:
                tmp[t] = order[b]
                b += 1
                t += 1
        order, tmp = tmp, order
        width *= 2
    return order


@njit(cache=True, nogil=True, inline="always")
def _key_less(x, y, lt, d, tie, i, vi, j, vj):
    """Whether row ``x``'s keys ``(lt, d, tie, i, vi, j, vj)`` come before row ``y``'s (no NaN)."""
    if lt[x] != lt[y]:
        return lt[x] < lt[y]
    if d[x] != d[y]:
        return d[x] < d[y]
    if tie[x] != tie[y]:
        return tie[x] < tie[y]
    if i[x] != i[y]:
        return i[x] < i[y]
    if vi[x] != vi[y]:
        return vi[x] < vi[y]
    if j[x] != j[y]:
        return j[x] < j[y]
    return vj[x] < vj[y]


def bridge_tree(rings, obstacles_a, obstacles_b, *, avoid=None, owners=None, allowed=None, waypoints=None,
                step=1.0, prefer=None, packed=None):
    """Bridges joining ``rings`` into one tree, or None where none keeps clear of everything.

    Parameters
    ----------
    rings : list of (n_i, 2) arrays
        The contours to join (closed implicitly), in one plane.
    obstacles_a, obstacles_b : (e, 2) arrays
        Every edge of the slice (the rings' own edges included), as end points.
    avoid : list of ((2,), (2,)) segments, optional
        Segments already in the plane (bridges of another join) that the bridges must not touch.
    owners : list of (component, is_hole), optional
        Which region each ring bounds.  Outer rings of different components are bridged through
        the background between them; a hole is bridged to its own component's outer ring or to
        another of its holes through the component's material (a *keyhole*).  Other pairs are
        not bridged.  Default: every ring is the outer ring of its own component.  Rings run
        counter-clockwise round their component's material when outer, clockwise when holes (the
        material is on their left).
    allowed : callable ``(p, q) -> bool``, optional
        A further test of a candidate keyhole (e.g. that it crosses no overlap with the other
        slice).
    waypoints : callable ``component -> ((m, 2) array, allowed)``, optional
        Points in a component's material that a keyhole may pass through (e.g. the centres of its
        pixels that do not overlap the other slice), and the test its pieces must pass (``None``:
        ``allowed``).  Where no straight keyhole keeps clear, a *polyline* keyhole is searched
        through them (:func:`keyhole_path`); without it only straight bridges are made.  With
        an :class:`OverlapFree` test (or none) the search runs in compiled code.
    step : float
        The spacing of the waypoints (the pixel size): neighbours are at most ``1.5 step`` apart.
    prefer : callable ``(P, Q) -> bool array``, optional
        Asked once per pair of rings of all its candidate bridges ``P[s] Q[s]`` (``(m, 2)`` arrays of
        their ends).  Bridges between different components for which it holds are tried before the others
        (each kind shortest first).  The mesher prefers bridges over the other slice's material:
        the crotch of a fork lies above what the branches grew from.  A shorter bridge across
        empty space (the mouth of a C whose two arms part above it) would make the band fold
        across the whole opening.  A :class:`PreferCovered` test is run in compiled code with the
        candidates (:func:`_candidate_kernel`); any other callable in Python.
    packed : (pts, off, lens), optional
        The rings packed as the compiled kernels take them (:func:`_packed_rings`: ring ``r`` in
        ``pts[off[r]: off[r] + lens[r]]``, one C array of float64), where the caller holds them so
        (the mesher's rings are runs of one vertex array): not packed again.  The same bridges.

    Returns
    -------
    list of (i, vi, j, vj) or (i, vi, j, vj, points)
        Ring ``i``'s vertex ``vi`` joined to ring ``j``'s vertex ``vj``; ``len(rings) - 1`` of them.
        A polyline keyhole has a fifth entry, its interior points from ``i``'s end to ``j``'s
        (an ``(m, 2)`` array, ``m >= 1``); a straight bridge has four.
    """
    n = len(rings)
    if n < 2:
        return []
    owners = owners or [(i, False) for i in range(n)]
    pairs = [(i, j) for i, j in _near_pairs(rings)
             if (owners[i][0] != owners[j][0] and not owners[i][1] and not owners[j][1])
             or (owners[i][0] == owners[j][0] and (owners[i][1] or owners[j][1]))]
    # (not preferred, length, tie-break, i, vi, j, vj): each kind shortest first
    cols = chosen = None
    if prefer is None or isinstance(prefer, PreferCovered):
        # the candidates and, where the keyhole test is compiled too, the straight bridges in one
        # compiled call (:func:`_tree_kernel`)
        got = _candidate_columns(rings, pairs, owners, prefer, straight=(obstacles_a, obstacles_b, avoid, allowed),
                                 packed=packed)
        if got is not None:
            cols, chosen = got
            if cols is None:  # (the straight bridges join them all)
                return chosen
    if cols is None:
        parts = []  # per pair of rings: (not preferred, length, tie-break, i, vi, j, vj) as arrays
        for i, j in pairs:
            vi, vj, d, tie = _candidates(rings[i], rings[j], CANDIDATES)
            # preferred bridges between components first (``prefer`` asked of all the pairs at once)
            later = ~np.asarray(prefer(rings[i][vi], rings[j][vj]), dtype=bool) \
                if prefer is not None and owners[i][0] != owners[j][0] else np.zeros(len(vi), dtype=bool)
            parts.append((later, d, tie, np.full(len(vi), i), vi, np.full(len(vi), j), vj))
        cols = _candidate_arrays(parts)
    if chosen is None and (allowed is None or isinstance(allowed, _Coverage)):  # (compiled)
        chosen = _straight_bridges(rings, np.stack(cols[3:], axis=1), owners, obstacles_a, obstacles_b, avoid, allowed)
    elif chosen is None:
        chosen = _straight_bridges_reference(rings, _candidate_list(cols), owners, obstacles_a, obstacles_b, avoid,
                                             allowed)
    if len(chosen) == n - 1:
        return chosen
    parent = list(range(n))
    find = partial(_find, parent)
    used = set()
    segs = [tuple(map(np.asarray, s)) for s in (avoid or [])]
    for i, vi, j, vj in chosen:
        parent[find(i)] = find(j)
        used.update([(i, vi), (j, vj)])
        segs.append((rings[i][vi], rings[j][vj]))
    if waypoints is None:
        return None
    # no spanning tree of straight bridges: join what is left by polyline keyholes through the
    # material (nearest pairs of rings first)
    pairs_left = []
    for i, j in zip(cols[3].tolist(), cols[5].tolist()):
        if owners[i][0] == owners[j][0] and (i, j) not in pairs_left:
            pairs_left.append((i, j))
    progress = True
    while progress and len(chosen) < n - 1:
        progress = False
        for i, j in pairs_left:
            if find(i) == find(j):
                continue
            pts_c, allowed_c = waypoints(owners[i][0])
            got = keyhole_path(rings[i], rings[j], pts_c, step, obstacles_a, obstacles_b,
                               segs, allowed=allowed if allowed_c is None else allowed_c, used_i={v for r, v in used if r == i},
                               used_j={v for r, v in used if r == j})
            if got is None:
                continue
            vi, vj, pts = got
            parent[find(i)] = find(j)
            used.update([(i, vi), (j, vj)])
            chosen.append((i, vi, j, vj, pts))
            path = np.concatenate([rings[i][vi][None], pts, rings[j][vj][None]])
            segs.extend((path[t], path[t + 1]) for t in range(len(path) - 1))
            progress = True
            if len(chosen) == n - 1:
                return chosen
    return None


def _find(parent, x):
    """The root of ``x`` in the union-find forest ``parent`` (a list), halving the path."""
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


def _straight_bridges_reference(rings, cand, owners, obstacles_a, obstacles_b, avoid, allowed) -> list:
    """The straight bridges of :func:`bridge_tree`: the candidates ``cand`` (sorted tuples ``(.., ..,
    .., i, vi, j, vj)``) taken in order where they join two trees of the forest, leave both rings
    at vertices no other bridge ends at, keep clear (:func:`_clear`) and, through the material,
    pass ``allowed``; up to ``len(rings) - 1`` of them.  The reference of :func:`_straight_bridges`."""
    n = len(rings)
    parent = list(range(n))
    find = partial(_find, parent)
    used = set()
    chosen = []
    segs = [tuple(map(np.asarray, s)) for s in (avoid or [])]
    seg_arrays = None  # segs as arrays, made again after each new bridge
    obstacles_a = np.ascontiguousarray(obstacles_a, dtype=np.float64)
    obstacles_b = np.ascontiguousarray(obstacles_b, dtype=np.float64)
    for _, _, _, i, vi, j, vj in cand:
        if find(i) == find(j) or (i, vi) in used or (j, vj) in used:
            continue
        p, q = rings[i][vi], rings[j][vj]
        through_material = owners[i][0] == owners[j][0]
        if seg_arrays is None:
            seg_arrays = _segment_arrays(segs)
        if not _clear(p, q, rings[i], vi, rings[j], vj, obstacles_a, obstacles_b, seg_arrays, through_material):
            continue
        if through_material and allowed is not None and not allowed(p, q):
            continue
        parent[find(i)] = find(j)
        used.update([(i, vi), (j, vj)])
        chosen.append((i, vi, j, vj))
        segs.append((p, q))
        seg_arrays = None
        if len(chosen) == n - 1:
            break
    return chosen


def _straight_bridges(rings, c, owners, obstacles_a, obstacles_b, avoid, allowed) -> list:
    """:func:`_straight_bridges_reference` in compiled code (:func:`_straight_kernel`), for
    ``allowed`` None or a keyhole test of :func:`keyhole_uncovered`: the same bridges.  ``c``: the
    sorted candidates' ``(i, vi, j, vj)`` as rows of an int64 array."""
    n = len(rings)
    if not len(c):
        return []
    pts, off, lens = _packed_rings(rings)
    ids = {}
    comp = np.array([ids.setdefault(o[0], len(ids)) for o in owners], dtype=np.int64)
    sa, sb = _segment_arrays([tuple(map(np.asarray, s_)) for s_ in (avoid or [])])
    lab, cids, grid = _keyhole_test_arrays(allowed)
    got = _straight_kernel(np.ascontiguousarray(c, dtype=np.int64).reshape(-1, 4), pts, off, lens, comp, np.ascontiguousarray(obstacles_a, dtype=np.float64),
                           np.ascontiguousarray(obstacles_b, dtype=np.float64),
                           np.ascontiguousarray(sa, dtype=np.float64), np.ascontiguousarray(sb, dtype=np.float64),
                           lab, cids, *grid, allowed is not None, np.int64(n))
    return [tuple(row) for row in got.tolist()]


@njit(cache=True, nogil=True)
def _straight_kernel(c, pts, off, lens, comp, oa, ob, sa0, sb0, lab, cids, ox, oy, dx, dy, use_allowed, n):
    """:func:`_straight_bridges_reference`'s loop: candidates ``c`` (rows ``i, vi, j, vj``) over the
    rings ``pts[off[r]: off[r] + lens[r]]`` of components ``comp``; the keyhole test is
    :func:`_coverage_kernel` (no sample covered) where ``use_allowed``.  Returns the bridges."""
    parent = np.arange(n)
    used = np.zeros(pts.shape[0], np.bool_)
    out = np.empty((max(n - 1, 0), 4), np.int64)
    k = 0
    ns = sa0.shape[0]
    sa = np.empty((ns + n, 2))
    sb = np.empty((ns + n, 2))
    sa[:ns] = sa0
    sb[:ns] = sb0
    corners = np.empty((2, 3, 2))
    P1 = np.empty((1, 2))
    Q1 = np.empty((1, 2))
    for t in range(c.shape[0]):
        if k == n - 1:
            break
        i, vi, j, vj = c[t, 0], c[t, 1], c[t, 2], c[t, 3]
        if _root(parent, i) == _root(parent, j) or used[off[i] + vi] or used[off[j] + vj]:
            continue
        if not _straight_ok(i, vi, j, vj, pts, off, lens, comp, oa, ob, sa[:ns], sb[:ns], corners, P1, Q1,
                            lab, cids, ox, oy, dx, dy, use_allowed):
            continue
        parent[_root(parent, i)] = _root(parent, j)
        used[off[i] + vi] = True
        used[off[j] + vj] = True
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = i, vi, j, vj
        k += 1
        sa[ns, 0], sa[ns, 1] = pts[off[i] + vi, 0], pts[off[i] + vi, 1]
        sb[ns, 0], sb[ns, 1] = pts[off[j] + vj, 0], pts[off[j] + vj, 1]
        ns += 1
    return out[:k]


@njit(cache=True, nogil=True, inline="always")
def _straight_ok(i, vi, j, vj, pts, off, lens, comp, oa, ob, sa, sb, corners, P1, Q1, lab, cids, ox, oy, dx, dy,
                 use_allowed):  # pragma: no cover (compiled)
    """Whether the candidate from ring ``i``'s vertex ``vi`` to ring ``j``'s ``vj`` keeps clear
    (:func:`_clear_kernel`, the other bridges ``sa, sb``) and, through the material, passes the
    keyhole test where ``use_allowed``: :func:`_straight_bridges_reference`'s test of a candidate.
    ``corners``, ``P1``, ``Q1``: scratch arrays ((2, 3, 2), (1, 2), (1, 2)).  :func:`_tree_kernel`
    writes it out in its loop (inlined, the helper counted each of its array arguments in and out
    on every candidate tested)."""
    for e in range(2):
        r, v = (i, vi) if e == 0 else (j, vj)
        m = lens[r]
        for u in range(3):
            w = off[r] + (v - 1 + u) % m
            corners[e, u, 0] = pts[w, 0]
            corners[e, u, 1] = pts[w, 1]
    px, py = pts[off[i] + vi, 0], pts[off[i] + vi, 1]
    qx, qy = pts[off[j] + vj, 0], pts[off[j] + vj, 1]
    through = comp[i] == comp[j]
    if not _clear_kernel(px, py, qx, qy, corners, np.int64(1), np.int64(1), oa, ob, sa, sb, through):
        return False
    if through and use_allowed:
        P1[0, 0], P1[0, 1], Q1[0, 0], Q1[0, 1] = px, py, qx, qy
        count, _ = _coverage_kernel(P1, Q1, lab, cids, ox, oy, dx, dy)
        if count[0] != 0:
            return False
    return True


#: Largest number of waypoints a polyline keyhole search settles before it gives up.
KEYHOLE_MAX_NODES = 20000


#: The last few answers of :func:`keyhole_path` (``allowed`` None or an :class:`OverlapFree`
#: test), keyed by all that the search reads: a bridged join is built again with the same rings
#: and obstacles near them (a pass that restarts after a join fell back, a sectioned join tried
#: again), and its keyhole searches, a few of them long and failing, are the same.
_KEYHOLES_KEEP = 16
_KEYHOLES_SEEN = Recent(_KEYHOLES_KEEP)


def keyhole_path(ri, rj, waypoints, step, obstacles_a, obstacles_b, segs=(), *, allowed=None,
                 used_i=(), used_j=(), max_nodes=KEYHOLE_MAX_NODES):
    """:func:`_keyhole_path` (see there), remembering the answers of the last
    :data:`_KEYHOLES_KEEP` searches whose ``allowed`` is None or an :class:`OverlapFree` test.

    The key holds what the search reads, as bytes: the waypoints and the two rings (float64), the
    step, the obstacle edges whose box meets the box of those points grown by a step (the only
    ones it tests, in order; the search keeps those alone), the segments ``segs``, the overlap
    test's image, offset and grid, the used vertices and ``max_nodes``.  The same key gives the
    same search, hence the same answer (its points handed out as a fresh copy)."""
    if allowed is not None and type(allowed) is not OverlapFree:
        return _keyhole_path(ri, rj, waypoints, step, obstacles_a, obstacles_b, segs, allowed=allowed,
                             used_i=used_i, used_j=used_j, max_nodes=max_nodes)
    ri = np.asarray(ri, dtype=np.float64)
    rj = np.asarray(rj, dtype=np.float64)
    W = np.asarray(waypoints, dtype=np.float64).reshape(-1, 2)
    if len(W) == 0:
        return None
    oa, ob = _edges_near(np.concatenate([ri, rj, W]), step, obstacles_a, obstacles_b)
    segs = list(segs)
    sa, sb = _segment_arrays(segs)  # (as the search makes them)
    key = (ri.shape, ri.tobytes(), rj.shape, rj.tobytes(), W.shape, W.tobytes(), float(step),
           oa.shape, oa.tobytes(), ob.tobytes(), sa.shape, sa.tobytes(), sb.shape, sb.tobytes(),
           None if allowed is None else (allowed.over.shape, allowed.over.tobytes(), allowed.x0, allowed.y0,
                                         allowed.grid),
           frozenset(used_i), frozenset(used_j), int(max_nodes), _KEYHOLE_ASKS, type(step))
    got = _KEYHOLES_SEEN.get(key, MISSING)
    if got is MISSING:
        # (the obstacles near the points: the search keeps them all, the same edges in order)
        got = _keyhole_path(ri, rj, W, step, oa, ob, segs, allowed=allowed, used_i=used_i, used_j=used_j,
                            max_nodes=max_nodes, near=(oa, ob))
        if got is not None:
            pts = np.array(got[2], dtype=np.float64)
            pts.flags.writeable = False
            got = (got[0], got[1], pts)
        _KEYHOLES_SEEN.put(key, got)
    return None if got is None else (got[0], got[1], got[2].copy())


def _edges_near(points, step, obstacles_a, obstacles_b):
    """The obstacle edges (as two float64 arrays, in order) whose box meets the box of ``points``
    grown by ``step`` on every side: those :func:`_keyhole_path` tests.  In compiled code
    (:func:`_edges_near_kernel`)."""
    return _edges_near_kernel(np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2), float(step),
                              np.ascontiguousarray(obstacles_a, dtype=np.float64).reshape(-1, 2),
                              np.ascontiguousarray(obstacles_b, dtype=np.float64).reshape(-1, 2))


@njit(cache=True, nogil=True)
def _edges_near_kernel(points, step, oa, ob):  # pragma: no cover (compiled)
    """:func:`_edges_near` edge by edge, as numpy found them: ``lo, hi = points.min(axis=0) - step,
    points.max(axis=0) + step`` and the edges with ``np.maximum(a, b) >= lo`` and ``np.minimum(a, b)
    <= hi`` in both coordinates.  A NaN is taken on as numpy takes it: a NaN point leaves no edge,
    an edge with a NaN end is left out (its maximum and minimum are NaN); a zero's sign does not
    change a comparison."""
    m = oa.shape[0]
    keep = np.empty(m, np.int64)
    k = 0
    if points.shape[0] == 0:  # (numpy's min of nothing raises)
        raise ValueError("zero-size array to reduction operation minimum which has no identity")
    lo0, lo1, hi0, hi1 = np.inf, np.inf, -np.inf, -np.inf
    nan = False
    for t in range(points.shape[0]):
        x, y = points[t, 0], points[t, 1]
        if x != x or y != y:
            nan = True
            break
        lo0, hi0 = min(lo0, x), max(hi0, x)
        lo1, hi1 = min(lo1, y), max(hi1, y)
    if not nan:
        lo0, lo1, hi0, hi1 = lo0 - step, lo1 - step, hi0 + step, hi1 + step
        for e in range(m):
            ax, ay, bx, by = oa[e, 0], oa[e, 1], ob[e, 0], ob[e, 1]
            if ax != ax or ay != ay or bx != bx or by != by:
                continue
            if max(ax, bx) >= lo0 and min(ax, bx) <= hi0 and max(ay, by) >= lo1 and min(ay, by) <= hi1:
                keep[k] = e
                k += 1
    a = np.empty((k, 2))
    b = np.empty((k, 2))
    for t in range(k):
        a[t, 0], a[t, 1], b[t, 0], b[t, 1] = oa[keep[t], 0], oa[keep[t], 1], ob[keep[t], 0], ob[keep[t], 1]
    return a, b


def _keyhole_path(ri, rj, waypoints, step, obstacles_a, obstacles_b, segs=(), *, allowed=None,
                  used_i=(), used_j=(), max_nodes=KEYHOLE_MAX_NODES, near=None):
    """The shortest polyline keyhole from ring ``ri`` to ring ``rj`` through ``waypoints``, or None.

    Both rings bound the same material, which lies on their left (an outer ring counter-clockwise
    and its holes clockwise), and the keyhole runs through it: it leaves each end vertex into the
    material, each of its pieces keeps clear of every obstacle edge (the rings' own edges only
    meet it at its two ends) and of the segments ``segs``, and passes ``allowed``.  The search is
    A* over the graph of the waypoints (neighbours at most ``1.5 step`` apart) and the rings'
    vertices (joined to waypoints at most ``2.5 step`` away), each edge tested when it is first
    used; the path found is then straightened (each point joined to the farthest later one that
    keeps clear), so it bends only where the material does.  ``allowed`` is asked only of the
    part of a piece more than ``step`` from a ring's vertex (a polygon's vertex may lie a pixel
    off the pixels it bounds, in the part another slice covers).  Vertices in ``used_i`` / ``used_j``
    (ends of other bridges) are not used.

    Returns ``(vi, vj, points)``: the end vertices and the ``(m, 2)`` interior points, ``m >= 1``
    (a keyhole that straightens to one segment is returned with its nearest waypoint kept, since
    the straight bridges were tried first).

    ``near``, where given, is :func:`_edges_near` of the rings, the waypoints and the obstacles, as
    the caller already holds it (:func:`keyhole_path`, whose key it is): not filtered again.
    """
    import heapq

    from scipy.spatial import cKDTree

    ri = np.asarray(ri, dtype=np.float64)
    rj = np.asarray(rj, dtype=np.float64)
    W = np.asarray(waypoints, dtype=np.float64).reshape(-1, 2)
    if len(W) == 0:
        return None
    oa, ob = _edges_near(np.concatenate([ri, rj, W]), step, obstacles_a, obstacles_b) if near is None else near
    segs = _segment_arrays(list(segs))
    m, ni = len(W), len(ri)
    # nodes: waypoints [0, m), ri's vertices [m, m + ni), rj's vertices [m + ni, ...)
    P = np.concatenate([W, ri, rj])
    if (allowed is None or isinstance(allowed, OverlapFree)) and len(ri) and len(rj):
        # the search and the straightening in compiled code (the same path; -1: a distance too close
        # to a neighbourhood's radius to be sure of the k-d tree's answer, searched below)
        path = _keyhole_compiled(P, m, ri, rj, step, oa, ob, segs, allowed, used_i, used_j, max_nodes)
        if path is None:
            return None
        if not isinstance(path, int):
            return _keyhole_result(P, path, m, ni)

    def end(node):
        if node < m:
            return None
        return (ri, node - m) if node < m + ni else (rj, node - m - ni)

    def ok(u, v):
        p, q = P[u], P[v]
        if not _clear_ends(p, q, end(u), end(v), oa, ob, segs, left=True):
            return False
        if allowed is None:
            return True
        # a ring's vertex may lie up to a pixel off the pixels it bounds: ``allowed`` is asked of
        # the piece more than a step away from a ring's end
        d = float(np.hypot(*(q - p)))
        t0 = step / d if end(u) is not None else 0.0
        t1 = 1.0 - step / d if end(v) is not None else 1.0
        return t0 >= t1 or bool(allowed(p + t0 * (q - p), p + t1 * (q - p)))

    tw, tj = cKDTree(W), cKDTree(rj)
    bad_j = set(used_j)
    dist_j = tj.query(P)[0]  # the heuristic of every node at once (the same distances)

    def h(node):
        return float(dist_j[node])

    heap = []
    came = {}
    for v in range(ni):
        if v not in used_i:
            heapq.heappush(heap, (h(m + v), 0.0, m + v, -1))
    settled = 0
    goal = None
    while heap:
        _, g, u, frm = heapq.heappop(heap)
        if u in came:
            continue
        if frm >= 0 and not ok(frm, u):
            continue
        came[u] = frm
        if u >= m + ni:
            goal = u
            break
        settled += 1
        if settled > max_nodes:
            return None
        if u >= m:  # a vertex of ri: to the waypoints near it
            nbr = tw.query_ball_point(P[u], 2.5 * step)
        else:
            nbr = tw.query_ball_point(P[u], 1.5 * step)
            nbr = list(nbr) + [m + ni + v for v in tj.query_ball_point(P[u], 2.5 * step) if v not in bad_j]
        for v in nbr:
            if v not in came and v != u:
                gv = g + float(np.hypot(*(P[v] - P[u])))
                heapq.heappush(heap, (gv + h(v), gv, v, u))
    if goal is None:
        return None
    path = [goal]
    while came[path[-1]] >= 0:
        path.append(came[path[-1]])
    path = path[::-1]
    if len(path) < 3:  # pragma: no cover - ring to ring edges are not in the graph
        return None
    # straighten: from each point, the farthest later point that keeps clear (the last point of a
    # keyhole must stay a ring vertex and the first too; at least one waypoint stays)
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        for j in range(len(path) - 1, i, -1):
            if j == len(path) - 1 and i == 0:
                continue
            if j == i + 1 or ok(path[i], path[j]):
                out.append(path[j])
                i = j
                break
    return _keyhole_result(P, out, m, ni)


def _keyhole_result(P, out, m, ni):
    """:func:`keyhole_path`'s answer for the straightened path ``out`` (node numbers): None where
    two of its pieces meet other than at their common end."""
    pts = P[out[1:-1]]
    # the pieces of the path must not meet each other (only consecutive pieces, at their common end)
    full = P[out]
    for t in range(len(full) - 1):
        others = [u for u in range(len(full) - 1) if abs(u - t) > 1]
        if others and segments_cross(full[t], full[t + 1], full[others], full[[u + 1 for u in others]]).any():
            return None
    return out[0] - m, out[-1] - m - ni, pts


class OverlapFree:
    """The test ``ok(p, q)`` that a polyline keyhole's piece ``p q`` keeps out of the pixels set in
    ``over`` (a boolean image whose pixel ``(0, 0)`` is pixel ``(x0, y0)`` of the grid ``(ox, oy,
    dx, dy)``, which puts pixel ``(i, j)``'s centre at ``(ox + i dx, oy + j dy)``): the piece is
    sampled 8 times per pixel, its ends left out, each sample taken to its nearest pixel (halves
    up).  :func:`keyhole_path` runs it in compiled code (:func:`_overlap_free_kernel`)."""

    def __init__(self, over, x0, y0, grid):
        self.over = np.ascontiguousarray(over, dtype=np.bool_)
        self.x0, self.y0 = int(x0), int(y0)
        self.grid = tuple(float(g) for g in grid)

    def __call__(self, p, q) -> bool:
        ox, oy, dx, dy = self.grid
        over = self.over
        steps = max(2, int(np.ceil(8 * max(abs(q[0] - p[0]) / dx, abs(q[1] - p[1]) / dy))))
        t = np.arange(1, steps)[:, None] / steps
        pt = p + t * (q - p)
        ii = np.floor((pt[:, 0] - ox) / dx + 0.5).astype(np.int64) - self.x0  # halves up
        jj = np.floor((pt[:, 1] - oy) / dy + 0.5).astype(np.int64) - self.y0
        inside = (ii >= 0) & (jj >= 0) & (ii < over.shape[1]) & (jj < over.shape[0])
        return not over[jj[inside], ii[inside]].any()


@njit(cache=True, nogil=True)
def _overlap_free_kernel(px, py, qx, qy, over, x0, y0, ox, oy, dx, dy):
    """:meth:`OverlapFree.__call__` sample by sample (the same arithmetic)."""
    steps = max(2, int(np.ceil(8 * max(abs(qx - px) / dx, abs(qy - py) / dy))))
    ny, nx = over.shape
    for u in range(1, steps):
        t = u / steps
        i = np.int64(np.floor((px + t * (qx - px) - ox) / dx + 0.5)) - x0
        j = np.int64(np.floor((py + t * (qy - py) - oy) / dy + 0.5)) - y0
        if i >= 0 and j >= 0 and i < nx and j < ny and over[j, i]:
            return False
    return True


def _keyhole_compiled(P, m, ri, rj, step, oa, ob, segs, allowed, used_i, used_j, max_nodes):
    """:func:`keyhole_path`'s search and straightening by :func:`_keyhole_kernel`: the straightened
    path (a list of node numbers), None where there is none, or -1 where the Python search must
    decide (more than :data:`_KEYHOLE_ASKS` nodes whose distance to another lies within a hair of a
    neighbourhood's radius, whose neighbours the k-d tree gives)."""
    from scipy.spatial import cKDTree

    ni, nj = len(ri), len(rj)
    dist_j = np.ascontiguousarray(cKDTree(rj).query(P)[0], dtype=np.float64)  # (as the Python search)
    free_i = np.ones(ni, dtype=np.bool_)
    free_i[[v for v in used_i if 0 <= v < ni]] = False
    free_j = np.ones(nj, dtype=np.bool_)
    free_j[[v for v in used_j if 0 <= v < nj]] = False
    if allowed is None:
        over, x0, y0, grid, use = np.zeros((1, 1), dtype=np.bool_), 0, 0, (0.0, 0.0, 1.0, 1.0), False
    else:
        over, x0, y0, grid, use = allowed.over, allowed.x0, allowed.y0, allowed.grid, True
    sa, sb = segs
    # every coordinate and the step a multiple of 2^-10 below 2^15 (a pixel grid of power-of-two
    # spacing): the squared distances and radii are exact, and the k-d tree's answer is theirs
    Q = np.concatenate([np.asarray(P, dtype=np.float64).reshape(-1), [float(step)]]) * 1024.0
    exact = bool(np.all(Q == np.floor(Q)) and np.abs(Q).max() < 2.0 ** 25)
    args = (np.ascontiguousarray(P, dtype=np.float64), np.int64(m), np.int64(ni), float(step),
            np.ascontiguousarray(oa, dtype=np.float64), np.ascontiguousarray(ob, dtype=np.float64),
            np.ascontiguousarray(sa, dtype=np.float64), np.ascontiguousarray(sb, dtype=np.float64), free_i, free_j,
            dist_j, over, np.int64(x0), np.int64(y0), *grid, use, np.int64(max_nodes), exact)
    # the nodes whose neighbours the k-d tree gave (a distance within a hair of a radius), as the
    # Python search asks it
    asked = {}
    ov_at = np.full(len(P), -1, dtype=np.int64)
    ov_ptr, ov_idx = np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    tw = tj = None
    for _ in range(_KEYHOLE_ASKS):
        status, path = _keyhole_kernel(*args, ov_at, ov_ptr, ov_idx)
        if status >= 0:
            return path.tolist() if status == 1 else None
        u = int(path[0])
        if tw is None:
            tw, tj = cKDTree(P[:m]), cKDTree(rj)
        if u >= m:
            nbr = tw.query_ball_point(P[u], 2.5 * step)
        else:
            bad_j = set(used_j)
            nbr = list(tw.query_ball_point(P[u], 1.5 * step)) + \
                [m + ni + v for v in tj.query_ball_point(P[u], 2.5 * step) if v not in bad_j]
        asked[u] = nbr
        ov_at[:] = -1
        ov_at[list(asked)] = np.arange(len(asked))
        ov_ptr = np.concatenate([[0], np.cumsum([len(v) for v in asked.values()])]).astype(np.int64)
        ov_idx = np.array([v for vs in asked.values() for v in vs], dtype=np.int64)
    return -1


#: How many nodes' neighbourhoods the compiled keyhole search asks the k-d tree for before it hands
#: the search to Python.
_KEYHOLE_ASKS = 16


@njit(cache=True, nogil=True, _nrt=False)
def _keyhole_ok(P, u, v, m, ni, step, oa, ob, sa, sb, over, x0, y0, ox, oy, dx, dy, use, corners):
    """``ok(u, v)`` of :func:`keyhole_path`: the piece between nodes ``u`` and ``v`` keeps clear
    (:func:`_clear_kernel`, leaving the rings on their left) and, more than a step from a ring's
    vertex, passes the overlap test where ``use``.  It allocates nothing, and is compiled without
    reference counting (``_nrt=False``): its calls of the two kernels then pass their arrays
    without counting them in and out, once per piece the search tests."""
    has0, has1 = np.int64(0), np.int64(0)  # (scalars, not an array made on every call)
    for t in range(2):
        node = u if t == 0 else v
        if node >= m:
            if node < m + ni:
                o, n_r = m, ni
            else:
                o, n_r = m + ni, P.shape[0] - m - ni
            w = node - o
            for c in range(3):
                x = o + (w - 1 + c) % n_r  # (r[v - 1] wraps to the ring's last vertex)
                corners[t, c, 0] = P[x, 0]
                corners[t, c, 1] = P[x, 1]
            if t == 0:
                has0 = np.int64(1)
            else:
                has1 = np.int64(1)
    px, py, qx, qy = P[u, 0], P[u, 1], P[v, 0], P[v, 1]
    if not _clear_kernel(px, py, qx, qy, corners, has0, has1, oa, ob, sa, sb, np.bool_(True)):
        return False
    if not use:
        return True
    d = np.hypot(qx - px, qy - py)
    t0 = step / d if has0 else 0.0
    t1 = 1.0 - step / d if has1 else 1.0
    if t0 >= t1:
        return True
    return _overlap_free_kernel(px + t0 * (qx - px), py + t0 * (qy - py), px + t1 * (qx - px), py + t1 * (qy - py),
                                over, x0, y0, ox, oy, dx, dy)


@njit(cache=True, nogil=True)
def _keyhole_kernel(P, m, ni, step, oa, ob, sa, sb, free_i, free_j, dist_j, over, x0, y0, ox, oy, dx, dy, use,
                    max_nodes, exact, ov_at, ov_ptr, ov_idx):
    """The A* search of :func:`keyhole_path` and the straightening of its path.  The heap holds the
    Python search's tuples ``(g + h, g, node, from)`` and pops them in the same order (all are
    distinct, so the order is that of the tuples).  The neighbours are the nodes within the radii
    of the k-d tree queries (squared distances against the squared radius); unless the distances
    are ``exact`` (see :func:`_keyhole_compiled`), where one lies within a relative ``1e-9`` of the
    radius, ``(-1, [u])``: the caller asks the k-d tree for node ``u``'s neighbours and searches
    again with them (``ov_at[u]``: their row in ``ov_ptr`` / ``ov_idx``, or -1).  Returns ``(1,
    path)``, or ``(0, ..)`` where there is no path (or the search settles more than
    ``max_nodes`` nodes).

    The heap's comparisons and swaps are written out where they are made: as inlined helpers
    taking the heap's four arrays, they counted each array in and out on every comparison."""
    n = P.shape[0]
    corners = np.zeros((2, 3, 2))
    came = np.full(n, -2, np.int64)
    cap = 64 + ni
    hf = np.empty(cap)
    hg = np.empty(cap)
    hv = np.empty(cap, np.int64)
    hu = np.empty(cap, np.int64)
    size = 0
    r_w, r_v = 1.5 * step, 2.5 * step
    r_w2, r_v2 = r_w * r_w, r_v * r_v
    none = np.zeros(0, np.int64)
    nb = np.empty(n, np.int64)
    # the first pushes: every free vertex of ri, from nowhere
    for v in range(ni):
        if free_i[v]:
            hf[size], hg[size], hv[size], hu[size] = dist_j[m + v], 0.0, m + v, -1
            size += 1
            c = size - 1  # (sift up)
            while c > 0:
                p = (c - 1) // 2
                if hf[c] != hf[p]:
                    less = hf[c] < hf[p]
                elif hg[c] != hg[p]:
                    less = hg[c] < hg[p]
                elif hv[c] != hv[p]:
                    less = hv[c] < hv[p]
                else:
                    less = hu[c] < hu[p]
                if not less:
                    break
                hf[c], hf[p] = hf[p], hf[c]
                hg[c], hg[p] = hg[p], hg[c]
                hv[c], hv[p] = hv[p], hv[c]
                hu[c], hu[p] = hu[p], hu[c]
                c = p
    settled = 0
    goal = -1
    while size > 0:
        # pop the smallest
        g, u, frm = hg[0], hv[0], hu[0]
        size -= 1
        hf[0], hg[0], hv[0], hu[0] = hf[size], hg[size], hv[size], hu[size]
        c = 0
        while True:  # (sift down)
            a, b, s_ = 2 * c + 1, 2 * c + 2, c
            for w in (a, b):
                if w < size:
                    if hf[w] != hf[s_]:
                        less = hf[w] < hf[s_]
                    elif hg[w] != hg[s_]:
                        less = hg[w] < hg[s_]
                    elif hv[w] != hv[s_]:
                        less = hv[w] < hv[s_]
                    else:
                        less = hu[w] < hu[s_]
                    if less:
                        s_ = w
            if s_ == c:
                break
            hf[c], hf[s_] = hf[s_], hf[c]
            hg[c], hg[s_] = hg[s_], hg[c]
            hv[c], hv[s_] = hv[s_], hv[c]
            hu[c], hu[s_] = hu[s_], hu[c]
            c = s_
        if came[u] != -2:
            continue
        if frm >= 0 and not _keyhole_ok(P, frm, u, m, ni, step, oa, ob, sa, sb, over, x0, y0, ox, oy, dx, dy, use,
                                        corners):
            continue
        came[u] = frm
        if u >= m + ni:
            goal = u
            break
        settled += 1
        if settled > max_nodes:
            return 0, none
        # the neighbours: waypoints within 2.5 steps of a vertex of ri, within 1.5 steps of a
        # waypoint, and the free vertices of rj within 2.5 steps of a waypoint (or the k-d tree's
        # answer for u, where the caller found it)
        n_nb = 0
        if ov_at[u] >= 0:
            for t in range(ov_ptr[ov_at[u]], ov_ptr[ov_at[u] + 1]):
                nb[n_nb] = ov_idx[t]
                n_nb += 1
        else:
            hi_v = m if u >= m else n
            for v in range(hi_v):
                if m <= v < m + ni:
                    continue
                if v >= m + ni and not free_j[v - m - ni]:
                    continue
                ddx = P[v, 0] - P[u, 0]
                ddy = P[v, 1] - P[u, 1]
                d2 = ddx * ddx + ddy * ddy
                r2 = r_w2 if (u < m and v < m) else r_v2
                if not exact and abs(d2 - r2) <= 1e-9 * r2:
                    ask = np.empty(1, np.int64)
                    ask[0] = u
                    return -1, ask
                if d2 <= r2:
                    nb[n_nb] = v
                    n_nb += 1
        for t in range(n_nb):
            v = nb[t]
            if came[v] != -2 or v == u:
                continue
            gv = g + np.hypot(P[v, 0] - P[u, 0], P[v, 1] - P[u, 1])
            if size == cap:
                cap *= 2
                hf2 = np.empty(cap)
                hg2 = np.empty(cap)
                hv2 = np.empty(cap, np.int64)
                hu2 = np.empty(cap, np.int64)
                for t2 in range(size):  # (element by element: slice assignment compiles slowly)
                    hf2[t2], hg2[t2], hv2[t2], hu2[t2] = hf[t2], hg[t2], hv[t2], hu[t2]
                hf, hg, hv, hu = hf2, hg2, hv2, hu2
            hf[size], hg[size], hv[size], hu[size] = gv + dist_j[v], gv, v, u
            size += 1
            c = size - 1  # (sift up)
            while c > 0:
                p = (c - 1) // 2
                if hf[c] != hf[p]:
                    less = hf[c] < hf[p]
                elif hg[c] != hg[p]:
                    less = hg[c] < hg[p]
                elif hv[c] != hv[p]:
                    less = hv[c] < hv[p]
                else:
                    less = hu[c] < hu[p]
                if not less:
                    break
                hf[c], hf[p] = hf[p], hf[c]
                hg[c], hg[p] = hg[p], hg[c]
                hv[c], hv[p] = hv[p], hv[c]
                hu[c], hu[p] = hu[p], hu[c]
                c = p
    if goal < 0:
        return 0, none
    L = 1
    x = goal
    while came[x] >= 0:
        x = came[x]
        L += 1
    path = np.empty(L, np.int64)
    x = goal
    for t in range(L - 1, -1, -1):
        path[t] = x
        x = came[x]
    if L < 3:
        return 0, none
    # straighten: from each point, the farthest later point that keeps clear
    out = np.empty(L, np.int64)
    out[0] = path[0]
    k = 1
    i = 0
    while i < L - 1:
        for j in range(L - 1, i, -1):
            if j == L - 1 and i == 0:
                continue
            if j == i + 1 or _keyhole_ok(P, path[i], path[j], m, ni, step, oa, ob, sa, sb, over, x0, y0, ox, oy,
                                         dx, dy, use, corners):
                out[k] = path[j]
                k += 1
                i = j
                break
    return 1, out[:k]


def _clear(p, q, ri, vi, rj, vj, oa, ob, segs, left=False) -> bool:
    """The open segment p q meets no obstacle edge and no other segment; at its ends it meets only
    the two ring edges there, and leaves each ring on its right (``left``: on its left)."""
    return _clear_ends(p, q, (ri, vi), (rj, vj), oa, ob, segs, left)


_NO_SEGMENTS = np.zeros((0, 2))


def _segment_arrays(segs):
    """``segs`` (a list of ``(p, q)`` pairs, or already a pair of ``(k, 2)`` arrays) as two
    contiguous float64 arrays."""
    if isinstance(segs, tuple) and len(segs) == 2 and isinstance(segs[0], np.ndarray) and segs[0].ndim == 2:
        return segs
    if not len(segs):
        return _NO_SEGMENTS, _NO_SEGMENTS
    return (np.array([s[0] for s in segs], dtype=np.float64).reshape(-1, 2),
            np.array([s[1] for s in segs], dtype=np.float64).reshape(-1, 2))


def _clear_ends(p, q, end_p, end_q, oa, ob, segs, left=False) -> bool:
    """:func:`_clear` where either end may be a free point (``None``) instead of a ring vertex
    ``(ring, vertex)``: a free end touches nothing at all.  ``segs``: a list of ``(p, q)`` pairs
    or a pair of arrays (:func:`_segment_arrays`).  Compiled (:func:`_clear_kernel`;
    :func:`_clear_ends_reference` is the reference it is tested against)."""
    corners = np.zeros((2, 3, 2))
    has = [0, 0]
    for t, e in enumerate((end_p, end_q)):
        if e is not None:
            r, v = e
            corners[t, 0] = r[v - 1]
            corners[t, 1] = r[v]
            corners[t, 2] = r[(v + 1) % len(r)]
            has[t] = 1
    sa, sb = _segment_arrays(segs)
    return bool(_clear_kernel(float(p[0]), float(p[1]), float(q[0]), float(q[1]), corners, has[0], has[1],
                              np.ascontiguousarray(oa, dtype=np.float64), np.ascontiguousarray(ob, dtype=np.float64),
                              sa, sb, bool(left)))


@njit(cache=True, nogil=True, inline="always")
def _same_point(ax, ay, bx, by):
    return ax == bx and ay == by


@njit(cache=True, nogil=True)
def _clear_kernel(px, py, qx, qy, corners, has_p, has_q, oa, ob, sa, sb, left):
    """:func:`_clear_ends_reference` compiled: ``corners[t]`` the previous, own and next vertex of
    end ``t`` (p, q) on its ring where ``has_p`` / ``has_q``; ``sa, sb`` the other segments."""
    if px == qx and py == qy:
        return False
    lox, hix = min(px, qx), max(px, qx)
    loy, hiy = min(py, qy), max(py, qy)
    has = (has_p, has_q)
    # leave each ring outward: the direction must not lie inside the ring's interior angle (tested
    # first: it reads the two corners only, and a candidate it refuses needs no scan of the edges)
    for t in range(2):
        if has[t] == 0:
            continue
        if t == 0:
            dx, dy = qx - px, qy - py
        else:
            dx, dy = px - qx, py - qy
        a0, a1 = corners[t, 0, 0], corners[t, 0, 1]
        c0, c1 = corners[t, 1, 0], corners[t, 1, 1]
        b0, b1 = corners[t, 2, 0], corners[t, 2, 1]
        if left:  # the left of a ring is the right of the reversed ring
            a0, a1, b0, b1 = b0, b1, a0, a1
        if not _outside_corner_k(a0, a1, c0, c1, b0, b1, dx, dy):
            return False
    for e in range(oa.shape[0]):
        ax, ay, bx, by = oa[e, 0], oa[e, 1], ob[e, 0], ob[e, 1]
        if not (max(ax, bx) >= lox and min(ax, bx) <= hix and max(ay, by) >= loy and min(ay, by) <= hiy):
            continue
        # the edges incident to p and q may touch the segment only at p and q
        incident = False
        for t in range(2):
            if has[t] == 0:
                continue
            for u in range(2):  # the edges (prev, v) and (v, next)
                sx, sy = corners[t, u, 0], corners[t, u, 1]
                tx, ty = corners[t, u + 1, 0], corners[t, u + 1, 1]
                if (_same_point(ax, ay, sx, sy) and _same_point(bx, by, tx, ty)) or \
                        (_same_point(ax, ay, tx, ty) and _same_point(bx, by, sx, sy)):
                    incident = True
        if incident:
            continue
        if _cross1(px, py, qx, qy, ax, ay, bx, by):
            return False
        # another edge may pass through p or q only as one of the incident edges
        if _same_point(ax, ay, px, py) or _same_point(bx, by, px, py) or _same_point(ax, ay, qx, qy) \
                or _same_point(bx, by, qx, qy):
            return False
    for e in range(sa.shape[0]):
        if _cross1(px, py, qx, qy, sa[e, 0], sa[e, 1], sb[e, 0], sb[e, 1]):
            return False
    return True


@njit(cache=True, nogil=True, inline="always")
def _outside_corner_k(a0, a1, c0, c1, b0, b1, d0, d1):
    """:func:`_outside_corner` on scalars (the same arithmetic)."""
    u0, u1 = a0 - c0, a1 - c1
    w0, w1 = b0 - c0, b1 - c1
    cross_wu = w0 * u1 - w1 * u0
    s_w = w0 * d1 - w1 * d0
    s_u = u0 * d1 - u1 * d0
    if cross_wu > 0:
        inside = s_w >= 0 and s_u <= 0
    elif cross_wu < 0:
        inside = not ((s_w < 0) and (s_u > 0))
    else:
        inside = s_w >= 0
    return not inside


def _clear_ends_reference(p, q, end_p, end_q, oa, ob, segs, left=False) -> bool:
    """:func:`_clear_ends` in numpy (the reference of the compiled kernel, for the tests)."""
    if p[0] == q[0] and p[1] == q[1]:
        return False
    # the edges incident to p and q may touch the segment only at p and q
    inc = []
    for e in (end_p, end_q):
        if e is not None:
            r, v = e
            inc += [(r[v - 1], r[v]), (r[v], r[(v + 1) % len(r)])]
    lo = np.minimum(p, q)
    hi = np.maximum(p, q)
    near = np.flatnonzero((np.maximum(oa[:, 0], ob[:, 0]) >= lo[0]) & (np.minimum(oa[:, 0], ob[:, 0]) <= hi[0])
                          & (np.maximum(oa[:, 1], ob[:, 1]) >= lo[1]) & (np.minimum(oa[:, 1], ob[:, 1]) <= hi[1]))
    na, nb = oa[near], ob[near]
    keep = np.ones(len(near), dtype=bool)
    for s, t in inc:
        keep &= ~(((na == s).all(axis=1) & (nb == t).all(axis=1)) | ((na == t).all(axis=1) & (nb == s).all(axis=1)))
    if _segments_cross_reference(p, q, na[keep], nb[keep]).any():
        return False
    # another edge may pass through p or q only as one of the incident edges (a ring touching
    # itself there has two more): refuse those vertices (such edges lie in the box: p, q are its corners)
    for v in (p, q):
        if (keep & (((na == v).all(axis=1)) | ((nb == v).all(axis=1)))).any():
            return False
    # leave each ring outward: the direction must not lie inside the ring's interior angle
    for e, d in ((end_p, q - p), (end_q, p - q)):
        if e is None:
            continue
        r, v = e
        a, c, b = r[v - 1], r[v], r[(v + 1) % len(r)]
        if left:  # the left of a ring is the right of the reversed ring
            a, b = b, a
        if not _outside_corner(a, c, b, d):
            return False
    if segs:
        sa = np.array([s[0] for s in segs], dtype=np.float64)
        sb = np.array([s[1] for s in segs], dtype=np.float64)
        if _segments_cross_reference(p, q, sa, sb).any():
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


def bridged_ring_arrays(lengths, bridges, root: int = 0):
    """:func:`bridged_ring` as two int64 arrays ``(ring, vertex)``: the same sequence.  Compiled
    (:func:`_tour_kernel`) where every contour has a vertex and no two bridge ends share a ring's
    vertex (as :func:`bridge_tree` makes them); else :func:`_bridged_ring_arrays_py`."""
    n = len(lengths)
    lens = np.asarray(lengths, dtype=np.int64).reshape(-1)
    br = np.array([tuple(b[:4]) + (len(b[4]) if len(b) > 4 else 0,) for b in bridges], dtype=np.int64).reshape(-1, 5)
    if n and lens.min() > 0 and 0 <= root < n:
        rr, vv, ok = _tour_kernel(lens, br, np.int64(root))
        if ok:
            return rr, vv
    return _bridged_ring_arrays_py(lengths, bridges, root)


def bridged_ring_ids(lengths, bridges, first, root: int = 0):
    """The vertex ids of the bridged ring's tour (:func:`bridged_ring_arrays`' ``(ring, vertex)``
    pairs) where each table of ids, ring ``r``'s and then each bridge's interior points', is a run of
    consecutive ids from ``first[t]`` (``first[len(lengths) + b]`` for bridge ``b``): ``first[ring] +
    vertex``, int64.  Tour and ids in one compiled call (:func:`_tour_ids_kernel`) where
    :func:`bridged_ring_arrays` takes its compiled tour; else its Python tour, then the same sums."""
    n = len(lengths)
    if n and min(lengths) > 0 and 0 <= root < n:
        br = np.array([tuple(b[:4]) + (len(b[4]) if len(b) > 4 else 0,) for b in bridges],
                      dtype=np.int64).reshape(-1, 5)
        ids, ok = _tour_ids_kernel(np.array(lengths, dtype=np.int64), br, np.int64(root),
                                   np.array(first, dtype=np.int64))
        if ok:
            return ids
    rr, vv = _bridged_ring_arrays_py(lengths, bridges, root)
    return np.array(first, dtype=np.int64)[rr] + vv


@njit(cache=True, nogil=True)
def _tour_ids_kernel(lengths, br, root, first):  # pragma: no cover (compiled)
    """:func:`_tour_kernel` and each tour entry's id ``first[ring] + vertex`` in one call: the ids
    (int64, the sums numpy's ``first[rr] + vv`` gives) and the tour kernel's flag."""
    rr, vv, ok = _tour_kernel(lengths, br, root)
    ids = np.empty(rr.shape[0], np.int64)
    for t in range(rr.shape[0]):
        ids[t] = first[rr[t]] + vv[t]
    return ids, ok


@njit(cache=True, nogil=True)
def _tour_kernel(lengths, br, root):
    """:func:`_bridged_ring_arrays_py`'s tour without recursion: ``br`` holds the bridges' rows ``(i,
    vi, j, vj, points)``.  Returns ``(rings, vertices, 1)``, or ``(.., .., 0)`` where two bridge ends
    share a ring's vertex or a bridge end is not a vertex of its ring (the caller then takes the
    Python tour)."""
    n = lengths.shape[0]
    nb = br.shape[0]
    rr = np.empty(0, np.int64)
    vv = np.empty(0, np.int64)
    off = np.zeros(n + 1, np.int64)
    for r in range(n):
        off[r + 1] = off[r] + lengths[r]
    # per ring vertex: the bridge end there (2 b for the end (i, vi), 2 b + 1 for (j, vj)), or -1
    end_at = np.full(off[n], -1, np.int64)
    for b in range(nb):
        for s in range(2):
            r, v = br[b, 2 * s], br[b, 2 * s + 1]
            if r < 0 or r >= n or v < 0 or v >= lengths[r] or end_at[off[r] + v] >= 0:
                return rr, vv, 0
            end_at[off[r] + v] = 2 * b + s
    # the bridges must form a forest (then each ring is entered once at most, and the frames and
    # the output below are large enough); else the Python tour (which would not end either)
    parent = np.arange(n)
    for b in range(nb):
        a, c = _root(parent, br[b, 0]), _root(parent, br[b, 2])
        if a == c:
            return rr, vv, 0
        parent[a] = c
    n_hooks = np.zeros(n, np.int64)
    total = off[n] + n
    for b in range(nb):
        total += 2 * br[b, 4] + 1
    rr = np.empty(total, np.int64)
    vv = np.empty(total, np.int64)
    k = 0
    # each frame: ring, entry vertex, parent ring, closing, the next hook to follow and the first
    # vertex not yet emitted, the bridge end it was entered by (-1: the root)
    fr = np.empty(n, np.int64)
    fe = np.empty(n, np.int64)
    fp = np.empty(n, np.int64)
    fc = np.empty(n, np.int64)
    fh = np.empty(n, np.int64)
    ft = np.empty(n, np.int64)
    fin = np.empty(n, np.int64)
    hooks = np.empty(off[n], np.int64)  # each entered ring's hooks to follow, at off[ring]
    start = 0
    for v in range(lengths[root]):
        if end_at[off[root] + v] < 0:
            start = v
            break
    fr[0], fe[0], fp[0], fc[0], fin[0] = root, start, -1, 0, -1
    fh[0], ft[0] = -1, 0
    sp = 1
    while sp > 0:
        d = sp - 1
        r, e, m = fr[d], fe[d], lengths[fr[d]]
        if fh[d] < 0:
            # entering the ring: its hooks to rings other than the parent, in the order of the walk
            # from e (the distance (v - e) mod m, distinct for distinct vertices)
            cnt = 0
            o = off[r]
            for v in range(m):
                x = end_at[o + (e + v) % m]
                if x >= 0:
                    other = br[x // 2, 2 * (1 - x % 2)]
                    if other != fp[d]:
                        hooks[o + cnt] = (e + v) % m
                        cnt += 1
            n_hooks[r] = cnt
            fh[d] = 0
        if fh[d] < n_hooks[r]:
            v = hooks[off[r] + fh[d]]
            t = (v - e) % m
            for u in range(ft[d], t + 1):
                rr[k], vv[k] = r, (e + u) % m
                k += 1
            x = end_at[off[r] + v]
            b, s = x // 2, x % 2
            pts = br[b, 4]
            for u in range(pts):
                rr[k], vv[k] = n + b, u if s == 0 else pts - 1 - u
                k += 1
            fh[d] += 1
            ft[d] = t + 1
            c = sp
            fr[c], fe[c], fp[c], fc[c], fin[c] = br[b, 2 * (1 - s)], br[b, 2 * (1 - s) + 1], r, 1, x
            fh[c], ft[c] = -1, 0
            sp += 1
            continue
        for u in range(ft[d], m + fc[d]):
            rr[k], vv[k] = r, (e + u) % m
            k += 1
        sp -= 1
        x = fin[d]
        if x >= 0:  # back along the bridge it was entered by, to the parent's vertex
            b, s = x // 2, x % 2
            pts = br[b, 4]
            for u in range(pts):
                rr[k], vv[k] = n + b, pts - 1 - u if s == 0 else u
                k += 1
            rr[k], vv[k] = br[b, 2 * s], br[b, 2 * s + 1]
            k += 1
    return rr[:k], vv[:k], 1


def _bridged_ring_arrays_py(lengths, bridges, root: int = 0):
    """:func:`bridged_ring_arrays` in Python, each run of a contour between two bridge ends emitted
    as one range instead of vertex by vertex (the reference of :func:`_tour_kernel`)."""
    n = len(lengths)
    at = {}
    hooks = [[] for _ in range(n)]  # per ring, the vertices where bridges leave it
    for b, br in enumerate(bridges):
        i, vi, j, vj = br[:4]
        m = len(br[4]) if len(br) > 4 else 0
        at[(i, vi)] = (j, vj, n + b, np.arange(m, dtype=np.int64))
        at[(j, vj)] = (i, vi, n + b, np.arange(m - 1, -1, -1, dtype=np.int64))
        hooks[i].append(vi)
        hooks[j].append(vj)
    rr, vv = [], []

    def emit(r, verts):
        rr.append(np.full(len(verts), r, dtype=np.int64))
        vv.append(verts)

    def tour(r, e, parent, closing):
        m = lengths[r]
        # the bridges to other rings than the parent, in the order the walk from e meets them
        here = sorted(((v - e) % m, v) for v in hooks[r] if at[(r, v)][0] != parent)
        t0 = 0
        for t, v in here:
            emit(r, (e + np.arange(t0, t + 1, dtype=np.int64)) % m)
            other = at[(r, v)]
            emit(other[2], other[3])
            tour(other[0], other[1], r, True)
            emit(other[2], other[3][::-1])
            emit(r, np.array([v], dtype=np.int64))
            t0 = t + 1
        emit(r, (e + np.arange(t0, m + (1 if closing else 0), dtype=np.int64)) % m)

    seen_start = next((v for v in range(lengths[root]) if (root, v) not in at), 0)
    try:
        tour(root, seen_start, -1, False)
    finally:
        # (tour calls itself through its own closure cell: a reference cycle, which would leave
        # this call's lists to the cyclic garbage collector; clearing the cell frees them now)
        tour = None
    return np.concatenate(rr), np.concatenate(vv)


def bridged_ring(lengths, bridges, root: int = 0):
    """The vertex sequence ``[(ring, vertex), ...]`` of the ring that runs round every contour and
    along every bridge once each way (an Euler tour of the bridge tree), starting on ``root``.

    The interior points of a polyline bridge ``b`` (a fifth entry, see :func:`bridge_tree`) appear
    as ``(len(lengths) + b, t)``, ``t`` counted from the bridge's ``i`` end: once on the way out
    and once, in reverse, on the way back."""
    n = len(lengths)
    at = {}
    adj = [[] for _ in range(n)]
    for b, br in enumerate(bridges):
        i, vi, j, vj = br[:4]
        m = len(br[4]) if len(br) > 4 else 0
        at[(i, vi)] = (j, vj, [(n + b, t) for t in range(m)])
        at[(j, vj)] = (i, vi, [(n + b, t) for t in range(m - 1, -1, -1)])
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
                out.extend(other[2])
                tour(other[0], other[1], r, True)
                out.extend(other[2][::-1])
                out.append((r, v))

    seen_start = next((v for v in range(lengths[root]) if (root, v) not in at), 0)
    tour(root, seen_start, -1, False)
    return out


def warm_rare_paths() -> None:
    """Compiles (or loads) the kernels of two paths that small volumes rarely take, for the warm-ups
    (``scripts/warm_kernels.py``, the comparison runner): a polyline keyhole's compiled search (a
    square hole in a square ring, waypoints on the pixels between them, one pixel kept out) and
    :func:`bridge_tree`'s Python candidate loop (the one the compiled search hands back to), with a
    preference over a label image."""
    outer = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 6.0], [0.0, 6.0]])
    hole = np.array([[2.0, 2.0], [2.0, 4.0], [4.0, 4.0], [4.0, 2.0]])
    pts = np.array([(x + 0.5, y + 0.5) for x in range(6) for y in range(6) if not (2 <= x < 4 and 2 <= y < 4)])
    edges = np.concatenate([hole, outer])
    keyhole_path(hole, outer, pts, 1.0, edges, np.concatenate([np.roll(hole, -1, axis=0), np.roll(outer, -1, axis=0)]),
                 allowed=OverlapFree(np.eye(6, dtype=bool), 0, 0, (0.5, 0.5, 1.0, 1.0)))
    cover = keyhole_uncovered(np.eye(8, dtype=np.uint8), [0], (0.0, 0.0, 1.0, 1.0))
    bridge_tree([outer[::-1] + 8.0, outer[::-1]], edges, edges[::-1], allowed=cover,
                prefer=lambda P, Q: cover.shares(P, Q) >= 0.5)
