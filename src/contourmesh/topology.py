"""Compiled topology of a binary volume (6-connected object, 26-connected background).

:func:`contourmesh.volumes.voxel_topology` is the reference: it labels the object and the
background of the whole volume (``scipy.ndimage.label``) and takes the Euler characteristic from
``skimage.measure.euler_number``, three passes over the volume with their own temporaries.  The
band refinement's stack route (:func:`contourmesh.api._stack_of_mask`) asks one question of every
volume with one contour per slice -- is the voxels' surface one sphere? -- and :func:`topology`
answers it with the same numbers from the runs of the rows (stretches of equal voxels along x):

* :func:`euler_characteristic` -- ``chi = V - E + F - C`` of the cubical complex on the voxel
  centres (voxels, 6-adjacent pairs, 2 x 2 squares, 2 x 2 x 2 cubes of object voxels), the Euler
  characteristic of the 6-connected object with a 26-connected background;
* object components -- union-find over the object's runs: a run joins the overlapping runs of the
  row before it in its slice and of the same row in the slice before (6-adjacency);
* cavities -- union-find over the background's runs: a run joins the runs of the four rows before
  it (in its slice and the slice before) that it overlaps or touches diagonally (26-adjacency);
  runs on the volume's border join the outside (voxels beyond the array are background), and
  every other set is a cavity.

The tests compare them with the reference on random volumes.
"""

from __future__ import annotations

import numpy as np

from ._kernels import njit

__all__ = ["euler_characteristic", "topology"]


def _as_bytes(mask) -> np.ndarray:
    m = np.asarray(mask)
    if m.ndim != 3:
        raise ValueError(f"mask must be a 3D array indexed [z, y, x]; got shape {m.shape}")
    return np.ascontiguousarray(m, dtype=bool).view(np.uint8)


@njit(cache=True, nogil=True)
def _euler(m):
    nz, ny, nx = m.shape
    chi = 0
    for k in range(nz):
        k1 = k + 1 < nz
        for j in range(ny):
            j1 = j + 1 < ny
            for i in range(nx):
                if m[k, j, i] == 0:
                    continue
                i1 = i + 1 < nx
                ex = i1 and m[k, j, i + 1] != 0
                ey = j1 and m[k, j + 1, i] != 0
                ez = k1 and m[k + 1, j, i] != 0
                fxy = ex and ey and m[k, j + 1, i + 1] != 0
                fxz = ex and ez and m[k + 1, j, i + 1] != 0
                fyz = ey and ez and m[k + 1, j + 1, i] != 0
                cube = fxy and fxz and fyz and m[k + 1, j + 1, i + 1] != 0
                chi += 1 - (ex + ey + ez) + (fxy + fxz + fyz) - cube
    return chi


def euler_characteristic(mask) -> int:
    """Euler characteristic of the 6-connected voxel object (as ``skimage.measure.euler_number(mask,
    connectivity=1)``); voxels outside the array are background."""
    return int(_euler(_as_bytes(mask)))


@njit(cache=True, nogil=True)
def _runs(m, value):
    """Runs of voxels equal to ``value`` along x: ``(row_start, x0, x1)``; the runs of row ``r = k *
    ny + j`` are ``row_start[r]:row_start[r + 1]``, run ``q`` covers ``x0[q] <= i < x1[q]``."""
    nz, ny, nx = m.shape
    nrow = nz * ny
    row_start = np.empty(nrow + 1, np.int64)
    n = 0
    for k in range(nz):  # count first
        for j in range(ny):
            inside = False
            for i in range(nx):
                on = m[k, j, i] == value
                if on and not inside:
                    n += 1
                inside = on
    x0 = np.empty(n, np.int64)
    x1 = np.empty(n, np.int64)
    n = 0
    for k in range(nz):
        for j in range(ny):
            row_start[k * ny + j] = n
            inside = False
            for i in range(nx):
                on = m[k, j, i] == value
                if on and not inside:
                    x0[n] = i
                elif inside and not on:
                    x1[n] = i
                    n += 1
                inside = on
            if inside:
                x1[n] = nx
                n += 1
    row_start[nrow] = n
    return row_start, x0, x1


@njit(cache=True, nogil=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def _union(parent, a, b):
    a = _root(parent, a)
    b = _root(parent, b)
    if a != b:
        parent[max(a, b)] = min(a, b)


@njit(cache=True, nogil=True)
def _join_rows(parent, x0, x1, i, i1, j, j1, reach):
    """Union the runs of two rows (``i:i1`` and ``j:j1``, each sorted by x) that overlap
    (``reach = 0``) or overlap or touch at a corner (``reach = 1``)."""
    while i < i1 and j < j1:
        if x0[i] < x1[j] + reach and x0[j] < x1[i] + reach:
            _union(parent, i, j)
        if x1[i] <= x1[j]:
            i += 1
        else:
            j += 1


@njit(cache=True, nogil=True)
def _count_object(m):
    """6-connected components of the object."""
    nz, ny, nx = m.shape
    row_start, x0, x1 = _runs(m, np.int64(1))
    n = len(x0)
    parent = np.empty(n, np.int64)
    for q in range(n):
        parent[q] = q
    for r in range(nz * ny):
        a, a1 = row_start[r], row_start[r + 1]
        if a == a1:
            continue
        if r % ny > 0:  # the row before in the slice
            _join_rows(parent, x0, x1, row_start[r - 1], row_start[r], a, a1, np.int64(0))
        if r >= ny:  # the same row in the slice before
            _join_rows(parent, x0, x1, row_start[r - ny], row_start[r - ny + 1], a, a1, np.int64(0))
    count = 0
    for q in range(n):
        if parent[q] == q:
            count += 1
    return count


@njit(cache=True, nogil=True)
def _count_cavities(m):
    """26-connected components of the background that do not reach the volume's border."""
    nz, ny, nx = m.shape
    row_start, x0, x1 = _runs(m, np.int64(0))
    n = len(x0)
    out = n  # the outside: every run on the border joins it
    parent = np.empty(n + 1, np.int64)
    for q in range(n + 1):
        parent[q] = q
    for k in range(nz):
        for j in range(ny):
            r = k * ny + j
            a, a1 = row_start[r], row_start[r + 1]
            if a == a1:
                continue
            if k == 0 or k == nz - 1 or j == 0 or j == ny - 1:
                for q in range(a, a1):
                    _union(parent, q, out)
            else:
                if x0[a] == 0:
                    _union(parent, a, out)
                if x1[a1 - 1] == nx:
                    _union(parent, a1 - 1, out)
            if j > 0:
                _join_rows(parent, x0, x1, row_start[r - 1], row_start[r], a, a1, np.int64(1))
            if k > 0:
                for dj in range(-1, 2):
                    if 0 <= j + dj < ny:
                        rr = r - ny + dj
                        _join_rows(parent, x0, x1, row_start[rr], row_start[rr + 1], a, a1, np.int64(1))
    outside = _root(parent, out)
    count = 0
    for q in range(n):
        if parent[q] == q and q != outside:
            count += 1
    return count


def topology(mask) -> dict:
    """:func:`contourmesh.volumes.voxel_topology` in compiled passes: components (6-connected),
    cavities (background components, 26-connected, not reaching the border), surfaces, Euler
    characteristic and total genus of the boundary of a binary volume; the same numbers."""
    m = _as_bytes(mask)
    ncomp = int(_count_object(m))
    cavities = int(_count_cavities(m))
    chi = int(_euler(m))
    surfaces = ncomp + cavities
    return {"components": ncomp, "cavities": cavities, "surfaces": surfaces, "euler": chi,
            "genus": surfaces - chi}
