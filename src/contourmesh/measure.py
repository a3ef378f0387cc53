"""Measures on meshes: area, volume, the paper's error and trade-off, and mesh checks.

All functions are pure and take ``vertices (n, 3)`` and ``faces (m, 3)`` arrays.
"""

from __future__ import annotations

import math

import numpy as np

from ._kernels import njit
from .intersect import _as_mesh_arrays, _pairs, canonical_vertices, self_intersections

__all__ = [
    "triangle_areas",
    "mesh_area",
    "mesh_volume",
    "relative_error",
    "tradeoff",
    "mesh_checks",
    "euler_genus",
    "exact_parts",
    "exact_area_volume",
]


@njit(cache=True, nogil=True)
def _face_cross(v, f):
    """``np.cross(b - a, c - a)`` of every face ``(a, b, c)`` without gathering the corners first
    (the same products and differences, so the same values); ``ok`` is False when a face indexes
    outside ``v`` (the caller then takes numpy's route and its error)."""
    m = f.shape[0]
    n = v.shape[0]
    out = np.empty((m, 3), np.float64)
    for t in range(m):
        a, b, c = f[t, 0], f[t, 1], f[t, 2]
        if a < 0 or a >= n or b < 0 or b >= n or c < 0 or c >= n:
            return out, False
        ax, ay, az = v[a, 0], v[a, 1], v[a, 2]
        ux, uy, uz = v[b, 0] - ax, v[b, 1] - ay, v[b, 2] - az
        wx, wy, wz = v[c, 0] - ax, v[c, 1] - ay, v[c, 2] - az
        out[t, 0] = uy * wz - uz * wy
        out[t, 1] = uz * wx - ux * wz
        out[t, 2] = ux * wy - uy * wx
    return out, True


#: From this many faces on, :func:`triangle_areas` takes the cross products from a compiled loop: every
#: non-empty face array (2048 until 2026-12-04; the volume mesher's joins measure thousands of small
#: bands, where the gather and ``np.cross`` cost 50-100 us a call against 7-25 us compiled).
_COMPILED_AREAS_FROM = 1


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of every triangle, ``|(b - a) x (c - a)| / 2``."""
    if len(faces) == 0:
        return np.zeros(0)
    cross = None
    if (len(faces) >= _COMPILED_AREAS_FROM and isinstance(vertices, np.ndarray) and vertices.dtype == np.float64
            and vertices.ndim == 2 and vertices.shape[1] == 3 and isinstance(faces, np.ndarray)
            and faces.dtype == np.int64 and faces.ndim == 2 and faces.shape[1] == 3):
        # (the (m, 3, 3) gather and numpy's cross skipped; the same values)
        cross, ok = _face_cross(vertices, faces)
        if not ok:
            cross = None
    if cross is None:
        tri = vertices[faces]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return 0.5 * np.sqrt(np.einsum("ij,ij->i", cross, cross))


def mesh_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Surface area: the sum of the triangle areas (compensated summation)."""
    return math.fsum(triangle_areas(vertices, faces))


def mesh_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed enclosed volume by the divergence theorem (positive when oriented outward).

    The same number however the vertices and faces are ordered and wherever each face starts
    (:func:`face_terms`): a mesh made in slabs on worker processes, which comes back in canonical
    order, has the volume of the one-process mesh to the bit."""
    if len(faces) == 0:
        return 0.0
    return math.fsum(face_terms(vertices, faces)[2]) / 6.0


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Surface area: the correctly rounded sum of the triangle areas, each computed from the face
    started at its lexicographically smallest corner, so the same number however the vertices
    and faces are ordered (:func:`face_terms`)."""
    if len(faces) == 0:
        return 0.0
    sums = _size_totals(vertices, faces)
    if sums is not None:
        return 0.5 * sums[0]
    return 0.5 * math.fsum(face_terms(vertices, faces)[0])


def face_terms(vertices, faces):
    """Per face, started at its lexicographically smallest corner (orientation kept):
    ``(|(b - a) x (c - a)|, wall, (a - o) . ((b - o) x (c - o)))``, twice its area, whether its normal
    lies along +-x or +-y (relative tolerance 1e-12, :func:`axis_wall_fraction`) and six times its
    signed volume term about ``o``, the centre of the vertices' bounding box (translated there
    first, the sum is better conditioned).  Each value depends on the face's corners alone, and
    ``o`` on the set of vertices, so sums of them taken with :func:`math.fsum` do not depend on the
    order of vertices or faces."""
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        return np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0)
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"faces refer to vertices outside 0 .. {len(v) - 1}")
    return _face_terms(v, f, _corner_box_centre(v, f))


@njit(cache=True, nogil=True)
def _corner_box_centre(v, f):
    """The centre of the bounding box of the faces' corners (unused vertices left out)."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(f.shape[0]):
        for t in range(3):
            for d in range(3):
                x = v[f[i, t], d]
                if x < lo[d]:
                    lo[d] = x
                if x > hi[d]:
                    hi[d] = x
    return 0.5 * (lo + hi)


@njit(cache=True, nogil=True)
def _lex_less(v, i, j):
    """Vertex ``i`` before vertex ``j`` in the lexicographic order of their coordinates: the first
    coordinate that differs decides.  Written without branches (bitwise on the comparisons: the
    order of a face's corners is as good as random, and branches on it were mispredicted); the
    same answer for every input, NaNs included (a NaN compares neither less nor equal, and ends
    the comparison as a differing coordinate would, with False)."""
    a0 = v[i, 0]
    b0 = v[j, 0]
    a1 = v[i, 1]
    b1 = v[j, 1]
    return (a0 < b0) | ((a0 == b0) & ((a1 < b1) | ((a1 == b1) & (v[i, 2] < v[j, 2]))))


@njit(cache=True, nogil=True)
def _lex_first(v, p, q, r):
    """The face ``(p, q, r)`` rotated (orientation kept) to start at its lexicographically smallest
    corner: ``(q, r, p)`` when q is before p and r is not before q, else ``(r, p, q)`` when r is
    before both, else unchanged (the three comparisons made first, the rotation selected)."""
    qp = _lex_less(v, q, p)
    rq = _lex_less(v, r, q)
    rp = _lex_less(v, r, p)
    c1 = qp & (not rq)
    c2 = rp & rq
    a = q if c1 else (r if c2 else p)
    b = r if c1 else (p if c2 else q)
    c = p if c1 else (q if c2 else r)
    return a, b, c


@njit(cache=True, nogil=True)
def _size_wall(v, p, q, r):
    """``(|(q - p) x (r - p)|, wall)`` of a face already started at its smallest corner (see
    :func:`face_terms`)."""
    ux, uy, uz = v[q, 0] - v[p, 0], v[q, 1] - v[p, 1], v[q, 2] - v[p, 2]
    wx, wy, wz = v[r, 0] - v[p, 0], v[r, 1] - v[p, 1], v[r, 2] - v[p, 2]
    nx = uy * wz - uz * wy
    ny = uz * wx - ux * wz
    nz = ux * wy - uy * wx
    s = math.sqrt(nx * nx + ny * ny + nz * nz)
    tol = 1e-12 * s
    return s, s > 0 and abs(nz) <= tol and (abs(nx) <= tol or abs(ny) <= tol)


@njit(cache=True, nogil=True)
def _face_terms(v, f, o):
    m = f.shape[0]
    size = np.empty(m)
    wall = np.zeros(m, np.bool_)
    six = np.empty(m)
    for i in range(m):
        p, q, r = _lex_first(v, f[i, 0], f[i, 1], f[i, 2])
        size[i], wall[i] = _size_wall(v, p, q, r)
        ax, ay, az = v[p, 0] - o[0], v[p, 1] - o[1], v[p, 2] - o[2]
        bx, by, bz = v[q, 0] - o[0], v[q, 1] - o[1], v[q, 2] - o[2]
        cx, cy, cz = v[r, 0] - o[0], v[r, 1] - o[1], v[r, 2] - o[2]
        six[i] = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    return size, wall, six


#: Room for one partial sum's expansion (:func:`_add_exact`): non-overlapping float64 components
#: number at most about 40 (the exponent range over the 53-bit significand).
_PARTS = 64


@njit(cache=True, nogil=True)
def _add_exact(parts, n, x):
    """Add ``x`` to the non-overlapping expansion ``parts[:n]`` (exactly, as :func:`math.fsum`
    accumulates its partials); returns the new length.  An overflow shows as a non-finite part."""
    i = 0
    for j in range(n):
        y = parts[j]
        if abs(x) < abs(y):
            x, y = y, x
        hi = x + y
        lo = y - (hi - x)
        if lo != 0.0:
            parts[i] = lo
            i += 1
        x = hi
    parts[i] = x
    return i + 1


#: The biased exponents (of a float64's bits) of the sizes that :func:`_size_sums` adds into integer
#: bins, one per exponent: normal numbers far from both ends of the range (the bins' floats made at
#: the end are then exact and finite); other sizes (tiny, huge, infinite or NaN) go to the
#: expansion as before.
_BIN_LO, _BIN_HI = 64, 1984


@njit(cache=True, nogil=True, inline="always")
def _bin_add(bins, ex, mant):
    """Add ``mant * 2^(ex - 1075)`` to the bins (bin ``e`` counts units of ``2^(e - 1075)``): in bin
    ``ex``, its excess over 2^62 carried up (half of it to the next bin, whose unit is twice as large),
    so that no bin overflows."""
    bins[ex] += mant
    while bins[ex] >= np.int64(1) << np.int64(62):
        carry = bins[ex] >> np.int64(1)
        bins[ex] &= np.int64(1)
        ex += 1
        bins[ex] += carry


@njit(cache=True, nogil=True)
def _fold_bins(bins, parts, n):
    """Each bin of :func:`_bin_add` added to the expansion ``parts[:n]`` (as two floats of its high and
    low 32 bits, each exact); returns the new length, or -1 where the expansion would not fit."""
    for e in range(bins.shape[0]):
        x = bins[e]
        if x == 0:
            continue
        lo = x & np.int64(0xFFFFFFFF)
        hi = x >> np.int64(32)
        for y, at in ((lo, e - 1075), (hi, e - 1043)):
            if y != 0:
                if n >= _PARTS - 1:
                    return np.int64(-1)
                n = _add_exact(parts, n, math.ldexp(float(y), at))
    return n


@njit(cache=True, nogil=True)
def _size_sums(v, f, i0, i1):
    """The faces ``i0 .. i1 - 1``'s sizes (twice their areas, :func:`face_terms`) summed exactly:
    ``(ok, parts, n, wall_parts, n_wall)``, two expansions whose exact sums are the sum of all the
    sizes and of the walls' sizes.  ``ok`` is False where a face indexes outside ``v`` or a part is
    not finite (NaN or infinite vertices, an overflow): the caller then takes :func:`face_terms`.

    A size of a normal exponent (:data:`_BIN_LO` .. :data:`_BIN_HI`, all but the extremes) is added
    as an integer, its significand, to a bin for its exponent (:func:`_bin_add`), a few operations
    where adding it to the expansion (:func:`_add_exact`, the form before:
    :func:`_size_sums_expansion`) walks all the expansion's parts; the bins are added to the
    expansion at the end (:func:`_fold_bins`).  Both are exact, so the parts sum to the same number
    and ``fsum`` of them gives the same float (the lobster's mesh: 9.3 -> 6.9 ms per call)."""
    parts = np.zeros(_PARTS)
    wparts = np.zeros(_PARTS)
    n = np.int64(0)  # (literal zeros would compile _add_exact a second time, for Literal[int](0))
    nw = np.int64(0)
    bins = np.zeros(2048 + 64, np.int64)  # (room for the carries above the highest binned exponent)
    wbins = np.zeros(2048 + 64, np.int64)
    buf = np.empty(1)
    bits = buf.view(np.int64)
    nv = v.shape[0]
    for i in range(i0, i1):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        if a < 0 or a >= nv or b < 0 or b >= nv or c < 0 or c >= nv:
            return False, parts, n, wparts, nw
        p, q, r = _lex_first(v, a, b, c)
        s, w = _size_wall(v, p, q, r)
        if s != 0.0:  # (fsum's partials skip zeros too; a NaN is caught below)
            buf[0] = s
            ex = (bits[0] >> np.int64(52)) & np.int64(0x7FF)
            if _BIN_LO <= ex <= _BIN_HI:  # (s > 0: the sign bit is clear)
                mant = (bits[0] & np.int64(0xFFFFFFFFFFFFF)) | (np.int64(1) << np.int64(52))
                _bin_add(bins, ex, mant)
                if w:
                    _bin_add(wbins, ex, mant)
            else:
                n = _add_exact(parts, n, s)
                if w:
                    nw = _add_exact(wparts, nw, s)
        if n >= _PARTS - 1 or nw >= _PARTS - 1:
            return False, parts, n, wparts, nw
    n = _fold_bins(bins, parts, n)
    nw = _fold_bins(wbins, wparts, nw)
    if n < 0 or nw < 0:
        return False, parts, np.int64(0), wparts, np.int64(0)
    return _finite_parts(parts, n, wparts, nw), parts, n, wparts, nw


@njit(cache=True, nogil=True)
def _finite_parts(parts, n, wparts, nw):
    """Whether the first ``n`` parts of ``parts`` and ``nw`` of ``wparts`` are all finite (the size
    sums' last check: a NaN or infinite vertex, or an overflow, shows there)."""
    for j in range(n):
        if not math.isfinite(parts[j]):
            return False
    for j in range(nw):
        if not math.isfinite(wparts[j]):
            return False
    return True


@njit(cache=True, nogil=True)
def _size_sums_expansion(v, f, i0, i1):
    """:func:`_size_sums` with every size added to the expansions (the form before; kept for the
    tests).  The faces ``i0 .. i1 - 1``'s sizes (twice their areas, :func:`face_terms`) summed exactly:
    ``(ok, parts, n, wall_parts, n_wall)``, two expansions whose exact sums are the sum of all the
    sizes and of the walls' sizes.  ``ok`` is False where a face indexes outside ``v`` or a part is
    not finite (NaN or infinite vertices, an overflow): the caller then takes :func:`face_terms`."""
    parts = np.zeros(_PARTS)
    wparts = np.zeros(_PARTS)
    n = np.int64(0)  # (literal zeros would compile _add_exact a second time, for Literal[int](0))
    nw = np.int64(0)
    nv = v.shape[0]
    for i in range(i0, i1):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        if a < 0 or a >= nv or b < 0 or b >= nv or c < 0 or c >= nv:
            return False, parts, n, wparts, nw
        p, q, r = _lex_first(v, a, b, c)
        s, w = _size_wall(v, p, q, r)
        if s != 0.0:  # (fsum's partials skip zeros too; a NaN is caught below)
            n = _add_exact(parts, n, s)
            if w:
                nw = _add_exact(wparts, nw, s)
        if n >= _PARTS - 1 or nw >= _PARTS - 1:
            return False, parts, n, wparts, nw
    return _finite_parts(parts, n, wparts, nw), parts, n, wparts, nw



#: From this many faces on, :func:`_size_totals` sums the faces' sizes in ranges on
#: ``CONTOURMESH_THREADS`` threads (the kernel releases the GIL): below it a thread costs more.
_SPLIT_SIZES = 20_000


def _size_totals(vertices, faces):
    """``(sum of the sizes, sum of the walls' sizes)`` of :func:`face_terms`, each the correctly
    rounded sum :func:`math.fsum` gives of them (the same floats), or None where the compiled sums
    decline (see :func:`_size_sums`).  Each range of faces (one per thread and a few more, where
    ``CONTOURMESH_THREADS`` asks for threads) sums its sizes exactly as an expansion; ``fsum`` of
    all the ranges' expansions is then the correctly rounded exact sum of every size, which is
    what ``fsum`` of the sizes themselves is."""
    from .intersect import _threads

    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    m = len(f)
    threads = _threads() if m >= _SPLIT_SIZES else 1
    if threads > 1:
        from ._workers import run_all

        bounds = np.linspace(0, m, 2 * threads + 1).astype(np.int64).tolist()
        out = run_all(lambda a, b: _size_sums(v, f, a, b), list(zip(bounds[:-1], bounds[1:])), threads)
    else:
        out = [_size_sums(v, f, 0, m)]
    if not all(o[0] for o in out):
        return None
    total = math.fsum([x for o in out for x in o[1][: o[2]].tolist()])
    walls = math.fsum([x for o in out for x in o[3][: o[4]].tolist()])
    return total, walls


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
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if len(f) == 0:
        return 0.0
    if f.ndim != 2 or f.shape[1] != 3 or v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"expected (n, 3) vertices and (m, 3) faces; got {v.shape} and {f.shape}")
    sums = _size_totals(v, f)
    if sums is None:  # (faces outside the vertices: face_terms raises; non-finite sizes)
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"faces refer to vertices outside 0 .. {len(v) - 1}")
        size, wall, _six = face_terms(v, f)
        sums = math.fsum(size), math.fsum(size[wall])
    total, walls = sums
    return float(walls / total) if total > 0 else 0.0


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


@njit(cache=True, nogil=True)
def _topology_kernel(F, n):
    """One pass over the faces (vertex indices below ``n``): ``(used vertices, undirected edges,
    boundary edges, non-manifold edges, directed edges used more than once, components, a root
    label per vertex)``; the edges are bucketed by their lower vertex (a counting sort), each
    bucket counted on its own; components by union-find over the face edges."""
    m = len(F)
    cnt = np.zeros(n + 1, np.int64)
    used = np.zeros(n, np.uint8)
    parent = np.arange(n)
    for i in range(m):
        for t in range(3):
            a = F[i, t]
            b = F[i, (t + 1) % 3]
            used[a] = 1
            cnt[min(a, b) + 1] += 1
            # union (path halving)
            ra = a
            while parent[ra] != ra:
                parent[ra] = parent[parent[ra]]
                ra = parent[ra]
            rb = b
            while parent[rb] != rb:
                parent[rb] = parent[parent[rb]]
                rb = parent[rb]
            if ra != rb:
                if ra < rb:
                    parent[rb] = ra
                else:
                    parent[ra] = rb
    for v in range(n):
        cnt[v + 1] += cnt[v]
    fill = cnt[:n].copy()
    key = np.empty(3 * m, np.int64)  # 2 * upper vertex + (1 if the edge runs downward)
    for i in range(m):
        for t in range(3):
            a = F[i, t]
            b = F[i, (t + 1) % 3]
            lo = min(a, b)
            key[fill[lo]] = 2 * max(a, b) + (1 if a > b else 0)
            fill[lo] += 1
    n_used = 0
    n_edges = 0
    boundary = 0
    nonmanifold = 0
    dup_directed = 0
    comps = 0
    for v in range(n):
        if used[v] == 0:
            continue
        n_used += 1
        r = v
        while parent[r] != r:
            r = parent[r]
        if r == v:
            comps += 1
        s0 = cnt[v]
        s1 = cnt[v + 1]
        if s1 - s0 > 16:
            key[s0:s1].sort()
        else:
            for x in range(s0 + 1, s1):  # insertion sort: the buckets are short
                kx = key[x]
                y = x - 1
                while y >= s0 and key[y] > kx:
                    key[y + 1] = key[y]
                    y -= 1
                key[y + 1] = kx
        t = s0
        while t < s1:  # runs of one undirected edge; within a run, runs of one direction
            u = t
            while u < s1 and key[u] >> 1 == key[t] >> 1:
                u += 1
            c = u - t
            n_edges += 1
            if c == 1:
                boundary += 1
            elif c > 2:
                nonmanifold += 1
            w = t
            while w < u:
                x = w
                while x < u and key[x] == key[w]:
                    x += 1
                if x - w > 1:
                    dup_directed += 1
                w = x
            t = u
    return n_used, n_edges, boundary, nonmanifold, dup_directed, comps


@njit(cache=True, nogil=True)
def _face_kernel(V, F, c, thr, canon):
    """Per face the volume term ``t0 . (t1 x t2)`` (corners less ``c``, as in
    :func:`mesh_volume`), and the counts of degenerate faces (a repeated index, or area at most
    ``thr``) and of used vertices whose position an earlier used vertex has (``canon``)."""
    m = len(F)
    vol = np.empty(m, np.float64)
    degenerate = 0
    for i in range(m):
        a = F[i, 0]
        b = F[i, 1]
        d = F[i, 2]
        ux = V[b, 0] - V[a, 0]
        uy = V[b, 1] - V[a, 1]
        uz = V[b, 2] - V[a, 2]
        wx = V[d, 0] - V[a, 0]
        wy = V[d, 1] - V[a, 1]
        wz = V[d, 2] - V[a, 2]
        cx = uy * wz - uz * wy
        cy = uz * wx - ux * wz
        cz = ux * wy - uy * wx
        area = 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
        if a == b or b == d or a == d or area <= thr:
            degenerate += 1
        p0 = V[a, 0] - c[0]
        p1 = V[a, 1] - c[1]
        p2 = V[a, 2] - c[2]
        q0 = V[b, 0] - c[0]
        q1 = V[b, 1] - c[1]
        q2 = V[b, 2] - c[2]
        r0 = V[d, 0] - c[0]
        r1 = V[d, 1] - c[1]
        r2 = V[d, 2] - c[2]
        vol[i] = p0 * (q1 * r2 - q2 * r1) + p1 * (q2 * r0 - q0 * r2) + p2 * (q0 * r1 - q1 * r0)
    n = len(V)
    seen = np.zeros(n, np.uint8)  # 1: used, 2: a used vertex has this position
    for i in range(m):
        for t in range(3):
            seen[F[i, t]] = 1
    distinct = 0
    n_used = 0
    for v in range(n):
        if seen[v] & 1:
            n_used += 1
            r = canon[v]
            if (seen[r] & 2) == 0:
                seen[r] |= 2
                distinct += 1
    return vol, degenerate, n_used - distinct


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
    V, F = _as_mesh_arrays(vertices, faces)
    if not V.flags.writeable:  # one compiled signature: writable C arrays
        V = V.copy()
    if not F.flags.writeable:
        F = F.copy()
    n_used, n_edges, boundary, nonmanifold, dup_directed, comps = _topology_kernel(F, np.int64(len(V)))
    diag2 = float(np.sum((V.max(0) - V.min(0)) ** 2)) or 1.0
    canon = canonical_vertices(V)
    _vol, degenerate, dup_vertices = _face_kernel(V, F, V.mean(axis=0), float(rel_tol * diag2), canon)
    volume = mesh_volume(V, F)  # (order-independent, as Mesh.volume)
    watertight = boundary == 0 and nonmanifold == 0
    # the pairs on the used vertices only when the mesh is a few faces of many vertices (as
    # intersecting_pairs does)
    if 3 * len(F) < len(V):
        pairs = self_intersections(V, F)
    else:
        pairs = int(len(_pairs(V, F, canon, 8, "auto")))
    out = {
        "watertight": bool(watertight),
        "winding_consistent": dup_directed == 0,
        "boundary_edges": int(boundary),
        "nonmanifold_edges": int(nonmanifold),
        "degenerate_faces": int(degenerate),
        "duplicate_vertices": int(dup_vertices),
        "volume": volume,
        "components": int(comps),
        "genus": euler_genus(int(n_used), int(n_edges), len(F), int(comps)) if watertight else None,
        "self_intersections": pairs,
    }
    # closed: a closed, consistently outward 2-manifold without degenerate faces; ok: also embedded
    out["closed"] = bool(watertight and out["winding_consistent"] and degenerate == 0 and dup_vertices == 0
                         and volume > 0)
    out["ok"] = bool(out["closed"] and out["self_intersections"] == 0)
    return out


# ------------------------------------------------------------------------------------------------
# order-independent area and volume
# ------------------------------------------------------------------------------------------------
def exact_parts(x) -> list:
    """Floats whose exact sum is the exact sum of ``x`` (a non-overlapping expansion, largest first)."""
    terms = np.asarray(x, dtype=np.float64).ravel().tolist()
    parts: list = []
    for _ in range(80):
        s = math.fsum(terms + [-p for p in parts])
        if s == 0.0:
            return parts
        parts.append(s)
    raise ArithmeticError("exact_parts: the expansion did not terminate")  # pragma: no cover


def _split(a):
    c = 134217729.0 * a  # 2^27 + 1 (Veltkamp)
    h = c - (c - a)
    return h, a - h


def _two_prod(a, b):
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _rotated(V, F):
    """Faces rotated (orientation kept) to start at their lexicographically smallest corner."""
    if not len(F):
        return F
    order = np.lexsort(V.T[::-1])
    rank = np.empty(len(V), np.int64)
    rank[order] = np.arange(len(V))
    r = np.argmin(rank[F], axis=1)
    rows = np.arange(len(F))
    return np.stack([F[rows, (r + i) % 3] for i in range(3)], axis=1)


def _area_terms(V, F):
    T = V[_rotated(V, F)]
    c = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    return 0.5 * np.sqrt(np.einsum("ij,ij->i", c, c))


def _volume_terms(V, F, chunk: int = 200_000):
    """Yields arrays of floats whose exact sum is ``sum_f a . (b x c)`` over the faces (six times
    the enclosed volume), exactly (barring overflow and underflow)."""
    for s in range(0, len(F), chunk):
        T = V[F[s:s + chunk]]
        a, b, c = T[:, 0], T[:, 1], T[:, 2]
        out = []
        for sign, (u, v, w) in ((1, (a[:, 0], b[:, 1], c[:, 2])), (-1, (a[:, 0], b[:, 2], c[:, 1])),
                                (1, (a[:, 1], b[:, 2], c[:, 0])), (-1, (a[:, 1], b[:, 0], c[:, 2])),
                                (1, (a[:, 2], b[:, 0], c[:, 1])), (-1, (a[:, 2], b[:, 1], c[:, 0]))):
            p, e = _two_prod(u, v)
            p2, e2 = _two_prod(p, w)
            p3, e3 = _two_prod(e, w)
            out.extend(sign * t for t in (p2, e2, p3, e3))
        yield np.concatenate(out)


def _volume_parts(V, F) -> list:
    parts: list = []
    for t in _volume_terms(V, F):
        parts = exact_parts(np.concatenate([t, parts]))
    return parts


def exact_area_volume(vertices, faces):
    """``(area, volume)`` of a mesh, independent of the order of its vertices and faces and of
    where its faces start: the correctly rounded sum of the per-face areas, and the correctly
    rounded exact divergence-theorem volume (divided by 6)."""
    V = np.asarray(vertices, dtype=np.float64) + 0.0
    F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    return math.fsum(_area_terms(V, F)), math.fsum(_volume_parts(V, F)) / 6.0
