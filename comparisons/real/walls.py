"""Where the axis-aligned walls of our meshes come from (issue 14, item 5's diagnostic).

    python comparisons/real/walls.py                       (every rotated mesh at 128, both modes)
    python comparisons/real/walls.py --size 64 --meshes bunny,socket --plot bunny-rot:0

A wall is a face whose normal is exactly +-x or +-y (``meta["axis_wall_fraction"]``). It is split in
two kinds by its edges:

* **riser** walls have an edge that stands vertically: two vertices at the same (x, y) in
  consecutive planes, as on the collars of exact joins and the crack rings beside them (a voxel
  staircase), and also where two MLPs have a vertex on the same pixel corner;
* **flat** walls have none: two polygon edges on the same grid line in consecutive slices (an MLP
  runs along a row of pixel corners where the section is nearly parallel to an axis, and so does
  the next slice's where the surface there is nearly vertical).

A mesh with no exact join and no crack ring has no staircase: its walls are the MLP polygons' own
geometry (vertices and edges on the pixel corners' lattice, repeated in the next slice where the
surface is nearly vertical), and such a face stands for a surface within a few degrees of its own
plane, so it carries little excess area.  Only moving the vertices off that lattice removes them
(``refine="band"``).

It prints, per mode, the median and largest share of the area on each kind over the meshes, and
with ``--plot NAME:REPEAT`` draws that mesh from the side with its walls coloured by kind
(``walls-NAME-REPEAT.png`` here, or ``-o``). The inputs are rebuilt as ``real.toml`` builds them;
the meshes come from the shared data folder (env ``CONTOURMESH_DATA``).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import warnings
from pathlib import Path

import numpy as np
import tomllib

HERE = Path(__file__).resolve().parent
MODES = {"paper": {}, "band": {"refine": "band"}}


def _inputs(names, size):
    from contourmesh.compare.inputs import data_dir, mesh_inputs

    spec = tomllib.loads((HERE / "real.toml").read_text())
    for item in spec["inputs"]:
        if item["name"] not in names:
            continue
        for inp in mesh_inputs(item["mesh"], [size], name=item["name"], repeats=int(item.get("repeats", 1)),
                               seed=int(spec["seed"]), offset=bool(item.get("offset", False)),
                               rotate=bool(item.get("rotate", False)), root=data_dir(),
                               placement=item.get("placement", "per-repeat")):
            yield item["name"], inp


def wall_kinds(vertices, faces):
    """Per face: 0 not a wall, 1 a riser wall (an edge standing vertically), 2 a flat wall; and the
    face areas."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    size = np.linalg.norm(n, axis=1)
    tol = 1e-12 * size
    ax, ay, az = np.abs(n).T
    wall = (az <= tol) & ((ax <= tol) | (ay <= tol)) & (size > 0)
    riser = np.zeros(len(f), bool)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = v[f[:, a]] - v[f[:, b]]
        riser |= (d[:, 0] == 0) & (d[:, 1] == 0) & (d[:, 2] != 0)
    kind = np.where(wall, np.where(riser, 1, 2), 0)
    return kind, 0.5 * size


def main(argv=None) -> int:
    import contourmesh

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--meshes", default=None, help="mesh names (rotated inputs), comma-separated (default: all)")
    ap.add_argument("--plot", default=None, help="NAME:REPEAT of the mesh to draw, e.g. bunny-rot:0")
    ap.add_argument("-o", "--out", default=None)
    a = ap.parse_args(argv)

    spec = tomllib.loads((HERE / "real.toml").read_text())
    names = [i["name"] for i in spec["inputs"] if i["name"].endswith("-rot")]
    if a.meshes:
        names = [n if n.endswith("-rot") else n + "-rot" for n in a.meshes.split(",")]
    share = {mode: {"riser": [], "flat": [], "clean": []} for mode in MODES}
    drawn = None
    for name, inp in _inputs(names, a.size):
        vol, sp, org = inp.volume()
        line = [f"{name}:{inp.repeat}"]
        for mode, kw in MODES.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = contourmesh.mesh(vol, spacing=sp, origin=org, **kw)
            kind, area = wall_kinds(m.vertices, m.faces)
            total = area.sum()
            r, fl = area[kind == 1].sum() / total, area[kind == 2].sum() / total
            share[mode]["riser"].append(r)
            share[mode]["flat"].append(fl)
            if not m.meta.get("exact_joins") and not m.meta.get("crack_rings"):
                share[mode]["clean"].append(r + fl)
            line.append(f"{mode}: riser {100 * r:.2f} % flat {100 * fl:.2f} % (exact joins {m.meta.get('exact_joins')}, "
                        f"crack rings {m.meta.get('crack_rings')})")
            if a.plot == f"{name}:{inp.repeat}" and mode == "paper":
                drawn = (m, kind)
        print("  ".join(line), flush=True)
    for mode, d in share.items():
        if d["riser"]:
            print(f"{mode}: riser walls median {100 * statistics.median(d['riser']):.2f} % / largest "
                  f"{100 * max(d['riser']):.2f} %; flat walls median {100 * statistics.median(d['flat']):.2f} % / "
                  f"largest {100 * max(d['flat']):.2f} % of the area ({len(d['riser'])} meshes at {a.size} across)")
            if d["clean"]:
                print(f"{mode}: on the {len(d['clean'])} meshes without exact joins or crack rings, walls median "
                      f"{100 * statistics.median(d['clean']):.2f} % / largest {100 * max(d['clean']):.2f} %")
    if a.plot:
        if drawn is None:
            raise SystemExit(f"--plot {a.plot}: no such mesh among the inputs run")
        _plot(drawn, a.plot, a.size, Path(a.out) if a.out else HERE / f"walls-{a.plot.replace(':', '-')}.png")
    return 0


def _plot(drawn, label, size, out: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    m, kind = drawn
    tri = m.vertices[m.faces]
    colours = np.array(["0.85", "tab:red", "tab:orange"], dtype=object)[kind]
    fig, axs = plt.subplots(1, 2, figsize=(14, 6.5))
    for ax, (i, j), view in ((axs[0], (0, 2), "x-z (walls facing +-y)"), (axs[1], (1, 2), "y-z (walls facing +-x)")):
        facing = 1 if i == 0 else 0  # the walls seen face-on in this view
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        show = (kind == 0) | (np.abs(n[:, facing]) > 0)
        order = np.argsort(tri[show][:, :, 1 - facing].mean(1))  # far to near
        polys = tri[show][order][:, :, [i, j]]
        ax.add_collection(PolyCollection(polys, facecolors=colours[show][order], edgecolor="k", linewidth=0.03))
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_title(f"{label} at {size} across, paper mode: {view}", fontsize=9)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in ("tab:red", "tab:orange", "0.85")]
    fig.legend(handles, ["riser wall (an edge standing vertically)", "flat wall (polygon edges on one grid line)",
                         "other faces"], loc="lower center", ncol=3)
    tmp = out.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=90)
    tmp.replace(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(main())
