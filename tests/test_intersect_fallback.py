"""Issue 13, item 2: the volume mesher's remaining causes of crossing faces, each on a minimal
volume found by shrinking a failing random volume (``benchmarks/intersect_counts.py``, seed 1).

Where faces still cross after the small-move repair, the joins and caps that made them fall back
to crack rings and exact joins and the mesh is rebuilt (``meta["crossing_fallbacks"]``).  Each
volume here crossed before that fallback existed.
"""

import numpy as np
import pytest

import contourmesh
from contourmesh.volumes import voxel_topology


def _vol(*slices):
    """A volume from its slices: nested lists of 0/1, or rows of text ('#' is object)."""
    if isinstance(slices[0][0], str):
        slices = [[[ch == "#" for ch in row] for row in sl] for sl in slices]
    return np.array(slices, dtype=bool)


def _embedded_and_right(v, **kw):
    m = contourmesh.mesh(v, **kw)
    chk = m.checks()
    assert chk["closed"] and chk["ok"] and chk["self_intersections"] == 0, chk
    assert m.meta["self_intersections"] == 0
    assert chk["genus"] == voxel_topology(np.pad(v, 1))["genus"]
    return m


# one slice, one component hooked around a diagonal single voxel: the hook's MLP and the voxel's
# polygon overlap (MLPs of 8-adjacent components), so their prisms' caps cross
HOOK_AROUND_VOXEL = _vol([[1, 1, 1, 0], [1, 0, 1, 1], [0, 1, 0, 1], [0, 0, 0, 1]])
# one slice, a thin zigzag touching itself diagonally and a diagonal neighbour
ZIGZAG_SHEET = _vol([[0, 0, 1, 1, 1], [1, 1, 1, 0, 1], [1, 0, 0, 1, 0], [1, 1, 0, 0, 0]])
# an L below, and above it a voxel diagonal to the L's corner plus a voxel over its foot: the
# band between the foot and the voxel above sweeps over the diagonal voxel's prism
BAND_OVER_DIAGONAL_PRISM = _vol([[0, 0, 1], [1, 1, 1]], [[0, 1, 0], [1, 0, 0]])
# a domino below, an L of three above overlapping one of its voxels: the band between the
# domino's thin polygon and the L's MLP crosses itself whatever the triangulation
DOMINO_UNDER_L = _vol([[1, 0], [1, 0], [0, 0], [0, 0]], [[0, 0], [1, 0], [1, 0], [1, 1]])

# a long L above a single voxel under one of its ends; a lone voxel touches the L's other end
# diagonally: the band from the single voxel up to the L's MLP crosses the lone voxel's prism
LONG_BAND_OVER_DIAGONAL_PRISM = _vol([[0, 0, 0, 0, 0, 1], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0],
                          [0, 0, 0, 0, 0, 0]],
                         [[0, 0, 0, 0, 0, 1], [0, 0, 0, 0, 0, 1], [0, 1, 0, 0, 0, 1], [1, 0, 0, 0, 0, 1],
                          [1, 1, 1, 1, 1, 1]])


@pytest.mark.parametrize("name, v", [
    ("long band over a diagonal prism", LONG_BAND_OVER_DIAGONAL_PRISM),
    ("hook around a diagonal voxel", HOOK_AROUND_VOXEL),
    ("zigzag sheet", ZIGZAG_SHEET),
    ("band over a diagonal prism", BAND_OVER_DIAGONAL_PRISM),
    ("domino under an L", DOMINO_UNDER_L),
])
def test_minimal_crossing_volumes_are_embedded(name, v):
    m = _embedded_and_right(v)
    assert m.meta["crossing_fallbacks"] > 0, name  # the cause is there, and handled


@pytest.mark.parametrize("kw", [dict(polygon="none"), dict(polygon="dss"), dict(triangulation="optimal"),
                                dict(caps="half")])
def test_minimal_crossing_volumes_in_other_modes(kw):
    for v in (HOOK_AROUND_VOXEL, ZIGZAG_SHEET, BAND_OVER_DIAGONAL_PRISM, DOMINO_UNDER_L, LONG_BAND_OVER_DIAGONAL_PRISM):
        _embedded_and_right(v, **kw)


# a band from a crack ring that touches itself (a pocket pinched at one corner) up to a convex MLP
# (from a random blob, slices 13 and 14): every band triangulation of the pair crosses itself
PINCHED_LO = [[1.5, 8.5], [2.5, 8.5], [3.5, 8.5], [3.5, 9.5], [4.5, 9.5], [5.5, 9.5], [5.5, 10.5], [5.5, 11.5],
              [6.5, 11.5], [6.5, 12.5], [7.5, 12.5], [7.5, 13.5], [7.5, 14.5], [7.5, 15.5], [7.5, 16.5],
              [7.5, 17.5], [7.5, 18.5], [6.5, 18.5], [5.5, 18.5], [4.5, 18.5], [3.5, 18.5], [2.5, 18.5],
              [1.5, 18.5], [0.5, 18.5], [-0.5, 18.5], [-0.5, 17.5], [0.5, 17.5], [1.5, 17.5], [1.5, 16.5],
              [2.5, 16.5], [2.5, 15.5], [3.5, 15.5], [3.5, 16.5], [4.5, 16.5], [4.5, 17.5], [5.5, 17.5],
              [5.5, 16.5], [5.5, 15.5], [4.5, 15.5], [3.5, 15.5], [3.5, 14.5], [3.5, 13.5], [4.5, 13.5],
              [4.5, 12.5], [4.5, 11.5], [3.5, 11.5], [3.5, 10.5], [2.5, 10.5], [1.5, 10.5], [1.5, 11.5],
              [0.5, 11.5], [0.5, 12.5], [-0.5, 12.5], [-0.5, 11.5], [-0.5, 10.5], [-0.5, 9.5], [0.5, 9.5],
              [1.5, 9.5]]
CONVEX_HI = [[1.0, 9.0], [2.0, 9.0], [5.0, 10.0], [7.0, 13.0], [7.0, 17.0], [5.0, 15.0], [4.0, 13.0], [3.0, 12.0],
             [0.0, 12.0], [0.0, 10.0]]


def test_band_crossing_test_sees_pinched_rings():
    from contourmesh.bands import _band_crosses, triangulate_band, twist_guarded_band

    lo = np.c_[np.array(PINCHED_LO), np.full(len(PINCHED_LO), 13.0)]
    hi = np.c_[np.array(CONVEX_HI), np.full(len(CONVEX_HI), 14.0)]
    P = np.concatenate([lo, hi])
    assert len(np.unique(P, axis=0)) < len(P)  # the ring touches itself
    for method in ("wiederhold", "optimal", "arclength"):
        assert _band_crosses(P, triangulate_band(lo, hi, method)), method
    # no alternative helps: the guard keeps the band, the mesher's check finds it and makes the join exact
    f, _ = twist_guarded_band(lo, hi, "wiederhold")
    assert _band_crosses(P, f)
    # a band between two plain squares does not cross
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    a, b = np.c_[sq, np.zeros(4)], np.c_[sq * 2 - 0.5, np.ones(4)]
    assert not _band_crosses(np.concatenate([a, b]), triangulate_band(a, b, "wiederhold"))


def test_bridged_join_whose_band_crosses_takes_another_strategy(monkeypatch):
    """A bridged join whose band crosses itself tries the other band strategies before it gives
    up and becomes a voxel-exact join (fandisk rotated as in comparisons/real, 64 across)."""
    from contourmesh import volumes
    from contourmesh.compare.inputs import data_dir, mesh_inputs

    path = data_dir() / "meshes" / "libigl-tutorial-data" / "fandisk.off"
    if not path.is_file():
        pytest.skip(f"the shared data folder is absent ({path} not found; set CONTOURMESH_DATA)")
    inp = next(i for i in mesh_inputs("meshes/libigl-tutorial-data/fandisk.off", [64], name="fandisk-rot",
                                      repeats=3, seed=20090823, offset=True, rotate=True, root=data_dir(),
                                      placement="per-repeat") if i.repeat == 1)
    vol, sp, org = inp.volume()
    out = {}
    from contourmesh import sections

    monkeypatch.setattr(sections, "MAX_DEPTH", 0)  # (intermediate sections would rescue the join too)
    monkeypatch.setattr(volumes, "_DENSE_STEP", None)  # (so would densified rings)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_FAILED_STEP", None)
    monkeypatch.setattr(volumes, "_MERGED_EXTRA", ())  # (the merged-ends retry tries the alternatives too)
    for key, alts in (("with", volumes._BRIDGED_ALTERNATIVES), ("without", ())):
        monkeypatch.setattr(volumes, "_BRIDGED_ALTERNATIVES", alts)
        m = contourmesh.mesh(vol, spacing=sp, origin=org, refine="band")
        c = m.checks()
        assert c["watertight"] and c["winding_consistent"] and c["volume"] > 0
        assert c["self_intersections"] == 0
        out[key] = m
    with_alts, without = out["with"], out["without"]
    assert with_alts.meta["exact_joins"] < without.meta["exact_joins"]
    assert with_alts.meta["bridged_joins"] > without.meta["bridged_joins"]
    assert with_alts.meta["axis_wall_fraction"] < without.meta["axis_wall_fraction"]


# soak seeds 7625, 11814, 28637 (real-valued rings on the raster route), shrunk: a one-slice
# component whose polygon touches itself is closed by pixels at its mid-planes (a prism one
# spacing thick); their hair-thin collar went 1 % of the spacing past the mid-plane, into the slab
# where the diagonal neighbour's exact join begins, and crossed its walls (coplanar overlaps)
_MIDPLANE_PIXEL_CAP = _vol(
    ["....###.", "...##.##", "...#.#.#", "...##.#.", "....###.", "........", "........", ".##.....",
     "..#....."],
    ["........", "........", "........", "..#.....", "..##....", "...#....", "####....", ".#......",
     "..#....."],
)


@pytest.mark.parametrize("caps", ["flat", "half"])
@pytest.mark.parametrize("polygon", ["mlp", "dss"])
@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (1.48, 1.5, 1.5)])
def test_a_pixel_cap_at_a_mid_plane_stays_in_its_own_slab(caps, polygon, spacing):
    m = _embedded_and_right(np.pad(_MIDPLANE_PIXEL_CAP, 1), polygon=polygon, caps=caps, spacing=spacing)
    z = np.unique(m.vertices[:, 2])
    assert z.min() >= 0.5 * spacing[0] - 1e-9 and z.max() <= 2.5 * spacing[0] + 1e-9  # within the mid-planes


# soak seeds 24136, 37637 (real-valued rings on the raster route), shrunk: the neck of two voxels
# of the background that meet only at a corner, with slices four pixels apart.  Its two cones are
# flat, and the tube that joins them, walked around its axis or in proportion to the two rings,
# crossed itself; the tube now starts from the first point of the second ring that keeps it clear
@pytest.mark.parametrize("polygon", ["mlp", "dss", "none"])
def test_the_tube_of_a_flat_neck_keeps_clear(polygon):
    v = np.zeros((4, 4, 4), bool)
    v[1, 1:3, 1:3] = [[1, 1], [1, 0]]
    v[2, 1:3, 1:3] = [[0, 1], [1, 1]]
    for triangulation in ("wiederhold", "greedy", "optimal", "arclength"):
        m = _embedded_and_right(v[1:-1, 1:-1, 1:-1], spacing=(2.98, 0.75, 0.75), polygon=polygon,
                                triangulation=triangulation)
        assert m.checks()["genus"] == 1  # the background passes through the neck: a handle
