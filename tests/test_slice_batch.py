"""The slices' compiled per-slice passes (issue 16: no Python per component) against the per-component
code they replace: every component's crack contours (``tracing.slice_cracks``) and MLP
(``fastpath.slice_mlps_flat``) in one pass per slice, and a whole :class:`volumes._Slice` against the
per-component loop it used to run, on random masks and on slices of the shared volumes."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import volumes
from contourmesh.fastpath import pixels_mlp, slice_labels, slice_mlps_flat
from contourmesh.geometry import grid_to_xy
from contourmesh.tracing import _crack_contours, _label_runs, slice_boxes, slice_cracks


def slice_mlps(labels, boxes):
    """Per component, its MLP from :func:`slice_mlps_flat` (``None`` where it encloses no area), as
    :func:`pixels_mlp` gives each."""
    pts, ps, a2s = slice_mlps_flat(labels, boxes)
    out = []
    for c in range(len(a2s)):
        p = pts[ps[c]: ps[c + 1]]
        out.append(None if len(p) < 3 or a2s[c] == 0 else p.copy())
    return out


def _random_masks(seed, count=60):
    """Specks, holes, nested holes (rings in rings), touching diagonals, one-pixel lines, borders."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        kind = rng.integers(4)
        if kind == 0:  # salt: specks and diagonal touches
            m = rng.random((h, w)) < rng.uniform(0.05, 0.95)
        elif kind == 1:  # smooth blobs with holes
            v = ndimage.gaussian_filter(rng.random((h + 4, w + 4)), 1.0)[2:-2, 2:-2]
            m = v > np.quantile(v, rng.uniform(0.2, 0.8))
        elif kind == 2:  # nested rings (holes with islands with holes), a checkerboard corner
            yy, xx = np.mgrid[:h, :w]
            r = np.maximum(abs(yy - h / 2), abs(xx - w / 2)).astype(int)
            m = r % 4 < 2
            m[: h // 3, : w // 3] = (yy + xx)[: h // 3, : w // 3] % 2 == 0
        else:  # thin lines and a pinched ring
            m = np.zeros((h, w), dtype=bool)
            m[:, rng.integers(w)] = True
            m[rng.integers(h)] = True
            if h > 4 and w > 4:
                m[1:4, 1:4] = True
                m[2, 2] = False
                m[0, 0] = m[4, 4] = True
        out.append(m)
    return out


def _slices_of_volumes(shared_data):
    from contourmesh.io import read_volume

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    return [np.pad(vol[k], 1) for k in range(0, len(vol), 7)] + [np.pad(liver[k], 1) for k in range(0, len(liver), 11)]


def _check_cracks_and_mlps(masks):
    seen_holes = 0
    for m in masks:
        labels, n, objects, runs = slice_labels(m, runs=True)
        boxes = slice_boxes(objects)
        pts, starts, area2, first = slice_cracks(labels, boxes)
        # (the labeller's runs are those the label image gives, and the scan restricted to their
        # ends finds what it finds from them)
        assert all(_same(a, b) for a, b in zip(runs, _label_runs(labels)))
        assert all(_same(a, b) for a, b in zip(slice_cracks(labels, boxes, runs), (pts, starts, area2, first)))
        mlps = slice_mlps(labels, boxes)
        assert len(first) == n + 1 and len(mlps) == n
        for c, sl in enumerate(objects):
            comp = labels[sl] == c + 1
            cont, a2 = _crack_contours(comp)
            off = np.array([sl[1].start, sl[0].start])
            k0, k1 = first[c], first[c + 1]
            assert k1 - k0 == len(cont)
            seen_holes += len(cont) - 1
            for i in range(len(cont)):
                assert np.array_equal(pts[starts[k0 + i]: starts[k0 + i + 1]], cont[i] + off)
                assert np.sign(area2[k0 + i]) == np.sign(a2[i])
            want = pixels_mlp(comp)
            if want is None:
                assert mlps[c] is None
            else:
                assert mlps[c].dtype == want.dtype and np.array_equal(mlps[c], want)
    return seen_holes


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_slice_cracks_and_mlps_equal_the_per_component_code(seed):
    assert _check_cracks_and_mlps(_random_masks(seed)) > 0  # (holes were met)


def test_slice_cracks_of_an_empty_slice():
    labels, n, objects = slice_labels(np.zeros((5, 6), dtype=bool))
    pts, starts, area2, first = slice_cracks(labels, slice_boxes(objects))
    assert n == 0 and len(pts) == 0 and list(starts) == [0] and len(area2) == 0 and list(first) == [0]
    assert slice_mlps(labels, slice_boxes(objects)) == []


def test_slice_cracks_where_contours_meet_at_corners():
    """The scan tries only the run ends of the row above each corner row (``_slice_cracks``): on
    masks where contours meet at corners and holes nest (salt of every density, checkerboards,
    diagonal staircases with holes), the contours, their starts and their order are still those
    of the per-component tracer, which tries every corner."""
    rng = np.random.default_rng(16)
    masks = []
    for p in np.linspace(0.05, 0.95, 19):
        h, w = (int(v) for v in rng.integers(2, 30, 2))
        masks.append(rng.random((h, w)) < p)
    yy, xx = np.mgrid[:17, :23]
    masks.append((yy + xx) % 2 == 0)  # (every pixel meets its neighbours at corners only)
    masks.append(((yy + xx) % 2 == 0) | (yy % 4 == 0))  # (rows joining them: holes one pixel wide)
    masks.append((yy - xx) % 5 < 2)  # (diagonal staircases)
    stairs = (yy + 2 * xx) % 7 < 4
    stairs[3:14, 5:18] &= ~(((yy - 3) % 3 == 1) & ((xx - 5) % 3 == 1))[3:14, 5:18]  # (holes in them)
    masks.append(stairs)
    assert _check_cracks_and_mlps(masks) > 0  # (holes were met)


def _match_holes(crack_h, hmasks, off):
    """The old loop's pairing of hole contours with hole pixel sets: each contour takes the set that
    holds the pixel right of its first edge."""
    assert len(crack_h) == len(hmasks)
    out = []
    for h in crack_h:
        py, px = volumes._Slice._hole_seed(h, off)
        found = [m for m in hmasks if 0 <= py < m.shape[0] and 0 <= px < m.shape[1] and m[py, px]]
        assert len(found) == 1
        out.append(found[0])
    return out


def _reference_slice(s, mask2d, polygon, to_xy_corner, to_xy_center):
    """The per-component loop of ``_Slice.__init__`` before the compiled passes, on ``s``'s labels:
    ``(outer, holes, crack_outer_c, crack_holes_c, hole masks, fallbacks)``."""
    ref = volumes._Slice.__new__(volumes._Slice)
    ref.fallbacks = 0
    outer, holes, co, ch, hms = [], [], [], [], []
    labels = s.labels
    for c in range(s.n):
        sl = s.objects[c]
        y0, x0 = sl[0].start, sl[1].start
        comp = labels[sl] == c + 1
        cont, area2 = _crack_contours(comp)
        outer_i = [i for i in range(len(cont)) if area2[i] > 0]
        assert len(outer_i) == 1
        off = np.array([x0, y0])
        crack_o = cont[outer_i[0]] + off
        crack_h = [cont[i] + off for i in range(len(cont)) if area2[i] < 0]
        hmasks = []
        if crack_h:
            blab, nb = ndimage.label(volumes._pad1(~comp, True), structure=volumes._SQUARE)
            hmasks = [(blab == b)[1:-1, 1:-1] for b in range(1, nb + 1) if b != blab[0, 0]]
        hmasks = _match_holes(crack_h, hmasks, off)
        hms.append((sl, hmasks, comp.shape))
        co.append(crack_o)
        ch.append(crack_h)
        outer.append(ref._polygon(crack_o, comp, polygon, to_xy_corner, to_xy_center, off, hole=False))
        holes.append([ref._polygon(h, hm, polygon, to_xy_corner, to_xy_center, off, hole=True)
                      for h, hm in zip(crack_h, hmasks)])
    return outer, holes, co, ch, hms, ref.fallbacks


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


def _check_slices(masks, polygon, box=False):
    to_center, to_corner = grid_to_xy(-3.7, 12.25, 0.3, 0.7)
    for m in masks:
        if box:
            full = np.zeros((m.shape[0] + 6, m.shape[1] + 9), dtype=bool)
            full[3: 3 + m.shape[0], 5: 5 + m.shape[1]] = m
            s = volumes._Slice(full, polygon, to_corner, to_center, box=np.s_[2: m.shape[0] + 4, 4: m.shape[1] + 6])
            m = full
        else:
            s = volumes._Slice(m, polygon, to_corner, to_center)
        outer, holes, co, ch, hms, fallbacks = _reference_slice(s, m, polygon, to_corner, to_center)
        assert s.fallbacks == fallbacks
        assert len(s.outer) == len(s.holes) == len(s.crack_outer_c) == len(s.crack_holes_c) == s.n
        for c in range(s.n):
            assert _same(s.outer[c], outer[c]) and _same(s.crack_outer_c[c], co[c])
            assert len(s.holes[c]) == len(holes[c]) == len(s.crack_holes_c[c]) == len(ch[c])
            assert all(_same(p, q) for p, q in zip(s.holes[c], holes[c]))
            assert all(_same(p, q) for p, q in zip(s.crack_holes_c[c], ch[c]))
            sl, hm = s.hole_masks[c]
            assert sl == hms[c][0] and hm.shape == hms[c][2] and len(hm) == len(hms[c][1])
            assert all(_same(p, q) for p, q in zip(hm, hms[c][1]))


@pytest.mark.parametrize("polygon", ["mlp", "dss", "none"])
@pytest.mark.parametrize("box", [False, True])
def test_slice_equals_the_per_component_loop(polygon, box):
    _check_slices(_random_masks(7, count=40), polygon, box)


@pytest.mark.slow
def test_slices_of_the_shared_volumes(shared_data):
    masks = _slices_of_volumes(shared_data)
    assert _check_cracks_and_mlps(masks) > 0
    _check_slices(masks, "mlp")


def test_thin_part_polygons_kernel_equals_thin_part_polygon():
    """The slice's compiled batch of :func:`thin_part_polygon` (the outer polygons of components one
    pixel wide) gives its polygons, on every crack contour of random masks (thin or not: both of its
    answers, the DSS polygon and the crack contour itself), and leaves the contours that
    ``check_contour4`` refuses (marked not ok) to it."""
    from contourmesh.polygons import thin_part_polygon

    kinds = set()
    for m in _random_masks(7, count=80):
        labels, n, objects = slice_labels(m)
        pts, starts, _, _ = slice_cracks(labels, slice_boxes(objects))
        which = np.arange(len(starts) - 1, dtype=np.int64)
        # (a few faulty contours appended: too short, a step of two, a reversal)
        bad = [np.array([[0, 0], [1, 0], [1, 1]]), np.array([[0, 0], [2, 0], [2, 1], [0, 1]]),
               np.array([[0, 0], [1, 0], [0, 0], [0, 1]])]
        allp = np.concatenate([pts] + bad).astype(np.int64)
        st = np.concatenate([starts, starts[-1] + np.cumsum([len(b) for b in bad])]).astype(np.int64)
        which = np.concatenate([which, len(starts) - 1 + np.arange(len(bad))]).astype(np.int64)
        out, ost, ok = volumes._thin_part_polygons(allp, st, which)
        for j, i in enumerate(which.tolist()):
            c = allp[st[i]: st[i + 1]]
            if j >= len(which) - len(bad):
                assert not ok[j] and ost[j + 1] == ost[j]
                continue
            assert ok[j]
            want = thin_part_polygon(c)
            got = out[ost[j]: ost[j + 1]]
            assert _same(got, want)
            kinds.add(len(want) == len(c))
    assert kinds == {True, False}
