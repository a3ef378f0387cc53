"""Contour following (contourmesh.tracing): hand-worked cases and independent checks."""

import numpy as np
import pytest

from contourmesh.tracing import check_contour4, rotate_start, trace_contours
from contourmesh.types import shoelace_area


def u_cells(mask, x0=0, y0=0):
    """The cells of U (lower-left corners), computed independently of the tracer."""
    pts = {(x0 + i, y0 + j) for j, i in zip(*np.nonzero(mask))}
    return {(x + dx, y + dy) for x, y in pts for dx in (-1, 0) for dy in (-1, 0)}


def boundary_edges(cells):
    """Directed unit edges of the boundary of the union of cells, with the cells on the left."""
    edges = []
    for a, b in cells:
        if (a, b - 1) not in cells:
            edges.append(((a, b), (a + 1, b)))
        if (a + 1, b) not in cells:
            edges.append(((a + 1, b), (a + 1, b + 1)))
        if (a, b + 1) not in cells:
            edges.append(((a + 1, b + 1), (a, b + 1)))
        if (a - 1, b) not in cells:
            edges.append(((a, b + 1), (a, b)))
    return sorted(edges)


def contour_edges(contours):
    out = []
    for c in contours:
        c = c.tolist()
        out += [(tuple(c[i]), tuple(c[(i + 1) % len(c)])) for i in range(len(c))]
    return sorted(out)


def check_basic(contours, parents):
    assert len(contours) == len(parents)
    for c, p in zip(contours, parents):
        assert c.dtype == np.int64 and c.ndim == 2 and c.shape[1] == 2
        check_contour4(c)  # unit 4-steps, closed implicitly, no reversal
        a = shoelace_area(c)
        assert (a > 0) == (p == -1) and a != 0
        if p >= 0:
            assert parents[p] == -1
        # starts at its lowest-then-leftmost point
        assert tuple(c[0][::-1]) == min(map(tuple, c[:, ::-1].tolist()))
    keys = [tuple(c[0][::-1]) for c in contours]
    assert keys == sorted(keys)


def test_single_point():
    (c,), parents = trace_contours(np.ones((1, 1), dtype=bool), x0=3, y0=-2)
    assert parents == [-1]
    assert c.tolist() == [[2, -3], [3, -3], [4, -3], [4, -2], [4, -1], [3, -1], [2, -1], [2, -2]]
    assert shoelace_area(c) == 4.0


def test_row_of_points():
    n = 7
    (c,), parents = trace_contours(np.ones((1, n), dtype=bool))
    assert parents == [-1]
    assert len(c) == 2 * (n + 1) + 4
    assert shoelace_area(c) == 2 * (n + 1)
    assert c.min(axis=0).tolist() == [-1, -1] and c.max(axis=0).tolist() == [n, 1]


def test_l_shape():
    m = np.zeros((6, 5), dtype=bool)
    m[:, :2] = True
    m[:2, :] = True
    contours, parents = trace_contours(m)
    check_basic(contours, parents)
    assert parents == [-1]
    cells = u_cells(m)
    assert shoelace_area(contours[0]) == len(cells)
    assert contour_edges(contours) == boundary_edges(cells)


def test_ring_outer_and_hole():
    m = np.ones((8, 9), dtype=bool)
    m[2:6, 3:6] = False
    contours, parents = trace_contours(m, x0=10, y0=20)
    check_basic(contours, parents)
    assert parents == [-1, 0]
    outer, hole = contours
    assert shoelace_area(outer) == 10 * 9
    # the hole of U: cells with no corner in I, x in [13, 15], y in [22, 25] -> a 2 x 3 rectangle of cells
    assert shoelace_area(hole) == -(2 * 3)
    assert hole[0].tolist() == [13, 22]
    assert contour_edges(contours) == boundary_edges(u_cells(m, 10, 20))


def test_nested_rings():
    m = np.zeros((17, 17), dtype=bool)
    m[:, :] = True
    m[2:15, 2:15] = False
    m[5:12, 5:12] = True
    m[7:10, 7:10] = False
    contours, parents = trace_contours(m)
    check_basic(contours, parents)
    areas = [shoelace_area(c) for c in contours]
    assert [a > 0 for a in areas] == [True, False, True, False]
    assert parents == [-1, 0, -1, 2]


def test_two_components_and_order():
    m = np.zeros((10, 12), dtype=bool)
    m[6:9, 1:3] = True  # upper left (larger y)
    m[1:3, 8:11] = True  # lower right (smaller y): listed first
    contours, parents = trace_contours(m)
    check_basic(contours, parents)
    assert parents == [-1, -1]
    assert contours[0][0].tolist() == [7, 0] and contours[1][0].tolist() == [0, 5]


def test_corner_pinch_splits_into_two_contours():
    m = np.zeros((3, 3), dtype=bool)
    m[0, 0] = m[2, 2] = True  # U's cells touch only at the corner (1, 1)
    contours, parents = trace_contours(m)
    check_basic(contours, parents)
    assert parents == [-1, -1]
    assert [len(c) for c in contours] == [8, 8]
    shared = set(map(tuple, contours[0].tolist())) & set(map(tuple, contours[1].tolist()))
    assert shared == {(1, 1)}


def test_border_touching_mask_is_padded():
    rng = np.random.default_rng(3)
    m = rng.random((9, 11)) < 0.6
    m[0, :] = m[:, -1] = True
    c1, p1 = trace_contours(m)
    padded = np.zeros((13, 15), dtype=bool)
    padded[2:-2, 2:-2] = m
    c2, p2 = trace_contours(padded, x0=-2, y0=-2)
    assert p1 == p2
    assert all(np.array_equal(a, b) for a, b in zip(c1, c2)) and len(c1) == len(c2)


def test_translation_invariance():
    rng = np.random.default_rng(4)
    m = rng.random((15, 13)) < 0.55
    c1, p1 = trace_contours(m)
    c2, p2 = trace_contours(m, x0=-37, y0=1005)
    assert p1 == p2
    for a, b in zip(c1, c2):
        assert np.array_equal(a + [-37, 1005], b)


@pytest.mark.parametrize("seed", range(12))
def test_random_masks_cover_every_boundary_edge_once(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(3, 25, size=2))
    m = rng.random(shape) < rng.uniform(0.3, 0.8)
    x0, y0 = (int(v) for v in rng.integers(-5, 5, size=2))
    contours, parents = trace_contours(m, x0=x0, y0=y0)
    check_basic(contours, parents)
    cells = u_cells(m, x0, y0)
    contours0 = contours
    assert contour_edges(contours0) == boundary_edges(cells)
    # total signed area = number of cells of U
    assert sum(shoelace_area(c) for c in contours0) == len(cells)
    # each hole lies inside its parent (winding number of the parent around a hole cell centre)
    for c, p in zip(contours0, parents):
        if p >= 0:
            q = c[0] + 0.5  # the hole's lowest-leftmost cell is background, centred here
            par = contours0[p].astype(float)
            x, y = par[:, 0], par[:, 1]
            x2, y2 = np.roll(x, -1), np.roll(y, -1)
            cross = (x2 - x) * (q[1] - y) - (y2 - y) * (q[0] - x)
            wn = np.sum((y <= q[1]) & (y2 > q[1]) & (cross > 0)) - np.sum((y > q[1]) & (y2 <= q[1]) & (cross < 0))
            assert wn != 0


def test_empty_mask():
    assert trace_contours(np.zeros((4, 5), dtype=bool)) == ([], [])
    assert trace_contours(np.zeros((0, 0), dtype=bool)) == ([], [])


def test_mask_validation():
    with pytest.raises(ValueError, match="2D"):
        trace_contours(np.ones((2, 2, 2), dtype=bool))
    with pytest.raises(ValueError, match="boolean"):
        trace_contours(np.full((2, 2), 3))
    with pytest.raises(ValueError, match="integers"):
        trace_contours(np.ones((2, 2), dtype=bool), x0=0.5)


def test_large_slice_is_fast_enough():
    yy, xx = np.mgrid[:1000, :1000]
    m = (xx - 500.3) ** 2 + (yy - 499.6) ** 2 < 480**2
    m[400:600, 400:600] = False
    contours, parents = trace_contours(m)
    assert parents == [-1, 0]
    assert shoelace_area(contours[1]) == -(199 * 199)


def test_rotate_start():
    c = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1]], dtype=np.int64)
    r = rotate_start(c, (2, 2))
    assert r.tolist() == [[2, 1], [1, 1], [0, 1], [0, 0], [1, 0], [2, 0]]
    # ties: (1, 0) and (1, 1) are both at distance 0.5 from (1, 0.5); the smaller index wins
    assert rotate_start(c, (1, 0.5))[0].tolist() == [1, 0]
    assert np.array_equal(rotate_start(c, (0, 0)), c)
    with pytest.raises(ValueError):
        rotate_start(c, (1, 2, 3))


def test_check_contour4_rejects_bad_input():
    good = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])
    assert check_contour4(good).dtype == np.int64
    with pytest.raises(ValueError, match="closing"):
        check_contour4(np.vstack([good, good[:1]]))
    with pytest.raises(ValueError, match="unit 4-step"):
        check_contour4(np.array([[0, 0], [2, 0], [2, 1], [0, 1]]))
    with pytest.raises(ValueError, match="integer"):
        check_contour4(good + 0.5)
    with pytest.raises(ValueError, match="reverses"):
        check_contour4(np.array([[0, 0], [1, 0], [0, 0], [0, 1], [1, 1], [0, 1]]))


def _contour4_steps_ok_numpy(c):
    """``check_contour4``'s step checks in their numpy form (before the compiled fast path)."""
    steps = np.roll(c, -1, axis=0) - c
    if np.any(np.abs(steps).sum(axis=1) != 1):
        return False
    return not np.any(np.all(steps == -np.roll(steps, 1, axis=0), axis=1))


def test_contour4_kernel_matches_numpy():
    from contourmesh.tracing import _contour4_ok

    rng = np.random.default_rng(2)
    seen = set()
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.int64)
    cases = [square, square[::-1].copy(), np.array([[0, 0], [1, 0], [0, 0], [1, 0]], dtype=np.int64)]
    for _ in range(400):  # random walks of unit and other steps, closed or not
        steps = rng.choice([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [0, 0]], size=rng.integers(4, 12),
                           p=[0.24, 0.24, 0.24, 0.24, 0.02, 0.02])
        cases.append(np.cumsum(steps, axis=0).astype(np.int64))
    for mask in (np.ones((3, 6), bool), np.eye(5, dtype=bool) | np.roll(np.eye(5, dtype=bool), 1, axis=1)):
        cases.extend(np.ascontiguousarray(c, dtype=np.int64) for c in trace_contours(mask)[0])
    for c in cases:
        want = _contour4_steps_ok_numpy(c)
        seen.add(want)
        assert _contour4_ok(c) is want
    assert seen == {True, False}


def test_cells_of_matches_the_numpy_reference():
    """The compiled cell complex of a mask (:func:`_cells_of`) is :func:`_cells_of_reference`'s,
    on random masks of several shapes and densities, contiguous or sliced."""
    from contourmesh.tracing import _cells_of, _cells_of_reference

    rng = np.random.default_rng(93)
    for shape in [(1, 1), (1, 7), (6, 1), (5, 9), (40, 33)]:
        for density in (0.0, 0.2, 0.7, 1.0):
            m = rng.random(shape) < density
            assert np.array_equal(_cells_of(m), _cells_of_reference(m))
    big = rng.random((30, 40)) < 0.5
    view = big[3:25:1, 5:37]
    assert not view.flags.c_contiguous
    got = _cells_of(view)
    assert got.dtype == np.bool_ and np.array_equal(got, _cells_of_reference(view))


def test_corner_tables_equal_the_per_direction_tests():
    """``_slice_cracks`` reads a corner's boundary edges and a walk's turns from tables of the four
    pixels round the corner: the same as ``_is_label_edge`` and ``_label_turn`` (which it used
    before), for every four pixels and every direction, the corner inside the image and on each of
    its borders."""
    from contourmesh import tracing

    for m in range(16):
        lab = np.array([[m & 1, (m >> 1) & 1], [(m >> 2) & 1, (m >> 3) & 1]], dtype=np.int32) * 3
        # the corner (1, 1) of the 2 x 2 image, and the same pixels cut to a border corner
        cases = [(lab, 1, 1, m)]
        if m & 0b0011 == 0:  # (the top row empty: a corner of the image's first pixel row)
            cases.append((lab[1:], 1, 0, m))
        if m & 0b1100 == 0:
            cases.append((lab[:1], 1, 1, m))
        if m & 0b0101 == 0:
            cases.append((lab[:, 1:], 0, 1, m))
        if m & 0b1010 == 0:
            cases.append((lab[:, :1], 1, 1, m))
        for img, vx, vy, mm in cases:
            img = np.ascontiguousarray(img)
            assert tracing._corner_mask(img, vx, vy, 3, img.shape[0], img.shape[1]) == mm
            for d in range(4):
                edge = bool(tracing._is_label_edge(img, np.int64(vx), np.int64(vy), np.int64(d), 3))
                assert edge == bool((tracing._CORNER_EDGES[mm] >> d) & 1)
                want = tracing._label_turn(img, np.int64(vx), np.int64(vy), np.int64(d), 3)
                assert tracing._CORNER_TURN[16 * d + mm] == want
