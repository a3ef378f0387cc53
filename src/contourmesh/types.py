"""Core data types: contours, sections, contour stacks and meshes.

Conventions (stated once, checked at the boundary):

* A *contour* is a ``(k, 2)`` array of grid points ``(x, y)``, closed implicitly (the last
  point joins the first).  Outer contours have a **positive shoelace area** in raw ``(x, y)``
  numbers; this is the paper's "clockwise with the y axis pointing down".  Holes run the
  other way (negative shoelace area).
* A *polygon* is a contour simplified by a polygonizer (DSS, MLP, or the contour itself);
  it keeps the orientation and the start point of its contour.
* A *section* is one slicing plane at height ``z`` with its contours.
* Mesh vertices are ``(x, y, z)`` float64 in physical units, faces ``(m, 3)`` int64, oriented
  so that normals point out of the enclosed solid (positive volume).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from .geometry import shoelace_area
from .measure import mesh_checks, mesh_volume, surface_area, triangle_areas
from .meshes import save_mesh, to_open3d, to_pymeshlab, to_trimesh

__all__ = ["Section", "ContourStack", "Mesh", "shoelace_area"]


@dataclass(frozen=True)
class Section:
    """One slicing plane: its height and its closed contours.

    ``contours[i]`` is a ``(k, 2)`` int64 array of grid points (or float64 for real-valued
    contours read from files).  ``parents[i]`` is ``-1`` for an outer contour and the index of
    the enclosing outer contour for a hole.
    """

    z: float
    contours: tuple = ()
    parents: tuple = ()

    def __post_init__(self):
        if not self.parents and self.contours:  # no nesting given: every contour is an outer one
            object.__setattr__(self, "parents", tuple([-1] * len(self.contours)))
        elif len(self.parents) != len(self.contours):
            raise ValueError(f"Section at z={self.z}: parents must give one entry per contour "
                             f"({len(self.contours)}); got {len(self.parents)}")


@dataclass(frozen=True)
class ContourStack:
    """Sections at increasing heights, in grid units within a slice.

    ``spacing = (dx, dy)`` converts in-slice grid units into physical units; ``origin`` is the
    physical ``(x, y)`` of grid point ``(0, 0)``.  Section heights ``z`` are already physical.
    An end section whose polygon encloses area is closed by a flat cap in its own plane
    (truncated shapes); one that degenerates to a point or a segment is a pole.
    """

    sections: tuple
    spacing: tuple = (1.0, 1.0)
    origin: tuple = (0.0, 0.0)
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.sections)

    @property
    def z(self) -> np.ndarray:
        return np.array([s.z for s in self.sections], dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Mesh:
    """A closed triangle mesh: ``vertices (n, 3) float64`` in ``(x, y, z)``, ``faces (m, 3) int64``.

    ``P`` is the paper's vertex count: the number of polygon vertices over all sections.
    ``meta`` records how the mesh was made (method, parameters, true area when known).
    """

    vertices: np.ndarray
    faces: np.ndarray
    P: Optional[int] = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"Mesh vertices must have shape (n, 3); got {v.shape}")
        if f.ndim != 2 or (f.size and f.shape[1] != 3):
            raise ValueError(f"Mesh faces must have shape (m, 3); got {f.shape}")
        f = f.reshape(-1, 3)
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError("Mesh faces index vertices that do not exist")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        if self.P is None:
            object.__setattr__(self, "P", int(len(v)))

    # --- measures -------------------------------------------------------------------------
    @property
    def triangle_areas(self) -> np.ndarray:

        return triangle_areas(self.vertices, self.faces)

    @property
    def area(self) -> float:
        """Surface area: the sum of the triangle areas, correctly rounded and independent of the
        order of the vertices and faces (:func:`contourmesh.measure.surface_area`)."""
        return surface_area(self.vertices, self.faces)

    @property
    def volume(self) -> float:
        """Enclosed volume by the divergence theorem (positive for an outward-oriented mesh)."""

        return mesh_volume(self.vertices, self.faces)

    def checks(self) -> dict:
        """Closedness, orientation, degeneracy and self-intersection checks (see
        :func:`contourmesh.measure.mesh_checks`)."""
        return mesh_checks(self.vertices, self.faces)

    # --- adapters -------------------------------------------------------------------------
    def to_trimesh(self):

        return to_trimesh(self)

    def to_open3d(self):

        return to_open3d(self)

    def to_pymeshlab(self):

        return to_pymeshlab(self)

    def save(self, path, *, force: bool = True) -> Path:
        """Write the mesh (``.ply``, ``.obj``, ``.stl``, ``.off``) atomically; returns the path."""

        return save_mesh(self, path, force=force)

    def __repr__(self) -> str:
        return f"Mesh(vertices={len(self.vertices)}, faces={len(self.faces)}, P={self.P})"
