"""DICOM volumes (issue 15 item 3): image series and DICOM-SEG read with their geometry, meshed in
the patient frame (LPS), routed by Modality; bad inputs raise errors that name the file.

Every file here is written by the test with pydicom from a geometry the test chooses, so the
expected world positions are computed from that geometry, not from the reader."""

import subprocess
import sys

import numpy as np
import pytest

pydicom = pytest.importorskip("pydicom")
from pydicom.dataset import Dataset, FileMetaDataset  # noqa: E402
from pydicom.sequence import Sequence  # noqa: E402
from pydicom.uid import ExplicitVRLittleEndian, generate_uid  # noqa: E402

import contourmesh  # noqa: E402
from contourmesh.api import mesh_file  # noqa: E402
from contourmesh.io import read_contours, read_image, read_volume  # noqa: E402

CT_STORAGE = "1.2.840.10008.5.1.4.1.1.2"
SEG_STORAGE = "1.2.840.10008.5.1.4.1.1.66.4"

# the ball, in the volume's own frame: index-space centre and radius (mm); spacing (dz, dy, dx)
SHAPE = (12, 24, 24)
SPACING = (2.0, 0.9, 1.1)
CENTRE_IJK = (11.3, 11.7, 5.6)  # (i, j, k) = (column, row, slice)
RADIUS = 7.5


def _rot(ax, ay, az):
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


# direction matrices (columns: row direction, column direction, slice normal)
AXIAL = np.eye(3)
FLIPPED = np.column_stack([[-1.0, 0, 0], [0, 1.0, 0], [0, 0, -1.0]])  # rows run right-to-left, slices head-to-feet
CORONAL_FLIP = np.column_stack([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # coronal, rows down the patient
OBLIQUE = _rot(0.35, -0.5, 0.8)
ORIGIN = np.array([-40.0, 25.0, 110.0])


def ball_mask():
    k, j, i = np.indices(SHAPE, dtype=np.float64)
    d2 = (((i - CENTRE_IJK[0]) * SPACING[2]) ** 2 + ((j - CENTRE_IJK[1]) * SPACING[1]) ** 2
          + ((k - CENTRE_IJK[2]) * SPACING[0]) ** 2)
    return d2 <= RADIUS ** 2


def world(direction, origin, ijk):
    """World (LPS) position of index-space point (i, j, k)."""
    return origin + direction @ (np.asarray(ijk, dtype=np.float64) * [SPACING[2], SPACING[1], SPACING[0]])


def _file_meta(sop_class, sop_uid):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = sop_uid
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    return meta


def _image_pixels(ds, arr, *, bits=16, signed=False):
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.Rows, ds.Columns = arr.shape[-2:]
    ds.BitsAllocated = bits
    ds.BitsStored = bits
    ds.HighBit = bits - 1
    ds.PixelRepresentation = int(signed)
    ds.PixelData = np.ascontiguousarray(arr).tobytes()


def write_series(folder, volume, direction, origin, *, spacing=SPACING, positions=None, uid=None, modality="CT",
                 slope=1.0, intercept=-1024.0, description="ball", number=3):
    """One single-frame file per slice of ``volume`` (stored values), in a shuffled file order
    with reversed InstanceNumbers, so that only positions can sort them."""
    folder.mkdir(parents=True, exist_ok=True)
    uid = uid or generate_uid()
    study = generate_uid()
    nz = volume.shape[0]
    row, col, normal = direction[:, 0], direction[:, 1], direction[:, 2]
    offsets = np.arange(nz) * spacing[0] if positions is None else np.asarray(positions, dtype=np.float64)
    order = np.random.default_rng(5).permutation(nz)
    paths = []
    for n, k in enumerate(order):
        sop = generate_uid()
        ds = Dataset()
        ds.file_meta = _file_meta(CT_STORAGE, sop)
        ds.SOPClassUID, ds.SOPInstanceUID = CT_STORAGE, sop
        ds.Modality = modality
        ds.StudyInstanceUID, ds.SeriesInstanceUID = study, uid
        ds.SeriesNumber, ds.SeriesDescription = number, description
        ds.InstanceNumber = nz - int(k)
        ds.ImageOrientationPatient = [f"{v:.10f}" for v in np.r_[row, col]]
        ds.ImagePositionPatient = [f"{v:.10f}" for v in origin + offsets[k] * normal]
        ds.PixelSpacing = [f"{spacing[1]:g}", f"{spacing[2]:g}"]
        ds.SliceThickness = f"{spacing[0]:g}"
        ds.RescaleSlope, ds.RescaleIntercept = f"{slope:g}", f"{intercept:g}"
        _image_pixels(ds, volume[k].astype(np.uint16))
        p = folder / f"img{n:03d}.dcm"
        ds.save_as(p, enforce_file_format=True)
        paths.append(p)
    return paths


def ct_of(mask):
    """Stored values of a CT of the ball: 1124 (100 HU) inside, 24 (-1000 HU) outside, intercept -1024."""
    return np.where(mask, 1124, 24).astype(np.uint16)


def centroid(m):
    v = m.vertices[m.faces]
    vol6 = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2]))
    return (vol6[:, None] * v.sum(axis=1)).sum(axis=0) / (4 * vol6.sum())


def assert_good(m):
    chk = m.checks()
    assert chk["watertight"] and chk["winding_consistent"] and chk["closed"], chk
    assert m.volume > 0 and chk["self_intersections"] == 0


# ------------------------------------------------------------------------------------------------
# image series
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name,direction", [("axial", AXIAL), ("flipped", FLIPPED), ("coronal", CORONAL_FLIP),
                                            ("oblique", OBLIQUE)])
def test_series_meshes_the_ball_in_lps(tmp_path, name, direction):
    mask = ball_mask()
    folder = tmp_path / name
    write_series(folder, ct_of(mask), direction, ORIGIN)
    img = read_image(folder, threshold=0)
    np.testing.assert_array_equal(img.volume, mask)
    assert img.spacing == pytest.approx(SPACING, abs=1e-9) and img.space == "LPS" and img.z is None
    np.testing.assert_allclose(img.direction, direction, atol=1e-9)
    np.testing.assert_allclose(img.origin, ORIGIN, atol=1e-6)
    m = contourmesh.mesh(str(folder), threshold=0)
    assert_good(m)
    assert m.meta["space"] == "LPS"
    centre = world(direction, ORIGIN, CENTRE_IJK)
    voxel = max(SPACING)
    assert np.linalg.norm(centroid(m) - centre) < 0.25 * voxel
    # the mesh's extent along each of the volume's axes: that of the ball's voxel centres, within half a voxel
    local = (m.vertices - ORIGIN) @ direction
    k, j, i = np.nonzero(mask)
    for axis, idx, h in ((0, i, SPACING[2]), (1, j, SPACING[1]), (2, k, SPACING[0])):
        assert local[:, axis].max() == pytest.approx(idx.max() * h, abs=0.5 * h)
        assert local[:, axis].min() == pytest.approx(idx.min() * h, abs=0.5 * h)


def test_oblique_mesh_is_the_axial_mesh_rotated(tmp_path):
    mask = ball_mask()
    write_series(tmp_path / "a", ct_of(mask), AXIAL, ORIGIN)
    other = np.array([3.0, -7.0, 55.0])
    write_series(tmp_path / "o", ct_of(mask), OBLIQUE, other)
    ma = contourmesh.mesh(str(tmp_path / "a"), threshold=0)
    mo = contourmesh.mesh(str(tmp_path / "o"), threshold=0)
    assert_good(ma) and assert_good(mo)
    assert mo.area == pytest.approx(ma.area, rel=1e-9) and mo.volume == pytest.approx(ma.volume, rel=1e-9)
    mapped = (ma.vertices - ORIGIN) @ OBLIQUE.T + other
    assert mo.vertices.shape == mapped.shape
    np.testing.assert_allclose(mo.vertices, mapped, atol=1e-6)
    np.testing.assert_array_equal(mo.faces, ma.faces)


def test_series_rescale_label_and_one_file_reads_its_series(tmp_path):
    mask = ball_mask()
    labels = np.where(mask, 7, 0).astype(np.uint16)
    labels[1:3, 2:6, 2:6] = 4
    paths = write_series(tmp_path / "s", labels, AXIAL, ORIGIN, slope=2.0, intercept=-5.0)
    from contourmesh.compare.phantoms import cylinder, draw, rtstruct_bytes

    # a structure set beside the slices (as planning systems export them) is not a slice: skipped
    (tmp_path / "s" / "rtss.dcm").write_bytes(rtstruct_bytes({"cyl": draw(cylinder(8, 12), 2.0, 0.5, seed=4)}))
    img = read_image(tmp_path / "s")
    assert img.volume.dtype == np.float64
    np.testing.assert_array_equal(img.volume, labels * 2.0 - 5.0)  # RescaleSlope/Intercept applied
    m9 = mesh_file(tmp_path / "s", label=9)  # 7 * 2 - 5
    assert_good(m9)
    # one file of the series names the whole series
    m1 = mesh_file(paths[4], label=9)
    np.testing.assert_array_equal(m1.vertices, m9.vertices)
    vol, spacing, origin = read_volume(paths[0], label=3)
    np.testing.assert_array_equal(vol, labels == 4)
    with pytest.raises(ValueError, match="names a segment.*give a number"):
        read_image(tmp_path / "s", label="Liver")


def test_uneven_series_is_meshed_at_its_positions(tmp_path):
    mask = ball_mask()
    positions = np.r_[0.0, np.cumsum([2.0, 2.0, 1.5, 2.5, 2.0, 3.0, 2.0, 2.0, 1.0, 2.0, 2.0])]
    write_series(tmp_path / "u", ct_of(mask), FLIPPED, ORIGIN, positions=positions)
    img = read_image(tmp_path / "u", threshold=0)
    np.testing.assert_allclose(img.z, positions, atol=1e-6)
    with pytest.raises(ValueError, match="not evenly spaced.*read_image"):
        read_volume(tmp_path / "u", threshold=0)
    planes = positions[np.any(mask, axis=(1, 2))]  # the slices that hold the ball
    m = contourmesh.mesh(str(tmp_path / "u"), threshold=0, polygon="none")
    assert_good(m)
    # flat caps: every vertex lies in one of those slice planes, and every plane has vertices
    along = (m.vertices - ORIGIN) @ FLIPPED[:, 2]
    np.testing.assert_allclose(np.unique(np.round(along, 6)), planes, atol=1e-6)
    half = contourmesh.mesh(str(tmp_path / "u"), threshold=0, polygon="none", caps="half")
    assert_good(half)
    along = (half.vertices - ORIGIN) @ FLIPPED[:, 2]
    k = np.flatnonzero(np.isin(positions, planes))
    assert along.min() == pytest.approx(planes[0] - 0.5 * (positions[k[0]] - positions[k[0] - 1]), abs=1e-6)
    assert along.max() == pytest.approx(planes[-1] + 0.5 * (positions[k[-1] + 1] - positions[k[-1]]), abs=1e-6)
    # an even grid at the mean step is not the same mesh: the positions matter
    even = tmp_path / "even"
    write_series(even, ct_of(mask), FLIPPED, ORIGIN, spacing=(positions[-1] / 11, SPACING[1], SPACING[2]))
    assert abs(contourmesh.mesh(str(even), threshold=0, polygon="none").volume - m.volume) > 1e-3 * m.volume
    with pytest.raises(ValueError, match="unevenly spaced.*axis=0"):
        contourmesh.mesh(str(tmp_path / "u"), threshold=0, axis=1)


# ------------------------------------------------------------------------------------------------
# DICOM-SEG
# ------------------------------------------------------------------------------------------------
def write_seg(path, segments: dict, direction, origin, *, spacing=SPACING, fractional=False, drop=(), positions=None):
    """A DICOM-SEG with one frame per (segment, slice) where the segment is non-empty, except the
    ``(segment, slice)`` pairs in ``drop``.  ``segments``: ``{number: (label, mask [z, y, x])}``."""
    sop = generate_uid()
    ds = Dataset()
    ds.file_meta = _file_meta(SEG_STORAGE, sop)
    ds.SOPClassUID, ds.SOPInstanceUID = SEG_STORAGE, sop
    ds.Modality = "SEG"
    ds.StudyInstanceUID, ds.SeriesInstanceUID = generate_uid(), generate_uid()
    ds.SegmentationType = "FRACTIONAL" if fractional else "BINARY"
    if fractional:
        ds.MaximumFractionalValue = 200
        ds.SegmentationFractionalType = "PROBABILITY"
    items = []
    for num, (label, _) in segments.items():
        it = Dataset()
        it.SegmentNumber, it.SegmentLabel, it.SegmentAlgorithmType = num, label, "MANUAL"
        items.append(it)
    ds.SegmentSequence = Sequence(items)
    row, col, normal = direction[:, 0], direction[:, 1], direction[:, 2]
    shared = Dataset()
    po = Dataset()
    po.ImageOrientationPatient = [f"{v:.10f}" for v in np.r_[row, col]]
    pm = Dataset()
    pm.PixelSpacing = [f"{spacing[1]:g}", f"{spacing[2]:g}"]
    pm.SliceThickness = f"{spacing[0]:g}"
    shared.PlaneOrientationSequence, shared.PixelMeasuresSequence = Sequence([po]), Sequence([pm])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    frames, per = [], []
    rng = np.random.default_rng(2)
    for num, (_, mask) in segments.items():
        for k in range(mask.shape[0]):
            if not mask[k].any() or (num, k) in drop:
                continue
            fg = Dataset()
            pp = Dataset()
            at = k * spacing[0] if positions is None else positions[k]
            pp.ImagePositionPatient = [f"{v:.10f}" for v in origin + at * normal]
            fg.PlanePositionSequence = Sequence([pp])
            si = Dataset()
            si.ReferencedSegmentNumber = num
            fg.SegmentIdentificationSequence = Sequence([si])
            per.append(fg)
            if fractional:  # inside: 101..200 (>= half), outside: 0..99
                frames.append(np.where(mask[k], rng.integers(101, 201, mask[k].shape), rng.integers(0, 100, mask[k].shape)))
            else:
                frames.append(mask[k])
    ds.PerFrameFunctionalGroupsSequence = Sequence(per)
    ds.NumberOfFrames = len(frames)
    arr = np.stack(frames)
    if fractional:
        _image_pixels(ds, arr.astype(np.uint8), bits=8)
    else:
        _image_pixels(ds, arr.astype(np.uint8), bits=1)
        ds.BitsStored, ds.HighBit = 1, 0
        ds.PixelData = pydicom.pixels.pack_bits(arr.astype(np.uint8))  # bits run on across frames
    ds.save_as(path, enforce_file_format=True)
    return path


def _two_segments(shape):
    k, j, i = np.indices(shape)
    ball = ((i - 9.4) * 1.1) ** 2 + ((j - 10.2) * 0.9) ** 2 + ((k - 5.5) * 2.0) ** 2 <= 6.5 ** 2
    box = (k >= 2) & (k <= 9) & (j >= 15) & (j <= 19) & (i >= 15) & (i <= 20)
    return ball, box


@pytest.mark.parametrize("fractional", [False, True])
def test_seg_segments_by_number_and_name(tmp_path, fractional):
    shape = (12, 23, 21)  # 483 pixels a frame: 1-bit frames do not end on a byte
    ball, box = _two_segments(shape)
    p = write_seg(tmp_path / "seg.dcm", {1: ("Liver", ball), 2: ("Node", box)}, OBLIQUE, ORIGIN,
                  fractional=fractional, drop={(2, 5)})
    img = read_image(p)
    assert not np.any(ball & box)
    expected = np.where(ball, 1, 0)
    expected[box] = 2
    expected[5][box[5]] = 0  # the dropped frame: segment 2 is empty in slice 5
    k0, k1 = np.flatnonzero(expected.any(axis=(1, 2)))[[0, -1]]  # the file has frames in slices k0..k1 only
    np.testing.assert_array_equal(img.volume, expected[k0:k1 + 1])
    assert img.space == "LPS" and img.spacing == pytest.approx(SPACING, abs=1e-9)
    np.testing.assert_allclose(img.direction, OBLIQUE, atol=1e-9)
    np.testing.assert_allclose(img.origin, world(OBLIQUE, ORIGIN, (0, 0, k0)), atol=1e-6)
    np.testing.assert_array_equal(read_image(p, label="Liver").volume, ball[k0:k1 + 1])
    np.testing.assert_array_equal(read_image(p, label=2).volume, (box & (np.arange(12) != 5)[:, None, None])[k0:k1 + 1])
    m = contourmesh.mesh(str(p), label="Liver")
    assert_good(m)
    assert m.meta["space"] == "LPS"
    centre = ORIGIN + OBLIQUE @ (np.array([9.4, 10.2, 5.5]) * [1.1, 0.9, 2.0])
    assert np.linalg.norm(centroid(m) - centre) < 0.5
    np.testing.assert_array_equal(contourmesh.mesh(str(p), label=1).vertices, m.vertices)
    node = contourmesh.mesh(str(p), label="node", polygon="none", caps="half")  # names match case-insensitively
    assert_good(node)
    assert node.checks()["components"] == 2  # split at the dropped frame
    assert node.volume == pytest.approx((box.sum() - box[5].sum()) * np.prod(SPACING), rel=1e-9)
    with pytest.raises(ValueError, match=r"no segment named 'Spleen'; segments: 1: 'Liver', 2: 'Node'"):
        read_image(p, label="Spleen")
    with pytest.raises(ValueError, match="no segment numbered 3"):
        read_image(p, label=3)


def test_seg_missing_positions_are_empty_slices(tmp_path):
    """Frames only where a segment is non-empty; a slice empty in every segment is absent from the
    file and comes back as an empty slice (the grid is whole multiples of the step)."""
    shape = (12, 16, 16)
    a = np.zeros(shape, bool)
    a[1:4, 3:9, 3:9] = True
    b = np.zeros(shape, bool)
    b[7:11, 5:12, 4:10] = True  # slices 4..6 are empty everywhere
    p = write_seg(tmp_path / "gap.dcm", {1: ("A", a), 5: ("B", b)}, FLIPPED, ORIGIN)
    img = read_image(p)
    assert img.volume.shape == (10, 16, 16) and img.z is None  # slices 1..10 of the grid
    np.testing.assert_array_equal(img.volume, (np.where(a, 1, 0) + np.where(b, 5, 0))[1:11])
    np.testing.assert_allclose(img.origin, ORIGIN + 1 * SPACING[0] * FLIPPED[:, 2], atol=1e-6)
    m = contourmesh.mesh(str(p), label="B", polygon="none", caps="half")
    assert_good(m)
    # the box's corners in world coordinates, half a voxel out
    ijk = np.linalg.solve(FLIPPED, (m.vertices - ORIGIN).T).T / [SPACING[2], SPACING[1], SPACING[0]]
    assert ijk.min(0) == pytest.approx([3.5, 4.5, 6.5], abs=1e-9) and ijk.max(0) == pytest.approx([9.5, 11.5, 10.5], abs=1e-9)


def test_seg_uneven_positions_are_kept(tmp_path):
    """Steps that are not whole multiples of one step: the slices stay at their positions (Image.z)
    and the mesh's sections lie in those planes."""
    shape = (6, 16, 16)
    a = np.zeros(shape, bool)
    a[:, 4:11, 3:12] = True
    positions = np.array([0.0, 2.0, 3.5, 6.0, 7.0, 10.0])
    p = write_seg(tmp_path / "uneven.dcm", {1: ("A", a)}, OBLIQUE, ORIGIN, positions=positions)
    img = read_image(p)
    np.testing.assert_allclose(img.z, positions, atol=1e-6)
    m = contourmesh.mesh(str(p), polygon="none")
    assert_good(m)
    along = (m.vertices - ORIGIN) @ OBLIQUE[:, 2]
    np.testing.assert_allclose(np.unique(np.round(along, 6)), positions, atol=1e-6)
    # flat caps, straight walls: the volume is the section area times the span
    assert m.volume == pytest.approx(7 * SPACING[1] * 9 * SPACING[2] * 10.0, rel=1e-9)  # 7 x 9 pixels


def test_all_labels_of_a_seg_by_the_cli(tmp_path):
    shape = (12, 23, 21)
    ball, box = _two_segments(shape)
    p = write_seg(tmp_path / "seg.dcm", {1: ("Liver", ball), 2: ("Node", box)}, CORONAL_FLIP, ORIGIN)
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "contourmesh", "mesh", str(p), "--all-labels", "-o", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rows = (out / "labels.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[1].startswith("1,") and rows[2].startswith("2,")
    r = subprocess.run([sys.executable, "-m", "contourmesh", "mesh", str(p), "--label", "Node", "-o",
                        str(tmp_path / "node.ply"), "--json", "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert '"space": "LPS"' in r.stdout


# ------------------------------------------------------------------------------------------------
# routing and bad inputs
# ------------------------------------------------------------------------------------------------
def test_rtstruct_still_routes_to_contours(tmp_path):
    from contourmesh.compare.phantoms import cylinder, draw, rtstruct_bytes

    p = tmp_path / "rt.dcm"
    p.write_bytes(rtstruct_bytes({"cyl": draw(cylinder(8, 12), 2.0, 0.5, seed=4)}))
    m = contourmesh.mesh(str(p))
    assert_good(m)
    assert m.meta["route"] == "contours"
    with pytest.raises(ValueError, match=r"rt.dcm' is a DICOM RTSTRUCT.*read_contours"):
        read_image(p)
    seg = write_seg(tmp_path / "seg.dcm", {1: ("A", ball_mask())}, AXIAL, ORIGIN)
    with pytest.raises(ValueError, match=r"seg.dcm.*RTSTRUCT.*found Modality 'SEG'"):
        read_contours(seg)
    with pytest.raises(TypeError, match="roi= does not apply to a volume file"):
        contourmesh.mesh(str(seg), roi="A")


def test_bad_dicom_inputs(tmp_path):
    mask = ball_mask()
    two = tmp_path / "two"
    write_series(two, ct_of(mask), AXIAL, ORIGIN, description="first", number=3)
    write_series(two / "x", ct_of(mask), AXIAL, ORIGIN + 1, description="second", number=4)
    for f in (two / "x").iterdir():
        f.rename(two / ("b" + f.name))
    (two / "x").rmdir()
    (two / "notes.txt").write_text("not dicom")  # files without the marker are skipped in a folder
    with pytest.raises(ValueError, match=r"holds 2 DICOM series.*series=") as err:
        read_image(two)
    assert "(CT 3 first, 12 files" in str(err.value) and "(CT 4 second, 12 files" in str(err.value)
    assert read_image(two, series=4, threshold=0).volume.sum() == mask.sum()
    with pytest.raises(ValueError, match="no series match series=5"):
        read_image(two, series=5)

    sizes = tmp_path / "sizes"
    write_series(sizes, ct_of(mask), AXIAL, ORIGIN, uid="1.2.3.4")
    f = sorted(sizes.iterdir())[3]
    ds = pydicom.dcmread(f)
    _image_pixels(ds, np.zeros((20, 24), np.uint16))
    ds.save_as(f, enforce_file_format=True)
    with pytest.raises(ValueError, match=rf"{f.name}'.*24 x 24 pixels.*found 20 x 24"):
        read_image(sizes)

    tilt = tmp_path / "tilt"
    write_series(tilt, ct_of(mask), AXIAL, ORIGIN)
    f = sorted(tilt.iterdir())[2]
    ds = pydicom.dcmread(f)
    ds.ImageOrientationPatient = [f"{v:.10f}" for v in np.r_[OBLIQUE[:, 0], OBLIQUE[:, 1]]]
    ds.save_as(f, enforce_file_format=True)
    with pytest.raises(ValueError, match=rf"{f.name}'.*one series, one orientation"):
        read_image(tilt)

    sheared = tmp_path / "sheared"  # gantry tilt: each slice shifted within its plane
    write_series(sheared, ct_of(mask), AXIAL, ORIGIN)
    for f in sheared.iterdir():
        ds = pydicom.dcmread(f)
        x, y, z = (float(v) for v in ds.ImagePositionPatient)
        ds.ImagePositionPatient = [f"{x:.4f}", f"{y + 0.3 * (z - ORIGIN[2]):.4f}", f"{z:.4f}"]
        ds.save_as(f, enforce_file_format=True)
    with pytest.raises(ValueError, match=r"sheared'.*stacked along their normal \(no gantry tilt.*offset"):
        read_image(sheared)
    dup = tmp_path / "dup"
    paths = write_series(dup, ct_of(mask), OBLIQUE, ORIGIN)
    a, b = pydicom.dcmread(paths[0]), pydicom.dcmread(paths[1])
    b.ImagePositionPatient = a.ImagePositionPatient
    b.save_as(paths[1], enforce_file_format=True)
    with pytest.raises(ValueError, match=r"one image per slice position.*img00[01].dcm and img00[01].dcm both at"):
        read_image(dup)

    fake = tmp_path / "fake.dcm"
    fake.write_bytes(b"hello, this is not DICOM" * 10)
    with pytest.raises(ValueError, match=r"fake.dcm'.*'DICM' marker"):
        read_image(fake)
    with pytest.raises(ValueError, match=r"fake.dcm'.*'DICM' marker"):
        contourmesh.mesh(str(fake))
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("no DICOM here")
    with pytest.raises(IsADirectoryError, match=r"empty' is a directory.*holds no DICOM file"):
        read_image(tmp_path / "empty")
    with pytest.raises(IsADirectoryError, match=r"empty' is a directory.*holds no DICOM file"):
        contourmesh.mesh(str(tmp_path / "empty"))
    rt_only = tmp_path / "rtonly"
    rt_only.mkdir()
    seg_in = write_seg(rt_only / "seg.dcm", {1: ("A", mask)}, AXIAL, ORIGIN)
    with pytest.raises(ValueError, match=r"rtonly'.*single-frame DICOM image slices.*found only seg.dcm \(SEG\)"
                       r".*pass a multi-frame or SEG file itself"):
        read_image(rt_only)
    assert read_image(seg_in).volume.any()

    good = write_seg(tmp_path / "seg.dcm", {1: ("A", mask)}, AXIAL, ORIGIN)
    data = good.read_bytes()
    for keep in (0.4, 0.98):
        cut = tmp_path / f"cut{keep}.dcm"
        cut.write_bytes(data[: int(len(data) * keep)])
        with pytest.raises(ValueError, match=rf"cut{keep}.dcm'.*(truncated|expected)"):
            read_image(cut)
    series_file = sorted((tmp_path / "sizes").iterdir())[0]
    cut = tmp_path / "cutct" / "one.dcm"
    cut.parent.mkdir()
    cut.write_bytes(series_file.read_bytes()[:-100])
    with pytest.raises(ValueError, match=r"one.dcm'.*truncated or corrupt"):
        read_image(cut)


def test_max_voxels_is_checked_before_the_pixels(tmp_path, monkeypatch):
    mask = ball_mask()
    folder = tmp_path / "s"
    write_series(folder, ct_of(mask), AXIAL, ORIGIN)
    seg = write_seg(tmp_path / "seg.dcm", {1: ("A", mask)}, AXIAL, ORIGIN)
    import contourmesh.io.dicom as dicom

    def no_pixels(*a, **k):
        raise AssertionError("pixel data read before the size check")

    monkeypatch.setattr(dicom, "_values", no_pixels)
    monkeypatch.setattr(dicom, "_pixels", no_pixels)
    with pytest.raises(ValueError, match=r"at most 1000 voxels.*12 x 24 x 24"):
        read_image(folder, max_voxels=1000)
    with pytest.raises(ValueError, match=r"seg.dcm'.*at most 1000 voxels"):
        read_image(seg, max_voxels=1000)


def test_dicom_tests_can_fail(tmp_path):
    """The world-position checks above see a wrong origin: a series shifted by a voxel is not the
    same mesh."""
    mask = ball_mask()
    write_series(tmp_path / "a", ct_of(mask), AXIAL, ORIGIN)
    write_series(tmp_path / "b", ct_of(mask), AXIAL, ORIGIN + [SPACING[2], 0, 0])
    ma = contourmesh.mesh(str(tmp_path / "a"), threshold=0)
    mb = contourmesh.mesh(str(tmp_path / "b"), threshold=0)
    assert np.allclose(mb.vertices - ma.vertices, [SPACING[2], 0, 0])
    assert not np.allclose(centroid(mb), world(AXIAL, ORIGIN, CENTRE_IJK), atol=0.25 * SPACING[2])



def test_multiframe_image_equals_the_series(tmp_path):
    """An enhanced (multi-frame) CT of the ball, frames in shuffled order with their positions in
    the per-frame functional groups, gives the series' mesh."""
    mask = ball_mask()
    write_series(tmp_path / "s", ct_of(mask), OBLIQUE, ORIGIN)
    sop = generate_uid()
    ds = Dataset()
    ds.file_meta = _file_meta("1.2.840.10008.5.1.4.1.1.2.1", sop)
    ds.SOPClassUID, ds.SOPInstanceUID = "1.2.840.10008.5.1.4.1.1.2.1", sop
    ds.Modality = "CT"
    ds.StudyInstanceUID, ds.SeriesInstanceUID = generate_uid(), generate_uid()
    shared = Dataset()
    po, pm, pv = Dataset(), Dataset(), Dataset()
    po.ImageOrientationPatient = [f"{v:.10f}" for v in np.r_[OBLIQUE[:, 0], OBLIQUE[:, 1]]]
    pm.PixelSpacing = [f"{SPACING[1]:g}", f"{SPACING[2]:g}"]
    pv.RescaleSlope, pv.RescaleIntercept, pv.RescaleType = "1", "-1024", "HU"
    shared.PlaneOrientationSequence, shared.PixelMeasuresSequence = Sequence([po]), Sequence([pm])
    shared.PixelValueTransformationSequence = Sequence([pv])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    order = np.random.default_rng(8).permutation(SHAPE[0])
    per = []
    for k in order:
        fg, pp = Dataset(), Dataset()
        pp.ImagePositionPatient = [f"{v:.10f}" for v in ORIGIN + k * SPACING[0] * OBLIQUE[:, 2]]
        fg.PlanePositionSequence = Sequence([pp])
        per.append(fg)
    ds.PerFrameFunctionalGroupsSequence = Sequence(per)
    ds.NumberOfFrames = SHAPE[0]
    _image_pixels(ds, ct_of(mask)[order])
    p = tmp_path / "enhanced.dcm"
    ds.save_as(p, enforce_file_format=True)
    img = read_image(p)
    np.testing.assert_array_equal(img.volume, ct_of(mask).astype(np.int32) - 1024)
    ms = contourmesh.mesh(str(tmp_path / "s"), threshold=0)
    mm = contourmesh.mesh(str(p), threshold=0)
    assert_good(mm)
    np.testing.assert_allclose(mm.vertices, ms.vertices, atol=1e-9)
    assert mm.meta["space"] == "LPS"
    # uneven frame positions are kept (Image.z) and meshed there
    positions = np.r_[0.0, np.cumsum([2.0, 2.0, 1.5, 2.5, 2.0, 3.0, 2.0, 2.0, 1.0, 2.0, 2.0])]
    for fg, k in zip(ds.PerFrameFunctionalGroupsSequence, order):
        fg.PlanePositionSequence[0].ImagePositionPatient = [f"{v:.10f}" for v in ORIGIN + positions[k] * OBLIQUE[:, 2]]
    ds.save_as(p, enforce_file_format=True)
    img = read_image(p, threshold=0)
    np.testing.assert_allclose(img.z, positions, atol=1e-6)
    mu = contourmesh.mesh(str(p), threshold=0, polygon="none")
    assert_good(mu)
    along = (mu.vertices - ORIGIN) @ OBLIQUE[:, 2]
    np.testing.assert_allclose(np.unique(np.round(along, 6)), positions[np.any(mask, axis=(1, 2))], atol=1e-6)


def test_one_lone_slice_and_the_cli_on_a_folder(tmp_path):
    mask = ball_mask()
    paths = write_series(tmp_path / "s", ct_of(mask), FLIPPED, ORIGIN)
    lone = tmp_path / "lone"
    lone.mkdir()
    one = paths[0].rename(lone / "only.dcm")  # a slice without its series: a volume of one slice
    img = read_image(one)
    assert img.volume.shape == (1, 24, 24) and img.spacing[0] == pytest.approx(SPACING[0])
    k = int(np.flatnonzero([np.array_equal(ct_of(mask)[i], img.volume[0] + 1024) for i in range(SHAPE[0])])[0])
    np.testing.assert_allclose(img.origin, world(FLIPPED, ORIGIN, (0, 0, k)), atol=1e-6)
    # the rest of the series, by the command line, on the folder (one slice missing: uneven steps)
    out = tmp_path / "ball.ply"
    r = subprocess.run([sys.executable, "-m", "contourmesh", "mesh", str(tmp_path / "s") + "/", "--threshold", "0",
                        "-o", str(out), "--json", "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert '"space": "LPS"' in r.stdout and out.stat().st_size > 0
    r = subprocess.run([sys.executable, "-m", "contourmesh", "mesh", str(tmp_path / "s"), "--label", "Liver",
                        "-o", str(out), "--force"], capture_output=True, text=True)
    assert r.returncode == 2 and "the label 'Liver' names a segment" in r.stderr and "give a number" in r.stderr
