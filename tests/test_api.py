"""The front door: every source kind x option pair either applies or raises, never silently ignored."""

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import contourmesh
from contourmesh import api
from contourmesh.digitize import outer_jordan_stack
from contourmesh.errors import ContourMeshError, InapplicableOption
from contourmesh.io import write_contours_json
from contourmesh.shapes import Sphere
from contourmesh.stacks import stack_from_rings
from contourmesh.types import ContourStack, Section

ROOT = Path(__file__).resolve().parents[1]


def _box(shape=(6, 6, 6)):
    v = np.zeros(shape, bool)
    v[1:-1, 1:-1, 1:-1] = True
    return v


def _square(x, y, s):
    return np.array([[x, y], [x + s, y], [x + s, y + s], [x, y + s]], float)


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    d = tmp_path_factory.mktemp("sources")
    np.save(d / "box.npy", _box())
    st = stack_from_rings([(z, [_square(0, 0, 6)]) for z in (0.0, 1.0, 2.0)])
    write_contours_json(st, d / "c.json")
    grid = outer_jordan_stack(Sphere(4, center=(0.3, 0.2, 0.1)))
    return {"shape": "sphere:r=4", "stack": grid, "volume": _box(), "volume file": str(d / "box.npy"),
            "contour file": str(d / "c.json")}


VALUES = {"h": 1.0, "pixel": 0.5, "spacing": (1.0, 1.0, 1.0), "z": None, "axis": 0, "label": 1, "threshold": 0.5,
          "origin": (0.0, 0.0, 0.0), "roi": 1}
KINDS = ["shape", "stack", "volume", "volume file", "contour file"]


# roi= on a contour file is exercised on the RTSTRUCT in test_io (a JSON stack holds one structure)
PAIRS = [(k, o) for k, o in itertools.product(KINDS, [k for k in VALUES if k != "z"]) if (k, o) != ("contour file", "roi")]


@pytest.mark.parametrize("kind,key", PAIRS)
def test_every_option_applies_or_raises(sources, kind, key):
    """For each source kind and option: in OPTIONS, it is used (the call works); else InapplicableOption."""
    src = sources[kind]
    applies = key in api.OPTIONS[kind]
    if applies:
        m = contourmesh.mesh(src, **{key: VALUES[key]})
        assert m.checks()["watertight"]
    else:
        with pytest.raises(InapplicableOption, match=f"{key}= does not apply to"):
            contourmesh.mesh(src, **{key: VALUES[key]})


def test_inapplicable_option_is_a_type_error_and_a_value_error():
    assert issubclass(InapplicableOption, TypeError) and issubclass(InapplicableOption, ContourMeshError)
    assert issubclass(ContourMeshError, ValueError)
    with pytest.raises(TypeError, match="use h= for its grid step"):
        contourmesh.mesh("sphere:r=5", spacing=(2, 1, 1))


def test_unknown_keyword_is_a_type_error():
    with pytest.raises(TypeError, match="unexpected keyword spacings="):
        contourmesh.mesh(_box(), spacings=(1, 1, 1))


def test_spacing_of_an_npy_file_is_used(sources):
    """The regression: a 4x4x4 cube read from .npy with spacing=(2, 1, 1) gives the array route's
    area (90), not the unit-spacing one (54)."""
    path = sources["volume file"]
    plain = contourmesh.mesh(path).area
    arr = contourmesh.mesh(_box(), spacing=(2, 1, 1)).area
    assert (plain, arr) == (54.0, 90.0)
    assert contourmesh.mesh(path, spacing=(2, 1, 1)).area == pytest.approx(arr)
    assert arr != pytest.approx(plain)
    assert contourmesh.mesh(path, spacing=(2, 1, 1)).meta["spacing"] == (2.0, 1.0, 1.0)


def test_bad_spacing_on_a_file_is_refused(sources):
    with pytest.raises(ValueError, match="spacing must be three positive"):
        contourmesh.mesh(sources["volume file"], spacing=(1, 1))


@pytest.mark.parametrize("kind", ["volume", "volume file", "shape", "stack"])
def test_refine_band_on_every_single_contour_source(sources, kind):
    m = contourmesh.mesh(sources[kind], refine="band")
    assert m.meta["refine"] == "band" and m.checks()["watertight"] and m.volume > 0


def test_refine_band_on_a_contour_file_refines_its_raster(sources):
    """Drawn rings are refined on their raster (the refinement needs a digital object); pixel=
    sets the raster's size, and the contours route, which meshes the rings as drawn, is refused."""
    from contourmesh.io import read_contours
    from contourmesh.rasterize import rasterize_stack
    from contourmesh.volumes import volume_to_mesh

    m = contourmesh.mesh(sources["contour file"], refine="band", pixel=0.5)
    chk = m.checks()
    assert m.meta["route"] == "raster-refined" and m.meta["refine"] == "band" and m.meta["pixel"] == 0.5
    assert chk["ok"] and chk["self_intersections"] == 0 and m.volume > 0
    r = rasterize_stack(read_contours(sources["contour file"]), 0.5)
    ref = volume_to_mesh(r.volume, **r.mesh_kwargs, triangulation="optimal", refine="band")
    assert m.area == pytest.approx(ref.area, rel=1e-12)
    with pytest.raises(InapplicableOption, match="drawn rings are refined on their raster"):
        contourmesh.mesh(sources["contour file"], refine="band", route="contours")


def test_two_valued_volume_is_binary():
    v = _box().astype(np.uint8) * 255
    assert contourmesh.mesh(v).area == pytest.approx(contourmesh.mesh(_box()).area)
    w = _box().astype(np.uint8) * 96
    w[2, 2, 2] = 3
    with pytest.raises(ValueError, match=r"dtype uint8, from 0 to 96\); pass label="):
        contourmesh.mesh(w)


def test_a_shape_below_the_grid_is_an_error():
    with pytest.raises(ValueError, match="less than two grid steps"):
        contourmesh.mesh("sphere:r=0.2")
    assert contourmesh.mesh("sphere:r=0.2", h=0.05).checks()["watertight"]


def test_two_dimensional_arrays_are_refused_by_api_and_files(tmp_path):
    img = np.ones((4, 4), bool)
    with pytest.raises(ValueError, match="2D .*image\\[None\\]"):
        contourmesh.mesh(img)
    np.save(tmp_path / "img.npy", img)
    with pytest.raises(ValueError, match="2D .*image\\[None\\]"):
        contourmesh.mesh(str(tmp_path / "img.npy"))


def test_section_parents_of_the_wrong_length_raise():
    c = np.array([[0, 0], [2, 0], [2, 2], [0, 2]])
    with pytest.raises(ValueError, match="parents must give one entry per contour"):
        Section(0.0, (c, c[::-1]), (-1,))
    assert Section(0.0, (c,)).parents == (-1,)


def test_import_changes_no_other_library():
    code = ("import trimesh, trimesh.exchange.load as L; before = L.mesh_loaders.get('json'); "
            "import matplotlib; b0 = matplotlib.get_backend(); import contourmesh, numpy as np; "
            "contourmesh.mesh(np.pad(np.ones((2, 2, 2), bool), 1)); import contourmesh.compare.paper, "
            "contourmesh.compare.report; "
            "print(L.mesh_loaders.get('json') is before, matplotlib.get_backend() == b0)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(ROOT / "src"), "MPLBACKEND": "svg", "PATH": "/usr/bin:/bin"})
    assert out.stdout.split() == ["True", "True"], out.stderr


def test_routes_are_recorded(sources):
    assert contourmesh.mesh(sources["shape"]).meta["route"] == "stack"
    assert contourmesh.mesh(sources["volume"]).meta["route"] == "volume"
    assert contourmesh.mesh(sources["contour file"]).meta["route"] in ("stack", "contours")
    assert contourmesh.mesh(sources["stack"], refine="band").meta["route"] == "refined"


def test_fallbacks_are_logged(caplog):
    import logging

    ring = np.array([[0, 5], [0, 0], [10, 0], [10, 10], [0, 10], [0, 5], [3, 5], [3, 7], [7, 7], [7, 3], [3, 3],
                     [3, 5]], float) + 0.25
    st = ContourStack(tuple(Section(float(z), (ring,)) for z in range(3)))
    with caplog.at_level(logging.DEBUG, logger="contourmesh"):
        m = contourmesh.mesh(st, polygon="none")
    assert m.meta["route"] == "contours"
    assert any("re-routing to the contours route" in r.getMessage() for r in caplog.records)


def test_json_summary_speaks_of_the_route(tmp_path, capsys):
    from contourmesh.cli import main

    assert main(["mesh", "sphere:r=6", "-o", str(tmp_path / "s.ply"), "--json", "--quiet"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["route"] == "stack" and s["watertight"]


@pytest.mark.parametrize("module,call", [
    ("nibabel", lambda p: contourmesh.read_volume(p / "x.nii")),
    ("open3d", lambda p: contourmesh.mesh("sphere:r=3").to_open3d()),
    ("pymeshlab", lambda p: contourmesh.mesh("sphere:r=3").to_pymeshlab()),
])
def test_a_missing_optional_package_names_what_to_install(module, call, tmp_path, monkeypatch):
    from contourmesh.errors import MissingDependency

    (tmp_path / "x.nii").write_bytes(b"\0" * 400)
    monkeypatch.setitem(sys.modules, module, None)  # import of it now fails, as if not installed
    with pytest.raises(MissingDependency, match=rf"{module} is not installed: pip install .*contourmesh\["):
        call(tmp_path)


def test_diagnostics_count_axis_walls_and_joins(tmp_path, capsys):
    from contourmesh.cli import main
    from contourmesh.shapes import Ellipsoid, rotation_from_euler

    box = contourmesh.mesh(_box(), polygon="none")
    # flat caps in the end slices' planes: walls 16 x 3 against caps 2 x 16
    assert box.meta["axis_wall_fraction"] == pytest.approx(48 / 80)
    smooth = contourmesh.mesh(Ellipsoid(9, 6, 5, center=(0.3, 0.2, 0.1), rotation=rotation_from_euler(20, 30, 40)))
    assert smooth.meta["axis_wall_fraction"] < box.meta["axis_wall_fraction"]
    v = np.zeros((6, 9, 9), bool)
    v[:3, 3:6, 3:6] = True
    v[3:, 0:3, 0:3] = v[3:, 6:9, 6:9] = True
    v[3, 1:8, 1:8] = True
    np.save(tmp_path / "y.npy", v)
    assert main(["mesh", str(tmp_path / "y.npy"), "-o", str(tmp_path / "y.ply"), "--json", "--quiet"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["exact_joins"] + s["bridged_joins"] >= 1 and 0 < s["axis_wall_fraction"] < 1


#: Five grid contours at uneven heights (found by the soak, seed 15961): the first two sections
#: barely overlap, and every band between them crosses itself with polygon="none".
_CROSSING_GRID_STACK = (
    (0.0078, [[-2, 0], [-2, 1], [-2, 2], [-2, 3], [-1, 3], [-1, 4], [-1, 5], [-1, 6], [0, 6], [1, 6], [1, 7], [2, 7],
              [3, 7], [3, 6], [3, 5], [3, 4], [2, 4], [2, 3], [2, 2], [2, 1], [2, 0], [1, 0], [0, 0], [-1, 0]]),
    (2.6803, [[3, -1], [3, 0], [3, 1], [3, 2], [3, 3], [3, 4], [4, 4], [5, 4], [5, 3], [6, 3], [6, 2], [6, 1], [7, 1],
              [7, 0], [7, -1], [6, -1], [5, -1], [4, -1]]),
    (3.1131, [[0, -1], [0, 0], [0, 1], [-1, 1], [-1, 2], [-1, 3], [-1, 4], [0, 4], [1, 4], [2, 4], [3, 4], [4, 4],
              [5, 4], [5, 3], [5, 2], [4, 2], [4, 1], [4, 0], [3, 0], [3, -1], [2, -1], [1, -1]]),
    (4.9144, [[2, -1], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2], [0, 3], [0, 4], [0, 5], [0, 6], [1, 6], [2, 6], [3, 6],
              [3, 5], [4, 5], [5, 5], [6, 5], [6, 4], [6, 3], [5, 3], [5, 2], [5, 1], [5, 0], [5, -1], [4, -1],
              [3, -1]]),
    (7.1731, [[2, -2], [2, -1], [1, -1], [0, -1], [0, 0], [0, 1], [0, 2], [1, 2], [1, 3], [1, 4], [2, 4], [3, 4],
              [4, 4], [4, 3], [5, 3], [5, 2], [6, 2], [6, 1], [6, 0], [6, -1], [5, -1], [5, -2], [4, -2], [3, -2]]),
)


def test_grid_stack_whose_bands_cross_goes_to_the_volume_mesher_with_a_warning():
    from contourmesh.errors import RasterFallbackWarning, SelfIntersectionWarning
    from contourmesh.refine import stack_points
    from contourmesh.volumes import voxel_topology

    st = ContourStack(tuple(Section(z, (np.array(c, dtype=np.int64),)) for z, c in _CROSSING_GRID_STACK))
    with pytest.warns(RasterFallbackWarning, match="crossing faces"):
        m = contourmesh.mesh(st, polygon="none", triangulation="arclength")
    chk = m.checks()
    assert m.meta["route"] == "volume" and "crossing faces" in m.meta["stack_route_error"]
    assert chk["ok"] and chk["self_intersections"] == 0 and chk["volume"] > 0
    topo = voxel_topology(stack_points(st, lattice=False)[0])
    assert chk["components"] == topo["components"] and chk["genus"] == topo["genus"]
    z = np.unique(m.vertices[:, 2])
    assert np.all(np.isin([s.z for s in st.sections], z))  # every section at its own height
    # the stack route itself, asked directly, keeps its mesh and says that faces cross
    with pytest.warns(SelfIntersectionWarning):
        direct = contourmesh.surface.stack_to_mesh(st, polygon="none", triangulation="arclength")
    assert direct.meta["self_intersections"] > 0 and not direct.checks()["ok"]
    # smooth ends exist only on the stack route: there the crossing is warned about, not rerouted
    with pytest.warns(SelfIntersectionWarning):
        smooth = contourmesh.mesh(st, polygon="none", triangulation="arclength", caps="smooth")
    assert smooth.meta["route"] == "stack"
