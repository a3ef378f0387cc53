"""contourmesh: closed triangle meshes and surface areas from serial cross-sections.

The pipeline (Wiederhold & Villafuerte 2009)::

    source (analytic shape | contour stack | volume | file)
      -> ContourStack (sections at heights z, each with its closed digital 4-contours)
      -> polygons (each contour -> DSS polygon | MLP | the contour itself)
      -> bands between consecutive sections (wiederhold | greedy | optimal | arclength) + caps
      -> Mesh (vertices, faces) -> area, volume, P, checks -> trimesh / Open3D / PyMeshLab / files

The names below are imported on first use, so ``import contourmesh`` is cheap and changes no
other library.

Example
-------
>>> import contourmesh
>>> from contourmesh.shapes import Sphere
>>> m = contourmesh.mesh(Sphere(20, center=(0.31, 0.17, 0.43)), polygon="mlp")
>>> abs(m.area / m.meta["area_true"] - 1) < 0.02
True
>>> m.checks()["ok"]
True
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_LAZY = {
    "mesh": "api", "mesh_shape": "api", "mesh_stack": "api", "mesh_volume": "api", "mesh_file": "api",
    "stack_to_mesh": "surface", "volume_to_mesh": "volumes",
    "Mesh": "types", "ContourStack": "types", "Section": "types", "shoelace_area": "geometry",
    "read_volume": "io", "read_contours": "io", "load_mesh": "io",
    "register_trimesh_loader": "trimesh_plugin", "unregister_trimesh_loader": "trimesh_plugin",
    "ContourMeshError": "errors", "InapplicableOption": "errors", "LostContourWarning": "errors",
    "RasterFallbackWarning": "errors",
    "mesh_labels": "api", "mesh_labels_chunked": "scale", "scan_labels": "scale",
}

__all__ = sorted(_LAZY) + ["__version__"]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'contourmesh' has no attribute {name!r}")


def __dir__():
    return __all__
