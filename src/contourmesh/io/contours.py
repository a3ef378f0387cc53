"""Contour-stack readers and writers: DICOM RTSTRUCT, the JSON contour format, contour ``.npz``.

Stacks are returned with float64 rings in physical millimetres, ``spacing = (1, 1)`` and
``origin = (0, 0)``; outer rings have positive shoelace area and holes negative (holes are
decided by nesting, even-odd: see :func:`contourmesh.stacks.stack_from_rings` and
``docs/contour-json.md``).  pydicom is imported when needed.
"""

from __future__ import annotations

import json
import math
import os
import zlib
from pathlib import Path

import numpy as np

from .._files import VOLUME_SUFFIXES, _bad, _reading, _require, _suffix, _wrap, check_file
from ..errors import warn_external
from ..meshes import atomic_write
from ..stacks import Z_TOLERANCE, stack_from_rings
from ..types import ContourStack
from .dicom import dicom_modality

__all__ = ["read_contours", "list_rois", "write_contours_json", "contours_json_bytes", "is_contour_file", "CONTOUR_SUFFIXES",
           "CONTOURS_FORMAT", "CONTOURS_VERSION"]


CONTOUR_SUFFIXES = (".dcm", ".json", ".npz")


CONTOURS_FORMAT = "contourmesh.contours"


CONTOURS_VERSION = 1


def read_contours(path, *, roi=None) -> ContourStack:
    """Read a contour stack: DICOM RTSTRUCT, the JSON contour format, or an ``rtss_contours.npz``.

    Parameters
    ----------
    path : str or Path
        ``.dcm`` (DICOM RTSTRUCT, needs pydicom), ``.json`` (``docs/contour-json.md``), or
        ``.npz`` holding ``<ROI>__points_mm`` (N x 3) and ``<ROI>__offsets`` arrays per ROI.
    roi : str or int, optional
        The ROI to read (RTSTRUCT and npz): its name (exact, else case-insensitive) or its ROI
        number.  Needed when the file holds more than one non-empty ROI.

    Returns
    -------
    ContourStack
        float64 rings in millimetres (``spacing = (1, 1)``); sections grouped by z within
        ``Z_TOLERANCE`` (1e-3 mm) and sorted; holes by even-odd nesting, outer rings with positive
        shoelace area, holes negative.  ``meta`` holds ``source``, ``roi`` and ``units``.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, ValueError
        Bad path, bad file, unknown/ambiguous ROI (the message lists the ROIs), a contour whose
        points are not all at one z, non-finite coordinates.
    """
    p = check_file(path, "contour")
    suffix = _suffix(p)
    if suffix not in CONTOUR_SUFFIXES:
        with open(p, "rb") as fh:
            pre = fh.read(132)
        if pre[128:132] == b"DICM":
            suffix = ".dcm"
        else:
            raise ValueError(f"{str(p)!r}: cannot tell the contour format; expected a suffix among "
                             f"{', '.join(CONTOUR_SUFFIXES)}, found {p.suffix or 'none'!r}")
    if suffix == ".json":
        if roi is not None:
            raise ValueError("roi= applies to RTSTRUCT and npz contour files, not to the JSON contour format")
        return _read_contours_json(p)
    if suffix == ".npz":
        return _read_contours_npz(p, roi)
    return _read_rtstruct(p, roi)


class _Listing(Exception):
    """Carries the ROI table out of a reader when :func:`list_rois` asks for it."""

    def __init__(self, rois):
        self.rois = rois


_LIST = object()


def list_rois(path) -> list:
    """The structures of a contour file: ``[(number, name, number of contours), ...]``.

    A JSON contour stack holds one structure (its ``name``, or the file name)."""
    p = check_file(path, "contour")
    if _suffix(p) == ".json":
        st = _read_contours_json(p)
        return [(1, str(st.meta.get("roi") or st.meta.get("name") or p.stem), sum(len(s.contours) for s in st.sections))]
    try:
        read_contours(p, roi=_LIST)
    except _Listing as listing:
        return listing.rois
    raise AssertionError("unreachable: the reader lists its ROIs")


def _select_roi(path: Path, rois: list[tuple[int, str, int]], roi):
    """Pick one of ``(number, name, n_contours)``; errors list what is available."""
    if roi is _LIST:
        raise _Listing(rois)
    listing = ", ".join(f"{num}: {name!r} ({n} contours)" for num, name, n in rois)
    if roi is None:
        nonempty = [r for r in rois if r[2] > 0]
        if len(nonempty) == 1:
            return nonempty[0]
        raise ValueError(f"{str(path)!r} holds {len(nonempty)} non-empty ROIs; pass roi= (a name or number) "
                         f"to pick one of: {listing}")
    if isinstance(roi, (int, np.integer)) and not isinstance(roi, bool):
        found = [r for r in rois if r[0] == int(roi)]
    elif isinstance(roi, str):
        found = [r for r in rois if r[1] == roi]
        if not found:
            norm = lambda s: s.strip().lower().replace("_", " ")
            found = [r for r in rois if norm(r[1]) == norm(roi)]
    else:
        raise ValueError(f"roi must be a name (str) or an ROI number (int); got {type(roi).__name__}")
    if len(found) != 1:
        what = "no ROI" if not found else f"{len(found)} ROIs"
        raise ValueError(f"{str(path)!r}: {what} matches roi={roi!r}; available ROIs: {listing}")
    if found[0][2] == 0:
        raise ValueError(f"{str(path)!r}: ROI {found[0][1]!r} holds no contours; available ROIs: {listing}")
    return found[0]


def _planar_slices(path: Path, name: str, contours3d):
    """Group (k, 3) contours by their single z; a contour spanning several z raises."""
    out = []
    for i, c in enumerate(contours3d):
        if len(c) == 0:
            continue
        if not np.all(np.isfinite(c)):
            raise ValueError(f"{str(path)!r}: ROI {name!r} contour {i} holds NaN or infinite coordinates")
        zr = float(c[:, 2].max() - c[:, 2].min())
        if zr > Z_TOLERANCE:
            raise ValueError(f"{str(path)!r}: ROI {name!r} contour {i}: expected a planar contour at one z; "
                             f"its points span z = {c[:, 2].min():g} .. {c[:, 2].max():g}")
        out.append((float(c[:, 2].mean()), [c[:, :2]]))
    return out


def _contour_data(item) -> np.ndarray:
    """An item's ContourData as float64: parsed from the raw bytes where pydicom has not decoded them yet
    (its per-value DS checks cost seconds on a body contour); otherwise through pydicom."""
    raw = item.get_item("ContourData")
    value = getattr(raw, "value", None)
    if isinstance(value, bytes):
        text = value.rstrip(b"\x00 ")
        if not text:
            return np.zeros(0, dtype=np.float64)
        try:
            return np.array(text.split(b"\\")).astype(np.float64)
        except ValueError:
            pass  # not plain decimal strings: pydicom says what is wrong below
    return np.asarray([float(v) for v in item.ContourData], dtype=np.float64)


#: The last RTSTRUCT parsed: ``((path, mtime_ns, size), dataset)``.  Meshing every ROI of a file reads
#: it once per ROI; parsing a large structure set takes about a second.
_LAST_RTSTRUCT: list = []


def _dcmread_once(pydicom, path: Path):
    """``pydicom.dcmread(path)``, reused while the file's path, modification time and size stay the same."""
    st = os.stat(path)
    key = (str(Path(path).resolve()), st.st_mtime_ns, st.st_size)
    if _LAST_RTSTRUCT and _LAST_RTSTRUCT[0][0] == key:
        return _LAST_RTSTRUCT[0][1]
    ds = pydicom.dcmread(str(path))
    _LAST_RTSTRUCT[:] = [(key, ds)]
    return ds


def _read_rtstruct(path: Path, roi) -> ContourStack:
    pydicom = _require("pydicom")
    try:
        ds = _dcmread_once(pydicom, path)
        modality = getattr(ds, "Modality", None)
        if modality != "RTSTRUCT":
            raise _bad(path, "a DICOM RTSTRUCT (Modality 'RTSTRUCT')", f"Modality {modality!r}")
        names = {int(r.ROINumber): str(r.ROIName) for r in getattr(ds, "StructureSetROISequence", [])}
        by_number = {}
        for rc in getattr(ds, "ROIContourSequence", []):
            by_number[int(rc.ReferencedROINumber)] = list(getattr(rc, "ContourSequence", []) or [])
        rois = [(num, names.get(num, f"ROI {num}"), len(by_number.get(num, []))) for num in sorted(set(names) | set(by_number))]
        if not rois:
            raise _bad(path, "an RTSTRUCT with ROIs", "no StructureSetROISequence / ROIContourSequence")
        num, name, _ = _select_roi(path, rois, roi)
        contours3d, skipped = [], {}
        for i, item in enumerate(by_number[num]):
            kind = str(getattr(item, "ContourGeometricType", "CLOSED_PLANAR"))
            data = _contour_data(item)
            if data.size % 3:
                raise _bad(path, f"ROI {name!r} contour {i}: ContourData as x, y, z triplets", f"{data.size} numbers")
            npts = getattr(item, "NumberOfContourPoints", None)
            if npts is not None and int(npts) != data.size // 3:
                raise _bad(path, f"ROI {name!r} contour {i}: NumberOfContourPoints = {int(npts)} points",
                           f"{data.size // 3} points in ContourData (truncated or corrupt file)")
            if kind != "CLOSED_PLANAR":
                skipped[kind] = skipped.get(kind, 0) + 1
                continue
            contours3d.append(data.reshape(-1, 3))
    except (ValueError, ImportError) as exc:
        if isinstance(exc, ImportError) or str(path) in str(exc):
            raise
        raise _wrap(path, "DICOM RTSTRUCT", exc) from None
    except _Listing:
        raise
    except Exception as exc:  # pydicom's InvalidDicomError, EOFError, struct.error, ...
        raise _wrap(path, "DICOM RTSTRUCT", exc) from None
    if skipped:
        warn_external(f"{str(path)!r}: ROI {name!r}: skipped contours that are not CLOSED_PLANAR: {skipped}")
    slices = _planar_slices(path, name, contours3d)
    return stack_from_rings(slices, source=f"{path.name} ROI {name!r}",
                            meta={"source": str(path), "roi": name, "roi_number": num, "units": "mm"})


def _read_contours_npz(path: Path, roi) -> ContourStack:
    import zipfile

    with _reading(path, "contour .npz", (zipfile.BadZipFile, EOFError, OSError, KeyError, zlib.error)):
        with np.load(path, allow_pickle=False) as npz:
            files = set(npz.files)
            keys = sorted(k[: -len("__points_mm")] for k in files if k.endswith("__points_mm"))
            if not keys:
                raise _bad(path, "arrays '<ROI>__points_mm' and '<ROI>__offsets'", f"arrays {sorted(files)[:8]}")
            rois = []
            for i, k in enumerate(keys):
                off = npz[k + "__offsets"] if k + "__offsets" in files else np.zeros(1)
                rois.append((i + 1, k, max(len(off) - 1, 0)))
            num, key, _ = _select_roi(path, rois, roi)
            pts = np.asarray(npz[key + "__points_mm"], dtype=np.float64)
            off = np.asarray(npz[key + "__offsets"], dtype=np.int64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise _bad(path, f"{key}__points_mm of shape (N, 3)", f"shape {pts.shape}")
    if off.ndim != 1 or len(off) < 1 or off[0] != 0 or off[-1] != len(pts) or np.any(np.diff(off) < 0):
        raise _bad(path, f"{key}__offsets increasing from 0 to {len(pts)}", f"{off[:3]}...{off[-3:]}")
    contours3d = [pts[off[i]: off[i + 1]] for i in range(len(off) - 1)]
    slices = _planar_slices(path, key, contours3d)
    return stack_from_rings(slices, source=f"{path.name} ROI {key!r}",
                            meta={"source": str(path), "roi": key, "units": "mm"})


def _read_contours_json(path: Path) -> ContourStack:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise _bad(path, "a UTF-8 JSON text", f"undecodable bytes ({exc.reason})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _bad(path, "a JSON document", f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    return _stack_from_json_doc(doc, str(path))


def _stack_from_json_doc(doc, where: str) -> ContourStack:
    def bad(expected, found):
        return ValueError(f"{where!r}: expected {expected}; found {found}")

    if not isinstance(doc, dict):
        raise bad("a JSON object with 'format', 'version', 'units' and 'slices'", type(doc).__name__)
    if doc.get("format") != CONTOURS_FORMAT:
        raise bad(f"'format': {CONTOURS_FORMAT!r}", repr(doc.get("format")))
    if doc.get("version") != CONTOURS_VERSION:
        raise bad(f"'version': {CONTOURS_VERSION} (this reader)", repr(doc.get("version")))
    units = doc.get("units", "mm")
    if not isinstance(units, str) or not units:
        raise bad("'units' as a non-empty string such as 'mm'", repr(units))
    slices = doc.get("slices")
    if not isinstance(slices, list):
        raise bad("'slices' as a list", type(slices).__name__)
    pairs = []
    for s, sl in enumerate(slices):
        if not isinstance(sl, dict) or "z" not in sl or "rings" not in sl:
            raise bad(f"slice {s} as an object with 'z' and 'rings'", repr(sl)[:80])
        z = sl["z"]
        if isinstance(z, bool) or not isinstance(z, (int, float)):
            raise bad(f"slice {s}: 'z' as a number", repr(z))
        if not isinstance(sl["rings"], list):
            raise bad(f"slice {s}: 'rings' as a list of rings", type(sl["rings"]).__name__)
        pairs.append((z, sl["rings"]))
    meta = {"source": where, "units": units}
    for k in ("name", "roi"):
        if isinstance(doc.get(k), str):
            meta[k] = doc[k]
    return stack_from_rings(pairs, source=repr(where), meta=meta)


def contours_json_bytes(stack: ContourStack, *, name: str | None = None, units: str = "mm") -> bytes:
    """Serialise a contour stack in the JSON contour format (physical coordinates, full precision)."""
    if not isinstance(stack, ContourStack):
        raise TypeError(f"expected a ContourStack; got {type(stack).__name__}")
    sx, sy = (float(v) for v in stack.spacing)
    ox, oy = (float(v) for v in stack.origin)
    out_slices = []
    for k, s in enumerate(stack.sections):
        rings = []
        for c, ring in enumerate(s.contours):
            r = np.asarray(ring, dtype=np.float64)
            if r.ndim != 2 or r.shape[1] != 2:
                raise ValueError(f"section {k} contour {c}: expected shape (k, 2); got {r.shape}")
            xy = np.c_[r[:, 0] * sx + ox, r[:, 1] * sy + oy]
            if not np.all(np.isfinite(xy)):
                raise ValueError(f"section {k} (z={s.z}) contour {c} holds NaN or infinite coordinates")
            rings.append(xy.tolist())
        if not math.isfinite(float(s.z)):
            raise ValueError(f"section {k}: z must be finite; got {s.z}")
        out_slices.append({"z": float(s.z), "rings": rings})
    doc = {"format": CONTOURS_FORMAT, "version": CONTOURS_VERSION, "units": units}
    nm = name if name is not None else stack.meta.get("roi") or stack.meta.get("name")
    if isinstance(nm, str):
        doc["name"] = nm
    doc["slices"] = out_slices
    return (json.dumps(doc, allow_nan=False, separators=(",", ":")) + "\n").encode("utf-8")


def write_contours_json(stack: ContourStack, path, *, name: str | None = None, units: str = "mm",
                        force: bool = True) -> Path:
    """Write a contour stack in the JSON contour format (``docs/contour-json.md``), atomically.

    Coordinates are physical (``contour * spacing + origin``), written with full float precision;
    each ring keeps its orientation and start point, so :func:`read_contours` gives the same
    rings back.  Returns the path.
    """

    return atomic_write(Path(path), contours_json_bytes(stack, name=name, units=units), force=force)


def is_contour_file(path) -> bool:
    """Whether a file holds a contour stack (``.json``, a DICOM RTSTRUCT, or an npz of ``<ROI>__points_mm``).

    A DICOM file (``.dcm``, or any file with the DICOM marker) is routed by its header's Modality:
    RTSTRUCT holds contours; SEG and images are volumes.  A ``.dcm`` whose header cannot be read
    (or without pydicom) goes to the contour reader when pydicom is missing, so that the install
    hint is shown, and to the volume reader otherwise, which says what is wrong with it."""
    p = Path(path)
    suffix = _suffix(p)
    if suffix == ".json":
        return True
    if suffix == ".dcm" or (suffix not in VOLUME_SUFFIXES and p.is_file() and _has_dicom_marker(p)):
        try:
            import pydicom  # noqa: F401
        except ImportError:
            return suffix == ".dcm"
        return dicom_modality(p) == "RTSTRUCT"
    if suffix == ".npz" and p.is_file():
        import zipfile

        try:
            with zipfile.ZipFile(p) as z:
                return any(n.endswith("__points_mm.npy") for n in z.namelist())
        except (zipfile.BadZipFile, OSError):
            return False
    return False


def _has_dicom_marker(p: Path) -> bool:
    with open(p, "rb") as fh:
        return fh.read(132)[128:132] == b"DICM"
