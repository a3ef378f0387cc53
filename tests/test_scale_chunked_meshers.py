"""The anchors of issue 17 run chunk by chunk (benchmarks/chunked_meshers.py): serra-mesh and zmesh meshed
over a volume's chunks with their halos, each label's pieces welded by exact vertex equality.

Without smoothing both meshers are local, so the welded mesh must be the one-piece mesh: the same
faces (count), the same area and volume. With serra-mesh's smoothing (its seam cells are pinned) it is
closed but not the same. A label whose faces come after its weld, or a weld that is not closed, is a
failed row that says so."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("serra_mesh", reason="serra-mesh is not installed")
pytest.importorskip("zmesh", reason="zmesh is not installed")

from contourmesh.cells import cells_volume, synthetic_cells  # noqa: E402

SHAPE = (40, 60, 60)


def _bench():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "chunked_meshers.py"
    spec = importlib.util.spec_from_file_location("chunked_meshers", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def bench():
    return _bench()


@pytest.fixture(scope="module")
def volume():
    vol = cells_volume(SHAPE, synthetic_cells(SHAPE, cell=20, seed=5))
    assert not vol[:2, :3, :3].any() and not vol[-3:, -4:, -4:].any()
    vol[:2, :3, :3] = 900  # touches three faces of the volume's border: closed by its virtual zero layer
    vol[-3:, -4:, -4:] = 901  # and the three far faces
    return vol


@pytest.fixture(scope="module")
def results(bench, volume):
    chunked, stats = bench.mesh_chunked(volume, (12, 25, 25))
    return chunked, stats, bench.mesh_whole(volume)


def test_chunks_cross_every_axis_and_every_label_is_closed(results, volume):
    chunked, stats, _whole = results
    assert stats["chunks"] == 4 * 3 * 3
    labels = set(np.unique(volume).tolist()) - {0}
    for m, rows in chunked.items():
        assert set(rows) == labels, m
        for lab, row in rows.items():
            assert row["status"] == "ok", (m, lab, row["status"])
    # most labels span seams, so their pieces were really joined
    assert sum(row["pieces"] > 1 for row in chunked["serra"].values()) >= len(labels) // 2


@pytest.mark.parametrize("mesher", ["serra", "zmesh"])
def test_unsmoothed_chunked_mesh_is_the_one_piece_mesh(results, mesher):
    chunked, _stats, whole = results
    assert set(chunked[mesher]) == set(whole[mesher])
    for lab, ref in whole[mesher].items():
        row = chunked[mesher][lab]
        assert (row["faces"], row["vertices"]) == (ref["faces"], ref["vertices"]), lab
        assert row["area"] == pytest.approx(ref["area"], rel=1e-12, abs=0)
        assert row["volume"] == pytest.approx(ref["volume"], rel=1e-12, abs=0)


def test_smoothed_serra_is_closed_but_not_the_one_piece_mesh(results):
    chunked, _stats, whole = results
    d = [abs(chunked["serra-fair"][lab]["area"] / ref["area"] - 1) for lab, ref in whole["serra-fair"].items()]
    assert max(d) > 1e-6  # the seam cells are pinned in chunks, free in one piece
    assert max(d) < 0.05


def test_open_welds_and_late_pieces_are_failed_rows(bench):
    # a closed box surface (two triangles per face of a unit cube), then with one face missing
    v = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    closed = bench.weld([(v[:4], np.zeros((0, 3), int)), (v, f)])
    assert closed["status"] == "ok" and closed["area"] == pytest.approx(6.0) and closed["volume"] == pytest.approx(1.0)
    # the same cube cut into two pieces that share vertices by value: welded
    assert bench.weld([(v, f[:5]), (v.copy(), f[5:])])["status"] == "ok"
    assert bench.weld([(v, f[:-1])])["status"] == "not closed: 3 edges in an odd number of faces"
    assert bench.weld([(v, np.vstack([f, f[:1]]))])["status"].startswith("not closed:")
    # two cubes of one piece meeting along an edge, each with its own copy of the edge's vertices: the
    # weld by coordinates merges the copies, a closed surface with one edge in four faces, still measured
    two = bench.weld([(np.vstack([v, v + np.float32([1, 1, 0])]), np.vstack([f, f + 8]))])
    assert two["status"] == ("closed, non-manifold: 1 edges in four or more faces (2 vertices that one piece "
                             "keeps apart merged by the weld)")
    assert two["area"] == pytest.approx(12.0) and two["volume"] == pytest.approx(2.0)
    assert bench._measured(two) and not bench._measured(bench.weld([(v, f[:-1])]))
    # a label in two parts further apart in z than a slab of chunks: its second part comes after its weld
    vol = np.zeros((30, 8, 8), np.uint8)
    vol[1:4, 2:5, 2:5] = 7
    vol[24:27, 2:5, 2:5] = 7
    rows, _ = bench.mesh_chunked(vol, (8, 8, 8), ["serra"])
    assert rows["serra"][7]["status"].startswith("failed: faces after its weld")
