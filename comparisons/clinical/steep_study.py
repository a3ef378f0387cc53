"""Steeply tilted short solids at dz = 3 mm: beyond the verification set, where the planar ends fall short.

The verification set tilts its cylinders 30 degrees and its frusta 25 (the keyhole tube 20); there
every slanted end is found and closed on its plane (results.md: within the targets). Steeper and
shorter solids break two assumptions of ``bands.ends``: a join whose two sections are cut by *both*
end planes (the planes overlap in height: a tube r = 6.6, L = 16.6 mm at 58 degrees) follows one
plane and cuts the other's corner, and a cone's narrow end shows one short trace, or none, so
that end stays a dome (frusta at 53 degrees). Each drawing is shifted by fractions of the spacing
(``draw(..., offset=f)``, seed 5, point spacing 0.5 mm); ``ends`` is how many ends were closed on
a plane (``meta["smooth_planar_ends"]``), ``joins`` the joins made next to them.

Run:  PYTHONPATH=src .venv/bin/python comparisons/clinical/steep_study.py > comparisons/clinical/steep_study.md
"""

from __future__ import annotations

import time
import warnings

import numpy as np

import contourmesh
from contourmesh.compare.phantoms import cylinder, draw, frustum

SETTINGS = (("smooth (ruled)", {"caps": "smooth", "route": "contours"}),
            ("smooth + curved", {"caps": "smooth", "route": "contours", "bands": "curved"}))
SHAPES = (cylinder(6.6, 16.6, tilt=58, azimuth=10), frustum(10, 4, 16, tilt=53, azimuth=10),
          frustum(8, 2, 14, tilt=53, azimuth=10))
OFFSETS = (0.1, 0.3, 0.5, 0.7, 0.9)


def main():
    t0 = time.process_time()
    print("# Steeply tilted short solids at dz = 3 mm\n")
    print(" ".join(__doc__.split("\n\n")[1].split()) + "\n")
    print("| drawing | f | sections | " + " | ".join(f"{s}: volume % | {s}: area % | {s}: ends / joins"
                                                   for s, _ in SETTINGS) + " | crossing faces |")
    print("|---|---|---|" + "---|---|---|" * len(SETTINGS) + "---|")
    for ph in SHAPES:
        errs = {s: [] for s, _ in SETTINGS}
        for f in OFFSETS:
            st = draw(ph, 3.0, 0.5, seed=5, offset=f)
            cells, crossings = [], 0
            for s, kw in SETTINGS:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    m = contourmesh.mesh(st, **kw)
                ev, ea = m.volume / ph.volume - 1, m.area / ph.area - 1
                errs[s].append((ev, ea))
                crossings += int(m.checks().get("self_intersections") or 0)
                cells.append(f"{100 * ev:+.2f} | {100 * ea:+.2f} | {m.meta.get('smooth_planar_ends')} / "
                             f"{m.meta.get('smooth_planar_joins')}")
            print(f"| {ph.name} | {f:.1f} | {len(st.sections)} | " + " | ".join(cells) + f" | {crossings} |")
        summary = []
        for s, _ in SETTINGS:
            e = 100 * np.array(errs[s])
            summary.append(f"{e[:, 0].min():+.2f} .. {e[:, 0].max():+.2f} | {e[:, 1].min():+.2f} .. {e[:, 1].max():+.2f} | ")
        print(f"| {ph.name} | range | | " + " | ".join(summary) + " |")
    print(f"\n({time.process_time() - t0:.0f} CPU-s)")


if __name__ == "__main__":
    main()
