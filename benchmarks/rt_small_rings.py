"""Rings smaller than a pixel on the contours route, per ROI of the shared RT structure set (issue 15).

For each non-empty ROI of ``$CONTOURMESH_DATA/contours/dicompyler-core/rtss.dcm`` (default
``../shared/data``), meshed with ``contourmesh.mesh(stack)`` (the contours route, flat caps, ruled
bands): the drawn rings, the rings named in the LostContourWarning (parsed from its text, so older
revisions are measured the same way), ``meta["kept_small_rings"]`` where the revision has it, the
mesh volume against the slab sum (each section's even-odd drawn area x its slice thickness) and
against the frustum-trapezoid interval (``contourmesh.compare.clinical.rules_rows``), crossing face
pairs, whether the mesh is closed and wound, and the median CPU seconds of ``--repeat`` meshes after a
warm-up.  ``--before REV`` runs the same on a git revision's sources (``git archive``) in its own
process and prints both side by side.

    PYTHONPATH=src .venv/bin/python benchmarks/rt_small_rings.py --before HEAD~1 --repeat 3
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from rt_set import at_revision, existing_rt_path  # noqa: E402 (the RT set's path and the revision runner)


def measure(path, repeat: int) -> dict:
    import contourmesh
    from contourmesh.compare.clinical import _outside, _rel, slab_volume
    from contourmesh.compare.phantoms import frustum_volume, trapezoid_volume
    from contourmesh.io.contours import list_rois, read_contours

    out = {}
    for num, name, n in list_rois(path):
        if not n:
            continue
        st = read_contours(path, roi=num)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m = contourmesh.mesh(st)  # also the warm-up
        lost = 0
        for w in caught:
            if type(w.message).__name__ == "LostContourWarning":
                hit = re.search(r"(\d+) (?:contour|drawn ring)\(s\)", str(w.message))
                lost += int(hit.group(1)) if hit else 0
        cpu = []
        for _ in range(repeat):
            t0 = time.process_time()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                contourmesh.mesh(st)
            cpu.append(time.process_time() - t0)
        chk = m.checks()
        fru, trap, slabs = frustum_volume(st), trapezoid_volume(st), slab_volume(st)
        out[name] = {"rings": sum(len(s.contours) for s in st.sections), "lost": lost,
                     "kept": m.meta.get("kept_small_rings"), "pixel": m.meta.get("pixel"),
                     "volume": m.volume, "vs_slabs": _rel(m.volume, slabs), "outside_rules": _outside(m.volume, fru, trap),
                     "crossings": chk["self_intersections"],
                     "sound": bool(chk["watertight"] and chk["winding_consistent"] and m.volume > 0),
                     "unmatched": m.meta.get("unmatched_components"), "cpu": statistics.median(cpu)}
    return out


def _before(rev: str, repeat: int) -> dict:
    return at_revision(rev, Path(__file__), ["--repeat", str(repeat)])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed meshes per ROI after the first (median)")
    ap.add_argument("--before", default=None, metavar="REV", help="also measure this git revision's code")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON only")
    args = ap.parse_args(argv)
    path = existing_rt_path()
    if path is None:
        return 2
    before = _before(args.before, args.repeat) if args.before else None
    res = measure(path, args.repeat)
    if args.json:
        print(json.dumps(res))
        return 0
    print("| ROI | rings | lost before | kept / lost after | vol vs slab sum before -> after | outside rules before -> after "
          "| crossings before -> after | sound | unmatched before -> after | CPU s before -> after |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, r in res.items():
        b = (before or {}).get(name, {})
        print(f"| {name} | {r['rings']} | {b.get('lost', '')} | {r['kept']} / {r['lost']} | "
              f"{100 * b.get('vs_slabs', float('nan')):+.3f} % -> {100 * r['vs_slabs']:+.3f} % | "
              f"{100 * b.get('outside_rules', float('nan')):+.3f} % -> {100 * r['outside_rules']:+.3f} % | "
              f"{b.get('crossings', '')} -> {r['crossings']} | {r['sound']} | {b.get('unmatched', '')} -> {r['unmatched']} | "
              f"{b.get('cpu', float('nan')):.2f} -> {r['cpu']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
