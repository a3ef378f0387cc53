"""The runs of a Fortran-ordered volume's slices from one pass over its bytes
(:class:`contourmesh.fastpath.FortranRuns`, read by the general mesher through
:meth:`volumes._Planes.runs`) against the scan of each slice made C-ordered
(:func:`contourmesh.fastpath.slice_runs`, the form it replaces): the same arrays, bit for bit, on
random volumes of every size modulo 8 (the word compare's shifted and aligned cases), bytes other
than 0 and 1, a buffer not on a word boundary, more run ends than the pass's buffer holds (counted
in one pass, placed in another), and the shared volumes; and the slices (and meshes) made from them equal those made from
the mask."""

import numpy as np
import pytest

from contourmesh import volumes
from contourmesh.fastpath import FortranRuns, runs_labels, slice_labels, slice_runs
from contourmesh.geometry import grid_to_xy
from test_slice_batch import _random_masks


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


def _check(vol, cap=None):
    """Every slice's runs of ``FortranRuns(vol)`` equal ``slice_runs`` of the slice made C-ordered."""
    assert vol.flags.f_contiguous and vol.dtype == bool
    got = FortranRuns(vol, cap)
    for k in range(vol.shape[0]):
        want = slice_runs(np.ascontiguousarray(vol[k]))
        assert all(_same(a, b) for a, b in zip(got[k], want)), k
    return got


def _random_volumes(seed, count):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        k, h, w = (int(v) for v in rng.integers(1, 26, 3))
        yield np.asfortranarray(rng.random((k, h, w)) < rng.uniform(0.02, 0.98))


def test_runs_of_random_fortran_volumes_equal_the_slice_scan():
    sizes = set()
    for vol in _random_volumes(3, 250):
        _check(vol)
        sizes.add((vol.shape[0] * vol.shape[1]) % 8)
    assert sizes == set(range(8))  # (every shift of the word p bytes back)


def test_bytes_other_than_0_and_1_are_voxels():
    rng = np.random.default_rng(5)
    for vol in _random_volumes(7, 60):
        raw = vol.view(np.uint8)
        raw[...] = np.where(raw > 0, rng.integers(1, 256, raw.shape), 0).astype(np.uint8)
        assert (raw > 1).any() or not raw.any()
        _check(vol)


def test_a_buffer_off_a_word_boundary_is_read_byte_by_byte():
    rng = np.random.default_rng(9)
    for shape in [(8, 16, 9), (5, 7, 30), (16, 3, 17)]:
        n = int(np.prod(shape))
        buf = np.zeros(n + 8, dtype=np.uint8)
        vol = buf[3: 3 + n].view(bool).reshape(shape[::-1]).T  # Fortran-ordered, at an odd address
        assert vol.flags.f_contiguous and vol.ctypes.data % 8 != 0
        vol[...] = rng.random(shape) < 0.5
        _check(vol)


def test_more_run_ends_than_the_buffer_holds_are_counted_then_placed():
    """Past ``cap`` changes the pass counts them and finds them again (the buffer never grows):
    the same runs for buffers of 8 changes and more, a checkerboard of 80 x 64 x 40 (204 800
    changes) with the default buffer (one pass) and a smaller one."""
    for cap in (8, 13, 100):
        for vol in _random_volumes(17, 40):
            _check(vol, cap)
    z, y, x = np.indices((80, 64, 40))
    vol = np.asfortranarray((x + y + z) % 2 == 0)
    for cap in (None, 5000):
        assert len(_check(vol, cap).tx) == 80 * 64 * 40


def test_runs_of_the_shared_volumes(shared_data):
    from contourmesh.io import read_volume

    lobster, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    for vol in (lobster, liver[::3]):
        _check(np.asfortranarray(vol))


def test_runs_labels_equal_slice_labels():
    for m in _random_masks(4, count=60):
        want = slice_labels(m, runs=True)
        got = runs_labels(slice_runs(m), m.shape, runs=True)
        assert _same(got[0], want[0]) and got[1] == want[1] and got[2] == want[2]
        assert all(_same(a, b) for a, b in zip(got[3], want[3]))


@pytest.mark.parametrize("polygon", ["mlp", "dss", "none"])
def test_a_slice_from_its_runs_equals_the_slice_from_its_mask(polygon):
    from test_slice_holes import _equal, _fields

    to_center, to_corner = grid_to_xy(-3.7, 12.25, 0.3, 0.7)
    for m in _random_masks(12, count=40):
        if not m.any():
            continue
        vol = np.asfortranarray(np.stack([m, m[::-1]]))
        planes = volumes._Planes(vol)
        assert planes.fortran
        for k in range(2):
            recent = volumes._RecentLabels(1)
            a = volumes._Slice(vol[k], polygon, to_corner, to_center, recent, scanned=planes.runs(k))
            b = volumes._Slice(np.ascontiguousarray(vol[k]), polygon, to_corner, to_center, recent)
            fa, fb = _fields(a), _fields(b)
            for key in fa:
                assert _equal(fa[key], fb[key]), key
            assert _equal(fields_again(a), fields_again(b))  # (the labels painted again from the runs)
    assert volumes._Planes(np.ascontiguousarray(vol)).runs(0) is None
    assert volumes._Planes(np.transpose(np.asfortranarray(vol), (1, 0, 2))).runs(0) is None


def fields_again(s):
    s._labels = None
    return s.labels


def test_fortran_and_c_ordered_volumes_mesh_alike():
    """The general mesher on a Fortran-ordered volume (its slices' runs from the pass) and on the
    same volume C-ordered (each slice scanned): the same mesh."""
    rng = np.random.default_rng(21)
    from scipy import ndimage

    v = ndimage.gaussian_filter(rng.random((12, 30, 27)), 1.5)
    vol = np.pad(v > np.quantile(v, 0.55), 1)
    want = volumes.volume_to_mesh(np.ascontiguousarray(vol))
    assert "fast_path" not in want.meta
    got = volumes.volume_to_mesh(np.asfortranarray(vol))
    assert np.array_equal(got.vertices, want.vertices) and np.array_equal(got.faces, want.faces)
