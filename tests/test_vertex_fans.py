"""Issue 16 (speed of the general mesher): the manifold repair's fans walked per vertex
(:func:`contourmesh.repair._vertex_fans`) and its four-face edges found without the counts of
every edge (:func:`contourmesh.repair._four_face_edges`) give what the forms they replace gave
(the half-edge twins with :func:`contourmesh.repair._split_fans`, and
``_four_face_rows(_edge_multiplicity(...))``), bit for bit: on touching boxes, on the meshes the
volume mesher repairs, on random faces, and where the mesh is at fault (the same errors)."""

import numpy as np
import pytest
import trimesh

import repair_reference
from contourmesh import repair


def _twins_path(V, F):
    """split_nonmanifold_vertices' fans as they were made: the half-edge twins (their sorted search
    where the compiled one reports a fault, which raises there), then _split_fans."""
    Fc = np.ascontiguousarray(F, dtype=np.int64)
    twin, status = repair._half_edge_twins(Fc, len(V))
    if status != 0:
        twin = repair._half_edge_twins_reference(Fc, len(V) + 1)
    return repair._split_fans(twin, np.ascontiguousarray(Fc.reshape(-1)), V, len(V))


def _split_before(V, F, nudge):
    """split_nonmanifold_vertices(V, F, nudge, four_face=False) as it was (the twins' path)."""
    several, F2, target, start, copies, vid = _twins_path(V, F)
    if not several:
        return V, F
    F2 = F2.reshape(-1, 3)
    d = target - V[start]
    V2 = np.concatenate([V, V[copies]])
    nrm = np.linalg.norm(d, axis=1)
    good = nrm > 0
    V2[vid[good]] += d[good] * (nudge / nrm[good])[:, None]
    return V2, F2


def _bits(a):
    a = np.ascontiguousarray(a)
    return a.dtype.str, a.shape, a.tobytes()


def _same_fans(V, F):
    """_vertex_fans against _split_fans on the twins: the same several, faces, targets, vertices,
    copies and moved ids; returns whether the mesh had vertices of several fans."""
    cv = np.ascontiguousarray(np.asarray(F, dtype=np.int64).reshape(-1))
    status, several, changed, new_ids, target, start, copies, vid = repair._vertex_fans(cv, V, len(V))
    want = _twins_path(V, F)
    assert status == 0 and several == want[0]
    if several:
        F2 = cv.copy()
        F2[changed] = new_ids
        assert np.array_equal(changed, np.flatnonzero(F2 != cv))
        assert _bits(F2) == _bits(want[1])
        for got, exp in zip((target, start, copies, vid), want[2:]):
            assert _bits(got) == _bits(exp)
    return bool(several)


def _touching_boxes(rng, n=4):
    """Boxes of random sizes, each touching the previous one at a corner (welded there)."""
    Vs, Fs, at = [], [], 0
    corner = np.zeros(3)
    for _ in range(n):
        b = trimesh.creation.box(extents=rng.uniform(0.5, 2.0, 3))
        V = b.vertices - b.vertices.min(axis=0) + corner
        Vs.append(V)
        Fs.append(b.faces + at)
        at += len(V)
        corner = V.max(axis=0)
    V = np.concatenate(Vs)
    _, first, inv = np.unique(V, axis=0, return_index=True, return_inverse=True)
    return V, np.ascontiguousarray(first[inv.reshape(-1)][np.concatenate(Fs)], dtype=np.int64)


def _mesher_inputs(monkeypatch, rng, trials=4):
    """The volume mesher's inputs to split_nonmanifold_vertices and to the four-face split, on
    noisy volumes (many vertices of several fans, many four-face edges)."""
    import contourmesh
    from contourmesh import volumes

    fans, four = [], []
    real_split, real_four = volumes.split_nonmanifold_vertices, volumes._split_four_face_edges

    def split(V, F, **k):
        fans.append((V.copy(), F.copy()))
        return real_split(V, F, **k)

    def split_four(V, F, side, nudge, overwrite=False):  # (the mesher gives its own arrays over)
        four.append((V.copy(), F.copy()))
        return real_four(V, F, side, nudge)

    monkeypatch.setattr(volumes, "split_nonmanifold_vertices", split)
    monkeypatch.setattr(volumes, "_split_four_face_edges", split_four)
    for t in range(trials):
        contourmesh.mesh(np.pad(rng.random((6 + t, 14, 13)) < 0.45, 1))
    monkeypatch.undo()
    return fans, four


def test_vertex_fans_equal_the_twins_path_on_touching_boxes_and_mesher_meshes(monkeypatch):
    rng = np.random.default_rng(41)
    meshes = []
    for _ in range(5):
        V, F = _touching_boxes(rng)
        F = F[rng.permutation(len(F))]  # (faces shuffled, corners rotated: other lowest corners)
        meshes.append((V, np.ascontiguousarray(np.roll(F, int(rng.integers(3)), axis=1))))
    s = trimesh.creation.icosphere(subdivisions=3)  # (one fan everywhere)
    meshes.append((np.array(s.vertices), np.ascontiguousarray(s.faces, dtype=np.int64)))
    fans, _ = _mesher_inputs(monkeypatch, rng)
    assert fans
    meshes += fans
    several = [_same_fans(V, F) for V, F in meshes]
    assert any(several) and not all(several)
    for V, F in meshes:  # the whole step, its faces written in place or not
        want_V, want_F = _split_before(V, F, 1e-3)
        for overwrite in (False, True):
            G = F.copy()
            got_V, got_F = repair.split_nonmanifold_vertices(V, G, nudge=1e-3, four_face=False, overwrite=overwrite)
            assert _bits(got_V) == _bits(want_V) and _bits(got_F) == _bits(want_F)
            assert np.array_equal(G, F) or (overwrite and np.shares_memory(got_F, G))


def test_vertex_fans_on_a_vertex_of_many_fans():
    """``k`` closed cones sharing their apex (vertex 0, ``k`` fans there), faces shuffled and
    corners rotated: the fans, their order and the copies' numbers as the twins' path makes them."""
    rng = np.random.default_rng(43)
    for k in (1, 2, 3, 7):
        V, F = [np.zeros((1, 3))], []
        for j in range(k):
            r = 1 + 5 * j  # (its ring r .. r + 3, its tip r + 4)
            t = np.linspace(0, 2 * np.pi, 5)[:-1] + j
            V += [np.stack([np.cos(t), np.sin(t), np.ones(4)], 1) * (1 + j), [[0.0, 0.0, 5.0 + j]]]
            F += [[0, r + (i + 1) % 4, r + i] for i in range(4)] + [[r + 4, r + i, r + (i + 1) % 4] for i in range(4)]
        V = np.concatenate(V)
        for _ in range(3):
            G = np.array(F, dtype=np.int64)[rng.permutation(len(F))]
            G = np.ascontiguousarray(np.roll(G, int(rng.integers(3)), axis=1))
            assert _same_fans(V, G) == (k > 1)


def test_vertex_fans_report_what_the_twins_report_and_the_errors_are_the_same():
    """A face removed (a half-edge without its opposite), a face twice (a half-edge used twice in
    one direction), a face turned over, a face with a repeated vertex: _vertex_fans reports a
    status and split_nonmanifold_vertices raises the twins' path's error (or, for the repeated
    vertex, makes what that path makes)."""
    s = trimesh.creation.icosphere(subdivisions=2)
    V = np.array(s.vertices)
    F = np.ascontiguousarray(s.faces, dtype=np.int64)
    bad = [F[1:], np.concatenate([F, F[:1]]), np.concatenate([F[:1, ::-1], F[1:]]),
           np.concatenate([F, [[0, 0, 1], [1, 0, 0]]])]
    for G in bad:
        G = np.ascontiguousarray(G)
        assert repair._vertex_fans(np.ascontiguousarray(G.reshape(-1)), V, len(V))[0] != 0
        try:
            want = _split_before(V, G, 1e-3)
        except RuntimeError as err:
            want = str(err)
        try:
            got = repair.split_nonmanifold_vertices(V, G.copy(), nudge=1e-3, four_face=False, overwrite=True)
        except RuntimeError as err:
            got = str(err)
        if isinstance(want, str):
            assert got == want
        else:
            assert _bits(got[0]) == _bits(want[0]) and _bits(got[1]) == _bits(want[1])
    # a vertex number beyond the vertices: reported, not read
    G = F.copy()
    G[0, 0] = len(V)
    assert repair._vertex_fans(np.ascontiguousarray(G.reshape(-1)), V, len(V))[0] == 3


def _random_faces(rng, m, nv):
    return np.ascontiguousarray(np.stack([rng.choice(nv, 3, replace=False) for _ in range(m)]), dtype=np.int64)


def _four_before(F, nv):
    odd, most, rows, hit = repair_reference.four_face_rows(repair_reference.edge_multiplicity(F, nv))
    return int(odd), int(most), _bits(rows), _bits(hit)


def _four_now(got):
    odd, most, rows, hit = got
    return int(odd), int(most), _bits(rows), _bits(hit)


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_four_face_edges_equal_the_rows_of_the_edge_counts(monkeypatch, threads):
    rng = np.random.default_rng(47)
    cases = []
    for m, nv in ((400, 40), (3000, 900), (5, 9), (300, 6), (1, 3)):
        cases.append((_random_faces(rng, m, nv), nv))  # (odd counts, counts above four)
    s = trimesh.creation.icosphere(subdivisions=2)
    F = np.ascontiguousarray(s.faces, dtype=np.int64)
    cases += [(F, len(s.vertices)), (np.concatenate([F, F[:, ::-1]]), len(s.vertices))]  # (2 and 4 everywhere)
    G = np.concatenate([F, F[:40, ::-1]])  # (some four-face edges, some of three faces)
    cases.append((G, len(s.vertices)))
    _, four = _mesher_inputs(monkeypatch, rng, trials=3)
    cases += [(np.ascontiguousarray(F, dtype=np.int64), len(V)) for V, F in four]
    kinds = set()
    for F, nv in cases:
        want = _four_before(F, nv)
        got = repair._four_face_edges(F, nv) if threads == 1 else repair._four_face_edges_threads(F, nv, threads)
        assert _four_now(got) == want
        kinds.add((want[0] != 0, want[1] > 4, len(got[2]) > 0))
    assert {(True, True, True), (False, False, True), (False, False, False)} <= kinds


def test_four_face_edges_count_past_a_byte():
    """The per-bucket counts stop at 255 (bytes): an edge in 300 faces (and one in 255, one in 256)
    still gives the largest count and the first odd count that the edge counts give."""
    F = [[0, 1, 2 + k] for k in range(300)] + [[3, 4, 400 + k] for k in range(255)]
    F += [[5, 6, 700 + k] for k in range(256)]
    F = np.array(F, dtype=np.int64)
    nv = int(F.max()) + 1
    want = _four_before(F, nv)
    assert want[1] == 300
    assert _four_now(repair._four_face_edges(F, nv)) == want


@pytest.mark.parametrize("threads", ["1", "2"])
def test_repair_with_the_new_kernels_meshes_as_before(monkeypatch, threads):
    """The general mesher's repair with the twins' path and the edge counts in place of the new
    kernels (patched in): the same meshes, on one thread and on two."""
    import contourmesh

    rng = np.random.default_rng(53)
    vol = np.pad(rng.random((9, 12, 11)) < 0.45, 1)
    monkeypatch.setenv("CONTOURMESH_THREADS", threads)
    monkeypatch.setattr(repair, "_SPLIT_EDGES", 10)
    now = contourmesh.mesh(vol)

    def old_fans(cv, V, nv):
        return np.int64(1), False, None, None, None, None, None, None  # (always the twins' path)

    def old_four(F, nv):
        return repair_reference.four_face_rows(repair_reference.edge_multiplicity(F, nv))

    monkeypatch.setattr(repair, "_vertex_fans", old_fans)
    monkeypatch.setattr(repair, "_four_face_edges", old_four)
    monkeypatch.setattr(repair, "_four_face_edges_threads",
                        lambda F, nv, t: repair_reference.four_face_rows(repair_reference.edge_multiplicity_threads(F, nv, t)))
    before = contourmesh.mesh(vol)
    assert now.meta == before.meta
    assert now.vertices.tobytes() == before.vertices.tobytes() and now.faces.tobytes() == before.faces.tobytes()


def _separate_before(V, F, nudge):
    """_separate_coincident as it was: the ids of every position (row_ids), counted."""
    V = np.asarray(V, dtype=np.float64)
    if len(V) == 0:
        return V
    F = np.asarray(F, dtype=np.int64)
    inv = repair_reference.row_ids(np.ascontiguousarray(V + 0.0).view(np.int64), False)
    cnt = np.bincount(inv)
    dup = np.flatnonzero(cnt[inv] > 1)
    if len(dup) == 0:
        return V
    rank = repair._copy_rank(inv[dup])
    V = V.copy()
    is_dup = np.zeros(len(V), dtype=bool)
    is_dup[dup] = True
    corner_v = F.reshape(-1)
    corners = np.flatnonzero(is_dup[corner_v])
    faces = corners // 3
    cen = V[F[faces]].mean(axis=1)
    at = np.searchsorted(dup, corner_v[corners])
    acc = np.zeros((len(dup), 3))
    np.add.at(acc, at, cen)
    deg = np.bincount(at, minlength=len(dup)).astype(np.float64)
    target = acc / np.maximum(deg, 1)[:, None]
    d = target - V[dup]
    nrm = np.linalg.norm(d, axis=1)
    ok = nrm > 0
    step = nudge * (1.0 + 0.5 * rank)
    V[dup[ok]] += d[ok] * (step[ok] / nrm[ok])[:, None]
    return V


def _shared_sums_before(V, F, mark, dup):
    """_separate_coincident's sums as numpy made them: the corners at shared positions in face
    order, their faces' centroids (``mean(axis=1)``) added at each vertex's place in ``dup`` by
    ``np.add.at`` from zero, the counts by ``np.bincount``."""
    corner_v = F.reshape(-1)
    corners = np.flatnonzero(mark[corner_v])
    cen = V[F[corners // 3]].mean(axis=1)
    at = np.searchsorted(dup, corner_v[corners])
    acc = np.zeros((len(dup), 3))
    np.add.at(acc, at, cen)
    return acc, np.bincount(at, minlength=len(dup)).astype(np.float64)


def test_shared_rows_and_separate_coincident_equal_the_ids_of_every_row():
    rng = np.random.default_rng(59)
    s = trimesh.creation.icosphere(subdivisions=3)
    F = np.ascontiguousarray(s.faces, dtype=np.int64)
    seen = set()
    for trial in range(12):
        V = np.array(s.vertices)
        k = 0 if trial == 2 else int(rng.integers(1, 60))
        src, dst = rng.choice(len(V), k), rng.choice(len(V), k)
        V[dst] = V[src]  # (positions shared by two, three, ... vertices)
        if trial % 3 == 0 and k:
            V[dst[:4]] = V[src[:4]] * np.where(V[src[:4]] == 0, -1.0, 1.0)  # (-0.0 against 0.0)
            V[dst[:2], 0] = 0.0
            V[src[:2], 0] = -0.0
        if trial % 4 == 1:
            V[:3] = np.nan  # (NaN rows: grouped by their bits, as the ids group them)
        R = np.ascontiguousarray(V + 0.0).view(np.int64)
        ids = repair_reference.row_ids(R, False)
        want = np.flatnonzero(np.bincount(ids)[ids] > 1)
        dup, group, mark = repair._shared_rows(V)
        assert np.array_equal(dup, want) and np.array_equal(np.flatnonzero(mark), want)
        assert np.array_equal(repair._copy_rank(group), repair._copy_rank(ids[want]))
        acc, deg = repair._shared_centroid_sums(V, np.ascontiguousarray(F.reshape(-1)), mark, dup)
        want_acc, want_deg = _shared_sums_before(V, F, mark, dup)
        assert _bits(acc) == _bits(want_acc) and _bits(deg) == _bits(want_deg)
        got = repair._separate_coincident(V, F, 1e-3)
        exp = _separate_before(V, F, 1e-3)
        assert _bits(got) == _bits(exp)
        W = V.copy()
        got = repair._separate_coincident(W, F, 1e-3, overwrite=True)
        assert _bits(got) == _bits(exp) and (got is W or not len(dup))
        W = np.asfortranarray(V)  # (not a C array: read as one, not overwritten)
        assert _bits(repair._separate_coincident(W, F, 1e-3, overwrite=True)) == _bits(exp)
        assert _bits(W) == _bits(V)
        seen.add(len(dup) > 0)
    assert seen == {True, False}
    # many rows on a coarse grid (most shared, by two to many) and a few rows anywhere: the
    # bitmap's candidates hold every shared row and some that are not
    for n in (1, 2, 5000, 40000):
        V = np.concatenate([rng.integers(-20, 20, (n // 2, 3)) / 4.0, rng.normal(size=(n - n // 2, 3))])
        V = V[rng.permutation(n)]
        R = np.ascontiguousarray(V + 0.0).view(np.int64)
        ids = repair_reference.row_ids(R, False)
        want = np.flatnonzero(np.bincount(ids)[ids] > 1)
        dup, group, mark = repair._shared_rows(V)
        assert np.array_equal(dup, want) and np.array_equal(np.flatnonzero(mark), want)
        assert np.array_equal(repair._copy_rank(group), repair._copy_rank(ids[want]))
        first = np.unique(ids, return_index=True)[1]  # (ids are numbered in order of first rows)
        assert np.array_equal(group, first[ids[want]])


def test_compact_in_one_pass_equals_the_counts():
    rng = np.random.default_rng(61)
    for nv, m in ((50, 10), (50, 40), (5, 3), (0, 0), (7, 0)):
        V = rng.normal(size=(nv, 3))
        F = rng.integers(0, max(nv, 1), (m, 3)) if nv else np.zeros((0, 3), np.int64)
        if m and nv == 5:
            F = np.arange(15).reshape(5, 3) % 5  # (every vertex used)
        F = np.ascontiguousarray(F, dtype=np.int64)
        used = np.flatnonzero(np.bincount(F.reshape(-1), minlength=nv))
        remap = np.full(nv, -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        for overwrite in (False, True):
            G = F.copy()
            W, H = repair._compact(V, G, overwrite=overwrite)
            if len(used) == nv:
                assert W is V and H is G
            else:
                assert _bits(W) == _bits(V[used]) and _bits(H) == _bits(remap[F])
                assert (H is G) == overwrite
    # numbers out of range: bincount's answers and errors, as before
    V = rng.normal(size=(4, 3))
    with pytest.raises(ValueError):
        repair._compact(V, np.array([[0, 1, -1]], dtype=np.int64))
    with pytest.raises(IndexError):
        repair._compact(V, np.array([[0, 1, 9]], dtype=np.int64))


def _repair_arrays(monkeypatch, volumes_and_spacings):
    """The volume mesher's arrays at two steps of its repair: the numbering's sides and tags handed
    to :func:`contourmesh.volumes._tagged_sides`, and the mesh handed to ``_separate_coincident``."""
    from contourmesh import volumes

    tagged, coincident = [], []
    real_tagged, real_sep = volumes._tagged_sides, volumes._separate_coincident

    def tag(S, T, out):
        tagged.append((S.copy(), T.copy()))
        return real_tagged(S, T, out)

    def sep(V, F, nudge, overwrite=False):
        coincident.append((V.copy(), np.array(F, dtype=np.int64)))
        return real_sep(V, F, nudge, overwrite=overwrite)

    monkeypatch.setattr(volumes, "_tagged_sides", tag)
    monkeypatch.setattr(volumes, "_separate_coincident", sep)
    for vol, spacing in volumes_and_spacings:
        volumes.volume_to_mesh(vol, spacing=spacing)
    monkeypatch.undo()
    return tagged, coincident


def _check_repair_arrays(tagged, coincident):
    """Both compiled steps against their numpy forms before, bit for bit; returns how many vertices
    shared a position."""
    from contourmesh import volumes

    assert tagged and coincident
    for S, T in tagged:
        assert S.dtype == np.int8 and T.dtype == np.int32
        assert _bits(volumes._tagged_sides(S, T, np.empty(len(S), dtype=np.int32))) == _bits(S.astype(np.int32) + 4 * (T + 1))
    shared = 0
    for V, F in coincident:
        dup, _, mark = repair._shared_rows(V)
        acc, deg = repair._shared_centroid_sums(V, np.ascontiguousarray(F.reshape(-1)), mark, dup)
        want_acc, want_deg = _shared_sums_before(V, F, mark, dup)
        assert _bits(acc) == _bits(want_acc) and _bits(deg) == _bits(want_deg)
        shared += len(dup)
    return shared


def test_repair_sums_and_tagged_sides_on_mesher_meshes(monkeypatch):
    """The centroid sums of the coincident vertices and the tagged sides as numpy made them, on the
    volume mesher's own arrays (noisy volumes: many shared positions)."""
    rng = np.random.default_rng(43)
    vols = [(np.pad(rng.random((6 + t, 14, 13)) < 0.45, 1), (1.0, 1.0, 1.0)) for t in range(3)]
    assert _check_repair_arrays(*_repair_arrays(monkeypatch, vols)) > 0


def test_repair_sums_and_tagged_sides_on_the_lobster(monkeypatch, shared_data):
    """The same on the lobster's two builds (skipped without the shared data)."""
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    tagged, coincident = _repair_arrays(monkeypatch, [(np.pad(vol, 1), tuple(spacing))])
    assert len(tagged) == len(coincident) == 2  # (a crossing fallback: built twice)
    assert _check_repair_arrays(tagged, coincident) > 1000
