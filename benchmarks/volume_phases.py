"""CPU seconds per phase of ``contourmesh.mesh`` on one input of volume_speed.py (lobster, liver,
liver-x2, bunny-128, Al.100, or ball-N-R).

The general mesher's phase functions are wrapped with timers (no cProfile, whose overhead distorts
numpy-heavy code), and CPU time (``time.process_time``) is reported rather than wall time, so that a
loaded machine changes the split little.  A phase called inside itself counts once.  The input is
meshed once untimed first (``--no-warm`` skips it): small warm-up volumes leave some kernels of
a large mesh to load from the numba cache in the timed call (the manifold repair's first edge
count 0.35 s instead of 0.015 s on the lobster).

    python benchmarks/volume_phases.py lobster
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import volume_speed as vs  # noqa: E402

import contourmesh  # noqa: E402
from contourmesh import api, intersect, repair, volumes  # noqa: E402

SECONDS: dict = collections.defaultdict(float)
CALLS: collections.Counter = collections.Counter()
_ACTIVE: list = []

PHASES = ["_build_bridges", "_bridge_join", "_bridge_plan", "_simple_join", "_exact_join", "_pixel_cap",
          "_refine_polygons", "_split_four_face_edges", "_open_necks", "_compact", "split_nonmanifold_vertices",
          "_separate_coincident", "_checked", "prepare_volume", "_fast_volume_to_mesh", "_crossing_pairs"]
METHODS = [(volumes._Slice, "__init__"), (volumes._Mesher, "band"), (volumes._Mesher, "cap"),
           (volumes._Mesher, "quads"), (volumes._Mesher, "ring"), (volumes._Mesher, "points")]


def _timed(fn, label):
    def run(*args, **kwargs):
        t = time.process_time()
        _ACTIVE.append(label)
        try:
            return fn(*args, **kwargs)
        finally:
            _ACTIVE.pop()
            if label not in _ACTIVE:
                SECONDS[label] += time.process_time() - t
            CALLS[label] += 1
    return run


def instrument():
    for name in PHASES:
        setattr(volumes, name, _timed(getattr(volumes, name), name))
    repair.intersecting_pairs = _timed(repair.intersecting_pairs, "intersecting_pairs (crossing repair)")
    intersect.intersecting_pairs = _timed(intersect.intersecting_pairs, "intersecting_pairs (bridged joins)")
    intersect.any_intersecting = _timed(intersect.any_intersecting, "any_intersecting (bridged, sectioned joins)")
    api.diagnose = _timed(api.diagnose, "diagnose")
    for cls, meth in METHODS:
        setattr(cls, meth, _timed(getattr(cls, meth), f"{cls.__name__}.{meth}"))


def main(name: str, warm: bool = True) -> None:
    instrument()
    vol, sp = vs.make_input(name)
    contourmesh.mesh(vs.ball_volume(24, 9.0))  # numba cache loaded before timing
    contourmesh.mesh(np.pad(np.random.default_rng(1).random((12, 14, 13)) < 0.35, 1))
    if warm:  # (every kernel and signature the input needs, loaded before timing)
        contourmesh.mesh(vol, spacing=sp)
    SECONDS.clear()
    CALLS.clear()
    t = time.process_time()
    m = contourmesh.mesh(vol, spacing=sp)
    total = time.process_time() - t
    keys = ("band_joins", "bridged_joins", "exact_joins", "self_intersections", "crossings_repaired")
    print(f"{name} {vol.shape}: {total:.2f} CPU s, {len(m.faces)} faces, {({k: m.meta.get(k) for k in keys})}")
    for label, sec in sorted(SECONDS.items(), key=lambda kv: -kv[1]):
        print(f"  {label:<40} {sec:8.3f} s  {100 * sec / total:5.1f} %  x{CALLS[label]}")


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("input", nargs="?", default="lobster",
                    help="lobster, liver, liver-x2, bunny-128, Al.100 or ball-N-R (default lobster)")
    ap.add_argument("--no-warm", dest="warm", action="store_false",
                    help="time the first mesh of the input (kernels it alone needs load from the cache inside it)")
    args = ap.parse_args()
    main(args.input, warm=args.warm)
