"""Post-processes: ``Mesh -> Mesh`` steps that compose with any mesh source, selected by name.

==========================  ======================================================================
``merge-coplanar``          exactly coplanar adjacent faces merged into polygons and re-triangulated
                            (trimesh facets + mapbox earcut, holes respected); area-faithful.
``meshlab-planar-qec``      PyMeshLab quadric edge collapse with planar quadrics, no optimal
                            placement, topology preserved; ``-p<fraction>`` of faces kept (0.5).
``meshlab-taubin``          PyMeshLab Taubin lambda|mu smoothing, ``-it<n>`` iterations (10).
``taubin``                  Taubin lambda|mu smoothing (trimesh), ``-it<n>`` iterations (10).
``mlx:PATH``                a MeshLab filter script (.mlx) applied with PyMeshLab.
==========================  ======================================================================

:func:`apply_postprocess` returns the new mesh and a dict with the area and vertex count before and
after.  :func:`save_filter_script` writes the MeshLab steps among them (:func:`meshlab_steps_of`) as an
``.mlx`` file that :func:`apply_mlx` (``mlx:PATH``) applies again; the scripts the project uses
live in ``comparisons/meshlab/``.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .._optional import require
from ..meshes import atomic_write
from ..types import Mesh

__all__ = [
    "available_postprocesses",
    "get_postprocess",
    "apply_postprocess",
    "merge_coplanar",
    "meshlab_planar_qec",
    "taubin",
    "meshlab_taubin",
    "apply_mlx",
    "check_filter_script",
    "meshlab_steps_of",
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
@contextlib.contextmanager
def _quiet_fds():
    """Send file descriptors 1 and 2 to /dev/null for the duration (PyMeshLab's C++ code prints there)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):
            pass
    saved = []
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # pragma: no cover - no /dev/null
        yield
        return
    try:
        for fd in (1, 2):
            try:
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
            except OSError:  # pragma: no cover - fd not open
                pass
        yield
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


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


def _taubin_params(iterations: int, lamb: float = 0.5, mu: float = -0.53) -> dict:
    return dict(lambda_=float(lamb), mu=float(mu), stepsmoothnum=int(iterations))


#: MeshLab-backed steps with their default parameters: PyMeshLab filter name and parameters.  The
#: same names (with the same ``-<key><number>`` suffixes) are post-processes; see :func:`meshlab_steps_of`.
MESHLAB_STEPS = {
    "meshlab-planar-qec": ("meshing_decimation_quadric_edge_collapse", _planar_qec_params(0.5)),
    "meshlab-taubin": ("apply_coord_taubin_smoothing", _taubin_params(10)),
}


def meshlab_planar_qec(mesh: Mesh, *, fraction: float = 0.5) -> Mesh:
    """PyMeshLab ``meshing_decimation_quadric_edge_collapse`` with ``planarquadric=True``,
    ``optimalplacement=False``, ``preservetopology=True`` (and ``preservenormal=True``), down to
    ``fraction`` of the faces.  Not area-faithful in general: collapses move the surface.
    """
    if not 0 < fraction < 1:
        raise ValueError(f"fraction of faces to keep must be in (0, 1); got {fraction}")
    _, ms = _to_ms(mesh)
    with _quiet_fds():
        ms.meshing_decimation_quadric_edge_collapse(**_planar_qec_params(fraction))
    return _from_ms(ms, **mesh.meta)


def meshlab_taubin(mesh: Mesh, *, iterations: int = 10) -> Mesh:
    """PyMeshLab ``apply_coord_taubin_smoothing`` (lambda 0.5, mu -0.53), ``iterations`` passes."""
    if iterations < 1:
        raise ValueError(f"iterations must be a positive integer; got {iterations}")
    _, ms = _to_ms(mesh)
    with _quiet_fds():
        ms.apply_coord_taubin_smoothing(**_taubin_params(iterations))
    return _from_ms(ms, **mesh.meta)


def taubin(mesh: Mesh, *, iterations: int = 10, lamb: float = 0.5, nu: float = 0.53) -> Mesh:
    """Taubin lambda|mu smoothing (Taubin 1995) with ``trimesh.smoothing.filter_taubin``."""
    trimesh = _require("trimesh", "trimesh")
    from trimesh.smoothing import filter_taubin

    tm = trimesh.Trimesh(vertices=mesh.vertices.copy(), faces=mesh.faces.copy(), process=False)
    filter_taubin(tm, lamb=lamb, nu=nu, iterations=int(iterations))
    return Mesh(np.asarray(tm.vertices), np.asarray(tm.faces), meta=dict(mesh.meta))


def check_filter_script(path) -> list[str]:
    """Check that ``path`` is a MeshLab filter script; return the names of its filters.

    A filter script is XML with a ``<FilterScript>`` root holding one or more ``<filter name=...>``
    (or ``<xmlfilter name=...>``) elements.  Anything else raises ValueError with one line that
    names the file and what is wrong.  Whether MeshLab knows each filter is found out when the
    script is applied (:func:`apply_mlx`).
    """
    import xml.etree.ElementTree as ET

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"MeshLab filter script {str(path)!r} does not exist")
    try:
        root = ET.fromstring(path.read_bytes())
    except ET.ParseError as exc:
        raise ValueError(f"{str(path)!r} is not a MeshLab filter script (.mlx): not XML ({exc})") from None
    if root.tag != "FilterScript":
        raise ValueError(f"{str(path)!r} is not a MeshLab filter script (.mlx): its root element is "
                         f"<{root.tag}>, expected <FilterScript>")
    filters = [el for el in root if el.tag in ("filter", "xmlfilter")]
    names = [el.get("name") for el in filters]
    if not filters:
        raise ValueError(f"MeshLab filter script {str(path)!r} holds no <filter> elements")
    if not all(names):
        raise ValueError(f"MeshLab filter script {str(path)!r} has a <filter> without a name")
    return names


def apply_mlx(mesh: Mesh, path) -> Mesh:
    """Apply a MeshLab filter script (``MeshSet.load_filter_script`` + ``apply_filter_script``).

    The script is checked first (:func:`check_filter_script`); a filter MeshLab does not know, or
    one that fails, raises ValueError naming the file.  PyMeshLab's own messages are silenced.
    """
    names = check_filter_script(path)
    _, ms = _to_ms(mesh)
    try:
        with _quiet_fds():
            ms.load_filter_script(str(path))
            ms.apply_filter_script()
    except Exception as exc:  # PyMeshLabException: "Something really bad happened" for unknown filters
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ValueError(f"MeshLab could not apply filter script {str(path)!r} (filters {names}): {first}") from None
    return _from_ms(ms, **mesh.meta)


def meshlab_steps_of(posts) -> list:
    """The MeshLab filters ``[(pymeshlab_filter_name, params), ...]`` a list of post-process names denotes.

    For ``contourmesh mesh ... --post meshlab-planar-qec-p0.3 --post meshlab-taubin-it5 --save-mlx
    F``: every name must be a MeshLab step (:data:`MESHLAB_STEPS`, with its ``-<key><number>``
    suffixes), so that the saved script does what ``--post`` did; any other name, or none, raises
    ValueError saying which.
    """
    posts = [posts] if isinstance(posts, str) else list(posts or [])
    if not posts:
        raise ValueError(f"a MeshLab filter script needs MeshLab post-processes; MeshLab steps: {sorted(MESHLAB_STEPS)}")
    other = [p for p in posts if _base_of(p) not in MESHLAB_STEPS]
    if other:
        raise ValueError(f"only MeshLab steps can be saved as a filter script; not MeshLab: {other} "
                         f"(MeshLab steps: {sorted(MESHLAB_STEPS)}, with the same suffixes as for the post-process)")
    out = []
    for p in posts:
        base, params = _parse(p)
        out.append(_MESHLAB_BUILD[base](**params))
    return out


def save_filter_script(steps, path) -> Path:
    """Write a chain of MeshLab filters as an ``.mlx`` script (``MeshSet.save_filter_script``).

    ``steps``: post-process names of MeshLab steps (``"meshlab-planar-qec-p0.3"``, see
    :func:`meshlab_steps_of`) or ``(pymeshlab_filter_name, params)`` pairs.  The filters are
    recorded by applying them, in order, to a small sample mesh (an icosphere); the file is
    written atomically.  Applying the script (:func:`apply_mlx`) reproduces the steps.
    """
    pymeshlab = _require("pymeshlab", "pymeshlab")
    trimesh = _require("trimesh", "trimesh")
    chain = []
    for step in steps:
        if isinstance(step, str):
            chain += meshlab_steps_of([step])
        else:
            name, params = step
            chain.append((str(name), dict(params)))
    if not chain:
        raise ValueError("save_filter_script needs at least one step")
    sphere = trimesh.creation.icosphere(subdivisions=3)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(sphere.vertices), face_matrix=np.asarray(sphere.faces, dtype=np.int32)))
    path = Path(path)
    with tempfile.TemporaryDirectory() as tmp:
        tmp_file = Path(tmp) / "script.mlx"
        with _quiet_fds():
            for name, params in chain:
                ms.apply_filter(name, **params)
            ms.save_filter_script(str(tmp_file))
        data = tmp_file.read_bytes()
    return atomic_write(path, data)


# --- registry -----------------------------------------------------------------------------------
_TOKEN = re.compile(r"^([A-Za-z]+)(\d+(?:\.\d*)?|\.\d+)$")
_POST = {
    "merge-coplanar": (merge_coplanar, {}),
    "meshlab-planar-qec": (meshlab_planar_qec, {"p": ("fraction", float)}),
    "meshlab-taubin": (meshlab_taubin, {"it": ("iterations", int)}),
    "taubin": (taubin, {"it": ("iterations", int)}),
}
#: The MeshLab filter each MeshLab post-process records in a script, from the same parameters.
_MESHLAB_BUILD = {
    "meshlab-planar-qec": lambda fraction=0.5: ("meshing_decimation_quadric_edge_collapse", _planar_qec_params(fraction)),
    "meshlab-taubin": lambda iterations=10: ("apply_coord_taubin_smoothing", _taubin_params(iterations)),
}


def available_postprocesses() -> list[str]:
    """The post-process names (``mlx:PATH`` takes any script path)."""
    return list(_POST) + ["mlx:PATH"]


def _base_of(name: str):
    return max((b for b in _POST if name == b or name.startswith(b + "-")), key=len, default=None)


def _parse(name: str):
    """``(base, params)`` of a post-process name ``base[-<key><number>...]``."""
    base = _base_of(name)
    if base is None:
        raise ValueError(f"unknown post-process {name!r}; expected one of {available_postprocesses()}")
    _, keys = _POST[base]
    params = {}
    for token in filter(None, name[len(base):].split("-")):
        m = _TOKEN.match(token)
        if not m or m.group(1) not in keys:
            raise ValueError(f"post-process {name!r}: cannot read parameter {token!r}; keys: {sorted(keys)}")
        pname, typ = keys[m.group(1)]
        params[pname] = typ(float(m.group(2)))
    return base, params


def get_postprocess(name: str):
    """The ``Mesh -> Mesh`` callable a post-process name denotes (parameters as ``-<key><number>``).

    ``mlx:PATH`` checks the script now (:func:`check_filter_script`), so a wrong file is reported
    before any meshing.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"a post-process name is a non-empty string; got {name!r}")
    if name.startswith("mlx:"):
        path = name[4:]
        check_filter_script(path)
        return lambda mesh: apply_mlx(mesh, path)
    base, params = _parse(name)
    fn, _ = _POST[base]
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
