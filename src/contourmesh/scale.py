"""Every label of a label volume larger than memory, meshed and measured in pieces (locally or on Dask).

Two passes over a :class:`~contourmesh.io.chunked.ChunkedVolume` (a Zarr store, a ``.npy``
memory map, HDF5, a dask array):

1. **Scan**, one task per tile (a z-slab, cut in y and x along the store's chunks when a whole
   slab would exceed ``scan_voxels``): each label's bounding box and voxel count in the tile
   (``scipy.ndimage.find_objects`` and ``bincount``), and a content hash of the tile.  The
   tiles' boxes are merged into one box per label.  A task holds one tile.
2. **Mesh**, one task per batch of labels: the task reads the union of its labels' padded boxes
   from the store (one read), cuts each label's box out of it (its bounding box padded by one
   voxel and clipped to the volume, exactly the crop that :func:`contourmesh.mesh_labels` cuts)
   and meshes it with :func:`contourmesh.mesh_labels` itself.  The mesh is therefore the
   in-memory one, vertex for vertex, by construction.

A label whose padded box holds more than ``max_box_voxels`` voxels is meshed in **slabs** of
slices, one task per slab, each reading its slices plus a halo of ``halo`` slices each side; the
slabs' faces are joined at their seams by identical vertex coordinates, and the result is the
in-memory mesh after a canonical ordering (:mod:`contourmesh.seams`).  With ``meshes=False`` the
slabs send their area, volume, vertex, edge and component counts and no faces, and the label's
row is summed from them without assembling its mesh.  With ``refine="band"`` such a label is
refused (:class:`LabelTooLarge`, raised before any meshing): the refinement is not local to a
slab (see :mod:`contourmesh.seams`).

A label the mesher raises on becomes a row with ``status`` ``"failed: <error>"`` (and no mesh)
instead of stopping the run; in memory, :func:`contourmesh.mesh_labels` raises.

Each batch's result is written atomically to a cache folder under a key made of the options, the
labels and their boxes, and the content hashes of the tiles the batch reads, so a rerun after a
crash or Ctrl-C skips the batches already done, and a changed voxel invalidates exactly the
batches whose boxes cross its tile.  Tasks are pure: a task rerun by Dask after its worker died
writes the same file.

See ``docs/scale-out.md``.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .io.chunked import ChunkedVolume, digest, open_chunked

__all__ = ["scan_labels", "mesh_labels_chunked", "LabelScan", "LabelTooLarge", "DEFAULT_MAX_BOX_VOXELS",
           "write_label_outputs"]

log = logging.getLogger("contourmesh")

#: Default per-task budget: the largest padded label box (in voxels) a mesh task reads.  A uint32
#: box of this size is 256 MiB; the mesher's working memory on it is a few times its boolean mask.
DEFAULT_MAX_BOX_VOXELS = 2**26

_CACHE_VERSION = 2
_LARGE_LABEL = 2**24  # above this label value (or 4 x the slab's voxels) the scan compacts labels first


class LabelTooLarge(ValueError):
    """A label's padded bounding box exceeds the per-task memory budget (``max_box_voxels``)."""


@dataclass
class LabelScan:
    """What the scan pass found.

    ``labels`` (n,) int64, sorted; ``boxes`` (n, 6) int64 ``zmin, zmax, ymin, ymax, xmin, xmax``
    inclusive; ``voxels`` (n,) int64 counts; ``tiles`` the ``(z0, z1, y0, y1, x0, x1)`` boxes
    scanned and ``digests`` their content hashes.
    """

    shape: tuple
    dtype: str
    labels: np.ndarray
    boxes: np.ndarray
    voxels: np.ndarray
    tiles: list
    digests: list

    def padded(self, i: int):
        """Label ``i``'s box padded by one voxel and clipped to the volume: ``(lo, hi)``, hi exclusive."""
        b = self.boxes[i]
        lo = [max(int(b[2 * a]) - 1, 0) for a in range(3)]
        hi = [min(int(b[2 * a + 1]) + 2, n) for a, n in enumerate(self.shape)]
        return lo, hi


# ------------------------------------------------------------------------------------------------
# pass 1: boxes and counts, slab by slab
# ------------------------------------------------------------------------------------------------
def _scan_slab(vol: ChunkedVolume, z0: int, z1: int, y0: int, y1: int, x0: int, x1: int):
    """Labels present in the tile, their boxes (global, inclusive), voxel counts and the tile's hash."""
    from scipy import ndimage

    slab = vol.read((z0, z1), (y0, y1), (x0, x1))
    h = digest(slab)
    if slab.dtype.kind == "b":
        slab = slab.view(np.uint8)
    if slab.dtype.kind == "i" and slab.size and slab.min() < 0:
        raise ValueError(f"{vol.where}: labels must be >= 0 (0 is the background); slices {z0}-{z1 - 1} hold "
                         f"{int(slab.min())}")
    top = int(slab.max()) if slab.size else 0
    if top == 0:
        return np.zeros(0, np.int64), np.zeros((0, 6), np.int64), np.zeros(0, np.int64), h
    if top <= max(_LARGE_LABEL, 4 * slab.size):
        compact = slab
        values = None
    else:  # huge label values: number the labels present 1..m first
        values, inverse = np.unique(slab, return_inverse=True)
        compact = inverse.reshape(slab.shape).astype(np.int64)
        if values[0] != 0:
            compact += 1
            values = np.concatenate([[0], values])
    objs = ndimage.find_objects(compact)
    counts = np.bincount(compact.ravel(), minlength=len(objs) + 1)
    labs, boxes, n = [], [], []
    for i, b in enumerate(objs):
        if b is None:
            continue
        labs.append(i + 1 if values is None else int(values[i + 1]))
        boxes.append((b[0].start + z0, b[0].stop - 1 + z0, b[1].start + y0, b[1].stop - 1 + y0, b[2].start + x0,
                      b[2].stop - 1 + x0))
        n.append(counts[i + 1])
    return np.array(labs, np.int64), np.array(boxes, np.int64).reshape(-1, 6), np.array(n, np.int64), h


def _merge_scans(parts):
    labs = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, np.int64)
    if not len(labs):
        return labs, np.zeros((0, 6), np.int64), np.zeros(0, np.int64)
    boxes = np.concatenate([p[1] for p in parts])
    n = np.concatenate([p[2] for p in parts])
    order = np.argsort(labs, kind="stable")
    labs, boxes, n = labs[order], boxes[order], n[order]
    starts = np.flatnonzero(np.r_[True, labs[1:] != labs[:-1]])
    out = np.empty((len(starts), 6), np.int64)
    for a in range(3):
        out[:, 2 * a] = np.minimum.reduceat(boxes[:, 2 * a], starts)
        out[:, 2 * a + 1] = np.maximum.reduceat(boxes[:, 2 * a + 1], starts)
    return labs[starts], out, np.add.reduceat(n, starts)


def scan_labels(source, *, slab: int | None = None, scan_voxels: int = DEFAULT_MAX_BOX_VOXELS, jobs: int | None = 1,
                client=None, scheduler=None, dataset: str | None = None, progress: bool = False) -> LabelScan:
    """Pass 1: every label's bounding box and voxel count, one tile at a time.

    ``slab`` is the tiles' depth in slices (default: the store's chunk depth); a slab larger
    than ``scan_voxels`` is cut in y and x along the store's chunks.  Memory per task: one tile.
    """
    vol = open_chunked(source, dataset=dataset)
    with _Executor(jobs, client, scheduler, vol) as ex:
        return _scan(vol, ex, slab, scan_voxels, progress)


def _scan(vol, ex, slab, scan_voxels, progress) -> LabelScan:
    tiles = vol.tiles(slab, int(scan_voxels))
    parts = dict(ex.map(_scan_slab, tiles, progress=progress, desc="scan"))
    ordered = [parts[t] for t in tiles]
    labs, boxes, n = _merge_scans([p[:3] for p in ordered])
    return LabelScan(vol.shape, vol.dtype.str, labs, boxes, n, tiles, [p[3] for p in ordered])


# ------------------------------------------------------------------------------------------------
# pass 2: one task per batch of labels
# ------------------------------------------------------------------------------------------------
def _plan(scan: LabelScan, idx: list, chunks, max_box_voxels: int, batch: int):
    """Batches of label indices, spatially grouped (by the store chunk of the box's centre), each
    batch's union box within ``max_box_voxels``."""
    centre = np.stack([(scan.boxes[idx, 2 * a] + scan.boxes[idx, 2 * a + 1]) // 2 // chunks[a] for a in range(3)], 1)
    order = [idx[k] for k in np.lexsort((centre[:, 2], centre[:, 1], centre[:, 0]))]
    batches, cur, ulo, uhi = [], [], None, None
    for i in order:
        lo, hi = scan.padded(i)
        if cur:
            nlo = [min(a, b) for a, b in zip(ulo, lo)]
            nhi = [max(a, b) for a, b in zip(uhi, hi)]
            if len(cur) < batch and int(np.prod([b - a for a, b in zip(nlo, nhi)])) <= max_box_voxels:
                cur.append(i)
                ulo, uhi = nlo, nhi
                continue
            batches.append((cur, ulo, uhi))
        cur, ulo, uhi = [i], lo, hi
    if cur:
        batches.append((cur, ulo, uhi))
    return batches


def _method_key(method: dict) -> dict:
    return {k: method.get(k) for k in ("polygon", "triangulation", "caps", "refine")}


def _batch_key(scan: LabelScan, idx, ulo, uhi, spacing, origin, method, meshes: bool, slab=None) -> str:
    tiles = [(t, d) for t, d in zip(scan.tiles, scan.digests)
             if all(t[2 * a] < uhi[a] and t[2 * a + 1] > ulo[a] for a in range(3))]
    desc = {"v": _CACHE_VERSION, "shape": list(scan.shape), "dtype": scan.dtype,
            "labels": [int(scan.labels[i]) for i in idx], "boxes": [scan.boxes[i].tolist() for i in idx],
            "spacing": list(map(float, spacing)), "origin": list(map(float, origin)), "method": _method_key(method),
            "meshes": bool(meshes), "tiles": tiles, "slab": slab}
    from . import __version__

    desc["contourmesh"] = __version__
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:32]


def _jsonable(meta: dict) -> dict:
    out = {}
    for k, v in meta.items():
        if isinstance(v, (np.integer, np.floating, np.bool_)):
            v = v.item()
        if isinstance(v, tuple):
            v = list(v)
        try:
            json.dumps(v)
        except (TypeError, ValueError):
            continue
        out[k] = v
    return out


def _status(chk: dict) -> str:
    if not chk["closed"]:
        return "not closed and outward (not written)"
    return "ok" if chk["ok"] else f"closed, {chk['self_intersections']} crossing face pairs"


def _mesh_batch(vol: ChunkedVolume, labels, los, his, ulo, uhi, spacing, origin, method, meshes: bool,
                cache_file: str | None):
    """One mesh task: the rows (and meshes) of a batch of labels; from the cache when it is there."""
    from .api import label_row, mesh_labels

    if cache_file is not None and os.path.isfile(cache_file):
        try:
            return _load_batch(cache_file, meshes)
        except Exception as exc:  # a damaged cache file is recomputed, never trusted
            log.warning("cache file %s unreadable (%s); recomputing", cache_file, exc)
    t0, c0 = time.perf_counter(), time.process_time()
    box = vol.read((ulo[0], uhi[0]), (ulo[1], uhi[1]), (ulo[2], uhi[2]))
    t_read = time.perf_counter() - t0
    rows, arrays = [], {}
    for lab, lo, hi in zip(labels, los, his):
        sub = box[lo[0] - ulo[0]:hi[0] - ulo[0], lo[1] - ulo[1]:hi[1] - ulo[1], lo[2] - ulo[2]:hi[2] - ulo[2]]
        crop = (sub == lab).view(np.uint8)  # the same mask mesh_labels cuts from the whole volume
        o = (origin[0] + lo[2] * spacing[2], origin[1] + lo[1] * spacing[1], origin[2] + lo[0] * spacing[0])
        try:
            (_, m, _), = mesh_labels(crop, labels=[1], spacing=tuple(spacing), origin=o, **method)
        except Exception as exc:  # one label the mesher cannot mesh does not stop the other thousands
            msg = " ".join(str(exc).split())
            rows.append({"label": int(lab), "status": f"failed: {type(exc).__name__}: {msg}"})
            continue
        row = label_row(int(lab), m, (0,) * 6)  # the box is filled in by the driver, from the scan
        row["status"] = _status(m.checks())
        rows.append(row)
        if meshes:
            arrays[f"v{lab}"] = m.vertices
            arrays[f"f{lab}"] = m.faces
            arrays[f"m{lab}"] = np.frombuffer(json.dumps(_jsonable(dict(m.meta, label=int(lab)))).encode(), np.uint8)
    info = {"rows": rows, "read_s": t_read, "total_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
            "voxels": int(box.size),
            "pid": os.getpid()}
    arrays["info"] = np.frombuffer(json.dumps(info).encode(), np.uint8)
    if cache_file is not None:
        from .meshes import atomic_write

        buf = io.BytesIO()
        np.savez(buf, **arrays)
        atomic_write(cache_file, buf.getvalue(), force=True)
    return info, (arrays if meshes else None), False


def _mesh_slab(vol: ChunkedVolume, lab, lo, hi, cuts, j, halo, spacing, origin, method, meshes: bool,
               cache_file: str | None):
    """One slab of a label too large for one task (:func:`contourmesh.seams.slab_piece`); cached."""
    from .seams import slab_piece
    from .volume_input import check_origin, check_spacing

    if cache_file is not None and os.path.isfile(cache_file):
        try:
            return _load_piece(cache_file)
        except Exception as exc:  # a damaged cache file is recomputed, never trusted
            log.warning("cache file %s unreadable (%s); recomputing", cache_file, exc)
    t0, c0 = time.perf_counter(), time.process_time()
    nz = hi[0] - lo[0]
    a = max(cuts[j] - halo, 0)
    b = min(cuts[j + 1] + halo, nz - 1) + 1
    sub = vol.read((lo[0] + a, lo[0] + b), (lo[1], hi[1]), (lo[2], hi[2]))
    t_read = time.perf_counter() - t0
    mask = (sub == lab).view(np.uint8)
    del sub
    # the heights and origin of the whole padded box, computed as mesh_labels and prepare_volume do
    o = check_origin((origin[0] + lo[2] * spacing[2], origin[1] + lo[1] * spacing[1], origin[2] + lo[0] * spacing[0]))
    sp = check_spacing(spacing)
    zs = o[2] + sp[0] * np.arange(nz, dtype=np.float64)
    piece = slab_piece(mask, zs, j, cuts, halo, tuple(spacing), tuple(float(v) for v in o), method, meshes)
    piece["label"] = int(lab)
    piece["info"] = {"read_s": t_read, "total_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
                     "voxels": int(mask.size), "pid": os.getpid()}
    if cache_file is not None:
        from .meshes import atomic_write

        arrays = {k: v for k, v in piece.items() if isinstance(v, np.ndarray)}
        rest = {k: v for k, v in piece.items() if not isinstance(v, np.ndarray)}
        rest["hash_own"] = {str(k): v for k, v in rest["hash_own"].items()}
        rest["hash_seen"] = {str(k): v for k, v in rest["hash_seen"].items()}
        arrays["json"] = np.frombuffer(json.dumps(rest).encode(), np.uint8)
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        atomic_write(cache_file, buf.getvalue(), force=True)
    piece["cached"] = False
    return piece


def _load_piece(path: str):
    with np.load(path, allow_pickle=False) as z:
        piece = json.loads(bytes(z["json"]).decode())
        piece.update({k: z[k] for k in z.files if k != "json"})
    piece["hash_own"] = {int(k): v for k, v in piece["hash_own"].items()}
    piece["hash_seen"] = {int(k): v for k, v in piece["hash_seen"].items()}
    piece["cached"] = True
    return piece


def _task(vol: ChunkedVolume, kind: str, *args):
    return (_mesh_batch if kind == "batch" else _mesh_slab)(vol, *args)


def _load_batch(path: str, meshes: bool):
    with np.load(path, allow_pickle=False) as z:
        info = json.loads(bytes(z["info"]).decode())
        arrays = {k: z[k] for k in z.files} if meshes else None
    return info, arrays, True


def _check_method(method: dict) -> dict:
    """The method keywords, checked once in the driver (a bad option fails before any task runs)."""
    from .api import _refine_method, _volume_caps

    if _refine_method(method.get("refine")) is None:  # refined labels take caps="smooth" too
        _volume_caps(method.get("caps", "flat"), "every label of a volume is meshed by the volume mesher")
    return method


def mesh_labels_chunked(source, *, labels=None, spacing=None, origin=None, polygon: str = "mlp",
                        triangulation: str | None = None, caps: str = "flat", refine: str | None = None,
                        meshes: bool = True, jobs: int | None = None, client=None, scheduler: str | None = None,
                        cache=None, max_box_voxels: int = DEFAULT_MAX_BOX_VOXELS, batch: int | None = None,
                        slab: int | None = None, scan_voxels: int = DEFAULT_MAX_BOX_VOXELS,
                        dataset: str | None = None, progress: bool = False, scan=None,
                        stats: dict | None = None, halo: int | None = None):
    """Mesh every non-zero label of a chunked label volume; yields ``(label, Mesh or None, bbox, row)``.

    The results are those of :func:`contourmesh.mesh_labels` on the whole array (the same meshes,
    vertex for vertex), but the volume is never held whole: see the module's docstring.  They are
    yielded as batches finish (sort by label if order matters).

    Parameters
    ----------
    source : path, zarr/numpy/dask array or ChunkedVolume
        See :func:`contourmesh.io.chunked.open_chunked` (``dataset=`` names an array in a Zarr
        group or an HDF5 file).
    labels, spacing, origin, polygon, triangulation, caps, refine
        As for :func:`contourmesh.mesh_labels`.
    meshes : bool
        False: compute each label's row only (``Mesh`` is None), and do not keep the meshes.
    jobs : int, optional
        Worker processes of the local pool (default ``os.cpu_count()``; 1 runs in this process).
    client : dask.distributed.Client, optional
        Run the tasks on this client's cluster instead (``scheduler=`` an address to connect to).
    cache : path, optional
        Folder for the per-batch results (created); a rerun with the same input and options
        reuses the batches already there.  With Dask it must be reachable from the workers.
    max_box_voxels : int
        Per-task budget: the largest padded label box (and batch union box) read by one task.
        A label above it is meshed in slabs of slices joined at their seams, each slab reading at
        most this many voxels (:mod:`contourmesh.seams`); with ``refine="band"``, or when not even
        one slice gap and the halo fit, it raises :class:`LabelTooLarge` before any meshing.
    halo : int, optional
        Slices a slab reads beyond each of its ends (default
        :data:`contourmesh.seams.DEFAULT_HALO` = 3; ``--halo`` on the command line).  With
        ``refine`` it raises :class:`~contourmesh.errors.InapplicableOption` (no label is cut into slabs).
    batch : int, optional
        At most this many labels per task (default: about eight tasks per worker, at most 16
        labels each).
    slab, scan_voxels
        Tiles of the scan pass: ``slab`` slices deep (default: the store's chunk depth), a slab
        cut in y and x along the store's chunks when it holds more than ``scan_voxels``.
    scan : LabelScan, optional
        A scan from :func:`scan_labels` of the same source, to skip pass 1.
    stats : dict, optional
        Filled with timings: ``scan_s`` and ``mesh_s`` (wall time of the two passes), ``tasks``,
        ``cached`` (tasks served from the cache), and sums over the mesh tasks run: ``read_s``
        (reading boxes), ``task_s`` (wall) and ``cpu_s`` (CPU time of the worker process).
    """
    from .api import _with_meta
    from .types import Mesh
    from .volume_input import check_origin, check_spacing

    vol = open_chunked(source, dataset=dataset)
    sp = check_spacing((1.0, 1.0, 1.0) if spacing is None else spacing)
    org = check_origin((0.0, 0.0, 0.0) if origin is None else origin)
    sp, org = tuple(float(s) for s in sp), tuple(float(o) for o in org)
    method = _check_method(dict(polygon=polygon, triangulation=triangulation, caps=caps, refine=refine))
    if int(max_box_voxels) < 27:
        raise ValueError(f"max_box_voxels must be at least 27 (a one-voxel label's padded box); got {max_box_voxels}")
    if batch is not None and int(batch) < 1:
        raise ValueError(f"batch must be at least 1; got {batch}")
    from .errors import InapplicableOption
    from .seams import DEFAULT_HALO

    if halo is not None and _refine_method_of(method) is not None:
        raise InapplicableOption(f"halo= does not apply with refine= {_refine_method_of(method)!r}: its "
                                 "labels are never cut into slabs (one above max_box_voxels is refused), so there "
                                 "is no seam to read a halo across")
    halo = DEFAULT_HALO if halo is None else halo
    if int(halo) != halo or halo < 1:
        raise ValueError(f"halo must be a positive number of slices; got {halo!r}")
    halo = int(halo)
    stats = {} if stats is None else stats
    cache_dir = None
    if cache is not None:
        cache_dir = Path(cache).expanduser()
        cache_dir.mkdir(parents=True, exist_ok=True)
    with _Executor(jobs, client, scheduler, vol) as ex:
        t0 = time.perf_counter()
        if scan is None:
            scan = _scan(vol, ex, slab, scan_voxels, progress)
        elif tuple(scan.shape) != vol.shape:
            raise ValueError(f"scan= was made on a volume of shape {scan.shape}, not {vol.shape}")
        stats["scan_s"] = time.perf_counter() - t0
        index = {int(lab): i for i, lab in enumerate(scan.labels)}
        if labels is None:
            idx = list(range(len(scan.labels)))
        else:
            wanted = [int(v) for v in labels]
            missing = sorted(set(wanted) - set(index))
            if missing:
                raise ValueError(f"no voxel has label {missing[0]}" + (f" (nor {missing[1:]})" if len(missing) > 1 else ""))
            idx = sorted({index[v] for v in wanted})
        from .seams import slab_cuts

        big, small, slabbed = [], [], {}
        for i in idx:
            lo, hi = scan.padded(i)
            size = int(np.prod([b - a for a, b in zip(lo, hi)]))
            if size <= max_box_voxels:
                small.append(i)
                continue
            desc = (f"label {int(scan.labels[i])} (padded box {' x '.join(str(b - a) for a, b in zip(lo, hi))}"
                    f" = {size} voxels)")
            if _refine_method_of(method) is not None:
                big.append(desc)
                continue
            cuts = slab_cuts(hi[0] - lo[0], (hi[1] - lo[1]) * (hi[2] - lo[2]), int(max_box_voxels), halo)
            if cuts is None:
                big.append(desc + f": one slice of it with a halo of {halo} slices each side does not fit")
                continue
            slabbed[i] = cuts
        if big:
            why = ("refine='band' is not meshed in slabs (its blur width, meridians and route are decided on "
                   "the whole object)" if _refine_method_of(method) is not None else
                   "They cannot be cut into slabs within it")
            raise LabelTooLarge(f"{vol.where}: {len(big)} label(s) exceed the per-task budget max_box_voxels="
                                f"{int(max_box_voxels)}: {'; '.join(big[:10])}{' ...' if len(big) > 10 else ''}. "
                                f"{why}; raise max_box_voxels (--max-box-voxels) and the workers' memory to mesh "
                                "them")
        if batch is None:
            batch = max(1, min(16, -(-len(small) // (8 * ex.workers()))))
        plan = _plan(scan, small, vol.chunks, int(max_box_voxels), int(batch)) if small else []
        tasks = []
        for members, ulo, uhi in plan:
            los, his = zip(*(scan.padded(i) for i in members))
            key = _batch_key(scan, members, ulo, uhi, sp, org, method, meshes)
            cf = None if cache_dir is None else str(cache_dir / f"batch-{key}.npz")
            tasks.append(("batch", [int(scan.labels[i]) for i in members], list(los), list(his), ulo, uhi, sp, org,
                          method, bool(meshes), cf))
        pending = {}
        for i, cuts in slabbed.items():
            lo, hi = scan.padded(i)
            lab = int(scan.labels[i])
            pending[lab] = []
            for j in range(len(cuts) - 1):
                a = max(cuts[j] - halo, 0)
                b = min(cuts[j + 1] + halo, hi[0] - lo[0] - 1) + 1
                key = _batch_key(scan, [i], [lo[0] + a, lo[1], lo[2]], [lo[0] + b, hi[1], hi[2]], sp, org, method,
                                 meshes, slab=[j, cuts, halo])
                cf = None if cache_dir is None else str(cache_dir / f"slab-{key}.npz")
                tasks.append(("slab", lab, lo, hi, cuts, j, halo, sp, org, method, bool(meshes), cf))
        stats.update(tasks=len(tasks), cached=0, read_s=0.0, task_s=0.0, cpu_s=0.0, labels=len(idx),
                     slabbed_labels=len(slabbed), slab_tasks=len(tasks) - len(plan))
        t1 = time.perf_counter()
        for args, res in ex.map(_task, tasks, progress=progress, desc="labels"):
            if args[0] == "slab":
                info = res["info"]
                stats["cached"] += bool(res["cached"])
                stats["read_s"] += info["read_s"]
                stats["task_s"] += info["total_s"]
                stats["cpu_s"] += info.get("cpu_s", 0.0)
                lab = int(args[1])
                pending[lab].append(res)
                if len(pending[lab]) < len(args[4]) - 1:
                    continue
                yield _join_label(pending.pop(lab), lab, scan, index, meshes)
                continue
            info, arrays, cached = res
            stats["cached"] += bool(cached)
            stats["read_s"] += info["read_s"]
            stats["task_s"] += info["total_s"]
            stats["cpu_s"] += info.get("cpu_s", 0.0)
            for row in info["rows"]:
                lab = int(row["label"])
                i = index[lab]
                bbox = tuple(int(v) for v in scan.boxes[i])
                row.update(zip(("zmin", "zmax", "ymin", "ymax", "xmin", "xmax"), bbox))
                row["voxels"] = int(scan.voxels[i])
                m = None
                if arrays is not None and f"v{lab}" in arrays:
                    meta = json.loads(bytes(arrays[f"m{lab}"]).decode())
                    m = Mesh(arrays[f"v{lab}"], arrays[f"f{lab}"], P=row["P"], meta=meta)
                    m = _with_meta(m, label=lab)
                yield lab, m, bbox, row
        stats["mesh_s"] = time.perf_counter() - t1


def _refine_method_of(method: dict):
    r = method.get("refine")
    return None if r in (None, "none") else r


def _join_label(pieces, lab: int, scan: LabelScan, index: dict, meshes: bool):
    """A slabbed label's ``(label, Mesh or None, bbox, row)`` from its slabs."""
    from .api import _with_meta, label_row
    from .seams import SeamMismatch, join_pieces, join_stats
    from .types import Mesh

    i = index[lab]
    bbox = tuple(int(v) for v in scan.boxes[i])
    m = None
    try:
        if meshes:
            V, F = join_pieces(pieces, lab)
            m = _with_meta(Mesh(V, F, P=len(V), meta={"method": "contourmesh", "source": "volume",
                                                       "route": "volume-slabs", "slabs": len(pieces)}), label=lab)
            row = label_row(lab, m, bbox)
            row["status"] = _status(m.checks())
        else:
            st = join_stats(pieces, lab)
            row = {"label": lab, **{k: st[k] for k in ("area", "volume", "P", "faces", "genus", "components",
                                                        "watertight", "self_intersections")}}
            row.update(zip(("zmin", "zmax", "ymin", "ymax", "xmin", "xmax"), bbox))
            row["status"] = _status(st)
    except SeamMismatch as exc:
        row = {"label": lab, "status": f"failed: SeamMismatch: {exc}"}
        row.update(zip(("zmin", "zmax", "ymin", "ymax", "xmin", "xmax"), bbox))
        m = None
    row["voxels"] = int(scan.voxels[i])
    return lab, m, bbox, row


# ------------------------------------------------------------------------------------------------
# executors: in this process, a local process pool, or Dask
# ------------------------------------------------------------------------------------------------
class _Executor:
    """``map(fn, arg_tuples)`` yielding ``(args, fn(vol, *args))`` as tasks finish."""

    def __init__(self, jobs, client, scheduler, vol):
        if client is not None and scheduler is not None:
            raise ValueError("give client= or scheduler=, not both")
        if (client is not None or scheduler is not None) and jobs not in (None,):
            raise ValueError("jobs= sets the local process pool; with a Dask client or scheduler the cluster's "
                             "workers run the tasks")
        if jobs is not None and (int(jobs) != jobs or jobs < 1):
            raise ValueError(f"jobs must be a positive integer; got {jobs!r}")
        self.vol = vol
        self.client = client
        self.scheduler = scheduler
        self.jobs = int(jobs) if jobs is not None else (os.cpu_count() or 1)
        self._own_client = False
        self._pool = None
        self._vol_ref = vol
        self._started = False

    def __enter__(self):
        if self.scheduler is not None or self.client is not None:
            from ._optional import require

            require("distributed", "scale")
        return self

    def _start(self):
        if self._started:
            return
        self._started = True
        if self.scheduler is not None and self.client is None:
            from distributed import Client

            self.client = Client(self.scheduler)
            self._own_client = True
        if self.client is not None:
            if self.vol.kind in ("numpy", "dask"):  # the data travel once, not with every task
                self._vol_ref = self.client.scatter(self.vol, broadcast=True)
            return
        if self.jobs > 1 and self._pool is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("spawn"))

    def workers(self) -> int:
        self._start()
        if self.client is not None:
            return max(1, sum(self.client.nthreads().values()))
        return self.jobs

    def map(self, fn, arg_list, *, progress=False, desc=""):
        from tqdm.auto import tqdm

        arg_list = [tuple(a) for a in arg_list]
        bar = tqdm(total=len(arg_list), desc=desc, disable=not progress, leave=False)
        try:
            self._start()
            if self.client is not None:
                from distributed import as_completed

                futs = {}
                for k, args in enumerate(arg_list):
                    f = self.client.submit(fn, self._vol_ref, *args, pure=False, retries=2,
                                           key=f"contourmesh-{fn.__name__}-{k}-{os.getpid()}-{id(arg_list)}")
                    futs[f] = args
                yield from _drain(futs, as_completed, bar)
            elif self._pool is not None:
                from concurrent.futures import as_completed

                futs = {self._pool.submit(fn, self.vol, *args): args for args in arg_list}
                yield from _drain(futs, as_completed, bar)
            else:
                for args in arg_list:
                    res = fn(self.vol, *args)
                    bar.update()
                    yield args, res
        finally:
            bar.close()

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._own_client:
            self.client.close()
        return False


# ------------------------------------------------------------------------------------------------
# outputs: one mesh file per label and labels.csv, all written atomically
# ------------------------------------------------------------------------------------------------
def write_label_outputs(results, out, *, fmt: str = "ply", write_meshes: bool = True, force: bool = False):
    """Write each label's mesh (``label_N.fmt``, when ``write_meshes`` and it passed its checks) and
    ``out/labels.csv`` (rows sorted by label).  Returns ``(rows, failed)``."""
    import csv

    from .meshes import atomic_write

    out = Path(out)
    rows, failed = [], 0
    for lab, m, _bbox, row in results:
        ok = not row["status"].startswith(("not closed", "failed"))
        failed += not ok
        if ok and write_meshes and m is not None:
            target = out / f"label_{lab}.{fmt}"
            if target.exists() and not force:
                raise FileExistsError(f"output file {str(target)!r} already exists (use --force to overwrite)")
            m.save(target, force=True)
            row["file"] = target.name
        rows.append(row)
    rows.sort(key=lambda r: r["label"])
    buf = io.StringIO()
    fields = list(dict.fromkeys(k for r in rows for k in r))
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write(out / "labels.csv", buf.getvalue().encode(), force=True)
    return rows, failed


# ------------------------------------------------------------------------------------------------
# the command line's --all-labels route for chunked inputs
# ------------------------------------------------------------------------------------------------
_CHUNK_FLAGS = ("jobs", "scheduler", "cache", "max_box_voxels", "halo")


def cli_wants_chunked(args) -> bool:
    """Whether ``contourmesh mesh --all-labels`` takes the piece-by-piece route: a Zarr store or
    HDF5 file, or any of ``--jobs --scheduler --cache --max-box-voxels --halo``."""
    from .io.chunked import _HDF5, _is_zarr_dir

    given = [f for f in _CHUNK_FLAGS if getattr(args, f, None) is not None]
    if not args.all_labels:
        if given:
            raise ValueError(f"--{given[0].replace('_', '-')} applies with --all-labels only")
        return False
    p = Path(args.source).expanduser()
    return bool(given) or _is_zarr_dir(p) or p.name.lower().endswith(_HDF5 + (".zarr", ".n5"))


def run_cli_chunked(args, out: Path) -> int:
    import shutil

    if args.axis not in (None, 0):
        raise ValueError("--axis does not apply with --all-labels: label volumes are sliced along their first axis")
    if args.jobs is not None and args.scheduler is not None:
        raise ValueError("--jobs sets the local process pool; with --scheduler the cluster's workers run the tasks")
    vol = open_chunked(args.source)  # a bad input fails before the output folder is made
    out.mkdir(exist_ok=True)
    cache = Path(args.cache) if args.cache is not None else out / ".contourmesh-cache"
    stats = {}
    results = mesh_labels_chunked(
        vol, spacing=args.spacing, polygon=args.polygon, triangulation=args.triangulation, caps=args.caps,
        refine=args.refine, meshes=not args.stats_only, jobs=args.jobs, scheduler=args.scheduler, cache=cache,
        max_box_voxels=args.max_box_voxels or DEFAULT_MAX_BOX_VOXELS, halo=args.halo, progress=not args.quiet,
        stats=stats)
    rows, failed = write_label_outputs(results, out, fmt=args.format.lstrip("."), write_meshes=not args.stats_only,
                                       force=args.force)
    if not rows:
        raise ValueError(f"{args.source!r}: nothing to mesh (no non-zero label)")
    if args.cache is None:
        shutil.rmtree(cache, ignore_errors=True)
    print(f"wrote {(out / 'labels.csv').resolve()}: {len(rows)} labels"
          + ("" if args.stats_only else f", one .{args.format.lstrip('.')} each")
          + f" ({stats.get('tasks', 0)} tasks, {stats.get('cached', 0)} from the cache)"
          + (f"; {failed} failed their checks" if failed else ""))
    return 1 if failed else 0


def _drain(futs: dict, as_completed, bar):
    """Yield ``(args, result)`` of the futures ``futs`` (future -> args) as they finish, advancing
    ``bar``; the ones left are cancelled if the caller stops early or a task raises."""
    try:
        for f in as_completed(futs):
            res = f.result()
            bar.update()
            yield futs[f], res
    finally:
        for f in futs:
            f.cancel()
