"""Issue 16 (tenth round, memory): the whole-mesh crossing test's grid (``_intersecting_pairs``)
makes and searches its (face, cell) entries a chunk of layers of cells at a time, and reads the
faces' boxes from the vertices instead of keeping a table of them.  It must report exactly the
pairs of the form it replaced, one hash table of every entry with a box table (kept here,
compiled, as the reference), for any chunk size: on random meshes (soups, folded spheres, stacks
of them along z, sectioned meshes with crossings and nudged heights), with and without the
vertices' stars and the touching-box shortcut, and on the real meshes the volume mesher tests
(the lobster's first build, with its crossing pairs, and a liver label)."""

import math

import numpy as np
import pytest
import trimesh
from numba import njit

import contourmesh
from contourmesh import intersect as I
from contourmesh import volumes
from contourmesh.intersect import (
    _KEY_BITS,
    _across_plane,
    _as_mesh_arrays,
    _cell,
    _o2,
    _pair_intersects,
    _push,
    _shares_certified,
    _star_due,
    _star_fill_levels,
    _touching_boxes,
    canonical_vertices,
)
from test_intersect_quick import _nudged
from test_intersect_slabs import _random_sectioned


# ------------------------------------------------------------------------------------------------
# the reference: the grid as it was before issue 16's tenth round (one table of every entry)
# ------------------------------------------------------------------------------------------------
@njit(cache=False)
def _count_cells_table(box, live, glo, h):
    total = 0
    for i in range(len(live)):
        if live[i] == 0:
            continue
        n = 1
        for k in range(3):
            n *= _cell(box[i, 3 + k], glo[k], h[k]) - _cell(box[i, k], glo[k], h[k]) + 1
        total += n
    return total


@njit(cache=False)
def _visit_cells_table(box, live, glo, h, mask, ny, nx, start, fill, ent_face, ent_key, store):
    for i in range(len(live)):
        if live[i] == 0:
            continue
        x0 = _cell(box[i, 0], glo[0], h[0])
        y0 = _cell(box[i, 1], glo[1], h[1])
        z0 = _cell(box[i, 2], glo[2], h[2])
        x1 = _cell(box[i, 3], glo[0], h[0])
        y1 = _cell(box[i, 4], glo[1], h[1])
        z1 = _cell(box[i, 5], glo[2], h[2])
        for cx in range(x0, x1 + 1):
            for cy in range(y0, y1 + 1):
                for cz in range(z0, z1 + 1):
                    key = (cz * ny + cy) * nx + cx
                    q = key & mask
                    if store == 0:
                        start[q] += 1
                    else:
                        r = fill[q]
                        ent_face[r] = i
                        ent_key[r] = key
                        fill[q] = r + 1


@njit(cache=False)
def _one_table_pairs(V, ws, F, star, sst, quick, budget, stop):
    """The pairs of ``_intersecting_pairs`` (same arguments but the chunk size) as found before
    the chunks: a box table of every face, every (face, cell) entry in one hash table."""
    m = len(F)
    box = np.empty((m, 6), np.float64)
    live = np.empty(m, np.int8)
    glo = np.empty(3, np.float64)
    ghi = np.empty(3, np.float64)
    for k in range(3):
        glo[k] = np.inf
        ghi[k] = -np.inf
    ext = np.empty((m, 3), np.float64)
    nlive = 0
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        for k in range(3):
            box[i, k] = min(V[a, k], min(V[b, k], V[c, k]))
            box[i, 3 + k] = max(V[a, k], max(V[b, k], V[c, k]))
        live[i] = 0
        if a == b or b == c or a == c:
            continue
        if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
            continue
        live[i] = 1
        nlive += 1
        for k in range(3):
            glo[k] = min(glo[k], box[i, k])
            ghi[k] = max(ghi[k], box[i, 3 + k])
            ext[nlive - 1, k] = box[i, 3 + k] - box[i, k]
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    npairs = np.int64(0)
    if nlive < 2:
        return pi[:0], pj[:0]
    h = np.empty(3, np.float64)
    for k in range(3):
        h[k] = np.median(ext[:nlive, k])
    hbig = max(h[0], max(h[1], h[2]))
    for k in range(3):
        hmin = max((ghi[k] - glo[k]) / (2.0 ** _KEY_BITS - 2.0), hbig / 16.0)
        if not h[k] > hmin:
            h[k] = hmin
        if not h[k] > 0.0:
            h[k] = 1.0
    limit = budget * nlive
    total = _count_cells_table(box, live, glo, h)
    while total > limit:
        for k in range(3):
            h[k] *= 1.5
        total = _count_cells_table(box, live, glo, h)
    nb = 1
    while nb < total:
        nb *= 2
    mask = nb - 1
    start = np.zeros(nb + 1, np.int32)
    ny = _cell(ghi[1], glo[1], h[1]) + 1
    nx = _cell(ghi[0], glo[0], h[0]) + 1
    dummy = np.empty(0, np.int32)
    _visit_cells_table(box, live, glo, h, mask, ny, nx, start, dummy, dummy, np.empty(0, np.int64), np.int64(0))
    acc = 0
    for q in range(nb):
        cnt = start[q]
        start[q] = acc
        acc += cnt
    start[nb] = acc
    ent_face = np.empty(acc, np.int32)
    ent_key = np.empty(acc, np.int64)
    _visit_cells_table(box, live, glo, h, mask, ny, nx, start, start, ent_face, ent_key, np.int64(1))
    for q in range(nb, 0, -1):
        start[q] = start[q - 1]
    start[0] = 0
    for q in range(nb):
        s0 = start[q]
        s1 = start[q + 1]
        for r in range(s0, s1):
            i0 = ent_face[r]
            key = ent_key[r]
            for t in range(r + 1, s1):
                if ent_key[t] != key:
                    continue
                j0 = ent_face[t]
                i = np.int64(min(i0, j0))
                j = np.int64(max(i0, j0))
                if (box[i, 0] > box[j, 3] or box[j, 0] > box[i, 3] or box[i, 1] > box[j, 4]
                        or box[j, 1] > box[i, 4] or box[i, 2] > box[j, 5] or box[j, 2] > box[i, 5]):
                    continue
                cx = _cell(max(box[i, 0], box[j, 0]), glo[0], h[0])
                cy = _cell(max(box[i, 1], box[j, 1]), glo[1], h[1])
                cz = _cell(max(box[i, 2], box[j, 2]), glo[2], h[2])
                if (cz * ny + cy) * nx + cx != key:
                    continue
                if _star_due(sst):
                    _star_fill_levels(V, F, star, np.zeros(len(V), np.int64), np.int64(0), np.int64(0))
                if _shares_certified(F, star, i, j):
                    continue
                hit = _across_plane(V, ws, F, i, j)
                if hit < 0 and quick == 1:
                    hit = _touching_boxes(V, ws, F, i, j)
                if hit < 0:
                    hit = 1 if _pair_intersects(V, ws, F, i, j) else 0
                if hit == 1:
                    pi, pj, npairs = _push(pi, pj, npairs, i, j)
                    if npairs == stop:
                        return pi[:npairs], pj[:npairs]
    return pi[:npairs], pj[:npairs]


# ------------------------------------------------------------------------------------------------
# both forms on the same inputs
# ------------------------------------------------------------------------------------------------
def _inputs(V, F):
    """The kernels' arrays as ``_pairs`` makes them: coordinates, canonical faces, workspace."""
    Va, Fa = _as_mesh_arrays(V, F)
    Va = I._exact_range(Va).copy()
    Fc = np.ascontiguousarray(canonical_vertices(Va)[Fa], dtype=np.int64)
    ws = np.zeros(1 + 3 * I._EXP_LEN)
    ws[0] = 1.0 if I._on_small_dyadic_grid(Va) else 0.0
    return Va, Fc, ws


def _run(kernel, V, Fc, ws, *, quick, delay, stop=0, chunk=None):
    star = np.zeros(len(V), np.int8)
    sst = np.array([0 if quick else -1, len(Fc) // 8 + delay], np.int64)
    args = (V, ws.copy(), Fc, star, sst, np.int64(1 if quick else 0), np.int64(8), np.int64(stop))
    if chunk is not None:  # (the kernel's: a chunk size and no groups)
        args = args + (np.int64(chunk), np.zeros(0, np.int64))
    pi, pj = kernel(*args)
    return sorted(zip(pi.tolist(), pj.tolist()))


def _layers(V, Fc):
    """The number of layers of cells and of live faces of the kernel's grid (computed again here,
    to check that the meshes below are cut into several chunks)."""
    T = V[Fc]
    lo, hi = T.min(axis=1), T.max(axis=1)
    live = (Fc[:, 0] != Fc[:, 1]) & (Fc[:, 1] != Fc[:, 2]) & (Fc[:, 0] != Fc[:, 2])
    live &= np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1) > 0
    lo, hi = lo[live], hi[live]
    glo, ghi = lo.min(axis=0), hi.max(axis=0)
    h = np.median(hi - lo, axis=0)
    hbig = h.max()
    for k in range(3):
        h[k] = max(h[k], (ghi[k] - glo[k]) / (2.0 ** _KEY_BITS - 2.0), hbig / 16.0) or 1.0
    cells = lambda h: (np.floor((hi - glo) / h) - np.floor((lo - glo) / h) + 1).prod(axis=1).sum()  # noqa: E731
    while cells(h) > 8 * len(lo):
        h = h * 1.5
    return int(math.floor((ghi[2] - glo[2]) / h[2])) + 1, int(live.sum())


def _same(V, F, chunks=(1, 5, 64, I._GRID_CHUNK), delays=(I._STAR_DELAY, -10 ** 9)):
    """Every chunk size gives the reference's pairs, with and without the shortcuts (stars at once
    or after the default delay), and a stopped search some of them.  Returns the pairs."""
    V, Fc, ws = _inputs(V, F)
    want = None
    for quick in (True, False):
        for delay in (delays if quick else delays[:1]):
            ref = _run(_one_table_pairs, V, Fc, ws, quick=quick, delay=delay)
            assert want is None or ref == want
            want = ref
            for chunk in chunks:
                got = _run(I._intersecting_pairs, V, Fc, ws, quick=quick, delay=delay, chunk=chunk)
                assert got == ref, (chunk, quick, delay, len(got), len(ref))
    first = _run(I._intersecting_pairs, V, Fc, ws, quick=True, delay=I._STAR_DELAY, stop=1, chunk=chunks[0])
    assert len(first) == min(1, len(want)) and set(first) <= set(want)
    return want


def _stack(rng, n):
    """``n`` jittered icospheres stacked along z, each overlapping the next: many layers of cells,
    folds within each sphere and crossings between neighbours."""
    s = trimesh.creation.icosphere(2)
    Vs, Fs = [], []
    for k in range(n):
        Vs.append(s.vertices + rng.normal(0, 0.05, s.vertices.shape) + (rng.normal(0, 0.3), 0.0, 1.7 * k))
        Fs.append(s.faces + k * len(s.vertices))
    return np.concatenate(Vs), np.concatenate(Fs)


def test_random_meshes_same_pairs_for_every_chunk_size():
    rng = np.random.default_rng(118)
    found = chunked = 0
    for it in range(24):
        kind = it % 4
        if kind == 0:
            V, F = _stack(rng, int(rng.integers(2, 5)))
        elif kind == 1:  # a soup on a coarse dyadic grid: ties, touching and coplanar faces
            V, F = rng.integers(0, 8, (80, 3)) * 0.5, rng.integers(0, 80, (120, 3))
        elif kind == 2:  # the same off the grid, long in z
            V = rng.integers(-3, 4, (60, 3)) * [0.1, 0.3, 3.0] + [105.7, -217.3, -80.44]
            F = rng.integers(0, 60, (90, 3))
        else:  # sectioned, with heights nudged off the planes as the repair does
            V, F = _random_sectioned(rng, int(rng.integers(3, 9)), 40, 80, 0.3)
            V = _nudged(rng, V, 0.3, 0.2)
        found += len(_same(V, F)) > 0
        nz, nlive = _layers(*_inputs(V, F)[:2])
        chunked += 1 < nz <= nlive
    assert found >= 12 and chunked >= 16, (found, chunked)


def test_degenerate_and_tiny_inputs():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [0, 0, 1.0]])
    assert _same(V, np.array([[0, 1, 2], [0, 1, 3]])) == []  # a collinear face: skipped
    assert _same(V, np.array([[0, 1, 2], [0, 1, 1]])) == []  # a repeated vertex
    assert _same(V, np.array([[0, 1, 2], [2, 1, 0]])) == [(0, 1)]  # a face repeated
    assert _same(V, np.array([[0, 1, 2], [0, 1, 4]])) == []  # a shared edge, not folded
    flat = np.c_[np.random.default_rng(1).random((30, 2)), np.zeros(30)]  # one layer of cells
    _same(flat, np.random.default_rng(2).integers(0, 30, (40, 3)))


def _first_build(vol, spacing=None):
    """The mesh the volume mesher tests whole first (its first build, before the repair moves
    anything), as ``volumes._crossing_pairs`` passes it to ``intersecting_pairs``."""
    seen = []
    real = volumes.intersecting_pairs

    def keep(V, F, **kw):
        seen.append((np.array(V), np.array(F)))
        return real(V, F, **kw)

    volumes.intersecting_pairs = keep
    try:
        contourmesh.mesh(vol, **({} if spacing is None else {"spacing": spacing}))
    finally:
        volumes.intersecting_pairs = real
    assert seen
    return seen[0]


def test_the_lobsters_first_build(shared_data):
    """The mesh of issue 16's memory figures: 396k faces in some 97 layers of cells, 2M entries,
    with crossing pairs (the repair's work)."""
    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    V, F = _first_build(np.transpose(z["volume"], (2, 1, 0)) > 60)
    assert len(F) > 300_000
    nz, nlive = _layers(*_inputs(V, F)[:2])
    assert nz > 20
    got = _same(V, F, chunks=(1000, I._GRID_CHUNK), delays=(I._STAR_DELAY,))
    assert len(got) > 0
    assert got == sorted(map(tuple, I.intersecting_pairs(V, F, method="grid").tolist()))


def test_a_liver_label(shared_data):
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == 85)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == 85
    V, F = _first_build(crop, tuple(float(s) for s in z["spacing_xyz"][::-1]))
    _same(V, F, chunks=(7, 500, I._GRID_CHUNK))
    rng = np.random.default_rng(85)
    W = V.copy()
    W[rng.integers(len(W), size=5)] += rng.uniform(-3, 3, (5, 3))  # crossings put in
    assert len(_same(W, F, chunks=(500, I._GRID_CHUNK), delays=(I._STAR_DELAY,))) > 0


@pytest.mark.parametrize("budget", [2, 8, 64])
def test_budget_changes_nothing(budget):
    rng = np.random.default_rng(budget)
    V, F = _stack(rng, 3)
    assert np.array_equal(I.intersecting_pairs(V, F, budget=budget, method="grid"),
                          I.intersecting_pairs(V, F, method="grid"))


def test_cell_sizes_from_a_sample_change_nothing():
    """A mesh of at least ``2 * _MEDIAN_SAMPLE`` live faces takes its cell sizes from a sample of
    its faces (issue 16's twenty-first round): its pairs are still those of the one-table
    reference (cell sizes from every face), and those of its parts tested alone (far apart, each
    small enough for every face to count)."""
    rng = np.random.default_rng(21)
    V0, F0 = _stack(rng, 3)
    Vs, Fs, want = [], [], []
    n = 0
    k = 0
    while n < 2 * I._MEDIAN_SAMPLE + 1000:
        # copies far apart along x, at three scales (so that the faces' extents vary along the list)
        V = V0 * (1.0 + k % 3) + (40.0 * k, 0.0, 0.0)
        part = I.intersecting_pairs(V, F0, method="grid")
        want.append(part + n)
        Vs.append(V)
        Fs.append(F0 + len(V0) * k)
        n += len(F0)
        k += 1
    V, F = np.concatenate(Vs), np.concatenate(Fs)
    want = np.concatenate(want)
    assert len(want) > 100
    got = I.intersecting_pairs(V, F, method="grid")
    assert np.array_equal(got, want)
    Va, Fc, ws = _inputs(V, F)
    assert _layers(Va, Fc)[1] >= 2 * I._MEDIAN_SAMPLE  # (the sampled path)
    ref = _run(_one_table_pairs, Va, Fc, ws, quick=True, delay=I._STAR_DELAY)
    assert ref == sorted(map(tuple, want.tolist()))
