"""Checks shared by every reader: file paths, suffixes, declared sizes, optional packages."""

from __future__ import annotations

import contextlib
from pathlib import Path

from ._optional import require

__all__ = ["check_file", "MAX_VOXELS", "VOLUME_SUFFIXES"]

#: File suffixes the volume reader understands.
VOLUME_SUFFIXES = (".npy", ".npz", ".tif", ".tiff", ".nii", ".nii.gz", ".vol", ".inr", ".inr.gz", ".nrrd", ".nhdr", ".dcm")

#: Largest volume (voxels) a file header may declare; larger headers are refused before allocating.
MAX_VOXELS = 2**32


_PIP_NAMES = {"nrrd": "pynrrd"}


def _require(module: str):
    """An optional file reader (the ``[io]`` extra), or MissingDependency naming what to install."""
    return require(module, "io", _PIP_NAMES.get(module))


def _suffix(path: Path) -> str:
    name = path.name.lower()
    for double in (".nii.gz", ".inr.gz", ".contours.json"):
        if name.endswith(double):
            return double if double != ".contours.json" else ".json"
    return path.suffix.lower()


def check_file(path, what: str) -> Path:
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


_DEFLATE_MAX_RATIO = 1032


def _wrap(path: Path, kind: str, exc: BaseException) -> ValueError:
    msg = str(exc) or type(exc).__name__
    return ValueError(f"{str(path)!r}: expected a readable {kind} file; the file is truncated or corrupt ({msg})")


@contextlib.contextmanager
def _reading(path: Path, kind: str, errors=(Exception,)):
    """Within it, an error of ``errors`` raised while reading ``path`` as a ``kind`` file becomes the
    ValueError of :func:`_wrap`; a ValueError that already names the file passes unchanged."""
    try:
        yield
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise _wrap(path, kind, exc) from None
    except errors as exc:
        raise _wrap(path, kind, exc) from None
