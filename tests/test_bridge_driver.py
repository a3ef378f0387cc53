"""The bridged-join driver's kept state against the plain forms it replaced (issue 16): the segments
each plane's bridges took (growing arrays, cut back to a prefix of the passed joins, instead of
lists rebuilt pass by pass and turned into arrays for every test), a slice's ring edges from
blocks kept per component (instead of made ring by ring) and the boxes near a join's components
in one compiled pass.  Each comparison is bit for bit and sees both
answers."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import volumes
from contourmesh.bands.bridges import segments_cross
from contourmesh.geometry import grid_to_xy


def _crosses_reference(taken, p, q):
    """The test as it was: the plane's segments (a list of ``(p, q)``) made into arrays, then
    :func:`segments_cross`."""
    if not taken:
        return False
    sa = np.array([s[0] for s in taken])
    sb = np.array([s[1] for s in taken])
    return bool(segments_cross(p, q, sa, sb).any())


def _segment(rng, grid):
    """A short segment ``(p, q)`` (on a grid of halves where ``grid``): many keep clear of the others."""
    if grid:
        p = rng.integers(-16, 17, 2) / 2.0
        return p, p + rng.integers(-2, 3, 2) / 2.0
    p = rng.uniform(-8, 8, 2)
    return p, p + rng.uniform(-1, 1, 2)


def test_plane_segments_equal_the_lists_rebuilt_each_pass():
    # passes of joins, each adding a few segments to a few planes; a pass restarts after a random
    # number of the passed joins, which keep their segments (keep) where the reference rebuilds the
    # lists from those joins; every test of a new segment gives the reference's answer
    rng = np.random.default_rng(1161)
    seen = {"cross": 0, "clear": 0, "kept": 0, "grown": 0}
    for trial in range(60):
        grid = trial % 2 == 0
        planes = {}  # plane -> _PlaneSegments
        passed = []  # per passed join: its segments [(plane, p, q)]
        for _pass in range(int(rng.integers(1, 6))):
            kept = int(rng.integers(0, len(passed) + 1))
            passed = passed[:kept]
            for segs in planes.values():
                segs.keep(kept)
            seen["kept"] += kept > 0
            lists = {}
            for join in passed:
                for plane, p, q in join:
                    lists.setdefault(plane, []).append((p, q))
            for plane, segs in planes.items():  # the arrays hold the lists' points, in order
                want = lists.get(plane, [])
                assert segs.n == len(want)
                assert segs.a[:segs.n].tobytes() == np.array([s[0] for s in want], dtype=np.float64).reshape(-1, 2).tobytes()
                assert segs.b[:segs.n].tobytes() == np.array([s[1] for s in want], dtype=np.float64).reshape(-1, 2).tobytes()
            for _join in range(int(rng.integers(1, 12))):
                segs_of_join = [(int(rng.integers(0, 3)), *_segment(rng, grid))
                                for _ in range(int(rng.integers(1, 4)))]
                clear = True
                for plane, p, q in segs_of_join:
                    got = planes.setdefault(plane, volumes._PlaneSegments()).crosses(p, q)
                    assert got == _crosses_reference(lists.get(plane, []), p, q)
                    seen["cross" if got else "clear"] += 1
                    if got:
                        clear = False
                        break
                if not clear and rng.random() < 0.7:
                    continue  # (a join whose bridge meets a taken one is not recorded)
                for plane, p, q in segs_of_join:
                    segs = planes.setdefault(plane, volumes._PlaneSegments())
                    before = len(segs.a)
                    segs.add(p, q, len(passed))
                    seen["grown"] += len(segs.a) > before
                    lists.setdefault(plane, []).append((p, q))
                passed.append(segs_of_join)
    assert min(seen.values()) > 10, seen


def _ring_edges_cases(rng, trial):
    """A slice-like namespace (polygons and crack rings of ``n`` components, some empty or of one
    point, integer-valued where ``trial`` is even) and sorted crack components."""
    n = int(rng.integers(1, 8))

    def ring():
        k = int(rng.integers(0, 9)) if trial % 5 == 0 else int(rng.integers(1, 9))
        r = rng.normal(size=(k, 2)) * 4
        return np.round(r) if trial % 2 == 0 else r

    holes = [[ring() for _ in range(int(rng.integers(0, 3)))] for _ in range(n)]
    s = SimpleNamespace(n=n, outer=[ring() for _ in range(n)], holes=holes,
                        crack_outer=[ring() for _ in range(n)],
                        crack_holes=[[ring() for _ in holes[c]] for c in range(n)])
    crack = sorted(rng.choice(n, int(rng.integers(0, n + 1)), replace=False).tolist())
    return s, crack


def _poly_of(s, crack):
    def poly(c, h):
        if c in crack:
            return s.crack_outer[c] if h < 0 else s.crack_holes[c][h]
        return s.outer[c] if h < 0 else s.holes[c][h]
    return poly


def _assert_blocks_equal(blocks, s, crack):
    a, b = volumes._ring_edges(s, _poly_of(s, crack))
    got_a, got_b = blocks.edges(set(crack))
    assert got_a.dtype == a.dtype and got_a.shape == a.shape and got_a.tobytes() == a.tobytes()
    assert got_b.dtype == b.dtype and got_b.shape == b.shape and got_b.tobytes() == b.tobytes()


def test_ring_blocks_equal_the_rings_one_by_one():
    # a slice's crack-only components grow from none to all (and, once in a while, some go back to
    # their polygons): at each step the blocks give _ring_edges's arrays
    rng = np.random.default_rng(1162)
    seen = {"none": 0, "some": 0, "all": 0, "back": 0}
    for trial in range(200):
        s, _crack = _ring_edges_cases(rng, trial)
        blocks = volumes._RingBlocks(s)
        crack = []
        for _step in range(5):
            _assert_blocks_equal(blocks, s, crack)
            seen["none" if not crack else "all" if len(crack) == s.n else "some"] += 1
            if trial % 7 == 0 and crack:
                crack = crack[1:]
                seen["back"] += 1
            else:
                crack = sorted(set(crack) | set(rng.choice(s.n, int(rng.integers(0, 3)), replace=True).tolist()))
    assert min(seen.values()) > 20, seen
    _assert_blocks_equal(volumes._RingBlocks(SimpleNamespace(n=0, outer=[], holes=[], crack_outer=[], crack_holes=[])),
                         SimpleNamespace(n=0, outer=[], holes=[], crack_outer=[], crack_holes=[]), [])


@pytest.mark.parametrize("polygon", ["mlp", "dss"])
def test_ring_blocks_on_real_slices(polygon):
    # slices of smoothed noise (forks, holes, specks), their crack rings in physical xy as the
    # driver reads them (_CrackXY), more components on their crack rings at each step
    to_center, to_corner = grid_to_xy(-3.7, 12.25, 0.3, 0.7)
    rng = np.random.default_rng(1163)
    v = ndimage.gaussian_filter(rng.random((6, 40, 44)), 1.2)
    seen_holes = 0
    for mask in v > np.quantile(v, 0.55):
        s = volumes._Slice(mask, polygon, to_corner, to_center)
        seen_holes += sum(len(h) for h in s.holes)
        blocks = volumes._RingBlocks(s)
        for crack in ([], list(range(1, s.n, 3)), list(range(0, s.n, 3)) + list(range(1, s.n, 3)), list(range(s.n))):
            _assert_blocks_equal(blocks, s, sorted(crack))
    assert seen_holes > 0


def _boxes_meeting_reference(blo, bhi, comps):
    """The boxes meeting the box of ``comps``' boxes, as the driver found them in numpy."""
    lo, hi = blo[list(comps)].min(axis=0), bhi[list(comps)].max(axis=0)
    return np.flatnonzero((blo <= hi).all(axis=1) & (bhi >= lo).all(axis=1))


def test_boxes_meeting_equal_the_numpy_masks():
    rng = np.random.default_rng(1164)
    sizes = set()
    for trial in range(500):
        n = int(rng.integers(1, 40))
        lo = rng.integers(-20, 20, (n, 2)) / 2.0 if trial % 2 else rng.normal(size=(n, 2)) * 10
        blo = lo.astype(np.float64)
        bhi = blo + (rng.integers(0, 8, (n, 2)) / 2.0 if trial % 2 else rng.uniform(0, 5, (n, 2)))
        if trial % 25 == 0:  # a NaN corner
            [blo, bhi][trial % 2][int(rng.integers(0, n)), int(rng.integers(0, 2))] = np.nan
        comps = tuple(sorted(rng.choice(n, int(rng.integers(1, min(n, 4) + 1)), replace=False).tolist()))
        got = volumes._boxes_meeting(blo, bhi, np.array(comps, dtype=np.int64))
        want = _boxes_meeting_reference(blo, bhi, comps)
        assert got.dtype == np.int64 and np.array_equal(got, want)
        sizes.add(len(want))
    assert len(sizes) > 10


def _crack_perimeter_reference(S, c):
    """A component's crack perimeter as the exact join's area took it: ring by ring."""
    return sum(float(np.hypot(*(volumes._next(r) - r).T).sum())
               for r in [S.crack_outer.made(c)] + list(S.crack_holes.made(c)))


@pytest.mark.parametrize("grid", [(0.0, 0.0, 1.0, 1.0), (-3.7, 12.25, 0.3, 0.7), (1e3, -1e3, 2.5, 0.125)])
def test_crack_perimeter_equals_ring_by_ring(grid):
    # real slices (holes, specks) and large blobs with many holes (rings beyond numpy's pairwise
    # blocks of 128), on grids whose steps do not add up exactly
    to_center, to_corner = grid_to_xy(*grid)
    rng = np.random.default_rng(1165)
    seen = {"holes": 0, "plain": 0, "long": 0}
    masks = list(ndimage.gaussian_filter(rng.random((4, 40, 44)), 1.2) > 0.5)
    for _ in range(3):
        big = ndimage.gaussian_filter(rng.random((160, 170)), 2.5) > 0.47
        big[ndimage.binary_erosion(ndimage.binary_fill_holes(big), iterations=3) & (rng.random(big.shape) < 0.01)] = False
        masks.append(big)
    for mask in masks:
        s = volumes._Slice(mask, "mlp", to_corner, to_center)
        for c in range(s.n):
            got = volumes._crack_perimeter(s, c)
            want = _crack_perimeter_reference(s, c)
            assert type(got) is float and got == want and np.float64(got).tobytes() == np.float64(want).tobytes()
            seen["holes" if len(s.crack_holes_c[c]) else "plain"] += 1
            seen["long"] += max(len(r) for r in [s.crack_outer_c[c]] + list(s.crack_holes_c[c])) > 300
    assert min(seen.values()) > 2, seen


def test_ring_lengths_compiled_are_numpys_sums():
    # the compiled steps and pairwise sums against the numpy form, bit for bit: rings of every size
    # around numpy's blocks (7, 8, 128, 129, thousands), empty ones, magnitudes far apart, on grids
    # whose steps do not add up exactly; and the pairwise sum alone against ndarray.sum
    rng = np.random.default_rng(1179)
    for grid in [(0.0, 0.0, 1.0, 1.0), (-3.7, 12.25, 0.3, 0.7), (1e3, -1e3, 2.5, 0.125)]:
        _, to_corner = grid_to_xy(*grid)
        for _ in range(60):
            sizes = rng.choice([0, 1, 2, 7, 8, 9, 127, 128, 129, 300, 1000, 4099], size=int(rng.integers(1, 6)))
            rings = [rng.integers(-50, 5000, size=(int(m), 2)) for m in sizes]
            got, want = volumes._ring_lengths(to_corner, rings), volumes._ring_lengths_numpy(to_corner, rings)
            assert len(got) == len(rings) and all(type(g) is float for g in got)
            assert np.array(got).tobytes() == np.array(want).tobytes()
    for _ in range(400):
        n = int(rng.integers(0, 3000))
        a = rng.random(n + 9) * 10.0 ** float(rng.integers(-4, 5))
        lo = int(rng.integers(0, 9))
        got, want = volumes._pairwise_sum(a, lo, n), a[lo: lo + n].sum()
        assert np.float64(got).tobytes() == np.float64(want).tobytes()


def test_distinct_rows_is_the_unique_rows_test_of_the_lids():
    # a lid's ring is refused where two of its points coincide: the sorted test gives numpy's
    # answer (points on a grid of halves, repeats, -0.0 beside 0.0, one point, none)
    rng = np.random.default_rng(1166)
    seen = {True: 0, False: 0}
    for trial in range(1500):
        n = int(rng.integers(0, 40))
        xy = rng.integers(-6, 7, (n, 2)) * rng.choice([0.5, -0.5, 1.0]) if trial % 3 else rng.normal(size=(n, 2))
        if trial % 5 == 0 and n > 2:
            xy[int(rng.integers(0, n))] = xy[int(rng.integers(0, n))]
        if trial % 13 == 1 and n > 1:  # (NaN and infinite coordinates: a NaN row equals no row)
            xy = xy.astype(np.float64)
            xy[int(rng.integers(0, n)), int(rng.integers(0, 2))] = rng.choice([np.nan, np.inf, -np.inf])
        if trial % 4 == 2:  # (a lid's rows: the first two columns of rows picked from a 3-column array)
            V = np.c_[xy, rng.normal(size=n)]
            xy = V[np.arange(n)][:, :2]
        got = volumes._distinct_rows(xy)
        assert got == (len(np.unique(xy, axis=0)) == len(xy))
        # the compiled test against the numpy sort it replaced
        assert got == volumes._distinct_rows_numpy(xy)
        seen[got] += 1
    assert min(seen.values()) > 100, seen


def test_made_band_makes_each_rule_once_and_gives_its_faces():
    from contourmesh.bands import triangulate_band

    rng = np.random.default_rng(1167)
    t = np.sort(rng.uniform(0, 2 * np.pi, 30))
    lo = np.c_[np.cos(t), np.sin(t), np.zeros(30)] * 5
    hi = np.c_[np.cos(t[::2] + 0.3), np.sin(t[::2] + 0.3), np.ones(15)] * 4
    made = {}
    for method in ("arclength", "wiederhold", "greedy", "arclength", "optimal"):
        got = volumes._made_band(made, lo, hi, method)
        assert got is made[method]
        assert np.array_equal(got, triangulate_band(lo, hi, method, fallback=False))
    assert sorted(made) == ["arclength", "greedy", "optimal", "wiederhold"]
