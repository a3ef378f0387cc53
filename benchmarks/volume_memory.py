"""Peak memory of ``contourmesh.mesh(volume)`` on the real inputs of ``volume_speed.py``.

Each (input, repeat) runs in a fresh process: the input is made (``volume_speed.make_input``),
the kernels are compiled on a small volume with holes and branching, the RSS high-water mark is
reset (``/proc/self/clear_refs``), then one call of ``contourmesh.mesh``.  Printed per run: the
RSS before the call, the peak (``VmHWM``), the peak above the RSS before, the input and output
mesh bytes (vertices + faces as returned), the ratio of the peak to (input + output), the
process CPU seconds of the call and a hash of the mesh (vertices and faces, as
``scripts/mesh_digest.py``).

    python benchmarks/volume_memory.py --inputs lobster,liver,liver-x2 --repeat 3
    python benchmarks/volume_memory.py --inputs liver --phases   # + the highest RSS per phase
    git archive e0b556d src | tar -x -C /tmp/base      # an older revision's code, then:
    python benchmarks/volume_memory.py --repeat 3 --against /tmp/base/src   # alternating runs, medians

``--phases`` also samples the RSS every 5 ms in a thread and prints, for each phase of the
general mesher (slices, joins, bridges, assembly, crossing test, repair, checks), the highest RSS
seen while it ran (the phases are found by wrapping the module's functions).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

CHILD = r"""
import sys, json, time, hashlib, threading
sys.path.insert(0, %(src)r); sys.path.insert(0, %(bench)r)
import numpy as np
import volume_speed as vs
sys.path.insert(0, %(src)r)  # (volume_speed puts its own tree's src first)
import contourmesh
assert contourmesh.__file__.startswith(%(src)r), contourmesh.__file__
vol, sp = vs.make_input(%(spec)r)
warm = np.pad(np.random.default_rng(1).random((12, 14, 13)) < 0.35, 1)
contourmesh.mesh(warm)

def st(key):
    return [int(l.split()[1]) / 1024 for l in open('/proc/self/status') if l.startswith(key)][0]

phases = {}
if %(phases)r:
    from contourmesh import volumes, repair
    current = ['other']
    stop = False
    def sample():
        while not stop:
            r = st('VmRSS:')
            if r > phases.get(current[0], 0):
                phases[current[0]] = r
            time.sleep(0.005)
    def wrap(mod, name, label):
        f = getattr(mod, name)
        def g(*a, **k):
            prev = current[0]
            current[0] = label
            try:
                return f(*a, **k)
            finally:
                current[0] = prev
        setattr(mod, name, g)
    for name, label in [('_fast_volume_to_mesh', 'fast path'), ('prepare_volume', 'prepare'),
                        ('_Slice', 'slices'), ('overlap_groups', 'joins'), ('_simple_join', 'joins'),
                        ('_bridge_plan', 'joins'), ('_densify_branching', 'densify'),
                        ('_build_bridges', 'bridges'), ('_assemble', 'assemble: joins and caps'),
                        ('_number_units', 'assemble: numbering'),
                        ('_split_four_face_edges', 'repair: four-face'), ('_open_necks', 'repair: necks'),
                        ('split_nonmanifold_vertices', 'repair: fans'), ('_separate_coincident', 'repair: coincident'),
                        ('_crossing_pairs', 'crossing test'), ('resolve_crossings', 'resolve crossings'),
                        ('_checked', 'checked')]:
        wrap(volumes, name, label)
    th = threading.Thread(target=sample, daemon=True)
    th.start()
rss0 = st('VmRSS:')
open('/proc/self/clear_refs', 'w').write('5')
t = time.process_time()
m = contourmesh.mesh(vol, spacing=sp)
cpu = time.process_time() - t
peak = st('VmHWM:')
if %(phases)r:
    stop = True
h = hashlib.sha1()
h.update(np.ascontiguousarray(m.vertices, dtype=np.float64).tobytes())
h.update(np.ascontiguousarray(m.faces, dtype=np.int64).tobytes())
print(json.dumps({'rss_before': rss0, 'peak': peak, 'vol_mib': vol.nbytes / 2**20,
                  'out_mib': (m.vertices.nbytes + m.faces.nbytes) / 2**20, 'faces': len(m.faces),
                  'cpu': cpu, 'hash': h.hexdigest()[:16], 'fast': bool(m.meta.get('fast_path', False)),
                  'phases': phases}))
"""


def run(spec: str, phases: bool = False, src: Path = ROOT / "src") -> dict:
    code = CHILD % {"src": str(src), "bench": str(HERE), "spec": spec, "phases": phases}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=3600)
    if out.returncode != 0:
        raise RuntimeError(out.stderr.strip()[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", default="lobster,liver,liver-x2")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--phases", action="store_true", help="highest RSS per phase of the general mesher")
    ap.add_argument("--json", help="write the runs here")
    ap.add_argument("--against", metavar="SRC",
                    help="another tree's src folder (say, an older revision's, from git archive): its runs "
                         "alternate with this tree's, and the medians of both are printed")
    a = ap.parse_args(argv)
    trees = [("this", ROOT / "src")] + ([("other", Path(a.against).resolve())] if a.against else [])
    runs = []
    print("| tree | input | run | RSS before MiB | peak MiB | peak - before | input MiB | output MiB | "
          "peak / (in + out) | (peak - before + in) / (in + out) | CPU s | faces | hash |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for rep in range(a.repeat):
        for spec in a.inputs.split(","):
            for tree, src in (trees if rep % 2 == 0 else trees[::-1]):
                r = run(spec, a.phases, src)
                r.update(input=spec, run=rep, tree=tree)
                runs.append(r)
                io = r["vol_mib"] + r["out_mib"]
                print(f"| {tree} | {spec} | {rep} | {r['rss_before']:.0f} | {r['peak']:.0f} | "
                      f"{r['peak'] - r['rss_before']:.0f} | {r['vol_mib']:.0f} | {r['out_mib']:.0f} | "
                      f"{r['peak'] / io:.2f} | {(r['peak'] - r['rss_before'] + r['vol_mib']) / io:.2f} | "
                      f"{r['cpu']:.2f} | {r['faces']} | {r['hash']} |", flush=True)
                if a.phases:
                    for name, mib in r["phases"].items():
                        print(f"    {name:24s} {mib:8.0f} MiB")
    if a.repeat > 1 or a.against:
        print("\nmedians: | tree | input | peak - before MiB | (peak - before + in) / (in + out) | CPU s |")
        for spec in a.inputs.split(","):
            for tree, _ in trees:
                rs = [r for r in runs if r["input"] == spec and r["tree"] == tree]
                med = lambda f: float(np.median([f(r) for r in rs]))  # noqa: E731
                print(f"| {tree} | {spec} | {med(lambda r: r['peak'] - r['rss_before']):.0f} | "
                      f"{med(lambda r: (r['peak'] - r['rss_before'] + r['vol_mib']) / (r['vol_mib'] + r['out_mib'])):.2f} | "
                      f"{med(lambda r: r['cpu']):.2f} |")
    if a.json:
        Path(a.json).write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
