"""The general mesher on worker processes: a volume meshed in slabs of slices, joined at their seams.

The general volume mesher is mostly Python, so threads cannot share its work (the GIL).  With
``CONTOURMESH_THREADS`` = ``n`` > 1, a volume that takes the general mesher in paper mode
(``refine=None``) and is large enough to pay for it is cut into slabs of slices, more slabs than
workers, which ``n`` worker processes forked from the calling process mesh at the same time.
The slabs are those of :mod:`contourmesh.seams`: slab ``j`` owns the gaps ``c_j .. c_{j+1}``,
meshes them with a halo of :data:`~contourmesh.seams.DEFAULT_HALO` slices each side at the whole
volume's slice heights, keeps the faces it owns, and the neighbours' hashes of the faces next to
every seam must agree (else :class:`~contourmesh.seams.SeamMismatch`).  The faces are joined by
identical coordinates (:func:`~contourmesh.seams.join_pieces`): the mesh is the one-process mesh
in canonical order (vertices sorted, each face rotated to its smallest index, faces sorted).

**Cut ends.**  A slab's first and last slices, where they are cuts inside the volume, are left
uncapped (:class:`~contourmesh.volumes.SlabPart`): a flat cap there would be a fan of long
triangles across the cut plane that the crossing test pairs with every face near it, and would
be repaired and tested for nothing (the halo's faces are not kept).  The faces a slab keeps lie
at least ``halo`` slices from its cut ends; the seam hashes check that the neighbourhood of every
seam came out the same from both sides.

**Cuts.**  The slabs are balanced on a per-slice work estimate (:func:`slice_work`: the object's
boundary runs along x in the slice, counted in one compiled pass), ``_SLABS_PER_WORKER`` slabs per
worker, and handed out largest first.

**Checks and meta.**  Every face pair of the joined mesh that can meet lies in one slab's mesh
as that slab made it: faces span at most one slice gap, so two faces that meet are owned by one
slab or by the two slabs of one seam, and then both lie within one gap of that seam, where each
slab's copy of its neighbour's faces is the neighbour's own (the seam hashes).  So the slabs'
crossing tests are the joined mesh's: each pair a slab finds is counted by the slab owning the
higher-numbered of its two faces.  ``meta``'s counts are the slabs' counts of the joins of their
own gaps and the caps and rings of their own slices (:class:`~contourmesh.volumes.SlabPart`),
added up, so they equal the one-process counts; ``crossing_repair_max_move`` is the largest move
of a kept face's vertex.  Area and volume are order-independent sums (:class:`contourmesh.Mesh`).

**Processes.**  Linux's ``fork`` only, from the calling process (its compiled kernels are the
children's), and only while no other thread runs in it (the package's thread pools are made per
call and shut down; a thread holding a lock at the fork could deadlock the child).  The children
mesh with ``CONTOURMESH_THREADS=1``.  Elsewhere, below :data:`MIN_WORK`, when a worker fails or
a seam disagrees, the volume is meshed in this process as before (logged at DEBUG): never a
different mesh.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import threading
import time

import numpy as np
from numba import njit

from .intersect import _threads
from .seams import DEFAULT_HALO, SeamMismatch, join_pieces, seam_hashes
from .types import Mesh
from .volumes import SlabPart, volume_to_mesh

__all__ = ["mesh_in_slabs", "slice_work", "balanced_cuts", "MIN_WORK"]

log = logging.getLogger("contourmesh")

#: The slab route is taken only when the volume's work estimate (:func:`slice_work`, summed) is at
#: least this: below it the forks, the halos and the join cost more than the second worker saves.
MIN_WORK = 20_000

#: Slabs per worker process: more slabs than workers even out slabs whose work the estimate
#: misjudges, at the cost of two halos each.
_SLABS_PER_WORKER = 3

#: The meta counts that the slabs add up (each counts its own gaps' joins and its own slices' caps).
_COUNTS = ("band_joins", "bridged_joins", "bridges", "intermediate_sections", "exact_joins", "polygon_fallbacks",
           "crack_rings", "band_fallbacks", "pixel_caps", "least_area_bands", "dense_rings", "crossing_fallbacks")

_JOB = None  # the job the forked workers read (set only while the pool runs)


@njit(cache=True, nogil=True)
def _runs_per_slice(mask):  # pragma: no cover - compiled
    nz, h, w = mask.shape
    out = np.zeros(nz, np.int64)
    for k in range(nz):
        n = 0
        for y in range(h):
            prev = False
            for x in range(w):
                v = mask[k, y, x]
                if v and not prev:
                    n += 1
                prev = v
        out[k] = n
    return out


def slice_work(mask: np.ndarray) -> np.ndarray:
    """Per slice of a boolean ``[z, y, x]`` mask, the number of runs of object pixels along x (about
    half the boundary length in pixels): the general mesher's work grows with the slices' contour
    lengths, not their areas."""
    return _runs_per_slice(np.ascontiguousarray(mask, dtype=bool))


def balanced_cuts(work, n_slabs: int, halo: int = DEFAULT_HALO) -> list:
    """Cut slices ``[0, c_1, ..., nz - 1]`` giving up to ``n_slabs`` slabs of about equal work, a gap
    ``k`` weighing ``work[k] + work[k + 1]``; each slab owns at least ``2 * halo`` gaps."""
    w = np.asarray(work, dtype=np.float64)
    nz = len(w)
    if nz < 2:
        return [0, max(nz - 1, 0)]
    gaps = w[:-1] + w[1:] + 1.0
    csum = np.concatenate([[0.0], np.cumsum(gaps)])
    cuts = [0]
    for i in range(1, n_slabs):
        c = int(np.searchsorted(csum, csum[-1] * i / n_slabs))
        if c - cuts[-1] >= 2 * halo and (nz - 1) - c >= 2 * halo:
            cuts.append(c)
    return cuts + [nz - 1]


def _fork_context():
    if "fork" not in multiprocessing.get_all_start_methods():
        return None
    return multiprocessing.get_context("fork")


def mesh_in_slabs(mask, zs, d_yx, o_xy, *, polygon, triangulation, caps):
    """The general mesher's mesh of a prepared volume (``mask``, slice heights ``zs``, pixel size
    ``(dy, dx)``, origin ``(ox, oy)``) made in slabs on ``CONTOURMESH_THREADS`` worker processes,
    in canonical order; None where this route does not apply or does not pay, or a slab failed or
    disagreed with its neighbour (the caller then meshes the volume itself)."""
    n = _threads()
    if n < 2:
        return None
    ctx = _fork_context()
    if ctx is None:
        log.debug("slab route: no fork start method here; one process")
        return None
    t0 = time.perf_counter()
    work = slice_work(mask)
    total = int(work.sum())
    if total < MIN_WORK:
        log.debug("slab route: work estimate %d below %d; one process", total, MIN_WORK)
        return None
    cuts = balanced_cuts(work, n * _SLABS_PER_WORKER)
    if len(cuts) < 3:
        log.debug("slab route: too few slices for two slabs; one process")
        return None
    if not _no_other_threads():
        log.debug("slab route: threads alive in this process (a fork could deadlock): %s; one process",
                  [t.name for t in threading.enumerate()])
        return None
    nslab = len(cuts) - 1
    gaps = work[:-1] + work[1:]
    est = [float(gaps[max(cuts[j] - DEFAULT_HALO, 0): cuts[j + 1] + DEFAULT_HALO].sum()) for j in range(nslab)]
    order = sorted(range(nslab), key=lambda j: -est[j])
    global _JOB
    _JOB = (mask, np.asarray(zs, dtype=np.float64), tuple(float(v) for v in d_yx), tuple(float(v) for v in o_xy),
            cuts, dict(polygon=polygon, triangulation=triangulation, caps=caps))
    try:
        with ctx.Pool(min(n, nslab), initializer=_child_init) as pool:
            pieces = list(pool.imap_unordered(_piece, order, chunksize=1))
    except Exception as exc:  # a slab the mesher could not make: the whole volume in this process
        log.debug("slab route: a slab failed (%s: %s); one process", type(exc).__name__, exc)
        return None
    finally:
        _JOB = None
    t1 = time.perf_counter()
    try:
        V, F = join_pieces(pieces, "volume")
    except SeamMismatch as exc:
        log.debug("slab route: %s; one process", exc)
        return None
    meta = {"method": "contourmesh", "source": "volume", "polygon": polygon, "triangulation": triangulation,
            "caps": caps, "connectivity": "object 6 (4 in slice) / background 26 (8 in slice)"}
    for k in _COUNTS:
        meta[k] = int(sum(p["counts"][k] for p in pieces))
    left = int(sum(p["left"] for p in pieces))
    repaired = int(sum(p["before"] for p in pieces)) - left
    meta.update(self_intersections=left, crossings_repaired=repaired)
    if repaired:
        meta["crossing_repair_max_move"] = max(p["max_move"] for p in pieces)
    if left:
        from .errors import SelfIntersectionWarning, warn_external

        log.warning("volume mesher: %d pairs of faces cross (%d repaired); the mesh is closed but not embedded",
                    left, repaired)
        warn_external(f"volume mesher: {left} pairs of faces still cross ({repaired} repaired); the mesh is "
                      "closed but not embedded (meta['self_intersections'])", SelfIntersectionWarning)
    log.debug("slab route: %d slabs on %d processes, cuts %s; slabs %.2f s, join %.2f s (slab CPU %s s)",
              nslab, min(n, nslab), cuts, t1 - t0, time.perf_counter() - t1,
              [round(p["cpu"], 2) for p in sorted(pieces, key=lambda p: p["j"])])
    return Mesh(V, F, P=len(V), meta=meta)


def _no_other_threads() -> bool:
    """Whether this thread is the process's only one, after stopping tqdm's idle monitor thread
    (tqdm starts one with its first bar, the general mesher's progress bar included, and keeps it
    after the last bar closes; it is started again by the next bar)."""
    import sys

    mon = sys.modules.get("tqdm._monitor")
    for t in threading.enumerate():
        if mon is not None and isinstance(t, mon.TMonitor) and not t.tqdm_cls._instances:
            with t.tqdm_cls.get_lock():
                if t.tqdm_cls.monitor is t:
                    t.tqdm_cls.monitor = None
            t.exit()
    return threading.active_count() == 1


def _child_init():
    os.environ["CONTOURMESH_THREADS"] = "1"  # the workers are the threads


def _piece(j: int) -> dict:
    """Slab ``j`` of the job: its kept faces, seam hashes, counts and crossing tallies."""
    c0 = time.process_time()
    mask, zs, (dy, dx), (ox, oy), cuts, method = _JOB
    nz = len(zs)
    a = max(cuts[j] - DEFAULT_HALO, 0)
    b = min(cuts[j + 1] + DEFAULT_HALO, nz - 1) + 1
    last = j == len(cuts) - 2
    part = SlabPart(lo=cuts[j] - a, hi=cuts[j + 1] - a, last=last, open_below=a > 0, open_above=b < nz)
    sub = np.ascontiguousarray(mask[a:b])
    out = {"j": j, "counts": dict.fromkeys(_COUNTS, 0), "left": 0, "before": 0, "max_move": 0.0}
    if not sub.any():
        V, F, slab = np.zeros((0, 3)), np.zeros((0, 3), np.int64), None
    else:
        m = volume_to_mesh(sub, spacing=(1.0, dy, dx), z=zs[a:b], origin=(ox, oy, 0.0), slab=part, **method)
        V = np.asarray(m.vertices, dtype=np.float64) + 0.0
        F = np.asarray(m.faces, dtype=np.int64)
        slab = m.meta["slab"]
        out["counts"] = {k: int(m.meta[k]) for k in _COUNTS}
    owner, _key, out["hash_seen"], out["hash_own"] = seam_hashes(V, F, zs, j, cuts, a, b)
    mine = owner == j
    if slab is not None:
        # a pair is counted by the slab that owns the higher-numbered of its faces (both faces are
        # the joined mesh's: see the module docstring)
        def counted(p):
            if not len(p):
                return 0
            o = owner[p]
            return int(((o.max(1) == j) & (o.min(1) >= j - 1)).sum())

        out["left"], out["before"] = counted(slab["pairs_left"]), counted(slab["pairs_before"])
        if slab["move"] is not None and mine.any():
            out["max_move"] = float(slab["move"][np.unique(F[mine])].max())
    Fm = F[mine]
    used = np.unique(Fm)
    remap = np.full(len(V), -1, np.int64)
    remap[used] = np.arange(len(used))
    out["V"], out["F"] = V[used], remap[Fm]
    out["cpu"] = time.process_time() - c0
    return out
