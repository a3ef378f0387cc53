"""Self-intersections of contourmesh's own meshes (issue 13): shared samples and random volumes.

For every shared sample volume (default mode and ``polygon="none"``, or every mode with
``--modes all``) prints the faces, the intersecting face pairs (``contourmesh.intersect``), the
faces involved, the route and its repair counts, and the time of the check against the meshing
time (wall and CPU seconds; an error raised by the mesher is recorded as the row's ``error``); then the counts over random volumes of the issue's five kinds.

    python benchmarks/intersect_counts.py                  # samples + 150 random volumes
    python benchmarks/intersect_counts.py --random 0 --samples bunny-64,liver
    python benchmarks/intersect_counts.py --random 0 --modes all --json out.json   # every sample, every mode
    python benchmarks/intersect_counts.py --speed          # the 512^3 ball and the liver, timed

A mode is ``default``, a polygon name (``none``), or ``polygon/triangulation/refine`` (``mlp/greedy/band``,
``none/optimal/-``); ``all`` is every ``polygon x triangulation x refine`` (3 x 4 x 2 = 24 modes).
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
DATA = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))

SAMPLES = {  # name -> (file, threshold or label rule)
    "bunny-32": ("volumes/dgtal/bunny-32.npz", None),
    "bunny-64": ("volumes/dgtal/bunny-64.npz", None),
    "bunny-128": ("volumes/dgtal/bunny-128.npz", None),
    "cat10": ("volumes/dgtal/cat10.npz", None),
    "Al.100": ("volumes/dgtal/Al.100.npz", None),
    "lobsterCroped": ("volumes/dgtal/lobsterCroped.npz", None),
    "lobster": ("volumes/dgtal/lobster.npz", None),
    "dicomSample": ("volumes/dgtal/dicomSample.npz", None),
    "liver": ("volumes/cgogn/liver.npz", None),
    "liver-255": ("volumes/cgogn/liver.npz", 255),
}


def load(name):
    f, label = SAMPLES[name]
    d = np.load(DATA / f)
    mask = d["mask"] if label is None else d["volume"] == label
    return np.pad(mask, 1), tuple(float(s) for s in d["spacing_xyz"])


POLYGONS = ("mlp", "dss", "none")
TRIANGULATIONS = ("wiederhold", "greedy", "optimal", "arclength")
REFINES = ("-", "band")
ALL_MODES = tuple(f"{p}/{t}/{r}" for r in REFINES for p in POLYGONS for t in TRIANGULATIONS)


def present_samples(text: str):
    """``(name, volume, spacing)`` for each comma-separated sample name found under DATA (the others
    are reported and skipped)."""
    for name in [s for s in text.split(",") if s]:
        if not (DATA / SAMPLES[name][0]).exists():
            print(f"{name}: not found under {DATA}", flush=True)
            continue
        yield (name, *load(name))


def mode_kwargs(mode: str) -> dict:
    """The ``contourmesh.mesh`` keywords of a mode name (see the module docstring)."""
    if mode == "default":
        return {}
    if "/" not in mode:
        return {"polygon": mode}
    p, t, r = mode.split("/")
    if p not in POLYGONS or t not in TRIANGULATIONS or r not in REFINES:
        raise ValueError(f"unknown mode {mode!r}; expected polygon/triangulation/refine with polygon in {POLYGONS}, "
                         f"triangulation in {TRIANGULATIONS}, refine in {REFINES}")
    return {"polygon": p, "triangulation": t, **({"refine": r} if r != "-" else {})}


def expand_modes(text: str) -> list[str]:
    out = []
    for m in (x for x in text.split(",") if x):
        out.extend(ALL_MODES if m == "all" else [m])
    for m in out:
        mode_kwargs(m)  # a bad name fails before any meshing
    return out


def measure(vol, spacing=(1.0, 1.0, 1.0), **kw):
    import contourmesh
    from contourmesh.intersect import intersecting_pairs

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t, c = time.perf_counter(), time.process_time()
        try:
            m = contourmesh.mesh(vol, spacing=spacing, **kw)
        except Exception as e:  # a refusal or a crash is recorded, and the run goes on
            return dict(error=f"{type(e).__name__}: {e}"[:400], pairs=0, faces=0,
                        mesh_cpu_s=round(time.process_time() - c, 3))
        tm, cm = time.perf_counter() - t, time.process_time() - c
    t, c = time.perf_counter(), time.process_time()
    p = intersecting_pairs(m.vertices, m.faces)
    tc, cc = time.perf_counter() - t, time.process_time() - c
    keys = ("route", "self_intersections", "crossings_repaired", "crossing_fallbacks", "band_fallbacks",
            "polygon_fallbacks")
    return dict(faces=int(len(m.faces)), pairs=int(len(p)), faces_involved=int(len(np.unique(p))),
                mesh_s=round(tm, 3), check_s=round(tc, 3), ratio=round(tc / tm, 3),
                mesh_cpu_s=round(cm, 3), check_cpu_s=round(cc, 3),
                **{k: m.meta[k] for k in keys if k in m.meta})


def ball(n, r):
    x = np.arange(n) - n / 2 + 0.5
    return x[:, None, None] ** 2 + x[None, :, None] ** 2 + x[None, None, :] ** 2 < r * r


def main(argv=None) -> int:
    from intersect_crosscheck import VOLUME_KINDS, random_volume

    from contourmesh.intersect import intersecting_pairs

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default=",".join(SAMPLES))
    ap.add_argument("--modes", default="default,none",
                    help="comma-separated modes: default, a polygon name, polygon/triangulation/refine, or all")
    ap.add_argument("--random", type=int, default=150)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--speed", action="store_true")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    modes = expand_modes(args.modes)

    def save(out):  # after every mesh, atomically: a long run can be read while it goes
        if args.json:
            tmp = args.json.with_suffix(args.json.suffix + ".tmp")
            tmp.write_text(json.dumps(out, indent=1))
            os.replace(tmp, args.json)
    intersecting_pairs(np.eye(3), np.array([[0, 1, 2], [0, 2, 1]]))  # compile outside the timings
    measure(ball(12, 4))
    out = {"samples": {}, "random": {}, "speed": {}}
    if args.speed:
        d = np.load(DATA / SAMPLES["liver"][0])
        sp = tuple(float(s) for s in d["spacing_xyz"])
        for name, vol, spacing in (("ball-512-r240", ball(512, 240), (1.0, 1.0, 1.0)),
                                   ("liver", np.pad(d["mask"], 1), sp), ("liver-255", np.pad(d["volume"] == 255, 1), sp)):
            best = None
            for _ in range(2):
                r = measure(vol, spacing)
                best = r if best is None or r["check_s"] < best["check_s"] else best
            out["speed"][name] = best
            print("speed", name, best, flush=True)
    for name, vol, spacing in present_samples(args.samples):
        for mode in modes:
            r = measure(vol, spacing, **mode_kwargs(mode))
            out["samples"][f"{name}:{mode}"] = r
            print(name, mode, r, flush=True)
            save(out)
    for mode in modes if args.random else []:
        kw = mode_kwargs(mode)
        rs = np.random.default_rng(args.seed)
        for i in range(args.random):
            kind = VOLUME_KINDS[i % 5]
            r = measure(random_volume(kind, rs), **kw)
            b = out["random"].setdefault(f"{kind}:{mode}", dict(volumes=0, crossing=0, pairs=0, max_pairs=0, faces=0))
            b["volumes"] += 1
            b["crossing"] += r["pairs"] > 0
            b["pairs"] += r["pairs"]
            b["max_pairs"] = max(b["max_pairs"], r["pairs"])
            b["faces"] += r["faces"]
        for k, b in out["random"].items():
            if k.endswith(":" + mode):
                print("random", k, b, flush=True)
    save(out)
    crossing = sorted(k for k, r in out["samples"].items() if r["pairs"])
    failed = sorted(k for k, r in out["samples"].items() if "error" in r)
    print(f"samples x modes: {len(out['samples'])} meshes, {len(crossing)} with crossing faces"
          + (f": {', '.join(crossing)}" if crossing else "")
          + (f"; {len(failed)} raised: {', '.join(failed)}" if failed else ""), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
