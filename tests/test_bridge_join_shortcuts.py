"""Shortcuts in the bridged joins' driver and builder (issue 16), each against the form it replaced:
a join whose kept band crosses itself skips the merged-band retry (which would give None), the
group look-up table filled one component at a time, the plane segments' ``keep`` that returns
early, and the loop over the bridged joins only."""

import hashlib
from bisect import bisect_left

import numpy as np
import pytest

import contourmesh
from contourmesh import volumes
from contourmesh.bands import _band_crosses


def _group_lut_reference(n, comps):
    lut = np.full(n + 1, -1, dtype=np.int64)
    lut[np.asarray(list(comps), dtype=np.int64) + 1] = np.arange(len(comps))
    return lut


def test_group_lut_is_the_fancy_assignment():
    rs = np.random.default_rng(7)
    for _ in range(500):
        n = int(rs.integers(0, 30))
        comps = rs.permutation(n)[: int(rs.integers(0, n + 1))].tolist()
        if rs.random() < 0.3:
            comps = sorted(comps)
        got, want = volumes._group_lut(n, comps), _group_lut_reference(n, comps)
        assert got.dtype == want.dtype and np.array_equal(got, want)
    for comps in ([5], [-6]):  # out of range: both raise
        for fn in (volumes._group_lut, _group_lut_reference):
            try:
                fn(3, comps)
            except IndexError:
                pass
            else:
                raise AssertionError("no IndexError")


def test_plane_segments_keep_is_the_bisection():
    rs = np.random.default_rng(8)
    for _ in range(300):
        segs = volumes._PlaneSegments()
        ref = []
        place = 0
        for _step in range(int(rs.integers(1, 40))):
            if rs.random() < 0.7:
                place += int(rs.integers(0, 3))
                p, q = rs.uniform(-5, 5, 2), rs.uniform(-5, 5, 2)
                segs.add(p, q, place)
                ref.append((place, p, q))
            else:
                count = int(rs.integers(0, place + 3))
                segs.keep(count)
                ref = ref[: bisect_left([r[0] for r in ref], count)]
            assert segs.n == len(ref) and segs.owner == [r[0] for r in ref]
            assert np.array_equal(segs.a[: segs.n], np.array([r[1] for r in ref]).reshape(-1, 2))
            assert np.array_equal(segs.b[: segs.n], np.array([r[2] for r in ref]).reshape(-1, 2))


def _cases(rs, count):
    """Bands as a bridged join has them (two rings bridged into one below, one ring above), some
    of them twisted so that the band crosses itself."""
    for _ in range(count):
        n1, n2, nb = (int(x) for x in rs.integers(4, 40, size=3))
        t1, t2, tb = (np.sort(rs.uniform(0, 2 * np.pi, m)) for m in (n1, n2, nb + 8))
        A = np.c_[-1.5 + np.cos(t1), np.sin(t1), np.zeros(n1)]
        B = np.c_[1.5 + np.cos(t2), np.sin(t2), np.zeros(n2)]
        r = rs.uniform(0.5, 3.5) * (1 + 0.6 * rs.standard_normal(len(tb)) * (rs.random() < 0.5))
        up = np.c_[1.2 * r * np.cos(tb), r * np.sin(tb), np.ones(len(tb))]
        V = np.concatenate([A, B, up])
        a, b = int(np.argmax(A[:, 0])), int(np.argmin(B[:, 0]))
        tour = np.r_[np.arange(a + 1), n1 + (b + np.arange(n2 + 1)) % n2, a + np.arange(n1 - a) % n1]
        ids = np.r_[tour, n1 + n2 + np.arange(len(up))].astype(np.int64)
        yield V[ids], len(tour), ids


def test_the_band_says_whether_it_crosses():
    rs = np.random.default_rng(9)
    seen = {True: 0, False: 0}
    for P, na, ids in _cases(rs, 80):
        for rule in ("optimal", "wiederhold"):
            got = volumes._bridged_band_crossing(P, na, ids, rule)
            plain = volumes._bridged_band(P, na, ids, rule)
            if got is None:
                assert plain is None
                continue
            assert np.array_equal(got[0], plain[0]) and got[1] == plain[1]
            assert got[2] == _band_crosses(P, got[0])
            seen[got[2]] += 1
    assert seen[False] > 20 and seen[True] > 0, seen


def _digest(m):
    h = hashlib.sha1()
    h.update(np.ascontiguousarray(m.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(m.faces, dtype=np.int64).tobytes())
    return h.hexdigest()


def test_a_crossing_band_makes_the_retry_give_none(shared_data, monkeypatch):
    """On the lobster, with the retry run as it was (every join whose faces cross), each retry of a
    join with a band that crosses itself gives None, and the mesh is the same as with the shortcut."""
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    vol, spacing = np.pad(vol, 1), tuple(spacing)  # (as benchmarks/volume_speed.py has it)
    want = _digest(contourmesh.mesh(vol, spacing=spacing))

    seen_band = volumes._bridged_band_seen
    retry = volumes._merged_band_retry
    asked = {"crossing": 0, "other": 0}

    def never_crossing(P, na, ids, rule):
        got = seen_band(P, na, ids, rule)
        return None if got is None else (got[0], got[1], False)

    def recorded(V, faces, bands):
        out = retry(V, faces, bands)
        crossing = any(_band_crosses(V[np.concatenate([a, b])], f) for a, b, _rule, f in bands)
        if crossing:
            assert out is None
        asked["crossing" if crossing else "other"] += 1
        return out

    monkeypatch.setattr(volumes, "_bridged_band_seen", never_crossing)
    monkeypatch.setattr(volumes, "_merged_band_retry", recorded)
    got = _digest(contourmesh.mesh(vol, spacing=spacing))
    assert got == want
    assert asked["crossing"] > 20 and asked["other"] > 0, asked


def _star(rng, c, r, k):
    t = np.sort(rng.uniform(0, 2 * np.pi, k))
    return c + (r * rng.uniform(0.5, 1.0, k))[:, None] * np.c_[np.cos(t), np.sin(t)]


def test_remembered_keyholes_are_the_searches_made_afresh():
    """``keyhole_path`` (with its memory of recent searches) against ``_keyhole_path`` (the search,
    made every time): the same answers bit for bit, asked once and again, with obstacles far from
    the keyhole added the second time (not read by the search: the same key), and with changes that
    the key must see (a used vertex, an overlap pixel, a near obstacle, max_nodes)."""
    from contourmesh.bands import bridges as B

    rng = np.random.default_rng(131)
    B._KEYHOLES_SEEN.clear()
    seen = {"path": 0, "none": 0}
    for trial in range(60):
        s = float(rng.choice([0.5, 1.0]))
        outer = _star(rng, np.zeros(2), 8 * s, int(rng.integers(8, 30)))
        hole = _star(rng, rng.uniform(-2, 2, 2) * s, 2 * s, int(rng.integers(4, 12)))[::-1]
        g = np.arange(-9, 10) * s
        W = np.array([(x, y) for x in g for y in g if 1.5 * s < np.hypot(x, y) < 7.5 * s])
        stray = rng.uniform(-8, 8, (int(rng.integers(0, 6)), 2)) * s
        oa = np.concatenate([hole, outer, stray])
        ob = np.concatenate([np.roll(hole, -1, axis=0), np.roll(outer, -1, axis=0),
                             stray + rng.normal(0, 2 * s, stray.shape)])
        segs = [(rng.uniform(-8, 8, 2) * s, rng.uniform(-8, 8, 2) * s) for _ in range(int(rng.integers(0, 3)))]
        over = rng.random((20, 20)) < rng.uniform(0.0, 0.15)
        test = B.OverlapFree(over, 0, 0, (-10 * s, -10 * s, s, s))
        used_i = set(rng.choice(len(hole), int(rng.integers(0, 3))).tolist())
        far = np.full((2, 2), 100.0 * s) + np.arange(4).reshape(2, 2)  # (edges far outside every box)
        variants = [
            dict(oa=oa, ob=ob, allowed=test, used_i=used_i, limit=B.KEYHOLE_MAX_NODES),
            dict(oa=np.concatenate([far, oa]), ob=np.concatenate([far + 1, ob]), allowed=test, used_i=used_i,
                 limit=B.KEYHOLE_MAX_NODES),
            dict(oa=oa, ob=ob, allowed=None, used_i=used_i, limit=B.KEYHOLE_MAX_NODES),
            dict(oa=oa, ob=ob, allowed=test, used_i=used_i | {0, 1}, limit=B.KEYHOLE_MAX_NODES),
            dict(oa=oa, ob=ob, allowed=test, used_i=used_i, limit=5),
            dict(oa=np.concatenate([oa, [[0.1 * s, 0.2 * s]]]), ob=np.concatenate([ob, [[0.3 * s, 2.5 * s]]]),
                 allowed=test, used_i=used_i, limit=B.KEYHOLE_MAX_NODES),
        ]
        if over.any():
            over2 = over.copy()
            over2[np.unravel_index(np.flatnonzero(over)[0], over.shape)] = False
            variants.append(dict(oa=oa, ob=ob, allowed=B.OverlapFree(over2, 0, 0, (-10 * s, -10 * s, s, s)),
                                 used_i=used_i, limit=B.KEYHOLE_MAX_NODES))
        for _rep in range(2):
            for v in variants:
                got = B.keyhole_path(hole, outer, W, s, v["oa"], v["ob"], segs, allowed=v["allowed"],
                                     used_i=v["used_i"], max_nodes=v["limit"])
                want = B._keyhole_path(hole, outer, W, s, v["oa"], v["ob"], segs, allowed=v["allowed"],
                                       used_i=v["used_i"], max_nodes=v["limit"])
                assert (got is None) == (want is None)
                if got is not None:
                    assert got[:2] == want[:2] and got[2].dtype == want[2].dtype
                    assert got[2].tobytes() == want[2].tobytes() and got[2].shape == want[2].shape
                    assert got[2].flags.writeable
                    got[2][:] = np.nan  # (the caller's copy: the memory keeps its own)
                seen["none" if got is None else "path"] += 1
    assert seen["path"] >= 200 and seen["none"] >= 10, seen
    assert 0 < len(B._KEYHOLES_SEEN) <= B._KEYHOLES_KEEP


@pytest.mark.parametrize("grid", [(0.0, 0.0, 1.0, 1.0), (-3.7, 12.25, 0.3, 0.7), (1e3, -1e3, 2.5, 0.125)])
def test_crack_perimeters_of_a_slice_are_the_components_one_by_one(grid):
    # every component's crack perimeter in one pass against _crack_perimeter per component (and
    # ring by ring): real-looking slices with holes and specks, large blobs with long rings, on
    # grids whose steps do not add up exactly, an empty slice
    from scipy import ndimage

    to_center, to_corner = volumes.grid_to_xy(*grid)
    rng = np.random.default_rng(1132)
    masks = list(ndimage.gaussian_filter(rng.random((5, 40, 44)), 1.2) > 0.5) + [np.zeros((6, 7), bool)]
    for _ in range(2):
        big = ndimage.gaussian_filter(rng.random((160, 170)), 2.5) > 0.47
        big[ndimage.binary_erosion(ndimage.binary_fill_holes(big), iterations=3) & (rng.random(big.shape) < 0.01)] = False
        masks.append(big)
    seen = {"holes": 0, "plain": 0}
    for mask in masks:
        s = volumes._Slice(mask, "mlp", to_corner, to_center)
        got = volumes._crack_perimeters(s)
        assert len(got) == s.n
        for c in range(s.n):
            want = volumes._crack_perimeter(s, c)
            ring_by_ring = sum(float(np.hypot(*(volumes._next(r) - r).T).sum())
                               for r in [s.crack_outer.made(c)] + list(s.crack_holes.made(c)))
            assert type(got[c]) is float and np.float64(got[c]).tobytes() == np.float64(want).tobytes()
            assert np.float64(want).tobytes() == np.float64(ring_by_ring).tobytes()
            seen["holes" if len(s.crack_holes_c[c]) else "plain"] += 1
    assert min(seen.values()) > 5, seen
