"""Per-label volume bias of a mode on the synthetic cells, split into its terms (issue 17).

Each label of a small synthetic cell volume (``contourmesh.cells``) is meshed; its signed volume
error (in % of the exact volume) is split into terms that add up to it:

* ``slices``: the mesh's cross-sections at the slice planes (just inside the end slices) against
  the exact sections there, summed (are the slice polygons short?);
* ``between``: the mesh volume against the trapezoid rule over its own cross-sections (the joins
  between slices, and any cap volume beyond the end slices);
* ``ends``: minus half the end sections (the trapezoid rule over the slices counts half a slice
  less at each end than the sum over the slices);
* ``generator``: the exact sections summed over the slices against the exact volume (the sum of
  the sections is an unbiased estimate of the volume; this term is its sampling error).

Exact sections: closed form for ellipsoids, a 0.05-voxel midpoint grid for tori.  Also the signed
area error.  Prints one row per label and the medians by kind.

    PYTHONPATH=src python benchmarks/label_volume_terms.py [--size 324 --cell 60 --labels 40 --refine band]
    PYTHONPATH=src python benchmarks/label_volume_terms.py --refine band2 [--caps smooth]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import contourmesh
from contourmesh.cells import cells_volume, synthetic_cells


def section_areas(V, F, zs):
    """Areas of the closed, outward-oriented mesh's cross-sections at the heights ``zs``."""
    T = V[F]
    N = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    zlo, zhi = T[:, :, 2].min(1), T[:, :, 2].max(1)
    out = []
    for z0 in zs:
        sel = (zlo < z0) & (zhi > z0)
        t, n = T[sel], N[sel]
        d = t[:, :, 2] - z0
        pts = []
        for i in range(3):
            a, b, da, db = t[:, i], t[:, (i + 1) % 3], d[:, i], d[:, (i + 1) % 3]
            cross = (da > 0) != (db > 0)
            w = np.where(cross, da / np.where(cross, da - db, 1.0), np.nan)
            pts.append(np.where(cross[:, None], a + w[:, None] * (b - a), np.nan))
        P = np.stack(pts, 1)  # (m, 3, 3) with nan rows where the edge does not cross
        ok = ~np.isnan(P[:, :, 0])
        good = ok.sum(1) == 2
        P, ok, n = P[good], ok[good], n[good]
        idx = np.argsort(~ok, axis=1, kind="stable")[:, :2]
        p = np.take_along_axis(P, idx[:, :, None], 1)
        p0, p1 = p[:, 0], p[:, 1]
        e = p1 - p0
        flip = e[:, 1] * n[:, 0] - e[:, 0] * n[:, 1] < 0
        p0, p1 = np.where(flip[:, None], p1, p0), np.where(flip[:, None], p0, p1)
        out.append(0.5 * float(np.sum(p0[:, 0] * p1[:, 1] - p1[:, 0] * p0[:, 1])))
    return np.array(out)


def torus_section(s, z, step=0.05):
    R = s.rotation if s.rotation is not None else np.eye(3)
    e = s.R + s.r + 1
    ax = np.arange(-e, e, step) + step / 2
    X, Y = np.meshgrid(ax, ax, indexing="xy")
    c = np.asarray(s.center, float)
    d = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z - c[2])], 1)  # world offsets from the centre
    q = d @ R  # local = R^T d
    rho2 = q[:, 0] ** 2 + q[:, 1] ** 2
    t = rho2 + q[:, 2] ** 2 + s.R ** 2 - s.r ** 2
    return float(np.count_nonzero(t * t < 4 * s.R ** 2 * rho2)) * step * step


def terms(m, zk, exact, V):
    am = section_areas(m.vertices, m.faces, [z + (1e-7 if i < len(zk) - 1 else -1e-7) for i, z in enumerate(zk)])
    trap = am.sum() - (am[0] + am[-1]) / 2
    ex = np.sum(exact)
    return {"volume": (m.volume - V) / V * 100, "slices": (am.sum() - ex) / V * 100,
            "between": (m.volume - trap) / V * 100, "ends": -(am[0] + am[-1]) / 2 / V * 100,
            "generator": (ex - V) / V * 100}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=324)
    ap.add_argument("--cell", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--labels", type=int, default=40, help="the first N labels (0: all)")
    ap.add_argument("--refine", default="band")
    ap.add_argument("--json", default=None, help="write the rows to this file")
    ap.add_argument("--cache", default=None, help="an .npy file holding the volume (written if absent)")
    ap.add_argument("--caps", default="flat")
    a = ap.parse_args()
    cells = synthetic_cells((a.size,) * 3, cell=a.cell, seed=a.seed)
    if a.cache and Path(a.cache).exists():
        vol = np.load(a.cache)
    else:
        vol = cells_volume((a.size,) * 3, cells)
        if a.cache:
            np.save(a.cache, vol)
    by = {c.label: c for c in cells}
    labs = sorted(by)[: a.labels] if a.labels else sorted(by)
    rows = []
    t0 = time.process_time()
    for lab, m, bb in contourmesh.mesh_labels(vol, refine=None if a.refine == "none" else a.refine, labels=labs,
                                                caps=a.caps):
        c = by[lab]
        zk = np.arange(bb[0], bb[1] + 1, dtype=float)
        sec = type(c.shape).section_area if c.kind == "ellipsoid" else torus_section
        ex = [sec(c.shape, z) for z in zk]
        r = terms(m, zk, ex, c.volume)
        row = {"label": lab, "kind": c.kind, "route": m.meta.get("route"), "area": (m.area - c.area) / c.area * 100,
               "voxels": (np.count_nonzero(vol == lab) - c.volume) / c.volume * 100, **r}
        rows.append(row)
        print({k: (round(float(v), 3) if isinstance(v, (float, np.floating)) else v) for k, v in row.items()},
              flush=True)
    print(f"CPU {time.process_time() - t0:.1f} s")
    for kind in ("ellipsoid", "torus", None):
        sel = [r for r in rows if kind is None or r["kind"] == kind]
        if not sel:
            continue
        med = {k: round(float(np.median([r[k] for r in sel])), 3) for k in
               ("area", "volume", "slices", "between", "ends", "generator", "voxels")}
        absmed = {f"|{k}|": round(float(np.median([abs(r[k]) for r in sel])), 3) for k in ("area", "volume")}
        print(kind or "all", len(sel), "median signed", med, "median abs", absmed)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh)


if __name__ == "__main__":
    main()
