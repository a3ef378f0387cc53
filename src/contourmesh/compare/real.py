"""The real-shapes comparison (``comparisons/real/``): closed meshes voxelized at several resolutions,
axis-aligned and randomly rotated, every method of the harness on the same volumes.

The rows come from the ordinary runner (:func:`contourmesh.compare.runner.run_spec`, one cached
row per input x method); this module pools them over the meshes:

* an input named ``NAME`` is the axis-aligned mesh, ``NAME-rot`` its random rotations (the
  *placement* sets ``"axis-aligned"`` and ``"rotated"``);
* per placement set, method and resolution ``N``: rows that ran / rows planned, the median of the
  signed error ``e``, the median and the largest ``|e|`` (with the mesh that has it);
* the empirical order of a method: the slope ``-p`` of ``log median |e|`` against ``log N``
  (least squares over the resolutions where it ran, :func:`~contourmesh.compare.report.empirical_order`);
* per mesh, the diagnostics of ours from the row's ``meta`` (axis wall fraction, exact joins,
  fallbacks, crack rings).

:func:`main` is the command line of ``comparisons/real/run.py``: it runs a part of the spec
(``--resolutions``, ``--methods``, ``--meshes``), re-imports the rows of an earlier
``results.csv`` so that a fresh checkout resumes instead of recomputing, and writes
``results.csv``, ``summary.md``, ``error.png`` and ``runs.csv`` (the wall time of each run)
atomically.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
import time
from collections import defaultdict
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..meshes import atomic_write
from .report import empirical_order, read_results_csv, write_results_csv

__all__ = ["ROTATED_SUFFIX", "split_name", "planned_counts", "pooled", "orders", "diagnostics", "markdown", "plot", "run", "main"]

#: Input names ending with this are the rotated copies of a mesh.
ROTATED_SUFFIX = "-rot"
PLACEMENTS = ("axis-aligned", "rotated")
PAPER = "ours-mlp-wiederhold"
#: The diagnostics of ours shown per mesh (keys of ``Mesh.meta``; absent keys are left blank).
DIAGNOSTICS = ("axis_wall_fraction", "exact_joins", "polygon_fallbacks", "crack_rings", "band_fallbacks",
               "intermediate_sections")


def split_name(name: str) -> tuple[str, str]:
    """``("bunny", "rotated")`` for ``"bunny-rot"``, ``("bunny", "axis-aligned")`` for ``"bunny"``."""
    if name.endswith(ROTATED_SUFFIX):
        return name[: -len(ROTATED_SUFFIX)], "rotated"
    return name, "axis-aligned"


def _size(row) -> int:
    return int(float(row["size"]))


def planned_counts(spec) -> dict:
    """``{(placement, N): rows each method has there}`` from a spec's inputs (one row per input)."""
    out: dict = defaultdict(int)
    for inp in spec.inputs:
        out[(split_name(inp.name)[1], int(inp.size))] += 1
    return dict(out)


def pooled(rows, planned=None) -> list[dict]:
    """Per (placement, method, N): ``n`` (rows present), ``planned`` (rows the spec plans there, from
    ``planned`` = :func:`planned_counts`; default ``n``), ``n_ok``, ``e_median``, ``abs_median``,
    ``abs_max``, ``worst`` (the mesh, and the rotation for the rotated set, with the largest |e|),
    ``seconds`` (median) and ``statuses`` (counts of the rows that did not run, by status; rows
    not run yet count as ``"not run yet"``)."""
    groups = defaultdict(list)
    for r in rows:
        mesh, placement = split_name(r["shape"])
        groups[(placement, r["method"], _size(r))].append((mesh, r))
    out = []
    for (placement, method, n), items in groups.items():
        ok = [(m, r) for m, r in items if r["status"] == "ok" and r.get("e") is not None]
        e = np.array([r["e"] for _, r in ok], dtype=np.float64)
        want = max(len(items), (planned or {}).get((placement, n), len(items)))
        statuses = _count(r["status"] for _, r in items if r["status"] != "ok")
        if want > len(items):
            statuses["not run yet"] = want - len(items)
        rec = {"placement": placement, "method": method, "N": n, "n": len(items), "planned": want, "n_ok": len(ok),
               "statuses": dict(sorted(statuses.items())),
               "e_median": None, "abs_median": None, "abs_max": None, "worst": None, "seconds": None}
        if len(ok):
            i = int(np.argmax(np.abs(e)))
            m, r = ok[i]
            rec.update(e_median=float(np.median(e)), abs_median=float(np.median(np.abs(e))),
                       abs_max=float(np.abs(e[i])), worst=m if placement == "axis-aligned" else f"{m} #{r['repeat']}",
                       seconds=float(np.median([r["seconds"] for _, r in ok if r.get("seconds") is not None] or [np.nan])))
        out.append(rec)
    out.sort(key=lambda d: (PLACEMENTS.index(d["placement"]), d["method"], d["N"]))
    return out


def _count(values) -> dict:
    c: dict = defaultdict(int)
    for v in values:
        c[v] += 1
    return c


def orders(pool) -> dict:
    """``{(placement, method): (order, number of resolutions)}`` from the pooled median |e|.

    A resolution counts only when every planned row of the method there ran: a median over part
    of the meshes would bias the slope.
    """
    pts = defaultdict(list)
    for d in pool:
        if d["abs_median"] is not None and d["n_ok"] == d["planned"]:
            pts[(d["placement"], d["method"])].append((d["N"], d["abs_median"]))
    return {k: (empirical_order(*zip(*p)), len(p)) for k, p in pts.items()}


def _meta(row) -> dict:
    text = row.get("meta")
    if not text:
        return {}
    try:
        got = json.loads(text)
    except ValueError:
        return {}
    return got if isinstance(got, dict) else {}


def diagnostics(rows, method: str = PAPER) -> list[dict]:
    """Per (mesh, N) for ``method``: the axis-aligned row's ``e`` and meta, and over the rotations the
    median and largest ``e`` and the median / largest of each meta entry of :data:`DIAGNOSTICS`."""
    groups = defaultdict(lambda: {"axis-aligned": [], "rotated": []})
    for r in rows:
        if r["method"] != method:
            continue
        mesh, placement = split_name(r["shape"])
        groups[(mesh, _size(r))][placement].append(r)
    out = []
    for (mesh, n), by in sorted(groups.items()):
        rec = {"mesh": mesh, "N": n}
        for placement, rs in by.items():
            ok = [r for r in rs if r["status"] == "ok"]
            tag = "axis" if placement == "axis-aligned" else "rot"
            rec[f"{tag}_n"] = f"{len(ok)}/{len(rs)}"
            es = [r["e"] for r in ok]
            rec[f"{tag}_e"] = float(np.median(es)) if es else None
            rec[f"{tag}_e_max"] = max(es, key=abs) if es else None
            for key in DIAGNOSTICS:
                vals = [_meta(r)[key] for r in ok if isinstance(_meta(r).get(key), (int, float))]
                rec[f"{tag}_{key}"] = float(np.median(vals)) if vals else None
                rec[f"{tag}_{key}_max"] = float(max(vals)) if vals else None
            rec[f"{tag}_errors"] = sorted({(r.get("error") or "")[:120] for r in rs if r["status"] != "ok"})
        out.append(rec)
    return out


# --- Markdown -----------------------------------------------------------------------------------------
def _pct(v, sign=False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return format(v, "+.2%" if sign else ".2%")


def _num(v, fmt=".0f") -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def _method_order(pool, placement, methods) -> list:
    present = {d["method"] for d in pool if d["placement"] == placement}
    ordered = [m for m in methods if m in present] + sorted(present - set(methods))
    return ordered


def markdown(rows, *, title: str, notes: str = "", methods=(), runs=(), planned=None) -> str:
    """The report: pooled table per placement set, orders, ours' diagnostics per mesh, failures, runs."""
    pool = pooled(rows, planned)
    order = orders(pool)
    sizes = sorted({d["N"] for d in pool})
    meshes = sorted({split_name(r["shape"])[0] for r in rows})
    lines = [f"# {title}", ""]
    counts = _count(r["status"] for r in rows)
    lines += [f"{len(rows)} rows ({', '.join(f'{v} {k}' for k, v in sorted(counts.items()))}); meshes: "
              + ", ".join(meshes) + ".", ""]
    if notes:
        lines += [notes.strip(), ""]
    lines += ["e = (area - area_true) / area_true, area_true the mesh's own area. Per method and resolution N "
              "(voxels across the largest extent): the median of e and of |e| over the meshes (rotated: 3 "
              "rotations each) and the largest |e| with its mesh (`#r`: rotation r). ok = rows that ran / rows "
              "planned; the statistics are over the rows that ran (a resolution not run for every mesh yet is "
              "over part of the meshes). p = empirical order, the slope of log median |e| against log N over "
              "the resolutions where every planned row ran (|e| ~ N^-p); the number of such resolutions in "
              "brackets. The plot draws those points only.", ""]
    for placement in PLACEMENTS:
        if not any(d["placement"] == placement for d in pool):
            continue
        lines += [f"## {placement.capitalize()}", ""]
        head = "| method |" + "".join(f" ok {n} | median e {n} | median abs(e) {n} | max abs(e) {n} |" for n in sizes) + " p (sizes) |"
        lines += [head.replace("abs(e)", "\\|e\\|"), "|---|" + "---:|---:|---:|---|" * len(sizes) + "---:|"]
        by = {(d["method"], d["N"]): d for d in pool if d["placement"] == placement}
        for m in _method_order(pool, placement, methods):
            cells = []
            for n in sizes:
                d = by.get((m, n))
                if d is None:
                    cells.append(" | | | |")
                    continue
                worst = f"{_pct(d['abs_max'])} ({d['worst']})" if d["abs_max"] is not None else ""
                cells.append(f" {d['n_ok']}/{d['planned']} | {_pct(d['e_median'], True)} | {_pct(d['abs_median'])} | {worst} |")
            p, k = order.get((placement, m), (float("nan"), 0))
            lines.append(f"| {m} |" + "".join(cells) + f" {_num(p, '.2f')} ({k}) |")
        lines.append("")
    diag = diagnostics(rows)
    if diag:
        lines += [f"## Per mesh: {PAPER} (the paper's mode) and its diagnostics", "",
                  "walls = fraction of the area on faces whose normal is exactly +-x or +-y "
                  "(`contourmesh.measure.axis_wall_fraction`); exact joins, polygon fallbacks and crack rings "
                  "from `Mesh.meta`. Rotated: median over the rotations, the largest in brackets.", "",
                  "| mesh | N | e axis | walls axis | exact joins axis | e rotated [worst] | walls rotated [max] "
                  "| exact joins rotated [max] | polygon fallbacks rotated [max] | crack rings rotated [max] |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for d in diag:
            def two(key, fmt=".0f", pct=False):
                a, b = d.get(f"rot_{key}"), d.get(f"rot_{key}_max")
                f = (lambda v: _pct(v)) if pct else (lambda v: _num(v, fmt))
                return f"{f(a)} [{f(b)}]" if a is not None else ""
            lines.append(
                f"| {d['mesh']} | {d['N']} | {_pct(d.get('axis_e'), True)} | {_pct(d.get('axis_axis_wall_fraction'))} "
                f"| {_num(d.get('axis_exact_joins'))} | {_pct(d.get('rot_e'), True)} [{_pct(d.get('rot_e_max'), True)}] "
                f"| {two('axis_wall_fraction', pct=True)} | {two('exact_joins')} | {two('polygon_fallbacks')} "
                f"| {two('crack_rings')} |")
        lines.append("")
    bad = defaultdict(lambda: [0, set()])
    for r in rows:
        if r["status"] != "ok":
            k = (r["method"], _size(r), r["status"])
            bad[k][0] += 1
            bad[k][1].add(split_name(r["shape"])[0])
    if bad:
        reasons = defaultdict(set)
        for r in rows:
            if r["status"] != "ok":
                reasons[(r["method"], _size(r), r["status"])].add(_reason(r.get("error")))
        lines += ["## Rows that did not run", "", "| method | N | status | rows | meshes | reasons |", "|---|---:|---|---:|---|---|"]
        for k in sorted(bad):
            n, ms = bad[k]
            why = "; ".join(sorted(reasons[k])).replace("|", "\\|")
            lines.append(f"| {k[0]} | {k[1]} | {k[2]} | {n} | {', '.join(sorted(ms))} | {why} |")
        lines.append("")
    if runs:
        lines += ["## Runs (wall time)", "", "| finished (UTC) | resolutions | methods | meshes | jobs | rows run | seconds |",
                  "|---|---|---|---|---:|---:|---:|"]
        for r in runs:
            lines.append(f"| {r['finished']} | {r['resolutions']} | {r['methods']} | {r['meshes']} | {r['jobs']} "
                         f"| {r['ran']} | {r['seconds']} |")
        lines.append("")
    return "\n".join(lines)


def _reason(error) -> str:
    """An error message with its per-row details (slice numbers, counts) generalised, to group rows."""
    import re

    text = (error or "").splitlines()[0] if error else ""
    text = re.sub(r"\[[^\]]*\.py:\d+\]", "", text)
    return re.sub(r"\d+(\.\d+)?", "#", text).strip()[:160]


# --- plot -----------------------------------------------------------------------------------------------
def plot(rows, path, *, methods=(), planned=None) -> Path:
    """``error.png``: median |e| over the meshes against N, log-log, one panel per placement set;
    ours in red / orange, thick; every method's order in the legend.  Only the points where every
    planned row of the method ran are drawn."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pool = [d for d in pooled(rows, planned) if d["n_ok"] == d["planned"]]
    order = orders(pool)
    panels = [p for p in PLACEMENTS if any(d["placement"] == p and d["abs_median"] for d in pool)]
    fig = Figure(figsize=(7.0 * max(1, len(panels)), 6.2))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, max(1, len(panels)), squeeze=False)[0]
    cmap = __import__("matplotlib").colormaps["tab20"]
    for ax, placement in zip(axes, panels):
        ms = _method_order(pool, placement, methods)
        peers = [m for m in ms if not m.startswith("ours")]
        for m in ms:
            pts = sorted((d["N"], d["abs_median"]) for d in pool
                         if d["placement"] == placement and d["method"] == m and d["abs_median"])
            if not pts:
                continue
            x, y = zip(*pts)
            p, k = order.get((placement, m), (float("nan"), 0))
            label = f"{m} (p = {p:.2f})" if math.isfinite(p) else f"{m} (p = n/a)"
            if m.startswith("ours"):
                colour = "#c0392b" if m == PAPER else "#e67e22"
                ax.plot(x, y, color=colour, lw=2.6, marker="o", ms=6, label=label, zorder=4)
            else:
                ax.plot(x, y, color=cmap(peers.index(m) % 20), lw=1.3, marker="s", ms=4, label=label, zorder=3)
        ax.set_xscale("log")
        ax.set_yscale("log")
        sizes = sorted({d["N"] for d in pool})
        ax.set_xticks(sizes)
        ax.set_xticklabels([str(s) for s in sizes])
        ax.minorticks_off()
        ax.set_xlabel("N (voxels across the largest extent)")
        ax.set_ylabel("median |e| over the meshes")
        ax.set_title(f"{placement}: median |e| vs resolution")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=7, loc="lower left", framealpha=0.9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return atomic_write(path, buf.getvalue())


# --- the run ---------------------------------------------------------------------------------------
RUN_COLUMNS = ("finished", "resolutions", "methods", "meshes", "jobs", "ran", "seconds")


def _read_runs(path: Path) -> list:
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return [r for r in csv.DictReader(fh) if set(RUN_COLUMNS) <= set(r)]


def _names(spec, meshes):
    if meshes is None:
        return None
    known = {i.name for i in spec.inputs}
    out = set()
    for m in meshes:
        got = {n for n in (m, m + ROTATED_SUFFIX) if n in known}
        if not got:
            raise ValueError(f"mesh {m!r} is not in the spec; it has {sorted({split_name(n)[0] for n in known})}")
        out |= got
    return out


def run(spec_path, out, *, resolutions=None, methods=None, meshes=None, jobs: int = 1, progress: bool = True,
        retry_failed: bool = False, data_root=None, reuse_csv: bool = True, write_plot: bool = True) -> dict:
    """Run (a part of) a real-shapes spec into ``out`` and write its four files (``write_plot=False``:
    all but ``error.png``); returns the runner's result plus ``imported`` (rows taken from an
    earlier ``results.csv``) and ``seconds`` (wall time)."""
    from .runner import import_rows, load_spec, run_spec

    out = Path(out)
    spec = load_spec(spec_path, data_root=data_root)
    imported = import_rows(spec_path, out, out / "results.csv", data_root=data_root) if reuse_csv else 0
    t0 = time.perf_counter()
    res = run_spec(spec_path, out, jobs=jobs, progress=progress, retry_failed=retry_failed, data_root=data_root,
                   sizes=None if resolutions is None else [str(int(n)) for n in resolutions],
                   methods=methods, names=_names(spec, meshes), write=False)
    seconds = time.perf_counter() - t0
    runs = _read_runs(out / "runs.csv")
    if res["ran"]:
        runs.append({"finished": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"),
                     "resolutions": ",".join(str(n) for n in resolutions) if resolutions else "all",
                     "methods": ",".join(methods) if methods else "all",
                     "meshes": ",".join(meshes) if meshes else "all", "jobs": jobs, "ran": res["ran"],
                     "seconds": f"{seconds:.0f}"})
        buf = io.StringIO()
        w = csv.DictWriter(buf, RUN_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows(runs)
        atomic_write(out / "runs.csv", buf.getvalue().encode())
    rows = res["rows"]
    planned = planned_counts(spec)
    files = [write_results_csv(rows, out / "results.csv"),
             atomic_write(out / "summary.md", markdown(rows, title=spec.title, notes=spec.notes, methods=spec.methods,
                                                       runs=runs, planned=planned).encode())]
    if write_plot and any(r["status"] == "ok" for r in rows):
        files.append(plot(rows, out / "error.png", methods=spec.methods, planned=planned))
    return res | {"imported": imported, "seconds": seconds, "files": files}


def report_only(spec_path, out) -> list:
    """Rebuild ``summary.md`` and ``error.png`` from ``out/results.csv`` alone (no run, no cache)."""
    from .runner import load_spec

    out = Path(out)
    spec = load_spec(spec_path)
    rows = read_results_csv(out / "results.csv")
    planned = planned_counts(spec)
    files = [atomic_write(out / "summary.md", markdown(rows, title=spec.title, notes=spec.notes, methods=spec.methods,
                                                       runs=_read_runs(out / "runs.csv"), planned=planned).encode())]
    if any(r["status"] == "ok" for r in rows):
        files.append(plot(rows, out / "error.png", methods=spec.methods, planned=planned))
    return files


def _csv_list(text):
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def main(argv=None, *, default_spec=None) -> int:
    p = argparse.ArgumentParser(description="Run the real-shapes comparison, or a part of it (finished rows are "
                                            "cached and re-imported from results.csv, so runs resume).")
    p.add_argument("--spec", default=default_spec, required=default_spec is None, help="the TOML spec")
    p.add_argument("--out", default=None, help="output folder (default: the spec's folder)")
    p.add_argument("--resolutions", default=None, help="run only these N, e.g. 64,128 (default: all)")
    p.add_argument("--methods", default=None, help="run only these methods, comma-separated")
    p.add_argument("--meshes", default=None, help="run only these meshes (axis-aligned and rotated), comma-separated")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("--retry-failed", action="store_true", help="re-run selected rows that failed or timed out")
    p.add_argument("--no-reuse-csv", action="store_true", help="do not import the rows of an earlier results.csv")
    p.add_argument("--report-only", action="store_true", help="rebuild summary.md and error.png from results.csv")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    a = p.parse_args(argv)
    spec = Path(a.spec)
    out = Path(a.out) if a.out else spec.parent
    if a.report_only:
        for f in report_only(spec, out):
            print(f"wrote {f}")
        return 0
    try:
        resolutions = [int(x) for x in _csv_list(a.resolutions)] if a.resolutions else None
    except ValueError:
        p.error(f"--resolutions takes integers separated by commas; got {a.resolutions!r}")
    try:
        res = run(spec, out, resolutions=resolutions, methods=_csv_list(a.methods), meshes=_csv_list(a.meshes),
                  jobs=a.jobs, progress=not a.quiet, retry_failed=a.retry_failed, reuse_csv=not a.no_reuse_csv)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    counts = _count(r["status"] for r in res["rows"])
    print(f"{len(res['rows'])} rows ({res['ran']} run in {res['seconds']:.0f} s, {res['cached']} cached, "
          f"{res['imported']} imported from results.csv; " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
          + "); wrote " + ", ".join(str(f) for f in res["files"]))
    return 1 if res["executor_failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
