"""Crossing faces on every ROI of the shared RT structure set, in every mode (issue 13).

Meshes every ROI of ``contours/dicompyler-core/rtss.dcm`` with ``polygon`` unset (the default: the
drawn rings on the contours route) or in (none, mlp, dss),
``triangulation`` in (wiederhold, greedy, optimal, arclength), ``caps`` in (flat, half, smooth),
``refine`` in (none, band) and ``bands`` in (ruled, curved), and counts the intersecting face pairs (:func:`contourmesh.intersect.intersecting_pairs`) of each
mesh; ``polygon="none"`` meshes the drawn rings (stack route with one ring per section, else the
contours route), ``mlp``/``dss`` rasterize the rings at ``--pixel`` (raster route).  A mode that
refuses an input (``caps="smooth"`` on the raster route) is recorded with its error.

    PYTHONPATH=src python benchmarks/rt_crossings.py                  # every ROI, every mode
    PYTHONPATH=src python benchmarks/rt_crossings.py --rois Heart,Scar --polygons none --json out.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
DATA = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))
RT = DATA / "contours" / "dicompyler-core"


def main(argv=None) -> int:
    import contourmesh
    from contourmesh.intersect import intersecting_pairs
    from contourmesh.io import read_contours

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rois", default=None, help="comma-separated ROI names (default: every non-empty ROI)")
    ap.add_argument("--polygons", default="default,none,mlp,dss",
                    help="'default' leaves polygon unset: the drawn rings on the contours route")
    ap.add_argument("--triangulations", default="wiederhold,greedy,optimal,arclength")
    ap.add_argument("--caps", default="flat,half,smooth")
    ap.add_argument("--refines", default="none,band")
    ap.add_argument("--bands", default="ruled,curved")
    ap.add_argument("--pixel", type=float, default=2.0, help="raster size in mm (default %(default)s)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    path = RT / "rtss.dcm"
    if not path.is_file():
        print(f"{path} not found (set CONTOURMESH_DATA)")
        return 1
    names = [str(n) for n in np.load(RT / "rtss_contours.npz")["roi_names"]]
    rois = args.rois.split(",") if args.rois else names
    out = {}
    crossing, refused, failed = [], [], []
    for roi in rois:
        try:
            stack = read_contours(path, roi=roi)
        except Exception as e:  # the empty ROI
            print(f"{roi}: not read ({type(e).__name__}: {e})", flush=True)
            continue
        for p in args.polygons.split(","):
            for t, c, rf, bd in itertools.product(args.triangulations.split(","), args.caps.split(","),
                                                  args.refines.split(","), args.bands.split(",")):
                key = f"{roi}:{p}/{t}/{c}/{rf}/{bd}"
                opts = {} if p == "default" else dict(polygon=p)
                if rf == "none":
                    opts["pixel"] = args.pixel  # the refinement meshes the stack's own grid: no raster
                else:
                    opts["refine"] = rf
                if bd != "ruled":
                    opts["bands"] = bd
                cpu = time.process_time()
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        m = contourmesh.mesh(stack, triangulation=t, caps=c, **opts)
                except contourmesh.errors.InapplicableOption as e:
                    r = dict(refused=str(e)[:200])
                    refused.append(key)
                except Exception as e:
                    r = dict(error=f"{type(e).__name__}: {e}"[:300])
                    failed.append(key)
                else:
                    cpu = time.process_time() - cpu
                    pairs = len(intersecting_pairs(m.vertices, m.faces))
                    chk = m.checks()
                    r = dict(route=m.meta.get("route"), faces=int(len(m.faces)), pairs=int(pairs),
                             closed=bool(chk["closed"]), ok=bool(chk["ok"]), cpu_s=round(cpu, 2),
                             crossing_fallbacks=m.meta.get("crossing_fallbacks"),
                             crossings_repaired=m.meta.get("crossings_repaired"))
                    if pairs or not chk["closed"]:
                        crossing.append(key)
                out[key] = r
                print(key, r, flush=True)
                if args.json:
                    tmp = args.json.with_suffix(args.json.suffix + ".tmp")
                    tmp.write_text(json.dumps(out, indent=1))
                    os.replace(tmp, args.json)
    meshed = [k for k, r in out.items() if "faces" in r]
    print(f"{len(out)} ROI x mode: {len(meshed)} meshed, {len(crossing)} with crossing faces or not closed"
          + (f" ({', '.join(crossing)})" if crossing else "") + f", {len(refused)} refused (InapplicableOption)"
          + f", {len(failed)} raised" + (f" ({', '.join(failed)})" if failed else ""), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
