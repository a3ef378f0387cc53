"""The clinical-contour comparison: phantoms drawn as contour stacks, meshed, measured against their truths.

:func:`measure` takes one phantom (:mod:`contourmesh.compare.phantoms`) and one drawing setting
(slice spacing ``dz``, point spacing ``ds``) and returns table rows:

* one row per mode of ours (``caps`` x ``polygon``, and ``caps="smooth"`` with ``polygon="none"``, the
  stack route only: refused, a failed row, where the stack goes to the raster route): mesh area and volume against the analytic
  values, volume against the trapezoid and frustum rules over the drawn sections' even-odd areas,
  the mesh's own cross-section just off each contour plane (its triangles cut by the plane, Green's
  theorem over the oriented cut segments) against that contour's area, the mesh checks;
* one row per peer (VTK surface nets, marching cubes after a sigma = 1 voxel blur) on the
  even-odd rasterization of the drawn stack at ``fine`` mm in the plane (the sections' own
  heights), through :func:`contourmesh.compare.methods.run_method`.

Phantoms without a closed form (the Y) take their reference from the solid itself sampled on an
isotropic ``fine`` grid: volume = voxel count, area = surface nets of that volume
(``truth = "solid-raster"``).
"""

from __future__ import annotations

import time

import numpy as np

from ..api import mesh as _mesh
from ..rasterize import rasterize_stack
from .methods import run_method
from .phantoms import Phantom, draw, frustum_volume, implicit_volume, section_areas, trapezoid_volume

__all__ = ["measure", "COLUMNS", "MODES", "PEERS", "cross_section_errors", "reference", "rules_rows", "RULE_COLUMNS",
           "RULE_SETTINGS", "padded_rules", "slab_volume"]

#: Our modes (caps, polygon); polygon ``"default"`` leaves it unset: drawn rings go to the contours route
#: (with ``caps="smooth"`` one ring per section goes to the stack route; ``"contours"`` asks for the
#: contours route with ``route="contours"``; ``"curved"`` the contours route with ``bands="curved"``).
MODES = (("flat", "mlp"), ("half", "mlp"), ("flat", "none"), ("half", "none"), ("smooth", "none"),
         ("flat", "default"), ("half", "default"), ("smooth", "contours"), ("smooth", "curved"))
PEERS = ("vtk-surfacenets", "mc-lewiner-blur1")

COLUMNS = ["phantom", "kind", "tilt", "dz", "ds", "seed", "method", "caps", "polygon", "status", "route",
           "sections", "area_true", "volume_true", "truth", "area", "volume", "area_err", "volume_err",
           "vol_trapezoid", "vol_frustum", "vol_vs_trapezoid", "vol_vs_frustum", "vol_outside_rules",
           "vol_outside_padded_rules", "vol_vs_slabs",
           "area_vs_surfacenets", "area_vs_mc_blur1", "area_solid_surfacenets", "area_vs_solid_surfacenets", "xsec_max_err", "xsec_worst_side_err", "xsec_median_err", "xsec_checked", "closed_ok", "self_intersections", "faces",
           "seconds", "error"]


def _rel(a, b):
    return float(a / b - 1.0) if (a is not None and b) else None


def cross_section_errors(m, stack, *, max_planes: int = 40, side: str = "best") -> np.ndarray:
    """Relative error of the mesh's cross-section area at contour planes against the contours' even-odd area.

    Each plane ``z_k`` is cut just off the plane (``z_k +- 1e-4`` of the gap to the neighbouring
    section: both sides for inner sections, the inner side for the end sections), since at ``z_k``
    itself flat caps and lids lie in the plane.  ``side="best"`` (the default) keeps the side that
    comes closer: with flat caps a branch or a hole that ends at ``z_k`` is closed in the plane and
    is present on one side only (the side of its band), so the drawn section is the mesh's section
    on that side; ``side="worst"`` keeps the worse side (equal to the best one where no ring ends in
    the plane, e.g. with ``caps="half"`` or ``"smooth"``).  At most ``max_planes`` sections are
    checked (evenly spread, the ends always).
    """
    if side not in ("best", "worst"):
        raise ValueError(f"side must be 'best' or 'worst'; got {side!r}")
    tri = np.asarray(m.vertices, dtype=np.float64)[np.asarray(m.faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    zs = np.array([s.z for s in stack.sections])
    ref = section_areas(stack)
    n = len(zs)
    idx = np.unique(np.r_[np.linspace(0, n - 1, min(n, max_planes)).round().astype(int)])
    out = []
    for k in idx:
        sides = []
        if k > 0:
            sides.append(zs[k] - 1e-4 * (zs[k] - zs[k - 1]))
        if k < n - 1:
            sides.append(zs[k] + 1e-4 * (zs[k + 1] - zs[k]))
        errs = [_section_area(tri, normals, z) / ref[k] - 1.0 for z in sides]
        pick = min if side == "best" else max
        out.append(pick(errs, key=abs) if errs else 0.0)
    return np.asarray(out)


def _section_area(tri, normals, z) -> float:
    """Even-odd area of the mesh's section by the plane ``z``: Green's theorem over the cut segments,
    each oriented by its face's outward normal (``z x n`` keeps the inside on the left)."""
    d = tri[:, :, 2] - z
    d = np.where(d == 0.0, 1e-300, d)
    cut = (d.min(1) < 0) & (d.max(1) > 0)
    if not cut.any():
        return 0.0
    t, d, n = tri[cut], d[cut], normals[cut]
    a, b = t, np.roll(t, -1, axis=1)  # edges 0-1, 1-2, 2-0
    da, db = d, np.roll(d, -1, axis=1)
    crosses = (da < 0) != (db < 0)
    w = (da / np.where(crosses, da - db, 1.0))[:, :, None]
    pts = (a + (b - a) * w)[:, :, :2]
    order = np.argsort(~crosses, axis=1, kind="stable")[:, :2]  # the two crossing edges of each face
    p0 = np.take_along_axis(pts, order[:, :1, None], axis=1)[:, 0]
    p1 = np.take_along_axis(pts, order[:, 1:2, None], axis=1)[:, 0]
    tangent = np.c_[-n[:, 1], n[:, 0]]  # z x n, in the plane
    flip = np.einsum("ij,ij->i", p1 - p0, tangent) < 0
    p0[flip], p1[flip] = p1[flip], p0[flip].copy()
    return float(0.5 * np.sum(p0[:, 0] * p1[:, 1] - p1[:, 0] * p0[:, 1]))


_REF_CACHE: dict = {}


def solid_raster(ph: Phantom, fine: float):
    """``(area, volume)`` of the solid itself sampled on an isotropic ``fine`` grid: VTK surface nets'
    area and the voxel count's volume (cached per phantom)."""
    key = (ph.name, fine)
    if key not in _REF_CACHE:
        vol, org = implicit_volume(ph, fine)
        row = run_method("vtk-surfacenets", vol, spacing=(fine,) * 3, origin=org)
        area = row["area"] if row["status"] == "ok" else None
        _REF_CACHE[key] = (area, float(vol.sum()) * fine**3)
    return _REF_CACHE[key]


def reference(ph: Phantom, fine: float):
    """``(area, volume, truth)``: the closed form, or surface nets / voxel count of the solid at ``fine`` mm."""
    if ph.area is not None and ph.volume is not None:
        return ph.area, ph.volume, "analytic"
    return (*solid_raster(ph, fine), "solid-raster")


class _Timeout(Exception):
    pass


def _with_deadline(fn, seconds):
    """``fn()``, interrupted after ``seconds`` by SIGALRM (main thread, POSIX); otherwise just ``fn()``."""
    import signal
    import threading

    if not seconds or not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        return fn()

    def _alarm(signum, frame):
        raise _Timeout(f"no result within {seconds:g} s")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        return fn()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _base(ph, stack, dz, ds, seed, truth):
    area_t, vol_t, kind = truth
    return {"phantom": ph.name, "kind": ph.kind, "tilt": ph.params.get("tilt", 0.0), "dz": dz, "ds": ds,
            "seed": seed, "sections": len(stack.sections), "area_true": area_t, "volume_true": vol_t,
            "truth": kind}


def _volume_cols(vol, trap, fru, padded=None, slabs=None):
    lo, hi = min(trap, fru), max(trap, fru)
    outside = 0.0 if lo <= vol <= hi else ((vol - hi) / hi if vol > hi else (vol - lo) / lo)
    out = {"vol_trapezoid": trap, "vol_frustum": fru, "vol_vs_trapezoid": _rel(vol, trap),
           "vol_vs_frustum": _rel(vol, fru), "vol_outside_rules": float(outside)}
    if padded is not None:
        out["vol_outside_padded_rules"] = _outside(vol, *padded)
    if slabs is not None and slabs == slabs:
        out["vol_vs_slabs"] = _rel(vol, slabs)
    return out


def measure(ph: Phantom, dz: float, ds: float, *, seed: int = 0, fine: float = 0.25, modes=MODES,
            peers=PEERS, max_planes: int = 40, stack=None, timeout: float | None = 120.0) -> list[dict]:
    """Table rows (:data:`COLUMNS`) for one phantom drawn at slice spacing ``dz`` and point spacing ``ds``.

    Parameters
    ----------
    ph : Phantom
    dz, ds : float
        Slice spacing and in-plane point spacing (mm).
    seed : int
        The drawing's seed (plane offset, ring start points).
    fine : float
        Pixel (mm) of the peers' rasterization of the drawn stack, and voxel of the solid's
        reference raster for phantoms without a closed form.
    modes : sequence of (caps, polygon)
        Our modes to run.
    peers : sequence of str
        Peer method names (:func:`contourmesh.compare.methods.run_method`).
    max_planes : int
        Cross-section planes checked per mesh.
    stack : ContourStack, optional
        The drawing, when the caller already has it (else ``draw(ph, dz, ds, seed=seed)``).
    timeout : float, optional
        Seconds allowed to each of our modes (SIGALRM, main thread only); ``None``: no limit.

    A mode that raises gives a row with ``status = "failed"`` and the error text, one that runs out
    of time ``status = "timeout"``; nothing is dropped.
    """
    if stack is None:
        stack = draw(ph, dz, ds, seed=seed)
    truth = reference(ph, fine)
    trap, fru = trapezoid_volume(stack), frustum_volume(stack)
    padded, slabs = padded_rules(stack), slab_volume(stack)
    rows = []
    for caps, polygon in modes:
        row = _base(ph, stack, dz, ds, seed, truth)
        row.update(method="ours", caps=caps, polygon=polygon)
        t0 = time.perf_counter()
        try:
            extra = {"contours": {"route": "contours"}, "curved": {"route": "contours", "bands": "curved"}}
            m = _with_deadline(lambda: _mesh(stack, caps=caps, polygon=None if polygon in ("default", "contours", "curved")
                                             else polygon, **extra.get(polygon, {})),
                               timeout)
        except _Timeout as exc:
            row.update(status="timeout", error=str(exc), seconds=time.perf_counter() - t0)
            rows.append(row)
            continue
        except Exception as exc:  # a failure is a result: tabulated, not hidden
            row.update(status="failed", error=f"{type(exc).__name__}: {exc}"[:300],
                       seconds=time.perf_counter() - t0)
            rows.append(row)
            continue
        sec = time.perf_counter() - t0
        chk = m.checks()
        xs = cross_section_errors(m, stack, max_planes=max_planes)
        xw = cross_section_errors(m, stack, max_planes=max_planes, side="worst")
        row.update(status="ok", route=m.meta.get("route"), area=m.area, volume=m.volume,
                   xsec_worst_side_err=float(xw[np.argmax(np.abs(xw))]) if len(xw) else None,
                   area_err=_rel(m.area, truth[0]), volume_err=_rel(m.volume, truth[1]),
                   xsec_max_err=float(xs[np.argmax(np.abs(xs))]) if len(xs) else None,
                   xsec_median_err=float(np.median(np.abs(xs))) if len(xs) else None, xsec_checked=len(xs),
                   closed_ok=bool(chk.get("watertight") and chk.get("winding_consistent")
                                  and chk.get("degenerate_faces", 1) == 0),
                   self_intersections=chk.get("self_intersections"), faces=len(m.faces), seconds=sec, error="")
        row.update(_volume_cols(m.volume, trap, fru, padded, slabs))
        rows.append(row)
    if peers:
        r = rasterize_stack(stack, fine)
        kw = r.mesh_kwargs
        for name in peers:
            row = _base(ph, stack, dz, ds, seed, truth)
            res = run_method(name, r.volume, spacing=kw["spacing"], origin=kw["origin"])
            row.update(method=name, caps="", polygon="", status=res["status"], route=f"raster{fine:g}",
                       area=res.get("area"), volume=res.get("volume"), seconds=res.get("seconds"),
                       error=(res.get("error") or "")[:300], faces=res.get("faces"))
            if res["status"] == "ok":
                row.update(area_err=_rel(res["area"], truth[0]),
                           volume_err=_rel(res["volume"], truth[1]) if res.get("volume") is not None else None)
                if res.get("volume") is not None:
                    row.update(_volume_cols(res["volume"], trap, fru, padded, slabs))
            rows.append(row)
    peer_area = {r["method"]: r["area"] for r in rows if r["method"] in PEERS and r["status"] == "ok"}
    # the branching target's reference: surface nets of the solid on an isotropic `fine` grid (the
    # drawing's own raster is `fine` in the plane only, dz along z: its rims are rounded over dz)
    solid_sn = solid_raster(ph, fine)[0] if ph.kind != "analytic" else None
    for row in rows:
        if row["method"] == "ours" and row["status"] == "ok":
            row["area_vs_surfacenets"] = _rel(row["area"], peer_area.get("vtk-surfacenets"))
            row["area_vs_mc_blur1"] = _rel(row["area"], peer_area.get("mc-lewiner-blur1"))
            row["area_solid_surfacenets"] = solid_sn
            row["area_vs_solid_surfacenets"] = _rel(row["area"], solid_sn)
    for row in rows:
        for c in COLUMNS:
            row.setdefault(c, None)
    return rows


# ------------------------------------------------------------------------------------------------
# "any contour file": the rules' interval and the cross-sections, per setting, for stacks without a truth
# ------------------------------------------------------------------------------------------------
#: The settings of the contours route whose rules figures are reported for every drawing and every ROI:
#: ``(label, keywords of contourmesh.mesh)``; ``"default"`` passes none (what a user gets).
RULE_SETTINGS = (("default", {}),
                 ("caps=half", {"caps": "half", "route": "contours"}),
                 ("caps=smooth", {"caps": "smooth", "route": "contours"}),
                 ("caps=smooth bands=curved", {"caps": "smooth", "route": "contours", "bands": "curved"}))

RULE_COLUMNS = ["structure", "sections", "rings", "setting", "status", "route", "volume", "vol_trapezoid",
                "vol_frustum", "vol_outside_rules", "vol_slabs", "vol_vs_slabs", "vol_outside_padded_rules",
                "xsec_max_err", "xsec_worst_side_err", "xsec_checked", "closed_ok", "self_intersections", "faces", "cpu",
                "error"]


def padded_rules(stack) -> tuple[float, float]:
    """``(frustum, trapezoid)`` over the sections' even-odd areas with an empty section one spacing
    beyond each end (the end gap: the stack's first and last gap): the rules' volumes when the
    object is taken to vanish at the next, undrawn plane.  The trapezoid then equals the
    planning systems' slab sum ``sum(area_k * thickness_k)`` on even spacing; the frustum puts a
    cone of height one spacing on each end section."""
    a, z = section_areas(stack), np.array([s.z for s in stack.sections], dtype=np.float64)
    if len(z) == 1:
        g = 1.0
        zp = np.r_[z[0] - g, z, z[0] + g]
    else:
        zp = np.r_[z[0] - (z[1] - z[0]), z, z[-1] + (z[-1] - z[-2])]
    ap = np.r_[0.0, a, 0.0]
    dz = np.diff(zp)
    trap = float(np.sum((ap[1:] + ap[:-1]) / 2 * dz))
    fru = float(np.sum(dz / 3 * (ap[1:] + ap[:-1] + np.sqrt(ap[1:] * ap[:-1]))))
    return fru, trap


def slab_volume(stack) -> float:
    """The planning systems' slab sum: each section's even-odd area times its slab (half the gap to each
    neighbour; the end sections' outer halves take their inner gap)."""
    a, z = section_areas(stack), np.array([s.z for s in stack.sections], dtype=np.float64)
    if len(z) == 1:
        return float("nan")
    g = np.diff(z)
    thick = np.r_[g[0], g] / 2 + np.r_[g, g[-1]] / 2
    return float(np.sum(a * thick))


def _outside(vol, lo, hi):
    lo, hi = min(lo, hi), max(lo, hi)
    return 0.0 if lo <= vol <= hi else ((vol - hi) / hi if vol > hi else (vol - lo) / lo)


def rules_rows(stack, structure: str, *, settings=RULE_SETTINGS, max_planes: int = 40,
               timeout: float | None = 120.0) -> list[dict]:
    """One row (:data:`RULE_COLUMNS`) per setting for any contour stack: the mesh volume against the
    frustum-trapezoid interval over the drawn sections (``vol_outside_rules``, 0 inside), against the
    same rules with an empty plane one spacing beyond each end (``vol_outside_padded_rules``) and the
    slab sum, and the worst cross-section error at the contour planes.  CPU seconds per mesh."""
    import warnings

    from ..api import mesh as _m

    trap, fru = trapezoid_volume(stack), frustum_volume(stack)
    pfru, ptrap = padded_rules(stack)
    slabs = slab_volume(stack)
    rows = []
    for label, kw in settings:
        row = {"structure": structure, "sections": len(stack.sections),
               "rings": sum(len(s.contours) for s in stack.sections), "setting": label,
               "vol_trapezoid": trap, "vol_frustum": fru, "vol_slabs": slabs}
        t0 = time.process_time()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = _with_deadline(lambda: _m(stack, **kw), timeout)
        except Exception as exc:  # a failure is a result
            row.update(status="failed", error=f"{type(exc).__name__}: {exc}"[:300], cpu=time.process_time() - t0)
            rows.append({c: row.get(c) for c in RULE_COLUMNS})
            continue
        cpu = time.process_time() - t0
        chk = m.checks()
        xs = cross_section_errors(m, stack, max_planes=max_planes)
        xw = cross_section_errors(m, stack, max_planes=max_planes, side="worst")
        row.update(status="ok", route=m.meta.get("route"), volume=m.volume,
                   xsec_worst_side_err=float(xw[np.argmax(np.abs(xw))]) if len(xw) else None,
                   vol_outside_rules=_outside(m.volume, fru, trap),
                   vol_vs_slabs=_rel(m.volume, slabs) if slabs == slabs else None,
                   vol_outside_padded_rules=_outside(m.volume, pfru, ptrap),
                   xsec_max_err=float(xs[np.argmax(np.abs(xs))]) if len(xs) else None, xsec_checked=len(xs),
                   closed_ok=bool(chk.get("watertight") and chk.get("winding_consistent")
                                  and chk.get("degenerate_faces", 1) == 0),
                   self_intersections=chk.get("self_intersections"), faces=len(m.faces), cpu=cpu, error="")
        rows.append({c: row.get(c) for c in RULE_COLUMNS})
    return rows
