"""The contours route: real-valued contour stacks meshed between their own drawn rings.

A contour file holds the rings a planner drew, section by section, often several per section,
with holes and structures that fork and merge.  The volume mesher
(:func:`contourmesh.volumes.volume_to_mesh`) knows how to join such sections (bands, bridged
joins for forks, merges and holes that open, lids, caps, and exact joins where a handle forms),
but it works on pixels.  This route uses a raster only for the **topology**:

1. the stack is rasterized even-odd (:func:`contourmesh.rasterize.rasterize_stack`, pixel as on
   the raster route); the raster's components, holes and overlaps between consecutive sections
   decide which component joins which, and how.  A drawn ring that holds no pixel centre (a sliver,
   a speck, a vessel hole of a square millimetre) is first given pixels of its own (an outer ring
   the pixels around it, a hole pixels cut out of its ring's), so that it takes part in the joins
   like any other ring (:func:`_keep_small_rings`, ``meta["kept_small_rings"]``); the few that
   cannot be given pixels without touching another ring's, or that lie in a hole, stay out of the
   mesh, counted in ``meta["lost_rings"]`` and named in a :class:`~contourmesh.errors.LostContourWarning`;
2. before any join is built, every raster component whose pixels are exactly those of one drawn
   outer ring minus its drawn holes gets that ring as its outer polygon, and each of its raster
   holes the drawn hole ring whose pixels it holds (rings oriented as the mesher wants: outer
   rings counter-clockwise, holes clockwise);
3. bands, bridged joins, lids and caps are then made between the drawn rings, so the mesh's
   section at a contour plane is the drawn section.

A component that cannot be matched one to one (two drawn rings that the raster merges, a ring
that touches or crosses itself or another ring, an even-odd fill that disagrees with the nesting of
the rings) keeps its raster polygon (the MLP of its pixels); each
such component is counted in ``meta["unmatched_components"]`` and named in a
:class:`~contourmesh.errors.RasterFallbackWarning`.  Components in exact joins (where a handle
forms between two sections) keep their crack contours, as on the raster route
(``meta["crack_rings"]``).
"""

from __future__ import annotations

import logging
import warnings

import numpy as np

from .bands.caps import _rings_that_meet
from .bands.ends import _DOME_RINGS, _end_profile, _SmoothEnds  # noqa: F401 (the contours route's ends)
from .bands.fidelity import FaithfulBands
from .errors import LostContourWarning, RasterFallbackWarning, warn_external
from .geometry import _fill_evenodd, grid_to_xy, shoelace_area
from .intersect import intersecting_faces
from .rasterize import _physical_rings, rasterize_stack
from .stacks import _nest_section
from .types import ContourStack, Mesh
from .volumes import volume_to_mesh

__all__ = ["mesh_drawn"]

log = logging.getLogger("contourmesh")

#: Meshing attempts: after one whose faces cross, the sections of the crossing faces take the raster's polygons.
_ATTEMPTS = 3


class _Quiet(logging.Filter):
    """Holds back the volume mesher's crossing warning on an attempt that is retried."""

    def filter(self, record):
        return record.levelno < logging.WARNING


def _split_at_repeats(ring: np.ndarray) -> list:
    """A ring that visits a point twice, split there into the rings it is made of (keyholes).

    Planning systems draw a hole as part of its outer ring: around the outer boundary, in along a
    zero-width channel, around the hole the other way, and back out.  Such a ring repeats the
    channel's two ends; cut at each repeated point it falls apart into the outer ring, the hole
    ring and the channel (two points, no area, dropped), whose even-odd fill is the keyhole
    ring's.  Consecutive repeats (a duplicate closing point) are removed first.  Pieces of fewer
    than three points or no area are dropped.
    """
    out, todo = [], [np.asarray(ring, dtype=np.float64)]
    while todo:
        r = todo.pop()
        r = r[np.any(r != np.roll(r, 1, axis=0), axis=1)] if len(r) > 1 else r
        if len(r) < 3:
            continue
        o = np.lexsort((r[:, 1], r[:, 0]))
        if not (r[o[1:]] == r[o[:-1]]).all(axis=1).any():  # no point visited twice (the common case)
            if shoelace_area(r) != 0.0:
                out.append(r)
            continue
        _, inv, cnt = np.unique(r, axis=0, return_inverse=True, return_counts=True)
        inv = inv.reshape(-1)
        dup = np.flatnonzero(cnt[inv] > 1)
        if not len(dup):
            if shoelace_area(r) != 0.0:
                out.append(r)
            continue
        i = int(dup[0])
        j = i + 1 + int(np.flatnonzero(inv[i + 1:] == inv[i])[0])
        todo += [r[i:j], np.concatenate([r[j:], r[:i]])]
    return out


def _fill(rings, x0, y0, pixel, shape_yx, box):
    """Even-odd fill of ``rings`` on the raster grid, within ``box = (j0, j1, i0, i1)``: a bool array of
    the box's shape (pixel ``[j, i]`` of the box is grid pixel ``[j0 + j, i0 + i]``)."""
    j0, j1, i0, i1 = box
    out = np.zeros((j1 - j0, i1 - i0), dtype=bool)
    xy = np.concatenate(rings)
    starts = np.zeros(len(rings) + 1, dtype=np.int64)
    starts[1:] = np.cumsum([len(r) for r in rings])
    _fill_evenodd(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]), starts,
                  x0 + i0 * pixel, y0 + j0 * pixel, pixel, out)
    return out


def _ring_box(ring, raster, shape):
    """The raster box ``(j0, j1, i0, i1)`` around ``ring``, a pixel of margin."""
    x0, y0, _ = raster.origin
    p = raster.spacing[0]
    i0 = max(int(np.floor((ring[:, 0].min() - x0) / p)) - 1, 0)
    i1 = min(int(np.ceil((ring[:, 0].max() - x0) / p)) + 2, shape[1])
    j0 = max(int(np.floor((ring[:, 1].min() - y0) / p)) - 1, 0)
    j1 = min(int(np.ceil((ring[:, 1].max() - y0) / p)) + 2, shape[0])
    return j0, j1, i0, i1


class _RingFills:
    """The even-odd fills of each section's drawn rings on one raster's grid, each made once (the
    split check, the sliver joining and the matching all look at them)."""

    _cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)

    def __init__(self, rings, raster):
        self.rings, self.raster = rings, raster
        self.shape = raster.volume.shape[1:]
        self.x0, self.y0 = raster.origin[0], raster.origin[1]
        self.p = raster.spacing[0]
        self._fills: dict = {}
        self._pieces: dict = {}

    def holes_of(self, k, i) -> list:
        return [j for j, q in enumerate(self.rings[k][1]) if q == i]

    def outer(self, k, i):
        """``(box, pixels)``: the fill of outer ring ``i`` of section ``k`` minus its drawn holes."""
        key = ("o", k, i)
        if key not in self._fills:
            rs = self.rings[k][0]
            box = _ring_box(rs[i], self.raster, self.shape)
            self._fills[key] = (box, _fill([rs[i]] + [rs[j] for j in self.holes_of(k, i)], self.x0, self.y0,
                                           self.p, self.shape, box))
        return self._fills[key]

    def ring(self, k, j):
        """``(box, pixels)``: the fill of ring ``j`` of section ``k`` alone."""
        key = ("r", k, j)
        if key not in self._fills:
            rs = self.rings[k][0]
            box = _ring_box(rs[j], self.raster, self.shape)
            self._fills[key] = (box, _fill([rs[j]], self.x0, self.y0, self.p, self.shape, box))
        return self._fills[key]

    def pieces(self, k, i) -> int:
        """The 4-connected pieces of :meth:`outer`."""
        from scipy import ndimage

        key = (k, i)
        if key not in self._pieces:
            self._pieces[key] = int(ndimage.label(self.outer(k, i)[1], structure=self._cross)[1])
        return self._pieces[key]


def _edge_samples(ring, raster, box):
    """The pixel indices ``(i, j)`` in ``box`` of points along the ring's edges, an eighth pixel apart
    (consecutive samples are in the same or in neighbouring pixels)."""
    x0, y0, _ = raster.origin
    p = raster.spacing[0]
    a, b = ring, np.roll(ring, -1, axis=0)
    n = np.maximum(np.ceil(np.hypot(*(b - a).T) / (p / 8)).astype(np.int64), 1)
    t = np.concatenate([np.arange(k) / k for k in n])
    seg = np.repeat(np.arange(len(a)), n)
    pts = a[seg] + (b[seg] - a[seg]) * t[:, None]
    return np.rint((pts[:, 0] - x0) / p).astype(np.int64) - box[2], np.rint((pts[:, 1] - y0) / p).astype(np.int64) - box[0]


def _mark(ii, jj, box) -> np.ndarray:
    j0, j1, i0, i1 = box
    out = np.zeros((j1 - j0, i1 - i0), dtype=bool)
    ok = (ii >= 0) & (ii < out.shape[1]) & (jj >= 0) & (jj < out.shape[0])
    out[jj[ok], ii[ok]] = True
    return out


def _edge_pixels(ring, raster, box) -> np.ndarray:
    """The pixels of ``box`` that the ring's edges pass through (the edges sampled every eighth pixel)."""
    return _mark(*_edge_samples(ring, raster, box), box)


def _connect_split_rings(raster, rings, fills=None) -> dict:
    """Where the raster cuts a drawn outer ring (minus its holes) into several 4-connected pieces (a
    sliver thinner than a pixel, as at the end of a tilted tube), the pixels its edges pass through
    join them, so that the raster keeps the ring one component and its joins are decided for it.
    Only where that makes one piece and touches no other ring's pixels.  Edits ``raster.volume``
    in place; returns ``{(section, ring): (box, pixels)}``, the pixels each such ring now owns."""
    from scipy import ndimage

    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
    x0, y0, _ = raster.origin
    p = raster.spacing[0]
    shape = raster.volume.shape[1:]
    fills = fills or _RingFills(rings, raster)
    grown = {}
    for k, (rs, parents) in enumerate(rings):
        for i, par in enumerate(parents):
            if par != -1:
                continue
            if fills.pieces(k, i) < 2:
                continue
            holes = [rs[j] for j, q in enumerate(parents) if q == i]
            box, pix = fills.outer(k, i)
            inner = _fill(holes, x0, y0, p, shape, box) if holes else np.zeros_like(pix)
            new = pix | (_edge_pixels(rs[i], raster, box) & ~inner)
            if ndimage.label(new, structure=cross)[1] != 1:
                continue
            sl = raster.volume[k, box[0]:box[1], box[2]:box[3]]
            others = sl & ~pix  # other rings' pixels: the new ones must not touch them
            if (ndimage.binary_dilation(new & ~pix, structure=cross) & others).any():
                continue
            sl |= new
            grown[(k, i)] = (box, new)
    return grown


def _loop_pixels(ring, raster, box) -> np.ndarray:
    """The pixels of ``box`` that the ring's edges pass through, made one 4-connected loop (at each
    diagonal step between samples the corner pixel is added), with the pixels that loop encloses:
    for a ring that holds no pixel centre, a set of pixels around it."""
    from scipy import ndimage

    ii, jj = _edge_samples(ring, raster, box)
    return ndimage.binary_fill_holes(_mark(np.r_[ii, ii], np.r_[jj, np.roll(jj, -1)], box))


def _centroid_pixel(ring, raster, box) -> np.ndarray:
    """The pixel of ``box`` that holds the ring's area centroid (its mean point if it has no area)."""
    x, y = ring[:, 0], ring[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cr = x * yn - xn * y
    a = cr.sum() / 2
    c = ring.mean(0) if a == 0 else np.array([((x + xn) * cr).sum(), ((y + yn) * cr).sum()]) / (6 * a)
    x0, y0, _ = raster.origin
    p = raster.spacing[0]
    return _mark(np.array([int(np.rint((c[0] - x0) / p)) - box[2]]), np.array([int(np.rint((c[1] - y0) / p)) - box[0]]), box)


def _inside_another(rs, i) -> bool:
    """Whether ring ``i`` of a section lies inside another of its rings (the test of ``_nest_section``)."""
    from .geometry import points_in_rings

    lo, hi, area = rs[i].min(0), rs[i].max(0), abs(shoelace_area(rs[i]))
    return any(j != i and abs(shoelace_area(q)) > area and (q.min(0) <= lo + 1e-9).all() and (q.max(0) >= hi - 1e-9).all()
               and points_in_rings(rs[i], q).mean() > 0.5 for j, q in enumerate(rs))


def _would_join(volume, k, box, new, solid) -> str | None:
    """Why giving section ``k`` the pixels ``new`` (in ``box``) as a component of their own (``solid``)
    or as a hole of their own (not ``solid``) would join it to more than its own column, or None.

    The regions of the sections above and below (components if ``solid``, background regions, the
    outside and the holes, if not; beyond an end section lies the outside) that the new pixels
    overlap would join it; a small ring is kept where it stands alone, ends a column or links two
    sections of one (a vessel that thins on one section), so each such region must overlap no other
    region of section ``k`` (else the ring would be a branch of a fork or a merge, whose bridged join
    moves the larger ring's volume by far more than the small ring holds), and the regions next to
    the new pixels (with their 8 neighbours) above and below must not already be joined through the
    three sections (else it would close a loop: a handle the drawing does not show)."""
    from scipy import ndimage

    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
    square = np.ones((3, 3), dtype=bool)
    j0, j1, i0, i1 = box
    at = np.zeros(volume.shape[1:], dtype=bool)
    at[j0:j1, i0:i1] = new
    near = np.zeros(volume.shape[1:], dtype=bool)
    near[j0:j1, i0:i1] = ndimage.binary_dilation(new, structure=square)
    labs, off = [], 0
    empty = np.zeros(volume.shape[1:], dtype=bool)
    for q in (k - 1, k, k + 1):  # regions numbered through the three sections (0: none)
        m = volume[q] if 0 <= q < len(volume) else empty
        m = m if solid else ~m
        lab, n = ndimage.label(m, structure=cross if solid else square)
        labs.append(np.where(lab > 0, lab + off, 0))
        off += n
    # the overlaps of consecutive sections' regions, as pairs (u < v)
    pairs = []
    for a, b in ((labs[0], labs[1]), (labs[1], labs[2])):
        both = (a > 0) & (b > 0)
        code = np.unique(a[both].astype(np.int64) * (off + 1) + b[both])
        pairs.append(np.c_[code // (off + 1), code % (off + 1)])
    pairs = np.concatenate(pairs)
    joined = np.unique(np.r_[labs[0][at], labs[2][at]])
    joined = joined[joined > 0]
    if np.isin(joined, pairs.ravel()).any():
        return ("it would branch off a larger ring's column (a fork)" if solid
                else "it would open onto the outside or branch off a larger hole (a fork)")
    parent = np.arange(off + 1)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for u, v in pairs:
        parent[find(u)] = find(v)
    touched = np.unique(np.r_[labs[0][near], labs[2][near]])
    roots = [find(t) for t in touched[touched > 0]]
    if len(set(roots)) < len(roots):
        return "it would join sections that are already joined (a handle)"
    return None


def _keep_small_rings(raster, rings, fills, taken=()) -> tuple[dict, dict, int, list]:
    """Pixels for the drawn rings that hold no pixel centre, so that the raster keeps them and decides
    their joins like any other ring's (the drawn ring then takes the component's or hole's place,
    :class:`_DrawnPolygons`).  Edits ``raster.volume`` in place.

    * An outer ring gets the pixels around it (:func:`_loop_pixels`, less the pixels of its drawn
      holes), or else the pixel of its centroid, where these make one 4-connected piece that touches
      no other pixel of the section (4-neighbours) and, if the ring has holes that hold pixel
      centres, leave exactly those as the piece's holes; and where the ring lies inside no other
      ring (an island in a hole stays out) and it would stand alone, end a column or link two
      sections of one, not branch off another ring's column or close a loop (:func:`_would_join`).
    * A hole gets pixels cut out of its outer ring's component: the pixels around it, or else the
      pixel of its centroid, where these and their 8 neighbours all belong to that outer ring's
      pixels as the raster holds them (so the cut is a hole of its own and the component stays one
      piece), and where the cut would be a cavity, end or link a column of holes, not open onto the
      outside or branch off another hole, nor close a loop (:func:`_would_join`); not in an outer
      ring whose pixels were joined or grown here (``taken``, the kept rings).

    Returns ``(outer, holes, kept, lost)``: ``{(section, ring): (box, pixels)}`` of the outer rings whose
    pixels changed (the kept rings and the outer rings holes were cut from), the same for the holes
    cut, how many rings were kept, and ``[(section, ring, area, why)]`` for the rings that stay out.
    """
    from scipy import ndimage

    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
    square = np.ones((3, 3), dtype=bool)
    outer, holes, kept, lost = {}, {}, 0, []
    kept_rings = set()
    for k, (rs, parents) in enumerate(rings):
        tiny_holes = []
        for i, par in enumerate(parents):
            if par != -1:
                if not fills.ring(k, i)[1].any():
                    tiny_holes.append(i)
                continue
            box, pix = fills.outer(k, i)
            if pix.any():
                continue
            area = abs(shoelace_area(rs[i]))
            if _inside_another(rs, i):
                lost.append((k, i, area, "it lies inside another drawn ring"))
                continue
            own = [j for j in fills.holes_of(k, i) if fills.ring(k, j)[1].any()]
            inner = _fill([rs[j] for j in own], fills.x0, fills.y0, fills.p, fills.shape, box) if own else None
            sl = raster.volume[k, box[0]:box[1], box[2]:box[3]]
            cands = [_loop_pixels(rs[i], raster, box)]
            if inner is None:
                cands.append(_centroid_pixel(rs[i], raster, box))
            else:
                cands[0] &= ~inner
            for new in cands:
                if not new.any() or ndimage.label(new, structure=cross)[1] != 1 \
                        or (ndimage.binary_dilation(new, structure=cross) & sl).any():
                    continue
                if inner is not None:  # the drawn holes must be the piece's holes, one raster hole each
                    gaps = ndimage.binary_fill_holes(new) & ~new
                    if not np.array_equal(gaps, inner) or ndimage.label(gaps, structure=square)[1] != len(own):
                        continue
                why = _would_join(raster.volume, k, box, new, solid=True)
                if why:
                    break
                sl |= new
                outer[(k, i)] = (box, new)
                kept_rings.add((k, i))
                kept += 1
                break
            else:
                why = "its pixels would touch another ring's" if inner is None else "its holes do not fit the pixels around it"
            if (k, i) not in outer:
                lost.append((k, i, area, why))
        for j in tiny_holes:
            area, par = abs(shoelace_area(rs[j])), parents[j]
            if (k, par) in taken or (k, par) in kept_rings:
                lost.append((k, j, area, "a hole that holds no pixel centre, in a ring that was given pixels"))
                continue
            pbox, ppix = outer.get((k, par)) or fills.outer(k, par)
            hbox = _ring_box(rs[j], raster, fills.shape)
            if not (pbox[0] <= hbox[0] and hbox[1] <= pbox[1] and pbox[2] <= hbox[2] and hbox[3] <= pbox[3]):
                lost.append((k, j, area, "a hole that holds no pixel centre and reaches out of its ring's box"))
                continue
            at = (slice(hbox[0] - pbox[0], hbox[1] - pbox[0]), slice(hbox[2] - pbox[2], hbox[3] - pbox[2]))
            sl = raster.volume[k, hbox[0]:hbox[1], hbox[2]:hbox[3]]
            room = ppix[at] & sl  # the outer ring's pixels, as the raster holds them
            for new in (_loop_pixels(rs[j], raster, hbox), _centroid_pixel(rs[j], raster, hbox)):
                if not new.any() or (ndimage.binary_dilation(new, structure=square) & ~room).any():
                    continue
                cut = ppix.copy()
                cut[at] &= ~new
                if ndimage.label(cut, structure=cross)[1] != ndimage.label(ppix, structure=cross)[1]:
                    continue
                why = _would_join(raster.volume, k, hbox, new, solid=False)
                if why:
                    why = f"a hole that holds no pixel centre; {why}"
                    break
                sl &= ~new
                outer[(k, par)] = (pbox, cut)
                holes[(k, j)] = (hbox, new)
                kept += 1
                break
            else:
                why = "a hole that holds no pixel centre, too near its ring's edge or another hole"
            if (k, j) not in holes:
                lost.append((k, j, area, why))
    return outer, holes, kept, lost


class _DrawnPolygons:
    """The hook of :func:`~contourmesh.volumes.volume_to_mesh` that puts the drawn rings in place of the
    raster's polygons (see the module docstring).  Called once, after the joins are decided."""

    def __init__(self, rings, raster, name, avoid=frozenset(), avoid_why="", smooth=False, flat=False, grown=None,
                 curved=False, fills=None, cut=None):
        self.rings = rings  # per section: (oriented rings, parents)
        self.raster = raster
        self.fills = fills or _RingFills(rings, raster)
        self.name = name
        self.avoid = avoid  # sections whose drawn rings made crossing faces: the raster's polygons
        self.avoid_why = avoid_why
        self.unmatched: list[tuple] = []  # (section, z, why)
        self.grown = grown or {}  # (section, ring) -> (box, pixels) of outer rings whose pixels were joined or grown
        self.cut = cut or {}  # (section, ring) -> (box, pixels) of holes cut into the raster (holes thinner than a pixel)
        # every band between drawn rings keeps a volume within the frustum and trapezoid rules
        self.band_guard = FaithfulBands(record=curved)
        # caps="smooth": the ends of band-joined rings close on the profile of their last sections;
        # caps="flat": ends inside the stack (a branch that stops) hold the trapezoid rule's share
        # (with curved bands, whose rings follow the section area, the domes get twice the rings)
        rings = _DOME_RINGS_CURVED if curved else _DOME_RINGS
        self.end_cap = (_SmoothEnds(dome_rings=rings, planar=True) if smooth else _SmoothEnds(interior_only=True, dome_rings=rings)
                        if flat else None)

    def _box(self, ring, shape):
        return _ring_box(ring, self.raster, shape)

    def __call__(self, slices, zs, crack_only, joins) -> dict:
        x0, y0, _ = self.raster.origin
        p = self.raster.spacing[0]
        to_xy_center, to_xy_corner = grid_to_xy(x0, y0, p, p)
        if self.end_cap is not None:
            self.end_cap.attach(slices, zs, joins)
        matched = drawn = unmatched = 0
        for k, s in enumerate(slices):
            if s is None:
                continue
            rings, parents = self.rings[k]
            meets = _rings_that_meet(list(rings))
            owner = {}  # component -> (outer ring, [(hole ring, raster hole)])
            refused = set()  # components that some ring claims but cannot have
            why = {}
            for i, (r, par) in enumerate(zip(rings, parents)):
                if par != -1:
                    continue
                holes = [j for j, q in enumerate(parents) if q == i]
                if (k, i) in self.grown:  # a sliver joined or a small ring kept (_keep_small_rings)
                    box, pix = self.grown[(k, i)]
                else:
                    box, pix = self.fills.outer(k, i)
                assert pix.shape == (box[1] - box[0], box[3] - box[2]) and s.labels.shape == self.fills.shape
                lab = s.labels[box[0]:box[1], box[2]:box[3]][pix]
                if lab.size == 0:
                    continue  # a ring that holds no pixel centre and could not be kept (LostContourWarning)
                comps = np.unique(lab)
                c = int(comps[-1]) - 1
                if comps[0] == 0 or len(comps) != 1:
                    for cc in comps[comps > 0]:
                        refused.add(int(cc) - 1)
                        why[int(cc) - 1] = "the even-odd fill of its rings differs from the rings' nesting" \
                            if comps[0] == 0 else "one drawn ring covers several raster components"
                    continue
                if c in owner:
                    refused.add(c)
                    why[c] = "the raster merges two drawn rings"
                    continue
                sl = s.objects[c]
                # the component is exactly this ring's fill: no other ring's pixels join it
                if int(np.count_nonzero(s.labels[sl] == c + 1)) != lab.size:
                    refused.add(c)
                    why[c] = "the raster merges two drawn rings"
                    continue
                if meets[i] or any(meets[j] for j in holes):
                    refused.add(c)
                    why[c] = "a drawn ring touches or crosses itself or another ring"
                    continue
                hsl, hmasks = s.hole_masks[c]
                fills = {}
                for j in holes:
                    fills[j] = self.cut.get((k, j)) or self.fills.ring(k, j)
                # a hole that holds no pixel centre and was not cut is lost (LostContourWarning): dropped
                holes = [j for j in holes if fills[j][1].any()]
                if len(hmasks) != len(holes):
                    refused.add(c)
                    why[c] = f"{len(holes)} drawn hole(s) but {len(hmasks)} raster hole(s)"
                    continue
                pairs, ok = [], True
                for j in holes:
                    hbox, hp = fills[j]
                    found = []
                    for h, hm in enumerate(hmasks):
                        # the raster hole's pixels in grid coordinates against the drawn hole's fill
                        ys, xs = np.nonzero(hm)
                        ys, xs = ys + hsl[0].start, xs + hsl[1].start
                        inb = (ys >= hbox[0]) & (ys < hbox[1]) & (xs >= hbox[2]) & (xs < hbox[3])
                        if inb.all() and hp.sum() == len(ys) and hp[ys - hbox[0], xs - hbox[2]].all():
                            found.append(h)
                    if len(found) != 1:
                        ok = False
                        break
                    pairs.append((rings[j], found[0]))
                if not ok or len({h for _, h in pairs}) != len(pairs):
                    refused.add(c)
                    why[c] = "its drawn holes do not match the raster's holes one to one"
                    continue
                owner[c] = (r, pairs)
            if k in self.avoid:
                refused.update(range(s.n))
                why.update({c: self.avoid_why for c in range(s.n)})
            s.own = set()  # these keep their drawn rings in exact joins too (volume_to_mesh)
            for c in range(s.n):
                if c in owner and c not in refused:
                    s.own.add(c)
                    r, pairs = owner[c]
                    s.outer[c] = r
                    for hring, h in pairs:
                        s.holes[c][h] = hring
                    matched += 1
                    drawn += 1 + len(pairs)
                    continue
                # no drawn ring of its own: the MLP of its pixels, as on the raster route
                unmatched += 1
                self.unmatched.append((k, float(zs[k]), why.get(c, "no drawn ring matches it")))
                sl = s.objects[c]
                off = np.array([sl[1].start, sl[0].start])
                comp = s.labels[sl] == c + 1
                s.outer[c] = s._polygon(s.crack_outer_c[c], comp, "mlp", to_xy_corner, to_xy_center, off, hole=False)
                hsl, hmasks = s.hole_masks[c]
                s.holes[c] = [s._polygon(hc, hm, "mlp", to_xy_corner, to_xy_center, off, hole=True)
                              for hc, hm in zip(s.crack_holes_c[c], hmasks)]
        if self.unmatched:
            where = "; ".join(f"section {k} (z={z:g}): {w}" for k, z, w in self.unmatched[:5])
            more = f"; and {len(self.unmatched) - 5} more" if len(self.unmatched) > 5 else ""
            warn_external(f"{self.name}: {len(self.unmatched)} component(s) are meshed from the raster's polygons "
                          f"(pixel={p:g}), not from drawn rings: {where}{more}", RasterFallbackWarning)
        return {"drawn_components": matched, "drawn_rings": drawn, "unmatched_components": unmatched}


#: A dome's rings with ``bands="curved"``: each ruled step between two of them falls short of the
#: area profile (0.2 % of a 5 mm ball's volume with 8 rings at dz = 3 mm, half that with 16).
_DOME_RINGS_CURVED = 16


def _curved(m: Mesh, zs, end_slopes, band_faces) -> Mesh:
    """``bands="curved"``: the mesh with the faces of its band joins bent (no face may cross)."""
    from .bands.curved import curved_without_crossings

    V, F, info = curved_without_crossings(m.vertices, m.faces, zs, end_slopes=end_slopes, band_faces=band_faces)
    bent = info["levels"][info["levels"] > 1]
    log.debug("contours route: curved bands, %d section pairs bent (up to %d segments), %d bands on their "
              "area profile, %d pairs without it and %d left ruled because faces crossed", len(bent),
              int(bent.max()) if len(bent) else 1, info["area_bands"], info["plain_pairs"], info["ruled_pairs"])
    meta = dict(m.meta, bands="curved", curved_levels=int(info["levels"].max()) if len(info["levels"]) else 1,
                ruled_pairs=info["ruled_pairs"], plain_pairs=info["plain_pairs"], area_bands=info["area_bands"])
    return Mesh(V, F, P=m.P, meta=meta)


#: Halvings of the default pixel where the raster loses or splits a drawn ring, and the voxel budget for them.
_FINER = 2
_FINER_VOXELS = 2e7


def _raster_splits_rings(r, rings, fills=None) -> bool:
    """Whether some drawn outer ring (minus its holes) covers several 4-connected pieces of the raster,
    or some drawn ring of at least a quarter pixel's area and 0.25 % of its section's covers no pixel
    centre."""
    p = r.spacing[0]
    fills = fills or _RingFills(rings, r)
    for k, (rs, parents) in enumerate(rings):
        section = abs(sum(shoelace_area(q) for q in rs)) if rs else 0.0
        for i, par in enumerate(parents):
            # a lost ring counts where it holds a quarter pixel or more (halving may catch it) and a
            # quarter percent of its section's area or more (not a speck beside a large contour)
            area = abs(shoelace_area(rs[i]))
            big = area >= 0.25 * p * p and area >= 2.5e-3 * section
            if par != -1:
                if big and not fills.ring(k, i)[1].any():
                    return True
                continue
            if (big and not fills.outer(k, i)[1].any()) or fills.pieces(k, i) > 1:
                return True
    return False


def _drawn_rings(stack: ContourStack):
    """Per section, ``(oriented rings, parents)`` of the drawn rings in physical units, keyhole rings
    split (:func:`_split_at_repeats`); and how many rings were split."""
    rings = []
    keyholes = 0
    for rs in _physical_rings(stack):
        split = []
        for q in rs:
            pieces = _split_at_repeats(q) if len(q) >= 3 else []
            keyholes += len(pieces) > 1
            split += pieces
        rings.append(_nest_section(split) if split else ((), ()))
    return rings, keyholes


def _warn_dropped(name, dropped, r) -> None:
    """The LostContourWarning of the contours route: the drawn rings that stay out of the mesh, and why."""
    p = r.spacing[0]
    zs = r.z
    where = ", ".join(f"section {k} (z={zs[k]:g}) ring {i} ({why})" for k, i, _, why in dropped[:5])
    more = f" and {len(dropped) - 5} more" if len(dropped) > 5 else ""
    largest = max(a for _, _, a, _ in dropped)
    empty = sorted({k for k, _, _, _ in dropped if not r.volume[k].any()})
    whole = f"; sections {empty} rasterize to no pixel at all and are left out of the mesh" if empty else ""
    warn_external(f"{name}: {len(dropped)} drawn ring(s) enclose no pixel centre at pixel={p:g} and cannot be kept "
                  f"(the largest has area {largest:.3g}, about {largest / p**2:.2g} pixels of {p:g} x {p:g}): "
                  f"{where}{more}{whole}; pass a smaller pixel= to keep them", LostContourWarning)


def decision_raster(stack: ContourStack, pixel: float):
    """The raster that decides the joins on the contours route at ``pixel`` (as ``meta["pixel"]`` records):
    the even-odd rasterization with the pixels that keep split slivers whole."""
    r = rasterize_stack(stack, pixel)
    rings = _drawn_rings(stack)[0]
    fills = _RingFills(rings, r)
    grown = _connect_split_rings(r, rings, fills)
    _keep_small_rings(r, rings, fills, grown)
    return r


def mesh_drawn(stack: ContourStack, *, pixel: float | None = None, triangulation: str = "wiederhold",
               caps: str = "flat", bands: str = "ruled", progress: bool = False) -> Mesh:
    """Mesh a real-valued contour stack between its drawn rings (the contours route; module docstring).

    ``pixel`` is the size of the raster that decides the topology (default
    :func:`contourmesh.rasterize.default_pixel`, halved up to twice, within ``2e7`` voxels, while a
    drawn ring of a quarter pixel and 0.25 % of its section's area or more holds no pixel centre, or a
    ring falls apart into several pieces in the raster).  ``meta``: ``route="contours"``, ``pixel``,
    ``drawn_components`` (components meshed from their drawn rings), ``unmatched_components``
    (meshed from the raster's polygons, each named in a RasterFallbackWarning) and the volume
    mesher's join counts; ``kept_small_rings`` (drawn rings that hold no pixel centre, meshed as drawn)
    and ``lost_rings`` (such rings that could not be kept, named in a LostContourWarning).

    ``bands="curved"`` bends the bands between consecutive sections onto cubic rungs, their
    intermediate rings scaled onto each band's fitted area profile (:mod:`contourmesh.bands.curved`;
    ``meta["curved_levels"]``, the most segments per rung, ``meta["area_bands"]``, the bands that
    follow their area profile, ``meta["plain_pairs"]``, section pairs that dropped it and
    ``meta["ruled_pairs"]``, pairs left ruled, because their bent faces crossed); the default
    ``"ruled"`` keeps every band's volume within the frustum-trapezoid interval of its rings' areas.
    """
    if bands not in ("ruled", "curved"):
        raise ValueError(f"unknown bands {bands!r}; expected 'ruled' or 'curved'")
    name = stack.meta.get("roi") or stack.meta.get("name") or "the stack"
    rings, keyholes = _drawn_rings(stack)
    with warnings.catch_warnings(record=True) as lost:
        warnings.simplefilter("always")
        r = rasterize_stack(stack, pixel)
        # the default pixel is halved (at most twice, within a voxel budget) where a drawn ring is lost
        # or falls apart in the raster: the joins are then decided for the rings as drawn
        fills = _RingFills(rings, r)
        for _ in range(_FINER if pixel is None else 0):
            if r.volume.size * 4 > _FINER_VOXELS or not _raster_splits_rings(r, rings, fills):
                break
            log.debug("contours route: a ring is lost or split at pixel=%g; pixel=%g", r.spacing[0], r.spacing[0] / 2)
            lost.clear()
            r = rasterize_stack(stack, r.spacing[0] / 2)
            fills = _RingFills(rings, r)
    grown = _connect_split_rings(r, rings, fills)
    small, cut, kept, dropped = _keep_small_rings(r, rings, fills, grown)
    for w in lost:  # the rasterization's other warnings, naming the structure (lost rings: below)
        if issubclass(w.category, LostContourWarning):
            continue
        text = str(w.message)
        warn_external(text if text.startswith(f"{name}:") else f"{name}: {text}", w.category)
    if dropped:
        _warn_dropped(name, dropped, r)
    avoid: set = set()
    everything = set(range(len(r.z)))
    why = "faces between its drawn rings and the next section's crossed"
    quiet = _Quiet()
    attempt = 0
    while True:
        hook = _DrawnPolygons(rings, r, name, frozenset(avoid), why, smooth=caps == "smooth", flat=caps == "flat",
                              grown={**grown, **small}, curved=bands == "curved", fills=fills, cut=cut)
        last = attempt >= _ATTEMPTS - 1 or avoid == everything
        if not last:
            log.addFilter(quiet)
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                m = volume_to_mesh(r.volume, **r.mesh_kwargs, polygon="none", triangulation=triangulation,
                                   caps="half" if caps == "smooth" else caps, progress=progress, polygons=hook)
        except RuntimeError as exc:
            # the drawn rings met the mesher's pixel constructions in a way it cannot make manifold:
            # every section takes the raster's polygons (named in the warning); never a broken mesh
            if avoid == everything:
                raise
            log.info("contours route: %s; every section takes the raster's polygons", exc)
            avoid, why = everything, f"the mesher could not join the drawn rings ({exc})"
            attempt += 1
            continue
        finally:
            log.removeFilter(quiet)
        if last or not m.meta.get("self_intersections"):
            break
        # faces that cross where drawn rings were joined: those sections take the raster's polygons
        bad = intersecting_faces(m.vertices, m.faces)
        z = m.vertices[m.faces[bad]][:, :, 2].ravel()
        k = np.searchsorted(r.z, z, side="left")
        near = np.unique(np.r_[k, k - 1].clip(0, len(r.z) - 1))
        fresh = set(near.tolist()) - avoid  # (not `grown`: the slivers joined in the raster stay joined)
        if not fresh:
            break
        log.debug("contours route: %d crossing face pairs; sections %s take the raster's polygons",
                  m.meta["self_intersections"], sorted(fresh))
        avoid |= fresh
        attempt += 1
    for w in caught:  # the warnings of the attempt that is kept
        warn_external(str(w.message), w.category)
    if bands == "curved":
        m = _curved(m, r.z, hook.end_cap.slopes if hook.end_cap is not None else None, hook.band_guard.faces())
    meta = dict(m.meta)
    meta.update(stack.meta)
    meta.update(route="contours", pixel=r.spacing[0], polygon="drawn", raster_sections=len(avoid),
                faithful_bands=hook.band_guard.replaced, split_rings=keyholes,
                joined_slivers=len(grown), kept_small_rings=kept, lost_rings=len(dropped))
    if caps == "smooth":
        e = hook.end_cap
        meta.update(caps="smooth", smooth_domes=e.count("dome"), smooth_tapers=e.count("taper"),
                    smooth_cut_ends=e.count("cut"), smooth_planar_ends=e.count("plane"),
                    smooth_planar_joins=len(e.planar_joins), smooth_branch_domes=e.count("branch"),
                    smooth_half_prisms=e.count("half"))
    elif caps == "flat":
        meta.update(interior_end_domes=hook.end_cap.count("branch"))
    return Mesh(m.vertices, m.faces, P=m.P, meta=meta)
