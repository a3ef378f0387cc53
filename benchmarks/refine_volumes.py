"""refine="band" on volumes with several contours per slice (issue 14 item 3): area errors.

For a torus lying flat (R = 2r, tube 0.8 r), two balls of radius r side by side, and a fork (a
trunk capsule of radius r splitting into two), all at sub-voxel offsets, prints the relative area
error of the paper's mesh (default mode), of the same with ``triangulation="optimal"`` (the band
triangulation ``refine="band"`` uses by default) and of ``refine="band"``.  The torus and the balls have
analytic areas; the fork's reference is marching cubes on its exact signed distance at 1/64 of
its radius (area ~ r^2, computed once).  With ``--samples`` also the shared DGtal bunnies against
marching cubes after a Gaussian blur of 1 voxel (an independent estimate, about +0.2 % on balls).

    python benchmarks/refine_volumes.py                      # r = 10, 20, 40
    python benchmarks/refine_volumes.py --radii 10,20 --samples bunny-64,bunny-128
    python benchmarks/refine_volumes.py --radii "" --meshes libigl-tutorial-data/bunny.off --n 64,128

``--meshes`` voxelizes closed sample meshes (as ``comparisons/voxelized/run.py`` does) and compares
with their true area.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
DATA = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))
OFF = np.array([0.31, -0.17, 0.23])


def _grid(lo, hi, step=1.0):
    """Grid points (x, y, z) covering [lo, hi] with OFF as a sub-voxel shift; returns P (nz, ny, nx, 3)."""
    ax = [np.arange(np.floor(lo[i]) - 2, np.ceil(hi[i]) + 3, step) + OFF[i] * (step == 1.0) for i in range(3)]
    zz, yy, xx = np.meshgrid(ax[2], ax[1], ax[0], indexing="ij")
    return np.stack([xx, yy, zz], -1)


def _capsule_sdf(P, a, b, rad):
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    t = np.clip(((P - a) @ d) / (d @ d), 0, 1)
    return np.linalg.norm(P - (a + t[..., None] * d), axis=-1) - rad


FORK = [((0, 0, 0), (0, 0, 2), 1.0), ((0, 0, 2), (-1.5, 0, 4), 1.0), ((0, 0, 2), (1.5, 0, 4), 1.0)]


def fork_sdf(P, r):
    return np.min([_capsule_sdf(P, np.multiply(a, r), np.multiply(b, r), rad * r) for a, b, rad in FORK], axis=0)


def fork_area_unit(n: int = 64) -> float:
    """The fork's area at r = 1: marching cubes on its signed distance, grid step 1/n."""
    from skimage import measure

    P = _grid(np.array([-3.0, -1.5, -1.5]) * n, np.array([3.0, 1.5, 5.5]) * n, 1.0) / n
    f = fork_sdf(P, 1.0)
    v, faces, _, _ = measure.marching_cubes(f, 0.0, spacing=(1.0 / n,) * 3)
    return float(measure.mesh_surface_area(v, faces))


def flat_torus(r: int):
    """A torus lying flat (R = 2r, tube 0.8 r): ``(mask, origin of voxel [0,0,0], area)``."""
    from contourmesh.digitize import gauss_volume
    from contourmesh.shapes import Torus

    t = Torus(2 * r, 0.8 * r, center=tuple(OFF))
    vol, org = gauss_volume(t)
    return vol, org, t.area


def two_balls(r: int):
    """Two balls of radius r, 2.5 r apart along x: ``(mask, origin, area)``."""
    from contourmesh.digitize import gauss_volume
    from contourmesh.shapes import Sphere

    a, b = Sphere(r, center=tuple(OFF)), Sphere(r, center=tuple(OFF + [2.5 * r, 0, 0]))
    va, oa = gauss_volume(a)
    vb, ob = gauss_volume(b)
    n = int(round(ob[0] - oa[0]))
    two = np.zeros((va.shape[0], va.shape[1], n + vb.shape[2]), bool)
    two[:, :, : va.shape[2]] |= va
    two[:, :, n:] |= vb
    return two, oa, 2 * a.area


def fork(r: int):
    """A trunk capsule of radius r splitting into two slanted ones (a Y): ``(mask, origin)``."""
    P = _grid(np.array([-2.6, -1.1, -1.1]) * r, np.array([2.6, 1.1, 5.1]) * r)
    return fork_sdf(P, r) < 0, tuple(P[0, 0, 0])


def volumes(r: int):
    """(name, mask, origin, reference area) of the three shapes at size r."""
    yield "torus", *flat_torus(r)
    yield "two balls", *two_balls(r)
    yield "fork", *fork(r), FORK_UNIT * r * r


def run(vol, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0)):
    import contourmesh

    out = {}
    for name, kw in [("paper", {}), ("optimal", {"triangulation": "optimal"}), ("band", {"refine": "band"})]:
        t = time.perf_counter()
        m = contourmesh.mesh(vol, origin=origin, spacing=spacing, **kw)
        out[name] = (m, time.perf_counter() - t)
    return out


def row(name, n, res, ref, note=""):
    (mp, tp), (mo, _), (mb, tb) = res["paper"], res["optimal"], res["band"]
    chk = mb.checks()
    print(f"{name:10s} {n:>4} {mp.area / ref - 1:+9.4%} {mo.area / ref - 1:+9.4%} {mb.area / ref - 1:+9.4%} "
          f"{tp:7.1f}s {tb:6.1f}s  {note}"
          f"ok={chk['ok']} genus={chk['genus']:g} route={mb.meta.get('route')} "
          f"exact_joins={mb.meta.get('exact_joins')} kept_seeds={mb.meta.get('refine_kept_seeds')}", flush=True)


def main(argv=None):
    global FORK_UNIT
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--radii", default="10,20,40")
    ap.add_argument("--samples", default="", help="comma-separated: bunny-64,bunny-128")
    ap.add_argument("--meshes", default="", help="comma-separated paths under DATA/meshes")
    ap.add_argument("--n", default="64,128", help="voxels across the largest extent, for --meshes")
    a = ap.parse_args(argv)
    FORK_UNIT = fork_area_unit()
    print(f"fork reference area at r=1: {FORK_UNIT:.5f}")
    print(f"{'shape':10s} {'r':>4s} {'paper':>9s} {'optimal':>9s} {'band':>9s} {'t paper':>8s} {'t band':>7s}  band mesh")
    for r in [int(x) for x in a.radii.split(",") if x]:
        for name, vol, org, ref in volumes(r):
            row(name, r, run(vol, org), ref)
    for name in [s for s in a.samples.split(",") if s]:
        from contourmesh.compare.methods import marching_cubes

        d = np.load(DATA / "volumes" / "dgtal" / f"{name}.npz")
        vol = np.pad(d["mask"], 1)
        ref = marching_cubes(vol, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), blur=1.0).mesh.area
        row(name, "", run(vol), ref, f"vs mc-lewiner-blur1 ({ref:.1f}); ")
    for name in [s for s in a.meshes.split(",") if s]:
        import trimesh

        from contourmesh.compare.inputs import load_closed_mesh
        from contourmesh.voxelize import voxelize_mesh

        tm = trimesh.Trimesh(*load_closed_mesh(DATA / "meshes" / name), process=False)
        for n in [int(x) for x in a.n.split(",")]:
            vol, spacing, origin = voxelize_mesh(tm.vertices, tm.faces, n)
            row(Path(name).name[:10], n, run(vol, origin, spacing), tm.area, "vs the mesh's area; ")


if __name__ == "__main__":
    main()
