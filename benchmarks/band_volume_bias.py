"""Where the per-label volume error of refine="band" on the synthetic cells comes from (issue 17).

For each ellipsoid cell of a small synthetic volume (``contourmesh.cells``), with its exact
cross-section areas ``A(z)`` (the rotated ellipsoid's section at each slice height):

* ``generator``: sum of the exact ``A(z_k)`` over the slices, and the voxel count, against the
  exact volume (is the generator's volume right?);
* ``slices``: the mesh's own cross-section areas at the slice planes (just inside the end slices)
  against ``A(z_k)``, summed (are the refined polygons short?);
* ``between``: the mesh volume against the trapezoid rule over its own cross-sections (the bands
  between slices);
* ``ends``: minus half the end sections (flat caps close the mesh in the end slices' planes, where a
  sum over slices counts half a slice more at each end);
* so ``volume = generator + slices + between + ends`` (in % of the exact volume; the generator's
  term is the exact sections' sum against the exact volume);
* and the same for balls meshed from their digitization (``mesh_shape``), by radius.

    PYTHONPATH=src python benchmarks/band_volume_bias.py [--size 96 --cell 48]
"""

from __future__ import annotations

import argparse

import numpy as np

import contourmesh
from contourmesh.cells import cells_volume, synthetic_cells
from contourmesh.shapes import Ellipsoid


def section_area(V, F, z0):
    """Area of the mesh's cross-section at height z0 (outward-oriented closed mesh)."""
    T = V[F]
    N = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    d = T[:, :, 2] - z0
    total = 0.0
    for t, n, dd in zip(T, N, d):
        if (dd > 0).all() or (dd < 0).all():
            continue
        pts = []
        for i in range(3):
            a, b, da, db = t[i], t[(i + 1) % 3], dd[i], dd[(i + 1) % 3]
            if (da > 0) != (db > 0):
                pts.append(a + da / (da - db) * (b - a))
        if len(pts) != 2:
            continue
        p, q = pts
        if (q - p)[1] * n[0] - (q - p)[0] * n[1] < 0:
            p, q = q, p
        total += 0.5 * (p[0] * q[1] - q[0] * p[1])
    return total


def decompose(m, zk, exact_areas, V):
    am = np.array([section_area(m.vertices, m.faces, z + (1e-7 if i < len(zk) - 1 else -1e-7))
                   for i, z in enumerate(zk)])
    trap = am.sum() - (am[0] + am[-1]) / 2
    return {"volume %": (m.volume - V) / V * 100, "slices %": (am.sum() - np.sum(exact_areas)) / V * 100,
            "between %": (m.volume - trap) / V * 100, "ends %": -(am[0] + am[-1]) / 2 / V * 100}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--cell", type=int, default=48)
    a = ap.parse_args()
    cells = synthetic_cells((a.size,) * 3, cell=a.cell, seed=0)
    vol = cells_volume((a.size,) * 3, cells)
    by = {c.label: c for c in cells if c.kind == "ellipsoid"}
    for lab, m, bb in contourmesh.mesh_labels(vol, refine="band", labels=sorted(by)):
        c = by[lab]
        zk = np.arange(bb[0], bb[1] + 1, dtype=float)
        ex = [c.shape.section_area(z) for z in zk]
        row = {"label": lab, "semi-axes": tuple(round(t, 1) for t in (c.shape.a, c.shape.b, c.shape.c)),
               "generator %": (np.sum(ex) - c.volume) / c.volume * 100,
               "voxels %": (np.count_nonzero(vol == lab) - c.volume) / c.volume * 100}
        row.update(decompose(m, zk, ex, c.volume))
        print({k: (round(float(v), 2) if isinstance(v, (float, np.floating)) else v) for k, v in row.items()},
              flush=True)
    for r in (8.0, 12.0, 16.0, 24.0):
        s = Ellipsoid(r, r, r, center=(0.3, 0.2, 0.1))
        m = contourmesh.mesh_shape(s, refine="band")
        zk = np.unique(m.vertices[:, 2])
        zk = zk[np.isclose(zk, np.round(zk))]
        ex = [s.section_area(z) for z in zk]
        row = {"ball r": r, "area %": (m.area - s.area) / s.area * 100}
        row.update(decompose(m, zk, ex, s.volume))
        print({k: round(float(v), 2) for k, v in row.items()}, flush=True)


if __name__ == "__main__":
    main()
