"""Optional dependencies: import one by name, or say exactly what to install.

The comparison peers (VTK, Open3D, PyMeshLab, DGtal, Dask), the file readers (tifffile, nibabel,
pydicom) and a few helpers are optional.  Code that needs one calls :func:`require` *before* any
``import`` of that package, so a user without it reads the install command instead of a bare
``No module named ...``.
"""

from __future__ import annotations

import importlib

__all__ = ["MissingDependency", "require"]


from .errors import MissingDependency  # the one class: an optional package that is not installed


def require(module_name: str, extra: str, pip_name: str | None = None):
    """Import and return ``module_name``, or raise :class:`MissingDependency` with the install hint.

    ``extra`` is the contourmesh extra that brings the package (``"compare"``, ``"io"``);
    ``pip_name`` the package's name on PyPI when it differs from the top-level module
    (``skimage`` -> ``scikit-image``, ``vtkmodules`` -> ``vtk``).

    >>> require("math", "compare").sqrt(4.0)
    2.0
    """
    try:
        return importlib.import_module(module_name)
    except ImportError as exc:
        pip = pip_name or module_name.split(".")[0]
        raise MissingDependency(
            f"{module_name} is not installed: pip install {pip}  (or pip install 'contourmesh[{extra}]'); {exc}"
        ) from exc
