"""What becomes of the general mesher's sectioned joins and of the bounded least-area bands inside
its bridged joins (issue 16), on one input of volume_speed.py (lobster, liver, ...).

Per mesh (one warm call first, then one counted call; CPU seconds, ``time.process_time``, the
wrappers' overhead included):

- each call of :func:`contourmesh.sections.sectioned_join` by its caller's reason (``alt``: a
  bridged join that built with more area than the exact join tries sections and keeps the smaller;
  ``fallback``: a join that could not be bridged) and its fate: ``None``; ``kept`` (in the result
  of its ``_build_bridges`` call); ``over area`` (built, but not below the plain join's area, or
  over the area limit: the caller drops it); ``dropped`` (built and within the area, replaced in a
  later rebuild round or its bridges cross another join's);
- the sectioned joins built again for the same group (a later rebuild round, or the second build);
- the bounded least-area bands (``triangulate_band_optimal`` with ``max_work``) made in
  ``_bridge_join``: how many, their CPU, how many of them fold (two faces share a diagonal of the
  bridged ring's repeated bridge ends, so the caller drops the band for the arc-length one), and
  how many of those were inside a bridged join that then failed.

    python benchmarks/section_outcomes.py liver
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import volume_speed as vs  # noqa: E402

import contourmesh  # noqa: E402
from contourmesh import sections, volumes  # noqa: E402
from contourmesh.measure import triangle_areas  # noqa: E402


def main(name: str) -> None:
    vol, sp = vs.make_input(name)
    contourmesh.mesh(vol, spacing=sp, progress=False)  # (compiled kernels loaded before counting)

    calls = []  # per sectioned join: [reason, group, result, seconds, fate]
    results = []  # the dicts _build_bridges returned
    bands = []  # per bounded band: [seconds, folded, join failed]
    pending = []  # the bounded bands of the _bridge_join calls being built: [seconds, faces, folded]
    starts = []  # where each of those calls' bands start in pending

    sectioned = sections.sectioned_join

    def sectioned_join(*a, **k):
        # (the area and limit of the _build_bridges call that asked: the nearest frame up that
        # holds them, as JoinMemory.join stands between the two)
        frame = sys._getframe(1)
        while frame is not None and "limit" not in frame.f_locals:
            frame = frame.f_back
        caller = frame.f_locals if frame is not None else {}
        reason = "fallback" if "topology_first" in k else "alt"
        t = time.process_time()
        got = sectioned(*a, **k)
        dt = time.process_time() - t
        fate = None
        if got is not None:
            area = float(triangle_areas(got.V, got.F).sum())
            over = area > caller["limit"] if reason == "fallback" else area >= caller["area"]
            fate = "over area" if over else "dropped"
        calls.append([reason, (a[1], tuple(a[2]), tuple(a[3])), got, dt, fate])
        return got

    build = volumes._build_bridges

    def build_bridges(*a, **k):
        out = build(*a, **k)
        results.append(out)
        return out

    bounded = volumes.triangulate_band_optimal

    def band_optimal(lo, hi, max_work=None):
        t = time.process_time()
        f = bounded(lo, hi, max_work=max_work)
        if max_work is not None and starts:
            pending.append([time.process_time() - t, f, None])
        return f

    folded = volumes.band_is_folded

    def band_is_folded(faces):
        got = folded(faces)
        if starts and len(pending) > starts[-1] and pending[-1][2] is None:
            pending[-1][2] = bool(got)  # (the next fold test is the bounded band's, as ids)
        return got

    bridge_join = volumes._bridge_join

    def bridge(*a, **k):
        starts.append(len(pending))
        got = bridge_join(*a, **k)
        first = starts.pop()
        bands.extend([dt, bool(fold), got is None] for dt, _f, fold in pending[first:])
        del pending[first:]
        return got

    sections.sectioned_join = volumes.sectioned_join = sectioned_join
    volumes._build_bridges = build_bridges
    volumes.triangulate_band_optimal = band_optimal
    volumes.band_is_folded = band_is_folded
    volumes._bridge_join = bridge
    t = time.process_time()
    m = contourmesh.mesh(vol, spacing=sp, progress=False)
    total = time.process_time() - t
    print(f"{name}: {total:.2f} CPU s, {len(m.faces)} faces")

    final = {id(b) for out in results for b in out.values()}
    fates = collections.defaultdict(lambda: [0, 0.0])
    seen = collections.Counter()
    again = [0, 0.0]
    for reason, group, got, dt, fate in calls:
        fate = "None" if got is None else "kept" if id(got) in final else fate
        fates[reason, fate][0] += 1
        fates[reason, fate][1] += dt
        if seen[reason, group]:
            again[0] += 1
            again[1] += dt
        seen[reason, group] += 1
    print(f"  sectioned joins: {len(calls)}, {sum(c[3] for c in calls):.3f} s")
    for (reason, fate), (n, dt) in sorted(fates.items()):
        print(f"    {reason:9s} {fate:10s} {n:4d}  {dt:.3f} s  ({100 * dt / total:.1f} % of the mesh)")
    print(f"    built again for the same group: {again[0]}, {again[1]:.3f} s")
    b = np.array(bands, dtype=float).reshape(-1, 3)
    print(f"  bounded least-area bands in bridged joins: {len(b)}, {b[:, 0].sum():.3f} s "
          f"({100 * b[:, 0].sum() / total:.1f} % of the mesh)")
    for label, sel in (("folded (dropped)", b[:, 1] > 0), ("in a join that failed", b[:, 2] > 0),
                       ("folded, in a join that failed", (b[:, 1] > 0) & (b[:, 2] > 0))):
        print(f"    {label:30s} {int(sel.sum()):4d}  {b[sel, 0].sum():.3f} s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "lobster")
