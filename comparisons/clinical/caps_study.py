"""Cap modes on spheres and cylinders drawn as contours (ds 0.5 mm, meshed as drawn, polygon="none").

Run:  PYTHONPATH=src .venv/bin/python comparisons/clinical/caps_study.py [SEEDS]  (default 5; prints markdown)
"""

import sys

import numpy as np

from contourmesh.compare.phantoms import cylinder, draw, sphere
from contourmesh.surface import stack_to_mesh

CAPS = ("flat", "half", "smooth")


def main(n_seeds: int = 5) -> None:
    families = (("sphere", [sphere(r) for r in (5, 10, 20, 30)]),
                ("cylinder", [cylinder(5, 20), cylinder(15, 40), cylinder(30, 60)]))
    for fam, phantoms in families:
        print(f"\n{fam}s: volume err % [min..max over seeds] / area err %")
        print("| phantom | dz | " + " | ".join(f"{c} vol | {c} area" for c in CAPS) + " |")
        print("|---|---|" + "---|---|" * len(CAPS))
        all_v = {c: [] for c in CAPS}
        all_a = {c: [] for c in CAPS}
        for ph in phantoms:
            for dz in (0.5, 1, 2, 3):
                res = {c: [] for c in CAPS}
                for seed in range(n_seeds):
                    st = draw(ph, dz, 0.5, seed=seed)
                    for c in CAPS:
                        m = stack_to_mesh(st, polygon="none", caps=c)
                        res[c].append((m.volume / ph.volume - 1, m.area / ph.area - 1))
                cells = []
                for c in CAPS:
                    v = np.array(res[c])[:, 0] * 100
                    a = np.array(res[c])[:, 1] * 100
                    all_v[c] += list(v)
                    all_a[c] += list(a)
                    cells += [f"{v.min():+.2f}..{v.max():+.2f}", f"{a.min():+.2f}..{a.max():+.2f}"]
                print(f"| {ph.name} | {dz:g} | " + " | ".join(cells) + " |")
        for c in CAPS:
            v, a = np.abs(all_v[c]), np.abs(all_a[c])
            print(f"{fam} {c}: |vol| median {np.median(v):.2f} max {v.max():.2f}; |area| median {np.median(a):.2f} "
                  f"max {a.max():.2f}; vol<=1%: {(v <= 1).sum()}/{len(v)}, area<=1.5%: {(a <= 1.5).sum()}/{len(a)}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
