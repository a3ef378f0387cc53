"""Readers and writers.

* :mod:`contourmesh.io.volumes`: volume files (``.npy .npz .tif .nii[.gz] .nrrd .vol .inr[.gz]``,
  DICOM through :mod:`contourmesh.io.dicom`: DICOM-SEG, image series, multi-frame images) and
  the volume writer;
* :mod:`contourmesh.io.contours`: contour stacks (DICOM RTSTRUCT, the JSON contour format,
  contour ``.npz``) and the JSON writer;
* meshes: :func:`load_mesh` here, and :func:`contourmesh.meshes.save_mesh` (``Mesh.save``).

Everything read is checked at the door: a bad file raises ``FileNotFoundError``,
``IsADirectoryError`` or ``ValueError`` naming the file, what was expected and what was found.
Nothing is ever unpickled.
"""

from .._files import MAX_VOXELS, check_file
from ..meshes import MESH_SUFFIXES, read_mesh_arrays, save_mesh
from ..stacks import Z_TOLERANCE, stack_from_rings
from ..types import Mesh
from .contours import (
    CONTOUR_SUFFIXES,
    CONTOURS_FORMAT,
    CONTOURS_VERSION,
    contours_json_bytes,
    is_contour_file,
    read_contours,
    write_contours_json,
)
from .volumes import VOLUME_SUFFIXES, Image, read_image, read_volume, write_volume


def load_mesh(path) -> Mesh:
    """Read a PLY/OBJ/STL/OFF mesh (vertices merged by position; see
    :func:`contourmesh.meshes.read_mesh_arrays`); ``meta["source"]`` is the path."""
    vertices, faces = read_mesh_arrays(path)
    return Mesh(vertices, faces, meta={"source": str(path)})

__all__ = [
    "read_volume", "read_image", "Image", "write_volume", "read_contours", "write_contours_json", "contours_json_bytes",
    "stack_from_rings", "load_mesh", "save_mesh", "is_contour_file", "check_file", "VOLUME_SUFFIXES",
    "CONTOUR_SUFFIXES", "MESH_SUFFIXES", "MAX_VOXELS", "CONTOURS_FORMAT", "CONTOURS_VERSION", "Z_TOLERANCE",
]
