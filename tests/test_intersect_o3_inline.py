"""Issue 16 (round 29): the exact tests of two faces in 3D (``_tri_tri_3d``, ``_edge_tri_3d``,
``_shared_vertex``, ``_shared_edge``) take their orientations from ``_o3_in``, ``_o3`` inlined (one
function, ``_o3_sign``, compiled both ways), instead of calls of ``_o3`` (each passing both arrays'
fields).  The signs, and so the answers, must be the same: ``_o3_in`` is compared with ``_o3``
sign for sign, and the form of the tests before (the same functions with calls of ``_o3``,
compiled here from their code as the reference) with the one now, through ``_pair_intersects``,
on random faces on a small grid (coplanar, touching and shared corners everywhere, exact in
floats), the same scaled off the grid (the error bound and the exact fallback decide), and on
nearby faces of the lobster's first build."""

import types

import numpy as np
import pytest
from numba import njit

from contourmesh import intersect as I
from contourmesh.intersect import _o3, _o3_in, _pair_intersects
from test_intersect_grid_chunks import _first_build


def _reference_pair_test():
    """``_pair_intersects`` with every orientation of the 3D tests a call of ``_o3``: the tests'
    code compiled with ``_o3`` in place of ``_o3_in`` (the form before round 29)."""
    g = dict(vars(I))
    g["_o3_in"] = I._o3
    for name in ("_edge_tri_3d", "_tri_tri_3d", "_shared_vertex", "_shared_edge", "_pair_shared",
                 "_pair_intersects"):
        fn = getattr(I, name).py_func
        g[name] = njit(cache=False, _nrt=False)(types.FunctionType(fn.__code__, g, name, fn.__defaults__))
    return g["_pair_intersects"]


_pair_intersects_reference = _reference_pair_test()


@njit(cache=False)
def _compare(V, ws, F, quads, pairs):
    """1 per row where the inlined and the called orientations agree (``quads``: four vertices),
    and per pair of faces where both forms of the pair test agree; and how many pairs meet."""
    ok = np.ones(len(quads) + len(pairs), np.int8)
    for t in range(len(quads)):
        a, b, c, d = quads[t, 0], quads[t, 1], quads[t, 2], quads[t, 3]
        if _o3_in(V, ws, a, b, c, d) != _o3(V, ws, a, b, c, d):
            ok[t] = 0
    hits = 0
    for t in range(len(pairs)):
        i, j = pairs[t, 0], pairs[t, 1]
        got = _pair_intersects(V, ws, F, i, j)
        if got != _pair_intersects_reference(V, ws, F, i, j):
            ok[len(quads) + t] = 0
        if got:
            hits += 1
    return ok, hits


def _ws(V):
    ws = np.zeros(1 + 3 * I._EXP_LEN, np.float64)
    ws[0] = 1.0 if I._on_small_dyadic_grid(V) else 0.0
    return ws


def _faces(rng, nv, n):
    """Faces of three distinct corners."""
    F = rng.integers(0, nv, (3 * n, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])][:n]
    return np.ascontiguousarray(F, dtype=np.int64)


@pytest.mark.parametrize("scale", [1.0, 0.1, 1e-9 / 3.0])
def test_random_faces(scale):
    """Points of a 4^3 grid (coplanar, touching and corner-sharing faces everywhere), on it and
    scaled off it (0.1 and 1e-9/3: the float filter then leaves the zeros to the exact fallback)."""
    rng = np.random.default_rng(29)
    V = np.ascontiguousarray(rng.integers(0, 4, (64, 3)).astype(np.float64) * scale)
    ws = _ws(V)
    assert ws[0] == (1.0 if scale == 1.0 else 0.0)
    F = _faces(rng, len(V), 3000)
    quads = rng.integers(0, len(V), (200_000, 4))
    pairs = rng.integers(0, len(F), (200_000, 2))
    ok, hits = _compare(V, ws, F, quads, pairs)
    assert ok.all()
    assert 0 < hits < len(pairs)


def test_the_lobsters_first_build(shared_data):
    """Nearby faces of the lobster's first build (whose pairs the whole-mesh test decides with
    these tests), on its own coordinates, and its pairs that intersect."""
    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    V, F = _first_build(np.transpose(z["volume"], (2, 1, 0)) > 60)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(I.canonical_vertices(V)[F], dtype=np.int64)  # (as the whole-mesh test)
    rng = np.random.default_rng(16)
    f = rng.integers(0, len(F) - 64, 300_000)
    crossing = I.intersecting_pairs(V, F)
    assert len(crossing) > 0
    pairs = np.concatenate([np.stack([f, f + rng.integers(1, 64, len(f))], axis=1), crossing])
    f = pairs[:, 0]
    quads = np.stack([F[f, 0], F[f, 1], F[f, 2], F[pairs[:, 1], rng.integers(0, 3, len(f))]], axis=1)
    ok, hits = _compare(V, _ws(V), F, quads, pairs)
    assert ok.all()
    assert hits >= len(crossing)
