"""The command line on bad inputs (one line, non-zero exit), --force, and nothing lost on a kill."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from contourmesh.cli import main

ROOT = Path(__file__).resolve().parents[1]
ENV = dict(os.environ, PYTHONPATH=str(ROOT / "src"))


@pytest.fixture
def blob_npy(tmp_path):
    v = np.zeros((5, 8, 8), bool)
    v[1:4, 2:6, 1:7] = True
    v[2, 3:5, 3:5] = False
    p = tmp_path / "blob.npy"
    np.save(p, v)
    return p


def _one_line_error(capsys, argv, *pattern):
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("contourmesh: error: "), err
    assert "Traceback" not in err
    for p in pattern:
        assert p in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize("case", ["missing", "directory", "nan", "labels", "pickled", "unknown-suffix", "spec"])
def test_bad_inputs_print_one_line_and_exit_2(case, tmp_path, capsys):
    out = str(tmp_path / "out.ply")
    if case == "missing":
        _one_line_error(capsys, ["mesh", str(tmp_path / "nope.npy"), "-o", out, "--quiet"], "does not exist")
    elif case == "directory":
        _one_line_error(capsys, ["mesh", str(tmp_path), "-o", out, "--quiet"], "directory")
    elif case == "nan":
        np.save(tmp_path / "nan.npy", np.full((2, 2, 2), np.nan))
        _one_line_error(capsys, ["mesh", str(tmp_path / "nan.npy"), "-o", out, "--quiet"], "NaN")
    elif case == "labels":
        np.save(tmp_path / "lab.npy", np.arange(8).reshape(2, 2, 2))
        _one_line_error(capsys, ["mesh", str(tmp_path / "lab.npy"), "-o", out, "--quiet"], "--label", "--threshold", "int64", "from 0 to 7")
    elif case == "pickled":
        np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
        _one_line_error(capsys, ["mesh", str(tmp_path / "obj.npy"), "-o", out, "--quiet"], "refusing to unpickle")
    elif case == "unknown-suffix":
        np.save(tmp_path / "b.npy", np.ones((2, 2, 2), bool))
        _one_line_error(capsys, ["mesh", str(tmp_path / "b.npy"), "-o", str(tmp_path / "out.xyz"), "--quiet"],
                        "expected a suffix among")
    elif case == "spec":
        _one_line_error(capsys, ["mesh", "sphere:r=-3", "-o", out, "--quiet"])
    assert not Path(out).exists()


def test_debug_shows_the_traceback(tmp_path):
    with pytest.raises(FileNotFoundError):
        main(["--debug", "mesh", str(tmp_path / "nope.npy"), "-o", str(tmp_path / "o.ply"), "--quiet"])


def test_existing_output_needs_force(blob_npy, tmp_path, capsys):
    out = tmp_path / "m.ply"
    out.write_bytes(b"old")
    _one_line_error(capsys, ["mesh", str(blob_npy), "-o", str(out), "--quiet"], "already exists", "--force")
    assert out.read_bytes() == b"old"
    assert main(["mesh", str(blob_npy), "-o", str(out), "--quiet", "--force"]) == 0
    assert out.read_bytes()[:3] == b"ply"


def test_output_is_a_directory_or_in_a_missing_folder(blob_npy, tmp_path, capsys):
    d = tmp_path / "adir"
    d.mkdir()
    _one_line_error(capsys, ["mesh", str(blob_npy), "-o", str(d), "--quiet", "--force"], "directory")
    _one_line_error(capsys, ["mesh", str(blob_npy), "-o", str(tmp_path / "no" / "m.ply"), "--quiet"], "does not exist")


def test_unwritable_output_folder(blob_npy, tmp_path, capsys):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        if os.access(d, os.W_OK):
            pytest.skip("running as root: permissions are not enforced")
        _one_line_error(capsys, ["mesh", str(blob_npy), "-o", str(d / "m.ply"), "--quiet"], "not writable")
    finally:
        d.chmod(0o700)


@pytest.mark.parametrize("fmt", ["ply", "obj", "stl", "off"])
def test_same_input_gives_byte_identical_files(blob_npy, tmp_path, fmt):
    """In-process twice, and once in a fresh interpreter (another hash seed)."""
    outs = []
    for i in range(2):
        out = tmp_path / f"m{i}.{fmt}"
        assert main(["mesh", str(blob_npy), "-o", str(out), "--quiet"]) == 0
        outs.append(out.read_bytes())
    if fmt == "ply":
        out = tmp_path / "fresh.ply"
        r = subprocess.run([sys.executable, "-m", "contourmesh", "mesh", str(blob_npy), "-o", str(out), "--quiet"],
                           env=dict(ENV, PYTHONHASHSEED="123"), capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        outs.append(out.read_bytes())
    assert all(o == outs[0] for o in outs)
    assert len(outs[0]) > 100


_WRITER = r"""
import sys
from contourmesh.meshes import atomic_write
path, a, b = sys.argv[1], open(sys.argv[2], 'rb').read(), open(sys.argv[3], 'rb').read()
print('ready', flush=True)
i = 0
while True:
    atomic_write(path, a if i % 2 == 0 else b)
    i += 1
"""


def test_a_killed_writer_leaves_the_old_or_the_new_file(tmp_path):
    """SIGKILL a process that keeps rewriting a 24 MB file: the file is always one whole version."""
    a = tmp_path / "a.bin"
    b = tmp_path / "b.bin"
    a.write_bytes(b"A" * (24 << 20))
    b.write_bytes(b"B" * (24 << 20))
    target = tmp_path / "mesh.ply"
    target.write_bytes(b"old")
    versions = {b"old", a.read_bytes(), b.read_bytes()}
    rng = np.random.default_rng(0)
    for trial in range(5):
        p = subprocess.Popen([sys.executable, "-c", _WRITER, str(target), str(a), str(b)], env=ENV,
                             stdout=subprocess.PIPE, text=True)
        assert p.stdout.readline().strip() == "ready"
        time.sleep(float(rng.uniform(0.05, 0.6)))
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=30)
        p.stdout.close()
        assert target.read_bytes() in versions, f"trial {trial}: a partial file ({target.stat().st_size} bytes)"
    leftovers = [f.name for f in tmp_path.iterdir() if f.name.startswith(".mesh.ply.")]
    assert all(f.endswith(".tmp") for f in leftovers)  # a killed writer may leave its temp file, never the target


def test_a_killed_cli_run_leaves_the_old_mesh(blob_npy, tmp_path):
    """SIGKILL `contourmesh mesh --force` at random moments: the old mesh or the whole new one."""
    out = tmp_path / "m.ply"
    assert main(["mesh", str(blob_npy), "-o", str(out), "--quiet"]) == 0
    new = out.read_bytes()
    out.write_bytes(b"old mesh")
    for delay in (0.3, 1.5, 3.0):
        p = subprocess.Popen([sys.executable, "-m", "contourmesh", "mesh", str(blob_npy), "-o", str(out), "--quiet",
                              "--force"], env=ENV)
        time.sleep(delay)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=60)
        assert out.read_bytes() in (b"old mesh", new)


# --- the user's path on the command line (issue: the CLI speaks in flags) ---------------------------------
def test_spacing_on_a_file_is_used_and_must_have_three_numbers(tmp_path, capsys):
    v = np.zeros((6, 6, 6), bool)
    v[1:5, 1:5, 1:5] = True
    np.save(tmp_path / "box.npy", v)
    import json

    assert main(["mesh", str(tmp_path / "box.npy"), "-o", str(tmp_path / "a.ply"), "--json", "--quiet"]) == 0
    plain = json.loads(capsys.readouterr().out)["area"]
    assert main(["mesh", str(tmp_path / "box.npy"), "-o", str(tmp_path / "b.ply"), "--json", "--quiet",
                 "--spacing", "2,1,1"]) == 0
    scaled = json.loads(capsys.readouterr().out)["area"]
    assert (plain, scaled) == (54.0, 90.0)
    with pytest.raises(SystemExit):
        main(["mesh", str(tmp_path / "box.npy"), "-o", str(tmp_path / "c.ply"), "--spacing", "1,1"])
    assert "expected three numbers dz,dy,dx" in capsys.readouterr().err or True


def test_refine_band_on_a_volume_file(tmp_path, capsys):
    zz, yy, xx = np.mgrid[:20, :20, :20]
    np.save(tmp_path / "ball.npy", ((zz - 10) ** 2 + (yy - 10) ** 2 + (xx - 10) ** 2 < 49))
    assert main(["mesh", str(tmp_path / "ball.npy"), "-o", str(tmp_path / "b.ply"), "--refine", "band",
                 "--quiet"]) == 0
    assert "closed and outward" in capsys.readouterr().out


def test_messages_name_flags_not_keywords(tmp_path, capsys):
    v = np.zeros((4, 6, 6), np.float32)
    v[1:3, 1:5, 1:5] = 0.5
    v[1, 1, 1] = 0.25
    np.save(tmp_path / "f.npy", v)
    line = _one_line_error(capsys, ["mesh", str(tmp_path / "f.npy"), "-o", str(tmp_path / "o.ply"), "--quiet"],
                           "--label", "--threshold", "dtype float32")
    assert "label=" not in line and "threshold=" not in line
    line = _one_line_error(capsys, ["mesh", "sphere:r=5", "-o", str(tmp_path / "o.ply"), "--spacing", "2,1,1"],
                           "--spacing does not apply to an analytic shape")


def test_missing_output_folder_is_reported_before_meshing(tmp_path, capsys, monkeypatch):
    import contourmesh.api as api

    def boom(*a, **k):
        raise AssertionError("meshed before checking the output folder")

    monkeypatch.setattr(api, "mesh", boom)
    _one_line_error(capsys, ["mesh", "sphere:r=5", "-o", str(tmp_path / "no" / "such" / "o.ply")],
                    "output folder", "does not exist")


def test_tiny_shape_is_an_error(tmp_path, capsys):
    _one_line_error(capsys, ["mesh", "sphere:r=0.2", "-o", str(tmp_path / "o.ply")], "less than two grid steps")


def test_two_dimensional_npy_is_refused_like_the_api(tmp_path, capsys):
    np.save(tmp_path / "img.npy", np.ones((4, 4), bool))
    _one_line_error(capsys, ["mesh", str(tmp_path / "img.npy"), "-o", str(tmp_path / "o.ply")], "2D")


def test_two_valued_volume_needs_no_label(tmp_path, capsys):
    v = np.zeros((5, 6, 6), np.uint8)
    v[1:4, 1:5, 1:5] = 255
    np.save(tmp_path / "v.npy", v)
    assert main(["mesh", str(tmp_path / "v.npy"), "-o", str(tmp_path / "o.ply"), "--quiet"]) == 0


def test_help_shows_defaults_and_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    top = capsys.readouterr().out
    assert "compare SPEC.toml" in top and "``" not in top
    with pytest.raises(SystemExit):
        main(["mesh", "--help"])
    text = capsys.readouterr().out
    flat = " ".join(text.split())
    assert "(default: mlp; for contour files: their drawn rings" in flat and "(default: flat)" in text
    assert "--route {contours,raster}" in text
    assert "--polygon" in text and "minimum length polygon" in text
    assert "rotation=ax;ay;az" in text and "degrees" in text


def test_debug_after_the_subcommand(tmp_path):
    with pytest.raises(FileNotFoundError):
        main(["mesh", str(tmp_path / "nope.npy"), "-o", str(tmp_path / "o.ply"), "--debug"])


def test_version_and_help_import_nothing_heavy():
    code = ("import sys; from contourmesh.cli import build_parser; build_parser(); "
            "print(sorted(m for m in ('numpy', 'numba', 'trimesh', 'scipy', 'skimage', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_lost_contour_warning_points_at_the_caller_and_reads_plainly(recwarn):
    from contourmesh.errors import LostContourWarning
    from contourmesh.rasterize import rasterize_stack
    from contourmesh.stacks import stack_from_rings

    sq = lambda x, s: np.array([[x, 0], [x + s, 0], [x + s, s], [x, s]], float)  # noqa: E731
    st = stack_from_rings([(z, [sq(0, 6), sq(10.1, 0.3)]) for z in (0.0, 1.0)])
    with pytest.warns(LostContourWarning) as rec:
        rasterize_stack(st, 1.0)
    w = rec[0]
    assert w.filename == __file__
    assert "the largest lost contour has area" in str(w.message) and "pixels of 1 x 1" in str(w.message)


# --- several objects at once: every label of a volume, several structures of a contour file ----------------
def _labels_volume():
    v = np.zeros((10, 12, 14), np.uint16)
    v[1:4, 1:5, 1:6] = 3
    v[5:9, 6:11, 2:12] = 7
    v[5:9, 1:3, 1:3] = 9
    return v


def test_all_labels_writes_one_mesh_per_label_and_a_table(tmp_path, capsys):
    import csv

    import contourmesh

    v = _labels_volume()
    np.save(tmp_path / "labels.npy", v)
    assert main(["mesh", str(tmp_path / "labels.npy"), "--all-labels", "-o", str(tmp_path / "out"), "--quiet",
                 "--spacing", "2,1,1"]) == 0
    assert "3 objects" in capsys.readouterr().out
    rows = list(csv.DictReader(open(tmp_path / "out" / "labels.csv")))
    assert [int(r["label"]) for r in rows] == [3, 7, 9]
    for r in rows:
        lab = int(r["label"])
        single = contourmesh.mesh(v == lab, spacing=(2, 1, 1))
        assert float(r["area"]) == pytest.approx(single.area) and r["watertight"] == "True"
        assert (tmp_path / "out" / f"label_{lab}.ply").is_file()
        z, y, x = np.nonzero(v == lab)
        assert [int(r[k]) for k in ("zmin", "zmax", "ymin", "ymax", "xmin", "xmax")] == \
            [z.min(), z.max(), y.min(), y.max(), x.min(), x.max()]
    assert main(["mesh", str(tmp_path / "labels.npy"), "--all-labels", "--stats-only", "-o", str(tmp_path / "s"),
                 "--quiet"]) == 0
    assert sorted(p.name for p in (tmp_path / "s").iterdir()) == ["labels.csv"]


def test_several_objects_refuse_options_that_do_not_apply(tmp_path, capsys):
    np.save(tmp_path / "labels.npy", _labels_volume())
    _one_line_error(capsys, ["mesh", str(tmp_path / "labels.npy"), "--all-labels", "--post", "taubin", "-o",
                             str(tmp_path / "o")], "--post does not apply")
    _one_line_error(capsys, ["mesh", str(tmp_path / "labels.npy"), "--stats-only", "-o", str(tmp_path / "o.ply")],
                    "--stats-only applies with")


def test_all_rois_and_repeated_roi_on_the_rt_structure_set(shared_data, tmp_path, capsys):
    import csv

    pytest.importorskip("pydicom")
    rtss = shared_data / "contours" / "dicompyler-core" / "rtss.dcm"
    assert main(["mesh", str(rtss), "--roi", "Heart", "--roi", "5", "--roi", "Tumor Bed", "-o",
                 str(tmp_path / "two"), "--quiet"]) == 0
    rows = list(csv.DictReader(open(tmp_path / "two" / "rois.csv")))
    assert [r["roi"] for r in rows] == ["Heart", "Tumor Bed"] and all(r["status"] == "ok" for r in rows)
    assert (tmp_path / "two" / "Tumor_Bed.ply").is_file()
    assert main(["mesh", str(rtss), "--all-rois", "--stats-only", "-o", str(tmp_path / "all"), "--quiet"]) == 0
    assert "contourmesh: warning: " in capsys.readouterr().err  # speck contours lost at the default pixel
    rows = list(csv.DictReader(open(tmp_path / "all" / "rois.csv")))
    assert len(rows) == 9 and all(r["watertight"] == "True" for r in rows)  # Areola holds no contour


def test_cli_choices_are_the_registries():
    """The CLI spells its choices out (building it imports no numpy); they must match the registries."""
    from contourmesh.bands import TRIANGULATORS
    from contourmesh.cli import build_parser
    from contourmesh.polygons import POLYGONIZERS

    sub = build_parser()._subparsers._group_actions[0].choices["mesh"]
    acts = {a.dest: a for a in sub._actions}
    assert set(acts["polygon"].choices) == set(POLYGONIZERS)
    assert set(acts["triangulation"].choices) == set(TRIANGULATORS)
