"""Mesh repair: make a closed triangle surface edge- and vertex-manifold.

Where two voxels (or two contours) touch only along an edge or at a corner, the surface built
around them has edges shared by four faces and vertices whose faces form several fans.  The
functions here split such edges and vertices, one copy per fan, and move each copy a small step
(``nudge``, in the units of the input) into its own fan, so the result is a 2-manifold with the
same faces.  Used by the volume mesher and the stack mesher alike; mesh in, mesh out.
"""

from __future__ import annotations

import sys

import numpy as np

from ._kernels import njit
from .intersect import _any_kernel, any_intersecting, intersecting_pairs

__all__ = ["split_nonmanifold_vertices", "resolve_crossings", "crossing_pairs_after_change"]


def _split_four_face_edges(V, F, side, nudge, overwrite: bool = False):
    """Replace every edge shared by four faces by two edges through side-specific midpoints.

    Such an edge joins a voxel of one slice and a voxel of the next that touch only along it;
    the two faces of each side are split at a midpoint of their own, which is then moved
    ``nudge`` into its side, so the two sheets no longer share the edge.

    The new vertices and faces are numbered in the order the edges and their faces are visited:
    the faces of an edge in the iteration order of a Python set of face numbers kept per edge
    (the form before, kept in ``tests/test_compiled_repair.py``, where every edge of the faces involved has one).
    Only the four-face edges' sets are ever read, and a face's split replaces its four-face edge
    and keeps its two other edges, so here only the four-face edges have sets, each receiving the
    same additions and removals in the same order: the same iteration orders, the same mesh.
    The loop handles integers alone, compiled (:func:`_split_faces`, which keeps each set as
    CPython's table of it: the same iteration orders; the Python loop, :func:`_split_faces_py`, where
    it reports a fault); the new vertices' coordinates are made after it, in a few whole-array
    steps (:func:`_midpoints`).  ``overwrite``: ``F`` and ``side`` are the caller's own, with no
    views of them, and may become the results (:func:`_kept_and_added`).
    """
    m = len(F)
    Fc = np.ascontiguousarray(F, dtype=np.int64)
    threads = _edge_threads(Fc)
    odd, most, work, fw_hit = _four_face_edges(Fc, len(V)) if threads < 2 else _four_face_edges_threads(Fc, len(V), threads)
    del Fc
    if odd:
        raise RuntimeError(f"internal error: an edge is shared by {int(odd)} faces")
    if most > 4:
        raise RuntimeError(f"internal error: an edge is shared by {int(most)} faces")
    if not len(work):
        return V, F, side
    Fw = np.ascontiguousarray(F[work], dtype=np.int64)
    # an edge u < v as the int u * base + v (every vertex, old or new, is below base)
    base = len(V) + 2 * len(work) + 1  # (at most two new vertices per four-face edge, 3/4 of one per face)
    done = False
    if _COMPILED_SET_ORDER:
        done, added, added_sides, made = _split_faces(Fw, np.ascontiguousarray(side[work], dtype=np.int64), work,
                                                      fw_hit, np.int64(m), np.int64(len(V)), np.int64(base))
    if not done:  # (the loop names the fault, if there is one)
        added, added_sides, made = _split_faces_py(Fw, side[work], work, fw_hit, m, len(V), base)
    # (made: per new vertex o0, o1, u, v)
    made = made[:, [2, 3, 0, 1]]
    newV = _midpoints(V, np.ascontiguousarray(made), nudge)
    keep = np.ones(m, dtype=bool)
    keep[work] = False
    F2, S2 = _kept_and_added(F, side, keep, added, added_sides, overwrite)
    V2 = np.concatenate([V, newV])
    return V2, F2, S2


def _split_faces_py(Fw, sw, work, fw_hit, m, nv, base):
    """The splitting loop of :func:`_split_four_face_edges` in Python, on the faces ``Fw`` (numbers
    ``work``, sides ``sw``) with their four-face edges ``fw_hit``: ``(added, added_sides, made)``,
    the faces made and left (``(k, 3)`` int64, in the order a dict of the live faces keeps them)
    with their sides, and per new vertex ``(o0, o1, u, v)``.  The form :func:`_split_faces`
    replaces; it runs where that one reports a fault (and raises the error that names it) or where
    Python's sets are not CPython's."""
    # the faces as slots of flat lists of ints (the work faces in order, then the new ones; ints
    # and flat lists: few objects for the collector to count, as lists and tuples per face were),
    # ``slot`` the live faces' (face number -> slot, in insertion order as the reference's dict)
    fa, fb, fc = Fw[:, 0].tolist(), Fw[:, 1].tolist(), Fw[:, 2].tolist()
    fside = np.asarray(sw).tolist()
    slot = dict(zip(work.tolist(), range(len(work))))
    # the four-face edges' sets, filled as the reference fills them: faces in order, edges in order
    lo_w = np.minimum(Fw, np.roll(Fw, -1, axis=1))
    hi_w = np.maximum(Fw, np.roll(Fw, -1, axis=1))
    rows, ts = np.nonzero(fw_hit)
    by_edge: dict = {}
    for i, key in zip(work[rows].tolist(), (lo_w[rows, ts] * base + hi_w[rows, ts]).tolist()):
        by_edge.setdefault(key, set()).add(i)
    del lo_w, hi_w, rows, ts
    get = by_edge.get
    # the faces first, in integers alone: each new vertex recorded as (u, v, o0, o1), the edge it
    # splits and the opposite corners of its two faces; their coordinates after (_midpoints)
    made = []
    nxt_v = nv
    nxt_f = m
    for key in sorted(by_edge):  # (the edges (u, v) in order)
        u, v = divmod(key, base)
        fs = list(by_edge[key])
        if len(fs) != 4:
            raise RuntimeError(f"internal error: edge ({u}, {v}) is shared by {len(fs)} faces while splitting")
        # the faces by side, the sides in order of first appearance (as the reference's dict)
        s0 = fside[slot[fs[0]]]
        pair0 = [i for i in fs if fside[slot[i]] == s0]
        pair1 = [i for i in fs if fside[slot[i]] != s0]
        if len(pair0) != 2 or len({fside[slot[i]] for i in pair1}) != 1:
            raise RuntimeError("internal error: a four-face edge does not pair by side")
        for group in (pair0, pair1):
            sd = fside[slot[group[0]]]
            for i in group:
                q = slot[i]
                made.append([w for w in (fa[q], fb[q], fc[q]) if w != u and w != v][0])
            made.append(u)
            made.append(v)
            mv = nxt_v
            nxt_v += 1
            for i in group:
                q = slot.pop(i)
                f0, f1, f2 = fa[q], fb[q], fc[q]
                for x, y in ((f0, f1), (f1, f2), (f2, f0)):
                    st = get(x * base + y if x < y else y * base + x)
                    if st is not None:
                        st.discard(i)
                # (the corner where the split edge starts)
                if (f0 == u and f1 == v) or (f0 == v and f1 == u):
                    a, b, c = f0, f1, f2
                elif (f1 == u and f2 == v) or (f1 == v and f2 == u):
                    a, b, c = f1, f2, f0
                else:
                    a, b, c = f2, f0, f1
                # the new faces' edges through mv are new; (c, a) and (b, c) may be four-face edges
                for x, y, z, p, q in ((a, mv, c, c, a), (mv, b, c, b, c)):
                    slot[nxt_f] = len(fa)
                    fa.append(x)
                    fb.append(y)
                    fc.append(z)
                    fside.append(sd)
                    st = get(p * base + q if p < q else q * base + p)
                    if st is not None:
                        st.add(nxt_f)
                    nxt_f += 1
    del by_edge
    live = np.fromiter(slot.values(), dtype=np.int64, count=len(slot))  # (the live faces' slots, in order)
    added = np.stack([np.array(fa, dtype=np.int64)[live], np.array(fb, dtype=np.int64)[live],
                      np.array(fc, dtype=np.int64)[live]], axis=1)
    return added, np.array(fside, dtype=np.int64)[live], np.array(made, dtype=np.int64).reshape(-1, 4)


#: Whether :func:`_split_faces` may stand for the Python loop: it keeps each set of face numbers
#: as CPython keeps a set of ints (``Objects/setobject.c``: an int's hash is its value, a small
#: table of 8 slots, probing, dummies, resizing), so its iteration orders are CPython's.
_COMPILED_SET_ORDER = sys.implementation.name == "cpython"

# CPython's set tables: a lookup tries the slot ``hash & mask`` and, where they fit in the table,
# the ``_LINEAR_PROBES`` slots after it, then jumps to ``(i * 5 + 1 + perturb) & mask`` with
# ``perturb`` (at first the hash) shifted right by ``_PERTURB_SHIFT``; a table grows when its
# used and dummy slots reach 3/5 of it.  ``_SET_CAP``: the largest table kept here (a set of
# four faces, a few of them replaced, needs 32 slots at most; a larger one is reported).
_LINEAR_PROBES = 9
_PERTURB_SHIFT = 5
_SET_CAP = 32
_SET_NULL = -2  # (an empty slot; -1 a dummy, one emptied by a removal; >= 0 a face number)
_SET_DUMMY = -1


@njit(cache=True, nogil=True, inline="always")
def _set_insert_clean(tk, tq, s, mask, key, q):
    """CPython's ``set_insert_clean``: ``key`` (with its slot ``q``) into the first empty slot
    of table ``s`` along its probe sequence (a table being rebuilt: no dummies, no equal key)."""
    i = key & mask
    perturb = key
    while True:
        if tk[s, i] == _SET_NULL:
            tk[s, i] = key
            tq[s, i] = q
            return
        if i + _LINEAR_PROBES <= mask:
            for j in range(i + 1, i + _LINEAR_PROBES + 1):
                if tk[s, j] == _SET_NULL:
                    tk[s, j] = key
                    tq[s, j] = q
                    return
        perturb >>= _PERTURB_SHIFT
        i = (i * 5 + 1 + perturb) & mask


@njit(cache=True, nogil=True, _nrt=False)
def _set_add(tk, tq, meta, s, key, q, old_k, old_q):
    """CPython's ``set_add_entry`` for the int ``key`` (its own hash) on table ``s`` (``tk[s]``
    its slots, ``tq[s]`` the face slot beside each key, ``meta[s]`` its mask, fill and used
    counts): a key met on the probe sequence is kept; else the key goes into the last dummy slot
    passed before the first empty one, or into that empty one, and then the table is rebuilt
    (``set_table_resize``, ``old_k`` and ``old_q`` scratch) where its filled slots reach 3/5.
    False where the table would grow beyond ``_SET_CAP`` (nothing then to rely on).  Compiled
    without reference counts (it makes no array): a call then neither counts its five arrays in
    nor out (the lobster's splits, replayed, 2.5 -> 2.2 ms CPU)."""
    mask = meta[s, 0]
    i = key & mask
    perturb = key
    free = -1
    j = -1
    while j < 0:
        probes = _LINEAR_PROBES if i + _LINEAR_PROBES <= mask else 0
        e = i
        while True:
            k = tk[s, e]
            if k == _SET_NULL:
                j = e
                break
            if k == key:
                return True
            if k == _SET_DUMMY:
                free = e
            e += 1
            if probes == 0:
                break
            probes -= 1
        if j < 0:
            perturb >>= _PERTURB_SHIFT
            i = (i * 5 + 1 + perturb) & mask
    if free >= 0:
        tk[s, free] = key
        tq[s, free] = q
        meta[s, 2] += 1
        return True
    tk[s, j] = key
    tq[s, j] = q
    meta[s, 1] += 1
    meta[s, 2] += 1
    if meta[s, 1] * 5 < mask * 3:
        return True
    used = meta[s, 2]
    minused = used * 2 if used > 50000 else used * 4
    size = 8
    while size <= minused:
        size <<= 1
    if size > _SET_CAP:
        return False
    if size == 8 and mask == 7 and meta[s, 1] == used:  # (the small table without dummies stays)
        return True
    for e in range(mask + 1):
        old_k[e] = tk[s, e]
        old_q[e] = tq[s, e]
        tk[s, e] = _SET_NULL
    meta[s, 0] = size - 1
    meta[s, 1] = used
    for e in range(mask + 1):
        if old_k[e] >= 0:
            _set_insert_clean(tk, tq, s, size - 1, old_k[e], old_q[e])
    return True


@njit(cache=True, nogil=True, inline="always")
def _set_discard(tk, meta, s, key):
    """CPython's ``set_discard_entry`` for the int ``key`` on table ``s``: its slot, if the probe
    sequence meets it before an empty slot, becomes a dummy."""
    mask = meta[s, 0]
    i = key & mask
    perturb = key
    while True:
        probes = _LINEAR_PROBES if i + _LINEAR_PROBES <= mask else 0
        e = i
        while True:
            k = tk[s, e]
            if k == _SET_NULL:
                return
            if k == key:
                tk[s, e] = _SET_DUMMY
                meta[s, 2] -= 1
                return
            e += 1
            if probes == 0:
                break
            probes -= 1
        perturb >>= _PERTURB_SHIFT
        i = (i * 5 + 1 + perturb) & mask


@njit(cache=True, nogil=True, _nrt=False)
def _edge_set(ekeys, x, y, base):
    """The set of the edge ``(x, y)`` (its key's index in the sorted ``ekeys``), -1 if it has none.
    A plain call without reference counts: inlined into :func:`_split_faces`, which allocates,
    ``ekeys`` was counted in and out on each call (2.2 -> 2.15 ms on the lobster's splits)."""
    key = x * base + y if x < y else y * base + x
    lo = 0
    hi = ekeys.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if ekeys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    if lo < ekeys.shape[0] and ekeys[lo] == key:
        return lo
    return -1


@njit(cache=True, nogil=True)
def _split_faces(Fw, sw, work, hit, m, nv, base):
    """:func:`_split_faces_py` compiled: ``(done, added, added_sides, made)``, the same three
    arrays where ``done``; not done (nothing to rely on) where the loop would raise (an edge
    whose set does not hold four faces of two sides in pairs) or a set's table would outgrow
    ``_SET_CAP``.  Each four-face edge's set of face numbers is kept as CPython's table of that
    set (:func:`_set_add`, :func:`_set_discard`), filled, emptied and read in the loop's order,
    so its faces come in the order the loop's ``list(set)`` gives them; a face's slot (its place
    in the lists of faces) rides beside its number in the table."""
    nw = Fw.shape[0]
    nh = 0
    for r in range(nw):
        for t in range(3):
            nh += hit[r, t]
    hk = np.empty(nh, np.int64)
    at = 0
    for r in range(nw):
        for t in range(3):
            if hit[r, t]:
                x = Fw[r, t]
                y = Fw[r, (t + 1) % 3]
                hk[at] = x * base + y if x < y else y * base + x
                at += 1
    srt = np.sort(hk)
    ne = 0
    for a in range(nh):
        if a == 0 or srt[a] != srt[a - 1]:
            srt[ne] = srt[a]
            ne += 1
    ekeys = srt[:ne]  # (the four-face edges' keys, increasing: the loop's order)
    tk = np.full((ne, _SET_CAP), _SET_NULL, np.int64)
    tq = np.empty((ne, _SET_CAP), np.int64)
    meta = np.zeros((ne, 3), np.int64)  # (per set: mask, fill, used)
    for s in range(ne):
        meta[s, 0] = 7
    old_k = np.empty(_SET_CAP, np.int64)
    old_q = np.empty(_SET_CAP, np.int64)
    cap = nw + 8 * ne  # (two new faces per face of a four-face edge)
    fa = np.empty(cap, np.int64)
    fb = np.empty(cap, np.int64)
    fc = np.empty(cap, np.int64)
    fs = np.empty(cap, np.int64)
    alive = np.zeros(cap, np.bool_)
    empty = np.zeros((0, 3), np.int64)
    for r in range(nw):
        fa[r] = Fw[r, 0]
        fb[r] = Fw[r, 1]
        fc[r] = Fw[r, 2]
        fs[r] = sw[r]
        alive[r] = True
    for r in range(nw):  # (faces in order, edges in order)
        for t in range(3):
            if hit[r, t]:
                s = _edge_set(ekeys, Fw[r, t], Fw[r, (t + 1) % 3], base)
                if not _set_add(tk, tq, meta, s, work[r], r, old_k, old_q):
                    return False, empty, fs[:0], empty
    made = np.empty((2 * ne, 4), np.int64)
    nm = 0
    nslots = nw
    nxt_v = nv
    nxt_f = m
    fk = np.empty(4, np.int64)  # (the edge's faces in the set's order: numbers and slots)
    fq = np.empty(4, np.int64)
    grp = np.empty(4, np.int64)  # (the two faces of the first face's side, then the other two)
    for e in range(ne):
        u = ekeys[e] // base
        v = ekeys[e] % base
        cnt = 0
        for j in range(meta[e, 0] + 1):
            k = tk[e, j]
            if k >= 0:
                if cnt < 4:
                    fk[cnt] = k
                    fq[cnt] = tq[e, j]
                cnt += 1
        if cnt != 4:
            return False, empty, fs[:0], empty
        s0 = fs[fq[0]]
        n0 = 0
        for i in range(4):
            if fs[fq[i]] == s0:
                grp[n0] = i
                n0 += 1
        if n0 != 2:
            return False, empty, fs[:0], empty
        n1 = 2
        for i in range(4):
            if fs[fq[i]] != s0:
                grp[n1] = i
                n1 += 1
        if fs[fq[grp[2]]] != fs[fq[grp[3]]]:
            return False, empty, fs[:0], empty
        for g in range(2):
            sd = fs[fq[grp[2 * g]]]
            for h in range(2):  # (each face's first corner off the edge)
                q = fq[grp[2 * g + h]]
                if fa[q] != u and fa[q] != v:
                    made[nm, h] = fa[q]
                elif fb[q] != u and fb[q] != v:
                    made[nm, h] = fb[q]
                elif fc[q] != u and fc[q] != v:
                    made[nm, h] = fc[q]
                else:
                    return False, empty, fs[:0], empty
            made[nm, 2] = u
            made[nm, 3] = v
            nm += 1
            mv = nxt_v
            nxt_v += 1
            for h in range(2):
                i = fk[grp[2 * g + h]]
                q = fq[grp[2 * g + h]]
                if not alive[q]:
                    return False, empty, fs[:0], empty
                alive[q] = False
                f0 = fa[q]
                f1 = fb[q]
                f2 = fc[q]
                for x, y in ((f0, f1), (f1, f2), (f2, f0)):
                    s = _edge_set(ekeys, x, y, base)
                    if s >= 0:
                        _set_discard(tk, meta, s, i)
                if (f0 == u and f1 == v) or (f0 == v and f1 == u):
                    a, b, c = f0, f1, f2
                elif (f1 == u and f2 == v) or (f1 == v and f2 == u):
                    a, b, c = f1, f2, f0
                else:
                    a, b, c = f2, f0, f1
                for x, y, z, p, w in ((a, mv, c, c, a), (mv, b, c, b, c)):
                    fa[nslots] = x
                    fb[nslots] = y
                    fc[nslots] = z
                    fs[nslots] = sd
                    alive[nslots] = True
                    s = _edge_set(ekeys, p, w, base)
                    if s >= 0:
                        if not _set_add(tk, tq, meta, s, nxt_f, nslots, old_k, old_q):
                            return False, empty, fs[:0], empty
                    nslots += 1
                    nxt_f += 1
    k = 0
    for q in range(nslots):
        k += alive[q]
    added = np.empty((k, 3), np.int64)
    sides = np.empty(k, np.int64)
    at = 0
    for q in range(nslots):  # (the live faces by slot: the order of the loop's dict)
        if alive[q]:
            added[at, 0] = fa[q]
            added[at, 1] = fb[q]
            added[at, 2] = fc[q]
            sides[at] = fs[q]
            at += 1
    return True, added, sides, made[:nm]


@njit(cache=True, nogil=True)
def _four_face_edges(F, nv):
    """``(odd, most, rows, hit)``: the first odd count of faces on an edge in row order (0 if
    none), the largest such count, the faces with an edge shared by four (increasing) and, per
    such face, which of its edges are; found without the counts of every edge: the half-edges
    bucketed by their lower vertex with their upper vertex alone (no half-edge numbers), each
    bucket counted in three short passes (upper vertices counted in a scratch array, read back,
    cleared), the largest count kept and the buckets with a count other than two marked; then the
    faces are read in order and only the half-edges of marked buckets counted again in their
    bucket (:func:`_marked_counts`): every other edge is in two faces, so the first odd count, the
    faces with an edge in four and which edges those are come out as the counts of every edge give them."""
    m = F.shape[0]
    start = np.zeros(nv + 2, np.int64)  # (counted at v + 2; each bucket's fill pointer at v + 1)
    for i in range(m):
        for k in range(3):
            start[min(F[i, k], F[i, (k + 1) % 3]) + 2] += 1
    for v in range(nv):
        start[v + 2] += start[v + 1]
    upper = np.empty(3 * m, np.int32)  # (vertex numbers: int32 as in _half_edges_by_vertex)
    for i in range(m):
        for k in range(3):
            a = F[i, k]
            b = F[i, (k + 1) % 3]
            lo = min(a, b)
            t = start[lo + 1]
            upper[t] = max(a, b)
            start[lo + 1] = t + 1
    # (the counts in bytes that stop at 255: a count other than two marks its bucket all the same,
    # and the marked buckets' counts are taken again exactly, their largest too; a quarter of an
    # int32 table's fresh pages after the heap's trim before the repair)
    cnt = np.zeros(nv, np.uint8)
    marked = np.zeros(nv, np.bool_)
    most = np.int32(0)
    some = False
    for v in range(nv):
        s0, s1 = start[v], start[v + 1]
        for t in range(s0, s1):
            u = upper[t]
            if cnt[u] < 255:
                cnt[u] += 1
        for t in range(s0, s1):
            c = np.int32(cnt[upper[t]])
            if c > most:
                most = c
            if c != 2:
                marked[v] = True
                some = True
        for t in range(s0, s1):
            cnt[upper[t]] = 0
    if not some:
        return np.int32(0), most, np.zeros(0, np.int64), np.zeros((0, 3), np.bool_)
    odd, most_marked, rows, hit = _marked_counts(F, start, upper, marked)
    return odd, max(most, most_marked), rows, hit


@njit(cache=True, nogil=True)
def _marked_counts(F, start, upper, marked):
    """:func:`_four_face_edges`' second pass: the faces in order, each half-edge whose lower
    vertex is ``marked`` counted in its bucket (``upper[start[lo]:start[lo + 1]]``): the first odd
    count (0 if none), the largest count, the faces with a half-edge counted four and, per such
    face, which (marked per face in one byte, bit ``k`` for its half-edge from corner ``k``: a
    third of the pages of a mark per half-edge, :func:`_hit_rows`' form)."""
    m = F.shape[0]
    odd = np.int32(0)
    most = np.int32(0)
    four = np.zeros(m, np.uint8)
    for i in range(m):
        for k in range(3):
            a = F[i, k]
            b = F[i, (k + 1) % 3]
            lo = min(a, b)
            if marked[lo]:
                hi = max(a, b)
                c = np.int32(0)
                for t in range(start[lo], start[lo + 1]):
                    c += upper[t] == hi
                if c > most:
                    most = c
                if c % 2 and odd == 0:
                    odd = c
                if c == 4:
                    four[i] |= np.uint8(1 << k)
    n = 0
    for i in range(m):
        n += four[i] != 0
    rows = np.empty(n, np.int64)
    hit = np.empty((n, 3), np.bool_)
    at = 0
    for i in range(m):
        if four[i]:
            rows[at] = i
            for k in range(3):
                hit[at, k] = (four[i] >> k) & 1
            at += 1
    return odd, most, rows, hit


def _four_face_edges_threads(F, nv, threads):
    """:func:`_four_face_edges` on ``threads`` threads: the half-edges with their numbers in the
    buckets of :func:`_buckets_on_threads`, each range of buckets counted on its own
    (:func:`_four_face_range`, the half-edges counted four marked), and the first odd count and the
    largest count of all ranges."""
    from ._workers import run_all

    start, items, other, vparts = _buckets_on_threads(F, nv, threads)
    hit = np.zeros(3 * F.shape[0], np.bool_)  # (each half-edge is in one bucket: one writer per entry)
    got = run_all(lambda a, b: _four_face_range(start, items, other, a, b, np.zeros(nv, np.int32), hit), vparts,
                  threads)
    odd_at = [(int(h), int(c)) for h, c, _ in got if h >= 0]
    most = max((int(x) for _, _, x in got), default=0)
    rows, rows_hit = _hit_rows(hit)
    return (min(odd_at)[1] if odd_at else 0), most, rows, rows_hit


@njit(cache=True, nogil=True)
def _four_face_range(start, items, other, v0, v1, cnt, hit):
    """The counts of faces per edge over the buckets ``v0 .. v1 - 1`` (:func:`_half_edges_by_vertex`), not kept:
    ``hit[h]`` set for the half-edges ``h`` counted four; returns ``(h, c, most)``, the lowest
    half-edge with an odd count and its count (-1, 0 where none) and the largest count."""
    first = np.int64(-1)
    odd = np.int32(0)
    most = np.int32(0)
    for v in range(v0, v1):
        s0, s1 = start[v], start[v + 1]
        for t in range(s0, s1):
            cnt[_upper(other[t])] += 1
        for t in range(s0, s1):
            c = cnt[_upper(other[t])]
            if c > most:
                most = c
            if c == 4:
                hit[items[t]] = True
            elif c % 2 and (first < 0 or items[t] < first):
                first = np.int64(items[t])
                odd = c
        for t in range(s0, s1):
            cnt[_upper(other[t])] = 0
    return first, odd, most


@njit(cache=True, nogil=True)
def _hit_rows(hit):
    """From the marks of :func:`_four_face_range` (one per half-edge): the faces with a marked
    edge (increasing) and, per such face, which of its edges are (:func:`_four_face_edges`' last two)."""
    m = hit.shape[0] // 3
    n = 0
    for i in range(m):
        n += hit[3 * i] or hit[3 * i + 1] or hit[3 * i + 2]
    rows = np.empty(n, np.int64)
    out = np.empty((n, 3), np.bool_)
    at = 0
    for i in range(m):
        if hit[3 * i] or hit[3 * i + 1] or hit[3 * i + 2]:
            rows[at] = i
            for k in range(3):
                out[at, k] = hit[3 * i + k]
            at += 1
    return rows, out

def _midpoints(V, made, nudge):
    """The new vertices of :func:`_split_four_face_edges`: row ``j`` of ``made`` is ``(u, v, o0,
    o1)``, vertex ``len(V) + j`` the midpoint of ``u`` and ``v`` moved ``nudge`` toward the mean of
    ``o0`` and ``o1`` (any of them may be an earlier new vertex).  Computed in rounds, each taking
    the rows whose four vertices are known, with the operations of the one-row form
    (:func:`_midpoint_one`, kept for the tests) in the same order: the same bits."""
    n_old, n = len(V), len(made)
    dt = (0.5 * V[:1]).dtype  # (the one-row form's result type)
    out = np.empty((n, 3), dtype=dt)
    if n == 0:
        return out.reshape(-1, 3)
    # the round of a row: one more than the latest round among the new vertices it uses
    level = np.zeros(n, dtype=np.int64)
    dep = made - n_old  # (>= 0: a new vertex)
    if (dep >= 0).any():
        for j in np.flatnonzero((dep >= 0).any(axis=1)).tolist():
            d = dep[j][dep[j] >= 0]
            level[j] = 1 + int(level[d].max())

    def at(ids):  # the coordinates of vertices old or new (the new ones of earlier rounds)
        old = ids < n_old
        if old.all():
            return V[ids]
        got = np.empty((len(ids), 3), dtype=dt)
        got[old] = V[ids[old]]
        got[~old] = out[ids[~old] - n_old]
        return got

    for lv in range(int(level.max()) + 1):
        rows = np.flatnonzero(level == lv)
        cu, cv, c0, c1 = (at(made[rows, t]) for t in range(4))
        mid = 0.5 * (cu + cv)
        toward = (c0 + c1) / 2.0 - mid
        # (np.linalg.norm of each row: the square root of its dot product, as the one-row form
        # takes it; np.vecdot makes the same dot call per row)
        nrm = np.sqrt(np.vecdot(toward, toward))
        pos = nrm > 0
        mid[pos] = mid[pos] + toward[pos] * (nudge / nrm[pos])[:, None]
        out[rows] = mid
    return out


def _midpoint_one(cu, cv, c0, c1, nudge):
    """One new vertex of :func:`_split_four_face_edges` as the splitting loop first made it."""
    mid = 0.5 * (cu + cv)
    toward = (c0 + c1) / 2.0 - mid
    nrm = np.linalg.norm(toward)
    if nrm > 0:
        mid = mid + toward * (nudge / nrm)
    return mid


def _kept_and_added(F, side, keep, added_faces, added_sides, overwrite: bool = False):
    """``np.concatenate([F[keep], added_faces])`` and the same of the sides, the kept rows
    written straight into the results in one compiled pass (:func:`_copy_kept`; no whole-mesh
    temporaries besides them).  ``overwrite``: ``F`` and ``side`` are the caller's own, with no
    views of them anywhere; where each is a C array that holds its own buffer (an int64 ``F`` of
    three columns), the kept rows are moved down in place and the buffers resized to the result
    (``ndarray.resize``: a ``realloc``, which for the large arrays remaps their pages instead of
    copying them): the same contents without a second whole-mesh pair of arrays to fill (on
    arrays of the lobster's 0.38 M faces, 2.2 -> 1.5 ms a call, most of it the new arrays'
    first writes) nor held beside the first."""
    if overwrite and _own_buffer(F) and _own_buffer(side) and F.dtype == np.int64 and F.ndim == 2 \
            and F.shape[1] == 3 and side.ndim == 1 and len(side) == len(F) and keep.dtype == np.bool_:
        nk = _copy_kept(F, side, np.ascontiguousarray(keep), F, side)  # (row at <= row i: read first)
        n = nk + len(added_faces)
        F.resize((n, 3), refcheck=False)  # (the caller holds the only references: see above)
        side.resize(n, refcheck=False)
        F[nk:] = np.array(added_faces, dtype=np.int64).reshape(-1, 3)
        side[nk:] = np.array(added_sides, dtype=side.dtype)
        return F, side
    nk = int(np.count_nonzero(keep))
    F2 = np.empty((nk + len(added_faces), 3), dtype=np.int64)
    S2 = np.empty(nk + len(added_sides), dtype=side.dtype)
    _copy_kept(np.ascontiguousarray(F, dtype=np.int64), np.ascontiguousarray(side), np.ascontiguousarray(keep), F2, S2)
    F2[nk:] = np.array(added_faces, dtype=np.int64).reshape(-1, 3)
    S2[nk:] = np.array(added_sides, dtype=side.dtype)
    return F2, S2


def _own_buffer(a) -> bool:
    """``a`` is a writeable C array that holds its own buffer (no view of another array): one that
    :func:`_kept_and_added` may resize."""
    return isinstance(a, np.ndarray) and a.flags.owndata and a.flags.c_contiguous and a.flags.writeable \
        and a.base is None


@njit(cache=True, nogil=True)
def _copy_kept(F, side, keep, F2, S2):
    """The rows of ``F`` and ``side`` where ``keep``, in order, into the first rows of ``F2`` and
    ``S2`` (a boolean-mask copy block by block cost about 0.09 s per call on liver x2's 1.1 M
    faces, twice per build)."""
    at = 0
    for i in range(F.shape[0]):
        if keep[i]:
            F2[at, 0] = F[i, 0]
            F2[at, 1] = F[i, 1]
            F2[at, 2] = F[i, 2]
            S2[at] = side[i]
            at += 1
    return at


@njit(cache=True, nogil=True)
def _half_edges_by_vertex(F, nv):
    """The half-edges ``3 i + k`` (face ``i``'s edge from corner ``k`` to ``k + 1``) bucketed by
    their lower vertex.  Returns ``(start, items, other)``: bucket ``v`` is ``items[start[v]:start[v
    + 1]]`` in increasing order (a counting sort), and ``other`` (beside ``items``) the half-edge's
    other vertex ``w >= v``, as ``w`` where it runs ``v -> w`` and ``~w`` where it runs ``w -> v``
    (a loop ``v -> v`` counts as the first): the passes over a bucket then read two arrays in
    order instead of the faces at random."""
    n = 3 * F.shape[0]
    start = np.zeros(nv + 1, np.int64)
    _lower_counts(F, 0, F.shape[0], start[1:])
    for v in range(nv):
        start[v + 1] += start[v]
    fill = start[:nv].copy()
    items = np.empty(n, np.int32)  # (half-edge numbers: a mesh of 700 M faces would not fit in memory anyway)
    other = np.empty(n, np.int32)  # (vertex numbers, fewer than the half-edges)
    _lower_scatter(F, 0, nv, fill, items, other)
    return start, items, other


@njit(cache=True, nogil=True)
def _lower_counts(F, i0, i1, cnt):
    """``cnt[v] +=`` the half-edges of faces ``i0 .. i1 - 1`` whose lower vertex is ``v``."""
    for i in range(i0, i1):
        for k in range(3):
            cnt[min(F[i, k], F[i, (k + 1) % 3])] += 1


@njit(cache=True, nogil=True)
def _lower_scatter(F, v0, v1, fill, items, other):
    """The half-edges whose lower vertex is in ``v0 .. v1 - 1`` written to their buckets from
    ``fill`` on (advanced), in increasing order, with their ``other`` entries (see
    :func:`_half_edges_by_vertex`; every face is read, only those half-edges written, so that
    threads filling other buckets do not write to the same cache lines)."""
    for i in range(F.shape[0]):
        for k in range(3):
            a = F[i, k]
            b = F[i, (k + 1) % 3]
            key, o = (a, b) if a <= b else (b, ~a)
            if v0 <= key < v1:
                t = fill[key]
                items[t] = 3 * i + k
                other[t] = o
                fill[key] = t + 1


@njit(cache=True, nogil=True, inline="always")
def _upper(o):
    """The upper vertex of an ``other`` entry (:func:`_half_edges_by_vertex`)."""
    return o if o >= 0 else ~o


@njit(cache=True, nogil=True)
def _key_counts(F, nv, i0, i1):
    """Per vertex, the half-edges of faces ``i0 .. i1 - 1`` in its bucket (:func:`_half_edges_by_vertex`)."""
    cnt = np.zeros(nv, np.int64)
    _lower_counts(F, i0, i1, cnt)
    return cnt


#: From this many faces on, the manifold repair's edge counts and half-edge twins
#: (:func:`_four_face_edges`, :func:`_half_edge_twins`) run on ``CONTOURMESH_THREADS`` threads.
_SPLIT_EDGES = 20_000


def _edge_threads(F) -> int:
    from .intersect import _threads

    return _threads() if len(F) >= _SPLIT_EDGES else 1


def _buckets_on_threads(F, nv, threads):
    """:func:`_half_edges_by_vertex` on ``threads`` threads: each counts the half-edges of its own
    range of faces, then fills its own range of buckets (the same buckets, in the same increasing
    order); and the ``threads * 2`` ranges of buckets, of about equal half-edge counts, that the
    callers work on."""
    from ._workers import run_all

    n = 3 * F.shape[0]
    fb = np.linspace(0, F.shape[0], threads + 1).astype(np.int64).tolist()
    counts = run_all(lambda a, b: _key_counts(F, nv, a, b), list(zip(fb[:-1], fb[1:])), threads)
    start = np.zeros(nv + 1, np.int64)
    np.cumsum(sum(counts), out=start[1:])
    del counts
    fill = start[:nv].copy()
    items = np.empty(n, np.int32)
    other = np.empty(n, np.int32)

    def ranges(parts):
        vb = np.searchsorted(start, np.linspace(0, n, parts + 1)[1:-1]).tolist()
        vb = [0] + [min(max(int(v), 0), nv) for v in vb] + [nv]
        return [(a, b) for a, b in zip(vb[:-1], vb[1:]) if b > a]

    run_all(lambda a, b: _lower_scatter(F, a, b, fill, items, other), ranges(threads), threads)
    return start, items, other, ranges(2 * threads)


def _half_edge_twins_threads(F, nv, threads):
    """:func:`_half_edge_twins` on ``threads`` threads: the same twins where its status is 0, a
    non-zero status (1 or 2, not necessarily the one-thread call's) where that call's is."""
    from ._workers import run_all

    start, items, other, vparts = _buckets_on_threads(F, nv, threads)
    twin = np.empty(3 * F.shape[0], np.int32)
    got = run_all(lambda a, b: _twins_range(start, items, other, a, b, twin, np.full(nv, -1, np.int32),
                                            np.full(nv, -1, np.int32)), vparts, threads)
    return twin, np.int64(max(got, default=0))


@njit(cache=True, nogil=True)
def _fan_components(twin):
    """The fans of a closed mesh: the connected components of its corners linked across its edges,
    from the half-edge twins (half-edge ``h = 3 i + k`` of face ``i`` runs from corner ``h`` to
    corner ``3 i + (k + 1) % 3``; ``twin`` pairs each with its opposite, an involution).  Returns
    ``(count, label per corner, lowest corner of each label)``, labels numbered in order of each
    component's lowest corner.

    Across edge ``h`` corner ``h`` is linked with the corner after ``twin[h]`` in its face, and
    the corner after ``h`` with corner ``twin[h]``: every link joins a corner ``c`` and the corner
    ``twin[prev(c)]`` that follows it around its vertex (``prev(c)``, the half-edge of ``c``'s face
    ending at ``c``).  That map is a permutation (twins are an involution), so the components are
    its cycles, each walked from its lowest corner, corners in increasing order: one pass, and
    the same labels as a union-find over the links (the form before)."""
    n = twin.shape[0]
    lab = np.full(n, -1, np.int64)
    count = 0
    for c in range(n):
        if lab[c] >= 0:
            continue
        x = c
        while True:
            lab[x] = count
            # (prev(x): the corner before x in its face, without the division by 3)
            x = np.int64(twin[x + 2 if x % 3 == 0 else x - 1])
            if lab[x] >= 0:  # (back at c; twins that are no involution stop here too)
                break
        count += 1
    first = np.empty(count, np.int64)
    at = 0
    for c in range(n):
        if lab[c] == at:
            first[at] = c
            at += 1
    return count, lab, first


def split_nonmanifold_vertices(V: np.ndarray, F: np.ndarray, nudge: float = 1e-3, side=None, four_face: bool = True,
                               overwrite: bool = False):
    """Make a closed mesh a manifold: pair faces at 4-face edges by side, split vertex fans.

    Edges shared by four faces occur where two voxels of consecutive slices touch along an
    edge (6-connectivity keeps them apart): each ``side``'s pair of faces gets an edge of its
    own (:func:`_split_four_face_edges`).  Then every vertex whose faces form several fans (touching corners) is split
    into one vertex per fan, and each copy is moved ``nudge`` (absolute units) towards the
    centroid of its fan so that the touching surfaces no longer share a point.  ``four_face=False``
    skips the first step (for a caller that has already split the four-face edges);
    ``overwrite``: the new faces may be written into ``F`` itself where it is an int64 C array
    (a caller that does not need it any more).
    """
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    if m == 0:
        return V, F
    V = np.asarray(V, dtype=np.float64)
    if four_face:
        side = np.zeros(m, dtype=np.int64) if side is None else np.asarray(side, dtype=np.int64)
        V, F, side = _split_four_face_edges(V, F, side, nudge)
    m = len(F)
    nv = len(V) + 1
    # fans = connected components of the corners linked across every edge, numbered in order of
    # their lowest corners; each vertex keeps its first fan, its other fans get new vertices
    # (numbered in the order of (vertex, fan)), and every fan of a split vertex has its vertex (or
    # the copy) nudged towards the fan's centroid: walked per vertex on the corners bucketed by
    # vertex (_vertex_fans, one compiled call on any number of threads), which also checks that
    # every directed edge is used once and has its opposite (every edge in exactly two faces)
    corner_vertex = np.ascontiguousarray(F.reshape(-1))
    status, several, changed, new_ids, target, start, copies, vid = _vertex_fans(corner_vertex, V, len(V))
    if status == 0 and several:  # (the other corners keep their vertices)
        F2 = corner_vertex if overwrite and F.flags.c_contiguous and F.flags.writeable else corner_vertex.copy()
        F2[changed] = new_ids
        del changed, new_ids
    if status != 0:  # (a fault, or a face with a repeated vertex: the twins' path names or handles it)
        Fc = np.ascontiguousarray(F)
        threads = _edge_threads(Fc)
        twin, status = _half_edge_twins(Fc, len(V)) if threads < 2 else _half_edge_twins_threads(Fc, len(V), threads)
        del Fc
        if status != 0:  # the sorted search names the edge at fault
            twin = _half_edge_twins_reference(F, nv)
        # (the same fans from the twins, in one compiled pass; the new faces written over the labels)
        several, F2, target, start, copies, vid = _split_fans(twin, corner_vertex, V, len(V))
        del twin
    if not several:
        return V, F
    F2 = F2.reshape(-1, 3)
    d = target - V[start]  # (V2[vid]: a fan's vertex or the copy of it)
    V2 = np.concatenate([V, V[copies]])
    nrm = np.linalg.norm(d, axis=1)
    good = nrm > 0
    V2[vid[good]] += d[good] * (nudge / nrm[good])[:, None]
    return V2, F2


@njit(cache=True, nogil=True)
def _fan_numbers(fan_vertex, nv):
    """Per fan its vertex number: the fan's own vertex for the first fan of each vertex (in fan
    order), else ``nv + j`` for the ``j``-th of the other fans in the order of (vertex, fan);
    and those other fans in that order.  (A stable argsort of ``fan_vertex`` and its heads, by
    counting: no sorted copies.)"""
    nf = fan_vertex.shape[0]
    off = np.zeros(nv + 1, np.int64)  # other fans per vertex, then where each vertex's begin
    first = np.zeros(nv, np.bool_)
    fan_to_new = np.empty(nf, np.int64)
    for f in range(nf):
        v = fan_vertex[f]
        if not first[v]:
            first[v] = True
            fan_to_new[f] = v
        else:
            off[v + 1] += 1
    for v in range(nv):
        off[v + 1] += off[v]
    others = np.empty(off[nv], np.int64)
    for v in range(nv):
        first[v] = False
    for f in range(nf):
        v = fan_vertex[f]
        if not first[v]:
            first[v] = True
        else:
            j = off[v]
            others[j] = f
            fan_to_new[f] = nv + j
            off[v] = j + 1
    return fan_to_new, others


@njit(cache=True, nogil=True)
def _split_fans(twin, corner_vertex, V, nv):
    """The fans of :func:`split_nonmanifold_vertices` from the half-edge twins, in one pass over
    the corners and one over the fans' corners: ``(several, F2, target, start, copies, vid)``,
    several False where no vertex has two fans (the rest then not made).  ``F2`` (flat, one entry
    per corner) numbers each corner by its fan's vertex (:func:`_fan_numbers`); per fan of a
    vertex with several, in fan order, ``target`` is the mean of its faces' centroids over its
    corners in order, ``start`` its vertex, ``vid`` its vertex or copy in ``F2``; ``copies`` the
    vertices the new ones copy.  The fans are :func:`_fan_components`'s, the sums those of the
    whole-array form before: each centroid ``((a + b) + c) / 3``, added in corner order from zero,
    divided by the count."""
    n = twin.shape[0]
    count, lab, first = _fan_components(twin)
    fan_vertex = np.empty(count, np.int64)
    fans_at = np.zeros(nv, np.int32)
    for f in range(count):
        v = corner_vertex[first[f]]
        fan_vertex[f] = v
        fans_at[v] += 1
    empty = np.zeros((0, 3))
    none = np.zeros(0, np.int64)
    several = False
    for v in range(nv):
        if fans_at[v] > 1:
            several = True
            break
    if not several:
        return False, lab, empty, none, none, none
    fan_to_new, others = _fan_numbers(fan_vertex, nv)
    # the fans of split vertices (in fan order) and their place among them
    k = 0
    for f in range(count):
        k += fans_at[fan_vertex[f]] > 1
    at = np.full(count, -1, np.int64)
    start = np.empty(k, np.int64)
    vid = np.empty(k, np.int64)
    t = 0
    for f in range(count):
        if fans_at[fan_vertex[f]] > 1:
            at[f] = t
            start[t] = fan_vertex[f]
            vid[t] = fan_to_new[f]
            t += 1
    sums = np.zeros((k, 3))
    cnt = np.zeros(k, np.int64)
    for c in range(n):
        f = lab[c]
        j = at[f]
        if j >= 0:
            i = c // 3
            for d in range(3):
                sums[j, d] += ((V[corner_vertex[3 * i], d] + V[corner_vertex[3 * i + 1], d])
                               + V[corner_vertex[3 * i + 2], d]) / 3.0
            cnt[j] += 1
        lab[c] = fan_to_new[f]
    for j in range(k):
        for d in range(3):
            sums[j, d] = sums[j, d] / np.float64(cnt[j])
    copies = np.empty(others.shape[0], np.int64)
    for j in range(others.shape[0]):
        copies[j] = fan_vertex[others[j]]
    return True, lab, sums, start, copies, vid


@njit(cache=True, nogil=True)
def _vertex_fans(corner_vertex, V, nv):
    """:func:`_split_fans`' results without the half-edge twins: ``(status, several, changed,
    new_ids, target, start, copies, vid)``, where ``status`` is 0 and ``several``: the corners
    ``changed`` (increasing) take the vertex numbers ``new_ids`` (every other corner keeps its
    vertex: ``F2`` there), the rest as there.

    The corners are bucketed by their vertex (a counting sort; per entry the next and the previous
    vertex of its corner in its face), and each vertex's fans are walked in its own bucket: from a
    corner whose previous vertex is ``b`` to the corner of the same vertex whose next vertex is
    ``b`` (the corner after the twin of the half-edge ``b -> v``: the step of
    :func:`_fan_components`).  The twins' checks are made per bucket, as every half-edge ``v -> w``
    is the next vertex of one entry of ``v`` and every ``w -> v`` the previous vertex of one: two
    entries of a vertex with the same next vertex (a half-edge used twice in one direction), a
    previous vertex that is no entry's next (a half-edge without its opposite) or links that are
    no permutation give ``status`` 1 or 2, a face with a repeated vertex or a vertex not below
    ``nv`` 3; the caller then takes the twins' path, which names the fault (or handles the loops).

    The fans of a vertex are its corners' classes under that step, whatever the corner they are
    walked from, and they are numbered among all fans by their lowest corners, as
    :func:`_fan_components` numbers them; the vertices with several fans (few) are then read again
    corner by corner in increasing order, so that each fan's centroid sum is added in the order
    of :func:`_split_fans` (from zero, in corner order, each face's ``((a + b) + c) / 3``), and
    their other fans are numbered ``nv + j`` in the order of (vertex, fan): the same bits."""
    n = corner_vertex.shape[0]
    m = n // 3
    empty = np.zeros((0, 3))
    none = np.zeros(0, np.int64)
    # the bucket of vertex v is e[cnt[v]:cnt[v + 1]] once filled (counted at v + 2, then each
    # bucket's fill pointer at v + 1 ends at the next bucket's start)
    cnt = np.zeros(nv + 2, np.int64)
    for i in range(m):
        a = corner_vertex[3 * i]
        b = corner_vertex[3 * i + 1]
        c = corner_vertex[3 * i + 2]
        if a == b or b == c or a == c or min(a, b, c) < 0 or max(a, b, c) >= nv:
            return np.int64(3), False, none, none, empty, none, none, none
        cnt[a + 2] += 1
        cnt[b + 2] += 1
        cnt[c + 2] += 1
    most = 0
    for v in range(nv):
        most = max(most, cnt[v + 2])
        cnt[v + 2] += cnt[v + 1]
    e = np.empty((n, 2), np.int32)  # (next, previous vertex; int32: 2^31 corners would not fit in memory here)
    for i in range(m):
        a = corner_vertex[3 * i]
        b = corner_vertex[3 * i + 1]
        c = corner_vertex[3 * i + 2]
        t = cnt[a + 1]
        e[t, 0] = b
        e[t, 1] = c
        cnt[a + 1] = t + 1
        t = cnt[b + 1]
        e[t, 0] = c
        e[t, 1] = a
        cnt[b + 1] = t + 1
        t = cnt[c + 1]
        e[t, 0] = a
        e[t, 1] = b
        cnt[c + 1] = t + 1
    start = cnt[:nv + 1]
    # (the tables over the vertices in int32 and bytes rather than int64: fewer fresh pages after
    # the heap's trim before the repair, each some 0.4 ms per MiB on the lobster's mesh)
    at_next = np.full(nv, -1, np.int32)  # (the entry of the current bucket with next vertex w; left so)
    split = np.zeros(nv, np.bool_)  # (the vertices with several fans)
    local = np.empty(most, np.int32)
    k_split = 0  # (fans of vertices with several)
    n_other = 0
    n_corners = 0  # (their corners)
    for v in range(nv):
        s0, s1 = start[v], start[v + 1]
        for t in range(s0, s1):
            w = e[t, 0]
            if at_next[w] >= 0:
                return np.int64(1), False, none, none, empty, none, none, none
            at_next[w] = t
        q = 0
        if s1 > s0:
            # one walk from the first entry covers them all where the vertex has one fan
            x = s0
            steps = 0
            while True:
                x = at_next[e[x, 1]]
                steps += 1
                if x < 0:
                    return np.int64(2), False, none, none, empty, none, none, none
                if x == s0 or steps > s1 - s0:
                    break
            if x != s0:
                return np.int64(1), False, none, none, empty, none, none, none
            q = 1
            if steps < s1 - s0:
                q = _bucket_fans(e, s0, s1, at_next, local)
                if q < 0:
                    return np.int64(1), False, none, none, empty, none, none, none
        for t in range(s0, s1):
            at_next[e[t, 0]] = -1
        if q > 1:
            split[v] = True
            k_split += q
            n_other += q - 1
            n_corners += s1 - s0
    if n_other == 0:
        return np.int64(0), False, none, none, empty, none, none, none
    # the fans of split vertices numbered in vertex order (g0[v]: v's first), and each entry's fan
    # written over its previous vertex (no longer needed)
    g0 = np.full(nv, -1, np.int32)  # (fans: fewer than the corners)
    fv = np.empty(k_split, np.int64)
    fid = np.empty(k_split, np.int64)
    copies = np.empty(n_other, np.int64)
    g = 0
    j = 0
    for v in range(nv):
        if split[v]:
            s0, s1 = start[v], start[v + 1]
            for t in range(s0, s1):
                at_next[e[t, 0]] = t
            q = _bucket_fans(e, s0, s1, at_next, local)
            g0[v] = g
            for p in range(q):
                fv[g + p] = v
                fid[g + p] = v if p == 0 else nv + j + p - 1
            for p in range(1, q):
                copies[j + p - 1] = v
            g += q
            j += q - 1
            for t in range(s0, s1):
                at_next[e[t, 0]] = -1
                e[t, 1] = local[t - s0]
    # their corners in increasing order: each fan's lowest corner, sums and counts, new numbers
    head = np.full(k_split, -1, np.int64)
    sums = np.zeros((k_split, 3))
    cn = np.zeros(k_split, np.int64)
    changed = np.empty(n_corners, np.int64)
    new_ids = np.empty(n_corners, np.int64)
    nc = 0
    for i in range(m):
        for k in range(3):
            c = 3 * i + k
            v = corner_vertex[c]
            b0 = g0[v]
            if b0 < 0:
                continue
            w = corner_vertex[3 * i + (k + 1) % 3]
            t = start[v]
            while e[t, 0] != w:  # (the corner's entry: the one with its next vertex)
                t += 1
            p = e[t, 1]
            f = b0 + p
            if head[f] < 0:
                head[f] = c
            for d in range(3):
                sums[f, d] += ((V[corner_vertex[3 * i], d] + V[corner_vertex[3 * i + 1], d])
                               + V[corner_vertex[3 * i + 2], d]) / 3.0
            cn[f] += 1
            if p > 0:
                changed[nc] = c
                new_ids[nc] = fid[f]
                nc += 1
    order = np.argsort(head)  # (the fans' order among all fans: by lowest corner)
    target = np.empty((k_split, 3))
    st = np.empty(k_split, np.int64)
    vid = np.empty(k_split, np.int64)
    for r in range(k_split):
        f = order[r]
        for d in range(3):
            target[r, d] = sums[f, d] / np.float64(cn[f])
        st[r] = fv[f]
        vid[r] = fid[f]
    return np.int64(0), True, changed[:nc], new_ids[:nc], target, st, copies, vid


@njit(cache=True, nogil=True)
def _bucket_fans(e, s0, s1, at_next, local):
    """The fans of one vertex of :func:`_vertex_fans`, its entries ``e[s0:s1]`` (``at_next`` filled
    for them): each entry's fan (0, 1, ... in order of their first entries) into ``local[:s1 -
    s0]``; returns their count, or -1 where the links are no permutation."""
    d = s1 - s0
    for t in range(d):
        local[t] = -1
    q = 0
    for t in range(d):
        if local[t] < 0:
            x = t
            while local[x] < 0:
                local[x] = q
                x = at_next[e[s0 + x, 1]] - s0
            if x != t:
                return np.int64(-1)
            q += 1
    return np.int64(q)


def _half_edge_twins_reference(F, nv):
    """Per half-edge ``3 i + k`` (face ``i``'s edge from corner ``k`` to ``k + 1``), the index of
    its opposite half-edge, by a sorted search; a RuntimeError naming the edge where one is used
    twice in one direction or has no opposite."""
    m = len(F)
    fi = np.repeat(np.arange(m), 3)
    li = np.tile(np.arange(3), m)
    u = F[fi, li]
    v = F[fi, (li + 1) % 3]
    key_uv = u * nv + v
    key_vu = v * nv + u
    order = np.argsort(key_uv, kind="stable")
    sk = key_uv[order]
    # every directed edge once and every one with its opposite <=> every edge in exactly two faces
    same = np.flatnonzero(sk[1:] == sk[:-1])
    if len(same):
        bad = int(order[same[0]])
        raise RuntimeError(
            f"internal error: edge ({u[bad]}, {v[bad]}) is used twice in one direction; cannot make a manifold"
        )
    pos = np.clip(np.searchsorted(sk, key_vu), 0, len(order) - 1)
    twin = order[pos]
    del sk, pos, order
    ok = key_uv[twin] == key_vu
    if not ok.all():
        bad = int(np.flatnonzero(~ok)[0])
        raise RuntimeError(
            f"internal error: half-edge ({u[bad]}, {v[bad]}) has no opposite half-edge; the surface is not closed "
            "and consistently oriented"
        )
    del key_uv, key_vu, ok
    return twin


@njit(cache=True, nogil=True)
def _half_edge_twins(F, nv):
    """:func:`_half_edge_twins_reference` with the half-edges bucketed by their lower vertex (one
    counting sort, int32 half-edge numbers): ``(twin, status)``, status 0, or 1 where an edge is
    used twice in one direction, 2 where a half-edge has no opposite (then the twins are not all
    set).  An edge from a vertex to itself is its own opposite, as in the sorted search."""
    n = 3 * F.shape[0]
    start, items, other = _half_edges_by_vertex(F, nv)
    twin = np.empty(n, np.int32)
    status = _twins_range(start, items, other, 0, nv, twin, np.full(nv, -1, np.int32), np.full(nv, -1, np.int32))
    return twin, status


@njit(cache=True, nogil=True)
def _twins_range(start, items, other, x0, x1, twin, up, down):
    """:func:`_half_edge_twins` for the buckets ``x0 .. x1 - 1``; returns its status.  Each
    bucket is first checked for an edge used twice in one direction (status 1), then every
    half-edge is matched with its opposite (status 2 where there is none), through ``up[w]`` (the
    half-edge ``x -> w``) and ``down[w]`` (the half-edge ``w -> x``), tables of -1 over the
    vertices (left so), every bucket alike (the same twins and statuses as comparing the entries
    of a small bucket among themselves, the form before; about a quarter less time)."""
    for x in range(x0, x1):
        s0, s1 = start[x], start[x + 1]
        for t in range(s0, s1):
            o = other[t]
            if o >= 0:  # x -> o (o == x: a loop)
                if up[o] >= 0:
                    return np.int64(1)
                up[o] = items[t]
            else:  # ~o -> x
                if down[~o] >= 0:
                    return np.int64(1)
                down[~o] = items[t]
        for t in range(s0, s1):
            o = other[t]
            g = up[o] if o == x else down[o] if o >= 0 else up[~o]
            if g < 0:
                return np.int64(2)
            twin[items[t]] = g
        for t in range(s0, s1):
            w = _upper(other[t])
            up[w] = -1
            down[w] = -1
    return np.int64(0)


@njit(cache=True, nogil=True)
def _renumber(a, table):
    """``a[:] = table[a]`` in place (``a`` 1-D)."""
    for i in range(a.shape[0]):
        a[i] = table[a[i]]


#: From this many necks on, :func:`_open_necks` opens them all at once; below, one at a time
#: (:func:`_open_necks_loop`, the same mesh).  The compiled steps' kernels take some 0.04 s to load
#: on a process's first mesh with necks, as long as the loop takes for some 150 necks: the liver's
#: 9 necks cost 0.019 s in the loop, 0.062 s at once on a first mesh (0.013 s on later ones); the
#: lobster's 546, 0.23 and 0.085 s (0.27 and 0.035 s on later meshes).
_NECKS_AT_ONCE = 32


def _open_necks(V, F, S, necks, nudge, tube_seen=None, overwrite: bool = False):
    """Replace each neck vertex by a small tube joining its two fans.

    At a mid-plane corner where the two empty voxels of the 2 x 2 x 2 block around it touch only
    at that corner (the six others are object), the surface meets itself in two cones there.  The
    background is 26-connected, so it passes through the point: the cones are joined by a tube
    (the star of the vertex is removed and its two link cycles are joined by a band).

    The mesh of :func:`_open_necks_loop` (the form before, one neck at a time in Python; kept for
    the cases below and as the tests' reference), made in four steps over all necks at once:

    1. the links, cycles and fan faces of every neck (:func:`_neck_steps`, compiled): they
       depend on no coordinates (a neck's star changes only by the fan faces of earlier necks;
       tube faces hold new vertices alone, never a neck), and every new vertex's number follows
       from the cycles' lengths;
    2. the rings, in rounds (a neck whose link holds an earlier neck's ring vertices waits for
       that ring) and the rings' angles about each tube's axis, in whole-array numpy steps that
       make the one-neck steps' numbers row by row (the same ufuncs, reductions in the same order;
       the BLAS products as the same calls, stacked by ring length: :func:`_necks_angles`);
    3. each neck's tube walk and the mesh of its exact crossing test (:func:`_neck_walks`,
       compiled), the test by the kernel of :func:`contourmesh.intersect.any_intersecting` called
       directly, and for the few tubes that cross, the loop's further walks (:func:`_tube_retry`);
    4. the faces, in the order the loop adds them (each neck's fan faces still alive, then its tube).

    ``tube_seen`` (a dict kept by the caller across rebuilds): the loop form's memo of whole necks
    and here the answers of the tubes' crossing tests, each keyed by the bytes of the test's points
    and faces (all that the answer depends on; on the lobster's rebuild all 546 tubes are met
    again, 0.018 s of tests saved).
    Fewer than :data:`_NECKS_AT_ONCE` necks, vertices other than finite float64 ones, or
    coordinates that the crossing test would have to rescale, and meshes the loop refuses (with
    its message) go to :func:`_open_necks_loop`.  ``overwrite``: ``F`` and ``S`` are the caller's
    own, with no views of them, and may become the results (step 4, :func:`_kept_and_added`).
    """
    if len(necks) == 0:
        return V, F, S
    if len(np.unique(necks)) < _NECKS_AT_ONCE:
        return _open_necks_loop(V, F, S, necks, nudge, tube_seen)
    return _open_necks_at_once(V, F, S, necks, nudge, tube_seen, overwrite)


def _open_necks_at_once(V, F, S, necks, nudge, tube_seen=None, overwrite: bool = False):
    """:func:`_open_necks` with the necks all at once (steps 1 to 4 there), however few."""
    neck_ids = np.ascontiguousarray(np.unique(necks), dtype=np.int64)
    if not (isinstance(V, np.ndarray) and V.dtype == np.float64 and V.ndim == 2):
        return _open_necks_loop(V, F, S, necks, nudge, tube_seen)
    n_v = len(V)
    status, old_index, cyc, cyc_at, old_alive, fans, fan_alive, rnd = _neck_steps(
        np.ascontiguousarray(F, dtype=np.int64), neck_ids, n_v)
    if status != 0:  # (the loop raises its own message)
        return _open_necks_loop(V, F, S, necks, nudge, tube_seen)
    R = _necks_rings(V, neck_ids, cyc, cyc_at, rnd, float(nudge))
    j0, ua, ub = _necks_angles(V, neck_ids, R, cyc_at)
    # the crossing test's kernel takes the points as they are where any_intersecting would check
    # and keep them: finite, and not to be rescaled (:func:`contourmesh.intersect._exact_range`;
    # the magnitudes of each neck's points lie within those of all the necks' points)
    from .intersect import _EXACT_EXP, _STAR_DELAY

    Vc = np.ascontiguousarray(V)
    P = np.abs(np.concatenate([Vc[cyc[cyc < n_v]], R]))
    hi = float(P.max(initial=0.0))
    lo = float(P[P > 0].min(initial=np.inf))
    low, high = _EXACT_EXP
    if not (np.isfinite(P).all() and hi <= 2.0 ** high and lo >= 2.0 ** -low):
        return _open_necks_loop(V, F, S, necks, nudge, tube_seen)
    del P
    tube, P, p_at, Fl = _neck_walks(Vc, R, fans, cyc_at, j0, ua, ub)
    delay = np.int64(_STAR_DELAY)
    at, pa = cyc_at.tolist(), p_at.tolist()
    for j in range(len(neck_ids)):  # (the crossing kernel itself: the mesher's tests load it anyway)
        s0, s1, s2 = at[2 * j], at[2 * j + 1], at[2 * j + 2]
        Pj, Fj = P[pa[j]:pa[j + 1]], Fl[3 * s0:3 * s2]
        if tube_seen is None:
            crosses = _any_kernel(Pj, Fj, delay)
        else:  # (the test's answer depends on these bytes alone: a rebuild meets most tubes again)
            memo = ("tube at once", Pj.tobytes(), Fj.tobytes())
            crosses = tube_seen.get(memo)
            if crosses is None:
                crosses = tube_seen[memo] = _any_kernel(Pj, Fj, delay)
        if crosses:
            b = (n_v + s2 - 1 - (j0[j] + np.arange(s2 - s1)) % (s2 - s1)).tolist()
            _tube_retry(Vc, R, fans[2 * s0:2 * s2], tube[s0:s2], list(range(n_v + s0, n_v + s1)), b, delay)
    added = _neck_faces(cyc_at, fans, fan_alive, tube)
    keep = np.ones(len(F), dtype=bool)
    keep[old_index[~old_alive]] = False
    F2, S2 = _kept_and_added(F, S, keep, added, np.zeros(len(added), dtype=S.dtype), overwrite)
    return np.concatenate([V, R]), F2, S2


def warm_neck_kernels():
    """Compile (or load) the kernels of :func:`_open_necks_at_once` (for ``scripts/warm_kernels.py``:
    the small volumes there have fewer necks than open at once): on two cones meeting at a point,
    with the volume mesher's argument types."""
    t = np.linspace(0.0, 2.0 * np.pi, 5)[:-1]
    ring = np.stack([np.cos(t), np.sin(t), np.ones(4)], axis=1)
    V = np.concatenate([[[0.0, 0.0, 0.0]], ring, ring * [1.0, 1.0, -1.0], [[0.0, 0.0, 2.0], [0.0, 0.0, -2.0]]])
    F = []
    for k in range(4):
        a, b = 1 + k, 1 + (k + 1) % 4
        F += [[0, a, b], [9, b, a], [0, b + 4, a + 4], [10, a + 4, b + 4]]
    F = np.array(F, dtype=np.int64)
    return _open_necks_at_once(V, F, np.zeros(len(F), np.int32), np.array([0]), 1e-2)


@njit(cache=True, nogil=True)
def _neck_steps(F, necks, n_v):
    """Step 1 of :func:`_open_necks` in one compiled call (one kernel to load): the faces at the
    necks (their rows, :func:`_rows_touching`), their cycles and fans (:func:`_neck_cycles`:
    ``status, cyc, cyc_at, old_alive, fans, fan_alive``) and each neck's round
    (:func:`_neck_rounds`).  Returns ``(status, rows, cyc, cyc_at, old_alive, fans, fan_alive,
    rounds)``."""
    mark = np.zeros(n_v, np.bool_)
    for j in range(necks.shape[0]):
        mark[necks[j]] = True
    rows = _rows_touching(F, mark)
    Fo = np.empty((rows.shape[0], 3), np.int64)
    for t in range(rows.shape[0]):
        for d in range(3):
            Fo[t, d] = F[rows[t], d]
    status, cyc, cyc_at, old_alive, fans, fan_alive = _neck_cycles(Fo, necks, n_v)
    rnd = _neck_rounds(cyc, cyc_at, n_v) if status == 0 else np.zeros(0, np.int64)
    return status, rows, cyc, cyc_at, old_alive, fans, fan_alive, rnd


@njit(cache=True, nogil=True)
def _rows_touching(F, mark):
    """The rows of ``F`` with a corner ``v`` where ``mark[v]`` (``np.flatnonzero(mark[F].any(axis=1))``)."""
    n = 0
    for i in range(F.shape[0]):
        n += mark[F[i, 0]] or mark[F[i, 1]] or mark[F[i, 2]]
    out = np.empty(n, np.int64)
    t = 0
    for i in range(F.shape[0]):
        if mark[F[i, 0]] or mark[F[i, 1]] or mark[F[i, 2]]:
            out[t] = i
            t += 1
    return out


@njit(cache=True, nogil=True)
def _neck_cycles(Fo, necks, n_v):
    """Step 1 of :func:`_open_necks`: ``(status, cyc, cyc_at, old_alive, fans, fan_alive)``.  Neck ``k``'s
    two link cycles are ``cyc[cyc_at[2k]:cyc_at[2k + 1]]`` and ``cyc[cyc_at[2k + 1]:cyc_at[2k +
    2]]``, each as the loop finds it; the new vertex of cycle entry ``p`` is ``n_v + p``.  The fan
    faces, two per cycle entry in the loop's order (``(r_t, x_t, x_t+1), (r_t, x_t+1, r_t+1)``),
    are ``fans``, numbered along ``cyc`` (neck ``k``'s from row ``2 cyc_at[2k]``); ``fan_alive`` says which are left at the end, ``old_alive`` which
    of the faces ``Fo`` (the faces at a neck, in mesh order).  A nonzero status where the loop
    raises (an apex not of two cones, a link that is not closed)."""
    k = necks.shape[0]
    n_old = Fo.shape[0]
    pos = np.full(n_v, -1, np.int64)
    for j in range(k):
        pos[necks[j]] = j
    # the faces (old, then fans: face g >= n_old is fan g - n_old) and each neck's star as a
    # linked list of faces in the order the loop appends them
    cap = max(16, 2 * n_old)
    faces = np.empty(3 * cap, np.int64)  # (flat: face g is faces[3 g:3 g + 3])
    alive = np.ones(cap, np.bool_)
    # (the old faces' entries, at most three a face, fit without growing: the loops below
    # append with no array made or swapped inside them, which in this kernel counts references)
    ent_cap = cap
    while ent_cap < 3 * n_old:
        ent_cap *= 2
    ent_face = np.empty(ent_cap, np.int64)
    ent_next = np.empty(ent_cap, np.int64)
    head = np.full(k, -1, np.int64)
    tail = np.full(k, -1, np.int64)
    nent = 0
    nf = 0
    cyc = np.empty(max(16, n_old), np.int64)
    cyc_at = np.zeros(2 * k + 1, np.int64)
    ncyc = 0
    for t in range(n_old):
        for d in range(3):
            faces[3 * t + d] = Fo[t, d]
    nf = n_old
    for t in range(n_old):
        for d in range(3):
            v = Fo[t, d]
            j = pos[v]
            if j >= 0:  # (face t appended to neck j's star)
                ent_face[nent] = t
                ent_next[nent] = -1
                if tail[j] >= 0:
                    ent_next[tail[j]] = nent
                else:
                    head[j] = nent
                tail[j] = nent
                nent += 1
    lx = np.empty(16, np.int64)
    ly = np.empty(16, np.int64)
    for j in range(k):
        c = necks[j]
        # (the star's length: the link's entries fit in lx and ly, and the two walks below,
        # of at most one more entry than the link each, in cyc)
        ns = 0
        e = head[j]
        while e >= 0:
            ns += 1
            e = ent_next[e]
        while ns > lx.shape[0]:
            lx = _grown1(lx)
            ly = _grown1(ly)
        while ncyc + 2 * ns + 2 > cyc.shape[0]:
            cyc = _grown1(cyc)
        nl = 0
        e = head[j]
        while e >= 0:
            t = ent_face[e]
            e = ent_next[e]
            if not alive[t]:
                continue
            i = 0 if faces[3 * t] == c else 1 if faces[3 * t + 1] == c else 2
            x = faces[3 * t + (i + 1) % 3]
            y = faces[3 * t + (i + 2) % 3]
            for q in range(nl):
                if lx[q] == x:
                    return np.int64(1), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
            lx[nl] = x
            ly[nl] = y
            nl += 1
        # the cycles, from the link's entries in order
        seen = np.zeros(nl, np.bool_)
        ncycles = 0
        for q0 in range(nl):
            if seen[q0]:
                continue
            ncycles += 1
            if ncycles > 2:
                return np.int64(2), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
            x0 = lx[q0]
            q = q0
            steps = 0
            while True:
                seen[q] = True
                cyc[ncyc] = lx[q]
                ncyc += 1
                x = ly[q]
                if x == x0:
                    break
                q = -1
                for q2 in range(nl):
                    if lx[q2] == x:
                        q = q2
                        break
                steps += 1
                if q < 0 or steps > nl:  # (the loop: a KeyError, or no end)
                    return np.int64(3), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
            cyc_at[2 * j + ncycles] = ncyc
        if ncycles != 2:
            return np.int64(2), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
        e = head[j]  # the star retired
        while e >= 0:
            alive[ent_face[e]] = False
            e = ent_next[e]
        # the fan faces, and the later necks' stars they join: two a cycle entry, and at most
        # two entries each (the arrays grown before, as they would be on reaching their ends)
        need = 2 * (cyc_at[2 * j + 2] - cyc_at[2 * j])
        while nf + need > alive.shape[0]:
            faces = _grown1(faces)
            alive = _grown1(alive)
        while nent + 2 * need > ent_face.shape[0]:
            ent_face = _grown1(ent_face)
            ent_next = _grown1(ent_next)
        for h in range(2):
            c0, c1 = cyc_at[2 * j + h], cyc_at[2 * j + h + 1]
            m = c1 - c0
            for t in range(m):
                p, p1 = c0 + t, c0 + (t + 1) % m
                for w in range(2):
                    if w == 0:
                        faces[3 * nf], faces[3 * nf + 1], faces[3 * nf + 2] = n_v + p, cyc[p], cyc[p1]
                    else:
                        faces[3 * nf], faces[3 * nf + 1], faces[3 * nf + 2] = n_v + p, cyc[p1], n_v + p1
                    alive[nf] = True
                    for d in range(3):
                        v = faces[3 * nf + d]
                        if v < n_v and pos[v] > j:  # (face nf appended to neck pos[v]'s star)
                            jv = pos[v]
                            ent_face[nent] = nf
                            ent_next[nent] = -1
                            if tail[jv] >= 0:
                                ent_next[tail[jv]] = nent
                            else:
                                head[jv] = nent
                            tail[jv] = nent
                            nent += 1
                    nf += 1
    return np.int64(0), cyc[:ncyc].copy(), cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()


@njit(cache=True, nogil=True)
def _grown1(a):
    """``a`` in an array twice as long (the rest not set)."""
    b = np.empty(2 * a.shape[0], a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, nogil=True)
def _neck_rounds(cyc, cyc_at, n_v):
    """The round of each neck's rings (:func:`_necks_rings`): 0, or one more than the latest round
    of the necks whose new vertices its cycles hold (always earlier necks)."""
    k = (cyc_at.shape[0] - 1) // 2
    rnd = np.zeros(k, np.int64)
    owner = np.empty(cyc.shape[0], np.int64)
    for j in range(k):
        for p in range(cyc_at[2 * j], cyc_at[2 * j + 2]):
            owner[p] = j
    for j in range(k):
        for p in range(cyc_at[2 * j], cyc_at[2 * j + 2]):
            v = cyc[p]
            if v >= n_v:
                rnd[j] = max(rnd[j], rnd[owner[v - n_v]] + 1)
    return rnd


def _necks_rings(V, necks, cyc, cyc_at, rounds, nudge):
    """Step 2 of :func:`_open_necks`: the new vertices (row ``p`` for cycle entry ``p``), each a
    hair from its neck towards its link vertex, as the loop makes them: ``pc + eps * dirs`` with
    ``dirs`` the unit directions, ``eps`` ``nudge`` on the first cycle and 1.5 ``nudge`` on the
    second; row by row, the same operations; ``rounds`` per neck (:func:`_neck_rounds`)."""
    n_v = len(V)
    n = len(cyc)
    R = np.empty((n, 3))
    lens = np.diff(cyc_at)
    which = np.repeat(np.arange(len(lens)), lens)  # (2 neck + cycle) of each entry
    nk = which // 2
    eps = np.array([nudge * (1.0 + 0.5 * 0), nudge * (1.0 + 0.5 * 1)])[which % 2]
    rnd = rounds[nk]
    for r in range(int(rnd.max(initial=-1)) + 1):
        rows = np.flatnonzero(rnd == r)
        v = cyc[rows]
        P = np.empty((len(rows), 3))
        old = v < n_v
        P[old] = V[v[old]]
        P[~old] = R[v[~old] - n_v]
        pc = V[necks[nk[rows]]]
        dirs = P - pc
        dirs /= np.maximum(np.linalg.norm(dirs, axis=1), 1e-300)[:, None]
        R[rows] = pc + eps[rows, None] * dirs
    return R


def _necks_angles(V, necks, R, cyc_at):
    """Step 2 of :func:`_open_necks`, continued: per neck the angles of its two rings about its
    tube's axis (the loop's :func:`_ring_angles` of ``ring0 - pc`` and ``ring1[::-1] - pc``) and
    the unwrapped angles its walk compares, all necks in whole-array steps.  Returns ``(ta, tb, ua,
    ub)`` flat along the rings' entries (the second ring's reversed), ``ta`` and ``tb`` as
    :func:`_ring_angles` gives them, ``ua`` and ``ub`` the loop's ``np.unwrap`` of them rolled
    (the second ring to start at the angle nearest the first's first) and turned, without the
    closing entry.

    Each step computes what the loop computes per neck, row by row: elementwise ufuncs on the
    stacked rows, the means as sums row after row (as numpy's reduction over the first axis adds
    them), the vectors' norms as ``np.vecdot`` (the dot product ``np.linalg.norm`` takes of one
    vector) and the matrix-vector products as the same BLAS calls (``np.matmul`` on the rings of
    one length, stacked)."""
    la = cyc_at[1::2] - cyc_at[0:-1:2]
    lb = cyc_at[2::2] - cyc_at[1::2]
    a_rows, b_rows = _ring_rows(cyc_at)
    pc = V[necks]
    A = R[a_rows] - np.repeat(pc, la, axis=0)
    B = R[b_rows] - np.repeat(pc, lb, axis=0)
    da = A / np.maximum(np.linalg.norm(A, axis=1), 1e-300)[:, None]
    db = B / np.maximum(np.linalg.norm(B, axis=1), 1e-300)[:, None]
    ax = _segment_means(db, lb) - _segment_means(da, la)
    ax /= np.maximum(np.sqrt(np.vecdot(ax, ax)), 1e-300)[:, None]
    # (_cross3 with (1, 0, 0), and with (0, 1, 0) where that is short: the same products)
    a0, a1, a2 = ax[:, 0], ax[:, 1], ax[:, 2]
    e1 = np.stack([a1 * 0.0 - a2 * 0.0, a2 * 1.0 - a0 * 0.0, a0 * 0.0 - a1 * 1.0], axis=1)
    short = np.sqrt(np.vecdot(e1, e1)) < 0.5
    if short.any():
        e1[short] = np.stack([a1 * 0.0 - a2 * 1.0, a2 * 0.0 - a0 * 0.0, a0 * 1.0 - a1 * 0.0], axis=1)[short]
    e1 /= np.sqrt(np.vecdot(e1, e1))[:, None]
    b0, b1, b2 = e1[:, 0], e1[:, 1], e1[:, 2]
    e2 = np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)
    ta = np.arctan2(_stacked_products(A, la, e2), _stacked_products(A, la, e1))
    tb = np.arctan2(_stacked_products(B, lb, e2), _stacked_products(B, lb, e1))
    # the second ring's start: the first angle nearest the first ring's first
    ta0 = ta[_starts(la)]
    ta0b = np.repeat(ta0, lb)
    j0 = _segment_argmin(np.abs(np.angle(np.exp(1j * (tb - ta0b)))), lb)
    ua = _unwrap_segments(ta - np.repeat(ta0, la), la)
    ub = _unwrap_segments(tb[_rolled_rows(lb, j0)] - ta0b, lb)
    return j0, ua, ub


def _ring_rows(cyc_at):
    """The rows of the first rings' entries in order and of the second rings' reversed."""
    s0, s1, s2 = cyc_at[0:-1:2], cyc_at[1::2], cyc_at[2::2]
    la, lb = s1 - s0, s2 - s1
    a_rows = np.arange(int(la.sum())) + np.repeat(s0 - _starts(la), la)
    # second rings reversed: entry i of neck j -> s2[j] - 1 - i
    i = np.arange(int(lb.sum())) - np.repeat(_starts(lb), lb)
    b_rows = np.repeat(s2 - 1, lb) - i
    return a_rows, b_rows


def _starts(lens):
    """Where each segment of lengths ``lens`` starts in the flat array."""
    out = np.zeros(len(lens), dtype=np.int64)
    np.cumsum(lens[:-1], out=out[1:])
    return out

@njit(cache=True, nogil=True)
def _segment_means(X, lens):
    """Per segment of rows (lengths ``lens``) ``X[seg].mean(axis=0)``: numpy adds the rows one
    after another from the first and divides by their count; so here."""
    out = np.empty((lens.shape[0], X.shape[1]))
    at = 0
    for j in range(lens.shape[0]):
        n = lens[j]
        for d in range(X.shape[1]):
            s = X[at, d]
            for i in range(at + 1, at + n):
                s += X[i, d]
            out[j, d] = s / np.float64(n)
        at += n
    return out


def _stacked_products(X, lens, e):
    """Per segment ``j`` of rows (lengths ``lens``), ``X[seg] @ e[j]``, flat: one ``np.matmul`` per
    length on the segments of that length stacked, which makes the BLAS call of each segment's own
    product (the same matrix-vector call per segment, so the same numbers)."""
    out = np.empty(len(X))
    starts = _starts(lens)
    for n in np.unique(lens).tolist():
        segs = np.flatnonzero(lens == n)
        rows = (starts[segs][:, None] + np.arange(n)).reshape(-1)
        got = np.matmul(X[rows].reshape(len(segs), n, X.shape[1]), e[segs][:, :, None])
        out[rows] = got.reshape(-1)
    return out


@njit(cache=True, nogil=True)
def _segment_argmin(x, lens):
    """Per segment (lengths ``lens``) ``np.argmin`` of its entries: the first least one, or the
    first NaN."""
    out = np.empty(lens.shape[0], np.int64)
    at = 0
    for j in range(lens.shape[0]):
        best = 0
        for i in range(lens[j]):
            v = x[at + i]
            if v != v:
                best = i
                break
            if v < x[at + best]:
                best = i
        out[j] = best
        at += lens[j]
    return out


def _rolled_rows(lens, k):
    """The flat rows of each segment (lengths ``lens``) rolled to start at its entry ``k[j]``
    (``_rolled`` per segment)."""
    starts = _starts(lens)
    i = np.arange(int(lens.sum())) - np.repeat(starts, lens)
    n = np.repeat(lens, lens)
    return np.repeat(starts, lens) + (i + np.repeat(k, lens)) % n


def _unwrap_segments(p, lens):
    """``np.unwrap`` of each segment (lengths ``lens``) of ``p``: its steps made on the whole array
    at once (the differences across two segments made and not used), the corrections summed up
    per segment in order (:func:`_add_segment_cumsums`, numpy's cumsum adds in order)."""
    period = 2 * np.pi
    discont = period / 2
    interval_high = period / 2
    interval_low = -interval_high
    dd = p[1:] - p[:-1]
    ddmod = np.mod(dd - interval_low, period) + interval_low
    np.copyto(ddmod, interval_high, where=(ddmod == interval_low) & (dd > 0))
    ph_correct = ddmod - dd
    np.copyto(ph_correct, 0, where=abs(dd) < discont)
    return _add_segment_cumsums(p, ph_correct, lens)


@njit(cache=True, nogil=True)
def _add_segment_cumsums(p, ph, lens):
    """``up[s] = p[s]`` and ``up[s + i] = p[s + i] + cumsum(ph[s:s + i])[-1]`` per segment from
    ``s`` (``ph[t]``: the correction between entries ``t`` and ``t + 1``)."""
    up = p.copy()
    at = 0
    for j in range(lens.shape[0]):
        c = 0.0
        for i in range(1, lens[j]):
            c = ph[at + i - 1] if i == 1 else c + ph[at + i - 1]
            up[at + i] = p[at + i] + c
        at += lens[j]
    return up


@njit(cache=True, nogil=True)
def _tube_walk(a, b, ua, ub, proportional, faces):
    """The loop's ``walk``: join rings ``a`` and ``b`` (``n``, ``m`` vertices) by ``n + m``
    triangles written to ``faces``, advancing the ring whose next vertex comes first around the
    axis (``ua[i + 1] <= ub[j + 1]``) or, ``proportional``, both in proportion to their sizes;
    returns whether the walk's path visits no pair ``(i % n, j % m)`` twice."""
    n, m = a.shape[0], b.shape[0]
    seen = np.zeros(n * m, np.bool_)
    seen[0] = True
    simple = True
    i = j = 0
    t = 0
    while i < n or j < m:
        if j >= m:
            first = True
        elif proportional:
            first = i < n and (i + 1) * m <= (j + 1) * n
        else:
            first = i < n and ua[i + 1] <= ub[j + 1]
        if first:
            faces[t, 0], faces[t, 1], faces[t, 2] = a[i % n], a[(i + 1) % n], b[j % m]
            i += 1
        else:
            faces[t, 0], faces[t, 1], faces[t, 2] = a[i % n], b[(j + 1) % m], b[j % m]
            j += 1
        t += 1
        if i < n or j < m:  # (the path's last point is not counted)
            q = (i % n) * m + (j % m)
            if seen[q]:
                simple = False
            seen[q] = True
    return simple


@njit(cache=True, nogil=True)
def _test_mesh(V, R, fans, tube, P, Fl):
    """The mesh the loop's :func:`_tube_crosses` tests, without the dict: the fans' and the tube's
    faces in local numbers (their vertices sorted) written to ``Fl`` (one row per face), the points
    to ``P`` (from ``V`` and ``R``: vertex ``len(V) + p`` is ``R[p]``); returns the number of points."""
    n_v = V.shape[0]
    nf = fans.shape[0] + tube.shape[0]
    allv = np.empty(3 * nf, np.int64)
    for i in range(fans.shape[0]):
        for d in range(3):
            allv[3 * i + d] = fans[i, d]
    for i in range(tube.shape[0]):
        for d in range(3):
            allv[3 * (fans.shape[0] + i) + d] = tube[i, d]
    ids = np.unique(allv)
    for t in range(ids.shape[0]):
        v = ids[t]
        for d in range(3):
            P[t, d] = V[v, d] if v < n_v else R[v - n_v, d]
    loc = np.searchsorted(ids, allv)
    for i in range(nf):
        for d in range(3):
            Fl[i, d] = loc[3 * i + d]
    return ids.shape[0]


@njit(cache=True, nogil=True)
def _neck_walks(V, R, fans, cyc_at, j0, ua, ub):
    """Step 3 of :func:`_open_necks`: each neck's tube faces as the loop's first choice makes
    them, rows ``cyc_at[2k]:cyc_at[2k + 2]`` for neck ``k`` (a tube has as many faces as its rings
    have vertices), and the meshes of their crossing tests: ``(tube, P, p_at, Fl)``, neck ``k``'s
    points ``P[p_at[k]:p_at[k + 1]]`` and faces ``Fl[3 cyc_at[2k]:3 cyc_at[2k + 2]]`` (its fans,
    then its tube).  The first ring runs in order, the second reversed and rolled to start at
    ``j0`` (:func:`_second_rings`); the walk by angle, or the proportional one where that path is
    not simple."""
    n_v = V.shape[0]
    k = j0.shape[0]
    tube = np.empty((cyc_at[2 * k], 3), np.int64)
    P = np.empty((2 * cyc_at[2 * k], 3))
    p_at = np.zeros(k + 1, np.int64)
    Fl = np.empty((3 * cyc_at[2 * k], 3), np.int64)
    rings = _second_rings(cyc_at, j0, n_v)
    oa = ob = 0  # (where the neck's entries start in ua, ub)
    for j in range(k):
        s0, s1, s2 = cyc_at[2 * j], cyc_at[2 * j + 1], cyc_at[2 * j + 2]
        n, m = s1 - s0, s2 - s1
        a = np.arange(n_v + s0, n_v + s1)
        b = rings[s1:s2]
        # the unwrapped angles, turned where the first ring runs backwards, and closed
        wa = np.empty(n + 1)
        wb = np.empty(m + 1)
        wa[:n] = ua[oa:oa + n]
        wb[:m] = ub[ob:ob + m]
        oa += n
        ob += m
        if wa[n - 1] < 0:
            for i in range(n):
                wa[i] = -wa[i]
            for i in range(m):
                wb[i] = -wb[i]
        wa[n] = wa[0] + 2 * np.pi
        wb[m] = wb[0] + 2 * np.pi
        faces = tube[s0:s2]
        if not _tube_walk(a, b, wa, wb, np.bool_(False), faces):  # (typed: literals compile it twice)
            _tube_walk(a, b, wa, wb, np.bool_(True), faces)
        got = _test_mesh(V, R, fans[2 * s0:2 * s2], faces, P[p_at[j]:], Fl[3 * s0:3 * s2])
        p_at[j + 1] = p_at[j] + got
    return tube, P, p_at, Fl


@njit(cache=True, nogil=True)
def _second_rings(cyc_at, j0, n_v):
    """Per neck ``k``, at rows ``cyc_at[2k + 1]:cyc_at[2k + 2]``: its second ring's new vertices
    reversed and rolled to start at entry ``j0[k]`` (the loop's ``b``); the other rows not set."""
    out = np.empty(cyc_at[-1], np.int64)
    for j in range(j0.shape[0]):
        s1, s2 = cyc_at[2 * j + 1], cyc_at[2 * j + 2]
        m = s2 - s1
        for i in range(m):
            out[s1 + i] = n_v + s2 - 1 - (j0[j] + i) % m
    return out


def _tube_retry(V, R, fans, faces, a, b, delay):
    """A tube whose first walk crosses its fans or itself (:func:`_neck_walks`): as the loop, the
    proportional walk from each start on the second ring ``b`` in turn, the first simple one
    keeping clear written over ``faces`` (else they are kept); ``a``, ``b``: the rings (lists)."""
    n, m = len(a), len(b)
    n_v = len(V)
    for r in range(m):
        simple, trial = _walk_rings(a, b[r:] + b[:r], lambda i, j: (i + 1) * m <= (j + 1) * n)
        if not simple:
            continue
        f = np.concatenate([fans, np.array(trial, dtype=np.int64)])
        ids, local = np.unique(f.reshape(-1), return_inverse=True)
        P = np.empty((len(ids), 3))
        old = ids < n_v
        P[old] = V[ids[old]]
        P[~old] = R[ids[~old] - n_v]
        if not _any_kernel(P, local.reshape(-1, 3).astype(np.int64), np.int64(delay)):
            faces[:] = trial
            return


@njit(cache=True, nogil=True)
def _neck_faces(cyc_at, fans, fan_alive, tube):
    """Step 4 of :func:`_open_necks`: the faces the necks add, in the loop's order: per neck its
    fan faces left alive (later necks retire those at them), then its tube."""
    k = (cyc_at.shape[0] - 1) // 2
    n = 0
    for i in range(fan_alive.shape[0]):
        n += fan_alive[i]
    out = np.empty((n + tube.shape[0], 3), np.int64)
    t = 0
    for j in range(k):
        s0, s2 = cyc_at[2 * j], cyc_at[2 * j + 2]
        for i in range(2 * s0, 2 * s2):
            if fan_alive[i]:
                out[t] = fans[i]
                t += 1
        for i in range(s0, s2):
            out[t] = tube[i]
            t += 1
    return out


def _open_necks_loop(V, F, S, necks, nudge, tube_seen=None):
    """Replace each neck vertex by a small tube joining its two fans.

    At a mid-plane corner where the two empty voxels of the 2 x 2 x 2 block around it touch only
    at that corner (the six others are object), the surface meets itself in two cones there.  The
    background is 26-connected, so it passes through the point: the cones are joined by a tube
    (the star of the vertex is removed and its two link cycles are joined by a band).
    ``tube_seen``: ``seen`` of :func:`_tube_crosses` (a dict the caller keeps across rebuilds of one mesh);
    it also keeps each neck's rings and faces in local numbers, for a rebuild that meets the same
    neck (the same apex, link points and order of their vertex numbers) again.
    """
    if len(necks) == 0:
        return V, F, S
    neck_ids = np.unique(necks)
    # faces (old and new, by index into `faces`) around each neck vertex, kept up to date
    is_neck = np.zeros(len(V), dtype=bool)  # (np.isin(F, neck_ids), by a lookup table)
    is_neck[neck_ids] = True
    # their rows in F: np.flatnonzero(is_neck[F].any(axis=1)), in one compiled pass where F is the
    # volume mesher's int64 array (the mask of every corner cost 4.5 of the liver's 6.3 ms)
    if isinstance(F, np.ndarray) and F.dtype == np.int64 and F.ndim == 2 and F.shape[1] == 3 and F.flags.c_contiguous:
        old_index = _rows_touching(F, is_neck)
    else:
        old_index = np.flatnonzero(is_neck[F].any(axis=1))
    faces = [tuple(f) for f in F[old_index].tolist()]
    n_old = len(faces)
    star_of = {int(c): [] for c in neck_ids}
    for t, f in enumerate(faces):
        for v in f:
            if v in star_of:
                star_of[v].append(t)
    alive = [True] * n_old
    Vs = [V]
    nv = len(V)
    pos = {}

    n_v = len(V)

    def replace_star(star, new_faces):
        """Retire the faces ``star`` and add ``new_faces``, keeping each neck's face list."""
        for t in star:
            alive[t] = False
        for f in new_faces:
            t = len(faces)
            faces.append(f)
            alive.append(True)
            for v in f:
                if v in star_of:
                    star_of[v].append(t)

    def xyz(ids):
        """The points of vertices ``ids`` (old ones from V, new ones from ``pos``), as
        ``np.array([V[i] if i < len(V) else pos[i] for i in ids])`` gives them."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        if len(ids) == 0 or V.dtype != np.float64:
            return np.array([V[i] if i < n_v else pos[i] for i in ids.tolist()])
        out = np.empty((len(ids), 3))
        old = ids < n_v
        out[old] = V[ids[old]]
        if not old.all():
            out[~old] = np.array([pos[i] for i in ids[~old].tolist()])
        return out

    for c in neck_ids.tolist():  # one at a time: a neck's link may hold another neck
        star = [t for t in star_of.pop(c) if alive[t]]
        link = {}
        for t in star:
            f = faces[t]
            i = f.index(c)
            x, y = f[(i + 1) % 3], f[(i + 2) % 3]
            if x in link:
                raise RuntimeError("internal error: a neck vertex is not the apex of two cones")
            link[x] = y
        cycles = []
        seen = set()
        for x0 in link:
            if x0 in seen:
                continue
            cyc = [x0]
            seen.add(x0)
            x = link[x0]
            while x != x0:
                cyc.append(x)
                seen.add(x)
                x = link[x]
            cycles.append(cyc)
        if len(cycles) != 2:
            raise RuntimeError(f"internal error: a neck vertex has {len(cycles)} fans, expected 2")
        # replace the apex of each cone by a tiny ring of new vertices (one per link vertex,
        # a hair from the apex towards it), then join the two rings by a tube
        new_faces = []
        tube = []
        rings_xyz = []
        pc = xyz([c])[0]
        cyc_xyz = [xyz(cyc) for cyc in cycles]
        # a neck met before (a rebuild of the same mesh meets most of them again): its rings and
        # faces are a function of the apex, the two link cycles' points and the order of their
        # vertex numbers (the tube's crossing test numbers its points so), kept in local numbers
        # (the cycles' vertices, then the new ones) in ``tube_seen``
        memo = got = None
        if tube_seen is not None:
            gids = np.array(cycles[0] + cycles[1], dtype=np.int64)
            memo = ("neck", float(nudge), pc.tobytes(), len(cycles[0]), len(cycles[1]),
                    np.concatenate(cyc_xyz).tobytes(), np.argsort(gids, kind="stable").tobytes())
            got = tube_seen.get(memo)
        if got is not None:
            rings_got, local = got
            glob = np.concatenate([gids, nv + np.arange(len(gids), dtype=np.int64)])
            for ring in rings_got:
                Vs.append(ring)
                pos.update(zip(range(nv, nv + len(ring)), ring))
                nv += len(ring)
            replace_star(star, [tuple(f) for f in glob[local].tolist()])
            continue
        nv0 = nv
        for n_c, cyc in enumerate(cycles):
            eps = nudge * (1.0 + 0.5 * n_c)
            dirs = cyc_xyz[n_c] - pc
            dirs /= np.maximum(np.linalg.norm(dirs, axis=1), 1e-300)[:, None]
            ids = nv + np.arange(len(cyc))
            ring = pc + eps * dirs
            Vs.append(ring)
            ids_l = ids.tolist()
            pos.update(zip(ids_l, ring))
            nv += len(cyc)
            k = len(cyc)
            for t in range(k):
                x, y = cyc[t], cyc[(t + 1) % k]
                rx, ry = ids_l[t], ids_l[(t + 1) % k]
                new_faces += [(rx, x, y), (rx, y, ry)]
            tube.append(ids)
            rings_xyz.append(ring)
        a = tube[0]
        b = tube[1][::-1]
        n, m = len(a), len(b)
        # the tube is short and thin: join the rings by their angle around its axis, so that no
        # two of its triangles overlap (both rings are star-shaped seen along the axis; their
        # points are the rings just made, as xyz gives them)
        ta, tb = _ring_angles(rings_xyz[0] - pc, rings_xyz[1][::-1] - pc)
        i0 = 0
        j0 = int(np.argmin(np.abs(np.angle(np.exp(1j * (tb - ta[0]))))))
        a = _rolled(a, i0).tolist()
        b = _rolled(b, j0).tolist()
        ua = np.unwrap(_rolled(ta, i0) - ta[0])
        ub = np.unwrap(_rolled(tb, j0) - ta[0])
        if ua[-1] < 0:  # both rings turn the same way around the axis; measure that way
            ua, ub = -ua, -ub
        ua = np.r_[ua, ua[0] + 2 * np.pi]
        ub = np.r_[ub, ub[0] + 2 * np.pi]
        # advance the ring whose next vertex comes first around the axis; where that path laps one
        # ring while the other waits (rings that are not star-shaped about the axis: the same
        # diagonal twice, four faces on an edge), advance both in proportion to their sizes instead
        def walk(b, first_of):
            return _walk_rings(a, b, first_of)

        for first_of in (lambda i, j: ua[i + 1] <= ub[j + 1], lambda i, j: (i + 1) * m <= (j + 1) * n):
            simple, tube_faces = walk(b, first_of)
            if simple:
                break
        if _tube_crosses(new_faces, tube_faces, xyz, tube_seen):
            # very flat cones (slices far apart against the pixel size) can defeat both rules: the
            # proportional walk from every start on the second ring, the first whose faces keep clear
            for r in range(m):
                simple, faces_r = walk(b[r:] + b[:r], lambda i, j: (i + 1) * m <= (j + 1) * n)
                if simple and not _tube_crosses(new_faces, faces_r, xyz, tube_seen):
                    tube_faces = faces_r
                    break
        new_faces += tube_faces
        if memo is not None:
            lut = {g: i for i, g in enumerate(cycles[0] + cycles[1])}
            lut.update((nv0 + i, len(gids) + i) for i in range(nv - nv0))
            tube_seen[memo] = (rings_xyz, np.array([[lut[v] for v in f] for f in new_faces], dtype=np.int64).reshape(-1, 3))
        replace_star(star, new_faces)
    keep = np.ones(len(F), dtype=bool)
    keep[old_index[~np.array(alive[:n_old], dtype=bool)]] = False
    added = [f for f, ok in zip(faces[n_old:], alive[n_old:]) if ok]
    F, S = _kept_and_added(F, S, keep, added, [0] * len(added))
    V = np.concatenate(Vs)
    return V, F, S


def _walk_rings(a, b, first_of):
    """The loop's walk joining rings ``a`` and ``b`` (lists): ``(simple, faces)``, the ``len(a) +
    len(b)`` triangles made advancing ``a`` where ``first_of(i, j)`` (else ``b``), and whether the
    path visits no pair ``(i % n, j % m)`` twice (see :func:`_tube_walk`, its compiled form)."""
    n, m = len(a), len(b)
    i = j = 0
    path, tube_faces = [(0, 0)], []
    while i < n or j < m:
        if j >= m or (i < n and first_of(i, j)):
            tube_faces.append((a[i % n], a[(i + 1) % n], b[j % m]))
            i += 1
        else:
            tube_faces.append((a[i % n], b[(j + 1) % m], b[j % m]))
            j += 1
        path.append((i % n, j % m))
    return len(set(path[:-1])) == len(path) - 1, tube_faces


def _tube_crosses(fans, tube, xyz, seen=None) -> bool:
    """True when the faces of a neck's tube cross each other or its two fans (exact test).

    ``seen`` (a dict, optional) keeps the answers by the faces' local numbering and corners'
    coordinates (the test depends on nothing else): a rebuild of the same mesh meets most of its
    necks again."""
    f = np.array(fans + tube, dtype=np.int64)
    ids, local = np.unique(f, return_inverse=True)
    P, Fl = xyz(ids.tolist()), local.reshape(-1, 3).astype(np.int64, copy=False)
    if seen is None:
        return any_intersecting(P, Fl)
    key = (P.shape, P.tobytes(), Fl.tobytes())
    got = seen.get(key)
    if got is None:
        got = seen[key] = bool(any_intersecting(P, Fl))
    return got


def _rolled(a, k):
    """``np.roll(a, -k)`` for a 1-D array and ``0 <= k < len(a)``."""
    return np.concatenate([a[k:], a[:k]])


def _cross3(a, b):
    """``np.cross(a, b)`` of two 3-vectors (the same products and differences, in floats: np.cross
    is slow on single vectors)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _ring_angles(A, B):
    """Angles of the points of two rings (relative to a common apex) around the axis from the
    mean direction of ``A`` to that of ``B``."""
    da = A / np.maximum(np.linalg.norm(A, axis=1), 1e-300)[:, None]
    db = B / np.maximum(np.linalg.norm(B, axis=1), 1e-300)[:, None]
    ax = db.mean(axis=0) - da.mean(axis=0)
    ax /= max(float(np.linalg.norm(ax)), 1e-300)
    e1 = _cross3(ax, (1.0, 0.0, 0.0))
    if np.linalg.norm(e1) < 0.5:
        e1 = _cross3(ax, (0.0, 1.0, 0.0))
    e1 /= np.linalg.norm(e1)
    e2 = _cross3(ax, e1)
    return np.arctan2(A @ e2, A @ e1), np.arctan2(B @ e2, B @ e1)


def _separate_coincident(V, F, nudge, overwrite: bool = False):
    """Move vertices that share a position apart, each towards the centroid of its own faces.

    Only the shared positions' vertices and their faces are touched (a hash groups the positions;
    the sums run over each vertex's corners in face order, as ``np.add.at`` over all of them did):
    the same result as :func:`_separate_coincident_reference`, in time linear in the vertices.
    ``overwrite``: the moves may be made in ``V`` itself (a caller that does not need it any more)."""
    V = np.asarray(V, dtype=np.float64)
    if len(V) == 0:
        return V
    F = np.asarray(F, dtype=np.int64)
    # the vertices whose position another shares (-0.0 and 0.0: one position), each with the first
    # of its position's vertices (a name of its group), in one hashed pass (_shared_rows)
    own = V.flags.c_contiguous and V.ndim == 2 and V.shape[1] == 3
    dup, group, is_dup = _shared_rows(V if own else np.ascontiguousarray(V).reshape(len(V), -1))
    if len(dup) == 0:
        return V
    # the j-th copy of a position (in index order) moves (1 + j/2) nudges: copies heading the same
    # way stay apart
    rank = _copy_rank(group)
    if not (overwrite and own and V.flags.writeable):
        V = V.copy()
    # the sums per shared vertex only, over its corners in face order (one compiled pass)
    acc, deg = _shared_centroid_sums(V, np.ascontiguousarray(F.reshape(-1)), is_dup, dup)
    del is_dup
    target = acc / np.maximum(deg, 1)[:, None]
    d = target - V[dup]
    nrm = np.linalg.norm(d, axis=1)
    ok = nrm > 0
    step = nudge * (1.0 + 0.5 * rank)
    V[dup[ok]] += d[ok] * (step[ok] / nrm[ok])[:, None]
    return V


@njit(cache=True, nogil=True, inline="always")
def _row_hash(V, i, buf, R):
    """The hash of row ``i`` of ``V`` by the bits of its values + 0.0 (left in ``buf``, whose int64
    view is ``R``), mixed as the tests' reference ``row_ids`` (tests/repair_reference.py) mixes a
    row."""
    h = np.uint64(0x9E3779B97F4A7C15)
    for c in range(V.shape[1]):
        buf[c] = V[i, c] + 0.0
        h ^= np.uint64(R[c]) + np.uint64(0x9E3779B97F4A7C15) + (h << np.uint64(6)) + (h >> np.uint64(2))
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(31)
    return h


@njit(cache=True, nogil=True)
def _shared_rows(V):
    """The rows of the float64 array ``V`` whose values another row has too, as the bits of
    ``V + 0.0`` tell (0.0 and -0.0 alike, a NaN like a NaN of the same bits): ``(dup, group,
    mark)``, their numbers (increasing), per such row the first row with its values, and a mark
    per row.  The groups of the reference ``row_ids`` (tests/repair_reference.py) on
    ``(V + 0.0).view(np.int64)`` (``np.bincount(ids)[ids]
    > 1`` there), without that copy of ``V`` or the ids of every row: the rows' hashes are first
    marked in a bitmap of about 8 bits per row (small enough to stay in cache), once and twice
    (each row's bit kept, so that the rows are hashed once: 2.6 -> 1.9 ms on the lobster's mesh);
    the rows whose hash was met twice (every row that shares its values, and a few others) are
    then grouped exactly in an open-addressing table of each group's first row, in row order."""
    n, k = V.shape
    buf = np.empty(k)
    R = buf.view(np.int64)  # (the bits of one row's values + 0.0)
    Q = np.empty(k)
    Rq = Q.view(np.int64)
    bits = 8
    while bits < 8 * n + 8:
        bits *= 2
    once = np.zeros(bits // 8, np.uint8)
    twice = np.zeros(bits // 8, np.uint8)
    kept = bits <= 2**31  # (each row's bit kept for the second pass, where it fits in int32: hashed once)
    slots = np.empty(n if kept else 0, np.int32)
    for i in range(n):
        s = np.int64(_row_hash(V, i, buf, R) >> np.uint64(20)) & (bits - 1)
        if kept:
            slots[i] = s
        b = np.uint8(1 << (s & 7))
        if once[s >> 3] & b:
            twice[s >> 3] |= b
        else:
            once[s >> 3] |= b
    cand = np.empty(n, np.int32)  # (row numbers: 2^31 rows would not fit in memory here)
    nc = 0
    for i in range(n):
        s = np.int64(slots[i]) if kept else np.int64(_row_hash(V, i, buf, R) >> np.uint64(20)) & (bits - 1)
        if twice[s >> 3] & np.uint8(1 << (s & 7)):
            cand[nc] = i
            nc += 1
    size = 1
    while size < 2 * nc + 2:
        size *= 2
    table = np.full(size, -1, np.int32)  # (a group's first candidate)
    first = np.empty(nc, np.int32)
    shared = np.zeros(nc, np.bool_)
    count = 0
    for q in range(nc):
        i = cand[q]
        slot = np.int64(_row_hash(V, i, buf, R) & np.uint64(size - 1))
        while True:
            p = table[slot]
            if p < 0:
                table[slot] = q
                first[q] = i
                break
            j = cand[p]
            same = True
            for c in range(k):
                Q[c] = V[j, c] + 0.0
                if Rq[c] != R[c]:
                    same = False
                    break
            if same:
                first[q] = j
                if not shared[p]:
                    shared[p] = True
                    count += 1
                shared[q] = True
                count += 1
                break
            slot = (slot + 1) & (size - 1)
    mark = np.zeros(n, np.bool_)
    dup = np.empty(count, np.int64)
    group = np.empty(count, np.int64)
    t = 0
    for q in range(nc):
        if shared[q]:
            i = cand[q]
            mark[i] = True
            dup[t] = i
            group[t] = first[q]
            t += 1
    return dup, group, mark


@njit(cache=True, nogil=True)
def _shared_centroid_sums(V, corner_v, mark, dup):
    """:func:`_separate_coincident`'s sums, in one pass over the corners (``corner_v``, the faces
    flat): per vertex of ``dup`` (increasing; ``mark`` per vertex) the sum of its faces' centroids
    over its corners in face order and their count, ``(acc, deg)``.  Each centroid ``((a + b) +
    c) / 3``, added from zero in corner order: the bits of the numpy form before (kept in
    ``tests/test_vertex_fans.py``: the corners ``np.flatnonzero(mark[corner_v])``, ``V[F[corners
    // 3]].mean(axis=1)`` added at each corner's place in ``dup`` by ``np.add.at``, the counts by
    ``np.bincount``), without its arrays (2.4 -> 0.5 ms a build on the lobster's mesh)."""
    k = dup.shape[0]
    acc = np.zeros((k, 3))
    deg = np.zeros(k)
    for c in range(corner_v.shape[0]):
        v = corner_v[c]
        if mark[v]:
            j = np.searchsorted(dup, v)
            i = c - c % 3
            for d in range(3):
                acc[j, d] += ((V[corner_v[i], d] + V[corner_v[i + 1], d]) + V[corner_v[i + 2], d]) / 3.0
            deg[j] += 1.0
    return acc, deg


def _copy_rank(groups):
    """For each entry of ``groups`` (position ids, entries in index order), how many earlier
    entries share its id: 0 for the first copy of a position, 1 for the second, ..."""
    order = np.argsort(groups, kind="stable")
    rank = np.empty(len(groups), dtype=np.int64)
    grp = groups[order]
    starts = np.r_[0, np.flatnonzero(np.diff(grp)) + 1]
    rank[order] = np.arange(len(groups)) - np.repeat(starts, np.diff(np.r_[starts, len(groups)]))
    return rank


def _separate_coincident_reference(V, F, nudge):
    """:func:`_separate_coincident` over the whole mesh (sorted groups, ``np.add.at`` over every
    corner): the reference it is tested against."""
    inv, cnt = _group_rows(V)
    dup = np.flatnonzero(cnt[inv] > 1)
    if len(dup) == 0:
        return V
    # the j-th copy of a position (in index order) moves (1 + j/2) nudges: copies heading the same
    # way stay apart
    rank = _copy_rank(inv[dup])
    V = V.copy()
    cen = V[F].mean(axis=1)
    corner_v = F.reshape(-1)
    corner_f = np.repeat(np.arange(len(F)), 3)
    acc = np.zeros((len(V), 3))
    np.add.at(acc, corner_v, cen[corner_f])
    deg = np.bincount(corner_v, minlength=len(V)).astype(np.float64)
    target = acc[dup] / np.maximum(deg[dup], 1)[:, None]
    d = target - V[dup]
    nrm = np.linalg.norm(d, axis=1)
    ok = nrm > 0
    step = nudge * (1.0 + 0.5 * rank)
    V[dup[ok]] += d[ok] * (step[ok] / nrm[ok])[:, None]
    return V


def _group_rows(V):
    """``(inv, cnt)``: a group number per row of ``V`` (rows with equal values share it) and the
    size of each group; like ``np.unique(V, axis=0, return_inverse=True, return_counts=True)``
    without sorting the rows as records."""
    if len(V) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.lexsort(V.T[::-1])
    sv = V[order]
    new = np.r_[True, np.any(sv[1:] != sv[:-1], axis=1)]
    gid = np.cumsum(new) - 1
    inv = np.empty(len(V), dtype=np.int64)
    inv[order] = gid
    return inv, np.bincount(gid)


def _compact(V, F, overwrite: bool = False):
    """The vertices the faces use, and the faces renumbered to them (``overwrite``: in ``F``
    itself, an int64 C array the caller does not need any more); every vertex used: ``V, F``."""
    used = remap = None
    if F.dtype == np.int64 and F.flags.c_contiguous:  # (the same arrays, in one compiled pass)
        ok, used, remap = _used_remap(F.reshape(-1), len(V))
        if ok and remap is None:
            return V, F
        if not ok:  # (a number out of range: np.bincount's answer or error)
            used = remap = None
    if used is None:
        used = np.flatnonzero(np.bincount(F.reshape(-1), minlength=len(V)))
        if len(used) == len(V):
            return V, F
        remap = np.full(len(V), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
    # (np.take along the rows: the same rows as V[used], some four times faster on a mesh's
    # vertices: 1.4 -> 0.35 ms on the lobster's)
    if overwrite and F.dtype == np.int64 and F.flags.c_contiguous and F.flags.writeable:
        _renumber(F.reshape(-1), remap)
        return np.take(V, used, axis=0), F
    return np.take(V, used, axis=0), remap[F]


@njit(cache=True, nogil=True)
def _used_remap(a, nv):
    """:func:`_compact`'s ``used`` (the vertices among ``a``, increasing) and ``remap`` (their new
    numbers, -1 for the others) from the 1-D int64 ``a``: ``(ok, used, remap)``, ``remap`` None
    where every vertex is used, ``ok`` False (nothing made) where a number is not below ``nv``
    or negative."""
    seen = np.zeros(nv, np.bool_)
    for i in range(a.shape[0]):
        v = a[i]
        if v < 0 or v >= nv:
            return False, None, None
        seen[v] = True
    n = 0
    for v in range(nv):
        n += seen[v]
    if n == nv:
        return True, None, None
    used = np.empty(n, np.int64)
    remap = np.empty(nv, np.int64)
    t = 0
    for v in range(nv):
        if seen[v]:
            used[t] = v
            remap[v] = t
            t += 1
        else:
            remap[v] = -1
    return True, used, remap


# ------------------------------------------------------------------------------------------------
# crossing faces: detect them exactly and pull the faces involved apart
# ------------------------------------------------------------------------------------------------
def _vertex_normals(V, F):
    """Area-weighted outward vertex normals (unit length; zero where the faces cancel)."""
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    vn = _add_at_rows(np.zeros_like(V), F, fn)
    nrm = np.linalg.norm(vn, axis=1)
    out = np.zeros_like(vn)
    ok = nrm > 0
    out[ok] = vn[ok] / nrm[ok, None]
    return out


def _vertex_normals_at(V, F, ids):
    """``_vertex_normals(V, F)[ids]`` (``ids`` distinct), from the faces at those vertices only:
    each sum takes the same face normals in the same order (corner 0 of every face, then 1, then
    2, faces in order), so the same bits."""
    ids = np.asarray(ids, dtype=np.int64)
    pos = np.full(len(V), len(ids), dtype=np.int64)  # row len(ids): a sink for the other vertices
    pos[ids] = np.arange(len(ids))
    mark = np.zeros(len(V), dtype=bool)
    mark[ids] = True
    # (the faces at those vertices in one compiled pass: numpy's pos[F] and .any(axis=1) over the
    # whole mesh took most of this call)
    sel = _rows_touching(np.ascontiguousarray(F, dtype=np.int64), mark)
    Fs = F[sel]
    fn = np.cross(V[Fs[:, 1]] - V[Fs[:, 0]], V[Fs[:, 2]] - V[Fs[:, 0]])
    vn = _add_at_rows(np.zeros((len(ids) + 1, 3)), pos[Fs], fn)[:-1]
    nrm = np.linalg.norm(vn, axis=1)
    out = np.zeros_like(vn)
    ok = nrm > 0
    out[ok] = vn[ok] / nrm[ok, None]
    return out


@njit(cache=True, nogil=True)
def _add_at_rows(acc, F, rows):
    """``np.add.at(acc, F[:, k], rows)`` for k = 0, 1, 2 in turn (the same sums, in the same order)."""
    for k in range(3):
        for i in range(F.shape[0]):
            v = F[i, k]
            for d in range(acc.shape[1]):
                acc[v, d] += rows[i, d]
    return acc


def _faces_near(V, W, F, moved_faces):
    """Indices of the faces whose bounding box (in ``V`` or ``W``) may meet the bounding box (in
    ``V`` or ``W``) of a face in ``moved_faces`` (a superset: faces sharing a grid cell with one):
    every face that can meet a moved face, whichever position it is in.

    The boxes are not kept: their extents, then their cells, are made from the corners in two
    compiled passes (the same numbers as from the boxes: minima, maxima and one subtraction and
    division each), the second testing each face's cells as it makes them
    (:func:`_near_cells`); the boxes, their extents and the float cells of the whole mesh took
    some 60 MiB on the lobster's mesh, at the general mesher's peak."""
    moved = np.asarray(moved_faces, dtype=np.int64)
    glo, ext = _box_extents(V, W, F, True)
    # cells as large as the moved faces (so each covers a few), and no smaller than most faces
    h = max(float(ext[moved].max()), float(np.median(ext)), 1e-12)
    return np.flatnonzero(_near_cells(V, W, F, glo, h, moved, True))


@njit(cache=True, nogil=True, inline="always")
def _face_box(V, W, F, i, d, both):
    """The extent ``(lo, hi)`` along axis ``d`` of face ``i``'s corners in ``V`` (and in ``W``
    with ``both``).  (Inlined: a call per face and axis, and a loop over the tuple ``(V, W)``,
    made the passes over the faces five times slower; numba's ``min`` and ``max`` of several
    numbers compare them left to right, as that loop did.)"""
    x0, x1, x2 = V[F[i, 0], d], V[F[i, 1], d], V[F[i, 2], d]
    if not both:
        return min(x0, x1, x2), max(x0, x1, x2)
    w0, w1, w2 = W[F[i, 0], d], W[F[i, 1], d], W[F[i, 2], d]
    return min(x0, x1, x2, w0, w1, w2), max(x0, x1, x2, w0, w1, w2)


@njit(cache=True, nogil=True)
def _box_extents(V, W, F, both):
    """``(glo, ext)``: the low corner of all the faces' boxes (corners in ``V``, and ``W`` with
    ``both``), and per face the longest side of its box.  :func:`_face_box` written out (the same
    comparisons in the same order): inlined, it counted its three arrays in and out on each of its
    three calls a face (the lobster's two calls 9.6 -> 8.5 ms CPU, replayed)."""
    glo = np.full(3, np.inf)
    ext = np.empty(F.shape[0])
    for i in range(F.shape[0]):
        e = 0.0
        f0, f1, f2 = F[i, 0], F[i, 1], F[i, 2]
        for d in range(3):
            x0, x1, x2 = V[f0, d], V[f1, d], V[f2, d]
            if not both:
                a, b = min(x0, x1, x2), max(x0, x1, x2)
            else:
                w0, w1, w2 = W[f0, d], W[f1, d], W[f2, d]
                a, b = min(x0, x1, x2, w0, w1, w2), max(x0, x1, x2, w0, w1, w2)
            glo[d] = min(glo[d], a)
            e = max(e, b - a)
        ext[i] = e
    return glo, ext


@njit(cache=True, nogil=True)
def _near_cells(V, W, F, glo, h, chosen, both):
    """Per face, whether it shares a cell of the grid of size ``h`` from ``glo`` with a face in
    ``chosen`` (boxes as :func:`_box_extents`; a face's cells along an axis ``floor((lo - glo) /
    h) .. floor((hi - glo) / h)``): the chosen faces' cells fill a table, every other face's are made and
    looked up in turn (no array of the whole mesh's cells)."""
    k = len(chosen)
    clo = np.empty((k, 3), np.int64)
    chi = np.empty((k, 3), np.int64)
    for t in range(k):
        for d in range(3):
            clo[t, d], chi[t, d] = _face_cells(V, W, F, chosen[t], d, glo, h, both)
    keys, used = _cell_table(clo, chi, np.arange(k))
    n = F.shape[0]
    near = np.zeros(n, np.bool_)
    for t in range(k):
        near[chosen[t]] = True
    # the layers of cells (along z) that hold a chosen face's cell: a face in none of them shares
    # no cell, found without its x and y cells or the table (the rebuild's re-test: most faces lie
    # away from the remade joins' heights).  Only where the layers are few enough to list.
    zlo = np.int64(0)
    zhi = np.int64(-1)
    for t in range(k):
        if t == 0 or clo[t, 2] < zlo:
            zlo = clo[t, 2]
        if t == 0 or chi[t, 2] > zhi:
            zhi = chi[t, 2]
    layers = k > 0 and zhi - zlo < 4 * n + 1024
    zocc = np.zeros(zhi - zlo + 1 if layers else 0, np.bool_)
    if layers:
        for t in range(k):
            for z in range(clo[t, 2], chi[t, 2] + 1):
                zocc[z - zlo] = True
    for i in range(n):
        if near[i]:
            continue
        z0, z1 = _face_cells(V, W, F, i, 2, glo, h, both)
        if layers:
            hit = False
            for z in range(max(z0, zlo), min(z1, zhi) + 1):
                if zocc[z - zlo]:
                    hit = True
                    break
            if not hit:
                continue
        x0, x1 = _face_cells(V, W, F, i, 0, glo, h, both)
        y0, y1 = _face_cells(V, W, F, i, 1, glo, h, both)
        near[i] = _in_cells(keys, used, x0, x1, y0, y1, z0, z1)
    return near


@njit(cache=True, nogil=True, inline="always")
def _face_cells(V, W, F, i, d, glo, h, both):
    """The cells of face ``i``'s box along axis ``d`` (see :func:`_near_cells`)."""
    a, b = _face_box(V, W, F, i, d, both)
    return np.int64(np.floor((a - glo[d]) / h)), np.int64(np.floor((b - glo[d]) / h))


@njit(cache=True, nogil=True, inline="always")
def _cell_slot(x, y, z, size):
    return np.int64((np.uint64(x) * np.uint64(73856093) ^ np.uint64(y) * np.uint64(19349663)
                     ^ np.uint64(z) * np.uint64(83492791)) & np.uint64(size - 1))


@njit(cache=True, nogil=True)
def _cell_table(clo, chi, rows):
    """An open-addressing set ``(keys, used)`` of the cells ``clo[r] .. chi[r]`` for ``r`` in
    ``rows``."""
    ncell = 0
    for t in range(len(rows)):
        r = rows[t]
        ncell += (chi[r, 0] - clo[r, 0] + 1) * (chi[r, 1] - clo[r, 1] + 1) * (chi[r, 2] - clo[r, 2] + 1)
    size = 1
    while size < 2 * ncell + 2:
        size *= 2
    keys = np.empty((size, 3), np.int64)
    used = np.zeros(size, np.bool_)
    for t in range(len(rows)):
        r = rows[t]
        for x in range(clo[r, 0], chi[r, 0] + 1):
            for y in range(clo[r, 1], chi[r, 1] + 1):
                for z in range(clo[r, 2], chi[r, 2] + 1):
                    slot = _cell_slot(x, y, z, size)
                    while used[slot] and not (keys[slot, 0] == x and keys[slot, 1] == y and keys[slot, 2] == z):
                        slot = (slot + 1) & (size - 1)
                    used[slot] = True
                    keys[slot, 0], keys[slot, 1], keys[slot, 2] = x, y, z
    return keys, used


@njit(cache=True, nogil=True)
def _in_cells(keys, used, x0, x1, y0, y1, z0, z1):
    """Whether a cell of ``x0 .. x1, y0 .. y1, z0 .. z1`` is in the set (:func:`_cell_table`)."""
    size = used.shape[0]
    for x in range(x0, x1 + 1):
        for y in range(y0, y1 + 1):
            for z in range(z0, z1 + 1):
                slot = _cell_slot(x, y, z, size)
                while used[slot]:
                    if keys[slot, 0] == x and keys[slot, 1] == y and keys[slot, 2] == z:
                        return True
                    slot = (slot + 1) & (size - 1)
    return False


def _face_position_keys(V0, F0, V1, F1):
    """One integer per face of two meshes such that two faces (of either mesh) get the same
    number exactly when they have the same three corner positions (in any order; positions equal
    bit for bit after ``-0.0`` becomes ``0.0``).

    The second mesh is mostly the first one's vertices and faces in the same order, with some
    runs left out, put in or changed (a rebuild remakes a few joins and caps): its rows are
    matched against the first mesh's next row first, and looked up only where that fails
    (:func:`_row_ids_after`, :func:`_face_groups_after`).  The positions' numbers are those of
    the tests' reference ``row_ids`` on both meshes' rows; the faces' numbers group them as its
    ``face_groups`` does (the same groups, in another order; both in tests/repair_reference.py)."""
    b0 = np.asarray(V0, dtype=np.float64) + 0.0  # (-0.0 + 0.0 == +0.0: one bit pattern per number)
    b1 = np.asarray(V1, dtype=np.float64) + 0.0
    pos = _row_ids_after(np.ascontiguousarray(b0).view(np.int64), np.ascontiguousarray(b1).view(np.int64))
    del b0, b1
    key = _face_groups_after(pos, np.ascontiguousarray(F0), np.ascontiguousarray(F1), np.int64(len(V0)))
    return key[: len(F0)], key[len(F0):]


@njit(cache=True, nogil=True)
def _row_key_hash(R, i, k):
    """The reference ``row_ids``' hash of row ``i`` of ``R`` (``k`` columns)."""
    h = np.uint64(0x9E3779B97F4A7C15)
    for c in range(k):
        h ^= np.uint64(R[i, c]) + np.uint64(0x9E3779B97F4A7C15) + (h << np.uint64(6)) + (h >> np.uint64(2))
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(31)
    return h


@njit(cache=True, nogil=True)
def _row_ids_after(R0, R1):
    """``row_ids(np.concatenate([R0, R1]), False)`` (the tests' reference, in
    tests/repair_reference.py): the same numbers, for a second array ``R1`` whose rows mostly
    follow the rows of ``R0`` in their order (a rebuilt mesh's vertices after the first build's):
    a row of ``R1`` equal to the row of ``R0`` after the one its previous row matched takes that
    row's number without a look-up in the hash table; the others are looked up (and put in) as
    the reference does.  On the lobster's rebuild (2 x 0.2 M vertices) 99 % of the second mesh's
    rows match so."""
    n0, k = R0.shape
    n1 = R1.shape[0]
    n = n0 + n1
    size = 1
    while size < 2 * n + 2:
        size *= 2
    # (the table as row_ids', by row number over both arrays: R0's rows, then R1's from n0)
    table = np.full(size, -1, np.int32)
    ids = np.empty(n, np.int64)
    count = 0
    cur = np.int64(-1)  # the row of R0 the previous row of R1 matched
    for i in range(n):
        if i >= n0:
            c = cur + 1
            if c < n0:
                same = True
                for t in range(k):
                    if R0[c, t] != R1[i - n0, t]:
                        same = False
                        break
                if same:
                    ids[i] = ids[c]
                    cur = c
                    continue
        if i < n0:
            h = _row_key_hash(R0, i, k)
        else:
            h = _row_key_hash(R1, i - n0, k)
        slot = np.int64(h & np.uint64(size - 1))
        while True:
            j = table[slot]
            if j < 0:
                table[slot] = i
                ids[i] = count
                count += 1
                break
            same = True
            for t in range(k):
                a = R0[j, t] if j < n0 else R1[j - n0, t]
                b = R0[i, t] if i < n0 else R1[i - n0, t]
                if a != b:
                    same = False
                    break
            if same:
                ids[i] = ids[j]
                if i >= n0 and j < n0:
                    cur = j
                break
            slot = (slot + 1) & (size - 1)
    return ids


@njit(cache=True, nogil=True, inline="always")
def _face_key(pos, F, off, g):
    """Face ``g`` of ``F`` as its corners' positions ``pos[off + F[g]]``, sorted (a face's key in
    :func:`_face_groups_after`, for either mesh)."""
    a = pos[off + F[g, 0]]
    b = pos[off + F[g, 1]]
    c = pos[off + F[g, 2]]
    if a > b:
        a, b = b, a
    if b > c:
        b, c = c, b
    if a > b:
        a, b = b, a
    return a, b, c


@njit(cache=True, nogil=True)
def _face_groups_after(pos, F0, F1, off):
    """A group number per face of ``F0`` then ``F1`` (corners ``pos[v]`` and ``pos[off + v]``):
    faces share one exactly when their sets of three corner numbers are equal, as in the tests'
    reference ``face_groups`` (tests/repair_reference.py; the same groups, int32 numbers in
    another order).  For a second mesh
    ``F1`` whose faces mostly follow the first one's in their order (a rebuild's): the faces of
    ``F0`` are grouped as there (by smallest corner and edge); a face of ``F1`` whose corners are
    those of the face of ``F0`` after the one its previous face matched takes that face's number;
    the others are looked up among the faces of ``F0`` with their smallest corner, and those not
    found (new faces) are grouped among themselves by the same lists.  On the lobster's rebuild
    (0.4 M faces each) 99 % of ``F1`` matches the next face; the sorted corners are kept for both
    meshes, as there, but the lists (``order``, ``nxt``) are ``F0``'s alone (the general mesher's
    memory peaks on the lobster here)."""
    m0 = len(F0)
    m1 = len(F1)
    npos = np.int64(0)
    for v in range(len(pos)):
        npos = max(npos, pos[v] + 1)
    if m0 + m1 >= 2**31 - 1 or npos >= 2**31 - 1:
        raise MemoryError("too many faces or corner positions for the int32 work arrays")
    T = np.empty((m0, 3), np.int32)  # each face of F0's corner numbers, sorted
    start = np.zeros(npos + 1, np.int32)
    for g in range(m0):
        a, b, c = _face_key(pos, F0, 0, g)
        T[g, 0] = a
        T[g, 1] = b
        T[g, 2] = c
        start[a + 1] += 1
    for q in range(npos):
        start[q + 1] += start[q]
    order = np.empty(m0, np.int32)
    fill = start[:npos].copy()
    for g in range(m0):
        order[fill[T[g, 0]]] = g
        fill[T[g, 0]] += 1
    head = np.empty(npos, np.int32)  # per middle corner: the first face of its list (stamped)
    stamp = np.full(npos, -1, np.int32)
    nxt = np.empty(m0, np.int32)
    ids = np.empty(m0 + m1, np.int32)
    count = 0
    for a in range(npos):
        for r in range(start[a], start[a + 1]):
            g = order[r]
            b = T[g, 1]
            c = T[g, 2]
            if stamp[b] != a:
                stamp[b] = a
                head[b] = -1
            h = head[b]
            while h >= 0 and T[h, 2] != c:
                h = nxt[h]
            if h >= 0:
                ids[g] = ids[h]
            else:
                ids[g] = count
                count += 1
                nxt[g] = head[b]
                head[b] = g
    # F1: the next face of F0 first, then F0's faces with the same smallest corner
    new = np.empty(m1, np.int32)  # the faces of F1 found in neither way
    T1 = np.empty((m1, 3), np.int32)
    nnew = 0
    cur = np.int64(-1)
    for g in range(m1):
        a, b, c = _face_key(pos, F1, off, g)
        T1[g, 0] = a
        T1[g, 1] = b
        T1[g, 2] = c
        q = cur + 1
        if q < m0 and T[q, 0] == a and T[q, 1] == b and T[q, 2] == c:
            ids[m0 + g] = ids[q]
            cur = q
            continue
        found = -1
        for r in range(start[a], start[a + 1]):
            h = order[r]
            if T[h, 1] == b and T[h, 2] == c:
                found = h
                break
        if found >= 0:
            ids[m0 + g] = ids[found]
            cur = found
        else:
            new[nnew] = g
            nnew += 1
    # the new faces among themselves: by smallest corner (a counting sort of the few) and edge
    if nnew > 0:
        cnt = np.zeros(npos + 1, np.int32)
        for t in range(nnew):
            cnt[T1[new[t], 0] + 1] += 1
        for q in range(npos):
            cnt[q + 1] += cnt[q]
        byc = np.empty(nnew, np.int32)
        for t in range(nnew):
            a = T1[new[t], 0]
            byc[cnt[a]] = new[t]
            cnt[a] += 1
        nxt1 = np.empty(m1, np.int32)
        stamp[:] = -1
        for t in range(nnew):  # (byc is in order of smallest corner: a run per corner)
            g = byc[t]
            a = T1[g, 0]
            b = T1[g, 1]
            c = T1[g, 2]
            if stamp[b] != a:
                stamp[b] = a
                head[b] = -1
            h = head[b]
            while h >= 0 and T1[h, 2] != c:
                h = nxt1[h]
            if h >= 0:
                ids[m0 + g] = ids[m0 + h]
            else:
                ids[m0 + g] = count
                count += 1
                nxt1[g] = head[b]
                head[b] = g
    return ids


@njit(cache=True, nogil=True)
def _boxes_near(V, F, chosen):
    """Faces sharing a cell of a grid with a face in ``chosen``: a superset of the faces whose
    closed bounding boxes meet the box of a chosen face.  The cells are as large as the chosen
    faces and no smaller than most faces.  (The faces' boxes are not kept: see :func:`_faces_near`.)"""
    glo, ext = _box_extents(V, V, F, np.bool_(False))  # (typed: a literal compiles it twice)
    h = max(np.median(ext), 1e-12)
    for t in range(len(chosen)):
        h = max(h, ext[chosen[t]])
    return np.flatnonzero(_near_cells(V, V, F, glo, h, chosen, np.bool_(False)))



#: How many faces' box sides (spread evenly over the mesh) :func:`_changed_faces_near` takes the
#: median of for its cells' size.
_NEAR_SAMPLE = 4096


@njit(cache=True, nogil=True)
def _changed_faces_near(V, F, chosen, sample):
    """:func:`_boxes_near` for the rebuild's re-test: the faces sharing a cell of a grid with a
    face in ``chosen`` (a superset of the faces whose boxes meet a chosen face's box), without a
    pass over every face's box first: the cells are as large as the chosen faces and no smaller
    than the median side of ``sample`` faces spread over the mesh, and the grid starts at the
    chosen faces' low corner.  The pairs of the faces found are tested and those with a chosen
    face kept, so any such superset gives the same pairs; the whole mesh's boxes and their median
    were a third of :func:`_boxes_near` on the lobster's rebuild.  (Where the chosen faces' boxes
    are not finite, none: the caller then uses :func:`_boxes_near`.)"""
    n = F.shape[0]
    step = max(np.int64(1), n // max(np.int64(1), sample))
    ext = np.empty((n + step - 1) // step)
    for t in range(len(ext)):
        e = 0.0
        for d in range(3):
            a, b = _face_box(V, V, F, t * step, d, False)
            e = max(e, b - a)
        ext[t] = e
    h = max(np.median(ext), 1e-12)
    glo = np.full(3, np.inf)
    for t in range(len(chosen)):
        for d in range(3):
            a, b = _face_box(V, V, F, chosen[t], d, False)
            glo[d] = min(glo[d], a)
            h = max(h, b - a)
    for d in range(3):
        if not np.isfinite(glo[d]):
            return np.zeros(0, np.int64)
    if not np.isfinite(h):
        return np.zeros(0, np.int64)
    return np.flatnonzero(_near_cells(V, V, F, glo, h, chosen, np.bool_(False)))


@njit(cache=True, nogil=True)
def _kept_faces(k0, k1, nk):
    """``(kept, new_of_old)`` from the face keys ``k0`` of the old mesh and ``k1`` of the new one
    (:func:`_face_position_keys`, below ``nk``): ``kept[j]`` where new face ``j``'s key occurs once
    among the old faces and once among the new ones, and ``new_of_old[i]`` that ``j`` for the old
    face ``i`` with that key (-1 for the other old faces).  What the numpy form (two ``bincount``
    and the masks, kept in ``tests/test_rebuild_checks.py``) gives, in one pass over each key
    array and int32 counts: a face occurs at most ``len(k0) + len(k1)`` times."""
    c0 = np.zeros(nk, np.int32)
    c1 = np.zeros(nk, np.int32)
    old_of_key = np.empty(nk, np.int32)  # (read only where the key occurs once in k0: set there)
    for i in range(len(k0)):
        g = k0[i]
        c0[g] += 1
        old_of_key[g] = i
    for j in range(len(k1)):
        c1[k1[j]] += 1
    kept = np.empty(len(k1), np.bool_)
    new_of_old = np.full(len(k0), -1, np.int64)
    for j in range(len(k1)):
        g = k1[j]
        kept[j] = c0[g] == 1 and c1[g] == 1
        if kept[j]:
            new_of_old[old_of_key[g]] = j
    return kept, new_of_old


@njit(cache=True, nogil=True, inline="always")
def _same_corners(VA, FA, a, VB, FB, b):
    """Whether face ``a`` of ``(VA, FA)`` and face ``b`` of ``(VB, FB)`` have the same three corner
    positions, in any order (compared as numbers: ``-0.0`` equals ``0.0``, a NaN equals nothing)."""
    for s in range(6):  # (the corners of b in each of their six orders; the first is the usual one)
        same = True
        for t in range(3):
            u = FA[a, t]
            w = FB[b, _CORNER_ORDERS[s, t]]
            if VA[u, 0] != VB[w, 0] or VA[u, 1] != VB[w, 1] or VA[u, 2] != VB[w, 2]:
                same = False
                break
        if same:
            return True
    return False


_CORNER_ORDERS = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]], dtype=np.int64)


@njit(cache=True, nogil=True, inline="always")
def _corner_bits(B, v, c):
    """Coordinate ``c`` of vertex ``v`` as its bits (``B``: the coordinates viewed as int64), with
    ``-0.0`` as ``0.0`` so that equal numbers hash alike."""
    x = B[v, c]
    return np.int64(0) if x == np.int64(-9223372036854775808) else x


@njit(cache=True, nogil=True)
def _corner_set_hash(B, F, g):
    """A hash of face ``g``'s three corner positions that does not depend on their order (a sum of
    one mixed number per corner)."""
    h = np.uint64(0)
    for t in range(3):
        v = F[g, t]
        x = np.uint64(0x9E3779B97F4A7C15)
        for c in range(3):
            x ^= np.uint64(_corner_bits(B, v, c)) + np.uint64(0x9E3779B97F4A7C15) + (x << np.uint64(6)) + (x >> np.uint64(2))
            x *= np.uint64(0xBF58476D1CE4E5B9)
            x ^= x >> np.uint64(31)
        h += x
    return h


#: The rebuild's face matching (:func:`_faces_in_order`): how many faces of the first mesh, from a
#: little before the next expected one, a look-up covers; and how far before it the window starts.
_MATCH_WINDOW = 2048
_MATCH_BEHIND = 64


@njit(cache=True, nogil=True)
def _faces_in_order(V0, B0, F0, V1, B1, F1, window, behind):
    """For each face of ``F1``, a face of ``F0`` with the same corner positions, or -1: each face of
    ``F0`` given to one face of ``F1`` at most.

    A rebuilt mesh's faces are mostly the first build's in their order, with runs left out or put
    in and a few moved a little: a face is compared with the face after the one the previous face
    matched first; where that fails it is looked up (by a hash of its corners, :func:`_corner_set_hash`)
    among the faces of ``F0`` from ``behind`` faces before that one over a ``window`` of faces,
    hashed as the look-ups need them.  A face found in neither way gets -1 (it is then tested as a
    new face: a match missed costs time, never pairs).  ``B0`` and ``B1`` are the coordinates'
    bits (``V0.view(np.int64)``)."""
    m0 = len(F0)
    m1 = len(F1)
    old = np.full(m1, -1, np.int64)
    used = np.zeros(m0, np.bool_)
    size = 1
    while size < 2 * window:
        size *= 2
    slot_of = np.full(size, -1, np.int64)  # the window's faces of F0 by hash (open addressing)
    lo = np.int64(-1)  # the window's first face (-1: none yet)
    hi = np.int64(-1)
    q = np.int64(0)  # the face of F0 expected next
    for g in range(m1):
        if q < m0 and not used[q] and _same_corners(V0, F0, q, V1, F1, g):
            old[g] = q
            used[q] = True
            q += 1
            continue
        if lo < 0 or q - behind < lo or q + window // 2 > hi:
            lo = max(np.int64(0), q - behind)
            hi = min(np.int64(m0), lo + window)
            slot_of[:] = -1
            for r in range(lo, hi):
                s = np.int64(_corner_set_hash(B0, F0, r) & np.uint64(size - 1))
                while slot_of[s] >= 0:
                    s = (s + 1) & (size - 1)
                slot_of[s] = r
        s = np.int64(_corner_set_hash(B1, F1, g) & np.uint64(size - 1))
        while slot_of[s] >= 0:
            r = slot_of[s]
            if not used[r] and _same_corners(V0, F0, r, V1, F1, g):
                old[g] = r
                used[r] = True
                q = r + 1
                break
            s = (s + 1) & (size - 1)
    return old


@njit(cache=True, nogil=True)
def _new_of_old(old, m0):
    """The inverse of :func:`_faces_in_order`'s matching: per face of the first mesh, the face of
    the second given to it, or -1."""
    out = np.full(m0, -1, np.int64)
    for g in range(len(old)):
        if old[g] >= 0:
            out[old[g]] = g
    return out


def _kept_faces_after(V0, F0, V1, F1):
    """``(kept, new_of_old)``: ``kept[j]`` where face ``j`` of ``F1`` is given a face of ``F0`` with
    the same corner positions, ``new_of_old[i]`` the face of ``F1`` given old face ``i`` (or -1); no
    face given twice.  Pairs of kept faces cross as their old faces did; the others are tested.

    The faces are matched in their order (:func:`_faces_in_order`: a rebuild's faces are mostly
    the first build's, so this reads each mesh once and hashes only a window of faces round where
    the order breaks).  Where that leaves many faces unmatched (meshes not in the same order),
    faces are grouped by their positions over both meshes (:func:`_face_position_keys`), which
    keeps the faces that occur once in each.  On the lobster's rebuild (0.4 M faces each) the order
    leaves the same 1040 faces to test as the keys, in 6-7 ms of CPU instead of 17-18."""
    V0 = np.ascontiguousarray(V0)
    V1 = np.ascontiguousarray(V1)
    F0 = np.ascontiguousarray(F0)
    F1 = np.ascontiguousarray(F1)
    old = _faces_in_order(V0, V0.view(np.int64), F0, V1, V1.view(np.int64), F1,
                          np.int64(_MATCH_WINDOW), np.int64(_MATCH_BEHIND))
    kept = old >= 0
    if len(F1) - np.count_nonzero(kept) <= max(256, len(F1) // 16):
        return kept, _new_of_old(old, np.int64(len(F0)))
    k0, k1 = _face_position_keys(V0, F0, V1, F1)
    nk = int(max(k0.max(initial=-1), k1.max(initial=-1))) + 1
    # (one compiled pass, with int32 counts, instead of the whole-mesh temporaries of the numpy form)
    return _kept_faces(k0, k1, np.int64(nk))


def crossing_pairs_after_change(V0, F0, pairs0, V1, F1, *, groups=None):
    """The crossing face pairs of a mesh ``(V1, F1)`` that is a changed copy of ``(V0, F0)``, whose
    crossing pairs ``pairs0`` (:func:`contourmesh.intersect.intersecting_pairs`) are known.

    Whether two faces intersect depends only on the positions of their corners (vertices are
    identified by position).  So a pair of faces of the new mesh that are given old faces with the
    same corners (no old face given twice: :func:`_kept_faces_after`) crosses exactly when the old
    pair did; only pairs with a face given none (new, or repeated: a face that occurs twice overlaps
    itself) are tested, against the faces whose boxes may meet them.  The result equals
    ``intersecting_pairs(V1, F1)``: ``(k, 2)`` face indices ``i < j``, sorted.  ``groups``
    (optional, an integer per face of ``F1``): the parts the new mesh was built from, passed on to
    the test of the changed faces (:func:`contourmesh.intersect.intersecting_pairs`: it only saves
    work, the pairs are the same)."""
    from .intersect import intersecting_pairs as _pairs

    V0 = np.asarray(V0, dtype=np.float64)
    V1 = np.asarray(V1, dtype=np.float64)
    F0 = np.asarray(F0, dtype=np.int64).reshape(-1, 3)
    F1 = np.asarray(F1, dtype=np.int64).reshape(-1, 3)
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (len(F1),):
            raise ValueError(f"groups must be one integer per face ({len(F1)}); got shape {groups.shape}")
    kept, new_of_old = _kept_faces_after(V0, F0, V1, F1)
    p0 = np.asarray(pairs0, dtype=np.int64).reshape(-1, 2)
    q = new_of_old[p0] if len(p0) else np.zeros((0, 2), dtype=np.int64)
    out = [q[(q >= 0).all(axis=1)]]
    changed = np.flatnonzero(~kept)
    if len(changed) and len(F1) > 1:
        sub = _changed_faces_near(V1, F1, changed, np.int64(_NEAR_SAMPLE))
        if len(sub) == 0:
            sub = _boxes_near(V1, F1, changed)
        r = _pairs(V1, F1[sub], groups=None if groups is None else groups[sub])
        if len(r):
            r = sub[r]
            out.append(r[(~kept[r]).any(axis=1)])
    p = np.sort(np.concatenate(out), axis=1)
    if len(p):
        p = np.unique(p, axis=0)  # sorted rows, i < j
    return p.reshape(-1, 2)


def resolve_crossings(V, F, nudge, *, rounds: int = 6, pairs=None, planes=None):
    """Find the face pairs that cross (exactly, :func:`contourmesh.intersect.intersecting_pairs`)
    and pull them apart where a small inward move can.

    Every vertex of a crossing face moves against its vertex normal (into the solid it bounds)
    by ``nudge``, doubled every round up to ``2**(rounds-1)`` nudges; a move is kept only where
    it leaves fewer crossing pairs.  After the first (whole-mesh) check only the faces that the
    largest move could bring near a moved one are checked again (found once), which gives the
    whole mesh's count since every crossing pair involves a moved face.  Two solids touching at a point or along a segment, and faces that
    cross by less than the step, come apart; crossings from a wrong triangulation do not (they
    are counted and left).  A vertex whose height is one of ``planes`` (the section heights; a
    callable giving them is called only when there are crossings) moves within its plane only, so
    the sections stay where they were.

    Returns ``(V, info)``, ``info = {"self_intersections": pairs left, "crossings_repaired":
    pairs removed, "vertices_moved": count, "max_move": largest vertex displacement, "pairs": the
    crossing pairs left, (k, 2)}``.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    p = intersecting_pairs(V, F) if pairs is None else np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    n0 = len(p)
    info = {"self_intersections": int(n0), "crossings_repaired": 0, "vertices_moved": 0, "max_move": 0.0,
            "pairs": p}
    if n0 == 0 or len(F) == 0:
        return V, info
    V0 = V
    if planes is not None:
        planes = np.asarray(planes() if callable(planes) else planes, dtype=np.float64)
    # the vertex normals (within the planes for vertices on them), of the vertices that move only
    # (_vertex_normals_at: the whole mesh's normals there, bit for bit), made as they are needed
    nrm = np.zeros_like(V)
    have = np.zeros(len(V), dtype=bool)

    def normals_for(ids):
        new = ids[~have[ids]]
        if len(new):
            nv = _vertex_normals_at(V0, F, new)
            if planes is not None:
                nv[np.isin(V0[new, 2], planes), 2] = 0.0
            nrm[new] = nv
            have[new] = True

    # the faces that any round can bring near a moved face: found once, for the largest total move
    # of the vertices of every face that takes part (rounds move only vertices of crossing faces,
    # and a face crossing after a move meets a moved face)
    reach = np.unique(F[np.unique(p)])
    normals_for(reach)
    Wmax = V.copy()
    Wmax[reach] -= nudge * (2.0 ** rounds) * nrm[reach]
    touched = np.zeros(len(V), dtype=bool)
    touched[reach] = True
    # each round tests the faces near the moved ones on their own vertices (``used``, the faces
    # renumbered to them: what intersecting_pairs would take from the whole mesh's, the same pairs),
    # and the whole mesh is copied once, where a round is first kept (a copy of it per round, and
    # the vertices the faces use found again each time, were a fifth of this call on the lobster)
    sub = _faces_near(V, Wmax, F, _rows_touching(F, touched))
    used, Fs = _compact_rows(F, sub)
    for r in range(rounds):
        if len(p) == 0:
            break
        verts = np.unique(F[np.unique(p)])
        normals_for(verts)
        if not touched[verts].all():  # a pair outside the region found first: widen it
            touched[verts] = True
            Wmax[verts] = V[verts] - nudge * (2.0 ** rounds) * nrm[verts]
            sub = _faces_near(V, Wmax, F, _rows_touching(F, touched))
            used, Fs = _compact_rows(F, sub)
        step = nudge * 2.0 ** r
        at = V[verts] - step * nrm[verts]  # (the crossing faces' vertices: used by faces of sub)
        Ws = V[used]
        lv = np.searchsorted(used, verts)
        Ws[lv] = at
        # a pair that crosses after the move has a moved face (the pairs of V that cross are p,
        # whose faces all move), and the other face's box meets that one's: only the faces of sub
        # near the moved ones are tested (the same pairs; the region is found for the largest move)
        mv = np.zeros(len(used), dtype=bool)
        mv[lv] = True
        near = _boxes_near(Ws, Fs, np.flatnonzero(mv[Fs].any(axis=1)))
        q = intersecting_pairs(Ws, Fs[near])
        q = sub[near[q]] if len(q) else q.reshape(0, 2)
        if len(q) < len(p):
            if V is V0:
                V = V.copy()
            V[verts] = at
            p = q
    # only the vertices of the region can have moved (every other row of V - V0 is zero)
    ids = np.flatnonzero(touched)
    moved = np.linalg.norm(V[ids] - V0[ids], axis=1)
    info.update(self_intersections=int(len(p)), crossings_repaired=int(n0 - len(p)),
                vertices_moved=int(np.count_nonzero(moved)), max_move=float(moved.max(initial=0.0)), pairs=p)
    return V, info


def _compact_rows(F, rows):
    """The vertices that the faces ``F[rows]`` use (sorted) and those faces renumbered to them."""
    Fr = F[rows]
    used = np.unique(Fr)
    return used, np.searchsorted(used, Fr)
