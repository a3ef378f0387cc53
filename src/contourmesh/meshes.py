"""Adapters between :class:`contourmesh.Mesh` and trimesh, Open3D, PyMeshLab, and mesh files.

Open3D and PyMeshLab are imported lazily; a missing one raises an ImportError that says what to
install.  Files are written atomically: to a temporary file in the target folder, then renamed.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ._files import _bad, _wrap, check_file
from ._optional import require

if TYPE_CHECKING:  # annotations only: the adapters take any object with vertices and faces
    from .types import Mesh

__all__ = ["to_trimesh", "to_open3d", "to_pymeshlab", "save_mesh", "atomic_write", "MESH_FORMATS"]

MESH_FORMATS = ("ply", "obj", "stl", "off")


def _require(module: str):
    """Open3D or PyMeshLab (the ``[compare]`` extra), or MissingDependency naming what to install."""
    return require(module, "compare")


def to_trimesh(mesh: Mesh):
    """A ``trimesh.Trimesh`` sharing our vertices and faces (no processing, no merging)."""
    import trimesh

    return trimesh.Trimesh(vertices=mesh.vertices.copy(), faces=mesh.faces.copy(), process=False)



def to_open3d(mesh: Mesh):
    """An ``open3d.geometry.TriangleMesh``."""
    o3d = _require("open3d")
    m = o3d.geometry.TriangleMesh()
    m.vertices = o3d.utility.Vector3dVector(mesh.vertices)
    m.triangles = o3d.utility.Vector3iVector(mesh.faces.astype(np.int32))
    return m


def to_pymeshlab(mesh: Mesh):
    """A ``pymeshlab.MeshSet`` holding the mesh as its current mesh."""
    pymeshlab = _require("pymeshlab")
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=mesh.faces.astype(np.int32)))
    return ms


def atomic_write(path, data: bytes, *, force: bool = True) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    A process killed mid-write leaves the old file (or none), never a partial one.  With
    ``force=False`` an existing file is an error.
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"output path {str(path)!r} is a directory, expected a file name")
    if path.exists() and not force:
        raise FileExistsError(f"output file {str(path)!r} already exists (use force / --force to overwrite)")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.exists():
        raise FileNotFoundError(f"output folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise PermissionError(f"output folder {str(folder)!r} is not writable")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        # mkstemp makes the file private (0600); give it the usual permissions (0666 & ~umask)
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


def mesh_bytes(mesh: Mesh, file_type: str) -> bytes:
    """Serialise a mesh to ``ply`` (binary), ``obj``, ``stl`` (binary) or ``off``, deterministically."""
    file_type = file_type.lower().lstrip(".")
    if file_type not in MESH_FORMATS:
        raise ValueError(f"unknown mesh format {file_type!r}; expected one of {', '.join(MESH_FORMATS)}")
    if file_type == "off":
        # Written here so that float formatting is full precision and stable.
        lines = ["OFF", f"{len(mesh.vertices)} {len(mesh.faces)} 0"]
        lines += [f"{x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist()]
        lines += [f"3 {a} {b} {c}" for a, b, c in mesh.faces.tolist()]
        return ("\n".join(lines) + "\n").encode()
    import io

    from trimesh.exchange.export import export_mesh

    buf = io.BytesIO()
    tm = to_trimesh(mesh)
    if file_type == "obj":
        data = export_mesh(tm, None, file_type="obj", include_normals=False, include_texture=False, header=None)
        return data.encode() if isinstance(data, str) else data
    export_mesh(tm, buf, file_type=file_type)
    return buf.getvalue()


def save_mesh(mesh: Mesh, path, *, force: bool = True) -> Path:
    """Write a mesh file chosen by the path's suffix (``.ply``, ``.obj``, ``.stl``, ``.off``), atomically."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"output path {str(path)!r} is a directory, expected a mesh file name")
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in MESH_FORMATS:
        raise ValueError(
            f"cannot tell the mesh format of {str(path)!r}: expected a suffix among "
            f"{', '.join('.' + s for s in MESH_FORMATS)}, found {path.suffix or 'none'!r}"
        )
    return atomic_write(path, mesh_bytes(mesh, suffix), force=force)


MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off")


def read_mesh_arrays(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a PLY/OBJ/STL/OFF mesh through trimesh, with vertices merged by position.

    The merge (``trimesh.Trimesh(v, f, process=False).merge_vertices(merge_tex=True,
    merge_norm=True)``) joins copies of a vertex that a file splits at UV or normal seams, so a
    closed surface reads as closed.  Returns ``(vertices (n, 3) float64, faces (m, 3) int64)``;
    :func:`contourmesh.io.load_mesh` wraps them as a :class:`~contourmesh.types.Mesh`.
    """
    p = check_file(path, "mesh")
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
    return np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces, dtype=np.int64)
