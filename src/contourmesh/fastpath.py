"""Fast path for volumes: the same mesh as :func:`contourmesh.volumes.volume_to_mesh`, in numba.

Scope
-----
:func:`fast_volume_to_mesh` builds the mesh of :mod:`contourmesh.volumes` for the volumes where
that mesher only uses the paper's own construction (Wiederhold & Villafuerte 2009): MLP polygons
(``polygon="mlp"``), the paper's band triangulation (``triangulation="wiederhold"``) and flat or
half caps, with

* every 4-component of every slice free of holes, and
* every pair of consecutive slices joined only by *simple band joins*: each component overlaps at
  most one component of the neighbouring slice, and their overlap is connected and hole-free
  (:func:`contourmesh.volumes._simple_join` without holes).

Outside that scope (exact joins, holes, other polygon or band methods, caps that earcut cannot
triangulate, vertices that share a position, ...) it returns ``None`` and the caller falls back
to the full mesher.  Inside it the result is **identical**: the same vertices (bit for bit, in the
same order) and the same faces, because every step is the full mesher's step done on runs:

1. *Runs.*  Each slice row is scanned eight voxels at a time (``uint64`` words over the ``bool``
   bytes): a word that is all background (or all object) inside a background (object) stretch is
   skipped, so only words that hold a boundary are looked at byte by byte.
2. *Components.*  4-connected components of the runs by union-find (runs overlapping in adjacent
   rows), numbered in raster order of their first pixel like ``scipy.ndimage.label``; each
   component's number of holes is ``1 - chi`` with the Euler number ``chi = #runs - #(pairs of
   overlapping runs in adjacent rows)`` (4-connected object, 8-connected background).
3. *Outer Jordan contour.*  The boundary of ``U`` (cells with a corner in the component's pixels)
   is followed from its lowest-then-leftmost vertex, turning left first, exactly as
   :func:`contourmesh.sections.trace_contours` does, but reading the 3 x 3 pixels around each
   vertex instead of a dilated cell image (so only the boundary is touched).
4. *MLP.*  The candidates and string pulling of :mod:`contourmesh.polygons.mlp` (Klette & Yip),
   called on that contour; degenerate MLPs fall back to the crack contour as in the full mesher.
5. *Joins.*  Overlap runs of consecutive slices give the component pairs; the overlap of each pair
   is checked connected and hole-free with the same run Euler number.
6. *Bands.*  The paper's triangulation (section 3.4, :func:`~contourmesh.bands.wiederhold.wiederhold_edges`)
   with the initial edge of section 3.2, and the full mesher's twist guard (arc-length band of
   Ganapathy & Dennehy as the reference); the rare folded or twisted bands (and near-ties of the
   guard) are handed to the full mesher's Python code.
7. *Caps* by earcut (:func:`~contourmesh.bands.caps.cap_faces`), as in the full mesher.

Steps 1-4 run per slice and 5-6 per slice pair in ``nogil`` numba kernels, so ``threads > 1``
spreads them over a thread pool.  The full mesher's manifold repair steps are provably no-ops on
this scope (every edge has two faces, every vertex one fan; positions are checked distinct per
plane), so they are skipped.
"""

from __future__ import annotations

import math
import os
import threading

import numpy as np
from numba import njit

from .bands.arclength import arclength_edges
from .bands.wiederhold import INITIAL_EDGE_WINDOW, _edges_to_faces, wiederhold_edges
from .polygons.mlp import _candidates, _clean_polygon, _string_pulling

__all__ = ["fast_volume_to_mesh", "slice_runs", "slice_components", "outer_jordan_contour",
           "slice_polygons", "band_faces"]

_ONES = np.uint64(0x0101010101010101)
_ZERO = np.uint64(0)


# ------------------------------------------------------------------------------------------------
# 1. runs
# ------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _scan_runs(b8, b64, base, h, w, aligned):
    """Runs of non-zero bytes of the ``h x w`` slice starting at byte ``base`` of ``b8``.

    ``b64`` is the ``uint64`` view of ``b8`` (used when ``aligned``).  Returns ``(ry, rx0, rx1,
    row_start, bad)``: run ``r`` covers pixels ``rx0[r] <= x < rx1[r]`` of row ``ry[r]``; runs of
    row ``y`` are ``row_start[y]:row_start[y + 1]``; ``bad`` counts bytes other than 0 and 1.
    """
    cap = 64
    ry = np.empty(cap, np.int32)
    rx0 = np.empty(cap, np.int32)
    rx1 = np.empty(cap, np.int32)
    row_start = np.empty(h + 1, np.int64)
    n = 0
    bad = 0
    for y in range(h):
        row_start[y] = n
        if cap - n < w // 2 + 1:
            # grow between rows only: rebinding arrays inside the hot loop costs numba 5-10x
            cap = 2 * cap + w
            ry = _grow32(ry, cap)
            rx0 = _grow32(rx0, cap)
            rx1 = _grow32(rx1, cap)
        start = base + y * w
        end = start + w
        i = start
        inside = False
        x0 = 0
        while i < end:
            if aligned and (i & 7) == 0:
                # skip whole words that continue the current stretch (all 0 or all 1 bytes)
                wi = i >> 3
                we = end >> 3
                if inside:
                    while wi < we and b64[wi] == _ONES:
                        wi += 1
                else:
                    while wi < we and b64[wi] == _ZERO:
                        wi += 1
                i = wi << 3
                if i >= end:
                    break
            v = b8[i]
            if v > 1:
                bad += 1
            on = v != 0
            if on != inside:
                if on:
                    x0 = i - start
                else:
                    ry[n] = y
                    rx0[n] = x0
                    rx1[n] = i - start
                    n += 1
                inside = on
            i += 1
        if inside:
            ry[n] = y
            rx0[n] = x0
            rx1[n] = w
            n += 1
    row_start[h] = n
    return ry[:n], rx0[:n], rx1[:n], row_start, bad


@njit(cache=True, nogil=True)
def _grow32(a, cap):
    b = np.empty(cap, a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, nogil=True)
def _grow64(a, cap):
    b = np.empty(cap, a.dtype)
    b[: a.shape[0]] = a
    return b


def slice_runs(mask2d) -> tuple:
    """Runs of a 2D boolean mask: ``(ry, rx0, rx1, row_start)`` (see :func:`_scan_runs`)."""
    m = np.ascontiguousarray(mask2d, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2D array indexed [y, x]; got shape {m.shape}")
    b8 = m.reshape(-1).view(np.uint8)
    b64, aligned = _words(b8)
    ry, rx0, rx1, rs, _ = _scan_runs(b8, b64, 0, m.shape[0], m.shape[1], aligned)
    return ry, rx0, rx1, rs


def _words(b8):
    n8 = (b8.shape[0] // 8) * 8
    if n8 == 0 or b8.ctypes.data % 8 != 0:
        return np.zeros(1, np.uint64), False
    return b8[:n8].view(np.uint64), True


# ------------------------------------------------------------------------------------------------
# 2. components (4-connected) of the runs
# ------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def _components(ry, rx0, rx1, row_start, h):
    """4-components of the runs: ``(label per run, n, holes per component, bbox (n, 4) =
    (xmin, ymin, xmax, ymax) inclusive, first run per component)``.

    Labels follow the raster order of each component's first pixel (as ``ndimage.label``).
    Holes (8-connected background components enclosed) = ``1 - chi`` with ``chi = #runs -
    #(overlapping run pairs in adjacent rows)``.
    """
    nr = ry.shape[0]
    parent = np.arange(nr)
    adj = 0
    for y in range(1, h):
        i, i1 = row_start[y - 1], row_start[y]
        j, j1 = row_start[y], row_start[y + 1]
        while i < i1 and j < j1:
            if rx0[i] < rx1[j] and rx0[j] < rx1[i]:
                a, b = _find(parent, i), _find(parent, j)
                if a != b:
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
            if rx1[i] <= rx1[j]:
                i += 1
            else:
                j += 1
    lab = np.empty(nr, np.int32)
    root_lab = np.full(nr, -1, np.int32)
    n = 0
    for r in range(nr):
        t = _find(parent, r)
        if root_lab[t] < 0:
            root_lab[t] = n
            n += 1
        lab[r] = root_lab[t]
    chi = np.zeros(n, np.int64)
    bbox = np.empty((n, 4), np.int64)
    first = np.full(n, -1, np.int64)
    for r in range(nr):
        c = lab[r]
        chi[c] += 1
        if first[c] < 0:
            first[c] = r
            bbox[c, 0] = rx0[r]
            bbox[c, 1] = ry[r]
            bbox[c, 2] = rx1[r] - 1
            bbox[c, 3] = ry[r]
        else:
            bbox[c, 0] = min(bbox[c, 0], rx0[r])
            bbox[c, 2] = max(bbox[c, 2], rx1[r] - 1)
            bbox[c, 3] = max(bbox[c, 3], ry[r])
    for y in range(1, h):
        i, i1 = row_start[y - 1], row_start[y]
        j, j1 = row_start[y], row_start[y + 1]
        while i < i1 and j < j1:
            if rx0[i] < rx1[j] and rx0[j] < rx1[i]:
                chi[lab[i]] -= 1
            if rx1[i] <= rx1[j]:
                i += 1
            else:
                j += 1
    holes = 1 - chi
    return lab, n, holes, bbox, first


def slice_components(mask2d):
    """4-connected components of a 2D mask from its runs: ``(runs, labels, n, holes, bbox)``."""
    ry, rx0, rx1, rs = slice_runs(mask2d)
    lab, n, holes, bbox, _ = _components(ry, rx0, rx1, rs, np.asarray(mask2d).shape[0])
    return (ry, rx0, rx1, rs), lab, n, holes, bbox


# ------------------------------------------------------------------------------------------------
# 3. the outer Jordan contour of one component
# ------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, inline="always")
def _pix(pm, x, y, ox, oy):
    xx = x - ox
    yy = y - oy
    if xx < 0 or yy < 0 or yy >= pm.shape[0] or xx >= pm.shape[1]:
        return False
    return pm[yy, xx] != 0


@njit(cache=True, nogil=True)
def _walk(pm, ox, oy, sx, sy, vx, vy, d, pts, n):
    """Walk on from vertex ``(vx, vy)`` (next step ``d``) writing points into ``pts[n:]``; stops
    when back at the start ``(sx, sy)`` with ``d == 0`` or when ``pts`` is full.
    Returns ``(n, vx, vy, d, done)``."""
    cap = pts.shape[0]
    while n < cap:
        pts[n, 0] = vx
        pts[n, 1] = vy
        n += 1
        if d == 0:
            vx += 1
        elif d == 1:
            vy += 1
        elif d == 2:
            vx -= 1
        else:
            vy -= 1
        a00 = _pix(pm, vx - 1, vy - 1, ox, oy)
        a10 = _pix(pm, vx, vy - 1, ox, oy)
        a20 = _pix(pm, vx + 1, vy - 1, ox, oy)
        a01 = _pix(pm, vx - 1, vy, ox, oy)
        a11 = _pix(pm, vx, vy, ox, oy)
        a21 = _pix(pm, vx + 1, vy, ox, oy)
        a02 = _pix(pm, vx - 1, vy + 1, ox, oy)
        a12 = _pix(pm, vx, vy + 1, ox, oy)
        a22 = _pix(pm, vx + 1, vy + 1, ox, oy)
        ll = a00 or a10 or a01 or a11   # cell with lower-left corner (vx-1, vy-1)
        lr = a10 or a20 or a11 or a21   # (vx, vy-1)
        ul = a01 or a11 or a02 or a12   # (vx-1, vy)
        ur = a11 or a21 or a12 or a22   # (vx, vy)
        e0 = ur and not lr
        e1 = ul and not ur
        e2 = ll and not ul
        e3 = lr and not ll
        # turn left, straight on, turn right: the first boundary edge wins
        for t in (1, 0, 3):
            nd = (d + t) % 4
            if (nd == 0 and e0) or (nd == 1 and e1) or (nd == 2 and e2) or (nd == 3 and e3):
                d = nd
                break
        if vx == sx and vy == sy and d == 0:
            return n, vx, vy, d, True
    return n, vx, vy, d, False


@njit(cache=True, nogil=True)
def _trace_outer(pm, ox, oy, sx, sy):
    """Boundary of ``U`` (closed cells with a corner in the pixels of ``pm``), from vertex ``(sx, sy)``.

    ``pm[y - oy, x - ox]`` is pixel ``(x, y)`` (outside the array: background).  Point ``(x, y)``
    is a pixel centre; the cell with lower-left corner ``(x, y)`` is in ``U`` when one of the
    pixels ``(x..x+1, y..y+1)`` is set.  The walk starts with a ``+x`` step at the lowest-then-
    leftmost vertex and takes, at every vertex, the first boundary edge among *turn left, go
    straight, turn right* (as :func:`contourmesh.sections._follow_boundaries`).  Only the 3 x 3
    pixels around each boundary vertex are read.
    """
    pts = np.empty((1024, 2), np.int64)
    n, vx, vy, d, done = _walk(pm, ox, oy, sx, sy, sx, sy, 0, pts, 0)
    while not done:
        q = np.empty((2 * pts.shape[0], 2), np.int64)
        q[:n] = pts[:n]
        pts = q
        n, vx, vy, d, done = _walk(pm, ox, oy, sx, sy, vx, vy, d, pts, n)
    return pts[:n]


def outer_jordan_contour(mask2d) -> np.ndarray:
    """The outer contour of the outer Jordan digitization of a 2D mask (one 4-component).

    Equal to the outer contour of :func:`contourmesh.sections.trace_contours` for that mask.
    """
    m = np.ascontiguousarray(mask2d, dtype=bool)
    if m.ndim != 2 or not m.any():
        raise ValueError(f"mask must be a non-empty 2D array indexed [y, x]; got shape {m.shape}")
    ys, xs = np.nonzero(m)
    y0 = ys.min()
    x0 = xs[ys == y0].min()
    return _trace_outer(m.view(np.uint8), 0, 0, int(x0) - 1, int(y0) - 1)


# ------------------------------------------------------------------------------------------------
# 4. the MLP of a contour (Klette & Yip, as in contourmesh.polygons.mlp)
# ------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _mlp_outer(c):
    """MLP of an outer 4-contour (positive area), as :func:`contourmesh.polygons.mlp_polygon`."""
    cand, kind = _candidates(c)
    nnz = 0
    last = -1
    for i in range(kind.shape[0]):
        if kind[i] != 0:
            nnz += 1
            last = i
    if nnz == 1:
        poly = cand[last: last + 1].copy()
    else:
        s = -1
        for i in range(kind.shape[0]):
            if kind[i] == 1:
                if s < 0 or cand[i, 1] < cand[s, 1] or (cand[i, 1] == cand[s, 1] and cand[i, 0] < cand[s, 0]):
                    s = i
        if s < 0:
            return np.empty((0, 2), np.int64)
        poly = _clean_polygon(cand[_string_pulling(cand, kind, s)])
    best = 0
    bd = -1
    for i in range(poly.shape[0]):
        dx = poly[i, 0] - c[0, 0]
        dy = poly[i, 1] - c[0, 1]
        d2 = dx * dx + dy * dy
        if bd < 0 or d2 < bd:
            bd = d2
            best = i
    out = np.empty_like(poly)
    p = poly.shape[0]
    for i in range(p):
        out[i] = poly[(i + best) % p]
    return out


@njit(cache=True, nogil=True)
def _slice_polygons(b8, b64, base, h, w, aligned, stamp, stamp_id):
    """Steps 1-4 for one slice.

    Returns ``(ry, rx0, rx1, row_start, lab, n, status, bbox, poly, poly_start, degenerate, bad)``:
    ``status`` is 0 in scope, 1 when a component has a hole, 2 when two MLP vertices of the
    slice share a position.  ``poly[poly_start[c]:poly_start[c + 1]]`` is component ``c``'s MLP
    (pixel-centre coordinates); ``degenerate[c]`` marks MLPs without area (crack contour instead).
    ``stamp`` (``(h + 3, w + 3)`` int64, reused across slices) detects shared positions.
    """
    ry, rx0, rx1, row_start, bad = _scan_runs(b8, b64, base, h, w, aligned)
    lab, n, holes, bbox, first = _components(ry, rx0, rx1, row_start, h)
    poly_start = np.zeros(n + 1, np.int64)
    degenerate = np.zeros(n, np.uint8)
    status = 0
    for c in range(n):
        if holes[c] != 0:
            status = 1
    if status != 0 or bad != 0:
        return ry, rx0, rx1, row_start, lab, n, status, bbox, np.empty((0, 2), np.int64), poly_start, degenerate, bad
    polys = []
    total = 0
    if n == 1:
        sl = b8[base: base + h * w].reshape(h, w)
        r = first[0]
        c0 = _trace_outer(sl, 0, 0, rx0[r] - 1, ry[r] - 1)
        polys.append(_mlp_outer(c0))
    else:
        # runs of each component (counting sort), painted into a local image around its bbox
        cnt = np.zeros(n + 1, np.int64)
        for r in range(ry.shape[0]):
            cnt[lab[r] + 1] += 1
        for c in range(n):
            cnt[c + 1] += cnt[c]
        order = np.empty(ry.shape[0], np.int64)
        fill = cnt[:n].copy()
        for r in range(ry.shape[0]):
            order[fill[lab[r]]] = r
            fill[lab[r]] += 1
        for c in range(n):
            x0, y0, x1, y1 = bbox[c, 0], bbox[c, 1], bbox[c, 2], bbox[c, 3]
            pm = np.zeros((y1 - y0 + 1, x1 - x0 + 1), np.uint8)
            for t in range(cnt[c], cnt[c + 1]):
                r = order[t]
                pm[ry[r] - y0, rx0[r] - x0: rx1[r] - x0] = 1
            r = first[c]
            cc = _trace_outer(pm, x0, y0, rx0[r] - 1, ry[r] - 1)
            polys.append(_mlp_outer(cc))
    for c in range(n):
        p = polys[c]
        k = p.shape[0]
        a2 = 0
        for i in range(k):
            j = (i + 1) % k
            a2 += p[i, 0] * p[j, 1] - p[j, 0] * p[i, 1]
        if k < 3 or a2 == 0:
            degenerate[c] = 1
        else:
            total += k
        poly_start[c + 1] = poly_start[c] + (0 if degenerate[c] else k)
    poly = np.empty((total, 2), np.int64)
    for c in range(n):
        if degenerate[c] == 0:
            p = polys[c]
            s = poly_start[c]
            for i in range(p.shape[0]):
                poly[s + i, 0] = p[i, 0]
                poly[s + i, 1] = p[i, 1]
                x = p[i, 0] + 1
                y = p[i, 1] + 1
                if stamp[y, x] == stamp_id:
                    status = 2
                stamp[y, x] = stamp_id
    return ry, rx0, rx1, row_start, lab, n, status, bbox, poly, poly_start, degenerate, bad


def slice_polygons(mask2d):
    """MLPs of the 4-components of a 2D mask (the full mesher's ``"mlp"`` rings, in pixel-centre
    coordinates): ``(polygons, degenerate, holes)`` with ``polygons[c]`` a ``(p, 2)`` int64 array."""
    m = np.ascontiguousarray(mask2d, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2D array indexed [y, x]; got shape {m.shape}")
    b8 = m.reshape(-1).view(np.uint8)
    b64, aligned = _words(b8)
    h, w = m.shape
    stamp = np.zeros((h + 3, w + 3), np.int64)
    out = _slice_polygons(b8, b64, 0, h, w, aligned, stamp, 1)
    n, status, poly, ps, deg = out[5], out[6], out[8], out[9], out[10]
    if status == 1:
        raise ValueError("a component of the mask has a hole; slice_polygons handles hole-free components only")
    return [poly[ps[c]: ps[c + 1]] for c in range(n)], deg.astype(bool)


# ------------------------------------------------------------------------------------------------
# 5. joins between consecutive slices
# ------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _pair_joins(ary, ax0, ax1, ars, alab, na, bry, bx0, bx1, brs, blab, nb, h):
    """Partners of the components of slices k (A) and k + 1 (B).

    Returns ``(ok, partner_a, partner_b)``; ``ok`` is True when every group is one component on
    each side whose overlap ``O`` is connected and hole-free (a simple band join), i.e. when
    each component overlaps at most one of the other slice and ``chi(O) = #components(O) = 1``.
    """
    pa = np.full(na, -1, np.int64)
    pb = np.full(nb, -1, np.int64)
    cap = 64
    oy = np.empty(cap, np.int64)
    o0 = np.empty(cap, np.int64)
    o1 = np.empty(cap, np.int64)
    oc = np.empty(cap, np.int64)
    ors = np.zeros(h + 1, np.int64)
    no = 0
    ok = True
    for y in range(h):
        ors[y] = no
        i, i1 = ars[y], ars[y + 1]
        j, j1 = brs[y], brs[y + 1]
        if cap - no < (i1 - i) + (j1 - j):
            cap = 2 * cap + (i1 - i) + (j1 - j)
            oy = _grow64(oy, cap)
            o0 = _grow64(o0, cap)
            o1 = _grow64(o1, cap)
            oc = _grow64(oc, cap)
        while i < i1 and j < j1:
            lo = max(ax0[i], bx0[j])
            hi = min(ax1[i], bx1[j])
            if lo < hi:
                a = alab[i]
                b = blab[j]
                if pa[a] < 0:
                    pa[a] = b
                elif pa[a] != b:
                    ok = False
                if pb[b] < 0:
                    pb[b] = a
                elif pb[b] != a:
                    ok = False
                oy[no] = y
                o0[no] = lo
                o1[no] = hi
                oc[no] = a
                no += 1
            if ax1[i] <= bx1[j]:
                i += 1
            else:
                j += 1
        if not ok:
            return False, pa, pb
    ors[h] = no
    # the overlap of each pair: components (union-find) and Euler number
    parent = np.arange(no)
    chi = np.zeros(na, np.int64)
    for r in range(no):
        chi[oc[r]] += 1
    for y in range(1, h):
        i, i1 = ors[y - 1], ors[y]
        j, j1 = ors[y], ors[y + 1]
        while i < i1 and j < j1:
            if o0[i] < o1[j] and o0[j] < o1[i]:
                chi[oc[i]] -= 1
                u, v = _find(parent, i), _find(parent, j)
                if u != v:
                    parent[max(u, v)] = min(u, v)
            if o1[i] <= o1[j]:
                i += 1
            else:
                j += 1
    ncomp = np.zeros(na, np.int64)
    for r in range(no):
        if _find(parent, r) == r:
            ncomp[oc[r]] += 1
    for a in range(na):
        if pa[a] >= 0 and (ncomp[a] != 1 or chi[a] != 1):
            ok = False
    return ok, pa, pb


# ------------------------------------------------------------------------------------------------
# 6. bands (the paper's triangulation with the full mesher's twist guard)
# ------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _initial_edge(c1, c2, window):
    """:func:`contourmesh.bands.wiederhold.initial_edge` (section 3.2), same ties."""
    m = c2.shape[0]
    px, py, pz = c1[0, 0], c1[0, 1], c1[0, 2]
    radius = 2.0 * abs(c2[0, 2] - pz)
    if m > 2 * window + 1:
        best = -1
        bd = 0.0
        bo = 0
        for t in range(2 * window + 1):
            off = 0 if t == 0 else ((t + 1) // 2 if t % 2 == 1 else -(t // 2))
            j = off % m
            dx = c2[j, 0] - px
            dy = c2[j, 1] - py
            dz = c2[j, 2] - pz
            d2 = dx * dx + dy * dy + dz * dz
            if best < 0 or d2 < bd:
                bd = d2
                best = j
                bo = off
        if bd <= radius * radius and abs(bo) < window:
            return best
    best = 0
    bd = -1.0
    for j in range(m):
        dx = c2[j, 0] - px
        dy = c2[j, 1] - py
        dz = c2[j, 2] - pz
        d2 = dx * dx + dy * dy + dz * dz
        if bd < 0 or d2 < bd:
            bd = d2
            best = j
    return best


@njit(cache=True, nogil=True)
def _folded(faces, n_lower):
    """True when some diagonal of the band carries four triangles (a "double cone"): all the
    advances of one polygon happen in one block (:func:`contourmesh.bands.band_is_folded`)."""
    s = faces.shape[0]
    changes = 0
    for t in range(s):
        # a triangle on a lower edge has two lower vertices
        lo_t = (faces[t, 0] < n_lower) + (faces[t, 1] < n_lower) + (faces[t, 2] < n_lower)
        u = (t + 1) % s
        lo_u = (faces[u, 0] < n_lower) + (faces[u, 1] < n_lower) + (faces[u, 2] < n_lower)
        if (lo_t == 2) != (lo_u == 2):
            changes += 1
    return changes <= 2


@njit(cache=True, nogil=True)
def _area_sum(P, f):
    tot = 0.0
    for t in range(f.shape[0]):
        a, b, c = f[t, 0], f[t, 1], f[t, 2]
        ux = P[b, 0] - P[a, 0]
        uy = P[b, 1] - P[a, 1]
        uz = P[b, 2] - P[a, 2]
        vx = P[c, 0] - P[a, 0]
        vy = P[c, 1] - P[a, 1]
        vz = P[c, 2] - P[a, 2]
        cx = uy * vz - uz * vy
        cy = uz * vx - ux * vz
        cz = ux * vy - uy * vx
        tot += 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
    return tot


@njit(cache=True, nogil=True)
def _band(lo, hi, window):
    """Faces of the band ``lo`` -> ``hi`` (indices into ``vstack([lo, hi])``) and a status:
    0 = the paper's band passes the twist guard; 1 = folded, twisted or too close to call
    (the caller redoes this band with the full mesher's code)."""
    n = lo.shape[0]
    m = hi.shape[0]
    if n <= m:
        c1, c2, swapped = lo, hi, False
    else:
        c1, c2, swapped = hi, lo, True
    n1 = c1.shape[0]
    n2 = c2.shape[0]
    j0 = _initial_edge(c1, c2, window)
    r2 = np.empty((n2, 3))
    for j in range(n2):
        r2[j] = c2[(j + j0) % n2]
    E = wiederhold_edges(c1[:, 0].copy(), c1[:, 1].copy(), r2[:, 0].copy(), r2[:, 1].copy())
    f = _edges_to_faces(E, n1, n2, 0, j0, n, swapped)
    if _folded(f, n):
        return f, 1
    if min(n, m) > 2:
        ref_e = arclength_edges(c1, r2)
        ref_f = _edges_to_faces(ref_e, n1, n2, 0, j0, n, swapped)
        if _folded(ref_f, n):
            return f, 1
        P = np.empty((n + m, 3))
        P[:n] = lo
        P[n:] = hi
        a = _area_sum(P, f)
        r = _area_sum(P, ref_f)
        if a > 1.25 * r * (1.0 - 1e-9):
            return f, 1
    return f, 0


def band_faces(lower, upper) -> np.ndarray:
    """The volume mesher's band between two rings (paper's triangulation plus its twist guard).

    ``lower`` ``(n, 3)`` and ``upper`` ``(m, 3)`` as in :func:`contourmesh.bands.triangulate_band`;
    returns faces indexing ``np.vstack([lower, upper])`` and whether the guard replaced the band.
    """
    lo = np.ascontiguousarray(lower, dtype=np.float64)
    hi = np.ascontiguousarray(upper, dtype=np.float64)
    if lo.ndim != 2 or lo.shape[1] != 3 or hi.ndim != 2 or hi.shape[1] != 3 or len(lo) < 1 or len(hi) < 1:
        raise ValueError(f"lower and upper must be (n, 3) arrays; got {lo.shape} and {hi.shape}")
    f, status = _band(lo, hi, INITIAL_EDGE_WINDOW)
    if status == 0:
        return f, False
    return _band_py(lo, hi)


def _band_py(lo, hi, triangulation="wiederhold"):
    """The full mesher's ``_Mesher.band`` on coordinates (folded/twisted bands)."""
    from .bands import triangulate_band
    from .measure import triangle_areas

    f = triangulate_band(lo, hi, triangulation)
    replaced = False
    if triangulation in ("wiederhold", "greedy") and min(len(lo), len(hi)) > 2:
        P = np.concatenate([lo, hi])
        ref_f = triangulate_band(lo, hi, "arclength")
        ref = triangle_areas(P, ref_f).sum()
        if triangle_areas(P, f).sum() > 1.25 * ref:
            n, m = sorted((len(lo), len(hi)))
            f = triangulate_band(lo, hi, "optimal") if n * n * m <= 3e7 else ref_f
            replaced = True
    return f, replaced


@njit(cache=True, nogil=True)
def _pair_bands(ringA, startA, ringB, startB, pa, window):
    """Bands of every pair ``(a, pa[a])`` (in order of ``a``): concatenated local faces, the face
    offset of each band and a status per band (see :func:`_band`)."""
    na = pa.shape[0]
    nb = 0
    tot = 0
    for a in range(na):
        if pa[a] >= 0:
            nb += 1
            b = pa[a]
            tot += (startA[a + 1] - startA[a]) + (startB[b + 1] - startB[b])
    faces = np.empty((tot, 3), np.int64)
    foff = np.zeros(nb + 1, np.int64)
    status = np.zeros(nb, np.int64)
    t = 0
    for a in range(na):
        if pa[a] < 0:
            continue
        b = pa[a]
        lo = ringA[startA[a]: startA[a + 1]]
        hi = ringB[startB[b]: startB[b + 1]]
        f, st = _band(lo, hi, window)
        s = foff[t]
        faces[s: s + f.shape[0]] = f
        foff[t + 1] = s + f.shape[0]
        status[t] = st
        t += 1
    return faces, foff, status


# ------------------------------------------------------------------------------------------------
# the driver
# ------------------------------------------------------------------------------------------------
_TLS = threading.local()


def _stamp(h, w):
    s = getattr(_TLS, "stamp", None)
    if s is None or s.shape != (h + 3, w + 3):
        s = np.zeros((h + 3, w + 3), np.int64)
        _TLS.stamp = s
        _TLS.next_id = 1
    _TLS.next_id += 1
    return s, _TLS.next_id


class _OutOfScope(Exception):
    pass


def _params_ok(volume, spacing, z, axis, label, threshold, origin):
    """The cheap parameter checks of :func:`contourmesh.volumes.prepare_volume` (True if all pass)."""
    if not isinstance(volume, np.ndarray) or volume.ndim != 3 or 0 in volume.shape:
        return False
    if volume.dtype.kind not in "biuf":
        return False
    if axis not in (0, 1, 2) or isinstance(axis, bool):
        return False
    try:
        sp = np.asarray(spacing, dtype=np.float64).reshape(-1)
        org = np.asarray(origin, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return False
    if sp.shape != (3,) or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
        return False
    if org.shape != (3,) or not np.all(np.isfinite(org)):
        return False
    if label is not None and threshold is not None:
        return False
    if threshold is not None:
        try:
            if not np.isfinite(threshold):
                return False
        except TypeError:
            return False
    return True


def fast_volume_to_mesh(volume, *, spacing=(1.0, 1.0, 1.0), z=None, axis: int = 0, label=None, threshold=None,
                        origin=(0.0, 0.0, 0.0), polygon: str = "mlp", triangulation: str = "wiederhold",
                        caps: str = "flat", threads: int | None = None):
    """The mesh of :func:`contourmesh.volumes.volume_to_mesh`, fast, or None outside the fast path's scope.

    Parameters
    ----------
    volume, spacing, z, axis, label, threshold, origin, polygon, triangulation, caps
        As for :func:`contourmesh.volumes.volume_to_mesh`.
    threads : int, optional
        Worker threads for the per-slice and per-pair kernels (default: ``NUMBA_NUM_THREADS`` or
        the number of CPUs; 1 runs everything in the calling thread).

    Returns
    -------
    Mesh or None
        The same vertices and faces as the full mesher (``meta["fast_path"] = True``), or None
        when the volume or the options are outside the scope described in the module docstring
        (the caller then runs the full mesher, which also raises the input errors).
    """
    if polygon != "mlp" or triangulation != "wiederhold" or caps not in ("flat", "half"):
        return None
    if not _params_ok(volume, spacing, z, axis, label, threshold, origin):
        return None
    try:
        return _fast(volume, spacing, z, axis, label, threshold, origin, caps, threads)
    except _OutOfScope:
        return None


def _slicer(vol, axis, label, threshold):
    """``(nz, h, w, get)``: ``get(k)`` -> ``(b8, b64, base, aligned, check)`` for slice k."""
    kind = vol.dtype.kind
    if axis != 0:
        order = [axis] + [a for a in (0, 1, 2) if a != axis]
        vol = np.transpose(vol, order)
    nz, h, w = vol.shape
    direct = label is None and threshold is None and (kind == "b" or vol.dtype.itemsize == 1) \
        and vol.flags.c_contiguous
    if direct:
        b8 = vol.reshape(-1).view(np.uint8)
        b64, aligned = _words(b8)

        def get(k):
            return b8, b64, k * h * w, aligned

        return nz, h, w, get

    def get(k):
        s = vol[k]
        if kind == "f" and not np.isfinite(s).all():
            raise _OutOfScope
        if label is not None:
            m = s == label
        elif threshold is not None:
            m = s > threshold
        elif kind == "b":
            m = s
        else:
            m = s != 0
            if np.count_nonzero(s == 1) != np.count_nonzero(m):
                raise _OutOfScope  # values other than 0 and 1: the full mesher says which
        m = np.ascontiguousarray(m, dtype=bool)
        b = m.reshape(-1).view(np.uint8)
        b64, aligned = _words(b)
        return b, b64, 0, aligned

    return nz, h, w, get


def _map(fn, items, threads):
    """``[fn(i) for i in items]``, on ``threads`` threads (the kernels release the GIL)."""
    if threads <= 1 or len(items) < 4:
        return [fn(i) for i in items]
    from concurrent.futures import ThreadPoolExecutor

    ex = ThreadPoolExecutor(max_workers=threads)
    try:
        return list(ex.map(fn, items))
    finally:
        ex.shutdown(wait=True, cancel_futures=True)


def _fast(volume, spacing, z, axis, label, threshold, origin, caps, threads):
    from .types import Mesh

    if threads is None:
        threads = int(os.environ.get("NUMBA_NUM_THREADS", 0)) or (os.cpu_count() or 1)
    threads = max(1, int(threads))
    sp = np.asarray(spacing, dtype=np.float64).reshape(-1)
    org = np.asarray(origin, dtype=np.float64).reshape(-1)
    if axis != 0:
        order = [axis] + [a for a in (0, 1, 2) if a != axis]
        sp = sp[order]
    dz, dy, dx = float(sp[0]), float(sp[1]), float(sp[2])
    ox, oy = float(org[0]), float(org[1])
    nz, h, w, get = _slicer(volume, axis, label, threshold)
    if z is None:
        zs = org[2] + sp[0] * np.arange(nz, dtype=np.float64)
    else:
        zs = np.asarray(z, dtype=np.float64).reshape(-1)
        if zs.shape != (nz,) or not np.all(np.isfinite(zs)) or (nz > 1 and not np.all(np.diff(zs) > 0)):
            raise _OutOfScope

    # steps 1-4, per slice
    def per_slice(k):
        b8, b64, base, aligned = get(k)
        stamp, sid = _stamp(h, w)
        out = _slice_polygons(b8, b64, base, h, w, aligned, stamp, sid)
        if out[11] != 0 or out[6] != 0:  # values other than 0/1, a hole, shared positions
            raise _OutOfScope
        return out

    S = _map(per_slice, list(range(nz)), threads)
    occupied = [k for k in range(nz) if S[k][5] > 0]
    if not occupied:
        raise _OutOfScope  # no foreground: the full mesher raises the error

    from .volumes import grid_to_xy

    to_center, to_corner = grid_to_xy(ox, oy, dx, dy)

    # rings (physical xyz) of every slice, concatenated per slice; degenerate MLPs -> crack contours
    fallbacks = 0
    ring_xyz = [None] * nz
    ring_start = [None] * nz
    for k in occupied:
        ry, rx0, rx1, rs, lab, n, _, bbox, poly, ps, deg, _ = S[k]
        if not deg.any():
            xyz = np.empty((len(poly), 3))
            xyz[:, 0] = ox + poly[:, 0].astype(np.float64) * dx
            xyz[:, 1] = oy + poly[:, 1].astype(np.float64) * dy
            xyz[:, 2] = zs[k]
            ring_xyz[k] = xyz
            ring_start[k] = ps
            continue
        from .volumes import _crack_contours

        parts, starts = [], [0]
        for c in range(n):
            if deg[c]:
                fallbacks += 1
                x0, y0, x1, y1 = (int(v) for v in bbox[c])
                comp = np.zeros((y1 - y0 + 1, x1 - x0 + 1), dtype=bool)
                sel = np.flatnonzero(lab == c)
                for r in sel:
                    comp[ry[r] - y0, rx0[r] - x0: rx1[r] - x0] = True
                cont, area2 = _crack_contours(comp)
                outer = [cont[i] for i in range(len(cont)) if area2[i] > 0]
                xy = to_corner(outer[0] + np.array([x0, y0]))
            else:
                xy = to_center(poly[ps[c]: ps[c + 1]])
            parts.append(xy)
            starts.append(starts[-1] + len(xy))
        xy = np.concatenate(parts)
        if len(np.unique(xy, axis=0)) != len(xy):
            raise _OutOfScope  # coincident vertices: the full mesher nudges them apart
        ring_xyz[k] = np.c_[xy, np.full(len(xy), zs[k])]
        ring_start[k] = np.asarray(starts, dtype=np.int64)

    # step 5-6, per slice pair
    def per_pair(k):
        if S[k][5] == 0 or S[k + 1][5] == 0:
            return None
        A, B = S[k], S[k + 1]
        ok, pa, pb = _pair_joins(A[0], A[1], A[2], A[3], A[4], A[5], B[0], B[1], B[2], B[3], B[4], B[5], h)
        if not ok:
            raise _OutOfScope
        if not (pa >= 0).any():
            return None
        faces, foff, status = _pair_bands(ring_xyz[k], ring_start[k], ring_xyz[k + 1], ring_start[k + 1], pa,
                                          INITIAL_EDGE_WINDOW)
        return pa, pb, faces, foff, status

    J = _map(per_pair, list(range(nz - 1)), threads)

    # vertex ids in the full mesher's order: rings are created when a join (k ascending, groups by
    # their component below) or a cap first needs them
    ring_id = {}
    blocks = []
    nverts = 0

    def ring(k, c):
        nonlocal nverts
        key = (k, c)
        if key not in ring_id:
            s = ring_start[k]
            blk = ring_xyz[k][s[c]: s[c + 1]]
            ring_id[key] = (nverts, len(blk))
            blocks.append(blk)
            nverts += len(blk)
        return ring_id[key]

    has_above, has_below = set(), set()
    face_blocks = []
    band_joins = 0
    band_fallbacks = 0
    for k in range(nz - 1):
        if J[k] is None:
            continue
        pa, pb, faces, foff, status = J[k]
        t = 0
        for a in np.flatnonzero(pa >= 0):
            b = int(pa[a])
            a = int(a)
            has_above.add((k, a))
            has_below.add((k + 1, b))
            lo0, nlo = ring(k, a)
            hi0, nhi = ring(k + 1, b)
            f = faces[foff[t]: foff[t + 1]]
            if status[t]:
                lo = ring_xyz[k][ring_start[k][a]: ring_start[k][a + 1]]
                hi = ring_xyz[k + 1][ring_start[k + 1][b]: ring_start[k + 1][b + 1]]
                f, replaced = _band_py(lo, hi)
                band_fallbacks += bool(replaced)
            face_blocks.append(np.where(f < nlo, f + lo0, f - nlo + hi0))
            band_joins += 1
            t += 1

    # ends: caps (and prisms for components without a partner on either side)
    from .bands.caps import cap_faces

    def gap(k, up):
        if up:
            return zs[k + 1] - zs[k] if k + 1 < nz else (zs[k] - zs[k - 1] if k > 0 else 1.0)
        return zs[k] - zs[k - 1] if k > 0 else (zs[k + 1] - zs[k] if k + 1 < nz else 1.0)

    shifted_planes = {}

    def new_ring(xy, zc):
        nonlocal nverts
        blk = np.c_[xy, np.full(len(xy), zc)]
        start = nverts
        blocks.append(blk)
        nverts += len(blk)
        key = float(zc)
        shifted_planes.setdefault(key, []).append(xy)
        return start, blk

    def close(k, c, up, zc):
        r0, nr = ring(k, c)
        s = ring_start[k]
        xyz = ring_xyz[k][s[c]: s[c + 1]]
        if zc is not None:
            t0, txyz = new_ring(xyz[:, :2], zc)
            if up:
                f, replaced = _band_or_py(xyz, txyz)
                face_blocks.append(np.where(f < nr, f + r0, f - nr + t0))
            else:
                f, replaced = _band_or_py(txyz, xyz)
                face_blocks.append(np.where(f < nr, f + t0, f - nr + r0))
            nonlocal band_fallbacks
            band_fallbacks += bool(replaced)
            r0, xyz = t0, txyz
        try:
            f = cap_faces(xyz[:, :2], [], upward=up)
        except ValueError:
            raise _OutOfScope from None  # the full mesher closes it with pixels
        face_blocks.append(f + r0)

    for k in occupied:
        n = S[k][5]
        for c in range(n):
            above, below = (k, c) in has_above, (k, c) in has_below
            if above and below:
                continue
            if not above and not below:
                close(k, c, False, zs[k] - gap(k, False) / 2)
                close(k, c, True, zs[k] + gap(k, True) / 2)
                continue
            up = not above
            zc = zs[k] + (gap(k, up) / 2 if up else -gap(k, up) / 2) if caps == "half" else None
            close(k, c, up, zc)
    for xys in shifted_planes.values():
        if len(xys) > 1:
            xy = np.concatenate(xys)
            if len(np.unique(xy, axis=0)) != len(xy):
                raise _OutOfScope
    V = np.concatenate(blocks) if blocks else np.zeros((0, 3))
    F = np.concatenate(face_blocks) if face_blocks else np.zeros((0, 3), np.int64)
    meta = {
        "method": "contourmesh", "source": "volume", "polygon": "mlp", "triangulation": "wiederhold",
        "caps": caps, "band_joins": band_joins, "exact_joins": 0, "polygon_fallbacks": fallbacks,
        "crack_rings": 0, "band_fallbacks": band_fallbacks,
        "connectivity": "object 6 (4 in slice) / background 26 (8 in slice)", "fast_path": True,
    }
    return Mesh(V, F, P=len(V), meta=meta)


def _band_or_py(lo, hi):
    f, status = _band(np.ascontiguousarray(lo), np.ascontiguousarray(hi), INITIAL_EDGE_WINDOW)
    if status == 0:
        return f, False
    return _band_py(lo, hi)
