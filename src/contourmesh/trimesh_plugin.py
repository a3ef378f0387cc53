"""Let ``trimesh.load("x.contours.json")`` return contourmesh's mesh of a contour stack.

Importing contourmesh leaves trimesh as it is.  :func:`register_trimesh_loader` adds the loader
(trimesh picks loaders from ``trimesh.exchange.load.mesh_loaders`` by the file's last suffix,
``"json"``); any JSON that is not in the contour format goes on to the loader that was there
before.  :func:`unregister_trimesh_loader` puts that loader back.

>>> import trimesh, contourmesh
>>> contourmesh.register_trimesh_loader()
>>> "json" in trimesh.exchange.load.mesh_loaders
True
>>> contourmesh.unregister_trimesh_loader()
"""

from __future__ import annotations

import io as _io
import json

__all__ = ["register_trimesh_loader", "unregister_trimesh_loader"]


class _ContoursLoader:
    """A trimesh loader for the JSON contour format that hands other JSON to ``previous``."""

    def __init__(self, previous):
        self.previous = previous

    def __call__(self, file_obj, file_type=None, resolver=None, metadata=None, **kwargs):
        from .api import mesh_stack
        from .io.contours import CONTOURS_FORMAT, _stack_from_json_doc

        data = file_obj.read() if hasattr(file_obj, "read") else file_obj
        if isinstance(data, bytes):
            data = data.decode("utf-8")
        where = getattr(file_obj, "name", "<json>")
        try:
            doc = json.loads(data)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{where!r}: expected a JSON document; found invalid JSON ({exc.msg})") from None
        if not (isinstance(doc, dict) and doc.get("format") == CONTOURS_FORMAT):
            if self.previous is not None:
                return self.previous(_io.BytesIO(data.encode()), file_type=file_type, resolver=resolver,
                                     metadata=metadata, **kwargs)
            raise ValueError(f"{where!r}: expected a {CONTOURS_FORMAT!r} JSON file (the only JSON that loads "
                             "as a mesh)")
        m = mesh_stack(_stack_from_json_doc(doc, str(where)))
        return {"vertices": m.vertices, "faces": m.faces, "process": False,
                "metadata": {"contourmesh": {k: v for k, v in m.meta.items() if isinstance(v, (str, int, float))}}}


def register_trimesh_loader() -> None:
    """Make ``trimesh.load("x.contours.json")`` return our mesh of the contour stack (idempotent)."""
    from trimesh.exchange import load as _load

    current = _load.mesh_loaders.get("json")
    if isinstance(current, _ContoursLoader):
        return
    _load.mesh_loaders["json"] = _ContoursLoader(current)


def unregister_trimesh_loader() -> None:
    """Undo :func:`register_trimesh_loader`: trimesh's own ``"json"`` loader (if any) is back."""
    from trimesh.exchange import load as _load

    current = _load.mesh_loaders.get("json")
    if isinstance(current, _ContoursLoader):
        if current.previous is None:
            del _load.mesh_loaders["json"]
        else:
            _load.mesh_loaders["json"] = current.previous
