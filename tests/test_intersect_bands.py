"""The crossing test on bands between two rings (the mesher's bands and joins, most of the calls of
``any_intersecting``): the slab phase decides the pairs of coordinates in its sweep for slabs whose
faces all span them (``_single_sweep``, with ``_apart_but_corner_w`` on the sweep's ranges); the
pairs must be exactly those of the general test with no shortcut (every candidate of the grid
tested), on the dyadic grid and off it, with crossings and without."""

import numpy as np
import pytest

from contourmesh.intersect import _as_mesh_arrays, _pairs, any_intersecting, canonical_vertices, intersecting_pairs


def _ring(rng, n, shift, step):
    """A closed ring of about n points around (shift), radius noisy, coordinates on a grid of
    ``step`` (runs of equal x or y, as on voxel contours), consecutive duplicates dropped."""
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 6.0 + rng.uniform(-1.5, 1.5) * np.cos(rng.integers(1, 4) * t + rng.uniform(0, 6)) + rng.uniform(-0.6, 0.6, n)
    P = np.column_stack([shift[0] + r * np.cos(t), shift[1] + r * np.sin(t)])
    P = np.round(P / step) * step
    keep = np.any(P != np.roll(P, 1, axis=0), axis=1)
    return P[keep]


def _band(rng, step=0.5, tidy=False):
    """Two rings at heights 0 and 1 joined by a band (each face two corners on one ring and one on
    the other, walked along both rings in order from matched starting points; ``tidy``: rings
    shifted less, and walked in proportion, as the mesher's bands that do not cross)."""
    A = _ring(rng, int(rng.integers(8, 60)), (0.0, 0.0), step)
    B = _ring(rng, int(rng.integers(8, 60)), rng.uniform(-2.5, 2.5, 2) * (0.2 if tidy else 1.0), step)
    if not tidy and rng.random() < 0.3:  # the other way round: faces twisted over each other
        B = B[::-1]
    n, m = len(A), len(B)
    V = np.vstack([np.column_stack([A, np.zeros(n)]), np.column_stack([B, np.ones(m)])])
    F = []
    i = j = 0
    while i < n or j < m:
        if j == m or (i < n and ((i + 0.5) / n < (j + 0.5) / m if tidy else rng.random() < n / (n + m))):
            F.append((i % n, (i + 1) % n, n + j % m))
            i += 1
        else:
            F.append((i % n, n + (j + 1) % m, n + j % m))
            j += 1
    return V, np.array(F, dtype=np.int64)


def _check(V, F):
    Va, Fa = _as_mesh_arrays(V, F)
    canon = canonical_vertices(Va)
    want = _pairs(Va, Fa, canon, 8, "grid", quick=False)  # every candidate by the general test
    assert np.array_equal(intersecting_pairs(V, F, method="slabs"), want)
    assert np.array_equal(intersecting_pairs(V, F, method="grid"), want)
    assert np.array_equal(intersecting_pairs(V, F), want)
    assert any_intersecting(V, F) == (len(want) > 0)
    first = _pairs(Va, Fa, canon, 8, "slabs", stop=1)
    assert len(first) == min(1, len(want)) and all(tuple(p) in set(map(tuple, want.tolist())) for p in first.tolist())
    return len(want)


@pytest.mark.parametrize("grid", ["dyadic", "off"])
def test_random_two_ring_bands_by_slabs_equal_the_plain_test(grid):
    rng = np.random.default_rng(16 if grid == "dyadic" else 17)
    crossing = clean = 0
    for t in range(150):
        V, F = _band(rng, step=0.5 if t % 3 else 1.0)
        if grid == "off":
            V = V * np.array([0.7, 0.7, 1.3]) + 0.113  # off the dyadic grid: the float filters and exact path
        if t % 4 == 0:  # a ring point moved onto a neighbour's line or beyond: touching and crossing faces
            v = int(rng.integers(len(V)))
            V[v, :2] += rng.choice([-0.5, 0.0, 0.5], 2)
        k = _check(V, F)
        crossing += k > 0
        clean += k == 0
    assert crossing >= 10 and clean >= 10, (crossing, clean)


@pytest.mark.parametrize("grid", ["dyadic", "off"])
def test_bands_across_a_plane_with_few_points(grid):
    # a band from height 0 to 1 with a small band from a mid-height to 1 beside or across it (as a
    # join's few points at a mid-height): the large band's faces span two slabs with no corner on
    # the middle plane, and their pairs are decided in the lower slab by the same coordinates
    rng = np.random.default_rng(41 if grid == "dyadic" else 42)
    crossing = clean = 0
    for t in range(80):
        V, F = _band(rng, step=0.5, tidy=True)
        W, G = _band(rng, step=0.5, tidy=True)
        W[:, :2] = W[:, :2] * 0.3 + rng.uniform(-10, 10, 2)  # in the hole, across the band or outside
        W[:, 2] = np.where(W[:, 2] == 0, 0.5, 1.0)
        if t % 2:  # the small band below the mid-height instead: from 0 to 0.5
            W[:, 2] -= 0.5
        V = np.vstack([V, W])
        F = np.vstack([F, G + len(V) - len(W)])
        if grid == "off":
            V = V * np.array([0.7, 0.7, 1.3]) + 0.113
        k = _check(V, F)
        crossing += k > 0
        clean += k == 0
    assert crossing >= 3 and clean >= 3, (crossing, clean)


def test_bands_with_one_common_corner_beside_each_other():
    # faces that share one corner and lie apart beside it along x or y (the fans of a ring point
    # over a run of the other ring), with the common corner on either plane, and the same faces
    # folded back over each other (a top point moved past its neighbour): the pairs of the plain test
    for flip in (False, True):
        for back in (0.0, 0.5, 1.0, 1.5):
            A = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
            B = np.array([[1, -1], [2, -1], [3, -1], [5 - back, -1], [5, 1], [5, 5], [-1, 5], [-1, -1]], float)
            if flip:
                A, B = B, A
            n, m = len(A), len(B)
            V = np.vstack([np.column_stack([A, np.zeros(n)]), np.column_stack([B, np.ones(m)])])
            rng = np.random.default_rng(int(back * 2) + 10 * flip)
            F = []
            i = j = 0
            while i < n or j < m:
                if j == m or (i < n and rng.random() < n / (n + m)):
                    F.append((i % n, (i + 1) % n, n + j % m))
                    i += 1
                else:
                    F.append((i % n, n + (j + 1) % m, n + j % m))
                    j += 1
            _check(V, np.array(F))


def test_any_intersecting_checks_in_its_compiled_call():
    """Arrays as the mesher passes them go straight to the compiled call, which checks them itself:
    a face index out of range, a coordinate not finite, or magnitudes out of the exact predicates'
    range make it refuse (-1, nothing done), and the checked path then gives its errors, or its
    answer on the rescaled coordinates."""
    from contourmesh import intersect as I

    rng = np.random.default_rng(3)
    V, F = _band(rng)
    d = np.int64(I._STAR_DELAY)
    want = len(intersecting_pairs(V, F)) > 0
    assert I._any_kernel(V, F, d) == int(want)
    for bad in (-1, len(V)):
        G = F.copy()
        G[5, 1] = bad
        assert I._any_kernel(V, G, d) == -1
        with pytest.raises(ValueError, match="do not exist"):
            any_intersecting(V, G)
    for x in (np.nan, np.inf, -np.inf):
        W = V.copy()
        W[3, 0] = x
        assert I._any_kernel(W, F, d) == -1
        with pytest.raises(ValueError, match="finite"):
            any_intersecting(W, F)
    for scale in (2.0 ** -300, 2.0 ** 400):  # exact scalings: the same answer, by the checked path
        W = V * scale
        assert I._any_kernel(W, F, d) == -1
        assert any_intersecting(W, F) == want
    W = V * 2.0 ** -200  # within range: the compiled call answers
    assert I._any_kernel(W, F, d) == int(want) and any_intersecting(W, F) == want
