"""Label volumes read piece by piece: Zarr (v2 and v3), ``.npy`` memory maps, HDF5 and dask arrays.

:func:`open_chunked` wraps a source in a :class:`ChunkedVolume`, which serves boxes
(``read((z0, z1), (y0, y1), (x0, x1))``) and z-slabs (``slabs()``) and never the whole array
unless asked for a box that covers it.  A ChunkedVolume pickles to its *description* (a path and
a kind, or the dask graph), not its data, so it can be sent to worker processes and Dask
workers, which reopen the store themselves.

Sources:

* a path to a Zarr store (a folder holding ``.zarray`` or ``zarr.json``; a group with one array
  is opened at that array, a group with several needs ``dataset=``);
* a path to a ``.npy`` file, opened with ``numpy.load(mmap_mode="r", allow_pickle=False)``: a file
  of Python objects is refused, never unpickled;
* a path to an HDF5 file (``.h5``, ``.hdf5``, ``.hdf``) with ``dataset=`` (or its only dataset),
  through h5py when it is installed;
* a ``zarr.Array``, a ``numpy.ndarray`` (including a memmap), or a ``dask.array.Array``.

Every source must be a 3D integer (or boolean) array indexed ``[z, y, x]``.
"""

from __future__ import annotations

import hashlib
import mmap
from pathlib import Path

import numpy as np

from .._optional import require

__all__ = ["ChunkedVolume", "open_chunked", "CHUNKED_SUFFIXES", "digest"]

#: Path suffixes read piece by piece (a Zarr store is recognised by its metadata file too).
CHUNKED_SUFFIXES = (".zarr", ".npy", ".h5", ".hdf5", ".hdf", ".n5")
_HDF5 = (".h5", ".hdf5", ".hdf")


def _zarr():
    return require("zarr", "scale")


def _is_zarr_dir(p: Path) -> bool:
    return p.is_dir() and any((p / f).is_file() for f in (".zarray", "zarr.json", ".zgroup"))


def _check_dtype(dtype, shape, where: str):
    dtype = np.dtype(dtype)
    if dtype.kind not in "iub":
        raise TypeError(f"{where}: expected an integer label volume; got dtype {dtype} "
                        "(mesh a greyscale volume with mesh_volume(threshold=...))")
    if len(shape) != 3:
        raise ValueError(f"{where}: expected a 3D array indexed [z, y, x]; got {len(shape)}D with shape {tuple(shape)}")
    if 0 in tuple(shape):
        raise ValueError(f"{where}: the array is empty (shape {tuple(shape)})")
    return dtype


class ChunkedVolume:
    """A 3D label array read box by box.  Build it with :func:`open_chunked`.

    Attributes
    ----------
    shape : tuple of int
    dtype : numpy.dtype
    chunks : tuple of int
        The store's chunk shape (for a memory map or HDF5 without chunks: a 64-slice slab).
    where : str
        The path, or a description of the in-memory array, for messages.
    """

    def __init__(self, kind: str, *, path: str | None = None, dataset: str | None = None, array=None):
        self.kind = kind
        self.path = path
        self.dataset = dataset
        self._array = array  # kept only for in-memory arrays and dask arrays (they pickle as themselves)
        self._handle = None
        arr = self._open()
        self.shape = tuple(int(s) for s in arr.shape)
        self.where = path if path is not None else f"a {kind} array of shape {self.shape}"
        self.dtype = _check_dtype(arr.dtype, self.shape, self.where)
        chunks = getattr(arr, "chunks", None)
        if kind == "dask":
            chunks = tuple(int(c[0]) for c in arr.chunks)
        if not chunks or len(chunks) != 3:
            chunks = (min(64, self.shape[0]), self.shape[1], self.shape[2])
        self.chunks = tuple(int(c) for c in chunks)

    # -- pickling: the description, never the data of a store ------------------------------------
    def __getstate__(self):
        state = dict(self.__dict__)
        state["_handle"] = None
        if self.kind in ("zarr", "npy", "hdf5"):
            state["_array"] = None
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)

    def _open(self):
        if self._handle is not None:
            return self._handle
        if self.kind == "npy":
            self._handle = np.load(self.path, mmap_mode="r", allow_pickle=False)
        elif self.kind == "zarr":
            zarr = _zarr()
            try:
                node = zarr.open(self.path, mode="r")
            except Exception as exc:
                raise ValueError(f"{self.path!r}: expected a readable Zarr store; {type(exc).__name__}: {exc}") from None
            if hasattr(node, "array_keys"):  # a group
                names = sorted(node.array_keys())
                if self.dataset is not None:
                    try:
                        node = node[self.dataset]
                    except KeyError:
                        raise ValueError(f"{self.path!r}: the Zarr group has no array {self.dataset!r}; its arrays "
                                         f"are {names}") from None
                    if hasattr(node, "array_keys"):
                        raise ValueError(f"{self.path!r}: {self.dataset!r} is a group, not an array")
                elif len(names) == 1:
                    node = node[names[0]]
                else:
                    raise ValueError(f"{self.path!r}: the Zarr group holds {len(names)} arrays {names}; "
                                     "name one with dataset=")
            self._handle = node
        elif self.kind == "hdf5":
            h5py = require("h5py", "scale")
            f = h5py.File(self.path, "r")
            names = []
            f.visititems(lambda n, obj: names.append(n) if isinstance(obj, h5py.Dataset) else None)
            name = self.dataset
            if name is None:
                if len(names) != 1:
                    raise ValueError(f"{self.path!r}: the HDF5 file holds {len(names)} datasets {names}; name one "
                                     "with dataset=")
                name = names[0]
            elif name not in f:
                raise ValueError(f"{self.path!r}: no dataset {name!r}; it holds {names}")
            self._handle = f[name]
        else:  # numpy or dask, held as themselves
            self._handle = self._array
        return self._handle

    def read(self, zr, yr=None, xr=None) -> np.ndarray:
        """The box ``[z0:z1, y0:y1, x0:x1]`` as an in-memory numpy array (ranges default to all)."""
        yr = (0, self.shape[1]) if yr is None else yr
        xr = (0, self.shape[2]) if xr is None else xr
        sl = tuple(slice(int(a), int(b)) for a, b in (zr, yr, xr))
        arr = self._open()
        if self.kind == "dask":
            out = arr[sl].compute(scheduler="sync")
        else:
            out = arr[sl]
        return np.ascontiguousarray(np.asarray(out))

    def slabs(self, depth: int | None = None):
        """``(z0, z1)`` ranges of ``depth`` slices (default: the store's chunk depth) covering the array."""
        depth = self.chunks[0] if depth is None else int(depth)
        if depth < 1:
            raise ValueError(f"slab depth must be at least 1; got {depth}")
        return [(z0, min(z0 + depth, self.shape[0])) for z0 in range(0, self.shape[0], depth)]

    def tiles(self, depth: int | None = None, max_voxels: int = 2**26):
        """``(z0, z1, y0, y1, x0, x1)`` boxes covering the array: slabs of ``depth`` slices (default:
        the store's chunk depth), each cut in y and x along the store's chunk grid into tiles of at
        most ``max_voxels`` voxels (a whole slab when it fits; never less than one chunk)."""
        slabs = self.slabs(depth)
        d = max(z1 - z0 for z0, z1 in slabs)
        ny, nx = self.shape[1], self.shape[2]
        cy, cx = min(self.chunks[1], ny), min(self.chunks[2], nx)
        ty, tx = ny, nx
        while d * ty * tx > max_voxels and (ty > cy or tx > cx):
            if tx > cx and (tx >= ty or ty <= cy):
                tx = max(cx, -(-(tx // 2) // cx) * cx)
            else:
                ty = max(cy, -(-(ty // 2) // cy) * cy)
        return [(z0, z1, y0, min(y0 + ty, ny), x0, min(x0 + tx, nx))
                for z0, z1 in slabs for y0 in range(0, ny, ty) for x0 in range(0, nx, tx)]

    def __repr__(self):
        return f"ChunkedVolume({self.kind}, {self.where!r}, shape={self.shape}, dtype={self.dtype}, chunks={self.chunks})"


def _check_npy(p: Path):
    with open(p, "rb") as fh:
        magic = fh.read(6)
        if magic != b"\x93NUMPY":
            raise ValueError(f"{str(p)!r}: expected a NumPy .npy file (starting with b'\\x93NUMPY'); found {magic!r}")
        fh.seek(0)
        major, minor = np.lib.format.read_magic(fh)
        reader = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
        shape, _fortran, dtype = reader(fh)
    if dtype.hasobject:
        raise ValueError(f"{str(p)!r}: the .npy file holds Python objects (dtype {dtype}); contourmesh never "
                         "unpickles data: save the labels as an integer array")
    return shape, dtype


def open_chunked(source, *, dataset: str | None = None) -> ChunkedVolume:
    """A :class:`ChunkedVolume` over ``source`` (a path, a zarr/numpy/dask array, or a ChunkedVolume).

    Raises
    ------
    FileNotFoundError
        A path that does not exist.
    TypeError
        A source of another type, or a non-integer array.
    ValueError
        A file that is not what its name says, a ``.npy`` of Python objects, a group or HDF5 file
        whose array is ambiguous, an array that is not 3D.
    """
    if isinstance(source, ChunkedVolume):
        return source
    if isinstance(source, (str, Path)):
        p = Path(source).expanduser()
        if not p.exists():
            raise FileNotFoundError(f"label volume {str(p)!r} does not exist")
        name = p.name.lower()
        if _is_zarr_dir(p) or (name.endswith((".zarr", ".n5")) and p.is_dir()):
            if not _is_zarr_dir(p):
                raise ValueError(f"{str(p)!r}: expected a Zarr store (a folder with .zarray, .zgroup or zarr.json); "
                                 "found none of them")
            return ChunkedVolume("zarr", path=str(p), dataset=dataset)
        if p.is_dir():
            raise IsADirectoryError(f"{str(p)!r} is a folder but not a Zarr store (no .zarray, .zgroup or zarr.json)")
        if name.endswith(".npy"):
            _check_npy(p)
            if dataset is not None:
                raise ValueError("dataset= does not apply to a .npy file (it holds one array)")
            return ChunkedVolume("npy", path=str(p))
        if name.endswith(_HDF5):
            return ChunkedVolume("hdf5", path=str(p), dataset=dataset)
        raise ValueError(f"{str(p)!r}: expected a Zarr store, a .npy file or an HDF5 file (.h5, .hdf5) to read "
                         f"piece by piece; other formats ({p.suffix or 'no suffix'}) are read whole by mesh_labels")
    if dataset is not None:
        raise ValueError("dataset= applies to a path of a Zarr group or an HDF5 file, not to an array")
    mod = type(source).__module__ or ""
    if mod.startswith("dask"):
        return ChunkedVolume("dask", array=source)
    if mod.startswith("zarr"):
        if hasattr(source, "array_keys"):
            raise TypeError("expected a zarr Array; got a Group (open its array, or pass the path with dataset=)")
        if getattr(source, "store", None) is not None and getattr(source.store, "root", None) is not None:
            root = Path(str(source.store.root))
            path = str(source.path) if getattr(source, "path", "") else None
            if root.is_dir():  # a store on disk: workers reopen it by its path
                return ChunkedVolume("zarr", path=str(root), dataset=path)
        return ChunkedVolume("numpy", array=source)  # an in-memory zarr array travels with the tasks
    if isinstance(source, np.memmap) and str(getattr(source, "filename", "") or "").lower().endswith(".npy"):
        try:
            shape, _ = _check_npy(Path(source.filename))
        except (OSError, ValueError):
            shape = None
        if shape is not None and tuple(shape) == source.shape and isinstance(source.base, mmap.mmap):
            return ChunkedVolume("npy", path=str(source.filename))  # workers reopen the file, not a copy
    if isinstance(source, np.ndarray):
        if source.dtype.hasobject:
            raise TypeError(f"expected an integer label volume; got dtype {source.dtype}")
        return ChunkedVolume("numpy", array=source)
    raise TypeError(f"cannot read a {type(source).__name__} piece by piece: expected a path (Zarr store, .npy, HDF5), "
                    "a zarr, numpy or dask array")


def digest(arr: np.ndarray) -> str:
    """A content hash of an array (its dtype, shape and bytes)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(str(arr.dtype.str).encode())
    h.update(repr(arr.shape).encode())
    h.update(np.ascontiguousarray(arr).view(np.uint8).reshape(-1))
    return h.hexdigest()
