"""Trims of a bridged join's bands and of its crossing tests (issue 16), each against the form it
replaced: the fold test made once per band in ``volumes._bridged_band_crossing`` and the start of
the upper ring rolled by one concatenation in the linear band rules (``np.roll`` before)."""


import numpy as np

from bridged_rings import bridged_band, circle
from contourmesh import volumes
from contourmesh.bands import (
    TRIANGULATORS,
    band_is_folded,
    triangulate_band_optimal,
)
from contourmesh.bands.arclength import arclength_edges
from contourmesh.bands.greedy import greedy_edges
from contourmesh.bands.wiederhold import (
    edges_to_faces,
    initial_edge,
    oriented_pair,
    validate_band_polygons,
    wiederhold_edges,
)


def _cases(rs, count):
    """Bands as a bridged join has them (as tests/test_bridged_band_memory.py makes them): below,
    two rings bridged into one (the bridge's ends visited twice, each one vertex), or one ring;
    above, one ring round them."""
    for _ in range(count):
        n1, n2, nb = (int(x) for x in rs.integers(3, 40, size=3))
        A, B = circle(rs, n1, -1.5, 1.0, 0.0), circle(rs, n2, 1.5, 1.0, 0.0)
        up = circle(rs, nb + 3, 0.0, rs.uniform(1.0, 3.5), rs.choice([1.0, 0.2]))
        up[:, 0] *= rs.uniform(0.3, 1.5)
        yield bridged_band(rs, A, B, up)


def _crossing_reference(P, na, ids, rule):
    """``volumes._bridged_band_crossing`` as it was: the fold test of the join's numbering asked
    again after every step, and once more after the loop."""
    from contourmesh.bands import _band_crosses
    from contourmesh.measure import triangle_areas

    Va, Vb = P[:na], P[na:]
    f, r = volumes._band_faces(Va, Vb, rule, volumes._BRIDGED_OPTIMAL_BUDGET)
    n_, m_ = sorted((na, len(P) - na))
    made = {}
    for method in ("optimal", "arclength"):
        if not band_is_folded(ids[f]):
            break
        if method != "optimal" or rule != "optimal" or r != 0 or n_ * n_ * m_ > volumes._BRIDGED_OPTIMAL_BUDGET:
            f = triangulate_band_optimal(Va, Vb, max_work=volumes._BRIDGED_OPTIMAL_BUDGET) \
                if method == "optimal" else volumes._made_band(made, Va, Vb, method)
        r += 1
    if band_is_folded(ids[f]):
        return None
    crosses = _band_crosses(P, f)
    if crosses:
        limit = volumes._BRIDGED_AREA_SLACK * float(triangle_areas(P, f).sum())
        for method in volumes._BRIDGED_ALTERNATIVES:
            if method == "optimal" and (rule == "optimal" or n_ * n_ * m_ > volumes._BRIDGED_OPTIMAL_BUDGET):
                continue
            g = volumes._made_band(made, Va, Vb, method)
            if g is f:
                continue
            if (not band_is_folded(ids[g]) and float(triangle_areas(P, g).sum()) <= limit
                    and not _band_crosses(P, g)):
                f, r, crosses = g, r + 1, False
                break
    return f, r, crosses


def test_bridged_band_crossing_is_the_form_it_replaced(monkeypatch):
    rs = np.random.default_rng(167)
    kinds = {"band": 0, "none": 0, "folded first": 0, "crosses": 0}
    for P, na, ids in _cases(rs, 150):
        for rule in ("optimal", "wiederhold", "arclength"):
            want = _crossing_reference(P, na, ids, rule)
            got = volumes._bridged_band_crossing(P, na, ids, rule)
            if want is None:
                assert got is None
                kinds["none"] += 1
                continue
            assert got is not None and np.array_equal(got[0], want[0]) and got[1:] == want[1:]
            kinds["band"] += 1
            kinds["folded first"] += got[1] > 0
            kinds["crosses"] += bool(got[2])
    assert kinds["band"] > 200 and kinds["folded first"] > 5, kinds


def _rolled_reference(lower, upper, rule):
    """A linear rule's band with the upper ring's start rolled by ``np.roll`` (the form replaced)."""
    lo, up = validate_band_polygons(lower, upper)
    c1, c2, swapped = oriented_pair(lo, up)
    j0 = initial_edge(c1, c2)
    r2 = np.roll(c2, -j0, axis=0)
    if rule == "wiederhold":
        edges = wiederhold_edges(np.ascontiguousarray(c1[:, 0]), np.ascontiguousarray(c1[:, 1]),
                                 np.ascontiguousarray(r2[:, 0]), np.ascontiguousarray(r2[:, 1]))
        return edges_to_faces(edges, len(c1), len(c2), 0, j0, len(lo), swapped)
    edges = (greedy_edges if rule == "greedy" else arclength_edges)(c1, np.ascontiguousarray(r2))
    return edges_to_faces(edges, len(c1), len(c2), 0, j0, len(lo), swapped)


def test_linear_rules_roll_the_upper_ring_as_np_roll():
    rs = np.random.default_rng(168)
    starts = set()
    for _ in range(300):
        n, m = (int(x) for x in rs.integers(2, 60, size=2))
        lo = circle(rs, n, rs.uniform(-0.5, 0.5), 1.0, 0.0)
        up = circle(rs, m, rs.uniform(-0.5, 0.5), rs.uniform(0.5, 2.0), 1.0)
        up = np.roll(up, int(rs.integers(0, m)), axis=0)  # (the nearest point anywhere on the ring)
        c1, c2, _ = oriented_pair(lo, up)
        starts.add(initial_edge(c1, c2) > 0)
        for rule in ("wiederhold", "greedy", "arclength"):
            got, want = TRIANGULATORS[rule](lo, up), _rolled_reference(lo, up, rule)
            assert got.dtype == want.dtype and np.array_equal(got, want)
    assert starts == {True, False}
