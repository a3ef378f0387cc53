"""Issue 16 (twentieth round): the slab phase (``intersect._slab_pairs``) no longer lists every
plane's and slab's faces for the whole mesh at once; it keeps the current plane's faces as it walks
up the planes (``_first_plane``, then ``_next_plane`` per plane).  Each plane's faces as the walk
holds them must be, bit for bit, the list the table held: the live faces with ``lo <= k <= hi`` in
the order of their numbers (the sweeps' candidates, work and stars depend on that order), on
random level ranges, on the general mesher's meshes and on a ball's, from the first plane and
from a range's first plane.  The slab phase's pairs themselves are compared with the grid's in
``test_intersect_slabs.py``."""

import numpy as np
import pytest
from scipy import ndimage

import contourmesh
from contourmesh import intersect as I


def _listed(lo, hi, nlev, kr0):
    """Each plane's faces from ``kr0`` on as the table listed them: face by face, in number order."""
    out, counts = [], []
    for k in range(kr0, nlev):
        f = np.flatnonzero((lo >= 0) & (lo <= k) & (k <= hi)).astype(np.int32)
        out.append(f)
        counts.append(len(f))
    return (np.concatenate(out) if out else np.empty(0, np.int32)), np.array(counts, np.int64)


def _walk(lo, hi, nlev, kr0):
    live = lo >= 0
    mp = 1
    if live.any():
        d = np.zeros(nlev + 1, np.int64)
        np.add.at(d, lo[live], 1)
        np.add.at(d, hi[live] + 1, -1)
        mp = int(np.cumsum(d).max())
    return I._plane_walk(lo, hi, np.int64(nlev), np.int64(kr0), np.int64(mp))


def _check(lo, hi, nlev, kr0):
    got, gc = _walk(lo, hi, nlev, kr0)
    want, wc = _listed(lo, hi, nlev, kr0)
    assert got.dtype == want.dtype
    np.testing.assert_array_equal(gc, wc)
    np.testing.assert_array_equal(got, want)
    return int(wc.sum())


@pytest.mark.parametrize("seed", range(4))
def test_random_level_ranges(seed):
    rng = np.random.default_rng(146 + seed)
    total = 0
    for trial in range(60):
        nlev = int(rng.integers(1, 40))
        m = int(rng.integers(0, 300))
        lo = rng.integers(0, nlev, m)
        span = rng.integers(0, 4, m) * (rng.random(m) < 0.7) + rng.integers(0, nlev, m) * (rng.random(m) < 0.05)
        hi = np.minimum(lo + span, nlev - 1)
        dead = rng.random(m) < 0.1  # (skipped faces: lo = hi = -1)
        lo = np.where(dead, -1, lo).astype(np.int32)
        hi = np.where(dead, -1, hi).astype(np.int32)
        for kr0 in {0, int(rng.integers(0, nlev)), nlev - 1}:
            # (a range's faces: those reaching its first plane or above, as _slab_pairs keeps them)
            keep = hi >= kr0
            total += _check(np.where(keep, lo, -1).astype(np.int32), np.where(keep, hi, -1).astype(np.int32),
                            nlev, kr0)
    assert total > 1000


def _mesh_levels(V, F):
    lev, nlev = I._levels(np.ascontiguousarray(V[:, 2], dtype=np.float64))
    L = lev[F]
    lo = L.min(1).astype(np.int32)
    hi = L.max(1).astype(np.int32)
    degenerate = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    lo[degenerate] = -1
    hi[degenerate] = -1
    return lo, hi, int(nlev)


def test_the_meshers_meshes_and_a_ball():
    rng = np.random.default_rng(20)
    z, y, x = np.mgrid[:40, :40, :40]
    vols = [(z - 19.5) ** 2 + (y - 19.5) ** 2 + (x - 19.5) ** 2 < 17 ** 2]
    for _ in range(4):
        vols.append(np.pad(ndimage.gaussian_filter(rng.random((14, 16, 15)), 1.3) > 0.5, 1))
    total = 0
    for v in vols:
        m = contourmesh.mesh(v)
        lo, hi, nlev = _mesh_levels(m.vertices, m.faces)
        for kr0 in (0, nlev // 3, nlev - 1):
            keep = hi >= kr0
            total += _check(np.where(keep, lo, -1).astype(np.int32), np.where(keep, hi, -1).astype(np.int32),
                            nlev, kr0)
    assert total > 10000
