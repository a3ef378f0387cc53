"""Real-valued contour stacks -> binary volumes (even-odd fill), and meshing them.

Contour stacks read from files (DICOM RTSTRUCT, the JSON contour format of
``docs/contour-json.md``) hold real-valued rings in millimetres, often several per slice, with
holes given as nested rings.  The paper's polygons (DSS, MLP; Wiederhold & Villafuerte 2009,
sections 2-3) are defined for digital contours, so such a stack is first rasterized: every
section becomes one slice of a binary volume on a regular pixel grid, filled by the even-odd
rule over all of its rings (a pixel is inside when a ray from its centre crosses the rings an
odd number of times, so nested rings are holes, rings inside holes are islands, and the
winding of each ring does not matter).  The volume mesher
(:func:`contourmesh.volumes.volume_to_mesh`) then handles several contours per slice, holes and
branching.

Conventions
-----------
* Pixel ``[j, i]`` of slice ``k`` has its centre at ``(ox + i * pixel, oy + j * pixel)`` in
  physical units and lies at height ``z[k]`` (the section's own height: uneven spacing is kept).
* The default pixel size is the median of the non-zero steps ``|dx|`` and ``|dy|`` between
  consecutive ring points (physical units), capped at ``1.0`` (1 mm for stacks in millimetres):
  for contours drawn on an image the steps are mostly one image pixel, so this recovers roughly
  the image's pixel size; the cap keeps coarse polygons (few long edges) from being rasterized
  coarser than 1 unit.  Without any such step it is ``1.0``.  Pass ``pixel=`` to choose.
* The grid is aligned to multiples of the pixel size and has a margin of one empty pixel around
  the rings' bounding box, so the object never touches the array border.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .errors import LostContourWarning, warn_external
from .geometry import _fill_evenodd, shoelace_area
from .stacks import check_stack
from .types import ContourStack

__all__ = ["Raster", "rasterize_stack", "default_pixel", "LostContourWarning"]

#: Largest slice a rasterization may produce (pixels per slice) unless ``max_pixels`` says otherwise.
MAX_SLICE_PIXELS = 4096 * 4096
#: Largest volume (voxels) a rasterization may produce unless ``max_voxels`` says otherwise.
MAX_VOXELS = 2**31


class Raster(NamedTuple):
    """The result of :func:`rasterize_stack`; unpacks as ``volume, z, spacing, origin``.

    Attributes
    ----------
    volume : numpy.ndarray
        ``bool [z, y, x]``: one slice per section.
    z : numpy.ndarray
        ``float64`` slice heights (strictly increasing, those of the sections).
    spacing : tuple of float
        ``(dy, dx)``, the pixel size (equal).
    origin : tuple of float
        Physical ``(x, y, z)`` of the centre of voxel ``[0, 0, 0]``.
    """

    volume: np.ndarray
    z: np.ndarray
    spacing: tuple
    origin: tuple

    @property
    def mesh_kwargs(self) -> dict:
        """Keyword arguments for :func:`contourmesh.volumes.volume_to_mesh` (``z``, ``spacing``, ``origin``).

        ``spacing[0]`` (``dz``) is the median section distance (``1.0`` for one section); the
        explicit ``z`` positions decide the slice heights.
        """
        dz = float(np.median(np.diff(self.z))) if len(self.z) > 1 else 1.0
        return {"z": self.z, "spacing": (dz, self.spacing[0], self.spacing[1]), "origin": self.origin}


# ------------------------------------------------------------------------------------------------
# even-odd rule (crossing numbers), exact in the half-open convention
# ------------------------------------------------------------------------------------------------
# ------------------------------------------------------------------------------------------------
# rasterization
# ------------------------------------------------------------------------------------------------
def _physical_rings(stack: ContourStack):
    sx, sy = (float(v) for v in stack.spacing)
    ox, oy = (float(v) for v in stack.origin)
    out = []
    for k, s in enumerate(stack.sections):
        rings = []
        for c, ring in enumerate(s.contours):
            r = np.asarray(ring, dtype=np.float64)
            if r.ndim != 2 or r.shape[1] != 2:
                raise ValueError(f"section {k} contour {c}: expected a (k, 2) array of (x, y) points; got shape {r.shape}")
            if not np.all(np.isfinite(r)):
                raise ValueError(f"section {k} (z={s.z}) contour {c} holds NaN or infinite coordinates")
            rings.append(np.c_[r[:, 0] * sx + ox, r[:, 1] * sy + oy])
        out.append(rings)
    return out


def default_pixel(stack: ContourStack) -> float:
    """The default pixel size: median non-zero coordinate step between consecutive ring points, at most 1.

    Steps ``|dx|`` and ``|dy|`` along every ring (including the closing edge), in physical
    units, pooled; the median of those above ``1e-9``, capped at ``1.0``.  ``1.0`` when there
    are none.
    """
    steps = []
    for rings in _physical_rings(stack):
        for r in rings:
            if len(r) < 2:
                continue
            d = np.abs(np.diff(np.vstack([r, r[:1]]), axis=0)).reshape(-1)
            steps.append(d[d > 1e-9])
    if not steps:
        return 1.0
    allsteps = np.concatenate(steps)
    return min(float(np.median(allsteps)), 1.0) if len(allsteps) else 1.0




def _ring_covers_a_pixel(ring, x0, y0, pixel) -> bool:
    """Whether the ring alone (even-odd) contains at least one pixel centre of the grid."""
    i0, j0 = (int(v) for v in np.floor((ring.min(0) - (x0, y0)) / pixel))
    i1, j1 = (int(v) for v in np.ceil((ring.max(0) - (x0, y0)) / pixel))
    out = np.zeros((j1 - j0 + 1, i1 - i0 + 1), dtype=bool)
    starts = np.array([0, len(ring)], dtype=np.int64)
    _fill_evenodd(np.ascontiguousarray(ring[:, 0], dtype=np.float64), np.ascontiguousarray(ring[:, 1], dtype=np.float64),
                  starts, x0 + i0 * pixel, y0 + j0 * pixel, pixel, out)
    return bool(out.any())


def rasterize_stack(stack: ContourStack, pixel: float | None = None, *, max_pixels: int = MAX_SLICE_PIXELS,
                    max_voxels: int = MAX_VOXELS) -> Raster:
    """Even-odd fill of each section's rings on a regular pixel grid: one volume slice per section.

    Parameters
    ----------
    stack : ContourStack
        Sections at strictly increasing heights; contours in grid units of ``stack.spacing`` /
        ``stack.origin`` (for stacks read by :func:`contourmesh.io.read_contours` these are
        millimetres with spacing ``(1, 1)``).
    pixel : float, optional
        Pixel size in physical units; default :func:`default_pixel`.
    max_pixels, max_voxels : int
        Refuse grids larger than this per slice / in total (a ValueError suggests a larger pixel).

    Returns
    -------
    Raster
        ``(volume bool [z, y, x], z, (dy, dx), origin (x, y, z))``; ``Raster.mesh_kwargs`` gives
        the matching arguments of :func:`contourmesh.volumes.volume_to_mesh`.

    Examples
    --------
    >>> import numpy as np
    >>> from contourmesh.types import ContourStack, Section
    >>> sq = np.array([[0., 0.], [4., 0.], [4., 4.], [0., 4.]])
    >>> r = rasterize_stack(ContourStack((Section(0.0, (sq,)), Section(2.0, (sq,)))), pixel=1.0)
    >>> r.volume.shape, int(r.volume[0].sum()), r.origin
    ((2, 7, 7), 16, (-1.0, -1.0, 0.0))
    """
    zs = check_stack(stack)
    rings = _physical_rings(stack)
    if pixel is None:
        pixel = default_pixel(stack)
    pixel = float(pixel)
    if not np.isfinite(pixel) or pixel <= 0:
        raise ValueError(f"pixel must be a positive finite size; got {pixel!r}")
    pts = [r for rs in rings for r in rs if len(r)]
    if not pts:
        raise ValueError("the contour stack holds no points to rasterize")
    allp = np.concatenate(pts)
    lo = np.floor(allp.min(0) / pixel).astype(np.int64) - 1
    hi = np.ceil(allp.max(0) / pixel).astype(np.int64) + 1
    nx, ny = (int(v) for v in hi - lo + 1)
    if nx * ny > max_pixels:
        raise ValueError(
            f"rasterizing at pixel={pixel:g} gives {ny} x {nx} pixels per slice (limit {max_pixels}); "
            "pass a larger pixel="
        )
    if nx * ny * len(zs) > max_voxels:
        raise ValueError(
            f"rasterizing at pixel={pixel:g} gives {len(zs)} x {ny} x {nx} voxels (limit {max_voxels}); pass a larger pixel="
        )
    x0, y0 = float(lo[0] * pixel), float(lo[1] * pixel)
    vol = np.zeros((len(zs), ny, nx), dtype=bool)
    lost = []
    for k, rs in enumerate(rings):
        rs = [r for r in rs if len(r) >= 3]
        if not rs:
            continue
        xy = np.concatenate(rs)
        starts = np.zeros(len(rs) + 1, dtype=np.int64)
        starts[1:] = np.cumsum([len(r) for r in rs])
        _fill_evenodd(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]), starts, x0, y0, pixel, vol[k])
        lost += [(k, c, abs(shoelace_area(r))) for c, r in enumerate(rs) if not _ring_covers_a_pixel(r, x0, y0, pixel)]
    if not vol.any():
        raise ValueError(f"no pixel centre lies inside any contour at pixel={pixel:g}; pass a smaller pixel=")
    if lost:
        empty = sorted({k for k, _, _ in lost if not vol[k].any()})
        where = ", ".join(f"section {k} (z={zs[k]:g}) contour {c}" for k, c, _ in lost[:5])
        largest = max(a for _, _, a in lost)
        more = f" and {len(lost) - 5} more" if len(lost) > 5 else ""
        whole = (f"; sections {empty} rasterize to no pixel at all and are left out of the mesh" if empty else "")
        warn_external(f"{len(lost)} contour(s) enclose no pixel centre at pixel={pixel:g} and are lost "
                      f"(the largest lost contour has area {largest:.3g}, about {largest / pixel**2:.2g} pixels of "
                      f"{pixel:g} x {pixel:g}): {where}{more}{whole}; pass a smaller pixel= to keep them",
                      LostContourWarning)
    return Raster(vol, zs.copy(), (pixel, pixel), (x0, y0, float(zs[0])))


