"""What ``Mesh.checks()`` costs against the meshing, before and after the fast check (issue 13).

For each input: the CPU seconds (``time.process_time``) of ``contourmesh.mesh`` (which itself runs
the crossing check once, in its repair step) and of ``Mesh.checks()`` on its mesh, and their
ratio; medians of ``--repeat`` runs after one warm-up run.  "before" is the code of a git revision
(``--before``, default the commit before the fast check), exported with ``git archive`` to a
temporary folder; "after" is this checkout's ``src``.  Each runs in its own process, one after the
other, with the same inputs; the pair counts of both are printed, and must agree.

    PYTHONPATH=src .venv/bin/python benchmarks/check_cost.py                       # ball, liver, lobster, bunny-128
    PYTHONPATH=src .venv/bin/python benchmarks/check_cost.py --inputs ball,bunny-128 --repeat 5
    PYTHONPATH=src .venv/bin/python benchmarks/check_cost.py --inputs ball,liver --repeat 1 --after-only
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
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "9e479ac"  # the commit before the fast check
INPUTS = ("ball", "liver", "lobster", "bunny-128")


def _load(name: str):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from volume_speed import ball_volume, real_volume

    if name == "ball":  # the 512^3 ball of radius 240 (takes the compiled fast path)
        return ball_volume(512, 240.0), (1.0, 1.0, 1.0)
    return real_volume(name)  # lobster: lobster.vol > 60; liver: every label > 0; bunny-128: > 0


def worker(src: str, inputs: list[str], repeat: int) -> None:
    sys.path.insert(0, src)
    import warnings

    import numpy as np

    import contourmesh

    assert Path(contourmesh.__file__).resolve().is_relative_to(Path(src).resolve()), contourmesh.__file__
    warnings.simplefilter("ignore")
    for name in inputs:
        vol, sp = _load(name)
        tm, tc = [], []
        for r in range(repeat + 1):  # run 0 warms up (compiles or loads the cached kernels)
            t = time.process_time()
            m = contourmesh.mesh(vol, spacing=sp)
            t1 = time.process_time()
            chk = m.checks()
            t2 = time.process_time()
            if r:
                tm.append(t1 - t)
                tc.append(t2 - t1)
        row = dict(input=name, faces=int(len(m.faces)), pairs=int(chk["self_intersections"]), ok=bool(chk["ok"]),
                   mesh_s=float(np.median(tm)), checks_s=float(np.median(tc)))
        row["ratio"] = row["checks_s"] / row["mesh_s"]
        print(json.dumps(row), flush=True)


def _export(rev: str, into: str) -> str:
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src"], check=True, capture_output=True).stdout
    path = Path(into) / "archive.tar"
    path.write_bytes(data)
    with tarfile.open(path) as tar:
        tar.extractall(into, filter="data")
    return str(Path(into) / "src")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", default=",".join(INPUTS))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--before", default=BEFORE, help="git revision measured as 'before' (default %(default)s)")
    ap.add_argument("--after-only", action="store_true", help="measure this checkout only (no 'before' columns)")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    inputs = [s for s in args.inputs.split(",") if s]
    if args.worker:
        worker(args.worker, inputs, args.repeat)
        return 0
    rows = {}
    with tempfile.TemporaryDirectory(prefix="check_cost_") as tmp:
        variants = (("after", str(ROOT / "src")),) if args.after_only else \
            (("before", _export(args.before, tmp)), ("after", str(ROOT / "src")))
        for variant, src in variants:
            env = dict(os.environ, PYTHONPATH=src)
            out = subprocess.run([sys.executable, __file__, "--worker", src, "--inputs", ",".join(inputs),
                                  "--repeat", str(args.repeat)], env=env, check=True, capture_output=True, text=True)
            for line in out.stdout.splitlines():
                if line.startswith("{"):
                    r = json.loads(line)
                    rows[(variant, r["input"])] = r
    if args.after_only:
        print(f"CPU seconds, medians of {args.repeat} runs; this checkout")
        print(f"{'input':10s} {'faces':>8s} {'pairs':>6s} | {'mesh':>7s} {'checks':>7s} {'ratio':>6s}")
    else:
        print(f"CPU seconds, medians of {args.repeat} runs; before = {args.before}, after = this checkout")
        print(f"{'input':10s} {'faces':>8s} {'pairs':>6s} | {'mesh':>7s} {'checks':>7s} {'ratio':>6s} (before) | "
              f"{'mesh':>7s} {'checks':>7s} {'ratio':>6s} (after)")
    for name in inputs:
        a = rows[("after", name)]
        if args.after_only:
            print(f"{name:10s} {a['faces']:8d} {a['pairs']:6d} | {a['mesh_s']:7.3f} {a['checks_s']:7.3f} {a['ratio']:6.2f}")
            continue
        b = rows[("before", name)]
        same = "" if (b["pairs"], b["faces"]) == (a["pairs"], a["faces"]) else "  PAIRS OR FACES DIFFER"
        print(f"{name:10s} {a['faces']:8d} {a['pairs']:6d} | {b['mesh_s']:7.3f} {b['checks_s']:7.3f} {b['ratio']:6.2f}"
              f"          | {a['mesh_s']:7.3f} {a['checks_s']:7.3f} {a['ratio']:6.2f}{same}")
    print(json.dumps({f"{v}:{n}": r for (v, n), r in rows.items()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
