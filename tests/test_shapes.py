"""Analytic shapes: closed forms vs quadrature, the exact inside test, placement, spec strings."""

import math
from fractions import Fraction

import numpy as np
import pytest

from contourmesh.shapes import (
    SHAPES,
    Cone,
    Ellipsoid,
    Hyperboloid,
    Paraboloid,
    Sphere,
    Spheroid,
    Torus,
    ellipsoid_area,
    ellipsoid_area_quad,
    parse_shape_spec,
    rotation_from_euler,
    spheroid_area,
)

ALL_SHAPES = [
    Sphere(7.5),
    Ellipsoid(3.0, 2.0, 1.0),
    Ellipsoid(2.0, 5.0, 3.5),
    Spheroid(10, 6),
    Spheroid(6, 10),
    Cone(5.0, 2.0, 7.0),
    Cone(2.0, 5.0, 3.0),
    Cone(4.0, 0.0, 9.0),
    Hyperboloid(3.0, 4.0, 10.0),
    Hyperboloid(8.0, 2.5, 6.0),
    Paraboloid(2.0, 9.0),
    Paraboloid(7.0, 1.5),
    Torus(30.0, 9.0),
    Torus(5.0, 4.5),
]


# ---------------------------------------------------------------------------- areas, volumes
@pytest.mark.parametrize("shape", ALL_SHAPES, ids=repr)
def test_closed_forms_match_quadrature(shape):
    assert shape.area == pytest.approx(shape.area_quad(), rel=1e-9)
    assert shape.volume == pytest.approx(shape.volume_quad(), rel=1e-9)


def test_paper_table2_spheroid_areas():
    # Table 2 of the paper, column A (prolate spheroids a > b, b = c)
    table = {(10, 6): 663.17, (15, 8): 1300.82, (20, 10): 2147.84, (25, 13): 3509.78, (30, 15): 4832.65,
             (35, 17): 6364.80}
    for (a, b), area in table.items():
        assert round(spheroid_area(a, b), 2) == pytest.approx(area, abs=1e-9)
        assert Ellipsoid(a, b, b).area == pytest.approx(area, abs=0.006)


def test_ellipsoid_limits_and_symmetry():
    assert ellipsoid_area(4, 4, 4) == pytest.approx(4 * math.pi * 16, rel=1e-14)
    assert Sphere(4).area == pytest.approx(4 * math.pi * 16, rel=1e-14)
    # Legendre's elliptic form against the paper's spheroid closed forms (prolate and oblate)
    for a, b in [(10, 6), (6, 10), (3, 2.999), (1, 50)]:
        ref = spheroid_area(a, b)
        for axes in [(a, b, b), (b, a, b), (b, b, a)]:
            assert ellipsoid_area(*axes) == pytest.approx(ref, rel=1e-12)
    # near-sphere: no cancellation trouble
    assert ellipsoid_area(5, 5 + 1e-9, 5 - 1e-9) == pytest.approx(4 * math.pi * 25, rel=1e-9)
    # general ellipsoid: elliptic integrals vs nested quadrature, order-independent
    for axes in [(3, 2, 1), (10, 1, 0.5), (1, 7, 2)]:
        ref = ellipsoid_area_quad(*axes)
        assert ellipsoid_area(*axes) == pytest.approx(ref, rel=1e-9)
        assert ellipsoid_area(*reversed(axes)) == pytest.approx(ref, rel=1e-9)
    # flat limit: a disc of radius 1 counted twice
    assert ellipsoid_area(1, 1, 1e-9) == pytest.approx(2 * math.pi, rel=1e-6)


def test_known_formulas():
    R, r = 30.0, 9.0
    assert Torus(R, r).area == pytest.approx(4 * math.pi**2 * R * r, rel=1e-14)
    assert Torus(R, r).volume == pytest.approx(2 * math.pi**2 * R * r**2, rel=1e-14)
    r0, r1, H = 5.0, 2.0, 4.0  # slant 5
    cone = Cone(r0, r1, H)
    assert cone.area == pytest.approx(math.pi * (r0 + r1) * 5.0 + math.pi * (r0**2 + r1**2), rel=1e-14)
    assert cone.volume == pytest.approx(math.pi * H / 3 * (r0**2 + r0 * r1 + r1**2), rel=1e-14)
    # cylinder-like limit of a cone and a flat hyperboloid
    assert Cone(3, 3, 5).area == pytest.approx(2 * math.pi * 3 * 5 + 2 * math.pi * 9, rel=1e-14)
    assert Hyperboloid(3, 1e6, 5).area == pytest.approx(2 * math.pi * 3 * 5 + 2 * math.pi * 9, rel=1e-9)
    assert Paraboloid(2, 3).volume == pytest.approx(0.5 * math.pi * 4 * 9, rel=1e-14)
    assert Sphere(3).volume == pytest.approx(36 * math.pi, rel=1e-14)
    assert Ellipsoid(1, 2, 3).volume == pytest.approx(8 * math.pi, rel=1e-14)


# ---------------------------------------------------------------------------- exact inside test
def test_point_on_surface_is_not_inside():
    s = Sphere(5)
    assert not s.contains(3, 4, 0)
    assert s.contains(3, 4, 0, strict=False)
    assert s.contains(3, 3.99, 0)
    assert not s.contains(0, 0, 5) and s.contains(0, 0, 4.999999999999)
    m = s.slice_mask(0, (-6, 7), (-6, 7))
    for x, y in [(3, 4), (5, 0), (0, -5), (-4, -3)]:  # on the circle: not strictly inside
        assert not m[y + 6, x + 6]
    assert m[6, 6] and m[3 + 6, 3 + 6]
    assert m.sum() == sum(1 for x in range(-6, 7) for y in range(-6, 7) if x * x + y * y < 25)
    assert s.slice_mask(0, (-6, 7), (-6, 7), strict=False).sum() == sum(
        1 for x in range(-6, 7) for y in range(-6, 7) if x * x + y * y <= 25)


def test_surface_point_with_offset_centre_on_fine_grid():
    # centre (0.5, 0.25, 0): the grid point 0.25 * (14, 17, 0) = (3.5, 4.25, 0) is exactly on the sphere
    s = Sphere(5, center=(0.5, 0.25, 0.0))
    assert not s.contains(3.5, 4.25, 0.0)
    m = s.slice_mask(0, (14, 15), (17, 18), h=0.25)
    assert m.shape == (1, 1) and not m[0, 0]
    assert s.slice_mask(0, (14, 15), (17, 18), h=0.25, strict=False)[0, 0]


def _exact_sphere_sign(p, c, r):
    d = sum((Fraction(pi) - Fraction(ci)) ** 2 for pi, ci in zip(p, c))
    return d - Fraction(r) ** 2


def test_exact_answer_wins_where_float_rounds_wrongly():
    """Radii rounded from the exact distance put grid points within an ulp of the sphere."""
    rng = np.random.default_rng(12345)
    wrong_float = 0
    for _ in range(400):
        c = tuple(float(v) for v in rng.uniform(-1, 1, 3))
        p = tuple(int(v) for v in rng.integers(-60, 60, 3))
        d2 = sum((pi - ci) ** 2 for pi, ci in zip(p, c))
        r = math.nextafter(math.sqrt(d2), rng.choice([-math.inf, math.inf])) if rng.random() < 0.5 else math.sqrt(d2)
        exact = _exact_sphere_sign(p, c, r)
        naive = (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2 + (p[2] - c[2]) ** 2 - r * r
        if (naive < 0) != (exact < 0):
            wrong_float += 1
        s = Sphere(r, center=c)
        assert bool(s.contains(*p)) == (exact < 0)
        m = s.slice_mask(p[2], (p[0], p[0] + 1), (p[1], p[1] + 1))
        assert bool(m[0, 0]) == (exact < 0)
        assert bool(s.slice_mask(p[2], (p[0], p[0] + 1), (p[1], p[1] + 1), strict=False)[0, 0]) == (exact <= 0)
    assert wrong_float >= 10  # the trap is real: naive float64 gets these wrong


def _brute_slice(shape, k, ii, jj, h, strict=True):
    """Independent exact reference: Fractions, local coordinates, the shape's own definition."""
    R = np.eye(3) if shape.rotation is None else shape.rotation
    Rf = [[Fraction(float(R[m, l])) for l in range(3)] for m in range(3)]
    cf = [Fraction(float(v)) for v in shape.center]
    H = Fraction(float(h))
    out = np.zeros((len(jj), len(ii)), dtype=bool)
    for b, j in enumerate(jj):
        for a, i in enumerate(ii):
            d = [H * i - cf[0], H * j - cf[1], H * k - cf[2]]
            q = [sum(Rf[m][l] * d[m] for m in range(3)) for l in range(3)]
            out[b, a] = _local_inside(shape, *q, strict=strict)
    return out


def _local_inside(s, x, y, z, strict):
    F = Fraction
    lt = (lambda v: v < 0) if strict else (lambda v: v <= 0)
    if isinstance(s, Torus):
        R, r = F(s.R), F(s.r)
        return lt((x * x + y * y + z * z + R * R - r * r) ** 2 - 4 * R * R * (x * x + y * y))
    if isinstance(s, Sphere):
        return lt(x * x + y * y + z * z - F(s.r) ** 2)
    if isinstance(s, Ellipsoid):
        return lt(x * x / F(s.a) ** 2 + y * y / F(s.b) ** 2 + z * z / F(s.c) ** 2 - 1)
    if isinstance(s, Cone):
        H = F(s.height)
        rho = F(s.r0) + (F(s.r1) - F(s.r0)) * z / H
        return 0 <= z <= H and lt(x * x + y * y - rho * rho)
    if isinstance(s, Hyperboloid):
        t = F(s.height) / 2
        return -t <= z <= t and lt((x * x + y * y) / F(s.a) ** 2 - z * z / F(s.c) ** 2 - 1)
    if isinstance(s, Paraboloid):
        return z <= F(s.height) and lt((x * x + y * y) / F(s.a) ** 2 - z)
    raise AssertionError(s)


PLACED = [
    Sphere(4, center=(0.5, 0.0, 0.5)),
    Ellipsoid(4.5, 3.0, 2.0, center=(0.25, -0.125, 0.0), rotation=rotation_from_euler(20, 35, 50)),
    Torus(4.0, 1.5, center=(0.1, 0.2, 0.3), rotation=rotation_from_euler(90, 0, 0)),
    Torus(4.0, 2.0),
    Cone(4.0, 2.0, 4.0, center=(0.0, 0.0, -2.0)),
    Cone(4.0, 1.0, 5.0, center=(0.3, 0.1, -2.0), rotation=rotation_from_euler(0, 45, 10)),
    Hyperboloid(2.0, 1.5, 6.0, rotation=rotation_from_euler(0, 90, 0)),
    Paraboloid(1.5, 4.0, center=(0.0, 0.5, -2.0)),
]


@pytest.mark.parametrize("shape", PLACED, ids=repr)
@pytest.mark.parametrize("h", [1.0, 0.5])
def test_slice_mask_matches_brute_force(shape, h):
    lo, hi = shape.bounds
    ii = np.arange(math.floor(lo[0] / h) - 1, math.ceil(hi[0] / h) + 2)
    jj = np.arange(math.floor(lo[1] / h) - 1, math.ceil(hi[1] / h) + 2)
    total = 0
    for k in range(math.floor(lo[2] / h), math.ceil(hi[2] / h) + 1, 2):
        X, Y = np.meshgrid(ii * h, jj * h)
        for strict in (True, False):
            got = shape.slice_mask(k, (ii[0], ii[-1] + 1), (jj[0], jj[-1] + 1), h, strict=strict)
            ref = _brute_slice(shape, k, ii, jj, h, strict=strict)
            np.testing.assert_array_equal(got, ref)
            # contains() on the same (float64) points agrees
            np.testing.assert_array_equal(shape.contains(X, Y, k * h, strict=strict), ref)
            total += ref.sum()
    assert total > 0


def test_end_planes_are_closed():
    cone = Cone(4.0, 2.0, 4.0)  # ends at z = 0 and z = 4
    assert cone.contains(0, 0, 0) and cone.contains(0, 0, 4) and cone.contains(1.9, 0, 4)
    assert not cone.contains(0, 0, -1e-300) and not cone.contains(2.0, 0, 4) and not cone.contains(0, 0, 4.0000001)
    assert cone.slice_mask(4, (-3, 4), (-3, 4)).sum() == sum(
        1 for x in range(-3, 4) for y in range(-3, 4) if x * x + y * y < 4)
    para = Paraboloid(2.0, 3.0)
    assert not para.contains(0, 0, 0)  # the apex is on the curved surface
    assert para.contains(0, 0, 3.0) and para.contains(0, 0, 1e-12)


def test_inside_sign_agrees_with_contains():
    rng = np.random.default_rng(0)
    for s in PLACED + ALL_SHAPES[:6]:
        lo, hi = s.bounds
        pts = rng.uniform(lo - 1, hi + 1, size=(2000, 3))
        f = s.inside(pts[:, 0], pts[:, 1], pts[:, 2])
        c = s.contains(pts[:, 0], pts[:, 1], pts[:, 2])
        np.testing.assert_array_equal(f < 0, c)
        # everything inside lies within the bounds
        assert np.all((pts[c] >= lo) & (pts[c] <= hi))
        assert c.any()


def test_rotated_bounds_are_tight_for_ellipsoid_and_torus():
    rot = rotation_from_euler(30, 0, 0)
    e = Ellipsoid(5, 3, 2, rotation=rot)
    c30, s30 = math.cos(math.radians(30)), math.sin(math.radians(30))
    np.testing.assert_allclose(e.bounds[1], [5, math.hypot(3 * c30, 2 * s30), math.hypot(3 * s30, 2 * c30)])
    t = Torus(10, 2, center=(1, 2, 3), rotation=rotation_from_euler(90, 0, 0))
    np.testing.assert_allclose(t.bounds, [[-11, 0, -9], [13, 4, 15]], atol=1e-12)


# ---------------------------------------------------------------------------- validation, specs
def test_constructor_validation():
    with pytest.raises(ValueError, match="positive"):
        Sphere(0)
    with pytest.raises(ValueError, match="positive"):
        Ellipsoid(1, -2, 3)
    with pytest.raises(ValueError, match="number"):
        Sphere("big")
    with pytest.raises(ValueError, match="R > r"):
        Torus(3, 3)
    with pytest.raises(ValueError, match="center"):
        Sphere(1, center=(0, 0))
    with pytest.raises(ValueError, match="rotation"):
        Sphere(1, rotation=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="rotation"):
        Sphere(1, rotation=np.ones((3, 3)))
    with pytest.raises(ValueError, match="finite"):
        Sphere(float("nan"))
    Cone(3, 0, 2)  # a full cone is allowed
    with pytest.raises(ValueError, match="r0"):
        Cone(0, 3, 2)


def test_parse_shape_spec():
    s = parse_shape_spec("sphere:r=40,center=0.3;0.1;0.2")
    assert isinstance(s, Sphere) and s.r == 40 and np.allclose(s.center, [0.3, 0.1, 0.2])
    e = parse_shape_spec("ellipsoid:a=30,b=20,c=10")
    assert (e.a, e.b, e.c) == (30, 20, 10) and e.name == "ellipsoid"
    t = parse_shape_spec(" Torus: R=30, r=9 ")
    assert (t.R, t.r) == (30, 9) and t.params == {"R": 30.0, "r": 9.0}
    sp = parse_shape_spec("spheroid:a=10,b=6")
    assert sp.params == {"a": 10.0, "b": 6.0} and sp.area == pytest.approx(663.17, abs=0.005)
    rot = parse_shape_spec("cone:r0=20,r1=10,height=30,rotation=0;90;0")
    np.testing.assert_allclose(rot.rotation, rotation_from_euler(0, 90, 0))
    m = parse_shape_spec("paraboloid:a=5,height=20,rotation=0;0;1;0;1;0;-1;0;0")
    np.testing.assert_allclose(m.rotation, [[0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    assert isinstance(parse_shape_spec("hyperboloid:a=10,c=8,height=30"), Hyperboloid)
    # round trip of the spec property
    for shape in [s, e, t, sp, rot, m]:
        again = parse_shape_spec(shape.spec)
        assert type(again) is type(shape) and again.params == shape.params
        assert np.array_equal(again.center, shape.center)
        assert (again.rotation is None) == (shape.rotation is None)
        assert again.area == shape.area
    assert set(SHAPES) == {"sphere", "ellipsoid", "spheroid", "cone", "hyperboloid", "paraboloid", "torus"}


@pytest.mark.parametrize(
    "spec, match",
    [
        ("cube:a=3", "unknown shape"),
        ("sphere:r=4,s=3", "unknown key"),
        ("sphere:r=four", "number"),
        ("sphere:r=-4", "positive"),
        ("sphere:r=0", "positive"),
        ("ellipsoid:a=3,b=2", "missing c"),
        ("sphere:r=3,center=1;2", "3 numbers"),
        ("sphere:r=3,center=1;x;2", "numbers"),
        ("sphere:r=3,rotation=1;2", "3 or 9"),
        ("sphere:r=3,r=4", "twice"),
        ("sphere:r", "key=value"),
        ("torus:R=3,r=5", "R > r"),
        ("", "non-empty"),
        ("sphere:r=inf", "finite"),
    ],
)
def test_parse_shape_spec_errors(spec, match):
    with pytest.raises(ValueError, match=match):
        parse_shape_spec(spec)


def test_describe_and_import_is_light():
    s = Sphere(3, center=(0.1, 0, 0), rotation=rotation_from_euler(10, 0, 0))
    d = s.describe()
    assert d["name"] == "sphere" and d["params"] == {"r": 3.0} and len(d["rotation"]) == 3
    assert "rotation" in repr(s)


@pytest.mark.parametrize("rotation", [None, (30.0, -50.0, 20.0)])
def test_ellipsoid_section_area_integrates_to_the_volume_and_matches_the_upright_formula(rotation):
    from scipy.integrate import quad

    R = None if rotation is None else rotation_from_euler(*rotation)
    e = Ellipsoid(5.0, 3.0, 2.0, center=(0.3, -0.2, 0.7), rotation=R)
    lo, hi = e.bounds[:, 2]
    assert e.section_area(lo - 0.1) == 0.0 and e.section_area(hi + 0.1) == 0.0
    vol, _ = quad(e.section_area, lo, hi, epsabs=1e-10)
    assert vol == pytest.approx(e.volume, rel=1e-9)
    if R is None:
        assert e.section_area(0.7 + 1.0) == pytest.approx(math.pi * 5.0 * 3.0 * (1 - 0.25), rel=1e-12)
