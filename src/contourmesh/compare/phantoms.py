"""Contour phantoms: analytic solids drawn as clinical contour stacks, with their exact area and volume.

A phantom is a solid given by an implicit function ``f(p) <= 0`` (``p`` in millimetres, ``(N, 3)``)
whose surface area and volume are known in closed form where one exists (spheres, cylinders with
flat ends, cone frusta, a torus, two overlapping spheres, a tube, a rod in a tube).  Tilting
rotates the solid before it is sliced: area and volume do not change, the sections become
ellipses and clipped ellipses.  :func:`draw` slices it by the planes ``z = z0 + k dz`` and draws
each section's boundary the way a contouring tool does: closed polygons whose vertices lie on the
true boundary, spaced ``ds`` apart along it, starting at a random point.  A ``"keyhole"`` phantom
draws each section's outer ring and its hole as one ring joined by a zero-width channel (how
several planning systems store holes).

Sections are found on a ``grid`` mm raster of ``f`` in the plane (:func:`skimage.measure.find_contours`),
resampled by arc length and projected onto ``f = 0`` by in-plane Newton steps, so the vertices
are on the surface to about 1e-9 mm; thin rings are traced again on finer rasters; rings smaller
than about one ``grid`` step, or enclosing less than ``MIN_RING_AREA``, are not drawn (as a
contouring tool would miss them).

Everything is generated from a seed; nothing is read from elsewhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ..geometry import shoelace_area
from ..stacks import stack_from_rings
from ..types import ContourStack

__all__ = ["Phantom", "sphere", "cylinder", "frustum", "torus", "two_lobes", "y_branch", "keyhole_tube",
           "rod_in_tube", "hollow_sphere", "draw", "section_areas", "trapezoid_volume", "frustum_volume",
           "rotation", "implicit_volume", "verification_set", "rtstruct_bytes", "first_plane",
           "consistent_truths", "with_ends"]


# ------------------------------------------------------------------------------------------------
# geometry helpers
# ------------------------------------------------------------------------------------------------
def rotation(tilt_deg: float = 0.0, azimuth_deg: float = 0.0) -> np.ndarray:
    """Rotation by ``tilt`` about the x axis, then by ``azimuth`` about the z axis (a 3 x 3 matrix)."""
    t, a = math.radians(tilt_deg), math.radians(azimuth_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    return rz @ rx


def _local(p, R, center):
    """World points -> the solid's own frame (inverse rotation about ``center``)."""
    return (np.asarray(p, dtype=np.float64) - center) @ R


def _box_corners(lo, hi):
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], float)


@dataclass(frozen=True)
class Phantom:
    """An implicit solid with its truths.

    Attributes
    ----------
    name : str
        A short label with the parameters (``"sphere-r20"``, ``"cyl-r10-L40-t30"``).
    kind : str
        ``"analytic"`` (one ring per section), ``"branching"``, ``"keyhole"`` or ``"nested"``.
    f : callable
        ``f(points (N, 3)) -> (N,)``, negative inside, zero on the surface (mm).
    lo, hi : ndarray
        A world bounding box of the solid (may be loose).
    area, volume : float or None
        Exact surface area (mm^2) and volume (mm^3); ``None`` when no closed form is used.
    style : str
        ``"plain"`` or ``"keyhole"`` (outer ring and hole drawn as one ring).
    params : dict
        The parameters, for tables.
    """

    name: str
    kind: str
    f: Callable
    lo: np.ndarray
    hi: np.ndarray
    area: Optional[float]
    volume: Optional[float]
    style: str = "plain"
    params: dict = field(default_factory=dict)


def _placed(name, kind, f_local, lo_local, hi_local, area, volume, tilt, azimuth, center, style="plain", **params):
    R = rotation(tilt, azimuth)
    c = np.asarray(center, dtype=np.float64)
    corners = _box_corners(lo_local, hi_local) @ R.T + c
    f = (lambda p, _f=f_local, _R=R, _c=c: _f(_local(p, _R, _c)))
    params = dict(params, tilt=float(tilt), azimuth=float(azimuth), center=tuple(float(v) for v in c))
    return Phantom(name, kind, f, corners.min(0), corners.max(0), area, volume, style, params)


def _tilt_suffix(tilt):
    return f"-t{tilt:g}" if tilt else ""


# ------------------------------------------------------------------------------------------------
# primitives (local frame; axis along z)
# ------------------------------------------------------------------------------------------------
def _f_sphere(r):
    return lambda q: np.sqrt(np.einsum("ij,ij->i", q, q)) - r


def _f_cylinder(r, L):
    return lambda q: np.maximum(np.hypot(q[:, 0], q[:, 1]) - r, np.abs(q[:, 2]) - L / 2)


def _f_frustum(r1, r2, h):
    """Cone frustum: radius ``r1`` at ``z = -h/2``, ``r2`` at ``z = +h/2``."""
    slant = math.hypot(r1 - r2, h)
    cos_a = h / slant

    def f(q):
        rz = r1 + (r2 - r1) * (q[:, 2] + h / 2) / h
        return np.maximum((np.hypot(q[:, 0], q[:, 1]) - rz) * cos_a, np.abs(q[:, 2]) - h / 2)

    return f


def _f_torus(R, r):
    """Torus about the local z axis."""
    return lambda q: np.hypot(np.hypot(q[:, 0], q[:, 1]) - R, q[:, 2]) - r


def _f_capsule(a, b, r):
    a, b = np.asarray(a, float), np.asarray(b, float)
    ba = b - a
    bb = float(ba @ ba)

    def f(q):
        pa = q - a
        t = np.clip(pa @ ba / bb, 0.0, 1.0)
        d = pa - t[:, None] * ba
        return np.sqrt(np.einsum("ij,ij->i", d, d)) - r

    return f


# ------------------------------------------------------------------------------------------------
# phantoms
# ------------------------------------------------------------------------------------------------
def sphere(r: float, *, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A ball of radius ``r``: area ``4 pi r^2``, volume ``4/3 pi r^3``."""
    return _placed(f"sphere-r{r:g}", "analytic", _f_sphere(r), (-r,) * 3, (r,) * 3, 4 * math.pi * r * r,
                   4 / 3 * math.pi * r**3, 0.0, 0.0, center, r=r)


def cylinder(r: float, L: float, *, tilt: float = 0.0, azimuth: float = 0.0, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A cylinder with flat ends (radius ``r``, length ``L``), tilted by ``tilt`` degrees from z."""
    return _placed(f"cyl-r{r:g}-L{L:g}{_tilt_suffix(tilt)}", "analytic", _f_cylinder(r, L), (-r, -r, -L / 2),
                   (r, r, L / 2), 2 * math.pi * r * (r + L), math.pi * r * r * L, tilt, azimuth, center, r=r, L=L)


def frustum(r1: float, r2: float, h: float, *, tilt: float = 0.0, azimuth: float = 0.0,
            center=(0.0, 0.0, 0.0)) -> Phantom:
    """A cone frustum (radii ``r1``, ``r2``, height ``h``); ``r2 = 0`` is a cone."""
    rm = max(r1, r2)
    area = math.pi * (r1 + r2) * math.hypot(r1 - r2, h) + math.pi * (r1 * r1 + r2 * r2)
    vol = math.pi * h * (r1 * r1 + r1 * r2 + r2 * r2) / 3
    return _placed(f"frustum-r{r1:g}-{r2:g}-h{h:g}{_tilt_suffix(tilt)}", "analytic", _f_frustum(r1, r2, h),
                   (-rm, -rm, -h / 2), (rm, rm, h / 2), area, vol, tilt, azimuth, center, r1=r1, r2=r2, h=h)


def torus(R: float, r: float, *, tilt: float = 90.0, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A torus (``R`` to the tube's centre, tube radius ``r``); ``tilt=90`` stands it up (branching)."""
    return _placed(f"torus-R{R:g}-r{r:g}{_tilt_suffix(tilt)}", "branching", _f_torus(R, r), (-R - r, -R - r, -r),
                   (R + r, R + r, r), 4 * math.pi**2 * R * r, 2 * math.pi**2 * R * r * r, tilt, 0.0, center, R=R, r=r)


def _lens(r1, r2, d):
    """Caps cut from two spheres at distance ``d`` by their common plane: (cap volumes, cap areas)."""
    a = (d * d + r1 * r1 - r2 * r2) / (2 * d)
    h1, h2 = r1 - a, r2 - (d - a)
    vol = math.pi * h1 * h1 * (3 * r1 - h1) / 3 + math.pi * h2 * h2 * (3 * r2 - h2) / 3
    area = 2 * math.pi * r1 * h1 + 2 * math.pi * r2 * h2
    return vol, area


def two_lobes(r1: float, r2: float, d: float, *, tilt: float = 20.0, center=(0.0, 0.0, 0.0)) -> Phantom:
    """Union of two balls whose centres are ``d`` apart along a line ``tilt`` degrees from horizontal.

    Sliced by z, the sections fork from one ring into two: a branching phantom with a closed form.
    """
    if not abs(r1 - r2) < d < r1 + r2:
        raise ValueError(f"two_lobes needs |r1 - r2| < d < r1 + r2 (overlapping, neither inside the other); "
                         f"got r1={r1}, r2={r2}, d={d}")
    t = math.radians(tilt)
    c1 = np.array([-d / 2 * math.cos(t), 0.0, -d / 2 * math.sin(t)])
    c2 = -c1
    f1, f2 = _f_sphere(r1), _f_sphere(r2)
    f = lambda q: np.minimum(f1(q - c1), f2(q - c2))
    lens_v, lens_a = _lens(r1, r2, d)
    area = 4 * math.pi * (r1 * r1 + r2 * r2) - lens_a
    vol = 4 / 3 * math.pi * (r1**3 + r2**3) - lens_v
    lo = np.minimum(c1 - r1, c2 - r2)
    hi = np.maximum(c1 + r1, c2 + r2)
    return _placed(f"lobes-r{r1:g}-{r2:g}-d{d:g}", "branching", f, lo, hi, area, vol, 0.0, 0.0, center,
                   r1=r1, r2=r2, d=d)


def y_branch(r: float, L: float, angle: float = 30.0, *, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A Y of three capsules of radius ``r``: a trunk of length ``L`` along z, two arms of length ``L``
    leaving its top at ``+-angle`` degrees from z.  No closed form (``area = volume = None``)."""
    a = math.radians(angle)
    top = np.array([0.0, 0.0, 0.0])
    caps = [_f_capsule((0, 0, -L), top, r),
            _f_capsule(top, (L * math.sin(a), 0, L * math.cos(a)), r),
            _f_capsule(top, (-L * math.sin(a), 0, L * math.cos(a)), r)]
    f = lambda q: np.minimum(np.minimum(caps[0](q), caps[1](q)), caps[2](q))
    lo = np.array([-L * math.sin(a) - r, -r, -L - r])
    hi = np.array([L * math.sin(a) + r, r, L * math.cos(a) + r])
    return _placed(f"Y-r{r:g}-L{L:g}-a{angle:g}", "branching", f, lo, hi, None, None, 0.0, 0.0, center,
                   r=r, L=L, angle=angle)


def keyhole_tube(R: float, r: float, L: float, *, tilt: float = 0.0, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A thick tube (outer radius ``R``, bore ``r``, length ``L``, flat ends) drawn with keyhole rings."""
    fo, fi = _f_cylinder(R, L), _f_cylinder(r, L + 4 * R)
    f = lambda q: np.maximum(fo(q), -fi(q))
    area = 2 * math.pi * L * (R + r) + 2 * math.pi * (R * R - r * r)
    vol = math.pi * L * (R * R - r * r)
    return _placed(f"keyhole-R{R:g}-r{r:g}-L{L:g}{_tilt_suffix(tilt)}", "keyhole", f, (-R, -R, -L / 2),
                   (R, R, L / 2), area, vol, tilt, 0.0, center, style="keyhole", R=R, r=r, L=L)


def rod_in_tube(R: float, r1: float, r2: float, L: float, *, tilt: float = 0.0, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A tube (outer ``R``, bore ``r1``) with a coaxial rod (radius ``r2 < r1``), all of length ``L``:
    each section is a ring with a hole holding an island."""
    if not 0 < r2 < r1 < R:
        raise ValueError(f"rod_in_tube needs 0 < r2 < r1 < R; got R={R}, r1={r1}, r2={r2}")
    fo, fb, fr = _f_cylinder(R, L), _f_cylinder(r1, L + 4 * R), _f_cylinder(r2, L)
    f = lambda q: np.minimum(np.maximum(fo(q), -fb(q)), fr(q))
    area = 2 * math.pi * L * (R + r1 + r2) + 2 * math.pi * (R * R - r1 * r1 + r2 * r2)
    vol = math.pi * L * (R * R - r1 * r1 + r2 * r2)
    return _placed(f"nested-R{R:g}-{r1:g}-{r2:g}-L{L:g}{_tilt_suffix(tilt)}", "nested", f, (-R, -R, -L / 2),
                   (R, R, L / 2), area, vol, tilt, 0.0, center, R=R, r1=r1, r2=r2, L=L)


def hollow_sphere(R: float, r: float, *, center=(0.0, 0.0, 0.0)) -> Phantom:
    """A ball of radius ``R`` with a concentric spherical cavity of radius ``r``: holes appear and vanish."""
    fo, fi = _f_sphere(R), _f_sphere(r)
    f = lambda q: np.maximum(fo(q), -fi(q))
    return _placed(f"hollow-R{R:g}-r{r:g}", "nested", f, (-R,) * 3, (R,) * 3, 4 * math.pi * (R * R + r * r),
                   4 / 3 * math.pi * (R**3 - r**3), 0.0, 0.0, center, R=R, r=r)


# ------------------------------------------------------------------------------------------------
# drawing
# ------------------------------------------------------------------------------------------------
def _project(f, xy, z, iters: int = 6, eps: float = 1e-6, max_move: float | None = None):
    """Newton steps in the plane ``z`` onto ``f = 0``.

    A point that would move farther than ``max_move`` keeps its place: near a sharp corner (where a
    flat end meets a side) the step can overshoot onto the extension of the other face and fold
    the ring; such points stay on the traced polyline, within one raster step inside the corner.
    """
    xy = np.asarray(xy, dtype=np.float64)
    p = np.c_[xy, np.full(len(xy), z)]
    for _ in range(iters):
        v = f(p)
        gx = (f(p + [eps, 0, 0]) - f(p - [eps, 0, 0])) / (2 * eps)
        gy = (f(p + [0, eps, 0]) - f(p - [0, eps, 0])) / (2 * eps)
        g2 = gx * gx + gy * gy
        ok = g2 > 1e-12
        step = np.where(ok, v / np.where(ok, g2, 1.0), 0.0)
        p[:, 0] -= step * gx
        p[:, 1] -= step * gy
    out = p[:, :2]
    if max_move is not None:
        far = np.hypot(*(out - xy).T) > max_move
        out[far] = xy[far]
    return out


def _resample(ring: np.ndarray, ds: float, start: float, min_points: int) -> np.ndarray:
    """Points every ``ds`` (about) along a closed polyline, the first at fraction ``start`` of its length."""
    closed = np.vstack([ring, ring[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    per = s[-1]
    n = max(int(round(per / ds)), min_points)
    t = (start * per + np.arange(n) * per / n) % per
    return np.c_[np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])]


def _keyhole(outer: np.ndarray, hole: np.ndarray) -> np.ndarray:
    """One ring: around ``outer`` (CCW), in along a zero-width channel, around ``hole`` (CW), back out."""
    if shoelace_area(outer) < 0:
        outer = outer[::-1]
    if shoelace_area(hole) > 0:
        hole = hole[::-1]
    d = np.linalg.norm(hole[:, None, :] - outer[None, :, :], axis=2)
    j, i = np.unravel_index(np.argmin(d), d.shape)
    o = np.roll(outer, -i, axis=0)
    h = np.roll(hole, -j, axis=0)
    return np.vstack([o, o[:1], h, h[:1]])


#: Rings enclosing less than this (mm^2) are not drawn: below any contouring tool's resolution, and
#: where a raster cuts off the tip of a very acute corner (a sliver's end) the tip is such a crumb.
MIN_RING_AREA = 1e-3


def draw(ph: Phantom, dz: float, ds: float, *, seed: int = 0, grid: float | None = None,
         min_points: int = 8, offset: float | None = None) -> ContourStack:
    """Slice a phantom by the planes ``z = z0 + k dz`` and draw each section's boundary.

    Parameters
    ----------
    ph : Phantom
    dz : float
        Slice spacing (mm).
    ds : float
        In-plane point spacing along each ring (mm); rings get at least ``min_points`` points.
    seed : int
        Chooses ``z0`` (the plane offset, in ``[0, dz)`` above the solid's lowest point) and each
        ring's start point.
    grid : float, optional
        The raster step used to find the sections (default ``min(0.25, ds)``).
    offset : float, optional
        The first plane's height above the solid's lowest point ``lo[2]``, as a fraction of ``dz``
        (in ``[0, 1)``); default: drawn from the seed (uniform), so a flat end lies anywhere within
        one spacing beyond its last section, as when a planner contours a real object.

    Returns
    -------
    ContourStack
        Rings in mm (``spacing (1, 1)``), outer rings counter-clockwise, holes clockwise;
        ``meta`` holds the phantom's name, ``dz``, ``ds``, ``seed`` and its truths.
    """

    if not (dz > 0 and ds > 0):
        raise ValueError(f"dz and ds must be positive; got dz={dz}, ds={ds}")
    rng = np.random.default_rng(seed)
    g = float(grid) if grid is not None else min(0.25, ds)
    lo, hi = ph.lo, ph.hi
    z0 = _first_plane(ph, dz, rng, offset)
    zs = np.arange(z0, hi[2], dz)
    slices = []
    for z in zs:
        rings = _section_rings(ph, z, lo[:2], hi[:2], g)
        rings = [_drawn_ring(ph, xy, z, ds, rng.uniform(), min_points, g) for xy in rings]
        rings = [r for r in rings if abs(shoelace_area(r)) > MIN_RING_AREA]
        if not rings:
            continue
        if ph.style == "keyhole":
            rings = _keyhole_rings(rings)
        slices.append((float(z), rings))
    if not slices:
        raise ValueError(f"{ph.name}: no section found at dz={dz}")
    meta = {"name": ph.name, "kind": ph.kind, "dz": float(dz), "ds": float(ds), "seed": int(seed),
            "area_true": ph.area, "volume_true": ph.volume, "units": "mm"}
    return stack_from_rings(slices, source=ph.name, meta=meta)


def _first_plane(ph: Phantom, dz: float, rng, offset: float | None) -> float:
    """The first plane's height (draws one number from ``rng`` even when ``offset`` is given, so the
    rings' start points do not depend on ``offset``)."""
    u = rng.uniform(0.0, dz)
    if offset is not None:
        if not 0.0 <= offset < 1.0:
            raise ValueError(f"offset is a fraction of dz in [0, 1); got {offset}")
        u = offset * dz
    return float(ph.lo[2] + u)


def first_plane(ph: Phantom, dz: float, *, seed: int = 0, offset: float | None = None) -> float:
    """The height ``z0`` of the first plane :func:`draw` uses with these arguments: its planes are
    ``z0 + k dz`` (the sections drawn are those of the planes that cut the solid)."""
    if not dz > 0:
        raise ValueError(f"dz must be positive; got {dz}")
    return _first_plane(ph, dz, np.random.default_rng(seed), offset)


def _crossings(r: np.ndarray) -> int:
    """How many pairs of non-adjacent edges of the closed ring ``r`` properly cross."""
    a, b = r, np.roll(r, -1, axis=0)

    def side(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    A, B, C, D = a[:, None], b[:, None], a[None], b[None]
    x = (side(A, B, C) * side(A, B, D) < 0) & (side(C, D, A) * side(C, D, B) < 0)
    return int(np.triu(x, 2).sum())


def _drawn_ring(ph, xy, z, ds, start, min_points, g):
    """The polygon drawn on one traced boundary: resampled every ``ds``, projected onto the surface.

    In the rare case that projection folds the ring at a sharp corner (a sliver where a flat end
    cuts a tilted side), the ring is drawn unprojected on the traced polyline instead (whose
    vertices are on the surface; its chords lie within about ``grid^2 / 8R`` of it).
    """
    base = _resample(xy, ds, start, min_points)
    ring = _project(ph.f, base, z, max_move=0.05 * g)
    if len(ring) <= 2000 and _crossings(ring):
        return base  # on the traced polyline, whose vertices are on the surface
    return ring


def _section_rings(ph: Phantom, z: float, lo, hi, g: float, depth: int = 0) -> list:
    """Boundary polylines of the section at ``z`` (on the surface), found on a ``g`` raster of ``f``.

    Where a ring comes out thinner than 8 ``g`` (the sliver where a flat end cuts a tilted side, a
    ring about to vanish), the section is traced again on a raster 8 times finer over that ring's
    box, so thin parts are neither split nor dropped.
    """
    from skimage.measure import find_contours

    x = np.arange(lo[0] - 2 * g, hi[0] + 2 * g + g / 2, g)
    y = np.arange(lo[1] - 2 * g, hi[1] + 2 * g + g / 2, g)
    X, Y = np.meshgrid(x, y)  # [row = y, col = x]
    F = ph.f(np.c_[X.ravel(), Y.ravel(), np.full(X.size, z)]).reshape(X.shape)
    if not (F < 0).any():
        return []
    out, thin = [], []
    for c in find_contours(F, 0.0):
        if len(c) < 4 or np.linalg.norm(c[0] - c[-1]) > 1e-9:
            continue  # open pieces cannot occur with the margin
        xy = _project(ph.f, np.c_[x[0] + c[:-1, 1] * g, y[0] + c[:-1, 0] * g], z, max_move=0.05 * g)
        if depth < 2 and np.min(np.ptp(xy, axis=0)) < 8 * g:
            thin.append((xy.min(0) - 2 * g, xy.max(0) + 2 * g))
        else:
            out.append(xy)
    if thin:
        # re-trace the thin rings' boxes (merged, since one sliver may have come out as several pieces)
        boxes = []
        for blo, bhi in sorted(thin, key=lambda b: tuple(b[0])):
            if boxes and np.all(blo <= boxes[-1][1]) and np.all(bhi >= boxes[-1][0]):
                boxes[-1] = (np.minimum(blo, boxes[-1][0]), np.maximum(bhi, boxes[-1][1]))
            else:
                boxes.append((blo, bhi))
        for blo, bhi in boxes:
            fine = [r for r in _section_rings(ph, z, blo, bhi, g / 8, depth + 1)
                    if not any(np.all(np.abs(r.min(0) - o.min(0)) < g) and np.all(np.abs(r.max(0) - o.max(0)) < g) for o in out)]
            out += fine
    return out


def _keyhole_rings(rings):
    """Join each hole to the ring just around it by a keyhole channel (the rings of one section)."""
    from ..geometry import points_in_rings

    order = sorted(range(len(rings)), key=lambda i: -abs(shoelace_area(rings[i])))
    placed = []  # (ring, depth, parent index in placed)
    for i in order:
        r = rings[i]
        inside = [k for k, (o, _, _) in enumerate(placed) if points_in_rings(r[:1], o)[0]]
        parent = inside[-1] if inside else -1
        placed.append((r, len(inside), parent))
    out = {k: r for k, (r, d, _) in enumerate(placed) if d % 2 == 0}
    for r, d, parent in placed:
        if d % 2 == 1:
            out[parent] = _keyhole(out[parent], r)
    return list(out.values())


def section_areas(stack: ContourStack) -> np.ndarray:
    """The even-odd area of each section (holes subtract), in the stack's physical units."""
    sx, sy = (float(v) for v in stack.spacing)
    return np.array([abs(sum(shoelace_area(np.asarray(c, float)) for c in s.contours)) * sx * sy
                     for s in stack.sections])


def trapezoid_volume(stack: ContourStack) -> float:
    """Trapezoid rule over the section areas (nothing beyond the end sections)."""
    a, z = section_areas(stack), np.array([s.z for s in stack.sections])
    return float(np.sum((a[1:] + a[:-1]) / 2 * np.diff(z)))


def frustum_volume(stack: ContourStack) -> float:
    """Frustum (prismatoid-of-similar-sections) rule: ``dz/3 (A0 + A1 + sqrt(A0 A1))`` per gap."""
    a, z = section_areas(stack), np.array([s.z for s in stack.sections])
    return float(np.sum(np.diff(z) / 3 * (a[1:] + a[:-1] + np.sqrt(a[1:] * a[:-1]))))


def implicit_volume(ph: Phantom, h: float, *, margin: int = 2):
    """The solid sampled at voxel centres of an isotropic ``h`` grid: ``(volume [z, y, x] bool, origin (x, y, z))``."""
    lo = np.floor(ph.lo / h) * h - margin * h
    hi = np.ceil(ph.hi / h) * h + margin * h
    axes = [np.arange(lo[i], hi[i] + h / 2, h) for i in range(3)]
    out = np.zeros((len(axes[2]), len(axes[1]), len(axes[0])), dtype=bool)
    X, Y = np.meshgrid(axes[0], axes[1])
    pts = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    for k, z in enumerate(axes[2]):
        pts[:, 2] = z
        out[k] = (ph.f(pts) <= 0).reshape(X.shape)
    return out, (float(axes[0][0]), float(axes[1][0]), float(axes[2][0]))


# ------------------------------------------------------------------------------------------------
# what a drawing cannot tell: the truths of every solid of the phantom's kind that gives the same drawing
# ------------------------------------------------------------------------------------------------
def _frustum_truths(rb: float, rt: float, H: float) -> tuple[float, float]:
    """Volume and area of a frustum of radii ``rb``, ``rt`` and height ``H`` (a cylinder if equal)."""
    vol = math.pi * H * (rb * rb + rb * rt + rt * rt) / 3
    area = math.pi * (rb + rt) * math.hypot(rb - rt, H) + math.pi * (rb * rb + rt * rt)
    return vol, area


def _end_range(t_e, out, cz, az, s, r_at, k, z0, dz):
    """The axial positions an end of a cylinder or frustum can take without changing the drawing.

    The end at axial position ``t_e`` (``out`` = -1 at the bottom, +1 at the top) is a disc of radius
    ``r_at(t)`` in the plane square to the axis; its heights span ``cz + t az -+ r(t) s``.  Planes
    that do not cut the disc see either the whole section or none of it, so while the disc stays in
    the open gap between two neighbouring planes ``z0 + k dz`` every plane's section is unchanged.
    A plane that cuts the disc (a slanted end whose trace shows in a section) fixes the end.
    Returns ``(t_inner, t_outer)`` (equal when fixed).
    """
    lo_e, hi_e = cz + t_e * az - r_at(t_e) * s, cz + t_e * az + r_at(t_e) * s
    z_below = z0 + math.floor((lo_e - z0) / dz) * dz
    z_above = z_below + dz
    if z_above < hi_e:
        return t_e, t_e
    # linear constraints a + b t > z_below (low edge), a + b t < z_above (high edge), r(t) >= 0
    r0 = r_at(0.0)
    cons = [(cz - s * r0, az - s * k, z_below, +1), (cz + s * r0, az + s * k, z_above, -1), (r0, k, 0.0, +1)]
    t_min, t_max = -math.inf, math.inf
    for a, b, bound, sign in cons:  # sign * (a + b t - bound) > 0
        if abs(b) < 1e-15:
            continue
        t = (bound - a) / b
        if sign * b > 0:
            t_min = max(t_min, t)
        else:
            t_max = min(t_max, t)
    if not t_min <= t_e <= t_max:
        raise AssertionError(f"end at {t_e} outside its own range [{t_min}, {t_max}]")
    return (t_max, t_min) if out < 0 else (t_min, t_max)


def with_ends(ph: Phantom, t_bottom: float, t_top: float) -> Phantom:
    """The cylinder or frustum ``ph`` with its ends moved to the axial positions ``t_bottom < t_top``
    (measured along its axis from its centre, as in :func:`consistent_truths`): the same radius and
    axis, or the same cone."""
    kind = ph.name.split("-")[0]
    if kind not in ("cyl", "frustum"):
        raise ValueError(f"with_ends: {ph.name} is not a cylinder or frustum")
    if not t_bottom < t_top:
        raise ValueError(f"with_ends needs t_bottom < t_top; got {t_bottom}, {t_top}")
    tilt, azimuth = ph.params.get("tilt", 0.0), ph.params.get("azimuth", 0.0)
    center = np.asarray(ph.params["center"]) + rotation(tilt, azimuth)[:, 2] * (t_bottom + t_top) / 2
    if kind == "cyl":
        return cylinder(ph.params["r"], t_top - t_bottom, tilt=tilt, azimuth=azimuth, center=center)
    r1, r2, h = ph.params["r1"], ph.params["r2"], ph.params["h"]
    r_at = lambda t: max(0.0, r1 + (r2 - r1) / h * (t + h / 2))  # noqa: E731
    return frustum(r_at(t_bottom), r_at(t_top), t_top - t_bottom, tilt=tilt, azimuth=azimuth, center=center)


def consistent_truths(ph: Phantom, dz: float, z0: float) -> dict:
    """The truths a drawing cannot tell apart.

    The drawing of ``ph`` on the planes ``z0 + k dz`` (:func:`draw`, :func:`first_plane`) is also the
    drawing of other solids of the same kind: a sphere's sections fix the sphere, but a flat end
    parallel to the planes lies anywhere in the gap between its last section and the next (empty)
    plane, and a cone's apex may as well be a small flat top in that gap.  Over the solids of the
    phantom's kind (spheres; cylinders of the same radius and axis; frusta on the same cone) whose
    drawing is the same, this returns the range of their volumes and areas:
    ``{"volume": (lo, hi), "area": (lo, hi), "ends": [(t_inner, t_outer) per end], "fixed": bool}``
    (``t`` along the solid's axis from its centre; the ranges are open at the gap's planes).
    Volume and area grow as either end moves outward, so the extremes are the ends' extreme places.

    Slanted ends (tilted cylinders and frusta) are fixed when a plane cuts the end disc, which it
    does whenever the disc spans more than one spacing in height (``2 r sin(tilt) > dz``).
    Supports the spheres, cylinders and frusta of :func:`verification_set` (analytic kind);
    other phantoms raise ``ValueError``.
    """
    if not dz > 0:
        raise ValueError(f"dz must be positive; got {dz}")
    kind = ph.name.split("-")[0]
    if kind == "sphere":
        return {"volume": (ph.volume, ph.volume), "area": (ph.area, ph.area), "ends": [], "fixed": True}
    if kind == "cyl":
        r1 = r2 = ph.params["r"]
        H = ph.params["L"]
    elif kind == "frustum":
        r1, r2, H = ph.params["r1"], ph.params["r2"], ph.params["h"]
    else:
        raise ValueError(f"consistent_truths: {ph.name} is not a sphere, cylinder or frustum")
    axis = rotation(ph.params.get("tilt", 0.0), ph.params.get("azimuth", 0.0))[:, 2]
    cz = ph.params["center"][2]
    az = float(axis[2])
    s = math.sqrt(max(0.0, 1.0 - az * az))
    k = (r2 - r1) / H
    r_at = lambda t: r1 + k * (t + H / 2)  # noqa: E731
    ends = [_end_range(-H / 2, -1, cz, az, s, r_at, k, z0, dz), _end_range(H / 2, +1, cz, az, s, r_at, k, z0, dz)]
    (b_in, b_out), (t_in, t_out) = ends
    v_lo, a_lo = _frustum_truths(r_at(b_in), r_at(t_in), t_in - b_in)
    v_hi, a_hi = _frustum_truths(r_at(b_out), r_at(t_out), t_out - b_out)
    return {"volume": (v_lo, v_hi), "area": (a_lo, a_hi), "ends": ends, "fixed": b_in == b_out and t_in == t_out}


# ------------------------------------------------------------------------------------------------
# the verification set and an RTSTRUCT writer
# ------------------------------------------------------------------------------------------------
def verification_set(full: bool = False, seed: int = 20150701):
    """The phantoms and drawing settings of the clinical comparison: a list of ``(phantom, dz, ds, seed)``.

    ``full=True`` is the whole grid: spheres (r = 5, 10, 20, 30), cylinders (r = 5, 15, 30; upright and
    tilted 30 degrees), frusta (upright and tilted 25 degrees) and a cone, at slice spacings 0.2, 0.5,
    1, 2, 3 mm and point spacings 0.2, 0.5, 1 mm, plus the branching, keyhole and nested phantoms at
    every slice spacing (point spacing 0.5 mm).  The default is a subsample of it (same seeds).
    """
    analytic = [sphere(5), sphere(10), sphere(20), sphere(30),
                cylinder(5, 20), cylinder(15, 40), cylinder(30, 60),
                cylinder(5, 20, tilt=30, azimuth=20), cylinder(15, 40, tilt=30, azimuth=20),
                cylinder(30, 60, tilt=30, azimuth=20),
                frustum(15, 5, 30), frustum(15, 5, 30, tilt=25, azimuth=-35), frustum(10, 0, 20)]
    other = [torus(15, 5), two_lobes(10, 8, 14), y_branch(5, 25), keyhole_tube(12, 6, 30),
             keyhole_tube(12, 6, 30, tilt=20), rod_in_tube(15, 9, 4, 30), hollow_sphere(15, 8)]
    dzs, dss = (0.2, 0.5, 1.0, 2.0, 3.0), (0.2, 0.5, 1.0)
    grid = [(ph, dz, ds) for ph in analytic for dz in dzs for ds in dss]
    grid += [(ph, dz, 0.5) for ph in other for dz in dzs]
    out = [(ph, dz, ds, seed + i) for i, (ph, dz, ds) in enumerate(grid)]
    if full:
        return out
    keep = {
        "sphere-r5": {(0.5, 0.5), (1.0, 0.2), (3.0, 0.5)},
        "sphere-r10": {(0.2, 0.5), (1.0, 1.0), (2.0, 0.5), (3.0, 0.5)},
        "sphere-r20": {(0.5, 0.5), (2.0, 0.5), (3.0, 1.0)},
        "sphere-r30": {(3.0, 1.0)},
        "cyl-r5-L20": {(1.0, 0.5), (3.0, 0.5)},
        "cyl-r15-L40": {(2.0, 0.5)},
        "cyl-r5-L20-t30": {(1.0, 0.5), (3.0, 0.5)},
        "cyl-r15-L40-t30": {(0.5, 0.5), (2.0, 1.0), (3.0, 0.5)},
        "frustum-r15-5-h30": {(1.0, 0.5), (3.0, 0.5)},
        "frustum-r15-5-h30-t25": {(2.0, 0.5), (3.0, 0.5)},
        "frustum-r10-0-h20": {(2.0, 0.5)},
        "torus-R15-r5-t90": {(1.0, 0.5), (3.0, 0.5)},
        "lobes-r10-8-d14": {(1.0, 0.5), (3.0, 0.5)},
        "Y-r5-L25-a30": {(1.0, 0.5), (3.0, 0.5)},
        "keyhole-R12-r6-L30": {(2.0, 0.5)},
        "keyhole-R12-r6-L30-t20": {(3.0, 0.5)},
        "nested-R15-9-4-L30": {(2.0, 0.5)},
        "hollow-R15-r8": {(1.0, 0.5), (3.0, 0.5)},
    }
    return [t for t in out if (t[1], t[2]) in keep.get(t[0].name, ())]


def rtstruct_bytes(stacks: dict) -> bytes:
    """A minimal DICOM RTSTRUCT holding one ROI per ``{name: ContourStack}`` (CLOSED_PLANAR contours, mm).

    Enough for :func:`contourmesh.io.read_contours` and other RTSTRUCT readers that do not need the
    referenced image series (the UIDs are fixed, derived from nothing).
    """
    import io

    from .._optional import require

    require("pydicom", "io", "pydicom")
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.sequence import Sequence
    from pydicom.uid import ExplicitVRLittleEndian

    ds = Dataset()
    ds.file_meta = FileMetaDataset()
    ds.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds.file_meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.481.3"
    ds.file_meta.MediaStorageSOPInstanceUID = "1.2.826.0.1.3680043.10.1511.1"
    ds.SOPClassUID = ds.file_meta.MediaStorageSOPClassUID
    ds.SOPInstanceUID = ds.file_meta.MediaStorageSOPInstanceUID
    ds.Modality = "RTSTRUCT"
    ds.PatientName = "PHANTOM^CONTOURMESH"
    ds.PatientID = "PHANTOM"
    ds.StructureSetLabel = "CM PHANTOMS"
    rois, contours = [], []
    for num, (name, stack) in enumerate(stacks.items(), start=1):
        roi = Dataset()
        roi.ROINumber = num
        roi.ROIName = name
        rois.append(roi)
        items = []
        sx, sy = (float(v) for v in stack.spacing)
        ox, oy = (float(v) for v in stack.origin)
        for s in stack.sections:
            for ring in s.contours:
                r = np.asarray(ring, dtype=np.float64)
                xyz = np.c_[r[:, 0] * sx + ox, r[:, 1] * sy + oy, np.full(len(r), float(s.z))]
                c = Dataset()
                c.ContourGeometricType = "CLOSED_PLANAR"
                c.NumberOfContourPoints = len(r)
                c.ContourData = [f"{v:.10g}"[:16] for v in xyz.ravel()]
                items.append(c)
        rc = Dataset()
        rc.ReferencedROINumber = num
        rc.ContourSequence = Sequence(items)
        contours.append(rc)
    ds.StructureSetROISequence = Sequence(rois)
    ds.ROIContourSequence = Sequence(contours)
    buf = io.BytesIO()
    try:
        ds.save_as(buf, enforce_file_format=True)
    except TypeError:  # pydicom < 3
        ds.save_as(buf, write_like_original=False)
    return buf.getvalue()
