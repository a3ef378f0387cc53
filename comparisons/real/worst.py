"""Where a real-shape mesh goes wrong: its faces coloured by signed distance to the true mesh.

    python comparisons/real/worst.py socket-rot 2 --refine band          (writes worst-socket-rot-2-band.png)
    python comparisons/real/worst.py 3holes 0 --refine band --size 128

The input is rebuilt exactly as ``real.toml`` builds it (same seed, rotation and offset).  The
figure has two panels: the mesh seen from above and the slab between two consecutive slice
planes whose area exceeds the true mesh's area there by the most, both with faces coloured by
their centroid's signed distance to the true surface in voxels (red: outside, blue: inside).  It
prints the error, the mesher's ``meta`` and the five slabs with the largest excess (``--short``:
the largest shortfall, for a mesh whose error is negative; written to ``...-short.png``).

    python comparisons/real/worst.py armadillo-rot 2 --refine band --short
The meshes come from the shared data folder (env ``CONTOURMESH_DATA``, default ``../shared/data``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import tomllib

HERE = Path(__file__).resolve().parent


def _input(name: str, repeat: int, size: int):
    from contourmesh.compare.inputs import data_dir, mesh_inputs

    spec = tomllib.loads((HERE / "real.toml").read_text())
    for item in spec["inputs"]:
        if item["name"] == name:
            ins = mesh_inputs(item["mesh"], [size], name=name, repeats=int(item.get("repeats", 1)),
                              seed=int(spec["seed"]), offset=bool(item.get("offset", False)),
                              rotate=bool(item.get("rotate", False)), root=data_dir(),
                              placement=item.get("placement", "per-resolution"))
            for i in ins:
                if i.repeat == repeat:
                    return i, item["mesh"]
            raise SystemExit(f"{name} has no repeat {repeat} (it has {len(ins)})")
    raise SystemExit(f"no input named {name!r} in real.toml")


def main(argv=None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import open3d as o3d
    import trimesh
    from matplotlib.collections import PolyCollection

    import contourmesh
    from contourmesh.compare.inputs import _place, data_dir, load_closed_mesh

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("name", help="an input name of real.toml, e.g. socket-rot")
    ap.add_argument("repeat", type=int, help="the rotation (0-2; 0 for axis-aligned inputs)")
    ap.add_argument("--size", type=int, default=128, help="voxels across (default 128)")
    ap.add_argument("--refine", default=None, help="'band' or none (the paper mode)")
    ap.add_argument("--triangulation", default=None)
    ap.add_argument("--short", action="store_true",
                    help="list and draw the slabs where ours has the least area against the true mesh's "
                         "(default: the most)")
    ap.add_argument("-o", "--out", default=None, help="the PNG (default: worst-NAME-REPEAT-MODE.png here)")
    a = ap.parse_args(argv)

    inp, rel = _input(a.name, a.repeat, a.size)
    vol, sp, org = inp.volume()
    m = contourmesh.mesh(vol, spacing=sp, origin=org, refine=a.refine, triangulation=a.triangulation)
    v, f = load_closed_mesh(Path(data_dir()) / rel)
    v = _place(v, inp.rotation, ())
    h = float(sp[0])
    if inp.offset:
        v = v + np.asarray(inp.offset) * (float((v.max(0) - v.min(0)).max()) / a.size)
    true = trimesh.Trimesh(v, f, process=False)
    e = m.area / true.area - 1
    print(f"{a.name} #{a.repeat} N={a.size} refine={a.refine}: e = {100 * e:+.2f} %")
    print({k: val for k, val in m.meta.items() if k not in ("connectivity", "method", "source")})

    tri = m.vertices[m.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
    d = scene.compute_signed_distance(o3d.core.Tensor(tri.mean(1).astype(np.float32))).numpy() / h
    # area per slab between slice planes, ours against the true mesh's (split finely)
    zs = np.unique(np.round(m.vertices[:, 2] / h, 3)) * h
    planes = zs[np.isclose((zs - org[2]) / h, np.rint((zs - org[2]) / h), atol=1e-3)]
    edges = np.concatenate([[-np.inf], planes, [np.inf]])
    fine = true.subdivide_to_size(h / 4)
    tt = fine.vertices[fine.faces]
    at = 0.5 * np.linalg.norm(np.cross(tt[:, 1] - tt[:, 0], tt[:, 2] - tt[:, 0]), axis=1)
    ours = np.histogram(tri[:, :, 2].mean(1), edges, weights=area)[0]
    ref = np.histogram(tt[:, :, 2].mean(1), edges, weights=at)[0]
    order = np.argsort(ours - ref if a.short else ref - ours)[:5]
    for i in order:
        print(f"  slab {edges[i]:.4g}..{edges[i + 1]:.4g}: ours {ours[i]:.4g}, true {ref[i]:.4g} "
              f"({100 * (ours[i] - ref[i]) / true.area:+.2f} % of the area)")
    worst = order[0]

    fig, axs = plt.subplots(1, 2, figsize=(14, 6.5))
    top = np.argsort(tri[:, :, 2].max(1))  # draw upward so the top faces show
    for ax, sel, title in [
        (axs[0], top, f"{a.name} #{a.repeat}, N={a.size}, refine={a.refine}: e = {100 * e:+.2f} %"),
        (axs[1], np.nonzero((tri[:, :, 2].mean(1) > edges[worst]) & (tri[:, :, 2].mean(1) < edges[worst + 1]))[0],
         f"slab {edges[worst]:.3g}..{edges[worst + 1]:.3g}: "
         f"{100 * (ours[worst] - ref[worst]) / true.area:+.2f} % of the area"),
    ]:
        pc = PolyCollection(tri[sel][:, :, :2], array=d[sel], cmap="coolwarm", clim=(-2, 2),
                            edgecolor="k", linewidth=0.05)
        ax.add_collection(pc)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
    fig.colorbar(pc, ax=axs, label="signed distance to the true surface (voxels)")
    mode = a.refine or "paper"
    out = Path(a.out) if a.out else HERE / f"worst-{a.name}-{a.repeat}-{mode}{'-short' if a.short else ''}.png"
    tmp = out.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=90)
    tmp.replace(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
