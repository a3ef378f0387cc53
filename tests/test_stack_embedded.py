"""Issue 13 on the contour-stack route: no crossing faces, repaired locally and counted, never silent.

The stack mesher guards every band (the first triangulation whose own faces keep clear), rebuilds
the bands of faces that still cross with their next triangulation, then meshes their sections
from the contours, pulls faces apart that a hair separates, and warns
(:class:`~contourmesh.errors.SelfIntersectionWarning`) or raises
(:class:`~contourmesh.errors.CrossingFacesError`) about what is left.  The front door reroutes
drawn rings and refined stacks on such an error.  Real-data tests: every small shared sample in
every mode (``polygon x triangulation x refine``), and every ROI of the RT structure set.
"""

import warnings

import numpy as np
import pytest

import contourmesh
import soak
from contourmesh.errors import CrossingFacesError, SelfIntersectionWarning
from contourmesh.surface import stack_to_mesh
from contourmesh.types import ContourStack, Section


def _scan_stack(seed, kind):
    """The stack, combo and caps that ``seed`` draws in the order of the stack scans of issue 13."""
    rng = np.random.default_rng(seed)
    combo = soak.COMBOS[int(rng.integers(len(soak.COMBOS)))]
    caps = "half" if rng.random() < 0.2 else "flat"
    if kind == "int":
        stack = soak.make_int_stack(rng)
        return (soak.reverse_stack(stack) if rng.random() < 0.5 else stack), combo, caps
    stack, pixel = soak.make_real_stack(rng)
    return (stack, pixel), combo, caps


# integer stacks whose meshes crossed before the repair: the band's own faces (none/arclength,
# none/wiederhold, none/greedy), or bands that no triangulation keeps clear (mlp, dss), whose
# sections then take their contours
CROSSED = [183, 191, 192, 204, 63, 145, 250, 300, 506]


@pytest.mark.parametrize("seed", CROSSED)
def test_integer_stacks_that_crossed_are_embedded_and_counted(seed):
    stack, (polygon, triangulation), caps = _scan_stack(seed, "int")
    with warnings.catch_warnings():
        warnings.simplefilter("error", SelfIntersectionWarning)
        m = soak.check_int_stack(stack, polygon, triangulation, caps)  # zero crossings asserted there
    assert m.meta["self_intersections"] == 0
    repaired = (m.meta["band_fallbacks"] + m.meta["crossing_fallbacks"] + m.meta["polygon_fallbacks"]
                + m.meta["crossings_repaired"])
    assert repaired > 0, m.meta  # the cause is there, and the repair is counted


def test_a_band_no_triangulation_keeps_clear_takes_the_contours():
    stack, (polygon, triangulation), caps = _scan_stack(300, "int")
    assert (polygon, triangulation) == ("dss", "arclength")
    m = contourmesh.mesh(stack, polygon=polygon, triangulation=triangulation, caps=caps)
    assert m.meta["polygon_fallbacks"] >= 1 and m.checks()["self_intersections"] == 0


def test_the_requested_band_is_kept_where_it_is_embedded():
    """A plain stack is meshed exactly as before: no guard fires, nothing is rebuilt."""
    sq = np.array([[0, 0], [4, 0], [4, 4], [0, 4]])
    stack = ContourStack(tuple(Section(float(z), (sq + z,)) for z in range(3)))
    for tri in ("wiederhold", "greedy", "optimal", "arclength"):
        m = stack_to_mesh(stack, polygon="none", triangulation=tri)
        assert m.meta["band_fallbacks"] == m.meta["crossing_fallbacks"] == m.meta["polygon_fallbacks"] == 0
        assert m.meta["self_intersections"] == 0 and m.checks()["self_intersections"] == 0


def _far_apart_rings():
    """Drawn rings of two sections far apart in the plane: every band between them crosses itself."""
    (stack, pixel), _, _ = _scan_stack(226, "real")
    return stack, pixel


def test_crossings_left_are_warned_and_counted_or_raised():
    stack, _ = _far_apart_rings()
    with pytest.warns(SelfIntersectionWarning, match="pairs of faces still cross"):
        m = stack_to_mesh(stack, polygon="none", triangulation="optimal")
    left = m.meta["self_intersections"]
    assert left > 0 and m.checks()["self_intersections"] == left and not m.checks()["ok"]
    with pytest.raises(CrossingFacesError, match="without crossing faces"):
        stack_to_mesh(stack, polygon="none", triangulation="optimal", crossings="raise")
    with pytest.raises(ValueError, match="crossings must be"):
        stack_to_mesh(stack, polygon="none", crossings="ignore")


def test_drawn_rings_whose_faces_would_cross_take_the_contours_route():
    from contourmesh.errors import RasterFallbackWarning

    stack, pixel = _far_apart_rings()
    with pytest.warns(RasterFallbackWarning, match="cannot be meshed as drawn on the stack route"):
        m = contourmesh.mesh(stack, polygon="none", triangulation="optimal", pixel=pixel)
    assert m.meta["route"] == "contours" and "without crossing faces" in m.meta["stack_route_error"]
    assert m.checks()["ok"] and m.checks()["self_intersections"] == 0


# ------------------------------------------------------------------------------------------------
# real data
# ------------------------------------------------------------------------------------------------
SMALL = {"bunny-32": "bunny-32", "bunny-64": "bunny-64", "lobsterCroped": "lobsterCroped", "Al.100": "Al.100",
         "cat10": "cat10", "dicomSample": "dicomSample", "liver": "../cgogn/liver"}
MODES = [(p, t, r) for r in (None, "band") for p in ("mlp", "dss", "none")
         for t in ("wiederhold", "greedy", "optimal", "arclength")]
#: every mode on a real-data block of at most this many voxels a side (the suite's budget); the whole
#: samples in every mode: ``python benchmarks/intersect_counts.py --random 0 --modes all``
BLOCK = 12


def _block(shared_data, name):
    """A ``BLOCK``-sided block of the sample's mask where its surface is densest."""
    from scipy import ndimage

    z = np.load(shared_data / "volumes" / "dgtal" / f"{SMALL[name]}.npz", allow_pickle=False)
    mask = z["mask"].astype(bool)
    if name == "liver":
        mask = mask[::4, ::4, ::4]  # the liver downsampled (7 M voxels)
    edge = mask & ~ndimage.binary_erosion(mask)
    dens = ndimage.uniform_filter(edge.astype(np.float32), BLOCK)
    c = np.array(np.unravel_index(int(np.argmax(dens)), dens.shape))
    lo = np.clip(c - BLOCK // 2, 0, np.maximum(np.array(mask.shape) - BLOCK, 0))
    return np.ascontiguousarray(mask[lo[0]:lo[0] + BLOCK, lo[1]:lo[1] + BLOCK, lo[2]:lo[2] + BLOCK])


@pytest.mark.parametrize("name", list(SMALL))
def test_shared_samples_in_every_mode_have_no_crossing_faces(shared_data, name):
    from contourmesh.volumes import voxel_topology

    vol = _block(shared_data, name)
    assert vol.any() and not vol.all()
    ref = voxel_topology(np.pad(vol, 1))
    bad = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for polygon, triangulation, refine in MODES:
            m = contourmesh.mesh(vol, polygon=polygon, triangulation=triangulation, refine=refine)
            chk = m.checks()
            if not chk["closed"] or chk["self_intersections"] or chk["genus"] != ref["genus"]:
                bad.append((polygon, triangulation, refine, chk["self_intersections"], chk["closed"]))
    assert not bad, bad


#: the RT structure set's large ROIs (many rings a section: the contours route, seconds each) are
#: meshed in the default triangulation only; the small ones, most on the stack route, in every one
LARGE_ROIS = ("BODY", "Lt Lung", "Breast")


@pytest.mark.parametrize("triangulation", ["wiederhold", "greedy", "optimal", "arclength"])
def test_every_rt_structure_has_no_crossing_faces(shared_data, triangulation):
    """Every ROI of the RT structure set meshed between its drawn rings with ``polygon="none"``: the
    stack route where each section holds one ring, else the contours route."""
    pytest.importorskip("pydicom")
    from contourmesh.io import read_contours

    path = shared_data / "contours" / "dicompyler-core" / "rtss.dcm"
    names = list(np.load(shared_data / "contours" / "dicompyler-core" / "rtss_contours.npz")["roi_names"])
    assert len(names) >= 8
    bad, routes = [], set()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for roi in names:
            if str(roi) in LARGE_ROIS and triangulation != "wiederhold":
                continue
            m = contourmesh.mesh(read_contours(path, roi=str(roi)), polygon="none", triangulation=triangulation,
                                 pixel=2.0)
            routes.add(m.meta["route"])
            chk = m.checks()
            if not chk["closed"] or chk["self_intersections"]:
                bad.append((str(roi), m.meta["route"], chk["self_intersections"]))
    assert not bad, bad
    assert routes == {"stack", "contours"} if triangulation == "wiederhold" else "stack" in routes
