"""Scale-out benchmark (issue 17): every label of a synthetic cell volume, meshed on a Dask LocalCluster.

1. Generates, with a seed, a synthetic cell volume (:mod:`contourmesh.cells`): one random
   ellipsoid or ring torus per cubic cell of ``--cell`` voxels, non-overlapping, some touching their
   neighbours, uint32, written as a compressed Zarr (v3) slab of chunks by slab of chunks, and a
   ``cells.csv`` of each object's exact area and volume.
2. Runs :func:`contourmesh.scale.mesh_labels_chunked` (stats only) on a ``LocalCluster`` of 1 and of
   2 worker processes (one thread each, ``memory_limit`` each), for the paper mode and
   ``refine="band"`` (``--modes``; ``band2`` too); reports wall time, the scan and mesh phases, and each worker's peak resident
   memory (``ru_maxrss`` of the worker process).
3. Per-label area and volume errors against the exact values, for both modes and for marching
   cubes per label (scikit-image on the label's padded box, level 0.5).

    PYTHONPATH=src python benchmarks/scale_out.py --size 320 --cell 40 --out /tmp/scale_out

The full-size target of the issue (about 10,000 labels, >= 8 GiB uncompressed) is
``--size 1296 --cell 60`` (1296^3 x 4 bytes = 8.1 GiB, 21^3 = 9261 labels).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np


def _peak_rss_mib():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def _rss_mib():
    import psutil

    return psutil.Process().memory_info().rss / 2**20


def _warm():
    """Import and load the compiled kernels once in a worker, so the run times meshing, not start-up."""
    import contourmesh

    box = np.zeros((7, 8, 8), np.uint8)
    box[2:5, 2:6, 2:6] = 1
    box[2:5, 2:4, 6:8] = 2
    for refine in (None, "band", "band2"):
        list(contourmesh.mesh_labels(box, refine=refine))
    return _rss_mib()


def generate(out: Path, size: int, cell: int, seed: int):
    from contourmesh.cells import cells_table, synthetic_cells, write_cells_zarr

    shape = (size, size, size)
    t = time.perf_counter()
    cells = synthetic_cells(shape, cell=cell, seed=seed)
    store = out / f"cells-{size}-{cell}-{seed}.zarr"
    if not store.exists():
        write_cells_zarr(str(store), shape, cells, chunks=(64, 128, 128))
    table = cells_table(cells)
    with open(out / "cells.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(dict.fromkeys(k for r in table for k in r)))
        w.writeheader()
        w.writerows(table)
    gen_s = time.perf_counter() - t
    disk = sum(f.stat().st_size for f in store.rglob("*") if f.is_file())
    return store, cells, {"shape": shape, "labels": len(cells), "uncompressed_bytes": int(np.prod(shape)) * 4,
                          "zarr_bytes": disk, "generate_s": gen_s,
                          "tori": sum(c.kind == "torus" for c in cells)}


def run_cluster(store, workers: int, refine, memory_limit: str):
    from distributed import Client, LocalCluster

    from contourmesh.scale import mesh_labels_chunked

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, memory_limit=memory_limit,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers, timeout=120)
        base = client.run(_warm)
        stats = {}
        t = time.perf_counter()
        rows = {lab: row for lab, _m, _b, row in mesh_labels_chunked(store, client=client, meshes=False,
                                                                      refine=refine, stats=stats)}
        wall = time.perf_counter() - t
        peaks = client.run(_peak_rss_mib)
        n_workers_end = len(client.scheduler_info()["workers"])
    return rows, {"workers": workers, "refine": refine or "none", "wall_s": wall, "scan_s": stats["scan_s"],
                  "mesh_s": stats["mesh_s"], "tasks": stats["tasks"], "task_s_sum": stats["task_s"],
                  "read_s_sum": stats["read_s"], "cpu_s_sum": stats.get("cpu_s"), "baseline_rss_mib": sorted(base.values()),
                  "peak_rss_mib": sorted(peaks.values()), "workers_at_end": n_workers_end}


def _area_volume(v, f):
    tri = np.asarray(v, np.float64)[np.asarray(f)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * float(np.linalg.norm(cross, axis=1).sum())
    volume = abs(float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6.0)
    return {"area": area, "volume": volume}


def marching_cubes_rows(store, labels_boxes, method="skimage"):
    """Per-label marching cubes on each label's padded box, read from the store label by label:
    scikit-image (level 0.5 on the binary mask) or zmesh (its multi-label mesher on the mask, closed)."""
    from contourmesh.io.chunked import open_chunked

    vol = open_chunked(store)
    out = {}
    if method == "zmesh":
        import zmesh

        mesher = zmesh.Mesher((1, 1, 1))
    for lab, box in labels_boxes.items():
        z0, z1, y0, y1, x0, x1 = box
        lo = [max(z0 - 1, 0), max(y0 - 1, 0), max(x0 - 1, 0)]
        hi = [min(z1 + 2, vol.shape[0]), min(y1 + 2, vol.shape[1]), min(x1 + 2, vol.shape[2])]
        mask = vol.read((lo[0], hi[0]), (lo[1], hi[1]), (lo[2], hi[2])) == lab
        mask = np.pad(mask, 1)
        if method == "zmesh":
            mesher.mesh(mask.astype(np.uint8), close=True)
            zm = mesher.get(1, normals=False)
            mesher.clear()
            out[lab] = _area_volume(zm.vertices, zm.faces)
        else:
            from skimage import measure

            v, f, _, _ = measure.marching_cubes(mask.astype(np.float32), 0.5)
            out[lab] = _area_volume(v, f)
    return out


def errors(rows, exact, key):
    """|estimate / exact - 1| over the labels that were measured (a failed label has no area)."""
    e = np.array([abs(rows[lab][key] / exact[lab][key] - 1.0) for lab in exact if rows[lab].get(key) is not None])
    return {"median": float(np.median(e)), "p90": float(np.percentile(e, 90)), "max": float(e.max()), "n": len(e),
            "missing": len(exact) - len(e)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=320, help="edge of the cubic volume in voxels")
    ap.add_argument("--cell", type=int, default=40, help="edge of one object's cell in voxels")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="scale_out_results")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--modes", nargs="+", default=["none", "band"], choices=["none", "band", "band2"])
    ap.add_argument("--memory-limit", default="2GiB")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    store, cells, info = generate(out, args.size, args.cell, args.seed)
    print(json.dumps(info), flush=True)
    exact = {c.label: {"area": c.area, "volume": c.volume} for c in cells}
    runs, acc = [], {}
    rows_by_mode = {}
    for mode in args.modes:
        for w in args.workers:
            rows, r = run_cluster(str(store), w, None if mode == "none" else mode, args.memory_limit)
            print(json.dumps(r), flush=True)
            runs.append(r)
            rows_by_mode[mode] = rows
        rows = rows_by_mode[mode]
        acc[mode] = {"area": errors(rows, exact, "area"), "volume": errors(rows, exact, "volume"),
                     "not_ok": sum(r["status"] != "ok" for r in rows.values())}
        print(mode, json.dumps(acc[mode]), flush=True)
    boxes = {lab: (row["zmin"], row["zmax"], row["ymin"], row["ymax"], row["xmin"], row["xmax"])
             for lab, row in next(iter(rows_by_mode.values())).items()}
    t = time.perf_counter()
    mc = marching_cubes_rows(store, boxes)
    acc["marching_cubes"] = {"area": errors(mc, exact, "area"), "volume": errors(mc, exact, "volume"),
                             "time_s": time.perf_counter() - t}
    print("marching_cubes", json.dumps(acc["marching_cubes"]), flush=True)
    try:
        t = time.perf_counter()
        zm = marching_cubes_rows(store, boxes, method="zmesh")
        acc["zmesh"] = {"area": errors(zm, exact, "area"), "volume": errors(zm, exact, "volume"),
                        "time_s": time.perf_counter() - t}
        print("zmesh", json.dumps(acc["zmesh"]), flush=True)
    except ImportError as exc:
        print(f"zmesh not run: {exc}", flush=True)
        zm = None
    with open(out / "per_label.csv", "w", newline="") as fh:  # every label's exact and estimated values
        estimates = [f"{k}_{m}" for m in [*rows_by_mode, "mc", "zmesh"] for k in ("area", "volume")]
        fields = ["label", "kind", "area_true", "volume_true", *estimates, *(f"status_{m}" for m in rows_by_mode)]
        w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        kinds = {c.label: c.kind for c in cells}
        for lab in sorted(exact):
            row = {"label": lab, "kind": kinds[lab], "area_true": exact[lab]["area"],
                   "volume_true": exact[lab]["volume"], "area_mc": mc[lab]["area"], "volume_mc": mc[lab]["volume"]}
            if zm is not None:
                row.update(area_zmesh=zm[lab]["area"], volume_zmesh=zm[lab]["volume"])
            for mode, rows in rows_by_mode.items():
                row[f"area_{mode}"] = rows[lab].get("area")
                row[f"volume_{mode}"] = rows[lab].get("volume")
                row[f"status_{mode}"] = rows[lab]["status"]
            w.writerow(row)
    speedup = {}
    for mode in args.modes:
        t = {r["workers"]: r["wall_s"] for r in runs if r["refine"] == mode}
        if 1 in t and 2 in t:
            speedup[mode] = t[1] / t[2]
    result = {"volume": info, "runs": runs, "accuracy": acc, "speedup_2_vs_1": speedup,
              "command": " ".join([os.path.basename(sys.executable), *sys.argv]), "cpu_count": os.cpu_count(),
              "loadavg_end": os.getloadavg()}
    (out / "scale_out.json").write_text(json.dumps(result, indent=1, default=str))
    print(json.dumps({"speedup_2_vs_1": speedup}), flush=True)
    return result


if __name__ == "__main__":
    main()
