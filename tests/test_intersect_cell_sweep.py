"""Issue 16 (ninth round): the slab phase finds the candidate pairs of a slab of many faces in a grid
of cells over x and y (``_cell_sweep``) instead of the sweep over x (``_x_sweep``).  Slab by slab
the two must test and report exactly the same pairs (compared on a real segmentation's mesh and on
random sectioned meshes, with and without the vertices' stars), and the slab phase as a whole must
still give the grid's pairs."""

import numpy as np
import pytest

import contourmesh
from contourmesh import intersect as I


def _slabs(V, F):
    """The slab phase's inputs for the whole mesh: canonical faces, levels, per face its lowest and
    highest level (-1 for a degenerate face), and the faces of each slab."""
    Fc = I.canonical_vertices(V)[F]
    lev, nlev = I._levels(np.ascontiguousarray(V[:, 2]))
    L = lev[Fc]
    lo = L.min(1).astype(np.int32)
    hi = L.max(1).astype(np.int32)
    bad = (Fc[:, 0] == Fc[:, 1]) | (Fc[:, 1] == Fc[:, 2]) | (Fc[:, 0] == Fc[:, 2])
    lo[bad] = -1
    hi[bad] = -1
    slabs = [np.flatnonzero((lo <= k) & (k < hi)).astype(np.int32) for k in range(max(nlev - 1, 0))]
    return Fc, lev, lo, hi, slabs


def _compare_per_slab(V, F, *, stars):
    """Every slab's pairs by both sweeps: the same (sorted) lists; returns (pairs, faces of the
    largest slab, box tests of the x sweep, of the cells)."""
    Fc, lev, lo, hi, slabs = _slabs(V, F)
    ws = np.zeros(1 + 3 * I._EXP_LEN)
    ws[0] = 1.0 if I._on_small_dyadic_grid(V) else 0.0
    star = I._star_certified(V, Fc) if stars else np.zeros(len(V), np.int8)
    found = 0
    work = [0, 0]
    for k, faces in enumerate(slabs):
        got = []
        for cells in (0, 1):
            sst = np.array([-1, 0], np.int64)  # (the stars as given, never filled in the kernel)
            pi, pj, w = I._slab_sweep_pairs(V, ws.copy(), Fc, star, sst, lev, lo, hi, faces, np.int64(k), np.int64(cells))
            got.append(sorted(zip(pi.tolist(), pj.tolist())))
            work[cells] += int(w)
        assert got[0] == got[1], (k, len(faces), len(got[0]), len(got[1]))
        assert len(set(got[0])) == len(got[0])
        found += len(got[0])
    return found, max((len(f) for f in slabs), default=0), work


def _random_big_sectioned(rng, n_levels, side, n_faces):
    """Faces between a few heights over a wide square (corners on a dyadic lattice, jittered off it
    for some), mostly over one slab, some flat, some through a plane (two slabs), a few long; many
    touching, shared and crossing cases."""
    z = np.sort(rng.choice(np.arange(0, 3 * n_levels) * 0.5, n_levels, replace=False))
    lev = np.repeat(np.arange(n_levels), side * side)
    xy = np.tile(np.argwhere(np.ones((side, side))) * 0.5, (n_levels, 1))
    V = np.c_[xy, z[lev]].astype(float)
    F = []
    while len(F) < n_faces:
        k = int(rng.integers(n_levels))
        kind = rng.random()
        span = 0 if kind < 0.2 else (2 if kind > 0.9 else 1)
        if k + span >= n_levels:
            continue
        reach = 8 if rng.random() < 0.02 else 2  # (a few long faces)
        c = rng.integers(0, side, 2)
        f = []
        for t in range(3):
            kk = k if (t == 0 or span == 0) else k + (span if t == 2 else int(rng.integers(0, span + 1)))
            p = np.clip(c + rng.integers(-reach, reach + 1, 2), 0, side - 1)
            f.append(kk * side * side + p[0] * side + p[1])
        if len(set(f)) < 3 or len({lev[v] for v in f}) == 1 and span:
            continue
        F.append(f)
    return V, np.array(F)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cell_sweep_equals_x_sweep_on_random_sectioned_meshes(seed):
    rng = np.random.default_rng(seed)
    V, F = _random_big_sectioned(rng, int(rng.integers(2, 4)), 40, 4000)
    if seed == 2:  # off the dyadic grid: the exact predicates' other branch, no coordinate shortcuts
        V = V * 0.1 + 0.37
    found = 0
    for stars in (False, True):
        n, largest, _ = _compare_per_slab(V, F, stars=stars)
        found += n
    assert found > 50 and largest >= I._CELL_SWEEP
    # the whole slab phase (the cells for its large slabs) still gives the grid's pairs
    grid = I.intersecting_pairs(V, F, method="grid")
    assert np.array_equal(I.intersecting_pairs(V, F, method="slabs"), grid)
    assert I.any_intersecting(V, F) == (len(grid) > 0)


def test_cell_sweep_equals_x_sweep_on_a_real_mesh(shared_data):
    """The repaired mesh of a real segmentation (the liver's label 255, slabs of thousands of faces
    between nearby heights), and the same mesh with its vertices snapped to a dyadic grid of 1/64
    (the coordinate shortcuts of the sweeps and exact float sums)."""
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == 255)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == 255
    m = contourmesh.mesh(crop, spacing=tuple(float(s) for s in z["spacing_xyz"][::-1]))
    V, F = m.vertices.copy(), m.faces.copy()
    _, largest, work = _compare_per_slab(V, F, stars=True)
    assert largest >= I._CELL_SWEEP
    assert work[1] < work[0]  # (fewer pairs of boxes met: what the cells are for)
    snapped = np.round(V * 64.0) / 64.0
    found, _, _ = _compare_per_slab(snapped, F, stars=False)
    assert found > 0
    grid = I.intersecting_pairs(snapped, F, method="grid")
    assert np.array_equal(I.intersecting_pairs(snapped, F, method="slabs"), grid)


@pytest.mark.parametrize("seed", [0, 1])
def test_plane_candidates_by_cells_equal_the_sweep_over_x(seed):
    """The planes' candidate pairs (``_sweep``: entries of groups 0 .. 3, closed xy boxes that
    overlap or touch, with and without ``need2``) by the grid of cells (whose cells list the entries
    of group 2 first, and with ``need2`` let only those start pairs) and by the sweep over x: the
    same pairs, each once; boxes on a coarse lattice (many touching), points, long and thin ones.
    With the entries' certified groups (``eg``): the same pairs less those of two entries of one
    group, by both."""
    rng = np.random.default_rng(seed)
    left = 0
    for trial in range(12):
        n = int(rng.integers(1, 3000))
        lo = rng.integers(0, 80, (n, 2)) * 0.5
        size = rng.integers(0, 4, (n, 2)) * 0.5
        size[rng.random(n) < 0.03] *= 30  # (a few long boxes)
        size[rng.random(n) < 0.2] = 0.0  # (points)
        if trial % 3 == 2:
            lo, size = lo * 0.1 + 0.37, size * 0.1
        box = np.c_[lo[:, 0], lo[:, 0] + size[:, 0], lo[:, 1], lo[:, 1] + size[:, 1]]
        grp = rng.integers(0, 4, n).astype(np.int8)
        ids = rng.permutation(n)[: max(1, n - int(rng.integers(0, 5)))].astype(np.int32)
        # the entries' certified groups (a few groups, many entries in none): a pair of one group
        # is no candidate, the others are those without groups
        eg = np.where(rng.random(n) < 0.6, rng.integers(0, 3, n), -1).astype(np.int64)
        for need2 in (0, 1):
            got = []
            for cells in (0, 1):
                for groups in (np.zeros(0, np.int64), eg):
                    a, b, _ = I._plane_candidates(*(np.ascontiguousarray(box[:, c]) for c in range(4)), grp, ids,
                                                  np.int64(need2), np.int64(cells), groups)
                    got.append(sorted((min(x, y), max(x, y)) for x, y in zip(a.tolist(), b.tolist())))
            assert got[0] == got[2], (trial, need2, len(got[0]), len(got[2]))
            assert got[1] == got[3], (trial, need2, len(got[1]), len(got[3]))
            assert len(set(got[2])) == len(got[2])
            assert got[1] == [(x, y) for x, y in got[0] if not (eg[x] >= 0 and eg[x] == eg[y])]
            left += len(got[0]) - len(got[1])
    assert left > 0  # (the groups left some pairs out)
