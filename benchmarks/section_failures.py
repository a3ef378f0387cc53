"""Where the general mesher's sectioned joins that fail spend their time (issue 16), on one input of
volume_speed.py (lobster, liver, ...).

Counts, per mesh, the sectioned joins (:func:`contourmesh.sections.sectioned_join`) that fail and
the CPU seconds they cost; for each failing join the piece that ended it (``lo-sec``: slice to
section, ``sec-hi``, ``sec-sec``), why (``plan``: no bridge plan, a cheap test of the groups;
``bridge``: :func:`contourmesh.volumes._bridge_join` gave None; ``other``: a lone component or a
keyhole under a cap), whether that piece's lower layer held bridges of the piece below it (``taken``:
its answer depends on the earlier pieces' output) and the seconds spent before it; why the pieces'
bridged joins failed (the last test that failed inside ``_bridge_join``); and, over the rebuild
rounds of ``_build_bridges``, the joins built again: whether their own rings, the slices' edges
and the result changed.  CPU time (``time.process_time``) with the wrappers' overhead included.

    python benchmarks/section_failures.py lobster
"""

from __future__ import annotations

import collections
import hashlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import volume_speed as vs  # noqa: E402

import contourmesh  # noqa: E402
from contourmesh import intersect, sections, volumes  # noqa: E402
from contourmesh.bands import bridges  # noqa: E402


def _digest(*arrays) -> str:
    h = hashlib.sha1()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def main(name: str) -> None:
    vol, sp = vs.make_input(name)
    contourmesh.mesh(vs.ball_volume(24, 9.0))  # numba cache loaded before counting
    contourmesh.mesh(np.pad(np.random.default_rng(1).random((12, 14, 13)) < 0.35, 1))

    joins = []  # per sectioned join: its pieces (dicts) and result
    inside = []  # events inside the current _bridge_join of a piece: (test, failed)

    def watch(mod, attr, failed):
        fn = getattr(mod, attr)

        def run(*a, **k):
            r = fn(*a, **k)
            if inside:
                inside[-1].append((attr, failed(r)))
            return r
        setattr(mod, attr, run)

    watch(bridges, "bridge_tree", lambda r: r is None)
    watch(intersect, "any_intersecting", bool)
    watch(volumes, "_merged_band_retry", lambda r: r is None)
    watch(volumes, "band_is_folded", bool)
    bridge_fail = collections.Counter()

    section_ops = volumes._section_ops

    def ops():
        o = section_ops()
        plan, bridge = o.bridge_plan, o.bridge_join

        def plan_w(*a, **k):
            r = plan(*a, **k)
            if joins and joins[-1]["pieces"]:
                joins[-1]["pieces"][-1]["last"] = "plan" if r is None else None
            return r

        def bridge_w(*a, **k):
            inside.append([])
            try:
                r = bridge(*a, **k)
            finally:
                ev = inside.pop()
            if r is None:
                bad = [e for e, f in ev if f]
                bridge_fail[bad[-1] if bad else "lid, cap or degenerate face"] += 1
            if joins and joins[-1]["pieces"]:
                joins[-1]["pieces"][-1]["last"] = "bridge" if r is None else None
            return r
        o.bridge_plan, o.bridge_join = plan_w, bridge_w
        return o
    volumes._section_ops = ops

    pieces = sections._pieces

    def pieces_w(o, P, Q, *a):
        rec = {"kind": ("lo" if P.main is not None else "sec") + "-" + ("hi" if Q.main is not None else "sec"),
               "taken": bool(P.taken), "last": None, "t0": time.process_time()}
        if joins:
            joins[-1]["pieces"].append(rec)
        r = pieces(o, P, Q, *a)
        rec["ok"] = r is not None
        if r is None and rec["last"] is None:
            rec["last"] = "other"
        return r
    sections._pieces = pieces_w

    sectioned = sections.sectioned_join
    seen = {}  # (k, ga, gb, topology_first) -> (own rings, edges, result) digests
    again = collections.Counter()
    again_s = collections.defaultdict(float)

    def sectioned_w(ops_, k, ga, gb, slices, zs, poly, edges_of, *a, topology_first=False):
        own = _digest(*[np.asarray(poly(kk, c, h)) for kk, g in ((k, ga), (k + 1, gb)) for c in g
                        for h in range(-1, len(slices[kk].holes[c]))])
        edges = _digest(*edges_of(k), *edges_of(k + 1))
        rec = {"pieces": [], "t0": time.process_time()}
        joins.append(rec)
        try:
            r = sectioned(ops_, k, ga, gb, slices, zs, poly, edges_of, *a, topology_first=topology_first)
        finally:
            joins.pop()
        dt = time.process_time() - rec["t0"]
        result = None if r is None else _digest(r.V, r.F)
        key = (k, tuple(ga), tuple(gb), topology_first)
        if key in seen:
            o_own, o_edges, o_result = seen[key]
            cat = ("own rings " + ("same" if o_own == own else "changed"),
                   "edges " + ("same" if o_edges == edges else "changed"),
                   "result " + ("same" if o_result == result else "changed"), "failed" if r is None else "built")
            again[cat] += 1
            again_s[cat] += dt
        seen[key] = (own, edges, result)
        stats.append((rec, r is not None, dt, topology_first))
        return r
    stats = []
    sections.sectioned_join = sectioned_w

    t = time.process_time()
    contourmesh.mesh(vol, spacing=sp)
    total = time.process_time() - t
    failed = [s for s in stats if not s[1]]
    print(f"{name}: {total:.2f} CPU s (instrumented); {len(stats)} sectioned joins, {len(failed)} failed, "
          f"{sum(s[2] for s in stats):.3f} s in all, {sum(s[2] for s in failed):.3f} s in the failed ones")
    ends = collections.Counter()
    ends_s = collections.defaultdict(lambda: [0.0, 0.0])
    for rec, _ok, dt, first in failed:
        if not rec["pieces"]:
            cat = ("no piece built", "topology first" if first else "")
            before = 0.0
        else:
            last = rec["pieces"][-1]
            why = last["last"] if not last["ok"] else "every piece built: the topology test or the assembly"
            cat = (last["kind"], why, "taken" if last["taken"] else "no taken",
                   f"{len(rec['pieces'])} pieces")
            before = last["t0"] - rec["t0"]
        ends[cat] += 1
        ends_s[cat][0] += before
        ends_s[cat][1] += dt
    print("failed joins by the piece that ended them: count, s before that piece, s in all")
    for cat, n in ends.most_common():
        print(f"  {' / '.join(c for c in cat if c):<45} {n:4d} {ends_s[cat][0]:7.3f} {ends_s[cat][1]:7.3f}")
    print("pieces' bridged joins that failed, by the last test that failed:")
    for cat, n in bridge_fail.most_common():
        print(f"  {cat:<45} {n:4d}")
    print("sectioned joins built again in a later round: count, s")
    for cat, n in again.most_common():
        print(f"  {' / '.join(cat):<60} {n:4d} {again_s[cat]:7.3f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "lobster")
