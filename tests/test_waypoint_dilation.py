"""The polyline keyholes' waypoints (``points_of`` in :func:`volumes._build_bridges`) take a
component's pixels and their 8-neighbours in its padded box: :func:`volumes._dilated_square` (two
shifted ORs down the columns, two along the rows) against the ``ndimage.binary_dilation`` by the
3 x 3 square it replaces, pixel for pixel, on random masks and on the components of slices of the
shared volumes."""

import numpy as np
from scipy import ndimage

from contourmesh import volumes
from contourmesh.fastpath import slice_labels
from test_slice_batch import _random_masks, _slices_of_volumes


def _reference(m):
    return ndimage.binary_dilation(m, structure=volumes._SQUARE)


def test_square_dilation_equals_ndimage_on_random_masks():
    rng = np.random.default_rng(5)
    masks = _random_masks(3, count=80) + [rng.random(s) < 0.2 for s in ((1, 1), (1, 7), (6, 1), (2, 2))]
    grown = 0
    for m in masks:
        got = volumes._dilated_square(m)
        assert got.dtype == bool and got.shape == m.shape
        assert np.array_equal(got, _reference(m))
        assert np.array_equal(m, m & got)  # (the input is left as it was, and kept)
        grown += int(got.sum() - m.sum())
    assert grown > 0


def test_square_dilation_equals_ndimage_on_the_shared_volumes(shared_data):
    seen = 0
    for m in _slices_of_volumes(shared_data)[::2]:
        labels, n, objects = slice_labels(m)
        for c, sl in enumerate(objects[:40]):
            # (the padded box points_of dilates: one pixel more on each side, within the slice)
            y0, x0 = max(sl[0].start - 1, 0), max(sl[1].start - 1, 0)
            own = labels[y0: sl[0].stop + 1, x0: sl[1].stop + 1] == c + 1
            assert np.array_equal(volumes._dilated_square(own), _reference(own))
            seen += 1
    assert seen > 100
