"""Volume readers and the volume writer.

Everything read here is checked at the door.  A bad file (missing, a directory, an unknown
suffix, truncated or corrupt data, a header that declares more data than the file can hold)
raises ``FileNotFoundError``, ``IsADirectoryError`` or ``ValueError`` with a message that names
the file and says what was expected and what was found; it never fails deep inside a parser.
Nothing is ever unpickled: NumPy files are opened with ``allow_pickle=False``.

Axis conventions (stated once)
------------------------------
* Volumes are returned indexed ``[z, y, x]`` with ``spacing = (dz, dy, dx)`` and ``origin`` the
  physical ``(x, y, z)`` of the centre of voxel ``[0, 0, 0]`` (as in
  :func:`contourmesh.volumes.volume_to_mesh`).
* ``.npy``: the array is taken as ``[z, y, x]``, spacing ``(1, 1, 1)``.
* ``.npz``: the array named ``volume`` or ``mask`` (or the only array).  Optional arrays:
  ``spacing`` = ``(dz, dy, dx)`` or ``spacing_xyz`` = ``(dx, dy, dz)``; ``origin`` = ``(x, y, z)``;
  ``axes``, a note such as ``"volume[x, y, z]; ..."`` giving the axis order of the stored array
  (the files of the sample data are stored ``[x, y, z]`` and are transposed).  Without ``axes``
  the array is ``[z, y, x]``.
* TIFF stacks: pages are z, then ``[y, x]``; ``dx``, ``dy`` from the X/Y resolution tags and
  ``dz`` from ImageJ's ``spacing`` when present.
* NIfTI: the data array is ``[x, y, z]`` and is transposed; spacing from the header zooms.
* DICOM (``.dcm``, or a folder of slices): DICOM-SEG segmentations, image series and multi-frame
  images, in the patient frame LPS with their orientation (see :mod:`contourmesh.io.dicom`).
* DGtal ``.vol`` and INRIMAGE ``.inr``/``.inr.gz``: voxels stored x fastest, read as ``[z, y, x]``.
* Contour stacks (:func:`read_contours`) hold float64 rings in physical millimetres with
  ``spacing = (1, 1)`` and ``origin = (0, 0)``; outer rings have positive shoelace area, holes
  negative (holes are decided by nesting, even-odd; see ``docs/contour-json.md``).

Optional packages (tifffile, nibabel, pydicom) are imported when needed; a missing one raises an
ImportError naming ``pip install 'contourmesh[io]'``.
"""

from __future__ import annotations

import gzip
import math
import re
import zlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._files import (
    _DEFLATE_MAX_RATIO,
    MAX_VOXELS,
    VOLUME_SUFFIXES,
    _bad,
    _check_size,
    _reading,
    _require,
    _suffix,
    _wrap,
    check_file,
)
from ..meshes import atomic_write
from ..volume_input import check_volume_array, select_voxels
from .dicom import _has_marker as _is_dicom
from .dicom import read_dicom

__all__ = ["read_volume", "read_image", "Image", "write_volume", "VOLUME_SUFFIXES", "MAX_VOXELS"]



# ================================================================================================
# volumes
# ================================================================================================
class Image(NamedTuple):
    """A volume read from a file, with the geometry that places it in the world.

    ``volume`` is indexed ``[z, y, x]``; ``spacing = (dz, dy, dx)``; ``origin`` is the world
    ``(x, y, z)`` of the centre of voxel ``[0, 0, 0]``; ``direction`` is a 3x3 matrix whose
    columns are the world directions of the x, y and z voxel axes (the identity for formats
    without one).  World position of voxel ``[k, j, i]``:
    ``origin + direction @ (i dx, j dy, k dz)``.  ``space`` names the world frame when the file
    does (NIfTI: ``"RAS"``; NRRD: its ``space`` field, e.g. ``"left-posterior-superior"``; DICOM:
    ``"LPS"``).  ``z``: for slices that are not evenly spaced (a DICOM series), their offsets along
    the z voxel axis from the first (``spacing[0]`` is then their mean step); None otherwise.
    """

    volume: np.ndarray
    spacing: tuple
    origin: tuple
    direction: np.ndarray
    space: str | None = None
    z: np.ndarray | None = None


_READERS = {}  # suffix -> reader, filled below the readers


def read_volume(source, *, label=None, threshold=None, max_voxels: int = MAX_VOXELS, series=None):
    """Read a volume file (or pass an array through) as ``(array [z, y, x], spacing, origin)``.

    Parameters
    ----------
    source : str, Path or numpy.ndarray
        A ``.npy``, ``.npz``, TIFF stack (``.tif``/``.tiff``), NIfTI (``.nii``/``.nii.gz``), NRRD,
        DGtal ``.vol``, INRIMAGE (``.inr``/``.inr.gz``) or DICOM file (a DICOM-SEG, or an image:
        with the other files of its series in its folder), or a folder of DICOM slices; or an
        array indexed ``[z, y, x]``.
    label : number, optional
        Return the boolean mask ``volume == label``.  A segment's name in a ``.seg.nrrd`` or
        DICOM-SEG file names its label.
    threshold : number, optional
        Return the boolean mask ``volume > threshold``.
    max_voxels : int
        Refuse files whose header declares more voxels (checked before allocating).
    series : str or int, optional
        For a folder holding several DICOM series: the SeriesInstanceUID or SeriesNumber to read.

    Returns
    -------
    volume : numpy.ndarray
        3D, ``[z, y, x]``: the stored values, or a boolean mask with ``label``/``threshold``.  For
        an ``.npz`` holding both ``volume`` and ``mask``, ``mask`` is returned without
        ``label``/``threshold`` and ``volume`` (the values) with them.
    spacing : tuple of float
        ``(dz, dy, dx)``.
    origin : tuple of float
        Physical ``(x, y, z)`` of the centre of voxel ``[0, 0, 0]``.

    Raises
    ------
    FileNotFoundError, IsADirectoryError
        The path does not name a file.
    ValueError
        Unknown suffix; truncated, corrupt or pickled data; a header declaring an impossible or
        over-large size; a volume that is not 3D; a bad ``label``/``threshold``; a DICOM series
        whose slices are not evenly spaced (:func:`read_image` gives their positions).
    """
    img = read_image(source, label=label, threshold=threshold, max_voxels=max_voxels, series=series)
    if img.z is not None:
        steps = np.diff(img.z)
        raise ValueError(f"{str(source)!r}: the slices are not evenly spaced (steps {steps.min():.6g} to "
                         f"{steps.max():.6g}); read_image returns their positions (Image.z), which "
                         "contourmesh.mesh uses")
    return img.volume, img.spacing, img.origin


def read_image(source, *, label=None, threshold=None, max_voxels: int = MAX_VOXELS, series=None) -> Image:
    """Like :func:`read_volume`, with the image's direction matrix and world frame (an :class:`Image`).

    ``label`` may also be a segment's name in a 3D Slicer ``.seg.nrrd`` file or a DICOM-SEG.
    ``source`` may be a folder of DICOM slices (``series=`` picks one of several series).
    """
    if label is not None and threshold is not None:
        raise ValueError("give label= or threshold=, not both")
    direction, space, z = np.eye(3), None, None
    if isinstance(source, np.ndarray):
        if series is not None:
            raise ValueError("series= picks a series of DICOM files; an array has none")
        vol, spacing, origin = source, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
        where = "the array"
    else:
        if isinstance(source, (str, Path)) and Path(source).expanduser().is_dir():
            path = Path(source).expanduser()
            suffix = "dicom folder"
            if not any(f.is_file() and _is_dicom(f) for f in path.iterdir()):
                raise IsADirectoryError(f"{str(path)!r} is a directory; expected a volume file, or a folder of DICOM "
                                        "image slices (it holds no DICOM file)")
        else:
            path = check_file(source, "volume")
            suffix = _suffix(path)
            if suffix not in _READERS and _is_dicom(path):
                suffix = ".dcm"
        where = repr(str(path))
        if series is not None and suffix not in (".dcm", "dicom folder"):
            raise ValueError(f"{where}: series= picks a series of DICOM files; this is not DICOM")
        if suffix not in _READERS and suffix != "dicom folder":
            raise ValueError(f"{str(path)!r}: cannot tell the volume format; expected a suffix among "
                             f"{', '.join(VOLUME_SUFFIXES)} (or a folder of DICOM files), found "
                             f"{path.suffix or 'none'!r}")
        prefer = "volume" if (label is not None or threshold is not None) else "mask"
        if suffix in (".dcm", "dicom folder"):
            vol, spacing, origin, direction, space, label, z = read_dicom(path, max_voxels=max_voxels, label=label,
                                                                          series=series)
        elif suffix in (".nrrd", ".nhdr"):
            vol, spacing, origin, direction, space, label = _read_nrrd(path, max_voxels=max_voxels, label=label)
        else:
            got = _READERS[suffix](path, max_voxels=max_voxels, prefer=prefer)
            vol, spacing, origin = got[:3]
            if len(got) > 3:
                direction, space = got[3], got[4]
    if isinstance(label, str):
        raise TypeError(f"label must be a number (or a segment name of a .seg.nrrd or DICOM-SEG file); got {label!r}")
    vol = check_volume_array(vol, where)
    spacing = tuple(float(s) for s in spacing)
    if len(spacing) != 3 or not all(math.isfinite(s) and s > 0 for s in spacing):
        raise ValueError(f"{where}: expected three positive finite voxel sizes (dz, dy, dx); found {spacing}")
    origin = tuple(float(o) for o in origin)
    if len(origin) != 3 or not all(math.isfinite(o) for o in origin):
        raise ValueError(f"{where}: expected a finite origin (x, y, z); found {origin}")
    direction = np.asarray(direction, dtype=np.float64)
    if direction.shape != (3, 3) or not np.all(np.isfinite(direction)) or abs(np.linalg.det(direction)) < 1e-6:
        raise ValueError(f"{where}: expected an invertible 3x3 direction matrix; found {direction.tolist()}")
    if label is not None or threshold is not None:
        vol = select_voxels(vol, label=label, threshold=threshold, where=where)
    if z is not None:
        z = np.asarray(z, dtype=np.float64)
    return Image(vol, spacing, origin, direction, space, z)


def _read_npy(path: Path, *, max_voxels: int, prefer: str):
    with open(path, "rb") as fh:
        magic = fh.read(6)
    if magic != b"\x93NUMPY":
        raise _bad(path, "a NumPy .npy file (starting with b'\\x93NUMPY')", f"the bytes {magic!r}")
    try:  # check the declared size before numpy allocates it (no allocation bomb)
        with open(path, "rb") as fh:
            major, _ = np.lib.format.read_magic(fh)
            read_header = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
            shape, _, dtype = read_header(fh)
        if dtype.hasobject:
            raise _bad(path, "a numeric array", "pickled Python objects (dtype object); refusing to unpickle them")
        n, nbytes = _check_size(path, shape, dtype.itemsize, max_voxels)
        have = path.stat().st_size
        if nbytes > have:
            raise _bad(path, f"{nbytes} bytes of data for shape {tuple(shape)} {dtype}", f"a file of {have} bytes (truncated file)")
    except (ValueError, EOFError, OSError) as exc:
        if str(exc).startswith(repr(str(path))):
            raise
        raise _wrap(path, ".npy", exc) from None
    try:
        arr = np.load(path, allow_pickle=False)
    except ValueError as exc:
        if "allow_pickle" in str(exc) or "Object arrays" in str(exc):
            raise _bad(path, "a numeric array", "pickled Python objects (dtype object); refusing to unpickle them") from None
        raise _wrap(path, ".npy", exc) from None
    except (EOFError, OSError) as exc:
        raise _wrap(path, ".npy", exc) from None
    return arr, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)


_AXES_RE = re.compile(r"\[\s*([xyz])\s*,\s*([xyz])\s*,\s*([xyz])\s*\]")


def _axes_order(path: Path, note) -> tuple | None:
    """Permutation taking the stored axes to [z, y, x], from an ``axes`` note; None = unchanged."""
    text = str(np.asarray(note).reshape(-1)[0]) if np.asarray(note).size else ""
    m = _AXES_RE.search(text)
    letters = m.groups() if m else tuple(text.strip().lower()) if re.fullmatch(r"\s*[xyzXYZ]{3}\s*", text) else None
    if letters is None or sorted(letters) != ["x", "y", "z"]:
        raise _bad(path, "an 'axes' note naming the stored axis order such as 'volume[x, y, z]' or 'zyx'", repr(text[:80]))
    return tuple(letters.index(c) for c in "zyx")


def _check_npz_member(path: Path, zf, name: str, max_voxels: int) -> None:
    """Read the .npy header of member ``name`` and check its declared size (and that it holds no
    pickled objects) before numpy allocates or decompresses the array."""
    member = name if name in zf.namelist() else name + ".npy"
    with zf.open(member) as fh:
        major, _ = np.lib.format.read_magic(fh)
        read_header = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
        shape, _, dtype = read_header(fh)
    if dtype.hasobject:
        raise _bad(path, f"a numeric array {name!r}", "pickled Python objects (dtype object); refusing to unpickle them")
    n, nbytes = _check_size(path, shape, dtype.itemsize, max_voxels)
    declared = zf.getinfo(member).file_size
    if nbytes > declared:
        raise _bad(path, f"{nbytes} bytes of data for array {name!r} of shape {tuple(shape)} {dtype}",
                   f"a member of {declared} bytes (truncated archive)")


def _read_npz(path: Path, *, max_voxels: int, prefer: str):
    import zipfile

    with open(path, "rb") as fh:
        magic = fh.read(4)
    if magic[:2] != b"PK":
        raise _bad(path, "a NumPy .npz (zip) archive", f"the bytes {magic!r}")
    with _reading(path, ".npz", (zipfile.BadZipFile, EOFError, OSError, KeyError, zlib.error)):
        with np.load(path, allow_pickle=False) as npz:
            names = list(npz.files)
            order = ("mask", "volume") if prefer == "mask" else ("volume", "mask")
            pick = next((n for n in order if n in names), None)
            if pick is None:
                arrays = [n for n in names if n not in ("spacing", "spacing_xyz", "origin", "axes")]
                if len(arrays) != 1:
                    raise _bad(path, "an array named 'volume' or 'mask', or a single array",
                               f"arrays {names}")
                pick = arrays[0]
            _check_npz_member(path, npz.zip, pick, max_voxels)
            try:
                vol = npz[pick]
            except ValueError as exc:
                if "allow_pickle" in str(exc) or "Object arrays" in str(exc):
                    raise _bad(path, f"a numeric array {pick!r}", "pickled Python objects; refusing to unpickle them") from None
                raise
            spacing, origin = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
            if "spacing" in names:
                spacing = tuple(np.asarray(npz["spacing"], dtype=np.float64).reshape(-1))
            elif "spacing_xyz" in names:
                spacing = tuple(np.asarray(npz["spacing_xyz"], dtype=np.float64).reshape(-1)[::-1])
            if "origin" in names:
                origin = tuple(np.asarray(npz["origin"], dtype=np.float64).reshape(-1))
            order_zyx = _axes_order(path, npz["axes"]) if "axes" in names else None
    if order_zyx is not None:
        if vol.ndim != 3:
            raise _bad(path, "a 3D array to go with the 'axes' note", f"shape {vol.shape}")
        vol = np.ascontiguousarray(np.transpose(vol, order_zyx))
    if len(spacing) != 3:
        raise _bad(path, "three spacings", f"{len(spacing)} values")
    return vol, spacing, origin


def _read_tiff(path: Path, *, max_voxels: int, prefer: str):
    tifffile = _require("tifffile")
    with _reading(path, "TIFF"):  # tifffile raises its own TiffFileError, struct.error, ...
        with tifffile.TiffFile(path) as tif:
            size = path.stat().st_size
            pages = list(tif.pages)
            for i, page in enumerate(pages):
                ends = [int(o) + int(c) for o, c in zip(page.dataoffsets, page.databytecounts)]
                if ends and max(ends) > size:
                    raise _bad(path, f"page {i}'s image data within the file's {size} bytes",
                               f"data up to byte {max(ends)} (truncated file)")
            ij = tif.imagej_metadata or {}
            if "images" in ij and int(ij["images"]) != len(pages):
                raise _bad(path, f"{int(ij['images'])} image pages (ImageJ metadata)",
                           f"{len(pages)} readable pages (truncated file)")
            series = tif.series[0]
            _check_size(path, series.shape, 1, max_voxels)
            vol = series.asarray()
            dx = dy = dz = 1.0
            tags = tif.pages[0].tags
            if "XResolution" in tags and "YResolution" in tags:
                xr, yr = tags["XResolution"].value, tags["YResolution"].value
                if xr[0] > 0 and yr[0] > 0:
                    dx, dy = xr[1] / xr[0], yr[1] / yr[0]
            if "spacing" in ij:
                dz = float(ij["spacing"])
    if vol.ndim == 4 or (vol.ndim == 3 and vol.shape[-1] in (3, 4) and series.axes.endswith("S")):
        raise _bad(path, "a greyscale or label image stack", f"colour samples (axes {series.axes!r})")
    return vol, (dz, dy, dx), (0.0, 0.0, 0.0)


def _read_nifti(path: Path, *, max_voxels: int, prefer: str):
    nib = _require("nibabel")
    with _reading(path, "NIfTI"):  # nibabel's ImageFileError, EOFError, zlib errors, ...
        img = nib.load(str(path))
        shape = img.shape
        if len(shape) == 4 and shape[3] == 1:
            shape = shape[:3]
        if len(shape) != 3:
            raise _bad(path, "a 3D NIfTI image", f"shape {img.shape}")
        _check_size(path, shape, 1, max_voxels)
        data = np.asanyarray(img.dataobj).reshape(shape)
        zooms = [float(z) for z in img.header.get_zooms()[:3]]
        affine = np.asarray(img.affine, dtype=np.float64)
    # the affine maps voxel indices (i, j, k) to RAS world coordinates: its columns are the axes'
    # directions times the voxel sizes
    direction = affine[:3, :3] / np.where(np.array(zooms) > 0, zooms, 1.0)[None, :]
    origin = tuple(affine[:3, 3])
    vol = np.ascontiguousarray(np.transpose(data, (2, 1, 0)))
    return vol, (zooms[2], zooms[1], zooms[0]), origin, direction, "RAS"


def _segments(header: dict) -> dict:
    """3D Slicer segment names of a ``.seg.nrrd`` header: ``{name: (label value, layer)}``."""
    out = {}
    for key, name in header.items():
        m = re.fullmatch(r"Segment(\d+)_Name", key)
        if m:
            n = m.group(1)
            value = header.get(f"Segment{n}_LabelValue", "1")
            layer = header.get(f"Segment{n}_Layer", "0")
            try:
                out[str(name)] = (int(value), int(layer))
            except ValueError:
                continue
    return out


def _read_nrrd(path: Path, *, max_voxels: int, label=None):
    """NRRD (``.nrrd``, ``.seg.nrrd``, detached ``.nhdr``) through pynrrd, in ``[z, y, x]`` with its
    space directions.  Returns ``(volume, spacing, origin, direction, space, label)``; a segment
    name given as ``label`` becomes its label value (and picks its layer)."""
    nrrd = _require("nrrd")
    try:
        header = nrrd.read_header(str(path))
    except Exception as exc:
        raise _wrap(path, "NRRD", exc) from None
    sizes = [int(s) for s in np.atleast_1d(header.get("sizes", []))]
    dirs = header.get("space directions")
    if dirs is None:
        spacing_xyz = np.asarray(header.get("spacings", [1.0] * len(sizes)), dtype=np.float64)
        dirs = [np.eye(3)[i] * (spacing_xyz[i] if i < len(spacing_xyz) else 1.0) for i in range(min(3, len(sizes)))]
    rows = [np.asarray(d, dtype=np.float64) for d in dirs]
    spatial = [i for i, d in enumerate(rows) if d.shape == (3,) and np.all(np.isfinite(d))]
    if len(spatial) != 3 or len(sizes) not in (3, 4):
        raise _bad(path, "a 3D NRRD image (or a 4D segmentation with one list axis)", f"sizes {sizes}")
    _check_size(path, sizes, 1, max_voxels)
    layer = 0
    if isinstance(label, str):
        segs = _segments(header)
        if label not in segs:
            raise ValueError(f"{str(path)!r}: no segment named {label!r}; segments: {sorted(segs) or 'none'}")
        label, layer = segs[label]
    try:
        data, _ = nrrd.read(str(path), index_order="F")
    except Exception as exc:
        raise _wrap(path, "NRRD", exc) from None
    data = np.asarray(data)
    if data.ndim == 4:  # layers of a segmentation: the non-spatial axis
        list_axis = [i for i in range(4) if i not in spatial][0]
        data = np.take(data, layer, axis=list_axis)
    d = np.array([rows[i] for i in spatial])  # rows: world vectors of the i, j, k axes
    spacing_xyz = np.linalg.norm(d, axis=1)
    direction = (d / spacing_xyz[:, None]).T  # columns: unit directions of i, j, k
    origin = tuple(np.asarray(header.get("space origin", [0.0, 0.0, 0.0]), dtype=np.float64))
    vol = np.ascontiguousarray(np.transpose(data, (2, 1, 0)))  # [i, j, k] -> [z, y, x]
    space = header.get("space")
    return vol, (spacing_xyz[2], spacing_xyz[1], spacing_xyz[0]), origin, direction, space, label


def _read_header_lines(fh, path: Path, limit: int = 1 << 16) -> tuple[dict, int]:
    """DGtal .vol header: ``Key: value`` lines ended by a line holding only ``.``."""
    head = fh.read(limit)
    end = head.find(b"\n.\n")
    if end < 0:
        raise _bad(path, "a DGtal .vol header of 'Key: value' lines ended by a line '.'",
                   "no terminating '.' line in the first 64 KiB" if len(head) == limit else "no terminating '.' line")
    fields = {}
    for line in head[:end].decode("ascii", errors="replace").splitlines():
        if not line.strip():
            continue
        if ":" not in line:
            raise _bad(path, "'Key: value' header lines", repr(line[:60]))
        k, v = line.split(":", 1)
        fields[k.strip()] = v.strip()
    return fields, end + 3


def _int_field(path, fields, key):
    try:
        v = int(fields[key])
    except KeyError:
        raise _bad(path, f"a header field {key!r}", f"fields {sorted(fields)}") from None
    except ValueError:
        raise _bad(path, f"an integer {key!r}", repr(fields[key])) from None
    if v <= 0:
        raise _bad(path, f"a positive {key!r}", v)
    return v


def _read_dgtal_vol(path: Path, *, max_voxels: int, prefer: str):
    """DGtal ``.vol`` (see DGtal's ``VolReader``): header, then X*Y*Z bytes, x fastest; v3 zlib."""
    with open(path, "rb") as fh:
        fields, start = _read_header_lines(fh, path)
        nx, ny, nz = (_int_field(path, fields, k) for k in ("X", "Y", "Z"))
        version = fields.get("Version", "2")
        if version not in ("2", "3"):
            raise _bad(path, "a .vol 'Version' of 2 (raw) or 3 (zlib)", repr(version))
        n, _ = _check_size(path, (nz, ny, nx), 1, max_voxels)
        fh.seek(start)
        payload_size = path.stat().st_size - start
        if version == "2":
            if payload_size < n:
                raise _bad(path, f"{n} voxel bytes after the header ({nx} x {ny} x {nz})",
                           f"only {payload_size} bytes (truncated file)")
            data = fh.read(n)
        else:
            if n > _DEFLATE_MAX_RATIO * payload_size + 1024:
                raise _bad(path, f"a zlib payload that can hold {nx} x {ny} x {nz} = {n} voxels",
                           f"{payload_size} compressed bytes (at most ~{_DEFLATE_MAX_RATIO * payload_size} "
                           "voxels; truncated file or wrong header)")
            comp = fh.read()
            d = zlib.decompressobj()
            try:
                data = d.decompress(comp, n)
            except zlib.error as exc:
                raise _wrap(path, "DGtal .vol (zlib payload)", exc) from None
            if len(data) < n:
                raise _bad(path, f"{n} voxels ({nx} x {ny} x {nz}) in the zlib payload",
                           f"{len(data)} (truncated file)")
            if d.unconsumed_tail:
                raise _bad(path, f"{n} voxels ({nx} x {ny} x {nz}) in the zlib payload", "more data than that")
            if not d.eof:
                raise _bad(path, "a complete zlib stream", "a stream that ends early (truncated file)")
    vol = np.frombuffer(data, dtype=np.uint8, count=n).reshape(nz, ny, nx).copy()
    vs = fields.get("Voxel-Size", "1").split()
    try:
        sizes = [float(v) for v in vs]
    except ValueError:
        raise _bad(path, "a numeric 'Voxel-Size'", repr(fields.get("Voxel-Size"))) from None
    if len(sizes) == 1:
        sizes = sizes * 3
    if len(sizes) != 3:
        raise _bad(path, "a 'Voxel-Size' of 1 or 3 numbers (x y z)", repr(fields.get("Voxel-Size")))
    return vol, (sizes[2], sizes[1], sizes[0]), (0.0, 0.0, 0.0)


_INR_TYPES = {("unsigned fixed", 8): "u1", ("unsigned fixed", 16): "u2", ("unsigned fixed", 32): "u4",
              ("signed fixed", 8): "i1", ("signed fixed", 16): "i2", ("signed fixed", 32): "i4",
              ("float", 32): "f4", ("float", 64): "f8"}


def _read_inr(path: Path, *, max_voxels: int, prefer: str):
    """INRIMAGE-4: a text header in blocks of 256 bytes ending with ``##}``, then raw voxels, x fastest."""
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    with _reading(path, "INRIMAGE", (EOFError, OSError, zlib.error)):
        with opener(path, "rb") as fh:
            head = fh.read(256)
            if not head.startswith(b"#INRIMAGE-4#{"):
                raise _bad(path, "an INRIMAGE-4 header starting with '#INRIMAGE-4#{'", f"the bytes {head[:16]!r}")
            while b"##}" not in head:
                block = fh.read(256)
                if len(block) < 256 or len(head) > 256 * 64:
                    raise _bad(path, "an INRIMAGE header ending with '##}'", "no end of header (truncated file)")
                head += block
            fields = {}
            for line in head.decode("ascii", errors="replace").splitlines()[1:]:
                if "=" in line and not line.startswith("##"):
                    k, v = line.split("=", 1)
                    fields[k.strip()] = v.strip()
            nx, ny, nz = (_int_field(path, fields, k) for k in ("XDIM", "YDIM", "ZDIM"))
            vdim = int(fields.get("VDIM", "1"))
            if vdim != 1:
                raise _bad(path, "a scalar image (VDIM=1)", f"VDIM={vdim}")
            m = re.match(r"(\d+)", fields.get("PIXSIZE", "8 bits"))
            bits = int(m.group(1)) if m else -1
            kind = fields.get("TYPE", "unsigned fixed")
            if (kind, bits) not in _INR_TYPES:
                raise _bad(path, f"a voxel type among {sorted(_INR_TYPES)}", f"TYPE={kind!r} PIXSIZE={fields.get('PIXSIZE')!r}")
            cpu = fields.get("CPU", "decm").lower()
            endian = ">" if cpu in ("sun", "sgi") else "<"
            dtype = np.dtype(endian + _INR_TYPES[(kind, bits)])
            n, nbytes = _check_size(path, (nz, ny, nx), dtype.itemsize, max_voxels)
            if opener is open and path.stat().st_size - len(head) < nbytes:
                raise _bad(path, f"{nbytes} bytes of voxels ({nx} x {ny} x {nz} x {dtype.itemsize})",
                           f"{path.stat().st_size - len(head)} bytes (truncated file)")
            data = fh.read(nbytes)
    if len(data) < nbytes:
        raise _bad(path, f"{nbytes} bytes of voxels ({nx} x {ny} x {nz})", f"{len(data)} bytes (truncated file)")
    vol = np.frombuffer(data, dtype=dtype, count=n).reshape(nz, ny, nx).copy()
    sp = []
    for k in ("VZ", "VY", "VX"):
        try:
            sp.append(float(fields.get(k, "1")))
        except ValueError:
            raise _bad(path, f"a numeric {k}", repr(fields.get(k))) from None
    return vol, tuple(sp), (0.0, 0.0, 0.0)


def write_volume(path, volume, *, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), force: bool = True) -> Path:
    """Write a ``[z, y, x]`` volume atomically, in the format given by the suffix.

    ``.npz`` (arrays ``volume``, ``spacing`` = ``(dz, dy, dx)``, ``origin``), ``.npy`` (array
    only), ``.vol`` (DGtal version 3, uint8 values 0..255, isotropic spacing only), ``.tif``/
    ``.tiff`` (tifffile, ImageJ hyperstack with resolution and ``spacing``), ``.nii``/``.nii.gz``
    (nibabel, diagonal affine).  :func:`read_volume` reads back what this writes.
    """
    import io as _io


    path = Path(path)
    vol = np.asarray(volume)
    if vol.ndim != 3:
        raise ValueError(f"expected a 3D volume [z, y, x]; got shape {vol.shape}")
    sp = tuple(float(s) for s in spacing)
    org = tuple(float(o) for o in origin)
    suffix = _suffix(path)
    buf = _io.BytesIO()
    if suffix == ".npz":
        np.savez_compressed(buf, volume=vol, spacing=np.array(sp), origin=np.array(org))
    elif suffix == ".npy":
        np.save(buf, vol, allow_pickle=False)
    elif suffix == ".vol":
        if vol.dtype == bool:
            vol = vol.astype(np.uint8)
        if vol.dtype.kind not in "biu" or vol.min() < 0 or vol.max() > 255:
            raise ValueError(f"a .vol file holds bytes 0..255; got dtype {vol.dtype} with range {vol.min()}..{vol.max()}")
        if len(set(sp)) != 1:
            raise ValueError(f"a .vol file has one voxel size; got spacing {sp}")
        nz, ny, nx = vol.shape
        head = (f"Center-X: {nx // 2}\nCenter-Y: {ny // 2}\nCenter-Z: {nz // 2}\nX: {nx}\nY: {ny}\nZ: {nz}\n"
                f"Voxel-Size: {sp[0]:g}\nAlpha-Color: 0\nVoxel-Endian: 0\nInt-Endian: 0123\nVersion: 3\n.\n")
        buf.write(head.encode("ascii") + zlib.compress(np.ascontiguousarray(vol, dtype=np.uint8).tobytes()))
    elif suffix in (".tif", ".tiff"):
        tifffile = _require("tifffile")
        data = vol.astype(np.uint8) if vol.dtype == bool else vol
        tifffile.imwrite(buf, data, imagej=True, resolution=(1.0 / sp[2], 1.0 / sp[1]),
                         metadata={"spacing": sp[0], "axes": "ZYX"})
    elif suffix in (".nii", ".nii.gz"):
        nib = _require("nibabel")
        data = vol.astype(np.uint8) if vol.dtype == bool else vol
        aff = np.diag([sp[2], sp[1], sp[0], 1.0])
        aff[:3, 3] = org
        img = nib.Nifti1Image(np.ascontiguousarray(np.transpose(data, (2, 1, 0))), aff)
        data_bytes = img.to_bytes()
        buf.write(gzip.compress(data_bytes) if suffix == ".nii.gz" else data_bytes)
    else:
        raise ValueError(f"cannot tell the volume format of {str(path)!r}: expected a suffix among "
                         ".npz, .npy, .vol, .tif, .tiff, .nii, .nii.gz; found {path.suffix or 'none'!r}")
    return atomic_write(path, buf.getvalue(), force=force)


# ================================================================================================
# contour stacks
# ================================================================================================
# ================================================================================================
# meshes
# ================================================================================================
# ================================================================================================
# files as mesh sources
# ================================================================================================


_READERS.update({".npy": _read_npy, ".npz": _read_npz, ".tif": _read_tiff, ".tiff": _read_tiff, ".nii": _read_nifti,
                 ".nii.gz": _read_nifti, ".vol": _read_dgtal_vol, ".inr": _read_inr, ".inr.gz": _read_inr,
                 ".nrrd": _read_nrrd, ".nhdr": _read_nrrd, ".dcm": read_dicom})
