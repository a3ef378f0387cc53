"""Shortcuts of the general mesher (issue 16) against the plain code they replace: each must give the
same numbers, so that the meshes stay the same bytes."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import volumes
from contourmesh.bands import caps
from contourmesh.geometry import grid_to_xy


def _masks(seed, shape=(6, 40, 44)):
    """Slices with forks, holes, specks and one-pixel parts (smoothed noise, two thresholds)."""
    rng = np.random.default_rng(seed)
    v = ndimage.gaussian_filter(rng.random(shape), 1.2)
    m = v > np.quantile(v, 0.55)
    m[:, ::7, ::9] ^= True  # specks and pin holes
    return m


@pytest.mark.parametrize("grid", [(0.0, 0.0, 1.0, 1.0), (-3.7, 12.25, 0.3, 0.7), (1e3, -1e3, 2.5, 0.125)])
@pytest.mark.parametrize("polygon", ["mlp", "dss", "none"])
def test_ring_boxes_equal_the_boxes_of_the_made_rings(grid, polygon):
    ox, oy, dx, dy = grid
    to_center, to_corner = grid_to_xy(ox, oy, dx, dy)
    seen_holes = 0
    for seed in (1, 2):
        for mask in _masks(seed):
            s = volumes._Slice(mask, polygon, to_corner, to_center)
            seen_holes += sum(len(h) for h in s.holes)
            lo, hi = volumes._ring_boxes(s)
            rlo, rhi = volumes._ring_boxes_reference(s)
            assert lo.dtype == rlo.dtype == np.float64 and lo.shape == rlo.shape == (s.n, 2)
            assert np.array_equal(lo, rlo) and np.array_equal(hi, rhi)
            # the compiled pass against the numpy form it replaced, bit for bit (signs of zeros too)
            nlo, nhi = volumes._ring_boxes_numpy(s)
            assert lo.tobytes() == nlo.tobytes() and hi.tobytes() == nhi.tobytes()
    assert seen_holes > 0  # (the samples have holes)


@pytest.mark.parametrize("polygon", ["mlp", "dss"])
def test_a_slice_labelled_in_its_box_is_the_slice_labelled_whole(polygon):
    to_center, to_corner = grid_to_xy(0.5, -2.0, 0.75, 1.25)
    for seed in (3, 4):
        for mask in _masks(seed):
            full = np.zeros((60, 70), dtype=bool)
            full[9:49, 13:57] = mask
            box = np.s_[8:50, 12:58]  # (a margin round the pixels, as the sections' boxes have)
            a = volumes._Slice(full, polygon, to_corner, to_center)
            b = volumes._Slice(full, polygon, to_corner, to_center, box=box)
            assert a.n == b.n and a.objects == b.objects
            assert a.labels.dtype == b.labels.dtype and np.array_equal(a.labels, b.labels)
            for c in range(a.n):
                assert np.array_equal(a.outer[c], b.outer[c])
                assert len(a.holes[c]) == len(b.holes[c])
                assert all(np.array_equal(p, q) for p, q in zip(a.holes[c], b.holes[c]))
                assert np.array_equal(a.crack_outer_c[c], b.crack_outer_c[c])
                assert all(np.array_equal(p, q) for p, q in zip(a.crack_holes_c[c], b.crack_holes_c[c]))
                assert all(np.array_equal(p, q) for p, q in zip(a.hole_masks[c][1], b.hole_masks[c][1]))


def _rings_of_slices(seed):
    """Outer and hole polygons (MLP and crack rings: long straight runs) of random slices."""
    to_center, to_corner = grid_to_xy(0.0, 0.0, 1.0, 1.0)
    out = []
    for mask in _masks(seed):
        for polygon in ("mlp", "none"):
            s = volumes._Slice(mask, polygon, to_corner, to_center)
            out += [(s.outer[c], list(s.holes[c])) for c in range(s.n)]
    return out


def test_collinear_runs_compiled_equal_the_reference():
    rng = np.random.default_rng(5)
    rings = [r for seed in (1, 2) for o, hs in _rings_of_slices(seed) for r in [o] + hs]
    # rings with runs nearly straight (round-off off the line), spikes and repeated points
    for n in (3, 4, 5, 9, 40):
        t = np.sort(rng.random(n)) * 2 * np.pi
        r = np.c_[np.cos(t), np.sin(t)]
        rings += [r, np.repeat(r, 2, axis=0), r + rng.normal(scale=1e-12, size=r.shape)]
    sq = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2], [2, 2], [1, 2], [0, 2], [0, 1]], float)
    rings += [sq, sq + 1e-10 * rng.normal(size=sq.shape), np.r_[sq[:4], [[2, 0]], sq[4:]]]
    dropped = 0
    for r in rings:
        for tol in (caps.COLLINEAR_TOL, 1e-3):
            got, ref = caps.collinear_runs(r, tol), caps._collinear_runs_reference(r, tol)
            assert got.dtype == ref.dtype and np.array_equal(got, ref)
            dropped += int((~got).sum())
    assert dropped > 0


def test_caps_with_the_compiled_steps_equal_the_reference_steps(monkeypatch):
    """cap_faces with the compiled collinear runs, flat-triangle test and T-junction fast path
    against the same function with the references (every edge sent to the exact T-junction
    test): the same faces, or the same error."""
    def run(outer, holes, up):
        try:
            return caps.cap_faces(outer, holes, upward=up)
        except ValueError as e:
            return type(e).__name__

    cases = [(o, hs, up) for seed in (1, 2, 6) for o, hs in _rings_of_slices(seed) for up in (True, False)]
    # rings that touch or cross each other (no valid cap), and a hole outside its ring
    sq = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    cases += [(sq, [sq[::-1] * 0.5 + 1], True), (sq, [sq[::-1] * 0.5 + 3], True), (sq, [sq[::-1]], False),
              (np.r_[sq, [[2, 2]]], [], True)]
    got = [run(*c) for c in cases]
    monkeypatch.setattr(caps, "collinear_runs", caps._collinear_runs_reference)
    monkeypatch.setattr(caps, "_drop_flat_triangles", caps._drop_flat_triangles_reference)
    monkeypatch.setattr(caps, "_busy_edges", lambda v, e, cand: np.ones(len(e), dtype=bool))
    ref = [run(*c) for c in cases]
    assert sum(isinstance(r, np.ndarray) and len(r) > 0 for r in ref) > 50
    for g, r in zip(got, ref):
        assert type(g) is type(r)
        if isinstance(r, np.ndarray):
            assert g.dtype == r.dtype and np.array_equal(g, r)
        else:
            assert g == r


def _cap_faces_reference(polygon_xy, holes_xy=(), upward: bool = True) -> np.ndarray:
    """``cap_faces`` step by step (each check a numpy step or a kernel call of its own): the
    reference of its compiled tail (``_cap_tail``)."""
    outer, holes = caps._cap_rings(polygon_xy, holes_xy)
    empty = np.empty((0, 3), dtype=np.int64)
    if len(outer) < 3 or caps._signed_area(outer) == 0.0:
        return empty

    import mapbox_earcut

    rings = [outer] + [h for h in holes if len(h) >= 3 and caps._signed_area(h) != 0.0]
    offsets = np.cumsum([0] + [len(r) for r in [outer] + holes])[:-1]
    # global index of each vertex handed to earcut
    glob = [np.arange(len(outer))]
    for k, h in enumerate(holes):
        if len(h) >= 3 and caps._signed_area(h) != 0.0:
            glob.append(offsets[k + 1] + np.arange(len(h)))
    glob = np.concatenate(glob).astype(np.int64)
    verts = np.ascontiguousarray(np.vstack(rings))
    ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
    # take collinear runs out of each ring (kept: the runs' ends), ear-clip the rest, put them back
    starts0 = np.concatenate([[0], ends[:-1]]).astype(np.int64)
    kept_idx, runs, kept_ends = [], {}, []
    for a, r in zip(starts0, rings):
        keep = caps.collinear_runs(r)
        k = a + np.flatnonzero(keep)
        kept_idx.append(k)
        kept_ends.append(len(k))
        if not keep.all():
            caps._note_runs(keep, a, runs)
    kept_idx = np.concatenate(kept_idx)
    tri = np.asarray(mapbox_earcut.triangulate_float64(np.ascontiguousarray(verts[kept_idx]),
                                                       np.cumsum(kept_ends).astype(np.uint32)),
                     dtype=np.int64).reshape(-1, 3)
    if len(tri) == 0:
        return empty
    tri = kept_idx[tri]
    if runs:
        tri = caps._reinsert_runs(tri, runs)
    # a zero-area ear (three vertices on one line, not consecutive on a ring: a notch whose mouth
    # lines up with a third point) is dropped; the T-junction split below joins its neighbours
    tri = caps._drop_flat_triangles(verts, tri)
    # earcut drops ring vertices lying on a straight line between their neighbours; put them
    # back so that every ring edge is an edge of the cap (the bands share those edges)
    starts = np.concatenate([[0], ends[:-1]]).astype(np.int64)
    # each ring's edges (a, a + 1), ..., (b - 1, a), all rings at once
    nxt = np.arange(1, len(verts) + 1, dtype=np.int64)
    nxt[ends.astype(np.int64) - 1] = starts
    boundary = np.stack([np.arange(len(verts), dtype=np.int64), nxt], axis=1)
    fixed = caps.split_t_junctions(verts, tri, np.concatenate([boundary, boundary[:, ::-1]]))
    if fixed is None:
        raise caps.CapError("cannot triangulate the cap: its rings cross or touch each other")
    tri = fixed
    p, q, r = verts[tri[:, 0]], verts[tri[:, 1]], verts[tri[:, 2]]
    s = (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])
    # ear clipping emits its triangles in one winding: orient them together (by their total area),
    # so that a sliver whose own sign is round-off cannot break the cap's consistency
    total = float(s.sum())
    if (total < 0) if upward else (total > 0):
        tri = tri[:, [0, 2, 1]]
    return np.ascontiguousarray(glob[tri])


def test_caps_equal_the_step_by_step_reference():
    """cap_faces (its checks after ear clipping in one compiled pass, fewer numpy steps) against
    _cap_faces_reference: the same faces (values and dtype) or the same error, on slices' MLP and
    crack rings with their holes, and on rings with collinear runs, flat ears, T-junctions, holes
    of zero area, touching and crossing rings, both orientations."""
    def run(f, outer, holes, up):
        try:
            return f(outer, holes, upward=up)
        except ValueError as e:
            return type(e).__name__

    rng = np.random.default_rng(3)
    cases = [(o, hs) for seed in (1, 2, 6) for o, hs in _rings_of_slices(seed)]
    sq = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    run4 = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2], [2, 2], [1, 2], [0, 2], [0, 1]], float)
    flat = np.array([[0, 0], [4, 0], [4, 4], [2, 4], [2, 2], [2, 4.0 - 1e-300], [0, 4]], float)
    cases += [(sq, [sq[::-1] * 0.5 + 1]), (sq, [sq[::-1] * 0.5 + 3]), (sq, [sq[::-1]]), (np.r_[sq, [[2, 2]]], []),
              (run4, []), (run4 * 2, [run4[::-1] * 0.5 + 1]), (sq * 3, [sq[::-1] + 1, np.zeros((3, 2)), sq[::-1] + 6]),
              (sq * 3, [sq[::-1] + [1, 4], sq[::-1] + [5, 4]]), (flat, []), (sq[:2], []), (np.zeros((4, 2)), []),
              (sq * 3, [sq[:2]]), (np.c_[sq, np.ones(4)], [np.c_[sq[::-1] * 0.5 + 1, np.ones(4)]])]
    for n in (3, 5, 12, 40):
        t = np.sort(rng.random(n)) * 2 * np.pi
        r = np.c_[np.cos(t), np.sin(t)] * 10
        cases += [(r, []), (r + rng.normal(scale=1e-12, size=r.shape), [0.3 * r[::-1]]), (r[::-1], [])]
    n_faces = n_errors = 0
    for outer, holes in cases:
        for up in (True, False):
            got, ref = run(caps.cap_faces, outer, holes, up), run(_cap_faces_reference, outer, holes, up)
            assert type(got) is type(ref)
            if isinstance(ref, np.ndarray):
                assert got.dtype == ref.dtype and got.shape == ref.shape and np.array_equal(got, ref)
                n_faces += len(ref) > 0
            else:
                assert got == ref
                n_errors += 1
    assert n_faces > 100 and n_errors >= 2


def test_t_junction_fast_path_refuses_what_the_loop_refuses():
    v = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    b = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    loops = np.concatenate([b, b[:, ::-1]])
    good = np.array([[0, 1, 2], [0, 2, 3]])
    assert np.array_equal(caps.split_t_junctions(v, good, loops), good)
    assert caps.split_t_junctions(v, np.array([[0, 1, 2], [0, 1, 2]]), loops) is None  # an edge twice one way
    assert caps.split_t_junctions(v, np.array([[0, 1, 2], [0, 1, 3]]), b) is None  # 1 -> 2 ... no opposite


@pytest.mark.parametrize("grid", [(0.0, 0.0, 1.0, 1.0), (-3.7, 12.25, 0.3, 0.7), (1e5, -2.5e4, 2.5, 0.125),
                                  (123.456, -0.001, 1e-3, 7.77)])
def test_exact_joins_take_the_crack_corners_that_the_round_trip_gives_back(grid):
    """_exact_join reads a crack ring's integer corners where the corners -> xy -> corners trip
    (its former route) returns them exactly: here every corner of a large image on several grids."""
    ox, oy, dx, dy = grid
    _, to_corner = grid_to_xy(ox, oy, dx, dy)
    p = np.stack(np.meshgrid(np.arange(-1, 2049), np.arange(-1, 2049)), axis=-1).reshape(-1, 2)
    p = np.concatenate([p, [[2 ** 20, 2 ** 20], [2 ** 20 - 1, 7]]])
    xy = to_corner(p)
    back = np.stack([np.rint((xy[:, 0] - ox) / dx + 0.5), np.rint((xy[:, 1] - oy) / dy + 0.5)], axis=1).astype(np.int64)
    assert np.array_equal(back, p)


def test_exact_joins_are_the_same_with_the_corner_round_trip(monkeypatch):
    """The general mesher with the exact joins' corners from the xy round trip (the guard made
    false) gives the same mesh bytes on a volume with many exact joins."""
    import contourmesh

    rng = np.random.default_rng(11)
    vol = ndimage.gaussian_filter(rng.random((8, 30, 30)), 1.0) > 0.5
    a = contourmesh.mesh(vol, spacing=(1.3, 0.7, 0.9))
    assert a.meta.get("exact_joins", 0) > 0
    monkeypatch.setattr(volumes, "_EXACT_TRIP_LIMIT", 0.0)
    b = contourmesh.mesh(vol, spacing=(1.3, 0.7, 0.9))
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def _record_exact_units(monkeypatch, vol, spacing):
    """Each exact join's unit of one mesh made three ways: directly (_exact_unit, the mesher's
    route), on a mesher by the compiled join (_exact_join) and on a mesher by the step-by-step
    reference: the triples of ``(nv, V, F, S, N, rings)``."""
    import contourmesh

    out = []
    direct = volumes._exact_unit

    def fields(u):
        return (u.nv, u.V, u.F, u.S, u.N, u.rings)

    def three(A, B, k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, polygon_of):
        u = direct(A, B, k, ga, gb, zs, dx, dy, ox, oy, to_xy_corner, polygon_of)
        args = (A, B, k, ga, gb, zs)
        made = [volumes._Unit.record(None, lambda M, ring, f=f: f(M, *args, ring, dx, dy, ox, oy, to_xy_corner),
                                     polygon_of, zs, "wiederhold", None)
                for f in (volumes._exact_join, volumes._exact_join_reference)]
        out.append([fields(u)] + [fields(m) for m in made])
        return u

    monkeypatch.setattr(volumes, "_exact_unit", three)
    contourmesh.mesh(vol, spacing=spacing)
    monkeypatch.setattr(volumes, "_exact_unit", direct)
    return out


@pytest.mark.parametrize("trip", [True, False])
def test_exact_joins_compiled_equal_the_reference(monkeypatch, trip):
    """The exact join's compiled pass (numbering, collars, pixel faces, necks), on a mesher and as a
    unit made directly, against the step by step reference, join by join on random volumes (forks,
    handles, diagonal touches), with the crack corners read directly and through the xy round trip:
    the same vertices (bits), faces, sides, neck vertices and rings' places."""
    if not trip:
        monkeypatch.setattr(volumes, "_EXACT_TRIP_LIMIT", 0.0)
    n = necks = 0
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        vol = ndimage.gaussian_filter(rng.random((7, 26, 30)), rng.uniform(0.6, 1.3)) > rng.uniform(0.47, 0.53)
        vol[:, ::5, ::6] ^= rng.random(vol[:, ::5, ::6].shape) < 0.3  # specks, pin holes, diagonal touches
        for units in _record_exact_units(monkeypatch, vol, tuple(rng.uniform(0.4, 1.6, 3))):
            ref = units[-1]
            n += 1
            necks += len(ref[4])
            for got in units[:2]:
                assert got[0] == ref[0] and got[5] == ref[5]  # vertex count, rings' places
                assert got[1].shape == ref[1].shape and got[1].tobytes() == ref[1].tobytes()
                for g, r in zip(got[2:5], ref[2:5]):
                    assert g.dtype == r.dtype and np.array_equal(g, r)
    assert n > 20 and necks > 0


def test_exact_join_kernel_refuses_corners_outside_the_box():
    ra = np.ones((2, 2), dtype=bool)
    cx = np.array([0, 2, 2, 0, 0, 3], dtype=np.int64)
    cy = np.array([0, 0, 2, 2, 0, 0], dtype=np.int64)
    ok = volumes._exact_join_kernel(ra, ra, np.int64(0), np.int64(0), cx[:4], cy[:4],
                                    np.array([0, 4], dtype=np.int64), np.int64(1), np.int64(0))
    assert ok[-1] and len(ok[0]) == 4 and len(ok[3]) == 8  # a collar of 8 faces, no pixel left open
    bad = volumes._exact_join_kernel(ra, ra, np.int64(0), np.int64(0), cx[4:], cy[4:],
                                     np.array([0, 2], dtype=np.int64), np.int64(1), np.int64(0))
    assert not bad[-1]


@pytest.mark.parametrize("kw", [{}, {"caps": "half"}, {"polygon": "none"}, {"triangulation": "greedy"},
                                {"triangulation": "optimal", "caps": "half"}])
def test_units_made_without_a_mesher_are_the_recorded_units(monkeypatch, kw):
    """The flat ends' and band joins' units made directly (_Unit.flat) against the same units
    recorded on a mesher (the direct route refused): the same mesh bytes and counts, on volumes
    with holes, specks (pixel caps), one-slice components (prisms), mixed bands and crossing
    fallbacks."""
    import contourmesh

    made = []
    flat = volumes._Unit.flat.__func__

    def counted(cls, *a):
        made.append(1)
        return flat(cls, *a)

    for seed in range(4):
        vol = _masks(20 + seed, shape=(5, 30, 34))
        monkeypatch.setattr(volumes._Unit, "flat", classmethod(counted))
        a = contourmesh.mesh(vol, spacing=(1.1, 0.8, 0.9), **kw)
        monkeypatch.setattr(volumes._Unit, "flat", classmethod(lambda cls, *a: None))
        b = contourmesh.mesh(vol, spacing=(1.1, 0.8, 0.9), **kw)
        assert a.vertices.tobytes() == b.vertices.tobytes() and np.array_equal(a.faces, b.faces)
        assert a.meta == b.meta
    assert len(made) > 20


def test_round9_compiled_equals_the_numpy_form():
    from contourmesh.bands import bridges

    rng = np.random.default_rng(9)
    x = np.concatenate([rng.uniform(0, 50, 5000), rng.integers(0, 2 ** 20, 2000) / 1024.0,
                        np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 2.0 ** 60, -2.5e-9])])
    x = np.concatenate([x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf)])
    got, ref = bridges._round9(x), bridges._round9_reference(x)
    assert np.array_equal(got.view(np.uint64), ref.view(np.uint64))  # (NaN's bits included)


def test_missing_corners_equal_the_unique_keys_form():
    from contourmesh.tracing import missing_corners, unique_keys

    rng = np.random.default_rng(12)
    for h, w, n in [(1, 1, 0), (1, 1, 3), (5, 9, 40), (30, 20, 2000), (200, 3, 50)]:
        ids = np.where(rng.random((h, w)) < 0.5, -1, rng.integers(0, 100, (h, w))).astype(np.int64)
        lx, ly = rng.integers(0, w, n).astype(np.int64), rng.integers(0, h, n).astype(np.int64)
        ux, uy, ok = missing_corners(ids, lx, ly)
        need = ids[ly, lx] < 0
        key = unique_keys(lx[need] * h + ly[need], w * h)
        assert ok and np.array_equal(ux, key // h) and np.array_equal(uy, key % h)
        assert ux.dtype == uy.dtype == np.int64
    # a place off the grid: not decided here
    assert not missing_corners(ids, np.array([0, w], dtype=np.int64), np.array([0, 0], dtype=np.int64))[2]
    assert not missing_corners(ids, np.array([-1], dtype=np.int64), np.array([0], dtype=np.int64))[2]


def _neck_inputs(monkeypatch, cases):
    """The inputs of the volume mesher's _open_necks on the noisy volumes ``cases`` ((seed, shape,
    spacing, threshold))."""
    from scipy import ndimage

    import contourmesh
    from contourmesh import volumes

    seen = []
    real = volumes._open_necks

    def keep(V, F, S, N, nudge, tube_seen=None, overwrite=False):  # (the mesher gives its own arrays over)
        seen.append((V.copy(), F.copy(), S.copy(), np.array(N).copy(), nudge))
        return real(V, F, S, N, nudge, tube_seen=tube_seen)

    monkeypatch.setattr(volumes, "_open_necks", keep)
    for seed, shape, spacing, thr in cases:
        rng = np.random.default_rng(seed)
        contourmesh.mesh(ndimage.gaussian_filter(rng.random(shape), 0.7) > thr, spacing=spacing)
    monkeypatch.undo()
    return seen


def test_open_necks_at_once_equals_the_loop(monkeypatch):
    """repair._open_necks (all necks at once: compiled links and walks, whole-array rings and
    angles) against the loop over the necks (_open_necks_loop): the same arrays, bit for bit, on
    noisy volumes whose necks include ones whose link holds an earlier neck's ring (later rounds)
    and tubes whose first walk crosses its fans (the tries from every start), the slices far apart
    against the pixels."""
    cases = [(4, (10, 40, 40), (1.0, 1.0, 1.0), 0.5), (5, (12, 30, 30), (4.0, 1.0, 1.0), 0.5),
             (6, (8, 40, 40), (8.0, 0.5, 0.7), 0.45)]
    from contourmesh import repair

    inputs = _neck_inputs(monkeypatch, cases)
    monkeypatch.setattr(repair, "_NECKS_AT_ONCE", 1)  # (all of them at once, however few)
    V, F, S = repair.warm_neck_kernels()  # (the warm-up's two cones: one tube, a closed manifold)
    assert len(V) == 19 and len(F) == 32 and np.array_equal(np.bincount(F.reshape(-1), minlength=19) > 0, np.r_[False, [True] * 18])
    crossed = []
    real = repair._tube_crosses
    monkeypatch.setattr(repair, "_tube_crosses", lambda *a, **k: crossed.append(real(*a, **k)) or crossed[-1])
    tests = []
    real_any = repair._any_kernel
    monkeypatch.setattr(repair, "_any_kernel", lambda *a: tests.append(1) or real_any(*a))
    later = 0
    for V, F, S, N, nudge in inputs:
        want = repair._open_necks_loop(V, F, S, N, nudge)
        ids = np.unique(N)
        # without a kept dict, and twice with one: the second time every tube's crossing test is
        # answered from it (crossing tubes too: their further walks are made again)
        kept: dict = {}
        runs = []
        for seen in (None, kept, kept):
            n0 = len(tests)
            got = repair._open_necks(V, F, S, N, nudge, tube_seen=seen)
            runs.append(len(tests) - n0)
            for a, b in zip(got, want):
                assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))
        assert sum(1 for k in kept if k[0] == "tube at once") == len(ids)
        # (with the caller's own faces and sides given over: the same arrays, their buffers resized)
        F_own, S_own = F.copy(), S.copy()
        got = repair._open_necks(V, F_own, S_own, N, nudge, tube_seen=kept, overwrite=True)
        assert got[1] is F_own and got[2] is S_own
        for a, b in zip(got, want):
            assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))
        assert runs[0] == runs[1] >= len(ids) and runs[2] == runs[0] - len(ids)
        mark = np.zeros(len(V), dtype=bool)
        mark[ids] = True
        rows = repair._rows_touching(F, mark)
        assert np.array_equal(rows, np.flatnonzero(mark[F].any(axis=1)))
        status, cyc, cyc_at = repair._neck_cycles(F[rows], ids, len(V))[:3]
        assert status == 0
        later += int((repair._neck_rounds(cyc, cyc_at, len(V)) > 0).sum())
    assert later >= 3 and sum(crossed) >= 5


def test_necks_met_again_are_opened_as_the_first_time(monkeypatch):
    """repair._open_necks_loop (the one-neck-at-a-time form, which _open_necks falls back on) with a
    kept dict: a second call on the same mesh takes every neck's rings and faces from it, and gives
    the same arrays as a call without the dict, and as _open_necks (which keeps only its tubes'
    crossing answers in it)."""
    from contourmesh import repair

    seen_inputs = _neck_inputs(monkeypatch, [(4, (10, 40, 40), None, 0.5)])
    V, F, S, N, nudge = max(seen_inputs, key=lambda x: len(x[3]))
    assert len(np.unique(N)) > 10  # (necks to open)
    plain = repair._open_necks_loop(V, F, S, N, nudge)
    kept: dict = {}
    first = repair._open_necks_loop(V, F, S, N, nudge, tube_seen=kept)
    n_kept = sum(1 for k in kept if isinstance(k, tuple) and k and k[0] == "neck")
    again = repair._open_necks_loop(V, F, S, N, nudge, tube_seen=kept)
    assert n_kept == len(np.unique(N))
    monkeypatch.setattr(repair, "_NECKS_AT_ONCE", 1)
    at_once = repair._open_necks(V, F, S, N, nudge, tube_seen=kept)
    for out in (first, again, at_once):
        assert all(a.dtype == b.dtype and np.array_equal(a, b) for a, b in zip(plain, out))
    # the faces at the necks found by the compiled pass (int64 C faces, as the mesher's) and by the
    # mask of every corner (the form before, kept for other faces: here Fortran-ordered ones)
    assert F.dtype == np.int64 and F.flags.c_contiguous
    by_mask = repair._open_necks_loop(V, np.asfortranarray(F), S, N, nudge)
    assert all(a.dtype == b.dtype and np.array_equal(a, b) for a, b in zip(plain, by_mask))


def test_a_holes_first_pixel_is_the_first_of_its_whole_mask():
    to_center, to_corner = grid_to_xy(0.0, 0.0, 1.0, 1.0)
    n = 0
    for seed in (1, 2, 3):
        for mask in _masks(seed):
            s = volumes._Slice(mask, "mlp", to_corner, to_center)
            for _, hm in s.hole_masks:
                for h in range(len(hm)):
                    whole = hm[h]
                    assert hm.first_pixel(h) == divmod(int(np.argmax(whole)), whole.shape[1])
                    n += 1
    assert n > 10


def test_ring_boxes_of_the_meshers_slices_equal_the_reference(shared_data, monkeypatch):
    """Every slice whose ring boxes the bridged joins read while meshing parts of the shared volumes
    (the crack rings' boxes read off the components' pixel boxes), against the rings made."""
    import contourmesh
    from contourmesh.io import read_volume

    real = volumes._ring_boxes
    seen = []

    def spy(s):
        got = real(s)
        seen.append((got, volumes._ring_boxes_reference(s)))
        return got

    monkeypatch.setattr(volumes, "_ring_boxes", spy)
    lobster, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    for vol in (lobster[15:40], liver[200:230]):
        contourmesh.mesh(vol)
    assert len(seen) > 5
    for (lo, hi), (rlo, rhi) in seen:
        assert lo.dtype == rlo.dtype == np.float64 and lo.shape == rlo.shape
        assert np.array_equal(lo, rlo) and np.array_equal(hi, rhi)
