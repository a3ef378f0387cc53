"""A seeded synthetic cell volume: random ellipsoids and tori with exact areas, labelled uint32.

The volume is cut into cubic cells of ``cell`` voxels; each cell holds one object (an ellipsoid
or a ring torus, randomly sized, placed and rotated) that lies inside its cell, so no two objects
overlap.  Some objects (about ``touch`` of them) reach their cell's face along x, so neighbours
meet there: their voxels are face-adjacent, as cells in a tissue are.  The grid point
``(x, y, z) = (i, j, k)`` is voxel ``[k, j, i]`` (spacing 1, origin 0), and an object's voxels
are its Gauss digitization (:func:`contourmesh.digitize.gauss_volume`).  Each object's exact
area and volume come from :mod:`contourmesh.shapes`.

:func:`write_cells_zarr` writes the volume as a compressed Zarr array slab by slab (memory: one
slab of chunks); :func:`cells_volume` builds it in memory (for small tests).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import shapes as _shapes
from .digitize import gauss_volume

__all__ = ["Cell", "synthetic_cells", "cells_volume", "write_cells_zarr", "cells_table"]


@dataclass
class Cell:
    label: int
    shape: _shapes.Shape
    kind: str
    box: tuple  # (k0, k1, j0, j1, i0, i1) exclusive stops: the cell's voxels

    @property
    def area(self) -> float:
        return float(self.shape.area)

    @property
    def volume(self) -> float:
        return float(self.shape.volume)


def synthetic_cells(shape, *, cell: int = 32, seed: int = 0, torus_share: float = 0.3, touch: float = 0.6):
    """The objects of a synthetic cell volume of ``shape = (nz, ny, nx)`` voxels, one per cell.

    ``cell`` (>= 14) is the cell's edge in voxels; there are ``prod(n // cell)`` objects, labelled
    1, 2, ... in z, y, x order of their cells.
    """
    shape = tuple(int(s) for s in shape)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"shape must be three positive sizes (nz, ny, nx); got {shape}")
    if int(cell) != cell or cell < 14:
        raise ValueError(f"cell must be an integer of at least 14 voxels; got {cell!r}")
    n = [s // cell for s in shape]
    if min(n) < 1:
        raise ValueError(f"a volume of shape {shape} holds no cell of {cell} voxels")
    rng = np.random.default_rng(seed)
    out = []
    label = 0
    for k in range(n[0]):
        for j in range(n[1]):
            for i in range(n[2]):
                label += 1
                lo = np.array([i, j, k], float) * cell  # x, y, z of the cell's first voxel
                half = (cell - 1) / 2.0
                centre = lo + half
                rho = half - 0.6  # the object's bounding sphere stays inside the cell's voxels
                touching = rng.random() < touch
                kind = "torus" if rng.random() < torus_share else "ellipsoid"
                if kind == "torus" and cell < 22:
                    kind = "ellipsoid"  # too small a cell to resolve a torus's hole and tube
                if touching and kind == "ellipsoid":
                    # x semi-axis reaches the cell's faces along x; rotation about x keeps that extent
                    jit = rng.uniform(-0.3, 0.3, 3) * np.array([0.0, 1.0, 1.0])
                    a = half + 0.45
                    b = rng.uniform(0.45, 0.8) * (rho - 0.3)
                    c = rng.uniform(0.6, 1.0) * b
                    rot = _shapes.rotation_from_euler(rng.uniform(0, 180), 0.0, 0.0)
                    s = _shapes.Ellipsoid(a, b, c, center=tuple(centre + jit), rotation=rot)
                else:
                    jit = rng.uniform(-1.0, 1.0, 3)
                    r_max = rho - np.abs(jit).max()
                    rot = _shapes.rotation_from_euler(*rng.uniform(0, 180, 3))
                    if kind == "ellipsoid":
                        a = rng.uniform(0.6, 1.0) * r_max
                        b = rng.uniform(0.55, 1.0) * a
                        c = max(rng.uniform(0.5, 1.0) * b, 3.0)
                        s = _shapes.Ellipsoid(a, b, c, center=tuple(centre + jit), rotation=rot)
                    else:
                        r = max(rng.uniform(0.22, 0.33) * r_max, 2.5)
                        R = rng.uniform(0.95, 1.0) * (r_max - r)
                        s = _shapes.Torus(R, r, center=tuple(centre + jit), rotation=rot)
                box = (k * cell, (k + 1) * cell, j * cell, (j + 1) * cell, i * cell, (i + 1) * cell)
                out.append(Cell(label, s, kind, box))
    return out


def _paste(slab: np.ndarray, z0: int, c: Cell, mask: np.ndarray, origin) -> None:
    """Write ``c``'s digitization (``mask`` at grid ``origin``) into ``slab`` (slices ``z0:z0+len``),
    clipped to its cell and the slab."""
    i0, j0, k0 = (int(round(o)) for o in origin)
    K0, K1, J0, J1, I0, I1 = c.box
    lo = [max(k0, K0, z0), max(j0, J0), max(i0, I0)]
    hi = [min(k0 + mask.shape[0], K1, z0 + slab.shape[0]), min(j0 + mask.shape[1], J1, slab.shape[1]),
          min(i0 + mask.shape[2], I1, slab.shape[2])]
    if any(b <= a for a, b in zip(lo, hi)):
        return
    m = mask[lo[0] - k0:hi[0] - k0, lo[1] - j0:hi[1] - j0, lo[2] - i0:hi[2] - i0]
    view = slab[lo[0] - z0:hi[0] - z0, lo[1]:hi[1], lo[2]:hi[2]]
    view[m] = c.label


def _slabs(shape, cells, depth: int):
    cache = {}
    for z0 in range(0, shape[0], depth):
        z1 = min(z0 + depth, shape[0])
        slab = np.zeros((z1 - z0, shape[1], shape[2]), np.uint32)
        for c in cells:
            if c.box[0] < z1 and c.box[1] > z0:
                if c.label not in cache:
                    cache[c.label] = gauss_volume(c.shape, 1.0, pad=0)
                _paste(slab, z0, c, *cache[c.label])
        for lab in [lab for lab in cache if cells[lab - 1].box[1] <= z1]:
            del cache[lab]  # done with this object
        yield z0, z1, slab


def cells_volume(shape, cells) -> np.ndarray:
    """The label volume in memory (uint32)."""
    return np.concatenate([s for _, _, s in _slabs(tuple(shape), cells, 64)], axis=0)


def write_cells_zarr(path, shape, cells, *, chunks=(64, 128, 128), zarr_format: int = 3, level: int = 3):
    """Write the label volume to a new compressed Zarr array at ``path``, one slab of chunks at a time."""
    from ._optional import require

    zarr = require("zarr", "scale")
    shape = tuple(int(s) for s in shape)
    chunks = tuple(min(int(c), s) for c, s in zip(chunks, shape))
    if zarr_format == 3:
        from zarr.codecs import BloscCodec

        compressors = [BloscCodec(cname="zstd", clevel=level, shuffle="bitshuffle")]
        arr = zarr.create_array(path, shape=shape, chunks=chunks, dtype="uint32", compressors=compressors,
                                fill_value=0, zarr_format=3)
    else:
        from numcodecs import Blosc

        arr = zarr.create_array(path, shape=shape, chunks=chunks, dtype="uint32",
                                compressors=Blosc(cname="zstd", clevel=level, shuffle=Blosc.BITSHUFFLE),
                                fill_value=0, zarr_format=2)
    for z0, z1, slab in _slabs(shape, cells, chunks[0]):
        arr[z0:z1] = slab
    return arr


def cells_table(cells) -> list:
    """One dict per object: label, kind, parameters, exact area and volume."""
    rows = []
    for c in cells:
        s = c.shape
        params = {"a": s.a, "b": s.b, "c": s.c} if c.kind == "ellipsoid" else {"R": s.R, "r": s.r}
        rows.append(dict(label=c.label, kind=c.kind, **{k: float(v) for k, v in params.items()},
                         cx=float(s.center[0]), cy=float(s.center[1]), cz=float(s.center[2]),
                         area=c.area, volume=c.volume))
    return rows
