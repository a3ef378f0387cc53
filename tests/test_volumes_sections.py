"""Intermediate sections (issue 14): a branching join that cannot be bridged whole is split in its gap
by the zero level of the interpolated signed distance of the two slices (contourmesh.sections)."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import sections
from contourmesh.volumes import volume_to_mesh
from test_volumes import check_embedded


def _blobs(seed=8, shape=(5, 14, 14)):
    """Smoothed noise: forks, merges and holes in most slice pairs, some whose bridged join crosses itself."""
    rng = np.random.default_rng(seed)
    return ndimage.gaussian_filter(rng.random(shape), 1.0) > 0.5 + 0.04 * rng.standard_normal()


def _sparse_rings(monkeypatch):
    """The branching joins' polygons as they are, not densified (``volumes._DENSE_STEP``) and not
    densified where a join fails either (``volumes._DENSE_RETRY_STEP``, ``_DENSE_FAILED_STEP``) or
    meets a crack ring (``_DENSE_MIXED_STEP``): on :func:`_blobs` some bridged joins then fail and
    take sections (densified, all are bridged)."""
    from contourmesh import volumes

    monkeypatch.setattr(volumes, "_DENSE_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_FAILED_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_MIXED_STEP", None)


def _dense_rings(monkeypatch):
    """The branching joins' polygons with a vertex every pixel (opt-in: ``volumes._DENSE_STEP``)."""
    from contourmesh import volumes

    monkeypatch.setattr(volumes, "_DENSE_STEP", 1.0)


@pytest.mark.parametrize("kw", [dict(), dict(refine="band"), dict(caps="half")])
def test_densified_rings_bridge_every_join_of_the_blobs(monkeypatch, kw):
    """A vertex every pixel on the branching joins' polygons keeps their bands' rungs local: every
    join of this volume is bridged whole (not densified: 2 exact joins and a sectioned one), with
    less area."""
    vol = _blobs()
    _dense_rings(monkeypatch)
    m = volume_to_mesh(vol, **kw)
    check_embedded(vol, m)
    assert m.meta["exact_joins"] == 0 and m.meta["crack_rings"] == 0 and m.meta["dense_rings"] > 0
    _sparse_rings(monkeypatch)
    sparse = volume_to_mesh(vol, **kw)
    assert sparse.meta["exact_joins"] > 0 and sparse.meta["dense_rings"] == 0
    assert m.area < sparse.area


@pytest.mark.parametrize("kw", [dict(), dict(refine="band")])
def test_failed_joins_are_tried_again_on_densified_rings(monkeypatch, kw):
    """By default (``_DENSE_STEP`` None) only the components of the branching joins that fail are
    densified, and the bridged joins are built again: the blobs' exact joins are bridged, with
    fewer rings changed than densifying every branching join; a retry that leaves as many exact
    joins is dropped (the first build's mesh, bit for bit)."""
    from contourmesh import volumes

    vol = _blobs()
    _sparse_rings(monkeypatch)
    sparse = volume_to_mesh(vol, **kw)
    _dense_rings(monkeypatch)
    dense = volume_to_mesh(vol, **kw)
    monkeypatch.setattr(volumes, "_DENSE_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", 1.0)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_REFINED", True)
    densified = []
    densify = volumes._densify_components

    def record(mask, slices, comps, grid, step, total=False):
        densified.append(set(comps))
        return densify(mask, slices, comps, grid, step, total)

    monkeypatch.setattr(volumes, "_densify_components", record)
    m = volume_to_mesh(vol, **kw)
    check_embedded(vol, m)
    assert sparse.meta["exact_joins"] > 0 and sparse.meta["dense_rings"] == 0
    assert m.meta["exact_joins"] < sparse.meta["exact_joins"] and m.meta["crack_rings"] < sparse.meta["crack_rings"]
    assert 0 < m.meta["dense_rings"] < dense.meta["dense_rings"]
    assert 1 <= len(densified) <= len(volumes._DENSE_RETRY_STAGES) and m.area < sparse.area
    # the retry keeps the bridged joins whose rings and neighbourhood did not change: the same mesh
    # as building every bridged join again
    build = volumes._build_bridges
    monkeypatch.setattr(volumes, "_build_bridges", lambda *a, **k: build(*a[:9], {}, **k))
    again = volume_to_mesh(vol, **kw)
    np.testing.assert_array_equal(again.vertices, m.vertices)
    np.testing.assert_array_equal(again.faces, m.faces)
    monkeypatch.setattr(volumes, "_build_bridges", build)
    # a retry that gains nothing (here: the rings are left as they are) is dropped
    monkeypatch.setattr(volumes, "_densify_components", lambda *a, **k: 1)
    same = volume_to_mesh(vol, **kw)
    assert same.meta["dense_rings"] == 0 and same.meta["exact_joins"] == sparse.meta["exact_joins"]
    np.testing.assert_array_equal(same.vertices, sparse.vertices)
    np.testing.assert_array_equal(same.faces, sparse.faces)


def test_the_retry_on_densified_rings_is_a_setting_and_skips_the_band_refinement(monkeypatch):
    """By default only the joins with a speck that fail and the polygons banded to crack rings are
    densified (``_DENSE_FAILED_STEP``, ``_DENSE_MIXED_STEP``; the retry of every failed join costs
    the paper mode time on noisy volumes); with ``_DENSE_RETRY_STEP`` set a failed join is tried
    again on densified rings in the paper mode, and still not with the band refinement
    (``_DENSE_RETRY_REFINED``: there it uncovers the refined polygons' bias)."""
    from contourmesh import volumes

    assert volumes._DENSE_STEP is None and volumes._DENSE_RETRY_STEP is None
    monkeypatch.setattr(volumes, "_DENSE_FAILED_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_MIXED_STEP", None)
    vol = _blobs()
    assert volume_to_mesh(vol).meta["dense_rings"] == 0
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", 1.0)
    paper = volume_to_mesh(vol)
    assert paper.meta["dense_rings"] > 0
    band = volume_to_mesh(vol, refine="band")
    assert band.meta["dense_rings"] == 0 and band.meta["exact_joins"] > 0


def test_a_ring_densified_twice_keeps_its_own_points_and_marks_the_rest_added():
    """The retry's second stage densifies rings densified by the first: the points the polygon had
    before either stays the only ones not marked as added (its band joins are made between them)."""
    from contourmesh import volumes
    from contourmesh.volumes import _densify_components, _Slice, grid_to_xy

    m2 = np.zeros((20, 24), bool)
    m2[3:15, 2:21] = True
    m2[3:6, 2:9] = False
    mask = np.stack([m2, m2])
    to_center, to_corner = grid_to_xy(0.0, 0.0, 1.0, 1.0)
    s = _Slice(m2, "mlp", to_corner, to_center)
    own = s.outer[0].copy()
    grid = (0.0, 0.0, 1.0, 1.0)
    for step in (1.0, 0.5):
        assert _densify_components(mask, [s, None], {(0, 0)}, grid, step, total=True) == 1
        ring, added = s.outer[0], s.dense[0, -1]
        assert len(added) == len(ring) > len(own)
        np.testing.assert_array_equal(ring[~added], own)
    assert (~added).sum() == len(own) and len(s.outer[0]) > 1.5 * len(own)
    # the retry's rings keep to about _DENSE_MAX points over its stages
    from contourmesh.volumes import _densify

    r, a = _densify(own, 0.05, most=len(own) + 8, total=True)
    assert len(own) < len(r) <= len(own) + 8 and a.sum() == len(r) - len(own)
    np.testing.assert_array_equal(r[~a], own)
    r, a = _densify(own, 0.05, most=len(own), total=True)
    assert len(r) == len(own) and not a.any()
    assert volumes._DENSE_RETRY_STAGES[0] > volumes._DENSE_RETRY_STAGES[-1]


def test_mid_section_lies_between_the_two_regions():
    yy, xx = np.mgrid[:41, :41]
    r2 = (yy - 20) ** 2 + (xx - 20) ** 2
    small, large = r2 < 6 ** 2, r2 < 14 ** 2
    m = sections.mid_section(small, large)
    assert (m >= (small & large)).all() and not (m & ~(small | large)).any()
    # a disc of radius about 10: the mean of the two radii
    assert abs(np.sqrt(m.sum() / np.pi) - 10) < 0.75
    # it is symmetric in the two regions, and a region with itself is itself
    assert (sections.mid_section(large, small) == m).all()
    assert (sections.mid_section(small, small) == small).all()
    # anisotropic pixels: distances in physical units (an ellipse of pixels is a physical disc)
    yy, xx = np.mgrid[:41, :81]
    e2 = (yy - 20) ** 2 + ((xx - 40) / 2) ** 2
    me = sections.mid_section(e2 < 36, e2 < 196, sampling=(1.0, 0.5))
    assert abs(np.sqrt(me.sum() / 2 / np.pi) - 10) < 0.75


@pytest.mark.parametrize("sampling", [(1.0, 1.0), (0.5, 0.5), (2.0, 2.0), (0.617, 0.667), (0.8, 0.8), (2.0 ** -300, 2.0 ** -300)])
def test_compiled_signed_distance_is_the_reference_bit_for_bit(sampling):
    # square power-of-two pixels take the compiled transform (exact integers): the same bytes as
    # scipy's; other pixels take scipy itself.  Noise, blobs, one pixel, full boxes, thin boxes
    rng = np.random.default_rng(72)
    for t in range(150):
        h, w = int(rng.integers(1, 30)), int(rng.integers(1, 30))
        m = rng.random((h, w)) < rng.uniform(0.02, 0.98) if t % 2 else \
            ndimage.gaussian_filter(rng.random((h, w)), 1.5) > 0.5
        if t % 25 == 0:
            m = np.ones((h, w), bool)
        if t % 25 == 1:
            m = np.zeros((h, w), bool)
            m[h // 2, w // 2] = True
        if not m.any():
            continue
        got, ref = sections._sdf(m, sampling), sections._sdf_reference(m, sampling)
        assert got.dtype == ref.dtype and got.shape == ref.shape
        assert got.tobytes() == ref.tobytes()
    # an empty region (no pixel to measure from) takes the reference
    empty = np.zeros((4, 5), bool)
    with np.errstate(all="ignore"):
        assert np.array_equal(sections._sdf(empty, sampling), sections._sdf_reference(empty, sampling), equal_nan=True)


def test_compiled_signed_distance_on_larger_regions_with_full_and_empty_rows():
    # the compiled transform skips a row's inside envelope where the row has no region pixel and
    # its outside one where the row is full: blobs with holes, full and empty rows and columns
    rng = np.random.default_rng(73)
    for t in range(40):
        h, w = int(rng.integers(1, 140)), int(rng.integers(1, 140))
        m = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(1.0, 6.0)) > rng.uniform(0.45, 0.55)
        if t % 3 == 0:
            m[int(rng.integers(h))] = True
            m[:, int(rng.integers(w))] = False
        if t % 4 == 1:
            m[: h // 3] = True
        if not m.any():
            continue
        for sampling in ((1.0, 1.0), (0.25, 0.25)):
            got, ref = sections._sdf(m, sampling), sections._sdf_reference(m, sampling)
            assert got.tobytes() == ref.tobytes()


@pytest.mark.parametrize("sampling", [(1.0, 1.0), (0.25, 0.25), (0.617, 0.667)])
def test_signed_distance_where_needed_is_the_full_one_there(sampling):
    """``_sdf(m, need=...)`` gives the full transform's bits on the needed pixels and only the
    sign (-inf on the region, +inf off it) elsewhere; so the sections of two regions (and the
    sections of a section with either) are the same masks when their distances are measured
    only where the two regions differ."""
    rng = np.random.default_rng(74)
    for t in range(60):
        h, w = int(rng.integers(1, 60)), int(rng.integers(1, 60))
        a = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.8, 3.0)) > rng.uniform(0.45, 0.55)
        b = a ^ (rng.random((h, w)) < rng.uniform(0.0, 0.3)) if t % 3 else \
            ndimage.gaussian_filter(rng.random((h, w)), 2.0) > 0.5
        if t % 10 == 0:
            b = a.copy()
        if not a.any() or not b.any():
            continue
        need = a ^ b
        for m in (a, b, rng.random((h, w)) < 0.5):
            if not m.any():
                continue
            full, part = sections._sdf(m, sampling), sections._sdf(m, sampling, need=need)
            assert part[need].tobytes() == full[need].tobytes()
            assert (part[~need] == np.where(m, -np.inf, np.inf)[~need]).all()
        # the sections (mid, then each quarter) as sectioned_join makes them
        fa, fb = sections._sdf(a, sampling), sections._sdf(b, sampling)
        pa, pb = sections._sdf(a, sampling, need=need), sections._sdf(b, sampling, need=need)
        mid = fa + fb < 0
        assert np.array_equal(mid, pa + pb < 0)
        if mid.any():
            fm, pm = sections._sdf(mid, sampling), sections._sdf(mid, sampling, need=need)
            assert np.array_equal(fa + fm < 0, pa + pm < 0)
            assert np.array_equal(fm + fb < 0, pm + pb < 0)


def _groups_reference(P, Q):
    """sections._groups as it was: the other components' labels cleared, then overlap_groups."""
    from contourmesh.tracing import label_mask, overlap_groups

    box = P.box if P.box is not None and P.box == Q.box else np.s_[:, :]
    lp, lq = P.S.labels[box], Q.S.labels[box]
    la = np.where(label_mask(lp, P.S.n, P.comps), lp, 0)
    lb = np.where(label_mask(lq, Q.S.n, Q.comps), lq, 0)
    pairs, groups = overlap_groups(la, lb, P.S.n, Q.S.n)
    lone_p = sorted(set(P.comps) - set(int(a) for a in pairs[:, 0]))
    lone_q = sorted(set(Q.comps) - set(int(b) for b in pairs[:, 1]))
    return [(sorted(a), sorted(b)) for a, b in groups], lone_p, lone_q


def _runs_of(labels):
    """The runs of a label image as ``_Slice.kept_runs`` holds them: int32 ``(4, n)`` ``[row, first
    column, end column, component]`` (0-based), in raster order."""
    out = []
    for y, row in enumerate(labels.tolist()):
        x = 0
        while x < len(row):
            if row[x]:
                s = x
                while x < len(row) and row[x] == row[s]:
                    x += 1
                out.append((y, s, x, row[s] - 1))
            else:
                x += 1
    return np.array(out, dtype=np.int32).reshape(-1, 4).T.copy()


def test_layer_groups_equal_the_reference():
    """A sectioned join's overlap groups of two layers (one compiled pass over the box) are those
    of the label images with the other components cleared: the same groups in the same order,
    the same lone components; with or without a shared box, some or all components, uint8 and
    uint16 labels, from the label images or from the slices' runs."""
    from types import SimpleNamespace

    from contourmesh.fastpath import slice_labels

    rng = np.random.default_rng(75)
    kinds = set()
    for t in range(150):
        h, w = int(rng.integers(2, 40)), int(rng.integers(2, 40))
        layers = []
        for _ in range(2):
            m = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.5, 2.0)) > rng.uniform(0.45, 0.6)
            labels, n, _objects = slice_labels(m)
            labels = labels.astype(np.uint16 if t % 4 == 3 else np.uint8) if n < 255 else labels
            layers.append(SimpleNamespace(labels=labels, n=n))
        if not all(S.n for S in layers):
            continue
        y0, x0 = int(rng.integers(0, h // 2 + 1)), int(rng.integers(0, w // 2 + 1))
        box = np.s_[y0:int(rng.integers(y0 + 1, h + 1)), x0:int(rng.integers(x0 + 1, w + 1))]
        Ls = []
        for kk, S in enumerate(layers):
            comps = range(S.n) if t % 3 == 0 else \
                sorted(int(c) for c in rng.choice(S.n, size=int(rng.integers(1, S.n + 1)), replace=False))
            Ls.append(sections._Layer(S, kk, comps, None, None, box=box if t % 5 else None))
        if t % 7 == 0:
            Ls[1].box = np.s_[0:h, 0:w]  # (boxes that differ: the whole images)
        got = sections._groups(*Ls)
        assert got == _groups_reference(*Ls), t
        for S in layers:  # the slices keep their runs (as _Slice.kept_runs gives them): the sweep over runs
            S.kept_runs = lambda runs=_runs_of(S.labels): runs
        assert sections._groups(*Ls) == got, t
        kinds.add((len(got[0]) > 1, bool(got[1] or got[2])))
    assert kinds == {(False, False), (False, True), (True, False), (True, True)}


def test_stack_invariants_see_a_tube_closed_by_a_section():
    ring = np.zeros((9, 9), bool)
    ring[1:8, 1:8] = True
    ring[3:6, 3:6] = False
    disc = np.zeros((9, 9), bool)
    disc[1:8, 1:8] = True
    two = sections.stack_invariants([ring, ring])
    assert two == (1, 1, 0)  # one solid torus: chi 0
    assert sections.stack_invariants([ring, disc, ring]) != two  # the section closes the tube
    assert sections.stack_invariants([ring, ring, ring]) == two


def test_stack_invariants_compiled_equal_the_labelled_reference():
    # the run-based counts equal scipy's labels of the padded stack and euler6, on random stacks of
    # noise and of smoothed blobs (tunnels, cavities), empty and full ones included
    rng = np.random.default_rng(16)
    kinds = set()
    for t in range(300):
        shape = (int(rng.integers(1, 6)), int(rng.integers(1, 12)), int(rng.integers(1, 12)))
        layers = rng.random(shape) < rng.uniform(0.1, 0.9) if t % 2 else \
            ndimage.gaussian_filter(rng.random(shape), 1.0) > 0.5
        if t % 50 == 0:
            layers = np.zeros(shape, bool) if t % 100 == 0 else np.ones(shape, bool)
        got = sections.stack_invariants(list(layers))
        assert got == sections._stack_invariants_reference(list(layers))
        assert all(type(x) is int for x in got)
        kinds.add((got[0] > 1, got[1] > 1))
    assert any(a for a, _ in kinds) and any(b for _, b in kinds)  # several components; cavities


def test_euler6_equals_skimage_on_random_stacks():
    # the Euler characteristic counted as vertices - edges + squares - cubes of the 6-connected
    # voxel complex is skimage's (connectivity=1): smoothed blobs (tunnels, cavities) and noise
    from skimage.measure import euler_number

    rng = np.random.default_rng(4)
    seen = set()
    for t in range(200):
        shape = tuple(int(n) for n in rng.integers(1, 10, 3))
        v = rng.random(shape) < rng.uniform(0.1, 0.9) if t % 2 else \
            ndimage.gaussian_filter(rng.random(shape), 1.0) > 0.5
        v = np.pad(v, 1) if t % 3 else v
        chi = euler_number(v, connectivity=1)
        assert sections.euler6(v) == chi
        seen.add(int(np.sign(chi)))
    assert seen == {-1, 0, 1}


@pytest.mark.parametrize("kw", [dict(), dict(refine="band"), dict(caps="half"),
                                dict(polygon="dss", triangulation="optimal")])
def test_sections_replace_exact_joins_and_keep_the_voxel_topology(monkeypatch, kw):
    vol = _blobs()
    _sparse_rings(monkeypatch)
    m = volume_to_mesh(vol, **kw)
    check_embedded(vol, m)
    # (with DSS polygons every join of this volume is bridged whole)
    assert m.meta["intermediate_sections"] >= (0 if kw.get("polygon") == "dss" else 1)


def test_sections_are_the_last_step_before_the_exact_join(monkeypatch):
    vol = _blobs()
    _sparse_rings(monkeypatch)
    with_sections = volume_to_mesh(vol)
    monkeypatch.setattr(sections, "MAX_DEPTH", 0)  # no section: those joins become exact
    without = volume_to_mesh(vol)
    check_embedded(vol, without)
    assert without.meta["intermediate_sections"] == 0
    assert with_sections.meta["exact_joins"] < without.meta["exact_joins"]
    assert with_sections.meta["crack_rings"] < without.meta["crack_rings"]
    # the staircase goes: less area than with the voxel-exact joins
    assert with_sections.area < without.area
    # the sections' vertices lie between the slices, off the pixel corners' mid-planes only where made
    z = with_sections.vertices[:, 2]
    assert (np.abs(z - np.rint(z)) > 1e-6).any()


def _two_cs(n=40, r0=8, r1=15, gap=2):
    """A thick C in one slice and the same C opening the other way in the next: the two overlaps
    (the upper and lower arcs) form a loop, so a handle opens in the gap (genus 1)."""
    vol = np.zeros((4, n, n), bool)
    yy, xx = np.mgrid[:n, :n] - (n - 1) / 2
    rr = np.hypot(yy, xx)
    ring = (rr >= r0) & (rr <= r1)
    vol[1] = ring & ~((np.abs(yy) <= gap / 2) & (xx > 0))
    vol[2] = ring & ~((np.abs(yy) <= gap / 2) & (xx < 0))
    return vol


@pytest.mark.parametrize("kw", [dict(), dict(refine="band"), dict(polygon="dss", triangulation="optimal")])
def test_a_loop_of_overlaps_is_sectioned_not_exact(kw):
    vol = _two_cs()
    m = volume_to_mesh(vol, **kw)
    chk, ref = check_embedded(vol, m)
    assert ref["genus"] == 1
    # before, a loop of overlaps was always joined voxel-exactly (crack rings, a staircase)
    assert m.meta["exact_joins"] == 0 and m.meta["crack_rings"] == 0, m.meta
    assert m.meta["intermediate_sections"] >= 1


def test_a_fork_and_a_merge_through_one_section_bridge_apart(monkeypatch):
    """Where a section splits a loop into a fork below it and a merge above it, the merge's bridges
    keep clear of the fork's: the same shortest bridge taken twice pinched the section, and the
    join became exact (this volume: 2 exact joins with sections and without)."""
    rng = np.random.default_rng(7)
    vol = ndimage.gaussian_filter(rng.random((5, 20, 20)), 1.2) > 0.5 + 0.03 * rng.standard_normal()
    with_sections = volume_to_mesh(vol)
    check_embedded(vol, with_sections)
    monkeypatch.setattr(sections, "MAX_DEPTH", 0)
    without = volume_to_mesh(vol)
    assert with_sections.meta["exact_joins"] < without.meta["exact_joins"]
    assert with_sections.area < without.area


def test_a_bridged_join_with_more_area_than_sections_takes_the_sections(monkeypatch):
    from contourmesh import volumes

    vol = _blobs()
    monkeypatch.setattr(volumes, "_SECTION_TRIAL", np.inf)  # never compared
    plain = volume_to_mesh(vol)
    monkeypatch.setattr(volumes, "_SECTION_TRIAL", 0.0)  # every bridged join tries sections
    tried = volume_to_mesh(vol)
    check_embedded(vol, tried)
    assert tried.meta["intermediate_sections"] > plain.meta["intermediate_sections"]
    # each join keeps whichever of the two has less area
    assert tried.area < plain.area


def _edges_close_reference(F, spans):
    """sections._edges_close as it was: unique rows and Python sets of edge tuples."""
    d = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    und, cnt = np.unique(np.sort(d, axis=1), axis=0, return_counts=True)
    if len(np.unique(d, axis=0)) != len(d) or cnt.max() > 2:
        return False
    ring_edges = set()
    for off, m in spans:
        e = np.sort(np.c_[off + np.arange(m), off + (np.arange(m) + 1) % m], axis=1)
        ring_edges.update(map(tuple, e.tolist()))
    return {tuple(e) for e in und[cnt == 1].tolist()} == ring_edges


def test_piece_edge_check_equals_the_set_reference():
    # bands between two rings (valid pieces: every ring edge once, every rung twice, each way once),
    # the same with a face flipped, dropped or doubled, rings of 1 and 2 points, and random faces
    from contourmesh.bands import triangulate_band

    rng = np.random.default_rng(61)
    verdicts = set()
    for t in range(300):
        n, m = int(rng.integers(1, 9)), int(rng.integers(3, 9))
        ta, tb = np.sort(rng.random(n)) * 2 * np.pi, np.sort(rng.random(m)) * 2 * np.pi
        lo = np.c_[np.cos(ta), np.sin(ta), np.zeros(n)]
        hi = np.c_[np.cos(tb), np.sin(tb), np.ones(m)]
        F = triangulate_band(lo, hi, "arclength") if n > 1 else np.c_[np.zeros(m, int), 1 + np.arange(m),
                                                                          1 + (np.arange(m) + 1) % m]
        spans = [(0, n), (n, m)]
        kind = t % 5
        if kind == 1:
            F = F.copy()
            F[0] = F[0, ::-1]
        elif kind == 2:
            F = F[1:]
        elif kind == 3:
            F = np.concatenate([F, F[:1]])
        elif kind == 4:
            F = rng.integers(0, n + m, (int(rng.integers(1, 12)), 3))
            spans = spans[: int(rng.integers(0, 3))]
        got = sections._edges_close(np.asarray(F, dtype=np.int64), n + m, spans)
        assert got == _edges_close_reference(np.asarray(F, dtype=np.int64), spans), (t, F)
        verdicts.add(got)
    assert verdicts == {True, False}


def test_a_sectioned_join_gives_up_early_only_where_it_would_come_to_nothing(monkeypatch):
    """A sectioned join stops building pieces once no stack of sections it can still get keeps the
    topology (``sections.GIVE_UP_EARLY``): the same meshes, bit for bit, as building every piece
    until one fails or the final topology test does, with fewer pieces built.  (On these noise
    volumes, as on the lobster, most sectioned joins are loops of overlaps.)"""
    _sparse_rings(monkeypatch)
    built = [0]
    pieces = sections._pieces

    def counted(*a):
        built[0] += 1
        return pieces(*a)

    monkeypatch.setattr(sections, "_pieces", counted)
    n_built = {}
    for early in (False, True):
        monkeypatch.setattr(sections, "GIVE_UP_EARLY", early)
        built[0] = 0
        vols = []
        # (seed 2: a loop of overlaps joined through a single section; the others: each has a
        # sectioned join given up early)
        for seed in (2, 16, 18, 21, 38):
            rng = np.random.default_rng(seed)
            vols.append(ndimage.gaussian_filter(rng.random((6, 24, 24)), 1.2) > 0.5 + 0.03 * rng.standard_normal())
        meshes = [volume_to_mesh(vol) for vol in vols]
        n_built[early] = built[0]
        if not early:
            reference = meshes
    for m, ref in zip(meshes, reference):
        assert np.array_equal(m.vertices, ref.vertices) and np.array_equal(m.faces, ref.faces)
        assert m.meta == ref.meta
    assert n_built[True] < n_built[False]


def _euler2_reference(m):
    """sections._euler2 as it was: four counts of shifted masks."""
    m = np.asarray(m, dtype=bool)
    a, b = slice(None, -1), slice(1, None)
    return (int(np.count_nonzero(m)) - int(np.count_nonzero(m[a] & m[b])) - int(np.count_nonzero(m[:, a] & m[:, b]))
            + int(np.count_nonzero(m[a, a] & m[a, b] & m[b, a] & m[b, b])))


def test_compiled_euler2_equals_the_reference():
    rng = np.random.default_rng(76)
    seen = set()
    for t in range(300):
        h, w = int(rng.integers(0, 30)), int(rng.integers(0, 30))
        m = rng.random((h, w)) < rng.uniform(0.0, 1.0) if t % 2 else \
            ndimage.gaussian_filter(rng.random((h, w)), 1.5) > rng.uniform(0.4, 0.6)
        if t % 9 == 0:
            m = m[::2, 1::3]  # (a strided view)
        got = sections._euler2(m)
        assert got == _euler2_reference(m), t
        seen.add(int(np.sign(got)))
    assert seen == {-1, 0, 1}


def test_stack_euler_from_layers_and_overlaps_equals_euler6():
    """A stack's Euler characteristic is its layers' (sections._euler2) less their consecutive
    overlaps': the sum the early topology test of a sectioned join compares (euler6 counts the
    whole stack)."""
    rng = np.random.default_rng(5)
    seen = set()
    for t in range(200):
        n = int(rng.integers(1, 5))
        layers = [rng.random((6, 7)) < rng.uniform(0.2, 0.8) for _ in range(n)]
        got = sum(sections._euler2(L) for L in layers) - sum(sections._euler2(a & b) for a, b in zip(layers, layers[1:]))
        chi = sections.euler6(np.stack(layers))
        assert got == chi == sections.stack_invariants(layers)[2]
        seen.add(int(np.sign(chi)))
    assert seen == {-1, 0, 1}


@pytest.mark.parametrize("kw", [dict(), dict(refine="band")])
def test_the_general_mesher_leaves_no_reference_cycles(monkeypatch, kw):
    # sectioned joins (their nested functions that call themselves), bridged rings (the tour) and
    # the slices' label cache all used to form reference cycles: every join's sections, masks and
    # slices then waited for the cyclic garbage collector (on the lobster 90k objects a call, a
    # tenth of a second of collections).  Now reference counting frees them when the call returns.
    import gc

    # Only the package's own objects are counted: a fresh environment can leave cycles of its own
    # in the call (numba typing a kernel, a module imported late), which are not the mesher's.
    vol = _blobs()
    _sparse_rings(monkeypatch)
    volume_to_mesh(vol, **kw)  # (first call: compiled kernels loaded, caches filled)
    gc.collect()
    was = gc.isenabled()
    gc.disable()
    try:
        m = volume_to_mesh(vol, **kw)
        gc.set_debug(gc.DEBUG_SAVEALL)
        gc.collect()
        ours = [o for o in gc.garbage
                if str(getattr(o, "__module__", None) or type(o).__module__).startswith("contourmesh")]
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        if was:
            gc.enable()
    assert m.meta["intermediate_sections"] >= 1 and m.meta["bridges"] >= 1
    assert ours == []


class _FreshJoins(dict):
    """A bridge cache that builds every bridged join again the first time a build asks for it
    (other entries kept), and keeps what the cache held before, to compare."""

    def __init__(self):
        super().__init__()
        self.build = 0
        self.before = {}  # (build, key) -> the join the cache held

    @staticmethod
    def _is_join(key):
        return isinstance(key, tuple) and len(key) >= 6 and isinstance(key[0], int)

    def __contains__(self, key):
        if self._is_join(key) and dict.__contains__(self, key) and (self.build, key) not in self.before:
            self.before[self.build, key] = dict.pop(self, key)
            return False
        return dict.__contains__(self, key)


def test_a_cached_bridged_join_is_what_a_fresh_build_of_its_key_gives(monkeypatch):
    # A rebuild after a crossing fallback takes the bridged joins whose key is unchanged from the
    # cache.  The key once left out whether the join may try intermediate sections (not after its
    # components were densified in the same build), so a later build took a join made without them
    # where a fresh build would try them: the mesh depended on the build history (this volume and
    # the lobster, by a little area).
    from contourmesh import volumes

    rng = np.random.default_rng(7)
    for _ in range(6):
        v = rng.random((12, 14, 13)) < 0.35
    vol = np.pad(v, 1)  # the sixth of scripts/mesh_digest.py's random volumes
    ref = volume_to_mesh(vol, polygon="dss")
    fresh = _FreshJoins()
    build = volumes._build_bridges

    def with_fresh_joins(*args, **kw):
        fresh.build += 1
        if len(args) >= 10:
            args = args[:9] + (fresh,) + args[10:]
        else:
            kw["cache"] = fresh
        return build(*args, **kw)

    monkeypatch.setattr(volumes, "_build_bridges", with_fresh_joins)
    m = volume_to_mesh(vol, polygon="dss")
    assert ref.meta["crossing_fallbacks"] >= 1  # a rebuild took cached joins
    again = [(n, k) for n, k in fresh.before if n > 1 and dict.__contains__(fresh, k)]
    assert again, "no cached join was asked for by a rebuild"
    for n, k in again:
        a, b = fresh.before[n, k], dict.__getitem__(fresh, k)
        assert (a is None) == (b is None), k
        if a is not None:
            assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F), k
    assert np.array_equal(m.vertices, ref.vertices) and np.array_equal(m.faces, ref.faces)


def test_signed_distance_column_arrays_of_either_width_and_dirty():
    # _sdf_square takes its column distances' arrays from the caller (int32 kept per thread where the
    # squared distances fit, int64 beyond): the same bytes with int64 arrays, with arrays left dirty
    # by another mask, and by runs of every length (single pixels, full rows, stripes)
    rng = np.random.default_rng(74)
    for t in range(60):
        h, w = int(rng.integers(1, 60)), int(rng.integers(1, 60))
        m = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.5, 4.0)) > rng.uniform(0.4, 0.6)
        if t % 5 == 0:
            m[:, ::2] = rng.random() < 0.5
        if t % 7 == 0:
            m = rng.random((h, w)) < 0.5
        if not m.any():
            continue
        ref = sections._sdf_reference(m, (0.5, 0.5))
        u8 = np.ascontiguousarray(m).view(np.uint8)
        for dt in (np.int32, np.int64):
            gi, go = (rng.integers(-5, 9, size=(h + 2, w + 2)).astype(dt) for _ in range(2))
            got = sections._sdf_square(u8, 0.25, 0.25, gi, go, sections._ALL)
            assert got.tobytes() == ref.tobytes()
        assert sections._sdf(m, (0.5, 0.5)).tobytes() == ref.tobytes()  # (the thread's kept arrays, dirty)


def test_the_meshers_layer_groups_equal_the_reference(shared_data, monkeypatch):
    """Every pair of layers whose groups the sectioned joins take (from the slices' runs) while
    meshing parts of the shared volumes, against the label images with the other components
    cleared."""
    import contourmesh
    from contourmesh.io import read_volume

    real = sections._groups
    seen = []

    def spy(P, Q):
        got = real(P, Q)
        seen.append((got, _groups_reference(P, Q), P.S.kept_runs() is not None and Q.S.kept_runs() is not None))
        return got

    monkeypatch.setattr(sections, "_groups", spy)
    lobster, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    for vol in (lobster[15:40], liver[200:230]):
        contourmesh.mesh(vol)
    assert len(seen) > 10 and any(runs for _, _, runs in seen)
    for got, want, _ in seen:
        assert got == want
