"""Issue 17's anchors run chunk by chunk: serra-mesh and zmesh over a label store's chunks, seams stitched.

Each mesher sees the volume one chunk at a time (``--chunk`` voxels, z-major order), never whole:

* **serra-mesh** (multi-label surface nets, Frisken 2022): a chunk owning ``[c0, c1)`` on each axis is
  read as ``[c0, c1 + 2)`` (clipped to the volume) and meshed with ``owned_shape = c1 - c0``, so each
  face is emitted by exactly one chunk; dual contouring reads two cell layers per face, hence the
  two-voxel halo on the positive side. Vertices lie on a 1/256-voxel lattice, so the same seam vertex
  is the same float in both chunks.
* **zmesh** (marching cubes): a chunk owning ``[c0, c1)`` is read as ``[c0, c1 + 1)``; its cubes are
  those between the owned voxels and the next one, so the chunks' cubes partition the volume's.
  Vertices sit at voxel-edge midpoints, exact in float32.

Each label's pieces (moved by their chunk's offset) are kept until a z-slab of chunks holds none of
them, then welded by exact vertex equality (``numpy.unique``, no tolerance) and measured: area, volume
(divergence theorem), and whether the weld is closed (every edge in exactly two faces), with no
duplicate and no degenerate faces. A label that is not closed, or has no faces, is a failed row that
says why; its error is not counted, and the number of such rows is reported (never dropped). A
closed weld with edges in four faces is measured and counted apart (``non_manifold``): where two
parts of a label meet along one voxel edge, serra-mesh gives each part its own vertex in that cell,
at the same point, and a weld by coordinates (serra-mesh's own ``stitch`` too) makes them one.

Serra-mesh runs in four settings: plain surface nets; ``fairing=20`` with Taubin steps (one position
per cell, shared by the labels that meet there; its documentation recommends it); ``taubin=10`` (per
label, the setting of the project's real-shape comparisons); ``relaxation=3`` (a Laplacian, the
setting of its README's area figure). Its smoothing pins each
chunk's outermost cells, so a smoothed stitched mesh is closed but not the one-piece mesh;
``--whole`` also meshes the volume in one piece (small volumes only) and reports how far apart they are.

    PYTHONPATH=src python benchmarks/chunked_meshers.py --size 648 --cell 60 --out /tmp/so648

``--size/--cell/--seed/--out`` name the synthetic store exactly as ``benchmarks/scale_out.py`` does
(and generate it when absent); ``--store PATH --cells CSV`` take any store and its exact table.
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

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

SERRA_SETTINGS = {
    "serra": {},
    "serra-fair": {"fairing": 20, "fairing_taubin": True},
    "serra-taubin10": {"taubin": 10},
    "serra-relax3": {"relaxation": 3},
}
MESHERS = [*SERRA_SETTINGS, "zmesh"]


def _mesher(name):
    if name == "zmesh":
        import zmesh

        return zmesh.Mesher((1, 1, 1))
    import serra_mesh

    return serra_mesh.Mesher(threads=1, **SERRA_SETTINGS[name])


def _chunk_ranges(n, step):
    return [(a, min(a + step, n)) for a in range(0, n, step)]


def _unique_rows(keys):
    """``(first_index_of_each_distinct_row, inverse)`` for an (N, k) integer array, by a lexicographic sort."""
    order = np.lexsort(keys.T[::-1])
    srt = keys[order]
    new = np.ones(len(keys), bool)
    new[1:] = np.any(srt[1:] != srt[:-1], axis=1)
    group = np.cumsum(new) - 1
    inv = np.empty(len(keys), np.int64)
    inv[order] = group
    return order[new], inv


def weld(pieces):
    """Join ``(vertices, faces)`` pieces by exact vertex equality; return a row of measures.

    ``status`` is "ok" when every edge lies in exactly two faces; "closed, non-manifold: ..." when
    every edge lies in an even number of faces, some in four (a closed surface whose area and volume
    are measured; the weld merges two vertices that one piece keeps apart where two parts of a label
    meet along a voxel edge: surface nets give each part its own vertex in the cell, at the same
    point); "not closed: ..." otherwise (not measured)."""
    verts = np.concatenate([v for v, _ in pieces]).astype(np.float32) + np.float32(0.0)  # -0.0 -> 0.0
    base = np.cumsum([0] + [len(v) for v, _ in pieces[:-1]])
    faces = np.concatenate([f.astype(np.int64) + b for (_, f), b in zip(pieces, base)])
    first, inv = _unique_rows(verts.view(np.uint32).astype(np.int64))  # equal floats <=> equal bits
    piece = np.repeat(np.arange(len(pieces)), [len(v) for v, _ in pieces])
    merged_within = len(inv) - len(np.unique(inv * len(pieces) + piece))  # one piece's vertices made one
    uniq = verts[first]
    faces = inv[faces]
    tri = uniq.astype(np.float64)[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * float(np.linalg.norm(cross, axis=1).sum())
    signed = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6.0
    degenerate = int(((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])).sum())
    n = len(uniq)
    duplicate = len(faces) - len(_unique_rows(np.sort(faces, axis=1))[0])
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges[:, 0] * n + edges[:, 1], return_counts=True)
    odd, more = int((counts % 2 == 1).sum()), int((counts > 2).sum())
    problems = []
    if odd:
        problems.append(f"{odd} edges in an odd number of faces")
    if duplicate:
        problems.append(f"{duplicate} duplicate faces")
    if degenerate:
        problems.append(f"{degenerate} degenerate faces")
    if problems:
        status = "not closed: " + ", ".join(problems)
    elif more:
        status = f"closed, non-manifold: {more} edges in four or more faces" + (
            f" ({merged_within} vertices that one piece keeps apart merged by the weld)" if merged_within else "")
    else:
        status = "ok"
    return {"area": area, "volume": abs(signed), "faces": len(faces), "vertices": len(uniq),
            "pieces": len(pieces), "merged_within": merged_within, "status": status}


def _measured(row):
    return row["status"] == "ok" or row["status"].startswith("closed")


def _read_padded(vol, lo, hi):
    """The box ``[lo, hi)`` of ``vol`` as uint32, zeros where it reaches past the volume's border."""
    out = np.zeros([b - a for a, b in zip(lo, hi)], np.uint32)
    inner = [(max(a, 0), min(b, n)) for a, b, n in zip(lo, hi, vol.shape)]
    box = vol.read(*inner)
    out[tuple(slice(a - lo_, b - lo_) for (a, b), lo_ in zip(inner, lo))] = box
    return out


def mesh_chunked(vol, chunk, meshers=MESHERS, log=None):
    """Mesh every label of ``vol`` (a ChunkedVolume or a 3D unsigned array) chunk by chunk with each of
    ``meshers``; return ``({mesher: {label: row}}, stats)``."""
    from contourmesh.io.chunked import open_chunked

    vol = open_chunked(vol)
    shape = vol.shape
    zs, ys, xs = (_chunk_ranges(n, c) for n, c in zip(shape, chunk))
    rows = {m: {} for m in meshers}
    pieces = {m: {} for m in meshers}
    late = {m: set() for m in meshers}
    stats = {"chunks": len(zs) * len(ys) * len(xs), "chunk": list(chunk), "read_s": 0.0,
             **{f"{m}_mesh_s": 0.0 for m in meshers}, **{f"{m}_weld_s": 0.0 for m in meshers}}

    def finish(m, labels):
        t = time.perf_counter()
        for lab in sorted(labels):
            rows[m][lab] = weld(pieces[m].pop(lab))
        stats[f"{m}_weld_s"] += time.perf_counter() - t

    t_all, cpu_all = time.perf_counter(), time.process_time()
    for iz, (z0, z1) in enumerate(zs):
        seen = {m: set() for m in meshers}
        for y0, y1 in ys:
            for x0, x1 in xs:
                t = time.perf_counter()
                own = ((z0, z1), (y0, y1), (x0, x1))
                # one zero layer outside the volume's border, so objects that touch it close there
                lo = [c0 - 1 if c0 == 0 else c0 for c0, _ in own]
                hi = [c1 + 2 if c1 < n else n + 1 for (_, c1), n in zip(own, shape)]
                arr = _read_padded(vol, lo, hi)
                stats["read_s"] += time.perf_counter() - t
                offset = np.array(lo, np.float64)
                for m in meshers:
                    t = time.perf_counter()
                    mesher = _mesher(m)
                    if m == "zmesh":
                        # cubes between the owned voxels and the next one: one voxel past the owned box
                        sub = arr[tuple(slice(0, c1 + 1 - a) for (_, c1), a in zip(own, lo))]
                        mesher.mesh(np.ascontiguousarray(sub), close=False)
                        got = [(int(lab), mesher.get(int(lab), normals=False)) for lab in mesher.ids()]
                    else:
                        # the owned box, counted from the array's start; the last chunk owns all it holds
                        owned = [c1 - a if c1 < n else s for (_, c1), a, n, s in zip(own, lo, shape, arr.shape)]
                        mesher.mesh(arr, close=False, owned_shape=owned)
                        got = [(int(lab), mesher.get(int(lab))) for lab in mesher.ids()]
                    mesher.clear()
                    for lab, mesh in got:
                        if len(mesh.faces) == 0:
                            continue
                        if lab in rows[m]:  # welded already: its z-range has a gap of a whole slab of chunks
                            late[m].add(lab)
                            continue
                        v = np.asarray(mesh.vertices, np.float64) + offset
                        pieces[m].setdefault(lab, []).append((v.astype(np.float32), np.asarray(mesh.faces)))
                        seen[m].add(lab)
                    stats[f"{m}_mesh_s"] += time.perf_counter() - t
        for m in meshers:  # a label with pieces but none in this slab of chunks is complete
            finish(m, [lab for lab in pieces[m] if lab not in seen[m]])
        if log:
            log(f"z-slab {iz + 1}/{len(zs)} ({z0}-{z1}) done, {time.perf_counter() - t_all:.0f} s, "
                f"labels open: {max(len(p) for p in pieces.values())}")
    for m in meshers:
        finish(m, list(pieces[m]))
        for lab in late[m]:
            rows[m][lab]["status"] = "failed: faces after its weld (not connected across a slab of chunks)"
    stats["wall_s"] = time.perf_counter() - t_all
    stats["cpu_s"] = time.process_time() - cpu_all
    stats["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return rows, stats


def mesh_whole(volume, meshers=MESHERS):
    """Every label of an in-memory volume meshed in one piece (closed at the volume's border)."""
    out = {}
    for m in meshers:
        mesher = _mesher(m)
        mesher.mesh(np.ascontiguousarray(volume.astype(np.uint32, copy=False)), close=True)
        out[m] = {int(lab): weld([(np.asarray(mesher.get(int(lab)).vertices, np.float32),
                                   np.asarray(mesher.get(int(lab)).faces))]) for lab in mesher.ids()}
    return out


def _whole_array(store):
    from contourmesh.io.chunked import open_chunked

    vol = open_chunked(store)
    return vol.read((0, vol.shape[0]))


def summarize(rows, exact, kinds):
    """Median, p90 and max of |e| for area and volume over the closed rows (manifold or not), overall and
    by kind; ``not_ok`` counts the others (not closed, failed, or no faces)."""
    out = {}
    for kind in (None, *sorted(set(kinds.values()))):
        labs = [lab for lab in exact if kind is None or kinds[lab] == kind]
        ok = [lab for lab in labs if lab in rows and _measured(rows[lab])]
        entry = {"n": len(labs), "not_ok": len(labs) - len(ok),
                 "non_manifold": sum(rows[lab]["status"].startswith("closed") for lab in ok)}
        for key in ("area", "volume"):
            e = np.array([abs(rows[lab][key] / exact[lab][key] - 1.0) for lab in ok])
            entry[key] = ({"median": float(np.median(e)), "p90": float(np.percentile(e, 90)), "max": float(e.max()),
                           "signed_median": float(np.median([rows[lab][key] / exact[lab][key] - 1.0 for lab in ok]))}
                          if len(e) else None)
        out[kind or "all"] = entry
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=320)
    ap.add_argument("--cell", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="scale_out_results")
    ap.add_argument("--store", help="a label store (then --cells gives the exact table)")
    ap.add_argument("--cells", help="CSV with label, kind, area, volume (cells.csv of scale_out.py)")
    ap.add_argument("--chunk", type=int, nargs=3, default=[128, 256, 256], metavar=("Z", "Y", "X"))
    ap.add_argument("--meshers", nargs="+", default=MESHERS, choices=MESHERS)
    ap.add_argument("--whole", action="store_true", help="also mesh the volume in one piece and compare")
    args = ap.parse_args(argv)
    if min(args.chunk) < 3:
        ap.error("--chunk: each edge must be at least 3 voxels (serra-mesh reads two past the owned box)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.store:
        if not args.cells:
            ap.error("--store needs --cells (the exact areas and volumes)")
        store, table = args.store, list(csv.DictReader(open(args.cells)))
    else:
        from scale_out import generate

        store, _cells, _info = generate(out, args.size, args.cell, args.seed)
        table = list(csv.DictReader(open(out / "cells.csv")))
    exact = {int(r["label"]): {"area": float(r["area"]), "volume": float(r["volume"])} for r in table}
    kinds = {int(r["label"]): r["kind"] for r in table}

    def log(msg):
        print(msg, flush=True)

    rows, stats = mesh_chunked(str(store), tuple(args.chunk), args.meshers, log=log)
    result = {"store": str(store), "stats": stats, "accuracy": {m: summarize(rows[m], exact, kinds) for m in rows}}
    for m in rows:
        failed = {lab: r["status"] for lab, r in rows[m].items() if r["status"] != "ok"}
        failed.update({lab: "no faces" for lab in exact if lab not in rows[m]})
        result["accuracy"][m]["failed"] = {str(k): v for k, v in sorted(failed.items())[:20]}
        log(f"{m}: " + json.dumps(result["accuracy"][m]["all"]))
    if args.whole:
        whole = mesh_whole(_whole_array(str(store)), args.meshers)
        result["whole_vs_chunked"] = {}
        for m in args.meshers:
            d = [abs(rows[m][lab]["area"] / whole[m][lab]["area"] - 1.0) for lab in whole[m] if lab in rows[m]]
            result["whole_vs_chunked"][m] = {"area_rel_diff_max": float(max(d)), "labels": len(d),
                                             "whole": summarize(whole[m], exact, kinds)["all"]}
            log(f"{m} whole vs chunked: " + json.dumps(result["whole_vs_chunked"][m]))
    with open(out / "chunked_meshers.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", "kind", "area_true", "volume_true"]
                   + [f"{k}_{m}" for m in rows for k in ("area", "volume", "status")])
        for lab in sorted(exact):
            w.writerow([lab, kinds[lab], exact[lab]["area"], exact[lab]["volume"]]
                       + [x for m in rows for x in ((rows[m][lab]["area"], rows[m][lab]["volume"], rows[m][lab]["status"])
                                                    if lab in rows[m] else ("", "", "no faces"))])
    result.update(command=" ".join([os.path.basename(sys.executable), *sys.argv]), loadavg_end=os.getloadavg())
    (out / "chunked_meshers.json").write_text(json.dumps(result, indent=1, default=str))
    return result


if __name__ == "__main__":
    main()
