"""Issue 13 (cost of the check): the broad phase by slabs and planes (``method="slabs"``) must give
exactly the pairs of the general grid (``method="grid"``) on our own meshes, on our meshes with
crossings put in, and on random meshes with the sectioned structure; ``mesh_checks``' compiled
counts must equal the plain numpy ones.  The search that stops at the first pair
(``any_intersecting``, issue 14) must answer as the whole list does."""

import numpy as np
import pytest
from scipy import ndimage

import contourmesh
from contourmesh.intersect import _as_mesh_arrays, _pairs, any_intersecting, canonical_vertices, intersecting_pairs
from contourmesh.measure import _components, _edge_counts, mesh_checks, mesh_volume, triangle_areas


def _sectioned(V, F):
    li = np.searchsorted(np.unique(V[:, 2]), V[F, 2])
    return int((li.max(1) - li.min(1)).sum()) <= 4 * len(F) + 1000


def _same(V, F, *, expect_slabs=None):
    grid = intersecting_pairs(V, F, method="grid")
    if expect_slabs is None:
        expect_slabs = _sectioned(V, F)
    if expect_slabs:
        slabs = intersecting_pairs(V, F, method="slabs")
        assert np.array_equal(slabs, grid), (len(slabs), len(grid))
    assert np.array_equal(intersecting_pairs(V, F), grid)  # auto
    # the search that stops at its first pair: a pair of the whole list, and one exactly when the
    # list has one (by each broad phase)
    assert any_intersecting(V, F) == (len(grid) > 0)
    Va, Fa = _as_mesh_arrays(V, F)
    for method in ("grid", "slabs") if expect_slabs else ("grid",):
        first = _pairs(Va, Fa, canonical_vertices(Va), 8, method, stop=1)
        assert len(first) == min(1, len(grid))
        assert all(tuple(p) in set(map(tuple, grid.tolist())) for p in first.tolist())
    return len(grid)


def test_levels_equal_np_unique():
    # the heights' ranks of the slab phase, compiled: np.unique's inverse and count (equal heights,
    # -0.0 and 0.0 among them, share a level; a NaN height is left to np.unique); heights in
    # order take one pass without the sort
    from contourmesh.intersect import _levels

    rng = np.random.default_rng(8)
    for t in range(300):
        n = int(rng.integers(0, 40))
        z = rng.integers(-3, 4, n) * 0.5 if t % 2 else rng.normal(size=n)
        if n and t % 5 == 0:
            z[rng.integers(n)] = -0.0
        if t % 3 == 0:  # heights in order (the one-pass case), -0.0 and 0.0 in either order
            z = np.sort(z)
            if n and t % 4 == 0:
                z[z == 0] = rng.choice([-0.0, 0.0], int(np.count_nonzero(z == 0)))
        elif t % 3 == 1:  # runs of equal heights out of order (rings' points): the runs' heights sorted
            z = np.repeat(z, rng.integers(1, 6, n))
            z[z == 0] = rng.choice([-0.0, 0.0], int(np.count_nonzero(z == 0)))
        levels, inv = np.unique(z, return_inverse=True)
        lev, nlev = _levels(np.ascontiguousarray(z, dtype=np.float64))
        assert nlev == len(levels) and np.array_equal(lev, inv.reshape(-1))
    assert _levels(np.array([1.0, np.nan, 2.0]))[1] == -1


def _volumes(rng, n):
    for t in range(n):
        if t % 3 == 0:  # a smoothed noise blob
            v = ndimage.gaussian_filter(rng.random((9, 11, 12)), 1.2) > 0.5
        elif t % 3 == 1:  # sparse voxels with edge and corner contacts
            v = rng.random((6, 7, 8)) < 0.25
        else:  # boxes touching each other
            v = np.zeros((8, 9, 9), bool)
            for _ in range(3):
                z, y, x = rng.integers(0, 6, 3)
                v[z:z + rng.integers(1, 4), y:y + rng.integers(1, 5), x:x + rng.integers(1, 5)] = True
        if v.any():
            yield np.pad(v, 1)


def _our_meshes(seed=0, n=12):
    rng = np.random.default_rng(seed)
    for v in _volumes(rng, n):
        for kw in ({}, {"polygon": "none"}):
            m = contourmesh.mesh(v, **kw)
            yield m.vertices.copy(), m.faces.copy()


def test_our_meshes_give_the_same_pairs_by_slabs():
    n = sectioned = 0
    for V, F in _our_meshes():
        _same(V, F)
        n += 1
        sectioned += _sectioned(V, F)
    assert n >= 16 and 4 * sectioned >= 3 * n, (n, sectioned)


def test_our_meshes_with_crossings_put_in():
    # a vertex moved far within its plane (the structure stays, its faces sweep through others),
    # or to the height of a neighbour plane where that keeps every face within two heights
    rng = np.random.default_rng(5)
    found = moved_z = 0
    for V, F in _our_meshes(seed=1, n=10):
        if not _sectioned(V, F):
            continue
        levels = np.unique(V[:, 2])
        for _ in range(4):
            W = V.copy()
            v = int(rng.integers(len(W)))
            if rng.random() < 0.5:
                W[v, :2] += rng.uniform(-3, 3, 2)
                found += _same(W, F) > 0
            else:
                k = int(np.searchsorted(levels, W[v, 2]))
                k2 = k + (1 if rng.random() < 0.5 else -1)
                if not 0 <= k2 < len(levels):
                    continue
                W[v, 2] = levels[k2]
                structured = _sectioned(W, F)
                found += _same(W, F) > 0
                moved_z += structured
    assert found >= 10 and moved_z >= 5, (found, moved_z)


def _random_sectioned(rng, n_levels, n_vertices, n_faces, flat_share):
    """Random faces whose corners lie on ``n_levels`` heights, each flat or spanning one slab
    between consecutive heights (some two or three), on a coarse dyadic grid (many touching,
    collinear, coplanar and shared cases)."""
    z = np.sort(rng.choice(np.arange(0, 3 * n_levels) * 0.5, n_levels, replace=False))
    lev = rng.integers(0, n_levels, n_vertices)
    V = np.c_[rng.integers(0, 6, (n_vertices, 2)) * 0.5, z[lev]]
    by_level = [np.flatnonzero(lev == k) for k in range(n_levels)]
    F = []
    while len(F) < n_faces:
        k = int(rng.integers(n_levels))
        if rng.random() < flat_share:
            pool = by_level[k]
        else:  # over one slab, or now and then two or three (faces through a plane)
            span = 1 + int(rng.integers(3) * (rng.random() < 0.3))
            if k + span >= n_levels:
                continue
            pool = np.concatenate(by_level[k:k + span + 1])
        if len(pool) < 3:
            continue
        f = rng.choice(pool, 3, replace=False)
        if len(set(lev[f])) == 1 and pool is not by_level[k]:
            continue
        F.append(f)
    return V.astype(float), np.array(F)


@pytest.mark.parametrize("flat_share", [0.0, 0.3])
def test_random_sectioned_meshes(flat_share):
    rng = np.random.default_rng(11)
    hits = 0
    for _ in range(60):
        V, F = _random_sectioned(rng, int(rng.integers(2, 6)), 30, 40, flat_share)
        hits += _same(V, F, expect_slabs=True) > 0
        # not on the dyadic grid: the exact predicates' other branch
        _same(V * 0.1 + 0.37, F, expect_slabs=True)
    assert hits >= 30


def test_random_unsectioned_meshes_fall_back_to_the_grid():
    rng = np.random.default_rng(2)
    V = rng.uniform(0, 4, (2000, 3))  # every vertex at its own height
    F = rng.integers(0, 2000, (300, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    with pytest.raises(ValueError, match="sections"):
        intersecting_pairs(V, F, method="slabs")
    assert np.array_equal(intersecting_pairs(V, F), intersecting_pairs(V, F, method="grid"))
    with pytest.raises(ValueError, match="method"):
        intersecting_pairs(V, F, method="bvh")


def test_plane_where_ring_edges_cross():
    # two prisms between z = 0 and z = 1 whose bottom edges cross in z = 0 (the planar graph there
    # is not embedded), and whose slab faces cross: all found, by slabs as by the grid
    a = np.array([[0, 0, 0], [2, 0, 0], [1, 2, 0], [0, 0, 1], [2, 0, 1], [1, 2, 1.0]])
    b = a + [1, -1, 0]
    b[:, 1] *= -1
    V = np.vstack([a, b])
    side = [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]]
    F = np.array(side + [[i + 6, j + 6, k + 6] for i, j, k in side] + [[0, 2, 1], [6, 8, 7], [3, 4, 5], [9, 11, 10]])
    n = _same(V, F)
    assert n > 0
    # the same prisms one above the other meet only in z = 1, in the crossing edges there
    b2 = b.copy()
    b2[:, 2] += 1
    n2 = _same(np.vstack([a, b2]), F)
    assert 0 < n2 < n


def test_mesh_checks_counts_match_numpy():
    rng = np.random.default_rng(4)
    for t in range(80):
        V = rng.integers(0, 4, (20, 3)) * 0.5
        F = rng.integers(0, 20, (int(rng.integers(1, 30)), 3))
        if t % 4 == 0:  # a closed mesh, sometimes with a duplicated vertex or face
            m = contourmesh.mesh(np.pad(rng.random((4, 4, 4)) < 0.5, 1))
            V, F = m.vertices.copy(), m.faces.copy()
            if t % 8 == 0:
                V = np.vstack([V, V[F[0, 0]]])
                F = np.vstack([F, F[:1]])
                F[-1, 0] = len(V) - 1
        chk = mesh_checks(V, F)
        uniq, counts, dup_directed = _edge_counts(F)
        used = np.unique(F)
        assert chk["boundary_edges"] == int((counts == 1).sum())
        assert chk["nonmanifold_edges"] == int((counts > 2).sum())
        assert chk["winding_consistent"] == (dup_directed == 0)
        assert chk["watertight"] == bool(np.all(counts == 2))
        assert chk["components"] == _components(len(V), F)
        assert chk["duplicate_vertices"] == len(used) - len(np.unique(V[used], axis=0))
        diag2 = float(np.sum((V.max(0) - V.min(0)) ** 2)) or 1.0
        rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
        assert chk["degenerate_faces"] == int((rep | (triangle_areas(V, F) <= 1e-12 * diag2)).sum())
        assert chk["volume"] == pytest.approx(mesh_volume(V, F), rel=1e-12, abs=1e-12)
        assert chk["self_intersections"] == len(intersecting_pairs(V, F, method="grid"))


def _twisted_tube(shifts, ring=((3, 1), (1, 3), (-1, 3), (-3, 1), (-3, -1), (-1, -3), (1, -3), (3, -1)), caps=True):
    """A closed tube through the planes z = 0, 1, ..: the ring of plane k turned by ``shifts[k]``
    places against the one below (0: a prism; half the ring: the band passes through the axis)."""
    ring = np.asarray(ring, float)
    n = len(ring)
    V, F, turn = [], [], 0
    for k in range(len(shifts) + 1):
        V += [(x, y, float(k)) for x, y in ring]
    for k, s in enumerate(shifts):
        turn += s
        b, t = k * n, (k + 1) * n
        for i in range(n):
            F.append([b + i, b + (i + 1) % n, t + (i + 1) % n])
            F.append([b + i, t + (i + 1) % n, t + i])
        # the ring above reindexed: the vertex above i is the ring's (i + turn)
        V[t:t + n] = [V[t + (i + turn) % n] for i in range(n)]
    if caps:
        top = len(shifts) * n
        F += [[0, i + 1, i] for i in range(1, n - 1)] + [[top, top + i, top + i + 1] for i in range(1, n - 1)]
    return np.array(V), np.array(F)


@pytest.mark.parametrize("shifts, crossing", [((0, 0, 0), False), ((1, 0, 2), False), ((0, 0, 7), False),
                                              ((0, 4, 0), True), ((3, 0, 0), True)])
def test_twisted_tubes(shifts, crossing):
    # embedded bands (decided by the slab certificate) and bands turned far enough to pass through
    # the axis or fold (decided pair by pair): the same pairs as the grid
    V, F = _twisted_tube(shifts)
    n = _same(V, F, expect_slabs=True)
    assert (n > 0) == crossing, n
    _same(V * 0.3 + 0.1, F, expect_slabs=True)  # off the dyadic grid: no certificate, pair by pair


def _pairs_on_one_and_two_threads(monkeypatch, V, F, **settings):
    """``intersecting_pairs(V, F)`` with ``CONTOURMESH_THREADS`` 1, then 2 with the two-thread split
    taken from 100 faces on (and ``settings``: other module constants of ``intersect``); returns
    ``(one, two, calls)``, ``calls`` the split's results."""
    import contourmesh.intersect as I

    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    one = intersecting_pairs(V, F)
    calls = []
    real = I._split_slab_pairs
    monkeypatch.setattr(I, "_split_slab_pairs", lambda *a: calls.append(real(*a)) or calls[-1])
    monkeypatch.setattr(I, "_SPLIT_FACES", 100)
    for name, value in settings.items():
        monkeypatch.setattr(I, name, value)
    monkeypatch.setenv("CONTOURMESH_THREADS", "2")
    return one, intersecting_pairs(V, F), calls


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_thread_split_gives_the_one_call_pairs(seed, monkeypatch):
    """With ``CONTOURMESH_THREADS=2`` a large sectioned mesh is tested in two ranges of height
    levels on two threads (issue 16): the pairs must be those of one call, in the same order,
    including pairs of faces through the middle level and faces lying flat in it."""

    rng = np.random.default_rng(seed)
    nl, per = 14, 300
    V = np.c_[rng.random((nl * per, 2)) * 40, np.repeat(np.arange(nl), per).astype(float)]
    F = []
    for k in range(nl - 1):  # thin faces between consecutive levels, some spanning two gaps
        a = rng.integers(0, per, 250) + k * per
        b = a + rng.integers(1, 4, 250)
        b = np.where(b < (k + 1) * per, b, a - 1)
        up = min(k + 1 + int(rng.integers(1, 3)), nl - 1) if k % 3 == 0 else k + 1
        c = rng.integers(0, per, 250) + up * per
        F.append(np.c_[a, b, c])
    flat = rng.integers(0, per, (40, 3)) + (nl // 2) * per  # flat faces in the middle level
    F = np.concatenate(F + [flat[(flat[:, 0] != flat[:, 1]) & (flat[:, 1] != flat[:, 2]) & (flat[:, 0] != flat[:, 2])]])
    one, two, calls = _pairs_on_one_and_two_threads(monkeypatch, V, F)
    assert len(one) > 50
    assert len(calls) == 1 and calls[0] is not None and np.array_equal(two, one)
    assert np.array_equal(intersecting_pairs(V, F, method="grid"), one)



def test_slab_pairs_over_ranges_of_planes_partition_the_pairs():
    """``_slab_pairs`` over the planes ``k0 .. k1 - 1`` (and the slabs below them) finds the pairs
    decided there: over any partition of the levels into ranges the lists are disjoint and their
    union is the whole call's list (faces spanning several slabs, flat faces, touching and
    coplanar cases), with and without the quick decisions; the grid agrees."""
    from contourmesh.intersect import _EXP_LEN, _SLAB_BUDGET, _levels, _on_small_dyadic_grid, _slab_pairs, canonical_vertices

    rng = np.random.default_rng(41)
    checked = 0
    for trial in range(60):
        V, F = _random_sectioned(rng, int(rng.integers(3, 9)), 30, int(rng.integers(10, 60)), 0.2)
        Fc = canonical_vertices(V)[F]  # (the kernels take canonical vertex indices)
        lev, nlev = _levels(np.ascontiguousarray(V[:, 2]))
        ws0 = np.zeros(1 + 3 * _EXP_LEN)
        ws0[0] = 1.0 if _on_small_dyadic_grid(V) else 0.0
        i64 = np.int64

        def run(k0, k1, quick):
            sst = np.array([0 if quick else -1, len(Fc) // 8 + 100], np.int64)
            pi, pj, ok = _slab_pairs(V, ws0.copy(), Fc, np.zeros(len(V), np.int8), sst, i64(quick), lev, i64(nlev),
                                     i64(_SLAB_BUDGET), i64(0), i64(k0), i64(k1), np.zeros(0, np.int64))
            assert ok == 1
            return sorted(zip(pi.tolist(), pj.tolist()))

        for quick in (1, 0):
            whole = run(0, nlev, quick)
            cuts = sorted(set(rng.integers(1, nlev, int(rng.integers(1, 4))).tolist())) if nlev > 1 else []
            bounds = [0] + cuts + [nlev]
            parts = [run(a, b, quick) for a, b in zip(bounds[:-1], bounds[1:])]
            union = sorted(p for part in parts for p in part)
            assert union == whole, (trial, bounds)
            assert len(set(union)) == len(union)
        assert [tuple(p) for p in intersecting_pairs(V, F, method="grid").tolist()] == whole
        checked += len(whole) > 0
    assert checked > 20


def test_any_intersecting_in_one_call_on_any_arrays():
    """``any_intersecting`` runs _pairs' steps in one compiled call: the same answer as the whole
    list, for read-only, Fortran-ordered and float32/int32 inputs too (converted first, so one
    compiled signature serves them all)."""
    import trimesh

    rng = np.random.default_rng(29)
    seen = set()
    s = trimesh.creation.icosphere(1)
    meshes = [(np.asarray(s.vertices, float), np.asarray(s.faces))]  # none cross
    meshes += [_random_sectioned(rng, int(rng.integers(2, 5)), 20, int(rng.integers(2, 25)), 0.2) for _ in range(30)]
    for V, F in meshes:
        want = len(intersecting_pairs(V, F)) > 0
        seen.add(want)
        Vr, Fr = V.copy(), F.copy()
        Vr.flags.writeable = False
        Fr.flags.writeable = False
        for Vx, Fx in ((V, F), (Vr, Fr), (np.asfortranarray(V), np.asfortranarray(F)),
                       (V.astype(np.float32).astype(np.float64), F.astype(np.int32))):
            assert any_intersecting(Vx, Fx) == want
    assert seen == {True, False}
    from numba.core.registry import CPUDispatcher

    from contourmesh import intersect
    assert len(intersect._any_kernel_seen.signatures) == 1  # (any_intersecting's entry)
    assert isinstance(intersect._any_kernel_seen, CPUDispatcher)


def test_range_stars_are_the_whole_meshs_stars_and_the_split_pairs_the_one_calls(monkeypatch):
    """A range of heights certifies the stars of its own vertices only (``_star_fill_levels``,
    issue 16: ranges on two threads no longer each certify the whole mesh's): those stars are the
    whole mesh's at those levels, and two overlapping closed sectioned meshes tested in ranges on
    two threads give the one call's pairs."""
    import contourmesh
    import contourmesh.intersect as I

    zz, yy, xx = np.mgrid[:14, :24, :24]
    ball = (zz - 6.5) ** 2 + (yy - 11.5) ** 2 + (xx - 11.5) ** 2 < 36
    m = contourmesh.mesh(ball | np.roll(ball, 5, axis=2))
    V = np.concatenate([m.vertices, m.vertices + [2.25, 1.5, 0.0]])
    F = np.concatenate([m.faces, m.faces + len(m.vertices)])
    Fc = I.canonical_vertices(V)[F]
    lev, nlev = I._levels(np.ascontiguousarray(V[:, 2]))
    whole = I._star_certified(V, Fc)
    assert whole.sum() > len(V) // 2
    for l0, l1 in [(0, 3), (2, 7), (5, nlev - 1), (0, nlev - 1)]:
        part = I._star_certified(V, Fc, lev, l0, l1)
        inside = (lev >= l0) & (lev <= l1)
        assert np.array_equal(part[inside], whole[inside]) and not part[~inside].any()
    one, two, calls = _pairs_on_one_and_two_threads(monkeypatch, V, F, _STAR_DELAY=0)  # (stars certified early)
    assert len(one) > 20
    assert len(calls) == 1 and calls[0] is not None and np.array_equal(two, one)
