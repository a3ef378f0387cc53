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
by a counting sort; each pair of faces whose boxes overlap is tested once, in the cell at the low
corner of the overlap of their boxes.  Meshes made from sections have most vertices in the
section planes: two faces whose boxes meet only in a plane ``z = c`` (one below, one above) can
meet only there, in the hull of their corners at that height, so such a pair is decided by one
segment test in that plane (the same rules, the same exact ``orient2d``).  Everything runs in one
numba kernel on one core; it is near-linear in the number of faces for meshes whose faces are of
comparable size.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["intersecting_pairs", "self_intersections", "canonical_vertices"]

# Compile-time rules as in contourmesh.fastpath: internal kernels without Python wrappers, one
# entry point cached on disk, int64 arguments only, explicit loops, no exceptions; nothing is
# compiled at import (the entry point compiles at its first call).
_OPTIONS = dict(nogil=True, no_rewrites=True)


def _kernel(fn):
    return njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, **_OPTIONS)(fn)


_EPS = 2.0 ** -53
_O3_BOUND = (7.0 + 56.0 * _EPS) * _EPS  # Shewchuk's o3derrboundA
_O2_BOUND = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk's ccwerrboundA
_EXP = 1  # workspace layout: ws[0] flag, an expansion, its scratch, the terms
_EXP_LEN = 256
_TERMS = 1 + 2 * _EXP_LEN
_EPS53 = 2.0 ** -53
_KEY_BITS = 21  # cell coordinates per axis below 2^21


# ------------------------------------------------------------------------------------------------
# predicates (vertex indices into V; a sign of 0 means zero or not certified)
# ------------------------------------------------------------------------------------------------
# Exact fallback: the determinant as a sum of products of the coordinate differences, each
# difference split exactly into two doubles (two_sum) and each product of three doubles into four
# (two_prod), accumulated without rounding into a nonoverlapping expansion (Shewchuk's
# Grow-Expansion with zero elimination); the sign of its largest component is the exact sign.
@_kernel
def _two_sum(a, b):
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@_kernel
def _split(a):
    c = 134217729.0 * a  # 2^27 + 1
    hi = c - (c - a)
    return hi, a - hi


@_kernel
def _two_prod(a, b):
    x = a * b
    ahi, alo = _split(a)
    bhi, blo = _split(b)
    err = x - ahi * bhi
    err -= alo * bhi
    err -= ahi * blo
    return x, alo * blo - err


@_kernel
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


@_kernel
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


@_kernel
def _exact_sign(V, ws, a, b, c, d, ax, ay, dim):
    """Exact sign of orient3d(a, b, c, d) (``dim == 3``) or of orient2d(a, b, c) on the axes ax,
    ay (``dim == 2``).  One function for both, called from two places, so that the compiler
    keeps it out of line and the float filters stay small.

    The determinant is written exactly as a sum of doubles (the terms); their sum is taken
    first with compensated summation (Ogita-Rump-Oishi Sum2) and its sign accepted when the
    error bound certifies it (the common case: a tiny determinant that is not zero); otherwise
    the terms are summed exactly into a nonoverlapping expansion."""
    one = 1.0
    n = 0
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
    m = 0
    for i in range(n):
        m = _grow_exp(ws, _EXP, m, ws[_TERMS + i], _EXP + _EXP_LEN)
    if m == 0:
        return 0
    if ws[_EXP + m - 1] > 0.0:
        return 1
    return -1


@_kernel
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


@_kernel
def _o2(V, ws, a, b, c, ax, ay):
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


@_kernel
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


@_kernel
def _seg_seg_2d(V, ws, p1, p2, q1, q2, ax, ay):
    """Closed segments p1p2 and q1q2 (in one plane, projected) have a common point."""
    d1 = _o2(V, ws, q1, q2, p1, ax, ay)
    d2 = _o2(V, ws, q1, q2, p2, ax, ay)
    d3 = _o2(V, ws, p1, p2, q1, ax, ay)
    d4 = _o2(V, ws, p1, p2, q2, ax, ay)
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


@_kernel
def _point_in_tri_2d(V, ws, p, a, b, c, ax, ay):
    """Point p lies in the closed triangle a, b, c (in one plane, projected)."""
    s = _o2(V, ws, a, b, c, ax, ay)
    if s == 0:
        return False
    return s * _o2(V, ws, a, b, p, ax, ay) >= 0 and s * _o2(V, ws, b, c, p, ax, ay) >= 0 and s * _o2(V, ws, c, a, p, ax, ay) >= 0


@_kernel
def _seg_tri_2d(V, ws, u, v, a, b, c, ax, ay):
    """Closed segment uv and closed triangle abc, all in one plane."""
    if _point_in_tri_2d(V, ws, u, a, b, c, ax, ay) or _point_in_tri_2d(V, ws, v, a, b, c, ax, ay):
        return True
    return _seg_seg_2d(V, ws, u, v, a, b, ax, ay) or _seg_seg_2d(V, ws, u, v, b, c, ax, ay) or _seg_seg_2d(V, ws, u, v, c, a, ax, ay)


@_kernel
def _outside(V, ws, u, v, t, a, b, c, ax, ay):
    """a, b, c all strictly on the outer side of edge uv of a triangle of orientation t."""
    return t * _o2(V, ws, u, v, a, ax, ay) < 0 and t * _o2(V, ws, u, v, b, ax, ay) < 0 and t * _o2(V, ws, u, v, c, ax, ay) < 0


@_kernel
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


@_kernel
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


@_kernel
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


@_kernel
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


@_kernel
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


@_kernel
def _shared_edge(V, ws, p, q, a, b):
    """Triangles p, q, a and p, q, b (common edge pq) overlap: coplanar, a and b on one side."""
    if _o3(V, ws, p, q, a, b) != 0:
        return False
    k = _drop_axis(V, ws, p, q, a)
    ax = (k + 1) % 3
    ay = (k + 2) % 3
    return _o2(V, ws, p, q, a, ax, ay) * _o2(V, ws, p, q, b, ax, ay) > 0


@_kernel
def _pair_intersects(V, ws, F, i, j):
    """Faces i and j (canonical vertex indices in F) intersect other than as neighbours."""
    a = F[i, 0]
    b = F[i, 1]
    c = F[i, 2]
    d = F[j, 0]
    e = F[j, 1]
    f = F[j, 2]
    # which corners of j are corners of i
    nshared = 0
    sd = d == a or d == b or d == c
    se = e == a or e == b or e == c
    sf = f == a or f == b or f == c
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


@_kernel
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


@_kernel
def _across_plane(V, ws, F, box, i, j):
    """Faces i and j whose boxes meet only in a plane ``z = c``, one face below it and the other
    above it, neither flat: 1 if they intersect (module docstring), 0 if not, -1 if the boxes do
    not meet that way (then the general test decides).

    Every common point lies in the plane, in the hull of each face's corners there (a corner or an
    edge), and so does every common vertex: the test is two segments in the plane.  With no common
    vertex they intersect if the segments meet; with one, ``p``, if both are segments from ``p``
    along one ray; with two (a common edge) they meet along it only, from opposite sides."""
    if box[i, 5] == box[j, 2] and box[i, 2] < box[i, 5] and box[j, 2] < box[j, 5]:
        c = box[i, 5]
    elif box[j, 5] == box[i, 2] and box[j, 2] < box[j, 5] and box[i, 2] < box[i, 5]:
        c = box[j, 5]
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
def _cell(x, lo, h):
    return np.int64(math.floor((x - lo) / h))


@_kernel
def _count_cells(box, live, glo, h):
    total = 0
    for i in range(len(live)):
        if live[i] == 0:
            continue
        n = 1
        for k in range(3):
            n *= _cell(box[i, 3 + k], glo[k], h[k]) - _cell(box[i, k], glo[k], h[k]) + 1
        total += n
    return total


@_kernel
def _visit_cells(box, live, glo, h, mask, ny, nx, start, fill, ent_face, ent_key, store):
    """Every (face, grid cell) entry: counted per hash bucket in ``start`` (``store == 0``) or
    stored at ``fill`` of its bucket (``store == 1``)."""
    for i in range(len(live)):
        if live[i] == 0:
            continue
        x0 = _cell(box[i, 0], glo[0], h[0])
        y0 = _cell(box[i, 1], glo[1], h[1])
        z0 = _cell(box[i, 2], glo[2], h[2])
        x1 = _cell(box[i, 3], glo[0], h[0])
        y1 = _cell(box[i, 4], glo[1], h[1])
        z1 = _cell(box[i, 5], glo[2], h[2])
        for cx in range(x0, x1 + 1):
            for cy in range(y0, y1 + 1):
                for cz in range(z0, z1 + 1):
                    key = (cz * ny + cy) * nx + cx  # z-major: a slab's cells are close in the table
                    q = key & mask
                    if store == 0:
                        start[q] += 1
                    else:
                        r = fill[q]
                        ent_face[r] = i
                        ent_key[r] = key
                        fill[q] = r + 1


@njit(cache=True, **_OPTIONS)
def _intersecting_pairs(V, ws, F, budget):
    """Pairs ``(i, j)``, ``i < j``, of faces that intersect (see the module docstring);
    ``F`` holds canonical vertex indices.  ``budget`` bounds the grid cells per face on average."""
    m = len(F)
    box = np.empty((m, 6), np.float64)
    live = np.empty(m, np.int64)
    glo = np.empty(3, np.float64)
    ghi = np.empty(3, np.float64)
    for k in range(3):
        glo[k] = np.inf
        ghi[k] = -np.inf
    ext = np.empty((m, 3), np.float64)
    nlive = 0
    ax0 = np.int64(0)
    ax1 = np.int64(1)
    ax2 = np.int64(2)
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        c = F[i, 2]
        for k in range(3):
            lo = min(V[a, k], min(V[b, k], V[c, k]))
            hi = max(V[a, k], max(V[b, k], V[c, k]))
            box[i, k] = lo
            box[i, 3 + k] = hi
        live[i] = 0
        if a == b or b == c or a == c:
            continue
        if _o2(V, ws, a, b, c, ax1, ax2) == 0 and _o2(V, ws, a, b, c, ax2, ax0) == 0 and _o2(V, ws, a, b, c, ax0, ax1) == 0:
            continue  # collinear (exactly)
        live[i] = 1
        nlive += 1
        for k in range(3):
            glo[k] = min(glo[k], box[i, k])
            ghi[k] = max(ghi[k], box[i, 3 + k])
            ext[nlive - 1, k] = box[i, 3 + k] - box[i, k]
    pi = np.empty(16, np.int64)
    pj = np.empty(16, np.int64)
    npairs = 0
    if nlive < 2:
        return pi[:0], pj[:0]
    # cell sizes: per axis, the median face extent along it (slices make faces thin across them),
    # no smaller than 1/16 of the largest (a few long faces, such as caps, span many cells)
    h = np.empty(3, np.float64)
    for k in range(3):
        h[k] = np.median(ext[:nlive, k])
    hbig = max(h[0], max(h[1], h[2]))
    for k in range(3):
        hmin = max((ghi[k] - glo[k]) / (2.0 ** _KEY_BITS - 2.0), hbig / 16.0)
        if not h[k] > hmin:
            h[k] = hmin
        if not h[k] > 0.0:
            h[k] = 1.0
    limit = budget * nlive
    total = _count_cells(box, live, glo, h)
    while total > limit:
        for k in range(3):
            h[k] *= 1.5
        total = _count_cells(box, live, glo, h)
    # hash table of cells: counting sort of (face, cell) entries by bucket
    nb = 1
    while nb < 2 * total:
        nb *= 2
    mask = nb - 1
    start = np.empty(nb + 1, np.int64)
    for q in range(nb + 1):
        start[q] = 0
    ny = _cell(ghi[1], glo[1], h[1]) + 1
    nx = _cell(ghi[0], glo[0], h[0]) + 1
    dummy = np.empty(0, np.int64)
    _visit_cells(box, live, glo, h, mask, ny, nx, start, dummy, dummy, dummy, np.int64(0))
    acc = 0
    for q in range(nb):
        cnt = start[q]
        start[q] = acc
        acc += cnt
    start[nb] = acc
    ent_face = np.empty(acc, np.int64)
    ent_key = np.empty(acc, np.int64)
    fill = np.empty(nb, np.int64)
    for q in range(nb):
        fill[q] = start[q]
    _visit_cells(box, live, glo, h, mask, ny, nx, start, fill, ent_face, ent_key, np.int64(1))
    for q in range(nb):
        s0 = start[q]
        s1 = start[q + 1]
        for r in range(s0, s1):
            i0 = ent_face[r]
            key = ent_key[r]
            for t in range(r + 1, s1):
                if ent_key[t] != key:
                    continue
                j0 = ent_face[t]
                i = min(i0, j0)
                j = max(i0, j0)
                if (box[i, 0] > box[j, 3] or box[j, 0] > box[i, 3] or box[i, 1] > box[j, 4]
                        or box[j, 1] > box[i, 4] or box[i, 2] > box[j, 5] or box[j, 2] > box[i, 5]):
                    continue
                # test the pair only in the cell of the low corner of the boxes' overlap
                cx = _cell(max(box[i, 0], box[j, 0]), glo[0], h[0])
                cy = _cell(max(box[i, 1], box[j, 1]), glo[1], h[1])
                cz = _cell(max(box[i, 2], box[j, 2]), glo[2], h[2])
                if (cz * ny + cy) * nx + cx != key:
                    continue
                hit = _across_plane(V, ws, F, box, i, j)
                if hit < 0:
                    hit = 1 if _pair_intersects(V, ws, F, i, j) else 0
                if hit == 1:
                    if npairs == len(pi):
                        pi = _grow(pi, 2 * npairs)
                        pj = _grow(pj, 2 * npairs)
                    pi[npairs] = i
                    pj[npairs] = j
                    npairs += 1
    return pi[:npairs], pj[:npairs]


# ------------------------------------------------------------------------------------------------
# Python API
# ------------------------------------------------------------------------------------------------
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


def _on_small_dyadic_grid(V) -> bool:
    """All coordinates are integer multiples of one power of two ``2^-k`` (``k <= 10``) and span
    less than ``2^16`` such steps per axis: then coordinate differences, the orientation
    determinants and their partial sums are all exact in float64 (below ``2^51`` steps cubed)."""
    if len(V) == 0:
        return True
    lo = V.min(axis=0)
    span = V.max(axis=0) - lo
    for k in range(11):
        s = 2.0 ** k
        if float(span.max()) * s >= 2.0 ** 16:
            return False
        W = V * s
        if np.array_equal(W, np.floor(W)):
            return True
    return False


def canonical_vertices(vertices) -> np.ndarray:
    """For every vertex, the lowest index of a vertex with bit-identical coordinates."""
    V = np.asarray(vertices, dtype=np.float64)
    n = len(V)
    if n == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((np.arange(n), V[:, 2], V[:, 1], V[:, 0]))
    sv = V[order]
    new = np.ones(n, dtype=bool)
    new[1:] = np.any(sv[1:] != sv[:-1], axis=1)
    first = order[new]
    canon = np.empty(n, dtype=np.int64)
    canon[order] = first[np.cumsum(new) - 1]
    return canon


def intersecting_pairs(vertices, faces, *, budget: int = 8) -> np.ndarray:
    """The pairs of faces that intersect other than along a shared edge or at a shared vertex.

    Returns a ``(k, 2)`` int64 array of face indices ``i < j``, sorted; see the module docstring
    for the exact rule, the predicates and the tolerance.  ``budget`` (the average number of grid
    cells a face may occupy) only trades memory for speed; the result does not depend on it.
    """
    V, F = _as_mesh_arrays(vertices, faces)
    if len(F) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    budget = int(budget)
    if budget < 1:
        raise ValueError(f"budget must be a positive integer; got {budget}")
    if 3 * len(F) < len(V):  # a few faces of a large mesh: only the vertices they use
        used = np.unique(F)
        V, F = V[used], np.searchsorted(used, F)
    Fc = canonical_vertices(V)[F]
    ws = np.zeros(1 + 3 * _EXP_LEN, dtype=np.float64)
    ws[0] = 1.0 if _on_small_dyadic_grid(V) else 0.0
    pi, pj = _intersecting_pairs(V, ws, Fc, np.int64(budget))
    out = np.stack([pi, pj], axis=1).astype(np.int64, copy=False)
    if len(out):
        out = out[np.lexsort((out[:, 1], out[:, 0]))]
    return out


def self_intersections(vertices, faces) -> int:
    """The number of face pairs that intersect other than as neighbours (see :func:`intersecting_pairs`)."""
    return int(len(intersecting_pairs(vertices, faces)))


def intersecting_faces(vertices, faces) -> np.ndarray:
    """Sorted indices of the faces that belong to at least one intersecting pair."""
    return np.unique(intersecting_pairs(vertices, faces))
