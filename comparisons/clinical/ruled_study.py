"""Why `caps="smooth"` with ruled bands misses the spheres: the bands, not the caps.

For each sphere drawing of the verification set (default subsample), mesh it with `caps="smooth"`
on the contours route, ruled bands (`polygon=contours` in results.md) and curved bands, and split
the mesh's volume at the end sections' planes: the part between them (the bands) against the
sphere's segment between the same planes, and the parts beyond them (the caps) against the true
polar caps. The part beyond is the integral of the mesh's own cross-section area (4000 heights per
cap); the bands' part is the rest. Also the trapezoid and frustum rules over the drawn sections
against the same segment. All figures in % of the sphere's volume.

Run:  PYTHONPATH=src .venv/bin/python comparisons/clinical/ruled_study.py > comparisons/clinical/ruled_study.md
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

import contourmesh
from contourmesh.compare.clinical import _section_area
from contourmesh.compare.phantoms import draw, frustum_volume, trapezoid_volume, verification_set

SETTINGS = (("ruled", {"caps": "smooth", "route": "contours"}),
            ("curved", {"caps": "smooth", "route": "contours", "bands": "curved"}))


def _segment(R, a, b):
    """Volume of the ball of radius R between the heights a < b (centred at 0)."""
    F = lambda z: math.pi * (R * R * z - z**3 / 3)  # noqa: E731
    return F(b) - F(a)


def _volume_between(m, a, b, n=4000):
    """The mesh's volume between heights a < b: the mean of its cross-section area over n heights."""
    tri = np.asarray(m.vertices, float)[np.asarray(m.faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    z = np.linspace(a, b, n + 1)[1:-1]
    return float(np.mean([_section_area(tri, normals, q) for q in z]) * (b - a))


def main():
    t0 = time.process_time()
    print("# Ruled bands on spheres: where the volume goes\n")
    print(__doc__.split("\n\n")[1].replace("\n", " ") + "\n")
    print("| drawing | sections | poles beyond the end sections (mm) | trapezoid rule (bands' span) | frustum rule "
          "(bands' span) | " + " | ".join(f"{s}: total | {s}: bands | {s}: caps" for s, _ in SETTINGS) + " |")
    print("|---|---|---|---|---|" + "---|---|---|" * len(SETTINGS))
    for ph, dz, ds, seed in verification_set():
        if not ph.name.startswith("sphere"):
            continue
        st = draw(ph, dz, ds, seed=seed)
        zs = [s.z for s in st.sections]
        R, V = ph.params["r"], ph.volume
        seg = _segment(R, zs[0], zs[-1])
        cells = []
        for _, kw in SETTINGS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = contourmesh.mesh(st, **kw)
            lo, hi = float(m.vertices[:, 2].min()), float(m.vertices[:, 2].max())
            caps = _volume_between(m, lo, zs[0]) + _volume_between(m, zs[-1], hi)
            bands = m.volume - caps
            cells.append(f"{100 * (m.volume / V - 1):+.2f} | {100 * (bands - seg) / V:+.2f} | "
                         f"{100 * (caps - (V - seg)) / V:+.2f}")
        print(f"| {ph.name} dz={dz:g} ds={ds:g} | {len(zs)} | {zs[0] + R:.2f} / {R - zs[-1]:.2f} | "
              f"{100 * (trapezoid_volume(st) - seg) / V:+.2f} | {100 * (frustum_volume(st) - seg) / V:+.2f} | "
              + " | ".join(cells) + " |")
    print(f"\n({time.process_time() - t0:.0f} CPU-s)")


if __name__ == "__main__":
    main()
