"""Joins next to single-pixel specks (noise on a nearly horizontal face) and the bands beside an
exact join (issue 14): a fork or merge with a speck is tried again on densified polygons, a
bridged band that crosses itself only once its bridge ends are one vertex tries the other rules,
and a polygon banded to a crack ring gets a vertex every pixel."""

import numpy as np
import pytest

import contourmesh
from contourmesh import volumes
from contourmesh.volumes import voxel_topology


def _tilted_disk(a, b, c, n=40, nz=14):
    """A disk whose top is the plane z = 7 + a x + b y + c (voxels, from the disk's centre): the
    digitized top leaves terraces with one-pixel specks along their edges."""
    z, y, x = np.mgrid[0:nz, 0:n, 0:n].astype(float)
    yy, xx = y - n / 2, x - n / 2
    return ((z < 7 + a * xx + b * yy + c) & (np.hypot(xx, yy) < n / 2 - 3) & (z > 0)).astype(np.uint8)


def _assert_embedded(m, vol):
    c = m.checks()
    assert c["ok"] and c["watertight"] and c["winding_consistent"] and c["volume"] > 0
    assert c["self_intersections"] == 0 and m.meta["self_intersections"] == 0
    topo = voxel_topology(vol > 0)
    assert c["components"] == topo["surfaces"] and c["genus"] == topo["genus"]


def _without(monkeypatch, *names):
    for name in names:
        if name == "merged":
            monkeypatch.setattr(volumes, "_merged_band_retry", lambda *a, **k: None)
        else:
            monkeypatch.setattr(volumes, name, None)


@pytest.mark.parametrize("abc", [(-0.1324, -0.2471, 0.4535), (-0.2904, 0.2312, 0.2769)])
def test_a_merge_with_specks_is_tried_again_on_densified_polygons(monkeypatch, abc):
    vol = _tilted_disk(*abc)
    m = contourmesh.mesh(vol)
    assert m.meta["exact_joins"] == 0 and m.meta["dense_rings"] >= 1
    _assert_embedded(m, vol)
    with monkeypatch.context() as mp:  # without the retry the join is exact, with more area
        _without(mp, "_DENSE_FAILED_STEP")
        sparse = contourmesh.mesh(vol)
    assert sparse.meta["exact_joins"] >= 1 and sparse.area > m.area


def test_only_a_group_with_a_speck_is_tried_again():
    labels = np.zeros((2, 12, 12), dtype=np.uint8)
    labels[0, 2:10, 2:10] = 1
    labels[1, 2:10, 2:6] = 1
    labels[1, 2:10, 7:10] = 1  # two wide components above one: no speck
    A = volumes._Slice(labels[0] > 0, "mlp", *reversed(volumes.grid_to_xy(0, 0, 1, 1)))
    B = volumes._Slice(labels[1] > 0, "mlp", *reversed(volumes.grid_to_xy(0, 0, 1, 1)))
    assert not volumes._has_speck([A, B], 0, [0], [0, 1])
    labels[1, 5, 6] = 0
    labels[1, 0, 0] = 1  # a single pixel
    B = volumes._Slice(labels[1] > 0, "mlp", *reversed(volumes.grid_to_xy(0, 0, 1, 1)))
    assert volumes._has_speck([A, B], 0, [0], list(range(B.n)))


def test_a_band_that_crosses_only_with_its_bridge_ends_merged_takes_another_rule(monkeypatch):
    """The bridged band's own test moves each bridge end's two visits a hair apart (as pinches);
    in the mesh they are one vertex, and there this join's band crossed itself: it now tries the
    other rules on the band as built (without the retry on densified polygons, which also saves
    it)."""
    vol = _tilted_disk(-0.178, -0.2876, 0.9486)
    _without(monkeypatch, "_DENSE_FAILED_STEP")
    m = contourmesh.mesh(vol)
    assert m.meta["exact_joins"] == 0
    _assert_embedded(m, vol)
    _without(monkeypatch, "merged")
    assert contourmesh.mesh(vol).meta["exact_joins"] >= 1


def test_a_polygon_banded_to_a_crack_ring_is_densified(monkeypatch):
    """Beside an exact join a polygon's long straight edges fanned over the crack ring's staircase:
    with a vertex every pixel the mixed band has less area, and the mesh stays embedded."""
    vol = _tilted_disk(-0.2059, 0.2442, 0.9173)
    m = contourmesh.mesh(vol)
    assert m.meta["exact_joins"] >= 1 and m.meta["dense_rings"] >= 1
    _assert_embedded(m, vol)
    _without(monkeypatch, "_DENSE_MIXED_STEP")
    sparse = contourmesh.mesh(vol)
    assert sparse.meta["dense_rings"] == 0 and sparse.area > m.area
    for refine in (None, "band"):  # both modes keep every rule
        _assert_embedded(contourmesh.mesh(vol, refine=refine), vol)
