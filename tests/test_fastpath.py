"""The fast path gives the full mesher's mesh, vertex for vertex and face for face.

No timings here (speed lives in ``benchmarks/volume_speed.py``): every test compares
:func:`contourmesh.fastpath.fast_volume_to_mesh` with :func:`contourmesh.volumes.volume_to_mesh`
on volumes inside the fast path's scope, and checks that it declines (returns None) outside it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from contourmesh._kernels import njit
from contourmesh.fastpath import (
    _stack_intervals,
    band_faces,
    fast_volume_to_mesh,
    outer_jordan_contour,
    slice_components,
    slice_polygons,
    slice_runs,
)
from contourmesh.tracing import trace_contours
from contourmesh.volumes import _mlp_of_pixels, volume_to_mesh

_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)


def ball(n, r, c=None, shape=None):
    shape = shape or (n, n, n)
    c = np.array([(s - 1) / 2 for s in shape]) if c is None else np.asarray(c, float)
    z, y, x = np.ogrid[: shape[0], : shape[1], : shape[2]]
    return (x - c[2]) ** 2 + (y - c[1]) ** 2 + (z - c[0]) ** 2 <= r * r


def ellipsoid(shape, c, radii):
    z, y, x = np.ogrid[: shape[0], : shape[1], : shape[2]]
    return ((x - c[2]) / radii[2]) ** 2 + ((y - c[1]) / radii[1]) ** 2 + ((z - c[0]) / radii[0]) ** 2 <= 1


def assert_same(fast, slow):
    assert fast is not None, "the fast path declined a volume inside its scope"
    assert fast.vertices.shape == slow.vertices.shape
    assert fast.faces.shape == slow.faces.shape
    assert np.array_equal(fast.vertices, slow.vertices)
    assert np.array_equal(fast.faces, slow.faces)
    for key in ("band_joins", "exact_joins", "polygon_fallbacks", "band_fallbacks"):
        assert fast.meta[key] == slow.meta[key], key
    assert fast.meta["fast_path"] is True
    assert fast.P == slow.P


# ------------------------------------------------------------------------------------------------
# the pieces against the full mesher's pieces
# ------------------------------------------------------------------------------------------------
def _stacked_runs(rng, h, w):
    # one run per row over consecutive rows, each overlapping the one below (a ball's slice), or
    # touching it only at a corner, or leaving a row out (then it is not one stack)
    m = np.zeros((h, w), bool)
    y0 = int(rng.integers(0, h))
    a = int(rng.integers(0, w))
    for y in range(y0, int(rng.integers(y0, h)) + 1):
        b = int(rng.integers(a + 1, w + 1))
        m[y, a:b] = True
        a = int(rng.integers(max(0, a - 3), b + (rng.random() < 0.2)))
        if a >= w or rng.random() < 0.05:
            break
    return m


def test_runs_and_components_match_ndimage():
    rng = np.random.default_rng(1)
    for i in range(90):
        h, w = rng.integers(1, 40, size=2)
        if i % 3:  # the one-stack shortcut of _components, and its near misses
            m = _stacked_runs(rng, h, w)
        else:
            m = ndimage.gaussian_filter(rng.random((h, w)), 1.2) > 0.5
        ry, rx0, rx1, rs = slice_runs(m)
        back = np.zeros_like(m)
        for y, a, b in zip(ry, rx0, rx1):
            back[y, a:b] = True
        assert np.array_equal(back, m)
        assert np.all(rs[1:] >= rs[:-1]) and rs[-1] == len(ry)
        (ry, rx0, rx1, _), lab, n, holes, bbox = slice_components(m)
        ref, nref = ndimage.label(m, structure=_CROSS)
        assert n == nref
        for y, a, b, c in zip(ry, rx0, rx1, lab):
            assert np.all(ref[y, a:b] == c + 1)  # same numbering (raster order of first pixel)
        for c in range(n):
            comp = ref == c + 1
            bg, nb = ndimage.label(np.pad(~comp, 1, constant_values=True), structure=np.ones((3, 3), bool))
            assert holes[c] == nb - 1
            ys, xs = np.nonzero(comp)
            assert bbox[c].tolist() == [xs.min(), ys.min(), xs.max(), ys.max()]


def test_runs_of_unaligned_rows_and_words():
    # widths that are not multiples of 8 exercise the byte head/tail around the word skip
    for w in (1, 7, 9, 17, 31):
        m = np.zeros((3, w), bool)
        m[1, w // 3:] = True
        m[2, :1] = True
        ry, rx0, rx1, _ = slice_runs(m)
        assert [(int(y), int(a), int(b)) for y, a, b in zip(ry, rx0, rx1)] == [(1, w // 3, w), (2, 0, 1)]


def test_runs_of_volume_slices_off_word_boundaries():
    # slices of a C-ordered volume whose slices are 2 mod 8 bytes start off a word boundary 3
    # times in 4 (the rotated socket's 441 x 514): slice_runs reads them a word at a time from
    # their first boundary on, the same runs as the byte-by-byte scan and the numpy reference
    from contourmesh.fastpath import _scan_runs_py, _words_from

    rng = np.random.default_rng(8)
    vol = ndimage.uniform_filter(rng.random((8, 21, 34)), 5) > 0.5
    vol[:, 3, 5:30] = True  # (long stretches of whole words of 1 too)
    offs = set()
    for k in range(len(vol)):
        m = vol[k]
        b8 = m.reshape(-1).view(np.uint8)
        b64, woff, aligned = _words_from(b8)
        offs.add(int(woff))
        want = _scan_runs_py(b8, np.zeros(1, np.uint64), 0, 21, 34, False, np.int64(0))
        got = slice_runs(m)
        for a, b in zip(got, want):
            np.testing.assert_array_equal(a, b)
        assert [(int(y), int(a), int(b)) for y, a, b in zip(*got[:3])] == _runs_reference(m.astype(np.uint8))
    assert len(offs) == 4  # (each offset 0, 2, 4, 6 taken)


def _runs_reference(img):
    """Runs of the non-zero bytes of a 2D uint8 image, row by row, in numpy."""
    out = []
    for y, row in enumerate(img):
        d = np.diff(np.r_[0, (row != 0).astype(np.int8), 0])
        out += [(y, int(a), int(b)) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]
    return out


def test_runs_of_words_with_boundaries_and_other_values():
    # _scan_runs reads 0/1 words a cache line and a word at a time and takes a boundary word's
    # transitions from its bits; bytes other than 0 and 1 go byte by byte and are counted.  Rows
    # of every width and offset into the buffer, dense stretches, isolated pixels, other values.
    from contourmesh.fastpath import _scan_runs_py, _words, _words_from

    rng = np.random.default_rng(5)
    for trial in range(60):
        h, w = int(rng.integers(1, 12)), int(rng.integers(1, 200))
        kind = trial % 3
        if kind == 0:  # long stretches: whole words and cache lines of 0 and of 1
            img = (ndimage.uniform_filter1d(rng.random((h, w)), 25, axis=1) > 0.5).astype(np.uint8)
        elif kind == 1:  # a boundary in nearly every word
            img = (rng.random((h, w)) < 0.5).astype(np.uint8)
        else:  # some bytes neither 0 nor 1
            img = (rng.random((h, w)) < 0.6).astype(np.uint8)
            img[rng.random((h, w)) < 0.03] = rng.integers(2, 256)
        for lead in (0, 3, 6, 8, 13):  # the slice starts `lead` bytes into the (aligned) buffer
            buf = np.zeros(lead + h * w + 16, np.uint8)
            buf[lead: lead + h * w] = img.reshape(-1)
            b64, aligned = _words(buf)
            assert aligned
            ry, rx0, rx1, rs, bad = _scan_runs_py(buf, b64, lead, h, w, aligned, np.int64(0))
            got = [(int(y), int(a), int(b)) for y, a, b in zip(ry, rx0, rx1)]
            assert got == _runs_reference(img), (trial, lead)
            assert bad == int(np.count_nonzero(img > 1))
            assert rs[0] == 0 and rs[-1] == len(ry)
            assert [int(np.count_nonzero(ry == y)) for y in range(h)] == np.diff(rs).tolist()
            # the buffer from byte `lead` on (off a word boundary of memory for lead 3): read a word
            # at a time from its first word boundary on (_words_from), the same runs and count as
            # the byte-by-byte scan (not aligned: the form _words left such a slice to)
            part = buf[lead:]
            p64, woff, p_aligned = _words_from(part)
            assert p_aligned and woff == (8 - lead % 8) % 8
            want = _scan_runs_py(part, np.zeros(1, np.uint64), 0, h, w, False, np.int64(0))
            got = _scan_runs_py(part, p64, 0, h, w, True, woff)
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a, b)


def test_outer_contour_and_mlp_match_trace_contours():
    rng = np.random.default_rng(2)
    done = 0
    while done < 40:
        h, w = rng.integers(2, 30, size=2)
        m = ndimage.gaussian_filter(rng.random((h, w)), 1.5) > 0.5
        lab, n = ndimage.label(m, structure=_CROSS)
        if n == 0:
            continue
        comp = lab == 1
        contours, parents = trace_contours(comp)
        outer = [c for c, p in zip(contours, parents) if p == -1]
        assert len(outer) == 1
        assert np.array_equal(outer_jordan_contour(comp), outer[0])
        done += 1
    # the MLPs of every component of a slice, as the full mesher computes them
    for _ in range(30):
        m = ndimage.gaussian_filter(rng.random((40, 40)), 2.0) > 0.5
        lab, n = ndimage.label(m, structure=_CROSS)
        (_, _, _, _), _, _, holes, _ = slice_components(m)
        if n == 0 or holes.any():
            continue
        polys, degenerate = slice_polygons(m)
        for c in range(n):
            sl = ndimage.find_objects(lab)[c]
            ref = _mlp_of_pixels(lab[sl] == c + 1)
            if ref is None:
                assert degenerate[c]
            else:
                assert not degenerate[c]
                assert np.array_equal(polys[c], ref + [sl[1].start, sl[0].start])


def test_contour_from_runs_is_the_walk():
    # a component with one run per row: the contour written from its runs (no pixel read) is the
    # walk's, point for point; with two runs in a row it declines (empty) and the walk is taken
    from contourmesh.fastpath import _trace_outer_py, _trace_runs_py

    rng = np.random.default_rng(5)
    written = declined = 0
    for it in range(600):
        h, w = (int(v) for v in rng.integers(1, 16, size=2))
        m = rng.random((h, w)) < rng.uniform(0.2, 0.9)
        if it % 2 == 0:  # stacked runs, each overlapping the one below
            m[:] = False
            y0 = int(rng.integers(0, h))
            a = int(rng.integers(0, w))
            for y in range(y0, int(rng.integers(y0, h)) + 1):
                b = int(rng.integers(a + 1, w + 1))
                m[y, a:b] = True
                a = int(rng.integers(max(0, a - 3), b))
        lab, n = ndimage.label(m, structure=_CROSS)
        for c in range(1, n + 1):
            comp = lab == c
            ry, rx0, rx1, _ = (np.asarray(v, np.int64) for v in slice_runs(comp)[:4])
            order = np.arange(len(ry), dtype=np.int64)
            got = _trace_runs_py(ry, rx0, rx1, order, np.int64(0), np.int64(len(ry)))
            if len(np.unique(ry)) < len(ry):
                assert len(got) == 0
                declined += 1
                continue
            b8 = np.ascontiguousarray(comp).reshape(-1).view(np.uint8)
            walk = _trace_outer_py(b8, np.int64(0), np.int64(h), np.int64(w), np.int64(0), np.int64(0),
                                   rx0[0] - 1, ry[0] - 1)
            assert np.array_equal(got, walk)
            written += 1
    assert written > 500 and declined > 20


def test_band_faces_match_the_mesher_band():
    from contourmesh.bands import triangulate_band

    rng = np.random.default_rng(3)
    for _ in range(40):
        n, m = rng.integers(3, 90, size=2)
        t1 = np.sort(rng.uniform(0, 2 * np.pi, n))[::1]
        t2 = np.sort(rng.uniform(0, 2 * np.pi, m))
        r1, r2 = rng.uniform(5, 20, 2)
        lo = np.c_[r1 * np.cos(t1), r1 * np.sin(t1), np.zeros(n)]
        hi = np.c_[r2 * np.cos(t2) + rng.normal(0, 1), r2 * np.sin(t2), np.ones(m)]
        f, replaced = band_faces(lo, hi)
        if not replaced:
            assert np.array_equal(f, triangulate_band(lo, hi, "wiederhold"))
        assert f.shape == (n + m, 3)


# ------------------------------------------------------------------------------------------------
# whole meshes
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n, r", [(9, 3.2), (20, 7.3), (33, 14.6), (48, 21.0), (70, 31.5)])
def test_balls(n, r):
    vol = ball(n, r)
    assert_same(fast_volume_to_mesh(vol, threads=1), volume_to_mesh(vol))


def test_balls_off_centre_and_threads():
    rng = np.random.default_rng(4)
    for _ in range(4):
        n = int(rng.integers(16, 40))
        vol = ball(n, rng.uniform(3, n / 2 - 2), c=rng.uniform(n / 2 - 2, n / 2 + 2, 3))
        slow = volume_to_mesh(vol)
        assert_same(fast_volume_to_mesh(vol, threads=1), slow)
        assert_same(fast_volume_to_mesh(vol, threads=2), slow)


def test_random_ellipsoids_and_options():
    rng = np.random.default_rng(5)
    checked = 0
    for it in range(12):
        shape = tuple(int(s) for s in rng.integers(12, 36, 3))
        c = [rng.uniform(s * 0.4, s * 0.6) for s in shape]
        radii = [rng.uniform(2.5, s * 0.45) for s in shape]
        vol = ellipsoid(shape, c, radii)
        kw = dict(spacing=tuple(rng.uniform(0.3, 2.0, 3)), origin=tuple(rng.uniform(-5, 5, 3)),
                  axis=int(rng.integers(0, 3)), caps=("flat", "half")[it % 2])
        slow = volume_to_mesh(vol, **kw)
        fast = fast_volume_to_mesh(vol, **kw, threads=1 + it % 2)
        if fast is None:  # a thin ellipsoid may need an exact join somewhere
            assert slow.meta["exact_joins"] + slow.meta["bridged_joins"] > 0
            continue
        assert_same(fast, slow)
        checked += 1
    assert checked >= 8


def test_several_components_prisms_and_half_caps():
    vol = np.zeros((12, 30, 34), bool)
    vol[1:10] |= ball(0, 5.2, c=(5, 8, 9), shape=(9, 30, 34))[:9]
    vol[2:11] |= ball(0, 4.1, c=(4, 20, 25), shape=(9, 30, 34))[:9]
    vol[6, 2:5, 28:32] = True          # a one-slice component: a prism
    vol[3:5, 25:28, 3:6] = True        # a two-slice box (flat caps on both ends)
    vol[8, 27, 2] = True               # a single voxel: its MLP degenerates to a point
    z = np.cumsum(np.r_[0.0, np.linspace(0.5, 1.5, 11)])
    for caps in ("flat", "half"):
        kw = dict(spacing=(1.0, 0.7, 1.3), z=z, caps=caps)
        slow = volume_to_mesh(vol, **kw)
        assert slow.meta["polygon_fallbacks"] >= 1
        assert_same(fast_volume_to_mesh(vol, **kw, threads=2), slow)


def test_value_kinds():
    vol = ball(24, 9.3)
    slow = volume_to_mesh(vol)
    u8 = vol.astype(np.uint8)
    assert_same(fast_volume_to_mesh(u8, threads=1), volume_to_mesh(u8))
    assert_same(fast_volume_to_mesh(u8, threads=1), slow)
    labels = vol.astype(np.int16) * 7
    assert_same(fast_volume_to_mesh(labels, label=7, threads=1), slow)
    grey = vol * 100.0 + 3.0
    assert_same(fast_volume_to_mesh(grey, threshold=50.0, threads=1), slow)
    assert_same(fast_volume_to_mesh(np.asfortranarray(vol), threads=1), slow)  # not C-contiguous


def test_declines_outside_its_scope():
    vol = ball(24, 9.3)
    # options it does not handle
    assert fast_volume_to_mesh(vol, polygon="dss") is None
    assert fast_volume_to_mesh(vol, triangulation="greedy") is None
    # a hole in a slice (a torus)
    z, y, x = np.ogrid[:16, :32, :32]
    torus = (np.sqrt((x - 15.5) ** 2 + (y - 15.5) ** 2) - 9) ** 2 + (z - 7.5) ** 2 <= 16
    assert fast_volume_to_mesh(torus) is None
    # branching: one component below, two above
    fork = np.zeros((6, 12, 20), bool)
    fork[1:3, 3:9, 2:18] = True
    fork[3:5, 3:9, 2:7] = True
    fork[3:5, 3:9, 12:18] = True
    assert fast_volume_to_mesh(fork) is None
    assert volume_to_mesh(fork).meta["bridged_joins"] > 0
    # invalid input: the full mesher raises the error
    assert fast_volume_to_mesh(vol.astype(np.uint8) * 2) is None
    assert fast_volume_to_mesh(np.zeros((4, 4, 4), bool)) is None
    assert fast_volume_to_mesh(vol, spacing=(1, -1, 1)) is None
    assert fast_volume_to_mesh(vol.astype(float) * np.nan, threshold=0.5) is None
    # slices of 2^31 pixels or more (the packed runs are int32): a zero-strided view, never read
    huge = np.broadcast_to(np.zeros(1, bool), (2, 2 ** 16, 2 ** 15))
    assert fast_volume_to_mesh(huge) is None


def test_shared_data_in_scope_volumes(shared_data):
    from contourmesh.io import read_volume

    checked = 0
    for name in ("cat10.vol", "bunny-64.vol", "cat10b.vol"):
        path = shared_data / "volumes" / "dgtal" / name
        if not path.is_file():
            continue
        vol, spacing, origin = read_volume(path, threshold=0)
        vol = np.pad(vol, 1)
        fast = fast_volume_to_mesh(vol, spacing=spacing, threads=2)
        slow = volume_to_mesh(vol, spacing=spacing)
        if fast is None:
            assert slow.meta["exact_joins"] + slow.meta["bridged_joins"] > 0
            continue
        assert_same(fast, slow)
        checked += 1
    if checked == 0:
        pytest.skip("no shared volume inside the fast path's scope")


# ------------------------------------------------------------------------------------------------
# compile time (issue 5): nothing at import, one non-literal signature per kernel
# ------------------------------------------------------------------------------------------------
def _dispatchers(*modules):
    from numba.core.registry import CPUDispatcher

    return {f"{m.__name__}.{k}": v for m in modules for k, v in vars(m).items() if isinstance(v, CPUDispatcher)}


def test_import_compiles_nothing():
    import subprocess
    import sys

    code = (
        "import contourmesh, contourmesh.fastpath as fp, contourmesh.polygons.mlp as m\n"
        "import contourmesh.bands.wiederhold as w, contourmesh.bands.arclength as a\n"
        "from numba.core.registry import CPUDispatcher\n"
        "ds = {k: v for mod in (fp, m, w, a) for k, v in vars(mod).items() if isinstance(v, CPUDispatcher)}\n"
        "assert len(ds) >= 10, sorted(ds)\n"
        "assert not [k for k, v in ds.items() if v.signatures], [k for k, v in ds.items() if v.signatures]\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)


def _type_cached_entries_again(dispatchers):
    """Compile, uncached, a copy of every Python-callable entry point for each signature that it
    loaded from the on-disk cache.  An entry loaded from the cache brings its callees' code with
    it, so they are never typed in this process and their signatures cannot be checked; typing
    the copy resolves every call in its body through the callees' own dispatchers (which compile,
    or load their own cache entries, for the argument types of each call site)."""
    from numba import njit

    for d in dispatchers:
        if d.targetoptions.get("no_cpython_wrapper"):
            continue
        opts = {k: v for k, v in d.targetoptions.items() if k not in ("cache", "nopython")}
        for sig in list(d.signatures):
            if d._cache_hits.get(sig):
                njit(**opts)(d.py_func).compile(sig)


def test_kernels_are_compiled_without_literal_arguments():
    # a literal argument (a constant 0 or True, or a loop variable that starts at 0) makes numba
    # compile a kernel once more, and so does a call site that passes another array layout; each
    # internal kernel of the fast path, the MLP, the band rules, the optimal band and the DSS gets
    # one signature.  Checked whether this process compiles the entry points or loads them from
    # the cache (then their bodies are typed again, uncached).
    from numba.core import types

    from contourmesh import fastpath
    from contourmesh.bands import arclength, fidelity, optimal, triangulate_band, wiederhold
    from contourmesh.polygons import dss, dss_polygon, mlp, mlp_polygon

    fast_volume_to_mesh(ball(20, 7.3), caps="half", threads=1)
    blob = ball(1, 5.2, c=(0, 7, 6), shape=(1, 15, 14))[0]
    slice_components(blob)
    fastpath.FortranRuns(np.asfortranarray(ball(6, 4.1)), cap=64)[3]  # (the general mesher's Fortran read)
    ry, rx0, rx1, _ = slice_runs(blob)
    fastpath._trace_runs_py(ry, rx0, rx1, np.arange(len(ry)), np.int64(0), np.int64(len(ry)))
    contour = outer_jordan_contour(blob)
    dss_polygon(contour)
    mlp_polygon(contour)
    t = np.linspace(0, 2 * np.pi, 36, endpoint=False)
    lo = np.c_[1.5 * np.cos(t), 6 * np.sin(t), np.zeros(36)]
    hi = np.c_[1.5 * np.cos(t + 0.37), 9 + 6 * np.sin(t + 0.37), np.full(36, 3.0)]
    for method in ("wiederhold", "arclength", "optimal"):
        triangulate_band(lo, hi, method)
    g, replaced = fidelity.faithful_band(lo, hi, triangulate_band(lo, hi, "wiederhold"))
    assert replaced  # the sliding pair takes the Lagrangian band (fidelity._best_edges)

    modules = (fastpath, mlp, wiederhold, arclength, optimal, fidelity, dss)
    ds = _dispatchers(*modules)
    _type_cached_entries_again(ds.values())
    for name, d in ds.items():
        for sig in d.signatures:
            assert not any(isinstance(t, types.Literal) for t in sig), (name, sig)
    # internal kernels (not callable from Python) and the kernels above that only compiled code calls
    once = {k: d for k, d in ds.items() if d.targetoptions.get("no_cpython_wrapper")}
    once.update({k: ds[k] for k in ("contourmesh.bands.optimal._annulus_dp", "contourmesh.polygons.dss._longest_dss")})
    for key in ("contourmesh.polygons.mlp._mlp_kernel", "contourmesh.bands.wiederhold._wiederhold_edges",
                "contourmesh.bands.arclength._arclength_edges", "contourmesh.fastpath._components"):
        assert key in once, sorted(once)
    assert {k: d.signatures for k, d in once.items() if len(d.signatures) != 1} == {}


def _python_mlp_of_pixels(pix):
    """The MLP of a pixel set as the volume mesher made it in Python: outer contour of ``U`` by
    :func:`trace_contours`, then :func:`mlp_polygon`; ``None`` where it encloses no area."""
    from contourmesh.polygons import mlp_polygon

    contours, parents = trace_contours(pix)
    outer = [c for c, p in zip(contours, parents) if p == -1]
    assert len(outer) == 1
    poly = mlp_polygon(outer[0])
    twice = np.dot(poly[:, 0], np.roll(poly[:, 1], -1)) - np.dot(np.roll(poly[:, 0], -1), poly[:, 1])
    return None if len(poly) < 3 or twice == 0 else poly


def test_pixels_mlp_matches_the_python_mlp_on_components_and_hole_sets():
    """The compiled MLP of the volume mesher (4-components, and holes: 8-connected background sets)
    equals the Python construction vertex for vertex, and is None exactly where that has no area."""
    from contourmesh.fastpath import pixels_mlp

    rng = np.random.default_rng(11)
    seen = {"poly": 0, "none": 0}
    for _ in range(60):
        m = rng.random((int(rng.integers(1, 24)), int(rng.integers(1, 24)))) < rng.uniform(0.3, 0.9)
        for struct in (_CROSS, np.ones((3, 3), bool)):  # components, and 8-connected sets like holes
            lab, n = ndimage.label(m, structure=struct)
            for c, sl in enumerate(ndimage.find_objects(lab)):
                pix = lab[sl] == c + 1
                got, ref = pixels_mlp(pix), _python_mlp_of_pixels(pix)
                assert (got is None) == (ref is None)
                if ref is not None:
                    assert np.array_equal(got, ref)
                    seen["poly"] += 1
                else:
                    seen["none"] += 1
                if ref is not None:
                    assert np.array_equal(_mlp_of_pixels(pix), ref.astype(float))
    assert seen["poly"] > 100 and seen["none"] > 10
    with pytest.raises(ValueError, match="non-empty 2D"):
        pixels_mlp(np.zeros((3, 3), bool))


def test_mesher_band_through_the_kernel_equals_the_python_band():
    """volumes._band_faces takes the compiled band where the kernel accepts it: the faces and the
    guard count equal the Python route's (twist_guarded_band, then the arc-length last resort),
    on plain, shifted, twisted and self-crossing ring pairs."""
    from contourmesh.bands import band_is_folded, triangulate_band, twist_guarded_band
    from contourmesh.volumes import _band_faces

    def python_route(lo, hi):
        f, replaced = twist_guarded_band(lo, hi, "wiederhold")
        if band_is_folded(f):
            f, replaced = triangulate_band(lo, hi, "arclength"), replaced + 1
        return f, int(replaced)

    rng = np.random.default_rng(5)
    kinds = set()
    for it in range(60):
        n, m = (int(v) for v in rng.integers(3, 60, size=2))
        t1 = np.sort(rng.uniform(0, 2 * np.pi, n))
        t2 = np.sort(rng.uniform(0, 2 * np.pi, m))
        r1, r2 = rng.uniform(5, 20, 2)
        shift = [0.0, 0.0] if it % 3 else rng.uniform(-15, 15, 2)
        lo = np.c_[r1 * np.cos(t1), r1 * np.sin(t1), np.zeros(n)]
        hi = np.c_[r2 * np.cos(t2) + shift[0], r2 * np.sin(t2) + shift[1], np.ones(m)]
        if it % 5 == 0:
            hi = np.roll(hi[::-1], int(rng.integers(m)), axis=0)  # opposite orientation: twisted
        f, r = _band_faces(lo, hi, "wiederhold")
        g, s = python_route(lo, hi)
        assert np.array_equal(f, g) and r == s
        kinds.add(r > 0)
    assert kinds == {False, True}  # both routes were taken


def _twisting_bars(rng, n):
    """Volumes of an elongated ellipse turning and drifting from slice to slice: bands that the
    twist guard hands back to the full mesher's Python code."""
    for _ in range(n):
        shape = tuple(int(s) for s in rng.integers(10, 30, 3))
        z, y, x = np.ogrid[:shape[0], :shape[1], :shape[2]]
        a, b = rng.uniform(1.5, 3), rng.uniform(4, 9)
        th = rng.uniform(0, np.pi) + z * rng.uniform(0.2, 0.8)
        cx, cy = shape[2] / 2 + z * rng.uniform(-0.8, 0.8), shape[1] / 2
        u = (x - cx) * np.cos(th) + (y - cy) * np.sin(th)
        v = -(x - cx) * np.sin(th) + (y - cy) * np.cos(th)
        vol = (u / b) ** 2 + (v / a) ** 2 <= 1
        vol[0] = vol[-1] = False
        yield vol


def test_slabs_with_handed_back_bands_and_degenerate_rings(monkeypatch):
    # the packed slabs of slices and of slice pairs (1 and 3 threads: one slab, or twelve), with
    # bands redone in Python spliced back in place and slices whose rings are crack contours
    from contourmesh import fastpath

    redone = []
    band_py = fastpath._band_py
    monkeypatch.setattr(fastpath, "_band_py", lambda *a, **k: redone.append(1) or band_py(*a, **k))
    vols = list(_twisting_bars(np.random.default_rng(7), 6))
    checked = 0
    for i in (0, 1, 4):  # 2 and 5: see the test below; 3 is out of the fast path's scope
        for lone in (False, True):
            vol = vols[i].copy()
            vol[3, 1, 1] = lone  # a lone voxel (a degenerate MLP, a prism) in a slice of the bar
            slow = volume_to_mesh(vol)
            for threads in (1, 3):
                assert_same(fast_volume_to_mesh(vol, threads=threads), slow)
                checked += 1
    assert checked == 12
    assert len(redone) >= 4
    assert fast_volume_to_mesh(vols[3], threads=1) is None


def _general_mesh(vol, monkeypatch):
    """The general mesher's mesh of ``vol`` (the fast path switched off)."""
    from contourmesh import volumes

    with monkeypatch.context() as m:
        m.setattr(volumes, "_fast_volume_to_mesh", lambda *a, **k: None)
        return volume_to_mesh(vol)


@pytest.mark.parametrize("i", range(6))
def test_twisting_bars_public_mesh_is_the_general_meshers(i, monkeypatch):
    # on these bars some kept bands of the fast path cross themselves (the fast path alone skips the
    # general mesher's band-by-band test): volume_to_mesh redoes the bands with a face in a crossing
    # pair as the general mesher does, and falls back to it where faces still cross
    from contourmesh import fastpath, volumes

    vol = list(_twisting_bars(np.random.default_rng(7), 6))[i]
    calls = []
    redo = fastpath.redo_self_crossing_bands
    monkeypatch.setattr(volumes, "redo_self_crossing_bands",
                        lambda *a: calls.append(r := redo(*a)) or r)
    got = volume_to_mesh(vol)
    want = _general_mesh(vol, monkeypatch)
    assert np.array_equal(got.vertices, want.vertices) and np.array_equal(got.faces, want.faces)
    for key in ("band_joins", "exact_joins", "polygon_fallbacks", "band_fallbacks", "self_intersections"):
        assert got.meta[key] == want.meta[key], key
    if i == 5:  # a self-crossing band redone: the fast path's mesh is kept, and equals the general one
        assert got.meta.get("fast_path") is True and calls and calls[0] is not None
    if i == 2:  # a crossing that a band redo cannot fix: the general mesher's crossing fallback
        assert got.meta.get("fast_path") is None and want.meta["crossing_fallbacks"] == 1


def test_fast_path_alone_keeps_a_self_crossing_band():
    # fast_volume_to_mesh on its own keeps the kernel's band on bar 5 (whose faces cross); the
    # band table it gives volume_to_mesh finds and redoes exactly that band
    from contourmesh.fastpath import _fast_volume_to_mesh, redo_self_crossing_bands
    from contourmesh.intersect import intersecting_pairs

    vol = list(_twisting_bars(np.random.default_rng(7), 6))[5]
    bands = []
    fast = _fast_volume_to_mesh(vol, threads=1, bands_out=bands)
    pairs = intersecting_pairs(fast.vertices, fast.faces)
    assert len(pairs) > 0
    (table,) = bands
    assert table[:, 1].sum() <= len(fast.faces) and np.all(np.diff(table[:, 0]) > 0)
    F2, fired = redo_self_crossing_bands(fast.vertices, fast.faces, table, pairs)
    assert fired >= 1 and F2.shape == fast.faces.shape
    changed = np.flatnonzero((F2 != fast.faces).any(axis=1))
    i = np.searchsorted(table[:, 0], changed[0], side="right") - 1
    assert table[i, 6] == 1 and np.all(changed < table[i, 0] + table[i, 1]) and np.all(changed >= table[i, 0])
    assert len(intersecting_pairs(fast.vertices, F2)) == 0


def test_shared_positions_bit_map_against_a_set():
    # _slice_polygons_k flags a slice whose MLP vertices share a position (status 2) with a bit
    # map that it leaves zero (before: an int64 stamp image, a stamp id per slice).  _mark_seen
    # and _clear_seen against a set of positions, over point sets of every corner of the range
    # [-1, w] x [-1, h] and many slices through one bit map; then _slice_polygons' flag against
    # np.unique of its rings (random masks: all without shared positions)
    from numba import njit

    from contourmesh.fastpath import _clear_seen, _mark_seen, _scratch, _seen_bits, _slice_polygons, _words

    @njit
    def mark_all(seen, p, starts, w):
        out = np.empty(len(starts) - 1, np.bool_)
        for s in range(len(starts) - 1):
            out[s] = _mark_seen(seen, p[starts[s]:starts[s + 1]].copy(), starts[s + 1] - starts[s], w)
        _clear_seen(seen, p, starts[-1], w)
        return out

    rng = np.random.default_rng(11)
    for trial in range(200):
        h, w = int(rng.integers(1, 40)), int(rng.integers(1, 90))
        seen = _seen_bits(h, w)
        for _ in range(3):  # slices through one map
            n = int(rng.integers(0, 30))
            p = np.c_[rng.integers(-1, w + 1, n), rng.integers(-1, h + 1, n)].astype(np.int64)
            if n and trial % 3 == 0:
                p[-1] = p[0]
            starts = np.unique(np.r_[0, rng.integers(0, n + 1, 3), n]).astype(np.int64)
            got = mark_all(seen, p, starts, np.int64(w))
            marked, want = set(), []
            for a, b in zip(starts[:-1], starts[1:]):
                pts = [tuple(v) for v in p[a:b].tolist()]
                want.append(len(set(pts)) < len(pts) or bool(marked & set(pts)))
                marked |= set(pts)
            assert got.tolist() == want, trial
            assert not seen.any()
    for trial in range(300):
        h, w = int(rng.integers(2, 24)), int(rng.integers(2, 70))
        m = np.ascontiguousarray(rng.random((h, w)) < rng.uniform(0.2, 0.7))
        b8 = m.reshape(-1).view(np.uint8)
        b64, aligned = _words(b8)
        seen, on, bg = _scratch(h, w)
        out = _slice_polygons(b8, b64, 0, h, w, aligned, seen, on, bg)
        assert not seen.any() and not on.any() and not bg.any()
        status, poly, ps, deg = out[6], out[8], out[9], out[10]
        if status != 1:  # (1: a hole, no polygons)
            rings = [poly[ps[c]: ps[c + 1]] for c in range(out[5]) if not deg[c]]
            pts = np.concatenate(rings) if rings else np.zeros((0, 2), np.int64)
            assert (status == 2) == (len(np.unique(pts, axis=0)) != len(pts)), trial


def test_stack_join_is_pair_joins_where_it_decides():
    # _slab_pairs asks _stack_join first for two slices of one component each: where it decides
    # (both slices one run per row and their overlap a stack, or no overlap) its answer must be
    # _pair_joins'; shapes: discs, bars, staircases, rows with gaps and with two runs, overlaps
    # that split, pinch, go round a hole or touch only at a corner
    from numba import njit

    from contourmesh.fastpath import _pair_joins, _stack_join, slice_components

    @njit
    def both(ry, rx0, rx1, rs, lab, n, a0, a1, b1, h):
        ok, pa, pb = _pair_joins(ry[a0:a1], rx0[a0:a1], rx1[a0:a1], rs[0], lab[a0:a1], n[0],
                                 ry[a1:b1], rx0[a1:b1], rx1[a1:b1], rs[1], lab[a1:b1], n[1], h)
        return _stack_join(ry, rx0, rx1, a0, a1, b1), ok, pa, pb

    rng = np.random.default_rng(17)
    decided = {0: 0, 1: 0}
    undecided = 0
    for trial in range(600):
        h, w = int(rng.integers(2, 16)), int(rng.integers(2, 20))
        pair = []
        for _ in range(2):
            kind = rng.integers(4)
            if kind == 0:  # a random stack: one interval per row over consecutive rows
                m = np.zeros((h, w), bool)
                y0 = int(rng.integers(0, h))
                y1 = int(rng.integers(y0 + 1, h + 1))
                x = int(rng.integers(0, w))
                for y in range(y0, y1):
                    a = int(np.clip(x + rng.integers(-2, 3), 0, w - 1))
                    b = int(rng.integers(a + 1, min(w, a + 8) + 1))
                    m[y, a:b] = True
                    x = a
            elif kind == 1:
                m = ball(1, rng.uniform(1, 8), c=(0, rng.uniform(0, h), rng.uniform(0, w)), shape=(1, h, w))[0]
            else:
                m = rng.random((h, w)) < rng.uniform(0.3, 0.9)
            lab, n = ndimage.label(m)
            if n == 0:
                break
            pair.append(lab == 1 + int(rng.integers(n)))  # one 4-component
        if len(pair) < 2:
            continue
        runs, labs, ns = [], [], []
        for m in pair:
            (ry, rx0, rx1, rs), lab, n, _, _ = slice_components(m)
            assert n == 1
            runs.append((ry, rx0, rx1, rs))
            labs.append(lab)
            ns.append(n)
        ry, rx0, rx1 = (np.concatenate([r[i] for r in runs]) for i in range(3))
        rs = np.stack([runs[0][3], runs[1][3]])
        a1, b1 = len(runs[0][0]), len(ry)
        got, ok, pa, pb = both(ry, rx0, rx1, rs, np.concatenate(labs), np.array(ns, np.int64), 0, a1, b1, h)
        if got < 0:
            undecided += 1
            continue
        decided[int(got)] += 1
        assert ok and pa.tolist() == [got - 1] and pb.tolist() == [got - 1], trial
    assert min(decided.values()) > 20 and undecided > 20, (decided, undecided)


@njit(cache=False)
def _stack_candidates_reference(pts, ry, rx0, rx1, order, t0, t1):
    """The fast path's stack candidates in their earlier form (``fastpath._stack_candidates``
    before it walked the contour without its array): read from the points ``pts`` that
    ``_trace_runs`` wrote, each inner corner tested against the four interval ends."""
    mr = t1 - t0
    y0, lo, hi = _stack_intervals(ry, rx0, rx1, order, t0, t1)
    n = len(pts)
    cand = np.empty((3 * n, 2), np.int64)
    kind = np.empty(3 * n, np.int64)
    m = 0
    lastw_x, lastw_y, has_w = 0, 0, False
    for k in range(n):
        kp = k - 1 if k > 0 else n - 1
        kn = k + 1 if k + 1 < n else 0
        px, py = pts[kp, 0], pts[kp, 1]
        cx, cy = pts[k, 0], pts[k, 1]
        nx, ny = pts[kn, 0], pts[kn, 1]
        ix, iy = cx - px, cy - py  # incoming step
        sx, sy = nx - cx, ny - cy  # outgoing step
        turn = ix * sy - iy * sx
        if turn != 0:
            cand[m, 0] = cx
            cand[m, 1] = cy
            kind[m] = 0 if turn > 0 else -1
            m += 1
        lx, ly = -sy, sx
        for j in range(2):
            qx, qy = cx + lx + j * sx, cy + ly + j * sy
            i = qy - 1 - y0  # the rows of the cells below and above q: i and i + 1
            if i < 0 or i >= mr:
                continue
            if lo[i] >= qx or qx >= hi[i] or lo[i + 1] >= qx or qx >= hi[i + 1]:
                continue  # a cell around q is not in U
            if has_w and qx == lastw_x and qy == lastw_y:
                continue
            cand[m, 0] = qx
            cand[m, 1] = qy
            kind[m] = 1
            m += 1
            lastw_x, lastw_y, has_w = qx, qy, True
    return cand, kind, np.int64(m)


def test_stack_candidates_are_the_grid_kernels():
    # the MLP of a stack (one run per row) starts from candidates made from its intervals
    # (_stack_candidates) instead of the grids of _mlp_grid: the same candidates in the same
    # order, and so the same MLP, on random stacks (width-one rows, rows that only touch the next
    # one at a corner of their cells, staircases, discs) and on the slices of a ball; and the same
    # candidates as the earlier form that read the points of _trace_runs's contour
    from numba import njit

    from contourmesh.fastpath import _stack_candidates, _trace_runs
    from contourmesh.polygons.mlp import _mlp_grid, _mlp_pull

    @njit
    def both(ry, rx0, rx1, order, colour, on, bg, w):
        # (int32 runs, as the fast path packs them: one signature per kernel, see above)
        ry, rx0, rx1 = ry.astype(np.int32), rx0.astype(np.int32), rx1.astype(np.int32)
        t0, t1 = np.int64(0), np.int64(len(order))
        cc = _trace_runs(ry, rx0, rx1, order, t0, t1)
        start, cand, kind, m = _stack_candidates(ry, rx0, rx1, order, t0, t1)
        if len(cc) == 0:
            e = np.empty((0, 2), np.int64)
            return m == -1, False, e, np.empty(0, np.int64), e, e, np.empty(0, np.int64), e
        rc, rk, rm = _stack_candidates_reference(cc, ry, rx0, rx1, order, t0, t1)
        same = m == rm and start[0, 0] == cc[0, 0] and start[0, 1] == cc[0, 1]
        if same:
            for i in range(m):
                if cand[i, 0] != rc[i, 0] or cand[i, 1] != rc[i, 1] or kind[i] != rk[i]:
                    same = False
        c1, k1, p1 = _mlp_pull(start, cand, kind, m, colour)
        c2, k2, p2 = _mlp_grid(cc, colour, on, bg, np.int64(-3), np.int64(-3), w + 6)
        return same, True, c1, k1, p1, c2, k2, p2

    rng = np.random.default_rng(23)
    masks = []
    for _ in range(400):
        h, w = int(rng.integers(1, 14)), int(rng.integers(1, 24))
        m = np.zeros((h, w), bool)
        y0 = int(rng.integers(0, h))
        y1 = int(rng.integers(y0 + 1, h + 1))
        x = int(rng.integers(0, w))
        for y in range(y0, y1):
            a = int(np.clip(x + rng.integers(-3, 4), 0, w - 1))
            b = int(rng.integers(a + 1, min(w, a + int(rng.integers(1, 9))) + 1))
            m[y, a:b] = True
            x = a if rng.random() < 0.5 else b - 1
        masks.append(m)
    masks += list(ball(1, 5.3, c=(0, 7, 7), shape=(1, 15, 15))) + list(ball(24, 10.7))
    done = 0
    for m in masks:
        if not m.any():
            continue
        (ry, rx0, rx1, rs), lab, n, _, _ = slice_components(m)
        if n != 1:
            continue
        h, w = m.shape
        on = np.zeros((h + 6) * (w + 6), np.uint8)
        bg = on.copy()
        order = np.arange(len(ry), dtype=np.int64)
        for colour in (1, 0):
            same, ok, c1, k1, p1, c2, k2, p2 = both(ry, rx0, rx1, order, np.int64(colour), on, bg, np.int64(w))
            assert same
            if not ok:
                break
            assert np.array_equal(c1, c2) and np.array_equal(k1, k2) and np.array_equal(p1, p2)
            assert not on.any() and not bg.any()
            done += colour
    assert done > 200


def test_runs_of_long_word_aligned_rows():
    # slices whose rows are whole words (widths multiples of 8, as the 512^3 ball's): the word
    # skip reads eight words at a time with unsigned word indices, then single words, then a
    # boundary word's bits; rows all 0, all 1, one run, runs ending on word and cache-line edges,
    # and bytes other than 0 and 1 among them, against the runs numpy finds
    from contourmesh.fastpath import _scan_runs_py, _words

    rng = np.random.default_rng(11)
    for w in (8, 64, 72, 512, 520):
        h = 24
        img = np.zeros((h, w), np.uint8)
        img[1] = 1
        for y in range(2, h):
            a, b = sorted(int(v) for v in rng.integers(0, w + 1, 2))
            if y % 4 == 0:  # ends on word / cache-line edges
                a, b = (a // 8) * 8, min(w, (b // 64) * 64 + 64 * (y % 8 == 0))
            img[y, a:b] = 1
            if y % 5 == 0:
                img[y, rng.integers(0, w)] = rng.integers(2, 256)
        for k in range(3):  # the slice as the k-th of a volume: its rows start k * h * w bytes in
            buf = np.zeros((k + 1) * h * w, np.uint8)
            buf[k * h * w:] = img.reshape(-1)
            b64, aligned = _words(buf)
            assert aligned
            ry, rx0, rx1, rs, bad = _scan_runs_py(buf, b64, k * h * w, h, w, aligned, np.int64(0))
            got = [(int(y), int(a), int(b)) for y, a, b in zip(ry, rx0, rx1)]
            assert got == _runs_reference(img), (w, k)
            assert bad == int(np.count_nonzero(img > 1))
            assert [int(np.count_nonzero(ry == y)) for y in range(h)] == np.diff(rs).tolist()


def _slab_inputs(vol):
    from contourmesh.fastpath import _scratch, _words

    vol = np.ascontiguousarray(vol, dtype=bool)
    nz, h, w = vol.shape
    b8 = vol.reshape(-1).view(np.uint8)
    b64, aligned = _words(b8)
    seen, on, bg = _scratch(h, w)
    zs = 0.5 + 1.25 * np.arange(nz, dtype=np.float64)
    return (b8, b64, 0, nz, h, w, aligned, seen, on, bg, -2.0, 3.0, 0.75, 1.5, zs)


def test_packs_in_kept_room_are_the_packs_in_new_arrays():
    # _slab_polygons and _slab_pairs write their packs in the room they are handed (a view of it
    # returned) or, where it is too small, in new arrays: the values must be the same bit for bit,
    # whatever the room held before (filled with junk here) and whether it holds all, part or none
    from contourmesh import fastpath
    from contourmesh.fastpath import INITIAL_EDGE_WINDOW, _slab_pairs, _slab_polygons

    rng = np.random.default_rng(23)
    vols = [ball(33, 14.6), ball(20, 7.3, c=(9.3, 10.1, 8.7)), ellipsoid((14, 30, 41), (7, 15, 19), (6, 11, 17))]
    for _ in range(4):  # several components per slice, degenerate MLPs
        vols.append(ndimage.binary_opening(rng.random((int(rng.integers(3, 12)), 24, 37)) < 0.55))
    vols.append(ball(30, 8.2, c=(14, 15, 9), shape=(30, 30, 44)) | ball(30, 7.1, c=(15, 14, 31), shape=(30, 30, 44)))
    ring = ball(24, 10.5) & ~ball(24, 4.2, shape=(24, 24, 24))
    vols.append(ring)  # slices with a hole (status 1)
    for vol in vols:
        args = _slab_inputs(vol)
        nz, h = args[3], args[4]
        none = (np.empty(0, np.int32), np.empty(0, np.int64), np.empty(0, np.float64))
        want = _slab_polygons(*args, *none, False)
        nr, npv = int(want[0][-1, 3]), int(want[0][-1, 5])
        rooms = {
            "all": (nz * (h + 1) + 4 * nr, 2 * npv, 3 * npv),
            "more": (nz * (h + 1) + 4 * (nr + 300), 2 * npv + 200, 3 * npv + 50),
            "part": (nz * (h + 1) + 4 * 64, 2 * 64, 3 * npv - 1),  # runs and vertices grow out of it
            "row starts only": (nz * (h + 1), 0, 0),
        }
        for name, (n32, n64, nf) in rooms.items():
            room = (np.full(n32, -7, np.int32), np.full(n64, -7, np.int64), np.full(nf, np.nan))
            got = _slab_polygons(*args, *room, False)
            for i in range(11):
                assert got[i].dtype == want[i].dtype and np.array_equal(got[i], want[i], equal_nan=True), (name, i)
            if name in ("all", "more") and nr >= 64:
                assert np.shares_memory(got[1], room[0]) and np.shares_memory(got[10], room[2]), name
            assert np.shares_memory(got[5], room[0]) or nz == 0, name
        meta, RY, RX0, RX1, LAB, RS, BBOX, POLY, PST, DEG, XYZ = want
        if meta[:-1, 1:3].any() or DEG.any() or nz < 2:
            continue  # (the pairs are asked for slices of status 0 only)
        soff = meta[:, 5].copy()
        ref = None
        for n in (0, 5, 6 * int(soff[-1]), 6 * int(soff[-1]) + 9):
            pa, pb = np.full(len(DEG), -1, np.int64), np.full(len(DEG), -1, np.int64)
            room = np.full(n, -7, np.int64)
            out = _slab_pairs(0, nz - 1, h, RY, RX0, RX1, LAB, meta, RS, XYZ, soff, PST, INITIAL_EDGE_WINDOW,
                              pa, pb, room)
            out = (out[0], out[1].copy(), out[2].copy(), pa, pb)
            if ref is None:
                ref = out
                continue
            assert out[0] == ref[0]
            for a, b in zip(out[1:], ref[1:]):
                assert np.array_equal(a, b)
    # the room a thread keeps: grown on demand, none above the limit
    assert len(fastpath._room("test", 10, np.int64)) >= 10
    assert fastpath._room("test", 100, np.int64) is fastpath._room("test", 50, np.int64)
    assert len(fastpath._room("test", fastpath._ROOM_BYTES // 8 + 1, np.int64)) == 0


def test_runs_scanned_in_place_are_the_per_slice_packs():
    # _slab_polygons scans each slice's runs and row starts straight into its packed arrays at the
    # slice's offset and has _components write the labels there (the slices once made their own
    # arrays, copied in): the packs must be, bit for bit, the pack of the per-slice route (each
    # slice in new arrays by _slice_polygons, concatenated by _pack_slices), the runs numpy finds
    # and the labels of ndimage.label, whether the room holds all runs, ends inside a slice (that
    # slice scanned again into grown arrays) or holds none
    from contourmesh.fastpath import _pack_slices, _slab_polygons, _slice_polygons

    rng = np.random.default_rng(41)
    vols = [ball(33, 14.6), ball(20, 7.3, c=(9.3, 10.1, 8.7)), ellipsoid((14, 30, 41), (7, 15, 19), (6, 11, 17))]
    for _ in range(4):  # several components per slice, degenerate MLPs
        vols.append(ndimage.binary_opening(rng.random((int(rng.integers(3, 12)), 24, 37)) < 0.55))
    vols.append(rng.random((5, 19, 70)) < 0.5)  # many runs per row
    vols.append(ball(30, 8.2, c=(14, 15, 9), shape=(30, 30, 44)) | ball(30, 7.1, c=(15, 14, 31), shape=(30, 30, 44)))
    vols.append(ball(24, 10.5) & ~ball(24, 4.2, shape=(24, 24, 24)))  # slices with a hole
    for vol in vols:
        args = _slab_inputs(vol)
        b8, b64, _, nz, h, w, aligned, seen, on, bg, ox, oy, dx, dy, zs = args
        outs = [_slice_polygons(b8, b64, k * h * w, h, w, aligned, seen, on, bg) for k in range(nz)]
        ref = list(_pack_slices(outs, h, ox, oy, dx, dy, zs))
        ref[6] = ref[6].reshape(-1)
        nr = int(ref[0][-1, 3])
        # the runs and labels against numpy and scipy
        want_runs, want_lab, want_rs = [], [], []
        for k in range(nz):
            runs = _runs_reference(vol[k].astype(np.uint8))
            labels, _ = ndimage.label(vol[k])
            want_runs += runs
            want_lab += [int(labels[y, a]) - 1 for y, a, _ in runs]
            want_rs.append(np.searchsorted([y for y, _, _ in runs], np.arange(h + 1)))
        got_runs = list(zip(ref[1].tolist(), ref[2].tolist(), ref[3].tolist()))
        assert got_runs == want_runs and ref[4].tolist() == want_lab
        assert np.array_equal(ref[5], np.array(want_rs).reshape(nz, h + 1))
        rooms = {"none": 0, "all": 4 * nr, "ends in the last slice": 4 * max(nr - 3, 64), "64 runs": 4 * 64}
        for name, n in rooms.items():
            r32 = np.full(nz * (h + 1) + n, -7, np.int32)
            got = _slab_polygons(*args, r32, np.empty(0, np.int64), np.empty(0, np.float64), False)
            for i in range(11):
                assert got[i].dtype == ref[i].dtype and np.array_equal(got[i], ref[i]), (name, i)



def test_pass_stopped_at_the_first_slice_out_of_scope():
    # with stop, _slab_polygons ends at the first slice with a hole (or other bytes): that slice's
    # meta row and everything before it are the whole pass's, bit for bit; the later slices are
    # empty (no run, component or vertex, zero row starts), and a volume with no such slice is
    # packed exactly as without stop
    from contourmesh.fastpath import _slab_polygons

    rng = np.random.default_rng(5)
    ring = ball(24, 10.5) & ~ball(24, 4.2, shape=(24, 24, 24))  # holes in the middle slices
    late = ball(24, 10.5) & ~ball(24, 3.2, c=(17.2, 11.6, 12.3), shape=(24, 24, 24))  # holes late
    onebyte = ball(20, 7.3, c=(9.3, 10.1, 8.7)).astype(np.uint8)
    onebyte[12, 9, 9] = 2  # another value: bad
    vols = [ball(33, 14.6), ndimage.binary_opening(rng.random((9, 24, 37)) < 0.55), ring, late, onebyte]
    stopped = 0
    for vol in vols:
        args = _slab_inputs(vol)
        nz, h = args[3], args[4]
        if vol.dtype == np.uint8:  # (its own bytes, the 2 among them)
            from contourmesh.fastpath import _words

            b8 = np.ascontiguousarray(vol).reshape(-1)
            args = (b8, *_words(b8)[:1], *args[2:6], _words(b8)[1], *args[7:])
        none = (np.empty(0, np.int32), np.empty(0, np.int64), np.empty(0, np.float64))
        want = _slab_polygons(*args, *none, False)
        room = (np.full(nz * (h + 1) + 4 * 64, -7, np.int32), np.full(0, -7, np.int64), np.full(0, np.nan))
        for rooms in (none, room):
            got = _slab_polygons(*args, *rooms, True)
            out = np.flatnonzero(want[0][:-1, 1:3].any(axis=1))
            if not len(out):
                for i in range(11):
                    assert got[i].dtype == want[i].dtype and np.array_equal(got[i], want[i]), i
                continue
            stopped += 1
            k = int(out[0])
            meta, wmeta = got[0], want[0]
            assert np.array_equal(meta[: k + 1], wmeta[: k + 1])
            assert meta[k, 1] == wmeta[k, 1] and meta[k, 2] == wmeta[k, 2] and (meta[k, 1] or meta[k, 2])
            assert not meta[k + 1: nz, :3].any()
            assert (meta[k + 1:, 3:] == meta[k + 1, 3:]).all()  # (nothing after slice k)
            nr, nc, npv = (int(x) for x in meta[-1, 3:])
            assert (nr, nc, npv) == tuple(int(x) for x in wmeta[k + 1, 3:])
            assert np.array_equal(got[5][: k + 1], want[5][: k + 1]) and not got[5][k + 1:].any()
            for i in (1, 2, 3, 4):
                assert np.array_equal(got[i], want[i][:nr]), i
            assert np.array_equal(got[6], want[6][: 4 * nc]) and np.array_equal(got[9], want[9][:nc])
            assert np.array_equal(got[7], want[7][:npv]) and np.array_equal(got[10], want[10][:npv])
            assert np.array_equal(got[8][: nc + k + 1], want[8][: nc + k + 1]) and not got[8][nc + k + 1:].any()
    assert stopped == 6  # (the ring, the late holes and the other byte, each in both rooms)


def test_meshes_with_kept_room_from_other_volumes():
    # the fast path keeps its room between calls, in the calling thread: the whole volume's on one
    # thread, one per slab (handed to the workers) and the joined packs' on several; a mesh after
    # meshes of larger and smaller volumes (rooms filled with their packs, slabs cut elsewhere) is
    # the mesh made with fresh rooms, on one, two and three threads
    import threading

    from contourmesh import fastpath

    vols = [ball(48, 21.0), ball(20, 7.3), ellipsoid((26, 31, 40), (13, 15, 20), (9, 12, 16)), ball(33, 14.6),
            ball(5, 2.2, shape=(5, 9, 9))]
    fresh, errors = {}, []

    def alone():
        try:
            fresh.update({i: fast_volume_to_mesh(v, threads=1) for i, v in enumerate(vols)})  # room kept in turn
            for i, v in enumerate(vols):
                fastpath._TLS.__dict__.pop("rooms", None)
                assert_same(fast_volume_to_mesh(v, threads=1), fresh[i])
            for th in (2, 3):
                for i, v in enumerate(vols):
                    fastpath._TLS.__dict__.pop("rooms", None)
                    assert_same(fast_volume_to_mesh(v, threads=th), fresh[i])
        except BaseException as e:  # (handed to the test's thread)
            errors.append(e)

    t = threading.Thread(target=alone)  # (a thread of its own: its room starts empty)
    t.start()
    t.join()
    if errors:
        raise errors[0]
    assert len(fresh) == len(vols)
    for _ in range(2):
        for i, v in enumerate(vols):
            for th in (1, 2, 3, 2):
                assert_same(fast_volume_to_mesh(v, threads=th), fresh[i])
    # the slabs' rooms are the calling thread's (keyed by the slab's index), not the workers'
    rooms = fastpath._rooms()
    assert {("runs", i) for i in range(8)} <= set(rooms) and {("faces", i) for i in range(8)} <= set(rooms)


def test_slab_rooms_of_two_calling_threads_and_past_their_limit(monkeypatch):
    # two threads meshing at once on two worker threads each (one pool) keep their own rooms: the
    # meshes are the one-thread meshes; and with the slabs' rooms too small for any slab (their
    # kernels make new arrays) or the joined rooms past their limit, the meshes are the same
    import threading

    from contourmesh import fastpath

    vols = [ball(48, 21.0), ellipsoid((26, 31, 40), (13, 15, 20), (9, 12, 16)), ball(33, 14.6)]
    want = [fast_volume_to_mesh(v, threads=1) for v in vols]
    errors = []

    def run(order):
        try:
            for _ in range(3):
                for i in order:
                    assert_same(fast_volume_to_mesh(vols[i], threads=2), want[i])
        except BaseException as e:  # (handed to the test's thread)
            errors.append(e)

    ts = [threading.Thread(target=run, args=(o,)) for o in ([0, 1, 2], [2, 0, 1])]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    if errors:
        raise errors[0]
    for slab_cap, cap in ((64, fastpath._ROOM_BYTES), (fastpath._SLAB_ROOM_BYTES, 64), (64, 64)):
        monkeypatch.setattr(fastpath, "_SLAB_ROOM_BYTES", slab_cap)
        monkeypatch.setattr(fastpath, "_ROOM_BYTES", cap)
        for i, v in enumerate(vols):
            assert_same(fast_volume_to_mesh(v, threads=2), want[i])


def test_packs_joined_in_kept_room_are_the_packs_joined_anew():
    # _join_packs with the calling thread's rooms writes the joined packs into them: the arrays
    # are those joined into new arrays, bit for bit, on one thread and on two, with rooms larger
    # than the packs (filled with other values), exactly their size or too small to be kept
    from contourmesh import fastpath
    from contourmesh.fastpath import _join_packs, _slab_polygons

    rng = np.random.default_rng(7)
    vols = [ball(33, 14.6), ellipsoid((26, 31, 40), (13, 15, 20), (9, 12, 16)),
            ndimage.binary_opening(rng.random((9, 24, 37)) < 0.55)]
    for vol in vols:
        args = _slab_inputs(vol)
        b8, b64, _, nz, h, w, aligned, seen, on, bg, ox, oy, dx, dy, zs = args
        e32, e64, ef = np.empty(0, np.int32), np.empty(0, np.int64), np.empty(0, np.float64)
        bounds = np.linspace(0, nz, 5).astype(int)
        packs = [_slab_polygons(b8, b64, int(a) * h * w, int(b - a), h, w, aligned, seen, on, bg, ox, oy, dx, dy,
                                zs[a:b], e32, e64, ef, False) for a, b in zip(bounds[:-1], bounds[1:])]
        ref = _join_packs(packs, 1)
        nr, npv = int(ref[0][-1, 3]), int(ref[0][-1, 5])
        for extra in (0, 50):
            for threads in (1, 2):
                rooms = {"runs": np.full(nz * (h + 1) + 4 * nr + extra, -7, np.int32),
                         "poly": np.full(2 * npv + extra, -7, np.int64), "xyz": np.full(3 * npv + extra, -7.0)}
                got = _join_packs(packs, threads, rooms)
                assert np.shares_memory(got[1], rooms["runs"]) and np.shares_memory(got[10], rooms["xyz"])
                for a, b in zip(got, ref):
                    assert a.dtype == b.dtype and np.array_equal(a, b)
        old = fastpath._ROOM_BYTES
        try:
            fastpath._ROOM_BYTES = 8
            rooms = {}
            got = _join_packs(packs, 2, rooms)
            assert not rooms
            for a, b in zip(got, ref):
                assert a.dtype == b.dtype and np.array_equal(a, b)
        finally:
            fastpath._ROOM_BYTES = old