"""Issue 15: caps of real-valued rings with collinear runs, no silent route change, and the smooth cap."""

import math
import warnings
from collections import Counter

import numpy as np
import pytest

import contourmesh
from conftest import assert_closed_outward
from contourmesh.bands.caps import cap_faces, collinear_runs
from contourmesh.compare.phantoms import cylinder, draw, keyhole_tube, sphere
from contourmesh.errors import ContourMeshError, InapplicableOption, RasterFallbackWarning
from contourmesh.geometry import shoelace_area
from contourmesh.io.contours import write_contours_json
from contourmesh.stacks import stack_from_rings
from contourmesh.surface import stack_to_mesh


def _square_with_runs(per_side=10, side=10.0, angle=0.3, shift=(0.123, -7.77)):
    """A square of ``per_side`` points a side (collinear runs), rotated so that no coordinate is round."""
    t = np.linspace(0.0, side, per_side, endpoint=False)
    z = np.zeros_like(t)
    sq = np.vstack([np.c_[t, z], np.c_[z + side, t], np.c_[side - t, z + side], np.c_[z, side - t]])
    c, s = math.cos(angle), math.sin(angle)
    return sq @ np.array([[c, s], [-s, c]]) + np.asarray(shift)


# A ring of an exported planning-system structure (dicompyler-core's sample, 'Lt Lung'): points
# 0..3 lie on one straight line up to round-off; ear clipping left a sliver there and the cap was
# refused as touching itself.
EXPORTED = np.array([[49.95, -255.98], [48.88, -254.91], [47.8, -253.83], [46.73, -252.76], [47.8, -251.41],
                     [49.95, -251.68], [51.03, -252.76], [51.03, -254.91]])


def _assert_cap_covers(ring, faces, upward=True):
    xy = np.asarray(ring, float)
    t = xy[faces]
    s = 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))
    assert np.all(s > 0) if upward else np.all(s < 0)
    scale = float(np.abs(xy).max()) ** 2 * len(xy)  # shoelace round-off grows with the coordinates
    assert abs(s.sum()) == pytest.approx(abs(shoelace_area(xy)), rel=1e-9, abs=1e-13 * scale)
    half = Counter((int(a), int(b)) for f in faces for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])))
    n, ccw = len(xy), shoelace_area(xy) > 0
    for i in range(n):  # every ring edge once, in the cap's direction; no other edge on the rim
        e = (i, (i + 1) % n) if ccw == upward else ((i + 1) % n, i)
        assert half[e] == 1 and half[(e[1], e[0])] == 0


@pytest.mark.parametrize("ring", [_square_with_runs(), _square_with_runs(25, 3.3, 1.1), EXPORTED, EXPORTED[::-1]],
                         ids=["square-10", "square-25", "exported", "exported-cw"])
@pytest.mark.parametrize("upward", [True, False])
def test_collinear_runs_cap_without_cap_error(ring, upward):
    _assert_cap_covers(ring, cap_faces(ring, upward=upward), upward)


def test_notch_lined_up_with_a_third_point_caps():
    """Vertices on one line that are not consecutive (notches whose mouths line up): the cap still uses
    every ring edge once and covers the polygon's area."""
    ring = np.array([[0, 0], [4, 0], [4, 1], [3, 1], [3, 0.5], [2, 0.5], [2, 1], [1, 1], [1, 0.5], [0.5, 0.5],
                     [0.5, 1], [0, 1]], float) * 1.1 + 0.37
    _assert_cap_covers(ring, cap_faces(ring))


def test_collinear_runs_keep_corners_and_spikes():
    sq = _square_with_runs(10)
    keep = collinear_runs(sq)
    assert keep.sum() == 4 and keep[[0, 10, 20, 30]].all()
    spike = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 3], [1, 1], [0, 1]], float)  # out and back
    assert collinear_runs(spike).all()


def test_square_prism_with_runs_stays_on_the_stack_route():
    ring = _square_with_runs(10)
    stack = stack_from_rings([(z, [ring]) for z in (0.0, 2.0, 4.0)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RasterFallbackWarning)
        m = contourmesh.mesh(stack, polygon="none", caps="flat")
    assert m.meta["route"] == "stack"
    assert_closed_outward(m, genus=0)
    assert m.volume == pytest.approx(100.0 * 4.0, rel=1e-9)


def test_exported_structures_cap_and_mesh_on_the_stack_route(shared_data):
    """Rings of the sample RT structure set that were refused as touching themselves cap: collinear runs
    (Heart, Tumor Bed Block) and, in the lowest Lt Lung sections, a zero-area ear across a notch; the
    set's one-ring-per-section structures mesh as drawn, with the smooth cap too."""
    from contourmesh.io.contours import read_contours

    path = shared_data / "contours" / "dicompyler-core" / "rtss.dcm"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    for name, zmax in (("Heart", np.inf), ("Tumor Bed Block", np.inf), ("Lt Lung", -98.0)):
        sections = [sec for sec in read_contours(path, roi=name).sections if sec.z <= zmax]
        assert sections
        for sec in sections:
            for ring in sec.contours:
                _assert_cap_covers(ring, cap_faces(ring))
    for name in ("Heart", "Tumor Bed"):
        with warnings.catch_warnings():
            warnings.simplefilter("error", RasterFallbackWarning)
            m = contourmesh.mesh(path, roi=name, polygon="none", caps="smooth")
        assert m.meta["route"] == "stack"
        assert m.checks()["ok"]


def test_a_stack_route_failure_warns_before_rasterizing():
    stack = draw(keyhole_tube(12, 6, 30), 3.0, 1.0, seed=1)
    with pytest.warns(RasterFallbackWarning, match="meshed on the contours route instead"):
        m = contourmesh.mesh(stack, polygon="none", caps="half")
    assert m.meta["route"] == "contours" and "stack_route_error" in m.meta
    # the keyhole rings touch themselves on the stack route; the contours route splits them at their
    # repeated points into outer rings and holes and meshes those as drawn
    assert m.meta["split_rings"] > 0 and m.meta["unmatched_components"] == 0 and m.checks()["ok"]
    # the smooth cap follows it there (the contours route makes it too)
    with pytest.warns(RasterFallbackWarning, match="meshed on the contours route instead"):
        ms = contourmesh.mesh(stack, polygon="none", caps="smooth")
    assert ms.meta["route"] == "contours" and ms.meta["caps"] == "smooth" and ms.checks()["ok"]


# --- the smooth cap ------------------------------------------------------------------------------
def test_smooth_cap_sphere_volume_and_area():
    ph = sphere(10)
    stack = draw(ph, 1.0, 0.5, seed=3)
    m = contourmesh.mesh(stack, polygon="none", caps="smooth")
    assert m.meta["route"] == "stack" and m.meta["caps"] == "smooth" and m.meta["smooth_fallbacks"] == 0
    assert_closed_outward(m, genus=0)
    assert m.checks()["ok"]
    assert abs(m.volume / ph.volume - 1) < 0.01
    assert abs(m.area / ph.area - 1) < 0.015
    half = contourmesh.mesh(stack, polygon="none", caps="half")
    flat = contourmesh.mesh(stack, polygon="none", caps="flat")
    # the dome holds the half prism's volume, without its side wall
    assert m.volume == pytest.approx(half.volume, rel=1e-9)
    assert flat.area < m.area < half.area
    zs = [s.z for s in stack.sections]
    assert zs[-1] + 0.5 < m.vertices[:, 2].max() < zs[-1] + 1.0
    assert zs[0] - 1.0 < m.vertices[:, 2].min() < zs[0] - 0.5


def test_smooth_cap_on_concave_clockwise_and_coarse_ends():
    # a C-shaped prism given clockwise (not star-shaped: the dome shrinks it toward its centroid)
    c = np.array([[0, 0], [6, 0], [6, 2], [2, 2], [2, 4], [6, 4], [6, 6], [0, 6]], float)[::-1] + 0.25
    stack = stack_from_rings([(0.0, [c]), (1.5, [c * 0.9]), (3.0, [c])])
    m = stack_to_mesh(stack, polygon="none", caps="smooth")
    assert_closed_outward(m, genus=0)
    assert m.checks()["ok"]
    half = stack_to_mesh(stack, polygon="none", caps="half")
    assert m.volume == pytest.approx(half.volume, rel=1e-9)
    # a cylinder drawn with few points: closed; its flat ends make the dome lose the side wall's area
    ph = cylinder(5, 20)
    cyl = draw(ph, 2.0, 1.0, seed=0)
    ms = contourmesh.mesh(cyl, polygon="none", caps="smooth")
    assert_closed_outward(ms, genus=0)
    assert ms.area < contourmesh.mesh(cyl, polygon="none", caps="half").area


def test_smooth_cap_is_refused_where_it_cannot_be_made(tmp_path):
    box = np.zeros((5, 6, 6), bool)
    box[1:4, 1:5, 1:5] = True
    with pytest.raises(InapplicableOption, match="volume mesher"):
        contourmesh.mesh(box, caps="smooth")
    drawn = draw(sphere(5), 1.0, 0.5, seed=0)
    with pytest.raises(InapplicableOption, match="raster route"):
        contourmesh.mesh(drawn, caps="smooth", polygon="mlp")  # real-valued rings, MLP polygons: the raster route
    # route='contours' makes its own smooth ends (test_drawn_fidelity)
    assert contourmesh.mesh(drawn, caps="smooth", route="contours").meta["route"] == "contours"
    # one drawn ring per section, polygon unset: the contours route (polygon='none': the stack route)
    assert contourmesh.mesh(drawn, caps="smooth").meta["route"] == "contours"
    assert contourmesh.mesh(drawn, caps="smooth", polygon="none").meta["route"] == "stack"
    with pytest.raises(ContourMeshError, match="holes"):
        contourmesh.mesh("torus:R=8,r=3", caps="smooth")
    # the refined route and the command line take it
    assert contourmesh.mesh(box, caps="smooth", refine="band").checks()["ok"]
    from contourmesh.cli import main

    write_contours_json(drawn, tmp_path / "s.json")
    assert main(["mesh", str(tmp_path / "s.json"), "-o", str(tmp_path / "s.ply"), "--polygon", "none",
                 "--caps", "smooth", "--json", "--quiet"]) == 0
