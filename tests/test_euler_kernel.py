"""The compiled topology and grouping kernels against their references (scipy / skimage / numpy).

Each kernel replaced a reference computation on the band route for speed only, so each must give
the reference's answer exactly: the tests draw random volumes, label images and rings, and add
the shapes where the answers differ from a plain count (cavities, tunnels, touching corners).
"""

from __future__ import annotations

import numpy as np
import pytest

from contourmesh.geometry import distinct_rows, predecessor, shoelace_area, successor
from contourmesh.topology import euler_characteristic, topology
from contourmesh.tracing import overlap_groups
from contourmesh.volumes import voxel_topology


def _random_volumes(seed, count, top=10):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        shape = tuple(int(v) for v in rng.integers(1, top, 3))
        yield rng.random(shape) < rng.uniform(0.05, 0.95)


def test_topology_equals_the_reference_on_random_volumes():
    seen = set()
    for v in _random_volumes(11, 1500):
        ref = voxel_topology(v)
        assert topology(v) == ref, v.shape
        seen.update(k for k in ("cavities", "genus") if ref[k] > 0)
        seen.update(["several"] if ref["components"] > 1 else ["sphere"] if ref["surfaces"] == 1 and ref["genus"] == 0 else [])
    # the draw reaches cavities, handles, several components and single spheres (else it proves little)
    assert seen == {"cavities", "genus", "several", "sphere"}


def test_topology_on_shapes_with_cavities_tunnels_and_corner_contacts():
    zz, yy, xx = np.mgrid[:16, :16, :16]
    r2 = (zz - 7.5) ** 2 + (yy - 7.5) ** 2 + (xx - 7.5) ** 2
    hollow = (r2 < 49) & (r2 > 9)  # a ball with a cavity
    torus = ((np.hypot(yy - 7.5, xx - 7.5) - 4.5) ** 2 + (zz - 7.5) ** 2) < 4
    corners = np.zeros((3, 3, 3), dtype=bool)
    corners[0, 0, 0] = corners[1, 1, 1] = corners[2, 2, 0] = True  # touching at corners only: 3 parts
    edge_cavity = np.ones((3, 4, 4), dtype=bool)
    edge_cavity[1, 1:3, 1:3] = False  # a cavity one voxel from the border
    open_box = edge_cavity.copy()
    open_box[1, 0, 0] = False  # the cavity still closed: it meets the outside only at a corner
    for v in (hollow, torus, corners, edge_cavity, open_box, np.zeros((2, 2, 2), bool), np.ones((1, 1, 1), bool)):
        assert topology(v) == voxel_topology(v)
    assert topology(hollow)["cavities"] == 1 and topology(torus)["genus"] == 1
    assert topology(corners)["components"] == 3


def test_euler_characteristic_is_skimage_euler_number_with_6_connectivity():
    from skimage.measure import euler_number

    for v in _random_volumes(5, 300, top=8):
        assert euler_characteristic(v) == euler_number(np.pad(v, 1), connectivity=1)


def test_topology_refuses_a_2d_mask():
    with pytest.raises(ValueError, match="3D array"):
        topology(np.ones((3, 3), dtype=bool))


def _overlap_groups_reference(la, lb, na, nb):
    """overlap_groups as it was: the pairs' bipartite graph labelled by scipy."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    both = (la > 0) & (lb > 0)
    nbk = np.int64(nb + 1)
    keys = np.unique(la[both].astype(np.int64) * nbk + lb[both])
    pairs = np.c_[keys // nbk, keys % nbk] - 1
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], na + pairs[:, 1])), shape=(na + nb, na + nb))
    _, glab = connected_components(g, directed=False)
    groups: dict = {}
    for a, b in pairs:
        ga_, gb_ = groups.setdefault(int(glab[a]), (set(), set()))
        ga_.add(int(a))
        gb_.add(int(b))
    return pairs, list(groups.values())


def test_overlap_groups_equal_the_scipy_reference():
    # int32 images take the histogram / np.unique route; the volume mesher's (uint8, C order) the
    # compiled pair table (_pair_table), and uint8 views the first route again: the same pairs and
    # groups, in the same order, each way
    from scipy import ndimage

    from contourmesh.tracing import _pair_table_ok

    rng = np.random.default_rng(3)
    several = taken = 0
    for _ in range(400):
        shape = tuple(int(v) for v in rng.integers(2, 30, 2))
        la, na = ndimage.label(rng.random(shape) < rng.uniform(0.2, 0.7))
        lb, nb = ndimage.label(rng.random(shape) < rng.uniform(0.2, 0.7))
        ref_pairs, ref_groups = _overlap_groups_reference(la, lb, na, nb)
        forms = [(la, lb)]
        if na < 256 and nb < 256:
            la8, lb8 = la.astype(np.uint8), lb.astype(np.uint8)
            taken += _pair_table_ok(la8, lb8, (na + 1) * (nb + 1))
            forms += [(la8, lb8), (la8[:, ::-1], lb8[:, ::-1])]
        for t, (x, y) in enumerate(forms):
            pairs, groups = overlap_groups(x, y, na, nb)
            want_pairs, want_groups = (ref_pairs, ref_groups) if t < 2 else \
                _overlap_groups_reference(la[:, ::-1], lb[:, ::-1], na, nb)
            assert pairs.dtype == np.int64
            np.testing.assert_array_equal(pairs, want_pairs)
            assert groups == want_groups  # the same sets in the same order
        several += len(ref_groups) > 1
    assert several > 100 and taken > 300


def test_distinct_rows_is_the_length_of_numpy_unique_rows():
    rng = np.random.default_rng(8)
    for _ in range(2000):
        n = int(rng.integers(0, 12))
        p = rng.integers(-2, 3, (n, 2)) * rng.choice([1.0, 0.5, -0.0])  # repeats, and -0.0 beside 0.0
        assert distinct_rows(p) == len(np.unique(p, axis=0))
    assert distinct_rows(np.array([[1, 2], [1, 2], [3, 4]])) == 2  # integer points too


def test_shoelace_area_and_ring_neighbours_are_those_of_np_roll():
    rng = np.random.default_rng(2)
    for n in (3, 4, 7, 50, 333):
        p = rng.normal(size=(n, 2)) * 1e3
        x, y = p[:, 0], p[:, 1]
        # bit for bit: the same dot products of the same arrays
        assert shoelace_area(p) == 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
        np.testing.assert_array_equal(successor(p), np.roll(p, -1, axis=0))
        np.testing.assert_array_equal(predecessor(p), np.roll(p, 1, axis=0))


def _meridian_params_reference(par, length, step):
    """refine._meridian_params as it was: Python loops over numpy arrays."""
    s = np.sort(np.mod(par, length))
    keep = [s[0]]
    for v in s[1:]:
        if v - keep[-1] >= 0.5 * step:
            keep.append(v)
    while len(keep) > 1 and keep[0] + length - keep[-1] < 0.5 * step:
        keep.pop()
    out = []
    k = np.array(keep)
    gaps = np.diff(np.concatenate([k, [k[0] + length]]))
    for v, g in zip(k, gaps):
        out.append(v)
        if g > 1.5 * step:
            m = int(round(g / step))
            out.extend(v + g * np.arange(1, m) / m)
    return np.mod(np.array(out), length)


def test_meridian_params_compiled_equal_the_python_loops_bit_for_bit():
    from contourmesh.refine import _meridian_params

    rng = np.random.default_rng(4)
    filled = 0
    for _ in range(1500):
        length = float(rng.uniform(5, 400))
        step = float(rng.uniform(0.3, 4.0))
        par = rng.uniform(-length, 2 * length, int(rng.integers(3, 60)))
        if rng.random() < 0.3:  # gaps of exactly k + 1/2 steps: the rounding's ties
            par = np.sort(rng.integers(0, 40, len(par)) * (step / 2)) % length
        got, ref = _meridian_params(par, length, step), _meridian_params_reference(par, length, step)
        np.testing.assert_array_equal(got, ref)
        filled += len(got) > len(np.unique(np.mod(par, length)))
    assert filled > 300  # gaps were filled, not only merged


def test_slice_labels_equal_ndimage_label_and_find_objects():
    from scipy import ndimage

    from contourmesh.fastpath import slice_labels

    cross = ndimage.generate_binary_structure(2, 1)
    rng = np.random.default_rng(6)
    for _ in range(1500):
        shape = tuple(int(v) for v in rng.integers(1, 16, 2))
        m = rng.random(shape) < rng.uniform(0.1, 0.9)
        if rng.random() < 0.2:
            m = m[:, ::2]  # not contiguous
        labels, n, objects = slice_labels(m)
        ref, ref_n = ndimage.label(m, structure=cross)
        assert n == ref_n and labels.dtype == ref.dtype
        np.testing.assert_array_equal(labels, ref)
        assert objects == ndimage.find_objects(ref)


def test_deepest_pixel_is_the_argmax_of_scipy_distance_transform():
    from scipy import ndimage

    from contourmesh.geometry import deepest_pixel

    rng = np.random.default_rng(9)
    for _ in range(2000):
        shape = tuple(int(v) for v in rng.integers(1, 30, 2))
        m = rng.random(shape) < rng.uniform(0.3, 1.0)
        if rng.random() < 0.4:  # discs and ellipses: many equal distances (ties go to the first)
            yy, xx = np.mgrid[: shape[0], : shape[1]]
            m = ((yy - shape[0] / 2) / rng.uniform(0.5, 2)) ** 2 + (xx - shape[1] / 2) ** 2 < rng.uniform(1, 200)
        d = ndimage.distance_transform_edt(np.pad(m, 1))
        assert deepest_pixel(m) == tuple(int(v) for v in np.unravel_index(np.argmax(d), d.shape))
    # larger rings, bars and blobs, many rows of equal depth: the rows taken by their bounds (the
    # rows whose bound falls below the best are left out) give the raster scan's first deepest pixel
    for _ in range(300):
        shape = tuple(int(v) for v in rng.integers(20, 90, 2))
        yy, xx = np.mgrid[: shape[0], : shape[1]]
        cy, cx = rng.uniform(0.3, 0.7, 2) * shape
        r = np.hypot((yy - cy) / rng.uniform(0.6, 1.6), xx - cx)
        r_out = rng.uniform(5, min(shape) / 2)
        m = (r < r_out) & (r >= rng.uniform(0, r_out - 1))  # discs and annuli
        if rng.random() < 0.3:
            m |= (np.abs(yy - xx * rng.uniform(-1, 1) - rng.uniform(0, shape[0])) < rng.uniform(1, 6))  # a bar
        if rng.random() < 0.3:
            m ^= rng.random(shape) < 0.02
        d = ndimage.distance_transform_edt(np.pad(m, 1))
        assert deepest_pixel(m) == tuple(int(v) for v in np.unravel_index(np.argmax(d), d.shape))


def _chord_push_reference(p, nz2=None):
    """refine._chord_push as it was: numpy expressions over the whole ring."""
    a = np.roll(p, 1, axis=0)
    c = np.roll(p, -1, axis=0)
    u, v, w = p - a, c - p, c - a
    lu, lv, lw = np.hypot(u[:, 0], u[:, 1]), np.hypot(v[:, 0], v[:, 1]), np.hypot(w[:, 0], w[:, 1])
    cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    den = lu * lv * lw
    kappa = np.where(den > 0, 2.0 * cross / np.where(den > 0, den, 1.0), 0.0)
    push = kappa * 0.5 * (lu**2 + lv**2) / 24.0
    if nz2 is not None:
        push = push * (1.0 + 3.0 * nz2) / (1.0 + nz2)
    t = w / np.where(lw > 0, lw, 1.0)[:, None]
    return p + push[:, None] * np.stack([t[:, 1], -t[:, 0]], axis=1)


def test_chord_push_compiled_equals_the_numpy_expressions_bit_for_bit():
    from contourmesh.refine import _chord_push

    rng = np.random.default_rng(12)
    for _ in range(500):
        n = int(rng.integers(3, 80))
        t = np.sort(rng.uniform(0, 2 * np.pi, n))
        p = np.c_[rng.uniform(5, 60) * np.cos(t), rng.uniform(5, 60) * np.sin(t)] + rng.normal(0, 0.3, (n, 2))
        if rng.random() < 0.2:
            p[1] = p[0]  # a repeated point: zero-length edges
        nz2 = rng.uniform(0, 1, n) if rng.random() < 0.7 else None
        np.testing.assert_array_equal(_chord_push(p, nz2), _chord_push_reference(p, nz2))


def test_two_scale_targets_equal_the_numpy_expressions_bit_for_bit():
    from contourmesh.refine import FINE_TOLERANCE, _two_scale_targets

    rng = np.random.default_rng(13)
    for _ in range(300):
        n = int(rng.integers(1, 60))
        out = rng.normal(0, 20, (n, 2))
        near = out + rng.normal(0, 0.2, (n, 2))
        found, found_fine = rng.random(n) < 0.9, rng.random(n) < 0.9
        r4 = (0.7 * rng.uniform(0.9, 1.1)) ** 4
        gap = np.hypot(*(near - out).T)
        w = np.clip((gap - FINE_TOLERANCE[0]) / (FINE_TOLERANCE[1] - FINE_TOLERANCE[0]), 0.0, 1.0) * (found & found_fine)
        ext = near + (r4 / (1.0 - r4)) * (near - out)
        target = np.empty_like(out)
        n_fine, n_any = _two_scale_targets(out, near, found, found_fine, FINE_TOLERANCE[0],
                                           FINE_TOLERANCE[1] - FINE_TOLERANCE[0], r4 / (1.0 - r4), target)
        assert n_fine == np.count_nonzero(w > 0.5) and n_any == bool(np.any(w > 0))
        np.testing.assert_array_equal(target, out + w[:, None] * (ext - out))



def _grid_record(rng, nz, kind):
    """A band-refinement grid record: square pixels on even slices, oblong pixels, or oblong pixels on
    unevenly spaced slices (slab weights)."""
    from contourmesh.refine import _make_grid

    if kind == "square":
        return _make_grid(1.0, 1.0, nz, dz=float(rng.choice([1.0, 0.5, 1.7])))[0]
    pixel = (0.617, 0.667) if rng.random() < 0.5 else (0.9, 0.35)
    if kind == "oblong":
        return _make_grid(*pixel, nz, dz=float(rng.uniform(0.4, 1.8)))[0]
    pad = min(2, (nz - 2) // 2)
    heights = np.cumsum(rng.uniform(0.3, 1.6, nz - 2 * pad))
    return _make_grid(*pixel, nz, zs=heights, pad=pad)[0]


@pytest.mark.parametrize("kind", ["square", "oblong", "uneven"])
def test_slice_moments_from_column_runs_equal_the_voxel_sums_bit_for_bit(kind):
    from scipy.ndimage import gaussian_filter

    from contourmesh.refine import _slice_moments, _slice_moments_runs, _z_runs

    rng = np.random.default_rng(14)
    for t in range(60):
        shape = tuple(int(v) for v in rng.integers(4, 30, 3))
        pts = gaussian_filter(rng.normal(size=shape), rng.uniform(0.5, 3)) > rng.uniform(-0.3, 0.3)
        if t % 5 == 0:
            pts[:] = t % 2 == 0  # all solid or all empty columns
        runs = _z_runs(pts)
        nz, ny, nx = shape
        grid = _grid_record(rng, nz, kind)
        for _ in range(5):
            k = int(rng.integers(0, nz))
            i0, j0 = int(rng.integers(0, nx)), int(rng.integers(0, ny))
            i1, j1 = int(rng.integers(i0, nx)), int(rng.integers(j0, ny))
            sigma = float(rng.uniform(0.7, 3.5))
            np.testing.assert_array_equal(_slice_moments_runs(pts, runs, k, sigma, grid, i0, i1, j0, j1),
                                          _slice_moments(pts, k, sigma, grid, i0, i1, j0, j1))


def test_unique_keys_is_numpy_unique():
    # the histogram route (small key ranges) and np.unique (large ranges, negative keys) give the
    # same sorted int64 values, empty input included
    from contourmesh.tracing import unique_keys

    rng = np.random.default_rng(16)
    routes = set()
    for t in range(600):
        n = int(rng.integers(0, 2000))
        bound = int(rng.integers(1, 10 ** int(rng.integers(1, 7))))
        keys = rng.integers(0, bound, n)
        if t % 7 == 0 and n:
            keys[0] = -1 - int(rng.integers(0, 5))  # outside the range: np.unique decides
        got, ref = unique_keys(keys, bound), np.unique(keys.astype(np.int64))
        assert got.dtype == np.int64 and np.array_equal(got, ref)
        routes.add(bound <= 8 * n + 4096)
    assert routes == {True, False}
