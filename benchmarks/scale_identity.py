"""Identity of the piece-by-piece route with in-memory meshing on real and synthetic label volumes (issue 17).

For each source, each mode and each budget: every label meshed in memory (``mesh_labels``) and
by ``mesh_labels_chunked`` from a Zarr copy of the volume (``jobs=1``), with meshes and stats
only.  A label is identical when its canonical mesh (vertices sorted, faces renumbered, rotated
and sorted) hashes the same and its row (area, volume, P, faces, genus, components, watertight,
self_intersections) is equal to the last bit.  With a small ``--slab-budget`` the larger labels
are cut into slabs joined at their seams (paper mode only; refine="band" labels must fit).

Sources: ``liver`` (cgogn liver.npz, labels 84/85/127/255), ``rt`` (the dicompyler-core RT
structure set rasterized at 2 mm, ROIs painted in order into one label volume), ``synthetic``
(``contourmesh.cells``, ``--size``^3 voxels of ``--cell``-voxel cells).

    PYTHONPATH=src python benchmarks/scale_identity.py --sources rt,liver,synthetic --out /tmp/ident
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import contourmesh
from contourmesh.api import label_row
from contourmesh.scale import mesh_labels_chunked

DATA = Path(os.environ.get("CONTOURMESH_DATA", Path(__file__).resolve().parents[1] / ".." / "shared" / "data"))
KEYS = ("area", "volume", "P", "faces", "genus", "components", "watertight", "self_intersections")


def canonical_hash(m) -> str:
    V = np.asarray(m.vertices, np.float64) + 0.0
    order = np.lexsort(V.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    f = rank[m.faces]
    r = np.argmin(f, 1)
    rows = np.arange(len(f))
    f = np.stack([f[rows, (r + i) % 3] for i in range(3)], 1)
    f = f[np.lexsort(f.T[::-1])]
    return hashlib.blake2b(V[order].tobytes() + f.astype(np.int64).tobytes(), digest_size=16).hexdigest()


def liver():
    d = np.load(DATA / "volumes" / "cgogn" / "liver.npz")
    sx, sy, sz = (float(v) for v in d["spacing_xyz"])
    return d["volume"], (sz, sy, sx)


def rt(pixel=2.0):
    from contourmesh.io.contours import list_rois, read_contours
    from contourmesh.rasterize import rasterize_stack

    path = DATA / "contours" / "dicompyler-core" / "rtss.dcm"
    rasters = []
    for num, _name, n in list_rois(path):
        if n:
            r = rasterize_stack(read_contours(path, roi=num), pixel=pixel)
            rasters.append((num, r))
    zall = np.unique(np.concatenate([r.z for _, r in rasters]))
    dz = float(np.median(np.concatenate([np.diff(r.z) for _, r in rasters if len(r.z) > 1])))
    z0 = zall.min()
    x0 = min(r.origin[0] for _, r in rasters)
    y0 = min(r.origin[1] for _, r in rasters)
    nx = max(int(round((r.origin[0] - x0) / pixel)) + r.volume.shape[2] for _, r in rasters)
    ny = max(int(round((r.origin[1] - y0) / pixel)) + r.volume.shape[1] for _, r in rasters)
    nz = int(round((zall.max() - z0) / dz)) + 1
    vol = np.zeros((nz, ny, nx), np.uint8)
    for num, r in rasters:  # in ROI order: later ROIs overwrite (BODY first, organs inside it)
        i0, j0 = int(round((r.origin[0] - x0) / pixel)), int(round((r.origin[1] - y0) / pixel))
        for k, z in enumerate(r.z):
            kk = int(round((z - z0) / dz))
            assert abs(z0 + kk * dz - z) < 1e-3 * dz
            sl = r.volume[k]
            vol[kk, j0:j0 + sl.shape[0], i0:i0 + sl.shape[1]][sl] = num
    return vol, (dz, pixel, pixel)


def synthetic(size, cell, seed=0):
    from contourmesh.cells import cells_volume, synthetic_cells

    cells = synthetic_cells((size,) * 3, cell=cell, seed=seed)
    return cells_volume((size,) * 3, cells).astype(np.uint16 if len(cells) < 65535 else np.uint32), (1.0, 1.0, 1.0)


def compare(name, vol, spacing, refine, budget, store, labels=None, out=None):
    res = {"source": name, "refine": refine, "budget": budget, "shape": list(vol.shape)}
    c0 = time.process_time()
    ref = {}
    for lab, m, bbox in contourmesh.mesh_labels(vol, spacing=spacing, refine=refine, labels=labels):
        ref[lab] = (canonical_hash(m), label_row(lab, m, bbox))
    res["memory_cpu_s"] = time.process_time() - c0
    for meshes in (True, False):
        st = {}
        c0 = time.process_time()
        same, diff = 0, []
        for lab, m, _b, row in mesh_labels_chunked(store, spacing=spacing, refine=refine, jobs=1, labels=labels,
                                                   max_box_voxels=budget, meshes=meshes, stats=st):
            h, r = ref[lab]
            ok = {k: row.get(k) for k in KEYS} == {k: r[k] for k in KEYS} and (not meshes or canonical_hash(m) == h)
            same += ok
            if not ok:
                diff.append((lab, row.get("status")))
        key = "meshes" if meshes else "stats_only"
        res[key] = {"labels": len(ref), "identical": same, "different": diff, "cpu_s": time.process_time() - c0,
                    "slabbed_labels": st.get("slabbed_labels"), "slab_tasks": st.get("slab_tasks"),
                    "tasks": st.get("tasks")}
    print(json.dumps(res), flush=True)
    if out is not None:
        with open(out, "a") as fh:
            fh.write(json.dumps(res) + "\n")
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sources", default="rt,liver,synthetic")
    ap.add_argument("--modes", default="none,band")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--cell", type=int, default=128)
    ap.add_argument("--slab-budget", type=int, default=2**20, help="max_box_voxels of the slabbed paper-mode run")
    ap.add_argument("--band-labels", type=int, default=0, help="at most this many labels in band mode (0: all)")
    ap.add_argument("--max-labels", type=int, default=0, help="at most this many labels in any mode (0: all)")
    ap.add_argument("--out", default=None, help="append one JSON line per comparison to this file")
    a = ap.parse_args(argv)
    import zarr

    warnings.simplefilter("ignore", contourmesh.errors.LostContourWarning)
    tmp = Path(tempfile.mkdtemp(prefix="scale-identity-"))
    for src in a.sources.split(","):
        vol, sp = {"liver": liver, "rt": rt}.get(src, lambda: synthetic(a.size, a.cell))()
        store = tmp / f"{src}.zarr"
        arr = zarr.create_array(str(store), shape=vol.shape, chunks=(64, 64, 64), dtype=vol.dtype, zarr_format=3)
        arr[:] = vol
        labs = [int(v) for v in np.unique(vol) if v]
        print(f"{src}: shape {vol.shape}, spacing {sp}, {len(labs)} labels", file=sys.stderr, flush=True)
        for mode in a.modes.split(","):
            refine = None if mode == "none" else mode
            if refine is None:
                compare(src, vol, sp, None, a.slab_budget, store, labels=labs[:a.max_labels] if a.max_labels else None,
                        out=a.out)
            else:
                n = min(v for v in (a.band_labels, a.max_labels, len(labs)) if v)
                pick = labs[:n] if n < len(labs) else None
                compare(src, vol, sp, refine, 2**26, store, labels=pick, out=a.out)


if __name__ == "__main__":
    main()
