"""The slice's holes in one compiled pass (:func:`volumes._slice_holes`, read by
``_Slice._components``) against the per-component loop it replaces (``_Slice._components_plain``),
and the band-join test's hole pairing (:func:`volumes._simple_join`) against its numpy form (the
overlap's background labelled by ``ndimage.label``, each hole's first pixel from ``np.nonzero`` of
its whole mask), and the overlap's components and holes counted from the two slices' runs
(:func:`volumes._overlap_topology`) against the labeller's on its mask: bit for bit, on random
masks and on slices of the shared volumes."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import volumes
from contourmesh.fastpath import slice_components
from contourmesh.geometry import grid_to_xy
from test_slice_batch import _random_masks, _slices_of_volumes


def _plain(monkeypatch):
    """Make ``_Slice`` take the per-component loop (the compiled pass reports a fault)."""
    real = volumes._slice_holes

    def refused(*args):
        got = real(*args)
        return (np.int64(1),) + tuple(got[1:])

    monkeypatch.setattr(volumes, "_slice_holes", refused)
    real_pass = volumes._slice_pass  # (a whole mask's slice calls _slice_holes inside its one pass)

    def refused_pass(*args):
        got = real_pass(*args)
        return got[:8] + ((np.int64(1),) + tuple(got[8][1:]),) + got[9:]

    monkeypatch.setattr(volumes, "_slice_pass", refused_pass)


def _same(a, b):
    return type(a) is type(b) and (not isinstance(a, np.ndarray) or
                                   (a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)))


def _fields(s):
    """Every per-component field of a slice, as comparable values."""
    hm = [(sl, hm.shape, [(y, x, p) for y, x, p in hm.parts]) for sl, hm in s.hole_masks]
    return dict(n=s.n, objects=s.objects, outer=s.outer, holes=s.holes, co=s.crack_outer_c,
                ch=s.crack_holes_c, hm=hm, fallbacks=s.fallbacks, labels=s.labels)


def _equal(x, y):
    if isinstance(x, (list, tuple)):
        return type(x) is type(y) and len(x) == len(y) and all(_equal(a, b) for a, b in zip(x, y))
    if isinstance(x, np.ndarray):
        return _same(x, y)
    return x == y


def _slices(masks, polygon, box):
    to_center, to_corner = grid_to_xy(-3.7, 12.25, 0.3, 0.7)
    out = []
    for m in masks:
        if box:
            full = np.zeros((m.shape[0] + 6, m.shape[1] + 9), dtype=bool)
            full[3: 3 + m.shape[0], 5: 5 + m.shape[1]] = m
            out.append(volumes._Slice(full, polygon, to_corner, to_center,
                                      box=np.s_[2: m.shape[0] + 4, 4: m.shape[1] + 6]))
        else:
            out.append(volumes._Slice(m, polygon, to_corner, to_center))
    return out


def _check(monkeypatch, masks, polygon, box):
    fast = _slices(masks, polygon, box)
    with monkeypatch.context() as mp:
        _plain(mp)
        plain = _slices(masks, polygon, box)
    holes = 0
    for a, b in zip(fast, plain):
        fa, fb = _fields(a), _fields(b)
        for key in fa:
            assert _equal(fa[key], fb[key]), key
        holes += sum(len(h) for h in a.holes)
    return holes


@pytest.mark.parametrize("polygon", ["mlp", "dss", "none"])
@pytest.mark.parametrize("box", [False, True])
def test_compiled_holes_equal_the_per_component_loop(monkeypatch, polygon, box):
    assert _check(monkeypatch, _random_masks(11, count=50), polygon, box) > 0


def test_compiled_holes_on_the_shared_volumes(monkeypatch, shared_data):
    masks = _slices_of_volumes(shared_data)
    assert _check(monkeypatch, masks, "mlp", False) > 0
    assert _check(monkeypatch, masks[::3], "mlp", True) > 0


def test_compiled_holes_report_a_component_without_one_outer_contour():
    """The pass refuses contours that are not one outer contour per component (the plain loop then
    names the fault), and gives an empty answer for a slice without components."""
    labels = np.ones((3, 3), np.int32)
    boxes = np.array([[0, 3, 0, 3]], np.int64)
    pts = np.zeros((8, 2), np.int64)
    for area2 in ([-4, -4], [4, 4]):
        got = volumes._slice_holes(labels, boxes, pts, np.array([0, 4, 8], np.int64),
                                   np.array(area2, np.int64), np.array([0, 2], np.int64),
                                   np.int64(0), np.int64(0), np.int64(1))
        assert got[0] == 1
    got = volumes._slice_holes(np.zeros((2, 2), np.int32), np.zeros((0, 4), np.int64),
                               np.zeros((0, 2), np.int64), np.zeros(1, np.int64), np.zeros(0, np.int64),
                               np.zeros(1, np.int64), np.int64(0), np.int64(0), np.int64(1))
    assert got[0] == 0 and len(got[1]) == 0 and len(got[2]) == 0 and list(got[3]) == [0]


def _simple_join_reference(A, B, a, b):
    """``_simple_join`` with the overlap's padded background labelled by ``ndimage.label`` and each
    hole's first pixel from ``np.nonzero`` of its whole mask (the form before the compiled labels)."""
    sa, sb = A.objects[a], B.objects[b]
    y0 = min(sa[0].start, sb[0].start)
    y1 = max(sa[0].stop, sb[0].stop)
    x0 = min(sa[1].start, sb[1].start)
    x1 = max(sa[1].stop, sb[1].stop)
    o = (A.labels[y0:y1, x0:x1] == a + 1) & (B.labels[y0:y1, x0:x1] == b + 1)
    _, _, no, holes_o, _ = slice_components(o)
    if no != 1:
        return None
    ha, hb = A.hole_masks[a][1], B.hole_masks[b][1]
    if len(ha) != len(hb) or int(holes_o[0]) != len(ha):
        return None
    if not ha:
        return []
    olab, nol = ndimage.label(volumes._pad1(~o, True), structure=volumes._SQUARE)
    ext = olab[0, 0]
    if nol - 1 != len(ha):
        return None

    def where(holes, sl):
        out = []
        for hm in holes:
            ys, xs = np.nonzero(hm)
            out.append(int(olab[ys[0] + sl[0].start - y0 + 1, xs[0] + sl[1].start - x0 + 1]))
        return out

    wa, wb = where(ha, sa), where(hb, sb)
    if ext in wa or ext in wb:
        return None
    if len(set(wa)) != len(wa) or len(set(wb)) != len(wb) or set(wa) != set(wb):
        return None
    pos_b = {lab: j for j, lab in enumerate(wb)}
    return [(i, pos_b[lab]) for i, lab in enumerate(wa)]


def _check_joins(stack):
    """Every overlapping component pair of consecutive slices: the two forms agree, for slices that
    keep their label images (the overlap counted from its mask) and for slices that keep their runs
    or were labelled in a box (the overlap counted from the runs, as for the mesher's slices and
    the sections'); returns how many pairs had holes on both sides and were paired."""
    paired = 0
    for kind in ("labels", "runs", "box"):
        slices = _kept_slices(stack, kind, "mlp")
        for A, B in zip(slices, slices[1:]):
            assert (A.kept_runs() is None) == (kind == "labels")
            la, lb = A.labels.astype(np.int64), B.labels.astype(np.int64)
            both = (la > 0) & (lb > 0)
            for key in np.unique(la[both] * (B.n + 1) + lb[both]).tolist():
                a, b = key // (B.n + 1) - 1, key % (B.n + 1) - 1
                got, want = volumes._simple_join(A, B, a, b), _simple_join_reference(A, B, a, b)
                assert got == want
                paired += bool(got) and kind == "runs"
    return paired


def _kept_slices(stack, kind, polygon):
    """The slices of ``stack``: keeping their label images ("labels"), their runs ("runs", with a
    :class:`volumes._RecentLabels`, as the mesher makes them) or labelled in a box ("box", the
    masks padded by two, as sections make them)."""
    to_center, to_corner = grid_to_xy(0.0, 0.0, 1.0, 1.0)
    if kind == "box":
        h, w = stack.shape[1:]
        return [volumes._Slice(np.pad(m, 2), polygon, to_corner, to_center, box=np.s_[1: h + 3, 2: w + 3])
                for m in stack]
    recent = volumes._RecentLabels() if kind == "runs" else None
    return [volumes._Slice(m, polygon, to_corner, to_center, recent) for m in stack]


def _check_overlap_topology(stack, every=False):
    """The overlap's ``(components, holes)`` from the slices' runs against the labeller's on its
    mask, for every overlapping component pair of consecutive slices (``every``: every pair of
    components, overlapping or not); returns how many overlaps had one component and holes, and
    how many had several components."""
    holed = split = 0
    pairs = []
    for kind in ("runs", "box"):
        slices = _kept_slices(stack, kind, "none")
        pairs += zip(slices, slices[1:])
    for A, B in pairs:
        la, lb = A.labels.astype(np.int64), B.labels.astype(np.int64)
        both = (la > 0) & (lb > 0)
        if every:
            keys = [(a + 1) * (B.n + 1) + b + 1 for a in range(A.n) for b in range(B.n)]
        else:
            keys = np.unique(la[both] * (B.n + 1) + lb[both]).tolist()
        for key in keys:
            a, b = key // (B.n + 1) - 1, key % (B.n + 1) - 1
            sa, sb = A.objects[a], B.objects[b]
            o = volumes._overlap_mask(A, B, a, b, 0, A.labels.shape[0], 0, A.labels.shape[1])
            want = volumes._overlap_topology_of_mask(o)
            got = volumes._overlap_topology(A.kept_runs(), np.int64(a), B.kept_runs(), np.int64(b),
                                            np.int64(max(sa[0].start, sb[0].start)),
                                            np.int64(min(sa[0].stop, sb[0].stop)))
            assert (int(got[0]), int(got[1])) == want
            holed += want[0] == 1 and want[1] > 0
            split += want[0] > 1
    return holed, split


def test_overlap_topology_from_runs_equals_the_labellers_on_random_stacks():
    rng = np.random.default_rng(11)
    holed = split = 0
    for _ in range(30):
        got = _check_overlap_topology(_holed_stack(rng))
        holed, split = holed + got[0], split + got[1]
    for seed in range(4):  # (salt: specks, diagonal touches, overlaps of many parts; every pair)
        for h, w in [(17, 29), (31, 8), (1, 12)]:
            r = np.random.default_rng(seed)
            stack = r.random((6, h, w)) < r.uniform(0.3, 0.8)
            got = _check_overlap_topology(stack, every=True)
            holed, split = holed + got[0], split + got[1]
    assert holed > 0 and split > 0


@pytest.mark.slow
def test_overlap_topology_from_runs_equals_the_labellers_on_the_shared_volumes(shared_data):
    import zlib

    from scipy.spatial.transform import Rotation

    from contourmesh.compare.inputs import load_closed_mesh
    from contourmesh.io import read_volume
    from contourmesh.voxelize import voxelize_mesh

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    v, f = load_closed_mesh(shared_data / "meshes" / "cgogn" / "socket.off")
    rot = Rotation.random(random_state=np.random.default_rng([20261204, zlib.crc32(b"socket")])).as_matrix()
    socket, _, _ = voxelize_mesh(v @ rot.T, f, 160)
    holed = split = 0
    for stack in (np.pad(vol, 1), np.pad(liver, 1)[::2], np.pad(socket, 1)):
        got = _check_overlap_topology(stack)
        holed, split = holed + got[0], split + got[1]
    assert holed > 0 and split > 0


def _holed_stack(rng, n=6, h=40, w=44):
    """Slices of a disc with a few holes that drift by a pixel from slice to slice (some close or
    split), with specks of noise: band joins whose holes pair, and some that do not."""
    yy, xx = np.mgrid[:h, :w]
    centres = rng.uniform([10, 10], [h - 10, w - 10], size=(int(rng.integers(1, 5)), 2))
    radii = rng.uniform(1.0, 4.0, size=len(centres))
    out = []
    for _ in range(n):
        disc = (yy - h / 2) ** 2 / (h / 2 - 2) ** 2 + (xx - w / 2) ** 2 / (w / 2 - 2) ** 2 < 1
        m = disc.copy()
        for (cy, cx), r in zip(centres, radii):
            m &= (yy - cy) ** 2 + (xx - cx) ** 2 > r * r
        m |= ~disc & (rng.random((h, w)) < 0.02)
        out.append(m)
        centres = centres + rng.integers(-1, 2, size=centres.shape)
        radii = np.clip(radii + rng.uniform(-0.7, 0.7, size=len(radii)), 0.3, 5.0)
    return np.array(out)


def test_simple_join_equals_its_numpy_form_on_random_stacks():
    rng = np.random.default_rng(5)
    assert sum(_check_joins(_holed_stack(rng)) for _ in range(30)) > 0


@pytest.mark.slow
def test_simple_join_equals_its_numpy_form_on_the_shared_volumes(shared_data):
    from contourmesh.io import read_volume

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    assert _check_joins(np.pad(vol, 1)[::2]) + _check_joins(np.pad(liver, 1)[100:260:3]) > 0


@pytest.mark.parametrize("box", [False, True])
def test_labels_made_again_are_the_labels_first_made(box):
    """A slice whose label image a :class:`volumes._RecentLabels` drops paints it again from the
    runs it keeps (or, labelled in a box, labels its mask whole): the same image, dtype and all."""
    to_center, to_corner = grid_to_xy(0.0, 0.0, 1.0, 1.0)
    recent = volumes._RecentLabels(size=1)
    masks = _random_masks(3, count=40) + [np.ones((3, 600), dtype=bool) ^ (np.arange(600) % 2 == 0)]
    for m in masks:
        if box:
            full = np.zeros((m.shape[0] + 4, m.shape[1] + 4), dtype=bool)
            full[2: 2 + m.shape[0], 2: 2 + m.shape[1]] = m
            s = volumes._Slice(full, "mlp", to_corner, to_center, recent, box=np.s_[1: m.shape[0] + 3, 2: m.shape[1] + 2])
        else:
            s = volumes._Slice(m, "mlp", to_corner, to_center, recent)
        first = s.labels.copy()
        other = volumes._Slice(np.ones((2, 2), dtype=bool), "mlp", to_corner, to_center, recent)
        assert s._labels is None and other._labels is not None  # (dropped)
        again = s.labels
        assert again.dtype == first.dtype and np.array_equal(again, first)
    assert recent.remade == len(masks)


def _mlps_both_ways(masks):
    from contourmesh.fastpath import slice_labels, slice_mlps_flat
    from contourmesh.tracing import slice_boxes

    n = 0
    for m in masks:
        labels, _, objects, runs = slice_labels(m, runs=True)
        boxes = slice_boxes(objects)
        want = slice_mlps_flat(labels, boxes)
        got = slice_mlps_flat(labels, boxes, runs)
        assert all(_same(a, b) for a, b in zip(got, want))
        n += len(boxes)
    return n


def test_mlps_from_the_runs_equal_the_mlps_from_the_labels():
    """The components' MLPs with their masks made from the runs (``_slice_mlps_runs``) and from the
    label image (``_slice_mlps``, the reference), on random masks and an empty one."""
    assert _mlps_both_ways(_random_masks(13, count=80) + [np.zeros((4, 5), dtype=bool)]) > 100


@pytest.mark.slow
def test_mlps_from_the_runs_on_the_shared_volumes(shared_data):
    assert _mlps_both_ways(_slices_of_volumes(shared_data)) > 100


def _check_overlap_groups(stack):
    """:func:`tracing.overlap_groups_runs` on the kept runs of each pair of consecutive slices
    (kept runs, or labelled in a box) against :func:`tracing.overlap_groups` on
    their label images: the same pairs and groups, in the same order; returns how many pairs of
    slices overlapped in several groups."""
    from contourmesh.tracing import overlap_groups, overlap_groups_runs

    several = 0
    runs, box = _kept_slices(stack, "runs", "none"), _kept_slices(stack, "box", "none")
    for A, B in list(zip(runs, runs[1:])) + list(zip(box, box[1:])):
        got = overlap_groups_runs(A.kept_runs(), B.kept_runs(), A.n, B.n)
        want = overlap_groups(A.labels, B.labels, A.n, B.n)
        assert got[0].dtype == np.int64
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1] == want[1]  # the same sets in the same order
        several += len(want[1]) > 1
    return several


def test_overlap_groups_from_runs_equal_the_pixel_scan_on_random_stacks():
    rng = np.random.default_rng(23)
    several = 0
    for _ in range(20):
        several += _check_overlap_groups(_holed_stack(rng))
    for seed in range(6):  # (salt: many components and pairs; a row, a column, an empty slice)
        for h, w in [(17, 29), (31, 8), (1, 12), (9, 1)]:
            r = np.random.default_rng(seed)
            stack = r.random((6, h, w)) < r.uniform(0.1, 0.8)
            stack[seed % 6] = False
            several += _check_overlap_groups(stack)
    assert several > 20


def test_overlap_groups_from_runs_refuse_a_table_too_large():
    from contourmesh.tracing import _PAIR_TABLE_MAX, overlap_groups_runs

    r = np.zeros((4, 0), np.int32)
    assert overlap_groups_runs(r, r, _PAIR_TABLE_MAX, 1) is None  # (the caller reads the label images)
    got = overlap_groups_runs(r, r, 3, 4)
    assert got[0].shape == (0, 2) and got[1] == []


@pytest.mark.slow
def test_overlap_groups_from_runs_on_the_shared_volumes(shared_data):
    import zlib

    from scipy.spatial.transform import Rotation

    from contourmesh.compare.inputs import load_closed_mesh
    from contourmesh.io import read_volume
    from contourmesh.voxelize import voxelize_mesh

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    v, f = load_closed_mesh(shared_data / "meshes" / "cgogn" / "socket.off")
    rot = Rotation.random(random_state=np.random.default_rng([20261204, zlib.crc32(b"socket")])).as_matrix()
    socket, _, _ = voxelize_mesh(v @ rot.T, f, 160)
    several = 0
    for stack in (np.pad(vol, 1), np.pad(liver, 1)[::2], np.pad(socket, 1)):
        several += _check_overlap_groups(stack)
    assert several > 0
