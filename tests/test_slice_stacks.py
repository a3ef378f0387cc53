"""The components' MLPs of a slice with the stacks' candidates taken from their runs
(:func:`volumes._slice_mlps_stacks`, read by ``_Slice``) against the reference that traces every
component on its cropped mask (:func:`fastpath._slice_mlps_runs`): bit for bit, on random masks,
on rows of bars (stacks only) and on slices of the shared volumes."""

import numpy as np

from contourmesh import volumes
from contourmesh.fastpath import _slice_mlps_runs, slice_labels
from contourmesh.tracing import slice_boxes
from test_slice_batch import _random_masks, _slices_of_volumes
from test_slice_holes import _same


def _stacks(runs, n):
    """How many of the ``n`` components have one run in each of their rows, rows consecutive."""
    ry, lab = runs[0], runs[3]
    count = 0
    for v in range(1, n + 1):
        rows = np.sort(ry[lab == v])
        count += bool(len(rows) and np.array_equal(rows, np.arange(rows[0], rows[0] + len(rows))))
    return count


def _check(masks):
    """Both kernels on every mask; returns the components that are stacks and the others."""
    stacks = others = 0
    for m in masks:
        _, n, objects, runs = slice_labels(m, runs=True)
        boxes = slice_boxes(objects)
        want = _slice_mlps_runs(boxes, *runs)
        got = volumes._slice_mlps_stacks(boxes, *runs)
        assert len(got) == 3
        for a, b in zip(got, want):
            assert _same(a, b)
        s = _stacks(runs, n)
        stacks += s
        others += n - s
    return stacks, others


def test_stack_mlps_equal_the_traced_mlps_on_random_masks():
    stacks, others = _check(_random_masks(31, count=120) + [np.zeros((4, 5), dtype=bool), np.ones((1, 1), dtype=bool)])
    assert stacks > 100 and others > 20


def test_stack_mlps_on_bars_and_blobs_of_every_width():
    """Stacks one pixel wide or high (MLPs without area), slanted bars, blobs beside them."""
    rng = np.random.default_rng(5)
    masks = []
    for _ in range(40):
        h, w = (int(v) for v in rng.integers(2, 30, 2))
        m = np.zeros((h, w), dtype=bool)
        for _ in range(int(rng.integers(1, 6))):
            y0, x0 = int(rng.integers(h)), int(rng.integers(w))
            hh, ww = int(rng.integers(1, h - y0 + 1)), int(rng.integers(1, w - x0 + 1))
            shift = int(rng.integers(-2, 3))
            for y in range(y0, y0 + hh):  # (a slanted bar: one run a row, rows consecutive)
                a = min(max(x0 + shift * (y - y0) // 2, 0), w - 1)
                m[y, a: a + ww] = True
        masks.append(m)
    stacks, others = _check(masks)
    assert stacks > 40 and others > 0


def test_stack_mlps_on_the_shared_volumes(shared_data):
    stacks, others = _check(_slices_of_volumes(shared_data))
    assert stacks > 0 and others > 0


def test_slices_read_the_stack_mlps(monkeypatch):
    """A slice made from its runs with the reference kernel in place of the new one has the same
    fields (the whole mask's one pass calls the new kernel compiled, and
    tests/test_volumes_slice_pass.py compares that pass with the reference)."""
    polygon = "mlp"
    from contourmesh.fastpath import slice_runs
    from contourmesh.geometry import grid_to_xy
    from test_slice_holes import _equal, _fields

    to_center, to_corner = grid_to_xy(-3.7, 12.25, 0.3, 0.7)
    masks = _random_masks(37, count=30)
    made = [volumes._Slice(m, polygon, to_corner, to_center, scanned=slice_runs(m)) for m in masks]
    monkeypatch.setattr(volumes, "_slice_mlps_stacks", _slice_mlps_runs)
    for m, a in zip(masks, made):
        b = volumes._Slice(m, polygon, to_corner, to_center, scanned=slice_runs(m))
        fa, fb = _fields(a), _fields(b)
        for key in fa:
            assert _equal(fa[key], fb[key]), key
