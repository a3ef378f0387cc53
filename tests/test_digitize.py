"""Outer Jordan digitization of analytic shapes into contour stacks (paper, section 6)."""

import math

import numpy as np
import pytest

from contourmesh.digitize import gauss_volume, grid_box, mask_stack, outer_jordan_stack, sample_volume, uneven_heights
from contourmesh.shapes import Cone, Ellipsoid, Paraboloid, Sphere, Torus, rotation_from_euler
from contourmesh.types import ContourStack, shoelace_area


def _boundary_points_of_U(I_points):
    """Grid points on the boundary of U = union of closed cells with a corner in I (independent)."""
    I = set(I_points)
    cells = set()
    for x, y in I:  # cells named by their lower-left corner
        cells.update({(x - 1, y - 1), (x, y - 1), (x - 1, y), (x, y)})
    pts = set()
    for cx, cy in cells:
        for p in [(cx, cy), (cx + 1, cy), (cx, cy + 1), (cx + 1, cy + 1)]:
            incident = [(p[0] - 1, p[1] - 1), (p[0], p[1] - 1), (p[0] - 1, p[1]), (p[0], p[1])]
            if not all(c in cells for c in incident):
                pts.add(p)
    return pts, len(cells)


def _check_contour(c):
    assert c.dtype == np.int64 and c.ndim == 2 and c.shape[1] == 2
    steps = np.abs(np.diff(np.vstack([c, c[:1]]), axis=0)).sum(axis=1)
    assert np.all(steps == 1), "consecutive points must be 4-adjacent, closed, no repeat"


@pytest.fixture(scope="module")
def sphere15():
    return outer_jordan_stack(Sphere(15), poles=False)


def test_sphere15_slices_and_points(sphere15):
    st = sphere15
    assert isinstance(st, ContourStack)
    # strict inside: the poles (0, 0, +-15) are on the surface, so I is empty there -> 29 slices
    assert len(st) == 29
    np.testing.assert_array_equal(st.z, np.arange(-14, 15, dtype=float))
    assert st.spacing == (1.0, 1.0) and st.origin == (0.0, 0.0)
    for sec in st.sections:
        assert len(sec.contours) == 1 and sec.parents == (-1,)
        c = sec.contours[0]
        _check_contour(c)
        assert shoelace_area(c) > 0
        k = int(sec.z)
        I = [(x, y) for x in range(-16, 17) for y in range(-16, 17) if x * x + y * y + k * k < 225]
        expected, ncells = _boundary_points_of_U(I)
        assert set(map(tuple, c.tolist())) == expected
        assert shoelace_area(c) == ncells  # U's area in cells
        assert not (set(I) & set(map(tuple, c.tolist())))


def test_sphere15_closed_keeps_poles():
    st = outer_jordan_stack(Sphere(15), strict=False)
    assert len(st) == 31 and st.z[0] == -15 and st.z[-1] == 15
    for sec in (st.sections[0], st.sections[-1]):
        (c,) = sec.contours  # one-point I -> the 2x2 cells around the pole: 8 boundary points
        assert len(c) == 8 and shoelace_area(c) == 4
        assert np.all(np.abs(c) <= 1)


def test_start_points(sphere15):
    secs = sphere15.sections
    first = secs[0].contours[0]
    ymin = first[:, 1].min()
    assert tuple(first[0]) == (first[first[:, 1] == ymin][:, 0].min(), ymin)
    for prev, cur in zip(secs[:-1], secs[1:]):
        p, c = prev.contours[0][0], cur.contours[0]
        d2 = ((c - p) ** 2).sum(axis=1)
        assert d2[0] == d2.min()  # starts at the point nearest the previous start
        assert math.sqrt(d2[0]) <= 6.0  # and that start is near (slices are similar)


def test_scaled_grid_is_the_same_digitization(sphere15):
    st = outer_jordan_stack(Sphere(7.5), h=0.5, poles=False)
    assert st.spacing == (0.5, 0.5)
    np.testing.assert_array_equal(st.z, 0.5 * sphere15.z)
    for a, b in zip(st.sections, sphere15.sections):
        np.testing.assert_array_equal(a.contours[0], b.contours[0])
    assert st.meta["h"] == 0.5


def test_translation_by_grid_vectors():
    a = outer_jordan_stack(Sphere(9.5, center=(0.25, 0.5, 0.125)))
    b = outer_jordan_stack(Sphere(9.5, center=(3.25, -3.5, 5.125)))
    assert len(a) == len(b)
    np.testing.assert_array_equal(a.z + 5, b.z)
    for sa, sb in zip(a.sections, b.sections):
        np.testing.assert_array_equal(sa.contours[0] + [3, -4], sb.contours[0])


def test_meta():
    s = Ellipsoid(6, 4, 3, center=(0.1, 0.2, 0.3))
    st = outer_jordan_stack(s)
    m = st.meta
    assert m["area_true"] == s.area and m["volume_true"] == s.volume
    assert m["shape"]["name"] == "ellipsoid" and m["shape"]["params"] == {"a": 6.0, "b": 4.0, "c": 3.0}
    assert m["shape"]["center"] == [0.1, 0.2, 0.3] and m["strict"] is True


def test_torus_holes_and_branches():
    st = outer_jordan_stack(Torus(10, 3))
    assert len(st) == 5  # z = -2..2 (z = +-3 touch the tube in circles: no strictly inside points)
    for sec in st.sections:
        assert len(sec.contours) == 2 and sec.parents == (-1, 0)
        outer, hole = sec.contours
        assert shoelace_area(outer) > 0 > shoelace_area(hole)
    # standing torus, off-grid: the top and bottom slices have one contour, the middle two outer ones
    st = outer_jordan_stack(Torus(10, 3, center=(0.1, 0.2, 0.3), rotation=rotation_from_euler(90, 0, 0)))
    counts = [len(s.contours) for s in st.sections]
    assert counts[0] == counts[-1] == 1 and 2 in counts and set(counts) <= {1, 2}
    for sec in st.sections:
        for c, p in zip(sec.contours, sec.parents):
            _check_contour(c)
            assert p == -1 and shoelace_area(c) > 0


@pytest.mark.parametrize(
    "shape",
    [
        Cone(5.0, 3.0, 6.0),
        Paraboloid(2.0, 9.0, center=(0.5, 0.0, 0.0)),
        Ellipsoid(8, 5, 3.5, center=(0.3, 0.1, 0.2), rotation=rotation_from_euler(25, 40, 10)),
        Torus(7, 2.5, center=(0.0, 0.5, 0.0), rotation=rotation_from_euler(60, 0, 0)),
    ],
    ids=repr,
)
def test_stack_agrees_with_gauss_volume(shape):
    st = outer_jordan_stack(shape)
    vol, (x0, y0, z0) = gauss_volume(shape)
    assert not vol[0].any() and not vol[-1].any() and not vol[:, 0].any() and not vol[:, :, -1].any()
    nonempty = [z0 + k for k in range(vol.shape[0]) if vol[k].any()]
    np.testing.assert_array_equal(st.z, nonempty)
    for sec in st.sections:
        k = int(round(sec.z - z0))
        jj, ii = np.nonzero(vol[k])
        I = list(zip((ii + int(x0)).tolist(), (jj + int(y0)).tolist()))
        expected, ncells = _boundary_points_of_U(I)
        got = set()
        for c in sec.contours:
            _check_contour(c)
            got |= set(map(tuple, c.tolist()))
        assert got == expected
        assert sum(shoelace_area(c) for c in sec.contours) == ncells


def test_truncated_end_slices():
    st = outer_jordan_stack(Cone(5.0, 3.0, 6.0))
    np.testing.assert_array_equal(st.z, np.arange(0, 7))  # closed end planes at z = 0 and z = 6
    top = st.sections[-1].contours[0]
    I = [(x, y) for x in range(-4, 5) for y in range(-4, 5) if x * x + y * y < 9]
    assert set(map(tuple, top.tolist())) == _boundary_points_of_U(I)[0]
    st = outer_jordan_stack(Paraboloid(2.0, 9.0), poles=False)
    np.testing.assert_array_equal(st.z, np.arange(1, 10))  # the apex z = 0 is on the surface
    st = outer_jordan_stack(Paraboloid(2.0, 9.0))
    np.testing.assert_array_equal(st.z, np.arange(0, 10))  # ... and is kept as a one-point pole
    assert st.sections[0].contours[0].tolist() == [[0, 0]]


def test_grid_point_poles_become_one_point_sections():
    st = outer_jordan_stack(Sphere(15))
    assert len(st) == 31 and st.z[0] == -15 and st.z[-1] == 15
    assert st.sections[0].contours[0].tolist() == [[0, 0]]
    assert st.sections[-1].contours[0].tolist() == [[0, 0]]
    # an off-grid pole gives no pole section: the end slices are ordinary contours
    st = outer_jordan_stack(Sphere(15, center=(0.3, 0.1, 0.2)))
    assert all(len(s.contours[0]) > 1 for s in st.sections)


def test_gauss_volume_counts():
    s = Sphere(20, center=(0.3, 0.1, 0.2))
    vol, origin = gauss_volume(s)
    assert vol.dtype == bool and vol.ndim == 3
    assert vol.sum() == pytest.approx(s.volume, rel=0.01)
    # voxel [k, j, i] is the grid point origin + (i, j, k)
    k, j, i = np.argwhere(vol)[0]
    assert s.contains(origin[0] + i, origin[1] + j, origin[2] + k)
    box = grid_box(s)
    assert origin == tuple(float(v) for v in box[0])
    v2, o2 = gauss_volume(s, h=0.5, pad=0)
    assert v2.sum() == pytest.approx(s.volume / 0.125, rel=0.005) and o2[2] == pytest.approx(-20.0)


def test_rotation_and_offset_accepted():
    s = Ellipsoid(9, 5, 4, center=(0.37, -0.21, 0.55), rotation=rotation_from_euler(15, 30, 45))
    st = outer_jordan_stack(s)
    assert len(st) > 10
    for sec in st.sections:
        for c in sec.contours:
            _check_contour(c)
            assert shoelace_area(c) > 0


def test_input_validation():
    with pytest.raises(ValueError, match="positive"):
        outer_jordan_stack(Sphere(3), h=0)
    with pytest.raises(ValueError, match="positive"):
        gauss_volume(Sphere(3), h=-1.0)
    with pytest.raises(ValueError, match="number"):
        outer_jordan_stack(Sphere(3), h="fine")
    with pytest.raises(ValueError, match="Shape"):
        outer_jordan_stack("sphere:r=3")
    with pytest.raises(ValueError, match="pad"):
        gauss_volume(Sphere(3), pad=-1)


def test_sample_volume_on_a_cubic_grid_is_the_gauss_digitization():
    e = Ellipsoid(4.3, 3.1, 2.7, center=(0.21, -0.37, 0.13))
    vol, org = gauss_volume(e, 0.5, pad=1)
    mask, z, org2 = sample_volume(e, (0.5, 0.5, 0.5), pad=1)
    assert mask.shape == vol.shape and np.array_equal(mask, vol)
    assert np.allclose(org2, org) and np.allclose(z, org[2] + 0.5 * np.arange(len(z)))


def test_sample_volume_on_oblong_pixels_and_uneven_heights_meshes_within_a_few_percent():
    import contourmesh

    s = Sphere(6.0, center=(0.31, 0.17, 0.05))
    sp = (0.9, 0.617, 0.667)
    zs = uneven_heights(6.0, seed=5)
    mask, z, org = sample_volume(s, sp, zs)
    assert np.array_equal(z, zs) and mask.shape[0] == len(zs)
    assert not mask[0].any() and not mask[-1].any()  # the heights cover the ball with room to spare
    m = contourmesh.mesh(mask, spacing=sp, z=z, origin=org, refine="band")
    assert abs(m.area / s.area - 1) < 0.02
    st = mask_stack(mask, z, sp, org)
    assert len(st.sections) == int(mask.any(axis=(1, 2)).sum())
    assert st.spacing == (0.667, 0.617) and st.sections[0].z == z[mask.any(axis=(1, 2))][0]


@pytest.mark.parametrize("kw, msg", [
    ({"spacing": (1.0, 0.0, 1.0)}, "spacing"),
    ({"spacing": (1.0, 1.0)}, "spacing"),
    ({"spacing": (1.0, 1.0, 1.0), "z": [0.0, 0.0, 1.0]}, "increasing"),
    ({"spacing": (1.0, 1.0, 1.0), "z": [0.0, np.nan]}, "increasing"),
    ({"spacing": (1.0, 1.0, 1.0), "pad": -1}, "pad"),
])
def test_sample_volume_rejects_bad_grids(kw, msg):
    with pytest.raises(ValueError, match=msg):
        sample_volume(Sphere(2.0), **kw)
