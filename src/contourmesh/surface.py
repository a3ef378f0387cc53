"""ContourStack -> Mesh: polygons per contour, bands between consecutive sections, caps.

This is the mesh source of the paper's method.  For every contour the selected polygonizer
(``"dss"``, ``"mlp"``, ``"none"``) gives a polygon; consecutive polygons that belong together are
joined by the selected band triangulation (``"wiederhold"``, ``"greedy"``, ``"optimal"``); ends are
closed by a fan to a pole point or by a flat cap triangulated with earcut.

End rules (stated once, see docs/DESIGN.md):

* A polygon that degenerates to a point or a segment (zero area; MLPs next to a pole do) ends a
  run of sections: it is joined by its band only, and closes the surface there without a cap.  Of
  several degenerate polygons at the same end of a run only the outermost is kept, so that no edge
  is shared by more than two triangles.  A degenerate polygon in the middle of a run is replaced
  by its contour (which always encloses area).
* An end polygon that encloses area is closed by a flat cap: in its own plane (``caps="flat"``) or,
  with ``caps="half"``, after a prism half a slice spacing beyond it (as SlicerRT does), which adds
  the prism's side area and ``area(cap) * gap / 2`` of volume.  ``caps="smooth"`` closes it by a
  dome (:func:`_dome`): copies of the end polygon shrunk toward a centre, at heights on a quarter
  ellipse, the last one closed by a flat cap; the dome holds the half prism's volume, without its
  side wall.  A polygon that touches itself (the
  MLP of a thin part goes out and back) cannot be capped by ear clipping: a collar 1 % of the
  spacing beyond the end then joins it to its contour, capped by the contour's grid cells.

Crossing faces (issue 13: closed means embedded).  Every band is guarded: of the requested
triangulation and then ``optimal``, ``arclength``, ``wiederhold``, ``greedy``, the first whose own
faces neither fold nor cross is used (``meta["band_fallbacks"]`` counts the bands that were not the
requested one).  The finished mesh is tested exactly (:mod:`contourmesh.intersect`); where faces of
different bands or caps still cross, each band involved takes its next triangulation, and a band
that no triangulation keeps clear, or a cap, has its sections meshed from their contours instead of
their polygons (``meta["polygon_fallbacks"]``); the mesh is built again, at most
``_MAX_REBUILDS`` times (``meta["crossing_fallbacks"]`` counts the changes).  Faces that then touch
or cross by a hair are pulled apart (:func:`contourmesh.repair.resolve_crossings`, section vertices
moving in their plane; ``meta["crossings_repaired"]``).  Whatever is left is counted in
``meta["self_intersections"]`` and, with ``crossings="warn"`` (the default), warned about
(:class:`~contourmesh.errors.SelfIntersectionWarning`), or raised with ``crossings="raise"``
(:class:`~contourmesh.errors.CrossingFacesError`): :func:`contourmesh.mesh` then meshes drawn rings on
the contours route and refined stacks by the volume mesher.  No crossing mesh is returned silently.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ._kernels import njit
from .bands import band_is_folded, triangulate_band
from .bands.caps import CapError, cap_faces
from .bands.ends import _CUT, _DOME_RINGS, _centroid, _dome_centre, _end_profile, _roundness
from .errors import (
    ContourMeshError,
    CrossingFacesError,
    OpenSurfaceError,
    SelfIntersectionWarning,
    StackSurfaceError,
    warn_external,
)
from .geometry import distinct_rows, points_in_rings, shoelace_area
from .intersect import any_intersecting, intersecting_pairs
from .measure import _edge_counts, mesh_volume
from .polygons import polygonize
from .repair import _separate_coincident, resolve_crossings, split_nonmanifold_vertices
from .stacks import check_stack
from .types import ContourStack, Mesh, Section

__all__ = ["stack_to_mesh", "CAPS", "StackSurfaceError"]

log = logging.getLogger("contourmesh")

CAPS = ("flat", "half", "smooth")

#: Shrunk copies of the end polygon in a smooth cap (the dome's rings above the end polygon).
DOME_RINGS = 4


def _polygon(contour: np.ndarray, method: str) -> np.ndarray:

    contour = np.asarray(contour)
    if len(contour) < 3 or method == "none":  # a pole point, or the contour as given
        return contour.astype(np.float64)
    return np.asarray(polygonize(contour, method), dtype=np.float64)


def _repeats_a_point(poly: np.ndarray) -> bool:
    """A polygon of 3 or more distinct points that visits one of them twice."""
    n = distinct_rows(poly)
    return 3 <= n < len(poly)


def _is_degenerate(poly: np.ndarray) -> bool:
    return distinct_rows(poly) < 3 or abs(shoelace_area(poly)) == 0.0


@njit(cache=True)
def _unique_rows_kernel(p):
    """The distinct rows of the finite ``(k, 2)`` array ``p`` in ``(x, y)`` order and each row's
    index among them: ``np.lexsort((y, x))`` as two stable sorts (by ``y``, then by ``x``), the
    first row of each run of equal rows kept (``-0.0 == 0.0``, as in the reference)."""
    n = p.shape[0]
    o = np.argsort(p[:, 1], kind="mergesort")
    xs = np.empty(n)
    for i in range(n):
        xs[i] = p[o[i], 0]
    o = o[np.argsort(xs, kind="mergesort")]
    inverse = np.empty(n, dtype=np.intp)
    keep = np.empty(n, dtype=np.intp)
    count = 0
    for i in range(n):
        if i == 0 or p[o[i], 0] != p[o[i - 1], 0] or p[o[i], 1] != p[o[i - 1], 1]:
            keep[count] = o[i]
            count += 1
        inverse[o[i]] = count - 1
    uniq = np.empty((count, 2))
    for i in range(count):
        uniq[i, 0] = p[keep[i], 0]
        uniq[i, 1] = p[keep[i], 1]
    return uniq, inverse


class _Builder:
    """Collects vertices and faces; vertices of one polygon are merged by position."""

    def __init__(self, spacing, origin):
        self.sx, self.sy = float(spacing[0]), float(spacing[1])
        self.ox, self.oy = float(origin[0]), float(origin[1])
        self.vertices: list[np.ndarray] = []
        self.faces: list[np.ndarray] = []
        self.n = 0
        self.cell_caps = 0
        self.smooth_fallbacks = 0
        self.dome = "ellipse"  # caps="smooth": "ellipse" (:func:`_dome`) or "profile" (:func:`_profile_dome`)
        self.keys: list = []  # what made each face block (a band's key, or None), parallel to faces
        self.key = None  # the key of the blocks added now
        self.levels: dict = {}  # band key -> first triangulation to try (index into _band_order)
        self.used: dict = {}  # band key -> the triangulation index the band took
        self.band_fallbacks = 0  # bands whose own faces crossed with the requested triangulation
        self.exhausted: set = set()  # band keys for which no triangulation keeps clear of itself
        self.sections_of: dict = {}  # key -> the sections whose rings its faces use
        self.contour_sections: set = set()  # sections meshed from their contours (crossing fallback)

    def add_polygon(self, poly_xy: np.ndarray, z: float) -> np.ndarray:
        """Add a polygon's vertices at height z; returns the vertex index of each polygon point."""
        uniq, inverse = self._unique_rows(poly_xy)
        v = np.empty((len(uniq), 3))
        v[:, 0] = uniq[:, 0] * self.sx + self.ox
        v[:, 1] = uniq[:, 1] * self.sy + self.oy
        v[:, 2] = z
        self.vertices.append(v)
        idx = self.n + inverse.reshape(-1)
        self.n += len(v)
        return idx

    def _unique_rows(self, poly_xy) -> tuple[np.ndarray, np.ndarray]:
        """``np.unique(poly_xy, axis=0, return_inverse=True)`` by a stable lexicographic sort (several
        times faster on short polygons).  The rows and the inverse are the same; of equal rows that
        differ only in the sign of a zero, the one kept may differ, which the vertex coordinates
        ``x * spacing + origin`` do not show unless an origin is -0.0 (then ``np.unique`` itself)."""
        p = np.asarray(poly_xy)
        if (p.ndim != 2 or p.shape[1] != 2 or p.dtype != np.float64 or not np.isfinite(p).all()
                or (self.ox == 0.0 and math.copysign(1.0, self.ox) < 0)
                or (self.oy == 0.0 and math.copysign(1.0, self.oy) < 0)):
            uniq, inverse = np.unique(poly_xy, axis=0, return_inverse=True)
            return uniq, inverse.reshape(-1)
        return _unique_rows_kernel(np.ascontiguousarray(p))

    @staticmethod
    def _unique_rows_reference(p) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_unique_rows`' sort and merge by numpy (finite float rows; the reference of
        :func:`_unique_rows_kernel`)."""
        x, y = p[:, 0], p[:, 1]
        order = np.lexsort((y, x))  # x first, then y, as np.unique's row order
        xs, ys = x[order], y[order]
        new = np.empty(len(p), dtype=bool)
        new[:1] = True
        new[1:] = (xs[1:] != xs[:-1]) | (ys[1:] != ys[:-1])
        inverse = np.empty(len(p), dtype=np.intp)
        inverse[order] = np.cumsum(new) - 1
        return p[order[new]], inverse

    def add_points(self, xy: np.ndarray, z: float) -> np.ndarray:
        """Add one vertex per point (no merging) at height z."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        v = np.empty((len(xy), 3))
        v[:, 0] = xy[:, 0] * self.sx + self.ox
        v[:, 1] = xy[:, 1] * self.sy + self.oy
        v[:, 2] = z
        self.vertices.append(v)
        idx = self.n + np.arange(len(xy))
        self.n += len(xy)
        return idx

    def coords(self, idx: np.ndarray) -> np.ndarray:
        allv = np.concatenate(self.vertices) if len(self.vertices) > 1 else self.vertices[0]
        self.vertices = [allv]
        return allv[idx]

    def add_faces(self, faces: np.ndarray):
        if len(faces):
            self.faces.append(np.asarray(faces, dtype=np.int64))
            self.keys.append(self.key)

    def face_keys(self) -> list:
        """The key of every face (see :attr:`key`)."""
        return [k for k, f in zip(self.keys, self.faces) for _ in range(len(f))]

    def mark(self) -> tuple[int, int, int]:
        """The builder's state (vertices, face blocks, cell caps), for :meth:`restore`."""
        return self.n, len(self.faces), self.cell_caps

    def restore(self, mark: tuple[int, int, int]) -> None:
        """Drop every vertex and face added since ``mark``."""
        n, nf, cells = mark
        if self.vertices:
            allv = np.concatenate(self.vertices)[:n]
            self.vertices = [allv] if n else []
        self.n, self.faces, self.cell_caps = n, self.faces[:nf], cells
        self.keys = self.keys[:nf]

    def box_volume_since(self, mark: tuple[int, int, int]) -> float:
        """Volume of the bounding box of the vertices added since ``mark`` (a scale for tolerances)."""
        if self.n <= mark[0]:
            return 0.0
        v = (np.concatenate(self.vertices) if len(self.vertices) > 1 else self.vertices[0])[mark[0]: self.n]
        return float(np.prod(v.max(axis=0) - v.min(axis=0)))

    def volume_since(self, mark: tuple[int, int, int]) -> float:
        """Signed volume enclosed by the faces added since ``mark`` (divergence theorem)."""

        if len(self.faces) <= mark[1]:
            return 0.0
        v = np.concatenate(self.vertices) if len(self.vertices) > 1 else self.vertices[0]
        return mesh_volume(v, np.concatenate(self.faces[mark[1]:]))

    def mesh(self, **kw) -> Mesh:
        v = np.concatenate(self.vertices) if self.vertices else np.zeros((0, 3))
        f = np.concatenate(self.faces) if self.faces else np.zeros((0, 3), dtype=np.int64)
        if self.cell_caps:  # cell caps may touch themselves at corners: make the surface a manifold

            nudge = 1e-3 * min(self.sx, self.sy)
            v, f = split_nonmanifold_vertices(v, f, nudge=nudge)
            v = _separate_coincident(v, f, nudge)
        return Mesh(v, f, P=len(v), **kw)


#: Largest ``n^2 m`` (ring sizes ``n <= m``) for which the band guard tries the optimal band.
_OPTIMAL_BUDGET = 3e7


def _band_order(method: str) -> list[str]:
    """The triangulations a band tries, the requested one first (see :func:`_band`)."""
    return [method] + [m for m in ("optimal", "arclength", "wiederhold", "greedy") if m != method]


def _band(builder: _Builder, lo_idx, hi_idx, method: str, key=None):
    """The band between two rings, guarded: the first triangulation (the requested one, then
    :func:`_band_order`'s others, from the key's level in ``builder.levels``) whose faces neither
    fold nor cross each other (exact test, :mod:`contourmesh.intersect`).  Where every one does,
    the first that does not fold is kept (the mesh-wide check then counts the crossings)."""
    lo = builder.coords(lo_idx)
    hi = builder.coords(hi_idx)
    both = np.concatenate([lo_idx, hi_idx])
    order = _band_order(method)
    key = builder.key if key is None else key
    start = builder.levels.get(key, 0)
    n, m = sorted((len(lo), len(hi)))
    P = np.concatenate([lo, hi])
    first, clear = None, False
    for i in range(start, len(order)):
        if order[i] == "optimal" and order[i] != method and n * n * m > _OPTIMAL_BUDGET:
            continue
        local = triangulate_band(lo, hi, order[i], fallback=False)
        if band_is_folded(local):
            continue
        if first is None:
            first = (i, local)
        if not any_intersecting(P, local):
            first, clear = (i, local), True
            break
    if first is None:  # every band folds: the requested one, with its own fold fallback
        first = (0, triangulate_band(lo, hi, method))
    i, local = first
    if i > 0 and key is not None:
        builder.band_fallbacks += 1
    if key is not None:
        builder.used[key] = i
        if not clear:
            builder.exhausted.add(key)
    prev, builder.key = builder.key, key
    builder.add_faces(both[local])
    builder.key = prev


def _cap(builder: _Builder, idx, holes_idx=(), upward=True):

    rings = [idx, *holes_idx]
    xy = [builder.coords(r)[:, :2] for r in rings]
    local = cap_faces(xy[0], xy[1:], upward=upward)
    both = np.concatenate(rings)
    builder.add_faces(both[local])


def _dome_profile(m: int = DOME_RINGS):
    """``(scale, height)`` of the dome's rings 1..m: a quarter ellipse sampled at ``theta_k = k pi / (2 (m + 1))``
    (``scale = cos theta``), heights in units of the gap, set so that the dome's volume is the half-gap
    prism's (``area * gap / 2``)."""
    theta = np.arange(1, m + 1) * np.pi / (2 * (m + 1))
    lam, h = np.r_[1.0, np.cos(theta)], np.r_[0.0, np.sin(theta)]
    # volume of the stack of similar frusta (and the flat top), per unit end area and unit height
    kappa = float(np.sum(np.diff(h) * (lam[:-1] ** 2 + lam[:-1] * lam[1:] + lam[1:] ** 2) / 3))
    return lam[1:], h[1:] * (0.5 / kappa)


def _dome(b: _Builder, ring, poly: np.ndarray, z: float, gap: float, upward: bool):
    """A smooth cap over the end polygon ``poly`` (its vertices ``ring`` at height ``z``); returns the
    top ring (its vertex indices), for the flat cap that closes it.

    Ring ``k`` of :data:`DOME_RINGS` is ``poly`` shrunk toward :func:`_dome_centre` by
    ``cos(theta_k)`` (``theta_k = k pi / (2 (m + 1))``), at a height beyond ``z`` proportional to
    ``sin(theta_k)``: a quarter ellipse from the end polygon's rim toward the centre, its tangent at
    the rim perpendicular to the section plane.  The heights are scaled so that the dome holds the
    volume of the ``caps="half"`` prism, ``area * gap / 2``: its top lies about 0.73 gap beyond the
    end section (a dome of the prism's height would hold only about 2/3 of it).  Each horizontal
    section of the dome is a scaled copy of the end polygon, so the dome does not cross itself; the
    rings are joined point to point (planar trapezoids, split in two triangles each).

    Raises
    ------
    CapError
        If ``ring`` visits a vertex twice (a polygon that touches itself).
    """
    ring = np.asarray(ring)
    if len(np.unique(ring)) != len(ring):
        raise CapError("the end polygon visits a point twice")
    centre, _ = _dome_centre(poly)
    sgn = 1.0 if upward else -1.0
    ccw = shoelace_area(poly) > 0
    return _ring_layers(b, ring, ((centre + lam * (poly - centre), z + sgn * gap * h)
                                  for lam, h in zip(*_dome_profile())), ccw == upward)


def _ring_layers(b: _Builder, ring, layers, forward: bool):
    """Rings stacked on ``ring``, joined point to point: ``layers`` yields each ring's ``(xy, z)``
    (as many points as ``ring``); ``forward`` is whether ``ring`` runs counter-clockwise seen from
    the side the layers rise to.  Returns the last ring's vertices."""
    prev = ring
    for xy, zc in layers:
        nxt = b.add_points(xy, zc)
        a0, a1, b0, b1 = prev, np.roll(prev, -1), nxt, np.roll(nxt, -1)
        if forward:
            b.add_faces(np.concatenate([np.c_[a0, a1, b1], np.c_[a0, b1, b0]]))
        else:
            b.add_faces(np.concatenate([np.c_[a0, b1, a1], np.c_[a0, b0, b1]]))
        prev = nxt
    return prev


def _profile_dome(b: _Builder, ring, polys, zs, gap: float, upward: bool):
    """A smooth cap over the end polygon ``polys[0]`` (its vertices ``ring`` at height ``zs[0]``)
    that follows the area profile of the last sections (``polys`` and ``zs``: the end polygon and
    the one or two polygons joined to it, inward); returns the top ring, for the flat cap that
    closes it.  The band refinement's ends (``refine="band", caps="smooth"``).

    As the contours route's smooth ends (:func:`contourmesh.bands.ends._end_profile`): the section's
    area is extrapolated outward from the last sections; where it closes within a spacing, the
    dome's rings are the end polygon scaled by ``lam`` (evenly spread on a quarter circle) at the
    distances where the extrapolated area is ``lam^2`` times the end's, so the dome continues the
    bands' slope and holds the volume the profile puts beyond the end section; otherwise a taper
    to a flat end half a spacing out.  An end section much less round than the one before (a cut
    at a slant) moves half a spacing along the axis instead.  The rings drift along the line
    through the last two sections' area centroids and are joined point to point.  With one
    section only (the next one inward is a point), :func:`_dome`.

    Raises
    ------
    CapError
        If ``ring`` visits a vertex twice (a polygon that touches itself).
    """
    if len(polys) < 2:
        return _dome(b, ring, polys[0], zs[0], gap, upward)
    ring = np.asarray(ring)
    if len(np.unique(ring)) != len(ring):
        raise CapError("the end polygon visits a point twice")
    poly = polys[0]
    areas = [abs(shoelace_area(p)) for p in polys]
    dists = [abs(float(z1) - float(z0)) for z0, z1 in zip(zs[:-1], zs[1:])]
    if _roundness(poly) < _CUT * _roundness(polys[1]):
        t, lam = np.array([gap / 2]), np.array([1.0])
    else:
        t, lam, _ = _end_profile(areas, dists, gap, _DOME_RINGS)
    drift = (_centroid(poly) - _centroid(polys[1])) / dists[0]
    centre, _ = _dome_centre(poly)
    sgn = 1.0 if upward else -1.0
    ccw = shoelace_area(poly) > 0
    return _ring_layers(b, ring, ((centre + lam_i * (poly - centre) + drift * t_i, zs[0] + sgn * t_i)
                                  for lam_i, t_i in zip(lam, t)), ccw == upward)


def _is_grid_4_curve(c: np.ndarray) -> bool:
    """Whether ``c`` is a closed digital 4-curve: integer points, unit axis steps (closing step included)."""
    if c.ndim != 2 or c.shape[1] != 2 or len(c) < 4 or not np.all(np.isfinite(c)) or not np.all(c == np.round(c)):
        return False
    d = np.abs(np.diff(np.vstack([c, c[:1]]), axis=0))
    return bool(np.all(d.sum(axis=1) == 1))


def _cap_or_cells(b: _Builder, ring, contour, z: float, gap: float, upward: bool, triangulation: str):
    """A flat earcut cap on the ring; where the polygon touches itself (a thin part whose MLP goes
    out and back), a hair-thin collar to the contour and a cap made of its grid cells instead."""
    try:
        _cap(b, ring, upward=upward)
        return
    except ValueError:
        pass
    c = np.asarray(contour)
    if not _is_grid_4_curve(c):

        raise CapError(f"cannot cap the section at z={z}: its polygon touches itself and its contour is not a "
                         "grid contour to fall back on")

    c = c.astype(np.int64)
    sgn = 1.0 if upward else -1.0
    t = b.add_points(c, z + sgn * 0.005 * gap)
    _band(b, ring, t, triangulation) if upward else _band(b, t, ring, triangulation)
    (x0, y0), (x1, y1) = c.min(axis=0), c.max(axis=0)
    ii, jj = np.meshgrid(np.arange(x0, x1), np.arange(y0, y1))
    cells = np.c_[ii.ravel(), jj.ravel()]
    cells = cells[points_in_rings(cells + 0.5, c)]
    corners = np.unique(np.concatenate([c, cells, cells + [1, 0], cells + [1, 1], cells + [0, 1]]), axis=0)
    gid = b.add_points(corners, z + sgn * 0.01 * gap)
    lookup = {tuple(p): int(i) for p, i in zip(corners.tolist(), gid)}
    g = np.array([lookup[tuple(p)] for p in c.tolist()])
    b.add_faces(np.concatenate([np.c_[t, np.roll(t, -1), np.roll(g, -1)], np.c_[t, np.roll(g, -1), g]])
                if upward else np.concatenate([np.c_[g, np.roll(g, -1), np.roll(t, -1)], np.c_[g, np.roll(t, -1), t]]))
    q = [np.array([lookup[tuple(p)] for p in (cells + d).tolist()]) for d in ([0, 0], [1, 0], [1, 1], [0, 1])]
    if upward:
        b.add_faces(np.concatenate([np.c_[q[0], q[1], q[2]], np.c_[q[0], q[2], q[3]]]))
    else:
        b.add_faces(np.concatenate([np.c_[q[0], q[2], q[1]], np.c_[q[0], q[3], q[2]]]))
    b.cell_caps += 1


def _outward(stack: ContourStack) -> ContourStack:
    """The stack with every contour in the outer orientation (positive shoelace area).

    With one contour per section every contour bounds the solid from outside, so a contour given
    clockwise-in-raw-numbers (negative area) is reversed, keeping its start point.  A contour that
    encloses no area (fewer than 3 distinct points, or collinear points) may only end the stack
    (a pole); between two sections it would pinch the surface to a point or a segment.
    """

    n = len(stack.sections)
    sections = []
    for k, s in enumerate(stack.sections):
        contours = []
        for c, cont in enumerate(s.contours):
            arr = np.asarray(cont)
            if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) == 0:
                raise ValueError(f"section {k} (z={s.z}) contour {c}: expected a non-empty (k, 2) array of "
                                 f"points (x, y); found shape {arr.shape}")
            area = shoelace_area(arr)
            if area == 0.0 and 0 < k < n - 1 and len(s.contours) == 1:
                raise StackSurfaceError(
                    f"section {k} (z={s.z}) contour {c} encloses no area ({len(arr)} point(s)); expected a closed "
                    "contour around an area: a point or segment contour can only be the first or last section (a pole)"
                )
            if area < 0 and len(s.contours) == 1:
                arr = np.concatenate([arr[:1], arr[:0:-1]])
            contours.append(arr)
        sections.append(Section(s.z, tuple(contours), s.parents))
    return ContourStack(tuple(sections), stack.spacing, stack.origin, dict(stack.meta))


def _nested_chains(stack: ContourStack):
    """For sections that each hold one outer contour and the same number of holes, the hole
    chains: ``chains[h][k]`` is the index in section k of the hole joined to hole h of section 0.

    Holes of consecutive sections are matched by their nearest centroids; the matching must be
    one to one and each matched pair must overlap (bounding boxes), else None.
    """
    first = stack.sections[0]
    n_holes = len(first.contours) - 1
    for s in stack.sections:
        outer = [i for i, p in enumerate(s.parents) if p == -1]
        if outer != [0] or len(s.contours) != n_holes + 1 or any(p != 0 for p in s.parents[1:]):
            return None
    def centroid_box(c):
        c = np.asarray(c, dtype=np.float64)
        return c.mean(axis=0), c.min(axis=0), c.max(axis=0)
    chains = [[h + 1] for h in range(n_holes)]
    for k in range(1, len(stack.sections)):
        prev = [centroid_box(stack.sections[k - 1].contours[ch[-1]]) for ch in chains]
        cur = [centroid_box(c) for c in stack.sections[k].contours[1:]]
        used = set()
        for ch, (pc, plo, phi) in zip(chains, prev):
            d = [np.linalg.norm(pc - cc) for cc, _, _ in cur]
            j = int(np.argmin(d))
            clo, chi = cur[j][1], cur[j][2]
            if j in used or np.any(plo > chi + 1) or np.any(clo > phi + 1):
                return None
            used.add(j)
            ch.append(j + 1)
    return chains


def _runs(stack: ContourStack):
    """Chains of (section index, contour index) joined section to section.

    One contour per section: the whole stack is one run.  Sections with one outer contour and
    holes matched one to one (a torus lying flat) are handled by :func:`_nested_chains`; other
    stacks with several contours per section go through the volume mesher
    (:func:`contourmesh.mesh` rasterizes them, :mod:`contourmesh.rasterize`).
    """
    for k, s in enumerate(stack.sections):
        if len(s.contours) != 1:
            raise ContourMeshError(
                f"section {k} (z={s.z}) has {len(s.contours)} contours that this stack mesher cannot join "
                "(it joins one contour per section, or one outer contour with matching holes); "
                "use contourmesh.mesh(stack), which rasterizes it for the volume mesher"
            )
    return [[(k, 0) for k in range(len(stack.sections))]]


def _mesh_nested(stack, chains, polygon, triangulation, caps, b, zs):
    """Bands along the outer chain and each hole chain; caps with holes at both ends.

    An end section whose polygons cannot be capped (outer and hole polygons of a thin ring that
    cross) is dropped, so the surface ends at the next section that can be capped.
    """

    n = len(stack.sections)
    if caps == "smooth":
        raise ContourMeshError("caps='smooth' applies to stacks of one contour per section; this stack's sections "
                               "hold holes (nested outer and hole chains): use caps='flat' or caps='half'")

    def poly(k, c):
        cont = stack.sections[k].contours[c]
        p = _polygon(cont, polygon)
        bad = _is_degenerate(p) or _repeats_a_point(p) or k in b.contour_sections
        return np.asarray(cont, dtype=np.float64) if bad else p

    all_chains = [[0] * n] + chains
    polys = [[poly(k, ch[k]) for k in range(n)] for ch in all_chains]

    def cappable(k):
        try:
            cap_faces(polys[0][k], [p[k] for p in polys[1:]])
            return True
        except ValueError:
            return False

    s0 = next((k for k in range(n) if cappable(k)), None)
    s1 = next((k for k in range(n - 1, -1, -1) if cappable(k)), None)
    if s0 is None or s1 is None or s1 - s0 < 1:
        raise StackSurfaceError("the stack's rings cannot be capped (outer and hole polygons cross at both ends)")
    rings = [[b.add_polygon(p[k], zs[k]) for k in range(s0, s1 + 1)] for p in polys]
    for h, ch in enumerate(rings):
        for k, (a, c) in enumerate(zip(ch[:-1], ch[1:]), start=s0):
            key = ("band", h, k, k + 1)
            b.sections_of[key] = {k, k + 1}
            _band(b, a, c, triangulation, key)
    for end, k, upward in ((0, s0, False), (-1, s1, True)):
        b.key = ("cap", 0, k)
        b.sections_of[b.key] = {k}
        ends = [ch[end] for ch in rings]
        if caps == "half":
            nb = k + 1 if upward is False else k - 1
            gap = abs(zs[nb] - zs[k])
            zc = zs[k] + (gap / 2 if upward else -gap / 2)
            shifted = [b.add_polygon(p[k], zc) for p in polys]
            for r, t in zip(ends, shifted):
                _band(b, r, t, triangulation) if upward else _band(b, t, r, triangulation)
            ends = shifted
        _cap(b, ends[0], ends[1:], upward=upward)
        b.key = None


def stack_to_mesh(
    stack: ContourStack,
    *,
    polygon: str = "mlp",
    triangulation: str = "wiederhold",
    caps: str = "flat",
    crossings: str = "warn",
    dome: str = "ellipse",
) -> Mesh:
    """Mesh a contour stack: polygons, bands and caps (see the module docstring for the end rules
    and for crossing faces).

    ``dome`` (with ``caps="smooth"``): ``"ellipse"``, the dome of :func:`_dome` (a quarter ellipse
    holding the half prism's volume), or ``"profile"``, that of :func:`_profile_dome` (the last
    sections' area profile extrapolated; the band refinement's ends).

    ``crossings``: what to do where faces still cross after the local repair: ``"warn"`` (a
    :class:`~contourmesh.errors.SelfIntersectionWarning`; the count is in
    ``meta["self_intersections"]``) or ``"raise"`` (:class:`~contourmesh.errors.CrossingFacesError`).
    """
    if caps not in CAPS:
        raise ValueError(f"caps must be one of {CAPS}, got {caps!r}")
    if crossings not in ("warn", "raise"):
        raise ValueError(f"crossings must be 'warn' or 'raise', got {crossings!r}")
    if dome not in ("ellipse", "profile"):
        raise ValueError(f"dome must be 'ellipse' or 'profile', got {dome!r}")
    zs = check_stack(stack)
    stack = _outward(stack)
    default_h = float(np.median(np.diff(zs))) if len(zs) > 1 else 1.0
    chains = _nested_chains(stack) if any(len(sec.contours) > 1 for sec in stack.sections) else None
    meta = dict(stack.meta)
    meta.update(polygon=polygon, triangulation=triangulation, caps=caps)

    # Build; where faces of the finished mesh cross, each band involved takes its next
    # triangulation (:func:`_band_order`) and the mesh is built again (a few rounds at most).
    levels: dict = {}
    contour_sections: set = set()
    rebuilt = 0
    for attempt in range(_MAX_REBUILDS + 1):
        b = _Builder(stack.spacing, stack.origin)
        b.levels, b.contour_sections = levels, contour_sections
        b.dome = dome
        if chains is not None:
            _mesh_nested(stack, chains, polygon, triangulation, caps, b, zs)
        else:
            for run in _runs(stack):
                mark, fallbacks = b.mark(), b.smooth_fallbacks
                _mesh_run(b, stack, run, polygon, triangulation, caps, zs, default_h, use_contours=False)
                if polygon != "none" and b.volume_since(mark) <= 1e-9 * b.box_volume_since(mark):
                    # the run's polygons fold its surface (e.g. a degenerate MLP segment beside a
                    # small polygon it does not lie under): mesh the run from its contours instead
                    b.restore(mark)
                    b.smooth_fallbacks = fallbacks
                    _mesh_run(b, stack, run, polygon, triangulation, caps, zs, default_h, use_contours=True)
        m = _verified(b.mesh(meta=meta))
        pairs = intersecting_pairs(m.vertices, m.faces)
        if not len(pairs) or attempt == _MAX_REBUILDS:
            break
        keys = b.face_keys()
        if len(keys) != len(m.faces):  # pragma: no cover - the builder keeps one key per face
            break
        changed, to_contours = 0, set()
        for key in {keys[f] for f in np.unique(pairs).tolist()}:
            if key is None:
                continue
            nxt = b.used.get(key, len(_band_order(triangulation))) + 1
            if key in b.used and key not in b.exhausted and nxt < len(_band_order(triangulation)):
                levels[key] = nxt
                changed += 1
            elif polygon != "none":  # every triangulation tried (or a cap): the sections take their contours
                to_contours |= b.sections_of.get(key, set()) - contour_sections
        if to_contours:
            contour_sections |= to_contours
            for key in [k for k in levels if b.sections_of.get(k, set()) & to_contours]:
                del levels[key]  # new rings: the bands start again from the requested triangulation
        if not changed and not to_contours:  # nothing left to change
            break
        rebuilt += changed + len(to_contours)
        log.debug("stack route: %d crossing face pairs; %d bands take another triangulation, sections %s "
                  "their contours", len(pairs), changed, sorted(to_contours))
    if caps == "smooth":
        meta["smooth_fallbacks"] = b.smooth_fallbacks
    meta.update(band_fallbacks=b.band_fallbacks, crossing_fallbacks=rebuilt,
                polygon_fallbacks=len(contour_sections))
    return _embedded(m, meta, pairs, min(b.sx, b.sy), zs, crossings)


#: How many times the stack mesher rebuilds a mesh whose faces cross, with the bands involved
#: taking their next triangulation.
_MAX_REBUILDS = 8


def _embedded(m: Mesh, meta: dict, pairs, pixel: float, zs, crossings: str = "warn") -> Mesh:
    """The stack mesh with crossing faces that a small move separates pulled apart
    (:func:`contourmesh.repair.resolve_crossings`, vertices at section heights moving in their
    plane), and ``meta`` recording the pairs repaired and left.  Pairs left are warned about
    (:class:`~contourmesh.errors.SelfIntersectionWarning`): never a crossing mesh in silence."""
    V = m.vertices
    meta = dict(meta, self_intersections=0, crossings_repaired=0)
    if len(pairs):
        V, info = resolve_crossings(m.vertices, m.faces, 1e-3 * pixel, pairs=pairs, planes=zs)
        meta.update(self_intersections=info["self_intersections"], crossings_repaired=info["crossings_repaired"])
        if info["crossings_repaired"]:
            meta["crossing_repair_max_move"] = info["max_move"]
        if info["self_intersections"]:
            what = (f"{info['self_intersections']} pairs of faces still cross after {meta['crossing_fallbacks']} "
                    f"rebuilds and {info['crossings_repaired']} pairs pulled apart")
            if crossings == "raise":
                raise CrossingFacesError(f"the stack route cannot mesh these contours without crossing faces: {what}")
            warn_external(f"stack route: {what}; the mesh is closed but not embedded (meta['self_intersections'])",
                          SelfIntersectionWarning)
    return Mesh(V, m.faces, P=m.P, meta=meta)


def _verified(m: Mesh) -> Mesh:
    """The mesh, after checking that it is closed, edge-manifold and consistently oriented outward
    (a contour that touches or crosses itself, such as a keyhole, breaks this on the stack route)."""

    f = np.asarray(m.faces, dtype=np.int64)
    _, counts, twice = _edge_counts(f) if len(f) else (None, np.zeros(0, np.int64), 0)
    boundary, crowded = int((counts == 1).sum()), int((counts > 2).sum())
    vol = m.volume if len(f) else 0.0
    box = float(np.prod(np.ptp(m.vertices, axis=0))) if len(m.vertices) else 0.0
    if boundary or crowded or twice or not vol > 1e-9 * box:
        raise OpenSurfaceError(
            f"the contours do not bound a closed surface on the stack route: {boundary} boundary edge(s), {crowded} "
            f"edge(s) in more than two faces, {twice} edge(s) used twice in one direction, volume {vol:.6g}; "
            "expected contours that do not touch or cross themselves (a keyhole contour does: split it into an "
            "outer contour and a hole)")
    return m


def _mesh_run(b: _Builder, stack: ContourStack, run, polygon: str, triangulation: str, caps: str, zs,
              default_h: float, use_contours: bool):
    """Mesh one run of sections (one contour each, overlapping from section to section): bands
    between consecutive polygons, and caps (or a prism for a run of one section)."""
    if use_contours:
        polys = [np.asarray(stack.sections[k].contours[c], dtype=np.float64) for k, c in run]
    else:
        polys = [_polygon(stack.sections[k].contours[c], polygon) for k, c in run]
    # a polygon that visits a point twice (the MLP of a thin part goes out and back) would
    # share an edge among four triangles: such a section uses its contour
    polys = [np.asarray(stack.sections[k].contours[c], dtype=np.float64)
             if _repeats_a_point(p) or k in b.contour_sections else p for p, (k, c) in zip(polys, run)]
    degenerate = [_is_degenerate(p) for p in polys]
    keep = list(range(len(run)))
    # Keep only the outermost degenerate polygon at each end of the run.
    while len(keep) > 2 and degenerate[keep[0]] and degenerate[keep[1]]:
        del keep[1]
    while len(keep) > 2 and degenerate[keep[-1]] and degenerate[keep[-2]]:
        del keep[-2]
    for pos in keep[1:-1]:
        if degenerate[pos]:
            k, c = run[pos]
            polys[pos] = np.asarray(stack.sections[k].contours[c], dtype=np.float64)
            degenerate[pos] = False
    if len(keep) > 1 and all(degenerate[i] for i in keep):
        # every polygon of the run degenerates (tiny contours): use the contours themselves, so
        # that no section is lost and the mesh stays at the sections' own heights
        keep = list(range(len(run)))
        polys = [np.asarray(stack.sections[k].contours[c], dtype=np.float64) for k, c in run]
        degenerate = [_is_degenerate(p) for p in polys]
    if len(keep) == 1 or all(degenerate[i] for i in keep):
        # A run of one section: a prism of the contour, one slice spacing thick.
        k, c = run[keep[0]]
        cont = np.asarray(stack.sections[k].contours[c], dtype=np.float64)
        if len(cont) < 3:
            raise StackSurfaceError(f"section {k} (z={zs[k]}) holds an isolated contour of {len(cont)} point(s)")
        lo = b.add_polygon(cont, zs[k] - default_h / 2)
        hi = b.add_polygon(cont, zs[k] + default_h / 2)
        b.key = ("prism", k)
        _band(b, lo, hi, triangulation)
        _cap(b, lo, upward=False)
        _cap(b, hi, upward=True)
        b.key = None
        return
    idx = [b.add_polygon(polys[i], zs[run[i][0]]) for i in keep]
    for i0, i1, a, c in zip(keep[:-1], keep[1:], idx[:-1], idx[1:]):
        key = ("band", 0, run[i0][0], run[i1][0])
        b.sections_of[key] = {run[i0][0], run[i1][0]}
        _band(b, a, c, triangulation, key)
    for end, upward in ((0, False), (-1, True)):
        i = keep[end]
        if degenerate[i]:
            continue
        b.key = ("cap", 0, run[i][0])
        b.sections_of[b.key] = {run[i][0]}
        _run_end(b, stack, run, keep, polys, idx, i, end, upward, caps, zs, triangulation)
        b.key = None


def _run_end(b, stack, run, keep, polys, idx, i, end, upward, caps, zs, triangulation):
    """Close one end of a run: a half prism (``caps="half"``), then a dome or a flat cap."""
    ring = idx[end]
    if caps == "half":
        k = run[i][0]
        nb = run[keep[1]][0] if end == 0 else run[keep[-2]][0]
        gap = abs(zs[nb] - zs[k])
        zc = zs[k] + (gap / 2 if upward else -gap / 2)
        outer = b.add_polygon(polys[i], zc)
        if upward:
            _band(b, ring, outer, triangulation)
        else:
            _band(b, outer, ring, triangulation)
        ring = outer
    k = run[i][0]
    nb = run[keep[1]][0] if end == 0 else run[keep[-2]][0]
    if caps == "smooth":
        mark = b.mark()
        try:
            if b.dome == "profile":
                inward = keep[::-1] if end == -1 else keep
                chain = [j for n_, j in enumerate(inward[:3]) if n_ == 0 or not _is_degenerate(polys[j])]
                top = _profile_dome(b, ring, [polys[j] for j in chain], [zs[run[j][0]] for j in chain],
                                    abs(zs[nb] - zs[k]), upward)
            else:
                top = _dome(b, ring, polys[i], zs[k], abs(zs[nb] - zs[k]), upward)
            _cap(b, top, upward=upward)
            return
        except ValueError as exc:  # a polygon that touches itself: closed flat, as caps="flat" does
            b.restore(mark)
            b.smooth_fallbacks += 1
            log.debug("section z=%g: no dome (%s); closed by a flat cap in its plane", zs[k], exc)
    zr = float(b.coords(ring[:1])[0, 2])
    _cap_or_cells(b, ring, stack.sections[k].contours[run[i][1]], zr, abs(zs[nb] - zs[k]), upward,
                  triangulation)


