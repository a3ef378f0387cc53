"""Issue 16, eleventh round: ``any_intersecting``'s compiled call certifies no vertex stars on a mesh
of fewer than 1.25 faces per vertex (a band between two rings: every vertex on a ring, so no star could
be certified), and the slab sweeps' test of a candidate (``_slab_hit``) finds the faces' common
corners once.  Neither may change an answer: on bands, on closed meshes (stars certified), with
crossings and without, on and off the dyadic grid, and on the real joins of a lobster build, the
answer must be that of the general test with no shortcut (``_pairs(..., quick=False)``, the old
form of every shortcut) and of the grid broad phase (which uses neither change)."""

import os

import numpy as np
import pytest

from contourmesh import intersect
from contourmesh.intersect import _any_kernel, _as_mesh_arrays, _pairs, any_intersecting, canonical_vertices
from test_intersect_bands import _band
from test_intersect_slabs import _random_sectioned


def _plain(V, F):
    """The pairs by the general test, every candidate of the grid tested."""
    Va, Fa = _as_mesh_arrays(V, F)
    return _pairs(Va, Fa, canonical_vertices(Va), 8, "grid", quick=False)


def _stars_off(V, F):
    """Whether the compiled call's rule leaves the stars out for this mesh (m < 1.25 nv)."""
    return 4 * len(F) < 5 * len(np.unique(canonical_vertices(V)[F]))


def _closed_sectioned(rng, off_grid):
    """A closed mesh of stacked sections (a marching-cubes surface of a random blob), nudged off the
    dyadic grid where asked."""
    from scipy import ndimage
    from skimage.measure import marching_cubes

    v = ndimage.gaussian_filter(rng.random((10, 12, 12)), 1.3) > 0.5
    v = np.pad(v, 1)
    V, F, _, _ = marching_cubes(v.astype(np.float32), 0.5, method="lorensen")
    V = V.astype(np.float64)
    if off_grid:
        V[:, :2] += rng.uniform(-1e-3, 1e-3, (len(V), 2))
    return V, F.astype(np.int64)


@pytest.mark.parametrize("step", [0.5, 0.3])
def test_bands_answer_as_the_plain_test(step):
    rng = np.random.default_rng(1611)
    seen = [0, 0]
    for t in range(120):
        V, F = _band(rng, step=step, tidy=t % 2 == 0)
        assert _stars_off(V, F)
        want = len(_plain(V, F)) > 0
        assert any_intersecting(V, F) == want
        assert _any_kernel(np.ascontiguousarray(V), F, np.int64(intersect._STAR_DELAY)) == int(want)
        seen[int(want)] += 1
    assert min(seen) > 10  # bands that cross and bands that do not


@pytest.mark.parametrize("off_grid", [False, True])
def test_closed_meshes_keep_their_stars_and_answers(off_grid, monkeypatch):
    monkeypatch.setattr(intersect, "_STAR_DELAY", -10 ** 9)  # stars at the first pair tested
    rng = np.random.default_rng(16110 + off_grid)
    for t in range(6):
        V, F = _closed_sectioned(rng, off_grid)
        assert not _stars_off(V, F)
        if t % 2:  # a crossing put in: one vertex pushed through the surface
            V = V.copy()
            V[rng.integers(len(V))] += rng.normal(0, 2.0, 3)
        assert any_intersecting(V, F) == (len(_plain(V, F)) > 0)


@pytest.mark.parametrize("flat_share", [0.0, 0.3])
def test_random_sectioned_meshes_answer_as_the_plain_test(flat_share):
    rng = np.random.default_rng(1612)
    for _ in range(60):
        V, F = _random_sectioned(rng, int(rng.integers(2, 5)), int(rng.integers(8, 30)), int(rng.integers(4, 40)),
                                 flat_share)
        assert any_intersecting(V, F) == (len(_plain(V, F)) > 0)


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
def test_real_joins_answer_as_the_plain_test(monkeypatch):
    """Every crossing test of a lobster build's bands and joins (a sample of the larger ones and every
    one that crosses): the same answer as the plain test."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import volume_speed as vs

        vol, sp = vs.make_input("lobster")
    except Exception as exc:  # pragma: no cover - data missing
        pytest.skip(f"lobster not available: {exc}")
    import contourmesh
    from contourmesh import bands

    calls = []
    orig, orig_seen, orig_band = intersect._any_kernel, intersect._any_kernel_seen, bands._band_any

    def wrap(V, F, delay):
        got = orig(V, F, delay)
        calls.append((V.copy(), F.copy(), got))
        return got

    def wrap_seen(V, F, delay, mem):  # (any_intersecting's entry, with the memory of the last pair)
        got = orig_seen(V, F, delay, mem)
        calls.append((V.copy(), F.copy(), got))
        return got

    def wrap_band(P, f, delay, mem):  # (a band's test: its points with the pinches split)
        got = orig_band(P, f, delay, mem)
        Q, status = bands._pinch_split(P, f)
        if status < 2:
            calls.append((Q.copy(), f.copy(), got))
        return got

    monkeypatch.setattr(intersect, "_any_kernel", wrap)
    monkeypatch.setattr(intersect, "_any_kernel_seen", wrap_seen)
    monkeypatch.setattr(bands, "_band_any", wrap_band)
    contourmesh.mesh(vol, spacing=sp)
    monkeypatch.setattr(intersect, "_any_kernel", orig)
    monkeypatch.setattr(intersect, "_any_kernel_seen", orig_seen)
    monkeypatch.setattr(bands, "_band_any", orig_band)
    assert len(calls) > 500
    big = sorted(range(len(calls)), key=lambda k: -len(calls[k][1]))[:40]
    hits = [k for k in range(len(calls)) if calls[k][2] == 1][:40]
    assert hits and any(_stars_off(calls[k][0], calls[k][1]) for k in big)
    for k in sorted(set(big + hits)):
        V, F, got = calls[k]
        assert got == int(len(_plain(V, F)) > 0), k
