"""The front door: every route from an input to a closed mesh is chosen here, and only here.

Four kinds of source, one typed entry point each, all returning a :class:`~contourmesh.types.Mesh`:

=====================  ==========================================================================
entry point            source and the keywords that apply to it
=====================  ==========================================================================
:func:`mesh_shape`     an analytic shape or a spec string (``"sphere:r=40"``): ``h``
:func:`mesh_stack`     a :class:`~contourmesh.types.ContourStack`: ``pixel, route``
:func:`mesh_volume`    a 3D array ``[z, y, x]``: ``spacing, z, axis, label, threshold, origin``
:func:`mesh_file`      a path: contour files take ``roi, pixel, route``; volume files take
                       ``spacing, z, axis, label, threshold, origin``
=====================  ==========================================================================

Every entry point also takes the method keywords ``polygon, triangulation, caps, refine`` and
``progress``.  :func:`mesh` looks at the source, then calls its entry point; a keyword that does
not apply to the source raises :class:`~contourmesh.errors.InapplicableOption` (a ``TypeError``)
that says which keyword and why, so no option is ever dropped silently.

The routes behind the entry points:

* **stack route** (:func:`contourmesh.surface.stack_to_mesh`): the paper's own path, for stacks
  with one contour per section (or nested outer/hole chains) of grid contours, and for
  real-valued single contours meshed as drawn (``polygon="none"``);
* **contours route** (:func:`contourmesh.drawn.mesh_drawn`, ``route="contours"``): the default
  for real-valued contour stacks (contour files): the drawn rings themselves are the mesh's
  sections, joined by the volume mesher's joins, which a raster at ``pixel`` decides;
* **raster route** (``route="raster"``, or ``polygon="mlp"``/``"dss"`` on real-valued rings): the
  stack is rasterized even-odd at ``pixel`` (:func:`contourmesh.rasterize.rasterize_stack`) and
  meshed as a volume;
* **volume route** (:func:`contourmesh.volumes.volume_to_mesh`): any binary volume, several
  contours per slice, holes and branching; its compiled fast path handles simple slices.  Grid
  contour stacks with several contours per section (not nested chains) take it too, with the
  grid points their contours bound as the volume (:func:`contourmesh.refine.stack_points`);
* **refined route** (``refine="band"``, or ``"band2"`` with twice the ring vertices; with
  ``caps="smooth"`` the ends follow the last sections' area profile on either mesher): the outer
  Jordan contour stack of the source is refined
  across slices (:func:`contourmesh.refine.refine_stack`) and meshed by the stack route, when
  every slice holds one contour (or one outer contour with holes that the stack route closes);
  otherwise (several contours, holes, branching) the volume mesher refines the polygons of its
  band joins and caps (``volume_to_mesh(refine="band")``, ``meta["route"] = "volume-refined"``).
  Drawn (real-valued) rings are refined on their raster at ``pixel`` (``meta["route"] =
  "raster-refined"``): the refinement keeps each vertex in its slice's digital band, so it needs a
  digital object.

Each route switch and fallback is logged on the ``contourmesh`` logger (``logging.DEBUG``).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from . import shapes as _shapes
from .bands.caps import CapError
from .digitize import gauss_volume, outer_jordan_stack
from .errors import (
    CrossingFacesError,
    InapplicableOption,
    OpenSurfaceError,
    RasterFallbackWarning,
    StackSurfaceError,
    ThinRegionError,
    warn_external,
)
from .intersect import _threads
from .io import check_file
from .io.contours import CONTOUR_SUFFIXES, is_contour_file, read_contours
from .io.volumes import VOLUME_SUFFIXES, read_image
from .measure import axis_wall_fraction
from .rasterize import rasterize_stack
from .refine import REFINERS, refine_stack, stack_points
from .surface import _nested_chains, stack_to_mesh
from .topology import topology
from .tracing import trace_contours
from .types import ContourStack, Mesh, Section, shoelace_area
from .volume_input import check_origin, check_spacing, check_volume_array, prepare_volume
from .volumes import volume_to_mesh

__all__ = ["mesh", "mesh_shape", "mesh_stack", "mesh_volume", "mesh_file", "source_kind", "is_file_source",
           "OPTIONS"]

log = logging.getLogger("contourmesh")

#: The keywords that apply to each kind of source, beyond the method keywords.
OPTIONS = {
    "shape": ("h",),
    "stack": ("pixel", "route", "bands"),
    "volume": ("spacing", "z", "axis", "label", "threshold", "origin"),
    "contour file": ("roi", "pixel", "route", "bands"),
    "volume file": ("spacing", "z", "axis", "label", "threshold", "origin"),
}
METHOD_OPTIONS = ("polygon", "triangulation", "caps", "refine", "progress")

_WHY = {
    ("shape", "spacing"): "an analytic shape is digitized on a cubic grid; use h= for its grid step",
    ("shape", "origin"): "an analytic shape carries its own placement; use center= on the shape",
    ("stack", "spacing"): "a ContourStack carries its own heights and pixel spacing",
    ("stack", "z"): "a ContourStack carries its own section heights",
    ("stack", "origin"): "a ContourStack carries its own origin",
    ("contour file", "spacing"): "contour files hold physical coordinates; use pixel= for the raster size",
    ("contour file", "origin"): "contour files hold physical coordinates",
    ("contour file", "z"): "contour files carry their own section heights",
    ("contour file", "label"): "label= and threshold= select voxels of a volume; use roi= to pick a structure",
    ("contour file", "threshold"): "label= and threshold= select voxels of a volume; use roi= to pick a structure",
    ("shape", "bands"): "bands= shapes the bands between drawn contour sections (contour files and ContourStacks)",
    ("volume", "bands"): "bands= shapes the bands between drawn contour sections (contour files and ContourStacks)",
    ("volume file", "bands"): "bands= shapes the bands between drawn contour sections (contour files and ContourStacks)",
    ("volume", "roi"): "roi= picks a structure of a contour file; use label= for a labelled volume",
    ("volume file", "roi"): "roi= picks a structure of a contour file; use label= for a labelled volume",
    ("volume", "pixel"): "pixel= is the raster size for contour files; a volume is already voxels",
    ("volume file", "pixel"): "pixel= is the raster size for contour files; a volume is already voxels",
    ("volume", "route"): "route= chooses how a contour stack is meshed; a volume is meshed by the volume mesher",
    ("volume file", "route"): "route= chooses how a contour stack is meshed; a volume is meshed by the volume mesher",
    ("shape", "route"): "route= chooses how a contour stack is meshed; an analytic shape has its own route",
    ("volume", "h"): "h= is the grid step for analytic shapes; use spacing= for a volume",
    ("volume file", "h"): "h= is the grid step for analytic shapes; use spacing= for a volume",
}

_ARTICLE = {"shape": "an analytic shape", "stack": "a ContourStack", "volume": "an array",
            "contour file": "a contour file", "volume file": "a volume file"}


def is_file_source(source) -> bool:
    """Whether ``source`` names a file: a ``Path``, or a string that names an existing file or folder
    or ends with a suffix contourmesh reads (so a missing file gives FileNotFoundError, not a
    shape-spec parse error)."""
    if isinstance(source, Path):
        return True
    if not isinstance(source, str):
        return False
    if source.lower().endswith(VOLUME_SUFFIXES + CONTOUR_SUFFIXES):
        return True
    try:
        return Path(source).expanduser().exists()
    except (OSError, ValueError):
        return False


def source_kind(source) -> str:
    """``"shape"``, ``"stack"``, ``"volume"``, ``"contour file"`` or ``"volume file"``.

    Raises
    ------
    TypeError
        For anything else.
    """
    if isinstance(source, (_shapes.Shape)):
        return "shape"
    if isinstance(source, ContourStack):
        return "stack"
    if isinstance(source, np.ndarray):
        return "volume"
    if is_file_source(source):
        p = Path(source).expanduser()
        return "contour file" if p.is_file() and is_contour_file(p) else "volume file"
    if isinstance(source, str):
        return "shape"
    raise TypeError(
        f"cannot mesh a {type(source).__name__}: expected a shape (contourmesh.shapes), a shape spec "
        "string such as 'sphere:r=40', a file path, a ContourStack or a 3D numpy array"
    )


def _refuse_inapplicable(kind: str, given: dict) -> None:
    allowed = set(OPTIONS[kind]) | set(METHOD_OPTIONS)
    for key in given:
        if key not in allowed:
            why = _WHY.get((kind, key))
            if why is None:
                why = f"{_ARTICLE[kind]} takes {', '.join(k + '=' for k in OPTIONS[kind])}"
            known = set(METHOD_OPTIONS).union(*OPTIONS.values())
            if key not in known:
                raise TypeError(f"mesh() got an unexpected keyword {key}=; expected one of "
                                f"{', '.join(sorted(k + '=' for k in known))}")
            raise InapplicableOption(f"{key}= does not apply to {_ARTICLE[kind]}: {why}")


def mesh(source, **options) -> Mesh:
    """The mesh source of contourmesh: ``source -> Mesh``, closed and outward-oriented.

    Looks at ``source`` and calls :func:`mesh_shape`, :func:`mesh_stack`, :func:`mesh_volume` or
    :func:`mesh_file` with ``options``.  See those functions for the keywords each takes.

    Parameters
    ----------
    source : Shape, str, Path, ContourStack or numpy.ndarray
        An analytic shape (``contourmesh.shapes.Sphere(40, center=(0.3, 0.1, 0.2))``), a shape spec
        string (``"sphere:r=40"``, ``"torus:R=30,r=9"``), a file (volumes: ``.npy .npz .tif .nii[.gz]
        .nrrd .vol .inr[.gz]``, DICOM-SEG and DICOM image ``.dcm``, a folder of DICOM slices; contours:
        ``.json``, DICOM RTSTRUCT ``.dcm``), a ContourStack, or a 3D array
        indexed ``[z, y, x]`` (binary, or labels with ``label=`` / ``threshold=``).
    **options
        ``polygon`` ({"mlp", "dss", "none"}; default ``"mlp"``, and the drawn rings themselves for
        real-valued contour stacks), ``triangulation`` ({"wiederhold", "greedy", "optimal",
        "arclength"}; default ``"wiederhold"``, or ``"optimal"`` with ``refine="band"``), ``caps``
        ({"flat", "half", "smooth"}; ``"smooth"`` on the stack and contours routes, and with ``refine``
        on any route), ``refine`` ({None, "none", "band", "band2"}; ``"band2"``: twice the ring vertices,
        closer volumes), ``progress``, and the keywords of the source's entry point.

    Returns
    -------
    Mesh
        ``meta`` holds ``area_true`` when the source knows it, and ``route``.

    Raises
    ------
    InapplicableOption
        A keyword that does not apply to this kind of source (a ``TypeError``).

    Examples
    --------
    >>> import numpy as np, contourmesh
    >>> box = np.zeros((6, 6, 6), bool); box[1:5, 1:5, 1:5] = True
    >>> contourmesh.mesh(box, spacing=(2, 1, 1)).area
    90.0
    >>> contourmesh.mesh("sphere:r=5", spacing=(2, 1, 1))
    Traceback (most recent call last):
    ...
    contourmesh.errors.InapplicableOption: spacing= does not apply to an analytic shape: an analytic shape is digitized on a cubic grid; use h= for its grid step
    """
    kind = source_kind(source)
    given = {k: v for k, v in options.items() if v is not None}
    _refuse_inapplicable(kind, given)
    entry = {"shape": mesh_shape, "stack": mesh_stack, "volume": mesh_volume,
             "contour file": mesh_file, "volume file": mesh_file}[kind]
    return diagnose(entry(source, **given))


def diagnose(m: Mesh) -> Mesh:
    """The mesh with its diagnostics in ``meta``: ``axis_wall_fraction``, the share of the area on
    faces facing exactly +-x or +-y (voxel-like walls; see :func:`contourmesh.measure.axis_wall_fraction`).
    The volume mesher's counts (``exact_joins``, ``intermediate_sections``, ``polygon_fallbacks``, ``crack_rings``,
    ``band_fallbacks``) are already there.  Every entry point's result goes through it."""
    return _with_meta(m, axis_wall_fraction=axis_wall_fraction(m.vertices, m.faces))


# ------------------------------------------------------------------------------------------------
# method keywords
# ------------------------------------------------------------------------------------------------
def _refine_method(refine) -> str | None:
    if refine in (None, "none"):
        return None
    if refine not in REFINERS:
        raise ValueError(f"unknown refine method {refine!r}; expected one of {list(REFINERS)}")
    return refine


def _refined(stack: ContourStack, *, polygon, triangulation, caps, refine) -> Mesh:
    one_each = all(len(s.contours) == 1 for s in stack.sections)
    if not one_each and _nested_chains(stack) is None:
        return _refined_volume(stack, polygon=polygon, triangulation=triangulation, caps=caps, refine=refine)
    log.debug("refined route: refine_stack(%r) then the stack mesher", refine)
    fine = refine_stack(stack, refine, polygon=polygon)
    try:
        m = stack_to_mesh(fine, polygon="none", triangulation=triangulation or "optimal", caps=caps,
                          crossings="raise", dome="profile")
    except (CapError, StackSurfaceError) as exc:
        if one_each and not isinstance(exc, CrossingFacesError):
            raise
        # an outer contour with holes whose refined rings do not close on the stack route, or
        # refined rings whose faces cross: the stack's digital object, by the volume mesher
        log.debug("refined stack route failed (%s); the volume mesher refines its polygons", exc)
        return _refined_volume(stack, polygon=polygon, triangulation=triangulation, caps=caps, refine=refine)
    return Mesh(m.vertices, m.faces, P=m.P, meta=dict(m.meta, polygon=polygon, refine=refine, route="refined"))


def _volume_caps(caps: str, why: str) -> str:
    """``caps`` for the volume mesher; ``"smooth"`` is refused there (it closes contour stacks only)."""
    if caps == "smooth":
        raise InapplicableOption(f"caps='smooth' does not apply here: {why}, and the volume mesher closes its ends "
                                 "with caps='flat' or caps='half' only (smooth ends are made on the stack route: "
                                 "one contour per section, grid contours or polygon='none'; and on the contours route "
                                 "of drawn rings)")
    return caps


def _refined_volume(stack: ContourStack, *, polygon, triangulation, caps, refine) -> Mesh:
    """A stack with several contours (or holes) in a section: its digital object (the grid points
    its contours bound, :func:`contourmesh.refine.stack_points`) meshed by the volume mesher, which
    refines its own polygons."""
    log.debug("refined route: several contours in a section; the volume mesher refines its polygons")
    pts, x0, y0, zidx, dz = stack_points(stack)
    dx, dy = (float(v) for v in stack.spacing)
    ox, oy = (float(v) for v in stack.origin)
    if dz is not None:  # sections on a regular lattice (gaps filled with empty slices)
        dzp = dz * max(dx, dy)
        origin = (ox + x0 * dx, oy + y0 * dy, float(stack.z[0]) - int(zidx[0]) * dzp)
        z = None
    else:  # unevenly spaced sections: one slice each at its own height
        z = _slice_heights(stack.z, int(zidx[0]), pts.shape[0])
        dzp = float(np.median(np.diff(stack.z)))
        origin = (ox + x0 * dx, oy + y0 * dy, 0.0)
    m = volume_to_mesh(pts, spacing=(dzp, dy, dx), z=z, origin=origin, polygon=polygon,
                       triangulation=triangulation or "optimal", caps=caps, refine=refine)
    meta = dict(stack.meta)
    meta.update(m.meta)
    meta.update(route="volume-refined")
    return Mesh(m.vertices, m.faces, P=m.P, meta=meta)


def _refined_raster(stack: ContourStack, pixel, *, polygon, triangulation, caps, refine, progress=False) -> Mesh:
    """Drawn (real-valued) rings with ``refine``: the refinement keeps each polygon vertex in its
    slice's digital band, so it needs a digital object; that is the rings' even-odd raster at
    ``pixel`` (as on the raster route), meshed by the volume mesher with its polygons refined."""
    log.debug("refined raster route: the drawn rings rasterized, refined by the volume mesher")
    return _raster_route(stack, pixel, polygon=polygon, triangulation=triangulation or "optimal", caps=caps,
                         refine=refine, progress=progress)


def _raster_route(stack: ContourStack, pixel, *, polygon, triangulation, caps, refine=None, progress=False) -> Mesh:
    """The stack's even-odd raster at ``pixel``, meshed by the volume mesher (route ``"raster"``, or
    ``"raster-refined"`` with ``refine``)."""
    r = rasterize_stack(stack, pixel)
    m = volume_to_mesh(r.volume, **r.mesh_kwargs, polygon=polygon, triangulation=triangulation, caps=caps,
                       refine=refine, progress=progress)
    meta = dict(m.meta)
    meta.update(stack.meta)  # the stack's source, roi and units win over the volume mesher's
    meta.update(route="raster" if refine is None else "raster-refined", pixel=r.spacing[0])
    return Mesh(m.vertices, m.faces, P=m.P, meta=meta)


def _with_meta(m: Mesh, **meta) -> Mesh:
    return Mesh(m.vertices, m.faces, P=m.P, meta=dict(m.meta, **meta))


# ------------------------------------------------------------------------------------------------
# typed entry points
# ------------------------------------------------------------------------------------------------
def mesh_shape(shape, *, h: float = 1.0, polygon: str = "mlp", triangulation: str | None = None,
               caps: str = "flat", refine: str | None = None, progress: bool = False) -> Mesh:
    """Mesh an analytic shape digitized on the grid ``h * Z^3`` (slices at ``z = k h``).

    A shape whose slices each hold one contour (or nested outer/hole chains, like a torus lying
    flat) is meshed as in the paper, from its outer Jordan contour stack; any other shape (a
    standing torus, a rotated shape) through its Gauss digitization by the volume mesher.

    Raises
    ------
    ValueError
        A shape narrower than two grid steps in some direction: the grid cannot resolve it.
    """
    if isinstance(shape, str):
        shape = _shapes.parse_shape_spec(shape)
    if not isinstance(shape, _shapes.Shape):
        raise TypeError(f"mesh_shape needs a shape or a spec string; got {type(shape).__name__}")
    h = float(h)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"h must be a positive grid step; got {h}")
    lo, hi = shape._local_bounds()
    width = float(np.min(np.asarray(hi, float) - np.asarray(lo, float)))
    if width < 2 * h:
        raise ValueError(f"{shape.spec} is {width:g} wide in its narrowest direction, less than two grid "
                         f"steps (h={h:g}): the digitization cannot resolve it; use a smaller h")
    refine = _refine_method(refine)
    stack = outer_jordan_stack(shape, h=h)
    if refine is not None:
        return _refined(stack, polygon=polygon, triangulation=triangulation, caps=caps, refine=refine)
    triangulation = triangulation or "wiederhold"
    if all(len(s.contours) == 1 for s in stack.sections) or _nested_chains(stack) is not None:
        return _with_meta(stack_to_mesh(stack, polygon=polygon, triangulation=triangulation, caps=caps),
                          route="stack")
    log.debug("%s: several contours in a slice; meshing its Gauss digitization", shape.spec)
    _volume_caps(caps, f"{shape.spec} has several contours in a slice, so it is meshed by the volume mesher")
    vol, org = gauss_volume(shape, h=h)
    m = volume_to_mesh(vol, polygon=polygon, triangulation=triangulation, caps=caps, spacing=(h, h, h),
                       origin=org, progress=progress)
    meta = dict(stack.meta)
    meta.update(m.meta)
    meta["route"] = "volume"
    return Mesh(m.vertices, m.faces, P=m.P, meta=meta)


def mesh_stack(stack: ContourStack, *, pixel: float | None = None, polygon: str | None = None,
               triangulation: str | None = None, caps: str = "flat", refine: str | None = None,
               route: str | None = None, bands: str | None = None, progress: bool = False) -> Mesh:
    """Mesh a contour stack, choosing the route by what the stack holds.

    * Grid contours (integer points): one contour per section, or nested outer/hole chains (a torus
      lying flat), goes to the stack route; other stacks with several contours per section go to
      the volume mesher, with the grid points the contours bound as the volume (route
      ``"volume"``).  ``polygon`` defaults to ``"mlp"``.
    * Real-valued rings (contour files), ``polygon`` unset or ``"none"``: the drawn rings are the
      data.  With one ring per section and ``polygon="none"``, the stack route
      triangulates them as drawn; otherwise (the default) the **contours route**
      (:func:`contourmesh.drawn.mesh_drawn`) meshes between the drawn rings, with several rings
      per section, holes, forks and merges; a raster at ``pixel`` (default: the median point
      spacing, at most 1) decides only which ring joins which.  A stack route failure (a ring that
      touches itself) goes to the contours route with a
      :class:`~contourmesh.errors.RasterFallbackWarning` (and ``meta["stack_route_error"]``).
    * Real-valued rings with ``polygon="mlp"`` or ``"dss"``, or ``route="raster"``: the raster
      route: the stack is rasterized even-odd at ``pixel`` and meshed by the volume mesher at the
      sections' own heights with the polygons of the raster.

    ``route`` (``"contours"`` or ``"raster"``) picks the route instead; ``route="contours"`` with
    ``polygon="mlp"``/``"dss"`` is refused (the contours route meshes the drawn rings, not polygons
    of a raster), and so is ``caps="smooth"`` off the stack and contours routes
    (:class:`~contourmesh.errors.InapplicableOption`).  ``meta["route"]`` records the route taken
    and ``meta["pixel"]`` the raster size.

    ``bands`` (contours route only): ``"ruled"`` (the default) keeps every band between two drawn
    sections ruled, its volume within the frustum-trapezoid interval of the two rings' areas;
    ``"curved"`` bends the bands onto cubic rungs through the neighbouring sections
    (:mod:`contourmesh.bands.curved`), so that smooth solids converge to their true volume and
    area (at the price of volumes above the trapezoid rule on convex profiles).  Elsewhere
    ``bands="curved"`` is refused (:class:`~contourmesh.errors.InapplicableOption`).
    """
    if not isinstance(stack, ContourStack):
        raise TypeError(f"mesh_stack needs a ContourStack; got {type(stack).__name__}")
    if bands not in (None, "ruled", "curved"):
        raise ValueError(f"unknown bands {bands!r}; expected 'ruled' or 'curved'")
    curved = bands == "curved"
    if route not in (None, "contours", "raster"):
        raise ValueError(f"unknown route {route!r}; expected 'contours' or 'raster'")
    refine = _refine_method(refine)
    integer = all(np.asarray(c).dtype.kind in "iu" for s in stack.sections for c in s.contours)
    if refine is not None:
        if curved:
            raise InapplicableOption("bands='curved' does not apply with refine='band': curved bands are made "
                                     "between drawn rings on the contours route")
        if integer and pixel is not None:
            raise InapplicableOption("pixel= does not apply with refine='band' on grid contours: the refinement "
                                     "meshes the stack's own grid contours, without rasterizing")
        if route is not None and (integer or route != "raster"):
            raise InapplicableOption(f"route={route!r} does not apply with refine='band': " + (
                "grid contours are refined on their own grid" if integer else
                "drawn rings are refined on their raster (route='raster', or leave route unset)"))
        if not integer:
            return _refined_raster(stack, pixel, polygon=polygon or "mlp", triangulation=triangulation, caps=caps,
                                   refine=refine, progress=progress)
        return _refined(stack, polygon=polygon or "mlp", triangulation=triangulation, caps=caps, refine=refine)
    triangulation = triangulation or "wiederhold"
    one_each = all(len(s.contours) == 1 for s in stack.sections)
    if route == "contours" and polygon in ("mlp", "dss"):
        raise InapplicableOption(f"polygon={polygon!r} does not apply with route='contours': that route meshes "
                                 "the drawn rings themselves (use route='raster' for the polygons of a raster)")
    drawn = route == "contours" or (route is None and not integer and polygon in (None, "none"))
    if curved and not (drawn and (route == "contours" or polygon is None)):
        why = ("route='raster' meshes the polygons of a raster" if route == "raster" else
               "grid contours go to the stack or raster route" if integer else
               f"polygon={polygon!r} sends the drawn rings to the " + ("stack route" if polygon == "none" else "raster route")
               + " (leave polygon unset, or route='contours')")
        raise InapplicableOption(f"bands='curved' applies on the contours route only: {why}")
    fallback = None
    nested = integer and not one_each and route is None and _nested_chains(stack) is not None
    if route is None and integer and not one_each and not nested:
        # several grid contours per section (islands, forks, merges): the grid points they bound,
        # meshed by the volume mesher.  Not their raster: a grid contour runs through the centres
        # of its boundary pixels, so the even-odd raster at those centres would take the boundary
        # in or out by the rasterizer's edge rule, half a pixel off on every side
        return _grid_stack_volume(stack, polygon=polygon or "mlp", triangulation=triangulation, caps=caps,
                                  why=None, progress=progress)
    if route is None and (one_each or nested) and (integer or polygon == "none"):
        try:
            # crossings left: grid contours go to the volume mesher, drawn rings to the contours
            # route below (smooth ends exist on the stack route only: there they are warned about)
            return _with_meta(stack_to_mesh(stack, polygon=polygon or ("mlp" if integer else "none"),
                                            triangulation=triangulation, caps=caps,
                                            crossings="warn" if caps == "smooth" else "raise"),
                              route="stack")
        except CrossingFacesError as exc:
            if not integer:
                fallback = _stack_route_failed(stack, exc)
            else:
                return _grid_stack_volume(stack, polygon=polygon or "mlp", triangulation=triangulation, caps=caps,
                                          why=str(exc), progress=progress)
        except (CapError, StackSurfaceError) as exc:
            if integer and isinstance(exc, OpenSurfaceError):
                # a grid contour that touches itself (two of its pixels meet at a corner only): the
                # stack route cannot always split the pinch; the grid points it bounds are a
                # digital object all the same, and the volume mesher meshes it (with the warning)
                return _grid_stack_volume(stack, polygon=polygon or "mlp", triangulation=triangulation, caps=caps,
                                          why=str(exc), progress=progress)
            if integer:  # bad input (a point contour between sections, ...): said as it is
                raise
            # a real-valued ring that touches or crosses itself (a keyhole, a figure eight): the
            # contours route below resolves it through its raster; never silently
            fallback = _stack_route_failed(stack, exc)
    elif not drawn:
        why = (f"route={route!r}" if route else
               f"its contours are real-valued and polygon={polygon!r} (leave polygon unset to mesh the drawn rings)")
        _volume_caps(caps, f"this stack goes to the raster route: {why}")
        log.debug("raster route: %s", why)
    if drawn:
        from .drawn import mesh_drawn

        log.debug("contours route: the drawn rings, joined as a raster at pixel=%s decides", pixel)
        m = mesh_drawn(stack, pixel=pixel, triangulation=triangulation, caps=caps, bands=bands or "ruled",
                       progress=progress)
        if fallback is not None:
            m = _with_meta(m, stack_route_error=fallback)
        return m
    return _raster_route(stack, pixel, polygon=polygon or "mlp", triangulation=triangulation, caps=caps,
                         progress=progress)


def _stack_route_failed(stack: ContourStack, exc: Exception) -> str:
    """Warn that drawn rings go to the contours route after the stack route failed; returns the reason."""
    name = stack.meta.get("roi") or stack.meta.get("name") or "the stack"
    log.info("%s: stack route failed (%s); re-routing to the contours route", name, exc)
    warn_external(f"{name}: the contours cannot be meshed as drawn on the stack route ({exc}); meshed on "
                  "the contours route instead (its raster decides the joins; pixel= sets its size)",
                  RasterFallbackWarning)
    return str(exc)


def _grid_stack_volume(stack: ContourStack, *, polygon, triangulation, caps, why: str | None, progress=False) -> Mesh:
    """Grid contours with several contours per section (``why`` None), or whose stack-route mesh
    keeps crossing faces or is no closed surface (a contour touching itself; ``why`` says so, with a
    warning): their digital object (the grid points the contours bound,
    :func:`contourmesh.refine.stack_points`, one slice per section at the sections' own heights)
    meshed by the volume mesher."""
    from .refine import stack_points

    name = stack.meta.get("roi") or stack.meta.get("name") or "the stack"
    if why is None:
        _volume_caps(caps, "several grid contours per section are meshed by the volume mesher")
    else:
        _volume_caps(caps, "these grid contours are meshed by the volume mesher (the stack route fails on them)")
        warn_external(f"{name}: the stack route fails ({why}); meshed by the volume mesher from the "
                      "grid points the contours bound instead", RasterFallbackWarning)
    pts, x0, y0, zidx, _ = stack_points(stack, lattice=False)
    zs = np.asarray(stack.z, dtype=np.float64)
    step = float(np.median(np.diff(zs))) if len(zs) > 1 else float(stack.spacing[0])
    z = _slice_heights(zs, int(zidx[0]), pts.shape[0], step)
    dx, dy = (float(v) for v in stack.spacing)
    ox, oy = (float(v) for v in stack.origin)
    m = volume_to_mesh(pts, z=z, spacing=(step, dy, dx), origin=(ox + x0 * dx, oy + y0 * dy, 0.0), polygon=polygon,
                       triangulation=triangulation, caps=caps, progress=progress)
    meta = dict(stack.meta)
    meta.update(m.meta)
    meta.update(route="volume")
    if why is not None:
        meta.update(stack_route_error=why)
    return Mesh(m.vertices, m.faces, P=m.P, meta=meta)


def _slice_heights(zs, first: int, n: int, step: float | None = None) -> np.ndarray:
    """Heights of the ``n`` slices of :func:`contourmesh.refine.stack_points`'s array with
    ``lattice=False``: section ``k`` at slice ``first + k``; the margin's empty slices continue the
    sections' median spacing (``step``)."""
    zs = np.asarray(zs, dtype=np.float64)
    if step is None:
        step = float(np.median(np.diff(zs)))
    z = np.empty(n)
    z[first:first + len(zs)] = zs
    z[:first] = zs[0] - step * np.arange(first, 0, -1)
    z[first + len(zs):] = zs[-1] + step * np.arange(1, n - first - len(zs) + 1)
    return z


def _stack_of_mask(mask, zs, dy, dx, ox, oy) -> ContourStack | None:
    """The outer Jordan contour stack of a binary volume with one contour per slice (for refinement);
    None when some slice has several contours (or a hole), or a contour that bounds no area (a part
    one pixel wide: the stack mesher cannot close it, the volume mesher can), or when the voxels'
    surface is not one sphere (6/26 connectivity: slices overlapping in two places make a handle).
    The slices are traced without labelling (:func:`contourmesh.tracing.trace_contours` labels only
    slices with holes) and the sphere is checked by :func:`contourmesh.topology.topology` (compiled
    union-finds over the runs and one Euler pass: 4 ms instead of 40-60 ms at 128 voxels)."""
    sections = []
    rows = mask.any(axis=2)  # each slice's rows and columns that hold the object: slices are traced
    cols = mask.any(axis=1)  # within their bounding boxes (points outside count as empty: the same contours)
    for k in range(mask.shape[0]):
        if not rows[k].any():
            continue
        j0, j1 = int(np.argmax(rows[k])), len(rows[k]) - int(np.argmax(rows[k][::-1]))
        i0, i1 = int(np.argmax(cols[k])), len(cols[k]) - int(np.argmax(cols[k][::-1]))
        contours, _ = trace_contours(mask[k, j0:j1, i0:i1], x0=i0, y0=j0)
        if len(contours) != 1 or len(contours[0]) < 3 or shoelace_area(contours[0]) == 0:
            return None
        sections.append(Section(float(zs[k]), (contours[0],), (-1,)))
    topo = topology(mask)  # compiled; the same numbers as volumes.voxel_topology
    if topo["surfaces"] != 1 or topo["genus"] != 0:
        # one contour per slice, but the slices overlap in several places (a handle), or an empty
        # slice parts them: the stack route would make one sphere, the volume mesher keeps the topology
        return None
    return ContourStack(tuple(sections), spacing=(dx, dy), origin=(ox, oy), meta={"source": "volume"})


def mesh_volume(volume, *, spacing=None, z=None, axis: int | None = None, label=None, threshold=None,
                origin=None, polygon: str | None = "mlp", triangulation: str | None = None, caps: str = "flat",
                refine: str | None = None, progress: bool = False) -> Mesh:
    """Mesh a 3D array indexed ``[z, y, x]`` (any topology: holes, branching, cavities).

    Parameters
    ----------
    volume : numpy.ndarray
        Binary, or labels/values with ``label=`` (voxels equal to it) or ``threshold=`` (voxels
        above it).  A volume holding exactly two distinct values (0 and 255, say) is binary.
    spacing : (dz, dy, dx), default (1, 1, 1)
        Voxel size; areas come out in the square of its unit.
    z : array, optional
        Explicit, strictly increasing slice positions (uneven spacing).
    axis : {0, 1, 2}, default 0
        The slicing axis.
    origin : (x, y, z), default (0, 0, 0)
        Physical position of the centre of voxel ``[0, 0, 0]``.
    """
    threads = _threads()  # (a bad CONTOURMESH_THREADS is refused before any work)
    spacing = (1.0, 1.0, 1.0) if spacing is None else spacing
    origin = (0.0, 0.0, 0.0) if origin is None else origin
    axis = 0 if axis is None else axis
    polygon = polygon or "mlp"
    refine = _refine_method(refine)
    if refine is not None:
        mask, zs, (dy, dx), (ox, oy) = prepare_volume(volume, spacing=spacing, z=z, axis=axis, label=label,
                                                      threshold=threshold, origin=origin)
        stack = _stack_of_mask(mask, zs, dy, dx, ox, oy)
        if stack is not None:
            try:
                return _refined(stack, polygon=polygon, triangulation=triangulation, caps=caps, refine=refine)
            except (CapError, StackSurfaceError, ThinRegionError) as exc:
                # a slice whose seed polygon is a point or a segment (a part one pixel wide), or
                # rings the stack mesher cannot close: the volume mesher below can
                log.debug("refined stack route failed (%s); the volume mesher refines its polygons", exc)
        # several contours in a slice, holes, branching: the volume mesher refines its own polygons
        # (caps="smooth" included: its refined components' ends follow their area profile)
        log.debug("refined route: several contours in a slice; the volume mesher refines its polygons")
        m = volume_to_mesh(volume, spacing=spacing, z=z, axis=axis, label=label, threshold=threshold, origin=origin,
                           polygon=polygon, triangulation=triangulation or "optimal", caps=caps, refine=refine,
                           progress=progress)
        return _with_meta(m, route="volume-refined")
    _volume_caps(caps, "a volume is meshed by the volume mesher (with refine='band', a volume with one contour "
                 "per slice is meshed as its contour stack)")
    general = None
    if threads > 1:  # the general mesher in slabs on worker processes (contourmesh.parallel)
        from .parallel import mesh_in_slabs as general
    m = volume_to_mesh(volume, spacing=spacing, z=z, axis=axis, label=label, threshold=threshold, origin=origin,
                       polygon=polygon, triangulation=triangulation or "wiederhold", caps=caps, progress=progress,
                       general=general)
    return _with_meta(m, route="volume")


def mesh_file(path, *, roi=None, pixel=None, route=None, spacing=None, z=None, axis: int | None = None, label=None,
              threshold=None, origin=None, polygon: str | None = None, triangulation: str | None = None,
              caps: str = "flat", refine: str | None = None, bands: str | None = None, progress: bool = False) -> Mesh:
    """Mesh a file: a contour stack (``.json``, DICOM RTSTRUCT, contour ``.npz``) or a volume.

    Contour files take ``roi`` (the structure, by name or number), ``pixel`` (the raster size) and
    ``route`` (``"contours"``, the default for drawn rings, or ``"raster"``) and go through
    :func:`mesh_stack`.  Volume files take the keywords of :func:`mesh_volume`;
    they carry their own spacing and origin, which ``spacing=`` and ``origin=`` replace when
    given (``meta["spacing"]`` records the spacing used).  ``meta["source"]`` is the path.

    Files with a direction matrix (NIfTI's affine, NRRD's space directions, DICOM's orientation
    and positions) are meshed in their world coordinates, flips and oblique axes included, so the
    mesh overlays the image in a viewer of that frame (``meta["space"]`` names it: NIfTI
    ``"RAS"``, NRRD its ``space``, DICOM ``"LPS"``).  A segment of a 3D Slicer ``.seg.nrrd`` or of
    a DICOM-SEG can be picked by name: ``label="Liver"``.  A DICOM file is routed by its Modality
    (RTSTRUCT: contours; SEG and images: volumes); a folder is read as a DICOM image series, whose
    slices, when unevenly spaced, are meshed at their own positions.
    """

    if isinstance(path, (str, Path)) and Path(path).expanduser().is_dir():
        p, kind = Path(path).expanduser(), "volume file"
    else:
        p = check_file(path, "input")
        kind = "contour file" if is_contour_file(p) else "volume file"
    _refuse_inapplicable(kind, {k: v for k, v in dict(roi=roi, pixel=pixel, route=route, spacing=spacing, z=z, axis=axis,
                                                      label=label, threshold=threshold, origin=origin,
                                                      bands=bands).items()
                                if v is not None})
    if kind == "contour file":
        m = mesh_stack(read_contours(p, roi=roi), pixel=pixel, route=route, polygon=polygon,
                       triangulation=triangulation, caps=caps, refine=refine, bands=bands, progress=progress)
        return _with_meta(m, source=str(p))
    img = read_image(p, label=label, threshold=threshold)
    used = tuple(float(s) for s in spacing) if spacing is not None else img.spacing
    if spacing is not None:
        log.debug("%s: spacing=%s replaces the file's %s", p, used, img.spacing)
    world_origin = img.origin if origin is None else tuple(float(o) for o in origin)
    oriented = _oriented(img)
    if z is None and img.z is not None:  # unevenly spaced slices: mesh them at their positions
        if axis not in (None, 0):
            raise ValueError(f"{str(p)!r}: its slices are unevenly spaced, so they must be the slicing axis "
                             f"(axis=0); got axis={axis}")
        z = img.z if oriented else world_origin[2] + img.z
    m = mesh_volume(img.volume, spacing=used, z=z, axis=axis, origin=(0.0, 0.0, 0.0) if oriented else world_origin,
                    polygon=polygon, triangulation=triangulation, caps=caps, refine=refine, progress=progress)
    if oriented:
        m = _to_world(m, img.direction, world_origin, 0 if axis is None else axis)
        log.debug("%s: mesh placed in world coordinates by the image's direction matrix", p)
    meta = dict(source=str(p), spacing=used)
    if img.space:
        meta["space"] = img.space
    return _with_meta(m, **meta)


def _oriented(img) -> bool:
    """Whether an image's direction matrix is not the identity (its mesh must be placed in the world)."""
    return not np.allclose(img.direction, np.eye(3), rtol=0, atol=1e-12)


def _to_world(m: Mesh, direction: np.ndarray, origin, axis: int) -> Mesh:
    """Place a mesh made in the volume's own frame in world coordinates.

    The volume mesher's vertex ``(x, y, z)`` lies at index-times-spacing along the array axes
    ``order[2], order[1], order[0]`` (``order`` puts the slicing axis first); ``direction`` maps
    the voxel axes ``(i, j, k)`` = array axes ``(2, 1, 0)`` to the world.  A map that reverses
    orientation (a flip) also reverses the faces, so the mesh stays outward.
    """
    order = [axis] + [a for a in (0, 1, 2) if a != axis]
    to_arr = np.zeros((3, 3))
    for col, arr_axis in enumerate((order[2], order[1], order[0])):  # mesh x, y, z
        to_arr[2 - arr_axis, col] = 1.0  # voxel axis i, j, k = array axis 2, 1, 0
    linear = np.asarray(direction, dtype=np.float64) @ to_arr
    vertices = m.vertices @ linear.T + np.asarray(origin, dtype=np.float64)
    faces = m.faces[:, ::-1] if np.linalg.det(linear) < 0 else m.faces
    return Mesh(vertices, np.ascontiguousarray(faces), P=m.P, meta=dict(m.meta, world=True))


# ------------------------------------------------------------------------------------------------
# many objects at once: every label of a segmentation, every structure of a contour file
# ------------------------------------------------------------------------------------------------
def mesh_labels(volume, *, labels=None, spacing=None, origin=None, polygon: str = "mlp",
                triangulation: str | None = None, caps: str = "flat", refine: str | None = None,
                progress: bool = False):
    """Mesh every non-zero label of an integer label volume ``[z, y, x]``; yields ``(label, Mesh, bbox)``.

    One pass over the volume finds each label's bounding box (``scipy.ndimage.find_objects``);
    each label is then meshed from its own box only, padded by one voxel, so the work grows with
    the labels' sizes, not with their number times the volume.  ``bbox`` is
    ``(zmin, zmax, ymin, ymax, xmin, xmax)`` in voxel indices, inclusive.  ``labels`` restricts
    the labels meshed (default: all that occur).  Vertices are in the volume's frame
    (``spacing``, ``origin`` as for :func:`mesh_volume`).
    """
    from scipy import ndimage
    from tqdm.auto import tqdm


    vol = check_volume_array(volume)
    if vol.dtype.kind not in "iub":
        raise TypeError(f"mesh_labels needs an integer label volume; got dtype {vol.dtype} (use threshold= with "
                        "mesh_volume for a greyscale one)")
    if vol.dtype.kind == "i" and vol.min() < 0:
        raise ValueError("mesh_labels needs labels >= 0 (0 is the background)")
    sp = check_spacing((1.0, 1.0, 1.0) if spacing is None else spacing)
    org = check_origin((0.0, 0.0, 0.0) if origin is None else origin)
    boxes = ndimage.find_objects(vol.astype(np.int64, copy=False) if vol.dtype.kind == "b" else vol)
    present = [i + 1 for i, b in enumerate(boxes) if b is not None]
    wanted = present if labels is None else [int(v) for v in labels]
    missing = sorted(set(wanted) - set(present))
    if missing:
        raise ValueError(f"no voxel has label {missing[0]}" + (f" (nor {missing[1:]})" if len(missing) > 1 else ""))
    for lab in tqdm(wanted, desc="labels", disable=not progress, leave=False):
        box = boxes[lab - 1]
        lo = [max(s.start - 1, 0) for s in box]
        hi = [min(s.stop + 1, n) for s, n in zip(box, vol.shape)]
        crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == lab
        o = (org[0] + lo[2] * sp[2], org[1] + lo[1] * sp[1], org[2] + lo[0] * sp[0])
        m = mesh_volume(crop, spacing=tuple(sp), origin=o, polygon=polygon, triangulation=triangulation,
                        caps=caps, refine=refine)
        bbox = (box[0].start, box[0].stop - 1, box[1].start, box[1].stop - 1, box[2].start, box[2].stop - 1)
        yield lab, diagnose(_with_meta(m, label=lab)), bbox


def label_row(label, m: Mesh, bbox) -> dict:
    """One row of ``labels.csv``: the label's area, volume, vertex count and checks, and its box."""
    from .measure import exact_area_volume

    chk = m.checks()
    # area and volume summed independently of the faces' order (the same numbers when a label is
    # meshed in slabs and joined, or summed slab by slab without a mesh)
    area, volume = exact_area_volume(m.vertices, m.faces)
    row = {"label": label, "area": area, "volume": volume, "P": int(m.P), "faces": int(len(m.faces)),
           "genus": chk["genus"], "components": chk["components"], "watertight": chk["watertight"],
           "self_intersections": chk.get("self_intersections", "")}
    row.update(zip(("zmin", "zmax", "ymin", "ymax", "xmin", "xmax"), (int(v) for v in bbox)))
    return row


def mesh_file_labels(path, *, labels=None, spacing=None, origin=None, polygon: str = "mlp",
                     triangulation: str | None = None, caps: str = "flat", refine: str | None = None,
                     progress: bool = False):
    """:func:`mesh_labels` of a label-volume file, in the file's world coordinates (as :func:`mesh_file`)."""
    img = read_image(path)
    if img.z is not None:
        raise ValueError(f"{str(path)!r}: its slices are unevenly spaced; meshing every label at once needs even "
                         "spacing: mesh the labels one at a time (label=)")
    used = img.spacing if spacing is None else tuple(float(s) for s in spacing)
    world_origin = img.origin if origin is None else tuple(float(o) for o in origin)
    oriented = _oriented(img)
    for lab, m, bbox in mesh_labels(img.volume, labels=labels, spacing=used,
                                    origin=(0.0, 0.0, 0.0) if oriented else world_origin, polygon=polygon,
                                    triangulation=triangulation, caps=caps, refine=refine, progress=progress):
        if oriented:
            m = _to_world(m, img.direction, world_origin, 0)
        yield lab, _with_meta(m, source=str(path), spacing=used), bbox


def mesh_file_rois(path, *, rois=None, pixel=None, route=None, polygon: str | None = None,
                   triangulation: str | None = None, caps: str = "flat", refine: str | None = None,
                   bands: str | None = None, progress: bool = False):
    """Mesh several structures of a contour file (default: every non-empty one); yields ``(name, Mesh)``.

    ``rois`` lists names or numbers.  Each structure is meshed as :func:`mesh_file` meshes it with
    ``roi=`` that structure."""
    from .io.contours import list_rois

    table = list_rois(path)
    if rois is None:
        picks = [(num, name) for num, name, n in table if n > 0]
    else:
        picks = []
        for r in rois:
            found = [(num, name) for num, name, n in table if r == num or r == name or str(r) == str(num)
                     or str(r).strip().lower().replace("_", " ") == name.strip().lower().replace("_", " ")]
            if len(found) != 1:
                listing = ", ".join(f"{num}: {name!r}" for num, name, _ in table)
                raise ValueError(f"{str(path)!r}: {'no' if not found else len(found)} ROI matches {r!r}; "
                                 f"available ROIs: {listing}")
            if found[0] not in picks:  # the same structure named twice (by name and number) is meshed once
                picks.append(found[0])
    for num, name in picks:
        m = mesh_file(path, roi=num if _suffix_of(path) != ".json" else None, pixel=pixel, route=route, polygon=polygon,
                      triangulation=triangulation, caps=caps, refine=refine, bands=bands, progress=progress)
        yield name, diagnose(_with_meta(m, roi=name, roi_number=num))


def _suffix_of(path) -> str:
    name = str(path).lower()
    return ".json" if name.endswith(".json") else Path(name).suffix
