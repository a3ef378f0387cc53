"""Band triangulations between consecutive polygons, and flat caps.

One signature for every strategy: ``triangulate(lower, upper) -> faces``, where ``lower`` is an
``(n, 3)`` closed polygon at height ``z1``, ``upper`` an ``(m, 3)`` one at ``z2 > z1`` (same
orientation convention), and ``faces`` an ``(n + m, 3)`` int64 array indexing
``np.vstack([lower, upper])`` that uses every polygon edge exactly once, with outward normals.

Strategies (registry :data:`TRIANGULATORS`):

``"wiederhold"``
    Wiederhold & Villafuerte (2009), section 3.4: coordinate comparisons, ``O(n + m)``.
``"greedy"``
    Christiansen & Sederberg (1978): shortest next diagonal, ``O(n + m)``.
``"optimal"``
    Fuchs, Kedem & Uselton (1977): least total area by dynamic programming, ``O(n m log n)``
    (start points searched by strips; ``O(n^2 m)`` where that search cannot certify its answer).
``"arclength"``
    Ganapathy & Dennehy (1982): advance in proportion to normalized arc length, ``O(n + m)``;
    never folds, the robust reference of the volume mesher's twist guard.

Folded bands.  On very dissimilar pairs (and between a polygon and a segment-shaped MLP next to
a pole) the local rules of ``wiederhold`` and ``greedy`` can join all the edges of one contour
to a single point of the other ("double cone"): every polygon edge is still used once, but one
diagonal then carries four triangles and the mesh is not a manifold.  :func:`triangulate_band`
detects this and, with ``fallback=True`` (the default), returns the ``optimal`` band for that
pair instead, whose search excludes such bands.
"""

from __future__ import annotations

import numpy as np

from .._kernels import njit
from .._recent import Recent
from ..intersect import _PAIR_SEEN, _STAR_DELAY, _any_steps, _canonical_kernel, any_intersecting, canonical_vertices
from ..measure import triangle_areas
from .arclength import triangulate_band_arclength
from .caps import cap_faces
from .greedy import triangulate_band_greedy
from .optimal import triangulate_band_optimal
from .wiederhold import triangulate_band_wiederhold

__all__ = [
    "twist_guarded_band",
    "TRIANGULATORS",
    "triangulate_band",
    "band_is_folded",
    "triangulate_band_wiederhold",
    "triangulate_band_greedy",
    "triangulate_band_optimal",
    "cap_faces",
]

#: Band triangulators by name; each maps ``(lower, upper)`` to ``faces``.
TRIANGULATORS = {
    "wiederhold": triangulate_band_wiederhold,
    "greedy": triangulate_band_greedy,
    "optimal": triangulate_band_optimal,
    "arclength": triangulate_band_arclength,
}


def band_is_folded(faces: np.ndarray) -> bool:
    """True when some edge of the band is shared by more than two of its triangles."""
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return False
    return bool(_folded(np.ascontiguousarray(f).reshape(-1, 3)))


@njit(cache=True)
def _folded(f):
    """:func:`band_is_folded` compiled: the undirected edges ``(lo, hi)`` of the faces bucketed by
    ``lo`` (a counting sort), each bucket's ``hi`` counted in a table; some edge is in more than two
    faces when a count reaches three.  Where the vertex numbers are not small next to the number
    of edges (a band's faces in a join's numbering), :func:`_folded_sorted` (the same answer)."""
    nf = f.shape[0]
    ne = 3 * nf
    base = f.max() + 1
    if f.min() < 0 or base > 2 * ne + 64:
        return _folded_sorted(f)
    start = np.zeros(base + 1, np.int64)
    for k in range(3):
        for t in range(nf):
            a, b = f[t, k], f[t, (k + 1) % 3]
            start[min(a, b) + 1] += 1
    for v in range(base):
        start[v + 1] += start[v]
    pos = start[:base].copy()
    his = np.empty(ne, np.int64)
    for k in range(3):
        for t in range(nf):
            a, b = f[t, k], f[t, (k + 1) % 3]
            lo = min(a, b)
            his[pos[lo]] = max(a, b)
            pos[lo] += 1
    cnt = np.zeros(base, np.int8)
    for v in range(base):
        for q in range(start[v], start[v + 1]):
            h = his[q]
            cnt[h] += 1
            if cnt[h] == 3:
                return True
        for q in range(start[v], start[v + 1]):
            cnt[his[q]] = 0
    return False


@njit(cache=True)
def _folded_sorted(f):
    """:func:`_folded` by sorting: one integer ``lo * (max + 1) + hi`` per undirected edge of
    each face, sorted; some edge is in more than two faces when a key equals the one two places
    before it."""
    nf = f.shape[0]
    base = f.max() + 1
    key = np.empty(3 * nf, dtype=np.int64)
    for k in range(3):
        for t in range(nf):
            a, b = f[t, k], f[t, (k + 1) % 3]
            key[k * nf + t] = min(a, b) * base + max(a, b)
    key.sort()
    for q in range(2, len(key)):
        if key[q] == key[q - 2]:
            return True
    return False


def triangulate_band(lower, upper, method: str = "wiederhold", *, fallback: bool = True) -> np.ndarray:
    """Triangulate the band between two consecutive polygons with the named strategy.

    Parameters
    ----------
    lower : array_like, shape (n, 3)
        Closed polygon at height ``z1``.
    upper : array_like, shape (m, 3)
        Closed polygon at height ``z2 > z1``, same orientation convention as ``lower``.
    method : {"wiederhold", "greedy", "optimal"}
        Strategy name (see :data:`TRIANGULATORS`).
    fallback : bool
        Replace a folded band (see the module docstring) by the ``optimal`` one.

    Returns
    -------
    faces : ndarray of int64, shape (n + m, 3)
        Triangles indexing ``np.vstack([lower, upper])``.

    Raises
    ------
    ValueError
        For an unknown method or invalid polygons.
    """
    try:
        fn = TRIANGULATORS[method]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown band triangulation method {method!r}; expected one of "
            f"{sorted(TRIANGULATORS)}"
        ) from None
    faces = fn(lower, upper)
    if fallback and method != "optimal" and band_is_folded(faces):
        faces = triangulate_band_optimal(lower, upper)
    return faces


def twist_guarded_band(lo: np.ndarray, hi: np.ndarray, triangulation: str,
                       optimal_budget: float = 3e7) -> tuple[np.ndarray, bool]:
    """The band of ``triangulation`` between two rings, and whether the twist guard replaced it.

    A band of the local rules (``wiederhold``, ``greedy``) whose area exceeds ``1.25`` times that
    of the arc-length band for the same pair is twisted; it is replaced by the optimal band, or by
    the arc-length band where the optimal one would be too slow (``n^2 m`` above
    ``optimal_budget``, ``n <= m`` the two rings' sizes).
    """

    f = triangulate_band(lo, hi, triangulation)
    if triangulation in ("wiederhold", "greedy") and min(len(lo), len(hi)) > 2:
        P = np.concatenate([lo, hi])
        ref_f = triangulate_band(lo, hi, "arclength")
        n, m = sorted((len(lo), len(hi)))
        if triangle_areas(P, f).sum() > 1.25 * triangle_areas(P, ref_f).sum():
            return (triangulate_band(lo, hi, "optimal") if n * n * m <= optimal_budget else ref_f), True
        if _band_crosses(P, f):  # a twist the area test misses: the first embedded alternative
            # (rings that touch themselves are left to the mesher's repair, which splits them)
            others = (["optimal"] if n * n * m <= optimal_budget else []) + ["arclength"]
            for method in others:
                g = ref_f if method == "arclength" else triangulate_band(lo, hi, method)
                if not _band_crosses(P, g):
                    return g, True
    return f, False


#: The last few answers of :func:`_band_crosses`, keyed by the bytes of its two arrays: the volume
#: mesher's bridged joins test the band that :func:`contourmesh.volumes._band_faces` has just tested
#: (the same rings and faces: about a quarter of the liver's crossing tests were such repeats).
_CROSSES_KEEP = 16
_CROSSES_SEEN = Recent(_CROSSES_KEEP)


def _band_crosses(P, f) -> bool:
    """True when two faces of one band cross or touch other than as neighbours (exact test).

    A ring that touches itself (a pinch: one position visited twice) is split later by the
    mesher, each copy moved a hair into its own fan; here each copy of a repeated position is
    moved the same way (a hair towards the middle of its two ring neighbours, in its plane), so
    the test sees the band as it will be, not the shared point.

    The answer depends on the two arrays only: a repeated call (equal bytes, shapes and dtypes)
    takes the remembered answer of one of the last :data:`_CROSSES_KEEP` calls."""
    P = np.asarray(P)
    f = np.asarray(f)
    key = (P.shape, P.dtype.str, P.tobytes(), f.shape, f.dtype.str, f.tobytes())
    got = _CROSSES_SEEN.get(key)
    if got is None:
        got = _band_crosses_uncached(P, f)
        _CROSSES_SEEN.put(key, got)
    return got


def _band_crosses_uncached(P, f) -> bool:
    """:func:`_band_crosses` without the memory of recent calls.  The pinches are found and split
    in one compiled call (:func:`_pinch_split`) where the points are finite; else, and in the
    tests, :func:`_band_crosses_reference`."""
    Pc = np.ascontiguousarray(P, dtype=np.float64)
    fc = np.ascontiguousarray(f, dtype=np.int64)
    if Pc.ndim == 2 and Pc.shape[1] == 3 and len(Pc) and fc.ndim == 2 and fc.shape[1] == 3:
        if len(fc) >= 2 and 3 * len(fc) >= len(Pc) and Pc.flags.writeable and fc.flags.writeable:
            got = _band_any(Pc, fc, np.int64(_STAR_DELAY), _PAIR_SEEN)
            if got >= 0:
                return bool(got)
        Q, status = _pinch_split(Pc, fc)
        if status == 2:
            return False
        if status != 3:
            return any_intersecting(Q, f)
    return _band_crosses_reference(P, f)


@njit(cache=True, nogil=True)
def _band_any(P, f, delay, mem):  # pragma: no cover (compiled)
    """:func:`_band_crosses_uncached`'s answer in one compiled call, where it can give it: 1 or 0,
    or -1 where the caller takes the steps one by one (a point not finite, a face index out of
    range, magnitudes out of the exact predicates' range).  The pinches split by
    :func:`_pinch_split`, then the crossing test of :func:`contourmesh.intersect.any_intersecting`'s
    kernel on the points so moved, told that no two of them share a position (:func:`_pinch_split`
    has just found so: every point is its own canonical point, so the faces are used as they are,
    without the table of equal points built again).  The same answer: the mesher's band tests
    (liver, lobster) spent about a fifth of their time in the set-up of the two calls."""
    Q, status = _pinch_split(P, f)
    if status == 2:
        return np.int64(0)
    if status == 3:
        return np.int64(-1)
    return _any_steps(Q, f, delay, np.int64(1), np.int64(1), mem)


@njit(cache=True, nogil=True)
def _pinch_split(P, f):  # pragma: no cover (compiled)
    """The steps of :func:`_band_crosses_reference` before its crossing test, in one pass:
    ``(Q, status)``, status 0 where no position is repeated (``Q`` is ``P``), 1 where the repeated
    ones were moved (``Q`` a moved copy, :func:`_split_pinches`), 2 where they cannot be (the band
    is taken not to cross), 3 where ``P`` has a NaN or an infinity (nothing done: the caller takes
    the reference, whose grouping of NaN points and extent of infinite ones differ).  Repeated positions as :func:`canonical_vertices`
    finds them (its compiled table), the extent as ``np.ptp`` over x and y, the moves by
    :func:`_pinch_moves`."""
    n = P.shape[0]
    for i in range(n):
        for d in range(3):
            if not np.isfinite(P[i, d]):
                return P, 3
    canon = _canonical_kernel((P + 0.0).view(np.uint64))  # (-0.0 + 0.0 == +0.0)
    cnt = np.zeros(n, np.int64)
    for i in range(n):
        cnt[canon[i]] += 1
    nd = 0
    for i in range(n):
        if cnt[canon[i]] > 1:
            nd += 1
    if nd == 0:
        return P, 0
    dup = np.empty(nd, np.int64)
    nd = 0
    for i in range(n):
        if cnt[canon[i]] > 1:
            dup[nd] = i
            nd += 1
    Q = P.copy()
    ext = 0.0
    for d in range(2):
        lo = Q[0, d]
        hi = Q[0, d]
        for i in range(1, n):
            lo = min(lo, Q[i, d])
            hi = max(hi, Q[i, d])
        ext = max(ext, hi - lo)
    if not ext > 0:
        return Q, 2
    if not _pinch_moves(Q, f, dup, ext):
        return Q, 2
    canon = _canonical_kernel((Q + 0.0).view(np.uint64))
    for i in range(n):
        if canon[i] != i:  # two points still at one position
            return Q, 2
    return Q, 1


def _band_crosses_reference(P, f) -> bool:
    """:func:`_band_crosses_uncached` step by step (its NaN route, and the tests' reference)."""
    canon = canonical_vertices(P)  # (as np.unique(P, axis=0), hashed: the same groups)
    dup = np.flatnonzero(np.bincount(canon, minlength=len(P))[canon] > 1)
    if len(dup):
        P = _split_pinches(P, f, dup)
        if P is None:
            return False
    return any_intersecting(P, f)


def _split_pinches(P, f, dup):
    """``P`` with every point in ``dup`` moved a hair towards the centroid of its faces in ``f``
    (as :func:`contourmesh.repair.split_nonmanifold_vertices` does), or None where that does not
    separate the copies.

    Compiled (:func:`_pinch_moves`): each face's centroid is numpy's mean of its corners (added in
    order, divided by three), each point's sum of its faces' centroids is added in the order
    ``np.add.at`` over the three corners would add them (corner 0 of every face, then 1, then 2),
    and each move is the loop's arithmetic (tests/test_compiled_repair.py holds that loop)."""
    P = np.array(P, dtype=np.float64)
    ext = float(np.ptp(P[:, :2], axis=0).max()) if len(P) else 0.0
    if not ext > 0:
        return None
    f = np.ascontiguousarray(f, dtype=np.int64).reshape(-1, 3)
    if not _pinch_moves(P, f, np.ascontiguousarray(dup, dtype=np.int64).reshape(-1), ext):
        return None
    canon = canonical_vertices(P)
    if (canon != np.arange(len(P))).any():  # two points still at one position
        return None
    return P


@njit(cache=True, nogil=True)
def _pinch_moves(P, f, dup, ext):
    """:func:`_split_pinches`' moves of the points ``dup`` of ``P`` (in place); False where one
    cannot move (no face, or its faces' centroid on it)."""
    nf = f.shape[0]
    cen = np.empty((nf, 3))
    for t in range(nf):
        for d in range(3):
            cen[t, d] = (P[f[t, 0], d] + P[f[t, 1], d] + P[f[t, 2], d]) / 3.0
    acc = np.zeros((P.shape[0], 3))
    deg = np.zeros(P.shape[0], np.int64)
    for d in range(3):
        for c in range(3):
            for t in range(nf):
                acc[f[t, c], d] += cen[t, d]
    for c in range(3):
        for t in range(nf):
            deg[f[t, c]] += 1
    for u in range(dup.shape[0]):
        if deg[dup[u]] == 0:
            return False
    step = 1e-4 * ext
    for u in range(dup.shape[0]):
        i = dup[u]
        dx = acc[i, 0] / deg[i] - P[i, 0]
        dy = acc[i, 1] / deg[i] - P[i, 1]
        n = np.hypot(dx, dy)
        if not n > 0:
            return False
        s = step / n
        P[i, 0] = P[i, 0] + dx * s
        P[i, 1] = P[i, 1] + dy * s
        P[i, 2] = P[i, 2] + 0.0 * s  # (the move has no z part: -0.0 becomes 0.0, as in numpy)
    return True
