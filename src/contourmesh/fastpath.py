"""Fast path for volumes: the same mesh as :func:`contourmesh.volumes.volume_to_mesh`, in numba.

Scope
-----
:func:`fast_volume_to_mesh` builds the mesh of :mod:`contourmesh.volumes` for the volumes where
that mesher only uses the paper's own construction (Wiederhold & Villafuerte 2009): MLP polygons
(``polygon="mlp"``), the paper's band triangulation (``triangulation="wiederhold"``) and flat or
half caps, with

* every 4-component of every slice free of holes, and
* every pair of consecutive slices joined only by *simple band joins*: each component overlaps at
  most one component of the neighbouring slice, and their overlap is connected and hole-free
  (:func:`contourmesh.volumes._simple_join` without holes).

Outside that scope (exact joins, holes, other polygon or band methods, caps that earcut cannot
triangulate, vertices that share a position, ...) it returns ``None`` and the caller falls back
to the full mesher.  Inside it the result is **identical**: the same vertices (bit for bit, in the
same order) and the same faces, because every step is the full mesher's step done on runs:

1. *Runs.*  Each slice row is scanned eight voxels at a time (``uint64`` words over the ``bool``
   bytes): a word that is all background (or all object) inside a background (object) stretch is
   skipped, so only words that hold a boundary are looked at byte by byte.
2. *Components.*  4-connected components of the runs by union-find (runs overlapping in adjacent
   rows), numbered in raster order of their first pixel like ``scipy.ndimage.label``; each
   component's number of holes is ``1 - chi`` with the Euler number ``chi = #runs - #(pairs of
   overlapping runs in adjacent rows)`` (4-connected object, 8-connected background).
3. *Outer Jordan contour.*  The boundary of ``U`` (cells with a corner in the component's pixels)
   is followed from its lowest-then-leftmost vertex, turning left first, exactly as
   :func:`contourmesh.tracing.trace_contours` does, but reading the 3 x 3 pixels around each
   vertex instead of a dilated cell image (so only the boundary is touched).
4. *MLP.*  The candidates and string pulling of :mod:`contourmesh.polygons.mlp` (Klette & Yip),
   called on that contour; a component with one run per row (a *stack*, such as every slice of a
   ball) gets its candidates from its rows' intervals instead of the MLP's grids
   (:func:`_stack_candidates`, the same list); degenerate MLPs fall back to the crack contour as in
   the full mesher.  Shared vertex positions are found with a bit map of the slice.
5. *Joins.*  Overlap runs of consecutive slices give the component pairs; the overlap of each pair
   is checked connected and hole-free with the same run Euler number (two stacks whose overlap is a
   stack join by a walk over their runs, :func:`_stack_join`, without the overlap's arrays).
6. *Bands.*  The paper's triangulation (section 3.4, :func:`~contourmesh.bands.wiederhold.wiederhold_edges`)
   with the initial edge of section 3.2, and the full mesher's twist guard (arc-length band of
   Ganapathy & Dennehy as the reference); the rare folded or twisted bands (and near-ties of the
   guard) are handed to the full mesher's Python code.  The full mesher also tests each kept band
   for faces crossing each other; here :func:`contourmesh.volumes.volume_to_mesh` tests only the
   bands with a face in one of the whole mesh's crossing pairs (:func:`redo_self_crossing_bands`),
   which finds the same bands, so the public mesh is the full mesher's.
7. *Caps* by earcut (:func:`~contourmesh.bands.caps.cap_faces`), as in the full mesher.

Steps 1-4 run over a slab of consecutive slices and 5-6 over a slab of slice pairs in one
``nogil`` numba call each (:func:`_slab_polygons`, :func:`_slab_pairs`; their outputs packed into
flat arrays, no Python per slice, pair or component), so ``threads > 1`` spreads the slabs over a
thread pool (:mod:`contourmesh._workers`, kept between calls); the vertex ids and faces of the bands are then assembled by one more kernel
(:func:`_assemble`), and Python only redoes the bands the twist guard hands back, the rings of
degenerate MLPs and the caps.  The full mesher's manifold repair steps are provably no-ops on
this scope (every edge has two faces, every vertex one fan; positions are checked distinct per
plane), so they are skipped.
"""

from __future__ import annotations

import math
import os
import sys
import threading

import numpy as np

from ._kernels import KERNEL_OPTIONS, internal_kernel, njit
from ._workers import run_all
from .bands import _band_crosses, band_is_folded, triangulate_band, twist_guarded_band
from .bands import arclength as _arclength
from .bands import wiederhold as _wiederhold
from .bands.caps import cap_faces
from .bands.wiederhold import INITIAL_EDGE_WINDOW
from .geometry import grid_to_xy, slice_gap
from .polygons import mlp as _mlp_module
from .polygons import thin_part_polygon
from .tracing import _crack_contours, _root
from .types import Mesh
from .volume_input import check_origin, check_spacing

__all__ = ["fast_volume_to_mesh", "slice_runs", "slice_components", "slice_labels", "outer_jordan_contour",
           "slice_polygons", "band_faces"]


# ------------------------------------------------------------------------------------------------
# compile time: the first call in a fresh process compiles everything below (issue 5)
# ------------------------------------------------------------------------------------------------
# The fast path calls three entry points from Python, cached on disk: ``_slab_polygons`` (steps
# 1-4 over a slab of slices), ``_slab_pairs`` (5-6 over a slab of slice pairs) and ``_assemble``;
# ``_slice_polygons`` (one slice: volumes that are not read from their own bytes, and the public
# ``slice_polygons``) and ``_pair_bands`` (one band: caps, ``band_faces``) are entry points over
# the same internal kernels.  Everything they call is an internal ``@_kernel``:
# compiled only as their callee, without the Python and C call wrappers (whose code costs about
# as much compile time as a small kernel's body) and without a cache file of its own (the entry
# points' cache holds its code).  The Python-level helpers (``slice_runs``, ``slice_components``,
# ``outer_jordan_contour``) reach the same kernels through ``_entry`` functions that only call
# them, so a process that meets both routes compiles each kernel once.  The MLP, the paper's edge
# sequence and the arc-length band are such kernels of their own modules (:mod:`._kernels`), whose
# public, cached functions only call them: the fast path and those functions share one compiled
# copy (the fast path passes the edge sequence contiguous x and y arrays, the layout of the
# public callers).  A kernel's code is optimized once more in every entry point that links it,
# so small helpers are written inline instead.  Compile-time rules for all of them:
# * one signature per kernel: pass int64 values, never literal constants (numba compiles a kernel
#   once more for a literal argument, even for a loop variable that starts as a literal);
# * explicit loops instead of slice assignments, and no exceptions (their error formatting pulls
#   in numba's string machinery);
# * ``np.empty`` with an explicit dtype only (``np.zeros``, ``np.full``, ``np.arange``, ``min``,
#   ``max`` are compiled overloads each), ``math.sqrt`` (not the ``np.sqrt`` ufunc), ``len(a)``
#   (with the rewrite passes off, ``a.shape[0]`` is one more overload).
# ``no_rewrites``: numba's IR rewrite passes (array expressions, constant getitems) find nothing
# to do in these loops and only cost compile time.
_OPTIONS = KERNEL_OPTIONS
_kernel = internal_kernel  # ``fn`` as an internal numba kernel (see above)

#: The connectivity every volume mesh is made with (recorded in ``meta``).
CONNECTIVITY = "object 6 (4 in slice) / background 26 (8 in slice)"


def _entry(fn):
    """A cached, Python-callable entry point (for the Python-level helpers) that only calls an
    internal kernel: the kernel is compiled once per process whether the fast path or the general
    mesher (``slice_labels``, ``slice_components``) reaches it first, not once more as a twin."""
    return njit(cache=True, **_OPTIONS)(fn)


_mlp = _mlp_module._mlp_kernel
_mlp_grid = _mlp_module._mlp_grid
_mlp_pull = _mlp_module._mlp_pull
wiederhold_edges = _wiederhold._wiederhold_edges
_edges_to_faces = _wiederhold._edges_to_faces_kernel
arclength_edges = _arclength._arclength_edges

_ONES = np.uint64(0x0101010101010101)
_ZERO = np.uint64(0)
_ONE = np.uint64(1)
_HIGH = np.uint64(0xFEFEFEFEFEFEFEFE)  # the bits a 0/1 byte never sets
_EIGHT = np.uint64(8)
_FIFTYSIX = np.uint64(56)
_SIXTYFOUR = np.uint64(64)
_BYTE_INDEX = np.uint64(0x0001020304050607)  # (1 << 8 j) * this >> 56 == j  (mod 2^64)
_U2, _U3, _U4, _U5, _U6, _U7 = (np.uint64(q) for q in range(2, 8))  # word offsets (unsigned: see _scan_runs)


# ------------------------------------------------------------------------------------------------
# 1. runs
# ------------------------------------------------------------------------------------------------
@_kernel
def _scan_runs(b8, b64, base, h, w, aligned, row_start, ry, rx0, rx1, woff):
    """Runs of non-zero bytes of the ``h x w`` slice starting at byte ``base`` of ``b8``, written in
    the caller's ``int32`` arrays: returns ``(n, bad)``.

    ``b64`` is a ``uint64`` view of ``b8`` from byte ``woff`` on (used when ``aligned``): word
    ``q`` is bytes ``woff + 8 q .. woff + 8 q + 7``, so a slice whose first byte is not at a word
    boundary of memory (a slice of a volume whose slices are not a multiple of 8 bytes) is still
    read a word at a time, from its first byte at such a boundary on.  Run ``r < n`` covers pixels
    ``rx0[r] <= x < rx1[r]`` of row ``ry[r]``; runs of row ``y`` are ``row_start[y]:row_start[y +
    1]`` (``h + 1`` items); ``bad`` counts bytes other than 0 and 1.  ``n`` is -1 when ``ry``,
    ``rx0`` and ``rx1`` (of equal length) hold fewer runs than the slice has: the caller gives
    larger arrays and scans again (the runs written are the same whatever room they get).
    :func:`_slab_polygons` hands it views of its packed arrays at the slice's offset, so the runs
    and row starts are written in place once, not made per slice and copied there.
    """
    cap = len(ry)
    n = 0
    bad = 0
    for y in range(h):
        row_start[y] = n
        start = base + y * w
        end = start + w
        i = start
        inside = False
        x0 = 0
        while i < end:
            if aligned and ((i - woff) & 7) == 0:  # (i - woff > -8, so 0: i >= woff)
                # skip whole words that continue the current stretch (all 0 or all 1 bytes)
                # (eight words, one cache line, at a time first: the test compiles to vector code)
                # (the word indices unsigned: numba then reads b64 without the check for a negative
                # index, which it cannot rule out here and which cost the skip half its speed)
                wi = np.uint64((i - woff) >> 3)
                we = np.uint64((end - woff) >> 3)
                if inside:
                    while wi + _EIGHT <= we and ((b64[wi] ^ _ONES) | (b64[wi + _ONE] ^ _ONES) | (b64[wi + _U2] ^ _ONES)
                                                 | (b64[wi + _U3] ^ _ONES) | (b64[wi + _U4] ^ _ONES)
                                                 | (b64[wi + _U5] ^ _ONES) | (b64[wi + _U6] ^ _ONES)
                                                 | (b64[wi + _U7] ^ _ONES)) == _ZERO:
                        wi += _EIGHT
                    while wi < we and b64[wi] == _ONES:
                        wi += _ONE
                else:
                    while wi + _EIGHT <= we and (b64[wi] | b64[wi + _ONE] | b64[wi + _U2] | b64[wi + _U3] | b64[wi + _U4]
                                                 | b64[wi + _U5] | b64[wi + _U6] | b64[wi + _U7]) == _ZERO:
                        wi += _EIGHT
                    while wi < we and b64[wi] == _ZERO:
                        wi += _ONE
                i = (np.int64(wi) << 3) + woff
                if i >= end:
                    break
                if wi < we:
                    x = b64[wi]
                    if (x & _HIGH) == _ZERO:
                        # a word of 0/1 bytes that holds a boundary: its transitions at once, as
                        # the set bytes of x ^ (x shifted one byte up, the stretch's value below)
                        t = x ^ ((x << _EIGHT) | (_ONE if inside else _ZERO))
                        while t != _ZERO:
                            low = t & (~t + _ONE)
                            j = np.int64((low * _BYTE_INDEX) >> _FIFTYSIX)  # index of low's byte
                            if inside:
                                if n >= cap:
                                    return np.int64(-1), bad
                                ry[n] = y
                                rx0[n] = x0
                                rx1[n] = i + j - start
                                n += 1
                            else:
                                x0 = i + j - start
                            inside = not inside
                            t ^= low
                        i += 8
                        continue
            v = b8[i]
            if v > 1:
                bad += 1
            on = v != 0
            if on != inside:
                if on:
                    x0 = i - start
                else:
                    if n >= cap:
                        return np.int64(-1), bad
                    ry[n] = y
                    rx0[n] = x0
                    rx1[n] = i - start
                    n += 1
                inside = on
            i += 1
        if inside:
            if n >= cap:
                return np.int64(-1), bad
            ry[n] = y
            rx0[n] = x0
            rx1[n] = w
            n += 1
    row_start[h] = n
    return np.int64(n), bad


@_kernel
def _scan_new(b8, b64, base, h, w, aligned, woff):
    """:func:`_scan_runs` into new arrays (grown until the slice's runs fit): ``(ry, rx0, rx1,
    row_start, bad)``, ``int32``."""
    row_start = np.empty(h + 1, np.int32)
    cap = 2 * h + 64
    while True:
        ry = np.empty(cap, np.int32)
        rx0 = np.empty(cap, np.int32)
        rx1 = np.empty(cap, np.int32)
        n, bad = _scan_runs(b8, b64, base, h, w, aligned, row_start, ry, rx0, rx1, woff)
        if n >= 0:
            return ry[:n], rx0[:n], rx1[:n], row_start, bad
        cap = 4 * cap


@_entry
def _scan_runs_py(b8, b64, base, h, w, aligned, woff):
    """:func:`_scan_runs` into new arrays, as ``int64`` (the Python-level helpers' arrays)."""
    ry, rx0, rx1, rs, bad = _scan_new(b8, b64, base, h, w, aligned, woff)
    return ry.astype(np.int64), rx0.astype(np.int64), rx1.astype(np.int64), rs.astype(np.int64), bad


@_kernel
def _grow(a, cap):
    """A new ``int64`` array of length ``cap`` starting with ``a`` (an explicit loop: a slice
    assignment would compile numba's shape-mismatch error formatting)."""
    b = np.empty(cap, np.int64)
    for i in range(len(a)):
        b[i] = a[i]
    return b


@_kernel
def _grow32(a, cap):
    """:func:`_grow` for the ``int32`` arrays of :func:`_slab_polygons`."""
    b = np.empty(cap, np.int32)
    for i in range(len(a)):
        b[i] = a[i]
    return b


def slice_runs(mask2d) -> tuple:
    """Runs of a 2D boolean mask: ``(ry, rx0, rx1, row_start)``, ``int64`` (see :func:`_scan_runs`)."""
    m = np.ascontiguousarray(mask2d, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2D array indexed [y, x]; got shape {m.shape}")
    b8 = m.reshape(-1).view(np.uint8)
    b64, woff, aligned = _words_from(b8)
    ry, rx0, rx1, rs, _ = _scan_runs_py(b8, b64, 0, m.shape[0], m.shape[1], aligned, woff)
    return ry, rx0, rx1, rs


def _words_from(b8):
    """``(b64, woff, aligned)``: the ``uint64`` view of ``b8`` from its first byte at a word
    boundary of memory (byte ``woff``) on, for :func:`_scan_runs`.  A slice of a C-ordered volume
    starts ``k h w`` bytes into it, off a word boundary for 3 slices in 4 where ``h w`` is 2 mod
    8 (the rotated socket's 441 x 514): :func:`_words` refuses those, and their scan went byte by
    byte (0.15 ms a slice, not 0.03)."""
    woff = (-b8.ctypes.data) % 8
    n8 = ((b8.shape[0] - woff) // 8) * 8 if b8.shape[0] > woff else 0
    if n8 == 0 or sys.byteorder != "little":
        return np.zeros(1, np.uint64), np.int64(0), False
    return b8[woff: woff + n8].view(np.uint64), np.int64(woff), True


def _words(b8):
    n8 = (b8.shape[0] // 8) * 8
    if n8 == 0 or b8.ctypes.data % 8 != 0 or sys.byteorder != "little":  # _scan_runs reads bytes in words
        return np.zeros(1, np.uint64), False
    return b8[:n8].view(np.uint64), True


# ------------------------------------------------------------------------------------------------
# 1b. runs of every slice of a Fortran-ordered volume, in one pass over its bytes
# ------------------------------------------------------------------------------------------------
@_kernel
def _fortran_scan(b8, b64, p, n, aligned, i, buf, nb):
    """The places where a Fortran-ordered volume's rows change value, from byte ``i`` on.

    ``b8``: the volume's ``n`` bytes in memory order (byte ``x * p + y * k + z`` is voxel ``[z,
    y, x]`` of a ``(k, h, w)`` volume, ``p = k * h``); ``b64`` the same as words where
    ``aligned``.  Row ``(z, y)`` of the volume runs through bytes ``r, r + p, r + 2 p, ...`` (``r
    = y * k + z``), so it changes value at byte ``i`` (column ``i // p``) where ``b8[i] != 0``
    differs from ``b8[i - p] != 0``, the bytes before the first column and from column ``w`` on
    read as 0: a run starts or ends there.  Those places ``i`` (``0 <= i < n + p``, increasing)
    are put in ``buf[nb:]`` until it has fewer than eight free places; returns ``(i, nb)``, where
    to go on (``n + p`` at the end).  Whole words are compared at once: the word ``p`` bytes back
    (two words shifted where ``p`` is not a multiple of 8) XOR the word is zero where no row
    changes; its set bytes are the changes where both hold 0/1 bytes, each byte read alone
    otherwise (any non-zero byte is a voxel, as :func:`_scan_runs` reads them)."""
    cap = len(buf)
    end = n + p
    lim = ((p + 7) // 8) * 8  # (the first word all of whose bytes have a byte p back)
    n8 = (n // 8) * 8
    while i < end and nb + 8 <= cap:
        if aligned and lim <= i < n8:
            q = i >> 3
            qe = n8 >> 3
            while q < qe and nb + 8 <= cap:
                w0 = b64[q]
                j = 8 * q - p
                a = j >> 3
                sh = np.uint64(8 * (j & 7))
                pw = b64[a] if sh == _ZERO else (b64[a] >> sh) | (b64[a + 1] << (_SIXTYFOUR - sh))
                t = w0 ^ pw
                if t != _ZERO:
                    i0 = 8 * q
                    if ((w0 | pw) & _HIGH) == _ZERO:
                        while t != _ZERO:
                            low = t & (~t + _ONE)
                            buf[nb] = i0 + np.int64((low * _BYTE_INDEX) >> _FIFTYSIX)  # (low's byte)
                            nb += 1
                            t ^= low
                    else:
                        for ii in range(i0, i0 + 8):
                            if (b8[ii] != 0) != (b8[ii - p] != 0):
                                buf[nb] = ii
                                nb += 1
                q += 1
            i = q << 3
            continue
        cur = b8[i] != 0 if i < n else False
        prev = b8[i - p] != 0 if i >= p else False
        if cur != prev:
            buf[nb] = i
            nb += 1
        i += 1
    return i, nb


@_kernel
def _fortran_runs(b8, b64, k, h, w, aligned, cap):
    """The runs of every slice of a Fortran-ordered ``(k, h, w)`` volume (bytes ``b8``, words
    ``b64``: see :func:`_fortran_scan`) from its bytes in memory order: ``(tx, off)``, where row
    ``y`` of slice ``z`` (place ``s = z * h + y``) changes value at the columns ``tx[off[s]: off[s +
    1]]`` (int32, increasing; the even ones start runs, the odd ones end them): the runs
    :func:`_scan_runs` finds in ``volume[z]`` made C-ordered (:func:`_slice_of_runs` gives them in
    its form), without the C-ordered copy.

    The changes are sorted by place (slice-major, then row; each place's in column order) by
    counting.  One pass over the bytes where at most ``cap`` changes are found (a buffer of 8
    bytes a change); with more (a noisy volume), a pass that counts them and another that puts
    them in place, through the same buffer: never more than ``cap`` of them held twice."""
    p = k * h
    n = p * w
    end = n + p
    buf = np.empty(cap + 8 if cap < end else end + 8, np.int64)
    off = np.empty(p + 1, np.int64)
    for s in range(p + 1):
        off[s] = 0
    i, nb = _fortran_scan(b8, b64, p, n, aligned, np.int64(0), buf, np.int64(0))
    one_pass = i >= end
    _count_places(buf, nb, off, p, k, h)
    while i < end:
        i, nb = _fortran_scan(b8, b64, p, n, aligned, i, buf, np.int64(0))
        _count_places(buf, nb, off, p, k, h)
    for s in range(p):
        off[s + 1] += off[s]
    at = np.empty(p, np.int64)
    for s in range(p):
        at[s] = off[s]
    tx = np.empty(off[p], np.int32)
    if one_pass:
        _put_places(buf, nb, at, tx, p, k, h)
    else:
        i = np.int64(0)
        while i < end:
            i, nb = _fortran_scan(b8, b64, p, n, aligned, i, buf, np.int64(0))
            _put_places(buf, nb, at, tx, p, k, h)
    return tx, off


@_kernel
def _count_places(buf, nb, off, p, k, h):
    """``off[s + 1] += 1`` for the place ``s`` of each change ``buf[:nb]`` (see :func:`_fortran_runs`)."""
    for t in range(nb):
        r = buf[t] % p
        y = r // k
        off[(r - y * k) * h + y + 1] += 1


@_kernel
def _put_places(buf, nb, at, tx, p, k, h):
    """Each change ``buf[:nb]``'s column put at its place's next slot (see :func:`_fortran_runs`)."""
    for t in range(nb):
        x = buf[t] // p
        r = buf[t] - x * p
        y = r // k
        s = (r - y * k) * h + y
        tx[at[s]] = x
        at[s] += 1


#: Changes :func:`_fortran_runs` finds in one pass (2 MiB of buffer; the liver has 135 000).
FORTRAN_PASS_CHANGES = 1 << 18


@_entry
def _fortran_runs_py(b8, b64, k, h, w, aligned, cap):
    return _fortran_runs(b8, b64, k, h, w, aligned, cap)


@_entry
def _slice_of_runs(tx, off, z, h):
    """Slice ``z``'s runs of :func:`_fortran_runs` as :func:`_scan_runs` gives them: ``(ry, rx0,
    rx1, row_start)`` (int64)."""
    a = off[z * h]
    nr = (off[(z + 1) * h] - a) // 2
    ry = np.empty(nr, np.int64)
    rx0 = np.empty(nr, np.int64)
    rx1 = np.empty(nr, np.int64)
    rs = np.empty(h + 1, np.int64)
    r = 0
    for y in range(h):
        rs[y] = r
        for t in range(off[z * h + y], off[z * h + y + 1], 2):
            ry[r] = y
            rx0[r] = tx[t]
            rx1[r] = tx[t + 1]
            r += 1
    rs[h] = r
    return ry, rx0, rx1, rs


class FortranRuns:
    """The runs of every slice of a Fortran-ordered 3D boolean volume ``mask`` (``[z, y, x]``),
    found in one pass over its bytes in memory order (:func:`_fortran_runs`): ``self[z]`` is
    ``slice_runs(mask[z])``, ``(ry, rx0, rx1, row_start)``.  Reading a slice of such a volume
    in raster order costs a cache line a voxel, and a C-ordered copy of a block of slices
    touches every page of the volume; this pass reads each byte once, in order.  Holds 8 bytes a
    row of the volume and 8 a run (``cap``: see :func:`_fortran_runs`)."""

    def __init__(self, mask, cap=None):
        if mask.ndim != 3 or mask.dtype != bool or not mask.flags.f_contiguous:
            raise ValueError("FortranRuns reads a Fortran-ordered 3D boolean volume")
        k, h, w = mask.shape
        b8 = mask.T.reshape(-1).view(np.uint8)  # (C-ordered [x, y, z]: the bytes in memory order)
        b64, aligned = _words(b8)
        self.shape = (h, w)
        self.tx, self.off = _fortran_runs_py(b8, b64, np.int64(k), np.int64(h), np.int64(w), aligned,
                                             np.int64(FORTRAN_PASS_CHANGES if cap is None else cap))

    def __getitem__(self, z: int):
        return _slice_of_runs(self.tx, self.off, np.int64(z), np.int64(self.shape[0]))


# ------------------------------------------------------------------------------------------------
# 2. components (4-connected) of the runs
# ------------------------------------------------------------------------------------------------
@_kernel
def _components(ry, rx0, rx1, row_start, h, lab):
    """4-components of the runs: ``(label per run, n, holes per component, bbox (n, 4) =
    (xmin, ymin, xmax, ymax) inclusive, first run per component)``.  The runs and ``row_start``
    are ``int32`` (:func:`_scan_runs`; one signature for every caller), and the labels are written
    in the caller's ``int32`` array ``lab`` (``len(ry)`` items or more; returned as its first
    ``len(ry)``): :func:`_slab_polygons` hands it a view of its packed labels.

    Labels follow the raster order of each component's first pixel (as ``ndimage.label``).
    Holes (8-connected background components enclosed) = ``1 - chi`` with ``chi = #runs -
    #(overlapping run pairs in adjacent rows)``.
    """
    nr = len(ry)
    # one run per row, each overlapping the one below (a slice of a ball): one component without
    # holes, no union-find
    stack = nr > 0
    xmin = rx0[0] if nr > 0 else 0
    xmax = rx1[0] if nr > 0 else 0
    for r in range(1, nr):
        if ry[r] != ry[r - 1] + 1 or rx0[r] >= rx1[r - 1] or rx0[r - 1] >= rx1[r]:
            stack = False
            break
        if rx0[r] < xmin:
            xmin = rx0[r]
        if rx1[r] > xmax:
            xmax = rx1[r]
    lab = lab[:nr]
    if stack:
        for r in range(nr):
            lab[r] = 0
        holes = np.empty(1, np.int64)
        holes[0] = 0
        bbox = np.empty((1, 4), np.int64)
        bbox[0, 0] = xmin
        bbox[0, 1] = ry[0]
        bbox[0, 2] = xmax - 1
        bbox[0, 3] = ry[nr - 1]
        first = np.empty(1, np.int64)
        first[0] = 0
        return lab, np.int64(1), holes, bbox, first
    parent = np.empty(nr, np.int64)
    for r in range(nr):
        parent[r] = r
    for y in range(1, h):
        i, i1 = np.int64(row_start[y - 1]), np.int64(row_start[y])  # (int64: _root's one signature)
        j, j1 = np.int64(row_start[y]), np.int64(row_start[y + 1])
        while i < i1 and j < j1:
            if rx0[i] < rx1[j] and rx0[j] < rx1[i]:
                a, b = _root(parent, i), _root(parent, j)
                if a != b:
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
            if rx1[i] <= rx1[j]:
                i += 1
            else:
                j += 1
    root_lab = np.empty(nr, np.int64)
    for r in range(nr):
        root_lab[r] = -1
    n = 0
    for r in range(nr):
        t = _root(parent, r)
        if root_lab[t] < 0:
            root_lab[t] = n
            n += 1
        lab[r] = root_lab[t]
    holes = np.empty(n, np.int64)  # 1 - chi, counted down from 1
    bbox = np.empty((n, 4), np.int64)
    first = np.empty(n, np.int64)
    for c in range(n):
        holes[c] = 1
        first[c] = -1
    for r in range(nr):
        c = lab[r]
        holes[c] -= 1
        if first[c] < 0:
            first[c] = r
            bbox[c, 0] = rx0[r]
            bbox[c, 1] = ry[r]
            bbox[c, 2] = rx1[r] - 1
            bbox[c, 3] = ry[r]
        else:
            if rx0[r] < bbox[c, 0]:
                bbox[c, 0] = rx0[r]
            if rx1[r] - 1 > bbox[c, 2]:
                bbox[c, 2] = rx1[r] - 1
            bbox[c, 3] = ry[r]  # runs come in row order
    for y in range(1, h):
        i, i1 = np.int64(row_start[y - 1]), np.int64(row_start[y])  # (int64: _root's one signature)
        j, j1 = np.int64(row_start[y]), np.int64(row_start[y + 1])
        while i < i1 and j < j1:
            if rx0[i] < rx1[j] and rx0[j] < rx1[i]:
                holes[lab[i]] += 1
            if rx1[i] <= rx1[j]:
                i += 1
            else:
                j += 1
    return lab, n, holes, bbox, first


@_entry
def _components_py(ry, rx0, rx1, row_start, h):
    """:func:`_components` of ``int64`` runs (:func:`slice_runs`, :class:`FortranRuns`), labels ``int64``."""
    lab = np.empty(len(ry), np.int32)
    lab, n, holes, bbox, first = _components(ry.astype(np.int32), rx0.astype(np.int32), rx1.astype(np.int32),
                                             row_start.astype(np.int32), h, lab)
    return lab.astype(np.int64), n, holes, bbox, first


def slice_components(mask2d):
    """4-connected components of a 2D mask from its runs: ``(runs, labels, n, holes, bbox)``."""
    ry, rx0, rx1, rs = slice_runs(mask2d)
    lab, n, holes, bbox, _ = _components_py(ry, rx0, rx1, rs, np.asarray(mask2d).shape[0])
    return (ry, rx0, rx1, rs), lab, n, holes, bbox


@njit(cache=True, nogil=True)
def _paint_labels(ry, rx0, rx1, lab, h, w):
    """The label image of the runs: component ``lab[r]`` of run ``r`` as ``lab[r] + 1``, 0 elsewhere.
    Each run is set as one slice of its row (a fill the compiler makes a block store; a loop over
    its pixels took a socket slice of 512 x 512 some four times as long): the same image."""
    out = np.zeros((h, w), np.int32)
    for r in range(len(ry)):
        out[ry[r], rx0[r]: rx1[r]] = lab[r] + 1
    return out


def slice_labels(mask2d, runs=False):
    """``scipy.ndimage.label(mask2d)`` (4-connected, int32 labels in raster order of each component's
    first pixel) and ``find_objects`` of it, from the runs in compiled code: ``(labels, n, objects)``,
    and with ``runs`` the runs too, ``(ry, rx0, rx1, label)`` (int64, raster order: run ``r`` the
    pixels ``[ry[r], rx0[r]: rx1[r]]`` of label ``label[r]``, as
    :func:`contourmesh.tracing.slice_cracks` takes them)."""
    m = np.ascontiguousarray(mask2d, dtype=bool)
    (ry, rx0, rx1, rs), lab, n, _, bbox = slice_components(m)
    return _labels_of(ry, rx0, rx1, rs, lab, n, bbox, m.shape, runs)


def runs_labels(scanned, shape, runs=False):
    """:func:`slice_labels` of a mask of ``shape`` from its runs ``scanned`` (``(ry, rx0, rx1,
    row_start)`` as :func:`slice_runs` gives them, e.g. by :class:`FortranRuns`): the same labels,
    objects and runs, without the mask."""
    ry, rx0, rx1, rs = scanned
    lab, n, _, bbox, _ = _components_py(ry, rx0, rx1, rs, shape[0])
    return _labels_of(ry, rx0, rx1, rs, lab, n, bbox, shape, runs)


def _labels_of(ry, rx0, rx1, rs, lab, n, bbox, shape, runs):
    labels = _paint_labels(ry, rx0, rx1, lab, shape[0], shape[1])
    objects = [(slice(int(b[1]), int(b[3]) + 1), slice(int(b[0]), int(b[2]) + 1)) for b in bbox.tolist()]
    if runs:
        return labels, int(n), objects, (ry, rx0, rx1, lab + 1)
    return labels, int(n), objects


# ------------------------------------------------------------------------------------------------
# 3. the outer Jordan contour of one component
# ------------------------------------------------------------------------------------------------
def _next_direction_table():
    """``_NEXT_DIR[512 * d + mask]``: the direction leaving a boundary vertex entered with
    direction ``d`` (0 = +x, 1 = +y, 2 = -x, 3 = -y), given the 3 x 3 pixels around the vertex
    as a 9-bit ``mask`` (bit ``3 j + i`` = pixel ``(vx - 1 + i, vy - 1 + j)``).

    The cell with lower-left corner ``(x, y)`` is in ``U`` when one of the pixels ``(x..x+1,
    y..y+1)`` is set; of the boundary edges leaving the vertex (``U`` on the left) the first among
    *turn left, go straight, turn right* wins (as :func:`contourmesh.tracing._follow_boundaries`).
    Built once with numpy at import (no compilation); 2 KiB.
    """
    table = np.empty(4 * 512, np.uint8)
    for mask in range(512):
        a00, a10, a20, a01, a11, a21, a02, a12, a22 = ((mask >> b) & 1 == 1 for b in range(9))
        ll = a00 or a10 or a01 or a11   # cell with lower-left corner (vx-1, vy-1)
        lr = a10 or a20 or a11 or a21   # (vx, vy-1)
        ul = a01 or a11 or a02 or a12   # (vx-1, vy)
        ur = a11 or a21 or a12 or a22   # (vx, vy)
        edge = (ur and not lr, ul and not ur, ll and not ul, lr and not ll)  # +x, +y, -x, -y
        for d in range(4):
            nd = d
            for t in (1, 0, 3):
                if edge[(d + t) % 4]:
                    nd = (d + t) % 4
                    break
            table[512 * d + mask] = nd
    return table


_NEXT_DIR = _next_direction_table()


@_kernel
def _trace_outer(img, base, hh, ww, ox, oy, sx, sy):
    """Boundary of ``U`` (closed cells with a corner in the pixels of ``img``), from vertex ``(sx, sy)``.

    ``img[base + (y - oy) * ww + (x - ox)]`` is pixel ``(x, y)`` for ``0 <= x - ox < ww`` and
    ``0 <= y - oy < hh`` (outside: background).  Point ``(x, y)`` is a pixel centre; the cell with
    lower-left corner ``(x, y)`` is in ``U`` when one of the pixels ``(x..x+1, y..y+1)`` is set.
    The walk starts with a ``+x`` step at the lowest-then-leftmost vertex and takes, at every
    vertex, the first boundary edge among *turn left, go straight, turn right*
    (:data:`_NEXT_DIR`, as :func:`contourmesh.tracing._follow_boundaries`).  Only the 3 x 3
    pixels around each boundary vertex are read.
    """
    cap = 1024
    pts = np.empty((cap, 2), np.int64)
    n = 0
    vx = sx
    vy = sy
    d = 0  # +x
    while True:
        if n == cap:
            # grow outside the walk below, so that the walk never rebinds ``pts``
            cap *= 2
            q = np.empty((cap, 2), np.int64)
            for i in range(n):
                q[i, 0] = pts[i, 0]
                q[i, 1] = pts[i, 1]
            pts = q
        while n < cap:
            pts[n, 0] = vx
            pts[n, 1] = vy
            n += 1
            if d == 0:
                vx += 1
            elif d == 1:
                vy += 1
            elif d == 2:
                vx -= 1
            else:
                vy -= 1
            mask = 0
            for j in range(3):
                yy = vy - 1 + j - oy
                if 0 <= yy < hh:
                    row = base + yy * ww - ox
                    for i in range(3):
                        xx = vx - 1 + i
                        if 0 <= xx - ox < ww and img[row + xx] != 0:
                            mask |= 1 << (3 * j + i)
            d = np.int64(_NEXT_DIR[512 * d + mask])
            if vx == sx and vy == sy and d == 0:
                return pts[:n]


@_entry
def _trace_outer_py(img, base, hh, ww, ox, oy, sx, sy):
    return _trace_outer(img, base, hh, ww, ox, oy, sx, sy)


@_kernel
def _stack_intervals(ry, rx0, rx1, order, t0, t1):
    """The intervals ``[lo[i], hi[i]]`` of lattice x of a stack of runs ``order[t0:t1]`` (one run per
    row, rows consecutive) between heights ``y0 + i`` and ``y0 + i + 1`` (``y0`` the bottom edge's):
    the union of the cells of the rows below and above, as corner coordinates.  Returns
    ``(y0, lo, hi)``, ``m + 1`` intervals for ``m`` rows."""
    m = t1 - t0
    y0 = ry[order[t0]] - 1
    lo = np.empty(m + 1, np.int64)
    hi = np.empty(m + 1, np.int64)
    for i in range(m + 1):
        if i == 0:
            r = order[t0]
            a = rx0[r] - 1
            b = rx1[r]
        else:
            r = order[t0 + i - 1]
            a = rx0[r] - 1
            b = rx1[r]
            if i < m:
                r = order[t0 + i]
                if rx0[r] - 1 < a:
                    a = rx0[r] - 1
                if rx1[r] > b:
                    b = rx1[r]
        lo[i] = a
        hi[i] = b
    return y0, lo, hi


@_kernel
def _trace_runs(ry, rx0, rx1, order, t0, t1):
    """The contour :func:`_trace_outer` walks, written from the runs when the component has one
    run in each of its rows (``order[t0:t1]``, rows ascending), without reading a pixel; else an
    empty array (the walk is needed).

    Run ``r`` puts the rectangle ``[rx0 - 1, rx1] x [ry - 1, ry + 1]`` into ``U``, so the cells
    between heights ``y`` and ``y + 1`` span one interval ``[L, R]`` (the union of the rectangles
    of rows ``y`` and ``y + 1``, which overlap in a 4-connected component): ``U`` is a stack of
    intervals, without the pinches where the walk's turning rule decides.  Its boundary, from the
    lowest-then-leftmost vertex counterclockwise, is the bottom edge, the right side (one unit up
    per interval, then along to the next interval's end), the top edge and the left side down,
    every lattice point on the way listed once, as the walk lists them.
    """
    m = t1 - t0
    if m <= 0:
        return np.empty((0, 2), np.int64)
    for t in range(t0 + 1, t1):
        if ry[order[t]] != ry[order[t - 1]] + 1:
            return np.empty((0, 2), np.int64)
    y0, lo, hi = _stack_intervals(ry, rx0, rx1, order, t0, t1)  # interval i: y0 + i .. y0 + i + 1
    n = (hi[0] - lo[0]) + (hi[m] - lo[m]) + 2 * (m + 1)
    for i in range(m):
        n += abs(hi[i + 1] - hi[i]) + abs(lo[i + 1] - lo[i])
    pts = np.empty((n, 2), np.int64)
    q = 0
    for x in range(lo[0], hi[0]):  # bottom, +x
        pts[q, 0] = x
        pts[q, 1] = y0
        q += 1
    for i in range(m + 1):  # right side, up
        pts[q, 0] = hi[i]
        pts[q, 1] = y0 + i
        q += 1
        y = y0 + i + 1
        if i < m:
            if hi[i + 1] > hi[i]:
                for x in range(hi[i], hi[i + 1]):
                    pts[q, 0] = x
                    pts[q, 1] = y
                    q += 1
            else:
                for x in range(hi[i], hi[i + 1], -1):
                    pts[q, 0] = x
                    pts[q, 1] = y
                    q += 1
    for x in range(hi[m], lo[m], -1):  # top, -x
        pts[q, 0] = x
        pts[q, 1] = y0 + m + 1
        q += 1
    for i in range(m, -1, -1):  # left side, down
        pts[q, 0] = lo[i]
        pts[q, 1] = y0 + i + 1
        q += 1
        y = y0 + i
        if i > 0:
            if lo[i - 1] < lo[i]:
                for x in range(lo[i], lo[i - 1], -1):
                    pts[q, 0] = x
                    pts[q, 1] = y
                    q += 1
            else:
                for x in range(lo[i], lo[i - 1]):
                    pts[q, 0] = x
                    pts[q, 1] = y
                    q += 1
    return pts


@_entry
def _trace_runs_py(ry, rx0, rx1, order, t0, t1):
    return _trace_runs(ry.astype(np.int32), rx0.astype(np.int32), rx1.astype(np.int32), order, t0, t1)


@_kernel
def _stack_point(cand, kind, m, wst, px, py, cx, cy, nx, ny, il, ih, y0, mr):
    """The candidates of contour point ``c`` (after ``p``, before ``n``) of a stack, written from
    ``cand[m]`` on: its turn (C or B) and the W among its two inner corners ``c + left`` and
    ``c + step + left``; returns the new ``m``.  ``wst`` = (a W written yet, its x, its y): a W
    equal to the last one is dropped.  The W test is :func:`_stack_candidates`'s."""
    ix, iy = cx - px, cy - py  # incoming step
    sx, sy = nx - cx, ny - cy  # outgoing step
    turn = ix * sy - iy * sx
    if turn != 0:
        cand[m, 0] = cx
        cand[m, 1] = cy
        kind[m] = 0 if turn > 0 else -1
        m += 1
    qx, qy = cx - sy, cy + sx
    for j in range(2):
        i = qy - 1 - y0  # the rows of the cells below and above q: i and i + 1
        if 0 <= i and i < mr and il[i] < qx and qx < ih[i] and not (wst[0] != 0 and qx == wst[1] and qy == wst[2]):
            cand[m, 0] = qx
            cand[m, 1] = qy
            kind[m] = 1
            m += 1
            wst[0] = 1
            wst[1] = qx
            wst[2] = qy
        qx += sx
        qy += sy
    return m


@_kernel
def _stack_candidates(ry, rx0, rx1, order, t0, t1):
    """Step 1 of the MLP (:func:`contourmesh.polygons.mlp._mlp_grid`) for the contour that
    :func:`_trace_runs` writes for the stack ``order[t0:t1]``, without the contour's array and
    without the grids: ``(start, cand, kind, m)``, ``start`` the contour's first point (a ``(1, 2)``
    array: :func:`~contourmesh.polygons.mlp._mlp_pull` reads only that point of the contour) and
    the candidates ``cand[:m]``, ``kind[:m]``; ``m == -1`` when the runs are not a stack (their
    rows not consecutive: the walk over the pixels is needed).

    The points are visited in :func:`_trace_runs`'s order (its loops, each point handed to
    :func:`_stack_point` when the next one is known; the first point's predecessor is the
    contour's last point ``(lo[0], y0 + 1)``, and the last point is followed by the first).

    The grids decide whether an inner corner ``q`` of a contour step is a W: ``q`` not on the
    contour and no cell around it right of a step.  ``q`` is a corner of the cell left of the step,
    which is in ``U``; were another cell around ``q`` outside ``U``, an edge at ``q`` would part the
    two, so ``q`` would be on the boundary of ``U``, which for a stack is this one contour; and a
    point of the contour has a cell around it outside ``U``.  So ``q`` is a W exactly when its four
    cells are in ``U``: rows ``q_y - 1`` and ``q_y`` of the stack's intervals (as
    :func:`_trace_runs` makes them) both hold the cells ``q_x - 1`` and ``q_x``, i.e. ``il[i] < q_x
    < ih[i]`` with the larger of the two rows' lows and the smaller of their highs.  For the 512^3
    ball's 785k contour points: a tenth of the time of the grids, which write, read and clear five
    bytes of two slice-sized images per point.  (tests/test_fastpath.py keeps the earlier form that
    read the points of :func:`_trace_runs`'s array, and compares.)
    """
    start = np.empty((1, 2), np.int64)
    for t in range(t0 + 1, t1):
        if ry[order[t]] != ry[order[t - 1]] + 1:
            return start, np.empty((0, 2), np.int64), np.empty(0, np.int64), np.int64(-1)
    mr = t1 - t0
    y0, lo, hi = _stack_intervals(ry, rx0, rx1, order, t0, t1)  # interval i: y0 + i .. y0 + i + 1
    n = (hi[0] - lo[0]) + (hi[mr] - lo[mr]) + 2 * (mr + 1)  # the contour's points (_trace_runs)
    for i in range(mr):
        n += abs(hi[i + 1] - hi[i]) + abs(lo[i + 1] - lo[i])
    # q = (qx, y0 + i + 1) has its four cells in U when il[i] < qx < ih[i]: the cells qx - 1 and qx
    # in the intervals i and i + 1 both (lo[i] < qx < hi[i] and lo[i + 1] < qx < hi[i + 1])
    il = np.empty(mr, np.int64)
    ih = np.empty(mr, np.int64)
    for i in range(mr):
        il[i] = lo[i] if lo[i] > lo[i + 1] else lo[i + 1]
        ih[i] = hi[i] if hi[i] < hi[i + 1] else hi[i + 1]
    cand = np.empty((3 * n, 2), np.int64)
    kind = np.empty(3 * n, np.int64)
    wst = np.empty(3, np.int64)
    wst[0] = 0
    wst[1] = 0
    wst[2] = 0
    m = np.int64(0)
    start[0, 0] = lo[0]
    start[0, 1] = y0
    # a, b: the last two points met; b's candidates are written when the point after it comes
    ax, ay = lo[0], y0 + 1  # the contour's last point (the end of the left side)
    bx, by = lo[0], y0  # its first point
    for x in range(lo[0] + 1, hi[0]):  # bottom, +x (after the first point)
        m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y0, il, ih, y0, mr)
        ax, ay, bx, by = bx, by, x, y0
    for i in range(mr + 1):  # right side, up
        x, y = hi[i], y0 + i
        m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
        ax, ay, bx, by = bx, by, x, y
        y = y0 + i + 1
        if i < mr:
            if hi[i + 1] > hi[i]:
                for x in range(hi[i], hi[i + 1]):
                    m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
                    ax, ay, bx, by = bx, by, x, y
            else:
                for x in range(hi[i], hi[i + 1], -1):
                    m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
                    ax, ay, bx, by = bx, by, x, y
    y = y0 + mr + 1
    for x in range(hi[mr], lo[mr], -1):  # top, -x
        m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
        ax, ay, bx, by = bx, by, x, y
    for i in range(mr, -1, -1):  # left side, down
        x, y = lo[i], y0 + i + 1
        m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
        ax, ay, bx, by = bx, by, x, y
        y = y0 + i
        if i > 0:
            if lo[i - 1] < lo[i]:
                for x in range(lo[i], lo[i - 1], -1):
                    m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
                    ax, ay, bx, by = bx, by, x, y
            else:
                for x in range(lo[i], lo[i - 1]):
                    m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, x, y, il, ih, y0, mr)
                    ax, ay, bx, by = bx, by, x, y
    m = _stack_point(cand, kind, m, wst, ax, ay, bx, by, lo[0], y0, il, ih, y0, mr)  # the last point
    return start, cand, kind, m


def outer_jordan_contour(mask2d) -> np.ndarray:
    """The outer contour of the outer Jordan digitization of a 2D mask (one 4-component).

    Equal to the outer contour of :func:`contourmesh.tracing.trace_contours` for that mask.
    """
    m = np.ascontiguousarray(mask2d, dtype=bool)
    if m.ndim != 2 or not m.any():
        raise ValueError(f"mask must be a non-empty 2D array indexed [y, x]; got shape {m.shape}")
    ys, xs = np.nonzero(m)
    y0 = ys.min()
    x0 = xs[ys == y0].min()
    h, w = m.shape
    return _trace_outer_py(m.reshape(-1).view(np.uint8), 0, h, w, 0, 0, int(x0) - 1, int(y0) - 1)


# ------------------------------------------------------------------------------------------------
# 4. the MLP of each contour (Klette & Yip: the kernel of contourmesh.polygons.mlp), per slice
# ------------------------------------------------------------------------------------------------
@njit(cache=True, no_cfunc_wrapper=True, **_OPTIONS)
def _slice_polygons(b8, b64, base, h, w, aligned, seen, on, bg):
    """Steps 1-4 for one slice (:func:`_slice_polygons_k`) in new arrays, callable from Python."""
    ry, rx0, rx1, rs, bad = _scan_new(b8, b64, base, h, w, aligned, np.int64(0))
    return _slice_polygons_k(b8, base, h, w, seen, on, bg, ry, rx0, rx1, rs, bad, np.empty(len(ry), np.int32))


@njit(cache=True, no_cfunc_wrapper=True, **_OPTIONS)
def _slab_polygons(b8, b64, base, nk, h, w, aligned, seen, on, bg, ox, oy, dx, dy, zs, r32, p64, f64, stop):
    """Steps 1-4 for the ``nk`` slices starting at byte ``base`` in one call, their outputs packed (no Python, no call and no boxed arrays per slice).

    ``stop``: the pass ends at the first slice out of scope (``status`` or ``bad`` non-zero in its
    ``meta`` row, which the caller then declines): the later slices are not scanned and hold
    nothing (no run, component or vertex; zero row starts).  The fast path declines most real
    segmentations so, at a slice with a hole near one end (the bunny's sixth of 130 slices),
    after a pass over the whole volume that took 2 of the general mesher's 36 CPU-ms.  The slices
    before it are packed as without ``stop``.

    Returns ``(meta, ry, rx0, rx1, lab, row_start, bbox, poly, poly_start, degenerate, xyz)``:
    ``meta[k] = (n, status, bad, first run, first component, first polygon vertex)`` of slice k
    (with a last row holding the totals), the per-slice arrays of :func:`_slice_polygons_k`
    concatenated (``row_start`` as ``(nk, h + 1)``, ``poly_start`` with ``n + 1`` entries per
    slice; the runs, their labels and ``row_start`` as ``int32``, the rest ``int64``), and ``xyz`` the polygon vertices in physical coordinates ``(ox + x dx, oy + y dy,
    zs[k])``: the rings of the slices without degenerate MLPs.

    ``r32``, ``p64`` and ``f64`` are the room the packed arrays are written in (:func:`_pack_room`:
    kept by the calling thread from call to call), so the returned arrays may be views of them:
    ``row_start`` and then the runs, their labels in four equal parts of the rest of ``r32``, the
    polygon vertices in ``p64`` (two per vertex) and ``xyz`` in ``f64`` (three per vertex).
    Where a part is too small, that array is a new one (grown as before).  Each slice's runs and row
    starts are written by its scan (:func:`_scan_runs`) straight into the packed arrays at its
    offset, and its labels by :func:`_components`, so no per-slice array is made and copied in (a
    slice whose runs do not fit is scanned again into grown arrays: the same values).  The values written are
    the same either way; only the pages differ: a page of a new array costs its fault when first
    written, every call, while the kept room's pages are mapped once (for the 512^3 ball some
    1100 faults, 3-4 ms of the call).
    """
    meta = np.empty((nk + 1, 6), np.int64)
    nrs = nk * (h + 1)
    if len(r32) >= nrs:
        row_start = r32[:nrs].reshape((nk, h + 1))
    else:
        row_start = np.empty((nk, h + 1), np.int32)
    # Room for two runs per row and 256 polygon vertices per slice from the start (or all that
    # the kept room holds, when more): np.empty only maps the pages, and a page costs its fault
    # when first written, so room that is never used costs nothing, while each growth (a new
    # array, the old contents copied in) touches the pages of the old contents once more.  The
    # runs are int32 (the caller keeps h * w below 2^31).
    rcap = (len(r32) - nrs) // 4 if len(r32) >= nrs else 0
    if rcap >= 64:
        ry = r32[nrs: nrs + rcap]
        rx0 = r32[nrs + rcap: nrs + 2 * rcap]
        rx1 = r32[nrs + 2 * rcap: nrs + 3 * rcap]
        lab = r32[nrs + 3 * rcap: nrs + 4 * rcap]
    else:
        rcap = 2 * nk * h
        if rcap < 64:
            rcap = 64
        ry = np.empty(rcap, np.int32)
        rx0 = np.empty(rcap, np.int32)
        rx1 = np.empty(rcap, np.int32)
        lab = np.empty(rcap, np.int32)
    ccap = 8
    pcap = len(p64) // 2
    if pcap >= 64:
        poly = p64[: 2 * pcap].reshape((pcap, 2))
    else:
        pcap = 256 * nk
        if pcap < 64:
            pcap = 64
        poly = np.empty((pcap, 2), np.int64)
    bbox = np.empty(4 * ccap, np.int64)
    deg = np.empty(ccap, np.int64)
    pst = np.empty(ccap + nk, np.int64)
    nr = 0
    nc = 0
    npv = 0
    for k in range(nk):
        # the slice's runs and row starts scanned straight into the packed arrays at its offset,
        # its labels written after them (grown, the runs so far copied, where the room ends)
        sb = base + k * h * w
        while True:
            m, bad = _scan_runs(b8, b64, sb, h, w, aligned, row_start[k], ry[nr:], rx0[nr:], rx1[nr:], np.int64(0))
            if m >= 0:
                break
            rcap = 2 * rcap + w
            ry = _grow32(ry[:nr], rcap)
            rx0 = _grow32(rx0[:nr], rcap)
            rx1 = _grow32(rx1[:nr], rcap)
            lab = _grow32(lab[:nr], rcap)
        out = _slice_polygons_k(b8, sb, h, w, seen, on, bg, ry[nr: nr + m], rx0[nr: nr + m], rx1[nr: nr + m],
                                row_start[k], bad, lab[nr:])
        n, status, sbbox, spoly, sps, sdeg = out[5], out[6], out[7], out[8], out[9], out[10]
        meta[k, 0] = n
        meta[k, 1] = status
        meta[k, 2] = bad
        meta[k, 3] = nr
        meta[k, 4] = nc
        meta[k, 5] = npv
        nr += m
        if nc + n > ccap:
            ccap = 2 * ccap + n
            bbox = _grow(bbox, 4 * ccap)
            deg = _grow(deg, ccap)
            pst = _grow(pst, ccap + nk)
        for c in range(n):
            for j in range(4):
                bbox[4 * (nc + c) + j] = sbbox[c, j]
            deg[nc + c] = sdeg[c]
        for c in range(n + 1):
            pst[nc + k + c] = sps[c]
        nc += n
        q = len(spoly)
        if npv + q > pcap:
            pcap = 2 * pcap + q
            grown = np.empty((pcap, 2), np.int64)
            for i in range(npv):
                grown[i, 0] = poly[i, 0]
                grown[i, 1] = poly[i, 1]
            poly = grown
        for i in range(q):
            poly[npv + i, 0] = spoly[i, 0]
            poly[npv + i, 1] = spoly[i, 1]
        npv += q
        if stop and (status != 0 or bad != 0):
            for k2 in range(k + 1, nk):
                meta[k2, 0] = 0
                meta[k2, 1] = 0
                meta[k2, 2] = 0
                meta[k2, 3] = nr
                meta[k2, 4] = nc
                meta[k2, 5] = npv
                for y in range(h + 1):
                    row_start[k2, y] = 0
                pst[nc + k2] = 0
            break
    meta[nk, 0] = 0
    meta[nk, 1] = 0
    meta[nk, 2] = 0
    meta[nk, 3] = nr
    meta[nk, 4] = nc
    meta[nk, 5] = npv
    if len(f64) >= 3 * npv:
        xyz = f64[: 3 * npv].reshape((npv, 3))
    else:
        xyz = np.empty((npv, 3), np.float64)
    for k in range(nk):
        for i in range(meta[k, 5], meta[k + 1, 5]):
            xyz[i, 0] = ox + np.float64(poly[i, 0]) * dx
            xyz[i, 1] = oy + np.float64(poly[i, 1]) * dy
            xyz[i, 2] = zs[k]
    return (meta, ry[:nr], rx0[:nr], rx1[:nr], lab[:nr], row_start, bbox[: 4 * nc], poly[:npv], pst[: nc + nk],
            deg[:nc], xyz)


@_kernel
def _slice_polygons_k(b8, base, h, w, seen, on, bg, ry, rx0, rx1, row_start, bad, lab):
    """Steps 2-4 for one slice whose runs ``ry, rx0, rx1, row_start`` (``int32``) and count of other
    bytes ``bad`` :func:`_scan_runs` found in the slice at byte ``base`` of ``b8``.

    Returns ``(ry, rx0, rx1, row_start, lab, n, status, bbox, poly, poly_start, degenerate, bad)``
    (the labels written in ``lab``'s first ``len(ry)`` items: :func:`_components`):
    ``status`` is 0 in scope, 1 when a component has a hole, 2 when two MLP vertices of the
    slice share a position.  ``poly[poly_start[c]:poly_start[c + 1]]`` is component ``c``'s MLP
    (pixel-centre coordinates); ``degenerate[c]`` marks MLPs without area (crack contour instead).
    ``seen`` (:func:`_seen_bits`: one bit per point of ``[-1, w + 1] x [-1, h + 1]``, zero, and zero
    again on return, reused across slices) detects shared positions: a bit map of 33 KiB for a
    512 x 512 slice stays in the cache, where the ``int64`` stamp image this replaced (2 MiB, a
    stamp id per slice) cost a cache miss per MLP vertex (9 ms of the 512^3 ball's 65).  ``on`` and
    ``bg`` (``(h + 6) * (w + 6)`` uint8, zero, reused across slices) are the MLP's grids.
    """
    lab, n, holes, bbox, first = _components(ry, rx0, rx1, row_start, h, lab)
    poly_start = np.empty(n + 1, np.int64)
    degenerate = np.empty(n, np.uint8)
    poly_start[0] = 0
    status = 0
    for c in range(n):
        degenerate[c] = 0
        poly_start[c + 1] = 0
    for c in range(n):
        if holes[c] != 0:
            status = 1
    if status != 0 or bad != 0:
        return ry, rx0, rx1, row_start, lab, n, status, bbox, np.empty((0, 2), np.int64), poly_start, degenerate, bad
    # runs of each component (counting sort by label)
    nr = len(ry)
    cnt = np.empty(n + 1, np.int64)
    for c in range(n + 1):
        cnt[c] = 0
    for r in range(nr):
        cnt[lab[r] + 1] += 1
    for c in range(n):
        cnt[c + 1] += cnt[c]
    order = np.empty(nr, np.int64)
    fill = np.empty(n, np.int64)
    for c in range(n):
        fill[c] = cnt[c]
    for r in range(nr):
        order[fill[lab[r]]] = r
        fill[lab[r]] += 1
    cap = 64
    poly = np.empty((cap, 2), np.int64)
    total = 0
    outer = np.int64(1)  # the MLP of an outer contour (an int64, not a literal: see _kernel)
    mthree = np.int64(-3)  # the MLP grids' origin: contour vertices lie in [-1, w] x [-1, h]
    for c in range(n):
        # one run per row: the contour from the runs; else the walk over the pixels
        start, cand, kind, mc = _stack_candidates(ry, rx0, rx1, order, cnt[c], cnt[c + 1])
        if mc >= 0:
            _, _, p = _mlp_pull(start, cand, kind, mc, outer)
        else:
            if n == 1:
                # the slice itself is the component's image
                img, ibase, ih, iw, ox, oy = b8, base, h, w, 0, 0
            else:
                # the component's runs painted into a local image around its bbox
                ox, oy = bbox[c, 0], bbox[c, 1]
                iw = bbox[c, 2] - ox + 1
                ih = bbox[c, 3] - oy + 1
                img = np.empty(ih * iw, np.uint8)
                for q in range(ih * iw):
                    img[q] = 0
                ibase = 0
                for t in range(cnt[c], cnt[c + 1]):
                    r = order[t]
                    row = (ry[r] - oy) * iw - ox
                    for x in range(rx0[r], rx1[r]):
                        img[row + x] = 1
            r = first[c]
            cc = _trace_outer(img, ibase, ih, iw, ox, oy, rx0[r] - 1, ry[r] - 1)
            _, _, p = _mlp_grid(cc, outer, on, bg, mthree, mthree, w + 6)
        k = len(p)
        a2 = 0
        for i in range(k):
            j = i + 1 if i + 1 < k else 0
            a2 += p[i, 0] * p[j, 1] - p[j, 0] * p[i, 1]
        if k < 3 or a2 == 0:
            degenerate[c] = 1
            poly_start[c + 1] = total
            continue
        if total + k > cap:
            cap = 2 * cap + k
            q = np.empty((cap, 2), np.int64)
            for i in range(total):
                q[i, 0] = poly[i, 0]
                q[i, 1] = poly[i, 1]
            poly = q
        for i in range(k):
            poly[total + i, 0] = p[i, 0]
            poly[total + i, 1] = p[i, 1]
        if _mark_seen(seen, p, k, w):
            status = 2
        total += k
        poly_start[c + 1] = total
    _clear_seen(seen, poly, np.int64(total), w)  # (an int64 value: total may be the literal 0)
    return ry, rx0, rx1, row_start, lab, n, status, bbox, poly[:total], poly_start, degenerate, bad


@_kernel
def _mark_seen(seen, p, k, w):
    """Sets the bits of the points ``p[:k]`` in the bit map ``seen`` of :func:`_slice_polygons_k`
    (slice width ``w``); True when one of them was set already (two vertices share a position)."""
    shared = False
    for i in range(k):
        q = (p[i, 1] + 1) * (w + 3) + p[i, 0] + 1
        bit = _ONE << np.uint64(q & 63)
        if seen[q >> 6] & bit:
            shared = True
        seen[q >> 6] |= bit
    return shared


@_kernel
def _clear_seen(seen, p, k, w):
    """The bit map ``seen`` back to zero after :func:`_mark_seen` of the points ``p[:k]`` (their
    words: every bit set in them is one of theirs)."""
    for i in range(k):
        seen[((p[i, 1] + 1) * (w + 3) + p[i, 0] + 1) >> 6] = _ZERO


@njit(cache=True, no_cfunc_wrapper=True, **_OPTIONS)
def _pixels_mlp(img, h, w):
    """Steps 3-4 for one pixel set (any connectivity whose ``U`` is connected, such as a
    4-component or a hole's 8-component): the MLP of the outer contour of ``U`` (pixel-centre
    coordinates, local to the image) and twice its signed area.  ``img`` is the ``(h, w)`` set as
    ``uint8`` bytes in raster order, not empty."""
    q = 0
    while img[q] == 0:
        q += 1
    zero = np.int64(0)  # not a literal 0, which would compile _trace_outer once more (see _kernel)
    cc = _trace_outer(img, zero, h, w, zero, zero, q % w - 1, q // w - 1)
    _, _, p = _mlp(cc, np.int64(1))
    k = len(p)
    a2 = 0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        a2 += p[i, 0] * p[j, 1] - p[j, 0] * p[i, 1]
    return p, a2


def pixels_mlp(pixels):
    """The general mesher's MLP of a pixel set (the outer Jordan construction with these pixels as
    ``I``), in compiled code: ``(p, 2)`` int64 pixel-centre coordinates, or ``None`` where the MLP
    encloses no area (a part one pixel wide: a segment or a point)."""
    m = np.ascontiguousarray(pixels, dtype=bool)
    if m.ndim != 2 or not m.any():
        raise ValueError(f"pixels must be a non-empty 2D array indexed [y, x]; got shape {m.shape}")
    h, w = m.shape
    p, a2 = _pixels_mlp(m.reshape(-1).view(np.uint8), h, w)
    if len(p) < 3 or a2 == 0:
        return None
    return p


@njit(cache=True, **_OPTIONS)
def _slice_mlps(lab, boxes):
    """:func:`_pixels_mlp` of every component of a label image (``c + 1`` for component ``c``, in
    ``boxes[c] = (y0, y1, x0, x1)``, stops exclusive), each on its cropped mask as
    :func:`pixels_mlp` reads it: the concatenated MLP vertices (pixel-centre coordinates local to
    the component's box), the start of each component's and twice their signed areas."""
    n = boxes.shape[0]
    size = 1
    for c in range(n):
        size = max(size, (boxes[c, 1] - boxes[c, 0]) * (boxes[c, 3] - boxes[c, 2]))
    buf = np.empty(size, np.uint8)
    ps = np.empty(n + 1, np.int64)
    a2s = np.empty(n, np.int64)
    cap = 64
    out = np.empty((cap, 2), np.int64)
    pos = 0
    for c in range(n):
        y0, y1, x0, x1 = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
        hh, ww = y1 - y0, x1 - x0
        v = c + 1
        for j in range(hh):
            for i in range(ww):
                buf[j * ww + i] = 1 if lab[y0 + j, x0 + i] == v else 0
        p, a2 = _pixels_mlp(buf[: hh * ww], hh, ww)
        k = len(p)
        if pos + k > cap:
            cap = max(2 * cap, pos + k)
            out2 = np.empty((cap, 2), np.int64)
            out2[:pos] = out[:pos]
            out = out2
        ps[c] = pos
        out[pos: pos + k] = p
        pos += k
        a2s[c] = a2
    ps[n] = pos
    return out[:pos], ps, a2s


@njit(cache=True, **_OPTIONS)
def _slice_mlps_runs(boxes, ry, rx0, rx1, rlab):
    """:func:`_slice_mlps` from the slice's runs (``ry``, ``rx0``, ``rx1`` and the component's label
    ``rlab`` per run, as :func:`slice_labels` gives them with ``runs``): each component's cropped
    mask is cleared and its runs set, instead of comparing every label of its box (the same bytes:
    a component's pixels are its runs), then traced as there.  The same three arrays."""
    n = boxes.shape[0]
    nr = ry.shape[0]
    # the runs of each component in raster order (a counting sort by label): those of label v are
    # order[at[v]: at[v + 1]]
    at = np.empty(n + 2, np.int64)
    for v in range(n + 2):
        at[v] = 0
    for r in range(nr):
        at[rlab[r]] += 1
    for v in range(1, n + 2):
        at[v] += at[v - 1]
    order = np.empty(nr, np.int64)
    for i in range(nr):
        r = nr - 1 - i
        at[rlab[r]] -= 1
        order[at[rlab[r]]] = r
    size = 1
    for c in range(n):
        size = max(size, (boxes[c, 1] - boxes[c, 0]) * (boxes[c, 3] - boxes[c, 2]))
    buf = np.empty(size, np.uint8)
    ps = np.empty(n + 1, np.int64)
    a2s = np.empty(n, np.int64)
    cap = 64
    out = np.empty((cap, 2), np.int64)
    pos = 0
    for c in range(n):
        y0, y1, x0, x1 = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
        hh, ww = y1 - y0, x1 - x0
        # (the box cleared and each run set as one slice: block stores, where a loop over the
        # pixels took several times as long on large components; the same bytes)
        buf[: hh * ww] = 0
        for t in range(at[c + 1], at[c + 2]):
            r = order[t]
            base = (ry[r] - y0) * ww - x0
            buf[base + rx0[r]: base + rx1[r]] = 1
        p, a2 = _pixels_mlp(buf[: hh * ww], hh, ww)
        k = len(p)
        if pos + k > cap:
            cap = max(2 * cap, pos + k)
            out2 = np.empty((cap, 2), np.int64)
            for i in range(pos):
                out2[i, 0] = out[i, 0]
                out2[i, 1] = out[i, 1]
            out = out2
        ps[c] = pos
        for i in range(k):
            out[pos + i, 0] = p[i, 0]
            out[pos + i, 1] = p[i, 1]
        pos += k
        a2s[c] = a2
    ps[n] = pos
    return out[:pos], ps, a2s


def slice_mlps_flat(labels, boxes, runs=None):
    """:func:`pixels_mlp` of every component of a slice's int32 label image at once (``boxes`` as
    :func:`contourmesh.tracing.slice_boxes`): ``(pts, ps, a2s)``, the components' MLP vertices
    (pixel-centre coordinates local to each box) concatenated, component ``c``'s ``pts[ps[c]:
    ps[c + 1]]``; a component whose MLP has fewer than three vertices or ``a2s[c] == 0`` encloses no
    area (``pixels_mlp`` gives ``None`` there).  ``runs``: the labels' runs ``(ry, rx0, rx1, label)``
    as :func:`slice_labels` gives them, from which the components' masks are made
    (:func:`_slice_mlps_runs`: no label of a box read; on the liver's slices, their label images no
    longer in cache, half the time of comparing every label of each box, and less gained where the
    image was just painted, as in :class:`contourmesh.volumes._Slice`)."""
    if runs is not None:
        return _slice_mlps_runs(boxes, *runs)
    return _slice_mlps(np.ascontiguousarray(labels, dtype=np.int32), boxes)


def slice_polygons(mask2d):
    """MLPs of the 4-components of a 2D mask (the full mesher's ``"mlp"`` rings, in pixel-centre
    coordinates): ``(polygons, degenerate, holes)`` with ``polygons[c]`` a ``(p, 2)`` int64 array."""
    m = np.ascontiguousarray(mask2d, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2D array indexed [y, x]; got shape {m.shape}")
    b8 = m.reshape(-1).view(np.uint8)
    b64, aligned = _words(b8)
    h, w = m.shape
    grids = np.zeros(2 * (h + 6) * (w + 6), np.uint8)
    out = _slice_polygons(b8, b64, 0, h, w, aligned, _seen_bits(h, w), grids[: (h + 6) * (w + 6)],
                          grids[(h + 6) * (w + 6):])
    n, status, poly, ps, deg = out[5], out[6], out[8], out[9], out[10]
    if status == 1:
        raise ValueError("a component of the mask has a hole; slice_polygons handles hole-free components only")
    return [poly[ps[c]: ps[c + 1]] for c in range(n)], deg.astype(bool)


# ------------------------------------------------------------------------------------------------
# 5. joins between consecutive slices
# ------------------------------------------------------------------------------------------------
@_kernel
def _pair_joins(ary, ax0, ax1, ars, alab, na, bry, bx0, bx1, brs, blab, nb, h):
    """Partners of the components of slices k (A) and k + 1 (B).

    Returns ``(ok, partner_a, partner_b)``; ``ok`` is True when every group is one component on
    each side whose overlap ``O`` is connected and hole-free (a simple band join), i.e. when
    each component overlaps at most one of the other slice and ``chi(O) = #components(O) = 1``.
    """
    pa = np.empty(na, np.int64)
    pb = np.empty(nb, np.int64)
    for a in range(na):
        pa[a] = -1
    for b in range(nb):
        pb[b] = -1
    cap = 64
    oy = np.empty(cap, np.int32)  # (int32 as the slices' runs: _components' one signature)
    o0 = np.empty(cap, np.int32)
    o1 = np.empty(cap, np.int32)
    oc = np.empty(cap, np.int64)
    ors = np.empty(h + 1, np.int32)  # (int32 as the slices' row starts: _components' one signature)
    no = 0
    ok = True
    for y in range(h):
        ors[y] = no
        i, i1 = ars[y], ars[y + 1]
        j, j1 = brs[y], brs[y + 1]
        if cap - no < (i1 - i) + (j1 - j):
            cap = 2 * cap + (i1 - i) + (j1 - j)
            oy = _grow32(oy, cap)
            o0 = _grow32(o0, cap)
            o1 = _grow32(o1, cap)
            oc = _grow(oc, cap)
        while i < i1 and j < j1:
            lo = ax0[i] if ax0[i] > bx0[j] else bx0[j]
            hi = ax1[i] if ax1[i] < bx1[j] else bx1[j]
            if lo < hi:
                a = alab[i]
                b = blab[j]
                if pa[a] < 0:
                    pa[a] = b
                elif pa[a] != b:
                    ok = False
                if pb[b] < 0:
                    pb[b] = a
                elif pb[b] != a:
                    ok = False
                oy[no] = y
                o0[no] = lo
                o1[no] = hi
                oc[no] = a
                no += 1
            if ax1[i] <= bx1[j]:
                i += 1
            else:
                j += 1
        if not ok:
            return False, pa, pb
    ors[h] = no
    # the overlap of each pair: its 4-components and their holes, as for a slice (step 2); each
    # overlap component lies in one component a, which must get exactly one, without holes
    _, nc, oholes, _, ofirst = _components(oy[:no], o0[:no], o1[:no], ors, h, np.empty(no, np.int32))
    count = np.empty(na, np.int64)
    for a in range(na):
        count[a] = 0
    for c in range(nc):
        count[oc[ofirst[c]]] += 1
        if oholes[c] != 0:
            ok = False
    for a in range(na):
        if pa[a] >= 0 and count[a] != 1:
            ok = False
    return ok, pa, pb


@_kernel
def _stack_join(ry, rx0, rx1, a0, a1, b1):
    """:func:`_pair_joins` for two slices of one component each (runs ``a0:a1`` and ``a1:b1``)
    where it is decided from the runs alone: 1 when both slices have one run per row and their
    overlap is a stack (its rows consecutive, one run each, every run overlapping the one below:
    one component without holes, the case :func:`_components` takes without union-find), so the
    components join; 0 when they do not overlap; -1 otherwise (then :func:`_pair_joins`).

    The 512^3 ball's 500 slice pairs are all stacks: this walk takes about 1 ms of the 12 ms that
    :func:`_pair_joins` spends building and labelling their overlap runs."""
    for r in range(a0 + 1, a1):
        if ry[r] != ry[r - 1] + 1:
            return np.int64(-1)  # (rows in order: a row twice, or a gap, is not one run per row)
    for r in range(a1 + 1, b1):
        if ry[r] != ry[r - 1] + 1:
            return np.int64(-1)
    i = a0
    j = a1
    n = 0
    py = 0
    plo = 0
    phi = 0
    while i < a1 and j < b1:
        if ry[i] < ry[j]:
            i += 1
            continue
        if ry[j] < ry[i]:
            j += 1
            continue
        lo = rx0[i] if rx0[i] > rx0[j] else rx0[j]
        hi = rx1[i] if rx1[i] < rx1[j] else rx1[j]
        if lo < hi:
            if n > 0 and (ry[i] != py + 1 or lo >= phi or plo >= hi):
                return np.int64(-1)
            n += 1
            py = ry[i]
            plo = lo
            phi = hi
        i += 1
        j += 1
    return np.int64(1) if n > 0 else np.int64(0)


# ------------------------------------------------------------------------------------------------
# 6. bands (the paper's triangulation with the full mesher's twist guard)
# ------------------------------------------------------------------------------------------------
@njit(cache=True, no_cfunc_wrapper=True, **_OPTIONS)
def _pair_bands(ringA, startA, ringB, startB, pa, window):
    """:func:`_pair_bands_k`, callable from Python (:func:`_one_band`)."""
    return _pair_bands_k(ringA, startA, ringB, startB, pa, window)


@_kernel
def _pair_bands_k(ringA, startA, ringB, startB, pa, window):
    """Bands of every pair ``(a, pa[a])`` (in order of ``a``): concatenated local faces, the face
    offset of each band and a status per band.

    Band ``lo = ringA[a]`` -> ``hi = ringB[pa[a]]`` has faces indexing ``vstack([lo, hi])`` and
    status 0 when the paper's band passes the full mesher's twist guard, 1 when it is folded,
    twisted or too close to call (the caller redoes it with the full mesher's code).  One flat
    loop: the initial edge, the guard's fold and area tests are written inline (as kernels of
    their own each would be compiled separately, and optimized again here).
    """
    na = len(pa)
    nb = 0
    tot = 0
    for a in range(na):
        if pa[a] >= 0:
            nb += 1
            b = pa[a]
            tot += (startA[a + 1] - startA[a]) + (startB[b + 1] - startB[b])
    faces = np.empty((tot, 3), np.int64)
    foff = np.empty(nb + 1, np.int64)
    status = np.empty(nb, np.int64)
    foff[0] = 0
    t = 0
    for a in range(na):
        if pa[a] < 0:
            continue
        b = pa[a]
        lo = ringA[startA[a]: startA[a + 1]]
        hi = ringB[startB[b]: startB[b + 1]]
        n = len(lo)
        m = len(hi)
        # the paper's condition (i): C(1) has the fewer points (faces are flipped back if swapped)
        if n <= m:
            c1, c2, swapped = lo, hi, False
        else:
            c1, c2, swapped = hi, lo, True
        n1 = len(c1)
        n2 = len(c2)

        # section 3.2, the initial edge (as contourmesh.bands.wiederhold.initial_edge, same ties):
        # the point of C(2) nearest to c1[0], looked for first among the offsets 0, +1, -1, +2, ...
        # of a window around C(2)'s start, accepted inside the ball of radius 2 |z2 - z1| and
        # off the window's ends; otherwise the nearest of all
        px, py, pz = c1[0, 0], c1[0, 1], c1[0, 2]
        radius = 2.0 * abs(c2[0, 2] - pz)
        j0 = np.int64(0)  # (not a literal: kernels called with it would compile for the literal)
        found = False
        if n2 > 2 * window + 1:
            bd = 0.0
            bo = 0
            for q in range(2 * window + 1):
                off = 0 if q == 0 else ((q + 1) // 2 if q % 2 == 1 else -(q // 2))
                j = off % n2
                dx = c2[j, 0] - px
                dy = c2[j, 1] - py
                dz = c2[j, 2] - pz
                d2 = dx * dx + dy * dy + dz * dz
                if q == 0 or d2 < bd:
                    bd = d2
                    j0 = j
                    bo = off
            found = bd <= radius * radius and abs(bo) < window
        if not found:
            bd = -1.0
            for j in range(n2):
                dx = c2[j, 0] - px
                dy = c2[j, 1] - py
                dz = c2[j, 2] - pz
                d2 = dx * dx + dy * dy + dz * dz
                if bd < 0 or d2 < bd:
                    bd = d2
                    j0 = j
        # C(2) from its initial point; contiguous x and y of both (one signature of the kernel)
        r2 = np.empty((n2, 3), np.float64)
        x2 = np.empty(n2, np.float64)
        y2 = np.empty(n2, np.float64)
        for j in range(n2):
            k = j + j0 if j + j0 < n2 else j + j0 - n2
            r2[j, 0] = c2[k, 0]
            r2[j, 1] = c2[k, 1]
            r2[j, 2] = c2[k, 2]
            x2[j] = c2[k, 0]
            y2[j] = c2[k, 1]
        x1 = np.empty(n1, np.float64)
        y1 = np.empty(n1, np.float64)
        for i in range(n1):
            x1[i] = c1[i, 0]
            y1[i] = c1[i, 1]

        # section 3.4: the paper's edge sequence (raw x and y comparisons) and its triangles
        E = wiederhold_edges(x1, y1, x2, y2)
        f = _edges_to_faces(E, n1, n2, np.int64(0), j0, n, swapped)
        s = foff[t]
        for i in range(len(f)):
            faces[s + i, 0] = f[i, 0]
            faces[s + i, 1] = f[i, 1]
            faces[s + i, 2] = f[i, 2]
        foff[t + 1] = s + len(f)

        # the full mesher's twist guard, on the edge sequences of the paper's band (g = 0) and of
        # the arc-length band of Ganapathy & Dennehy (g = 1, only when both have > 2 points):
        # * folded (contourmesh.bands.band_is_folded): some diagonal carries four triangles, i.e.
        #   all the advances of one polygon happen in one block.  Triangle q (edges q, q + 1) lies
        #   on a lower edge exactly when C(1) advances (up to the swap, which flips all alike);
        # * twisted: the paper's band is more than 1.25 times the area of the reference.  The
        #   triangles are those of edges_to_faces, summed in the faces' order with the faces'
        #   first vertex c1[i_q], so the sums equal triangle_areas on the faces bit for bit
        #   (swapping the other two vertices only negates the cross product).
        st = 0
        area0 = 0.0
        e = E
        for g in range(2):
            if g == 1:
                if st != 0 or n <= 2 or m <= 2:
                    break
                e = arclength_edges(c1, r2)
            ne = len(e)
            changes = 0
            # (both edge sequences hold indices 0 <= i < n1, 0 <= j < n2: no modulo needed)
            prev = e[ne - 1, 0] != e[0, 0]  # C(1) advances in triangle ne - 1
            area = 0.0
            for q in range(ne):
                u = q + 1 if q + 1 < ne else 0
                i1 = e[q, 0]
                j1 = e[q, 1]
                i2 = e[u, 0]
                adv = i1 != i2
                if adv != prev:
                    changes += 1
                prev = adv
                if adv:  # triangle (c1[i1], c1[i2], c2[j1])
                    bx, by, bz = c1[i2, 0], c1[i2, 1], c1[i2, 2]
                else:    # triangle (c1[i1], c2[j2], c2[j1])
                    j2 = e[u, 1]
                    bx, by, bz = r2[j2, 0], r2[j2, 1], r2[j2, 2]
                ux = bx - c1[i1, 0]
                uy = by - c1[i1, 1]
                uz = bz - c1[i1, 2]
                vx = r2[j1, 0] - c1[i1, 0]
                vy = r2[j1, 1] - c1[i1, 1]
                vz = r2[j1, 2] - c1[i1, 2]
                cx = uy * vz - uz * vy
                cy = uz * vx - ux * vz
                cz = ux * vy - uy * vx
                area += 0.5 * math.sqrt(cx * cx + cy * cy + cz * cz)
            if changes <= 2:
                st = 1
            elif g == 0:
                area0 = area
            elif area0 > 1.25 * area * (1.0 - 1e-9):
                st = 1
        status[t] = st
        t += 1
    return faces, foff, status


@njit(cache=True, no_cfunc_wrapper=True, **_OPTIONS)
def _slab_pairs(k0, k1, h, ry, rx0, rx1, lab, meta, rs, xyz, soff, rst, window, pa_all, pb_all, room):
    """Steps 5-6 for the slice pairs ``(k, k + 1)``, ``k0 <= k < k1``, in one call, on the packed
    slices (``meta``, runs and ``row_start`` as :func:`_slab_polygons` packs them, for the whole
    volume) and rings (``xyz[soff[k]:soff[k + 1]]`` holds slice k's rings, ring c starting at
    ``rst[meta[k, 4] + k + c]`` within it).

    Fills ``pa_all[meta[k, 4] + a]`` (the partner of component a of slice k above it, or -1) for
    the slices k0 .. k1 - 1 and ``pb_all`` (the partner below) for k0 + 1 .. k1; returns ``(ok,
    bands, faces)``: ``ok`` False when a pair is not a simple band join (the caller declines),
    ``bands (nb, 5)`` = ``(k, a, b, first face, status)`` in the order of k then a, and the bands'
    faces (local indices as :func:`_pair_bands_k` gives them) concatenated.  The faces are written
    in ``room`` (``int64``, three per face: a view of it is returned) where it holds them all,
    else in a new array: the same values, ``room`` kept by the caller so that its pages are not
    faulted in again every call (see :func:`_slab_polygons`).
    """
    # at most one band per component of the lower slices, of n + m faces: room for all of them
    bands = np.empty((meta[k1, 4] - meta[k0, 4], 5), np.int64)
    nfc = 2 * (soff[k1 + 1] - soff[k0])
    if len(room) >= 3 * nfc:
        faces = room[: 3 * nfc].reshape((nfc, 3))
    else:
        faces = np.empty((nfc, 3), np.int64)
    nb = 0
    nf = 0
    for k in range(k0, k1):
        na = meta[k, 0]
        nbk = meta[k + 1, 0]
        if na == 0 or nbk == 0:
            continue
        a0, a1 = meta[k, 3], meta[k + 1, 3]
        b1 = meta[k + 2, 3]
        joined = -1
        if na == 1 and nbk == 1:
            joined = _stack_join(ry, rx0, rx1, a0, a1, b1)
        if joined >= 0:
            # (two stacks whose overlap is a stack or empty: _pair_joins' answer without its arrays)
            ok = True
            pa = np.empty(1, np.int64)
            pb = np.empty(1, np.int64)
            pa[0] = joined - 1
            pb[0] = joined - 1
        else:
            ok, pa, pb = _pair_joins(ry[a0:a1], rx0[a0:a1], rx1[a0:a1], rs[k], lab[a0:a1], na,
                                     ry[a1:b1], rx0[a1:b1], rx1[a1:b1], rs[k + 1], lab[a1:b1], nbk, h)
        if not ok:
            return False, bands[:0], faces[:0]
        ca = meta[k, 4]
        cb = meta[k + 1, 4]
        any_pair = False
        for a in range(na):
            pa_all[ca + a] = pa[a]
            if pa[a] >= 0:
                any_pair = True
        for b in range(nbk):
            pb_all[cb + b] = pb[b]
        if not any_pair:
            continue
        f, foff, status = _pair_bands_k(xyz[soff[k]:soff[k + 1]], rst[ca + k: ca + na + k + 1],
                                      xyz[soff[k + 1]:soff[k + 2]], rst[cb + k + 1: cb + nbk + k + 2], pa, window)
        t = 0
        for a in range(na):
            if pa[a] < 0:
                continue
            bands[nb, 0] = k
            bands[nb, 1] = a
            bands[nb, 2] = pa[a]
            bands[nb, 3] = nf + foff[t]
            bands[nb, 4] = status[t]
            nb += 1
            t += 1
        for i in range(len(f)):
            faces[nf + i, 0] = f[i, 0]
            faces[nf + i, 1] = f[i, 1]
            faces[nf + i, 2] = f[i, 2]
        nf += len(f)
    return True, bands[:nb], faces[:nf]


@njit(cache=True, no_cfunc_wrapper=True, **_OPTIONS)
def _assemble(bands, bfaces, F, nf_total, vroom, meta, comp_k, xyz, soff, rst, rid):
    """The vertices and faces of the bands, in the full mesher's order: ring (k, c) gets its
    vertex ids when a band first needs it (bands in order of k then a, the lower ring first),
    ``rid[meta[k, 4] + c]`` (-1 on entry) records its first id.  Band i's faces are
    ``bfaces[bands[i, 3]:bands[i + 1, 3]]`` (the last ones end at ``nf_total``), local to
    ``vstack([lower ring, upper ring])``; they are written at the same rows of ``F`` in vertex
    ids (``F`` may be ``bfaces`` itself: mapped in place; its rows from ``nf_total`` on are left
    for the caps).  ``comp_k[g]`` is the slice of component g.  Returns ``(V, nv)``: the bands'
    ``nv`` vertices in the first rows of ``V``, which has ``vroom`` rows more for the caps."""
    nb = len(bands)
    nv = 0
    for i in range(nb):
        for side in range(2):
            k = bands[i, 0] + side
            c = bands[i, 1 + side]
            g = meta[k, 4] + c
            if rid[g] < 0:
                rid[g] = nv
                nv += rst[g + k + 1] - rst[g + k]
    V = np.empty((nv + vroom, 3), np.float64)
    for g in range(len(rid)):
        if rid[g] >= 0:
            k = comp_k[g]
            s0 = soff[k] + rst[g + k]
            for i in range(rst[g + k + 1] - rst[g + k]):
                V[rid[g] + i, 0] = xyz[s0 + i, 0]
                V[rid[g] + i, 1] = xyz[s0 + i, 1]
                V[rid[g] + i, 2] = xyz[s0 + i, 2]
    for i in range(nb):
        k = bands[i, 0]
        ga = meta[k, 4] + bands[i, 1]
        gb = meta[k + 1, 4] + bands[i, 2]
        nlo = rst[ga + k + 1] - rst[ga + k]
        lo0 = rid[ga]
        hi0 = rid[gb]
        f1 = bands[i + 1, 3] if i + 1 < nb else nf_total
        for t in range(bands[i, 3], f1):
            for j in range(3):
                v = bfaces[t, j]
                F[t, j] = v + lo0 if v < nlo else v - nlo + hi0
    return V, nv


def _one_band(lo, hi, window=INITIAL_EDGE_WINDOW):
    """The guarded band of one pair of rings: ``(faces, status)`` of :func:`_pair_bands`."""
    lo = np.ascontiguousarray(lo, dtype=np.float64)
    hi = np.ascontiguousarray(hi, dtype=np.float64)
    faces, foff, status = _pair_bands(lo, np.array([0, len(lo)], np.int64), hi, np.array([0, len(hi)], np.int64),
                                      np.zeros(1, np.int64), window)
    return faces[: foff[1]], int(status[0])


#: one guarded band (benchmarks time it band by band)
_band = _one_band


def band_faces(lower, upper) -> np.ndarray:
    """The volume mesher's band between two rings (paper's triangulation plus its twist guard).

    ``lower`` ``(n, 3)`` and ``upper`` ``(m, 3)`` as in :func:`contourmesh.bands.triangulate_band`;
    returns faces indexing ``np.vstack([lower, upper])`` and whether the guard replaced the band.
    """
    lo = np.ascontiguousarray(lower, dtype=np.float64)
    hi = np.ascontiguousarray(upper, dtype=np.float64)
    if lo.ndim != 2 or lo.shape[1] != 3 or hi.ndim != 2 or hi.shape[1] != 3 or len(lo) < 1 or len(hi) < 1:
        raise ValueError(f"lower and upper must be (n, 3) arrays; got {lo.shape} and {hi.shape}")
    f, status = _one_band(lo, hi)
    if status == 0:
        return f, False
    f, replaced = _band_py(lo, hi)
    return f, bool(replaced)


def _band_py(lo, hi, triangulation="wiederhold"):
    """The full mesher's band with its twist guard (:func:`contourmesh.bands.twist_guarded_band`),
    for the folded, twisted or self-crossing bands the kernel's band is not kept for; as in
    :func:`contourmesh.volumes._band_faces`, a band that is still folded becomes the arc-length
    band (which never folds).  Returns the faces and how many guards fired."""

    f, replaced = twist_guarded_band(lo, hi, triangulation)
    replaced = int(replaced)
    if band_is_folded(f):
        f = triangulate_band(lo, hi, "arclength")
        replaced += 1
    return f, replaced


# ------------------------------------------------------------------------------------------------
# the driver
# ------------------------------------------------------------------------------------------------
_TLS = threading.local()


def _seen_bits(h, w):
    """A zero bit map for :func:`_slice_polygons_k`'s ``seen``: one bit per point of ``[-1, w + 1] x
    [-1, h + 1]`` (MLP vertices lie in ``[-1, w] x [-1, h]``), as ``uint64`` words."""
    return np.zeros(((h + 3) * (w + 3) + 63) // 64, np.uint64)


def _scratch(h, w):
    """This thread's scratch arrays for :func:`_slice_polygons`: ``(seen, on, bg)`` (zero: the
    kernels leave them as they found them)."""
    s = getattr(_TLS, "seen", None)
    if s is None or getattr(_TLS, "shape", None) != (h, w):
        s = _seen_bits(h, w)
        _TLS.seen = s
        _TLS.shape = (h, w)
        g = np.zeros(2 * (h + 6) * (w + 6), np.uint8)
        _TLS.grids = g[: (h + 6) * (w + 6)], g[(h + 6) * (w + 6):]
    return s, _TLS.grids[0], _TLS.grids[1]


_ROOM_BYTES = 16 << 20  # the most a kept room (_room) may take, per array and thread


def _rooms():
    """This thread's kept rooms (:func:`_room`), a dict made at its first call."""
    rooms = getattr(_TLS, "rooms", None)
    if rooms is None:
        rooms = _TLS.rooms = {}
    return rooms


def _room(name, n, dtype, rooms=None, cap=None):
    """This thread's kept array ``name`` (``dtype``) of ``n`` items or more, made anew when the kept
    one is smaller; an empty array where ``n`` items would take more than :data:`_ROOM_BYTES` (the
    kernels then make their own).  The fast path's kernels write their packed outputs in it
    (:func:`_slab_polygons`, :func:`_slab_pairs`): its pages are faulted in by the first call
    only, while new arrays of that size (mapped anew by malloc) are faulted in every call.  The
    contents are the caller's only during one call (:func:`_fast` lets none of it out).

    ``rooms`` (a dict from :func:`_rooms`) is another thread's: the calling thread of a call on
    several threads hands its own to the slabs its workers run, so the rooms follow the call, not
    the worker that happens to take a slab; ``cap`` replaces :data:`_ROOM_BYTES` as the limit."""
    n = int(n)
    if n * np.dtype(dtype).itemsize > (_ROOM_BYTES if cap is None else cap):
        return np.empty(0, dtype)
    if rooms is None:
        rooms = _rooms()
    a = rooms.get(name)
    if a is None or len(a) < n or a.dtype != dtype:
        a = rooms[name] = np.empty(n, dtype)
    return a


class _OutOfScope(Exception):
    pass


def _params_ok(volume, spacing, z, axis, label, threshold, origin):
    """The cheap parameter checks of :func:`contourmesh.volumes.prepare_volume` (True if all pass)."""
    if not isinstance(volume, np.ndarray) or volume.ndim != 3 or 0 in volume.shape:
        return False
    if volume.dtype.kind not in "biuf":
        return False
    if axis not in (0, 1, 2) or isinstance(axis, bool):
        return False
    try:  # the volume validator's own checks; the general mesher then reports what is wrong
        check_spacing(spacing)
        check_origin(origin)
    except ValueError:
        return False
    if label is not None and threshold is not None:
        return False
    if threshold is not None:
        try:
            if not np.isfinite(threshold):
                return False
        except TypeError:
            return False
    return True


def fast_volume_to_mesh(volume, *, spacing=(1.0, 1.0, 1.0), z=None, axis: int = 0, label=None, threshold=None,
                        origin=(0.0, 0.0, 0.0), polygon: str = "mlp", triangulation: str = "wiederhold",
                        caps: str = "flat", refine: str | None = None, threads: int | None = None):
    """The mesh of :func:`contourmesh.volumes.volume_to_mesh`, fast, or None outside the fast path's scope.

    Parameters
    ----------
    volume, spacing, z, axis, label, threshold, origin, polygon, triangulation, caps
        As for :func:`contourmesh.volumes.volume_to_mesh`.
    refine : {None, "none", "band", "band2"}
        The fast path has no refinement: with ``"band"`` or ``"band2"`` it declines (returns None).
    threads : int, optional
        Worker threads for the per-slice and per-pair kernels (default: ``$CONTOURMESH_THREADS`` or
        1, which runs everything in the calling thread).

    Returns
    -------
    Mesh or None
        The same vertices and faces as the full mesher (``meta["fast_path"] = True``), or None
        when the volume or the options are outside the scope described in the module docstring
        (the caller then runs the full mesher, which also raises the input errors).
    """
    return _fast_volume_to_mesh(volume, spacing=spacing, z=z, axis=axis, label=label, threshold=threshold,
                                origin=origin, polygon=polygon, triangulation=triangulation, caps=caps,
                                refine=refine, threads=threads)


def _fast_volume_to_mesh(volume, *, spacing=(1.0, 1.0, 1.0), z=None, axis: int = 0, label=None, threshold=None,
                         origin=(0.0, 0.0, 0.0), polygon: str = "mlp", triangulation: str = "wiederhold",
                         caps: str = "flat", refine: str | None = None, threads: int | None = None, bands_out=None):
    """:func:`fast_volume_to_mesh`; with a list ``bands_out``, the mesh's band table (see
    :func:`_fast`) is appended to it (for :func:`redo_self_crossing_bands`)."""
    if polygon != "mlp" or triangulation != "wiederhold" or caps not in ("flat", "half"):
        return None
    if refine not in (None, "none"):
        return None  # refined polygons are the general mesher's
    if not _params_ok(volume, spacing, z, axis, label, threshold, origin):
        return None
    try:
        return _fast(volume, spacing, z, axis, label, threshold, origin, caps, threads, bands_out)
    except _OutOfScope:
        return None


def _slicer(vol, axis, label, threshold):
    """``(nz, h, w, get, direct)``: ``get(k)`` -> ``(b8, b64, base, aligned)`` for slice k;
    ``direct`` is ``(b8, b64, aligned)`` when the volume's own bytes are the slices (a C-contiguous
    bool or one-byte volume without label or threshold), else None."""
    kind = vol.dtype.kind
    if axis != 0:
        order = [axis] + [a for a in (0, 1, 2) if a != axis]
        vol = np.transpose(vol, order)
    nz, h, w = vol.shape
    direct = label is None and threshold is None and (kind == "b" or vol.dtype.itemsize == 1) \
        and vol.flags.c_contiguous
    if direct:
        b8 = vol.reshape(-1).view(np.uint8)
        b64, aligned = _words(b8)

        def get(k):
            return b8, b64, k * h * w, aligned

        return nz, h, w, get, (b8, b64, aligned)

    def get(k):
        s = vol[k]
        if kind == "f" and not np.isfinite(s).all():
            raise _OutOfScope
        if label is not None:
            m = s == label
        elif threshold is not None:
            m = s > threshold
        elif kind == "b":
            m = s
        else:
            m = s != 0
            if np.count_nonzero(s == 1) != np.count_nonzero(m):
                raise _OutOfScope  # values other than 0 and 1: the full mesher says which
        m = np.ascontiguousarray(m, dtype=bool)
        b = m.reshape(-1).view(np.uint8)
        b64, aligned = _words(b)
        return b, b64, 0, aligned

    return nz, h, w, get, None


#: Slabs per thread in :func:`_map`: a few, so that a thread whose slabs hold the object's thick
#: middle does not leave the others idle at the end.
SLABS_PER_THREAD = 4


def _map(fn, items, threads):
    """``[fn(i) for i in items]``, on ``threads`` threads (the kernels release the GIL).

    The items (slices, or slice pairs) go to the threads in slabs of consecutive items, a few
    slabs per thread (:data:`SLABS_PER_THREAD`), not one by one: a task per slice costs the pool
    more than a thin slice's kernel takes."""
    if threads <= 1 or len(items) < 4:
        return [fn(i) for i in items]
    n = len(items)
    bounds = np.linspace(0, n, min(n, threads * SLABS_PER_THREAD) + 1).astype(int)
    slabs = [(items[a:b],) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    return [r for part in run_all(lambda slab: [fn(i) for i in slab], slabs, threads) for r in part]


def _pack_slices(outs, h, ox, oy, dx, dy, zs):
    """The outputs of :func:`_slice_polygons`, one per slice, packed as :func:`_slab_polygons`
    packs them (for the volumes that are not read from their own bytes)."""
    nk = len(outs)
    meta = np.zeros((nk + 1, 6), np.int64)
    meta[:-1, 0] = [o[5] for o in outs]
    meta[:-1, 1] = [o[6] for o in outs]
    meta[:-1, 2] = [o[11] for o in outs]
    meta[1:, 3] = np.cumsum([len(o[0]) for o in outs])
    meta[1:, 4] = np.cumsum(meta[:-1, 0])
    npoly = [len(o[8]) for o in outs]
    meta[1:, 5] = np.cumsum(npoly)
    cat = [np.concatenate([o[i] for o in outs]).astype(np.int32) for i in (0, 1, 2, 4)]
    rs = np.stack([o[3] for o in outs]).astype(np.int32) if nk else np.zeros((0, h + 1), np.int32)
    bbox = np.concatenate([o[7] for o in outs]).astype(np.int64).reshape(-1)
    poly = np.concatenate([o[8] for o in outs]).astype(np.int64).reshape(-1, 2)
    pst = np.concatenate([o[9] for o in outs]).astype(np.int64)
    deg = np.concatenate([o[10] for o in outs]).astype(np.int64)
    xyz = np.empty((len(poly), 3))
    xyz[:, 0] = ox + poly[:, 0].astype(np.float64) * dx
    xyz[:, 1] = oy + poly[:, 1].astype(np.float64) * dy
    xyz[:, 2] = np.repeat(zs, npoly)
    return (meta, cat[0], cat[1], cat[2], cat[3], rs, bbox, poly, pst, deg, xyz)


def _join_packs(packs, threads=1, rooms=None):
    """Packs of consecutive slabs (:func:`_slab_polygons`) as one pack of the whole volume.

    With ``rooms`` (:func:`_rooms`), the runs, labels and row starts, the polygon vertices and
    their coordinates are joined into the kept rooms ``runs``, ``poly`` and ``xyz`` (laid out as
    :func:`_slab_polygons` lays out one slab's), not into new arrays: the same values, in pages
    faulted in once rather than at every call, on the calling thread (the 512^3 ball's 6.6 MB in
    0.55 ms, where handing half to a worker took 1.9 ms of wall time with other processes on the
    cores).  Where a room would pass its limit, the arrays are new, and joined on two threads
    where ``threads > 1`` (numpy copies without the GIL; new pages of the ball's runs and row
    starts, 8 MB, took 3-5 ms on one thread)."""
    if len(packs) == 1:
        meta, ry, rx0, rx1, lab, rs, bbox, poly, pst, deg, xyz = packs[0]
        return meta, ry, rx0, rx1, lab, rs, bbox.reshape(-1, 4), poly, pst, deg, xyz
    metas, base = [], np.zeros(6, np.int64)
    for p in packs:
        m = p[0].copy()
        m[:, 3:] += base[3:]
        metas.append(m[:-1])
        base = m[-1]
    meta = np.concatenate(metas + [base[None]])
    outs = {}
    if rooms is not None:
        nr, npv = int(base[3]), int(base[5])
        nrs = sum(p[5].shape[0] for p in packs) * packs[0][5].shape[1]
        r32 = _room("runs", nrs + 4 * nr, np.int32, rooms)
        if len(r32):
            outs[5] = r32[:nrs].reshape(-1, packs[0][5].shape[1])
            for j in range(4):  # ry, rx0, rx1, lab after the row starts
                outs[1 + j] = r32[nrs + j * nr: nrs + (j + 1) * nr]
        p64 = _room("poly", 2 * npv, np.int64, rooms)
        if len(p64):
            outs[7] = p64[: 2 * npv].reshape(npv, 2)
        f64 = _room("xyz", 3 * npv, np.float64, rooms)
        if len(f64):
            outs[10] = f64[: 3 * npv].reshape(npv, 3)

    def join(fields):
        return [np.concatenate([p[i] for p in packs], out=outs.get(i)) for i in fields]

    if threads > 1 and len(outs) < 6:  # (new arrays: their pages faulted in on two threads)
        runs, rest = run_all(join, [((1, 2, 3),), (range(4, 11),)], threads)  # (ry, rx0, rx1; the rest)
        cat = runs + rest
    else:
        cat = join(range(1, 11))
    cat[5] = cat[5].reshape(-1, 4)
    return (meta, *cat)


def _map_slabs(fn, n, threads):
    """``fn(k0, k1, i)`` (a list of ``k1 - k0`` results) over slabs covering ``0 .. n - 1`` (``i``
    the slab's index), joined: one slab on one thread, a few per thread (:data:`SLABS_PER_THREAD`)
    on a thread pool."""
    if threads <= 1 or n < 4:
        return fn(0, n, 0)
    bounds = np.linspace(0, n, min(n, threads * SLABS_PER_THREAD) + 1).astype(int).tolist()
    slabs = [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    return [r for part in run_all(fn, [(a, b, i) for i, (a, b) in enumerate(slabs)], threads) for r in part]


#: The most a slab's kept room (one of several slabs of a call, :func:`_fast`) may take, per
#: array: the slabs of one kind together keep about :data:`_ROOM_BYTES` per thread.
_SLAB_ROOM_BYTES = _ROOM_BYTES // SLABS_PER_THREAD


def _fast(volume, spacing, z, axis, label, threshold, origin, caps, threads, bands_out=None):

    if threads is None:
        # one thread unless asked: per-slice threads cost more than they gain on two cores, and a
        # process pool (compare --jobs N) would be oversubscribed
        threads = int(os.environ.get("CONTOURMESH_THREADS", 1))
    threads = max(1, int(threads))
    sp = np.asarray(spacing, dtype=np.float64).reshape(-1)
    org = np.asarray(origin, dtype=np.float64).reshape(-1)
    if axis != 0:
        order = [axis] + [a for a in (0, 1, 2) if a != axis]
        sp = sp[order]
    dy, dx = float(sp[1]), float(sp[2])
    ox, oy = float(org[0]), float(org[1])
    nz, h, w, get, direct = _slicer(volume, axis, label, threshold)
    if h * w >= 2 ** 31:
        raise _OutOfScope  # the packed runs are int32 (_slab_polygons): the full mesher takes it
    if z is None:
        zs = org[2] + sp[0] * np.arange(nz, dtype=np.float64)
    else:
        zs = np.ascontiguousarray(z, dtype=np.float64).reshape(-1)
        if zs.shape != (nz,) or not np.all(np.isfinite(zs)) or (nz > 1 and not np.all(np.diff(zs) > 0)):
            raise _OutOfScope

    # steps 1-4: the slices of each slab packed by one kernel call, then joined into arrays over
    # the whole volume (no Python per slice)
    # The packs are written in kept rooms (_room), the calling thread's even where its workers run
    # the slabs: the whole volume's (one slab) or the slab's own, keyed by its index (slabs are
    # the same cuts of the same volume from call to call, so each slab's room fits it next time)
    rooms = _rooms()

    def per_slab(k0, k1, i):
        b8, b64, aligned = direct
        seen, on, bg = _scratch(h, w)
        nk, nrs = k1 - k0, (k1 - k0) * (h + 1)
        if nk == nz:
            names, cap = ("runs", "poly", "xyz"), _ROOM_BYTES
        else:  # (the slabs' packs are joined into the rooms of the whole volume: _join_packs)
            names, cap = (("runs", i), ("poly", i), ("xyz", i)), _SLAB_ROOM_BYTES
        r32 = _room(names[0], nrs + 4 * max(2 * nk * h, 64), np.int32, rooms, cap)
        p64 = _room(names[1], 2 * max(256 * nk, 64), np.int64, rooms, cap)
        f64 = _room(names[2], 3 * max(256 * nk, 64), np.float64, rooms, cap)
        pack = _slab_polygons(b8, b64, k0 * h * w, nk, h, w, aligned, seen, on, bg, ox, oy, dx, dy,
                              zs[k0:k1], r32, p64, f64, True)
        if pack[0][:-1, 1:3].any():  # values other than 0/1, a hole, shared positions
            raise _OutOfScope
        # room for as many runs and vertices next time (kept if not too large)
        _room(names[0], nrs + 4 * int(pack[0][-1, 3]), np.int32, rooms, cap)
        _room(names[1], 2 * int(pack[0][-1, 5]), np.int64, rooms, cap)
        _room(names[2], 3 * int(pack[0][-1, 5]), np.float64, rooms, cap)
        return [pack]

    def per_slice(k):
        b8, b64, base, aligned = get(k)
        seen, on, bg = _scratch(h, w)
        out = _slice_polygons(b8, b64, base, h, w, aligned, seen, on, bg)
        if out[11] != 0 or out[6] != 0:  # values other than 0/1, a hole, shared positions
            raise _OutOfScope
        return out

    if direct is not None:
        packs = _map_slabs(per_slab, nz, threads)
    else:
        packs = [_pack_slices(_map(per_slice, list(range(nz)), threads), h, ox, oy, dx, dy, zs)]
    meta, RY, RX0, RX1, LAB, RS, BBOX, POLY, PST, DEG, XYZ = _join_packs(packs, threads, rooms)
    ncomp = meta[:-1, 0]
    if not ncomp.any():
        raise _OutOfScope  # no foreground: the full mesher raises the error
    comp_off = meta[:, 4]
    comp_k = np.repeat(np.arange(nz), ncomp)

    to_center, to_corner = grid_to_xy(ox, oy, dx, dy)

    # rings (physical xyz) of every slice, concatenated: slice k's at RXYZ[soff[k]:soff[k + 1]],
    # component c's from RST[comp_off[k] + k + c] on within it; degenerate MLPs -> crack contours
    degenerate = np.flatnonzero(DEG)
    fallbacks = len(degenerate)
    if fallbacks == 0:
        RXYZ, RST, soff = XYZ, PST, meta[:, 5].copy()
    else:
        remade = set(comp_k[degenerate].tolist())
        parts, starts_all, soff = [], [], [0]
        for k in range(nz):
            c0, c1 = int(comp_off[k]), int(comp_off[k + 1])
            if k not in remade:
                parts.append(XYZ[meta[k, 5]: meta[k + 1, 5]])
                starts_all.append(PST[c0 + k: c1 + k + 1])
                soff.append(soff[-1] + len(parts[-1]))
                continue
            r0, r1 = meta[k, 3], meta[k + 1, 3]
            ry, rx0, rx1, lab = RY[r0:r1], RX0[r0:r1], RX1[r0:r1], LAB[r0:r1]
            poly, ps = POLY[meta[k, 5]: meta[k + 1, 5]], PST[c0 + k: c1 + k + 1]
            xys, starts = [], [0]
            for c in range(c1 - c0):
                if DEG[c0 + c]:
                    x0, y0, x1, y1 = (int(v) for v in BBOX[c0 + c])
                    comp = np.zeros((y1 - y0 + 1, x1 - x0 + 1), dtype=bool)
                    sel = np.flatnonzero(lab == c)
                    for r in sel:
                        comp[ry[r] - y0, rx0[r] - x0: rx1[r] - x0] = True
                    cont, area2 = _crack_contours(comp)
                    outer = [cont[i] for i in range(len(cont)) if area2[i] > 0]
                    xy = to_corner(thin_part_polygon(outer[0]) + np.array([x0, y0]))
                else:
                    xy = to_center(poly[ps[c]: ps[c + 1]])
                xys.append(xy)
                starts.append(starts[-1] + len(xy))
            xy = np.concatenate(xys)
            if len(np.unique(xy, axis=0)) != len(xy):
                raise _OutOfScope  # coincident vertices: the full mesher nudges them apart
            parts.append(np.c_[xy, np.full(len(xy), zs[k])])
            starts_all.append(np.asarray(starts, dtype=np.int64))
            soff.append(soff[-1] + len(xy))
        RXYZ = np.ascontiguousarray(np.concatenate(parts), dtype=np.float64)
        RST = np.concatenate(starts_all).astype(np.int64)
        soff = np.asarray(soff, dtype=np.int64)

    def ring_xyz(k, c):
        g = comp_off[k] + c
        return RXYZ[soff[k] + RST[g + k]: soff[k] + RST[g + k + 1]]

    # steps 5-6: the slice pairs of each slab by one kernel call
    PA = np.full(len(DEG), -1, np.int64)  # partner above / below of every component, or -1
    PB = np.full(len(DEG), -1, np.int64)

    flat_caps = {}  # component -> its flat cap's faces (local), made in the slab tasks

    def pair_slab(k0, k1, i):
        # the faces in a kept room of the calling thread (read by _assemble, or copied into the
        # mesh's faces, only): the whole volume's, or the slab's own
        one = k1 - k0 == nz - 1
        room = _room("faces" if one else ("faces", i), 6 * (soff[k1 + 1] - soff[k0]), np.int64, rooms,
                     _ROOM_BYTES if one else _SLAB_ROOM_BYTES)
        ok, bands, bfaces = _slab_pairs(k0, k1, h, RY, RX0, RX1, LAB, meta, RS, RXYZ, soff, RST, INITIAL_EDGE_WINDOW,
                                        PA, PB, room)
        if not ok:
            raise _OutOfScope
        if caps == "flat":
            # the slab's slices whose partners above and below are both known by now (the first
            # and last slice of the volume have none on their outer side): the flat caps of their
            # components with one partner are triangulated here, in the thread, not after the joins
            ka = k0 if k0 == 0 else k0 + 1
            kb = k1 + 1 if k1 == nz - 1 else k1
            g0, g1 = int(comp_off[ka]), int(comp_off[kb])
            for g in (np.flatnonzero((PA[g0:g1] < 0) != (PB[g0:g1] < 0)) + g0).tolist():
                k = int(comp_k[g])
                try:
                    flat_caps[g] = cap_faces(ring_xyz(k, g - int(comp_off[k]))[:, :2], [], upward=bool(PA[g] < 0))
                except ValueError:
                    raise _OutOfScope from None  # the full mesher closes it with pixels
        return [(bands, bfaces)]

    parts = _map_slabs(pair_slab, nz - 1, threads)
    shift = np.cumsum([0] + [len(f) for _, f in parts])
    nf = int(shift[-1])
    for (bands, _), sh in zip(parts, shift):
        bands[:, 3] += sh
    if len(parts) == 1:
        BANDS, BF = parts[0]
    else:
        BANDS = np.concatenate([b for b, _ in parts]) if parts else np.zeros((0, 5), np.int64)

    # room for the caps in the final arrays (the mesh's vertices and faces are written once, at
    # their rows, not joined at the end): a component without a partner above or below gets a cap
    # (n - 2 faces), with half caps or as a prism also a band (2 n faces) and a shifted ring (n
    # vertices), and as a prism its own ring (n vertices)
    capped = np.flatnonzero((PA < 0) | (PB < 0))
    ck = comp_k[capped]
    nring = RST[capped + ck + 1] - RST[capped + ck]
    ncaps = 1 + ((PA[capped] < 0) & (PB[capped] < 0))
    vroom = int((nring * (1 + ncaps)).sum())
    froom = int((3 * nring * ncaps).sum())
    F = np.empty((nf + froom, 3), np.int64)
    if len(parts) != 1:
        if parts:
            np.concatenate([f for _, f in parts], out=F[:nf])
        BF = F  # mapped in place

    # vertex ids in the full mesher's order: rings are created when a join (k ascending, groups by
    # their component below) or a cap first needs them
    rid = np.full(len(DEG), -1, np.int64)
    V, nverts = _assemble(BANDS, BF, F, nf, vroom, meta, comp_k, RXYZ, soff, RST, rid)
    nverts = int(nverts)
    band_joins = len(BANDS)
    band_fallbacks = 0
    nfaces = nf
    redo = np.flatnonzero(BANDS[:, 4])
    band_faces_n = np.diff(np.r_[BANDS[:, 3], nf])  # each band's faces, in order, from row 0
    if len(redo):
        # folded, twisted or too close to call: the full mesher's band replaces the paper's
        ends = np.r_[BANDS[:, 3], nf]
        face_blocks, done = [], 0
        for i in redo.tolist():
            k, a, b = (int(v) for v in BANDS[i, :3])
            lo, hi = ring_xyz(k, a), ring_xyz(k + 1, b)
            f, replaced = _band_py(lo, hi)
            band_faces_n[i] = len(f)
            band_fallbacks += replaced
            lo0, hi0 = int(rid[comp_off[k] + a]), int(rid[comp_off[k + 1] + b])
            face_blocks += [F[done: ends[i]], np.where(f < len(lo), f + lo0, f - len(lo) + hi0)]
            done = ends[i + 1]
        face_blocks.append(F[done:nf])
        nfaces = sum(len(f) for f in face_blocks)
        F = np.concatenate(face_blocks + [np.empty((froom, 3), np.int64)])

    def put_vertices(blk):
        nonlocal V, nverts
        if nverts + len(blk) > len(V):  # not expected (the room is an upper bound): grow
            V = np.concatenate([V[:nverts], np.empty((len(blk) + len(V), 3))])
        V[nverts: nverts + len(blk)] = blk
        nverts += len(blk)

    def put_faces(f):
        nonlocal F, nfaces
        if nfaces + len(f) > len(F):
            F = np.concatenate([F[:nfaces], np.empty((len(f) + len(F), 3), np.int64)])
        F[nfaces: nfaces + len(f)] = f
        nfaces += len(f)

    def ring(k, c):
        g = comp_off[k] + c
        if rid[g] < 0:
            rid[g] = nverts
            put_vertices(ring_xyz(k, c))
        return int(rid[g]), int(RST[g + k + 1] - RST[g + k])

    # ends: caps (and prisms for components without a partner on either side)

    def gap(k, up):
        return slice_gap(zs, k, up)

    shifted_planes = {}

    def new_ring(xy, zc):
        blk = np.c_[xy, np.full(len(xy), zc)]
        start = nverts
        put_vertices(blk)
        key = float(zc)
        shifted_planes.setdefault(key, []).append(xy)
        return start, blk

    cap_bands = []  # the half caps' bands: (first face, faces, lower ring, its size, upper ring, its size, kept)

    def close(k, c, up, zc):
        r0, nr = ring(k, c)
        xyz = ring_xyz(k, c)
        if zc is not None:
            t0, txyz = new_ring(xyz[:, :2], zc)
            lo0, hi0 = (r0, t0) if up else (t0, r0)
            f, replaced, kept = _band_or_py(*((xyz, txyz) if up else (txyz, xyz)))
            cap_bands.append((nfaces, len(f), lo0, nr, hi0, nr, int(kept)))
            put_faces(np.where(f < nr, f + lo0, f - nr + hi0))
            nonlocal band_fallbacks
            band_fallbacks += replaced
            r0, xyz = t0, txyz
        f = flat_caps.get(int(comp_off[k]) + c) if zc is None else None
        if f is None:
            try:
                f = cap_faces(xyz[:, :2], [], upward=up)
            except ValueError:
                raise _OutOfScope from None  # the full mesher closes it with pixels
        put_faces(f + r0)

    for g in capped.tolist():  # (k, c) in order
        k = int(comp_k[g])
        c = g - int(comp_off[k])
        above, below = PA[g] >= 0, PB[g] >= 0
        if not above and not below:
            close(k, c, False, zs[k] - gap(k, False) / 2)
            close(k, c, True, zs[k] + gap(k, True) / 2)
            continue
        up = not above
        zc = zs[k] + (gap(k, up) / 2 if up else -gap(k, up) / 2) if caps == "half" else None
        close(k, c, up, zc)
    for xys in shifted_planes.values():
        if len(xys) > 1:
            xy = np.concatenate(xys)
            if len(np.unique(xy, axis=0)) != len(xy):
                raise _OutOfScope
    V = V[:nverts]  # leading rows: still C-contiguous, so Mesh keeps them without a copy
    F = F[:nfaces]
    if bands_out is not None:
        # the band table: per band, its first face row and face count, the first vertex and size of
        # its lower and upper ring, and 1 where the kernel's band was kept (it passed the twist guard
        # but was not tested for faces crossing each other, see redo_self_crossing_bands)
        kb = BANDS[:, 0]
        g_lo = comp_off[kb] + BANDS[:, 1]
        g_hi = comp_off[kb + 1] + BANDS[:, 2]
        table = np.empty((len(BANDS), 7), np.int64)
        table[:, 0] = np.r_[0, np.cumsum(band_faces_n)[:-1]] if len(BANDS) else 0
        table[:, 1] = band_faces_n
        table[:, 2] = rid[g_lo]
        table[:, 3] = RST[g_lo + kb + 1] - RST[g_lo + kb]
        table[:, 4] = rid[g_hi]
        table[:, 5] = RST[g_hi + kb + 2] - RST[g_hi + kb + 1]
        table[:, 6] = BANDS[:, 4] == 0
        bands_out.append(np.concatenate([table, np.array(cap_bands, np.int64).reshape(-1, 7)]))
    meta = {
        "method": "contourmesh", "source": "volume", "polygon": "mlp", "triangulation": "wiederhold",
        "caps": caps, "band_joins": band_joins, "bridged_joins": 0, "bridges": 0, "intermediate_sections": 0,
        "exact_joins": 0,
        "polygon_fallbacks": fallbacks,
        "crack_rings": 0, "band_fallbacks": band_fallbacks, "pixel_caps": 0, "least_area_bands": 0, "dense_rings": 0,
        "connectivity": CONNECTIVITY, "fast_path": True,
    }
    return Mesh(V, F, P=len(V), meta=meta)


def _band_or_py(lo, hi):
    """``(faces, guards fired, kept)``: the kernel's band where it passes the twist guard (kept),
    else the full mesher's (:func:`_band_py`)."""
    f, status = _one_band(lo, hi)
    if status == 0:
        return f, 0, True
    return (*_band_py(lo, hi), False)


def redo_self_crossing_bands(V, F, bands, pairs):
    """The faces ``F`` of a fast-path mesh with its kept bands that cross themselves redone, as
    the general mesher does them, or None when none does.

    The general mesher keeps the paper's band only where no two of its faces cross
    (:func:`contourmesh.volumes._band_faces`); the fast path skips that test band by band.  A band
    whose faces cross has them among the whole mesh's crossing ``pairs``, so only the kept bands
    (``bands`` from :func:`_fast_volume_to_mesh`) with a face in a pair are tested, with the same
    test, and a band that crosses itself gets the general mesher's band (:func:`_band_py`).
    Returns ``(faces, guards fired)``; a band whose replacement has another face count (not
    expected: a band between closed rings of n and m points has n + m faces) gives None."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1)
    if not len(pairs) or not len(bands):
        return None
    order = np.argsort(bands[:, 0], kind="stable")
    starts = bands[order, 0]
    faces = np.unique(pairs)
    at = np.searchsorted(starts, faces, side="right") - 1
    ok = at >= 0
    faces, at = faces[ok], order[at[ok]]
    hit = np.unique(at[faces < bands[at, 0] + bands[at, 1]])
    F2, fired = None, 0
    for i in hit.tolist():
        f0, nf, lo0, nlo, hi0, nhi, kept = (int(v) for v in bands[i])
        if not kept:
            continue
        lo, hi = V[lo0: lo0 + nlo], V[hi0: hi0 + nhi]
        block = F[f0: f0 + nf]
        local = np.where((block >= lo0) & (block < lo0 + nlo), block - lo0, block - hi0 + nlo)
        if not _band_crosses(np.concatenate([lo, hi]), local):
            continue
        f, replaced = _band_py(lo, hi)
        if len(f) != nf:
            return None
        if F2 is None:
            F2 = np.array(F, dtype=np.int64)
        F2[f0: f0 + nf] = np.where(f < nlo, f + lo0, f - nlo + hi0)
        fired += replaced
    return None if F2 is None else (F2, fired)
