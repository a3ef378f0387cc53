"""contourmesh: closed triangle meshes and surface areas from serial cross-sections.

The pipeline (Wiederhold & Villafuerte 2009)::

    source (analytic shape | contour stack)
      -> ContourStack (sections at heights z, each with its closed digital 4-contours)
      -> polygons (each contour -> DSS polygon | MLP | the contour itself)
      -> bands between consecutive sections (wiederhold | greedy | optimal) + caps
      -> Mesh (vertices, faces) -> area, volume, P, checks -> trimesh / Open3D / PyMeshLab / files

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

from .types import ContourStack, Mesh, Section, shoelace_area
from .surface import mesh, stack_to_mesh
from .io import register_trimesh_loader

try:  # trimesh.load_mesh("x.contours.json") returns our mesh of the contour stack
    register_trimesh_loader()
except ImportError:  # pragma: no cover - trimesh is a core dependency
    pass

__version__ = "0.1.0"

__all__ = ["mesh", "stack_to_mesh", "register_trimesh_loader", "Mesh", "ContourStack", "Section", "shoelace_area", "__version__"]
