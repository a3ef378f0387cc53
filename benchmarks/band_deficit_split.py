"""Where refine="band" loses area on the rotated real meshes (issue 14): slope classes and oracle rings.

Two measurements on one input of ``comparisons/real`` (the same seed, rotation and offset):

* ``--split`` (default): the mesh and the true mesh are cut into bins (the slabs between two slice
  planes times square cells of ``--cell`` voxels in x, y; both meshes subdivided to half a voxel
  and binned by face centroid).  Each bin is classed by the true surface's mean ``|n_z|`` there
  (0: a vertical wall, 1: a horizontal cap), and per class the table gives the true area's share
  and our excess over it (in % of the whole true area, and of the class's own area).
* ``--oracle``: the mesher is run again with each refined ring's vertices moved onto the true
  section at the ring's height (nearest point; ``proj``), and then also pushed out by step 5's chord
  rule (``chord``): same joins, same vertex count and spacing, only the places differ.  ``proj``
  measures what the rings' chords and the joins cost with exact vertices; the distance from our
  error to ``chord`` is what the vertex placement (blur, curvature correction, band clamp) costs.

    PYTHONPATH=src python benchmarks/band_deficit_split.py quadknot-rot 0 --size 256
    PYTHONPATH=src python benchmarks/band_deficit_split.py bunny-rot 0 --size 256 --oracle

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

CLASSES = [(0.0, 0.3), (0.3, 0.6), (0.6, 0.8), (0.8, 0.9), (0.9, 0.97), (0.97, 1.01)]


def true_mesh(name: str, repeat: int, size: int):
    """``(input, true trimesh)`` of one input of the comparison."""
    import trimesh
    import worst  # comparisons/real/worst.py: the comparison's own inputs

    from contourmesh.compare.inputs import _place, data_dir, load_closed_mesh

    inp, rel = worst._input(name, repeat, size)
    v, f = load_closed_mesh(Path(data_dir()) / rel)
    v = _place(v, inp.rotation, ())
    if inp.offset:
        v = v + np.asarray(inp.offset) * (float((v.max(0) - v.min(0)).max()) / size)
    return inp, trimesh.Trimesh(v, f, process=False)


def _bins(tm, edges, org, h, cell):
    fm = tm.subdivide_to_size(h / 2)
    tt = fm.vertices[fm.faces]
    cr = np.cross(tt[:, 1] - tt[:, 0], tt[:, 2] - tt[:, 0])
    a = 0.5 * np.linalg.norm(cr, axis=1)
    nz = np.abs(cr[:, 2]) / np.maximum(2 * a, 1e-300)
    c = tt.mean(1)
    s = np.searchsorted(edges, c[:, 2]) - 1
    ix = np.floor((c[:, 0] - org[0]) / (cell * h)).astype(np.int64)
    iy = np.floor((c[:, 1] - org[1]) / (cell * h)).astype(np.int64)
    return (s * 4096 + ix + 1024) * 4096 + iy + 1024, a, nz


def split(m, true, org, h, cell: float = 8.0):
    """Per slope class: ``(lo, hi, true share, our excess / whole true area, excess / class area)``."""
    import trimesh

    zs = np.unique(np.round(m.vertices[:, 2] / h, 3)) * h
    planes = zs[np.isclose((zs - org[2]) / h, np.rint((zs - org[2]) / h), atol=1e-3)]
    edges = np.concatenate([[-np.inf], planes, [np.inf]])
    ko, ao, _ = _bins(trimesh.Trimesh(m.vertices, m.faces, process=False), edges, org, h, cell)
    kt, at, nzt = _bins(true, edges, org, h, cell)
    keys = np.unique(np.concatenate([ko, kt]))
    a_o = np.bincount(np.searchsorted(keys, ko), ao, len(keys))
    a_t = np.bincount(np.searchsorted(keys, kt), at, len(keys))
    nz = np.bincount(np.searchsorted(keys, kt), at * nzt, len(keys)) / np.maximum(a_t, 1e-300)
    tot = true.area
    rows = []
    for lo, hi in CLASSES:
        sel = (nz >= lo) & (nz < hi) & (a_t > 0)
        d = (a_o[sel] - a_t[sel]).sum()
        rows.append((lo, hi, a_t[sel].sum() / tot, d / tot, d / max(a_t[sel].sum(), 1e-300)))
    rows.append((None, None, 0.0, a_o[a_t == 0].sum() / tot, float("nan")))  # ours where the truth has none
    return rows


def _nearest(p, loops):
    """Nearest points of the closed polylines ``loops`` to ``p (n, 2)`` and their distances."""
    a = np.concatenate([lp[:-1] for lp in loops])
    b = np.concatenate([lp[1:] for lp in loops])
    best = np.full(len(p), np.inf)
    q = p.copy()
    for s in range(0, len(a), 2000):
        aa, bb = a[s:s + 2000], b[s:s + 2000]
        d = bb - aa
        l2 = (d ** 2).sum(1)
        t = np.clip(((p[:, None] - aa[None]) * d[None]).sum(2) / np.where(l2 > 0, l2, 1), 0, 1)
        c = aa[None] + t[..., None] * d[None]
        dist = np.hypot(*(p[:, None] - c).transpose(2, 0, 1))
        j = dist.argmin(1)
        dm = dist[np.arange(len(p)), j]
        upd = dm < best
        best[upd] = dm[upd]
        q[upd] = c[upd, j[upd]]
    return q, best


def oracle(vol, sp, org, true, mode: str):
    """The band mesh with every refined ring moved onto the true section (``mode``: ``proj`` or
    ``chord``, see the module docstring); returns ``(mesh, rings moved, rings)``."""
    import contourmesh
    import contourmesh.volumes as VM
    from contourmesh import refine as R

    h = float(sp[0])
    orig = VM.refine_volume_rings
    moved = [0, 0]

    def rings_on_truth(mask, zs, spacing_xy, origin_xy, *a, **kw):
        rings, info = orig(mask, zs, spacing_xy, origin_xy, *a, **kw)
        cache, out = {}, {}
        for key, p in rings.items():
            z = float(zs[key[0]])
            if z not in cache:
                sec = true.section(plane_origin=[0, 0, z], plane_normal=[0, 0, 1])
                cache[z] = [] if sec is None else [np.asarray(d)[:, :2] for d in sec.discrete if len(d) >= 4]
            out[key] = p
            moved[1] += 1
            if not cache[z] or len(p) < 3:
                continue
            q, dist = _nearest(np.asarray(p, dtype=np.float64), cache[z])
            if dist.max() > 2.5 * h:
                continue  # the ring does not follow one true loop
            if mode == "chord":
                q = R._chord_push(q / h) * h
            if R._is_simple(q):
                out[key] = q
                moved[0] += 1
        return out, info

    VM.refine_volume_rings = rings_on_truth
    try:
        m = contourmesh.mesh(vol, spacing=sp, origin=org, refine="band")
    finally:
        VM.refine_volume_rings = orig
    return m, moved[0], moved[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("name", help="an input name of real.toml, e.g. quadknot-rot")
    ap.add_argument("repeat", type=int, help="the rotation (0-2)")
    ap.add_argument("--size", type=int, default=256, help="voxels across (default 256)")
    ap.add_argument("--cell", type=float, default=8.0, help="bin width in x, y (voxels) of the split")
    ap.add_argument("--oracle", action="store_true", help="also mesh with the rings moved onto the true sections")
    a = ap.parse_args(argv)

    import contourmesh

    inp, true = true_mesh(a.name, a.repeat, a.size)
    vol, sp, org = inp.volume()
    h = float(sp[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = contourmesh.mesh(vol, spacing=sp, origin=org, refine="band")
        e = m.area / true.area - 1
        print(f"{a.name} #{a.repeat} N={a.size} refine=band: e = {100 * e:+.3f} %  (sigma "
              f"{m.meta.get('refine_sigma', float('nan')):.2f}, exact joins {m.meta.get('exact_joins')}, "
              f"crack rings {m.meta.get('crack_rings')})")
        print(f"  true |nz|    area share   ours - true: % of all   % of the class   ({a.cell:g}-voxel bins)")
        for lo, hi, share, d, rel in split(m, true, org, h, a.cell):
            if lo is None:
                print(f"  (no truth)   {'':10s}   {100 * d:+8.3f}")
            else:
                print(f"  {lo:.2f}-{hi:.2f}    {100 * share:8.2f} %   {100 * d:+8.3f}   {100 * rel:+14.3f}")
        if a.oracle:
            for mode in ("proj", "chord"):
                mo, k, n = oracle(vol, sp, org, true, mode)
                print(f"  oracle rings ({mode:5s}): e = {100 * (mo.area / true.area - 1):+.3f} %  ({k} of {n} rings moved)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
