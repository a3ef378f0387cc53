"""The least-area band's memory of recent calls (``bands.optimal._SEEN``): a band asked for again
is the band made afresh (same faces, bit for bit), the caller's copy is its own, and the bound
``max_work`` is part of the key."""

import numpy as np
import pytest

from contourmesh.bands import optimal
from contourmesh.bands.optimal import _optimal_faces, triangulate_band_optimal
from contourmesh.bands.wiederhold import validate_band_polygons


def _ring(rs, n, z):
    t = np.sort(rs.uniform(0, 2 * np.pi, n))
    r = rs.uniform(0.5, 2) * (1 + 0.2 * rs.standard_normal(n))
    return np.c_[r * np.cos(t), r * np.sin(t), np.full(n, z)]


def test_a_band_asked_again_is_the_band_made_afresh():
    rs = np.random.default_rng(5)
    optimal._SEEN.clear()
    pairs = [(_ring(rs, int(rs.integers(3, 30)), 0.0), _ring(rs, int(rs.integers(3, 60)), 1.0)) for _ in range(40)]
    for rep in range(2):
        for lo, hi in pairs:
            for max_work in (None, 300.0):
                want = _optimal_faces(*validate_band_polygons(lo, hi), max_work)
                got = triangulate_band_optimal(lo, hi, max_work=max_work)
                assert got.dtype == want.dtype and np.array_equal(got, want)
                got[:] = -1  # the caller's copy: the memory keeps its own
    assert len(optimal._SEEN) == optimal._SEEN_KEEP
    lo, hi = pairs[-1]
    assert np.array_equal(triangulate_band_optimal(lo, hi, max_work=300.0),
                          _optimal_faces(*validate_band_polygons(lo, hi), 300.0))


def test_the_bound_is_part_of_the_key():
    rs = np.random.default_rng(6)
    lo, hi = _ring(rs, 40, 0.0), _ring(rs, 90, 1.0)
    optimal._SEEN.clear()
    full = triangulate_band_optimal(lo, hi)
    bounded = triangulate_band_optimal(lo, hi, max_work=40 * 90 * 2)
    assert np.array_equal(full, _optimal_faces(*validate_band_polygons(lo, hi), None))
    assert np.array_equal(bounded, _optimal_faces(*validate_band_polygons(lo, hi), 40 * 90 * 2))
    assert len(optimal._SEEN) == 2


def test_bad_input_keeps_its_error_and_is_not_remembered():
    optimal._SEEN.clear()
    with pytest.raises(ValueError):
        triangulate_band_optimal(np.full((4, 3), np.nan), np.zeros((5, 3)))
    assert not optimal._SEEN


def test_the_size_limits_are_checked_before_the_memory(monkeypatch):
    rs = np.random.default_rng(7)
    lo, hi = _ring(rs, 20, 0.0), _ring(rs, 30, 1.0)
    optimal._SEEN.clear()
    triangulate_band_optimal(lo, hi)
    monkeypatch.setattr(optimal, "MAX_OPTIMAL_CELLS", 100)
    with pytest.raises(ValueError, match="table cells"):
        triangulate_band_optimal(lo, hi)
