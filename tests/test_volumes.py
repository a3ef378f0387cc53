"""Binary volumes of any topology -> closed, oriented, manifold meshes with the right genus."""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import contourmesh
from conftest import assert_closed_outward
from contourmesh.bands import TRIANGULATORS
from contourmesh.polygons import POLYGONIZERS
from contourmesh.volumes import prepare_volume, split_nonmanifold_vertices, volume_to_mesh, voxel_topology

COMBOS = list(itertools.product(sorted(POLYGONIZERS), sorted(TRIANGULATORS)))  # arclength included


def check_topology(vol, m):
    ref = voxel_topology(vol)
    chk = assert_closed_outward(m)
    assert chk["components"] == ref["surfaces"], (chk, ref)
    assert chk["genus"] == ref["genus"], (chk, ref)
    assert chk["nonmanifold_edges"] == 0
    return chk, ref


def check_embedded(vol, m):
    """check_topology, and no crossing faces (issue 13: every shared sample in the default mode)."""
    chk, ref = check_topology(vol, m)
    assert chk["self_intersections"] == 0 and chk["ok"], chk
    assert m.meta["self_intersections"] == 0, m.meta
    return chk, ref


def test_single_voxel_is_a_unit_cube():
    vol = np.zeros((3, 3, 3), bool)
    vol[1, 1, 1] = True
    m = volume_to_mesh(vol, polygon="none")
    check_topology(vol, m)
    assert m.volume == pytest.approx(1.0)
    assert m.area == pytest.approx(6.0)
    assert np.allclose(m.vertices.min(0), 0.5) and np.allclose(m.vertices.max(0), 1.5)


def test_anisotropic_spacing_scales_the_box():
    vol = np.ones((2, 3, 4), bool)
    m = volume_to_mesh(vol, spacing=(2.0, 0.5, 0.25), polygon="none", caps="half")
    check_topology(vol, m)
    ext = m.vertices.max(0) - m.vertices.min(0)
    assert ext == pytest.approx([4 * 0.25, 3 * 0.5, 2 * 2.0])
    assert m.volume == pytest.approx(1.0 * 1.5 * 4.0)


@pytest.mark.parametrize("polygon,tri", COMBOS)
def test_ring_has_genus_one_and_hollow_shell_two_surfaces(polygon, tri):
    ring = np.zeros((3, 7, 7), bool)
    ring[:, 1:6, 1:6] = True
    ring[:, 3, 3] = False  # a one-voxel tunnel
    chk, ref = check_topology(ring, volume_to_mesh(ring, polygon=polygon, triangulation=tri))
    assert ref["genus"] == 1
    shell = np.zeros((7, 7, 7), bool)
    shell[1:6, 1:6, 1:6] = True
    shell[3, 3, 3] = False  # a one-voxel cavity
    chk, ref = check_topology(shell, volume_to_mesh(shell, polygon=polygon, triangulation=tri))
    assert ref["surfaces"] == 2 and chk["components"] == 2


def test_edge_and_corner_contacts_stay_apart():
    # 6-connectivity: voxels touching along an edge or at a corner are separate objects
    vol = np.zeros((2, 2, 2), bool)
    vol[0, 0, 0] = vol[1, 1, 0] = True  # edge contact across slices
    chk, _ = check_topology(vol, volume_to_mesh(vol))
    assert chk["components"] == 2
    vol = np.zeros((1, 2, 2), bool)
    vol[0, 0, 0] = vol[0, 1, 1] = True  # corner contact in a slice
    chk, _ = check_topology(vol, volume_to_mesh(vol))
    assert chk["components"] == 2 and chk["duplicate_vertices"] == 0
    vol = np.zeros((2, 2, 2), bool)
    vol[0, 0, 0] = vol[1, 1, 1] = True  # vertex contact
    chk, _ = check_topology(vol, volume_to_mesh(vol))
    assert chk["components"] == 2


@pytest.mark.parametrize("polygon,tri", COMBOS)
def test_branching_y_shape_and_border_touching(polygon, tri):
    vol = np.zeros((6, 9, 9), bool)
    vol[:3, 3:6, 3:6] = True  # trunk
    vol[3:, 0:3, 0:3] = vol[3:, 6:9, 6:9] = True  # two arms touching the border
    vol[3, 1:8, 1:8] = True  # the fork
    m = volume_to_mesh(vol, polygon=polygon, triangulation=tri)
    check_topology(vol, m)
    assert m.meta["exact_joins"] + m.meta["bridged_joins"] >= 1


def test_sphere_volume_path_matches_the_paper_path():
    from contourmesh.digitize import gauss_volume
    from contourmesh.shapes import Sphere

    shape = Sphere(14, center=(0.3, 0.1, 0.2))
    vol, origin = gauss_volume(shape)
    mv = volume_to_mesh(vol, origin=origin, polygon="mlp")
    ms = contourmesh.mesh(shape, polygon="mlp")
    check_topology(vol, mv)
    # the same I in every slice: the same MLPs, hence areas within the end-cap difference
    assert mv.area == pytest.approx(ms.area, rel=0.02)
    assert mv.meta["exact_joins"] == 0


def test_uneven_slices_axis_label_threshold():
    labels = np.zeros((5, 6, 7), np.uint8)
    labels[1:4, 1:5, 1:6] = 3
    labels[2, 2:4, 2:4] = 7
    m3 = volume_to_mesh(labels, label=3, z=[0.0, 3.0, 9.0, 12.0, 13.0])
    check_topology(labels == 3, m3)
    zs = np.unique(np.round(m3.vertices[:, 2], 6))
    assert 3.0 in zs and 9.0 in zs
    mt = volume_to_mesh(labels.astype(float) * 10, threshold=25)
    assert mt.volume == pytest.approx(volume_to_mesh(labels >= 3).volume)
    for axis in (1, 2):
        ma = volume_to_mesh(labels == 3, axis=axis, polygon="none", caps="half")
        check_topology(np.moveaxis(labels == 3, axis, 0), ma)
        assert ma.volume == pytest.approx(3 * 4 * 5 - 4)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((3, 3)), "3D"),
        (np.zeros((2, 2, 2, 2)), "3D"),
        (np.zeros((3, 3, 3)), "no foreground"),
        (np.full((2, 2, 2), np.nan), "NaN"),
        (np.full((2, 2, 2), np.inf), "inf"),
        (np.ones((2, 2, 2), complex), "complex"),
        (np.array([[[1]]], dtype=object), "object"),
        (np.arange(8).reshape(2, 2, 2), "label= .* threshold="),
        (np.zeros((0, 2, 2), bool), "empty"),
    ],
)
def test_bad_volumes_are_named(bad, match):
    with pytest.raises(ValueError, match=match):
        volume_to_mesh(bad)


def test_bad_parameters_are_named():
    vol = np.ones((2, 2, 2), bool)
    with pytest.raises(ValueError, match="spacing"):
        volume_to_mesh(vol, spacing=(1, 0, 1))
    with pytest.raises(ValueError, match="spacing"):
        volume_to_mesh(vol, spacing=(1, -1, 1))
    with pytest.raises(ValueError, match="increasing"):
        volume_to_mesh(vol, z=[1.0, 1.0])
    with pytest.raises(ValueError, match="one position per slice"):
        volume_to_mesh(vol, z=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="axis"):
        volume_to_mesh(vol, axis=3)
    with pytest.raises(ValueError, match="not both"):
        prepare_volume(vol, label=1, threshold=0)
    with pytest.raises(ValueError, match="polygon"):
        volume_to_mesh(vol, polygon="hull")
    with pytest.raises(ValueError, match="caps"):
        volume_to_mesh(vol, caps="dome")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    arrays(np.bool_, st.tuples(st.integers(1, 4), st.integers(1, 5), st.integers(1, 5))),
    st.sampled_from(COMBOS),
)
def test_random_volumes_are_closed_manifolds_with_the_voxel_genus(vol, combo):
    if not vol.any():
        return
    polygon, tri = combo
    check_topology(vol, volume_to_mesh(vol, polygon=polygon, triangulation=tri))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**32 - 1), st.sampled_from(COMBOS), st.floats(0.35, 0.75))
def test_random_blobs_are_closed_manifolds_with_the_voxel_genus(seed, combo, p):
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    vol = ndimage.gaussian_filter(rng.random((6, 12, 12)), 1.0) > np.quantile(rng.random(10), p)
    vol = ndimage.gaussian_filter(rng.random((6, 12, 12)), 1.2) > 0.5 if not vol.any() else vol
    if not vol.any():
        return
    check_topology(vol, volume_to_mesh(vol, polygon=combo[0], triangulation=combo[1]))


def test_split_nonmanifold_vertices_separates_two_tetrahedra_sharing_a_vertex():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float)
    t1 = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    t2 = np.array([[0, 4, 5], [0, 6, 4], [0, 5, 6], [4, 6, 5]])
    V2, F2 = split_nonmanifold_vertices(V, np.vstack([t1, t2]), nudge=1e-3)
    assert len(V2) == 8
    assert contourmesh.Mesh(V2, F2).checks()["components"] == 2


REAL = [
    ("dgtal/Al.100.npz", 2), ("dgtal/bunny-32.npz", 0), ("dgtal/bunny-64.npz", 0), ("dgtal/bunny-128.npz", 0),
    ("dgtal/cat10.npz", 0), ("dgtal/lobsterCroped.npz", None),
]


@pytest.mark.parametrize("name, genus", REAL)
def test_real_volumes(shared_data, name, genus):
    z = np.load(shared_data / "volumes" / name, allow_pickle=False)
    vol = np.transpose(z["mask"], (2, 1, 0))  # the files are indexed [x, y, z]
    m = contourmesh.mesh(vol, spacing=tuple(float(s) for s in z["spacing_xyz"][::-1]))
    chk, ref = check_embedded(vol, m)
    if genus is not None:
        assert chk["genus"] == genus


@pytest.mark.parametrize("label", [85, 127, 255])
def test_liver_labels(shared_data, label):
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0))
    sel = np.argwhere(vol == label)
    lo, hi = sel.min(0), sel.max(0) + 1
    crop = vol[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    m = contourmesh.mesh(crop, label=label, spacing=tuple(float(s) for s in z["spacing_xyz"][::-1]))
    check_embedded(crop == label, m)


@pytest.mark.parametrize("roi, loses", [("BODY", True), ("Lt Lung", True), ("Heart", False)])
def test_rtstruct_structures(shared_data, roi, loses):
    import warnings

    pytest.importorskip("pydicom")

    from contourmesh.io import read_contours
    from contourmesh.rasterize import LostContourWarning, rasterize_stack

    stack = read_contours(shared_data / "contours" / "dicompyler-core" / "rtss.dcm", roi=roi)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vol, zs, (dy, dx), origin = rasterize_stack(stack, pixel=2.0)
    # at 2 mm, BODY and the lung lose their smallest rings (said in a LostContourWarning); the heart none
    assert [w.category for w in caught] == ([LostContourWarning] if loses else [])
    m = volume_to_mesh(vol, z=zs, spacing=(1.0, dy, dx), origin=origin)
    check_embedded(vol, m)
    assert m.meta["source"] == "volume"


def test_whole_lobster_at_threshold_60(shared_data):
    """The messiest sample: up to 47 contours and 46 holes in one slice, 283 surfaces."""
    z = np.load(shared_data / "volumes" / "dgtal" / "lobster.npz", allow_pickle=False)
    vol = np.transpose(z["volume"], (2, 1, 0)) > 60
    chk, ref = check_embedded(vol, volume_to_mesh(vol))
    assert ref["surfaces"] == 283


VOXELIZED = ["trimesh-models/torus.STL", "libigl-tutorial-data/fertility.off", "libigl-tutorial-data/3holes.off",
             "cgogn/socket.off", "cgogn/aneurysm_3D.off", "libigl-tutorial-data/bunny.off",
             "common-3d-test-models/spot.obj", "common-3d-test-models/rocker-arm.obj", "trimesh-models/round.stl",
             "trimesh-models/quadknot.obj"]


@pytest.mark.parametrize("n", [64, 128])
@pytest.mark.parametrize("name", VOXELIZED)
def test_voxelized_sample_meshes(shared_data, name, n):
    import trimesh

    from contourmesh.compare.inputs import load_closed_mesh
    from contourmesh.voxelize import voxelize_mesh

    v, f = load_closed_mesh(shared_data / "meshes" / name)
    tm = trimesh.Trimesh(v, f, process=False)
    vol, spacing, origin = voxelize_mesh(v, f, n)
    m = contourmesh.mesh(vol, spacing=spacing, origin=origin)
    chk, ref = check_topology(vol, m)
    if ref["surfaces"] == 1:  # one surface: its genus is the original mesh's
        assert chk["genus"] == round((2 - tm.euler_number) / 2)


# ------------------------------------------------------------------------------------------------
# branching joins between the polygons themselves (bridges), not voxel staircases
# ------------------------------------------------------------------------------------------------
def _fork(nz=12):
    yy, xx = np.mgrid[:30, :40]
    v = np.zeros((nz, 30, 40), bool)
    for k in range(nz):
        v[k] = ((yy - 15) ** 2 / 100 + (xx - 20) ** 2 / 225 < 1) if k < nz // 2 else \
            ((yy - 15) ** 2 + (xx - 12) ** 2 < 30) | ((yy - 15) ** 2 + (xx - 28) ** 2 < 30)
    return v


@pytest.mark.parametrize("caps", ["flat", "half"])
@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (2.5, 1.0, 1.0)])
def test_a_fork_is_one_band_to_the_bridged_arms(caps, spacing):
    v = _fork()
    m = volume_to_mesh(v, spacing=spacing, caps=caps)
    chk, _ = check_topology(v, m)
    assert chk["self_intersections"] == 0 and chk["ok"]
    assert m.meta["bridged_joins"] == 1 and m.meta["bridges"] == 1
    assert m.meta["exact_joins"] == 0 and m.meta["crack_rings"] == 0
    # no voxel staircase at the fork: its vertices are the polygons' own: none at the mid-plane between slices 5 and 6
    zmid = 5.5 * spacing[0]
    assert not np.isclose(m.vertices[:, 2], zmid).any()


def test_holes_that_open_close_or_last_one_slice_get_lids():
    # a box with a pit from the top, a pit from the bottom and a one-slice cavity
    v = np.zeros((9, 12, 12), bool)
    v[1:8, 1:11, 1:11] = True
    v[5:8, 3:6, 3:6] = False   # pit open at the top: a hole that closes going down
    v[1:3, 6:9, 6:9] = False   # pit open at the bottom
    v[4, 7:10, 2:5] = False    # a cavity one slice thick
    for caps in ("flat", "half"):
        m = volume_to_mesh(v, caps=caps)
        chk, ref = check_topology(v, m)
        assert ref["cavities"] == 1
        assert chk["self_intersections"] == 0
        assert m.meta["exact_joins"] == 0 and m.meta["bridged_joins"] >= 3


def test_bridged_joins_keep_the_voxel_topology_on_a_standing_torus_and_two_merging_lobes():
    zz, yy, xx = np.mgrid[-20:21, -8:9, -20:21]
    torus = (np.sqrt(xx ** 2 + zz ** 2) - 12) ** 2 + yy ** 2 < 25
    lobes = np.zeros((14, 24, 36), bool)
    g = np.mgrid[:24, :36]
    for k in range(14):
        r = 6 + 0.8 * k
        lobes[k] = ((g[0] - 12) ** 2 + (g[1] - 9) ** 2 < r) | ((g[0] - 12) ** 2 + (g[1] - 27) ** 2 < r)
        if k >= 9:
            lobes[k] |= ((g[0] - 12) ** 2 / 30 + (g[1] - 18) ** 2 / 160 < 1)
    for v in (torus, lobes):
        m = volume_to_mesh(v)
        chk, _ = check_topology(v, m)
        assert m.meta["bridged_joins"] >= 1 and m.meta["exact_joins"] == 0
        assert chk["self_intersections"] == 0


def test_bridged_ring_is_an_euler_tour_and_bridges_keep_clear():
    from contourmesh.bands.bridges import bridge_tree, bridged_ring, segments_cross

    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    rings = [sq, sq + [3, 0], sq + [6, 0]]
    edges_a = np.concatenate(rings)
    edges_b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    br = bridge_tree(rings, edges_a, edges_b)
    assert len(br) == 2
    seq = bridged_ring([4, 4, 4], br)
    assert len(seq) == 12 + 2 * 2  # every vertex once, every bridge end once more
    assert sorted(set(seq)) == [(r, v) for r in range(3) for v in range(4)]
    # each bridge is walked once each way
    walk = [rings[r][v] for r, v in seq]
    steps = {(tuple(walk[i]), tuple(walk[(i + 1) % len(walk)])) for i in range(len(walk))}
    for i, vi, j, vj in br:
        p, q = tuple(rings[i][vi]), tuple(rings[j][vj])
        assert (p, q) in steps and (q, p) in steps
    # a wall between two rings leaves no bridge
    wall_a, wall_b = np.array([[2.0, -5.0]]), np.array([[2.0, 5.0]])
    assert bridge_tree(rings[:2], np.r_[edges_a[:8], wall_a], np.r_[edges_b[:8], wall_b]) is None
    # touching counts as crossing
    assert segments_cross(np.array([0.0, 0.0]), np.array([2.0, 0.0]), [[1.0, 0.0]], [[1.0, 1.0]]).all()
    assert not segments_cross(np.array([0.0, 0.0]), np.array([2.0, 0.0]), [[1.0, 0.5]], [[1.0, 1.0]]).any()


def _bent_keyhole_volume():
    """A square with a square hole (slices 1-2) under the same square whose hole runs out of its
    side through an L-shaped channel (slices 3-4): the hole opens between slices 2 and 3, and no
    straight segment from the hole to the outer contour stays in the channel."""
    v = np.zeros((6, 26, 26), bool)
    a = np.zeros((26, 26), bool)
    a[2:22, 2:22] = True
    a[10:14, 10:14] = False
    b = a.copy()
    b[11:13, 14:20] = False  # the channel: right from the hole ...
    b[11:22, 18:22] = False  # ... then up and out at the top-right corner
    v[1] = v[2] = a
    v[3] = v[4] = b
    return v


@pytest.mark.parametrize("kw", [dict(triangulation="optimal"), dict(refine="band")])
def test_polyline_keyhole_where_no_straight_keyhole_keeps_clear(monkeypatch, kw):
    """Issue 14 (a): a keyhole follows the uncovered channel as a polyline, so the join is bridged
    between the polygons instead of becoming a voxel-exact join."""
    from contourmesh.bands import bridges

    v = _bent_keyhole_volume()
    found = []
    path = bridges.keyhole_path

    def keyhole_path(*a, **k):
        got = path(*a, **k)
        found.append(got)
        return got

    # with the branching join's polygons densified (a vertex every pixel) a straight keyhole from a
    # vertex inside the channel's mouth keeps clear: the polyline keyholes are tested on the
    # polygons' own vertices
    from contourmesh import volumes

    monkeypatch.setattr(volumes, "_DENSE_STEP", 1.0)
    m0 = volume_to_mesh(v, **kw)
    check_topology(v, m0)
    assert m0.meta["exact_joins"] == 0 and m0.meta["bridged_joins"] == 1 and m0.meta["dense_rings"] >= 2
    monkeypatch.setattr(volumes, "_DENSE_STEP", None)
    monkeypatch.setattr(volumes, "_DENSE_RETRY_STEP", None)  # (the failed join's retry on densified rings)
    monkeypatch.setattr(bridges, "keyhole_path", keyhole_path)
    m = volume_to_mesh(v, **kw)
    chk, _ = check_topology(v, m)
    assert m.meta["exact_joins"] == 0 and m.meta["bridged_joins"] == 1 and m.meta["dense_rings"] == 0
    assert chk["self_intersections"] == 0 and m.meta["self_intersections"] == 0
    got = [g for g in found if g is not None]
    assert len(got) == 1 and len(got[0][2]) >= 1  # a bent keyhole, with interior points
    # its interior points are mesh vertices in the plane of the opening hole (z = 2), inside the channel
    pts = got[0][2]
    for p in pts:
        assert np.isclose(np.hypot(*(m.vertices[:, :2] - p).T), 0, atol=1e-2).any()
        i, j = np.rint(p).astype(int)
        assert v[2, j, i] and not v[3, j, i]
    # only straight keyholes: none keeps clear, and an intermediate section splits the join
    # (contourmesh.sections); without sections too, the join is exact (voxel walls)
    from contourmesh import sections

    monkeypatch.setattr(bridges, "keyhole_path", lambda *a, **k: None)
    m2 = volume_to_mesh(v, **kw)
    check_embedded(v, m2)
    assert m2.meta["exact_joins"] == 0 and m2.meta["intermediate_sections"] >= 1
    monkeypatch.setattr(sections, "MAX_DEPTH", 0)
    m3 = volume_to_mesh(v, **kw)
    check_topology(v, m3)
    assert m3.meta["exact_joins"] == 1 and m3.meta["bridged_joins"] == 0


def test_bridged_ring_walks_a_polyline_bridge_out_and_back():
    from contourmesh.bands.bridges import bridged_ring

    pts = np.array([[5.0, 5.0], [6.0, 5.0]])
    seq = bridged_ring([4, 3], [(0, 1, 1, 2, pts)])
    assert seq == [(0, 0), (0, 1), (2, 0), (2, 1), (1, 2), (1, 0), (1, 1), (1, 2), (2, 1), (2, 0), (0, 1),
                   (0, 2), (0, 3)]


def test_bridged_ring_arrays_are_the_tour_of_bridged_ring():
    # random bridge trees over 1-6 rings of 1-8 points (straight and polyline bridges, either end
    # first): the ranges give the vertex-by-vertex tour, pair for pair
    from contourmesh.bands.bridges import bridged_ring, bridged_ring_arrays

    rng = np.random.default_rng(72)
    trees = 0
    for _ in range(1500):
        lengths = [int(v) for v in rng.integers(1, 9, int(rng.integers(1, 7)))]
        bridges, used = [], set()
        for j in range(1, len(lengths)):
            i = int(rng.integers(0, j))
            free_i = [v for v in range(lengths[i]) if (i, v) not in used]
            free_j = [v for v in range(lengths[j]) if (j, v) not in used]
            if not free_i or not free_j:
                break
            vi, vj = int(rng.choice(free_i)), int(rng.choice(free_j))
            used |= {(i, vi), (j, vj)}
            br = (i, vi, j, vj) if rng.random() < 0.5 else (j, vj, i, vi)
            if rng.random() < 0.3:
                br = br + (rng.random((int(rng.integers(1, 4)), 2)),)
            bridges.append(br)
        else:
            ring, vertex = bridged_ring_arrays(lengths, bridges)
            assert ring.dtype == vertex.dtype == np.int64
            assert list(zip(ring.tolist(), vertex.tolist())) == bridged_ring(lengths, bridges)
            trees += len(bridges) > 1
    assert trees > 500


def test_tour_kernel_gives_the_python_tour():
    # the compiled tour against the Python ranges it replaced: random forests of bridges over 1-7
    # rings (any root, rings numbered in any order, polyline bridges), and the inputs it hands back
    # to Python (two bridge ends at one vertex, a cycle of bridges)
    from contourmesh.bands.bridges import _bridged_ring_arrays_py, _tour_kernel, bridged_ring_arrays

    rng = np.random.default_rng(97)
    compiled = 0
    for _ in range(2000):
        n = int(rng.integers(1, 8))
        lengths = [int(v) for v in rng.integers(1, 10, n)]
        order = rng.permutation(n)
        bridges, used = [], set()
        for t in range(1, n):
            if rng.random() < 0.1:
                continue  # (a forest: some rings stay unreached)
            i, j = int(order[int(rng.integers(0, t))]), int(order[t])
            vi, vj = int(rng.integers(0, lengths[i])), int(rng.integers(0, lengths[j]))
            used_before = (i, vi) in used or (j, vj) in used
            if used_before and rng.random() < 0.7:
                continue
            used |= {(i, vi), (j, vj)}
            br = (i, vi, j, vj) if rng.random() < 0.5 else (j, vj, i, vi)
            if rng.random() < 0.3:
                br = br + (rng.random((int(rng.integers(1, 4)), 2)),)
            bridges.append(br)
        root = int(rng.integers(0, n))
        want = _bridged_ring_arrays_py(lengths, bridges, root)
        got = bridged_ring_arrays(lengths, bridges, root)
        assert [a.tolist() for a in got] == [a.tolist() for a in want]
        br = np.array([tuple(b[:4]) + (len(b[4]) if len(b) > 4 else 0,) for b in bridges], np.int64).reshape(-1, 5)
        rr, vv, ok = _tour_kernel(np.array(lengths, np.int64), br, np.int64(root))
        if ok:
            compiled += 1
            assert [rr.tolist(), vv.tolist()] == [a.tolist() for a in want]
        else:  # handed back: two ends at one vertex
            ends = [(b[0], b[1]) for b in bridges] + [(b[2], b[3]) for b in bridges]
            assert len(set(ends)) < len(ends)
    assert compiled > 1500
    # a cycle of bridges is handed back to Python
    _, _, ok = _tour_kernel(np.array([3, 3, 3], np.int64), np.array([[0, 0, 1, 0, 0], [1, 1, 2, 0, 0],
                                                                     [2, 1, 0, 1, 0]], np.int64), np.int64(0))
    assert ok == 0


def test_bridged_joins_of_drawn_rings_keep_the_volume_within_the_rules(monkeypatch):
    """Issue 15 (through issue 14's bridged joins): on the contours route a fork or merge is a
    bridged join, and its band goes through the same volume guard as every other band: the two
    lobes drawn 3 mm apart with flat caps hold a volume between the frustum and trapezoid rules."""
    from contourmesh import volumes
    from contourmesh.compare.phantoms import draw, frustum_volume, trapezoid_volume, two_lobes

    stack = draw(two_lobes(10, 8, 14), 3.0, 0.5, seed=0)
    lo, hi = sorted((trapezoid_volume(stack), frustum_volume(stack)))
    m = contourmesh.mesh(stack, caps="flat")
    assert m.meta["route"] == "contours" and m.meta["bridged_joins"] >= 1
    assert m.meta["self_intersections"] == 0 and m.checks()["ok"]
    assert lo * (1 - 1e-4) <= m.volume <= hi * (1 + 1e-4)
    # without the guard on its bridged joins the volume falls below the frustum rule
    join = volumes._bridge_join
    monkeypatch.setattr(volumes, "_bridge_join", lambda *a: join(*a[:12]))
    m2 = contourmesh.mesh(stack, caps="flat")
    assert m2.meta["bridged_joins"] == m.meta["bridged_joins"]
    assert m2.volume < lo * (1 - 1e-4)


def test_the_general_mesher_reads_a_fortran_ordered_volume_without_copying_it():
    """Issue 16 (memory): a boolean volume in another memory layout (Fortran-ordered, as many file
    readers give it, or sliced along another axis) is read a slice at a time, not copied whole in
    C order and held to the end (a Fortran-ordered one gives its slices' runs from one pass over its
    bytes, :class:`contourmesh.fastpath.FortranRuns`; another layout is copied a block of slices at
    a time, :class:`_Planes`): a
    400 x 200 x 200 volume (15.3 MiB) with a small object (a box with a cavity and a hole through
    it: the general mesher) is meshed with less than 5 MiB of Python and numpy allocations at the
    peak (a block of 64 slices is 2.4 MiB; 16.1 MiB with the copy), and every layout gives the same
    mesh."""
    import tracemalloc

    vol = np.zeros((400, 200, 200), dtype=bool)
    vol[290:300, 90:110, 90:110] = True
    vol[292:298, 95:105, 95:105] = False
    vol[295, 99:101, 90:110] = False
    want = volume_to_mesh(vol)
    assert want.meta["method"] == "contourmesh" and "fast_path" not in want.meta
    fortran = np.asfortranarray(vol)
    tracemalloc.start()
    try:
        got = volume_to_mesh(fortran)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 5 * 2**20, peak
    for m in (got, volume_to_mesh(np.transpose(vol, (1, 0, 2)), axis=1),
              volume_to_mesh(np.transpose(vol, (1, 2, 0)), axis=2)):
        assert np.array_equal(m.vertices, want.vertices) and np.array_equal(m.faces, want.faces)


def test_densified_rings_are_the_same_for_any_memory_layout():
    """The general mesher's densified rings test their points against one slice of the mask, made
    C-ordered where the volume is not: random blobs (forks and merges with specks: densified)
    give the same mesh from a Fortran-ordered copy of the volume."""
    rng = np.random.default_rng(11)
    vol = np.pad(rng.random((14, 18, 17)) < 0.4, 1)
    want = volume_to_mesh(vol)
    assert want.meta["dense_rings"] > 0
    got = volume_to_mesh(np.asfortranarray(vol))
    assert np.array_equal(got.vertices, want.vertices) and np.array_equal(got.faces, want.faces)
