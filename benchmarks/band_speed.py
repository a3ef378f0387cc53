"""CPU time of ``refine="band"`` against the paper mode on the real shapes (issue 14: at most 5x).

Each input is rebuilt as ``comparisons/real/real.toml`` builds it (``NAME:REPEAT:SIZE``, e.g.
``fandisk:0:64``; rotated inputs are ``NAME-rot`` with repeats 0-2).  Both modes run as the
comparison runs them (``ours-mlp-wiederhold`` and ``ours-mlp-optimal-band``) after the runner's
warm-up (:func:`contourmesh.compare.runner.warm_up`), in one process, each ``--repeat`` times in
alternating order; the table shows the median CPU seconds (``time.process_time``, so a busy machine
shifts the ratio little), the ratio, the band's area error and the numba kernel signatures that a
row added (0 after the warm-up).  ``--cold`` skips the warm-up: the first row then pays for loading
(or, with a stale disk cache, compiling) the kernels, as the comparison's rows did before.

    python benchmarks/band_speed.py                                  # the default rows below
    python benchmarks/band_speed.py fandisk:0:128 armadillo-rot:1:128 --repeat 3
    python benchmarks/band_speed.py armadillo:0:64 --cold

Exit status 1 when a ratio exceeds ``--limit`` (default 5).  The meshes come from
``$CONTOURMESH_DATA`` (default ``../shared/data`` beside the checkout).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
os.environ.setdefault("CONTOURMESH_DATA", str(ROOT.parent / "shared" / "data"))
SPEC = ROOT / "comparisons" / "real" / "real.toml"
PAPER, BAND = "ours-mlp-wiederhold", "ours-mlp-optimal-band"
DEFAULT_ROWS = ("armadillo:0:64", "armadillo:0:128", "fandisk:0:64", "fandisk:0:128", "armadillo-rot:0:128",
                "3holes-rot:0:128", "quadknot:0:64", "torus:0:64", "lion-rot:0:64",
                # the slowest relative to the paper mode of the 84 rotated rows at 128 and 256 across
                # (band_sigma.py's inputs; a one-run scan of all of them: benchmarks/README.md)
                "torus-rot:2:128", "quadknot-rot:2:128", "bunny-rot:2:256", "torus-rot:2:256",
                "quadknot-rot:0:256", "3holes-rot:1:256")


def build(row: str):
    """``(volume, spacing, origin, true area)`` of ``NAME:REPEAT:SIZE`` as real.toml builds it."""
    sys.path.insert(0, str(SPEC.parent))
    import worst  # comparisons/real/worst.py: the comparison's own inputs

    from contourmesh.compare.inputs import data_dir, load_closed_mesh

    try:
        name, repeat, size = row.split(":")
        repeat, size = int(repeat), int(size)
    except ValueError:
        raise SystemExit(f"a row is NAME:REPEAT:SIZE, e.g. fandisk:0:64; got {row!r}") from None
    inp, rel = worst._input(name, repeat, size)
    v, f = load_closed_mesh(Path(data_dir()) / rel)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    return (*inp.volume(), float(area))


def signatures() -> int:
    """Compiled signatures of every numba kernel of the package loaded so far."""
    import numba.core.registry as reg

    return sum(len(v.signatures) for name, mod in list(sys.modules.items()) if name.startswith("contourmesh")
               for v in vars(mod).values() if isinstance(v, reg.CPUDispatcher))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", nargs="*", default=list(DEFAULT_ROWS), help="NAME:REPEAT:SIZE of real.toml")
    ap.add_argument("--repeat", type=int, default=1, help="runs per mode (median; default 1)")
    ap.add_argument("--cold", action="store_true", help="no warm-up: the first rows load or compile the kernels")
    ap.add_argument("--limit", type=float, default=5.0, help="largest band/paper ratio (default 5)")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    from contourmesh.compare.methods import get_method
    from contourmesh.compare.runner import warm_up

    if not a.cold:
        t0 = time.process_time()
        warm_up([PAPER, BAND])
        print(f"warm-up: {time.process_time() - t0:.1f} s CPU", file=sys.stderr)
    print(f"{'input':22s} {'paper s':>8s} {'band s':>8s} {'ratio':>6s} {'band e %':>9s}  kernels added")
    worst = 0.0
    for row in a.rows:
        vol, sp, org, true_area = build(row)
        times = {PAPER: [], BAND: []}
        added = {PAPER: 0, BAND: 0}
        area = None
        for _ in range(max(1, a.repeat)):
            for name in (PAPER, BAND):
                m = get_method(name)
                s0 = signatures()
                t0 = time.process_time()
                res = m.fn(vol, sp, org, **m.params)
                times[name].append(time.process_time() - t0)
                added[name] += signatures() - s0
                if name == BAND:
                    area = res.area
        tp, tb = statistics.median(times[PAPER]), statistics.median(times[BAND])
        worst = max(worst, tb / tp)
        print(f"{row:22s} {tp:8.3f} {tb:8.3f} {tb / tp:6.2f} {100 * (area / true_area - 1):+9.3f}  "
              f"{added[PAPER]} / {added[BAND]}", flush=True)
    print(f"largest ratio {worst:.2f} (limit {a.limit:g})")
    return 0 if worst <= a.limit else 1


if __name__ == "__main__":
    sys.exit(main())
