"""Issue 16, round 24: ``any_intersecting``'s compiled call answers a mesh whose vertices lie on two
heights (the mesher's bands and joins) by a path of its own (``intersect._two_level_any``: its own
sweep, the rule "ends apart" inline, and a rule for faces with a common rung, ``_rung_apart``).  The
answer must be that of the general steps (``_any_kernel_reference``, the path every such mesh took
before) and of the plain test (every candidate of the grid tested exactly): on random bands that
cross and that do not, on and off the dyadic grid, with repeated points, degenerate and flat faces,
walls whose faces fold onto each other along their rungs, and on every crossing test of real builds."""

import os

import numpy as np
import pytest

from contourmesh import intersect
from contourmesh.intersect import _any_kernel, _any_kernel_reference, _as_mesh_arrays, _pairs, canonical_vertices
from test_intersect_bands import _band, _ring

DELAY = np.int64(intersect._STAR_DELAY)


def _plain(V, F):
    """Whether two faces intersect, by the general test with every candidate of the grid tested."""
    Va, Fa = _as_mesh_arrays(V, F)
    return len(_pairs(Va, Fa, canonical_vertices(Va), 8, "grid", quick=False)) > 0


def _answers(V, F, delay=DELAY):
    """The new path's answer, checked against the reference path's and the plain test's."""
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    got = _any_kernel(V, F, delay)
    assert got == _any_kernel_reference(V, F, delay)
    assert got == int(_plain(V, F))
    return got


def _wall(rng, n, step):
    """A band between a ring and the same ring one height up, shifted by a few grid steps or not at
    all: walls whose neighbouring faces are coplanar wherever the ring runs straight, the faces on
    either side of a rung pointing the same way or not."""
    A = _ring(rng, n, (0.0, 0.0), step)
    B = A + (rng.integers(-2, 3, 2) * step if rng.random() < 0.5 else 0.0)
    if rng.random() < 0.3:
        B = np.roll(B, int(rng.integers(1, 4)), axis=0)  # rungs that lean along the ring
    k = len(A)
    V = np.vstack([np.column_stack([A, np.zeros(k)]), np.column_stack([B, np.ones(k)])])
    F = []
    for i in range(k):
        if rng.random() < 0.5:
            F += [(i, (i + 1) % k, k + i), ((i + 1) % k, k + (i + 1) % k, k + i)]
        else:
            F += [(i, (i + 1) % k, k + (i + 1) % k), (i, k + (i + 1) % k, k + i)]
    return V, np.array(F, dtype=np.int64)


@pytest.mark.parametrize("grid", ["dyadic", "off"])
def test_random_bands_answer_as_the_reference(grid):
    rng = np.random.default_rng(24165 if grid == "dyadic" else 24166)
    seen = [0, 0]
    for t in range(160):
        V, F = _band(rng, step=0.5 if t % 3 else 1.0, tidy=t % 2 == 0)
        if grid == "off":
            V[:, :2] += rng.uniform(-1e-3, 1e-3, (len(V), 2)) * (t % 4 != 0)
            V[:, :2] *= 1.1
        seen[_answers(V, F)] += 1
    assert min(seen) > 15  # bands that cross and bands that do not


def test_bands_with_repeated_points_and_degenerate_faces():
    """Repeated positions (one point twice on a ring, a point of one ring where the other's is seen
    from above), faces with two equal corners, exactly collinear faces, and a flat face added
    (the general steps then, as a face on one height has pairs in that plane too)."""
    rng = np.random.default_rng(24167)
    seen = [0, 0]
    for t in range(160):
        V, F = _band(rng, step=1.0, tidy=t % 2 == 0)
        V = V.copy()
        n = int(np.sum(V[:, 2] == 0))
        kind = t % 5
        if kind == 0:  # a ring that touches itself
            a, b = rng.choice(n, 2, replace=False)
            V[b] = V[a]
        elif kind == 1:  # a top point straight over a bottom one
            V[n + int(rng.integers(len(V) - n)), :2] = V[int(rng.integers(n)), :2]
        elif kind == 2:  # a face with two equal corners, and a collinear one
            F = np.vstack([F, [[0, 0, n]], [[0, n, n]]])
            m = len(V)
            V = np.vstack([V, 0.5 * (V[0] + V[n])])
            F = np.vstack([F, [[0, n, m]]])
        elif kind == 3:  # a flat face on the lower ring
            F = np.vstack([F, [[0, 1, 2]]])
        seen[_answers(V, F)] += 1
    assert min(seen) > 15


def test_walls_folded_along_their_rungs():
    """Coplanar neighbours: the rule for faces on one rung must leave every fold to the exact test."""
    rng = np.random.default_rng(24168)
    seen = [0, 0]
    for t in range(200):
        V, F = _wall(rng, int(rng.integers(6, 30)), 1.0)
        if t % 3 == 0:
            V[:, :2] += rng.uniform(-1e-3, 1e-3, (len(V), 2)) * (rng.random((len(V), 1)) < 0.2)
        seen[_answers(V, F)] += 1
    assert min(seen) > 15


@pytest.mark.parametrize("b", [(2.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (2.0, 1.0), (-1.0, 0.0), (1.0, 1e-9), (3.0, -0.0)])
def test_two_faces_on_one_rung(b):
    """Faces (p, a, q) and (p, q, b) on the rung p-q: they fold onto each other (intersect) exactly
    where a - p and b - q point the same way."""
    V = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [b[0], b[1], 1.0]])
    F = np.array([[0, 2, 1], [0, 1, 3]], dtype=np.int64)
    want = int(b[0] > 0 and b[1] == 0.0)
    assert _answers(V, F) == want


def _build_calls(name, monkeypatch):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import volume_speed as vs

        vol, sp = vs.make_input(name)
    except Exception as exc:  # pragma: no cover - data missing
        pytest.skip(f"{name} not available: {exc}")
    import contourmesh
    from contourmesh import bands, repair

    calls = []
    orig, orig_seen, orig_band = intersect._any_kernel, intersect._any_kernel_seen, bands._band_any

    def wrap(V, F, delay):
        got = orig(V, F, delay)
        calls.append((V.copy(), F.copy(), delay, got))
        return got

    def wrap_seen(V, F, delay, mem):  # (any_intersecting's entry, with the memory of the last pair)
        got = orig_seen(V, F, delay, mem)
        calls.append((V.copy(), F.copy(), delay, got))
        return got

    def wrap_band(P, f, delay, mem):  # (a band's test: its points with the pinches split)
        got = orig_band(P, f, delay, mem)
        Q, status = bands._pinch_split(P, f)
        if status < 2:
            calls.append((Q.copy(), f.copy(), delay, got))
        return got

    monkeypatch.setattr(intersect, "_any_kernel", wrap)
    monkeypatch.setattr(intersect, "_any_kernel_seen", wrap_seen)
    monkeypatch.setattr(bands, "_band_any", wrap_band)
    monkeypatch.setattr(repair, "_any_kernel", wrap)
    contourmesh.mesh(vol, spacing=sp)
    return calls


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
@pytest.mark.parametrize("name", ["lobster", "liver"])
def test_every_real_crossing_test_answers_as_the_reference(name, monkeypatch):
    """Every crossing test of a build (bands, joins, the repair's tubes): the reference path's answer,
    and the plain test's on the larger two-level ones and every two-level one that crosses."""
    calls = _build_calls(name, monkeypatch)
    assert len(calls) > 500
    two = [k for k, c in enumerate(calls) if len(np.unique(c[0][:, 2])) == 2]
    assert len(two) > len(calls) // 2
    for V, F, delay, got in calls:
        assert got == _any_kernel_reference(V, F, delay)
    hits = [k for k in two if calls[k][3] == 1][:30]
    big = sorted(two, key=lambda k: -len(calls[k][1]))[:20]
    assert hits
    for k in sorted(set(hits + big)):
        V, F, delay, got = calls[k]
        assert got == int(_plain(V, F)), k


def test_bands_with_a_far_point():
    """One point far off along x: the counting sort of the sweep then puts nearly every face in one
    bucket and the sweep's order comes from ``np.argsort`` instead (the same answers)."""
    rng = np.random.default_rng(24169)
    seen = [0, 0]
    for t in range(80):
        V, F = _band(rng, step=0.5, tidy=t % 2 == 0)
        V = V.copy()
        V[int(rng.integers(len(V))), 0] += 1e4 * (1 if t % 4 < 2 else -1)
        seen[_answers(V, F)] += 1
    assert min(seen) > 2  # (mostly crossing: the far point's faces reach over the rings)


def _remembered_pair_crosses(V, F, delay=DELAY):
    """The answer of ``_any_kernel_seen`` from an empty memory, checked against the reference path's;
    where it finds a crossing, the pair it remembers (two faces' corners) crosses by the plain test
    of those two faces alone, and is two faces of ``F``."""
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    mem = np.zeros(19)
    got = intersect._any_kernel_seen(V, F, delay, mem)
    assert got == _any_kernel_reference(V, F, delay)
    if got == 1:
        assert mem[18] == 1.0
        pair = mem[:18].reshape(6, 3)
        corners = {tuple(p) for p in V[F].reshape(-1, 3)}
        assert all(tuple(p) in corners for p in pair)
        assert _plain(pair, np.array([[0, 1, 2], [3, 4, 5]], dtype=np.int64))
    else:
        assert mem[18] == 0.0
    return got


def test_the_pair_the_sweeps_find_crosses():
    """The pair that the two-level and few-level sweeps report (their rules written out in the sweep,
    issue 16 round 28) is one that crosses: on random bands, on and off the dyadic grid, and on
    bands stacked on three rings (the few-level sweep)."""
    rng = np.random.default_rng(24170)
    seen = [0, 0]
    for t in range(160):
        V, F = _band(rng, step=0.5 if t % 3 else 1.0, tidy=t % 2 == 0)
        V = V.copy()
        if t % 4 == 1:
            V[:, :2] += rng.uniform(-1e-3, 1e-3, (len(V), 2))
        if t % 4 == 3:  # the band again one height up (three heights; its lower ring in the plane of the upper)
            V = np.vstack([V, V + [0.0, 0.0, V[:, 2].max() - V[:, 2].min()]])
            F = np.vstack([F, F + len(V) // 2])
        seen[_remembered_pair_crosses(V, F)] += 1
    assert min(seen) > 15


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
def test_the_pair_real_sweeps_find_crosses(monkeypatch):
    """Every crossing test of a lobster build that crosses: the pair remembered crosses."""
    calls = _build_calls("lobster", monkeypatch)
    hits = [c for c in calls if c[3] == 1]
    assert len(hits) > 100
    for V, F, delay, got in hits:
        assert _remembered_pair_crosses(V, F, delay) == 1
