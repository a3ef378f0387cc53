"""Tables and plots of a comparison run: ``results.csv``, ``summary.md`` and PNG figures per shape family.

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
    "highlighted",
    "PLOTS",
]

#: results.csv columns, in order (the first fifteen are the issue's).
COLUMNS = ("method", "postprocess", "shape", "size", "repeat", "area_true", "area", "e", "P", "t", "faces",
           "watertight", "seconds", "status", "error", "kind", "digitization", "size_value", "family",
           "winding_consistent", "volume", "key", "meta")

#: ``meta`` is JSON text: the scalar entries of the method's ``Mesh.meta`` (ours: exact joins,
#: fallbacks, ...) and ``axis_wall_fraction`` of the final mesh
#: (:func:`contourmesh.measure.axis_wall_fraction`); empty for methods that make no mesh.

#: Row statuses: ran and measured; optional package missing; raised; over its time limit; left out
#: by the spec (``max_size``); input data missing.
STATUSES = ("ok", "not-installed", "failed", "timeout", "skipped", "no-data")

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
#: The figures :func:`plot_results` writes, one file per metric and shape family:
#: ``error-<shape>.png``, ``tradeoff-<shape>.png``, ``seconds-<shape>.png``.
PLOTS = ("error-<shape>.png", "tradeoff-<shape>.png", "seconds-<shape>.png")

#: How many of our variants and how many peers each plot draws in colour.
N_OURS, N_PEERS = 2, 3
_OURS_COLOURS = ("#c0392b", "#e67e22")  # ours: red, orange, thick lines
_PEER_COLOURS = ("#1f77b4", "#2ca02c", "#9467bd")  # the strongest peers: blue, green, purple
_FADED = "#b8b8b8"
#: The paper's variant of our method (MLP polygons, Wiederhold-Villafuerte triangulation).
PAPER_OURS = ("ours-mlp-wiederhold", "none")


def _is_ours(method: str) -> bool:
    return method == "ours" or str(method).startswith("ours-")


def _strength(points) -> float:
    """Mean log10 |e| over the largest half of a family's sizes where the series ran (lower = stronger)."""
    if not points:
        return math.inf
    return float(np.mean([math.log10(e) for _, e in points]))


def highlighted(summary, shape, n_ours: int = N_OURS, n_peers: int = N_PEERS, having: str = "abs_e"):
    """The series ``(method, post)`` drawn in colour for ``shape``: ours' and the peers' strongest.

    Ours: our strongest variant and the paper's (``ours-mlp-wiederhold``) when it ran.  Strength is the mean of ``log10 |e|`` (medians over repeats) over the larger half of the
    family's sizes; a series that did not run there ranks last.  Only series with values in
    column ``having`` are candidates (``"t"``: methods without a vertex count have no t).
    Returns ``(ours, peers)``.
    """
    recs = [d for d in summary if d["shape"] == shape and d["abs_e"] and d["size_value"] is not None]
    sizes = sorted({d["size_value"] for d in recs})
    large = set(sizes[len(sizes) // 2:]) if sizes else set()
    pts = defaultdict(list)
    for d in recs:
        if d["size_value"] in large:
            pts[(d["method"], d["postprocess"])].append((d["size_value"], d["abs_e"]))
    series = sorted({(d["method"], d["postprocess"]) for d in recs}
                    & {(d["method"], d["postprocess"]) for d in summary if d["shape"] == shape and d[having] is not None})
    rank = sorted(series, key=lambda k: (_strength(pts.get(k)), k))
    ours = [k for k in rank if _is_ours(k[0])][:1]
    if PAPER_OURS in series and PAPER_OURS not in ours:  # the paper's own variant is always shown
        ours.append(PAPER_OURS)
    ours += [k for k in rank if _is_ours(k[0]) and k not in ours][:max(0, n_ours - len(ours))]
    peers = [k for k in rank if not _is_ours(k[0])][:n_peers]
    return ours, peers


def _series_points(summary, shape, method, post, col):
    pts = sorted((d["size_value"], d) for d in summary
                 if d["shape"] == shape and d["method"] == method and d["postprocess"] == post
                 and d[col] is not None and d["size_value"] is not None)
    if not pts:
        return None
    x = np.array([p[0] for p in pts], dtype=float)
    if col == "abs_e":
        y = np.array([p[1]["abs_e"] for p in pts])
        lo = np.array([min(abs(p[1]["e_min"]), abs(p[1]["e_max"])) if p[1]["e_min"] * p[1]["e_max"] > 0 else 0.0
                       for p in pts])
        hi = np.array([max(abs(p[1]["e_min"]), abs(p[1]["e_max"])) for p in pts])
    else:
        y = np.array([p[1][col] for p in pts], dtype=float)
        lo = np.array([p[1][col + "_min"] for p in pts], dtype=float)
        hi = np.array([p[1][col + "_max"] for p in pts], dtype=float)
    pos = y > 0
    if not pos.any():
        return None
    return x[pos], y[pos], lo[pos], hi[pos]


def _label_ends(ax, ends):
    """Write each highlighted series' name just right of its last point, nudged apart vertically."""
    if not ends:
        return
    ymin, ymax = ax.get_ylim()
    span = math.log10(ymax) - math.log10(ymin) if ymin > 0 and ymax > ymin else 1.0
    gap = 0.045 * span
    placed = []
    for x, y, text, colour in sorted(ends, key=lambda e: math.log10(e[1])):
        ly = math.log10(y)
        if placed and ly < placed[-1] + gap:
            ly = placed[-1] + gap
        placed.append(ly)
        ax.annotate(text, xy=(x, y), xytext=(x * 1.06, 10 ** ly), fontsize=8, color=colour, va="center",
                    fontweight="bold", annotation_clip=False,
                    arrowprops=dict(arrowstyle="-", color=colour, lw=0.6, alpha=0.7) if abs(10 ** ly / y - 1) > 0.15 else None)


def _plot_family(summary, orders, shape, col, ylabel, with_order, path) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ours, peers = highlighted(summary, shape, having=col)
    colours = dict(zip(ours, _OURS_COLOURS)) | dict(zip(peers, _PEER_COLOURS))
    series = sorted({(d["method"], d["postprocess"]) for d in summary if d["shape"] == shape})
    fig = Figure(figsize=(10.5, 6.0))  # object API: a caller's pyplot backend is left alone
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    faded = 0
    for key in series:  # the others first, faded, so the highlighted lines sit on top
        if key in colours:
            continue
        pts = _series_points(summary, shape, *key, col)
        if pts is None:
            continue
        x, y, _, _ = pts
        ax.plot(x, y, color=_FADED, lw=0.8, alpha=0.7, marker=".", ms=3, zorder=1)
        faded += 1
    ends = []
    for rank, key in enumerate(ours + peers):
        pts = _series_points(summary, shape, *key, col)
        if pts is None:
            continue
        x, y, lo, hi = pts
        name = _series_label(*key)
        label = name
        if with_order:
            p, _ = orders.get((shape, *key), (float("nan"), 0))
            label += f"  (order p = {p:.2f})" if math.isfinite(p) else "  (order p = n/a)"
        is_ours = key in ours
        # the spread over the repeats as a light band (its lower edge kept within a decade and a
        # half of the median: |e| of a repeat can pass through zero)
        lo = np.maximum(np.nan_to_num(lo, nan=0.0), y / 30.0)
        hi = np.maximum(np.nan_to_num(hi, nan=0.0), y)
        if np.any(hi > lo * 1.0001):
            ax.fill_between(x, lo, hi, color=colours[key], alpha=0.12, lw=0, zorder=2)
        ax.plot(x, y, color=colours[key], lw=2.4 if is_ours else 1.6, marker="o" if is_ours else "s",
                ms=5 if is_ours else 4, label=label, zorder=4 if is_ours else 3)
        ends.append((x[-1], y[-1], name, colours[key]))
    if faded:
        ax.plot([], [], color=_FADED, lw=0.8, label=f"{faded} other methods")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("size (grid units; meshes: voxels across)")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{shape}: ours and the {len(peers)} strongest peers (by |e| at the larger sizes)")
    ax.grid(True, which="both", alpha=0.25)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="lower left", framealpha=0.9)
    xmin, xmax = ax.get_xlim()
    ax.set_xlim(xmin, xmax * 1.7)  # room for the end labels
    _label_ends(ax, ends)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return atomic_write(path, buf.getvalue())


def _safe(name) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name)) or "shape"


def plot_results(rows, out_dir) -> list[Path]:
    """Write ``error-<shape>.png`` (|e| vs size, log-log, fitted orders in the legend),
    ``tradeoff-<shape>.png`` (t = |e| P vs size) and ``seconds-<shape>.png``, one file per shape
    family and metric.

    Each plot draws ours (our two strongest variants) and the three strongest peers for that
    family (:func:`highlighted`) in distinct colours, with a light band from the smallest to the
    largest value over the repeats and each line's name at its end; every other method is a
    faded grey line behind them.  Returns the paths written.
    """
    out_dir = Path(out_dir)
    summary = summarize(rows)
    orders = fit_orders(summary)
    specs = (("error", "abs_e", "|e| (relative area error)", True),
             ("tradeoff", "t", "t = |e| P", False),
             ("seconds", "seconds", "seconds (method + post-process)", False))
    paths = []
    for shape in sorted({d["shape"] for d in summary}):
        for stem, col, ylabel, with_order in specs:
            if not any(d["shape"] == shape and d[col] is not None for d in summary):
                continue
            paths.append(_plot_family(summary, orders, shape, col, ylabel, with_order,
                                      out_dir / f"{stem}-{_safe(shape)}.png"))
    return paths
