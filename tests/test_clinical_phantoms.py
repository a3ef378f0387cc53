"""Issue 15 item 5: contour phantoms with exact truths, and the clinical comparison's core function."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from contourmesh.compare import phantoms as P
from contourmesh.compare.clinical import COLUMNS, MODES, PEERS, measure
from contourmesh.geometry import shoelace_area

ROOT = Path(__file__).resolve().parents[1]


def test_closed_forms():
    assert P.sphere(7).area == pytest.approx(4 * math.pi * 49)
    assert P.sphere(7).volume == pytest.approx(4 / 3 * math.pi * 343)
    c = P.cylinder(3, 10, tilt=30)
    assert (c.area, c.volume) == pytest.approx((2 * math.pi * 3 * 13, math.pi * 9 * 10))
    # a frustum with equal radii is a cylinder; with r2 = 0 a cone (lateral pi r s + base)
    f = P.frustum(3, 3, 10)
    assert (f.area, f.volume) == pytest.approx((c.area, c.volume))
    cone = P.frustum(3, 0, 4)
    assert (cone.area, cone.volume) == pytest.approx((math.pi * 3 * 5 + math.pi * 9, math.pi * 9 * 4 / 3))
    t = P.torus(10, 2)
    assert (t.area, t.volume) == pytest.approx((4 * math.pi**2 * 20, 2 * math.pi**2 * 40))
    # two balls just touching: the union is both balls; one far inside the other's cap shrinks both
    touch = P.two_lobes(5, 4, 9 - 1e-9)
    assert touch.volume == pytest.approx(4 / 3 * math.pi * (125 + 64), rel=1e-6)
    assert touch.area == pytest.approx(4 * math.pi * (25 + 16), rel=1e-6)
    with pytest.raises(ValueError, match="overlapping"):
        P.two_lobes(5, 4, 10)


@pytest.mark.parametrize("ph", [P.two_lobes(6, 5, 7), P.rod_in_tube(6, 4, 2, 8, tilt=20), P.hollow_sphere(6, 3)],
                         ids=lambda p: p.name)
def test_closed_forms_match_the_sampled_solid(ph):
    vol, _ = P.implicit_volume(ph, 0.2)
    assert vol.sum() * 0.2**3 == pytest.approx(ph.volume, rel=0.01)


def test_drawn_sphere_rings_are_on_the_surface_evenly_spaced_and_counter_clockwise():
    ph = P.sphere(8)
    st = P.draw(ph, 1.0, 0.5, seed=3)
    assert st.meta["area_true"] == pytest.approx(4 * math.pi * 64)
    zs = np.array([s.z for s in st.sections])
    assert np.allclose(np.diff(zs), 1.0) and -8 < zs[0] < -7 and 7 < zs[-1] < 8
    for s in st.sections:
        (ring,) = s.contours
        assert shoelace_area(ring) > 0  # outer ring counter-clockwise
        rr = np.hypot(ring[:, 0], ring[:, 1])
        assert np.allclose(rr, math.sqrt(64 - s.z**2), atol=1e-7)  # vertices on the true circle
        edges = np.linalg.norm(np.diff(np.vstack([ring, ring[:1]]), axis=0), axis=1)
        if 2 * math.pi * rr[0] > 8 * 0.5:
            assert np.allclose(edges, 0.5, rtol=0.05)
    # the even-odd areas are those of the inscribed (nearly regular) polygons, just under the discs
    a = P.section_areas(st)
    n = np.array([len(s.contours[0]) for s in st.sections])
    polygon = n / 2 * (64 - zs**2) * np.sin(2 * np.pi / n)
    assert a == pytest.approx(polygon, rel=1e-3)
    assert np.all(a < math.pi * (64 - zs**2))
    assert P.frustum_volume(st) <= P.trapezoid_volume(st) < ph.volume


def test_tilted_cylinder_sections_are_ellipses():
    ph = P.cylinder(5, 40, tilt=30)
    st = P.draw(ph, 2.0, 0.2, seed=1)
    mid = st.sections[len(st.sections) // 2]
    assert shoelace_area(mid.contours[0]) == pytest.approx(math.pi * 25 / math.cos(math.radians(30)), rel=2e-3)


def test_nested_and_keyhole_orientation_and_areas():
    st = P.draw(P.rod_in_tube(10, 6, 3, 10), 2.0, 0.5, seed=2)
    s = st.sections[1]
    areas = sorted((shoelace_area(c) for c in s.contours), key=abs)
    # island (+), hole (-), outer (+)
    assert areas == pytest.approx([math.pi * 9, -math.pi * 36, math.pi * 100], rel=5e-3)
    kh = P.draw(P.keyhole_tube(10, 5, 10), 2.0, 0.5, seed=2)
    for s in kh.sections:
        (ring,) = s.contours  # the hole is drawn into the outer ring through a zero-width channel
        assert shoelace_area(ring) == pytest.approx(math.pi * 75, rel=5e-3)
    y = P.draw(P.y_branch(3, 10), 1.0, 0.5, seed=2)
    counts = [len(s.contours) for s in y.sections]
    assert counts[0] == 1 and max(counts) == 2  # the arms fork from the trunk


def test_rtstruct_round_trip(tmp_path):
    pytest.importorskip("pydicom")
    from contourmesh.io import read_contours

    stacks = {"ball": P.draw(P.sphere(4), 1.0, 0.5, seed=1), "pipe": P.draw(P.keyhole_tube(5, 2, 4), 1.0, 0.5, seed=1)}
    p = tmp_path / "ph.dcm"
    p.write_bytes(P.rtstruct_bytes(stacks))
    for name, st in stacks.items():
        back = read_contours(p, roi=name)
        assert [s.z for s in back.sections] == pytest.approx([s.z for s in st.sections], abs=1e-8)
        assert P.section_areas(back) == pytest.approx(P.section_areas(st), rel=1e-8)


@pytest.fixture(scope="module")
def sphere_rows():
    return measure(P.sphere(4), 1.0, 0.5, seed=5, fine=0.25, max_planes=8)


def test_measure_rows_carry_the_truths_and_all_columns(sphere_rows):
    rows = sphere_rows
    assert [r["method"] for r in rows] == ["ours"] * len(MODES) + list(PEERS)
    assert [(r["caps"], r["polygon"]) for r in rows[: len(MODES)]] == list(MODES)
    for r in rows:
        assert set(COLUMNS) <= set(r)
        assert r["status"] == "ok", r["error"]
        assert r["area_true"] == pytest.approx(4 * math.pi * 16)
        assert r["volume_true"] == pytest.approx(4 / 3 * math.pi * 64)
        assert r["truth"] == "analytic"
        assert r["area_err"] == pytest.approx(r["area"] / r["area_true"] - 1)
        assert r["vol_frustum"] <= r["vol_trapezoid"] < r["volume_true"]
        assert abs(r["area_err"]) < 0.25 and abs(r["volume_err"]) < 0.25  # the right object was measured
    for r in rows[: len(MODES)]:
        assert r["closed_ok"] is True
        assert r["xsec_checked"] == 8
        assert r["area_vs_surfacenets"] == pytest.approx(r["area"] / rows[len(MODES)]["area"] - 1)
    # polygon="none" meshes the drawn rings themselves: their cross-sections are the contours
    none_flat = rows[MODES.index(("flat", "none"))]
    assert none_flat["route"] == "stack" and abs(none_flat["xsec_max_err"]) < 1e-3
    # the smooth cap: the half prism's volume, less area (no side wall)
    smooth, half = rows[MODES.index(("smooth", "none"))], rows[MODES.index(("half", "none"))]
    assert smooth["route"] == "stack" and smooth["volume"] == pytest.approx(half["volume"], rel=1e-9)
    assert smooth["area"] < half["area"]


def test_run_script_writes_its_outputs(sphere_rows, tmp_path):
    spec = importlib.util.spec_from_file_location("clinical_run", ROOT / "comparisons" / "clinical" / "run.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.write(sphere_rows, tmp_path, False, 0.25)
    back = mod.read_csv(tmp_path / "results.csv")
    assert len(back) == len(sphere_rows)
    assert back[0]["area_true"] == pytest.approx(4 * math.pi * 16, rel=1e-5)
    md = (tmp_path / "results.md").read_text()
    assert "sphere-r4" in md and "ours caps=half polygon=mlp" in md
    assert (tmp_path / "errors.png").read_bytes()[:4] == b"\x89PNG"
