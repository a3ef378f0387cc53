"""Measures on meshes: area, volume, the paper's error and trade-off, and mesh checks.

All functions are pure and take ``vertices (n, 3)`` and ``faces (m, 3)`` arrays.
"""

from __future__ import annotations

import math

import numpy as np

from .intersect import canonical_vertices, self_intersections

__all__ = [
    "triangle_areas",
    "mesh_area",
    "mesh_volume",
    "relative_error",
    "tradeoff",
    "mesh_checks",
    "euler_genus",
]


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of every triangle, ``|(b - a) x (c - a)| / 2``."""
    if len(faces) == 0:
        return np.zeros(0)
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return 0.5 * np.sqrt(np.einsum("ij,ij->i", cross, cross))


def mesh_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Surface area: the sum of the triangle areas (compensated summation)."""
    return math.fsum(triangle_areas(vertices, faces))


def mesh_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed enclosed volume by the divergence theorem (positive when oriented outward)."""
    if len(faces) == 0:
        return 0.0
    # Translate to the centroid first: the sum is exact in theory and better conditioned.
    c = vertices.mean(axis=0)
    tri = vertices[faces] - c
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def axis_wall_fraction(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The fraction of the area on faces whose normal is exactly along +-x or +-y.

    On the surface of a smooth object in general position such faces carry essentially no area;
    on a mesh made of voxel faces (or of contours rising vertically to a mid-plane) they carry a
    lot.  A diagnostic of staircase joins; exact up to a relative tolerance of 1e-12.

    >>> import numpy as np
    >>> square = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1.0]])  # a wall facing -y
    >>> axis_wall_fraction(square, np.array([[0, 1, 2], [0, 2, 3]]))
    1.0
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return 0.0
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    size = np.linalg.norm(n, axis=1)
    tol = 1e-12 * size
    ax, ay, az = np.abs(n[:, 0]), np.abs(n[:, 1]), np.abs(n[:, 2])
    wall = (az <= tol) & ((ax <= tol) | (ay <= tol)) & (size > 0)
    total = size.sum()
    return float(size[wall].sum() / total) if total > 0 else 0.0


def relative_error(area: float, area_true: float | None) -> float | None:
    """Signed relative error ``(area - area_true) / area_true`` (None when the truth is unknown)."""
    if area_true is None or not np.isfinite(area_true) or area_true == 0:
        return None
    return (area - area_true) / area_true


def tradeoff(e: float | None, P: int | None) -> float | None:
    """The paper's trade-off measure ``t = |e| * P``."""
    if e is None or P is None:
        return None
    return abs(e) * P


def _edge_counts(faces: np.ndarray):
    """Undirected edges with their use counts, and directed-edge duplicates."""
    faces = np.asarray(faces, dtype=np.int64)
    a = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2]])
    b = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]])
    n = int(max(a.max(), b.max())) + 1 if len(a) else 1
    # one int64 key per edge (sorted like the rows (u, v)): far faster than unique rows
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keys, counts = np.unique(lo * n + hi, return_counts=True)
    uniq = np.stack([keys // n, keys % n], axis=1)
    _, dcounts = np.unique(a * n + b, return_counts=True)
    return uniq, counts, int((dcounts > 1).sum())


def euler_genus(n_vertices: int, n_edges: int, n_faces: int, n_components: int) -> float:
    """Total genus from the Euler characteristic of a closed orientable surface."""
    chi = n_vertices - n_edges + n_faces
    return (2 * n_components - chi) / 2


def _components(n: int, faces: np.ndarray) -> int:
    """Connected components of the vertices used by faces (union-find over face edges)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(faces) == 0:
        return 0
    used = np.unique(faces)
    remap = np.full(n, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    f = remap[faces]
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(used), len(used)))
    return int(connected_components(g, directed=False)[0])


def mesh_checks(vertices: np.ndarray, faces: np.ndarray, *, rel_tol: float = 1e-12) -> dict:
    """The checks every emitted mesh must pass, computed without third-party mesh code.

    Returns a dict with ``watertight`` (every undirected edge in exactly two faces),
    ``winding_consistent`` (no directed edge used twice), ``boundary_edges``,
    ``nonmanifold_edges``, ``degenerate_faces`` (repeated vertex or area below
    ``rel_tol`` times the squared bounding-box diagonal), ``duplicate_vertices``,
    ``volume``, ``components``, ``genus`` (total, from the Euler characteristic) and
    ``self_intersections`` (face pairs that meet other than along a shared edge or at a shared
    vertex, :func:`contourmesh.intersect.self_intersections`).  ``ok`` means closed, consistently
    oriented outward, without degenerate faces or duplicate vertices, and embedded (no
    self-intersections).
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return {
            "watertight": False, "winding_consistent": False, "boundary_edges": 0,
            "nonmanifold_edges": 0, "degenerate_faces": 0, "duplicate_vertices": 0,
            "volume": 0.0, "components": 0, "genus": None, "self_intersections": 0, "closed": False, "ok": False,
        }
    uniq, counts, dup_directed = _edge_counts(faces)
    diag2 = float(np.sum((vertices.max(0) - vertices.min(0)) ** 2)) or 1.0
    areas = triangle_areas(vertices, faces)
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    degenerate = int((repeated | (areas <= rel_tol * diag2)).sum())
    used = np.unique(faces)
    # positions shared by several used vertices (lexsort of the coordinates, not unique rows)
    dup_vertices = len(used) - int(np.count_nonzero(canonical_vertices(vertices[used]) == np.arange(len(used))))
    comps = _components(len(vertices), faces)
    watertight = bool(np.all(counts == 2))
    volume = mesh_volume(vertices, faces)
    out = {
        "watertight": watertight,
        "winding_consistent": dup_directed == 0,
        "boundary_edges": int((counts == 1).sum()),
        "nonmanifold_edges": int((counts > 2).sum()),
        "degenerate_faces": degenerate,
        "duplicate_vertices": int(dup_vertices),
        "volume": volume,
        "components": comps,
        "genus": euler_genus(len(used), len(uniq), len(faces), comps) if watertight else None,
        "self_intersections": self_intersections(vertices, faces),
    }
    # closed: a closed, consistently outward 2-manifold without degenerate faces; ok: also embedded
    out["closed"] = bool(watertight and out["winding_consistent"] and degenerate == 0 and dup_vertices == 0
                         and volume > 0)
    out["ok"] = bool(out["closed"] and out["self_intersections"] == 0)
    return out
