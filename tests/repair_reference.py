"""Reference forms of the manifold repair's edge counts and of the rebuild's position keys, kept
for the tests only.

The repair finds edges shared by four faces with :func:`contourmesh.repair._four_face_edges`,
which never holds the count of every edge. The forms below do hold them (one count per face
edge, then one pass over those counts) and are what the compiled repair is compared against,
bit for bit, in ``test_vertex_fans.py`` and ``test_compiled_repair.py``. ``row_ids`` and
``face_groups`` number positions and faces in one hash table / one pass over both meshes, as the
rebuild's re-test did before it matched the second mesh against the first in order
(:func:`contourmesh.repair._row_ids_after`, :func:`contourmesh.repair._face_groups_after`;
``test_rebuild_keys_after.py``).
"""

from __future__ import annotations

import numpy as np

from contourmesh import repair
from contourmesh._kernels import njit


@njit(cache=True, nogil=True)
def four_face_rows(mult):
    """From the counts of :func:`edge_multiplicity`: ``(odd, most, rows, hit)``, the first odd
    count in row order (0 if none), the largest count, the faces with an edge shared by four
    (increasing) and, per such face, which of its edges are."""
    odd = 0
    most = 0
    n = 0
    for i in range(mult.shape[0]):
        four = False
        for k in range(3):
            c = mult[i, k]
            if c % 2 and not odd:
                odd = c
            most = max(most, c)
            four = four or c == 4
        n += four
    rows = np.empty(n, np.int64)
    hit = np.empty((n, 3), np.bool_)
    at = 0
    for i in range(mult.shape[0]):
        if mult[i, 0] == 4 or mult[i, 1] == 4 or mult[i, 2] == 4:
            rows[at] = i
            for k in range(3):
                hit[at, k] = mult[i, k] == 4
            at += 1
    return odd, most, rows, hit


@njit(cache=True, nogil=True)
def edge_multiplicity_range(start, items, other, v0, v1, out, cnt):
    """The counts of :func:`edge_multiplicity` for the buckets ``v0 .. v1 - 1`` (scratch ``cnt``
    indexed by the upper vertex, left zero), written into ``out`` by half-edge number."""
    flat = out.reshape(-1)
    for v in range(v0, v1):
        s0, s1 = start[v], start[v + 1]
        for t in range(s0, s1):
            o = other[t]
            cnt[o if o >= 0 else ~o] += 1
        for t in range(s0, s1):
            o = other[t]
            flat[items[t]] = cnt[o if o >= 0 else ~o]
        for t in range(s0, s1):
            o = other[t]
            cnt[o if o >= 0 else ~o] = 0


@njit(cache=True, nogil=True)
def edge_multiplicity(F, nv):
    """Per face edge ``(F[i, k], F[i, k + 1])``, the number of face edges with the same two
    vertices (either direction): an ``(m, 3)`` int32 array."""
    start, items, other = repair._half_edges_by_vertex(F, nv)
    out = np.empty((F.shape[0], 3), np.int32)
    edge_multiplicity_range(start, items, other, 0, nv, out, np.zeros(nv, np.int32))
    return out


def edge_multiplicity_threads(F, nv, threads):
    """:func:`edge_multiplicity` with the buckets built and counted on ``threads`` threads
    (``repair._buckets_on_threads``): the same counts."""
    from contourmesh._workers import run_all

    start, items, other, vparts = repair._buckets_on_threads(F, nv, threads)
    out = np.empty((F.shape[0], 3), np.int32)
    run_all(lambda a, b: edge_multiplicity_range(start, items, other, a, b, out, np.zeros(nv, np.int32)), vparts,
            threads)
    return out


@njit(cache=True, nogil=True)
def row_ids(R, sort_rows, overwrite=False):
    """A group number per row of the int64 array ``R`` (rows with equal values share it; with
    ``sort_rows``, rows equal up to the order of their values: sorted in ``R`` itself where
    ``overwrite``), numbered in order of first occurrence; an open-addressing hash table, linear in
    the number of rows."""
    n, k = R.shape
    if sort_rows:  # (insertion sort of each short row)
        if not overwrite:
            R = R.copy()
        for i in range(n):
            for c in range(1, k):
                x = R[i, c]
                j = c - 1
                while j >= 0 and R[i, j] > x:
                    R[i, j + 1] = R[i, j]
                    j -= 1
                R[i, j + 1] = x
    size = 1
    while size < 2 * n + 2:
        size *= 2
    # the first row of each group in this slot (int32: 2^31 rows would not fit in memory here
    # anyway); that row's id is its group's
    table = np.full(size, -1, np.int32)
    ids = np.empty(n, np.int64)
    count = 0
    for i in range(n):
        h = np.uint64(0x9E3779B97F4A7C15)
        for c in range(k):
            h ^= np.uint64(R[i, c]) + np.uint64(0x9E3779B97F4A7C15) + (h << np.uint64(6)) + (h >> np.uint64(2))
            h *= np.uint64(0xBF58476D1CE4E5B9)
            h ^= h >> np.uint64(31)
        slot = np.int64(h & np.uint64(size - 1))
        while True:
            j = table[slot]
            if j < 0:
                table[slot] = i
                ids[i] = count
                count += 1
                break
            same = True
            for c in range(k):
                if R[j, c] != R[i, c]:
                    same = False
                    break
            if same:
                ids[i] = ids[j]
                break
            slot = (slot + 1) & (size - 1)
    return ids


@njit(cache=True, nogil=True)
def face_groups(pos, F0, F1, off):
    """A group number per face of ``F0`` then ``F1`` (corners ``pos[v]`` and ``pos[off + v]``):
    faces share one exactly when their sets of three corner numbers are equal.  int32 numbers,
    in order of first occurrence in the order below.

    The faces are sorted by their smallest corner (a counting sort), and within one smallest
    corner matched through lists by the middle one, stamped per smallest corner: a face is compared
    only with the faces that share its two smallest corners (an edge), not looked up in a hash
    table of all faces as :func:`row_ids` would (on the lobster's rebuild, 0.79 M faces of two
    meshes: 42 ms there, the table's and the rows' random reads).  The work arrays and the
    numbers are int32: in int64 they took some 44 MiB on that rebuild, where the general mesher's
    memory peaks on the lobster, 22 MiB in int32 (12 MiB with each face's sorted corners read
    again where needed instead of kept in ``T``, but then 0.065 s instead of 0.03 s)."""
    m0 = len(F0)
    m = m0 + len(F1)
    npos = np.int64(0)
    for v in range(len(pos)):
        npos = max(npos, pos[v] + 1)
    if m >= 2**31 - 1 or npos >= 2**31 - 1:
        raise MemoryError("too many faces or corner positions for the int32 work arrays")
    T = np.empty((m, 3), np.int32)  # each face's corner numbers, sorted
    start = np.zeros(npos + 1, np.int32)
    for g in range(m):
        if g < m0:
            a = pos[F0[g, 0]]
            b = pos[F0[g, 1]]
            c = pos[F0[g, 2]]
        else:
            a = pos[off + F1[g - m0, 0]]
            b = pos[off + F1[g - m0, 1]]
            c = pos[off + F1[g - m0, 2]]
        if a > b:
            a, b = b, a
        if b > c:
            b, c = c, b
        if a > b:
            a, b = b, a
        T[g, 0] = a
        T[g, 1] = b
        T[g, 2] = c
        start[a + 1] += 1
    for q in range(npos):
        start[q + 1] += start[q]
    order = np.empty(m, np.int32)
    fill = start[:npos].copy()
    for g in range(m):
        order[fill[T[g, 0]]] = g
        fill[T[g, 0]] += 1
    head = np.empty(npos, np.int32)  # per middle corner: the first face of its list (stamped)
    stamp = np.full(npos, -1, np.int32)
    nxt = np.empty(m, np.int32)
    ids = np.empty(m, np.int32)
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
    return ids
