"""Issue 16, round 26: ``any_intersecting``'s compiled call answers a mesh on a few heights that is
not one band between two (a join whose band spans two rings with a few faces at a mid-height, bands
stacked on three rings, a band with flat faces) by a path of its own (``intersect._few_levels_any``:
one sweep, the rules of one band between faces of one band, heights and ``_across_plane`` between
others).  The answer must be that of the general steps (``_any_kernel_reference``, the path every
such mesh took before) and of the plain test (every candidate of the grid tested exactly): on random
joins that cross and that do not, on the dyadic grid and off it (on two heights), and on every
crossing test of real builds on more than two heights or with flat faces."""

import os

import numpy as np
import pytest

from contourmesh.intersect import _any_kernel_reference
from test_intersect_bands import _band, _ring
from test_intersect_two_level import _answers, _build_calls, _plain


def _fan(V, F, rng, z, step):
    """A few flat faces at height ``z``: a fan from a point near the middle to a few points of a
    small ring (a bridge's lid), appended to ``V``, ``F``."""
    C = _ring(rng, int(rng.integers(4, 9)), rng.uniform(-3.0, 3.0, 2), step) * rng.uniform(0.1, 0.5)
    C = np.round(C / step) * step
    c0 = np.round(C.mean(axis=0) / step) * step
    n0 = len(V)
    V = np.vstack([V, [[c0[0], c0[1], z]], np.column_stack([C, np.full(len(C), z)])])
    k = len(C)
    G = [(n0, n0 + 1 + t, n0 + 1 + (t + 1) % k) for t in range(k)]
    return V, np.vstack([F, np.array(G, dtype=np.int64)])


def _join(rng, t, step):
    """A random join on three or four heights: a band spanning two rings at heights 0 and 2 with a
    lid at the mid-height and a few faces from a mid-height point to the top ring, or bands stacked
    on rings at 0, 1, 2 (and 3), or a band between 0 and 1 with flat faces on either ring."""
    kind = t % 3
    if kind == 0:
        V, F = _band(rng, step=step, tidy=t % 2 == 0)
        V = V.copy()
        V[:, 2] *= 2.0
        V, F = _fan(V, F, rng, 1.0, step)
        n0 = len(V)
        top = np.flatnonzero(V[:, 2] == 2.0)
        q = int(rng.integers(len(top) - 2))
        p = np.round(rng.uniform(-4.0, 4.0, 2) / step) * step
        V = np.vstack([V, [[p[0], p[1], 1.0]]])
        F = np.vstack([F, [[n0, top[q], top[q + 1]], [n0, top[q + 1], top[q + 2]]]])
        return V, F
    if kind == 1:
        parts = []
        off = 0
        for z in range(int(rng.integers(2, 4))):
            V, F = _band(rng, step=step, tidy=t % 4 != 1)
            V = V.copy()
            V[:, 2] += z
            parts.append((V, F + off))
            off += len(V)
        return np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts])
    V, F = _band(rng, step=step, tidy=t % 2 == 0)
    V, F = _fan(V.copy(), F, rng, float(rng.integers(0, 2)), step)
    return V, F


@pytest.mark.parametrize("grid", ["dyadic", "off"])
def test_random_joins_answer_as_the_reference(grid):
    rng = np.random.default_rng(26180 if grid == "dyadic" else 26181)
    seen = [0, 0]
    for t in range(180):
        V, F = _join(rng, t, 0.5 if t % 4 else 1.0)
        if grid == "off":  # (off the dyadic grid the two-height meshes and the small ones take the new path)
            V[:, :2] = V[:, :2] * 1.1 + rng.uniform(-1e-3, 1e-3, (len(V), 2)) * (t % 5 != 0)
            if t % 3 == 0:  # heights off the grid too (equal heights stay equal)
                V[:, 2] = V[:, 2] * 0.7 + 0.013
        seen[_answers(V, F)] += 1
    assert min(seen) > 10  # joins that cross and joins that do not


def test_joins_with_repeated_points_and_degenerate_faces():
    """Repeated positions, faces with two equal corners, faces exactly collinear across three
    heights (not live, as in the slab phase), and a face with a corner on each of three heights."""
    rng = np.random.default_rng(26182)
    seen = [0, 0]
    for t in range(150):
        V, F = _join(rng, t, 1.0)
        V = V.copy()
        kind = t % 4
        if kind == 0:
            a, b = rng.choice(len(V), 2, replace=False)
            V[b, :2] = V[a, :2]
        elif kind == 1:
            m = len(V)
            V = np.vstack([V, [V[0, 0], V[0, 1], V[0, 2] + 0.5], [V[0, 0], V[0, 1], V[0, 2] + 1.0]])
            F = np.vstack([F, [[0, m, m + 1]], [[0, 0, m]]])
        elif kind == 2:
            m = len(V)
            lo = int(np.argmin(V[:, 2]))
            hi = int(np.argmax(V[:, 2]))
            V = np.vstack([V, [V[lo, 0] + 1.0, V[lo, 1], 0.5 * (V[lo, 2] + V[hi, 2])]])
            F = np.vstack([F, [[lo, hi, m]]])
        seen[_answers(V, F)] += 1
    assert min(seen) > 5


def test_faces_meeting_in_one_plane_only():
    """A face below a plane and one above it with a common edge, a common corner or none there:
    they intersect exactly where their parts in the plane overlap beyond what they share."""
    base = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [1.0, -1.0, 0.0], [1.0, 1.0, 2.0], [3.0, 0.0, 1.0],
                     [1.0, 0.0, 1.0], [20.0, 20.0, 0.0], [21.0, 20.0, 2.0], [20.0, 21.0, 2.0]])
    # (a third face far off: the mesh is on three heights whichever two faces are tested)
    cases = [([0, 1, 2], [0, 1, 3], 0), ([0, 1, 2], [1, 4, 3], 0), ([0, 1, 2], [5, 4, 3], 1),
             ([0, 4, 2], [0, 1, 3], 1), ([0, 5, 2], [1, 4, 3], 0)]
    for f, g, want in cases:
        F = np.array([f, g, [6, 7, 8]], dtype=np.int64)
        assert _answers(base, F) == want, (f, g)


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
@pytest.mark.parametrize("name", ["lobster", "liver"])
def test_every_real_join_on_a_few_heights_answers_as_the_reference(name, monkeypatch):
    """Every crossing test of a build on more than two heights or with a flat face: the reference
    path's answer, and the plain test's on the larger ones."""
    calls = _build_calls(name, monkeypatch)
    few = []
    for k, (V, F, delay, got) in enumerate(calls):
        z = V[F, 2]
        if len(np.unique(V[:, 2])) > 2 or bool((z.min(axis=1) == z.max(axis=1)).any()):
            few.append(k)
    assert len(few) > 20
    for k in few:
        V, F, delay, got = calls[k]
        assert got == _any_kernel_reference(V, F, delay), k
    for k in sorted(few, key=lambda k: -len(calls[k][1]))[:15]:
        V, F, delay, got = calls[k]
        assert got == int(_plain(V, F)), k
