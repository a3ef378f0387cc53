"""The bad-input catalogue: each kind raises a specific exception saying what was expected and found.

``CASES`` maps a name to ``(make, exception, pattern)``: ``make(tmp_path)`` performs the bad call.
``python tests/test_bad_inputs.py`` prints the table of every case with the message it gets.
"""

import io
import sys
from pathlib import Path

import numpy as np
import pytest

import contourmesh
from contourmesh.io import read_contours, read_volume, stack_from_rings
from contourmesh.types import ContourStack, Section
from contourmesh.volumes import volume_to_mesh

SQ = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1]], dtype=np.int64)


def _stack(*contours, z=None):
    z = list(range(len(contours))) if z is None else z
    return ContourStack(tuple(Section(float(zk), (c,)) for zk, c in zip(z, contours)))


def _blob():
    v = np.zeros((4, 5, 6), np.uint8)
    v[1:3, 1:4, 1:5] = 1
    return v


def _write(tmp_path, name, data: bytes):
    p = tmp_path / name
    p.write_bytes(data)
    return p


def _truncated(tmp_path, suffix):
    p = tmp_path / f"full{suffix}"
    contourmesh.io.write_volume(p, _blob())
    data = p.read_bytes()
    return contourmesh.mesh(_write(tmp_path, f"cut{suffix}", data[: max(8, len(data) * 6 // 10)]))


def _pickled_npy(tmp_path):
    p = tmp_path / "evil.npy"
    marker = tmp_path / "was-unpickled"

    class Evil:
        def __reduce__(self):
            return (Path.touch, (marker,))

    np.save(p, np.array([Evil()], dtype=object), allow_pickle=True)
    try:
        read_volume(p)
    finally:
        assert not marker.exists(), "the .npy was unpickled"


def _huge_vol_header(tmp_path):
    head = b"Center-X: 0\nCenter-Y: 0\nCenter-Z: 0\nX: 100000\nY: 100000\nZ: 100000\nVoxel-Size: 1\nVersion: 2\n.\n"
    return read_volume(_write(tmp_path, "huge.vol", head + b"\0" * 64))


def _huge_npy_header(tmp_path):
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "|u1", "fortran_order": False, "shape": (100000, 100000, 100000)})
    return read_volume(_write(tmp_path, "huge.npy", buf.getvalue() + b"\0" * 64))


def _huge_npz_member(tmp_path):
    import zipfile

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "|u1", "fortran_order": False, "shape": (100000, 100000, 100000)})
    p = tmp_path / "huge.npz"
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("volume.npy", buf.getvalue() + b"\0" * (1 << 20))  # a megabyte that deflates to a kilobyte
    return read_volume(p)


def _pickled_npz(tmp_path):
    import zipfile

    p = tmp_path / "evil.npz"
    marker = tmp_path / "was-unpickled"

    class Evil:
        def __reduce__(self):
            return (Path.touch, (marker,))

    np.savez(p, volume=np.array([Evil()], dtype=object))
    try:
        read_volume(p)
    finally:
        assert not marker.exists(), "the .npz was unpickled"
        assert zipfile.is_zipfile(p)


def _huge_optimal_band():
    from contourmesh.bands import triangulate_band

    t = np.linspace(0, 2 * np.pi, 5000, endpoint=False)
    lo = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)] * 100
    return triangulate_band(lo, lo + [0, 0, 1], "optimal")


KEYHOLE = np.array([[0, 5], [0, 0], [10, 0], [10, 10], [0, 10], [0, 5], [3, 5], [3, 7], [7, 7], [7, 3], [3, 3], [3, 5]],
                   float) + 0.25


def _keyhole_on_the_stack_route():
    from contourmesh.surface import stack_to_mesh

    return stack_to_mesh(_stack(KEYHOLE, KEYHOLE, KEYHOLE), polygon="none")


def _figure_eight_cap():
    from contourmesh.bands.caps import cap_faces

    return cap_faces(np.array([[0.0, 0.0], [2.0, 2.0], [4.0, 0.0], [4.0, 4.0], [2.0, 2.0], [0.0, 4.0]]), [])


def _corrupt_tiff(tmp_path):
    return read_volume(_write(tmp_path, "bad.tif", b"II*\0" + b"\xff" * 60))


def _corrupt_nifti(tmp_path):
    return read_volume(_write(tmp_path, "bad.nii", b"\x5c\x01\0\0" + b"\x07" * 400))


def _corrupt_dicom(tmp_path):
    return read_contours(_write(tmp_path, "bad.dcm", b"\0" * 128 + b"DICM" + b"\x08\x00\x05\x00CS\xff\xff" + b"x" * 10))


def _rtstruct_off_plane(tmp_path):
    pytest.importorskip("pydicom")
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.sequence import Sequence
    from pydicom.uid import ExplicitVRLittleEndian

    ds = Dataset()
    ds.file_meta = FileMetaDataset()
    ds.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds.file_meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.481.3"
    ds.file_meta.MediaStorageSOPInstanceUID = "1.2.3"
    ds.Modality = "RTSTRUCT"
    roi = Dataset()
    roi.ROINumber = 1
    roi.ROIName = "X"
    ds.StructureSetROISequence = Sequence([roi])
    c = Dataset()
    c.ContourGeometricType = "CLOSED_PLANAR"
    c.NumberOfContourPoints = 3
    c.ContourData = [0, 0, 0, 5, 0, 0, 5, 5, 2.5]  # third point leaves the plane z = 0
    rc = Dataset()
    rc.ReferencedROINumber = 1
    rc.ContourSequence = Sequence([c])
    ds.ROIContourSequence = Sequence([rc])
    p = tmp_path / "offplane.dcm"
    ds.save_as(p, enforce_file_format=True) if "enforce_file_format" in ds.save_as.__code__.co_varnames else ds.save_as(p, write_like_original=False)
    return read_contours(p)


CASES = {
    # --- arrays -----------------------------------------------------------------------------
    "float volume with NaN": (lambda t: volume_to_mesh(np.full((2, 2, 2), np.nan)), ValueError, "NaN"),
    "float volume with inf": (lambda t: volume_to_mesh(np.full((2, 2, 2), np.inf)), ValueError, "inf"),
    "complex volume": (lambda t: volume_to_mesh(np.ones((2, 2, 2), complex)), ValueError, "complex"),
    "object volume": (lambda t: volume_to_mesh(np.array([[[1]]], dtype=object)), ValueError, "object"),
    "string volume": (lambda t: volume_to_mesh(np.full((2, 2, 2), "a")), ValueError, "numeric or boolean"),
    "1D array": (lambda t: contourmesh.mesh(np.ones(5, bool)), ValueError, "3D.*1D"),
    "2D array": (lambda t: contourmesh.mesh(np.ones((3, 3), bool)), ValueError, "3D.*2D"),
    "4D array": (lambda t: contourmesh.mesh(np.ones((2, 2, 2, 2), bool)), ValueError, "3D.*4D"),
    "empty volume (zero-size)": (lambda t: contourmesh.mesh(np.zeros((0, 3, 3), bool)), ValueError, "empty"),
    "volume without foreground": (lambda t: contourmesh.mesh(np.zeros((3, 3, 3), bool)), ValueError, "no foreground"),
    "all-foreground label volume, label absent": (lambda t: read_volume(np.ones((2, 2, 2), np.uint8), label=7),
                                                  ValueError, "no voxel has label 7"),
    "labels without label=/threshold=": (lambda t: contourmesh.mesh(np.arange(8).reshape(2, 2, 2)), ValueError,
                                         "label= .* threshold="),
    "zero spacing": (lambda t: contourmesh.mesh(_blob(), spacing=(1, 0, 1)), ValueError, "spacing.*positive"),
    "negative spacing": (lambda t: contourmesh.mesh(_blob(), spacing=(1, -1, 1)), ValueError, "spacing.*positive"),
    "non-increasing slice positions": (lambda t: contourmesh.mesh(_blob(), z=[0, 1, 1, 2]), ValueError,
                                       r"strictly increasing; z\[1\]=1.0 >= z\[2\]=1.0"),
    "wrong number of slice positions": (lambda t: contourmesh.mesh(_blob(), z=[0, 1]), ValueError, "one position per slice"),
    # --- contour stacks ------------------------------------------------------------------------
    "non-increasing section heights": (lambda t: contourmesh.mesh(_stack(SQ, SQ, z=[1, 0])), ValueError,
                                       r"strictly increasing; found z\[0\]=1.0 >= z\[1\]=0.0"),
    "NaN section height": (lambda t: contourmesh.mesh(_stack(SQ, SQ, z=[np.nan, 1])), ValueError, "finite.*nan"),
    "duplicate consecutive points": (lambda t: contourmesh.mesh(_stack(np.repeat(SQ, 2, axis=0), SQ)), ValueError,
                                     "not a unit 4-step from point 0"),
    "repeated closing point": (lambda t: contourmesh.mesh(_stack(np.vstack([SQ, SQ[:1]]), SQ)), ValueError,
                               "repeated closing point"),
    "self-intersecting integer contour (bow tie)": (
        lambda t: contourmesh.mesh(_stack(np.array([[0, 0], [2, 2], [2, 0], [0, 2]]), SQ)), ValueError,
        "closed digital 4-curve"),
    "open contour (gap in a 4-curve)": (lambda t: contourmesh.mesh(_stack(SQ[:-2], SQ)), ValueError,
                                        "not a unit 4-step"),
    "1-point contour between sections": (lambda t: contourmesh.mesh(_stack(SQ, np.array([[1, 1]]), SQ)), ValueError,
                                         "encloses no area.*first or last section"),
    "2-point contour between sections": (lambda t: contourmesh.mesh(_stack(SQ, np.array([[1, 1], [2, 1]]), SQ)),
                                         ValueError, "encloses no area.*first or last section"),
    "contour with 3 columns": (lambda t: contourmesh.mesh(_stack(np.c_[SQ, SQ[:, :1]], SQ)), ValueError,
                               r"\(k, 2\).*\(8, 3\)"),
    "contour with NaN coordinates": (lambda t: contourmesh.mesh(_stack(SQ * np.nan, SQ.astype(float))), ValueError,
                                     "NaN or infinite"),
    "empty contour stack": (lambda t: contourmesh.mesh(ContourStack(())), ValueError, "empty"),
    "rings that are all 1- or 2-point": (lambda t: stack_from_rings([(0.0, [[[0, 0]], [[0, 0], [1, 1]]])]),
                                         ValueError, "no contour with 3 or more distinct points"),
    "contour outside the declared plane (RTSTRUCT)": (_rtstruct_off_plane, ValueError, "planar"),
    "keyhole ring meshed as given (stack route)": (lambda t: _keyhole_on_the_stack_route(), ValueError,
                                                   "do not bound a closed surface.*keyhole"),
    "cap of a ring that touches itself (figure eight)": (lambda t: _figure_eight_cap(), ValueError,
                                                         "rings cross or touch"),
    # --- files ---------------------------------------------------------------------------------
    "pickled objects in .npy (never unpickled)": (_pickled_npy, ValueError, "refusing to unpickle"),
    "truncated .npy": (lambda t: _truncated(t, ".npy"), ValueError, "expected"),
    "truncated .npz": (lambda t: _truncated(t, ".npz"), ValueError, "expected"),
    "truncated TIFF": (lambda t: _truncated(t, ".tif"), ValueError, "expected"),
    "truncated NIfTI": (lambda t: _truncated(t, ".nii"), ValueError, "expected"),
    "truncated .vol": (lambda t: _truncated(t, ".vol"), ValueError, "expected"),
    "corrupt TIFF": (_corrupt_tiff, ValueError, "expected"),
    "corrupt NIfTI": (_corrupt_nifti, ValueError, "expected"),
    "corrupt DICOM": (_corrupt_dicom, ValueError, "expected"),
    "not an .npy at all": (lambda t: read_volume(_write(t, "x.npy", b"hello world")), ValueError, "NUMPY"),
    ".vol header declaring an enormous size": (_huge_vol_header, ValueError, "at most .* voxels"),
    ".npy header declaring an enormous size": (_huge_npy_header, ValueError, "at most .* voxels"),
    ".npz member declaring an enormous size": (_huge_npz_member, ValueError, "at most .* voxels"),
    "pickled objects in .npz (never unpickled)": (_pickled_npz, ValueError, "refusing to unpickle"),
    "optimal band too large for memory (ruled surface of 5000 x 5000 points)": (
        lambda t: _huge_optimal_band(), ValueError, "optimal band between polygons of 5000 and 5000 vertices.*limits"),
    "a directory instead of a file": (lambda t: contourmesh.mesh(Path(t)), IsADirectoryError, "is a directory"),
    "a missing file": (lambda t: contourmesh.mesh(Path(t) / "nope.npy"), FileNotFoundError, "does not exist"),
    "unknown file suffix": (lambda t: read_volume(_write(t, "x.xyz", b"0")), ValueError, "suffix"),
    # --- outputs -------------------------------------------------------------------------------
    "output path is a directory": (lambda t: contourmesh.mesh(_blob()).save(Path(t)), IsADirectoryError,
                                   "is a directory"),
    "output folder missing": (lambda t: contourmesh.mesh(_blob()).save(Path(t) / "no" / "m.ply"), FileNotFoundError,
                              "does not exist"),
    "output folder not writable": (lambda t: _unwritable(t), PermissionError, "not writable"),
    "output exists without force": (lambda t: _exists(t), FileExistsError, "already exists.*force"),
    "unknown output suffix": (lambda t: contourmesh.mesh(_blob()).save(Path(t) / "m.xyz"), ValueError,
                              "expected a suffix among"),
}


def _unwritable(tmp_path):
    import os

    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        if os.access(d, os.W_OK):  # root ignores permissions
            pytest.skip("running as root: permissions are not enforced")
        contourmesh.mesh(_blob()).save(d / "m.ply")
    finally:
        d.chmod(0o700)


def _exists(tmp_path):
    p = tmp_path / "m.ply"
    p.write_bytes(b"old")
    try:
        contourmesh.mesh(_blob()).save(p, force=False)
    finally:
        assert p.read_bytes() == b"old"


#: Cases whose input also gives our warning on the way to the error (asserted with pytest.warns).
WARNS = {"rings that are all 1- or 2-point": (UserWarning, "dropped 2 contour")}
#: Cases where a third-party reader may warn about the garbage it is given (version-dependent): filtered.
OTHERS_WARN = {"corrupt DICOM"}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_is_named(name, tmp_path):
    import warnings

    make, exc, pattern = CASES[name]
    for reader, module in (("NIfTI", "nibabel"), ("DICOM", "pydicom"), ("TIFF", "tifffile")):
        if reader in name:  # the reader is an optional extra ([io]); without it the case cannot be made
            pytest.importorskip(module)
    with pytest.raises(exc, match=pattern) as info:
        if name in WARNS:
            with pytest.warns(WARNS[name][0], match=WARNS[name][1]):
                make(tmp_path)
        elif name in OTHERS_WARN:
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", category=UserWarning, module="pydicom")
                make(tmp_path)
        else:
            make(tmp_path)
    msg = str(info.value)
    assert len(msg) > 15 and "\n" not in msg.strip(), msg


def test_catalogue_has_at_least_25_kinds():
    assert len(CASES) >= 25


if __name__ == "__main__":  # print the table: input | exception | message
    import tempfile

    for name, (make, exc, _) in CASES.items():
        with tempfile.TemporaryDirectory() as d:
            try:
                make(Path(d))
                print(f"| {name} | (no error) | |")
            except BaseException as e:  # noqa: BLE001
                print(f"| {name} | {type(e).__name__} | {str(e).replace('|', '/')} |")
    sys.exit(0)
