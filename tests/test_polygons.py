"""Polygonizers (contourmesh.polygons): DSS and MLP, checked with exact integer predicates."""

from math import gcd

import numpy as np
import pytest

from contourmesh.polygons import POLYGONIZERS, contour_polygon, dss_polygon, mlp_polygon, polygonize
from contourmesh.polygons.dss import dss_vertex_indices
from contourmesh.tracing import trace_contours
from contourmesh.types import shoelace_area

# ----------------------------------------------------------------------------------------------
# exact geometry helpers (independent of the code under test)


class Band:
    """Cells of U and V of a slice, with exact membership tests for points on segments.

    A contour determines U but not I: the polygonizers use the grid points interior to U (all four
    cells in U), ``I' >= I``, which equals I except where a point missing from I is surrounded by
    points of I on all four sides of it (see ``test_interior_points_equal_I_for_the_shapes``).
    ``I`` and ``V`` here are those implied by the contour: ``I'`` and the cells with 4 corners in ``I'``.
    """

    def __init__(self, mask, x0=0, y0=0):
        m = np.asarray(mask, bool)
        p = np.zeros((m.shape[0] + 4, m.shape[1] + 4), bool)
        p[2:-2, 2:-2] = m
        self.ox, self.oy = x0 - 2, y0 - 2  # cell [r, c] has lower-left corner (c + ox, r + oy)
        a, b, c, d = p[:-1, :-1], p[:-1, 1:], p[1:, :-1], p[1:, 1:]
        self.U = np.zeros(p.shape, bool)
        self.U[:-1, :-1] = a | b | c | d
        ys, xs = np.nonzero(m)
        self.I_mask = np.c_[xs + x0, ys + y0].astype(np.int64)
        q = np.zeros(p.shape, bool)  # q[r, c]: grid point (c + ox, r + oy) interior to U
        q[1:, 1:] = self.U[1:, 1:] & self.U[:-1, 1:] & self.U[1:, :-1] & self.U[:-1, :-1]
        a, b, c, d = q[:-1, :-1], q[:-1, 1:], q[1:, :-1], q[1:, 1:]
        self.V = np.zeros(p.shape, bool)
        self.V[:-1, :-1] = a & b & c & d
        ys, xs = np.nonzero(q)
        self.I = np.c_[xs + self.ox, ys + self.oy].astype(np.int64)
        self.Iset = set(map(tuple, self.I.tolist()))
        # centres of the background cells next to U, doubled to stay integer: (2a + 1, 2b + 1)
        near = np.zeros(p.shape, bool)
        near[1:-1, 1:-1] = self.U[1:-1, 1:-1] | self.U[:-2, 1:-1] | self.U[2:, 1:-1] | self.U[1:-1, :-2] | self.U[1:-1, 2:]
        ys, xs = np.nonzero(near & ~self.U)
        self.bg2 = np.c_[2 * (xs + self.ox) + 1, 2 * (ys + self.oy) + 1].astype(np.int64)

    def _cell(self, arr, cx, cy):
        r, c = cy - self.oy, cx - self.ox
        ok = (r >= 0) & (r < arr.shape[0]) & (c >= 0) & (c < arr.shape[1])
        out = np.zeros(r.shape, bool)
        out[ok] = arr[r[ok], c[ok]]
        return out

    def segment_ok(self, P, Q):
        """Segment PQ lies in U and outside the interior of V.  Exact: the sample points (integer
        numerators over one denominator) are every crossing with a grid line and a point between
        each two consecutive crossings, where the segment stays in one open cell."""
        dx, dy = int(Q[0] - P[0]), int(Q[1] - P[1])
        L = abs(dx * dy) // gcd(abs(dx), abs(dy)) if dx and dy else max(abs(dx), abs(dy), 1)
        den = 2 * L
        j = np.arange(den + 1, dtype=np.int64)
        X, Y = den * int(P[0]) + j * dx, den * int(P[1]) + j * dy
        fx, fy = X // den, Y // den
        xd, yd = X % den == 0, Y % den == 0
        g = self._cell
        in_u = g(self.U, fx, fy) | (xd & g(self.U, fx - 1, fy)) | (yd & g(self.U, fx, fy - 1))
        in_u |= xd & yd & g(self.U, fx - 1, fy - 1)
        in_int_v = g(self.V, fx, fy) & (~xd | g(self.V, fx - 1, fy)) & (~yd | g(self.V, fx, fy - 1))
        in_int_v &= ~(xd & yd) | g(self.V, fx - 1, fy - 1)
        return bool(in_u.all() and not in_int_v.any())

    def polygon_ok(self, poly, edges=None):
        n = len(poly)
        edges = range(n) if edges is None else edges
        return all(self.segment_ok(poly[i % n], poly[(i + 1) % n]) for i in edges)


def on_and_winding(poly, pts):
    """Exact integer point-on-boundary flags and winding numbers of ``poly`` at ``pts``."""
    poly = np.asarray(poly, np.int64)
    a = poly[:, None, :]
    b = np.roll(poly, -1, 0)[:, None, :]
    px, py = pts[None, :, 0], pts[None, :, 1]
    ax, ay, bx, by = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
    cr = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    box = (np.minimum(ax, bx) <= px) & (px <= np.maximum(ax, bx)) & (np.minimum(ay, by) <= py) & (py <= np.maximum(ay, by))
    on = np.any((cr == 0) & box, axis=0)
    wn = np.sum((ay <= py) & (by > py) & (cr > 0), axis=0) - np.sum((ay > py) & (by <= py) & (cr < 0), axis=0)
    return on, wn


def on_boundary(poly, pts):
    return on_and_winding(poly, pts)[0]


def perimeter(p):
    p = np.asarray(p, float)
    return float(np.sqrt(((np.roll(p, -1, 0) - p) ** 2).sum(1)).sum()) if len(p) > 1 else 0.0


def turns(poly):
    p = np.asarray(poly, np.int64)
    u = p - np.roll(p, 1, 0)
    v = np.roll(p, -1, 0) - p
    return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0], (u * v).sum(1)


def concave_corners(contour):
    t, _ = turns(contour)
    return set(map(tuple, contour[t < 0].tolist()))


def mlp_constraints_ok(poly, band, contour, check_band=True):
    """The polygon lies in the band and encloses I the way the contour does: an outer contour's
    points of I stay inside or on it; a hole's MLP has no point of I strictly inside."""
    if check_band and not band.polygon_ok(poly):
        return False
    pts = band.I
    on, wn_p = on_and_winding(poly, pts)
    # background cells next to U stay on the same side as for the contour (no cell outside U gets
    # enclosed or released through a corner where U touches itself)
    if not np.array_equal(on_and_winding(2 * poly, band.bg2)[1] != 0, on_and_winding(2 * contour, band.bg2)[1] != 0):
        return False
    if shoelace_area(contour) > 0:
        mine = on_and_winding(contour, pts)[1] != 0  # the points of I enclosed by this contour
        return bool(np.all(on[mine] | (wn_p[mine] != 0)))
    return bool(np.all(on | (wn_p == 0)))


def assert_mlp_ok(contour, band, local_moves=True):
    poly = mlp_polygon(contour)
    assert poly.dtype == np.int64 and poly.ndim == 2 and poly.shape[1] == 2 and len(poly) >= 1
    n = len(poly)
    if n > 1:
        assert not np.any(np.all(poly == np.roll(poly, -1, 0), axis=1)), "consecutive duplicates"
    cross, dot = turns(poly)
    if n > 2:
        assert not np.any((cross == 0) & (dot > 0)), "three consecutive collinear vertices"
    # vertex types: left turns at points of I, right turns at concave corners of the contour
    conc = concave_corners(contour)
    for q, c in zip(map(tuple, poly.tolist()), cross if n > 2 else np.zeros(n, int)):
        if c > 0:
            assert q in band.Iset, f"convex MLP vertex {q} is not a point of I"
        elif c < 0:
            assert q in conc, f"concave MLP vertex {q} is not a concave corner of the contour"
        else:
            assert q in band.Iset or q in conc
    # orientation kept
    a = shoelace_area(poly)
    if a != 0:
        assert np.sign(a) == np.sign(shoelace_area(contour))
    else:
        assert shoelace_area(contour) > 0, "a hole's MLP must enclose the hole"
    assert mlp_constraints_ok(poly, band, contour)
    # starts at the vertex nearest the contour's start
    d = ((poly - contour[0]) ** 2).sum(1)
    assert d[0] == d.min()
    if local_moves and n > 1:
        p0 = perimeter(poly)
        for i in range(n):
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    if dx == dy == 0:
                        continue
                    moved = poly.copy()
                    moved[i] += (dx, dy)
                    if not band.polygon_ok(moved, edges=(i - 1, i)):
                        continue
                    if mlp_constraints_ok(moved, band, contour, check_band=False):
                        assert perimeter(moved) >= p0 - 1e-9, f"moving vertex {i} by {(dx, dy)} shortens the MLP"
    return poly


def is_dss4(points):
    """Brute force: a 4-connected digital path is a DSS iff its steps use at most two, not
    opposite, directions and some coprime (a, b) >= 0 puts it in a standard line
    mu <= a X - b Y < mu + a + b (in coordinates flipped into the first quadrant)."""
    p = np.asarray(points, np.int64)
    st = np.diff(p, axis=0)
    assert np.all(np.abs(st).sum(1) == 1)
    if (np.any(st[:, 0] > 0) and np.any(st[:, 0] < 0)) or (np.any(st[:, 1] > 0) and np.any(st[:, 1] < 0)):
        return False
    sx = -1 if np.any(st[:, 0] < 0) else 1
    sy = -1 if np.any(st[:, 1] < 0) else 1
    X, Y = (p[:, 0] - p[0, 0]) * sx, (p[:, 1] - p[0, 1]) * sy
    nx, ny = int(X[-1]), int(Y[-1])
    for a in range(0, ny + 2):
        for b in range(0, nx + 2):
            if (a, b) == (0, 0) or gcd(a, b) != 1:
                continue
            r = a * X - b * Y
            if r.max() - r.min() <= a + b - 1:
                return True
    return False


# ----------------------------------------------------------------------------------------------
# shapes


def disk_mask(R, cx_num, cy_num, den=1000):
    """I = {(x, y): (den x - cx)^2 + (den y - cy)^2 < (den R)^2}, exact in int64."""
    x0, y0 = cx_num // den - R - 2, cy_num // den - R - 2
    n = 2 * R + 6
    xs = np.arange(x0, x0 + n, dtype=np.int64)
    ys = np.arange(y0, y0 + n, dtype=np.int64)
    m = (den * xs[None, :] - cx_num) ** 2 + (den * ys[:, None] - cy_num) ** 2 < (den * R) ** 2
    return m, int(x0), int(y0)


def polygon_mask(vertices, shape):
    """Grid points strictly inside an integer polygon (exact winding numbers)."""
    ys, xs = np.mgrid[: shape[0], : shape[1]]
    pts = np.c_[xs.ravel(), ys.ravel()].astype(np.int64)
    on, wn = on_and_winding(np.asarray(vertices), pts)
    return ((wn != 0) & ~on).reshape(shape)


def star_mask(n_tips=5, r_out=18, r_in=7, c=22):
    ang = np.arange(2 * n_tips) * np.pi / n_tips
    r = np.where(np.arange(2 * n_tips) % 2 == 0, r_out, r_in)
    v = np.round(np.c_[c + r * np.cos(ang), c + r * np.sin(ang)]).astype(np.int64)
    return polygon_mask(v, (2 * c + 1, 2 * c + 1))


def spiral_mask(turns_=2.2, width=4.5, pitch=11.0, size=70):
    ys, xs = np.mgrid[:size, :size].astype(float)
    x, y = xs - size / 2 + 0.37, ys - size / 2 + 0.21
    r, th = np.hypot(x, y), np.mod(np.arctan2(y, x), 2 * np.pi)
    k = np.floor((r - pitch * th / (2 * np.pi)) / pitch)
    t = th + 2 * np.pi * k
    d = r - pitch * t / (2 * np.pi)
    return (d >= 0) & (d < width) & (t >= 0) & (t < 2 * np.pi * turns_)


def l_mask():
    m = np.zeros((20, 16), bool)
    m[1:19, 1:6] = True
    m[1:6, 1:15] = True
    return m


def _ring():
    m, _, _ = disk_mask(15, 310, 720)
    h, _, _ = disk_mask(7, 310, 720)
    k = (m.shape[0] - h.shape[0]) // 2
    m[k : k + h.shape[0], k : k + h.shape[1]] &= ~h
    return m


SHAPES = {"L": l_mask, "star": star_mask, "spiral": spiral_mask, "ring": _ring}


def random_blob(seed, size=16):
    rng = np.random.default_rng(seed)
    m = rng.random((size, size)) < 0.5
    for _ in range(2):  # a little smoothing: majority of the 3 x 3 neighbourhood
        p = np.pad(m, 1).astype(int)
        s = sum(p[1 + dy : 1 + dy + size, 1 + dx : 1 + dx + size] for dy in (-1, 0, 1) for dx in (-1, 0, 1))
        m = s >= 5 - rng.integers(0, 2)
    return m


# ----------------------------------------------------------------------------------------------
# registry


def test_registry_and_unknown_method():
    assert set(POLYGONIZERS) == {"dss", "mlp", "none"}
    (c,), _ = trace_contours(l_mask())
    assert np.array_equal(polygonize(c, "none"), c)
    assert np.array_equal(polygonize(c, "mlp"), mlp_polygon(c))
    assert np.array_equal(polygonize(c, "dss"), dss_polygon(c))
    with pytest.raises(ValueError, match="dss.*mlp.*none"):
        polygonize(c, "convex-hull")


def test_contour_polygon_is_the_contour():
    (c,), _ = trace_contours(star_mask())
    p = contour_polygon(c)
    assert np.array_equal(p, c) and p is not c
    assert contour_polygon(np.array([[0.5, 0.25], [1.0, 2.0], [0.0, 3.0]])).dtype == np.float64
    with pytest.raises(ValueError):
        contour_polygon(np.zeros((3, 3)))


@pytest.mark.parametrize("fn", [dss_polygon, mlp_polygon])
def test_input_validation(fn):
    with pytest.raises(ValueError, match=r"\(k, 2\)"):
        fn(np.zeros((5, 3), dtype=int))
    with pytest.raises(ValueError, match="unit"):
        fn(np.array([[0, 0], [2, 0], [2, 2], [0, 2]]))


# ----------------------------------------------------------------------------------------------
# MLP


def test_mlp_hand_worked_cases():
    one = lambda m: trace_contours(m)[0][0]
    assert mlp_polygon(one(np.ones((1, 1), bool))).tolist() == [[0, 0]]  # a single point
    assert mlp_polygon(one(np.ones((1, 5), bool))).tolist() == [[0, 0], [4, 0]]  # a row: a segment
    assert mlp_polygon(one(np.eye(4, dtype=bool))).tolist() == [[0, 0], [3, 3]]  # a diagonal
    assert mlp_polygon(one(np.ones((3, 4), bool))).tolist() == [[0, 0], [3, 0], [3, 2], [0, 2]]
    # an L of width 1: the relative convex hull is a triangle (the hypotenuse stays inside U)
    m = np.zeros((3, 3), bool)
    m[0, :] = m[:, 2] = True
    assert mlp_polygon(one(m)).tolist() == [[0, 0], [2, 0], [2, 2]]



@pytest.mark.parametrize("k", range(8))
def test_mlp_of_a_thin_L_under_rotations_and_mirrors(k):
    """Regression (soak seed 1002106): for I = {(4..8, 0), (8, 1)} the MLP kept a spurious vertex
    (5, 0).  The first contour point is a convex corner whose diagonal W point is listed both last
    and first; dropping the last copy put that corner before its W and ended the path early."""
    m = np.zeros((2, 9), bool)
    m[0, 4:9] = m[1, 8] = True
    ends = np.zeros(m.shape, int)
    ends[0, 4], ends[0, 8], ends[1, 8] = 1, 2, 3  # the three MLP vertices
    if k & 4:
        m, ends = m.T, ends.T
    m, ends = np.rot90(m, k & 3), np.rot90(ends, k & 3)
    (c,), _ = trace_contours(m)
    p = mlp_polygon(c)
    expected = {tuple(np.argwhere(ends == i)[0][::-1]) for i in (1, 2, 3)}  # (row, col) -> (x, y)
    assert set(map(tuple, p.tolist())) == expected and len(p) == 3
    assert perimeter(p) == pytest.approx(5 + np.sqrt(17))
    assert_mlp_ok(c, Band(m))

def test_mlp_of_a_non_convex_shape_is_not_the_convex_hull():
    m = l_mask()
    (c,), _ = trace_contours(m)
    p = mlp_polygon(c)
    # the L's MLP goes round the inner corner: it has a concave vertex at the contour's inner corner
    cross, _ = turns(p)
    assert np.sum(cross < 0) == 1
    assert tuple(p[cross < 0][0]) == (6, 6)
    assert perimeter(p) < perimeter(c)


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_mlp_lies_in_band_and_is_locally_shortest(name):
    m = SHAPES[name]()
    band = Band(m)
    contours, parents = trace_contours(m)
    assert contours
    if name == "ring":
        assert parents == [-1, 0]
    for c in contours:
        assert_mlp_ok(c, band)


@pytest.mark.parametrize("seed", range(40))
def test_mlp_random_blobs_with_holes_and_thin_parts(seed):
    m = random_blob(seed)
    band = Band(m, 3, -4)
    contours, _ = trace_contours(m, 3, -4)
    for c in contours:
        assert_mlp_ok(c, band, local_moves=seed < 12)


@pytest.mark.parametrize("name", ["L", "ring", "spiral"])
def test_interior_points_equal_I_for_the_shapes(name):
    band = Band(SHAPES[name]())
    assert set(map(tuple, band.I_mask.tolist())) == band.Iset


def test_mlp_of_disk_is_convex_hull_of_I():
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(11)
    for R in (4, 9, 23, 41):
        for _ in range(4):
            m, x0, y0 = disk_mask(R, *(int(v) for v in rng.integers(0, 1000, 2)))
            (c,), _ = trace_contours(m, x0, y0)
            p = mlp_polygon(c)
            pts = Band(m, x0, y0).I
            hull = pts[ConvexHull(pts).vertices]
            assert set(map(tuple, p.tolist())) == set(map(tuple, hull.tolist()))


def _rot90(points):
    return np.c_[-points[:, 1], points[:, 0]]


def _mask_from_points(pts):
    x0, y0 = pts.min(0)
    m = np.zeros(tuple((pts.max(0) - (x0, y0) + 1)[::-1]), bool)
    m[pts[:, 1] - y0, pts[:, 0] - x0] = True
    return m, int(x0), int(y0)


@pytest.mark.parametrize("name", ["star", "spiral", "ring"])
def test_translation_and_rotation_invariance(name):
    m = SHAPES[name]()
    pts = Band(m).I
    cs, _ = trace_contours(m)
    p_mlp = [mlp_polygon(c) for c in cs]
    p_dss = [dss_polygon(c) for c in cs]
    shifted, _ = trace_contours(m, 123, -77)
    for c, p in zip(shifted, p_mlp):
        assert np.array_equal(mlp_polygon(c), p + (123, -77))
    for k in range(1, 4):
        q = pts
        for _ in range(k):
            q = _rot90(q)
        mr, x0, y0 = _mask_from_points(q)
        cr, _ = trace_contours(mr, x0, y0)
        assert len(cr) == len(cs)
        got = sorted(map(tuple, np.vstack([mlp_polygon(c) for c in cr]).tolist()))
        want = p_mlp[0] if len(p_mlp) == 1 else np.vstack(p_mlp)
        for _ in range(k):
            want = _rot90(want)
        assert got == sorted(map(tuple, want.tolist()))  # MLP: exactly the rotated vertices
        per_r = sum(perimeter(dss_polygon(c)) for c in cr)
        assert per_r == pytest.approx(sum(perimeter(p) for p in p_dss), rel=0.03)


# ----------------------------------------------------------------------------------------------
# DSS


def assert_dss_ok(c):
    idx = dss_vertex_indices(c)
    p = dss_polygon(c)
    assert np.array_equal(p, c[idx]) and idx[0] == 0 and np.all(np.diff(idx) > 0)
    n = len(c)
    bounds = list(idx) + [n]
    for s in range(len(idx)):
        seg = c[np.arange(bounds[s], bounds[s + 1] + 1) % n]
        assert is_dss4(seg), f"segment {s} is not a DSS"
        if s < len(idx) - 1:  # maximal: one more contour point breaks it (the last closes at the start)
            assert not is_dss4(c[np.arange(bounds[s], bounds[s + 1] + 2) % n]), f"segment {s} is not maximal"
    a = shoelace_area(p)
    if len(p) > 2 and a != 0:
        assert np.sign(a) == np.sign(shoelace_area(c))
    return p


def test_dss_hand_worked_cases():
    (c,), _ = trace_contours(np.ones((1, 1), bool))
    assert dss_polygon(c).tolist() == [[-1, -1], [1, 0], [-1, 1]]
    (c,), _ = trace_contours(np.ones((3, 6), bool))
    # E^7 N is a DSS (slope 1/7), E^7 N N is not
    assert dss_polygon(c).tolist() == [[-1, -1], [6, 0], [5, 3], [-1, 2]]
    c = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [3, 1], [4, 1], [4, 2], [3, 2], [2, 2], [1, 2], [0, 2], [0, 1]])
    assert dss_polygon(c)[:2].tolist() == [[0, 0], [4, 2]]  # E E N E E N is a DSS of slope 1/2


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_dss_segments_are_maximal_dss(name):
    contours, _ = trace_contours(SHAPES[name]())
    for c in contours:
        assert_dss_ok(c)


@pytest.mark.parametrize("seed", range(15))
def test_dss_random_blobs(seed):
    contours, _ = trace_contours(random_blob(seed))
    for c in contours:
        assert_dss_ok(c)


def test_dss_keeps_start_point_and_hole_orientation():
    m = _ring()
    cs, parents = trace_contours(m)
    assert parents == [-1, 0]
    for c in cs:
        p = dss_polygon(c)
        assert np.array_equal(p[0], c[0])
        assert np.sign(shoelace_area(p)) == np.sign(shoelace_area(c))


# ----------------------------------------------------------------------------------------------
# digitized circles: perimeter accuracy


def _circle_errors(R, n_centres, seed):
    rng = np.random.default_rng(seed)
    err = {"dss": [], "mlp": []}
    for _ in range(n_centres):
        m, x0, y0 = disk_mask(R, *(int(v) for v in rng.integers(0, 1000, 2)))
        (c,), _ = trace_contours(m, x0, y0)
        for k in err:
            err[k].append(abs(perimeter(polygonize(c, k)) / (2 * np.pi * R) - 1))
    return {k: np.array(v) for k, v in err.items()}


def test_circle_perimeter_r80():
    e = _circle_errors(80, 8, seed=1)
    assert e["mlp"].max() < 0.003
    assert e["dss"].max() < 0.012


def test_circle_perimeter_r1000():
    e = _circle_errors(1000, 3, seed=2)
    assert e["mlp"].max() < 0.0002


def test_orientation_signs_on_disk_and_hole():
    m = _ring()
    cs, parents = trace_contours(m)
    for c in cs:
        for fn in (dss_polygon, mlp_polygon):
            assert np.sign(shoelace_area(fn(c))) == np.sign(shoelace_area(c))
