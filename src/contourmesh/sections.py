"""Intermediate sections: a branching join that cannot be bridged whole, split in the gap.

A bridged join (:func:`contourmesh.volumes._bridge_join`) joins the contours of each side of a fork,
a merge or a hole that opens or closes into one ring and puts one band between the two rings.  On
rotated real shapes that band (or a tube or a lid beside it) sometimes crosses itself or the rest
of the join, and the join would fall back to the voxel-exact join (walls and pixel faces: the
staircase).  Here such a join gets an **intermediate section** half way up the gap instead: the
zero level of the interpolated signed distance of the two slices' regions (shape-based
interpolation, Raya & Udupa 1990; Herman, Zheng & Bucholtz 1992), digitized on the slices' pixel
grid.  Its components get their polygons like any slice's (MLP, DSS or crack), and the join becomes
two joins, lower slice -> section and section -> upper slice, each a band join or a bridged join
decided by the same rules as between slices.  A part that still fails is split again (a section
at a quarter of the gap), up to :data:`MAX_DEPTH` levels.

The sections must not change the topology: the 6-connected voxel stack lower / sections / upper
(26-connected background) must have the same components, background components and Euler
characteristic as the stack lower / upper, so the join's piece of the mesh keeps the voxel
object's genus.  A section component with no partner on one side (material that ends in the gap)
is capped flat in the section's plane.  The whole join must be a valid piece (every new edge used
twice, the slices' ring edges once, no degenerate face, no crossing faces); otherwise the join
stays what it was (the caller makes it exact).  The mesher's crossing check still sees the result
with the rest of the mesh: where its faces cross another join's, the join falls back like any
bridged join.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from ._kernels import njit
from ._recent import MISSING
from .bands.bridges import keyhole_uncovered, segments_cross
from .bands.caps import cap_faces
from .geometry import grid_to_xy
from .intersect import any_intersecting
from .measure import triangle_areas
from .tracing import _first_row_run, _pair_groups, label_mask

#: How many times a join is split (1: one section at mid-gap; 2: also at quarters where needed).
MAX_DEPTH = 2
#: Give a sectioned join of a loop of overlaps up as soon as no stack of sections it can still get
#: keeps the Euler characteristic (see :func:`sectioned_join`'s ``topology_first``); False builds its
#: pieces until they fail or the final test does (the same joins, more work: the tests' reference).
GIVE_UP_EARLY = True
#: Before the pieces below a section are built, ask whether the pair above it is ruled out by its
#: labels alone (:func:`sectioned_join`'s ``doomed``): then the join gives None without building
#: them.  False builds them first (the same joins, more work: the tests' reference).
DOOMED_FIRST = True

_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)


def mid_section(ra: np.ndarray, rb: np.ndarray, sampling=(1.0, 1.0)) -> np.ndarray:
    """The pixels of the intermediate section between two regions (boolean masks, same box):
    where the mean of their signed distances is negative.  Each signed distance is measured from
    pixel centres to the crack boundary (half a pixel from the nearest centre on the other side),
    negative inside.  Pixels inside both regions are always in it, pixels outside both never."""
    return _sdf(ra, sampling) + _sdf(rb, sampling) < 0


def _sdf(m: np.ndarray, sampling, need=None) -> np.ndarray:
    """:func:`mid_section`'s signed distance of a region (a boolean mask).

    On square pixels whose side is a power of two (1 mm, 0.5 mm, ...; between 2^-200 and 2^200, so
    that no square underflows or overflows) and a region with a pixel, compiled
    (:func:`_sdf_square`): every squared distance is then an exact integer times the pixel area, so
    it is the same number whichever nearest pixel is found, and the same bits as the reference
    (:func:`_sdf_reference`, scipy's exact transform).  Other pixels (any sides, the two may differ)
    take a compiled port of scipy's transform (:func:`_sdf_any`: the same feature pixel for every
    pixel, so the same bits) where their sides are in its range (:func:`_any_pixel_ok`), else the
    reference itself.

    ``need`` (a boolean mask of the same shape, or None: every pixel): the pixels whose distance is
    wanted; the others get ``-inf`` on the region and ``+inf`` off it (only the sign is right).  A
    sectioned join's layers all agree outside the pixels where its two slices differ, so its
    sections' signs there never depend on a distance (see :func:`sectioned_join`)."""
    m = np.asarray(m, dtype=bool)
    s0, s1 = (float(x) for x in sampling)
    if s0 == s1 and 2.0 ** -200 <= s0 <= 2.0 ** 200 and math.frexp(s0)[0] == 0.5 and m.ndim == 2 and m.any():
        want = _ALL if need is None else np.ascontiguousarray(need, dtype=bool).view(np.uint8)
        return _sdf_square(np.ascontiguousarray(m).view(np.uint8), s0 * s0, 0.5 * min(s0, s1), *_column_buffers(*m.shape),
                           want)
    if m.ndim == 2 and _any_pixel_ok(s0, s1, *m.shape) and m.any():
        want = _ALL if need is None else np.ascontiguousarray(need, dtype=bool).view(np.uint8)
        return _sdf_any(np.ascontiguousarray(m).view(np.uint8), s0, s1, 0.5 * min(s0, s1), *_column_buffers(*m.shape),
                        want)
    out = _sdf_reference(m, sampling)
    if need is not None:
        out[~np.asarray(need, dtype=bool)] = np.where(m, -np.inf, np.inf)[~np.asarray(need, dtype=bool)]
    return out


#: :func:`_sdf_square`'s ``need`` for every pixel.
_ALL = np.zeros((0, 0), np.uint8)


def _sdf_wanted(m: np.ndarray, sampling, need: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``_sdf(m, sampling, need=need).ravel()[at]``: the signed distances of the wanted pixels
    alone, ``at`` the flat indices of ``need``'s pixels in raster order (the same floats).

    On square pixels whose side is a power of two (where :func:`_sdf` takes :func:`_sdf_square`)
    and a region with a pixel they are measured by a search round each wanted pixel
    (:func:`_sdf_near`), which falls back to the whole transform where the search grows long
    (with :data:`NEAR_FIRST`): a sectioned join wants the pixels where its two slices differ, a
    few in its box (on the liver one in a hundred), and the whole transform and its output of the
    box's size (mapped anew at every call) cost more than the search.  On other square pixels (in
    :func:`_any_pixel_ok`'s range) the search is :func:`_sdf_near_any`, which also gives up where
    the nearest pixels of one pixel's search lie at distances whose floats differ (the whole
    transform then decides which it takes)."""
    m = np.asarray(m, dtype=bool)
    s0, s1 = (float(x) for x in sampling)
    if NEAR_FIRST and s0 == s1 and 2.0 ** -200 <= s0 <= 2.0 ** 200 and math.frexp(s0)[0] == 0.5 and m.ndim == 2 \
            and m.any():
        out, done = _sdf_near(np.ascontiguousarray(m).view(np.uint8), s0 * s0, 0.5 * s0,
                              np.ascontiguousarray(at, dtype=np.int64), np.int64(_NEAR_WORK * m.size))
        if done:
            return out
    elif NEAR_FIRST and s0 == s1 and m.ndim == 2 and _any_pixel_ok(s0, s1, *m.shape) and m.any():
        out, done = _sdf_near_any(np.ascontiguousarray(m).view(np.uint8), s0, 0.5 * s0,
                                  np.ascontiguousarray(at, dtype=np.int64), np.int64(_NEAR_WORK * m.size))
        if done:
            return out
    return _sdf(m, sampling, need=need).ravel()[at]


#: :func:`_sdf_wanted` measures on square pixels by :func:`_sdf_near` (or :func:`_sdf_near_any`)
#: first; False: by the whole transform always (the same numbers: the tests' reference).
NEAR_FIRST = True
#: :func:`_sdf_near` gives up once it has looked at this many pixels per pixel of the mask (the
#: whole transform passes over each pixel of the padded mask a few times).
_NEAR_WORK = 8


@njit(cache=True, nogil=True)
def _ring_feature(m, yy, xx, inside):
    """Whether pixel ``(yy, xx)`` of the padded mask (``-1 .. H``, ``-1 .. W``; the padding is
    empty) is a feature of :func:`_sdf_near`'s search: empty for a pixel of the region (``inside``),
    of the region for one off it."""
    H, W = m.shape
    if yy < 0 or yy >= H or xx < 0 or xx >= W:
        return inside
    return (m[yy, xx] == 0) == inside


@njit(cache=True, nogil=True)
def _sdf_near(m, area, h, at, budget):
    """:func:`_sdf_square`'s signed distances of a non-empty mask (uint8) on square pixels of area
    ``area`` (``h`` half the side) at the pixels of flat indices ``at``, by a search round each:
    ``(out, True)`` with ``out[i]`` pixel ``at[i]``'s distance (the same float), or ``(out,
    False)`` (unfinished) once the search has looked at more than ``budget`` pixels.

    The search looks at the square rings round the pixel, radius 1, 2, ... (pixels of the padded
    mask only), and keeps the least squared distance (an integer number of pixel steps) to a
    feature (:func:`_ring_feature`: an empty pixel of the padded mask for a pixel of the region, a
    pixel of the region for one off it, as the transform's).  Every pixel of ring ``r`` is at least
    ``r`` steps away, so once ``r^2`` is no less than the least found no farther ring holds a
    nearer feature: that least is the transform's squared distance, the same integer, and the
    distance (``h - inside`` on the region, ``outside - h`` off it, each the square root of the
    integer times ``area``) the same float."""
    H, W = m.shape
    out = np.empty(at.shape[0], np.float64)
    work = 0
    big = np.int64(1) << 62
    for i in range(at.shape[0]):
        y, x = at[i] // W, at[i] % W
        inside = m[y, x] != 0
        best = big
        r = 1
        while r * r < best:
            c0, c1 = max(x - r, -1), min(x + r, W)
            r0, r1 = max(y - r + 1, -1), min(y + r - 1, H)
            for side in range(2):
                yy = y - r if side == 0 else y + r
                if -1 <= yy <= H:  # (a row of the ring)
                    work += c1 - c0 + 1
                    for xx in range(c0, c1 + 1):
                        if _ring_feature(m, yy, xx, inside):
                            d = r * r + (xx - x) * (xx - x)
                            if d < best:
                                best = d
                xx = x - r if side == 0 else x + r
                if -1 <= xx <= W:  # (a column of the ring, less its corners)
                    work += r1 - r0 + 1
                    for yy in range(r0, r1 + 1):
                        if _ring_feature(m, yy, xx, inside):
                            d = r * r + (yy - y) * (yy - y)
                            if d < best:
                                best = d
            if work > budget:
                return out, False
            r += 1
        if inside:
            out[i] = h - math.sqrt(float(best) * area)
        else:
            out[i] = -h + math.sqrt(float(best) * area)
    return out, True


@njit(cache=True, nogil=True, inline="always")
def _nearer(best, dist, dy, dx, s):  # pragma: no cover (compiled)
    """One feature of :func:`_sdf_near_any`'s ring at ``(dy, dx)`` pixel steps against the least
    integer squared distance ``best`` so far (measured ``dist``): ``(best, dist, tie)``, the
    feature's where it is nearer, as they were where it is farther, and ``tie`` where it is as
    near and measures another float (the transform's operations: ``sqrt((dy * s)^2 + (dx * s)^2)``)."""
    d = dy * dy + dx * dx
    if d > best:
        return best, dist, False
    t0 = float(dy) * s
    t1 = float(dx) * s
    f = math.sqrt(t0 * t0 + t1 * t1)
    if d < best:
        return d, f, False
    return best, dist, f != dist


@njit(cache=True, nogil=True)
def _sdf_near_any(m, s, h, at, budget):
    """:func:`_sdf_any`'s signed distances of a non-empty mask (uint8) on square pixels of side
    ``s`` (any, in :func:`_any_pixel_ok`'s range; ``h`` half of it) at the pixels of flat indices
    ``at``, by :func:`_sdf_near`'s search round each: ``(out, True)`` with the same floats, or
    ``(out, False)`` where it gives up (over ``budget`` pixels looked at, or a tie it cannot settle).

    The transform takes a nearest feature (the least integer squared distance in pixel steps:
    where distances differ its float comparisons order them as the integers, the gaps being of the
    order of the pixel area) and measures ``sqrt((dy * s)^2 + (dx * s)^2)`` to it; of features at
    one integer distance it picks by comparisons of rounded floats, which the search does not
    repeat.  So the search finds every feature at the least integer distance (it goes on through
    the ring whose radius squared equals that distance: an axis pixel of it may be one), measures
    each in the transform's operations and order, and gives up where two of those floats differ
    (``25 = 5^2 + 0^2 = 3^2 + 4^2`` may round apart): where they agree it is the transform's
    distance whichever it picks, and the signed distance (``h - d`` on the region, ``d - h`` off
    it) the same float."""
    H, W = m.shape
    out = np.empty(at.shape[0], np.float64)
    work = 0
    big = np.int64(1) << 62
    for i in range(at.shape[0]):
        y, x = at[i] // W, at[i] % W
        inside = m[y, x] != 0
        best = big
        dist = 0.0
        r = 1
        while r * r <= best:
            c0, c1 = max(x - r, -1), min(x + r, W)
            r0, r1 = max(y - r + 1, -1), min(y + r - 1, H)
            for side in range(2):
                yy = y - r if side == 0 else y + r
                if -1 <= yy <= H:  # (a row of the ring)
                    work += c1 - c0 + 1
                    for xx in range(c0, c1 + 1):
                        if _ring_feature(m, yy, xx, inside):
                            best, dist, tie = _nearer(best, dist, yy - y, xx - x, s)
                            if tie:
                                return out, False
                xx = x - r if side == 0 else x + r
                if -1 <= xx <= W:  # (a column of the ring, less its corners)
                    work += r1 - r0 + 1
                    for yy in range(r0, r1 + 1):
                        if _ring_feature(m, yy, xx, inside):
                            best, dist, tie = _nearer(best, dist, yy - y, xx - x, s)
                            if tie:
                                return out, False
            if work > budget:
                return out, False
            r += 1
        out[i] = h - dist if inside else dist - h
    return out, True


#: Largest padded image (pixels) whose column-distance arrays a thread keeps for the next one.
_KEPT_PIXELS = 1 << 20
_LOCAL = threading.local()


def _column_buffers(H, W):
    """``gi`` and ``go`` for :func:`_sdf_square` on an ``H x W`` mask: int32 where the squared
    distances fit (``(H + 1)^2 < 2^31``), this thread's (grown as needed, up to ``_KEPT_PIXELS``):
    fresh arrays of a megabyte or so are mapped anew at every call, and their pages being zeroed at
    the first write cost the liver's sections half of their signed distances' time."""
    shape, dt = (H + 2, W + 2), np.int32 if H + 2 <= 46_340 else np.int64
    n = shape[0] * shape[1]
    if n > _KEPT_PIXELS or dt is np.int64:
        return np.empty(shape, dt), np.empty(shape, dt)
    got = getattr(_LOCAL, "columns", None)
    if got is None or len(got) < 2 * n:
        got = np.empty(2 * n, np.int32)
        _LOCAL.columns = got
    return got[:n].reshape(shape), got[n:2 * n].reshape(shape)


def release_buffers() -> None:
    """Let go of this thread's kept column buffers (:func:`_column_buffers`; see
    :func:`contourmesh.bands.optimal.release_buffers`)."""
    _LOCAL.__dict__.pop("columns", None)


@njit(cache=True, nogil=True)
def _column_distances(m, gi, go):
    """Squared distances along each column of the image ``m`` padded by one empty pixel, to the
    nearest feature pixel of that column, written into ``gi`` and ``go`` (``(H + 2, W + 2)``, an
    integer type that holds ``(H + 1)^2``): ``gi`` to the padded image's empty pixels (every column
    has some: the padding), ``go`` to its object pixels (-1 where a column has none).  Both in one
    pass down the rows and one up, every column at once (row-major: the image is read in order)."""
    H, W = m.shape
    Hp, Wp = H + 2, W + 2
    li = np.zeros(Wp, np.int64)  # the row of the last empty pixel seen from above (row 0: padding)
    lo = np.full(Wp, -1, np.int64)  # ... of the last object pixel (-1: none yet)
    for x in range(Wp):
        gi[0, x] = 0
        go[0, x] = -1
    for y in range(1, Hp):
        inner = y < Hp - 1
        for x in range(Wp):
            if inner and 0 < x < Wp - 1 and m[y - 1, x - 1] != 0:
                li_ = li[x]
                gi[y, x] = (y - li_) * (y - li_)
                lo[x] = y
                go[y, x] = 0
            else:
                li[x] = y
                gi[y, x] = 0
                lo_ = lo[x]
                go[y, x] = -1 if lo_ < 0 else (y - lo_) * (y - lo_)
    for x in range(Wp):  # (now the next feature from below)
        li[x] = Hp - 1
        lo[x] = -1
    for y in range(Hp - 2, -1, -1):
        for x in range(Wp):
            if gi[y, x] == 0:
                li[x] = y
            else:
                d = (li[x] - y) * (li[x] - y)
                if d < gi[y, x]:
                    gi[y, x] = d
            if go[y, x] == 0:
                lo[x] = y
            elif lo[x] >= 0:
                d = (lo[x] - y) * (lo[x] - y)
                if go[y, x] < 0 or d < go[y, x]:
                    go[y, x] = d


@njit(cache=True, nogil=True)
def _envelope(grow, v, zn, zd):
    """The lower envelope of the parabolas ``(x - q)^2 + grow[q]`` over the columns ``q`` with
    ``grow[q] >= 0`` (Felzenszwalb & Huttenlocher), their crossings compared exactly (integers):
    parabola ``v[t]`` is the lowest from ``zn[t] / zd[t]`` on.  Returns the last ``t``."""
    k = -1
    for q in range(grow.shape[0]):
        fq = grow[q]
        if fq < 0:
            continue
        while k > 0:
            p = v[k]
            num = (fq + q * q) - (grow[p] + p * p)
            if num * zd[k] <= zn[k] * (2 * (q - p)):
                k -= 1
            else:
                break
        k += 1
        v[k] = q
        if k > 0:
            p = v[k - 1]
            zn[k] = (fq + q * q) - (grow[p] + p * p)
            zd[k] = 2 * (q - p)
    return k


@njit(cache=True, nogil=True)
def _sdf_square(m, area, h, gi, go, need):
    """:func:`_sdf` of a non-empty mask (uint8) on square pixels of area ``area`` (a power of two
    squared), ``h`` half the pixel side: ``h - inside`` on the region, ``outside - h`` off it, each
    distance the square root of its squared number of pixel steps times ``area`` (exact).  ``gi``
    and ``go``: :func:`_column_distances`' arrays (their contents do not matter).  ``need``: a
    uint8 mask of the pixels whose distance is wanted (the others get ``-inf`` on the region,
    ``+inf`` off it), or an empty array: every pixel.

    The squared distances of each row (to the nearest empty pixel of the padded mask for the
    region's pixels, to the nearest region pixel for the others) are read off the lower envelope
    of that row's column distances, one envelope per run of the row: a run's nearest pixel lies in
    the columns of the run or of the pixels just beyond it, which are of the other kind (at column
    distance 0: every column farther is farther), so each envelope has only those columns (about
    half as many parabolas as two envelopes of the whole row).  The pixels beyond a run at the
    padding of an outside run are no region pixels, but there the run reaches the padding: no
    column lies beyond it.  A run with no wanted pixel gets no envelope, nor is it walked: a row
    gets its signs first, then only its runs that hold a wanted pixel, each found from its first
    wanted pixel (on the lobster and the liver most runs of a row with a wanted pixel have none;
    walking them took a quarter of the signed distances' time).  Where some pixels are
    wanted (:func:`_wanted_in_run`), each wanted pixel's nearest column lies no farther from it than
    a column beyond the run (whose distance is 0), so the run's envelope is made only over the
    columns within that reach of its wanted pixels: the lowest parabola there is as low as over the
    whole run, the squared distance is the same integer, and the distance the same bits."""
    H, W = m.shape
    Wp = W + 2
    every = need.shape[0] == 0
    _column_distances(m, gi, go)
    out = np.empty((H, W), np.float64)
    v = np.empty(Wp, np.int64)  # the run's envelope
    zn = np.empty(Wp, np.int64)
    zd = np.empty(Wp, np.int64)
    for y in range(H):
        row = m[y]
        if not every:
            # the signs first (a loop the compiler vectorizes), then the runs that hold a wanted
            # pixel, each found from its first wanted pixel: the other runs are only signs
            nrow = need[y]
            for x in range(W):
                out[y, x] = -np.inf if row[x] != 0 else np.inf
            x = 0
            while True:
                while x < W and nrow[x] == 0:
                    x += 1
                if x >= W:
                    break
                inside = row[x] != 0
                a = x
                while a > 0 and (row[a - 1] != 0) == inside:
                    a -= 1
                b = x + 1
                while b < W and (row[b] != 0) == inside:
                    b += 1
                # (an outside run's column beyond it at the padding has no distance: no bound there)
                g = gi[y + 1, a:b + 2] if inside else go[y + 1, a:b + 2]
                _wanted_in_run(out[y, a:b], g, nrow[a:b], inside, inside or a > 0, inside or b < W, h, area, v, zn, zd)
                x = b
            continue
        x = 0
        while x < W:
            inside = row[x] != 0
            b = x + 1
            while b < W and (row[b] != 0) == inside:
                b += 1
            o = out[y, x:b]  # (relative column xr at o[xr - 1])
            # the run is image columns x .. b - 1, padded x + 1 .. b; with the pixels beyond it,
            # padded columns x .. b + 1 (relative columns 0 .. b - x + 1)
            g = gi[y + 1, x:b + 2] if inside else go[y + 1, x:b + 2]
            k = _envelope(g, v, zn, zd)
            # parabola v[t] is the lowest on the columns past zn[t] / zd[t] (zd > 0; increasing
            # in t) up to the next one's: the integer columns from floor(zn / zd) + 1 on
            sgn = -1.0 if inside else 1.0
            hs = h if inside else -h
            end = b - x + 1
            for t in range(k + 1):
                lo = 1 if t == 0 else max(1, zn[t] // zd[t] + 1)
                hi = end if t == k else min(end, zn[t + 1] // zd[t + 1] + 1)
                p = v[t]
                gp = g[p]
                for xr in range(lo, hi):
                    o[xr - 1] = hs + sgn * math.sqrt(float((xr - p) * (xr - p) + gp) * area)
            x = b
    return out


@njit(cache=True, nogil=True)
def _wanted_in_run(o, g, need, inside, left, right, h, area, v, zn, zd):
    """:func:`_sdf_square` on one run whose pixels ``need`` (uint8, the run's) are wanted: ``o``
    (the run's output) gets each wanted pixel's signed distance, the others ``-inf`` on the region
    and ``+inf`` off it.  ``g``: the column distances of the run's columns and of the two beyond it
    (relative columns ``0 .. end``); ``left`` / ``right``: whether that beyond column has distance 0
    (not a padding column of an outside run).

    A wanted pixel at relative column ``xr`` is at most ``r = min(xr, end - xr)`` (of the beyond
    columns with distance 0) from a feature, so its nearest column lies in ``xr - r .. xr + r``.
    These windows move right with ``xr`` (both ends never decrease), so the wanted pixels fall
    into runs of overlapping windows; each gets one envelope over the columns its windows cover,
    read as the whole run's is (the owner of column ``c`` is the last parabola whose crossing's
    floor is below ``c``)."""
    end = g.shape[0] - 1
    sgn = -1.0 if inside else 1.0
    hs = h if inside else -h
    o[:] = sgn * np.inf
    big = end + 1
    cl, ch, w0, w1 = -1, -1, -1, -1  # the current cluster's columns and first / last wanted pixel
    xr = 1
    while xr <= end:
        lo_, hi_ = end + 1, end + 1
        if xr < end and need[xr - 1] != 0:
            r = min(xr if left else big, end - xr if right else big)
            lo_, hi_ = max(0, xr - r), min(end, xr + r)
        if cl >= 0 and (xr == end or lo_ <= end and lo_ > ch):
            # the cluster's envelope over columns cl .. ch, read at its wanted pixels w0 .. w1
            k = _envelope(g[cl:ch + 1], v, zn, zd)
            t = 0
            for w in range(w0, w1 + 1):
                if need[w - 1] == 0:
                    continue
                c = w - cl
                while t < k and zn[t + 1] // zd[t + 1] < c:
                    t += 1
                p = v[t] + cl
                o[w - 1] = hs + sgn * math.sqrt(float((w - p) * (w - p) + g[p]) * area)
            cl = -1
        if lo_ <= end:
            if cl < 0:
                cl, ch, w0 = lo_, hi_, xr
            elif hi_ > ch:
                ch = hi_
            w1 = xr
        xr += 1


def _any_pixel_ok(s0, s1, H, W) -> bool:
    """Whether :func:`_sdf_any` gives the reference's bits on an ``H x W`` mask with pixel sides
    ``s0`` (rows) and ``s1`` (columns): no side below ``2^-500`` and no distance across the padded
    image above ``2^511`` (so both are finite and positive).  There the column pass's float
    distances ``((r - y) * s0)^2`` are normal numbers that grow strictly with ``|r - y|``, which
    :func:`_column_features` relies on."""
    lo, hi = 2.0 ** -500, 2.0 ** 511
    return lo <= s0 and lo <= s1 and max(s0, s1) * (max(H, W) + 2) <= hi


@njit(cache=True, nogil=True)
def _column_features(m, fi, fo):
    """The first (column) pass of scipy's exact feature transform of the image ``m`` padded by one
    empty pixel, for both of :func:`_sdf_any`'s transforms at once: ``fi[y, x]`` (``(H + 2, W + 2)``)
    the row of the nearest empty pixel of the padded image in column ``x`` (every column has some:
    the padding), ``fo[y, x]`` that of the nearest object pixel (-1 where the column has none); of
    two at the same distance, the upper one.

    scipy's pass along a column keeps every feature of the column (its test whether a feature hides
    the one before reduces there to ``-a * b * c <= 0`` with ``a``, ``b``, ``c`` positive: always
    true) and walks each pixel to the first feature whose float distance ``((r - y) * s0)^2`` is no
    larger than the next one's.  Where those floats are normal and finite (see
    :func:`_any_pixel_ok`) they grow strictly with ``|r - y|``, so that walk stops at the nearest
    feature, the upper one of a tie: the integer choice made here."""
    H, W = m.shape
    Hp, Wp = H + 2, W + 2
    for x in range(Wp):  # row 0: padding (empty)
        fi[0, x] = 0
        fo[0, x] = -1
    for y in range(1, Hp):  # the nearest feature above (or the pixel itself)
        inner = y < Hp - 1
        for x in range(Wp):
            if inner and 0 < x < Wp - 1 and m[y - 1, x - 1] != 0:
                fi[y, x] = fi[y - 1, x]
                fo[y, x] = y
            else:
                fi[y, x] = y
                fo[y, x] = fo[y - 1, x]
    # then the nearest below, where it is strictly nearer (the last row is padding: only fo there)
    for y in range(Hp - 2, -1, -1):
        for x in range(Wp):
            a = fi[y, x]
            b = fi[y + 1, x]
            if a != y and b - y < y - a:
                fi[y, x] = b
            a = fo[y, x]
            b = fo[y + 1, x]
            if a != y and b >= 0 and (a < 0 or b - y < y - a):
                fo[y, x] = b


@njit(cache=True, nogil=True)
def _row_features(fr, y, s0, s1, g, pick, hv, upto):
    """The second (row) pass of scipy's exact feature transform (``_VoronoiFT`` of
    ``ni_morphology.c`` along one row), with its float operations in its order: ``fr`` the padded
    row ``y``'s column features (:func:`_column_features`; -1: none); ``pick[x]`` gets the column
    of pixel ``x``'s feature (its row is ``fr[pick[x]]``) for ``x < upto``.  ``g`` and ``hv``:
    scratch of the row's length (``hv[x]``: ``((fr[x] - y) * s0)^2``, the one float scipy computes
    anew at each use).  Returns False where the row has no feature (nothing picked).

    Two shortcuts give scipy's picks: the pixels are picked left to right, each from where the one
    before stopped, so stopping at ``upto`` changes none before it; and a feature on the row itself
    (``hv`` 0) on top of the stack is never removed: scipy's test is then
    ``c * 0 - b * uR - a * wR - a * b * c <= 0`` with ``a``, ``b``, ``c`` positive and finite
    (:func:`_any_pixel_ok`), true, so it is not computed."""
    n = fr.shape[0]
    for ii in range(n):
        r = fr[ii]
        if r >= 0:
            t = float(r - y) * s0
            hv[ii] = t * t
    l = -1
    for ii in range(n):
        if fr[ii] < 0:
            continue
        fd = float(ii)
        wr = hv[ii]
        while l >= 1:
            i1 = g[l]
            vr = hv[i1]
            if vr == 0.0:
                break
            i2 = g[l - 1]
            f1 = float(i1)
            a = (f1 - float(i2)) * s1
            b = (fd - f1) * s1
            c = a + b
            if c * vr - b * hv[i2] - a * wr - a * b * c <= 0.0:
                break
            l -= 1
        l += 1
        g[l] = ii
    maxl = l
    if maxl < 0:
        return False
    l = 0
    for ii in range(upto):
        p = g[l]
        t1 = float(p - ii) * s1
        d1 = hv[p] + t1 * t1
        while l < maxl:
            q = g[l + 1]
            t1 = float(q - ii) * s1
            d2 = hv[q] + t1 * t1
            if d1 <= d2:
                break
            d1 = d2
            l += 1
        pick[ii] = g[l]
    return True


@njit(cache=True, nogil=True)
def _sdf_any(m, s0, s1, h, fi, fo, need):
    """:func:`_sdf` of a non-empty mask (uint8) on pixels of sides ``s0`` (between rows) and ``s1``
    (between columns) accepted by :func:`_any_pixel_ok`, ``h`` half the shorter side: the same bits
    as :func:`_sdf_reference`.  ``fi`` and ``fo``: :func:`_column_distances`-shaped integer arrays
    (their contents do not matter); ``need`` as :func:`_sdf_square`'s.

    Each of the reference's two transforms (of the padded mask and of its complement) is scipy's
    exact feature transform followed by the distance to the feature; here both share the column
    pass (:func:`_column_features`, the same features as scipy's), the row pass
    (:func:`_row_features`, scipy's own float comparisons in its order, so the same feature even
    where two lie at one distance) runs only on rows with a wanted pixel of its kind, up to the
    last one, and the distance ``sqrt(((r - y) * s0)^2 + ((c - x) * s1)^2)`` (numpy's operations in
    numpy's order) only at the wanted pixels.  A row's pass reads only that row's column features,
    so the rows left out change nothing.  The padding shifts every coordinate by one: only
    differences are used."""
    H, W = m.shape
    Wp = W + 2
    every = need.shape[0] == 0
    _column_features(m, fi, fo)
    out = np.empty((H, W), np.float64)
    g = np.empty(Wp, np.int64)
    pick = np.empty(Wp, np.int64)
    hv = np.empty(Wp, np.float64)
    for y in range(H):
        row = m[y]
        last_in, last_out = -1, -1  # the last wanted pixel of the region / off it
        for x in range(W):
            if every or need[y, x] != 0:
                if row[x] != 0:
                    last_in = x
                else:
                    last_out = x
        for x in range(W):
            out[y, x] = -np.inf if row[x] != 0 else np.inf
        for inside in (True, False):
            last = last_in if inside else last_out
            if last < 0:
                continue
            fr = fi[y + 1] if inside else fo[y + 1]
            _row_features(fr, y + 1, s0, s1, g, pick, hv, last + 2)  # (a row with a wanted pixel has a feature)
            for x in range(last + 1):
                if (row[x] != 0) != inside or not (every or need[y, x] != 0):
                    continue
                c = pick[x + 1]
                t0 = float(fr[c] - (y + 1)) * s0
                t1 = float(c - (x + 1)) * s1
                d = math.sqrt(t0 * t0 + t1 * t1)
                out[y, x] = h - d if inside else d - h
    return out


def _sdf_reference(m: np.ndarray, sampling) -> np.ndarray:
    """:func:`_sdf` by scipy's exact Euclidean distance transform of the padded mask and of its
    complement (any pixel shape): the reference."""
    from scipy import ndimage

    pad = np.pad(m, 1)
    inside = ndimage.distance_transform_edt(pad, sampling=sampling)[1:-1, 1:-1]
    outside = ndimage.distance_transform_edt(~pad, sampling=sampling)[1:-1, 1:-1]
    h = 0.5 * min(sampling)
    return np.where(m, h - inside, outside - h)


def stack_invariants(layers) -> tuple:
    """(object components, background components, Euler characteristic) of a stack of 2D masks as
    a voxel object: 6-connected object, 26-connected background, padded by empty voxels.

    Counted from the runs of the rows (:mod:`contourmesh.topology`, compiled): the padded stack's
    background is its cavities and the outside, and padding changes neither the object nor its
    Euler characteristic; the same numbers as :func:`_stack_invariants_reference`."""
    from .topology import _count_cavities, _count_object, _euler

    m = np.ascontiguousarray(np.stack(layers), dtype=bool).view(np.uint8)
    return int(_count_object(m)), int(_count_cavities(m)) + 1, int(_euler(m))


def _stack_invariants_reference(layers) -> tuple:
    """:func:`stack_invariants` by labelling the padded stack (``scipy.ndimage.label``) and
    :func:`euler6`: the reference it is tested against."""
    from scipy import ndimage

    v = np.pad(np.stack(layers), 1)
    _, n_obj = ndimage.label(v, structure=ndimage.generate_binary_structure(3, 1))
    _, n_bg = ndimage.label(~v, structure=np.ones((3, 3, 3), dtype=bool))
    return n_obj, n_bg, euler6(v)


def _euler2(m) -> int:
    """The Euler characteristic of a 2D boolean mask as a 4-connected pixel complex: a vertex per
    pixel, an edge per pair of side-adjacent pixels, a square per 2 x 2 block.  A stack of masks
    has ``sum(_euler2(L_i)) - sum(_euler2(L_i & L_i+1))`` as :func:`euler6` (its vertical edges,
    squares and cubes are the pixels, edges and squares of the overlaps of consecutive layers).
    Counted in one compiled pass (:func:`_euler2_kernel`)."""
    m = np.asarray(m, dtype=bool)
    if m.ndim != 2:
        raise ValueError("_euler2 takes a 2D mask")
    return int(_euler2_kernel(np.ascontiguousarray(m).view(np.uint8)))


@njit(cache=True, nogil=True)
def _euler2_kernel(m):
    """:func:`_euler2` of a uint8 mask: pixels less side-adjacent pairs plus 2 x 2 blocks."""
    H, W = m.shape
    chi = 0
    for y in range(H):
        for x in range(W):
            if m[y, x] == 0:
                continue
            chi += 1
            right = x + 1 < W and m[y, x + 1] != 0
            down = y + 1 < H and m[y + 1, x] != 0
            if right:
                chi -= 1
            if down:
                chi -= 1
                if right and m[y + 1, x + 1] != 0:
                    chi += 1
    return chi


def warm_rare_kernels() -> None:
    """Compile (or load) the kernels of sectioned joins that small volumes rarely reach: the Euler
    numbers of the early topology test (:func:`_euler2`, only on a loop of overlaps), the signed
    distances of wanted pixels (:func:`_sdf`, on square pixels of a power-of-two side and on
    others, and the searches round each wanted pixel, :func:`_sdf_near` and :func:`_sdf_near_any`), the edge check of an
    assembled join (:func:`_edges_close`) and the layers' overlap groups (:func:`_run_group_lists`)."""
    m = np.eye(3, dtype=bool)
    _euler2(m)
    _sdf(m, (1.0, 1.0), need=m)
    _sdf_wanted(m, (1.0, 1.0), m, np.flatnonzero(m))
    _sdf(m, (0.75, 0.75), need=m)
    _sdf_wanted(m, (0.75, 0.75), m, np.flatnonzero(m))
    _edges_close(np.array([[0, 1, 2]], dtype=np.int64), 3, [(0, 3)])
    # (the overlap groups of two layers from their runs, as _groups takes them)
    runs = np.array([[0], [0], [2], [0]], dtype=np.int32)
    _run_group_lists(runs, runs, 0, 1, 0, 2, 1, 1, np.zeros(1, np.int64), np.zeros(1, np.int64))


def euler6(v) -> int:
    """The Euler characteristic of a 3D boolean array's object as a 6-connected voxel object
    (``skimage.measure.euler_number(v, connectivity=1)``, an integer, counted another way): the
    complex with a vertex per voxel, an edge per pair of face-adjacent voxels, a square per 2 x 2
    block of voxels in a coordinate plane and a cube per 2 x 2 x 2 block, ``V - E + F - C``."""
    v = np.asarray(v, dtype=bool)
    a, b = slice(None, -1), slice(1, None)
    n_v = int(np.count_nonzero(v))
    n_e = int(np.count_nonzero(v[a] & v[b]) + np.count_nonzero(v[:, a] & v[:, b])
              + np.count_nonzero(v[:, :, a] & v[:, :, b]))
    yz = v[:, a] & v[:, b]  # edges along y, then squares in the (y, z), (x, y) planes and cubes
    xy = v[:, :, a] & v[:, :, b]
    sq_zy = yz[a] & yz[b]
    sq_zx = xy[a] & xy[b]
    sq_yx = xy[:, a] & xy[:, b]
    cubes = sq_yx[a] & sq_yx[b]
    n_f = int(np.count_nonzero(sq_zy) + np.count_nonzero(sq_zx) + np.count_nonzero(sq_yx))
    return n_v - n_e + n_f - int(np.count_nonzero(cubes))


class _Layer:
    """One plane of a sectioned join: a slice of the mesh (``main``: its rings are the mesh's) or an
    intermediate section (its rings are the join's own vertices)."""

    def __init__(self, S, z, comps, poly, edges, main=None, double=frozenset(), box=None, kinds=None):
        self.S, self.z, self.comps = S, float(z), list(comps)
        # (a section's: its pairs' piece kinds by the other layer, kept with its slice: see
        # _pair_kinds; None for a slice's layer)
        self.kinds = kinds
        self.box = box  # a box (a pair of slices) holding every pixel of its components, or None
        self._poly, self._edges = poly, edges
        self.main = main  # the slice index, or None for a section
        self.double = double  # (c, h) of holes lidded from both sides (lids get a collar)
        self.taken = []  # (p, q): bridges that the join below put in this section

    def poly(self, c, h):
        return self._poly(c, h)

    def edges(self):
        a, b = self._edges()
        if not self.taken:
            return a, b
        # the join above must bridge elsewhere: two joins' bridges meeting in a section would pinch it
        return (np.concatenate([a, np.array([p for p, _ in self.taken], dtype=np.float64)]),
                np.concatenate([b, np.array([q for _, q in self.taken], dtype=np.float64)]))


def _section_layer(ops, shape, box, z, polygon, grid, m, memory=None):
    """The intermediate section whose pixels in ``box`` (a pair of slices of an image of
    ``shape``) are ``m`` (:func:`mid_section` of the two layers' regions there), as a
    :class:`_Layer` of a new :class:`_Slice`.

    ``memory`` (a :class:`SectionSlices`, or None): the build's sections made already.  A section
    with the same box and pixels (and polygon method and grid) takes the slice made for it before:
    a slice depends on those alone, and a join only reads a section's slice (its labels and rings;
    the bridges it takes are its layer's, made anew)."""
    if not m.any():
        return None, None
    key = got = None
    if memory is not None:
        key = (shape, tuple((b.start, b.stop) for b in box), polygon, tuple(float(g) for g in grid), m.shape,
               m.tobytes())
        got = memory.get(key)
    if got is None:
        full = np.zeros(shape, dtype=bool)
        full[box] = m
        ox, oy, dx, dy = grid
        to_center, to_corner = grid_to_xy(ox, oy, dx, dy)
        got = (ops.Slice(full, polygon, to_corner, to_center, box=box), [], {})
        if memory is not None:
            memory.put(key, got)
    # (made: the section's edges, made once: its polygons do not change; kinds: its pairs' piece
    # kinds, made once per other layer, see _pair_kinds)
    S, made, kinds = got

    def poly(c, h):
        return S.outer[c] if h < 0 else S.holes[c][h]

    def edges():
        if not made:
            rs = [np.asarray(poly(c, h), dtype=np.float64) for c in range(S.n) for h in range(-1, len(S.holes[c]))]
            made.append((np.concatenate(rs), np.concatenate([np.concatenate([r[1:], r[:1]]) for r in rs])))
        return made[0]

    return _Layer(S, z, range(S.n), poly, edges, box=box, kinds=kinds), m


class SectionSlices:
    """The slices of the last few intermediate sections one build made (:func:`_section_layer`),
    by their box and pixels: a sectioned join asked for again (a restart whose key changed, or
    the same join with another area bound) makes the same sections, and the halves of a gap
    often repeat their pair's section (on the lobster about one section in five is made
    again).  :data:`SECTION_MEMORY` are kept (each holds a label image of the slice's size)."""

    def __init__(self, keep=None):
        self.keep = SECTION_MEMORY if keep is None else keep
        self.seen = {}

    def get(self, key):
        got = self.seen.pop(key, None)
        if got is not None:
            self.seen[key] = got  # (the most recent now)
        return got

    def put(self, key, value):
        while len(self.seen) >= self.keep > 0:
            del self.seen[next(iter(self.seen))]  # (the oldest: dicts keep insertion order)
        if self.keep > 0:
            self.seen[key] = value


#: How many section slices a :class:`SectionSlices` keeps (the lobster's repeats come within
#: some twenty sections but for a few).
SECTION_MEMORY = 24


def _groups(P: _Layer, Q: _Layer):
    """The overlap groups of two layers' components (as the mesher's pass 2), and the components
    of each layer that overlap nothing on the other.

    Within the box that holds both layers' components (the groups do not depend on where the
    pixels lie, only on which labels overlap), one compiled pass marks the pairs of the two
    layers' components that share a pixel: a sweep over the two slices' runs in the box's rows
    where both keep them (:func:`_run_groups`, which also groups the pairs and finds the lone
    components), else over the box's pixels (:func:`_overlap_table`); the groups are the connected
    sets of those pairs, in the order of their first pair, each side sorted: what
    :func:`contourmesh.tracing.overlap_groups` gives for the two label images with every other
    component cleared (as the tests check)."""
    SP, SQ = P.S, Q.S
    lp, lq = SP.labels, SQ.labels
    if P.box is not None and P.box == Q.box:
        (y0, y1, _), (x0, x1, _) = (b.indices(n) for b, n in zip(P.box, lp.shape))
    else:
        y0, y1, x0, x1 = 0, lp.shape[0], 0, lp.shape[1]
    na, nb = SP.n, SQ.n
    rp = getattr(SP, "kept_runs", None)
    rq = getattr(SQ, "kept_runs", None)
    rp, rq = (rp(), rq()) if rp is not None and rq is not None else (None, None)
    if rp is not None and rq is not None:
        # (the groups' members and the lone components listed in the same compiled call:
        # _run_group_lists; the components' marks made there too)
        af, ast, bf, bst, lone_p, lone_q = _run_group_lists(
            rp, rq, y0, y1, x0, x1, na, nb, np.array(P.comps, dtype=np.int64), np.array(Q.comps, dtype=np.int64))
        af, ast, bf, bst = af.tolist(), ast.tolist(), bf.tolist(), bst.tolist()
        return ([(af[ast[g]: ast[g + 1]], bf[bst[g]: bst[g + 1]]) for g in range(len(ast) - 1)], lone_p.tolist(),
                lone_q.tolist())
    inp, inq = np.zeros(na + 1, np.bool_), np.zeros(nb + 1, np.bool_)
    inp[np.asarray(list(P.comps), dtype=np.int64) + 1] = True
    inq[np.asarray(list(Q.comps), dtype=np.int64) + 1] = True
    nbk = np.int64(nb + 1)
    keys = np.flatnonzero(_overlap_table(lp, lq, y0, y1, x0, x1, inp, inq, nbk))
    pa, pb = keys // nbk - 1, keys % nbk - 1
    group, ng = _pair_groups(pa, pb, np.int64(na), np.int64(nb))
    groups = [(set(), set()) for _ in range(ng)]
    la, lb = pa.tolist(), pb.tolist()
    for a, b, g in zip(la, lb, group.tolist()):
        groups[g][0].add(a)
        groups[g][1].add(b)
    lone_p = sorted(set(P.comps).difference(la))
    lone_q = sorted(set(Q.comps).difference(lb))
    return [(sorted(a), sorted(b)) for a, b in groups], lone_p, lone_q


@njit(cache=True, nogil=True)
def _run_groups(rp, rq, y0, y1, x0, x1, inp, inq):
    """:func:`_groups` from the two slices' runs (``(4, n)`` ``[row, first column, end column,
    component]``, raster order: ``_Slice.kept_runs``): the pairs ``(a, b)`` (0-based, ``inp[a +
    1]`` and ``inq[b + 1]``) of components that share a pixel of rows ``y0 .. y1 - 1``, columns
    ``x0 .. x1 - 1``, in increasing order of ``a * len(inq) + b`` (:func:`_overlap_table`'s keys),
    their groups (:func:`contourmesh.tracing._pair_groups`), how many, and the components of
    each side in ``inp`` / ``inq`` without a pair, in increasing order.  Two runs of a row share a
    pixel of the box where their column ranges clipped to it meet; the runs of a row are taken in
    increasing order from both sides, each step past the one that ends first."""
    nbk = inq.shape[0]
    seen = np.zeros(inp.shape[0] * nbk, np.bool_)
    i, j = _first_row_run(rp, y0), _first_row_run(rq, y0)
    n_p, n_q = rp.shape[1], rq.shape[1]
    while i < n_p and j < n_q and rp[0, i] < y1 and rq[0, j] < y1:
        yi, yj = rp[0, i], rq[0, j]
        if yi < yj:
            i += 1
            continue
        if yj < yi:
            j += 1
            continue
        lo = max(max(rp[1, i], rq[1, j]), x0)
        hi = min(min(rp[2, i], rq[2, j]), x1)
        if lo < hi:
            a = np.int64(rp[3, i]) + 1
            b = np.int64(rq[3, j]) + 1
            if inp[a] and inq[b]:
                seen[a * nbk + b] = True
        if rp[2, i] <= rq[2, j]:
            i += 1
        else:
            j += 1
    n = 0
    for k in range(seen.shape[0]):
        if seen[k]:
            n += 1
    pa = np.empty(n, np.int64)
    pb = np.empty(n, np.int64)
    used_p = np.zeros(inp.shape[0], np.bool_)
    used_q = np.zeros(nbk, np.bool_)
    n = 0
    for k in range(seen.shape[0]):
        if seen[k]:
            pa[n] = k // nbk - 1
            pb[n] = k % nbk - 1
            used_p[k // nbk] = True
            used_q[k % nbk] = True
            n += 1
    group, ng = _pair_groups(pa, pb, np.int64(inp.shape[0] - 1), np.int64(nbk - 1))
    m = 0
    for a in range(1, inp.shape[0]):
        if inp[a] and not used_p[a]:
            m += 1
    lone_p = np.empty(m, np.int64)
    m = 0
    for a in range(1, inp.shape[0]):
        if inp[a] and not used_p[a]:
            lone_p[m] = a - 1
            m += 1
    m = 0
    for b in range(1, nbk):
        if inq[b] and not used_q[b]:
            m += 1
    lone_q = np.empty(m, np.int64)
    m = 0
    for b in range(1, nbk):
        if inq[b] and not used_q[b]:
            lone_q[m] = b - 1
            m += 1
    return pa, pb, group, ng, lone_p, lone_q


@njit(cache=True, nogil=True)
def _run_group_lists(rp, rq, y0, y1, x0, x1, na, nb, cp, cq):
    """:func:`_groups` from the two slices' runs in one call: :func:`_run_groups` with the marks of
    the components ``cp`` of ``na`` below and ``cq`` of ``nb`` above (0-based), its groups listed
    as :func:`_groups` gives them (each side's members in increasing order, the groups in the
    order of their first pair): the members below of group ``g`` are ``af[ast[g]: ast[g + 1]]``,
    those above ``bf[bst[g]: bst[g + 1]]``; and the lone components of each side.  A component
    of a pair is in exactly one group (the groups are connected sets of pairs), so each side's
    members are its paired components in increasing order, placed by their group (a counting sort,
    stable)."""
    inp = np.zeros(na + 1, np.bool_)
    inq = np.zeros(nb + 1, np.bool_)
    for c in cp:
        inp[c + 1] = True
    for c in cq:
        inq[c + 1] = True
    pa, pb, group, ng, lone_p, lone_q = _run_groups(rp, rq, np.int64(y0), np.int64(y1), np.int64(x0), np.int64(x1),
                                                     inp, inq)
    ga = np.full(na, -1, np.int64)
    gb = np.full(nb, -1, np.int64)
    for i in range(pa.shape[0]):
        ga[pa[i]] = group[i]
        gb[pb[i]] = group[i]
    af, ast = _members_by_group(ga, ng)
    bf, bst = _members_by_group(gb, ng)
    return af, ast, bf, bst, lone_p, lone_q


@njit(cache=True, nogil=True)
def _members_by_group(g, ng):
    """The indices ``i`` with ``g[i] >= 0``, by group ``g[i]`` (``0 .. ng - 1``) and in increasing
    order within each: ``(flat, starts)``, group ``k``'s at ``flat[starts[k]: starts[k + 1]]``."""
    starts = np.zeros(ng + 1, np.int64)
    for i in range(g.shape[0]):
        if g[i] >= 0:
            starts[g[i] + 1] += 1
    for k in range(ng):
        starts[k + 1] += starts[k]
    at = starts[:ng].copy()
    flat = np.empty(starts[ng], np.int64)
    for i in range(g.shape[0]):
        if g[i] >= 0:
            flat[at[g[i]]] = i
            at[g[i]] += 1
    return flat, starts


@njit(cache=True, nogil=True)
def _overlap_table(lp, lq, y0, y1, x0, x1, inp, inq, nbk):
    """Which pairs of labels ``a`` of ``lp`` and ``b`` of ``lq`` (both with ``inp[a]``, ``inq[b]``)
    share a pixel of rows ``y0 .. y1 - 1``, columns ``x0 .. x1 - 1``: a table of ``len(inp) *
    nbk`` booleans (``nbk = len(inq)``), pair ``(a, b)`` at ``a * nbk + b``."""
    seen = np.zeros(inp.shape[0] * nbk, np.bool_)
    for y in range(y0, y1):
        for x in range(x0, x1):
            a = np.int64(lp[y, x])
            if a > 0 and inp[a]:
                b = np.int64(lq[y, x])
                if b > 0 and inq[b]:
                    seen[a * nbk + b] = True
    return seen


def _stacks_reference(split_at, path, depth):
    """The section stacks (tuples of pair paths, bottom up) strictly inside pair ``path`` that the
    splits decided so far (``split_at``: pair path -> whether it is split) allow, ``depth`` splits
    left: what :func:`_stack_table` gives filtered (kept as its reference for the tests)."""
    out = []
    if split_at.get(path) is not True:
        out.append(())
    if split_at.get(path) is not False and depth > 0:
        out.extend(a + (path,) + b for a in _stacks_reference(split_at, path + (0,), depth - 1)
                   for b in _stacks_reference(split_at, path + (1,), depth - 1))
    return out


_STACK_TABLES = {}


def _stack_table(depth):
    """Every section stack a sectioned join of ``depth`` splits may get, sorted by its number of
    sections (stable), each as ``(stack, unsplit, order)``: its pair paths bottom up (the pairs
    split), the pairs it leaves unsplit (those it reaches that are not split: the root where it is
    empty, else the halves of its split pairs that are not in it) and its paths by length (a
    section before those made from it).  A stack is allowed where none of its pairs is decided
    unsplit and none of its unsplit pairs decided split: the stacks :func:`_stacks_reference`
    gives, in the same order (filtering keeps the order of a list built by concatenation and
    products), made once per depth rather than at every topology test."""
    got = _STACK_TABLES.get(depth)
    if got is None:
        every = sorted(_stacks_reference({}, (), depth), key=len)
        got = []
        for st in every:
            splits = set(st)
            unsplit = [()] if not st else [p + (i,) for p in st for i in (0, 1) if p + (i,) not in splits]
            got.append((st, tuple(unsplit), tuple(sorted(st, key=len))))
        got = _STACK_TABLES[depth] = tuple(got)
    return got


class _NoTopology(Exception):
    """No stack of sections that a sectioned join can still get keeps the topology (or keeps within
    the caller's area)."""


#: :func:`sectioned_join` gives a join up once its kept pieces' area exceeds ``max_area`` times
#: ``1 + _AREA_MARGIN``: the join's area and theirs are sums of the same faces' areas (the join's
#: over more faces) in other orders, and rounding moves a sum of n positive numbers by less than
#: ``n`` units in the last place (relative), far below this for any mesh.
_AREA_MARGIN = 1e-9


def sectioned_join(ops, k, ga, gb, slices, zs, poly, edges_of, double, caps, triangulation, polygon, grid,
                   topology_first=False, max_area=None, memory=None):
    """Join components ``ga`` of slice ``k`` and ``gb`` of slice ``k + 1`` through intermediate
    sections (see the module docstring).  Returns a :class:`contourmesh.volumes._Bridged` (its
    ``sections`` counts the sections made) or None where no sectioning keeps every rule.

    ``ops`` holds the volume mesher's own pieces that a section join is built from (``Slice``,
    ``simple_join``, ``bridge_plan``, ``bridge_join``, ``band_faces``, ``Bridged``): the mesher
    passes them in (:func:`contourmesh.volumes._section_ops`), so that this module does not import
    the mesher that imports it.  ``poly(kk, c, h)`` and ``edges_of(kk)`` are the mesher's polygons
    and every edge of a slice (as for :func:`contourmesh.volumes._bridge_join`); ``double`` the
    ``(k, c, h)`` of holes lidded from both sides; ``grid = (ox, oy, dx, dy)``; ``polygon`` the
    polygon method for the sections.

    ``topology_first``: compare the Euler characteristic of the stacks of sections as the pieces
    are decided, and give the join up as soon as no stack they still allow keeps it (with
    :data:`GIVE_UP_EARLY`; the same answer, less work where the test fails early).  The mesher asks
    it for a loop of overlaps (a handle forms in the gap), whose sections often cannot keep the
    topology; a fork or a merge rarely fails that test, and there it would only add work.

    ``max_area``: where given, the caller keeps the join only if its area (``float(triangle_areas(V,
    F).sum())``) is at most this; any other join is given up (None: the caller's answer is the
    same).  The finished join is measured before its costlier tests (edges, crossings, topology),
    and the join is given up as soon as the bridged pieces it keeps have more area than that with
    a margin (:data:`_AREA_MARGIN`): each of their faces is a face of the join, the same numbers.

    ``memory``: the build's :class:`SectionSlices` (sections made already, by their pixels), or
    None (every section made here)."""
    A, B = slices[k], slices[k + 1]
    sl = [A.objects[a] for a in ga] + [B.objects[b] for b in gb]
    ny, nx = A.labels.shape
    y0, y1 = max(min(s[0].start for s in sl) - 1, 0), min(max(s[0].stop for s in sl) + 1, ny)
    x0, x1 = max(min(s[1].start for s in sl) - 1, 0), min(max(s[1].stop for s in sl) + 1, nx)
    box = np.s_[y0:y1, x0:x1]
    sampling = (grid[3], grid[2])

    def main_layer(kk, comps):
        dbl = frozenset((c, h) for (k_, c, h) in double if k_ == kk)
        return _Layer(slices[kk], zs[kk], comps, lambda c, h: poly(kk, c, h), lambda: edges_of(kk), main=kk,
                      double=dbl, box=box)

    lo, hi = main_layer(k, ga), main_layer(k + 1, gb)
    masks = {}  # id(layer) -> (layer, its mask in the box) (the sections' regions, the topology test)
    sdfs = {}  # id(layer) -> (layer, the signed distance of its mask): a layer next to two sections

    def mask_of(L):
        if id(L) not in masks:
            masks[id(L)] = (L, label_mask(L.S.labels[box], L.S.n, L.comps))
        return masks[id(L)][1]

    # Every layer agrees with lo and hi where those two agree (inside both: inside all, a section
    # being where the mean of its two ends' signed distances is negative; outside both: outside
    # all), so a section's sign is decided by distances only where lo and hi differ: the signed
    # distances are measured there alone (_sdf_wanted: the same numbers there, in raster order),
    # and a section is lo's mask with those pixels set by the sign of the sum (the same mask as
    # the sum's sign over the box, where the other pixels' distances were -inf or +inf as lo's).
    differ = []

    def sdf_of(L):
        if id(L) not in sdfs:
            sdfs[id(L)] = (L, _sdf_wanted(mask_of(L), sampling, *where_differ()))
        return sdfs[id(L)][1]

    def where_differ():
        """The pixels where lo and hi differ (a mask of the box) and their flat indices."""
        if not differ:
            d = mask_of(lo) ^ mask_of(hi)
            differ.append((d, np.flatnonzero(d)))
        return differ[0]

    # The sections a join may get form a tree: pair () is (lo, hi), its section splits it into the
    # pairs path + (0,) (below) and path + (1,) (above).  The pieces decide which pairs are split
    # (a pair whose pieces do not all build is split, where depth is left), and the result must
    # keep the topology (the test below the split), its Euler characteristic first; so once no
    # stack of sections that the splits decided so far still allow keeps that number, the join is
    # given up without building more pieces.  (A section is the mid_section of its pair's two ends,
    # the same mask whether or not its layer is made yet; a stack with an empty section cannot be
    # built either: the join is given up only where it would come to nothing anyway.)
    early = GIVE_UP_EARLY and topology_first
    kept_area = [0.0]  # the area of the bridged pieces decided so far (each is in the join, if any)

    def keep(pieces):
        if max_area is None:
            return
        for p_ in pieces:
            if p_[0] == "bridged":
                kept_area[0] += float(triangle_areas(p_[3].V, p_[3].F).sum())
        if kept_area[0] > max_area * (1.0 + _AREA_MARGIN):
            raise _NoTopology  # (no join within max_area: given up like one without the topology)
    split_at = {(): True}  # pair path -> whether it is split, where decided
    node_sdf = {}  # node ("lo", "hi" or a pair path: that pair's section) -> its signed distance
    layer_at = {"lo": lo, "hi": hi}  # node -> its layer, where made
    euler_kept = {}  # sections (pair paths, bottom up) -> whether lo / them / hi keeps the Euler number
    euler_of = {}  # node, or pair of nodes (their overlap) -> _euler2 of its mask

    def ends(path):
        if not path:
            return "lo", "hi"
        a, b = ends(path[:-1])
        return (a, path[:-1]) if path[-1] == 0 else (path[:-1], b)

    def sdf_at(node):
        if node in layer_at:
            return sdf_of(layer_at[node])
        if node not in node_sdf:
            node_sdf[node] = _sdf_wanted(section_mask(node), sampling, *where_differ())
        return node_sdf[node]

    section_masks = {}  # pair path -> its section's mask, made once (the same array whenever asked)
    filled = {}  # pair path -> whether its section's mask has a pixel

    def section_mask(path):
        got = section_masks.get(path)
        if got is None:
            a, b = ends(path)
            below, above = sdf_at(a), sdf_at(b)
            got = mask_of(lo).copy()
            got.ravel()[where_differ()[1]] = below + above < 0
            section_masks[path] = got
        return got

    def has_pixel(path, m):
        """Whether ``m``, pair ``path``'s section mask (as made or as its layer keeps it: the same
        array), has a pixel; asked once per path."""
        got = filled.get(path)
        if got is None:
            got = filled[path] = bool(m.any())
        return got

    def stack_euler(nodes, ms):
        """The Euler characteristic of the stack of ``nodes`` (masks ``ms``), from its layers'
        and their overlaps' (see :func:`_euler2`): most stacks that do not keep the topology
        change it, and it costs a few array passes where stack_invariants labels the stack."""
        for t, u in enumerate(nodes):
            if u not in euler_of:
                euler_of[u] = _euler2(ms[t])
            if t and (nodes[t - 1], u) not in euler_of:
                euler_of[nodes[t - 1], u] = _euler2(ms[t - 1] & ms[t])
        return sum(euler_of[u] for u in nodes) - sum(euler_of[u, v] for u, v in zip(nodes[:-1], nodes[1:]))

    def may_keep_topology():
        # the stacks the splits decided so far allow (_stack_table: every stack with the splits it
        # needs, the fewest sections first: the least to make)
        for st, unsplit, order in _stack_table(MAX_DEPTH):
            if any(split_at.get(p) is False for p in st) or any(split_at.get(p) is True for p in unsplit):
                continue
            if st not in euler_kept:
                ms = {}
                for p in order:  # (a section before those made from it)
                    ms[p] = mask_of(layer_at[p]) if p in layer_at else section_mask(p)
                    if not has_pixel(p, ms[p]):
                        break
                euler_kept[st] = all(p in ms and has_pixel(p, ms[p]) for p in st) and \
                    stack_euler(("lo",) + st + ("hi",), [mask_of(lo)] + [ms[p] for p in st] + [mask_of(hi)]) == \
                    stack_euler(("lo", "hi"), [mask_of(lo), mask_of(hi)])
            if euler_kept[st]:
                return True
        return False

    def decide(path, split):
        split_at[path] = split
        if early and not may_keep_topology():
            raise _NoTopology

    made = {}  # pair path -> its section's layer (None where the section is empty), made once

    def section_at(path, P, Q):
        """Pair ``path``'s section between its layers P and Q, as a layer (None where empty)."""
        if path not in made:
            # mid_section of the two layers' regions (a section's region is its mask)
            M, m = _section_layer(ops, A.labels.shape, box, 0.5 * (P.z + Q.z), polygon, grid, section_mask(path),
                                  memory)
            made[path] = M
            if M is not None:
                masks[id(M)] = (M, m)
                layer_at[path] = M
                if path in node_sdf:
                    sdfs[id(M)] = (M, node_sdf.pop(path))
        return made[path]

    kinds_at = {}  # pair path -> _piece_kinds of its two layers, made once

    def kinds_of(path, P, Q):
        if path not in kinds_at:
            kinds_at[path] = _pair_kinds(ops, P, Q)
        return kinds_at[path]

    def doomed(P, Q, depth, path):
        """Whether pair ``path`` (layers P and Q, ``depth`` splits left) surely gives None, from the
        labels alone: its pieces are None whatever is built (:func:`_piece_kinds`), and it has no
        splits left, an empty section, or a half that is doomed in turn.  Then :func:`split` of it
        gives None too (or the join is given up before it), so nothing need be built for it."""
        if kinds_of(path, P, Q) is not None:
            return False
        if depth == 0:
            return True
        M = section_at(path, P, Q)
        return M is None or doomed(P, M, depth - 1, path + (0,)) or doomed(M, Q, depth - 1, path + (1,))

    def split(P, Q, depth, first, path):
        """The layers strictly between P and Q (pair ``path``) and the pieces joining them, or None."""
        pieces = None if first else _pieces(ops, P, Q, caps, triangulation, grid, kinds_of(path, P, Q))
        if pieces is not None:
            decide(path, False)
            keep(pieces)
            return [], pieces
        if depth == 0:
            return None
        if not first:
            decide(path, True)
        M = section_at(path, P, Q)
        if M is None:
            return None
        # the pair above is joined after the one below, which it needs (the bridges taken in M);
        # where its labels alone rule it out, the join gives None and the pieces below are not
        # built in vain
        if DOOMED_FIRST and doomed(M, Q, depth - 1, path + (1,)):
            return None
        below = split(P, M, depth - 1, False, path + (0,))
        if below is None:
            return None
        M.taken = [(p_, q_) for piece in below[1] if piece[0] == "bridged" and piece[2] is M
                   for plane, p_, q_ in piece[3].segments if plane == 1]
        above = split(M, Q, depth - 1, False, path + (1,))
        if above is None:
            return None
        return below[0] + [M] + above[0], below[1] + above[1]

    try:
        if early and not may_keep_topology():
            return None
        got = split(lo, hi, MAX_DEPTH, True, ())
    except _NoTopology:
        return None
    finally:
        # the nested functions that call themselves or each other (split, ends, and sdf_at with
        # section_mask) hold their own closure cells: reference cycles that would leave
        # the join's sections, masks and layers to the cyclic garbage collector; clearing the cells
        # frees them by reference counting when the join returns
        split = ends = sdf_at = doomed = None
    if got is None:
        return None
    layers, pieces = got
    # the join (None where it is no valid piece of mesh or has more area than max_area), and the
    # sections must keep the topology of the join's voxel object: each of the three tests gives
    # None alone, so the cheapest come first (the area before the costlier tests, in assembly)
    out = _assemble_pieces(ops, pieces, layers, triangulation, max_area)
    if out is None or stack_invariants([mask_of(lo), mask_of(hi)]) != \
            stack_invariants([mask_of(L) for L in [lo] + layers + [hi]]):
        return None
    return out


class JoinMemory:
    """The last few sectioned joins of one build of the bridged joins, with what each read from the
    slices' planes, so that a join asked for again gets its answer without being built again.

    The bridged joins' pass restarts after a join falls back to exact, and a sectioned join near
    that slice is tried again (the mesher's key of the join names the crack rings near it, which
    changed; on the lobster about one sectioned join in seven is such a repeat).  A sectioned join
    (:func:`sectioned_join`) reads of the planes of its two slices only the labels (which do not
    change while the joins are built), the rings of its own components (``poly``: of the
    components ``ga`` and ``gb``, outer rings and holes), which of their holes are lidded from both
    sides (``double``) and, in its pieces that bridge rings of a slice, that slice's edges
    (``edges_of``) as obstacles of the bridges.  Those bridges join vertices of the components'
    rings, so they lie in the box of those rings, and an obstacle edge enters a bridge's test only
    where its box meets the bridge's (:func:`contourmesh.bands.bridges._clear`): the edges whose box
    meets the box of the components' rings are all that the join can read of a plane.  A join asked
    for again with the same components, bound and settings, the same rings (bytes), the same
    lidded holes and, in each plane whose edges it read, the same such edges (bytes, in order) is
    the same join: its answer is handed back (the same object; the mesher does not change a built
    join).  :data:`JOIN_MEMORY` joins are kept."""

    def __init__(self, keep=None):
        self.keep = JOIN_MEMORY if keep is None else keep
        self.seen = {}  # key -> (answer, {plane: edges as read}, {plane: near edges' bytes, when made})
        self.sections = SectionSlices()  # (the sections' slices the joins built here made)

    def join(self, ops, k, ga, gb, slices, zs, poly, edges_of, double, caps, triangulation, polygon, grid,
             topology_first=False, max_area=None):
        """:func:`sectioned_join` with these arguments (the same answer), from memory where it can."""
        ga, gb = list(ga), list(gb)
        rings = []
        for kk, comps in ((k, ga), (k + 1, gb)):
            for c in comps:
                for h in range(-1, len(slices[kk].holes[c])):
                    r = np.asarray(poly(kk, c, h))
                    rings.append((r.shape, r.dtype.str, r.tobytes()))
        dbl = tuple(sorted(d for d in double if (d[0] == k and d[1] in ga) or (d[0] == k + 1 and d[1] in gb)))
        key = (k, tuple(ga), tuple(gb), topology_first, max_area, tuple(rings), dbl, caps, triangulation, polygon,
               tuple(float(g) for g in grid), tuple(float(z) for z in zs[k:k + 2]))
        got = self.seen.get(key)
        if got is not None:
            answer, read, near = got
            if all(self._same_edges(kk, read, near, edges_of(kk), poly, slices, ga if kk == k else gb)
                   for kk in read):
                self.seen[key] = self.seen.pop(key)  # (the most recent now)
                return answer
        planes = {}

        def edges_read(kk):
            e = planes[kk] = edges_of(kk)
            return e

        answer = sectioned_join(ops, k, ga, gb, slices, zs, poly, edges_read, double, caps, triangulation, polygon,
                                grid, topology_first=topology_first, max_area=max_area, memory=self.sections)
        self.seen.pop(key, None)
        while len(self.seen) >= self.keep > 0:
            del self.seen[next(iter(self.seen))]  # the oldest (dicts keep insertion order)
        if self.keep > 0:
            self.seen[key] = (answer, planes, {})
        return answer

    @staticmethod
    def _same_edges(kk, read, near, now, poly, slices, comps):
        """Whether plane ``kk``'s edges ``now`` agree with those the kept join read (``read[kk]``)
        wherever the join can see them: the same arrays, or the same edges meeting the box of the
        components' rings (``near`` keeps the kept edges' share, once made)."""
        then = read[kk]
        if now is then:
            return True
        rs = [np.asarray(poly(kk, c, h), dtype=np.float64).reshape(-1, 2)
              for c in comps for h in range(-1, len(slices[kk].holes[c]))]
        xy = np.concatenate(rs)
        box = xy.min(axis=0), xy.max(axis=0)
        if kk not in near:
            near[kk] = _edges_meeting(then, box)
        return _edges_meeting(now, box) == near[kk]


def _edges_meeting(edges, box):
    """The bytes of the edges (``(a, b)``: two ``(e, 2)`` arrays of end points) whose box meets the
    closed box ``(lo, hi)``, in order, and of their end points' dtype and shape."""
    a, b = (np.asarray(e) for e in edges)
    (x0, y0), (x1, y1) = box
    keep = ((np.maximum(a[:, 0], b[:, 0]) >= x0) & (np.minimum(a[:, 0], b[:, 0]) <= x1)
            & (np.maximum(a[:, 1], b[:, 1]) >= y0) & (np.minimum(a[:, 1], b[:, 1]) <= y1))
    return a.dtype.str, b.dtype.str, a[keep].tobytes(), b[keep].tobytes()


#: How many sectioned joins a :class:`JoinMemory` keeps (the repeats of the lobster's come within
#: a dozen other sectioned joins but for a few).
JOIN_MEMORY = 32


def _pieces(ops, P: _Layer, Q: _Layer, caps, triangulation, grid, kinds=MISSING):
    """The joins between two adjacent layers, each ``("band", P, Q, a, b, matched)``, ``("bridged",
    P, Q, built)`` or ``("cap", layer, c, upward)``; None where some group is neither a band join
    nor a bridged join that builds, or where a slice's component would have no partner.

    ``kinds``: :func:`_piece_kinds` of the two layers, where the caller has it (the same)."""
    _bridge_join = ops.bridge_join
    if kinds is MISSING:
        kinds = _piece_kinds(ops, P, Q)
    if kinds is None:
        return None
    out, kinds = list(kinds[0]), kinds[1]
    pair = (P, Q)
    zs = np.array([P.z, Q.z])

    def poly(kk, c, h):
        return pair[kk].poly(c, h)

    def edges_of(kk):
        return pair[kk].edges()

    def uncovered(other, comps):
        return keyhole_uncovered(pair[other].S.labels, comps, grid)

    dbl = {(0, c, h) for c, h in P.double} | {(1, c, h) for c, h in Q.double}
    for kind in kinds:
        if kind[0] == "band":
            out.append(kind)
            continue
        _, gp, gq, plan = kind
        b = _bridge_join(0, gp, gq, plan, poly, zs, edges_of, uncovered, triangulation, caps, dbl)
        if b is None:
            return None
        out.append(("bridged", P, Q, b, plan))
    return out


def _pair_kinds(ops, P: _Layer, Q: _Layer):
    """:func:`_piece_kinds` of two adjacent layers (the same kinds), from the section's memory where
    the same pair was asked for before.

    A pair's kinds are read from its two slices' labels, runs, boxes and holes, the components of
    each layer and whether each is a slice's layer (the boxes of the two are the join's box, which
    is part of a remembered section's key): a section's layer taken again from the build's memory
    (:class:`SectionSlices`) with the same slice's layer on its other side (slice and components)
    has the same kinds, the layers' own places in them aside.  They are kept with the section's
    slice (its layer's ``kinds``) without the layers (:func:`_unbound_kinds`) and bound to the two
    layers asked for (:func:`_bound_kinds`).  (On the lobster about one pair in seven is taken so;
    a pair of two sections, fewer, is made anew: its kinds kept would keep the other section's
    slice, label image and all, past its time in the memory.)"""
    if Q.kinds is not None and P.main is not None:
        memo, other, key = Q.kinds, P.S, (0, id(P.S), tuple(P.comps))
    elif P.kinds is not None and Q.main is not None:
        memo, other, key = P.kinds, Q.S, (1, id(Q.S), tuple(Q.comps))
    else:  # (two sections: not kept, so that a section's memory holds no other section's slice)
        return _piece_kinds(ops, P, Q)
    got = memo.get(key)
    if got is not None and got[0] is other:  # (the slice itself kept with them: no other can take its id)
        return _bound_kinds(got[1], P, Q)
    kinds = _piece_kinds(ops, P, Q)
    memo[key] = (other, _unbound_kinds(kinds))
    return kinds


def _unbound_kinds(kinds):
    """:func:`_piece_kinds`' answer without its layers (kept by a section without making a cycle of
    references through its layer): None, or ``(caps, kinds)`` with each cap ``(c, upward)`` and
    each band ``("band", a, b, matched)``."""
    if kinds is None:
        return None
    caps, ks = kinds
    return ([(c, up) for _, _, c, up in caps],
            [("band",) + k[3:] if k[0] == "band" else k for k in ks])


def _bound_kinds(kinds, P, Q):
    """:func:`_unbound_kinds`' form bound to the layers ``P`` (below) and ``Q`` (above) again: the
    caps upward are P's, the others Q's."""
    if kinds is None:
        return None
    caps, ks = kinds
    return ([("cap", P if up else Q, c, up) for c, up in caps],
            [("band", P, Q) + k[1:] if k[0] == "band" else k for k in ks])


def _piece_kinds(ops, P: _Layer, Q: _Layer):
    """What :func:`_pieces` learns of two adjacent layers before it builds a bridged join, from
    their labels alone: ``(caps, kinds)``, the caps of the components without a partner and per
    group ``("band", P, Q, a, b, matched)`` or ``("plan", gp, gq, plan)``; None where the pieces
    are None whatever the bridged joins build (a slice's component without a partner, a group
    that is neither a band join nor has a bridge plan, a keyhole in a capped component)."""
    _bridge_plan, _simple_join = ops.bridge_plan, ops.simple_join

    groups, lone_p, lone_q = _groups(P, Q)
    if (P.main is not None and lone_p) or (Q.main is not None and lone_q):
        return None  # a slice's component without a partner in the section
    out = [("cap", P, c, True) for c in lone_p] + [("cap", Q, c, False) for c in lone_q]
    capped_p, capped_q = set(lone_p), set(lone_q)
    # every group's kind first (cheap), the bridged joins after (_pieces): a group that is neither a
    # band nor a bridged join gives None whatever the others build, and each build depends only on
    # its own group and the two layers, so none is built in vain (the same answer as group by group)
    kinds = []
    for gp, gq in groups:
        if len(gp) == 1 and len(gq) == 1:
            matched = _simple_join(P.S, Q.S, gp[0], gq[0])
            if matched is not None:
                kinds.append(("band", P, Q, gp[0], gq[0], matched))
                continue
        plan = _bridge_plan(P.S, Q.S, gp, gq)
        if plan is None:
            return None
        # a keyhole lies in its component's plane: a cap there would meet the fold along it
        if any(a in capped_p for a, _ in plan[3]) or any(b in capped_q for b, _ in plan[4]):
            return None
        kinds.append(("plan", gp, gq, plan))
    return out, kinds


def _assemble_pieces(ops, pieces, layers, triangulation, max_area=None):
    """One :class:`contourmesh.volumes._Bridged` of all pieces: the slices' rings first (in order of
    first use), then the sections' rings and the pieces' own vertices; None where the result is
    not a valid piece of mesh, or (``max_area`` given) where its area, ``float(triangle_areas(V,
    F).sum())`` of the ``V`` and ``F`` it would have, exceeds ``max_area``."""
    _band_faces, _Bridged = ops.band_faces, ops.Bridged

    used = []  # ring keys (layer, c, h) in order of first use
    seen = set()

    def use(L, c, h):
        key = (id(L), c, h)
        if key not in seen:
            seen.add(key)
            used.append((L, c, h))

    for p in pieces:
        if p[0] == "band":
            _, P, Q, a, b, matched = p
            use(P, a, -1)
            use(Q, b, -1)
            for ha, hb in matched:
                use(P, a, ha)
                use(Q, b, hb)
        elif p[0] == "bridged":
            _, P, Q, b, _plan = p
            for (kk, c, h), _off in b.rings:
                use((P, Q)[kk], c, h)
        else:
            _, L, c, _up = p
            use(L, c, -1)
            for h in range(len(L.S.holes[c])):
                use(L, c, h)
    pts, rings, ids_of, n = [], [], {}, 0
    for main in (True, False):
        for L, c, h in used:
            if (L.main is not None) != main:
                continue
            xy = np.asarray(L.poly(c, h), dtype=np.float64)
            xyz = np.empty((len(xy), 3), dtype=np.float64)  # (np.c_[xy, z], without np.c_'s cost)
            xyz[:, :2] = xy
            xyz[:, 2] = L.z
            pts.append(xyz)
            if main:
                rings.append(((L.main, c, h), n))
            ids_of[id(L), c, h] = n + np.arange(len(xy))
            n += len(xy)
        if main:
            n_ring = n
    # the bands and caps read only rings' vertices, all made above (the bridged pieces' own
    # vertices come after them)
    V_rings = np.concatenate(pts) if pts else np.zeros((0, 3))
    faces, replaced, nb, segments = [], 0, 0, []
    least_area = 0  # the pieces' bands made by the least-area rule
    in_section = {}  # id(section) -> its bridges' segments, per piece
    keyholes, capped = set(), set()  # (id(section), c)
    for p in pieces:
        if p[0] == "band":
            _, P, Q, a, b, matched = p
            for ha, hb in [(-1, -1)] + list(matched):
                lo, hi = ids_of[id(P), a, ha], ids_of[id(Q), b, hb]
                f, r = _band_faces(V_rings[lo], V_rings[hi], triangulation)
                faces.append(np.concatenate([lo, hi])[f])
                replaced += r
        elif p[0] == "bridged":
            _, P, Q, b, plan = p
            pair = (P, Q)
            ids = np.empty(len(b.V), dtype=np.int64)
            for (kk, c, h), off in b.rings:
                r = ids_of[id(pair[kk]), c, h]
                ids[off: off + len(r)] = r
            extra = b.V[b.n_ring:]
            ids[b.n_ring:] = n + np.arange(len(extra))
            pts.append(extra)
            n += len(extra)
            faces.append(ids[b.F])
            replaced += b.replaced
            least_area += b.least_area
            nb += b.bridges
            for plane, p_, q_ in b.segments:
                L = pair[plane]
                if L.main is not None:
                    segments.append((L.main, p_, q_))
                else:
                    in_section.setdefault(id(L), []).append((id(b), p_, q_))
            keyholes.update((id(P), a) for a, _ in plan[3] if P.main is None)
            keyholes.update((id(Q), c) for c, _ in plan[4] if Q.main is None)
        else:
            _, L, c, up = p
            capped.add((id(L), c))
            rs = [ids_of[id(L), c, -1]] + [ids_of[id(L), c, h] for h in range(len(L.S.holes[c]))]
            try:
                f = cap_faces(V_rings[rs[0]][:, :2], [V_rings[r][:, :2] for r in rs[1:]], upward=up)
            except ValueError:
                return None
            if len(f) == 0:
                return None
            faces.append(np.concatenate(rs)[f])
    if keyholes & capped:  # a keyhole of a section's component and a cap of it, in one plane
        return None
    for segs in in_section.values():  # bridges of the two joins that meet in a section
        for i, (owner, p_, q_) in enumerate(segs):
            other = [s for s in segs[i + 1:] if s[0] != owner]
            if other and segments_cross(p_, q_, np.array([s[1] for s in other]),
                                        np.array([s[2] for s in other])).any():
                return None
    V = np.concatenate(pts)
    F = np.concatenate(faces)
    if max_area is not None and not float(triangle_areas(V, F).sum()) <= max_area:
        return None
    if (F[:, 0] == F[:, 1]).any() or (F[:, 1] == F[:, 2]).any() or (F[:, 0] == F[:, 2]).any():
        return None
    # each new edge used twice (once each way), each edge of a slice's ring once
    spans = [(off, len(ids_of[id(L), c, h]))
             for (_key, off), (L, c, h) in zip(rings, [u for u in used if u[0].main is not None])]
    if not _edges_close(F, len(V), spans):
        return None
    if any_intersecting(V, F):
        return None
    out = _Bridged(V, F, rings, n_ring, replaced, nb, segments)
    out.sections = len(layers)
    out.least_area = least_area
    return out


def _edges_close(F, nv, spans) -> bool:
    """The faces ``F`` (of ``nv`` vertices) use every edge at most twice and never twice the same
    way, and the edges they use once are exactly those of the rings ``spans`` (``(offset, size)``:
    vertices ``offset .. offset + size - 1`` in order round the ring).  Each edge is one integer
    (``u * nv + v``; undirected ``min * nv + max``), so the rows are compared as numbers, in one
    compiled pass (:func:`_edges_close_kernel`; :func:`_edges_close_numpy` is the same test with
    numpy's sorts, its reference)."""
    F = np.asarray(F)
    if len(F) == 0:
        return _edges_close_numpy(F, nv, spans)  # (no face: numpy's answer, as it always was)
    sp = np.array(spans, dtype=np.int64).reshape(-1, 2)
    return bool(_edges_close_kernel(np.ascontiguousarray(F, dtype=np.int64), np.int64(nv), sp))


@njit(cache=True, nogil=True)
def _edges_close_kernel(F, nv, spans):
    """:func:`_edges_close` of int64 faces ``F`` (at least one) and rings ``spans`` (``(offset,
    size)`` rows), in one sort: each edge's key is its undirected key ``min * nv + max`` times two,
    plus one where it runs from the larger end, so that the sorted keys hold each undirected edge's
    uses side by side.  A run of more than two uses, or of two the same way, fails (what the
    directed keys' repeats and the undirected counts tell); the runs of one use, in order, must be
    the rings' keys, sorted and without repeats (a ring of one or two vertices repeats its keys).
    The same verdicts as the sorts of directed and undirected keys apart (half the sorting)."""
    m = F.shape[0]
    k = np.empty(3 * m, np.int64)
    for i in range(m):
        for j in range(3):
            a, b = F[i, j], F[i, (j + 1) % 3]
            k[3 * i + j] = 2 * (a * nv + b) if a < b else 2 * (b * nv + a) + 1
    k.sort()
    nr = 0
    for r in range(spans.shape[0]):
        nr += spans[r, 1]
    ring = np.empty(nr, np.int64)
    t = 0
    for r in range(spans.shape[0]):
        off, n = spans[r, 0], spans[r, 1]
        for i in range(n):
            a, b = off + i, off + (i + 1) % n
            ring[t] = min(a, b) * nv + max(a, b)
            t += 1
    ring.sort()
    # the once-used undirected keys, in order, against the rings' distinct keys, in order
    j = 0  # next distinct ring key
    i = 0
    while i < 3 * m:
        u = k[i] >> 1
        e = i + 1
        while e < 3 * m and (k[e] >> 1) == u:
            e += 1
        if e - i > 2 or (e - i == 2 and k[i] == k[i + 1]):
            return False
        if e - i == 1:
            if j >= nr or ring[j] != u:
                return False
            while j < nr and ring[j] == u:
                j += 1
        i = e
    return j == nr


def _edges_close_numpy(F, nv, spans) -> bool:
    """:func:`_edges_close` with numpy's sorts and ``np.unique`` (the form it had): the reference."""
    nv = np.int64(nv)
    d = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]).astype(np.int64, copy=False)
    directed = np.sort(d[:, 0] * nv + d[:, 1])
    und, cnt = np.unique(np.minimum(d[:, 0], d[:, 1]) * nv + np.maximum(d[:, 0], d[:, 1]), return_counts=True)
    if (directed[1:] == directed[:-1]).any() or cnt.max() > 2:
        return False
    ring_keys = [np.zeros(0, dtype=np.int64)]
    for off, m in spans:
        a, b = off + np.arange(m, dtype=np.int64), off + (np.arange(m, dtype=np.int64) + 1) % m
        ring_keys.append(np.minimum(a, b) * nv + np.maximum(a, b))
    return bool(np.array_equal(und[cnt == 1], np.unique(np.concatenate(ring_keys))))
