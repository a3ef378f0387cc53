"""The sectioned joins' signed distances at the wanted pixels alone (sections._sdf_wanted and its
search round each pixel, sections._sdf_near): the same floats, bit for bit, as the whole transform
(sections._sdf with ``need``, read at those pixels), on random masks, where the search gives up
(its budget) and on the sections of the real volumes; and the same meshes without the search."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import sections
from contourmesh.volumes import volume_to_mesh
from test_volumes_sections import _blobs, _two_cs

SQUARE = [(1.0, 1.0), (0.5, 0.5), (4.0, 4.0), (2.0 ** -40, 2.0 ** -40)]


def _pairs(rng, count, largest):
    """Masks and wanted pixels: where two regions differ (as a sectioned join wants them), random
    pixels, a whole row, every pixel; regions of noise, blobs, one pixel, full, thin."""
    for t in range(count):
        h, w = int(rng.integers(1, largest)), int(rng.integers(1, largest))
        kind = t % 5
        if kind == 0:
            a = rng.random((h, w)) < rng.uniform(0.05, 0.95)
        elif kind in (1, 2):
            a = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.8, 5.0)) > rng.uniform(0.45, 0.55)
        elif kind == 3:
            a = np.zeros((h, w), bool)
            a[int(rng.integers(h)), int(rng.integers(w))] = True
        else:
            a = np.ones((h, w), bool)
            if t % 2:
                a[:, int(rng.integers(w))] = False
        if not a.any():
            continue
        b = a ^ (ndimage.gaussian_filter(rng.random((h, w)), 1.5) > rng.uniform(0.5, 0.6))
        which = t % 4
        if which == 0:
            need = a ^ b
        elif which == 1:
            need = rng.random((h, w)) < 0.05
        elif which == 2:
            need = np.zeros((h, w), bool)
            need[int(rng.integers(h))] = True
        else:
            need = np.ones((h, w), bool)
        yield a, need


def _full(m, sampling, need, at):
    return sections._sdf(m, sampling, need=need).ravel()[at]


@pytest.mark.parametrize("sampling", SQUARE + [(0.7, 0.7), (0.5, 0.25)])
def test_wanted_distances_are_the_whole_transforms(sampling):
    rng = np.random.default_rng(168)
    checked = 0
    for m, need in _pairs(rng, 150, 50):
        at = np.flatnonzero(need)
        got = sections._sdf_wanted(m, sampling, need, at)
        assert got.dtype == np.float64 and got.shape == at.shape
        assert got.tobytes() == _full(m, sampling, need, at).tobytes(), (m.shape, sampling)
        checked += len(at)
    assert checked > 1000


@pytest.mark.parametrize("sampling", SQUARE)
def test_the_search_is_the_square_transform_or_gives_up(sampling):
    """_sdf_near against _sdf_square read at the wanted pixels, with a budget that lets it finish
    and one that makes it give up on the larger masks (it says so; the caller takes the whole
    transform)."""
    rng = np.random.default_rng(5)
    s0 = sampling[0]
    gave_up = 0
    for m, need in _pairs(rng, 120, 60):
        at = np.flatnonzero(need)
        u8 = np.ascontiguousarray(m).view(np.uint8)
        ref = sections._sdf_square(u8, s0 * s0, 0.5 * s0, *sections._column_buffers(*m.shape),
                                   np.ascontiguousarray(need).view(np.uint8)).ravel()[at]
        got, done = sections._sdf_near(u8, s0 * s0, 0.5 * s0, at, np.int64(1 << 60))
        assert done and got.tobytes() == ref.tobytes()
        _, done = sections._sdf_near(u8, s0 * s0, 0.5 * s0, at, np.int64(3))
        gave_up += not done
        # and through _sdf_wanted with a small budget: the whole transform where the search gives up
        old = sections._NEAR_WORK
        try:
            sections._NEAR_WORK = 0
            assert sections._sdf_wanted(m, sampling, need, at).tobytes() == ref.tobytes()
        finally:
            sections._NEAR_WORK = old
    assert gave_up > 10


def test_far_pixels_and_the_padding():
    """Pixels far from any feature (a region filling its box but for one pixel, a lone pixel in a
    wide box): the padding is empty (a feature for the region), and off the region only its pixels
    count."""
    for shape in [(1, 1), (1, 40), (40, 1), (33, 47)]:
        m = np.ones(shape, bool)
        m[shape[0] // 2, shape[1] // 3] = False
        for mm in (m, ~m):
            if not mm.any():
                continue
            need = np.ones(shape, bool)
            at = np.flatnonzero(need)
            assert sections._sdf_wanted(mm, (1.0, 1.0), need, at).tobytes() == \
                _full(mm, (1.0, 1.0), need, at).tobytes()


def _record(monkeypatch):
    calls = []
    wanted = sections._sdf_wanted

    def recorded(m, sampling, need, at):
        calls.append((np.array(m, dtype=bool), sampling, np.array(need, dtype=bool), np.array(at)))
        return wanted(m, sampling, need, at)

    monkeypatch.setattr(sections, "_sdf_wanted", recorded)
    return calls, wanted


@pytest.mark.parametrize("name", ["lobster", "liver"])
def test_the_real_sections_distances(monkeypatch, shared_data, name):
    """Every signed distance the lobster's and the liver's sectioned joins ask for: the search's
    (with its budget, as the mesher runs it) against the whole transform's, bit for bit."""
    from contourmesh.io import read_volume

    if name == "lobster":
        vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    else:
        z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
        vol = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    calls, wanted = _record(monkeypatch)
    volume_to_mesh(vol)
    assert len(calls) > 50
    for m, sampling, need, at in calls:
        assert np.array_equal(np.flatnonzero(need), at)
        got = wanted(m, sampling, need, at)
        assert got.tobytes() == _full(m, sampling, need, at).tobytes()


def test_the_same_meshes_without_the_search(monkeypatch):
    vols = [_blobs(), _blobs(seed=3, shape=(6, 18, 18)), _two_cs()]
    monkeypatch.setattr(sections, "NEAR_FIRST", False)
    ref = [volume_to_mesh(v) for v in vols]
    monkeypatch.setattr(sections, "NEAR_FIRST", True)
    for v, r in zip(vols, ref):
        got = volume_to_mesh(v)
        assert got.vertices.tobytes() == r.vertices.tobytes() and got.faces.tobytes() == r.faces.tobytes()


#: Square pixels whose side is no power of two (the rotated sockets' 0.93 mm among them): there
#: the search is _sdf_near_any, measured in the whole transform's float operations.
NOT_POWER = [(0.7, 0.7), (0.9300629462322155, 0.9300629462322155), (1.3, 1.3), (3.0, 3.0), (0.1, 0.1)]


@pytest.mark.parametrize("sampling", NOT_POWER)
def test_the_any_search_is_the_transform_or_gives_up(sampling):
    """_sdf_near_any against _sdf_any read at the wanted pixels (scipy's numbers, see
    test_sdf_any_pixel.py), bit for bit wherever it finishes; it gives up on its budget and where
    the nearest pixels' floats differ (a tie it cannot settle), and _sdf_wanted then gives the whole
    transform's numbers."""
    rng = np.random.default_rng(185)
    s = sampling[0]
    done_n = ties = gave_up = 0
    for m, need in _pairs(rng, 150, 60):
        at = np.flatnonzero(need)
        u8 = np.ascontiguousarray(m).view(np.uint8)
        ref = _full(m, sampling, need, at)
        got, done = sections._sdf_near_any(u8, s, 0.5 * s, at, np.int64(1 << 60))
        if done:
            assert got.tobytes() == ref.tobytes(), (m.shape, sampling)
            done_n += 1
        else:
            ties += 1
        _, done = sections._sdf_near_any(u8, s, 0.5 * s, at, np.int64(3))
        gave_up += not done
        assert sections._sdf_wanted(m, sampling, need, at).tobytes() == ref.tobytes()
    assert done_n > 100 and gave_up > 10
    if sampling == (0.7, 0.7):
        assert ties > 0  # (the fallback on a tie is exercised)


def test_the_any_search_finds_ties_on_the_last_ring():
    """A pixel whose nearest features lie at one integer distance along an axis and off it
    (``25 = 5^2 + 0^2 = 3^2 + 4^2``): the search looks at the ring of radius 5 too, and either
    gives the transform's float or gives up."""
    for s in (0.7, 1.3, 0.9300629462322155):
        for feats in ([(5, 0)], [(3, 4)], [(5, 0), (3, 4)], [(0, 5), (4, 3)], [(5, 0), (0, -5)]):
            m = np.zeros((13, 13), bool)
            for dy, dx in feats:
                m[6 + dy, 6 + dx] = True
            need = np.zeros_like(m)
            need[6, 6] = True
            at = np.flatnonzero(need)
            ref = _full(m, (s, s), need, at)
            got, done = sections._sdf_near_any(np.ascontiguousarray(m).view(np.uint8), s, 0.5 * s, at,
                                               np.int64(1 << 60))
            assert not done or got.tobytes() == ref.tobytes()
            assert sections._sdf_wanted(m, (s, s), need, at).tobytes() == ref.tobytes()


def test_the_real_sections_distances_off_power_pixels(monkeypatch, shared_data):
    """The lobster's sectioned joins on 0.93 mm voxels (no power of two: _sdf_near_any): every
    signed distance they ask for against the whole transform's, bit for bit."""
    from contourmesh.io import read_volume

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    calls, wanted = _record(monkeypatch)
    volume_to_mesh(vol, spacing=(0.9300629462322155,) * 3)
    assert len(calls) > 50
    for m, sampling, need, at in calls:
        assert sampling[0] == sampling[1] == 0.9300629462322155
        got = wanted(m, sampling, need, at)
        assert got.tobytes() == _full(m, sampling, need, at).tobytes()


def test_the_same_meshes_without_the_search_off_power_pixels(monkeypatch):
    vols = [_blobs(), _blobs(seed=3, shape=(6, 18, 18)), _two_cs()]
    sp = (0.7, 0.7, 0.7)
    monkeypatch.setattr(sections, "NEAR_FIRST", False)
    ref = [volume_to_mesh(v, spacing=sp) for v in vols]
    monkeypatch.setattr(sections, "NEAR_FIRST", True)
    for v, r in zip(vols, ref):
        got = volume_to_mesh(v, spacing=sp)
        assert got.vertices.tobytes() == r.vertices.tobytes() and got.faces.tobytes() == r.faces.tobytes()
