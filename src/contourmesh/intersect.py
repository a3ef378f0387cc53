"""Self-intersections of a triangle mesh: which pairs of faces meet other than as neighbours.

A closed mesh bounds a solid only if it is *embedded*: two faces may meet along an edge they
share or at a vertex they share, and nowhere else.  :func:`intersecting_pairs` lists the face
pairs that break this, :func:`self_intersections` counts them.

What counts as an intersection
------------------------------
Faces are closed triangles (boundary included).  Vertices are identified by position: two
vertex indices with bit-identical coordinates are one vertex (meshes of this package are welded;
a duplicate vertex is reported separately by :func:`contourmesh.measure.mesh_checks`).  For a
pair of faces, by the number of vertices they share:

* **none**: the pair intersects if the closed triangles have any point in common: crossing,
  touching at a point or along a segment (a vertex on the other face, an edge across an edge),
  or overlapping in a common plane.
* **one vertex** ``p``: the pair intersects if the triangles have a point other than ``p`` in
  common: an edge of one pierces or touches the other, or the two lie in one plane and their
  corners at ``p`` overlap (also when they only share a ray from ``p``).
* **two vertices** (a shared edge): the pair intersects only if the two faces lie in one plane on
  the same side of the edge (a fold: they overlap); otherwise they meet exactly along the edge.
* **three vertices**: a face repeated (in either orientation) overlaps itself: counted.

Degenerate faces (a repeated vertex, or three exactly collinear points) have no plane; they are
skipped here (``mesh_checks`` counts them, with a tolerance, as ``degenerate_faces``).

Predicates: exact
-----------------
Every decision is the sign of an orientation determinant (``orient3d`` of four vertices, or
``orient2d`` of three vertices projected on a coordinate plane that keeps the supporting face
non-degenerate), as in the triangle-triangle tests of Moller and Guigue-Devillers.  Each sign is
computed in float64 first and certified with Shewchuk's a-priori error bound (``7 eps`` times the
permanent for ``orient3d``, ``3 eps`` for ``orient2d``, ``eps = 2^-53``); when the bound does not
certify it, the determinant is evaluated again exactly (coordinate differences split into two
doubles, products into error-free pairs, summed into a nonoverlapping expansion).  So every sign
is the exact sign for the float64 coordinates as given: the answer is exact, with **no
tolerance**.  Faces that touch count as intersecting however small the contact; faces apart by
one unit in the last place do not.  (The exact path is rare: voxel meshes, whose coordinates are
small multiples of 1/2 or 1/4, never need it.)

Speed
-----
The broad phase is a uniform grid hashed into a table (cell sizes per axis from the faces'
bounding boxes, grown until every face lies in a bounded number of cells; keys z-major), filled
by a counting sort, a chunk of layers of cells along z at a time (so only one chunk's entries and
faces are held); each pair of faces whose boxes overlap is tested once, in the cell at the low
corner of the overlap of their boxes.  Meshes made from sections have most vertices in the
section planes: two faces whose boxes meet only in a plane ``z = c`` (one below, one above) can
meet only there, in the hull of their corners at that height, so such a pair is decided by one
segment test in that plane (the same rules, the same exact ``orient2d``); so is any pair of faces
without a common vertex whose boxes only touch across some axis.  Most candidate pairs of a closed
mesh share a vertex: where the faces around that vertex project one-to-one along a direction of
components -1, 0, 1 (a certificate per vertex, exact), none of its pairs needs a test ("neighbours
decided at once" below).  Everything runs in one numba kernel on one core; it is near-linear in
the number of faces for meshes whose faces are of comparable size.

Meshes made from sections take a cheaper broad phase that gives the same pairs (``method``):
per slab between consecutive vertex heights a 2D sweep, per height a sweep over the faces' parts
in that plane, and a planar-graph certificate that decides all pairs meeting only in a plane at
once (see "broad phase for sectioned meshes" below).
"""

from __future__ import annotations

import math

import numpy as np

from ._kernels import njit

__all__ = ["intersecting_pairs", "any_intersecting", "self_intersections", "canonical_vertices"]

# Compile-time rules as in contourmesh.fastpath: internal kernels without Python wrappers, one
# entry point cached on disk, int64 arguments only, explicit loops, no exceptions; nothing is
# compiled at import (the entry point compiles at its first call).
_OPTIONS = dict(nogil=True, no_rewrites=True)


def _kernel(fn):
    return njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, **_OPTIONS)(fn)


def _pure(fn):
    """A kernel that allocates nothing (the predicates): compiled without reference counting
    (``_nrt=False``).  With it, every call of a predicate that is not inlined increfs and decrefs
    its array arguments (atomic operations); without it the whole-mesh test runs about twice as
    fast, with the same arithmetic and so the same answers.  A kernel marked so that allocates
    fails to compile."""
    return njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False, **_OPTIONS)(fn)


def _inlined(fn):
    """A predicate as :func:`_pure` that is also inlined into its callers by numba (``inline=
    "always"``), for the few called many times per call of their caller (:func:`_dir_sign` in
    :func:`_fan_winds_once`, :func:`_o2_in` in :func:`_seg_seg_2d`): the same operations on the
    same numbers, without a call that passes every array's fields.  Callable from compiled code
    only, and best from a :func:`_pure` caller: inlined into a kernel with reference counting,
    numba counts each array argument in and out (atomic) per inlined call, which can cost more
    than the call saves (:func:`_fan_winds_once` inlined into :func:`_star_fill_levels` did so,
    three arrays per vertex and direction tried)."""
    return njit(inline="always", no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False, **_OPTIONS)(fn)


_EPS = 2.0 ** -53
_O3_BOUND = (7.0 + 56.0 * _EPS) * _EPS  # Shewchuk's o3derrboundA
_O2_BOUND = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk's ccwerrboundA
_EXP = 1  # workspace layout: ws[0] flag, an expansion, its scratch, the terms
_EXP_LEN = 256
_TERMS = 1 + 2 * _EXP_LEN
_EPS53 = 2.0 ** -53
_KEY_BITS = 21  # cell coordinates per axis below 2^21
#: Slabs of at least this many faces, and planes of at least this many entries, find their
#: candidate pairs in a grid of cells over x and y (:func:`_cell_sweep`, :func:`_cell_pairs`),
#: smaller ones by the sweep over x (:func:`_x_sweep`, :func:`_x_pairs`): the same pairs.  On the
#: liver's whole mesh the sweeps over x met 44 M pairs of boxes (23 M in the slabs, 16 M of those
#: pairs of lower slabs: faces across thin slabs between nearby heights; 21 M in the planes), and
#: the slab phase took some 0.43 s, 0.37 s with the cells; on the mesher's bands (small slabs) the
#: cells were some 10 % slower than the sweep.
_CELL_SWEEP = 1024
_SLAB_BUDGET = 256  # box tests per face in the slab sweeps before the grid takes over
#: The grid of the whole-mesh test (:func:`_intersecting_pairs`) makes and searches its (face, cell)
#: entries in chunks of layers of cells of about this many entries.  On the lobster's mesh (396k
#: faces, 2M entries in 97 layers: a chunk per layer) the test held some 53 MiB in one table, 8 MiB
#: in chunks, in about the same time (same-process A/Bs: 0.43 -> 0.40 CPU-s in one, 0.37 -> 0.38 in
#: another); the liver's mesh by the grid 0.39 -> 0.35 (the chunk's tables stay in cache).  Chunks
#: of 4096 and 65536 entries were no faster.
_GRID_CHUNK = 16384
#: The grid's cell sizes (:func:`_intersecting_pairs`) come from the median extents of at most
#: about twice this many faces (every ``nlive // _MEDIAN_SAMPLE``-th live face of a larger mesh):
#: a smaller or larger cell changes how the candidates are found, not which pairs intersect.  On
#: the lobster's mesh (396k faces, a sample of 66k) the sample gives the same cell sizes as all
#: the faces, and the three medians of all of them took some 20 ms of the 0.23 s test.
_MEDIAN_SAMPLE = 65536


# ------------------------------------------------------------------------------------------------
# predicates (vertex indices into V; a sign of 0 means zero or not certified)
# ------------------------------------------------------------------------------------------------
# Exact fallback: the determinant as a sum of products of the coordinate differences, each
# difference split exactly into two doubles (two_sum) and each product of three doubles into four
# (two_prod), accumulated without rounding into a nonoverlapping expansion (Shewchuk's
# Grow-Expansion with zero elimination); the sign of its largest component is the exact sign.
@_pure
def _two_sum(a, b):
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@_pure
def _split(a):
    c = 134217729.0 * a  # 2^27 + 1
    hi = c - (c - a)
    return hi, a - hi


@_pure
def _two_prod(a, b):
    x = a * b
    ahi, alo = _split(a)
    bhi, blo = _split(b)
    err = x - ahi * bhi
    err -= alo * bhi
    err -= ahi * blo
    return x, alo * blo - err


@_pure
def _grow_exp(ws, e0, n, b, t0):
    """Add the double b to the expansion ws[e0:e0 + n] exactly (scratch at ws[t0:]); returns
    the new length."""
    q = b
    k = 0
    for i in range(n):
        q, hh = _two_sum(q, ws[e0 + i])
        if hh != 0.0:
            ws[t0 + k] = hh
            k += 1
    if q != 0.0:
        ws[t0 + k] = q
        k += 1
    for i in range(k):
        ws[e0 + i] = ws[t0 + i]
    return k


@_pure
def _add_product3(ws, n, x0, x1, y0, y1, z0, z1, sign):
    """Append the exact terms of sign * (x0 + x1)(y0 + y1)(z0 + z1) to the term list in ws
    (four doubles per product of three doubles); returns the new count."""
    t0 = _TERMS
    for ix in range(2):
        x = x0
        if ix == 1:
            x = x1
        if x == 0.0:
            continue
        for iy in range(2):
            y = y0
            if iy == 1:
                y = y1
            if y == 0.0:
                continue
            p, q = _two_prod(x, y)
            for iz in range(2):
                z = z0
                if iz == 1:
                    z = z1
                if z == 0.0:
                    continue
                r0, r1 = _two_prod(p, z)
                r2, r3 = _two_prod(q, z)
                ws[t0 + n] = sign * r0
                ws[t0 + n + 1] = sign * r1
                ws[t0 + n + 2] = sign * r2
                ws[t0 + n + 3] = sign * r3
                n += 4
    return n


@_pure
def _exact_sign(V, ws, a, b, c, d, ax, ay, dim):
    """Exact sign of orient3d(a, b, c, d) (``dim == 3``) or of orient2d(a, b, c) on the axes ax,
    ay (``dim == 2``).  One function for both, called from two places, so that the compiler
    keeps it out of line and the float filters stay small.

    The determinant is written exactly as a sum of doubles (the terms); their sum is taken
    first with compensated summation (Ogita-Rump-Oishi Sum2) and its sign accepted when the
    error bound certifies it (the common case: a tiny determinant that is not zero); otherwise
    the terms are summed exactly into a nonoverlapping expansion."""
    one = 1.0
    n = np.int64(0)
    if dim == 3:
        adx, adx1 = _two_sum(V[a, 0], -V[d, 0])
        ady, ady1 = _two_sum(V[a, 1], -V[d, 1])
        adz, adz1 = _two_sum(V[a, 2], -V[d, 2])
        bdx, bdx1 = _two_sum(V[b, 0], -V[d, 0])
        bdy, bdy1 = _two_sum(V[b, 1], -V[d, 1])
        bdz, bdz1 = _two_sum(V[b, 2], -V[d, 2])
        cdx, cdx1 = _two_sum(V[c, 0], -V[d, 0])
        cdy, cdy1 = _two_sum(V[c, 1], -V[d, 1])
        cdz, cdz1 = _two_sum(V[c, 2], -V[d, 2])
        n = _add_product3(ws, n, adx, adx1, bdy, bdy1, cdz, cdz1, one)
        n = _add_product3(ws, n, adx, adx1, bdz, bdz1, cdy, cdy1, -one)
        n = _add_product3(ws, n, ady, ady1, bdx, bdx1, cdz, cdz1, -one)
        n = _add_product3(ws, n, ady, ady1, bdz, bdz1, cdx, cdx1, one)
        n = _add_product3(ws, n, adz, adz1, bdx, bdx1, cdy, cdy1, one)
        n = _add_product3(ws, n, adz, adz1, bdy, bdy1, cdx, cdx1, -one)
    else:
        zero = 0.0
        acx, acx1 = _two_sum(V[a, ax], -V[c, ax])
        bcx, bcx1 = _two_sum(V[b, ax], -V[c, ax])
        acy, acy1 = _two_sum(V[a, ay], -V[c, ay])
        bcy, bcy1 = _two_sum(V[b, ay], -V[c, ay])
        n = _add_product3(ws, n, acx, acx1, bcy, bcy1, one, zero, one)
        n = _add_product3(ws, n, acy, acy1, bcx, bcx1, one, zero, -one)
    # Sum2: |res - exact| <= eps |res| + gamma(n)^2 sum|t| (with gamma(n) = n eps / (1 - n eps))
    s = 0.0
    comp = 0.0
    sabs = 0.0
    for i in range(n):
        t = ws[_TERMS + i]
        s, e = _two_sum(s, t)
        comp += e
        sabs += abs(t)
    res = s + comp
    g = n * _EPS53 * 1.01
    bound = 2.0 * _EPS53 * abs(res) + 2.0 * g * g * sabs
    if res > bound:
        return 1
    if res < -bound:
        return -1
    # exact: grow a nonoverlapping expansion term by term
    m = np.int64(0)
    for i in range(n):
        m = _grow_exp(ws, np.int64(_EXP), m, ws[_TERMS + i], _EXP + _EXP_LEN)
    if m == 0:
        return 0
    if ws[_EXP + m - 1] > 0.0:
        return 1
    return -1


@_pure
def _o3(V, ws, a, b, c, d):
    """Exact sign of det[a - d, b - d, c - d] (positive when d is below the plane of a, b, c seen
    with a, b, c counter-clockwise): float64 with Shewchuk's error bound, exact arithmetic when
    the bound does not certify the sign."""
    adx = V[a, 0] - V[d, 0]
    ady = V[a, 1] - V[d, 1]
    adz = V[a, 2] - V[d, 2]
    bdx = V[b, 0] - V[d, 0]
    bdy = V[b, 1] - V[d, 1]
    bdz = V[b, 2] - V[d, 2]
    cdx = V[c, 0] - V[d, 0]
    cdy = V[c, 1] - V[d, 1]
    cdz = V[c, 2] - V[d, 2]
    bc1 = bdx * cdy
    bc2 = cdx * bdy
    ca1 = cdx * ady
    ca2 = adx * cdy
    ab1 = adx * bdy
    ab2 = bdx * ady
    det = adz * (bc1 - bc2) + bdz * (ca1 - ca2) + cdz * (ab1 - ab2)
    if ws[0] == 1.0:  # coordinates on a small dyadic grid: the float evaluation is exact
        if det > 0.0:
            return 1
        if det < 0.0:
            return -1
        return 0
    perm = (abs(bc1) + abs(bc2)) * abs(adz) + (abs(ca1) + abs(ca2)) * abs(bdz) + (abs(ab1) + abs(ab2)) * abs(cdz)
    err = _O3_BOUND * perm
    if det > err:
        return 1
    if det < -err:
        return -1
    if perm == 0.0:
        return 0
    return _exact_sign(V, ws, a, b, c, d, a, a, np.int64(3))


def _o2_sign(V, ws, a, b, c, ax, ay):
    """Exact sign of the 2D orientation of a, b, c projected on the axes ``ax``, ``ay``."""
    acx = V[a, ax] - V[c, ax]
    bcx = V[b, ax] - V[c, ax]
    acy = V[a, ay] - V[c, ay]
    bcy = V[b, ay] - V[c, ay]
    l = acx * bcy
    r = acy * bcx
    det = l - r
    if ws[0] == 1.0:
        if det > 0.0:
            return 1
        if det < 0.0:
            return -1
        return 0
    err = _O2_BOUND * (abs(l) + abs(r))
    if det > err:
        return 1
    if det < -err:
        return -1
    if l == 0.0 and r == 0.0:
        return 0
    return _exact_sign(V, ws, a, b, c, c, ax, ay, np.int64(2))


_o2 = _pure(_o2_sign)
#: :func:`_o2` inlined into its caller (:func:`_seg_seg_2d`, four per call, on most pairs that the
#: whole-mesh test decides in a plane): the same function compiled inlined, without a call per
#: orientation.
_o2_in = _inlined(_o2_sign)


@_pure
def _drop_axis(V, ws, a, b, c):
    """A coordinate axis along which the normal of the (non-degenerate) triangle a, b, c is
    largest, such that its projection away keeps the triangle non-degenerate (checked exactly)."""
    ux = V[b, 0] - V[a, 0]
    uy = V[b, 1] - V[a, 1]
    uz = V[b, 2] - V[a, 2]
    vx = V[c, 0] - V[a, 0]
    vy = V[c, 1] - V[a, 1]
    vz = V[c, 2] - V[a, 2]
    nx = abs(uy * vz - uz * vy)
    ny = abs(uz * vx - ux * vz)
    nz = abs(ux * vy - uy * vx)
    k = 2
    if nx >= ny and nx >= nz:
        k = 0
    elif ny >= nz:
        k = 1
    for t in range(3):
        kk = (k + t) % 3
        if _o2(V, ws, a, b, c, (kk + 1) % 3, (kk + 2) % 3) != 0:
            return kk
    return k


@_pure
def _seg_seg_2d(V, ws, p1, p2, q1, q2, ax, ay):
    """Closed segments p1p2 and q1q2 (in one plane, projected) have a common point."""
    d1 = _o2_in(V, ws, q1, q2, p1, ax, ay)
    d2 = _o2_in(V, ws, q1, q2, p2, ax, ay)
    d3 = _o2_in(V, ws, p1, p2, q1, ax, ay)
    d4 = _o2_in(V, ws, p1, p2, q2, ax, ay)
    if d1 * d2 > 0 or d3 * d4 > 0:
        return False
    if (d1 == 0 and d2 == 0) or (d3 == 0 and d4 == 0):
        # collinear: overlap of the projections on both axes
        for k in range(2):
            t = ax
            if k == 1:
                t = ay
            plo = min(V[p1, t], V[p2, t])
            phi = max(V[p1, t], V[p2, t])
            qlo = min(V[q1, t], V[q2, t])
            qhi = max(V[q1, t], V[q2, t])
            if phi < qlo or qhi < plo:
                return False
        return True
    return True


@_pure
def _point_in_tri_2d(V, ws, p, a, b, c, ax, ay):
    """Point p lies in the closed triangle a, b, c (in one plane, projected)."""
    s = _o2(V, ws, a, b, c, ax, ay)
    if s == 0:
        return False
    return s * _o2(V, ws, a, b, p, ax, ay) >= 0 and s * _o2(V, ws, b, c, p, ax, ay) >= 0 and s * _o2(V, ws, c, a, p, ax, ay) >= 0


@_pure
def _seg_tri_2d(V, ws, u, v, a, b, c, ax, ay):
    """Closed segment uv and closed triangle abc, all in one plane."""
    if _point_in_tri_2d(V, ws, u, a, b, c, ax, ay) or _point_in_tri_2d(V, ws, v, a, b, c, ax, ay):
        return True
    return _seg_seg_2d(V, ws, u, v, a, b, ax, ay) or _seg_seg_2d(V, ws, u, v, b, c, ax, ay) or _seg_seg_2d(V, ws, u, v, c, a, ax, ay)


@_pure
def _outside(V, ws, u, v, t, a, b, c, ax, ay):
    """a, b, c all strictly on the outer side of edge uv of a triangle of orientation t."""
    return t * _o2(V, ws, u, v, a, ax, ay) < 0 and t * _o2(V, ws, u, v, b, ax, ay) < 0 and t * _o2(V, ws, u, v, c, ax, ay) < 0


@_pure
def _tri_tri_2d(V, ws, a, b, c, d, e, f, ax, ay):
    """Closed triangles abc and def, in one plane."""
    # quick rejection: the other triangle strictly outside the line of an edge
    t = _o2(V, ws, a, b, c, ax, ay)
    u = _o2(V, ws, d, e, f, ax, ay)
    if t != 0 and u != 0:
        if (_outside(V, ws, a, b, t, d, e, f, ax, ay) or _outside(V, ws, b, c, t, d, e, f, ax, ay)
                or _outside(V, ws, c, a, t, d, e, f, ax, ay) or _outside(V, ws, d, e, u, a, b, c, ax, ay)
                or _outside(V, ws, e, f, u, a, b, c, ax, ay) or _outside(V, ws, f, d, u, a, b, c, ax, ay)):
            return False
    if _seg_tri_2d(V, ws, a, b, d, e, f, ax, ay) or _seg_tri_2d(V, ws, b, c, d, e, f, ax, ay) or _seg_tri_2d(V, ws, c, a, d, e, f, ax, ay):
        return True
    return _point_in_tri_2d(V, ws, d, a, b, c, ax, ay)


@_pure
def _edge_tri_3d(V, ws, u, v, su, sv, a, b, c):
    """Closed segment uv and closed triangle abc meet (3D); ``su``, ``sv`` are the signs
    ``_o3(V, ws, a, b, c, u)`` and ``_o3(V, ws, a, b, c, v)``."""
    if su * sv > 0:
        return False
    if su == 0 and sv == 0:
        k = _drop_axis(V, ws, a, b, c)
        return _seg_tri_2d(V, ws, u, v, a, b, c, (k + 1) % 3, (k + 2) % 3)
    w1 = _o3(V, ws, u, v, a, b)
    w2 = _o3(V, ws, u, v, b, c)
    if w1 * w2 < 0:
        return False
    w3 = _o3(V, ws, u, v, c, a)
    if w1 == 0 and w2 == 0 and w3 == 0:  # uncertain: the line looks coplanar with the triangle
        k = _drop_axis(V, ws, a, b, c)
        return _seg_tri_2d(V, ws, u, v, a, b, c, (k + 1) % 3, (k + 2) % 3)
    pos = w1 > 0 or w2 > 0 or w3 > 0
    neg = w1 < 0 or w2 < 0 or w3 < 0
    return not (pos and neg)


@_pure
def _tri_tri_3d(V, ws, a, b, c, d, e, f):
    """Closed triangles abc and def (no common vertex) have a common point."""
    s1 = _o3(V, ws, a, b, c, d)
    s2 = _o3(V, ws, a, b, c, e)
    s3 = _o3(V, ws, a, b, c, f)
    if (s1 > 0 and s2 > 0 and s3 > 0) or (s1 < 0 and s2 < 0 and s3 < 0):
        return False
    r1 = _o3(V, ws, d, e, f, a)
    r2 = _o3(V, ws, d, e, f, b)
    r3 = _o3(V, ws, d, e, f, c)
    if (r1 > 0 and r2 > 0 and r3 > 0) or (r1 < 0 and r2 < 0 and r3 < 0):
        return False
    if (s1 == 0 and s2 == 0 and s3 == 0) or (r1 == 0 and r2 == 0 and r3 == 0):
        k = _drop_axis(V, ws, a, b, c)
        return _tri_tri_2d(V, ws, a, b, c, d, e, f, (k + 1) % 3, (k + 2) % 3)
    # not coplanar: the intersection, if any, is a segment whose ends lie on edges
    return (_edge_tri_3d(V, ws, a, b, r1, r2, d, e, f) or _edge_tri_3d(V, ws, b, c, r2, r3, d, e, f)
            or _edge_tri_3d(V, ws, c, a, r3, r1, d, e, f) or _edge_tri_3d(V, ws, d, e, s1, s2, a, b, c)
            or _edge_tri_3d(V, ws, e, f, s2, s3, a, b, c) or _edge_tri_3d(V, ws, f, d, s3, s1, a, b, c))


@_pure
def _in_corner(V, ws, p, a, c, d):
    """For a in the plane of triangle p, c, d: a - p points into the triangle's closed corner at p
    (so the edge from p to a has points other than p in the triangle)."""
    k = _drop_axis(V, ws, p, c, d)
    ax = (k + 1) % 3
    ay = (k + 2) % 3
    t = _o2(V, ws, p, c, d, ax, ay)
    if t == 0:
        return False
    return t * _o2(V, ws, p, c, a, ax, ay) >= 0 and t * _o2(V, ws, p, a, d, ax, ay) >= 0


@_pure
def _shared_vertex(V, ws, p, a, b, c, d):
    """Triangles p, a, b and p, c, d (common vertex p only) have a common point other than p.

    Such a point exists if and only if the opposite edge of one meets the other triangle, or an
    edge from p of one lies in the other's plane and points into its corner at p."""
    sa = _o3(V, ws, p, c, d, a)
    sb = _o3(V, ws, p, c, d, b)
    if sa * sb > 0:  # p, a, b strictly on one side of the plane of p, c, d (but for p)
        return False
    sc = _o3(V, ws, p, a, b, c)
    sd = _o3(V, ws, p, a, b, d)
    if sc * sd > 0:
        return False
    if sa == 0 and sb == 0 and sc == 0 and sd == 0:
        # one plane: the corners at p overlap iff a side of one corner points into the other
        k = _drop_axis(V, ws, p, c, d)
        ax = (k + 1) % 3
        ay = (k + 2) % 3
        t1 = _o2(V, ws, p, a, b, ax, ay)
        t2 = _o2(V, ws, p, c, d, ax, ay)
        if t1 != 0 and t2 != 0:
            return ((t2 * _o2(V, ws, p, c, a, ax, ay) >= 0 and t2 * _o2(V, ws, p, a, d, ax, ay) >= 0)
                    or (t2 * _o2(V, ws, p, c, b, ax, ay) >= 0 and t2 * _o2(V, ws, p, b, d, ax, ay) >= 0)
                    or (t1 * _o2(V, ws, p, a, c, ax, ay) >= 0 and t1 * _o2(V, ws, p, c, b, ax, ay) >= 0)
                    or (t1 * _o2(V, ws, p, a, d, ax, ay) >= 0 and t1 * _o2(V, ws, p, d, b, ax, ay) >= 0))
    if _edge_tri_3d(V, ws, a, b, sa, sb, p, c, d) or _edge_tri_3d(V, ws, c, d, sc, sd, p, a, b):
        return True
    return ((sa == 0 and _in_corner(V, ws, p, a, c, d)) or (sb == 0 and _in_corner(V, ws, p, b, c, d))
            or (sc == 0 and _in_corner(V, ws, p, c, a, b)) or (sd == 0 and _in_corner(V, ws, p, d, a, b)))


@_pure
def _shared_edge(V, ws, p, q, a, b):
    """Triangles p, q, a and p, q, b (common edge pq) overlap: coplanar, a and b on one side."""
    if _o3(V, ws, p, q, a, b) != 0:
        return False
    k = _drop_axis(V, ws, p, q, a)
    ax = (k + 1) % 3
    ay = (k + 2) % 3
    return _o2(V, ws, p, q, a, ax, ay) * _o2(V, ws, p, q, b, ax, ay) > 0


@_pure
def _pair_intersects(V, ws, F, i, j):
    """Faces i and j (canonical vertex indices in F) intersect other than as neighbours."""
    a = F[i, 0]
    b = F[i, 1]
    c = F[i, 2]
    d = F[j, 0]
    e = F[j, 1]
    f = F[j, 2]
    # which corners of j are corners of i
    sd = d == a or d == b or d == c
    se = e == a or e == b or e == c
    sf = f == a or f == b or f == c
    return _pair_shared(V, ws, F, i, j, sd, se, sf)


@_pure
def _pair_shared(V, ws, F, i, j, sd, se, sf):
    """:func:`_pair_intersects` where it is known which corners of face j are corners of face i
    (``sd``, ``se``, ``sf`` for ``F[j, 0]``, ``F[j, 1]``, ``F[j, 2]``)."""
    a = F[i, 0]
    b = F[i, 1]
    c = F[i, 2]
    d = F[j, 0]
    e = F[j, 1]
    f = F[j, 2]
    nshared = 0
    if sd:
        nshared += 1
    if se:
        nshared += 1
    if sf:
        nshared += 1
    if nshared == 0:
        return _tri_tri_3d(V, ws, a, b, c, d, e, f)
    if nshared == 3:
        return True
    if nshared == 1:
        # the common vertex p, and the other two corners of each face
        p = d
        if se:
            p = e
        elif sf:
            p = f
        x1 = b
        x2 = c
        if p == b:
            x1 = c
            x2 = a
        elif p == c:
            x1 = a
            x2 = b
        y1 = e
        y2 = f
        if p == e:
            y1 = f
            y2 = d
        elif p == f:
            y1 = d
            y2 = e
        return _shared_vertex(V, ws, p, x1, x2, y1, y2)
    # two shared corners: the odd ones out
    y = d
    if not se:
        y = e
    elif not sf:
        y = f
    if a != d and a != e and a != f:
        return _shared_edge(V, ws, b, c, a, y)
    if b != d and b != e and b != f:
        return _shared_edge(V, ws, c, a, b, y)
    return _shared_edge(V, ws, a, b, c, y)


@_pure
def _plane_part(F, V, i, c):
    """The corners of face i at height c: ``(count, first, second)`` (-1 where absent)."""
    n = 0
    u = np.int64(-1)
    w = np.int64(-1)
    for t in range(3):
        v = F[i, t]
        if V[v, 2] == c:
            if n == 0:
                u = v
            else:
                w = v
            n += 1
    return n, u, w


@_inlined
def _level_part(V, F, lev, i, k):
    """Face i's part on level ``k``: its lowest and highest vertex numbers there (-1 for both where
    no corner lies on it) and their xy box ``(xlo, xhi, ylo, yhi)`` (zeros where none), as the
    slab phase's planes and the two-level test's planes lay their parts out."""
    u = np.int64(-1)
    w = np.int64(-1)
    x0 = 0.0
    x1 = 0.0
    y0 = 0.0
    y1 = 0.0
    for q in range(3):
        v = F[i, q]
        if lev[v] != k:
            continue
        if u < 0:
            u = v
            w = v
            x0 = V[v, 0]
            x1 = V[v, 0]
            y0 = V[v, 1]
            y1 = V[v, 1]
        else:
            u = min(u, v)
            w = max(w, v)
            x0 = min(x0, V[v, 0])
            x1 = max(x1, V[v, 0])
            y0 = min(y0, V[v, 1])
            y1 = max(y1, V[v, 1])
    return u, w, x0, x1, y0, y1


@_pure
def _z_range(V, F, i):
    """The lowest and highest corner heights of face i (its box's z-range)."""
    a = V[F[i, 0], 2]
    b = V[F[i, 1], 2]
    c = V[F[i, 2], 2]
    return min(a, min(b, c)), max(a, max(b, c))


@_pure
def _across_plane(V, ws, F, i, j):
    """Faces i and j whose boxes meet only in a plane ``z = c``, one face below it and the other
    above it, neither flat: 1 if they intersect (module docstring), 0 if not, -1 if the boxes do
    not meet that way (then the general test decides).

    Every common point lies in the plane, in the hull of each face's corners there (a corner or an
    edge), and so does every common vertex: the test is two segments in the plane.  With no common
    vertex they intersect if the segments meet; with one, ``p``, if both are segments from ``p``
    along one ray; with two (a common edge) they meet along it only, from opposite sides."""
    zi0, zi1 = _z_range(V, F, i)
    zj0, zj1 = _z_range(V, F, j)
    if zi1 == zj0 and zi0 < zi1 and zj0 < zj1:
        c = zi1
    elif zj1 == zi0 and zj0 < zj1 and zi0 < zi1:
        c = zj1
    else:
        return -1
    na, a1, a2 = _plane_part(F, V, i, c)
    nb, b1, b2 = _plane_part(F, V, j, c)
    if na == 1:
        a2 = a1
    if nb == 1:
        b2 = b1
    # cull: the xy boxes of the two parts
    if (max(V[a1, 0], V[a2, 0]) < min(V[b1, 0], V[b2, 0]) or max(V[b1, 0], V[b2, 0]) < min(V[a1, 0], V[a2, 0])
            or max(V[a1, 1], V[a2, 1]) < min(V[b1, 1], V[b2, 1]) or max(V[b1, 1], V[b2, 1]) < min(V[a1, 1], V[a2, 1])):
        return 0
    s11 = a1 == b1 or a1 == b2
    s12 = na == 2 and (a2 == b1 or a2 == b2)
    shared = np.int64(s11) + np.int64(s12)
    ax = np.int64(0)
    ay = np.int64(1)
    if shared == 0:
        return 1 if _seg_seg_2d(V, ws, a1, a2, b1, b2, ax, ay) else 0
    if shared == 2:
        return 0
    if na == 1 or nb == 1:  # a corner and a segment from it: only the corner in common
        return 0
    p = a1 if s11 else a2
    q = a2 if s11 else a1
    r = b2 if b1 == p else b1
    if _o2(V, ws, p, q, r, ax, ay) != 0:
        return 0
    # collinear: one ray from p when q - p and r - p point the same way along an axis where they move
    for t in range(2):
        dq = V[q, t] - V[p, t]
        dr = V[r, t] - V[p, t]
        if dq != 0.0 or dr != 0.0:
            return 1 if (dq > 0.0 and dr > 0.0) or (dq < 0.0 and dr < 0.0) else 0
    return 0  # pragma: no cover - q and r differ from p


@_pure
def _touching_boxes(V, ws, F, i, j):
    """Faces i and j with no common vertex whose boxes only touch along some axis k (the top of
    one at the bottom of the other, ``c``), neither face flat across k: 1 if they intersect, 0 if
    not, -1 if no axis is so (then the general test decides).

    Every common point lies in the plane ``x_k = c``, on each face in the hull of its corners
    there (a corner or an edge: the face's extreme part along k), so the faces meet exactly where
    those two parts do, a test of two segments (or points) in that plane, on its two coordinates
    (the test of :func:`_across_plane`, for any axis and for faces without a common vertex)."""
    for t in range(3):
        v = F[i, t]
        if v == F[j, 0] or v == F[j, 1] or v == F[j, 2]:
            return -1
    for k in range(3):
        ilo = min(V[F[i, 0], k], min(V[F[i, 1], k], V[F[i, 2], k]))
        ihi = max(V[F[i, 0], k], max(V[F[i, 1], k], V[F[i, 2], k]))
        jlo = min(V[F[j, 0], k], min(V[F[j, 1], k], V[F[j, 2], k]))
        jhi = max(V[F[j, 0], k], max(V[F[j, 1], k], V[F[j, 2], k]))
        if not (ilo < ihi and jlo < jhi):
            continue
        if ihi == jlo:
            c = ihi
        elif jhi == ilo:
            c = jhi
        else:
            continue
        a1 = np.int64(-1)
        a2 = np.int64(-1)
        b1 = np.int64(-1)
        b2 = np.int64(-1)
        for t in range(3):
            v = F[i, t]
            if V[v, k] == c:
                if a1 < 0:
                    a1 = v
                a2 = v
            w = F[j, t]
            if V[w, k] == c:
                if b1 < 0:
                    b1 = w
                b2 = w
        ax = (k + 1) % 3
        ay = (k + 2) % 3
        if (max(V[a1, ax], V[a2, ax]) < min(V[b1, ax], V[b2, ax]) or max(V[b1, ax], V[b2, ax]) < min(V[a1, ax], V[a2, ax])
                or max(V[a1, ay], V[a2, ay]) < min(V[b1, ay], V[b2, ay]) or max(V[b1, ay], V[b2, ay]) < min(V[a1, ay], V[a2, ay])):
            return 0
        return 1 if _seg_seg_2d(V, ws, a1, a2, b1, b2, ax, ay) else 0
    return -1


# ------------------------------------------------------------------------------------------------
# neighbours decided at once: vertices whose star projects one-to-one onto a coordinate plane
# ------------------------------------------------------------------------------------------------
# Most candidate pairs of a closed mesh share a vertex (about five in six of them share one or an
# edge on the lobster's and the liver's meshes).  Around a vertex p whose faces form one fan
# (p, a_1, a_2), (p, a_2, a_3), ..., (p, a_n, a_1) (n >= 3, the a_i distinct) that projects onto
# a coordinate plane with every triangle of the same strict orientation and the link polygon
# a_1 ... a_n winding once around p, the projected triangles are n sectors at p of angles in
# (0, pi) that tile the directions once: two sectors of faces that are not consecutive meet only
# in p, two consecutive ones only along the ray of their common edge.  The projection is one-to-one
# on each (non-degenerate) face, so two faces of the fan meet only at p, or along their common
# edge without folding: no pair of faces that shares p intersects (module docstring), and such
# pairs need no test.  Every sign is the exact one (``_o2``); the winding is counted exactly as the
# link edges that cross the ray from p along +x upwards (all edges turn the same way around p, so
# none crosses it downwards).
@_pure
def _unit_step(x, big):
    """-1, 0 or 1: the sign of x where |x| is at least half of ``big`` (else 0)."""
    if x >= 0.5 * big:
        return 1.0
    if x <= -0.5 * big:
        return -1.0
    return 0.0


@_pure
def _direction(c):
    """The c-th (0 .. 12) direction of components -1, 0, 1 whose first nonzero one is +1."""
    if c == 0:
        return 0.0, 0.0, 1.0
    if c < 4:  # (0, 1, -1..1)
        return 0.0, 1.0, float(c - 2)
    c -= 4  # (1, -1..1, -1..1)
    return 1.0, float(c // 3 - 1), float(c % 3 - 1)


@_inlined
def _dir_sign(V, grid, p, a, b, d0, d1, d2):
    """The sign of det[a - p, b - p, d] for a direction d of components -1, 0, 1 (the
    orientation of p, a, b seen along d; for d an axis, that of ``_o2`` on the coordinate plane
    across it): -1, 0 or 1 where known, 2 where the float evaluation does not certify it.

    Where p, a and b have the coordinates that enter on the grid (``grid``: bit k set where
    coordinate k is a multiple of ``2^-10`` below ``2^14`` in magnitude; those across the nonzero
    components of d enter), every difference, product and sum below is exact in float64 (the
    products of two differences stay below ``2^50`` grid steps squared), so the sign is exact,
    zero included.  Otherwise the bound: along each product, the two differences, the product,
    the 2x2 minor and the two additions of the sum (the components of d are exact factors) round
    once each, by at most eps times the magnitude; so the error is below ``6.01 eps`` times the
    permanent (the sum of the absolute products), itself computed to within a few ulps:
    ``8 eps`` certifies a sign."""
    ux = V[a, 0] - V[p, 0]
    uy = V[a, 1] - V[p, 1]
    uz = V[a, 2] - V[p, 2]
    vx = V[b, 0] - V[p, 0]
    vy = V[b, 1] - V[p, 1]
    vz = V[b, 2] - V[p, 2]
    det = 0.0
    perm = 0.0
    if d0 != 0.0:
        l = uy * vz
        r = uz * vy
        det += d0 * (l - r)
        perm += abs(l) + abs(r)
    if d1 != 0.0:
        l = uz * vx
        r = ux * vz
        det += d1 * (l - r)
        perm += abs(l) + abs(r)
    if d2 != 0.0:
        l = ux * vy
        r = uy * vx
        det += d2 * (l - r)
        perm += abs(l) + abs(r)
    need = 0
    if d0 != 0.0:
        need |= 6
    if d1 != 0.0:
        need |= 5
    if d2 != 0.0:
        need |= 3
    if grid[p] & grid[a] & grid[b] & need == need:
        if det > 0.0:
            return 1
        if det < 0.0:
            return -1
        return 0
    if not perm > 1e-280:  # (far from underflow, where the relative bound holds)
        return 2
    err = 8.0 * _EPS * perm
    if det > err:
        return 1
    if det < -err:
        return -1
    return 2


@_pure
def _fan_winds_once(V, grid, nxt, r, n, p, d0, d1, d2):
    """The ``n`` faces around p (one fan, see :func:`_star_certified`), seen along d: every one of
    one strict orientation, and the sectors at p cover the direction of the link vertex r exactly
    once (half-open: a sector holds its first side, not its second).  The faces are walked along
    the link cycle from r (``nxt``: the link edge a -> b of the face (p, a, b)), not read again
    from the faces' rows.

    A sector from u to v (its link vertices a, b) of orientation s holds r when r is strictly
    inside (``s det[u, r] > 0``, ``s det[r, v] > 0``) or along u (``det[u, r] = 0`` and
    ``s det[r, v] > 0``: r in the direction of u, not the opposite one).  Along the cycle a
    sector's first side is the previous one's second, so ``det[r, u]`` is the previous sector's
    ``det[r, v]`` where that was computed, and ``det[u, r] = -det[r, u]`` exactly
    (:func:`_dir_sign` forms the same products and subtracts them the other way round, and
    rounding to nearest is symmetric; an uncertified 2 stays 2): each sign that the test of
    every sector in turn needs is the same number, computed once, and the outcome (which does
    not depend on the order of the sectors) is the same.

    A call, not inlined into :func:`_star_fill_levels` (which counts references): inlined there,
    each try counted ``V``, ``grid`` and ``nxt`` in and out; as a call without reference counting,
    the stars of every vertex of the lobster's whole mesh took some 42 ms instead of 47 (liver 34
    instead of 37; CPU medians of one kernel in alternating processes)."""
    sgn = 0
    a = r
    for t in range(n):
        b = np.int64(nxt[a])  # (int64: one signature of _dir_sign)
        o = _dir_sign(V, grid, p, a, b, d0, d1, d2)
        if o == 0 or o == 2 or (sgn != 0 and o != sgn):
            return False
        sgn = o
        a = b
    cover = 1  # (the sector from r holds r; the one to r does not)
    a = np.int64(nxt[r])
    prev = 3  # det[r, a] where the previous sector computed it, else 3
    for t in range(n - 2):
        b = np.int64(nxt[a])  # (int64: one signature of _dir_sign)
        o2 = _dir_sign(V, grid, p, r, b, d0, d1, d2)
        if o2 == 2:
            return False
        if o2 == sgn:
            sa = prev
            if sa == 3:
                sa = _dir_sign(V, grid, p, r, a, d0, d1, d2)
            if sa == 2:
                return False
            if sa == -sgn or sa == 0:  # (det[a, r] = -sa is sgn or 0)
                cover += 1
        prev = o2
        a = b
    return cover == 1


def _star_certified(V, F, lev=None, l0=0, l1=0):
    """Per vertex (canonical indices in F): 1 where the faces around it are certified as above,
    0 where not (or where no face uses it).  With ``lev`` (a level per vertex), only the vertices
    of levels ``l0 .. l1`` are certified (:func:`_star_fill_levels`)."""
    if lev is None:
        lev, l0, l1 = np.zeros(len(V), np.int64), 0, 0
    return _star_kernel(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64),
                        np.ascontiguousarray(lev, dtype=np.int64), np.int64(l0), np.int64(l1))


@njit(cache=True, **_OPTIONS)
def _star_kernel(V, F, lev, l0, l1):
    """:func:`_star_certified` on checked arrays."""
    star = np.zeros(len(V), np.int8)
    _star_fill_levels(V, F, star, lev, l0, l1)
    return star


@_kernel
def _star_fill_levels(V, F, star, lev, l0, l1):
    """:func:`_star_certified` into ``star`` (zeros on entry) for the vertices ``p`` with
    ``l0 <= lev[p] <= l1`` only (the others stay 0): a range of heights of :func:`_slab_pairs` certifies the stars of its own vertices, not the
    whole mesh's once per range.  A vertex's star is the same whichever others are certified (its
    faces in the order of their numbers)."""
    nv = len(V)
    m = len(F)
    # (offsets in int32 as the entries below: a mesh of 2^29 faces would not fit in memory here)
    start = np.zeros(nv + 1, np.int32)
    for i in range(m):
        for t in range(3):
            v = F[i, t]
            if l0 <= lev[v] <= l1:
                start[v + 1] += 1
    for v in range(nv):
        start[v + 1] += start[v]
    fill = start[:nv].copy()
    # the faces at each vertex, by corner: 3 * face + corner; int32, as the per-vertex arrays below
    # (a byte for the grid bits): on the liver's whole mesh these were some 18 MiB in int64, at the
    # peak of the general mesher's crossing test (a mesh of 2^29 faces would not fit in memory here)
    inc = np.empty(start[nv], np.int32)
    for i in range(m):
        for t in range(3):
            v = F[i, t]
            if l0 <= lev[v] <= l1:
                inc[fill[v]] = 3 * i + t
                fill[v] += 1
    grid = np.zeros(nv, np.int8)  # coordinates on the grid of _dir_sign (bit k: coordinate k)
    for v in range(nv):
        g = 0
        for k in range(3):
            x = V[v, k]
            if abs(x) < 16384.0 and x * 1024.0 == math.floor(x * 1024.0):
                g |= 1 << k
        grid[v] = g
    nxt = np.empty(nv, np.int32)  # link edge a -> b of the face (p, a, b), stamped by p
    stamp = np.full(nv, -1, np.int32)
    most = 0
    for p in range(nv):
        most = max(most, np.int64(start[p + 1]) - np.int64(start[p]))
    nrm = np.empty((most, 3), np.float64)  # the fan's face normals (float: to choose directions)
    for p in range(nv):
        s0 = np.int64(start[p])
        s1 = np.int64(start[p + 1])
        n = s1 - s0
        if n < 3:
            continue
        ok = True
        nx_ = 0.0
        ny_ = 0.0
        nz_ = 0.0
        for r in range(s0, s1):
            i = inc[r] // 3
            t = inc[r] % 3
            a = F[i, (t + 1) % 3]
            b = F[i, (t + 2) % 3]
            if a == p or b == p or a == b or stamp[a] == p:
                ok = False  # a degenerate face, or a link vertex twice as a start
                break
            stamp[a] = p
            nxt[a] = b
            ux = V[a, 0] - V[p, 0]
            uy = V[a, 1] - V[p, 1]
            uz = V[a, 2] - V[p, 2]
            vx = V[b, 0] - V[p, 0]
            vy = V[b, 1] - V[p, 1]
            vz = V[b, 2] - V[p, 2]
            wx = uy * vz - uz * vy
            wy = uz * vx - ux * vz
            wz = ux * vy - uy * vx
            nrm[r - s0, 0] = wx
            nrm[r - s0, 1] = wy
            nrm[r - s0, 2] = wz
            ln = math.sqrt(wx * wx + wy * wy + wz * wz)
            if ln > 0.0:
                nx_ += wx / ln
                ny_ += wy / ln
                nz_ += wz / ln
        if not ok:
            continue
        # one cycle through all n link vertices
        a0 = F[inc[s0] // 3, (inc[s0] % 3 + 1) % 3]
        c = a0
        for step in range(n):
            if stamp[c] != p:
                ok = False
                break
            c = nxt[c]
            if c == a0 and step < n - 1:
                ok = False
                break
        if not ok or c != a0:
            continue
        r0 = F[inc[s0] // 3, (inc[s0] % 3 + 1) % 3]  # (the cycle's start, a0 above)
        # the directions to project along: the summed unit normals rounded to a vector of -1, 0
        # and 1 (creases and corners of voxel surfaces: no coordinate plane sees their faces
        # one-to-one), then the axis of its largest component, then any of the 13 directions
        # (up to sign) that sees every face's float normal strictly on one side
        big = max(abs(nx_), max(abs(ny_), abs(nz_)))
        if not big > 0.0:
            continue
        t0 = _unit_step(nx_, big)
        t1 = _unit_step(ny_, big)
        t2 = _unit_step(nz_, big)
        a0 = _unit_step(nx_, 2.0 * big)  # the largest component only
        a1 = _unit_step(ny_, 2.0 * big)
        a2 = _unit_step(nz_, 2.0 * big)
        for q in range(15):
            if q == 0:
                d0, d1, d2 = t0, t1, t2
            elif q == 1:
                d0, d1, d2 = a0, a1, a2
                if abs(d0) + abs(d1) + abs(d2) != 1.0 or (d0 == t0 and d1 == t1 and d2 == t2):
                    continue
            else:
                # the 13 directions with a first nonzero component of +1
                d0, d1, d2 = _direction(q - 2)
                if (d0 == t0 and d1 == t1 and d2 == t2) or (d0 == -t0 and d1 == -t1 and d2 == -t2):
                    continue
                if (d0 == a0 and d1 == a1 and d2 == a2) or (d0 == -a0 and d1 == -a1 and d2 == -a2):
                    continue
                pos = 0
                neg = 0
                for r in range(n):
                    w = nrm[r, 0] * d0 + nrm[r, 1] * d1 + nrm[r, 2] * d2
                    if w > 0.0:
                        pos += 1
                    elif w < 0.0:
                        neg += 1
                if pos != n and neg != n:
                    continue
            if _fan_winds_once(V, grid, nxt, r0, n, p, d0, d1, d2):
                star[p] = 1
                break


@_pure
def _star_due(sst):
    """The stars are computed when first needed: ``sst[0]`` counts the pairs that reach the tests
    until it passes ``sst[1]`` (a mesh whose pairs are mostly decided otherwise, as by the slab
    certificates of a mesh on a small dyadic grid, does not pay for them); then True, once (the
    caller fills ``star``, :func:`_fill_stars`), and ``sst[0]`` is -1 from then on.  Until then
    ``star`` is all 0: every pair is tested, with the same answers."""
    if sst[0] < 0:
        return False
    sst[0] += 1
    if sst[0] <= sst[1]:
        return False
    sst[0] = -1
    return True


@_pure
def _shares_certified(F, star, i, j):
    """Faces i and j share a vertex whose star is certified (so they do not intersect)."""
    for t in range(3):
        v = F[i, t]
        if star[v] != 0 and (v == F[j, 0] or v == F[j, 1] or v == F[j, 2]):
            return True
    return False


# ------------------------------------------------------------------------------------------------
# pairs decided by how a group of faces lies: cells of one rectilinear grid
# ------------------------------------------------------------------------------------------------
# A caller that built the mesh from parts (the volume mesher's joins and caps) may number each face
# by its part (``groups``).  Many faces of a voxel-exact part are halves of axis-aligned rectangles
# (a pixel at a mid-plane, a collar's wall between a ring and its crack contour), split along a
# diagonal.  Take, per group, the values along each axis of the corners of its faces that are such
# halves (the candidates): a candidate whose rectangle spans two consecutive values along both of
# its free axes is half of a 2-cell of the group's product grid.  Two distinct 2-cells of one
# product grid meet in a common side, a common corner or not at all (along each axis two intervals
# between consecutive values are equal, share one endpoint or are apart; a cell meets a point value
# at an endpoint), and a half of a cell holds a side of it whole or only that side's endpoint that
# is one of its corners (never the missing corner).  So two such faces in distinct cells have in
# common at most a shared corner, or a shared side along which they meet from opposite sides (two
# cells of one plane with a common side lie on either side of it) or at an angle: by the module's
# rules (vertices identified by position), they do not intersect.  Two faces of one cell do not
# intersect if they are its two halves along one diagonal (opposite right angles); any other two
# (the other diagonal, the same half twice) overlap, so such cells are not certified.  Every step is
# a comparison of coordinates (no arithmetic): exact.  The pairs of two certified faces of one group
# are then not tested at all (on the lobster's mesh some 84 % of the faces, its exact joins and
# pixel caps), and a vertex whose faces are all certified in one group needs no star.
@njit(cache=True, **_OPTIONS)
def _lattice_cells(V, F, grp):
    """Per face (canonical vertex indices ``F``) its group ``grp[i]`` where the face is certified
    by the rule above, else -1 (``grp[i] < 0``: no group).  Groups are numbers below ``8 m + 16``
    (``m`` faces); with a larger one nothing is certified."""
    m = len(F)
    n = len(V)
    cg = np.full(m, -1, np.int64)
    ng = np.int64(0)
    for i in range(m):
        ng = max(ng, grp[i] + 1)
    if ng > 8 * m + 16:
        return cg
    fax = np.full(m, -1, np.int8)  # the candidate's fixed axis
    rc = np.empty(m, np.int8)  # its corner at the right angle (0, 1, 2)
    cnt = np.zeros(ng + 1, np.int64)
    for i in range(m):
        if grp[i] < 0:
            continue
        a0 = F[i, 0]
        a1 = F[i, 1]
        a2 = F[i, 2]
        if a0 == a1 or a1 == a2 or a0 == a2:
            continue
        a = -1
        for k in range(3):
            if V[a0, k] == V[a1, k] and V[a1, k] == V[a2, k]:
                a = k if a < 0 else 3  # (two fixed axes: collinear)
        if a < 0 or a == 3:
            continue
        u = (a + 1) % 3
        w = (a + 2) % 3
        for r in range(3):
            pr = F[i, r]
            p = F[i, (r + 1) % 3]
            q = F[i, (r + 2) % 3]
            # (each coordinate compared equal to another one is not NaN; the two compared unequal
            # are checked: a NaN would pass the comparison)
            if ((V[p, w] == V[pr, w] and V[p, u] != V[pr, u] and V[q, u] == V[pr, u] and V[q, w] != V[pr, w]
                 and V[p, u] == V[p, u] and V[q, w] == V[q, w])
                    or (V[q, w] == V[pr, w] and V[q, u] != V[pr, u] and V[p, u] == V[pr, u] and V[p, w] != V[pr, w]
                        and V[q, u] == V[q, u] and V[p, w] == V[p, w])):
                fax[i] = a
                rc[i] = r
                cnt[grp[i] + 1] += 1
                break
    for g in range(ng):
        cnt[g + 1] += cnt[g]
    # (face numbers and table slots per face in int32, and no copy of V for its values' bits: on
    # the liver's whole mesh these were some 10 MiB at the peak of the general mesher's crossing test)
    order = np.empty(cnt[ng], np.int32)  # the candidates by group
    fill = cnt[:ng].copy()
    most = np.int64(0)
    for i in range(m):
        if fax[i] >= 0:
            order[fill[grp[i]]] = i
            fill[grp[i]] += 1
    for g in range(ng):
        most = max(most, cnt[g + 1] - cnt[g])
    # (per vertex in int32: a group's values and ranks are far fewer than 2^31)
    stamp = np.full(n, -1, np.int32)
    rk = np.empty((n, 3), np.int32)  # a vertex's rank per axis among its group's values
    verts = np.empty(3 * most + 1, np.int64)
    vals = np.empty(3 * most + 1, np.float64)
    vslot = np.empty(3 * most + 1, np.int64)
    dslot = np.empty(3 * most + 1, np.int64)
    cap = np.int64(2)
    while cap < 2 * most + 2:
        cap *= 2
    # a hash table of the values of one group along one axis (its bits; stamped, not cleared)
    vcap = np.int64(2)
    while vcap < 6 * most + 2:
        vcap *= 2
    hbits = np.empty(vcap, np.int64)
    hst = np.full(vcap, -1, np.int64)
    hrank = np.empty(vcap, np.int64)
    gb = np.empty(3 * most + 1, np.float64)  # a group's values along one axis, + 0.0 ...
    gbb = gb.view(np.int64)  # ... and their bits (-0.0 + 0.0 == +0.0: one bit pattern per value)
    sid = np.int64(-1)
    tkey = np.empty(cap, np.int64)
    tface = np.empty(cap, np.int64)  # the cell's first face, or -1: a cell not certified
    tcnt = np.empty(cap, np.int64)
    tstamp = np.full(cap, -1, np.int64)
    slot = np.empty(m, np.int32)
    dim = np.empty(3, np.int64)
    for g in range(ng):
        c0 = cnt[g]
        c1 = cnt[g + 1]
        if c1 - c0 < 2:
            continue
        nv = 0
        for r in range(c0, c1):
            i = order[r]
            for t in range(3):
                v = F[i, t]
                if stamp[v] != g:
                    stamp[v] = g
                    verts[nv] = v
                    nv += 1
        for k in range(3):
            # the distinct values (hashed), sorted, and each vertex's rank among them
            sid += 1
            nd = 0
            for t in range(nv):
                gb[t] = V[verts[t], k] + 0.0
            for t in range(nv):
                b = gbb[t]
                h = b ^ (b >> 29)
                h *= np.int64(-7046029254386353131)  # (0x9E3779B97F4A7C15, wrapped)
                h ^= h >> 32
                q = h & (vcap - 1)
                while hst[q] == sid and hbits[q] != b:
                    q = (q + 1) & (vcap - 1)
                if hst[q] != sid:
                    hst[q] = sid
                    hbits[q] = b
                    vals[nd] = V[verts[t], k]
                    dslot[nd] = q
                    nd += 1
                vslot[t] = q
            idx = np.argsort(vals[:nd])
            for r in range(nd):
                hrank[dslot[idx[r]]] = r
            for t in range(nv):
                rk[verts[t], k] = hrank[vslot[t]]
            dim[k] = nd
        if dim[0] * dim[1] > (2 ** 62) // (3 * dim[2]):
            continue  # (cell numbers past int64: none of this group certified)
        for r in range(c0, c1):
            i = order[r]
            a = np.int64(fax[i])
            ok = True
            key = a
            mul = np.int64(3)
            corner = 0  # bit k: the right-angle corner at the high end along axis k
            pr = F[i, rc[i]]
            for k in range(3):
                lo_ = min(rk[F[i, 0], k], min(rk[F[i, 1], k], rk[F[i, 2], k]))
                hi_ = max(rk[F[i, 0], k], max(rk[F[i, 1], k], rk[F[i, 2], k]))
                if k != a and hi_ != lo_ + 1:
                    ok = False
                    break
                if rk[pr, k] == hi_ and k != a:
                    corner |= 1 << k
                key += mul * lo_
                mul *= dim[k]
            slot[i] = -1
            if not ok:
                continue
            s = (key * np.int64(0x9E3779B1)) & (cap - 1)
            while tstamp[s] == g and tkey[s] != key:
                s = (s + 1) & (cap - 1)
            slot[i] = s
            if tstamp[s] != g:
                tstamp[s] = g
                tkey[s] = key
                tface[s] = i
                tcnt[s] = corner
                continue
            # a second face of the cell: certified only as the other half along the same diagonal
            # (the right angle at the opposite corner: both free bits differ); a third never
            both = 7 - (1 << a)
            if tface[s] < 0 or tcnt[s] < 0 or (tcnt[s] ^ corner) & both != both:
                tface[s] = -1
            else:
                tcnt[s] = -1  # (two halves: full)
        for r in range(c0, c1):
            i = order[r]
            s = slot[i]
            if s >= 0 and tface[s] >= 0:
                cg[i] = g
    return cg


@_pure
def _same_cells(cg, i, j):
    """Faces i and j are certified in one group (:func:`_lattice_cells`): they do not intersect.
    (``cg`` empty: no groups.)"""
    return len(cg) > 0 and cg[i] >= 0 and cg[i] == cg[j]


@_kernel
def _fill_stars(V, F, star, lev, l0, l1, cg):
    """:func:`_star_fill_levels`, less the vertices whose faces are all certified in one group
    (:func:`_lattice_cells`): every pair of faces at such a vertex is decided before its stars
    are asked (a vertex's star does not depend on which others are certified)."""
    if len(cg) == 0:
        _star_fill_levels(V, F, star, lev, l0, l1)
        return
    nv = len(V)
    # -1 no face yet, -2 a star needed, else the one group (int32: groups are below 8 m + 16)
    mark = np.full(nv, -1, np.int32)
    for i in range(len(F)):
        g = cg[i]
        for t in range(3):
            v = F[i, t]
            if g < 0 or (mark[v] >= 0 and mark[v] != g):
                mark[v] = -2
            elif mark[v] == -1:
                mark[v] = g
    lv = np.empty(nv, np.int64)
    for v in range(nv):
        lv[v] = lev[v] if mark[v] == -2 else l1 + 1
    _star_fill_levels(V, F, star, lv, l0, l1)


# ------------------------------------------------------------------------------------------------
# broad phase: hashed uniform grid
# ------------------------------------------------------------------------------------------------
@_kernel
def _grow(a, cap):
    b = np.empty(cap, np.int64)
    for i in range(len(a)):
        b[i] = a[i]
    return b


@_kernel
def _push(pi, pj, n, i, j):
    """The pair ``(i, j)`` appended at ``n`` to the lists ``pi``, ``pj`` (grown when full):
    ``(pi, pj, n + 1)``."""
    if n == len(pi):
        pi = _grow(pi, 2 * n)
        pj = _grow(pj, 2 * n)
    pi[n] = i
    pj[n] = j
    return pi, pj, n + 1


@_pure
def _cell(x, lo, h):
    return np.int64(math.floor((x - lo) / h))


@_pure
def _face_range(V, F, i, k):
    """The lowest and highest coordinate ``k`` of face i's corners: its box along axis k."""
    a = V[F[i, 0], k]
    b = V[F[i, 1], k]
    c = V[F[i, 2], k]
    return min(a, min(b, c)), max(a, max(b, c))


@_kernel
def _median_extent(V, F, live, nlive, k, step):
    """The median extent along axis ``k`` of every ``step``-th of the ``nlive`` faces marked in
    ``live`` (the first, then every ``step``-th after it, in the order of their numbers; all of
    them for ``step == 1``)."""
    ext = np.empty((nlive + step - 1) // step, np.float64)
    n = 0
    c = 0
    for i in range(len(F)):
        if live[i] != 0:
            if c % step == 0:
                lo, hi = _face_range(V, F, i, k)
                ext[n] = hi - lo
                n += 1
            c += 1
    return np.median(ext[:n])


@_pure
def _count_cells(V, F, live, glo, h):
    """The (face, cell) entries of the faces marked in ``live`` in the grid of cell sizes ``h``
    from ``glo``."""
    total = 0
    for i in range(len(F)):
        if live[i] == 0:
            continue
        n = 1
        for k in range(3):
            lo, hi = _face_range(V, F, i, k)
            n *= _cell(hi, glo[k], h[k]) - _cell(lo, glo[k], h[k]) + 1
        total += n
    return total


@_pure
def _chunk_end(lay, z0, nz, chunk):
    """The chunk of layers of cells from ``z0``: one layer, then as many more as keep its entries
    (``lay`` per layer) at most ``chunk``.  Returns ``(z1, entries)``, the layers ``z0 .. z1 - 1``."""
    z1 = z0
    run = lay[z0] - lay[z0]
    while z1 < nz and (run == 0 or run + lay[z1] <= chunk):
        run += lay[z1]
        z1 += 1
    return z1, run


@_pure
def _box_gates(abox, a, b):
    """Which in-plane tests can decide the pair of rows ``a`` and ``b`` of a table of face boxes
    (``lo x, y, z, hi x, y, z`` per row, as :func:`_face_range` gives them): bit 1 where their
    z-ranges meet only at one height with neither face flat there (else :func:`_across_plane`
    returns -1), bit 2 where along some axis both faces have extent and the boxes only touch
    (else :func:`_touching_boxes` returns -1).  The same comparisons of the same numbers as those
    tests make first, so skipping a test whose bit is clear changes no outcome; on the lobster's
    mesh some 700k of the 1.3M pairs that reach the tests skip the first, 260k the second."""
    gate = 0
    for k in range(3):
        alo = abox[a, k]
        ahi = abox[a, 3 + k]
        blo = abox[b, k]
        bhi = abox[b, 3 + k]
        if alo < ahi and blo < bhi and (ahi == blo or bhi == alo):
            gate |= 2
            if k == 2:
                gate |= 1
    return gate


@_pure
def _grid_scan(V, ws, F, star, sst, quick, start, ent_slot, ent_key, ent_low, abox, aface, acg, nbc, at):
    """The pair loop of one chunk of :func:`_intersecting_pairs`' grid: the pairs of entries of one
    bucket (``start``, the ``nbc`` buckets' entries ``ent_*`` of slots ``abox``, ``aface``, ``acg``)
    from the place ``at[0:3]`` (bucket, entry, second entry; zeros at first), each tested as there.
    Returns 1 at a pair that intersects (faces ``at[3] < at[4]``; ``at`` then holds the place after
    it), 2 where the vertices' stars fall due before the pair at ``at`` is tested (the caller fills
    them and calls again: the pair is taken again from its start, and its tests repeat the same
    comparisons), 0 at the chunk's end.

    The loop that the caller would run (the same pairs, tests and order), in a kernel without
    reference counting (:func:`_pure`): in the caller, which allocates, each call of a test counted
    its array arguments in and out (atomic operations) once per pair."""
    q = at[0]
    r = at[1]
    t0 = at[2]
    while q < nbc:
        s1 = start[q + 1]
        if r < start[q]:
            r = start[q]
        while r < s1:
            a = ent_slot[r]
            key = ent_key[r]
            low = ent_low[r]
            t = max(t0, r + 1)
            t0 = 0
            while t < s1:
                # test the pair only in the cell of the low corner of the boxes' overlap (the cell
                # of a larger coordinate is never lower: the larger of the two cells): both faces
                # reach this cell, so along each axis it is the larger of their lowest cells where
                # it is the lowest of one of them (ent_low), which two bytes say without the faces'
                # rows
                if ent_key[t] != key or (low | ent_low[t]) != 7:
                    t += 1
                    continue
                b = ent_slot[t]
                if acg[a] >= 0 and acg[a] == acg[b]:
                    t += 1
                    continue  # (two faces certified in one group: the pair needs nothing)
                if (abox[a, 0] > abox[b, 3] or abox[b, 0] > abox[a, 3] or abox[a, 1] > abox[b, 4]
                        or abox[b, 1] > abox[a, 4] or abox[a, 2] > abox[b, 5] or abox[b, 2] > abox[a, 5]):
                    t += 1
                    continue
                i = min(aface[a], aface[b])
                j = max(aface[a], aface[b])
                if _star_due(sst):
                    at[0] = q
                    at[1] = r
                    at[2] = t
                    return 2
                if _shares_certified(F, star, i, j):
                    t += 1
                    continue
                # the in-plane tests only where the boxes say they decide (_box_gates): the same
                # outcome as calling them, without reading the faces' corners again
                gate = _box_gates(abox, a, b)
                hit = np.int64(-1)
                if gate & 1:
                    hit = _across_plane(V, ws, F, i, j)
                if hit < 0 and quick == 1 and gate & 2:
                    hit = _touching_boxes(V, ws, F, i, j)
                if hit < 0:
                    hit = 1 if _pair_intersects(V, ws, F, i, j) else 0
                if hit == 1:
                    at[0] = q
                    at[1] = r
                    at[2] = t + 1
                    at[3] = i
                    at[4] = j
                    return 1
                t += 1
            r += 1
        q += 1
    at[0] = q
    return 0


@njit(cache=True, **_OPTIONS)
def _intersecting_pairs(V, ws, F, star, sst, quick, budget, stop, chunk, cg):
    """Pairs ``(i, j)``, ``i < j``, of faces that intersect (see the module docstring);
    ``F`` holds canonical vertex indices, ``star`` marks the vertices whose pairs are decided
    (:func:`_star_certified`; all 0 for none), filled when first needed (``sst``, see
    :func:`_shares_certified`); ``quick == 1``: pairs of faces whose boxes only touch
    are decided in the plane where they touch (:func:`_touching_boxes`).  ``budget`` bounds the grid cells per face on average.
    ``stop > 0``: return as soon as ``stop`` pairs are found (some of the pairs, for a caller that
    asks only whether there are any).  ``cg``: per face its group where certified by
    :func:`_lattice_cells` (pairs of one group not tested), or empty.

    The grid's (face, cell) entries are made and searched in chunks of consecutive layers of cells
    along z of about ``chunk`` entries (one chunk for a small mesh): a pair is taken only in the
    cell of the low corner of its boxes' overlap, which lies in one layer and so in one chunk, and
    both faces have an entry there; so every pair is found once, as with all entries in one table.
    Only the faces of the current chunk's layers are held (box, cells), and the faces' boxes come
    from ``V`` and ``F`` (not a table of them): on the lobster's mesh (396k faces, 2M entries) the
    test took some 53 MiB in one table, 8 in chunks."""
    m = len(F)
    live = np.empty(m, np.int8)
    glo = np.empty(3, np.float64)
    ghi = np.empty(3, np.float64)
    for k in range(3):
        glo[k] = np.inf
        ghi[k] = -np.inf
    nlive = np.int64(0)  # (a literal 0 would compile _median_extent a second time, for Literal[int](0))
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        live[i] = 0
        if a == b or b == c or a == c:
            continue
        # (a face certified in a group (_lattice_cells) is half of a rectangle, its two legs along two
        # axes from the right-angle corner, each of nonzero length: not collinear, no test needed; on
        # the lobster's mesh 84 % of the faces, some 3 % of this call)
        if ((len(cg) == 0 or cg[i] < 0) and _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0
                and _o2(V, ws, a, b, c, ax0, ax1) == 0):
            continue  # collinear (exactly)
        live[i] = 1
        nlive += 1
        for k in range(3):
            lo, hi = _face_range(V, F, i, k)
            glo[k] = min(glo[k], lo)
            ghi[k] = max(ghi[k], hi)
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    npairs = np.int64(0)  # (a literal 0 would compile _push a second time, for Literal[int](0))
    if nlive < 2:
        return pi[:0], pj[:0]
    # cell sizes: per axis, the median face extent along it (slices make faces thin across them),
    # no smaller than 1/16 of the largest (a few long faces, such as caps, span many cells).  On a
    # large mesh the median of a sample of the faces (see _MEDIAN_SAMPLE): the cell sizes only set
    # the work and the memory, never the pairs, and the entries are counted exactly below
    h = np.empty(3, np.float64)
    step = max(nlive // _MEDIAN_SAMPLE, np.int64(1))
    for k in range(3):
        h[k] = _median_extent(V, F, live, nlive, np.int64(k), step)
    hbig = max(h[0], max(h[1], h[2]))
    for k in range(3):
        hmin = max((ghi[k] - glo[k]) / (2.0 ** _KEY_BITS - 2.0), hbig / 16.0)
        if not h[k] > hmin:
            h[k] = hmin
        if not h[k] > 0.0:
            h[k] = 1.0
    limit = budget * nlive
    total = _count_cells(V, F, live, glo, h)
    while total > limit:
        for k in range(3):
            h[k] *= 1.5
        total = _count_cells(V, F, live, glo, h)
    nz = _cell(ghi[2], glo[2], h[2]) + 1
    ny = _cell(ghi[1], glo[1], h[1]) + 1
    nx = _cell(ghi[0], glo[0], h[0]) + 1
    # the live faces in order of their lowest layer (a counting sort), the entries per layer, and
    # the largest chunk's entries (``most``) and faces (``cap``); one chunk where the mesh is
    # small, or where its layers outnumber its faces (the tables per layer would be the larger)
    chunked = total > chunk and 1 < nz <= nlive
    order = np.empty(nlive, np.int32)
    if chunked:
        lay = np.zeros(nz, np.int64)
        first = np.zeros(nz + 1, np.int64)  # faces whose lowest layer is below z: first[z]
        last = np.zeros(nz + 1, np.int64)  # faces whose highest layer is below z: last[z]
        for i in range(m):
            if live[i] == 0:
                continue
            lo, hi = _face_range(V, F, i, ax0)
            nxy = _cell(hi, glo[0], h[0]) - _cell(lo, glo[0], h[0]) + 1
            lo, hi = _face_range(V, F, i, ax1)
            nxy *= _cell(hi, glo[1], h[1]) - _cell(lo, glo[1], h[1]) + 1
            lo, hi = _face_range(V, F, i, ax2)
            z0 = _cell(lo, glo[2], h[2])
            z1 = _cell(hi, glo[2], h[2])
            for cz in range(z0, z1 + 1):
                lay[cz] += nxy
            first[z0 + 1] += 1
            last[z1 + 1] += 1
        for z in range(nz):
            first[z + 1] += first[z]
            last[z + 1] += last[z]
        fill = first[:nz].copy()
        for i in range(m):
            if live[i] == 0:
                continue
            lo, hi = _face_range(V, F, i, ax2)
            z0 = _cell(lo, glo[2], h[2])
            order[fill[z0]] = i
            fill[z0] += 1
        most = np.int64(1)
        cap = np.int64(1)
        z0 = np.int64(0)
        while z0 < nz:
            z1, run = _chunk_end(lay, z0, nz, chunk)
            most = max(most, run)
            cap = max(cap, first[z1] - last[z0])  # faces with a layer in z0 .. z1 - 1
            z0 = z1
    else:
        lay = np.zeros(1, np.int64)
        first = np.zeros(1, np.int64)
        n = 0
        for i in range(m):
            if live[i] != 0:
                order[n] = i
                n += 1
        most = total
        cap = np.int64(nlive)
    # a chunk's hash table of cells: a counting sort of its (face, cell) entries by bucket (about
    # one entry per bucket: the entries of one cell share a bucket anyway); bucket starts and slots
    # in int32, the keys (cells, z-major) in int64
    if most >= 2**31 - 1:
        raise MemoryError("too many grid cells in one layer for the crossing test's int32 tables")
    nb = 1
    while nb < most:
        nb *= 2
    start = np.empty(nb + 1, np.int32)
    ent_slot = np.empty(most, np.int32)
    ent_key = np.empty(most, np.int64)
    # per entry, which of its cell's coordinates are the face's lowest (bit k: along axis k)
    ent_low = np.empty(most, np.int8)
    # the chunk's faces (slots): box, cells (lowest and highest per axis), face
    abox = np.empty((cap, 6), np.float64)
    acell = np.empty((cap, 6), np.int64)
    aface = np.empty(cap, np.int64)
    acg = np.empty(cap, np.int64)  # (its group where certified, else -1: see _lattice_cells)
    at = np.zeros(5, np.int64)  # (_grid_scan's place and pair)
    nact = 0
    nxt = 0
    z0 = np.int64(0)
    while z0 < nz:
        if chunked:
            z1, run = _chunk_end(lay, z0, nz, chunk)
            upto = first[z1]
        else:
            z1 = nz
            run = total
            upto = nlive
        # the faces of the layers z0 .. z1 - 1: those still reaching z0, in order, then the new ones
        keep = 0
        for s in range(nact):
            if acell[s, 5] >= z0:
                if keep != s:
                    for k in range(6):
                        abox[keep, k] = abox[s, k]
                        acell[keep, k] = acell[s, k]
                    aface[keep] = aface[s]
                    acg[keep] = acg[s]
                keep += 1
        nact = keep
        while nxt < upto:
            i = np.int64(order[nxt])
            nxt += 1
            for k in range(3):
                lo, hi = _face_range(V, F, i, k)
                abox[nact, k] = lo
                abox[nact, 3 + k] = hi
                acell[nact, k] = _cell(lo, glo[k], h[k])
                acell[nact, 3 + k] = _cell(hi, glo[k], h[k])
            aface[nact] = i
            acg[nact] = cg[i] if len(cg) > 0 else -1
            nact += 1
        nbc = 1
        while nbc < run:
            nbc *= 2
        mask = nbc - 1
        for q in range(nbc + 1):
            start[q] = 0
        # every (face, cell) entry of the chunk: counted per bucket, then stored at its bucket's
        # fill pointer (start itself, each bucket's ending at the next one's start; shifted back)
        for store in range(2):
            for s in range(nact):
                for cz in range(max(acell[s, 2], z0), min(acell[s, 5], z1 - 1) + 1):
                    for cy in range(acell[s, 1], acell[s, 4] + 1):
                        for cx in range(acell[s, 0], acell[s, 3] + 1):
                            key = (cz * ny + cy) * nx + cx
                            q = key & mask
                            if store == 0:
                                start[q] += 1
                            else:
                                r = start[q]
                                ent_slot[r] = s
                                ent_key[r] = key
                                ent_low[r] = ((1 if cx == acell[s, 0] else 0) | (2 if cy == acell[s, 1] else 0)
                                              | (4 if cz == acell[s, 2] else 0))
                                start[q] = r + 1
            if store == 0:
                acc = 0
                for q in range(nbc):
                    cnt = start[q]
                    start[q] = acc
                    acc += cnt
                start[nbc] = acc
        for q in range(nbc, 0, -1):
            start[q] = start[q - 1]
        start[0] = 0
        # the chunk's pairs (_grid_scan), stopping at each pair that intersects and once where the
        # stars fall due (both allocate here, which the scan cannot)
        at[0] = 0
        at[1] = 0
        at[2] = 0
        while True:
            got = _grid_scan(V, ws, F, star, sst, quick, start, ent_slot, ent_key, ent_low, abox, aface, acg,
                             nbc, at)
            if got == 0:
                break
            if got == 2:
                _fill_stars(V, F, star, np.zeros(len(V), np.int64), ax0, ax0, cg)
                continue
            pi, pj, npairs = _push(pi, pj, npairs, at[3], at[4])
            if npairs == stop:
                return pi[:npairs], pj[:npairs]
        z0 = z1
    return pi[:npairs], pj[:npairs]


# ------------------------------------------------------------------------------------------------
# broad phase for sectioned meshes: slabs between consecutive heights, 2D sweeps
# ------------------------------------------------------------------------------------------------
# Meshes made from sections have every vertex at one of a few heights z_0 < z_1 < ... (the
# section planes, and mid-planes between them).  A face is flat (its corners at one height) or
# spans the slabs between its lowest and highest corner heights (one slab, mostly).  The faces'
# z-ranges say which pairs can meet at all:
#   * two faces whose z-ranges overlap in more than a point share a slab: the pair is a candidate
#     when their xy boxes overlap, found in the lowest slab both span (so once);
#   * faces whose z-ranges meet only at one height c (a face ending at c and one starting there, a
#     flat face at c and a face ending, starting or passing there, two flat faces at c): every
#     common point lies in the plane z = c, in the part of each face at that height (a corner, an
#     edge, the whole flat face; the xy box of the face for one passing through), so the pair is a
#     candidate when the xy boxes of those parts overlap;
#   * all other pairs have disjoint z-ranges and cannot meet.
# The candidates of each slab and of each plane are found by a sweep over x with a y-overlap
# test, and every candidate gets the same exact test as in the grid path (the in-plane test for a
# face ending and one starting at c, the general test otherwise).  Since those tests are exact
# and every pair that can meet is a candidate, the pairs are exactly those of the grid path.  The
# pairs of a face ending and a face starting at c are all decided without a test when their parts
# at c form an embedded planar graph (_plane_embedded), which is checked once per plane.  Two faces
# within one slab whose corners lie apart along x or y on both its planes, or that share one corner
# and lie apart beside it (the two rules before _slab_hit: comparisons of coordinates), do not meet
# (the bands between two rings: most of their candidates).
@_kernel
def _sweep(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, n_out, work, limit, need2):
    """The candidate pairs of :func:`_x_pairs` (arguments and result as there), from
    :func:`_cell_pairs` for at least :data:`_CELL_SWEEP` entries (the same pairs, in another order
    and with less work: on the liver's whole mesh the planes' sweeps over x met some 21 M pairs of
    boxes)."""
    if len(ids) >= _CELL_SWEEP:
        return _cell_pairs(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, n_out, work, limit, need2)
    return _x_pairs(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, n_out, work, limit, need2)


@_pure
def _group_pair(ga, gb, need2):
    """Entries of groups ``ga`` and ``gb`` make a candidate pair (the rules of :func:`_x_pairs`)."""
    if ga == gb and ga != 2:
        return False
    if (need2 == 1 or ga == 3 or gb == 3) and ga != 2 and gb != 2:
        return False
    return True


@_kernel
def _cell_pairs(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, n_out, work, limit, need2):
    """:func:`_x_pairs`' candidate pairs (each once, in another order) from a grid of about
    ``len(ids)`` cells over the entries' xy box, fewer where the entries would take more than four
    cells each on average: two entries whose closed boxes overlap share the cell of the low corner
    of the overlap and are taken there only.  ``work`` counts the pairs of entries met in a cell."""
    n = len(ids)
    if n < 2:
        return out_i, out_j, n_out, work
    gxl = np.inf
    gxh = -np.inf
    gyl = np.inf
    gyh = -np.inf
    for t in range(n):
        e = ids[t]
        gxl = min(gxl, xlo[e])
        gxh = max(gxh, xhi[e])
        gyl = min(gyl, ylo[e])
        gyh = max(gyh, yhi[e])
    g = np.int64(1)
    while (g + 1) * (g + 1) <= n:
        g += 1
    gx = g
    gy = g
    cx0 = np.empty(n, np.int64)
    cy0 = np.empty(n, np.int64)
    while True:
        hx = (gxh - gxl) / gx
        hy = (gyh - gyl) / gy
        if not hx > 0.0:
            hx = 1.0
        if not hy > 0.0:
            hy = 1.0
        nent = np.int64(0)
        for t in range(n):
            e = ids[t]
            x0 = min(np.int64((xlo[e] - gxl) / hx), gx - 1)
            x1 = min(np.int64((xhi[e] - gxl) / hx), gx - 1)
            y0 = min(np.int64((ylo[e] - gyl) / hy), gy - 1)
            y1 = min(np.int64((yhi[e] - gyl) / hy), gy - 1)
            cx0[t] = x0
            cy0[t] = y0
            nent += (x1 - x0 + 1) * (y1 - y0 + 1)
        if nent <= 4 * n or (gx == 1 and gy == 1):
            break
        gx = max(gx // 2, np.int64(1))
        gy = max(gy // 2, np.int64(1))
    nc = gx * gy
    start = np.zeros(nc + 1, np.int64)
    for t in range(n):
        e = ids[t]
        x1 = min(np.int64((xhi[e] - gxl) / hx), gx - 1)
        y1 = min(np.int64((yhi[e] - gyl) / hy), gy - 1)
        for cy in range(cy0[t], y1 + 1):
            for cx in range(cx0[t], x1 + 1):
                start[cy * gx + cx + 1] += 1
    for q in range(nc):
        start[q + 1] += start[q]
    ent = np.empty(nent, np.int64)
    # (start[q] is the fill pointer of cell q, shifted back below).  A cell lists its entries of
    # group 2 first: with need2 every pair has one, so only those start pairs, with any later
    # entry, and two others are never met (on the liver's whole mesh the planes hold 467k
    # entries, 52k of them flat faces: 5.0 M pairs of boxes met for 618k candidates before)
    for two in range(2):
        for t in range(n):
            e = ids[t]
            if (grp[e] == 2) != (two == 0):
                continue
            x1 = min(np.int64((xhi[e] - gxl) / hx), gx - 1)
            y1 = min(np.int64((yhi[e] - gyl) / hy), gy - 1)
            for cy in range(cy0[t], y1 + 1):
                for cx in range(cx0[t], x1 + 1):
                    q = cy * gx + cx
                    ent[start[q]] = t
                    start[q] += 1
    for q in range(nc, 0, -1):
        start[q] = start[q - 1]
    start[0] = 0
    for q in range(nc):
        for r in range(start[q], start[q + 1]):
            s = ent[r]
            a = ids[s]
            if need2 == 1 and grp[a] != 2:
                break  # (the others: no pair of two of them is a candidate)
            for v in range(r + 1, start[q + 1]):
                u = ent[v]
                b = ids[u]
                work += 1
                if len(eg) > 0 and eg[a] >= 0 and eg[a] == eg[b]:
                    continue  # (two faces certified in one group: no candidate, see _x_pairs)
                if xlo[b] > xhi[a] or xlo[a] > xhi[b] or ylo[a] > yhi[b] or ylo[b] > yhi[a]:
                    continue
                if max(cy0[s], cy0[u]) * gx + max(cx0[s], cx0[u]) != q:
                    continue  # (taken in the cell of the low corner of the overlap)
                if not _group_pair(grp[a], grp[b], need2):
                    continue
                if n_out == len(out_i):
                    out_i = _grow(out_i, 2 * n_out)
                    out_j = _grow(out_j, 2 * n_out)
                out_i[n_out] = a
                out_j[n_out] = b
                n_out += 1
            if work > limit:
                return out_i, out_j, np.int64(-1), work
    return out_i, out_j, n_out, work


@_kernel
def _x_pairs(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, n_out, work, limit, need2):
    """Candidate pairs among the entries ``ids``: closed xy boxes overlapping, not two entries of
    one group unless the group is 2, an entry of group 3 only with one of group 2 (with
    ``need2``: only pairs with an entry of group 2), and not two entries of faces certified in one
    group (``eg``, per entry, the face's group of :func:`_lattice_cells` or -1; empty: none; such a
    pair needs no test, and on the liver's whole mesh 600k of the planes' 618k candidates were such),
    appended to out_i/out_j from ``n_out``.  Returns the new count and the work done (box
    tests), or ``-1`` as count when ``work`` exceeds ``limit``.

    The entries are sorted into ``len(ids)`` equal buckets by the low end of their x-range (a
    counting sort; the bucket of x is monotone in x), and each entry meets the later ones of its
    own bucket and those of the buckets up to the one of its high end: each overlapping pair once."""
    n = len(ids)
    if n < 2:
        return out_i, out_j, n_out, work
    lo = np.inf
    hi = -np.inf
    for t in range(n):
        lo = min(lo, xlo[ids[t]])
        hi = max(hi, xhi[ids[t]])
    nb = n
    h = (hi - lo) / nb
    if not h > 0.0:
        h = 1.0
    start = np.zeros(nb + 1, np.int64)
    bk = np.empty(n, np.int64)
    for t in range(n):
        q = min(np.int64((xlo[ids[t]] - lo) / h), nb - 1)
        bk[t] = q
        start[q + 1] += 1
    for q in range(nb):
        start[q + 1] += start[q]
    fill = start[:nb].copy()
    order = np.empty(n, np.int64)
    for t in range(n):
        order[fill[bk[t]]] = ids[t]
        fill[bk[t]] += 1
    for q in range(nb):
        for s in range(start[q], start[q + 1]):
            a = order[s]
            xa = xhi[a]
            qh = min(np.int64((xa - lo) / h), nb - 1)
            for u in range(s + 1, start[qh + 1]):
                b = order[u]
                work += 1
                if len(eg) > 0 and eg[a] >= 0 and eg[a] == eg[b]:
                    continue
                if xlo[b] > xa or xlo[a] > xhi[b] or ylo[a] > yhi[b] or ylo[b] > yhi[a]:
                    continue
                if grp[a] == grp[b] and grp[a] != 2:
                    continue
                if (need2 == 1 or grp[a] == 3 or grp[b] == 3) and grp[a] != 2 and grp[b] != 2:
                    continue
                if n_out == len(out_i):
                    out_i = _grow(out_i, 2 * n_out)
                    out_j = _grow(out_j, 2 * n_out)
                out_i[n_out] = a
                out_j[n_out] = b
                n_out += 1
            if work > limit:
                return out_i, out_j, np.int64(-1), work
    return out_i, out_j, n_out, work


@_kernel
def _plane_convex_ring(V, ws, pu, pw, ne, k, stamp, d1, d2):
    """A certificate for :func:`_plane_embedded` (entries ``0 .. ne-1``, segments ``pu - pw`` and
    points ``pu == pw``) without its sweep: True when the segments, a common edge once, form one
    closed polygon, strictly convex and winding once, and every point ends a segment.  False means
    "not shown" (the caller then runs :func:`_plane_embedded`).

    Then the parts form an embedded planar graph: a closed polygon that turns the same strict way
    at every corner and whose edge directions go round exactly once is convex and simple, so two
    distinct edges meet only where consecutive, in their common corner, and there not along one ray
    (the turn is not zero); a point part is a corner.  (The bands between two rings of a convex
    section, as the slices of a ball: one ring per plane, and a sweep over it saved.)  Exact: the
    turns are :func:`_o2`, and the half-plane of an edge direction reads the signs of coordinate
    differences, which floating-point subtraction keeps.  ``stamp``, ``d1``, ``d2`` are
    :func:`_plane_embedded`'s workspaces (the two neighbours of each corner), marked with ``-(k +
    2)``, a value :func:`_plane_embedded`'s marks (``k``) and its untouched ones (-1) never take."""
    tag = -(k + 2)
    nseg = 0
    v0 = -1
    for e in range(ne):
        u = pu[e]
        w = pw[e]
        if u == w:
            continue
        if stamp[u] == tag and (d1[u] == w or d2[u] == w):
            continue  # the edge again (from the face on the other side of the plane)
        for q in range(2):
            a = u if q == 0 else w
            b = w if q == 0 else u
            if stamp[a] != tag:
                stamp[a] = tag
                d1[a] = b
                d2[a] = -1
            elif d2[a] < 0:
                d2[a] = b
            else:
                return False  # a corner of three edges
        nseg += 1
        v0 = u
    if nseg < 3:
        return False
    for e in range(ne):
        if pu[e] == pw[e] and stamp[pu[e]] != tag:
            return False  # a point that ends no segment
    ax = np.int64(0)
    ay = np.int64(1)
    sign = 0
    wraps = 0
    a = v0
    b = np.int64(d1[v0])
    for t in range(nseg):
        if d2[b] < 0:
            return False  # an open end
        c = np.int64(d1[b]) if d1[b] != a else np.int64(d2[b])
        turn = _o2(V, ws, a, b, c, ax, ay)
        if turn == 0 or (sign != 0 and turn != sign):
            return False
        sign = turn
        # the half-plane of each direction (0: y > 0 or y == 0 < x; 1: the rest): turning left
        # the directions pass +x going from half 1 to half 0, turning right from 0 to 1
        h1 = 0 if (V[b, 1] > V[a, 1] or (V[b, 1] == V[a, 1] and V[b, 0] > V[a, 0])) else 1
        h2 = 0 if (V[c, 1] > V[b, 1] or (V[c, 1] == V[b, 1] and V[c, 0] > V[b, 0])) else 1
        if (turn > 0 and h1 == 1 and h2 == 0) or (turn < 0 and h1 == 0 and h2 == 1):
            wraps += 1
        a = b
        b = c
        if a == v0 and t + 1 < nseg:
            return False  # closed before every edge was met: more than one polygon
    return a == v0 and b == d1[v0] and wraps == 1


@_kernel
def _plane_embedded(V, ws, xlo, xhi, ylo, yhi, pu, pw, ne, k, stamp, d1, d2, cert, all2, ci, cj, work, limit):
    """:func:`_plane_embedded_g` with no groups (every pair of parts whose boxes meet checked)."""
    return _plane_embedded_g(V, ws, xlo, xhi, ylo, yhi, pu, pw, ne, k, stamp, d1, d2, cert, all2, np.zeros(0, np.int64),
                             ci, cj, work, limit)


@_kernel
def _plane_embedded_g(V, ws, xlo, xhi, ylo, yhi, pu, pw, ne, k, stamp, d1, d2, cert, all2, eg, ci, cj, work, limit):
    """The parts at one height of the faces below and above it (entries ``0 .. ne-1``: a segment
    ``pu - pw`` or a point ``pu == pw``, canonical vertex indices) form an embedded planar graph:
    two distinct segments meet at most in a common endpoint (not along a common ray from it), and
    a point lies on no segment but the ones it ends.  Returns ``(embedded, work)``.

    Then no face below and face above intersect (``_across_plane``): their parts are one
    element (a common edge, or a common corner that is a point part), or two distinct elements,
    which meet at most in a common endpoint, from which they do not run along one ray.  A point
    part that ends some segment is not an element of its own: a part that contains it meets that
    segment beyond a common endpoint, or along its ray, which the test sees.  ``stamp`` (per
    vertex, with ``d1``, ``d2``: the segments seen from a lower end), ``cert``, ``ci``, ``cj`` are
    workspaces (``all2`` all 2s); more than ``limit`` box
    tests in all: not embedded.  Returns ``(embedded, work, ci, cj)``.

    ``eg`` (per entry, or empty): the group of :func:`_lattice_cells` of the entry's face, or -1.
    Two parts of faces certified in one group are not checked: they never fail the checks.  The
    faces, halves of distinct cells of one product grid (two halves of one cell give a segment and
    its own endpoint), meet at most in a common corner or along a common side that both hold
    whole, and a part is a side of its face or a corner of it, at the height of the plane.  Two
    parts without a common endpoint that touch would meet in a common corner, an endpoint of both
    (and so their common vertex, canonical indices), or at a point inside a common side, which
    only that side itself holds of either face's sides and corners: the same segment in both.  Two
    with a common endpoint along one ray would overlap in a segment, inside a common side: again
    the same segment twice, checked once."""
    n = 0
    for e in range(ne):  # the segments, a common edge once (up to two per lower end are remembered)
        u = pu[e]
        w = pw[e]
        if u == w:
            continue
        if stamp[u] != k:
            d1[u] = -1
            d2[u] = -1
        elif d1[u] == w or d2[u] == w:
            continue
        if d1[u] < 0:
            d1[u] = w
        elif d2[u] < 0:
            d2[u] = w
        cert[n] = e
        n += 1
        if stamp[w] != k:
            d1[w] = -1
            d2[w] = -1
        stamp[u] = k
        stamp[w] = k
    for e in range(ne):  # the points that end no segment, once each
        if pu[e] == pw[e] and stamp[pu[e]] != k:
            stamp[pu[e]] = k
            cert[n] = e
            n += 1
    ci, cj, n_out, work = _sweep(xlo, xhi, ylo, yhi, all2, eg, cert[:n], ci, cj, np.int64(0), work, limit,
                                 np.int64(0))
    if n_out < 0:
        return False, work, ci, cj
    ax = np.int64(0)
    ay = np.int64(1)
    for t in range(n_out):
        a = ci[t]
        b = cj[t]
        u1 = pu[a]
        w1 = pw[a]
        u2 = pu[b]
        w2 = pw[b]
        if u1 == u2 and w1 == w2:
            continue
        p = np.int64(-1)
        if u1 == u2 or u1 == w2:
            p = u1
        elif w1 == u2 or w1 == w2:
            p = w1
        if p < 0:
            if _seg_seg_2d(V, ws, u1, w1, u2, w2, ax, ay):
                return False, work, ci, cj
            continue
        if u1 == w1 or u2 == w2:
            continue  # a point that ends the other segment
        q = w1 if u1 == p else u1
        r = w2 if u2 == p else u2
        if _o2(V, ws, p, q, r, ax, ay) != 0:
            continue
        for c in range(2):
            dq = V[q, c] - V[p, c]
            dr = V[r, c] - V[p, c]
            if dq != 0.0 or dr != 0.0:
                if (dq > 0.0 and dr > 0.0) or (dq < 0.0 and dr < 0.0):
                    return False, work, ci, cj
                break
    return True, work, ci, cj


@_kernel
def _slab_embedded(V, F, lev, faces, k, keys, head, hstamp, nxt):
    """The faces ``faces``, each with its corners on the heights ``k`` and ``k + 1`` only, on a small
    dyadic grid (float arithmetic exact), do not meet each other in the open slab
    ``z_k < z < z_k+1`` except along common edges between the heights ("rungs"), and no two such
    faces fold onto each other along a rung.  A certificate, not a test: False means "not shown".

    Argument.  At a height between the planes (``t`` in (0, 1) of the way up) a face cuts a
    segment from the point on one rung to the point on the other; name the rung that the face's
    boundary runs down the *start*, the other the *end*.  Let ``c`` be the centre of the faces' xy
    box.  For a face with bottom corners ``b1, b2`` and top ``u`` (in boundary order) the
    orientation of ``c``, start point, end point is ``(1 - t)((1 - t) X + t Y)`` with
    ``X = (b1 - c) x (b2 - c)``, ``Y = (b1 - c) x (u - c) + (u - c) x (b2 - c)``; for bottom ``b``
    and top ``u1, u2`` it is ``t((1 - t) Y' + t X')`` with ``X' = (u2 - c) x (u1 - c)``,
    ``Y' = (b - c) x (u1 - c) + (u2 - c) x (b - c)``.  When all ``X, X'`` have one strict sign and
    ``Y, Y'`` that sign or zero, every segment at every such height turns strictly one way around
    ``c``: it covers an open arc of directions from ``c`` (less than a half turn).  When every
    rung is the start of exactly one face and the end of exactly one, the arcs chain end to start,
    so the number of arcs over a direction is the same for all directions and all heights; it is
    counted where the faces reach the lower plane (the arcs become those of the bottom edges): the
    bottom edges that cross the ray from ``c`` along +x.  When it is 1, at every height the arcs
    are disjoint and tile the directions once: two faces meet there only in the point of a rung
    they share (two chained arcs), distinct rungs never meet, and two faces on one rung do not
    overlap.  Every sign here is exact: the coordinates and ``c`` lie on a dyadic grid of under
    ``2^17`` steps per axis, so the products and sums are exact in float64.  Workspaces: ``keys``
    (two per face), ``nxt`` (one per face), ``head`` and ``hstamp`` (one per vertex, ``hstamp``
    never equal to ``k + 1`` on entry for a vertex of these faces)."""
    n = len(faces)
    if n < 2 or len(V) > 2147483647:  # (a rung's key packs its two corners in 32 bits each)
        return False
    xlo = np.inf
    xhi = -np.inf
    ylo = np.inf
    yhi = -np.inf
    for t in range(n):
        i = faces[t]
        for q in range(3):
            v = F[i, q]
            xlo = min(xlo, V[v, 0])
            xhi = max(xhi, V[v, 0])
            ylo = min(ylo, V[v, 1])
            yhi = max(yhi, V[v, 1])
    cx = 0.5 * (xlo + xhi)
    cy = 0.5 * (ylo + yhi)
    sigma = 0.0
    wind = 0
    for t in range(n):
        i = faces[t]
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        nb = (lev[a] == k) + (lev[b] == k) + (lev[c] == k)
        # rotate: two bottom corners -> (b1, b2, u); one -> (b, u1, u2)
        if nb == 2:
            if lev[a] != k:
                a, b, c = b, c, a
            elif lev[b] != k:
                a, b, c = c, a, b
        else:
            if lev[b] == k:
                a, b, c = b, c, a
            elif lev[c] == k:
                a, b, c = c, a, b
        ax = V[a, 0] - cx
        ay = V[a, 1] - cy
        bx = V[b, 0] - cx
        by = V[b, 1] - cy
        ux = V[c, 0] - cx
        uy = V[c, 1] - cy
        if nb == 2:  # a = b1, b = b2, c = u
            X = ax * by - ay * bx
            Y = (ax * uy - ay * ux) + (ux * by - uy * bx)
            start = (a << 32) | c
            end = (b << 32) | c
        else:  # a = b, b = u1, c = u2
            if ax == 0.0 and ay == 0.0:
                return False  # its arc would not shrink to nothing at the lower plane
            X = ux * by - uy * bx
            Y = (ax * by - ay * bx) + (ux * ay - uy * ax)
            start = (a << 32) | c
            end = (a << 32) | b
        if sigma == 0.0:
            sigma = 1.0 if X > 0.0 else -1.0
        if not sigma * X > 0.0 or sigma * Y < 0.0:
            return False
        keys[2 * t] = start
        keys[2 * t + 1] = end
        if nb == 2:  # the bottom edge's arc over the +x ray (half-open)
            if sigma > 0.0:
                py, qy = ay, by
            else:
                py, qy = by, ay
            if py < 0.0 and qy >= 0.0:
                wind += 1
    if wind != 1:
        return False
    # every rung the start of exactly one face and the end of exactly one: the ends in lists by
    # bottom corner (no rung twice), then each start takes an end of its list once (n of each)
    tag = k + 1
    for t in range(n):
        e = keys[2 * t + 1]
        b = e >> 32
        if hstamp[b] != tag:
            hstamp[b] = tag
            head[b] = -1
        r = head[b]
        while r >= 0:
            if keys[2 * r + 1] == e:
                return False
            r = nxt[r]
        nxt[t] = head[b]
        head[b] = t
    for t in range(n):
        st = keys[2 * t]
        b = st >> 32
        if hstamp[b] != tag:
            return False
        r = head[b]
        found = False
        while r >= 0:
            if keys[2 * r + 1] == st:
                keys[2 * r + 1] = -1  # taken
                found = True
                break
            r = nxt[r]
        if not found:
            return False
    return True


@_pure
def _corner_ranges(V, F, lev, i, k):
    """The x and y ranges of face i's corners on level k and of its other corners:
    ``(bx0, bx1, by0, by1, tx0, tx1, ty0, ty1)`` (infinite, lower above upper, where none)."""
    bx0 = np.inf
    bx1 = -np.inf
    by0 = np.inf
    by1 = -np.inf
    tx0 = np.inf
    tx1 = -np.inf
    ty0 = np.inf
    ty1 = -np.inf
    for q in range(3):
        v = F[i, q]
        x = V[v, 0]
        y = V[v, 1]
        if lev[v] == k:
            bx0 = min(bx0, x)
            bx1 = max(bx1, x)
            by0 = min(by0, y)
            by1 = max(by1, y)
        else:
            tx0 = min(tx0, x)
            tx1 = max(tx1, x)
            ty0 = min(ty0, y)
            ty1 = max(ty1, y)
    return bx0, bx1, by0, by1, tx0, tx1, ty0, ty1


@_pure
def _box_row(W, s, V, F, lev, i, k):
    """Row ``s`` of a sweep's rows for face i (:func:`_x_sweep`, :func:`_cell_sweep`,
    :func:`_two_level_sweep`): its xy box (columns 0-3), the x and y ranges of its corners on
    level k (4-7) and of its other corners (8-11), from :func:`_corner_ranges`."""
    bx0, bx1, by0, by1, tx0, tx1, ty0, ty1 = _corner_ranges(V, F, lev, i, k)
    W[s, 0] = min(bx0, tx0)
    W[s, 1] = max(bx1, tx1)
    W[s, 2] = min(by0, ty0)
    W[s, 3] = max(by1, ty1)
    W[s, 4] = bx0
    W[s, 5] = bx1
    W[s, 6] = by0
    W[s, 7] = by1
    W[s, 8] = tx0
    W[s, 9] = tx1
    W[s, 10] = ty0
    W[s, 11] = ty1


# Two rules decide most candidate pairs of a slab by comparisons of coordinates alone (exact);
# the slab sweep (:func:`_single_sweep`) applies them to its rows of corner ranges, and the tests
# keep them in their plain form.  Both hold for two faces whose corners lie on the same two
# heights only, planes k and k + 1.
#
# Ends apart: along x or y, one face's corners on plane k all lie strictly before the other's
# there, and the same on plane k + 1 (the same face first); then the faces have no common point.
# At a height t of the way up (0 <= t <= 1) a face's section is the hull of points that move
# linearly with t from its corners on plane k to those on plane k + 1: the largest x of the first
# face's section is a maximum of linear functions of t, convex, so at most the interpolation of its
# values at t = 0 and t = 1; the smallest x of the other's is concave, at least the interpolation of
# its own.  Both ends strictly apart put the interpolations, and so the sections, apart at every t.
#
# Apart but at a corner: the faces share one corner p; along x or y, one face's corners on the
# other plane than p's all lie strictly before the other face's there, and on p's plane the first
# face's other corners lie strictly before p and the second's strictly after it.  Then they meet
# only at p: as above, from p's plane (t = 0) to the other (t = 1), the first face's largest
# coordinate at height t is at most (1 - t) p + t its largest on the other plane and the second's
# smallest at least (1 - t) p + t its smallest there, so the sections are strictly apart at every
# t > 0; at t = 0 the first face's part lies at or before p and the second's at or after it, with
# p the only point of either on p's line.


@_pure
def _slab_hit(V, ws, F, star, quick, i, j):
    """Faces i and j, a candidate pair of a slab, intersect: a pair sharing a certified vertex not
    tested, with ``quick`` boxes that only touch decided where they touch (:func:`_touching_boxes`).
    (Allocating nothing, it is compiled without reference counting, :func:`_pure`: as a kernel that
    also filled the stars it cost the liver's band calls some 15 %.)"""
    # (the common corners found once: a pair with one is not decided by _touching_boxes, and on
    # the mesher's bands most candidates that get here share an edge; liver's 988 band and join
    # tests 0.236 -> 0.224 CPU-s)
    d = F[j, 0]
    e = F[j, 1]
    f = F[j, 2]
    sd = d == F[i, 0] or d == F[i, 1] or d == F[i, 2]
    se = e == F[i, 0] or e == F[i, 1] or e == F[i, 2]
    sf = f == F[i, 0] or f == F[i, 1] or f == F[i, 2]
    if (sd and star[d] != 0) or (se and star[e] != 0) or (sf and star[f] != 0):
        return False  # (_shares_certified)
    if quick == 1 and not (sd or se or sf):
        hit = _touching_boxes(V, ws, F, i, j)
        if hit >= 0:
            return hit == 1
    return _pair_shared(V, ws, F, i, j, sd, se, sf)


@_pure
def _apart_in_slab(V, F, lev, lo_, W, s, u, i, j):
    """Whether faces ``i`` and ``j`` of one slab (rows ``s`` and ``u`` of its table ``W``, as
    :func:`_x_sweep` and :func:`_cell_sweep` fill it) are apart by the corner-range rules, with no
    exact test: both have every corner on the slab's two levels, and their ends are apart (which
    no two faces with a common corner are), or apart but at their one common corner."""
    if not (W[s, 15] == 1.0 and W[u, 15] == 1.0 and W[s, 13] == W[u, 13] and W[s, 14] == W[u, 14]):
        return False
    if ((W[s, 5] < W[u, 4] and W[s, 9] < W[u, 8]) or (W[u, 5] < W[s, 4] and W[u, 9] < W[s, 8])
            or (W[s, 7] < W[u, 6] and W[s, 11] < W[u, 10]) or (W[u, 7] < W[s, 6] and W[u, 11] < W[s, 10])):
        return True
    ns = 0
    p = np.int64(-1)
    for c in range(3):
        v = F[i, c]
        if v == F[j, 0] or v == F[j, 1] or v == F[j, 2]:
            ns += 1
            p = v
    return ns == 1 and _apart_but_corner_w(W, s, u, V[p, 0], V[p, 1], lev[p] == lo_[i])


@_pure
def _apart_but_corner_w(W, a, b, px, py, bottom):
    """The rule "apart but at a corner" (see the note above) for the faces of rows ``a`` and ``b`` of :func:`_single_sweep`'s
    ``W`` with their one common corner at ``px, py`` on plane k (``bottom``) or k + 1: the same
    comparisons, on the ranges of the rows (on p's plane the range of a face's corners there
    holds p, and its other corner, where it has one, is the end of the range below p if there is
    one, else the upper end; ``W[., 12]`` is the number of corners on plane k)."""
    oa = 4 if bottom else 8  # p's plane's ranges, then the other plane's
    ob = 8 if bottom else 4
    na = W[a, 12] if bottom else 3.0 - W[a, 12]  # corners on p's plane
    nb = W[b, 12] if bottom else 3.0 - W[b, 12]
    for c in range(2):
        pc = px if c == 0 else py
        i0lo = np.inf
        i0hi = -np.inf
        if na == 2.0:
            o = W[a, oa + 2 * c] if W[a, oa + 2 * c] < pc else W[a, oa + 2 * c + 1]
            i0lo = o
            i0hi = o
        j0lo = np.inf
        j0hi = -np.inf
        if nb == 2.0:
            o = W[b, oa + 2 * c] if W[b, oa + 2 * c] < pc else W[b, oa + 2 * c + 1]
            j0lo = o
            j0hi = o
        i1lo = W[a, ob + 2 * c]
        i1hi = W[a, ob + 2 * c + 1]
        j1lo = W[b, ob + 2 * c]
        j1hi = W[b, ob + 2 * c + 1]
        if i1hi < j1lo and i0hi < pc and pc < j0lo:
            return True
        if j1hi < i1lo and j0hi < pc and pc < i0lo:
            return True
    return False


@_kernel
def _cell_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, cx0, cy0, start, npairs, pi, pj, work, limit, stop,
                l0, l1, cg):
    """:func:`_x_sweep`'s pairs for a slab of many faces (at least :data:`_CELL_SWEEP`): the pairs of
    slab k (its faces ``faces``, levels ``lo_``, ``hi_`` per face), those of
    its faces whose closed xy boxes overlap and that first share this slab (no pair of a lower
    slab), tested as they are found (as in :func:`_slab_step`, so a search that stops at its first
    pair stops there), less the pairs that the rules "ends apart" and "apart but at a corner"
    decide (the note before :func:`_slab_hit`), which it decides on the way instead of listing
    them (most candidates of a two-ring band: on the liver's bands some nine in ten).  Those two
    hold for any two faces with their corners on the same two heights only (the argument is the
    same between any two planes): here the faces of one ``lo_``, ``hi_`` with no corner between
    (a face across a plane with no corner on it, as over a join's few points at a mid-height).

    Candidates come from a grid of about ``len(faces)`` cells over the faces' xy box (a counting
    sort of (face, cell) entries): two faces whose boxes overlap share the cell of the low corner
    of the overlap, and are taken there only, so once; a pair of a lower slab is dropped before its
    box test.  (By the sweep over x alone the liver's whole mesh took 44 M box tests, 16 M of them
    pairs of lower slabs: faces across thin slabs between nearby heights.)  Each
    face's corner ranges on its two planes are computed once, into ``W`` by its place in
    ``faces`` (a row: xy box, the x and y ranges on plane ``lo_``, then on plane ``hi_``, the
    number of corners on plane ``lo_``, then ``lo_``, ``hi_`` and 1 where no corner lies between,
    else 0, then the face's certified group, ``cg``, or -1).  Returns ``(npairs, pi, pj, work)``
    (``work``: pairs of entries met in a cell);
    ``npairs`` is -1 when ``work`` exceeds ``limit``.  ``W``, ``cx0``, ``cy0``, ``start``:
    workspaces of one entry per face (``start`` one more)."""
    n = len(faces)
    if n < 2:
        return npairs, pi, pj, work
    gxl = np.inf
    gxh = -np.inf
    gyl = np.inf
    gyh = -np.inf
    for t in range(n):
        i = faces[t]
        kl = lo_[i]
        kh = hi_[i]
        _box_row(W, t, V, F, lev, i, kl)
        nl = (lev[F[i, 0]] == kl) + (lev[F[i, 1]] == kl) + (lev[F[i, 2]] == kl)
        nh = (lev[F[i, 0]] == kh) + (lev[F[i, 1]] == kh) + (lev[F[i, 2]] == kh)
        W[t, 12] = 1.0 * nl
        W[t, 13] = 1.0 * kl
        W[t, 14] = 1.0 * kh
        W[t, 15] = 1.0 if nl + nh == 3 and kl < kh else 0.0
        W[t, 16] = cg[i] if len(cg) > 0 else -1.0
        gxl = min(gxl, W[t, 0])
        gxh = max(gxh, W[t, 1])
        gyl = min(gyl, W[t, 2])
        gyh = max(gyh, W[t, 3])
    # about n cells, fewer where the faces would take more than four entries each on average
    g = np.int64(1)
    while (g + 1) * (g + 1) <= n:
        g += 1
    gx = g
    gy = g
    while True:
        hx = (gxh - gxl) / gx
        hy = (gyh - gyl) / gy
        if not hx > 0.0:
            hx = 1.0
        if not hy > 0.0:
            hy = 1.0
        nent = np.int64(0)
        for t in range(n):
            x0 = min(np.int64((W[t, 0] - gxl) / hx), gx - 1)
            x1 = min(np.int64((W[t, 1] - gxl) / hx), gx - 1)
            y0 = min(np.int64((W[t, 2] - gyl) / hy), gy - 1)
            y1 = min(np.int64((W[t, 3] - gyl) / hy), gy - 1)
            cx0[t] = x0
            cy0[t] = y0
            nent += (x1 - x0 + 1) * (y1 - y0 + 1)
        if nent <= 4 * n or (gx == 1 and gy == 1):
            break
        gx = max(gx // 2, np.int64(1))
        gy = max(gy // 2, np.int64(1))
    nc = gx * gy
    for q in range(nc + 1):
        start[q] = 0
    for t in range(n):
        x1 = min(np.int64((W[t, 1] - gxl) / hx), gx - 1)
        y1 = min(np.int64((W[t, 3] - gyl) / hy), gy - 1)
        for cy in range(cy0[t], y1 + 1):
            for cx in range(cx0[t], x1 + 1):
                start[cy * gx + cx + 1] += 1
    for q in range(nc):
        start[q + 1] += start[q]
    ent = np.empty(nent, np.int64)
    # (start[q] is the fill pointer of cell q, shifted back below).  A cell lists first the faces
    # that start in this slab, then those from a lower one: two of the latter met in a lower slab
    # (the pair is not this slab's), so the pairs are those of a face of the first kind with any
    # later entry, the same pairs in another order without meeting the others (on the liver's
    # whole mesh 1.07 M slab entries of 417k faces: most slabs between nearby heights)
    for lower in range(2):
        for t in range(n):
            if (W[t, 13] != k) != (lower == 1):
                continue
            x1 = min(np.int64((W[t, 1] - gxl) / hx), gx - 1)
            y1 = min(np.int64((W[t, 3] - gyl) / hy), gy - 1)
            for cy in range(cy0[t], y1 + 1):
                for cx in range(cx0[t], x1 + 1):
                    q = cy * gx + cx
                    ent[start[q]] = t
                    start[q] += 1
    for q in range(nc, 0, -1):
        start[q] = start[q - 1]
    start[0] = 0
    for q in range(nc):
        for r in range(start[q], start[q + 1]):
            s = ent[r]
            if W[s, 13] != k:
                break  # (the faces from a lower slab: every pair of theirs is a lower slab's)
            for v in range(r + 1, start[q + 1]):
                u = ent[v]
                work += 1
                if max(W[s, 13], W[u, 13]) != k:
                    continue  # (a pair of a lower slab)
                if W[u, 0] > W[s, 1] or W[s, 0] > W[u, 1] or W[s, 2] > W[u, 3] or W[u, 2] > W[s, 3]:
                    continue
                if W[s, 16] >= 0.0 and W[s, 16] == W[u, 16]:
                    continue  # (two faces certified in one group: the pair needs nothing)
                if max(cy0[s], cy0[u]) * gx + max(cx0[s], cx0[u]) != q:
                    continue  # (taken in the cell of the low corner of the overlap)
                i = np.int64(faces[s])
                j = np.int64(faces[u])
                if _apart_in_slab(V, F, lev, lo_, W, s, u, i, j):
                    continue
                if i > j:
                    i, j = j, i
                if _star_due(sst):
                    _fill_stars(V, F, star, lev, l0, l1, cg)
                if _slab_hit(V, ws, F, star, np.int64(1), i, j):
                    pi, pj, npairs = _push(pi, pj, npairs, i, j)
                    if npairs == stop:
                        return npairs, pi, pj, work
            if work > limit:
                return np.int64(-1), pi, pj, work
    return npairs, pi, pj, work


@_kernel
def _single_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, order, bk, start, npairs, pi, pj, work, limit, stop,
                  l0, l1, cg):
    """The pairs of slab k as :func:`_slab_step` needs them: by :func:`_cell_sweep` for a slab of at
    least :data:`_CELL_SWEEP` faces, else by :func:`_x_sweep` (the same pairs; arguments and
    result as there)."""
    if len(faces) >= _CELL_SWEEP:
        return _cell_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, order, bk, start, npairs, pi, pj, work,
                           limit, stop, l0, l1, cg)
    return _x_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, order, bk, start, npairs, pi, pj, work, limit, stop,
                    l0, l1, cg)


@njit(cache=True, **_OPTIONS)
def _slab_sweep_pairs(V, ws, F, star, sst, lev, lo_, hi_, faces, k, cells):
    """One slab's pairs by :func:`_cell_sweep` (``cells == 1``) or :func:`_x_sweep` (``0``), whatever
    its size, with fresh workspaces and no budget: ``(pi, pj, work)``, for the tests that compare
    the two."""
    n = max(len(faces), 1)
    W = np.empty((n, 17), np.float64)
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    start = np.empty(n + 1, np.int64)
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    zero = k - k
    limit = zero + 2 ** 62
    cg = np.zeros(0, np.int64)  # (no groups)
    if cells == 1:
        npairs, pi, pj, work = _cell_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, a, b, start, zero, pi, pj,
                                           zero, limit, zero, zero, zero, cg)
    else:
        npairs, pi, pj, work = _x_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, a, b, start, zero, pi, pj, zero,
                                        limit, zero, zero, zero, cg)
    return pi[:npairs], pj[:npairs], work


@njit(cache=True, **_OPTIONS)
def _plane_candidates(xlo, xhi, ylo, yhi, grp, ids, need2, cells, eg):
    """The candidate pairs of the entries ``ids`` by :func:`_cell_pairs` (``cells == 1``) or
    :func:`_x_pairs` (``0``), whatever their number, without a budget: ``(out_i, out_j, work)``,
    for the tests that compare the two (``eg``: the entries' certified groups, or empty)."""
    zero = need2 - need2
    out_i = np.empty(16, np.int64)
    out_j = np.empty(16, np.int64)
    limit = zero + 2 ** 62
    if cells == 1:
        out_i, out_j, n_out, work = _cell_pairs(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, zero, zero, limit, need2)
    else:
        out_i, out_j, n_out, work = _x_pairs(xlo, xhi, ylo, yhi, grp, eg, ids, out_i, out_j, zero, zero, limit, need2)
    return out_i[:n_out], out_j[:n_out], work


@_kernel
def _x_sweep(V, ws, F, star, sst, lev, lo_, hi_, faces, k, W, order, bk, start, npairs, pi, pj, work, limit, stop,
             l0, l1, cg):
    """The pairs of slab k (its faces ``faces``, levels ``lo_``, ``hi_`` per face), its candidates
    as :func:`_sweep` finds them (the same buckets, box tests and work), tested as they are found
    (as in :func:`_slab_step`, so a search that stops at its first pair stops there), less the
    pairs that the rules "ends apart" and "apart but at a corner" decide (the note before
    :func:`_slab_hit`), which it decides on the
    way instead of listing them (most candidates of a two-ring band: on the liver's bands some nine
    in ten).  Those two hold for any two faces with their corners on the same two heights only
    (the argument is the same between any two planes): here the faces of one ``lo_``, ``hi_`` with
    no corner between (a face across a plane with no corner on it, as over a join's few points at
    a mid-height).  Each face's corner ranges on its two planes are computed once, into ``W`` by its
    place in the sweep's order (a row: xy box, the x and y ranges on plane ``lo_``, then on plane
    ``hi_``, the number of corners on plane ``lo_``, then ``lo_``, ``hi_`` and 1 where no corner
    lies between, else 0, then the face's certified group, ``cg``, or -1).  Returns ``(npairs, pi,
    pj, work)``; ``npairs`` is -1 when ``work``
    exceeds ``limit``.  ``W``, ``order``, ``bk``, ``start``: workspaces of one entry per face
    (``start`` one more)."""
    n = len(faces)
    if n < 2:
        return npairs, pi, pj, work
    lo = np.inf
    hi = -np.inf
    for t in range(n):
        i = faces[t]
        for q in range(3):
            x = V[F[i, q], 0]
            lo = min(lo, x)
            hi = max(hi, x)
    nb = n
    h = (hi - lo) / nb
    if not h > 0.0:
        h = 1.0
    for q in range(nb + 1):
        start[q] = 0
    for t in range(n):
        i = faces[t]
        xl = min(V[F[i, 0], 0], min(V[F[i, 1], 0], V[F[i, 2], 0]))
        q = min(np.int64((xl - lo) / h), nb - 1)
        bk[t] = q
        start[q + 1] += 1
    for q in range(nb):
        start[q + 1] += start[q]
    for t in range(n):  # (start[q] is the fill pointer of bucket q, shifted back below)
        s = start[bk[t]]
        order[s] = t
        start[bk[t]] = s + 1
    for q in range(nb, 0, -1):
        start[q] = start[q - 1]
    start[0] = 0
    for s in range(n):
        i = faces[order[s]]
        kl = lo_[i]
        kh = hi_[i]
        _box_row(W, s, V, F, lev, i, kl)
        nl = (lev[F[i, 0]] == kl) + (lev[F[i, 1]] == kl) + (lev[F[i, 2]] == kl)
        nh = (lev[F[i, 0]] == kh) + (lev[F[i, 1]] == kh) + (lev[F[i, 2]] == kh)
        W[s, 12] = 1.0 * nl
        W[s, 13] = 1.0 * kl
        W[s, 14] = 1.0 * kh
        W[s, 15] = 1.0 if nl + nh == 3 and kl < kh else 0.0
        W[s, 16] = cg[i] if len(cg) > 0 else -1.0
    for s in range(n):
        xa = W[s, 1]
        qh = min(np.int64((xa - lo) / h), nb - 1)
        for u in range(s + 1, start[qh + 1]):
            work += 1
            if W[u, 0] > xa or W[s, 0] > W[u, 1] or W[s, 2] > W[u, 3] or W[u, 2] > W[s, 3]:
                continue
            if max(W[s, 13], W[u, 13]) != k or (W[s, 16] >= 0.0 and W[s, 16] == W[u, 16]):
                continue  # (a pair of a lower slab; two faces certified in one group)
            i = np.int64(faces[order[s]])
            j = np.int64(faces[order[u]])
            if _apart_in_slab(V, F, lev, lo_, W, s, u, i, j):
                continue
            if i > j:
                i, j = j, i
            if _star_due(sst):
                _fill_stars(V, F, star, lev, l0, l1, cg)
            if _slab_hit(V, ws, F, star, np.int64(1), i, j):
                pi, pj, npairs = _push(pi, pj, npairs, i, j)
                if npairs == stop:
                    return npairs, pi, pj, work
        if work > limit:
            return np.int64(-1), pi, pj, work
    return npairs, pi, pj, work


@_kernel
def _slab_step(V, ws, F, star, sst, quick, lev, lo, hi, sbox, sgrp, sids, sW, sord, sbk, sstart, faces, k, pemb, scert,
               ci, cj, npairs, pi, pj, work, limit, stop, l0, l1, cg):
    """Slab k of :func:`_slab_pairs`: its pairs, each tested in the lowest slab the two faces
    share; none when the planes on both sides hold embedded planar graphs and the slab's faces
    (all within it) have the certificate of :func:`_slab_embedded` (``scert[k]``, and ``pemb``
    for the planes).  ``npairs`` is -1 when the
    sweep went over ``limit``.  ``sbox`` (the slab's faces' xy boxes, by their place in ``faces``),
    ``sgrp`` (all 2) and ``sids`` (``0, 1, ...``) are workspaces of one entry per face of the
    fullest slab.  ``l0 .. l1``: the levels of the vertices whose stars the range certifies."""
    if len(faces) < 2:
        return ci, cj, npairs, pi, pj, work
    if scert[k] == 1 and pemb[k] == 1 and pemb[k + 1] == 1:
        return ci, cj, npairs, pi, pj, work
    if quick == 1:  # (the candidates that coordinates decide are decided in the sweep)
        npairs, pi, pj, work = _single_sweep(V, ws, F, star, sst, lev, lo, hi, faces, k, sW, sord, sbk, sstart, npairs,
                                             pi, pj, work, limit, stop, l0, l1, cg)
        return ci, cj, npairs, pi, pj, work
    # the sweep over the faces' places in the slab list (the same order, so the same candidates
    # in the same order as over their face numbers), then back to face numbers
    ns = len(faces)
    for t in range(ns):
        i = faces[t]
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        sbox[t, 0] = min(V[a, 0], min(V[b, 0], V[c, 0]))
        sbox[t, 1] = max(V[a, 0], max(V[b, 0], V[c, 0]))
        sbox[t, 2] = min(V[a, 1], min(V[b, 1], V[c, 1]))
        sbox[t, 3] = max(V[a, 1], max(V[b, 1], V[c, 1]))
    ci, cj, n_out, work = _sweep(sbox[:, 0], sbox[:, 1], sbox[:, 2], sbox[:, 3], sgrp, cg[:0], sids[:ns], ci, cj,
                                 np.int64(0), work, limit, np.int64(1))
    if n_out < 0:
        return ci, cj, np.int64(-1), pi, pj, work
    for t in range(n_out):
        i = np.int64(min(faces[ci[t]], faces[cj[t]]))  # (int64: one signature for the tests below)
        j = np.int64(max(faces[ci[t]], faces[cj[t]]))
        if max(lo[i], lo[j]) != k or _same_cells(cg, i, j):
            continue
        if _star_due(sst):
            _fill_stars(V, F, star, lev, l0, l1, cg)
        if _slab_hit(V, ws, F, star, quick, i, j):
            pi, pj, npairs = _push(pi, pj, npairs, i, j)
            if npairs == stop:
                break
    return ci, cj, npairs, pi, pj, work


@_kernel
def _first_plane(lo, hi, nlev, kr0, act):
    """The start of :func:`_slab_pairs`' walk over the planes from ``kr0``: the live faces
    (``lo >= 0``) whose lowest level is above ``kr0``, by that level and then by number
    (``bylo``, level ``k``'s from ``cnt_l[k]`` to ``cnt_l[k + 1]``: the ``new`` of
    :func:`_next_plane`), and plane ``kr0``'s faces (``lo <= kr0 <= hi``) in the order of their
    numbers into ``act``.  Returns ``(bylo, cnt_l, nact)``."""
    m = len(lo)
    cnt_l = np.zeros(nlev + 1, np.int64)
    nact = np.int64(0)
    for i in range(m):
        if lo[i] > kr0:
            cnt_l[lo[i] + 1] += 1
        elif lo[i] >= 0 and kr0 <= hi[i]:
            act[nact] = i
            nact += 1
    for k in range(nlev):
        cnt_l[k + 1] += cnt_l[k]
    bylo = np.empty(cnt_l[nlev], np.int32)
    fl = cnt_l[:nlev].copy()
    for i in range(m):
        if lo[i] > kr0:
            bylo[fl[lo[i]]] = i
            fl[lo[i]] += 1
    return bylo, cnt_l, nact


@njit(cache=True, **_OPTIONS)
def _plane_walk(lo, hi, nlev, kr0, mp):
    """Every plane's faces from plane ``kr0`` on as :func:`_slab_pairs` meets them
    (:func:`_first_plane`, then :func:`_next_plane`), one plane after another, and how many each
    (``mp``: the most on one plane): for the tests that compare them with each plane's faces
    listed face by face."""
    act = np.empty(max(mp, 1), np.int32)
    mrg = np.empty(max(mp, 1), np.int32)
    counts = np.zeros(max(nlev - kr0, 0), np.int64)
    out = np.empty(0, np.int32)
    for rep in range(2):  # (counted, then listed)
        bylo, cnt_l, nact = _first_plane(lo, hi, nlev, kr0, act)
        at = np.int64(0)
        for k in range(kr0, nlev):
            if k > kr0:
                nact = _next_plane(lo, hi, bylo[cnt_l[k]:cnt_l[k + 1]], act, nact, mrg, k)
            counts[k - kr0] = nact
            if rep == 1:
                out[at:at + nact] = act[:nact]
            at += nact
        if rep == 0:
            out = np.empty(at, np.int32)
    return out, counts


@_kernel
def _next_plane(lo, hi, new, act, nact, mrg, k):
    """Plane ``k``'s faces from plane ``k - 1``'s: the faces ``act[:nact]`` (in the order of their
    numbers) that reach plane ``k`` (``hi >= k``), merged with ``new``, the faces whose lowest level
    is ``k`` (in that order too), into ``act``; returns their number.  Every face of plane ``k``
    with a lower level is on plane ``k - 1`` as well (its levels span ``lo .. hi``), so these are
    the faces ``lo <= k <= hi``, in the order of their numbers, as a list of every plane's faces
    filled face by face would hold them.  ``mrg``: a workspace as long as ``act``."""
    n = np.int64(0)
    a = np.int64(0)
    b = np.int64(0)
    nn = len(new)
    while a < nact or b < nn:
        if a < nact and hi[act[a]] < k:
            a += 1
            continue
        if b >= nn or (a < nact and act[a] < new[b]):
            mrg[n] = act[a]
            a += 1
        else:
            mrg[n] = new[b]
            b += 1
        n += 1
    for t in range(n):
        act[t] = mrg[t]
    return n


@njit(cache=True, **_OPTIONS)
def _slab_pairs(V, ws, F, star, sst, quick, lev, nlev, budget, stop, k0, k1, cg):
    """The pairs of :func:`_intersecting_pairs` for a mesh whose vertex heights have level indices
    ``lev`` (``0 .. nlev-1``, in the order of the heights), by slabs and planes (see above).
    Returns ``(pi, pj, ok)``: ``ok == 1`` done; ``0`` the mesh is not sectioned (its faces span
    more than four slabs per face on average); ``-1`` the sweeps did more than ``budget`` box
    tests per face (very long thin faces): then nothing is decided here.  ``stop > 0``: done
    (``ok == 1``) as soon as ``stop`` pairs are found (see :func:`_intersecting_pairs`).

    ``k0 <= k < k1``: only the pairs decided at the planes ``k`` and in the slabs below them
    (``k - 1``, ``k > 0``), and only the faces that reach them are sorted into the slabs and
    planes (:func:`_split_slab_pairs` gives each thread a range; ``0, nlev`` is the whole mesh).
    Every pair is decided at exactly one plane or slab, so the ranges of a partition of
    ``0 .. nlev - 1`` find every pair once; ``ok`` and the work counted against ``budget`` are
    then the range's own (a range may finish where the whole would give up).  The vertices' stars
    are certified where first needed for the range's own vertices (levels ``k0 - 1 .. k1 - 1``,
    :func:`_star_fill_levels`), so ranges on several threads do not each certify the whole mesh's.
    ``cg``: per face its group where certified by :func:`_lattice_cells` (pairs of one group not
    tested), or empty."""
    m = len(F)
    kr0 = max(k0 - 1, 0)  # plane k0 - 1 only for whether it is embedded (slab k0 - 1 needs it)
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    # (no boxes of the whole mesh: each slab's and plane's faces get theirs in a workspace)
    # (levels and face numbers in int32: a mesh of 2^31 faces would not fit in memory here anyway)
    lo = np.full(m, -1, np.int32)  # -1: not live (skipped, as in the grid path)
    hi = np.full(m, -1, np.int32)
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    nslab = max(nlev - 1, 1)
    # (no lists of every plane's and slab's faces, some 10 MiB on the liver's whole mesh: each
    # plane's faces are kept as the planes are met, by _next_plane, from the faces sorted by their
    # lowest level; the counts give the fullest plane and slab for the workspaces)
    dif_s = np.zeros(nslab + 1, np.int64)  # slab memberships, as differences
    dif_p = np.zeros(nlev + 1, np.int64)  # plane memberships, as differences
    total = 0
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        if a == b or b == c or a == c:
            continue
        la = min(lev[a], min(lev[b], lev[c]))
        ha = max(lev[a], max(lev[b], lev[c]))
        if ha < kr0 or la >= k1:
            continue  # reaches no plane or slab of the range
        if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
            continue  # collinear (exactly)
        lo[i] = la
        hi[i] = ha
        total += ha - la
        if total > 4 * m + 1000:
            return pi[:0], pj[:0], np.int64(0)
        if ha > la:
            dif_s[la] += 1
            dif_s[ha] -= 1
        dif_p[la] += 1
        dif_p[ha + 1] -= 1
    limit = budget * m + 1000000
    work = np.int64(0)
    n_out = np.int64(0)
    ci = np.empty(64, np.int64)
    cj = np.empty(64, np.int64)
    npairs = np.int64(0)
    # the workspaces per plane and per slab hold one entry per face of the fullest plane or slab
    # (a face at most once in each), not one per face of the mesh
    mp = np.int64(1)
    run = np.int64(0)
    for k in range(nlev):
        run += dif_p[k]
        mp = max(mp, run)
    ms = np.int64(1)
    run = np.int64(0)
    for k in range(nslab):
        run += dif_s[k]
        ms = max(ms, run)
    # the current plane's faces (act, in the order of their numbers), a merge buffer, and the
    # faces of the slabs below and above it
    act = np.empty(mp, np.int32)
    mrg = np.empty(mp, np.int32)
    sbelow = np.empty(ms, np.int32)
    sabove = np.empty(ms, np.int32)
    bylo, cnt_l, nact = _first_plane(lo, hi, nlev, kr0, act)
    # plane entries (reused per plane).  Their xy boxes are columns of one array, as the slabs'
    # are columns of box, and entries are numbered in int32 as the slabs' faces are: the sweeps
    # get one signature
    pbox = np.empty((mp, 4), np.float64)
    sbox = np.empty((ms, 4), np.float64)  # (a slab's: every pair of its faces is a candidate, group 2)
    sgrp = np.full(ms, 2, np.int8)
    sids = np.arange(ms).astype(np.int32)
    sW = np.empty((ms, 17), np.float64)  # (_single_sweep's)
    sord = np.empty(ms, np.int64)
    sbk = np.empty(ms, np.int64)
    sstart = np.empty(ms + 1, np.int64)
    pxlo = pbox[:, 0]
    pxhi = pbox[:, 1]
    pylo = pbox[:, 2]
    pyhi = pbox[:, 3]
    pgrp = np.zeros(mp, np.int8)
    pface = np.empty(mp, np.int64)
    peg = np.empty(mp if len(cg) > 0 else 0, np.int64)  # (the entries' faces' groups, cg)
    ids = np.arange(mp).astype(np.int32)
    pu = np.empty(mp, np.int64)
    pw = np.empty(mp, np.int64)
    cert = np.empty(mp, np.int32)
    all2 = np.full(mp, 2, np.int8)
    # per vertex: levels, vertex and face numbers in int32
    stamp = np.full(len(V), -1, np.int32)
    d1 = np.empty(len(V), np.int32)
    d2 = np.empty(len(V), np.int32)
    pemb = np.zeros(nlev, np.int64)
    keys = np.empty(2 * ms + 2, np.int64)
    nvh = len(V) if ws[0] == 1.0 else 0  # (_slab_embedded's, on the dyadic grid only)
    head = np.empty(nvh, np.int32)
    hstamp = np.full(nvh, -1, np.int32)
    nxt = np.empty(ms + 1, np.int64)
    # the slabs' certificates first (_slab_embedded: cheap, and on the dyadic grid only): a plane
    # that holds only parts of faces ending there or only of faces starting there has no pairs of
    # its own to decide, and its embedded graph (the costlier check) matters only to a certified
    # slab beside it (the mesher's bands between two rings: most slabs fail the certificate)
    # (each slab's, ``kr0 .. k1 - 2``, is found at the plane below it, before that plane needs it)
    scert = np.zeros(nslab, np.int8)
    nabove = np.int64(0)
    for k in range(kr0, k1):
        if k > kr0:
            nact = _next_plane(lo, hi, bylo[cnt_l[k]:cnt_l[k + 1]], act, nact, mrg, np.int64(k))
        # the slab below (k - 1: the faces of plane k - 1 reaching plane k), then the one above
        nbelow = nabove
        sbelow, sabove = sabove, sbelow
        nabove = np.int64(0)
        for t in range(nact):
            if hi[act[t]] > k:
                sabove[nabove] = act[t]
                nabove += 1
        if ws[0] == 1.0 and k < min(k1 - 1, nslab) and nabove >= 2:
            faces = sabove[:nabove]
            single = True
            for t in range(len(faces)):
                if lo[faces[t]] != k or hi[faces[t]] != k + 1:
                    single = False
                    break
            if single and _slab_embedded(V, F, lev, faces, np.int64(k), keys, head, hstamp, nxt):
                scert[k] = 1
        # plane k: the parts at z_k of the faces ending there (group 0) and starting there (group
        # 1), first; then the flat faces there (group 2) and the faces through it (group 3: they
        # meet the others in a slab, only flat faces here)
        ne = 0
        n0 = 0
        n1 = 0
        for t in range(nact):
            i = act[t]
            if lo[i] == hi[i] or (lo[i] < k and k < hi[i]):
                continue
            e = ne
            u, w, x0, x1, y0, y1 = _level_part(V, F, lev, i, k)
            pu[e] = u
            if u >= 0:
                pw[e] = w
                pxlo[e] = x0
                pxhi[e] = x1
                pylo[e] = y0
                pyhi[e] = y1
            if hi[i] == k:
                pgrp[e] = 0
                n0 += 1
            else:
                pgrp[e] = 1
                n1 += 1
            pface[e] = i
            ne += 1
        ne01 = ne
        nflat = 0
        for t in range(nact):
            i = act[t]
            if lo[i] == hi[i]:
                pgrp[ne] = 2
                nflat += 1
            elif lo[i] < k and k < hi[i]:
                pgrp[ne] = 3
            else:
                continue
            a = F[i, 0]
            b = F[i, 1]
            c = F[i, 2]
            pxlo[ne] = min(V[a, 0], min(V[b, 0], V[c, 0]))
            pxhi[ne] = max(V[a, 0], max(V[b, 0], V[c, 0]))
            pylo[ne] = min(V[a, 1], min(V[b, 1], V[c, 1]))
            pyhi[ne] = max(V[a, 1], max(V[b, 1], V[c, 1]))
            pface[ne] = i
            ne += 1
        # the pairs of a face ending here and a face starting here are all decided at once (none
        # intersects) when their parts form an embedded planar graph (_plane_embedded)
        # (unchecked, True: no parts here, or the parts of one side only and no certified slab beside)
        emb = True
        if n0 + n1 > 0 and ((n0 > 0 and n1 > 0) or (k > 0 and scert[k - 1] == 1) or (k < nslab and scert[k] == 1)):
            if not (ws[0] == 1.0 and _plane_convex_ring(V, ws, pu, pw, np.int64(ne01), np.int64(k), stamp, d1, d2)):
                if len(peg) > 0:
                    for e in range(ne01):
                        peg[e] = cg[pface[e]]
                emb, work, ci, cj = _plane_embedded_g(V, ws, pxlo, pxhi, pylo, pyhi, pu, pw, np.int64(ne01),
                                                      np.int64(k), stamp, d1, d2, cert, all2, peg, ci, cj, work,
                                                      limit)
        pemb[k] = 1 if emb else 0
        if k < k0:
            continue  # (plane k0 - 1: its pairs are another range's)
        if k > 0:
            ci, cj, npairs, pi, pj, work = _slab_step(V, ws, F, star, sst, quick, lev, lo, hi, sbox, sgrp, sids,
                                                      sW, sord, sbk, sstart,
                                                      sbelow[:nbelow], np.int64(k - 1), pemb, scert,
                                                      ci, cj, npairs, pi, pj, work, limit, stop, kr0, k1 - 1, cg)
            if npairs < 0:
                return pi[:0], pj[:0], np.int64(-1)
            if stop > 0 and npairs >= stop:
                return pi[:npairs], pj[:npairs], np.int64(1)
        if nflat == 0 and (n0 == 0 or n1 == 0 or emb):
            continue
        need2 = np.int64(1) if emb else np.int64(0)
        if len(peg) > 0:
            for e in range(ne):
                peg[e] = cg[pface[e]]
        ci, cj, n_out, work = _sweep(pxlo, pxhi, pylo, pyhi, pgrp, peg, ids[:ne], ci, cj, np.int64(0), work, limit,
                                     need2)
        if n_out < 0:
            return pi[:0], pj[:0], np.int64(-1)
        for t in range(n_out):
            a = pface[ci[t]]
            b = pface[cj[t]]
            i = min(a, b)
            j = max(a, b)
            if _same_cells(cg, i, j):
                continue
            if _star_due(sst):
                _fill_stars(V, F, star, lev, kr0, k1 - 1, cg)
            if _shares_certified(F, star, i, j):
                continue
            hit = np.int64(-1)
            if pgrp[ci[t]] < 2 and pgrp[cj[t]] < 2:
                hit = _across_plane(V, ws, F, i, j)
            if hit < 0 and quick == 1:
                hit = _touching_boxes(V, ws, F, i, j)
            if hit < 0:
                hit = 1 if _pair_intersects(V, ws, F, i, j) else 0
            if hit == 1:
                pi, pj, npairs = _push(pi, pj, npairs, i, j)
                if npairs == stop:
                    return pi[:npairs], pj[:npairs], np.int64(1)
    return pi[:npairs], pj[:npairs], np.int64(1)


# ------------------------------------------------------------------------------------------------
# Python API
# ------------------------------------------------------------------------------------------------
@njit(cache=True, **_OPTIONS)
def _sectioned(V, ws, F, lev):
    """1 where :func:`_slab_pairs` over the whole mesh (``k0, k1 = 0, nlev``) gets past its first
    loop, 0 where that loop gives the mesh up as not sectioned (its ``ok == 0``): the same count of
    the slabs its faces span (faces with two equal vertex indices, and exactly collinear ones by
    :func:`_o2`, left out), against the same limit ``4 m + 1000``.  The count only grows, so
    ``_slab_pairs`` stopping at the first prefix over the limit and this count of all faces agree.
    First an upper bound without the collinearity test (every face's span): below the limit the
    mesh is sectioned without an exact predicate.  For the ``auto`` route of :func:`_pairs`: a
    mesh that is not sectioned (the lobster's repaired mesh, 396k faces) goes to the grid without
    loading the slab phase's compiled code (some 10 MiB of a process's first call) for nothing."""
    m = len(F)
    limit = 4 * m + 1000
    total = m - m
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        if a == b or b == c or a == c:
            continue
        total += max(lev[a], max(lev[b], lev[c])) - min(lev[a], min(lev[b], lev[c]))
    if total <= limit:
        return np.int64(1)
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    total = m - m
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        if a == b or b == c or a == c:
            continue
        if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
            continue  # collinear (exactly)
        total += max(lev[a], max(lev[b], lev[c])) - min(lev[a], min(lev[b], lev[c]))
        if total > limit:
            return np.int64(0)
    return np.int64(1)


def _as_mesh_arrays(vertices, faces):
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"vertices must have shape (n, 3); got {V.shape}")
    if F.size == 0:
        return V, F.reshape(0, 3)
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"faces must have shape (m, 3); got {F.shape}")
    if F.min() < 0 or F.max() >= len(V):
        raise ValueError("faces index vertices that do not exist")
    if not np.all(np.isfinite(V)):
        raise ValueError("vertices must be finite (found NaN or infinity)")
    return V, F


@njit(cache=True, **_OPTIONS)
def _levels(z):
    """``np.unique(z, return_inverse=True)`` as ``(inverse, number of levels)``: each height's rank
    among the distinct heights (equal heights, ``-0.0`` and ``0.0`` too, share one).  ``(_, -1)``
    where a height is NaN (the caller then asks np.unique, which counts NaNs as one height)."""
    n = len(z)
    lev = np.empty(n, np.int64)
    ascending = True
    for t in range(n):
        if z[t] != z[t]:
            return lev, np.int64(-1)
        if t > 0 and z[t] < z[t - 1]:
            ascending = False
    if ascending:
        # heights already in order (a mesh of sections whose vertices come slice by slice, as the
        # fast path's without half caps): the ranks in one pass, no sort
        k = np.int64(-1)
        prev = 0.0
        for t in range(n):
            if t == 0 or z[t] != prev:
                k += 1
                prev = z[t]
            lev[t] = k
        return lev, k + 1
    # the heights come in runs (a ring's points share one): the runs' heights sorted, not every
    # vertex's (liver x2's repaired mesh, 0.56 M vertices: 50 ms sorting them all, serial in a
    # two-thread call)
    run = np.empty(n, np.int64)  # each vertex's run
    starts = np.empty(n, np.int64)
    r = np.int64(-1)
    for t in range(n):
        if t == 0 or z[t] != z[t - 1]:
            r += 1
            starts[r] = t
        run[t] = r
    nr = r + 1
    rz = np.empty(nr)
    for i in range(nr):
        rz[i] = z[starts[i]]
    order = np.argsort(rz)
    rank = np.empty(nr, np.int64)
    k = np.int64(-1)
    prev = 0.0
    for t in range(nr):
        v = rz[order[t]]
        if t == 0 or v != prev:
            k += 1
            prev = v
        rank[order[t]] = k
    for t in range(n):
        lev[t] = rank[run[t]]
    return lev, k + 1


@njit(cache=True, **_OPTIONS)
def _dyadic_kernel(V):
    """See :func:`_on_small_dyadic_grid`: 1 or 0."""
    n = len(V)
    if n == 0:
        return np.int64(1)
    kmin = 0
    s = 1.0
    for k3 in range(3):
        for i in range(n):
            x = V[i, k3]
            w = x * s
            while w != math.floor(w):  # the smallest k with every coordinate a multiple of 2^-k
                kmin += 1
                if kmin > 10:
                    return np.int64(0)
                s = 2.0 ** kmin
                w = x * s
    span = 0.0
    for k3 in range(3):
        lo = np.inf
        hi = -np.inf
        for i in range(n):
            lo = min(lo, V[i, k3])
            hi = max(hi, V[i, k3])
        span = max(span, hi - lo)
    return np.int64(1) if span * 2.0 ** kmin < 2.0 ** 16 else np.int64(0)


def _on_small_dyadic_grid(V) -> bool:
    """All coordinates are integer multiples of one power of two ``2^-k`` (``k <= 10``) and span
    less than ``2^16`` such steps per axis: then coordinate differences, the orientation
    determinants and their partial sums are all exact in float64 (below ``2^51`` steps cubed)."""
    V = np.ascontiguousarray(V, dtype=np.float64)
    return bool(_dyadic_kernel(V if V.flags.writeable else V.copy()))


@njit(cache=True, **_OPTIONS)
def _canonical_kernel(B):
    """For rows of bit patterns ``B`` (n, 3) uint64: the lowest index of a row equal to each
    (a hash table with open addressing, filled in index order)."""
    n = len(B)
    cap = 2
    bits = 1
    while cap < 2 * n:
        cap *= 2
        bits += 1
    mask = np.uint64(cap - 1)
    shift = np.uint64(64 - bits)
    table = np.full(cap, -1, np.int64)
    canon = np.empty(n, np.int64)
    m1 = np.uint64(0x9E3779B97F4A7C15)
    m2 = np.uint64(0xC2B2AE3D27D4EB4F)
    m3 = np.uint64(0x165667B19E3779F9)
    for i in range(n):
        h = (B[i, 0] ^ (B[i, 0] >> np.uint64(29))) * m1
        h = ((h >> np.uint64(32)) ^ h ^ B[i, 1]) * m2
        h = ((h >> np.uint64(32)) ^ h ^ B[i, 2]) * m3
        q = h >> shift  # the high bits: they depend on every bit of the three numbers
        while True:
            j = table[q]
            if j < 0:
                table[q] = i
                canon[i] = i
                break
            if B[j, 0] == B[i, 0] and B[j, 1] == B[i, 1] and B[j, 2] == B[i, 2]:
                canon[i] = j
                break
            q = (q + np.uint64(1)) & mask
    return canon


def canonical_vertices(vertices) -> np.ndarray:
    """For every vertex, the lowest index of a vertex with equal coordinates (``-0.0`` equals
    ``0.0``; compared as float64 numbers, so bit-identical up to the sign of zero)."""
    V = np.asarray(vertices, dtype=np.float64)
    n = len(V)
    if n == 0:
        return np.zeros(0, np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"vertices must have shape (n, 3); got {V.shape}")
    if np.isnan(V).any():  # NaN equals nothing, not even itself: sort
        order = np.lexsort((np.arange(n), V[:, 2], V[:, 1], V[:, 0]))
        sv = V[order]
        new = np.ones(n, dtype=bool)
        new[1:] = np.any(sv[1:] != sv[:-1], axis=1)
        first = order[new]
        canon = np.empty(n, dtype=np.int64)
        canon[order] = first[np.cumsum(new) - 1]
        return canon
    W = np.ascontiguousarray(V + 0.0)  # -0.0 + 0.0 == +0.0: one bit pattern per number
    return _canonical_kernel(W.view(np.uint64))


def intersecting_pairs(vertices, faces, *, budget: int = 8, method: str = "auto", groups=None) -> np.ndarray:
    """The pairs of faces that intersect other than along a shared edge or at a shared vertex.

    Returns a ``(k, 2)`` int64 array of face indices ``i < j``, sorted; see the module docstring
    for the exact rule, the predicates and the tolerance.  ``budget`` (the average number of grid
    cells a face may occupy, at least 2) only trades memory for speed; the result does not depend on it.
    ``method``: ``"grid"`` the general broad phase (a 3D grid), ``"slabs"`` the broad phase by
    slabs between consecutive vertex heights (for meshes made from sections; an error for a mesh
    without that structure; where a sweep would test too many boxes, the grid takes over),
    ``"auto"`` slabs where the mesh has that structure, else the grid (and the grid for a mesh
    of fewer than ``_GRID_FACES`` faces off the small dyadic grid, where it is as fast or faster,
    unless its vertices lie on two heights, a band between two rings, or ``groups`` are given).
    The pairs are the same whichever method decides them.
    ``groups`` (optional, an integer per face, -1 for none): the parts the mesh was built from (as
    the volume mesher's joins and caps).  It only saves work: within a group, the faces that are
    halves of the cells of one rectilinear grid are certified not to meet each other and their
    pairs are not tested (see "cells of one rectilinear grid" in the source); the pairs are the same
    with any groups.
    """
    if method not in ("auto", "grid", "slabs"):
        raise ValueError(f"method must be 'auto', 'grid' or 'slabs'; got {method!r}")
    V, F = _as_mesh_arrays(vertices, faces)
    if len(F) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    budget = int(budget)
    if budget < 2:
        # a face whose box crosses a cell boundary occupies two cells or more, so an average of one
        # cell per face is reached only by a single cell holding every face: quadratic time
        raise ValueError(f"budget must be an integer >= 2 (grid cells per face on average; 1 would put "
                         f"every face in one cell); got {budget}")
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (len(F),) or not (groups.dtype.kind in "iu" or groups.dtype == bool):
            raise ValueError(f"groups must be one integer per face ({len(F)}); got an array of shape "
                             f"{groups.shape} and dtype {groups.dtype}")
        # (made int64 where _pairs uses it: a copy of the volume mesher's int32 tags is not held
        # through the broad phase)
    if 3 * len(F) < len(V):  # a few faces of a large mesh: only the vertices they use
        used = np.unique(F)
        V, F = V[used], np.searchsorted(used, F)
    return _pairs(V, F, canonical_vertices(V), budget, method, groups=groups)


#: The exact predicates hold for coordinates whose nonzero magnitudes lie in ``[2^-L, 2^H]``
#: (``L, H = _EXACT_EXP``).  A coordinate difference and its rounding error are multiples of the
#: smaller coordinate's unit in the last place, so where they are not zero they are at least
#: 2^(-L-53); the smallest term of the exact path (the rounding error of a product of three, times
#: a third) is then above 2^-969, where every error-free product is still exact (L <= 252), and the
#: largest product of three differences stays far from overflow (H <= 330).  Tiny coordinates broke
#: this before: a mesh scaled by 2^-1040 had no crossing pairs where exact rationals find dozens
#: (its products underflowed to zero), and one scaled by 2^1000 lost pairs to overflow.
_EXACT_EXP = (240, 320)
_EXACT_LO = 2.0 ** -_EXACT_EXP[0]
_EXACT_HI = 2.0 ** _EXACT_EXP[1]


@njit(cache=True, nogil=True)
def _magnitudes(V):
    """The smallest nonzero and the largest magnitude of ``V``'s entries (inf, 0 where all are 0)."""
    lo = np.inf
    hi = 0.0
    for i in range(V.shape[0]):
        for t in range(V.shape[1]):
            a = abs(V[i, t])
            if a > hi:
                hi = a
            if 0.0 < a < lo:
                lo = a
    return lo, hi


def _exact_range(V):
    """``V`` itself where its coordinates suit the exact predicates (:data:`_EXACT_EXP`), else ``V``
    times a power of two that brings them into that range: an exact scaling, which keeps every
    orientation's sign and so every pair.  A ValueError where no power of two does (the nonzero
    magnitudes span more than about ``2^559``: a vertex at 1e-300 beside one at 1, say)."""
    if len(V) == 0:
        return V
    lo, hi = _magnitudes(V)
    low, high = _EXACT_EXP
    if hi <= _EXACT_HI and lo >= _EXACT_LO:
        return V
    e_lo, e_hi = math.frexp(lo)[1], math.frexp(hi)[1]  # 2^(e_lo - 1) <= lo, hi < 2^e_hi
    # a shift s fits where e_lo - 1 + s >= -low and e_hi + s <= high
    s_min, s_max = 1 - low - e_lo, high - e_hi
    if s_min > s_max:
        raise ValueError(f"the vertex coordinates span too many orders of magnitude for the exact crossing "
                         f"test (smallest nonzero |x| {lo:.3g}, largest {hi:.3g}; at most about a factor "
                         f"2^{low + high - 1}): snap the tiny coordinates to zero or rescale the mesh")
    return np.ldexp(V, (s_min + s_max) // 2)


#: The corners of the last pair of faces that :func:`any_intersecting` found to intersect (and
#: 1.0 at the end once it holds one): tested first on the next call (:func:`_seen_pair`).  Only
#: time depends on it: a pair it names is tested exactly on the call's own arrays.
_PAIR_SEEN = np.zeros(19)


def any_intersecting(vertices, faces) -> bool:
    """``len(intersecting_pairs(vertices, faces)) > 0``, stopping at the first pair found.

    Every pair the search reports is tested exactly, and the broad phases find every pair
    whichever decides them, so the first pair found answers the question as the whole list
    would; a mesh without crossing faces costs the same as :func:`intersecting_pairs`."""
    # (the mesher asks this of thousands of small bands and joins: arrays as the mesher passes them
    # go straight to the compiled call, which checks them itself, some 5 us a call less than the
    # numpy checks; anything it refuses takes the checked path below, with its errors)
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if (V.ndim == 2 and V.shape[1] == 3 and F.ndim == 2 and F.shape[1] == 3 and len(F) >= 2
            and 3 * len(F) >= len(V) and V.flags.writeable and F.flags.writeable):
        got = _any_kernel_seen(V, F, np.int64(_STAR_DELAY), _PAIR_SEEN)
        if got >= 0:
            return bool(got)
    V, F = _as_mesh_arrays(vertices, faces)
    if len(F) < 2:
        return False
    if 3 * len(F) < len(V):
        used = np.unique(F)
        V, F = V[used], np.searchsorted(used, F)
    V = _exact_range(V)
    if not V.flags.writeable:  # one compiled signature: writable C arrays
        V = V.copy()
    if not F.flags.writeable:
        F = F.copy()
    # (the steps of _pairs(..., "auto", stop=1) in one compiled call)
    got = _any_kernel(V, F, np.int64(_STAR_DELAY))
    if got < 0:  # pragma: no cover - checked and brought into range above
        raise RuntimeError("the crossing test refused arrays it had checked")
    return bool(got)


# ------------------------------------------------------------------------------------------------
# the crossing test of a band between two heights
# ------------------------------------------------------------------------------------------------
# Most of the mesher's crossing tests (:func:`any_intersecting`) ask it of a band or a join whose
# vertices lie on two heights, every face reaching from one to the other.  :func:`_slab_pairs` then
# meets one slab and its two planes, and the slab's sweep (:func:`_x_sweep`) is most of the cost:
# each pair of faces whose boxes overlap calls the rules of :func:`_apart_in_slab`, out of line,
# with its rows of corner ranges some 136 bytes apart (liver's 792 such calls of a build: 1.75 M
# such pairs, nine in ten decided by "ends apart").  :func:`_two_level_any` answers the same
# question for such a mesh with the same certificates and exact tests, its sweep over the faces
# sorted by their lowest x, the boxes in columns of their own, "ends apart" inline and the rest
# (a common corner, the exact tests) out of line, stopping at the first pair that intersects.
# Every test is exact, so the order in which the pairs are met does not change the answer.


@_kernel
def _two_level_plane(V, ws, F, lev, faces, k, pbox, pu, pw, stamp, d1, d2, cert, all2, ci, cj, limit):
    """Plane ``k`` (0 or 1) of a two-level mesh as :func:`_slab_pairs` checks it: the parts there
    of ``faces`` (each with corners on both heights), in the order of their numbers, form an
    embedded planar graph (:func:`_plane_convex_ring` on the dyadic grid, else
    :func:`_plane_embedded`).  Returns ``(embedded, ci, cj)``."""
    ne = len(faces)
    for e in range(ne):
        u, w, x0, x1, y0, y1 = _level_part(V, F, lev, faces[e], k)
        pu[e] = u
        if u >= 0:
            pw[e] = w
            pbox[e, 0] = x0
            pbox[e, 1] = x1
            pbox[e, 2] = y0
            pbox[e, 3] = y1
    if ws[0] == 1.0 and _plane_convex_ring(V, ws, pu, pw, np.int64(ne), k, stamp, d1, d2):
        return True, ci, cj
    emb, work, ci, cj = _plane_embedded(V, ws, pbox[:, 0], pbox[:, 1], pbox[:, 2], pbox[:, 3], pu, pw, np.int64(ne),
                                        k, stamp, d1, d2, cert, all2, ci, cj, np.int64(0), limit)
    return emb, ci, cj


@_pure
def _rung_apart(V, F, lev, i, j, k):
    """Faces i and j, with their corners on levels k and one level above only and a common edge
    between the two (a rung, ``p`` below, ``q`` above), meet along the rung only, shown by the signs of
    coordinate differences (exact in floating point); False means "not shown".

    At a height ``t`` of the way up (``0 <= t <= 1``) face i's section is the segment from the
    rung's point ``r = (1 - t) p + t q`` to the point of its third corner's edge there: for a
    corner ``a`` on level 0 that is ``(1 - t) a + t q``, ``r + (1 - t)(a - p)``; for one on level 1
    ``(1 - t) p + t a``, ``r + t (a - q)``.  So both sections run from ``r`` along the xy
    directions ``d_i`` (``a - p`` or ``a - q``) and ``d_j`` (the same with j's corner ``b``), or are
    the point ``r`` alone (at ``t = 0`` or ``1``), and they meet beyond ``r`` only where the two
    directions point the same way.  Two directions that do have equal signs on each axis; where the
    signs of ``d_i`` and ``d_j`` differ on x or on y the faces meet along the rung only."""
    a = np.int64(-1)
    b = np.int64(-1)
    p = np.int64(-1)
    q = np.int64(-1)
    for c in range(3):
        v = F[i, c]
        if v == F[j, 0] or v == F[j, 1] or v == F[j, 2]:
            if lev[v] == k:
                p = v
            else:
                q = v
        else:
            a = v
        w = F[j, c]
        if w != F[i, 0] and w != F[i, 1] and w != F[i, 2]:
            b = w
    if p < 0 or q < 0:
        return False  # (an edge on one level: not a rung)
    ra = p if lev[a] == k else q
    rb = p if lev[b] == k else q
    for c in range(2):
        di = V[a, c] - V[ra, c]
        dj = V[b, c] - V[rb, c]
        if (di > 0.0) != (dj > 0.0) or (di < 0.0) != (dj < 0.0):
            return True
    return False


@_kernel
def _x_order(x0):
    """The indices that sort ``x0`` (finite) ascending, ties in any order: a counting sort into
    ``len(x0)`` buckets of equal width, then insertion sort, which has little to do after it (a
    band's lowest x spread over its range); where it would move entries more than ``8 n`` places
    in all, ``np.argsort``.  (On the liver's bands ``np.argsort`` was some 10 % of the crossing test.)"""
    n = len(x0)
    lo = np.inf
    hi = -np.inf
    for t in range(n):
        lo = min(lo, x0[t])
        hi = max(hi, x0[t])
    h = (hi - lo) / n
    if not h > 0.0:
        h = 1.0
    start = np.zeros(n + 1, np.int64)
    bk = np.empty(n, np.int64)
    for t in range(n):
        q = min(np.int64((x0[t] - lo) / h), n - 1)
        bk[t] = q
        start[q + 1] += 1
    for q in range(n):
        start[q + 1] += start[q]
    order = np.empty(n, np.int64)
    for t in range(n):
        order[start[bk[t]]] = t
        start[bk[t]] += 1
    moves = 0
    for t in range(1, n):
        v = order[t]
        x = x0[v]
        r = t
        while r > 0 and x0[order[r - 1]] > x:
            order[r] = order[r - 1]
            r -= 1
        order[r] = v
        moves += t - r
        if moves > 8 * n:
            return np.argsort(x0)
    return order


@_kernel
def _sweep_order(V, F, faces):
    """The set-up the sweeps of :func:`_two_level_sweep` and :func:`_few_levels_sweep` share:
    ``faces`` in the order of their lowest x (:func:`_x_order`), as ``(fid, cs)``: each row's face
    and its three corners (copied so that the corners of two nearby rows are read from nearby
    places, not from two faces' places in ``F``).  The caller fills its rows in this order."""
    n = len(faces)
    x0 = np.empty(n)
    for t in range(n):
        i = faces[t]
        x0[t] = min(V[F[i, 0], 0], min(V[F[i, 1], 0], V[F[i, 2], 0]))
    order = _x_order(x0)
    fid = np.empty(n, np.int64)
    cs = np.empty((n, 3), np.int64)
    for s in range(n):
        i = np.int64(faces[order[s]])
        fid[s] = i
        cs[s, 0] = F[i, 0]
        cs[s, 1] = F[i, 1]
        cs[s, 2] = F[i, 2]
    return fid, cs


@_kernel
def _sweep_boxes(W):
    """Columns 0-3 of a sweep's rows ``W`` (each face's xy box) as four arrays ``(xs, x1s, y0s,
    y1s)``: the sweep's inner loop reads only these for most pairs, from contiguous memory."""
    n = len(W)
    xs = np.empty(n)
    x1s = np.empty(n)
    y0s = np.empty(n)
    y1s = np.empty(n)
    for s in range(n):
        xs[s] = W[s, 0]
        x1s[s] = W[s, 1]
        y0s[s] = W[s, 2]
        y1s[s] = W[s, 3]
    return xs, x1s, y0s, y1s


@_kernel
def _two_level_sweep(V, ws, F, star, sst, lev, faces, limit, hit):
    """Whether two of ``faces`` (each with its corners on levels 0 and 1 of a two-level mesh)
    intersect (that pair in ``hit``), as :func:`_x_sweep` decides slab 0's pairs: every pair whose closed xy boxes
    overlap, less those the rules "ends apart" and "apart but at a corner" decide (the note before
    :func:`_slab_hit`) and those on one rung that :func:`_rung_apart` decides, tested by
    :func:`_slab_hit`, the stars as :func:`_slab_step` fills them.  1 at the first pair that
    intersects, 0 where none does, -1 where more than ``limit`` pairs of boxes overlapping along x
    were met (then nothing is decided here).

    The faces are swept in the order of their lowest x (:func:`_x_order`, so each face meets only
    the faces that follow it up to the first past its own highest x); a row per face in that order
    holds its xy box (columns 0-3), the x and y ranges of its corners on level 0 (4-7) and on level
    1 (8-11) and the number of its corners on level 0 (12), as the rows of :func:`_x_sweep`, and
    its corners are copied in that order too (the common corners of a pair read from two nearby
    rows, not from two faces' places in ``F``)."""
    n = len(faces)
    fid, cs = _sweep_order(V, F, faces)
    W = np.empty((n, 13))
    zero = np.int64(0)
    for s in range(n):
        i = fid[s]
        _box_row(W, s, V, F, lev, i, zero)
        W[s, 12] = 1.0 * ((lev[F[i, 0]] == 0) + (lev[F[i, 1]] == 0) + (lev[F[i, 2]] == 0))
    xs, x1s, y0s, y1s = _sweep_boxes(W)
    cg = np.zeros(0, np.int64)  # (no groups)
    work = np.int64(0)
    for s in range(n):
        xa = x1s[s]
        ya0 = y0s[s]
        ya1 = y1s[s]
        for u in range(s + 1, n):
            if xs[u] > xa:
                break  # (the faces after u start further along x still)
            work += 1
            if y0s[u] > ya1 or ya0 > y1s[u]:
                continue
            i = fid[s]
            j = fid[u]
            # the one band's rules, written out here (as a helper inlined by numba its array
            # arguments were counted in and out for every pair: the liver's band tests of a build
            # 128 -> 51 ms): "ends apart" (the boxes overlap, so this is the rule's whole content
            # here; without branches, since most pairs are apart by no one rule of the four),
            # "apart but at a corner" for one common corner, _rung_apart for a common rung
            if (((W[s, 5] < W[u, 4]) & (W[s, 9] < W[u, 8])) | ((W[u, 5] < W[s, 4]) & (W[u, 9] < W[s, 8]))
                    | ((W[s, 7] < W[u, 6]) & (W[s, 11] < W[u, 10])) | ((W[u, 7] < W[s, 6]) & (W[u, 11] < W[s, 10]))):
                continue
            a0 = cs[s, 0]
            a1 = cs[s, 1]
            a2 = cs[s, 2]
            b0 = cs[u, 0]
            b1 = cs[u, 1]
            b2 = cs[u, 2]
            s0 = (a0 == b0) | (a0 == b1) | (a0 == b2)
            s1 = (a1 == b0) | (a1 == b1) | (a1 == b2)
            s2 = (a2 == b0) | (a2 == b1) | (a2 == b2)
            ns = np.int64(s0) + np.int64(s1) + np.int64(s2)
            if ns == 1:
                p = a0 if s0 else (a1 if s1 else a2)
                if _apart_but_corner_w(W, s, u, V[p, 0], V[p, 1], lev[p] == 0):
                    continue
            elif ns == 2 and _rung_apart(V, F, lev, i, j, zero):
                continue
            if i > j:
                i, j = j, i
            if _star_due(sst):
                _fill_stars(V, F, star, lev, zero, zero + 1, cg)
            if _slab_hit(V, ws, F, star, np.int64(1), i, j):
                hit[0] = i
                hit[1] = j
                return np.int64(1)
        if work > limit:
            return np.int64(-1)
    return np.int64(0)


@_kernel
def _two_level_any(V, ws, F, star, sst, lev, hit):
    """:func:`_slab_pairs`' answer (a pair found or not) for a mesh whose vertices lie on two
    heights (levels 0 and 1), where it applies: 1 where two faces intersect, 0 where none do, -1
    where the mesh is not such a band (a live face with its three corners on one height) or the
    sweep went over its budget (then the caller takes the general path; the answer is the same).
    The pair found goes in ``hit``.

    The same steps: the live faces (no two equal corners, not exactly collinear), the slab's
    certificate (:func:`_slab_embedded`, on the dyadic grid) with the two planes' embedded graphs,
    which decide every pair at once, else the sweep (:func:`_two_level_sweep`)."""
    m = len(F)
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    faces = np.empty(m, np.int32)
    n = 0
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        if a == b or b == c or a == c:
            continue
        if lev[a] == lev[b] and lev[b] == lev[c]:
            if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
                continue  # collinear (exactly): not live, as in _slab_pairs
            return np.int64(-1)  # a flat face: pairs in a plane too
        # (a face with corners on both heights is never collinear: its two corners on one height
        # are distinct points, and the line through them stays at that height)
        faces[n] = i
        n += 1
    if n < 2:
        return np.int64(0)
    faces = faces[:n]
    if ws[0] == 1.0:
        nv = len(V)
        keys = np.empty(2 * n + 2, np.int64)
        head = np.empty(nv, np.int32)
        hstamp = np.full(nv, -1, np.int32)
        nxt = np.empty(n + 1, np.int64)
        if _slab_embedded(V, F, lev, faces, np.int64(0), keys, head, hstamp, nxt):
            pbox = np.empty((n, 4), np.float64)
            pu = np.empty(n, np.int64)
            pw = np.empty(n, np.int64)
            stamp = np.full(nv, -1, np.int32)
            d1 = np.empty(nv, np.int32)
            d2 = np.empty(nv, np.int32)
            cert = np.empty(n, np.int32)
            all2 = np.full(n, 2, np.int8)
            ci = np.empty(64, np.int64)
            cj = np.empty(64, np.int64)
            limit = np.int64(_SLAB_BUDGET) * m + 1000000
            emb, ci, cj = _two_level_plane(V, ws, F, lev, faces, ax0, pbox, pu, pw, stamp, d1, d2, cert, all2, ci, cj,
                                           limit)
            if emb:
                emb, ci, cj = _two_level_plane(V, ws, F, lev, faces, ax1, pbox, pu, pw, stamp, d1, d2, cert, all2, ci,
                                               cj, limit)
                if emb:
                    return np.int64(0)
    return _two_level_sweep(V, ws, F, star, sst, lev, faces, np.int64(_SLAB_BUDGET) * m + 1000000, hit)


# ------------------------------------------------------------------------------------------------
# the crossing test of a join on a few heights
# ------------------------------------------------------------------------------------------------
# The joins on more than two heights (a bridged join whose band spans two rings with a few faces at
# a mid-height, a sectioned join's bands stacked on three or four rings) and the bands with a few
# flat faces went through the general slab phase (:func:`_slab_pairs`): its planes, its slabs'
# sweeps with the rules out of line, some 2-2.5 times the cost per face of :func:`_two_level_any`'s
# sweep (the liver's 56 joins on more than two heights and 35 bands with flat faces of a build:
# some 26 ms of its 38 ms of crossing tests).  :func:`_few_levels_any` answers them by one sweep
# over all their faces in the manner of :func:`_two_level_sweep`: two faces with their corners on
# the same two heights (a band, as the rules need) by the rules "ends apart", "apart but at a
# corner" and the rung's; any other two by their heights (apart, or meeting in one plane only:
# :func:`_across_plane`) and else the exact test.  Every decision is exact, so the answer is the
# general steps' answer.

#: :func:`_any_steps` takes a mesh on at most this many heights (all its vertices', used or not),
#: of fewer than :data:`_GRID_FACES` faces, to :func:`_few_levels_any` where the general steps would
#: take it to the slab phase (on the small dyadic grid, or on two heights).
_FEW_LEVELS = 16
#: Off the small dyadic grid, a mesh on a few heights of at most this many faces goes to
#: :func:`_few_levels_any` too, where the general steps would take it to the grid of
#: :func:`_intersecting_pairs` (whose set-up is most of the cost of a small mesh): the repair's neck
#: tubes (some 30 faces on 7 heights; the lobster's 546 of a build 11 -> 9 ms).  The sweep's
#: decisions are exact on any coordinates; larger meshes keep the grid, which bounds their work.
_FEW_LEVELS_OFF_GRID = 256


@_kernel
def _few_levels_sweep(V, ws, F, star, sst, lev, nlev, faces, limit, hit):
    """Whether two of ``faces`` (live: no two equal corners, not exactly collinear) intersect (that
    pair in ``hit``): 1 at the first pair that intersects, 0 where none does, -1 where more than
    ``limit`` pairs of boxes overlapping along x were met (then nothing is decided here).

    The faces are swept in the order of their lowest x (:func:`_x_order`) with rows as
    :func:`_two_level_sweep`'s: the xy box (columns 0-3), for a face with its corners on two levels
    only (``lo < hi``) the x and y ranges of its corners on ``lo`` (4-7) and on ``hi`` (8-11), the
    number of its corners on ``lo`` (12) and the band's key ``lo * nlev + hi`` (13); for any other
    face -1 and a key of its own, below -1 (13); then the face's z-range (14, 15).  Each pair whose
    xy boxes overlap: of one band (one key), decided by the rules "ends apart" and "apart but at a
    corner" (the note before :func:`_slab_hit`) and :func:`_rung_apart`, which hold between any two
    heights, else tested by :func:`_slab_hit`; of two bands or with another face, apart where the
    z-ranges are, decided by :func:`_across_plane` where they meet in one plane only (neither face
    flat), else tested by :func:`_slab_hit`."""
    n = len(faces)
    fid, cs = _sweep_order(V, F, faces)
    W = np.empty((n, 16))
    klo = np.empty(n, np.int64)
    for s in range(n):
        i = fid[s]
        a = cs[s, 0]
        b = cs[s, 1]
        c = cs[s, 2]
        la = min(lev[a], min(lev[b], lev[c]))
        ha = max(lev[a], max(lev[b], lev[c]))
        klo[s] = la
        if la < ha and (lev[a] == la or lev[a] == ha) and (lev[b] == la or lev[b] == ha) and (
                lev[c] == la or lev[c] == ha):
            _box_row(W, s, V, F, lev, i, la)
            W[s, 12] = 1.0 * ((lev[a] == la) + (lev[b] == la) + (lev[c] == la))
            W[s, 13] = 1.0 * (la * nlev + ha)
        else:
            W[s, 0] = min(V[a, 0], min(V[b, 0], V[c, 0]))
            W[s, 1] = max(V[a, 0], max(V[b, 0], V[c, 0]))
            W[s, 2] = min(V[a, 1], min(V[b, 1], V[c, 1]))
            W[s, 3] = max(V[a, 1], max(V[b, 1], V[c, 1]))
            W[s, 12] = -1.0
            W[s, 13] = -2.0 - s
        W[s, 14] = min(V[a, 2], min(V[b, 2], V[c, 2]))
        W[s, 15] = max(V[a, 2], max(V[b, 2], V[c, 2]))
    xs, x1s, y0s, y1s = _sweep_boxes(W)
    cg = np.zeros(0, np.int64)  # (no groups)
    zero = np.int64(0)
    top = nlev - 1
    work = np.int64(0)
    for s in range(n):
        xa = x1s[s]
        ya0 = y0s[s]
        ya1 = y1s[s]
        for u in range(s + 1, n):
            if xs[u] > xa:
                break  # (the faces after u start further along x still)
            work += 1
            if y0s[u] > ya1 or ya0 > y1s[u]:
                continue
            i = fid[s]
            j = fid[u]
            if W[s, 13] == W[u, 13]:  # one band: the rules, as in _two_level_sweep
                if (((W[s, 5] < W[u, 4]) & (W[s, 9] < W[u, 8])) | ((W[u, 5] < W[s, 4]) & (W[u, 9] < W[s, 8]))
                        | ((W[s, 7] < W[u, 6]) & (W[s, 11] < W[u, 10]))
                        | ((W[u, 7] < W[s, 6]) & (W[u, 11] < W[s, 10]))):
                    continue
                a0 = cs[s, 0]
                a1 = cs[s, 1]
                a2 = cs[s, 2]
                b0 = cs[u, 0]
                b1 = cs[u, 1]
                b2 = cs[u, 2]
                s0 = (a0 == b0) | (a0 == b1) | (a0 == b2)
                s1 = (a1 == b0) | (a1 == b1) | (a1 == b2)
                s2 = (a2 == b0) | (a2 == b1) | (a2 == b2)
                ns = np.int64(s0) + np.int64(s1) + np.int64(s2)
                lo = klo[s]
                if ns == 1:
                    p = a0 if s0 else (a1 if s1 else a2)
                    if _apart_but_corner_w(W, s, u, V[p, 0], V[p, 1], lev[p] == lo):
                        continue
                elif ns == 2 and _rung_apart(V, F, lev, i, j, lo):
                    continue
            else:
                zs0 = W[s, 14]
                zs1 = W[s, 15]
                zu0 = W[u, 14]
                zu1 = W[u, 15]
                if zs1 < zu0 or zu1 < zs0:
                    continue
                if (zs1 == zu0 or zu1 == zs0) and zs0 < zs1 and zu0 < zu1:
                    got = _across_plane(V, ws, F, i, j)
                    if got == 0:
                        continue
                    if got == 1:
                        hit[0] = min(i, j)
                        hit[1] = max(i, j)
                        return np.int64(1)
            if i > j:
                i, j = j, i
            if _star_due(sst):
                _fill_stars(V, F, star, lev, zero, top, cg)
            if _slab_hit(V, ws, F, star, np.int64(1), i, j):
                hit[0] = i
                hit[1] = j
                return np.int64(1)
        if work > limit:
            return np.int64(-1)
    return np.int64(0)


@_kernel
def _few_levels_any(V, ws, F, star, sst, lev, nlev, hit):
    """:func:`_slab_pairs`' answer (a pair found or not) for a mesh on a few heights, by
    :func:`_few_levels_sweep` over its live faces (as :func:`_slab_pairs` takes them: no two equal
    corners, not exactly collinear; a face with its corners on two heights never is): 1 where two
    faces intersect (the pair in ``hit``), 0 where none do, -1 where the sweep went over its budget
    (then the caller takes the general path; the answer is the same)."""
    m = len(F)
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    faces = np.empty(m, np.int64)
    n = 0
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        if a == b or b == c or a == c:
            continue
        la = min(lev[a], min(lev[b], lev[c]))
        ha = max(lev[a], max(lev[b], lev[c]))
        if la == ha or (lev[a] != la and lev[a] != ha) or (lev[b] != la and lev[b] != ha) or (
                lev[c] != la and lev[c] != ha):
            if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
                continue  # collinear (exactly): not live, as in _slab_pairs
        faces[n] = i
        n += 1
    if n < 2:
        return np.int64(0)
    return _few_levels_sweep(V, ws, F, star, sst, lev, np.int64(nlev), faces[:n], np.int64(_SLAB_BUDGET) * m + 1000000,
                             hit)


@_kernel
def _any_steps(V, F, delay, two, distinct, mem):
    """:func:`_any_kernel`; ``two == 1``: a mesh on two heights by :func:`_two_level_any` where it
    applies, one on a few heights (or on two with flat faces) by :func:`_few_levels_any` where the
    general steps would take the slab phase, ``0``: by the general steps only (the reference the
    tests compare it with).
    ``distinct == 1``: the caller has found no two vertices at one position (as
    :func:`canonical_vertices` compares them, as :func:`contourmesh.bands._pinch_split` does), so
    every vertex is its own canonical vertex and ``F`` is used as it is, without the table and the
    copy (``F`` is only read).  ``mem``: the corners of the last pair found (:func:`_seen_pair`),
    tested first where both faces are here, and set to the pair found here."""
    n = V.shape[0]
    for i in range(F.shape[0]):
        for t in range(3):
            if F[i, t] < 0 or F[i, t] >= n:
                return -1
    lo = np.inf
    hi = 0.0
    for i in range(n):
        for t in range(3):
            a = abs(V[i, t])
            if not a <= 1.7976931348623157e308:  # (NaN or infinite)
                return -1
            hi = max(hi, a)
            if 0.0 < a < lo:
                lo = a
    if not (hi <= _EXACT_HI and lo >= _EXACT_LO):
        return -1
    m = F.shape[0]
    if distinct == 1:
        Fc = F
    else:
        canon = _canonical_kernel((V + 0.0).view(np.uint64))  # (-0.0 + 0.0 == +0.0)
        Fc = np.empty((m, 3), np.int64)
        for i in range(m):
            for t in range(3):
                Fc[i, t] = canon[F[i, t]]
    # (the exact predicates' scratch: each of its entries is written before it is read, so it is
    # not zeroed, some 6 kB a call less to clear)
    ws = np.empty(1 + 3 * _EXP_LEN, dtype=np.float64)
    ws[0] = 1.0 if _dyadic_kernel(V) == 1 else 0.0
    star = np.zeros(len(V), np.int8)
    sst = np.zeros(2, np.int64)
    sst[1] = m // 8 + delay
    # stars only where enough vertices can have one: a vertex's star is certified only where its
    # faces close around it, and a mesh of m faces on nv vertices has m near 2 nv where it is
    # closed, near nv where it is a band between two rings (every vertex on a ring: no star).
    # Where m < 1.25 nv none is certified (the same answer: every pair is then tested).  The
    # mesher's band and join tests have m/nv of 1 to 1.2 (liver 0.226 -> 0.203 CPU-s for its 988
    # calls, lobster 0.100 -> 0.094 for its 2,734; same-process A/B on the calls of one build); the
    # repair's neck tubes have 1.5 and keep their stars (with none, 0.019 -> 0.022 s for 546)
    seen = np.zeros(n, np.int8)
    nv = 0
    for i in range(m):
        for t in range(3):
            v = Fc[i, t]
            if seen[v] == 0:
                seen[v] = 1
                nv += 1
    if 4 * m < 5 * nv:
        sst[0] = -1
    if mem[18] == 1.0 and _seen_pair(V, ws, Fc, mem):
        return 1
    hit = np.full(2, -1, np.int64)
    one = m - m + 1  # (int64 values, not literals: the signatures of the Python calls)
    ok = one - one
    lev, nlev = _levels(V[:, 2].copy())
    if two == 1 and nlev == 2:  # a band between two heights (most of the mesher's calls)
        got = _two_level_any(V, ws, Fc, star, sst, lev, hit)
        if got >= 0:
            if got == 1:
                _remember_pair(V, Fc, hit[0], hit[1], mem)
            return got
    if two == 1 and (ws[0] == 1.0 or nlev == 2 or m <= _FEW_LEVELS_OFF_GRID) and nlev <= _FEW_LEVELS and m < _GRID_FACES:
        # (a join on a few heights, or a band with flat faces: where the general steps take the slab phase;
        # a small mesh off the grid on a few heights, where they take the grid)
        got = _few_levels_any(V, ws, Fc, star, sst, lev, nlev, hit)
        if got >= 0:
            if got == 1:
                _remember_pair(V, Fc, hit[0], hit[1], mem)
            return got
    cg = np.zeros(0, np.int64)  # (no groups)
    if ws[0] == 1.0 or m >= _GRID_FACES or nlev == 2:  # (the route of _pairs)
        pi, pj, ok = _slab_pairs(V, ws, Fc, star, sst, one, lev, nlev, one * _SLAB_BUDGET, one, one - one, nlev, cg)
    if ok != 1:
        pi, pj = _intersecting_pairs(V, ws, Fc, star, sst, one, one * 8, one, one * _GRID_CHUNK, cg)
    if len(pi) > 0:
        _remember_pair(V, Fc, pi[0], pj[0], mem)
        return 1
    return 0


@_kernel
def _remember_pair(V, F, i, j, mem):
    """Keep the corners of faces i and j (a pair that intersects) in ``mem``: face i's three
    points in entries 0-8, face j's in 9-17, and 1.0 in entry 18 (the memory holds a pair)."""
    for t in range(3):
        for c in range(3):
            mem[3 * t + c] = V[F[i, t], c]
            mem[9 + 3 * t + c] = V[F[j, t], c]
    mem[18] = 1.0


@_kernel
def _face_at(V, F, mem, o):
    """The first face of ``F`` whose three corners are the three points ``mem[o:o + 9]`` (in any
    order; equal as numbers), or -1."""
    for i in range(F.shape[0]):
        ok = True
        for t in range(3):
            v = F[i, t]
            x = V[v, 0]
            y = V[v, 1]
            z = V[v, 2]
            found = False
            for q in range(3):
                if x == mem[o + 3 * q] and y == mem[o + 3 * q + 1] and z == mem[o + 3 * q + 2]:
                    found = True
                    break
            if not found:
                ok = False
                break
        if ok:
            return np.int64(i)
    return np.int64(-1)


@_kernel
def _seen_pair(V, ws, F, mem):
    """Whether the pair of faces kept in ``mem`` (:func:`_remember_pair`) is here, both faces live
    (three distinct corners, not exactly collinear), and intersects by the exact test
    (:func:`_pair_intersects`): then the mesh has a pair that intersects, whatever else it holds.
    The mesher asks again of a band or join that differs little from one that crossed (a bridged
    join's first band, then the join; a band and the other rules' bands of the same rings): where
    the faces that crossed are still there, one exact test answers (liver: some 46 of its 138 calls
    that answer "crossing").  False proves nothing (the caller runs the whole test)."""
    i = _face_at(V, F, mem, np.int64(0))
    if i < 0:
        return False
    j = _face_at(V, F, mem, np.int64(9))
    if j < 0 or j == i:
        return False
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    for k in (i, j):
        a = F[k, 0]
        b = F[k, 1]
        c = F[k, 2]
        if a == b or b == c or a == c:
            return False
        if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
            return False
    if i > j:
        i, j = j, i
    return _pair_intersects(V, ws, F, i, j)

@njit(cache=True, **_OPTIONS)
def _any_kernel(V, F, delay):
    """:func:`any_intersecting` on C arrays of shapes (n, 3) and (m, 3): the steps of
    :func:`_pairs` with ``method="auto"``, ``stop=1`` and the shortcuts, one thread, a mesh on two
    heights by :func:`_two_level_any`; 1 where a pair is found, 0 where none, -1 where the arrays
    need :func:`_as_mesh_arrays`' errors or :func:`_exact_range`'s scaling (a face index out of
    range, a coordinate not finite, or magnitudes out of the exact predicates' range): then
    nothing is done."""
    return _any_steps(V, F, delay, np.int64(1), np.int64(0), np.zeros(19))


@njit(cache=True, **_OPTIONS)
def _any_kernel_seen(V, F, delay, mem):
    """:func:`_any_kernel` with the memory of the last pair found (``mem``, 19 float64: see
    :func:`_seen_pair`), which only saves time: the same answers."""
    return _any_steps(V, F, delay, np.int64(1), np.int64(0), mem)


@njit(cache=True, **_OPTIONS)
def _any_kernel_reference(V, F, delay):
    """:func:`_any_kernel` by the general steps only, a mesh on two heights too (for the tests)."""
    return _any_steps(V, F, delay, np.int64(0), np.int64(0), np.zeros(19))


def _pairs(V, F, canon, budget, method, stop=0, quick=True, groups=None):
    """:func:`intersecting_pairs` on checked arrays, ``canon`` from :func:`canonical_vertices`;
    ``stop > 0``: only until that many pairs are found (see :func:`any_intersecting`).
    ``quick=False``: every candidate pair gets the general test, none is decided by a vertex's
    star (:func:`_star_certified`) or in the plane where the boxes touch (:func:`_touching_boxes`):
    the same pairs, for the tests that compare the two.  ``groups`` (an integer per face, -1 none; with
    ``quick`` and no ``stop`` only): the pairs of two faces certified in one group
    (:func:`_lattice_cells`) are not tested, and the slab phase certifies no stars
    (:data:`_SLAB_STARS`); the same pairs."""
    V = _exact_range(V)
    if not V.flags.writeable:  # one compiled signature: writable C arrays
        V = V.copy()
    if F.flags.writeable and F.flags.c_contiguous and bool((canon == np.arange(len(canon))).all()):
        Fc = F  # no two vertices share coordinates (as after the volume mesher's repair): no copy
    else:
        Fc = canon[F]
    # (the caller's canon, handed over as a temporary, goes here: not held through the broad phase)
    del canon
    ws = np.zeros(1 + 3 * _EXP_LEN, dtype=np.float64)
    ws[0] = 1.0 if _on_small_dyadic_grid(V) else 0.0
    # the vertices' stars (filled in the kernels once they test enough pairs)
    star = np.zeros(len(V), np.int8)
    sst = np.array([0 if quick else -1, len(Fc) // 8 + _STAR_DELAY], np.int64)
    qk = np.int64(1 if quick else 0)
    cg = np.zeros(0, np.int64)
    sst_slabs = sst  # (the slab phase's: see _SLAB_STARS)
    if groups is not None and quick and stop == 0:
        sst_slabs = np.array([sst[0] if _SLAB_STARS else -1, sst[1]], np.int64)
        # (int32 groups, as the volume mesher's face tags, as they are: no int64 copy of one per face)
        groups = np.asarray(groups)
        cg = _lattice_cells(V, Fc, np.ascontiguousarray(groups, dtype=np.int32 if groups.dtype == np.int32
                                                         else np.int64))
    ok = 0
    # "auto": the grid for a mesh off the small dyadic grid of fewer than _GRID_FACES faces whose
    # vertices lie on other than two heights (see there) and without groups, else the slab phase
    # (the grid where it gives up)
    on_grid = ws[0] == 0.0 and len(Fc) < _GRID_FACES and len(cg) == 0
    lev = None
    if method == "auto" and on_grid:
        lev, nlev = _levels(np.ascontiguousarray(V[:, 2]))
        on_grid = nlev != 2  # (a band between two rings: slabs all the same, see _GRID_FACES)
    split = stop == 0 and method == "auto" and len(Fc) >= _SPLIT_FACES and _threads() > 1
    sectioned = None  # (_sectioned's answer, once asked)
    if method == "slabs" or (method == "auto" and (not on_grid or split)):
        if lev is None:
            lev, nlev = _levels(np.ascontiguousarray(V[:, 2]))
        if nlev < 0:  # a NaN height: np.unique's levels (NaNs as one)
            levels, lev = np.unique(V[:, 2], return_inverse=True)
            lev, nlev = lev.astype(np.int64).reshape(-1), len(levels)
        if split and nlev > 8:
            # (a mesh that is not sectioned goes to the grid without the split first: its ranges
            # mostly give up after their first loops over every face, the lobster's repaired mesh
            # on two threads some 10 ms of CPU for nothing; where they would all finish, the grid
            # finds the same pairs)
            sectioned = _sectioned(V, ws, Fc, lev) == 1
            if sectioned:
                got = _split_slab_pairs(V, ws, Fc, sst_slabs, qk, lev, nlev, _threads(), cg)
                if got is not None:
                    return got
    if method == "slabs" or (method == "auto" and not on_grid):
        # a box test is cheap next to the grid's cost per face: on the liver's whole mesh a budget
        # of 64 gave up after 1.3 s of sweeping (the grid then took 2.1 s more); 256 finishes in 1.9 s
        # ("auto": a mesh that is not sectioned goes to the grid unasked, see _sectioned)
        if sectioned is None:
            sectioned = method == "slabs" or _sectioned(V, ws, Fc, lev) == 1
        if method == "slabs" or sectioned:
            pi, pj, ok = _slab_pairs(V, ws, Fc, star, sst_slabs, qk, lev, np.int64(nlev),
                                     np.int64(_SLAB_BUDGET), np.int64(stop), np.int64(0), np.int64(nlev), cg)
        if ok == 0 and method == "slabs":
            raise ValueError("method='slabs' needs a mesh made from sections; this one's faces span more "
                             "than four slabs between consecutive vertex heights per face on average")
    if ok != 1:  # not sectioned, or a sweep over its budget: the grid (the same pairs)
        pi, pj = _intersecting_pairs(V, ws, Fc, star, sst, qk, np.int64(budget), np.int64(stop),
                                     np.int64(_GRID_CHUNK), cg)
    out = np.stack([pi, pj], axis=1).astype(np.int64, copy=False)
    if len(out):
        out = out[np.lexsort((out[:, 1], out[:, 0]))]
    return out


#: The vertices' stars are certified (:func:`_star_due`) once this many pairs plus one per eight
#: faces have reached the tests (the 512^3 ball's slab phase decides its pairs without them: its
#: 117k faces take 14 ms, the stars 17 ms more; the lobster's and the liver's meshes need them).
_STAR_DELAY = 100

#: Whether the slab phase of a mesh with face groups (the volume mesher's whole-mesh test) certifies
#: the vertices' stars: it does not.  Its pairs are mostly decided by coordinates in the sweeps
#: (:func:`_single_sweep`) and by the groups (:func:`_lattice_cells`), and the stars (a pass over
#: every vertex's fan) cost more than the pair tests they spare (issue 16's twentieth round, the
#: dumped first builds with their tags, one thread, CPU-s with / without: the liver 0.222 / 0.195,
#: liver x2 0.603 / 0.491, the socket rotated at 256 voxels 0.056 / 0.045, at 512 0.186 / 0.144).
#: The grid keeps them (where the slab phase gives up, and for the lobster's mesh, the 128^3
#: bunny's and Al.100's: with them 0.239, 0.0084, 0.0050 CPU-s, without 0.254, 0.0115, 0.0064).
#: The same pairs either way: a certified star only spares tests whose answer is no.
_SLAB_STARS = False

#: Meshes off the small dyadic grid (:func:`_on_small_dyadic_grid`; as the repaired meshes of real
#: volumes and many of the mesher's bands and joins) of fewer faces than this are tested by the grid
#: (``method="auto"``): the slab phase's certificates that decide whole planes and slabs need the
#: dyadic grid (the 512^3 ball's 117k faces: 15 ms by slabs, 85 ms by the grid), and off it the grid
#: finds the same pairs with less work (the 3,280 any_intersecting calls of a lobster build: 0.22 s
#: vs 0.26 s, the liver's 988 as fast; one thread, whole meshes: liver 0.37 s vs 0.46 s, liver x2
#: 1.00 s vs 1.16 s).  But for a mesh whose vertices lie on two heights (a band between two rings,
#: with or without flat faces): since its slab's pairs that coordinates decide are decided in the
#: sweep (:func:`_single_sweep`), the slabs take it in a half to a third of the grid's time (issue
#: 16's seventh round, the dumped calls off the dyadic grid: the liver's 198 such bands 0.048 s by
#: slabs vs 0.175 s by the grid, the lobster's 792 0.026 s vs 0.057 s).  Larger meshes stay on the slab phase all the same: the grid's tables (some 150 bytes
#: per face) then set the general mesher's peak memory (the liver's +56 MiB, 80 -> 136 MiB).
#: A whole mesh with groups (the volume mesher's whole-mesh test, whose groups certify the pairs of
#: one join's or cap's grid cells, :func:`_lattice_cells`) takes the slab phase at any size where it
#: is sectioned: its sweeps decide by coordinates most of the pairs the grid sends to the stars
#: (issue 16's twenty-seventh round, the first builds' meshes with their tags, one thread, CPU ms
#: by the grid / by slabs: cat10 1.01 / 0.46, the 32^3 bunny 0.64 / 0.36, 64^3 3.03 / 1.60, Al.100
#: 3.60 / 2.75, the 128^3 bunny 7.74 / 5.87).  A process that meshes only small volumes then loads
#: the slab phase's compiled code as well (Al.100 in a fresh process: some +16 MiB at the peak and
#: 0.04-0.07 CPU-s more on the first call; the calls after it some 1 ms faster).
_GRID_FACES = 20_000

#: Meshes of at least this many faces are tested in two ranges of heights on two threads (where
#: ``CONTOURMESH_THREADS`` asks for more than one): below it a thread costs more than it saves.
#: (Until issue 16's second round the split copied each half's faces and found the pairs through
#: the middle level twice: the 512^3 ball's 117k faces took 18 ms on one thread, 23-26 ms split,
#: and the split started at 200,000 faces; the ranges of planes copy nothing.)
_SPLIT_FACES = 20_000


def _threads() -> int:
    """Worker threads asked for (``CONTOURMESH_THREADS``, default 1): a whole number of at least 1;
    anything else is refused (ValueError) rather than read as one thread."""
    import os

    raw = os.environ.get("CONTOURMESH_THREADS")
    if raw is None:
        return 1
    try:
        n = int(raw.strip())
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"CONTOURMESH_THREADS must be a whole number of at least 1 (the worker threads and "
                         f"processes a mesh may use); got {raw!r}")
    return n


def _split_slab_pairs(V, ws, Fc, sst0, qk, lev, nlev, threads, cg):
    """The slab broad phase on ``threads`` threads: :func:`_slab_pairs` over ``2 threads`` ranges of
    planes (with the slabs below them), cut at quantiles of the vertices' levels, taken one after
    another by the calling thread and the workers (:func:`contourmesh._workers.run_all`; the
    kernels release the GIL).  Each pair is decided at one plane or slab, so the lists are
    disjoint and together the pairs of one call, returned sorted the same way.  None where a range
    is not finished there (a sweep over its budget, or faces spanning too many slabs): the caller
    then runs the whole mesh as one call, whose outcome (the slab phase's pairs or the grid's) is
    the same pairs.  Each range certifies the stars of its own vertices only, once its tests reach
    its share of the whole call's threshold (until issue 16's third round every range certified the
    whole mesh's: liver x2's repaired mesh took 1.8 CPU-s on two threads, 1.4 now, 1.3 on one)."""
    from ._workers import run_all

    parts = 2 * threads
    cuts = np.unique(np.partition(lev, [len(lev) * q // parts for q in range(1, parts)])[
        [len(lev) * q // parts for q in range(1, parts)]])
    bounds = [0] + [int(c) for c in cuts if 0 < c < nlev] + [nlev]
    if len(bounds) < 3:
        return None

    # each range holds about a part's share of the faces: its stars are certified once the tests
    # reach that share of the whole mesh's threshold (:func:`_star_due`)
    sst1 = sst0.copy()
    if sst1[0] >= 0:
        sst1[1] = max(sst0[1] - _STAR_DELAY, 0) // parts + _STAR_DELAY

    def part(k0, k1):
        w = ws.copy()  # the exact predicates' workspace is written to
        star = np.zeros(len(V), np.int8)  # (each range's stars: those of its own vertices)
        return _slab_pairs(V, w, Fc, star, sst1.copy(), qk, lev, np.int64(nlev), np.int64(_SLAB_BUDGET),
                           np.int64(0), np.int64(k0), np.int64(k1), cg)

    out = run_all(part, list(zip(bounds[:-1], bounds[1:])), threads)
    if any(ok != 1 for _, _, ok in out):
        return None
    res = np.stack([np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out])],
                   axis=1).astype(np.int64, copy=False)
    if len(res):
        res = res[np.lexsort((res[:, 1], res[:, 0]))]
    return res


def self_intersections(vertices, faces) -> int:
    """The number of face pairs that intersect other than as neighbours (see :func:`intersecting_pairs`)."""
    return int(len(intersecting_pairs(vertices, faces)))


def intersecting_faces(vertices, faces) -> np.ndarray:
    """Sorted indices of the faces that belong to at least one intersecting pair."""
    return np.unique(intersecting_pairs(vertices, faces))
