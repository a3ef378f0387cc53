"""Issue 13, item 3: faces whose boxes meet only in a plane ``z = c`` are decided in that plane
(``contourmesh.intersect._across_plane``); the answers must be those of the general test, which
the same pairs get when the plane is not horizontal (coordinates rotated)."""

import numpy as np
import pytest

from contourmesh.intersect import intersecting_pairs

P0 = (0.0, 0.0, 0.0)
BELOW = [P0, (2.0, 0.0, 0.0), (1.0, 1.0, -1.0)]  # an edge from P0 along +x in the plane z = 0

CASES = [  # (face above the plane, intersects)
    ([(1.0, 0.0, 0.0), (3.0, 0.0, 0.0), (2.0, 0.5, 1.0)], True),    # overlapping in-plane edges
    ([(2.5, 0.0, 0.0), (3.0, 0.0, 0.0), (2.0, 0.5, 1.0)], False),   # collinear, apart
    ([P0, (1.0, 0.0, 0.0), (0.0, 1.0, 1.0)], True),                 # common corner, one ray
    ([P0, (-1.0, 0.0, 0.0), (0.0, 1.0, 1.0)], False),               # common corner, opposite rays
    ([P0, (0.0, 1.0, 0.0), (0.0, 1.0, 1.0)], False),                # common corner, other direction
    ([P0, (0.5, 2.0, 1.0), (-0.5, 2.0, 1.0)], False),               # common corner only
    ([(1.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2.0, -1.0, 1.0)], True),   # a corner on the edge
    ([(1.0, 0.5, 0.0), (1.0, 1.0, 1.0), (2.0, -1.0, 1.0)], False),  # a corner beside it
    ([(1.0, -1.0, 0.0), (1.0, 1.0, 0.0), (1.0, 0.0, 1.0)], True),   # in-plane edges crossing
    ([(2.0, 0.0, 0.0), P0, (1.0, -1.0, 1.0)], False),               # the common edge, opposite sides
    ([(2.0, 0.0, 0.0), (4.0, 0.0, 0.0), (3.0, 1.0, 1.0)], False),   # end to end: a common corner
]


@pytest.mark.parametrize("above, hit", CASES)
def test_pairs_meeting_in_a_plane(above, hit):
    V = np.array(BELOW + above)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    assert (len(intersecting_pairs(V, F)) == 1) == hit
    # the same pair with the plane vertical: the general test decides, and agrees
    assert (len(intersecting_pairs(V[:, [2, 0, 1]], F)) == 1) == hit


def test_random_slab_meshes_agree_with_the_general_test():
    # random triangles with corners on three planes: every answer equals the rotated one's
    rng = np.random.default_rng(3)
    for _ in range(30):
        n = 40
        V = np.c_[rng.integers(0, 4, (n, 2)).astype(float) / 2, rng.integers(0, 3, n).astype(float)]
        F = rng.integers(0, n, (60, 3))
        F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
        a = intersecting_pairs(V, F)
        b = intersecting_pairs(V[:, [2, 0, 1]], F)
        assert np.array_equal(a, b)
