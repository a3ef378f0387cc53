"""A whole RT structure set, every ROI: CPU seconds of reading and meshing (issue 15's speed target).

For each non-empty ROI of the shared RT structure set (``$CONTOURMESH_DATA`` or ``../shared/data``:
``contours/dicompyler-core/rtss.dcm``): the CPU seconds (``time.process_time``, so a busy machine
shifts the figure little) of ``read_contours`` plus ``contourmesh.mesh`` with the given options, the
faces and the crossing face pairs left.  One warm-up pass (numba's caches), then the best of
``--repeat`` passes.  ``--before REV`` also runs the code of a git revision (exported with
``git archive``) in its own process, one after the other, for a ratio measured in the same session.

    PYTHONPATH=src .venv/bin/python benchmarks/rt_set.py
    PYTHONPATH=src .venv/bin/python benchmarks/rt_set.py --before c65abcf --repeat 3
    PYTHONPATH=src .venv/bin/python benchmarks/rt_set.py --caps smooth --bands curved
    PYTHONPATH=src .venv/bin/python benchmarks/rt_set.py --profile 30    # cProfile, top 30 by own time
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def rt_path() -> Path:
    data = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))
    return data / "contours" / "dicompyler-core" / "rtss.dcm"


def existing_rt_path() -> Path | None:
    """:func:`rt_path` where the file is there, else None after saying so on stderr."""
    path = rt_path()
    if not path.exists():
        print(f"the shared RT structure set is not here: {path} (set CONTOURMESH_DATA)", file=sys.stderr)
        return None
    return path


def one_pass(path, options) -> tuple[float, dict]:
    import contourmesh
    from contourmesh.io.contours import list_rois, read_contours

    rois = [(num, name) for num, name, n in list_rois(path) if n]
    per = {}
    t_all = time.process_time()
    for num, name in rois:
        t0 = time.process_time()
        st = read_contours(path, roi=num)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = contourmesh.mesh(st, **options)
        per[name] = {"cpu": round(time.process_time() - t0, 3), "faces": len(m.faces),
                     "crossings": m.meta.get("self_intersections")}
    return time.process_time() - t_all, per


def measure(path, options, repeat: int, profile: int = 0) -> dict:
    one_pass(path, options)  # warm-up: numba's caches
    if profile:
        import cProfile
        import pstats

        pr = cProfile.Profile()
        pr.enable()
        total, per = one_pass(path, options)
        pr.disable()
        pstats.Stats(pr, stream=sys.stderr).sort_stats("tottime").print_stats(profile)
        return {"total": total, "per_roi": per}
    runs = [one_pass(path, options) for _ in range(repeat)]
    total, per = min(runs, key=lambda r: r[0])
    return {"total": total, "per_roi": per, "all": [r[0] for r in runs]}


def at_revision(rev: str, script: Path, args: list) -> dict:
    """The JSON that ``script --json ARGS`` prints when run against revision ``rev``'s sources (``git
    archive`` of ``src`` into a temporary folder, put first on ``PYTHONPATH``)."""
    with tempfile.TemporaryDirectory() as tmp:
        tar = Path(tmp) / "src.tar"
        with open(tar, "wb") as fh:
            subprocess.run(["git", "archive", rev, "src"], cwd=ROOT, stdout=fh, check=True)
        with tarfile.open(tar) as tf:
            tf.extractall(tmp, filter="data")
        cmd = [sys.executable, str(Path(script).resolve()), "--json", *args]
        env = dict(os.environ, PYTHONPATH=str(Path(tmp) / "src"))
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
        return json.loads(out)


def _before(rev: str, args) -> dict:
    # this script, run against that revision's sources
    return at_revision(rev, Path(__file__), ["--repeat", str(args.repeat)] + _option_args(args))


def _option_args(args) -> list:
    out = []
    for k in ("caps", "bands"):
        if getattr(args, k) is not None:
            out += [f"--{k}", getattr(args, k)]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="timed passes after the warm-up (the best is kept)")
    ap.add_argument("--caps", default=None, choices=["flat", "half", "smooth"])
    ap.add_argument("--bands", default=None, choices=["ruled", "curved"])
    ap.add_argument("--before", default=None, metavar="REV", help="also time this git revision's code")
    ap.add_argument("--profile", type=int, default=0, metavar="N", help="one profiled pass: the top N functions")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON only")
    args = ap.parse_args(argv)
    path = existing_rt_path()
    if path is None:
        return 2
    options = {k: getattr(args, k) for k in ("caps", "bands") if getattr(args, k) is not None}
    res = measure(path, options, args.repeat, args.profile)
    if args.json:
        print(json.dumps(res))
        return 0
    before = _before(args.before, args) if args.before else None
    print(f"RT set {path.name}, options {options or 'default'}: CPU {res['total']:.2f} s (best of {args.repeat})")
    for name, r in res["per_roi"].items():
        b = f"   before {before['per_roi'][name]['cpu']:.2f} s" if before and name in before["per_roi"] else ""
        print(f"  {name:<18} {r['cpu']:6.2f} s  {r['faces']:7d} faces  crossings {r['crossings']}{b}")
    if before:
        print(f"before ({args.before}): CPU {before['total']:.2f} s; ratio after/before {res['total'] / before['total']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
