"""A bridged join's band (``volumes._bridged_band``) and its memory of recent answers
(``volumes._bridged_band_seen``): asked again with the same rings, ids and rule, the band is the
one made afresh (faces and guard count bit for bit, None alike), kept as a read-only copy; a different rule
or a different id pattern (which bridge ends are one vertex) is another key."""

import numpy as np

from bridged_rings import bridged_band, circle
from contourmesh import volumes


def _ring(rs, n, z, r0=1.0):
    t = np.sort(rs.uniform(0, 2 * np.pi, n))
    r = r0 * (1 + 0.15 * rs.standard_normal(n))
    return np.c_[r * np.cos(t), r * np.sin(t), np.full(n, z)]


def _cases(rs, count):
    """Bands as a bridged join has them: below, two rings bridged into one (the bridge's ends
    visited twice, each one vertex), or one ring; above, one ring round them."""
    for _ in range(count):
        n1, n2, nb = (int(x) for x in rs.integers(4, 40, size=3))
        A, B = circle(rs, n1, -1.5, 1.0, 0.0), circle(rs, n2, 1.5, 1.0, 0.0)
        up = circle(rs, nb + 8, 0.0, rs.uniform(2.5, 3.5), 1.0)
        up[:, 0] *= 1.2
        yield bridged_band(rs, A, B, up)


def test_the_remembered_band_is_the_band_made_afresh():
    rs = np.random.default_rng(123)
    volumes._BANDS_SEEN.clear()
    kinds = {"band": 0, "none": 0, "replaced": 0}
    cases = list(_cases(rs, 60))
    for rep in range(2):
        for P, na, ids in cases:
            for rule in ("optimal", "wiederhold"):
                want = volumes._bridged_band(P.copy(), na, ids.copy(), rule)
                got = volumes._bridged_band_seen(P, na, ids, rule)
                if want is None:
                    assert got is None
                    kinds["none"] += rep == 0
                    continue
                assert np.array_equal(got[0], want[0]) and got[1] == want[1]
                # handed out writable (one array type for the kernels), and a caller writing to
                # it does not change what the memory answers next
                assert got[0].flags.writeable
                got[0][:] = -1
                kinds["band"] += rep == 0
                kinds["replaced"] += rep == 0 and want[1] > 0
    assert kinds["band"] > 50, kinds
    assert len(volumes._BANDS_SEEN) == volumes._BANDS_KEEP


def test_rule_and_id_pattern_are_part_of_the_key():
    rs = np.random.default_rng(124)
    volumes._BANDS_SEEN.clear()
    P, na, ids = next(_cases(rs, 1))
    volumes._bridged_band_seen(P, na, ids, "optimal")
    volumes._bridged_band_seen(P, na, ids, "wiederhold")
    other = ids.copy()
    other[0] = other[1]
    volumes._bridged_band_seen(P, na, other, "optimal")
    assert len(volumes._BANDS_SEEN) == 3
    for (key, got), rule, i in zip(volumes._BANDS_SEEN.items(), ("optimal", "wiederhold", "optimal"), (ids, ids, other)):
        want = volumes._bridged_band(P, na, i, rule)
        assert (got is None) == (want is None)
        if want is not None:
            assert np.array_equal(got[0], want[0]) and got[1] == want[1]


def test_repeated_corner_test_is_the_numpy_form():
    """``_repeats_a_corner`` (one compiled pass) against the three numpy comparisons it replaced."""
    rs = np.random.default_rng(125)
    seen = {True: 0, False: 0}
    for t in range(300):
        F = rs.integers(0, int(rs.integers(3, 400)), size=(int(rs.integers(0, 60)), 3)).astype(np.int64)
        want = bool((F[:, 0] == F[:, 1]).any() or (F[:, 1] == F[:, 2]).any() or (F[:, 0] == F[:, 2]).any())
        got = bool(volumes._repeats_a_corner(F))
        assert got == want
        seen[want] += 1
    assert min(seen.values()) > 30, seen


def test_a_changed_setting_is_not_answered_from_memory(monkeypatch):
    rs = np.random.default_rng(126)
    volumes._BANDS_SEEN.clear()
    P, na, ids = next(_cases(rs, 1))
    volumes._bridged_band_seen(P, na, ids, "wiederhold")
    monkeypatch.setattr(volumes, "_BRIDGED_ALTERNATIVES", ())
    volumes._bridged_band_seen(P, na, ids, "wiederhold")
    assert len(volumes._BANDS_SEEN) == 2
