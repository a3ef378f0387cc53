"""A bridged join that gives up on a lid whose ring repeats a point before it builds its bands."""

import numpy as np

from contourmesh import volumes


def _square(x0, y0, s=1.0):
    return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]])


def test_a_bridged_join_with_a_lid_that_repeats_a_point_builds_no_band(monkeypatch):
    """A lid's ring with a point twice gives the bridged join up before its bands are made: None, as
    where the lids were tested after the bands."""
    made = [0]
    band = volumes._bridged_band_seen

    def counted(*a):
        made[0] += 1
        return band(*a)

    monkeypatch.setattr(volumes, "_bridged_band_seen", counted)
    outer0, outer1 = _square(0, 0, 6.0), _square(0.5, 0.5, 5.0)
    hole = np.array([[2.0, 2.0], [2.0, 3.0], [3.0, 3.0], [3.0, 2.0], [2.0, 2.0]])  # (clockwise, repeats a point)
    rings = {(0, 0, -1): outer0, (0, 0, 0): hole, (1, 0, -1): outer1}

    def poly(kk, c, h):
        return rings[kk, c, h]

    plan = ([], [(0, 0)], [], [], [])
    args = (0, [0], [0], plan, poly, np.array([0.0, 1.0]), None, None, "wiederhold", "flat", set())
    assert volumes._bridge_join(*args) is None
    assert made[0] == 0
    rings[0, 0, 0] = hole[:-1]  # (distinct points: the bands are made)
    volumes._bridge_join(*args)
    assert made[0] > 0
