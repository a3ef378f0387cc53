"""Local surface-area estimators on binary volumes: counting and weighting voxel faces and m-cubes.

These are *estimators*, not mesh sources: they read the area straight off local voxel
configurations and make no surface.  All take a binary volume indexed ``[z, y, x]`` (numpy /
scikit-image order) with ``spacing = (dz, dy, dx)`` and return physical areas.  Everything
outside the array counts as background (the volume is padded with one empty layer).

* :func:`surfel_area` - the area of the voxel boundary ("surfel counting"): every object /
  background face counts with its full area.  Anisotropic spacing is respected.  On smooth
  shapes it overestimates by about 3/2 (the mean of ``|n_x| + |n_y| + |n_z|`` over the sphere).
* :func:`mullikin_verbeek_area` - weighted surface-voxel counting, J. C. Mullikin and P. W.
  Verbeek, "Surface area estimation of digitized planes", Bioimaging 1 (1993) 6-16.
* :func:`lindblad_area` - weighted local configurations (m-cubes, the 2x2x2 windows of marching
  cubes), J. Lindblad, "Surface area estimation of digitized 3D objects using weighted local
  configurations", Image and Vision Computing 23 (2005) 111-122.

The weighted estimators are defined on cubic grids; they accept isotropic spacing only.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..volume_input import binary_volume, check_spacing

__all__ = [
    "MULLIKIN_VERBEEK_WEIGHTS",
    "LINDBLAD_A1",
    "boundary_face_counts",
    "surfel_area",
    "exposed_faces",
    "mullikin_verbeek_area",
    "mcube_histogram",
    "mcube_case",
    "lindblad_case_areas",
    "lindblad_area",
]

#: Mullikin & Verbeek (1993) optimal weights, in grid units squared, for a surface voxel with one,
#: two or three mutually adjacent faces exposed to the background (the abstract of the paper:
#: W1 ~ 0.8940, W2 ~ 1.3409, W3 ~ 1.5879; also tabulated by Windreich, Kiryati & Lohmann,
#: "Voxel-based surface area estimation: from theory to practice", Pattern Recognition 36 (2003)).
MULLIKIN_VERBEEK_WEIGHTS = (0.8940, 1.3409, 1.5879)

#: Lindblad (2005)'s free parameter: the area of marching-cubes case 1 (one corner set).
LINDBLAD_A1 = 0.6380


# --- input checks -------------------------------------------------------------------------------
_check_volume = binary_volume  # the package's one volume validator
_check_spacing = check_spacing


def _isotropic(spacing) -> float:
    s = _check_spacing(spacing)
    if not np.allclose(s, s[0], rtol=1e-12, atol=0):
        raise ValueError(
            f"this estimator's weights are defined on a cubic grid; spacing must be isotropic, got {tuple(s)}"
        )
    return float(s[0])


# --- surfel counting ----------------------------------------------------------------------------
def boundary_face_counts(volume) -> np.ndarray:
    """Number of object/background voxel faces, by the axis they are normal to.

    Returns an int64 array ``(n_z, n_y, n_x)``: ``n_z`` faces normal to z, and so on.
    """
    v = np.pad(_check_volume(volume), 1).view(np.int8)
    return np.array([np.count_nonzero(np.diff(v, axis=a)) for a in range(3)], dtype=np.int64)


def surfel_area(volume, spacing=(1.0, 1.0, 1.0)) -> float:
    """Surfel counting: the area of the boundary of the union of voxels.

    A face normal to z has area ``dx * dy``, normal to y ``dx * dz``, normal to x ``dy * dz``.
    The estimator is not multigrid convergent: on a sphere it tends to 3/2 of the true area.
    """
    dz, dy, dx = _check_spacing(spacing)
    nz, ny, nx = boundary_face_counts(volume)
    return float(nz * dx * dy + ny * dx * dz + nx * dy * dz)


# --- Mullikin & Verbeek -------------------------------------------------------------------------
def exposed_faces(volume) -> np.ndarray:
    """6-bit code of the faces of every voxel that touch the background.

    Bit 0: -x, 1: +x, 2: -y, 3: +y, 4: -z, 5: +z.  Background voxels get 0, as do interior ones.
    Returned as a uint8 array of the volume's shape.
    """
    v = _check_volume(volume)
    p = np.pad(v, 1)
    inner = (slice(1, -1),) * 3
    code = np.zeros(v.shape, dtype=np.uint8)
    bit = 0
    for axis in (2, 1, 0):  # x, y, z
        for step in (-1, 1):
            sl = list(inner)
            sl[axis] = slice(1 + step, p.shape[axis] - 1 + step)
            code |= ((v & ~p[tuple(sl)]).astype(np.uint8) << bit)
            bit += 1
    return code


@lru_cache(maxsize=None)
def _mv_table(w1: float, w2: float, w3: float) -> tuple:
    """Weight and class of each of the 64 exposure codes.

    Classes: 1, 2, 3 = one, two or three mutually adjacent exposed faces (Mullikin & Verbeek's
    three basic types, the only ones on digital planes); 0 = any other configuration (two opposite
    faces, three faces with an opposite pair, four or more faces).  The paper gives no weight for
    these; we weigh each of their exposed faces as a lone face (``k * W1``) and report how many
    there were.
    """
    weights = np.zeros(64)
    kinds = np.zeros(64, dtype=np.int64)
    for c in range(1, 64):
        bits = [(c >> b) & 1 for b in range(6)]
        k = sum(bits)
        opposite = any(bits[2 * i] and bits[2 * i + 1] for i in range(3))
        if k <= 3 and not opposite:
            weights[c], kinds[c] = (w1, w2, w3)[k - 1], k
        else:
            weights[c], kinds[c] = k * w1, 0
    return weights, kinds


def mullikin_verbeek_area(volume, spacing=(1.0, 1.0, 1.0), weights=MULLIKIN_VERBEEK_WEIGHTS) -> tuple[float, dict]:
    """Mullikin & Verbeek (1993) weighted surface-voxel counting.

    Each surface voxel (an object voxel 6-adjacent to the background) contributes a weight chosen by
    how many of its faces are exposed: ``W1, W2, W3`` for one, two or three mutually adjacent faces
    (defaults :data:`MULLIKIN_VERBEEK_WEIGHTS`, optimal and unbiased for randomly oriented planes).
    Other configurations, which do not occur on planes, count ``W1`` per exposed face.

    Returns
    -------
    area : float
        Estimated area in physical units (``spacing**2`` times the weighted count).
    counts : dict
        ``{"S1": n1, "S2": n2, "S3": n3, "other": n_other}`` surface voxels per type.
    """
    h = _isotropic(spacing)
    w1, w2, w3 = (float(w) for w in weights)
    table, kinds = _mv_table(w1, w2, w3)
    hist = np.bincount(exposed_faces(volume).ravel(), minlength=64)
    hist[0] = 0
    by_kind = np.bincount(kinds, weights=hist, minlength=4).astype(np.int64)
    counts = {"S1": int(by_kind[1]), "S2": int(by_kind[2]), "S3": int(by_kind[3]), "other": int(by_kind[0])}
    return math.fsum(hist * table) * h * h, counts


# --- Lindblad: weighted m-cube configurations ---------------------------------------------------
def mcube_histogram(volume) -> np.ndarray:
    """How many times each of the 256 m-cube configurations occurs.

    An m-cube is a 2x2x2 window of voxel centres; its code has bit ``4*dz + 2*dy + dx`` set when
    the voxel at offset ``(dz, dy, dx)`` is object.  The volume is padded with one background layer
    so that every window touching the object is counted.  Returns an int64 array of length 256.
    """
    p = np.pad(_check_volume(volume), 1)
    nz, ny, nx = p.shape
    code = np.zeros((nz - 1, ny - 1, nx - 1), dtype=np.uint8)
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                code |= p[dz:nz - 1 + dz, dy:ny - 1 + dy, dx:nx - 1 + dx].astype(np.uint8) << (4 * dz + 2 * dy + dx)
    return np.bincount(code.ravel(), minlength=256).astype(np.int64)


def _corner(i: int) -> tuple:
    return (i >> 2) & 1, (i >> 1) & 1, i & 1


@lru_cache(maxsize=None)
def _mcube_cases() -> np.ndarray:
    """Marching-cubes case (0-13, Lorensen & Cline's numbering, mirror cases 11/14 merged) of each code.

    The case is read off invariants of the set of corners, after replacing a set of more than
    four corners by its complement (complementary configurations share their surface):
    the number of corners ``n`` and, among them, the numbers of cube edges, face diagonals and
    body diagonals, and the degree pattern of the edge graph.
    """
    cases = np.zeros(256, dtype=np.int64)
    for code in range(256):
        c = code if bin(code).count("1") <= 4 else 255 - code
        pts = [_corner(i) for i in range(8) if (c >> i) & 1]
        n = len(pts)
        dist = [[sum(a != b for a, b in zip(p, q)) for q in pts] for p in pts]
        edges = sum(dist[i][j] == 1 for i in range(n) for j in range(i + 1, n))
        degree = sorted(sum(d == 1 for d in row) for row in dist)
        if n == 0:
            case = 0
        elif n == 1:
            case = 1
        elif n == 2:
            case = {1: 2, 2: 3, 3: 4}[dist[0][1]]  # edge, face diagonal, body diagonal
        elif n == 3:
            case = {2: 5, 1: 6, 0: 7}[edges]  # L on a face, edge + lone corner, three lone corners
        else:
            if edges == 4:
                case = 8  # a whole face
            elif edges == 3:
                case = 9 if degree[-1] == 3 else 11  # tripod (hexagon) | zig-zag path (cases 11/14)
            elif edges == 2:
                case = 10 if degree == [1, 1, 1, 1] else 12  # two opposite edges | L + lone corner
            elif edges == 0:
                case = 13  # four lone corners (tetrahedron)
            else:  # pragma: no cover - an edge and two lone corners cannot occur in a cube
                raise AssertionError(f"unexpected m-cube configuration {code}")
        cases[code] = case
    return cases


def mcube_case(code: int) -> int:
    """The marching-cubes case (0-13) of an 8-bit m-cube code (see :func:`mcube_histogram`)."""
    if not 0 <= int(code) < 256:
        raise ValueError(f"an m-cube code is an integer in [0, 255]; got {code!r}")
    return int(_mcube_cases()[int(code)])


def lindblad_case_areas(a1: float = LINDBLAD_A1) -> np.ndarray:
    """Area weight of each of the 14 marching-cubes cases (Lindblad 2005).

    The weights are unbiased for randomly oriented planes for any choice of the case-1 area ``a1``
    (Lindblad 2005; ``a1 = 0.6380`` minimises the variance, the value of that paper): case 2
    ``A2 = 0.6690``, case 5 ``A5 = 1.1897 - a1``, case 8 ``A8 = 0.9270``, case 9
    ``A9 = 1.6942 - 2 a1``; the non-planar case 11 takes its marching-cubes triangulation's area
    ``A11 = 1.573132``; the remaining cases are unions of these (case 3 and 4 = two case-1 corners,
    6 = 1 + 2, 7 = three case-1 corners, 10 = two case-2 edges, 12 = 1 + 5, 13 = four corners).
    """
    a1 = float(a1)
    a2, a5, a8, a9, a11 = 0.6690, 1.1897 - a1, 0.9270, 1.6942 - 2 * a1, 1.573132
    return np.array([0.0, a1, a2, 2 * a1, 2 * a1, a5, a1 + a2, 3 * a1, a8, a9, 2 * a2, a11, a1 + a5, 4 * a1])


def lindblad_area(volume, spacing=(1.0, 1.0, 1.0), a1: float = LINDBLAD_A1) -> tuple[float, np.ndarray]:
    """Lindblad (2005) surface area from weighted local configurations.

    Sums, over all 2x2x2 m-cubes of the (padded) volume, the area weight of the m-cube's
    marching-cubes case (:func:`lindblad_case_areas`).  Returns the area in physical units and the
    histogram of the 14 cases.
    """
    h = _isotropic(spacing)
    per_case = np.bincount(_mcube_cases(), weights=mcube_histogram(volume), minlength=14).astype(np.int64)
    per_case[0] = 0
    return math.fsum(per_case * lindblad_case_areas(a1)) * h * h, per_case
