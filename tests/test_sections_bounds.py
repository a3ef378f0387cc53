"""Sectioned joins (contourmesh.sections) that stop early: the caller's area bound, the signed
distances measured only near the wanted pixels, and the compiled edge check; each against the
form it replaces, on synthetic volumes and on the real inputs' sectioned joins."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import sections, volumes
from contourmesh.measure import triangle_areas
from contourmesh.volumes import volume_to_mesh
from test_volumes_sections import _blobs, _edges_close_reference, _sparse_rings, _two_cs


def _bits(segments):
    return [(plane, np.asarray(p, dtype=np.float64).tobytes(), np.asarray(q, dtype=np.float64).tobytes())
            for plane, p, q in segments]


def _checked_calls(monkeypatch):
    """Wrap sectioned_join, _sdf, _sdf_wanted and _edges_close so that each call is compared with
    the reference: the join without its area bound (the same join where that one is within the
    bound, else None), scipy's signed distance on the wanted pixels (signs elsewhere), and the
    numpy edge check."""
    seen = {"joins": 0, "bounded_none": 0, "built": 0, "sdf": 0, "edges": 0}
    join, sdf, edges = sections.sectioned_join, sections._sdf, sections._edges_close
    wanted = sections._sdf_wanted

    def checked_join(*a, **kw):
        got = join(*a, **kw)
        bound = kw.pop("max_area", None)
        ref = join(*a, **kw)
        seen["joins"] += 1
        if ref is None:
            assert got is None
        elif bound is not None and not float(triangle_areas(ref.V, ref.F).sum()) <= bound:
            assert got is None
            seen["bounded_none"] += 1
        else:
            assert got is not None
            assert got.V.tobytes() == ref.V.tobytes() and got.F.tobytes() == ref.F.tobytes()
            assert got.rings == ref.rings and got.sections == ref.sections
            assert _bits(got.segments) == _bits(ref.segments)
            seen["built"] += 1
        return got

    def checked_sdf(m, sampling, need=None):
        got = sdf(m, sampling, need)
        ref = sections._sdf_reference(np.asarray(m, dtype=bool), sampling)
        if need is None:
            assert got.tobytes() == ref.tobytes()
        else:
            need = np.asarray(need, dtype=bool)
            assert got[need].tobytes() == ref[need].tobytes()
            assert (got[~need] == np.where(m, -np.inf, np.inf)[~need]).all()
        seen["sdf"] += 1
        return got

    def checked_wanted(m, sampling, need, at):
        got = wanted(m, sampling, need, at)
        ref = sections._sdf_reference(np.asarray(m, dtype=bool), sampling).ravel()[at]
        assert np.array_equal(np.flatnonzero(need), at) and got.tobytes() == ref.tobytes()
        seen["sdf"] += 1
        return got

    def checked_edges(F, nv, spans):
        got = edges(F, nv, spans)
        assert got == sections._edges_close_numpy(np.asarray(F, dtype=np.int64), nv, spans)
        seen["edges"] += 1
        return got

    monkeypatch.setattr(sections, "sectioned_join", checked_join)
    monkeypatch.setattr(sections, "_sdf", checked_sdf)
    monkeypatch.setattr(sections, "_sdf_wanted", checked_wanted)
    monkeypatch.setattr(sections, "_edges_close", checked_edges)
    return seen


@pytest.mark.parametrize("trial", [None, 0.0])
def test_bounded_sectioned_joins_of_the_blobs_equal_the_unbounded(monkeypatch, trial):
    _sparse_rings(monkeypatch)
    if trial is not None:
        monkeypatch.setattr(volumes, "_SECTION_TRIAL", trial)  # every bridged join tries sections too
    seen = _checked_calls(monkeypatch)
    for vol in (_blobs(), _blobs(seed=3, shape=(6, 18, 18)), _two_cs()):
        volume_to_mesh(vol)
    assert seen["built"] > 0 and seen["sdf"] > 0 and seen["edges"] > 0
    if trial is not None:
        assert seen["bounded_none"] > 0  # (sections with more area than the bridged join: given up)


def test_a_join_over_its_area_bound_is_given_up_with_its_pieces(monkeypatch):
    """A bound below the area of the first bridged pieces gives the join up before it is assembled."""
    _sparse_rings(monkeypatch)
    calls = {"assembled": 0, "joins": 0, "built": 0}
    join, assemble = sections.sectioned_join, sections._assemble_pieces

    def tiny(*a, **kw):
        calls["joins"] += 1
        free = join(*a, **{k: v for k, v in kw.items() if k != "max_area"})
        calls["built"] += free is not None
        before = calls["assembled"]
        got = join(*a, **dict(kw, max_area=1e-3))
        assert got is None
        if free is not None and free.bridges:
            assert calls["assembled"] == before  # (its bridged pieces alone were over the bound)
        return None

    def counted(*a, **kw):
        calls["assembled"] += 1
        return assemble(*a, **kw)

    monkeypatch.setattr(sections, "sectioned_join", tiny)
    monkeypatch.setattr(sections, "_assemble_pieces", counted)
    volume_to_mesh(_blobs())
    assert calls["joins"] > 0 and calls["built"] > 0


@pytest.mark.parametrize("name", ["lobster", "liver"])
def test_real_sectioned_joins_equal_the_reference(monkeypatch, shared_data, name):
    """The lobster's and the liver's sectioned joins (hundreds on the lobster, with and without the
    early topology test; on the liver some with more area than their bound): each as without its
    bound, their signed distances as scipy's, their edge checks as numpy's."""
    if name == "lobster":
        from contourmesh.io import read_volume

        vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    else:
        path = shared_data / "volumes" / "cgogn" / "liver.npz"
        if not path.is_file():
            pytest.skip("no liver in the shared data")
        z = np.load(path)
        vol = np.pad(np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0, 1)
    seen = _checked_calls(monkeypatch)
    volume_to_mesh(vol)
    assert seen["joins"] > 10 and seen["built"] > 0 and seen["sdf"] > 0 and seen["edges"] > 0
    if name == "liver":
        assert seen["bounded_none"] > 0


def test_compiled_edge_check_equals_the_numpy_form():
    from contourmesh.bands import triangulate_band

    rng = np.random.default_rng(5)
    verdicts = set()
    for t in range(400):
        n, m = int(rng.integers(1, 12)), int(rng.integers(1, 12))
        ta, tb = np.sort(rng.random(n)) * 2 * np.pi, np.sort(rng.random(m)) * 2 * np.pi
        lo = np.c_[np.cos(ta), np.sin(ta), np.zeros(n)]
        hi = np.c_[np.cos(tb), np.sin(tb), np.ones(m)]
        if n > 2 and m > 2:
            F = np.asarray(triangulate_band(lo, hi, "arclength"), dtype=np.int64)
        else:
            F = rng.integers(0, n + m, (int(rng.integers(1, 6)), 3))
        spans = [(0, n), (n, m)]
        kind = t % 6
        if kind == 1:
            F = F.copy()
            F[int(rng.integers(len(F)))] = F[int(rng.integers(len(F)))][::-1]
        elif kind == 2 and len(F) > 1:
            F = np.delete(F, int(rng.integers(len(F))), axis=0)
        elif kind == 3:
            F = np.concatenate([F, F[: int(rng.integers(1, len(F) + 1))]])
        elif kind == 4:
            F = rng.integers(0, n + m, (int(rng.integers(1, 14)), 3))
            spans = spans[: int(rng.integers(0, 3))]
        elif kind == 5:
            spans = [(0, n), (n, m), (n + m, 0)][: int(rng.integers(0, 4))]
        F = np.asarray(F, dtype=np.int64)
        got = sections._edges_close(F, n + m, spans)
        assert got == sections._edges_close_numpy(F, n + m, spans), (t, F, spans)
        assert got == _edges_close_reference(F, spans)
        verdicts.add(got)
    assert verdicts == {True, False}


@pytest.mark.parametrize("sampling", [(1.0, 1.0), (0.5, 0.5), (0.617, 0.667)])
def test_signed_distance_near_sparse_wanted_pixels_is_the_full_one(sampling):
    """Wanted pixels few and far apart, at a run's ends, in long runs, at the image's edges (an outside
    run reaching the padding on one side or both), whole rows wanted or none: the signed distance
    there is the full transform's, bit for bit; the other pixels get only their sign."""
    rng = np.random.default_rng(31)
    for t in range(150):
        h, w = int(rng.integers(1, 70)), int(rng.integers(1, 70))
        m = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.8, 5.0)) > rng.uniform(0.4, 0.6)
        if t % 5 == 0:
            m[int(rng.integers(h))] = False  # an empty row: one outside run at the padding both sides
        if t % 7 == 0:
            m[:, : int(rng.integers(1, w + 1))] = True
        if not m.any():
            continue
        kind = t % 4
        if kind == 0:
            need = rng.random((h, w)) < 0.02
        elif kind == 1:  # the region's edge pixels (as where two slices differ)
            need = m ^ ndimage.binary_erosion(m)
        elif kind == 2:
            need = np.zeros((h, w), bool)
            need[int(rng.integers(h))] = True
        else:
            need = rng.random((h, w)) < 0.5
        full = sections._sdf(m, sampling)
        part = sections._sdf(m, sampling, need=need)
        assert full.tobytes() == sections._sdf_reference(m, sampling).tobytes()
        assert part[need].tobytes() == full[need].tobytes(), t
        assert (part[~need] == np.where(m, -np.inf, np.inf)[~need]).all()
