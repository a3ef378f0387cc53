"""Band refinement on oblong pixels and unevenly spaced slices (issue 14 item 3): convergence tables.

A ball digitized at the liver sample's voxel shape, ``(dz, dy, dx) = (0.9, 0.617, 0.667)`` mm, of radius
``r`` pixels of 0.667 mm (r = 10, 20, 40), at a few sub-voxel centres, meshed on the volume route
(``contourmesh.mesh(volume, spacing=(dz, dy, dx), refine="band")``): the median relative area error
against ``4 pi R^2``, beside the paper mode's.  Then an ellipsoid on uneven slice heights (gaps drawn
from 0.5-1.3 mm) at the same pixels, on the volume route and as a contour stack.  With ``--liver`` the
shared liver sample (pixels 0.617 x 0.667 mm, as ``benchmarks/intersect_counts.py`` reads it) in every
band mode (polygon mlp / dss / none x the four triangulations), with its crossing face pairs.

    python benchmarks/band_anisotropic.py            # the tables (about a minute)
    python benchmarks/band_anisotropic.py --liver    # and the liver's 12 band modes (about 10 minutes)
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from contourmesh.digitize import mask_stack, sample_volume, uneven_heights  # noqa: E402

LIVER = (0.9, 0.617, 0.667)  # (dz, dy, dx), mm
CENTRES = [(0.31, 0.17, 0.43), (0.05, 0.23, 0.11), (0.4, 0.02, 0.27)]


def ball_table(sizes) -> None:
    import contourmesh
    from contourmesh.shapes import Sphere

    print(f"ball at (dz, dy, dx) = {LIVER} mm, r in pixels of {LIVER[2]} mm; median over {len(CENTRES)} centres")
    print("| r | refine='band' | paper mode | band P | seconds (band) |")
    print("|---|---|---|---|---|")
    prev = None
    for r in sizes:
        band, paper, P, secs = [], [], [], []
        for c in CENTRES:
            s = Sphere(r * LIVER[2], center=c)
            mask, zs, org = sample_volume(s, LIVER)
            t = time.perf_counter()
            m = contourmesh.mesh(mask, spacing=LIVER, origin=org, refine="band")
            secs.append(time.perf_counter() - t)
            chk = m.checks()
            if not (chk["ok"] and chk["self_intersections"] == 0):
                print(f"  r={r} centre {c}: mesh checks failed: {chk}")
            band.append(m.area / s.area - 1)
            P.append(m.P)
            paper.append(contourmesh.mesh(mask, spacing=LIVER, origin=org).area / s.area - 1)
        e = float(np.median(np.abs(band)))
        order = f" (order {np.log(prev[1] / e) / np.log(r / prev[0]):.2f})" if prev else ""
        print(f"| {r} | {100 * np.median(band):+.3f} % (|e| {100 * e:.3f} %{order}) | "
              f"{100 * np.median(paper):+.2f} % | {int(np.median(P))} | {np.median(secs):.2f} |", flush=True)
        prev = (r, e)


def uneven_table(scales) -> None:
    import contourmesh
    from contourmesh.shapes import Ellipsoid

    print()
    print("ellipsoid (6.7, 5.0, 6.0) x scale mm on slices 0.5-1.3 mm apart (median of 5 draws), pixels 0.617 x "
          "0.667 mm; beside it the same ellipsoids on slices 0.9 mm apart")
    print("| scale | volume route | contour-stack route | paper mode | even slices, volume route |")
    print("|---|---|---|---|---|")
    for k in scales:
        vol, stk, pap, even = [], [], [], []
        for seed in (3, 4, 5, 6, 7):
            c = tuple(np.random.default_rng(seed).uniform(-0.5, 0.5, 3))
            e = Ellipsoid(6.7 * k, 5.0 * k, 6.0 * k, center=c)
            mask, zs, org = sample_volume(e, LIVER)
            even.append(contourmesh.mesh(mask, spacing=LIVER, origin=org, refine="band").area / e.area - 1)
            mask, zs, org = sample_volume(e, LIVER, uneven_heights(6.0 * k, seed))
            vol.append(contourmesh.mesh(mask, spacing=LIVER, z=zs, origin=org, refine="band").area / e.area - 1)
            st = mask_stack(mask, zs, LIVER, org)
            stk.append(contourmesh.mesh(st, refine="band").area / e.area - 1)
            pap.append(contourmesh.mesh(st).area / e.area - 1)
        print(f"| {k} | {100 * np.median(vol):+.3f} % | {100 * np.median(stk):+.3f} % | {100 * np.median(pap):+.2f} % | "
              f"{100 * np.median(even):+.3f} % |", flush=True)


def liver_modes() -> int:
    from intersect_counts import ALL_MODES, measure, mode_kwargs, present_samples

    modes = [m for m in ALL_MODES if m.endswith("/band")]
    print()
    print(f"liver (intersect_counts.py's reading), {len(modes)} band modes")
    bad = 0
    for name, vol, spacing in present_samples("liver"):
        print(f"{name}: shape {vol.shape}, spacing (dz, dy, dx) = {spacing}")
        for mode in modes:
            r = measure(vol, spacing, **mode_kwargs(mode))
            bad += bool(r.get("error")) or r["pairs"] > 0
            print(f"  {mode:22s} {r.get('route', '-'):15s} faces {r['faces']:7d}  crossing pairs {r['pairs']}"
                  f"  mesh {r.get('mesh_s', 0):.1f} s" + (f"  ERROR {r['error']}" if r.get("error") else ""), flush=True)
    print(f"liver: {len(modes) - bad} of {len(modes)} band modes meshed with no crossing faces")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,20,40")
    ap.add_argument("--liver", action="store_true", help="also mesh the liver sample in every band mode")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    ball_table([int(s) for s in args.sizes.split(",") if s])
    uneven_table([1, 2, 4])
    return liver_modes() if args.liver else 0


if __name__ == "__main__":
    raise SystemExit(main())
