"""Reproduction of the paper's Tables 1-2: our values beside the published ones, within stated tolerances."""

import csv
import io

import pytest

from contourmesh.compare.paper import (
    compute_table,
    paper_table,
    plot_figure,
    reproduce,
    rows_to_csv,
    rows_to_markdown,
)


@pytest.fixture(scope="module")
def table1():
    return compute_table("sphere", progress=False)


@pytest.fixture(scope="module")
def table2():
    return compute_table("spheroid", progress=False)


def _by(rows, pol, tri):
    return {r["size"]: r for r in rows if r["polygon"] == pol and r["triangulation"] == tri}


def test_paper_data_is_typed_consistently():
    t1 = paper_table("table1_sphere")
    assert len(t1) == 15 and t1[0]["r"] == 15 and t1[-1]["r"] == 82
    for row in t1:
        # the published true areas are 4 pi r^2, rounded to 4 significant digits
        assert row["A"] == pytest.approx(4 * 3.141592653589793 * row["r"] ** 2, rel=2e-3)
    t2 = paper_table("table2_spheroid")
    assert [(r["a"], r["b"]) for r in t2] == [(10, 6), (15, 8), (20, 10), (25, 13), (30, 15), (35, 17)]


def test_table1_rows_and_meshes(table1):
    assert len(table1) == 15 * 2 * 3
    for r in table1:
        assert r["watertight"] and r["winding_consistent"] and r["volume"] > 0
        assert r["t"] == pytest.approx(abs(r["e"]) * r["P"])
        assert r["area_true"] == pytest.approx(4 * 3.141592653589793 * float(r["size"]) ** 2)


def test_table1_mlp_within_1pct_and_dss_within_3pct_of_paper(table1):
    for pol, tol in (("mlp", 0.01), ("dss", 0.03)):
        rows = _by(table1, pol, "wiederhold")
        for size, r in rows.items():
            if int(size) >= 25:
                assert abs(r["area"] / r["paper_area"] - 1) <= tol, (pol, size, r["area"], r["paper_area"])


def test_table1_optimal_mlp_error_below_0_8pct(table1):
    for size, r in _by(table1, "mlp", "optimal").items():
        if int(size) >= 25:
            assert abs(r["e"]) <= 0.008, (size, r["e"])


def test_optimal_never_above_other_triangulations(table1, table2):
    for rows in (table1, table2):
        for pol in ("dss", "mlp"):
            opt = _by(rows, pol, "optimal")
            for tri in ("wiederhold", "greedy"):
                for size, r in _by(rows, pol, tri).items():
                    assert opt[size]["area"] <= r["area"] + 1e-9


def test_table2_spheroid_true_areas_match_paper(table2):
    for r in _by(table2, "mlp", "wiederhold").values():
        a, b = map(float, r["size"].split(","))
        published = [p for p in paper_table("table2_spheroid") if (p["a"], p["b"]) == (a, b)][0]["A"]
        assert r["area_true"] == pytest.approx(published, abs=0.01)
        assert r["watertight"] and r["volume"] > 0


def test_outputs_csv_markdown_png(tmp_path, table1):
    data = rows_to_csv(table1)
    rows = list(csv.DictReader(io.StringIO(data.decode())))
    assert list(rows[0])[:12] == ["size", "polygon", "triangulation", "area_true", "area", "e", "P", "t",
                                 "paper_area", "paper_e", "paper_P", "paper_t"]
    assert rows[0]["paper_area"] != "" and [r for r in rows if r["triangulation"] == "optimal"][0]["paper_area"] == ""
    md = rows_to_markdown(table1, "Table 1")
    assert md.count("\n| ") == len(table1) + 1 and "Footnote" in md
    png = tmp_path / "f.png"
    plot_figure(table1, "sphere", png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_reproduce_writes_everything(tmp_path, monkeypatch):
    import contourmesh.compare.paper as paper

    small = {"sphere": (15, 25), "spheroid": ((10, 6),)}
    real = paper.compute_table
    monkeypatch.setattr(paper, "compute_table", lambda which, progress=True: real(which, sizes=small[which], progress=False))
    from contourmesh.cli import main

    assert main(["reproduce", "--out", str(tmp_path), "--quiet"]) == 0
    for name in ("table1_sphere.csv", "table2_spheroid.csv", "table1_sphere.md", "table2_spheroid.md",
                 "figure2_sphere.png", "figure3_spheroid.png"):
        assert (tmp_path / name).stat().st_size > 0, name


def _small_tables(monkeypatch):
    import contourmesh.compare.paper as paper

    small = {"sphere": (15,), "spheroid": ((10, 6),)}
    real = paper.compute_table
    monkeypatch.setattr(paper, "compute_table", lambda which, progress=True: real(which, sizes=small[which], progress=False))


def test_reproduce_writes_to_the_current_directory_by_default(tmp_path, monkeypatch):
    # issue 12 item 11: without --out, reproduce wrote into the checkout's comparisons/paper
    from pathlib import Path

    import contourmesh
    from contourmesh.cli import main

    checkout_paper = Path(contourmesh.__file__).resolve().parents[2] / "comparisons" / "paper"
    before = {p.name: p.stat().st_mtime_ns for p in checkout_paper.glob("*")} if checkout_paper.is_dir() else {}
    _small_tables(monkeypatch)
    monkeypatch.chdir(tmp_path)
    assert main(["reproduce", "--quiet"]) == 0
    for name in ("table1_sphere.csv", "table2_spheroid.md", "figure2_sphere.png"):
        assert (tmp_path / "paper" / name).stat().st_size > 0, name
    after = {p.name: p.stat().st_mtime_ns for p in checkout_paper.glob("*")} if checkout_paper.is_dir() else {}
    assert after == before


def test_reproduce_returns_the_folder_and_files(tmp_path, monkeypatch):
    _small_tables(monkeypatch)
    res = reproduce(tmp_path / "out", progress=False)
    assert res["out"] == tmp_path / "out"
    assert sorted(p.name for p in res["files"]) == sorted(
        ["table1_sphere.csv", "table1_sphere.md", "figure2_sphere.png",
         "table2_spheroid.csv", "table2_spheroid.md", "figure3_spheroid.png"])
    assert all(p.is_file() for p in res["files"])


def test_plot_figure_leaves_the_matplotlib_backend_alone(tmp_path, table1):
    # issue 11: plot_figure called matplotlib.use("Agg"), switching a notebook's backend
    import matplotlib

    old = matplotlib.get_backend()
    matplotlib.use("template", force=True)
    try:
        plot_figure(table1, "sphere", tmp_path / "f.png")
        assert matplotlib.get_backend() == "template"
    finally:
        matplotlib.use(old, force=True)
    assert (tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"
