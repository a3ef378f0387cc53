"""Hash the meshes contourmesh makes of a fixed set of inputs (shared samples, shapes, contour files).

Used to show that a refactoring changes no mesh: run it before and after and compare the outputs::

    python scripts/mesh_digest.py > before.txt   # ... change the code ...
    python scripts/mesh_digest.py > after.txt && diff before.txt after.txt

The inputs: analytic shapes in every polygon, triangulation and cap mode and with the band
refinement (also on oblong pixels and on unevenly spaced slices), random volumes, drawn contour
stacks on the contours route (flat and smooth caps, ruled and curved bands), the shared samples
and the RT structure set.  Each line is ``input | options | sha1 of vertices and faces | area``.  Inputs from the shared
sample data are read from ``$CONTOURMESH_DATA`` (default ``../shared/data``) and skipped when absent.
"""

from __future__ import annotations

import hashlib
import os
import sys
import warnings
from pathlib import Path

import numpy as np

import contourmesh
from contourmesh.shapes import Ellipsoid, Sphere, Torus

DATA = Path(os.environ.get("CONTOURMESH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def digest(m) -> str:
    h = hashlib.sha1()
    h.update(np.ascontiguousarray(m.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(m.faces, dtype=np.int64).tobytes())
    return h.hexdigest()[:16]


def cases():
    modes = [dict(), dict(polygon="none"), dict(polygon="dss"), dict(triangulation="optimal"),
             dict(triangulation="arclength"), dict(triangulation="greedy"), dict(caps="half")]
    shapes = {"sphere20": Sphere(20, center=(0.31, 0.17, 0.43)),
              "ellipsoid": Ellipsoid(18, 12, 9, center=(0.2, 0.3, 0.1)),
              "torus": Torus(14, 5, center=(0.3, 0.1, 0.2))}
    for name, s in shapes.items():
        for mo in modes:
            yield name, mo, (lambda s=s, mo=mo: contourmesh.mesh(s, **mo))
        yield name, {"refine": "band"}, (lambda s=s: contourmesh.mesh(s, refine="band"))
    # band refinement on oblong pixels and on unevenly spaced slices
    oblong = (0.9, 0.617, 0.667)
    yield "ball12-oblong", {"refine": "band", "spacing": oblong}, \
        (lambda: contourmesh.mesh(_ball_mask(12.0, oblong)[0], spacing=oblong, refine="band"))
    mask_u, zs_u = _ball_mask(12.0, (1.0, 1.0, 1.0), zs=_uneven_heights(12.0))
    yield "ball12-uneven", {"refine": "band", "z": "uneven"}, \
        (lambda: contourmesh.mesh(mask_u, spacing=(1.0, 1.0, 1.0), z=zs_u, refine="band"))
    # drawn contours on the contours route: ruled bands with flat and smooth caps, curved bands
    from contourmesh.compare.phantoms import draw, sphere, y_branch

    for pname, ph in (("drawn-sphere-r5", sphere(5.0)), ("drawn-Y", y_branch(5.0, 25.0, 30.0))):
        for dzs in (1.0, 3.0):
            for mo in ({"route": "contours"}, {"route": "contours", "caps": "smooth"},
                       {"route": "contours", "caps": "smooth", "bands": "curved"}):
                yield f"{pname}-dz{dzs:g}", mo, (lambda ph=ph, dzs=dzs, mo=mo: contourmesh.mesh(draw(ph, dzs, 0.5), **mo))
    rng = np.random.default_rng(7)
    for k in range(6):
        v = rng.random((12, 14, 13)) < 0.35
        for mo in modes[:3]:
            yield f"random{k}", mo, (lambda v=v, mo=mo: contourmesh.mesh(np.pad(v, 1), **mo))
    vols = DATA / "volumes" / "dgtal"
    files = [("Al.100.vol", {}), ("bunny-64.vol", {"threshold": 0}), ("bunny-128.vol", {"threshold": 0}), ("cat10.vol", {"threshold": 0}),
             ("lobsterCroped.vol", {"threshold": 60}), ("lobster.vol", {"threshold": 60})]
    for fname, sel in files:
        p = vols / fname
        if not p.is_file():
            continue
        for mo in modes[:4]:
            if fname == "lobster.vol" and mo:
                continue
            yield fname, dict(sel, **mo), (lambda p=p, sel=sel, mo=mo: _padded(p, sel, mo))
    liver = DATA / "volumes" / "cgogn" / "liver.inr.gz"
    if liver.is_file() and "--quick" not in sys.argv:
        yield "liver.inr.gz", {"label": 127}, (lambda: contourmesh.mesh(str(liver), label=127))
    rt = DATA / "contours" / "dicompyler-core" / "rtss.dcm"
    if rt.is_file():
        for roi in ("Lt Lung", "Heart", "Tumor Bed"):
            for mo in modes[:2]:
                yield f"rtss:{roi}", mo, (lambda roi=roi, mo=mo: contourmesh.mesh(str(rt), roi=roi, **mo))


def _ball_mask(r, spacing, zs=None, center=(0.31, 0.17, 0.43)):
    """The grid points of a ball inside ``(dz, dy, dx)`` spacing (or at the heights ``zs``)."""
    dz, dy, dx = spacing
    xs = np.arange(-r - 3 * dx, r + 3 * dx, dx)
    ys = np.arange(-r - 3 * dy, r + 3 * dy, dy)
    zs = np.arange(-r - 3 * dz, r + 3 * dz, dz) if zs is None else np.asarray(zs, dtype=np.float64)
    Z, Y, X = np.meshgrid(zs, ys, xs, indexing="ij")
    c = center
    return (X - c[0]) ** 2 + (Y - c[1]) ** 2 + (Z - c[2]) ** 2 <= r * r, zs


def _uneven_heights(r):
    z = np.cumsum(np.tile([0.6, 1.3, 0.9], int(2 * r) + 4)) - r - 3.0
    return z[z < r + 3.0]


def _padded(path, sel, mo):
    from contourmesh.io import read_volume

    vol, spacing, origin = read_volume(path, **sel)
    return contourmesh.mesh(np.pad(vol, 1), spacing=spacing, **mo)


def main() -> int:
    warnings.simplefilter("ignore")
    for name, mo, make in cases():
        opts = ",".join(f"{k}={v}" for k, v in sorted(mo.items())) or "default"
        try:
            m = make()
            print(f"{name} | {opts} | {digest(m)} | {m.area:.9g}", flush=True)
        except Exception as exc:  # a failure is a line of the digest too
            print(f"{name} | {opts} | error {type(exc).__name__}: {str(exc)[:80]}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
