"""DICOM volumes: segmentations (DICOM-SEG), image series (a folder of CT/MR slices) and
multi-frame images, read with pydicom into ``[z, y, x]`` with the geometry that places them in
the patient frame.

Geometry
--------
DICOM positions are in the patient frame LPS (x towards the patient's left, y towards the back,
z towards the head).  ``ImageOrientationPatient`` gives two unit vectors: the direction in which
a row's pixels advance (the column index, our x) and the direction in which the rows advance (the
row index, our y).  Their cross product is the slice normal.  Slices (files of a series, frames
of a multi-frame file) are sorted by their position along that normal, so the third column of
the direction matrix is the normal itself and the matrix is a rotation.  ``PixelSpacing`` is
``(between rows, between columns)`` = ``(dy, dx)``; the slice step comes from the positions.
The origin is ``ImagePositionPatient`` of the first sorted slice: the centre of its first pixel.

Slices that are not evenly spaced are kept at their positions: :class:`~contourmesh.io.Image`
then carries ``z``, the slices' offsets along the normal, which the volume mesher takes as its
slice heights.  In a DICOM-SEG, a segment's frames may be absent where it is empty (writers leave
them out); positions that are whole multiples of the slice step are filled with empty slices.

Header first
------------
Every file's header is read without its pixel data (``stop_before_pixels``) to route it, to check
the geometry and to check the declared size against ``max_voxels``; pixel data is decoded after.
pydicom never unpickles anything.  A file without the ``DICM`` marker, an unreadable or truncated
file, a missing attribute or a series that does not form one grid raises ``ValueError`` naming
the file and what is wrong.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .._files import _bad, _check_size, _reading, _require, _wrap
from ..errors import warn_external

__all__ = ["dicom_modality", "read_dicom", "DICOM_SPACE"]

log = logging.getLogger("contourmesh")

#: The world frame of every DICOM volume.
DICOM_SPACE = "LPS"

#: Modalities that are not images (a folder's series reader skips these files).
_NOT_IMAGES = {"RTSTRUCT", "RTPLAN", "RTRECORD", "SR", "KO", "PR", "REG", "SEG", "RWV", "DOC", "PLAN"}


def _has_marker(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            return fh.read(132)[128:132] == b"DICM"
    except OSError:
        return False


def _check_marker(path: Path) -> None:
    """ValueError naming the file when it lacks the DICOM preamble's marker (checked without pydicom)."""
    with open(path, "rb") as fh:
        head = fh.read(132)
    if head[128:132] != b"DICM":
        raise _bad(path, "a DICOM file (the 'DICM' marker at byte 128)",
                   f"a file of {path.stat().st_size} bytes without it" if len(head) >= 132 else
                   f"a file of {len(head)} bytes (too short for a DICOM preamble)")


def _header(pydicom, path: Path):
    """The file's attributes up to its pixel data; ValueError naming the file when it is not DICOM
    or cannot be read."""
    _check_marker(path)
    try:
        ds = pydicom.dcmread(str(path), stop_before_pixels=True)
        ds.walk(lambda _ds, _elem: None)  # values are parsed lazily: parse them all, so a corrupt header fails here
    except Exception as exc:  # InvalidDicomError, EOFError, struct.error, ...
        raise _wrap(path, "DICOM", exc) from None
    return ds


def dicom_modality(path) -> str | None:
    """The Modality of a DICOM file (``"RTSTRUCT"``, ``"SEG"``, ``"CT"``, ...), ``""`` when it has
    none, or None when the file is not readable DICOM (or pydicom is not installed)."""
    p = Path(path)
    if not p.is_file() or not _has_marker(p):
        return None
    try:
        import pydicom
    except ImportError:
        return None
    try:
        ds = pydicom.dcmread(str(p), stop_before_pixels=True, specific_tags=["Modality"])
        return str(ds.get("Modality", "") or "")
    except Exception:
        return None


def _floats(path: Path, ds, keyword: str, n: int, where: str = "") -> np.ndarray:
    value = ds.get(keyword) if ds is not None else None
    if value is None:
        raise _bad(path, f"a {keyword}{where}", "none")
    try:
        arr = np.asarray([float(v) for v in (value if n > 1 else [value])], dtype=np.float64)
    except (TypeError, ValueError):
        raise _bad(path, f"{n} numbers in {keyword}{where}", repr(value)) from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise _bad(path, f"{n} finite numbers in {keyword}{where}", repr(value))
    return arr


def _frame_of(path: Path, row: np.ndarray, col: np.ndarray, where: str = ""):
    """Unit row and column directions and the slice normal; ValueError when they are not orthonormal."""
    nr, nc = np.linalg.norm(row), np.linalg.norm(col)
    if not (abs(nr - 1) < 1e-3 and abs(nc - 1) < 1e-3 and abs(float(row @ col)) < 1e-3):
        raise _bad(path, f"an ImageOrientationPatient of two orthogonal unit vectors{where}",
                   f"{np.r_[row, col].tolist()}")
    row, col = row / nr, col / nc
    col = col - (col @ row) * row  # rounding in the file: make them exactly orthogonal
    col /= np.linalg.norm(col)
    return row, col, np.cross(row, col)


def _grid(path: Path, positions: np.ndarray, row, col, normal, pixel: float, *, names=None,
          fill: bool = False, step_hint: float | None = None):
    """Sort slice positions along the normal and lay them on a grid.

    Returns ``(order, slots, dz, z)``: ``order`` sorts the given positions, ``slots[i]`` is the
    grid slice of sorted position ``i`` (positions within a twentieth of a pixel share a slot),
    ``dz`` the slice step, and ``z`` the slots' offsets along the normal when they are not evenly
    spaced (None when they are).  ``fill`` allows gaps that are whole multiples of the smallest
    step (they become empty slices); otherwise every slot holds one position.  ``step_hint`` is
    the step of a single slice (its SpacingBetweenSlices or SliceThickness), used only then: a
    thickness is not a spacing, and a hint smaller than the steps would interleave empty slices.
    """
    names = names or [f"slice {i}" for i in range(len(positions))]
    d = positions @ normal
    order = np.argsort(d, kind="stable")
    d = d[order]
    rel = positions[order] - positions[order[0]]
    off = np.abs(np.c_[rel @ row, rel @ col]).max(axis=1)
    tol = 5e-2 * pixel  # positions are written in decimal text: allow their rounding
    if np.any(off > tol):
        i = int(np.argmax(off))
        raise _bad(path, "slices stacked along their normal (no gantry tilt or shear)",
                   f"{names[order[i]]} offset {off[i]:.4g} mm within its plane from {names[order[0]]}")
    same = np.diff(d) <= tol
    if same.any() and not fill:
        i = int(np.flatnonzero(same)[0])
        raise _bad(path, "one image per slice position",
                   f"{names[order[i]]} and {names[order[i + 1]]} both at {d[i]:.6g} mm along the normal")
    slots = np.concatenate([[0], np.cumsum(~same)])
    planes = np.array([d[slots == s].mean() for s in range(int(slots[-1]) + 1)])
    if len(planes) == 1:
        return order, slots, (step_hint or 1.0), None
    steps = np.diff(planes)
    span = planes[-1] - planes[0]
    if fill:
        base = float(steps.min())
        k = np.rint((planes - planes[0]) / base).astype(np.int64)
        dz = span / k[-1] if k[-1] > 0 else base
        if np.all(np.diff(k) > 0) and np.abs(planes - planes[0] - k * dz).max() <= 2e-2 * dz:
            if k[-1] + 1 > len(planes):
                log.debug("%s: %d slice positions on a grid of %d (missing ones are empty)", path, len(planes), k[-1] + 1)
            return order, k[slots], dz, None
        return order, slots, span / (len(planes) - 1), planes - planes[0]
    dz = span / (len(planes) - 1)
    if np.abs(planes - planes[0] - dz * np.arange(len(planes))).max() <= 2e-2 * dz:
        return order, slots, dz, None
    log.debug("%s: slices unevenly spaced (steps %.4g..%.4g mm); kept at their positions", path, steps.min(), steps.max())
    return order, slots, dz, planes - planes[0]


def _rescale(ds):
    slope, intercept = ds.get("RescaleSlope"), ds.get("RescaleIntercept")
    return (1.0 if slope is None else float(slope)), (0.0 if intercept is None else float(intercept))


def _values(slices: list, rescale: list) -> np.ndarray:
    """Stack decoded slices with their rescale applied: integers when the pixels are integers of at
    most 16 bits, every slope is 1 and every intercept whole; float64 otherwise."""
    whole = (all(a.dtype.kind in "biu" and a.dtype.itemsize <= 2 for a in slices)
             and all(s == 1.0 and float(i).is_integer() and abs(i) < 2**30 for s, i in rescale))
    dtype = np.int32 if whole else np.float64
    vol = np.empty((len(slices),) + slices[0].shape, dtype=dtype)
    for t, (arr, (s, i)) in enumerate(zip(slices, rescale)):
        vol[t] = arr if whole and s == 1.0 and i == 0.0 else arr.astype(np.float64) * s + i
    return vol


# ------------------------------------------------------------------------------------------------
# entry point
# ------------------------------------------------------------------------------------------------
def read_dicom(path, *, max_voxels: int, label=None, series=None):
    """A DICOM volume: a DICOM-SEG file, a multi-frame or single-frame image file, or a folder
    holding an image series.

    Returns ``(volume [z, y, x], spacing (dz, dy, dx), origin (x, y, z), direction, "LPS", label, z)``;
    ``label`` is the segment number when ``label`` named a segment; ``z`` the slice offsets along
    the normal when they are uneven (else None).  A single-frame image file whose folder holds
    other files of its series is read with them (the whole series).
    """
    p = Path(path)
    if not p.is_dir():
        _check_marker(p)  # a file that is not DICOM at all is named as such, with or without pydicom
    pydicom = _require("pydicom")
    if p.is_dir():
        return _read_series(pydicom, p, _series_files(pydicom, p), max_voxels=max_voxels, series=series, label=label)
    if series is not None:
        raise ValueError(f"series= picks a series in a folder of DICOM files; {str(p)!r} is a file")
    ds = _header(pydicom, p)
    modality = str(ds.get("Modality", "") or "")
    if modality == "RTSTRUCT":
        raise ValueError(f"{str(p)!r} is a DICOM RTSTRUCT (contours, not a volume): read it with read_contours, or "
                         "mesh it with contourmesh.mesh")
    if modality == "SEG":
        return _read_seg(pydicom, p, ds, max_voxels=max_voxels, label=label)
    if isinstance(label, str):
        raise ValueError(f"{str(p)!r}: the label {label!r} names a segment, but this is a {modality or 'DICOM'} image, "
                         "not a DICOM-SEG; give a number")
    if "Rows" not in ds or "Columns" not in ds:
        raise _bad(p, "a DICOM image or segmentation (Rows and Columns)", f"Modality {modality!r} without an image")
    frames = int(ds.get("NumberOfFrames", 1) or 1)
    if frames > 1 or "PerFrameFunctionalGroupsSequence" in ds:
        vol, spacing, origin, direction, z = _read_multiframe_image(pydicom, p, ds, max_voxels=max_voxels)
        return vol, spacing, origin, direction, DICOM_SPACE, label, z
    uid = ds.get("SeriesInstanceUID")
    if uid is not None:
        mates = [f for f in _series_files(pydicom, p.parent, quiet=True) if f[1].get("SeriesInstanceUID") == uid]
        if len(mates) > 1:
            log.debug("%s: read with the %d files of its series in %s", p, len(mates), p.parent)
            return _read_series(pydicom, p.parent, mates, max_voxels=max_voxels, series=None, label=label)
    return _read_series(pydicom, p.parent, [(p, ds)], max_voxels=max_voxels, series=None, label=label)


# ------------------------------------------------------------------------------------------------
# image series (a folder of single-frame slices)
# ------------------------------------------------------------------------------------------------
def _series_files(pydicom, folder: Path, quiet: bool = False) -> list:
    """``(path, header)`` of the single-frame image files in a folder.  Files without the DICM
    marker and DICOM objects that are not image slices (structure sets, segmentations, plans,
    multi-frame files) are skipped; a file with the marker that cannot be read raises."""
    out, skipped = [], []
    for f in sorted(folder.iterdir()):
        if not f.is_file() or f.name.startswith("."):
            continue
        if not _has_marker(f):
            skipped.append(f"{f.name} (not DICOM)")
            continue
        if quiet:
            try:
                ds = _header(pydicom, f)
            except ValueError:
                continue
        else:
            ds = _header(pydicom, f)
        modality = str(ds.get("Modality", "") or "")
        if (modality in _NOT_IMAGES or "Rows" not in ds or "ImagePositionPatient" not in ds
                or int(ds.get("NumberOfFrames", 1) or 1) > 1 or "DirectoryRecordSequence" in ds):
            skipped.append(f"{f.name} ({modality or 'no image'})")
            continue
        out.append((f, ds))
    if skipped:
        log.debug("%s: skipped %s", folder, ", ".join(skipped[:10]) + (" ..." if len(skipped) > 10 else ""))
    if not out and not quiet:
        found = f"only {', '.join(skipped[:5])}" + (" ..." if len(skipped) > 5 else "") if skipped else "no files"
        raise ValueError(f"{str(folder)!r}: expected a folder of single-frame DICOM image slices (one series); "
                         f"found {found}" + ("; pass a multi-frame or SEG file itself" if skipped else ""))
    return out


def _describe(uid, items) -> str:
    ds = items[0][1]
    what = " ".join(str(v) for v in (ds.get("Modality"), ds.get("SeriesNumber"), ds.get("SeriesDescription")) if v not in (None, ""))
    return f"{uid} ({what + ', ' if what else ''}{len(items)} files, e.g. {items[0][0].name})"


def _read_series(pydicom, folder: Path, files: list, *, max_voxels: int, series, label):
    if isinstance(label, str):
        raise ValueError(f"{str(folder)!r}: the label {label!r} names a segment, but this is an image series, not a "
                         "DICOM-SEG; give a number")
    groups: dict = {}
    for f, ds in files:
        groups.setdefault(str(ds.get("SeriesInstanceUID", "")), []).append((f, ds))
    if series is not None:
        pick = [u for u, items in groups.items() if series == u or str(series) == str(items[0][1].get("SeriesNumber", ""))]
        if len(pick) != 1:
            raise ValueError(f"{str(folder)!r}: {'no' if not pick else len(pick)} series match series={series!r}; "
                             f"series: {'; '.join(_describe(u, it) for u, it in groups.items())}")
        files = groups[pick[0]]
    elif len(groups) > 1:
        raise ValueError(f"{str(folder)!r} holds {len(groups)} DICOM series; expected one. Pass series= (a "
                         f"SeriesInstanceUID or SeriesNumber), one file of the series, or a folder of its own: "
                         f"{'; '.join(_describe(u, it) for u, it in groups.items())}")
    first, ds0 = files[0]
    rows, cols = int(ds0.Rows), int(ds0.Columns)
    iop0 = _floats(first, ds0, "ImageOrientationPatient", 6)
    ps0 = _floats(first, ds0, "PixelSpacing", 2)
    for f, ds in files:
        if int(ds.get("SamplesPerPixel", 1) or 1) != 1:
            raise _bad(f, "a greyscale image (SamplesPerPixel 1)", f"SamplesPerPixel {ds.SamplesPerPixel}")
        if (int(ds.Rows), int(ds.Columns)) != (rows, cols):
            raise _bad(f, f"{rows} x {cols} pixels like {first.name} (one series, one grid)",
                       f"{int(ds.Rows)} x {int(ds.Columns)}")
        iop = _floats(f, ds, "ImageOrientationPatient", 6)
        if np.abs(iop - iop0).max() > 1e-4:
            raise _bad(f, f"the ImageOrientationPatient of {first.name}, {iop0.tolist()} (one series, one orientation)",
                       iop.tolist())
        ps = _floats(f, ds, "PixelSpacing", 2)
        if np.abs(ps - ps0).max() > 1e-4 * ps0.max():
            raise _bad(f, f"the PixelSpacing of {first.name}, {ps0.tolist()}", ps.tolist())
    if np.any(ps0 <= 0):
        raise _bad(first, "a positive PixelSpacing", ps0.tolist())
    row, col, normal = _frame_of(first, iop0[:3], iop0[3:])
    positions = np.array([_floats(f, ds, "ImagePositionPatient", 3) for f, ds in files])
    names = [f.name for f, _ in files]
    hint = None
    if len(files) == 1:
        for key in ("SpacingBetweenSlices", "SliceThickness"):
            if ds0.get(key) not in (None, "") and float(ds0.get(key)) > 0:
                hint = float(ds0.get(key))
                break
    where = folder if len(files) > 1 else first  # errors about the whole series name its folder
    order, slots, dz, z = _grid(where, positions, row, col, normal, float(ps0.min()), names=names, step_hint=hint)
    _check_size(where, (len(files), rows, cols), 1, max_voxels)
    slices, rescale = [], []
    for i in order:
        ds, arr = _pixels(pydicom, files[i][0], 1, rows, cols)
        slices.append(arr[0])
        rescale.append(_rescale(ds))
    vol = _values(slices, rescale)
    direction = np.column_stack([row, col, normal])
    origin = tuple(positions[order[0]])
    return vol, (dz, float(ps0[0]), float(ps0[1])), origin, direction, DICOM_SPACE, label, z


# ------------------------------------------------------------------------------------------------
# multi-frame files: functional groups
# ------------------------------------------------------------------------------------------------
def _group(ds, per, i: int, seq: str):
    """The first item of functional-group sequence ``seq`` for frame ``i``: per-frame, else shared."""
    if per is not None and i < len(per):
        item = per[i].get(seq)
        if item:
            return item[0]
    shared = ds.get("SharedFunctionalGroupsSequence")
    if shared:
        item = shared[0].get(seq)
        if item:
            return item[0]
    return None


def _frame_geometry(path: Path, ds, frames: int):
    """Positions ``(frames, 3)``, row/column/normal directions and ``(dy, dx)`` of a multi-frame file."""
    per = ds.get("PerFrameFunctionalGroupsSequence")
    if per is None or len(per) != frames:
        raise _bad(path, f"a PerFrameFunctionalGroupsSequence of {frames} items (NumberOfFrames)",
                   "none" if per is None else f"{len(per)} items")
    iop0 = ps0 = None
    positions = np.empty((frames, 3))
    for i in range(frames):
        where = f" (frame {i + 1})"
        pos = _group(ds, per, i, "PlanePositionSequence")
        positions[i] = _floats(path, pos, "ImagePositionPatient", 3, where)
        iop = _floats(path, _group(ds, per, i, "PlaneOrientationSequence"), "ImageOrientationPatient", 6, where)
        ps = _floats(path, _group(ds, per, i, "PixelMeasuresSequence"), "PixelSpacing", 2, where)
        if iop0 is None:
            iop0, ps0 = iop, ps
        elif np.abs(iop - iop0).max() > 1e-4:
            raise _bad(path, f"one ImageOrientationPatient for every frame, {iop0.tolist()}", f"{iop.tolist()}{where}")
        elif np.abs(ps - ps0).max() > 1e-4 * ps0.max():
            raise _bad(path, f"one PixelSpacing for every frame, {ps0.tolist()}", f"{ps.tolist()}{where}")
    if np.any(ps0 <= 0):
        raise _bad(path, "a positive PixelSpacing", ps0.tolist())
    row, col, normal = _frame_of(path, iop0[:3], iop0[3:])
    measures = _group(ds, per, 0, "PixelMeasuresSequence")
    hint = None
    for key in ("SpacingBetweenSlices", "SliceThickness"):
        v = measures.get(key) if measures is not None else None
        if v not in (None, "") and float(v) > 0:
            hint = float(v)
            break
    return per, positions, row, col, normal, ps0, hint


def _pixels(pydicom, path: Path, frames: int, rows: int, cols: int):
    """``(dataset, pixels [frames, rows, cols])`` of one file (integer, float or double-float pixel
    data); ValueError naming the file when they are missing, unreadable or of another shape."""
    with _reading(path, "DICOM"):
        ds = pydicom.dcmread(str(path))
        if "PixelData" not in ds and "FloatPixelData" not in ds and "DoubleFloatPixelData" not in ds:
            raise _bad(path, "pixel data", "none (truncated file?)")
        arr = np.asarray(ds.pixel_array)
    if frames == 1 and arr.shape == (rows, cols):
        arr = arr[None]
    if arr.shape != (frames, rows, cols):
        what = f"one {rows} x {cols} frame of pixel data" if frames == 1 else f"{frames} frames of {rows} x {cols} pixels"
        raise _bad(path, what, f"pixel data of shape {arr.shape}")
    return ds, arr


def _read_multiframe_image(pydicom, path: Path, ds, *, max_voxels: int):
    """An enhanced (multi-frame) CT/MR/... image: one frame per slice position."""
    frames = int(ds.get("NumberOfFrames", 1) or 1)
    rows, cols = int(ds.Rows), int(ds.Columns)
    if int(ds.get("SamplesPerPixel", 1) or 1) != 1:
        raise _bad(path, "a greyscale image (SamplesPerPixel 1)", f"SamplesPerPixel {ds.SamplesPerPixel}")
    _check_size(path, (frames, rows, cols), 1, max_voxels)
    with _reading(path, "DICOM"):
        per, positions, row, col, normal, ps, hint = _frame_geometry(path, ds, frames)
    names = [f"frame {i + 1}" for i in range(frames)]
    order, slots, dz, z = _grid(path, positions, row, col, normal, float(ps.min()), names=names, step_hint=hint)
    full, arr = _pixels(pydicom, path, frames, rows, cols)
    rescale = []
    for i in order:
        t = _group(full, per, int(i), "PixelValueTransformationSequence")
        rescale.append(_rescale(t) if t is not None else _rescale(full))
    vol = _values([arr[i] for i in order], rescale)
    return vol, (dz, float(ps[0]), float(ps[1])), tuple(positions[order[0]]), np.column_stack([row, col, normal]), z


# ------------------------------------------------------------------------------------------------
# DICOM-SEG
# ------------------------------------------------------------------------------------------------
def _segments(path: Path, ds) -> dict:
    """``{segment number: label}`` of a DICOM-SEG."""
    out = {}
    for item in ds.get("SegmentSequence", []) or []:
        try:
            num = int(item.SegmentNumber)
        except (AttributeError, TypeError, ValueError):
            raise _bad(path, "a SegmentNumber in every SegmentSequence item", "an item without one") from None
        out[num] = str(item.get("SegmentLabel", "") or f"Segment {num}")
    if not out:
        raise _bad(path, "a DICOM-SEG with a SegmentSequence", "no segments")
    return out


def _pick_segment(path: Path, segments: dict, label) -> int:
    listing = ", ".join(f"{n}: {name!r}" for n, name in sorted(segments.items()))
    if isinstance(label, str):
        found = [n for n, name in segments.items() if name == label]
        if not found:
            found = [n for n, name in segments.items() if name.strip().lower() == label.strip().lower()]
        if len(found) != 1:
            what = "no segment" if not found else f"{len(found)} segments"
            raise ValueError(f"{str(path)!r}: {what} named {label!r}; segments: {listing}")
        return found[0]
    try:
        num = float(label)
    except (TypeError, ValueError):
        raise ValueError(f"label must be a segment number or name; got {label!r}") from None
    if not num.is_integer() or int(num) not in segments:
        raise ValueError(f"{str(path)!r}: no segment numbered {label!r}; segments: {listing}")
    return int(num)


def _read_seg(pydicom, path: Path, ds, *, max_voxels: int, label):
    """A DICOM-SEG as a label volume: each segment's voxels hold its SegmentNumber.  With ``label``
    (a number or a SegmentLabel), only that segment is read."""
    with _reading(path, "DICOM-SEG"):  # a value pydicom cannot parse: struct.error, OSError, ...
        segments = _segments(path, ds)
        frames = int(ds.get("NumberOfFrames", 1) or 1)
        rows, cols = int(ds.Rows), int(ds.Columns)
        kind = str(ds.get("SegmentationType", "BINARY") or "BINARY").upper()
        if kind not in ("BINARY", "FRACTIONAL"):
            raise _bad(path, "a SegmentationType BINARY or FRACTIONAL", repr(kind))
        top = float(ds.get("MaximumFractionalValue", 255) or 255) if kind == "FRACTIONAL" else 1.0
        _check_size(path, (frames, rows, cols), 1, max_voxels)
        per, positions, row, col, normal, ps, hint = _frame_geometry(path, ds, frames)
        seg_of = np.empty(frames, dtype=np.int64)
        for i in range(frames):
            ident = per[i].get("SegmentIdentificationSequence")
            if not ident or "ReferencedSegmentNumber" not in ident[0]:
                raise _bad(path, f"a SegmentIdentificationSequence for frame {i + 1}", "none")
            seg_of[i] = int(ident[0].ReferencedSegmentNumber)
            if seg_of[i] not in segments:
                raise _bad(path, f"frames of the segments {sorted(segments)}", f"frame {i + 1} of segment {seg_of[i]}")
    wanted = None if label is None else _pick_segment(path, segments, label)
    names = [f"frame {i + 1} (segment {seg_of[i]})" for i in range(frames)]
    order, slots, dz, z = _grid(path, positions, row, col, normal, float(ps.min()), names=names, fill=True, step_hint=hint)
    nz = int(slots.max()) + 1
    _check_size(path, (nz, rows, cols), 1, max_voxels)
    slot_of = np.empty(frames, dtype=np.int64)
    slot_of[order] = slots
    for s in np.unique(slot_of):  # one frame per segment and position
        segs = seg_of[slot_of == s]
        vals, counts = np.unique(segs, return_counts=True)
        if np.any(counts > 1):
            dup = int(vals[counts > 1][0])
            raise _bad(path, "one frame per segment and slice position", f"several frames of segment {dup} at one position")
    _, arr = _pixels(pydicom, path, frames, rows, cols)
    top_number = max(segments)
    vol = np.zeros((nz, rows, cols), dtype=np.uint8 if top_number < 256 else np.uint16)
    overlap = 0
    for num in sorted(segments):  # the higher number wins where segments overlap
        if wanted is not None and num != wanted:
            continue
        for i in np.flatnonzero(seg_of == num):
            on = arr[i] > 0 if kind == "BINARY" else arr[i].astype(np.float64) * 2 >= top
            on &= arr[i] > 0
            sl = vol[slot_of[i]]
            overlap += int(np.count_nonzero(sl[on]))
            sl[on] = num
    if overlap:
        warn_external(f"{str(path)!r}: segments overlap in {overlap} voxels; the label volume holds the higher "
                      "segment number there (pick one segment with label= for its whole extent)")
    origin = tuple(positions[order[0]])
    return (vol, (dz, float(ps[0]), float(ps[1])), origin, np.column_stack([row, col, normal]), DICOM_SPACE,
            wanted if wanted is not None else label, z)
