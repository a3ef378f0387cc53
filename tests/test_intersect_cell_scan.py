"""Issue 16 (round 29): the pair loop of the slab phase's sweep by cells (``_cell_sweep``) runs in
``_cell_scan``, a kernel without reference counting, which stops at each pair that intersects (the
caller appends it), where the vertices' stars fall due (the caller fills them) and where the work
passes its limit.  In the caller, which allocates, the pair lists were counted in and out (atomic
operations) for every pair that reached the exact test.  The result must be exactly that of the
form before (the pairs in the same order, the work, the stars filled, a stop after a few pairs, a
limit passed): the form before is kept here, compiled, as the reference, and compared slab by slab
on random sectioned meshes (on and off the dyadic grid) and on a real segmentation's mesh."""

import numpy as np
from numba import njit

import contourmesh
from contourmesh import intersect as I
from contourmesh.intersect import (
    _apart_in_slab,
    _box_row,
    _cell_sweep,
    _fill_stars,
    _push,
    _slab_hit,
    _star_due,
)
from test_intersect_cell_sweep import _random_big_sectioned, _slabs


@njit(cache=False, nogil=True, no_rewrites=True)
def _cell_sweep_before(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, cx0, cy0, start, npairs, pi, pj, work, limit, stop,
                l0, l1, cg):
    """``_cell_sweep`` as it was before its pair loop moved into ``_cell_scan`` (issue 16, round
    29): the loop in this kernel, which counts references."""
    n = len(faces)
    if n < 2:
        return npairs, pi, pj, work
    gxl = np.inf
    gxh = -np.inf
    gyl = np.inf
    gyh = -np.inf
    for t in range(n):
        i = faces[t]
        kl = lo_[i]
        kh = hi_[i]
        _box_row(W, t, V, F, lev, i, kl)
        nl = (lev[F[i, 0]] == kl) + (lev[F[i, 1]] == kl) + (lev[F[i, 2]] == kl)
        nh = (lev[F[i, 0]] == kh) + (lev[F[i, 1]] == kh) + (lev[F[i, 2]] == kh)
        W[t, 12] = 1.0 * nl
        W[t, 13] = 1.0 * kl
        W[t, 14] = 1.0 * kh
        W[t, 15] = 1.0 if nl + nh == 3 and kl < kh else 0.0
        W[t, 16] = cg[i] if len(cg) > 0 else -1.0
        gxl = min(gxl, W[t, 0])
        gxh = max(gxh, W[t, 1])
        gyl = min(gyl, W[t, 2])
        gyh = max(gyh, W[t, 3])
    # about n cells, fewer where the faces would take more than four entries each on average
    g = np.int64(1)
    while (g + 1) * (g + 1) <= n:
        g += 1
    gx = g
    gy = g
    while True:
        hx = (gxh - gxl) / gx
        hy = (gyh - gyl) / gy
        if not hx > 0.0:
            hx = 1.0
        if not hy > 0.0:
            hy = 1.0
        nent = np.int64(0)
        for t in range(n):
            x0 = min(np.int64((W[t, 0] - gxl) / hx), gx - 1)
            x1 = min(np.int64((W[t, 1] - gxl) / hx), gx - 1)
            y0 = min(np.int64((W[t, 2] - gyl) / hy), gy - 1)
            y1 = min(np.int64((W[t, 3] - gyl) / hy), gy - 1)
            cx0[t] = x0
            cy0[t] = y0
            nent += (x1 - x0 + 1) * (y1 - y0 + 1)
        if nent <= 4 * n or (gx == 1 and gy == 1):
            break
        gx = max(gx // 2, np.int64(1))
        gy = max(gy // 2, np.int64(1))
    nc = gx * gy
    for q in range(nc + 1):
        start[q] = 0
    for t in range(n):
        x1 = min(np.int64((W[t, 1] - gxl) / hx), gx - 1)
        y1 = min(np.int64((W[t, 3] - gyl) / hy), gy - 1)
        for cy in range(cy0[t], y1 + 1):
            for cx in range(cx0[t], x1 + 1):
                start[cy * gx + cx + 1] += 1
    for q in range(nc):
        start[q + 1] += start[q]
    ent = np.empty(nent, np.int64)
    # (start[q] is the fill pointer of cell q, shifted back below).  A cell lists first the faces
    # that start in this slab, then those from a lower one: two of the latter met in a lower slab
    # (the pair is not this slab's), so the pairs are those of a face of the first kind with any
    # later entry, the same pairs in another order without meeting the others (on the liver's
    # whole mesh 1.07 M slab entries of 417k faces: most slabs between nearby heights)
    for lower in range(2):
        for t in range(n):
            if (W[t, 13] != k) != (lower == 1):
                continue
            x1 = min(np.int64((W[t, 1] - gxl) / hx), gx - 1)
            y1 = min(np.int64((W[t, 3] - gyl) / hy), gy - 1)
            for cy in range(cy0[t], y1 + 1):
                for cx in range(cx0[t], x1 + 1):
                    q = cy * gx + cx
                    ent[start[q]] = t
                    start[q] += 1
    for q in range(nc, 0, -1):
        start[q] = start[q - 1]
    start[0] = 0
    for q in range(nc):
        for r in range(start[q], start[q + 1]):
            s = ent[r]
            if W[s, 13] != k:
                break  # (the faces from a lower slab: every pair of theirs is a lower slab's)
            for v in range(r + 1, start[q + 1]):
                u = ent[v]
                work += 1
                if max(W[s, 13], W[u, 13]) != k:
                    continue  # (a pair of a lower slab)
                if W[u, 0] > W[s, 1] or W[s, 0] > W[u, 1] or W[s, 2] > W[u, 3] or W[u, 2] > W[s, 3]:
                    continue
                if W[s, 16] >= 0.0 and W[s, 16] == W[u, 16]:
                    continue  # (two faces certified in one group: the pair needs nothing)
                if max(cy0[s], cy0[u]) * gx + max(cx0[s], cx0[u]) != q:
                    continue  # (taken in the cell of the low corner of the overlap)
                i = np.int64(faces[s])
                j = np.int64(faces[u])
                if _apart_in_slab(V, F, lev, lo_, W, s, u, i, j):
                    continue
                if i > j:
                    i, j = j, i
                if _star_due(sst):
                    _fill_stars(V, F, star, lev, l0, l1, cg)
                if _slab_hit(V, ws, F, star, np.int64(1), i, j):
                    pi, pj, npairs = _push(pi, pj, npairs, i, j)
                    if npairs == stop:
                        return npairs, pi, pj, work
            if work > limit:
                return np.int64(-1), pi, pj, work
    return npairs, pi, pj, work



@njit(cache=False)
def _run(which, V, ws, F, star, sst, lev, lo_, hi_, faces, k, limit, stop, cg):
    """One slab by the form now (``which == 1``) or before (0), fresh workspaces:
    ``(npairs, pairs, work)``."""
    n = max(len(faces), 1)
    W = np.empty((n, 17), np.float64)
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    start = np.empty(n + 1, np.int64)
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    zero = k - k
    top = zero + 1000
    if which == 1:
        npairs, pi, pj, work = _cell_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, a, b, start, zero, pi, pj,
                                           zero + 3, limit, stop, zero, top, cg)
    else:
        npairs, pi, pj, work = _cell_sweep_before(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, a, b, start, zero,
                                                  pi, pj, zero + 3, limit, stop, zero, top, cg)
    m = max(npairs, zero)
    return npairs, np.stack((pi[:m], pj[:m])), work


def _compare(V, F, rng):
    """Every slab of at least 64 faces by both forms, with the stars filled in the kernel (due at
    once, after some pairs, never), face groups or none, without a stop and at 1 or 2 pairs, and
    with a limit that a large slab passes.  Returns (pairs found, stars filled, limits passed)."""
    Fc, lev, lo, hi, slabs = _slabs(V, F)
    Fc = np.ascontiguousarray(Fc, dtype=np.int64)
    ws = np.zeros(1 + 3 * I._EXP_LEN)
    ws[0] = 1.0 if I._on_small_dyadic_grid(V) else 0.0
    found = filled = passed = 0
    groups = [np.zeros(0, np.int64), rng.integers(-1, 4, len(Fc)).astype(np.int64)]
    for k, faces in enumerate(slabs):
        if len(faces) < 64:
            continue
        for cg in groups:
            for delay in (-1, 20, 10 ** 9):
                for stop, limit in ((0, 2 ** 62), (1, 2 ** 62), (2, 2 ** 62), (0, 3 * len(faces))):
                    out = []
                    for which in (0, 1):
                        star = np.zeros(len(V), np.int8)
                        sst = np.array([0, delay], np.int64)
                        npairs, pairs, work = _run(which, V, ws.copy(), Fc, star, sst, lev, lo, hi, faces, np.int64(k),
                                                   np.int64(limit), np.int64(stop), cg)
                        out.append((int(npairs), pairs.tolist(), int(work), star.tobytes(), sst.tolist()))
                    assert out[1] == out[0], (k, len(faces), len(cg), delay, stop, limit)
                    if stop == 0 and limit == 2 ** 62:
                        found += out[0][0]
                    filled += out[0][4][0] == -1
                    passed += out[0][0] == -1
    return found, filled, passed


def test_random_sectioned_meshes():
    rng = np.random.default_rng(29)
    found = filled = passed = 0
    for seed in range(3):
        V, F = _random_big_sectioned(rng, int(rng.integers(2, 4)), 40, 4000)
        if seed == 2:  # off the dyadic grid: the exact predicates' other branch, no coordinate shortcuts
            V = V * 0.1 + 0.37
        f, s, p = _compare(V, F, rng)
        found, filled, passed = found + f, filled + s, passed + p
    assert found > 20 and filled > 0 and passed > 0, (found, filled, passed)


def test_a_real_mesh(shared_data):
    """The repaired mesh of the liver's label 255 (slabs of thousands of faces between nearby
    heights)."""
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == 255)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == 255
    m = contourmesh.mesh(crop, spacing=tuple(float(s) for s in z["spacing_xyz"][::-1]))
    _, filled, passed = _compare(m.vertices.copy(), m.faces.copy(), np.random.default_rng(255))
    assert filled > 0 and passed > 0
