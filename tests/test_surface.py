"""Analytic shapes -> closed, outward-oriented meshes, for every polygon x triangulation."""

import itertools

import numpy as np
import pytest

import contourmesh
from conftest import assert_closed_outward
from contourmesh.bands import TRIANGULATORS
from contourmesh.digitize import outer_jordan_stack
from contourmesh.errors import ThinRegionError
from contourmesh.polygons import POLYGONIZERS
from contourmesh.shapes import Cone, Ellipsoid, Hyperboloid, Paraboloid, Sphere, rotation_from_euler
from contourmesh.surface import stack_to_mesh
from contourmesh.types import ContourStack, Section

POLYGONS = tuple(sorted(POLYGONIZERS))
TRIANGULATIONS = tuple(sorted(TRIANGULATORS))  # every registered band, arclength included
COMBOS = list(itertools.product(POLYGONS, TRIANGULATIONS))

rng = np.random.default_rng(20091)
SHAPES = [
    Sphere(12),
    Sphere(17.5, center=tuple(rng.random(3))),
    Ellipsoid(14, 9, 6, center=tuple(rng.random(3))),
    Ellipsoid(10, 6, 6),  # the paper's smallest spheroid
    Ellipsoid(6, 10, 13, center=tuple(rng.random(3))),
    Cone(9.0, 4.0, 12.0, center=(0.3, 0.2, 0.0)),
    Cone(9.0, 0.0, 12.0, center=(0.3, 0.2, 0.0)),
    Hyperboloid(6.0, 8.0, 16.0, center=(0.1, 0.4, 0.0)),
    Paraboloid(3.0, 14.0, center=(0.25, 0.5, 0.0)),
    Ellipsoid(14, 9, 6, center=(0.2, 0.3, 0.1), rotation=rotation_from_euler(0, 0, 33)),
]


_STACKS = {}


@pytest.mark.parametrize("polygon,tri", COMBOS, ids=lambda v: v)
@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.spec if hasattr(s, "spec") else repr(s))
def test_every_shape_meshes_closed_for_every_combination(shape, polygon, tri):
    stack = _STACKS.get(id(shape)) or _STACKS.setdefault(id(shape), outer_jordan_stack(shape))
    m = stack_to_mesh(stack, polygon=polygon, triangulation=tri)
    assert_closed_outward(m, genus=0)
    e = m.area / shape.area - 1
    # the contour itself and DSS overestimate (outer digitization); MLP is close
    bound = {"mlp": 0.12, "dss": 0.35, "none": 0.6}[polygon]
    assert abs(e) < bound, (polygon, tri, e)
    assert m.volume == pytest.approx(shape.volume, rel=0.35)


def test_optimal_band_never_above_the_others_on_whole_meshes():
    stack = outer_jordan_stack(Sphere(20, center=(0.31, 0.17, 0.43)))
    for polygon in POLYGONS:
        areas = {t: stack_to_mesh(stack, polygon=polygon, triangulation=t).area for t in TRIANGULATIONS}
        assert areas["optimal"] <= areas["wiederhold"] + 1e-9
        assert areas["optimal"] <= areas["greedy"] + 1e-9


def test_P_counts_polygon_vertices_and_mlp_is_smaller_than_contour():
    stack = outer_jordan_stack(Sphere(20))
    ms = {p: stack_to_mesh(stack, polygon=p) for p in POLYGONS}
    for m in ms.values():
        assert m.P == len(m.vertices)
    assert ms["dss"].P < ms["mlp"].P < ms["none"].P
    assert ms["none"].P == sum(len(s.contours[0]) for s in stack.sections)


def test_poles_fan_and_caps():
    # centred sphere: one-point poles at z = +-r; no flat cap faces (all faces join two heights)
    m = contourmesh.mesh(Sphere(10))
    z = m.vertices[:, 2]
    assert z.min() == -10 and z.max() == 10
    assert np.sum(z == 10) == 1 and np.sum(z == -10) == 1
    flat = np.ptp(z[m.faces], axis=1) == 0
    assert not flat.any()
    # off-grid centre: the end slices are closed by flat caps
    m = contourmesh.mesh(Sphere(10, center=(0.3, 0.1, 0.2)))
    z = m.vertices[:, 2]
    flat = np.ptp(z[m.faces], axis=1) == 0
    assert flat.any()
    assert set(np.unique(z[m.faces[flat]])) == {z.min(), z.max()}


def test_half_caps_add_the_prism():
    shape = Cone(8.0, 5.0, 10.0)
    flat = contourmesh.mesh(shape, caps="flat")
    half = contourmesh.mesh(shape, caps="half")
    assert_closed_outward(half)
    z = half.vertices[:, 2]
    assert z.min() == -0.5 and z.max() == 10.5
    assert half.volume > flat.volume
    assert half.area > flat.area


def test_scale_and_translation():
    a = contourmesh.mesh(Sphere(9, center=(0.25, 0.5, 0.125)))
    b = contourmesh.mesh(Sphere(9, center=(3.25, -4.5, 2.125)))
    assert a.area == pytest.approx(b.area, rel=1e-12)
    c = contourmesh.mesh(Sphere(4.5, center=(0.125, 0.25, 0.0625)), h=0.5)
    assert c.area == pytest.approx(a.area / 4, rel=1e-12)


def test_spec_strings_and_bad_sources():
    m = contourmesh.mesh("ellipsoid:a=9,b=6,c=5,center=0.1;0.2;0.3", polygon="dss", triangulation="greedy")
    assert_closed_outward(m)
    assert m.meta["area_true"] == pytest.approx(Ellipsoid(9, 6, 5).area)
    with pytest.raises(TypeError, match="cannot mesh"):
        contourmesh.mesh(42)
    with pytest.raises(ValueError):
        contourmesh.mesh("sphere:r=-3")
    with pytest.raises(ValueError, match="caps"):
        contourmesh.mesh(Sphere(5), caps="dome")
    with pytest.raises(ValueError, match="polygon|method"):
        contourmesh.mesh(Sphere(5), polygon="convexhull")
    with pytest.raises(ValueError, match="triangulation|method"):
        contourmesh.mesh(Sphere(5), triangulation="delaunay")


def rect(x0, y0, w, h):
    """A w x h rectangle as a digital 4-contour (unit steps, positive shoelace area)."""
    pts = [(x0 + i, y0) for i in range(w)] + [(x0 + w, y0 + j) for j in range(h)]
    pts += [(x0 + w - i, y0 + h) for i in range(w)] + [(x0, y0 + h - j) for j in range(h)]
    return np.array(pts)


def test_handmade_stack_with_degenerate_polygons():
    sq = lambda x0, y0, s: rect(x0, y0, s, s)
    # pole point, a thin 3 x 2 contour in the middle (U of a row of points: its MLP is a segment),
    # and a square top
    line = rect(0, 0, 3, 2)
    st = ContourStack(
        sections=(
            Section(0.0, (np.array([[1, 1]]),)),
            Section(1.0, (sq(-1, -1, 4),)),
            Section(2.0, (sq(-2, -2, 6),)),
            Section(3.0, (line,)),
            Section(4.0, (sq(-1, -1, 4),)),
        )
    )
    for polygon, tri in COMBOS:
        assert_closed_outward(stack_to_mesh(st, polygon=polygon, triangulation=tri), genus=0)


def test_contour_one_cell_thin_is_not_an_outer_jordan_contour():
    st = ContourStack(sections=(Section(0.0, (rect(0, 0, 3, 1),)), Section(1.0, (rect(0, 0, 3, 2),))))
    with pytest.raises(ThinRegionError, match="outer Jordan"):  # typed, so the front door can reroute it
        stack_to_mesh(st, polygon="mlp")
    assert issubclass(ThinRegionError, ValueError)
    assert_closed_outward(stack_to_mesh(st, polygon="none"))


def test_stack_validation():
    with pytest.raises(ValueError, match="empty"):
        stack_to_mesh(ContourStack(sections=()))
    sq = rect(0, 0, 2, 2)
    with pytest.raises(ValueError, match="increasing"):
        stack_to_mesh(ContourStack(sections=(Section(1.0, (sq,)), Section(0.0, (sq,)))))


def test_single_section_is_a_prism():
    sq = rect(0, 0, 3, 2)
    m = stack_to_mesh(ContourStack(sections=(Section(5.0, (sq,)),)))
    assert_closed_outward(m)
    assert m.volume == pytest.approx(6.0)


def test_torus_lying_flat_joins_outer_and_hole_chains():
    from contourmesh.shapes import Torus

    shape = Torus(12, 4, center=(0.3, 0.1, 0.2))
    stack = outer_jordan_stack(shape)
    assert all(len(s.contours) == 2 for s in stack.sections)
    for polygon, tri in COMBOS:
        m = stack_to_mesh(stack, polygon=polygon, triangulation=tri)
        assert_closed_outward(m, genus=1)
    m = contourmesh.mesh(shape, polygon="mlp", triangulation="optimal")
    assert "exact_joins" not in m.meta  # the paper's path, not the volume mesher
    assert abs(m.area / shape.area - 1) < 0.03


def test_standing_torus_goes_through_the_volume_mesher():
    from contourmesh.shapes import Torus

    shape = Torus(10, 3, center=(0.3, 0.1, 0.2), rotation=rotation_from_euler(90, 0, 0))
    m = contourmesh.mesh(shape)
    assert_closed_outward(m, genus=1)
    assert m.meta["exact_joins"] + m.meta["bridged_joins"] >= 1
    with pytest.raises(ValueError, match="cannot join"):
        stack_to_mesh(outer_jordan_stack(shape))


def test_unique_rows_kernel_is_the_lexsort_reference_bit_for_bit():
    """The compiled row merge of the stack mesher's builder gives the rows (zeros' signs included)
    and the inverse of its numpy reference (``np.lexsort``), on rows with repeats and signed zeros."""
    from contourmesh.surface import _Builder, _unique_rows_kernel

    rng = np.random.default_rng(93)
    for n in (0, 1, 2, 3, 9, 64, 500):
        p = np.round(rng.normal(size=(n, 2)) * 3) / 2
        p = np.vstack([p, p[: n // 2][::-1], [[0.0, -0.0], [-0.0, 0.0], [0.0, 0.0], [-0.0, -0.0]]])
        p = p[rng.permutation(len(p))]
        got_u, got_i = _unique_rows_kernel(np.ascontiguousarray(p))
        want_u, want_i = _Builder._unique_rows_reference(p)
        assert got_u.tobytes() == want_u.tobytes() and got_i.dtype == want_i.dtype
        assert np.array_equal(got_i, want_i) and np.array_equal(got_u[got_i], p)


def test_builder_unique_rows_match_np_unique():
    from contourmesh.surface import _Builder

    rng = np.random.default_rng(3)
    b = _Builder((0.5, 0.7), (1.0, 0.0))
    for n in (1, 2, 5, 60, 400):
        p = np.round(rng.normal(size=(n, 2)) * 4) / 2
        p = np.vstack([p, p[: n // 3], [[0.0, -0.0], [-0.0, 0.0], [0.0, 0.0]]])
        uniq, inverse = b._unique_rows(p)
        want_u, want_i = np.unique(p, axis=0, return_inverse=True)
        assert np.array_equal(uniq, want_u) and np.array_equal(inverse, want_i.reshape(-1))
        # the vertices the builder makes are the same bytes (a zero's sign disappears in x * s + o)
        assert (uniq * 0.5 + 1.0).tobytes() == (want_u * 0.5 + 1.0).tobytes()
        assert (uniq[:, 1] * 0.7 + 0.0).tobytes() == (want_u[:, 1] * 0.7 + 0.0).tobytes()
    neg = _Builder((1.0, 1.0), (-0.0, 2.0))  # an origin of -0.0 keeps np.unique's own choice
    p = np.array([[0.0, 1.0], [-0.0, 1.0], [1.0, 1.0]])
    assert neg._unique_rows(p)[0].tobytes() == np.unique(p, axis=0).tobytes()


def _band_is_folded_numpy(faces):
    """The numpy form of ``bands.band_is_folded`` before it was compiled."""
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return False
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    key = np.sort(e[:, 0] * (int(f.max()) + 1) + e[:, 1])
    return bool(len(key) > 2 and (key[2:] == key[:-2]).any())


def test_band_is_folded_kernel_matches_numpy():
    from contourmesh.bands import band_is_folded

    rng = np.random.default_rng(5)
    lo = np.c_[np.cos(np.linspace(0, 6, 9)), np.sin(np.linspace(0, 6, 9)), np.zeros(9)]
    hi = np.c_[lo[:7, :2] * 0.8, np.ones(7)]
    seen = set()
    for name, fn in TRIANGULATORS.items():
        f = fn(lo, hi)
        assert band_is_folded(f) is _band_is_folded_numpy(f) is False, name
    for _ in range(300):
        f = rng.integers(0, rng.integers(3, 12), size=(rng.integers(1, 9), 3))
        want = _band_is_folded_numpy(f)
        seen.add(want)
        assert band_is_folded(f) is want
    assert seen == {True, False}
    assert band_is_folded(np.zeros((0, 3), np.int64)) is False


def test_band_is_folded_by_buckets_and_by_sorting_agree():
    # _folded counts each edge in buckets where the vertex numbers are small next to the number of
    # edges, and sorts keys otherwise (a band's faces in a join's numbering): both as the numpy form,
    # on random faces, on bands with a doubled diagonal, and with vertex numbers offset far
    from contourmesh.bands import _folded, _folded_sorted, band_is_folded

    rng = np.random.default_rng(6)
    seen = set()
    for t in range(600):
        nv = int(rng.integers(3, 60))
        f = rng.integers(0, nv, size=(int(rng.integers(1, 3 * nv)), 3))
        if t % 3 == 1:  # a band: fans between two rings, one diagonal used again
            n = int(rng.integers(3, 30))
            f = np.array([[i, (i + 1) % n, n + i] for i in range(n)] + [[(i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)])
            if t % 2:
                f = np.concatenate([f, f[int(rng.integers(len(f)))][None]])
        if t % 5 == 4:
            f = f + int(rng.integers(10**4, 10**6))  # (the sorting route)
        want = _band_is_folded_numpy(f)
        seen.add(want)
        g = np.ascontiguousarray(f, dtype=np.int64)
        assert band_is_folded(f) is want
        assert bool(_folded(g)) is bool(_folded_sorted(g)) is want
    assert seen == {True, False}
