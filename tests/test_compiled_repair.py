"""Issue 16 (speed of the general mesher): the compiled kernels and the narrowed numpy passes give
exactly what the code they replace gave.  Each is compared with its numpy reference (kept in the
package, in tests/repair_reference.py, or written out here where the old code was replaced) on
random inputs, bit for bit, and each comparison sees both answers (crossing and not, clear and not,
split and not)."""

import numpy as np
import pytest
import trimesh
from numba import njit

import repair_reference
from contourmesh import repair
from contourmesh.bands import bridges


def _points(rng, k, grid):
    # on a grid of halves (many exact zeros: touching, collinear) or anywhere
    return rng.integers(-4, 5, (k, 2)) / 2.0 if grid else rng.normal(size=(k, 2))


def test_segments_cross_kernel_equals_the_numpy_reference():
    rng = np.random.default_rng(3)
    seen = set()
    for trial in range(400):
        grid = trial % 2 == 0
        p, q = _points(rng, 1, grid)[0], _points(rng, 1, grid)[0]
        a, b = _points(rng, 25, grid), _points(rng, 25, grid)
        if trial % 5 == 0:  # ends shared with the segment
            a[:3] = p
            b[3:6] = q
        got = bridges.segments_cross(p, q, a, b)
        want = bridges._segments_cross_reference(p, q, a, b)
        assert got.dtype == bool and np.array_equal(got, want)
        seen.update(want.tolist())
    assert seen == {True, False}


def test_clear_ends_kernel_equals_the_numpy_reference():
    rng = np.random.default_rng(5)
    outcomes = set()
    for trial in range(600):
        grid = trial % 2 == 0
        r1, r2 = _points(rng, 6, grid), _points(rng, 7, grid)
        vi, vj = int(rng.integers(6)), int(rng.integers(7))
        p = r1[vi] if trial % 3 else _points(rng, 1, grid)[0]
        q = r2[vj]
        oa = np.concatenate([r1, r2, _points(rng, 8, grid)])
        ob = np.concatenate([np.roll(r1, -1, 0), np.roll(r2, -1, 0), _points(rng, 8, grid)])
        segs = list(zip(_points(rng, 3, grid), _points(rng, 3, grid))) if trial % 4 else []
        end_p = (r1, vi) if trial % 3 else None
        end_q = (r2, vj) if trial % 7 else None
        for left in (False, True):
            want = bridges._clear_ends_reference(p, q, end_p, end_q, oa, ob, segs, left)
            assert bridges._clear_ends(p, q, end_p, end_q, oa, ob, segs, left) == want
            assert bridges._clear_ends(p, q, end_p, end_q, oa, ob, bridges._segment_arrays(segs), left) == want
            outcomes.add(want)
    assert outcomes == {True, False}


def test_coverage_kernel_equals_the_numpy_reference():
    # the keyhole test and the covered share of a segment over some components of a label image:
    # ends on a grid of halves (samples exactly half way between pixel centres) or anywhere, some
    # beyond the image, anisotropic pixels and an offset grid
    rng = np.random.default_rng(11)
    shares = set()
    for trial in range(300):
        lab = rng.integers(0, 5, (9, 11)).astype((np.uint8, np.uint16, np.int32)[trial % 3])
        comps = sorted(rng.choice(4, int(rng.integers(1, 4)), replace=False).tolist())
        grid = (0.0, 0.0, 1.0, 1.0) if trial % 2 else (-0.25, 0.5, 0.75, 1.25)
        cov = bridges.keyhole_uncovered(lab, comps, grid)
        m = 6
        P = rng.integers(-4, 26, (m, 2)) / 2.0 if trial % 4 < 2 else rng.uniform(-2, 13, (m, 2))
        Q = rng.integers(-4, 26, (m, 2)) / 2.0 if trial % 4 < 2 else rng.uniform(-2, 13, (m, 2))
        got = cov.shares(P, Q)
        for s in range(m):
            hits = cov._hits_reference(P[s], Q[s])
            assert got[s] == float(hits.mean())
            assert cov.share(P[s], Q[s]) == float(hits.mean())
            assert cov(P[s], Q[s]) == (not hits.any())
            shares.add(0.0 if not hits.any() else 1.0 if hits.all() else 0.5)
    assert shares == {0.0, 0.5, 1.0}


def test_candidate_pairs_equal_the_kd_tree_query():
    # the nearest vertex pairs between two rings, measured all at once, are the k-d tree's (as a
    # set: the bridge search sorts them), distances bit for bit; on a grid of halves many distances
    # are equal, and where the tree's choice among them would decide, the tree is asked
    rng = np.random.default_rng(17)
    fell_back = agreed = 0
    for trial in range(400):
        grid = trial % 2 == 0
        ni, nj = int(rng.integers(1, 30)), int(rng.integers(1, 30))
        if grid:
            ri = rng.integers(-6, 7, (ni, 2)) / 2.0
            rj = rng.integers(-6, 7, (nj, 2)) / 2.0 + (rng.integers(0, 8) / 2.0, 0.0)
        else:
            ri = rng.normal(size=(ni, 2)) * 7.3
            rj = rng.normal(size=(nj, 2)) * 7.3 + rng.normal(size=2) * 9
        k = int(rng.choice([1, 3, 12]))
        got = bridges._candidates(ri, rj, k)
        want = bridges._candidates_reference(ri, rj, k)
        as_set = lambda c: sorted(zip(c[0].tolist(), c[1].tolist(), c[2].tolist(), c[3].tolist()))  # noqa: E731
        assert as_set(got) == as_set(want)
        ok = bridges._nearest_kernel(ri, rj, np.int64(k))[3]
        fell_back += not ok
        agreed += ok
    assert fell_back > 0 and agreed > 100, (fell_back, agreed)



def test_tie_kernel_equals_numpy_on_long_rings():
    # the tie-break of the candidate pairs (distance of a pair's midpoint from the centroid of both
    # rings) on rings up to the size the compiled search takes, far from the origin and near it:
    # the same bits as numpy's mean along the rows and hypot
    rng = np.random.default_rng(19)
    for trial in range(60):
        ni = int(rng.integers(1, 20000 if trial % 10 == 0 else 400))
        nj = int(rng.integers(1, 400))
        scale, shift = 10.0 ** rng.uniform(-3, 3), rng.normal(size=2) * 10.0 ** rng.uniform(0, 4)
        ri = rng.normal(size=(ni, 2)) * scale + shift
        rj = rng.normal(size=(nj, 2)) * scale + shift
        vi, vj = rng.integers(0, ni, 50), rng.integers(0, nj, 50)
        centre = np.concatenate([ri, rj]).mean(axis=0)
        want = np.hypot(*(0.5 * (ri[vi] + rj[vj]) - centre).T)
        got = bridges._tie_kernel(ri, rj, vi, vj)
        assert np.array_equal(got.view(np.uint64), want.view(np.uint64))


def _split_pinches_add_at(P, f, dup):
    """bands._split_pinches as it was, with np.add.at (the reference)."""
    from contourmesh.intersect import canonical_vertices

    P = np.array(P, dtype=np.float64)
    ext = float(np.ptp(P[:, :2], axis=0).max()) if len(P) else 0.0
    if not ext > 0:
        return None
    cen = P[f].mean(axis=1)
    acc = np.zeros_like(P)
    for k in range(3):
        np.add.at(acc, f[:, k], cen)
    deg = np.bincount(f.reshape(-1), minlength=len(P))
    for i in dup:
        if deg[i] == 0:
            return None
        d = acc[i] / deg[i] - P[i]
        d[2] = 0.0
        n = float(np.hypot(d[0], d[1]))
        if not n > 0:
            return None
        P[i] = P[i] + d * (1e-4 * ext / n)
    canon = canonical_vertices(P)
    if (canon != np.arange(len(P))).any():
        return None
    return P


def test_split_pinches_equals_the_add_at_form():
    # the centroid sums by bincount in the corners' order are np.add.at's, bit for bit: the moved
    # points of pinched bands (a ring visiting one position twice) are the same
    from contourmesh.bands import _split_pinches, triangulate_band

    rng = np.random.default_rng(23)
    moved = 0
    for trial in range(200):
        n = int(rng.integers(5, 40))
        t = (np.arange(n) + rng.uniform(0, 0.5, n)) * (2 * np.pi / n)
        lo = np.c_[np.cos(t), np.sin(t), np.zeros(n)] * rng.uniform(5, 50)
        hi = np.c_[np.cos(t + 0.2), np.sin(t + 0.2), np.ones(n)] * rng.uniform(5, 50)
        if trial % 2:  # a dyadic grid
            lo[:, :2], hi[:, :2] = np.round(lo[:, :2] * 64) / 64, np.round(hi[:, :2] * 64) / 64
        lo[n // 2] = lo[0]  # the lower ring visits one position twice
        f = triangulate_band(lo, hi, "arclength")
        P = np.concatenate([lo, hi])
        dup = np.array([0, n // 2])
        got, want = _split_pinches(P, f, dup), _split_pinches_add_at(P, f, dup)
        assert (got is None) == (want is None)
        if want is not None:
            assert np.array_equal(got, want)
            moved += 1
    assert moved > 100



def test_split_pinches_moves_many_points_as_the_loop_did():
    # several pinched positions at once (bridge ends: a ring visits each of them twice), points
    # used by no face, and points that cannot move (their faces' centroid on them): the moves of
    # all the points at once equal the loop's, and so does giving up
    from contourmesh.bands import _split_pinches, triangulate_band

    rng = np.random.default_rng(31)
    seen = {"moved": 0, "none": 0}
    for trial in range(300):
        n = int(rng.integers(8, 60))
        t = (np.arange(n) + rng.uniform(0, 0.5, n)) * (2 * np.pi / n)
        lo = np.c_[np.cos(t), np.sin(t), np.zeros(n)] * rng.uniform(5, 50)
        hi = np.c_[np.cos(t + 0.3), np.sin(t + 0.3), np.ones(n)] * rng.uniform(5, 50)
        if trial % 2:
            lo[:, :2], hi[:, :2] = np.round(lo[:, :2] * 16) / 16, np.round(hi[:, :2] * 16) / 16
        k = int(rng.integers(1, 4))
        for _ in range(k):  # the lower ring visits a few positions twice (never at neighbours)
            a, b = rng.choice(n, 2, replace=False)
            if (a - b) % n not in (1, n - 1) and not (lo[[(b - 1) % n, (b + 1) % n], :2] == lo[a, :2]).all(axis=1).any():
                lo[b] = lo[a]
        if (lo[:, :2] == np.roll(lo[:, :2], -1, axis=0)).all(axis=1).any():
            continue
        f = triangulate_band(lo, hi, "arclength")
        P = np.concatenate([lo, hi])
        if trial % 7 == 0:  # a point no face uses
            P = np.concatenate([P, P[:1]])
        if trial % 11 == 0:  # a flat band: a point on its faces' centroid cannot move
            P[:, 2] = 0.0
        if trial % 5 == 0:  # the lower ring at z = -0.0 (a move keeps no sign of zero)
            P[:, 2] = -P[:, 2]
        canon = np.unique(P, axis=0, return_inverse=True)[1].reshape(-1)
        dup = np.flatnonzero(np.bincount(canon)[canon] > 1)
        got, want = _split_pinches(P, f, dup), _split_pinches_add_at(P, f, dup)
        assert (got is None) == (want is None)
        if want is None:
            seen["none"] += 1
        else:
            assert np.array_equal(got.view(np.uint64), want.view(np.uint64))  # bit for bit (signs of zero too)
            seen["moved"] += 1
    assert seen["moved"] > 100 and seen["none"] > 10, seen


def test_round9_is_pythons_round():
    # Python's round(v, 9) (the decimal rounding of the exact binary value, halves to even) on
    # lengths, exact halves (v * 1e9 = k + 1/2 exactly: v = odd / 1024), values a rounding error
    # away from a half, huge and tiny values, negative zero, infinities and NaN
    rng = np.random.default_rng(41)
    vals = [rng.uniform(0, 10, 3000), 10.0 ** rng.uniform(-12, 8, 3000), rng.integers(0, 2 ** 20, 2000) / 1024.0,
            (rng.integers(0, 10 ** 9, 2000) + 0.5) / 1e9, rng.integers(0, 10 ** 6, 1000) / 1e3,
            np.array([0.0, -0.0, 5e-10, -5e-10, 1.5e-9, 2.5e-9, 1e15, 2.0 ** 60, -3.7, np.inf, -np.inf, np.nan])]
    x = np.concatenate(vals)
    x = np.concatenate([x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf)])
    got = bridges._round9(x)
    want = np.array([round(float(v), 9) for v in x])
    assert np.array_equal(np.isnan(got), np.isnan(want))
    ok = ~np.isnan(want)
    assert np.array_equal(got[ok].view(np.uint64), want[ok].view(np.uint64))  # the same bits (signs of zero too)
    # the shortcut decides most values and Python the rest (both paths are exercised)
    with np.errstate(over="ignore", invalid="ignore"):
        y = x[ok & np.isfinite(x)] * 1e9
        near_half = np.abs(y - np.floor(y) - 0.5) <= np.abs(y) * 2.0 ** -50
    assert near_half.sum() > 100 and (~near_half).sum() > 5000


def test_sorted_candidates_equal_the_sorted_tuples():
    # candidate bridges from several pairs of rings, with many equal lengths and tie-breaks (a grid)
    # and lengths that differ below the rounding: the same list as sorting the tuples
    rng = np.random.default_rng(43)
    differ = 0
    for trial in range(200):
        parts = []
        for _ in range(int(rng.integers(0, 6))):
            m = int(rng.integers(1, 30))
            i, j = sorted(rng.choice(8, 2, replace=False).tolist())
            d = rng.integers(1, 6, m) / 2.0 if trial % 2 else rng.uniform(0, 5, m)
            d = d + rng.choice([0.0, 1e-12, 3e-10], m)  # below, and about, the rounding
            tie = rng.integers(0, 4, m) / 4.0 + rng.choice([0.0, 2e-10], m)
            later = rng.random(m) < 0.3
            parts.append((later, d, tie, np.full(m, i), rng.integers(0, 50, m), np.full(m, j), rng.integers(0, 50, m)))
        got = bridges._sorted_candidates(parts)
        want = bridges._sorted_candidates_reference(parts)
        assert got == want
        assert all(type(v) is type(w) for g, h in zip(got, want) for v, w in zip(g, h))
        # the rounding decides: the unrounded lengths order some of the lists otherwise
        raw = sorted((int(lt), dd, t, int(a_), int(a), int(b_), int(b)) for p in parts for lt, dd, t, a_, a, b_, b in zip(*p))
        differ += [c[3:] for c in raw] != [c[3:] for c in want]
    assert differ > 20, differ
    assert bridges._sorted_candidates([]) == []



def _star(rng, c, r, k, grid):
    t = np.sort(rng.uniform(0, 2 * np.pi, k))
    pts = c + (r * rng.uniform(0.5, 1.0, k))[:, None] * np.c_[np.cos(t), np.sin(t)]
    return np.round(pts * 2) / 2 if grid else pts


def random_rings(rng, nr, grid, big=False):
    """``nr`` star-shaped rings and their owners ``(component, is_hole)``: outer rings, and holes
    (reversed) of an earlier ring's component; with ``big`` the first two have 500 points (beyond
    the compiled candidate search)."""
    rings, owners = [], []
    for r in range(nr):
        hole = r > 0 and rng.random() < 0.4
        comp = owners[int(rng.integers(0, r))][0] if hole else r
        k = 500 if big and r < 2 else int(rng.integers(3, 14))
        ring = _star(rng, rng.uniform(-6, 6, 2), rng.uniform(0.5, 3), k, grid)
        if len(np.unique(ring, axis=0)) < 3:
            ring = _star(rng, rng.uniform(-6, 6, 2), 2.0, 6, False)
        rings.append(ring[::-1] if hole else ring)
        owners.append((comp, hole))
    return rings, owners


def test_straight_bridges_kernel_equals_the_python_loop():
    # rings of a few components (outer rings, and holes bridged through the material), candidates
    # sorted as bridge_tree sorts them, the rings' edges and stray edges as obstacles, segments to
    # avoid, and a keyhole test over a label image: the compiled loop takes the same bridges
    from contourmesh.bands import bridges as B

    rng = np.random.default_rng(47)
    seen = {"whole": 0, "part": 0, "refused": 0}
    for trial in range(300):
        grid = trial % 2 == 0
        nr = int(rng.integers(2, 7))
        rings, owners = [], []
        for r in range(nr):
            hole = r > 0 and rng.random() < 0.4
            comp = owners[int(rng.integers(0, r))][0] if hole else r
            ring = _star(rng, rng.uniform(-6, 6, 2), rng.uniform(0.5, 3), int(rng.integers(3, 12)), grid)
            if len(np.unique(ring, axis=0)) < 3:
                ring = _star(rng, rng.uniform(-6, 6, 2), 2.0, 6, False)
            rings.append(ring[::-1] if hole else ring)
            owners.append((comp, hole))
        parts = []
        for i, j in B._near_pairs(rings):
            (ci, hi), (cj, hj) = owners[i], owners[j]
            if not ((ci != cj and not hi and not hj) or (ci == cj and (hi or hj))):
                continue
            vi, vj, d, tie = B._candidates(rings[i], rings[j], B.CANDIDATES)
            parts.append((rng.random(len(vi)) < 0.3, d, tie, np.full(len(vi), i), vi, np.full(len(vi), j), vj))
        cols = B._candidate_arrays(parts)
        stray = rng.uniform(-8, 8, (int(rng.integers(0, 6)), 2))  # edges of other contours
        oa = np.concatenate(rings + [stray])
        ob = np.concatenate([np.roll(r, -1, axis=0) for r in rings] + [stray + rng.normal(0, 2, stray.shape)])
        avoid = [(rng.uniform(-8, 8, 2), rng.uniform(-8, 8, 2)) for _ in range(int(rng.integers(0, 3)))]
        allowed = None
        if trial % 3:
            lab = rng.integers(0, 3, (24, 24)).astype(np.uint8 if trial % 3 == 1 else np.int32)
            allowed = B.keyhole_uncovered(lab, [int(rng.integers(0, 2))], (-8.0, -8.0, 0.7, 0.7))
        got = B._straight_bridges(rings, np.stack(cols[3:], axis=1), owners, oa, ob, avoid, allowed)
        want = B._straight_bridges_reference(rings, B._candidate_list(cols), owners, oa, ob, avoid, allowed)
        assert got == want
        assert all(type(v) is int for t in got for v in t)
        seen["whole" if len(want) == nr - 1 else "part"] += 1
        seen["refused"] += allowed is not None and len(want) < nr - 1
    assert min(seen.values()) > 20, seen


def test_candidate_kernel_equals_the_python_loop():
    # bridge_tree's candidates, compiled in one call (_candidate_columns), against the loop over the
    # pairs of rings it replaced (each pair's nearest vertices, the preference over a label image,
    # the rounded keys and their lexicographic order): the same seven columns, bit for bit.  Rings
    # on a half-pixel grid give equal lengths and tie-breaks; the large pair goes back to Python
    from contourmesh.bands import bridges as B

    rng = np.random.default_rng(97)
    seen = {"compiled": 0, "python": 0, "preferred": 0}
    for trial in range(300):
        grid = trial % 2 == 0
        nr = int(rng.integers(2, 9))
        rings, owners = random_rings(rng, nr, grid, big=trial % 50 == 7)
        prefer = None
        if trial % 3:
            lab = rng.integers(0, 3, (24, 24)).astype(np.uint8 if trial % 3 == 1 else np.int32)
            prefer = B.PreferCovered(B.keyhole_uncovered(lab, [int(rng.integers(0, 2))], (-8.0, -8.0, 0.7, 0.7)),
                                     float(rng.choice([0.25, 0.5, 0.75])))
        pairs = [(i, j) for i, j in B._near_pairs(rings)
                 if (owners[i][0] != owners[j][0] and not owners[i][1] and not owners[j][1])
                 or (owners[i][0] == owners[j][0] and (owners[i][1] or owners[j][1]))]
        parts = []
        for i, j in pairs:
            vi, vj, d, tie = B._candidates(rings[i], rings[j], B.CANDIDATES)
            later = ~np.asarray(prefer(rings[i][vi], rings[j][vj]), dtype=bool) \
                if prefer is not None and owners[i][0] != owners[j][0] else np.zeros(len(vi), dtype=bool)
            parts.append((later, d, tie, np.full(len(vi), i), vi, np.full(len(vi), j), vj))
        want = B._candidate_arrays(parts)
        got = B._candidate_columns(rings, pairs, owners, prefer)
        if got is None:
            seen["python"] += 1
            continue
        seen["compiled"] += 1
        seen["preferred"] += int((got[0] == 0).sum() > 0 and prefer is not None)
        assert len(got) == 7
        for a, b in zip(got, want):
            assert a.dtype == b.dtype
            assert a.tobytes() == b.tobytes()
    assert seen["compiled"] > 200 and seen["python"] >= 3 and seen["preferred"] > 20, seen


def _random_faces(rng, m, nv):
    F = np.stack([rng.choice(nv, 3, replace=False) for _ in range(m)])
    return np.ascontiguousarray(F, dtype=np.int64)


def test_edge_multiplicity_counts_each_undirected_edge():
    rng = np.random.default_rng(7)
    F = _random_faces(rng, 400, 40)  # few vertices: edges shared by 1 .. many faces
    got = repair_reference.edge_multiplicity(F, 40)
    e = np.stack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1)
    und = np.minimum(e[..., 0], e[..., 1]) * 41 + np.maximum(e[..., 0], e[..., 1])
    _, inv, cnt = np.unique(und.reshape(-1), return_inverse=True, return_counts=True)
    assert np.array_equal(got, cnt[inv].reshape(-1, 3))
    assert got.min() == 1 and got.max() > 4


def test_half_edge_twins_equal_the_sorted_search_and_errors_are_named():
    s = trimesh.creation.icosphere(subdivisions=2)
    F = np.ascontiguousarray(s.faces, dtype=np.int64)
    rng = np.random.default_rng(11)
    F = F[rng.permutation(len(F))]
    twin, status = repair._half_edge_twins(F, len(s.vertices))
    assert status == 0
    assert np.array_equal(twin, repair._half_edge_twins_reference(F, len(s.vertices) + 1))
    # an open surface: a half-edge without its opposite
    _, status = repair._half_edge_twins(F[1:], len(s.vertices))
    assert status == 2
    with pytest.raises(RuntimeError, match="no opposite"):
        repair.split_nonmanifold_vertices(s.vertices, F[1:], four_face=False)
    # a face repeated: its edges are used twice in one direction
    G = np.concatenate([F, F[:1]])
    _, status = repair._half_edge_twins(G, len(s.vertices))
    assert status == 1
    with pytest.raises(RuntimeError, match="twice in one direction"):
        repair.split_nonmanifold_vertices(s.vertices, G, four_face=False)


def _bipyramid(n, apex_lo=True):
    """A closed double cone over an ``n``-gon, outward: apexes 0 and ``n + 1`` (``apex_lo``: both
    numbered below the ring's vertices, so that their buckets hold ``2 n`` half-edges each)."""
    ring = np.arange(1, n + 1) if apex_lo else np.arange(n)
    top, bot = (0, n + 1) if apex_lo else (n, n + 1)
    nxt = np.roll(ring, -1)
    F = np.concatenate([np.stack([np.full(n, top), ring, nxt], 1), np.stack([np.full(n, bot), nxt, ring], 1)])
    return np.ascontiguousarray(F, dtype=np.int64), n + 2


@pytest.mark.parametrize("n", [3, 11, 12, 13, 40])
def test_edge_kernels_small_and_large_buckets_equal_the_sorted_forms(n):
    """The edge counts and half-edge twins match every bucket through tables per vertex, small
    buckets and large alike: they give the counts of np.unique and the twins and statuses of the
    sorted search (bipyramids whose apexes have 2 n half-edges in their buckets, on both sides
    of the bound of 24 the comparing form used for small buckets; faces and vertices shuffled)."""
    rng = np.random.default_rng(n)
    for apex_lo in (True, False):
        F, nv = _bipyramid(n, apex_lo)
        perm = rng.permutation(nv)
        F = np.ascontiguousarray(perm[F][rng.permutation(len(F))])
        F = np.ascontiguousarray(np.roll(F, rng.integers(3), axis=1))
        twin, status = repair._half_edge_twins(F, nv)
        assert status == 0
        assert np.array_equal(twin, repair._half_edge_twins_reference(F, nv + 1))
        assert np.array_equal(repair_reference.edge_multiplicity(F, nv), np.full(F.shape, 2))
        assert repair._half_edge_twins(F[1:], nv)[1] == 2  # an open surface
        assert repair._half_edge_twins(np.concatenate([F, F[-1:]]), nv)[1] == 1  # a face twice
        # a second copy glued along the same vertices: four-face edges, every edge used twice each way
        G = np.concatenate([F, F])
        assert np.array_equal(repair_reference.edge_multiplicity(G, nv), np.full(G.shape, 4))
        for threads in (2, 3):
            assert np.array_equal(repair._half_edge_twins_threads(F, nv, threads)[0], twin)
            assert repair._half_edge_twins_threads(F[1:], nv, threads)[1] != 0
    # random faces on few vertices: buckets of every size, edges in one face up to many
    for nv in (6, 20, 60, 400):
        F = _random_faces(rng, 300, nv)
        e = np.stack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1)
        und = np.minimum(e[..., 0], e[..., 1]) * (nv + 1) + np.maximum(e[..., 0], e[..., 1])
        _, inv, cnt = np.unique(und.reshape(-1), return_inverse=True, return_counts=True)
        assert np.array_equal(repair_reference.edge_multiplicity(F, nv), cnt[inv].reshape(-1, 3))
        assert np.array_equal(repair_reference.edge_multiplicity_threads(F, nv, 2), cnt[inv].reshape(-1, 3))


@njit
def _corner_components(n, a1, b1, a2, b2):
    """Connected components of ``n`` nodes under the links ``a1[i] - b1[i]`` and ``a2[i] - b2[i]``:
    ``(count, label per node, lowest node of each label)``, labels numbered in order of each
    component's lowest node."""
    parent = np.arange(n)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for i in range(len(a1)):
        for x, y in ((a1[i], b1[i]), (a2[i], b2[i])):
            rx, ry = find(x), find(y)
            if rx != ry:
                if rx < ry:
                    parent[ry] = rx
                else:
                    parent[rx] = ry
    lab = np.empty(n, np.int64)
    first = np.empty(n, np.int64)
    count = 0
    for x in range(n):
        r = find(x)
        if r == x:
            lab[x] = count
            first[count] = x
            count += 1
        else:
            lab[x] = lab[r]
    return count, lab, first[:count]


def _split_reference(V, F, nudge):
    """split_nonmanifold_vertices as it was: sorted twins, fan centroids summed over every corner."""
    m = len(F)
    fi = np.repeat(np.arange(m), 3)
    li = np.tile(np.arange(3), m)
    t = repair._half_edge_twins_reference(F, len(V) + 1)
    g, lg = fi[t], li[t]
    ncomp, lab, first = _corner_components(3 * m, fi * 3 + li, g * 3 + (lg + 1) % 3, fi * 3 + (li + 1) % 3,
                                           g * 3 + lg)
    fan_vertex = F.reshape(-1)[first]
    fans_per_vertex = np.bincount(fan_vertex, minlength=len(V))
    centroids = V[F].mean(axis=1)
    by_vertex = np.argsort(fan_vertex, kind="stable")
    sv = fan_vertex[by_vertex]
    head = np.r_[True, sv[1:] != sv[:-1]]
    fan_to_new = np.empty(ncomp, dtype=np.int64)
    fan_to_new[by_vertex[head]] = sv[head]
    others = by_vertex[~head]
    fan_to_new[others] = len(V) + np.arange(len(others))
    F2 = fan_to_new[lab].reshape(-1, 3)
    V2 = np.concatenate([V, V[fan_vertex[others]]])
    corner_face = np.arange(3 * m) // 3
    counts = np.bincount(lab, minlength=ncomp).astype(np.float64)
    target = np.stack([np.bincount(lab, weights=centroids[corner_face, d], minlength=ncomp) for d in range(3)], axis=1)
    target /= counts[:, None]
    moved = np.flatnonzero(fans_per_vertex[fan_vertex] > 1)
    vid = fan_to_new[moved]
    d = target[moved] - V2[vid]
    nrm = np.linalg.norm(d, axis=1)
    good = nrm > 0
    V2[vid[good]] += d[good] * (nudge / nrm[good])[:, None]
    return V2, F2


def _touching_boxes(rng):
    """Boxes of random sizes, each pair touching at one corner (welded there): vertices with
    several fans."""
    Vs, Fs, n = [], [], 0
    corner = np.zeros(3)
    for k in range(4):
        ext = rng.uniform(0.5, 2.0, 3)
        b = trimesh.creation.box(extents=ext)
        V = b.vertices - b.vertices.min(axis=0) + corner  # its lowest corner at the previous box's highest
        Vs.append(V)
        Fs.append(b.faces + n)
        n += len(V)
        corner = V.max(axis=0)
    V = np.concatenate(Vs)
    _, first, inv = np.unique(V, axis=0, return_index=True, return_inverse=True)
    return V, np.ascontiguousarray(first[inv.reshape(-1)][np.concatenate(Fs)], dtype=np.int64)


def test_split_nonmanifold_vertices_equals_the_whole_mesh_computation():
    rng = np.random.default_rng(13)
    for _ in range(5):
        V, F = _touching_boxes(rng)
        got_V, got_F = repair.split_nonmanifold_vertices(V, F, nudge=1e-3, four_face=False)
        want_V, want_F = _split_reference(V, F, 1e-3)
        assert len(got_V) > len(V)  # the touching corners were split
        assert np.array_equal(got_F, want_F)
        assert np.array_equal(got_V.view(np.int64), want_V.view(np.int64))


def test_separate_coincident_equals_the_whole_mesh_computation():
    rng = np.random.default_rng(17)
    s = trimesh.creation.icosphere(subdivisions=2)
    for _ in range(5):
        V = np.array(s.vertices)
        src = rng.choice(len(V), 20, replace=False)
        dst = rng.choice(len(V), 20, replace=False)
        V[dst] = V[src]  # vertices sharing positions (some -0.0 against 0.0)
        V[dst[:3]] = V[src[:3]] * np.where(V[src[:3]] == 0, -1.0, 1.0)
        got = repair._separate_coincident(V, s.faces, 1e-3)
        want = repair._separate_coincident_reference(V, s.faces, 1e-3)
        assert not np.array_equal(got, V)
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_single_vector_helpers_equal_numpy():
    rng = np.random.default_rng(19)
    for _ in range(200):
        a = rng.normal(size=3) * rng.choice([0.0, 1.0, 1e-300, 1e300], size=3)
        b = rng.normal(size=3) * rng.choice([0.0, -1.0, 1.0], size=3)
        assert np.array_equal(repair._cross3(a, b).view(np.int64), np.cross(a, b).view(np.int64))
        x = rng.normal(size=int(rng.integers(1, 9)))
        k = int(rng.integers(len(x)))
        assert np.array_equal(repair._rolled(x, k), np.roll(x, -k))


def split_four_face_edges_reference(V, F, side, nudge):
    """:func:`_split_four_face_edges` as first written (the differential tests compare the two):
    replace every edge shared by four faces by two edges through side-specific midpoints.

    Such an edge joins a voxel of one slice and a voxel of the next that touch only along it;
    the two faces of each side are split at a midpoint of their own, which is then moved
    ``nudge`` into its side, so the two sheets no longer share the edge.
    """
    m = len(F)
    mult = repair_reference.edge_multiplicity(np.ascontiguousarray(F, dtype=np.int64), len(V))
    if np.any(mult % 2):
        bad = np.argwhere(mult % 2 == 1)[0]
        raise RuntimeError(f"internal error: an edge is shared by {int(mult[tuple(bad)])} faces")
    if np.any(mult > 4):
        raise RuntimeError(f"internal error: an edge is shared by {int(mult.max())} faces")
    hit = mult == 4
    if not hit.any():
        return V, F, side
    work = np.flatnonzero(hit.any(axis=1))
    faces = {int(i): (list(map(int, F[i])), int(side[i])) for i in work}
    by_edge: dict = {}
    for i, (f, _) in faces.items():
        for t in range(3):
            key = (min(f[t], f[(t + 1) % 3]), max(f[t], f[(t + 1) % 3]))
            by_edge.setdefault(key, set()).add(i)
    todo = sorted({tuple(sorted((int(F[i, t]), int(F[i, (t + 1) % 3])))) for i, t in np.argwhere(hit)})
    newV = []
    nxt_v = len(V)
    nxt_f = m
    Vl = V

    def coord(i):
        return Vl[i] if i < len(Vl) else newV[i - len(Vl)]

    for u, v in todo:
        fs = list(by_edge.get((u, v), ()))
        if len(fs) != 4:
            raise RuntimeError(f"internal error: edge ({u}, {v}) is shared by {len(fs)} faces while splitting")
        groups: dict = {}
        for i in fs:
            groups.setdefault(faces[i][1], []).append(i)
        for sd, group in groups.items():
            if len(group) != 2:
                raise RuntimeError("internal error: a four-face edge does not pair by side")
            mid = 0.5 * (coord(u) + coord(v))
            opp = []
            for i in group:
                f = faces[i][0]
                opp.append([w for w in f if w != u and w != v][0])
            toward = np.mean([coord(w) for w in opp], axis=0) - mid
            nrm = np.linalg.norm(toward)
            if nrm > 0:
                mid = mid + toward * (nudge / nrm)
            newV.append(mid)
            mv = nxt_v
            nxt_v += 1
            for i in group:
                f, _ = faces.pop(i)
                for t in range(3):
                    key = (min(f[t], f[(t + 1) % 3]), max(f[t], f[(t + 1) % 3]))
                    by_edge[key].discard(i)
                t = [k for k in range(3) if {f[k], f[(k + 1) % 3]} == {u, v}][0]
                a, b, c = f[t], f[(t + 1) % 3], f[(t + 2) % 3]
                for nf in ([a, mv, c], [mv, b, c]):
                    faces[nxt_f] = (nf, sd)
                    for k in range(3):
                        key = (min(nf[k], nf[(k + 1) % 3]), max(nf[k], nf[(k + 1) % 3]))
                        by_edge.setdefault(key, set()).add(nxt_f)
                    nxt_f += 1
    keep = np.ones(m, dtype=bool)
    keep[work] = False
    items = list(faces.values())
    F2 = np.concatenate([F[keep], np.array([f for f, _ in items], dtype=np.int64).reshape(-1, 3)])
    S2 = np.concatenate([side[keep], np.array([sd for _, sd in items], dtype=side.dtype)])
    V2 = np.concatenate([V, np.array(newV).reshape(-1, 3)])
    return V2, F2, S2


def test_four_face_rows_equal_the_whole_array_steps():
    """The four-face edge split's one pass over the edge counts: the first odd count (row order),
    the largest, and the faces with a four-face edge with the mask of those edges, as the numpy
    steps it replaced gave them; and the split raises the same errors as its reference."""
    rng = np.random.default_rng(23)
    for trial in range(200):
        m = int(rng.integers(0, 40))
        mult = (2 * rng.integers(1, 3 if trial % 3 else 4, (m, 3))).astype(np.int32)
        if trial % 4 == 0 and m:
            mult.reshape(-1)[rng.integers(mult.size, size=int(rng.integers(1, 4)))] = rng.choice([1, 3, 5])
        odd, most, rows, hit = repair_reference.four_face_rows(mult)
        want = np.argwhere(mult % 2 == 1)
        assert odd == (int(mult[tuple(want[0])]) if len(want) else 0)
        assert most == (int(mult.max()) if m else 0)
        four = mult == 4
        assert np.array_equal(rows, np.flatnonzero(four.any(axis=1)))
        assert np.array_equal(hit, four[rows])
    V = np.zeros((8, 3))
    for F in (np.array([[0, 1, 2], [0, 1, 3], [1, 0, 4]]), np.concatenate([np.array([[0, 1, 2], [1, 0, 3]])] * 3)):
        msgs = []
        for fn in (repair._split_four_face_edges, split_four_face_edges_reference):
            with pytest.raises(RuntimeError, match="an edge is shared by") as err:
                fn(V, F, np.zeros(len(F), dtype=np.int64), 1e-3)
            msgs.append(str(err.value))
        assert msgs[0] == msgs[1]


def test_split_four_face_edges_equals_the_reference_on_voxel_meshes(monkeypatch):
    # the general mesher's four-face edges (voxels of consecutive slices touching along an edge),
    # among them faces with two such edges (a split face's other edge is split after it), and the
    # numbering of the new vertices and faces, which follows the iteration order of Python sets
    import contourmesh
    from contourmesh import volumes

    seen = {"edges": 0, "chained": 0}

    def both(V, F, side, nudge, overwrite=False):  # (the mesher gives its own arrays over)
        got = repair._split_four_face_edges(V, F, side, nudge)
        want = split_four_face_edges_reference(V, F, side, nudge)
        assert all(np.array_equal(g, w) and g.dtype == w.dtype for g, w in zip(got, want))
        assert np.array_equal(got[0].view(np.int64), want[0].view(np.int64))
        hit = repair_reference.edge_multiplicity(np.ascontiguousarray(F, dtype=np.int64), len(V)) == 4
        seen["edges"] += int(hit.sum()) // 4
        seen["chained"] += int((hit.sum(axis=1) > 1).sum())
        return got

    monkeypatch.setattr(volumes, "_split_four_face_edges", both)
    rng = np.random.default_rng(23)
    for _ in range(6):
        vol = np.pad(rng.random((6, 14, 13)) < 0.4, 1)
        m = contourmesh.mesh(vol)
        assert m.checks()["ok"]
    assert seen["edges"] > 50 and seen["chained"] > 0


def test_overlap_holes_equals_ndimage_label():
    # the bridged join's overlap structure (volumes._bridge_plan): the overlap's 4-components, its
    # padded background's 8-components with ndimage.label's numbers, and the overlaps that reach
    # the outside, against scipy on random masks (holes, diagonal contacts, rings around islands)
    from numba import njit
    from numba.core import types
    from scipy import ndimage

    from contourmesh import tracing

    rng = np.random.default_rng(29)
    inside = set()
    for _ in range(1500):
        h, w = (int(v) for v in rng.integers(1, 13, 2))
        o = rng.random((h, w)) < rng.uniform(0.2, 0.9)
        n, blab, nb, n_out = tracing.overlap_holes(o)
        olab, want_n = ndimage.label(o, structure=np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool))
        want_blab, want_nb = ndimage.label(np.pad(~o, 1, constant_values=True), structure=np.ones((3, 3), bool))
        near = ndimage.binary_dilation(want_blab == want_blab[0, 0], structure=np.ones((3, 3), bool))[1:-1, 1:-1]
        assert (n, nb, n_out) == (want_n, want_nb, len(np.unique(olab[near & o])))
        assert blab.dtype == np.int64 and np.array_equal(blab, want_blab)
        inside.add(n_out < n)
    assert inside == {True, False}
    # one signature per kernel, no literal argument (typed again uncached: the cached entry brings
    # its callees' code without typing them in this process)
    for sig in tracing._overlap_hole_labels.signatures:
        njit(nogil=True)(tracing._overlap_hole_labels.py_func).compile(sig)
    for d in (tracing._overlap_hole_labels, tracing._join):
        assert len(d.signatures) == 1
        assert not any(isinstance(t, types.Literal) for t in d.signatures[0])


def test_label_mask_equals_isin():
    from contourmesh.tracing import label_mask

    rng = np.random.default_rng(31)
    for dtype in (np.uint8, np.uint16, np.int32):
        for _ in range(50):
            n = int(rng.integers(0, 12))
            lab = rng.integers(0, n + 1, (int(rng.integers(1, 9)), int(rng.integers(1, 9)))).astype(dtype)
            comps = sorted(set(rng.integers(0, max(n, 1), int(rng.integers(0, 4))).tolist())) if n else []
            got = label_mask(lab, n, comps)
            assert got.dtype == bool and np.array_equal(got, np.isin(lab, [c + 1 for c in comps]))


def test_label_mask_on_boxes_of_a_label_image_for_one_some_and_all_components():
    # label_mask compares where it selects one component or all of them, and takes from its table
    # otherwise: on views of a larger image (the mesher's boxes), the same pixels as np.isin
    from contourmesh.tracing import label_mask

    rng = np.random.default_rng(32)
    for dtype in (np.uint8, np.int32):
        for t in range(60):
            n = int(rng.integers(1, 7))
            big = rng.integers(0, n + 1, (40, 50)).astype(dtype)
            lab = big[int(rng.integers(0, 10)):int(rng.integers(20, 40)), int(rng.integers(0, 10)):int(rng.integers(20, 50))]
            comps = [list(range(n)), [int(rng.integers(n))], sorted(set(rng.integers(0, n, 3).tolist()))][t % 3]
            before = big.copy()
            got = label_mask(lab, n, comps)
            assert got.dtype == bool and got.shape == lab.shape and got.flags.c_contiguous
            assert np.array_equal(got, np.isin(lab, [c + 1 for c in comps]))
            got[...] = True  # (a fresh array: the label image is untouched)
            assert np.array_equal(big, before)


def test_vertex_normals_at_some_vertices_equal_the_whole_mesh_normals():
    rng = np.random.default_rng(37)
    s = trimesh.creation.icosphere(subdivisions=3)
    V = np.array(s.vertices) * rng.uniform(0.5, 2.0, (1, 3)) + rng.normal(scale=0.05, size=s.vertices.shape)
    F = np.ascontiguousarray(s.faces, dtype=np.int64)
    whole = repair._vertex_normals(V, F)
    for _ in range(10):
        ids = rng.choice(len(V), int(rng.integers(1, 60)), replace=False)
        assert np.array_equal(repair._vertex_normals_at(V, F, ids).view(np.int64), whole[ids].view(np.int64))


def test_compact_renumbers_in_place_and_leaves_a_mesh_using_every_vertex_alone():
    # issue 16 (memory): _compact(overwrite=True) writes the renumbered faces into F itself; a mesh
    # that uses every vertex comes back as it is (no copies)
    rng = np.random.default_rng(23)
    V = rng.normal(size=(50, 3))
    F = _random_faces(rng, 60, 50)
    unused = np.setdiff1d(np.arange(50), F)
    assert len(unused)  # (the case with vertices to drop)
    used = np.flatnonzero(np.bincount(F.reshape(-1), minlength=50))
    remap = np.full(50, -1)
    remap[used] = np.arange(len(used))
    want_V, want_F = V[used], remap[F]
    got_V, got_F = repair._compact(V, F.copy())
    assert np.array_equal(got_V, want_V) and np.array_equal(got_F, want_F)
    G = F.copy()
    got_V, got_F = repair._compact(V, G, overwrite=True)
    assert got_F is G and np.array_equal(G, want_F) and np.array_equal(got_V, want_V)
    W, H = repair._compact(want_V, want_F)  # every vertex used
    assert W is want_V and H is want_F
    # the kept rows (taken along the rows) of a vertex array in any layout are V[used]'s
    for U in (np.asfortranarray(V), V[:, ::-1], V.astype(np.float32)):
        got_V, got_F = repair._compact(U, F.copy())
        assert got_V.dtype == U.dtype and np.array_equal(got_V, U[used]) and np.array_equal(got_F, want_F)


def test_kept_and_added_equals_the_concatenation():
    rng = np.random.default_rng(29)
    F = _random_faces(rng, 1000, 300)
    for dtype in (np.int32, np.int64):  # (the volume mesher's sides carry tags in int32; the repair's int64)
        side = rng.integers(0, 40, 1000).astype(dtype)
        for keep in (rng.random(1000) < 0.9, np.ones(1000, bool), np.zeros(1000, bool)):
            for added, sides in (([[1, 2, 3], [4, 5, 6]], [7, 8]), ([], [])):
                want_F = np.concatenate([F[keep], np.array(added, dtype=np.int64).reshape(-1, 3)])
                want_S = np.concatenate([side[keep], np.array(sides, dtype=dtype)])
                got_F, got_S = repair._kept_and_added(F, side, keep, added, sides)
                assert got_F.dtype == np.int64 and got_S.dtype == side.dtype
                assert np.array_equal(got_F, want_F) and np.array_equal(got_S, want_S)
                # (overwrite: the caller's own arrays, the kept rows moved down and resized in place)
                F_own, side_own = F.copy(), side.copy()
                got_F, got_S = repair._kept_and_added(F_own, side_own, keep, added, sides, overwrite=True)
                assert got_F is F_own and got_S is side_own
                assert got_F.dtype == np.int64 and got_S.dtype == side.dtype
                assert np.array_equal(got_F, want_F) and np.array_equal(got_S, want_S)
    # (a view, or an array of other dtypes, is not resized: the copy as without overwrite)
    side = np.arange(1000, dtype=np.int32)
    view = F[::2]
    got_F, got_S = repair._kept_and_added(view, side[::2], np.ones(500, bool), [[1, 2, 3]], [9], overwrite=True)
    assert got_F is not view and np.array_equal(got_F, np.concatenate([view, [[1, 2, 3]]]))
    assert np.array_equal(got_S, np.r_[side[::2], 9]) and np.array_equal(view, F[::2])


def test_fan_numbers_equal_the_stable_sort_by_vertex():
    # issue 16 (memory): the fans' new vertex numbers by counting, as the stable argsort gave them
    rng = np.random.default_rng(31)
    split = False
    for _ in range(200):
        nv = int(rng.integers(1, 30))
        fv = rng.integers(0, nv, int(rng.integers(1, 80))).astype(np.int64)
        by = np.argsort(fv, kind="stable")
        sv = fv[by]
        head = np.r_[True, sv[1:] != sv[:-1]]
        want = np.empty(len(fv), dtype=np.int64)
        want[by[head]] = sv[head]
        others = by[~head]
        want[others] = nv + np.arange(len(others))
        got, got_others = repair._fan_numbers(fv, nv)
        assert np.array_equal(got, want) and np.array_equal(got_others, others)
        split |= len(others) > 0
    assert split


def test_release_free_heap_only_for_large_meshes(monkeypatch):
    # issue 16 (memory): the general mesher gives freed heap back between its steps on large
    # meshes only; where the C library has no malloc_trim nothing happens; the mesh is the same
    import contourmesh
    from contourmesh import _heap

    calls = []
    monkeypatch.setattr(_heap, "_trim", lambda pad: calls.append(pad) or 1)
    assert not _heap.release_free_heap(_heap.RELEASE_FROM_FACES - 1) and calls == []
    assert _heap.release_free_heap(_heap.RELEASE_FROM_FACES) and calls == [0]
    vol = np.pad(np.random.default_rng(5).random((10, 12, 11)) < 0.4, 1)
    want = contourmesh.mesh(vol)
    monkeypatch.setattr(_heap, "RELEASE_FROM_FACES", 0)  # every step of the small mesh trims
    calls.clear()
    got = contourmesh.mesh(vol)
    assert len(calls) >= 5
    assert np.array_equal(got.vertices, want.vertices) and np.array_equal(got.faces, want.faces)
    monkeypatch.setattr(_heap, "_trim", False)  # no malloc_trim here
    assert not _heap.release_free_heap(10**9)


def test_midpoints_in_rounds_equal_the_one_row_form():
    # new vertices made from old ones and from earlier new ones (chains several rounds deep),
    # with edges whose opposite corners average onto the midpoint (no nudge there), in float64
    # and float32: bit for bit what the one-row form makes in order
    rng = np.random.default_rng(5)
    for dtype in (np.float64, np.float32):
        V = (rng.random((40, 3)) * 10).astype(dtype)
        V[3:6] = [[1, 2, 3], [1.5, 2, 3], [0.5, 2, 3]]  # o0=4, o1=5 average onto 3 (zero toward)
        made = []
        for j in range(60):
            top = 40 + j
            made.append(rng.integers(0, top, 4) if j % 7 else [3, 3, 4, 5])
        made = np.array(made, dtype=np.int64)
        got = repair._midpoints(V, made, 0.01)
        pts = list(V)
        for u, v, a, b in made.tolist():
            pts.append(repair._midpoint_one(pts[u], pts[v], pts[a], pts[b], 0.01))
        want = np.array(pts[40:])
        assert got.dtype == want.dtype == dtype
        assert np.array_equal(got.view(np.uint8), want.view(np.uint8))
        assert np.array_equal(got[0], 0.5 * (V[3] + V[3]))  # (the zero-length toward: not moved)
    assert repair._midpoints(V, np.zeros((0, 4), np.int64), 0.01).shape == (0, 3)


def test_keyhole_kernel_equals_the_python_search():
    # polyline keyholes from a hole to its component's outer ring through waypoints on a pixel grid,
    # past stray edges and segments, kept out of random overlap pixels: the compiled search and
    # straightening (keyhole_path with an OverlapFree test, or none) against the Python search (the
    # same tests as plain functions); rings on the half-pixel grid meet the neighbourhoods' radii
    # exactly, where the compiled search asks the k-d tree (on a grid of 0.7: not exact numbers)
    from contourmesh.bands import bridges as B

    rng = np.random.default_rng(97)
    seen = {"path": 0, "none": 0, "asked": 0}
    calls = []
    real, real_kernel = B._keyhole_compiled, B._keyhole_kernel

    def spy(*a, **k):
        got = real(*a, **k)
        calls.append(isinstance(got, int))
        return got

    def spy_kernel(*a):
        got = real_kernel(*a)
        seen["asked"] += int(got[0] < 0)
        return got

    B._keyhole_compiled, B._keyhole_kernel = spy, spy_kernel
    try:
        for trial in range(160):
            s = float(rng.choice([0.5, 0.7, 1.0]))
            half = trial % 4 == 0
            outer = _star(rng, np.zeros(2), 8 * s, int(rng.integers(8, 30)), False)
            hole = _star(rng, rng.uniform(-2, 2, 2) * s, 2 * s, int(rng.integers(4, 12)), False)[::-1]
            if half:
                outer, hole = np.round(outer / (0.5 * s)) * 0.5 * s, np.round(hole / (0.5 * s)) * 0.5 * s
            g = np.arange(-9, 10) * s
            W = np.array([(x, y) for x in g for y in g if 1.5 * s < np.hypot(x, y) < 7.5 * s])
            stray = rng.uniform(-8, 8, (int(rng.integers(0, 6)), 2)) * s
            oa = np.concatenate([hole, outer, stray])
            ob = np.concatenate([np.roll(hole, -1, axis=0), np.roll(outer, -1, axis=0),
                                 stray + rng.normal(0, 2 * s, stray.shape)])
            segs = [(rng.uniform(-8, 8, 2) * s, rng.uniform(-8, 8, 2) * s) for _ in range(int(rng.integers(0, 3)))]
            over = rng.random((20, 20)) < rng.uniform(0.0, 0.15)
            test = B.OverlapFree(over, int(rng.integers(-3, 3)), int(rng.integers(-3, 3)), (-10 * s, -10 * s, s, s))
            used_i = set(rng.choice(len(hole), int(rng.integers(0, 3))).tolist())
            used_j = set(rng.choice(len(outer), int(rng.integers(0, 4))).tolist())
            limit = 5 if trial % 7 == 3 else B.KEYHOLE_MAX_NODES
            for allowed, plain in ((test, lambda p, q, t=test: t(p, q)), (None, lambda p, q: True)):
                n0 = len(calls)
                got = B.keyhole_path(hole, outer, W, s, oa, ob, segs, allowed=allowed, used_i=used_i, used_j=used_j,
                                     max_nodes=limit)
                assert len(calls) == n0 + 1
                want = B.keyhole_path(hole, outer, W, s, oa, ob, segs, allowed=plain, used_i=used_i, used_j=used_j,
                                      max_nodes=limit)
                assert len(calls) == n0 + 1  # (the plain test takes the Python search)
                assert (got is None) == (want is None)
                if got is not None:
                    assert got[:2] == want[:2] and got[2].tobytes() == want[2].tobytes()
                seen["none" if got is None else "path"] += 1
    finally:
        B._keyhole_compiled, B._keyhole_kernel = real, real_kernel
    assert min(seen.values()) >= 5, seen


def test_overlap_free_kernel_equals_the_numpy_test():
    from contourmesh.bands import bridges as B

    rng = np.random.default_rng(98)
    hits = 0
    for _ in range(2000):
        dx, dy = rng.choice([0.5, 0.7, 1.0], 2)
        over = rng.random((12, 14)) < 0.2
        t = B.OverlapFree(over, int(rng.integers(-2, 3)), int(rng.integers(-2, 3)), (-1.0, -2.0, dx, dy))
        p, q = rng.uniform(-3, 12, 2), rng.uniform(-3, 12, 2)
        if rng.random() < 0.3:
            p, q = np.round(p * 2) / 2, np.round(q * 2) / 2  # (samples on halves)
        want = t(p, q)
        got = B._overlap_free_kernel(float(p[0]), float(p[1]), float(q[0]), float(q[1]), t.over, np.int64(t.x0),
                                     np.int64(t.y0), *t.grid)
        assert bool(got) == bool(want)
        hits += not want
    assert hits > 200


def test_fortran_ordered_volume_is_copied_to_c_order_exactly():
    # prepare_volume copies a Fortran-ordered boolean volume by tiles (volume_input._fortran_to_c):
    # the same voxels, C-contiguous, for shapes around and across the tile side
    from contourmesh.volume_input import _c_order, prepare_volume

    rng = np.random.default_rng(41)
    for shape in [(1, 1, 1), (3, 5, 7), (64, 3, 64), (65, 2, 130), (130, 4, 63), (7, 129, 66)]:
        v = rng.random(shape) < 0.3
        f = np.asfortranarray(v)
        got = _c_order(f)
        assert got.dtype == bool and got.flags.c_contiguous and got.shape == shape and np.array_equal(got, v)
        assert np.array_equal(_c_order(v[:, ::2]), v[:, ::2])  # (other layouts: numpy's copy)
        if v.any():
            assert np.array_equal(prepare_volume(f)[0], v)


def _faces_near_reference(V, W, F, moved_faces):
    # repair._faces_near until issue 16's memory round: the whole mesh's boxes, extents and cells
    # as numpy arrays
    P = np.stack([V[F], W[F]], axis=1).reshape(len(F), 6, 3)
    lo, hi = P.min(axis=1), P.max(axis=1)
    glo = lo.min(axis=0)
    ext = hi - lo
    h = max(float(ext[moved_faces].max()), float(np.median(ext.max(axis=1))), 1e-12)
    clo = np.floor((lo - glo) / h).astype(np.int64)
    chi = np.floor((hi - glo) / h).astype(np.int64)
    return _share_cell_brute(clo, chi, np.asarray(moved_faces, dtype=np.int64))


def _share_cell_brute(clo, chi, chosen):
    # faces sharing a cell with a chosen one: their ranges of cells overlap along every axis (no
    # hash table, as repair._near_cells has)
    meet = ((clo[:, None, :] <= chi[None, chosen, :]) & (clo[None, chosen, :] <= chi[:, None, :])).all(axis=2)
    near = np.flatnonzero(meet.any(axis=1))
    return near


@njit(cache=False)
def _boxes_near_reference(V, F, chosen):
    # repair._boxes_near until issue 16's memory round (boxes, extents and cells kept per face):
    # the cells of every face
    n = F.shape[0]
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    ext = np.empty(n)
    for i in range(n):
        e = 0.0
        for d in range(3):
            a, b, c = V[F[i, 0], d], V[F[i, 1], d], V[F[i, 2], d]
            lo[i, d] = min(a, b, c)
            hi[i, d] = max(a, b, c)
            e = max(e, hi[i, d] - lo[i, d])
        ext[i] = e
    h = max(np.median(ext), 1e-12)
    for t in range(len(chosen)):
        h = max(h, ext[chosen[t]])
    glo = np.empty(3)
    for d in range(3):
        glo[d] = lo[:, d].min()
    clo = np.empty((n, 3), np.int64)
    chi = np.empty((n, 3), np.int64)
    for i in range(n):
        for d in range(3):
            clo[i, d] = np.int64(np.floor((lo[i, d] - glo[d]) / h))
            chi[i, d] = np.int64(np.floor((hi[i, d] - glo[d]) / h))
    return clo, chi


def test_faces_near_without_whole_mesh_boxes_equals_the_reference():
    # issue 16 (memory): the faces near the moved ones (resolve_crossings) and near the changed
    # ones (crossing_pairs_after_change) from compiled passes over the corners, without the whole
    # mesh's boxes: the same faces as from the boxes, on grid coordinates (cells meet exactly at
    # box sides) and anywhere, with few and many chosen faces
    rng = np.random.default_rng(37)
    sizes = set()
    for trial in range(120):
        nv, m = int(rng.integers(4, 200)), int(rng.integers(2, 400))
        V = (rng.integers(-20, 21, (nv, 3)) / 4.0) if trial % 2 == 0 else rng.normal(scale=5.0, size=(nv, 3))
        W = V.copy()
        F = _random_faces(rng, m, nv)
        chosen = np.unique(rng.choice(m, int(rng.integers(1, max(2, m // (1 + 9 * (trial % 3)))))))
        W[np.unique(F[chosen])] += rng.normal(scale=0.3, size=(len(np.unique(F[chosen])), 3))
        got = repair._faces_near(V, W, F, chosen)
        assert np.array_equal(got, _faces_near_reference(V, W, F, chosen))
        got = repair._boxes_near(V, F, chosen)
        assert np.array_equal(got, _share_cell_brute(*_boxes_near_reference(V, F, chosen), chosen))
        sizes.add(len(got) == m)
    assert sizes == {True, False}


@pytest.mark.parametrize("threads", [2, 3])
def test_edge_counts_and_twins_on_threads_equal_one_threads(monkeypatch, threads):
    """The manifold repair's edge counts and half-edge twins on threads (meshes of at least
    _SPLIT_EDGES faces, CONTOURMESH_THREADS > 1): the one-thread kernels' arrays, a non-zero status
    where theirs is, and the same repaired meshes."""
    rng = np.random.default_rng(17)
    for m, nv in ((400, 40), (3000, 900), (5, 9)):
        F = _random_faces(rng, m, nv)
        assert np.array_equal(repair_reference.edge_multiplicity_threads(F, nv, threads), repair_reference.edge_multiplicity(F, nv))
    s = trimesh.creation.icosphere(subdivisions=4)
    F = np.ascontiguousarray(s.faces, dtype=np.int64)[rng.permutation(len(s.faces))]
    nv = len(s.vertices)
    twin, status = repair._half_edge_twins_threads(F, nv, threads)
    assert status == 0 and np.array_equal(twin, repair._half_edge_twins(F, nv)[0])
    assert repair._half_edge_twins_threads(F[1:], nv, threads)[1] != 0
    assert repair._half_edge_twins_threads(np.concatenate([F, F[:1]]), nv, threads)[1] != 0
    # the general mesher's repair (four-face edges split by side, vertex fans) on a noisy volume
    import contourmesh

    vol = np.pad(rng.random((10, 12, 11)) < 0.45, 1)
    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    one = contourmesh.mesh(vol)
    calls = []
    monkeypatch.setattr(repair, "_SPLIT_EDGES", 10)
    monkeypatch.setattr(repair, "_buckets_on_threads", lambda *a, f=repair._buckets_on_threads: calls.append(1) or f(*a))
    monkeypatch.setenv("CONTOURMESH_THREADS", str(threads))
    many = contourmesh.mesh(vol)
    assert len(calls) >= 1 and one.meta == many.meta  # (the four-face edges on threads; the fans walk per vertex)
    assert one.vertices.tobytes() == many.vertices.tobytes() and one.faces.tobytes() == many.faces.tobytes()


def test_open_necks_refused_as_the_loop_refuses(monkeypatch):
    # a vertex whose star is three cones, and one whose link is not closed: the loop's messages
    rng = np.random.default_rng(3)

    def cone(apex, ring, base):
        k = len(ring)
        return [[apex, ring[t], ring[(t + 1) % k]] for t in range(k)] + [[base, ring[(t + 1) % k], ring[t]] for t in range(k)]

    monkeypatch.setattr(repair, "_NECKS_AT_ONCE", 1)
    V = rng.normal(size=(40, 3))
    F = np.array(cone(0, [1, 2, 3], 4) + cone(0, [5, 6, 7], 8) + cone(0, [9, 10, 11], 12), dtype=np.int64)
    S = np.zeros(len(F), dtype=np.int32)
    with pytest.raises(RuntimeError, match="has 3 fans, expected 2"):
        repair._open_necks(V, F, S, np.array([0]), 1e-3)
    with pytest.raises(RuntimeError, match="not the apex of two cones"):
        repair._open_necks(V, np.concatenate([F[:3], F[:1]]), S, np.array([0]), 1e-3)


def test_neck_steps_equal_their_numpy_forms():
    # the whole-array steps of _necks_angles, segment by segment, against the numpy calls the
    # loop makes per neck (means, matrix-vector products, argmin with NaN, unwrap, roll), and the
    # compiled walk against the loop's
    rng = np.random.default_rng(23)
    lens = rng.integers(1, 14, size=300)
    lens[:5] = [1, 2, 3, 8, 9]
    n = int(lens.sum())
    starts = repair._starts(lens)
    X = rng.normal(size=(n, 3)) * rng.choice([1e-3, 1.0, 1e3], size=(n, 1))
    E = rng.normal(size=(len(lens), 3))
    means = repair._segment_means(X, lens)
    prods = repair._stacked_products(X, lens, E)
    # angles with steps of about pi and 2 pi, and exact ties
    p = np.round(np.cumsum(rng.normal(size=n) * 2.5), 1)
    p[::7] = np.pi
    up = repair._unwrap_segments(p, lens)
    x = np.round(rng.random(n), 1)
    x[rng.random(n) < 0.02] = np.nan
    arg = repair._segment_argmin(x, lens)
    k = rng.integers(0, lens)
    rolled = repair._rolled_rows(lens, k)
    for j, (s, m) in enumerate(zip(starts.tolist(), lens.tolist())):
        seg = slice(s, s + m)
        assert means[j].tobytes() == X[seg].mean(axis=0).tobytes()
        assert prods[seg].tobytes() == (X[seg] @ E[j]).tobytes()
        assert up[seg].tobytes() == np.unwrap(p[seg]).tobytes()
        assert arg[j] == np.argmin(x[seg])
        assert np.array_equal(rolled[seg], s + repair._rolled(np.arange(m), int(k[j])))

    simple = [0, 0]
    for _ in range(400):
        na, nb = (int(v) for v in rng.integers(1, 10, size=2))
        a = np.arange(100, 100 + na)
        b = np.arange(200, 200 + nb)
        ua = np.round(np.sort(rng.random(na + 1)) * 6 * rng.choice([1, -1]), 1)
        ub = np.round(np.sort(rng.random(nb + 1)) * 6, 1)
        for prop in (False, True):
            rule = (lambda i, j: (i + 1) * nb <= (j + 1) * na) if prop else (lambda i, j: ua[i + 1] <= ub[j + 1])
            ok, faces = repair._walk_rings(a.tolist(), b.tolist(), rule)
            got = np.empty((na + nb, 3), np.int64)
            assert repair._tube_walk(a, b, ua, ub, prop, got) == ok
            assert got.tolist() == [list(f) for f in faces]
            simple[ok] += 1
    assert min(simple) > 20


def test_fan_cycles_equal_the_union_find_over_the_links(monkeypatch):
    """repair._fan_components walks the corners around each vertex (the links' permutation): the
    count, labels and lowest corners of the union-find over the links, on touching boxes (faces
    shuffled and their corners rotated) and on the meshes the volume mesher splits; and
    split_nonmanifold_vertices (the same walk in _split_fans) makes the reference's meshes there."""
    rng = np.random.default_rng(29)
    meshes = []
    for _ in range(4):
        V, F = _touching_boxes(rng)
        F = F[rng.permutation(len(F))]
        F = np.ascontiguousarray(np.roll(F, 1, axis=1) if rng.random() < 0.5 else F)
        meshes.append((V, F))
    from scipy import ndimage

    import contourmesh
    from contourmesh import volumes

    real = volumes.split_nonmanifold_vertices
    monkeypatch.setattr(volumes, "split_nonmanifold_vertices",
                        lambda V, F, **k: meshes.append((V.copy(), F.copy())) or real(V, F, **k))
    contourmesh.mesh(ndimage.gaussian_filter(rng.random((8, 30, 30)), 0.7) > 0.5)
    several = 0
    for V, F in meshes:
        twin, status = repair._half_edge_twins(np.ascontiguousarray(F, dtype=np.int64), len(V))
        assert status == 0
        m = len(F)
        t = twin.astype(np.int64)
        c = np.arange(3 * m)
        nxt = 3 * (c // 3) + (c % 3 + 1) % 3
        want = _corner_components(3 * m, c, 3 * (t // 3) + (t % 3 + 1) % 3, nxt, t)
        got = repair._fan_components(twin)
        assert got[0] == want[0] and np.array_equal(got[1], want[1]) and np.array_equal(got[2], want[2])
        several += int((np.bincount(F.reshape(-1)[got[2]]) > 1).sum())
        # and the split itself (its fans, numbers and nudges in one compiled pass) as the reference
        got_V, got_F = repair.split_nonmanifold_vertices(V, F, nudge=1e-3, four_face=False)
        want_V, want_F = _split_reference(V, F, 1e-3)
        assert np.array_equal(got_F, want_F) and np.array_equal(got_V.view(np.int64), want_V.view(np.int64))
    assert several > 10  # (vertices of several fans)


@njit
def _set_replay(ops):
    """The compiled set helpers of the four-face edge split replaying ``ops`` (rows ``(0, key)``
    add, ``(1, key)`` discard) on one set: its keys in table order and whether it fit."""
    tk = np.full((1, repair._SET_CAP), repair._SET_NULL, np.int64)
    tq = np.zeros((1, repair._SET_CAP), np.int64)
    meta = np.zeros((1, 3), np.int64)
    meta[0, 0] = 7
    old_k = np.empty(repair._SET_CAP, np.int64)
    old_q = np.empty(repair._SET_CAP, np.int64)
    for t in range(ops.shape[0]):
        if ops[t, 0] == 0:
            if not repair._set_add(tk, tq, meta, 0, ops[t, 1], -ops[t, 1], old_k, old_q):
                return np.zeros(0, np.int64), np.zeros(0, np.int64), False
        else:
            repair._set_discard(tk, meta, 0, ops[t, 1])
    keys, slots = [], []
    for j in range(meta[0, 0] + 1):
        if tk[0, j] >= 0:
            keys.append(tk[0, j])
            slots.append(tq[0, j])
    return np.array(keys, dtype=np.int64), np.array(slots, dtype=np.int64), True


def test_compiled_sets_iterate_as_python_sets():
    """The four-face edge split's compiled sets of face numbers give the iteration order of this
    Python's sets after the same additions and removals (random sequences of keys small and large,
    re-added, removed and absent, with the tables' dummies and growth), each key with its slot."""
    rng = np.random.default_rng(29)
    fit = grown = 0
    for trial in range(4000):
        hi = int(rng.choice([8, 16, 33, 64, 10**6, 2**40]))
        ops, s, live = [], set(), []
        for _ in range(int(rng.integers(1, 30))):
            if live and rng.random() < 0.4:
                x = live.pop(int(rng.integers(len(live)))) if rng.random() < 0.9 else int(rng.integers(hi))
                ops.append((1, x))
                s.discard(x)
            else:
                x = int(rng.integers(hi))
                ops.append((0, x))
                if x not in s:
                    live.append(x)
                s.add(x)
        keys, slots, ok = _set_replay(np.array(ops, dtype=np.int64).reshape(-1, 2))
        if ok:
            assert keys.tolist() == list(s)
            assert np.array_equal(slots, -keys)
            fit += 1
            grown += len(ops) - sum(o == 1 for o, _ in ops) > 4
    assert fit > 3000 and grown > 500


def _four_face_inputs(rng, trials=6):
    """The general mesher's inputs to the four-face edge split on random voxel volumes."""
    import contourmesh
    from contourmesh import volumes

    seen = []
    real = volumes._split_four_face_edges

    def keep(V, F, side, nudge, overwrite=False):  # (the mesher gives its own arrays over)
        seen.append((V.copy(), F.copy(), side.copy(), nudge))
        return real(V, F, side, nudge)

    volumes._split_four_face_edges = keep
    try:
        for _ in range(trials):
            contourmesh.mesh(np.pad(rng.random((6, 14, 13)) < 0.4, 1))
    finally:
        volumes._split_four_face_edges = real
    return seen


def test_compiled_split_loop_equals_the_python_loop(monkeypatch):
    """The four-face edge split with its compiled loop (:func:`repair._split_faces`) gives what the
    Python loop gives, bit for bit, on the general mesher's meshes (faces with two four-face edges
    among them) and on those meshes with the sides of the faces renumbered at random (other
    pairings, other orders of the sides); where a set does not pair by side or has other than four
    faces the compiled loop reports it and the Python loop's error is raised."""
    rng = np.random.default_rng(31)
    runs = 0
    for V, F, side, nudge in _four_face_inputs(rng):
        for trial in range(3):
            sd = side if trial == 0 else rng.permutation(8)[side % 8] + 4 * (side // 8)
            monkeypatch.setattr(repair, "_COMPILED_SET_ORDER", False)
            try:
                want = repair._split_four_face_edges(V, F, sd, nudge)
            except RuntimeError as err:
                want = str(err)
            monkeypatch.setattr(repair, "_COMPILED_SET_ORDER", True)
            try:
                got = repair._split_four_face_edges(V, F, sd, nudge)
            except RuntimeError as err:
                got = str(err)
            if isinstance(want, str):
                assert got == want
                continue
            assert all(np.array_equal(g, w) and g.dtype == w.dtype for g, w in zip(got, want))
            assert np.array_equal(got[0].view(np.int64), want[0].view(np.int64))
            runs += len(got[1]) > len(F)
            # (with the caller's own faces and sides given over: the same arrays, F's buffer resized)
            F_own, sd_own = F.copy(), np.array(sd)
            own = repair._split_four_face_edges(V, F_own, sd_own, nudge, overwrite=True)
            assert own[1] is F_own and own[2] is sd_own
            assert all(np.array_equal(g, w) and g.dtype == w.dtype for g, w in zip(own, want))
            assert np.array_equal(own[0].view(np.int64), want[0].view(np.int64))
    assert runs >= 6
    # a four-face edge whose faces do not pair by side, and one whose set lost a face: reported
    # by the compiled loop, named by the Python loop
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 0, 5]], dtype=np.int64)
    _, _, work, hit = repair_reference.four_face_rows(repair_reference.edge_multiplicity(F, 6))
    args = (np.int64(4), np.int64(6), np.int64(20))
    assert repair._split_faces(F[work], np.array([0, 1, 0, 1]), work, hit, *args)[0]
    assert not repair._split_faces(F[work], np.array([0, 0, 0, 1]), work, hit, *args)[0]
    with pytest.raises(RuntimeError, match="does not pair by side"):
        repair._split_faces_py(F[work], np.array([0, 0, 0, 1]), work, hit, 4, 6, 20)
    hit[0, 0] = False  # (face 0 left out of the edge's set: three faces)
    assert not repair._split_faces(F[work], np.array([0, 1, 0, 1]), work, hit, *args)[0]
    with pytest.raises(RuntimeError, match="shared by 3 faces while splitting"):
        repair._split_faces_py(F[work], np.array([0, 1, 0, 1]), work, hit, 4, 6, 20)
