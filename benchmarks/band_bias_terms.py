"""Where refine="band"'s negative area bias on real shapes comes from (issue 14): per-step terms.

For a rotated, voxelized real mesh (the inputs of ``comparisons/real``: same seed, rotations and
offsets), the volume mesher is run with ``refine="band"`` while every call of
:func:`contourmesh.refine.refine_ring` is recorded.  Each recorded seed polygon is then pushed
through the refinement's steps again, one at a time, and after each step its vertices are compared
with the true mesh's cross-section at the slice height:

* ``seed``      the MLP seed polygon;
* ``level``     the 1/2-level of the blurred indicator at sigma (no curvature correction);
* ``curv``      with the curvature correction (step 3), still at sigma, without the band clamp;
* ``curv+band`` the same, clamped into the band (step 4);
* ``2scale``    the two-scale choice (step 3b) -- the guide polygon;
* ``meridian``  the meridian polygon (step 6) where the ring has a guide below, else the guide;
* ``chord``     after the chord push (step 5), clamped;
* ``final``     the ring the mesher used (after the band guarantee and the untangling).

Per step: the mean signed horizontal offset of the vertices from the true section (voxels,
positive outside), and the ratio of the polygons' perimeters and enclosed areas to the true
section loops they follow (pooled over the rings matched one-to-one to a loop), in %.  Then the
mesh's area error.

    PYTHONPATH=src python benchmarks/band_bias_terms.py --mesh armadillo --rot 2 --n 128
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))
DATA = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))
SEED = 20090823  # comparisons/real/real.toml


def _loops_at(tm, z):
    """The true section's closed loops at height z: list of (k, 2) arrays (x, y)."""
    sec = tm.section(plane_origin=[0, 0, z], plane_normal=[0, 0, 1])
    if sec is None:
        return []
    return [np.asarray(d)[:, :2] for d in sec.discrete if len(d) >= 4]


def _seg_arrays(loops):
    a = np.concatenate([lp[:-1] if np.allclose(lp[0], lp[-1]) else lp for lp in loops])
    b = np.concatenate([(lp[1:] if np.allclose(lp[0], lp[-1]) else np.roll(lp, -1, 0)) for lp in loops])
    ids = np.concatenate([np.full(len(lp) - (1 if np.allclose(lp[0], lp[-1]) else 0), i) for i, lp in enumerate(loops)])
    return a, b, ids


def _signed_dist(p, a, b, ids):
    """Signed distance (positive outside) of points p (n, 2) to the segments, and the nearest loop id."""
    d = b - a
    l2 = (d ** 2).sum(1)
    t = np.clip(((p[:, None, :] - a[None]) * d[None]).sum(2) / np.where(l2 > 0, l2, 1)[None], 0, 1)
    c = a[None] + t[..., None] * d[None]
    dist = np.hypot(*(p[:, None, :] - c).transpose(2, 0, 1))
    j = np.argmin(dist, axis=1)
    dmin = dist[np.arange(len(p)), j]
    # even-odd inside test against every segment
    y = p[:, 1][:, None]
    x = p[:, 0][:, None]
    cond = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    xs = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / np.where(
        b[None, :, 1] != a[None, :, 1], b[None, :, 1] - a[None, :, 1], 1)
    inside = (np.count_nonzero(cond & (x < xs), axis=1) % 2) == 1
    return np.where(inside, -dmin, dmin), ids[j]


def _perim(p):
    return float(np.hypot(*np.diff(np.vstack([p, p[:1]]), axis=0).T).sum())


def _area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def stages(pts, seed, kz, sigma, dz, prev, opts):
    """The polygons after each step of refine_ring (see the module docstring), array-local."""
    from contourmesh import refine as R

    kk = int(kz)
    dz = R._as_grid(dz, pts.shape[0])  # the lattice record (refine._make_grid), also from a plain spacing
    fine = opts.get("fine_sigma")
    mm = opts.get("max_move", 3.0)
    strict = opts.get("strict", False)
    kzs = np.full(len(seed), kk, dtype=np.int64)
    out = {"seed": seed}
    lev = np.empty_like(seed)
    _move_noclamp(pts, np.ascontiguousarray(seed), kzs, sigma, dz, False, mm, lev, strict)
    out["level"] = lev
    cur = np.empty_like(seed)
    _move_noclamp(pts, np.ascontiguousarray(seed), kzs, sigma, dz, True, mm, cur, strict)
    out["curv"] = cur
    cb = np.empty_like(seed)
    R._move_to_surface(pts, np.ascontiguousarray(seed), kzs, sigma, dz, True, mm, cb, strict, np.empty(len(seed), bool))
    out["curv+band"] = cb
    guide, _ = R._surface_points(pts, seed, kzs, sigma, dz, True, mm, strict, fine, None)
    out["2scale"] = guide
    ring = guide if R._is_simple(guide) and R.shoelace_area(guide) * R.shoelace_area(seed) > 0 else seed
    if prev is not None and len(prev) and opts.get("meridians", True):
        length = _perim(guide)
        step = length / (len(seed) * float(opts.get("density", 1.0)))
        par, dist, _, _ = R._project_to_ring(guide, np.ascontiguousarray(prev))
        par = par[dist < 3.0]
        if len(par) >= 3:
            s = R._meridian_params(par, length, step)
            if len(s) >= 3:
                start = R._ring_point_at(guide, s)
                k2 = np.full(len(start), kk, dtype=np.int64)
                cand, _ = R._surface_points(pts, start, k2, sigma, dz, True, mm, strict, fine, None)
                if R._is_simple(cand) and R.shoelace_area(cand) * R.shoelace_area(seed) > 0:
                    ring = cand
    out["meridian"] = ring
    loc = np.empty((len(ring), 3))
    loc[:, :2] = ring
    loc[:, 2] = kk
    fld = R._field_many(pts, loc, sigma, dz)
    g2 = (fld[:, 1:4] ** 2).sum(axis=1)
    nz2 = np.where(g2 > 0, fld[:, 3] ** 2 / np.where(g2 > 0, g2, 1.0), 0.0)
    target = R._chord_push(ring, nz2)
    out["chord-free"] = target
    k3 = np.full(len(ring), kk, dtype=np.int64)
    o = np.empty_like(ring)
    R._clamp_to_band(pts, np.ascontiguousarray(ring), target, k3, o, dz)
    out["chord"] = o if R._is_simple(o) else ring
    return out


_move_noclamp = None


def _build_noclamp():
    """refine._move_to_surface without the band clamp of step 4 (the target itself)."""
    import math

    from numba import njit

    from contourmesh.refine import _field, _lattice_norm, _mean_curvature_shift

    @njit
    def move(pts, xy, kz, sigma, dz, curvature, max_move, out, strict):
        norm = _lattice_norm(sigma, dz)
        buf = np.empty(10)
        for n in range(xy.shape[0]):
            x0, y0 = xy[n, 0], xy[n, 1]
            out[n, 0], out[n, 1] = x0, y0
            z = float(kz[n])
            _field(pts, x0, y0, z, sigma, dz, norm, buf)
            hx, hy = -buf[1], -buf[2]
            hn = math.sqrt(hx * hx + hy * hy)
            gn = math.sqrt(buf[1] ** 2 + buf[2] ** 2 + buf[3] ** 2)
            if hn <= 1e-3 * gn or hn == 0.0:
                continue
            dx, dy = hx / hn, hy / hn
            lo, hi = -max_move, max_move
            t = 0.0
            ok = False
            g = 1.0
            for it in range(40):
                _field(pts, x0 + t * dx, y0 + t * dy, z, sigma, dz, norm, buf)
                g = buf[0] - 0.5
                if abs(g) < 1e-12:
                    ok = True
                    break
                if g > 0.0:
                    lo = t
                else:
                    hi = t
                d = buf[1] * dx + buf[2] * dy
                tn = t - g / d if d < 0.0 else 0.5 * (lo + hi)
                if not (lo < tn < hi):
                    tn = 0.5 * (lo + hi)
                if abs(tn - t) < 1e-10:
                    t = tn
                    ok = True
                    break
                t = tn
            if not ok and hi - lo > 1e-6:
                continue
            if strict and abs(g) > 1e-6:
                continue
            tx, ty = x0 + t * dx, y0 + t * dy
            if curvature:
                _field(pts, tx, ty, z, sigma, dz, norm, buf)
                shift, gnorm = _mean_curvature_shift(buf, sigma)
                hz = math.sqrt(buf[1] ** 2 + buf[2] ** 2)
                if gnorm > 0.0 and hz > 0.0:
                    s = shift * gnorm / hz
                    s = min(1.0, max(-1.0, s))
                    tx += s * dx
                    ty += s * dy
            out[n, 0], out[n, 1] = tx, ty
        return 0

    return move


def run(mesh_name, rot, n, max_rings=None, verbose=True):
    global _move_noclamp
    import trimesh
    from real_shapes import MESHES

    import contourmesh
    from contourmesh import refine as R
    from contourmesh.compare.inputs import load_closed_mesh, mesh_inputs

    if _move_noclamp is None:
        _move_noclamp = _build_noclamp()
    name = mesh_name + ("-rot" if rot is not None else "")
    inp = mesh_inputs(MESHES[mesh_name], [n], name=name, repeats=(rot or 0) + 1, seed=SEED, offset=rot is not None,
                      rotate=rot is not None, root=DATA / "meshes", placement="per-repeat")[rot or 0]
    vol, sp, org = inp.volume()
    v, f = load_closed_mesh(DATA / "meshes" / inp.source)
    if inp.rotation:
        v = v @ np.asarray(inp.rotation).reshape(3, 3).T
    h = float((v.max(0) - v.min(0)).max()) / n
    if inp.offset:
        v = v + np.asarray(inp.offset) * h
    tm = trimesh.Trimesh(v, f, process=False)
    tm.merge_vertices(merge_tex=True, merge_norm=True)

    calls = []
    ctx = {}
    orig_ring, orig_rvr = R.refine_ring, R.refine_volume_rings

    def rec_ring(pts, seed, kz, sigma, dz, prev=None, **kw):
        ring, nc = orig_ring(pts, seed, kz, sigma, dz, prev, **kw)
        calls.append((seed.copy(), int(kz), sigma, dz, None if prev is None else np.array(prev), dict(kw), ring))
        ctx["pts"] = pts
        return ring, nc

    def rec_rvr(mask, zs, spacing_xy, origin_xy, *a, **kw):
        ctx.update(zs=np.asarray(zs, float), dx=float(spacing_xy[0]), ox=float(origin_xy[0]), oy=float(origin_xy[1]))
        rings, info = orig_rvr(mask, zs, spacing_xy, origin_xy, *a, **kw)
        ctx["rings"] = rings
        ctx["info"] = info
        return rings, info

    import contourmesh.volumes as VM
    R.refine_ring = rec_ring
    VM.refine_volume_rings = rec_rvr
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t = time.process_time()
            m = contourmesh.mesh(vol, spacing=sp, origin=org, refine="band")
            cpu = time.process_time() - t
    finally:
        R.refine_ring, VM.refine_volume_rings = orig_ring, orig_rvr
    e = m.area / inp.area_true - 1
    pad = 6
    dx, ox, oy, zs = ctx["dx"], ctx["ox"], ctx["oy"], ctx["zs"]
    finals = [np.c_[(r[:, 0] - ox) / dx + pad, (r[:, 1] - oy) / dx + pad] for r in ctx["rings"].values()]
    final_by_key = {}
    for r in finals:
        final_by_key.setdefault(len(r), []).append(r)
    names = ["seed", "level", "curv", "curv+band", "2scale", "meridian", "chord-free", "chord", "final", "used"]
    acc = {s: [0.0, 0, 0.0, 0.0, 0.0, 0.0] for s in names}  # sum off, count, perim, true perim, area, true area
    loops_cache = {}
    used = 0
    pts = ctx["pts"]
    sel = calls if max_rings is None else calls[:: max(1, len(calls) // max_rings)]
    for seed, kz, sigma, dz, prev, kw, ring in sel:
        z = zs[kz - pad]
        if z not in loops_cache:
            loops_cache[z] = [np.c_[(lp[:, 0] - ox) / dx + pad, (lp[:, 1] - oy) / dx + pad] for lp in _loops_at(tm, z)]
        loops = loops_cache[z]
        if not loops or len(seed) < 3:
            continue
        a, b, ids = _seg_arrays(loops)
        st = stages(pts, seed, kz, sigma, dz, prev, kw)
        st["final"] = ring
        # the ring the mesher used: the untangled output with this seed's final ring, if present
        st["used"] = ring
        _, lid = _signed_dist(seed, a, b, ids)
        vals, cnt = np.unique(lid, return_counts=True)
        lp = int(vals[np.argmax(cnt)])
        if cnt.max() < 0.9 * len(seed):
            continue  # the ring follows several loops: not matched one-to-one
        tl = loops[lp]
        tper = _perim(tl[:-1] if np.allclose(tl[0], tl[-1]) else tl)
        tar = abs(_area(tl[:-1] if np.allclose(tl[0], tl[-1]) else tl))
        if abs(abs(_area(seed)) / tar - 1) > 0.5:
            continue
        used += 1
        for s in names:
            p = st[s]
            d, _ = _signed_dist(p, a, b, ids)
            acc[s][0] += d.sum()
            acc[s][1] += len(d)
            acc[s][2] += _perim(p)
            acc[s][3] += tper
            acc[s][4] += abs(_area(p))
            acc[s][5] += tar
    rows = {}
    for s in names:
        o, c, p, tp, ar, ta = acc[s]
        rows[s] = (o / max(c, 1), 100 * (p / tp - 1) if tp else float("nan"), 100 * (ar / ta - 1) if ta else float("nan"))
    if verbose:
        print(f"{name} #{rot} N={n}: e = {100 * e:+.2f}%  ({cpu:.1f} s CPU, {len(calls)} rings, {used} matched, "
              f"sigma {ctx['info']['refine_sigma']:.2f}, fine share {ctx['info']['refine_fine_share']:.3f}, "
              f"clamped {ctx['info']['refine_clamped']}, kept seeds {ctx['info']['refine_kept_seeds']}, "
              f"thin {ctx['info']['refine_thin']})")
        print(f"  {'step':11s} {'offset vx':>9s} {'perim %':>8s} {'area %':>8s}")
        for s in names[:-1]:
            print(f"  {s:11s} {rows[s][0]:+9.4f} {rows[s][1]:+8.3f} {rows[s][2]:+8.3f}")
    return e, rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="armadillo")
    ap.add_argument("--rot", type=int, default=2, help="rotation 0-2 of comparisons/real; -1: axis-aligned")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--max-rings", type=int, default=None, help="examine every k-th ring only")
    a = ap.parse_args(argv)
    for mname in a.mesh.split(","):
        run(mname, None if a.rot < 0 else a.rot, a.n, a.max_rings)


if __name__ == "__main__":
    main()
