"""The comparison runner: spec -> rows -> results.csv, summary.md, plots; cache, parallel runs, Dask."""

from __future__ import annotations

import argparse
import csv
import json
import time

import numpy as np
import pytest

from contourmesh.compare import methods as M
from contourmesh.compare import runner
from contourmesh.compare.command import add_compare_parser
from contourmesh.compare.inputs import Input, shape_inputs
from contourmesh.compare.report import COLUMNS, empirical_order, fit_orders, read_results_csv, summarize

CALLS = {"count": 0, "fail": 0}


def _count(volume, spacing, origin):
    CALLS["count"] += 1
    from contourmesh.compare.local import surfel_area

    return M.Result(area=surfel_area(volume, spacing))


def _fail(volume, spacing, origin):
    CALLS["fail"] += 1
    raise RuntimeError("deliberate failure for the test")


def _missing(volume, spacing, origin):
    raise M.MissingDependency("nosuchpkg is not installed: pip install nosuchpkg")


def _sleep(volume, spacing, origin):
    time.sleep(60)
    return M.Result(area=1.0)


@pytest.fixture
def fakes(monkeypatch):
    for name, fn in (("t-count", _count), ("t-fail", _fail), ("t-missing", _missing), ("t-sleep", _sleep)):
        monkeypatch.setitem(M._EXTRA, name, M.Method(name=name, family="local", params={}, fn=fn))
    CALLS.update(count=0, fail=0)
    return CALLS


TINY = """
title = "tiny"
seed = 7
repeats = 2
methods = ["t-count", "t-fail", "t-missing"]
[[inputs]]
shape = "sphere"
sizes = [6, 9]
[method."t-missing"]
max_size = 7
"""


@pytest.fixture
def spec(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    return p


def strip(rows):
    return [{k: r[k] for k in COLUMNS if k != "seconds"} for r in rows]


def test_tiny_spec_rows_tables_and_plots(fakes, spec, tmp_path, monkeypatch):
    work = tmp_path / "elsewhere"
    work.mkdir()
    monkeypatch.chdir(work)
    res = runner.run_spec(spec, progress=False)
    out = work / "tiny"  # default: the current directory, not next to the spec (issue 12, item 11)
    assert res["out"] == out and not (spec.parent / "tiny").exists()
    rows = read_results_csv(out / "results.csv")
    assert len(rows) == 2 * 2 * 3
    assert list(rows[0]) == list(COLUMNS)
    by = {}
    for r in rows:
        by.setdefault(r["method"], []).append(r)
    assert {r["status"] for r in by["t-count"]} == {"ok"}
    assert {r["status"] for r in by["t-fail"]} == {"failed"}
    assert all("deliberate failure" in r["error"] for r in by["t-fail"])
    assert sorted(r["status"] for r in by["t-missing"]) == ["not-installed"] * 2 + ["skipped"] * 2
    assert all("pip install nosuchpkg" in r["error"] for r in by["t-missing"] if r["status"] == "not-installed")
    assert all("max_size 7" in r["error"] for r in by["t-missing"] if r["status"] == "skipped")
    for r in by["t-count"]:
        assert r["e"] == pytest.approx((r["area"] - r["area_true"]) / r["area_true"])
        assert 0.2 < r["e"] < 0.7  # surfel counting overestimates by about 50 %
        assert r["area_true"] == pytest.approx(4 * np.pi * float(r["size"]) ** 2)
    assert sorted({(r["size"], r["repeat"]) for r in rows}) == [("6", 0), ("6", 1), ("9", 0), ("9", 1)]
    md = (out / "summary.md").read_text()
    assert "# tiny" in md and "| 9 | t-count | none | 2/2 |" in md and "deliberate failure" in md
    for stem in ("error", "seconds"):  # one file per metric and shape family
        assert (out / f"{stem}-sphere.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # surfel counting has no vertex count, so no t and no trade-off plot
    assert sorted(p.name for p in res["files"] if p.suffix == ".png") == ["error-sphere.png", "seconds-sphere.png"]
    assert fakes["count"] == 4 and fakes["fail"] == 4


def test_rerun_uses_the_cache_and_recomputes_a_corrupt_row(fakes, spec, monkeypatch):
    monkeypatch.chdir(spec.parent)
    first = runner.run_spec(spec, progress=False)
    assert (fakes["count"], fakes["fail"]) == (4, 4)
    again = runner.run_spec(spec, progress=False)
    assert (fakes["count"], fakes["fail"]) == (4, 4)  # nothing re-run ...
    assert again["ran"] == 2  # ... but the not-installed rows, which are re-tried
    assert strip(again["rows"]) == strip(first["rows"])
    # corrupt one finished row's file (a torn write from another tool): it is ignored and recomputed
    cache = spec.parent / "tiny" / "cache"
    ok_key = next(r["key"] for r in first["rows"] if r["method"] == "t-count")
    (cache / f"{ok_key}.json").write_text('{"method": "t-count", "area": 1')
    fail_key = next(r["key"] for r in first["rows"] if r["method"] == "t-fail")
    (cache / f"{fail_key}.json").write_text(json.dumps({"key": "somebody-else", "status": "ok"}))
    third = runner.run_spec(spec, progress=False)
    assert (fakes["count"], fakes["fail"]) == (5, 5)
    assert strip(third["rows"]) == strip(first["rows"])
    json.loads((cache / f"{ok_key}.json").read_text())  # rewritten whole
    assert not list(cache.glob("*.tmp")) and not list(cache.glob(".*.tmp"))


def test_retry_failed(fakes, spec, monkeypatch):
    monkeypatch.chdir(spec.parent)
    runner.run_spec(spec, progress=False)
    runner.run_spec(spec, progress=False, retry_failed=True)
    assert fakes["fail"] == 8 and fakes["count"] == 4


def test_jobs_2_gives_the_same_rows(fakes, spec, tmp_path):
    serial = runner.run_spec(spec, tmp_path / "serial", progress=False)
    pooled = runner.run_spec(spec, tmp_path / "pooled", jobs=2, progress=False)
    assert pooled["ran"] == 10
    assert strip(pooled["rows"]) == strip(serial["rows"])
    with open(tmp_path / "pooled" / "results.csv") as fh:
        assert len(list(csv.DictReader(fh))) == 12


def test_dask_local_cluster_gives_the_same_rows(fakes, spec, tmp_path):
    distributed = pytest.importorskip("distributed")
    serial = runner.run_spec(spec, tmp_path / "serial", progress=False)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        dask = runner.run_spec(spec, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    assert dask["ran"] == 10
    assert strip(dask["rows"]) == strip(serial["rows"])


def test_timeout_row(fakes, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = tmp_path / "slow.toml"
    p.write_text('methods = ["t-sleep", "t-count"]\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n'
                 '[method."t-sleep"]\ntimeout = 0.3\n')
    t0 = time.perf_counter()
    rows = runner.run_spec(p, progress=False)["rows"]
    # the row is cut at its 0.3 s timeout, not left to sleep its 60 s (wide margin: a loaded machine
    # spends seconds starting the worker)
    assert time.perf_counter() - t0 < 40
    assert [r["status"] for r in rows] == ["timeout", "ok"]
    assert "0.3 s" in rows[0]["error"]


def test_ours_on_a_shape_and_postprocess_of_a_meshless_method(tmp_path, fakes, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = tmp_path / "ours.toml"
    p.write_text('methods = ["ours-mlp-wiederhold", "t-count"]\npostprocess = ["none", "merge-coplanar"]\n'
                 '[[inputs]]\nshape = "sphere"\nsizes = [12]\n')
    rows = {(r["method"], r["postprocess"]): r for r in runner.run_spec(p, progress=False)["rows"]}
    ours = rows[("ours-mlp-wiederhold", "none")]
    assert ours["status"] == "ok" and ours["family"] == "ours" and ours["watertight"] is True
    assert abs(ours["e"]) < 0.05 and ours["t"] == pytest.approx(abs(ours["e"]) * ours["P"])
    merged = rows[("ours-mlp-wiederhold", "merge-coplanar")]
    assert merged["status"] == "ok" and merged["area"] == pytest.approx(ours["area"], rel=1e-9)
    bad = rows[("t-count", "merge-coplanar")]
    assert bad["status"] == "failed" and "makes no mesh" in bad["error"]


def test_missing_mesh_file_is_a_no_data_row(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = tmp_path / "m.toml"
    p.write_text('methods = ["surfels"]\n[[inputs]]\nmesh = "meshes/absent.off"\nresolutions = [16, 32]\n')
    rows = runner.run_spec(p, progress=False, data_root=tmp_path)["rows"]
    assert [r["status"] for r in rows] == ["no-data", "no-data"]
    assert "absent.off" in rows[0]["error"] and "CONTOURMESH_DATA" in rows[0]["error"]


def test_empirical_order_on_synthetic_data():
    r = np.array([10, 14, 20, 28, 40, 56, 80])
    assert empirical_order(r, 3.0 / r) == pytest.approx(1.0, abs=1e-12)
    assert empirical_order(r, -0.5 * r ** -2.0) == pytest.approx(2.0, abs=1e-12)  # |e| is used
    noisy = 3.0 / r * np.exp(np.random.default_rng(0).normal(0, 0.05, len(r)))
    assert empirical_order(r, noisy) == pytest.approx(1.0, abs=0.15)
    assert np.isnan(empirical_order([10, 10], [0.1, 0.2]))
    # through the summary: median |e| per size over repeats, one order per (shape, method, post)
    rows = [{"shape": "sphere", "size": str(s), "size_value": float(s), "method": "m", "postprocess": "none",
             "status": "ok", "e": sign * 2.0 / s, "P": 10, "t": None, "seconds": 0.1, "area": 1.0,
             "watertight": None, "error": None} for s in r for sign in (1, -1, 1)]
    (order, n), = fit_orders(summarize(rows)).values()
    assert order == pytest.approx(1.0) and n == len(r)


def test_seeded_random_placements(tmp_path):
    a = shape_inputs("sphere", [10, 20], repeats=3, seed=5)
    b = shape_inputs("sphere", [20], repeats=3, seed=5)
    assert [i.source for i in a[3:]] == [i.source for i in b]  # sub-seeds do not depend on the other sizes
    assert len({i.source for i in a}) == 6
    c = shape_inputs("sphere", [20], repeats=3, seed=6)
    assert [i.source for i in c] != [i.source for i in b]
    for inp in a:
        centre = np.array(inp.shape().center)
        assert np.all((0 <= centre) & (centre < 1))
    rot = shape_inputs("ellipsoid", [[9, 6, 4]], repeats=1, seed=1, rotate=True)[0]
    R = rot.shape().rotation
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_outer_jordan_volume_is_the_cell_dilation():
    g, = shape_inputs("sphere", [6], repeats=1, seed=2)
    oj = Input(**{**g.__dict__, "digitization": "outer-jordan"})
    vg, sg, og = g.volume()
    vo, so, oo = oj.volume()
    assert sg == so and np.allclose(np.subtract(og, oo), 0.5)
    # a cell is in iff one of its 8 corners (grid points) is strictly inside
    p = np.pad(vg, 1)
    for k, j, i in [(0, 0, 0), tuple(np.array(vo.shape) // 2), (3, 5, 4)]:
        assert vo[k, j, i] == p[k:k + 2, j:j + 2, i:i + 2].any()
    assert vo.sum() > vg.sum()


@pytest.mark.parametrize(
    "text, match",
    [
        ('methods = ["nope"]\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n', "unknown method"),
        ('methods = ["ours-mlp-bogus"]\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n', "ours-<polygon>"),
        ('methods = ["surfels"]\n', "inputs"),
        ('methods = ["surfels"]\npostprocess = ["blur"]\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n', "post-process"),
        ('methods = ["surfels"]\n[[inputs]]\nshape = "sphere"\nsizes = [[5, 6]]\n', "a sphere size gives r"),
        ('methods = ["surfels"]\n[[inputs]]\nshape = "sphere"\nsizes = [5]\ndigitization = "inner"\n', "digitization"),
        ('methods = ["surfels"]\n[method.mc-lewiner]\nmax_size = 3\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n',
         "not in methods"),
        ('methods = ["surfels"]\nrepeats = 0\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n', "repeats"),
        ('methods = [\n', "not valid TOML"),
    ],
)
def test_spec_validation(tmp_path, text, match):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        runner.load_spec(p)


def test_cli_parser(fakes, spec, tmp_path, capsys):
    parser = argparse.ArgumentParser(prog="contourmesh")
    add_compare_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["compare", str(spec), "--out", str(tmp_path / "cli"), "--quiet"])
    assert (args.jobs, args.scheduler) == (1, None)
    assert args.func(args) == 0
    assert "12 rows" in capsys.readouterr().out
    assert (tmp_path / "cli" / "results.csv").is_file()


def test_shipped_specs_load():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "comparisons"
    for name in ("spheres", "shapes", "meshes", "quick"):
        spec = runner.load_spec(root / f"{name}.toml")
        tasks = runner.plan(spec)
        assert len({t.key for t in tasks}) == len(tasks)
    spheres = runner.load_spec(root / "spheres.toml")
    assert len({i.size for i in spheres.inputs}) >= 8 and spheres.repeats == 5
    # the quick spec (README: "runs in under a minute") stays small: no slow peers, few rows
    quick = runner.load_spec(root / "quick.toml")
    assert len(runner.plan(quick)) <= 60
    assert not [m for m in quick.methods if m.split("-")[0] in ("o3d", "ml", "dgtal")]


def _synthetic_rows():
    """Rows of one shape family: ours (two variants) and five peers with known error levels."""
    levels = {"ours-mlp-wiederhold": 1e-2, "ours-mlp-optimal-band": 1e-4, "p-best": 2e-4, "p-second": 5e-4,
              "p-third": 1e-3, "p-fourth": 3e-2, "p-small-only": 1e-6}
    rows = []
    for m, level in levels.items():
        for s in (10, 20, 40, 80):
            if m == "p-small-only" and s > 20:  # strong at small sizes only: not among the strongest
                continue
            rows.append({"shape": "sphere", "size": str(s), "size_value": float(s), "method": m, "postprocess": "none",
                         "status": "ok", "e": level * (1 + 0.01 * s), "P": 100 if m != "p-second" else None,
                         "t": level * 100 if m != "p-second" else None, "seconds": 0.1, "area": 1.0,
                         "watertight": None, "error": None})
    return rows


def test_plots_highlight_ours_and_the_three_strongest_peers(tmp_path):
    # issue 12 item 13: 25 methods in look-alike colours on one axis; ours could not be found
    from contourmesh.compare.report import highlighted, plot_results

    summary = summarize(_synthetic_rows())
    ours, peers = highlighted(summary, "sphere")
    assert ours == [("ours-mlp-optimal-band", "none"), ("ours-mlp-wiederhold", "none")]
    assert peers == [("p-best", "none"), ("p-second", "none"), ("p-third", "none")]
    # for t, a peer without a vertex count gives way to the next one
    assert highlighted(summary, "sphere", having="t")[1] == [("p-best", "none"), ("p-third", "none"), ("p-fourth", "none")]
    import matplotlib

    old = matplotlib.get_backend()
    matplotlib.use("template", force=True)
    try:
        files = plot_results(_synthetic_rows(), tmp_path)
        assert matplotlib.get_backend() == "template"  # the object API: no matplotlib.use
    finally:
        matplotlib.use(old, force=True)
    assert sorted(p.name for p in files) == ["error-sphere.png", "seconds-sphere.png", "tradeoff-sphere.png"]
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in files)


def test_run_method_runs_ours_like_any_other_method():
    # issue 11: run_method("ours-mlp-wiederhold", volume) answered "unknown method"
    vol = np.zeros((12, 12, 12), dtype=bool)
    vol[2:10, 2:10, 2:10] = True
    row = M.run_method("ours-mlp-wiederhold", vol, spacing=(2.0, 1.0, 1.0))
    assert row["status"] == "ok", row["error"]
    assert row["family"] == "ours" and row["watertight"] is True
    # the surface through the boundary voxel centres: a 14 x 7 x 7 box (z spacing 2)
    assert row["area"] == pytest.approx(2 * (7 * 7) + 4 * (7 * 14))
    assert M.get_method("ours-dss-optimal-band").params == {"polygon": "dss", "triangulation": "optimal",
                                                            "refine": "band"}
    with pytest.raises(ValueError, match="ours-<polygon>"):
        M.get_method("ours-mlp")


def test_cli_compare_writes_to_the_current_directory_and_says_where(tmp_path):
    # issue 12 item 11: compare wrote into the checkout's comparisons/ from any directory, silently
    import os
    import subprocess
    import sys
    from pathlib import Path

    specs = tmp_path / "specs"
    specs.mkdir()
    (specs / "one.toml").write_text('methods = ["surfels"]\n[[inputs]]\nshape = "sphere"\nsizes = [4]\n')
    work = tmp_path / "work"
    work.mkdir()
    src = str(Path(runner.__file__).resolve().parents[2])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]))
    run = subprocess.run([sys.executable, "-m", "contourmesh", "compare", str(specs / "one.toml"), "--quiet"],
                         cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert (work / "one" / "results.csv").is_file()
    assert sorted(p.name for p in specs.iterdir()) == ["one.toml"]  # nothing next to the spec
    assert f"wrote {work / 'one'}" in run.stdout


# issue 14: the band's rows on the real shapes took 50-90x the paper mode's time where a worker's
# first row compiled the numba kernels (the disk cache was stale after a merge); run_spec now warms
# our methods up before the rows.  The probe counts the kernel signatures a row adds in a fresh
# process: compiled or loaded from the cache inside the row without the warm-up, none with it.
_WARM_PROBE = r"""
import sys
import numpy as np
import numba.core.registry as reg
from scipy.ndimage import gaussian_filter
from contourmesh.compare import runner
from contourmesh.compare.methods import get_method

def signatures():
    return sum(len(v.signatures) for name, mod in list(sys.modules.items()) if name.startswith("contourmesh")
               for v in vars(mod).values() if isinstance(v, reg.CPUDispatcher))

methods = ["ours-mlp-wiederhold", "ours-mlp-optimal-band"]
if sys.argv[1] == "warm":
    assert runner.warm_up(methods + ["mc-lewiner"]) == methods
zz, yy, xx = np.mgrid[:16, :19, :17]
ellipsoid = (zz - 7.6) ** 2 / 1.8 + (yy - 9.2) ** 2 + (xx - 8.1) ** 2 / 1.3 < 36
noise = np.pad(gaussian_filter(np.random.default_rng(5).standard_normal((18, 20, 19)), 1.7) > 0.0, 1)
before = signatures()
for vol in (ellipsoid, noise):
    for name in methods:
        m = get_method(name)
        m.fn(vol, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), **m.params)
print(signatures() - before)
"""


def test_warm_up_leaves_no_kernel_to_compile_or_load_in_a_row():
    import subprocess
    import sys

    def added(mode):
        run = subprocess.run([sys.executable, "-c", _WARM_PROBE, mode], capture_output=True, text=True, timeout=900)
        assert run.returncode == 0, run.stderr[-2000:]
        return int(run.stdout.split()[-1])

    assert added("cold") > 0  # without the warm-up the rows pay for the kernels
    assert added("warm") == 0


def test_run_spec_warms_our_methods_before_the_rows(fakes, tmp_path, monkeypatch):
    order = []
    monkeypatch.setattr(runner, "warm_up", lambda methods: order.append(("warm", sorted(set(methods)))))
    real_execute = runner.execute
    monkeypatch.setattr(runner, "execute", lambda task: order.append(("row", task.method)) or real_execute(task))
    p = tmp_path / "s.toml"
    p.write_text('methods = ["t-count"]\n[[inputs]]\nshape = "sphere"\nsizes = [5]\n')
    runner.run_spec(p, tmp_path / "out", progress=False)
    assert order == [("warm", ["t-count"]), ("row", "t-count")]
    order.clear()
    runner.run_spec(p, tmp_path / "out2", progress=False, warm=False)
    assert order == [("row", "t-count")]


def test_warm_rare_compiles_both_two_scale_target_forms():
    """The band refinement's ``_two_scale_targets`` is called with a gain per vertex (rings with
    creases) or without (``None``): the warm-up compiles both, so no real row compiles one."""
    from contourmesh.compare.runner import _warm_rare
    from contourmesh.refine import _two_scale_targets

    _warm_rare()
    last = [str(sig[-1]) for sig in _two_scale_targets.signatures]
    assert "none" in last and any(s.startswith("array(float64") for s in last), last
