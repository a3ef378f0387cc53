"""Smooth ends on the area profile of the last sections (the contours route's ``caps="smooth"``,
and the band refinement's): shared by :mod:`contourmesh.drawn`, :mod:`contourmesh.surface` and
:mod:`contourmesh.volumes`.

* :func:`_dome_centre`: a centre to shrink an end polygon toward;
* :func:`_end_profile`: where the section's area goes beyond an end, from the last sections' areas;
* :func:`_chords`, :func:`_planar_end`: an end section cut by a plane (straight traces of it in the
  last sections) and the surface beyond it;
* :class:`_SmoothEnds`: the volume mesher's ``end_cap`` hook that closes ends on that profile (or on
  their plane), and its band hook for the joins next to a plane-cut end.
"""

from __future__ import annotations

import numpy as np

from ..geometry import shoelace_area, slice_gap
from .caps import _rings_that_meet, cap_faces


def _dome_centre(poly: np.ndarray) -> tuple[np.ndarray, bool]:
    """A centre to shrink ``poly`` toward, and whether ``poly`` is star-shaped about it.

    The area centroid when it sees the whole polygon (it lies in the polygon's kernel, the part
    on the inner side of every edge line); otherwise the point deepest inside the kernel (a
    linear program); if the kernel is empty, the centroid (the polygon is not star-shaped).
    """
    p = np.asarray(poly, dtype=np.float64)
    if shoelace_area(p) < 0:
        p = p[::-1]
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    w = x * yn - xn * y
    a = w.sum() / 2
    centroid = np.array([((x + xn) * w).sum(), ((y + yn) * w).sum()]) / (6 * a)
    d = np.c_[xn - x, yn - y]
    length = np.hypot(d[:, 0], d[:, 1])
    ok = length > 0
    d, length, q = d[ok], length[ok], p[ok]

    def depth(c):  # signed distance of c from the edge lines, inner side positive; the least one
        return float(np.min((d[:, 0] * (c[1] - q[:, 1]) - d[:, 1] * (c[0] - q[:, 0])) / length))

    scale = float(np.sqrt(abs(a)))
    if depth(centroid) > 1e-9 * scale:
        return centroid, True
    from scipy.optimize import linprog

    # maximize r subject to: c lies at least r inside every edge line
    A = np.c_[d[:, 1], -d[:, 0], length]
    rhs = d[:, 1] * q[:, 0] - d[:, 0] * q[:, 1]
    lo, hi = p.min(axis=0), p.max(axis=0)
    res = linprog([0, 0, -1], A_ub=A, b_ub=rhs, bounds=[(lo[0], hi[0]), (lo[1], hi[1]), (None, scale)],
                  method="highs")
    if res.status == 0 and -res.fun > 1e-9 * scale:
        c = np.asarray(res.x[:2])
        if depth(c) > 0:
            return c, True
    return centroid, False


#: Shrunk copies of the end ring in a smooth end: a dome (the section closes within a spacing) or a
#: taper to a flat end half a spacing out.
_DOME_RINGS = 8
_TAPER_RINGS = 2


def _end_profile(areas, dists, gap, rings: int = _DOME_RINGS):
    """Where the section's area goes beyond an end ring, from the last sections' areas.

    ``areas``: the end ring's area and those of the one or two sections joined to it, at outward
    positions ``0, -dists[0], -(dists[0] + dists[1])``.  The area is extrapolated outward (a
    quadratic through three sections, exact for a sphere, a cone or a cylinder; a line through
    two).  If it closes (falls to zero, or to a minimum below 5 % of the end's area; a profile that
    grows first counts from the end's own area) within one spacing ``gap``, the surface closes there: ``(t, lam)`` of a dome whose rings are the end ring
    scaled by ``lam`` at distances ``t`` beyond it (``lam`` evenly spread on a quarter circle,
    ``rings`` of them).
    Otherwise the object ends somewhere within the next spacing, half of it on average: a taper
    to a flat end at ``gap / 2``, its copies following the trend, growth included (a widening end,
    as at a cone's base, flares up to ``_MAX_FLARE`` times the end's linear size).  Returns
    ``(t, lam, kind)``.
    """
    areas = np.asarray(areas, dtype=np.float64)
    tp = -np.r_[0.0, np.cumsum(dists)]
    coef = np.polyfit(tp, areas, min(len(areas) - 1, 2))
    t = np.linspace(0.0, gap, 513)
    a = np.minimum.accumulate(np.minimum(np.polyval(coef, t), areas[0]))
    neg = a <= 0.0
    if neg.any() or a.min() <= 0.05 * areas[0]:
        if neg.any():  # a root: where the line between the samples crosses zero
            i = int(np.argmax(neg))
            t0 = t[i] if i == 0 else t[i - 1] + (t[i] - t[i - 1]) * a[i - 1] / (a[i - 1] - a[i])
        else:  # touches (nearly) zero: a double root, as at a cone's tip
            i = int(np.argmin(a))
            t0 = t[i]
        lam_of_t = np.sqrt(np.r_[np.clip(a[:i], 0.0, None), 0.0] / areas[0])
        theta = np.arange(1, rings + 1) * np.pi / (2 * (rings + 1))
        lam = np.cos(theta)
        tt = np.interp(lam, lam_of_t[::-1], np.r_[t[:i], t0][::-1])
        return tt, lam, "dome"
    tt = gap / 2 * np.arange(1, _TAPER_RINGS + 1) / _TAPER_RINGS
    # the trend, growth included (a cone's base, a widening end: the section goes on growing up to
    # the flat end), within _MAX_FLARE of the end section's linear size
    grow = np.polyval(coef, tt)
    at = np.where(grow > areas[0], np.minimum(grow, _MAX_FLARE**2 * areas[0]), np.interp(tt, t, a))
    lam = np.sqrt(at / areas[0])
    return tt, lam, "taper"


#: A taper's last copy is at most this many times the end section's linear size (a widening end).
_MAX_FLARE = 1.25

#: An end section whose roundness (4 pi area / perimeter^2) is below this fraction of the previous
#: section's is a slanted cut (a tilted tube's end): caps="smooth" moves it half a spacing along the axis.
_CUT = 0.85


def _centroid(xy) -> np.ndarray:
    """The area centroid of a simple polygon (the vertex mean where it has no area)."""
    x, y = xy[:, 0], xy[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    w = x * yn - xn * y
    a = w.sum() / 2
    if a == 0.0:
        return xy.mean(axis=0)
    return np.array([((x + xn) * w).sum(), ((y + yn) * w).sum()]) / (6 * a)


def _roundness(xy) -> float:
    """``4 pi area / perimeter^2``: 1 for a circle, small for a sliver."""
    per = float(np.hypot(*(np.roll(xy, -1, axis=0) - xy).T).sum())
    return 4 * np.pi * abs(shoelace_area(xy)) / per**2 if per > 0 else 0.0


def _end_rate(areas, dists) -> float:
    """``d(lam)/dt`` at an end ring: the rate at which the section's linear scale shrinks outward, from the
    area profile of :func:`_end_profile` (0 where the area would grow)."""
    areas = np.asarray(areas, dtype=np.float64)
    tp = -np.r_[0.0, np.cumsum(dists)]
    coef = np.polyfit(tp, areas, min(len(areas) - 1, 2))
    da = float(np.polyval(np.polyder(coef), 0.0))
    return min(da, 0.0) / (2.0 * areas[0])


#: A ring's point lies on the straight line of its neighbours when it is off their chord by at most
#: this fraction of the chord's length.
_STRAIGHT = 1e-4
#: A straight run (or several on one line) is an end plane's trace when it holds at least this
#: fraction of the ring's half perimeter.
_CHORD_MIN = 0.25
#: The traces of one plane in consecutive sections are parallel within this angle (radians).
_PARALLEL = 0.02
#: A plane-cut end may reach this many spacings beyond its last section: the next plane is empty,
#: but a sliver of the end thinner than the drawing's resolution may be missing from it.
_REACH = 1.15
#: A planar end needs the lateral surface's motion fitted on at least this many support directions.
_SUPPORT_MIN = 6


def _chords(xy) -> list:
    """The straight traces that bound a ring on one side, longest first: ``[(n, c, tol, length)]``.

    Runs of points on one straight line (each point within :data:`_STRAIGHT` of its neighbours'
    chord) are grouped by line; a group holding :data:`_CHORD_MIN` of the half perimeter or more,
    with every other point of the ring on one side of its line, is a trace: ``n`` the line's unit
    normal pointing away from the ring, ``c = n . p`` on the line, ``tol`` the points' distance
    from it that still counts as on it.
    """
    p = np.asarray(xy, dtype=np.float64)
    m = len(p)
    if m < 4:
        return []
    a, b = np.roll(p, 1, axis=0), np.roll(p, -1, axis=0)
    d, e = b - a, p - a
    L2 = (d * d).sum(1)
    ok = L2 > 0
    t = np.where(ok, (e * d).sum(1) / np.where(ok, L2, 1.0), -1.0)
    straight = ok & (t > 0) & (t < 1) & (np.abs(e[:, 0] * d[:, 1] - e[:, 1] * d[:, 0]) <= _STRAIGHT * L2)
    if straight.all():
        return []
    seg = np.hypot(*(b - p).T)
    scale = float(np.ptp(p, axis=0).max())
    half = 0.5 * float(seg.sum())
    # the runs: from each point that is not straight to the next one (cyclic), with their lengths
    brk = np.flatnonzero(~straight)
    cum = np.r_[0.0, np.cumsum(seg)]
    nxt = np.r_[brk[1:], brk[0] + m]
    lengths = np.r_[cum[nxt[:-1]] - cum[brk[:-1]], cum[m] - cum[brk[-1]] + cum[brk[0]]]
    # runs too short to matter (a trace may be split into a few runs by a hole or a corner point,
    # but each of them is a sizeable part of it) are left out before the runs are grouped by line
    big = np.flatnonzero(lengths >= 0.2 * _CHORD_MIN * half)
    groups: list = []  # [normal, offset, point indices, length]
    for r in big.tolist():
        idx = np.arange(brk[r], nxt[r] + 1) % m
        u = p[idx[-1]] - p[idx[0]]
        length = float(lengths[r])
        if length <= 1e-12 * scale:
            continue
        nrm = np.array([u[1], -u[0]]) / np.hypot(*u)
        for g in groups:
            if abs(abs(g[0] @ nrm) - 1) < 1e-6 and np.abs(p[idx] @ g[0] - g[1]).max() <= 1e-6 * scale:
                g[2].extend(idx.tolist())
                g[3] += length
                break
        else:
            groups.append([nrm, float(nrm @ p[idx[0]]), idx.tolist(), length])
    out = []
    for _, _, idx, length in groups:
        if length < _CHORD_MIN * half:
            continue
        idx = np.unique(idx)
        ctr = p[idx].mean(0)
        nrm = np.linalg.svd(p[idx] - ctr)[2][1]
        off = (p - ctr) @ nrm
        tol = max(2 * float(np.abs(off[idx]).max()), 1e-9 * scale)
        if (off > tol).any() and (off < -tol).any():
            continue  # points on both sides: the line does not bound the ring
        if (off > tol).any():
            nrm = -nrm
        out.append((nrm, float(nrm @ ctr), tol, length))
    out.sort(key=lambda g: -g[3])
    return out


def _support_fit(end, inner, end_free, inner_free, dirs: int = 360):
    """The similarity ``S_end = rho S_inner + shift`` of two sections' lateral surface, fitted on their
    support functions in the directions where both rings' extreme points are free (not on a
    trace): ``(shift, rho)``, or None where too few directions are left or the fit is poor."""
    ang = np.arange(dirs) * (2 * np.pi / dirs)
    u = np.c_[np.cos(ang), np.sin(ang)]
    he, hi = end @ u.T, inner @ u.T
    ie, ii = he.argmax(0), hi.argmax(0)
    # an extreme point and both its neighbours free: a point of the lateral surface's own extreme
    # (next to a trace, the extreme is the corner's, not the lateral surface's)
    end_free = end_free & np.roll(end_free, 1) & np.roll(end_free, -1)
    inner_free = inner_free & np.roll(inner_free, 1) & np.roll(inner_free, -1)
    use = end_free[ie] & inner_free[ii]
    if use.sum() < _SUPPORT_MIN:
        return None
    u, he, hi = u[use], he[ie[use], np.flatnonzero(use)], hi[ii[use], np.flatnonzero(use)]
    # the fit's tolerance: a fraction of the section's size, or of its point spacing (a polygon's
    # support function is off its curve's by up to a sagitta, ds^2 / 8R)
    edge = float(np.median(np.hypot(*(np.roll(inner, -1, axis=0) - inner).T)))
    tol = max(2e-3 * float(np.ptp(inner, axis=0).max()), 0.05 * edge)

    def fit(A, b):
        # least squares, then again without the directions far off it (a drawn point that cuts a
        # corner: planning tools and tracers round the corner where a trace meets the lateral surface)
        keep = np.ones(len(b), dtype=bool)
        for _ in range(3):
            if keep.sum() < _SUPPORT_MIN:
                return None, np.inf
            x = np.linalg.lstsq(A[keep], b[keep], rcond=None)[0]
            res = np.abs(A @ x - b)
            new = res <= max(tol, 3.0 * float(np.median(res[keep])))
            if (new == keep).all():
                break
            keep = new
        return x, float(res[keep].max())

    # a translation (a cylinder) where it fits; else a scaling too (a cone)
    x, worst = fit(u, he - hi)
    if x is not None and worst <= tol:
        return x, 1.0
    x, worst = fit(np.c_[u, hi], he)
    if x is None or worst > tol or not 0.5 < x[2] < 2.0:
        return None
    return x[:2], float(x[2])


def _trace_offset(ring, nrm, traces=None):
    """The offset ``nrm . p`` of a trace of ``ring`` parallel to ``nrm`` (the longest), its tolerance, and
    the ring's points free of it (:func:`_support_fit`); ``(None, None, all points)`` where it has none."""
    ring = np.asarray(ring, dtype=np.float64)
    par = [g for g in (_chords(ring) if traces is None else traces) if g[0] @ nrm > np.cos(_PARALLEL)]
    if not par:
        return None, None, np.ones(len(ring), dtype=bool)
    g = max(par, key=lambda g: g[3])
    d = g[1] - ring @ g[0]
    return float(np.mean(ring[d <= g[2]] @ nrm)), g[2], d > max(g[2], 0.05 * float(d.max()))


def _lateral(near, far, nrm, c, tol, dist):
    """The lateral surface's motion from section ``far`` to section ``near`` (outer rings ``dist`` apart;
    ``near`` bounded by the trace ``(nrm, c, tol)``): ``(shift, rho)`` of :func:`_support_fit`, or None."""
    delta = c - near @ nrm
    # the lateral surface's own extremes: points off the trace by a twentieth of the section's
    # depth or more (next to a trace the extreme is the corner's, not the lateral surface's)
    free = delta > max(tol, 0.05 * float(delta.max()))
    return _support_fit(near, far, free, _trace_offset(far, nrm)[2])


def _square_gamma(nrm, far, shift, rho, dist):
    """A plane square to the lateral surface's axis (the drift of the centre of section ``far``): the
    rate at which its trace moves along ``nrm`` per unit distance outward, or None where the trace is
    not square to the drift (or the surface hardly drifts: an upright tube's end is not cut)."""
    drift = ((rho - 1.0) * _centroid(np.asarray(far, dtype=np.float64)) + shift) / dist
    speed = float(np.hypot(*drift))
    if speed < np.tan(np.radians(5.0)) or drift @ nrm < np.cos(5 * _PARALLEL) * speed:
        return None
    return -1.0 / speed


def _sweep(q, nrm, c, tol, gamma, shift, rho, dist):
    """Points ``q`` (at the height where the trace is ``nrm . p = c``) moved outward along the lateral
    surface until they meet the plane: ``(tops, t, v)``, ``t`` the distance beyond (0 on the trace,
    inf where the point never meets it), ``v`` the motion per unit distance."""
    v = ((rho - 1.0) * q + shift) / dist
    delta = c - q @ nrm
    on = delta <= tol
    rate = v @ nrm - gamma
    hit = ~on & (rate > 0)
    t = np.full(len(q), np.inf)
    t[on] = 0.0
    t[hit] = delta[hit] / rate[hit]
    tops = q + v * np.where(np.isfinite(t), t, 0.0)[:, None]
    return tops, t, v


def _planar_end(xys, inner, dist, gap, plane=None):
    """Where an end section is cut by a plane (a tube's slanted flat end), the surface beyond it.

    ``xys``: the end's rings (outer first, then holes); ``inner``: the outer ring of the section
    joined to it, ``dist`` inward.  The end plane shows as a straight trace bounding the end section
    (:func:`_chords`); ``plane = (nrm, c, tol, gamma)``, where known from the traces of several
    sections (:meth:`_SmoothEnds._plane`), gives it; else, where the inner section has a parallel
    trace, the two give the plane (its trace moves by their offset per ``dist``); where it has
    none, the plane is taken square to the lateral surface's axis, if the trace is square to the
    axis's drift.  The lateral surface goes on as the similarity that maps the inner section's free
    boundary onto the end's (:func:`_support_fit`: a translation for a tilted cylinder, a scaling
    too for a cone).  Every point of the end rings moves along it, outward, until it meets the
    plane: ``(tops, ts, vs)`` per ring, the points' places, distances beyond the end and motions
    per unit distance (trace points stay: ``t = 0``); None where the end is not such a cut, or the
    plane would not be reached within ``gap`` (the next plane is empty: the object ends before it;
    :data:`_REACH` of it, for a sliver too thin to be drawn).
    """
    outer = xys[0]
    inner = np.asarray(inner, dtype=np.float64)
    cands = [plane] if plane is not None else [(n, c, tol, None) for n, c, tol, _ in _chords(outer)]
    for nrm, c, tol, gamma in cands:
        fit = _lateral(outer, inner, nrm, c, tol, dist)
        if fit is None:
            continue
        shift, rho = fit
        if gamma is None:
            ci = _trace_offset(inner, nrm)[0]
            gamma = (c - ci) / dist if ci is not None else _square_gamma(nrm, inner, shift, rho, dist)
            if gamma is None:
                continue
        swept = [_sweep(q, nrm, c, tol, gamma, shift, rho, dist) for q in xys]
        ts = [t for _, t, _ in swept]
        if max(float(t.max()) for t in ts) > _REACH * gap or (ts[0] > 0).all():
            continue
        return [w[0] for w in swept], ts, [w[2] for w in swept]
    return None


def _runs(mask) -> list:
    """The cyclic runs of True in ``mask``, each as its indices in ring order."""
    mask = np.asarray(mask, dtype=bool)
    if mask.all():
        return [np.arange(len(mask))]
    starts = np.flatnonzero(mask & ~np.roll(mask, 1))
    out = []
    for s0 in starts:
        n = int(np.argmin(np.roll(mask, -s0)))  # the run's length: up to the first False
        out.append((s0 + np.arange(n)) % len(mask))
    return out


def _cut_plan(Ps, sweeps, Q, q_on, dist, up):
    """How the rings ``Ps`` of section P join ring ``Q`` next to a plane-cut end (:meth:`_SmoothEnds.make_band`).

    P's points on the plane before Q's height (moved there, or on P's own trace) make runs ``s`` of
    its rings; Q's points on its trace make runs ``c``.  Each run ``s`` ends where the lateral
    surface goes on up to Q's arc, next to the end of the run ``c`` nearest to it, and the next
    run of its ring starts next to the start of the next run of Q: there a lateral band joins
    them.  The planar polygons go round the runs: each ``s`` forward, then its ``c`` backward, then
    the run ``s`` that starts next to that ``c``'s start.  Returns ``{"on", "flat", "lateral"}`` (per
    ring, its points on the plane; ``[(parts, faces)]`` of the planar polygons, parts ``(ring,
    indices)`` with ring -1 for Q; ``[(ring, P indices, Q indices)]`` of the lateral bands), or
    None where the runs do not pair up so, or a planar polygon is not simple."""
    on = [t < dist * (1 - 1e-6) for _, t, _ in sweeps]
    if any(o.all() for o in on) or q_on.all() or not q_on.any():
        return None
    runs = [(r, x) for r in range(len(Ps)) for x in _runs(on[r])]
    cruns = _runs(q_on)
    if len(runs) != len(cruns) or any(not o.any() for o in on):
        return None
    tops = [w[0] for w in sweeps]

    def nearest(pt, cands):
        d = [float(np.sum((pt - x) ** 2)) for x in cands]
        return int(np.argmin(d))

    end_of = [nearest(tops[r][x[-1]], [Q[c[-1]] for c in cruns]) for r, x in runs]
    start_of = [nearest(Q[c[0]], [tops[r][x[0]] for r, x in runs]) for c in cruns]
    if sorted(end_of) != list(range(len(runs))) or sorted(start_of) != list(range(len(runs))):
        return None
    m = len(Q)
    lateral = []
    for i, (r, x) in enumerate(runs):
        # the next run of ring r (P's rings' runs are listed in ring order) and the next run of Q
        mine = [j for j, (rr, _) in enumerate(runs) if rr == r]
        nxt = mine[(mine.index(i) + 1) % len(mine)]
        ci = end_of[i]
        cn = (ci + 1) % len(cruns)
        if start_of[cn] != nxt:
            return None
        n = len(Ps[r])
        lo = (x[-1] + np.arange((runs[nxt][1][0] - x[-1]) % n + 1)) % n
        c_end = cruns[ci][-1]
        hi = (c_end + np.arange((cruns[cn][0] - c_end) % m + 1)) % m
        lateral.append((r, lo, hi))
    flat, seen = [], set()
    for i0 in range(len(runs)):
        if i0 in seen:
            continue
        parts, i = [], i0
        while i not in seen:
            seen.add(i)
            r, x = runs[i]
            c = cruns[end_of[i]]
            parts += [(r, x), (-1, c[::-1])]
            i = start_of[end_of[i]]
        if i != i0:
            return None
        xy = np.concatenate([tops[r][x] if r >= 0 else Q[x] for r, x in parts])
        if len(np.unique(xy, axis=0)) != len(xy) or _rings_that_meet([xy]).any():
            return None
        try:
            f = cap_faces(xy, upward=up)
        except ValueError:
            return None
        if len(f) != len(xy) - 2:
            return None
        flat.append((parts, f))
    return {"on": on, "flat": flat, "lateral": lateral}


class _SmoothEnds:
    """``caps="smooth"`` on the contours route (the volume mesher's ``end_cap`` hook).

    An end ring joined by a band to the ring below it (or above, at a lower end) is closed by
    shrunk copies of itself beyond it (:func:`_end_profile`), each moved along the line through
    the last two rings' centroids and joined to the next point to point, the last one closed flat.
    Holes shrink with their outer ring (about the same centre): each section of this cap is a
    scaled copy of the end section, so it does not cross itself.  An end without a band join (a
    fork, a merge, an exact join: no trend of its own) gets a dome of shrunk copies on a quarter
    ellipse holding the half prism's volume (``"branch"``); one that cannot be capped is left to the
    mesher (``caps="half"``: a prism half a spacing out).

    With ``planar=True`` (the contours route), an end section bounded by a straight trace of a
    plane (a tube's slanted flat end) is closed by the lateral surface continued up to that plane
    and the plane itself (:func:`_planar_end`, ``"plane"``), and the joins next to it are made the
    same way (:meth:`make_band`, the volume mesher's band hook), where the traces say where the
    plane lies.
    """

    def __init__(self, interior_only: bool = False, dome_rings: int = _DOME_RINGS, branch_domes: bool = True,
                 planar: bool = False):
        self.planar = planar  # ends cut by a plane, and their bands (drawn rings: the contours route)
        self.interior_only = interior_only  # caps="flat": only ends inside the stack (see _InteriorEnds)
        self.branch_domes = branch_domes  # False: an end without a band join of its own is left to the mesher
        self.dome_rings = dome_rings  # the rings of a dome that closes on the area profile
        self.kinds: dict = {}  # (k, c, upward) -> "dome", "taper", "plane", "cut", "branch" or "half" (last mesh)
        self.slopes: dict = {}  # (x, y, z) of an end ring's vertex -> d(x, y)/dz of its cap at the ring
        self.planar_joins: set = set()  # (k, a, b) of the joins next to a plane-cut end (make_band)
        self._plane_cache: dict = {}

    def count(self, kind) -> int:
        return sum(v == kind for v in self.kinds.values())

    def attach(self, slices, zs, joins):
        self.slices, self.zs = slices, zs
        self._plane_cache = {}
        self.below, self.above = {}, {}
        for k, kind, data in joins:
            if kind == "band":
                a, b = data[0], data[1]
                self.above[(k, a)] = (k + 1, b)
                self.below[(k + 1, b)] = (k, a)

    def _area_centre(self, k, c):
        s = self.slices[k]
        xy = np.asarray(s.outer[c], dtype=np.float64)
        area = abs(shoelace_area(xy)) - sum(abs(shoelace_area(np.asarray(h, np.float64))) for h in s.holes[c])
        return area, _centroid(xy), _roundness(xy)

    def __call__(self, M, k, c, rings, up) -> bool:
        inward = self.below if up else self.above
        interior = k < len(self.zs) - 1 if up else k > 0
        if self.interior_only and not interior:
            return False
        self.kinds[(k, c, up)] = "half"
        xyzs = [M.coords(r) for r in rings]
        xys, z = [q[:, :2] for q in xyzs], float(xyzs[0][0, 2])
        a0 = abs(shoelace_area(xys[0])) - sum(abs(shoelace_area(q)) for q in xys[1:])
        allxy = np.concatenate(xys)
        if a0 <= 0.0 or len(np.unique(allxy, axis=0)) != len(allxy):
            return False
        gap = float(slice_gap(self.zs, k, up))
        centre, _ = _dome_centre(xys[0])  # outer ring and holes shrink together: similar sections
        if ((k, c) not in inward or self.interior_only) and not self.branch_domes:
            return False
        if (k, c) not in inward or self.interior_only:
            # an end whose inward join is a fork, a merge or an exact join: no trend of its own to
            # extrapolate; a dome of shrunk copies on a quarter ellipse holding the half prism's
            # volume (0.75 gap high: 2/3 x area x height = area x gap / 2), without its wall
            theta = np.arange(1, _DOME_RINGS + 1) * np.pi / (2 * (_DOME_RINGS + 1))
            return self._build(M, k, c, rings, xys, z, up, 0.75 * gap * np.sin(theta), np.cos(theta),
                               np.zeros(2), centre, 0.0, "branch")
        areas, dists, centres, round_ = [a0], [], [_centroid(xys[0])], [_roundness(xys[0])]
        cur = (k, c)
        for _ in range(2):
            nxt = inward.get(cur)
            if nxt is None:
                break
            a, ctr, q = self._area_centre(*nxt)
            if a <= 0:
                break
            areas.append(a)
            dists.append(abs(float(self.zs[nxt[0]] - self.zs[cur[0]])))
            centres.append(ctr)
            round_.append(q)
            cur = nxt
        if len(areas) < 2:
            return False
        drift = (centres[0] - centres[1]) / dists[0]  # the centroids' line, per unit distance outward
        far = self.slices[inward[(k, c)][0]].outer[inward[(k, c)][1]]
        for plane in self._planes((k, c), up) if self._drawn((k, c), inward[(k, c)]) else ():
            cut = _planar_end(xys, far, dists[0], gap, plane)
            if cut is not None and self._build_plane(M, k, c, rings, xys, z, up, *cut):
                return True
        if round_[0] < _CUT * round_[1]:
            # the end section is much less round than the one before: a flat end cut at a slant (a
            # tilted tube), not a closing dome; its copy moves along the axis half a spacing out
            t, lam, kind, rate = np.array([gap / 2]), np.array([1.0]), "cut", 0.0
        else:
            t, lam, kind = _end_profile(areas, dists, gap, self.dome_rings)
            rate = _end_rate(areas, dists)  # d(lam)/dt at the end ring
        return self._build(M, k, c, rings, xys, z, up, t, lam, drift, centre, rate, kind)

    def _drawn(self, *comps) -> bool:
        """Whether planar ends apply to these components: on the contours route, each keeping its drawn
        rings (a component in an exact join keeps its pixels' crack ring, whose straight runs are
        pixel edges, not an end plane's trace)."""
        return self.planar and all(c in getattr(self.slices[k], "own", ()) for k, c in comps)

    def _planes(self, q, up) -> list:
        """The end planes that may cut component ``q = (k, c)`` toward its ``up`` end: per trace of its
        outer ring (:func:`_chords`), longest first, ``(nrm, c, tol, gamma)``, ``gamma`` the trace's
        move per unit distance outward fitted on the parallel traces of the sections joined to it
        by bands on either side (None where no other section has one)."""
        key = (q, up)
        if key in self._plane_cache:
            return self._plane_cache[key]
        out = []
        ring = np.asarray(self.slices[q[0]].outer[q[1]], dtype=np.float64)
        z0, sgn = float(self.zs[q[0]]), 1.0 if up else -1.0
        chain = []  # (outward distance, outer ring) of the sections joined to q along bands, two each way
        for step in (self.above, self.below):
            cur = q
            for _ in range(2):
                cur = step.get(cur)
                if cur is None:
                    break
                chain.append((sgn * (float(self.zs[cur[0]]) - z0), np.asarray(self.slices[cur[0]].outer[cur[1]])))
        scale = float(np.ptp(ring, axis=0).max())
        for nrm, c, tol, _ in _chords(ring):
            pts = [(0.0, c)] + [(t, ci) for t, r in chain for ci in [_trace_offset(r, nrm)[0]] if ci is not None]
            gamma = None
            if len(pts) > 1:
                t, ci = np.array(pts).T
                fit = np.polyfit(t, ci, 1)
                if np.abs(np.polyval(fit, t) - ci).max() > 2e-3 * scale or fit[0] >= 0:
                    continue  # traces of different planes, or a plane that does not close this end
                gamma = float(fit[0])
            out.append((nrm, c, tol, gamma))
        self._plane_cache[key] = out
        return out

    def make_band(self, M, k, a, b, matched, ring, mixed) -> bool:
        """The volume mesher's band hook (``caps="smooth"``): a join next to an end cut by a plane.

        Where the section nearer the end, ``Q``, is bounded by a trace of that end's plane
        (:meth:`_planes`), the points of the other section's rings, ``P``, go on along the lateral
        surface (the similarity from ``P`` to ``Q``, :func:`_lateral`) and those that meet the plane
        before ``Q``'s height stop there (:meth:`_cut_band`).  A ruled band straight from ``P`` to
        ``Q`` cuts the corner where the lateral surface meets the plane (a tube r = 5 mm tilted 30
        degrees and drawn every 3 mm loses 3.8 % of its volume there).  ``matched``: the hole pairs
        of a band join (joined as usual); None for a bridged join of one component to one, where
        the holes of ``P`` open onto the plane and ``Q`` has none (a tube's bore at a slanted end:
        an annulus, then a C).  Returns False (the mesher's own join) where no such plane is found."""
        if self.interior_only or not self.planar:
            return False
        for up in (True, False):
            q, p = ((k + 1, b), (k, a)) if up else ((k, a), (k + 1, b))
            sp, sq = self.slices[p[0]], self.slices[q[0]]
            if not self._drawn(p, q):
                continue
            if matched is None and (len(sq.holes[q[1]]) or not len(sp.holes[p[1]])):
                continue
            holes = range(len(sp.holes[p[1]])) if matched is None else ()
            ids = [ring(*p, -1)] + [ring(*p, h) for h in holes]  # the rings the mesher joins (crack rings too)
            qid = ring(*q, -1)
            Ps = [M.coords(r)[:, :2] for r in ids]
            Q = M.coords(qid)[:, :2]
            dist = abs(float(self.zs[q[0]] - self.zs[p[0]]))
            for nrm, c, tol, gamma in self._planes(q, up):
                fit = _lateral(Q, Ps[0], nrm, c, tol, dist)
                if fit is None:
                    continue
                shift, rho = fit
                if gamma is None:
                    gamma = _square_gamma(nrm, Ps[0], shift, rho, dist)
                    if gamma is None:
                        continue
                cp = c - gamma * dist  # the trace's place at P's height
                if any((R @ nrm > cp + max(tol, 1e-6 * dist)).any() for R in Ps):
                    continue  # P reaches beyond the plane
                sweeps = [_sweep(R, nrm, cp, tol, gamma, shift, rho, dist) for R in Ps]
                plan = _cut_plan(Ps, sweeps, Q, c - Q @ nrm <= tol, dist, up)
                if plan is None:
                    continue
                self._cut_band(M, float(self.zs[p[0]]), up, ids, qid, sweeps, plan)
                if matched:
                    for ha, hb in matched:
                        M.band(ring(k, a, ha), ring(k + 1, b, hb), mixed)
                self.planar_joins.add((k, a, b))
                return True
        return False

    def _cut_band(self, M, z, up, ids, qid, sweeps, plan):
        """The faces of a plan (:func:`_cut_plan`): the strips from ``P``'s rings to their points'
        places on the plane, the planar polygons, and the lateral bands."""
        sgn = 1.0 if up else -1.0
        tops_ids = []
        for pid, (tops, t, _), on in zip(ids, sweeps, plan["on"]):
            top = pid.copy()
            moved = on & (t > 0)
            top[moved] = M.points(np.c_[tops[moved], z + sgn * t[moved]])
            self._strip(M, pid, top, up)
            tops_ids.append(top)
        for parts, f in plan["flat"]:
            M.faces(np.concatenate([tops_ids[r][i] if r >= 0 else qid[i] for r, i in parts])[f])
        for r, lo, hi in plan["lateral"]:
            self._open_band(M, tops_ids[r][lo], qid[hi], up)

    @staticmethod
    def _open_band(M, lo, hi, up):
        """A band between two open chains (P's side ``lo``, Q's ``hi``, in ring order, sharing no point):
        each advances by its share of its own length (the chains run between the same corners)."""
        X, Y = M.coords(lo), M.coords(hi)

        def share(W):
            s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))]
            return s / s[-1] if s[-1] > 0 else np.linspace(0.0, 1.0, len(W))

        u, w = share(X), share(Y)
        i = j = 0
        tri = []
        while i < len(lo) - 1 or j < len(hi) - 1:
            if j == len(hi) - 1 or (i < len(lo) - 1 and u[i + 1] <= w[j + 1]):
                tri.append((lo[i], lo[i + 1], hi[j]))
                i += 1
            else:
                tri.append((lo[i], hi[j + 1], hi[j]))
                j += 1
        tri = np.asarray(tri, dtype=np.int64)
        M.faces(tri if up else tri[:, [0, 2, 1]])

    @staticmethod
    def _strip(M, ids, top, up):
        """The lateral strip from a ring to its moved copy (points that stay make triangles, not quads)."""
        a1, b1 = np.roll(ids, -1), np.roll(top, -1)
        lo, lo1, hi, hi1 = (ids, a1, top, b1) if up else (top, b1, ids, a1)
        tri = np.concatenate([np.stack([lo, lo1, hi1], axis=1), np.stack([lo, hi1, hi], axis=1)])
        M.faces(tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])])

    def _build_plane(self, M, k, c, rings, xys, z, up, tops, ts, vs) -> bool:
        """An end cut by a plane (:func:`_planar_end`): each end ring's points go on along the lateral
        surface to the plane (``tops`` at distances ``ts`` beyond the end), and the plane closes it."""
        try:
            f = cap_faces(tops[0], tops[1:], upward=up)
        except ValueError:
            return False
        if len(f) == 0 or _rings_that_meet(list(tops)).any():
            return False
        sgn = 1.0 if up else -1.0
        tids = []
        for ids, q, t in zip(rings, tops, ts):
            ids = np.asarray(ids).copy()
            out = t > 0
            ids[out] = M.points(np.c_[q[out], z + sgn * t[out]])
            tids.append(ids)
        for a, b in zip(rings, tids):
            self._strip(M, np.asarray(a), b, up)
        M.faces(np.concatenate(tids)[f])
        self.kinds[(k, c, up)] = "plane"
        for q, t, v in zip(xys, ts, vs):  # the lateral surface's slope at the end ring (curved bands)
            for (x, y), (sx, sy) in zip(q[t > 0], v[t > 0] * sgn):
                self.slopes[(float(x), float(y), z)] = (float(sx), float(sy))
        return True

    def _build(self, M, k, c, rings, xys, z, up, t, lam, drift, centre, rate, kind) -> bool:
        """The end's shrunk copies (scale ``lam[i]`` about ``centre``, moved ``drift * t[i]``) at
        distances ``t`` beyond the end ring, joined point to point, the last one closed flat."""
        def placed(i):
            return [centre + lam[i] * (q - centre) + drift * t[i] for q in xys]

        last = placed(-1)
        try:
            cap_faces(last[0], last[1:], upward=up)
        except ValueError:
            return False
        sgn = 1.0 if up else -1.0
        prev = list(rings)
        for i in range(len(t)):
            nxt_ids = [M.ring(q, z + sgn * t[i]) for q in placed(i)]
            for p_ids, n_ids in zip(prev, nxt_ids):
                M.quads(p_ids, n_ids) if up else M.quads(n_ids, p_ids)
            prev = nxt_ids
        M.cap(prev, upward=up)
        self.kinds[(k, c, up)] = kind
        # the cap's slope at the end ring (outward t is +z at an upper end, -z at a lower one): curved
        # bands (bands="curved") meet it without a kink
        for q in xys:
            d = (rate * (q - centre) + drift) * sgn
            for (x, y), (sx, sy) in zip(q, d):
                self.slopes[(float(x), float(y), z)] = (float(sx), float(sy))
        return True
