"""A second process meshes from numba's on-disk cache what the first compiled, and gets the same mesh.

Every user's second run loads the cached kernels instead of compiling them, in whatever order its
input reaches them. The lobster's second run once failed there (``RuntimeError: In
'NRT_adapt_ndarray_to_python', 'descr' is NULL``: a callee called from Python after a cached
caller that holds a copy of it was loaded; see ``tests/test_cache_guard.py`` and
``contourmesh._cache_guard``). These tests mesh an input in the test process (compiling or loading
what it needs), then again in a fresh process, and compare the vertex and face bytes.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import textwrap

import numpy as np
from scipy import ndimage

import contourmesh

_CHILD = textwrap.dedent("""\
    import hashlib, sys
    import numpy as np
    import contourmesh
    vol = np.load(sys.argv[1], allow_pickle=False)
    m = contourmesh.mesh(vol)
    V = np.ascontiguousarray(m.vertices, dtype=np.float64)
    F = np.ascontiguousarray(m.faces, dtype=np.int64)
    print(hashlib.sha256(V.tobytes() + F.tobytes()).hexdigest())
    """)


def _digest(mesh) -> str:
    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    return hashlib.sha256(V.tobytes() + F.tobytes()).hexdigest()


def _in_a_fresh_process(tmp_path, vol) -> str:
    path = tmp_path / "volume.npy"
    np.save(path, vol)
    (tmp_path / "child.py").write_text(_CHILD)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT",)}
    out = subprocess.run([sys.executable, "child.py", str(path)], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout.split()[-1]


def _blobs(seed: int, shape=(20, 28, 26)) -> np.ndarray:
    """Smoothed noise, thresholded: components that branch, merge and hold holes (the general
    mesher's joins, sections and repair), as a segmentation's are."""
    rng = np.random.default_rng(seed)
    vol = ndimage.gaussian_filter(rng.random(shape), 1.6) > 0.5
    vol[0], vol[-1], vol[:, 0], vol[:, -1], vol[:, :, 0], vol[:, :, -1] = (False,) * 6
    return vol


def test_a_fresh_process_meshes_branching_blobs_the_same(tmp_path):
    vol = _blobs(7)
    first = contourmesh.mesh(vol)
    assert ndimage.label(vol)[1] > 1 and len(first.faces) > 1000  # several components, a real mesh
    assert _in_a_fresh_process(tmp_path, vol) == _digest(first)


def test_a_fresh_process_meshes_the_lobster_the_same(tmp_path, shared_data):
    from contourmesh.io import read_volume

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    vol = np.pad(vol, 1)
    first = contourmesh.mesh(vol)
    assert _in_a_fresh_process(tmp_path, vol) == _digest(first)
