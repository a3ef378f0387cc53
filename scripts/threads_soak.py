"""Soak of the slab route (issue 16): random stacks of small shapes meshed with one and with two
processes must give the same mesh, bit for bit (vertices, faces, meta, area, volume, checks).

Each stack is three to six of the robustness soak's small random volumes (``tests/soak.py``), one
above another, so that slab seams fall everywhere; the slab route's work threshold is lifted.

    PYTHONPATH=src python scripts/threads_soak.py --seed 1000 --minutes 5

Prints how many stacks took the slab route, how many fell back to one process, and the seeds of
any stack whose two meshes differ (exit status 1 then).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import contourmesh  # noqa: E402
import soak  # noqa: E402
from contourmesh import parallel  # noqa: E402

KINDS = ["blob", "sheet", "line", "tube", "checker", "staircase", "border", "components", "shells", "single"]


def stack(seed: int) -> np.ndarray:
    """The stack of seed ``seed`` (the same as ``tests/test_parallel.py``'s ``_soak_stack``)."""
    rng = np.random.default_rng(seed)
    parts = []
    for _ in range(int(rng.integers(3, 7))):
        v = soak.make_volume(str(rng.choice(KINDS)), rng)[:, :12, :12]
        parts.append(np.pad(v, ((0, int(rng.integers(0, 2))), (0, 12 - v.shape[1]), (0, 12 - v.shape[2]))))
    return np.pad(np.concatenate(parts), 1)


class _Routes(logging.Handler):
    def __init__(self):
        super().__init__()
        self.msgs: list = []

    def emit(self, record):
        m = record.getMessage()
        if m.startswith("slab route:"):
            self.msgs.append(m)


def _mesh(vol, threads: int):
    os.environ["CONTOURMESH_THREADS"] = str(threads)
    return contourmesh.mesh(vol, progress=False)


def same(m1, m2) -> bool:
    return bool(np.array_equal(m1.vertices, m2.vertices) and np.array_equal(m1.faces, m2.faces)
                and m1.meta == m2.meta and m1.area == m2.area and m1.volume == m2.volume
                and m1.checks() == m2.checks())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--minutes", type=float, default=5.0)
    args = ap.parse_args(argv)
    parallel.MIN_WORK = 0
    routes = _Routes()
    log = logging.getLogger("contourmesh")
    log.setLevel(logging.DEBUG)
    log.addHandler(routes)
    end = time.time() + 60 * args.minutes
    seed, n, slab, bad = args.seed, 0, 0, []
    while time.time() < end:
        vol = stack(seed)
        seed += 1
        if not vol.any():
            continue
        try:
            m1 = _mesh(vol, 1)
        except ValueError:  # a stack the mesher refuses (said so by name): not this soak's subject
            continue
        routes.msgs.clear()
        m2 = _mesh(vol, 2)
        n += 1
        slab += any("slabs on" in m for m in routes.msgs)
        if not same(m1, m2):
            bad.append(seed - 1)
    print(f"seeds {args.seed}..{seed - 1}: {n} stacks, {slab} on the slab route, {n - slab} fell back to one "
          f"process; different meshes: {bad or 'none'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
