"""Compile (and cache on disk) every numba kernel that the README's commands use.

Run by ``scripts/setup.sh`` so that the first ``contourmesh reproduce``, the first mesh of a
clinical contour stack, the first ``--refine band`` and the first volume do not each stop to
compile (about 3 minutes in all on an empty cache on 2 cores, 2026-12-07: the paper's
triangulations 70 s, the contour stack 37 s, ``--refine band`` 21 s, the fast path 8 s, the
general mesher 46 s).  Each step prints one line to stderr.  Only public entry points are
called, on small inputs, so the script follows the package as it changes.

    python scripts/warm_kernels.py            # exit status 1 if a step failed
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _say(msg: str) -> None:
    print(f"setup: {msg}", file=sys.stderr, flush=True)


def _reproduce():
    """contourmesh reproduce: outer Jordan stacks -> DSS / MLP polygons -> every triangulation."""
    import contourmesh
    from contourmesh.shapes import Ellipsoid, Sphere

    for shape in (Sphere(6, center=(0.31, 0.17, 0.43)), Ellipsoid(7, 4, 4)):
        for polygon in ("dss", "mlp"):
            for tri in ("wiederhold", "greedy", "optimal", "arclength"):
                contourmesh.mesh(shape, polygon=polygon, triangulation=tri)


def _contour_stack():
    """A clinical contour stack (the RTSTRUCT route): rings in mm, rasterized even-odd, meshed."""
    import contourmesh

    slices = []
    for k, z in enumerate(np.arange(-6.0, 6.5, 1.5)):
        t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        r = 8.0 * np.sqrt(max(1e-3, 1 - (z / 7.0) ** 2))
        outer = np.column_stack([r * np.cos(t), 0.8 * r * np.sin(t)])
        rings = [outer.round(3).tolist()]
        if k in (3, 4, 5):  # a hole in the middle slices
            rings.append((0.3 * outer[::-1]).round(3).tolist())
        slices.append({"z": float(z), "rings": rings})
    doc = {"format": "contourmesh.contours", "version": 1, "units": "mm", "name": "warm-up", "slices": slices}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "warm.contours.json"
        path.write_text(json.dumps(doc))
        contourmesh.mesh(str(path))


def _refine_band():
    """--refine band on a shape and on volumes (the stack route and the volume mesher)."""
    import contourmesh
    from contourmesh.shapes import Sphere

    contourmesh.mesh(Sphere(8, center=(0.31, 0.17, 0.43)), polygon="mlp", triangulation="optimal", refine="band")
    ball = np.zeros((14, 14, 14), dtype=bool)
    zz, yy, xx = np.mgrid[:14, :14, :14]
    ball[(zz - 6.6) ** 2 + (yy - 6.3) ** 2 + (xx - 6.8) ** 2 < 25] = True
    contourmesh.mesh(ball, refine="band")
    tunnel = np.zeros((9, 12, 12), dtype=bool)  # slices with holes: the volume mesher refines its polygons
    tunnel[1:8, 2:10, 2:10] = True
    tunnel[1:8, 5:7, 5:7] = False
    contourmesh.mesh(tunnel, refine="band")


def _fast_path():
    """A simple binary volume (one contour per slice): the fast path."""
    import contourmesh

    contourmesh.mesh(np.pad(np.ones((3, 4, 5), dtype=bool), 1))


def _general_mesher():
    """A volume with a hole, branching and a cavity: the general volume mesher, its exact and sectioned joins."""
    import contourmesh

    v = np.zeros((9, 12, 12), dtype=bool)
    v[1:8, 2:10, 2:10] = True
    v[1:8, 5:7, 5:7] = False  # a tunnel: slices with holes
    v[4, 3:9, 3:9] = True  # ... closed in one slice: branching above and below
    v[2:4, 3, 8] = False  # a small cavity
    contourmesh.mesh(v)
    labels = np.zeros((6, 8, 8), dtype=np.uint8, order="F")  # (Fortran order: volume_input's copy)
    labels[1:5, 1:7, 1:4] = 3
    labels[1:5, 1:7, 5:7] = 7
    contourmesh.mesh(labels, label=7, spacing=(2.0, 1.0, 1.0))
    # a small random volume: forks and merges whose bridged joins take intermediate sections (their
    # signed distances and topology counts are compiled too)
    contourmesh.mesh(np.pad(np.random.default_rng(1).random((8, 9, 9)) < 0.4, 1))
    # the bridged joins' rare paths (a polyline keyhole; bridge_tree's Python loop)
    from contourmesh.bands.bridges import warm_rare_paths
    from contourmesh.sections import warm_rare_kernels

    warm_rare_paths()
    warm_rare_kernels()  # (the sections' early topology test: loops of overlaps)
    # the manifold repair's necks opened all at once (real volumes have hundreds; these, a few)
    from contourmesh.repair import warm_neck_kernels

    warm_neck_kernels()


def _checks():
    """Mesh.checks() (and --json): the self-intersection test; and the manifold repair's edge
    kernels on threads (CONTOURMESH_THREADS > 1, large meshes)."""
    import contourmesh
    from contourmesh import repair

    m = contourmesh.mesh(np.pad(np.ones((2, 2, 2), dtype=bool), 1))
    m.checks()
    repair._half_edge_twins_threads(m.faces, len(m.vertices), 2)
    repair._four_face_edges_threads(m.faces, len(m.vertices), 2)


STEPS = (
    ("reproduce: DSS and MLP polygons, every triangulation", _reproduce),
    ("clinical contour stack (RTSTRUCT route: rasterize, mesh)", _contour_stack),
    ("refine='band' (--refine band)", _refine_band),
    ("volume fast path", _fast_path),
    ("general volume mesher (holes, branching, cavities, labels)", _general_mesher),
    ("mesh checks (self-intersection test)", _checks),
)


def main() -> int:
    import warnings

    failed = 0
    for n, (what, fn) in enumerate(STEPS, 1):
        _say(f"compiling kernels {n}/{len(STEPS)}: {what} ...")
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fn()
        except Exception as exc:  # noqa: BLE001 - report and go on: a later call compiles instead
            failed += 1
            _say(f"  failed ({type(exc).__name__}: {exc}); the first such call will compile instead")
            continue
        _say(f"  done in {time.perf_counter() - t0:.1f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
