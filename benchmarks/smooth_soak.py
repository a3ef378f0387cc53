"""The soak's random drawn-ring stacks with the contours route's smooth caps, ruled and curved bands.

``tests/soak.py`` meshes its random real-valued stacks (non-convex rings, holes, islands, forks and
merges, uneven heights: ``soak.make_real_stack``) with ``caps`` flat or half only. This runs the same
generator (its own seeds: ``default_rng([seed, 67])``) through ``caps="smooth", route="contours"``
with ruled bands and with ``bands="curved"``, and counts meshes that fail ``checks()``: not closed,
not consistently wound, crossing faces, or a non-positive volume. Errors are printed and counted.

    PYTHONPATH=src python benchmarks/smooth_soak.py --seeds 0:400
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
sys.path.insert(0, str(ROOT / "tests"))

import contourmesh  # noqa: E402
import soak  # noqa: E402

SETTINGS = (("ruled", {}), ("curved", {"bands": "curved"}))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0:400", help="seed range START:STOP (default 0:400)")
    args = ap.parse_args(argv)
    n0, n1 = (int(v) for v in args.seeds.split(":"))
    stats = {lab: {"meshes": 0, "failed checks": 0, "errors": 0} for lab, _ in SETTINGS}
    t0 = time.perf_counter()
    for seed in range(n0, n1):
        stack, pixel = soak.make_real_stack(np.random.default_rng([seed, 67]))
        for lab, kw in SETTINGS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    m = contourmesh.mesh(stack, caps="smooth", route="contours", pixel=pixel, **kw)
                except Exception as exc:  # noqa: BLE001 - every error is a result
                    stats[lab]["errors"] += 1
                    print(f"seed {seed} {lab}: {type(exc).__name__}: {str(exc)[:200]}", flush=True)
                    continue
            c = m.checks()
            stats[lab]["meshes"] += 1
            if not (c.get("watertight") and c.get("winding_consistent") and c.get("self_intersections") == 0
                    and m.volume > 0):
                stats[lab]["failed checks"] += 1
                print(f"seed {seed} {lab}: checks {c}", flush=True)
    print(f"seeds {n0}..{n1 - 1}: {stats} ({time.perf_counter() - t0:.0f} s)")
    return int(any(s["failed checks"] or s["errors"] for s in stats.values()))


if __name__ == "__main__":
    raise SystemExit(main())
