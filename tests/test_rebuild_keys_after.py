"""Issue 16 (round 22): the rebuild's re-test (``repair.crossing_pairs_after_change``) matches the
second mesh's vertices and faces against the first mesh's next ones before it looks them up
(``_row_ids_after``, ``_face_groups_after``), and skips the faces away from the changed faces' layers
of cells (``_near_cells``).  The forms they replace are the references (tests/repair_reference.py): ``row_ids`` on both
meshes' rows (the same numbers), ``face_groups`` (the same groups) and the cells of every face
looked up in the table (the same faces)."""

import numpy as np
import pytest

import contourmesh
import repair_reference
from contourmesh import repair


def _same_partition(a, b):
    """Two labellings group the same items together (a bijection between their labels)."""
    pairs = np.unique(np.stack([a, b], axis=1), axis=0)
    return len(pairs) == len(np.unique(a)) == len(np.unique(b))


def _edited(rng, n, pieces):
    """Indices ``0 .. n - 1`` in order with runs left out, runs of new ones (``>= n``, marked as
    ``-1 - k``) put in, and some repeated or moved: a rebuild's order of the first build's rows."""
    out = []
    at = 0
    new = 0
    while at < n:
        step = int(rng.integers(1, max(2, n // pieces)))
        out.extend(range(at, min(n, at + step)))
        at += step
        r = rng.random()
        if r < 0.3:
            at += int(rng.integers(1, 6))  # (left out)
        elif r < 0.6:
            k = int(rng.integers(1, 6))
            out.extend(-1 - np.arange(new, new + k))  # (new rows)
            new += k
        elif r < 0.7 and at > 0:
            out.extend(rng.integers(0, at, int(rng.integers(1, 4))).tolist())  # (repeated, moved)
    return np.array(out, dtype=np.int64), new


@pytest.mark.parametrize("seed", range(10))
def test_row_ids_after_equal_the_hashed_rows(seed):
    # rows from few values (many equal rows within each array and across the two, -0.0 and 0.0),
    # the second mostly the first's in order, or (odd seeds from 5 on) shuffled: the same numbers
    rng = np.random.default_rng(seed)
    n0 = int(rng.integers(0, 400))
    vals = np.array([0.0, -0.0, 1.0, 0.5, -2.25, 3.0, 1e-300, np.inf])
    R0 = vals[rng.integers(0, 3 if seed % 2 else len(vals), (n0, 3))] + 0.0
    idx, new = _edited(rng, n0, 20)
    extra = vals[rng.integers(0, len(vals), (new, 3))] + rng.integers(0, 3, (new, 3))
    R1 = np.where((idx >= 0)[:, None], R0[np.maximum(idx, 0)], extra[np.maximum(-1 - idx, 0)]) + 0.0
    if seed >= 5 and seed % 2:
        R1 = R1[rng.permutation(len(R1))]
    B0 = np.ascontiguousarray(R0).view(np.int64)
    B1 = np.ascontiguousarray(R1).view(np.int64)
    got = repair._row_ids_after(B0, B1)
    want = repair_reference.row_ids(np.concatenate([B0, B1]), False)
    assert got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)
    if n0 > 20:
        assert len(np.unique(want)) < len(want)  # (some rows are equal)


@pytest.mark.parametrize("seed", range(10))
def test_face_groups_after_group_as_before(seed):
    # faces on few corner positions (faces sharing their corners in any order, degenerate ones,
    # repeated faces within a mesh and across the two), the second mesh's faces mostly the first's
    # in order with runs left out, new ones put in, some repeated; or unrelated (seeds from 7)
    rng = np.random.default_rng(seed)
    n0, n1 = (int(x) for x in rng.integers(5, 60, size=2))
    pos = rng.integers(0, max(3, (n0 + n1) // (2 if seed % 2 else 6)), size=n0 + n1).astype(np.int64)
    F0 = rng.integers(0, n0, size=(int(rng.integers(1, 400)), 3)).astype(np.int64)
    if seed >= 7:
        F1 = rng.integers(0, n1, size=(int(rng.integers(1, 400)), 3)).astype(np.int64)
    else:
        idx, new = _edited(rng, len(F0), 15)
        extra = rng.integers(0, n1, size=(new, 3))
        F1 = np.where((idx >= 0)[:, None], F0[np.maximum(idx, 0)] % n1, extra[np.maximum(-1 - idx, 0)])
        # (the same positions in the second mesh's numbers for most of its vertices)
        pos[n0:n0 + min(n0, n1)] = pos[:min(n0, n1)]
        rot = rng.random(len(F1)) < 0.2
        F1[rot] = F1[rot][:, ::-1]
    F1 = np.ascontiguousarray(F1, dtype=np.int64)
    got = repair._face_groups_after(pos, F0, F1, np.int64(n0))
    want = repair_reference.face_groups(pos, F0, F1, np.int64(n0))
    assert got.dtype == np.int32 and len(got) == len(F0) + len(F1)
    assert _same_partition(got, want)
    assert len(np.unique(want)) < len(want)  # (some faces share their corners)


def _near_cells_reference(V, F, glo, h, chosen):
    """``_near_cells`` as it was (``both`` False): every face's cells looked up in the set of the
    chosen faces' cells."""
    def cells(i):
        lo = np.floor((V[F[i]].min(0) - glo) / h).astype(np.int64)
        hi = np.floor((V[F[i]].max(0) - glo) / h).astype(np.int64)
        return {(x, y, z) for x in range(lo[0], hi[0] + 1) for y in range(lo[1], hi[1] + 1)
                for z in range(lo[2], hi[2] + 1)}

    table = set()
    for i in chosen:
        table |= cells(i)
    near = np.zeros(len(F), bool)
    near[chosen] = True
    for i in range(len(F)):
        if not near[i]:
            near[i] = bool(cells(i) & table)
    return near


@pytest.mark.parametrize("seed", range(6))
def test_boxes_near_the_same_faces(seed):
    # faces of boxes from points to long ones in a tall block, a few chosen (none, one, many):
    # the faces sharing a cell with a chosen one are the same with and without the layers' filter
    rng = np.random.default_rng(seed)
    nv = 300
    V = np.c_[rng.random((nv, 2)) * 10.0, rng.integers(0, 40, nv) * 0.5]
    if seed % 2:
        V = V * 0.37 - 1.3
    F = rng.integers(0, nv, (500, 3)).astype(np.int64)
    near = rng.random(len(F)) < 0.9  # (most faces short: corners from nearby vertices)
    order = np.argsort(V[:, 2] + rng.random(nv) * 0.1)
    rank = np.empty(nv, np.int64)
    rank[order] = np.arange(nv)
    F[near] = order[np.clip(rank[F[near, :1]] + rng.integers(-3, 4, (int(near.sum()), 3)), 0, nv - 1)]
    for k in (0, 1, 5, 60):
        chosen = np.sort(rng.choice(len(F), k, replace=False)).astype(np.int64)
        glo, ext = repair._box_extents(V, V, F, np.bool_(False))
        h = max(np.median(ext), 1e-12)
        for t in chosen:
            h = max(h, ext[t])
        want = np.flatnonzero(_near_cells_reference(V, F, glo, h, chosen))
        got = repair._boxes_near(V, F, chosen)
        np.testing.assert_array_equal(got, want)
        if k == 1:
            assert len(got) < len(F)  # (the filter has faces to drop)


def test_rebuilds_keep_their_keys_and_pairs(monkeypatch):
    """The re-tests of real rebuilds (random volumes of the digest that rebuild): the new keys group
    the faces as the old pipeline (``row_ids`` over both meshes' rows, ``face_groups``) does."""
    seen = []
    orig = repair.crossing_pairs_after_change

    def recorded(V0, F0, pairs0, V1, F1, **kw):
        seen.append((V0.copy(), F0.copy(), V1.copy(), F1.copy()))
        return orig(V0, F0, pairs0, V1, F1, **kw)

    monkeypatch.setattr(repair, "crossing_pairs_after_change", recorded)
    from contourmesh import volumes

    monkeypatch.setattr(volumes, "crossing_pairs_after_change", recorded)
    rng = np.random.default_rng(7)
    for _ in range(2):
        contourmesh.mesh(np.pad(rng.random((12, 14, 13)) < 0.35, 1))
    assert seen
    for V0, F0, V1, F1 in seen:
        k0, k1 = repair._face_position_keys(V0, F0, V1, F1)
        bits = np.concatenate([V0, V1]) + 0.0
        pos = repair_reference.row_ids(bits.view(np.int64), False)
        want = repair_reference.face_groups(pos, np.ascontiguousarray(F0), np.ascontiguousarray(F1), np.int64(len(V0)))
        assert _same_partition(np.concatenate([k0, k1]), want)


def test_box_extents_equal_the_numpy_boxes():
    """``_box_extents`` (the face boxes written out in its loop) against numpy's boxes of the
    faces' corners (in ``V``, and in ``W`` too with ``both``): the low corner and each face's
    longest side, bit for bit, on random meshes with signed zeros and repeated corners."""
    rng = np.random.default_rng(1195)
    for seed in range(20):
        nv = int(rng.integers(3, 60))
        V = rng.normal(size=(nv, 3)) * 10.0 ** rng.integers(-3, 4)
        V[rng.random(nv) < 0.1] = -0.0
        W = V + rng.normal(size=(nv, 3)) * (seed % 3)
        F = rng.integers(0, nv, (int(rng.integers(1, 200)), 3)).astype(np.int64)
        for both in (False, True):
            C = np.concatenate([V[F], W[F]], axis=1) if both else V[F]
            lo, hi = C.min(axis=1), C.max(axis=1)
            glo, ext = repair._box_extents(V, W, F, np.bool_(both))
            np.testing.assert_array_equal(glo, lo.min(axis=0))
            np.testing.assert_array_equal(ext, np.maximum((hi - lo).max(axis=1), 0.0))
