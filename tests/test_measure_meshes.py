import subprocess
import sys

import numpy as np
import pytest
import trimesh

from contourmesh import Mesh
from contourmesh.measure import mesh_checks


def _box():
    tm = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    return Mesh(tm.vertices, tm.faces)


def test_box_measures_match_trimesh():
    m = _box()
    assert m.area == pytest.approx(2 * (6 + 8 + 12))
    assert m.volume == pytest.approx(24.0)
    chk = m.checks()
    assert chk["ok"] and chk["genus"] == 0 and chk["components"] == 1


def test_checks_catch_flipped_face_open_mesh_and_degenerate():
    m = _box()
    f = m.faces.copy()
    f[0] = f[0, ::-1]
    chk = mesh_checks(m.vertices, f)
    assert not chk["winding_consistent"] and not chk["ok"]
    chk = mesh_checks(m.vertices, m.faces[1:])
    assert not chk["watertight"] and chk["boundary_edges"] == 3
    inv = mesh_checks(m.vertices, m.faces[:, ::-1])
    assert inv["volume"] < 0 and not inv["ok"]
    v = np.vstack([m.vertices, [[0.0, 0.0, 0.0]]])
    f = np.vstack([m.faces, [[0, 1, 0]]])
    assert mesh_checks(v, f)["degenerate_faces"] == 1


def test_torus_genus():
    tm = trimesh.creation.torus(major_radius=3, minor_radius=1)
    chk = Mesh(tm.vertices, tm.faces).checks()
    assert chk["watertight"] and chk["genus"] == 1


def test_mesh_validates_shapes():
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        Mesh(np.zeros((3, 2)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="do not exist"):
        Mesh(np.zeros((3, 3)), np.array([[0, 1, 5]]))


@pytest.mark.parametrize("suffix", ["ply", "obj", "stl", "off"])
def test_save_roundtrip_and_deterministic(tmp_path, suffix):
    m = _box()
    p = m.save(tmp_path / f"box.{suffix}")
    data1 = p.read_bytes()
    m.save(p)
    assert p.read_bytes() == data1
    back = trimesh.load(p, process=True)
    assert back.area == pytest.approx(m.area)
    assert abs(back.volume) == pytest.approx(m.volume)


def test_save_refuses_unknown_suffix_existing_file_and_directory(tmp_path):
    m = _box()
    with pytest.raises(ValueError, match="suffix"):
        m.save(tmp_path / "x.xyz")
    p = m.save(tmp_path / "a.ply")
    with pytest.raises(FileExistsError, match="already exists"):
        m.save(p, force=False)
    with pytest.raises(IsADirectoryError):
        m.save(tmp_path, force=True)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        m.save(tmp_path / "nope" / "a.ply")


def test_atomic_write_killed_midway_leaves_old_file(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    code = f"""
import os, sys
sys.path.insert(0, {str(__import__('pathlib').Path(__file__).resolve().parents[1] / 'src')!r})
import contourmesh.meshes as mm
real = os.fsync
def dying(fd):
    os._exit(9)
mm.os.fsync = dying
mm.atomic_write({str(target)!r}, b"new" * 1000000)
"""
    r = subprocess.run([sys.executable, "-c", code])
    assert r.returncode == 9
    assert target.read_bytes() == b"old"


def test_adapters_open3d_pymeshlab():
    m = _box()
    pytest.importorskip("open3d", reason="open3d not installed")
    o = m.to_open3d()
    assert len(o.triangles) == len(m.faces)
    pytest.importorskip("pymeshlab", reason="pymeshlab not installed")
    ms = m.to_pymeshlab()
    assert ms.current_mesh().face_number() == len(m.faces)


def test_triangle_areas_of_large_meshes_equal_numpys_bit_for_bit():
    # from _COMPILED_AREAS_FROM faces on the cross products come from a compiled loop; the areas
    # must be numpy's (gather, np.cross, einsum) exactly, and bad indices keep numpy's behaviour
    from contourmesh import measure

    def numpy_areas(v, f):
        tri = v[f]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return 0.5 * np.sqrt(np.einsum("ij,ij->i", cross, cross))

    rng = np.random.default_rng(3)
    n = measure._COMPILED_AREAS_FROM
    for scale in (1e-3, 1.0, 1e4):
        v = rng.normal(size=(500, 3)) * scale
        for m in (n, n + 1, n + 17, 300, 2065):  # (small bands too: the mesher's joins measure thousands)
            f = rng.integers(0, 500, size=(m, 3))
            assert np.array_equal(measure.triangle_areas(v, f), numpy_areas(v, f))
    f[5, 1] = -3  # numpy's negative index: counted from the end, as before
    assert np.array_equal(measure.triangle_areas(v, f), numpy_areas(v, f))
    f[7, 2] = 500
    with pytest.raises(IndexError):
        measure.triangle_areas(v, f)


def test_axis_wall_fraction_matches_the_normals_rule():
    """The compiled wall share against the rule written with numpy (normals along +-x or +-y within
    1e-12 of their length), on a noisy volume's mesh (walls, slopes and caps) and on random
    triangles with exact walls mixed in; bad face arrays are refused by name."""
    import contourmesh
    from contourmesh.measure import axis_wall_fraction

    def rule(v, f):
        n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        size = np.linalg.norm(n, axis=1)
        tol = 1e-12 * size
        wall = (np.abs(n[:, 2]) <= tol) & ((np.abs(n[:, 0]) <= tol) | (np.abs(n[:, 1]) <= tol)) & (size > 0)
        return size[wall].sum() / size.sum()

    rng = np.random.default_rng(5)
    m = contourmesh.mesh(np.pad(rng.random((12, 16, 15)) < 0.4, 1))
    got = axis_wall_fraction(m.vertices, m.faces)
    assert 0.05 < got < 0.95 and got == pytest.approx(rule(m.vertices, m.faces), rel=1e-12)
    v = rng.integers(0, 3, (300, 3)).astype(float)  # many faces in x = c or y = c planes, some degenerate
    f = rng.integers(0, 300, (400, 3))
    assert axis_wall_fraction(v, f) == pytest.approx(rule(v, f), rel=1e-12)
    assert 0 < rule(v, f) < 1
    with pytest.raises(ValueError, match="outside"):
        axis_wall_fraction(v, f + 300)
    with pytest.raises(ValueError, match=r"\(m, 3\) faces"):
        axis_wall_fraction(v, f[:, :2])


@pytest.mark.parametrize("threads", ["1", "2", "3"])
def test_compiled_size_sums_are_fsums_of_the_face_terms(monkeypatch, threads):
    """surface_area and axis_wall_fraction sum the faces' sizes in compiled ranges (on threads where
    CONTOURMESH_THREADS asks): the same floats as math.fsum of face_terms' sizes, at scales from
    tiny to large, with exact walls mixed in; NaN and infinite sizes and bad faces take
    face_terms' route (its values and errors)."""
    import math

    from contourmesh import measure

    monkeypatch.setenv("CONTOURMESH_THREADS", threads)
    monkeypatch.setattr(measure, "_SPLIT_SIZES", 50)

    def reference(v, f):
        size, wall, _six = measure.face_terms(v, f)
        total = math.fsum(size)
        return 0.5 * total, (float(math.fsum(size[wall]) / total) if total > 0 else 0.0)

    rng = np.random.default_rng(11)
    for t in range(120):
        n, m = int(rng.integers(3, 80)), int(rng.integers(1, 700))
        scale = 10.0 ** int(rng.integers(-70, 76))  # (squares of the cross products below 1e308)
        v = rng.normal(size=(n, 3))
        if t % 3 == 0:
            v = np.round(v * 4) / 4  # faces in x = c or y = c planes, some degenerate
        v *= scale
        f = rng.integers(0, n, size=(m, 3))
        got = (measure.surface_area(v, f), measure.axis_wall_fraction(v, f))
        assert got == reference(v, f), (t, scale)
        assert Mesh(v, f).area == got[0]
    v = rng.normal(size=(40, 3)) * 1e76
    f = rng.integers(0, 40, size=(400, 3))
    nan, inf = (np.where(rng.random(v.shape) < 0.01, x, v) for x in (np.nan, np.inf))
    for bad in (v, v * 1e84, nan, inf):  # (finite; cross products whose squares overflow; NaN; inf)
        assert np.array_equal((measure.surface_area(bad, f), measure.axis_wall_fraction(bad, f)),
                              reference(bad, f), equal_nan=True)
    with pytest.raises(ValueError, match="outside"):
        measure.surface_area(v, f + 40)


def test_size_sums_kernel_is_exact_per_range():
    """The kernel's two expansions sum exactly what fsum sums (each range's, then all ranges' parts)."""
    import math

    from contourmesh import measure

    rng = np.random.default_rng(12)
    v = rng.normal(size=(200, 3)) * np.array([1.0, 1e-9, 1e9])
    v[:50, 0] = np.round(v[:50, 0])
    f = rng.integers(0, 200, size=(5000, 3))
    size, wall, _ = measure.face_terms(v, f)
    for a, b in ((0, 5000), (0, 1), (17, 4000), (3000, 3000)):
        ok, parts, n, wparts, nw = measure._size_sums(v, f, a, b)
        assert ok and n < measure._PARTS and nw < measure._PARTS
        assert math.fsum(parts[:n].tolist() + [-x for x in size[a:b]]) == 0.0
        assert math.fsum(wparts[:nw].tolist() + [-x for x in size[a:b][wall[a:b]]]) == 0.0
        assert math.fsum(parts[:n].tolist()) == math.fsum(size[a:b])


def test_binned_size_sums_equal_the_expansion_form():
    """measure._size_sums (sizes of normal exponents added as integers in per-exponent bins, the
    rest to the expansion) against the form that adds every size to the expansion
    (_size_sums_expansion, kept): parts whose fsums are the same floats, the same ok, on meshes
    from tiny to huge scales (hundreds of exponents, several in one mesh), many equal sizes (bins
    carried up), and NaN, infinite and overflowing sizes (the expansion's, refused)."""
    import math

    from contourmesh import measure

    def same(v, f, a, b):
        got = measure._size_sums(v, f, a, b)
        want = measure._size_sums_expansion(v, f, a, b)
        assert got[0] == want[0]
        if want[0]:
            for k in (1, 3):
                assert math.fsum(got[k][:got[k + 1]].tolist()) == math.fsum(want[k][:want[k + 1]].tolist())
        return got[0]

    rng = np.random.default_rng(21)
    exponents = set()
    for t in range(200):
        n, m = int(rng.integers(3, 60)), int(rng.integers(1, 500))
        v = rng.normal(size=(n, 3))
        if t % 3 == 0:
            v = np.round(v * 4) / 4  # (walls and degenerate faces)
        if t % 4 == 1:  # (two scales in one mesh)
            v[: n // 2] *= 10.0 ** int(rng.integers(-40, -20))
        v *= 10.0 ** int(rng.integers(-140, 76))  # (squares of the cross products below 1e308)
        f = rng.integers(0, n, size=(m, 3))
        size = measure.face_terms(v, f)[0]
        exponents.update(np.unique((size[size > 0].view(np.int64) >> 52) & 0x7FF).tolist())
        a = int(rng.integers(0, m))
        assert same(v, f, 0, m) and same(v, f, a, m)
    assert len(exponents) > 600 and min(exponents) < 500 and max(exponents) > 1400
    # one face repeated: 2^20 equal sizes carry up through the bins
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0 - 2**-40]])
    assert same(v, np.zeros((1 << 20, 3), np.int64) + np.array([0, 1, 2]), 0, 1 << 20)
    # NaN, infinite and overflowing sizes, faces outside: refused by both
    w = rng.normal(size=(30, 3)) * 1e160
    f = rng.integers(0, 30, size=(300, 3))
    for bad in (w, np.where(rng.random(w.shape) < 0.02, np.nan, w / 1e160), np.where(rng.random(w.shape) < 0.02, np.inf, w / 1e160)):
        assert not same(bad, f, 0, 300)
    assert not same(w / 1e160, f + 30, 0, 300)


def test_binned_size_sums_equal_the_expansion_form_on_the_lobster(shared_data):
    """As above, on the lobster's mesh (the volume mesher's sizes; skipped without the shared data)."""
    import math

    import contourmesh
    from contourmesh import measure
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    m = contourmesh.mesh(np.pad(vol, 1), spacing=tuple(spacing))
    v, f = np.ascontiguousarray(m.vertices), np.ascontiguousarray(m.faces, dtype=np.int64)
    got = measure._size_sums(v, f, 0, len(f))
    want = measure._size_sums_expansion(v, f, 0, len(f))
    assert got[0] and want[0]
    for k in (1, 3):
        assert math.fsum(got[k][:got[k + 1]].tolist()) == math.fsum(want[k][:want[k + 1]].tolist())
