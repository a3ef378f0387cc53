"""The per-slice kernels that set runs as block stores (:func:`fastpath._paint_labels`,
:func:`fastpath._slice_mlps_runs`, the hole bytes gathered by :func:`volumes._slice_holes`) against
their forms with a loop over every pixel (kept here as the reference): bit for bit, on random masks
and on slices of the shared volumes."""

import numpy as np
import pytest

from contourmesh import fastpath, volumes
from contourmesh.fastpath import slice_labels, slice_runs
from contourmesh.tracing import slice_boxes, slice_cracks
from test_slice_batch import _random_masks, _slices_of_volumes


def _paint_reference(ry, rx0, rx1, lab, h, w):
    """The label image painted a pixel at a time (the loop ``_paint_labels`` replaced)."""
    out = np.zeros((h, w), np.int32)
    for r in range(len(ry)):
        v = lab[r] + 1
        for x in range(rx0[r], rx1[r]):
            out[ry[r], x] = v
    return out


def _mlps_reference(boxes, ry, rx0, rx1, rlab):
    """``_slice_mlps_runs`` with each component's box cleared and its runs set a byte at a time."""
    n = boxes.shape[0]
    ps, a2s, out = np.empty(n + 1, np.int64), np.empty(n, np.int64), []
    size = max([1] + [int((b[1] - b[0]) * (b[3] - b[2])) for b in boxes])
    buf = np.empty(size, np.uint8)
    pos = 0
    for c in range(n):
        y0, y1, x0, x1 = (int(v) for v in boxes[c])
        hh, ww = y1 - y0, x1 - x0
        for i in range(hh * ww):
            buf[i] = 0
        for r in np.flatnonzero(rlab == c + 1).tolist():  # (its runs in raster order)
            base = (int(ry[r]) - y0) * ww - x0
            for x in range(int(rx0[r]), int(rx1[r])):
                buf[base + x] = 1
        p, a2 = fastpath._pixels_mlp(buf[: hh * ww], np.int64(hh), np.int64(ww))
        ps[c] = pos
        out.append(p)
        pos += len(p)
        a2s[c] = a2
    ps[n] = pos
    return (np.concatenate(out) if out else np.zeros((0, 2), np.int64)), ps, a2s


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


def _check(masks):
    """Both kernels against their references on every mask; returns the pixels painted."""
    painted = 0
    for m in masks:
        labels, n, objects, runs = slice_labels(m, runs=True)
        ry, rx0, rx1, rs = slice_runs(m)
        lab, n2, _, _, _ = fastpath._components_py(ry, rx0, rx1, rs, m.shape[0])
        got = fastpath._paint_labels(ry, rx0, rx1, lab, m.shape[0], m.shape[1])
        assert _same(got, _paint_reference(ry, rx0, rx1, lab, m.shape[0], m.shape[1]))
        assert _same(got, labels) and n2 == n
        # (the int32 runs a slice keeps, painted again when its labels were dropped)
        r32 = np.array([ry, rx0, rx1, lab], np.int32).astype(np.int64)
        assert _same(fastpath._paint_labels(*r32, m.shape[0], m.shape[1]), got)
        boxes = slice_boxes(objects)
        want = _mlps_reference(boxes, *runs)
        for a, b in zip(fastpath._slice_mlps_runs(boxes, *runs), want):
            assert _same(a, b)
        painted += int(np.count_nonzero(got))
    return painted


def _holes_reference(lab32, boxes, pts, starts, area2, first):
    """The hole bytes of every component, gathered a component at a time from
    :func:`contourmesh.tracing._hole_parts` (what ``_slice_holes`` concatenates)."""
    from contourmesh.tracing import _hole_parts

    parts = []
    _, outer_at, hole_at, hole_start = volumes._slice_holes(lab32, boxes, pts, starts, area2, first, np.int64(0),
                                                            np.int64(0), np.int64(0))[:4]
    for c in range(len(boxes)):
        h0, h1 = int(hole_start[c]), int(hole_start[c + 1])
        if h0 == h1:
            continue
        off = np.array([boxes[c, 2], boxes[c, 0]])
        seeds = np.array([volumes._Slice._hole_seed(pts[starts[i]: starts[i + 1]], off)
                          for i in hole_at[h0: h1].tolist()], dtype=np.int64)
        parts.append(_hole_parts(lab32, np.int64(c + 1), boxes[c], seeds)[1])
    return np.concatenate(parts) if parts else np.zeros(0, np.uint8)


def _check_holes(masks):
    held = 0
    for m in masks:
        labels, n, objects, runs = slice_labels(m, runs=True)
        boxes = slice_boxes(objects)
        pts, starts, area2, first = slice_cracks(labels, boxes, runs)
        flat = volumes._slice_holes(labels, boxes, pts, starts, area2, first, np.int64(0), np.int64(0),
                                    np.int64(1))[5]
        assert _same(flat, _holes_reference(labels, boxes, pts, starts, area2, first))
        held += len(flat)
    return held


@pytest.mark.parametrize("seed", [3, 17])
def test_block_fills_equal_the_pixel_loops_on_random_masks(seed):
    masks = _random_masks(seed, count=40) + [np.ones((5, 70), bool), np.zeros((4, 6), bool),
                                             np.ones((3, 600), dtype=bool) ^ (np.arange(600) % 2 == 0)]
    assert _check(masks) > 0
    assert _check_holes(masks) > 0


def test_block_fills_equal_the_pixel_loops_on_the_shared_volumes(shared_data):
    masks = _slices_of_volumes(shared_data)
    assert _check(masks[::2]) > 0
    assert _check_holes(masks) > 0


def test_hole_spans_equal_hole_parts_on_random_labels():
    """The run-at-a-time fill against the pixel-at-a-time one on random label images, boxes and
    seeds (any pixel not labelled ``v``: holes, the background round the component, a seed twice,
    seeds in one region), meta and bytes alike."""
    from contourmesh.tracing import _hole_parts, _hole_spans

    rng = np.random.default_rng(8)
    tried = 0
    for _ in range(300):
        h, w = (int(t) for t in rng.integers(1, 30, 2))
        lab = rng.integers(0, 3, (h, w)).astype(np.int32)
        if rng.random() < 0.5:  # (larger regions: smoothed noise)
            lab = (np.cumsum(rng.random((h, w)) < 0.3, axis=1) % 3).astype(np.int32)
        y0, x0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        box = np.array([y0, int(rng.integers(y0 + 1, h + 1)), x0, int(rng.integers(x0 + 1, w + 1))], np.int64)
        v = np.int64(rng.integers(0, 3))
        free = np.argwhere(lab[box[0]: box[1], box[2]: box[3]] != v)
        if not len(free):
            continue
        seeds = free[rng.integers(0, len(free), int(rng.integers(1, 5)))].astype(np.int64)
        got, want = _hole_spans(lab, v, box, seeds), _hole_parts(lab, v, box, seeds)
        assert _same(got[0], want[0]) and _same(got[1], want[1])
        tried += 1
    assert tried > 200
