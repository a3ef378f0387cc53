"""Issue 16 (twelfth round): the grid of the whole-mesh crossing test (``_intersecting_pairs``) calls
the in-plane tests only where the faces' boxes say they can decide the pair (``_box_gates``):
``_across_plane`` where the z-ranges meet at one height with neither face flat there,
``_touching_boxes`` where along some axis the boxes only touch.  Every pair whose bit is clear
must be one that the test would have left undecided (-1), so that skipping it changes nothing;
checked here on every pair of overlapping boxes of random sectioned meshes, voxel meshes (with
heights nudged off their planes), and folded spheres.  The whole grid against the form before the
gates (which called both tests on every pair) is compared in ``test_intersect_grid_chunks``."""

import numpy as np
import pytest
import trimesh
from numba import njit

import contourmesh
from contourmesh.intersect import (
    _EXP_LEN,
    _across_plane,
    _as_mesh_arrays,
    _box_gates,
    _face_range,
    _touching_boxes,
    canonical_vertices,
)
from test_intersect_quick import _nudged, _volume
from test_intersect_slabs import _random_sectioned


@njit(cache=False)
def _check_gates(V, ws, F):
    """Over every pair of faces whose closed boxes overlap: counts of (pairs, bit 1 set and
    ``_across_plane`` decided, bit 2 set and ``_touching_boxes`` decided), and the number of pairs
    where a clear bit skipped a test that would have decided (must be 0)."""
    m = len(F)
    box = np.empty((m, 6), np.float64)
    for i in range(m):
        for k in range(3):
            lo, hi = _face_range(V, F, i, k)
            box[i, k] = lo
            box[i, 3 + k] = hi
    out = np.zeros(4, np.int64)
    for i in range(m):
        for j in range(i + 1, m):
            if (box[i, 0] > box[j, 3] or box[j, 0] > box[i, 3] or box[i, 1] > box[j, 4]
                    or box[j, 1] > box[i, 4] or box[i, 2] > box[j, 5] or box[j, 2] > box[i, 5]):
                continue
            out[0] += 1
            gate = _box_gates(box, i, j)
            if gate != _box_gates(box, j, i):
                out[3] += 1
            across = _across_plane(V, ws, F, i, j)
            touch = _touching_boxes(V, ws, F, i, j)
            if gate & 1:
                out[1] += across >= 0
            elif across >= 0:
                out[3] += 1
            if gate & 2:
                out[2] += touch >= 0
            elif touch >= 0:
                out[3] += 1
    return out


def _gates(V, F):
    Va, Fa = _as_mesh_arrays(V, F)
    Fc = canonical_vertices(Va)[Fa]
    ws = np.zeros(1 + 3 * _EXP_LEN)
    return _check_gates(np.ascontiguousarray(Va, dtype=np.float64), ws, np.ascontiguousarray(Fc, dtype=np.int64))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_clear_gate_skips_only_undecided_tests(seed):
    rng = np.random.default_rng(seed)
    seen = np.zeros(4, np.int64)
    for t in range(6):
        V, F = _random_sectioned(rng, int(rng.integers(2, 6)), 60, 150, 0.3)
        seen += _gates(V, F)
        m = contourmesh.mesh(_volume(rng, t))
        seen += _gates(m.vertices, m.faces)
        seen += _gates(_nudged(rng, m.vertices), m.faces)
    s = trimesh.creation.icosphere(2)
    V = s.vertices + rng.normal(0, 0.08, s.vertices.shape)
    V[rng.random(len(V)) < 0.3, 2] = 0.25  # (flat parts and faces touching a plane)
    seen += _gates(V, s.faces)
    assert seen[3] == 0, seen
    # both tests decide many pairs where their bits are set (the gates do not merely skip them)
    assert seen[1] > 100 and seen[2] > 100, seen
