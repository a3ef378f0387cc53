"""Issue 16 (thirteenth round): the whole-mesh crossing test takes the faces' groups (the volume
mesher's joins and caps) and does not test the pairs of two faces of one group that are halves of
cells of the group's own rectilinear grid (``intersect._lattice_cells``).  The certificate against
a plain Python form of its rule; no certified pair intersecting (by the test without groups, every
pair tested in full); and the pairs with groups equal to those without, bit for bit: on random
lattice meshes with planted overlaps (the other diagonal of a cell, a face twice, a rectangle over
two intervals, a value between two grid lines, faces across the lattice), on the general mesher's
meshes of random volumes, on two threads, and on the lobster's first build and a liver label."""

import numpy as np
import pytest

import contourmesh
from contourmesh import intersect as I
from contourmesh import volumes
from contourmesh._kernels import njit
from contourmesh.intersect import canonical_vertices, intersecting_pairs
from plane_parts import part_boxes
from test_intersect_quick import _volume


def _cells_reference(V, F, grp):
    """:func:`contourmesh.intersect._lattice_cells` step by step, with Python sets and dicts."""
    m = len(F)
    cg = np.full(m, -1, dtype=np.int64)
    if m and int(np.max(grp, initial=-1)) + 1 > 8 * m + 16:
        return cg
    cand = {}
    for i in range(m):
        if grp[i] < 0 or len(set(F[i].tolist())) < 3:
            continue
        P = V[F[i]]
        fixed = [k for k in range(3) if P[0, k] == P[1, k] == P[2, k]]
        if len(fixed) != 1:
            continue
        a = fixed[0]
        u, w = (a + 1) % 3, (a + 2) % 3
        for r in range(3):
            R, p, q = P[r], P[(r + 1) % 3], P[(r + 2) % 3]
            if any(p_[w] == R[w] and p_[u] != R[u] and q_[u] == R[u] and q_[w] != R[w]
                   and not np.isnan(p_[u]) and not np.isnan(q_[w]) for p_, q_ in ((p, q), (q, p))):
                cand[i] = (a, r)
                break
    for g in sorted({int(grp[i]) for i in cand}):
        faces = [i for i in cand if grp[i] == g]
        if len(faces) < 2:
            continue
        verts = sorted(set(F[faces].ravel().tolist()))
        rank = [{x: t for t, x in enumerate(sorted(set(V[verts, k].tolist())))} for k in range(3)]
        cells = {}
        for i in faces:
            a, r = cand[i]
            P = V[F[i]]
            lo, hi = P.min(axis=0), P.max(axis=0)
            if not all(k == a or rank[k][hi[k]] == rank[k][lo[k]] + 1 for k in range(3)):
                continue
            key = (a,) + tuple(rank[k][lo[k]] for k in range(3))
            corner = tuple(bool(P[r, k] == hi[k]) for k in range(3) if k != a)
            cells.setdefault(key, []).append((i, corner))
        for lst in cells.values():
            if len(lst) == 1 or (len(lst) == 2 and all(x != y for x, y in zip(lst[0][1], lst[1][1]))):
                for i, _ in lst:
                    cg[i] = g
    return cg


def _lattice_mesh(rng, n_cells, n_groups=3, n_loose=0):
    """Random halves of the cells of an irregular grid (values per axis drawn from a coarse dyadic
    set), with planted trouble: a cell's complementary half (fine), the other diagonal's half and
    a face twice (overlaps), a rectangle over two intervals, a vertex between two grid lines, and
    ``n_loose`` faces between random grid points (crossing the lattice).
    Returns ``(V, F, groups)``; vertices are shared by position, now and then repeated."""
    grid = [np.sort(rng.choice(np.arange(0, 16) * 0.25, 6, replace=False)) for _ in range(3)]
    pts, faces, groups = [], [], []
    index = {}

    def vid(p):
        p = tuple(float(x) for x in p)
        if p not in index or rng.random() < 0.05:  # (now and then a repeated position)
            index[p] = len(pts)
            pts.append(p)
        return index[p]

    def half(a, c, lo, hi, corner):
        """The half of the rectangle ``lo..hi`` (two free axes) in plane ``x_a = c`` with its right
        angle at ``corner`` (bits: high end along the first, second free axis)."""
        u, w = (a + 1) % 3, (a + 2) % 3
        R = np.empty(3)
        R[a] = c
        R[u] = hi[0] if corner & 1 else lo[0]
        R[w] = hi[1] if corner & 2 else lo[1]
        P, Q = R.copy(), R.copy()
        P[u] = lo[0] if corner & 1 else hi[0]
        Q[w] = lo[1] if corner & 2 else hi[1]
        tri = [R, P, Q]
        rng.shuffle(tri)
        return [vid(x) for x in tri]

    for _ in range(n_cells):
        a = int(rng.integers(3))
        u, w = (a + 1) % 3, (a + 2) % 3
        c = rng.choice(grid[a])
        iu = int(rng.integers(len(grid[u]) - 2))
        iw = int(rng.integers(len(grid[w]) - 2))
        su = 2 if rng.random() < 0.08 else 1  # (a rectangle over two intervals)
        sw = 1
        lo = (grid[u][iu], grid[w][iw])
        hi = (grid[u][iu + su], grid[w][iw + sw])
        corner = int(rng.integers(4))
        g = int(rng.integers(-1, n_groups)) if rng.random() < 0.1 else int(a % n_groups)
        faces.append(half(a, c, lo, hi, corner))
        groups.append(g)
        roll = rng.random()
        if roll < 0.5:  # the other half along the same diagonal
            faces.append(half(a, c, lo, hi, corner ^ 3))
            groups.append(g)
        elif roll < 0.58:  # a half along the other diagonal: overlaps
            faces.append(half(a, c, lo, hi, corner ^ 1))
            groups.append(g)
        elif roll < 0.62:  # the same half again
            faces.append(half(a, c, lo, hi, corner))
            groups.append(g)
    grid_pts = np.array(np.meshgrid(*grid, indexing="ij")).reshape(3, -1).T
    for _ in range(n_loose):
        f = [vid(grid_pts[t]) for t in rng.choice(len(grid_pts), 3, replace=False)]
        faces.append(f)
        groups.append(int(rng.integers(-1, n_groups)))
    V = np.array(pts, dtype=float)
    if rng.random() < 0.5 and len(V):  # a value between two grid lines (the grid gains a line)
        V[int(rng.integers(len(V))), int(rng.integers(3))] += 0.125
    F = np.array(faces, dtype=np.int64).reshape(-1, 3)
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])
    return V, F[keep], np.array(groups, dtype=np.int64)[keep]


def _canon(V, F):
    return np.ascontiguousarray(canonical_vertices(V)[F], dtype=np.int64)


def _reference_pairs(V, F):
    """Every candidate pair tested in full (no stars, no in-plane shortcuts, no groups)."""
    Va, Fa = I._as_mesh_arrays(V, F)
    return I._pairs(Va, Fa, canonical_vertices(Va), 8, "grid", quick=False)


def test_certificate_equals_its_plain_form():
    rng = np.random.default_rng(129)
    certified = planted = 0
    for trial in range(80):
        V, F, G = _lattice_mesh(rng, int(rng.integers(5, 120)), int(rng.integers(1, 4)), int(rng.integers(0, 6)))
        Fc = _canon(V, F)
        got = I._lattice_cells(np.ascontiguousarray(V), Fc, G)
        want = _cells_reference(V, Fc, G)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(I._lattice_cells(np.ascontiguousarray(V), Fc, G.astype(np.int32)), want)
        certified += int((got >= 0).sum())
        planted += int(((got < 0) & (G >= 0)).sum())
    assert certified > 1000 and planted > 100  # (both outcomes met)


def test_a_group_number_past_the_bound_certifies_nothing():
    rng = np.random.default_rng(5)
    V, F, G = _lattice_mesh(rng, 60)
    Fc = _canon(V, F)
    assert (I._lattice_cells(V, Fc, G) >= 0).any()
    big = G.copy()
    big[0] = 8 * len(F) + 16
    assert (I._lattice_cells(V, Fc, big) < 0).all()
    np.testing.assert_array_equal(I._lattice_cells(V, Fc, big), _cells_reference(V, Fc, big))


@pytest.mark.parametrize("seed", range(6))
def test_no_certified_pair_intersects_and_the_pairs_are_the_same(seed):
    rng = np.random.default_rng(1000 + seed)
    met = inside = 0
    for trial in range(25):
        V, F, G = _lattice_mesh(rng, int(rng.integers(20, 200)), int(rng.integers(1, 4)), int(rng.integers(0, 12)))
        ref = _reference_pairs(V, F)
        Va, Fa = I._as_mesh_arrays(V, F)
        cg = I._lattice_cells(np.ascontiguousarray(Va), _canon(Va, Fa), G)
        if len(ref):
            a, b = cg[ref[:, 0]], cg[ref[:, 1]]
            assert not ((a >= 0) & (a == b)).any(), "a certified pair intersects"
            inside += int(((G[ref[:, 0]] == G[ref[:, 1]]) & (G[ref[:, 0]] >= 0)).sum())
        for method in ("auto", "grid", "slabs"):
            try:
                want = intersecting_pairs(V, F, method=method)
            except ValueError:
                with pytest.raises(ValueError):
                    intersecting_pairs(V, F, method=method, groups=G)
                continue
            np.testing.assert_array_equal(want, ref)
            np.testing.assert_array_equal(intersecting_pairs(V, F, method=method, groups=G), want)
        met += int((cg >= 0).sum())
    assert met > 100 and inside > 0  # (pairs crossing inside one group were found all the same)


def test_two_threads_same_pairs(monkeypatch):
    """A lattice mesh large enough for the split over two threads (the slab phase in ranges)."""
    rng = np.random.default_rng(77)
    V, F, G = _lattice_mesh(rng, 16000, 3, 40)
    V = V[:, [0, 1, 2]] * 1.0
    assert len(F) >= I._SPLIT_FACES
    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    want = intersecting_pairs(V, F)
    assert len(want) > 0
    monkeypatch.setenv("CONTOURMESH_THREADS", "2")
    np.testing.assert_array_equal(intersecting_pairs(V, F, groups=G), want)
    np.testing.assert_array_equal(intersecting_pairs(V, F), want)


def test_bad_groups_are_refused():
    V, F, G = _lattice_mesh(np.random.default_rng(3), 10)
    with pytest.raises(ValueError, match="groups"):
        intersecting_pairs(V, F, groups=G[:-1])
    with pytest.raises(ValueError, match="groups"):
        intersecting_pairs(V, F, groups=G.astype(float))


def _whole_tests(vol, spacing=None):
    """Each whole-mesh crossing test of the general mesher on ``vol``: ``(V, F, tags)``."""
    seen = []
    real = volumes._crossing_pairs

    def keep(V, F, previous, tags=None):
        if previous is None:
            seen.append((np.array(V), np.array(F), None if tags is None else np.array(tags)))
        return real(V, F, previous, tags)

    volumes._crossing_pairs = keep
    try:
        contourmesh.mesh(vol, **({} if spacing is None else {"spacing": spacing}))
    finally:
        volumes._crossing_pairs = real
    return seen


def _same_with_tags(V, F, T, reference=False):
    want = intersecting_pairs(V, F)
    np.testing.assert_array_equal(intersecting_pairs(V, F, groups=T), want)
    Fc = _canon(V, F)
    cg = I._lattice_cells(np.ascontiguousarray(V), Fc, np.ascontiguousarray(T, dtype=np.int64))
    # (int32 groups, as the volume mesher's tags, are taken as they are: the same cells)
    np.testing.assert_array_equal(I._lattice_cells(np.ascontiguousarray(V), Fc, np.ascontiguousarray(T, dtype=np.int32)), cg)
    if reference:
        np.testing.assert_array_equal(cg, _cells_reference(V, Fc, T))
    return want, int((cg >= 0).sum())


def test_the_general_meshers_meshes():
    rng = np.random.default_rng(16)
    certified = tested = 0
    for t in range(12):
        v = _volume(rng, t)
        if not v.any():
            continue
        for V, F, T in _whole_tests(v):
            assert T is not None and len(T) == len(F)
            _, n = _same_with_tags(V, F, T, reference=True)
            certified += n
            tested += 1
            # crossings put in: a few vertices moved
            W = V.copy()
            W[rng.integers(len(W), size=3)] += rng.uniform(-1.5, 1.5, (3, 3))
            _same_with_tags(W, F, T)
    assert tested >= 8 and certified > 500


def test_the_lobsters_first_build(shared_data):
    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    seen = _whole_tests(np.transpose(z["volume"], (2, 1, 0)) > 60)
    V, F, T = seen[0]
    want, n = _same_with_tags(V, F, T)
    assert len(F) > 300_000 and len(want) > 0 and n > len(F) // 2
    np.testing.assert_array_equal(want, _reference_pairs(V, F))


def test_a_liver_label(shared_data):
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == 85)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == 85
    seen = _whole_tests(crop, tuple(float(s) for s in z["spacing_xyz"][::-1]))
    for V, F, T in seen:
        _, n = _same_with_tags(V, F, T, reference=len(F) < 60_000)
        assert n > 0
        W = V.copy()
        W[np.random.default_rng(85).integers(len(W), size=5)] += 2.0  # crossings put in
        want = _same_with_tags(W, F, T)[0]
        assert len(want) > 0


def test_groups_of_any_integer_dtype_give_the_same_pairs():
    """``groups`` is taken as it is where int32 (the general mesher's tags), else made int64, where
    the broad phase's certificate is computed (not held through the broad phase): int32 tags, int64
    and a strided view give the same pairs, with the groups and without."""
    V, F, G = _lattice_mesh(np.random.default_rng(41), 3000, 3, 20)
    want = intersecting_pairs(V, F)
    assert len(want) > 0
    G64 = np.asarray(G, dtype=np.int64)
    strided = np.repeat(G64, 2)[::2]
    for g in (G64, G64.astype(np.int32), strided):
        np.testing.assert_array_equal(intersecting_pairs(V, F, groups=g), want)


def test_the_slab_phase_with_groups_certifies_no_stars(monkeypatch):
    """With groups the slab phase gets a star count that never comes due (``_SLAB_STARS``), and
    certifies no star; the pairs are those with the stars certified and those without groups, on
    the general mesher's meshes (tested by slabs) with crossings put in."""
    rng = np.random.default_rng(146)
    meshes = []  # (made first: the mesher's compiled kernels read the names patched below)
    for t in range(8):
        v = _volume(rng, t)
        if v.any():
            meshes += _whole_tests(v)
    monkeypatch.setattr(I, "_GRID_FACES", 0)  # (every mesh by slabs where sectioned)
    real = I._slab_pairs
    seen = []

    def spy(V, ws, F, star, sst, *rest):
        due = int(sst[0])
        out = real(V, ws, F, star, sst, *rest)
        seen.append((due, int(star.sum())))
        return out

    monkeypatch.setattr(I, "_slab_pairs", spy)
    met = found = 0
    for V, F, T in meshes:
        W = V.copy()
        W[rng.integers(len(W), size=3)] += rng.uniform(-1.5, 1.5, (3, 3))
        for X in (V, W):
            want = intersecting_pairs(X, F)
            seen.clear()
            got = intersecting_pairs(X, F, groups=T)
            np.testing.assert_array_equal(got, want)
            assert all(due == -1 and n == 0 for due, n in seen)
            by_slabs = len(seen) > 0  # (else not sectioned: the grid)
            monkeypatch.setattr(I, "_SLAB_STARS", True)
            seen.clear()
            np.testing.assert_array_equal(intersecting_pairs(X, F, groups=T), want)
            assert all(due == 0 for due, _ in seen) and (len(seen) > 0) == by_slabs
            monkeypatch.setattr(I, "_SLAB_STARS", False)
            met += by_slabs
            found += by_slabs and len(want) > 0
    assert met >= 6 and found >= 2, (met, found)


def _collinear(V, f):
    """Face ``f``'s corners on one line (exactly: the cross product in rationals)."""
    from fractions import Fraction

    p, q, r = ([Fraction(float(x)) for x in V[v]] for v in f)
    u = [q[k] - p[k] for k in range(3)]
    w = [r[k] - p[k] for k in range(3)]
    return all(u[(k + 1) % 3] * w[(k + 2) % 3] == u[(k + 2) % 3] * w[(k + 1) % 3] for k in range(3))


@pytest.mark.parametrize("seed", range(4))
def test_certified_faces_are_never_collinear(seed):
    """The grid's first pass takes a certified face as not collinear without the orientation tests
    (issue 16, round 24): the property it rests on, on lattice meshes with collinear faces put into
    the groups (three grid points along a line, corners repeated by position), and the pairs with
    groups on the grid equal to those without (every pair tested in full)."""
    rng = np.random.default_rng(2400 + seed)
    certified = collinear = 0
    for trial in range(20):
        V, F, G = _lattice_mesh(rng, int(rng.integers(20, 150)), int(rng.integers(1, 4)), int(rng.integers(0, 8)))
        # faces along a line of the lattice: a corner pair or the three points of an axis line
        extra, groups = [], []
        m = len(F)
        for _ in range(int(rng.integers(1, 8))):
            a, b = rng.choice(m, 2, replace=False)
            p, q = V[F[a, 0]], V[F[b, 1]]
            k = int(rng.integers(3))
            r = p.copy()
            r[k] = q[k]
            s = (p + r) / 2.0
            base = len(V) + 3 * len(extra)
            extra.append(np.stack([p, r, s]))
            groups.append(int(G[a]) if rng.random() < 0.8 else -1)
            F = np.vstack([F, [[base, base + 1, base + 2]]])
        V = np.vstack([V] + extra)
        G = np.concatenate([G, np.array(groups, np.int64)])
        Fc = _canon(V, F)
        cg = I._lattice_cells(np.ascontiguousarray(V), Fc, G)
        for i in np.flatnonzero(cg >= 0):
            assert not _collinear(V, F[i]), "a certified face is collinear"
        certified += int((cg >= 0).sum())
        collinear += sum(_collinear(V, f) for f in F[G >= 0])
        np.testing.assert_array_equal(intersecting_pairs(V, F, method="grid", groups=G), _reference_pairs(V, F))
    assert certified > 500 and collinear > 20  # (both kinds of face met)


@njit(cache=False)
def _plane_answers(V, ws, pu, pw, eg, k):
    """Whether the parts ``pu - pw`` at plane ``k`` form an embedded planar graph, by
    ``_plane_embedded`` (every pair of parts) and by ``_plane_embedded_g`` with the parts' faces'
    groups ``eg`` (fresh workspaces, no work limit)."""
    ne = len(pu)
    out = np.zeros(2, np.int64)
    for r in range(2):
        stamp = np.full(len(V), -1, np.int32)
        d1 = np.empty(len(V), np.int32)
        d2 = np.empty(len(V), np.int32)
        xlo, xhi, ylo, yhi = part_boxes(V, pu, pw)
        cert = np.empty(ne, np.int32)
        all2 = np.full(ne, 2, np.int8)
        ci = np.empty(16, np.int64)
        cj = np.empty(16, np.int64)
        if r == 0:
            emb, _, _, _ = I._plane_embedded(V, ws, xlo, xhi, ylo, yhi, pu, pw, np.int64(ne), k, stamp, d1, d2,
                                             cert, all2, ci, cj, np.int64(0), np.int64(1 << 40))
        else:
            emb, _, _, _ = I._plane_embedded_g(V, ws, xlo, xhi, ylo, yhi, pu, pw, np.int64(ne), k, stamp, d1, d2,
                                               cert, all2, eg, ci, cj, np.int64(0), np.int64(1 << 40))
        out[r] = 1 if emb else 0
    return out


@pytest.mark.parametrize("seed", range(3))
def test_plane_parts_of_one_group_never_fail_the_plane(seed):
    """The slab phase's plane check (``_plane_embedded_g``) leaves out the pairs of parts whose
    faces are certified in one group: on the lattice meshes (with their planted overlaps and loose
    faces) every plane gets the same answer as with every pair checked, planes that fail included."""
    rng = np.random.default_rng(2000 + seed)
    planes = failed = grouped = 0
    for trial in range(30):
        V, F, G = _lattice_mesh(rng, int(rng.integers(20, 300)), int(rng.integers(1, 4)), int(rng.integers(0, 8)))
        Va = np.ascontiguousarray(V, dtype=np.float64)
        Fc = _canon(Va, F)
        cg = I._lattice_cells(Va, Fc, G)
        ws = np.zeros(1 + 3 * I._EXP_LEN)
        ws[0] = 1.0 if I._on_small_dyadic_grid(Va) else 0.0
        lev, nlev = I._levels(np.ascontiguousarray(Va[:, 2]))
        L = lev[Fc]
        lo, hi = L.min(1), L.max(1)
        for k in range(nlev):
            # the parts of the faces ending or starting at plane k, in the order of their numbers
            sel = np.flatnonzero((lo < hi) & ((lo == k) | (hi == k)))
            if len(sel) < 2:
                continue
            on = L[sel] == k
            big = np.iinfo(np.int64).max
            pu = np.where(on, Fc[sel], big).min(1)
            pw = np.where(on, Fc[sel], -1).max(1)
            eg = cg[sel].astype(np.int64)
            got = _plane_answers(Va, ws, pu, pw, eg, np.int64(k))
            assert got[0] == got[1], (seed, trial, k)
            planes += 1
            failed += int(got[0] == 0)
            grouped += int(np.bincount(eg[eg >= 0]).max(initial=0) >= 2)
    assert planes > 100 and failed > 0 and grouped > 50


def test_small_meshes_with_groups_take_the_slab_phase(monkeypatch):
    """``auto`` with groups sends a small sectioned mesh off the dyadic grid (fewer than
    ``_GRID_FACES`` faces: the grid's without groups) to the slab phase; the pairs are the grid's,
    with the groups and without, also with crossings put in; a mesh that is not sectioned still
    goes to the grid."""
    rng = np.random.default_rng(182)
    meshes = []  # (made first: the mesher's compiled kernels read the names patched below)
    for t in range(8):
        v = _volume(rng, t)
        if v.any():
            meshes += _whole_tests(v)
    calls = []
    real = I._slab_pairs
    monkeypatch.setattr(I, "_slab_pairs", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    by_slabs = found = 0
    for V, F, T in meshes:
        W = V.copy()
        W[rng.integers(len(W), size=3)] += rng.uniform(-1.5, 1.5, (3, 3))
        for X in (V, W):
            if I._on_small_dyadic_grid(X) or len(F) >= I._GRID_FACES:
                continue
            want = intersecting_pairs(X, F, method="grid")
            calls.clear()
            assert len(intersecting_pairs(X, F)) == len(want) and not calls  # (without groups: the grid)
            got = intersecting_pairs(X, F, groups=T)
            np.testing.assert_array_equal(got, want)
            np.testing.assert_array_equal(intersecting_pairs(X, F, groups=T, method="grid"), want)
            by_slabs += len(calls) > 0
            found += len(calls) > 0 and len(want) > 0
    assert by_slabs >= 6 and found >= 2, (by_slabs, found)
    # a mesh whose faces span many slabs (heights spread out): the grid, the same pairs
    V, F, T = meshes[0]
    X = V + rng.uniform(-0.3, 0.3, V.shape)
    calls.clear()
    np.testing.assert_array_equal(intersecting_pairs(X, F, groups=T), intersecting_pairs(X, F, method="grid"))
    assert not calls
