"""Command line: ``contourmesh reproduce`` and ``contourmesh mesh``.

Errors print one line to stderr and exit with status 2 (``--debug`` shows the traceback).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

__all__ = ["main"]


def _mesh_summary(m) -> dict:
    chk = m.checks()
    area = m.area
    area_true = m.meta.get("area_true")
    e = (area - area_true) / area_true if area_true else None
    return {
        "area": area,
        "volume": chk["volume"],
        "P": int(m.P),
        "vertices": int(len(m.vertices)),
        "faces": int(len(m.faces)),
        "watertight": chk["watertight"],
        "winding_consistent": chk["winding_consistent"],
        "boundary_edges": chk["boundary_edges"],
        "degenerate_faces": chk["degenerate_faces"],
        "components": chk["components"],
        "genus": chk["genus"],
        "area_true": area_true,
        "volume_true": m.meta.get("volume_true"),
        "e": e,
        "t": abs(e) * m.P if e is not None else None,
        "polygon": m.meta.get("polygon"),
        "triangulation": m.meta.get("triangulation"),
        "refine": m.meta.get("refine", "none"),
    }


def _cmd_reproduce(args) -> int:
    from .compare.paper import reproduce

    reproduce(args.out, progress=not args.quiet)
    return 0


def _cmd_mesh(args) -> int:
    from .surface import mesh

    out = Path(args.output)
    if out.exists() and not args.force:
        raise FileExistsError(f"output file {str(out)!r} already exists (use --force to overwrite)")
    roi = int(args.roi) if args.roi is not None and args.roi.isdigit() else args.roi
    spacing = tuple(float(v) for v in args.spacing.split(",")) if args.spacing else (1.0, 1.0, 1.0)
    extra = {"refine": args.refine} if args.refine else {}
    m = mesh(args.source, polygon=args.polygon, triangulation=args.triangulation, caps=args.caps, **extra, roi=roi, pixel=args.pixel, label=args.label, threshold=args.threshold,
             axis=args.axis, spacing=spacing, progress=not args.quiet)
    infos = []
    posts = list(args.post or []) + [f"mlx:{p}" for p in (args.mlx or [])]
    if posts:
        from .compare.postprocess import apply_postprocess

        for name in posts:
            m, info = apply_postprocess(name, m)
            infos.append(info)
    if args.save_mlx:
        from .compare.postprocess import MESHLAB_STEPS, save_filter_script

        steps = [p.split("-")[0] if p.startswith("meshlab-") else p for p in (args.post or [])]
        steps = [s for s in steps if s in MESHLAB_STEPS]
        if not steps:
            raise ValueError(f"--save-mlx needs MeshLab post-processes among --post; MeshLab steps: {sorted(MESHLAB_STEPS)}")
        save_filter_script(steps, args.save_mlx)
    chk = m.checks()
    if not chk["ok"]:
        raise RuntimeError(f"the mesh failed its checks, not written: {chk}")
    m.save(out, force=True)
    summary = _mesh_summary(m)
    if infos:
        summary["postprocess"] = infos
    if args.json:
        print(json.dumps(summary, sort_keys=True))
    else:
        e = summary["e"]
        print(f"{out}: area {summary['area']:.6g}" + (f" (true {summary['area_true']:.6g}, e {e:+.4%})" if e is not None else "")
              + f", P {summary['P']}, {summary['faces']} faces, closed and outward")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = argparse.ArgumentParser(prog="contourmesh", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"contourmesh {__version__}")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("reproduce", help="reproduce the paper's Tables 1-2 and Figures 2-3")
    r.add_argument("--out", default=None, help="output folder (default: comparisons/paper/)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_reproduce)

    m = sub.add_parser("mesh", help="mesh a source and write a mesh file")
    m.add_argument("source", help="a shape spec NAME:key=value,... (sphere:r=40, torus:R=30,r=9) or a file: "
                   "volumes .npy .npz .tif .nii[.gz] .vol .inr[.gz]; contours .json .dcm (RTSTRUCT)")
    m.add_argument("-o", "--output", required=True, help="output mesh file (.ply, .obj, .stl, .off)")
    m.add_argument("--polygon", default="mlp", choices=["dss", "mlp", "none"])
    m.add_argument("--triangulation", default=None, choices=["wiederhold", "greedy", "optimal", "arclength"],
                   help="band triangulation (default: wiederhold, or optimal with --refine band)")
    m.add_argument("--caps", default="flat", choices=["flat", "half"])
    m.add_argument("--refine", default=None, choices=["none", "band"],
                   help="band: the multigrid-convergent refinement of the polygons across slices")
    m.add_argument("--roi", default=None, help="RTSTRUCT structure: name or number")
    m.add_argument("--pixel", type=float, default=None, help="pixel size for rasterizing contour files")
    m.add_argument("--label", type=int, default=None, help="use the voxels equal to this label")
    m.add_argument("--threshold", type=float, default=None, help="use the voxels above this value")
    m.add_argument("--axis", type=int, default=0, choices=[0, 1, 2], help="slicing axis of a volume")
    m.add_argument("--spacing", default=None, help="dz,dy,dx for .npy volumes without spacing")
    m.add_argument("--quiet", action="store_true", help="no progress bar")
    m.add_argument("--post", action="append", help="post-process, repeatable: merge-coplanar, taubin, "
                   "meshlab-planar-qec, mlx:FILE")
    m.add_argument("--mlx", action="append", help="apply a MeshLab filter script (.mlx) to the mesh")
    m.add_argument("--save-mlx", default=None, help="save the MeshLab filters among --post as an .mlx script")
    m.add_argument("--json", action="store_true", help="print a JSON summary")
    m.add_argument("--force", action="store_true", help="overwrite an existing output file")
    m.set_defaults(func=_cmd_mesh)

    from .compare.runner import add_compare_parser

    add_compare_parser(sub)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("contourmesh: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # one line unless --debug
        if args.debug:
            raise
        print(f"contourmesh: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
