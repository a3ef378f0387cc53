"""The general mesher in slabs on worker processes (``CONTOURMESH_THREADS`` > 1, :mod:`contourmesh.parallel`):
the same mesh as one process, in the same order, with the same meta, area, volume and checks; every
case the slab route does not handle, or a slab that fails or disagrees with its neighbour, gives the
one-process mesh."""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from scipy import ndimage

import contourmesh
from contourmesh import parallel

pytestmark = pytest.mark.skipif(parallel._fork_context() is None, reason="the slab route needs the fork start method")

DATA = Path(os.environ.get("CONTOURMESH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def _blob(seed, shape=(30, 36, 36), sigma=1.3, level=0.5):
    rng = np.random.default_rng(seed)
    return ndimage.gaussian_filter(rng.random(shape), sigma) > level


def _specks(seed):
    """A blob with one-voxel specks and pinholes scattered through it."""
    rng = np.random.default_rng(seed)
    v = ndimage.gaussian_filter(rng.random((28, 32, 32)), 1.6) > 0.5
    v |= rng.random(v.shape) < 0.003
    v &= ~(rng.random(v.shape) < 0.003)
    return v


def _tori(seed):
    """Stacked rings (holes) whose radii drift, so that they split and merge between slices."""
    rng = np.random.default_rng(seed)
    nz, n = 26, 40
    yy, xx = np.mgrid[:n, :n]
    v = np.zeros((nz, n, n), bool)
    for k in range(nz):
        for cx, cy in ((12, 14), (27, 25)):
            r = np.hypot(xx - cx - rng.integers(-1, 2), yy - cy)
            v[k] |= (r > 3 + k % 4) & (r < 8 + rng.integers(0, 3))
    return v


def _fallback_stack():
    """Blobs one above the other; the lowest one's mesh needs a crossing fallback (a rebuild)
    in the one-process mesher (test_rebuild_checks.BLOB_WITH_FALLBACK)."""
    rng = np.random.default_rng(18)
    low = ndimage.gaussian_filter(rng.random((10, 24, 24)), 1.2) > 0.5
    high = _blob(5, (14, 24, 24))
    return np.concatenate([low, np.zeros((1, 24, 24), bool), high, low[::-1]])


def _mesh(vol, threads, monkeypatch, **kw):
    monkeypatch.setenv("CONTOURMESH_THREADS", str(threads))
    return contourmesh.mesh(vol, **kw)


def _same(m1, m2):
    assert m1.vertices.shape == m2.vertices.shape and m1.faces.shape == m2.faces.shape
    assert np.array_equal(m1.vertices, m2.vertices)  # the same bits, in the same order
    assert np.array_equal(m1.faces, m2.faces)
    assert m1.P == m2.P
    assert m1.meta == m2.meta
    assert m1.area == m2.area and m1.volume == m2.volume
    assert m1.checks() == m2.checks()


def _routed(caplog):
    return [r.getMessage() for r in caplog.records if r.getMessage().startswith("slab route")]


@pytest.fixture
def slab_route(monkeypatch, caplog):
    """The slab route on small volumes too (no work threshold), its decisions logged.  Threads that
    earlier tests left idle in this process (Dask's offload thread) and the package's own idle
    worker threads do not keep it from forking here; another thread started during the test does."""
    monkeypatch.setattr(parallel, "MIN_WORK", 0)
    before = {t.ident for t in threading.enumerate()}
    check = parallel._no_other_threads

    def no_new_threads():
        from contourmesh._workers import kept_threads_idle

        check()  # (stops tqdm's monitor)
        return all(t.ident in before or kept_threads_idle(t) for t in threading.enumerate())

    monkeypatch.setattr(parallel, "_no_other_threads", no_new_threads)
    caplog.set_level(logging.DEBUG, logger="contourmesh")
    return caplog


@pytest.mark.parametrize("make,seed,rebuilds", [(_blob, 0, False), (_blob, 3, False), (_specks, 1, True),
                                                (_specks, 2, False), (_specks, 3, False), (_tori, 2, False)])
def test_two_processes_make_the_one_process_mesh(make, seed, rebuilds, slab_route, monkeypatch):
    vol = make(seed)
    m1 = _mesh(vol, 1, monkeypatch, spacing=(1.5, 0.8, 0.7))
    assert not _routed(slab_route)
    assert (m1.meta["crossing_fallbacks"] > 0) == rebuilds
    m2 = _mesh(vol, 2, monkeypatch, spacing=(1.5, 0.8, 0.7))
    msgs = _routed(slab_route)
    if rebuilds:  # the one-process mesher builds again where faces cross: the slabs do not
        assert any("would rebuild" in m for m in msgs), msgs
    else:
        assert any("slabs on 2 processes" in m for m in msgs), msgs  # the slab route made it
    _same(m1, m2)
    assert m2.meta["route"] == "volume" and m2.checks()["closed"]


def test_a_rebuild_in_the_whole_takes_one_process(slab_route, monkeypatch):
    vol = _fallback_stack()
    m1 = _mesh(vol, 1, monkeypatch)
    assert m1.meta["crossing_fallbacks"] > 0
    m2 = _mesh(vol, 2, monkeypatch)
    msgs = _routed(slab_route)
    assert any("would rebuild" in m for m in msgs), msgs
    _same(m1, m2)


def test_three_workers_and_uneven_slices(slab_route, monkeypatch):
    vol = _blob(7, (34, 30, 30))
    z = np.cumsum(np.random.default_rng(7).uniform(0.5, 2.0, len(vol)))
    m1 = _mesh(vol, 1, monkeypatch, z=z, origin=(1.0, -2.0, 0.0))
    m3 = _mesh(vol, 3, monkeypatch, z=z, origin=(1.0, -2.0, 0.0))
    assert any("slabs on 3 processes" in m for m in _routed(slab_route))
    _same(m1, m3)


def test_a_seam_mismatch_falls_back_to_one_process(slab_route, monkeypatch):
    from contourmesh import volumes

    vol = _blob(0)
    m1 = _mesh(vol, 1, monkeypatch)
    units = volumes._slab_units

    def disagreeing(kept, joins, slices, slab):  # (runs in the forked workers)
        out = units(kept, joins, slices, slab)
        if slab.lo == slab.offset == 0:  # the first slab: its digests of the units next to its seam
            out["hashes"] = {k: "not the neighbour's" for k in out["hashes"]}
        return out

    monkeypatch.setattr(volumes, "_slab_units", disagreeing)
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("disagree" in m for m in _routed(slab_route))
    _same(m1, m2)


def test_a_failing_slab_falls_back_to_one_process(slab_route, monkeypatch):
    vol = _blob(3)
    m1 = _mesh(vol, 1, monkeypatch)
    mesher = parallel.volume_to_mesh

    def failing(sub, **kw):  # (runs in the forked workers)
        if kw["slab"].offset > 0:
            raise RuntimeError("this slab cannot be meshed")
        return mesher(sub, **kw)

    monkeypatch.setattr(parallel, "volume_to_mesh", failing)
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("a slab failed" in m and "this slab cannot be meshed" in m for m in _routed(slab_route))
    _same(m1, m2)


@pytest.mark.parametrize("case", ["made", "disagree", "failed", "join raises"])
def test_the_workers_are_gone_after_the_slab_route(case, slab_route, monkeypatch):
    """The workers are let go once every slab is in and exit while the calling process joins the
    slabs; when the call returns (a mesh, a fall-back, or an error in the join) no worker process
    and no pool thread is left, so the next call can fork again."""
    import multiprocessing

    from contourmesh import volumes

    vol = _blob(3)
    if case == "disagree":
        units = volumes._slab_units

        def disagreeing(kept, joins, slices, slab):
            out = units(kept, joins, slices, slab)
            if slab.offset == 0:
                out["hashes"] = {k: "not the neighbour's" for k in out["hashes"]}
            return out

        monkeypatch.setattr(volumes, "_slab_units", disagreeing)
    elif case == "failed":
        mesher = parallel.volume_to_mesh

        def failing(sub, **kw):
            if kw["slab"].offset > 0:
                raise RuntimeError("this slab cannot be meshed")
            return mesher(sub, **kw)

        monkeypatch.setattr(parallel, "volume_to_mesh", failing)
    elif case == "join raises":
        def broken(*a, **k):
            raise KeyError("a join that fails")

        monkeypatch.setattr(parallel, "_join", broken)
    if case == "join raises":
        with pytest.raises(KeyError, match="a join that fails"):
            _mesh(vol, 2, monkeypatch)
    else:
        _mesh(vol, 2, monkeypatch)
    msgs = _routed(slab_route)
    want = {"made": "slabs on 2 processes", "disagree": "disagree", "failed": "a slab failed", "join raises": ""}[case]
    assert any(want in m for m in msgs), msgs
    assert multiprocessing.active_children() == []
    assert parallel._no_other_threads()  # (the fixture's: no thread started by the call is left)
    assert _open_slab_files() == []  # (the slabs' files are closed whatever the outcome)


def _open_slab_files():
    """This process's open files made by :func:`contourmesh.parallel._slab_files`."""
    fds = Path("/proc/self/fd")
    if not fds.is_dir():  # pragma: no cover - Linux has it
        return []
    out = []
    for f in fds.iterdir():
        try:
            if "contourmesh-slab" in os.readlink(f):
                out.append(f.name)
        except OSError:  # (the listing's own descriptor, closed since)
            pass
    return out


def _same_piece(p, q):
    """Two slabs' pieces hold the same units, rings, digests and counts (not the CPU times)."""
    assert set(p) == set(q) and p["j"] == q["j"]
    for k in ("counts", "hashes", "n_comp"):
        assert p[k] == q[k]
    assert p["rings"].keys() == q["rings"].keys()
    for k in p["rings"]:
        assert np.array_equal(p["rings"][k], q["rings"][k])
    assert len(p["units"]) == len(q["units"])
    for (i, u), (i2, u2) in zip(p["units"], q["units"]):
        assert i == i2 and type(u) is type(u2)
        for a in type(u).__slots__:
            x, y = getattr(u, a), getattr(u2, a)
            if isinstance(x, np.ndarray):
                assert x.dtype == y.dtype and np.array_equal(x, y)
            else:
                assert x == y


def test_pieces_come_through_files_as_through_the_pipe(slab_route, monkeypatch):
    """The workers write their pieces to the slabs' files in memory (one per slab, made before the
    fork) and the calling process reads them back: the same pieces as those sent through the pool's
    pipe where there are no files, and the one-process mesh either way."""
    vol = _tori(2)
    m1 = _mesh(vol, 1, monkeypatch)
    got, how = [], []
    join, received = parallel._join, parallel._received

    def keeping(pieces, *a):
        got.append(pieces)
        return join(pieces, *a)

    def noting(p, files):
        how.append(bool(p.get("in_file")))
        if p.get("in_file"):  # (the piece itself is in the file)
            assert set(p) == {"j", "in_file"}
        return received(p, files)

    monkeypatch.setattr(parallel, "_join", keeping)
    monkeypatch.setattr(parallel, "_received", noting)
    m_files = _mesh(vol, 2, monkeypatch)
    assert how and all(how)
    monkeypatch.setattr(parallel, "_slab_files", lambda n: None)
    how.clear()
    m_pipe = _mesh(vol, 2, monkeypatch)
    assert how and not any(how)
    assert sum("slabs on 2 processes" in m for m in _routed(slab_route)) == 2
    assert len(got) == 2 and len(got[0]) == len(got[1]) > 2
    for p, q in zip(*got):
        _same_piece(p, q)
    _same(m1, m_files)
    _same(m1, m_pipe)
    assert _open_slab_files() == []


def test_a_worker_freezes_the_inherited_objects(monkeypatch):
    """A worker's set-up moves the objects it inherits out of its garbage collector's reach
    (``gc.freeze``); the calling process's collector is left as it was."""
    import gc

    monkeypatch.setenv("CONTOURMESH_THREADS", "2")
    before = gc.get_freeze_count()
    with parallel._fork_context().Pool(1, initializer=parallel._child_init) as pool:
        frozen, threads = pool.apply(_worker_state)
    assert frozen > 1000 and threads == "1"
    assert gc.get_freeze_count() == before
    assert os.environ["CONTOURMESH_THREADS"] == "2"


def _worker_state():
    import gc

    return gc.get_freeze_count(), os.environ["CONTOURMESH_THREADS"]


def test_the_slab_join_does_not_trim_the_heap(slab_route, monkeypatch):
    """The calling process joins the slabs without heap trims between the repair's steps (their
    pages were touched again at once); the mesh is the one-process mesh all the same."""
    from contourmesh import volumes

    vol = _blob(0)
    m1 = _mesh(vol, 1, monkeypatch)
    asked = []
    trim = volumes.release_free_heap
    monkeypatch.setattr(volumes, "release_free_heap", lambda faces: asked.append(faces) or trim(faces))
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("slabs on 2 processes" in m for m in _routed(slab_route))
    assert asked == [0, 0, 0]  # (the join's three; the workers' asks are made in their own memory)
    _same(m1, m2)


@pytest.mark.parametrize("kw", [dict(refine="band"), dict(refine="band2"), dict(polygon="dss", refine="band")])
def test_refined_meshes_take_one_process(kw, slab_route, monkeypatch):
    vol = _blob(0, (16, 24, 24))
    m1 = _mesh(vol, 1, monkeypatch, **kw)
    m2 = _mesh(vol, 2, monkeypatch, **kw)
    assert not any("slabs on" in m for m in _routed(slab_route))
    _same(m1, m2)


@pytest.mark.parametrize("kw", [dict(polygon="dss"), dict(polygon="none"), dict(triangulation="optimal"),
                                dict(caps="half"), dict(axis=2)])
def test_paper_options_in_slabs(kw, slab_route, monkeypatch):
    vol = _blob(4, (24, 26, 28))
    m1 = _mesh(vol, 1, monkeypatch, **kw)
    m2 = _mesh(vol, 2, monkeypatch, **kw)
    msgs = _routed(slab_route)
    # (triangulation="optimal" and caps="half": two slabs of this blob disagree on a band next to a
    # seam, three gaps from one's cut end: the one-process mesh)
    may_disagree = "triangulation" in kw or "caps" in kw
    assert any("slabs on 2 processes" in m or ("disagree" in m and may_disagree) for m in msgs), msgs
    _same(m1, m2)


def test_no_fork_or_a_live_thread_means_one_process(slab_route, monkeypatch):
    vol = _blob(0)
    m1 = _mesh(vol, 1, monkeypatch)
    fork_context = parallel._fork_context
    monkeypatch.setattr(parallel, "_fork_context", lambda: None)
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("no fork" in m for m in _routed(slab_route))
    _same(m1, m2)
    monkeypatch.setattr(parallel, "_fork_context", fork_context)
    stop = threading.Event()
    t = threading.Thread(target=stop.wait, name="someone else's thread")
    t.start()
    try:
        slab_route.clear()
        m3 = _mesh(vol, 2, monkeypatch)
    finally:
        stop.set()
        t.join()
    assert any("threads alive" in m and "someone else's thread" in m for m in _routed(slab_route))
    _same(m1, m3)


def test_small_volumes_take_one_process(monkeypatch, caplog):
    caplog.set_level(logging.DEBUG, logger="contourmesh")
    vol = _blob(0)
    m1 = _mesh(vol, 1, monkeypatch)
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("below" in m for m in _routed(caplog))
    _same(m1, m2)


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5", " "])
def test_bad_thread_settings_are_refused(value, monkeypatch):
    monkeypatch.setenv("CONTOURMESH_THREADS", value)
    with pytest.raises(ValueError, match="CONTOURMESH_THREADS must be a whole number of at least 1"):
        contourmesh.mesh(_blob(0, (6, 12, 12)))


def test_balanced_cuts():
    work = np.r_[np.zeros(20), np.full(40, 100.0), np.ones(100)]
    cuts = parallel.balanced_cuts(work, 8)
    assert cuts[0] == 0 and cuts[-1] == len(work) - 1
    assert all(b - a >= 2 * parallel.HALO for a, b in zip(cuts[:-1], cuts[1:]))
    assert sum(20 <= c <= 60 for c in cuts) >= 4  # most cuts where the work is
    assert parallel.balanced_cuts(np.ones(10), 4) == [0, 9]  # too few slices for two slabs
    assert parallel.balanced_cuts(np.ones(1), 4) == [0, 0]
    # shares: a slab of twice the work where asked
    cuts = parallel.balanced_cuts(np.ones(301), 3, shares=[2, 1, 1])
    assert cuts[0] == 0 and cuts[-1] == 300 and abs(cuts[1] - 150) <= 19 and abs(cuts[2] - 225) <= 19  # (moved by at most a quarter of the smaller share: 18.75 gaps)
    assert parallel.slab_shares(2) == [3.0, 3.0, 2.0, 2.0, 1.0, 1.0]
    for bad in ([1, 1], [1, 0, 1], [[1, 1, 1]]):
        with pytest.raises(ValueError, match="shares must be 3 positive numbers"):
            parallel.balanced_cuts(np.ones(301), 3, shares=bad)


def test_slice_work_counts_runs():
    m = np.zeros((2, 8, 9), bool)
    m[0, 0, 1:3] = m[0, 0, 5:7] = True  # two runs in row 0
    m[1, 4, :] = True  # one run in row 4
    m[1, 1, :] = True  # (row 1: not sampled)
    assert parallel.slice_work(m).tolist() == [2, 1]
    assert parallel.slab_work(m).tolist() == [2, 1]  # (no holes)


def test_slab_work_weighs_small_holes():
    m = np.zeros((3, 40, 40), bool)
    m[:, 4:36, 4:36] = True
    m[1, 10:14, 10:14] = False  # a small hole crossed by sampled rows 12
    m[2, 8:30, 20:23] = False  # a narrow slit closed above and below: counted as well (rows 8, ..., 28)
    runs = parallel.slice_work(m)
    assert runs.tolist() == [8, 9, 8 + 6]  # rows 4, 8, ..., 32; the hole's row 12 has two runs
    assert parallel.slab_work(m).tolist() == [8, 9 + parallel.HOLE_WEIGHT, 14 + 6 * parallel.HOLE_WEIGHT]
    wide = np.zeros((1, 60, 60), bool)
    wide[0, 4:56, 4:56] = True
    wide[0, 10:14, 6:54] = False  # wider than the reach: not a small hole
    assert parallel.slab_work(wide).tolist() == parallel.slice_work(wide).tolist() == [14]
    vol = np.concatenate([m, wide[:, :40, :40], m[::-1], m])
    one = parallel._slice_counts(vol)
    for threads in (2, 3):  # slices split in ranges on threads: the same counts
        got = parallel._slice_counts(vol, threads)
        assert all(np.array_equal(a, b) for a, b in zip(got, one))


@njit(cache=False, nogil=True)
def _runs_per_slice_pixels(mask, reach):  # pragma: no cover - compiled
    """The counts of :func:`contourmesh.parallel._runs_per_slice` as first written: every pixel of
    every sampled row read on its own (the reference its word steps must match)."""
    nz, h, w = mask.shape
    out = np.zeros(nz, np.int64)
    holes = np.zeros(nz, np.int64)
    for k in range(nz):
        n = 0
        e = 0
        for y in range(0, h, 4):
            prev = False
            end = -1
            for x in range(w):
                v = mask[k, y, x]
                if v and not prev:
                    n += 1
                    if end >= 0 and x - end <= reach:
                        mid = (end + x) // 2
                        for yy in range(y - 1, max(y - reach, 0) - 1, -1):
                            if mask[k, yy, mid]:
                                for y2 in range(y + 1, min(y + reach + 1, h)):
                                    if mask[k, y2, mid]:
                                        e += 1
                                        break
                                break
                if prev and not v:
                    end = x
                prev = v
        out[k] = n
        holes[k] = e
    return out, holes


def _counts_match(vol):
    ref = _runs_per_slice_pixels(vol, np.int64(parallel._HOLE_REACH))
    for threads in (1, 2, 3):
        got = parallel._slice_counts(vol, threads)
        assert all(np.array_equal(a, b) for a, b in zip(got, ref)), (vol.shape, threads)
    return ref


@pytest.mark.parametrize("seed", range(6))
def test_slice_counts_step_words_as_pixels(seed):
    """The run counts stepping over 8-byte words where nothing changes are the pixel loop's, bit for
    bit: rows of any width (words straddling rows), masks starting off an 8-byte boundary (the
    threads' ranges, slices of a larger array), masks not C-contiguous (no words), runs and gaps
    of every length around 8, small holes and wide ones."""
    rng = np.random.default_rng(seed)
    for _ in range(4):
        nz, h, w = (int(v) for v in rng.integers([2, 5, 1], [14, 60, 90]))
        vol = ndimage.gaussian_filter(rng.random((nz, h, w)), float(rng.uniform(0.6, 4.0))) > rng.uniform(0.35, 0.65)
        vol |= rng.random(vol.shape) < rng.uniform(0, 0.02)
        vol &= ~(rng.random(vol.shape) < rng.uniform(0, 0.02))
        _counts_match(vol)
        big = np.zeros(vol.size + 16, bool)
        for off in range(1, 8):  # the same mask at every offset from an 8-byte boundary
            v = big[off: off + vol.size].reshape(vol.shape)
            v[...] = vol
            assert v.flags.c_contiguous
            assert all(np.array_equal(a, b) for a, b in zip(parallel._slice_counts(v), _counts_match(vol)))
        _counts_match(vol[:, :, ::-1])  # (a view, not C-contiguous)
        _counts_match(np.asfortranarray(vol))
    full = np.ones((3, 9, 67), bool)
    full[1] = False
    full[2, :, 30:33] = False
    _counts_match(full)
    _counts_match(np.zeros((2, 0, 5), bool))


def test_slice_counts_step_words_as_pixels_on_shared_samples():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import volume_speed

    for name in ("liver", "lobster"):
        try:
            vol = volume_speed.make_input(name)[0]
        except (FileNotFoundError, OSError) as exc:
            pytest.skip(f"shared sample {name!r} not found under {DATA} ({exc})")
        ref = _counts_match(np.ascontiguousarray(vol, dtype=bool))
        assert ref[0].sum() > 0 and ref[1].sum() > 0  # (runs and small holes both counted)


@pytest.mark.parametrize("name", ["liver", "lobster"])
def test_shared_samples(name, slab_route, monkeypatch):
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import volume_speed

    try:
        vol, sp = volume_speed.make_input(name)[:2]
    except (FileNotFoundError, OSError) as exc:
        pytest.skip(f"shared sample {name!r} not found under {DATA} ({exc})")
    m1 = _mesh(vol, 1, monkeypatch, spacing=sp)
    m2 = _mesh(vol, 2, monkeypatch, spacing=sp)
    msgs = _routed(slab_route)
    if name == "liver":
        assert any("slabs on 2 processes" in m for m in msgs), msgs
    else:  # the lobster's mesh is built again after crossing fallbacks: one process, by a fall-back
        assert any("slabs on 2 processes" in m or "disagree" in m or "would rebuild" in m for m in msgs), msgs
    _same(m1, m2)


def test_the_kept_worker_threads_do_not_keep_the_slab_route_from_forking(monkeypatch, caplog):
    """The fast path and the crossing test leave their worker threads waiting between calls
    (contourmesh._workers); idle, they do not stop the fork, busy they do."""
    from contourmesh import _workers

    monkeypatch.setattr(parallel, "MIN_WORK", 0)
    caplog.set_level(logging.DEBUG, logger="contourmesh")
    zz, yy, xx = np.mgrid[:40, :40, :40]
    ball = (zz - 20) ** 2 + (yy - 20) ** 2 + (xx - 20) ** 2 < 15**2
    _mesh(ball, 2, monkeypatch)  # the fast path on two threads: one kept worker thread
    kept = [t for t in threading.enumerate() if t.name.startswith(_workers.THREAD_PREFIX)]
    assert kept and all(_workers.kept_threads_idle(t) for t in kept)
    seen = []
    _workers.run_all(lambda i: seen.append(_workers.kept_threads_idle(kept[0])), [(0,), (1,), (2,)], 2)
    assert seen == [False, False, False]  # busy while a call runs
    # other threads earlier tests left in this process are not this test's subject
    others = {t.ident for t in threading.enumerate() if not t.name.startswith(_workers.THREAD_PREFIX)}
    others.discard(threading.current_thread().ident)
    enumerate_all = threading.enumerate
    monkeypatch.setattr(threading, "enumerate", lambda: [t for t in enumerate_all() if t.ident not in others])
    vol = _blob(0)
    m1 = _mesh(vol, 1, monkeypatch)
    caplog.clear()
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("slabs on 2 processes" in m for m in _routed(caplog)), _routed(caplog)
    _same(m1, m2)


def _soak_stack(seed):
    """A stack of small random shapes of the robustness soak (tests/soak.py), one above another."""
    import soak

    rng = np.random.default_rng(seed)
    parts = []
    kinds = ["blob", "sheet", "line", "tube", "checker", "staircase", "border", "components", "shells", "single"]
    for _ in range(int(rng.integers(3, 7))):
        v = soak.make_volume(str(rng.choice(kinds)), rng)[:, :12, :12]
        parts.append(np.pad(v, ((0, int(rng.integers(0, 2))), (0, 12 - v.shape[1]), (0, 12 - v.shape[2]))))
    return np.pad(np.concatenate(parts), 1)


def test_a_join_four_slices_from_a_cut_end_is_the_one_process_join(slab_route, monkeypatch):
    """Seed 1086 of the threads soak: with a halo of three slices both slabs next to the seam at slice
    21 made the same bridged join, where the whole volume makes an exact one (a different mesh that
    no seam check could see); the slabs' halo of four gives the one-process mesh.  (The cuts of
    then: four slabs per worker on runs alone.)"""
    monkeypatch.setattr(parallel, "slab_shares", lambda workers: [1.0] * (4 * workers))
    monkeypatch.setattr(parallel, "HOLE_WEIGHT", 0)
    vol = _soak_stack(1086)
    m1 = _mesh(vol, 1, monkeypatch)
    m2 = _mesh(vol, 2, monkeypatch)
    assert any("slabs on 2 processes" in m for m in _routed(slab_route)), _routed(slab_route)
    _same(m1, m2)
    monkeypatch.setattr(parallel, "HALO", 3)
    m3 = _mesh(vol, 2, monkeypatch)
    assert m3.meta["bridged_joins"] != m1.meta["bridged_joins"]  # (why the halo is four)
