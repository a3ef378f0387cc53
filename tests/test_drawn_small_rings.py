"""Issue 15: drawn rings that hold no pixel centre of the contours route's raster (slivers, specks,
vessel holes of a square millimetre) are meshed as drawn, not dropped; the few that still cannot be
kept (an island in a hole, a speck against another ring) are named in a LostContourWarning."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import contourmesh
from contourmesh.compare.clinical import _section_area
from contourmesh.errors import LostContourWarning, RasterFallbackWarning
from contourmesh.geometry import shoelace_area
from contourmesh.stacks import stack_from_rings

DZ = 2.0


def circle(cx, cy, r, n=48):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]


def box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


# at pixel=1 the pixel centres are the integer points: none of these holds one
SLIVER = box(12.05, -3.0, 12.35, 3.0)  # 0.3 x 6, beside the large ring
SPECK = np.array([[25.1, 0.1], [25.6, 0.15], [25.3, 0.6]])  # a triangle of 0.12


def mesh(st, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = contourmesh.mesh(st, pixel=1.0, **kw)
    return m, caught


def assert_sound(m):
    chk = m.checks()
    assert chk["watertight"] and chk["winding_consistent"] and chk["degenerate_faces"] == 0, chk
    assert chk["self_intersections"] == 0, chk
    assert chk["volume"] > 0
    return chk


def parts(m):
    """The mesh's connected pieces: ``(faces' triangles, signed volume)`` each."""
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    e = np.r_[F[:, [0, 1]], F[:, [1, 2]]]
    n, lab = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(V),) * 2), directed=False)
    out = []
    for c in range(n):
        tri = V[F[lab[F[:, 0]] == c]]
        if len(tri):
            out.append((tri, float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6)))
    return out


def xsec(tri, z):
    return _section_area(tri, np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), z)


def near(tri, ring):
    """Whether the triangles lie over the ring's box (a pixel of margin)."""
    c = tri[:, :, :2].reshape(-1, 2).mean(0)
    return bool(np.all(c >= ring.min(0) - 1) and np.all(c <= ring.max(0) + 1))


def plane_gaps(m, st, eps=1e-6):
    """Per contour plane: the mesh's section just below and just above it minus the drawn even-odd area."""
    from contourmesh.compare.phantoms import section_areas

    tri = np.asarray(m.vertices)[np.asarray(m.faces)]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    zs, ref = st.z, section_areas(st)
    out = []
    for k, z in enumerate(zs):
        sides = ([z - eps] if k > 0 else []) + ([z + eps] if k < len(zs) - 1 else [])
        out.append([_section_area(tri, nrm, h) - ref[k] for h in sides])
    return out


def small_ring_stack(small=True):
    """A large ring on sections 0-4 ending in a speck on section 5 (a section of its own speck only); a
    sliver beside it on section 2; a column at x=25 whose two end sections are specks."""
    secs = []
    for k in range(6):
        rs = [circle(0, 0, 8)] if k < 5 else []
        if k == 5 and small:
            rs.append(SPECK - (25, 0))  # the large column's end: a speck over its middle
        if k == 2 and small:
            rs.append(SLIVER)
        if k in (2, 3):
            rs.append(circle(25, 0, 3, 32))
        if k in (1, 4) and small:
            rs.append(SPECK)
        secs.append((DZ * k, rs))
    return stack_from_rings(secs, meta={"roi": "specks"})


@pytest.mark.parametrize("opts", [{}, {"caps": "smooth"}, {"caps": "smooth", "bands": "curved"}])
def test_rings_below_a_pixel_are_meshed_as_drawn(opts):
    st = small_ring_stack()
    m, caught = mesh(st, **opts)
    assert not [w for w in caught if issubclass(w.category, (LostContourWarning, RasterFallbackWarning))], \
        [str(w.message) for w in caught]
    assert m.meta["route"] == "contours" and m.meta["kept_small_rings"] == 4 and m.meta["lost_rings"] == 0
    assert m.meta["unmatched_components"] == 0
    chk = assert_sound(m)
    assert chk["components"] == 3 and chk["genus"] == 0
    # every contour plane's mesh section is the drawn section, specks and sliver included
    for k, gaps in enumerate(plane_gaps(m, st)):
        assert np.allclose(gaps, 0, atol=2e-3), (k, gaps)
    # the sliver is its own piece, a slab of its drawn ring (not of the seven pixels it was given)
    (tri, vol), = [(t, v) for t, v in parts(m) if near(t, SLIVER)]
    a = shoelace_area(SLIVER)
    for h in (2 * DZ - 1e-6, 2 * DZ + 1e-6):
        assert xsec(tri, h) == pytest.approx(a, rel=1e-9)
    np.testing.assert_allclose(tri[:, :, :2].reshape(-1, 2).min(0), SLIVER.min(0), atol=1e-12)
    np.testing.assert_allclose(tri[:, :, :2].reshape(-1, 2).max(0), SLIVER.max(0), atol=1e-12)
    assert vol == pytest.approx(a * DZ, rel=1e-9)  # a single-section ring is a slab one spacing thick
    # the speck-ended column: its specks are in the mesh at their planes
    (tri, vol), = [(t, v) for t, v in parts(m) if near(t, circle(25, 0, 3))]
    for k in (1, 4):
        assert xsec(tri, DZ * k + (1e-6 if k == 1 else -1e-6)) == pytest.approx(abs(shoelace_area(SPECK)), abs=1e-4)


def rules(areas, dz):
    """The frustum and trapezoid rules' volumes over a run of section areas ``dz`` apart."""
    a = np.asarray(areas, dtype=float)
    return (float(np.sum(dz / 3 * (a[1:] + a[:-1] + np.sqrt(a[1:] * a[:-1])))),
            float(np.sum(dz / 2 * (a[1:] + a[:-1]))))


def test_each_piece_holds_the_volume_its_drawn_rings_imply():
    m, _ = mesh(small_ring_stack())
    big, col, speck = (abs(shoelace_area(r)) for r in (circle(0, 0, 8), circle(25, 0, 3, 32), SPECK))
    pieces = parts(m)
    assert len(pieces) == 3
    for tri, vol in pieces:
        if near(tri, SLIVER):
            lo = hi = shoelace_area(SLIVER) * DZ
        elif near(tri, circle(25, 0, 3)):  # speck, circle, circle, speck: bands between them
            lo, hi = rules([speck, col, col, speck], DZ)
        else:  # the large ring on five sections, then the speck that ends it: a cone on the last band
            lo, hi = rules([big] * 5 + [speck], DZ)
        assert lo * (1 - 1e-9) <= vol <= hi * (1 + 1e-9), (vol, lo, hi)


def test_a_vessel_hole_below_a_pixel_keeps_its_tunnel():
    """A hole through every section (a vessel), a speck on the middle one: the tunnel goes through
    (genus 1); dropping the speck would make two blind pits (genus 0)."""
    hole = lambda s: box(-s, -s, s, s)[::-1] + 0.5  # noqa: E731 - centred between pixel centres
    secs = [(DZ * k, [circle(0, 0, 8), hole(0.3 if k == 2 else 1.2)]) for k in range(5)]
    st = stack_from_rings(secs, meta={"roi": "vessel"})
    m, caught = mesh(st)
    assert not [w for w in caught if issubclass(w.category, (LostContourWarning, RasterFallbackWarning))]
    assert m.meta["kept_small_rings"] == 1 and m.meta["lost_rings"] == 0
    chk = assert_sound(m)
    assert chk["components"] == 1 and chk["genus"] == 1
    for k, gaps in enumerate(plane_gaps(m, st)):
        assert np.allclose(gaps, 0, atol=2e-3), (k, gaps)


def test_a_cavity_below_a_pixel_is_cut_out():
    secs = [(DZ * k, [circle(0, 0, 8)] + ([box(0.1, 0.1, 0.4, 0.4)[::-1]] if k == 2 else [])) for k in range(5)]
    m, caught = mesh(stack_from_rings(secs, meta={"roi": "cavity"}))
    full, _ = mesh(stack_from_rings([(DZ * k, [circle(0, 0, 8)]) for k in range(5)]))
    assert not [w for w in caught if issubclass(w.category, LostContourWarning)]
    assert m.meta["kept_small_rings"] == 1
    chk = assert_sound(m)
    assert chk["components"] == 2  # the void is a surface of its own, wound inwards
    assert full.volume - m.volume == pytest.approx(0.09 * DZ, rel=1e-9)


def test_rings_that_still_cannot_be_kept_are_named():
    big = circle(0, 0, 8)
    island = box(0.1, 0.1, 0.4, 0.4)  # inside a hole of radius 4
    against = box(8.1, 3.1, 8.4, 3.4)  # outside the circle, but its pixel (8, 3) touches the circle's (7, 3)
    secs = [(DZ * k, [big] if k != 2 else [big, circle(0, 0, 4)[::-1], island, against, SLIVER]) for k in range(5)]
    m, caught = mesh(stack_from_rings(secs, meta={"roi": "Specks"}))
    lost = [str(w.message) for w in caught if issubclass(w.category, LostContourWarning)]
    assert len(lost) == 1 and lost[0].startswith("Specks: 2 drawn ring(s)"), lost
    assert "section 2 (z=4) ring 2 (it lies inside another drawn ring)" in lost[0]
    assert "section 2 (z=4) ring 3 (its pixels would touch another ring's)" in lost[0]
    assert m.meta["lost_rings"] == 2 and m.meta["kept_small_rings"] == 1  # the sliver
    assert_sound(m)


@pytest.mark.parametrize("what", ["speck", "hole"])
def test_small_rings_that_would_make_a_handle_stay_out(what):
    """A speck beside a column that narrows on its section, inside the column's pixels above and below,
    or a hole a pixel from the outside above and below: given pixels, either would join what is
    already joined (a handle the drawing does not show), so it is named and left out."""
    if what == "speck":
        mid = [circle(0, 0, 6), box(7.6, 0.1, 7.9, 0.4)]
        wide = circle(0, 0, 8)
    else:
        mid = [circle(0, 0, 9.5, 64), box(7.1, 0.1, 7.4, 0.4)[::-1]]
        wide = circle(0, 0, 8)
    st = stack_from_rings([(DZ * k, mid if k == 2 else [wide]) for k in range(5)], meta={"roi": what})
    m, caught = mesh(st)
    lost = [str(w.message) for w in caught if issubclass(w.category, LostContourWarning)]
    assert len(lost) == 1 and "section 2 (z=4) ring 1" in lost[0] and "(a handle)" in lost[0], lost
    assert m.meta["lost_rings"] == 1 and m.meta["kept_small_rings"] == 0
    chk = assert_sound(m)
    assert chk["genus"] == 0 and chk["components"] == 1
    # kept where it makes no handle: the speck on the last section (nothing above it), the hole where
    # the column is as wide above and below
    secs = [(DZ * k, mid if k == 2 else [wide]) for k in range(3)] if what == "speck" else \
        [(DZ * k, mid if k == 2 else [mid[0]]) for k in range(5)]
    st = stack_from_rings(secs, meta={"roi": what})
    m, caught = mesh(st)
    assert m.meta["kept_small_rings"] == 1 and m.meta["lost_rings"] == 0
    assert assert_sound(m)["genus"] == 0


@pytest.mark.parametrize("what", ["speck", "hole"])
def test_small_rings_that_would_branch_off_another_column_stay_out(what):
    """A speck whose pixel lies in the wider ring above, beside the ring that ring continues into, or
    a hole whose pixel lies in a larger hole above that also continues into another hole: kept, it
    would be a branch of a fork, whose bridged join moves the larger ring's volume by far more than
    the small ring holds; it is named and left out."""
    if what == "speck":
        narrow, wide = [circle(0, 0, 6), box(7.6, 0.1, 7.9, 0.4)], [circle(0, 0, 9)]
        secs = [(DZ * k, narrow if k == 2 else wide if k > 2 else narrow[:1]) for k in range(5)]
    else:
        big = circle(0, 0, 9.5, 64)
        mid = [big, box(-3.2, -0.7, -0.8, 1.7)[::-1], box(1.1, 0.1, 1.4, 0.4)[::-1]]
        above = [big, box(-3.5, -1.5, 2.5, 2.5)[::-1]]
        secs = [(DZ * k, mid if k == 2 else above if k > 2 else [big]) for k in range(5)]
    m, caught = mesh(stack_from_rings(secs, meta={"roi": what}))
    lost = [str(w.message) for w in caught if issubclass(w.category, LostContourWarning)]
    ring = 1 if what == "speck" else 2
    assert len(lost) == 1 and f"section 2 (z=4) ring {ring}" in lost[0] and "(a fork)" in lost[0], lost
    assert m.meta["lost_rings"] == 1 and m.meta["kept_small_rings"] == 0
    assert_sound(m)


def random_specks_stack(seed):
    """Random columns of circles (some sections missing), with specks, slivers and small holes strewn
    over random sections at pixel=1 (none of them need hold a pixel centre)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 8))
    secs = [[] for _ in range(n)]
    for _ in range(int(rng.integers(1, 4))):
        c = rng.uniform(-12, 12, 2)
        k0 = int(rng.integers(0, n - 1))
        k1 = int(rng.integers(k0 + 1, n + 1))
        for k in range(k0, k1):
            r = rng.uniform(2.5, 7.0)
            secs[k].append(circle(*(c + rng.uniform(-1, 1, 2)), r, 40))
            if rng.random() < 0.4:  # a small hole well inside
                h = c + rng.uniform(-0.5 * r, 0.5 * r, 2)
                s = rng.uniform(0.1, 0.6)
                secs[k].append(box(h[0], h[1], h[0] + s, h[1] + s * rng.uniform(0.3, 1))[::-1])
    for _ in range(int(rng.integers(1, 6))):
        k = int(rng.integers(0, n))
        p = rng.uniform(-22, 22, 2)
        if rng.random() < 0.5:  # a speck
            secs[k].append(p + rng.uniform(0, 0.7, (3, 2)))
        else:  # a sliver, along x or y
            w, L = rng.uniform(0.1, 0.4), rng.uniform(1.0, 6.0)
            secs[k].append(box(p[0], p[1], p[0] + w, p[1] + L) if rng.random() < 0.5 else box(p[0], p[1], p[0] + L, p[1] + w))
    dz = float(rng.uniform(1.0, 3.0))
    secs = [(dz * k, rs) for k, rs in enumerate(secs) if rs]
    return stack_from_rings(secs, meta={"roi": f"random{seed}"})


@pytest.mark.parametrize("seed", range(int(os.environ.get("CONTOURMESH_SMALL_RING_SEEDS", "24"))))  # more by hand
def test_random_specks_make_sound_meshes_with_the_decision_rasters_topology(seed):
    from contourmesh.drawn import decision_raster
    from contourmesh.volumes import voxel_topology

    st = random_specks_stack(seed)
    m, caught = mesh(st)
    assert not [w for w in caught if not issubclass(w.category, (LostContourWarning, RasterFallbackWarning))]
    assert m.meta["route"] == "contours"
    chk = assert_sound(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = voxel_topology(decision_raster(st, m.meta["pixel"]).volume)
    assert (chk["components"], chk["genus"]) == (ref["surfaces"], ref["genus"])
    lost = [str(w.message) for w in caught if issubclass(w.category, LostContourWarning)]
    assert bool(lost) == (m.meta["lost_rings"] > 0)
    if not m.meta["unmatched_components"]:  # every ring that is kept is in the mesh as drawn: its points
        V = np.asarray(m.vertices)                # are the mesh's vertices in its plane (up to the crossing
        tol = m.meta.get("crossing_repair_max_move", 0.0) + 1e-12  # repair's nudges)
        for s in st.sections:
            have = V[np.abs(V[:, 2] - s.z) <= tol, :2]
            drawn = [c for c in s.contours
                     if np.linalg.norm(c[:, None] - have[None], axis=2).min(1).max() <= tol]
            assert len(s.contours) - len(drawn) <= m.meta["lost_rings"], (s.z, len(s.contours), len(drawn))
