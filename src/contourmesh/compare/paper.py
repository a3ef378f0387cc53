"""Reproduction of the paper's Tables 1-2 and Figures 2-3, beside the published values.

The published values are data typed from the paper (package data ``contourmesh/data/paper/*.csv``); this module computes
ours for every polygon x triangulation and writes CSV, Markdown and PNG next to each other.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from .. import stack_to_mesh
from ..digitize import outer_jordan_stack
from ..measure import relative_error, tradeoff
from ..meshes import atomic_write
from ..shapes import Ellipsoid, Sphere

__all__ = ["paper_table", "reproduce", "DEFAULT_OUT", "SPHERE_RADII", "SPHEROIDS", "COLUMNS"]

SPHERE_RADII = (15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80, 82)
SPHEROIDS = ((10, 6), (15, 8), (20, 10), (25, 13), (30, 15), (35, 17))
POLYGONS = ("dss", "mlp")
TRIANGULATIONS = ("wiederhold", "greedy", "optimal")
COLUMNS = ("size", "polygon", "triangulation", "area_true", "area", "e", "P", "t",
           "paper_area", "paper_e", "paper_P", "paper_t", "watertight", "winding_consistent", "volume")

FOOTNOTE = (
    "t = |e| * P from unrounded e. The paper's t column was computed from e truncated to two or "
    "three digits (r = 25: 0.08 * 1127 = 90.16), so paper_t differs from |paper_e| * paper_P. "
    "paper_e is the paper's unsigned e as printed; our e is signed, (area - area_true) / area_true. "
    "Paper values are given for its own triangulation (wiederhold) only. Poles: where the surface "
    "touches a slicing plane in one grid point (the centred sphere's poles z = +-r) that section is a "
    "one-point contour joined to its neighbour by a fan; other ends get a flat cap."
)


def paper_table(name: str) -> list[dict]:
    """Rows of the paper's table ``"table1_sphere"`` or ``"table2_spheroid"`` as dicts of floats.

    The tables ship as package data (``contourmesh/data/paper/*.csv``), so an installed package
    reads them as well as a checkout does.
    """
    from importlib.resources import files

    if name not in ("table1_sphere", "table2_spheroid"):
        raise ValueError(f"unknown paper table {name!r}; expected 'table1_sphere' or 'table2_spheroid'")
    text = (files("contourmesh") / "data" / "paper" / f"{name}.csv").read_text()
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(lines)]


def _fmt(v, digits=6):
    if v is None or (isinstance(v, str) and v == ""):
        return ""
    if isinstance(v, str):
        return v
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, float) and math.isfinite(v) and v == int(v) and abs(v) < 1e15 and digits > 6:
        return str(int(v))
    return f"{v:.{digits}g}"


def _rows_for(shape, size_label, paper_row, polygons, triangulations):
    stack = outer_jordan_stack(shape)
    area_true = shape.area
    rows = []
    for pol in polygons:
        for tri in triangulations:
            m = stack_to_mesh(stack, polygon=pol, triangulation=tri)
            area = m.area
            e = relative_error(area, area_true)
            chk = m.checks()
            row = {
                "size": size_label, "polygon": pol, "triangulation": tri,
                "area_true": area_true, "area": area, "e": e, "P": m.P, "t": tradeoff(e, m.P),
                "paper_area": "", "paper_e": "", "paper_P": "", "paper_t": "",
                "watertight": chk["watertight"], "winding_consistent": chk["winding_consistent"],
                "volume": chk["volume"],
            }
            if paper_row is not None and tri == "wiederhold":
                key = pol.upper()
                row.update(paper_area=paper_row[f"A_{key}"], paper_e=paper_row[f"e_{key}"],
                           paper_P=int(paper_row[f"P_{key}"]), paper_t=paper_row[f"t_{key}"])
            rows.append(row)
    return rows


def compute_table(which: str, *, sizes=None, polygons=POLYGONS, triangulations=TRIANGULATIONS,
                  progress: bool = True) -> list[dict]:
    """Compute the rows of Table 1 (``which="sphere"``) or Table 2 (``which="spheroid"``)."""
    if which == "sphere":
        paper = {int(r["r"]): r for r in paper_table("table1_sphere")}
        sizes = SPHERE_RADII if sizes is None else sizes
        jobs = [(Sphere(r), str(r), paper.get(r)) for r in sizes]
    elif which == "spheroid":
        paper = {(int(r["a"]), int(r["b"])): r for r in paper_table("table2_spheroid")}
        sizes = SPHEROIDS if sizes is None else sizes
        jobs = [(Ellipsoid(a, b, b), f"{a},{b}", paper.get((a, b))) for a, b in sizes]
    else:
        raise ValueError(f"unknown table {which!r}; expected 'sphere' or 'spheroid'")
    from tqdm.auto import tqdm

    rows = []
    for shape, label, prow in tqdm(jobs, desc=f"{which} sizes", disable=not progress, leave=False):
        rows.extend(_rows_for(shape, label, prow, polygons, triangulations))
    return rows


def rows_to_csv(rows) -> bytes:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([_fmt(r[c], 10) if isinstance(r[c], float) else _fmt(r[c]) for c in COLUMNS])
    return buf.getvalue().encode()


def rows_to_markdown(rows, title: str) -> str:
    cols = ("size", "polygon", "triangulation", "area_true", "area", "e", "P", "t",
            "paper_area", "paper_e", "paper_P", "paper_t")
    fmt = {"area_true": 7, "area": 7, "e": 3, "t": 4, "paper_area": 7, "paper_e": 3, "paper_t": 5}
    out = [f"### {title}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        cells = []
        for c in cols:
            v = r[c]
            if isinstance(v, float) and c in fmt:
                cells.append(f"{v:.{fmt[c]}g}" if c not in ("e",) else f"{v:+.4f}")
            else:
                cells.append(_fmt(v))
        out.append("| " + " | ".join(cells) + " |")
    out += ["", f"Footnote: {FOOTNOTE}", ""]
    return "\n".join(out)


def plot_figure(rows, which: str, path: Path):
    """Relative error |e| and trade-off t against size, ours beside the paper's (Figures 2-3)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    def xval(label):
        return float(label.split(",")[0])

    fig = Figure(figsize=(11, 4.2))  # the object API: the caller's pyplot backend is left alone
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    styles = {"dss": "tab:red", "mlp": "tab:blue"}
    marks = {"wiederhold": "o-", "greedy": "s--", "optimal": "^:"}
    for pol in POLYGONS:
        for tri in TRIANGULATIONS:
            sel = [r for r in rows if r["polygon"] == pol and r["triangulation"] == tri]
            if not sel:
                continue
            x = [xval(r["size"]) for r in sel]
            for ax, key in zip(axes, ("e", "t")):
                ax.plot(x, [abs(r[key]) for r in sel], marks[tri], color=styles[pol], lw=1,
                        ms=7 if tri == "optimal" else 3.5, mfc="none" if tri == "optimal" else None,
                        label=f"ours {pol.upper()} {tri}")
        sel = [r for r in rows if r["polygon"] == pol and r["triangulation"] == "wiederhold" and r["paper_e"] != ""]
        if sel:
            x = [xval(r["size"]) for r in sel]
            for ax, key in zip(axes, ("paper_e", "paper_t")):
                ax.plot(x, [r[key] for r in sel], "x", color=styles[pol], ms=8, mew=2,
                        label=f"paper {pol.upper()}")
    xlabel = "sphere radius r" if which == "sphere" else "spheroid semi-axis a"
    axes[0].set_ylabel("relative error |e|")
    axes[1].set_ylabel("trade-off t = |e| P")
    for ax in axes:
        ax.set_xlabel(xlabel)
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"Surface area of a {which}: ours vs Wiederhold & Villafuerte (2009)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write(path, buf.getvalue())


#: Where :func:`reproduce` writes when no folder is given: ``paper/`` in the current directory.
DEFAULT_OUT = "paper"


def reproduce(out=None, *, progress: bool = True, echo=None) -> dict:
    """Write Tables 1-2 (CSV + Markdown) and Figures 2-3 (PNG) to ``out``; return the rows.

    ``out`` defaults to ``./paper`` under the current working directory (never the checkout's
    ``comparisons/paper``, which holds the committed results).  ``echo``, when given (e.g.
    ``print``), receives each table as Markdown.  Returns ``{"sphere": rows, "spheroid": rows,
    "out": Path, "files": [Path, ...]}``.
    """
    out = Path(out) if out is not None else Path.cwd() / DEFAULT_OUT
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    files = []
    for which, name, fig, title in (
        ("sphere", "table1_sphere", "figure2_sphere.png", "Table 1: sphere"),
        ("spheroid", "table2_spheroid", "figure3_spheroid.png", "Table 2: prolate spheroid (a, b, b)"),
    ):
        rows = compute_table(which, progress=progress)
        files.append(atomic_write(out / f"{name}.csv", rows_to_csv(rows)))
        md = rows_to_markdown(rows, title)
        files.append(atomic_write(out / f"{name}.md", md.encode()))
        plot_figure(rows, which, out / fig)
        files.append(out / fig)
        if echo:
            echo(md)
        results[which] = rows
    results["out"] = out
    results["files"] = files
    return results
