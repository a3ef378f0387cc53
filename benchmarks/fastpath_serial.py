"""The fast path's serial part on the 512^3 ball: time outside ``_map_slabs`` (the thread pool).

Per call, at 1 and 2 threads alternating: wall time, the time inside ``_map_slabs`` and the
calling thread's CPU time outside it (``time.thread_time``, which a loaded machine does not
inflate the way it inflates wall time).  Medians over the repeats; run it against another
checkout with ``PYTHONPATH=<checkout>/src`` for an A/B.

    PYTHONPATH=src python benchmarks/fastpath_serial.py [repeats]
"""

import statistics as st
import sys
import time
from pathlib import Path

import contourmesh.fastpath as fp  # before volume_speed, which puts this checkout's src first on the path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from volume_speed import ball_volume  # noqa: E402

T = {}
_map = fp._map_slabs


def _timed_map(*a, **k):
    t, c = time.perf_counter(), time.thread_time()
    r = _map(*a, **k)
    T["map"] = T.get("map", 0) + time.perf_counter() - t
    T["map_cpu"] = T.get("map_cpu", 0) + time.thread_time() - c
    return r


fp._map_slabs = _timed_map


def main(reps):
    print("module", fp.__file__)
    vol = ball_volume(512, 250)
    for th in (1, 2):
        fp.fast_volume_to_mesh(vol, threads=th)  # compile, warm up
    res = {1: [], 2: []}
    for r in range(reps):
        for th in ((1, 2) if r % 2 == 0 else (2, 1)):
            T.clear()
            c, t = time.thread_time(), time.perf_counter()
            fp.fast_volume_to_mesh(vol, threads=th)
            wall, cpu = time.perf_counter() - t, time.thread_time() - c
            res[th].append({"wall": wall, "map": T["map"], "serial": wall - T["map"], "serial_cpu": cpu - T["map_cpu"]})
    for th in (1, 2):
        print(f"threads={th}", " ".join(f"{k}={1e3 * st.median(d[k] for d in res[th]):.2f}ms" for k in res[th][0]))
    print("wall ratio 1/2 threads (medians): %.3f" % (st.median(d["wall"] for d in res[1])
                                                     / st.median(d["wall"] for d in res[2])))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 15)
