"""Issue 16 (peak memory of a first call): ``intersect._sectioned`` decides, before the slab phase
is asked, whether :func:`intersect._slab_pairs` over the whole mesh would give the mesh up as not
sectioned (its ``ok == 0``), so that the ``auto`` route sends such a mesh (the lobster's repaired
mesh) to the grid without loading the slab phase's compiled code.  Its answer must be the slab
phase's own, on random meshes around the limit (with collinear and degenerate faces, on and off
the dyadic grid) and on a real mesh; and the pairs of ``auto`` stay those of the grid."""

import numpy as np
import pytest

import contourmesh.intersect as I
from contourmesh.intersect import _as_mesh_arrays, canonical_vertices, intersecting_pairs


def _prepared(V, F):
    """The arrays :func:`intersect._pairs` hands the slab phase: vertices, workspace, faces on
    canonical vertices, the heights' levels and their number."""
    V, F = _as_mesh_arrays(V, F)
    canon = canonical_vertices(V)
    V = I._exact_range(V)
    if not V.flags.writeable:
        V = V.copy()
    Fc = np.ascontiguousarray(canon[F])
    ws = np.zeros(1 + 3 * I._EXP_LEN, dtype=np.float64)
    ws[0] = 1.0 if I._on_small_dyadic_grid(V) else 0.0
    lev, nlev = I._levels(np.ascontiguousarray(V[:, 2]))
    return V, ws, Fc, lev, nlev


def _slab_phase_takes(V, F) -> tuple[bool, bool]:
    """(``_sectioned``'s answer, whether the whole-mesh slab phase gets past its first loop)."""
    V, ws, Fc, lev, nlev = _prepared(V, F)
    got = I._sectioned(V, ws.copy(), Fc, lev) == 1
    _, _, ok = I._slab_pairs(V, ws.copy(), Fc, np.zeros(len(V), np.int8),
                             np.array([0, len(Fc) // 8 + I._STAR_DELAY], np.int64), np.int64(1), lev,
                             np.int64(nlev), np.int64(I._SLAB_BUDGET), np.int64(0), np.int64(0), np.int64(nlev),
                             np.zeros(0, np.int64))
    return got, ok != 0


def _mesh_near_the_limit(rng, n_faces, mean_span, n_collinear, dyadic):
    """Random faces over many heights whose spans of levels add up near ``4 m + 1000``, plus
    ``n_collinear`` exactly collinear faces over many levels (counted by the upper bound only) and
    some faces with a repeated vertex (counted by neither)."""
    n_levels = 400
    z = np.arange(n_levels) * 0.5
    if not dyadic:
        z = z * 0.1 + 0.37
    verts, faces = [], []
    n = 0
    for _ in range(n_faces):
        k = int(rng.integers(0, n_levels - 40))
        span = int(rng.poisson(mean_span))
        lv = [k, k + span, k + int(rng.integers(0, span + 1))]
        xy = rng.integers(0, 8, (3, 2)) * 0.5
        for t in range(3):
            verts.append((xy[t, 0], xy[t, 1], z[lv[t]]))
        faces.append((n, n + 1, n + 2))
        n += 3
    for _ in range(n_collinear):  # a line through three heights far apart: exactly collinear
        k = int(rng.integers(0, n_levels - 300))
        d = rng.integers(1, 4, 2) * 0.5
        for t, s in enumerate((0, 100, 300)):
            verts.append((d[0] * t, d[1] * t, z[k + s]))
        faces.append((n, n + 1, n + 2))
        n += 3
    for _ in range(20):
        faces.append((n - 1, n - 1, n - 2))
    return np.array(verts), np.array(faces)


@pytest.mark.parametrize("dyadic", [True, False])
def test_sectioned_is_the_slab_phase_answer_around_the_limit(dyadic):
    rng = np.random.default_rng(11 if dyadic else 12)
    seen = set()
    for trial in range(60):
        m = int(rng.integers(200, 900))
        limit_span = (4 * m + 1000) / m
        mean_span = limit_span * rng.uniform(0.8, 1.2)
        n_col = int(rng.integers(0, 3) * rng.integers(0, 8))
        V, F = _mesh_near_the_limit(rng, m, mean_span, n_col, dyadic)
        got, want = _slab_phase_takes(V, F)
        assert got == want, trial
        seen.add((want, n_col > 0))
    # both answers met, also where collinear faces decide (the exact count after the upper bound)
    assert {(True, False), (False, False), (True, True), (False, True)} <= seen, seen


def test_sectioned_on_a_real_mesh_and_one_made_not_sectioned(shared_data):
    import contourmesh
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    m = contourmesh.mesh(vol[40:70], spacing=spacing)
    V, F = m.vertices.copy(), m.faces.copy()
    got, want = _slab_phase_takes(V, F)
    assert got == want
    # the same faces with heights spread over many levels (every vertex its own): not sectioned
    W = V.copy()
    W[:, 2] += np.arange(len(W)) * 1e-9
    got, want = _slab_phase_takes(W, F)
    assert got == want and not want


def test_auto_sends_a_mesh_not_sectioned_to_the_grid_without_the_slab_phase(monkeypatch):
    rng = np.random.default_rng(3)
    V, F = _mesh_near_the_limit(rng, 600, 12.0, 0, False)
    V[:, :2] += rng.uniform(0, 0.5, (len(V), 2))  # (crossings among them)
    calls = []
    real = I._slab_pairs
    monkeypatch.setattr(I, "_slab_pairs", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setattr(I, "_GRID_FACES", 10)  # a "large" mesh off the grid: the slab route
    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    want = intersecting_pairs(V, F, method="grid")
    assert len(want) > 0
    assert np.array_equal(intersecting_pairs(V, F), want) and calls == []
    with pytest.raises(ValueError, match="sections"):
        intersecting_pairs(V, F, method="slabs")  # (asked for: still asked, and refused)
    assert calls == [1]
    # a sectioned mesh on the same route still takes the slab phase
    V2, F2 = _mesh_near_the_limit(rng, 600, 1.0, 0, False)
    assert np.array_equal(intersecting_pairs(V2, F2), intersecting_pairs(V2, F2, method="grid"))
    assert calls == [1, 1]


def test_a_mesh_not_sectioned_is_not_split_over_threads(monkeypatch):
    """On two threads, "auto" asks :func:`_sectioned` before the split: a mesh that is not
    sectioned goes to the grid without its ranges' slab phases (the same pairs), and a sectioned
    one is still split."""
    rng = np.random.default_rng(5)
    V, F = _mesh_near_the_limit(rng, 600, 12.0, 0, False)
    V[:, :2] += rng.uniform(0, 0.5, (len(V), 2))  # (crossings among them)
    want = intersecting_pairs(V, F, method="grid")
    assert len(want) > 0
    split = []
    real_split = I._split_slab_pairs
    monkeypatch.setattr(I, "_split_slab_pairs", lambda *a: split.append(1) or real_split(*a))
    monkeypatch.setattr(I, "_GRID_FACES", 10)
    monkeypatch.setattr(I, "_SPLIT_FACES", 10)
    monkeypatch.setenv("CONTOURMESH_THREADS", "2")
    assert np.array_equal(intersecting_pairs(V, F), want) and split == []
    V2, F2 = _mesh_near_the_limit(rng, 600, 1.0, 0, False)
    assert np.array_equal(intersecting_pairs(V2, F2), intersecting_pairs(V2, F2, method="grid"))
    assert split == [1]
