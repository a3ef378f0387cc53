"""The volume validator: one set of checks for every array that is meshed or measured.

Volumes are indexed ``[z, y, x]`` with ``spacing = (dz, dy, dx)``; ``origin`` is the physical
``(x, y, z)`` of the centre of voxel ``[0, 0, 0]``.  Which voxels are the object:

* ``label=L``: the voxels equal to ``L``;
* ``threshold=T``: the voxels above ``T``;
* neither: a boolean array, or an array holding only 0 and 1, or exactly two values one of
  which is 0 (``0/255``, ``0/96``: the non-zero value is the object).  Anything else is an error
  that names the dtype and the range and asks for ``label=`` or ``threshold=``.
"""

from __future__ import annotations

import numpy as np

from ._kernels import njit

__all__ = ["check_volume_array", "check_spacing", "check_origin", "binary_label", "select_voxels", "binary_volume",
           "prepare_volume"]


def check_volume_array(volume, where: str = "volume") -> np.ndarray:
    """The array, after checking its dtype (real numbers or booleans), that it is 3D and not empty."""
    if isinstance(volume, np.ndarray) and volume.dtype == object:
        raise ValueError(f"{where} has dtype object; expected a numeric or boolean array")
    vol = np.asarray(volume)
    if vol.dtype == object or vol.dtype.kind in "OUSVMm":
        raise ValueError(f"{where} must be a numeric or boolean array; got dtype {vol.dtype}")
    if vol.dtype.kind == "c":
        raise ValueError(f"{where} must be real-valued; got complex dtype {vol.dtype}")
    if vol.ndim != 3:
        hint = " (a single image is one slice: add an axis, e.g. image[None])" if vol.ndim == 2 else ""
        raise ValueError(f"{where} must be a 3D array indexed [z, y, x]; got {vol.ndim}D with shape {vol.shape}{hint}")
    if 0 in vol.shape:
        raise ValueError(f"{where} is empty (shape {vol.shape})")
    return vol


def _finite(vol: np.ndarray, where: str) -> None:
    if vol.dtype.kind == "f" and not np.all(np.isfinite(vol)):
        bad = "NaN" if np.isnan(vol).any() else "inf"
        raise ValueError(f"{where} holds {bad} values; expected finite numbers")


def binary_label(vol: np.ndarray, where: str = "volume"):
    """For a volume given without ``label``/``threshold``: ``None`` if it is boolean or 0/1, else the
    object's value when it holds exactly two values one of which is 0; otherwise a ValueError."""
    if vol.dtype == bool:
        return None
    _finite(vol, where)
    lo, hi = vol.min(), vol.max()
    if lo >= 0 and hi <= 1 and (vol.dtype.kind != "f" or not np.any((vol != 0) & (vol != 1))):
        return None
    if lo == 0 or hi == 0:
        other = hi if lo == 0 else lo
        if not np.any((vol != 0) & (vol != other)):
            return other.item()
    raise ValueError(f"{where} holds values other than 0 and 1 (dtype {vol.dtype}, from {lo.item():g} to "
                     f"{hi.item():g}); pass label= to pick one label or threshold= to binarize")


def select_voxels(vol: np.ndarray, *, label=None, threshold=None, where: str = "volume") -> np.ndarray:
    """The boolean object mask of a checked volume (see the module docstring for the rule)."""
    if label is not None and threshold is not None:
        raise ValueError("give label= or threshold=, not both")
    if label is not None:
        if isinstance(label, (str, bytes, bool)) or not np.isscalar(label):
            raise TypeError(f"label must be a number; got {label!r}")
        mask = vol == label
        if not mask.any():
            raise ValueError(f"{where}: no voxel has label {label!r}")
        return mask
    if threshold is not None:
        if isinstance(threshold, (str, bytes, bool)) or not np.isscalar(threshold):
            raise TypeError(f"threshold must be a number; got {threshold!r}")
        if not np.isfinite(threshold):
            raise ValueError(f"threshold must be finite; got {threshold!r}")
        _finite(vol, where)
        return vol > threshold
    value = binary_label(vol, where)
    if value is not None:
        return vol == value
    return vol if vol.dtype == bool else vol.astype(bool)


def prepare_volume(volume, *, spacing=(1.0, 1.0, 1.0), z=None, axis: int = 0, label=None, threshold=None,
                   origin=(0.0, 0.0, 0.0), contiguous: bool = True):
    """Validate a volume and return ``(mask [z, y, x] bool, zs, (dy, dx), (ox, oy))``.

    ``label=L`` selects voxels equal to ``L``; ``threshold=T`` selects voxels ``> T``; without
    either the array must be boolean or hold only 0 and 1.  ``axis`` is the slicing axis (its
    spacing becomes ``dz``); ``z`` gives explicit slice positions (strictly increasing).
    ``origin`` is the physical ``(x, y, z)`` of voxel ``[0, 0, 0]``'s centre (after ``axis``).
    ``contiguous=False``: the mask may be a view of a boolean volume in another memory layout (a
    Fortran-ordered array, or ``axis`` other than 0) rather than a C-ordered copy of it, for a
    caller that reads it a slice at a time (the copy is the size of the volume).
    """
    vol = check_volume_array(volume)
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2; got {axis!r}")
    sp = check_spacing(spacing)
    mask = select_voxels(vol, label=label, threshold=threshold)
    org = check_origin(origin)
    if axis != 0:
        # the slicing axis goes first; the remaining two keep their order as (y, x)
        order = [axis] + [a for a in (0, 1, 2) if a != axis]
        mask = np.transpose(mask, order)
        sp = sp[order]
    if contiguous:
        mask = _c_order(mask)
    if not mask.any():
        raise ValueError("volume holds no foreground voxels (nothing to mesh)")
    nz = mask.shape[0]
    if z is None:
        zs = org[2] + sp[0] * np.arange(nz, dtype=np.float64)
    else:
        zs = np.asarray(z, dtype=np.float64).reshape(-1)
        if zs.shape != (nz,):
            raise ValueError(f"z must give one position per slice ({nz}); got {zs.shape[0]}")
        if not np.all(np.isfinite(zs)):
            raise ValueError("slice positions z must be finite")
        if nz > 1 and not np.all(np.diff(zs) > 0):
            bad = int(np.flatnonzero(np.diff(zs) <= 0)[0])
            raise ValueError(f"slice positions z must be strictly increasing; z[{bad}]={zs[bad]} >= z[{bad + 1}]={zs[bad + 1]}")
    return mask, zs, (float(sp[1]), float(sp[2])), (float(org[0]), float(org[1]))


def check_spacing(spacing) -> np.ndarray:
    """``(dz, dy, dx)`` as a float64 (3,) array, after checking three positive finite numbers."""
    try:
        sp = np.asarray(spacing, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"spacing must be three positive finite numbers (dz, dy, dx); got {spacing!r}") from None
    if sp.shape != (3,) or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
        raise ValueError(f"spacing must be three positive finite numbers (dz, dy, dx); got {spacing!r}")
    return sp


def check_origin(origin) -> np.ndarray:
    """``(x, y, z)`` as a float64 (3,) array, after checking three finite numbers."""
    try:
        org = np.asarray(origin, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"origin must be three finite numbers (x, y, z); got {origin!r}") from None
    if org.shape != (3,) or not np.all(np.isfinite(org)):
        raise ValueError(f"origin must be three finite numbers (x, y, z); got {origin!r}")
    return org


def binary_volume(volume, where: str = "volume") -> np.ndarray:
    """A checked volume's object mask, without label/threshold (boolean, 0/1, or two-valued)."""
    return select_voxels(check_volume_array(volume, where), where=where)


def _c_order(mask: np.ndarray) -> np.ndarray:
    """``np.ascontiguousarray(mask, dtype=bool)``; a Fortran-ordered boolean volume (as NIfTI
    readers and ``np.load`` of such files give, the liver benchmark's among them) is copied by
    :func:`_fortran_to_c` in tiles, about twice as fast as numpy's element-by-element copy."""
    if mask.dtype == bool and mask.ndim == 3 and mask.flags.f_contiguous and not mask.flags.c_contiguous:
        n0, n1, n2 = mask.shape
        flat = mask.ravel(order="F").view(np.uint8)  # (a view: the array's own memory order)
        return _fortran_to_c(flat, np.int64(n0), np.int64(n1), np.int64(n2)).view(bool)
    return np.ascontiguousarray(mask, dtype=bool)


#: Side of :func:`_fortran_to_c`'s tiles: 64 input lines of 64 bytes and 64 output lines stay in
#: the first-level cache while a tile is copied.
_TILE = 64


@njit(cache=True, nogil=True)
def _fortran_to_c(flat, n0, n1, n2):
    """The C-ordered ``(n0, n1, n2)`` array whose Fortran-ordered bytes are ``flat``: per index
    ``i1``, tiles of ``_TILE`` values of ``i2`` by ``_TILE`` of ``i0``, reading runs of ``i0``
    (contiguous in ``flat``) and writing each to its ``_TILE`` output lines."""
    out = np.empty((n0, n1, n2), np.uint8)
    for i1 in range(n1):
        for a2 in range(0, n2, _TILE):
            e2 = min(a2 + _TILE, n2)
            for a0 in range(0, n0, _TILE):
                e0 = min(a0 + _TILE, n0)
                for i2 in range(a2, e2):
                    base = n0 * (i1 + n1 * i2)
                    for i0 in range(a0, e0):
                        out[i0, i1, i2] = flat[base + i0]
    return out
