"""The real-shapes comparison (comparisons/real/, issue 14 item 4): the spec, the pooled statistics, a tiny run."""

import json
from pathlib import Path

import numpy as np
import pytest

from contourmesh.compare import real
from contourmesh.compare.inputs import data_dir, mesh_inputs
from contourmesh.compare.methods import get_method
from contourmesh.compare.report import read_results_csv
from contourmesh.compare.runner import load_spec

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "comparisons" / "real" / "real.toml"
MESHES = {"armadillo", "lion", "rocker-arm", "fertility", "bunny", "spot", "3holes", "quadknot", "socket", "aneurysm",
          "elephant", "cheburashka", "fandisk", "torus"}


def test_spec_parses_and_covers_the_issue(tmp_path):
    # an empty data folder: the spec still parses (its rows would be "no-data"), and fast
    spec = load_spec(SPEC, data_root=tmp_path)
    for m in spec.methods:
        get_method(m)  # registered (load_spec checks it too; this names the method on failure)
    need = {"ours-mlp-wiederhold", "ours-mlp-optimal-band", "mc-lewiner", "mc-lewiner-blur1", "vtk-surfacenets",
            "vtk-flyingedges", "dgtal-ii-r3", "dgtal-vcm-R5-r3", "lindblad", "mullikin-verbeek", "o3d-poisson-d8",
            "serra", "serra-taubin10", "zmesh"}
    assert need <= set(spec.methods)
    assert get_method("ours-mlp-optimal-band").params.get("refine") == "band"
    by = {}
    for inp in spec.inputs:
        by.setdefault(real.split_name(inp.name), []).append(inp)
    assert {m for m, _ in by} == MESHES
    for (mesh, placement), inputs in by.items():
        assert sorted({int(i.size) for i in inputs}) == [64, 128, 256]
        if placement == "axis-aligned":
            assert all(i.rotation == () and i.offset == () and i.repeat == 0 for i in inputs)
        else:  # 3 seeded rotations, the same at every resolution
            assert sorted({i.repeat for i in inputs}) == [0, 1, 2]
            for r in range(3):
                rots = {i.rotation for i in inputs if i.repeat == r}
                assert len(rots) == 1 and len(next(iter(rots))) == 9
            assert len({i.rotation for i in inputs}) == 3


def test_placement_per_repeat_or_per_resolution(tmp_path):
    per_n = mesh_inputs("x.off", [16, 32], rotate=True, offset=True, seed=3, repeats=2, root=tmp_path)
    same = mesh_inputs("x.off", [16, 32], rotate=True, offset=True, seed=3, repeats=2, root=tmp_path,
                       placement="per-repeat")
    assert per_n[0].rotation != per_n[2].rotation  # repeat 0 at 16 and at 32
    assert same[0].rotation == same[2].rotation and same[0].offset == same[2].offset
    assert same[0].rotation != same[1].rotation
    assert all(i.error and "not found" in i.error for i in same)
    with pytest.raises(ValueError, match="placement"):
        mesh_inputs("x.off", [16], placement="sometimes", root=tmp_path)


def _row(shape, size, method, e, status="ok", repeat=0):
    return {"shape": shape, "size": str(size), "method": method, "e": e if status == "ok" else None,
            "status": status, "repeat": repeat, "seconds": 1.0, "error": None if status == "ok" else "no: slice 3 has 2",
            "meta": None}


def test_pooled_statistics_and_order():
    rows = []
    for n, scale in ((64, 4.0), (128, 2.0), (256, 1.0)):
        rows += [_row("a", n, "m", 0.01 * scale), _row("b", n, "m", -0.03 * scale), _row("c", n, "m", 0.02 * scale)]
        rows += [_row("a-rot", n, "m", 0.05 * scale, repeat=1)]
    rows += [_row("a", 64, "x", 0.1), _row("b", 64, "x", None, status="failed"), _row("a", 128, "x", 0.05),
             _row("b", 128, "x", 0.05)]
    pool = {(d["placement"], d["method"], d["N"]): d for d in real.pooled(rows)}
    d = pool[("axis-aligned", "m", 64)]
    assert (d["n"], d["n_ok"]) == (3, 3)
    assert d["e_median"] == pytest.approx(0.04) and d["abs_median"] == pytest.approx(0.08)
    assert d["abs_max"] == pytest.approx(0.12) and d["worst"] == "b"
    assert pool[("rotated", "m", 256)]["worst"] == "a #1"
    assert pool[("axis-aligned", "x", 64)]["statuses"] == {"failed": 1}
    orders = real.orders(real.pooled(rows))
    assert orders[("axis-aligned", "m")] == (pytest.approx(1.0), 3)
    assert orders[("axis-aligned", "x")][1] == 1  # the partial resolution 64 does not count
    part = {(d["method"], d["N"]): d for d in real.pooled(rows, planned={("axis-aligned", 128): 3})}
    assert part[("x", 128)]["statuses"] == {"not run yet": 1} and part[("x", 128)]["planned"] == 3
    assert ("axis-aligned", "x") not in real.orders(list(part.values()))  # 64 failed a row, 128 is partial
    md = real.markdown(rows, title="t", methods=["m", "x"])
    assert "| m | 3/3 | +4.00% | 8.00% | 12.00% (b) |" in md
    assert "| x | 64 | failed | 1 | b | no: slice # has # |" in md


def _socket():
    path = data_dir() / "meshes" / "cgogn" / "socket.off"
    if not path.is_file():
        pytest.skip(f"the shared data folder is absent ({path} not found; set CONTOURMESH_DATA)")
    return path


TINY = """
title = "tiny real"
seed = 7
timeout = 120
methods = ["ours-mlp-wiederhold", "lindblad"]

[[inputs]]
mesh = "meshes/cgogn/socket.off"
name = "socket"
resolutions = [24]

[[inputs]]
mesh = "meshes/cgogn/socket.off"
name = "socket-rot"
resolutions = [24]
rotate = true
offset = true
placement = "per-repeat"
"""


def test_tiny_run_rows_summary_plot_and_resume(tmp_path):
    _socket()
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY)
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=r"sizes \['99'\] not in the spec"):
        real.run(spec, out, resolutions=[99], progress=False)
    part = real.run(spec, out, methods=["lindblad"], resolutions=[24], progress=False, write_plot=False)  # a part
    assert part["ran"] == 2 and {r["method"] for r in part["rows"]} == {"lindblad"}
    res = real.run(spec, out, jobs=1, progress=False)  # the rest; lindblad's rows come from the cache
    assert res["ran"] == 2 and res["cached"] == 2 and res["imported"] == 0
    rows = read_results_csv(out / "results.csv")
    assert len(rows) == 4 and {r["status"] for r in rows} == {"ok"}
    assert {(r["shape"], r["method"]) for r in rows} == {(s, m) for s in ("socket", "socket-rot")
                                                         for m in ("ours-mlp-wiederhold", "lindblad")}
    for r in rows:
        assert r["e"] == pytest.approx(r["area"] / r["area_true"] - 1) and abs(r["e"]) < 0.6
        if r["method"] == "lindblad":  # an area estimate, no mesh: no meta
            assert r["meta"] is None and r["faces"] is None
            continue
        meta = json.loads(r["meta"])
        assert 0.0 <= meta["axis_wall_fraction"] <= 1.0 and r["watertight"]
        assert isinstance(meta["exact_joins"], int) and meta["polygon"] == "mlp"
    md = (out / "summary.md").read_text()
    for r in rows:  # each row is its own pooled group here: median = max = the row's |e|
        placement = "Rotated" if r["shape"].endswith("-rot") else "Axis-aligned"
        section = md.split(f"## {placement}")[1].split("## ")[0]
        cells = f"| {r['method']} | 1/1 | {r['e']:+.2%} | {abs(r['e']):.2%} | {abs(r['e']):.2%} (socket"
        assert cells in section
    assert "| socket | 24 |" in md.split("## Per mesh")[1]
    assert (out / "error.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    runs = (out / "runs.csv").read_text().splitlines()
    assert len(runs) == 3 and runs[1].split(",")[-2] == "2" and runs[2].split(",")[-2] == "2"
    # a fresh checkout (no cache) resumes from the committed results.csv: nothing is recomputed
    for f in (out / "cache").iterdir():
        f.unlink()
    again = real.run(spec, out, jobs=1, progress=False, write_plot=False)
    assert again["ran"] == 0 and again["imported"] == 4
    assert [(r["key"], r["area"]) for r in read_results_csv(out / "results.csv")] == [(r["key"], r["area"]) for r in rows]
    assert len((out / "runs.csv").read_text().splitlines()) == 3  # a run that computed nothing is not logged
    np.testing.assert_allclose(sorted(r["e"] for r in again["rows"]), sorted(r["e"] for r in rows))
