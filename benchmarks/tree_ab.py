"""CPU seconds of ``contourmesh.mesh`` from two source trees, in alternating processes (issue 16).

    git -C /work/main archive b8be1c9 src | tar -x -C /tmp/base    # the tree to compare with
    PYTHONPATH=src python benchmarks/tree_ab.py --base /tmp/base/src --inputs lobster,liver --rounds 4

Each round starts one process per tree (base first, then this checkout's ``src``); a process makes
the input of ``volume_speed.py``, meshes it once to load the compiled kernels, then times
``--calls`` calls (``time.process_time``, so a busy machine shifts the figures less than wall
time).  Printed per input: the medians of each tree's calls, their ratio, and each tree's mesh
hash (``scripts/mesh_digest.py``'s: sha1 of the vertex and face bytes), which must agree where a
change is meant to keep the meshes.  The machine is shared: quote medians and the ratio of one run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import hashlib, json, sys, time
sys.path.insert(0, {src!r})
import numpy as np
import contourmesh  # (first: volume_speed puts this checkout's src on the path)
sys.path.insert(0, {bench!r})
import volume_speed as vs

vol, sp = vs.make_input({name!r})
m = contourmesh.mesh(vol, spacing=sp)
h = hashlib.sha1()
h.update(np.ascontiguousarray(m.vertices, dtype=np.float64).tobytes())
h.update(np.ascontiguousarray(m.faces, dtype=np.int64).tobytes())
ts = []
for _ in range({calls}):
    t = time.process_time()
    contourmesh.mesh(vol, spacing=sp)
    ts.append(time.process_time() - t)
print(json.dumps({{"file": contourmesh.__file__, "hash": h.hexdigest()[:16], "cpu": ts}}))
"""


def run(src: str, name: str, calls: int) -> dict:
    code = CHILD.format(src=str(src), bench=str(ROOT / "benchmarks"), name=name, calls=calls)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ))
    if out.returncode != 0:
        raise SystemExit(f"{src} {name}: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}")
    got = json.loads(out.stdout.strip().splitlines()[-1])
    if not Path(got["file"]).resolve().is_relative_to(Path(src).resolve()):
        raise SystemExit(f"the process meant for {src} imported {got['file']}")
    return got


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the other tree's src folder")
    ap.add_argument("--inputs", default="lobster,liver", help="inputs of volume_speed.py, comma-separated")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--calls", type=int, default=2, help="timed calls per process")
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.calls < 1:
        ap.error("--rounds and --calls must be at least 1")
    trees = {"base": str(Path(args.base).resolve()), "this": str(ROOT / "src")}
    for name in args.inputs.split(","):
        cpu = {t: [] for t in trees}
        hashes = {t: set() for t in trees}
        for _ in range(args.rounds):
            for t, src in trees.items():
                got = run(src, name, args.calls)
                cpu[t] += got["cpu"]
                hashes[t].add(got["hash"])
        med = {t: statistics.median(v) for t, v in cpu.items()}
        print(f"{name}: base {med['base']:.3g} CPU s, this {med['this']:.3g} CPU s, "
              f"{med['base'] / med['this']:.2f}x ({len(cpu['this'])} calls each); "
              f"hashes base {sorted(hashes['base'])}, this {sorted(hashes['this'])}")
        print("  base: " + " ".join(f"{x:.3g}" for x in cpu["base"]))
        print("  this: " + " ".join(f"{x:.3g}" for x in cpu["this"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
