"""Band refinement: a multigrid-convergent surface from a contour stack (issue 6).

The paper's mesh (Wiederhold & Villafuerte 2009, sect. 5) puts every vertex on its slice's MLP.
Each MLP is an excellent *curve*, but it is the relative convex hull of the slice's points ``I`` in
``U``: it runs on the inner side of the band and its vertices jitter by up to one voxel from one
slice to the next (flat stretches wherever the boundary is nearly parallel to a grid axis or to a
rational direction).  The band triangles follow that jitter, and the extra slant does not shrink
with the resolution; the inward bias of the convex-hull vertices adds a negative error of its own.
The paper's conclusion asks for triangles that "grow over various slices".

Method ``"band"`` (:func:`refine_stack`, :func:`band_mesh`) replaces every slice polygon by a
polygon whose vertices sit *in their own slice plane* on a smooth estimate of the surface that
sees several slices at once, aligned from slice to slice, and clamped into the slice's band
``U_k \\ int(V_k)``; the result is a contour stack of float polygons that the ordinary pipeline
meshes (``stack_to_mesh(..., polygon="none")``, any band triangulation, the same caps and poles):

1. **Digital object from the contours.**  For every section, ``U_k`` is rasterized from its
   contours (even-odd rule over the unit cells, so holes are handled) and ``I_k`` is recovered as
   the grid points whose four surrounding cells are in ``U_k`` (:func:`stack_points`).  Nothing
   else is used: volumes, files and analytic shapes all reach this step as contour stacks.
2. **A smooth indicator across slices.**  ``f(x) = sum_{p in I} G_sigma(x - p) / sum_{p in Z^3}
   G_sigma(p)``, the Gauss-digitized solid blurred by a Gaussian of ``sigma`` voxels
   (:func:`auto_sigma`: 2 to 3.5, growing like the cube root of the object's size), evaluated
   exactly at any point with its gradient and Hessian by a sum over the lattice points within
   ``4 sigma`` (:func:`blurred_indicator`).  The level-set search of steps 3-4 evaluates it in the
   vertex's own slice, where the sum across the slices is done once per slice and search
   (:func:`_slice_moments`): each evaluation then sums ``(8 sigma)^2`` terms, not ``(8 sigma)^3``.
3. **The level set, corrected for curvature.**  For a smooth surface with principal curvatures
   ``k1, k2`` the level ``f = 1/2`` of the blurred indicator lies *inside* the surface by
   ``(k1 + k2) sigma^2 / 2`` (to second order: the Gaussian-weighted share of a paraboloid's
   inside).  A seed vertex is moved along the horizontal direction of ``-grad f`` to the level
   ``f = 1/2`` (safeguarded Newton), then outward by that shift, with ``k1 + k2 = div(n)`` from
   the gradient and Hessian of ``f`` there (the horizontal move is the normal shift divided by
   the horizontal part of the unit normal, capped at one voxel).
3b. **Two scales.**  The correction is exact only to second order in ``sigma kappa``: on real
   shapes, details a few voxels across (ears, fingers, creases) are flattened by a wide blur and
   the surface comes out short (spot, aneurysm, rocker arm at 128 voxels: -0.5 to -0.7 %), while
   a narrow blur leaves lattice roughness on smooth parts (+0.3 % on balls at ``sigma = 1.2``).
   So every vertex is placed at both ``sigma`` and a fine width (:data:`FINE_RATIO` of it); where the
   two places agree to within :data:`FINE_TOLERANCE`'s lower bound (0.1 voxel, above the fine
   scale's own lattice noise) the wide one stands, where they differ by more than its upper
   bound (0.3) an extrapolated place does, and linearly in between: a Lepski-type choice of the
   widest blur that agrees with the narrower one.  On balls 1 % of the vertices change scale.
   The extrapolation (issue 14): once step 3 has removed the ``sigma^2`` term, a place's error
   grows like ``sigma^4`` (a wave of wavenumber ``k`` keeps ``e^-s (1 + s) = 1 - s^2/2 + ...``
   of its amplitude, ``s = k^2 sigma^2 / 2``), so the two places give ``x0 = x_fine + rho
   (x_fine - x_wide)``, ``rho = r^4 / (1 - r^4)``, ``r`` = :data:`FINE_RATIO` (0.32 at 0.7): a
   Richardson step with no new constant, clamped into the band like every move.  That gain is
   for smooth detail; a crease of a faceted surface (the shared test meshes are polyhedra whose
   faces are several voxels wide) puts the place off by ``O(sigma)``, whose gain is ``r / (1 - r)``.
   The two places' mean curvatures tell them apart (:data:`FINE_CREASE`, off by default): equal on
   a smooth bend, in the ratio ``1 / r`` on a crease's rounded apex, but also near ``1 / r`` on a
   smooth wave a few blur widths long, whose order is nearly 4 (:data:`CREASE_WIDER`: a third,
   wider level that bends the other way marks a wave; :data:`CREASE_PLANAR`: where the slices are
   thicker than the pixels their terraces are creases of the data, and the sections' curvatures,
   which do not see them, give the ratio; settings, docs/DESIGN.md).  Where the two
   scales agree, the wide place stands alone: extrapolating there adds the fine scale's lattice
   noise (+0.015 % on balls r = 80).  Only a search that found no level keeps the wide place: a
   vertex whose wide place the band clamp put back on its seed (a crest or a finger tip that the
   wide blur pulls inside ``V``) takes part like the others.
4. **Faithful to the digital object.**  If the target leaves the band ``U_k \\ int(V_k)`` of the
   vertex's slice, the vertex goes to the band point nearest to the target on the segment from
   its start (on the seed polygon, in the band) to the target.
5. **Chord compensation.**  Vertices on the curve make a polygon that is short of it; each vertex
   is pushed outward by ``kappa L^2 / 24 * (1 + 3 nz^2) / (1 + nz^2)`` (see :func:`_chord_push`),
   then clamped into the band.
6. **Meridians** ("triangles that grow over various slices", the paper's sect. 7).  Vertices
   placed independently in consecutive slices make Schwarz-lantern bands: a vertex facing the
   middle of an edge of the next slice stands out by the edge's sagitta ``L^2 / (8 rho)``, and
   the band area grows by about ``(sagitta / h)^2 / 2``, some +0.5 % on a ball whatever its size.
   So slice ``k + 1`` takes the projections of slice ``k``'s final vertices onto its own curve
   (the seed polygon moved to the surface), merged where closer than half the seed polygon's
   mean edge and filled where further than 1.5 of it; the bands then join near-planar quads.

The vertex count stays that of the seed polygons (MLP by default): ``P`` is 1.04-1.10 times the
MLP stack's on balls r = 20-160.

**Units and lattices.**  "Voxel" above means ``h``, the longer pixel side: every length (``sigma``,
the search reach, the moves, the chord and curvature steps) is measured in units of ``h``, and the
lattice's geometry is one record, ``grid = (ax, ay, dz, zpos, zwt)`` (:func:`_make_grid`): pixel
``(i, j)`` of slice ``n`` lies at ``(i ax, j ay, zpos[n] dz)`` with ``ax = dx / h``, ``ay = dy / h``,
so oblong pixels (``dx != dy``) blur and measure as the physical object does, and the band test
divides by ``ax, ay`` back to pixel indices.  Unevenly spaced slices keep their own heights
``zpos``; each is weighted by its midpoint slab ``zwt`` (half the gaps on either side), and the
blur across the slices is normalised at every height (``f = N / D(z)``, the z-derivatives by the
quotient rule) so that a constant stays constant.  Square pixels and evenly spaced slices give
``ax = ay = 1``, every weight 1 and a constant normalisation: the same numbers as a pixel-unit
computation, bit for bit.

Functions here are pure: arrays (and a ContourStack) in, arrays (and a Mesh) out.
"""

from __future__ import annotations

import math

import numpy as np

from ._kernels import njit
from .bands.caps import _segments_meet  # the closed-segment test, shared with the caps
from .geometry import distinct_rows
from .polygons import polygonize
from .stacks import check_stack
from .types import ContourStack, Mesh, Section, shoelace_area

__all__ = ["REFINERS", "stack_points", "blurred_indicator", "in_band", "refine_stack", "refine_ring",
           "refine_volume_rings", "auto_sigma", "band_violations"]

#: Refinement methods by name (``"band"``, ``"band2"``; ``"none"``: no refinement).
REFINERS = ("band", "band2", "none")
#: Ring vertices per seed-polygon vertex of each refinement (the ``density`` of :func:`refine_stack`
#: and :func:`refine_volume_rings` when not given).  ``"band2"`` doubles them from each component's
#: second slice on (the meridians' step is half the seed polygon's mean edge), which quarters the
#: area each refined polygon loses to its chords (issue 17's per-label volumes; see
#: docs/scale-out.md), at twice the vertices: above issue 6's bound of 1.5 times the MLP stack's.
RING_DENSITY = {"band": 1.0, "band2": 2.0}

#: The fine Gaussian width of the two-scale selection (step 3b), as a share of the chosen width
#: (1.4-2.45 voxels for the automatic widths 2-3.5).  A fixed fine width (1.6) left a lattice
#: noise floor on large balls (+0.015 % at r = 160, where the wide blur reaches 0.0017 %).
FINE_RATIO = 0.7
#: Disagreement between the two scales (voxels) below which the coarse estimate stands alone and
#: above which the fine one replaces it (linear in between).
FINE_TOLERANCE = (0.1, 0.3)
#: The extrapolation gain of step 3b where the two scales disagree; None: the Richardson gain
#: ``r^4 / (1 - r^4)`` of a bias growing like ``sigma^4``.  A setting for measurements
#: (``benchmarks/band_sigma.py --rules rho=...``): a crease's area loss grows like ``sigma`` itself,
#: whose gain would be ``r / (1 - r)`` (docs/DESIGN.md, "Blur bias beyond second order").
FINE_RHO = None
#: Coefficient ``c`` of a third-order term ``c (k1 + k2)^3 sigma^4`` added to step 3's normal shift
#: (0: none).  For a ball and a cylinder the 1/2-level sits inside by ``(k1 + k2) sigma^2 / 2 -
#: (k1 + k2)^3 sigma^4 / 24 + ...`` (continuous blur, ``k1, k2`` the level set's curvatures), so
#: ``c = -1/24`` is the exact next term; it only lowers the area (measured on the real shapes: worse),
#: so the default leaves it out.  A setting for measurements (``band_sigma.py --rules cubic=...``).
SHIFT_CUBIC = 0.0
#: Step 3b with a gain per vertex (:func:`_three_scale_targets`): False (the default) for the one
#: gain :data:`FINE_RHO`; True, or the smallest difference (voxels) between the wide and a wider
#: place that is trusted, for a third search at ``sigma / r`` where the scales disagree.  A setting
#: for measurements (``band_sigma.py --rules adaptive``; not a default: docs/DESIGN.md).
FINE_ADAPTIVE = False
#: Step 3b's gain per vertex (issue 14; True, the default since session 19, docs/DESIGN.md, "Crease
#: gains as the default"; False: the one gain of :data:`FINE_RHO` everywhere, ``band_sigma.py
#: --rules nocrease``).  The
#: mean curvature ``S`` of the blurred level at the two places tells a crease from a smooth bend: a
#: smooth surface has the same ``S`` at both widths, the rounded apex of a crease (a faceted
#: surface's edge) has ``S ~ 1 / sigma``.  With ``q = S_fine / S_wide`` (each averaged along the ring
#: over :data:`CREASE_WINDOW` sigma), ``m = clip(log q / log(1 / r), 0, 1)`` is 0 on a smooth bend
#: and 1 on a crease, the bias order ``p = 4 - 3 m`` (a crease's place errs like ``sigma`` itself)
#: and the Richardson gain ``r^p / (1 - r^p)``: 0.32 on smooth parts, up to 2.33 on a crease; its
#: tolerance shrinks by ``1 - CREASE_TOLERANCE m`` (a crease's two places differ by about
#: ``0.18 theta sigma``, under the smooth tolerance for the few-degree creases of fine meshes).
#: On smooth shapes the test also reads the fine level's lattice roughness: its convex bumps take
#: crease gains (the concave ones, ``q < 1``, do not), which moves some vertices out by up to 0.4
#: voxel and raises the area.  That is all the gains do on balls and ellipsoids (where the wide place
#: is the better one, the truth lies nearer it than the extrapolation): balls at r = 20-40 were
#: 0.02-0.07 % short and gain, two of three rotated ellipsoids of size 20-40 were near 0 and end
#: 0.04-0.13 % over.  :data:`CREASE_NOISE` and :data:`CREASE_MIN_FINE` trade that back against the
#: real shapes (docs/DESIGN.md, "Crease gains on smooth shapes").
FINE_CREASE = True
#: The Gaussian (in arc length, times ``sigma``) over which ``S`` is averaged along the ring.
CREASE_WINDOW = 1.0
#: Where the wide place's averaged ``|S| sigma`` is below this, the smooth gain stands (a nearly flat
#: part, whose ``q`` is noise: balls r >= 80); a pair ``(lo, hi)``: below ``lo``, and the crease share
#: fades in from ``lo`` to ``hi`` (a ball's lattice facets bend its level by 0.10-0.13 at r = 160).
CREASE_MIN_BEND = (0.1, 0.13)
#: The crease gain fades out as ``|S| sigma`` grows from half this to this: detail narrower than the
#: blur (a finger, an ear's rim) also has ``S ~ 1 / sigma`` and is not a crease.  None: no limit.
CREASE_MAX_BEND = 0.5
#: The curvature ratio ``q`` up to which a vertex counts as smooth (1: any ``q > 1`` is a partial
#: crease).  On balls the ring-averaged ``q`` scatters by about 0.1 around 1 (lattice noise).
CREASE_MIN_RATIO = 1.0
#: The ratio ``q`` from the curvatures of the level's sections by the slice plane rather than the
#: level's mean curvature: a crease crossing the slices bends the section at both widths, the
#: terraces of thick slices (creases along the slices) do not.  True / False: always / never; a
#: number: in the slices whose slab (the spacing, in units of ``h``) is thicker than it.
CREASE_PLANAR = 1.0
#: A crease's tolerance is FINE_TOLERANCE times ``1 - CREASE_TOLERANCE m`` (on the shared meshes at
#: 256 a quarter of the crease vertices part the two places by less than 0.09 voxel).
CREASE_TOLERANCE = 0.9
#: A third, wider width ``sigma / r`` that tells a crease from a smooth wave (None: not used).  A
#: crease's curvature ratio is scale-free (``S(sigma) / S(sigma / r)`` is about ``S(r sigma) /
#: S(sigma)``, both ``1 / r``); a wave of wavenumber ``k`` keeps ``exp(-k^2 s^2 / 2)`` of its
#: amplitude, so it fades fast with the width: where the level at ``sigma / r`` bends the other way
#: the crease share ``m`` is dropped (True: only that).  ``(t_lo, t_hi)``: also where ``t``, the
#: ratio of the two log-ratios (about ``1 / r^2`` = 2.04 for a wave, 1 for a crease), exceeds
#: ``t_hi``, linearly from ``t_lo``.  Only the vertices that can act (``m > 0``, past their
#: tolerance) and their averaging window are evaluated at ``sigma / r``.  Not the default: with
#: :data:`CREASE_MAX_ORDER` the wave of ``tests/test_refine.py`` no longer needs it.
CREASE_WIDER = None
#: The crease share fades out as the ratio's order ``log q / log(1 / r)`` grows from 1 (a crease,
#: scale-free) to this (None: no fade): a curvature that grows faster with the narrowing width
#: than a crease's is a step narrower than the blur (the lattice facets of large balls: ``q``
#: 1.4-1.9 at ``|S| sigma`` 0.10-0.15), whose place a crease gain overshoots.
CREASE_MAX_ORDER = 1.5
#: Lattice noise floor of step 3b's crease test (0, the default: none).  The fine width's level
#: carries the lattice's roughness: on smooth shapes (balls, ellipsoids) its ring-averaged curvature
#: exceeds the wide one's by a scatter of ``N(f) = CREASE_NOISE_LEVEL / f^CREASE_NOISE_POWER``
#: (``(S_fine - S_wide) sigma``, the interquartile spread over 1.35, ``f`` the fine width in ``h``;
#: measured 0.027 at ``f`` = 1.54, 0.013 at 2.09) and by a median offset of about ``0.4 N(f)``; its
#: convex bumps read as creases (``q`` 1.3-1.7 on 1-3 % of a small ellipsoid's ring length, 0.3 % of
#: a ball's).  With ``z > 0`` only the excess beyond ``z N(f)`` counts: ``q = 1 + max((S_f - S_w)
#: sigma - z N(f), 0) / (|S_w| sigma)`` (signed by the wide curvature; the order fade of
#: :data:`CREASE_MAX_ORDER` then sees this ``q``).  A setting for measurements (``band_sigma.py
#: --rules noise=Z``; not a default: docs/DESIGN.md, "Crease gains on smooth shapes").
CREASE_NOISE = 0.0
CREASE_NOISE_LEVEL = 0.0775
CREASE_NOISE_POWER = 2.4
#: The fine width (units of ``h``) below which the crease test is not trusted: ``(lo, hi)``, the
#: crease share fading in as ``fine`` grows from ``lo`` to ``hi`` (None, the default: at every
#: width).  Small objects get small widths (:func:`auto_sigma`): the ellipsoids of size 20 have
#: ``f`` = 1.54, balls r = 20 1.67, the real shapes at 256 across 1.75-2.45.  A setting for
#: measurements (``band_sigma.py --rules ffade=LO/HI``).
CREASE_MIN_FINE = None
#: New slice images (:func:`_slice_moments`) of a ring's first search reach this many ``max_move``
#: (plus 2 voxels) beyond what it needs, so that the ring's later searches (its meridian points lie
#: within ``max_move + 1`` of its seed) and its chord step reuse them.
IMAGE_MARGIN = 1.0


# ----------------------------------------------------------------------------------------------
# 1. The digital object I from the contours
# ----------------------------------------------------------------------------------------------
def _check_stack(stack) -> np.ndarray:
    zs = check_stack(stack)
    sx, sy = (float(v) for v in stack.spacing)
    if not (sx > 0 and sy > 0 and math.isfinite(sx) and math.isfinite(sy)):
        raise ValueError(f"band refinement needs a positive pixel size (dx, dy > 0); got spacing {stack.spacing}")
    for k, s in enumerate(stack.sections):
        for c in s.contours:
            c = np.asarray(c)
            if c.ndim != 2 or c.shape[1] != 2 or not np.issubdtype(c.dtype, np.integer):
                raise ValueError(
                    f"section {k} (z={s.z}): band refinement needs integer grid contours (k, 2); "
                    f"got dtype {c.dtype}, shape {c.shape}"
                )
    return zs


def _section_grid_index(zs: np.ndarray, h: float):
    """Integer lattice index of each section along z, and the lattice step in units of ``h``.

    Where the sections lie on a regular lattice ``z0 + n * dz`` (gaps allowed, e.g. omitted empty
    slices) returns ``(idx, dz_phys / h)``; otherwise (unevenly spaced sections) None.
    """
    if len(zs) == 1:
        return np.zeros(1, dtype=np.int64), 1.0
    dz = float(np.min(np.diff(zs)))
    idx = np.rint((zs - zs[0]) / dz)
    if np.max(np.abs(idx * dz - (zs - zs[0]))) > 1e-6 * dz:
        return None
    return idx.astype(np.int64), dz / h


def stack_points(stack: ContourStack, *, lattice: bool = True):
    """The grid points ``I`` of every section, recovered from its contours.

    ``U_k`` (the union of the closed cells with a corner in ``I_k``) is the region the section's
    contours bound; its cells are found by the even-odd rule (a cell is in ``U`` when a ray from
    its centre crosses the contours an odd number of times), so holes come out right.  A grid
    point is in ``I`` when its four cells are in ``U``.  (For contours traced from a mask this
    gives back the mask, except in configurations where four different points of ``I`` surround
    a point that is not, which a smooth surface's digitization does not produce.)

    Returns
    -------
    points : (nz, ny, nx) bool ndarray
        ``points[n, j, i]`` is the grid point ``(x0 + i, y0 + j)`` of lattice slice ``n`` (``n``
        counts in steps of the section spacing from the first section; missing slices are empty).
    x0, y0 : int
        Grid coordinates of ``points[:, 0, 0]``; the array has a margin of empty points all round.
    zidx : (n_sections,) int64
        The lattice slice of every section.
    dz : float or None
        Slice spacing in units of ``h = max(dx, dy)`` (the longer pixel side; the pixel side where
        pixels are square); None where the sections are not on a regular lattice.

    With ``lattice=False``, or where the sections do not lie on a regular lattice (unevenly spaced
    sections), section ``k`` is slice ``k`` (plus the margin) and ``dz`` is None: the slices' heights
    are the sections' own.
    """
    zs = _check_stack(stack)
    on = _section_grid_index(zs, max(float(v) for v in stack.spacing)) if lattice else None
    if on is not None:
        zidx, dz = on
    else:
        zidx, dz = np.arange(len(zs), dtype=np.int64), None
    allpts = [np.asarray(c, dtype=np.int64) for s in stack.sections for c in s.contours]
    if not allpts:
        raise ValueError("the contour stack holds no contour points")
    cat = np.concatenate(allpts)
    pad = 6
    x0, y0 = int(cat[:, 0].min()) - pad, int(cat[:, 1].min()) - pad
    nx = int(cat[:, 0].max()) - x0 + pad + 1
    ny = int(cat[:, 1].max()) - y0 + pad + 1
    nz = int(zidx[-1]) + 1 + 2 * pad
    pts = np.zeros((nz, ny, nx), dtype=np.bool_)
    for k, s in enumerate(stack.sections):
        if not s.contours:
            continue
        cells = np.zeros((ny, nx), dtype=np.int64)  # cells[j, i]: cell [x0+i, x0+i+1] x [y0+j, y0+j+1]
        for c in s.contours:
            c = np.ascontiguousarray(c, dtype=np.int64)
            if len(c) < 3:
                continue  # a pole point or a segment bounds no cell
            _toggle_cells(cells, c.reshape(-1, 2), x0, y0)
        _points_of_cells(cells, pts[zidx[k] + pad])
    return pts, x0, y0, zidx + pad, dz


@njit(cache=True)
def _toggle_cells(cells, c, x0, y0):
    """Count each vertical edge of the closed contour ``c`` in the cell to its right (``cells[j, i]``:
    cell ``[x0+i, x0+i+1] x [y0+j, y0+j+1]``); the parity of the row sums then tells the inside."""
    n = c.shape[0]
    for q in range(n):
        r = (q + 1) % n
        if c[r, 0] == c[q, 0]:
            cells[min(c[q, 1], c[r, 1]) - y0, c[q, 0] - x0] += 1


@njit(cache=True)
def _points_of_cells(cells, out):
    """The grid points of one section: a cell is in ``U`` when the running row sum of ``cells`` up
    to it is odd (even-odd rule); point ``(i, j)`` (``out[j, i]``, ``i, j >= 1``) is in ``I`` when its
    four cells ``(i-1..i, j-1..j)`` are in ``U``."""
    ny, nx = cells.shape
    inside = np.empty((ny, nx), dtype=np.bool_)
    for j in range(ny):
        run = 0
        for i in range(nx):
            run += cells[j, i]
            inside[j, i] = (run & 1) == 1
    for j in range(1, ny):
        for i in range(1, nx):
            out[j, i] = inside[j, i] and inside[j - 1, i] and inside[j, i - 1] and inside[j - 1, i - 1]


def _stack_grid(stack: ContourStack):
    """:func:`stack_points` with the lattice's grid record (:func:`_make_grid`): ``(pts, x0, y0, zidx,
    grid)``; sections off a regular lattice keep their own heights (the margins continue the end
    spacings)."""
    pts, x0, y0, zidx, dz = stack_points(stack)
    dx, dy = (float(v) for v in stack.spacing)
    if dz is not None:
        grid, _ = _make_grid(dx, dy, pts.shape[0], dz=dz)
    else:
        grid, _ = _make_grid(dx, dy, pts.shape[0], zs=stack.z, pad=int(zidx[0]))
    return pts, x0, y0, zidx, grid


# ----------------------------------------------------------------------------------------------
# 2. The blurred indicator, its gradient and Hessian, at any point
# ----------------------------------------------------------------------------------------------
def _make_grid(dx: float, dy: float, nz: int, *, dz: float | None = None, zs=None, pad: int = 0):
    """The lattice's geometry in one record: ``(grid, h)``.

    Lengths are measured in units of ``h``, the longer pixel side.  ``grid = (ax, ay, dz, zpos,
    zwt)``: ``ax = dx / h`` and ``ay = dy / h`` (at most 1, one of them 1) are a pixel's sides in
    those units, so the lattice point ``[n, j, i]`` of the array lies at ``(i ax, j ay, zpos[n]
    dz)``; ``dz`` is the slice spacing in those units (for unevenly spaced slices, their median
    spacing, a reference length); ``zpos (nz,)`` the slice positions in units of ``dz``; ``zwt``
    each slice's weight, the slab between the midpoints to its neighbours in units of ``dz``.
    Evenly spaced slices (``dz`` given) have ``zpos = 0, 1, 2, ...`` and ``zwt`` empty (every
    weight 1, and the normalisation of the blurred indicator a constant).  ``zs``: the heights of
    the array's slices ``pad .. nz - pad - 1`` (at least two; the margins continue the end
    spacings), for slices at any heights.
    """
    dx, dy = float(dx), float(dy)
    if not (dx > 0 and dy > 0 and math.isfinite(dx) and math.isfinite(dy)):
        raise ValueError(f"band refinement needs a positive pixel size; got dx={dx}, dy={dy}")
    h = max(dx, dy)
    ax, ay = dx / h, dy / h
    if zs is None:
        return (ax, ay, float(dz), np.arange(nz, dtype=np.float64), np.zeros(0)), h
    u = np.asarray(zs, dtype=np.float64) / h
    gaps = np.diff(u)
    ref = float(np.median(gaps))
    pos = np.empty(nz)
    m = len(u)
    pos[pad:pad + m] = (u - u[0]) / ref
    pos[:pad] = pos[pad] - (pos[pad + 1] - pos[pad]) * np.arange(pad, 0, -1)
    pos[pad + m:] = pos[pad + m - 1] + (pos[pad + m - 1] - pos[pad + m - 2]) * np.arange(1, nz - pad - m + 1)
    wt = np.empty(nz)
    wt[1:-1] = 0.5 * (pos[2:] - pos[:-2])
    wt[0], wt[-1] = pos[1] - pos[0], pos[-1] - pos[-2]  # the margins' spacing goes on beyond the array
    return (ax, ay, ref, pos, wt), h


def _grid_of_heights(dx: float, dy: float, zs, nz: int, pad: int):
    """:func:`_make_grid` for slices at the heights ``zs``: an even grid where they are evenly spaced
    (to ``1e-6`` of the step), else one with the slices' own positions and weights."""
    zs = np.asarray(zs, dtype=np.float64)
    h = max(float(dx), float(dy))
    if len(zs) < 2:
        return _make_grid(dx, dy, nz, dz=1.0)
    steps = np.diff(zs)
    if np.max(np.abs(steps - steps[0])) <= 1e-6 * abs(steps[0]):
        return _make_grid(dx, dy, nz, dz=float(steps[0]) / h)
    return _make_grid(dx, dy, nz, zs=zs, pad=pad)


def _as_grid(dz, nz: int):
    """A grid record from a slice spacing (square pixels, even slices), or the record itself."""
    if isinstance(dz, tuple):
        return dz
    return _make_grid(1.0, 1.0, nz, dz=float(dz))[0]


@njit(cache=True)
def _even(grid):
    return grid[4].shape[0] == 0


@njit(cache=True)
def _zweight(grid, n):
    """The weight of slice ``n`` (1 on evenly spaced slices)."""
    return 1.0 if grid[4].shape[0] == 0 else grid[4][n]


@njit(cache=True)
def _zwindow(grid, z, rad, nz):
    """``(k0, k1, zc)``: the slices within the Gaussian's reach ``rad`` of the fractional slice index
    ``z``, and its position ``zc`` (in units of ``dz``)."""
    dz = grid[2]
    if grid[4].shape[0] == 0:
        return max(int(math.floor(z - rad / dz)), 0), min(int(math.ceil(z + rad / dz)), nz - 1), z
    zpos = grid[3]
    f = min(max(int(math.floor(z)), 0), nz - 1)
    if f < nz - 1:
        zc = zpos[f] + (z - f) * (zpos[f + 1] - zpos[f])
    else:
        zc = zpos[f] + (z - f) * (zpos[f] - zpos[f - 1]) if f > 0 else z
    r = rad / dz
    k0 = f
    while k0 > 0 and zpos[k0 - 1] >= zc - r:
        k0 -= 1
    k1 = f
    while k1 < nz - 1 and zpos[k1 + 1] <= zc + r:
        k1 += 1
    return k0, k1, zc


@njit(cache=True)
def _lattice_norm(sigma, grid):
    """The normalisation of f: the sum over the lattice of exp(-|p|^2 / (2 sigma^2)), in-slice pixel
    sides ``ax, ay``, slice spacing ``dz``.  For unevenly spaced slices only the in-slice factor (the
    factor across the slices depends on the slice: :func:`_slice_norm`)."""
    ax, ay, dz = grid[0], grid[1], grid[2]
    rx = int(math.ceil(6.0 * sigma / ax)) + 1
    sx = 0.0
    for i in range(-rx, rx + 1):
        sx += math.exp(-(i * ax) ** 2 / (2.0 * sigma * sigma))
    ry = int(math.ceil(6.0 * sigma / ay)) + 1
    sy = 0.0
    for j in range(-ry, ry + 1):
        sy += math.exp(-(j * ay) ** 2 / (2.0 * sigma * sigma))
    if grid[4].shape[0] != 0:
        return sx * sy
    rz = int(math.ceil(6.0 * sigma / dz)) + 1
    s3 = 0.0
    for k in range(-rz, rz + 1):
        s3 += math.exp(-(k * dz) ** 2 / (2.0 * sigma * sigma))
    return sx * sy * s3


@njit(cache=True)
def _slice_norm(grid, sigma, norm, z, nz):
    """``(norm', a, b)`` at the fractional slice index ``z``: on evenly spaced slices ``(norm, 0, 0)``.

    On unevenly spaced slices the blur across the slices is the sum over the slices of their slab
    weight times the Gaussian, so the normalisation ``D(z) = sum_n zwt_n G(zpos_n - z)`` (which
    keeps a constant field constant) varies with the height; ``norm' = norm D``, and ``a = D'/D``,
    ``b = D''/D`` give the field's z-derivatives by the quotient rule (:func:`_z_correct`).  The
    slices beyond the array continue its end spacings."""
    if grid[4].shape[0] == 0:
        return norm, 0.0, 0.0
    dz, zpos, zwt = grid[2], grid[3], grid[4]
    rad = 4.0 * sigma
    k0, k1, zc = _zwindow(grid, z, rad, nz)
    s2 = sigma * sigma
    d0 = 0.0
    d1 = 0.0
    d2 = 0.0
    for n in range(k0, k1 + 1):
        w = (zpos[n] - zc) * dz
        e = math.exp(-(w * w) / (2.0 * s2)) * zwt[n]
        d0 += e
        d1 += e * w
        d2 += e * (w * w - s2)
    r = rad / dz
    g = zpos[nz - 1] - zpos[nz - 2]
    m = 1
    while zpos[nz - 1] + m * g <= zc + r:  # beyond the top
        w = (zpos[nz - 1] + m * g - zc) * dz
        e = math.exp(-(w * w) / (2.0 * s2)) * g
        d0 += e
        d1 += e * w
        d2 += e * (w * w - s2)
        m += 1
    g = zpos[1] - zpos[0]
    m = 1
    while zpos[0] - m * g >= zc - r:  # below the bottom
        w = (zpos[0] - m * g - zc) * dz
        e = math.exp(-(w * w) / (2.0 * s2)) * g
        d0 += e
        d1 += e * w
        d2 += e * (w * w - s2)
        m += 1
    return norm * d0, d1 / (d0 * s2), d2 / (d0 * s2 * s2)


@njit(cache=True)
def _z_correct(out, a, b):
    """The quotient rule for ``f = N / D(z)``: ``out`` holds ``N``'s values and derivatives divided by
    ``D`` (and the in-slice norm); ``a = D'/D``, ``b = D''/D`` (:func:`_slice_norm`)."""
    fz = out[3] - out[0] * a
    out[6] = out[6] - 2.0 * fz * a - out[0] * b
    out[8] = out[8] - out[1] * a
    out[9] = out[9] - out[2] * a
    out[3] = fz


@njit(cache=True)
def _field(pts, x, y, z, sigma, grid, norm, out):
    """f, grad f (3) and Hessian (xx, yy, zz, xy, xz, yz) of the blurred indicator at (x, y, z).

    ``(x, y)`` are array-local coordinates in units of ``h`` (the lattice point ``[n, j, i]`` at
    ``(i ax, j ay)``, see :func:`_make_grid`), ``z`` the slice index (fractional allowed).
    ``out`` receives the 10 numbers; f = sum_{p in I} w_p exp(-|p - x|^2 / (2 sigma^2)) / norm over
    the lattice points within ``4 sigma`` on each axis (``w_p``: the slice's weight).  The Gaussian is
    separable, so the weights are products of three 1D tables.  ``norm``: :func:`_lattice_norm`.
    """
    nz, ny, nx = pts.shape
    ax, ay, dz, zpos = grid[0], grid[1], grid[2], grid[3]
    rad = 4.0 * sigma
    i0 = max(int(math.floor((x - rad) / ax)), 0)
    i1 = min(int(math.ceil((x + rad) / ax)), nx - 1)
    j0 = max(int(math.floor((y - rad) / ay)), 0)
    j1 = min(int(math.ceil((y + rad) / ay)), ny - 1)
    k0, k1, zc = _zwindow(grid, z, rad, nz)
    s2 = sigma * sigma
    ex = np.empty(i1 - i0 + 1)
    ey = np.empty(j1 - j0 + 1)
    ez = np.empty(k1 - k0 + 1)
    for i in range(i0, i1 + 1):
        ex[i - i0] = math.exp(-((i * ax - x) ** 2) / (2.0 * s2))
    for j in range(j0, j1 + 1):
        ey[j - j0] = math.exp(-((j * ay - y) ** 2) / (2.0 * s2))
    for k in range(k0, k1 + 1):
        ez[k - k0] = math.exp(-(((zpos[k] - zc) * dz) ** 2) / (2.0 * s2)) * _zweight(grid, k)
    for q in range(10):
        out[q] = 0.0
    for k in range(k0, k1 + 1):
        wz = (zpos[k] - zc) * dz
        for j in range(j0, j1 + 1):
            wy = j * ay - y
            wyz = ey[j - j0] * ez[k - k0]
            # row sums over i of w, w*wx, w*wx^2
            s0 = 0.0
            s1 = 0.0
            s2x = 0.0
            for i in range(i0, i1 + 1):
                if pts[k, j, i]:
                    e = ex[i - i0]
                    wx = i * ax - x
                    s0 += e
                    s1 += e * wx
                    s2x += e * wx * wx
            if s0 == 0.0:
                continue
            s0 *= wyz
            s1 *= wyz
            s2x *= wyz
            out[0] += s0
            out[1] += s1
            out[2] += s0 * wy
            out[3] += s0 * wz
            out[4] += s2x - s0 * s2
            out[5] += s0 * (wy * wy - s2)
            out[6] += s0 * (wz * wz - s2)
            out[7] += s1 * wy
            out[8] += s1 * wz
            out[9] += s0 * wy * wz
    norm, a, b = _slice_norm(grid, sigma, norm, z, nz)
    out[0] /= norm
    for q in range(1, 4):
        out[q] /= norm * s2
    for q in range(4, 10):
        out[q] /= norm * s2 * s2
    if not _even(grid):
        _z_correct(out, a, b)


@njit(cache=True)
def _slice_moments(pts, k, sigma, grid, i0, i1, j0, j1, cols=False):
    """The solid blurred across the slices around lattice slice ``k``: three images of the box
    ``[j0, j1] x [i0, i1]``, ``M_p[j, i] = sum_n pts[n, j, i] c_n G(w_n) w_n^p`` (``p = 0, 1, 2``)
    with ``w_n = (zpos_n - zpos_k) dz``, ``c_n`` the slice's weight (:func:`_make_grid`; 1 on evenly
    spaced slices) and ``G(w) = exp(-w^2 / (2 sigma^2))`` over the slices within ``4 sigma``.

    The Gaussian is separable, so at every point of slice ``k`` the field and its derivatives are
    sums over the in-slice window of these images (:func:`_field_in_slice`): ``(8 sigma)^2``
    terms per evaluation instead of the ``(8 sigma)^3`` of :func:`_field`, which the level-set
    search of :func:`_move_to_surface` evaluates five times per vertex and search on average.

    ``cols``: the images column by column, ``M_p[i, j]`` (shape ``(3, i1 - i0 + 1, j1 - j0 + 1)``,
    the same numbers), as the searches read them (:func:`_level_cols`)."""
    nz = pts.shape[0]
    dz, zpos = grid[2], grid[3]
    rad = 4.0 * sigma
    k0, k1, zc = _zwindow(grid, float(k), rad, nz)
    s2 = sigma * sigma
    mom = np.zeros((3, i1 - i0 + 1, j1 - j0 + 1)) if cols else np.zeros((3, j1 - j0 + 1, i1 - i0 + 1))
    for n in range(k0, k1 + 1):
        w = (zpos[n] - zc) * dz
        e = math.exp(-(w * w) / (2.0 * s2)) * _zweight(grid, n)
        ew = e * w
        eww = ew * w
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                if pts[n, j, i]:
                    a, b = (i - i0, j - j0) if cols else (j - j0, i - i0)
                    mom[0, a, b] += e
                    mom[1, a, b] += ew
                    mom[2, a, b] += eww
    return mom


@njit(cache=True)
def _z_runs(pts):
    """``runs[n, j, i]``: how many slices from ``n`` up hold the value of ``pts[n, j, i]`` at ``(j, i)``
    (int32; 1 where the next slice differs).  :func:`_slice_moments_runs` reads a whole column's
    sums from it."""
    nz, ny, nx = pts.shape
    runs = np.empty((nz, ny, nx), np.int32)
    for j in range(ny):
        for i in range(nx):
            runs[nz - 1, j, i] = 1
    for n in range(nz - 2, -1, -1):
        for j in range(ny):
            for i in range(nx):
                runs[n, j, i] = runs[n + 1, j, i] + 1 if pts[n, j, i] == pts[n + 1, j, i] else 1
    return runs


@njit(cache=True)
def _slice_moments_runs(pts, runs, k, sigma, grid, i0, i1, j0, j1, cols=False):
    """:func:`_slice_moments` with the column runs of :func:`_z_runs`: the same images, bit for bit,
    on any grid (oblong pixels, unevenly spaced slices).

    The weights ``c_n G(w_n) w_n^p`` are computed as there; each image point sums its column's
    weights in slice order, starting from 0.  The sums of every stretch of consecutive slices,
    added in that order from 0, are tabulated once for the slice (``(8 sigma)^2 / 2`` entries): a
    column's first solid run takes its sum from the table (the same additions, so the same value;
    a column that is all solid over the slices within ``4 sigma`` is the one run that spans them
    all), an empty one keeps 0, and only the runs after the first of a column that crosses the
    surface more than once are summed voxel by voxel.  ``cols``: as there."""
    nz = pts.shape[0]
    dz, zpos = grid[2], grid[3]
    rad = 4.0 * sigma
    k0, k1, zc = _zwindow(grid, float(k), rad, nz)
    s2 = sigma * sigma
    nk = k1 - k0 + 1
    e = np.empty(nk)
    ew = np.empty(nk)
    eww = np.empty(nk)
    for n in range(k0, k1 + 1):
        w = (zpos[n] - zc) * dz
        e[n - k0] = math.exp(-(w * w) / (2.0 * s2)) * _zweight(grid, n)
        ew[n - k0] = e[n - k0] * w
        eww[n - k0] = ew[n - k0] * w
    # run[p, a, b] (a <= b): the weights e, ew, eww of slices k0 + a .. k0 + b summed in order from 0
    run = np.zeros((3, nk, nk))
    for a in range(nk):
        t0 = 0.0
        t1 = 0.0
        t2 = 0.0
        for b in range(a, nk):
            t0 += e[b]
            t1 += ew[b]
            t2 += eww[b]
            run[0, a, b] = t0
            run[1, a, b] = t1
            run[2, a, b] = t2
    mom = np.zeros((3, i1 - i0 + 1, j1 - j0 + 1)) if cols else np.zeros((3, j1 - j0 + 1, i1 - i0 + 1))
    for j in range(j0, j1 + 1):
        for i in range(i0, i1 + 1):
            a, b = (i - i0, j - j0) if cols else (j - j0, i - i0)
            if runs[k0, j, i] >= nk:  # one value over the whole column
                if pts[k0, j, i]:
                    mom[0, a, b] = run[0, 0, nk - 1]
                    mom[1, a, b] = run[1, 0, nk - 1]
                    mom[2, a, b] = run[2, 0, nk - 1]
                continue
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            first = True  # no run summed yet: the sums are still 0
            n = k0
            solid = pts[k0, j, i]  # the runs alternate between solid and empty
            while n <= k1:
                r = runs[n, j, i]
                if solid:
                    last = min(n + r, k1 + 1) - 1
                    if first:
                        a0 = run[0, n - k0, last - k0]
                        a1 = run[1, n - k0, last - k0]
                        a2 = run[2, n - k0, last - k0]
                        first = False
                    else:
                        for q in range(n, last + 1):
                            a0 += e[q - k0]
                            a1 += ew[q - k0]
                            a2 += eww[q - k0]
                n += r
                solid = not solid
            mom[0, a, b] = a0
            mom[1, a, b] = a1
            mom[2, a, b] = a2
    return mom


@njit(cache=True)
def _row_spans(mom):
    """``span (ny, 2)``: the first and last column (box-local) of each row of the images ``mom`` where
    ``M_0`` is not 0 (``(nx, -1)`` for an empty row).  ``M_0`` is 0 only where the column holds no
    point of ``I`` within the blur's reach, and then ``M_1 = M_2 = 0`` too: the sums of
    :func:`_field_in_slice` skip those columns, and the zeros between a row's ends add exact zeros."""
    nyb, nxb = mom.shape[1], mom.shape[2]
    span = np.empty((nyb, 2), np.int64)
    for jj in range(nyb):
        lo = nxb
        hi = -1
        for ii in range(nxb):
            if mom[0, jj, ii] != 0.0:
                if lo == nxb:
                    lo = ii
                hi = ii
        span[jj, 0] = lo
        span[jj, 1] = hi
    return span


@njit(cache=True)
def _x_weights(a0, a1, x, sigma, ax, powers):
    """The in-slice Gaussian weights of the columns ``a0 .. a1`` at ``x``: rows ``G``, ``G wx`` and
    (``powers = 3``) ``G wx^2`` of a ``(powers, a1 - a0 + 1)`` array, ``wx = i ax - x``, each the
    product that the sums of :func:`_field_in_slice` once formed term by term (so the same values)."""
    s2 = sigma * sigma
    w = np.empty((powers, a1 - a0 + 1))
    for i in range(a0, a1 + 1):
        wx = i * ax - x
        e = math.exp(-(wx ** 2) / (2.0 * s2))
        w[0, i - a0] = e
        w[1, i - a0] = e * wx
        if powers > 2:
            w[2, i - a0] = e * wx * wx
    return w


@njit(cache=True)
def _field_in_slice(mom, span, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, za, zb, out):
    """:func:`_field` at ``(x, y)`` of the slice whose :func:`_slice_moments` are ``mom`` (taken
    over the box from ``(i0, j0)``, which holds the window ``4 sigma`` around the point; ``nx, ny``
    are the volume's, the window is clipped to them as there; ``span``: :func:`_row_spans` of
    ``mom``).  ``ax, ay``: the pixel's sides; ``norm, za, zb``: the slice's :func:`_slice_norm`
    (``za = zb = 0``: evenly spaced slices, no correction).  Equal to :func:`_field` up to the
    rounding of the sums' order."""
    rad = 4.0 * sigma
    a0 = max(int(math.floor((x - rad) / ax)), 0)
    a1 = min(int(math.ceil((x + rad) / ax)), nx - 1)
    b0 = max(int(math.floor((y - rad) / ay)), 0)
    b1 = min(int(math.ceil((y + rad) / ay)), ny - 1)
    s2 = sigma * sigma
    w = _x_weights(a0, a1, x, sigma, ax, 3)
    for q in range(10):
        out[q] = 0.0
    for j in range(b0, b1 + 1):
        jj = j - j0
        lo = max(a0, span[jj, 0] + i0)  # the row's columns that meet the solid (zeros between add 0)
        hi = min(a1, span[jj, 1] + i0)
        if lo > hi:
            continue
        r0 = 0.0  # sum over the row of G M0, G wx M0, G wx^2 M0, G M1, G wx M1, G M2
        r1 = 0.0
        r2 = 0.0
        q0 = 0.0
        q1 = 0.0
        p0 = 0.0
        for i in range(lo, hi + 1):
            ii = i - i0
            c = i - a0
            m0 = mom[0, jj, ii]
            m1 = mom[1, jj, ii]
            r0 += w[0, c] * m0
            r1 += w[1, c] * m0
            r2 += w[2, c] * m0
            q0 += w[0, c] * m1
            q1 += w[1, c] * m1
            p0 += w[0, c] * mom[2, jj, ii]
        if r0 == 0.0:
            continue
        wy = j * ay - y
        ey = math.exp(-(wy * wy) / (2.0 * s2))  # (only for rows that meet the solid)
        out[0] += ey * r0
        out[1] += ey * r1
        out[2] += ey * r0 * wy
        out[3] += ey * q0
        out[4] += ey * (r2 - r0 * s2)
        out[5] += ey * r0 * (wy * wy - s2)
        out[6] += ey * (p0 - r0 * s2)
        out[7] += ey * r1 * wy
        out[8] += ey * q1
        out[9] += ey * q0 * wy
    out[0] /= norm
    for q in range(1, 4):
        out[q] /= norm * s2
    for q in range(4, 10):
        out[q] /= norm * s2 * s2
    if za != 0.0 or zb != 0.0:
        _z_correct(out, za, zb)


@njit(cache=True)
def _row_pair(span, i0, jj, a0, a1, two):
    """The columns ``lo .. hi`` that rows ``jj`` and (``two``) ``jj + 1`` of the images sum over in
    :func:`_gradient_in_slice` and :func:`_level_in_slice`, and which of the two rows meet the solid
    there: ``(lo, hi, first, second)``.  Where both do, the range covers both rows' spans (the
    zeros of one row beyond its span add exact zeros to its sums)."""
    loa = max(a0, span[jj, 0] + i0)
    hia = min(a1, span[jj, 1] + i0)
    lob, hib = a1 + 1, a0 - 1
    if two:
        lob = max(a0, span[jj + 1, 0] + i0)
        hib = min(a1, span[jj + 1, 1] + i0)
    first = loa <= hia
    second = lob <= hib
    if first and second:
        return min(loa, lob), max(hia, hib), True, True
    if first:
        return loa, hia, True, False
    return lob, hib, False, second


@njit(cache=True)
def _gradient_in_slice(mom, span, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, za, zb, out):
    """``f`` and ``grad f`` of :func:`_field_in_slice` into ``out[:4]`` (the same sums, so the same
    values; ``out[4:]`` is left as it was): what the level-set search needs at its start.  Two rows
    are summed in one pass (independent sums, each in its own order), then added in row order."""
    rad = 4.0 * sigma
    a0 = max(int(math.floor((x - rad) / ax)), 0)
    a1 = min(int(math.ceil((x + rad) / ax)), nx - 1)
    b0 = max(int(math.floor((y - rad) / ay)), 0)
    b1 = min(int(math.ceil((y + rad) / ay)), ny - 1)
    s2 = sigma * sigma
    w = _x_weights(a0, a1, x, sigma, ax, 2)
    f = 0.0
    fx = 0.0
    fy = 0.0
    fz = 0.0
    for j in range(b0, b1 + 1, 2):
        jj = j - j0
        lo, hi, first, second = _row_pair(span, i0, jj, a0, a1, j + 1 <= b1)
        r0 = 0.0  # row j: G M0, G wx M0, G M1
        r1 = 0.0
        q0 = 0.0
        t0 = 0.0  # row j + 1: the same
        t1 = 0.0
        u0 = 0.0
        if first and second:
            for i in range(lo, hi + 1):
                ii = i - i0
                c = i - a0
                m0 = mom[0, jj, ii]
                n0 = mom[0, jj + 1, ii]
                r0 += w[0, c] * m0
                r1 += w[1, c] * m0
                q0 += w[0, c] * mom[1, jj, ii]
                t0 += w[0, c] * n0
                t1 += w[1, c] * n0
                u0 += w[0, c] * mom[1, jj + 1, ii]
        elif first:
            for i in range(lo, hi + 1):
                m0 = mom[0, jj, i - i0]
                r0 += w[0, i - a0] * m0
                r1 += w[1, i - a0] * m0
                q0 += w[0, i - a0] * mom[1, jj, i - i0]
        elif second:
            for i in range(lo, hi + 1):
                n0 = mom[0, jj + 1, i - i0]
                t0 += w[0, i - a0] * n0
                t1 += w[1, i - a0] * n0
                u0 += w[0, i - a0] * mom[1, jj + 1, i - i0]
        if r0 != 0.0:
            wy = j * ay - y
            ey = math.exp(-(wy * wy) / (2.0 * s2))
            f += ey * r0
            fx += ey * r1
            fy += ey * r0 * wy
            fz += ey * q0
        if t0 != 0.0:
            wy = (j + 1) * ay - y
            ey = math.exp(-(wy * wy) / (2.0 * s2))
            f += ey * t0
            fx += ey * t1
            fy += ey * t0 * wy
            fz += ey * u0
    out[0] = f / norm
    out[1] = fx / (norm * s2)
    out[2] = fy / (norm * s2)
    out[3] = fz / (norm * s2)
    if za != 0.0 or zb != 0.0:
        out[3] = out[3] - out[0] * za  # the quotient rule's fz (:func:`_z_correct`)


@njit(cache=True)
def _level_in_slice(mom, span, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, out):
    """``f, fx, fy`` of :func:`_field_in_slice` into ``out[:3]`` (the same sums, so the same values;
    ``out[3:]`` is left as it was): what the level-set search needs at its steps.  Two rows at a
    time, as in :func:`_gradient_in_slice`."""
    rad = 4.0 * sigma
    a0 = max(int(math.floor((x - rad) / ax)), 0)
    a1 = min(int(math.ceil((x + rad) / ax)), nx - 1)
    b0 = max(int(math.floor((y - rad) / ay)), 0)
    b1 = min(int(math.ceil((y + rad) / ay)), ny - 1)
    s2 = sigma * sigma
    w = _x_weights(a0, a1, x, sigma, ax, 2)
    f = 0.0
    fx = 0.0
    fy = 0.0
    for j in range(b0, b1 + 1, 2):
        jj = j - j0
        lo, hi, first, second = _row_pair(span, i0, jj, a0, a1, j + 1 <= b1)
        r0 = 0.0
        r1 = 0.0
        t0 = 0.0
        t1 = 0.0
        if first and second:
            for i in range(lo, hi + 1):
                c = i - a0
                m0 = mom[0, jj, i - i0]
                n0 = mom[0, jj + 1, i - i0]
                r0 += w[0, c] * m0
                r1 += w[1, c] * m0
                t0 += w[0, c] * n0
                t1 += w[1, c] * n0
        elif first:
            for i in range(lo, hi + 1):
                m0 = mom[0, jj, i - i0]
                r0 += w[0, i - a0] * m0
                r1 += w[1, i - a0] * m0
        elif second:
            for i in range(lo, hi + 1):
                n0 = mom[0, jj + 1, i - i0]
                t0 += w[0, i - a0] * n0
                t1 += w[1, i - a0] * n0
        if r0 != 0.0:
            wy = j * ay - y
            ey = math.exp(-(wy * wy) / (2.0 * s2))  # (only for rows that meet the solid)
            f += ey * r0
            fx += ey * r1
            fy += ey * r0 * wy
        if t0 != 0.0:
            wy = (j + 1) * ay - y
            ey = math.exp(-(wy * wy) / (2.0 * s2))
            f += ey * t0
            fx += ey * t1
            fy += ey * t0 * wy
    out[0] = f / norm
    out[1] = fx / (norm * s2)
    out[2] = fy / (norm * s2)


# The searches' evaluations read the images column by column (``cols=True`` of the builders):
# every row's sums take the columns' terms in column order from 0, as the row-by-row forms above,
# so each sum gets the same additions, but the rows are independent sums that the compiler
# updates four at a time, and four columns are added to each row in one pass (``((r + a) + b) +
# ...``, the same order).  A column's terms count only between its first and last row where
# ``M_0`` is not 0 (:func:`_row_spans` of the column images); a pass runs over the rows of its
# columns' spans together, and the terms it adds beyond a column's span (or for a column the window
# holds none of) are exact zeros, which leave a sum that starts at +0 unchanged, as the zeros that
# the row-by-row forms add between a row's ends.  So the values are the same bit for bit.

@njit(cache=True)
def _window(x, y, sigma, ax, ay, nx, ny):
    """The lattice window ``(a0, a1, b0, b1)`` of the sums at ``(x, y)`` (clipped to the volume)."""
    rad = 4.0 * sigma
    a0 = max(int(math.floor((x - rad) / ax)), 0)
    a1 = min(int(math.ceil((x + rad) / ax)), nx - 1)
    b0 = max(int(math.floor((y - rad) / ay)), 0)
    b1 = min(int(math.ceil((y + rad) / ay)), ny - 1)
    return a0, a1, b0, b1


@njit(cache=True)
def _workspace(sigma, ax, ay):
    """The workspace of :func:`_level_cols` and its siblings: 9 rows (the per-row sums, the
    columns' weights ``G, G wx`` and the rows' weights that :func:`_level_cols` keeps for
    :func:`_field_after_level`), each longer than any window's rows or columns."""
    return np.empty((9, int(math.ceil(8.0 * sigma / min(ax, ay))) + 4))


@njit(cache=True)
def _col_weights(cspan, i, i0, j0, b0, b1, x, ax, s2):
    """Column ``i``'s in-slice weights ``G, G wx, G wx^2`` (:func:`_x_weights`' products) and the rows
    ``lo .. hi`` of the window ``b0 .. b1`` where its ``M_0`` may be non-zero; weights 0 where none is."""
    ii = i - i0
    lo = max(b0, cspan[ii, 0] + j0)
    hi = min(b1, cspan[ii, 1] + j0)
    if lo > hi:
        return 0.0, 0.0, 0.0, lo, hi
    wx = i * ax - x
    e = math.exp(-(wx ** 2) / (2.0 * s2))
    return e, e * wx, e * wx * wx, lo, hi


@njit(cache=True)
def _cols_sums(momt, cspan, i0, j0, a0, a1, b0, b1, x, ax, s2, ws, nsum):
    """The per-row sums of the window's columns into ``ws[:nsum, :b1 - b0 + 1]``: ``nsum = 2``: ``G M0,
    G wx M0``; 3: and ``G M1``; 6: ``G M0, G wx M0, G wx^2 M0, G M1, G wx M1, G M2`` (the sums of
    :func:`_level_in_slice`, :func:`_gradient_in_slice` and :func:`_field_in_slice`).  With
    ``nsum = 2`` the columns' weights ``G, G wx`` are kept in ``ws[6:8, :a1 - a0 + 1]``."""
    nr = b1 - b0 + 1
    for q in range(nsum):
        for t in range(nr):
            ws[q, t] = 0.0
    m0 = momt[0]
    m1 = momt[1]
    m2 = momt[2]
    r0 = ws[0]
    r1 = ws[1]
    r2 = ws[2]
    r3 = ws[3]
    r4 = ws[4]
    r5 = ws[5]
    i = a0
    while i <= a1:
        g = 4 if i + 3 <= a1 else 1  # columns in this pass
        ea, fa, ga, lo, hi = _col_weights(cspan, i, i0, j0, b0, b1, x, ax, s2)
        eb = fb = gb = ec = fc = gc = ed = fd = gd = 0.0
        if g == 4:
            eb, fb, gb, lb, hb = _col_weights(cspan, i + 1, i0, j0, b0, b1, x, ax, s2)
            ec, fc, gc, lc, hc = _col_weights(cspan, i + 2, i0, j0, b0, b1, x, ax, s2)
            ed, fd, gd, ld, hd = _col_weights(cspan, i + 3, i0, j0, b0, b1, x, ax, s2)
            lo = min(min(lo, lb), min(lc, ld))
            hi = max(max(hi, hb), max(hc, hd))
        if nsum == 2:
            ws[6, i - a0] = ea
            ws[7, i - a0] = fa
            if g == 4:
                ws[6, i - a0 + 1] = eb
                ws[7, i - a0 + 1] = fb
                ws[6, i - a0 + 2] = ec
                ws[7, i - a0 + 2] = fc
                ws[6, i - a0 + 3] = ed
                ws[7, i - a0 + 3] = fd
        if lo > hi:
            i += g
            continue
        ia = np.uintp(i - i0)
        oc = lo - j0  # >= 0: the box holds the window
        orow = lo - b0
        if g == 4:
            ib, ic, id_ = ia + np.uintp(1), ia + np.uintp(2), ia + np.uintp(3)
            if nsum == 2:
                for t in range(hi - lo + 1):
                    u = np.uintp(oc + t)
                    v = np.uintp(orow + t)
                    pa, pb, pc, pd = m0[ia, u], m0[ib, u], m0[ic, u], m0[id_, u]
                    r0[v] = r0[v] + ea * pa + eb * pb + ec * pc + ed * pd
                    r1[v] = r1[v] + fa * pa + fb * pb + fc * pc + fd * pd
            elif nsum == 3:
                for t in range(hi - lo + 1):
                    u = np.uintp(oc + t)
                    v = np.uintp(orow + t)
                    pa, pb, pc, pd = m0[ia, u], m0[ib, u], m0[ic, u], m0[id_, u]
                    r0[v] = r0[v] + ea * pa + eb * pb + ec * pc + ed * pd
                    r1[v] = r1[v] + fa * pa + fb * pb + fc * pc + fd * pd
                    r2[v] = r2[v] + ea * m1[ia, u] + eb * m1[ib, u] + ec * m1[ic, u] + ed * m1[id_, u]
            else:
                for t in range(hi - lo + 1):
                    u = np.uintp(oc + t)
                    v = np.uintp(orow + t)
                    pa, pb, pc, pd = m0[ia, u], m0[ib, u], m0[ic, u], m0[id_, u]
                    qa, qb, qc, qd = m1[ia, u], m1[ib, u], m1[ic, u], m1[id_, u]
                    r0[v] = r0[v] + ea * pa + eb * pb + ec * pc + ed * pd
                    r1[v] = r1[v] + fa * pa + fb * pb + fc * pc + fd * pd
                    r2[v] = r2[v] + ga * pa + gb * pb + gc * pc + gd * pd
                    r3[v] = r3[v] + ea * qa + eb * qb + ec * qc + ed * qd
                    r4[v] = r4[v] + fa * qa + fb * qb + fc * qc + fd * qd
                    r5[v] = r5[v] + ea * m2[ia, u] + eb * m2[ib, u] + ec * m2[ic, u] + ed * m2[id_, u]
        else:
            for t in range(hi - lo + 1):
                u = np.uintp(oc + t)
                v = np.uintp(orow + t)
                pa = m0[ia, u]
                r0[v] = r0[v] + ea * pa
                r1[v] = r1[v] + fa * pa
                if nsum == 3:
                    r2[v] = r2[v] + ea * m1[ia, u]
                elif nsum == 6:
                    qa = m1[ia, u]
                    r2[v] = r2[v] + ga * pa
                    r3[v] = r3[v] + ea * qa
                    r4[v] = r4[v] + fa * qa
                    r5[v] = r5[v] + ea * m2[ia, u]
        i += g


@njit(cache=True)
def _level_cols(momt, cspan, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, out, ws):
    """:func:`_level_in_slice` from the column images ``momt`` (``cspan``: their column spans): the
    same ``f, fx, fy`` into ``out[:3]``.  ``ws``: :func:`_workspace`; its sums and weights stay
    there for :func:`_field_after_level` at the same point."""
    a0, a1, b0, b1 = _window(x, y, sigma, ax, ay, nx, ny)
    s2 = sigma * sigma
    _cols_sums(momt, cspan, i0, j0, a0, a1, b0, b1, x, ax, s2, ws, 2)
    f = 0.0
    fx = 0.0
    fy = 0.0
    for j in range(b0, b1 + 1):
        t0 = ws[0, j - b0]
        if t0 != 0.0:
            wy = j * ay - y
            ey = math.exp(-(wy * wy) / (2.0 * s2))
            ws[8, j - b0] = ey  # kept for :func:`_field_after_level`
            f += ey * t0
            fx += ey * ws[1, j - b0]
            fy += ey * t0 * wy
    out[0] = f / norm
    out[1] = fx / (norm * s2)
    out[2] = fy / (norm * s2)


@njit(cache=True)
def _gradient_cols(momt, cspan, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, za, zb, out, ws):
    """:func:`_gradient_in_slice` from the column images: the same ``f, grad f`` into ``out[:4]``."""
    a0, a1, b0, b1 = _window(x, y, sigma, ax, ay, nx, ny)
    s2 = sigma * sigma
    _cols_sums(momt, cspan, i0, j0, a0, a1, b0, b1, x, ax, s2, ws, 3)
    f = 0.0
    fx = 0.0
    fy = 0.0
    fz = 0.0
    for j in range(b0, b1 + 1):
        t0 = ws[0, j - b0]
        if t0 != 0.0:
            wy = j * ay - y
            ey = math.exp(-(wy * wy) / (2.0 * s2))
            f += ey * t0
            fx += ey * ws[1, j - b0]
            fy += ey * t0 * wy
            fz += ey * ws[2, j - b0]
    out[0] = f / norm
    out[1] = fx / (norm * s2)
    out[2] = fy / (norm * s2)
    out[3] = fz / (norm * s2)
    if za != 0.0 or zb != 0.0:
        out[3] = out[3] - out[0] * za  # the quotient rule's fz (:func:`_z_correct`)


@njit(cache=True)
def _field_cols(momt, cspan, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, za, zb, out, ws):
    """:func:`_field_in_slice` from the column images: the same 10 numbers."""
    a0, a1, b0, b1 = _window(x, y, sigma, ax, ay, nx, ny)
    s2 = sigma * sigma
    _cols_sums(momt, cspan, i0, j0, a0, a1, b0, b1, x, ax, s2, ws, 6)
    for q in range(10):
        out[q] = 0.0
    for j in range(b0, b1 + 1):
        r0 = ws[0, j - b0]
        if r0 == 0.0:
            continue
        wy = j * ay - y
        ey = math.exp(-(wy * wy) / (2.0 * s2))
        r1 = ws[1, j - b0]
        q0 = ws[3, j - b0]
        out[0] += ey * r0
        out[1] += ey * r1
        out[2] += ey * r0 * wy
        out[3] += ey * q0
        out[4] += ey * (ws[2, j - b0] - r0 * s2)
        out[5] += ey * r0 * (wy * wy - s2)
        out[6] += ey * (ws[5, j - b0] - r0 * s2)
        out[7] += ey * r1 * wy
        out[8] += ey * ws[4, j - b0]
        out[9] += ey * q0 * wy
    out[0] /= norm
    for q in range(1, 4):
        out[q] /= norm * s2
    for q in range(4, 10):
        out[q] /= norm * s2 * s2
    if za != 0.0 or zb != 0.0:
        _z_correct(out, za, zb)


@njit(cache=True)
def _field_after_level(momt, cspan, i0, j0, nx, ny, x, y, sigma, ax, ay, norm, za, zb, out, ws):
    """:func:`_field_cols` at the point of the last :func:`_level_cols` call with this ``ws``: its
    sums ``G M0, G wx M0`` and its columns' and rows' weights are taken from ``ws`` (the same
    numbers), only the other four sums are made (in the same passes and order as there)."""
    a0, a1, b0, b1 = _window(x, y, sigma, ax, ay, nx, ny)
    s2 = sigma * sigma
    nr = b1 - b0 + 1
    for q in range(2, 6):
        for t in range(nr):
            ws[q, t] = 0.0
    m0 = momt[0]
    m1 = momt[1]
    m2 = momt[2]
    r2 = ws[2]
    r3 = ws[3]
    r4 = ws[4]
    r5 = ws[5]
    i = a0
    while i <= a1:
        g = 4 if i + 3 <= a1 else 1
        lo, hi = b1 + 1, b0 - 1
        for c in range(i, i + g):  # the pass's rows, as :func:`_cols_sums` takes them
            ii = c - i0
            lo = min(lo, max(b0, cspan[ii, 0] + j0))
            hi = max(hi, min(b1, cspan[ii, 1] + j0))
        if lo > hi:
            i += g
            continue
        ea, fa = ws[6, i - a0], ws[7, i - a0]
        ga = fa * (i * ax - x)  # e wx wx, as :func:`_col_weights` forms it
        ia = np.uintp(i - i0)
        oc = lo - j0
        orow = lo - b0
        if g == 4:
            eb, fb = ws[6, i - a0 + 1], ws[7, i - a0 + 1]
            ec, fc = ws[6, i - a0 + 2], ws[7, i - a0 + 2]
            ed, fd = ws[6, i - a0 + 3], ws[7, i - a0 + 3]
            gb = fb * ((i + 1) * ax - x)
            gc = fc * ((i + 2) * ax - x)
            gd = fd * ((i + 3) * ax - x)
            ib, ic, id_ = ia + np.uintp(1), ia + np.uintp(2), ia + np.uintp(3)
            for t in range(hi - lo + 1):
                u = np.uintp(oc + t)
                v = np.uintp(orow + t)
                pa, pb, pc, pd = m0[ia, u], m0[ib, u], m0[ic, u], m0[id_, u]
                qa, qb, qc, qd = m1[ia, u], m1[ib, u], m1[ic, u], m1[id_, u]
                r2[v] = r2[v] + ga * pa + gb * pb + gc * pc + gd * pd
                r3[v] = r3[v] + ea * qa + eb * qb + ec * qc + ed * qd
                r4[v] = r4[v] + fa * qa + fb * qb + fc * qc + fd * qd
                r5[v] = r5[v] + ea * m2[ia, u] + eb * m2[ib, u] + ec * m2[ic, u] + ed * m2[id_, u]
        else:
            for t in range(hi - lo + 1):
                u = np.uintp(oc + t)
                v = np.uintp(orow + t)
                qa = m1[ia, u]
                r2[v] = r2[v] + ga * m0[ia, u]
                r3[v] = r3[v] + ea * qa
                r4[v] = r4[v] + fa * qa
                r5[v] = r5[v] + ea * m2[ia, u]
        i += g
    for q in range(10):
        out[q] = 0.0
    for j in range(b0, b1 + 1):
        r0 = ws[0, j - b0]
        if r0 == 0.0:
            continue
        wy = j * ay - y
        ey = ws[8, j - b0]
        r1 = ws[1, j - b0]
        q0 = ws[3, j - b0]
        out[0] += ey * r0
        out[1] += ey * r1
        out[2] += ey * r0 * wy
        out[3] += ey * q0
        out[4] += ey * (ws[2, j - b0] - r0 * s2)
        out[5] += ey * r0 * (wy * wy - s2)
        out[6] += ey * (ws[5, j - b0] - r0 * s2)
        out[7] += ey * r1 * wy
        out[8] += ey * ws[4, j - b0]
        out[9] += ey * q0 * wy
    out[0] /= norm
    for q in range(1, 4):
        out[q] /= norm * s2
    for q in range(4, 10):
        out[q] /= norm * s2 * s2
    if za != 0.0 or zb != 0.0:
        _z_correct(out, za, zb)

@njit(cache=True)
def _images_for(pts, k, sigma, grid, xlo, xhi, ylo, yhi, reach, margin, mom, span, box, runs=None):
    """The images of slice ``k`` (:func:`_slice_moments`) over a box holding the windows of every
    point of ``[xlo, xhi] x [ylo, yhi]`` widened by ``reach`` (lengths in units of ``h``), with their
    :func:`_row_spans`: ``(mom, span)`` themselves when their box (``box = (k, i0, i1, j0, j1)``,
    pixel indices, ``k = -1``: none) holds that already, else new images over that box widened by
    ``margin`` more (so the next searches of the slice find them), ``box`` updated in place.  The
    images at a lattice point do not depend on the box.  ``runs`` (:func:`_z_runs` of ``pts``,
    optional) makes them faster, not different.  The images are kept column by column (``cols``
    of the builders; ``span`` holds the columns' first and last rows), as :func:`_level_cols` and
    its siblings read them."""
    nz, ny, nx = pts.shape
    ax, ay = grid[0], grid[1]
    i0 = min(max(int(math.floor((xlo - reach) / ax)), 0), nx - 1)
    i1 = max(min(int(math.ceil((xhi + reach) / ax)), nx - 1), i0)
    j0 = min(max(int(math.floor((ylo - reach) / ay)), 0), ny - 1)
    j1 = max(min(int(math.ceil((yhi + reach) / ay)), ny - 1), j0)
    if box[0] == k and box[1] <= i0 and i1 <= box[2] and box[3] <= j0 and j1 <= box[4]:
        return mom, span
    box[0] = k
    box[1] = min(max(int(math.floor((xlo - reach - margin) / ax)), 0), nx - 1)
    box[2] = max(min(int(math.ceil((xhi + reach + margin) / ax)), nx - 1), box[1])
    box[3] = min(max(int(math.floor((ylo - reach - margin) / ay)), 0), ny - 1)
    box[4] = max(min(int(math.ceil((yhi + reach + margin) / ay)), ny - 1), box[3])
    if runs is None:
        mom = _slice_moments(pts, k, sigma, grid, box[1], box[2], box[3], box[4], True)
    else:
        mom = _slice_moments_runs(pts, runs, k, sigma, grid, box[1], box[2], box[3], box[4], True)
    return mom, _row_spans(mom)


def _no_images():
    """An empty slot for :func:`_images_for`: ``(mom, box, span)``."""
    return np.zeros((3, 1, 1)), np.full(5, -1, dtype=np.int64), np.zeros((1, 2), dtype=np.int64)


def _fields_in_slice(pts, xy, k, sigma, grid, mom, box, span, margin, runs=None, *, full=True):
    """:func:`_fields_kernel`: ``(out (n, 10), (mom, span))``; ``grid`` may be a slice spacing (square
    pixels, even slices); ``runs``: as in :func:`_images_for`; ``full=False``: only ``f`` and
    ``grad f`` (``out[:, :4]``, by :func:`_gradient_in_slice`: the same values), the rest 0."""
    args = (pts, xy, k, sigma, _as_grid(grid, pts.shape[0]), mom, span, box, margin, np.bool_(full))
    out, mom, span = _fields_kernel(*args) if runs is None else _fields_kernel(*args, runs)
    return out, (mom, span)


@njit(cache=True)
def _fields_kernel(pts, xy, k, sigma, grid, mom, span, box, margin, full, runs=None):
    """:func:`_field` at the points ``xy (n, 2)`` of lattice slice ``k``, through the slice's images
    (:func:`_images_for`, reused from ``mom, span, box`` where they cover the points' windows):
    ``(out (n, 10), mom, span)``; where not ``full``, ``out[:, :4]`` only (:func:`_gradient_in_slice`)."""
    nz, ny, nx = pts.shape
    n = xy.shape[0]
    out = np.zeros((n, 10))
    if n == 0:
        return out, mom, span
    mom, span = _images_for(pts, k, sigma, grid, np.min(xy[:, 0]), np.max(xy[:, 0]), np.min(xy[:, 1]),
                            np.max(xy[:, 1]), 4.0 * sigma + 1.0, margin, mom, span, box, runs)
    norm, za, zb = _slice_norm(grid, sigma, _lattice_norm(sigma, grid), float(k), nz)
    buf = np.zeros(10)
    ws = _workspace(sigma, grid[0], grid[1])
    for m in range(n):
        if full:
            _field_cols(mom, span, box[1], box[3], nx, ny, xy[m, 0], xy[m, 1], sigma, grid[0], grid[1], norm, za,
                        zb, buf, ws)
        else:
            _gradient_cols(mom, span, box[1], box[3], nx, ny, xy[m, 0], xy[m, 1], sigma, grid[0], grid[1], norm,
                           za, zb, buf, ws)
        out[m, :] = buf
    return out, mom, span


def blurred_indicator(points, xyz, sigma: float = 1.0, dz: float = 1.0, *, spacing=(1.0, 1.0),
                      heights=None) -> np.ndarray:
    """The blurred indicator ``f`` (step 2 of the module docstring) and its derivatives at points.

    Parameters
    ----------
    points : (nz, ny, nx) bool ndarray
        Lattice points of the solid (as from :func:`stack_points`).
    xyz : (n, 3) array_like
        Array-local coordinates ``(x, y, n)``: ``x, y`` in units of ``h``, the longer pixel side
        (the point ``points[n, j, i]`` lies at ``(i dx / h, j dy / h)``; with square pixels these
        are pixel indices), ``n`` the slice index (fractional allowed).
    sigma : float
        Gaussian width in units of ``h``.
    dz : float
        Slice spacing in units of ``h`` (ignored with ``heights``).
    spacing : (dx, dy)
        Pixel size (only its shape counts: ``dx / h, dy / h``).
    heights : (nz,) array_like, optional
        The slices' heights in the unit of ``spacing``, for unevenly spaced slices: each slice is
        weighted by the slab between the midpoints to its neighbours and the blur across the
        slices is normalised at every height (a constant stays constant).

    Returns
    -------
    (n, 10) ndarray
        ``f, fx, fy, fz, fxx, fyy, fzz, fxy, fxz, fyz`` (derivatives per unit ``h``).
    """
    pts = np.ascontiguousarray(points, dtype=np.bool_)
    if heights is None:
        grid, _ = _make_grid(spacing[0], spacing[1], pts.shape[0], dz=float(dz))
    else:
        grid, _ = _make_grid(spacing[0], spacing[1], pts.shape[0], zs=heights)
    p = np.ascontiguousarray(xyz, dtype=np.float64).reshape(-1, 3)
    return _field_many(pts, p, float(sigma), grid)


def _field_many(pts, p, sigma, grid):
    """:func:`_field` at the points ``p (n, 3)``; ``grid`` may be a slice spacing (square pixels, even slices)."""
    return _field_many_kernel(pts, p, sigma, _as_grid(grid, pts.shape[0]))


@njit(cache=True)
def _field_many_kernel(pts, p, sigma, grid):
    norm = _lattice_norm(sigma, grid)
    out = np.empty((p.shape[0], 10))
    buf = np.empty(10)
    for n in range(p.shape[0]):
        _field(pts, p[n, 0], p[n, 1], p[n, 2], sigma, grid, norm, buf)
        out[n, :] = buf
    return out


# ----------------------------------------------------------------------------------------------
# 4. The band U_k \ int(V_k) of a slice
# ----------------------------------------------------------------------------------------------
@njit(cache=True)
def _cell_corners(pts, k, i, j):
    """Number of corners of cell [i, i+1] x [j, j+1] (array-local) in I of slice k."""
    nz, ny, nx = pts.shape
    c = 0
    for dj in range(2):
        for di in range(2):
            ii, jj = i + di, j + dj
            if 0 <= ii < nx and 0 <= jj < ny and pts[k, jj, ii]:
                c += 1
    return c


@njit(cache=True)
def _in_band_idx(pts, k, x, y):
    """Is the point (x, y) (array-local pixel indices) of slice k in the closed band U_k minus int(V_k)?

    The cells whose closure holds the point are examined (one, two or four of them, with a 1e-9
    tolerance on either side of a cell edge): the point is in ``U`` if one of them has a corner in
    ``I``; it is interior to ``V`` if all of them have their four corners in ``I``.
    """
    eps = 1e-9
    fx = math.floor(x)
    fy = math.floor(y)
    ilo = int(fx) - 1 if x - fx < eps else int(fx)
    ihi = int(fx) + 1 if fx + 1.0 - x < eps else int(fx)
    jlo = int(fy) - 1 if y - fy < eps else int(fy)
    jhi = int(fy) + 1 if fy + 1.0 - y < eps else int(fy)
    in_u = False
    all_v = True
    for i in range(ilo, ihi + 1):
        for j in range(jlo, jhi + 1):
            c = _cell_corners(pts, k, i, j)
            if c > 0:
                in_u = True
            if c < 4:
                all_v = False
    return in_u and not all_v


@njit(cache=True)
def _in_band(pts, k, x, y, grid):
    """:func:`_in_band_idx` at the point ``(x, y)`` in units of ``h`` (pixel ``(i, j)`` at ``(i ax, j ay)``)."""
    return _in_band_idx(pts, k, x / grid[0], y / grid[1])


@njit(cache=True)
def _off_band(pts, k, xy, grid):
    """Whether each point ``xy (n, 2)`` (units of ``h``) lies outside slice ``k``'s band (:func:`_in_band`)."""
    out = np.empty(xy.shape[0], dtype=np.bool_)
    for n in range(xy.shape[0]):
        out[n] = not _in_band(pts, k, xy[n, 0], xy[n, 1], grid)
    return out


def band_violations(stack: ContourStack, mesh: Mesh) -> int:
    """Number of mesh vertices on a section that lie outside that section's band ``U_k \\ int(V_k)``.

    Vertices whose height is not a section's (half-slice caps) are not counted.
    """
    pts, x0, y0, zidx, _ = stack_points(stack)
    zs = stack.z
    v = mesh.vertices
    dx, dy = (float(t) for t in stack.spacing)
    ox, oy = (float(t) for t in stack.origin)
    pos = np.clip(np.searchsorted(zs, v[:, 2]), 0, len(zs) - 1)
    on = np.abs(zs[pos] - v[:, 2]) <= 1e-9 * max(1.0, float(np.abs(zs).max()))
    bad = 0
    for n in np.flatnonzero(on):
        if not _in_band_idx(pts, int(zidx[pos[n]]), (v[n, 0] - ox) / dx - x0, (v[n, 1] - oy) / dy - y0):
            bad += 1
    return bad


def in_band(points, k, xy) -> np.ndarray:
    """Whether each point ``xy (n, 2)`` (array-local pixel indices) lies in the band of slice ``k``."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    return np.array([_in_band_idx(points, int(k), float(a), float(b)) for a, b in xy], dtype=bool)


# ----------------------------------------------------------------------------------------------
# 3 + 4. Moving the vertices
# ----------------------------------------------------------------------------------------------
@njit(cache=True)
def _back_into_band(pts, k, x0, y0, tx, ty, steps, out, n, grid):
    """Walk from ``(tx, ty)`` back towards ``(x0, y0)`` (in the band) in ``steps`` samples; write the
    first sample inside slice ``k``'s band to ``out[n]`` (``out[n]`` keeps its value if none is).

    A sample off the band that lies well inside one cell (further than ``1e-6`` pixel from its
    sides, far beyond :func:`_in_band_idx`'s tolerance) is in a cell that is not a band cell (its
    corners all in ``I`` or none), and so is every later sample on the segment's stretch through
    that cell's inner part: the walk skips those without testing them (the same first sample as
    testing every one)."""
    ax, ay = grid[0], grid[1]
    du = (tx - x0) / ax  # the walk's direction in pixel indices, per unit of a
    dv = (ty - y0) / ay
    m = 1e-6
    q = 1
    while q <= steps:
        a = 1.0 - q / steps
        px, py = x0 + a * (tx - x0), y0 + a * (ty - y0)
        if _in_band(pts, k, px, py, grid):
            out[n, 0], out[n, 1] = px, py
            return
        u, v = px / ax, py / ay
        fx, fy = math.floor(u), math.floor(v)
        if u - fx > m and fx + 1.0 - u > m and v - fy > m and fy + 1.0 - v > m:
            # the smallest a down to which the segment stays within m of the cell's inside (a decreases)
            alo = 0.0
            if du > 0.0:
                alo = max(alo, a - (u - fx - m) / du)
            elif du < 0.0:
                alo = max(alo, a - (fx + 1.0 - m - u) / -du)
            if dv > 0.0:
                alo = max(alo, a - (v - fy - m) / dv)
            elif dv < 0.0:
                alo = max(alo, a - (fy + 1.0 - m - v) / -dv)
            # samples q' <= (1 - alo) steps - 1 have a' > alo: inside the same cell, off the band
            q = max(q + 1, int(math.floor((1.0 - alo) * steps)))
        else:
            q += 1


@njit(cache=True)
def _mean_curvature_shift(buf, sigma):
    """Normal shift ``(k1 + k2) sigma^2 / 2`` of the true surface beyond the 1/2-level, and |grad f|."""
    gx, gy, gz = buf[1], buf[2], buf[3]
    g2 = gx * gx + gy * gy + gz * gz
    g = math.sqrt(g2)
    if g == 0.0:
        return 0.0, 0.0
    lap = buf[4] + buf[5] + buf[6]
    ghg = (gx * gx * buf[4] + gy * gy * buf[5] + gz * gz * buf[6]
           + 2.0 * (gx * gy * buf[7] + gx * gz * buf[8] + gy * gz * buf[9]))
    # outward normal n = -grad f / |grad f|; div n = -(lap - g^T H g / |g|^2) / |g| = k1 + k2
    ksum = -(lap - ghg / g2) / g
    return 0.5 * ksum * sigma * sigma, g


def _move_to_surface(pts, xy, kz, sigma, grid, curvature, max_move, out, strict, found):
    """Steps 3-4 for every vertex: returns the number of vertices clamped into their band.

    ``found (n,)`` receives whether the search reached the level (False: the vertex was left where
    it was; a vertex clamped back onto its start did find it).

    ``xy (n, 2)`` array-local positions (units of ``h``), ``kz (n,)`` their lattice slice (-1: leave
    unmoved), ``grid`` the lattice (:func:`_make_grid`).
    ``strict``: a vertex moves only where the search ends on the level (``|f - 1/2| < 1e-6``);
    otherwise one whose slice has no level within reach (a part thinner than the blur) is
    dragged to the end of the search interval.
    """
    mom, box, span = _no_images()
    clamped, _, _ = _move_with_images(pts, xy, kz, float(sigma), _as_grid(grid, pts.shape[0]), curvature, max_move, out,
                                      strict, found, mom, span, box, 0.0, float(SHIFT_CUBIC))
    return clamped


@njit(cache=True)
def _move_with_images(pts, xy, kz, sigma, grid, curvature, max_move, out, strict, found, mom, span, box, margin,
                      cubic=0.0, runs=None):
    """:func:`_move_to_surface` with the slice images ``mom, span, box`` of an earlier search (see
    :func:`_images_for`; ``margin``: how much wider new images are made; ``runs``: as there);
    ``(clamped, mom, span)``."""
    norm0 = _lattice_norm(sigma, grid)
    norm, za, zb = norm0, 0.0, 0.0
    ax, ay = grid[0], grid[1]
    buf = np.empty(10)
    ws = _workspace(sigma, ax, ay)
    clamped = 0
    nz, ny, nx = pts.shape
    reach = max_move + 4.0 * sigma + 1.0  # the search's points and their windows: within this of the start
    cur = -1
    i0 = j0 = 0
    for n in range(xy.shape[0]):
        x0, y0 = xy[n, 0], xy[n, 1]
        out[n, 0], out[n, 1] = x0, y0
        found[n] = False
        k = kz[n]
        if k < 0:
            continue
        if k != cur:  # the slice's blurred images over the box the searches of its vertices can reach
            xlo, xhi, ylo, yhi = x0, x0, y0, y0
            for m in range(n + 1, xy.shape[0]):
                if kz[m] == k:
                    xlo, xhi = min(xlo, xy[m, 0]), max(xhi, xy[m, 0])
                    ylo, yhi = min(ylo, xy[m, 1]), max(yhi, xy[m, 1])
            mom, span = _images_for(pts, k, sigma, grid, xlo, xhi, ylo, yhi, reach, margin, mom, span, box, runs)
            i0, j0 = box[1], box[3]
            norm, za, zb = _slice_norm(grid, sigma, norm0, float(k), nz)
            cur = k
        _gradient_cols(mom, span, i0, j0, nx, ny, x0, y0, sigma, ax, ay, norm, za, zb, buf, ws)  # f, grad f
        hx, hy = -buf[1], -buf[2]
        hn = math.sqrt(hx * hx + hy * hy)
        gn = math.sqrt(buf[1] ** 2 + buf[2] ** 2 + buf[3] ** 2)
        if hn <= 1e-3 * gn or hn == 0.0:
            continue  # the surface is horizontal here (a pole): no horizontal move is defined
        dx, dy = hx / hn, hy / hn
        # safeguarded Newton along the outward horizontal direction for f = 1/2
        lo, hi = -max_move, max_move
        t = 0.0
        ok = False
        at_level = False  # the last evaluation (a step's) was at x0 + t dx: ws holds its sums
        for it in range(40):
            if it > 0:  # at t = 0, buf holds the field at the start already
                _level_cols(mom, span, i0, j0, nx, ny, x0 + t * dx, y0 + t * dy, sigma, ax, ay, norm, buf, ws)
            g = buf[0] - 0.5
            if abs(g) < 1e-12:
                ok = True
                at_level = it > 0
                break
            if g > 0.0:
                lo = t  # still inside: the level is further out
            else:
                hi = t
            d = buf[1] * dx + buf[2] * dy  # derivative along the direction (negative)
            tn = t - g / d if d < 0.0 else 0.5 * (lo + hi)
            if not (lo < tn < hi):
                tn = 0.5 * (lo + hi)
            if abs(tn - t) < 1e-10:
                t = tn
                ok = True
                break
            t = tn
        if not ok and hi - lo > 1e-6:
            continue  # no level crossing within reach: keep the vertex
        if strict and abs(g) > 1e-6:
            continue  # the search ended off the level (none within reach): keep the vertex
        found[n] = True
        tx, ty = x0 + t * dx, y0 + t * dy
        if curvature:
            if at_level:  # the same point: the step's sums and weights stand
                _field_after_level(mom, span, i0, j0, nx, ny, tx, ty, sigma, ax, ay, norm, za, zb, buf, ws)
            else:
                _field_cols(mom, span, i0, j0, nx, ny, tx, ty, sigma, ax, ay, norm, za, zb, buf, ws)
            shift, gnorm = _mean_curvature_shift(buf, sigma)
            if cubic != 0.0:
                ks = 2.0 * shift / (sigma * sigma)
                shift += cubic * ks * ks * ks * sigma ** 4
            hz = math.sqrt(buf[1] ** 2 + buf[2] ** 2)
            if gnorm > 0.0 and hz > 0.0:
                s = shift * gnorm / hz  # normal shift -> horizontal shift
                if s > 1.0:
                    s = 1.0
                elif s < -1.0:
                    s = -1.0
                tx += s * dx
                ty += s * dy
        # step 4: stay in the band (the original vertex is in it)
        if _in_band(pts, k, tx, ty, grid):
            out[n, 0], out[n, 1] = tx, ty
            continue
        clamped += 1
        _back_into_band(pts, k, x0, y0, tx, ty, 256, out, n, grid)
    return clamped, mom, span


def _clamp_to_band(pts, start, target, kz, out, grid=1.0):
    """Move each point from ``start`` toward ``target`` as far as its band allows (sampled); ``grid``:
    the lattice (:func:`_make_grid`), or a slice spacing (square pixels)."""
    return _clamp_kernel(pts, start, target, kz, out, _as_grid(grid, pts.shape[0]))


@njit(cache=True)
def _clamp_kernel(pts, start, target, kz, out, grid):
    """:func:`_clamp_to_band`'s loop."""
    clamped = 0
    for n in range(start.shape[0]):
        x0, y0 = start[n, 0], start[n, 1]
        tx, ty = target[n, 0], target[n, 1]
        out[n, 0], out[n, 1] = x0, y0
        k = kz[n]
        if k < 0:
            continue
        if _in_band(pts, k, tx, ty, grid):
            out[n, 0], out[n, 1] = tx, ty
            continue
        clamped += 1
        _back_into_band(pts, k, x0, y0, tx, ty, 64, out, n, grid)
    return clamped


# ----------------------------------------------------------------------------------------------
# 5. Chord compensation along each slice polygon
# ----------------------------------------------------------------------------------------------
def _chord_push(ring_xy: np.ndarray, nz2=None) -> np.ndarray:
    """Outward push ``kappa L^2 / 24 * (1 + 3 nz^2) / (1 + nz^2)`` of every polygon vertex (step 5).

    ``kappa`` is the signed curvature of the circle through a vertex and its two neighbours
    (positive where the polygon is convex for its orientation, ``U`` on the left), ``L^2`` the
    mean of the squared lengths of the vertex's two edges, ``nz`` the vertical component of the
    unit surface normal there (``nz2 = nz^2``; 0 when not given).  The push is along the outward
    vertex normal (to the right of the travel direction).

    Why this amount: between two inscribed polygons of edge ``L`` on circles of radii ``rho1,
    rho2`` a slice apart, the band's area falls short of the zone's by the relative amount
    ``a + b nz^2`` with ``a = L^2 / (24 rho^2)`` (the perimeter's chord deficit) and ``b = L^2 /
    (8 rho^2)`` (the apothem's, which enters through the slant ``sqrt(h^2 + d rho^2)``); scaling
    both polygons by ``1 + e`` changes the area by ``(1 + nz^2) e``.  So the perimeter-matching
    push ``kappa L^2 / 24`` holds where the surface is vertical and doubles where it is flat
    (where what counts is the polygon's enclosed area, short by ``L^2 / (6 rho^2)``).
    """
    p = np.ascontiguousarray(ring_xy, dtype=np.float64)
    out = np.empty_like(p)
    _chord_push_kernel(p, np.zeros(0) if nz2 is None else np.ascontiguousarray(nz2, dtype=np.float64),
                       nz2 is not None, out)
    return out


@njit(cache=True)
def _chord_push_kernel(p, nz2, with_nz, out):
    """:func:`_chord_push` vertex by vertex, the same operations in the same order as its former
    numpy expressions (so the same values)."""
    n = p.shape[0]
    for i in range(n):
        a = i - 1 if i > 0 else n - 1  # the predecessor and successor round the ring
        c = i + 1 if i + 1 < n else 0
        ux, uy = p[i, 0] - p[a, 0], p[i, 1] - p[a, 1]
        vx, vy = p[c, 0] - p[i, 0], p[c, 1] - p[i, 1]
        wx, wy = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1]
        lu = math.hypot(ux, uy)
        lv = math.hypot(vx, vy)
        lw = math.hypot(wx, wy)
        cross = ux * vy - uy * vx  # > 0: left turn = convex for U on the left
        den = lu * lv * lw
        kappa = 2.0 * cross / den if den > 0 else 0.0
        push = kappa * 0.5 * (lu * lu + lv * lv) / 24.0
        if with_nz:
            push = push * (1.0 + 3.0 * nz2[i]) / (1.0 + nz2[i])
        # outward normal (U on the left, so outward is to the right of the travel direction)
        d = lw if lw > 0 else 1.0
        tx, ty = wx / d, wy / d
        out[i, 0] = p[i, 0] + push * ty
        out[i, 1] = p[i, 1] + push * -tx


# ----------------------------------------------------------------------------------------------
# Meridians: vertices of consecutive slices aligned across the slices
# ----------------------------------------------------------------------------------------------
@njit(cache=True)
def _project_to_ring(ring, q):
    """Nearest point of the closed polygon ``ring`` to each query point.

    Returns ``(param, dist, px, py)``: the arc-length parameter (from ring[0]) of the nearest
    point, its distance, and its coordinates.
    """
    n = ring.shape[0]
    cum = np.zeros(n + 1)
    for i in range(n):
        j = (i + 1) % n
        cum[i + 1] = cum[i] + math.hypot(ring[j, 0] - ring[i, 0], ring[j, 1] - ring[i, 1])
    m = q.shape[0]
    par = np.empty(m)
    dist = np.empty(m)
    px = np.empty(m)
    py = np.empty(m)
    ex = np.empty(n)  # the edges and their squared lengths, once
    ey = np.empty(n)
    l2 = np.empty(n)
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        ex[i], ey[i] = ring[j, 0] - ring[i, 0], ring[j, 1] - ring[i, 1]
        l2[i] = ex[i] * ex[i] + ey[i] * ey[i]
    for a in range(m):
        best = 1e300
        cut = math.inf  # a squared distance above this cannot give a hypot below best
        for i in range(n):
            t = 0.0
            if l2[i] > 0.0:
                t = ((q[a, 0] - ring[i, 0]) * ex[i] + (q[a, 1] - ring[i, 1]) * ey[i]) / l2[i]
                t = min(1.0, max(0.0, t))
            cx, cy = ring[i, 0] + t * ex[i], ring[i, 1] + t * ey[i]
            dx, dy = q[a, 0] - cx, q[a, 1] - cy
            if dx * dx + dy * dy > cut:
                continue
            d = math.hypot(dx, dy)
            if d < best:
                best = d
                cut = best * best * (1.0 + 1e-9)
                par[a] = cum[i] + t * (cum[i + 1] - cum[i])
                px[a], py[a] = cx, cy
        dist[a] = best
    return par, dist, px, py


def _ring_point_at(ring: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points of the closed polygon ``ring`` at arc-length parameters ``s`` (from ring[0])."""
    closed = np.ascontiguousarray(np.vstack([ring, ring[:1]]), dtype=np.float64)
    seg, cum = _ring_edges(closed[:-1])
    s = np.mod(s, cum[-1])
    return _points_at(closed, seg, cum, np.ascontiguousarray(s, dtype=np.float64))


def _ring_point_at_reference(ring: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`_ring_point_at` with its edge lengths and their running sums by numpy (the reference)."""
    closed = np.vstack([ring, ring[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.mod(s, cum[-1])
    return _points_at(np.ascontiguousarray(closed, dtype=np.float64), seg, cum, np.ascontiguousarray(s, dtype=np.float64))


@njit(cache=True)
def _ring_edges(ring):
    """The edge lengths of the closed polygon ``ring (n, 2)`` (``np.hypot(*np.diff(np.vstack([ring,
    ring[:1]]), axis=0).T)``: the same differences and ``hypot``) and their running sums from 0
    (``n + 1`` values, ``np.cumsum``'s order)."""
    n = ring.shape[0]
    seg = np.empty(n)
    cum = np.empty(n + 1)
    cum[0] = 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        seg[i] = math.hypot(ring[j, 0] - ring[i, 0], ring[j, 1] - ring[i, 1])
        cum[i + 1] = cum[i] + seg[i] if i > 0 else seg[i]
    return seg, cum


@njit(cache=True)
def _points_at(closed, seg, cum, s):
    """The interpolation of :func:`_ring_point_at`, compiled: for each ``s``, the segment ``i`` with
    ``cum[i] <= s < cum[i + 1]`` (``searchsorted(side="right") - 1``, clipped to the ring) and the
    point ``closed[i] + t (closed[i + 1] - closed[i])``, ``t = (s - cum[i]) / seg[i]`` (0 on an empty
    segment): the same arithmetic as the numpy expression, so the same values."""
    n = closed.shape[0] - 1
    out = np.empty((len(s), closed.shape[1]))
    for a in range(len(s)):
        lo, hi = 0, len(cum)
        while lo < hi:
            mid = (lo + hi) // 2
            if cum[mid] <= s[a]:
                lo = mid + 1
            else:
                hi = mid
        i = min(max(lo - 1, 0), n - 1)
        t = (s[a] - cum[i]) / seg[i] if seg[i] > 0 else 0.0
        for d in range(closed.shape[1]):
            out[a, d] = closed[i, d] + t * (closed[i + 1, d] - closed[i, d])
    return out


def _meridian_params(par: np.ndarray, length: float, step: float) -> np.ndarray:
    """Arc parameters of a slice's vertices from the projections of the previous slice's.

    Projections closer than ``step / 2`` along the arc are merged (the later one is dropped);
    gaps longer than ``1.5 step`` are filled with evenly spaced new parameters (compiled:
    :func:`_merge_and_fill`).
    """
    s = np.sort(np.mod(par, length))
    return np.mod(_merge_and_fill(s, float(length), float(step)), length)


@njit(cache=True)
def _merge_and_fill(s, length, step):
    """:func:`_meridian_params` on the sorted parameters ``s``, before the final ``mod length``: the
    same arithmetic as a loop over numpy arrays (``v + g * i / m``), so the same values."""
    n = len(s)
    keep = np.empty(n)
    keep[0] = s[0]
    nk = 1
    for q in range(1, n):
        if s[q] - keep[nk - 1] >= 0.5 * step:
            keep[nk] = s[q]
            nk += 1
    while nk > 1 and keep[0] + length - keep[nk - 1] < 0.5 * step:
        nk -= 1
    gaps = np.empty(nk)
    fill = np.zeros(nk, np.int64)
    total = nk
    for q in range(nk):
        gaps[q] = (keep[q + 1] if q + 1 < nk else keep[0] + length) - keep[q]
        if gaps[q] > 1.5 * step:
            x = gaps[q] / step
            m = math.floor(x)  # round half to even, as Python's round()
            if x - m > 0.5 or (x - m == 0.5 and m % 2 == 1):
                m += 1
            fill[q] = max(int(m) - 1, 0)
            total += fill[q]
    out = np.empty(total)
    pos = 0
    for q in range(nk):
        v = keep[q]
        out[pos] = v
        pos += 1
        m = fill[q] + 1
        for i in range(1, m):
            out[pos] = v + gaps[q] * i / m
            pos += 1
    return out


@njit(cache=True)
def _is_simple(ring):
    """True when no two non-adjacent edges of the closed polygon meet (an O(n^2) check)."""
    n = ring.shape[0]
    for i in range(n):
        ax, ay = ring[i, 0], ring[i, 1]
        bx, by = ring[(i + 1) % n, 0], ring[(i + 1) % n, 1]
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            cx, cy = ring[j, 0], ring[j, 1]
            dx, dy = ring[(j + 1) % n, 0], ring[(j + 1) % n, 1]
            if _segments_meet(ax, ay, bx, by, cx, cy, dx, dy):
                return False
    return True


def _search(images, pts, xy, kz, sigma, grid, curvature, max_move, out, strict, found) -> int:
    """:func:`_move_to_surface` keeping the slice images in ``images`` (``width -> (mom, box, span)``, see
    :func:`_images_for`) for the next searches and field evaluations of the slice; ``images["runs"]``,
    where set, is :func:`_z_runs` of ``pts`` (faster images, the same values)."""
    if images is None:
        return _move_to_surface(pts, xy, kz, sigma, grid, curvature, max_move, out, strict, found)
    mom, box, span = images.get(float(sigma)) or _no_images()
    args = (pts, xy, kz, float(sigma), grid, curvature, max_move, out, strict, found, mom, span, box,
            IMAGE_MARGIN * max_move + 2.0, float(SHIFT_CUBIC))
    runs = images.get("runs")
    clamped, mom, span = _move_with_images(*args) if runs is None else _move_with_images(*args, runs)
    images[float(sigma)] = (mom, box, span)
    return clamped


def _surface_points(pts, xy, kz, sigma, grid, curvature, max_move, strict=False, fine=None, counts=None, images=None):
    """Steps 3-4 at ``sigma``; with ``fine`` (a smaller width), the two-scale selection of step 3b.
    ``grid``: the lattice (:func:`_make_grid`), or a slice spacing (square pixels, even slices).

    ``counts`` (a two-item list) accumulates the vertices that took the fine estimate and the
    vertices seen; ``images`` (a dict, or None) keeps the slice images between searches of one slice."""
    xy = np.ascontiguousarray(xy)
    grid = _as_grid(grid, pts.shape[0])
    out = np.empty_like(xy)
    found = np.empty(len(xy), dtype=np.bool_)
    clamped = _search(images, pts, xy, kz, sigma, grid, curvature, max_move, out, strict, found)
    if fine is None or not fine < sigma or len(xy) < 3:
        return out, clamped
    near = np.empty_like(xy)
    found_fine = np.empty(len(xy), dtype=np.bool_)
    _search(images, pts, xy, kz, float(fine), grid, curvature, max_move, near, strict, found_fine)
    # a vertex that one of the two searches left where it was (no level within reach) keeps the
    # coarse decision; elsewhere the extrapolated estimate weighs in where the two scales disagree
    # (also where the band clamp put the wide place back on the seed: that search did find the level)
    # the fine place keeps a residual bias of order fine^4 (the curvature correction removes the
    # sigma^2 term): with both places x(s) = x0 + c s^4, x0 = x_fine + rho (x_fine - x_coarse)
    r4 = (float(fine) / sigma) ** 4
    rho = r4 / (1.0 - r4) if FINE_RHO is None else float(FINE_RHO)
    target = np.empty_like(xy)
    n_fine, n_any = _two_scale_targets(out, near, found, found_fine, FINE_TOLERANCE[0],
                                       FINE_TOLERANCE[1] - FINE_TOLERANCE[0], rho, target,
                                       *_crease_gains(pts, xy, kz, sigma, float(fine), grid, images, out, near, max_move))
    if FINE_ADAPTIVE and n_any:
        target = _three_scale_targets(pts, xy, kz, sigma, fine, grid, curvature, max_move, strict, images, out, near,
                                      found, found_fine, rho)
    if counts is not None:
        counts[0] += int(n_fine)
        counts[1] += len(xy)
    if not n_any:
        return out, clamped
    res = np.empty_like(xy)
    _clamp_to_band(pts, out, target, np.ascontiguousarray(kz, dtype=np.int64), res, grid)
    return res, clamped


def _three_scale_targets(pts, xy, kz, sigma, fine, grid, curvature, max_move, strict, images, out, near, found,
                         found_fine, rho0):
    """Step 3b's targets with a gain per vertex (experiment, :data:`FINE_ADAPTIVE`): where the two
    scales disagree, a third place at the wider width ``sigma / r`` gives the ratio ``q`` of the
    successive differences, which is ``r^p`` for a bias growing like ``sigma^p``; the gain is
    ``q / (1 - q)`` with ``q`` clipped to ``[r^4, r]`` (``p`` from 4, smooth detail, to 1, a crease)."""
    r = float(fine) / sigma
    d = near - out
    gap = np.hypot(d[:, 0], d[:, 1])
    lo, hi = FINE_TOLERANCE
    w = np.clip((gap - lo) / (hi - lo), 0.0, 1.0) * (found & found_fine)
    sel = np.flatnonzero(w > 0)
    rho = np.full(len(xy), rho0)
    wide = np.empty((len(sel), 2))
    found_w = np.empty(len(sel), dtype=np.bool_)
    _search(images, pts, np.ascontiguousarray(xy[sel]), np.ascontiguousarray(kz[sel]), sigma / r, grid, curvature,
            max_move, wide, strict, found_w)
    u = d[sel] / np.maximum(gap[sel], 1e-12)[:, None]
    a = gap[sel]  # (near - out) . u
    b = ((out[sel] - wide) * u).sum(axis=1)
    trust = 0.0 if FINE_ADAPTIVE is True else float(FINE_ADAPTIVE)  # the smallest wide step trusted
    q = np.where(b > trust, a / np.where(b > 0, b, 1.0), r ** 4)
    q = np.clip(q, r ** 4, r)
    rho[sel] = np.where(found_w, q / (1.0 - q), rho0)
    return out + w[:, None] * (near + rho[:, None] * d - out)


@njit(cache=True)
def _two_scale_targets(out, near, found, found_fine, lo, span, rho, target, rho_v=None, tol_v=None):
    """Step 3b's weights and targets (the numpy expressions of :func:`_surface_points`, term by
    term): ``w = clip((|near - out| - lo) / span, 0, 1)`` where both searches found the level (0
    elsewhere), ``target = out + w (ext - out)`` with ``ext = near + rho (near - out)``.  Returns the
    number of weights above 1/2 and whether any is positive.  ``rho_v``, ``tol_v`` (arrays, from
    :func:`_crease_gains`): a gain per vertex, and ``|near - out|`` divided by ``tol_v`` first."""
    n_fine = 0
    n_any = False
    for n in range(out.shape[0]):
        gap = math.hypot(near[n, 0] - out[n, 0], near[n, 1] - out[n, 1])
        if tol_v is not None:
            gap = gap / tol_v[n]  # a crease's tolerance is narrower
        w = min(max((gap - lo) / span, 0.0), 1.0) * (1.0 if (found[n] and found_fine[n]) else 0.0)
        if w > 0.5:
            n_fine += 1
        if w > 0.0:
            n_any = True
        rr = rho if rho_v is None else rho_v[n]
        for c in range(2):
            ext = near[n, c] + rr * (near[n, c] - out[n, c])
            target[n, c] = out[n, c] + w * (ext - out[n, c])
    return n_fine, n_any


def _crease_gains(pts, xy, kz, sigma, fine, grid, images, out, near, max_move):
    """Step 3b's gains and tolerance factors per vertex (:data:`FINE_CREASE`), or ``(None, None)``
    (the one gain and tolerance).  ``xy`` is one ring of one slice, in order; ``out``, ``near`` its
    places at ``sigma`` and ``fine``.

    With the module's default crease settings (:func:`_crease_fast_settings`) the per-vertex
    arithmetic runs in compiled kernels (:func:`_crease_live`, :func:`_crease_ratio`,
    :func:`_crease_power`) with the same operations in the same order, the logarithms and powers
    still by numpy, so the results are those of :func:`_crease_gains_reference` bit for bit; any
    other setting takes the reference."""
    fast = _crease_fast_settings()
    if fast is None:
        return _crease_gains_reference(pts, xy, kz, sigma, fine, grid, images, out, near, max_move)
    if not FINE_CREASE or len(xy) < 3 or not (kz == kz[0]).all():
        return None, None
    kmin, lo_b, hi_b, max_bend, max_order = fast
    ring = np.ascontiguousarray(out)
    nearc = np.ascontiguousarray(near)
    cand = _crease_candidates(ring, nearc, 0.999 * FINE_TOLERANCE[0] * max(1.0 - CREASE_TOLERANCE, 0.0))
    if cand is None:
        return None, None
    win = float(CREASE_WINDOW) * sigma
    images = {} if images is None else images
    k = int(kz[0])
    r = fine / sigma
    planar = _planar_ratio(grid, k)
    need = np.flatnonzero(_ring_reach(ring, cand, win))
    fld_w = _fields_at(pts, out, need, k, sigma, grid, images, max_move)
    images["fields"] = (float(sigma), ring.copy(), fld_w, need)  # for the chord step at the same points
    sw = _ring_curvature_mean(fld_w, float(sigma), ring, win)
    live = _crease_live(sw, cand, float(sigma), kmin, max_bend)
    fld_f = _fields_at(pts, near, np.flatnonzero(_ring_reach(ring, live, win)), k, fine, grid, images, max_move)
    sf = _ring_curvature_mean(fld_f, float(fine), ring, win)
    if planar:
        pw = _ring_curvature_mean(fld_w, float(sigma), ring, win, True)
        pf = _ring_curvature_mean(fld_f, float(fine), ring, win, True)
    else:
        pw, pf = sw, sf
    q0 = float(CREASE_MIN_RATIO)
    qq = _crease_ratio(sw, pw, pf, live, float(sigma), kmin, planar)  # where(q > 0, q, 1)
    lq = np.log(qq / q0)
    lu = lq if q0 == 1.0 else np.log(qq)  # x / 1.0 is x
    p, tol = _crease_power(lq, lu, sw, float(sigma), math.log(1.0 / (r * q0)), math.log(1.0 / r), float(max_order),
                           lo_b, hi_b, float(max_bend), float(CREASE_TOLERANCE))
    rp = r ** p
    return np.ascontiguousarray(rp / (1.0 - rp)), tol


def _crease_fast_settings():
    """``(kmin, lo, hi, max_bend, max_order)`` when the crease settings are the ones the compiled
    steps of :func:`_crease_gains` take (a bend fade ``(lo, hi)``, a largest bend and order, a
    smallest ratio of at least 1, no noise floor, no fine-width fade, no wider check), else None."""
    if (CREASE_NOISE or CREASE_MIN_FINE is not None or CREASE_WIDER is not None or np.isscalar(CREASE_MIN_BEND)
            or CREASE_MAX_BEND is None or CREASE_MAX_ORDER is None or not float(CREASE_MIN_RATIO) >= 1.0):
        return None
    lo_b, hi_b = CREASE_MIN_BEND
    return float(lo_b), float(lo_b), float(hi_b), float(CREASE_MAX_BEND), float(CREASE_MAX_ORDER)


@njit(cache=True)
def _crease_candidates(out, near, thr):
    """``hypot(near - out) > thr`` per vertex (:func:`_crease_gains_reference`'s candidates), or None
    when no vertex is one."""
    n = out.shape[0]
    cand = np.empty(n, dtype=np.bool_)
    anyc = False
    for i in range(n):
        c = math.hypot(near[i, 0] - out[i, 0], near[i, 1] - out[i, 1]) > thr
        cand[i] = c
        anyc = anyc or c
    return cand if anyc else None


@njit(cache=True)
def _crease_live(sw, cand, sigma, kmin, max_bend):
    """``cand & (|sw| sigma > kmin) & (|sw| sigma < max_bend)``."""
    n = sw.shape[0]
    live = np.empty(n, dtype=np.bool_)
    for i in range(n):
        b = abs(sw[i]) * sigma
        live[i] = cand[i] and b > kmin and b < max_bend
    return live


@njit(cache=True)
def _crease_ratio(sw, a_w, a_f, live, sigma, kmin, planar):
    """The curvature ratio ``q`` of :func:`_crease_gains_reference` (no noise floor) as
    ``where(q > 0, q, 1)``: ``a_f / a_w`` where the wide level bends (and, ``planar``, both section
    curvatures agree in sign), 1 elsewhere and off ``live``."""
    n = sw.shape[0]
    qq = np.empty(n)
    for i in range(n):
        ok = abs(sw[i]) * sigma > kmin
        if planar:
            ok = ok and a_w[i] * a_f[i] > 0
        q = 1.0
        if live[i] and ok:
            q = a_f[i] / (a_w[i] if a_w[i] != 0 else 1.0)
        qq[i] = q if q > 0 else 1.0
    return qq


@njit(cache=True)
def _np_clip01(x):
    """``np.clip(x, 0.0, 1.0)`` of one float64 (numpy's order of comparisons; NaN stays NaN)."""
    t = x if (x != x or x >= 0.0) else 0.0  # -0.0 stays -0.0, as in numpy
    return t if (t != t or t <= 1.0) else 1.0


@njit(cache=True)
def _crease_power(lq, lu, sw, sigma, l_m, l_r, max_order, lo_b, hi_b, max_bend, tol_k):
    """The exponents ``p = 4 - 3 m`` and tolerance factors ``1 - tol_k m`` of
    :func:`_crease_gains_reference` from the logarithms ``lq`` of ``q / q0`` and ``lu`` of ``q``: the
    crease share ``m`` rising with ``lq / l_m``, faded by the order ``lu / l_r`` past 1 toward
    ``max_order``, by the bend ``|sw| sigma`` from ``lo_b`` to ``hi_b`` and toward ``max_bend``."""
    n = lq.shape[0]
    p = np.empty(n)
    tol = np.empty(n)
    o1 = max_order - 1.0
    db = hi_b - lo_b
    hb = 0.5 * max_bend
    for i in range(n):
        m = _np_clip01(lq[i] / l_m)
        u = lu[i] / l_r
        m = m * _np_clip01((max_order - u) / o1)
        m = m * _np_clip01((abs(sw[i]) * sigma - lo_b) / db)
        b = abs(sw[i]) * sigma
        m = m * _np_clip01((max_bend - b) / hb)
        p[i] = 4.0 - 3.0 * m
        tol[i] = 1.0 - tol_k * m
    return p, tol


def _crease_gains_reference(pts, xy, kz, sigma, fine, grid, images, out, near, max_move):
    """:func:`_crease_gains` in numpy expressions, for every setting of the crease constants (the
    reference of its compiled steps)."""
    if not FINE_CREASE or len(xy) < 3 or not (kz == kz[0]).all():
        return None, None
    if CREASE_MIN_FINE is not None and fine <= CREASE_MIN_FINE[0]:
        return None, None  # every share would be 0: the one gain and tolerance
    # only a vertex whose places differ by more than the narrowest tolerance can take a gain: the
    # curvatures are needed there and within the averaging window's reach of it (the same gains)
    cand = np.hypot(*(near - out).T) > 0.999 * FINE_TOLERANCE[0] * max(1.0 - CREASE_TOLERANCE, 0.0)
    if not cand.any():
        return None, None
    ring = np.ascontiguousarray(out)
    win = float(CREASE_WINDOW) * sigma
    images = {} if images is None else images
    k = int(kz[0])
    r = fine / sigma
    planar = _planar_ratio(grid, k)
    need = np.flatnonzero(_ring_reach(ring, cand, win))
    fld_w = _fields_at(pts, out, need, k, sigma, grid, images, max_move)
    images["fields"] = (float(sigma), ring.copy(), fld_w, need)  # for the chord step at the same points
    sw = _ring_curvature_mean(fld_w, float(sigma), ring, win)
    kmin = CREASE_MIN_BEND if np.isscalar(CREASE_MIN_BEND) else CREASE_MIN_BEND[0]
    # where the wide level hardly bends (q = 1) or bends strongly (the fade below) the share is 0:
    # the fine width's curvatures are needed only for the other candidates
    live = cand & (np.abs(sw) * sigma > kmin) if float(CREASE_MIN_RATIO) >= 1.0 else cand
    if CREASE_MAX_BEND is not None:
        live &= np.abs(sw) * sigma < CREASE_MAX_BEND
    fld_f = _fields_at(pts, near, np.flatnonzero(_ring_reach(ring, live, win)), k, fine, grid, images, max_move)
    sf = _ring_curvature_mean(fld_f, float(fine), ring, win)
    if planar:  # the ratio from the sections' curvatures (the bend tests keep the surface's)
        pw = _ring_curvature_mean(fld_w, float(sigma), ring, win, True)
        pf = _ring_curvature_mean(fld_f, float(fine), ring, win, True)
        a_w, a_f, ok = pw, pf, (np.abs(sw) * sigma > kmin) & (pw * pf > 0)
    else:
        a_w, a_f, ok = sw, sf, np.abs(sw) * sigma > kmin
    if CREASE_NOISE:  # only the curvature excess beyond the fine level's lattice noise counts
        floor = float(CREASE_NOISE) * float(CREASE_NOISE_LEVEL) / fine ** float(CREASE_NOISE_POWER)
        excess = np.maximum((a_f - a_w) * np.sign(a_w) * sigma - floor, 0.0)
        q = np.where(ok, 1.0 + excess / np.maximum(np.abs(a_w) * sigma, 1e-12), 1.0)
    else:
        q = np.where(ok, a_f / np.where(a_w != 0, a_w, 1.0), 1.0)
    q = np.where(live, q, 1.0)
    q0 = float(CREASE_MIN_RATIO)  # a ratio up to q0 is noise: m rises from 0 at q0 to 1 at 1 / r
    m = np.clip(np.log(np.where(q > 0, q, 1.0) / q0) / math.log(1.0 / (r * q0)), 0.0, 1.0)
    if CREASE_MAX_ORDER is not None:  # q beyond 1 / r: the curvature grows faster than a crease's, a step narrower than the blur
        u = np.log(np.where(q > 0, q, 1.0)) / math.log(1.0 / r)
        m = m * np.clip((float(CREASE_MAX_ORDER) - u) / (float(CREASE_MAX_ORDER) - 1.0), 0.0, 1.0)
    if not np.isscalar(CREASE_MIN_BEND):  # (lo, hi): the crease share fades in as |S| sigma grows from lo to hi
        lo_b, hi_b = CREASE_MIN_BEND
        m = m * np.clip((np.abs(sw) * sigma - lo_b) / (hi_b - lo_b), 0.0, 1.0)
    if CREASE_MAX_BEND is not None:  # detail narrower than the blur also has S ~ 1 / sigma: a strong bend is not a crease
        b = np.abs(sw) * sigma
        m = m * np.clip((CREASE_MAX_BEND - b) / (0.5 * CREASE_MAX_BEND), 0.0, 1.0)
    if CREASE_MIN_FINE is not None:  # a fine level too rough for the test: its lattice noise reads as creases
        f_lo, f_hi = CREASE_MIN_FINE
        m = m * min(max((fine - f_lo) / (f_hi - f_lo), 0.0), 1.0)
    if CREASE_WIDER is not None:
        m = m * _wider_check(pts, k, sigma, r, grid, images, out, near, max_move, pw if planar else sw, q, m, planar)
    p = 4.0 - 3.0 * m
    return np.ascontiguousarray(r ** p / (1.0 - r ** p)), np.ascontiguousarray(1.0 - CREASE_TOLERANCE * m)


def _planar_ratio(grid, k) -> bool:
    """Whether :func:`_crease_gains` takes the ratio from the sections' curvatures in slice ``k``
    (:data:`CREASE_PLANAR`: always, never, or where the slice's slab is thicker than that many ``h``)."""
    if CREASE_PLANAR is True or CREASE_PLANAR is False:
        return bool(CREASE_PLANAR)
    g = _as_grid(grid, k + 1)
    slab = g[2] * (g[4][k] if len(g[4]) else 1.0)
    return bool(slab > float(CREASE_PLANAR) * (1.0 + 1e-6))


def _wider_check(pts, k, sigma, r, grid, images, out, near, max_move, sw, q, m, planar=False):
    """The factor (0 to 1) by which :data:`CREASE_WIDER` keeps each vertex's crease share ``m``:
    ``t = log(S(sigma) / S(sigma / r)) / log(S(r sigma) / S(sigma))`` (ring-averaged mean curvatures,
    the wider one at the wide places ``out``), 1 at ``t <= t_lo``, 0 at ``t >= t_hi``."""
    keep = np.ones(len(out))
    gap = np.hypot(*(near - out).T)
    # only a vertex past its own tolerance acts (a smaller share only widens the tolerance)
    acts = (m > 0) & (gap > 0.999 * FINE_TOLERANCE[0] * (1.0 - CREASE_TOLERANCE * m))
    if not acts.any():
        return keep
    wider = sigma / r
    ring = np.ascontiguousarray(out)
    need = np.flatnonzero(_ring_reach(ring, acts, float(CREASE_WINDOW) * sigma))
    fld = _fields_at(pts, out, need, k, wider, grid, images, max_move)
    sx = _ring_curvature_mean(fld, float(wider), np.ascontiguousarray(out), float(CREASE_WINDOW) * sigma,
                              planar)
    ratio = sw / np.where(sx != 0, sx, 1.0)
    keep = (ratio > 0).astype(np.float64)  # a wider level that bends the other way has lost the detail: a wave
    if CREASE_WIDER is not True:
        l1 = np.log(np.where(q > 1.0, q, 1.0))  # m > 0 only where q > 1
        l2 = np.log(np.where(ratio > 0, ratio, 1.0))
        t = np.where(l1 > 0, l2 / np.where(l1 > 0, l1, 1.0), 0.0)
        t_lo, t_hi = CREASE_WIDER
        keep *= np.clip((t_hi - t) / (t_hi - t_lo), 0.0, 1.0)
    return keep


def _fields_at(pts, p, idx, k, width, grid, images, max_move):
    """The fields (:func:`_fields_in_slice`) at the points ``p[idx]`` of slice ``k``, in an array of
    ``len(p)`` rows (zero elsewhere); the slice images are kept in ``images``."""
    mom, box, span = images.get(float(width)) or _no_images()
    fld = np.zeros((len(p), 10))
    if len(idx) == 0:
        return fld
    sub, (mom, span) = _fields_in_slice(pts, np.ascontiguousarray(p[idx]), k, float(width), grid, mom, box, span,
                                        IMAGE_MARGIN * max_move + 2.0, images.get("runs"))
    images[float(width)] = (mom, box, span)
    fld[idx] = sub
    return fld


@njit(cache=True)
def _ring_reach(ring, sel, width):
    """The ring vertices whose value :func:`_ring_curvature_mean` (window ``width``) averages into
    some selected vertex's: the same arc lengths and walk, marking instead of summing."""
    n = ring.shape[0]
    mark = np.zeros(n, dtype=np.bool_)
    cum = np.empty(n + 1)
    cum[0] = 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        cum[i + 1] = cum[i] + math.hypot(ring[j, 0] - ring[i, 0], ring[j, 1] - ring[i, 1])
    length = cum[n]
    if length <= 0.0 or width <= 0.0:
        for i in range(n):
            mark[i] = sel[i]
        return mark
    reach = min(3.0 * width, 0.5 * length)
    for i in range(n):
        if not sel[i]:
            continue
        for side in (1, -1):
            k = 0 if side == 1 else 1
            while k < n:
                j = (i + side * k) % n
                d = abs(cum[j] - cum[i])
                d = min(d, length - d)
                if d > reach:
                    break
                mark[j] = True
                k += 1
    return mark


@njit(cache=True)
def _ring_curvature_mean(fld, sigma, ring, width, planar=False):
    """The mean curvature ``k1 + k2`` of the blurred level at each ring vertex (``fld``: the fields
    there, :func:`_field`), averaged along the ring with a Gaussian of ``width`` in arc length;
    ``planar``: the curvature of the level's section by the slice plane instead."""
    n = ring.shape[0]
    s = np.empty(n)
    for i in range(n):
        if planar:
            gx, gy = fld[i, 1], fld[i, 2]
            g2 = gx * gx + gy * gy
            s[i] = 0.0 if g2 == 0.0 else -(fld[i, 4] * gy * gy - 2.0 * fld[i, 7] * gx * gy
                                           + fld[i, 5] * gx * gx) / (g2 * math.sqrt(g2))
        else:
            shift, g = _mean_curvature_shift(fld[i], sigma)
            s[i] = 2.0 * shift / (sigma * sigma)
    cum = np.empty(n + 1)
    cum[0] = 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        cum[i + 1] = cum[i] + math.hypot(ring[j, 0] - ring[i, 0], ring[j, 1] - ring[i, 1])
    length = cum[n]
    out = s.copy()
    if length <= 0.0 or width <= 0.0:
        return out
    reach = min(3.0 * width, 0.5 * length)
    for i in range(n):
        num = 0.0
        den = 0.0
        for side in (1, -1):
            k = 0 if side == 1 else 1
            while k < n:
                j = (i + side * k) % n
                d = abs(cum[j] - cum[i])
                d = min(d, length - d)
                if d > reach:
                    break
                g = math.exp(-0.5 * (d / width) ** 2)
                num += g * s[j]
                den += g
                k += 1
        out[i] = num / den if den > 0 else s[i]
    return out


def auto_sigma(stack: ContourStack, *, factor: float = 0.8, lo: float = 2.0, hi: float = 3.5) -> float:
    """The default Gaussian width: ``clip(factor * R^(1/3), lo, hi)`` in units of ``h`` (the longer
    pixel side; a voxel's side where the pixels are square), ``R = 3 V / A``.

    ``V`` and ``A`` are the volume and lateral area of the stack's contours (sum of the contours'
    areas and perimeters times the slice spacing, in units of ``h``), so ``R`` is the radius for a ball.
    The lattice noise of the blurred indicator adds a roughness whose area excess falls like
    ``sigma^-3.5`` (measured: +0.12 % at sigma = 1.5, +0.03 % at 2, +0.008 % at 2.5 on the ball
    r = 80), while the curvature correction is exact only to order ``(sigma kappa)^2``; letting
    ``sigma`` grow slowly with the object's size in voxels (as integral-invariant radii grow like
    ``h^(-1/3)``) keeps both small; the cap bounds the cost (``sigma^3`` per evaluation).
    """

    _check_stack(stack)
    zs = stack.z
    grid, h = _make_grid(*stack.spacing, 1, dz=1.0)
    scale = np.array([grid[0], grid[1]])
    dz = float(np.median(np.diff(zs))) / h if len(zs) > 1 else 1.0
    # grid contours are 4-connected staircases: pi/4 of their length estimates the curve's
    return _auto_sigma_of([np.asarray(c) * scale for s in stack.sections for c in s.contours], dz, math.pi / 4,
                          factor=factor, lo=lo, hi=hi)


def _auto_sigma_of(polygons, dz: float, length_factor: float = 1.0, *, factor: float = 0.8, lo: float = 2.0,
                   hi: float = 3.5) -> float:
    """:func:`auto_sigma`'s rule for polygons in units of ``h`` (``length_factor`` scales their perimeters)."""
    vol = 0.0
    lat = 0.0
    for c in polygons:
        c = np.asarray(c, dtype=np.float64)
        if len(c) < 3:
            continue
        vol += shoelace_area(c) * dz
        lat += float(_ring_edges(np.ascontiguousarray(c))[0].sum()) * dz * length_factor
    if vol <= 0 or lat <= 0:
        return float(lo)
    r = 3.0 * vol / lat
    return float(min(max(factor * r ** (1.0 / 3.0), lo), hi))


def _resolve_sigma(sigma, auto) -> float:
    """A checked Gaussian width: a number >= 0.7 voxels, or ``"auto"`` (then ``auto()``)."""
    if isinstance(sigma, str):
        if sigma != "auto":
            raise ValueError(f"sigma must be a number of voxels or 'auto'; got {sigma!r}")
        sigma = auto()
    sigma = float(sigma)
    if not (math.isfinite(sigma) and sigma >= 0.7):
        raise ValueError(f"sigma must be a number >= 0.7 voxels; got {sigma!r}")
    return sigma


def _resolve_fine(fine_sigma, sigma: float):
    """The fine width of step 3b, or None (one scale): ``"auto"`` is :data:`FINE_RATIO` times ``sigma``."""
    if fine_sigma is None:
        return None
    if isinstance(fine_sigma, str):
        if fine_sigma != "auto":
            raise ValueError(f"fine_sigma must be a number of voxels, 'auto' or None; got {fine_sigma!r}")
        return FINE_RATIO * sigma
    fine = _resolve_sigma(fine_sigma, None)
    if not fine < sigma:
        raise ValueError(f"fine_sigma ({fine}) must be smaller than sigma ({sigma})")
    return fine


def _method_density(method, density):
    """``density``, or the refinement ``method``'s own (:data:`RING_DENSITY`) when None."""
    if method not in RING_DENSITY:
        raise ValueError(f"unknown refine method {method!r}; expected one of {sorted(RING_DENSITY)}")
    return RING_DENSITY[method] if density is None else density


def _check_density(density) -> None:
    if not (float(density) > 0):
        raise ValueError(f"density must be a positive number; got {density!r}")


def refine_ring(pts, seed, kz: int, sigma: float, dz, prev=None, *, curvature: bool = True,
                chord: bool = True, meridians: bool = True, density: float = 1.0, max_move: float = 3.0,
                strict: bool = False, fine_sigma: float | None = None, counts: list | None = None,
                images: dict | None = None):
    """Steps 3-6 of the module docstring for one seed polygon of lattice slice ``kz``.

    Parameters
    ----------
    pts : (nz, ny, nx) bool ndarray
        The digital object ``I`` (as from :func:`stack_points`).
    seed : (n, 2) float ndarray
        The seed polygon in array-local coordinates (units of ``h``, the longer pixel side: pixel
        ``(i, j)`` at ``(i ax, j ay)``), in the band of slice ``kz``; outer polygons
        counter-clockwise, holes clockwise (the object on the left).
    sigma : float
        Gaussian width in units of ``h``.
    dz : float or tuple
        The slice spacing in units of ``h`` (square pixels, evenly spaced slices), or the grid
        record of :func:`_make_grid` (any pixel shape, slices at any heights).
    prev : (m, 2) float ndarray, optional
        Final vertices of the polygon(s) below that this one continues (step 6, meridians).
    curvature, chord, meridians, density, max_move
        As for :func:`refine_stack`.
    strict : bool
        Move only the vertices whose level-set search ends on the level ``f = 1/2``; the others
        (no level within reach: a part thinner than the blur) stay where they are.  Off in
        :func:`refine_stack` (its balls' figures are with it off).
    fine_sigma : float, optional
        The fine width of the two-scale selection (step 3b); None: one scale.
    counts : list, optional
        ``[fine, seen]``: accumulates the vertices that took the fine estimate.
    images : dict, optional
        Slice images kept between the searches of slice ``kz`` (pass the same dict for the rings of
        one slice; a new one per slice), and under ``"runs"`` the :func:`_z_runs` of ``pts`` that
        make new images faster.  The results do not depend on it.

    Returns
    -------
    ring : (k, 2) float ndarray
        The refined polygon (array-local), simple and oriented like the seed; the seed itself
        where a step would fold it.  A seed that is a point or a segment is returned as it is.
    clamped : int
        Vertices clamped into the band.
    """
    kk = int(kz)
    grid = _as_grid(dz, pts.shape[0])
    seed_area = shoelace_area(seed)
    if distinct_rows(seed) < 3 or seed_area == 0.0:
        return seed, 0  # a pole point or a segment: kept as it is
    clamped = 0
    images = {} if images is None else images
    kzs = np.full(len(seed), kk, dtype=np.int64)
    guide, nc = _surface_points(pts, seed, kzs, sigma, grid, curvature, max_move, strict, fine_sigma, counts, images)
    clamped += nc
    ring = guide if _is_simple(guide) and shoelace_area(guide) * seed_area > 0 else seed
    if meridians and prev is not None and len(prev):
        length = float(_ring_edges(np.ascontiguousarray(guide))[0].sum())
        step = length / (len(seed) * float(density))
        par, dist, _, _ = _project_to_ring(guide, np.ascontiguousarray(prev))
        par = par[dist < 3.0]
        if len(par) >= 3:
            s = _meridian_params(par, length, step)
            if len(s) >= 3:
                start = _ring_point_at(guide, s)
                kzs = np.full(len(start), kk, dtype=np.int64)
                cand, nc = _surface_points(pts, start, kzs, sigma, grid, curvature, max_move, strict, fine_sigma,
                                           counts, images)
                if _is_simple(cand) and shoelace_area(cand) * seed_area > 0:
                    ring = cand  # otherwise (a fold at a thin end) keep the slice's own vertices
                    clamped += nc
    if chord:
        fld = _chord_gradients(pts, np.ascontiguousarray(ring, dtype=np.float64), kk, float(sigma), grid, images,
                               max_move)
        g2 = (fld[:, 1:4] ** 2).sum(axis=1)
        nz2 = np.where(g2 > 0, fld[:, 3] ** 2 / np.where(g2 > 0, g2, 1.0), 0.0)
        target = _chord_push(ring, nz2)
        kzs = np.full(len(ring), kk, dtype=np.int64)
        out = np.empty_like(ring)
        nc = _clamp_to_band(pts, np.ascontiguousarray(ring), target, kzs, out, grid)
        if _is_simple(out):
            ring = out
            clamped += nc
    # the guarantee: every vertex in its band.  A vertex whose walk started off the band (a
    # projection onto a chord of the guide) goes back toward the seed polygon, which lies in the
    # band (the MLP does), as far as the band allows.
    kzs = np.full(len(ring), kk, dtype=np.int64)
    bad = _off_band(pts, kk, np.ascontiguousarray(ring, dtype=np.float64), grid)
    if bad.any():
        _, _, px, py = _project_to_ring(np.ascontiguousarray(seed), np.ascontiguousarray(ring[bad]))
        start = np.stack([px, py], axis=1)
        out = np.empty_like(start)
        clamped += _clamp_to_band(pts, start, np.ascontiguousarray(ring[bad]), kzs[: len(start)], out, grid)
        cand = ring.copy()
        cand[bad] = out
        ring = cand if _is_simple(cand) else seed
    return ring, clamped


def _chord_gradients(pts, ring, k, sigma, grid, images, max_move):
    """``f`` and ``grad f`` at width ``sigma`` at the ring's points (``(n, 10)``, the rest 0) for the
    chord step: where a point is one at which the two-scale step took the fields already
    (``images["fields"]``, :func:`_crease_gains`; the same point bit for bit, the same slice and
    width) its numbers are taken from there (:func:`_gradient_in_slice` gives ``f`` and ``grad f``
    the same values as :func:`_field_in_slice`), the others are evaluated."""
    n = len(ring)
    fld = np.zeros((n, 10))
    todo = np.arange(n)
    kept = images.get("fields")
    if kept is not None and kept[0] == sigma and len(kept[1]) == n:
        _, at, kf, idx = kept
        same = np.zeros(n, dtype=np.bool_)
        same[idx] = (at[idx] == ring[idx]).all(axis=1)
        fld[same, :4] = kf[same, :4]
        todo = np.flatnonzero(~same)
    if len(todo):
        mom, box, span = images.get(sigma) or _no_images()
        sub, (mom, span) = _fields_in_slice(pts, np.ascontiguousarray(ring[todo]), k, sigma, grid, mom, box, span,
                                            IMAGE_MARGIN * max_move + 2.0, images.get("runs"), full=False)
        images[sigma] = (mom, box, span)
        fld[todo] = sub
    return fld

def refine_stack(stack: ContourStack, method: str = "band", *, polygon: str = "mlp", sigma="auto",
                 curvature: bool = True, chord: bool = True, meridians: bool = True,
                 density: float | None = None, max_move: float = 3.0, fine_sigma="auto") -> ContourStack:
    """Refined slice polygons: a ContourStack of float polygons on the estimated surface.

    Parameters
    ----------
    stack : ContourStack
        Integer grid contours; any positive pixel size ``(dx, dy)``, sections at any heights
        (evenly spaced, with gaps, or not: unevenly spaced sections keep their own heights).
    method : {"band", "band2"}
        The refinement (see the module docstring); ``"band2"``: twice the ring vertices
        (:data:`RING_DENSITY`).
    polygon : {"mlp", "dss", "none"}
        The polygonizer whose vertices seed every slice (and set its vertex density).
    sigma : float or "auto"
        Width of the Gaussian in units of ``h``, the longer pixel side (>= 0.7); ``"auto"``:
        :func:`auto_sigma`.  Lengths below are in the same unit.
    curvature, chord : bool
        Steps 3 (curvature correction) and 5 (chord compensation).
    meridians : bool
        Align the vertices of consecutive slices (step 6): each slice takes the projections of the
        previous slice's vertices, merged or filled to the seed polygon's mean edge length.
    density : float, optional
        Vertices per seed-polygon vertex (the mean edge length is divided by it); default: the
        method's (:data:`RING_DENSITY`).
    max_move : float
        Largest horizontal move searched, in units of ``h``.
    fine_sigma : float, "auto" or None
        The fine width of the two-scale selection (step 3b), smaller than ``sigma``; ``"auto"``:
        :data:`FINE_RATIO` times ``sigma``; None: one scale.

    Returns
    -------
    ContourStack
        Same sections, heights, parents, spacing and origin; every contour of three or more points
        is replaced by its refined polygon (float64, pixel units as the input's); ``meta`` gains ``refine``,
        ``refine_sigma``, ``refine_fine_share`` (share of vertices that took the fine estimate) and
        ``refine_clamped``.  Mesh it with ``stack_to_mesh(..., polygon="none")``.
    """

    density = _method_density(method, density)
    sigma = _resolve_sigma(sigma, lambda: auto_sigma(stack))
    fine = _resolve_fine(fine_sigma, sigma)
    counts = [0, 0]
    _check_density(density)
    pts, x0, y0, zidx, grid = _stack_grid(stack)
    runs = _z_runs(pts)  # the columns' runs, for the slice images (the same images, faster)
    off = np.array([x0, y0], dtype=np.float64)
    scale = np.array([grid[0], grid[1]])  # pixel indices -> units of the longer pixel side
    opts = dict(curvature=curvature, chord=chord, meridians=meridians, density=density, max_move=max_move,
                fine_sigma=fine, counts=counts)
    clamped = 0
    new_sections = []
    prev = []  # final polygons of the previous section (array-local coordinates)
    for k, sec in enumerate(stack.sections):
        kk = int(zidx[k])
        finals = []
        q = np.concatenate([p for p in prev if len(p) >= 3] or [np.zeros((0, 2))])
        images = {"runs": runs}  # the section's slice images, shared by its contours
        for c in sec.contours:
            c = np.asarray(c, dtype=np.int64)
            seed = np.asarray(polygonize(c, polygon), dtype=np.float64) if len(c) >= 3 else c.astype(np.float64)
            ring, nc = refine_ring(pts, (seed - off) * scale, kk, sigma, grid, q if prev else None, images=images,
                                   **opts)
            clamped += nc
            finals.append(ring)
        prev = finals
        new_sections.append(Section(z=sec.z, contours=tuple(f / scale + off for f in finals), parents=sec.parents))
    meta = dict(stack.meta)
    meta.update(refine=method, refine_sigma=sigma, refine_fine_share=counts[0] / max(counts[1], 1),
                refine_clamped=int(clamped), refine_seed=polygon)
    return ContourStack(sections=tuple(new_sections), spacing=stack.spacing, origin=stack.origin, meta=meta)


@njit(cache=True)
def _rings_meet(a, b):
    """True when an edge of the closed polygon ``a`` meets (crosses or touches) an edge of ``b``."""
    n, m = a.shape[0], b.shape[0]
    for i in range(n):
        ax, ay = a[i, 0], a[i, 1]
        bx, by = a[(i + 1) % n, 0], a[(i + 1) % n, 1]
        for j in range(m):
            cx, cy = b[j, 0], b[j, 1]
            dx, dy = b[(j + 1) % m, 0], b[(j + 1) % m, 1]
            if _segments_meet(ax, ay, bx, by, cx, cy, dx, dy):
                return True
    return False


def _boxes_meet(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all(a.min(axis=0) <= b.max(axis=0)) and np.all(b.min(axis=0) <= a.max(axis=0)))


@njit(cache=True)
def _inside_share(a, b):
    """Share of the points of ``a`` inside the closed polygon ``b`` (even-odd ray casting)."""
    n, m = a.shape[0], b.shape[0]
    hits = 0
    for i in range(n):
        x, y = a[i, 0], a[i, 1]
        inside = False
        for j in range(m):
            x1, y1 = b[j, 0], b[j, 1]
            x2, y2 = b[(j + 1) % m, 0], b[(j + 1) % m, 1]
            if (y1 > y) != (y2 > y):
                if x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
                    inside = not inside
        if inside:
            hits += 1
    return hits / n


def _untangle(rings: list, seeds: list, fixed: list) -> int:
    """Put back the seed of every refined ring that meets another ring of its slice or a fixed one,
    or that changes which of them it lies inside (or which lie inside it).

    ``rings`` (refined) and ``seeds`` are parallel lists (a ring that is its seed is not refined);
    ``fixed`` are rings that stay.  Where the slice holds no level crossing (a thin end), outer and
    hole polygons can pass each other inside the band without meeting: the nesting test catches
    that.  Repeats until nothing changes (a ring put back can disturb a neighbour's refined ring).
    Returns the number of rings put back.
    """
    boxes: dict = {}  # id -> (xmin, ymin, xmax, ymax, ring): each ring's box once (the ring kept alive)

    def meet(a, b):  # :func:`_boxes_meet` from the kept boxes
        for r in (a, b):
            if id(r) not in boxes:
                lo, hi = r.min(axis=0).tolist(), r.max(axis=0).tolist()
                boxes[id(r)] = (*lo, *hi, r)
        a0, a1, a2, a3, _ = boxes[id(a)]
        b0, b1, b2, b3, _ = boxes[id(b)]
        return a0 <= b2 and a1 <= b3 and b0 <= a2 and b1 <= a3

    def nested(a, b):  # is a inside b (most of its vertices: touching seeds share a few)
        return meet(a, b) and _inside_share(a, b) > 0.5

    n = len(rings)
    others_seed = list(seeds) + list(fixed)
    back = 0
    changed = True
    while changed:
        changed = False
        for i in range(n):
            if rings[i] is seeds[i]:
                continue
            others = list(rings) + list(fixed)
            for j, o in enumerate(others):
                if j == i or len(o) < 3:
                    continue
                so = others_seed[j]
                if ((meet(rings[i], o) and _rings_meet(rings[i], o))
                        or nested(rings[i], o) != nested(seeds[i], so) or nested(o, rings[i]) != nested(so, seeds[i])):
                    rings[i] = seeds[i]
                    back += 1
                    changed = True
                    break
    return back


def refine_volume_rings(mask, zs, spacing_xy, origin_xy, seeds: dict, below: dict | None = None,
                        fixed: dict | None = None, deepest: dict | None = None, *, method: str = "band", sigma="auto", curvature: bool = True,
                        chord: bool = True, meridians: bool = True, density: float | None = None,
                        max_move: float = 3.0, fine_sigma="auto"):
    """Refined slice polygons of a binary volume: the band refinement inside the volume mesher.

    The digital object ``I`` is the mask itself (voxel centres); every seed polygon goes through
    :func:`refine_ring` in the order of its slice, its meridian guide being the final ring of the
    polygon ``below`` names.  A refined ring that meets another ring of its slice (refined or
    ``fixed``) is replaced by its seed, so the polygons of a slice stay disjoint as the seeds are.

    Parameters
    ----------
    mask : (nz, ny, nx) bool ndarray
        The volume, indexed ``[k, j, i]``; voxel ``[k, j, i]`` has its centre at
        ``(ox + i dx, oy + j dy, zs[k])``.
    zs : (nz,) array
        Slice heights, strictly increasing (evenly spaced or not: see :func:`_make_grid`).
    spacing_xy, origin_xy : (dx, dy), (ox, oy)
        Pixel size (any positive ``dx, dy``) and the centre of pixel ``(0, 0)``.
    seeds : dict
        ``key -> (k, polygon)``: the polygons to refine, physical ``(x, y)``, outer ones
        counter-clockwise and holes clockwise, each in the band of slice ``k``.
    below : dict, optional
        ``key -> key``: the polygon of the slice below that a polygon continues (one-to-one band
        joins); its final ring guides the meridians.
    fixed : dict, optional
        ``k -> [polygon, ...]``: polygons of slice ``k`` that stay as they are.
    deepest : dict, optional
        ``key -> (x, y)``: the pixel centre of the polygon's component furthest from its
        boundary.  Where the blurred indicator is below 1/2 there, the slice holds no level set
        around the component (a part thinner than the blur: a thin tube, a tip) and the polygon
        keeps its seed; the level-set search would otherwise drag its vertices to the search's end.
    method, sigma, curvature, chord, meridians, density, max_move, fine_sigma
        As for :func:`refine_stack` (``sigma="auto"``: :func:`auto_sigma`'s rule applied to the seeds).

    Returns
    -------
    rings : dict
        ``key -> polygon`` (physical ``(x, y)``), the seed itself where refinement would fold it
        or make it meet a neighbour.
    info : dict
        ``refine_sigma``, ``refine_fine_share``, ``refine_clamped``, ``refine_kept_seeds`` (rings put back) and
        ``refine_thin`` (rings left as seeds in parts thinner than the blur).
    """
    density = _method_density(method, density)
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 3:
        raise ValueError(f"refine_volume_rings needs a 3D mask; got shape {mask.shape}")
    dx, dy = (float(v) for v in spacing_xy)
    if not (dx > 0 and dy > 0 and math.isfinite(dx) and math.isfinite(dy)):
        raise ValueError(f"band refinement needs a positive pixel size (dx, dy > 0); got dx={dx}, dy={dy}")
    zs = np.asarray(zs, dtype=np.float64)
    if len(zs) != mask.shape[0]:
        raise ValueError(f"{len(zs)} slice heights for {mask.shape[0]} slices")
    if len(zs) > 1 and not np.all(np.diff(zs) > 0):
        raise ValueError("band refinement needs strictly increasing slice heights")
    ox, oy = (float(v) for v in origin_xy)
    pad = 6
    pts = np.pad(mask, pad)
    runs = _z_runs(pts)  # the columns' runs, for the slice images (the same images, faster)
    grid, h = _grid_of_heights(dx, dy, zs, pts.shape[0], pad)
    ax, ay = grid[0], grid[1]
    # the mean slice spacing (units of h) for the automatic width's volume (it cancels in R = 3 V / A)
    dz = grid[2] if _even(grid) or len(zs) < 2 else float(zs[-1] - zs[0]) / (len(zs) - 1) / h

    def local(p):  # physical -> array-local, in units of h
        return np.c_[(np.asarray(p, dtype=np.float64)[:, 0] - ox) / h + pad * ax,
                     (np.asarray(p, dtype=np.float64)[:, 1] - oy) / h + pad * ay]

    loc = {key: (int(k), local(p)) for key, (k, p) in seeds.items()}
    sigma = _resolve_sigma(sigma, lambda: _auto_sigma_of([p for _, p in loc.values()], dz))
    fine = _resolve_fine(fine_sigma, sigma)
    counts = [0, 0]
    _check_density(density)
    opts = dict(curvature=curvature, chord=chord, meridians=meridians, density=density, max_move=max_move,
                strict=True, fine_sigma=fine, counts=counts)
    below = below or {}
    fixed = fixed or {}
    deepest = deepest or {}
    thin = set()
    if deepest:
        keys = list(deepest)
        at = np.array([[*local(np.reshape(deepest[key], (1, 2)))[0], loc[key][0] + pad] for key in keys])
        f = _field_many(pts, at, sigma, grid)[:, 0]
        thin = {key for key, v in zip(keys, f) if v < 0.5}
    by_slice: dict = {}
    for key, (k, _) in loc.items():
        by_slice.setdefault(k, []).append(key)
    finals = {}
    clamped = back = 0
    for k in sorted(by_slice):
        keys = by_slice[k]
        rings, starts = [], []
        images = {"runs": runs}  # the slice's images, shared by its rings
        for key in keys:
            seed = loc[key][1]
            guide = finals.get(below.get(key)) if meridians else None
            ring, nc = ((seed, 0) if key in thin
                        else refine_ring(pts, seed, k + pad, sigma, grid, guide, images=images, **opts))
            clamped += nc
            rings.append(ring)
            starts.append(seed)
        back += _untangle(rings, starts, [local(p) for p in fixed.get(k, ())])
        finals.update(zip(keys, rings))
    out = {key: np.c_[ox + (r[:, 0] - pad * ax) * h, oy + (r[:, 1] - pad * ay) * h] for key, r in finals.items()}
    return out, {"refine_sigma": sigma, "refine_fine_share": counts[0] / max(counts[1], 1),
                 "refine_clamped": int(clamped), "refine_kept_seeds": int(back),
                 "refine_thin": len(thin)}
