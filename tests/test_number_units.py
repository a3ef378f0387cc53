"""The units' numbering into one mesh (:func:`contourmesh.volumes._number_units`): its loop over
Python integers and compiled renumbering give what the per-unit form it replaced gave (kept
here), bit for bit and in the same dtypes, on random units: own vertices before, between and
after their rings, rings shared by several units, units without faces or with necks."""

import numpy as np

from contourmesh.repair import _own_buffer
from contourmesh.volumes import _number_units, _stacked_rows, _tagged_sides, _Unit


def _number_units_reference(units, tags, ring_points):
    """The units' vertices and faces numbered into one mesh, in order: a ring gets its vertices
    where it is first used (``ring_points((k, comp, hole))``: its points, as the unit made them),
    a unit's own vertices where the unit makes them.  Returns ``(V, F, S, N, T)``: vertices,
    faces, side per face, neck vertices, and per face the tag of its unit (int32)."""
    # the vertex count first, then every array written at its final size (no per-unit copies
    # and no concatenation)
    seen = set()
    nv = 0
    for u in units:
        nv += u.nv
        for rk, a, b in u.rings:
            if rk in seen:
                nv -= b - a
            seen.add(rk)
    del seen
    V = np.empty((nv, 3))
    nf = sum(len(u.F) for u in units)
    F = np.empty((nf, 3), dtype=np.int64)
    S = np.empty(nf, dtype=np.int8)
    T = np.empty(nf, dtype=np.int32)
    ring_ids = {}
    Nb = []
    at = 0
    n = 0
    for u, t in zip(units, tags):
        nl = u.nv
        if not u.rings:  # (all its vertices its own: one block)
            g = np.arange(n, n + nl)
            V[n: n + nl] = u.V
            n += nl
        else:
            g = np.empty(nl, dtype=np.int64)
            pos = own = 0  # (local vertex; row of u.V)
            for rk, a, b in u.rings:
                if a > pos:
                    g[pos:a] = np.arange(n, n + a - pos)
                    V[n: n + a - pos] = u.V[own: own + a - pos]
                    own += a - pos
                    n += a - pos
                r = ring_ids.get(rk)
                if r is None:
                    r = ring_ids[rk] = np.arange(n, n + b - a)
                    xyz = ring_points(rk)
                    if len(xyz) != b - a:  # pragma: no cover - the key holds the ring's polygon
                        raise RuntimeError(f"internal error: ring {rk} changed under a kept unit")
                    V[n: n + b - a] = xyz
                    n += b - a
                g[a:b] = r
                pos = b
            if nl > pos:
                g[pos:] = np.arange(n, n + nl - pos)
                V[n: n + nl - pos] = u.V[own:]
                n += nl - pos
        if len(u.F):
            end = at + len(u.F)
            F[at:end] = g[u.F]
            S[at:end] = u.S
            T[at:end] = t
            at = end
        if len(u.N):
            Nb.append(g[u.N])
    N = np.concatenate(Nb) if Nb else np.zeros(0, dtype=np.int64)
    return V, F, S, N, T


def _random_units(rng, n_units, n_rings):
    sizes = rng.integers(3, 9, n_rings)
    points = {rk: rng.normal(size=(int(sizes[i]), 3)) for i, rk in enumerate((i, 0, -1) for i in range(n_rings))}
    keys = list(points)
    units, tags = [], []
    for j in range(n_units):
        u = _Unit()
        chosen = [keys[i] for i in rng.choice(n_rings, size=int(rng.integers(0, min(4, n_rings + 1))), replace=False)]
        at, own, spans = 0, 0, []
        for rk in chosen:
            gap = int(rng.integers(0, 3))  # own vertices before the ring
            at += gap
            own += gap
            spans.append((rk, at, at + len(points[rk])))
            at += len(points[rk])
        tail = int(rng.integers(0, 4))
        u.nv = at + tail
        own += tail
        u.V = rng.normal(size=(own, 3))
        nf = 0 if u.nv == 0 or rng.random() < 0.15 else int(rng.integers(1, 12))
        u.F = rng.integers(0, max(u.nv, 1), (nf, 3)).astype(np.int32 if rng.random() < 0.8 else np.int64)
        u.S = rng.integers(0, 3, nf).astype(np.int8)
        nn = int(rng.integers(0, 3)) if u.nv and rng.random() < 0.3 else 0
        u.N = rng.integers(0, max(u.nv, 1), nn).astype(np.int64)
        u.rings = spans
        units.append(u)
        tags.append(int(rng.integers(-1, 50)))
    return units, tags, points


def test_number_units_equals_the_per_unit_reference():
    rng = np.random.default_rng(113)
    shared = necks = 0
    for trial in range(300):
        units, tags, points = _random_units(rng, int(rng.integers(0, 12)), int(rng.integers(1, 6)))
        want = _number_units_reference(units, tags, points.__getitem__)
        got = _number_units(units, tags, points.__getitem__)
        for w, g in zip(want, got):
            assert g.dtype == w.dtype and g.shape == w.shape and np.array_equal(g, w)
        used = [rk for u in units for rk, _, _ in u.rings]
        shared += len(used) > len(set(used))
        necks += len(want[3]) > 0
    assert shared > 50 and necks > 50  # (both paths seen often)


def test_number_units_from_polygons_equals_the_reference():
    # the rings' points written from their polygons and heights (the volume mesher's form) are
    # the reference's points made by ring_points, bit for bit
    rng = np.random.default_rng(127)
    rings = 0
    for trial in range(300):
        units, tags, points = _random_units(rng, int(rng.integers(0, 12)), int(rng.integers(1, 6)))
        zs = rng.normal(size=8)
        polygons = {rk: np.ascontiguousarray(p[:, :2]) for rk, p in points.items()}

        def ring_points(rk):
            p = polygons[rk]
            return np.c_[p, np.full(len(p), zs[rk[0]])]

        def polygon_of(k, c, hole):
            return polygons[(k, c, hole)]

        want = _number_units_reference(units, tags, ring_points)
        got = _number_units(units, tags, ring_points, polygon_of, zs)
        for w, g in zip(want, got):
            assert g.dtype == w.dtype and g.shape == w.shape and np.array_equal(g, w)
        rings += sum(len(u.rings) for u in units)
    assert rings > 500


def test_stacked_rows_of_any_parts():
    parts = [np.arange(6.0).reshape(3, 2), np.zeros((0, 2)), [[7, 8]]]
    want = np.concatenate([np.asarray(x, dtype=np.float64).reshape(-1, 2) for x in parts])
    for ps in (parts, parts[:2], [np.arange(4.0), np.arange(2.0)], [np.arange(6, dtype=np.float32).reshape(3, 2)]):
        want = np.concatenate([np.asarray(x, dtype=np.float64).reshape(-1, 2) for x in ps])
        got = _stacked_rows(ps, 2)
        assert got.dtype == np.float64 and np.array_equal(got, want)
    assert _stacked_rows([], 3).shape == (0, 3)


def test_number_units_of_no_units():
    V, F, S, N, T = _number_units([], [], None)
    assert V.shape == (0, 3) and F.shape == (0, 3) and S.shape == (0,) and N.shape == (0,) and T.shape == (0,)
    assert (F.dtype, S.dtype, N.dtype, T.dtype) == (np.int64, np.int8, np.int64, np.int32)


def test_tagged_sides_equal_the_whole_array_form():
    """The repair's side-and-tag numbers (:func:`contourmesh.volumes._tagged_sides`, compiled) are
    ``S.astype(np.int32) + 4 * (T + 1)`` of the numbering's int8 sides and int32 tags, the form
    before: the same numbers and dtype, on random sides and tags (-1 and up, some near the top of
    the range) and on no faces."""
    rng = np.random.default_rng(7)
    for n, top in ((0, 5), (1, 0), (257, 3), (5000, 2000), (3000, 2**29 - 2)):
        S = rng.integers(0, 3, n).astype(np.int8)
        T = rng.integers(-1, top + 1, n).astype(np.int32)
        want = S.astype(np.int32) + 4 * (T + 1)
        out = np.empty(len(S), dtype=np.int32)
        got = _tagged_sides(S, T, out)
        assert got is out and _own_buffer(got)  # (the repair may resize it in place)
        assert got.dtype == want.dtype == np.int32 and np.array_equal(got, want)
        assert np.array_equal(got // 4 - 1, T) and np.array_equal(got % 4, S)
    # what _join_units hands over: the numbering's arrays of random units
    units, tags = [], []
    for t in range(40):
        u = _Unit.flat([], [], np.zeros((0, 3), dtype=np.int64))
        k = int(rng.integers(0, 6))
        u.nv, u.F = 3, rng.integers(0, 3, (k, 3)).astype(np.int32)
        u.S = rng.integers(0, 3, k).astype(np.int8)
        u.V = rng.random((3, 3))
        units.append(u)
        tags.append(t if t % 7 else -1)
    _, _, S, _, T = _number_units(units, tags, None)
    assert S.dtype == np.int8 and T.dtype == np.int32 and len(S) == len(T) > 0
    assert np.array_equal(_tagged_sides(S, T, np.empty(len(S), dtype=np.int32)), S.astype(np.int32) + 4 * (T + 1))
