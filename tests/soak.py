"""Soak test: many random volumes and contour stacks through every polygon x triangulation.

Run by hand (not part of the default pytest run)::

    python tests/soak.py --examples 100000 --jobs 2 --seed 0 --out /tmp/soak

Every example is drawn from a seed (so any failure replays with ``--replay SEED``) and is one of:

* a random binary volume of one of :data:`KINDS` (blobs, thin sheets, one-voxel lines and tubes,
  checkerboards, diagonal staircases, objects touching every border, many components, nested
  hollow shells, single voxels, noise, all-foreground), meshed by
  :func:`contourmesh.volumes.volume_to_mesh`; the mesh must be closed, consistently oriented
  (each object surface outward, each cavity surface inward), edge-manifold, without degenerate
  faces or duplicate vertices, with the components and genus of
  :func:`contourmesh.volumes.voxel_topology`;
* a random integer contour stack with one contour per section at uneven heights (the paper's
  path, :func:`contourmesh.surface.stack_to_mesh`), given in either orientation: closed,
  outward, one sphere;
* a random real-valued contour stack (non-convex star polygons, nested rings, branching,
  uneven z), meshed through the rasterizer: closed, outward, with the topology of the raster;
* a randomly rotated real mesh of the shared data folder (``comparisons/real/real.toml``'s 14
  meshes, env ``CONTOURMESH_DATA``), voxelized at 16-40 voxels across and meshed in the paper mode
  or with ``refine="band"``: the same guarantees and the voxels' topology (skipped, and counted
  as ``real-skipped``, where the folder is absent);
* an invariance check: the same volume translated, rotated by a multiple of 90 degrees or
  mirrored in the slice plane gives the same topology, and the same area (to round-off for
  translations and for ``optimal`` bands; see :func:`check_invariance`) wherever the mesher made
  the same choices in both (its fallbacks, exact joins and pixel caps); where it did not, the area
  difference is reported per kind, not asserted.

Every mesh, on every route (volumes, integer stacks, drawn rings, refined), must also be free of
crossing faces (``checks()["self_intersections"] == 0``, issue 13).

The helpers here are imported by ``tests/test_robustness.py``, which runs the same checks
under hypothesis with a CI-sized budget.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import time
import traceback
from pathlib import Path

import numpy as np

from contourmesh.bands import TRIANGULATORS
from contourmesh.polygons import POLYGONIZERS

POLYGONS = tuple(sorted(POLYGONIZERS))
TRIANGULATIONS = tuple(sorted(TRIANGULATORS))  # every registered band, arclength included
COMBOS = list(itertools.product(POLYGONS, TRIANGULATIONS))
KINDS = ("blob", "sheet", "line", "tube", "checker", "staircase", "border", "components", "shells", "single",
         "noise", "full")
TRANSFORMS = ("shift", "rot90", "rot180", "rot270", "mirror_x", "mirror_y", "transpose")


# ------------------------------------------------------------------------------------------------
# generators
# ------------------------------------------------------------------------------------------------
def _shape(rng, zmax=6, ymax=10, xmax=10):
    return int(rng.integers(1, zmax + 1)), int(rng.integers(1, ymax + 1)), int(rng.integers(1, xmax + 1))


def make_volume(kind: str, rng: np.random.Generator) -> np.ndarray:
    """A small random boolean volume ``[z, y, x]`` of the given kind (never empty)."""
    from scipy import ndimage

    if kind == "blob":
        nz, ny, nx = _shape(rng)
        v = ndimage.gaussian_filter(rng.random((nz, ny, nx)), float(rng.uniform(0.6, 1.6))) > rng.uniform(0.45, 0.55)
    elif kind == "sheet":  # one voxel thick, along a random axis, maybe perforated and bent
        nz, ny, nx = _shape(rng)
        v = np.zeros((nz, ny, nx), bool)
        ax = int(rng.integers(0, 3))
        idx = [slice(None)] * 3
        idx[ax] = int(rng.integers(0, v.shape[ax]))
        v[tuple(idx)] = True
        if rng.random() < 0.5:
            v &= rng.random(v.shape) > 0.2
    elif kind in ("line", "tube"):  # a 6-connected random walk; a tube is its hollow thickening
        nz, ny, nx = _shape(rng, 6, 9, 9)
        v = np.zeros((nz, ny, nx), bool)
        p = np.array([rng.integers(0, s) for s in v.shape])
        for _ in range(int(rng.integers(1, 25))):
            v[tuple(p)] = True
            ax = int(rng.integers(0, 3))
            p[ax] = np.clip(p[ax] + rng.choice((-1, 1)), 0, v.shape[ax] - 1)
        if kind == "tube":
            cube = np.ones((3, 3, 3), bool)  # a shell at Chebyshev distance 2: 6-connected
            thick = ndimage.binary_dilation(np.pad(v, 2), cube, iterations=2)
            v = thick & ~ndimage.binary_dilation(np.pad(v, 2), cube, iterations=1)
            if rng.random() < 0.5 and len(v) > 4:  # cut the ends off: an open tube
                v = v[2:-2]
    elif kind == "checker":
        nz, ny, nx = _shape(rng, 4, 7, 7)
        k, j, i = np.indices((nz, ny, nx))
        v = (k + j + i) % 2 == 0 if rng.random() < 0.5 else (j + i) % 2 == 0
    elif kind == "staircase":
        nz, ny, nx = _shape(rng, 6, 8, 8)
        k, j, i = np.indices((nz, ny, nx))
        c = int(rng.integers(0, 6))
        v = (i + j == c + k) if rng.random() < 0.5 else (i + j <= c + k) & (i + j >= c + k - 1)
    elif kind == "border":  # touches all six faces of the array
        nz, ny, nx = _shape(rng)
        v = rng.random((nz, ny, nx)) > rng.uniform(0.05, 0.4)
        v[0] = v[-1] = v[:, 0] = v[:, -1] = v[:, :, 0] = v[:, :, -1] = True
    elif kind == "components":
        nz, ny, nx = _shape(rng, 6, 12, 12)
        v = np.zeros((nz, ny, nx), bool)
        for _ in range(int(rng.integers(2, 10))):
            a = [int(rng.integers(0, s)) for s in v.shape]
            b = [min(s, x + int(rng.integers(1, 3))) for s, x in zip(v.shape, a)]
            v[a[0]:b[0], a[1]:b[1], a[2]:b[2]] = True
    elif kind == "shells":  # nested hollow cubes: shell, cavity, shell, ... (maybe holed)
        n = int(rng.integers(3, 6))
        size = 2 * n + 1
        v = np.zeros((size, size, size), bool)
        for level in range(n):
            if level % 2 == 0:
                v[level:size - level, level:size - level, level:size - level] = True
            else:
                v[level:size - level, level:size - level, level:size - level] = False
        if rng.random() < 0.3:  # a tunnel through the outer shell
            v[size // 2, size // 2, :2] = False
    elif kind == "single":
        nz, ny, nx = _shape(rng, 3, 4, 4)
        v = np.zeros((nz, ny, nx), bool)
        v[tuple(int(rng.integers(0, s)) for s in v.shape)] = True
    elif kind == "noise":
        nz, ny, nx = _shape(rng, 5, 8, 8)
        v = rng.random((nz, ny, nx)) < rng.uniform(0.2, 0.8)
    elif kind == "full":
        v = np.ones(_shape(rng, 4, 6, 6), bool)
    else:
        raise ValueError(f"unknown volume kind {kind!r}; expected one of {KINDS}")
    v = np.ascontiguousarray(v, dtype=bool)
    if not v.any():
        v[tuple(s // 2 for s in v.shape)] = True
    return v


def _star(rng, cx, cy, r0, k=None, jitter=0.45):
    """A random non-convex star-shaped polygon (positive area), float (k, 2)."""
    k = int(rng.integers(5, 16)) if k is None else k
    t = np.sort(rng.uniform(0, 2 * np.pi, k))
    r = r0 * (1 - jitter * rng.random(k))
    return np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]


def _ray_hit(ring, cx, cy, th):
    """Index of the edge of a ring (star-shaped about ``(cx, cy)``) that the ray at angle ``th``
    crosses, and the crossing point."""
    d = np.array([np.cos(th), np.sin(th)])
    for i in range(len(ring)):
        p, q = ring[i], ring[(i + 1) % len(ring)]
        m = np.array([d, p - q]).T  # s * d = p + u (q - p) - c
        if abs(np.linalg.det(m)) < 1e-12:
            continue
        s_, u = np.linalg.solve(m, p - [cx, cy])
        if s_ > 0 and 0 <= u <= 1:
            return i, np.array([cx, cy]) + s_ * d
    return None  # the ring does not hold (cx, cy)


def _keyhole(outer, hole, cx, cy, th):
    """One ring for an outer ring and a hole: out along the outer ring from the ray at ``th``,
    in along a zero-width channel on that ray, round the hole the other way, and back out."""
    a, b = _ray_hit(outer, cx, cy, th), _ray_hit(hole, cx, cy, th)
    if a is None or b is None or np.linalg.norm(b[1] - [cx, cy]) >= np.linalg.norm(a[1] - [cx, cy]):
        return None  # no clean channel on this ray: keep the two rings
    (i, P), (j, H) = a, b
    o = np.vstack([P, outer[i + 1:], outer[: i + 1]])           # P, then the outer ring back to P
    h = np.vstack([H, hole[: j + 1][::-1], hole[j + 1:][::-1]])  # H, then the hole reversed
    return np.vstack([o, P, h, H])


def _uneven_z(rng, n):
    return np.cumsum(np.r_[rng.uniform(-3, 3), rng.uniform(0.3, 3.0, n - 1)])


def make_int_stack(rng: np.random.Generator):
    """A stack of integer outer Jordan contours, one per section, at uneven heights.

    Each section is the outer Jordan contour (:func:`contourmesh.tracing.trace_contours`) of the
    grid points inside a random star polygon, drifting from section to section; sections whose
    ``U`` has more than one boundary are redrawn.
    """
    from contourmesh.geometry import points_in_rings
    from contourmesh.tracing import trace_contours
    from contourmesh.types import ContourStack, Section

    n = int(rng.integers(1, 6))
    zs = _uneven_z(rng, n)
    secs = []
    cx, cy = rng.uniform(-3, 3, 2)
    for z in zs:
        for _ in range(50):
            r0 = rng.uniform(0.8, 6.0)
            poly = _star(rng, cx, cy, r0)
            lo = np.floor(poly.min(0)).astype(int) - 1
            hi = np.ceil(poly.max(0)).astype(int) + 1
            gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
            inside = points_in_rings(np.c_[gx.ravel(), gy.ravel()], poly).reshape(gx.shape)
            if not inside.any():
                continue
            cs, parents = trace_contours(inside, x0=int(lo[0]), y0=int(lo[1]))
            if len(cs) == 1:
                secs.append(Section(float(z), (cs[0],)))
                break
        else:  # pragma: no cover - practically never
            secs.append(Section(float(z), (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.int64),)))
        cx += rng.uniform(-1.5, 1.5)
        cy += rng.uniform(-1.5, 1.5)
    return ContourStack(tuple(secs), meta={"generator": "int"})


def make_real_stack(rng: np.random.Generator):
    """A real-valued stack: non-convex rings, nested (holes, islands), branching, uneven z.

    Returns ``(stack, pixel)``; rings are given in random windings (the reader's even-odd rule
    decides holes).
    """
    from contourmesh.io import stack_from_rings

    n = int(rng.integers(1, 6))
    zs = _uneven_z(rng, n)
    slices = []
    for z in zs:
        rings = []
        for _ in range(int(rng.integers(1, 3))):  # branching: one or two separate objects
            cx, cy = rng.uniform(-8, 8, 2)
            r0 = rng.uniform(2.0, 7.0)
            rings.append(_star(rng, cx, cy, r0, jitter=0.3))
            if rng.random() < 0.4:  # a hole, maybe with an island
                rings.append(_star(rng, cx, cy, r0 * 0.45, jitter=0.2))
                if rng.random() < 0.3:  # drawn as one keyhole ring (RTSTRUCT style)
                    key = _keyhole(rings[-2], rings[-1], cx, cy, rng.uniform(0, 2 * np.pi))
                    if key is not None:
                        rings[-2:] = [key]
                if rng.random() < 0.5:
                    rings.append(_star(rng, cx, cy, r0 * 0.2, jitter=0.1))
        rings = [r[::-1] if rng.random() < 0.5 else r for r in rings]
        slices.append((float(z), rings))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        stack = stack_from_rings(slices, source="soak")
    pixel = float(rng.choice([0.5, 0.75, 1.0, 1.5]))
    return stack, pixel


# ------------------------------------------------------------------------------------------------
# checks
# ------------------------------------------------------------------------------------------------
def component_volumes(mesh) -> np.ndarray:
    """Signed enclosed volume of every connected component of the mesh's faces."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    F = mesh.faces
    nv = len(mesh.vertices)
    rows = np.repeat(np.arange(len(F)), 3)
    g = coo_matrix((np.ones(len(rows)), (rows, F.reshape(-1))), shape=(len(F), nv)).tocsr()
    adj = g @ g.T
    _, lab = connected_components(adj, directed=False)
    a, b, c = (mesh.vertices[F[:, i]] for i in range(3))
    vol6 = np.einsum("ij,ij->i", a, np.cross(b, c))
    return np.bincount(lab, weights=vol6) / 6.0


def check_mesh(mesh, ref: dict | None = None, embedded: bool = True) -> dict:
    """Assert the guarantees of every emitted mesh; compare the topology with ``ref`` if given.

    ``ref`` is a :func:`contourmesh.volumes.voxel_topology` dict (components, cavities,
    surfaces, genus).
    """
    chk = mesh.checks()
    assert np.all(np.isfinite(mesh.vertices)), "non-finite vertices"
    assert chk["watertight"], chk
    assert chk["boundary_edges"] == 0 and chk["nonmanifold_edges"] == 0, chk
    assert chk["winding_consistent"], chk
    assert chk["degenerate_faces"] == 0, chk
    assert chk["duplicate_vertices"] == 0, chk
    if embedded:  # closed means embedded (issue 13): asserted on every route's outputs
        assert chk["self_intersections"] == 0, chk
    assert chk["volume"] > 0, chk
    vols = component_volumes(mesh)
    assert np.all(vols != 0), f"a component encloses no volume: {vols}"
    if ref is not None:
        assert chk["components"] == ref["surfaces"], (chk, ref)
        assert chk["genus"] == ref["genus"], (chk, ref)
        # every object surface faces out (positive volume), every cavity surface faces in
        assert int((vols > 0).sum()) == ref["components"], (vols, ref)
        assert int((vols < 0).sum()) == ref["cavities"], (vols, ref)
    else:
        assert np.all(vols > 0), vols
    return chk


def check_volume(vol, polygon, triangulation, caps="flat"):
    from contourmesh.volumes import volume_to_mesh, voxel_topology

    m = volume_to_mesh(vol, polygon=polygon, triangulation=triangulation, caps=caps)
    check_mesh(m, voxel_topology(vol), embedded=True)
    return m


def reverse_stack(stack):
    """The same stack with every contour traversed the other way (start point kept)."""
    from contourmesh.types import ContourStack, Section

    rev = lambda c: np.concatenate([c[:1], c[:0:-1]])  # noqa: E731
    return ContourStack(tuple(Section(s.z, tuple(rev(np.asarray(c)) for c in s.contours), s.parents)
                              for s in stack.sections), stack.spacing, stack.origin, dict(stack.meta))


def _check_heights(stack, m):
    """Interior sections are never dropped: each lies at its own height in the mesh."""
    from contourmesh.surface import _is_degenerate, _outward, _polygon

    stack = _outward(stack)
    zs = np.unique(m.vertices[:, 2])
    # by the documented end rule, of several sections whose polygons degenerate at one end of a
    # stack only the outermost is kept; every other interior section must be there
    poly = m.meta.get("polygon", "mlp")
    inner = [s.z for s in stack.sections[1:-1] if not _is_degenerate(_polygon(s.contours[0], poly))]
    assert np.all(np.isin(inner, zs)), "a section is missing from the mesh (wrong slice heights)"
    if len(stack.z) > 1 and m.meta.get("caps") == "flat":
        # a flat cap lies in the end plane, except the documented fallback for a polygon touching
        # itself: a collar 1 % of the spacing beyond the end carries a cap made of grid cells
        tol = 0.0101 * float(np.max(np.diff(stack.z)))
        assert zs.min() >= stack.z[0] - tol and zs.max() <= stack.z[-1] + tol, "the mesh leaves the stack's z range"


def check_int_stack(stack, polygon, triangulation, caps="flat"):
    """The paper's path: one closed outward sphere-like surface (genus 0, one component)."""
    import warnings

    import contourmesh
    from contourmesh.errors import RasterFallbackWarning
    from contourmesh.refine import stack_points
    from contourmesh.volumes import voxel_topology

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = contourmesh.mesh(stack, polygon=polygon, triangulation=triangulation, caps=caps)
    if m.meta.get("route") == "volume":
        # the documented fallback: a stack-route mesh with crossing faces, or one that is no closed
        # surface (a contour touching itself), goes to the volume mesher, with a warning; the mesh
        # then has the topology of the contours' grid points
        why = m.meta.get("stack_route_error", "")
        assert "crossing faces" in why or "do not bound a closed surface" in why, m.meta
        assert any(issubclass(w.category, RasterFallbackWarning) for w in caught), [str(w.message) for w in caught]
        return check_mesh(m, voxel_topology(stack_points(stack, lattice=False)[0]), embedded=True)
    assert m.meta.get("route") == "stack", m.meta
    chk = check_mesh(m, embedded=True)
    assert chk["components"] == 1 and chk["genus"] == 0, chk
    _check_heights(stack, m)
    return m


def check_real_stack(stack, pixel, polygon, triangulation, caps="flat"):
    """Real-valued stacks: the contours or raster path (closed, oriented, with the raster's own
    topology, at the sections' heights), or, with one ring per section and ``polygon="none"``, the paper's
    path on the rings as given (one surface of genus 0)."""
    import warnings

    from contourmesh.api import mesh_stack as mesh_contour_stack
    from contourmesh.errors import LostContourWarning, RasterFallbackWarning
    from contourmesh.rasterize import rasterize_stack
    from contourmesh.volumes import voxel_topology

    # random rings can be smaller than a pixel: a LostContourWarning is expected then; random rings
    # that cross themselves cannot be meshed as drawn: a RasterFallbackWarning is expected then (and
    # only on the raster route, with the reason in meta); no other warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            r = rasterize_stack(stack, pixel)
        except ValueError as exc:  # documented: every ring smaller than a pixel
            assert "no pixel centre lies inside any contour" in str(exc), exc
            r = None
        if r is not None:
            m = mesh_contour_stack(stack, polygon=polygon, triangulation=triangulation, caps=caps, pixel=pixel)
    unexpected = [w for w in caught if not issubclass(w.category, (LostContourWarning, RasterFallbackWarning))]
    assert not unexpected, [str(w.message) for w in unexpected]
    if r is None:
        return None
    # a stack route failure, or (contours route) components meshed from the raster's polygons
    fell_back = any(issubclass(w.category, RasterFallbackWarning) and "on the stack route" in str(w.message)
                    for w in caught)
    assert fell_back == ("stack_route_error" in m.meta), m.meta
    assert not fell_back or m.meta["route"] == "contours", m.meta
    unmatched = any(issubclass(w.category, RasterFallbackWarning) and "not from drawn rings" in str(w.message)
                    for w in caught)
    assert unmatched == bool(m.meta.get("unmatched_components")), m.meta
    if m.meta["route"] == "contours":  # the raster that decided the joins (finer where rings are thin)
        from contourmesh.drawn import decision_raster

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = decision_raster(stack, m.meta["pixel"])
    if m.meta["route"] == "stack":
        chk = check_mesh(m, embedded=True)
        assert chk["components"] == 1 and chk["genus"] == 0, chk
        _check_heights(stack, m)
        return m
    check_mesh(m, voxel_topology(r.volume), embedded=True)
    occupied = r.z[r.volume.reshape(len(r.z), -1).any(axis=1)]
    zs = np.unique(m.vertices[:, 2])
    assert np.all(np.isin(occupied, zs)), "an occupied section is missing from the mesh"
    return m


def transform(vol, name):
    if name == "shift":
        return np.pad(vol, ((0, 0), (3, 0), (2, 0)))
    if name.startswith("rot"):
        return np.rot90(vol, int(name[3:]) // 90, axes=(1, 2))
    if name == "mirror_x":
        return vol[:, :, ::-1]
    if name == "mirror_y":
        return vol[:, ::-1, :]
    if name == "transpose":
        return np.swapaxes(vol, 1, 2)
    raise ValueError(f"unknown transform {name!r}")


def invariance_tolerance(polygon, triangulation, name, bridged: bool = False) -> tuple[float, float]:
    """``(relative, absolute)`` area tolerance of a slice-plane transform (absolute in pixel areas).

    * Translations: the same surface up to the ``1e-3``-pixel nudges that separate touching
      sheets, so ``1e-4`` relative.
    * Every other transform with ``optimal`` bands over ``mlp`` or ``none`` polygons: the same
      surface up to those nudges, which the crossing repair makes in an order that follows the
      orientation (a tie among equally short tube joints may go either way), so ``1e-3`` relative.
    * ``wiederhold`` and ``greedy`` bands are local rules that start at each polygon's start
      point and break ties by traversal order, and DSS polygons depend on the start point and
      direction of the contour (greedy segmentation): a rotated or mirrored input gives another,
      equally valid polygon or triangulation.  The topology is always identical; the areas agree
      within ``50 %`` plus two pixel areas on these small volumes (one-voxel-wide lines are the
      worst case; the soak reports the largest difference seen).
    * MLP polygons with ``optimal`` bands are exact too (the MLP does not depend on the start
      point; see ``test_mlp_of_a_thin_L_is_mirror_symmetric``).
    * Except with bridged (branching) joins (``bridged``): a bridge is one of several equally
      short candidates, and whether a bridged band keeps clear of itself (else the join is exact)
      depends on that choice, so these meshes get the local rules' tolerance.
    """
    if name == "shift":
        return 1e-4, 0.0
    if triangulation == "optimal" and polygon in ("none", "mlp") and not bridged:
        return 1e-3, 0.0
    return 0.5, 2.0


#: What the general mesher chose for a volume: its fallbacks to voxel-exact joins, crack rings and
#: pixel caps.  These choices rest on exact geometric tests (does this band cross, can this cap be
#: triangulated), and a one-voxel-thin part can pass a test in one orientation and fail it in the
#: mirrored one (a band's start point and a tie in the optimal band move with the orientation).
#: Each choice gives a valid mesh, but their areas differ by what a voxel-exact join or a pixel cap
#: adds, up to 3x on the soak's smallest lines and sheets.
CHOICES = ("route", "fast_path", "exact_joins", "crack_rings", "polygon_fallbacks", "pixel_caps", "crossing_fallbacks",
           "bridged_joins")


def mesher_choices(m) -> tuple:
    return tuple(m.meta.get(k) for k in CHOICES)


def check_invariance(vol, polygon, triangulation, name) -> tuple[float, bool]:
    """Same topology, and the same area (within :func:`invariance_tolerance`) where the mesher
    made the same choices (:data:`CHOICES`) in both orientations.  Returns the relative area
    difference and whether the choices were the same."""
    from contourmesh.volumes import volume_to_mesh

    a = volume_to_mesh(vol, polygon=polygon, triangulation=triangulation)
    b = volume_to_mesh(np.ascontiguousarray(transform(vol, name)), polygon=polygon, triangulation=triangulation)
    ca, cb = a.checks(), b.checks()
    assert ca["closed"] and cb["closed"], (ca, cb)  # crossing faces: issue 13, counted by checks()
    assert (ca["components"], ca["genus"]) == (cb["components"], cb["genus"]), (name, ca, cb)
    if name == "shift":  # the same surface, moved, up to the 1e-3-pixel nudges that separate touching sheets
        assert abs(a.volume - b.volume) <= 1e-4 * a.volume, (name, a.volume, b.volume)
    same = mesher_choices(a) == mesher_choices(b)
    bridged = bool(a.meta.get("bridged_joins") or b.meta.get("bridged_joins"))
    rel, absolute = invariance_tolerance(polygon, triangulation, name, bridged)
    if same or name == "shift":
        assert abs(a.area - b.area) <= rel * a.area + absolute, (name, polygon, triangulation, a.area, b.area,
                                                                 mesher_choices(a), mesher_choices(b))
    return abs(a.area - b.area) / a.area, same


# ------------------------------------------------------------------------------------------------
# the soak
# ------------------------------------------------------------------------------------------------
REAL_MESHES = ("libigl-tutorial-data/armadillo.obj", "dgtal/lion-tri.obj", "common-3d-test-models/rocker-arm.obj",
               "libigl-tutorial-data/fertility.off", "libigl-tutorial-data/bunny.off", "common-3d-test-models/spot.obj",
               "libigl-tutorial-data/3holes.off", "trimesh-models/quadknot.obj", "cgogn/socket.off",
               "cgogn/aneurysm_3D.off", "libigl-tutorial-data/elephant.obj", "common-3d-test-models/cheburashka.obj",
               "libigl-tutorial-data/fandisk.off", "trimesh-models/torus.STL")
_REAL_CACHE: dict = {}


def make_real_volume(rng: np.random.Generator):
    """A shared real mesh, randomly rotated and offset, voxelized at 16-40 across; None without the data."""
    from scipy.spatial.transform import Rotation

    from contourmesh.compare.inputs import data_dir, load_closed_mesh
    from contourmesh.voxelize import voxelize_mesh

    name = REAL_MESHES[int(rng.integers(len(REAL_MESHES)))]
    n = int(rng.integers(16, 41))
    rot = Rotation.random(random_state=int(rng.integers(2 ** 31))).as_matrix()
    off = rng.uniform(0.0, 1.0, 3)
    path = data_dir() / "meshes" / name
    if not path.is_file():
        return name, n, None
    if name not in _REAL_CACHE:
        _REAL_CACHE[name] = load_closed_mesh(path)
    v, f = _REAL_CACHE[name]
    v = v @ rot.T
    v = v + off * float((v.max(0) - v.min(0)).max()) / n
    vol, _, _ = voxelize_mesh(v, f, n)
    return name, n, vol


def check_real(vol, polygon, triangulation, caps, refine):
    from contourmesh.api import mesh_volume
    from contourmesh.volumes import voxel_topology

    m = mesh_volume(vol, polygon=polygon, triangulation=triangulation, caps=caps, refine=refine)
    check_mesh(m, voxel_topology(vol), embedded=True)
    return m


#: The kinds of example, by the draw ``u`` that picks them (see :func:`run_example`).
EXAMPLE_KINDS = {"volume": (0.0, 0.6), "int-stack": (0.6, 0.72), "real-stack": (0.72, 0.84), "real": (0.84, 0.9),
                 "invariance": (0.9, 1.0)}


def run_example(seed: int, only: str | None = None) -> tuple[str, str | None]:
    """Run the example of this seed; returns ``(description, None)`` or ``(description, traceback)``.
    With ``only`` (a key of :data:`EXAMPLE_KINDS`), a seed of another kind is passed over
    (``("other", None)``), so that one kind can be soaked on its own with the same seeds."""
    rng = np.random.default_rng(seed)
    polygon, triangulation = COMBOS[int(rng.integers(len(COMBOS)))]
    caps = "half" if rng.random() < 0.2 else "flat"
    u = rng.random()
    if only is not None and not EXAMPLE_KINDS[only][0] <= u < EXAMPLE_KINDS[only][1]:
        return "other", None
    try:
        if u < 0.6:
            kind = KINDS[int(rng.integers(len(KINDS)))]
            desc = f"volume:{kind}:{polygon}/{triangulation}/{caps}"
            check_volume(make_volume(kind, rng), polygon, triangulation, caps)
        elif u < 0.72:
            stack = make_int_stack(rng)
            rev = rng.random() < 0.5
            desc = f"int-stack{':reversed' if rev else ''}:{polygon}/{triangulation}/{caps}"
            check_int_stack(reverse_stack(stack) if rev else stack, polygon, triangulation, caps)
        elif u < 0.84:
            desc = f"real-stack:{polygon}/{triangulation}/{caps}"
            stack, pixel = make_real_stack(rng)
            check_real_stack(stack, pixel, polygon, triangulation, caps)
        elif u < 0.9:
            name, n, vol = make_real_volume(rng)
            refine = "band" if rng.random() < 0.4 else None
            if refine:  # the refinement seeds with MLPs (or DSS) and has its own caps
                polygon = "mlp" if polygon == "none" else polygon
                caps = "flat"
            desc = f"real{'-skipped' if vol is None else ''}:{name}@{n}{':band' if refine else ''}:{polygon}/{triangulation}/{caps}"
            if vol is not None:
                check_real(vol, polygon, triangulation, caps, refine)
        else:
            kind = KINDS[int(rng.integers(len(KINDS)))]
            name = TRANSFORMS[int(rng.integers(len(TRANSFORMS)))]
            desc = f"invariance:{name}:{kind}:{polygon}/{triangulation}"
            d, same = check_invariance(make_volume(kind, rng), polygon, triangulation, name)
            desc += f":rel={d:.3g}" + ("" if same else ":other-choices")
    except Exception:  # noqa: BLE001 - the soak records every failure
        return desc, traceback.format_exc(limit=6)
    return desc, None


def _chunk(args):
    start, stop, only = args
    out = []
    for s in range(start, stop):
        desc, err = run_example(s, only)
        out.append((s, desc, err))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--examples", type=int, default=100_000)
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--out", default=None, help="folder for soak.json (progress and failures)")
    p.add_argument("--replay", type=int, default=None, help="run one seed and print its traceback")
    p.add_argument("--max-minutes", type=float, default=None, help="stop after this long (reports what ran)")
    p.add_argument("--only", choices=sorted(EXAMPLE_KINDS), default=None,
                   help="run only the seeds of this kind (the others are passed over and counted as 'other')")
    args = p.parse_args(argv)
    if args.replay is not None:
        desc, err = run_example(args.replay)
        print(desc, "OK" if err is None else "FAILED")
        if err:
            print(err)
        return 0 if err is None else 1
    out = Path(args.out) if args.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    chunk = 200
    tasks = [(s, min(s + chunk, args.seed + args.examples), args.only)
             for s in range(args.seed, args.seed + args.examples, chunk)]
    t0 = time.time()
    done, failures, kinds, worst = 0, [], {}, {}

    def report(final=False):
        state = {"examples": done, "failures": len(failures), "seconds": round(time.time() - t0, 1),
                 "first_seed": args.seed, "by_kind": kinds,
                 "invariance_worst_rel_area_diff": dict(sorted(worst.items())), "failed": failures[:200], "finished": final}
        if out:
            tmp = out / "soak.json.tmp"
            tmp.write_text(json.dumps(state, indent=1))
            os.replace(tmp, out / "soak.json")
        return state

    from multiprocessing import get_context

    with get_context("spawn").Pool(args.jobs) as pool:
        for res in pool.imap_unordered(_chunk, tasks):
            for s, desc, err in res:
                done += 1
                key = desc.split(":")[0]
                kinds[key] = kinds.get(key, 0) + 1
                if key == "invariance" and err is None:
                    _, name, _, combo, rel, *other = desc.split(":")
                    grp = f"{combo}:{'shift' if name == 'shift' else 'rotate/mirror'}{':other-choices' if other else ''}"
                    worst[grp] = max(worst.get(grp, 0.0), float(rel[4:]))
                if err is not None:
                    failures.append({"seed": s, "what": desc, "error": err})
            report()
            print(f"{done} examples, {len(failures)} failures, {time.time() - t0:.0f} s", flush=True)
            if args.max_minutes and time.time() - t0 > 60 * args.max_minutes:
                pool.terminate()
                break
    state = report(final=True)
    print(json.dumps({k: state[k] for k in ("examples", "failures", "seconds", "by_kind")}))
    for f in failures[:20]:
        print(f"seed {f['seed']}: {f['what']}\n{f['error']}")
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    sys.exit(main())
