"""The slab phase's plane certificate without a sweep (``contourmesh.intersect._plane_convex_ring``):
it may say "embedded" only where :func:`~contourmesh.intersect._plane_embedded` (the sweep, which
it skips) says so too, it must say so for one strictly convex ring (the planes of a ball), and the
pairs of meshes through such planes are those of the general broad phase."""

import numpy as np

from contourmesh._kernels import njit
from contourmesh.intersect import _plane_convex_ring, _plane_embedded, intersecting_pairs
from plane_parts import part_boxes


@njit(cache=False)
def _both(V, ws, pu, pw, k):
    """Both answers for the parts ``pu - pw`` at plane ``k`` (fresh workspaces, no work limit)."""
    ne = len(pu)
    n = len(V)
    stamp = np.full(n, -1, np.int32)
    d1 = np.empty(n, np.int32)
    d2 = np.empty(n, np.int32)
    ring = _plane_convex_ring(V, ws, pu, pw, np.int64(ne), np.int64(k), stamp, d1, d2)
    xlo, xhi, ylo, yhi = part_boxes(V, pu, pw)
    cert = np.empty(ne, np.int32)
    all2 = np.full(ne, 2, np.int8)
    ci = np.empty(16, np.int64)
    cj = np.empty(16, np.int64)
    # (after the ring certificate, on its workspaces: its marks must not confuse the sweep)
    emb, _, _, _ = _plane_embedded(V, ws, xlo, xhi, ylo, yhi, pu, pw, np.int64(ne), np.int64(k), stamp, d1, d2,
                                   cert, all2, ci, cj, np.int64(0), np.int64(1 << 40))
    return ring, emb


def _ws():
    ws = np.zeros(64)
    ws[0] = 1.0  # small dyadic grid: the float arithmetic is exact
    return ws


def _parts(ids, twice=False, points=()):
    """The parts of a closed polygon through the vertex ids (each edge once, or twice as from the
    faces on both sides), plus point parts."""
    pu, pw = [], []
    for _ in range(2 if twice else 1):
        for a, b in zip(ids, np.roll(ids, -1)):
            pu.append(min(a, b))
            pw.append(max(a, b))
    for p in points:
        pu.append(p)
        pw.append(p)
    order = np.random.default_rng(len(pu)).permutation(len(pu))
    return np.array(pu, np.int64)[order], np.array(pw, np.int64)[order]


def _turn(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _convex(rng, n):
    """A strictly convex polygon on a dyadic grid: the hull of random points, counterclockwise."""
    while True:
        P = rng.integers(-40, 41, (n, 2)).astype(float) / 4
        keep = []  # monotone chain hull
        P = P[np.lexsort((P[:, 1], P[:, 0]))]
        for side in (P, P[::-1]):
            h = []
            for p in side:
                while len(h) >= 2 and _turn(h[-2], h[-1], p) <= 0:
                    h.pop()
                h.append(p)
            keep += h[:-1]
        H = np.array(keep)
        if len(H) >= 3:
            return H


def test_certificate_on_convex_rings_and_only_where_the_sweep_agrees():
    rng = np.random.default_rng(7)
    ws = _ws()
    fired = 0
    for trial in range(300):
        H = _convex(rng, int(rng.integers(3, 30)))
        n = len(H)
        kind = trial % 6
        V = np.c_[H, np.zeros(n)]
        ids = np.arange(n)
        points = ()
        if kind == 1:  # clockwise
            ids = ids[::-1]
        elif kind == 2:  # a collinear corner added (zero turn): not certified
            V = np.r_[V, [0.5 * (V[0] + V[1])]]
            ids = np.r_[0, n, np.arange(1, n)]
        elif kind == 3:  # a star: the corners visited by steps of two or three (winds more than once)
            step = 2 if n % 2 else 3
            if np.gcd(step, n) != 1 or n < 5:
                continue
            ids = (np.arange(n) * step) % n
        elif kind == 4:  # a point part beside the ring / on a corner
            V = np.r_[V, [[0.125, 0.0625, 0.0]]]
            points = (n,) if trial % 12 == 4 else (0,)
        elif kind == 5:  # a second ring, shifted (two polygons: not certified)
            V = np.r_[V, V + [0.25, 0.0, 0.0]]
            pu1, pw1 = _parts(ids)
            pu2, pw2 = _parts(ids + n)
            ring, emb = _both(V, ws, np.r_[pu1, pu2], np.r_[pw1, pw2], 3)
            assert not ring
            continue
        pu, pw = _parts(ids, twice=bool(trial % 2), points=points)
        ring, emb = _both(V, ws, pu, pw, int(trial % 5))
        if ring:
            assert emb, trial
            fired += 1
        expect = kind in (0, 1) or (kind == 4 and points == (0,))
        assert ring == expect, (trial, kind)
    assert fired > 100


def test_certificate_declines_open_and_branching_graphs():
    ws = _ws()
    V = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 0]], float)
    square = [0, 1, 2, 3]
    for pu, pw in (
        ([0, 1, 2], [1, 2, 3]),                 # open: one edge missing
        ([0, 1, 2, 0, 0], [1, 2, 3, 3, 2]),     # a chord: a corner of three edges
        ([0, 1, 0, 3], [1, 2, 2, 3]),           # a triangle, and the point 3 on no segment
    ):
        ring, emb = _both(V, ws, np.array(pu, np.int64), np.array(pw, np.int64), 0)
        assert not ring
    ring, emb = _both(V, ws, *_parts(np.array(square)), 0)
    assert ring and emb


def _tube(rings, zs):
    """A closed mesh through rings (each an (n, 2) array, all of n corners) at heights ``zs``:
    quads between consecutive rings split in two, and fans closing both ends."""
    n = len(rings[0])
    V = np.concatenate([np.c_[r, np.full(n, z)] for r, z in zip(rings, zs)])
    F = []
    for k in range(len(rings) - 1):
        for i in range(n):
            a, b = k * n + i, k * n + (i + 1) % n
            F += [[a, b, b + n], [a, b + n, a + n]]
    last = (len(rings) - 1) * n
    for i in range(1, n - 1):
        F += [[0, i + 1, i], [last, last + i, last + i + 1]]
    return V, np.array(F, np.int64)


def test_pairs_through_certified_planes_equal_the_grid():
    # tubes of convex rings (the planes certified without a sweep), twisted or squeezed ones, and
    # two tubes through each other: the slab phase's pairs are the grid's
    rng = np.random.default_rng(9)
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    base = np.round(np.c_[np.cos(t), np.sin(t)] * 32) / 4
    for trial in range(24):
        rings = []
        for k in range(6):
            r = base * (1 + 0.25 * rng.integers(0, 3)) + rng.integers(-2, 3, 2) / 4
            if trial % 4 == 1 and k == 3:
                r = r[::-1] * [1, -1]  # a mirrored ring: bands that fold
            if trial % 4 == 2 and k == 2:
                r = np.roll(r, 5, axis=0)  # a twist
            rings.append(r)
        V, F = _tube(rings, np.arange(6, dtype=float))
        if trial % 4 == 3:  # a second tube through the first
            V2, F2 = _tube([r[:, ::-1] * [1.5, 0.5] for r in rings], np.arange(6, dtype=float) + 0.5)
            V, F = np.r_[V, V2], np.r_[F, F2 + len(V)]
        a = intersecting_pairs(V, F, method="slabs")
        b = intersecting_pairs(V, F, method="grid")
        assert np.array_equal(a, b), trial
