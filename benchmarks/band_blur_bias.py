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
   ``theta^2 sigma C / (4 pi)`` less area per unit length, ``C = int (1 - T(u)^2) / u^2 du = 1.53``
   with ``T(u) = e^-s (1 + s)``, ``s = u^2 / 2``, the transfer of the blur followed by step 3's
   correction.  The loss grows like ``sigma`` (not ``sigma^4``): a smooth estimator loses it on any
   faceted truth, and the real meshes of ``comparisons/real`` are faceted at 256 voxels across
   (bunny: edges 7.7 voxels, dihedral angles 10 deg median, 27 deg at the 90th percentile).

    python benchmarks/band_blur_bias.py --part curvature
    python benchmarks/band_blur_bias.py --part creases --rules "auto;extrapolate;rho=1"
    python benchmarks/band_blur_bias.py --part meshes --size 256 --meshes bunny-rot,spot-rot

``--part meshes`` sums the crease model over a shared mesh's edges (each edge a sawtooth of slopes
whose period is its two faces' mean width), beside the band's measured error at rotation 0: an
estimate only where the faces are a few blur widths across, and wrong on fine tessellations of
smooth surfaces (their dihedral angles are curvature, not creases).
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


def meshes_part(size: int, names):
    """The crease model summed over a shared mesh's edges, beside the band's measured error."""
    import band_sigma
    import trimesh

    sys.path.insert(0, str(ROOT.parent / "comparisons" / "real"))
    import worst

    from contourmesh.compare.inputs import data_dir, load_closed_mesh

    n = np.arange(1, 200)[None, :]

    def t(u):
        s = u * u / 2
        return np.exp(-s) * (1 + s)

    print(f"N = {size}, rotation 0: measured e, and the sawtooth form of the crease model (%)")
    for name in names:
        vol, sp, org, area = band_sigma.load(name, 0, size)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = band_sigma.mesh_with("auto", vol, sp, org)
        sigma = m.meta["refine_sigma"]
        _, rel = worst._input(name, 0, size)
        v, f = load_closed_mesh(Path(data_dir()) / rel)
        tm = trimesh.Trimesh(v, f, process=True)
        h = float((v.max(0) - v.min(0)).max()) / size
        th = tm.face_adjacency_angles
        e = tm.face_adjacency_edges
        el = np.linalg.norm(tm.vertices[e[:, 0]] - tm.vertices[e[:, 1]], axis=1)
        width = tm.area_faces[tm.face_adjacency].sum(1) / el / h  # the two faces' mean width, voxels
        # a sawtooth of slopes +-theta/2 with period `width`: harmonics 2 pi n / width, power 6/(pi n)^2
        keep = ((1 - t(2 * np.pi * n * sigma / width[:, None]) ** 2) / n ** 2).sum(1)
        model = -(el * width * h * th ** 2 / 24 * 6 / np.pi ** 2 * keep).sum() / tm.area * 100
        print(f"  {name:<18} sigma {sigma:.2f}  e {100 * (m.area / area - 1):+.3f}  model {model:+.3f}"
              f"  (faces {np.median(width):.1f} voxels wide, dihedral {np.degrees(np.median(th)):.1f} deg median)",
              flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=["curvature", "creases", "meshes", "both"], default="both")
    ap.add_argument("--size", type=int, default=256, help="voxels across (--part meshes)")
    ap.add_argument("--meshes", default="bunny-rot,spot-rot,quadknot-rot,elephant-rot", help="--part meshes")
    ap.add_argument("--rules", default="auto;extrapolate", help="band_sigma.py's rules, separated by ';'")
    ap.add_argument("--radius", type=float, default=60.0)
    a = ap.parse_args(argv)
    if a.part in ("curvature", "both"):
        curvature_part()
    if a.part in ("creases", "both"):
        creases_part([r.strip() for r in a.rules.split(";") if r.strip()], a.radius)
    if a.part == "meshes":
        meshes_part(a.size, a.meshes.split(","))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
