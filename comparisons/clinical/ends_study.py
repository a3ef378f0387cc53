"""Where the drawing holds the information: flat ends, and the same shape shifted by a fraction of a spacing.

A contouring tool draws a section on every plane ``z0 + k dz`` that cuts the object; the
verification set picks ``z0`` at random (uniform within one spacing), so a flat end lies anywhere
between 0 and ``dz`` beyond its last section.  This study

1. shifts each shape by fractions of a spacing (``draw(..., offset=f)``, ``f = 0.05 .. 0.95``) and
   tabulates our volume and area errors per setting: for a flat-ended solid they follow the end's
   unknown position (the mean over shifts is the bias, the spread the information limit); for a
   smooth solid they stay small at every shift;
2. draws cylinders of different lengths that give the *same* drawing (six identical circles
   3 mm apart, for any length in (15, 21) mm): one mesh, several truths;
3. reports, per shift, how far beyond the last sections the true ends lie.

Run:  PYTHONPATH=src .venv/bin/python comparisons/clinical/ends_study.py > comparisons/clinical/ends_study.md
"""

from __future__ import annotations

import time
import warnings

import numpy as np

import contourmesh
from contourmesh.compare.phantoms import cylinder, draw, frustum, section_areas, sphere

SETTINGS = (("flat", {}), ("half", {"caps": "half", "route": "contours"}),
            ("smooth", {"caps": "smooth", "route": "contours"}),
            ("smooth+curved", {"caps": "smooth", "route": "contours", "bands": "curved"}))
SHIFTS = np.round(np.arange(0.05, 1.0, 0.1), 2)


def _mesh(st, kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return contourmesh.mesh(st, **kw)


def shifted(ph, dz, ds=0.5, seed=3):
    print(f"\n### {ph.name} at dz = {dz:g} mm, shifted by a fraction f of the spacing\n")
    print("`below`, `above`: distance (mm) from the lowest / highest section to the solid's end along z "
          "(the half-spacing convention assumes dz/2 each).\n")
    print("| f | sections | below | above | " + " | ".join(f"{s} vol % | {s} area %" for s, _ in SETTINGS) + " |")
    print("|---|---|---|---|" + "---|---|" * len(SETTINGS))
    errs = {s: [] for s, _ in SETTINGS}
    for f in SHIFTS:
        st = draw(ph, dz, ds, seed=seed, offset=float(f))
        zs = [s.z for s in st.sections]
        cells = []
        for s, kw in SETTINGS:
            m = _mesh(st, kw)
            ev, ea = m.volume / ph.volume - 1, m.area / ph.area - 1
            errs[s].append((ev, ea))
            cells.append(f"{100 * ev:+.2f} | {100 * ea:+.2f}")
        print(f"| {f:.2f} | {len(zs)} | {zs[0] - ph.lo[2]:.2f} | {ph.hi[2] - zs[-1]:.2f} | " + " | ".join(cells) + " |")
    line = []
    for s, _ in SETTINGS:
        e = 100 * np.array(errs[s])
        line.append(f"{e[:, 0].mean():+.2f} [{e[:, 0].min():+.2f}, {e[:, 0].max():+.2f}] | "
                    f"{e[:, 1].mean():+.2f} [{e[:, 1].min():+.2f}, {e[:, 1].max():+.2f}]")
    print("| mean [min, max] | | | | " + " | ".join(line) + " |")
    return errs


def same_drawing(r=5.0, dz=3.0, n=6, lengths=(15.3, 16.5, 18.0, 19.5, 20.0, 20.7), ds=0.5, seed=3):
    span = (n - 1) * dz
    print(f"\n### One drawing, several truths: cylinders r = {r:g} mm of length L drawn with {n} sections "
          f"{dz:g} mm apart\n")
    print(f"For any L in ({span:g}, {span + 2 * dz:g}) mm the planes {dz:g} mm apart can cut the cylinder in "
          f"exactly {n} circles, {span:g} mm from first to last; the drawings below differ only in "
          "round-off (the largest difference of any section's area is listed).\n")
    print("| L (mm) | max section area difference (mm^2) | " + " | ".join(f"{s} volume (mm^3) | {s} vol err %"
                                                                    for s, _ in SETTINGS) + " |")
    print("|---|---|" + "---|---|" * len(SETTINGS))
    ref = None
    for L in lengths:
        ph = cylinder(r, L)
        off = (L / 2 - span / 2) / dz  # the first plane at z = -span / 2
        st = draw(ph, dz, ds, seed=seed, offset=off)
        assert len(st.sections) == n, (L, len(st.sections))
        a = section_areas(st)
        ref = a if ref is None else ref
        cells = []
        for s, kw in SETTINGS:
            m = _mesh(st, kw)
            cells.append(f"{m.volume:.1f} | {100 * (m.volume / ph.volume - 1):+.2f}")
        print(f"| {L:g} | {np.abs(a - ref).max():.2e} | " + " | ".join(cells) + " |")


def main():
    t0 = time.process_time()
    print("# Ends of drawn solids: what the contours say, and what they cannot say")
    print("\nOutput of `PYTHONPATH=src .venv/bin/python comparisons/clinical/ends_study.py` "
          "(point spacing 0.5 mm, seed 3; `flat` is the default, `half`/`smooth` `route=\"contours\"`).")
    same_drawing()
    for ph, dz in ((cylinder(5, 20), 3.0), (cylinder(15, 40), 3.0), (frustum(10, 0, 20), 2.0),
                   (sphere(5), 3.0), (sphere(10), 3.0)):
        shifted(ph, dz)
    print(f"\n({time.process_time() - t0:.0f} CPU-s)")


if __name__ == "__main__":
    main()
