"""Peer surface methods for the comparison harness: a registry of named, parameterised mesh sources.

Every method reads the same input - a binary volume indexed ``[z, y, x]`` with ``spacing =
(dz, dy, dx)`` and ``origin = (x0, y0, z0)``, the physical position of voxel ``[0, 0, 0]``'s
centre - and returns a :class:`Result`: an area, and a :class:`~contourmesh.types.Mesh` with
vertices in ``(x, y, z)`` physical units and outward faces when the method makes a surface.

Names carry their parameters as ``-<key><number>`` suffixes (``"mc-lewiner-blur1"``,
``"o3d-poisson-d8"``, ``"dgtal-vcm-R5-r3"``) or flag words (``"o3d-poisson-d8-estnormals"``);
lengths in names are in **voxel units** (multiples of the mean spacing).  The families:

==================  =========================================================================
marching-cubes      ``mc-lewiner``, ``mc-lorensen`` (scikit-image), ``-blur<sigma>``: Gaussian
                    pre-blur (scipy), sigma in voxels.  Level 0.5, volume padded with background.
vtk                 ``vtk-flyingedges`` (``-blur<sigma>``), ``vtk-discreteflyingedges``,
                    ``vtk-surfacenets`` (``-it<n>`` smoothing iterations, 16 = VTK's default,
                    ``-it0`` = no smoothing).  VTK runs single-threaded (``vtkSMPTools``, 1 thread).
open3d              ``o3d-poisson`` (``-d<depth>``), ``o3d-bpa`` (``-r<radius>``) from surfel points
                    (:func:`surfel_points`); ``o3d-alpha`` (``-a<alpha>``) from voxel centres.
meshlab             ``ml-spoisson`` (``-d<depth>``), ``ml-bpa`` (``-r<radius>``) on the same points;
                    ``ml-alphawrap`` (``-a<alpha>-o<offset>``) around the voxel staircase mesh.
ours                ``ours-<polygon>-<triangulation>[-band]`` (polygon ``dss|mlp|none``,
                    triangulation ``wiederhold|greedy|optimal``): :func:`contourmesh.mesh`;
                    on an analytic shape it meshes the shape's slices (``Method.shape_fn``).
local               ``surfels``, ``mullikin-verbeek``, ``lindblad`` (``-a<A1>``): estimators, no mesh;
                    ``voxel-faces``: the staircase surface of the voxels as a mesh.
dgtal               ``dgtal-ii`` (``-r<radius>``), ``dgtal-vcm`` (``-R<offset>-r<radius>``):
                    digital integration with integral-invariant / VCM normals, no mesh.
==================  =========================================================================

:func:`run_method` runs one of them and never raises for a method's own failure: it returns a
row whose ``status`` is ``"ok"``, ``"not-installed"`` (naming what to pip install),
``"failed"`` (with the error text) or ``"timeout"``.
"""

from __future__ import annotations

import math
import re
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from .._optional import MissingDependency, require
from ..api import mesh as _mesh_source
from ..bands import TRIANGULATORS
from ..measure import mesh_checks
from ..polygons import POLYGONIZERS
from ..types import Mesh
from ..volume_input import binary_volume, check_origin, check_spacing
from .execute import ExecutorError, call_in_subprocess
from .local import boundary_face_counts, lindblad_area, mullikin_verbeek_area, surfel_area
from .postprocess import apply_postprocess

__all__ = [
    "Method",
    "Result",
    "parse_ours",
    "ours_volume",
    "ours_shape",
    "OURS_POLYGONS",
    "OURS_TRIANGULATIONS",
    "MissingDependency",
    "get_method",
    "available_methods",
    "register_method",
    "unregister_method",
    "run_method",
    "voxel_boundary_mesh",
    "DEFAULT_METHODS",
    "check_volume",
    "surfel_points",
    "volume_to_mesh_frame",
]

FAMILIES = ("ours", "marching-cubes", "vtk", "multilabel", "open3d", "meshlab", "local", "dgtal")


# --- public types -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Method:
    """A named, parameterised surface method: ``fn(volume, spacing, origin, **params) -> Result``.

    ``shape_fn(shape, h, **params) -> Result``, when given, meshes an analytic shape directly (ours
    does: it traces the shape's slices instead of reading its Gauss volume); the runner uses it
    for shape inputs.
    """

    name: str
    family: str
    params: dict
    fn: Callable
    shape_fn: Optional[Callable] = None

    def __call__(self, volume, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)) -> "Result":
        vol, sp, org = check_volume(volume, spacing, origin)
        return self.fn(vol, sp, org, **self.params)


@dataclass
class Result:
    """What the harness tabulates: an area, the mesh if there is one, its vertex count, and extras."""

    area: float
    mesh: Optional[Mesh] = None
    P: Optional[int] = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.mesh is not None and self.P is None:
            self.P = int(len(self.mesh.vertices))


def _require(module: str, pip_name: str):
    return require(module, "compare", pip_name)


# --- input checks and frames --------------------------------------------------------------------
def check_volume(volume, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """Validate a binary volume ``[z, y, x]``, its ``spacing (dz, dy, dx)`` and ``origin (x0, y0, z0)``.

    Returns ``(volume as bool, spacing float64 (3,), origin float64 (3,))``; raises ValueError
    saying what was expected and what was found.
    """
    return binary_volume(volume), check_spacing(spacing), check_origin(origin)


def volume_to_mesh_frame(index_zyx: np.ndarray, spacing, origin) -> np.ndarray:
    """Map ``(n, 3)`` fractional voxel indices ``(z, y, x)`` to physical ``(x, y, z)`` points."""
    idx = np.asarray(index_zyx, dtype=np.float64)
    dz, dy, dx = spacing
    return np.column_stack([origin[0] + idx[:, 2] * dx, origin[1] + idx[:, 1] * dy, origin[2] + idx[:, 0] * dz])


def _mesh(vertices, faces, **meta) -> Mesh:
    """Our Mesh from raw arrays: unused vertices dropped, faces turned outward when inverted.

    Orientation: a mesh with negative signed volume has all its faces reversed (methods that
    deliver a consistently oriented surface then come out outward; for open surfaces, e.g. ball
    pivoting, the sign test is only a heuristic).
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f):
        used = np.unique(f)
        if len(used) < len(v):
            remap = np.full(len(v), -1, dtype=np.int64)
            remap[used] = np.arange(len(used))
            v, f = v[used], remap[f]
    m = Mesh(v, f, meta=dict(meta))
    if len(f) and m.volume < 0:
        m = Mesh(v, f[:, ::-1].copy(), meta=dict(meta))
    return m


def _mesh_result(mesh: Mesh, **extra) -> Result:
    return Result(area=mesh.area, mesh=mesh, P=int(len(mesh.vertices)), extra=dict(extra))


def _blurred(volume: np.ndarray, sigma: float) -> np.ndarray:
    """The padded volume as float, Gaussian-blurred with ``sigma`` voxels when ``sigma > 0``.

    Padding: ``ceil(3 sigma) + 1`` background layers, so the blur has room and the 0.5 level
    closes inside the array.  Returns ``(array, pad)``.
    """
    pad = 1 + (int(math.ceil(3 * sigma)) if sigma > 0 else 0)
    f = np.pad(volume, pad).astype(np.float64)
    if sigma > 0:
        from scipy.ndimage import gaussian_filter

        f = gaussian_filter(f, sigma=sigma, mode="constant", cval=0.0)
    return f, pad


def _level(f: np.ndarray, level: float) -> None:
    if not (f.min() < level < f.max()):
        raise ValueError(
            f"the volume has no {level} level crossing (values in [{f.min():.3g}, {f.max():.3g}]); "
            "is it empty or too thin for the blur?"
        )


# --- marching cubes (scikit-image) --------------------------------------------------------------
def marching_cubes(volume, spacing, origin, *, method: str = "lewiner", blur: float = 0.0) -> Result:
    """Marching cubes (scikit-image) at level 0.5 on the binary volume or its Gaussian blur.

    ``method="lewiner"`` (Lewiner et al. 2003, topologically consistent) or ``"lorensen"``
    (Lorensen & Cline 1987).  The volume is padded with background so the surface closes.
    scikit-image returns vertices in ``(z, y, x)``; they are mapped to physical ``(x, y, z)`` and
    the faces are turned outward (positive signed volume).  Expected on a Gauss-digitized ball:
    binary about +8.8 % (converged), ``blur=1`` about +0.2 %.
    """
    measure = _require("skimage.measure", "scikit-image")
    f, pad = _blurred(volume, float(blur))
    _level(f, 0.5)
    verts, faces, _, _ = measure.marching_cubes(f, level=0.5, method=method, allow_degenerate=False)
    mesh = _mesh(volume_to_mesh_frame(verts - pad, spacing, origin), faces, method=f"mc-{method}", blur=blur)
    return _mesh_result(mesh)


# --- VTK ----------------------------------------------------------------------------------------
def _require_vtk():
    """VTK's Python modules, or the install hint (called before any ``vtkmodules`` import)."""
    return _require("vtkmodules", "vtk")


def _vtk_image(f: np.ndarray, spacing, origin, pad: int):
    """A ``vtkImageData`` of the ``[z, y, x]`` array ``f`` (x fastest = VTK's point order)."""
    _require_vtk()
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkImageData

    vtkSMPTools.Initialize(1)  # reproducible: one thread
    dz, dy, dx = spacing
    img = vtkImageData()
    img.SetDimensions(f.shape[2], f.shape[1], f.shape[0])
    img.SetSpacing(dx, dy, dz)
    img.SetOrigin(origin[0] - pad * dx, origin[1] - pad * dy, origin[2] - pad * dz)
    arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(f).ravel(order="C"), deep=True)
    arr.SetName("values")
    img.GetPointData().SetScalars(arr)
    return img


def _vtk_polydata_to_mesh(poly, **meta) -> Mesh:
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter

    tri = vtkTriangleFilter()
    tri.SetInputData(poly)
    tri.PassVertsOff()
    tri.PassLinesOff()
    tri.Update()
    out = tri.GetOutput()
    if out.GetNumberOfPoints() == 0:
        raise RuntimeError("VTK produced an empty surface")
    pts = numpy_support.vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    conn = numpy_support.vtk_to_numpy(out.GetPolys().GetConnectivityArray()).astype(np.int64)
    return _mesh(pts, conn.reshape(-1, 3), **meta)


def vtk_flying_edges(volume, spacing, origin, *, blur: float = 0.0) -> Result:
    """``vtkFlyingEdges3D`` (Schroeder et al. 2015) at level 0.5, on the binary volume or its blur."""
    _require_vtk()
    f, pad = _blurred(volume, float(blur))
    _level(f, 0.5)
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

    alg = vtkFlyingEdges3D()
    alg.SetInputData(_vtk_image(f, spacing, origin, pad))
    alg.SetValue(0, 0.5)
    alg.ComputeNormalsOff()
    alg.ComputeGradientsOff()
    alg.ComputeScalarsOff()
    alg.Update()
    return _mesh_result(_vtk_polydata_to_mesh(alg.GetOutput(), method="vtk-flyingedges", blur=blur), vtk_threads=1)


def vtk_discrete_flying_edges(volume, spacing, origin) -> Result:
    """``vtkDiscreteFlyingEdges3D``: the label-1 boundary of the (padded) label volume."""
    _require_vtk()
    f, pad = _blurred(volume, 0.0)
    _level(f, 0.5)
    from vtkmodules.vtkFiltersGeneral import vtkDiscreteFlyingEdges3D

    alg = vtkDiscreteFlyingEdges3D()
    alg.SetInputData(_vtk_image(f.astype(np.uint8), spacing, origin, pad))
    alg.SetValue(0, 1)
    alg.ComputeNormalsOff()
    alg.ComputeGradientsOff()
    alg.ComputeScalarsOff()
    alg.Update()
    return _mesh_result(_vtk_polydata_to_mesh(alg.GetOutput(), method="vtk-discreteflyingedges"), vtk_threads=1)


def vtk_surface_nets(volume, spacing, origin, *, iterations: int = 16) -> Result:
    """``vtkSurfaceNets3D`` (Frisken's SurfaceNets, VTK 9.3+) with its constrained smoothing.

    ``iterations`` smoothing passes (16 = VTK's default; 0 turns smoothing off).  Relaxation
    factor and constraint scale stay at VTK's defaults (0.5 and 2).  Triangles out.
    """
    _require_vtk()
    f, pad = _blurred(volume, 0.0)
    _level(f, 0.5)
    from vtkmodules.vtkFiltersCore import vtkSurfaceNets3D

    alg = vtkSurfaceNets3D()
    alg.SetInputData(_vtk_image(f.astype(np.uint8), spacing, origin, pad))
    alg.SetValue(0, 1)
    alg.SetOutputMeshTypeToTriangles()
    alg.SetSmoothing(int(iterations) > 0)
    if int(iterations) > 0:
        alg.SetNumberOfIterations(int(iterations))
    alg.Update()
    mesh = _vtk_polydata_to_mesh(alg.GetOutput(), method="vtk-surfacenets", iterations=int(iterations))
    return _mesh_result(mesh, vtk_threads=1)


# --- multi-label meshers of connectomics (zmesh, serra-mesh) -----------------------------------
def zmesh_mc(volume, spacing, origin) -> Result:
    """``zmesh.Mesher`` (multi-label marching cubes, as connectomics pipelines run it), unsimplified.

    The volume is handed over as ``[x, y, z]`` (zmesh's order) with ``close=True``, which pads one
    voxel of background; the vertices are shifted back by it and placed at ``origin``.
    """
    zmesh = _require("zmesh", "zmesh")
    dz, dy, dx = (float(s) for s in spacing)
    labels = np.asfortranarray(np.asarray(volume, dtype=np.uint32).T)
    mesher = zmesh.Mesher((dx, dy, dz))
    mesher.mesh(labels, close=True)
    got = mesher.get(1, normals=False)
    verts = np.asarray(got.vertices, dtype=np.float64) - (dx, dy, dz) + np.asarray(origin, dtype=np.float64)
    return _mesh_result(_mesh(verts, got.faces, method="zmesh"))


def serra_mesh_dc(volume, spacing, origin, *, taubin: int = 0) -> Result:
    """``serra_mesh.Mesher`` (multi-material dual contouring) with ``taubin`` smoothing passes (0: none)."""
    serra = _require("serra_mesh", "serra-mesh")
    mesher = serra.Mesher(tuple(float(s) for s in spacing), axis_order="ZYX", taubin=int(taubin), threads=1)
    mesher.mesh(np.ascontiguousarray(np.asarray(volume, dtype=np.uint32)), close=True)
    got = mesher.get(1)
    verts = np.asarray(got.vertices, dtype=np.float64) + np.asarray(origin, dtype=np.float64)
    return _mesh_result(_mesh(verts, got.faces, method="serra-mesh", taubin=int(taubin)))


# --- oriented boundary points (for Open3D and MeshLab) ------------------------------------------
def surfel_points(volume, spacing, origin, *, normal_radius: float = 2.0):
    """Centres of the boundary voxel faces (surfels) and smoothed outward normals.

    Each surfel gets the outward axis normal of its face; the normal used is the average of the
    axis normals of all surfels within ``normal_radius`` voxels (physical radius ``normal_radius``
    times the mean spacing), renormalised.  ``normal_radius=0`` keeps the raw axis normals.

    Returns ``points (n, 3)`` and ``normals (n, 3)``, float64, physical ``(x, y, z)``.
    """
    p = np.pad(volume, 1).view(np.int8)
    pts, nrm = [], []
    for axis in range(3):  # z, y, x
        d = np.diff(p, axis=axis)
        idx = np.argwhere(d != 0).astype(np.float64)
        sign = d[d != 0].astype(np.float64)  # +1: background -> object along +axis, outward is -axis
        idx -= 1.0
        idx[:, axis] += 0.5
        n = np.zeros((len(idx), 3))
        n[:, 2 - axis] = -sign  # column of (x, y, z) for axis (z, y, x)
        pts.append(volume_to_mesh_frame(idx, spacing, origin))
        nrm.append(n)
    pts, nrm = np.concatenate(pts), np.concatenate(nrm)
    if normal_radius > 0 and len(pts):
        from scipy.spatial import cKDTree

        pairs = cKDTree(pts).query_pairs(float(normal_radius) * float(np.mean(spacing)), output_type="ndarray")
        acc = nrm.copy()
        np.add.at(acc, pairs[:, 0], nrm[pairs[:, 1]])
        np.add.at(acc, pairs[:, 1], nrm[pairs[:, 0]])
        length = np.linalg.norm(acc, axis=1, keepdims=True)
        nrm = np.where(length > 1e-12, acc / np.maximum(length, 1e-300), nrm)
    return pts, nrm


def voxel_boundary_mesh(volume, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)) -> Mesh:
    """The boundary of the union of voxels as a triangle mesh (the "cuberille" / staircase surface).

    Every object/background voxel face becomes two triangles, outward; lattice corners shared by
    faces are merged.  Its area is exactly :func:`contourmesh.compare.local.surfel_area`.  The mesh
    is closed; it is non-manifold where two voxels touch only along an edge or at a corner.
    """
    vol, sp, org = check_volume(volume, spacing, origin)
    p = np.pad(vol, 1).view(np.int8)
    quads, normals = [], []
    for axis in range(3):  # z, y, x
        d = np.diff(p, axis=axis)
        idx = np.argwhere(d != 0).astype(np.int64)  # padded index of the voxel below the face
        sign = d[d != 0].astype(np.int64)
        b, c = [a for a in range(3) if a != axis]
        # Corners in doubled padded index units (integers): voxel centre 2i, face plane 2i + 1.
        base = 2 * idx
        base[:, axis] += 1
        corners = []
        for db, dc in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            q = base.copy()
            q[:, b] += db
            q[:, c] += dc
            corners.append(q)
        quads.append(np.stack(corners, axis=1))  # (n, 4, 3) zyx doubled
        n = np.zeros((len(idx), 3))
        n[:, 2 - axis] = -sign
        normals.append(n)
    quads = np.concatenate(quads)
    normals = np.concatenate(normals)
    if len(quads) == 0:
        raise ValueError("the volume is empty: it has no boundary faces")
    keys, inverse = np.unique(quads.reshape(-1, 3), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1, 4)
    faces = np.concatenate([inverse[:, [0, 1, 2]], inverse[:, [0, 2, 3]]])
    vertices = volume_to_mesh_frame(keys / 2.0 - 1.0, sp, org)
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", fn, np.concatenate([normals, normals])) < 0
    faces[flip] = faces[flip][:, ::-1]
    return Mesh(vertices, faces, meta={"method": "voxel-faces"})


def voxel_faces(volume, spacing, origin) -> Result:
    """The staircase surface of the voxels (:func:`voxel_boundary_mesh`): surfel counting with a mesh."""
    return _mesh_result(voxel_boundary_mesh(volume, spacing, origin))


def _o3d_cloud(volume, spacing, origin, normal_radius, estimate_normals: bool, knn: int = 15):
    o3d = _require("open3d", "open3d")
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    pts, nrm = surfel_points(volume, spacing, origin, normal_radius=0.0 if estimate_normals else normal_radius)
    if len(pts) == 0:
        raise ValueError("the volume has no boundary: no points to reconstruct from")
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(pts)
    if estimate_normals:
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=knn))
        pcd.orient_normals_consistent_tangent_plane(knn)
    else:
        pcd.normals = o3d.utility.Vector3dVector(nrm)
    return o3d, pcd


def _o3d_mesh(m, **meta) -> Mesh:
    return _mesh(np.asarray(m.vertices), np.asarray(m.triangles), **meta)


def o3d_poisson(volume, spacing, origin, *, depth: int = 8, normal_radius: float = 2.0,
                estimate_normals: bool = False) -> Result:
    """Open3D screened Poisson reconstruction (Kazhdan & Hoppe 2013) from surfel points.

    Points: surfel centres; normals: surfel normals averaged over ``normal_radius`` voxels
    (:func:`surfel_points`), or with ``estimate_normals`` Open3D's PCA ``estimate_normals`` plus
    ``orient_normals_consistent_tangent_plane`` (k = 15).  No density trimming (the surface is
    kept closed).  Single-threaded (``n_threads=1``) for reproducibility.
    """
    o3d, pcd = _o3d_cloud(volume, spacing, origin, normal_radius, estimate_normals)
    m, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=int(depth), n_threads=1)
    mesh = _o3d_mesh(m, method="o3d-poisson", depth=int(depth))
    return _mesh_result(mesh, points=len(pcd.points), min_density=float(np.min(np.asarray(dens))) if len(dens) else None)


def o3d_ball_pivoting(volume, spacing, origin, *, radius: float = 1.0, normal_radius: float = 2.0,
                      estimate_normals: bool = False) -> Result:
    """Open3D ball pivoting (Bernardini et al. 1999) from surfel points, radii ``radius * (1, 1.5, 2)`` voxels."""
    o3d, pcd = _o3d_cloud(volume, spacing, origin, normal_radius, estimate_normals)
    h = float(np.mean(spacing))
    radii = o3d.utility.DoubleVector([float(radius) * h * k for k in (1.0, 1.5, 2.0)])
    m = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(pcd, radii)
    if len(m.triangles) == 0:
        raise RuntimeError(f"ball pivoting made no triangles with radius {radius} voxels")
    return _mesh_result(_o3d_mesh(m, method="o3d-bpa", radius=radius), points=len(pcd.points))


def o3d_alpha_shape(volume, spacing, origin, *, alpha: float = 1.0, surfels: bool = False) -> Result:
    """Open3D alpha shape (Edelsbrunner & Muecke 1994), ``alpha`` in voxels.

    Default input: the centres of **all object voxels**, jittered by 1e-6 voxel (seeded) to
    break the lattice's co-spherical degeneracies, which otherwise make Open3D's tetrahedral mesh
    invalid; the alpha shape of the solid is then a closed surface through the boundary voxel
    centres once ``alpha`` exceeds the cell's half diagonal (0.87 voxel).  With ``surfels=True``
    the input is the surfel centres, as for the other point methods; their alpha complex is a
    two-sided shell (about +100 % to +200 % area), kept only for comparison.
    """
    o3d = _require("open3d", "open3d")
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    h = float(np.mean(spacing))
    if surfels:
        pts, _ = surfel_points(volume, spacing, origin, normal_radius=0.0)
    else:
        pts = volume_to_mesh_frame(np.argwhere(volume), spacing, origin)
    if len(pts) < 4:
        raise ValueError(f"the alpha shape needs at least 4 points; the volume gives {len(pts)}")
    pts = pts + 1e-6 * h * np.random.default_rng(0).standard_normal(pts.shape)
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(pts)
    m = o3d.geometry.TriangleMesh.create_from_point_cloud_alpha_shape(pcd, float(alpha) * h)
    if len(m.triangles) == 0:
        raise RuntimeError(f"the alpha shape with alpha {alpha} voxels has no triangles (alpha must exceed 0.87)")
    return _mesh_result(_o3d_mesh(m, method="o3d-alpha", alpha=alpha, surfels=surfels), points=len(pts))


# --- PyMeshLab ----------------------------------------------------------------------------------
def _ml_points(volume, spacing, origin, normal_radius):
    pymeshlab = _require("pymeshlab", "pymeshlab")
    pts, nrm = surfel_points(volume, spacing, origin, normal_radius=normal_radius)
    if len(pts) == 0:
        raise ValueError("the volume has no boundary: no points to reconstruct from")
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=pts, v_normals_matrix=nrm), "surfels")
    return pymeshlab, ms, len(pts)


def _ml_current(ms, **meta) -> Mesh:
    cm = ms.current_mesh()
    return _mesh(cm.vertex_matrix(), cm.face_matrix(), **meta)


def ml_screened_poisson(volume, spacing, origin, *, depth: int = 8, normal_radius: float = 2.0) -> Result:
    """PyMeshLab ``generate_surface_reconstruction_screened_poisson`` (Kazhdan & Hoppe 2013) from surfel points.

    Points and normals as for :func:`o3d_poisson`; ``threads=1``; no pre-cleaning.
    """
    pymeshlab, ms, n = _ml_points(volume, spacing, origin, normal_radius)
    ms.generate_surface_reconstruction_screened_poisson(depth=int(depth), threads=1, preclean=False)
    return _mesh_result(_ml_current(ms, method="ml-spoisson", depth=int(depth)), points=n)


def ml_ball_pivoting(volume, spacing, origin, *, radius: float = 1.0, normal_radius: float = 2.0) -> Result:
    """PyMeshLab ``generate_surface_reconstruction_ball_pivoting`` with ball radius ``radius`` voxels."""
    pymeshlab, ms, n = _ml_points(volume, spacing, origin, normal_radius)
    ms.generate_surface_reconstruction_ball_pivoting(ballradius=pymeshlab.PureValue(float(radius) * float(np.mean(spacing))))
    if ms.current_mesh().face_number() == 0:
        raise RuntimeError(f"ball pivoting made no triangles with radius {radius} voxels")
    return _mesh_result(_ml_current(ms, method="ml-bpa", radius=radius), points=n)


def ml_alpha_wrap(volume, spacing, origin, *, alpha: float = 2.0, offset: float = 0.1) -> Result:
    """PyMeshLab ``generate_alpha_wrap`` (CGAL 3D alpha wrapping) of the voxel staircase surface.

    The input is :func:`voxel_boundary_mesh` (the surfel quads), not the bare surfel centres:
    pymeshlab 2025.7 crashes (segmentation fault) when wrapping a point cloud without faces.
    ``alpha`` and ``offset`` in voxels (absolute values).  The wrap is closed and lies ``offset``
    outside the staircase; with ``alpha`` of a few voxels it bridges the steps.
    """
    pymeshlab = _require("pymeshlab", "pymeshlab")
    stairs = voxel_boundary_mesh(volume, spacing, origin)
    ms = pymeshlab.MeshSet()
    if not hasattr(ms, "generate_alpha_wrap"):
        raise MissingDependency("this pymeshlab has no generate_alpha_wrap: pip install -U pymeshlab (2023.12+)")
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=stairs.vertices, face_matrix=stairs.faces.astype(np.int32)), "voxels")
    h = float(np.mean(spacing))
    ms.generate_alpha_wrap(alpha=pymeshlab.PureValue(float(alpha) * h), offset=pymeshlab.PureValue(float(offset) * h))
    return _mesh_result(_ml_current(ms, method="ml-alphawrap", alpha=alpha, offset=offset),
                        input_faces=int(len(stairs.faces)))


# --- local estimators ---------------------------------------------------------------------------
def surfel_count(volume, spacing, origin) -> Result:
    """Surfel counting (:func:`contourmesh.compare.local.surfel_area`), about +50 % on smooth shapes."""
    return Result(area=surfel_area(volume, spacing), extra={"faces_zyx": boundary_face_counts(volume).tolist()})


def mullikin_verbeek(volume, spacing, origin) -> Result:
    """Mullikin & Verbeek (1993) weighted surface-voxel counting (:func:`~contourmesh.compare.local.mullikin_verbeek_area`)."""
    area, counts = mullikin_verbeek_area(volume, spacing)
    return Result(area=area, extra=counts)


def lindblad(volume, spacing, origin, *, a1: float = 0.6380) -> Result:
    """Lindblad (2005) weighted m-cube configurations (:func:`~contourmesh.compare.local.lindblad_area`)."""
    area, per_case = lindblad_area(volume, spacing, a1=a1)
    return Result(area=area, extra={"cases": per_case.tolist()})


# --- DGtal --------------------------------------------------------------------------------------
def dgtal_integration(volume, spacing, origin, *, estimator: str = "ii", radius: float = 3.0,
                      offset_radius: float = 5.0) -> Result:
    """Digital integration with DGtal: area = sum over surfels of ``|n . n_surfel|`` times the surfel area.

    Normals ``n`` from DGtal's Shortcuts: integral invariants (``estimator="ii"``, ball radius
    ``radius`` voxels; Coeurjolly, Lachaud & Levallois 2014) or the Voronoi covariance measure
    (``"vcm"``, offset ``offset_radius`` and integration ``radius`` voxels, hat kernel; Cuel,
    Lachaud, Merigot & Thibert 2015).  The binary image is built from numpy and passed to
    ``SH3.makeBinaryImage(values, domain)`` (``makeDigitizedImplicitShape3D`` is not used).
    DGtal works on the unit grid; for anisotropic spacing the grid normal is mapped to physical
    space (``n / spacing``, renormalised) and a surfel normal to axis k has area
    ``prod(spacing) / spacing_k``.
    """
    dgtal = _require("dgtal", "dgtal")
    SH3 = dgtal.SH3
    P = dgtal.kernel.Point3D
    nz, ny, nx = volume.shape
    pad = int(math.ceil(max(radius, offset_radius if estimator == "vcm" else 0.0))) + 2
    vol = np.pad(volume, pad)
    if not vol.any():
        raise ValueError("the volume is empty: no surfels")
    dom = dgtal.kernel.DomainZ3i(P(0, 0, 0), P(vol.shape[2] - 1, vol.shape[1] - 1, vol.shape[0] - 1))
    img = SH3.makeBinaryImage(vol.astype(np.float64).ravel(order="C").tolist(), dom)  # x fastest
    params = SH3.defaultParameters()
    params.set("verbose", 0)
    params.set("surfaceComponents", "All")
    K = SH3.getKSpace(img, params)
    gp = SH3.parametersGeometryEstimation()
    gp.set("verbose", 0)
    gp.set("gridstep", 1.0)
    gp.set("r-radius", float(radius))
    if estimator == "vcm":
        gp.set("R-radius", float(offset_radius))
        gp.set("kernel", "hat")
    elif estimator != "ii":
        raise ValueError(f"estimator must be 'ii' or 'vcm'; got {estimator!r}")
    n_grid, kc = [], []
    # One light digital surface per boundary component ("surfaceComponents" = "All").
    # (SH3.makeDigitalSurface's return type is not bound in the Python package.)
    for surface in SH3.makeLightDigitalSurfaces(img, K, params):
        surfels = SH3.getSurfelRange(surface, params)
        if estimator == "ii":
            normals = SH3.getIINormalVectors(img, surfels, gp)
        else:
            normals = SH3.getVCMNormalVectors(surface, surfels, gp)
        if len(normals) != len(surfels):
            raise RuntimeError("DGtal returned a normal range that does not match its surfel range")
        n_grid += [[nv[0], nv[1], nv[2]] for nv in normals]  # (x, y, z)
        kc += [K.sKCoords(s) for s in surfels]
    n_grid = np.array(n_grid, dtype=np.float64).reshape(-1, 3)
    kc = np.array(kc, dtype=np.int64).reshape(-1, 3)
    expected = int(boundary_face_counts(volume).sum())
    if len(kc) != expected or np.any((kc % 2).sum(axis=1) != 2):
        raise RuntimeError(f"DGtal's digital surfaces have {len(kc)} surfels; the volume has {expected} boundary faces")
    axis = np.argmin(kc % 2, axis=1)  # the even Khalimsky coordinate is the surfel's normal axis
    dxyz = np.asarray(spacing, dtype=np.float64)[::-1]
    n_phys = n_grid / dxyz
    n_phys /= np.maximum(np.linalg.norm(n_phys, axis=1, keepdims=True), 1e-300)
    face_area = np.prod(dxyz) / dxyz[axis]
    area = math.fsum(face_area * np.abs(n_phys[np.arange(len(axis)), axis]))
    return Result(area=area, extra={"surfels": int(len(kc)), "estimator": estimator})


# --- ours ---------------------------------------------------------------------------------------
OURS_POLYGONS = tuple(sorted(POLYGONIZERS))  # the registries' names, so every strategy is reachable
OURS_TRIANGULATIONS = tuple(sorted(TRIANGULATORS))


def parse_ours(name: str):
    """``(polygon, triangulation, refine)`` of a name ``"ours-<polygon>-<triangulation>[-band]"``
    (refine ``band``: :mod:`contourmesh.refine`), None for names that are not ours."""
    if not isinstance(name, str) or not (name == "ours" or name.startswith("ours-")):
        return None
    parts = name.split("-")
    ok = (len(parts) in (3, 4) and parts[1] in OURS_POLYGONS and parts[2] in OURS_TRIANGULATIONS
          and (len(parts) == 3 or parts[3] == "band"))
    if not ok:
        raise ValueError(f"our method's name is ours-<polygon>-<triangulation>[-band] with polygon in {OURS_POLYGONS} "
                         f"and triangulation in {OURS_TRIANGULATIONS}; got {name!r}")
    return parts[1], parts[2], (parts[3] if len(parts) == 4 else "none")


def ours_volume(volume, spacing, origin, *, polygon: str, triangulation: str, refine: str = "none") -> Result:
    """The paper's method (Wiederhold & Villafuerte 2009) on a binary volume ``[z, y, x]``.

    ``contourmesh.mesh(volume, spacing=(dz, dy, dx), origin=(x0, y0, z0), ...)``; ``refine="band"``
    adds the multigrid-convergent refinement.  ``P`` is the paper's vertex count.
    """
    kw = {"refine": refine} if refine != "none" else {}
    m = _mesh_source(volume, spacing=tuple(spacing), origin=tuple(origin), polygon=polygon,
                     triangulation=triangulation, **kw)
    return Result(area=float(m.area), mesh=m, P=int(m.P))


def ours_shape(shape, h: float = 1.0, *, polygon: str, triangulation: str, refine: str = "none") -> Result:
    """The paper's method on an analytic shape: the outer Jordan contours of the grid points
    strictly inside each slice ``z = k h`` (the slices of the shape's Gauss volume)."""
    kw = {"refine": refine} if refine != "none" else {}
    m = _mesh_source(shape, polygon=polygon, triangulation=triangulation, h=h, **kw)
    return Result(area=float(m.area), mesh=m, P=int(m.P))


def _ours(name: str, parsed) -> Method:
    params = {"polygon": parsed[0], "triangulation": parsed[1]}
    if parsed[2] != "none":
        params["refine"] = parsed[2]
    return Method(name=name, family="ours", params=params, fn=ours_volume, shape_fn=ours_shape)


# --- registry -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Spec:
    family: str
    fn: Callable
    keys: dict  # name token prefix -> (parameter name, type, default)
    flags: dict = field(default_factory=dict)  # flag word -> (parameter name, value)
    fixed: dict = field(default_factory=dict)  # parameters fixed by the base name


_REGISTRY: dict[str, _Spec] = {
    "mc-lewiner": _Spec("marching-cubes", marching_cubes, {"blur": ("blur", float, 0.0)}, fixed={"method": "lewiner"}),
    "mc-lorensen": _Spec("marching-cubes", marching_cubes, {"blur": ("blur", float, 0.0)}, fixed={"method": "lorensen"}),
    "vtk-flyingedges": _Spec("vtk", vtk_flying_edges, {"blur": ("blur", float, 0.0)}),
    "vtk-discreteflyingedges": _Spec("vtk", vtk_discrete_flying_edges, {}),
    "vtk-surfacenets": _Spec("vtk", vtk_surface_nets, {"it": ("iterations", int, 16)}),
    "zmesh": _Spec("multilabel", zmesh_mc, {}),
    "serra": _Spec("multilabel", serra_mesh_dc, {"taubin": ("taubin", int, 0)}),
    "o3d-poisson": _Spec("open3d", o3d_poisson, {"d": ("depth", int, 8), "nr": ("normal_radius", float, 2.0)},
                         {"estnormals": ("estimate_normals", True)}),
    "o3d-bpa": _Spec("open3d", o3d_ball_pivoting, {"r": ("radius", float, 1.0), "nr": ("normal_radius", float, 2.0)},
                     {"estnormals": ("estimate_normals", True)}),
    "o3d-alpha": _Spec("open3d", o3d_alpha_shape, {"a": ("alpha", float, 1.0)}, {"surfels": ("surfels", True)}),
    "ml-spoisson": _Spec("meshlab", ml_screened_poisson, {"d": ("depth", int, 8), "nr": ("normal_radius", float, 2.0)}),
    "ml-bpa": _Spec("meshlab", ml_ball_pivoting, {"r": ("radius", float, 1.0), "nr": ("normal_radius", float, 2.0)}),
    "ml-alphawrap": _Spec("meshlab", ml_alpha_wrap, {"a": ("alpha", float, 2.0), "o": ("offset", float, 0.1)}),
    "surfels": _Spec("local", surfel_count, {}),
    "voxel-faces": _Spec("local", voxel_faces, {}),
    "mullikin-verbeek": _Spec("local", mullikin_verbeek, {}),
    "lindblad": _Spec("local", lindblad, {"a": ("a1", float, 0.6380)}),
    "dgtal-ii": _Spec("dgtal", dgtal_integration, {"r": ("radius", float, 3.0)}, fixed={"estimator": "ii"}),
    "dgtal-vcm": _Spec("dgtal", dgtal_integration, {"R": ("offset_radius", float, 5.0), "r": ("radius", float, 3.0)},
                       fixed={"estimator": "vcm"}),
}

#: Methods registered at run time (:func:`register_method`), looked up by exact name.
_EXTRA: dict[str, Method] = {}

#: The default line-up of :func:`available_methods`.
DEFAULT_METHODS = (
    "ours-mlp-wiederhold", "mc-lewiner", "mc-lorensen", "mc-lewiner-blur1", "vtk-flyingedges", "vtk-discreteflyingedges",
    "vtk-surfacenets", "o3d-poisson-d8", "o3d-bpa-r1", "o3d-alpha-a1", "ml-spoisson-d8", "ml-bpa-r1",
    "ml-alphawrap-a2-o0.1", "surfels", "voxel-faces", "mullikin-verbeek", "lindblad", "dgtal-ii-r3", "dgtal-vcm-R5-r3",
)

_TOKEN = re.compile(r"^([A-Za-z]+)(\d+(?:\.\d*)?|\.\d+)$")


def _valid_names_text() -> str:
    lines = []
    for base, spec in _REGISTRY.items():
        keys = "".join(f"[-{k}<{t.__name__}>]" for k, (_, t, _) in spec.keys.items())
        flags = "".join(f"[-{w}]" for w in spec.flags)
        lines.append(f"{base}{keys}{flags}")
    lines.append(f"ours-<{'|'.join(OURS_POLYGONS)}>-<{'|'.join(OURS_TRIANGULATIONS)}>[-band]")
    lines += sorted(_EXTRA)
    return "; ".join(lines)


def get_method(name: str) -> Method:
    """The :class:`Method` a name denotes, with the parameters its suffixes give.

    ``"mc-lewiner-blur1.5"`` -> marching cubes (Lewiner) with ``blur=1.5``; unknown names or
    tokens raise ValueError listing the valid forms.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"a method name is a non-empty string; got {name!r}")
    if name in _EXTRA:
        return _EXTRA[name]
    ours = parse_ours(name)
    if ours is not None:
        return _ours(name, ours)
    base = max((b for b in _REGISTRY if name == b or name.startswith(b + "-")), key=len, default=None)
    if base is None:
        raise ValueError(f"unknown method {name!r}; valid names: {_valid_names_text()}")
    spec = _REGISTRY[base]
    params = {pname: default for (pname, _, default) in spec.keys.values()}
    for token in filter(None, name[len(base):].split("-")):
        if token in spec.flags:
            pname, value = spec.flags[token]
            params[pname] = value
            continue
        m = _TOKEN.match(token)
        if not m or m.group(1) not in spec.keys:
            raise ValueError(
                f"method {name!r}: cannot read parameter {token!r} for {base!r}; valid names: {_valid_names_text()}"
            )
        pname, typ, _ = spec.keys[m.group(1)]
        value = float(m.group(2))
        if typ is int:
            if value != int(value):
                raise ValueError(f"method {name!r}: parameter {m.group(1)!r} must be an integer; got {m.group(2)}")
            value = int(value)
        params[pname] = value
    params.update(spec.fixed)
    return Method(name=name, family=spec.family, params=params, fn=spec.fn)


def register_method(method: Method) -> None:
    """Add a method under its exact name (e.g. ours, or a test double); it shadows name parsing."""
    if not isinstance(method, Method):
        raise ValueError(f"register_method expects a Method; got {type(method).__name__}")
    if method.family not in FAMILIES:
        raise ValueError(f"method family must be one of {FAMILIES}; got {method.family!r}")
    _EXTRA[method.name] = method


def unregister_method(name: str) -> None:
    """Remove a method added with :func:`register_method` (no error when absent)."""
    _EXTRA.pop(name, None)


def available_methods() -> list[str]:
    """The default line-up of method names (each parameterisable; see :func:`get_method`) plus registered ones."""
    return list(DEFAULT_METHODS) + sorted(n for n in _EXTRA if n not in DEFAULT_METHODS)


# --- running ------------------------------------------------------------------------------------
def _row(name: str) -> dict:
    return {"method": name, "family": None, "params": None, "status": None, "error": None, "area": None,
            "P": None, "faces": None, "watertight": None, "winding_consistent": None, "volume": None,
            "seconds": None, "extra": {}, "mesh": None}


def _run_inprocess(name, volume, spacing, origin, postprocess=()) -> dict:
    row = _row(name)
    t0 = time.perf_counter()
    try:
        method = get_method(name)
        row["family"], row["params"] = method.family, dict(method.params)
        res = method.fn(volume, spacing, origin, **method.params)
        if not isinstance(res, Result):
            raise TypeError(f"method {name!r} returned {type(res).__name__}, expected Result")
        mesh = res.mesh
        extra = dict(res.extra)
        if postprocess:
            if mesh is None:
                raise ValueError(f"method {name!r} makes no mesh; post-processes {list(postprocess)} need one")
            extra["post"] = []
            for pname in postprocess:
                mesh, info = apply_postprocess(pname, mesh)
                extra["post"].append(info)
            res = Result(area=mesh.area, mesh=mesh, P=int(len(mesh.vertices)), extra=extra)
        row["seconds"] = time.perf_counter() - t0
        row.update(status="ok", area=float(res.area), P=res.P, extra=extra, mesh=mesh)
        if mesh is not None:
            chk = mesh_checks(mesh.vertices, mesh.faces)
            row.update(faces=int(len(mesh.faces)), watertight=chk["watertight"],
                       winding_consistent=chk["winding_consistent"], volume=chk["volume"])
    except ImportError as exc:
        row.update(status="not-installed", error=str(exc), seconds=time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - a method's failure is a row, not a crash
        row.update(status="failed", error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - t0)
        row["extra"] = {"traceback": traceback.format_exc(limit=6)}
    return row


def run_method(name: str, volume, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), timeout: float | None = None,
               postprocess=()) -> dict:
    """Run a method on a binary volume and return a table row; never raises for the method's failure.

    Parameters
    ----------
    name : str
        A method name (:func:`get_method`).
    volume : (nz, ny, nx) bool array
        Indexed ``[z, y, x]``.  A malformed volume, spacing or origin raises ValueError (that is the
        caller's error, not the method's).
    spacing, origin : 3-sequences
        ``(dz, dy, dx)`` and the physical ``(x0, y0, z0)`` of voxel ``[0, 0, 0]``'s centre.
    timeout : float, optional
        Seconds.  ``None`` runs in this process.  Otherwise the method runs in a fresh Python
        process (:func:`contourmesh.compare.execute.call_in_subprocess`) that is killed at the
        deadline (a thread cannot be stopped); the limit includes the interpreter start-up and
        the method's imports (about 1-3 s), and registered methods (:func:`register_method`) are
        not visible there.
    postprocess : str or sequence of str
        Post-process names (:mod:`contourmesh.compare.postprocess`) applied in order to the mesh;
        the row's area and P are then the final mesh's, ``extra["post"]`` has before/after figures.

    Returns
    -------
    dict
        ``method, family, params, status ("ok" | "not-installed" | "failed" | "timeout"), error,
        area, P, faces, watertight, winding_consistent, volume, seconds`` (wall clock, including
        post-processes), ``extra`` and ``mesh`` (the Mesh, or None).
    """
    vol, sp, org = check_volume(volume, spacing, origin)
    post = (postprocess,) if isinstance(postprocess, str) else tuple(postprocess or ())
    if timeout is None:
        return _run_inprocess(name, vol, sp, org, post)
    if not timeout > 0:
        raise ValueError(f"timeout must be a positive number of seconds or None; got {timeout!r}")
    try:
        status, value, seconds = call_in_subprocess(_run_inprocess, name, vol, sp, org, post, timeout=timeout,
                                                    kill_after=timeout)
    except ExecutorError as exc:
        status, value, seconds = "executor", str(exc), None
    if status == "ok":
        return value
    row = _row(name)
    if status == "timeout":
        row.update(status="timeout", error=f"no result within {timeout} s", seconds=seconds)
    elif status == "died":
        row.update(status="failed", error=value, seconds=seconds)
    else:
        row.update(status="failed", error=f"the executor failed (not the method): {value}", seconds=seconds)
    try:
        m = get_method(name)
        row["family"], row["params"] = m.family, dict(m.params)
    except ValueError:
        pass
    return row
