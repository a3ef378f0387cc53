"""A whole slice's labels, cracks, holes and MLPs in one compiled call (:func:`volumes._slice_pass`,
read by ``_Slice``) against the calls it replaces one by one (``slice_labels``, ``slice_boxes``,
``slice_cracks``, ``_slice_holes``, ``slice_mlps_flat`` and the thin outer parts'
``_thin_part_polygons``), and the slices made from it against those made from the same mask's runs
(the ``scanned`` route, which still makes those calls): bit for bit, on random masks and on slices
of the shared volumes."""

import numpy as np
import pytest

from contourmesh import volumes
from contourmesh.fastpath import _words_from, slice_labels, slice_mlps_flat, slice_runs
from contourmesh.geometry import grid_to_xy
from contourmesh.tracing import slice_boxes, slice_cracks
from test_slice_batch import _random_masks, _slices_of_volumes
from test_slice_holes import _equal, _fields, _same


def _one_by_one(m, mlp):
    """What ``_slice_pass`` returns, made by the calls one by one (``_Slice`` before it)."""
    labels, n, objects, runs = slice_labels(m, runs=True)
    boxes = slice_boxes(objects)
    pts, starts, area2, first = slice_cracks(labels, boxes, runs)
    found = volumes._slice_holes(labels, boxes, pts, starts, area2, first, np.int64(0), np.int64(0),
                                 np.int64(mlp))
    kept = np.empty((4, len(runs[0])), np.int32)
    kept[0], kept[1], kept[2], kept[3] = runs[0], runs[1], runs[2], runs[3] - 1
    if mlp:
        mlps = slice_mlps_flat(labels, boxes, runs)
        cnt = np.diff(mlps[1])
        which = found[1][np.flatnonzero(~((cnt >= 3) & (mlps[2] != 0)))] if found[0] == 0 else np.zeros(0, np.int64)
    else:
        mlps = (np.empty((0, 2), np.int64), np.zeros(n + 1, np.int64), np.empty(0, np.int64))
        which = np.zeros(0, np.int64)
    thin = volumes._thin_part_polygons(pts, starts, np.ascontiguousarray(which, dtype=np.int64))
    off = np.array([(x0, y0) for y0, _, x0, _ in boxes.tolist()], dtype=np.int64).reshape(-1, 2)
    moved = mlps[0] + np.repeat(off, np.diff(mlps[1]), axis=0)  # (as _outer_polygons moves them)
    return labels, n, boxes, kept, pts, starts, area2, first, found, mlps, thin, moved


def _pass(m, mlp):
    m = np.ascontiguousarray(m, dtype=bool)
    b8 = m.reshape(-1).view(np.uint8)
    b64, woff, aligned = _words_from(b8)
    return volumes._slice_pass(b8, b64, np.int64(m.shape[0]), np.int64(m.shape[1]), aligned, woff, np.int64(mlp))


def _flat(x):
    if isinstance(x, tuple):
        return [y for v in x for y in _flat(v)]
    return [x]


def _check_pass(masks):
    holes = thin = 0
    for m in masks:
        for mlp in (1, 0):
            got, want = _flat(_pass(m, mlp)), _flat(_one_by_one(m, mlp))
            assert len(got) == len(want)
            for i, (a, b) in enumerate(zip(got, want)):
                if isinstance(b, np.ndarray):
                    assert _same(a, b) or (not len(b) and not len(a) and a.dtype == b.dtype), (i, mlp)
                else:
                    assert int(a) == int(b), (i, mlp)
            found = _pass(m, mlp)[8]
            holes += len(found[2])
            thin += len(_pass(m, mlp)[10][2])
    return holes, thin


def _check_slices(masks, polygon):
    to_center, to_corner = grid_to_xy(-3.7, 12.25, 0.3, 0.7)
    for m in masks:
        for recent in (None, volumes._RecentLabels()):
            a = volumes._Slice(m, polygon, to_corner, to_center, recent)
            b = volumes._Slice(m, polygon, to_corner, to_center, recent, scanned=slice_runs(m))
            fa, fb = _fields(a), _fields(b)
            for key in fa:
                assert _equal(fa[key], fb[key]), key
            assert _equal(a.kept_runs(), b.kept_runs())


def test_slice_pass_is_the_calls_one_by_one():
    holes, thin = _check_pass(_random_masks(17, count=60) + [np.zeros((5, 7), bool), np.ones((3, 4), bool)])
    assert holes > 0 and thin > 0


@pytest.mark.parametrize("polygon", ["mlp", "dss", "none"])
def test_slices_from_the_pass_are_the_slices_from_the_runs(polygon):
    _check_slices(_random_masks(19, count=40), polygon)


def test_slice_pass_on_the_shared_volumes(shared_data):
    masks = _slices_of_volumes(shared_data)
    holes, _ = _check_pass(masks)
    assert holes > 0
    _check_slices(masks[::2], "mlp")


def _moved_after(m, mlp, sx, sy):
    """``_slice_pass`` with its box's numbers moved by ``(sx, sy)`` in numpy after the call, as
    ``_Slice`` moved them before ``_slice_pass_at``."""
    got = list(_pass(m, mlp))
    shift = np.array([sx, sy], dtype=np.int64)
    got[3][0] += sy
    got[3][1] += sx
    got[3][2] += sx
    got[4] = got[4] + shift
    got[8] = got[8][:6] + (got[8][6] + shift,) + got[8][7:]
    got[10] = (got[10][0] + shift,) + got[10][1:]
    got[11] = got[11] + shift
    return tuple(got)


def test_slice_pass_at_moves_what_the_slice_moved():
    rng = np.random.default_rng(41)
    moved = 0
    for m in _random_masks(43, count=40) + [np.zeros((3, 5), bool)]:
        sx, sy = (int(v) for v in rng.integers(0, 300, 2))
        for mlp in (1, 0):
            c = np.ascontiguousarray(m, dtype=bool)
            b8 = c.reshape(-1).view(np.uint8)
            b64, woff, aligned = _words_from(b8)
            got = volumes._slice_pass_at(b8, b64, np.int64(c.shape[0]), np.int64(c.shape[1]), aligned, woff,
                                         np.int64(mlp), np.int64(sx), np.int64(sy))
            got, want = _flat(got), _flat(_moved_after(m, mlp, sx, sy))
            assert len(got) == len(want)
            for i, (a, b) in enumerate(zip(got, want)):
                if isinstance(b, np.ndarray):
                    assert _same(a, b), (i, mlp)
                else:
                    assert int(a) == int(b), (i, mlp)
            moved += len(want[3][0]) > 0 and len(want[4]) > 0
    assert moved > 20
