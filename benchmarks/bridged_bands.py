"""CPU time of the bridged joins' bands of one input, replayed band by band (issue 16).

    PYTHONPATH=src python benchmarks/bridged_bands.py rot-socket-256 lobster liver --reps 5

The input (``volume_speed.py``'s names) is meshed twice; the second call records the arguments and
answers of every :func:`contourmesh.volumes._bridged_band_crossing` call (the band of a bridged
ring pair or tube, its fold and crossing tests and the other rules tried).  The recorded bands are
then replayed ``--reps`` times in order (so the recent-answer memories of the least-area programme
and of the crossing test see what they see in a mesh call: a band's repeats within its own call,
not the next pass's) and each replay is checked against the recorded answer.  Printed per input:
the bands, the CPU median of one replay, the part of it in the compiled kernels (least-area
programme, crossing test, fold test, the paper's band) and the rest (Python), and the bands by
rule and outcome (``r`` guards fired, ``c1`` where the band kept crosses itself) with their CPU.

A whole-mesh A/B (``tree_ab.py``) cannot resolve a change of a few milliseconds in a call of a
second on the shared machine; this replay can, and tells where the bands' time goes.
"""

from __future__ import annotations

import argparse
import collections
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import volume_speed as vs  # noqa: E402

import contourmesh  # noqa: E402
from contourmesh import bands, fastpath, volumes  # noqa: E402
from contourmesh.bands import optimal  # noqa: E402

#: The compiled kernels whose CPU is reported apart: (module, name).
KERNELS = ((optimal, "_optimal_edges_in"), (bands, "_band_any"), (bands, "_folded"), (fastpath, "_pair_bands"))


def record(name):
    """The bands of the second mesh call of ``name``: ``(P, na, ids, rule, answer)`` each."""
    vol, sp = vs.make_input(name)
    contourmesh.mesh(vol, spacing=sp)
    got = []
    inner = volumes._bridged_band_crossing

    def wrapped(P, na, ids, rule):
        out = inner(P, na, ids, rule)
        got.append((P.copy(), na, ids.copy(), rule, None if out is None else (out[0].copy(), out[1], out[2])))
        return out

    volumes._bridged_band_crossing = wrapped
    try:
        contourmesh.mesh(vol, spacing=sp)
    finally:
        volumes._bridged_band_crossing = inner
    return got


def same(out, want):
    """Whether a replayed answer is the recorded one (faces bit for bit, guards, crossing)."""
    if out is None or want is None:
        return out is None and want is None
    return out[0].tobytes() == want[0].tobytes() and out[1:] == want[1:]


def replay(rec, reps):
    """CPU seconds of each replay of ``rec``, and the number of answers that differ."""
    bad = sum(not same(volumes._bridged_band_crossing(P, na, ids, rule), want) for P, na, ids, rule, want in rec)
    times = []
    for _ in range(reps):
        t = time.process_time()
        for P, na, ids, rule, _want in rec:
            volumes._bridged_band_crossing(P, na, ids, rule)
        times.append(time.process_time() - t)
    return times, bad


def split(rec):
    """CPU seconds of one replay in each of :data:`KERNELS`, and per (rule, outcome)."""
    spent = collections.Counter()
    kinds = collections.Counter()
    count = collections.Counter()
    saved = [(mod, fn, getattr(mod, fn)) for mod, fn in KERNELS]

    def timed(fn, inner):
        def call(*args):
            t = time.process_time()
            out = inner(*args)
            spent[fn] += time.process_time() - t
            return out
        return call

    for mod, fn, inner in saved:
        setattr(mod, fn, timed(fn, inner))
    try:
        for P, na, ids, rule, want in rec:
            t = time.process_time()
            volumes._bridged_band_crossing(P, na, ids, rule)
            kind = (rule, "none" if want is None else f"r{want[1]}c{int(want[2])}")
            kinds[kind] += time.process_time() - t
            count[kind] += 1
    finally:
        for mod, fn, inner in saved:
            setattr(mod, fn, inner)
    return spent, kinds, count


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("inputs", nargs="+")
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args(argv)
    for name in args.inputs:
        rec = record(name)
        times, bad = replay(rec, args.reps)
        total = statistics.median(times)
        spent, kinds, count = split(rec)
        print(f"{name}: {len(rec)} bands, replay CPU median {1e3 * total:.1f} ms (min {1e3 * min(times):.1f}), "
              f"answers differing {bad}")
        rest = total - sum(spent.values())
        print("  kernels: " + ", ".join(f"{fn} {1e3 * spent[fn]:.1f} ms" for _m, fn in KERNELS)
              + f"; the rest {1e3 * rest:.1f} ms")
        for kind in sorted(kinds):
            print(f"  {kind[0]:>10} {kind[1]:>5}: {count[kind]:4d} bands {1e3 * kinds[kind]:7.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
