"""What the blur of ``refine="band"`` costs beyond its curvature correction (issue 14): two checks.

1. **Constant curvature, continuous blur** (``--part curvature``).  The 1/2-level of a ball and of
   a cylinder of radius R blurred by a Gaussian of width sigma (exact formulas: the noncentral
   chi distribution), the level's own curvatures ``k1, k2`` (what step 3 measures there), and the
   residual ``R - r_half - (k1 + k2) sigma^2 / 2`` after step 3's shift, divided by
   ``(k1 + k2)^3 sigma^4``.  Both tend to ``-1/24``: the next term of the shift is
   ``-(k1 + k2)^3 sigma^4 / 24`` (a saddle gets none by symmetry), which moves every surface
   towards its flatter side, so it only removes area.

2. **Creases** (``--part creases``).  Convex polyhedra (icospheres of radius ``--radius`` voxels,
   1-3 subdivisions, randomly rotated, Gauss-voxelized) meshed with ``refine="band"`` under
   ``band_sigma.py``'s rules; the signed error against the polyhedron's own area, beside the
   linear model of a blurred crease: a crease of dihedral angle theta keeps
   ``theta^2 sigma C / (4 pi)`` less area per unit length, ``C = int (1 - T(u)^2) / u^2 du = 1.52``
   with ``T(u) = e^-s (1 + s)``, ``s = u^2 / 2``, the transfer of the blur followed by step 3's
   correction.  The loss grows like ``sigma`` (not ``sigma^4``): a smooth estimator loses it on any
   faceted truth, and the real meshes of ``comparisons/real`` are faceted at 256 voxels across
   (bunny: edges 7.7 voxels, dihedral angles 10 deg median, 27 deg at the 90th percentile).

    python benchmarks/band_blur_bias.py --part curvature
    python benchmarks/band_blur_bias.py --part creases --rules "auto;extrapolate;rho=1"
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT.parent / "src"))


def curvature_part():
    from scipy.optimize import brentq
    from scipy.stats import ncx2, norm

    def ball(r, R, s):  # P(|c + Z| <= R), |c| = r, Z ~ N(0, s^2 I_3)
        return norm.cdf((R - r) / s) - norm.cdf((-R - r) / s) - (s / r) * (norm.pdf((R - r) / s) - norm.pdf((R + r) / s))

    def cylinder(r, R, s):  # the same in the plane
        return ncx2.cdf(R ** 2 / s ** 2, 2, r ** 2 / s ** 2)

    print("continuous blur, sigma = 1: residual after step 3 = R - r_half - (k1 + k2) sigma^2 / 2")
    for kind, f, m in (("ball", ball, 2), ("cylinder", cylinder, 1)):
        for R in (20.0, 10.0, 6.0, 4.0, 3.0):
            rh = brentq(lambda r: f(r, R, 1.0) - 0.5, 1e-6, R)
            ks = m / rh  # k1 + k2 of the level set
            res = R - rh - ks / 2
            print(f"  {kind:<8} R = {R:4.0f} sigma  k1+k2 = {ks:.4f}  residual {res:+.6f}  / (k1+k2)^3 = {res / ks ** 3:+.4f}")
    print("  -1/24 = -0.0417")


def icosphere_volume(sub: int, radius: float):
    import trimesh

    P = trimesh.creation.icosphere(subdivisions=sub, radius=radius)
    P.apply_transform(trimesh.transformations.random_rotation_matrix(np.random.default_rng(sub).random(3)))
    P.apply_translation([0.31, -0.17, 0.23])
    n = int(np.ceil(radius)) + 3
    ax = np.arange(-n, n + 1, dtype=float)
    zz, yy, xx = np.meshgrid(ax, ax, ax, indexing="ij")
    c = np.stack([xx, yy, zz], -1).reshape(-1, 3)
    inside = np.ones(len(c), bool)
    for fn, p0 in zip(P.face_normals, P.triangles[:, 0]):  # convex: inside every face plane
        inside &= (c - p0) @ fn <= 0
    return P, inside.reshape(zz.shape), (-float(n),) * 3


def crease_constant() -> float:
    from scipy.integrate import quad

    def t(u):
        s = u * u / 2
        return np.exp(-s) * (1 + s)

    return 2 * quad(lambda u: (1 - t(u) ** 2) / u ** 2, 1e-9, 80, limit=400)[0]


def creases_part(rules, radius: float):
    import band_sigma

    C = crease_constant()
    print(f"icospheres of radius {radius:g} voxels; crease model C = {C:.3f}")
    for sub in (1, 2, 3):
        P, vol, org = icosphere_volume(sub, radius)
        th = P.face_adjacency_angles
        e = P.face_adjacency_edges
        el = np.linalg.norm(P.vertices[e[:, 0]] - P.vertices[e[:, 1]], axis=1)
        cells = []
        for rule in rules:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = band_sigma.mesh_with(rule, vol, (1.0, 1.0, 1.0), org)
            s = m.meta["refine_sigma"]
            model = -(th ** 2 * el).sum() * s * C / (4 * np.pi) / P.area * 100
            cells.append(f"{rule} {100 * (m.area / P.area - 1):+.3f} % (sigma {s:.2f}, model {model:+.3f} %)")
        print(f"  {len(P.faces):5d} faces, edge {el.mean():4.1f} vox, dihedral {np.degrees(th.mean()):4.1f} deg: "
              + "; ".join(cells), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=["curvature", "creases", "both"], default="both")
    ap.add_argument("--rules", default="auto;extrapolate", help="band_sigma.py's rules, separated by ';'")
    ap.add_argument("--radius", type=float, default=60.0)
    a = ap.parse_args(argv)
    if a.part in ("curvature", "both"):
        curvature_part()
    if a.part in ("creases", "both"):
        creases_part([r.strip() for r in a.rules.split(";") if r.strip()], a.radius)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
