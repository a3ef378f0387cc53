"""A label larger than one task's budget, meshed in slabs of slices joined at their seams by vertex identity.

Every vertex the paper-mode volume mesher makes lies in a slice plane or between two consecutive
ones, and every face it makes spans at most one gap between consecutive slices.  A label's padded
box (``nz`` slices) is cut at slices ``c_0 = 0 < c_1 < ... < c_n = nz - 1``; slab ``j`` *owns*
the gaps ``c_j .. c_{j+1}`` and meshes the slices ``c_j - halo .. c_{j+1} + halo`` (clipped to the
box) with :func:`contourmesh.mesh_volume`, at the slice heights of the whole box (``z=``), so its
vertices are the whole mesh's to the bit wherever its faces do not depend on slices outside that
range.  It keeps the faces it owns (:func:`face_owner`: by the face's height range, and for a
face lying in a seam plane by the side its normal faces away from), and the pieces are joined by
identical coordinates.

**Halo.**  In the paper mode (``refine=None``) a face between slices ``k`` and ``k + 1`` depends on
slices ``k - 1 .. k + 2``: the join of the pair needs the two slices, the choice of crack or MLP
rings needs the joins on either side, and a component's caps need its neighbours above and
below.  The crossing repair and its rebuilds, and the manifold repairs, act within a face's
neighbourhood.  :data:`DEFAULT_HALO` = 3 slices gives these two slices of margin.  Every seam is
checked: each slab also returns a hash of the faces it made within one slice gap on the *other*
side of each seam, and the driver compares it with the hash of the faces the neighbour owns there;
a mismatch is an error (:class:`SeamMismatch`), never a silently different mesh.

``refine="band"`` is not meshed in slabs: its blur width comes from the whole object's contours
(:func:`contourmesh.refine.auto_sigma`), its meridians chain each slice's vertices to the slice
below from the bottom of the object up, and the choice between the stack route and the volume
route looks at the whole object's topology; no finite halo reproduces those.

Area and volume are sums that do not depend on the order of the faces (:func:`exact_area_volume`):
the area is the correctly rounded sum of per-face areas (each computed from the face rotated to
start at its lexicographically smallest corner), the volume is the correctly rounded exact
divergence-theorem sum (every triple product split into floats that add up to it exactly), so a
slab's share can be carried as a few floats whose exact sum is its share (:func:`exact_parts`) and
the label's total is the same number however the faces are cut into slabs.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from .measure import _area_terms, _rotated, _volume_parts, exact_area_volume, exact_parts

__all__ = ["DEFAULT_HALO", "SeamMismatch", "exact_parts", "exact_area_volume", "face_owner", "slab_cuts",
           "slab_piece", "seam_hashes", "join_pieces", "join_stats"]

#: Slices read beyond each end of a slab's own range (paper mode; see the module docstring).
DEFAULT_HALO = 3


class SeamMismatch(RuntimeError):
    """Two slabs disagree on the faces next to their seam (the halo is too small for this label)."""


# ------------------------------------------------------------------------------------------------
# slabs and ownership
# ------------------------------------------------------------------------------------------------
def slab_cuts(nz: int, plane: int, max_box_voxels: int, halo: int):
    """The cut slices ``[c_0 = 0, ..., c_n = nz - 1]`` of a box of ``nz`` slices of ``plane`` voxels
    each, so that a slab's read (its own gaps, one slice, and ``halo`` slices each side) stays
    within ``max_box_voxels``; None when not even one gap per slab fits."""
    depth = int(max_box_voxels) // int(plane) - 2 * int(halo) - 1
    if depth < 1:
        return None
    if nz <= 1:
        return [0, 0]
    return list(range(0, nz - 1, depth)) + [nz - 1]


def _face_keys(V, F):
    """Per face: ``zmin + zmax`` and the sign of its normal's z component."""
    T = V[_rotated(V, F)]
    z = T[:, :, 2]
    nzs = np.sign(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])[:, 2])
    return z.min(1) + z.max(1), nzs


def face_owner(V, F, seams) -> np.ndarray:
    """Per face, the index of the slab that owns it: the number of seam heights (increasing) it lies
    above.  A face lies above the seam at height ``s`` when ``zmin + zmax > 2 s``, or ``== 2 s`` and
    its normal points down (a face in the seam plane closes what lies above it)."""
    key, nzs = _face_keys(V, F)
    owner = np.zeros(len(F), np.int64)
    for s in seams:
        owner += (key > 2 * s) | ((key == 2 * s) & (nzs < 0))
    return owner


def _faces_hash(V, F) -> str:
    """A hash of a set of faces by their coordinates (independent of order and numbering)."""
    if not len(F):
        return "empty"
    T = V[_rotated(V, F)].reshape(-1, 9) + 0.0
    T = T[np.lexsort(T.T[::-1])]
    return hashlib.blake2b(np.ascontiguousarray(T).tobytes(), digest_size=16).hexdigest()


def slab_piece(mask, zs, j: int, cuts, halo: int, spacing, origin, method, meshes: bool):
    """Mesh slab ``j`` of a label's box.  ``mask`` holds the box's slices ``a .. b`` (``a = max(cuts[j]
    - halo, 0)``), ``zs`` the heights of *all* the box's slices.  Returns a dict: ``V``, ``F`` (the
    owned faces, ``meshes``) or their statistics, and the seam hashes."""
    from .volumes import volume_to_mesh

    a = max(cuts[j] - halo, 0)
    b = a + mask.shape[0]
    out = {"j": j}
    if not mask.any():
        V = np.zeros((0, 3))
        F = np.zeros((0, 3), np.int64)
    else:
        m = volume_to_mesh(mask, spacing=tuple(spacing), z=zs[a:b], origin=tuple(origin),
                           polygon=method.get("polygon") or "mlp",
                           triangulation=method.get("triangulation") or "wiederhold", caps=method.get("caps") or "flat")
        V = np.asarray(m.vertices, dtype=np.float64) + 0.0
        F = np.asarray(m.faces, dtype=np.int64)
    owner, key, out["hash_seen"], out["hash_own"] = seam_hashes(V, F, zs, j, cuts, a, b)
    mine = owner == j
    Fm = F[mine]
    if meshes:
        used = np.unique(Fm)
        remap = np.full(len(V), -1, np.int64)
        remap[used] = np.arange(len(used))
        out["V"], out["F"] = V[used], remap[Fm]
        return out
    out.update(_piece_stats(V, F, owner, j, zs, cuts))
    return out


def seam_hashes(V, F, zs, j: int, cuts, a: int, b: int):
    """Slab ``j``'s side of the seam checks, from its mesh ``V, F`` of the box's slices ``a .. b - 1``
    (``zs``: the heights of all the box's slices): ``(owner, key, hash_seen, hash_own)``, the
    owner of each face (:func:`face_owner`), its ``zmin + zmax``, and per seam the hash of the
    neighbour's faces within one gap of it as this slab made them (where it sees that whole
    neighbourhood) and of its own faces there."""
    nz = len(zs)
    seams = [float(zs[c]) for c in cuts[1:-1]]
    owner = face_owner(V, F, seams) if len(F) else np.zeros(0, np.int64)
    key, _ = _face_keys(V, F) if len(F) else (np.zeros(0), None)
    seen = {}
    for s in (j, j + 1):  # seam s lies between slabs s - 1 and s, at cut s
        if s < 1 or s > len(cuts) - 2:
            continue
        zc = cuts[s]
        lo, hi = zs[max(zc - 1, 0)], zs[min(zc + 1, nz - 1)]
        near = (key >= 2 * lo) & (key <= 2 * hi)
        other = s - 1 if s == j else s
        if zc - 1 >= a and zc + 1 < b:  # this slab sees the whole neighbourhood
            seen[s] = _faces_hash(V, F[near & (owner == other)])
    mine = owner == j
    Fm = F[mine]
    own = {s: _faces_hash(V, Fm[_near(key[mine], zs, cuts, s)]) for s in (j, j + 1) if 1 <= s <= len(cuts) - 2}
    return owner, key, seen, own


def _near(key, zs, cuts, s):
    zc = cuts[s]
    nz = len(zs)
    lo, hi = zs[max(zc - 1, 0)], zs[min(zc + 1, nz - 1)]
    return (key >= 2 * lo) & (key <= 2 * hi)


def _piece_stats(V, F, owner, j, zs, cuts):
    """What the label's row needs from slab ``j``'s owned faces, without the faces themselves."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from .intersect import intersecting_pairs

    mine = owner == j
    Fm = F[mine]
    st = {"faces": int(len(Fm)), "area": exact_parts(_area_terms(V, Fm)), "volume6": _volume_parts(V, Fm)}
    used = np.unique(Fm)
    Vu = V[used]
    remap = np.full(len(V), -1, np.int64)
    remap[used] = np.arange(len(used))
    f = remap[Fm]
    # the vertices this slab shares with its neighbours: those that faces owned by another slab use
    on_seam = np.isin(used, np.unique(F[~mine])) if (~mine).any() else np.zeros(len(used), bool)
    # components of the owned faces; the seam vertices carry them to the driver
    if len(f):
        g = coo_matrix((np.ones(2 * len(f)), (np.r_[f[:, 0], f[:, 1]], np.r_[f[:, 1], f[:, 2]])),
                       shape=(len(Vu), len(Vu)))
        ncomp, comp = connected_components(g, directed=False)
    else:
        ncomp, comp = 0, np.zeros(0, np.int64)
    st["components"] = int(ncomp)
    st["inner_vertices"] = int((~on_seam).sum())
    st["seam_vertices"] = Vu[on_seam]
    st["seam_comp"] = comp[on_seam].astype(np.int64)
    # edges: interior ones counted here, the ones used once (on a seam) matched in the driver
    d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    und = np.sort(d, axis=1)
    ue, cnt = np.unique(und, axis=0, return_counts=True)
    dd, dcnt = np.unique(d, axis=0, return_counts=True)
    st["edges"] = int(len(ue))
    st["nonmanifold_edges"] = int((cnt > 2).sum())
    st["dup_directed"] = int((dcnt > 1).sum())
    once = ue[cnt == 1]
    is_once = np.zeros(len(d), bool)
    if len(once):
        k1 = und[:, 0] * len(Vu) + und[:, 1]
        is_once = np.isin(k1, once[:, 0] * len(Vu) + once[:, 1])
    be = d[is_once]
    st["boundary"] = Vu[be].reshape(-1, 6) if len(be) else np.zeros((0, 6))
    # degenerate faces and duplicate positions, as mesh_checks counts them (threshold: see join_stats)
    T = Vu[f]
    c = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    st["min_area"] = float((0.5 * np.sqrt(np.einsum("ij,ij->i", c, c))).min()) if len(f) else math.inf
    st["repeated_index"] = int(((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])).sum())
    st["dup_positions"] = int(len(Vu) - len(np.unique(Vu, axis=0))) if len(Vu) else 0
    st["lo"] = Vu.min(0) if len(Vu) else np.full(3, np.inf)
    st["hi"] = Vu.max(0) if len(Vu) else np.full(3, -np.inf)
    # crossing pairs: each pair is counted by the slab that owns the higher-numbered of its faces
    if len(F):
        pairs = intersecting_pairs(V, F)
        o = owner[pairs] if len(pairs) else np.zeros((0, 2), np.int64)
        st["self_intersections"] = int((o.max(1) == j).sum()) if len(o) else 0
    else:
        st["self_intersections"] = 0
    return st


# ------------------------------------------------------------------------------------------------
# the driver's side: join the pieces
# ------------------------------------------------------------------------------------------------
def _check_seams(pieces, label):
    """Every seam's neighbourhood as each of its two slabs made it must agree."""
    by_j = {p["j"]: p for p in pieces}
    for p in pieces:
        for s, seen in p["hash_seen"].items():
            other = by_j[s - 1 if s == p["j"] else s]
            if other["hash_own"].get(s) != seen:
                raise SeamMismatch(f"label {label}: slabs {min(p['j'], other['j'])} and {max(p['j'], other['j'])} "
                                   f"disagree on the faces next to their seam; mesh it with a larger halo or budget")


def join_pieces(pieces, label):
    """The label's mesh from its slabs' owned faces, joined by identical vertex coordinates, in
    canonical order (vertices sorted lexicographically, each face rotated to its smallest index,
    faces sorted)."""
    _check_seams(pieces, label)
    Vs = [p["V"] for p in pieces if len(p["F"])]
    if not Vs:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    U, inv = np.unique(np.concatenate(Vs) + 0.0, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    Fs, off = [], 0
    for p in pieces:
        if len(p["F"]):
            Fs.append(inv[off + p["F"]])
            off += len(p["V"])
    F = np.concatenate(Fs)
    r = np.argmin(F, axis=1)
    rows = np.arange(len(F))
    F = np.stack([F[rows, (r + i) % 3] for i in range(3)], axis=1)
    return U, F[np.lexsort(F.T[::-1])]


def join_stats(pieces, label) -> dict:
    """The row's numbers from the slabs' statistics (no mesh assembled): area, volume, P, faces,
    genus, components, watertight, self_intersections, and ``closed`` as :func:`mesh_checks`
    decides it (its degenerate-face threshold from the union of the slabs' bounding boxes)."""
    from .measure import euler_genus

    _check_seams(pieces, label)
    pieces = sorted(pieces, key=lambda p: p["j"])
    area = math.fsum(x for p in pieces for x in p["area"])
    volume = math.fsum(x for p in pieces for x in p["volume6"]) / 6.0
    faces = sum(p["faces"] for p in pieces)
    # vertices and components across the seams: union-find over (slab, local component)
    parent: dict = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    ncomp = 0
    for p in pieces:
        for c in range(p["components"]):
            find((p["j"], c))
        ncomp += p["components"]
    P = sum(p["inner_vertices"] for p in pieces)
    seam_rows = [(p["seam_vertices"], p["seam_comp"], p["j"]) for p in pieces if len(p["seam_vertices"])]
    if seam_rows:
        allv = np.concatenate([r[0] for r in seam_rows]) + 0.0
        comp = np.concatenate([r[1] for r in seam_rows])
        slab = np.concatenate([np.full(len(r[0]), r[2]) for r in seam_rows])
        U, inv = np.unique(allv, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        P += len(U)
        first = np.full(len(U), -1)
        for i in range(len(allv)):
            u = inv[i]
            if first[u] < 0:
                first[u] = i
            else:
                a, b = find((int(slab[first[u]]), int(comp[first[u]]))), find((int(slab[i]), int(comp[i])))
                if a != b:
                    parent[a] = b
                    ncomp -= 1
    # edges used once by a slab must be met, reversed, by exactly one edge of the neighbour
    edges = sum(p["edges"] for p in pieces)
    nonmanifold = sum(p["nonmanifold_edges"] for p in pieces)
    dup_directed = sum(p["dup_directed"] for p in pieces)
    B = [p["boundary"] for p in pieces if len(p["boundary"])]
    boundary = 0
    if B:
        be = np.concatenate(B) + 0.0
        keys = {}
        for r in be:
            a, b = r[:3].tobytes(), r[3:].tobytes()
            k = (a, b) if a < b else (b, a)
            keys.setdefault(k, []).append((a, b))
        for k, uses in keys.items():
            if len(uses) == 1:
                boundary += 1
            elif len(uses) == 2:
                edges -= 1
                if uses[0] == uses[1]:
                    dup_directed += 1
            else:
                edges -= len(uses) - 1
                nonmanifold += 1
    watertight = boundary == 0 and nonmanifold == 0
    comps = int(ncomp)
    lo = np.min([p["lo"] for p in pieces], axis=0)
    hi = np.max([p["hi"] for p in pieces], axis=0)
    diag2 = float(np.sum((hi - lo) ** 2)) or 1.0
    degenerate = sum(p["repeated_index"] for p in pieces) + sum(p["min_area"] <= 1e-12 * diag2 for p in pieces)
    dup_vertices = sum(p["dup_positions"] for p in pieces)
    crossings = sum(p["self_intersections"] for p in pieces)
    closed = bool(watertight and dup_directed == 0 and degenerate == 0 and dup_vertices == 0 and volume > 0)
    return {"area": area, "volume": volume, "P": int(P), "faces": int(faces),
            "genus": euler_genus(int(P), int(edges), int(faces), comps) if watertight else None,
            "components": comps, "watertight": bool(watertight), "self_intersections": int(crossings),
            "closed": closed, "ok": bool(closed and crossings == 0)}
