"""Peer methods, local estimators and post-processes of the comparison harness."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from contourmesh.compare import local
from contourmesh.compare.methods import (
    Method,
    available_methods,
    get_method,
    register_method,
    run_method,
    unregister_method,
    voxel_boundary_mesh,
)
from contourmesh.compare.postprocess import apply_postprocess, get_postprocess, merge_coplanar, save_filter_script

ROOT = Path(__file__).resolve().parents[1]


def have(*modules):
    return all(importlib.util.find_spec(m) is not None for m in modules)


def ball(r: float, shift: float = 0.37) -> np.ndarray:
    """Gauss digitization of a ball of radius r (voxel units), centre off the lattice."""
    n = int(2 * r + 6)
    g = np.arange(n) - (n - 1) / 2 + shift
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    return x * x + y * y + z * z < r * r


R = 16.0
BALL = ball(R)
AREA = 4 * np.pi * R * R

# name, required modules, (low, high) relative error, closed surface promised
CASES = [
    ("mc-lewiner", ("skimage",), (0.05, 0.10), True),
    ("mc-lorensen", ("skimage",), (0.05, 0.10), True),
    ("mc-lewiner-blur1", ("skimage",), (-0.015, 0.015), True),
    ("vtk-flyingedges", ("vtk",), (0.05, 0.10), True),
    ("vtk-discreteflyingedges", ("vtk",), (0.05, 0.10), True),
    ("vtk-surfacenets", ("vtk",), (-0.03, 0.0), True),  # -1.4 % at r = 20, -0.05 % at r = 80
    ("zmesh", ("zmesh",), (0.05, 0.10), True),  # marching cubes, as skimage's
    ("serra", ("serra_mesh",), (0.0, 0.06), True),
    ("serra-taubin10", ("serra_mesh",), (-0.01, 0.02), True),
    ("o3d-poisson-d7", ("open3d",), (-0.03, 0.03), True),
    ("o3d-alpha-a1", ("open3d",), (0.0, 0.10), True),  # staircase through voxel centres
    ("ml-spoisson-d7", ("pymeshlab",), (-0.03, 0.03), True),
    ("ml-alphawrap-a2-o0.1", ("pymeshlab",), (0.0, 0.2), True),
    ("voxel-faces", (), (0.40, 0.55), True),
    ("surfels", (), (0.40, 0.55), False),
    ("mullikin-verbeek", (), (-0.04, 0.0), False),
    ("lindblad", (), (-0.01, 0.01), False),
    ("dgtal-ii-r3", ("dgtal",), (-0.02, 0.02), False),
    ("dgtal-vcm-R5-r3", ("dgtal",), (-0.02, 0.02), False),
]


@pytest.mark.parametrize("name, modules, bounds, closed", CASES, ids=[c[0] for c in CASES])
def test_ball_error_sign_and_size(name, modules, bounds, closed):
    if not have(*modules):
        pytest.skip(f"{modules} not installed")
    row = run_method(name, BALL, spacing=(0.5, 0.5, 0.5), origin=(1.0, 2.0, 3.0))
    assert row["status"] == "ok", row["error"]
    err = row["area"] / (AREA * 0.25) - 1
    assert bounds[0] <= err <= bounds[1], f"{name}: relative error {err:+.4f} outside {bounds}"
    if closed:
        assert row["watertight"] and row["winding_consistent"], name
        assert row["volume"] > 0, f"{name}: faces not outward"
        assert row["P"] == len(row["mesh"].vertices) and row["faces"] == len(row["mesh"].faces)
        # physical frame: the ball's centre maps to origin + centre index * spacing
        centre = np.array([1.0, 2.0, 3.0]) + 0.5 * ((BALL.shape[0] - 1) / 2 - 0.37)
        assert np.allclose(row["mesh"].vertices.mean(axis=0), centre, atol=0.3)
    else:
        assert row["mesh"] is None and row["P"] is None


def test_ball_pivoting_runs_and_reports_open_surface():
    if not have("open3d"):
        pytest.skip("open3d not installed")
    row = run_method("o3d-bpa-r0.8", ball(8))
    assert row["status"] == "ok", row["error"]
    assert row["faces"] > 0 and isinstance(row["watertight"], bool)


# --- axis order and anisotropic spacing ---------------------------------------------------------
def _box():
    vol = np.zeros((7, 10, 16), dtype=bool)  # [z, y, x]
    vol[2:5, 2:8, 3:14] = True  # 3 x 6 x 11 voxels
    spacing = (3.0, 2.0, 1.0)  # dz, dy, dx
    origin = (10.0, 20.0, 30.0)  # x0, y0, z0
    ext = np.array([11 * 1.0, 6 * 2.0, 3 * 3.0])  # physical x, y, z extents of the voxel union
    return vol, spacing, origin, ext


@pytest.mark.parametrize("name, modules", [("voxel-faces", ()), ("mc-lewiner", ("skimage",)),
                                           ("vtk-flyingedges", ("vtk",)), ("vtk-discreteflyingedges", ("vtk",))])
def test_vertex_order_is_xyz_with_anisotropic_spacing(name, modules):
    if not have(*modules):
        pytest.skip(f"{modules} not installed")
    vol, spacing, origin, ext = _box()
    row = run_method(name, vol, spacing=spacing, origin=origin)
    assert row["status"] == "ok", row["error"]
    v = row["mesh"].vertices
    extents = v.max(0) - v.min(0)
    if name == "voxel-faces":
        assert np.allclose(extents, ext)
        assert np.allclose(v.min(0), [10.0 + 2.5 * 1.0, 20.0 + 1.5 * 2.0, 30.0 + 1.5 * 3.0])  # origin is (x0, y0, z0)
    else:  # the 0.5 level runs through the voxel faces' planes on a box
        assert np.allclose(extents, ext, atol=1e-9)
    assert row["volume"] > 0


def test_local_and_dgtal_anisotropic_box():
    vol, spacing, origin, ext = _box()
    x, y, z = ext
    exact = 2 * (x * y + y * z + x * z)
    assert local.surfel_area(vol, spacing) == pytest.approx(exact, rel=1e-12)
    assert run_method("surfels", vol, spacing, origin)["area"] == pytest.approx(exact, rel=1e-12)
    if have("dgtal"):
        row = run_method("dgtal-ii-r2", vol, spacing, origin)
        assert row["status"] == "ok", row["error"]
        # normals tilt near the edges, so slightly less; a wrong axis order would miss by tens of %
        assert 0.85 * exact < row["area"] <= exact * 1.001
    with pytest.raises(ValueError, match="isotropic"):
        local.mullikin_verbeek_area(vol, spacing)


# --- statuses -------------------------------------------------------------------------------------
def _hide(monkeypatch, top):
    """Make ``top`` and its submodules unimportable, as if the package were not installed."""
    for name in [n for n in sys.modules if n == top or n.startswith(top + ".")] + [top]:
        monkeypatch.setitem(sys.modules, name, None)


@pytest.mark.parametrize("name", ["vtk-flyingedges", "vtk-discreteflyingedges", "vtk-surfacenets"])
def test_vtk_missing_gives_the_install_hint(monkeypatch, name):
    # issue 11: the VTK methods imported vtkmodules before the helper that names the package
    _hide(monkeypatch, "vtkmodules")
    _hide(monkeypatch, "vtk")
    row = run_method(name, ball(5))
    assert row["status"] == "not-installed"
    assert "pip install vtk" in row["error"] and "contourmesh[compare]" in row["error"]


def test_not_installed_is_reported(monkeypatch):
    monkeypatch.setitem(sys.modules, "skimage.measure", None)
    row = run_method("mc-lewiner", ball(5))
    assert row["status"] == "not-installed" and "pip install scikit-image" in row["error"]


def test_failures_are_rows_with_the_error_text():
    def boom(volume, spacing, origin):
        raise RuntimeError("boom: the method broke")

    register_method(Method("test-boom", "local", {}, boom))
    try:
        row = run_method("test-boom", ball(5))
    finally:
        unregister_method("test-boom")
    assert row["status"] == "failed" and "boom: the method broke" in row["error"]
    assert row["seconds"] >= 0
    empty = run_method("mc-lewiner", np.zeros((5, 5, 5), dtype=bool))
    assert empty["status"] == "failed" and "level" in empty["error"]


def test_timeout_runs_in_a_subprocess():
    row = run_method("surfels", ball(6), timeout=0.05)  # a spawned interpreter cannot start that fast
    assert row["status"] == "timeout" and row["family"] == "local"
    row = run_method("lindblad", ball(6), timeout=120)
    assert row["status"] == "ok" and row["area"] == pytest.approx(local.lindblad_area(ball(6))[0])


def test_bad_input_is_the_callers_error():
    with pytest.raises(ValueError, match="3D array"):
        run_method("surfels", np.zeros((4, 4), dtype=bool))
    with pytest.raises(ValueError, match="spacing"):
        run_method("surfels", ball(4), spacing=(1, 0, 1))
    with pytest.raises(ValueError, match="values other than 0 and 1"):
        run_method("surfels", np.full((3, 3, 3), 0.5))


# --- names ----------------------------------------------------------------------------------------
def test_names_and_parameters():
    m = get_method("mc-lewiner-blur1.5")
    assert m.family == "marching-cubes" and m.params == {"blur": 1.5, "method": "lewiner"}
    assert get_method("dgtal-vcm-R6-r2").params == {"offset_radius": 6.0, "radius": 2.0, "estimator": "vcm"}
    assert get_method("o3d-poisson-d9-estnormals").params["estimate_normals"] is True
    assert get_method("vtk-surfacenets-it0").params == {"iterations": 0}
    for name in available_methods():
        assert get_method(name).name == name
    with pytest.raises(ValueError, match="valid names"):
        get_method("marching-squares")
    with pytest.raises(ValueError, match="cannot read parameter"):
        get_method("mc-lewiner-sigma2")
    with pytest.raises(ValueError, match="integer"):
        get_method("o3d-poisson-d7.5")


def test_importing_does_not_import_heavy_packages():
    code = ("import sys, contourmesh.compare.methods, contourmesh.compare.postprocess, contourmesh.compare.local;"
            "print([m for m in ('vtk', 'open3d', 'pymeshlab', 'dgtal', 'skimage') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(ROOT / "src"), "PATH": ""})
    assert out.stdout.strip() == "[]"


# --- local estimators -----------------------------------------------------------------------------
def test_mcube_cases_have_the_classic_class_sizes():
    sizes = np.bincount([local.mcube_case(c) for c in range(256)], minlength=14)
    assert sizes.tolist() == [2, 16, 24, 24, 8, 48, 48, 16, 6, 8, 6, 24, 24, 2]
    assert local.mcube_case(0b00000011) == 2 and local.mcube_case(0b00001111) == 8
    assert local.mcube_case(0b10000001) == 4 and local.mcube_case(0b00010111) == 9


def test_local_estimators_on_a_single_voxel_and_counts():
    one = np.zeros((3, 3, 3), dtype=bool)
    one[1, 1, 1] = True
    assert local.surfel_area(one) == 6.0
    area, counts = local.mullikin_verbeek_area(one)
    assert counts == {"S1": 0, "S2": 0, "S3": 0, "other": 1} and area == pytest.approx(6 * 0.894)
    area, per_case = local.lindblad_area(one)
    assert per_case[1] == 8 and area == pytest.approx(8 * 0.638)
    assert local.boundary_face_counts(BALL).sum() == local.surfel_area(BALL)


# --- post-processes -------------------------------------------------------------------------------
def test_merge_coplanar_on_a_box_keeps_area_and_edge_vertices():
    vol, spacing, origin, ext = _box()
    stairs = voxel_boundary_mesh(vol, spacing, origin)
    merged = merge_coplanar(stairs)
    assert merged.area == pytest.approx(stairs.area, rel=1e-12)
    # only the lattice points on the box's 12 edges survive (shared by two faces each)
    assert len(merged.vertices) == 8 + 4 * (11 - 1) + 4 * (6 - 1) + 4 * (3 - 1)
    assert merged.checks()["ok"]


def test_merge_coplanar_on_a_staircase_ball():
    stairs = voxel_boundary_mesh(ball(8), spacing=(2.0, 1.0, 0.5))
    out, info = apply_postprocess("merge-coplanar", stairs)
    assert abs(info["area_after"] - info["area_before"]) <= 1e-9 * info["area_before"]
    assert info["P_after"] < info["P_before"] and info["faces_after"] < info["faces_before"]
    chk = out.checks()
    assert chk["watertight"] and chk["winding_consistent"] and chk["volume"] == pytest.approx(stairs.volume)


def test_postprocess_chain_through_run_method():
    if not have("skimage"):
        pytest.skip("scikit-image not installed")
    row = run_method("mc-lewiner", ball(8), postprocess=["merge-coplanar", "taubin-it5"])
    assert row["status"] == "ok", row["error"]
    merge, smooth = row["extra"]["post"]
    assert merge["area_after"] == pytest.approx(merge["area_before"], rel=1e-9) and merge["P_after"] < merge["P_before"]
    assert smooth["area_before"] == pytest.approx(merge["area_after"]) and smooth["P_after"] == merge["P_after"]
    assert smooth["area_after"] != smooth["area_before"] and row["area"] == pytest.approx(smooth["area_after"])
    assert row["P"] == smooth["P_after"]
    with pytest.raises(ValueError, match="unknown post-process"):
        get_postprocess("decimate")


@pytest.mark.skipif(not have("pymeshlab"), reason="pymeshlab not installed")
def test_meshlab_planar_qec_and_shipped_script(tmp_path):
    stairs = voxel_boundary_mesh(ball(6))
    out, info = apply_postprocess("meshlab-planar-qec", stairs)
    assert info["P_after"] < info["P_before"] and out.checks()["watertight"]
    shipped = ROOT / "comparisons" / "meshlab" / "planar-qec.mlx"
    assert shipped.is_file()
    out2, info2 = apply_postprocess(f"mlx:{shipped}", stairs)
    assert info2["faces_after"] == info["faces_after"]
    path = save_filter_script(["meshlab-planar-qec", "meshlab-taubin"], tmp_path / "chain.mlx")
    text = path.read_text()
    assert "Quadric Edge Collapse" in text and "Taubin" in text


@pytest.mark.parametrize("name", ["zmesh", "serra-taubin10"])
def test_multilabel_peers_are_placed_like_the_others(name):
    """Vertices in the same physical frame as marching cubes: the meshes' centroids agree."""
    if not have("zmesh" if name == "zmesh" else "serra_mesh", "skimage"):
        pytest.skip("zmesh / serra-mesh not installed")
    def centroid(method):
        m = get_method(method)
        return m.fn(BALL, (0.5, 0.75, 1.0), (1.0, 2.0, 3.0), **m.params).mesh.vertices.mean(0)

    ca, cb = centroid(name), centroid("mc-lewiner")
    assert np.allclose(ca, cb, atol=0.05), (ca, cb)
