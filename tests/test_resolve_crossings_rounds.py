"""resolve_crossings tests each round's move on the region's own vertices and only the faces near
the moved ones, copying the mesh once; the vertices, the pairs and the counts must be those of the
plain form below (a whole-mesh copy per round, every face of the region tested), bit for bit."""

import numpy as np
import pytest
import trimesh

from contourmesh.intersect import intersecting_pairs
from contourmesh.repair import _faces_near, _vertex_normals_at, resolve_crossings


def _resolve_reference(V, F, nudge, rounds=6, planes=None):
    """The rounds of resolve_crossings as they were written before (issue 16's eighth round)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    p = intersecting_pairs(V, F)
    n0 = len(p)
    if n0 == 0:
        return V, {"self_intersections": 0, "crossings_repaired": 0, "vertices_moved": 0, "max_move": 0.0,
                   "pairs": p}
    V0 = V
    nrm = _vertex_normals_at(V0, F, np.arange(len(V)))
    if planes is not None:
        nrm[np.isin(V0[:, 2], planes), 2] = 0.0
    reach = np.unique(F[np.unique(p)])
    Wmax = V.copy()
    Wmax[reach] -= nudge * (2.0 ** rounds) * nrm[reach]
    touched = np.zeros(len(V), dtype=bool)
    touched[reach] = True
    sub = _faces_near(V, Wmax, F, np.flatnonzero(touched[F].any(axis=1)))
    for r in range(rounds):
        if len(p) == 0:
            break
        verts = np.unique(F[np.unique(p)])
        if not touched[verts].all():
            touched[verts] = True
            Wmax[verts] = V[verts] - nudge * (2.0 ** rounds) * nrm[verts]
            sub = _faces_near(V, Wmax, F, np.flatnonzero(touched[F].any(axis=1)))
        W = V.copy()
        W[verts] -= nudge * 2.0 ** r * nrm[verts]
        q = intersecting_pairs(W, F[sub])
        q = sub[q] if len(q) else q.reshape(0, 2)
        if len(q) < len(p):
            V, p = W, q
    moved = np.linalg.norm(V - V0, axis=1)
    return V, {"self_intersections": int(len(p)), "crossings_repaired": int(n0 - len(p)),
               "vertices_moved": int(np.count_nonzero(moved)), "max_move": float(moved.max()), "pairs": p}


def _crossing_meshes(seed):
    rng = np.random.default_rng(seed)
    a = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    b = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    # a small sphere through the big one's surface (deep: rounds cannot all separate it), a box
    # resting against it (a touch, which a small move separates), and a few faces pushed across
    # their neighbours (shallow crossings)
    c = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    V = np.concatenate([a.vertices, b.vertices + [0.0, 0.0, 1.0 + rng.uniform(-0.45, 0.4)],
                        c.vertices + [1.2 + rng.uniform(0, 0.02), 0.0, 0.0]])
    F = np.concatenate([a.faces, b.faces + len(a.vertices), c.faces + len(a.vertices) + len(b.vertices)])
    V = V.copy()
    dent = rng.choice(len(a.vertices), 6, replace=False)
    V[dent] *= 1.0 - rng.uniform(0.02, 0.25, size=(6, 1))
    return V, F


@pytest.mark.parametrize("seed", range(8))
def test_resolve_crossings_equals_the_plain_rounds(seed):
    V, F = _crossing_meshes(seed)
    planes = np.unique(V[:, 2])[::7] if seed % 2 else None
    nudge = 1e-3 * (1 + seed % 3)
    want_V, want = _resolve_reference(V, F, nudge, planes=planes)
    assert want["self_intersections"] + want["crossings_repaired"] > 0  # there were crossings
    V_in = V.copy()
    got_V, got = resolve_crossings(V, F, nudge, planes=planes)
    np.testing.assert_array_equal(V, V_in)  # the caller's vertices are left as they were
    np.testing.assert_array_equal(got_V, want_V)
    assert set(got) == set(want)
    for k in want:
        if k == "pairs":
            np.testing.assert_array_equal(got[k], want[k])
        else:
            assert got[k] == want[k], k
    # given the pairs, as the general mesher calls it
    got_V2, got2 = resolve_crossings(V, F, nudge, planes=planes, pairs=intersecting_pairs(V, F))
    np.testing.assert_array_equal(got_V2, want_V)
    np.testing.assert_array_equal(got2["pairs"], want["pairs"])


def test_some_cases_move_and_some_keep_crossings():
    # the cases above cover both outcomes: rounds that are kept, and pairs that stay
    kept = left = 0
    for seed in range(8):
        V, F = _crossing_meshes(seed)
        _, info = resolve_crossings(V, F, 1e-3)
        kept += info["crossings_repaired"] > 0
        left += info["self_intersections"] > 0
    assert kept > 0 and left > 0
