"""Issue 16 (twelfth round): the vertices' stars (``_star_certified``) walk each fan along its link
cycle in ``_fan_winds_once`` and compute each sign of the cover test once, instead of reading the
faces' rows again and computing a sector's first side both as the previous sector's second side
and on its own.  The certificate must be the same vertex for vertex: the form before is kept here,
compiled, as the reference, and both are compared on random meshes (voxel meshes, nudged off
their planes, folded and flattened spheres, random soups with shared corners) and on the meshes
of the lobster's first build and of a liver label."""

import math

import numpy as np
import pytest
import trimesh
from numba import njit

import contourmesh
from contourmesh import intersect as I
from contourmesh.intersect import _as_mesh_arrays, _dir_sign, _direction, _unit_step, canonical_vertices
from test_intersect_grid_chunks import _first_build
from test_intersect_quick import _nudged, _volume


# ------------------------------------------------------------------------------------------------
# the reference: the stars as they were before issue 16's twelfth round
# ------------------------------------------------------------------------------------------------
@njit(cache=False)
def _fan_winds_once_reference(V, grid, F, inc, s0, s1, p, d0, d1, d2):
    """The faces ``inc[s0:s1]`` around p (one fan, see :func:`_star_certified`), seen along d:
    every one of one strict orientation, and the sectors at p cover the direction of the first
    link vertex r exactly once (half-open: a sector holds its first side, not its second).

    A sector from u to v (its link vertices a, b) of orientation s holds r when r is strictly
    inside (``s det[u, r] > 0``, ``s det[r, v] > 0``) or along u (``det[u, r] = 0`` and
    ``s det[r, v] > 0``: r in the direction of u, not the opposite one)."""
    r = F[inc[s0] // 3, (inc[s0] % 3 + 1) % 3]
    sgn = 0
    for t in range(s0, s1):
        i = inc[t] // 3
        c = inc[t] % 3
        o = _dir_sign(V, grid, p, F[i, (c + 1) % 3], F[i, (c + 2) % 3], d0, d1, d2)
        if o == 0 or o == 2 or (sgn != 0 and o != sgn):
            return False
        sgn = o
    cover = 0
    for t in range(s0, s1):
        i = inc[t] // 3
        c = inc[t] % 3
        a = F[i, (c + 1) % 3]
        b = F[i, (c + 2) % 3]
        if a == r:
            cover += 1
            continue
        if b == r:
            continue
        o2 = _dir_sign(V, grid, p, r, b, d0, d1, d2)
        if o2 == 2:
            return False
        if o2 != sgn:
            continue
        o1 = _dir_sign(V, grid, p, a, r, d0, d1, d2)
        if o1 == 2:
            return False
        if o1 == sgn or o1 == 0:
            cover += 1
    return cover == 1


@njit(cache=False)
def _star_fill_reference(V, F, star, lev, l0, l1):
    """:func:`_star_fill` for the vertices ``p`` with ``l0 <= lev[p] <= l1`` only (the others stay
    0): a range of heights of :func:`_slab_pairs` certifies the stars of its own vertices, not the
    whole mesh's once per range.  A vertex's star is the same whichever others are certified (its
    faces in the order of their numbers)."""
    nv = len(V)
    m = len(F)
    start = np.zeros(nv + 1, np.int64)
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
        most = max(most, start[p + 1] - start[p])
    nrm = np.empty((most, 3), np.float64)  # the fan's face normals (float: to choose directions)
    for p in range(nv):
        s0 = start[p]
        s1 = start[p + 1]
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
            if _fan_winds_once_reference(V, grid, F, inc, s0, s1, p, d0, d1, d2):
                star[p] = 1
                break


def _stars(V, F, lev=None, l0=0, l1=0):
    """(new, reference) certificates of the mesh's vertices (canonical numbers)."""
    Va, Fa = _as_mesh_arrays(V, F)
    Va = np.ascontiguousarray(Va, dtype=np.float64)
    Fc = np.ascontiguousarray(canonical_vertices(Va)[Fa], dtype=np.int64)
    if lev is None:
        lev = np.zeros(len(Va), np.int64)
    new = I._star_certified(Va, Fc, lev, l0, l1)
    ref = np.zeros(len(Va), np.int8)
    _star_fill_reference(Va, Fc, ref, np.ascontiguousarray(lev, dtype=np.int64), np.int64(l0), np.int64(l1))
    return new, ref


def _sphere(rng, sub, noise, flat):
    s = trimesh.creation.icosphere(sub)
    V = s.vertices + rng.normal(0, noise, s.vertices.shape)
    if flat:  # a flattened cap (one plane) and some vertices on the grid of _dir_sign
        V[V[:, 2] > 0.5, 2] = 0.5
        V = np.round(V * 64.0) / 64.0
    return V, s.faces


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_meshes_same_stars(seed):
    rng = np.random.default_rng(seed)
    total = certified = differ = 0
    for t in range(9):
        m = contourmesh.mesh(_volume(rng, t))
        meshes = [(m.vertices, m.faces), (_nudged(rng, m.vertices), m.faces),
                  _sphere(rng, 2, 0.02 * (t % 3), t % 2 == 0), _sphere(rng, 1, 0.3, False)]
        # a soup of random triangles on a few shared corners (fans that fail every way)
        V = rng.integers(0, 4, (12, 3)) * 0.5
        meshes.append((V, rng.integers(0, 12, (40, 3))))
        for V, F in meshes:
            new, ref = _stars(V, F)
            differ += int((new != ref).sum())
            total += len(new)
            certified += int(ref.sum())
        lev = rng.integers(0, 3, len(m.vertices))  # (only the vertices of some levels)
        new, ref = _stars(m.vertices, m.faces, lev, 1, 2)
        differ += int((new != ref).sum())
    assert differ == 0
    assert 0.3 * total < certified < total  # (both outcomes seen)


def test_real_meshes_same_stars(shared_data):
    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    V, F = _first_build(np.transpose(z["volume"], (2, 1, 0)) > 60)
    new, ref = _stars(V, F)
    assert np.array_equal(new, ref)
    assert ref.sum() > 0.9 * len(ref)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == 85)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == 85
    V, F = _first_build(crop, tuple(float(s) for s in z["spacing_xyz"][::-1]))
    new, ref = _stars(V, F)
    assert np.array_equal(new, ref)
