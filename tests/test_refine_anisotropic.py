"""Band refinement on oblong pixels (dx != dy) and on unevenly spaced slices (issue 14 item 3).

Balls and ellipsoids digitized at the liver sample's voxel shape ((dz, dy, dx) = (0.9, 0.617, 0.667)),
and at uneven slice heights, meshed with ``refine="band"`` on the volume route and the contour-stack
route: closed, outward, no crossing faces, every polygon vertex in its slice's digital band, and an
area error against the analytic surface that shrinks with the resolution.  Before, such inputs were
refused ("band refinement needs square pixels"), and taking one pixel side for both (the bug of
``_grid_stack_volume``) puts the surface off by the pixels' aspect (8 % here).
"""

import numpy as np
import pytest

import contourmesh
from conftest import assert_closed_outward
from contourmesh import refine as R
from contourmesh.api import _stack_of_mask
from contourmesh.digitize import mask_stack, sample_volume, uneven_heights
from contourmesh.refine import band_violations, blurred_indicator, in_band, stack_points
from contourmesh.shapes import Ellipsoid, Sphere
from contourmesh.types import ContourStack, Section

LIVER = (0.9, 0.617, 0.667)  # (dz, dy, dx), mm








def rel(m, shape):
    return m.area / shape.area - 1


def refined_volume(shape, spacing, zs=None, **kw):
    mask, zs, org = sample_volume(shape, spacing, zs)
    m = contourmesh.mesh(mask, spacing=spacing, z=zs, origin=org, refine="band", **kw)
    chk = assert_closed_outward(m, genus=0)
    assert chk["self_intersections"] == 0, chk
    # every vertex on a slice lies in that slice's band (the stack the refinement saw)
    stack = _stack_of_mask(mask, zs, spacing[1], spacing[2], org[0], org[1])
    assert band_violations(stack, m) == 0
    return m


# ----------------------------------------------------------------------------------------------
# the volume route
# ----------------------------------------------------------------------------------------------
def test_oblong_pixels_converge_on_the_volume_route():
    """A ball at the liver's voxel shape, r = 10 and 20 pixels of 0.667 mm: -0.70 / -0.12 %."""
    errs = []
    for r in (10, 20):
        s = Sphere(r * 0.667, center=(0.31, 0.17, 0.43))
        m = refined_volume(s, LIVER)
        assert m.meta["route"] == "refined"
        errs.append(rel(m, s))
    assert abs(errs[0]) < 1.0e-2 and abs(errs[1]) < 2.5e-3, errs
    assert abs(errs[1]) < 0.5 * abs(errs[0]), errs  # shrinks with the resolution


def test_uneven_slices_on_the_volume_route():
    """An ellipsoid on slices 0.5-1.3 mm apart (random), oblong pixels: -0.53 / -0.16 % at two sizes."""
    errs = []
    for scale in (1, 2):
        e = Ellipsoid(6.7 * scale, 5.0 * scale, 6.0 * scale, center=(0.2, 0.1, 0.05))
        zs = uneven_heights(6.0 * scale)
        m = refined_volume(e, LIVER, zs=zs)
        assert m.meta["route"] == "refined"
        errs.append(rel(m, e))
    assert abs(errs[0]) < 8e-3 and abs(errs[1]) < 2.5e-3, errs
    assert abs(errs[1]) < 0.6 * abs(errs[0]), errs


def test_several_contours_per_slice_take_the_volume_mesher_refinement():
    """Two ellipsoids side by side: the volume mesher refines its polygons at any pixel shape and
    slice heights."""
    a = Ellipsoid(5.5, 4.5, 5.0, center=(-6.4, 0.1, 0.05))
    b = Ellipsoid(4.5, 5.0, 4.0, center=(6.1, 0.3, 0.2))
    for zs in (None, uneven_heights(6.0, seed=5)):
        sp = LIVER
        dz, dy, dx = sp
        lo = np.minimum(a.bounds[0], b.bounds[0])
        hi = np.maximum(a.bounds[1], b.bounds[1])
        xs = np.arange(np.floor(lo[0] / dx) - 2, np.ceil(hi[0] / dx) + 3) * dx
        ys = np.arange(np.floor(lo[1] / dy) - 2, np.ceil(hi[1] / dy) + 3) * dy
        z = np.arange(np.floor(lo[2] / dz) - 2, np.ceil(hi[2] / dz) + 3) * dz if zs is None else zs
        zz, yy, xx = np.meshgrid(z, ys, xs, indexing="ij")
        mask = a.contains(xx, yy, zz) | b.contains(xx, yy, zz)
        m = contourmesh.mesh(mask, spacing=sp, z=z, origin=(xs[0], ys[0], z[0]), refine="band")
        chk = assert_closed_outward(m)
        assert m.meta["route"] == "volume-refined" and chk["components"] == 2 and chk["self_intersections"] == 0
        assert abs(m.area / (a.area + b.area) - 1) < 1.5e-2


# ----------------------------------------------------------------------------------------------
# the contour-stack route
# ----------------------------------------------------------------------------------------------
def test_contour_stack_route_oblong_pixels_and_uneven_heights():
    e = Ellipsoid(12.0, 10.0, 11.0, center=(0.2, 0.1, 0.05))
    for zs in (None, uneven_heights(11.0)):
        mask, z, org = sample_volume(e, LIVER, zs)
        stack = mask_stack(mask, z, LIVER, org)
        m = contourmesh.mesh(stack, refine="band")
        chk = assert_closed_outward(m, genus=0)
        assert m.meta["route"] == "refined" and chk["self_intersections"] == 0
        assert band_violations(stack, m) == 0
        assert abs(rel(m, e)) < 4e-3, (zs is None, rel(m, e))
        paper = contourmesh.mesh(stack)
        assert abs(rel(m, e)) < 0.3 * abs(rel(paper, e))


def test_grid_stack_with_two_contours_uses_both_pixel_sides():
    """A grid stack with two contours per section goes to the volume mesher (no refinement), which
    must get (dz, dy, dx): with (dz, dx, dx) the y extent and the volume were 8 % off (and before
    that, stack_points refused the oblong pixels)."""
    a = Ellipsoid(5.5, 4.5, 5.0, center=(-6.4, 0.1, 0.05))
    b = Ellipsoid(4.5, 5.0, 4.0, center=(6.1, 0.3, 0.2))
    dz, dy, dx = LIVER
    lo = np.minimum(a.bounds[0], b.bounds[0])
    hi = np.maximum(a.bounds[1], b.bounds[1])
    xs = np.arange(np.floor(lo[0] / dx) - 2, np.ceil(hi[0] / dx) + 3) * dx
    ys = np.arange(np.floor(lo[1] / dy) - 2, np.ceil(hi[1] / dy) + 3) * dy
    z = np.arange(np.floor(lo[2] / dz) - 2, np.ceil(hi[2] / dz) + 3) * dz
    zz, yy, xx = np.meshgrid(z, ys, xs, indexing="ij")
    mask = a.contains(xx, yy, zz) | b.contains(xx, yy, zz)
    stack = mask_stack(mask, z, LIVER, (xs[0], ys[0], z[0]))
    assert max(len(s.contours) for s in stack.sections) == 2
    m = contourmesh.mesh(stack)
    chk = assert_closed_outward(m)
    assert m.meta["route"] == "volume" and chk["components"] == 2
    # the mesh spans the grid points' y range (not dx / dy of it)
    occupied = np.flatnonzero(mask.any(axis=(0, 2)))
    assert m.vertices[:, 1].min() == pytest.approx(ys[occupied[0]], abs=0.5 * dy)
    assert m.vertices[:, 1].max() == pytest.approx(ys[occupied[-1]], abs=0.5 * dy)
    # the paper mode's MLP runs inside the pixels (-14 % volume, -6.7 % area at this size); the
    # crack contours (polygon="none") bound the pixels: -1.8 % volume
    assert abs(m.area / (a.area + b.area) - 1) < 0.08
    crack = contourmesh.mesh(stack, polygon="none")
    assert abs(crack.volume / (a.volume + b.volume) - 1) < 0.03
    # and the same as the volume itself (up to the triangulations' ties, which the coordinates'
    # rounding breaks one way or the other off a unit lattice: 0.016 % here)
    ref = contourmesh.mesh(mask, spacing=LIVER, origin=(xs[0], ys[0], z[0]))
    assert m.volume == pytest.approx(ref.volume, rel=1e-3)
    assert len(m.vertices) == len(ref.vertices)
    # refined, the two-contour stack goes to the volume mesher's refinement, on its lattice
    mr = contourmesh.mesh(stack, refine="band")
    assert mr.meta["route"] == "volume-refined"
    assert_closed_outward(mr)
    assert abs(mr.area / (a.area + b.area) - 1) < 1e-2  # -0.47 %


# ----------------------------------------------------------------------------------------------
# the pieces: the lattice, the field, the band test
# ----------------------------------------------------------------------------------------------
def test_stack_points_off_lattice_and_oblong():
    c = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], dtype=np.int64)
    even = ContourStack(sections=tuple(Section(z=0.9 * k, contours=(c,)) for k in (0, 1, 3)), spacing=(0.667, 0.617))
    _, _, _, zidx, dz = stack_points(even)
    assert dz == pytest.approx(0.9 / 0.667) and list(np.diff(zidx)) == [1, 2]  # a gap: an empty slice
    odd = ContourStack(sections=tuple(Section(z=z, contours=(c,)) for z in (0.0, 0.9, 1.3)), spacing=(0.667, 0.617))
    _, _, _, zidx, dz = stack_points(odd)
    assert dz is None and list(np.diff(zidx)) == [1, 1]


def test_uneven_field_is_normalised_and_its_z_derivatives_are_exact():
    """On uneven slices a full solid blurs to 1 at every height, and fz, fzz, fxz match finite
    differences of f (the quotient rule for the height-dependent normalisation)."""
    heights = np.cumsum(np.r_[0.0, np.random.default_rng(1).uniform(0.4, 1.4, size=39)])
    n = len(heights)
    full = np.ones((n, 30, 30), dtype=bool)
    sp = (0.667, 0.617)
    f = blurred_indicator(full, [[10.0, 9.0, 20.0], [10.3, 9.2, 17.0]], sigma=2.0, spacing=sp, heights=heights)
    # (the in-slice window stops at 4 sigma, the norm at 6: 1 - 1.3e-4; across the slices both stop at 4)
    assert np.allclose(f[:, 0], 1.0, atol=2e-4) and np.allclose(f[:, 3], 0.0, atol=1e-12)
    # a ball: compare the analytic z-derivatives with differences along the slice index
    zz, yy, xx = np.meshgrid(heights - heights[n // 2], np.arange(30) * sp[1] - 9.0, np.arange(30) * sp[0] - 10.0,
                             indexing="ij")
    ball = xx**2 + yy**2 + zz**2 < 36
    k = n // 2 + 5
    p = np.array([14.3 * 1.0, 13.1, float(k)])  # x, y in units of h = 0.667 mm; slice k
    h = 0.667
    eps = 1e-4
    gap = (heights[k + 1] - heights[k]) / h  # slice spacing above k, in units of h

    def at(dz_idx=0.0, dx=0.0):
        return blurred_indicator(ball, [p + [dx, 0.0, dz_idx]], sigma=2.0, spacing=sp, heights=heights)[0]

    c = at()
    fz = (at(eps)[0] - at(-eps * (heights[k + 1] - heights[k]) / (heights[k] - heights[k - 1]))[0]) / (2 * eps * gap)
    assert c[3] == pytest.approx(fz, rel=1e-4, abs=1e-7)
    fzz = (at(eps)[3] - at(-eps * (heights[k + 1] - heights[k]) / (heights[k] - heights[k - 1]))[3]) / (2 * eps * gap)
    assert c[6] == pytest.approx(fzz, rel=1e-3, abs=1e-6)
    fxz = (at(dx=eps)[3] - at(dx=-eps)[3]) / (2 * eps)
    assert c[8] == pytest.approx(fxz, rel=1e-3, abs=1e-6)


def test_band_test_tolerance_is_symmetric():
    """A point within 1e-9 of a cell edge sees the cells on both sides, whichever side it is on."""
    pts = np.zeros((1, 8, 8), dtype=bool)
    pts[0, 2:5, 2:6] = True  # cell [2, 3] x [2, 3] is interior, cell [5, 6] x [2, 3] is not
    # the edge x = 5 between the full cell [4, 5] and the half-empty cell [5, 6]: on the boundary of V
    for x in (5.0, 5.0 - 1e-12, 5.0 + 1e-12):
        assert in_band(pts, 0, [[x, 2.5]])[0], x
    for y in (4.0, 4.0 - 1e-12, 4.0 + 1e-12):
        assert in_band(pts, 0, [[3.5, y]])[0], y
    assert not in_band(pts, 0, [[3.5, 3.0 - 1e-6]])[0]  # interior of V
    # in units of h on oblong pixels the same point is on the edge
    grid, _ = R._make_grid(0.617, 0.667, 1, dz=1.0)
    assert R._in_band(pts, 0, 5 * (0.617 / 0.667) * (1 - 1e-16), 2.5, grid)


def test_drawn_rings_on_uneven_sections_are_refined_on_their_raster():
    """Real-valued rings (a ball's sections) on unevenly spaced heights: refused before, now
    refined on their raster like evenly spaced ones."""
    rad = 9.0
    zs = uneven_heights(rad - 0.3, seed=7)
    zs = zs[np.abs(zs) < rad - 0.3]
    t = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    secs = tuple(Section(z=float(z), contours=(np.c_[np.cos(t), np.sin(t)] * np.sqrt(rad**2 - z**2) + [0.3, -0.2],))
                 for z in zs)
    m = contourmesh.mesh(ContourStack(sections=secs), refine="band", pixel=0.5)
    chk = assert_closed_outward(m, genus=0)
    assert m.meta["route"] == "raster-refined" and chk["self_intersections"] == 0
    # the sections end inside the ball (0.3 mm or more short of its poles): a little less area
    assert -0.015 < m.area / (4 * np.pi * rad**2) - 1 < 0.0  # -0.43 %
