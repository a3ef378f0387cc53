"""Command line: ``contourmesh mesh``, ``contourmesh reproduce`` and ``contourmesh compare``.

Errors print one line to stderr and exit with status 2 (``--debug`` shows the traceback).
Messages name the command-line flags (``--label``), not the Python keywords (``label=``).
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
from pathlib import Path

__all__ = ["main", "build_parser"]

DESCRIPTION = """\
Closed triangle meshes and surface-area estimates from serial cross-sections
(Wiederhold & Villafuerte 2009), and a harness that compares them with other methods.

commands:
  mesh SOURCE -o FILE    mesh a shape spec, a volume file or a contour file and write the mesh
  reproduce              reproduce the paper's Tables 1-2 and Figures 2-3
  compare SPEC.toml      run a comparison (every method on the same inputs): tables and plots
"""

SHAPES_HELP = """\
shape specs: NAME:key=value,... with NAME one of sphere:r, ellipsoid:a,b,c, spheroid:a,b,
torus:R,r, cone:r0,r1,height, hyperboloid:a,c,height, paraboloid:a,height; placement keys
center=x;y;z and rotation=ax;ay;az, three angles in degrees applied about the x axis first,
then y, then z (R = Rz Ry Rx), or nine numbers giving the rotation matrix row by row.
Example: "torus:R=30,r=9,center=0.3;0.1;0.2,rotation=30;0;0".

volume files: .npy .npz .tif .nii[.gz] .nrrd .seg.nrrd .vol .inr[.gz], DICOM-SEG and DICOM images
(.dcm; a folder of DICOM slices is read as one series), indexed [z, y, x] once read;
meshes of NIfTI, NRRD and DICOM files are in the image's world coordinates (its affine applied;
DICOM: patient LPS); a volume with exactly two values (0/255) is binary, others need --label or
--threshold.
contour files: DICOM RTSTRUCT (.dcm, pick a structure with --roi), .json contour stacks.
A .dcm file goes by its Modality: RTSTRUCT is contours, SEG and images are volumes.
Areas are in the square of the file's (or --spacing's) unit.
"""

#: Python keywords that the command line spells as flags.
_FLAGS = ("roi", "label", "threshold", "pixel", "route", "spacing", "axis", "refine", "polygon", "triangulation", "caps", "h",
          "halo")
_KEYWORD = re.compile(r"\b(" + "|".join(_FLAGS) + r")=(?=[\s,;.)'\"]|$)")


def _cli_words(message: str) -> str:
    """A library message with its keywords (``label=``) spelled as the CLI's flags (``--label``)."""
    return _KEYWORD.sub(lambda m: "--" + m.group(1), message)


def _spacing(text: str) -> tuple:
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three numbers dz,dy,dx; got {text!r}") from None
    if len(values) != 3 or not all(v > 0 and v < float("inf") for v in values):
        raise argparse.ArgumentTypeError(f"expected three positive numbers dz,dy,dx; got {text!r}")
    return values


def _number(text: str):
    """A threshold: an int when it is one (so messages say 7, not 7.0)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number; got {text!r}") from None
    return int(value) if value.is_integer() else value


def _label(text: str):
    """A label: a number, or a segment's name in a .seg.nrrd or DICOM-SEG file."""
    try:
        return _number(text)
    except argparse.ArgumentTypeError:
        return text


def _mesh_summary(m) -> dict:
    from .measure import relative_error, tradeoff

    chk = m.checks()
    area_true = m.meta.get("area_true")
    e = relative_error(m.area, area_true)
    summary = {
        "area": m.area,
        "volume": chk["volume"],
        "P": int(m.P),
        "vertices": int(len(m.vertices)),
        "faces": int(len(m.faces)),
        "area_true": area_true,
        "volume_true": m.meta.get("volume_true"),
        "e": e,
        "t": tradeoff(e, m.P) if e is not None else None,
        "polygon": m.meta.get("polygon"),
        "triangulation": m.meta.get("triangulation"),
        "refine": m.meta.get("refine", "none"),
        "route": m.meta.get("route"),
    }
    for key in ("watertight", "winding_consistent", "boundary_edges", "degenerate_faces", "components", "genus",
                "self_intersections", "closed", "ok"):
        if key in chk:
            summary[key] = chk[key]
    for key in ("axis_wall_fraction", "exact_joins", "bridged_joins", "bridges", "intermediate_sections", "band_joins",
                "polygon_fallbacks", "crack_rings",
                "band_fallbacks", "pixel", "space"):
        if key in m.meta:  # where the mesh came from: the diagnostics of its route
            summary[key] = m.meta[key]
    return summary


def _cmd_reproduce(args) -> int:
    from .compare.paper import reproduce

    res = reproduce(args.out, progress=not args.quiet, echo=print)
    print(f"wrote {Path(res['out']).resolve()}")
    return 0


def _check_output(out: Path, force: bool) -> None:
    """Refuse an output path that cannot be written, before any meshing."""
    from .meshes import MESH_FORMATS

    if out.suffix.lower().lstrip(".") not in MESH_FORMATS:
        raise ValueError(f"output file {str(out)!r}: expected a suffix among "
                         f"{', '.join('.' + f for f in MESH_FORMATS)}")
    if out.is_dir():
        raise IsADirectoryError(f"output {str(out)!r} is a directory; expected a mesh file name")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"the output folder {str(out.parent)!r} does not exist")
    if out.exists() and not force:
        raise FileExistsError(f"output file {str(out)!r} already exists (use --force to overwrite)")


def _cmd_mesh_many(args) -> int:
    """``--all-labels`` / ``--all-rois`` / several ``--roi``: one mesh file per object and a table."""
    import csv
    import io

    from .api import label_row, mesh_file_labels, mesh_file_rois
    from .meshes import atomic_write

    for flag, value in (("--post", args.post), ("--mlx", args.mlx), ("--save-mlx", args.save_mlx),
                        ("--label", args.label), ("--threshold", args.threshold), ("--json", args.json or None)):
        if value:
            raise ValueError(f"{flag} does not apply when meshing several objects at once")
    if args.all_labels and (args.roi or args.all_rois or args.pixel is not None or args.route is not None
                            or args.bands is not None):
        raise ValueError("--all-labels is for label volumes; --roi, --all-rois, --pixel, --route and --bands are for "
                         "contour files")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"-o {str(out)!r}: several objects need an output folder, and this is a file")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"the output folder's parent {str(out.parent)!r} does not exist")
    from .scale import cli_wants_chunked, run_cli_chunked

    if cli_wants_chunked(args):  # a chunked store, or --jobs/--scheduler/--cache: the two-pass route
        return run_cli_chunked(args, out)
    out.mkdir(exist_ok=True)
    fmt = args.format.lstrip(".")
    method = dict(polygon=args.polygon, triangulation=args.triangulation, caps=args.caps, refine=args.refine,
                  progress=not args.quiet)
    if args.all_labels:
        table = "labels.csv"
        objects = ((lab, m, bbox) for lab, m, bbox in mesh_file_labels(args.source, spacing=args.spacing, **method))
    else:
        table = "rois.csv"
        rois = None if args.all_rois else [int(r) if r.isdigit() else r for r in args.roi]
        objects = ((name, m, None) for name, m in mesh_file_rois(args.source, rois=rois, pixel=args.pixel,
                                                                    route=args.route, bands=args.bands, **method))
    rows, failed = [], 0
    while True:
        try:
            key, m, bbox = next(objects)
        except StopIteration:
            break
        if bbox is not None:
            row = label_row(key, m, bbox)
            name = f"label_{key}"
        else:
            chk = m.checks()
            row = {"roi": key, "area": m.area, "volume": chk["volume"], "P": int(m.P), "faces": int(len(m.faces)),
                   "genus": chk["genus"], "components": chk["components"], "watertight": chk["watertight"],
                   "self_intersections": chk.get("self_intersections", ""), "route": m.meta.get("route")}
            name = re.sub(r"[^A-Za-z0-9._-]+", "_", str(key)).strip("_") or "roi"
        chk = m.checks()
        ok = chk["closed"]
        row["status"] = ("ok" if chk["ok"] else f"closed, {chk['self_intersections']} crossing face pairs") if ok \
            else "not closed and outward (not written)"
        failed += not ok
        if ok and not args.stats_only:
            target = out / f"{name}.{fmt}"
            if target.exists() and not args.force:
                raise FileExistsError(f"output file {str(target)!r} already exists (use --force to overwrite)")
            m.save(target, force=True)
            row["file"] = target.name
        rows.append(row)
    if not rows:
        raise ValueError(f"{args.source!r}: nothing to mesh")
    buf = io.StringIO()
    fields = list(dict.fromkeys(k for r in rows for k in r))
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write(out / table, buf.getvalue().encode(), force=True)
    print(f"wrote {(out / table).resolve()}: {len(rows)} objects" + ("" if args.stats_only else f", one .{fmt} each")
          + (f"; {failed} failed their checks" if failed else ""))
    return 1 if failed else 0


def _cmd_mesh(args) -> int:
    from .api import mesh

    if args.all_labels or args.all_rois or len(args.roi or []) > 1:
        return _cmd_mesh_many(args)
    if args.stats_only:
        raise ValueError("--stats-only applies with --all-labels, --all-rois or several --roi")
    for flag in ("jobs", "scheduler", "cache", "max_box_voxels", "halo"):
        if getattr(args, flag, None) is not None:
            raise ValueError(f"--{flag.replace('_', '-')} applies with --all-labels only")
    out = Path(args.output)
    _check_output(out, args.force)
    posts = list(args.post or []) + [f"mlx:{p}" for p in (args.mlx or [])]
    steps = None
    if posts or args.save_mlx:  # an unknown post-process or a file that is not a script fails before meshing
        from .compare.postprocess import get_postprocess, meshlab_steps_of

        for name in posts:
            get_postprocess(name)
        if args.save_mlx:
            steps = meshlab_steps_of(args.post or [])
    roi = args.roi[0] if args.roi else None
    roi = int(roi) if roi is not None and roi.isdigit() else roi
    m = mesh(args.source, polygon=args.polygon, triangulation=args.triangulation, caps=args.caps,
             refine=args.refine, roi=roi, pixel=args.pixel, route=args.route, label=args.label, threshold=args.threshold,
             axis=args.axis, spacing=args.spacing, bands=args.bands, progress=not args.quiet)
    infos = []
    if posts:
        from .compare.postprocess import apply_postprocess

        for name in posts:
            m, info = apply_postprocess(name, m)
            infos.append(info)
    if args.save_mlx:
        from .compare.postprocess import save_filter_script

        save_filter_script(steps, args.save_mlx)
    chk = m.checks()
    if not chk["closed"]:
        raise RuntimeError(f"the mesh failed its checks, not written: {chk}")
    m.save(out, force=True)
    if chk["self_intersections"]:
        print(f"contourmesh: warning: {out}: {chk['self_intersections']} pairs of faces cross (the mesh is closed and "
              "outward but not embedded; a known limit of joins where voxels touch only along an edge or at a corner)",
              file=sys.stderr)
    summary = _mesh_summary(m)
    if infos:
        summary["postprocess"] = infos
    if args.json:
        print(json.dumps(summary, sort_keys=True))
    else:
        e = summary["e"]
        print(f"{out}: area {summary['area']:.6g}" + (f" (true {summary['area_true']:.6g}, e {e:+.4%})" if e is not None else "")
              + f", volume {summary['volume']:.6g}, P {summary['P']}, {summary['faces']} faces, closed and outward"
              + ("" if summary.get("self_intersections") else ", no crossing faces"))
    return 0


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Every option's default in its help (unless the help states it, or there is none to state);
    descriptions keep their line breaks."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "default" in text or action.default in (None, False, argparse.SUPPRESS) or not action.option_strings:
            return text
        return text + " (default: %(default)s)"


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks on errors")
    common.add_argument("--verbose", "-v", action="store_true", default=argparse.SUPPRESS,
                        help="log every route choice and fallback on stderr")

    p = argparse.ArgumentParser(prog="contourmesh", description=DESCRIPTION, formatter_class=_Formatter,
                                parents=[common])
    p.add_argument("--version", action="version", version=f"contourmesh {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="{mesh,reproduce,compare}")

    m = sub.add_parser("mesh", help="mesh a source and write a mesh file", parents=[common],
                       description="Mesh a shape spec, a volume file or a contour file; write the mesh and print "
                                   "its area.", epilog=SHAPES_HELP, formatter_class=_Formatter)
    m.add_argument("source", help="a shape spec NAME:key=value,... (sphere:r=40, torus:R=30,r=9) or a file")
    m.add_argument("-o", "--output", required=True,
                   help="output mesh file (.ply, .obj, .stl, .off); a folder with --all-labels/--all-rois")
    m.add_argument("--polygon", default=None, choices=["mlp", "dss", "none"],
                   help="each contour becomes its minimum length polygon, its maximal-DSS polygon, or stays as traced "
                        "(default: mlp; for contour files: their drawn rings, see --route)")
    m.add_argument("--triangulation", default=None, choices=["wiederhold", "greedy", "optimal", "arclength"],
                   help="band triangulation between consecutive polygons (default: wiederhold, "
                        "or optimal with --refine band)")
    m.add_argument("--caps", default="flat", choices=["flat", "half", "smooth"],
                   help="end caps in the last section's plane, half a slice spacing beyond it, or a smooth dome "
                        "holding the half-spacing volume (smooth: contour stacks on the stack route, and any "
                        "source with --refine, whose domes follow the last sections' areas)")
    m.add_argument("--refine", default=None, choices=["none", "band", "band2"],
                   help="band: the convergent refinement of the polygons across slices; band2: the same with "
                        "twice the ring vertices (closer volumes, twice the vertices) (default: none)")
    m.add_argument("--roi", action="append", default=None,
                   help="contour files: the structure, by name or number; repeat it for several (-o is then a folder)")
    m.add_argument("--all-rois", action="store_true",
                   help="contour files: every non-empty structure, one mesh file each in the folder -o, and rois.csv")
    m.add_argument("--all-labels", action="store_true",
                   help="label volumes: every non-zero label in one pass, one mesh file each in the folder -o, "
                        "and labels.csv (label, area, volume, P, faces, genus, components, watertight, "
                        "self_intersections, bounding box)")
    m.add_argument("--stats-only", action="store_true", help="with --all-labels/--all-rois: the table only, no meshes")
    m.add_argument("--jobs", type=int, default=None,
                   help="--all-labels: read the volume piece by piece and mesh labels in this many local processes "
                        "(a Zarr store, HDF5 or .npy is read this way by default, with one process per core)")
    m.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="--all-labels: run the label tasks on the Dask cluster at this scheduler address")
    m.add_argument("--cache", default=None, metavar="DIR",
                   help="--all-labels, piece by piece: keep per-batch results here so a rerun resumes "
                        "(default: OUTDIR/.contourmesh-cache, removed after a complete run)")
    m.add_argument("--max-box-voxels", type=int, default=None,
                   help="--all-labels, piece by piece: per-task budget, the largest box read by one task; a "
                        "larger label is meshed in slabs of slices joined at their seams (the in-memory mesh; "
                        "refused by name with --refine band) (default: 2**26)")
    m.add_argument("--halo", type=int, default=None, metavar="N",
                   help="--all-labels, piece by piece: slices each slab of a label above --max-box-voxels reads "
                        "beyond each of its seams (default: 3; every seam is checked, a disagreement is a "
                        "failed row); not with --refine band/band2, whose labels are never cut into slabs")
    m.add_argument("--format", default="ply", choices=["ply", "obj", "stl", "off"],
                   help="mesh file format with --all-labels/--all-rois")
    m.add_argument("--pixel", type=float, default=None,
                   help="contour files: pixel size of the raster that decides the joins (contours route) or is "
                        "meshed (raster route) (default: the median point spacing, at most 1)")
    m.add_argument("--route", default=None, choices=["contours", "raster"],
                   help="contour files: mesh between the drawn rings, joined as a raster decides (contours, the "
                        "default; --polygon mlp/dss does not apply), or mesh the polygons of the raster (raster); "
                        "one ring per section with --polygon none or --caps smooth goes to the stack route")
    m.add_argument("--bands", default=None, choices=["ruled", "curved"],
                   help="contour files, contours route: ruled bands between drawn sections (the default; volume "
                        "within the frustum-trapezoid interval) or curved bands through the neighbouring sections "
                        "(smooth shapes converge to their true volume and area)")
    m.add_argument("--label", type=_label, default=None,
                   help="volumes: use the voxels equal to this label (.seg.nrrd, DICOM-SEG: a segment name)")
    m.add_argument("--threshold", type=_number, default=None, help="volumes: use the voxels above this value")
    m.add_argument("--axis", type=int, default=None, choices=[0, 1, 2], help="volumes: slicing axis (default 0)")
    m.add_argument("--spacing", type=_spacing, default=None, metavar="DZ,DY,DX",
                   help="volumes: voxel size, replacing the file's own (.npy files carry none: 1,1,1)")
    m.add_argument("--quiet", action="store_true", help="no progress bar")
    m.add_argument("--post", action="append", help="post-process, repeatable: merge-coplanar, taubin, "
                   "meshlab-planar-qec, mlx:FILE")
    m.add_argument("--mlx", action="append", help="apply a MeshLab filter script (.mlx) to the mesh")
    m.add_argument("--save-mlx", default=None, help="save the MeshLab filters among --post as an .mlx script")
    m.add_argument("--json", action="store_true", help="print a JSON summary")
    m.add_argument("--force", action="store_true", help="overwrite an existing output file")
    m.set_defaults(func=_cmd_mesh)

    r = sub.add_parser("reproduce", help="reproduce the paper's Tables 1-2 and Figures 2-3", parents=[common],
                       formatter_class=_Formatter)
    r.add_argument("--out", default=None, help="output folder (default: ./paper/ in the current directory)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_reproduce)

    from .compare.command import add_compare_parser

    c = add_compare_parser(sub)
    for action in common._actions:
        if action.option_strings and not any(o in c._option_string_actions for o in action.option_strings):
            c._add_action(action)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    debug = getattr(args, "debug", False)
    if getattr(args, "verbose", False):
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("contourmesh: %(message)s"))
        log = logging.getLogger("contourmesh")
        log.addHandler(handler)
        log.setLevel(logging.DEBUG)
    try:
        import warnings

        from .errors import LostContourWarning, RasterFallbackWarning

        with warnings.catch_warnings():
            warnings.simplefilter("default")

            def show(message, category, filename, lineno, file=None, line=None):
                if issubclass(category, (LostContourWarning, RasterFallbackWarning)) or filename.endswith("cli.py"):
                    print(f"contourmesh: warning: {_cli_words(str(message))}", file=sys.stderr)
                else:
                    print(warnings.formatwarning(message, category, filename, lineno, line), end="", file=sys.stderr)

            warnings.showwarning = show
            return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("contourmesh: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # one line unless --debug
        if debug:
            raise
        text = " ".join(str(exc).split())
        print(f"contourmesh: error: {type(exc).__name__}: {_cli_words(text)}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
