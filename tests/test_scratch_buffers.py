"""The general mesher's kept scratch buffers (least-area bands, sections' distances)."""

import numpy as np

import contourmesh


def test_kept_scratch_buffers_are_let_go_once_the_joins_are_built(monkeypatch):
    """The least-area bands and the sections' distances keep per-thread buffers from join to join;
    the general mesher lets them go when its joins are built, before the steps that set its peak."""
    from contourmesh import sections, volumes
    from contourmesh.bands import optimal

    calls = []
    build = volumes._build_bridges

    def spy(*args, **kwargs):
        calls.append(1)
        # as left by joins built earlier in this thread
        optimal._LOCAL.buffers = (np.empty(64), np.empty(64, np.int8))
        sections._LOCAL.columns = np.empty(64, np.int32)
        return build(*args, **kwargs)

    monkeypatch.setattr(volumes, "_build_bridges", volumes._scratch_released(spy))
    vol = np.zeros((8, 12, 16), bool)
    vol[1:4, 2:10, 2:14] = True  # a slab that forks into two columns
    vol[4:7, 2:10, 2:6] = True
    vol[4:7, 2:10, 10:14] = True
    m = contourmesh.mesh(vol)
    assert calls and m.checks()["watertight"]
    assert not hasattr(optimal._LOCAL, "buffers")
    assert not hasattr(sections._LOCAL, "columns")
    # and a mesher's own thread keeps using them afterwards
    optimal._buffers(4, 5)
    assert hasattr(optimal._LOCAL, "buffers")
    optimal.release_buffers()
    assert not hasattr(optimal._LOCAL, "buffers")
