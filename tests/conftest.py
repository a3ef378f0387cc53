import os
from pathlib import Path

import pytest
from hypothesis import settings

# The test suite is deterministic: hypothesis draws the same examples on every run (locally and in
# CI), so a green run stays green; exploring new examples is the soak's job (tests/soak.py).
settings.register_profile("contourmesh", derandomize=True, deadline=None, print_blob=True)
settings.load_profile("contourmesh")

SHARED_DATA = Path(os.environ.get("CONTOURMESH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared sample data not found at {SHARED_DATA} (set CONTOURMESH_DATA)")
    return SHARED_DATA


def assert_closed_outward(mesh, *, genus=None):
    """The guarantee for every emitted mesh: closed, consistently oriented outward, no degenerate faces."""
    import trimesh

    chk = mesh.checks()
    assert chk["watertight"], chk
    assert chk["winding_consistent"], chk
    assert chk["degenerate_faces"] == 0, chk
    assert chk["duplicate_vertices"] == 0, chk
    assert chk["volume"] > 0, chk
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    assert tm.is_watertight
    assert tm.is_winding_consistent
    assert tm.volume > 0
    if genus is not None:
        assert chk["genus"] == genus, chk
    return chk
