"""Post-processes: ``Mesh -> Mesh`` steps that compose with any mesh source, selected by name.

==========================  ======================================================================
``merge-coplanar``          exactly coplanar adjacent faces merged into polygons and re-triangulated
                            (trimesh facets + mapbox earcut, holes respected); area-faithful.
``meshlab-planar-qec``      PyMeshLab quadric edge collapse with planar quadrics, no optimal
                            placement, topology preserved; ``-p<fraction>`` of faces kept (0.5).
``taubin``                  Taubin lambda|mu smoothing (trimesh), ``-it<n>`` iterations (10).
``mlx:PATH``                a MeshLab filter script (.mlx) applied with PyMeshLab.
==========================  ======================================================================

:func:`apply_postprocess` returns the new mesh and a dict with the area and vertex count before and
after.  :func:`save_filter_script` writes a chain of MeshLab filters as an ``.mlx`` file; the
scripts the project uses live in ``comparisons/meshlab/``.
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path

import numpy as np

from .._optional import require
from ..types import Mesh

__all__ = [
    "available_postprocesses",
    "get_postprocess",
    "apply_postprocess",
    "merge_coplanar",
    "meshlab_planar_qec",
    "taubin",
    "apply_mlx",
    "save_filter_script",
    "MESHLAB_STEPS",
]


def _require(module: str, pip_name: str):
    return require(module, "compare", pip_name)


def _compact(vertices, faces, **meta) -> Mesh:
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    v = np.asarray(vertices, dtype=np.float64)
    used = np.unique(f)
    remap = np.full(len(v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return Mesh(v[used], remap[f], meta=meta)


# --- merge coplanar -----------------------------------------------------------------------------
def _boundary_loops(directed: np.ndarray) -> list:
    """Closed loops of directed boundary edges ``(k, 2)``; at a pinch vertex the next unused edge is taken."""
    out_edges: dict = {}
    for k, (a, _) in enumerate(directed.tolist()):
        out_edges.setdefault(a, []).append(k)
    used = np.zeros(len(directed), dtype=bool)
    loops = []
    for start in range(len(directed)):
        if used[start]:
            continue
        loop, k = [], start
        while not used[k]:
            used[k] = True
            a, b = directed[k]
            loop.append(int(a))
            nxt = [e for e in out_edges.get(int(b), []) if not used[e]]
            if not nxt:
                break
            k = nxt[0]
        if directed[k][1] != loop[0]:
            raise ValueError("facet boundary is not a closed loop")
        loops.append(loop)
    return loops


def _retriangulate_facet(vertices, faces, normal):
    """Earcut triangulation of the polygon (with holes) that a set of coplanar faces covers.

    Returns the new faces, or None when the facet's boundary cannot be triangulated faithfully.
    """
    import mapbox_earcut

    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = directed[:, 0] * (len(vertices) + 1) + directed[:, 1]
    rkey = directed[:, 1] * (len(vertices) + 1) + directed[:, 0]
    boundary = directed[~np.isin(key, rkey)]
    try:
        loops = _boundary_loops(boundary)
    except ValueError:
        return None
    n = normal / np.linalg.norm(normal)
    u = np.cross(n, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 0.5:
        u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)  # (u, w, n) right-handed: counter-clockwise loops in (u, w) face +n
    areas = []
    for loop in loops:
        p = vertices[loop]
        x, y = p @ u, p @ w
        areas.append(0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
    outers = [i for i, a in enumerate(areas) if a > 0]
    if len(outers) != 1:
        return None
    order = outers + [i for i in range(len(loops)) if i != outers[0]]
    ring_vertices = np.concatenate([np.asarray(loops[i]) for i in order])
    pts2 = np.column_stack([vertices[ring_vertices] @ u, vertices[ring_vertices] @ w])
    ends = np.cumsum([len(loops[i]) for i in order]).astype(np.uint32)
    idx = np.asarray(mapbox_earcut.triangulate_float64(pts2, ends), dtype=np.int64).reshape(-1, 3)
    if len(idx) == 0:
        return None
    new = _split_t_junctions(vertices, ring_vertices[idx], boundary)
    if new is None:
        return None
    tri = vertices[new]
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = cr @ n < 0
    new[flip] = new[flip][:, ::-1]
    return new


from ..bands.caps import split_t_junctions as _split_t_junctions  # noqa: E402


def merge_coplanar(mesh: Mesh, *, rel_tol: float = 1e-9) -> Mesh:
    """Merge exactly coplanar adjacent faces into polygons and re-triangulate them.

    Facets (maximal edge-connected sets of coplanar faces) come from ``trimesh``; each facet's
    boundary loops (outer loop and holes) are triangulated with ``mapbox_earcut`` in the facet's
    plane, keeping the facet's orientation.  Vertices inside a facet disappear; boundary vertices
    stay (so the mesh stays closed, collinear boundary vertices included).  A facet whose new
    triangles do not reproduce its area to ``rel_tol`` (pinched or self-touching boundaries) is
    left as it was, so the total area is preserved.
    """
    trimesh = _require("trimesh", "trimesh")
    tm = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
    tm.merge_vertices(merge_tex=True, merge_norm=True)
    vertices = np.asarray(tm.vertices, dtype=np.float64)
    faces = np.asarray(tm.faces, dtype=np.int64)
    areas = np.asarray(tm.area_faces)
    normals = np.asarray(tm.face_normals)
    keep = np.ones(len(faces), dtype=bool)
    new_faces = []
    merged = 0
    for facet in tm.facets:
        sub = faces[facet]
        # trimesh groups faces whose normals agree to a tolerance: insist on exact coplanarity.
        n = normals[facet[0]]
        offsets = vertices[sub.ravel()] @ n
        scale = max(1.0, float(np.abs(vertices).max()))
        if np.ptp(offsets) > 1e-12 * scale:
            continue
        tri = _retriangulate_facet(vertices, sub, n)
        if tri is None:
            continue
        a_old = math.fsum(areas[facet])
        t = vertices[tri]
        a_new = math.fsum(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1))
        if abs(a_new - a_old) > rel_tol * a_old:
            continue
        keep[facet] = False
        new_faces.append(tri)
        merged += 1
    out = np.concatenate([faces[keep]] + new_faces) if new_faces else faces
    meta = dict(mesh.meta)
    meta["merge_coplanar"] = {"facets_merged": merged}
    return _compact(vertices, out, **meta)


# --- MeshLab ------------------------------------------------------------------------------------
def _to_ms(mesh: Mesh):
    pymeshlab = _require("pymeshlab", "pymeshlab")
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=mesh.faces.astype(np.int32)), "mesh")
    return pymeshlab, ms


def _from_ms(ms, **meta) -> Mesh:
    cm = ms.current_mesh()
    return _compact(cm.vertex_matrix(), cm.face_matrix(), **meta)


def _planar_qec_params(fraction: float) -> dict:
    return dict(targetperc=float(fraction), planarquadric=True, optimalplacement=False, preservetopology=True,
                preservenormal=True, autoclean=True)


#: MeshLab-backed steps by name: PyMeshLab filter name and parameters (used by :func:`save_filter_script`).
MESHLAB_STEPS = {
    "meshlab-planar-qec": ("meshing_decimation_quadric_edge_collapse", _planar_qec_params(0.5)),
    "meshlab-taubin": ("apply_coord_taubin_smoothing", dict(lambda_=0.5, mu=-0.53, stepsmoothnum=10)),
}


def meshlab_planar_qec(mesh: Mesh, *, fraction: float = 0.5) -> Mesh:
    """PyMeshLab ``meshing_decimation_quadric_edge_collapse`` with ``planarquadric=True``,
    ``optimalplacement=False``, ``preservetopology=True`` (and ``preservenormal=True``), down to
    ``fraction`` of the faces.  Not area-faithful in general: collapses move the surface.
    """
    if not 0 < fraction < 1:
        raise ValueError(f"fraction of faces to keep must be in (0, 1); got {fraction}")
    _, ms = _to_ms(mesh)
    ms.meshing_decimation_quadric_edge_collapse(**_planar_qec_params(fraction))
    return _from_ms(ms, **mesh.meta)


def taubin(mesh: Mesh, *, iterations: int = 10, lamb: float = 0.5, nu: float = 0.53) -> Mesh:
    """Taubin lambda|mu smoothing (Taubin 1995) with ``trimesh.smoothing.filter_taubin``."""
    trimesh = _require("trimesh", "trimesh")
    from trimesh.smoothing import filter_taubin

    tm = trimesh.Trimesh(vertices=mesh.vertices.copy(), faces=mesh.faces.copy(), process=False)
    filter_taubin(tm, lamb=lamb, nu=nu, iterations=int(iterations))
    return Mesh(np.asarray(tm.vertices), np.asarray(tm.faces), meta=dict(mesh.meta))


def apply_mlx(mesh: Mesh, path) -> Mesh:
    """Apply a MeshLab filter script (``MeshSet.load_filter_script`` + ``apply_filter_script``)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"MeshLab filter script {str(path)!r} does not exist")
    _, ms = _to_ms(mesh)
    ms.load_filter_script(str(path))
    ms.apply_filter_script()
    return _from_ms(ms, **mesh.meta)


def save_filter_script(steps, path) -> Path:
    """Write a chain of MeshLab filters as an ``.mlx`` script (``MeshSet.save_filter_script``).

    ``steps``: names from :data:`MESHLAB_STEPS` or ``(pymeshlab_filter_name, params)`` pairs.  The
    filters are recorded by applying them, in order, to a small sample mesh (an icosphere).
    """
    pymeshlab = _require("pymeshlab", "pymeshlab")
    trimesh = _require("trimesh", "trimesh")
    chain = []
    for step in steps:
        if isinstance(step, str):
            if step not in MESHLAB_STEPS:
                raise ValueError(f"unknown MeshLab step {step!r}; expected one of {sorted(MESHLAB_STEPS)} "
                                 "or a (filter_name, params) pair")
            chain.append(MESHLAB_STEPS[step])
        else:
            name, params = step
            chain.append((str(name), dict(params)))
    if not chain:
        raise ValueError("save_filter_script needs at least one step")
    sphere = trimesh.creation.icosphere(subdivisions=3)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(sphere.vertices), face_matrix=np.asarray(sphere.faces, dtype=np.int32)))
    for name, params in chain:
        ms.apply_filter(name, **params)
    path = Path(path)
    ms.save_filter_script(str(path))
    return path


# --- registry -----------------------------------------------------------------------------------
_TOKEN = re.compile(r"^([A-Za-z]+)(\d+(?:\.\d*)?|\.\d+)$")
_POST = {
    "merge-coplanar": (merge_coplanar, {}),
    "meshlab-planar-qec": (meshlab_planar_qec, {"p": ("fraction", float)}),
    "taubin": (taubin, {"it": ("iterations", int)}),
}


def available_postprocesses() -> list[str]:
    """The post-process names (``mlx:PATH`` takes any script path)."""
    return list(_POST) + ["mlx:PATH"]


def get_postprocess(name: str):
    """The ``Mesh -> Mesh`` callable a post-process name denotes (parameters as ``-<key><number>``)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"a post-process name is a non-empty string; got {name!r}")
    if name.startswith("mlx:"):
        path = name[4:]
        return lambda mesh: apply_mlx(mesh, path)
    base = max((b for b in _POST if name == b or name.startswith(b + "-")), key=len, default=None)
    if base is None:
        raise ValueError(f"unknown post-process {name!r}; expected one of {available_postprocesses()}")
    fn, keys = _POST[base]
    params = {}
    for token in filter(None, name[len(base):].split("-")):
        m = _TOKEN.match(token)
        if not m or m.group(1) not in keys:
            raise ValueError(f"post-process {name!r}: cannot read parameter {token!r}; keys: {sorted(keys)}")
        pname, typ = keys[m.group(1)]
        params[pname] = typ(float(m.group(2)))
    return lambda mesh: fn(mesh, **params)


def apply_postprocess(name: str, mesh: Mesh) -> tuple[Mesh, dict]:
    """Apply one post-process; returns the new mesh and ``{name, area_before, area_after, P_before,
    P_after, faces_before, faces_after, seconds}``."""
    if not isinstance(mesh, Mesh):
        raise ValueError(f"post-processes take a contourmesh Mesh; got {type(mesh).__name__}")
    fn = get_postprocess(name)
    t0 = time.perf_counter()
    out = fn(mesh)
    info = {"name": name, "area_before": mesh.area, "area_after": out.area, "P_before": int(len(mesh.vertices)),
            "P_after": int(len(out.vertices)), "faces_before": int(len(mesh.faces)),
            "faces_after": int(len(out.faces)), "seconds": time.perf_counter() - t0}
    return out, info
