"""The blur width of ``refine="band"`` on the rotated real meshes of ``comparisons/real`` (issue 14).

The same inputs as the real-shapes comparison (``comparisons/real/real.toml``: each mesh rotated
at 3 seeded random rotations, Gauss-voxelized at N across), meshed with ``refine="band"`` under
several rules for the Gaussian width ``sigma`` and for the two-scale step, in one process.
Prints each mesh's signed area error per rule, then per rule the median and largest |e|.

Rules (``--rules``, separated by ``;``):

* ``auto``: the default (:func:`contourmesh.refine.auto_sigma`, ``clip(0.8 R^(1/3), 2, 3.5)``);
* ``sigma=LO-HI``: the same rule clipped to ``[LO, HI]`` (``sigma=2-2`` is a fixed width of 2);
* ``extrapolate``: the two-scale step's extrapolated place at every vertex, not only where the
  two widths disagree (``FINE_TOLERANCE`` below zero);
* ``tol=LO/HI``: the two-scale step's disagreement bounds (``FINE_TOLERANCE``, voxels);
* ``ratio=R``: the fine width's share of the wide one (``FINE_RATIO``);
* ``rho=X``: the extrapolation gain where the widths disagree (``FINE_RHO``; default the
  Richardson gain ``r^4 / (1 - r^4)``, 0.32);
* ``nocrease`` / ``crease``: step 3b's one gain everywhere (the default before session 19) / a gain
  per vertex from the two places' curvatures (``FINE_CREASE``, the default), with ``cwin=W``
  (``CREASE_WINDOW``), ``kmin=B`` / ``kfade=LO/HI`` (``CREASE_MIN_BEND``: a floor / a fade-in of the
  bend), ``qmax=E`` (``CREASE_MAX_ORDER``), ``bend=B`` (``CREASE_MAX_BEND``), ``ctol=T`` (``CREASE_TOLERANCE``),
  ``wider`` / ``wider=LO/HI`` / ``nowider`` (``CREASE_WIDER``: a third width ``sigma / r`` tells
  a crease from a smooth wave), ``planar`` / ``noplanar`` (``CREASE_PLANAR``: the ratio from the sections'
  curvatures), ``qmin=Q`` (``CREASE_MIN_RATIO``), ``noise=Z`` (``CREASE_NOISE``: only the curvature
  excess beyond Z times the fine level's lattice noise counts) and ``ffade=LO/HI``
  (``CREASE_MIN_FINE``: no crease shares where the fine width is below LO voxels, all from HI);
* ``density=D``: ring vertices per seed vertex of the mode (``RING_DENSITY``);
* ``cubic=C``: a third-order term ``C (k1 + k2)^3 sigma^4`` in the curvature shift
  (``SHIFT_CUBIC``; ``-0.0416667`` = -1/24, the exact term for balls and cylinders).

Settings combine with ``+`` (``sigma=2-2.5+rho=1``).  ``--balls 20,40,80`` meshes balls (outer
Jordan stacks at the convergence comparison's centres) under the same rules instead, and prints
the median signed and absolute errors per radius and the fitted order.

    python benchmarks/band_sigma.py --size 256
    python benchmarks/band_sigma.py --size 128 --meshes bunny-rot,torus-rot --rules "auto;sigma=2-2"
    python benchmarks/band_sigma.py --size 256 --rules auto --refine band2
    python benchmarks/band_sigma.py --balls 20,40,80,160 --rules "auto;sigma=2-2"

Voxelized inputs are kept in ``comparisons/real/cache/volumes`` (not committed).
The data folder is ``$CONTOURMESH_DATA`` (default ``../shared/data`` beside the checkout).
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "comparisons" / "real"))
os.environ.setdefault("CONTOURMESH_DATA", str(ROOT.parent / "shared" / "data"))

MESHES = ["armadillo-rot", "lion-rot", "rocker-arm-rot", "fertility-rot", "bunny-rot", "spot-rot", "3holes-rot",
          "quadknot-rot", "socket-rot", "aneurysm-rot", "elephant-rot", "cheburashka-rot", "fandisk-rot",
          "torus-rot"]


def load(name: str, repeat: int, size: int):
    """``(volume, spacing, origin, true area)`` of one input of the comparison, cached."""
    import trimesh
    import worst  # comparisons/real/worst.py: the comparison's own inputs

    from contourmesh.compare.inputs import _place, data_dir, load_closed_mesh

    cache = ROOT / "comparisons" / "real" / "cache" / "volumes" / f"{name}-{repeat}-{size}.npz"
    if cache.exists():
        z = np.load(cache, allow_pickle=False)
        return z["vol"], tuple(z["sp"]), tuple(z["org"]), float(z["area"])
    inp, rel = worst._input(name, repeat, size)
    vol, sp, org = inp.volume()
    v, f = load_closed_mesh(Path(data_dir()) / rel)
    v = _place(v, inp.rotation, ())
    if inp.offset:
        v = v + np.asarray(inp.offset) * (float((v.max(0) - v.min(0)).max()) / size)
    area = trimesh.Trimesh(v, f, process=False).area
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, vol=vol, sp=sp, org=org, area=area)
    tmp.replace(cache)
    return vol, sp, org, area


def _clipped(rule, lo: float, hi: float):
    """``rule`` (:func:`contourmesh.refine._auto_sigma_of`) clipped to ``[lo, hi]`` whatever bounds
    its caller passes (the stack route's :func:`~contourmesh.refine.auto_sigma` passes its own)."""
    def clipped(*args, **kw):
        kw.update(lo=lo, hi=hi)
        return rule(*args, **kw)
    return clipped


#: Rule parts that set a refine setting to a fixed value (``extrapolate``: always the fine place).
_FLAGS = {"extrapolate": ("FINE_TOLERANCE", (-1.0, -0.999)), "adaptive": ("FINE_ADAPTIVE", True),
          "crease": ("FINE_CREASE", True), "nocrease": ("FINE_CREASE", False), "wider": ("CREASE_WIDER", True),
          "nowider": ("CREASE_WIDER", None), "planar": ("CREASE_PLANAR", True), "noplanar": ("CREASE_PLANAR", False)}
#: ``KEY=x`` rule parts: the refine setting that takes the number x.
_NUMBERS = {"ratio": "FINE_RATIO", "rho": "FINE_RHO", "adaptive": "FINE_ADAPTIVE", "cubic": "SHIFT_CUBIC",
            "ctol": "CREASE_TOLERANCE", "bend": "CREASE_MAX_BEND", "kmin": "CREASE_MIN_BEND",
            "cwin": "CREASE_WINDOW", "planar": "CREASE_PLANAR", "qmin": "CREASE_MIN_RATIO",
            "qmax": "CREASE_MAX_ORDER", "noise": "CREASE_NOISE"}
#: ``KEY=a/b`` rule parts: the refine setting that takes the pair (a, b).
_PAIRS = {"tol": "FINE_TOLERANCE", "wider": "CREASE_WIDER", "kfade": "CREASE_MIN_BEND", "ffade": "CREASE_MIN_FINE"}


def mesh_with(rule: str, vol, sp=None, org=None, mode: str = "band"):
    """``contourmesh.mesh(vol, refine=mode)`` under one rule (module settings restored after).

    A rule is one or more settings joined by ``+`` (``auto`` alone: the defaults)."""
    import contourmesh
    from contourmesh import refine

    names = ("_auto_sigma_of", "FINE_TOLERANCE", "FINE_RATIO", "FINE_RHO", "SHIFT_CUBIC", "FINE_ADAPTIVE",
             "FINE_CREASE", "CREASE_WINDOW", "CREASE_MIN_BEND", "CREASE_MAX_BEND", "CREASE_TOLERANCE",
             "CREASE_WIDER", "CREASE_PLANAR", "CREASE_MIN_RATIO", "CREASE_MAX_ORDER", "CREASE_NOISE", "CREASE_MIN_FINE")
    saved = {n: getattr(refine, n) for n in names}
    saved_density = dict(refine.RING_DENSITY)
    try:
        for part in rule.split("+"):
            key, _, val = part.partition("=")
            if part == "auto":
                continue
            if part in _FLAGS:  # a setting named alone
                setattr(refine, *_FLAGS[part])
            elif key in _NUMBERS:  # NAME=x: one number
                setattr(refine, _NUMBERS[key], float(val))
            elif key in _PAIRS:  # NAME=a/b: two numbers
                setattr(refine, _PAIRS[key], tuple(float(x) for x in val.split("/")))
            elif key == "sigma":
                lo, hi = (float(x) for x in val.split("-"))
                refine._auto_sigma_of = _clipped(saved["_auto_sigma_of"], lo, hi)
            elif key == "density":
                refine.RING_DENSITY[mode] = float(val)
            else:
                raise SystemExit(f"unknown rule {rule!r}")
        if sp is None:  # a contour stack
            return contourmesh.mesh(vol, refine=mode)
        return contourmesh.mesh(vol, spacing=sp, origin=org, refine=mode)
    finally:
        for n, v in saved.items():
            setattr(refine, n, v)
        refine.RING_DENSITY.update(saved_density)


def balls(rules, radii, n_centres: int = 5, mode: str = "band"):
    """Signed area errors (%) of balls (outer Jordan stacks) at the convergence comparison's centres
    (``comparisons/convergence/run.py``'s first ``sphere-oj`` centres), per rule and radius."""
    from contourmesh.digitize import outer_jordan_stack
    from contourmesh.shapes import Sphere

    centres = np.random.default_rng(2024).uniform(-0.5, 0.5, (5, 3))[:n_centres]
    out = {r: {} for r in rules}
    for rad in radii:
        for c in centres:
            s = Sphere(rad, center=tuple(c))
            st = outer_jordan_stack(s)
            for r in rules:
                m = mesh_with(r, st, mode=mode)
                out[r].setdefault(rad, []).append(100.0 * (m.area / s.area - 1.0))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256, help="voxels across (64, 128 or 256)")
    ap.add_argument("--meshes", default=",".join(MESHES), help="comma-separated input names of real.toml")
    ap.add_argument("--repeats", default="0,1,2", help="the rotations")
    ap.add_argument("--rules", default="auto;sigma=2-2;sigma=2-2.5;extrapolate")
    ap.add_argument("--refine", default="band", choices=["band", "band2"], help="the refinement mode")
    ap.add_argument("--balls", default="", help="ball radii (e.g. 20,40,80,160): balls instead of meshes")
    ap.add_argument("--centres", type=int, default=5, help="ball centres per radius (at most 5)")
    a = ap.parse_args(argv)
    rules = [r.strip() for r in a.rules.split(";") if r.strip()]
    if a.balls:
        radii = [float(x) for x in a.balls.split(",")]
        res = balls(rules, radii, a.centres, a.refine)
        print(f"balls, {a.centres} centres: median signed e (%) / median |e| (%) per radius; fitted order of median |e|")
        for r in rules:
            med = [float(np.median(np.abs(res[r][rad]))) for rad in radii]
            cells = " ".join(f"r={rad:g}: {np.median(res[r][rad]):+.4f} / {m:.4f}" for rad, m in zip(radii, med))
            order = -np.polyfit(np.log(radii), np.log(med), 1)[0] if len(radii) > 1 else float("nan")
            print(f"  {r:<24} {cells}  order {order:.2f}")
        return 0
    errors = {r: [] for r in rules}
    from tqdm.auto import tqdm

    cases = [(n, int(r)) for n in a.meshes.split(",") for r in a.repeats.split(",")]
    print(f"{'input':<20} " + " ".join(f"{r:>14}" for r in rules))
    for name, rep in tqdm(cases, desc="meshes", leave=False):
        vol, sp, org, area = load(name, rep, a.size)
        row = []
        for r in rules:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = mesh_with(r, vol, sp, org, a.refine)
            e = 100.0 * (m.area / area - 1.0)
            errors[r].append(e)
            row.append(f"{e:+8.3f} s{m.meta['refine_sigma']:.1f}")
        tqdm.write(f"{name + '#' + str(rep):<20} " + " ".join(f"{x:>14}" for x in row))
    print(f"\nN = {a.size}, {len(cases)} meshes: median |e| / largest |e| (%)")
    for r in rules:
        e = np.abs(errors[r])
        print(f"  {r:<14} {np.median(e):.3f} / {e.max():.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
