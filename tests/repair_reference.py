"""Reference forms of the manifold repair's edge counts, kept for the tests only.

The repair finds edges shared by four faces with :func:`contourmesh.repair._four_face_edges`,
which never holds the count of every edge. The forms below do hold them (one count per face
edge, then one pass over those counts) and are what the compiled repair is compared against,
bit for bit, in ``test_vertex_fans.py`` and ``test_compiled_repair.py``.
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
