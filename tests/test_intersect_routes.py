"""Issue 16: ``method="auto"`` takes the grid for meshes off the small dyadic grid of fewer than
``_GRID_FACES`` faces (the mesher's bands and joins whose heights are moved by hairs) and the slab
phase for the others (or the split over threads; the grid where slabs give up, as on the lobster's
repaired mesh and its 2,058 heights).  The route changes the speed only: the
pairs must be those of the grid and of the slab phase, exactly, also where heights differ from a
section plane by one unit in the last place or by tiny amounts, and ``any_intersecting`` (one
compiled call with the same routes) must answer as the whole list does."""

import numpy as np
import pytest

import contourmesh
import contourmesh.intersect as I
from contourmesh.intersect import _as_mesh_arrays, _pairs, any_intersecting, canonical_vertices, intersecting_pairs
from test_intersect import reference_pairs
from test_intersect_slabs import _our_meshes, _random_sectioned, _sectioned


def _agree(V, F):
    """The pairs by the grid, by slabs (where the mesh is sectioned), by ``auto``; the first pair
    of each; ``any_intersecting``: all the same.  Returns the number of pairs."""
    grid = intersecting_pairs(V, F, method="grid")
    assert np.array_equal(intersecting_pairs(V, F), grid)
    sectioned = _sectioned(V, F)
    if sectioned:
        try:
            slabs = intersecting_pairs(V, F, method="slabs")
        except ValueError:  # (ties of heights counted otherwise than by _sectioned: no structure)
            slabs = grid
        assert np.array_equal(slabs, grid), (len(slabs), len(grid))
    assert any_intersecting(V, F) == (len(grid) > 0)
    Va, Fa = _as_mesh_arrays(V, F)
    every = set(map(tuple, grid.tolist()))
    for method in ("auto", "grid"):
        first = _pairs(Va, Fa, canonical_vertices(Va), 8, method, stop=1)
        assert len(first) == min(1, len(grid)) and all(tuple(p) in every for p in first.tolist())
    return len(grid)


def _perturbed(rng, V, kind):
    """V with some vertex heights moved: by one unit in the last place up or down, by 1e-9, or by
    up to 1e-4 (the repair's hairs), on about a third of the vertices."""
    W = V.copy()
    # (not heights 0: one unit in the last place there is subnormal, where the exact predicates'
    # products underflow; the reference and the kernels then disagree, in main as well)
    pick = (rng.random(len(W)) < 1 / 3) & (W[:, 2] != 0)
    z = W[pick, 2]
    if kind == "ulp":
        W[pick, 2] = np.where(rng.random(len(z)) < 0.5, np.nextafter(z, np.inf), np.nextafter(z, -np.inf))
    elif kind == "1e-9":
        W[pick, 2] = z + rng.choice([-1e-9, 1e-9], len(z))
    else:
        W[pick, 2] = z + rng.uniform(-1e-4, 1e-4, len(z))
    return W


@pytest.mark.parametrize("kind", ["ulp", "1e-9", "1e-4"])
def test_random_sectioned_meshes_with_heights_moved_by_hairs(kind):
    rng = np.random.default_rng({"ulp": 1, "1e-9": 2, "1e-4": 3}[kind])
    hits = 0
    for t in range(40):
        V, F = _random_sectioned(rng, int(rng.integers(2, 6)), 30, 40, 0.2)
        W = _perturbed(rng, V, kind)
        n = _agree(W, F)
        hits += n > 0
        if t < 8:  # and the exact rule, pair by pair in rationals
            assert set(map(tuple, intersecting_pairs(W, F).tolist())) == reference_pairs(W, F)
        _agree(V, F)  # (the dyadic original: the slab route)
    assert hits >= 20, hits


@pytest.mark.parametrize("kind", ["ulp", "1e-4"])
def test_our_meshes_with_heights_moved_by_hairs(kind):
    """Meshes of small volumes, with heights moved: meshes on many heights near few planes (the
    lobster's case: the slab phase's faces span many slabs), with crossings where a hair is enough."""
    rng = np.random.default_rng(7)
    n = 0
    for V, F in _our_meshes(seed=3, n=9):
        _agree(_perturbed(rng, V, kind), F)
        n += 1
    assert n >= 10


def test_auto_routes(monkeypatch):
    """``auto`` asks the slab phase only for meshes on a small dyadic grid, meshes of at least
    ``_GRID_FACES`` faces, meshes on two heights (bands between two rings), or to split a large
    mesh over two threads; the grid decides the others (the same pairs)."""
    calls = []
    real = I._slab_pairs
    monkeypatch.setattr(I, "_slab_pairs", lambda *a: calls.append(1) or real(*a))
    V, F = _random_sectioned(np.random.default_rng(4), 12, 200, 300, 0.1)
    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    on_grid = intersecting_pairs(V, F)
    assert len(calls) == 1 and I._on_small_dyadic_grid(V)
    W = V * 0.1 + 0.37  # off the dyadic grid
    assert not I._on_small_dyadic_grid(W)
    off_grid = intersecting_pairs(W, F)
    assert len(calls) == 1
    assert np.array_equal(on_grid, intersecting_pairs(V, F, method="grid"))
    assert np.array_equal(off_grid, intersecting_pairs(W, F, method="grid")) and len(calls) == 1
    assert np.array_equal(intersecting_pairs(W, F, method="slabs"), off_grid) and len(calls) == 2
    monkeypatch.setattr(I, "_GRID_FACES", len(F))  # a large mesh off the grid: slabs (memory)
    assert np.array_equal(intersecting_pairs(W, F), off_grid) and len(calls) == 3
    monkeypatch.setattr(I, "_GRID_FACES", len(F) + 1)
    split = []
    real_split = I._split_slab_pairs
    monkeypatch.setattr(I, "_split_slab_pairs", lambda *a: split.append(real_split(*a)) or split[-1])
    monkeypatch.setattr(I, "_SPLIT_FACES", 10)
    monkeypatch.setenv("CONTOURMESH_THREADS", "2")
    assert np.array_equal(intersecting_pairs(W, F), off_grid)
    assert len(split) == 1 and split[0] is not None and len(off_grid) > 0


@pytest.mark.parametrize("label", [85, 255])
def test_liver_meshes_by_every_route(shared_data, label):
    """The repaired mesh of a real segmentation (heights moved by the repair: off the dyadic grid),
    by every broad phase, and with its heights moved by hairs more."""
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == label)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == label
    m = contourmesh.mesh(crop, spacing=tuple(float(s) for s in z["spacing_xyz"][::-1]))
    V, F = m.vertices.copy(), m.faces.copy()
    assert _agree(V, F) == 0
    rng = np.random.default_rng(label)
    for kind in ("ulp", "1e-4"):
        _agree(_perturbed(rng, V, kind), F)


@pytest.mark.parametrize("kind", ["tiny", "huge", "subnormal"])
def test_tiny_huge_and_subnormal_coordinates_keep_the_exact_pairs(kind):
    """The exact predicates' products underflowed for tiny coordinates (a mesh scaled by 2^-1040
    had no pairs where rationals find dozens) and overflowed for huge ones: a mesh is now scaled by a
    power of two into their range (the same signs), and one whose nonzero magnitudes span too far
    for any such scaling (a height of 5e-324 or 1e-300 beside 3.5) is refused with a clear error."""
    from test_intersect_slabs import _random_sectioned

    checked = 0
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        V, F = _random_sectioned(rng, 4, 30, 40, 0.3)
        if kind == "subnormal":
            W = V.copy()
            for tiny in (5e-324, 1e-300):
                W[F[0, 0], 2] = tiny  # (a used vertex)
                with pytest.raises(ValueError, match="orders of magnitude"):
                    intersecting_pairs(W, F)
                with pytest.raises(ValueError, match="orders of magnitude"):
                    any_intersecting(W, F)
            continue
        W = V * 2.0 ** (-1040 if kind == "tiny" else 1000)
        want = np.array(sorted(reference_pairs(W, F)), dtype=np.int64).reshape(-1, 2)
        assert np.array_equal(intersecting_pairs(W, F), want)
        assert np.array_equal(intersecting_pairs(W, F, method="grid"), want)
        assert any_intersecting(W, F) == (len(want) > 0)
        assert np.array_equal(intersecting_pairs(V, F), want)  # (the scaling keeps every sign)
        checked += len(want) > 0
    if kind != "subnormal":
        assert checked >= 3  # (meshes with pairs: a test that an underflow to "no pair" would fail)


def test_auto_takes_the_slabs_for_two_heights_off_the_grid(monkeypatch):
    """A mesh off the dyadic grid whose vertices lie on two heights (a band between two rings, with
    or without its caps) goes to the slab phase in ``intersecting_pairs`` and ``any_intersecting``
    alike; a third height sends it back to the grid.  The same pairs either way."""
    calls = []
    real = I._slab_pairs
    monkeypatch.setattr(I, "_slab_pairs", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setenv("CONTOURMESH_THREADS", "1")
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t)])
    n = len(ring)
    V = np.vstack([np.column_stack([ring, np.zeros(n)]), np.column_stack([1.1 * ring + 0.05, np.full(n, 0.7)])])
    F = np.array([f for i in range(n) for f in ((i, (i + 1) % n, n + i), ((i + 1) % n, n + (i + 1) % n, n + i))])
    assert not I._on_small_dyadic_grid(V)
    want = intersecting_pairs(V, F, method="grid")
    assert np.array_equal(intersecting_pairs(V, F), want) and len(calls) == 1
    W = V.copy()
    W[0, 2] = 0.3  # a third height: the grid
    assert np.array_equal(intersecting_pairs(W, F), intersecting_pairs(W, F, method="grid")) and len(calls) == 1
    # any_intersecting's compiled route (the kernel sees the real _slab_pairs): a crossing put in (a
    # top point pulled over the band) is found
    monkeypatch.undo()
    assert not I.any_intersecting(V, F)
    X = V.copy()
    X[n + 3, :2] = -X[n + 3, :2]
    assert I.any_intersecting(X, F) == (len(intersecting_pairs(X, F, method="grid")) > 0) == True  # noqa: E712

