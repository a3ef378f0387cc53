"""Issue 16 (round 29): the pair loop of the whole-mesh crossing test's grid (``_intersecting_pairs``)
runs in ``_grid_scan``, a kernel without reference counting, which stops at each pair that
intersects (the caller appends it) and where the vertices' stars fall due (the caller fills them).
In the caller, which allocates, the pair lists that the loop appends to were counted in and out
(atomic operations) for every pair that reached the tests.  The pairs must be exactly those of the
form before, in the same order (a search that stops at its first pairs returns the same ones): the
form before is kept here, compiled, as the reference, and compared on random meshes (stacks of
folded spheres, soups on and off the dyadic grid, sectioned meshes), with and without the stars,
the touching-box shortcut and face groups, for several chunk sizes and stops, and on the lobster's
first build."""

import numpy as np
from numba import njit

from contourmesh import intersect as I
from contourmesh.intersect import (
    _KEY_BITS,
    _MEDIAN_SAMPLE,
    _across_plane,
    _box_gates,
    _cell,
    _chunk_end,
    _count_cells,
    _face_range,
    _fill_stars,
    _median_extent,
    _o2,
    _pair_intersects,
    _push,
    _shares_certified,
    _star_due,
    _touching_boxes,
)
from test_intersect_grid_chunks import _first_build, _inputs, _stack
from test_intersect_quick import _nudged
from test_intersect_slabs import _random_sectioned


@njit(cache=False, nogil=True, no_rewrites=True)
def _intersecting_pairs_before(V, ws, F, star, sst, quick, budget, stop, chunk, cg):
    """``_intersecting_pairs`` as it was before its pair loop moved into ``_grid_scan`` (issue 16,
    round 29): the loop in this kernel, which counts references."""
    m = len(F)
    live = np.empty(m, np.int8)
    glo = np.empty(3, np.float64)
    ghi = np.empty(3, np.float64)
    for k in range(3):
        glo[k] = np.inf
        ghi[k] = -np.inf
    nlive = np.int64(0)  # (a literal 0 would compile _median_extent a second time, for Literal[int](0))
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        live[i] = 0
        if a == b or b == c or a == c:
            continue
        # (a face certified in a group (_lattice_cells) is half of a rectangle, its two legs along two
        # axes from the right-angle corner, each of nonzero length: not collinear, no test needed; on
        # the lobster's mesh 84 % of the faces, some 3 % of this call)
        if ((len(cg) == 0 or cg[i] < 0) and _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0
                and _o2(V, ws, a, b, c, ax0, ax1) == 0):
            continue  # collinear (exactly)
        live[i] = 1
        nlive += 1
        for k in range(3):
            lo, hi = _face_range(V, F, i, k)
            glo[k] = min(glo[k], lo)
            ghi[k] = max(ghi[k], hi)
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    npairs = np.int64(0)  # (a literal 0 would compile _push a second time, for Literal[int](0))
    if nlive < 2:
        return pi[:0], pj[:0]
    # cell sizes: per axis, the median face extent along it (slices make faces thin across them),
    # no smaller than 1/16 of the largest (a few long faces, such as caps, span many cells).  On a
    # large mesh the median of a sample of the faces (see _MEDIAN_SAMPLE): the cell sizes only set
    # the work and the memory, never the pairs, and the entries are counted exactly below
    h = np.empty(3, np.float64)
    step = max(nlive // _MEDIAN_SAMPLE, np.int64(1))
    for k in range(3):
        h[k] = _median_extent(V, F, live, nlive, np.int64(k), step)
    hbig = max(h[0], max(h[1], h[2]))
    for k in range(3):
        hmin = max((ghi[k] - glo[k]) / (2.0 ** _KEY_BITS - 2.0), hbig / 16.0)
        if not h[k] > hmin:
            h[k] = hmin
        if not h[k] > 0.0:
            h[k] = 1.0
    limit = budget * nlive
    total = _count_cells(V, F, live, glo, h)
    while total > limit:
        for k in range(3):
            h[k] *= 1.5
        total = _count_cells(V, F, live, glo, h)
    nz = _cell(ghi[2], glo[2], h[2]) + 1
    ny = _cell(ghi[1], glo[1], h[1]) + 1
    nx = _cell(ghi[0], glo[0], h[0]) + 1
    # the live faces in order of their lowest layer (a counting sort), the entries per layer, and
    # the largest chunk's entries (``most``) and faces (``cap``); one chunk where the mesh is
    # small, or where its layers outnumber its faces (the tables per layer would be the larger)
    chunked = total > chunk and 1 < nz <= nlive
    order = np.empty(nlive, np.int32)
    if chunked:
        lay = np.zeros(nz, np.int64)
        first = np.zeros(nz + 1, np.int64)  # faces whose lowest layer is below z: first[z]
        last = np.zeros(nz + 1, np.int64)  # faces whose highest layer is below z: last[z]
        for i in range(m):
            if live[i] == 0:
                continue
            lo, hi = _face_range(V, F, i, ax0)
            nxy = _cell(hi, glo[0], h[0]) - _cell(lo, glo[0], h[0]) + 1
            lo, hi = _face_range(V, F, i, ax1)
            nxy *= _cell(hi, glo[1], h[1]) - _cell(lo, glo[1], h[1]) + 1
            lo, hi = _face_range(V, F, i, ax2)
            z0 = _cell(lo, glo[2], h[2])
            z1 = _cell(hi, glo[2], h[2])
            for cz in range(z0, z1 + 1):
                lay[cz] += nxy
            first[z0 + 1] += 1
            last[z1 + 1] += 1
        for z in range(nz):
            first[z + 1] += first[z]
            last[z + 1] += last[z]
        fill = first[:nz].copy()
        for i in range(m):
            if live[i] == 0:
                continue
            lo, hi = _face_range(V, F, i, ax2)
            z0 = _cell(lo, glo[2], h[2])
            order[fill[z0]] = i
            fill[z0] += 1
        most = np.int64(1)
        cap = np.int64(1)
        z0 = np.int64(0)
        while z0 < nz:
            z1, run = _chunk_end(lay, z0, nz, chunk)
            most = max(most, run)
            cap = max(cap, first[z1] - last[z0])  # faces with a layer in z0 .. z1 - 1
            z0 = z1
    else:
        lay = np.zeros(1, np.int64)
        first = np.zeros(1, np.int64)
        n = 0
        for i in range(m):
            if live[i] != 0:
                order[n] = i
                n += 1
        most = total
        cap = np.int64(nlive)
    # a chunk's hash table of cells: a counting sort of its (face, cell) entries by bucket (about
    # one entry per bucket: the entries of one cell share a bucket anyway); bucket starts and slots
    # in int32, the keys (cells, z-major) in int64
    if most >= 2**31 - 1:
        raise MemoryError("too many grid cells in one layer for the crossing test's int32 tables")
    nb = 1
    while nb < most:
        nb *= 2
    start = np.empty(nb + 1, np.int32)
    ent_slot = np.empty(most, np.int32)
    ent_key = np.empty(most, np.int64)
    # per entry, which of its cell's coordinates are the face's lowest (bit k: along axis k)
    ent_low = np.empty(most, np.int8)
    # the chunk's faces (slots): box, cells (lowest and highest per axis), face
    abox = np.empty((cap, 6), np.float64)
    acell = np.empty((cap, 6), np.int64)
    aface = np.empty(cap, np.int64)
    acg = np.empty(cap, np.int64)  # (its group where certified, else -1: see _lattice_cells)
    nact = 0
    nxt = 0
    z0 = np.int64(0)
    while z0 < nz:
        if chunked:
            z1, run = _chunk_end(lay, z0, nz, chunk)
            upto = first[z1]
        else:
            z1 = nz
            run = total
            upto = nlive
        # the faces of the layers z0 .. z1 - 1: those still reaching z0, in order, then the new ones
        keep = 0
        for s in range(nact):
            if acell[s, 5] >= z0:
                if keep != s:
                    for k in range(6):
                        abox[keep, k] = abox[s, k]
                        acell[keep, k] = acell[s, k]
                    aface[keep] = aface[s]
                    acg[keep] = acg[s]
                keep += 1
        nact = keep
        while nxt < upto:
            i = np.int64(order[nxt])
            nxt += 1
            for k in range(3):
                lo, hi = _face_range(V, F, i, k)
                abox[nact, k] = lo
                abox[nact, 3 + k] = hi
                acell[nact, k] = _cell(lo, glo[k], h[k])
                acell[nact, 3 + k] = _cell(hi, glo[k], h[k])
            aface[nact] = i
            acg[nact] = cg[i] if len(cg) > 0 else -1
            nact += 1
        nbc = 1
        while nbc < run:
            nbc *= 2
        mask = nbc - 1
        for q in range(nbc + 1):
            start[q] = 0
        # every (face, cell) entry of the chunk: counted per bucket, then stored at its bucket's
        # fill pointer (start itself, each bucket's ending at the next one's start; shifted back)
        for store in range(2):
            for s in range(nact):
                for cz in range(max(acell[s, 2], z0), min(acell[s, 5], z1 - 1) + 1):
                    for cy in range(acell[s, 1], acell[s, 4] + 1):
                        for cx in range(acell[s, 0], acell[s, 3] + 1):
                            key = (cz * ny + cy) * nx + cx
                            q = key & mask
                            if store == 0:
                                start[q] += 1
                            else:
                                r = start[q]
                                ent_slot[r] = s
                                ent_key[r] = key
                                ent_low[r] = ((1 if cx == acell[s, 0] else 0) | (2 if cy == acell[s, 1] else 0)
                                              | (4 if cz == acell[s, 2] else 0))
                                start[q] = r + 1
            if store == 0:
                acc = 0
                for q in range(nbc):
                    cnt = start[q]
                    start[q] = acc
                    acc += cnt
                start[nbc] = acc
        for q in range(nbc, 0, -1):
            start[q] = start[q - 1]
        start[0] = 0
        for q in range(nbc):
            s0 = start[q]
            s1 = start[q + 1]
            for r in range(s0, s1):
                a = ent_slot[r]
                key = ent_key[r]
                low = ent_low[r]
                for t in range(r + 1, s1):
                    # test the pair only in the cell of the low corner of the boxes' overlap (the
                    # cell of a larger coordinate is never lower: the larger of the two cells): both
                    # faces reach this cell, so along each axis it is the larger of their lowest
                    # cells where it is the lowest of one of them (ent_low), which two bytes say
                    # without the faces' rows
                    if ent_key[t] != key or (low | ent_low[t]) != 7:
                        continue
                    b = ent_slot[t]
                    if acg[a] >= 0 and acg[a] == acg[b]:
                        continue  # (two faces certified in one group: the pair needs nothing)
                    if (abox[a, 0] > abox[b, 3] or abox[b, 0] > abox[a, 3] or abox[a, 1] > abox[b, 4]
                            or abox[b, 1] > abox[a, 4] or abox[a, 2] > abox[b, 5] or abox[b, 2] > abox[a, 5]):
                        continue
                    i = min(aface[a], aface[b])
                    j = max(aface[a], aface[b])
                    if _star_due(sst):
                        _fill_stars(V, F, star, np.zeros(len(V), np.int64), ax0, ax0, cg)
                    if _shares_certified(F, star, i, j):
                        continue
                    # the in-plane tests only where the boxes say they decide (_box_gates): the
                    # same outcome as calling them, without reading the faces' corners again
                    gate = _box_gates(abox, a, b)
                    hit = np.int64(-1)
                    if gate & 1:
                        hit = _across_plane(V, ws, F, i, j)
                    if hit < 0 and quick == 1 and gate & 2:
                        hit = _touching_boxes(V, ws, F, i, j)
                    if hit < 0:
                        hit = 1 if _pair_intersects(V, ws, F, i, j) else 0
                    if hit == 1:
                        pi, pj, npairs = _push(pi, pj, npairs, i, j)
                        if npairs == stop:
                            return pi[:npairs], pj[:npairs]
        z0 = z1
    return pi[:npairs], pj[:npairs]



def _both(V, Fc, ws, *, quick, delay, stop, chunk, cg):
    """The pairs (in the order found) of both forms on the same arguments, and the stars and the
    star counter each leaves."""
    out = []
    for kernel in (_intersecting_pairs_before, I._intersecting_pairs):
        star = np.zeros(len(V), np.int8)
        sst = np.array([0 if quick else -1, len(Fc) // 8 + delay], np.int64)
        pi, pj = kernel(V, ws.copy(), Fc, star, sst, np.int64(1 if quick else 0), np.int64(8), np.int64(stop),
                        np.int64(chunk), cg)
        out.append((list(zip(pi.tolist(), pj.tolist())), star.tobytes(), sst.tolist()))
    return out


def _same_order(V, F, rng, chunks=(1, 64, I._GRID_CHUNK)):
    """Both forms agree for every chunk size, with and without shortcuts and groups, and at stops
    of 1, 2 and 3 pairs.  Returns the number of pairs."""
    V, Fc, ws = _inputs(V, F)
    groups = [np.zeros(0, np.int64), rng.integers(-1, 3, len(Fc)).astype(np.int64)]
    n = 0
    for quick, delay in ((True, I._STAR_DELAY), (True, -10 ** 9), (False, I._STAR_DELAY)):
        for cg in groups:
            for chunk in chunks:
                for stop in (0, 1, 2, 3):
                    ref, got = _both(V, Fc, ws, quick=quick, delay=delay, stop=stop, chunk=chunk, cg=cg)
                    assert got == ref, (quick, delay, len(cg), chunk, stop)
                    if stop == 0 and len(cg) == 0:
                        n = max(n, len(ref[0]))
    return n


def test_random_meshes_same_pairs_in_the_same_order():
    rng = np.random.default_rng(29)
    found = several = 0
    for it in range(16):
        kind = it % 4
        if kind == 0:
            V, F = _stack(rng, int(rng.integers(2, 5)))
        elif kind == 1:  # a soup on a coarse dyadic grid: ties, touching and coplanar faces
            V, F = rng.integers(0, 8, (80, 3)) * 0.5, rng.integers(0, 80, (120, 3))
        elif kind == 2:  # the same off the grid, long in z
            V = rng.integers(-3, 4, (60, 3)) * [0.1, 0.3, 3.0] + [105.7, -217.3, -80.44]
            F = rng.integers(0, 60, (90, 3))
        else:  # sectioned, with heights nudged off the planes as the repair does
            V, F = _random_sectioned(rng, int(rng.integers(3, 9)), 40, 80, 0.3)
            V = _nudged(rng, V, 0.3, 0.2)
        n = _same_order(V, F, rng)
        found += n > 0
        several += n > 3
    assert found >= 8 and several >= 4, (found, several)


def test_a_pair_list_that_grows():
    """More pairs than the lists' first 16 places (grown while the scan waits)."""
    rng = np.random.default_rng(7)
    V, F = rng.random((60, 3)), rng.integers(0, 60, (200, 3))
    assert _same_order(V, F, rng, chunks=(I._GRID_CHUNK,)) > 16


def test_the_lobsters_first_build(shared_data):
    """The lobster's first build (396k faces, its crossing pairs), in chunks as the volume mesher
    tests it, with the vertices' stars falling due along the way."""

    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    V, F = _first_build(np.transpose(z["volume"], (2, 1, 0)) > 60)
    V, Fc, ws = _inputs(V, F)
    for stop in (0, 5):
        ref, got = _both(V, Fc, ws, quick=True, delay=I._STAR_DELAY, stop=stop, chunk=I._GRID_CHUNK,
                         cg=np.zeros(0, np.int64))
        assert got == ref
        assert len(ref[0]) > (5 if stop == 0 else 4)
