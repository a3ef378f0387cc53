"""One against two (or more) processes for volumes that take the general mesher (issue 16).

``contourmesh.mesh(volume, spacing=...)`` with ``CONTOURMESH_THREADS`` = 1 and = N, alternating
(the order flips every repetition), in one warm process; the medians of the wall times, the calling
process's CPU, and whether the meshes are the same (vertices, faces, meta, area, volume, checks):

    python benchmarks/threads_speed.py --inputs liver-x2,liver,lobster --threads 2 --repeat 3
    python benchmarks/threads_speed.py --inputs liver-x2 --memory    # peak memory, fresh processes
    python benchmarks/threads_speed.py --inputs liver-x2 --phases    # where the slab route's time goes

``--memory`` runs each setting in a fresh process and reports its peak resident set (``ru_maxrss``)
and the workers' largest (``RUSAGE_CHILDREN``; a forked worker's figure counts the pages it shares
with the calling process), with the input's and the output mesh's sizes.  The inputs are those of
``volume_speed.py``.  The machine's load average is printed with every line: with another job
running, two processes are slowed more than one.

``--phases`` adds, for the calls on N processes, the medians of the slab route's parts of the call's
wall time, from the route's debug log (logger ``contourmesh``): before the route (preparing the
volume, the fast path's decline), the work estimate, the slabs (forks, workers, pieces read back),
the join (numbering and manifold repair, crossing test, crossing repair), the rest of the join and
checks, and after the route (the entry point's diagnostics); and the slabs' CPU times.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))


def _same(m1, m2) -> bool:
    return (m1.vertices.shape == m2.vertices.shape and m1.faces.shape == m2.faces.shape
            and bool((m1.vertices == m2.vertices).all()) and bool((m1.faces == m2.faces).all())
            and m1.meta == m2.meta and m1.area == m2.area and m1.volume == m2.volume and m1.checks() == m2.checks())


class _RouteLog(logging.Handler):
    """The slab route's debug records of one call, each with the time it was made."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.got = []

    def emit(self, record):
        self.got.append((time.perf_counter(), record.msg, record.args))


def _phases(records, start: float, end: float):
    """The parts of one call's wall time (seconds) from the slab route's debug records, or None
    where the call did not take the route."""
    est = next(((t, a) for t, m, a in records if m.startswith("slab route: work estimate %.3f")), None)
    join = next((a for _t, m, a in records if m.startswith("slab route join:")), None)
    done = next(((t, a) for t, m, a in records if m.startswith("slab route: %d slabs")), None)
    if est is None or join is None or done is None:
        return None
    (t_est, (e,)), (t_done, a) = est, done
    units, pairs, resolve = join
    return {"before the route": t_est - e - start, "estimate": e, "slabs": a[3] - e, "join units": units,
            "join pairs": pairs, "join resolve": resolve, "join, rest": a[4] - units - pairs - resolve,
            "after the route": end - t_done, "slab CPU": sorted(a[5], reverse=True)}


def speed(names, threads: int, repeat: int, phases: bool = False) -> None:
    import volume_speed as vs

    import contourmesh

    route_log = logging.getLogger("contourmesh")
    handler = _RouteLog()

    contourmesh.mesh(vs.ball_volume(40, 15))  # (warm: the fast path's and the general mesher's kernels)
    for name in names:
        vol, sp = vs.make_input(name)[:2]
        contourmesh.mesh(vol[len(vol) // 2 - 6: len(vol) // 2 + 6], spacing=sp)
        wall = {1: [], threads: []}
        cpu = {1: [], threads: []}
        kids = []
        loads = []
        last = {}
        parts = []
        for r in range(repeat):
            for th in ((1, threads) if r % 2 == 0 else (threads, 1)):
                os.environ["CONTOURMESH_THREADS"] = str(th)
                watch = phases and th != 1
                if watch:
                    handler.got.clear()
                    level = route_log.level
                    route_log.addHandler(handler)
                    route_log.setLevel(logging.DEBUG)
                k0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                c0, t0 = time.process_time(), time.perf_counter()
                try:
                    m = contourmesh.mesh(vol, spacing=sp)
                finally:
                    t1 = time.perf_counter()
                    if watch:
                        route_log.removeHandler(handler)
                        route_log.setLevel(level)
                wall[th].append(t1 - t0)
                if watch:
                    parts.append(_phases(handler.got, t0, t1))
                cpu[th].append(time.process_time() - c0)
                k1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                if th != 1:
                    kids.append(k1.ru_utime + k1.ru_stime - k0.ru_utime - k0.ru_stime)
                loads.append(os.getloadavg()[0])
                last[th] = m
                del m
        med = {th: float(np.median(v)) for th, v in wall.items()}
        print(f"{name}: 1 process {med[1]:.2f} s {[round(x, 2) for x in wall[1]]} (CPU {[round(x, 2) for x in cpu[1]]}); "
              f"{threads} {med[threads]:.2f} s {[round(x, 2) for x in wall[threads]]} (calling process CPU "
              f"{[round(x, 2) for x in cpu[threads]]}, workers' CPU {[round(x, 2) for x in kids]}); "
              f"x{med[1] / med[threads]:.2f}; same mesh: {_same(last[1], last[threads])}; "
              f"load {min(loads):.2f}-{max(loads):.2f}", flush=True)
        if phases:
            got = [p for p in parts if p is not None]
            if not got:
                print(f"  {name}: the calls on {threads} processes did not take the slab route", flush=True)
            else:
                print(f"  {name} on {threads} processes, medians of {len(got)} calls (s): " + ", ".join(
                    f"{k} {float(np.median([p[k] for p in got])):.3f}" for k in got[0] if k != "slab CPU")
                    + "; slab CPU " + str([round(float(np.median(c)), 2) for c in zip(*[p["slab CPU"] for p in got])]
                                          if len({len(p["slab CPU"]) for p in got}) == 1 else [p["slab CPU"] for p in got]),
                    flush=True)
        del last


def _one_memory(name: str, threads: int) -> dict:
    import volume_speed as vs

    import contourmesh

    vol, sp = vs.make_input(name)[:2]
    contourmesh.mesh(vol[len(vol) // 2 - 6: len(vol) // 2 + 6], spacing=sp)
    with open("/proc/self/status") as f:
        rss0 = next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024
    os.environ["CONTOURMESH_THREADS"] = str(threads)
    t = time.perf_counter()
    m = contourmesh.mesh(vol, spacing=sp)
    dt = time.perf_counter() - t
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return {"input": name, "threads": threads, "seconds": round(dt, 2), "input_MiB": round(vol.nbytes / 2**20, 1),
            "mesh_MiB": round((m.vertices.nbytes + m.faces.nbytes) / 2**20, 1), "rss_before_MiB": round(rss0, 1),
            "peak_MiB": round(own, 1), "worker_peak_MiB": round(kids, 1)}


def memory(names, threads: int) -> None:
    for name in names:
        for th in (1, threads):
            out = subprocess.run([sys.executable, __file__, "--one-memory", name, "--threads", str(th)],
                                 capture_output=True, text=True, check=True, env=dict(os.environ))
            print(out.stdout.strip().splitlines()[-1], flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inputs", default="liver-x2,liver,lobster")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--memory", action="store_true")
    ap.add_argument("--phases", action="store_true", help="the slab route's parts of the calls on N processes")
    ap.add_argument("--one-memory", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one_memory:
        print(json.dumps(_one_memory(a.one_memory, a.threads)))
        return
    names = [n for n in a.inputs.split(",") if n]
    if a.memory:
        memory(names, a.threads)
    else:
        speed(names, a.threads, a.repeat, a.phases)


if __name__ == "__main__":
    main()
