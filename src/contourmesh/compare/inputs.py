"""Inputs of a comparison: analytic shapes and voxelized meshes, each at a size and a repeat.

An :class:`Input` is one thing every method of a comparison sees: a binary volume (indexed
``[z, y, x]``, with ``spacing`` and ``origin``) and, for analytic shapes, the placed
:class:`~contourmesh.shapes.Shape` itself.  Both are built lazily (:meth:`Input.volume`,
:meth:`Input.shape`), in the process that runs the method, so that an input is a few strings and
numbers that pickle cheaply to a worker.

Shapes
------
``size`` is the shape's scale parameter(s) in grid units (``"20"`` for a sphere of radius 20,
``"10,6"`` for the spheroid ``a=10, b=6``).  Repeat ``r`` of a size draws, from
``numpy.random.default_rng([seed, crc32(name|size), r])`` (a sub-seed that depends only on the
shape, the size and the repeat, so adding sizes to a spec leaves the other inputs unchanged):

* with ``offset``, a centre uniform in the unit voxel ``[0, h)**3`` (a random sub-voxel position);
* with ``rotate``, a uniformly random rotation (``scipy.spatial.transform.Rotation.random``).

Digitizations of a shape for the volume methods:

``gauss``         the grid points strictly inside (:func:`contourmesh.digitize.gauss_volume`);
``outer-jordan``  the 3-D outer Jordan digitization: the closed grid cubes with at least one
                  corner strictly inside (the Gauss set dilated by a 2x2x2 box), a voxel per cube,
                  centred half a grid step off the grid points.

Our method on a shape input meshes the shape itself (``contourmesh.mesh(shape, h=h)``): its outer
Jordan contours are traced around ``I`` = the grid points strictly inside each slice, which is
exactly slice ``k`` of the Gauss volume, so ours and the volume methods see the same data.

Meshes
------
A closed mesh file (path relative to the data folder: env ``CONTOURMESH_DATA``, default
``../shared/data`` next to the repository), merged by position
(``trimesh.Trimesh(v, f, process=False).merge_vertices(merge_tex=True, merge_norm=True)``) and
voxelized at ``N`` voxels across its largest extent (:func:`contourmesh.voxelize.voxelize_mesh`);
``size`` is ``N`` and ``area_true`` is the mesh's area in its own units (the volume's spacing is
in the same units).  Optional ``offset`` / ``rotate`` move the mesh by a random sub-voxel offset
and rotation before voxelizing.  ``placement`` says what the random draw depends on:
``"per-resolution"`` (the default) draws it from the mesh's name, ``N`` and the repeat, so every
resolution sees other placements; ``"per-repeat"`` draws it from the name and the repeat only, so
repeat ``r`` is the same rotation and the same offset (in voxels) at every ``N`` (a convergence
study of one rotated object).  A missing file gives an input whose :attr:`Input.error` says so;
its rows get status ``"no-data"``.
"""

from __future__ import annotations

import hashlib
import math
import os
import zlib
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from ..digitize import gauss_volume
from ..shapes import SHAPES, parse_shape_spec
from ..voxelize import voxelize_mesh

__all__ = ["Input", "DIGITIZATIONS", "PLACEMENTS", "data_dir", "shape_inputs", "mesh_inputs", "load_closed_mesh", "sub_rng"]

DIGITIZATIONS = ("gauss", "outer-jordan")

#: What the random placement of a mesh input depends on (see the module docstring).
PLACEMENTS = ("per-resolution", "per-repeat")


def data_dir() -> Path:
    """The shared data folder: env ``CONTOURMESH_DATA``, else ``../shared/data`` beside the repository."""
    env = os.environ.get("CONTOURMESH_DATA")
    if env:
        return Path(env)
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "pyproject.toml").is_file():
            return parent.parent / "shared" / "data"
    return Path.cwd().parent / "shared" / "data"


def sub_rng(seed: int, name: str, size: str, repeat: int) -> np.random.Generator:
    """The random generator of repeat ``repeat`` of ``name`` at ``size`` (a deterministic sub-seed)."""
    tag = zlib.crc32(f"{name}|{size}".encode())
    return np.random.default_rng([int(seed), int(tag), int(repeat)])


def _random_rotation(rng) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=rng).as_matrix()


# A small per-process cache of built volumes: consecutive rows usually share their input.
_VOLUMES: "OrderedDict[str, tuple]" = OrderedDict()
_VOLUME_CACHE_SIZE = 2


@dataclass(frozen=True)
class Input:
    """One input of a comparison (see the module docstring).

    Attributes
    ----------
    kind : {"shape", "mesh"}
    name : str
        ``"sphere"``, ``"torus"``, ``"bunny"``, ...
    size : str
        The size label: the shape's scale parameter(s) joined by ``","``, or the resolution N.
    repeat : int
        Repeat number (random placement), from 0.
    area_true : float or None
        The exact area (shapes) or the mesh's area (meshes); None when the data is missing.
    source : str
        The placed shape's spec string (:func:`contourmesh.shapes.parse_shape_spec`) or the mesh
        path relative to the data folder.
    digitization : str
        ``"gauss"`` or ``"outer-jordan"`` (shapes), ``"voxelize"`` (meshes).
    h : float
        Grid spacing (shapes); meshes get ``h = extent / N``.
    size_value : float
        A number for plots and ``max_size``: the largest size parameter, or N.
    offset, rotation : tuple
        Mesh placement: offset in voxels (3) and row-major rotation (9), empty when none.
    fingerprint : str
        sha256 prefix of the mesh file (part of the cache key); empty for shapes.
    error : str or None
        Why the input cannot be built (rows say ``"no-data"``).
    """

    kind: str
    name: str
    size: str
    repeat: int
    area_true: Optional[float]
    source: str
    digitization: str
    h: float = 1.0
    size_value: float = 0.0
    offset: tuple = ()
    rotation: tuple = ()
    fingerprint: str = ""
    error: Optional[str] = None
    data_root: str = field(default="", compare=False)

    def __post_init__(self):
        if self.kind not in ("shape", "mesh"):
            raise ValueError(f"Input kind must be 'shape' or 'mesh'; got {self.kind!r}")

    @property
    def key(self) -> dict:
        """What identifies the input's data (for the cache key)."""
        return {"kind": self.kind, "name": self.name, "size": self.size, "repeat": self.repeat,
                "source": self.source, "digitization": self.digitization, "h": self.h,
                "offset": list(self.offset), "rotation": list(self.rotation), "fingerprint": self.fingerprint}

    @property
    def key_text(self) -> str:
        import json

        return json.dumps(self.key, sort_keys=True)

    def shape(self):
        """The placed analytic shape (shape inputs only)."""
        if self.kind != "shape":
            raise ValueError(f"input {self.name!r} is a {self.kind}, not an analytic shape")
        return parse_shape_spec(self.source)

    def volume(self):
        """``(volume bool [z, y, x], spacing (dz, dy, dx), origin (x0, y0, z0))``, built once per process."""
        if self.error:
            raise FileNotFoundError(self.error)
        k = self.key_text
        if k in _VOLUMES:
            _VOLUMES.move_to_end(k)
            return _VOLUMES[k]
        out = self._build_volume()
        _VOLUMES[k] = out
        while len(_VOLUMES) > _VOLUME_CACHE_SIZE:
            _VOLUMES.popitem(last=False)
        return out

    def _build_volume(self):
        if self.kind == "shape":
            vol, origin = gauss_volume(self.shape(), self.h)
            h = float(self.h)
            if self.digitization == "outer-jordan":
                g = np.pad(vol, 1)
                nz, ny, nx = (s - 1 for s in g.shape)
                cells = np.zeros((nz, ny, nx), dtype=bool)
                for dz in (0, 1):
                    for dy in (0, 1):
                        for dx in (0, 1):
                            cells |= g[dz:dz + nz, dy:dy + ny, dx:dx + nx]
                # cell between padded grid points p and p + 1: centre at grid point (p - 1) + 1/2
                origin = tuple(float(o) - h / 2 for o in origin)
                vol = cells
            elif self.digitization != "gauss":
                raise ValueError(f"unknown digitization {self.digitization!r}; expected one of {DIGITIZATIONS}")
            return vol, (h, h, h), tuple(float(o) for o in origin)
        v, f = load_closed_mesh(Path(self.data_root) / self.source)
        v = _place(v, self.rotation, ())
        # the offset is in voxels of the final grid: h = largest extent / N (rotation first)
        h = float((v.max(0) - v.min(0)).max()) / int(self.size)
        if self.offset:
            v = v + np.asarray(self.offset) * h
        return voxelize_mesh(v, f, int(self.size))

    def label(self) -> str:
        return f"{self.name} {self.size} #{self.repeat}"


def _place(v, rotation, offset):
    if rotation:
        v = v @ np.asarray(rotation, dtype=np.float64).reshape(3, 3).T
    if offset:
        v = v + np.asarray(offset)
    return v


def load_closed_mesh(path):
    """Vertices and faces of a mesh file, merged by position (UV / normal seams closed)."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"mesh file {str(path)!r} does not exist")
    tm = trimesh.load(str(path), force="mesh", process=False)
    tm = trimesh.Trimesh(np.asarray(tm.vertices), np.asarray(tm.faces), process=False)
    tm.merge_vertices(merge_tex=True, merge_norm=True)
    return np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces, dtype=np.int64)


def _size_label(values) -> str:
    return ",".join(f"{v:g}" for v in values)


def shape_inputs(name: str, sizes, *, digitization: str = "gauss", repeats: int = 1, seed: int = 0,
                 offset: bool = True, rotate: bool = False, h: float = 1.0, fixed: dict | None = None) -> list:
    """The inputs of one analytic shape at every size and repeat.

    Parameters
    ----------
    name : str
        A shape of :data:`contourmesh.shapes.SHAPES` (``"sphere"``, ``"spheroid"``, ``"torus"``, ...).
    sizes : sequence
        Each a number or a sequence of numbers: the shape's size parameters in order
        (``Sphere: r``; ``Spheroid: a, b``; ``Torus: R, r``; ``Ellipsoid: a, b, c``), in grid units
        times ``h``.
    fixed : dict, optional
        Further size parameters fixed for every size (e.g. ``{"height": 30}``).
    """
    if name not in SHAPES:
        raise ValueError(f"unknown shape {name!r}; expected one of {', '.join(SHAPES)}")
    if digitization not in DIGITIZATIONS:
        raise ValueError(f"shape digitization must be one of {DIGITIZATIONS}; got {digitization!r}")
    cls = SHAPES[name]
    fixed = dict(fixed or {})
    free = [p for p in cls._param_names if p not in fixed]
    out = []
    for s in sizes:
        vals = [float(x) for x in (s if isinstance(s, (list, tuple)) else [s])]
        if len(vals) != len(free):
            raise ValueError(f"a {name} size gives {', '.join(free)} ({len(free)} numbers); got {s!r}")
        if not all(math.isfinite(x) and x > 0 for x in vals):
            raise ValueError(f"{name} sizes must be positive numbers; got {s!r}")
        label = _size_label(vals)
        params = dict(zip(free, vals))
        params.update(fixed)
        for r in range(int(repeats)):
            rng = sub_rng(seed, name, label, r)
            centre = rng.uniform(0.0, 1.0, 3) * h if offset else np.zeros(3)
            rot = _random_rotation(rng) if rotate else None
            shape = cls(**params, center=centre, rotation=rot)
            out.append(Input(kind="shape", name=name, size=label, repeat=r, area_true=float(shape.area),
                             source=shape.spec, digitization=digitization, h=float(h), size_value=max(vals)))
    return out


def _fingerprint(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def mesh_inputs(path: str, resolutions, *, name: str | None = None, repeats: int = 1, seed: int = 0,
                offset: bool = False, rotate: bool = False, root=None, placement: str = "per-resolution") -> list:
    """The inputs of one closed mesh file (relative to the data folder ``root``) at every resolution.

    ``placement``: ``"per-resolution"`` (a random offset / rotation drawn for each resolution and
    repeat) or ``"per-repeat"`` (the same draw at every resolution for a given repeat).
    """
    if placement not in PLACEMENTS:
        raise ValueError(f"mesh placement must be one of {PLACEMENTS}; got {placement!r}")
    root = Path(root) if root is not None else data_dir()
    name = name or Path(path).stem
    full = root / path
    error, area, fp = None, None, ""
    if not full.is_file():
        error = (f"mesh file {str(full)!r} not found (data folder {str(root)!r}; "
                 "set CONTOURMESH_DATA to the folder that holds it)")
    else:
        import trimesh

        v, f = load_closed_mesh(full)  # an open mesh is refused later, by voxelize_mesh (status "failed")
        area = float(trimesh.Trimesh(v, f, process=False).area)
        fp = _fingerprint(full)
    out = []
    for n in resolutions:
        if isinstance(n, bool) or int(n) != n or n < 2:
            raise ValueError(f"mesh resolutions are integers >= 2 (voxels across the largest extent); got {n!r}")
        for r in range(int(repeats)):
            rng = sub_rng(seed, name, str(int(n)) if placement == "per-resolution" else "placement", r)
            off = tuple(float(x) for x in rng.uniform(0.0, 1.0, 3)) if offset else ()
            rot = tuple(float(x) for x in _random_rotation(rng).ravel()) if rotate else ()
            out.append(Input(kind="mesh", name=name, size=str(int(n)), repeat=r, area_true=area, source=str(path),
                             digitization="voxelize", h=0.0, size_value=float(n), offset=off, rotation=rot,
                             fingerprint=fp, error=error, data_root=str(root)))
    return out
