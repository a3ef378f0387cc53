"""Readers and writers: volumes, contour stacks and meshes.

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
* DGtal ``.vol`` and INRIMAGE ``.inr``/``.inr.gz``: voxels stored x fastest, read as ``[z, y, x]``.
* Contour stacks (:func:`read_contours`) hold float64 rings in physical millimetres with
  ``spacing = (1, 1)`` and ``origin = (0, 0)``; outer rings have positive shoelace area, holes
  negative (holes are decided by nesting, even-odd; see ``docs/contour-json.md``).

Optional packages (tifffile, nibabel, pydicom) are imported when needed; a missing one raises an
ImportError naming ``pip install 'contourmesh[io]'``.
"""

from __future__ import annotations

import gzip
import json
import math
import re
import warnings
import zlib
from pathlib import Path

import numpy as np

from .types import ContourStack, Mesh, Section, shoelace_area

__all__ = [
    "read_volume", "write_volume", "read_contours", "write_contours_json", "stack_from_rings",
    "load_mesh", "register_trimesh_loader", "mesh_file", "is_file_source", "is_contour_file", "VOLUME_SUFFIXES", "CONTOUR_SUFFIXES", "MAX_VOXELS",
    "CONTOURS_FORMAT", "CONTOURS_VERSION", "Z_TOLERANCE",
]

#: File suffixes :func:`read_volume` understands.
VOLUME_SUFFIXES = (".npy", ".npz", ".tif", ".tiff", ".nii", ".nii.gz", ".vol", ".inr", ".inr.gz")
#: File suffixes :func:`read_contours` understands.
CONTOUR_SUFFIXES = (".dcm", ".json", ".npz")
#: Largest volume (voxels) a file header may declare; larger headers are refused before allocating.
MAX_VOXELS = 2**32
#: The ``format`` tag and ``version`` of the JSON contour format.
CONTOURS_FORMAT = "contourmesh.contours"
CONTOURS_VERSION = 1
#: Contours whose heights differ by at most this much (mm) belong to one section.
Z_TOLERANCE = 1e-3

#: deflate cannot compress by more than about 1032:1; used to reject impossible .vol headers.
_DEFLATE_MAX_RATIO = 1032


def _require(module: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(
            f"{module} is needed to read this file; install it with `pip install 'contourmesh[io]'` "
            f"(or `pip install {module}`): {exc}"
        ) from exc


def _suffix(path: Path) -> str:
    name = path.name.lower()
    for double in (".nii.gz", ".inr.gz", ".contours.json"):
        if name.endswith(double):
            return double if double != ".contours.json" else ".json"
    return path.suffix.lower()


def _check_file(path, what: str) -> Path:
    """The path as a Path, after checking that it names an existing regular file."""
    if isinstance(path, (bytes, bytearray)):
        path = path.decode()
    if not isinstance(path, (str, Path)):
        raise TypeError(f"expected a file path for the {what}; got {type(path).__name__}")
    p = Path(path).expanduser()
    if p.is_dir():
        raise IsADirectoryError(f"{str(p)!r} is a directory; expected {'an' if what[0] in 'aeiou' else 'a'} {what} file")
    if not p.exists():
        raise FileNotFoundError(f"{what} file {str(p)!r} does not exist")
    if not p.is_file():
        raise ValueError(f"{str(p)!r} is not a regular file; expected {'an' if what[0] in 'aeiou' else 'a'} {what} file")
    return p


def _bad(path: Path, expected: str, found) -> ValueError:
    return ValueError(f"{str(path)!r}: expected {expected}; found {found}")


def _check_size(path: Path, shape, itemsize: int, max_voxels: int):
    n = 1
    for s in shape:
        n *= int(s)
    if n > max_voxels:
        raise _bad(path, f"a volume of at most {max_voxels} voxels",
                   f"a header declaring {' x '.join(str(int(s)) for s in shape)} = {n} voxels")
    return n, n * itemsize


# ================================================================================================
# volumes
# ================================================================================================
def read_volume(source, *, label=None, threshold=None, max_voxels: int = MAX_VOXELS):
    """Read a volume file (or pass an array through) as ``(array [z, y, x], spacing, origin)``.

    Parameters
    ----------
    source : str, Path or numpy.ndarray
        A ``.npy``, ``.npz``, TIFF stack (``.tif``/``.tiff``), NIfTI (``.nii``/``.nii.gz``), DGtal
        ``.vol`` or INRIMAGE (``.inr``/``.inr.gz``) file; or an array indexed ``[z, y, x]``.
    label : number, optional
        Return the boolean mask ``volume == label``.
    threshold : number, optional
        Return the boolean mask ``volume > threshold``.
    max_voxels : int
        Refuse files whose header declares more voxels (checked before allocating).

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
        over-large size; a volume that is not 3D; a bad ``label``/``threshold``.
    """
    if label is not None and threshold is not None:
        raise ValueError("give label= or threshold=, not both")
    if isinstance(source, np.ndarray):
        vol, spacing, origin = source, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
        where = "the array"
    else:
        path = _check_file(source, "volume")
        where = repr(str(path))
        suffix = _suffix(path)
        readers = {".npy": _read_npy, ".npz": _read_npz, ".tif": _read_tiff, ".tiff": _read_tiff,
                   ".nii": _read_nifti, ".nii.gz": _read_nifti, ".vol": _read_dgtal_vol,
                   ".inr": _read_inr, ".inr.gz": _read_inr}
        if suffix not in readers:
            hint = " (DICOM RTSTRUCT contours are read by read_contours)" if suffix == ".dcm" else ""
            raise ValueError(f"{str(path)!r}: cannot tell the volume format; expected a suffix among "
                             f"{', '.join(VOLUME_SUFFIXES)}, found {path.suffix or 'none'!r}{hint}")
        vol, spacing, origin = readers[suffix](path, max_voxels=max_voxels,
                                               prefer="volume" if (label is not None or threshold is not None) else "mask")
    vol = np.asarray(vol)
    if vol.dtype == object or vol.dtype.kind not in "biuf":
        raise ValueError(f"{where}: expected a numeric or boolean volume; found dtype {vol.dtype}")
    if vol.ndim == 2:
        vol = vol[None]
    if vol.ndim != 3:
        raise ValueError(f"{where}: expected a 3D volume [z, y, x]; found {vol.ndim}D with shape {vol.shape}")
    spacing = tuple(float(s) for s in spacing)
    if len(spacing) != 3 or not all(math.isfinite(s) and s > 0 for s in spacing):
        raise ValueError(f"{where}: expected three positive finite voxel sizes (dz, dy, dx); found {spacing}")
    origin = tuple(float(o) for o in origin)
    if len(origin) != 3 or not all(math.isfinite(o) for o in origin):
        raise ValueError(f"{where}: expected a finite origin (x, y, z); found {origin}")
    if label is not None:
        if not np.isscalar(label) or isinstance(label, (str, bytes)):
            raise ValueError(f"label must be a number; got {label!r}")
        vol = vol == label
        if not vol.any():
            raise ValueError(f"{where}: no voxel has label {label!r}")
    elif threshold is not None:
        if not np.isscalar(threshold) or isinstance(threshold, (str, bytes)) or not np.isfinite(threshold):
            raise ValueError(f"threshold must be a finite number; got {threshold!r}")
        if vol.dtype.kind == "f" and np.isnan(vol).any():
            raise ValueError(f"{where}: the volume holds NaN values; cannot threshold it")
        vol = vol > threshold
    return vol, spacing, origin


def _wrap(path: Path, kind: str, exc: BaseException) -> ValueError:
    msg = str(exc) or type(exc).__name__
    return ValueError(f"{str(path)!r}: expected a readable {kind} file; the file is truncated or corrupt ({msg})")


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
    try:
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
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise _wrap(path, ".npz", exc) from None
    except (zipfile.BadZipFile, EOFError, OSError, KeyError, zlib.error) as exc:
        raise _wrap(path, ".npz", exc) from None
    if order_zyx is not None:
        if vol.ndim != 3:
            raise _bad(path, "a 3D array to go with the 'axes' note", f"shape {vol.shape}")
        vol = np.ascontiguousarray(np.transpose(vol, order_zyx))
    if len(spacing) != 3:
        raise _bad(path, "three spacings", f"{len(spacing)} values")
    return vol, spacing, origin


def _read_tiff(path: Path, *, max_voxels: int, prefer: str):
    tifffile = _require("tifffile")
    try:
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
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise _wrap(path, "TIFF", exc) from None
    except Exception as exc:  # tifffile raises its own TiffFileError, struct.error, ...
        raise _wrap(path, "TIFF", exc) from None
    if vol.ndim == 4 or (vol.ndim == 3 and vol.shape[-1] in (3, 4) and series.axes.endswith("S")):
        raise _bad(path, "a greyscale or label image stack", f"colour samples (axes {series.axes!r})")
    return vol, (dz, dy, dx), (0.0, 0.0, 0.0)


def _read_nifti(path: Path, *, max_voxels: int, prefer: str):
    nib = _require("nibabel")
    try:
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
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise _wrap(path, "NIfTI", exc) from None
    except Exception as exc:  # nibabel's ImageFileError, EOFError, zlib errors, ...
        raise _wrap(path, "NIfTI", exc) from None
    rot = affine[:3, :3]
    if np.allclose(rot, np.diag(np.diag(rot))) and np.all(np.diag(rot) > 0):
        origin = tuple(affine[:3, 3])
    else:
        warnings.warn(f"{str(path)!r}: the NIfTI affine rotates or flips the axes; origin set to (0, 0, 0) "
                      "and the voxel axes taken as x, y, z", stacklevel=3)
        origin = (0.0, 0.0, 0.0)
    vol = np.ascontiguousarray(np.transpose(data, (2, 1, 0)))
    return vol, (zooms[2], zooms[1], zooms[0]), origin


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
    try:
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
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise _wrap(path, "INRIMAGE", exc) from None
    except (EOFError, OSError, zlib.error) as exc:
        raise _wrap(path, "INRIMAGE", exc) from None
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

    from .meshes import atomic_write

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
def _clean_ring(ring: np.ndarray) -> np.ndarray:
    """Drop consecutive repeated points and a repeated closing point."""
    if len(ring) == 0:
        return ring
    keep = np.ones(len(ring), dtype=bool)
    keep[1:] = np.any(ring[1:] != ring[:-1], axis=1)
    r = ring[keep]
    while len(r) > 1 and np.all(r[-1] == r[0]):
        r = r[:-1]
    return r


def _reverse_keep_start(r: np.ndarray) -> np.ndarray:
    return np.concatenate([r[:1], r[:0:-1]])


def _nest_section(rings: list) -> tuple[tuple, tuple]:
    """Holes by even-odd nesting; outer rings positive, holes negative; parents of holes.

    Ring ``i`` lies inside ring ``j`` when ``|area j| > |area i|`` and most of ``i``'s points are
    inside ``j`` (even-odd test).  A ring inside an odd number of others is a hole; its parent is
    the smallest ring containing it.
    """
    from .rasterize import points_in_rings

    n = len(rings)
    areas = np.array([abs(shoelace_area(r)) for r in rings])
    inside = np.zeros((n, n), dtype=bool)  # inside[i, j]: ring i lies inside ring j
    lo = np.array([r.min(0) for r in rings]) if n else np.zeros((0, 2))
    hi = np.array([r.max(0) for r in rings]) if n else np.zeros((0, 2))
    for i in range(n):
        for j in range(n):
            if i == j or areas[j] <= areas[i]:
                continue
            # a ring inside another lies within its bounding box (up to a shared boundary)
            if np.any(lo[i] < lo[j] - 1e-9) or np.any(hi[i] > hi[j] + 1e-9):
                continue
            inside[i, j] = points_in_rings(rings[i], rings[j]).mean() > 0.5
    depth = inside.sum(1)
    contours, parents = [], []
    for i in range(n):
        r = rings[i]
        hole = depth[i] % 2 == 1
        if hole:
            cands = np.flatnonzero(inside[i])
            parents.append(int(cands[np.argmin(areas[cands])]))
        else:
            parents.append(-1)
        a = shoelace_area(r)
        if (a < 0) != hole:
            r = _reverse_keep_start(r)
        contours.append(r)
    return tuple(contours), tuple(parents)


def stack_from_rings(slices, *, z_tol: float = Z_TOLERANCE, meta: dict | None = None, source: str = "input") -> ContourStack:
    """Build a ContourStack from rings at heights: grouping, cleaning, nesting, orientation.

    Parameters
    ----------
    slices : iterable of (z, rings)
        ``rings`` a sequence of ``(k, 2)`` array-likes of physical ``(x, y)`` points, closed
        implicitly (a repeated closing point is dropped), either winding.
    z_tol : float
        Heights that differ by at most this much (chained) are one section; the section's height
        is their mean.  Slices may come in any order; sections come out sorted.
    meta : dict, optional
        Stored in ``ContourStack.meta``.
    source : str
        Named in error and warning messages.

    Returns
    -------
    ContourStack
        float64 rings, ``spacing = (1, 1)``, ``origin = (0, 0)``; per section, rings in input
        order, holes (inside an odd number of others) with negative shoelace area and their
        ``parents`` set to the smallest enclosing ring, outer rings with positive area.

    Raises
    ------
    ValueError
        Non-finite heights or coordinates, rings that are not ``(k, 2)``, or no ring left.

    Warns
    -----
    UserWarning
        Rings with fewer than 3 distinct points, or enclosing no area, are dropped, naming the
        slice and the count.
    """
    items = []
    for s, (z, rings) in enumerate(slices):
        try:
            zf = float(z)
        except (TypeError, ValueError):
            raise ValueError(f"{source}: slice {s}: expected a number for z; found {z!r}") from None
        if not math.isfinite(zf):
            raise ValueError(f"{source}: slice {s}: z must be finite; found {z!r}")
        for r, ring in enumerate(rings):
            try:
                arr = np.asarray(ring, dtype=np.float64)
            except (TypeError, ValueError):
                raise ValueError(f"{source}: slice {s} (z={zf:g}) ring {r}: expected a list of [x, y] pairs") from None
            if arr.size == 0:
                arr = arr.reshape(0, 2)
            if arr.ndim != 2 or arr.shape[1] != 2:
                raise ValueError(f"{source}: slice {s} (z={zf:g}) ring {r}: expected a (k, 2) list of [x, y] "
                                 f"points; found shape {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{source}: slice {s} (z={zf:g}) ring {r} holds NaN or infinite coordinates")
            items.append((zf, s, r, arr))
    if not items:
        raise ValueError(f"{source}: no contour found; expected at least one ring")
    items.sort(key=lambda t: t[0])
    groups, cur = [], [items[0]]
    for it in items[1:]:
        if it[0] - cur[-1][0] <= z_tol:
            cur.append(it)
        else:
            groups.append(cur)
            cur = [it]
    groups.append(cur)
    sections = []
    dropped_total = 0
    for g in groups:
        z = float(np.mean([it[0] for it in g]))
        g = sorted(g, key=lambda t: (t[1], t[2]))
        rings, dropped = [], 0
        for _, _, _, arr in g:
            r = _clean_ring(arr)
            if len(r) < 3 or shoelace_area(r) == 0.0:
                dropped += 1
                continue
            rings.append(r)
        if dropped:
            dropped_total += dropped
            warnings.warn(f"{source}: slice z={z:g}: dropped {dropped} contour(s) with fewer than 3 distinct points "
                          "or no enclosed area", UserWarning, stacklevel=3)
        if not rings:
            continue
        contours, parents = _nest_section(rings)
        sections.append(Section(z, contours, parents))
    if not sections:
        raise ValueError(f"{source}: no contour with 3 or more distinct points; nothing to mesh")
    m = dict(meta or {})
    m.setdefault("dropped_contours", dropped_total)
    return ContourStack(tuple(sections), spacing=(1.0, 1.0), origin=(0.0, 0.0), meta=m)


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
    p = _check_file(path, "contour")
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


def _select_roi(path: Path, rois: list[tuple[int, str, int]], roi):
    """Pick one of ``(number, name, n_contours)``; errors list what is available."""
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


def _read_rtstruct(path: Path, roi) -> ContourStack:
    pydicom = _require("pydicom")
    try:
        ds = pydicom.dcmread(str(path))
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
            data = np.asarray([float(v) for v in item.ContourData], dtype=np.float64)
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
    except Exception as exc:  # pydicom's InvalidDicomError, EOFError, struct.error, ...
        raise _wrap(path, "DICOM RTSTRUCT", exc) from None
    if skipped:
        warnings.warn(f"{str(path)!r}: ROI {name!r}: skipped contours that are not CLOSED_PLANAR: {skipped}",
                      UserWarning, stacklevel=3)
    slices = _planar_slices(path, name, contours3d)
    return stack_from_rings(slices, source=f"{path.name} ROI {name!r}",
                            meta={"source": str(path), "roi": name, "roi_number": num, "units": "mm"})


def _read_contours_npz(path: Path, roi) -> ContourStack:
    import zipfile

    try:
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
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise _wrap(path, "contour .npz", exc) from None
    except (zipfile.BadZipFile, EOFError, OSError, KeyError, zlib.error) as exc:
        raise _wrap(path, "contour .npz", exc) from None
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
    from .meshes import atomic_write

    return atomic_write(Path(path), contours_json_bytes(stack, name=name, units=units), force=force)


# ================================================================================================
# meshes
# ================================================================================================
MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off")


def load_mesh(path) -> Mesh:
    """Read a PLY/OBJ/STL/OFF mesh through trimesh, with vertices merged by position.

    The merge (``trimesh.Trimesh(v, f, process=False).merge_vertices(merge_tex=True,
    merge_norm=True)``) joins copies of a vertex that a file splits at UV or normal seams, so a
    closed surface reads as closed.  ``meta["source"]`` is the path.
    """
    p = _check_file(path, "mesh")
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"{str(p)!r}: cannot tell the mesh format; expected a suffix among "
                         f"{', '.join(MESH_SUFFIXES)}, found {p.suffix or 'none'!r}")
    import trimesh

    try:
        loaded = trimesh.load(str(p), force="mesh", process=False)
        v = np.asarray(loaded.vertices, dtype=np.float64)
        f = np.asarray(loaded.faces, dtype=np.int64)
    except Exception as exc:
        raise _wrap(p, f"{p.suffix} mesh", exc) from None
    if len(f) == 0:
        raise _bad(p, "a mesh with triangle faces", "no faces")
    tm = trimesh.Trimesh(v, f, process=False)
    tm.merge_vertices(merge_tex=True, merge_norm=True)
    return Mesh(np.asarray(tm.vertices), np.asarray(tm.faces), meta={"source": str(p)})


def _trimesh_contours_loader(file_obj, file_type=None, resolver=None, metadata=None, **kwargs):
    """trimesh loader for ``*.contours.json``: the stack meshed by :func:`contourmesh.rasterize.mesh_contour_stack`."""
    from .rasterize import mesh_contour_stack

    data = file_obj.read() if hasattr(file_obj, "read") else file_obj
    if isinstance(data, bytes):
        data = data.decode("utf-8")
    where = getattr(file_obj, "name", "<json>")
    try:
        doc = json.loads(data)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where!r}: expected a JSON document; found invalid JSON ({exc.msg})") from None
    if not (isinstance(doc, dict) and doc.get("format") == CONTOURS_FORMAT):
        if _PREVIOUS_JSON_LOADER is not None:
            import io as _io

            return _PREVIOUS_JSON_LOADER(_io.BytesIO(data.encode()), file_type=file_type, resolver=resolver,
                                         metadata=metadata, **kwargs)
        raise ValueError(f"{where!r}: expected a {CONTOURS_FORMAT!r} JSON file (the only JSON that loads as a mesh)")
    m = mesh_contour_stack(_stack_from_json_doc(doc, str(where)))
    return {"vertices": m.vertices, "faces": m.faces, "process": False,
            "metadata": {"contourmesh": {k: v for k, v in m.meta.items() if isinstance(v, (str, int, float))}}}


_PREVIOUS_JSON_LOADER = None


def register_trimesh_loader() -> None:
    """Make ``trimesh.load("x.contours.json")`` return our mesh of the contour stack.

    trimesh picks a loader from ``trimesh.exchange.load.mesh_loaders`` by the file's last suffix
    (``"json"``).  This adds a ``"json"`` loader that meshes files in the JSON contour format and
    hands any other JSON to the loader that was registered before (if any).  Idempotent.
    """
    global _PREVIOUS_JSON_LOADER
    from trimesh.exchange import load as _load

    current = _load.mesh_loaders.get("json")
    if current is _trimesh_contours_loader:
        return
    _PREVIOUS_JSON_LOADER = current
    _load.mesh_loaders["json"] = _trimesh_contours_loader


# ================================================================================================
# files as mesh sources
# ================================================================================================
def is_file_source(source) -> bool:
    """Whether ``contourmesh.mesh(source)`` should treat ``source`` as a file path.

    True for a ``Path``, and for a string that names an existing file or folder or ends with a suffix this
    module reads (so a missing file gives FileNotFoundError, not a shape-spec parse error).
    """
    if isinstance(source, Path):
        return True
    if not isinstance(source, str):
        return False
    name = source.lower()
    if name.endswith(VOLUME_SUFFIXES + CONTOUR_SUFFIXES):
        return True
    try:  # an existing directory too, so that it gets "is a directory", not a shape-spec error
        return Path(source).expanduser().exists()
    except (OSError, ValueError):
        return False


def is_contour_file(path) -> bool:
    """Whether a file holds a contour stack (``.json``, ``.dcm``, or an npz of ``<ROI>__points_mm``)."""
    p = Path(path)
    suffix = _suffix(p)
    if suffix in (".json", ".dcm"):
        return True
    if suffix == ".npz" and p.is_file():
        import zipfile

        try:
            with zipfile.ZipFile(p) as z:
                return any(n.endswith("__points_mm.npy") for n in z.namelist())
        except (zipfile.BadZipFile, OSError):
            return False
    if suffix not in VOLUME_SUFFIXES and p.is_file():
        with open(p, "rb") as fh:
            return fh.read(132)[128:132] == b"DICM"
    return False


def mesh_file(path, *, roi=None, pixel=None, label=None, threshold=None, axis: int = 0, polygon: str = "mlp",
              triangulation: str = "wiederhold", caps: str = "flat", progress: bool = False) -> Mesh:
    """Mesh a file: a contour stack (:func:`read_contours`) or a volume (:func:`read_volume`).

    Contour stacks go through :func:`contourmesh.rasterize.mesh_contour_stack` (``roi`` picks the
    ROI, ``pixel`` the raster size); volumes through :func:`contourmesh.volumes.volume_to_mesh`
    with the file's spacing and origin (``label``/``threshold`` select the object, ``axis`` the
    slicing axis).  ``meta["source"]`` is the path.
    """
    p = _check_file(path, "input")
    if is_contour_file(p):
        if label is not None or threshold is not None:
            raise ValueError(f"{str(p)!r} holds contours; label= and threshold= apply to volumes only")
        from .rasterize import mesh_contour_stack

        return mesh_contour_stack(read_contours(p, roi=roi), polygon=polygon, triangulation=triangulation,
                                  caps=caps, pixel=pixel, progress=progress)
    if roi is not None or pixel is not None:
        raise ValueError(f"{str(p)!r} holds a volume; roi= and pixel= apply to contour files only")
    from .volumes import volume_to_mesh

    vol, spacing, origin = read_volume(p, label=label, threshold=threshold)
    m = volume_to_mesh(vol, spacing=spacing, origin=origin, axis=axis, polygon=polygon,
                       triangulation=triangulation, caps=caps, progress=progress)
    meta = dict(m.meta, source=str(p), spacing=spacing)
    return Mesh(m.vertices, m.faces, P=m.P, meta=meta)
