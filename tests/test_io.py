"""Readers and writers: round trips, the real sample files, and the bad-input catalogue."""

import gzip
import json
import os
import pickle
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

import contourmesh
from contourmesh.api import is_file_source, mesh_file
from contourmesh.api import mesh_stack as mesh_contour_stack
from contourmesh.errors import LostContourWarning
from contourmesh.geometry import points_in_rings
from contourmesh.io import load_mesh, read_contours, read_volume, stack_from_rings, write_contours_json, write_volume
from contourmesh.rasterize import default_pixel, rasterize_stack
from contourmesh.trimesh_plugin import register_trimesh_loader
from contourmesh.types import ContourStack, Section, shoelace_area
from contourmesh.volumes import volume_to_mesh, voxel_topology

DATA = Path(os.environ.get("CONTOURMESH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
RTSS = DATA / "contours" / "dicompyler-core" / "rtss.dcm"
RTSS_NPZ = DATA / "contours" / "dicompyler-core" / "rtss_contours.npz"
DGTAL = ["Al.100", "bunny-32", "bunny-64", "bunny-128", "cat10", "cat10b", "lobster", "lobsterCroped"]


def need(path):
    if not Path(path).exists():
        pytest.skip(f"sample data {path} not present (set CONTOURMESH_DATA to the ../shared/data mirror)")
    return path


@pytest.fixture
def blob():
    rng = np.random.default_rng(3)
    v = np.zeros((6, 7, 8), dtype=np.uint8)
    v[1:5, 2:6, 1:7] = rng.integers(0, 4, size=(4, 4, 6))
    return v


# ------------------------------------------------------------------------------------------------
# volume round trips
# ------------------------------------------------------------------------------------------------
def _reader_or_skip(suffix):
    """The optional reader of a suffix ([io] extra), or a skip that names it."""
    module = {".tif": "tifffile", ".nii": "nibabel", ".nii.gz": "nibabel"}.get(suffix)
    if module:
        pytest.importorskip(module)


@pytest.mark.parametrize("suffix", [".npz", ".npy", ".vol", ".tif", ".nii", ".nii.gz"])
def test_volume_round_trip(tmp_path, blob, suffix):
    _reader_or_skip(suffix)
    sp = (1.0, 1.0, 1.0) if suffix in (".vol", ".npy") else (2.5, 0.5, 0.75)
    org = (3.0, -2.0, 7.5) if suffix in (".npz", ".nii", ".nii.gz") else (0.0, 0.0, 0.0)
    p = write_volume(tmp_path / f"v{suffix}", blob, spacing=sp, origin=org)
    vol, spacing, origin = read_volume(p)
    assert vol.shape == blob.shape
    np.testing.assert_array_equal(vol, blob)
    np.testing.assert_allclose(spacing, sp, rtol=1e-6)
    np.testing.assert_allclose(origin, org)
    mask, _, _ = read_volume(p, label=2)
    np.testing.assert_array_equal(mask, blob == 2)
    mask, _, _ = read_volume(p, threshold=1)
    np.testing.assert_array_equal(mask, blob > 1)


def test_npz_axes_note_and_spacing_xyz_are_honoured(tmp_path):
    zyx = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4)
    p = tmp_path / "xyz.npz"
    np.savez(p, volume=zyx.transpose(2, 1, 0), spacing_xyz=np.array([0.5, 0.25, 3.0]),
             axes=np.array("volume[x, y, z]; x fastest"))
    vol, spacing, _ = read_volume(p)
    np.testing.assert_array_equal(vol, zyx)
    assert spacing == (3.0, 0.25, 0.5)
    p2 = tmp_path / "bad_axes.npz"
    np.savez(p2, volume=zyx, axes=np.array("rows and columns"))
    with pytest.raises(ValueError, match="axes"):
        read_volume(p2)


def test_array_passes_through_and_label_threshold_checks(blob):
    vol, sp, org = read_volume(blob)
    assert vol is blob and sp == (1.0, 1.0, 1.0) and org == (0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="not both"):
        read_volume(blob, label=1, threshold=0)
    with pytest.raises(ValueError, match="no voxel has label 9"):
        read_volume(blob, label=9)
    with pytest.raises(ValueError, match="3D"):
        read_volume(np.zeros((2, 2, 2, 2)))


# ------------------------------------------------------------------------------------------------
# real volumes
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", DGTAL)
def test_dgtal_vol_equals_its_npz(name):
    vol_path = need(DATA / "volumes" / "dgtal" / f"{name}.vol")
    npz = np.load(DATA / "volumes" / "dgtal" / f"{name}.npz", allow_pickle=False)
    vol, spacing, _ = read_volume(vol_path)
    np.testing.assert_array_equal(vol, npz["volume"].transpose(2, 1, 0))
    mask_vol, _, _ = read_volume(vol_path, threshold=int(npz["threshold"]))
    mask_npz, sp_npz, _ = read_volume(DATA / "volumes" / "dgtal" / f"{name}.npz")  # the stored mask
    np.testing.assert_array_equal(mask_vol, mask_npz)
    np.testing.assert_array_equal(mask_npz, npz["mask"].transpose(2, 1, 0))
    assert spacing == sp_npz == (1.0, 1.0, 1.0)


def test_liver_inrimage_labels():
    p = need(DATA / "volumes" / "cgogn" / "liver.inr.gz")
    vol, spacing, _ = read_volume(p)
    assert vol.shape == (329, 353, 438) and vol.dtype == np.uint8
    np.testing.assert_allclose(spacing, (0.666667, 0.617188, 0.617188))
    counts = {lab: int(np.count_nonzero(vol == lab)) for lab in (255, 127, 85, 84)}
    assert counts == {255: 6322002, 127: 628131, 85: 35274, 84: 6}  # data README
    npz_vol, npz_sp, _ = read_volume(DATA / "volumes" / "cgogn" / "liver.npz", label=255)
    np.testing.assert_array_equal(npz_vol, vol == 255)
    np.testing.assert_allclose(npz_sp, spacing)


# ------------------------------------------------------------------------------------------------
# contour stacks: RTSTRUCT
# ------------------------------------------------------------------------------------------------
def _counts(stack):
    n = [len(s.contours) for s in stack.sections]
    holes = sum(sum(p >= 0 for p in s.parents) for s in stack.sections)
    return len(stack), sum(n), max(n), holes


@pytest.mark.parametrize("roi, expected", [("BODY", (98, 141, 4, 2)), ("Lt Lung", (80, 165, 7, 77)),
                                           ("Heart", (33, 33, 1, 0))])
def test_rtstruct_rois(roi, expected):
    pytest.importorskip("pydicom")
    stack = read_contours(need(RTSS), roi=roi)
    assert _counts(stack) == expected  # sections, contours, max per slice, nested (holes)
    assert stack.spacing == (1.0, 1.0) and stack.meta["roi"] == roi and stack.meta["units"] == "mm"
    z = stack.z
    assert np.all(np.diff(z) > 0)
    np.testing.assert_allclose(np.diff(z), 3.0, atol=1e-6)  # 3 mm slices
    for s in stack.sections:
        for c, p in zip(s.contours, s.parents):
            assert c.dtype == np.float64 and c.shape[1] == 2 and len(c) >= 3
            a = shoelace_area(c)
            assert (a > 0) == (p == -1)  # outer positive, holes negative
            if p >= 0:
                assert s.parents[p] == -1 and points_in_rings(c, s.contours[p]).mean() > 0.5
    # the npz copy of the same contours gives the same stack
    same = read_contours(need(RTSS_NPZ), roi=roi.replace(" ", "_"))
    assert _counts(same) == expected
    for a, b in zip(stack.sections, same.sections):
        assert a.z == pytest.approx(b.z) and a.parents == b.parents
        for ca, cb in zip(a.contours, b.contours):
            np.testing.assert_allclose(ca, cb)


def test_rtstruct_roi_selection_errors():
    pytest.importorskip("pydicom")
    need(RTSS)
    with pytest.raises(ValueError, match=r"pass roi=.*'BODY'.*'Heart'.*'Lt Lung'"):
        read_contours(RTSS)
    with pytest.raises(ValueError, match=r"no ROI matches roi='Liver'; available ROIs: .*'Heart'"):
        read_contours(RTSS, roi="Liver")
    with pytest.raises(ValueError, match="'Areola' holds no contours"):
        read_contours(RTSS, roi="Areola")
    heart = read_contours(RTSS, roi=5)  # by ROI number
    assert heart.meta["roi"] == "Heart" and len(heart) == 33
    assert len(read_contours(RTSS, roi="lt lung")) == 80  # case-insensitive fallback


def test_lt_lung_raster_mesh_is_embedded():  # issue 13: it had 35 crossing pairs before the crossing fallback
    stack = read_contours(need(RTSS_NPZ), roi="Lt_Lung")
    with pytest.warns(LostContourWarning):
        r2 = rasterize_stack(stack, pixel=2.0)
    assert volume_to_mesh(r2.volume, **r2.mesh_kwargs, polygon="dss").checks()["self_intersections"] == 0


def test_lt_lung_raster_meshes_closed_with_the_voxel_genus():
    stack = read_contours(need(RTSS_NPZ), roi="Lt_Lung")
    # at the default pixel (median coordinate step, ~1 mm) each slice's pixel area matches the
    # signed area of its rings (outer minus holes)
    with pytest.warns(LostContourWarning):  # the lung's smallest vessel rings are below a pixel
        r = rasterize_stack(stack)
    px = default_pixel(stack)
    assert 0.9 < px <= 1.0 and r.spacing == (px, px)
    np.testing.assert_array_equal(r.z, stack.z)
    for k, s in enumerate(stack.sections):
        ring_area = sum(shoelace_area(c) for c in s.contours)
        assert r.volume[k].sum() * px * px == pytest.approx(ring_area, rel=0.08, abs=30 * px * px)
    # a coarser raster keeps the test fast; the mesh is closed and has the raster's genus
    with pytest.warns(LostContourWarning):
        r2 = rasterize_stack(stack, pixel=2.0)
    m = volume_to_mesh(r2.volume, **r2.mesh_kwargs, polygon="dss")
    chk, ref = m.checks(), voxel_topology(r2.volume)
    assert chk["closed"] and chk["watertight"] and chk["winding_consistent"]
    assert chk["components"] == ref["surfaces"] and chk["genus"] == ref["genus"]
    assert ref["genus"] > 0  # the lung's nested vessels make handles
    assert m.volume == pytest.approx(r2.volume.sum() * 4.0 * 3.0, rel=0.03)


# ------------------------------------------------------------------------------------------------
# contour stacks: JSON
# ------------------------------------------------------------------------------------------------
def _square(x0, y0, s, ccw=True):
    r = np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]], dtype=float)
    return r if ccw else r[::-1]


def _doc(slices, **kw):
    d = {"format": "contourmesh.contours", "version": 1, "units": "mm", "slices": slices}
    d.update(kw)
    return d


def test_json_round_trip_is_exact(tmp_path):
    outer, hole = _square(0, 0, 10), _square(3, 3, 4, ccw=False)
    stack = stack_from_rings([(0.0, [outer, hole]), (2.5, [outer * 1.1 + 0.123456789]), (4.0, [outer])])
    p = write_contours_json(stack, tmp_path / "s.contours.json")
    doc = json.loads(p.read_text())
    assert doc["format"] == "contourmesh.contours" and doc["version"] == 1 and len(doc["slices"]) == 3
    back = read_contours(p)
    assert back.z.tolist() == [0.0, 2.5, 4.0]
    for a, b in zip(stack.sections, back.sections):
        assert a.parents == b.parents
        for ca, cb in zip(a.contours, b.contours):
            np.testing.assert_array_equal(ca, cb)  # same points, start point and orientation


def test_json_round_trip_of_a_grid_stack_applies_spacing_and_origin(tmp_path):
    c = np.array([[0, 0], [2, 0], [2, 1], [0, 1]], dtype=np.int64)
    stack = ContourStack((Section(1.0, (c,)),), spacing=(0.5, 2.0), origin=(10.0, 20.0))
    back = read_contours(write_contours_json(stack, tmp_path / "g.json"))
    np.testing.assert_array_equal(back.sections[0].contours[0], [[10, 20], [11, 20], [11, 22], [10, 22]])


def test_json_either_winding_and_even_odd_nesting(tmp_path):
    # outer (given clockwise = negative), hole (given positive), island inside the hole
    rings = [_square(0, 0, 20, ccw=False), _square(4, 4, 12, ccw=True), _square(8, 8, 4, ccw=False)]
    p = tmp_path / "n.json"
    p.write_text(json.dumps(_doc([{"z": 0, "rings": [r.tolist() for r in rings]}])))
    s = read_contours(p).sections[0]
    assert s.parents == (-1, 0, -1)
    assert [np.sign(shoelace_area(c)) for c in s.contours] == [1, -1, 1]
    # re-orientation keeps the start point
    np.testing.assert_array_equal(s.contours[0][0], rings[0][0])


def test_json_two_point_ring_dropped_with_warning(tmp_path):
    p = tmp_path / "w.json"
    p.write_text(json.dumps(_doc([{"z": 1.5, "rings": [_square(0, 0, 3).tolist(), [[0, 0], [1, 1]], [[5, 5]]]}])))
    with pytest.warns(UserWarning, match=r"slice z=1.5: dropped 2 contour"):
        st = read_contours(p)
    assert len(st.sections[0].contours) == 1 and st.meta["dropped_contours"] == 2


def test_json_duplicate_and_unordered_z_are_merged_and_sorted(tmp_path):
    p = tmp_path / "d.json"
    p.write_text(json.dumps(_doc([{"z": 3.0, "rings": [_square(0, 0, 2).tolist()]},
                                  {"z": 0.0, "rings": [_square(0, 0, 2).tolist()]},
                                  {"z": 3.0004, "rings": [_square(5, 5, 2).tolist()]}])))
    st = read_contours(p)
    assert len(st) == 2 and st.z[0] == 0.0 and st.z[1] == pytest.approx(3.0002)
    assert len(st.sections[1].contours) == 2


@pytest.mark.parametrize("doc, match", [
    (_doc([{"z": 0, "rings": [[[0, 0], [1, float("nan")], [0, 1]]]}]), "NaN"),
    (_doc([{"z": float("inf"), "rings": []}]), "z must be finite"),
    (_doc([{"z": "a", "rings": []}]), "'z' as a number"),
    (_doc([{"z": 0, "rings": [[[0, 0, 1], [1, 0, 1], [0, 1, 1]]]}]), r"\(k, 2\)"),
    (_doc([{"z": 0, "rings": [[[0, 0], "x", [0, 1]]]}]), r"\[x, y\]"),
    (_doc([]), "no contour"),
    (_doc([], format="other"), "'format'"),
    (_doc([], version=2), "'version': 1"),
    ([1, 2], "JSON object"),
])
def test_json_bad_documents(tmp_path, doc, match):
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=match):
        read_contours(p)


def test_json_invalid_text(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"format": "contourmesh.contours", "slices": [')
    with pytest.raises(ValueError, match=r"bad.json.*invalid JSON at line 1"):
        read_contours(p)


def test_write_refuses_nan(tmp_path):
    st = ContourStack((Section(0.0, (np.array([[0, 0], [1, np.nan], [0, 1.0]]),)),))
    with pytest.raises(ValueError, match="NaN"):
        write_contours_json(st, tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()


# ------------------------------------------------------------------------------------------------
# rasterization and the meshing route
# ------------------------------------------------------------------------------------------------
def test_rasterize_square_with_hole_any_winding():
    for ccw in (True, False):
        st = ContourStack((Section(0.0, (_square(0, 0, 8, ccw), _square(2, 2, 4, ccw))),
                           Section(1.0, (_square(0, 0, 8, not ccw),)),
                           Section(4.0, (_square(0, 0, 8),))))
        vol, z, sp, org = rasterize_stack(st, pixel=1.0)
        assert vol.shape == (3, 11, 11) and sp == (1.0, 1.0) and org == (-1.0, -1.0, 0.0)
        assert z.tolist() == [0.0, 1.0, 4.0]  # uneven z kept
        assert vol[0].sum() == 64 - 16 and vol[1].sum() == 64
        assert not vol[0, 5, 5] and vol[0, 2, 2]  # pixel centre (4, 4) is in the hole, (1, 1) is not


def test_rasterize_limits_and_errors():
    big = ContourStack((Section(0.0, (_square(0, 0, 1e5),)),))
    with pytest.raises(ValueError, match="larger pixel"):
        rasterize_stack(big, pixel=1.0)
    tiny = ContourStack((Section(0.0, (_square(0.1, 0.1, 0.2),)),))
    with pytest.raises(ValueError, match="smaller pixel"):
        rasterize_stack(tiny, pixel=1.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        rasterize_stack(ContourStack((Section(1.0, (_square(0, 0, 2),)), Section(1.0, (_square(0, 0, 2),)))))
    with pytest.raises(ValueError, match="positive"):
        rasterize_stack(tiny, pixel=-1)


def test_mesh_contour_stack_routes():
    one = stack_from_rings([(z, [_square(0, 0, 6)]) for z in (0.0, 1.0, 2.0)])
    m = mesh_contour_stack(one, polygon="none")
    assert m.meta["route"] == "stack" and m.checks()["ok"]
    assert m.volume == pytest.approx(36 * 2.0)
    two = stack_from_rings([(z, [_square(0, 0, 6), _square(10, 0, 6)]) for z in (0.0, 1.0, 2.0)])
    m2 = mesh_contour_stack(two, polygon="mlp")
    chk = m2.checks()
    assert m2.meta["route"] == "raster" and chk["ok"] and chk["components"] == 2


def test_trimesh_loads_contour_json(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    register_trimesh_loader()
    register_trimesh_loader()  # idempotent
    st = stack_from_rings([(z, [_square(0, 0, 6), _square(2, 2, 2)]) for z in (0.0, 1.0, 2.0, 3.0)])
    p = write_contours_json(st, tmp_path / "ring.contours.json")
    tm = trimesh.load_mesh(str(p))
    assert isinstance(tm, trimesh.Trimesh) and tm.is_watertight
    ours = mesh_contour_stack(read_contours(p))
    np.testing.assert_array_equal(tm.vertices, ours.vertices)
    np.testing.assert_array_equal(tm.faces, ours.faces)
    assert tm.volume == pytest.approx(ours.volume) and tm.euler_number == 0  # a tube: genus 1
    assert tm.metadata["contourmesh"]["route"] == "contours"  # drawn rings: meshed between them
    assert tm.metadata["contourmesh"]["source"].endswith("ring.contours.json")
    # trimesh 4+/5: plain load() returns a Scene for file types outside its legacy mesh list
    scene = trimesh.load(str(p))
    geom = scene if isinstance(scene, trimesh.Trimesh) else next(iter(scene.geometry.values()))
    assert len(geom.faces) == len(tm.faces)
    other = tmp_path / "other.json"
    other.write_text('{"a": 1}')
    with pytest.raises(ValueError, match="contourmesh.contours"):
        trimesh.load_mesh(str(other))


# ------------------------------------------------------------------------------------------------
# meshes
# ------------------------------------------------------------------------------------------------
def test_load_mesh_merges_seams():
    p = need(DATA / "meshes" / "common-3d-test-models" / "spot.obj")
    m = load_mesh(p)
    chk = m.checks()
    assert chk["watertight"] and chk["genus"] == 0
    assert m.area == pytest.approx(5.70952, rel=1e-5)  # data README
    assert m.volume == pytest.approx(0.718259, rel=1e-5)


def test_load_mesh_bad_inputs(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_mesh(tmp_path / "none.obj")
    (tmp_path / "x.xyzmesh").write_text("")
    with pytest.raises(ValueError, match="expected a suffix among"):
        load_mesh(tmp_path / "x.xyzmesh")
    (tmp_path / "e.off").write_text("OFF\n0 0 0\n")
    with pytest.raises(ValueError, match="e.off"):
        load_mesh(tmp_path / "e.off")


# ------------------------------------------------------------------------------------------------
# the bad-input catalogue
# ------------------------------------------------------------------------------------------------
class Evil:
    """Unpickling this would create the marker file."""

    marker = None

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def test_pickled_npy_is_never_unpickled(tmp_path):
    marker = tmp_path / "UNPICKLED"
    Evil.marker = str(marker)
    p = tmp_path / "evil.npy"
    np.save(p, np.array([Evil()], dtype=object), allow_pickle=True)
    with pytest.raises(ValueError, match=r"evil.npy.*pickled Python objects"):
        read_volume(p)
    q = tmp_path / "evil.npz"
    np.savez(q, volume=np.array([Evil()], dtype=object))
    with pytest.raises(ValueError, match=r"evil.npz.*pickled"):
        read_volume(q)
    assert not marker.exists()
    # sanity: the payload is live (the marker appears when it *is* unpickled)
    pickle.loads(pickle.dumps(Evil()))
    assert marker.exists()


def _truncate(path, keep):
    data = Path(path).read_bytes()
    Path(path).write_bytes(data[: int(len(data) * keep) if isinstance(keep, float) else keep])
    return path


@pytest.mark.parametrize("suffix", [".npy", ".npz", ".vol", ".tif", ".nii", ".nii.gz"])
@pytest.mark.parametrize("keep", [0.6, 40])
def test_truncated_volume_files_raise_clear_errors(tmp_path, blob, suffix, keep):
    _reader_or_skip(suffix)
    p = write_volume(tmp_path / f"t{suffix}", np.tile(blob, (4, 4, 4)))
    _truncate(p, keep)
    with pytest.raises(ValueError, match=rf"t{suffix.replace('.', '[.]')}'.*expected"):
        read_volume(p)


def test_truncated_inr_raises(tmp_path):
    src = need(DATA / "volumes" / "cgogn" / "liver.inr.gz")
    p = tmp_path / "liver.inr.gz"
    p.write_bytes(src.read_bytes()[:50000])
    with pytest.raises(ValueError, match=r"liver.inr.gz.*(truncated|expected)"):
        read_volume(p)
    raw = tmp_path / "small.inr"
    raw.write_bytes(gzip.decompress(src.read_bytes())[:256 + 1000])
    with pytest.raises(ValueError, match=r"small.inr.*truncated"):
        read_volume(raw)


def test_truncated_rtstruct_raises(tmp_path):
    pytest.importorskip("pydicom")
    for keep in (0.5, 0.9, 200):
        p = tmp_path / "rt.dcm"
        p.write_bytes(need(RTSS).read_bytes())
        _truncate(p, keep)
        with pytest.raises(ValueError, match=r"rt.dcm'.*expected"):
            read_contours(p, roi="Lt Lung")


def test_vol_header_declaring_huge_size_raises_without_allocating(tmp_path):
    p = tmp_path / "huge.vol"
    p.write_bytes(b"X: 10000\nY: 10000\nZ: 10000\nVersion: 3\n.\n" + zlib.compress(b"\0" * 1000))
    t = time.perf_counter()
    with pytest.raises(ValueError, match=r"huge.vol.*1000000000000 voxels"):
        read_volume(p)
    with pytest.raises(ValueError, match=r"huge.vol.*compressed bytes"):
        read_volume(p, max_voxels=10**13)
    p.write_bytes(b"X: 10000\nY: 10000\nZ: 10000\nVersion: 2\n.\n" + b"\0" * 1000)
    with pytest.raises(ValueError, match=r"huge.vol.*truncated"):
        read_volume(p, max_voxels=10**13)
    assert time.perf_counter() - t < 1.0


def test_vol_bad_headers(tmp_path):
    p = tmp_path / "h.vol"
    p.write_bytes(b"X: 2\nY: 2\nZ: 2\nVersion: 3\n" + zlib.compress(b"\1" * 8))
    with pytest.raises(ValueError, match="terminating '.' line"):
        read_volume(p)
    p.write_bytes(b"X: 2\nY: -2\nZ: 2\nVersion: 3\n.\n" + zlib.compress(b"\1" * 8))
    with pytest.raises(ValueError, match="positive 'Y'"):
        read_volume(p)
    p.write_bytes(b"X: 2\nY: 2\nZ: 2\nVersion: 3\n.\n" + zlib.compress(b"\1" * 9))
    with pytest.raises(ValueError, match="more data"):
        read_volume(p)
    p.write_bytes(b"X: 2\nY: 2\nZ: 2\nVersion: 3\n.\n" + b"not zlib at all")
    with pytest.raises(ValueError, match="truncated or corrupt"):
        read_volume(p)


def test_paths_that_are_not_files(tmp_path):
    with pytest.raises(IsADirectoryError, match="is a directory; expected a volume file"):
        read_volume(tmp_path)
    with pytest.raises(IsADirectoryError, match="contour"):
        read_contours(tmp_path)
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        read_volume(tmp_path / "missing.npz")
    with pytest.raises(FileNotFoundError, match="missing.json"):
        read_contours(tmp_path / "missing.json")
    (tmp_path / "v.xyz").write_bytes(b"\0" * 10)
    with pytest.raises(ValueError, match=r"v.xyz.*expected a suffix among .*found '.xyz'"):
        read_volume(tmp_path / "v.xyz")
    with pytest.raises(ValueError, match=r"v.xyz.*expected a suffix among"):
        read_contours(tmp_path / "v.xyz")
    (tmp_path / "ct.dcm").write_bytes(b"\0" * 10)  # .dcm is a volume format too (DICOM-SEG, images)
    with pytest.raises(ValueError, match=r"ct.dcm'.*'DICM' marker.*10 bytes"):
        read_volume(tmp_path / "ct.dcm")
    (tmp_path / "fake.npy").write_bytes(b"hello world")
    with pytest.raises(ValueError, match=r"fake.npy.*expected a NumPy .npy file"):
        read_volume(tmp_path / "fake.npy")


def test_rtstruct_point_contours_duplicate_closing_points_and_specks(tmp_path):
    """Issue 15 item 4: POINT contours are skipped with a warning that counts them (a ROI of POINTs
    only is refused), a duplicate closing point changes nothing, and a 1- or 2-point contour is
    dropped with a warning naming its slice."""
    pydicom = pytest.importorskip("pydicom")
    from pydicom.dataset import Dataset

    from contourmesh.compare.phantoms import cylinder, draw, rtstruct_bytes

    stack = draw(cylinder(8, 12), 2.0, 0.5, seed=4)
    ds = pydicom.dcmread(__import__("io").BytesIO(rtstruct_bytes({"cyl": stack, "quirky": stack, "marks": stack})))

    def item(pts, kind="CLOSED_PLANAR"):
        c = Dataset()
        c.ContourGeometricType = kind
        c.NumberOfContourPoints = len(pts)
        c.ContourData = [f"{v:.10g}" for v in np.ravel(pts)]
        return c

    quirky, marks = ds.ROIContourSequence[1].ContourSequence, ds.ROIContourSequence[2]
    rings = [np.array([float(v) for v in c.ContourData]).reshape(-1, 3) for c in quirky]
    for c, r in zip(quirky, rings):  # each ring with its first point repeated at the end
        c.ContourData, c.NumberOfContourPoints = [f"{v:.10g}" for v in np.vstack([r, r[:1]]).ravel()], len(r) + 1
    quirky.append(item(rings[0][:1], "POINT"))
    quirky.append(item(rings[2][:2]))  # a 2-point contour on a plane that has a ring
    marks.ContourSequence = [item(rings[0][:1], "POINT"), item(rings[1][:1], "POINT")]
    path = tmp_path / "quirks.dcm"
    ds.save_as(path)
    ref = read_contours(path, roi="cyl")
    with pytest.warns(UserWarning) as rec:
        got = read_contours(path, roi="quirky")
    msgs = [str(w.message) for w in rec]
    assert any("skipped contours that are not CLOSED_PLANAR: {'POINT': 1}" in m for m in msgs), msgs
    assert any(f"z={got.z[2]:g}: dropped 1 contour(s) with fewer than 3 distinct points" in m for m in msgs), msgs
    assert len(got) == len(ref)
    for a, b in zip(ref.sections, got.sections):
        assert a.z == pytest.approx(b.z, abs=1e-12) and len(a.contours) == len(b.contours) == 1
        np.testing.assert_array_equal(a.contours[0], b.contours[0])
    assert contourmesh.mesh(got).volume == pytest.approx(contourmesh.mesh(ref).volume, rel=1e-9)
    with pytest.warns(UserWarning, match="'POINT': 2"), pytest.raises(ValueError, match="no contour found"):
        read_contours(path, roi="marks")


def test_rtstruct_not_planar_and_not_rtstruct(tmp_path):
    pydicom = pytest.importorskip("pydicom")
    ds = pydicom.dcmread(need(RTSS))
    rc = [r for r in ds.ROIContourSequence if int(r.ReferencedROINumber) == 5][0]
    item = rc.ContourSequence[0]
    data = [float(v) for v in item.ContourData]
    data[2] += 1.0  # first point off the contour's plane
    item.ContourData = data
    p = tmp_path / "tilted.dcm"
    ds.save_as(p)
    with pytest.raises(ValueError, match=r"'Heart' contour 0: expected a planar contour"):
        read_contours(p, roi="Heart")
    ct = need(DATA / "contours" / "dicompyler-core" / "ct.0.dcm")
    with pytest.raises(ValueError, match=r"ct.0.dcm.*RTSTRUCT.*found Modality 'CT'"):
        read_contours(ct)


def test_mesh_file_dispatches_volumes_and_contours(tmp_path):
    vol = np.zeros((4, 5, 6), dtype=np.uint8)
    vol[1:3, 1:4, 1:5] = 7
    p = write_volume(tmp_path / "box.npz", vol, spacing=(2.0, 1.0, 0.5))
    m = mesh_file(p, label=7, polygon="none", caps="half")  # half caps: the full voxel box
    assert m.checks()["ok"] and m.volume == pytest.approx(2 * 3 * 4 * 2.0 * 1.0 * 0.5)
    assert m.meta["source"] == str(p)
    with pytest.raises(TypeError, match="pixel= does not apply to a volume file"):
        mesh_file(p, label=7, pixel=1.0)
    st = stack_from_rings([(z, [_square(0, 0, 6), _square(10, 0, 6)]) for z in (0.0, 1.0, 2.0)])
    q = write_contours_json(st, tmp_path / "two.json")
    m2 = mesh_file(q, polygon="none")
    assert m2.meta["route"] == "contours" and m2.checks()["components"] == 2
    assert mesh_file(q, route="raster").meta["route"] == "raster"
    with pytest.raises(TypeError, match="threshold= does not apply to a contour file"):
        mesh_file(q, threshold=0)
    assert is_file_source(q) and is_file_source("missing.nii.gz") and is_file_source(Path("x"))
    assert not is_file_source("sphere:r=40") and not is_file_source(np.zeros(3))


# --- readers that keep the geometry (NIfTI affine, NRRD space directions, .seg.nrrd segments) ---------------
def _world_box_check(m, corner_lo, corner_hi):
    assert m.checks()["watertight"] and m.checks()["winding_consistent"] and m.volume > 0
    lo, hi = m.vertices.min(0), m.vertices.max(0)
    assert lo == pytest.approx(corner_lo, abs=1e-9) and hi == pytest.approx(corner_hi, abs=1e-9)


@pytest.mark.parametrize("axis", [0, 2])
def test_nifti_with_a_flipping_affine_meshes_in_world_coordinates(tmp_path, axis):
    nib = pytest.importorskip("nibabel")
    data = np.zeros((10, 12, 14), np.uint8)  # [i, j, k]
    data[2:6, 3:9, 4:11] = 1
    affine = np.diag([-2.0, 1.5, 3.0, 1.0])
    affine[:3, 3] = (100.0, -20.0, 5.0)
    p = tmp_path / "flip.nii.gz"
    nib.save(nib.Nifti1Image(data, affine), str(p))
    m = contourmesh.mesh(str(p), polygon="none", caps="half", axis=axis)
    # voxels i in 2..5 (x = 100 - 2 i, half a voxel either side), j in 3..8, k in 4..10
    _world_box_check(m, (100 - 2 * 5.5, -20 + 1.5 * 2.5, 5 + 3 * 3.5), (100 - 2 * 1.5, -20 + 1.5 * 8.5, 5 + 3 * 10.5))
    assert m.meta["space"] == "RAS" and m.volume == pytest.approx(4 * 6 * 7 * 2 * 1.5 * 3)


def test_nrrd_oblique_directions_and_segment_names(tmp_path):
    nrrd = pytest.importorskip("nrrd")
    data = np.zeros((10, 12, 14), np.uint8)  # [i, j, k]
    data[2:6, 3:9, 4:11] = 3
    data[7:9, 1:3, 1:3] = 5
    c, s = np.cos(0.4), np.sin(0.4)
    dirs = np.array([[c * 1.0, s * 1.0, 0.0], [-s * 2.0, c * 2.0, 0.0], [0.0, 0.0, 0.5]])  # rows: i, j, k
    hdr = {"space": "left-posterior-superior", "space directions": dirs, "space origin": np.array([1.0, 2.0, 3.0]),
           "Segment0_Name": "lesion", "Segment0_LabelValue": "3", "Segment0_Layer": "0",
           "Segment1_Name": "node", "Segment1_LabelValue": "5", "Segment1_Layer": "0"}
    p = tmp_path / "seg.seg.nrrd"
    nrrd.write(str(p), data, hdr, index_order="F")
    m = contourmesh.mesh(str(p), label="lesion", polygon="none", caps="half")
    assert m.checks()["watertight"] and m.volume == pytest.approx(4 * 6 * 7 * 1.0 * 2.0 * 0.5)
    # every vertex, mapped back to voxel coordinates, lies on the box [1.5, 5.5] x [2.5, 8.5] x [3.5, 10.5]
    ijk = np.linalg.solve(dirs.T, (m.vertices - [1.0, 2.0, 3.0]).T).T
    assert ijk.min(0) == pytest.approx([1.5, 2.5, 3.5], abs=1e-9)
    assert ijk.max(0) == pytest.approx([5.5, 8.5, 10.5], abs=1e-9)
    assert m.meta["space"] == "left-posterior-superior"
    assert contourmesh.mesh(str(p), label=5).checks()["components"] == 1
    with pytest.raises(ValueError, match="no segment named 'liver'; segments: \\['lesion', 'node'\\]"):
        contourmesh.mesh(str(p), label="liver")
