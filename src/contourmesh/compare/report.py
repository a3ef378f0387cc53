"""Tables and plots of a comparison run: ``results.csv``, ``summary.md`` and three PNG figures.

Everything here works on *rows*: dicts with the columns of :data:`COLUMNS` (one row per input x
method x post-process x repeat, see :mod:`contourmesh.compare.runner`).  Repeats (random
placements) are summarised by their median and their spread (smallest and largest value).

The empirical order of a method is the slope ``-p`` of the least-squares line through
``(log size, log median |e|)`` over the sizes where it ran: ``|e| ~ c size**-p``.
"""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from ..meshes import atomic_write

__all__ = [
    "COLUMNS",
    "STATUSES",
    "rows_to_csv",
    "read_results_csv",
    "write_results_csv",
    "empirical_order",
    "summarize",
    "fit_orders",
    "markdown_summary",
    "plot_results",
    "PLOTS",
]

#: results.csv columns, in order (the first fifteen are the issue's).
COLUMNS = ("method", "postprocess", "shape", "size", "repeat", "area_true", "area", "e", "P", "t", "faces",
           "watertight", "seconds", "status", "error", "kind", "digitization", "size_value", "family",
           "winding_consistent", "volume", "key")

#: Row statuses: ran and measured; optional package missing; raised; over its time limit; left out
#: by the spec (``max_size``); input data missing.
STATUSES = ("ok", "not-installed", "failed", "timeout", "skipped", "no-data")

#: The figure files :func:`plot_results` writes.
PLOTS = ("error.png", "tradeoff.png", "seconds.png")

_INT = ("repeat", "P", "faces")
_FLOAT = ("area_true", "area", "e", "t", "seconds", "size_value", "volume")
_BOOL = ("watertight", "winding_consistent")


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (float, np.floating)):
        return "" if not math.isfinite(v) else repr(float(v))
    return str(v)


def rows_to_csv(rows) -> str:
    """CSV text of rows (columns :data:`COLUMNS`; empty cell = no value)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([_cell(r.get(c)) for c in COLUMNS])
    return buf.getvalue()


def write_results_csv(rows, path) -> Path:
    """Write ``results.csv`` atomically."""
    return atomic_write(path, rows_to_csv(rows).encode())


def read_results_csv(path) -> list[dict]:
    """Rows of a ``results.csv`` with numbers and booleans typed back (empty cells -> None)."""
    out = []
    with open(path, newline="") as fh:
        for rec in csv.DictReader(fh):
            row = {}
            for k, v in rec.items():
                if v == "":
                    row[k] = None
                elif k in _INT:
                    row[k] = int(float(v))
                elif k in _FLOAT:
                    row[k] = float(v)
                elif k in _BOOL:
                    row[k] = v == "true"
                else:
                    row[k] = v
            out.append(row)
    return out


# --- statistics ---------------------------------------------------------------------------------
def empirical_order(sizes, errors) -> float:
    """The order ``p`` of ``|e| ~ c size**-p`` fitted by least squares on log-log axes.

    Pairs with a non-positive or non-finite size or error are left out; fewer than two distinct
    sizes give NaN.

    Examples
    --------
    >>> round(empirical_order([10, 20, 40], [0.1, 0.05, 0.025]), 6)
    1.0
    """
    s = np.asarray(sizes, dtype=np.float64)
    e = np.abs(np.asarray(errors, dtype=np.float64))
    ok = np.isfinite(s) & np.isfinite(e) & (s > 0) & (e > 0)
    s, e = s[ok], e[ok]
    if len(np.unique(s)) < 2:
        return float("nan")
    slope = np.polyfit(np.log(s), np.log(e), 1)[0]
    return float(-slope)


def _series_label(method: str, post: str) -> str:
    return method if post in (None, "", "none") else f"{method} + {post}"


def summarize(rows) -> list[dict]:
    """Per (shape, size, method, post-process): counts by status and median / min / max over ok repeats."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r["shape"], r["size"], r["method"], r["postprocess"])].append(r)
    out = []
    for (shape, size, method, post), rs in groups.items():
        ok = [r for r in rs if r["status"] == "ok"]
        rec = {"shape": shape, "size": size, "size_value": rs[0].get("size_value"), "method": method,
               "postprocess": post, "n": len(rs), "n_ok": len(ok),
               "statuses": dict(sorted({s: sum(r["status"] == s for r in rs) for s in {r["status"] for r in rs}}.items())),
               "errors": sorted({(r.get("error") or "").splitlines()[0][:160] for r in rs if r["status"] != "ok" and r.get("error")})}
        for col in ("e", "P", "t", "seconds", "area"):
            vals = np.array([r[col] for r in ok if r.get(col) is not None], dtype=np.float64)
            rec[col] = float(np.median(vals)) if len(vals) else None
            rec[col + "_min"] = float(vals.min()) if len(vals) else None
            rec[col + "_max"] = float(vals.max()) if len(vals) else None
        abs_e = np.array([abs(r["e"]) for r in ok if r.get("e") is not None], dtype=np.float64)
        rec["abs_e"] = float(np.median(abs_e)) if len(abs_e) else None
        wt = [r.get("watertight") for r in ok if r.get("watertight") is not None]
        rec["watertight"] = (all(wt) if wt else None)
        out.append(rec)
    out.sort(key=lambda d: (str(d["shape"]), d["size_value"] if d["size_value"] is not None else 0.0, str(d["size"]),
                            d["method"], str(d["postprocess"])))
    return out


def fit_orders(summary) -> dict:
    """``{(shape, method, post): (order, number of sizes)}`` from the per-size medians of ``|e|``."""
    pts = defaultdict(list)
    for d in summary:
        if d["abs_e"] is not None and d["size_value"] is not None:
            pts[(d["shape"], d["method"], d["postprocess"])].append((d["size_value"], d["abs_e"]))
    out = {}
    for k, p in pts.items():
        s, e = zip(*p)
        out[k] = (empirical_order(s, e), len(set(s)))
    return out


# --- Markdown ---------------------------------------------------------------------------------------
def _f(v, fmt):
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def markdown_summary(rows, *, title: str = "Comparison", notes: str = "") -> str:
    """A Markdown report: status counts, per-size medians and spreads, fitted orders, failures."""
    summary = summarize(rows)
    orders = fit_orders(summary)
    lines = [f"# {title}", ""]
    if notes:
        lines += [notes.strip(), ""]
    counts = defaultdict(int)
    for r in rows:
        counts[r["status"]] += 1
    lines += [f"{len(rows)} rows: " + ", ".join(f"{counts[s]} {s}" for s in STATUSES if counts[s]) + ".", ""]
    lines += [
        "e = (area - area_true) / area_true (signed); t = |e| P; P = vertices (ours: polygon vertices). "
        "Medians over the repeats that ran (ok), with the smallest and largest value in brackets; "
        "seconds = wall clock of the method and its post-processes.", ""]
    for shape in sorted({d["shape"] for d in summary}):
        lines += [f"## {shape}", "", "### Empirical order (|e| ~ size^-p, least squares on the medians)", "",
                  "| method | post-process | p | sizes |", "|---|---|---:|---:|"]
        keys = sorted(k for k in orders if k[0] == shape)
        for k in keys:
            p, n = orders[k]
            lines.append(f"| {k[1]} | {k[2]} | {_f(p, '.2f')} | {n} |")
        lines += ["", "### By size", "",
                  "| size | method | post-process | ok/n | e median | e [min, max] | P | t | seconds | status |",
                  "|---|---|---|---:|---:|---|---:|---:|---:|---|"]
        for d in (d for d in summary if d["shape"] == shape):
            spread = f"[{_f(d['e_min'], '+.3%')}, {_f(d['e_max'], '+.3%')}]" if d["e"] is not None else ""
            st = ", ".join(f"{v} {k}" for k, v in d["statuses"].items() if k != "ok")
            lines.append(
                f"| {d['size']} | {d['method']} | {d['postprocess']} | {d['n_ok']}/{d['n']} | {_f(d['e'], '+.3%')} "
                f"| {spread} | {_f(d['P'], '.0f')} | {_f(d['t'], '.4g')} | {_f(d['seconds'], '.3g')} | {st} |")
        lines.append("")
    bad = [d for d in summary if d["errors"]]
    if bad:
        lines += ["## Rows that did not run", "", "| shape | size | method | post-process | status | error |",
                  "|---|---|---|---|---|---|"]
        for d in bad:
            st = ", ".join(f"{v} {k}" for k, v in d["statuses"].items() if k != "ok")
            err = "; ".join(d["errors"]).replace("|", "\\|")
            lines.append(f"| {d['shape']} | {d['size']} | {d['method']} | {d['postprocess']} | {st} | {err} |")
        lines.append("")
    return "\n".join(lines)


# --- plots ------------------------------------------------------------------------------------------
def plot_results(rows, out_dir) -> list[Path]:
    """Write ``error.png`` (|e| vs size, log-log, fitted order in the legend), ``tradeoff.png`` (t vs
    size) and ``seconds.png`` (seconds vs size), one panel per shape, one line per method and
    post-process (median over repeats, bars from the smallest to the largest value)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    summary = summarize(rows)
    orders = fit_orders(summary)
    all_shapes = sorted({d["shape"] for d in summary})
    series = sorted({(d["method"], d["postprocess"]) for d in summary})
    cmap = plt.get_cmap("tab20")
    styles = ("-", "--", ":", "-.")
    markers = ("o", "s", "^", "v", "D", "x", "+", "*")
    paths = []
    specs = (("error.png", "abs_e", "|e| (relative area error)", True),
             ("tradeoff.png", "t", "t = |e| P", False),
             ("seconds.png", "seconds", "seconds (method + post-process)", False))
    for fname, col, ylabel, with_order in specs:
        # one panel per shape that has something to plot (a shape whose rows all failed has none)
        shapes = [s for s in all_shapes if any(d["shape"] == s and d[col] is not None for d in summary)] or ["no data"]
        ncols = min(2, max(1, len(shapes)))
        nrows = max(1, math.ceil(len(shapes) / ncols))
        fig, axes = plt.subplots(nrows, ncols, figsize=(7.5 * ncols + 3.5, 5.0 * nrows), squeeze=False)
        for ax, shape in zip(axes.ravel(), shapes):
            for si, (method, post) in enumerate(series):
                pts = sorted((d["size_value"], d) for d in summary
                             if d["shape"] == shape and d["method"] == method and d["postprocess"] == post
                             and d[col] is not None and d["size_value"] is not None)
                if not pts:
                    continue
                x = np.array([p[0] for p in pts], dtype=float)
                if col == "abs_e":
                    y = np.array([p[1]["abs_e"] for p in pts])
                    lo = np.array([min(abs(p[1]["e_min"]), abs(p[1]["e_max"])) if p[1]["e_min"] * p[1]["e_max"] > 0 else 0.0
                                   for p in pts])
                    hi = np.array([max(abs(p[1]["e_min"]), abs(p[1]["e_max"])) for p in pts])
                else:
                    y = np.array([p[1][col] for p in pts])
                    lo = np.array([p[1][col + "_min"] for p in pts])
                    hi = np.array([p[1][col + "_max"] for p in pts])
                label = _series_label(method, post)
                if with_order:
                    p, _ = orders.get((shape, method, post), (float("nan"), 0))
                    label += f" (p = {p:.2f})" if math.isfinite(p) else " (p = n/a)"
                pos = y > 0
                if not pos.any():
                    continue
                yerr = np.vstack([np.clip(y - lo, 0, None), np.clip(hi - y, 0, None)])[:, pos]
                ax.errorbar(x[pos], y[pos], yerr=yerr, color=cmap(si % 20), linestyle=styles[(si // 20) % 4],
                            marker=markers[si % len(markers)], markersize=4, linewidth=1.2, capsize=2, label=label)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("size (grid units; meshes: voxels across)")
            ax.set_ylabel(ylabel)
            ax.set_title(str(shape))
            ax.grid(True, which="both", alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
        for ax in axes.ravel()[len(shapes):]:
            ax.axis("off")
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110)
        plt.close(fig)
        paths.append(atomic_write(out_dir / fname, buf.getvalue()))
    return paths
