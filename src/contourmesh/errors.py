"""The exceptions and warnings of contourmesh, in one place.

Every error that a bad input can cause derives from :class:`ContourMeshError`, itself a
``ValueError``; a keyword that does not apply to the source is also a ``TypeError``.  Wrong types
raise ``TypeError``; wrong values ``ValueError``.
"""

from __future__ import annotations

import os
import warnings

__all__ = ["ContourMeshError", "InapplicableOption", "CapError", "StackSurfaceError", "CrossingFacesError",
           "ThinRegionError",
           "MissingDependency",
           "LostContourWarning", "RasterFallbackWarning", "SelfIntersectionWarning", "warn_external"]


class ContourMeshError(ValueError):
    """Base class of contourmesh's own errors about its inputs."""


class InapplicableOption(ContourMeshError, TypeError):
    """A keyword was given that does not apply to this kind of source (it would be ignored)."""


class CapError(ContourMeshError):
    """A planar cap cannot be triangulated as given (its rings cross or touch each other)."""


class StackSurfaceError(ContourMeshError):
    """The contours do not bound a closed surface on the stack route (e.g. a keyhole contour)."""


class OpenSurfaceError(StackSurfaceError):
    """The stack route's finished mesh is not a closed, edge-manifold, outward surface (a contour
    that touches or crosses itself); the front door then takes another route."""


class CrossingFacesError(StackSurfaceError):
    """Faces of a stack-route mesh still cross after its local repair (asked for with
    ``crossings="raise"``; the front door then takes another route)."""


class ThinRegionError(ContourMeshError):
    """A contour bounds no grid point whose four surrounding cells are inside (a region one cell
    thin), so it has no minimum length polygon."""


class MissingDependency(ImportError):
    """An optional package that a method, reader or adapter needs is not installed."""


class LostContourWarning(UserWarning):
    """A contour encloses no pixel centre at the chosen pixel size, so the raster loses it."""


class RasterFallbackWarning(UserWarning):
    """A structure that the stack route was to mesh as drawn could not be, and was rasterized instead."""


class SelfIntersectionWarning(UserWarning):
    """A mesh is closed but some of its faces cross (its repair was exhausted); the number of
    crossing face pairs is in ``meta["self_intersections"]``."""


_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep


def warn_external(message: str, category=UserWarning) -> None:
    """Warn, attributing the warning to the first frame outside contourmesh (the user's call)."""
    import sys

    level = 2
    frame = sys._getframe(1)
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE_DIR):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)
