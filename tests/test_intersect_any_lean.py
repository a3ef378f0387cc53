"""The mesher's crossing tests by their lean entries: a band's test in one compiled call
(``bands._band_any``: the pinches split, then the crossing test told that no two points share a
position) and the memory of the last pair found (``intersect._seen_pair``, tested first on the next
call).  Both only save time: every answer must be the reference's (the general steps, no memory),
on random bands (series of related ones, as the mesher's retries) and on every call of a real build."""

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from contourmesh import bands, intersect
from contourmesh.bands import _band_crosses_reference, _band_crosses_uncached, _pinch_split, triangulate_band

_D = np.int64(intersect._STAR_DELAY)


def _reference_any(V, F):
    """The crossing test by the general steps, without the two-level path or the memory."""
    return int(intersect._any_kernel_reference(np.ascontiguousarray(V, dtype=np.float64),
                                               np.ascontiguousarray(F, dtype=np.int64), _D))


def _reference_band(P, f):
    """``bands._band_any``'s answer step by step: the pinches split, then the reference test."""
    Q, status = _pinch_split(np.ascontiguousarray(P, dtype=np.float64), np.ascontiguousarray(f, dtype=np.int64))
    if status == 3:
        return -1
    return 0 if status == 2 else _reference_any(Q, f)


def _rings(rng, trial):
    n = int(rng.integers(6, 50))
    t = (np.arange(n) + rng.uniform(0, 0.5, n)) * (2 * np.pi / n)
    lo = np.c_[np.cos(t), np.sin(t), np.zeros(n)] * rng.uniform(5, 50)
    twist = rng.uniform(0.1, 3.0) if trial % 2 == 0 else 0.2
    hi = np.c_[np.cos(t + twist), np.sin(t + twist), np.ones(n)] * rng.uniform(5, 50)
    if trial % 3:
        lo[:, :2], hi[:, :2] = np.round(lo[:, :2] * 16) / 16, np.round(hi[:, :2] * 16) / 16
    if trial % 4 == 1:  # a pinch: a position visited twice
        a, b = rng.choice(n, 2, replace=False)
        if (a - b) % n not in (1, n - 1):
            lo[b] = lo[a]
    return lo, hi


def test_band_any_and_the_memory_answer_as_the_reference():
    # series of bands of one pair of rings (each rule's band), then the two rings' band with its
    # faces renumbered and with a third ring's faces beside it (a join holding the band): the
    # memory holds the pair the last call found, so these calls test it first
    mem = np.zeros(19)
    rng = np.random.default_rng(17101)
    seen = {"crosses": 0, "clear": 0, "kept": 0, "scaled": 0}
    for trial in range(300):
        lo, hi = _rings(rng, trial)
        P = np.concatenate([lo, hi])
        if (lo[:, :2] == np.roll(lo[:, :2], -1, axis=0)).all(axis=1).any() or \
                (hi[:, :2] == np.roll(hi[:, :2], -1, axis=0)).all(axis=1).any():
            continue
        for method in ("greedy", "wiederhold", "arclength"):
            f = triangulate_band(lo, hi, method, fallback=False)
            want = _reference_band(P, f)
            got = int(bands._band_any(np.ascontiguousarray(P), np.ascontiguousarray(f, dtype=np.int64), _D, mem))
            assert got == want, (trial, method)
            assert _band_crosses_uncached(P, f) == _band_crosses_reference(P, f) == bool(want)
            seen["crosses" if want else "clear"] += 1
            seen["kept"] += int(mem[18] == 1.0)
            # the same faces in a larger numbering with other faces (a join): by the entry with memory
            extra = np.c_[rng.uniform(-60, 60, (3, 2)), np.full(3, 0.5)]
            V = np.concatenate([extra, P])
            F = np.concatenate([f + 3, [[0, 1, 2]]])[rng.permutation(len(f) + 1)]
            assert int(intersect._any_kernel_seen(V, F, _D, mem)) == _reference_any(V, F)
            # the band with a few of its faces dropped (the pair kept may be gone)
            G = np.ascontiguousarray(f[rng.random(len(f)) > 0.1])
            if len(G) >= 2:
                assert int(intersect._any_kernel_seen(P, G, _D, mem)) == _reference_any(P, G)
        # out of the exact range: the compiled call refuses, the checked path answers
        W = P * 2.0 ** 400
        assert int(bands._band_any(W, np.ascontiguousarray(f, dtype=np.int64), _D, mem)) == -1
        assert _band_crosses_uncached(W, f) == _band_crosses_reference(P, f)
        seen["scaled"] += 1
    assert min(seen.values()) > 20, seen


def test_memory_of_a_degenerate_or_absent_pair_proves_nothing():
    # a memory naming faces that are here but no longer cross (moved apart), or are not live (three
    # collinear corners), or are absent: the whole test answers
    V = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 1], [3, 3, 0.5],
                  [10, 10, 0], [11, 10, 0], [12, 10, 0]], dtype=np.float64)
    F = np.array([[0, 1, 2], [3, 4, 5]], dtype=np.int64)
    mem = np.zeros(19)
    assert intersect._any_kernel_seen(V, F, _D, mem) == 1 and mem[18] == 1.0
    W = V.copy()
    W[3:6, 0] += 100.0  # the second face moved away: the memory's pair is not here
    assert intersect._any_kernel_seen(W, F, _D, mem) == 0
    mem2 = mem.copy()
    mem2[9:18] = V[[6, 7, 8]].ravel()  # a collinear "face" as the pair's second face
    G = np.array([[0, 1, 2], [6, 7, 8]], dtype=np.int64)
    assert intersect._any_kernel_seen(V, G, _D, mem2) == 0 == _reference_any(V, G)


@pytest.mark.skipif(not os.environ.get("CONTOURMESH_DATA"), reason="needs the real volumes (CONTOURMESH_DATA)")
@pytest.mark.parametrize("name", ["lobster", "liver"])
def test_every_call_of_a_real_build_answers_as_the_reference(monkeypatch, name):
    """Every band test (``_band_any``) and every ``any_intersecting`` call of a real build, with the
    memory as the build leaves it call by call: the reference's answer."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import volume_speed as vs

        vol, sp = vs.make_input(name)
    except Exception as exc:  # pragma: no cover - data missing
        pytest.skip(f"{name} not available: {exc}")
    import contourmesh

    counts = {"band": 0, "any": 0, "crosses": 0, "from memory": 0}
    band_any, any_seen = bands._band_any, intersect._any_kernel_seen

    def band_wrap(P, f, delay, mem):
        before = mem.copy()
        got = band_any(P, f, delay, mem)
        assert got == _reference_band(P, f)
        counts["band"] += 1
        counts["crosses"] += int(got == 1)
        counts["from memory"] += int(got == 1 and np.array_equal(before, mem))
        return got

    def any_wrap(V, F, delay, mem):
        before = mem.copy()
        got = any_seen(V, F, delay, mem)
        assert got == _reference_any(V, F)
        counts["any"] += 1
        counts["crosses"] += int(got == 1)
        counts["from memory"] += int(got == 1 and np.array_equal(before, mem))
        return got

    monkeypatch.setattr(bands, "_band_any", band_wrap)
    monkeypatch.setattr(intersect, "_any_kernel_seen", any_wrap)
    contourmesh.mesh(vol, spacing=sp)
    assert counts["band"] > 200 and counts["any"] > 20 and counts["crosses"] > 50, counts
    assert counts["from memory"] > 5, counts
