"""Shortcuts of the general mesher (issue 16) against the plain code they replace: each must give the
same numbers, so that the meshes stay the same bytes."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import volumes
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
