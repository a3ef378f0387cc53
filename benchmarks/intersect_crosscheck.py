"""Cross-check of contourmesh.intersect against Open3D and PyMeshLab on random meshes (issue 13).

For every mesh, contourmesh's intersecting face pairs are compared with

* Open3D's ``TriangleMesh.get_self_intersecting_triangles`` (pairs; it skips every pair of faces
  with a common vertex index), and
* PyMeshLab's ``compute_selection_by_self_intersections_per_face`` (selected faces).

A crossing a peer finds that we miss is a failure, unless the exact reference says the two faces
have no point in common (a false positive of the peer's float arithmetic; counted separately).  What we find beyond a peer is classified:
pairs with a common vertex index (Open3D never tests them), and the rest, whose common part is
computed exactly (rationals, the reference of tests/test_intersect.py): a single point (a vertex
on the other face, or edges crossing at a point: a contact the peers' tests report as apart), or
more (listed as examples).

The meshes: contourmesh's meshes of random volumes of five kinds (smoothed noise blobs, sparse
voxels with diagonal contacts, boxes touching the borders, hollow shells, one-voxel lines and
sheets; default mode and ``polygon="none"``), jittered icospheres (folds next to shared vertices)
and random triangle soups.

    python benchmarks/intersect_crosscheck.py                # 1,000 meshes
    python benchmarks/intersect_crosscheck.py --n 100 --seed 5 --json out.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests"))

VOLUME_KINDS = ("blob", "sparse", "border", "shell", "linesheet")


def random_volume(kind: str, rng: np.random.Generator) -> np.ndarray:
    """A small random boolean volume of one of the issue's five kinds (never empty)."""
    from scipy import ndimage

    shape = tuple(int(s) for s in rng.integers(4, 24, 3))
    if kind == "blob":
        v = ndimage.gaussian_filter(rng.random(shape), float(rng.uniform(0.7, 2.0))) > rng.uniform(0.48, 0.53)
    elif kind == "sparse":  # isolated voxels touching along edges and corners
        v = rng.random(shape) < rng.uniform(0.05, 0.3)
    elif kind == "border":  # boxes, some touching the array's border
        v = np.zeros(shape, bool)
        for _ in range(int(rng.integers(1, 6))):
            a = [int(rng.integers(0, s)) for s in shape]
            b = [min(s, x + int(rng.integers(1, max(2, s // 2)))) for s, x in zip(shape, a)]
            if rng.random() < 0.5:
                a[int(rng.integers(0, 3))] = 0
            v[a[0]:b[0], a[1]:b[1], a[2]:b[2]] = True
    elif kind == "shell":  # hollow boxes, maybe holed
        v = np.zeros(shape, bool)
        lo = [int(rng.integers(0, max(1, s - 3))) for s in shape]
        hi = [int(rng.integers(x + 3, s + 1)) for s, x in zip(shape, lo)]
        v[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = True
        v[lo[0] + 1:hi[0] - 1, lo[1] + 1:hi[1] - 1, lo[2] + 1:hi[2] - 1] = False
        if rng.random() < 0.5:
            v &= rng.random(shape) > 0.1
    else:  # one-voxel lines (random walks with diagonal steps) and sheets
        v = np.zeros(shape, bool)
        if rng.random() < 0.5:
            p = np.array([rng.integers(0, s) for s in shape])
            for _ in range(int(rng.integers(5, 60))):
                v[tuple(p)] = True
                p = np.clip(p + rng.integers(-1, 2, 3), 0, np.array(shape) - 1)
        else:
            ax = int(rng.integers(0, 3))
            idx = [slice(None)] * 3
            idx[ax] = int(rng.integers(0, shape[ax]))
            v[tuple(idx)] = rng.random(v[tuple(idx)].shape) > 0.3
    if not v.any():
        v[tuple(s // 2 for s in shape)] = True
    return v


def random_mesh(i: int, rng: np.random.Generator):
    """(label, vertices, faces) of the i-th mesh."""
    import trimesh

    import contourmesh

    r = i % 10
    if r < 8:
        kind = VOLUME_KINDS[r % 5]
        polygon = "none" if r >= 5 else None
        v = random_volume(kind, rng)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = contourmesh.mesh(v, polygon=polygon) if polygon else contourmesh.mesh(v)
        return f"volume:{kind}:{polygon or 'default'}", m.vertices, m.faces
    if r == 8:
        s = trimesh.creation.icosphere(int(rng.integers(1, 4)))
        return "jittered-sphere", s.vertices + rng.normal(0, float(rng.uniform(0.02, 0.2)), s.vertices.shape), s.faces
    V = rng.uniform(0, 10, (80, 3))
    F = rng.integers(0, 80, (60, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    return "soup", V, F


def open3d_pairs(V, F) -> set:
    import open3d as o3d

    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32)))
    return {tuple(sorted(p)) for p in np.asarray(m.get_self_intersecting_triangles()).tolist()}


def pymeshlab_faces(V, F) -> set:
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F.astype(np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return set(np.flatnonzero(ms.current_mesh().face_selection_array()).tolist())


def _common_points(V, F, i, j) -> list:
    """Vertices of the exact common part of faces i and j (rational arithmetic)."""
    from fractions import Fraction

    from test_intersect import _common_part

    P = [tuple(Fraction(float(x)) for x in V[k]) for k in (*F[i], *F[j])]
    return _common_part(P[:3], P[3:])


def main(argv=None) -> int:
    from contourmesh.intersect import intersecting_pairs

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=13)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    t0 = time.time()
    tot = dict(meshes=0, faces=0, ours_pairs=0, o3d_pairs=0, o3d_missed=0, o3d_false_positive=0, ours_extra_shared_index=0,
               ours_extra_point_contact=0, ours_extra_other=0, pml_faces=0, ours_faces=0, pml_missed=0, ours_extra_faces=0,
               meshes_crossing=0, seconds_ours=0.0)
    by_label: dict = {}
    examples = []
    for i in range(args.n):
        label, V, F = random_mesh(i, rng)
        V = np.asarray(V, np.float64)
        F = np.asarray(F, np.int64)
        t = time.perf_counter()
        ours = {tuple(p) for p in intersecting_pairs(V, F).tolist()}
        tot["seconds_ours"] += time.perf_counter() - t
        o3 = open3d_pairs(V, F)
        pml = pymeshlab_faces(V, F)
        our_faces = {f for p in ours for f in p}
        false_pos = {p for p in o3 - ours if not _common_points(V, F, *p)}
        missed = o3 - ours - false_pos
        extra = ours - o3
        shared = {p for p in extra if set(F[p[0]]) & set(F[p[1]])}
        pml_missed = pml - our_faces
        tot["meshes"] += 1
        tot["faces"] += len(F)
        tot["ours_pairs"] += len(ours)
        tot["o3d_pairs"] += len(o3)
        tot["o3d_missed"] += len(missed)
        tot["o3d_false_positive"] += len(false_pos)
        tot["ours_extra_shared_index"] += len(shared)
        points = {p for p in extra - shared if len(_common_points(V, F, *p)) == 1}
        tot["ours_extra_point_contact"] += len(points)
        tot["ours_extra_other"] += len(extra - shared - points)
        tot["pml_faces"] += len(pml)
        tot["ours_faces"] += len(our_faces)
        tot["pml_missed"] += len(pml_missed)
        tot["ours_extra_faces"] += len(our_faces - pml)
        tot["meshes_crossing"] += bool(ours)
        b = by_label.setdefault(label, dict(meshes=0, crossing=0, ours_pairs=0, o3d_pairs=0, pml_faces=0, ours_faces=0))
        b["meshes"] += 1
        b["crossing"] += bool(ours)
        b["ours_pairs"] += len(ours)
        b["o3d_pairs"] += len(o3)
        b["pml_faces"] += len(pml)
        b["ours_faces"] += len(our_faces)
        if (missed or pml_missed or extra - shared - points) and len(examples) < 20:
            examples.append(dict(i=i, label=label, o3d_missed=sorted(missed)[:5], pml_missed=sorted(pml_missed)[:5],
                                 extra_other=sorted(extra - shared - points)[:5]))
        if (i + 1) % 50 == 0:  # progress, and the figures so far (a long run can be read while it goes)
            print(json.dumps(dict(done=i + 1, **{k: tot[k] for k in ("o3d_missed", "pml_missed", "ours_extra_other",
                                                                       "meshes_crossing", "ours_pairs", "o3d_pairs")})),
                  file=sys.stderr, flush=True)
    tot["seconds_total"] = time.time() - t0
    out = dict(args=vars(args) | {"json": str(args.json) if args.json else None}, totals=tot, by_label=by_label,
               examples=examples)
    text = json.dumps(out, indent=1, default=str)
    print(text)
    if args.json:
        args.json.write_text(text)
    return 1 if tot["o3d_missed"] or tot["pml_missed"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
