"""MeshLab filter scripts in and out (issue 12, item 4): ``--post`` / ``--save-mlx`` / ``--mlx``."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from contourmesh.cli import main
from contourmesh.compare.postprocess import (
    MESHLAB_STEPS,
    apply_mlx,
    apply_postprocess,
    check_filter_script,
    meshlab_steps_of,
    save_filter_script,
)

pytestmark = pytest.mark.skipif(importlib.util.find_spec("pymeshlab") is None, reason="pymeshlab not installed")

POSTS = ["meshlab-planar-qec-p0.3", "meshlab-taubin-it5"]


@pytest.fixture(scope="module")
def sphere_mesh():
    import contourmesh

    return contourmesh.mesh("sphere:r=5")


def test_every_meshlab_step_is_a_post_process_and_back():
    for name in MESHLAB_STEPS:
        apply_postprocess  # noqa: B018 - the names below must parse as post-processes
        assert meshlab_steps_of([name]) == [MESHLAB_STEPS[name]]
    assert meshlab_steps_of(POSTS) == [
        ("meshing_decimation_quadric_edge_collapse", dict(MESHLAB_STEPS["meshlab-planar-qec"][1], targetperc=0.3)),
        ("apply_coord_taubin_smoothing", dict(MESHLAB_STEPS["meshlab-taubin"][1], stepsmoothnum=5)),
    ]
    with pytest.raises(ValueError, match=r"not MeshLab: \['taubin'\]"):
        meshlab_steps_of(["meshlab-taubin", "taubin"])
    with pytest.raises(ValueError, match="needs MeshLab post-processes"):
        meshlab_steps_of([])


def test_saved_script_reproduces_the_post_processes(tmp_path, sphere_mesh):
    expected = sphere_mesh
    for name in POSTS:
        expected, _ = apply_postprocess(name, expected)
    path = save_filter_script(POSTS, tmp_path / "chain.mlx")
    assert check_filter_script(path) == ["Simplification: Quadric Edge Collapse Decimation", "Taubin Smooth"]
    again = apply_mlx(sphere_mesh, path)
    np.testing.assert_array_equal(again.faces, expected.faces)
    np.testing.assert_allclose(again.vertices, expected.vertices, rtol=0, atol=1e-12)
    # and PyMeshLab itself loads the file and does the same
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=sphere_mesh.vertices, face_matrix=sphere_mesh.faces.astype(np.int32)))
    ms.load_filter_script(str(path))
    ms.apply_filter_script()
    assert ms.current_mesh().face_number() == len(expected.faces)


def test_cli_save_mlx_then_mlx_gives_the_same_mesh(tmp_path, capsys):
    # --save-mlx demanded MeshLab steps among --post but named one (meshlab-taubin) that --post refused
    a, b, script = tmp_path / "a.ply", tmp_path / "b.ply", tmp_path / "s.mlx"
    argv = ["mesh", "sphere:r=5", "-o", str(a), "--quiet", "--save-mlx", str(script)]
    for name in POSTS:
        argv += ["--post", name]
    assert main(argv) == 0, capsys.readouterr().err
    assert script.is_file()
    assert main(["mesh", "sphere:r=5", "-o", str(b), "--quiet", "--mlx", str(script)]) == 0
    import trimesh

    ta, tb = trimesh.load(a, process=False), trimesh.load(b, process=False)
    np.testing.assert_array_equal(ta.faces, tb.faces)
    np.testing.assert_allclose(ta.vertices, tb.vertices, atol=1e-6)


def _bad_scripts(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("# A README\n\nNot a filter script.\n")
    broken = tmp_path / "broken.mlx"
    broken.write_text("<FilterScript><filter name='Taubin Smooth'")
    other = tmp_path / "other.xml"
    other.write_text("<project><filter name='x'/></project>")
    empty = tmp_path / "empty.mlx"
    empty.write_text("<!DOCTYPE FilterScript>\n<FilterScript>\n</FilterScript>\n")
    unknown = tmp_path / "unknown.mlx"
    unknown.write_text('<!DOCTYPE FilterScript>\n<FilterScript>\n <filter name="No Such Filter"/>\n</FilterScript>\n')
    return {"readme": readme, "broken": broken, "other": other, "empty": empty, "unknown": unknown}


@pytest.mark.parametrize("kind", ["readme", "broken", "other", "empty", "unknown"])
def test_cli_rejects_a_file_that_is_not_a_filter_script(tmp_path, capfd, kind):
    # --mlx README.md wrote the unmodified mesh with exit 0 while PyMeshLab printed a parse error
    bad = _bad_scripts(tmp_path)[kind]
    out = tmp_path / "out.ply"
    status = main(["mesh", "sphere:r=4", "-o", str(out), "--quiet", "--mlx", str(bad)])
    err = capfd.readouterr().err
    assert status == 2
    assert not out.exists()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert str(bad) in lines[0]
    assert "FilterScript\n" not in err and "Reading filter" not in err and "Failure in setting" not in err


def test_pymeshlab_chatter_is_silenced(tmp_path, capfd, sphere_mesh):
    script = save_filter_script(["meshlab-taubin-it2"], tmp_path / "t.mlx")
    capfd.readouterr()
    apply_mlx(sphere_mesh, script)
    captured = capfd.readouterr()
    assert "Reading filter" not in captured.err + captured.out
    assert "FilterScript" not in captured.err + captured.out


def test_postprocess_names_the_install_when_pymeshlab_is_missing(monkeypatch, sphere_mesh):
    monkeypatch.setitem(sys.modules, "pymeshlab", None)
    with pytest.raises(ImportError, match=r"pip install pymeshlab .*contourmesh\[compare\]"):
        apply_postprocess("meshlab-taubin", sphere_mesh)
