"""The calling thread's serial CPU in ``contourmesh.mesh(...)`` plus ``.area`` (issue 16).

Per call, at ``CONTOURMESH_THREADS`` 1 and 2 alternating, in one warm process: wall time, the
process's CPU (every thread), the calling thread's CPU outside :func:`contourmesh._workers.run_all`
(``serial_cpu``: what a second thread cannot share; ``time.thread_time``, which another job on
the machine inflates far less than wall time) and the wall time inside ``run_all``.  Medians over
the repeats; run it against another checkout with ``PYTHONPATH=<checkout>/src`` for an A/B.

    PYTHONPATH=src python benchmarks/threads_serial.py [input] [repeats]    # default ball-512-250 15
"""

import os
import statistics as st
import sys
import time
from pathlib import Path

import contourmesh  # (first: volume_speed puts this checkout's src first on the path)
import contourmesh._workers as workers
import contourmesh.fastpath as fp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import volume_speed as vs  # noqa: E402

T = {}
_run_all = workers.run_all


def _timed_run_all(*a, **k):
    c, w = time.thread_time(), time.perf_counter()
    try:
        return _run_all(*a, **k)
    finally:
        T["in_cpu"] = T.get("in_cpu", 0) + time.thread_time() - c
        T["in_wall"] = T.get("in_wall", 0) + time.perf_counter() - w


workers.run_all = fp.run_all = _timed_run_all  # (the other modules import it at each call)


def main(name, reps):
    print("module", contourmesh.__file__, "input", name, "load", os.getloadavg())
    vol, sp = vs.make_input(name)[:2]

    def call(th):
        os.environ["CONTOURMESH_THREADS"] = str(th)
        return contourmesh.mesh(vol, spacing=sp).area

    for th in (1, 2):
        call(th)
    res = {1: [], 2: []}
    for r in range(reps):
        for th in ((1, 2) if r % 2 == 0 else (2, 1)):
            T.clear()
            c, p, w = time.thread_time(), time.process_time(), time.perf_counter()
            call(th)
            res[th].append({"wall": time.perf_counter() - w, "proc_cpu": time.process_time() - p,
                            "serial_cpu": time.thread_time() - c - T.get("in_cpu", 0), "in_run_all": T.get("in_wall", 0)})
    for th in (1, 2):
        print(f"threads={th}", " ".join(f"{k}={1e3 * st.median(d[k] for d in res[th]):.1f}ms" for k in res[th][0]))
    print("wall ratio 1/2 threads (medians): %.3f" % (st.median(d["wall"] for d in res[1])
                                                     / st.median(d["wall"] for d in res[2])))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "ball-512-250", int(sys.argv[2]) if len(sys.argv) > 2 else 15)
