"""Issue 16 (speed on real segmentations): a rebuild after a crossing fallback reuses the bridged
joins it can and tests only the faces that changed; the meshes and the crossing pairs stay the
same as when everything is built and checked again.  The optimal band that bridged joins retry on
folded bands is bounded in time (a window of start points)."""

import numpy as np
import pytest
import trimesh
from scipy import ndimage

import contourmesh
from contourmesh import volumes
from contourmesh.intersect import intersecting_pairs
from contourmesh.repair import crossing_pairs_after_change


def _blob(seed, shape=(10, 24, 24)):
    rng = np.random.default_rng(seed)
    return ndimage.gaussian_filter(rng.random(shape), 1.2) > 0.5


# a blob whose mesh needs a crossing fallback, with bridged joins on both sides of it
BLOB_WITH_FALLBACK = 18


def _two_spheres():
    a = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    b = trimesh.creation.icosphere(subdivisions=2, radius=0.8)
    V = np.concatenate([a.vertices, b.vertices + [0.9, 0.1, 0.05]])
    F = np.concatenate([a.faces, b.faces + len(a.vertices)])
    return V, F


@pytest.mark.parametrize("seed", range(4))
def test_pairs_after_change_equal_the_whole_check(seed):
    rng = np.random.default_rng(seed)
    V0, F0 = _two_spheres()
    p0 = intersecting_pairs(V0, F0)
    assert len(p0) > 0  # the spheres cross: there are old pairs to carry over
    V1, F1 = V0.copy(), F0.copy()
    # some vertices move (their faces change), a face is repeated (it overlaps itself), the faces
    # are shuffled and the vertices renumbered
    moved = rng.choice(len(V1), 12, replace=False)
    V1[moved] += rng.normal(scale=0.15, size=(12, 3))
    F1 = np.concatenate([F1, F1[rng.integers(len(F1))][None, ::-1]])
    F1 = F1[rng.permutation(len(F1))]
    perm = rng.permutation(len(V1))
    V1 = V1[np.argsort(perm)]
    F1 = perm[F1]
    got = crossing_pairs_after_change(V0, F0, p0, V1, F1)
    want = intersecting_pairs(V1, F1)
    assert len(want) > 0
    np.testing.assert_array_equal(got, want)


def test_pairs_after_change_of_an_unchanged_mesh_are_the_old_ones():
    V0, F0 = _two_spheres()
    p0 = intersecting_pairs(V0, F0)
    np.testing.assert_array_equal(crossing_pairs_after_change(V0, F0, p0, V0, F0), p0)
    # a mesh whose pairs are all gone after the change (the second sphere moved away)
    V1 = V0.copy()
    V1[len(trimesh.creation.icosphere(subdivisions=2).vertices):] += [5.0, 0, 0]
    assert len(crossing_pairs_after_change(V0, F0, p0, V1, F0)) == 0 == len(intersecting_pairs(V1, F0))


def test_rebuilds_check_the_same_pairs_and_reuse_bridged_joins(monkeypatch):
    # (on undensified rings: with a vertex every pixel on the branching joins' polygons this
    # volume's faces no longer cross, and there is no rebuild to test)
    monkeypatch.setattr(volumes, "_DENSE_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", None)
    v = _blob(BLOB_WITH_FALLBACK)
    checks = []
    whole = volumes._crossing_pairs

    def crossing_pairs(V, F, previous, tags=None):
        got = whole(V, F, previous, tags)
        checks.append(previous is not None)
        np.testing.assert_array_equal(got, intersecting_pairs(V, F))
        return got

    calls = []
    join = volumes._bridge_join

    def bridge_join(*args, **kw):
        calls.append(args[:3])
        return join(*args, **kw)

    monkeypatch.setattr(volumes, "_crossing_pairs", crossing_pairs)
    monkeypatch.setattr(volumes, "_bridge_join", bridge_join)
    m = contourmesh.mesh(v)
    assert m.meta["crossing_fallbacks"] > 0 and m.meta["bridged_joins"] > 0
    assert m.meta["self_intersections"] == 0 and m.checks()["ok"]
    assert checks[0] is False and any(checks[1:])  # a rebuild was checked from the first build
    cached_calls = len(calls)

    # the same mesh when every rebuild builds every bridged join again
    build = volumes._build_bridges
    monkeypatch.setattr(volumes, "_build_bridges", lambda *a, **k: build(*a[:9], None, **k))
    calls.clear()
    m2 = contourmesh.mesh(v)
    assert cached_calls < len(calls)
    np.testing.assert_array_equal(m.vertices, m2.vertices)
    np.testing.assert_array_equal(m.faces, m2.faces)



def test_rebuilds_reuse_unchanged_joins_and_caps_and_make_the_same_mesh(monkeypatch):
    """Issue 16: a rebuild makes again only the joins and caps whose kind or rings changed; the
    mesh is the one made when every rebuild makes every join and cap again."""
    # (on undensified rings: with a vertex every pixel on the branching joins' polygons this
    # volume's faces no longer cross, and there is no rebuild to test)
    monkeypatch.setattr(volumes, "_DENSE_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", None)
    v = _blob(BLOB_WITH_FALLBACK)
    made = []
    record = volumes._Unit.record.__func__

    def counted(cls, key, *args):
        made.append(key[0])
        return record(cls, key, *args)

    monkeypatch.setattr(volumes._Unit, "record", classmethod(counted))
    m = contourmesh.mesh(v)
    assert m.meta["crossing_fallbacks"] > 0 and m.checks()["ok"]
    reused = len(made)
    assemble = volumes._assemble
    monkeypatch.setattr(volumes, "_assemble", lambda *a: assemble(*a[:14], None))
    made.clear()
    m2 = contourmesh.mesh(v)
    assert reused < len(made)  # the rebuild made fewer units than the whole mesh
    np.testing.assert_array_equal(m.vertices, m2.vertices)
    np.testing.assert_array_equal(m.faces, m2.faces)
    assert m.meta == m2.meta

def _ring(n, r, z, phase=0.0, wobble=0.0):
    t = phase + 2 * np.pi * np.arange(n) / n
    rr = r * (1 + wobble * np.sin(5 * t))
    return np.c_[rr * np.cos(t), rr * np.sin(t), np.full(n, z)]


def test_bounded_optimal_band_is_a_band_no_smaller_than_the_optimum():
    from contourmesh.bands import band_is_folded
    from contourmesh.bands.optimal import triangulate_band_optimal
    from contourmesh.measure import triangle_areas

    lo, hi = _ring(40, 5.0, 0.0, wobble=0.2), _ring(150, 5.5, 1.0, phase=0.3, wobble=0.1)
    full = triangulate_band_optimal(lo, hi)
    P = np.concatenate([lo, hi])
    # a budget above n^2 m is the optimum itself
    np.testing.assert_array_equal(triangulate_band_optimal(lo, hi, max_work=40 * 40 * 150), full)
    for k in (1, 3, 7):
        f = triangulate_band_optimal(lo, hi, max_work=k * 40 * 150)
        assert len(f) == len(lo) + len(hi) and not band_is_folded(f)
        # every edge of the rings is used once: a closed annulus
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        ring_edges = {tuple(sorted((i, (i + 1) % 40))) for i in range(40)} | \
            {tuple(sorted((40 + j, 40 + (j + 1) % 150))) for j in range(150)}
        assert ring_edges <= {tuple(x) for x in e.tolist()}
        assert triangle_areas(P, f).sum() >= triangle_areas(P, full).sum() - 1e-9
    # these rings are alike: the window round the nearest point holds the optimal start
    assert triangle_areas(P, triangulate_band_optimal(lo, hi, max_work=7 * 40 * 150)).sum() == \
        pytest.approx(triangle_areas(P, full).sum(), rel=1e-12)


def _same_partition(a, b):
    """Two labellings group the same items together (a bijection between their labels)."""
    pairs = np.unique(np.stack([a, b], axis=1), axis=0)
    return len(pairs) == len(np.unique(a)) == len(np.unique(b))


@pytest.mark.parametrize("seed", range(6))
def test_face_groups_equal_the_hashed_rows(seed):
    # the faces of two meshes grouped by their corner positions (the reference face_groups, by
    # smallest corner and edge) as the hash table of the sorted rows groups them (row_ids): few
    # distinct positions, so many faces share corners, edges and all three corners, in any order,
    # within a mesh and across the two; degenerate faces (a corner twice) included
    from repair_reference import face_groups as _face_groups
    from repair_reference import row_ids as _row_ids

    rng = np.random.default_rng(seed)
    n0, n1 = rng.integers(5, 40, size=2)
    pos = rng.integers(0, max(3, (n0 + n1) // 3), size=n0 + n1).astype(np.int64)
    F0 = rng.integers(0, n0, size=(rng.integers(1, 300), 3)).astype(np.int64)
    F1 = rng.integers(0, n1, size=(rng.integers(1, 300), 3)).astype(np.int64)
    F1 = np.concatenate([F1, F0[rng.integers(len(F0), size=20)][:, ::-1] % n1])
    got = _face_groups(pos, F0, F1, np.int64(n0))
    R = np.concatenate([pos[F0], pos[n0 + F1]])
    want = _row_ids(R, True)
    assert len(np.unique(want)) < len(want)  # some faces do share their corners
    assert _same_partition(got, want)


def _kept_faces_reference(k0, k1, n_faces0):
    """The numpy form :func:`contourmesh.repair._kept_faces` replaces (crossing_pairs_after_change's
    masks as they were): ``(kept, new_of_old)``."""
    nk = int(max(k0.max(initial=-1), k1.max(initial=-1))) + 1
    c0 = np.bincount(k0, minlength=nk)
    once0 = c0[k0] == 1
    old_of_key = np.full(nk, -1, dtype=np.int64)
    old_of_key[k0[once0]] = np.flatnonzero(once0)
    kept = c0[k1] == 1
    kept &= np.bincount(k1, minlength=nk)[k1] == 1  # the face occurs once in each mesh
    new_of_old = np.full(n_faces0, -1, dtype=np.int64)
    new_of_old[old_of_key[k1[kept]]] = np.flatnonzero(kept)
    return kept, new_of_old


def _assert_kept_faces_equal(k0, k1):
    from contourmesh.repair import _kept_faces

    nk = int(max(k0.max(initial=-1), k1.max(initial=-1))) + 1
    kept, new_of_old = _kept_faces(k0, k1, np.int64(nk))
    want_kept, want_new = _kept_faces_reference(k0, k1, len(k0))
    assert kept.dtype == np.bool_ and new_of_old.dtype == np.int64
    np.testing.assert_array_equal(kept, want_kept)
    np.testing.assert_array_equal(new_of_old, want_new)
    return kept


@pytest.mark.parametrize("seed", range(8))
def test_kept_faces_equal_the_numpy_form_on_random_keys(seed):
    # keys drawn from few values: keys once in each, twice in one, only in one of the two meshes
    rng = np.random.default_rng(seed)
    hi = int(rng.integers(1, 60))
    k0 = rng.integers(0, hi, size=int(rng.integers(0, 80))).astype(np.int32)
    k1 = rng.integers(0, hi, size=int(rng.integers(0, 80))).astype(np.int32)
    kept = _assert_kept_faces_equal(k0, k1)
    if seed == 0:
        assert kept.any() and not kept.all()


def test_kept_faces_equal_the_numpy_form_on_rebuilds(monkeypatch):
    # the face keys of real rebuilds: the blob with a crossing fallback, and random volumes of
    # the digest that rebuild (most faces kept, some changed, repeated faces)
    from contourmesh import repair

    seen = []
    orig = repair.crossing_pairs_after_change

    def recorded(V0, F0, pairs0, V1, F1, **kw):  # (the keys of each rebuild's re-test, found here)
        seen.append(repair._face_position_keys(V0, F0, V1, F1))
        return orig(V0, F0, pairs0, V1, F1, **kw)

    monkeypatch.setattr(repair, "crossing_pairs_after_change", recorded)
    monkeypatch.setattr(volumes, "crossing_pairs_after_change", recorded)
    rng = np.random.default_rng(7)
    vols = [np.pad(rng.random((12, 14, 13)) < 0.35, 1) for _ in range(2)]
    for v in vols:
        contourmesh.mesh(v)
    with monkeypatch.context() as m:
        m.setattr(volumes, "_DENSE_STEP", None)
        m.setattr(volumes, "_DENSE_RETRY_STEP", None)
        contourmesh.mesh(_blob(BLOB_WITH_FALLBACK))
    assert len(seen) >= 3
    for k0, k1 in seen:
        kept = _assert_kept_faces_equal(k0, k1)
        assert kept.any() and not kept.all()
