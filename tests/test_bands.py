"""Tests for band triangulations (wiederhold, greedy, optimal) and flat caps."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from contourmesh.bands import TRIANGULATORS, cap_faces, triangulate_band
from contourmesh.bands.optimal import optimal_edges
from contourmesh.bands.wiederhold import initial_edge, wiederhold_edges

METHODS = sorted(TRIANGULATORS)
SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ----------------------------------------------------------------------------------------------
# polygon generators
# ----------------------------------------------------------------------------------------------
def shoelace(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def dedupe_cyclic(p):
    """Drop points equal to their predecessor (cyclically)."""
    keep = [0]
    for k in range(1, len(p)):
        if np.any(p[k] != p[keep[-1]]):
            keep.append(k)
    p = p[keep]
    while len(p) > 1 and np.all(p[-1] == p[0]):
        p = p[:-1]
    return p


def convex_hull(pts):
    """Andrew's monotone chain; counter-clockwise in raw numbers (positive shoelace)."""
    pts = np.unique(pts, axis=0)
    if len(pts) < 3:
        return pts

    def half(points):
        h = []
        for p in points:
            while len(h) >= 2 and (h[-1][0] - h[-2][0]) * (p[1] - h[-2][1]) - (h[-1][1] - h[-2][1]) * (p[0] - h[-2][0]) <= 0:
                h.pop()
            h.append(p)
        return h

    lower = half(pts)
    upper = half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def trace_cells(cells):
    """Boundary 4-curve (all grid points, positive shoelace) of a set of unit cells, or None
    if it is not a single simple curve (several pieces, or cells touching at a corner only)."""
    nxt = {}
    edges = set()
    for cx, cy in cells:
        c = [(cx, cy), (cx + 1, cy), (cx + 1, cy + 1), (cx, cy + 1)]
        for k in range(4):
            e = (c[k], c[(k + 1) % 4])
            if (e[1], e[0]) in edges:
                edges.remove((e[1], e[0]))
            else:
                edges.add(e)
    for a, b in edges:
        if a in nxt:
            return None
        nxt[a] = b
    start = min(nxt, key=lambda p: (p[1], p[0]))  # first point in raster order
    out = [start]
    while True:
        q = nxt[out[-1]]
        if q == start:
            break
        out.append(q)
    if len(out) != len(nxt):
        return None
    return np.array(out, dtype=np.float64)


def digital_contour(radius, seed):
    """Outer boundary of the unit cells whose centres lie in a random ellipse (a 4-curve)."""
    rng = np.random.default_rng(seed)
    r = max(float(radius), 2.5)
    for _ in range(20):
        a, b = r, r * rng.uniform(0.5, 1.0)
        th = rng.uniform(0, np.pi)
        c0 = rng.uniform(0, 1, 2)
        g = np.arange(-int(r) - 2, int(r) + 3)
        X, Y = np.meshgrid(g, g)
        u = (X + 0.5 - c0[0]) * np.cos(th) + (Y + 0.5 - c0[1]) * np.sin(th)
        v = -(X + 0.5 - c0[0]) * np.sin(th) + (Y + 0.5 - c0[1]) * np.cos(th)
        inside = (u / a) ** 2 + (v / b) ** 2 < 1
        curve = trace_cells(list(zip(X[inside].tolist(), Y[inside].tolist())))
        if curve is not None:
            return curve
    raise AssertionError("no simple digital contour found")


def make_polygon(kind, k, radius, seed, integer=True):
    rng = np.random.default_rng(seed)
    if kind == "point":
        return np.round(rng.uniform(-3, 3, (1, 2)))
    if kind == "segment":
        a = np.round(rng.uniform(-radius, radius, 2))
        b = a + np.array([1.0 + rng.integers(0, 5), rng.integers(-3, 4)])
        return np.array([a, b])
    if kind == "digital":
        return digital_contour(radius, seed)
    ang = np.sort(rng.uniform(0, 2 * np.pi, k))
    if kind == "convex":
        pts = np.c_[radius * np.cos(ang), radius * np.sin(ang)]
        p = convex_hull(np.round(pts) if integer else pts).astype(np.float64)
        if len(p) < 3:
            p = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * max(radius, 1)
        return p
    if kind == "star":  # star-shaped around the origin: angular gaps below pi
        k = max(k, 4)
        ang = rng.uniform(0, 2 * np.pi) + 2 * np.pi * (np.arange(k) + rng.uniform(-0.4, 0.4, k)) / k
        r = radius * rng.uniform(0.35, 1.0, k)
        pts = np.c_[r * np.cos(ang), r * np.sin(ang)]
        p = dedupe_cyclic(np.round(pts) if integer else pts)
        return p[::-1].copy() if shoelace(p) < 0 else p   # outer orientation
    if kind == "scribble":  # arbitrary, self-intersecting point sequence
        return dedupe_cyclic(np.round(rng.uniform(-radius, radius, (k, 2))))
    raise AssertionError(kind)


KINDS = ["convex", "star", "digital", "scribble", "point", "segment"]


@st.composite
def band_pairs(draw, kinds=KINDS, holes=True):
    kl = draw(st.sampled_from(kinds))
    ku = draw(st.sampled_from(kinds))
    lower = make_polygon(kl, draw(st.integers(3, 40)), draw(st.integers(1, 25)), draw(st.integers(0, 2**31)))
    upper = make_polygon(ku, draw(st.integers(3, 40)), draw(st.integers(1, 25)), draw(st.integers(0, 2**31)))
    scale = draw(st.sampled_from([1.0, 0.37, 2.5]))
    off = np.array([draw(st.integers(-50, 50)), draw(st.integers(-50, 50))], dtype=np.float64)
    du = np.array([draw(st.integers(-4, 4)), draw(st.integers(-4, 4))], dtype=np.float64)
    if holes and draw(st.booleans()):
        lower, upper = lower[::-1].copy(), upper[::-1].copy()
    z1 = float(draw(st.integers(-5, 5)))
    dz = draw(st.sampled_from([0.25, 1.0, 3.0]))
    lo = np.c_[(lower + off) * scale, np.full(len(lower), z1)]
    up = np.c_[(upper + off + du) * scale, np.full(len(upper), z1 + dz)]
    return lo, up


# ----------------------------------------------------------------------------------------------
# checks
# ----------------------------------------------------------------------------------------------
def check_band(lower, upper, faces, annulus=False):
    """The band contract: shape, every polygon edge once with its direction, closed band.

    With ``annulus`` also require a topological annulus: no diagonal is used twice (no
    "double cone" pinched at one edge).  Returns True if the band is an annulus."""
    n, m = len(lower), len(upper)
    V = np.vstack([lower, upper])
    assert faces.dtype == np.int64 and faces.ndim == 2 and faces.shape[1] == 3
    if n == 1 and m == 1:
        assert len(faces) == 0
        return True
    expected_k = max(n, m) if min(n, m) == 1 else n + m
    assert len(faces) == expected_k
    assert faces.min() >= 0 and faces.max() < n + m
    # three distinct vertices, nonzero area (the polygons are at different heights)
    assert np.all((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2]))
    t = V[faces]
    area2 = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    assert np.all(area2 > 0)
    # each face: two vertices on one level, one on the other
    is_up = faces >= n
    assert np.all((is_up.sum(axis=1) == 1) | (is_up.sum(axis=1) == 2))
    half = Counter()
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            half[(int(a), int(b))] += 1
    same_level = Counter({e: c for e, c in half.items() if (e[0] >= n) == (e[1] >= n)})
    want = Counter()
    if n >= 2:
        for i in range(n):
            want[(i, (i + 1) % n)] += 1          # a_i -> a_{i+1}
    if m >= 2:
        for j in range(m):
            want[(n + (j + 1) % m, n + j)] += 1  # b_{j+1} -> b_j
    assert same_level == want
    # cross edges (diagonals) pair up: the band closes and is winding-consistent
    for (a, b), c in half.items():
        if (a >= n) != (b >= n):
            assert half[(b, a)] == c, ((a, b), c, half[(b, a)])
    is_annulus = all(c == 1 for (a, b), c in half.items() if (a >= n) != (b >= n))
    if min(n, m) == 1:
        is_annulus = True   # a fan: its one-point "edge" is degenerate by nature
    if annulus:
        assert is_annulus
    return is_annulus


def band_area(lower, upper, faces):
    t = np.vstack([lower, upper])[faces]
    return 0.5 * float(np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


# ----------------------------------------------------------------------------------------------
# the hand-worked case (paper, section 3.4, traced line by line)
# ----------------------------------------------------------------------------------------------
SQUARE = np.array([(1, 1), (3, 1), (3, 3), (1, 3)], dtype=np.float64)
OCTAGON = np.array([(1, 0), (3, 0), (4, 1), (4, 3), (3, 4), (1, 4), (0, 3), (-1, 1)], dtype=np.float64)


def test_hand_worked_square_above_octagon():
    """Square (z = 1) above an 8-point polygon (z = 0), traced by hand through lines 01-32.

    n = 4 < m = 8 after the swap, so C(1) = square (p1_1..p1_4), C(2) = octagon (p2_1..p2_8).
    Initial edge: p1_1 = (1, 1, 1); nearest C(2) point is p2_1 = (1, 0, 0) (dist^2 2).
    Trace (i, j after each new edge):
      04 x1_2=3 >= x2_1=1 -> j=2; 05 right: 3>1, 3>=1; 06 3>3 no -> 23, 24: e1=(2,1)
      05 (i=2,j=2) down: y1_3=3>1, y2_2=0>=0; 15 3>0 -> 22: e2=(2,2)
      05 (i=2,j=3) down: 1>=0; 3>1 -> 22: e3=(2,3)
      05 (i=2,j=4) down: 3>=1; 3>3 no -> 23, 24: e4=(3,3)
      05 (i=3,j=4) left: x1_4=1<3, x2_4=4<=4; 1<4 -> 22: e5=(3,4)
      05 (i=3,j=5) left: 3<=4; 1<3 -> 22: e6=(3,5)
      05 (i=3,j=6) left: 1<=3; 1<1 no -> 23, 24: e7=(4,5), i=n
      30 i=n -> 22: e8=(4,6), e9=(4,7), e10=(4,8); 25 i=n, j=m -> 26: e11=(1,8); (e11, e0) last.
    """
    assert shoelace(SQUARE) > 0 and shoelace(OCTAGON) > 0
    lo = np.c_[OCTAGON, np.zeros(8)]
    up = np.c_[SQUARE, np.ones(4)]
    # C(1)/C(2) edge sequence, 0-based (p_i -> i-1)
    E = wiederhold_edges(SQUARE[:, 0].copy(), SQUARE[:, 1].copy(), OCTAGON[:, 0].copy(), OCTAGON[:, 1].copy())
    assert E.tolist() == [[0, 0], [1, 0], [1, 1], [1, 2], [2, 2], [2, 3], [2, 4], [3, 4],
                          [3, 5], [3, 6], [3, 7], [0, 7]]
    # faces: octagon (lower) = 0..7, square (upper) = 8..11; swapped, so flipped back
    faces = triangulate_band(lo, up, "wiederhold")
    assert faces.tolist() == [[8, 0, 9], [9, 0, 1], [9, 1, 2], [9, 2, 10], [10, 2, 3], [10, 3, 4],
                              [10, 4, 11], [11, 4, 5], [11, 5, 6], [11, 6, 7], [11, 7, 8], [8, 7, 0]]
    check_band(lo, up, faces)
    # the same pair the other way up (no swap): lower = square at z=0, upper = octagon at z=1
    faces2 = triangulate_band(np.c_[SQUARE, np.zeros(4)], np.c_[OCTAGON, np.ones(8)], "wiederhold")
    assert faces2.tolist() == [[0, 1, 4], [1, 5, 4], [1, 6, 5], [1, 2, 6], [2, 7, 6], [2, 8, 7],
                               [2, 3, 8], [3, 9, 8], [3, 10, 9], [3, 11, 10], [3, 0, 11], [0, 4, 11]]


def test_hand_worked_first_step_line_24():
    """Line 04 false (x1_2 < x2_1): C(1) advances first, via line 24."""
    c1 = np.array([(5, 0), (0, 0), (0, 5)], dtype=np.float64)  # x decreases first
    c2 = np.array([(6, 1), (-1, 1), (-1, 6), (6, 6)], dtype=np.float64)
    E = wiederhold_edges(c1[:, 0].copy(), c1[:, 1].copy(), c2[:, 0].copy(), c2[:, 1].copy())
    # 04: 0 >= 6 false -> 24: e1=(2,1), i=2; 27 j=2; 05: left: x1_3=0<0 no; down: 5>0 and
    # y2_2=1>=1 -> 15: 5>1 -> 22: e2=(2,2); j=3: down: 6>=1, 5>6 no -> 23,24: e3=(3,2), i=n;
    # 22: e4=(3,3), 22: e5=(3,4); 26: e6=(1,4)
    assert E.tolist() == [[0, 0], [1, 0], [1, 1], [2, 1], [2, 2], [2, 3], [0, 3]]


def test_hand_worked_line_04_equality_and_upward_step():
    """Line 04 with x(1)_2 == x(2)_1 (>= holds), then line 05 'to the right' fails and line 08
    'upwards' decides (09: C(2) advances)."""
    c1 = np.array([(0, 2), (1, 0), (2, 2)], dtype=np.float64)
    c2 = np.array([(1, 3), (0, 1), (1, -1), (3, 1)], dtype=np.float64)
    E = wiederhold_edges(c1[:, 0].copy(), c1[:, 1].copy(), c2[:, 0].copy(), c2[:, 1].copy())
    # 04: 1 >= 1 -> j=2; 05: x2_2=0 >= 1 fails; 08: 0<2, 1<=3; 09: 0<1 -> 22: e1=(1,2)
    # 05 (1,3): right, 06: 1>1 no -> 23,24: e2=(2,2); 05 (2,3): right, 2>1 -> 22: e3=(2,3)
    # 05 (2,4): right, 2>3 no -> 23,24: e4=(3,3), i=n; 22: e5=(3,4); 26: e6=(1,4)
    assert E.tolist() == [[0, 0], [0, 1], [1, 1], [1, 2], [2, 2], [2, 3], [0, 3]]


# ----------------------------------------------------------------------------------------------
# contract, for every method, on random pairs
# ----------------------------------------------------------------------------------------------
@SETTINGS
@given(band_pairs())
def test_band_contract_random_pairs(pair):
    lo, up = pair
    for method in METHODS:
        check_band(lo, up, triangulate_band(lo, up, method), annulus=(method == "optimal"))


@settings(max_examples=300, deadline=None)
@given(st.integers(2, 30), st.integers(0, 40), st.integers(0, 2**31), st.sampled_from([0, 3]))
def test_wiederhold_pseudocode_steps_advance_one_contour(n, extra, seed, span):
    """Lines 02-32 as written: n + m edges, each step advances exactly one contour by one."""
    rng = np.random.default_rng(seed)
    m = n + extra
    a = rng.integers(-span - 1, span + 2, (n, 2)).astype(np.float64)
    b = rng.integers(-span - 1, span + 2, (m, 2)).astype(np.float64)
    E = wiederhold_edges(a[:, 0].copy(), a[:, 1].copy(), b[:, 0].copy(), b[:, 1].copy())
    assert E.shape == (n + m, 2)
    assert E[0].tolist() == [0, 0]
    nxt = np.roll(E, -1, axis=0)
    di = (nxt[:, 0] - E[:, 0]) % n
    dj = (nxt[:, 1] - E[:, 1]) % m
    assert np.all(((di == 1) & (dj == 0)) | ((di == 0) & (dj == 1)))
    assert di.sum() == n and dj.sum() == m


@settings(max_examples=60, deadline=None)
@given(band_pairs(kinds=["convex", "star", "digital", "scribble", "segment"]))
def test_optimal_area_not_above_others(pair):
    lo, up = pair
    a_opt = band_area(lo, up, triangulate_band(lo, up, "optimal"))
    for method in ("wiederhold", "greedy"):
        f = triangulate_band(lo, up, method)
        if check_band(lo, up, f):   # optimal ranges over annular bands only
            assert a_opt <= band_area(lo, up, f) * (1 + 1e-12) + 1e-12


def test_optimal_is_brute_force_minimum_small():
    """Against exhaustive enumeration of all monotone lattice paths and all starts."""
    from itertools import combinations

    rng = np.random.default_rng(7)
    for _ in range(25):
        n, m = rng.integers(2, 5), rng.integers(2, 6)
        a = np.c_[rng.normal(size=(n, 2)) * 3, np.zeros(n)]
        b = np.c_[rng.normal(size=(m, 2)) * 3, np.ones(m)]
        c1, c2 = (a, b) if n <= m else (b, a)
        best = np.inf
        N, M = len(c1), len(c2)
        for s in range(N):
            for t in range(M):
                for pos in combinations(range(N + M), N):
                    i = j = 0
                    tot = 0.0
                    nodes = set()
                    for k in range(N + M):
                        p, q = c1[(s + i) % N], c2[(t + j) % M]
                        nodes.add(((s + i) % N, (t + j) % M))
                        if k in pos:
                            r = c1[(s + i + 1) % N]
                            i += 1
                        else:
                            r = c2[(t + j + 1) % M]
                            j += 1
                        tot += 0.5 * np.linalg.norm(np.cross(r - p, q - p))
                    if len(nodes) == N + M:   # annulus: no diagonal (torus node) visited twice
                        best = min(best, tot)
        _, _, total = optimal_edges(c1, c2)
        assert total == pytest.approx(best, rel=1e-12)
        assert band_area(a, b, triangulate_band(a, b, "optimal")) == pytest.approx(best, rel=1e-12)


# ----------------------------------------------------------------------------------------------
# orientation
# ----------------------------------------------------------------------------------------------
def cylinder_section(k, r, seed, integer, phase=0.0):
    """Convex hull of k points around the axis (0, 0): jittered even angles, radius within 5 % of r."""
    rng = np.random.default_rng(seed)
    ang = phase + 2 * np.pi * (np.arange(k) + rng.uniform(-0.3, 0.3, k)) / k
    rad = r * rng.uniform(0.95, 1.05, k)
    p = np.c_[rad * np.cos(ang), rad * np.sin(ang)]
    return convex_hull(np.round(p) if integer else p).astype(np.float64)


@SETTINGS
@given(st.integers(8, 40), st.integers(8, 40), st.floats(8, 30), st.floats(0.8, 1.25),
       st.integers(0, 2**31), st.sampled_from(METHODS), st.booleans())
def test_normals_point_away_from_axis_on_cylinder_like_pair(n, m, r, ratio, seed, method, integer):
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi)
    lo2 = cylinder_section(n, r, seed, integer, phase)
    up2 = cylinder_section(m, r * ratio, seed + 1, integer, phase)
    lo = np.c_[lo2 + 100, np.zeros(len(lo2))]
    up = np.c_[up2 + 100, np.full(len(up2), 2.0)]
    faces = triangulate_band(lo, up, method)
    check_band(lo, up, faces)
    t = np.vstack([lo, up])[faces]
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    radial = t.mean(axis=1)[:, :2] - 100.0
    assert np.all(np.einsum("ij,ij->i", normal[:, :2], radial) > 0)


def _closed_mesh(lo, up, faces, holes=()):
    """Band(s) + downward lower cap + upward upper cap, as one vertex array."""
    import trimesh

    V = np.vstack([lo, up])
    F = [faces]
    n = len(lo)
    F.append(cap_faces(lo, upward=False))
    F.append(cap_faces(up, upward=True) + n)
    return trimesh.Trimesh(V, np.vstack(F), process=False)


def assert_closed_positive(lo, up, method, positive=True):
    mesh = _closed_mesh(lo, up, triangulate_band(lo, up, method))
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    if positive:
        assert mesh.volume > 0


@SETTINGS
@given(st.sampled_from(["convex", "digital"]), st.integers(6, 40), st.integers(6, 40),
       st.floats(0.8, 1.25), st.floats(0, 2 * np.pi), st.integers(0, 2**31), st.sampled_from(METHODS))
def test_cylinder_like_band_plus_caps_is_watertight_with_positive_volume(kind, n, m, ratio, phase, seed,
                                                                          method):
    if kind == "convex":
        lo2 = cylinder_section(n, 12, seed, False, phase)
        up2 = cylinder_section(m, 12 * ratio, seed + 1, True, phase)
    else:
        lo2, up2 = digital_contour(9, seed), digital_contour(9 * ratio, seed + 1)
    lo = np.c_[lo2, np.zeros(len(lo2))]
    up = np.c_[up2 + 0.5, np.full(len(up2), 1.5)]
    assert_closed_positive(lo, up, method)


@SETTINGS
@given(st.sampled_from(["convex", "star", "digital"]), st.sampled_from(["convex", "star", "digital"]),
       st.integers(3, 40), st.integers(3, 40), st.integers(0, 2**31))
def test_optimal_band_plus_caps_is_always_watertight(kl, ku, n, m, seed):
    """The optimal band is an annulus for any pair of simple polygons (closed and consistently
    wound; the volume sign is not asserted: very dissimilar pairs may self-intersect)."""
    lo2 = make_polygon(kl, n, 12, seed, integer=False)
    up2 = make_polygon(ku, m, 7, seed + 1, integer=False)
    lo = np.c_[lo2, np.zeros(len(lo2))]
    up = np.c_[up2 + 3, np.full(len(up2), 1.5)]
    assert_closed_positive(lo, up, "optimal", positive=False)


def test_double_cone_from_local_rules_and_not_from_optimal():
    """Two thin, rotated triangles: the paper's rule advances all of C(2) at one point of C(1)
    (a "double cone": the diagonal (a_0, b_2) carries four triangles).  This is the algorithm
    as written; the optimal band excludes such paths and closes into a watertight mesh."""
    lo = np.array([[-11.96691237, -0.89051013, 0.0], [11.42343356, -3.67493752, 0.0],
                   [7.40484903, 9.44289208, 0.0]])
    up = np.array([[-1.99986822, 10.53943346, 1.5], [4.92678502, -8.19675809, 1.5],
                   [0.27103524, 10.97339513, 1.5]])
    f = triangulate_band(lo, up, "wiederhold", fallback=False)
    assert f.tolist() == [[0, 4, 3], [0, 5, 4], [0, 1, 5], [1, 2, 5], [2, 0, 5], [0, 3, 5]]
    assert not check_band(lo, up, f)
    from contourmesh.bands import band_is_folded

    assert band_is_folded(f)
    # the dispatcher's default replaces the folded band by the optimal one
    assert triangulate_band(lo, up, "wiederhold").tolist() == triangulate_band(lo, up, "optimal").tolist()
    assert check_band(lo, up, triangulate_band(lo, up, "optimal"), annulus=True)
    assert_closed_positive(lo, up, "optimal")


@pytest.mark.parametrize("method", METHODS)
def test_annulus_with_hole_bands_is_closed_and_outward(method):
    """Outer contours positive, holes negative: bands + caps with holes bound a positive volume."""
    import trimesh

    def ring(r, k, z, sign):
        ang = np.linspace(0, 2 * np.pi, k, endpoint=False)
        p = np.c_[r * np.cos(ang), r * np.sin(ang)]
        p = p if sign > 0 else p[::-1]
        return np.c_[p, np.full(k, z)]

    lo_out, up_out = ring(10, 24, 0.0, +1), ring(9, 17, 1.0, +1)
    lo_hole, up_hole = ring(4, 9, 0.0, -1), ring(5, 13, 1.0, -1)
    assert shoelace(lo_hole) < 0 and shoelace(lo_out) > 0
    V = np.vstack([lo_out, up_out, lo_hole, up_hole])
    o1, o2, o3 = len(lo_out), len(lo_out) + len(up_out), len(lo_out) + len(up_out) + len(lo_hole)
    F = [
        triangulate_band(lo_out, up_out, method),
        triangulate_band(lo_hole, up_hole, method) + o2,
    ]
    lower_cap = cap_faces(lo_out, [lo_hole], upward=False)  # indices into [lo_out, lo_hole]
    lower_cap = np.where(lower_cap >= o1, lower_cap - o1 + o2, lower_cap)
    upper_cap = cap_faces(up_out, [up_hole], upward=True)   # indices into [up_out, up_hole]
    upper_cap = np.where(upper_cap >= len(up_out), upper_cap - len(up_out) + o3, upper_cap + o1)
    mesh = trimesh.Trimesh(V, np.vstack(F + [lower_cap, upper_cap]), process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume > 0


def _canon(tri):
    k = int(np.argmin(tri))
    return tuple(int(v) for v in np.roll(tri, -k))


@SETTINGS
@given(band_pairs(), st.sampled_from(METHODS))
def test_internal_swap_equals_mirrored_problem(pair, method):
    """With n > m the contours are swapped internally; the result must equal the z-mirrored
    problem solved without a swap, with every triangle reversed (the mirror flips orientation)."""
    lo, up = pair
    if len(lo) < len(up):
        z1, z2 = lo[0, 2], up[0, 2]
        lo, up = np.c_[up[:, :2], np.full(len(up), z1)], np.c_[lo[:, :2], np.full(len(lo), z2)]
    n, m = len(lo), len(up)
    if n == m:
        return
    f1 = triangulate_band(lo, up, method)  # swapped internally
    lo_m = np.c_[up[:, :2], -up[:, 2]]      # mirrored: the old upper is now below
    up_m = np.c_[lo[:, :2], -lo[:, 2]]
    f2 = triangulate_band(lo_m, up_m, method)  # m < n: no swap
    remap = np.r_[np.arange(m) + n, np.arange(n)]
    f2 = remap[f2][:, ::-1]
    assert sorted(_canon(f) for f in f1) == sorted(_canon(f) for f in f2)


# ----------------------------------------------------------------------------------------------
# degenerate polygons, initial edge, validation
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_pole_fan_and_point_pairs(method):
    ring = np.c_[np.array([(0, 0), (4, 0), (4, 4), (0, 4), (-1, 2)], float), np.zeros(5)]
    pole = np.array([[2.0, 2.0, 3.0]])
    f = triangulate_band(ring, pole, method)
    assert sorted(_canon(t) for t in f) == sorted(_canon((i, (i + 1) % 5, 5)) for i in range(5))
    f = triangulate_band(pole - [0, 0, 6], ring, method)
    assert sorted(_canon(t) for t in f) == sorted(_canon((0, 1 + (j + 1) % 5, 1 + j)) for j in range(5))
    assert triangulate_band(pole - [0, 0, 6], pole, method).shape == (0, 3)
    seg = np.array([[0.0, 0.0, 1.0], [3.0, 1.0, 1.0]])
    check_band(ring, seg, triangulate_band(ring, seg, method))
    check_band(seg - [0, 0, 2], seg, triangulate_band(seg - [0, 0, 2], seg, method))
    check_band(pole - [0, 0, 9], seg, triangulate_band(pole - [0, 0, 9], seg, method))


def test_initial_edge_local_window_and_fallback():
    ang = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    c2 = np.c_[50 * np.cos(ang), 50 * np.sin(ang), np.ones(400)]
    c1 = np.c_[49 * np.cos(ang[::4]), 49 * np.sin(ang[::4]), np.zeros(100)]
    assert initial_edge(c1, c2) == 0                       # found in the window around C(2)'s start
    rolled = np.roll(c2, 137, axis=0)                       # start far away: full search fallback
    assert initial_edge(c1, rolled) == 137
    assert initial_edge(c1, np.roll(c2, 5, axis=0)) == 5    # inside the window
    small = c2[::50]
    d = np.sum((small - c1[0]) ** 2, axis=1)
    assert initial_edge(c1, small) == int(np.argmin(d))


def test_validation_messages():
    sq = np.c_[SQUARE, np.zeros(4)]
    with pytest.raises(ValueError, match="greedy.*optimal.*wiederhold"):
        triangulate_band(sq, sq + [0, 0, 1], method="nope")
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        triangulate_band(SQUARE, sq + [0, 0, 1])
    with pytest.raises(ValueError, match="strictly above"):
        triangulate_band(sq, sq)
    with pytest.raises(ValueError, match="consecutive"):
        triangulate_band(np.vstack([sq, sq[:1]]), sq + [0, 0, 1])
    with pytest.raises(ValueError, match="one plane"):
        triangulate_band(sq + np.c_[np.zeros((4, 2)), np.arange(4)], sq + [0, 0, 9])
    with pytest.raises(ValueError, match="finite"):
        triangulate_band(np.where(sq == 3, np.nan, sq), sq + [0, 0, 1])
    with pytest.raises(ValueError, match="at least one point"):
        triangulate_band(np.empty((0, 3)), sq)
    with pytest.raises(ValueError, match="sequence"):
        cap_faces(SQUARE, SQUARE)


# ----------------------------------------------------------------------------------------------
# caps
# ----------------------------------------------------------------------------------------------
def _signed_cap_area(xy, faces):
    t = xy[faces]
    u, v = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return 0.5 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def test_cap_square_orientation_and_area():
    f = cap_faces(SQUARE)
    assert f.shape == (2, 3) and f.dtype == np.int64
    s = _signed_cap_area(SQUARE, f)
    assert np.all(s > 0) and s.sum() == pytest.approx(4.0)
    s = _signed_cap_area(SQUARE[::-1], cap_faces(SQUARE[::-1], upward=False))
    assert np.all(s < 0) and s.sum() == pytest.approx(-4.0)
    # (k, 3) input is accepted, only x, y used
    assert np.array_equal(cap_faces(np.c_[SQUARE, np.full(4, 7.0)]), f)


def test_cap_with_holes_area_and_indexing():
    outer = np.c_[np.array([0, 10, 10, 0], float), np.array([0, 0, 10, 10], float)]
    h1 = np.array([(2, 2), (2, 4), (4, 4), (4, 2)], float)   # negative orientation
    tiny = np.array([(6, 6), (7, 7)], float)                  # degenerate hole: ignored
    h2 = np.array([(6, 2), (8, 2), (8, 5)], float)
    f = cap_faces(outer, [h1, tiny, h2])
    V = np.vstack([outer, h1, tiny, h2])
    assert not np.isin(f, [8, 9]).any()
    s = _signed_cap_area(V, f)
    assert np.all(s > 0)
    assert s.sum() == pytest.approx(100 - 4 - 3)


@pytest.mark.parametrize("poly", [np.zeros((0, 2)), [[0, 0]], [[0, 0], [1, 1]], [[0, 0], [1, 1], [2, 2]]])
def test_cap_degenerate_is_empty(poly):
    assert cap_faces(np.asarray(poly, float)).shape == (0, 3)


@SETTINGS
@given(st.sampled_from(["convex", "star", "digital"]), st.integers(3, 60), st.integers(0, 2**31), st.booleans())
def test_cap_uses_every_boundary_edge_once(kind, k, seed, upward):
    p = make_polygon(kind, k, 15, seed, integer=(kind == "digital"))
    f = cap_faces(p, upward=upward)
    s = _signed_cap_area(p, f)
    assert np.all(s > 0) if upward else np.all(s < 0)
    assert abs(s.sum()) == pytest.approx(abs(shoelace(p)))
    half = Counter()
    for t in f:
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            half[(int(a), int(b))] += 1
    n = len(p)
    for i in range(n):
        e = (i, (i + 1) % n) if upward else ((i + 1) % n, i)
        assert half[e] == 1 and half[(e[1], e[0])] == 0


def test_t_junction_splitting_of_collinear_triangles_ends():
    """Degenerate triangles along a collinear run once re-split each other for ever (a hang); the
    splitter now gives up and reports the cap as not triangulable (the caller's CapError)."""
    from contourmesh.bands.caps import split_t_junctions

    v = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [1.5, 0]], float)
    assert split_t_junctions(v, [(0, 3, 1), (3, 0, 2)], np.array([[0, 1], [1, 2], [2, 3], [3, 0]])) is None
