"""Bridged and sectioned joins that give None before building all they would: a bridged join whose
band kept crosses itself and whose faces so far already cross (``volumes._BRIDGED_CROSSING_FIRST``),
and a sectioned join whose pair above a section is ruled out by its labels alone
(``sections.DOOMED_FIRST``).  Each join is compared, call by call, with the join built without
the shortcut, on synthetic volumes and on the lobster."""

import numpy as np

from contourmesh import sections, volumes
from contourmesh.volumes import volume_to_mesh
from test_volumes_sections import _blobs, _sparse_rings, _two_cs


def _bits(segments):
    return [(plane, np.asarray(p, dtype=np.float64).tobytes(), np.asarray(q, dtype=np.float64).tobytes())
            for plane, p, q in segments]


def _same(got, ref):
    if ref is None:
        assert got is None
        return
    assert got is not None
    assert got.V.tobytes() == ref.V.tobytes() and got.F.tobytes() == ref.F.tobytes()
    assert got.rings == ref.rings and got.n_ring == ref.n_ring and got.replaced == ref.replaced
    assert got.bridges == ref.bridges and got.sections == ref.sections and got.least_area == ref.least_area
    assert _bits(got.segments) == _bits(ref.segments)


def _checked_bridge_joins(monkeypatch):
    """Wrap ``_bridge_join`` so that each call is compared with the same call without the crossing
    shortcut; counts the calls and those the shortcut ended early (before the whole join's test)."""
    seen = {"joins": 0, "none": 0, "early": 0}
    join, corner = volumes._bridge_join, volumes._repeats_a_corner
    reached = []

    def counted_corner(F):
        reached.append(True)
        return corner(F)

    def checked(*a, **kw):
        reached.clear()
        got = join(*a, **kw)
        early = not reached
        monkeypatch.setattr(volumes, "_BRIDGED_CROSSING_FIRST", False)
        try:
            reached.clear()
            ref = join(*a, **kw)
        finally:
            monkeypatch.setattr(volumes, "_BRIDGED_CROSSING_FIRST", True)
        _same(got, ref)
        seen["joins"] += 1
        seen["none"] += got is None
        seen["early"] += early and bool(reached)  # (the reference went on to the whole join's test)
        return got

    monkeypatch.setattr(volumes, "_repeats_a_corner", counted_corner)
    monkeypatch.setattr(volumes, "_bridge_join", checked)
    return seen


def _checked_sectioned_joins(monkeypatch):
    """Wrap ``sectioned_join`` so that each call is compared with the same call without the doomed
    pair test; counts the calls and the bridged pieces that the test did not build."""
    seen = {"joins": 0, "built": 0, "pieces": 0, "pieces_ref": 0}
    join, bridge_join = sections.sectioned_join, volumes._bridge_join
    counter = [None]  # (the count the bridged joins go to: none outside a sectioned join)

    def counted(*a, **kw):
        if counter[0] is not None:
            seen[counter[0]] += 1
        return bridge_join(*a, **kw)

    def checked(*a, **kw):
        counter[0] = "pieces"
        try:
            got = join(*a, **kw)
        finally:
            counter[0] = None
        monkeypatch.setattr(sections, "DOOMED_FIRST", False)
        counter[0] = "pieces_ref"
        try:
            ref = join(*a, **kw)
        finally:
            monkeypatch.setattr(sections, "DOOMED_FIRST", True)
            counter[0] = None
        _same(got, ref)
        seen["joins"] += 1
        seen["built"] += got is not None
        return got

    monkeypatch.setattr(volumes, "_bridge_join", counted)  # (the sections' pieces take it through _section_ops)
    monkeypatch.setattr(sections, "sectioned_join", checked)
    return seen


def test_bridged_joins_with_the_crossing_shortcut_are_the_joins_without(monkeypatch):
    _sparse_rings(monkeypatch)
    seen = _checked_bridge_joins(monkeypatch)
    for vol in (_blobs(), _blobs(seed=3, shape=(6, 18, 18)), _blobs(seed=5, shape=(6, 20, 20)), _two_cs()):
        volume_to_mesh(vol)
    assert seen["joins"] > 10 and seen["none"] > 0 and seen["early"] > 0, seen


def test_sectioned_joins_with_the_doomed_test_are_the_joins_without(monkeypatch):
    _sparse_rings(monkeypatch)
    monkeypatch.setattr(volumes, "_SECTION_TRIAL", 0.0)  # (every bridged join tries sections too)
    seen = _checked_sectioned_joins(monkeypatch)
    for vol in (_blobs(), _blobs(seed=3, shape=(8, 28, 28)), _blobs(seed=4, shape=(8, 28, 28)), _two_cs()):
        volume_to_mesh(vol)
    assert seen["joins"] > 20 and seen["built"] > 0, seen
    assert seen["pieces"] < seen["pieces_ref"], seen  # (the test left some pieces unbuilt)


def _lobster(shared_data):
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    return np.pad(vol, 1), tuple(spacing)  # (as benchmarks/volume_speed.py has it)


def test_lobster_bridged_joins_with_the_crossing_shortcut(monkeypatch, shared_data):
    """The lobster's bridged joins (hundreds, over a hundred ended early): each as without the shortcut."""
    vol, spacing = _lobster(shared_data)
    seen = _checked_bridge_joins(monkeypatch)
    volume_to_mesh(vol, spacing=spacing)
    assert seen["joins"] > 100 and seen["early"] > 20, seen


def test_lobster_sectioned_joins_with_the_doomed_test(monkeypatch, shared_data):
    """The lobster's sectioned joins (hundreds): each as without the doomed pair test, which leaves
    some of their bridged pieces unbuilt."""
    vol, spacing = _lobster(shared_data)
    seen = _checked_sectioned_joins(monkeypatch)
    volume_to_mesh(vol, spacing=spacing)
    assert seen["joins"] > 100 and seen["built"] > 0, seen
    assert seen["pieces"] < seen["pieces_ref"], seen

