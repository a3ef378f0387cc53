"""The sectioned joins' signed distance on pixels of any size (contourmesh.sections._sdf_any):
scipy's exact transform (sections._sdf_reference) bit for bit, with and without ``need``."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from scipy import ndimage

import contourmesh
from contourmesh import sections, volumes

SAMPLINGS = [(0.78125, 0.78125), (0.7, 0.7), (1 / 3, 1 / 3), (1.1, 1.1), (3.0, 3.0), (0.7, 0.9), (0.9, 0.7),
             (1.0, 0.78125), (2.5, 0.4), (1e-150, 1e-150), (1e150, 1e150), (1e-150, 3e-150), (1.0, 1e-3)]


def _masks(rng, count, largest):
    """Random masks of many kinds: noise of any density, blobs, one pixel, full, thin, striped,
    with empty and full rows and columns."""
    for t in range(count):
        h, w = int(rng.integers(1, largest)), int(rng.integers(1, largest))
        if t % 13 == 0:
            h = 1
        if t % 17 == 0:
            w = 1
        kind = t % 6
        if kind == 0:
            m = rng.random((h, w)) < rng.uniform(0.01, 0.99)
        elif kind in (1, 2):
            m = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.8, 6.0)) > rng.uniform(0.45, 0.55)
        elif kind == 3:
            m = np.zeros((h, w), bool)
            m[int(rng.integers(h)), int(rng.integers(w))] = True
        elif kind == 4:
            m = np.ones((h, w), bool)
        else:
            m = rng.random((h, w)) < 0.5
            m[:, ::2] = rng.random() < 0.5
        if t % 3 == 0:
            m[int(rng.integers(h))] = False
        if t % 5 == 0:
            m[:, int(rng.integers(w))] = True
        if m.any():
            yield m


def _check(m, sampling, need=None):
    m = np.asarray(m, dtype=bool)
    got = sections._sdf(m, sampling, need=need)
    ref = sections._sdf_reference(m, sampling)
    if need is not None:
        ref[~need] = np.where(m, -np.inf, np.inf)[~need]
    assert got.dtype == ref.dtype and got.shape == ref.shape
    assert got.tobytes() == ref.tobytes(), (m.shape, sampling)


@pytest.mark.parametrize("sampling", SAMPLINGS)
def test_compiled_transform_is_the_reference_bit_for_bit(sampling):
    assert sections._any_pixel_ok(*sampling, 200, 200)
    rng = np.random.default_rng(143)
    for m in _masks(rng, 120, 60):
        _check(m, sampling)


@pytest.mark.parametrize("sampling", [(0.78125, 0.78125), (0.7, 0.9), (1 / 3, 1 / 3)])
def test_compiled_transform_on_large_masks(sampling):
    rng = np.random.default_rng(1430)
    for m in _masks(rng, 12, 200):
        _check(m, sampling)
    for m in (np.ones((200, 200), bool), np.eye(200, dtype=bool), np.ones((1, 200), bool)):
        _check(m, sampling)


@pytest.mark.parametrize("sampling", [(0.78125, 0.78125), (0.7, 0.9), (3.0, 3.0), (1e-150, 1e-150)])
def test_compiled_transform_where_needed(sampling):
    rng = np.random.default_rng(1431)
    for m in _masks(rng, 80, 70):
        h, w = m.shape
        for need in (rng.random((h, w)) < 0.1, m ^ ndimage.binary_dilation(m), np.zeros((h, w), bool),
                     np.ones((h, w), bool)):
            _check(m, sampling, need=need)


def test_column_pass_is_a_nearest_feature_with_the_upper_one_on_ties():
    # the integer column pass against a plain search (nearest row, the smaller of two at one distance)
    rng = np.random.default_rng(1432)
    for m in _masks(rng, 60, 30):
        h, w = m.shape
        fi, fo = (rng.integers(-5, 9, size=(h + 2, w + 2)).astype(np.int32) for _ in range(2))
        sections._column_features(np.ascontiguousarray(m).view(np.uint8), fi, fo)
        pad = np.pad(m, 1)
        for feat, f in ((~pad, fi), (pad, fo)):
            for x in range(w + 2):
                rows = np.flatnonzero(feat[:, x])
                for y in range(h + 2):
                    want = -1 if rows.size == 0 else rows[np.argmin(np.abs(rows - y))]
                    assert f[y, x] == want


def test_pixel_sizes_out_of_reach_take_the_reference():
    m = np.zeros((5, 6), bool)
    m[2, 3] = True
    for sampling in ((2.0 ** -520, 2.0 ** -520), (1e300, 1e300), (1.0, 2.0 ** -600)):
        assert not sections._any_pixel_ok(*sampling, *m.shape)
        with np.errstate(all="ignore"):
            assert np.array_equal(sections._sdf(m, sampling), sections._sdf_reference(m, sampling), equal_nan=True)


def _mesh_hash(vol, spacing):
    got = contourmesh.mesh(vol, spacing=spacing)
    h = hashlib.sha1()
    h.update(np.ascontiguousarray(got.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(got.faces, dtype=np.int64).tobytes())
    return h.hexdigest()


def _reference_only(m, sampling, need=None):
    out = sections._sdf_reference(np.asarray(m, dtype=bool), sampling)
    if need is not None:
        need = np.asarray(need, dtype=bool)
        out[~need] = np.where(m, -np.inf, np.inf)[~need]
    return out


def test_meshes_on_non_power_of_two_pixels_are_unchanged(monkeypatch):
    # a mesh whose sectioned joins take the compiled transform, against the same mesh with every
    # signed distance from scipy (sections whose joins fork at 0.78125 mm pixels)
    from test_volumes_sections import _blobs, _sparse_rings

    _sparse_rings(monkeypatch)
    monkeypatch.setattr(volumes, "_SECTION_TRIAL", 0.0)  # every bridged join tries sections too
    seen = {"any": 0}
    sdf_any = sections._sdf_any

    def counted(*a):
        seen["any"] += 1
        return sdf_any(*a)

    vols = [_blobs(), _blobs(seed=3, shape=(6, 18, 18)), _blobs(seed=5, shape=(8, 24, 24))]
    spacings = ((1.0, 0.78125, 0.78125), (1.5, 0.7, 0.9))
    monkeypatch.setattr(sections, "_sdf_any", counted)
    got = [_mesh_hash(v, sp) for v in vols for sp in spacings]
    monkeypatch.setattr(sections, "_sdf", lambda m, s, need=None: _reference_only(m, s, need))
    ref = [_mesh_hash(v, sp) for v in vols for sp in spacings]
    assert got == ref
    assert seen["any"] > 0


def test_compiled_transform_with_dirty_arrays_of_either_width():
    # the column arrays come from the caller (the thread's kept int32 arrays, int64 on very tall
    # masks) with anything in them
    rng = np.random.default_rng(1434)
    for m in _masks(rng, 40, 50):
        h, w = m.shape
        ref = sections._sdf_reference(m, (0.7, 0.9))
        u8 = np.ascontiguousarray(m).view(np.uint8)
        for dt in (np.int32, np.int64):
            fi, fo = (rng.integers(-5, 9, size=(h + 2, w + 2)).astype(dt) for _ in range(2))
            assert sections._sdf_any(u8, 0.7, 0.9, 0.35, fi, fo, sections._ALL).tobytes() == ref.tobytes()
