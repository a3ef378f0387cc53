"""Generate the clinical verification set: analytic phantoms drawn as contour stacks (nothing is downloaded).

Writes into OUT (default: a new temporary folder):

* ``<phantom>__dz<dz>__ds<ds>.contours.json`` for every phantom and drawing setting of
  :func:`contourmesh.compare.phantoms.verification_set` (the JSON contour format,
  ``docs/contour-json.md``);
* ``phantoms.rtstruct.dcm``: a DICOM RTSTRUCT with a few of them as ROIs (needs pydicom);
* ``manifest.csv``: file, ROI, phantom, kind, tilt, dz, ds, seed, sections, exact area and
  volume (empty where the phantom has no closed form).

The set is reproducible from ``--seed``; the files are not committed.

Run:  PYTHONPATH=src python scripts/make_clinical_phantoms.py [OUT] [--full] [--seed N]
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import tempfile
from pathlib import Path

from contourmesh.compare.phantoms import draw, rtstruct_bytes, verification_set
from contourmesh.io import read_contours, write_contours_json
from contourmesh.meshes import atomic_write

# drawings also written as ROIs of the RTSTRUCT: (phantom name, dz, ds)
RTSTRUCT_ROIS = [("sphere-r20", 2.0, 0.5), ("cyl-r15-L40-t30", 3.0, 0.5), ("frustum-r15-5-h30-t25", 3.0, 0.5),
                 ("lobes-r10-8-d14", 3.0, 0.5), ("keyhole-R12-r6-L30", 2.0, 0.5), ("nested-R15-9-4-L30", 2.0, 0.5)]


def _fmt(v):
    return f"{v:g}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", nargs="?", help="output folder (default: a new temporary folder)")
    ap.add_argument("--full", action="store_true", help="the whole grid (default: the comparison's subsample)")
    ap.add_argument("--seed", type=int, default=20150701, help="base seed (default 20150701)")
    args = ap.parse_args(argv)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="contourmesh-phantoms-"))
    out.mkdir(parents=True, exist_ok=True)
    rows, for_rt = [], {}
    settings = verification_set(full=args.full, seed=args.seed)
    wanted = set(RTSTRUCT_ROIS)
    if not args.full:  # the RTSTRUCT's drawings are in the full grid; draw them also in a subsample run
        full = verification_set(full=True, seed=args.seed)
        extra = [t for t in full if (t[0].name, t[1], t[2]) in wanted and t not in settings]
        settings = settings + extra
    for ph, dz, ds, seed in settings:
        stack = draw(ph, dz, ds, seed=seed)
        fname = f"{ph.name}__dz{_fmt(dz)}__ds{_fmt(ds)}.contours.json"
        write_contours_json(stack, out / fname, name=ph.name)
        roi = ""
        if (ph.name, dz, ds) in wanted:
            roi = f"{ph.name} dz{_fmt(dz)}"
            for_rt[roi] = stack
        rows.append({"file": fname, "roi": roi, "phantom": ph.name, "kind": ph.kind,
                     "tilt": ph.params.get("tilt", 0.0), "dz": dz, "ds": ds, "seed": seed,
                     "sections": len(stack.sections), "area_true": ph.area if ph.area is not None else "",
                     "volume_true": ph.volume if ph.volume is not None else ""})
    rt = ""
    try:
        data = rtstruct_bytes(for_rt)
    except ImportError as exc:
        print(f"RTSTRUCT not written: {exc}", file=sys.stderr)
    else:
        rt = "phantoms.rtstruct.dcm"
        atomic_write(out / rt, data)
        for name, stack in for_rt.items():  # the RTSTRUCT reads back as the same sections
            back = read_contours(out / rt, roi=name)
            if len(back.sections) != len(stack.sections):
                raise SystemExit(f"{rt}: ROI {name!r} reads back with {len(back.sections)} sections, "
                                 f"drew {len(stack.sections)}")
    for r in rows:
        r["rtstruct"] = rt if r["roi"] else ""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write(out / "manifest.csv", buf.getvalue().encode())
    print(f"{len(rows)} contour stacks in {out}" + (f"; {len(for_rt)} of them also as ROIs of {rt}" if rt else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
