"""Every label of a chunked label volume, meshed piece by piece (issue 17): the chunked reader,
identity with the in-memory mesh_labels, a Dask run with a killed worker, the cache, bad input."""

import os
import pickle
import subprocess
import sys

import numpy as np
import pytest

zarr = pytest.importorskip("zarr", reason="zarr is not installed (pip install 'contourmesh[scale]')")

import contourmesh  # noqa: E402
from contourmesh.cells import cells_volume, synthetic_cells, write_cells_zarr  # noqa: E402
from contourmesh.io.chunked import open_chunked  # noqa: E402
from contourmesh.scale import LabelTooLarge, mesh_labels_chunked, scan_labels  # noqa: E402
from contourmesh.seams import exact_area_volume  # noqa: E402

SHAPE = (32, 48, 48)


@pytest.fixture(scope="module")
def cells():
    return synthetic_cells(SHAPE, cell=16, seed=3)


@pytest.fixture(scope="module")
def volume(cells):
    vol = cells_volume(SHAPE, cells)
    assert not vol[0:2, 0:3, 0:2].any()
    vol[0:2, 0:3, 0:2] = 1000  # a label at the volume's corner (its padded box is clipped), a sparse label id
    return vol


@pytest.fixture(scope="module")
def store(tmp_path_factory, volume):
    path = tmp_path_factory.mktemp("scale") / "cells.zarr"
    arr = zarr.create_array(str(path), shape=volume.shape, chunks=(8, 24, 24), dtype="uint32", zarr_format=3)
    arr[:] = volume
    return path


def canonical(m):
    """Vertices sorted lexicographically, faces renumbered, each rotated to its smallest index, sorted."""
    order = np.lexsort(m.vertices.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    f = rank[m.faces]
    f = np.array([np.roll(t, -int(np.argmin(t))) for t in f])
    return m.vertices[order], f[np.lexsort(f.T[::-1])]


# ---------------------------------------------------------------------------------------------- reader
@pytest.mark.parametrize("fmt", [2, 3])
def test_zarr_reader_serves_boxes_and_pickles_without_data(tmp_path, volume, fmt):
    path = tmp_path / f"v{fmt}.zarr"
    arr = zarr.create_array(str(path), shape=volume.shape, chunks=(8, 16, 16), dtype="uint32", zarr_format=fmt)
    arr[:] = volume
    cv = open_chunked(path)
    assert (cv.kind, cv.shape, cv.chunks, cv.dtype) == ("zarr", volume.shape, (8, 16, 16), np.dtype("uint32"))
    np.testing.assert_array_equal(cv.read((3, 17), (5, 40), (0, 9)), volume[3:17, 5:40, 0:9])
    assert cv.slabs() == [(0, 8), (8, 16), (16, 24), (24, 32)]
    assert cv.slabs(10)[-1] == (30, 32)
    blob = pickle.dumps(cv)
    assert len(blob) < 2000  # a description of the store, not its voxels
    np.testing.assert_array_equal(pickle.loads(blob).read((0, 2)), volume[0:2])
    assert open_chunked(arr).kind == "zarr"  # an on-disk zarr Array is reopened by path on workers


@pytest.mark.parametrize("fmt", [2, 3])
def test_generator_writes_the_same_volume_to_zarr_slab_by_slab(tmp_path, cells, fmt):
    write_cells_zarr(str(tmp_path / "g.zarr"), SHAPE, cells, chunks=(8, 32, 32), zarr_format=fmt)
    np.testing.assert_array_equal(open_chunked(tmp_path / "g.zarr").read((0, SHAPE[0])), cells_volume(SHAPE, cells))
    assert {c.kind for c in cells} == {"ellipsoid"}  # cells of 16 voxels are too small for tori
    v = cells_volume(SHAPE, cells)
    a, b = v[:, :, 1:], v[:, :, :-1]
    meet = (a != b) & (a > 0) & (b > 0)
    assert len(set(zip(a[meet], b[meet]))) >= 2  # neighbours that touch (face-adjacent voxels)
    big = synthetic_cells((96, 96, 96), cell=32, seed=1)
    assert {c.kind for c in big} == {"ellipsoid", "torus"}
    assert all(c.area > 0 and c.volume > 0 for c in big)


def test_zarr_groups_and_damaged_stores(tmp_path, volume):
    g = zarr.open_group(str(tmp_path / "g.zarr"), mode="w")
    g.create_array("raw", shape=(2, 2, 2), dtype="uint8")
    sub = g.create_group("seg")
    a = sub.create_array("cells", shape=volume.shape, chunks=(8, 48, 48), dtype="uint32")
    a[:] = volume
    g.create_array("other", shape=(2, 2, 2), dtype="uint8")
    with pytest.raises(ValueError, match=r"holds 2 arrays \['other', 'raw'\]; name one with dataset="):
        open_chunked(tmp_path / "g.zarr")
    cv = open_chunked(tmp_path / "g.zarr", dataset="seg/cells")
    np.testing.assert_array_equal(cv.read((5, 6)), volume[5:6])
    via_array = open_chunked(zarr.open_array(str(tmp_path / "g.zarr"), path="seg/cells", mode="r"))
    assert (via_array.kind, via_array.dataset) == ("zarr", "seg/cells")
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(via_array)).read((0, 1)), volume[0:1])
    with pytest.raises(ValueError, match="no array 'nope'"):
        open_chunked(tmp_path / "g.zarr", dataset="nope")
    (tmp_path / "bad.zarr").mkdir()
    (tmp_path / "bad.zarr" / "zarr.json").write_text("{not json")
    with pytest.raises(ValueError, match="expected a readable Zarr store"):
        open_chunked(tmp_path / "bad.zarr")


def test_npy_memmap_reader(tmp_path, volume):
    path = tmp_path / "v.npy"
    np.save(path, volume)
    cv = open_chunked(path)
    assert cv.kind == "npy" and cv.shape == volume.shape
    np.testing.assert_array_equal(cv.read((30, 32), (0, 48), (47, 48)), volume[30:32, :, 47:])
    assert len(pickle.dumps(cv)) < 2000
    mm = np.load(path, mmap_mode="r", allow_pickle=False)
    assert open_chunked(mm).kind == "npy"  # a memmap of a whole .npy travels as its path
    scan = scan_labels(path, slab=5)
    from scipy import ndimage

    objs = ndimage.find_objects(volume)
    for lab, box, n in zip(scan.labels, scan.boxes, scan.voxels):
        b = objs[lab - 1]
        assert tuple(box) == (b[0].start, b[0].stop - 1, b[1].start, b[1].stop - 1, b[2].start, b[2].stop - 1)
        assert n == np.count_nonzero(volume == lab)
    assert sorted(scan.labels) == sorted(int(v) for v in np.unique(volume) if v)


def test_hdf5_and_dask_array_readers(tmp_path, volume):
    h5py = pytest.importorskip("h5py", reason="h5py is not installed (pip install 'contourmesh[scale]')")
    da = pytest.importorskip("dask.array", reason="dask.array is not installed")
    with h5py.File(tmp_path / "v.h5", "w") as f:
        f.create_dataset("seg/labels", data=volume, chunks=(8, 16, 16), compression="gzip")
        f.create_dataset("raw", data=np.zeros((2, 2, 2), np.float32))
    with pytest.raises(ValueError, match="holds 2 datasets.*name one with dataset="):
        open_chunked(tmp_path / "v.h5").read((0, 1))
    cv = open_chunked(tmp_path / "v.h5", dataset="seg/labels")
    assert cv.kind == "hdf5" and cv.shape == volume.shape and cv.chunks == (8, 16, 16)
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(cv)).read((4, 9), (1, 30), (2, 3)), volume[4:9, 1:30, 2:3])
    d = da.from_array(volume, chunks=(8, 48, 48))
    cd = open_chunked(d)
    assert cd.kind == "dask" and cd.chunks == (8, 48, 48)
    np.testing.assert_array_equal(cd.read((7, 20)), volume[7:20])
    a = {lab: row for lab, _m, _b, row in mesh_labels_chunked(cv, jobs=1, labels=[2, 1000], meshes=False)}
    b = {lab: row for lab, _m, _b, row in mesh_labels_chunked(d, jobs=1, labels=[2, 1000], meshes=False)}
    assert a == b and a[1000]["voxels"] == 12


def test_scan_tiles_follow_the_chunk_grid_and_give_the_same_boxes(store):
    whole = scan_labels(store)
    tiled = scan_labels(store, scan_voxels=8 * 24 * 24)
    assert len(whole.tiles) == 4 and len(tiled.tiles) == 16
    assert (0, 8, 24, 48, 0, 24) in tiled.tiles
    for a in ("labels", "boxes", "voxels"):
        np.testing.assert_array_equal(getattr(whole, a), getattr(tiled, a))
    assert open_chunked(store).tiles(8, 1) == tiled.tiles  # never less than one chunk


# ---------------------------------------------------------------------------------------------- identity
@pytest.mark.parametrize("refine", [None, "band"])
def test_identical_to_in_memory_mesh_labels(store, volume, refine):
    ref = {lab: (m, bbox) for lab, m, bbox in contourmesh.mesh_labels(volume, spacing=(2.0, 1.0, 1.0),
                                                                        origin=(5.0, -3.0, 1.5), refine=refine)}
    stats = {}
    got = {lab: (m, bbox, row) for lab, m, bbox, row in mesh_labels_chunked(
        store, spacing=(2.0, 1.0, 1.0), origin=(5.0, -3.0, 1.5), refine=refine, jobs=1, batch=4, slab=5,
        scan_voxels=5 * 24 * 24, stats=stats)}
    assert sorted(got) == sorted(ref) and len(ref) == 19
    assert stats["tasks"] >= 5
    for lab, (r, rbox) in ref.items():
        m, bbox, row = got[lab]
        assert bbox == rbox
        for a, b in zip(canonical(m), canonical(r)):
            np.testing.assert_array_equal(a, b)
        area, volume = exact_area_volume(r.vertices, r.faces)
        assert m.area == r.area and row["area"] == area  # to the last bit
        assert row["volume"] == volume and row["P"] == r.P
        assert abs(area - r.area) <= 1e-12 * area and abs(volume - r.checks()["volume"]) <= 1e-9 * volume
        assert row["status"] in ("ok",) or row["status"].startswith("closed")
        assert m.meta["label"] == lab


ROW_KEYS = ("area", "volume", "P", "faces", "genus", "components", "watertight", "self_intersections")
SLAB_BUDGET = 1600  # voxels: 7 of the 19 labels exceed it and are cut into 4 to 9 slabs each


@pytest.fixture(scope="module")
def memory(volume):
    """In-memory meshes and rows of every label (paper mode)."""
    return {lab: (m, contourmesh.api.label_row(lab, m, bbox)) for lab, m, bbox in contourmesh.mesh_labels(volume)}


@pytest.mark.parametrize("meshes", [True, False])
def test_labels_above_the_budget_are_meshed_in_slabs_identical_to_memory(store, memory, meshes):
    """Issue 17: a label larger than max_box_voxels is meshed in slabs of slices (halo 3) joined by
    vertex identity: the in-memory mesh after canonical ordering, the same row to the last bit;
    with meshes=False the row is summed slab by slab without a mesh and is the same."""
    stats = {}
    got = {lab: (m, row) for lab, m, _b, row in mesh_labels_chunked(
        store, jobs=1, max_box_voxels=SLAB_BUDGET, meshes=meshes, stats=stats)}
    assert stats["slabbed_labels"] == 7 and stats["slab_tasks"] >= 40
    assert sorted(got) == sorted(memory)
    for lab, (r, ref) in memory.items():
        m, row = got[lab]
        assert row["status"] == "ok", (lab, row["status"])
        assert {k: row[k] for k in ROW_KEYS} == {k: ref[k] for k in ROW_KEYS}, lab
        if meshes:
            for a, b in zip(canonical(m), canonical(r)):
                np.testing.assert_array_equal(a, b)
            assert m.checks()["ok"]
        else:
            assert m is None


def test_slab_seams_that_disagree_are_failed_rows_never_a_different_mesh(volume, memory):
    """A halo of one slice is too small for the seam check (the slab's own cut end lies within one
    gap of the seam): the labels concerned fail with SeamMismatch; the others equal memory."""
    rows = {lab: row for lab, _m, _b, row in mesh_labels_chunked(volume, jobs=1, max_box_voxels=SLAB_BUDGET,
                                                                 meshes=False, halo=1)}
    failed = [lab for lab, row in rows.items() if row["status"] != "ok"]
    assert failed
    for lab, row in rows.items():
        if lab in failed:
            assert row["status"].startswith("failed: SeamMismatch: label ")
        else:
            assert {k: row[k] for k in ROW_KEYS} == {k: memory[lab][1][k] for k in ROW_KEYS}
    with pytest.raises(LabelTooLarge, match="refine='band' is not meshed in slabs"):
        list(mesh_labels_chunked(volume, jobs=1, max_box_voxels=SLAB_BUDGET, refine="band"))
    with pytest.raises(ValueError, match="halo must be a positive number"):
        list(mesh_labels_chunked(volume, jobs=1, halo=0))


def test_slab_results_are_cached_and_a_damaged_piece_is_recomputed(tmp_path, volume, memory):
    cache = tmp_path / "cache"
    first = {lab: row for lab, _m, _b, row in mesh_labels_chunked(volume, jobs=1, max_box_voxels=SLAB_BUDGET,
                                                                  labels=[3, 7], cache=cache)}
    pieces = sorted(cache.glob("slab-*.npz"))
    assert len(pieces) >= 8
    pieces[0].write_bytes(b"damaged")
    stats = {}
    again = {lab: (m, row) for lab, m, _b, row in mesh_labels_chunked(
        volume, jobs=1, max_box_voxels=SLAB_BUDGET, labels=[3, 7], cache=cache, stats=stats)}
    assert stats["cached"] == stats["tasks"] - 1
    assert {lab: r for lab, (_m, r) in again.items()} == first
    for lab, (m, _row) in again.items():
        for a, b in zip(canonical(m), canonical(memory[lab][0])):
            np.testing.assert_array_equal(a, b)


def test_stats_only_rows_equal_mesh_rows(store):
    with_meshes = {lab: row for lab, _m, _b, row in mesh_labels_chunked(store, jobs=1, labels=[1, 5, 1000])}
    rows = {lab: (m, row) for lab, m, _b, row in mesh_labels_chunked(store, jobs=1, meshes=False,
                                                                     labels=[1000, 5, 1])}
    assert sorted(rows) == [1, 5, 1000]
    assert all(m is None for m, _ in rows.values())
    assert {k: r for k, (_, r) in rows.items()} == with_meshes


def test_a_label_the_mesher_refuses_is_a_failed_row_not_a_stopped_run(monkeypatch, volume):
    from contourmesh import api

    real = api.mesh_volume

    def picky(crop, **kw):
        if np.count_nonzero(crop) == 12:  # label 1000's 2 x 3 x 2 block
            raise ValueError("cannot mesh this one")
        return real(crop, **kw)

    monkeypatch.setattr(api, "mesh_volume", picky)
    rows = {lab: row for lab, _m, _b, row in mesh_labels_chunked(volume, jobs=1, labels=[1, 1000, 2])}
    assert rows[1000]["status"] == "failed: ValueError: cannot mesh this one"
    assert rows[1]["status"] == "ok" and rows[2]["status"] == "ok"
    assert rows[1000]["voxels"] == 12 and rows[1000]["zmax"] == 1


# ---------------------------------------------------------------------------------------------- Dask
def test_local_cluster_with_a_killed_worker_changes_nothing(store, volume):
    distributed = pytest.importorskip("distributed", reason="Dask distributed is not installed")
    ref = {lab: contourmesh.api.label_row(lab, m, bbox) for lab, m, bbox in contourmesh.mesh_labels(volume)}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, memory_limit="2GiB",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        client.wait_for_workers(2, timeout=60)
        victim = sorted(client.scheduler_info()["workers"])[0]
        killed = []
        rows = {}
        # labels above the budget are cut into slabs, so slab tasks die with the worker too
        for lab, m, _bbox, row in mesh_labels_chunked(store, client=client, batch=1, meshes=False,
                                                      max_box_voxels=SLAB_BUDGET):
            rows[lab] = row
            if not killed:
                pid = client.run(os.getpid, workers=[victim])[victim]
                os.kill(pid, 9)  # the worker process dies mid-run; its tasks are rerun elsewhere
                killed.append(pid)
        assert killed and len(rows) == len(ref)
        assert victim not in client.scheduler_info()["workers"]  # the worker really died (its nanny restarts it)
        for lab, r in ref.items():
            got = {k: v for k, v in rows[lab].items() if k in r}
            assert got == r, lab


# ---------------------------------------------------------------------------------------------- cache
def test_cache_resumes_and_a_changed_voxel_redoes_only_its_batches(tmp_path, volume):
    path = tmp_path / "c.zarr"
    arr = zarr.create_array(str(path), shape=volume.shape, chunks=(8, 48, 48), dtype="uint32", zarr_format=2)
    arr[:] = volume
    cache = tmp_path / "cache"
    run = mesh_labels_chunked(path, jobs=1, batch=2, cache=cache)
    first = [next(run) for _ in range(3)]
    run.close()  # an interrupted run: Ctrl-C after three labels
    done = sorted(cache.glob("batch-*.npz"))
    assert len(done) == 2 and not list(cache.glob("*.tmp"))
    stats = {}
    full = {lab: (m, row) for lab, m, _b, row in mesh_labels_chunked(path, jobs=1, batch=2, cache=cache,
                                                                     stats=stats)}
    assert stats["cached"] == 2 and stats["tasks"] == 10
    for lab, m, _b, row in first:
        assert full[lab][1] == row and np.array_equal(full[lab][0].faces, m.faces)
    # a damaged cache file is recomputed, not trusted
    done[0].write_bytes(b"not an npz")
    stats = {}
    again = {lab: row for lab, _m, _b, row in mesh_labels_chunked(path, jobs=1, batch=2, cache=cache, stats=stats)}
    assert stats["cached"] == 9 and again == {lab: r for lab, (_m, r) in full.items()}
    # one changed voxel (in slab 24-31) invalidates the batches whose boxes reach that slab, only those
    lab = int(volume[28, 8:40, 8:40].max())
    k, j, i = np.argwhere(volume == lab)[0]
    arr[k, j, i] = 0
    stats = {}
    changed = {lab2: row for lab2, _m, _b, row in mesh_labels_chunked(path, jobs=1, batch=2, cache=cache,
                                                                       stats=stats)}
    assert 0 < stats["tasks"] - stats["cached"] < stats["tasks"]
    assert changed[lab]["voxels"] == full[lab][1]["voxels"] - 1


# ---------------------------------------------------------------------------------------------- errors
def test_bad_inputs_get_clear_errors(tmp_path, volume):
    f = zarr.create_array(str(tmp_path / "f.zarr"), shape=(4, 4, 4), dtype="float32", zarr_format=3)
    f[:] = 0.5
    with pytest.raises(TypeError, match="integer label volume; got dtype float32"):
        list(mesh_labels_chunked(tmp_path / "f.zarr", jobs=1))
    obj = np.empty((2, 2, 2), dtype=object)
    np.save(tmp_path / "o.npy", obj, allow_pickle=True)
    with pytest.raises(ValueError, match="Python objects.*never unpickles"):
        open_chunked(tmp_path / "o.npy")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        open_chunked(tmp_path / "missing.zarr")
    (tmp_path / "plain").mkdir()
    with pytest.raises(IsADirectoryError, match="not a Zarr store"):
        open_chunked(tmp_path / "plain")
    (tmp_path / "x.npy").write_bytes(b"PK\x03\x04junk")
    with pytest.raises(ValueError, match="expected a NumPy .npy"):
        open_chunked(tmp_path / "x.npy")
    with pytest.raises(ValueError, match="3D"):
        open_chunked(np.zeros((4, 4), np.uint8))
    with pytest.raises(LabelTooLarge, match=r"max_box_voxels=100: label 1 \(padded box 9 x 10 x 17 = 1530 voxels\)"):
        list(mesh_labels_chunked(volume, jobs=1, max_box_voxels=100, labels=[1]))
    with pytest.raises(ValueError, match="no voxel has label 77"):
        list(mesh_labels_chunked(volume, jobs=1, labels=[77]))
    with pytest.raises(contourmesh.InapplicableOption, match="caps='smooth'"):
        list(mesh_labels_chunked(volume, jobs=1, caps="smooth"))
    # with the refinement the labels' ends follow their area profile (tests/test_refine.py)
    from contourmesh.scale import _check_method

    for refine in ("band", "band2"):
        assert _check_method(dict(caps="smooth", refine=refine))["refine"] == refine


# ---------------------------------------------------------------------------------------------- CLI
def test_cli_all_labels_on_a_zarr_store_matches_the_in_memory_table(tmp_path, store, volume):
    np.save(tmp_path / "v.npy", volume)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [str(contourmesh.__path__[0].rsplit("/", 1)[0]),
                                                                   os.environ.get("PYTHONPATH", "")] if p))

    def cm(*args):
        r = subprocess.run([sys.executable, "-m", "contourmesh", "mesh", *args, "--quiet"], capture_output=True,
                           text=True, env=env, timeout=300)
        return r

    r = cm(str(store), "--all-labels", "-o", str(tmp_path / "chunked"), "--jobs", "1", "--stats-only")
    assert r.returncode == 0, r.stderr
    assert "19 labels" in r.stdout and not (tmp_path / "chunked" / ".contourmesh-cache").exists()
    r = cm(str(tmp_path / "v.npy"), "--all-labels", "-o", str(tmp_path / "memory"), "--stats-only")
    assert r.returncode == 0, r.stderr
    import csv

    a = list(csv.DictReader(open(tmp_path / "chunked" / "labels.csv")))
    b = list(csv.DictReader(open(tmp_path / "memory" / "labels.csv")))
    assert [{k: v for k, v in row.items() if k in b[0]} for row in a] == b
    r = cm(str(store), "-o", str(tmp_path / "one.ply"), "--label", "3", "--jobs", "2")
    assert r.returncode == 2 and "--jobs applies with --all-labels only" in r.stderr


# ---------------------------------------------------------------------------------------------- real data
@pytest.mark.parametrize("refine", [None, "band"])
def test_identical_on_the_real_lobster_cut_into_touching_labels(shared_data, tmp_path, refine):
    """lobsterCroped (31 x 91 x 51) cut into octant labels that touch along the cut planes; its
    four smaller labels (the suite stays fast).  A label the in-memory mesher raises on is a
    failed row with the same error."""
    vol, _sp, _o = contourmesh.read_volume(shared_data / "volumes" / "dgtal" / "lobsterCroped.npz")
    zz, yy, xx = np.indices(vol.shape)
    labels = (vol * (1 + (zz >= 15) + 2 * (yy >= 45) + 4 * (xx >= 25))).astype(np.uint16)
    np.save(tmp_path / "lobster.npy", labels)
    picked = [3, 4, 6, 7]
    got = {lab: (m, row) for lab, m, _b, row in mesh_labels_chunked(tmp_path / "lobster.npy", refine=refine,
                                                                     jobs=1, slab=4, batch=3, labels=picked)}
    assert sorted(got) == picked
    for lab in picked:
        m, row = got[lab]
        try:
            (_, r, _), = contourmesh.mesh_labels(labels, labels=[lab], refine=refine)
        except Exception as exc:
            assert m is None and row["status"] == f"failed: {type(exc).__name__}: {' '.join(str(exc).split())}"
            continue
        for a, b in zip(canonical(m), canonical(r)):
            np.testing.assert_array_equal(a, b)
        assert m.area == r.area and row["area"] == exact_area_volume(r.vertices, r.faces)[0]


def test_exact_area_volume_does_not_depend_on_order_or_cut(memory):
    """The rows' area and volume: the same bits whatever the order of vertices and faces, where each
    face starts, and however the faces are split into parts whose exact sums are added."""
    import math

    from contourmesh.seams import _area_terms, _volume_parts, exact_parts

    m = memory[5][0]
    a0, v0 = exact_area_volume(m.vertices, m.faces)
    assert abs(a0 - m.area) <= 1e-12 * a0 and abs(v0 - m.volume) <= 1e-10 * v0
    rng = np.random.default_rng(0)
    perm = rng.permutation(len(m.vertices))
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(perm))
    F = inv[m.faces][rng.permutation(len(m.faces))]
    F = np.stack([np.roll(f, int(s)) for f, s in zip(F, rng.integers(0, 3, len(F)))])
    assert exact_area_volume(m.vertices[perm], F) == (a0, v0)
    halves = (F[: len(F) // 3], F[len(F) // 3:])
    V = m.vertices[perm]
    assert math.fsum(x for h in halves for x in exact_parts(_area_terms(V, h))) == a0
    assert math.fsum(x for h in halves for x in _volume_parts(V, h)) / 6.0 == v0
    x = rng.normal(size=1000) * 10.0 ** rng.integers(-8, 8, 1000)
    assert math.fsum(exact_parts(x)) == math.fsum(x)


def test_cli_halo_reaches_the_slabs_and_is_refused_where_it_does_not_apply(tmp_path, store, volume, memory):
    """--halo on the command line: with the slab budget of the tests a halo of one slice makes the seam
    check fail for some labels (failed rows, exit status 1), the default halo of 3 gives the in-memory
    rows; with the refinement, or without --all-labels, it is an error naming the option."""
    import csv

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [str(contourmesh.__path__[0].rsplit("/", 1)[0]),
                                                                   os.environ.get("PYTHONPATH", "")] if p))

    def cm(*args):
        return subprocess.run([sys.executable, "-m", "contourmesh", "mesh", *args, "--quiet"], capture_output=True,
                              text=True, env=env, timeout=300)

    budget = ("--max-box-voxels", str(SLAB_BUDGET), "--jobs", "1", "--stats-only")
    r = cm(str(store), "--all-labels", "-o", str(tmp_path / "h1"), *budget, "--halo", "1")
    assert r.returncode == 1, r.stderr
    rows = list(csv.DictReader(open(tmp_path / "h1" / "labels.csv")))
    failed = [row for row in rows if row["status"] != "ok"]
    assert failed and all(row["status"].startswith("failed: SeamMismatch") for row in failed)
    r = cm(str(store), "--all-labels", "-o", str(tmp_path / "h3"), *budget, "--halo", "3")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(tmp_path / "h3" / "labels.csv")))
    assert len(rows) == len(memory) and all(row["status"] == "ok" for row in rows)
    assert all(float(row["area"]) == memory[int(row["label"])][1]["area"] for row in rows)
    r = cm(str(store), "--all-labels", "-o", str(tmp_path / "band"), "--refine", "band", "--halo", "2", "--jobs", "1")
    assert r.returncode == 2 and "--halo does not apply with --refine 'band'" in r.stderr
    r = cm(str(store), "-o", str(tmp_path / "one.ply"), "--label", "3", "--halo", "2")
    assert r.returncode == 2 and "--halo applies with --all-labels only" in r.stderr
    with pytest.raises(contourmesh.InapplicableOption, match="never cut into slabs"):
        list(mesh_labels_chunked(volume, jobs=1, refine="band2", halo=3))
