"""The bridge kernels whose helpers are written out in their loops, on the lobster's own calls: the
fused tree kernel's straight bridges against :func:`_straight_kernel` (which keeps the helper
``_straight_ok``) on the same candidates, and the compiled keyhole search (its heap's comparisons
written out) against the Python search.  The random inputs are in ``test_bridged_kernels.py``
and ``test_compiled_repair.py``; these take the calls a real mesh makes."""

import numpy as np

from contourmesh.bands import bridges as B
from contourmesh.volumes import volume_to_mesh


def _lobster(shared_data):
    from contourmesh.io import read_volume

    vol, spacing, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    return np.pad(vol, 1), tuple(spacing)  # (as benchmarks/volume_speed.py has it)


def test_lobster_tree_kernel_equals_candidates_then_straight_kernel(monkeypatch, shared_data):
    # each call of the fused kernel: its bridges are _straight_kernel's on the candidate kernel's
    # columns (all preferences measured, sorted by them), and where they do not join every ring
    # its columns are those columns
    vol, spacing = _lobster(shared_data)
    real = B._tree_kernel
    calls = []

    def spy(*a):
        got = real(*a)
        calls.append((a, got))
        return got

    monkeypatch.setattr(B, "_tree_kernel", spy)
    volume_to_mesh(vol, spacing=spacing)
    seen = {"whole": 0, "part": 0, "keyhole test": 0, "bridges": 0}
    for a, got in calls:
        if not got[7]:
            continue
        (pts, off, lens, pairs, ask, k, lab, cids, ox, oy, dx, dy, share, comp, oa, ob, sa0, sb0, alab, acids,
         aox, aoy, adx, ady, use_allowed, n) = a
        cols = B._candidate_kernel(pts, off, lens, pairs, ask, k, lab, cids, ox, oy, dx, dy, share)
        want = B._straight_kernel(np.stack(cols[3:7], axis=1), pts, off, lens, comp, oa, ob, sa0, sb0, alab, acids,
                                  aox, aoy, adx, ady, use_allowed, n)
        assert got[8].dtype == want.dtype and got[8].tobytes() == want.tobytes()
        assert got[9] == (len(want) == n - 1)
        if not got[9]:
            for x, y in zip(got[:7], cols[:7]):
                assert x.dtype == y.dtype and x.tobytes() == y.tobytes()
        seen["whole" if got[9] else "part"] += 1
        seen["keyhole test"] += bool(use_allowed)
        seen["bridges"] += len(want)
    assert seen["whole"] > 100 and seen["part"] > 0 and seen["keyhole test"] > 0, seen


def test_lobster_keyhole_searches_equal_the_python_search(monkeypatch, shared_data):
    # each polyline keyhole search of a lobster mesh (none answered from the memory of recent
    # searches): the compiled search's path against the Python search's, given the same test as a
    # plain function (which the compiled search does not take)
    vol, spacing = _lobster(shared_data)
    real = B._keyhole_path
    calls = []

    def spy(*a, **k):
        got = real(*a, **k)
        calls.append((a, k, got))
        return got

    monkeypatch.setattr(B, "_KEYHOLES_SEEN", B.Recent(B._KEYHOLES_KEEP))
    monkeypatch.setattr(B, "_keyhole_path", spy)
    volume_to_mesh(vol, spacing=spacing)
    monkeypatch.setattr(B, "_keyhole_path", real)
    seen = {"path": 0, "none": 0}
    for a, k, got in calls:
        allowed = k.get("allowed")
        plain = (lambda p, q: True) if allowed is None else (lambda p, q, t=allowed: t(p, q))
        want = real(*a, **{**k, "allowed": plain})
        assert (got is None) == (want is None)
        if got is not None:
            assert got[:2] == want[:2] and got[2].tobytes() == want[2].tobytes()
        seen["none" if got is None else "path"] += 1
    assert seen["path"] > 5, seen
