"""Area error of the volume mesher on randomly rotated, voxelized real meshes (issue 14).

Every closed mesh of the shared data folder is rotated at random (seeded), voxelized at N voxels
across its largest extent (Gauss digitization by ray parity) and meshed by ``contourmesh.mesh``;
its area is compared with the mesh's own.  Per mesh: the relative error, the join counts of the
volume mesher (band, bridged, exact), the crack rings and polygon fallbacks, the share of area on
faces normal to x or y (staircase walls), crossing face pairs, and the time.

    python benchmarks/real_shapes.py                      # 128 across, paper mode
    python benchmarks/real_shapes.py --n 64 --refine band
    python benchmarks/real_shapes.py --meshes bunny,socket --triangulation optimal

The data folder is ``$CONTOURMESH_DATA`` (default ``../shared/data`` beside the checkout).
The full comparison of every method is ``comparisons/real``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
DATA = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))

MESHES = {
    "bunny": "libigl-tutorial-data/bunny.off", "fertility": "libigl-tutorial-data/fertility.off",
    "socket": "cgogn/socket.off", "armadillo": "libigl-tutorial-data/armadillo.obj",
    "elephant": "libigl-tutorial-data/elephant.obj", "3holes": "libigl-tutorial-data/3holes.off",
    "spot": "common-3d-test-models/spot.obj", "rocker-arm": "common-3d-test-models/rocker-arm.obj",
    "quadknot": "trimesh-models/quadknot.obj", "aneurysm": "cgogn/aneurysm_3D.off",
    "fandisk": "libigl-tutorial-data/fandisk.off", "cheburashka": "common-3d-test-models/cheburashka.obj",
    "lion": "dgtal/lion-tri.obj", "torus": "trimesh-models/torus.STL",
}


def main(argv=None) -> int:
    import contourmesh
    from contourmesh.compare.inputs import mesh_inputs
    from contourmesh.measure import axis_wall_fraction

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=128, help="voxels across the largest extent (default 128)")
    ap.add_argument("--seed", type=int, default=0, help="rotation seed (default 0)")
    ap.add_argument("--meshes", default=",".join(MESHES), help="comma-separated names (default: all)")
    ap.add_argument("--refine", default=None, help="refine method (default none: the paper mode)")
    ap.add_argument("--triangulation", default=None, help="band triangulation (default: the mesher's)")
    ap.add_argument("--axis-aligned", action="store_true", help="no rotation")
    args = ap.parse_args(argv)
    root = DATA / "meshes"
    if not root.is_dir():
        print(f"no meshes under {root}: set CONTOURMESH_DATA to the shared data folder", file=sys.stderr)
        return 2
    kw = {k: v for k, v in (("refine", args.refine), ("triangulation", args.triangulation)) if v}
    errs = []
    print(f"{'mesh':12s} {'e':>8s} {'s':>6s} band bridged exact crack fallb walls  X")
    for name in [m for m in args.meshes.split(",") if m]:
        inp = mesh_inputs(MESHES[name], [args.n], rotate=not args.axis_aligned, seed=args.seed, root=root)[0]
        if inp.error:
            print(f"{name:12s} skipped: {inp.error}")
            continue
        vol, sp, org = inp.volume()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t = time.perf_counter()
            m = contourmesh.mesh(vol, spacing=sp, origin=org, **kw)
            dt = time.perf_counter() - t
        c = m.checks()
        e = m.area / inp.area_true - 1
        errs.append(e)
        g = m.meta.get
        print(f"{name:12s} {100 * e:+7.2f}% {dt:6.2f} {g('band_joins', '-'):>4} {g('bridged_joins', '-'):>7} "
              f"{g('exact_joins', '-'):>5} {g('crack_rings', '-'):>5} {g('polygon_fallbacks', '-'):>5} "
              f"{axis_wall_fraction(m.vertices, m.faces):5.3f} {c['self_intersections']:3d}"
              f"{'' if c['closed'] else '  NOT CLOSED'}", flush=True)
    if errs:
        a = np.abs(errs)
        print(f"median e {100 * np.median(errs):+.2f}%, median |e| {100 * np.median(a):.2f}%, "
              f"largest |e| {100 * a.max():.2f}% over {len(errs)} meshes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
