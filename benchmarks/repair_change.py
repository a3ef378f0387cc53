"""How much the crossing repairs change the area and the volume of the shared samples (issue 13).

The volume mesher pulls touching or barely crossing faces apart by small inward moves
(:func:`contourmesh.repair.resolve_crossings`) and, where faces still cross, rebuilds the joins and
caps involved as voxel-exact joins.  This script records every call of the move repair while a
sample is meshed (the compiled fast path's check and each build of the general mesher), and
compares, on the same faces or builds:

* **move**: the mesh the last check received against the one it returned (the same faces; only the
  moved vertices differ): the change of area and volume, the largest vertex move ``d``, and the
  bounds ``A_moved * d`` (volume) and ``L_moved * d`` (area), where ``A_moved`` and ``L_moved`` are the
  area and the summed edge length of the faces with a moved vertex: the volume a face sweeps when
  its corners move by at most ``d`` is at most about its area times ``d``, and its area changes by
  at most its perimeter times ``d``.
* **rebuild**: the first build (before any rebuild, as made, crossing) against the last one (before
  its moves): the change of area and volume and the area of the faces that differ between them.
* **total**: the first build against the mesh returned.

    PYTHONPATH=src python benchmarks/repair_change.py                         # every sample, default mode
    PYTHONPATH=src python benchmarks/repair_change.py --samples bunny-64,lobster --json out.json
    PYTHONPATH=src python benchmarks/repair_change.py --modes default,mlp/optimal/-

Relative changes are to the returned mesh's area and volume.  A sample whose meshing made no
crossing at all shows zeros (one check, nothing moved, no rebuild).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))


def area_volume(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    return area, float(vol)


def changed_area(V0, F0, V1, F1, decimals=9):
    """Area and count of the faces of build 0 not in build 1 and of build 1 not in build 0 (a face is
    its three corners' rounded coordinates)."""
    P0 = [tuple(r) for r in np.round(V0[F0], decimals).reshape(len(F0), 9)]
    P1 = [tuple(r) for r in np.round(V1[F1], decimals).reshape(len(F1), 9)]
    k0, k1 = set(P0), set(P1)
    gone = np.array([r not in k1 for r in P0], dtype=bool)
    new = np.array([r not in k0 for r in P1], dtype=bool)
    a0, _ = area_volume(V0, F0)
    a1, _ = area_volume(V1, F1)
    return float(a0[gone].sum()), float(a1[new].sum()), int(gone.sum()), int(new.sum())


def measure(vol, spacing, **kw):
    import contourmesh
    import contourmesh.volumes as volumes

    calls = []
    real = volumes.resolve_crossings

    def recording(V, F, nudge, **k):
        V2, info = real(V, F, nudge, **k)
        calls.append((np.array(V, dtype=np.float64), np.asarray(F, dtype=np.int64), V2, dict(info)))
        return V2, info

    volumes.resolve_crossings = recording
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t = time.process_time()
            m = contourmesh.mesh(vol, spacing=spacing, **kw)
            cpu = time.process_time() - t
    finally:
        volumes.resolve_crossings = real
    V, F = np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)
    aF, vF = area_volume(V, F)
    A, Vol = float(aF.sum()), vF
    row = dict(route=m.meta.get("route"), faces=int(len(F)), area=A, volume=Vol, checks=len(calls),
               crossing_fallbacks=int(m.meta.get("crossing_fallbacks", 0)),
               crossings_repaired=int(m.meta.get("crossings_repaired", 0)),
               left=int(m.meta.get("self_intersections", 0)), mesh_cpu_s=round(cpu, 2))
    if not calls:
        row.update(note="no crossing check was recorded (not the volume mesher)")
        return row
    # move: the last check's input against its output (same faces)
    Vi, Fi, Vo, info = calls[-1]
    ai, vi = area_volume(Vi, Fi)
    ao, vo = area_volume(Vo, Fi)
    d = np.linalg.norm(Vo - Vi, axis=1)
    moved_faces = (d[Fi] > 0).any(axis=1)
    Fm = Fi[moved_faces]
    L = sum(np.linalg.norm(Vi[Fm[:, i]] - Vi[Fm[:, (i + 1) % 3]], axis=1).sum() for i in range(3))
    dmax = float(d.max()) if len(d) else 0.0
    row.update(move_vertices=int(np.count_nonzero(d)), move_max=dmax,
               move_dA=float(ao.sum() - ai.sum()), move_dV=float(vo - vi),
               move_bound_A=float(L * dmax), move_bound_V=float(ai[moved_faces].sum() * dmax))
    # rebuild: the first build against the last one, both before their moves
    V0, F0, _, _ = calls[0]
    a0, v0 = area_volume(V0, F0)
    if len(calls) > 1:
        gone, new, ngone, nnew = changed_area(V0, F0, Vi, Fi)
        row.update(rebuild_dA=float(ai.sum() - a0.sum()), rebuild_dV=float(vi - v0), rebuild_area_changed=gone + new,
                   rebuild_faces_changed=ngone + nnew)
    else:
        row.update(rebuild_dA=0.0, rebuild_dV=0.0, rebuild_area_changed=0.0, rebuild_faces_changed=0)
    row.update(total_dA=float(A - a0.sum()), total_dV=float(Vol - v0),
               rel_dA=float(abs(A - a0.sum()) / A) if A else 0.0, rel_dV=float(abs(Vol - v0) / abs(Vol)) if Vol else 0.0)
    return row


def main(argv=None) -> int:
    from intersect_counts import SAMPLES, expand_modes, mode_kwargs, present_samples

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default=",".join(SAMPLES))
    ap.add_argument("--modes", default="default")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    modes = expand_modes(args.modes)
    rows = {}
    head = (f"{'sample:mode':28s} {'faces':>8s} {'checks':>6s} {'rebuilt':>7s} {'moved':>6s} {'max move':>9s} "
            f"{'move dA':>10s} {'<= L d':>10s} {'move dV':>10s} {'<= A d':>10s} {'rebuild dA':>11s} "
            f"{'rebuild dV':>11s} {'A changed':>10s} {'rel dA':>9s} {'rel dV':>9s}")
    print(head, flush=True)
    for name, vol, spacing in present_samples(args.samples):
        for mode in modes:
            r = measure(vol, spacing, **mode_kwargs(mode))
            rows[f"{name}:{mode}"] = r
            if "note" in r:
                print(f"{name + ':' + mode:28s} {r['note']}", flush=True)
                continue
            print(f"{name + ':' + mode:28s} {r['faces']:8d} {r['checks']:6d} {r['crossing_fallbacks']:7d} "
                  f"{r['move_vertices']:6d} {r['move_max']:9.2e} {r['move_dA']:10.2e} {r['move_bound_A']:10.2e} "
                  f"{r['move_dV']:10.2e} {r['move_bound_V']:10.2e} {r['rebuild_dA']:11.3e} {r['rebuild_dV']:11.3e} "
                  f"{r['rebuild_area_changed']:10.3e} {r['rel_dA']:9.2e} {r['rel_dV']:9.2e}", flush=True)
            if args.json:
                tmp = args.json.with_suffix(args.json.suffix + ".tmp")
                tmp.write_text(json.dumps(rows, indent=1))
                os.replace(tmp, args.json)
    done = [r for r in rows.values() if "note" not in r]
    if done:
        print(f"largest relative change: area {max(r['rel_dA'] for r in done):.2e}, volume "
              f"{max(r['rel_dV'] for r in done):.2e}; largest vertex move {max(r['move_max'] for r in done):.2e}; "
              f"move changes within their bounds: "
              f"{all(abs(r['move_dA']) <= r['move_bound_A'] + 1e-12 and abs(r['move_dV']) <= r['move_bound_V'] + 1e-12 for r in done)}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
