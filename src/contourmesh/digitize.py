"""Digitization of analytic shapes into contour stacks and binary volumes (paper, section 6).

Wiederhold & Villafuerte (2009), section 6, slice each test surface by the grid planes
``z = k h`` and take, in every slice, the 4-contour of the *outer Jordan digitization* of the
cross-section; all contours run the same (clockwise, y down) way and each starts near the start of
the previous one.  Here, in every slice:

* ``I`` = the grid points ``(i h, j h)`` strictly inside the cross-section, decided with the exact
  (filtered, integer-fallback) inside test of :mod:`contourmesh.shapes`;
* ``U`` = the union of the closed grid cells with at least one corner in ``I``; its boundary is the
  slice's contour (one or more closed digital 4-curves, traced by
  :func:`contourmesh.tracing.trace_contours`), stored in grid units with ``spacing = (h, h)``.

Choices (documented once here)
------------------------------
* Slices: every ``k`` whose plane meets the solid's bounding box is examined; slices whose ``I``
  is empty are omitted.  With the default strict test a pole that is a grid point gives an empty
  ``I`` (the cross-section is a single point), so the centred sphere ``r = 15`` has the 29 slices
  ``z = -14 .. 14``; ``strict=False`` (closed solid) also keeps the two pole slices (31 slices),
  each with a one-point ``I``.
* Poles (``poles=True``, the default): where the closed solid touches the plane just beyond the
  first or last strict slice in exactly one grid point (the centred sphere's poles ``z = +-r``),
  that plane is added as a section whose contour is that single point; the mesh joins it to its
  neighbour by a fan (the natural reading of the paper, which is silent on poles).  Without a
  grid-point pole the end slice is closed by a flat cap (see :mod:`contourmesh.surface`).
* Truncated shapes: the end planes are closed, so if ``z0`` or ``z1`` falls on a grid plane that
  slice holds the whole end disc.
* Start points: the first slice's (first) contour starts at its point with the smallest ``y``, then
  the smallest ``x`` (the first point in raster order).  Every later contour starts at its point
  nearest to the nearest start point of the previous slice (``rotate_start(contour, near)``).
"""

from __future__ import annotations

import math

import numpy as np

from .shapes import Shape
from .tracing import rotate_start, trace_contours
from .types import ContourStack, Section

__all__ = ["outer_jordan_stack", "gauss_volume", "grid_box", "sample_volume", "mask_stack", "uneven_heights"]


def _check_inputs(shape, h):
    if not isinstance(shape, Shape):
        raise ValueError(f"expected a contourmesh.shapes.Shape; got {type(shape).__name__}")
    try:
        h = float(h)
    except (TypeError, ValueError):
        raise ValueError(f"grid spacing h must be a positive number; got {h!r}") from None
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"grid spacing h must be a finite positive number; got {h!r}")
    return h


def grid_box(shape: Shape, h: float = 1.0, pad: int = 1) -> np.ndarray:
    """Grid-index box ``[[i0, j0, k0], [i1, j1, k1]]`` (inclusive) covering the shape plus ``pad``.

    Every grid point ``h * (i, j, k)`` inside the solid lies in the box; ``pad`` extra layers of
    (outside) points surround it.
    """
    h = _check_inputs(shape, h)
    lo, hi = shape.bounds
    lo_i = np.floor(lo / h).astype(np.int64) - pad
    hi_i = np.ceil(hi / h).astype(np.int64) + pad
    return np.array([lo_i, hi_i])


def _raster_first(contour: np.ndarray) -> int:
    """Index of the point with the smallest y, then the smallest x."""
    return int(np.lexsort((contour[:, 0], contour[:, 1]))[0])


def _start_near(contours, previous_starts, rotate_start):
    """Rotate each contour to start near the previous slice's start points (paper, section 6)."""
    out = []
    for c in contours:
        c = np.asarray(c)
        if previous_starts is None or len(previous_starts) == 0:
            out.append(np.roll(c, -_raster_first(c), axis=0))
            continue
        # the previous start nearest to this contour
        d = ((c[None, :, :] - previous_starts[:, None, :]) ** 2).sum(axis=2).min(axis=1)
        near = previous_starts[int(np.argmin(d))]
        out.append(rotate_start(c, near))
    return out


def _pole(shape, k, h, box):
    """The single grid point where the closed solid touches plane ``k``, or None."""
    (i0, j0, _), (i1, j1, _) = box
    mask = shape.slice_mask(k, (i0, i1 + 1), (j0, j1 + 1), h, strict=False)
    if mask.sum() != 1:
        return None
    j, i = np.argwhere(mask)[0]
    return np.array([[i0 + i, j0 + j]], dtype=np.int64)


def outer_jordan_stack(shape: Shape, h: float = 1.0, *, strict: bool = True, poles: bool = True) -> ContourStack:
    """Slice a shape by the planes ``z = k h`` into a stack of outer-Jordan 4-contours.

    Implements the digitization of Wiederhold & Villafuerte (2009), section 6 (see the module
    docstring for the slice, end-plane and start-point conventions).

    Parameters
    ----------
    shape : contourmesh.shapes.Shape
        The solid, placed by its ``center`` and ``rotation``.
    h : float
        Grid spacing (the same in x, y and between slices).
    strict : bool
        ``True`` (default): ``I`` holds the grid points strictly inside.  ``False``: grid points on
        the curved surface count as inside too (the closed solid; keeps grid-point poles).
    poles : bool
        Add one-point pole sections where the solid touches the next grid plane in one grid point.

    Returns
    -------
    ContourStack
        Sections at ``z = k h`` (physical) with int64 contours in grid units, ``spacing = (h, h)``,
        ``origin = (0, 0)``; ``meta`` holds ``area_true``, ``volume_true``, ``shape`` (name,
        params, placement), ``h``, ``strict`` and ``digitization = "outer_jordan"``.

    Examples
    --------
    >>> from contourmesh.shapes import Sphere
    >>> st = outer_jordan_stack(Sphere(15))
    >>> len(st), st.sections[0].z, st.sections[-1].z
    (31, -15.0, 15.0)
    >>> st.sections[0].contours[0].tolist()
    [[0, 0]]
    >>> len(outer_jordan_stack(Sphere(15), poles=False))
    29
    """

    h = _check_inputs(shape, h)
    (i0, j0, k0), (i1, j1, k1) = grid_box(shape, h)
    sections = []
    previous = None
    for k in range(int(k0), int(k1) + 1):
        mask = shape.slice_mask(k, (i0, i1 + 1), (j0, j1 + 1), h, strict=strict)
        if not mask.any():
            continue
        # crop to the rows and columns that hold points of I (the tracer pads by itself)
        rows = np.flatnonzero(mask.any(axis=1))
        cols = np.flatnonzero(mask.any(axis=0))
        mask = mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
        contours, parents = trace_contours(mask, x0=int(i0 + cols[0]), y0=int(j0 + rows[0]))
        contours = _start_near([np.asarray(c, dtype=np.int64) for c in contours], previous, rotate_start)
        previous = np.array([c[0] for c in contours], dtype=np.int64)
        sections.append(Section(z=k * h, contours=tuple(contours), parents=tuple(int(p) for p in parents)))
    if poles and strict and sections:
        box = ((i0, j0, k0), (i1, j1, k1))
        below = _pole(shape, int(round(sections[0].z / h)) - 1, h, box)
        above = _pole(shape, int(round(sections[-1].z / h)) + 1, h, box)
        if below is not None:
            sections.insert(0, Section(z=sections[0].z - h, contours=(below,), parents=(-1,)))
        if above is not None:
            sections.append(Section(z=sections[-1].z + h, contours=(above,), parents=(-1,)))
    meta = {
        "area_true": float(shape.area),
        "volume_true": float(shape.volume),
        "shape": shape.describe(),
        "h": h,
        "strict": bool(strict),
        "poles": bool(poles),
        "digitization": "outer_jordan",
    }
    return ContourStack(sections=tuple(sections), spacing=(h, h), origin=(0.0, 0.0), meta=meta)


def gauss_volume(shape: Shape, h: float = 1.0, *, strict: bool = True, pad: int = 1):
    """Binary volume of the grid points inside the shape (Gauss digitization), indexed ``[z, y, x]``.

    Uses the same exact inside test (and end-plane convention) as :func:`outer_jordan_stack`, so
    its slice ``k`` is exactly the set ``I`` of that slice.

    Parameters
    ----------
    shape : contourmesh.shapes.Shape
    h : float
        Voxel spacing (isotropic).
    strict : bool
        See :func:`outer_jordan_stack`.
    pad : int
        Layers of empty voxels kept around the shape (>= 1 so that marching cubes closes it).

    Returns
    -------
    volume : numpy.ndarray of bool, shape ``(nz, ny, nx)``
    origin : tuple of float
        Physical ``(x0, y0, z0)`` of voxel ``[0, 0, 0]``; voxel ``[k, j, i]`` is the grid point
        ``origin + h * (i, j, k)``.
    """
    h = _check_inputs(shape, h)
    if int(pad) != pad or pad < 0:
        raise ValueError(f"pad must be a non-negative integer; got {pad!r}")
    (i0, j0, k0), (i1, j1, k1) = grid_box(shape, h, pad=int(pad))
    vol = np.zeros((int(k1 - k0 + 1), int(j1 - j0 + 1), int(i1 - i0 + 1)), dtype=bool)
    for n, k in enumerate(range(int(k0), int(k1) + 1)):
        vol[n] = shape.slice_mask(k, (i0, i1 + 1), (j0, j1 + 1), h, strict=strict)
    return vol, (float(i0 * h), float(j0 * h), float(k0 * h))


def sample_volume(shape: Shape, spacing, z=None, *, pad: int = 2):
    """The grid points inside ``shape`` on a grid of any spacing, with optional uneven slice heights.

    Where :func:`gauss_volume` samples the points ``h * (i, j, k)`` of a cubic grid,
    this samples ``(x0 + i dx, y0 + j dy, z[k])``: oblong pixels and slice gaps of a scanner
    (``spacing = (dz, dy, dx)``), or slices at the heights ``z`` (increasing; ``dz`` then only
    sets the padding when ``z`` is None).  ``x0 = dx * floor(xmin / dx) - pad dx`` (and so for
    ``y``), so the grid is aligned with the origin.  The inside test is :meth:`Shape.contains`
    (strict).

    Returns ``(mask, z, origin)``: ``mask[k, j, i]`` (bool), the slice heights (float64) and the
    physical ``(x0, y0, z0)`` of ``mask[0, 0, 0]`` (pass ``spacing``, ``z`` and ``origin`` on to
    :func:`contourmesh.mesh`).
    """
    if not isinstance(shape, Shape):
        raise ValueError(f"expected a contourmesh.shapes.Shape; got {type(shape).__name__}")
    try:
        dz, dy, dx = (float(v) for v in spacing)
    except (TypeError, ValueError):
        raise ValueError(f"spacing must be three numbers (dz, dy, dx); got {spacing!r}") from None
    if not all(math.isfinite(v) and v > 0 for v in (dz, dy, dx)):
        raise ValueError(f"spacing must be three finite positive numbers (dz, dy, dx); got {spacing!r}")
    if int(pad) != pad or pad < 0:
        raise ValueError(f"pad must be a non-negative integer; got {pad!r}")
    lo, hi = shape.bounds
    xs = np.arange(np.floor(lo[0] / dx) - pad, np.ceil(hi[0] / dx) + pad + 1) * dx
    ys = np.arange(np.floor(lo[1] / dy) - pad, np.ceil(hi[1] / dy) + pad + 1) * dy
    if z is None:
        zs = np.arange(np.floor(lo[2] / dz) - pad, np.ceil(hi[2] / dz) + pad + 1) * dz
    else:
        zs = np.asarray(z, dtype=np.float64).reshape(-1)
        if len(zs) == 0 or not np.all(np.isfinite(zs)) or np.any(np.diff(zs) <= 0):
            raise ValueError("z must be finite, strictly increasing slice heights")
    zz, yy, xx = np.meshgrid(zs, ys, xs, indexing="ij")
    return shape.contains(xx, yy, zz), np.asarray(zs, dtype=np.float64), (float(xs[0]), float(ys[0]), float(zs[0]))


def mask_stack(mask, z, spacing, origin) -> ContourStack:
    """The contour stack of a binary volume: each non-empty slice's 4-contours (with their nesting),
    at the physical heights ``z``, with pixels of ``spacing = (dz, dy, dx)`` from ``origin``
    (as :func:`sample_volume` returns them)."""
    mask = np.asarray(mask, dtype=bool)
    secs = []
    for k in range(mask.shape[0]):
        if mask[k].any():
            cs, ps = trace_contours(mask[k])
            secs.append(Section(z=float(z[k]), contours=tuple(np.asarray(c, dtype=np.int64) for c in cs),
                                parents=tuple(int(p) for p in ps)))
    return ContourStack(sections=tuple(secs), spacing=(float(spacing[2]), float(spacing[1])),
                        origin=(float(origin[0]), float(origin[1])))


def uneven_heights(extent: float, seed: int = 3, lo: float = 0.5, hi: float = 1.3) -> np.ndarray:
    """Slice heights covering ``[-extent, extent]`` with gaps drawn uniformly from ``[lo, hi]``
    (seeded), one height at 0: a test grid for uneven slice spacing."""
    gaps = np.random.default_rng(seed).uniform(lo, hi, size=int(2 * extent / lo) + 8)
    zs = np.cumsum(gaps)
    zs = zs - zs[np.searchsorted(zs, zs[-1] / 2)]
    return zs[(zs > -extent - 2 * hi) & (zs < extent + 2 * hi)]
