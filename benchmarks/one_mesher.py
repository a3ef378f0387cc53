"""Does the public mesher give the general mesher's mesh? (issue 16, "one mesher")

    PYTHONPATH=src python benchmarks/one_mesher.py --seed 11 --n 150

``contourmesh.volumes.volume_to_mesh`` takes the compiled fast path where it can and the general
mesher otherwise.  This meshes random volumes both ways (the second with the fast path switched
off) and counts the meshes that differ in a vertex or a face: twisting elliptic bars (the test
suite's ``_twisting_bars``, bands that twist from slice to slice) and thresholded blurred noise
(blobs with holes and branching).  It prints each difference, then how many volumes took the fast
path and how many differed; the exit status is 1 if any did.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests"))


def general(volumes, vol):
    """The general mesher's mesh (the fast path switched off)."""
    orig = volumes._fast_volume_to_mesh
    volumes._fast_volume_to_mesh = lambda *a, **k: None
    try:
        return volumes.volume_to_mesh(vol)
    finally:
        volumes._fast_volume_to_mesh = orig


def blobs(rng, n):
    for _ in range(n):
        shape = tuple(int(s) for s in rng.integers(12, 28, 3))
        f = ndimage.gaussian_filter(rng.standard_normal(shape), rng.uniform(2, 4))
        vol = f > np.quantile(f, rng.uniform(0.6, 0.85))
        vol[0] = vol[-1] = False
        vol[:, 0] = vol[:, -1] = False
        vol[:, :, 0] = vol[:, :, -1] = False
        yield vol


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=150, help="volumes of each kind")
    args = ap.parse_args(argv)
    from tqdm.auto import tqdm

    from contourmesh import volumes
    from test_fastpath import _twisting_bars

    rng = np.random.default_rng(args.seed)
    n = fast = diff = 0
    for kind, src in (("bars", _twisting_bars(rng, args.n)), ("blobs", blobs(rng, args.n))):
        for vol in tqdm(src, total=args.n, desc=kind):
            if not vol.any():
                continue
            a, b = volumes.volume_to_mesh(vol), general(volumes, vol)
            n += 1
            fast += bool(a.meta.get("fast_path"))
            if not (a.vertices.shape == b.vertices.shape and np.array_equal(a.vertices, b.vertices)
                    and a.faces.shape == b.faces.shape and np.array_equal(a.faces, b.faces)):
                diff += 1
                print(f"differs: {kind} {vol.shape} fast path {bool(a.meta.get('fast_path'))}, band fallbacks "
                      f"{a.meta['band_fallbacks']} vs {b.meta['band_fallbacks']}, crossings repaired "
                      f"{a.meta.get('crossings_repaired')} vs {b.meta.get('crossings_repaired')}")
    print(f"{n} volumes, {fast} through the fast path, {diff} differ from the general mesher")
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
