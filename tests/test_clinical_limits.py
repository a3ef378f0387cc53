"""What a drawing cannot tell (issue 15): solids whose contour stacks are the same but whose truths differ.

A contouring tool draws a section on every plane ``z0 + k dz`` that cuts the object, so a flat end
parallel to the planes can lie anywhere between its last section and the next (empty) plane.
:func:`contourmesh.compare.phantoms.consistent_truths` gives the range of volumes and areas over the
solids of a phantom's kind that share its drawing; these tests draw such solids with the project's
phantom code and check that the drawings are the same (so every mesher returns one figure for all
of them) while their truths differ by more than the target window.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

import contourmesh
from contourmesh.compare import phantoms as P

TARGET_VOL = 0.01


def _row(name, dz):
    """The verification set's (phantom, dz, ds, seed) for one drawing of the default subsample."""
    return next(t for t in P.verification_set() if t[0].name == name and t[1] == dz)


def _draw_on(ph, box_of, dz, ds, seed, z0):
    """Draw ``ph`` on the raster of the union of the boxes of ``box_of`` (the in-plane raster the
    sections are traced on starts at the box's corner) with its first plane at ``z0`` (mod dz)."""
    lo = np.min([b.lo for b in box_of], axis=0)
    hi = np.max([b.hi for b in box_of], axis=0)
    boxed = dataclasses.replace(ph, lo=lo, hi=hi)
    return P.draw(boxed, dz, ds, seed=seed, offset=((z0 - lo[2]) / dz) % 1.0)


def _same_drawing(a, b, atol=1e-9):
    if len(a.sections) != len(b.sections):
        return False
    for sa, sb in zip(a.sections, b.sections):
        if abs(sa.z - sb.z) > atol or len(sa.contours) != len(sb.contours):
            return False
        for ra, rb in zip(sa.contours, sb.contours):
            ra, rb = np.asarray(ra, float), np.asarray(rb, float)
            if ra.shape != rb.shape or not np.allclose(ra, rb, rtol=0, atol=atol):
                return False
    return True


def test_two_cylinders_of_different_lengths_give_one_drawing():
    ph, dz, ds, seed = _row("cyl-r5-L20", 3.0)  # the verification set's drawing: 6 circles 3 mm apart
    z0 = P.first_plane(ph, dz, seed=seed)
    short = P.cylinder(5, 18)  # same axis and radius, each end 1 mm further in
    a = _draw_on(ph, (ph, short), dz, ds, seed, z0)
    b = _draw_on(short, (ph, short), dz, ds, seed, z0)
    assert len(a.sections) == 6
    assert _same_drawing(a, b), "the two cylinders' drawings differ"
    # the drawing is the verification set's own (drawn on its own box: same planes, same circles)
    own = P.draw(ph, dz, ds, seed=seed)
    assert [s.z for s in own.sections] == pytest.approx([s.z for s in a.sections], abs=1e-9)
    assert P.section_areas(own) == pytest.approx(P.section_areas(a), rel=1e-6)
    # their volumes are further apart than any one figure can be within 1 % of both
    assert ph.volume / short.volume > (1 + TARGET_VOL) / (1 - TARGET_VOL)
    assert ph.volume / short.volume - 1 > 0.02
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        va = contourmesh.mesh(a, caps="smooth", route="contours", bands="curved").volume
        vb = contourmesh.mesh(b, caps="smooth", route="contours", bands="curved").volume
    assert va == pytest.approx(vb, rel=1e-12)
    within = [abs(va / truth - 1) <= TARGET_VOL for truth in (ph.volume, short.volume)]
    assert sum(within) <= 1


#: Verification drawings with an end parallel to the planes (the band of consistent truths is wide)
#: and the half-width of that band in volume (the least worst-case error any estimator can promise).
FREE = [("cyl-r5-L20", 3.0, 0.167), ("cyl-r15-L40", 2.0, 0.05), ("frustum-r10-0-h20", 2.0, 0.145),
        ("frustum-r15-5-h30", 3.0, 0.115)]


@pytest.mark.parametrize("name,dz,half_width", FREE)
def test_consistent_truths_are_the_drawings_own(name, dz, half_width):
    """Solids with their ends inside the ranges given by consistent_truths draw the same stack; an
    end moved a tenth of a spacing beyond a range changes the drawing.

    The ends are kept 20 % of their range (0.3 mm or more here) from the last drawn section: the
    phantom generator traces sections on a 0.25 mm raster of the implicit function, and within a
    raster step of a flat end the raster's values inside the section are the end's, which moves
    the traced boundary by about 0.01 mm (a limit of the generator, not of the information).
    """
    ph, _, ds, seed = _row(name, dz)
    z0 = P.first_plane(ph, dz, seed=seed)
    band = P.consistent_truths(ph, dz, z0)
    (b_in, b_out), (t_in, t_out) = band["ends"]
    assert not band["fixed"]
    lo, hi = band["volume"]
    a_lo, a_hi = band["area"]
    assert lo < ph.volume < hi and a_lo < ph.area < a_hi
    assert (hi - lo) / (hi + lo) == pytest.approx(half_width, abs=0.002)
    # the band's ends are the truths of the solids with their ends at the ranges' ends
    assert P.with_ends(ph, b_in, t_in).volume == pytest.approx(lo, rel=1e-12)
    assert P.with_ends(ph, b_out, t_out).area == pytest.approx(a_hi, rel=1e-12)

    def place(fb, ft):
        return P.with_ends(ph, b_in + fb * (b_out - b_in), t_in + ft * (t_out - t_in))

    small, large = place(0.2, 0.2), place(0.97, 0.97)
    assert lo < small.volume < large.volume < hi and a_lo < small.area < large.area < a_hi
    assert large.volume / small.volume > (1 + TARGET_VOL) / (1 - TARGET_VOL)
    boxes = (ph, small, large)
    ref = _draw_on(ph, boxes, dz, ds, seed, z0)
    for other in (small, large):
        assert _same_drawing(ref, _draw_on(other, boxes, dz, ds, seed, z0))
    # beyond the range: a section more (outward) or a section less (inward)
    step = 0.1 * dz
    r2 = ph.params.get("r2", 1.0)
    if r2 > 0:  # a flat top (a cone's apex cannot move outward)
        longer = P.with_ends(ph, -ph.params.get("L", ph.params.get("h")) / 2, t_out + step)
        assert len(_draw_on(longer, (ph, longer), dz, ds, seed, z0).sections) == len(ref.sections) + 1
    shorter = P.with_ends(ph, b_in + step, ph.params.get("L", ph.params.get("h")) / 2)
    assert len(_draw_on(shorter, (ph, shorter), dz, ds, seed, z0).sections) == len(ref.sections) - 1


def test_slanted_ends_are_fixed_by_their_traces():
    """A tilted cylinder's end disc spans more than a spacing in height: a plane cuts it, and moving
    the end changes that section, so the drawing tells where the end is."""
    ph, dz, ds, seed = _row("cyl-r5-L20-t30", 3.0)
    assert 2 * 5 * math.sin(math.radians(30)) > dz
    z0 = P.first_plane(ph, dz, seed=seed)
    band = P.consistent_truths(ph, dz, z0)
    assert band["fixed"] and band["volume"] == pytest.approx((ph.volume, ph.volume), rel=1e-12)
    moved = P.with_ends(ph, -10.0, 10.2)
    boxes = (ph, moved)
    a = P.section_areas(_draw_on(ph, boxes, dz, ds, seed, z0))
    b = P.section_areas(_draw_on(moved, boxes, dz, ds, seed, z0))
    assert len(a) != len(b) or np.max(np.abs(a / b - 1)) > 1e-3


def test_spheres_are_fixed_and_other_kinds_refused():
    ph, dz, _, seed = _row("sphere-r5", 3.0)
    band = P.consistent_truths(ph, dz, P.first_plane(ph, dz, seed=seed))
    assert band["fixed"] and band["volume"] == (ph.volume, ph.volume)
    with pytest.raises(ValueError, match="not a sphere, cylinder or frustum"):
        P.consistent_truths(P.torus(15, 5), 1.0, 0.0)
    with pytest.raises(ValueError, match="t_bottom < t_top"):
        P.with_ends(P.cylinder(5, 20), 3.0, 1.0)


def test_first_plane_is_the_drawings():
    ph, dz, ds, seed = _row("cyl-r5-L20", 1.0)
    z0 = P.first_plane(ph, dz, seed=seed)
    zs = [s.z for s in P.draw(ph, dz, ds, seed=seed).sections]
    k = np.round((np.array(zs) - z0) / dz)
    assert np.allclose(z0 + k * dz, zs, atol=1e-9) and z0 <= zs[0] < z0 + dz


def _run_module():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "comparisons" / "clinical" / "run.py"
    spec = importlib.util.spec_from_file_location("clinical_run_limits", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_comparisons_limits_section():
    """run.py's section: a figure at the band's centre is within the window against it though 10 %
    off the analytic value; a figure at the band's lower edge is inside the band, not near its centre."""
    mod = _run_module()
    ph, dz, ds, seed = _row("cyl-r5-L20", 3.0)
    band = P.consistent_truths(ph, dz, P.first_plane(ph, dz, seed=seed))
    (vlo, vhi), (alo, ahi) = band["volume"], band["area"]
    base = {"phantom": ph.name, "kind": "analytic", "dz": dz, "ds": ds, "seed": seed, "status": "ok",
            "method": "ours", "sections": 6}
    rows = [dict(base, caps="smooth", polygon="curved", volume=(vlo + vhi) / 2, area=(alo + ahi) / 2),
            dict(base, caps="flat", polygon="default", volume=vlo, area=alo)]
    md = mod.limits_md(rows)
    assert md.startswith("\n" + mod.LIMITS_HEAD)
    assert "| smooth + curved | 0/1 | 1/1 | 1/1 | 0/1 | 1/1 | 1/1 |" in md
    assert "| flat (default) | 0/1 | 0/1 | 1/1 | 0/1 | 0/1 | 1/1 |" in md
    assert "| cyl-r5-L20 dz=3 ds=0.5 | 6 | -25.00 .. +5.00 | -20.00 .. +4.00 | 16.67 / 13.04 |" in md
    # splicing replaces the section in place, or inserts it before the branching section
    doc = "# t\n\n## Analytic\n\nx\n\n## Branching, keyhole\n\ny\n"
    once = mod.splice_limits(doc, md)
    assert once.index(mod.LIMITS_HEAD) < once.index("## Branching") and once.count(mod.LIMITS_HEAD) == 1
    assert mod.splice_limits(once, md) == once
