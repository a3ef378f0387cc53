"""Issue 15 item 1: contour stacks with several rings per section are meshed between their drawn rings
(the contours route), with the raster deciding only the joins."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import contourmesh
from contourmesh.compare.clinical import _section_area
from contourmesh.compare.phantoms import frustum_volume, section_areas, trapezoid_volume
from contourmesh.errors import InapplicableOption, RasterFallbackWarning
from contourmesh.stacks import stack_from_rings


def circle(cx, cy, r, n=48):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]


def box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def plane_errors(m, stack):
    """Per contour plane: the relative error of the mesh's section just below and just above the plane
    (inner planes both, end planes the inner side) against the drawn even-odd area."""
    tri = np.asarray(m.vertices)[np.asarray(m.faces)]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    zs, ref = stack.z, section_areas(stack)
    out = []
    for k in range(len(zs)):
        sides = []
        if k > 0:
            sides.append(_section_area(tri, nrm, zs[k] - 1e-4 * (zs[k] - zs[k - 1])) / ref[k] - 1)
        if k < len(zs) - 1:
            sides.append(_section_area(tri, nrm, zs[k] + 1e-4 * (zs[k + 1] - zs[k])) / ref[k] - 1)
        out.append(sides)
    return out


def assert_sound(m):
    chk = m.checks()
    assert chk["watertight"] and chk["winding_consistent"] and chk["degenerate_faces"] == 0, chk
    assert chk["self_intersections"] == 0, chk
    assert chk["volume"] > 0


def merge_stack():
    """Two circles that merge into one (an upside-down Y)."""
    return stack_from_rings([(2.0 * k, [circle(-6, 0, 5), circle(6, 0, 5)] if k < 3 else [circle(0, 0, 9, 64)])
                             for k in range(6)], meta={"roi": "merge"})


def test_two_circles_merging_mesh_their_drawn_rings():
    st = merge_stack()
    m = contourmesh.mesh(st)
    assert m.meta["route"] == "contours" and m.meta["polygon"] == "drawn"
    assert m.meta["bridged_joins"] == 1 and m.meta["unmatched_components"] == 0
    assert m.meta["drawn_components"] == sum(len(s.contours) for s in st.sections)
    assert_sound(m)
    for k, sides in enumerate(plane_errors(m, st)):
        # a merge leaves no lid: on both sides of every plane the section is the drawn one
        assert max(abs(e) for e in sides) < 1e-3, (k, sides)
    # the raster route loses area at every plane (its polygons lie inside the drawn rings)
    r = contourmesh.mesh(st, route="raster")
    assert r.meta["route"] == "raster"
    assert max(abs(e) for sides in plane_errors(r, st) for e in sides) > 5e-3


def test_a_fork_y_and_separate_tubes_keep_their_sections_and_volume():
    y = stack_from_rings([(1.5 * k, [circle(0, 0, 6)] if k < 3 else [circle(-4 - k, 0, 4), circle(4 + k, 0, 4)])
                          for k in range(7)])
    m = contourmesh.mesh(y)
    assert m.meta["route"] == "contours" and m.meta["bridged_joins"] == 1
    assert_sound(m)
    assert m.checks()["components"] == 1
    assert all(max(abs(e) for e in sides) < 1e-3 for sides in plane_errors(m, y))
    # two straight tubes: the volume is exactly the rules' (equal sections)
    tubes = stack_from_rings([(2.0 * k, [circle(-8, 0, 5), circle(8, 0, 5)]) for k in range(4)])
    t = contourmesh.mesh(tubes)
    assert_sound(t)
    assert t.checks()["components"] == 2
    assert t.volume == pytest.approx(trapezoid_volume(tubes), rel=1e-9)
    assert frustum_volume(tubes) == pytest.approx(trapezoid_volume(tubes), rel=1e-12)


def test_a_hole_that_closes_and_nested_islands():
    st = stack_from_rings([(2.0 * k, [circle(0, 0, 10, 64), circle(0, 0, 4)] if k < 3 else [circle(0, 0, 10, 64)])
                           for k in range(6)])
    assert st.sections[0].parents == (-1, 0)
    m = contourmesh.mesh(st)
    assert m.meta["route"] == "contours" and m.meta["unmatched_components"] == 0
    assert m.meta["drawn_rings"] == sum(len(s.contours) for s in st.sections)
    assert_sound(m)
    assert m.checks()["genus"] == 0
    for k, sides in enumerate(plane_errors(m, st)):
        # the hole is closed by a flat lid in plane 2: the section above that plane holds the lid,
        # the one below is the drawn annulus
        assert min(abs(e) for e in sides) < 1e-3, (k, sides)
    # an island inside the hole of a ring (nested rings: even-odd)
    isl = stack_from_rings([(2.0 * k, [circle(0, 0, 10, 64), circle(0, 0, 6), circle(0, 0, 3, 24)]) for k in range(3)])
    assert isl.sections[0].parents == (-1, 0, -1)
    mi = contourmesh.mesh(isl)
    assert mi.meta["unmatched_components"] == 0 and mi.checks()["components"] == 2
    assert_sound(mi)
    assert all(max(abs(e) for e in sides) < 1e-3 for sides in plane_errors(mi, isl))


def test_an_exact_join_keeps_the_drawn_rings():
    # two bars below, two crossing bars above: the overlaps close a loop (a handle), an exact join
    lo = [box(-10, -6, 10, -2), box(-10, 2, 10, 6)]
    hi = [box(-6, -10, -2, 10), box(2, -10, 6, 10)]
    st = stack_from_rings([(0.0, lo), (2.0, lo), (4.0, hi), (6.0, hi)])
    m = contourmesh.mesh(st)
    assert m.meta["route"] == "contours" and m.meta["exact_joins"] == 1
    assert m.meta["unmatched_components"] == 0
    assert_sound(m)
    assert m.checks()["genus"] == 1
    errs = plane_errors(m, st)
    # planes 1 and 2 face the exact join on one side; the band side is the drawn section
    assert all(min(abs(e) for e in sides) < 1e-3 for sides in errs)


def test_rings_the_raster_cannot_match_are_named_and_meshed_from_the_raster():
    # two rings that cross each other in section 1: the even-odd fill is not their nesting
    st = stack_from_rings([(0.0, [circle(0, 0, 6)]), (2.0, [circle(-2, 0, 6), circle(2, 0, 6)]),
                           (4.0, [circle(0, 0, 6)])], meta={"roi": "Crossing"})
    with pytest.warns(RasterFallbackWarning, match=r"Crossing: .*section 1 \(z=2\)"):
        m = contourmesh.mesh(st)
    assert m.meta["route"] == "contours" and m.meta["unmatched_components"] >= 1
    assert m.meta["drawn_components"] == 2  # the sections above and below keep theirs
    assert_sound(m)


def test_options_that_do_not_apply_to_the_contours_route_are_refused():
    st = merge_stack()
    with pytest.raises(InapplicableOption, match="polygon='mlp' does not apply with route='contours'"):
        contourmesh.mesh(st, route="contours", polygon="mlp")
    # caps='smooth' is made on the contours route too (its ends: test_drawn_fidelity)
    assert contourmesh.mesh(st, caps="smooth").meta["caps"] == "smooth"
    with pytest.raises(InapplicableOption, match="route= does not apply to an array"):
        contourmesh.mesh(np.ones((3, 3, 3), bool), route="raster")
    # drawn rings are refined on their raster: route='raster' says so, route='contours' is refused
    assert contourmesh.mesh(st, route="raster", refine="band").meta["route"] == "raster-refined"
    with pytest.raises(InapplicableOption, match="route='contours' does not apply with refine='band'"):
        contourmesh.mesh(st, route="contours", refine="band")
    with pytest.raises(ValueError, match="unknown route"):
        contourmesh.mesh(st, route="drawn")
    # polygon='mlp' on drawn rings asks for the raster's polygons: the raster route, recorded
    assert contourmesh.mesh(st, polygon="mlp").meta["route"] == "raster"
    # one ring per section: polygon='none' keeps the stack route (caps='smooth' too); route= picks another
    one = stack_from_rings([(2.0 * k, [circle(0, 0, 5)]) for k in range(4)])
    assert contourmesh.mesh(one, caps="smooth").meta["route"] == "contours"
    assert contourmesh.mesh(one, caps="smooth", polygon="none").meta["route"] == "stack"
    assert contourmesh.mesh(one, polygon="none").meta["route"] == "stack"
    assert contourmesh.mesh(one).meta["route"] == "contours"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert contourmesh.mesh(one, route="raster").meta["route"] == "raster"


def test_missing_sections_inside_a_structure_are_bridged_by_one_band():
    """Issue 15 item 4, missing slices: sections left out inside a structure (here three of a cone's)
    are not filled in; the rings on either side of the gap are joined by one band across it, as
    between any two consecutive sections, so the mesh's section inside the gap is the band's
    (radius interpolated linearly) and its volume stays within the rules over the drawn sections."""
    zs = [float(z) for z in range(11) if z not in (4, 5, 6)]
    stack = stack_from_rings([(z, [circle(0.0, 0.0, 10.0 - 0.6 * z)]) for z in zs])
    m = contourmesh.mesh(stack)
    chk = m.checks()
    assert m.meta["route"] == "contours" and chk["ok"] and chk["components"] == 1
    lo, hi = frustum_volume(stack), trapezoid_volume(stack)
    assert lo * (1 - 1e-3) <= m.volume <= hi * (1 + 1e-3)
    tri = np.asarray(m.vertices)[np.asarray(m.faces)]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ring = circle(0.0, 0.0, 10.0 - 0.6 * 5.0)
    drawn_mid = abs(float(np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1]))) / 2
    assert _section_area(tri, nrm, 5.0) == pytest.approx(drawn_mid, rel=0.01)
    assert all(abs(e) <= 0.005 for sides in plane_errors(m, stack) for e in sides)
