"""Multigrid convergence of the surface area: contourmesh ``refine="band"`` against the paper's
MLP stacks and the volume peers (issue 6).

Regenerates, next to this file: ``results.csv`` (one row per shape instance x size x method),
``table.md`` (median |e|, P and t = |e| P per shape family, size and method, with the fitted
order of convergence) and ``loglog.png``.

Run:  PYTHONPATH=src .venv/bin/python comparisons/convergence/run.py [--quick]
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from pathlib import Path

import numpy as np

import contourmesh
from contourmesh.digitize import gauss_volume, outer_jordan_stack
from contourmesh.meshes import atomic_write
from contourmesh.refine import band_violations


def band_mesh(source, *, refine="band", triangulation="optimal", **kw):
    return contourmesh.mesh(source, refine=refine, triangulation=triangulation, **kw)
from contourmesh.shapes import Ellipsoid, Sphere, Torus, rotation_from_euler
from contourmesh.tracing import trace_contours
from contourmesh.types import ContourStack, Section

HERE = Path(__file__).resolve().parent
SIZES = (20, 40, 80, 160)
PEERS = {  # peer -> largest size it is run at (cost)
    "vtk-surfacenets": 160,
    "mc-lewiner-blur1": 160,
    "dgtal-vcm-R5-r3": 40,
}


def volume_stack(vol, origin, h=1.0) -> ContourStack:
    """Contour stack of a Gauss-digitized volume ``[z, y, x]`` (each slice traced as I)."""
    x0, y0, z0 = (int(round(v / h)) for v in origin)
    secs = []
    for n in range(vol.shape[0]):
        if not vol[n].any():
            continue
        cs, ps = trace_contours(vol[n], x0=x0, y0=y0)
        secs.append(Section(z=(z0 + n) * h, contours=tuple(np.asarray(c, dtype=np.int64) for c in cs),
                            parents=tuple(int(p) for p in ps)))
    return ContourStack(sections=tuple(secs), spacing=(h, h), origin=(0.0, 0.0))


def instances(quick: bool):
    """(family, size, instance id, shape) for every experiment."""
    rng = np.random.default_rng(2024)
    n_sph = 3 if quick else 5
    sizes = SIZES[:3] if quick else SIZES
    for fam in ("sphere-oj", "sphere-gauss"):
        centres = rng.uniform(-0.5, 0.5, (n_sph, 3))
        for r in sizes:
            for i, c in enumerate(centres):
                yield fam, r, i, Sphere(r, center=tuple(c))
    centres = rng.uniform(-0.5, 0.5, (3, 3))
    for a in sizes:  # the paper's spheroid (a, b, b), a : b = 5 : 3, grown by scaling
        for i, c in enumerate(centres):
            yield "spheroid", a, i, Ellipsoid(a, 0.6 * a, 0.6 * a, center=tuple(c))
    axes = rng.uniform(0.55, 1.0, (3, 3))
    axes[:, 0] = 1.0
    angles = rng.uniform(0, 180, (3, 3))
    centres = rng.uniform(-0.5, 0.5, (3, 3))
    for s in sizes:  # ellipsoids with random axes and random rotations, largest semi-axis s
        for i in range(3):
            a, b, c = (s * axes[i]).tolist()
            yield "ellipsoid-rot", s, i, Ellipsoid(a, b, c, center=tuple(centres[i]),
                                                    rotation=rotation_from_euler(*angles[i]))
    for s in sizes[:3]:  # torus R : r = 3 : 1, lying flat: an outer contour and a hole in every slice
        yield "torus", s, 0, Torus(s * 0.75, s * 0.25, center=(0.3, 0.1, 0.2))


#: Our methods: the paper's (MLP stack) and the band refinement, each with two band rules.
OURS = {"mlp-wiederhold": dict(refine="none", triangulation="wiederhold"),
        "mlp-optimal": dict(refine="none", triangulation="optimal"),
        "band-optimal": dict(refine="band", triangulation="optimal"),
        "band-wiederhold": dict(refine="band", triangulation="wiederhold")}


def run(quick: bool, family=None, methods=None, p_mlp=None):
    """The rows of every experiment (of ``family`` only, if given); ``methods``: only these of
    ours and no peers, with the MLP stack's vertex count for ``P_over_mlp`` from ``p_mlp``
    (``(family, size, instance) -> P`` of the ``mlp-wiederhold`` rows kept)."""
    from contourmesh.compare.methods import run_method

    rows = []
    for fam, size, inst, shape in instances(quick):
        if family is not None and fam != family:
            continue
        true = float(shape.area)
        if fam == "sphere-gauss":
            vol, org = gauss_volume(shape)
            stack = volume_stack(vol, org)
        else:
            stack = outer_jordan_stack(shape)
        P_mlp = (p_mlp or {}).get((fam, size, inst))
        for name, kw in OURS.items():
            if methods is not None and name not in methods:
                continue
            t0 = time.perf_counter()
            try:
                m = band_mesh(stack, **kw)
                chk = m.checks()
                viol = band_violations(stack, m) if kw["refine"] == "band" else None
                row = dict(status="ok", area=m.area, P=int(m.P), watertight=chk.get("watertight"),
                           outward=chk.get("volume", 0) > 0, band_violations=viol)
                if name == "mlp-wiederhold":
                    P_mlp = int(m.P)
            except Exception as exc:  # noqa: BLE001 - a failure is a row
                row = dict(status=f"failed: {type(exc).__name__}: {exc}"[:120])
            row.update(family=fam, size=size, instance=inst, method=name, area_true=true,
                       seconds=time.perf_counter() - t0)
            rows.append(row)
        peers_here = fam.startswith("sphere") and inst < 2 or (fam != "sphere-oj" and fam != "sphere-gauss" and inst == 0)
        if methods is None and peers_here:  # (with methods: only those of ours)
            vol, org = gauss_volume(shape)
            for peer, smax in PEERS.items():
                if size > smax or (quick and size > 80):
                    continue
                t0 = time.perf_counter()
                res = run_method(peer, vol, (1.0, 1.0, 1.0), org)
                row = dict(status=res["status"], area=res["area"], P=res["P"], watertight=res["watertight"],
                           outward=(res["volume"] or 0) > 0 if res["volume"] is not None else None)
                row.update(family=fam, size=size, instance=inst, method=peer, area_true=true,
                           seconds=time.perf_counter() - t0)
                rows.append(row)
        for r in rows[-12:]:
            if r["family"] == fam and r["size"] == size and r["instance"] == inst and r.get("area"):
                r["e"] = r["area"] / r["area_true"] - 1
                r["t"] = abs(r["e"]) * r["P"] if r.get("P") else None
                r["P_over_mlp"] = r["P"] / P_mlp if (P_mlp and r.get("P")) else None
        done = [r for r in rows[-12:] if r["instance"] == inst and r["size"] == size and r["family"] == fam]
        print(fam, size, inst, "  ".join(f"{r['method']}={100 * r['e']:+.4f}%" for r in done if "e" in r),
              f"({sum(r['seconds'] for r in done):.1f}s)", flush=True)
    return rows


COLS = ("family", "size", "instance", "method", "status", "area_true", "area", "e", "P", "P_over_mlp", "t",
        "watertight", "outward", "band_violations", "seconds")


def slope(sizes, errs):
    x, y = np.log(np.asarray(sizes, float)), np.log(np.asarray(errs, float))
    ok = np.isfinite(y)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(x[ok], y[ok], 1)[0])


def summarize(rows):
    """{(family, method): {size: (median |e|, median P, median t, n)}} and slopes."""
    out = {}
    for r in rows:
        if "e" not in r:
            continue
        out.setdefault((r["family"], r["method"]), {}).setdefault(r["size"], []).append(r)
    summ = {}
    for key, by in out.items():
        summ[key] = {s: (float(np.median([abs(x["e"]) for x in v])),
                         float(np.median([x["P"] if x.get("P") else np.nan for x in v])),
                         float(np.median([x["t"] if x.get("t") else np.nan for x in v])), len(v))
                     for s, v in sorted(by.items())}
    return summ


def write_csv(rows):
    import io


    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=COLS, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{r[k]:.10g}" if isinstance(r.get(k), float) else r.get(k)) for k in COLS})
    atomic_write(HERE / "results.csv", buf.getvalue().encode())


def read_csv():
    rows = []
    with open(HERE / "results.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            for k in ("size", "instance", "P", "band_violations"):
                r[k] = int(r[k]) if r.get(k) not in (None, "", "None") else None
            for k in ("area_true", "area", "e", "P_over_mlp", "t", "seconds"):
                r[k] = float(r[k]) if r.get(k) not in (None, "", "None") else None
            if r["e"] is None:
                del r["e"]
            rows.append(r)
    return rows


def write(rows, quick):
    summ = summarize(rows)
    fams = list(dict.fromkeys(r["family"] for r in rows))
    lines = ["# Multigrid convergence: median |e| (%), median P, median t = |e| P", "",
             "Generated by `comparisons/convergence/run.py`" + (" --quick" if quick else "") + "; "
             "slope = least-squares slope of log median |e| against log size over the sizes shown.", ""]
    for fam in fams:
        methods = [m for (f, m) in summ if f == fam]
        sizes = sorted({s for (f, m), v in summ.items() if f == fam for s in v})
        lines += [f"## {fam}", "", "| method | " + " | ".join(f"size {s}: \\|e\\| % / P / t" for s in sizes) + " | slope |",
                  "|---|" + "---|" * (len(sizes) + 1)]
        for m in methods:
            v = summ[(fam, m)]
            cells = [f"{100 * v[s][0]:.4f} / {v[s][1]:.0f} / {v[s][2]:.2f}" if s in v else "" for s in sizes]
            sl = slope(list(v), [v[s][0] for s in v])
            lines.append(f"| {m} | " + " | ".join(cells) + f" | {sl:.2f} |")
        fails = sorted({r["status"] for r in rows if r["family"] == fam and r["status"] != "ok"})
        if fails:
            lines += ["", "Failures: " + "; ".join(fails)]
        lines.append("")

    atomic_write(HERE / "table.md", "\n".join(lines).encode())
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot", file=sys.stderr)
        return
    fams_p = [f for f in fams if any(f == k[0] for k in summ)]
    fig, axs = plt.subplots(1, len(fams_p), figsize=(4.2 * len(fams_p), 4), squeeze=False)
    for ax, fam in zip(axs[0], fams_p):
        for (f, m), v in summ.items():
            if f != fam:
                continue
            s = list(v)
            e = [100 * v[x][0] for x in s]
            style = "o-" if m.startswith("band") else ("s--" if m.startswith("mlp") else "^:")
            ax.loglog(s, e, style, label=f"{m} ({slope(s, e):.2f})")
        ss = np.array([20, 160])
        ax.loglog(ss, 0.2 * (ss / 20.0) ** -1.0, "k-", lw=0.6, alpha=0.5, label="order 1")
        ax.set_title(fam)
        ax.set_xlabel("size (radius / largest semi-axis, voxels)")
        ax.set_ylabel("median |e| (%)")
        ax.legend(fontsize=6)
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    atomic_write(HERE / "loglog.png", buf.getvalue())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="sizes 20-80, fewer instances")
    ap.add_argument("--from-csv", action="store_true", help="only rebuild table.md and loglog.png from results.csv")
    ap.add_argument("--family", default=None, help="re-run one family only (e.g. torus), replacing its rows")
    ap.add_argument("--methods", default=None,
                    help="re-run only these of ours (comma-separated, e.g. band-optimal,band-wiederhold), "
                         "replacing their rows and keeping every other row")
    args = ap.parse_args(argv)
    if args.from_csv:
        rows = read_csv()
    elif args.methods:
        methods = {m for m in args.methods.split(",") if m}
        unknown = methods - set(OURS)
        if unknown:
            ap.error(f"--methods: unknown {sorted(unknown)}; ours are {list(OURS)}")
        old = read_csv()
        p_mlp = {(r["family"], r["size"], r["instance"]): r["P"] for r in old
                 if r["method"] == "mlp-wiederhold" and r.get("P")}
        new = {(r["family"], r["size"], r["instance"], r["method"]): r
               for r in run(args.quick, args.family, methods, p_mlp)}
        rows = [new.pop((r["family"], r["size"], r["instance"], r["method"]), r) for r in old]
        rows += list(new.values())
        write_csv(rows)
    elif args.family:
        rows = [r for r in read_csv() if r["family"] != args.family] + run(args.quick, args.family)
        write_csv(rows)
    else:
        rows = run(args.quick)
        write_csv(rows)
    write(rows, args.quick)


if __name__ == "__main__":
    main()
