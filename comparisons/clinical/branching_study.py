"""Branching phantoms: our area against surface nets of the solid (isotropic 0.25 mm) and of the drawing's raster, per setting.

Run:  PYTHONPATH=src .venv/bin/python comparisons/clinical/branching_study.py > comparisons/clinical/branching_study.md
"""
import time
import warnings

import numpy as np

import contourmesh
from contourmesh.compare.clinical import RULE_SETTINGS, _outside, cross_section_errors, padded_rules, solid_raster
from contourmesh.compare.methods import run_method
from contourmesh.compare.phantoms import draw, frustum_volume, trapezoid_volume, verification_set
from contourmesh.rasterize import rasterize_stack

t0 = time.process_time()
print("| phantom | dz | setting | area vs analytic % | vs surface nets (solid) % | vs surface nets (drawing) % | outside rules % | outside padded rules % | x-sec % | crossings |")
print("|---|---|---|---|---|---|---|---|---|---|")
for ph, dz, ds, seed in verification_set():
    if ph.kind == "analytic":
        continue
    st = draw(ph, dz, ds, seed=seed)
    sn = solid_raster(ph, 0.25)[0]
    r = rasterize_stack(st, 0.25)
    dr = run_method("vtk-surfacenets", r.volume, spacing=r.mesh_kwargs["spacing"], origin=r.mesh_kwargs["origin"])["area"]
    trap, fru = trapezoid_volume(st), frustum_volume(st)
    pad = padded_rules(st)
    for label, kw in RULE_SETTINGS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = contourmesh.mesh(st, **kw)
        xs = cross_section_errors(m, st)
        a = "" if ph.area is None else f"{100 * (m.area / ph.area - 1):+.2f}"
        print(f"| {ph.name} | {dz:g} | {label} | {a} | {100 * (m.area / sn - 1):+.2f} | {100 * (m.area / dr - 1):+.2f} | "
              f"{100 * _outside(m.volume, fru, trap):+.2f} | {100 * _outside(m.volume, *pad):+.2f} | "
              f"{100 * np.abs(xs).max():.3f} | {m.checks()['self_intersections']} |", flush=True)
print(f"\n({time.process_time() - t0:.0f} CPU-s)")
