"""Binary volumes -> closed, genus-correct meshes: several contours per slice, holes, branching.

The paper allows one contour per slice.  Real segmentations have many, with holes, and they
split and merge from slice to slice.  This module meshes any binary volume with the paper's
polygons and bands wherever the slices allow it, and falls back to an exact construction where
they do not.

Conventions (stated once)
-------------------------
* Volumes are indexed ``[z, y, x]`` (``axis`` picks another slicing axis) with ``spacing =
  (dz, dy, dx)`` or explicit, strictly increasing slice positions ``z``.  Mesh vertices are
  ``(x, y, z)``: voxel ``[k, j, i]`` has its centre at ``(ox + i dx, oy + j dy, z_k)``.
* **Connectivity**: object 4 / background 8 within a slice, and slices join where their object
  pixels overlap (face-adjacent voxels): the object is **6-connected**, the background
  26-connected.  Objects touching the array border behave as if padded with background.
* **Contours** of a slice are the crack boundaries of its 4-connected components (pixels as unit
  squares centred on the voxel centres), outer ones with positive shoelace area, holes negative.
* **Polygons**: ``"none"`` is the crack contour itself; ``"dss"`` its maximal-DSS polygon;
  ``"mlp"`` is the paper's MLP with the object pixels playing the role of ``I`` (the same outer
  Jordan construction as for analytic shapes: the shortest curve around the component's pixel
  centres inside its ``U``; for a hole, the same for the hole's pixels).  Where an MLP
  degenerates to a point or a segment (one-pixel-wide parts, one-pixel holes) the maximal-DSS
  polygon of the crack contour is used for that contour instead (the crack contour itself where
  that polygon is not simple), so every polygon encloses area.
* **Joins** between consecutive slices: the components of both slices that overlap form groups.
  A group of one component below and one above, whose overlap ``O`` is connected and whose holes
  match one to one through the holes of ``O``, is joined by the selected band triangulation
  (outer to outer, hole to hole): the paper's method.  A fork or a merge (one component on one
  side), chains of several on both sides whose overlaps form a tree, a hole that closes or
  opens, and a hole that runs out of the side of its component are
  **bridged joins**: the contours of each side are joined into one ring by bridges (segments in
  their plane, through the background between components or through the material from a hole to
  its component's outer contour: a keyhole, a polyline through the pixels outside the overlap
  where no straight one keeps clear) and the two rings by one band; a hole that the other
  slice covers is closed by a lid.  This needs every pair's overlap connected, no overlap inside
  a hole of another, at most one hole from each side in each hole of ``O``, and bridges that touch
  nothing else in their plane; the band and lids are tested for crossing faces before they are
  used.  Opt-in (``_DENSE_STEP``), the polygons of components in such joins get a vertex every
  pixel along their edges (where the point lies in the slice's band), so that the least-area
  band's rungs stay local; their band joins keep the faces made between the polygons' own
  points.  Also opt-in (``_DENSE_RETRY_STEP``), only the components of the joins that fail are
  densified so (a vertex every pixel, then every half pixel) and those joins tried again before
  they become exact (not with the band refinement unless ``_DENSE_RETRY_REFINED``).  By default
  (``_DENSE_FAILED_STEP``) a failed fork or merge with a speck (a component of a few pixels) is
  tried once more on densified polygons, and kept densified where that builds; a bridged band that
  crosses itself only once its bridge ends are one vertex tries the other band rules; and the
  polygons banded to crack rings (beside exact joins) get a vertex every pixel
  (``_DENSE_MIXED_STEP``).  Every other group (overlaps that close a loop: a handle forms) is joined
  *exactly*: each contour rises as a collar to its crack contour in the mid-plane, the lower
  slice's pixels not covered from above are closed there by up-facing faces, and the upper slice
  mirrors this; the overlap stays open.  That is the surface of the 6-connected voxel object
  between the two slices (edges where two voxels touch are kept apart), so the genus is right by
  construction; the area there is voxel-like.  ``meta`` counts each kind.
* **Ends**: a component with no partner above (below) is closed by a flat earcut cap (holes
  included) in its plane (``caps="flat"``) or half a slice spacing beyond it (``caps="half"``);
  with the band refinement, ``caps="smooth"`` closes an end that continues a band join on its
  last sections' area profile (a dome or a taper) and the others flat;
  a component with no partner on either side becomes a prism one spacing thick.
* **Manifold**: where two contours touch at a corner (diagonal pixels), the touching vertex is
  split per fan of faces and each copy is moved a hair (``1e-3`` of a pixel) into its own fan, so
  the mesh is an edge- and vertex-manifold surface.
* **Embedded**: the finished mesh is checked for crossing faces (exactly,
  :mod:`contourmesh.intersect`); faces that cross by a hair are pulled apart
  (:func:`contourmesh.repair.resolve_crossings`).  Where faces still cross, each band or bridged
  join that made one becomes an exact join and each capped component that made one keeps its crack
  rings, and the mesh is built again (a few rounds at most; ``meta["crossing_fallbacks"]`` counts
  the joins and caps changed).  A rebuild keeps the bridged joins whose rings, neighbourhood and
  permission to try intermediate sections did not change (a kept join is what building it again
  would give: tested), makes again only the joins and caps whose kind or rings changed (each is made in
  local vertex numbers and the mesh numbered from them in order: the same mesh as making them one
  after the other), and only its faces that did not occur in the previous build are tested again
  (the other pairs are known: the same answer as a whole check).  This covers a band sweeping through the prism of a component that
  touches its own only diagonally, polygons of 8-adjacent components that overlap, and bands from
  a crack ring that touches itself.  Whatever is left is counted in ``meta["self_intersections"]``
  and logged as a warning.
"""

from __future__ import annotations

import functools
import logging
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import accumulate

import numpy as np

from ._heap import collector_paused, release_free_heap
from ._kernels import KERNEL_OPTIONS, internal_kernel, njit
from ._recent import MISSING, Recent
from .bands import TRIANGULATORS, _band_crosses, band_is_folded, triangulate_band, twist_guarded_band
from .bands.bridges import PreferCovered, bridge_tree, bridged_ring_ids, segments_cross
from .bands.caps import cap_faces
from .bands.ends import _SmoothEnds
from .bands.optimal import triangulate_band_optimal
from .fastpath import (
    CONNECTIVITY,
    FortranRuns,
    _components,
    _fast_volume_to_mesh,
    _one_band,
    _paint_labels,
    _pixels_mlp,
    _scan_new,
    _stack_candidates,
    _trace_outer,
    _words_from,
    pixels_mlp,
    redo_self_crossing_bands,
    runs_labels,
    slice_components,
    slice_labels,
)
from .geometry import _distinct_rows as _count_distinct_rows  # (compiled: called in _rows_distinct_kernel)
from .geometry import deepest_pixel, grid_to_xy, shoelace_area, slice_gap
from .intersect import any_intersecting, intersecting_pairs
from .measure import triangle_areas
from .polygons import POLYGONIZERS, dss_polygon, thin_part_polygon
from .polygons.dss import _greedy_segmentation
from .polygons.mlp import _mlp_grid, _mlp_pull
from .refine import REFINERS, refine_volume_rings
from .repair import (
    _compact,
    _open_necks,
    _separate_coincident,
    _split_four_face_edges,
    crossing_pairs_after_change,
    resolve_crossings,
    split_nonmanifold_vertices,
)
from .topology import _root  # the compiled union-find root (path halving), shared
from .tracing import (
    _contour4_ok,
    _first_row_run,
    _hole_parts,
    _hole_spans,
    _runs_hole_labels,
    _slice_cracks,
    label_mask,
    missing_corners,
    overlap_groups,
    overlap_groups_runs,
    overlap_hole_labels,
    slice_boxes,
    slice_cracks,
    unique_keys,
)
from .types import Mesh
from .volume_input import _c_order, binary_label, prepare_volume

log = logging.getLogger("contourmesh")

__all__ = ["volume_to_mesh", "prepare_volume", "voxel_topology"]

_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
_SQUARE = np.ones((3, 3), dtype=bool)


def _with_z(xy, z) -> np.ndarray:
    """Points ``(x, y)`` at height ``z``: ``np.c_[xy, np.full(len(xy), z)]`` (np.c_ is slow on
    the many small arrays of the mesher)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    out = np.empty((len(xy), 3))
    out[:, :2] = xy
    out[:, 2] = z
    return out


def _pad1(m, value=False) -> np.ndarray:
    """``np.pad(m, 1, constant_values=value)`` of a 2D boolean mask (np.pad costs some 15 us a
    call on the mesher's small masks)."""
    out = np.full((m.shape[0] + 2, m.shape[1] + 2), value, dtype=m.dtype)
    out[1:-1, 1:-1] = m
    return out


def _next(a) -> np.ndarray:
    """``np.roll(a, -1, axis=0)``: each element's successor round the ring."""
    return np.concatenate([a[1:], a[:1]])


# ------------------------------------------------------------------------------------------------
# input validation
# ------------------------------------------------------------------------------------------------
# ------------------------------------------------------------------------------------------------
# topology reference
# ------------------------------------------------------------------------------------------------
def voxel_topology(mask) -> dict:
    """Components, cavities and total genus of a binary volume's boundary surface (6/26).

    Computed independently of the meshing: the Euler characteristic of the 6-connected voxel
    complex (``skimage.measure.euler_number(connectivity=1)``), object components (6-connected),
    cavities (background components, 26-connected, not touching the padded border).  The boundary
    has ``components + cavities`` surfaces with total genus ``surfaces - chi``.  The reference for
    :func:`contourmesh.topology.topology`, its compiled twin on the band route.
    """
    from scipy import ndimage
    from skimage.measure import euler_number

    m = np.pad(np.asarray(mask, dtype=bool), 1)
    chi = int(euler_number(m, connectivity=1))
    _, ncomp = ndimage.label(m, structure=ndimage.generate_binary_structure(3, 1))
    _, nback = ndimage.label(~m, structure=ndimage.generate_binary_structure(3, 3))
    cavities = nback - 1
    surfaces = ncomp + cavities
    return {"components": int(ncomp), "cavities": int(cavities), "surfaces": int(surfaces),
            "euler": chi, "genus": int(surfaces - chi)}


# ------------------------------------------------------------------------------------------------
# per-slice contours and polygons
# ------------------------------------------------------------------------------------------------
def _mlp_of_pixels(pix: np.ndarray) -> np.ndarray | None:
    """MLP (outer Jordan construction) of an 8- or 4-connected pixel set; centre coordinates.

    ``None`` where it encloses no area.  Compiled (:func:`contourmesh.fastpath.pixels_mlp`): the
    outer contour of ``U`` (connected for such a set) and the MLP kernel of
    :func:`contourmesh.polygons.mlp_polygon`, the same polygon."""
    poly = pixels_mlp(pix)
    return None if poly is None else poly.astype(np.float64)


def _dilated_square(m: np.ndarray) -> np.ndarray:
    """``ndimage.binary_dilation(m, structure=_SQUARE)`` of a 2D bool mask (outside it: background),
    as the dilation by a column of three and then by a row of three, each two shifted ORs: the same
    pixels, without ndimage's set-up (most of its cost on a component's box)."""
    d = m.copy()
    d[1:] |= m[:-1]
    d[:-1] |= m[1:]
    out = d.copy()
    out[:, 1:] |= d[:, :-1]
    out[:, :-1] |= d[:, 1:]
    return out


class _RecentLabels:
    """The label images of the last few slices used (:attr:`_Slice.labels`); the others are
    dropped and made again from their masks when next asked for.  The joins go up the stack, each
    using two neighbouring slices (a bridged join's sections and waypoints the same two), so a few
    images are enough; every slice's image kept to the end was a second copy of the volume (a
    byte a voxel)."""

    def __init__(self, size: int = 4):
        self.size = size
        self.held: list = []  # most recent last
        self.remade = 0  # label images made again (for the tests and benchmarks)

    def hold(self, s) -> None:
        held = self.held
        if held and held[-1] is s:
            return
        if s in held:
            held.remove(s)
        held.append(s)
        if len(held) > self.size:
            held.pop(0)._labels = None


class _Planes:
    """The slices of a boolean volume, each C-ordered when read (``planes[k]``, a 2D array): the
    volume's own where it is C-ordered, else from the block of about 4 MiB of consecutive slices
    last read going up the stack (:meth:`reading`), else copied alone.  The general mesher reads
    the slices going up the stack; a volume in another layout (Fortran-ordered, as many file
    readers give it) read a slice at a time costs a cache line per voxel, a block at a time about
    as much as one C-ordered copy of the whole, without holding a second volume to the end.

    A Fortran-ordered volume's slices are not read at all to label them: :meth:`runs` gives each
    slice's runs (what the labeller finds in the C-ordered slice) from one pass over the volume's
    bytes in memory order (:class:`contourmesh.fastpath.FortranRuns`, made when first asked for);
    a block of such a volume made C-ordered touched every page of it, 0.08 CPU-s a call on the liver
    where the pass takes 0.012."""

    def __init__(self, mask, block_bytes: int = 4 << 20):
        self.mask = mask
        self.direct = mask.flags.c_contiguous
        self.block = int(min(64, max(1, block_bytes // max(1, mask[0].size)))) if len(mask) else 1
        self.k0, self.part = -1, None
        self.fortran = (not self.direct and mask.ndim == 3 and mask.dtype == bool and mask.size > 0
                        and mask.flags.f_contiguous)
        self.scanned = None

    def runs(self, k: int):
        """Slice ``k``'s runs ``(ry, rx0, rx1, row_start)`` where the volume is Fortran-ordered
        (:func:`contourmesh.fastpath.slice_runs` of ``self[k]``, the same arrays), else ``None``."""
        if not self.fortran:
            return None
        if self.scanned is None:
            self.scanned = FortranRuns(self.mask)
        return self.scanned[k]

    def __len__(self) -> int:
        return len(self.mask)

    def __getitem__(self, k: int) -> np.ndarray:
        if self.direct:
            return self.mask[k]
        if self.part is not None and 0 <= k - self.k0 < len(self.part):
            return self.part[k - self.k0]
        return np.ascontiguousarray(self.mask[k])

    def reading(self, k: int) -> np.ndarray:
        """``self[k]``, from the block that holds it (read now where it is not the last one)."""
        if not self.direct and (self.part is None or not 0 <= k - self.k0 < len(self.part)):
            self.part = None  # (the old block goes first)
            self.k0 = k - k % self.block
            self.part = np.ascontiguousarray(self.mask[self.k0: self.k0 + self.block])
        return self[k]

    def release(self) -> None:
        """Drops the block last read and the runs (the slices read later are copied alone)."""
        self.k0, self.part = -1, None
        self.fortran, self.scanned = False, None


class _HoleMasks(Sequence):
    """The holes of one component as pixel sets: a sequence of bool masks over the component's
    box (``hole_masks[c][1]`` of a :class:`_Slice`).  Each is kept cropped to the hole's own box
    and made whole when read: on large slices with many small holes a whole box per hole came to
    more than all the slice's contours."""

    __slots__ = ("shape", "parts")

    def __init__(self, shape, masks):
        self.shape = tuple(shape)
        self.parts = []
        for m in masks:
            ys, xs = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
            y0, x0 = int(ys[0]), int(xs[0])
            self.parts.append((y0, x0, m[y0: ys[-1] + 1, x0: xs[-1] + 1].copy()))

    @classmethod
    def empty(cls, shape):
        """No hole in a box of ``shape`` (``cls(shape, [])``, made without the constructor's loop)."""
        out = object.__new__(cls)
        out.shape, out.parts = tuple(shape), []
        return out

    @classmethod
    def of_parts(cls, shape, parts):
        """The holes given as ``(y0, x0, cropped mask)`` (each mask's first and last rows and columns
        hold a pixel), as ``__init__`` crops them."""
        out = cls(shape, [])
        out.parts = list(parts)
        return out

    def __len__(self) -> int:
        return len(self.parts)

    def first_pixel(self, i):
        """``divmod(int(np.argmax(self[i])), width)``: hole ``i``'s first pixel in raster order, read
        from its cropped mask (whose first row holds a pixel) without making the whole one."""
        y0, x0, part = self.parts[i]
        return y0, x0 + int(part[0].argmax())

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(len(self))[i]]
        y0, x0, part = self.parts[i]
        m = np.zeros(self.shape, dtype=bool)
        m[y0: y0 + part.shape[0], x0: x0 + part.shape[1]] = part
        return m


class _CrackXY(Sequence):
    """The crack contours of a slice's components in physical xy (``crack_outer``, or with
    ``holes`` the lists of ``crack_holes``), made from their corner coordinates when first read
    and kept from then on (the components read are those with crack rings, a few): every one
    kept, as corners and as floats, came to a sixth of the general mesher's live memory on large
    volumes.  :meth:`made` gives one without keeping it."""

    __slots__ = ("corners", "to_xy", "holes", "kept")

    def __init__(self, corners, to_xy, holes: bool):
        self.corners, self.to_xy, self.holes = corners, to_xy, holes
        self.kept: dict = {}

    def __len__(self) -> int:
        return len(self.corners)

    def made(self, c):
        if self.holes:
            return [self.to_xy(h) for h in self.corners[c]]
        return self.to_xy(self.corners[c])

    def __getitem__(self, c):
        if isinstance(c, slice):
            return [self[i] for i in range(len(self))[c]]
        got = self.kept.get(c)
        if got is None:
            got = self.kept[c] = self.made(c)
        return got


class _Slice:
    """The components of one slice with their contours and polygons (physical xy).

    ``recent``: a :class:`_RecentLabels` that decides how long the slice keeps its label image
    (``None``: for the slice's lifetime); the slice then keeps its runs instead of its mask, and
    paints the label image again from them when it is asked for after being dropped (the same
    image: the labeller paints it from these runs).  A view of a block of :class:`_Planes` is not
    kept, nor the mask's bits; relabelling the mask, once more for each later pass over the slices
    that reads it, took the lobster 0.031 CPU-s a call and painting 0.005 (liver 0.018 and 0.008),
    and the liver's peak went from 89 to 84 MiB.  ``box``: a pair of slices of ``mask2d`` outside which it
    has no pixel (an intermediate section): only the box is labelled (the same labels, numbered
    in raster order within it, and the same boxes, moved back to the whole image).  ``scanned``:
    the mask's runs ``(ry, rx0, rx1, row_start)`` found already (:meth:`_Planes.runs`), with its
    shape as ``mask2d`` (any object with that ``shape``): the same slice, the mask not read."""

    def __init__(self, mask2d, polygon, to_xy_corner, to_xy_center, recent=None, box=None, scanned=None):
        # ndimage.label(mask2d, structure=_CROSS) and find_objects, from the runs (compiled)
        self._recent, self._shape = recent, tuple(mask2d.shape)
        self._mask = self._runs = self._box_runs = None
        # every component's crack contours in one compiled pass over the int32 labels (slice corner
        # coordinates; component c's contours are first[c]: first[c + 1], outer and holes in the
        # order _crack_contours gives them for the component's cropped mask), and with "mlp" every
        # component's MLP in another (what _mlp_of_pixels gives for its cropped mask)
        mlp = polygon not in ("dss", "none")
        thin = moved = None
        if scanned is None:
            # (the whole mask, or its box: labels, boxes, cracks, holes and MLPs in one compiled call,
            # _slice_pass; a box's numbers are moved to the whole image in the call, _slice_pass_at, and
            # its labels below)
            m = np.ascontiguousarray(mask2d if box is None else mask2d[box], dtype=bool)
            if m.ndim != 2:
                raise ValueError(f"mask must be a 2D array indexed [y, x]; got shape {m.shape}")
            b8 = m.reshape(-1).view(np.uint8)
            b64, woff, aligned = _words_from(b8)
            if box is None:
                labels, n, boxes, runs32, pts, starts, area2, first, found, mlps, thin, moved = _slice_pass(
                    b8, b64, np.int64(m.shape[0]), np.int64(m.shape[1]), aligned, woff, np.int64(mlp))
                self.objects = [(slice(y0, y1), slice(x0, x1)) for y0, y1, x0, x1 in boxes.tolist()]
            else:  # (the boxes moved to the whole image: the same slices as moving each one after)
                sy, sx = box[0].start or 0, box[1].start or 0
                # (the runs, crack points, holes' MLPs, thin parts' polygons and MLPs moved to the whole
                # image in the call: _slice_pass_at)
                labels, n, boxes, runs32, pts, starts, area2, first, found, mlps, thin, moved = _slice_pass_at(
                    b8, b64, np.int64(m.shape[0]), np.int64(m.shape[1]), aligned, woff, np.int64(mlp),
                    np.int64(sx), np.int64(sy))
                self.objects = [(slice(y0 + sy, y1 + sy), slice(x0 + sx, x1 + sx))
                                for y0, y1, x0, x1 in boxes.tolist()]
            self.n = int(n)
            lab32 = labels
            if recent is not None and box is None:
                self._runs = runs32
            if not mlp:
                mlps = None
            if found[0] != 0:  # pragma: no cover - (see _slice_holes)
                thin = moved = None
            if box is not None:
                if recent is not None:  # (labelled whole it gives the same labels)
                    self._mask = mask2d
                # (its runs in the whole image, as _runs holds them, for _simple_join: the runs the whole
                # mask has, as it has no pixel outside the box)
                self._box_runs = runs32
        else:
            labels, self.n, self.objects, runs = runs_labels(scanned, self._shape, runs=True)
            lab32, sx, sy = labels, 0, 0
            if recent is not None:  # (row, first and end column, component: a copy, not views of the labeller's
                # buffers, in int32: half the bytes, for a volume of many slices held to the end)
                self._runs = np.empty((4, len(runs[0])), np.int32)
                self._runs[0], self._runs[1], self._runs[2], self._runs[3] = runs[0], runs[1], runs[2], runs[3] - 1
            boxes = slice_boxes(self.objects)
            pts, starts, area2, first = slice_cracks(lab32, boxes, runs)
            # every component's outer contour, its holes' pixel sets and (with "mlp") its holes' MLPs in
            # one compiled pass (_slice_holes; the loop it replaces is _components_plain, which also names
            # a fault the pass refuses)
            found = _slice_holes(lab32, boxes, pts, starts, area2, first, np.int64(sx), np.int64(sy), np.int64(mlp))
            # with "mlp", every component's MLP (one compiled pass, _slice_mlps_stacks: what
            # fastpath.slice_mlps_flat gives from the runs) and the outer polygons made after the loop,
            # all at once (_outer_polygons)
            mlps = _slice_mlps_stacks(boxes, *runs) if mlp else None
        if box is None:
            # the labels in the smallest dtype that holds them
            self._labels = self._small(labels)
        else:
            part = self._small(lab32)  # (the whole image's labels made in that dtype at once)
            labels = np.zeros(mask2d.shape, dtype=part.dtype)
            labels[box] = part
            self._labels = labels
        self.dense = {}   # (component, hole or -1) -> which points of a densified polygon were added
        self.dense_gen = {}  # component -> how many times its polygons were densified (see _retry_dense)
        self.fallbacks = 0
        if found[0] == 0:
            outer_at = self._components(found, boxes, pts, starts, polygon, to_xy_corner, to_xy_center)
        else:  # pragma: no cover - (the plain loop raises the fault the compiled pass found)
            outer_at = self._components_plain(lab32, boxes, pts, starts, area2, first, polygon, mlps,
                                              to_xy_corner, to_xy_center)
        # the crack contours in physical xy (used by exact joins), made when read
        self.crack_outer = _CrackXY(self.crack_outer_c, to_xy_corner, False)
        self.crack_holes = _CrackXY(self.crack_holes_c, to_xy_corner, True)
        if mlps is not None:
            self.outer = self._outer_polygons(mlps, pts, starts, outer_at, to_xy_corner, to_xy_center, thin, moved)
        if recent is not None:
            recent.hold(self)

    def _components(self, found, boxes, pts, starts, polygon, to_xy_corner, to_xy_center):
        """The per-component lists of the slice (``crack_outer_c``, ``crack_holes_c``, ``hole_masks``,
        ``holes``, and ``outer`` but with "mlp") from :func:`_slice_holes`' pass ``found``; returns
        the index of each component's outer crack contour (int64).  What :meth:`_components_plain`
        makes, each hole's MLP polygon a view of one array of the slice's hole polygons (the same
        integer sums and row maps; see :func:`_slice_holes`)."""
        _, outer_at, hole_at, hole_start, hmeta, hflat, hp, hps, hok = found
        st = starts.tolist()
        self.crack_outer_c = [pts[st[i]: st[i + 1]] for i in outer_at.tolist()]
        hs = hole_start.tolist()
        hxy = to_xy_center(hp) if len(hp) else None
        ha, hm, hps, hok = hole_at.tolist(), hmeta.tolist(), hps.tolist(), hok.tolist()
        mlp = polygon not in ("dss", "none")
        thin = {}  # (a hole one pixel wide, whose MLP encloses no area: its thin part's polygon)
        if mlp and not all(hok):
            which = [j for j in range(len(hok)) if not hok[j]]
            tp, ts, tok = _thin_part_polygons(pts, starts, hole_at[which])
            txy = to_xy_corner(tp)
            ts = ts.tolist()
            thin = {j: txy[ts[i]: ts[i + 1]] for i, (j, good) in enumerate(zip(which, tok.tolist())) if good}
        crack_holes, hole_masks, holes = [], [], []
        empty = _HoleMasks.empty
        for c, (y0, y1, x0, x1) in enumerate(boxes.tolist()):
            sl = self.objects[c]
            h0, h1 = hs[c], hs[c + 1]
            if h0 == h1:  # (most components: no hole)
                crack_holes.append([])
                hole_masks.append((sl, empty((y1 - y0, x1 - x0))))
                holes.append([])
                continue
            crack_h = [pts[st[i]: st[i + 1]] for i in ha[h0: h1]]
            crack_holes.append(crack_h)
            hole_masks.append((sl, _HoleMasks.of_parts((y1 - y0, x1 - x0), [
                (hy, hx, hflat[o: o + hh * hw].view(bool).reshape(hh, hw).copy())
                for hy, hx, hh, hw, o in hm[h0: h1]])))
            if not mlp:
                off = np.array([sl[1].start, sl[0].start])
                holes.append([self._polygon(h, None, polygon, to_xy_corner, to_xy_center, off, hole=True)
                              for h in crack_h])
                continue
            got = []
            for j, h in zip(range(h0, h1), crack_h):
                if hok[j]:
                    got.append(hxy[hps[j]: hps[j + 1]])
                    continue
                self.fallbacks += 1  # (as _polygon does; the compiled batch refuses what the plain form names)
                t = thin.get(j)
                got.append(to_xy_corner(thin_part_polygon(h)) if t is None else t)
            holes.append(got)
        self.crack_holes_c, self.hole_masks, self.holes = crack_holes, hole_masks, holes
        if not mlp:
            self.outer = [self._polygon(crack_o, None, polygon, to_xy_corner, to_xy_center,
                                        np.array([sl[1].start, sl[0].start]), hole=False)
                          for crack_o, sl in zip(self.crack_outer_c, self.objects)]
        return outer_at

    def _components_plain(self, lab32, boxes, pts, starts, area2, first, polygon, mlps, to_xy_corner,
                          to_xy_center):
        """The per-component loop that :meth:`_components` and :func:`_slice_holes` replace (kept as
        their reference, and for the faults the compiled pass refuses, which it names)."""
        self.outer = []   # per component: polygon (physical xy)
        self.holes = []   # per component: list of hole polygons
        self.hole_masks = []  # per component: list of (slices, mask) for each hole (local bbox)
        self.crack_outer_c = []  # raw crack contours in corner coordinates (integers)
        self.crack_holes_c = []
        outer_at = []  # (per component, its outer crack contour's index in pts / starts)
        for c in range(self.n):
            sl = self.objects[c]
            y0, x0 = sl[0].start, sl[1].start
            k0, k1 = int(first[c]), int(first[c + 1])
            if k1 - k0 == 1 and area2[k0] > 0:  # (most components: one outer contour, no hole)
                crack_o, crack_h = pts[starts[k0]: starts[k1]], []
                outer_at.append(k0)
            else:
                cont = [pts[starts[i]: starts[i + 1]] for i in range(k0, k1)]
                outer_i = [i for i in range(len(cont)) if area2[k0 + i] > 0]
                if len(outer_i) != 1:  # pragma: no cover - a 4-component has one outer boundary
                    raise RuntimeError(f"component {c} has {len(outer_i)} outer crack contours")
                crack_o = cont[outer_i[0]]
                outer_at.append(k0 + outer_i[0])
                crack_h = [cont[i] for i in range(len(cont)) if area2[k0 + i] < 0]
            off = np.array([x0, y0])
            # the holes as pixel sets: background 8-components of the component's bbox not
            # connected to the bbox border: each filled (compiled) from the pixel right of its hole
            # contour's first edge, so in the order of the contours; cropped to its own box
            shape = (sl[0].stop - y0, sl[1].stop - x0)
            parts = []
            if crack_h:  # (a component without hole contours has no holes)
                seeds = np.array([self._hole_seed(h, off) for h in crack_h], dtype=np.int64)
                meta, flat = _hole_parts(lab32, c + 1, boxes[c], seeds)
                for hy, hx, hh, hw, o in meta.tolist():
                    if hh <= 0:  # pragma: no cover - 4/8 duality: one hole per hole contour
                        raise RuntimeError("could not pair a hole contour with its pixels")
                    parts.append((hy, hx, flat[o: o + hh * hw].view(bool).reshape(hh, hw).copy()))
            self.hole_masks.append((sl, _HoleMasks.of_parts(shape, parts)))
            self.crack_outer_c.append(crack_o)
            self.crack_holes_c.append(crack_h)
            # (the holes' polygons by "mlp" made from their cropped masks and moved to the component's box)
            if mlps is None:
                self.outer.append(self._polygon(crack_o, None, polygon, to_xy_corner, to_xy_center, off, hole=False))
            self.holes.append([
                self._polygon(h, None, polygon, to_xy_corner, to_xy_center, off, hole=True,
                              mlp=False if mlps is None else self._moved(pixels_mlp(part), hx, hy))
                for h, (hy, hx, part) in zip(crack_h, parts)
            ])
        return np.array(outer_at, dtype=np.int64)

    def _outer_polygons(self, mlps, pts, starts, outer_at, to_xy_corner, to_xy_center, made=None, moved=None):
        """The components' outer polygons by "mlp", as :meth:`_polygon` makes each (``hole=False``),
        made for the whole slice at once: the MLPs (``mlps``: :func:`contourmesh.fastpath.slice_mlps_flat`)
        moved to the slice and mapped in one call; the components whose MLP encloses no area (parts
        one pixel wide) by :func:`_thin_part_polygons` on their crack contours (``pts[starts[i]:
        starts[i + 1]]`` for ``i`` in ``outer_at``), mapped in another.  The same numbers (integer
        sums and maps of each row alone), each polygon a view of one of the two arrays.  ``made``:
        the thin contours' ``_thin_part_polygons`` made already (by :func:`_slice_pass`), or None;
        ``moved``: the MLPs moved to the slice already (the same integers), or None."""
        mp, mps, ma2 = mlps
        n = self.n
        if n == 0:
            return []
        if made is not None and moved is not None and not len(made[2]):
            # (most slices: _slice_pass found no thin component, so every MLP encloses area and
            # has three points or more; the same views as below, without the test of each)
            xy, mps = to_xy_center(moved), mps.tolist()
            return [xy[a: b] for a, b in zip(mps, mps[1:])]
        cnt = mps[1:] - mps[:-1]  # (np.diff)
        has = ((cnt >= 3) & (ma2 != 0)).tolist()
        if moved is None:
            off = np.array([(sl[1].start, sl[0].start) for sl in self.objects], dtype=np.int64).reshape(-1, 2)
            moved = mp + np.repeat(off, cnt, axis=0)
        xy = to_xy_center(moved) if len(mp) else None
        thin = [c for c in range(n) if not has[c]]
        self.fallbacks += len(thin)
        # (called where no component is thin too: every slice compiles it, so a warm-up does)
        tp, ts, ok = _thin_part_polygons(pts, starts, outer_at[thin]) if made is None else made
        mps = mps.tolist()
        if not thin:  # (most slices: every MLP encloses area)
            return [xy[mps[c]: mps[c + 1]] for c in range(n)]
        txy = to_xy_corner(tp)
        ok, ts = ok.tolist(), ts.tolist()
        out = []
        j = 0
        for c in range(n):
            if has[c]:
                out.append(xy[mps[c]: mps[c + 1]])
                continue
            if ok[j]:
                out.append(txy[ts[j]: ts[j + 1]])
            else:  # (a contour the compiled checks refuse: the plain form, which names the fault)
                i = int(outer_at[c])
                out.append(to_xy_corner(thin_part_polygon(pts[starts[i]: starts[i + 1]])))
            j += 1
        return out

    def _small(self, labels):
        small = np.uint8 if self.n < 2**8 else np.uint16 if self.n < 2**16 else None
        return labels.astype(small) if small is not None else labels

    @property
    def labels(self) -> np.ndarray:
        """The slice's component labels (0 background, ``c + 1`` component ``c``), as
        ``slice_labels`` makes them from the mask: made again where :class:`_RecentLabels`
        dropped them."""
        if self._labels is None:
            if self._runs is not None:
                ry, rx0, rx1, comp = self._runs.astype(np.int64)  # (the labeller's int64 signature)
                self._labels = self._small(_paint_labels(ry, rx0, rx1, comp, self._shape[0], self._shape[1]))
            else:  # pragma: no cover - (a slice labelled in a box keeps its labels)
                self._labels = self._small(slice_labels(self._mask)[0])
            self._recent.remade += 1
        if self._recent is not None:
            self._recent.hold(self)
        return self._labels

    def kept_runs(self):
        """The slice's runs (int32 ``[row, first column, end column, component]``, raster order,
        whole-image coordinates) where it keeps them: with a :class:`_RecentLabels` (in place of
        its label image) or labelled in a box; None for a slice made without either."""
        return self._runs if self._runs is not None else self._box_runs

    @staticmethod
    def _moved(p, x, y):
        """An MLP of :func:`pixels_mlp` (or ``None``) moved by ``(x, y)``."""
        return None if p is None else p + np.array([x, y], dtype=np.int64)

    @staticmethod
    def _hole_seed(h, off):
        """``(py, px)``: the pixel (in the component's box, whose lower-left corner is ``off``) right of
        the first edge of the hole contour ``h``, a pixel of the hole (the object is on its left)."""
        p, q = h[0] - off, h[1 % len(h)] - off
        d = q - p
        # pixel on the right of the step p->q (y up): for +x step it is the pixel below
        if d[0] == 1:
            return p[1] - 1, p[0]
        if d[0] == -1:
            return p[1], p[0] - 1
        if d[1] == 1:
            return p[1], p[0]
        return p[1] - 1, p[0] - 1

    def _polygon(self, crack, pixels, method, to_xy_corner, to_xy_center, off, hole, mlp=False):
        """The polygon of one crack contour by ``method`` (physical xy).  ``mlp``: with "mlp", the
        MLP of ``pixels`` made already (:func:`contourmesh.fastpath.pixels_mlp` moved to the box: int64
        or ``None``),
        ``False`` where it is to be made here from ``pixels``."""

        if method == "none":
            return to_xy_corner(crack)
        if method == "dss":
            poly = np.asarray(dss_polygon(crack), dtype=np.float64)
            if len(np.unique(poly, axis=0)) >= 3 and abs(shoelace_area(poly)) > 0:
                return to_xy_corner(poly)
            self.fallbacks += 1
            return to_xy_corner(crack)
        # mlp: the outer Jordan construction with these pixels as I
        poly = _mlp_of_pixels(pixels) if mlp is False else None if mlp is None else mlp.astype(np.float64)
        if poly is None:  # a part one pixel wide: the MLP is a segment or a point
            self.fallbacks += 1
            return to_xy_corner(thin_part_polygon(crack))
        poly = poly + off
        if hole:
            poly = poly[::-1]
        return to_xy_center(poly)


@njit(cache=True, **KERNEL_OPTIONS)
def _slice_holes(lab, boxes, pts, starts, area2, first, sx, sy, mlp):  # pragma: no cover (compiled)
    """The holes of every component of a slice in one pass (``lab`` its int32 labels; ``boxes``,
    ``pts``, ``starts``, ``area2``, ``first`` as :func:`contourmesh.tracing.slice_cracks` gives them,
    in the frame of ``lab``): what :meth:`_Slice._components_plain` finds component by component.
    Returns ``(status, outer_at, hole_at, hole_start, meta, flat, hp, hps, ok)``:

    * ``outer_at[c]``: the index of component ``c``'s outer crack contour (the one of positive
      area); ``hole_at[hole_start[c]: hole_start[c + 1]]``: its hole contours (negative area), in
      order;
    * hole ``j``'s pixels (:func:`contourmesh.tracing._hole_parts` from the pixel right of its
      contour's first edge, :meth:`_Slice._hole_seed`; found by its run-at-a-time form
      :func:`contourmesh.tracing._hole_spans`, the same bytes): ``flat[o: o + h * w]`` as ``(h, w)`` with
      ``meta[j] = (y, x, h, w, o)``, ``(y, x)`` its first row and column in the component's box;
    * with ``mlp``: hole ``j``'s MLP (:func:`contourmesh.fastpath._pixels_mlp` of those pixels, as
      :func:`contourmesh.fastpath.pixels_mlp` reads them) moved to the slice (by the box's corner and
      ``(sx, sy)``) and reversed, ``hp[hps[j]: hps[j + 1]]``, where ``ok[j]`` (three points or more
      and a non-zero area; :meth:`_Slice._polygon` takes the thin part's polygon otherwise).  The
      integers of ``(p + (hx, hy)) + off`` in the plain form, summed before the map to floats: the
      same numbers.

    ``status`` 1 where a component has not one outer contour or a hole contour finds no pixels (both
    impossible for a 4-component; nothing else is then given, and the plain loop names the fault)."""
    n = boxes.shape[0]
    one = np.int64(1)
    outer_at = np.empty(n, np.int64)
    hole_at = np.empty(area2.shape[0], np.int64)
    hole_start = np.empty(n + 1, np.int64)
    nh = 0
    for c in range(n):
        hole_start[c] = nh
        no = 0
        for i in range(first[c], first[c + 1]):
            if area2[i] > 0:
                outer_at[c] = i
                no += 1
            elif area2[i] < 0:
                hole_at[nh] = i
                nh += 1
        if no != 1:
            return (one, outer_at, hole_at[:0], hole_start, np.empty((0, 5), np.int64), np.empty(0, np.uint8),
                    np.empty((0, 2), np.int64), np.empty(1, np.int64), np.empty(0, np.bool_))
    hole_start[n] = nh
    meta = np.empty((nh, 5), np.int64)
    fcap = 64
    flat = np.empty(fcap, np.uint8)
    fused = 0
    pcap = 64
    hp = np.empty((pcap, 2), np.int64)
    hps = np.empty(nh + 1, np.int64)
    ok = np.empty(nh, np.bool_)
    pos = 0
    hps[0] = 0
    for c in range(n):
        h0, h1 = hole_start[c], hole_start[c + 1]
        if h0 == h1:
            continue
        x0, y0 = boxes[c, 2], boxes[c, 0]
        seeds = np.empty((h1 - h0, 2), np.int64)
        for j in range(h0, h1):
            a = starts[hole_at[j]]
            k = starts[hole_at[j] + 1] - a
            b = a + 1 if k > 1 else a
            px, py = pts[a, 0] - x0, pts[a, 1] - y0
            dx, dy = pts[b, 0] - pts[a, 0], pts[b, 1] - pts[a, 1]
            # the pixel right of the step (y up), as _Slice._hole_seed
            if dx == 1:
                seeds[j - h0, 0], seeds[j - h0, 1] = py - 1, px
            elif dx == -1:
                seeds[j - h0, 0], seeds[j - h0, 1] = py, px - 1
            elif dy == 1:
                seeds[j - h0, 0], seeds[j - h0, 1] = py, px
            else:
                seeds[j - h0, 0], seeds[j - h0, 1] = py - 1, px - 1
        m, f = _hole_spans(lab, c + one, boxes[c], seeds)
        if fused + f.shape[0] > fcap:
            fcap = max(2 * fcap, fused + f.shape[0])
            f2 = np.empty(fcap, np.uint8)
            f2[:fused] = flat[:fused]
            flat = f2
        flat[fused: fused + f.shape[0]] = f  # (block copies: the same bytes as a loop over them)
        for j in range(h0, h1):
            hy, hx, hh, hw = m[j - h0, 0], m[j - h0, 1], m[j - h0, 2], m[j - h0, 3]
            if hh <= 0:
                return (one, outer_at, hole_at[:0], hole_start, np.empty((0, 5), np.int64), np.empty(0, np.uint8),
                        np.empty((0, 2), np.int64), np.empty(1, np.int64), np.empty(0, np.bool_))
            o = fused + m[j - h0, 4]
            meta[j, 0], meta[j, 1], meta[j, 2], meta[j, 3], meta[j, 4] = hy, hx, hh, hw, o
            ok[j] = False
            if mlp:
                p, a2 = _pixels_mlp(flat[o: o + hh * hw], hh, hw)
                k = p.shape[0]
                if k >= 3 and a2 != 0:
                    ok[j] = True
                    if pos + k > pcap:
                        pcap = max(2 * pcap, pos + k)
                        hp2 = np.empty((pcap, 2), np.int64)
                        for t in range(pos):
                            hp2[t, 0], hp2[t, 1] = hp[t, 0], hp[t, 1]
                        hp = hp2
                    mx, my = hx + x0 + sx, hy + y0 + sy
                    for t in range(k):
                        hp[pos + t, 0] = p[k - 1 - t, 0] + mx
                        hp[pos + t, 1] = p[k - 1 - t, 1] + my
                    pos += k
            hps[j + 1] = pos
        fused += f.shape[0]
    return np.int64(0), outer_at, hole_at[:nh], hole_start, meta, flat[:fused], hp[:pos], hps, ok



@njit(cache=True, **KERNEL_OPTIONS)
def _slice_pass(b8, b64, h, w, aligned, woff, mlp):  # pragma: no cover (compiled)
    """What :class:`_Slice` reads of a whole mask (``b8``: its ``h * w`` bytes, ``b64``, ``woff``,
    ``aligned`` as :func:`contourmesh.fastpath._words_from` gives them), in one compiled call: the
    labeller's runs and labels (:func:`contourmesh.fastpath.slice_labels` with ``runs``), the boxes,
    the crack contours (:func:`contourmesh.tracing.slice_cracks`), the holes
    (:func:`_slice_holes`), with ``mlp`` the MLPs (:func:`contourmesh.fastpath.slice_mlps_flat`, made by
    :func:`_slice_mlps_stacks`)
    and the thin outer parts' polygons (:meth:`_Slice._outer_polygons`' call of
    :func:`_thin_part_polygons`).  The same kernels on the same values as the calls one by one
    (``tests/test_volumes_slice_pass.py``), which cost a small slice more in Python, in arrays
    boxed and unboxed between them and in the wrappers round them than in the kernels: some
    30 of the 90 us of a bunny-128 slice.

    Returns ``(labels, n, boxes, runs, pts, starts, area2, first, found, mlps, thin, moved)``: ``labels``
    int32, ``boxes`` as :func:`contourmesh.tracing.slice_boxes`, ``runs`` the int32 ``(4, runs)``
    rows ``(row, first column, end column, component)`` that :class:`_Slice` keeps, ``found``
    :func:`_slice_holes`' tuple, ``mlps`` the MLPs' ``(pts, ps, a2s)`` (empty without ``mlp``) and
    ``thin`` the ``(out, ostarts, ok)`` of the components whose MLP encloses no area (empty without
    ``mlp`` or where ``found`` is a fault) and ``moved`` the MLPs' points moved to the slice (each
    component's by its box's lower-left corner)."""
    ry32, rx032, rx132, rs32, _ = _scan_new(b8, b64, np.int64(0), h, w, aligned, woff)
    nr = len(ry32)
    lab32 = np.empty(nr, np.int32)
    lab32, n, _, bbox, _ = _components(ry32, rx032, rx132, rs32, h, lab32)
    ry = ry32.astype(np.int64)
    rx0 = rx032.astype(np.int64)
    rx1 = rx132.astype(np.int64)
    lab = lab32.astype(np.int64)
    labels = _paint_labels(ry, rx0, rx1, lab, h, w)
    rlab = lab + 1
    runs = np.empty((4, nr), np.int32)
    for r in range(nr):
        runs[0, r] = ry[r]
        runs[1, r] = rx0[r]
        runs[2, r] = rx1[r]
        runs[3, r] = lab[r]
    boxes = np.empty((n, 4), np.int64)
    for c in range(n):
        boxes[c, 0] = bbox[c, 1]
        boxes[c, 1] = bbox[c, 3] + 1
        boxes[c, 2] = bbox[c, 0]
        boxes[c, 3] = bbox[c, 2] + 1
    pts, starts, area2, first = _slice_cracks(labels, boxes, ry, rx0, rx1, rlab)
    zero = np.int64(0)
    found = _slice_holes(labels, boxes, pts, starts, area2, first, zero, zero, mlp)
    if mlp:
        mlps = _slice_mlps_stacks(boxes, ry, rx0, rx1, rlab)
    else:
        mlps = (np.empty((0, 2), np.int64), np.zeros(n + 1, np.int64), np.empty(0, np.int64))
    which = np.empty(0, np.int64)
    if mlp and found[0] == 0:
        ps, a2s = mlps[1], mlps[2]
        nt = 0
        for c in range(n):
            if not (ps[c + 1] - ps[c] >= 3 and a2s[c] != 0):
                nt += 1
        which = np.empty(nt, np.int64)
        nt = 0
        for c in range(n):
            if not (ps[c + 1] - ps[c] >= 3 and a2s[c] != 0):
                which[nt] = found[1][c]
                nt += 1
    thin = _thin_part_polygons(pts, starts, which)
    # the MLPs moved to the slice (each by its box's corner: the integers _outer_polygons adds)
    mp, ps = mlps[0], mlps[1]
    moved = np.empty((len(mp), 2), np.int64)
    for c in range(n):
        for i in range(ps[c], ps[c + 1]):
            moved[i, 0] = mp[i, 0] + boxes[c, 2]
            moved[i, 1] = mp[i, 1] + boxes[c, 0]
    return labels, n, boxes, runs, pts, starts, area2, first, found, mlps, thin, moved


@njit(cache=True, **KERNEL_OPTIONS)
def _slice_pass_at(b8, b64, h, w, aligned, woff, mlp, sx, sy):  # pragma: no cover (compiled)
    """:func:`_slice_pass` of a box of a slice (an intermediate section's) whose first row and column
    are ``sy`` and ``sx`` of the whole image, with what :class:`_Slice` reads in whole-image
    coordinates moved there in place: the runs' rows and columns, the crack points, the holes' MLPs,
    the thin parts' polygons and the moved MLPs (the same integers as adding ``(sx, sy)`` to each
    after the call: a sum of integers).  Eight array operations in Python a section, about 8 us of
    the lobster's 323 sections a call."""
    got = _slice_pass(b8, b64, h, w, aligned, woff, mlp)
    runs = got[3]
    for r in range(runs.shape[1]):
        runs[0, r] += sy
        runs[1, r] += sx
        runs[2, r] += sx
    _shift_xy(got[4], sx, sy)
    _shift_xy(got[8][6], sx, sy)
    _shift_xy(got[10][0], sx, sy)
    _shift_xy(got[11], sx, sy)
    return got


@internal_kernel
def _shift_xy(p, sx, sy):  # pragma: no cover (compiled)
    """Adds ``(sx, sy)`` to the points ``p`` (int64 ``(k, 2)``), in place."""
    for i in range(p.shape[0]):
        p[i, 0] += sx
        p[i, 1] += sy


@njit(cache=True, **KERNEL_OPTIONS)
def _slice_mlps_stacks(boxes, ry, rx0, rx1, rlab):  # pragma: no cover (compiled)
    """:func:`contourmesh.fastpath._slice_mlps_runs` (the reference, the same three arrays), each
    component that is a stack (one run in each of its rows, rows consecutive) given its MLP's
    candidates from its runs (:func:`contourmesh.fastpath._stack_candidates`, as the fast path takes
    them) and pulled (:func:`contourmesh.polygons.mlp._mlp_pull`), without its cropped mask, the
    walk round it or the MLP's grids; the others traced on their cropped masks as there, the MLP's
    grids one pair for the slice (zero again after each component) rather than a pair made and
    cleared per component.  The MLP is translation-equivariant (integer candidates and tests, the
    start the vertex nearest the contour's first point): a stack's MLP, made in slice coordinates,
    moved to its box is the one made in the box.  The lobster's slices and sections: 2631 of their
    3166 components are stacks, the kernel 8.4 -> 7.3 ms a call; the rotated socket's 273 of 521,
    8.9 -> 7.5 ms; the liver's 130 of 586, level."""
    n = boxes.shape[0]
    nr = ry.shape[0]
    # the runs of each component in raster order (a counting sort by label): those of label v are
    # order[at[v]: at[v + 1]]
    at = np.empty(n + 2, np.int64)
    for v in range(n + 2):
        at[v] = 0
    for r in range(nr):
        at[rlab[r]] += 1
    for v in range(1, n + 2):
        at[v] += at[v - 1]
    order = np.empty(nr, np.int64)
    for i in range(nr):
        r = nr - 1 - i
        at[rlab[r]] -= 1
        order[at[rlab[r]]] = r
    size = 1
    hm = 1
    wm = 1
    for c in range(n):
        size = max(size, (boxes[c, 1] - boxes[c, 0]) * (boxes[c, 3] - boxes[c, 2]))
        hm = max(hm, boxes[c, 1] - boxes[c, 0])
        wm = max(wm, boxes[c, 3] - boxes[c, 2])
    buf = np.empty(size, np.uint8)
    # (the MLP's grids for every component's box: its contour lies in [-1, w] x [-1, h] of the box,
    # the grids' origin (-3, -3) leaves the margin of two the grids want)
    gw = wm + 6
    on = np.zeros((hm + 6) * gw, np.uint8)
    bg = np.zeros((hm + 6) * gw, np.uint8)
    zero = np.int64(0)
    one = np.int64(1)
    mthree = np.int64(-3)
    ps = np.empty(n + 1, np.int64)
    a2s = np.empty(n, np.int64)
    cap = 64
    out = np.empty((cap, 2), np.int64)
    pos = 0
    for c in range(n):
        y0, y1, x0, x1 = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
        hh, ww = y1 - y0, x1 - x0
        start, cand, kind, mc = _stack_candidates(ry, rx0, rx1, order, at[c + 1], at[c + 2])
        if mc >= 0:
            _, _, p = _mlp_pull(start, cand, kind, mc, one)
            dx, dy = x0, y0  # (slice coordinates: moved to the box below)
        else:
            buf[: hh * ww] = 0
            for t in range(at[c + 1], at[c + 2]):
                r = order[t]
                base = (ry[r] - y0) * ww - x0
                buf[base + rx0[r]: base + rx1[r]] = 1
            # (from the component's first run's first pixel, the first pixel of its mask)
            r = order[at[c + 1]]
            cc = _trace_outer(buf, zero, hh, ww, zero, zero, rx0[r] - x0 - 1, ry[r] - y0 - 1)
            _, _, p = _mlp_grid(cc, one, on, bg, mthree, mthree, gw)
            dx, dy = zero, zero
        k = len(p)
        if pos + k > cap:
            cap = max(2 * cap, pos + k)
            out2 = np.empty((cap, 2), np.int64)
            for i in range(pos):
                out2[i, 0] = out[i, 0]
                out2[i, 1] = out[i, 1]
            out = out2
        ps[c] = pos
        for i in range(k):
            out[pos + i, 0] = p[i, 0] - dx
            out[pos + i, 1] = p[i, 1] - dy
        # (twice the signed area of the moved points, as _pixels_mlp sums it)
        a2 = 0
        for i in range(k):
            j = i + 1 if i + 1 < k else 0
            a2 += out[pos + i, 0] * out[pos + j, 1] - out[pos + j, 0] * out[pos + i, 1]
        pos += k
        a2s[c] = a2
    ps[n] = pos
    return out[:pos], ps, a2s


@njit(cache=True, **KERNEL_OPTIONS)
def _thin_part_polygons(pts, starts, which):  # pragma: no cover (compiled)
    """:func:`contourmesh.polygons.thin_part_polygon` of the contours ``pts[starts[i]: starts[i +
    1]]`` for ``i`` in ``which``, in one pass: ``(out, ostarts, ok)``, contour ``j``'s polygon
    ``out[ostarts[j]: ostarts[j + 1]]`` where ``ok[j]``; not ok (nothing written) where the contour
    fails :func:`contourmesh.tracing.check_contour4`'s compiled checks, for the plain form to take.
    The areas' signs and the simplicity test as the plain form's on integer points: its float
    orientations are exact there and only their signs are read."""
    m = which.shape[0]
    total = 0
    for j in range(m):
        total += starts[which[j] + 1] - starts[which[j]]
    out = np.empty((total, 2), np.int64)
    ost = np.zeros(m + 1, np.int64)
    ok = np.zeros(m, np.bool_)
    at = 0
    for j in range(m):
        c = pts[starts[which[j]]: starts[which[j] + 1]]
        k = c.shape[0]
        if k >= 4 and _contour4_ok(c):
            ok[j] = True
            idx = _greedy_segmentation(c)
            nd = idx.shape[0]
            use = False
            if nd >= 3:
                ad = _ring_area2(c, idx, nd)
                ac = _ring_area2(c, np.arange(k), k)
                if (ad > 0 and ac > 0) or (ad < 0 and ac < 0):
                    use = _simple_ring(c, idx, nd)
            if use:
                for t in range(nd):
                    out[at, 0] = c[idx[t], 0]
                    out[at, 1] = c[idx[t], 1]
                    at += 1
            else:
                for t in range(k):
                    out[at, 0] = c[t, 0]
                    out[at, 1] = c[t, 1]
                    at += 1
        ost[j + 1] = at
    return out[:at], ost, ok


@internal_kernel
def _ring_area2(c, idx, n):  # pragma: no cover (compiled)
    """Twice the signed area of the ring ``c[idx[:n]]`` (integers: ``thin_part_polygon``'s ``area``)."""
    a = 0
    b = 0
    for t in range(n):
        u = idx[t]
        v = idx[(t + 1) % n]
        a += c[u, 0] * c[v, 1]
        b += c[v, 0] * c[u, 1]
    return a - b


@internal_kernel
def _orient(ux, uy, vx, vy, wx, wy):  # pragma: no cover (compiled)
    return (vx - ux) * (wy - uy) - (vy - uy) * (wx - ux)


@internal_kernel
def _simple_ring(c, idx, n):  # pragma: no cover (compiled)
    """:func:`contourmesh.polygons.is_simple_polygon` of the ring ``c[idx[:n]]`` (``n >= 3``): distinct
    points and no two non-adjacent edges meeting."""
    for s in range(n):
        for t in range(s):
            if c[idx[s], 0] == c[idx[t], 0] and c[idx[s], 1] == c[idx[t], 1]:
                return False
    for i in range(n):
        ax, ay = c[idx[i], 0], c[idx[i], 1]
        bx, by = c[idx[(i + 1) % n], 0], c[idx[(i + 1) % n], 1]
        for j in range(n):
            d = abs(i - j)
            if d <= 1 or d == n - 1:
                continue
            px, py = c[idx[j], 0], c[idx[j], 1]
            qx, qy = c[idx[(j + 1) % n], 0], c[idx[(j + 1) % n], 1]
            d1 = _orient(ax, ay, bx, by, px, py)
            d2 = _orient(ax, ay, bx, by, qx, qy)
            d3 = _orient(px, py, qx, qy, ax, ay)
            d4 = _orient(px, py, qx, qy, bx, by)
            if _sign(d1) * _sign(d2) <= 0 and _sign(d3) * _sign(d4) <= 0:
                return False
    return True


@internal_kernel
def _sign(x):  # pragma: no cover (compiled)
    return (x > 0) - (x < 0)


# ------------------------------------------------------------------------------------------------
# mesh assembly
# ------------------------------------------------------------------------------------------------
#: The local band rules (the paper's and the shortest-diagonal rule): made for two similar contours.
_LOCAL_RULES = ("wiederhold", "greedy")


def _dissimilar_rule(n_lo: int, n_hi: int, triangulation: str, budget: float) -> str:
    """The band rule for two rings that are not two similar contours: a crack ring against a
    polygon (next to an exact join), or two bridged rings (each runs along its bridges twice).

    The local rules step along both rings by their own measure (the paper's by length, greedy
    by the shorter diagonal); on such a pair they fan: a crack ring's steps across the surface
    each take a long thin triangle to a far vertex of the polygon, and a bridged band can be
    twice the area of the surface it stands for while passing the twist guard (1.25 times the
    arc-length band).  There the least-area band (``"optimal"``) is used, where its cubic cost
    ``n^2 m`` (``n <= m`` the ring sizes) is within ``budget``; otherwise, and for the other
    rules, ``triangulation`` itself."""
    if triangulation in _LOCAL_RULES:
        n, m = sorted((n_lo, n_hi))
        if n > 2 and n * n * m <= budget:
            return "optimal"
    return triangulation


#: Largest ``n^2 m`` for which a band is made optimal (least-area): a twisted band's replacement,
#: and the least-area band of a mixed pair (:func:`_band_faces`).
_MIXED_OPTIMAL_BUDGET = 3e7


def _band_faces(lo, hi, triangulation, optimal_budget=_MIXED_OPTIMAL_BUDGET, mixed=False):
    """The guarded band between two rings (see :meth:`_Mesher.band`) and how many guards fired.

    The paper's band is made in compiled code (:func:`contourmesh.fastpath._one_band`: the same
    faces and the same twist guard); the bands it hands back (folded, twisted, too close to call)
    and the ones whose faces cross go through :func:`~contourmesh.bands.twist_guarded_band`.

    ``mixed``: one ring is a crack ring and the other a polygon (next to an exact join).  Such
    pairs differ most, and a band of any rule can cross itself there; its faces are then tested
    whatever the rule, and the first other rule whose band keeps clear is taken.  Without this, the
    whole-mesh test turns the band into an exact join, which makes the next section a crack ring
    and its next band mixed in turn: a cascade up a tube, one slice per rebuild.  A mixed pair is
    joined by the least-area band rather than a local rule (:func:`_dissimilar_rule`)."""
    if mixed:
        triangulation = _dissimilar_rule(len(lo), len(hi), triangulation, optimal_budget)
    if triangulation == "wiederhold" and min(len(lo), len(hi)) > 2:
        f, status = _one_band(lo, hi)
        if status == 0 and not _band_crosses(np.concatenate([lo, hi]), f):
            return f, 0
    f, replaced = twist_guarded_band(lo, hi, triangulation, optimal_budget)
    if band_is_folded(f):  # last resort: the arc-length band never folds
        f = triangulate_band(lo, hi, "arclength")
        replaced += 1
    if mixed and min(len(lo), len(hi)) > 2:
        P = np.concatenate([lo, hi])
        if _band_crosses(P, f):
            n, m = sorted((len(lo), len(hi)))
            for method in ("optimal", "arclength", "wiederhold", "greedy", "bounded"):
                if method == triangulation or (method == "optimal" and n * n * m > optimal_budget) or \
                        (method == "bounded" and n * n * m <= optimal_budget):
                    continue
                # (over the budget, last: the least-area band among those that start near the
                # shortest rung, in about optimal_budget steps; see triangulate_band_optimal)
                g = triangulate_band_optimal(lo, hi, max_work=optimal_budget) if method == "bounded" else \
                    triangulate_band(lo, hi, method)
                if not band_is_folded(g) and not _band_crosses(P, g):
                    return g, int(replaced) + 1
    return f, int(replaced)


def _fan_added(f, rings) -> np.ndarray:
    """Band faces ``f`` made between the kept points of ``rings`` (``(ids, keep)`` each: a ring's
    vertex ids and which of them the band used), with each face on an edge between two kept points
    that skips others made a fan over them (same orientation, same area)."""
    where = {}
    for r, (ids, keep) in enumerate(rings):
        kept = np.flatnonzero(keep)
        nxt = np.roll(kept, -1)
        for p, q in zip(kept.tolist(), nxt.tolist()):
            if (q - p) % len(ids) != 1:
                where[int(ids[p])] = (r, p, q)  # the kept point after p is q, with points between
    if not where:
        return f
    out = []
    for a, b, c in np.asarray(f, dtype=np.int64).tolist():
        for x, y, w in ((a, b, c), (b, c, a), (c, a, b)):
            hit = None
            if x in where and int(rings[where[x][0]][0][where[x][2]]) == y:
                hit = (where[x], False)  # the edge x -> y runs along the ring
            elif y in where and int(rings[where[y][0]][0][where[y][2]]) == x:
                hit = (where[y], True)  # the edge x -> y runs against it
            if hit is not None:
                (r, p, q), back = hit
                ids = rings[r][0]
                path = ids[(p + np.arange((q - p) % len(ids) + 1)) % len(ids)]
                if back:
                    out += [(int(path[t + 1]), int(path[t]), w) for t in range(len(path) - 1)]
                else:
                    out += [(int(path[t]), int(path[t + 1]), w) for t in range(len(path) - 1)]
                break
        else:
            out.append((a, b, c))
    return np.array(out, dtype=np.int64).reshape(-1, 3)


class _Mesher:
    def __init__(self, triangulation: str, band_guard=None, size: int = 1024):
        self.triangulation = triangulation
        self.band_guard = band_guard  # band_guard(lo_xyz, hi_xyz, faces) -> faces (the contours route's)
        self._V = np.empty((size, 3))  # vertex buffer (rows [0, n)), grown by doubling
        self.F: list[np.ndarray] = []
        self.S: list[np.ndarray] = []  # side label per face (0, or 1/2 for the two slices of an exact join)
        self.n = 0
        self.side = 0
        self.necks: list[np.ndarray] = []  # vertices where the background passes through a point
        self.band_fallbacks = 0
        self.pixel_caps = 0  # ends closed by their pixels (see _pixel_cap)
        self.least_area = 0  # bands of dissimilar rings joined by the least-area rule (_dissimilar_rule)

    def _add(self, f):
        f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
        self.F.append(f)
        self.S.append(np.full(len(f), self.side, dtype=np.int8))

    def ring(self, xy: np.ndarray, z: float) -> np.ndarray:
        """A polygon's vertices at height z, one vertex per point (a contour that touches itself
        keeps two vertices at the touching point)."""
        xy = np.asarray(xy, dtype=np.float64)
        return self.points(_with_z(xy, z))

    def points(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
        need = self.n + len(v)
        if need > len(self._V):
            grown = np.empty((max(need, 2 * len(self._V)), 3))
            grown[: self.n] = self._V[: self.n]
            self._V = grown
        self._V[self.n: need] = v
        ids = self.n + np.arange(len(v))
        self.n = need
        return ids

    def coords(self, ids):
        return self._V[: self.n][ids]

    def band(self, lo_ids, hi_ids, mixed=False, lo_added=None, hi_added=None):
        """The selected band triangulation, with a guard against twisted bands (``mixed``: see
        :func:`_band_faces`).

        ``lo_added``, ``hi_added``: which points of a densified ring were added on its polygon's
        edges (:func:`_densify_branching`).  The band is made between the polygons' own points,
        and each face on a densified edge becomes a fan over its added points: the same faces
        and area as without them, and the ring's edges shared with its branching join.

        The paper's rule and the shortest-diagonal rule assume similar contours.  Real slices
        can differ a lot (and a contour next to an exact join keeps its crack contour while its
        partner has an MLP): a band of the local rules whose area exceeds ``1.25`` times that of
        the arc-length band for the same pair is twisted, and is replaced by the optimal
        (least-area) band, or by the arc-length band where the optimal one would be too slow.
        """

        if lo_added is not None or hi_added is not None:
            keep = [np.ones(len(ids), dtype=bool) if a is None else ~a for ids, a in
                    ((lo_ids, lo_added), (hi_ids, hi_added))]
            n0 = len(self.F)
            self.band(lo_ids[keep[0]], hi_ids[keep[1]], mixed)
            f = np.concatenate(self.F[n0:])
            del self.F[n0:], self.S[n0:]
            self._add(_fan_added(f, [(lo_ids, keep[0]), (hi_ids, keep[1])]))
            return
        lo, hi = self.coords(lo_ids), self.coords(hi_ids)
        f, replaced = _band_faces(lo, hi, self.triangulation, mixed=mixed)
        if mixed and _dissimilar_rule(len(lo), len(hi), self.triangulation, _MIXED_OPTIMAL_BUDGET) != self.triangulation:
            self.least_area += 1
        if self.band_guard is not None:
            f = self.band_guard(lo, hi, f)
        self.band_fallbacks += replaced
        self._add(np.concatenate([lo_ids, hi_ids])[f])

    def quads(self, lo_ids, hi_ids):
        """Band between two rings with the same points (a prism wall): two triangles per edge."""
        a, b = lo_ids, hi_ids
        a1, b1 = _next(a), _next(b)
        self._add(np.concatenate([np.stack([a, a1, b1], axis=1), np.stack([a, b1, b], axis=1)]))

    def cap(self, rings, upward):

        xy = [self.coords(r)[:, :2] for r in rings]
        f = cap_faces(xy[0], xy[1:], upward=upward)
        self._add(np.concatenate(rings)[f])

    def faces(self, f):
        self._add(f)

    def result(self):
        V = self._V[: self.n].copy()
        F = np.concatenate(self.F) if self.F else np.zeros((0, 3), dtype=np.int64)
        S = np.concatenate(self.S) if self.S else np.zeros(0, dtype=np.int8)
        N = np.concatenate(self.necks) if self.necks else np.zeros(0, dtype=np.int64)
        return V, F, S, N


@collector_paused()
def volume_to_mesh(volume, *, spacing=(1.0, 1.0, 1.0), z=None, axis: int = 0, label=None, threshold=None,
                   origin=(0.0, 0.0, 0.0), polygon: str = "mlp", triangulation: str = "wiederhold",
                   caps: str = "flat", refine: str | None = None, progress: bool = False,
                   polygons=None, general=None, slab=None) -> Mesh:
    """Mesh a binary (or labelled) volume: the mesh source for volumes (see the module docstring).

    ``refine="band"`` replaces every polygon of a component that is not crack-only (its rings
    take part in band joins and caps, not in exact joins) by its band-refined polygon
    (:func:`contourmesh.refine.refine_volume_rings`: any pixel size, slices at any heights);
    ``refine="band2"`` with twice the ring vertices.  With the refinement, ``caps="smooth"`` closes
    the ends of the refined components that continue a band join by shrunk copies on the last
    sections' area profile (:class:`contourmesh.bands.ends._SmoothEnds`); other ends are flat.

    ``polygons`` (internal): a callable ``polygons(slices, zs, crack_only, joins) -> dict`` run once the
    joins are decided and before the bridged joins are built; it may replace the polygons of any
    component (``slices[k].outer[c]``, ``slices[k].holes[c][h]``, outer rings counter-clockwise and
    holes clockwise) and returns entries for ``meta``.  Components it lists in ``slices[k].own`` (a
    set) keep its polygons in exact joins too: their collars are bands up to the crack contours.  A
    ``band_guard`` attribute of it, when set, is called on every band as ``band_guard(lo, hi, faces)``
    (ring coordinates, the band's faces) and returns the faces to use; an ``end_cap`` attribute is
    called on every end of a component that is not crack-only as ``end_cap(mesher, k, c, ring_ids,
    upward)`` and returns True where it closed that end itself.  The compiled fast path is not used with it
    (the contours route, :mod:`contourmesh.drawn`, puts the drawn rings in this way).

    ``general`` (internal): a callable ``general(mask, zs, (dy, dx), (ox, oy), polygon=, triangulation=,
    caps=)`` asked for the mesh where the general mesher would make it (paper mode only: no
    ``polygons``, no refinement); it returns a Mesh, or None to let this call mesh the volume
    itself (:mod:`contourmesh.parallel`: slabs of slices on worker processes).  ``slab``
    (internal): this volume is one slab of a larger one (:class:`SlabPart`); the fast path is not
    tried, the slab is built once, and the returned Mesh is empty: ``meta["slab"]`` holds the slab's
    joins and caps for the driver, and its counts are those of its own gaps and slices.

    Returns a closed, outward-oriented, manifold Mesh whose genus equals that of the 6-connected
    voxel object; ``meta`` records the method, the number of exact (voxel-like) joins and of
    polygon fallbacks.
    """
    if polygon not in POLYGONIZERS:
        raise ValueError(f"unknown polygon method {polygon!r}; expected one of {sorted(POLYGONIZERS)}")
    if triangulation not in TRIANGULATORS:
        raise ValueError(f"unknown band triangulation method {triangulation!r}; expected one of {sorted(TRIANGULATORS)}")
    if refine is not None and refine not in REFINERS:
        raise ValueError(f"unknown refine method {refine!r}; expected 'band', 'band2' or 'none'")
    refine = None if refine == "none" else refine
    if caps not in ("flat", "half") and not (caps == "smooth" and refine is not None):
        raise ValueError(f"caps must be 'flat' or 'half' (or 'smooth' with the band refinement); got {caps!r}")
    smooth_ends, caps_given = None, caps
    if caps == "smooth":  # the refined components' ends follow their last sections' area profile
        smooth_ends, caps = _SmoothEnds(branch_domes=False), "flat"
    if polygons is not None and refine is not None:
        raise ValueError("polygons= and refine='band' both replace the polygons; give one of them")
    if (label is None and threshold is None and isinstance(volume, np.ndarray) and volume.ndim == 3
            and volume.size and volume.dtype.kind in "iuf"):
        label = binary_label(volume)  # a two-valued volume (0/255) is binary: its non-zero value
    # the common case (no holes, every slice pair a simple band join) in compiled code, the same mesh
    bands = []
    if slab is not None and (polygons is not None or refine is not None or smooth_ends is not None
                             or not slab_supported()):
        raise ValueError("slab= meshes a slab in paper mode only (no polygons= hook, no refinement)")
    fast = None if polygons is not None or smooth_ends is not None or slab is not None else \
        _fast_volume_to_mesh(volume, spacing=spacing, z=z, axis=axis, label=label, threshold=threshold,
                             origin=origin, polygon=polygon, triangulation=triangulation, caps=caps, refine=refine,
                             bands_out=bands)
    if fast is not None:
        log.debug("volume mesher: the compiled fast path took the volume")
        sp = [float(s) for i, s in enumerate(np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,))) if i != axis]
        def planes():  # the section heights, needed only where faces cross
            return prepare_volume(volume, spacing=spacing, z=z, axis=axis, label=label, threshold=threshold,
                                  origin=origin, contiguous=False)[1]

        V, F = fast.vertices, fast.faces
        pairs = intersecting_pairs(V, F)
        # the general mesher tests every kept band for faces crossing each other; the fast path
        # tests those with a face in a crossing pair (the others cannot cross themselves)
        redone = redo_self_crossing_bands(V, F, bands[0], pairs) if len(pairs) else None
        if redone is not None:
            F2, fired = redone
            pairs = crossing_pairs_after_change(V, F, pairs, V, F2)
            fast = Mesh(V, F2, P=fast.P, meta=dict(fast.meta, band_fallbacks=fast.meta["band_fallbacks"] + fired))
        nudge = 1e-3 * min(sp)
        fast = _checked(fast, nudge, planes, warn=False,
                        resolved=resolve_crossings(fast.vertices, fast.faces, nudge, planes=planes, pairs=pairs))
        if not fast.meta["self_intersections"]:
            return fast
        # the compiled bands are not checked one by one: the general mesher's are (twisted bands)
        log.debug("volume mesher: the fast path's mesh has crossing faces; general mesher")
    else:
        log.debug("volume mesher: the fast path declined (holes, branching or options); general mesher")
    # the mask as given where it is boolean (a view): the slices are read one at a time and each made
    # C-ordered where labelled (slice_labels); a C-ordered copy of a Fortran-ordered volume (as read
    # from many files) was a second volume held to the end, 49 of the 132 MiB the liver took
    mask, zs, (dy, dx), (ox, oy) = prepare_volume(volume, spacing=spacing, z=z, axis=axis, label=label,
                                                  threshold=threshold, origin=origin, contiguous=False)
    if general is not None and polygons is None and refine is None and smooth_ends is None and slab_supported():
        got = general(_c_order(mask), zs, (dy, dx), (ox, oy), polygon=polygon, triangulation=triangulation,
                      caps=caps)
        if got is not None:
            return got
    from tqdm.auto import tqdm

    nz = mask.shape[0]
    px = min(dx, dy)

    to_xy_center, to_xy_corner = grid_to_xy(ox, oy, dx, dy)

    # pass 1: contours and polygons of every slice, made as pass 2 reaches the slice; only the
    # label images of the last few slices used are kept (_RecentLabels)
    slices = [None] * nz
    planes = _Planes(mask)  # (the slices C-ordered, a block at a time where the volume is not; the runs
    # of a Fortran-ordered one from one pass over it, :meth:`_Planes.runs`)
    # (in one pass over the volume: in another layout a slice at a time costs a cache line per voxel)
    occupied = np.flatnonzero(mask.any(axis=(1, 2))).tolist()
    recent = _RecentLabels()
    bar = tqdm(total=len(occupied), desc="slices", disable=not progress, leave=False)

    def load(k):
        if slices[k] is None and k in occupied_set:
            got = planes.runs(k)  # (a Fortran-ordered volume: the slice's runs, the slice not read)
            m2 = planes.reading(k) if got is None else mask[k]
            slices[k] = _Slice(m2, polygon, to_xy_corner, to_xy_center, recent, scanned=got)
            bar.update()

    occupied_set = set(occupied)

    # pass 2: which components join, and how
    has_above, has_below = set(), set()
    crack_only = set()  # components whose rings are their crack contours (they take part in exact joins)
    joins = []  # (k, kind, data)
    for k in range(nz - 1):
        load(k), load(k + 1)
        A, B = slices[k], slices[k + 1]
        if A is None or B is None:
            continue
        # (from the slices' runs where both keep them: the same pairs, their label images not read)
        ra, rb = A.kept_runs(), B.kept_runs()
        found = None if ra is None or rb is None else overlap_groups_runs(ra, rb, A.n, B.n)
        if found is None:
            both = (A.labels > 0) & (B.labels > 0)
            if not both.any():
                continue
            found = overlap_groups(A.labels, B.labels, A.n, B.n)
        elif not len(found[0]):  # (no overlap)
            continue
        _, groups = found
        for ga, gb in groups:
            has_above.update((k, a) for a in ga)
            has_below.update((k + 1, b) for b in gb)
            matched = None
            if len(ga) == 1 and len(gb) == 1:
                matched = _simple_join(A, B, next(iter(ga)), next(iter(gb)))
            plan = None if matched is not None else _bridge_plan(A, B, ga, gb)
            if matched is not None:
                joins.append((k, "band", (next(iter(ga)), next(iter(gb)), matched)))
            elif plan is not None:
                joins.append((k, "bridge", (sorted(ga), sorted(gb), plan)))
            elif polygons is None:
                # neither a band nor a bridged join (a loop of overlaps: a handle forms in the gap):
                # intermediate sections are tried before the exact join (plan None: sections only)
                joins.append((k, "bridge", (sorted(ga), sorted(gb), None)))
            else:
                joins.append((k, "exact", (sorted(ga), sorted(gb))))
                crack_only.update((k, a) for a in ga)
                crack_only.update((k + 1, b) for b in gb)
    for k in occupied:  # (a single slice)
        load(k)
    bar.close()
    planes.release()  # (every slice is read: the last block goes; 3.9 MiB on the liver)

    refine_info = {}
    if refine is not None:  # the polygons of band joins and caps become their refined polygons
        refine_info = _refine_polygons(_c_order(mask), zs, slices, occupied, crack_only, joins, (dx, dy),
                                       (ox, oy), refine)
    hook_info = polygons(slices, zs, crack_only, joins) if polygons is not None else {}
    # with _DENSE_STEP set, the rings of branching joins get a vertex at least every pixel (see _densify_branching)
    # (band2: a vertex every half pixel, as its refined polygons have twice the vertices)
    dense_step = px / (2.0 if refine == "band2" else 1.0)
    dense_rings = 0 if polygons is not None or _DENSE_STEP is None else \
        _densify_branching(planes, slices, joins, crack_only, (ox, oy, dx, dy), _DENSE_STEP * dense_step)
    # without it, the components of the branching joins that fail (would become exact) are densified
    # and the bridged joins built again (see _retry_dense); not on the contours route
    retry_dense = polygons is None and _DENSE_STEP is None and _DENSE_RETRY_STEP is not None and \
        (refine is None or _DENSE_RETRY_REFINED)
    end_cap = getattr(polygons, "end_cap", None)
    if smooth_ends is not None:
        smooth_ends.attach(slices, zs, joins)
        end_cap = smooth_ends

    # pass 2b: branching joins between the polygons themselves (bridges), where they keep clear of
    # everything else in their planes; the others become exact joins (their contours then keep
    # crack rings, which can change other joins' rings: repeat until nothing changes)
    # pass 3: vertices and faces.  Every face is tagged with what made it (a join or a cap); where
    # faces still cross after the repair, the band and bridged joins and the caps involved fall back
    # to the exact join (their components to crack rings) and the mesh is built again.
    fallback_joins = fallback_caps = 0
    bridge_cache: dict = {}  # bridged joins built so far, kept across rebuilds (see _build_bridges)
    # the joins and caps made so far, kept across rebuilds (see _assemble); not with the hooks of
    # the contours route, which count what they do on every build
    unit_cache = {} if polygons is None and end_cap is None else None
    tube_cache: dict = {}  # the necks' tube tests, kept across rebuilds (see repair._tube_crosses)
    previous = None  # the last build's vertices, faces and crossing pairs (before any repair)
    densified = [0]  # rings densified by the bridged joins' retry (see _build_bridges' densify)
    touched = set()  # the components densified since the last build (their units are made again)

    def densify(comps, trial=False):
        """The components' densified rings (``trial``: ``{(k, c): rings}``, nothing changed), or
        densify them (the number of rings changed)."""
        step = _DENSE_FAILED_STEP * dense_step
        if trial:
            return {(k, c): [d for d, _a in _dense_rings(planes, slices, k, c, (ox, oy, dx, dy), step, True)]
                    for k, c in comps}
        got = _densify_components(planes, slices, set(comps), (ox, oy, dx, dy), step, total=True, tally=dense_tally)
        densified[0] += got
        touched.update(comps)
        return got

    kept_units = {"units_only": True} if slab is not None else None  # (a slab's units, for the driver)
    dense_tally: dict = {}  # rings densified per slice (a slab's meta counts those of its own slices)
    own_gap = slab.gap if slab is not None else None
    own_slice = slab.slice if slab is not None else None
    dense_failed = densify if (polygons is None and _DENSE_FAILED_STEP is not None and not retry_dense
                               and (refine is None or _DENSE_FAILED_REFINED)) else None
    for attempt in range(_MAX_REBUILDS + 1):
        joins0, crack0 = list(joins), set(crack_only)  # before this build's bridged joins
        n_before = densified[0]
        built = _build_bridges(joins, slices, zs, crack_only, triangulation, caps, (ox, oy, dx, dy),
                               has_above, has_below, bridge_cache, band_guard=getattr(polygons, "band_guard", None),
                               polygon=polygon, densify=dense_failed)
        if retry_dense:  # (also after a crossing fallback: its crack rings can make neighbours fail)
            built, bridge_cache, n_dense = _retry_dense(
                built, bridge_cache, joins, joins0, crack_only, crack0, planes, slices,
                (ox, oy, dx, dy), _DENSE_RETRY_STEP * dense_step,
                lambda cache, sections: _build_bridges(joins, slices, zs, crack_only, triangulation, caps,
                                                       (ox, oy, dx, dy), has_above, has_below, cache,
                                                       polygon=polygon, sections=sections))
            if n_dense and unit_cache:
                unit_cache.clear()  # (a unit's key does not hold its rings' points)
            dense_rings += n_dense
        if _DENSE_MIXED_STEP is not None and polygons is None:
            # the polygons banded to crack rings (next to exact joins) get a vertex every pixel
            dense_rings += _densify_mixed(planes, slices, joins, crack_only, (ox, oy, dx, dy),
                                          _DENSE_MIXED_STEP * dense_step, touched, tally=dense_tally)
        dense_rings += densified[0] - n_before
        if touched and unit_cache:  # (a unit's key does not hold its rings' points)
            _forget_units(unit_cache, joins, touched)
        touched.clear()
        V, F, tags, counts = _assemble(slices, occupied, joins, built, crack_only, has_above, has_below, zs,
                                       triangulation, caps, (ox, oy, dx, dy), to_xy_corner,
                                       getattr(polygons, "band_guard", None), end_cap, unit_cache, tube_cache,
                                       **({} if slab is None else dict(owned=(own_gap, own_slice), keep=kept_units)))
        if V is None:  # a slab's units alone (SlabPart): the driver repairs and tests the whole
            break
        # the first build is checked whole; a rebuild differs from it only around the joins and caps
        # that fell back, and only pairs with a changed face are tested again (the same pairs)
        release_free_heap(len(F))
        pairs = _crossing_pairs(V, F, previous, tags)
        previous = (V, F, pairs)
        V2, info = resolve_crossings(V, F, 1e-3 * px, planes=zs, pairs=pairs)
        left = info.pop("pairs")
        if not len(left) or attempt == _MAX_REBUILDS:
            break
        n_j, n_c = _fall_back(np.unique(tags[np.unique(left)]), joins, crack_only, slices, has_above, has_below)
        if n_j + n_c == 0:  # only exact joins involved: nothing left to fall back to
            break
        fallback_joins += n_j
        fallback_caps += n_c
        log.debug("volume mesher: %d crossing pairs left; %d joins and %d caps fall back to crack rings",
                  len(left), n_j, n_c)
        # (this build's repaired vertices and face tags are not the next build's: not held through it)
        V2 = info = tags = None
    exact_joins, band_joins, bridged_joins, n_bridges, band_fallbacks, pixel_caps, n_sections, least_area = counts
    fallbacks = sum(s.fallbacks for s in slices if s is not None)
    # (the slices held there hold it back: a reference cycle, which would leave the slices to the
    # cyclic garbage collector; emptied, they go when this call returns)
    recent.held.clear()
    meta = volume_meta(polygon, triangulation, caps_given, {
        "band_joins": band_joins, "bridged_joins": bridged_joins, "bridges": n_bridges,
        "intermediate_sections": n_sections, "exact_joins": exact_joins, "polygon_fallbacks": fallbacks,
        "crack_rings": len(crack_only), "band_fallbacks": band_fallbacks, "pixel_caps": pixel_caps,
        "least_area_bands": least_area, "dense_rings": dense_rings,
        "crossing_fallbacks": fallback_joins + fallback_caps})
    if refine is not None:
        meta.update(refine_info, refine=refine)
    if smooth_ends is not None:
        meta.update(smooth_domes=smooth_ends.count("dome"), smooth_tapers=smooth_ends.count("taper"),
                    smooth_cut_ends=smooth_ends.count("cut"))
    meta.update(hook_info or {})
    if slab is not None:
        # the counts of the joins and caps this slab owns (see SlabPart), and what the driver needs
        # for the crossing counts of the faces it keeps
        meta.update(polygon_fallbacks=sum(s.fallbacks for k, s in enumerate(slices) if s is not None and own_slice(k)),
                    crack_rings=sum(1 for k, _c in crack_only if own_slice(k)),
                    dense_rings=sum(n for k, n in dense_tally.items() if own_slice(k)))
        meta["slab"] = _slab_units(kept_units, joins, slices, slab)
        # (the mesh itself is not used: the driver numbers, repairs and tests the slabs' units together)
        return Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), P=0, meta=meta)
    if exact_joins or fallbacks or band_fallbacks:
        log.debug("volume mesher: %d exact (voxel-like) joins, %d polygon fallbacks to crack contours, "
                  "%d twisted bands replaced", exact_joins, fallbacks, band_fallbacks)
    return _checked(Mesh(V, F, P=len(V), meta=meta), 1e-3 * px, zs, resolved=(V2, info))


#: The general mesher's counts in ``meta``, in order (a slab counts those of its own gaps and slices,
#: and :mod:`contourmesh.parallel` adds the slabs' up).
VOLUME_COUNTS = ("band_joins", "bridged_joins", "bridges", "intermediate_sections", "exact_joins",
                 "polygon_fallbacks", "crack_rings", "band_fallbacks", "pixel_caps", "least_area_bands",
                 "dense_rings", "crossing_fallbacks")


def volume_meta(polygon, triangulation, caps, counts: dict) -> dict:
    """The general mesher's ``meta``: the method, the options and the :data:`VOLUME_COUNTS` from
    ``counts``, in one order for the one-process mesher and the slab driver."""
    meta = {"method": "contourmesh", "source": "volume", "polygon": polygon, "triangulation": triangulation,
            "caps": caps}
    meta.update((k, counts[k]) for k in VOLUME_COUNTS)
    meta["connectivity"] = CONNECTIVITY
    return meta


def _slab_units(kept, joins, slices, slab) -> dict:
    """What a slab's build hands to the driver (:mod:`contourmesh.parallel`), in the whole
    volume's slice numbers: ``units``, its own joins' and caps' units in order, each as
    ``(ident, unit)`` with ``ident`` ``("join", k, ga, gb, kind)`` or ``("cap", k, c, crack)``
    (kind and crack: whether a crossing would make it fall back); ``rings``, the points of every
    ring they use; ``n_comp``, the component count of each of its own slices; and ``hashes``, a
    digest of every unit (its own or not) within one gap of its seams, keyed by ident."""
    import hashlib

    o = slab.offset
    units, tags, counted, ring_points, is_crack = (kept[k] for k in ("units", "tags", "counted", "ring_points",
                                                                    "is_crack"))
    first = np.cumsum([len(joins)] + [0 if s is None else s.n for s in slices])
    seams = ([slab.lo] if slab.open_below or slab.lo > 0 else []) + ([slab.hi] if not slab.last else [])
    out, rings, hashes = [], {}, {}
    for u, t, own in zip(units, tags, counted):
        if t < len(joins):
            k, kind, data = joins[t]
            ga, gb = ([data[0]], [data[1]]) if kind == "band" else (list(data[0]), list(data[1]))
            ident = ("join", k + o, tuple(ga), tuple(gb), kind)
            near = any(c - 1 <= k <= c for c in seams)
        else:
            k = int(np.searchsorted(first, t, side="right")) - 1
            c = int(t - first[k])
            ident = ("cap", k + o, c, bool(is_crack(k, c)))
            near = any(c_ - 1 <= k <= c_ + 1 for c_ in seams)
        rks = [rk for rk, _a, _b in u.rings]
        pts = {rk: ring_points(rk) for rk in rks}
        if near:
            h = hashlib.blake2b(digest_size=16)
            h.update(repr((ident, u.nv, [(rk[0] + o,) + tuple(rk[1:]) for rk in rks], [(a, b) for _r, a, b in u.rings],
                           u.replaced, u.pixel_caps, u.least_area)).encode())
            for arr in [u.V, u.F, u.S, u.N] + [pts[rk] for rk in rks]:
                h.update(np.ascontiguousarray(arr).tobytes())
            hashes[ident] = h.hexdigest()
        if own:
            c_u = _Unit()
            c_u.key, c_u.V, c_u.nv, c_u.F, c_u.S, c_u.N = None, u.V, u.nv, u.F, u.S, u.N
            c_u.rings = [((rk[0] + o,) + tuple(rk[1:]), a, b) for rk, a, b in u.rings]
            c_u.replaced, c_u.pixel_caps, c_u.least_area = u.replaced, u.pixel_caps, u.least_area
            out.append((ident, c_u))
            for rk in rks:
                rings[(rk[0] + o,) + tuple(rk[1:])] = pts[rk]
    n_comp = {k + o: (0 if s is None else s.n) for k, s in enumerate(slices) if slab.slice(k)}
    return {"units": out, "rings": rings, "n_comp": n_comp, "hashes": hashes}


def slab_supported() -> bool:
    """Whether the general mesher's settings allow meshing in slabs (:class:`SlabPart`): the
    opt-in densifications (``_DENSE_STEP``, ``_DENSE_RETRY_STEP``) count rings that a slab cannot
    attribute to its own slices."""
    return _DENSE_STEP is None and _DENSE_RETRY_STEP is None


@dataclass(frozen=True)
class SlabPart:
    """A volume given to the general mesher is one slab of a larger volume (:mod:`contourmesh.parallel`).

    In the slab's own slice numbers it *owns* the gaps ``lo <= k < hi`` and the slices ``lo <= k <
    hi`` (and ``hi`` too when it is the ``last`` slab): its meta counts only the joins of those
    gaps and the caps, rings and polygon fallbacks of those slices, so that the slabs' counts add
    up to the whole volume's.  ``open_below`` / ``open_above``: its first / last slice is a cut
    inside the whole volume (the end of a halo).  A slab is built once: its joins and caps (the
    units of :func:`_assemble`) are kept and handed to the driver, which numbers the units of all
    slabs into one mesh, makes it a manifold and tests it for crossing faces as the one-process
    mesher does its first build (:mod:`contourmesh.parallel`); the slab itself is neither made a
    manifold nor tested, so its cut ends cost no more than its other slices."""

    lo: int
    hi: int
    last: bool
    open_below: bool
    open_above: bool
    offset: int = 0  # the whole volume's number of the slab's first slice

    def gap(self, k: int) -> bool:
        return self.lo <= k < self.hi

    def slice(self, k: int) -> bool:
        return self.lo <= k < self.hi or (self.last and k == self.hi)


def _crossing_pairs(V, F, previous, tags=None):
    """The crossing face pairs of a built mesh: checked whole, or from the ``previous`` build's
    ``(V, F, pairs)`` where there is one (:func:`contourmesh.repair.crossing_pairs_after_change`).
    ``tags`` (:func:`_assemble`'s, a join or cap per face) group the faces for the whole test: the
    voxel-exact faces of one join or cap need not be tested against each other (the same pairs);
    on a rebuild, those of the changed faces' test."""
    if previous is None:
        return intersecting_pairs(V, F, groups=tags)
    return crossing_pairs_after_change(*previous, V, F, groups=tags)


#: How many times the general mesher rebuilds a mesh whose faces cross after the repair, with the
#: joins and caps involved falling back to crack rings and exact joins.  Every rebuild changes at
#: least one join or cap (else the loop stops), so the loop ends anyway; the bound caps its time.
_MAX_REBUILDS = 16


def _fall_back(tags, joins, crack_only, slices, has_above, has_below):
    """Joins and caps whose faces cross (``tags`` from :func:`_assemble`) fall back: a band or
    bridged join becomes exact (its components keep crack rings), a capped component keeps its
    crack rings.  Returns how many joins and how many caps changed."""
    n_j = n_c = 0
    ncaps = sum(s.n for s in slices if s is not None)
    for t in tags.tolist():
        if t < 0:
            continue
        if t < len(joins):
            k, kind, data = joins[t]
            if kind == "exact":
                continue
            ga, gb = ([data[0]], [data[1]]) if kind == "band" else (list(data[0]), list(data[1]))
            joins[t] = (k, "exact", (sorted(ga), sorted(gb)))
            crack_only.update((k, a) for a in ga)
            crack_only.update((k + 1, b) for b in gb)
            n_j += 1
        elif t - len(joins) < ncaps:
            key = _cap_key(slices, t - len(joins))
            if key not in crack_only:
                crack_only.add(key)
                n_c += 1
    return n_j, n_c


def _cap_key(slices, i):
    """The ``(k, c)`` of the ``i``-th component over all slices (caps are tagged this way)."""
    for k, s in enumerate(slices):
        if s is None:
            continue
        if i < s.n:
            return (k, i)
        i -= s.n
    raise IndexError(i)  # pragma: no cover


#: The ring pairs of a band join without holes (:func:`_assemble`): the outer contours alone.
_OUTER_PAIR = ((-1, -1),)


def _assemble(slices, occupied, joins, built, crack_only, has_above, has_below, zs, triangulation, caps, grid,
              to_xy_corner, band_guard=None, end_cap=None, cache=None, tube_cache=None, owned=None, keep=None):
    """Pass 3 of the general mesher: the vertices and faces of every join and cap, made a
    manifold.  Returns ``(V, F, tags, counts)``: ``tags`` per face the index of the join that made
    it, or ``len(joins) + i`` for the caps of the ``i``-th component over all slices, or -1
    (faces the manifold repair made); ``counts = (exact, band, bridged joins, bridges, twisted
    bands replaced, intermediate sections)``.

    Each join and each cap is made on its own, in local vertex numbers (a :class:`_Unit`), and the
    units are then numbered in order (:func:`_number_units`): the same vertices and faces, in the
    same order, as making them one after the other into one mesh.  ``cache`` (a dict kept by the
    caller across rebuilds of one mesh) keeps the units made so far, each with all that it depends
    on (its join or cap, and which of its rings are crack rings): a rebuild after a crossing
    fallback makes again only the joins and caps whose rings or kind changed.  ``tube_cache``
    (a dict kept the same way) holds the answers of the necks' tube tests
    (:func:`contourmesh.repair._open_necks`): a rebuild meets most necks again.

    A slab's (:class:`SlabPart`): ``owned = (gap, slice)`` predicates restrict ``counts`` to the
    joins of its own gaps and the caps of its own slices, and ``keep`` (a dict) receives the units,
    their tags, which are owned, and the ring points."""
    ox, oy, dx, dy = grid
    px = min(dx, dy)
    band_maker = getattr(end_cap, "make_band", None)

    def is_crack(k, c):
        return (k, c) in crack_only and c not in getattr(slices[k], "own", ())

    def polygon_of(k, c, hole):
        s = slices[k]
        if is_crack(k, c):
            return s.crack_outer[c] if hole < 0 else s.crack_holes[c][hole]
        return s.outer[c] if hole < 0 else s.holes[c][hole]

    def gap(k, up):
        return slice_gap(zs, k, up)

    def cap_unit(k, c):
        s = slices[k]
        above, below = (k, c) in has_above, (k, c) in has_below

        def make(M, ring):
            def shifted(rs, zc):
                return [M.ring(M.coords(r)[:, :2], zc) for r in rs]

            def close(rs, up, zc=None):
                """Cap the rings rs facing up or down, in their plane or at zc (after a collar)."""
                xy = [M.coords(r)[:, :2] for r in rs]
                f = None
                if _distinct_rows(np.concatenate(xy)):  # rings that touch go to the pixel cap
                    try:
                        f = cap_faces(xy[0], xy[1:], upward=up)
                    except ValueError:
                        pass
                z_pixels = None
                if f is None:
                    # the polygons cross or touch (thin parts): a hair-thin collar to the pixels, 1 % of
                    # the spacing beyond the rings.  A cap at a mid-plane (zc) keeps its pixels short of
                    # it: that plane is where the joins of the next slab begin (an exact join's walls,
                    # another component's cap from the other side), and pixels beyond it would cross them.
                    step = (1e-2 if up else -1e-2) * gap(k, up)
                    if zc is None:
                        z_pixels = M.coords(rs[0][:1])[0, 2] + step
                    else:
                        zc, z_pixels = zc - step, zc - 0.5 * step
                if zc is not None:
                    sh = shifted(rs, zc)
                    for r, t in zip(rs, sh):
                        M.band(r, t) if up else M.band(t, r)
                    rs = sh
                if f is not None:
                    M.faces(np.concatenate(rs)[f])
                    return
                _pixel_cap(M, s, k, c, rs, z_pixels, up, to_xy_corner)

            rs = [ring(k, c, -1)] + [ring(k, c, h) for h in range(len(s.holes[c]))]
            if not above and not below:  # a prism one spacing thick
                close(rs, False, zs[k] - gap(k, False) / 2)
                close(rs, True, zs[k] + gap(k, True) / 2)
                return
            up = not above
            if end_cap is not None and (k, c) not in crack_only and end_cap(M, k, c, rs, up):
                return  # the hook closed this end itself
            zc = zs[k] + (gap(k, up) / 2 if up else -gap(k, up) / 2) if caps == "half" else None
            close(rs, up, zc)

        def direct():
            """The unit of a flat end (the usual one) made without a mesher: its rings' points are
            all its vertices, in order, and the earcut faces number them as they are (the mesher
            would give the same numbers, faces and sides).  None where the end is not so made (a
            prism, half a spacing beyond, a hook's, rings that touch or a cap that fails: the pixel
            cap), for ``make`` to do."""
            if above == below or caps == "half" or end_cap is not None:
                return None
            keys = [(k, c, h) for h in range(-1, len(s.holes[c]))]
            xy = [np.asarray(polygon_of(*rk), dtype=np.float64).reshape(-1, 2) for rk in keys]
            allxy = np.concatenate(xy) if len(xy) > 1 else xy[0]
            if not _distinct_rows(allxy):
                return None
            try:
                f = cap_faces(xy[0], xy[1:], upward=not above)
            except ValueError:
                return None
            return _Unit.flat(keys, [len(r) for r in xy], f)

        return ("cap", is_crack(k, c)), make, direct

    def join_unit(idx):
        k, kind, data = joins[idx]
        if kind == "band":
            a, b, matched = data
            crack_a, crack_b = is_crack(k, a), is_crack(k + 1, b)
            mixed = crack_a != crack_b

            def added(kk, c, h):  # a densified polygon's added points (see _densify_branching)
                return None if mixed or is_crack(kk, c) else slices[kk].dense.get((c, h))

            def make(M, ring):
                if band_maker is not None and band_maker(M, k, a, b, matched, ring, mixed):
                    return  # the hook made this band (a plane-cut end's, caps="smooth" on drawn rings)
                for ha, hb in [(-1, -1)] + list(matched):
                    M.band(ring(k, a, ha), ring(k + 1, b, hb), mixed, added(k, a, ha), added(k + 1, b, hb))

            def direct():
                """The band join's unit made without a mesher (its rings in order, each pair's band
                numbering them as they are): what ``make`` records, where no hook, guard or densified
                ring takes part; None otherwise."""
                if band_maker is not None or band_guard is not None:
                    return None
                pairs = [(-1, -1)] + list(matched) if matched else _OUTER_PAIR
                A, B = slices[k], slices[k + 1]
                # (added() and polygon_of() with the two components' kinds found once: the same answers)
                if not mixed and ((not crack_a and A.dense and any(A.dense.get((a, ha)) is not None for ha, _ in pairs))
                                  or (not crack_b and B.dense and
                                      any(B.dense.get((b, hb)) is not None for _, hb in pairs))):
                    return None
                outer_a, holes_a = (A.crack_outer, A.crack_holes) if crack_a else (A.outer, A.holes)
                outer_b, holes_b = (B.crack_outer, B.crack_holes) if crack_b else (B.outer, B.holes)
                za, zb = zs[k], zs[k + 1]
                keys, sizes, faces = [], [], []
                at = replaced = least_area = 0
                for ha, hb in pairs:
                    lo = _with_z(outer_a[a] if ha < 0 else holes_a[a][ha], za)
                    hi = _with_z(outer_b[b] if hb < 0 else holes_b[b][hb], zb)
                    f, r = _band_faces(lo, hi, triangulation, mixed=mixed)
                    if mixed and _dissimilar_rule(len(lo), len(hi), triangulation, _MIXED_OPTIMAL_BUDGET) != triangulation:
                        least_area += 1
                    replaced += r
                    # (f + at: the numbers np.arange(at, at + len(lo) + len(hi))[f] picks)
                    faces.append(f if at == 0 else np.asarray(f, dtype=np.int64) + at)
                    keys += [(k, a, ha), (k + 1, b, hb)]
                    sizes += [len(lo), len(hi)]
                    at += len(lo) + len(hi)
                return _Unit.flat(keys, sizes, np.concatenate(faces) if len(faces) > 1 else faces[0],
                                  replaced, least_area)

            return ("band", crack_a, crack_b), make, direct
        if kind == "bridge":
            b_ = built[k, tuple(data[0]), tuple(data[1])]

            def make(M, ring):
                if band_maker is not None and len(data[0]) == 1 and len(data[1]) == 1 and \
                        band_maker(M, k, data[0][0], data[1][0], None, ring, False):
                    return  # the hook made this join (a bore opening onto a plane-cut end)
                ids = np.empty(len(b_.V), dtype=np.int64)
                for (kk, c, h), off in b_.rings:
                    r = ring(kk, c, h)
                    ids[off: off + len(r)] = r
                if b_.n_ring < len(b_.V):
                    ids[b_.n_ring:] = M.points(b_.V[b_.n_ring:])
                M.faces(ids[b_.F])
                M.band_fallbacks += b_.replaced
                M.least_area += b_.least_area

            return ("bridge", b_, tuple(is_crack(kk, c) for (kk, c, _), _o in b_.rings)), make, None
        ga, gb = data

        def make(M, ring):
            _exact_join(M, slices[k], slices[k + 1], k, ga, gb, zs, ring, dx, dy, ox, oy, to_xy_corner)

        def direct():
            return _exact_unit(slices[k], slices[k + 1], k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, polygon_of)

        return ("exact", tuple(ga), tuple(gb), tuple(is_crack(k, a) for a in ga),
                tuple(is_crack(k + 1, b) for b in gb)), make, direct

    def unit(uid, key, make, direct=None):
        old = None if cache is None else cache.get(uid)
        if old is not None and old.key == key:
            return old
        u = None if direct is None else direct()
        if u is None:
            u = _Unit.record(key, make, polygon_of, zs, triangulation, band_guard)
        u.key = key
        if cache is not None:
            cache[uid] = u
        return u

    units, tags, counted = [], [], []
    exact_joins = band_joins = bridged_joins = n_bridges = n_sections = 0
    for idx, (k, kind, data) in enumerate(joins):
        key, make, direct = join_unit(idx)
        units.append(unit(("join", idx), key, make, direct))
        tags.append(idx)
        counted.append(owned is None or owned[0](k))
        if not counted[-1]:
            continue
        if kind == "band":
            band_joins += 1
        elif kind == "bridge":
            bridged_joins += 1
            n_bridges += key[1].bridges
            n_sections += key[1].sections
        else:
            exact_joins += 1
    first = len(joins)
    for k in range(len(slices)):
        s = slices[k]
        if s is None:
            continue
        for c in range(s.n):
            if (k, c) in has_above and (k, c) in has_below:
                continue
            key, make, direct = cap_unit(k, c)
            units.append(unit(("cap", k, c), key, make, direct))
            tags.append(first + c)
            counted.append(owned is None or owned[1](k))
        first += s.n
    # (the freed heap given back between the large steps: see contourmesh._heap)
    nf = sum(len(u.F) for u in units)
    release_free_heap(nf)

    def ring_points(rk):
        return _with_z(polygon_of(*rk), zs[rk[0]])

    if keep is not None:  # (a slab's: its units, for the driver to number with the other slabs')
        keep.update(units=units, tags=tags, counted=counted, ring_points=ring_points, is_crack=is_crack)
    band_fallbacks = sum(u.replaced for u, o in zip(units, counted) if o)
    pixel_caps = sum(u.pixel_caps for u, o in zip(units, counted) if o)
    least_area = sum(u.least_area for u, o in zip(units, counted) if o)
    counts = (exact_joins, band_joins, bridged_joins, n_bridges, band_fallbacks, pixel_caps, n_sections, least_area)
    if keep is not None and keep.get("units_only"):
        return None, None, None, counts  # (a slab's units alone: see SlabPart)
    V, F, T = _join_units(units, tags, ring_points, px, tube_cache, nf, polygon_of, zs)
    return V, F, T, counts


def _join_units(units, tags, ring_points, px, tube_cache=None, nf=0, polygon_of=None, zs=None):
    """The units numbered into one mesh (:func:`_number_units`) and made a manifold: ``(V, F,
    tags)``, the tag of each face's unit (-1 for faces the repair made).  The general mesher's
    last step of every build, and the slab driver's (:mod:`contourmesh.parallel`) on the units of
    all slabs, so that both make the same mesh in the same order.  ``polygon_of``, ``zs``: the
    rings' polygons and heights that ``ring_points`` makes its points of, where the caller has
    them (the numbering then writes them in place)."""
    V, F, S, N, T = _number_units(units, tags, ring_points, polygon_of, zs)
    # the tag rides along with the side through the manifold repair (a side is 0, 1 or 2; faces
    # the repair adds get side 0 and tag -1)
    # (in int32, as the tags: there are far fewer joins and caps than 2^29)
    S = _tagged_sides(S, T, np.empty(len(S), dtype=np.int32))
    del T
    release_free_heap(nf)
    # (F and S are this function's own, and no view of them is made: each step may resize them
    # into its result)
    V, F, S = _split_four_face_edges(V, F, S, 1e-3 * px, overwrite=True)
    release_free_heap(nf)
    V, F, S = _open_necks(V, F, S, N, 1e-2 * px, tube_seen=tube_cache, overwrite=True)
    V, F = _compact(V, F, overwrite=True)  # (F is this function's own)
    release_free_heap(nf)
    V, F = split_nonmanifold_vertices(V, F, nudge=1e-3 * px, four_face=False, overwrite=True)
    V = _separate_coincident(V, F, 1e-3 * px, overwrite=True)  # (V is this function's own)
    return V, F, S // 4 - 1


class _Unit:
    """The vertices and faces one join or one cap adds to the mesh, in local vertex numbers:
    ``rings`` lists the rings it uses as ``((k, comp, hole), start, stop)`` ranges of its local
    vertices (in the order it first used them); its other vertices are its own, and only those
    are kept (``V``, in local order; ``nv`` counts all): the rings' points are made again from
    their polygons when the units are numbered (each ring is in two units or more, and the same
    polygon makes the same points while the unit's key holds).  ``key`` is all that the unit
    depends on besides the fixed input (see :func:`_assemble`)."""

    __slots__ = ("key", "V", "nv", "F", "S", "N", "rings", "replaced", "pixel_caps", "least_area")

    @classmethod
    def record(cls, key, make, polygon_of, zs, triangulation, band_guard):
        """Run ``make(M, ring)`` on a mesher of its own; ``ring(k, c, hole)`` gives the local
        vertex ids of a ring (made at its first use, from ``polygon_of(k, c, hole)`` at ``zs[k]``)."""
        M = _Mesher(triangulation, band_guard, size=64)
        rings, spans = {}, []

        def ring(k, c, hole):
            rk = (k, c, hole)
            r = rings.get(rk)
            if r is None:
                r = rings[rk] = M.ring(polygon_of(k, c, hole), zs[k])
                if len(r):
                    spans.append((rk, int(r[0]), int(r[0]) + len(r)))
            return r

        make(M, ring)
        u = cls()
        u.key = key
        V, F, u.S, u.N = M.result()
        u.nv = len(V)
        if spans:
            own = np.ones(len(V), dtype=bool)
            for _, a, b in spans:
                own[a:b] = False
            V = V[own]
        u.V = V
        u.F = F.astype(np.int32) if u.nv < 2**31 else F  # (local numbers: kept across rebuilds)
        u.rings = spans
        u.replaced = M.band_fallbacks
        u.pixel_caps = M.pixel_caps
        u.least_area = M.least_area
        return u

    @classmethod
    def flat(cls, keys, sizes, f, replaced=0, least_area=0):
        """The unit of faces ``f`` on the rings ``keys`` (``sizes`` points each) alone, made in
        this order: what :meth:`record` gives for a ``make`` that makes the rings and adds ``f``
        (numbering their concatenation) with nothing else (``replaced``, ``least_area``: the
        bands' counts)."""
        u = cls()
        u.key = None
        spans, at = [], 0
        for rk, n in zip(keys, sizes):
            if n:
                spans.append((rk, at, at + n))
            at += n
        u.nv = at
        u.V = np.zeros((0, 3))
        f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
        u.F = f.astype(np.int32) if at < 2**31 else f
        u.S = np.zeros(len(f), dtype=np.int8)
        u.N = np.zeros(0, dtype=np.int64)
        u.rings = spans
        u.replaced, u.pixel_caps, u.least_area = replaced, 0, least_area
        return u


def _number_units(units, tags, ring_points, polygon_of=None, zs=None):
    """The units' vertices and faces numbered into one mesh, in order: a ring gets its vertices
    where it is first used (``ring_points((k, comp, hole))``: its points, as the unit made them;
    or, given ``polygon_of`` and ``zs``, the points ``polygon_of(k, comp, hole)`` at height
    ``zs[k]``, the same), a unit's own vertices where the unit makes them.  Returns ``(V, F, S,
    N, T)``: vertices, faces, side per face, neck vertices, and per face the tag of its unit
    (int32).

    The loop over the units handles Python integers and collects array pieces alone: each unit's
    local vertices as runs of consecutive mesh numbers (``seg_g``, ``seg_len``: its own vertices'
    runs and its rings', in local order), and the vertices' pieces in mesh order (``pieces``: a
    run of own vertices as its length, a ring's first use as minus its length), with the units'
    own vertices and the rings' points (or their polygons and heights) beside them; the vertices
    are then written in one compiled pass (:func:`_unit_vertices`; a slice assignment per piece
    and a new array per ring, the form before, cost the lobster some 5 ms a build), the units'
    faces concatenated straight into the results, and the faces and necks renumbered in another
    (:func:`_unit_numbering`).  The per-unit form it replaces is kept in
    ``tests/test_number_units.py``."""
    xy_only = polygon_of is not None
    ring_at = {}  # (ring key -> the mesh number of its first point)
    seg_g, seg_len, pieces = [], [], []
    owns, rps, rzs = [], [], []
    fs, ss, face_end, face_base, face_tag = [], [], [], [], []
    ns, neck_end, neck_base = [], [], []
    n = nl_all = nf = nn = 0  # (mesh vertices, local vertices of the units so far, faces, necks)
    for u, t in zip(units, tags):
        nl = u.nv
        pos = 0  # (local vertex)
        for rk, a, b in u.rings:
            if a > pos:
                seg_g.append(n)
                seg_len.append(a - pos)
                pieces.append(a - pos)
                n += a - pos
            r = ring_at.get(rk)
            if r is None:
                r = ring_at[rk] = n
                xyz = polygon_of(*rk) if xy_only else ring_points(rk)
                if len(xyz) != b - a:  # pragma: no cover - the key holds the ring's polygon
                    raise RuntimeError(f"internal error: ring {rk} changed under a kept unit")
                rps.append(xyz)
                if xy_only:
                    rzs.append(zs[rk[0]])
                pieces.append(a - b)
                n += b - a
            seg_g.append(r)
            seg_len.append(b - a)
            pos = b
        if nl > pos:
            seg_g.append(n)
            seg_len.append(nl - pos)
            pieces.append(nl - pos)
            n += nl - pos
        owns.append(u.V)
        if len(u.F):
            fs.append(u.F)
            ss.append(u.S)
            nf += len(u.F)
            face_end.append(nf)
            face_base.append(nl_all)
            face_tag.append(t)
        if len(u.N):
            ns.append(u.N)
            nn += len(u.N)
            neck_end.append(nn)
            neck_base.append(nl_all)
        nl_all += nl
    i64 = functools.partial(np.array, dtype=np.int64)
    V = np.empty((n, 3))
    if n:
        cols = 2 if xy_only else 3
        own = np.concatenate(owns, dtype=np.float64)
        del owns
        rp = _stacked_rows(rps, cols)
        del rps
        if _unit_vertices(V, own, rp, np.array(rzs, dtype=np.float64), i64(pieces)) != n:  # pragma: no cover
            raise RuntimeError(f"internal error: the vertices' pieces do not add up to {n}")
        del own, rp
    F = np.empty((nf, 3), dtype=np.int64)
    S = np.empty(nf, dtype=np.int8)
    if fs:
        np.concatenate(fs, out=F)
        np.concatenate(ss, out=S)
    del fs, ss
    T = np.repeat(np.array(face_tag, dtype=np.int32), np.diff(np.array([0] + face_end, dtype=np.int64)))
    N = np.concatenate(ns).astype(np.int64) if ns else np.zeros(0, dtype=np.int64)
    _unit_numbering(i64(seg_g), i64(seg_len), F, i64(face_end), i64(face_base), N, i64(neck_end), i64(neck_base))
    return V, F, S, N, T


def _stacked_rows(parts, cols) -> np.ndarray:
    """The arrays ``parts`` (each of ``cols`` columns once read as float64 rows, as
    ``np.asarray(x, dtype=np.float64).reshape(-1, cols)``) stacked into one float64 array; in one
    concatenation where they are all such arrays already (the rings' polygons are)."""
    if not parts:
        return np.zeros((0, cols))
    try:
        got = np.concatenate(parts, dtype=np.float64)
        if got.ndim == 2 and got.shape[1] == cols:
            return got
    except ValueError:
        pass
    return np.concatenate([np.asarray(x, dtype=np.float64).reshape(-1, cols) for x in parts])


@njit(cache=True, **KERNEL_OPTIONS)
def _unit_vertices(V, own, rp, rz, pieces):  # pragma: no cover (compiled)
    """:func:`_number_units`' vertices, written into ``V`` in order, piece by piece: a piece
    ``p > 0`` is the next ``p`` rows of ``own`` (the units' own vertices, concatenated), ``p < 0``
    the next ``-p`` rows of ``rp`` (the rings' points, concatenated), with their ring's height
    from ``rz`` where ``rp`` has two columns (x, y); returns the rows written."""
    n = 0
    o = 0
    r = 0
    j = 0
    xy = rp.shape[1] == 2
    for q in range(pieces.shape[0]):
        p = pieces[q]
        if p > 0:
            for i in range(p):
                V[n + i, 0] = own[o + i, 0]
                V[n + i, 1] = own[o + i, 1]
                V[n + i, 2] = own[o + i, 2]
            o += p
            n += p
        else:
            for i in range(-p):
                V[n + i, 0] = rp[r + i, 0]
                V[n + i, 1] = rp[r + i, 1]
                V[n + i, 2] = rz[j] if xy else rp[r + i, 2]
            j += 1
            r -= p
            n -= p
    return n


@njit(cache=True, **KERNEL_OPTIONS)
def _unit_numbering(seg_g, seg_len, F, face_end, face_base, N, neck_end, neck_base):  # pragma: no cover (compiled)
    """:func:`_number_units`' renumbering, in place: the units' local vertices, concatenated in
    unit order, are the runs ``seg_g[s], seg_g[s] + 1, ...`` (``seg_len[s]`` long) in order; the
    faces ``face_end[j - 1] .. face_end[j] - 1`` and the necks ``neck_end[j - 1] ..
    neck_end[j] - 1`` are a unit's whose local vertices begin at ``face_base[j]``
    (``neck_base[j]``) in that concatenation."""
    total = 0
    for s in range(seg_len.shape[0]):
        total += seg_len[s]
    g = np.empty(total, np.int64)
    t = 0
    for s in range(seg_len.shape[0]):
        g0 = seg_g[s]
        for i in range(seg_len[s]):
            g[t] = g0 + i
            t += 1
    a = 0
    for j in range(face_end.shape[0]):
        b0 = face_base[j]
        for i in range(a, face_end[j]):
            for d in range(3):
                F[i, d] = g[b0 + F[i, d]]
        a = face_end[j]
    a = 0
    for j in range(neck_end.shape[0]):
        b0 = neck_base[j]
        for i in range(a, neck_end[j]):
            N[i] = g[b0 + N[i]]
        a = neck_end[j]


def _distinct_rows(xy) -> bool:
    """No two rows of ``xy`` are equal (``len(np.unique(xy, axis=0)) == len(xy)``), in compiled
    code (:func:`_rows_distinct_kernel`): two rows are equal where both coordinates compare equal,
    whatever sorts them; rows with a NaN (which a sort may place anywhere) go to
    :func:`_distinct_rows_numpy`, the form it replaces."""
    if len(xy) < 2:
        return True
    got = _rows_distinct_kernel(np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2))
    return _distinct_rows_numpy(xy) if got < 0 else bool(got)


@njit(cache=True, **KERNEL_OPTIONS)
def _rows_distinct_kernel(p):  # pragma: no cover (compiled)
    """1 where no two rows of ``p`` are equal (:func:`contourmesh.geometry.distinct_rows`' count
    is its length), 0 where two are, -1 where a coordinate is NaN."""
    n = p.shape[0]
    for i in range(n):
        if p[i, 0] != p[i, 0] or p[i, 1] != p[i, 1]:
            return -1
    return 1 if _count_distinct_rows(p) == n else 0


def _distinct_rows_numpy(xy) -> bool:
    """:func:`_distinct_rows` by numpy's lexicographic sort (the tests' reference)."""
    if len(xy) < 2:
        return True
    s = xy[np.lexsort(xy.T[::-1])]
    return not bool((s[1:] == s[:-1]).all(axis=1).any())


def _checked(mesh: Mesh, nudge: float, planes, warn: bool = True, resolved=None) -> Mesh:
    """The mesh with its crossing faces pulled apart where a small move can
    (:func:`contourmesh.repair.resolve_crossings`); ``meta`` records the crossing pairs repaired
    and left, and any left are logged as a warning.  Vertices at the section heights ``planes``
    move within their plane.  ``resolved``: that function's result, where the caller has it."""
    V, info = resolve_crossings(mesh.vertices, mesh.faces, nudge, planes=planes) if resolved is None else resolved


    meta = dict(mesh.meta, self_intersections=info["self_intersections"],
                crossings_repaired=info["crossings_repaired"])
    if info["crossings_repaired"]:
        meta["crossing_repair_max_move"] = info["max_move"]
    if info["self_intersections"] and warn:
        log.warning("volume mesher: %d pairs of faces cross (%d repaired); the mesh is closed but not embedded",
                    info["self_intersections"], info["crossings_repaired"])
        from .errors import SelfIntersectionWarning, warn_external

        warn_external(f"volume mesher: {info['self_intersections']} pairs of faces still cross "
                      f"({info['crossings_repaired']} repaired); the mesh is closed but not embedded "
                      "(meta['self_intersections'])", SelfIntersectionWarning)
    if info["vertices_moved"] == 0:
        return Mesh(mesh.vertices, mesh.faces, P=mesh.P, meta=meta)
    return Mesh(V, mesh.faces, P=mesh.P, meta=meta)


def _refine_polygons(mask, zs, slices, occupied, crack_only, joins, spacing_xy, origin_xy, method="band") -> dict:
    """refine="band": the polygons of every component that is not crack-only become refined polygons,
    each guided by its partner below in a band join; crack rings stay (and bound the others)."""
    seeds, fixed, below, deepest = {}, {}, {}, {}
    to_xy_center, _ = grid_to_xy(*origin_xy, *spacing_xy)
    for k in occupied:
        s = slices[k]
        for c in range(s.n):
            if (k, c) in crack_only:
                fixed.setdefault(k, []).extend([s.crack_outer[c]] + list(s.crack_holes[c]))
                continue
            sl = s.objects[c]
            # the argmax of ndimage.distance_transform_edt of the padded component (compiled)
            j, i = deepest_pixel(s.labels[sl] == c + 1)
            rings = [(-1, s.outer[c])] + list(enumerate(s.holes[c]))
            seeds.update({(k, c, h): (k, p) for h, p in rings})
            deepest.update({(k, c, h): to_xy_center([[sl[1].start + i - 1, sl[0].start + j - 1]])[0] for h, _ in rings})
    for k, kind, data in joins:
        if kind == "band":
            a, b, matched = data
            below.update({(k + 1, b, hb): (k, a, ha) for ha, hb in [(-1, -1)] + list(matched)})
    rings, info = refine_volume_rings(mask, zs, spacing_xy, origin_xy, seeds, below, fixed, deepest, method=method)
    for (k, c, h), p in rings.items():
        if h < 0:
            slices[k].outer[c] = p
        else:
            slices[k].holes[c][h] = p
    return info


#: The longest polygon edge, in pixels, of a component that takes part in a branching join
#: (:func:`_densify_branching`); None (the default) leaves the polygons as they are.  Off by
#: default: on the rotated real meshes it removes the exact-join chains that set the largest
#: errors at 256 voxels across, but the band mode's median error rises at 128 and 256 (the
#: staircases it removes hid the band's own negative error); see the DESIGN note "Densified rings".
_DENSE_STEP = None
#: ... and its most vertices: a longer ring keeps longer edges (the optimal band's work grows as
#: ``n^2 m``; 1024-vertex rings keep it near 1e9).
_DENSE_MAX = 1024


def _densify(ring: np.ndarray, step: float, most: int = _DENSE_MAX, total: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``ring`` with points added on its edges (evenly, the corners kept) so that none is longer
    than ``step``, or than the ring's length over ``most`` where that is longer (``total``: over
    ``most`` less the points it has, so that it ends with about ``most`` points at most); and which
    of its points are added ones."""
    r = np.asarray(ring, dtype=np.float64)
    d = np.roll(r, -1, axis=0) - r
    length = np.hypot(d[:, 0], d[:, 1])
    if total and len(r) >= most - 1:
        return r, np.zeros(len(r), dtype=bool)
    step = max(step, float(length.sum()) / (most - len(r) if total else most))
    k = np.maximum(np.ceil(length / step - 1e-9).astype(np.int64), 1)
    i = np.repeat(np.arange(len(r)), k)
    q = np.arange(len(i)) - np.repeat(np.cumsum(k) - k, k)
    return r[i] + (q / k[i])[:, None] * d[i], q > 0


#: Where the joins are left as they are (``_DENSE_STEP`` None), the components of the branching
#: joins that fail (they would become exact) get a vertex every this many pixels along their
#: polygons' edges and those joins are tried again (:func:`_retry_dense`), then every half of it
#: for the joins that still fail; None (the default): no retry.  A setting, not a default: it
#: takes the paper mode's largest error over the rotated real shapes at 256 from 11.07 % to 5.09 %
#: but the lobster's CPU time up by about 1.3x, and the paper mode's time on the lobster and the
#: liver is held where it is (issue 14); see docs/DESIGN.md, "Densified rings".
_DENSE_RETRY_STEP = None
#: ... also with the band refinement (``refine="band"``, ``"band2"``).  Off: there the staircases
#: it removes hid the refined polygons' negative bias (band mode over the 42 rotated real
#: placements at 128 across: largest |e| 2.98 % -> 3.45 %, armadillo rotated #2; see docs/DESIGN.md).
_DENSE_RETRY_REFINED = False
#: The retry's steps, as fractions of ``_DENSE_RETRY_STEP``: each for the joins the previous left
#: failed.  Only the first tries intermediate sections again (the second, on lobster, cost about
#: 4 CPU-s more for 3 joins).
_DENSE_RETRY_STAGES = (1.0, 0.5)
#: ... also for loops of overlaps (joins without a bridge plan, which only sections can join).
_DENSE_RETRY_LOOPS = True


def _retry_dense(built, cache, joins, joins0, crack_only, crack0, mask, slices, grid, step, build):
    """Where bridged joins failed in a build (``joins`` now has exact joins where ``joins0``, the
    joins before that build, has branching ones), densify the polygons of their components
    (:func:`_densify_components`, every ``step`` times each of ``_DENSE_RETRY_STAGES``) and build
    the bridged joins again from ``joins0`` (``build(cache, sections)``: intermediate sections
    tried in the first stage only).  A stage is kept where it leaves
    fewer exact joins than the one before, and the next stage densifies the components of the
    joins that still fail; a stage that does not help is undone (polygons, joins and crack rings)
    and ends the retry.  Returns ``(built, cache, rings densified)``.

    A join fails mostly where a polygon's long straight edges meet small components (single
    pixels left by noise on a nearly horizontal face): the least-area band fans the edges' ends
    across them and folds, and the exact join that replaces it turns its components into crack
    rings, against which the neighbouring joins fan and fail in turn.  Densifying every
    branching join's polygons removes those chains too, but changes every branching join of
    every mesh (``_DENSE_STEP``); this touches only the failed ones."""
    n = 0
    for i, stage in enumerate(_DENSE_RETRY_STAGES):
        failed = set()
        for (k, kind0, data0), (_, kind, _d) in zip(joins0, joins):
            if kind0 == "bridge" and kind == "exact" and (_DENSE_RETRY_LOOPS or data0[2] is not None):
                failed.update((k, a) for a in data0[0])
                failed.update((k + 1, b) for b in data0[1])
        failed -= crack0
        if not failed:
            break
        exact1 = sum(kind == "exact" for _, kind, _d in joins)
        before = (list(joins), set(crack_only))
        saved = {(k, c): (slices[k].outer[c], list(slices[k].holes[c]),
                          {key: v for key, v in slices[k].dense.items() if key[0] == c},
                          slices[k].dense_gen.get(c)) for k, c in failed}
        # (at most about _DENSE_MAX points per ring over the stages: a band of such a ring against a
        # long crack ring stays within the optimal band's limits)
        got = _densify_components(mask, slices, failed, grid, stage * step, total=True)
        if got == 0:
            break
        joins[:] = joins0
        crack_only.clear()
        crack_only.update(crack0)
        # the joins whose rings and neighbourhood kept their points keep what they built (the
        # densified components near a join are part of its key in the cache)
        built2 = build(cache, i == 0)
        if sum(kind == "exact" for _, kind, _d in joins) < exact1:
            built, n = built2, n + got
            continue
        for (k, c), (outer, holes, dense, gen) in saved.items():  # no better: back to the previous build
            sl = slices[k]
            sl.outer[c], sl.holes[c] = outer, holes
            for key in [key for key in sl.dense if key[0] == c]:
                del sl.dense[key]
            sl.dense.update(dense)
            if gen is None:
                sl.dense_gen.pop(c, None)
            else:
                sl.dense_gen[c] = gen
        joins[:] = before[0]
        crack_only.clear()
        crack_only.update(before[1])
        break
    return built, cache, n


def _densify_branching(mask, slices, joins, crack_only, grid, step) -> int:
    """Every polygon (outer and holes) of a component that takes part in a branching join (a
    ``"bridge"`` join: a fork, a merge, a hole that opens or closes, a loop) gets a vertex at least
    every ``step`` along its edges, where the point lies in its slice's band ``U \\ int(V)`` (as the
    band refinement's vertices do: :func:`contourmesh.refine.in_band`); its corners stay where they
    are, so the polygon is the same curve.  Returns how many rings changed.

    Such a join is one band between two long bridged rings (or sections' bands).  A straight run
    of a polygon has only its two end vertices, and the least-area band fans the run's ends across
    the other ring: around a small component bridged to a large one (noise on a near-horizontal
    face: single pixels above a sloping wall) it makes a double cone, an edge in four faces, and
    the join fails; a fan from a polygon's straight run to a crack ring's staircase (next to the
    exact join that follows) lies almost flat and has several times the area of the surface.  With
    a vertex every pixel the band's rungs stay local.  The component's other joins use the same
    rings (the added vertices lie on its edges)."""
    comps = set()
    for k, kind, data in joins:
        if kind == "bridge":
            comps.update((k, a) for a in data[0])
            comps.update((k + 1, b) for b in data[1])
    return _densify_components(mask, slices, comps - crack_only, grid, step)


#: A fork or merge with a speck whose bridged join fails (it would become exact) is tried once more
#: with a vertex at least every this many pixels on its components' polygons, and keeps them where
#: that builds (see :func:`_build_bridges`'s ``densify``); None: not tried again.  Not with
#: ``_DENSE_RETRY_STEP`` set (that retry densifies every failed join).
_DENSE_FAILED_STEP = 1.0
#: ... also with the band refinement.
_DENSE_FAILED_REFINED = True
#: ... and with intermediate sections on its second try too (off: their cost on the lobster).
_DENSE_FAILED_SECTIONS = False
#: ... only where the group has a component of at most this many pixels (a speck: single pixels
#: that noise leaves on a terrace's edge; a retry of every failed fork or merge cost the liver
#: about 1.6 times the CPU time for one join more).
_DENSE_FAILED_SPECK = 2
#: The polygons of a component whose band join meets a crack ring (a mixed band, next to an exact
#: join) get a vertex at least every this many pixels (:func:`_densify_mixed`); None: left as they are.
_DENSE_MIXED_STEP = 1.0


def _forget_units(cache, joins, comps):
    """Drop from :func:`_assemble`'s unit cache the joins and caps that use a ring of the
    components ``comps`` (``(slice, component)`` pairs, densified since they were made)."""
    for idx, (k, kind, data) in enumerate(joins):
        ga, gb = ([data[0]], [data[1]]) if kind == "band" else (data[0], data[1])
        if any((k, a) in comps for a in ga) or any((k + 1, b) in comps for b in gb):
            cache.pop(("join", idx), None)
    for k, c in comps:
        cache.pop(("cap", k, c), None)


def _densify_mixed(mask, slices, joins, crack_only, grid, step, touched=None, tally=None) -> int:
    """The polygons of every component that a band join pairs with a crack ring (a mixed band: one
    side of the join is next to an exact join) get a vertex at least every ``step`` along their
    edges (:func:`_densify_components`); not those densified before, nor those of components in a
    bridged join (built from the rings as they were: densifying them as well and building their
    bridged joins again changed nothing on fandisk rotated #1 at 256 and cost the lobster time).
    Returns how many rings changed; ``touched`` (a set, where given) gets the components, and
    ``tally`` (a dict, where given) the rings changed per slice.

    A polygon's straight run has only its two end vertices, and the least-area band fans each of
    them over the crack ring's staircase: long thin faces that lie almost flat, several times the
    area of the surface (fandisk rotated #1 at 256: the two mixed bands beside a chain of exact
    joins held +4.7 % of the mesh's area).  With a vertex every pixel the band's rungs stay local.
    The component's other band joins keep their faces (fanned over the added points), its caps
    use the denser ring."""
    in_bridge = set()
    comps = set()
    for k, kind, data in joins:
        if kind == "bridge":
            in_bridge.update((k, a) for a in data[0])
            in_bridge.update((k + 1, b) for b in data[1])
        elif kind == "band":
            a, b = data[0], data[1]
            ca, cb = (k, a) in crack_only, (k + 1, b) in crack_only
            if ca != cb:
                comps.add((k + 1, b) if ca else (k, a))
    comps = {(k, c) for k, c in comps - in_bridge if c not in slices[k].dense_gen}
    if touched is not None:
        touched.update(comps)
    return _densify_components(mask, slices, comps, grid, step, tally=tally) if comps else 0


def _densify_components(mask, slices, comps, grid, step, total=False, tally=None) -> int:
    """The polygons of the components ``comps`` (``(slice, component)`` pairs) with a vertex at
    least every ``step`` where the point lies in the slice's band (see :func:`_densify_branching`;
    ``total``: at most about ``_DENSE_MAX`` points per ring, see :func:`_densify`); returns how
    many rings changed (and adds them per slice to ``tally``, a dict, where given)."""
    n = 0
    for k, c in sorted(comps):
        s = slices[k]
        dense = []
        for h, (d, added) in enumerate(_dense_rings(mask, slices, k, c, grid, step, total)):
            if added is not None:
                n += 1
                if tally is not None:
                    tally[k] = tally.get(k, 0) + 1
                mark = added
                prev = s.dense.get((c, h - 1))
                if prev is not None:  # densified before: its added points stay added ones
                    mark[~mark] = prev
                s.dense[c, h - 1] = mark
            dense.append(d)
        s.outer[c], s.holes[c] = dense[0], dense[1:]
        s.dense_gen[c] = s.dense_gen.get(c, 0) + 1
    return n


def _dense_rings(mask, slices, k, c, grid, step, total=False) -> list:
    """Component ``c`` of slice ``k``'s polygons (outer first, then holes) densified as
    :func:`_densify_components` does, without changing them: ``(ring, added)`` each, ``added``
    marking the added points among its points, or None where the ring is unchanged."""
    from .refine import _off_band

    ox, oy, dx, dy = grid
    s = slices[k]
    out = []
    for r in [s.outer[c]] + list(s.holes[c]):
        d, added = _densify(r, step, total=total)
        if added.any():
            idx = np.c_[(d[added, 0] - ox) / dx, (d[added, 1] - oy) / dy]
            keep = ~added
            # (slice k alone, C-ordered (mask: the volume or its _Planes); the band test reads no other slice)
            keep[added] = ~_off_band(mask[k][None], 0, idx, (1.0, 1.0))
            d, added = d[keep], added[keep]
        out.append((d, added) if len(d) != len(r) else (r, None))
    return out


def _overlap_mask(A: _Slice, B: _Slice, a: int, b: int, y0, y1, x0, x1) -> np.ndarray:
    """The overlap of component a of slice A and b of slice B in the box ``[y0:y1, x0:x1]``."""
    return (A.labels[y0:y1, x0:x1] == a + 1) & (B.labels[y0:y1, x0:x1] == b + 1)


def _overlap_topology_of_mask(o) -> tuple:
    """``(components, holes)`` of a 2D mask: its 4-connected components, and the holes of them
    all (8-connected background components enclosed, ``components - chi``), by the labeller
    (:func:`contourmesh.fastpath.slice_components`; the reference of :func:`_overlap_topology`)."""
    _, _, no, holes_o, _ = slice_components(o)
    return int(no), int(holes_o.sum())


@njit(cache=True, **KERNEL_OPTIONS)
def _overlap_topology(ra, a, rb, b, ylo, yhi):  # pragma: no cover (compiled)
    """``(components, holes)`` of the overlap of component ``a`` of one slice and ``b`` of the next,
    as :func:`_overlap_topology_of_mask` gives them for the overlap's mask, from the slices' runs
    alone (``ra``, ``rb``: :meth:`_Slice.kept_runs`, rows ``[row, first column, end column,
    component]`` in raster order), looking at rows ``ylo <= y < yhi`` (where both components have
    pixels).

    The overlap's runs are the intersections, row by row, of a's runs and b's runs (each
    row's runs are disjoint and in column order, so one merge per row gives them in column
    order); they are the runs the labeller finds in the overlap's mask.  From them the same
    counts: components by union-find over runs of adjacent rows that share a column, and holes
    ``components - chi`` with ``chi = runs - such pairs`` (4-connected foreground, 8-connected
    background), as :func:`contourmesh.fastpath._components` counts them per component."""
    if yhi <= ylo:  # (no row in common: nothing overlaps)
        return np.int64(0), np.int64(0)
    ia0 = np.searchsorted(ra[0], ylo)
    ia1 = np.searchsorted(ra[0], yhi)
    ib0 = np.searchsorted(rb[0], ylo)
    ib1 = np.searchsorted(rb[0], yhi)
    cap = (ia1 - ia0) + (ib1 - ib0)
    oy = np.empty(cap, np.int64)
    ox0 = np.empty(cap, np.int64)
    ox1 = np.empty(cap, np.int64)
    n = 0
    i, j = ia0, ib0
    while i < ia1 and j < ib1:
        if ra[3, i] != a:
            i += 1
            continue
        if rb[3, j] != b:
            j += 1
            continue
        ya, yb = ra[0, i], rb[0, j]
        if ya < yb:
            i += 1
            continue
        if yb < ya:
            j += 1
            continue
        lo = max(ra[1, i], rb[1, j])
        hi = min(ra[2, i], rb[2, j])
        if lo < hi:
            oy[n] = ya
            ox0[n] = lo
            ox1[n] = hi
            n += 1
        if ra[2, i] <= rb[2, j]:
            i += 1
        else:
            j += 1
    if n == 0:
        return np.int64(0), np.int64(0)
    parent = np.empty(n, np.int64)
    for r in range(n):
        parent[r] = r
    comps = n
    pairs = np.int64(0)
    # the runs of one row are p0 <= r < p1, those of the next row (where it is the next) p1 <= r < p2
    p0 = np.int64(0)
    while p0 < n:
        p1 = p0
        while p1 < n and oy[p1] == oy[p0]:
            p1 += 1
        if p1 < n and oy[p1] == oy[p0] + 1:
            p2 = p1
            while p2 < n and oy[p2] == oy[p1]:
                p2 += 1
            u, v = p0, p1
            while u < p1 and v < p2:
                if ox0[u] < ox1[v] and ox0[v] < ox1[u]:
                    pairs += 1
                    # (topology's union-find: its root with path halving; the larger root joins
                    # the smaller, as topology._union links them)
                    ru = _root(parent, u)
                    rv = _root(parent, v)
                    if ru != rv:
                        parent[max(ru, rv)] = min(ru, rv)
                        comps -= 1
                if ox1[u] <= ox1[v]:
                    u += 1
                else:
                    v += 1
        p0 = p1
    return np.int64(comps), np.int64(comps - (n - pairs))


def _simple_join(A: _Slice, B: _Slice, a: int, b: int):
    """Hole pairs ``[(ha, hb), ...]`` if components a (below) and b (above) join as a band, else None.

    The join is a product (a band per contour pair) exactly when the overlap ``O`` is connected
    and every hole of ``O`` holds exactly one hole of ``a`` and one of ``b`` (and every hole of
    ``a`` and ``b`` lies in a hole of ``O``): then the 6-connected voxel object between the two
    slices has the topology of ``a`` times an interval (Mayer-Vietoris).
    """
    sa, sb = A.objects[a], B.objects[b]
    ya, yb = sa[0], sb[0]
    # components of O and its holes, from the two slices' runs where both keep them (compiled: no
    # mask of O is made unless O has holes), else from O's mask (the same two numbers)
    ra, rb = A.kept_runs(), B.kept_runs()
    if ra is not None and rb is not None:
        # (Python ints: the compiled pass takes them as int64, as it took np.int64)
        no, holes = _overlap_topology(ra, int(a), rb, int(b), max(ya.start, yb.start), min(ya.stop, yb.stop))
        o = None
    else:
        o = _overlap_mask(A, B, a, b, min(ya.start, yb.start), max(ya.stop, yb.stop), min(sa[1].start, sb[1].start),
                          max(sa[1].stop, sb[1].stop))
        no, holes = _overlap_topology_of_mask(o)
    if no != 1:
        return None
    ha = A.hole_masks[a][1]
    hb = B.hole_masks[b][1]
    if len(ha) != len(hb) or holes != len(ha):
        return None
    if not ha:
        return []  # no hole anywhere: nothing to pair, and O's background need not be labelled
    y0, y1 = min(ya.start, yb.start), max(ya.stop, yb.stop)
    x0, x1 = min(sa[1].start, sb[1].start), max(sa[1].stop, sb[1].stop)
    if o is None:
        o = _overlap_mask(A, B, a, b, y0, y1, x0, x1)
    # (the padded background of O labelled 8-connected in compiled code, ndimage.label's labels, read
    # at each hole's first pixel of its whole mask, in raster order)
    qy, qx = [], []
    for holes, sl in ((ha, sa), (hb, sb)):
        for i in range(len(holes)):
            hy, hx = holes.first_pixel(i)
            qy.append(hy + sl[0].start - y0 + 1)
            qx.append(hx + sl[1].start - x0 + 1)
    _, labs, nol, _, ext = overlap_hole_labels(o, qy, qx)
    if nol - 1 != len(ha):
        return None
    labs = labs.tolist()
    wa, wb = labs[:len(ha)], labs[len(ha):]
    if ext in wa or ext in wb:
        return None
    if len(set(wa)) != len(wa) or len(set(wb)) != len(wb) or set(wa) != set(wb):
        return None
    pos_b = {lab: j for j, lab in enumerate(wb)}
    return [(i, pos_b[lab]) for i, lab in enumerate(wa)]


class _CornerGrid:
    """Vertices at the pixel corners of a box, at one height, created on demand."""

    def __init__(self, M, x0, y0, hgt, wid, z, to_xy_corner):
        self.M, self.x0, self.y0, self.z, self.to_xy = M, x0, y0, z, to_xy_corner
        self.ids = np.full((hgt + 1, wid + 1), -1, dtype=np.int64)

    def __call__(self, cx, cy):
        lx, ly = np.asarray(cx) - self.x0, np.asarray(cy) - self.y0
        ok = False
        if lx.dtype == np.int64 and ly.dtype == np.int64 and lx.ndim == ly.ndim == 1 and len(lx) == len(ly):
            # the new corners in (x, y) order (compiled: tracing.missing_corners)
            ux, uy, ok = missing_corners(self.ids, np.ascontiguousarray(lx), np.ascontiguousarray(ly))
        if ok:
            if len(ux):
                xy = self.to_xy(np.stack([ux + self.x0, uy + self.y0], axis=1))
                self.ids[uy, ux] = self.M.points(_with_z(xy, self.z))
            return self.ids[ly, lx]
        need = self.ids[ly, lx] < 0
        if need.any():
            # the new corners in (x, y) order, as one integer key each (x major)
            hh = np.int64(self.ids.shape[0])
            key = unique_keys(lx[need].astype(np.int64) * hh + ly[need], self.ids.shape[1] * hh)
            ux, uy = key // hh, key % hh
            xy = self.to_xy(np.stack([ux + self.x0, uy + self.y0], axis=1))
            self.ids[uy, ux] = self.M.points(_with_z(xy, self.z))
        return self.ids[ly, lx]


def _pixel_cap(M, s, k, c, rings, z, up, to_xy_corner):
    """Close a component with its pixels: bands from its rings to its crack contours at height z,
    then two triangles per pixel there (always valid, whatever the polygons do).  Seen from above,
    the collar and the pixels both cover the sliver between a polygon and its contour, so such an
    end counts that sliver's area twice (counted in ``meta["pixel_caps"]``)."""
    M.pixel_caps += 1
    sl = s.objects[c]
    y0, x0 = sl[0].start, sl[1].start
    comp = s.labels[sl] == c + 1
    grid = _CornerGrid(M, x0, y0, comp.shape[0], comp.shape[1], z, to_xy_corner)
    z_mid = 0.5 * (M.coords(rings[0][:1])[0, 2] + z)
    for r, crack in zip(rings, [s.crack_outer_c[c]] + list(s.crack_holes_c[c])):
        # the band goes to the crack contour with one vertex per point (a contour touching itself
        # keeps two), then vertical quads to the shared corner vertices of the pixel faces
        t = M.ring(to_xy_corner(crack), z_mid)
        M.band(r, t) if up else M.band(t, r)
        g = grid(crack[:, 0], crack[:, 1])
        M.quads(t, g) if up else M.quads(g, t)
    _pixel_faces(M, comp, x0, y0, grid, up=up)


#: :func:`_exact_join` reads crack rings' integer corners (not their xy taken back to corners) where
#: ``max(|ox| / dx, |oy| / dy)`` plus the largest pixel coordinate plus one is below this.
_EXACT_TRIP_LIMIT = 2.0 ** 40


def _exact_join(M: _Mesher, A: _Slice, B: _Slice, k, ga, gb, zs, ring, dx, dy, ox, oy, to_xy_corner):
    """The voxel-exact join of a group of components between slices k and k+1.

    Each contour of the group rises as a collar (two triangles per edge) to its crack contour in
    the mid-plane; the lower slice's pixels not covered from above close there facing up, the upper
    slice's facing down, and the corners where the empty voxels of a 2 x 2 x 2 block touch only at
    the corner are necks.  The same vertices and faces, in the same order, as
    :func:`_exact_join_reference` (each collar and pixel pass a call of its own): the corners'
    numbering, the collars and the pixel faces are worked out in one compiled pass
    (:func:`_exact_plan`), and the mesher then receives the points in the order the reference
    makes them (each ring through ``ring``, where the reference first uses it).  Groups with a
    caller's polygons (whose collars are bands) take the reference."""
    n0 = M.n
    plan = _exact_plan(A, B, k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, n0)
    if plan is None:
        return _exact_join_reference(M, A, B, k, ga, gb, zs, ring, dx, dy, ox, oy, to_xy_corner)
    keys, starts, XY, made, F, n_f1, necks = plan
    at = 0  # corners handed to the mesher so far
    for i, key in enumerate(keys):
        if made[i] > at:  # the corners the reference makes before this ring
            M.points(XY[at: made[i]])
            at = int(made[i])
        r = ring(*key)
        if len(r) != starts[i + 1] - starts[i] or (len(r) and r[0] != n0 + at + starts[i]):
            raise RuntimeError(f"internal error: exact join's ring {key} not made where expected")
    if at < len(XY):
        M.points(XY[at:])
    M.side = 1
    M.faces(F[:n_f1])
    M.side = 2
    M.faces(F[n_f1:])
    M.side = 0
    if len(necks):
        M.necks.append(necks)


def _exact_unit(A: _Slice, B: _Slice, k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, polygon_of):
    """The unit of :func:`_exact_join` made without a mesher (what :meth:`_Unit.record` gives for
    it: its rings where it first uses them, its corners its own vertices in the order made), or
    None where the join takes the reference or a ring's polygon is not its crack ring's size."""
    plan = _exact_plan(A, B, k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, 0)
    if plan is None:
        return None
    keys, starts, XY, made, F, n_f1, necks = plan
    spans = []
    for i, key in enumerate(keys):
        n = int(starts[i + 1] - starts[i])
        if len(polygon_of(*key)) != n:  # pragma: no cover - crack rings are their corners' size
            return None
        if n:
            a = int(made[i] + starts[i])
            spans.append((key, a, a + n))
    u = _Unit()
    u.key = None
    u.nv = int(starts[-1]) + len(XY)
    u.V = XY
    u.F = F.astype(np.int32) if u.nv < 2**31 else F
    u.S = np.empty(len(F), dtype=np.int8)
    u.S[:n_f1] = 1
    u.S[n_f1:] = 2
    u.N = necks
    u.rings = spans
    u.replaced = u.pixel_caps = u.least_area = 0
    return u


def _exact_plan(A: _Slice, B: _Slice, k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, n0):
    """:func:`_exact_join`'s numbering for a mesher whose next vertex is ``n0``: ``(keys, starts,
    XY, made, F, n_f1, necks)``, the rings ``(k, comp, hole)`` in the order first used and their
    sizes (``starts``), the corner points in the order made, how many corners come before each
    ring, the faces (the ``n_f1`` of side 1 first) and the neck vertices; None where the group
    takes the reference (a caller's polygons, a corner outside the box)."""
    if getattr(A, "own", ()) or getattr(B, "own", ()):
        return None
    x0, y0, x1, y1, ra, rb = _group_box(A, B, ga, gb)
    exact_trip = (A.crack_outer.to_xy is to_xy_corner and B.crack_outer.to_xy is to_xy_corner
                  and A.crack_holes.to_xy is to_xy_corner and B.crack_holes.to_xy is to_xy_corner
                  and max(abs(ox) / dx, abs(oy) / dy) + max(y1, x1) + 1 < _EXACT_TRIP_LIMIT)
    keys, corners = [], []  # the rings (k, c, hole) in the reference's order, and their crack corners
    for kk, S, group in ((k, A, ga), (k + 1, B, gb)):
        for c in group:
            if exact_trip:
                rc = [np.asarray(S.crack_outer_c[c], dtype=np.int64)] + \
                    [np.asarray(r, dtype=np.int64) for r in S.crack_holes_c[c]]
            else:
                rc = [_back_to_corners(xy, dx, dy, ox, oy) for xy in [S.crack_outer[c]] + list(S.crack_holes[c])]
            keys += [(kk, c, h) for h in range(-1, len(rc) - 1)]
            corners += rc
    n_lower = sum(1 for key in keys if key[0] == k)
    starts = np.zeros(len(corners) + 1, dtype=np.int64)
    starts[1:] = np.cumsum([len(r) for r in corners])
    cxy = np.concatenate(corners) if corners else np.zeros((0, 2), dtype=np.int64)
    ux, uy, made, F, n_f1, necks, ok = _exact_join_kernel(
        np.ascontiguousarray(ra), np.ascontiguousarray(rb), np.int64(x0), np.int64(y0),
        np.ascontiguousarray(cxy[:, 0]), np.ascontiguousarray(cxy[:, 1]), starts, np.int64(n_lower), np.int64(n0))
    if not ok:  # pragma: no cover - a crack corner outside the group's box (numpy's indexing decides)
        return None
    zm = 0.5 * (zs[k] + zs[k + 1])
    XY = _with_z(to_xy_corner(np.stack([ux + x0, uy + y0], axis=1)), zm) if len(ux) else np.zeros((0, 3))
    return keys, starts, XY, made, F, int(n_f1), necks


def _back_to_corners(xy, dx, dy, ox, oy):
    """A crack ring's integer corners from its points (``to_xy_corner`` undone, rounded)."""
    return np.stack([np.rint((xy[:, 0] - ox) / dx + 0.5), np.rint((xy[:, 1] - oy) / dy + 0.5)], axis=1).astype(np.int64)


@internal_kernel
def _corner_pass(ids, lx, ly, nxt, ux, uy, nu):  # pragma: no cover (compiled)
    """:class:`_CornerGrid` on the places ``(lx, ly)`` (box coordinates): the missing corners get
    the numbers ``nxt, nxt + 1, ...`` in (x, y) order and are appended to ``ux, uy`` (from ``nu``).
    Returns ``(nxt, nu)`` after them, or ``(-1, -1)`` where a place lies outside the box."""
    h = ids.shape[0]
    w = ids.shape[1]
    keys = np.empty(len(lx), np.int64)
    nk = 0
    for t in range(len(lx)):
        if lx[t] < 0 or ly[t] < 0 or lx[t] >= w or ly[t] >= h:
            return np.int64(-1), np.int64(-1)
        if ids[ly[t], lx[t]] < 0:
            keys[nk] = lx[t] * h + ly[t]
            nk += 1
    keys = np.sort(keys[:nk])
    for t in range(nk):
        if t == 0 or keys[t] != keys[t - 1]:
            x = keys[t] // h
            y = keys[t] % h
            ids[y, x] = nxt
            nxt += 1
            ux[nu] = x
            uy[nu] = y
            nu += 1
    return nxt, nu


@njit(cache=True, **KERNEL_OPTIONS)
def _exact_join_kernel(ra, rb, x0, y0, cx, cy, starts, n_lower, n0):  # pragma: no cover (compiled)
    """The numbering and faces of :func:`_exact_join_reference` in one pass.  ``ra, rb``: the
    group's pixels below and above (its box); ``cx, cy``: the crack corners of its rings (pixel
    coordinates), ring ``i`` in ``starts[i]:starts[i + 1]``, the ``n_lower`` rings of the lower
    slice first, in the reference's order; ``n0``: the mesher's next vertex number.

    Returns ``(ux, uy, made, F, n_f1, necks, ok)``: the new corners (box coordinates) in the order
    they are made, how many corners are made before ring ``i`` is, the faces (the ``n_f1`` of side
    1 first), the neck vertices, and False where a corner lies outside the box."""
    hgt = ra.shape[0]
    wid = ra.shape[1]
    nr = len(starts) - 1
    ids = np.empty((hgt + 1, wid + 1), np.int64)
    for y in range(hgt + 1):
        for x in range(wid + 1):
            ids[y, x] = -1
    n_pix = 0
    for y in range(hgt):
        for x in range(wid):
            if ra[y, x] != rb[y, x]:
                n_pix += 1
    n_ring = starts[nr]
    empty = np.empty(0, np.int64)
    cap = (hgt + 1) * (wid + 1)  # (each corner is made once)
    ux = np.empty(cap, np.int64)
    uy = np.empty(cap, np.int64)
    made = np.empty(nr, np.int64)
    F = np.empty((2 * n_ring + 2 * n_pix, 3), np.int64)
    nf = 0
    n_f1 = 0
    nxt = n0
    nu = np.int64(0)  # (a literal 0 would compile _corner_pass a second time, for Literal[int](0))
    work = np.empty((8, n_pix), np.int64)  # a side's pixels, a corner's places, the four corners' numbers
    px, py, lx, ly, c00, c10, c11, c01 = work[0], work[1], work[2], work[3], work[4], work[5], work[6], work[7]
    for side in range(2):
        r0 = 0 if side == 0 else n_lower
        r1 = n_lower if side == 0 else nr
        for i in range(r0, r1):
            a, b = starts[i], starts[i + 1]
            m = b - a
            lxr = np.empty(m, np.int64)
            lyr = np.empty(m, np.int64)
            for t in range(m):
                lxr[t] = cx[a + t] - x0
                lyr[t] = cy[a + t] - y0
            if side == 0:  # the ring first, then its corners: quads(ring, corners)
                made[i] = nu
                first = nxt
                nxt += m
                nxt, nu = _corner_pass(ids, lxr, lyr, nxt, ux, uy, nu)
                if nxt < 0:
                    return ux[:0], uy[:0], made, F[:0], np.int64(0), empty[:0], False
            else:  # the corners first, then the ring: quads(corners, ring)
                nxt, nu = _corner_pass(ids, lxr, lyr, nxt, ux, uy, nu)
                if nxt < 0:
                    return ux[:0], uy[:0], made, F[:0], np.int64(0), empty[:0], False
                made[i] = nu
                first = nxt
                nxt += m
            for t in range(m):
                t1 = t + 1 if t + 1 < m else 0
                rt, rt1 = first + t, first + t1
                gt, gt1 = ids[lyr[t], lxr[t]], ids[lyr[t1], lxr[t1]]
                if side == 0:
                    F[nf + t, 0], F[nf + t, 1], F[nf + t, 2] = rt, rt1, gt1
                    F[nf + m + t, 0], F[nf + m + t, 1], F[nf + m + t, 2] = rt, gt1, gt
                else:
                    F[nf + t, 0], F[nf + t, 1], F[nf + t, 2] = gt, gt1, rt1
                    F[nf + m + t, 0], F[nf + m + t, 1], F[nf + m + t, 2] = gt, rt1, rt
            nf += 2 * m
        # the pixels of this side not covered by the other, row by row (np.nonzero's order)
        own = ra if side == 0 else rb
        other = rb if side == 0 else ra
        npx = 0
        for y in range(hgt):
            for x in range(wid):
                if own[y, x] and not other[y, x]:
                    px[npx] = x
                    py[npx] = y
                    npx += 1
        if npx:
            for corner in range(4):
                ox_ = 1 if corner == 1 or corner == 2 else 0
                oy_ = 1 if corner >= 2 else 0
                for t in range(npx):
                    lx[t] = px[t] + ox_
                    ly[t] = py[t] + oy_
                nxt, nu = _corner_pass(ids, lx[:npx], ly[:npx], nxt, ux, uy, nu)
                if nxt < 0:
                    return ux[:0], uy[:0], made, F[:0], np.int64(0), empty[:0], False
                out = c00 if corner == 0 else c10 if corner == 1 else c11 if corner == 2 else c01
                for t in range(npx):
                    out[t] = ids[ly[t], lx[t]]
            for t in range(npx):
                if side == 0:  # facing up
                    F[nf + t, 0], F[nf + t, 1], F[nf + t, 2] = c00[t], c10[t], c11[t]
                    F[nf + npx + t, 0], F[nf + npx + t, 1], F[nf + npx + t, 2] = c00[t], c11[t], c01[t]
                else:
                    F[nf + t, 0], F[nf + t, 1], F[nf + t, 2] = c00[t], c11[t], c10[t]
                    F[nf + npx + t, 0], F[nf + npx + t, 1], F[nf + npx + t, 2] = c00[t], c01[t], c11[t]
            nf += 2 * npx
        if side == 0:
            n_f1 = nf
    # necks: three of the four pixels below and three above, the two missing ones diagonally opposite
    nn = 0
    nkx = np.empty((hgt + 1) * (wid + 1), np.int64)
    nky = np.empty((hgt + 1) * (wid + 1), np.int64)
    for y in range(hgt + 1):
        for x in range(wid + 1):
            # pixel (x - 1 + i, y - 1 + j) of each side, outside the box empty
            lla = y >= 1 and x >= 1 and ra[y - 1, x - 1]
            lra = y >= 1 and x < wid and ra[y - 1, x]
            ula = y < hgt and x >= 1 and ra[y, x - 1]
            ura = y < hgt and x < wid and ra[y, x]
            llb = y >= 1 and x >= 1 and rb[y - 1, x - 1]
            lrb = y >= 1 and x < wid and rb[y - 1, x]
            ulb = y < hgt and x >= 1 and rb[y, x - 1]
            urb = y < hgt and x < wid and rb[y, x]
            if int(lla) + int(lra) + int(ula) + int(ura) != 3 or int(llb) + int(lrb) + int(ulb) + int(urb) != 3:
                continue
            if (not lla and not urb) or (not ura and not llb) or (not lra and not ulb) or (not ula and not lrb):
                nkx[nn] = x
                nky[nn] = y
                nn += 1
    necks = np.empty(nn, np.int64)
    if nn:
        nxt, nu = _corner_pass(ids, nkx[:nn], nky[:nn], nxt, ux, uy, nu)
        if nxt < 0:
            return ux[:0], uy[:0], made, F[:0], np.int64(0), empty[:0], False
        for t in range(nn):
            necks[t] = ids[nky[t], nkx[t]]
    return ux[:nu], uy[:nu], made, F[:nf], n_f1, necks[:nn], True


def _group_box(A: _Slice, B: _Slice, ga, gb):
    """``(x0, y0, x1, y1, ra, rb)``: the box of components ``ga`` below and ``gb`` above, and their
    pixels in it."""
    sl = [A.objects[a] for a in ga] + [B.objects[b] for b in gb]
    y0 = min(s[0].start for s in sl)
    y1 = max(s[0].stop for s in sl)
    x0 = min(s[1].start for s in sl)
    x1 = max(s[1].stop for s in sl)
    return x0, y0, x1, y1, label_mask(A.labels[y0:y1, x0:x1], A.n, ga), label_mask(B.labels[y0:y1, x0:x1], B.n, gb)


def _exact_join_reference(M: _Mesher, A: _Slice, B: _Slice, k, ga, gb, zs, ring, dx, dy, ox, oy, to_xy_corner):
    """:func:`_exact_join` step by step: each collar and each pixel pass a call of its own on the
    mesher, the corners made on demand (:class:`_CornerGrid`).  The reference of the compiled
    form, and the route of groups with a caller's polygons (their collars are bands)."""

    x0, y0, x1, y1, ra, rb = _group_box(A, B, ga, gb)
    o = ra & rb
    zk, zk1 = zs[k], zs[k + 1]
    zm = 0.5 * (zk + zk1)
    hgt, wid = ra.shape
    corner_ids = _CornerGrid(M, x0, y0, hgt, wid, zm, to_xy_corner)  # vertices at the mid-plane

    def back_to_corners(xy):
        return np.stack([np.rint((xy[:, 0] - ox) / dx + 0.5), np.rint((xy[:, 1] - oy) / dy + 0.5)], axis=1).astype(np.int64)

    # the crack rings' own integer corners where the round trip above gives them back exactly: both
    # slices' rings made by to_xy_corner (ox + (p - 0.5) dx), whose rounding errors, some units of
    # 2^-53 times |ox| / dx + |p| + 1 pixels, stay far below the half pixel that rint forgives
    exact_trip = (A.crack_outer.to_xy is to_xy_corner and B.crack_outer.to_xy is to_xy_corner
                  and A.crack_holes.to_xy is to_xy_corner and B.crack_holes.to_xy is to_xy_corner
                  and max(abs(ox) / dx, abs(oy) / dy) + max(y1, x1) + 1 < _EXACT_TRIP_LIMIT)

    def crack_rings(S, c):
        """``(h, corners)`` of component c's crack rings (-1 the outer one)."""
        if exact_trip:
            return [(-1, np.asarray(S.crack_outer_c[c], dtype=np.int64))] + \
                [(h, np.asarray(r, dtype=np.int64)) for h, r in enumerate(S.crack_holes_c[c])]
        return [(h, back_to_corners(xy)) for h, xy in [(-1, S.crack_outer[c])] + list(enumerate(S.crack_holes[c]))]

    # corners where the empty voxels of the 2 x 2 x 2 block touch only at the corner: three of
    # the four pixels below, three above, the two missing ones diagonally opposite
    pa = _pad1(ra)
    pb = _pad1(rb)
    q = lambda m, dy_, dx_: m[dy_: dy_ + hgt + 1, dx_: dx_ + wid + 1]  # pixel (cx-1+dx_, cy-1+dy_)
    lla, lra, ula, ura = q(pa, 0, 0), q(pa, 0, 1), q(pa, 1, 0), q(pa, 1, 1)
    llb, lrb, ulb, urb = q(pb, 0, 0), q(pb, 0, 1), q(pb, 1, 0), q(pb, 1, 1)
    three_a = lla.astype(int) + lra + ula + ura == 3
    three_b = llb.astype(int) + lrb + ulb + urb == 3
    opposite = (~lla & ~urb) | (~ura & ~llb) | (~lra & ~ulb) | (~ula & ~lrb)
    neck = three_a & three_b & opposite
    # side 1: the lower slice's collars (polygon ring at z_k up to its crack contour at the
    # mid-plane) and its pixels not covered above (facing up); side 2 mirrors it from above.
    M.side = 1
    for a in ga:
        collar = M.band if a in getattr(A, "own", ()) else M.quads  # a caller's polygon: a band to the crack
        for h, c in crack_rings(A, a):
            collar(ring(k, a, h), corner_ids(c[:, 0], c[:, 1]))
    _pixel_faces(M, ra & ~o, x0, y0, corner_ids, up=True)
    M.side = 2
    for b in gb:
        collar = M.band if b in getattr(B, "own", ()) else M.quads
        for h, c in crack_rings(B, b):
            collar(corner_ids(c[:, 0], c[:, 1]), ring(k + 1, b, h))
    _pixel_faces(M, rb & ~o, x0, y0, corner_ids, up=False)
    M.side = 0
    if neck.any():
        ny_, nx_ = np.nonzero(neck)
        M.necks.append(corner_ids(nx_ + x0, ny_ + y0))


def _pixel_faces(M, region, x0, y0, corner_ids, up):
    """Two triangles per pixel of ``region`` at the mid-plane, facing +z (``up``) or -z."""
    ys, xs = np.nonzero(region)
    if len(ys) == 0:
        return
    gx, gy = xs + x0, ys + y0
    c00 = corner_ids(gx, gy)
    c10 = corner_ids(gx + 1, gy)
    c11 = corner_ids(gx + 1, gy + 1)
    c01 = corner_ids(gx, gy + 1)
    if up:
        M.faces(np.concatenate([np.stack([c00, c10, c11], axis=1), np.stack([c00, c11, c01], axis=1)]))
    else:
        M.faces(np.concatenate([np.stack([c00, c11, c10], axis=1), np.stack([c00, c01, c11], axis=1)]))


# ------------------------------------------------------------------------------------------------
# branching joins by bridges
# ------------------------------------------------------------------------------------------------
def _bridge_plan(A: _Slice, B: _Slice, ga, gb):
    """How a fork or merge group joins between its polygons, or None where it cannot.

    The components overlap as a tree (a fork, a merge, or several of each side in a chain; one on
    each side with holes that do not match one to one).  It qualifies when every overlap of a
    pair of components is connected, no overlap lies in a hole of another, and every hole of the overlap ``O`` holds at most one hole from below
    and one from above: then the join is one band between the contours of each side bridged into
    one ring.
    Returns ``(tubes, lids_below, lids_above, open_below, open_above)``: hole pairs ``((a, ha),
    (b, hb))`` joined by a band (a tube); holes closed by a lid because the other slice covers
    them; and holes that open to the outside of the overlap (a handle that ends), which join
    their component's ring through a keyhole.
    """
    # (the group's box, its holes' pixels and the kernel's arguments made in plain loops: a group
    # has a few components, most without holes, and this runs for every fork and merge tried)
    y0 = x0 = 1 << 62
    y1 = x1 = -(1 << 62)
    for objects, comps in ((A.objects, ga), (B.objects, gb)):
        for c in comps:
            sy, sx = objects[c]
            if sy.start < y0:
                y0 = sy.start
            if sy.stop > y1:
                y1 = sy.stop
            if sx.start < x0:
                x0 = sx.start
            if sx.stop > x1:
                x1 = sx.stop
    # each hole of the group's components by its first pixel (raster order) in the padded box: the
    # background label there says which hole of the overlap holds it (_HoleMasks.first_pixel, read
    # from the parts: each part's first row holds a pixel)
    held, qy, qx = [], [], []
    for side, S, comps in ((0, A, ga), (1, B, gb)):
        for c in comps:
            csl, masks = S.hole_masks[c]
            if not masks.parts:
                continue
            dy, dx = csl[0].start - y0 + 1, csl[1].start - x0 + 1
            for h, (py, px, part) in enumerate(masks.parts):
                held.append((side, c, h))
                qy.append(py + dy)
                qx.append(px + int(part[0].argmax()) + dx)
    # in one compiled pass: how many pairs of components overlap, the overlap's 4-components, its
    # padded background's 8-components (ndimage.label's numbers, read at the holes' pixels) and the
    # overlaps that reach the outside
    # (from the two slices' runs in the box's rows where both keep them: the same numbers, the label
    # images not read)
    ra, rb = A.kept_runs(), B.kept_runs()
    lut_a, lut_b, qy, qx = _group_lut(A.n, ga), _group_lut(B.n, gb), np.array(qy, np.int64), np.array(qx, np.int64)
    if ra is not None and rb is not None:
        npairs, no, labs, nbl, n_out, ext = _overlap_plan_runs(
            ra, rb, y0, y1, x0, x1, lut_a, lut_b, len(ga), len(gb), qy, qx, 1)
    else:
        npairs, no, labs, nbl, n_out, ext = _overlap_plan(
            A.labels[y0:y1, x0:x1], B.labels[y0:y1, x0:x1], lut_a, lut_b, np.int64(len(ga)), np.int64(len(gb)), qy, qx,
            np.int64(1))
    if npairs != len(ga) + len(gb) - 1:  # the overlaps close a loop: a handle forms here
        return None
    if no != npairs:  # some pair overlaps in more than one piece: a handle
        return None
    if n_out != no:  # an overlap inside a hole of another
        return None
    if not held:  # (no hole in the group: nothing to pair; the overlap has none but the outside)
        if nbl - (1 <= ext <= nbl):  # pragma: no cover - a hole of O without a hole inside
            return None
        return [], [], [], [], []
    holes_o = set(range(1, nbl + 1)) - {ext}  # (the labels are 1 .. nbl, 0 the overlap)
    wa, wb = {}, {}
    for (side, c, h), lab in zip(held, labs.tolist()):
        (wb if side else wa).setdefault(lab, []).append((c, h))
    # holes open to the outside of the overlap (a handle ends between the slices): keyholes
    open_a, open_b = wa.pop(ext, []), wb.pop(ext, [])
    if any(len(v) > 1 for v in wa.values()) or any(len(v) > 1 for v in wb.values()):
        return None
    if set(wa) | set(wb) != holes_o:  # pragma: no cover - a hole of O without a hole inside
        return None
    tubes = [(wa[lab][0], wb[lab][0]) for lab in sorted(set(wa) & set(wb))]
    lids_a = [wa[lab][0] for lab in sorted(set(wa) - set(wb))]
    lids_b = [wb[lab][0] for lab in sorted(set(wb) - set(wa))]
    return tubes, lids_a, lids_b, open_a, open_b


def _group_lut(n, comps):
    """Per label ``0 .. n`` of a slice, the place of its component in ``comps`` (0-based
    components, label ``c + 1``), -1 for the labels of the others and the background."""
    lut = np.full(n + 1, -1, dtype=np.int64)
    # (a group has a few components: set one by one, in order, as the fancy assignment sets them;
    # a component out of range raises as it did)
    for t, c in enumerate(comps):
        lut[int(c) + 1] = t
    return lut


@njit(cache=True, **KERNEL_OPTIONS)
def _overlap_pairs(la, lb, lut_a, lut_b, na, nb):  # pragma: no cover (compiled)
    """The overlap of a group's components below and above in its box (``la``, ``lb``: the two
    label images there; ``lut_a``, ``lut_b``: :func:`_group_lut` of each side, ``na``, ``nb`` the
    sizes of the two groups) and the number of distinct pairs ``(a, b)`` of components that overlap:
    ``label_mask(la, .., ga) & label_mask(lb, .., gb)`` and the number of ``unique_keys`` of the
    label pairs on it, in one pass."""
    h, w = la.shape
    o = np.empty((h, w), np.bool_)
    seen = np.zeros((na, nb), np.bool_)
    npairs = 0
    for y in range(h):
        for x in range(w):
            a = lut_a[la[y, x]]
            b = lut_b[lb[y, x]]
            inside = a >= 0 and b >= 0
            o[y, x] = inside
            if inside and not seen[a, b]:
                seen[a, b] = True
                npairs += 1
    return o, npairs


@njit(cache=True, **KERNEL_OPTIONS)
def _overlap_plan(la, lb, lut_a, lut_b, na, nb, ys, xs, one):  # pragma: no cover (compiled)
    """What :func:`_bridge_plan` reads of a group's overlap, in one pass over its box (``la``,
    ``lb``, ``lut_a``, ``lut_b``, ``na``, ``nb`` as for :func:`_overlap_pairs`; ``one`` is 1):
    ``(npairs, n, labels, nb, n_out, ext)``, the number of pairs of components that overlap and,
    where they form no loop (``npairs == na + nb - 1``; else ``n`` is -1 and the rest empty or 0),
    :func:`contourmesh.tracing.overlap_hole_labels` of the overlap at the padded pixels
    ``(ys[i], xs[i])``.  The overlap's runs are taken as its pixels are found, so no mask of it
    is made, nor its background's labels painted: the same numbers as ``_overlap_pairs`` and
    ``overlap_holes`` of its mask (as the tests check)."""
    h, w = la.shape
    seen = np.zeros((na, nb), np.bool_)
    npairs = 0
    cap = h * ((w + 1) // 2)
    ox0 = np.empty(cap, np.int64)
    ox1 = np.empty(cap, np.int64)
    ors = np.empty(h + 1, np.int64)
    nr = 0
    for y in range(h):
        ors[y] = nr
        open_ = False
        for x in range(w):
            a = lut_a[la[y, x]]
            b = lut_b[lb[y, x]]
            if a >= 0 and b >= 0:
                if not seen[a, b]:
                    seen[a, b] = True
                    npairs += 1
                if not open_:
                    ox0[nr] = x
                    open_ = True
            elif open_:
                ox1[nr] = x
                nr += 1
                open_ = False
        if open_:
            ox1[nr] = w
            nr += 1
    ors[h] = nr
    if npairs != na + nb - 1:
        return npairs, one - 2, np.empty(0, np.int64), one - one, one - one, one - one
    no, labels, nbl, n_out, ext = _runs_hole_labels(ox0, ox1, ors, h, w, ys, xs, one)
    return npairs, no, labels, nbl, n_out, ext


@njit(cache=True, **KERNEL_OPTIONS)
def _overlap_plan_runs(ra, rb, y0, y1, x0, x1, lut_a, lut_b, na, nb, ys, xs, one):  # pragma: no cover (compiled)
    """:func:`_overlap_plan` of the box ``y0 .. y1 - 1``, ``x0 .. x1 - 1`` from the two slices' runs
    (``(4, n)`` ``[row, first column, end column, component]``, raster order, whole-image
    coordinates: ``_Slice.kept_runs``; the luts indexed by component + 1) rather than their label
    images: the overlap's runs in a row are where a run of the group below meets one of the group
    above (the runs of a row taken in increasing order from both sides, each step past the one
    that ends first), two that touch made one; the same numbers."""
    n_a, n_b = ra.shape[1], rb.shape[1]
    i, j = _first_row_run(ra, y0), _first_row_run(rb, y0)
    i1, j1 = _first_row_run(ra, y1), _first_row_run(rb, y1)
    h, w = y1 - y0, x1 - x0
    seen = np.zeros((na, nb), np.bool_)
    npairs = 0
    cap = (i1 - i) + (j1 - j) + 1
    ox0 = np.empty(cap, np.int64)
    ox1 = np.empty(cap, np.int64)
    ors = np.empty(h + 1, np.int64)
    nr = 0
    for y in range(h):
        ors[y] = nr
        yy = y0 + y
        while i < n_a and j < n_b and ra[0, i] == yy and rb[0, j] == yy:
            a = lut_a[np.int64(ra[3, i]) + 1]
            b = lut_b[np.int64(rb[3, j]) + 1]
            lo = max(max(np.int64(ra[1, i]), np.int64(rb[1, j])), x0)
            hi = min(min(np.int64(ra[2, i]), np.int64(rb[2, j])), x1)
            if a >= 0 and b >= 0 and lo < hi:
                if not seen[a, b]:
                    seen[a, b] = True
                    npairs += 1
                if nr > ors[y] and ox1[nr - 1] == lo - x0:
                    ox1[nr - 1] = hi - x0
                else:
                    ox0[nr] = lo - x0
                    ox1[nr] = hi - x0
                    nr += 1
            if ra[2, i] <= rb[2, j]:
                i += 1
            else:
                j += 1
        while i < n_a and ra[0, i] == yy:
            i += 1
        while j < n_b and rb[0, j] == yy:
            j += 1
    ors[h] = nr
    if npairs != na + nb - 1:
        return npairs, one - 2, np.empty(0, np.int64), one - one, one - one, one - one
    no, labels, nbl, n_out, ext = _runs_hole_labels(ox0, ox1, ors, h, w, ys, xs, one)
    return npairs, no, labels, nbl, n_out, ext


#: Largest ``n^2 m`` for which a twisted bridged band is replaced by the optimal band (else by the
#: arc-length band): bridged rings of many small contours are long, and the optimal band is cubic.
_BRIDGED_OPTIMAL_BUDGET = 3e6


class _Bridged:
    """One bridged join, built in local vertex numbers: ``V[:n_ring]`` are the rings' vertices
    (``rings``: ``((k, comp, hole), offset)``), the rest new vertices (lid collars)."""

    __slots__ = ("V", "F", "rings", "n_ring", "replaced", "bridges", "segments", "polyline", "sections", "least_area")

    def __init__(self, V, F, rings, n_ring, replaced, bridges, segments, polyline=False):
        self.V, self.F, self.rings, self.n_ring = V, F, rings, n_ring
        self.replaced, self.bridges, self.segments = replaced, bridges, segments
        self.polyline = polyline  # a keyhole of the join is a polyline
        self.sections = 0  # intermediate sections in the gap (contourmesh.sections)
        self.least_area = 0  # its bands made by the least-area rule in place of a local one


#: Band strategies tried, in order, on a bridged join whose band crosses itself.
_BRIDGED_ALTERNATIVES = ("optimal", "arclength", "wiederhold", "greedy")
#: An alternative band may exceed the crossing band's area by this factor at most (a larger one is
#: twisted across the slits: elephant rotated #0 at 64 across took an arc-length band 4.5 times
#: the area, +15 % on the whole mesh).
_BRIDGED_AREA_SLACK = 1.25
#: Where a band of a bridged join kept crosses itself, test the join's faces made so far at once
#: (the join is given up where they cross, without the bands and lids after them); False tests
#: only the whole join (the same joins, more work: the tests' reference).
_BRIDGED_CROSSING_FIRST = True


def _bridge_join(k, ga, gb, plan, poly, zs, edges_of, uncovered, triangulation, caps, double, waypoints=None,
                 band_guard=None):
    """Build one bridged join (a :class:`_Bridged`), or None where a bridge, a lid or the faces
    would not keep clear of each other.

    ``waypoints(plane, other, comps)``, where given, returns ``(step, points_of)`` for polyline
    keyholes (:func:`contourmesh.bands.bridges.keyhole_path`): ``points_of(c)`` is ``(points,
    allowed)``, the pixel centres near component ``c`` of ``plane`` outside its overlap with the
    components ``comps`` of slice ``other``, and the test that a keyhole's pieces stay out of
    that overlap.  The interior points of such a keyhole become new vertices of the join, in its
    plane, after the rings' (``V[n_ring:]``, with the lid collars).

    ``band_guard`` (the contours route's volume guard, see :meth:`_Mesher.band`), where given, may
    replace each band of the join (the bridged rings' band and the tubes'); its band is kept
    only where it neither folds nor crosses itself.

    Where the join's faces cross at a bridge end, its band gets other rules
    (:func:`_merged_band_retry`)."""
    tubes, lids_a, lids_b, open_a, open_b = plan
    zk, zk1 = float(zs[k]), float(zs[k + 1])
    pts, heights, rings = [], [], []  # the rings' points (x, y), their planes' heights
    n = 0

    def add(kk, c, h):
        nonlocal n
        xy = np.asarray(poly(kk, c, h), dtype=np.float64).reshape(-1, 2)
        pts.append(xy)
        heights.append(zs[kk])
        rings.append(((kk, c, h), n))
        n += len(xy)
        return np.arange(n - len(xy), n)

    lo = [add(k, a, -1) for a in ga] + [add(k, a, h) for a, h in open_a]
    hi = [add(k + 1, b, -1) for b in gb] + [add(k + 1, b, h) for b, h in open_b]
    owners_lo = [(a, False) for a in ga] + [(a, True) for a, _ in open_a]
    owners_hi = [(b, False) for b in gb] + [(b, True) for b, _ in open_b]
    tube_ids = [(add(k, a, ha), add(k + 1, b, hb)) for (a, ha), (b, hb) in tubes]
    # a hole lidded from both sides (a cavity one slice thick) gets its lids half a gap out, so that
    # the two do not coincide (as a component alone in its slice becomes a prism)
    lid_ids = [(add(k, a, h), True, (k, a, h) in double) for a, h in lids_a] + \
        [(add(k + 1, b, h), False, (k + 1, b, h) in double) for b, h in lids_b]
    # (as _with_z of each ring, concatenated: the same numbers, in one array)
    V = np.empty((n, 3))
    V[:, :2] = np.concatenate(pts)
    V[:, 2] = np.repeat(np.array(heights, dtype=np.float64), [len(xy) for xy in pts])
    n_ring = len(V)
    # a lid needs its ring's points distinct (a collar copies them): a test of the rings alone, so
    # it comes before the bridges and the bands, which a join that fails it would build in vain
    # (the same None)
    for ids, _below, _collar in lid_ids:
        if not _distinct_rows(V[ids][:, :2]):  # (len(np.unique(xy, axis=0)) != len(xy), sorted faster)
            return None
    segments, nb = [], 0
    path_pts = []  # interior points of polyline keyholes: new vertices after the rings'
    for plane, multi, owners, other, comps in ((k, lo, owners_lo, k + 1, gb), (k + 1, hi, owners_hi, k, ga)):
        if len(multi) == 1:
            continue
        # (each ring's ids are a run: its rows of V, as a view, are V[r][:, :2])
        rs = [V[r[0]:r[0] + len(r), :2] if len(r) else V[r][:, :2] for r in multi]
        lengths = [len(r) for r in multi]
        # the plane's rings follow each other in V: packed for the compiled kernels in one copy
        # (the numbers _packed_rings would concatenate); an empty ring leaves them to bridge_tree
        packed = None
        if min(lengths) > 0:
            s0 = int(multi[0][0])
            packed = (np.ascontiguousarray(V[s0:int(multi[-1][-1]) + 1, :2]),
                      np.array([int(r[0]) - s0 for r in multi], dtype=np.int64), np.array(lengths, dtype=np.int64))
        oa, ob = edges_of(plane)
        step, points_of = (1.0, None) if waypoints is None else waypoints(plane, other, comps)
        cover = uncovered(other, comps)
        br = bridge_tree(rs, oa, ob, owners=owners, allowed=cover, waypoints=points_of, step=step,
                         prefer=PreferCovered(cover, 0.5), packed=packed)
        if br is None:
            return None
        # the first id of each table of the tour: ring r's (its ids run from r[0]), then each
        # polyline bridge's interior points (new vertices, numbered on from base; 0 for a straight
        # bridge, which the tour does not visit)
        first = [int(r[0]) if len(r) else 0 for r in multi]
        for bridge in br:
            first.append(0)
            if len(bridge) > 4:
                first[-1] = n_ring + sum(len(p) for p in path_pts)
                path_pts.append(_with_z(bridge[4], zs[plane]))
        seq = bridged_ring_ids(lengths, br, first)  # (the tour's ids, in one compiled call)
        for bridge in br:
            i, vi, j, vj = bridge[:4]
            line = [rs[i][vi]] + (list(bridge[4]) if len(bridge) > 4 else []) + [rs[j][vj]]
            segments += [(plane, line[t], line[t + 1]) for t in range(len(line) - 1)]
        nb += len(br)
        if plane == k:
            lo = [seq]
        else:
            hi = [seq]
    if path_pts:
        V = np.concatenate([V] + path_pts)
    faces, replaced, least_area = [], 0, 0
    bands = []  # (lower ids, upper ids, rule) of each band, in the order of faces
    # some band kept crosses itself (its bridge ends a hair apart): then where the join's faces
    # cross, _merged_band_retry gives None whatever the bands before it do (it gives None at that
    # band at the latest), so it is not run
    crossing = False
    for t, (a_ids, b_ids) in enumerate([(lo[0], hi[0])] + tube_ids):
        ids = np.concatenate([a_ids, b_ids])
        P = V[ids]  # (the rows of V[a_ids], then those of V[b_ids])
        na = len(a_ids)
        # the bridged rings' band by the least-area rule (see _dissimilar_rule); the tubes (pairs
        # of holes) by the selected one
        rule = triangulation if t else _dissimilar_rule(na, len(b_ids), triangulation, _BRIDGED_OPTIMAL_BUDGET)
        least_area += rule != triangulation
        got = _bridged_band_crossing(P, na, ids, rule) if band_guard is not None else \
            _bridged_band_seen(P, na, ids, rule)
        if got is None:
            return None
        f, r, crosses = got
        if band_guard is not None:  # a bridged ring's area is the sum of its contours' (slits add none)
            g = np.asarray(band_guard(V[a_ids], V[b_ids], f))
            if not np.array_equal(g, f) and not band_is_folded(ids[g]) and not _band_crosses(P, g):
                f, crosses = g, False
        crossing = crossing or crosses
        faces.append(ids[f])
        bands.append((a_ids, b_ids, rule, f))
        replaced += r
        if crosses and _BRIDGED_CROSSING_FIRST and any_intersecting(V, np.concatenate(faces)):
            # a band kept crosses itself, so the join is given up wherever its faces cross (below,
            # without a retry); the faces so far already cross, and so do the join's, which hold
            # them: the same None without the bands and lids after it
            return None
    extra = []
    for ids, below, collar in lid_ids:
        # a hole of the lower slice covered from above: its lid faces down (and the other way)
        if caps == "half" or collar:
            zc = zk + 0.5 * (zk1 - zk) if below else zk1 - 0.5 * (zk1 - zk)
            top = len(V) + sum(len(e) for e in extra) + np.arange(len(ids))
            extra.append(_with_z(V[ids][:, :2], zc))
            Vx = np.concatenate([V] + extra)
            pair = (ids, top) if below else (top, ids)
            f, r = _band_faces(Vx[pair[0]], Vx[pair[1]], triangulation)
            faces.append(np.concatenate(pair)[f])
            replaced += r
            ids = top
            xy = Vx[ids][:, :2]
        else:
            xy = V[ids][:, :2]
        # (its points are distinct: tested with the rings, above)
        try:
            f = cap_faces(xy, upward=not below)
        except ValueError:
            return None
        if len(f) == 0:
            return None
        faces.append(ids[f])
    if extra:
        V = np.concatenate([V] + extra)
    F = np.concatenate(faces)
    if band_is_folded(F):  # an edge in more than two faces (compiled: the sorted edge keys)
        return None
    if _repeats_a_corner(F):
        return None
    if any_intersecting(V, F):
        # the bands were tested with the two visits of each bridge end a hair apart (as pinches); as
        # one vertex a band can cross itself where they meet: try the other rules on the band as built
        # (only faces that the retry replaced are tested again: those that passed keep their answer)
        F = None if crossing else _merged_band_retry(V, faces, bands)
        if F is None or any_intersecting(V, F):
            return None
        replaced += 1
    out = _Bridged(V, F, rings, n_ring, replaced, nb, segments, polyline=bool(path_pts))
    out.least_area = least_area
    return out


def _bridged_band(P, na, ids, rule):
    """:func:`_bridged_band_crossing` without its third value: ``(faces, guards)`` or None."""
    got = _bridged_band_crossing(P, na, ids, rule)
    return None if got is None else got[:2]


def _bridged_band_crossing(P, na, ids, rule):
    """The faces (local numbers) of one band of a bridged join, how many guards fired and whether
    the band kept crosses itself (:func:`contourmesh.bands._band_crosses` of ``P`` and the faces:
    True where no other rule's band replaced a band that crosses), or None
    where every rule's band folds: ``P`` its two rings' points (the lower ring's ``na`` first), ``ids``
    their vertex ids in the join (a bridged ring visits its bridge ends twice, with one id) and
    ``rule`` its band rule (:func:`_dissimilar_rule`'s).  The band of :func:`_band_faces`; where it
    uses a diagonal twice in the join's numbering, the bounded least-area band, then the arc-length
    band; where it crosses itself, the first other rule's that does not (see :func:`_bridge_join`).
    A function of ``P``, ``na``, ``ids`` and ``rule`` only."""
    Va, Vb = P[:na], P[na:]
    f, r = _band_faces(Va, Vb, rule, _BRIDGED_OPTIMAL_BUDGET)
    # a bridged ring visits its bridge ends twice: the band must not use a diagonal twice.  The
    # optimal band is bounded here (bridged rings are long; see triangulate_band_optimal)
    n_, m_ = sorted((na, len(P) - na))
    made = {}  # the rules' bands made below for this pair, by name (_made_band)
    # (each band is tested once: a band not made again keeps its answer)
    folded = band_is_folded(ids[f])
    for method in ("optimal", "arclength"):
        if not folded:
            break
        # (where _band_faces kept the least-area band of a pair within the budget, the bounded
        # one is that band: it is not made again)
        if method != "optimal" or rule != "optimal" or r != 0 or n_ * n_ * m_ > _BRIDGED_OPTIMAL_BUDGET:
            f = triangulate_band_optimal(Va, Vb, max_work=_BRIDGED_OPTIMAL_BUDGET) \
                if method == "optimal" else _made_band(made, Va, Vb, method)
            folded = band_is_folded(ids[f])
        r += 1
    if folded:
        return None
    # a bridged ring is far from convex (its slits): the chosen band may cross itself where
    # another strategy does not; take the first embedded one that is not twisted (its area at
    # most _BRIDGED_AREA_SLACK times the crossing band's) before giving the join up
    crosses = _band_crosses(P, f)
    if crosses:
        limit = _BRIDGED_AREA_SLACK * float(triangle_areas(P, f).sum())
        for method in _BRIDGED_ALTERNATIVES:
            if method == "optimal" and (rule == "optimal" or n_ * n_ * m_ > _BRIDGED_OPTIMAL_BUDGET):
                continue  # already tried, or too slow (cubic)
            g = _made_band(made, Va, Vb, method)
            if g is f:  # (the band that crosses: it would not pass the test below)
                continue
            if (not band_is_folded(ids[g]) and float(triangle_areas(P, g).sum()) <= limit
                    and not _band_crosses(P, g)):
                f, r, crosses = g, r + 1, False
                break
    return f, r, crosses


#: The last few answers of :func:`_bridged_band`, keyed by the bytes of its arguments and the
#: settings it reads (``_BRIDGED_ALTERNATIVES``, ``_BRIDGED_OPTIMAL_BUDGET``, ``_BRIDGED_AREA_SLACK``): a bridged
#: join is built again with the same rings (a pass that restarts after a join fell back, the same
#: piece of intermediate sections tried again; about a sixth of the lobster's joins), and its bands
#: are the same.  The memory keeps a read-only copy of the faces and hands out a writable copy.
_BANDS_KEEP = 64
_BANDS_SEEN = Recent(_BANDS_KEEP)


def _bridged_band_seen(P, na, ids, rule):
    """:func:`_bridged_band_crossing` (faces, guards, whether the band crosses itself), remembering
    the answers of the last :data:`_BANDS_KEEP` calls."""
    key = (P.shape, P.dtype.str, P.tobytes(), na, ids.dtype.str, ids.tobytes(), rule,
           # (the settings it reads, so that a changed setting is never answered from memory)
           _BRIDGED_ALTERNATIVES, _BRIDGED_OPTIMAL_BUDGET, _BRIDGED_AREA_SLACK)
    got = _BANDS_SEEN.get(key, MISSING)
    if got is not MISSING:
        # (a copy of the kept faces: writable, as a band made now, so that the kernels they go to
        # see one array type and compile once, not again for read-only arrays)
        return None if got is None else (got[0].copy(), got[1], got[2])
    got = _bridged_band_crossing(P, na, ids, rule)
    kept = None if got is None else (got[0].copy(), got[1], got[2])
    if kept is not None:
        kept[0].flags.writeable = False
    _BANDS_SEEN.put(key, kept)
    return got


@njit(cache=True, **KERNEL_OPTIONS)
def _repeats_a_corner(F):  # pragma: no cover (compiled)
    """Whether some face of ``F`` names one vertex twice: ``(F[:, 0] == F[:, 1]).any() or (F[:, 1] ==
    F[:, 2]).any() or (F[:, 0] == F[:, 2]).any()`` in one pass."""
    for t in range(F.shape[0]):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        if a == b or b == c or a == c:
            return True
    return False


def _made_band(made, lo, hi, method):
    """``triangulate_band(lo, hi, method, fallback=False)``, kept in ``made`` (a dict by method, for
    one pair of rings): a rule's band is made once per pair however often it is asked for (the
    same rings give the same faces)."""
    got = made.get(method)
    if got is None:
        got = made[method] = triangulate_band(lo, hi, method, fallback=False)
    return got


#: The rules :func:`_merged_band_retry` tries after ``_BRIDGED_ALTERNATIVES``: ``"bounded"`` is the
#: least-area band within ``_BRIDGED_OPTIMAL_BUDGET`` steps (see triangulate_band_optimal's
#: ``max_work``), for rings too long for the whole optimal band.
_MERGED_EXTRA = ("bounded",)


def _merged_band_retry(V, faces, bands):
    """The faces of a bridged join whose faces cross (``faces``: its bands' faces, as ``bands``
    lists them as ``(lower ids, upper ids, rule, local faces)``, then the lids'), with each band
    that crosses itself (its bridge ends one vertex, as in the mesh) replaced by the first other
    rule's band that neither folds nor crosses itself nor has more than ``_BRIDGED_AREA_SLACK``
    times its area; None where a crossing band has none.  Lids are left as they are (the caller
    tests the whole join again).

    The band's own test (:func:`contourmesh.bands._band_crosses`) moves the two visits of each
    bridge end a hair apart, as the mesher does with a ring that touches itself; a bridge end is
    one vertex in the join, and there the band can fold onto itself across the bridge (on the
    lobster, in about half of the sectioned joins' pieces that failed).  Only such bands are tried:
    a band that crosses with its ends apart too has had the other rules already (trying it again
    on the densified try of a join with a speck changed none of fandisk's, lion's or socket's
    rotations at 256 and cost the lobster time)."""
    from .intersect import any_intersecting

    out = list(faces)
    for t, (a_ids, b_ids, rule, f) in enumerate(bands):
        ids = np.concatenate([a_ids, b_ids])
        P = V[ids]
        if _band_crosses(P, f):
            return None  # (it crosses with the ends apart too: the other rules were tried)
        if len(faces) > 1 and not any_intersecting(V, out[t]):  # (one band alone: it is the one that crosses)
            continue
        n_, m_ = sorted((len(a_ids), len(b_ids)))
        limit = _BRIDGED_AREA_SLACK * float(triangle_areas(V, out[t]).sum())
        for method in _BRIDGED_ALTERNATIVES + _MERGED_EXTRA:
            if method == rule or (method == "optimal" and n_ * n_ * m_ > _BRIDGED_OPTIMAL_BUDGET) or \
                    (method == "bounded" and n_ * n_ * m_ <= _BRIDGED_OPTIMAL_BUDGET):
                continue
            g = triangulate_band_optimal(V[a_ids], V[b_ids], max_work=_BRIDGED_OPTIMAL_BUDGET) \
                if method == "bounded" else triangulate_band(V[a_ids], V[b_ids], method, fallback=False)
            if band_is_folded(ids[g]) or float(triangle_areas(P, g).sum()) > limit or any_intersecting(V, ids[g]):
                continue
            out[t] = ids[g]
            break
        else:
            return None
    return np.concatenate(out)


#: A bridged join is given up (it gets intermediate sections, or becomes exact) where its area
#: exceeds this many times the voxel-exact join's (:func:`_exact_area`): its band folds over itself,
#: fanning across the slice.  On the rotated real shapes good polyline-keyhole joins stay below 1.2;
#: rocker arm rotated #2 at 64 across had one at 2.1 (+8 % on the whole mesh), and a slanted torus
#: of the scale-out synthetic, whose C-shaped section closes into a ring, one at 3 (+28 %).
_BRIDGED_AREA_LIMIT = 1.5
#: A bridged join with more area than this share of the exact join's also tries intermediate sections
#: (:func:`contourmesh.sections.sectioned_join`) and keeps whichever of the two has less area.
_SECTION_TRIAL = 1.0


def _exact_area(slices, zs, k, ga, gb, pixel_area, perimeters=None):
    """The area of the voxel-exact join of a group (:func:`_exact_join`): crack contours' collars
    half a gap high on each side, and the pixels each slice does not share with the other.
    ``perimeters``: a dict that keeps each component's crack perimeter, ``(slice, component) ->
    float``, across calls (crack rings do not change)."""
    A, B = slices[k], slices[k + 1]
    h = 0.5 * float(zs[k + 1] - zs[k])
    perimeters = {} if perimeters is None else perimeters

    def perimeter(kk, c):
        if (kk, c) not in perimeters:
            # (every component of the slice at once: most are asked for in time, and one pass over
            # the slice's crack rings costs about what two components cost one by one)
            for c2, got in enumerate(_crack_perimeters(slices[kk])):
                perimeters.setdefault((kk, c2), got)
        return perimeters[kk, c]

    collars = sum(perimeter(k, a) for a in ga) + sum(perimeter(k + 1, b) for b in gb)
    # the pixels of either side lie in the box of their components' boxes
    sl = [A.objects[a] for a in ga] + [B.objects[b] for b in gb]
    box = np.s_[min(s[0].start for s in sl):max(s[0].stop for s in sl),
                min(s[1].start for s in sl):max(s[1].stop for s in sl)]
    # (np.count_nonzero(label_mask(A's box, ga) ^ label_mask(B's box, gb)), compiled: from the two
    # slices' runs in the box's rows where both keep them, else from the box's label pixels)
    ra, rb = A.kept_runs(), B.kept_runs()
    if ra is not None and rb is not None:
        only = _count_one_side_runs(ra, rb, np.int64(box[0].start), np.int64(box[0].stop), np.int64(box[1].start),
                                    np.int64(box[1].stop), _group_lut(A.n, ga), _group_lut(B.n, gb))
    else:
        only = _count_one_side(A.labels[box], B.labels[box], _group_lut(A.n, ga), _group_lut(B.n, gb))
    return collars * h + float(only) * pixel_area


def _crack_perimeter(S, c):
    """The length of component ``c``'s crack rings in slice ``S`` (outer ring and holes) in physical
    xy: per ring ``np.hypot`` of its steps summed by numpy, the rings' sums added in order.  Their
    xy, steps and lengths are made for all the rings at once (elementwise, so the same numbers as
    ring by ring, :meth:`_CrackXY.made`) and each ring's lengths summed as a slice of them (numpy's
    sum of a run depends only on its values and length): the same float as ring by ring."""
    outer, holes = S.crack_outer, S.crack_holes
    rings = [outer.corners[c]] + list(holes.corners[c])
    if holes.to_xy is not outer.to_xy or len(rings) == 1:  # (made for the sum, not kept: see _CrackXY)
        return sum(float(np.hypot(*(_next(r) - r).T).sum()) for r in [outer.made(c)] + list(holes.made(c)))
    return sum(_ring_lengths(outer.to_xy, rings))


def _ring_lengths(to_xy, rings) -> list:
    """The length of each crack ring of ``rings`` (corner coordinates) in physical xy, in order:
    their xy made for all the rings at once (elementwise: the same numbers as ring by ring), then
    each ring's steps, their lengths and their sum in one compiled pass
    (:func:`_ring_lengths_kernel`, numpy's pairwise sum written out: the same floats as
    :func:`_ring_lengths_numpy`, the form it replaces)."""
    lens = np.array([len(r) for r in rings], dtype=np.int64)
    xy = np.ascontiguousarray(to_xy(np.concatenate(rings)), dtype=np.float64).reshape(-1, 2)
    return _ring_lengths_kernel(xy, lens).tolist()


@njit(cache=True, **KERNEL_OPTIONS)
def _ring_lengths_kernel(xy, lens):  # pragma: no cover (compiled)
    """Per ring (the next ``lens[r]`` rows of ``xy``), the sum of its steps' lengths
    ``np.hypot(dx, dy)`` (a ring's last point followed by its first), summed as numpy sums a
    contiguous float64 array (:func:`_pairwise_sum`)."""
    steps = np.empty(xy.shape[0])
    out = np.empty(lens.shape[0])
    t = 0
    for r in range(lens.shape[0]):
        n = lens[r]
        for u in range(n):
            a = t + u
            b = a + 1 if u + 1 < n else t
            steps[a] = np.hypot(xy[b, 0] - xy[a, 0], xy[b, 1] - xy[a, 1])
        out[r] = _pairwise_sum(steps, t, n)
        t += n
    return out


@njit(cache=True, **KERNEL_OPTIONS)
def _pairwise_sum(a, lo, n):  # pragma: no cover (compiled)
    """``a[lo: lo + n].sum()`` as numpy sums a contiguous float64 array, bit for bit: fewer than 8
    values added in order from 0.0; up to 128 in eight running sums (every eighth value), joined
    as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, then the rest added in order; more
    split in two (the first part's length halved down to a multiple of 8) and the halves' sums
    added."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        m = n - n % 8
        i = 8
        while i < m:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise_sum(a, lo, n2) + _pairwise_sum(a, lo + n2, n - n2)


def _ring_lengths_numpy(to_xy, rings) -> list:
    """:func:`_ring_lengths` in numpy (the form the compiled pass replaced; the tests compare them):
    the steps and their lengths for all the rings at once, each ring's summed by numpy as its slice
    of them."""
    lens = np.array([len(r) for r in rings], dtype=np.int64)
    xy = to_xy(np.concatenate(rings))
    ends = np.cumsum(lens)
    nxt = np.arange(1, len(xy) + 1)
    full = lens > 0
    nxt[ends[full] - 1] = (ends - lens)[full]  # each ring's last point is followed by its first
    d = xy[nxt] - xy
    steps = np.hypot(d[:, 0], d[:, 1])
    return [float(steps[e - n: e].sum()) for e, n in zip(ends.tolist(), lens.tolist())]


def _crack_perimeters(S) -> list:
    """:func:`_crack_perimeter` of every component of slice ``S``, in order: the crack rings of all
    the components (each one's outer ring, then its holes) made into xy, steps and lengths at once
    (elementwise: the same numbers as ring by ring), each ring's lengths summed by numpy as its
    slice of them (as :func:`_crack_perimeter` sums its rings'), and each component's rings' sums
    added in order from 0 (Python's ``sum``): the same floats, bit for bit."""
    outer, holes = S.crack_outer, S.crack_holes
    if holes.to_xy is not outer.to_xy:
        return [_crack_perimeter(S, c) for c in range(S.n)]
    rings, per = [], []
    for c in range(S.n):
        rs = [outer.corners[c]] + list(holes.corners[c])
        rings += rs
        per.append(len(rs))
    if not rings:
        return []
    sums = _ring_lengths(outer.to_xy, rings)
    out, t = [], 0
    for m in per:
        out.append(sum(sums[t: t + m]))
        t += m
    return out


@njit(cache=True, **KERNEL_OPTIONS)
def _count_one_side(la, lb, lut_a, lut_b):  # pragma: no cover (compiled)
    """How many pixels of the box lie in a component of exactly one of the two groups (``la``,
    ``lb``: the label images there; ``lut_a``, ``lut_b``: :func:`_group_lut` of each group)."""
    h, w = la.shape
    count = 0
    for y in range(h):
        for x in range(w):
            if (lut_a[la[y, x]] >= 0) != (lut_b[lb[y, x]] >= 0):
                count += 1
    return count


@njit(cache=True, **KERNEL_OPTIONS)
def _count_one_side_runs(ra, rb, y0, y1, x0, x1, lut_a, lut_b):  # pragma: no cover (compiled)
    """:func:`_count_one_side` of the box ``y0 .. y1 - 1``, ``x0 .. x1 - 1`` from the two slices'
    runs (``_Slice.kept_runs``; the luts indexed by component + 1): the pixels of the group below
    and of the group above in the box, less twice those of both (where a run of one meets a run of
    the other, the runs of a row taken in increasing order from both sides)."""
    count = 0
    i, i1 = _first_row_run(ra, y0), _first_row_run(ra, y1)
    for r in range(i, i1):
        if lut_a[np.int64(ra[3, r]) + 1] >= 0:
            count += max(min(np.int64(ra[2, r]), x1) - max(np.int64(ra[1, r]), x0), 0)
    j, j1 = _first_row_run(rb, y0), _first_row_run(rb, y1)
    for r in range(j, j1):
        if lut_b[np.int64(rb[3, r]) + 1] >= 0:
            count += max(min(np.int64(rb[2, r]), x1) - max(np.int64(rb[1, r]), x0), 0)
    while i < i1 and j < j1:
        if ra[0, i] < rb[0, j]:
            i += 1
        elif rb[0, j] < ra[0, i]:
            j += 1
        else:
            if lut_a[np.int64(ra[3, i]) + 1] >= 0 and lut_b[np.int64(rb[3, j]) + 1] >= 0:
                lo = max(max(np.int64(ra[1, i]), np.int64(rb[1, j])), x0)
                hi = min(min(np.int64(ra[2, i]), np.int64(rb[2, j])), x1)
                if lo < hi:
                    count -= 2 * (hi - lo)
            if ra[2, i] <= rb[2, j]:
                i += 1
            else:
                j += 1
    return count


def _ring_edges(s, poly):
    """Every edge of slice ``s``'s rings ``poly(c, h)`` (each component's outer ring, then its
    holes), as two ``(e, 2)`` arrays of end points: ``np.concatenate`` of the rings and of their
    :func:`_next`, by one gather."""
    return _rings_and_next([np.asarray(poly(c, h), dtype=np.float64).reshape(-1, 2) for c in range(s.n)
                            for h in range(-1, len(s.holes[c]))])


def _rings_and_next(rs):
    """The rings ``rs`` (float64 ``(n_i, 2)`` arrays) concatenated, and each point's successor on its
    ring (a ring's last point is followed by its first), by one gather."""
    a = np.concatenate(rs) if rs else np.zeros((0, 2))
    lens = np.array([len(r) for r in rs], dtype=np.int64)
    ends = np.cumsum(lens)
    nxt = np.arange(1, len(a) + 1)
    full = lens > 0
    nxt[ends[full] - 1] = (ends - lens)[full]  # each ring's last point is followed by its first
    return a, a[nxt]


class _RingBlocks:
    """Per component of a slice, the edges of its rings (its outer ring, then its holes): their
    points and their successors, as two float64 arrays, of its polygons or of its crack rings once
    it is crack-only (:meth:`edges`).  The driver's crack-only components only grow within a build,
    so each component's crack block is made once or twice, not once per set of crack-only
    components.  The polygons' blocks are made for the whole slice at once (views of its edges,
    which :meth:`edges` gives where no component is crack-only)."""

    __slots__ = ("s", "a", "b", "poly_a", "poly_b", "whole", "crack")

    def __init__(self, s):
        self.s = s
        rs = [[np.asarray(r, dtype=np.float64).reshape(-1, 2) for r in [s.outer[c]] + [s.holes[c][h]
               for h in range(len(s.holes[c]))]] for c in range(s.n)]
        a, b = self.whole = _rings_and_next([r for rings in rs for r in rings])
        ends = list(accumulate(sum(len(r) for r in rings) for rings in rs))
        cuts = list(zip([0] + ends[:-1], ends))
        self.poly_a = [a[i:j] for i, j in cuts]
        self.poly_b = [b[i:j] for i, j in cuts]
        self.a, self.b = list(self.poly_a), list(self.poly_b)
        self.crack = set()

    def edges(self, crack):
        """:func:`_ring_edges` of the slice with the components ``crack`` on their crack rings and
        the others on their polygons: the same points and successors, concatenated per component
        (the same arrays, bit for bit; with no crack ring, the slice's edges as first made)."""
        s = self.s
        for c in self.crack.symmetric_difference(crack):
            if c in crack:
                rs = [np.asarray(r, dtype=np.float64).reshape(-1, 2)
                      for r in [s.crack_outer[c]] + [s.crack_holes[c][h] for h in range(len(s.holes[c]))]]
                # (each ring's successors: the ring from its second point on, then its first; the
                # block is copied into the slice's edges, so one ring is used as it is)
                self.a[c] = rs[0] if len(rs) == 1 else np.concatenate(rs)
                self.b[c] = np.concatenate([x for r in rs for x in (r[1:], r[:1])])
            else:
                self.a[c], self.b[c] = self.poly_a[c], self.poly_b[c]
        self.crack = set(crack)
        if not self.crack or not self.a:
            return self.whole
        return np.concatenate(self.a), np.concatenate(self.b)


def _ring_boxes(s):
    """Per component of slice ``s``, the box ``(lo, hi)`` (two ``(n, 2)`` arrays) of all its rings:
    its polygons and its crack rings in physical xy.  The crack rings' corners are integers and
    ``to_xy`` is increasing in each coordinate, so their box is that of their integer corners' box,
    converted (no crack ring is made), and that box is the corners of the component's pixel box: the
    same numbers as :func:`_ring_boxes_reference`.  The polygons' points are taken into those boxes
    in one compiled pass (:func:`_ring_boxes_kernel`); :func:`_ring_boxes_numpy` is the form it
    replaces (per ring, then per component, by ``reduceat``), kept for a slice with an empty ring."""
    if s.n == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    # a component's outer crack ring runs round its pixels' box, corner to corner, and its holes lie
    # inside: the box of its crack rings' corners is that of its pixels (s.objects), read off it
    corners = np.array([(sl[1].start, sl[0].start, sl[1].stop, sl[0].stop) for sl in s.objects], dtype=np.int64)
    # (both corners of every box mapped in one call, rows (x0, y0), (x1, y1) of each box in turn:
    # the map takes each point alone, so the same numbers as mapping the lower and upper corners apart)
    cxy = np.ascontiguousarray(s.crack_outer.to_xy(corners.reshape(-1, 2)), dtype=np.float64)
    rs, counts = [], []
    for c in range(s.n):
        outer, holes = np.asarray(s.outer[c], dtype=np.float64), s.holes[c]
        rs.append(outer)
        m = len(outer)
        for h in holes:
            rs.append(h)
            m += len(h)
        counts.append(m)
    if any(len(r) == 0 for r in rs):  # pragma: no cover - (a polygon has three points or more)
        return _ring_boxes_numpy(s)
    cat = np.ascontiguousarray(np.concatenate(rs), dtype=np.float64).reshape(-1, 2)
    return _ring_boxes_kernel(cat, np.array(counts, dtype=np.int64), cxy)


@njit(cache=True, **KERNEL_OPTIONS)
def _ring_boxes_kernel(cat, counts, cxy):  # pragma: no cover (compiled)
    """:func:`_ring_boxes`' boxes: component ``c``'s crack box, from ``cxy[2 c]`` to ``cxy[2 c + 1]``
    (physical xy), grown by its rings' points, the next ``counts[c]`` rows of ``cat``;
    ``np.minimum`` and ``np.maximum`` one by one (a NaN taken on as they take it; the order of a
    minimum of numbers does not change it)."""
    n = counts.shape[0]
    lo = np.empty((n, 2))
    hi = np.empty((n, 2))
    t = 0
    for c in range(n):
        lo0, lo1, hi0, hi1 = cxy[2 * c, 0], cxy[2 * c, 1], cxy[2 * c + 1, 0], cxy[2 * c + 1, 1]
        for u in range(t, t + counts[c]):
            x, y = cat[u, 0], cat[u, 1]
            lo0 = _min_nan(lo0, x)
            lo1 = _min_nan(lo1, y)
            hi0 = _max_nan(hi0, x)
            hi1 = _max_nan(hi1, y)
        t += counts[c]
        lo[c, 0], lo[c, 1], hi[c, 0], hi[c, 1] = lo0, lo1, hi0, hi1
    return lo, hi


def _ring_boxes_numpy(s):
    """:func:`_ring_boxes` by numpy's ``reduceat``, per ring and then per component (the form the
    compiled pass replaced; the tests compare the two)."""
    def per_component(rings_of):
        per = [rings_of(c) for c in range(s.n)]  # (each component's rings, asked for once)
        rs = [r for rings in per for r in rings]
        sizes = [len(r) for r in rs]
        owner = np.repeat(np.arange(s.n), [len(rings) for rings in per])
        cat = np.concatenate(rs)
        at = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        lo, hi = np.minimum.reduceat(cat, at, axis=0), np.maximum.reduceat(cat, at, axis=0)
        # (rings in component order: each component's first ring starts its run of rows)
        first = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=s.n))[:-1]]).astype(np.int64)
        return np.minimum.reduceat(lo, first, axis=0), np.maximum.reduceat(hi, first, axis=0)

    if s.n == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    corners = np.array([(sl[1].start, sl[0].start, sl[1].stop, sl[0].stop) for sl in s.objects], dtype=np.int64)
    clo, chi = np.ascontiguousarray(corners[:, :2]), np.ascontiguousarray(corners[:, 2:])
    plo, phi = per_component(lambda c: [np.asarray(s.outer[c], dtype=np.float64)] + list(s.holes[c]))
    to_xy = s.crack_outer.to_xy
    return np.minimum(to_xy(clo), plo), np.maximum(to_xy(chi), phi)


@njit(cache=True, **KERNEL_OPTIONS)
def _boxes_meeting(blo, bhi, comps):  # pragma: no cover (compiled)
    """The boxes ``(blo[i], bhi[i])`` that meet the box of the boxes ``comps`` (one at least):
    ``np.flatnonzero((blo <= hi).all(axis=1) & (bhi >= lo).all(axis=1))`` with ``lo, hi`` the
    ``min``/``max`` over ``comps`` (a NaN taken on as numpy's minimum and maximum take it)."""
    lo0, lo1, hi0, hi1 = blo[comps[0], 0], blo[comps[0], 1], bhi[comps[0], 0], bhi[comps[0], 1]
    for t in range(1, comps.shape[0]):
        c = comps[t]
        lo0 = _min_nan(lo0, blo[c, 0])
        lo1 = _min_nan(lo1, blo[c, 1])
        hi0 = _max_nan(hi0, bhi[c, 0])
        hi1 = _max_nan(hi1, bhi[c, 1])
    out = np.empty(blo.shape[0], np.int64)
    m = 0
    for i in range(blo.shape[0]):
        if blo[i, 0] <= hi0 and blo[i, 1] <= hi1 and bhi[i, 0] >= lo0 and bhi[i, 1] >= lo1:
            out[m] = i
            m += 1
    return out[:m]


@njit(cache=True, inline="always", **KERNEL_OPTIONS)
def _min_nan(a, b):  # pragma: no cover (compiled)
    return a if (a <= b or a != a) else b


@njit(cache=True, inline="always", **KERNEL_OPTIONS)
def _max_nan(a, b):  # pragma: no cover (compiled)
    return a if (a >= b or a != a) else b


def _ring_boxes_reference(s):
    """:func:`_ring_boxes` from every ring made in physical xy (the tests' reference)."""
    rs = [np.concatenate([s.crack_outer.made(c), s.outer[c]] + s.crack_holes.made(c) + list(s.holes[c]))
          for c in range(s.n)]
    return np.array([r.min(axis=0) for r in rs]), np.array([r.max(axis=0) for r in rs])


def _has_speck(slices, k, ga, gb) -> bool:
    """Whether a group has a component of at most ``_DENSE_FAILED_SPECK`` pixels (noise on a nearly
    horizontal face), the joins that :func:`_build_bridges` densifies and tries again."""
    for kk, comps in ((k, ga), (k + 1, gb)):
        s = slices[kk]
        for c in comps:
            sl = s.objects[c]
            if (sl[0].stop - sl[0].start) * (sl[1].stop - sl[1].start) <= _DENSE_FAILED_SPECK or \
                    np.count_nonzero(s.labels[sl] == c + 1) <= _DENSE_FAILED_SPECK:
                return True
    return False


def _scratch_released(fn):
    """``fn``, after which the calling thread's kept scratch buffers of the least-area bands and of
    the sections' signed distances (up to some 16 MiB, reused from join to join) are let go: the
    mesh's later steps, where its peak memory lies, do not hold them."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        finally:
            from . import sections
            from .bands import optimal

            optimal.release_buffers()
            sections.release_buffers()
    return run


class _PlaneSegments:
    """The bridges' segments taken in one plane by the joins that passed, in the order they passed:
    their end points in two growing ``(n, 2)`` float64 arrays (the test of a new segment reads
    them as they are, not made again from a list each time) and, per segment, the place of its
    join among the passed joins, so that a pass that repeats the previous pass's first joins keeps
    exactly their segments (:meth:`keep`)."""

    __slots__ = ("a", "b", "n", "owner")

    def __init__(self):
        self.a, self.b, self.n, self.owner = np.empty((8, 2)), np.empty((8, 2)), 0, []

    def add(self, p, q, place):
        if self.n == len(self.a):
            self.a = np.concatenate([self.a, np.empty_like(self.a)])
            self.b = np.concatenate([self.b, np.empty_like(self.b)])
        self.a[self.n], self.b[self.n] = p, q
        self.n += 1
        self.owner.append(place)

    def crosses(self, p, q) -> bool:
        """Whether the segment ``p q`` shares a point with one taken (:func:`segments_cross`)."""
        return self.n > 0 and bool(segments_cross(p, q, self.a[:self.n], self.b[:self.n]).any())

    def keep(self, count):
        """Keep the segments of the first ``count`` passed joins only (their places are increasing).
        (A plane whose last segment's join is among them keeps all: nothing to look up.)"""
        if not self.owner or self.owner[-1] < count:
            return
        self.n = bisect_left(self.owner, count)
        del self.owner[self.n:]


@_scratch_released
def _build_bridges(joins, slices, zs, crack_only, triangulation, caps, grid, has_above, has_below, cache=None,
                   band_guard=None, polygon="mlp", sections=True, densify=None):
    """Decide and build every bridged join; the ones that cannot be built become exact joins
    (``joins`` and ``crack_only`` are updated in place).  Returns ``{(k, ga, gb): _Bridged}``.

    ``cache`` (a dict kept by the caller across rebuilds of one mesh with the same ``joins`` list)
    holds every join built so far, keyed by all that its result depends on: the join (its index),
    the crack-only components of its two planes whose rings may meet the box of its own rings in
    that plane (they decide its rings and the edges near its bridges, which lie in that box) and
    which of its lids are lidded from both sides.  A rebuild after a crossing
    fallback then builds only the joins whose planes or lids changed.  ``band_guard``: see
    :func:`_bridge_join`.

    A join that cannot be bridged whole gets intermediate sections in its gap
    (:func:`contourmesh.sections.sectioned_join`, with ``polygon`` the sections' polygon method)
    before it becomes exact; not on the contours route (``band_guard`` given), nor with
    ``sections=False``.

    ``densify(comps, trial=False)`` (the mesher's, where given): a fork or merge with a speck
    (:func:`_has_speck`) that fails is built once more with its components' polygons densified
    (``densify(comps, trial=True)``: the rings, nothing changed; without sections, which it had);
    where that builds within the area limit the polygons are densified (``densify(comps)``) and
    the pass restarts, so that the other joins of those slices are built from the same rings.
    Around single pixels left on a terrace's edge the least-area band fans a polygon's long
    straight edges across them and folds; with a vertex every pixel its rungs stay local
    (fandisk rotated #1 at 256: 9 exact joins -> 3)."""
    from collections import defaultdict

    from .bands.bridges import OverlapFree, keyhole_uncovered
    from .sections import JoinMemory

    by_slice = defaultdict(set)
    for kk, c in crack_only:
        by_slice[kk].add(c)

    def poly(kk, c, h):
        s = slices[kk]
        if c in by_slice[kk] and c not in getattr(s, "own", ()):
            return s.crack_outer[c] if h < 0 else s.crack_holes[c][h]
        return s.outer[c] if h < 0 else s.holes[c][h]

    def sig(kk):
        return tuple(sorted(by_slice[kk]))

    boxes = {}  # slice -> (lo, hi): per component a box holding all its rings, as polygons and as crack rings
    near = {}  # (slice, components) -> the components of that slice whose boxes meet theirs

    near_seen = {}  # (slice, components) -> (size of by_slice[slice], near_sig): by_slice only grows

    def near_sig(kk, comps):
        """The crack-only components of slice kk whose rings may meet the box of ``comps``' rings:
        the only ones whose edges a bridge between ``comps``' rings can meet."""
        key = (kk, tuple(comps))
        seen = near_seen.get(key)
        if seen is not None and seen[0] == len(by_slice[kk]):
            return seen[1]
        got = _near_sig(kk, key)
        near_seen[key] = (len(by_slice[kk]), got)
        return got

    def near_dense(kk, comps):
        """The densified components of slice kk near ``comps`` (as :func:`near_sig`), each with how
        many times it was densified: a join's bridges and band read only those rings."""
        gen = slices[kk].dense_gen
        if not gen:
            return ()
        key = (kk, tuple(comps))
        return tuple(sorted((c, gen[c]) for c in _near(kk, key) if c in gen))

    def _near_sig(kk, key):
        if not by_slice[kk]:
            # (no crack-only component in the slice: none can be near, whatever the boxes; they are
            # not made for it, most slices of a volume with few exact joins)
            if not key[1]:
                raise ValueError("a join without components on one side")
            return ()
        return tuple(sorted(_near(kk, key) & by_slice[kk]))

    def _near(kk, key):
        """The components of slice kk whose boxes meet the box of ``key[1]``'s (made once)."""
        comps = key[1]
        if key not in near:
            if kk not in boxes:
                boxes[kk] = _ring_boxes(slices[kk])
            blo, bhi = boxes[kk]
            if not comps:
                raise ValueError("a join without components on one side")
            near[key] = frozenset(_boxes_meeting(blo, bhi, np.array(comps, dtype=np.int64)).tolist())
        return near[key]

    edge_cache = {}
    ox, oy, dx, dy = grid

    # (a sectioned join asked for again after a restart, with all it reads the same, is not built again)
    sectioned_join = JoinMemory().join

    @functools.lru_cache(maxsize=None)
    def section_ops():
        return _section_ops()  # (made once per build: the same pieces every time)

    def uncovered(other, comps):
        """A keyhole must run where the other slice does not cover its component: there the
        material ends between the slices and the band may come down to the keyhole."""
        return keyhole_uncovered(slices[other].labels, comps, (ox, oy, dx, dy))

    def waypoints(plane, other, comps):
        """Polyline keyholes pass through the pixel centres near their component (its pixels and
        their 8-neighbours: a polygon may enclose a notch one pixel deep) outside its overlap with
        the other slice's components ``comps`` (see :func:`_bridge_join`).  A straight keyhole
        keeps out of every pixel those components cover (``uncovered``); a polyline one only out
        of the overlap, so it may cut through a notch the other slice covers."""
        s, lab, n_other = slices[plane], slices[other].labels, slices[other].n

        def points_of(c):
            sl = s.objects[c]
            y0, x0 = max(sl[0].start - 1, 0), max(sl[1].start - 1, 0)
            box = np.s_[y0: sl[0].stop + 1, x0: sl[1].stop + 1]
            own = s.labels[box] == c + 1
            over = own & label_mask(lab[box], n_other, comps)
            j, i = np.nonzero(_dilated_square(own) & ~over)
            pts = np.c_[ox + (i + x0) * dx, oy + (j + y0) * dy]
            # (samples taken to their nearest pixel with halves up, as in uncovered)
            return pts, OverlapFree(over, x0, y0, (ox, oy, dx, dy))

        return max(dx, dy), points_of

    ring_blocks = {}  # slice -> _RingBlocks (until its polygons are densified)

    def edges_of(kk):
        key = (kk, sig(kk))
        if key not in edge_cache:
            # (_ring_edges with poly: the crack-only components not in s.own take their crack rings)
            s = slices[kk]
            if kk not in ring_blocks:
                ring_blocks[kk] = _RingBlocks(s)
            own = getattr(s, "own", ())
            edge_cache[key] = ring_blocks[kk].edges({c for c in key[1] if c not in own})
        return edge_cache[key]

    lids = defaultdict(int)
    for k, kind, data in joins:
        if kind == "bridge" and data[2] is not None:
            for a, h in data[2][1]:
                lids[k, a, h] += 1
            for b, h in data[2][2]:
                lids[k + 1, b, h] += 1
    double = {key for key, n in lids.items() if n > 1}
    cache = {} if cache is None else cache
    # a pass that restarts after a join fell back repeats the previous one up to where something
    # changed: while it does (the same joins passed with the same keys, in order), each join meets
    # the same bridges in its planes as before and passes their test again, so the test is skipped,
    # and a join away from the slices of the join that fell back keeps its key (see near_sig)
    changed = set()  # the slices whose crack rings changed since the previous pass
    dense_tried = set()  # the joins whose components were densified (tried once more)

    def dense_trial(idx, k, ga, gb, plan, rings):
        """Whether the join builds (within its area limit) with the components' polygons ``rings``
        (``{(slice, component): [outer, holes...]}``): then the mesher densifies them."""
        def poly2(kk, c, h):
            got = rings.get((kk, c))
            return got[h + 1] if got is not None else poly(kk, c, h)

        def edges2(kk):
            if not any(kk == k_ for k_, _c in rings):
                return edges_of(kk)
            return _ring_edges(slices[kk], lambda c, h: poly2(kk, c, h))

        got = _bridge_join(k, ga, gb, plan, poly2, zs, edges2, uncovered, triangulation, caps, double, waypoints,
                           band_guard)
        exact = cache.get(("exact area", k, tuple(ga), tuple(gb)))
        if exact is None:
            exact = _exact_area(slices, zs, k, ga, gb, dx * dy, cache.setdefault(("crack perimeters",), {}))
        return got is not None and float(triangle_areas(got.V, got.F).sum()) <= _BRIDGED_AREA_LIMIT * exact
    bridge_ids = [i for i, (_k, kind, _d) in enumerate(joins) if kind == "bridge"]  # (kept up to date below)
    taken = defaultdict(_PlaneSegments)
    out = {}
    passed = []
    while True:
        restart = False
        replay = True
        # the joins that the loop below would replay as they were (the previous pass's, in order, up
        # to the first on a slice whose crack rings changed) keep what they recorded: their bridges'
        # segments (the first ones of each plane) and their results; the loop starts after them
        passed_before = passed
        kept = 0
        for (idx, _key), at in zip(passed_before, bridge_ids):
            k = joins[idx][0]
            if idx != at or k in changed or k + 1 in changed:
                break
            kept += 1
        for idx, _key in passed_before[kept:]:
            k, _kind, (ga, gb, _plan) = joins[idx]
            del out[k, tuple(ga), tuple(gb)]
        for segs in taken.values():
            segs.keep(kept)
        passed = passed_before[:kept]
        start = passed[-1][0] + 1 if passed else 0
        # (the bridged joins from start on: bridge_ids lists them in order; a copy, since the loop
        # takes a join that falls back out of it and leaves the loop)
        for idx in bridge_ids[bisect_left(bridge_ids, start):]:
            k, _kind, data = joins[idx]
            ga, gb, plan = data
            # while the pass repeats the previous one, a join whose two slices kept their crack rings
            # has the same key as then (near_sig reads only those slices' crack rings)
            prev = passed_before[len(passed)] if replay and len(passed) < len(passed_before) else None
            if prev is not None and prev[0] == idx and k not in changed and k + 1 not in changed:
                key = prev[1]
            else:
                dbl = () if plan is None else \
                    tuple((k, a, h) in double for a, h in plan[1]) + tuple((k + 1, b, h) in double for b, h in plan[2])
                # (whether the join may try intermediate sections is part of the key: a join densified in
                # one build does not try them there, and may in a later build; see sectioned below)
                sectioned = sections and (_DENSE_FAILED_SECTIONS or idx not in dense_tried)
                key = (idx, near_sig(k, ga), near_sig(k + 1, gb), dbl, near_dense(k, ga), near_dense(k + 1, gb),
                       sectioned)
                # a keyhole lies in its component's plane, inside the component: a flat cap there (the
                # component ends on the other side) would meet the fold along it
                if plan is not None and caps == "flat" and (any((k, a) not in has_below for a, _ in plan[3])
                                                            or any((k + 1, b) not in has_above for b, _ in plan[4])):
                    cache[key] = None
                if key not in cache:
                    cache[key] = None if plan is None else _bridge_join(k, ga, gb, plan, poly, zs, edges_of, uncovered,
                                                                        triangulation, caps, double, waypoints, band_guard)
                    got = cache[key]
                    # a band can fan across the slice (from a polyline keyhole, or from the tips of a C
                    # whose mouth closes into a ring): such a join folds over itself, and may not have
                    # much more area than the voxel-exact join it replaces
                    # (the same for every pass and build: crack rings and labels do not change)
                    exact_key = ("exact area", k, tuple(ga), tuple(gb))
                    if exact_key not in cache:
                        cache[exact_key] = _exact_area(slices, zs, k, ga, gb, dx * dy,
                                                       cache.setdefault(("crack perimeters",), {}))
                    exact = cache[exact_key]
                    limit = _BRIDGED_AREA_LIMIT * exact
                    area = float(triangle_areas(got.V, got.F).sum()) if got is not None else None
                    # (a join tried again with densified polygons does not try sections again: key[-1])
                    sectioned = key[-1]
                    if got is not None and area > limit:
                        cache[key] = None
                    elif got is not None and area > _SECTION_TRIAL * exact and band_guard is None and sectioned:
                        # more area than the exact join: a fold is likely; intermediate sections may
                        # follow the surface with less, and the join takes whichever has less area
                        alt = sectioned_join(section_ops(), k, ga, gb, slices, zs, poly, edges_of, double, caps,
                                             triangulation, polygon, grid, max_area=float(np.nextafter(area, -np.inf)))
                        if alt is not None and float(triangle_areas(alt.V, alt.F).sum()) < area:
                            cache[key] = alt
                    if cache[key] is None and band_guard is None and sectioned:
                        # split the gap by intermediate sections; held to the same area limit
                        got = sectioned_join(section_ops(), k, ga, gb, slices, zs, poly, edges_of, double, caps, triangulation,
                                             polygon, grid, topology_first=plan is None, max_area=limit)
                        if got is not None and float(triangle_areas(got.V, got.F).sum()) <= limit:
                            cache[key] = got
            b = cache[key]
            replay = prev is not None and prev[0] == idx and prev[1] == key
            if b is not None and not replay:
                for plane, p, q in b.segments:
                    if taken[plane].crosses(p, q):
                        b = None
                        break
            if b is None and densify is not None and plan is not None and cache[key] is None and \
                    idx not in dense_tried and _has_speck(slices, k, ga, gb):
                # a fork or merge that failed gets a vertex every pixel on its components' polygons
                # and one more try (see _densify_failed); the joins of its slices are built again
                dense_tried.add(idx)
                comps = [(k, a) for a in ga if a not in by_slice[k] and a not in slices[k].dense_gen] + \
                    [(k + 1, c) for c in gb if c not in by_slice[k + 1] and c not in slices[k + 1].dense_gen]
                if comps and dense_trial(idx, k, ga, gb, plan, densify(comps, trial=True)) and densify(comps):
                    for kk in (k, k + 1):
                        for ek in [ek for ek in edge_cache if ek[0] == kk]:
                            del edge_cache[ek]
                        ring_blocks.pop(kk, None)
                    changed = {k, k + 1}
                    restart = True
                    break
            if b is None:
                joins[idx] = (k, "exact", (ga, gb))
                bridge_ids.remove(idx)
                crack_only.update((k, a) for a in ga)
                crack_only.update((k + 1, c) for c in gb)
                by_slice[k].update(ga)
                by_slice[k + 1].update(gb)
                changed = {k, k + 1}
                restart = True
                break
            for plane, p, q in b.segments:
                taken[plane].add(p, q, len(passed))
            out[k, tuple(ga), tuple(gb)] = b
            passed.append((idx, key))
        if not restart:
            return out


def _section_ops():
    """The pieces :func:`contourmesh.sections.sectioned_join` builds a sectioned join from (passed
    in, so that ``sections`` does not import this module back)."""
    from types import SimpleNamespace

    return SimpleNamespace(Slice=_Slice, simple_join=_simple_join, bridge_plan=_bridge_plan,
                           bridge_join=_bridge_join, band_faces=_band_faces, Bridged=_Bridged)


def _tagged_sides(S, T, out):
    """:func:`_join_units`' side and tag of each face in one int32, ``S + 4 * (T + 1)`` (``S`` the
    int8 sides, 0 to 2; ``T`` the int32 tags, -1 and up), written into ``out`` (int32, as long) in
    one compiled pass and returned: the same numbers as ``S.astype(np.int32) + 4 * (T + 1)``,
    without its three whole-mesh temporaries (1.2 -> 0.05 ms on the lobster's 0.38 M faces, once
    per build).  ``out`` is the caller's numpy array: the repair resizes its buffer in place
    (:func:`contourmesh.repair._kept_and_added`), which an array made in the kernel does not allow."""
    _tagged_sides_into(S, T, out)
    return out


@njit(cache=True, **KERNEL_OPTIONS)
def _tagged_sides_into(S, T, out):  # pragma: no cover (compiled)
    """:func:`_tagged_sides`' pass."""
    for i in range(S.shape[0]):
        out[i] = np.int32(S[i]) + np.int32(4) * (T[i] + np.int32(1))
