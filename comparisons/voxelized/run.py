"""Voxelize closed meshes from the shared sample data at 64 and 128 voxels across, mesh them with
contourmesh (MLP polygons, the paper's triangulation) and report the areas against the true mesh
areas, with the topology checks.

    python comparisons/voxelized/run.py [DATA_DIR]     (default: $CONTOURMESH_DATA or ../shared/data)

Writes ``results.csv`` and ``results.md`` next to this file.
"""

from __future__ import annotations

import argparse
import csv
import io
import os
import sys
import time
from pathlib import Path

import contourmesh
from contourmesh.compare.inputs import load_closed_mesh
from contourmesh.meshes import atomic_write
from contourmesh.volumes import voxel_topology
from contourmesh.voxelize import voxelize_mesh

MESHES = [
    "trimesh-models/torus.STL", "libigl-tutorial-data/fertility.off", "libigl-tutorial-data/3holes.off",
    "cgogn/socket.off", "cgogn/aneurysm_3D.off", "libigl-tutorial-data/bunny.off",
    "common-3d-test-models/spot.obj", "common-3d-test-models/rocker-arm.obj", "trimesh-models/round.stl",
    "libigl-tutorial-data/decimated-knight.off", "trimesh-models/quadknot.obj", "libigl-tutorial-data/elephant.obj",
]
RESOLUTIONS = (64, 128)
HERE = Path(__file__).resolve().parent


def data_root(path=None) -> Path:
    if path:
        return Path(path)
    return Path(os.environ.get("CONTOURMESH_DATA", HERE.parents[2] / "shared" / "data"))


def run_one(path: Path, n: int, polygon="mlp", triangulation="wiederhold") -> dict:
    import trimesh

    tm = trimesh.Trimesh(*load_closed_mesh(path), process=False)
    vol, spacing, origin = voxelize_mesh(tm.vertices, tm.faces, n)
    t = time.perf_counter()
    m = contourmesh.mesh(vol, spacing=spacing, origin=origin, polygon=polygon, triangulation=triangulation)
    seconds = time.perf_counter() - t
    chk = m.checks()
    ref = voxel_topology(vol)
    mesh_genus = int(round((2 * tm.body_count - tm.euler_number) / 2))
    return {
        "mesh": path.name, "n": n, "polygon": polygon, "triangulation": triangulation,
        "area_true": float(tm.area), "area": m.area, "e": m.area / tm.area - 1, "P": m.P,
        "faces": len(m.faces), "watertight": chk["watertight"], "winding_consistent": chk["winding_consistent"],
        "genus": chk["genus"], "genus_voxels": ref["genus"], "genus_mesh": mesh_genus,
        "components": chk["components"], "surfaces_voxels": ref["surfaces"],
        "exact_joins": m.meta["exact_joins"], "seconds": seconds,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("data", nargs="?", default=None,
                    help="the shared data folder (default: $CONTOURMESH_DATA or ../shared/data)")
    root = data_root(ap.parse_args(argv).data) / "meshes"
    if not root.is_dir():
        print(f"no sample meshes at {root}; pass the data folder or set CONTOURMESH_DATA", file=sys.stderr)
        return 2
    rows = []
    for name in MESHES:
        for n in RESOLUTIONS:
            rows.append(run_one(root / name, n))
            r = rows[-1]
            print(f"{r['mesh']:>22} n={n:<4} e={r['e']:+.4f} genus {r['genus']:.0f}/{r['genus_voxels']} "
                  f"({r['seconds']:.2f} s)", flush=True)
    cols = list(rows[0])
    buf = io.StringIO()
    w = csv.DictWriter(buf, cols, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.8g}" if isinstance(v, float) else v) for k, v in r.items()})
    atomic_write(HERE / "results.csv", buf.getvalue().encode())
    md = ["# Voxelized sample meshes: contourmesh area against the true mesh area", "",
          "MLP polygons, the paper's triangulation; each mesh voxelized (Gauss) at n voxels across its largest "
          "extent. genus: our mesh / the voxel object's (6-connected) / the original mesh's. Regenerate with "
          "`python comparisons/voxelized/run.py`.", "",
          "| mesh | n | area_true | area | e | P | genus (ours / voxels / mesh) | surfaces | exact joins | s |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['mesh']} | {r['n']} | {r['area_true']:.6g} | {r['area']:.6g} | {r['e']:+.4f} | {r['P']} | "
                  f"{r['genus']:.0f} / {r['genus_voxels']} / {r['genus_mesh']} | {r['components']} | "
                  f"{r['exact_joins']} | {r['seconds']:.2f} |")
    atomic_write(HERE / "results.md", ("\n".join(md) + "\n").encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
