"""Curved bands (``bands="curved"``): the faces between two drawn sections bent onto a smooth profile.

A band between two rings drawn ``h`` apart is ruled: every rung (an edge from one ring to the
other) is straight.  Its volume is about the trapezoid rule's (:mod:`contourmesh.bands.fidelity`
keeps it within the frustum-trapezoid interval); on a smooth solid that is short of the truth, by
about ``h^2 / (4 R^2)`` on a sphere of radius ``R`` (2.25 % at ``R = 10``, ``h = 3``), because the
surface between two sections bulges out beyond the rungs.

:func:`curve_bands` replaces every rung by a cubic Hermite curve through its two ends, with the
surface's slope ``d(x, y)/dz`` at each end estimated from that vertex's neighbours one section up
and one section down (the band's own vertex correspondence; a three-point difference over uneven
spacings).  At an end with no neighbour on the far side the curve's second derivative is zero
there (a natural end).  Each band then gets ``L - 1`` intermediate rings (one point per rung);
``L`` per pair of sections is the smallest that keeps the polyline within ``eps`` of its curve
(at most ``max_levels``).  The drawn rings are untouched, so the mesh's section at every contour
plane is still the drawn one; faces that are not between two consecutive section planes (caps,
domes, collars, mid-plane joins) are kept as they are, and a rung is bent only where both of its
faces are bent, so the mesh stays closed.

A cubic in the rung's parameter cannot follow a profile whose slope grows without bound, as near
a pole: a 5 mm ball drawn every 3 mm (three or four sections) stays 1.1 to 1.4 % short in volume
with cubic rungs alone.  The section's *area* is better behaved: on a sphere or an ellipsoid it is
exactly quadratic in z, and near a smooth pole it is linear.  So each band that runs from one
closed ring to one closed ring (:func:`_level_links`, which also finds the band continuing it
through each of its rings) gets a parabola of its area, ``A(z) = A_k + (A_k1 - A_k) s + c h^2 s
(s - 1)`` through its two drawn areas, with ``c`` the second divided difference over them and the
section beyond (:func:`_area_curvature`; where there is a section beyond each end, the smaller of
the two, and none where they differ in sign: an inflection is left to the cubic).  Each of the
band's intermediate rings is then scaled about its own area centroid so that it encloses ``A`` at
its height (:func:`_follow_area_profile`).  Guards: the areas of one sign (a hole's band follows
its own area), the fitted area within 0.5 and 1.5 times the smaller and larger drawn one, no ring
scaled by more than 1.25 (or less than 0.8), and, in :func:`curved_without_crossings`, a pair whose
scaled rings make faces cross keeps its plain cubic rungs (and is left ruled if those cross too).
The 5 mm ball at dz = 3 mm: -1.39 % -> -0.60 % volume, -0.78 % -> -0.32 % area; what is left is
mostly the drawing (its polygons lie inside the circles: about ``ds^2 / (4 R^2)`` of the volume)
and the smooth ends' domes.  Straight walls (equal areas, zero second difference) stay straight.

On a solid with smooth sections the volume and area converge to the solid's (a sphere drawn at
``R / h = 3.3`` comes within a fraction of a percent, where the ruled band is 2.25 % short); the
price is that the volume no longer lies within the frustum-trapezoid interval of the drawn areas
(it is above the trapezoid rule on convex profiles), which is what the ruled default keeps.
"""

from __future__ import annotations

import numpy as np

__all__ = ["curve_bands"]


#: Where a rung runs one way, its end slopes along the chord are at most this many times the chord's.
_MAX_SLOPE = 2.0


def _plane_index(z: np.ndarray, zs: np.ndarray, tol: float) -> np.ndarray:
    """Per vertex, the index of the section plane it lies on (within ``tol``), or -1."""
    k = np.searchsorted(zs, z)
    k = np.clip(k, 0, len(zs) - 1)
    km = np.clip(k - 1, 0, len(zs) - 1)
    best = np.where(np.abs(zs[km] - z) < np.abs(zs[k] - z), km, k)
    return np.where(np.abs(zs[best] - z) <= tol, best, -1)


def _slopes(V: np.ndarray, E: np.ndarray, on_plane: np.ndarray, tol: float):
    """Per vertex on a section plane, ``d(x, y)/dz`` from the mean of its neighbours above and below
    (three-point difference over uneven steps), and whether both sides were found."""
    n = len(V)
    a, b = np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]]  # directed: a's neighbour b
    dz = V[b, 2] - V[a, 2]
    m = on_plane[a] & on_plane[b]  # neighbours on the section planes only (not a dome's or a collar's)
    a, b, dz = a[m], b[m], dz[m]
    out = {}
    for side, sel in (("up", dz > tol), ("down", dz < -tol)):
        cnt = np.bincount(a[sel], minlength=n).astype(np.float64)
        sx = np.bincount(a[sel], weights=V[b[sel], 0], minlength=n)
        sy = np.bincount(a[sel], weights=V[b[sel], 1], minlength=n)
        sz = np.bincount(a[sel], weights=V[b[sel], 2], minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[side] = (cnt > 0, np.c_[sx, sy] / cnt[:, None], sz / cnt)
    has_u, xy_u, z_u = out["up"]
    has_d, xy_d, z_d = out["down"]
    both = has_u & has_d & on_plane
    slope = np.zeros((n, 2))
    i = np.flatnonzero(both)
    h2 = (z_u[i] - V[i, 2])[:, None]
    h1 = (V[i, 2] - z_d[i])[:, None]
    d2 = (xy_u[i] - V[i, :2]) / h2
    d1 = (V[i, :2] - xy_d[i]) / h1
    slope[i] = (h2 * d1 + h1 * d2) / (h1 + h2)
    return slope, both


def _face_keys(T) -> np.ndarray:
    """Faces ``T`` (``(n, 3, 3)`` corner coordinates) as keys that compare equal where two faces have
    the same corners, whatever their vertex order (the corners sorted, each a 72-byte record)."""
    T = np.ascontiguousarray(np.asarray(T, dtype=np.float64).reshape(-1, 3, 3) + 0.0)  # -0.0 -> 0.0
    pts = T.view([("x", "f8"), ("y", "f8"), ("z", "f8")]).reshape(len(T), 3)
    return np.ascontiguousarray(np.sort(pts, axis=1)).view("V72").ravel()


def _ring_directions(V: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Per vertex, the unit direction of the ring through it (the principal direction of its ring
    edges ``E``); zero where it has none."""
    n = len(V)
    d = V[E[:, 1], :2] - V[E[:, 0], :2]
    L = np.hypot(*d.T)
    ok = L > 0
    d, E = d[ok] / L[ok, None], E[ok]
    m = np.zeros((n, 3))  # the 2x2 scatter matrix (xx, xy, yy) of the incident edge directions
    for col, val in enumerate((d[:, 0] ** 2, d[:, 0] * d[:, 1], d[:, 1] ** 2)):
        m[:, col] = np.bincount(E[:, 0], weights=val, minlength=n) + np.bincount(E[:, 1], weights=val, minlength=n)
    # the principal eigenvector of [[a, b], [b, c]]
    a, b, c = m.T
    ang = 0.5 * np.arctan2(2 * b, a - c)
    t = np.c_[np.cos(ang), np.sin(ang)]
    t[(a + c) == 0] = 0.0
    return t


def _along(v, t):
    return (v * t).sum(axis=1)[:, None] * t


def _across(v, t):
    return v - _along(v, t)


def _hermite(p, q, mp, mq, h, s):
    """Points at fractions ``s`` (shape ``(L,)``) of the cubic from ``p`` to ``q`` (``(r, 2)``) with
    slopes ``mp``, ``mq`` (per unit z) over a height ``h`` (``(r,)``): ``(r, L, 2)``."""
    s = s[None, :, None]
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    hh = h[:, None, None]
    return h00 * p[:, None] + h10 * hh * mp[:, None] + h01 * q[:, None] + h11 * hh * mq[:, None]


#: Area following (:func:`_follow_area_profile`) scales an intermediate ring by at most this factor
#: (or its inverse); a larger correction means the area fit does not describe the band.
_MAX_AREA_SCALE = 1.25

#: The fitted area between two sections stays within these multiples of the smaller and larger of
#: the two drawn areas (else the band keeps its cubic rungs).
_AREA_BOUNDS = (0.5, 1.5)


def _face_rungs(F, pk, inv, rung_of_edge, sel):
    """For band faces ``F[sel]``: ``(x, y, w, rx, ry, lower)``, each face rotated so that ``x``, ``y``
    lie on one plane and ``w`` on the other, ``rx``, ``ry`` the indices of its rungs ``w-x`` and
    ``y-w``, and whether ``x``, ``y`` lie on the lower plane."""
    f = F[sel]
    kf = pk[f]
    rot = np.where(kf[:, 0] == kf[:, 1], 0, np.where(kf[:, 1] == kf[:, 2], 1, 2))
    rows = np.arange(len(f))
    x, y, w = f[rows, rot], f[rows, (rot + 1) % 3], f[rows, (rot + 2) % 3]
    eid = inv.reshape(-1, 3)[sel]  # edges (0,1), (1,2), (2,0) of each face
    rx = rung_of_edge[eid[rows, (rot + 2) % 3]]
    ry = rung_of_edge[eid[rows, (rot + 1) % 3]]
    return x, y, w, rx, ry, pk[x] < pk[w]


def _one_loop(a, b):
    """The vertex set of the edges ``a[i] -> b[i]`` if they form a single closed loop, else None."""
    if len(a) < 3 or len(np.unique(a)) != len(a) or not np.array_equal(np.sort(a), np.sort(b)):
        return None
    nxt = dict(zip(a.tolist(), b.tolist()))
    v0 = v = int(a[0])
    for n in range(1, len(a) + 1):
        v = nxt[v]
        if v == v0:
            return frozenset(a.tolist()) if n == len(a) else None
    return None


def _level_links(V, comp, x, y, lower, pair):
    """Each band (``comp``: per face, its connected band) that runs from one closed ring to one closed
    ring: its signed areas at its lower and upper section, and the bands that continue it below and
    above through the same drawn ring (one band on each side of that ring).

    Returns ``(ok, a_lo, a_hi, below, above)`` per band (``below``/``above``: index or -1); the
    areas are the rings' signed areas in the faces' order (outward faces: positive on an outer ring,
    negative on a hole's)."""
    nc = int(comp.max()) + 1 if len(comp) else 0
    cr = V[x, 0] * V[y, 1] - V[x, 1] * V[y, 0]
    a_lo = 0.5 * np.bincount(comp[lower], weights=cr[lower], minlength=nc)
    a_hi = -0.5 * np.bincount(comp[~lower], weights=cr[~lower], minlength=nc)
    ok = np.zeros(nc, dtype=bool)
    keys: dict = {}
    order = np.argsort(comp, kind="stable")
    bounds = np.searchsorted(comp[order], np.arange(nc + 1))
    for c in range(nc):
        f = order[bounds[c]:bounds[c + 1]]
        lo, hi = f[lower[f]], f[~lower[f]]
        k_lo, k_hi = _one_loop(x[lo], y[lo]), _one_loop(y[hi], x[hi])
        if k_lo is None or k_hi is None:
            continue
        ok[c] = True
        k = int(pair[f[0]])
        keys.setdefault((k, k_lo), []).append((c, "up"))  # c starts upward from the ring on plane k
        keys.setdefault((k + 1, k_hi), []).append((c, "down"))
    below = np.full(nc, -1)
    above = np.full(nc, -1)
    for users in keys.values():
        ups = [c for c, d in users if d == "up"]
        downs = [c for c, d in users if d == "down"]
        if len(ups) == 1 and len(downs) == 1:
            below[ups[0]], above[downs[0]] = downs[0], ups[0]
    return ok, a_lo, a_hi, below, above


def _area_curvature(zs, pc, ok, a_lo, a_hi, below, above):
    """Per band, the second coefficient ``c`` of the parabola of its section area,
    ``A(z) = A_k + (A_k1 - A_k) (z - z_k) / h + c (z - z_k) (z - z_k1)``: the second divided
    difference over the band's two sections and the one beyond each of them where a band continues
    it there; where both exist, the one of smaller magnitude, and 0 where they differ in sign
    (minmod: a profile with an inflection is left to the cubic rungs).  NaN where the band does
    not qualify (not ring to ring, areas of mixed sign, no neighbour)."""
    nc = len(ok)
    c = np.full(nc, np.nan)
    for i in np.flatnonzero(ok):
        k = int(pc[i])
        a0, a1 = a_lo[i], a_hi[i]
        sg = np.sign(a0)
        if sg == 0 or np.sign(a1) != sg:
            continue
        a0, a1 = sg * a0, sg * a1  # a hole's band: its (positive) area
        z0, z1 = zs[k], zs[k + 1]
        d01 = (a1 - a0) / (z1 - z0)
        cands = []
        b = below[i]
        if b >= 0 and np.sign(a_lo[b]) == sg:
            zm = zs[k - 1]
            cands.append((d01 - (a0 - sg * a_lo[b]) / (z0 - zm)) / (z1 - zm))
        u = above[i]
        if u >= 0 and np.sign(a_hi[u]) == sg:
            zp = zs[k + 2]
            cands.append(((sg * a_hi[u] - a1) / (zp - z1) - d01) / (zp - z0))
        if not cands:
            continue
        if len(cands) == 2:
            l, r = cands
            c[i] = 0.0 if l * r <= 0 else (l if abs(l) < abs(r) else r)
        else:
            c[i] = cands[0]
    return c


def _band_components(nf, nr, rx, ry):
    """Per band face and per rung, the connected band (faces joined through their rungs) it belongs to."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows = np.r_[np.arange(nf), np.arange(nf)]
    cols = nf + np.r_[rx, ry]
    g = coo_matrix((np.ones(2 * nf), (rows, cols)), shape=(nf + nr, nf + nr))
    _, lab = connected_components(g, directed=False)
    _, lab = np.unique(lab, return_inverse=True)
    return lab[:nf], lab[nf:]


def _area_targets(V, zs, bands, levels):
    """Per band that follows its area profile, the fitted area at each of its intermediate levels
    (``{band: (sign, targets)}``), within the guards: a parabola fit (:func:`_area_curvature`),
    positive, between ``_AREA_BOUNDS`` of the band's two drawn areas."""
    out = {}
    for i in np.flatnonzero(np.isfinite(bands["c"]) & (bands["c"] != 0)):
        k = int(bands["pair"][i])
        lv = int(levels[k])
        if lv < 2:
            continue
        sg = np.sign(bands["a_lo"][i])
        a0, a1 = sg * bands["a_lo"][i], sg * bands["a_hi"][i]
        h = zs[k + 1] - zs[k]
        s = np.arange(1, lv) / lv
        tgt = a0 + (a1 - a0) * s + bands["c"][i] * h * h * s * (s - 1)
        lo, hi = _AREA_BOUNDS[0] * min(a0, a1), _AREA_BOUNDS[1] * max(a0, a1)
        if (tgt > lo).all() and (tgt < hi).all():
            out[int(i)] = (sg, tgt)
    return out


def _follow_area_profile(newV, nV, start, bands, targets, levels):
    """Scale each intermediate ring of the bands in ``targets`` about its own area centroid so that
    its enclosed area is the fitted one (in place on ``newV``, the intermediate points).  A band
    whose rings would need more than ``_MAX_AREA_SCALE`` is left as its cubic rungs made it.
    Returns how many bands were scaled."""
    fcomp, frx, fry, sig = bands["fcomp"], bands["frx"], bands["fry"], bands["sigma"]
    rcomp = bands["rcomp"]
    done = 0
    for lv in np.unique(levels[bands["pair"][list(targets)]]) if targets else ():
        comps = np.array([c for c in targets if levels[bands["pair"][c]] == lv])
        fsel = np.flatnonzero(np.isin(fcomp, comps))
        rsel = np.flatnonzero(np.isin(rcomp, comps))
        nc = len(bands["pair"])
        lam = np.ones((nc, lv - 1))
        cen = np.zeros((nc, lv - 1, 2))
        ok = np.zeros(nc, dtype=bool)
        ok[comps] = True
        for j in range(1, lv):
            px = newV[start[frx[fsel]] - nV + j - 1, :2]
            py = newV[start[fry[fsel]] - nV + j - 1, :2]
            cr = sig[fsel] * (px[:, 0] * py[:, 1] - px[:, 1] * py[:, 0])
            fc = fcomp[fsel]
            a2 = np.bincount(fc, weights=cr, minlength=nc)
            sx = np.bincount(fc, weights=(px[:, 0] + py[:, 0]) * cr, minlength=nc)
            sy = np.bincount(fc, weights=(px[:, 1] + py[:, 1]) * cr, minlength=nc)
            for c in comps:
                sg, tgt = targets[c]
                a = sg * a2[c] / 2
                if not a > 0:
                    ok[c] = False
                    continue
                lam[c, j - 1] = np.sqrt(tgt[j - 1] / a)
                cen[c, j - 1] = (sx[c], sy[c]) / (3 * a2[c])
        bad = (lam > _MAX_AREA_SCALE) | (lam < 1 / _MAX_AREA_SCALE)
        ok &= ~bad.any(axis=1)
        rsel = rsel[ok[rcomp[rsel]]]
        rc = rcomp[rsel]
        for j in range(1, lv):
            rows = start[rsel] - nV + j - 1
            c0 = cen[rc, j - 1]
            newV[rows, :2] = c0 + lam[rc, j - 1][:, None] * (newV[rows, :2] - c0)
        done += int(ok[comps].sum())
    return done


class _BandFaces:
    """The keys (:func:`_face_keys`) of the faces that may be bent, computed once for every attempt."""

    def __init__(self, faces):
        self.keys = np.unique(_face_keys(faces))


def curve_bands(V: np.ndarray, F: np.ndarray, zs, *, eps: float | None = None, max_levels: int = 8,
                flat_pairs=frozenset(), end_slopes=None, band_faces=None, follow_area: bool = True,
                plain_pairs=frozenset()):
    """Bend the bands between consecutive section planes ``zs`` onto cubic rungs (module docstring).

    ``V``, ``F``: a closed, outward-oriented mesh whose drawn rings lie on the planes ``zs``.
    ``eps``: the largest distance allowed between a bent rung and its polyline (default 2 % of the
    median length of the in-plane edges).  ``flat_pairs``: indices ``k`` of plane pairs
    ``(zs[k], zs[k + 1])`` left ruled.  ``end_slopes``: ``{(x, y, z): (dx/dz, dy/dz)}`` for vertices
    of end rings whose slope is known (the smooth ends' profile), used where a vertex has no
    neighbour on its far side (instead of a natural end).  ``band_faces``: ``(n, 3, 3)`` corner
    coordinates of the faces that may be bent (the band joins'; default every face between two
    consecutive planes); the slopes are taken along these faces' rungs only.  ``follow_area``: scale
    the intermediate rings of each band that runs from one ring to one ring onto the parabola of its
    section area (:func:`_follow_area_profile`), except in the plane pairs ``plain_pairs``.  Returns
    ``(V, F, info)``; ``info``: ``levels`` (per plane pair, the segments per rung; 1 where it is
    left ruled), ``bent_faces``, ``face_pair`` (per output face, the plane pair of the band it
    comes from, or -1), ``area_bands`` (bands scaled onto their area profile) and ``area_pairs``
    (the plane pairs holding them).
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    zs = np.unique(np.asarray(zs, dtype=np.float64))
    npairs = max(len(zs) - 1, 0)
    none = {"levels": np.ones(npairs, dtype=np.int64), "bent_faces": 0, "face_pair": np.full(len(F), -1),
            "area_bands": 0, "area_pairs": frozenset()}
    if npairs == 0 or not len(F):
        return V, F, none
    gaps = np.diff(zs)
    tol = 1e-7 * float(gaps.min())
    pk = _plane_index(V[:, 2], zs, tol)
    on = pk >= 0
    fk = pk[F]
    cand = (fk >= 0).all(axis=1) & (fk.max(axis=1) - fk.min(axis=1) == 1)
    if flat_pairs:
        cand &= ~np.isin(fk.min(axis=1), np.fromiter(flat_pairs, dtype=np.int64))
    if band_faces is not None:
        known = band_faces if isinstance(band_faces, _BandFaces) else _BandFaces(band_faces)
        idx = np.flatnonzero(cand)
        cand[idx] = np.isin(_face_keys(V[F[idx]]), known.keys)
    # the edges, each with its two faces
    e = np.stack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1).reshape(-1, 2)
    key = np.sort(e, axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    face_of = np.repeat(np.arange(len(F)), 3)
    rung = pk[uniq[:, 0]] != pk[uniq[:, 1]]
    rung &= on[uniq[:, 0]] & on[uniq[:, 1]]
    # a rung is bent only where every face on it is a band face (else the bent rung would leave a gap)
    while True:
        good_face = cand[face_of]
        bad_edge = np.zeros(len(uniq), dtype=bool)
        np.logical_or.at(bad_edge, inv, ~good_face)
        uses = np.bincount(inv, minlength=len(uniq))
        bad_edge |= uses != 2
        drop = np.zeros(len(F), dtype=bool)
        np.logical_or.at(drop, face_of, rung[inv] & bad_edge[inv])
        drop &= cand
        if not drop.any():
            break
        cand &= ~drop
    if not cand.any():
        return V, F, none
    bent_edge = np.zeros(len(uniq), dtype=bool)
    bent_edge[inv[cand[face_of]]] = True
    bent_edge &= rung
    slope, both = _slopes(V, uniq[bent_edge], on, tol)
    if end_slopes:
        ends = np.flatnonzero(on & ~both)
        for i in ends:
            got = end_slopes.get((V[i, 0], V[i, 1], V[i, 2]))
            if got is not None:
                slope[i] = got
                both[i] = True
    # the ring's direction at each vertex (from the band faces' in-plane edges): only the slope across
    # the ring is the surface's; along the ring, a rung just runs straight (no sideways bulge)
    ring_e = np.zeros(len(uniq), dtype=bool)
    ring_e[inv[cand[face_of]]] = True
    ring_e &= ~rung & on[uniq[:, 0]] & on[uniq[:, 1]]
    tdir = _ring_directions(V, uniq[ring_e])
    # the rungs, oriented from the lower plane to the upper
    r = np.flatnonzero(bent_edge)
    lo_v, hi_v = uniq[r, 0].copy(), uniq[r, 1].copy()
    swap = pk[lo_v] > pk[hi_v]
    lo_v[swap], hi_v[swap] = uniq[r[swap], 1], uniq[r[swap], 0]
    pair = pk[lo_v]
    h = V[hi_v, 2] - V[lo_v, 2]
    p, q = V[lo_v, :2], V[hi_v, :2]
    chord = (q - p) / h[:, None]
    # where a vertex's rungs run one way across the ring, its slope across the ring is at most twice
    # theirs (so a^2 + b^2 <= 8 < 9 on each rung, Fritsch and Carlson's condition for a cubic without
    # overshoot): near a pole the section's slope grows without bound, and a cubic with that slope would
    # bulge past the next ring.  One factor per vertex, so that the rungs of a fan stay apart.
    normal = np.c_[-tdir[:, 1], tdir[:, 0]]
    sx = (slope * normal).sum(axis=1)  # each vertex's slope across its ring
    tau = np.ones(len(V))
    for v in (lo_v, hi_v):
        cx = (chord * normal[v]).sum(axis=1)
        sv = sx[v]
        lim = (sv * cx > 0) & (np.abs(sv) > _MAX_SLOPE * np.abs(cx))
        np.minimum.at(tau, v[lim], _MAX_SLOPE * np.abs(cx[lim]) / np.abs(sv[lim]))
    slope = slope - ((1.0 - tau) * sx)[:, None] * normal
    tp, tq = tdir[lo_v], tdir[hi_v]
    mp = _across(slope[lo_v], tp) + _along(chord, tp)
    mq = _across(slope[hi_v], tq) + _along(chord, tq)
    kp, kq = both[lo_v], both[hi_v]
    # natural ends: zero second derivative where a vertex has no neighbour on its far side
    only_q = ~kp & kq
    mp[only_q] = 1.5 * chord[only_q] - 0.5 * mq[only_q]
    only_p = kp & ~kq
    mq[only_p] = 1.5 * chord[only_p] - 0.5 * mp[only_p]
    neither = ~kp & ~kq
    mp[neither] = chord[neither]
    mq[neither] = chord[neither]
    # segments per plane pair: the bulge of a rung (at mid height, h/8 |mp - mq|) over eps, as a parabola's
    bulge = h / 8 * np.hypot(*(mp - mq).T)
    if eps is None:
        flat_e = uniq[~rung & on[uniq[:, 0]] & on[uniq[:, 1]]]
        lens = np.hypot(*(V[flat_e[:, 0], :2] - V[flat_e[:, 1], :2]).T) if len(flat_e) else np.ones(1)
        eps = 0.02 * float(np.median(lens)) if np.median(lens) > 0 else float(gaps.min()) * 1e-2
    worst = np.zeros(npairs)
    np.maximum.at(worst, pair, bulge)
    rung_of_edge = np.full(len(uniq), -1, dtype=np.int64)
    rung_of_edge[r] = np.arange(len(r))
    bands = None
    if follow_area:
        # the bands (connected band faces), their section areas and the parabola of each one's area
        fi = np.flatnonzero(cand)
        fx, fy, fw, frx, fry, flow = _face_rungs(F, pk, inv, rung_of_edge, fi)
        fpair = fk[fi].min(axis=1)
        fcomp, rcomp = _band_components(len(fi), len(r), frx, fry)
        ok, a_lo, a_hi, below, above = _level_links(V, fcomp, fx, fy, flow, fpair)
        pc = np.zeros(len(ok), dtype=np.int64)
        pc[fcomp] = fpair
        if plain_pairs:
            ok &= ~np.isin(pc, np.fromiter(plain_pairs, dtype=np.int64))
        c = _area_curvature(zs, pc, ok, a_lo, a_hi, below, above)
        bands = {"fcomp": fcomp, "rcomp": rcomp, "frx": frx, "fry": fry, "sigma": np.where(flow, 1.0, -1.0),
                 "pair": pc, "a_lo": a_lo, "a_hi": a_hi, "c": c}
        # the area's bulge at mid height, as a normal offset (area over the ring's length), also sets
        # the segments per rung
        lo_f = flow
        perim = np.bincount(fcomp[lo_f], weights=np.hypot(*(V[fy[lo_f], :2] - V[fx[lo_f], :2]).T),
                            minlength=len(ok))
        use = np.isfinite(c) & (perim > 0)
        hh = gaps[pc[use]]
        np.maximum.at(worst, pc[use], np.abs(c[use]) * hh * hh / 4 / perim[use])
    levels = np.clip(np.ceil(np.sqrt(worst / eps)), 1, max_levels).astype(np.int64)
    L = levels[pair]
    # intermediate points: rung i has L_i - 1 of them, stored from offset start_i
    count = L - 1
    start = len(V) + np.r_[0, np.cumsum(count)[:-1]]
    newV = np.empty((int(count.sum()), 3))
    for lv in np.unique(L):
        if lv < 2:
            continue
        sel = np.flatnonzero(L == lv)
        s = np.arange(1, lv) / lv
        pts = _hermite(p[sel], q[sel], mp[sel], mq[sel], h[sel], s)
        zz = V[lo_v[sel], 2][:, None] + h[sel][:, None] * s[None, :]
        o = (start[sel] - len(V))[:, None] + np.arange(lv - 1)[None, :]
        newV[o.ravel()] = np.c_[pts.reshape(-1, 2), zz.ravel()]
    area_bands, area_pairs = 0, frozenset()
    if bands is not None:
        targets = _area_targets(V, zs, bands, levels)
        area_bands = _follow_area_profile(newV, len(V), start, bands, targets, levels)
        area_pairs = frozenset(int(bands["pair"][i]) for i in targets)
    out, pairs_out = [F[~cand]], [np.full(int((~cand).sum()), -1)]
    fi = np.flatnonzero(cand)
    lvf = levels[fk[fi].min(axis=1)]
    for lv in np.unique(lvf):
        sel = fi[lvf == lv]
        if lv < 2:
            out.append(F[sel])
            pairs_out.append(fk[sel].min(axis=1))
            continue
        kf = pk[F[sel]]
        # each face as (x, y, w): x, y on one plane, w on the other; rungs w-x and y-w
        x, y, w, rx, ry, _ = _face_rungs(F, pk, inv, rung_of_edge, sel)
        t = np.arange(1, lv)[None, :]

        def points(u, ri):
            fwd = lo_v[ri] == u
            mid = np.where(fwd[:, None], start[ri][:, None] + t - 1, start[ri][:, None] + lv - 1 - t)
            return np.c_[u, mid, w]

        X, Y = points(x, rx), points(y, ry)
        tri = [np.stack([X[:, j], Y[:, j], Y[:, j + 1]], axis=1) for j in range(lv - 1)]
        tri += [np.stack([X[:, j], Y[:, j + 1], X[:, j + 1]], axis=1) for j in range(lv - 1)]
        tri.append(np.stack([X[:, lv - 1], Y[:, lv - 1], w], axis=1))
        out += tri
        pairs_out += [kf.min(axis=1)] * len(tri)
    V2 = np.concatenate([V, newV])
    F2 = np.concatenate(out)
    levels_used = levels.copy()
    return V2, F2, {"levels": levels_used, "bent_faces": int(cand.sum()), "face_pair": np.concatenate(pairs_out),
                    "area_bands": area_bands, "area_pairs": area_pairs}


#: Attempts of :func:`curved_without_crossings`: after one whose faces cross, the plane pairs of the
#: crossing faces keep their cubic rungs without the area profile, or, if they had none, are left ruled.
_ATTEMPTS = 4


def curved_without_crossings(V, F, zs, *, end_slopes=None, band_faces=None):
    """:func:`curve_bands`, then the exact crossing test: in the plane pairs holding crossing faces,
    bands that followed their area profile keep only their cubic rungs, and the others are left
    ruled; then the bands are bent again (at most 4 times; then every pair is left ruled if faces
    still cross).  Returns ``(V, F, info)``, ``info`` as :func:`curve_bands`'s plus ``ruled_pairs``
    (pairs left ruled because their bent faces crossed) and ``plain_pairs`` (pairs whose area
    profile was dropped because their faces crossed)."""
    from ..intersect import intersecting_faces

    flat: set = set()
    plain: set = set()
    zs = np.unique(np.asarray(zs, dtype=np.float64))
    if band_faces is not None:
        band_faces = _BandFaces(band_faces)
    for attempt in range(_ATTEMPTS + 1):
        last = attempt == _ATTEMPTS
        if last:
            flat = set(range(len(zs)))
        V2, F2, info = curve_bands(V, F, zs, end_slopes=end_slopes, flat_pairs=frozenset(flat),
                                   band_faces=band_faces, plain_pairs=frozenset(plain))
        if last or not info["bent_faces"]:
            break
        bad = intersecting_faces(V2, F2)
        if not len(bad):
            break
        pairs = set(np.unique(info["face_pair"][bad]).tolist()) - {-1}
        if not pairs - flat:  # the crossings are not the bent bands' (the ruled mesh has them too)
            break
        scaled = (pairs - flat) & set(info["area_pairs"])
        plain |= scaled
        flat |= pairs - scaled
    info["ruled_pairs"] = len(flat & set(range(len(zs) - 1)))
    info["plain_pairs"] = len(plain & set(range(len(zs) - 1)) - flat)
    return V2, F2, info
