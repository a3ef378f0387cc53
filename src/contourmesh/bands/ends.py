"""Smooth ends on the area profile of the last sections (the contours route's ``caps="smooth"``,
and the band refinement's): shared by :mod:`contourmesh.drawn`, :mod:`contourmesh.surface` and
:mod:`contourmesh.volumes`.

* :func:`_dome_centre`: a centre to shrink an end polygon toward;
* :func:`_end_profile`: where the section's area goes beyond an end, from the last sections' areas;
* :class:`_SmoothEnds`: the volume mesher's ``end_cap`` hook that closes ends on that profile.
"""

from __future__ import annotations

import numpy as np

from ..geometry import shoelace_area, slice_gap
from .caps import cap_faces


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
    """

    def __init__(self, interior_only: bool = False, dome_rings: int = _DOME_RINGS, branch_domes: bool = True):
        self.interior_only = interior_only  # caps="flat": only ends inside the stack (see _InteriorEnds)
        self.branch_domes = branch_domes  # False: an end without a band join of its own is left to the mesher
        self.dome_rings = dome_rings  # the rings of a dome that closes on the area profile
        self.kinds: dict = {}  # (k, c, upward) -> "dome", "taper", "cut", "branch" or "half" (the last mesh built)
        self.slopes: dict = {}  # (x, y, z) of an end ring's vertex -> d(x, y)/dz of its cap at the ring

    def count(self, kind) -> int:
        return sum(v == kind for v in self.kinds.values())

    def attach(self, slices, zs, joins):
        self.slices, self.zs = slices, zs
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
        if round_[0] < _CUT * round_[1]:
            # the end section is much less round than the one before: a flat end cut at a slant (a
            # tilted tube), not a closing dome; its copy moves along the axis half a spacing out
            t, lam, kind, rate = np.array([gap / 2]), np.array([1.0]), "cut", 0.0
        else:
            t, lam, kind = _end_profile(areas, dists, gap, self.dome_rings)
            rate = _end_rate(areas, dists)  # d(lam)/dt at the end ring
        return self._build(M, k, c, rings, xys, z, up, t, lam, drift, centre, rate, kind)

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
