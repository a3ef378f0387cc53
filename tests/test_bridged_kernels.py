"""The bridged joins' compiled steps against the code they replaced: the nearest vertex pairs
between two rings (the cut found as the q smallest distances of all pairs, not by sorting every
vertex's k nearest), bridge_tree's candidates and straight bridges in one compiled call, and a
slice's ring edges by one gather.  Random inputs, bit for bit, each comparison seeing both answers."""

import os
from types import SimpleNamespace

import numpy as np
import pytest

from contourmesh import volumes
from contourmesh.bands import bridges as B
from test_compiled_repair import random_rings


def _nearest_reference(ri, rj, k):
    """The nearest-pair search as it was: every vertex of ``rj`` with its ``min(k, len(ri))``
    nearest distances, all of them sorted, the ``min(k, ...)``-th the cut (times ``1 + 1e-12``);
    the pairs within the cut in row order; ok False where a vertex of ``rj`` has more than
    ``min(k, len(ri))`` of them."""
    ni, nj = len(ri), len(rj)
    kk = min(k, ni)
    D = np.empty((nj, ni))
    for j in range(nj):
        for i in range(ni):
            dx = ri[i, 0] - rj[j, 0]
            dy = ri[i, 1] - rj[j, 1]
            D[j, i] = np.sqrt(dx * dx + dy * dy)
    pool = np.sort(np.sort(D, axis=1)[:, :kk].ravel())
    cut = pool[min(k, nj * kk) - 1] * (1 + 1e-12)
    within = D <= cut
    if (within.sum(axis=1) > kk).any():
        return None
    jj, ii = np.nonzero(within)
    return ii.astype(np.int64), jj.astype(np.int64), D[jj, ii]


def test_nearest_kernel_equals_the_sorted_pool():
    rng = np.random.default_rng(112)
    seen = {"ok": 0, "refused": 0, "ties": 0}
    for trial in range(600):
        ni, nj = int(rng.integers(1, 40)), int(rng.integers(1, 40))
        if trial % 3 == 0:  # a half-pixel grid: many equal distances
            ri = rng.integers(-5, 6, (ni, 2)) / 2.0
            rj = rng.integers(-5, 6, (nj, 2)) / 2.0 + (rng.integers(0, 6) / 2.0, 0.0)
        else:
            ri = rng.normal(size=(ni, 2)) * 5.1
            rj = rng.normal(size=(nj, 2)) * 5.1 + rng.normal(size=2) * 6
        k = int(rng.choice([1, 2, 5, 12]))
        vi, vj, d, ok = B._nearest_kernel(np.ascontiguousarray(ri), np.ascontiguousarray(rj), np.int64(k))
        want = _nearest_reference(ri, rj, k)
        if want is None:
            assert not ok
            seen["refused"] += 1
            continue
        assert ok
        assert np.array_equal(vi, want[0]) and np.array_equal(vj, want[1])
        assert d.tobytes() == want[2].tobytes()
        seen["ok"] += 1
        seen["ties"] += len(d) > min(k, ni * nj)
    assert min(seen.values()) > 20, seen


def _same_nearest(a, b):
    """Two answers of the nearest-pair kernels are the same, bit for bit (ok flags included)."""
    return a[3] == b[3] and all(x.dtype == y.dtype and x.tobytes() == y.tobytes() for x, y in zip(a[:3], b[:3]))


def test_nearest_kernel_equals_measuring_every_pair():
    # _nearest_kernel (squares kept, roots only near the cut, one pass out) against _nearest_all (every
    # root, the table of all distances, the form it replaced): random rings, half-pixel grids (many
    # ties, refusals), tiny and huge scales (no pruning), NaN and infinite coordinates
    rng = np.random.default_rng(151)
    seen = {"ok": 0, "refused": 0, "nan": 0, "scaled": 0}
    for trial in range(1500):
        ni, nj = int(rng.integers(1, 60)), int(rng.integers(1, 60))
        if trial % 3 == 0:
            ri = rng.integers(-5, 6, (ni, 2)) / 2.0
            rj = rng.integers(-5, 6, (nj, 2)) / 2.0 + (rng.integers(0, 6) / 2.0, 0.0)
        else:
            ri = rng.normal(size=(ni, 2)) * 5.1
            rj = rng.normal(size=(nj, 2)) * 5.1 + rng.normal(size=2) * 6
        if trial % 7 == 1:
            scale = float(rng.choice([1e-160, 1e-101, 1e-99, 1e99, 1e101, 1e155, 1e160]))
            ri, rj = ri * scale, rj * scale
            seen["scaled"] += 1
        if trial % 11 == 2:
            (ri if trial % 2 else rj)[int(rng.integers(0, min(ni, nj)))] = rng.choice([np.nan, np.inf, -np.inf])
            seen["nan"] += 1
        k = int(rng.choice([1, 2, 5, 12]))
        ri, rj = np.ascontiguousarray(ri), np.ascontiguousarray(rj)
        got = B._nearest_kernel(ri, rj, np.int64(k))
        assert _same_nearest(got, B._nearest_all(ri, rj, np.int64(k)))
        seen["ok" if got[3] else "refused"] += 1
    assert min(seen.values()) > 20, seen


def test_large_ring_pairs_equal_the_kd_tree_query():
    # the compiled search now takes pairs of rings up to _BRUTE_PAIRS (200 000 pairs of vertices):
    # rings of hundreds of points, random and on a grid of halves, give the k-d tree's pairs and
    # distances, bit for bit (the ties the tree decides are the small rings' tests')
    rng = np.random.default_rng(1160)
    compiled = 0
    for trial in range(24):
        ni, nj = int(rng.integers(150, 700)), int(rng.integers(20, 400))
        t = np.sort(rng.uniform(0, 2 * np.pi, ni)), np.sort(rng.uniform(0, 2 * np.pi, nj))
        ri = np.c_[np.cos(t[0]), np.sin(t[0])] * 30.0
        rj = np.c_[np.cos(t[1]), np.sin(t[1])] * 20.0 + (rng.uniform(45, 60), rng.uniform(-5, 5))
        if trial % 2:
            ri, rj = np.round(ri * 2) / 2, np.round(rj * 2) / 2
        got = B._candidates(ri, rj, B.CANDIDATES)
        want = B._candidates_reference(ri, rj, B.CANDIDATES)
        as_set = lambda c: sorted(zip(*(a.tolist() for a in c)))  # noqa: E731
        assert as_set(got) == as_set(want)
        compiled += ni * nj > 40000 and ni * nj <= B._BRUTE_PAIRS and B._nearest_kernel(ri, rj, np.int64(12))[3]
    assert compiled >= 10, compiled


def test_later_kernel_equals_the_covered_share():
    # a candidate's preference sampled until decided (_later_kernel) against the covered share of
    # all its samples (_coverage_kernel, then count / n >= share, the form it replaced): random
    # label images (uint8 and int32), segments short and long, inside and beyond the image,
    # shares at the ends and between
    rng = np.random.default_rng(1151)
    seen = {0: 0, 1: 0, "early": 0}
    for trial in range(3000):
        lab = rng.integers(0, 4, (int(rng.integers(1, 30)), int(rng.integers(1, 30))))
        lab = lab.astype(np.uint8 if trial % 2 else np.int32)
        if trial % 5 == 0:  # large blocks of one label: long runs covered or not
            lab = np.kron(lab[:4, :4], np.ones((8, 8), lab.dtype))
        ids = np.array(sorted(set(rng.integers(1, 4, int(rng.integers(1, 3))).tolist())), np.int64)
        grid = (float(rng.normal()), float(rng.normal()), float(rng.uniform(0.3, 2)), float(rng.uniform(0.3, 2)))
        P = rng.uniform(-5, 40, (1, 2))
        Q = P + rng.normal(size=(1, 2)) * float(rng.choice([0.2, 3.0, 20.0]))
        share = float(rng.choice([0.0, 0.25, 0.5, 0.5, 0.75, 1.0]))
        count, n = B._coverage_kernel(P, Q, lab, ids, *grid)
        want = 0 if count[0] / n[0] >= share else 1
        got = B._later_kernel(P[0, 0], P[0, 1], Q[0, 0], Q[0, 1], lab, ids, *grid, share)
        assert got == want
        seen[want] += 1
        seen["early"] += n[0] >= 16
    assert min(seen.values()) > 300, seen


def test_coverage_kernel_equals_its_samples_one_by_one():
    # the coverage kernel and the preference kernel write the sample out in their loops: the
    # count of covered samples against _sample_covered (the rule of one sample) summed sample by
    # sample, and the preference against that count; random images, grids, segments and labels
    rng = np.random.default_rng(1195)
    seen = {0: 0, 1: 0}
    for trial in range(1500):
        lab = rng.integers(0, 4, (int(rng.integers(1, 25)), int(rng.integers(1, 25))))
        lab = lab.astype(np.uint8 if trial % 2 else np.int32)
        ids = np.array(sorted(set(rng.integers(0, 4, int(rng.integers(1, 4))).tolist())), np.int64)
        grid = (float(rng.normal()), float(rng.normal()), float(rng.uniform(0.3, 2)), float(rng.uniform(0.3, 2)))
        P = rng.uniform(-5, 35, (3, 2))
        Q = P + rng.normal(size=(3, 2)) * float(rng.choice([0.2, 3.0, 20.0]))
        count, n = B._coverage_kernel(P, Q, lab, ids, *grid)
        for s in range(3):
            steps = n[s] + 1
            want = sum(int(B._sample_covered(P[s, 0], P[s, 1], Q[s, 0], Q[s, 1], u / steps, lab, ids, *grid))
                       for u in range(1, steps))
            assert count[s] == want
            seen[int(0 < want < n[s])] += 1
        share = float(rng.choice([0.25, 0.5, 1.0]))
        later = B._later_kernel(P[0, 0], P[0, 1], Q[0, 0], Q[0, 1], lab, ids, *grid, share)
        assert later == (0 if count[0] / n[0] >= share else 1)
    assert min(seen.values()) > 300, seen


def test_tree_kernel_equals_candidates_then_straight_bridges():
    # _candidate_columns with ``straight`` (one compiled call, _tree_kernel) against the two calls
    # it fuses: the same seven columns and the same straight bridges (Python ints); a keyhole test
    # that is not compiled leaves the bridges to the caller
    rng = np.random.default_rng(1120)
    seen = {"compiled": 0, "python": 0, "whole": 0, "part": 0, "callable": 0, "preferred": 0}
    for trial in range(300):
        grid = trial % 2 == 0
        nr = int(rng.integers(2, 8))
        rings, owners = random_rings(rng, nr, grid, big=trial % 50 == 7)
        lab = rng.integers(0, 3, (24, 24)).astype(np.uint8 if trial % 4 < 2 else np.int32)
        cover = B.keyhole_uncovered(lab, [int(rng.integers(0, 2))], (-8.0, -8.0, 0.7, 0.7))
        prefer = B.PreferCovered(cover, float(rng.choice([0.25, 0.5]))) if trial % 3 else None
        allowed = [None, cover, lambda p, q: True][trial % 3] if trial % 5 else cover
        pairs = [(i, j) for i, j in B._near_pairs(rings)
                 if (owners[i][0] != owners[j][0] and not owners[i][1] and not owners[j][1])
                 or (owners[i][0] == owners[j][0] and (owners[i][1] or owners[j][1]))]
        stray = rng.uniform(-8, 8, (int(rng.integers(0, 6)), 2))
        oa = np.concatenate(rings + [stray])
        ob = np.concatenate([np.roll(r, -1, axis=0) for r in rings] + [stray + rng.normal(0, 2, stray.shape)])
        avoid = [(rng.uniform(-8, 8, 2), rng.uniform(-8, 8, 2)) for _ in range(int(rng.integers(0, 3)))]
        got = B._candidate_columns(rings, pairs, owners, prefer, straight=(oa, ob, avoid, allowed))
        cols = B._candidate_columns(rings, pairs, owners, prefer)
        if cols is None:
            assert got is None
            seen["python"] += 1
            continue
        seen["compiled"] += 1
        if allowed is not None and not isinstance(allowed, B._Coverage):
            assert got[1] is None
            for a, b in zip(got[0], cols):
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
            seen["callable"] += 1
            continue
        want = B._straight_bridges(rings, np.stack(cols[3:], axis=1), owners, oa, ob, avoid, allowed)
        assert got[1] == want
        assert all(type(v) is int for t in got[1] for v in t)
        seen["whole" if len(want) == nr - 1 else "part"] += 1
        # (some trees with candidates of both kinds: the preference measured only as far as needed)
        seen["preferred"] += bool(len(cols[0]) and cols[0][0] == 0 and cols[0][-1] == 1)
        if len(want) == nr - 1:  # the columns, which bridge_tree then does not read, are not made
            assert got[0] is None
        else:
            for a, b in zip(got[0], cols):
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
        # and bridge_tree as a whole, which takes the fused call
        tree = B.bridge_tree(rings, oa, ob, avoid=avoid, owners=owners, allowed=allowed, prefer=prefer)
        assert tree == (want if len(want) == nr - 1 else None)
    assert min(seen.values()) >= 3 and seen["compiled"] > 200, seen


def test_ring_edges_equal_each_ring_and_its_successors():
    rng = np.random.default_rng(11201)
    for trial in range(100):
        n = int(rng.integers(1, 6))
        holes = [[rng.normal(size=(int(rng.integers(1, 9)), 2)) for _ in range(int(rng.integers(0, 3)))]
                 for _ in range(n)]
        outer = [rng.normal(size=(int(rng.integers(1, 12)), 2)) for _ in range(n)]
        s = SimpleNamespace(n=n, holes=holes)

        def poly(c, h):
            return outer[c] if h < 0 else holes[c][h]

        rs = [poly(c, h) for c in range(n) for h in range(-1, len(holes[c]))]
        a, b = volumes._ring_edges(s, poly)
        assert a.tobytes() == np.concatenate(rs).tobytes()
        assert b.tobytes() == np.concatenate([volumes._next(r) for r in rs]).tobytes()


def _outcome(fn, *args):
    """``fn(*args)``, or the type of the error it raises."""
    try:
        return fn(*args)
    except ValueError as e:
        return type(e)


def test_band_crosses_pinch_split_equals_the_steps():
    # _band_crosses_uncached (repeated positions found and moved in one compiled call) against the
    # steps it replaced (canonical_vertices, bincount, _split_pinches, then the crossing test):
    # bands of rings that visit positions twice (bridge ends), some twisted so that they cross,
    # points no face uses, flat bands whose points cannot move, -0.0, a NaN, and no pinch at all
    from contourmesh.bands import _band_crosses_reference, _band_crosses_uncached, _pinch_split, triangulate_band

    rng = np.random.default_rng(11202)
    seen = {"crosses": 0, "clear": 0, "status0": 0, "status1": 0, "status2": 0}
    for trial in range(400):
        n = int(rng.integers(6, 50))
        t = (np.arange(n) + rng.uniform(0, 0.5, n)) * (2 * np.pi / n)
        lo = np.c_[np.cos(t), np.sin(t), np.zeros(n)] * rng.uniform(5, 50)
        twist = rng.uniform(0.1, 3.0) if trial % 3 == 0 else 0.2
        hi = np.c_[np.cos(t + twist), np.sin(t + twist), np.ones(n)] * rng.uniform(5, 50)
        if trial % 2:
            lo[:, :2], hi[:, :2] = np.round(lo[:, :2] * 16) / 16, np.round(hi[:, :2] * 16) / 16
        if trial % 4:
            for _ in range(int(rng.integers(1, 4))):
                a, b = rng.choice(n, 2, replace=False)
                if (a - b) % n not in (1, n - 1):
                    lo[b] = lo[a]
        if (lo[:, :2] == np.roll(lo[:, :2], -1, axis=0)).all(axis=1).any() or \
                (hi[:, :2] == np.roll(hi[:, :2], -1, axis=0)).all(axis=1).any():
            continue
        f = triangulate_band(lo, hi, str(rng.choice(["arclength", "greedy", "wiederhold"])), fallback=False)
        P = np.concatenate([lo, hi])
        if trial % 7 == 0:
            P = np.concatenate([P, P[:1]])
        if trial % 11 == 0:
            P[:, 2] = 0.0
        if trial % 5 == 0:
            P[:, 2] = -P[:, 2]
        if trial % 37 == 0:  # not finite: the reference's route, its error
            P[3, 0] = [np.nan, np.inf][trial % 2]
            assert _outcome(_band_crosses_reference, P, f) == _outcome(_band_crosses_uncached, P, f)
            continue
        want = _band_crosses_reference(P, f)
        assert _band_crosses_uncached(P, f) == want
        seen["crosses" if want else "clear"] += 1
        seen[f"status{int(_pinch_split(np.ascontiguousarray(P), np.ascontiguousarray(f))[1])}"] += 1
    assert min(seen.values()) > 5, seen


def _random_group(rng, trial):
    """Two label images' boxes (views, as the plan's) of slices with ``na``, ``nb`` components and
    a group of each: ``(la, lb, na, nb, ga, gb)``."""
    h, w = int(rng.integers(1, 30)), int(rng.integers(1, 30))
    na, nb = int(rng.integers(1, 7)), int(rng.integers(1, 7))
    dt = [np.uint8, np.int32, np.uint16, np.int64][trial % 4]
    la = rng.integers(0, na + 1, (h + 4, w + 4)).astype(dt)[2:2 + h, 1:1 + w]
    lb = rng.integers(0, nb + 1, (h + 4, w + 4)).astype(dt)[1:1 + h, 2:2 + w]
    ga = sorted(rng.choice(na, int(rng.integers(1, na + 1)), replace=False).tolist())
    gb = sorted(rng.choice(nb, int(rng.integers(1, nb + 1)), replace=False).tolist())
    return la, lb, na, nb, ga, gb


def test_overlap_pairs_and_one_side_count_equal_the_label_masks():
    # _bridge_plan's overlap of a group (its components below and above) and its number of
    # overlapping pairs of components, and _exact_area's pixels of one group only, each in one
    # compiled pass, against the masks, keys and xor they replaced
    from contourmesh.tracing import label_mask, unique_keys

    rng = np.random.default_rng(11203)
    counts, empty = set(), set()
    for trial in range(400):
        la, lb, na, nb, ga, gb = _random_group(rng, trial)
        if trial % 10 == 0:  # the same pixels on both sides
            lb, nb, gb = la.copy(), na, ga
        lut_a, lut_b = volumes._group_lut(na, ga), volumes._group_lut(nb, gb)
        ma, mb = label_mask(la, na, ga), label_mask(lb, nb, gb)
        want_n = len(unique_keys(la[ma & mb].astype(np.int64) * np.int64(nb + 1) + lb[ma & mb], (na + 1) * (nb + 1)))
        o, n = volumes._overlap_pairs(la, lb, lut_a, lut_b, np.int64(len(ga)), np.int64(len(gb)))
        assert o.dtype == np.bool_ and np.array_equal(o, ma & mb)
        assert n == want_n
        counts.add(min(int(n), 5))
        only = volumes._count_one_side(la, lb, lut_a, lut_b)
        assert only == int(np.count_nonzero(ma ^ mb))
        empty.add(only == 0)
    assert counts == {0, 1, 2, 3, 4, 5} and empty == {True, False}


def _tour_ids_reference(tables, tour_r, tour_v):
    """The bridged ring's vertex ids as :func:`volumes._bridge_join` made them before: every table
    (a ring's ids, then each bridge's interior points' ids, empty for a straight bridge) made,
    concatenated, and indexed at each table's start plus the tour's vertex."""
    tables = [np.asarray(t, dtype=np.int64) for t in tables]
    start = np.cumsum([0] + [len(t) for t in tables[:-1]]).astype(np.int64)
    return np.concatenate(tables)[start[tour_r] + tour_v]


def _tables(lengths, bridges, first):
    """The tables of ids that :func:`volumes._bridge_join` numbers as runs: ring ``r``'s ``lengths[r]``
    ids from ``first[r]``, then each bridge's interior points' from its own ``first`` (none for a
    straight bridge)."""
    n = len(lengths)
    return [np.arange(first[r], first[r] + lengths[r]) for r in range(n)] + \
        [np.arange(first[n + b], first[n + b] + (len(br[4]) if len(br) > 4 else 0)) for b, br in enumerate(bridges)]


def _tour_ids_old(first, tour_r, tour_v):
    """The ids as :func:`volumes._bridge_join` took them from the tour before :func:`B.bridged_ring_ids`:
    ``first`` as an int64 array indexed by the tour's rings, plus its vertices."""
    return np.array(first, dtype=np.int64)[tour_r] + tour_v


def _random_tree(rng, n, lengths, shared=False):
    """Random bridges over ``n`` rings (a tree, or None where a drawn bridge end is taken); with
    ``shared`` two bridge ends may meet at one vertex (the compiled tour hands those to Python)."""
    bridges, used = [], set()
    for j in range(1, n):  # a random tree, each bridge at unused vertices
        i = int(rng.integers(0, j))
        vi, vj = int(rng.integers(0, lengths[i])), int(rng.integers(0, lengths[j]))
        if not shared and ((i, vi) in used or (j, vj) in used):
            return None
        used.update([(i, vi), (j, vj)])
        bridges.append((i, vi, j, vj) + ((rng.normal(size=(int(rng.integers(1, 4)), 2)),) if rng.random() < 0.3
                                         else ()))
    return bridges


def test_tour_ids_equal_the_concatenated_tables_on_random_tours():
    # bridged_ring_ids (tour and ids in one compiled call) against the tour's pairs indexed into the
    # tables (and first[ring] + vertex, the form it replaced), also where the tour is Python's
    rng = np.random.default_rng(149)
    seen = {"compiled": 0, "python": 0}
    for trial in range(400):
        n = int(rng.integers(2, 7))
        lengths = rng.integers(1, 12, n).tolist()
        bridges = _random_tree(rng, n, lengths, shared=trial % 4 == 3)
        if bridges is None:
            continue
        first = np.cumsum([int(rng.integers(0, 3))] + lengths).tolist()[:n]
        base = first[-1] + lengths[-1] + int(rng.integers(0, 5))
        for br in bridges:
            first.append(base if len(br) > 4 else 0)
            base += len(br[4]) if len(br) > 4 else 0
        root = int(rng.integers(0, n)) if trial % 2 else 0
        tour_r, tour_v = B.bridged_ring_arrays(lengths, bridges, root)
        got = B.bridged_ring_ids(lengths, bridges, first, root)
        want = _tour_ids_reference(_tables(lengths, bridges, first), tour_r, tour_v)
        old = _tour_ids_old(first, tour_r, tour_v)
        assert got.dtype == want.dtype == old.dtype and np.array_equal(got, want) and np.array_equal(got, old)
        br = np.array([tuple(b[:4]) + (len(b[4]) if len(b) > 4 else 0,) for b in bridges], np.int64).reshape(-1, 5)
        seen["compiled" if B._tour_kernel(np.array(lengths, np.int64), br, np.int64(root))[2] else "python"] += 1
    assert seen["compiled"] > 100 and seen["python"] > 10, seen


def test_tour_ids_and_packed_rings_on_the_lobsters_joins(shared_data, monkeypatch):
    """Every bridged ring of the lobster's joins: the ids :func:`B.bridged_ring_ids` gives equal
    the tables _bridge_join made before, concatenated, indexed by the tour; the rings it packs
    from its vertex array equal :func:`B._packed_rings` of the rings, with the same bridges as
    :func:`B.bridge_tree` without them; and every pair of its rings gets the same nearest pairs
    from :func:`B._nearest_kernel` as from :func:`B._nearest_all`."""
    import contourmesh
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    vol, spacing = np.pad(vol, 1), tuple(spacing)
    real_ids, real_tree = volumes.bridged_ring_ids, volumes.bridge_tree
    seen = {"calls": 0, "polyline": 0, "packed": 0, "pairs": 0}

    def ids(lengths, bridges, first, *a):
        got = real_ids(lengths, bridges, first, *a)
        tour_r, tour_v = B.bridged_ring_arrays(lengths, bridges, *a)
        want = _tour_ids_reference(_tables(lengths, bridges, first), tour_r, tour_v)
        assert got.dtype == want.dtype and np.array_equal(got, want)
        assert np.array_equal(got, _tour_ids_old(first, tour_r, tour_v))
        seen["calls"] += 1
        seen["polyline"] += any(len(br) > 4 for br in bridges)
        return got

    def tree(rings, oa, ob, *, packed=None, **kw):
        got = real_tree(rings, oa, ob, packed=packed, **kw)
        for i, j in B._near_pairs(rings):  # (the nearest pairs of every two rings, as measured before)
            ri, rj = np.ascontiguousarray(rings[i]), np.ascontiguousarray(rings[j])
            if len(ri) * len(rj) <= B._BRUTE_PAIRS:
                assert _same_nearest(B._nearest_kernel(ri, rj, np.int64(12)), B._nearest_all(ri, rj, np.int64(12)))
                seen["pairs"] += 1
        if packed is not None:
            for a, b in zip(packed, B._packed_rings(rings)):
                assert a.dtype == b.dtype and a.flags.c_contiguous and a.tobytes() == b.tobytes()
            want = real_tree(rings, oa, ob, **kw)
            assert (got is None) == (want is None) and len(got or []) == len(want or [])
            for a, b in zip(got or [], want or []):
                assert a[:4] == b[:4] and len(a) == len(b) and (len(a) == 4 or a[4].tobytes() == b[4].tobytes())
            seen["packed"] += 1
        return got

    monkeypatch.setattr(volumes, "bridged_ring_ids", ids)
    monkeypatch.setattr(volumes, "bridge_tree", tree)
    contourmesh.mesh(vol, spacing=spacing)
    assert seen["calls"] > 100 and seen["polyline"] > 0 and seen["packed"] > 100 and seen["pairs"] > 1000, seen


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
def test_real_trees_equal_candidates_then_straight_bridges(monkeypatch):
    """Every fused call (_tree_kernel) of a lobster build, which measures a candidate's preference
    only where the straight loop reaches it, against the two calls it replaces (every preference
    measured, all seven columns sorted, then the straight loop): the same bridges, and the same
    columns where the bridges do not join all the rings."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import volume_speed as vs

        vol, sp = vs.make_input("lobster")
    except Exception as exc:  # pragma: no cover - data missing
        pytest.skip(f"lobster not available: {exc}")
    import contourmesh

    calls = []
    orig = B._tree_kernel

    def wrap(*args):
        got = orig(*args)
        calls.append((args, got))
        return got

    monkeypatch.setattr(B, "_tree_kernel", wrap)
    contourmesh.mesh(vol, spacing=sp)
    monkeypatch.setattr(B, "_tree_kernel", orig)
    seen = {"whole": 0, "part": 0, "preferred": 0}
    for args, got in calls:
        cols = B._candidate_kernel(*args[:13])
        assert got[7] == cols[7]
        if not cols[7]:
            continue
        want = B._straight_kernel(np.stack(cols[3:7], axis=1), *args[:3], *args[13:])
        assert np.array_equal(got[8], want)
        whole = len(want) == args[-1] - 1
        assert got[9] == whole
        if not whole:
            for a, b in zip(got[:7], cols[:7]):
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
        seen["whole" if whole else "part"] += 1
        seen["preferred"] += bool(len(cols[0]) and cols[0][0] == 0 and cols[0][-1] == 1)
    assert seen["whole"] > 300 and seen["part"] > 10 and seen["preferred"] > 50, seen


def _edges_near_reference(points, step, obstacles_a, obstacles_b):
    """The obstacle edges near the points as the keyhole search filtered them, in numpy (the form
    :func:`contourmesh.bands.bridges._edges_near` replaced)."""
    lo, hi = points.min(axis=0) - step, points.max(axis=0) + step
    oa = np.asarray(obstacles_a, dtype=np.float64)
    ob = np.asarray(obstacles_b, dtype=np.float64)
    keep = ((np.maximum(oa[:, 0], ob[:, 0]) >= lo[0]) & (np.minimum(oa[:, 0], ob[:, 0]) <= hi[0])
            & (np.maximum(oa[:, 1], ob[:, 1]) >= lo[1]) & (np.minimum(oa[:, 1], ob[:, 1]) <= hi[1]))
    return oa[keep], ob[keep]


def test_edges_near_equal_the_numpy_masks():
    # the keyhole search's obstacles near its points (compiled) against the numpy masks: random
    # points and edges, on a grid of halves (edges touching the box exactly), signed zeros, NaN and
    # infinite coordinates in the points and in the edges, no edges at all
    rng = np.random.default_rng(11603)
    seen = {"some": 0, "none": 0, "all": 0, "nan": 0}
    for trial in range(1500):
        pts = rng.normal(size=(int(rng.integers(1, 30)), 2)) * 3
        e = int(rng.integers(0, 60)) if trial % 50 else 0
        oa = rng.normal(size=(e, 2)) * 8
        ob = oa + rng.normal(size=(e, 2)) * float(rng.choice([0.5, 3.0]))
        if trial % 3 == 0:
            pts, oa, ob = np.round(pts * 2) / 2, np.round(oa * 2) / 2, np.round(ob * 2) / 2
            oa[oa == 0] = -0.0
        step = float(rng.choice([0.0, 0.5, 1.0, 1.5]))
        if trial % 7 == 1 and e:
            (oa if trial % 2 else ob)[int(rng.integers(0, e)), int(rng.integers(0, 2))] = rng.choice([np.nan, np.inf, -np.inf])
        if trial % 11 == 2:
            pts[int(rng.integers(0, len(pts))), int(rng.integers(0, 2))] = rng.choice([np.nan, np.inf, -np.inf])
            seen["nan"] += 1
        got = B._edges_near(pts, step, oa, ob)
        want = _edges_near_reference(pts, step, oa, ob)
        for g, w in zip(got, want):
            assert g.dtype == w.dtype and g.shape == w.shape and g.tobytes() == w.tobytes()
        seen["none" if len(want[0]) == 0 else "all" if len(want[0]) == e else "some"] += 1
    assert min(seen.values()) >= 10, seen
