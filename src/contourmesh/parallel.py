"""The general mesher on worker processes: a volume built in slabs of slices, numbered and checked as one.

The general volume mesher is mostly Python, so threads cannot share its work (the GIL).  With
``CONTOURMESH_THREADS`` = ``n`` > 1, a volume that takes the general mesher in paper mode
(``refine=None``) and is large enough to pay for it (:data:`MIN_WORK`) is cut into slabs of
slices, more slabs than workers, which ``n`` worker processes forked from the calling process
build at the same time.  The slabs are those of :mod:`contourmesh.seams`: slab ``j`` owns the gaps
``c_j .. c_{j+1}`` (and their slices) and is built with a halo of
:data:`HALO` slices each side, at the whole volume's slice heights.

**What a slab hands back.**  Not faces: its *units*, the joins of its own gaps and the caps of its
own slices as the general mesher makes each of them on its own, in local vertex numbers
(:func:`contourmesh.volumes._assemble`), with the points of the rings they use.  The driver numbers
the units of all slabs in the one-process order (joins by gap, then caps by slice) and makes the
mesh a manifold, tests it for crossing faces (on the threads asked for: the test splits by
heights) and repairs the crossings as the one-process mesher does with its first build
(:func:`contourmesh.volumes._join_units`).  So the mesh is the one-process mesh in the same order,
bit for bit, and ``meta``, area, volume and ``checks()`` are the same: the manifold repairs and the
crossing repair depend on the faces' numbers (Python sets of face numbers, sums over a vertex's
faces in order), so slabs repaired apart and joined by coordinates would differ from the
one-process mesh in the last bit of a few moved vertices (the lobster: one vertex).  A slab is
neither repaired nor tested, so its cut ends cost no more than its other slices.  ``meta``'s
counts are each slab's counts of its own gaps' joins and its own slices' caps, rings and
polygon fallbacks (:class:`~contourmesh.volumes.SlabPart`), added up.

**Checks.**  Each slab also digests every unit within one gap of its seams; two neighbours must
agree on all they share, else the volume is meshed in one process.  Where the whole mesh's
faces still cross so that the one-process mesher would fall back and build again (crossing
fallbacks: the build history is not local to a slab), the volume is meshed in one process too.

**Cuts.**  The slabs are cut on a per-slice work estimate (:func:`slab_work`: runs of object
pixels along x in every fourth row, and small holes those rows cross, weighed :data:`HOLE_WEIGHT`
runs each, counted in one compiled pass on the threads asked for), in the shares of
:func:`slab_shares` (per worker one slab of share 3, one of 2 and one of 1), each cut moved to
where the gaps its two slabs both build weigh least, and handed out largest first.  The
holes matter: the general mesher's work on a slice with holes (labels, joins of rings with holes,
intermediate sections) is many times its work on a slice of the same contour length without, and a
cut's halos cost what the slices they repeat cost, so few cuts should fall where the holes are
(liver x2's six equal slabs spent 7.6 CPU-s against the one-process build's 7.0).

**Processes.**  Linux's ``fork`` only, from the calling process (its compiled kernels are the
children's), and only while no other thread runs in it (tqdm's idle monitor thread is stopped
first, the package's own idle worker threads are let be; a thread holding a lock at the fork
could deadlock a child).  The workers mesh with ``CONTOURMESH_THREADS=1``, locks of their own for tqdm
and the calling process's objects frozen out of their garbage collector (:func:`_child_init`), and
write each slab's piece to a file in memory made for it before the fork (:func:`_slab_files`),
which the calling process reads as it comes in.  Elsewhere, below :data:`MIN_WORK`,
when a worker fails or a seam disagrees, the volume is meshed in this process (each decision
logged at DEBUG): never a different mesh.
"""

from __future__ import annotations

import gc
import logging
import multiprocessing
import os
import pickle
import threading
import time

import numpy as np

from ._kernels import njit
from .intersect import _threads, intersecting_pairs
from .repair import resolve_crossings
from .types import Mesh
from .volumes import VOLUME_COUNTS, SlabPart, _checked, _join_units, volume_meta, volume_to_mesh

__all__ = ["mesh_in_slabs", "slice_work", "slab_work", "balanced_cuts", "MIN_WORK"]

log = logging.getLogger("contourmesh")

#: The slab route is taken only when the volume's work estimate (:func:`slice_work`, summed) is at
#: least this: below it the forks, the halos and the join cost more than the second worker saves
#: (the liver, 16.9 k: 1.4 times faster on two processes; the lobster, 5.4 k, 57 slices: its eight
#: slabs disagree at a seam, and with fewer its halos cost more than the second process saves).
MIN_WORK = 10_000

_JOB = None  # the job the forked workers read (set only while the pool runs)

#: Slices each slab builds beyond each end of its own gaps.  Four, one more than the scale-out
#: default (:data:`contourmesh.seams.DEFAULT_HALO`): with three, a random stack of small shapes
#: (seed 1086 of `scripts/threads_soak.py`) gave a seam on which both
#: slabs agreed and which still differed from the one-process mesh (a join four slices from a cut
#: end chose a bridged join where the whole made an exact one).  With four, that stack and every
#: other of 6,347 stacks that took the slab route in two five-minute soaks (`python
#: scripts/threads_soak.py --seed 1000` and `--seed 20000`) gave the one-process mesh; no bound is proved.
HALO = 4


@njit(cache=True, nogil=True)
def _runs_per_slice(mask, words, lead, reach):  # pragma: no cover - compiled
    nz, h, w = mask.shape
    out = np.zeros(nz, np.int64)
    holes = np.zeros(nz, np.int64)
    ones = np.uint64(0x0101010101010101)  # (eight True bytes)
    none = np.uint64(0)
    for k in range(nz):
        n = 0
        e = 0
        for y in range(0, h, 4):
            prev = False
            end = -1  # where the last run ended
            row = (k * h + y) * w  # (the row's first byte in the mask's memory)
            x = 0
            while x < w:
                # eight bytes at once where they continue the run or the gap in hand (nothing to count)
                i = row + x
                if x + 8 <= w and i >= lead and (i - lead) % 8 == 0:
                    word = words[(i - lead) // 8]
                    if (word == ones) if prev else (word == none):
                        x += 8
                        continue
                v = mask[k, y, x]
                if v and not prev:
                    n += 1
                    # a gap of at most `reach` pixels between two runs, closed within `reach`
                    # rows above and below at its middle: a small hole (or a narrow inlet)
                    if end >= 0 and x - end <= reach:
                        mid = (end + x) // 2
                        for yy in range(y - 1, max(y - reach, 0) - 1, -1):
                            if mask[k, yy, mid]:
                                for y2 in range(y + 1, min(y + reach + 1, h)):
                                    if mask[k, y2, mid]:
                                        e += 1
                                        break
                                break
                if prev and not v:
                    end = x
                prev = v
                x += 1
        out[k] = n
        holes[k] = e
    return out, holes


def _words(mask):
    """The arguments ``(words, lead)`` of :func:`_runs_per_slice` for a boolean mask: its memory
    as 8-byte words from its first 8-byte boundary (``lead`` bytes in), so that the kernel steps
    over eight pixels at once where they all continue the run or the gap it is in (most of a
    slice's row: liver x2's counts in half the time); for a mask not C-contiguous, no words (every
    pixel read on its own).  The counts are those of reading every pixel: a word is skipped only
    where each of its bytes is the one the pixel loop would have read and passed over."""
    if not (mask.flags.c_contiguous and mask.size):
        return np.zeros(0, np.uint64), np.int64(np.iinfo(np.int64).max)
    flat = mask.reshape(-1).view(np.uint8)
    lead = (-flat.ctypes.data) % 8
    if lead >= len(flat):
        return np.zeros(0, np.uint64), np.int64(np.iinfo(np.int64).max)
    return flat[lead: lead + (len(flat) - lead) // 8 * 8].view(np.uint64), np.int64(lead)


def _slice_counts(mask, threads: int = 1):
    """``(runs, small holes)`` per slice (:func:`slice_work`, :func:`slab_work`), the slices split
    in ``threads`` ranges on as many threads (the kernel releases the GIL; liver x2: 0.04-0.05 s on one,
    0.09 s before it stepped over whole words, :func:`_words`)."""
    mask = np.asarray(mask)
    if mask.dtype != np.bool_:
        mask = mask.astype(bool)
    reach = np.int64(_HOLE_REACH)
    nz = len(mask)
    if threads < 2 or nz < 2 * threads:
        return _runs_per_slice(mask, *_words(mask), reach)
    from ._workers import run_all

    bounds = np.linspace(0, nz, threads + 1).astype(int)
    parts = run_all(lambda a, b: _runs_per_slice(mask[a:b], *_words(mask[a:b]), reach),
                    list(zip(bounds[:-1], bounds[1:])), threads)
    return np.concatenate([r for r, _h in parts]), np.concatenate([h for _r, h in parts])


def slice_work(mask: np.ndarray) -> np.ndarray:
    """Per slice of a boolean ``[z, y, x]`` mask, the number of runs of object pixels along x in every
    fourth row (about an eighth of the boundary length in pixels): the general mesher's work grows
    with the slices' contour lengths, not their areas (liver-x2, 413 M voxels: about 0.1 s).  The
    route's size test (:data:`MIN_WORK`) sums it; the cuts weigh small holes too
    (:func:`slab_work`)."""
    return _slice_counts(mask)[0]


#: The gaps between runs that :func:`slab_work` counts as small holes: at most this many pixels
#: wide, closed within as many rows above and below.
_HOLE_REACH = 32

#: A small hole's weight in :func:`slab_work`, in runs.  The general mesher's holes (their labels,
#: the joins of rings with holes, intermediate sections) cost far more than their contours' length:
#: on liver x2, 24 slabs of about equal runs took 0.06 to 1.22 CPU-s, the costly ones those with the
#: vessels' holes (a least-squares fit of the slabs' times on runs and small holes: 25, noisy);
#: with three equal slabs per worker 12 gave the best-balanced slabs of 0, 8, 12, 25 and 50 on
#: liver x2 and the liver, and with the shares of :func:`slab_shares` it did as well as 25 and
#: better than 40.
HOLE_WEIGHT = 12


def slab_work(mask: np.ndarray) -> np.ndarray:
    """The cuts' work estimate per slice: :func:`slice_work` plus :data:`HOLE_WEIGHT` per small hole
    crossed by a sampled row (a gap of at most ``_HOLE_REACH`` pixels between two runs, closed
    within as many rows above and below at its middle; narrow inlets count too)."""
    runs, holes = _slice_counts(mask)
    return runs + HOLE_WEIGHT * holes


def balanced_cuts(work, n_slabs: int, halo: int = HALO, shares=None) -> list:
    """Cut slices ``[0, c_1, ..., nz - 1]`` giving up to ``n_slabs`` slabs of about equal work (or of
    the relative ``shares`` given, one per slab in order: ``len(shares) == n_slabs``), a gap
    ``k`` weighing ``work[k] + work[k + 1]``, each cut moved (by at most a quarter of the smaller
    share of its two slabs) to where the gaps its two slabs both mesh weigh least; each slab owns
    at least ``2 * halo`` gaps."""
    if shares is None:
        shares = [1.0] * int(n_slabs)
    shares = np.asarray(shares, dtype=np.float64)
    if shares.ndim != 1 or len(shares) != n_slabs or not (shares > 0).all():
        raise ValueError(f"shares must be {n_slabs} positive numbers, one per slab; got {shares!r}")
    shares = shares / shares.sum()
    w = np.asarray(work, dtype=np.float64)
    nz = len(w)
    if nz < 2:
        return [0, max(nz - 1, 0)]
    gaps = w[:-1] + w[1:] + 1.0
    csum = np.concatenate([[0.0], np.cumsum(gaps)])
    # the work two slabs repeat around a cut at c: its halo window's gaps
    win = np.array([csum[min(c + halo, nz - 1)] - csum[max(c - halo, 0)] for c in range(nz)])
    cuts = [0]
    ends = np.cumsum(shares)
    for i in range(len(shares) - 1):
        c = int(np.searchsorted(csum, csum[-1] * ends[i]))
        # within a quarter of the smaller share either way, the cut whose halo window is lightest
        share = csum[-1] * min(shares[i], shares[i + 1]) / 4
        lo = int(np.searchsorted(csum, max(csum[c] - share, 0.0)))
        hi = int(np.searchsorted(csum, csum[c] + share))
        cand = np.arange(max(lo, cuts[-1] + 2 * halo), min(hi, nz - 1 - 2 * halo) + 1)
        if len(cand):
            cuts.append(int(cand[np.argmin(win[cand])]))
    return cuts + [nz - 1]


def slab_shares(workers: int) -> list:
    """The relative work of the slabs for ``workers`` processes, in slice order: per worker one slab
    of share 3, one of 2 and one of 1, handed out largest first, so that each worker starts on a
    large slab and the small ones even out what the estimate misjudged, with fewer cuts where the
    work is than equal slabs make (a cut's halos cost what the slices they repeat cost, see
    :data:`HOLE_WEIGHT`).  Modelled from each slab's CPU time (two workers taking the slabs largest
    estimate first; a loaded machine): liver x2 3.8-3.9 s against 4.2-4.3 s for six equal slabs, the
    liver 1.8-1.9 s against 2.1 s; shares 2, 2, 1, 1, 1 did as well on those two but cut the liver
    where its two slabs disagreed (one process)."""
    return [3.0] * workers + [2.0] * workers + [1.0] * workers


def _fork_context():
    if "fork" not in multiprocessing.get_all_start_methods():
        return None
    return multiprocessing.get_context("fork")


def mesh_in_slabs(mask, zs, d_yx, o_xy, *, polygon, triangulation, caps):
    """The general mesher's mesh of a prepared volume (``mask``, slice heights ``zs``, pixel size
    ``(dy, dx)``, origin ``(ox, oy)``) made in slabs on ``CONTOURMESH_THREADS`` worker processes;
    None where this route does not apply or does not pay, or a slab failed or disagreed with its
    neighbour (the caller then meshes the volume itself)."""
    n = _threads()
    if n < 2:
        return None
    ctx = _fork_context()
    if ctx is None:
        log.debug("slab route: no fork start method here; one process")
        return None
    t0 = time.perf_counter()
    runs, holes = _slice_counts(mask, n)
    work = runs + HOLE_WEIGHT * holes  # (slab_work)
    log.debug("slab route: work estimate %.3f s", time.perf_counter() - t0)
    total = int(runs.sum())
    if total < MIN_WORK:
        log.debug("slab route: work estimate %d below %d; one process", total, MIN_WORK)
        return None
    shares = slab_shares(n)
    cuts = balanced_cuts(work, len(shares), shares=shares)
    if len(cuts) < 3:
        log.debug("slab route: too few slices for two slabs; one process")
        return None
    if not _no_other_threads():
        log.debug("slab route: threads alive in this process (a fork could deadlock): %s; one process",
                  [t.name for t in threading.enumerate()])
        return None
    nslab = len(cuts) - 1
    gaps = work[:-1] + work[1:]
    est = [float(gaps[max(cuts[j] - HALO, 0): cuts[j + 1] + HALO].sum()) for j in range(nslab)]
    order = sorted(range(nslab), key=lambda j: -est[j])
    zs = np.asarray(zs, dtype=np.float64)
    dy, dx = (float(v) for v in d_yx)
    global _JOB
    files = _slab_files(nslab)
    _JOB = (mask, zs, (dy, dx), tuple(float(v) for v in o_xy), cuts,
            dict(polygon=polygon, triangulation=triangulation, caps=caps), files)
    pool = ctx.Pool(min(n, nslab), initializer=_child_init)
    try:
        # (each slab read as it comes in, while the workers build the others)
        pieces = sorted((_received(p, files) for p in pool.imap_unordered(_piece, order, chunksize=1)),
                        key=lambda p: p["j"])
    except Exception as exc:  # a slab the mesher could not make: the whole volume in this process
        pool.terminate()
        log.debug("slab route: a slab failed (%s: %s); one process", type(exc).__name__, exc)
        return None
    except BaseException:
        pool.terminate()
        raise
    finally:
        _JOB = None
        for fd in files or ():
            os.close(fd)
    # every slab is in: the workers are let go, and exit while this process joins the slabs (ending
    # them first, as leaving a `with` block of the pool does, waited for their exits: about 0.03 s on
    # liver x2); they are reaped when the mesh is made
    pool.close()
    t1 = time.perf_counter()
    try:
        got = _join(pieces, zs, min(dx, dy), polygon, triangulation, caps)
    finally:
        pool.join()
    if got is not None:
        log.debug("slab route: %d slabs on %d processes, cuts %s; slabs %.2f s, join and checks %.2f s "
                  "(slab CPU %s s)", nslab, min(n, nslab), cuts, t1 - t0, time.perf_counter() - t1,
                  [round(p["cpu"], 2) for p in pieces])
    return got


def _join(pieces, zs, px, polygon, triangulation, caps):
    """The whole mesh from the slabs' units, numbered, repaired, tested and measured as the
    one-process mesher's first build does it; None where two slabs disagree on a unit next to their
    seam, or where faces still cross that would make the one-process mesher build again."""
    for p, q in zip(pieces[:-1], pieces[1:]):
        shared = p["hashes"].keys() & q["hashes"].keys()
        if any(p["hashes"][k] != q["hashes"][k] for k in shared):
            log.debug("slab route: slabs %d and %d disagree on the joins or caps next to their seam; one process",
                      p["j"], q["j"])
            return None
    joins = [(ident, u) for p in pieces for ident, u in p["units"] if ident[0] == "join"]
    capped = [(ident, u) for p in pieces for ident, u in p["units"] if ident[0] == "cap"]
    n_comp = {}
    for p in pieces:
        n_comp.update(p["n_comp"])
    first = np.cumsum([len(joins)] + [n_comp[k] for k in range(len(zs))])
    units = [u for _i, u in joins] + [u for _i, u in capped]
    tags = list(range(len(joins))) + [int(first[ident[1]] + ident[2]) for ident, _u in capped]
    rings = {}
    for p in pieces:
        rings.update(p["rings"])
    tj = time.perf_counter()
    # (no heap trims between the repair's steps, nf=0: see contourmesh._heap.  Here they gave back
    # pages that the next step touched again: on liver x2 14.5 k page faults, 0.04 CPU-s and
    # 0.04-0.07 s of the join, against 4-5 MiB more of the calling process's peak, 762 -> 767 MiB)
    V, F, T = _join_units(units, tags, rings.__getitem__, px, {}, 0)
    tj1 = time.perf_counter()
    # the whole mesh's crossing test (on the threads asked for: intersect splits it by heights),
    # with the faces grouped by the join or cap that made them (T) as the one-process mesher
    # groups them: the voxel-exact faces of one group are certified apart, not paired (same pairs)
    pairs = intersecting_pairs(V, F, groups=T)
    tj2 = time.perf_counter()
    V2, info = resolve_crossings(V, F, 1e-3 * px, planes=zs, pairs=pairs)
    left = info.pop("pairs")
    log.debug("slab route join: units %.2f s, pairs %.2f s, resolve %.2f s", tj1 - tj, tj2 - tj1, time.perf_counter() - tj2)
    if len(left):
        ident_of = dict(zip(tags, [i for i, _u in joins] + [i for i, _u in capped]))
        for t in np.unique(T[np.unique(left)]).tolist():
            if t < 0:
                continue
            ident = ident_of[t]
            if (ident[0] == "join" and ident[4] != "exact") or (ident[0] == "cap" and not ident[3]):
                log.debug("slab route: faces cross that the one-process mesher would rebuild (crossing "
                          "fallbacks); one process")
                return None
    meta = volume_meta(polygon, triangulation, caps,
                       {k: int(sum(p["counts"][k] for p in pieces)) for k in VOLUME_COUNTS})
    return _checked(Mesh(V, F, P=len(V), meta=meta), 1e-3 * px, zs, resolved=(V2, info))


def _slab_files(n: int):
    """``n`` anonymous files in memory (``os.memfd_create``), one per slab, made before the fork so
    that the workers hold them too; None where the system makes none (the slabs then come back
    through the pool's pipe).

    A slab's piece is some megabytes of pickled units (liver x2: 0.7 to 11.7 MiB, 28 MiB in all).
    Through the pipe (64 KiB at a time) the worker waits until the calling process has read the
    last chunk, a switch of processes per chunk, before it takes its next slab: on a loaded machine
    the workers of liver x2 waited 0.17-0.25 s in all between their slabs, 0.04-0.12 s with the
    pieces written to these files (`python benchmarks/threads_speed.py --inputs liver-x2`).  The
    piece read back is the piece written, pickled as the pool pickles it for the pipe, so the mesh
    is the same."""
    make = getattr(os, "memfd_create", None)
    if make is None:
        return None
    files = []
    try:
        for j in range(n):
            files.append(make(f"contourmesh-slab-{j}"))
    except OSError:
        for fd in files:
            os.close(fd)
        return None
    return files


def _received(p: dict, files) -> dict:
    """A slab's piece as :func:`_piece` made it: ``p`` itself where it came through the pool's pipe,
    else read from the slab's file (:func:`_slab_files`)."""
    if not p.get("in_file"):
        return p
    with open(files[p["j"]], "rb", closefd=False) as f:
        f.seek(0)
        return pickle.load(f)


def _no_other_threads() -> bool:
    """Whether this thread is the process's only one, after stopping tqdm's idle monitor thread
    (tqdm starts one with its first bar, the general mesher's progress bar included, and keeps it
    after the last bar closes; it is started again by the next bar), apart from the package's own
    kept worker threads while none of them has work (:func:`contourmesh._workers.kept_threads_idle`:
    the fast path and the crossing test leave them waiting between calls)."""
    import sys

    mon = sys.modules.get("tqdm._monitor")
    for t in threading.enumerate():
        if mon is not None and isinstance(t, mon.TMonitor) and not t.tqdm_cls._instances:
            with t.tqdm_cls.get_lock():
                if t.tqdm_cls.monitor is t:
                    t.tqdm_cls.monitor = None
            t.exit()
    from ._workers import kept_threads_idle

    me = threading.current_thread()
    return all(t is me or kept_threads_idle(t) for t in threading.enumerate())


def _child_init():
    """A worker's set-up: the calling process's objects out of its garbage collector's reach, one
    thread (the workers are the threads), and locks of its own for tqdm.

    ``gc.freeze()``: a full collection in a worker would walk every object inherited from the
    calling process (writing to each, so that the pages holding them are copied) besides the
    slab's own.  After a one-process call of liver x2 the calling process's collector is due for
    one, and a worker's full collection then cost it 0.1-0.17 s on liver x2; the inherited objects
    are the calling process's and live as long as the worker, so nothing is kept that a
    collection would have freed there.  The calling process's collector is not touched.

    tqdm guards its bars with a process-shared semaphore made before the fork; a worker ended
    while holding it (the pool stops its workers when a slab fails) would block the calling
    process's next progress bar for ever.  The workers' bars (disabled ones: the general mesher's)
    take a thread lock of their own instead."""
    import sys

    gc.freeze()
    os.environ["CONTOURMESH_THREADS"] = "1"
    std = sys.modules.get("tqdm.std")
    if std is not None:
        lock = std.TqdmDefaultWriteLock
        lock.mp_lock = None
        lock.th_lock = threading.RLock()
        todo = [std.tqdm]
        while todo:
            c = todo.pop()
            todo.extend(c.__subclasses__())
            if "_lock" in vars(c):
                c._lock = lock()


def _piece(j: int) -> dict:
    """Slab ``j`` of the job: its own joins' and caps' units with their rings' points, the digests
    of the units next to its seams, its own slices' component counts and its meta counts; written
    to the slab's file where the job has files (:func:`_slab_files`; then only ``{"j": j, "in_file":
    True}`` is returned, :func:`_received` reads the rest)."""
    c0 = time.process_time()
    mask, zs, (dy, dx), (ox, oy), cuts, method, files = _JOB
    nz = len(zs)
    a = max(cuts[j] - HALO, 0)
    b = min(cuts[j + 1] + HALO, nz - 1) + 1
    last = j == len(cuts) - 2
    part = SlabPart(lo=cuts[j] - a, hi=cuts[j + 1] - a, last=last, open_below=a > 0, open_above=b < nz, offset=a)
    sub = np.ascontiguousarray(mask[a:b])
    out = {"j": j, "counts": dict.fromkeys(VOLUME_COUNTS, 0), "units": [], "rings": {}, "hashes": {},
           "n_comp": {k: 0 for k in range(cuts[j], cuts[j + 1] + (1 if last else 0))}}
    if sub.any():
        m = volume_to_mesh(sub, spacing=(1.0, dy, dx), z=zs[a:b], origin=(ox, oy, 0.0), slab=part, **method)
        info = m.meta["slab"]
        out["counts"] = {k: int(m.meta[k]) for k in VOLUME_COUNTS}
        out.update(units=info["units"], rings=info["rings"], hashes=info["hashes"])
        out["n_comp"].update(info["n_comp"])
    out["cpu"] = time.process_time() - c0
    if files is None:
        return out
    from multiprocessing.reduction import ForkingPickler

    with open(files[j], "wb", closefd=False) as f:
        f.seek(0)
        f.truncate()
        ForkingPickler(f).dump(out)  # (as the pool pickles a result for its pipe: the same arrays back)
    return {"j": j, "in_file": True}
