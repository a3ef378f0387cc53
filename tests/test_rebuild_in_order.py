"""Issue 16 (round 27): the rebuild's re-test (``repair.crossing_pairs_after_change``) gives the
faces of the rebuilt mesh their old faces by matching the two meshes' faces in their order
(``repair._faces_in_order``, a look-up in a window of old faces where the order breaks) instead of
grouping every face of both meshes by position (``repair._face_position_keys``, still used where the
order leaves many faces unmatched).  Any match of faces with the same corner positions, no old face
given twice, gives the same pairs: these tests check the matches and compare the pairs with the
whole check, on edited meshes (faces left out, put in, turned, moved, repeated; ``-0.0``), on
shuffled ones (the keys' route) and on the rebuilds of real volumes."""

import numpy as np
import pytest
import trimesh

import contourmesh
from contourmesh import repair, volumes
from contourmesh.intersect import intersecting_pairs
from contourmesh.repair import crossing_pairs_after_change


def _spheres():
    a = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    b = trimesh.creation.icosphere(subdivisions=3, radius=0.8)
    V = np.concatenate([a.vertices, b.vertices + [0.9, 0.1, 0.05]])
    F = np.concatenate([a.faces, b.faces + len(a.vertices)]).astype(np.int64)
    return V, F


def _edit(rng, V0, F0, gap):
    """A rebuild-like copy of ``(V0, F0)``: the faces in order with runs left out (up to ``gap``
    faces), runs of new faces put in (on copies of vertices, most of them moved), some faces turned or mirrored,
    neighbours swapped and a face repeated; the vertices renumbered (new ones put in between) and
    a zero coordinate written as ``-0.0``."""
    rows = []
    at = 0
    while at < len(F0):
        step = int(rng.integers(20, 400))
        rows.extend(range(at, min(len(F0), at + step)))
        at += step
        r = rng.random()
        if r < 0.3:
            at += int(rng.integers(1, gap))
        elif r < 0.6:
            # (copies of the last faces met: a copy of a face far ahead or behind, left in place,
            # could take its match and the faces round it be tested again: time, not pairs)
            end = min(at, len(F0))
            rows.extend(-1 - rng.integers(max(0, end - 40), end, int(rng.integers(1, 40))))
        elif r < 0.7 and len(rows) > 3:
            rows[-3], rows[-2] = rows[-2], rows[-3]
        elif r < 0.75:
            rows.append(rows[-1])
    rows = np.array(rows, dtype=np.int64)
    F1 = F0[np.maximum(rows, 0)].copy()
    new = rows < 0
    F1[new] = F0[-1 - rows[new]]
    # new faces: on fresh copies of their vertices, moved (or not: a copy at the same place)
    V = V0.copy()
    fresh = np.unique(F1[new])
    copies = V0[fresh] + rng.normal(scale=0.05, size=(len(fresh), 3)) * (rng.random((len(fresh), 1)) < 0.7)
    V = np.concatenate([V, copies])
    F1[new] = len(V0) + np.searchsorted(fresh, F1[new])
    turn = rng.random(len(F1)) < 0.02
    F1[turn] = np.roll(F1[turn], 1, axis=1)
    mirror = rng.random(len(F1)) < 0.01
    F1[mirror] = F1[mirror][:, ::-1]
    # renumber: the old vertices in order with the new ones spread among them
    order = np.argsort(np.concatenate([np.arange(len(V0)), rng.integers(0, len(V0), len(V) - len(V0))]),
                       kind="stable")
    rank = np.empty(len(V), np.int64)
    rank[order] = np.arange(len(V))
    V1 = V[order]
    F1 = rank[F1]
    zero = np.flatnonzero(V1 == 0.0)
    V1[np.unravel_index(zero, V1.shape)] = -0.0
    return V1, F1


def _check_match(V0, F0, V1, F1, old):
    """Every match has the same corner positions (as sets) and no old face is given twice."""
    hit = np.flatnonzero(old >= 0)
    assert len(np.unique(old[hit])) == len(hit)
    a = np.sort((V1[F1[hit]] + 0.0).view([("x", float), ("y", float), ("z", float)]).reshape(len(hit), 3), axis=1)
    b = np.sort((V0[F0[old[hit]]] + 0.0).view([("x", float), ("y", float), ("z", float)]).reshape(len(hit), 3), axis=1)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", range(8))
def test_edited_meshes_match_in_order_and_give_the_whole_checks_pairs(seed):
    rng = np.random.default_rng(seed)
    V0, F0 = _spheres()
    p0 = intersecting_pairs(V0, F0)
    assert len(p0) > 0
    V1, F1 = _edit(rng, V0, F0, gap=60 if seed % 2 else 600)
    old = repair._faces_in_order(V0, V0.view(np.int64), F0, V1, V1.view(np.int64), F1,
                                 np.int64(repair._MATCH_WINDOW), np.int64(repair._MATCH_BEHIND))
    _check_match(V0, F0, V1, F1, old)
    # the order finds every face the position keys keep (faces once in each mesh)
    kept, _ = repair._kept_faces_after(V0, F0, V1, F1)
    k0, k1 = repair._face_position_keys(V0, F0, V1, F1)
    keys_kept, _ = repair._kept_faces(k0, k1, np.int64(max(k0.max(), k1.max()) + 1))
    assert (old >= 0)[keys_kept].all()
    assert np.array_equal(kept, old >= 0)  # (few unmatched: the order's match is the one used)
    got = crossing_pairs_after_change(V0, F0, p0, V1, F1)
    want = intersecting_pairs(V1, F1)
    assert len(want) > 0
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("window,behind", [(8, 2), (64, 8), (2048, 64)])
def test_small_windows_miss_faces_but_never_pairs(window, behind, monkeypatch):
    # a window smaller than the runs left out: the faces after such a run are unmatched (tested
    # as new, or grouped by the keys' route), and the pairs stay the whole check's
    rng = np.random.default_rng(11)
    V0, F0 = _spheres()
    p0 = intersecting_pairs(V0, F0)
    V1, F1 = _edit(rng, V0, F0, gap=300)
    old = repair._faces_in_order(V0, V0.view(np.int64), F0, V1, V1.view(np.int64), F1,
                                 np.int64(window), np.int64(behind))
    _check_match(V0, F0, V1, F1, old)
    if window == 8:
        assert (old < 0).sum() > len(F1) // 16  # (the keys' route takes over)
    monkeypatch.setattr(repair, "_MATCH_WINDOW", window)
    monkeypatch.setattr(repair, "_MATCH_BEHIND", behind)
    np.testing.assert_array_equal(crossing_pairs_after_change(V0, F0, p0, V1, F1), intersecting_pairs(V1, F1))


def test_shuffled_faces_take_the_keys_route_and_give_the_same_pairs():
    rng = np.random.default_rng(3)
    V0, F0 = _spheres()
    p0 = intersecting_pairs(V0, F0)
    V1, F1 = _edit(rng, V0, F0, gap=30)
    F1 = F1[rng.permutation(len(F1))]
    old = repair._faces_in_order(V0, V0.view(np.int64), F0, V1, V1.view(np.int64), F1,
                                 np.int64(repair._MATCH_WINDOW), np.int64(repair._MATCH_BEHIND))
    _check_match(V0, F0, V1, F1, old)
    assert (old < 0).sum() > len(F1) // 16
    np.testing.assert_array_equal(crossing_pairs_after_change(V0, F0, p0, V1, F1), intersecting_pairs(V1, F1))


def test_nan_corners_match_nothing():
    V0, F0 = _spheres()
    V1 = V0.copy()
    V1[5] = np.nan
    old = repair._faces_in_order(V0, V0.view(np.int64), F0, V1, V1.view(np.int64), F0, np.int64(64), np.int64(8))
    touching = (F0 == 5).any(axis=1)
    assert (old[touching] < 0).all() and (old[~touching] == np.flatnonzero(~touching)).all()


def _rebuild_calls(monkeypatch, vols):
    seen = []
    orig = repair.crossing_pairs_after_change

    def recorded(V0, F0, pairs0, V1, F1, **kw):
        got = orig(V0, F0, pairs0, V1, F1, **kw)
        seen.append((V0.copy(), F0.copy(), V1.copy(), F1.copy(), got))
        return got

    monkeypatch.setattr(repair, "crossing_pairs_after_change", recorded)
    monkeypatch.setattr(volumes, "crossing_pairs_after_change", recorded)
    for v in vols:
        contourmesh.mesh(v)
    return seen


def _check_rebuilds(seen):
    for V0, F0, V1, F1, got in seen:
        old = repair._faces_in_order(V0, V0.view(np.int64), F0, V1, V1.view(np.int64), F1,
                                     np.int64(repair._MATCH_WINDOW), np.int64(repair._MATCH_BEHIND))
        _check_match(V0, F0, V1, F1, old)
        k0, k1 = repair._face_position_keys(V0, F0, V1, F1)
        keys_kept, _ = repair._kept_faces(k0, k1, np.int64(max(k0.max(), k1.max()) + 1))
        assert (old >= 0)[keys_kept].all()  # (no more faces tested than by the keys)
        np.testing.assert_array_equal(got, intersecting_pairs(V1, F1))


def test_random_volumes_rebuilds_give_the_whole_checks_pairs(monkeypatch):
    rng = np.random.default_rng(7)
    seen = _rebuild_calls(monkeypatch, [np.pad(rng.random((12, 14, 13)) < 0.35, 1) for _ in range(2)])
    assert seen
    _check_rebuilds(seen)


def test_lobster_rebuild_gives_the_whole_checks_pairs(shared_data, monkeypatch):
    from contourmesh.io import read_volume

    lobster, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    seen = _rebuild_calls(monkeypatch, [lobster])
    assert seen and len(seen[0][3]) > 100000
    _check_rebuilds(seen)


@pytest.mark.parametrize("seed", range(6))
def test_changed_faces_near_hold_every_face_whose_box_meets_a_chosen_one(seed):
    # boxes from points to long faces, a few chosen (one, many; tiny ones): every face whose closed
    # box meets a chosen face's box is found, with any sample of faces for the cells' size
    rng = np.random.default_rng(seed)
    nv = 400
    V = np.c_[rng.random((nv, 2)) * 10.0, rng.integers(0, 30, nv) * 0.5]
    if seed % 2:
        V = V * 0.37 - 1.3
    F = rng.integers(0, nv, (700, 3)).astype(np.int64)
    order = np.argsort(V[:, 2] + rng.random(nv) * 0.1)
    rank = np.empty(nv, np.int64)
    rank[order] = np.arange(nv)
    near = rng.random(len(F)) < 0.9
    F[near] = order[np.clip(rank[F[near, :1]] + rng.integers(-3, 4, (int(near.sum()), 3)), 0, nv - 1)]
    lo, hi = V[F].min(axis=1), V[F].max(axis=1)
    for k in (1, 7, 80):
        chosen = np.sort(rng.choice(len(F), k, replace=False)).astype(np.int64)
        meet = ((lo[:, None] <= hi[chosen][None]) & (lo[chosen][None] <= hi[:, None])).all(axis=2).any(axis=1)
        for sample in (1, 16, 4096):
            got = repair._changed_faces_near(V, F, chosen, np.int64(sample))
            assert np.all(np.diff(got) > 0)
            assert np.isin(np.flatnonzero(meet), got).all()
            if k == 1:
                assert len(got) < len(F)


@pytest.mark.parametrize("seed", range(3))
def test_groups_give_the_same_pairs(seed):
    rng = np.random.default_rng(seed)
    V0, F0 = _spheres()
    p0 = intersecting_pairs(V0, F0)
    V1, F1 = _edit(rng, V0, F0, gap=60)
    want = intersecting_pairs(V1, F1)
    for groups in (np.arange(len(F1)) // 50, np.zeros(len(F1), np.int64), np.full(len(F1), -1)):
        np.testing.assert_array_equal(crossing_pairs_after_change(V0, F0, p0, V1, F1, groups=groups), want)
    with pytest.raises(ValueError, match="one integer per face"):
        crossing_pairs_after_change(V0, F0, p0, V1, F1, groups=np.zeros(3, np.int64))
