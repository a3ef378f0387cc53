"""Volume -> closed mesh + surface area: ``contourmesh.mesh`` against marching-cubes-family peers.

Everything from the numpy array to the area is timed, for every method, on the same arrays in
one process, in alternating order (the method order rotates every repetition).  Peak memory is
the resident set size of a fresh subprocess per (method, input) (``ru_maxrss``), reported with
the RSS just before the call (the input volume already resident).

    python benchmarks/volume_speed.py                   # 256^3 and 512^3 balls, 1 and all threads
    python benchmarks/volume_speed.py --sweep           # seconds against r = 50 .. 400 (log-log slope)
    python benchmarks/volume_speed.py --cold            # first call in a fresh process, empty numba cache
    python benchmarks/volume_speed.py --cold --inputs "" --cold-cases fast,general,band   # only that
    python benchmarks/volume_speed.py --real            # lobster (> 60), liver labels x2
    python benchmarks/volume_speed.py --inputs rot-bunny-256,rot-armadillo-512   # rotated real meshes
    python benchmarks/volume_speed.py --sweep-rotated bunny,armadillo   # 128, 256, 512 across (slope)
    python benchmarks/volume_speed.py --all --out comparisons/speed

Thread counts are set explicitly: ``threads=1`` (everyone single-threaded) and ``threads=all``
(contourmesh's thread pool and ``vtkSMPTools`` on every core; scikit-image is single-threaded).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

METHODS = ["contourmesh", "skimage-mc", "vtk-flyingedges", "vtk-discreteflyingedges", "vtk-surfacenets", "zmesh",
           "serra-mesh"]
REAL = ["lobster", "liver", "liver-x2", "bunny-128", "Al.100"]


# ------------------------------------------------------------------------------------------------
# inputs
# ------------------------------------------------------------------------------------------------
def ball_volume(n: int, r: float) -> np.ndarray:
    """A centred binary ball, built slice by slice (no float temporaries the size of the volume)."""
    c = (n - 1) / 2
    vol = np.zeros((n, n, n), dtype=bool)
    yy, xx = np.ogrid[:n, :n]
    d2 = (xx - c) ** 2 + (yy - c) ** 2
    for k in range(n):
        rr = r * r - (k - c) ** 2
        if rr >= 0:
            vol[k] = d2 <= rr
    return vol


def real_volume(name: str):
    data = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))
    if name == "lobster":
        from contourmesh.io import read_volume

        vol, sp, _ = read_volume(data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
        return np.pad(vol, 1), tuple(sp)
    if name in ("bunny-128", "Al.100"):
        from contourmesh.io import read_volume

        vol, sp, _ = read_volume(data / "volumes" / "dgtal" / f"{name}.vol", threshold=0)
        return np.pad(vol, 1), tuple(sp)
    if name in ("liver", "liver-x2"):
        z = np.load(data / "volumes" / "cgogn" / "liver.npz")
        vol = z["volume"] if "volume" in z.files else z["mask"]
        vol = np.asarray(vol) > 0  # every label: one object
        if name == "liver-x2":
            vol = vol.repeat(2, 0).repeat(2, 1).repeat(2, 2)  # nearest-neighbour upsampling x2
        return np.pad(vol, 1), (1.0, 1.0, 1.0)
    raise ValueError(name)


#: Closed meshes of the shared data (``meshes/``) that ``rot-NAME-N`` inputs voxelize.
ROTATED_MESHES = {
    "bunny": "libigl-tutorial-data/bunny.off", "armadillo": "libigl-tutorial-data/armadillo.obj",
    "fertility": "libigl-tutorial-data/fertility.off", "elephant": "libigl-tutorial-data/elephant.obj",
    "socket": "cgogn/socket.off", "lion": "dgtal/lion-tri.obj",
}
#: The seed of every rotated input's rotation (one rotation per mesh, the same at every N).
ROTATION_SEED = 20261204


def rotated_volume(name: str, n: int):
    """A closed mesh of the shared data, rotated by a fixed random rotation (seeded by
    :data:`ROTATION_SEED` and the name, so the same at every ``n``) and voxelized (Gauss, by ray
    parity: :func:`contourmesh.voxelize_mesh`) at ``n`` voxels across its largest extent."""
    import zlib

    from scipy.spatial.transform import Rotation

    from contourmesh.compare.inputs import load_closed_mesh
    from contourmesh.voxelize import voxelize_mesh

    if name not in ROTATED_MESHES:
        raise ValueError(f"unknown rotated mesh {name!r}; expected one of {sorted(ROTATED_MESHES)}")
    data = Path(os.environ.get("CONTOURMESH_DATA", ROOT.parent / "shared" / "data"))
    v, f = load_closed_mesh(data / "meshes" / ROTATED_MESHES[name])
    rng = np.random.default_rng([ROTATION_SEED, zlib.crc32(name.encode())])
    rot = Rotation.random(random_state=rng).as_matrix()
    vol, sp, _ = voxelize_mesh(v @ rot.T, f, int(n))
    return vol, tuple(float(x) for x in sp)


def make_input(spec: str):
    """``ball-N-R``, ``rot-NAME-N`` (:func:`rotated_volume`) or a real-data name -> (bool volume
    [z, y, x], spacing)."""
    if spec.startswith("ball-"):
        _, n, r = spec.split("-")
        return ball_volume(int(n), float(r)), (1.0, 1.0, 1.0)
    if spec.startswith("rot-"):
        name, n = spec[4:].rsplit("-", 1)
        return rotated_volume(name, int(n))
    return real_volume(spec)


# ------------------------------------------------------------------------------------------------
# methods: volume -> (area, triangles)
# ------------------------------------------------------------------------------------------------
def ours(vol, spacing, threads):
    """contourmesh as a user calls it: ``contourmesh.mesh(volume, spacing=...)``, the whole public
    path (the compiled fast path or the general mesher, the crossing-face test and repair that every
    returned mesh gets, and the diagnostics in ``meta``), with ``threads`` worker threads
    (``CONTOURMESH_THREADS``).  Until 2026-12-04 the balls were timed on the fast path's kernels
    alone (``fastpath.fast_volume_to_mesh``), without the crossing test: about 0.7 of this."""
    import contourmesh

    os.environ["CONTOURMESH_THREADS"] = str(int(threads))
    return contourmesh.mesh(vol, spacing=tuple(float(s) for s in spacing), progress=False)


def _tri_area(pts, tri):
    a = pts[tri[:, 1]] - pts[tri[:, 0]]
    b = pts[tri[:, 2]] - pts[tri[:, 0]]
    return float(0.5 * np.linalg.norm(np.cross(a, b), axis=1).sum())


def _vtk_image(vol, spacing):
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkImageData

    img = vtkImageData()
    img.SetDimensions(vol.shape[2], vol.shape[1], vol.shape[0])
    img.SetSpacing(spacing[2], spacing[1], spacing[0])
    arr = numpy_support.numpy_to_vtk(vol.reshape(-1).view(np.uint8), deep=False)
    img.GetPointData().SetScalars(arr)
    return img, arr


def _vtk_area(poly):
    from vtkmodules.util import numpy_support

    pts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    conn = numpy_support.vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    return _tri_area(pts, conn), len(conn)


def run_method(name, vol, spacing, threads):
    if name == "contourmesh":
        m = ours(vol, spacing, threads)
        return m.area, len(m.faces), bool(m.meta.get("fast_path", False))
    if name == "zmesh":  # multi-label marching cubes (connectomics); the volume as [x, y, z]
        import zmesh

        mesher = zmesh.Mesher(tuple(spacing[::-1]))
        mesher.mesh(np.asfortranarray(vol.view(np.uint8).T), close=True)
        got = mesher.get(1, normals=False)
        return _tri_area(np.asarray(got.vertices, np.float64), np.asarray(got.faces)), len(got.faces), None
    if name == "serra-mesh":  # multi-material dual contouring, no smoothing
        import serra_mesh

        mesher = serra_mesh.Mesher(tuple(spacing), axis_order="ZYX", threads=threads)
        mesher.mesh(vol.view(np.uint8), close=True)
        got = mesher.get(1)
        return _tri_area(np.asarray(got.vertices, np.float64), np.asarray(got.faces)), len(got.faces), None
    if name == "skimage-mc":
        from skimage import measure

        v, f, _, _ = measure.marching_cubes(vol.view(np.uint8), 0.5, spacing=spacing)
        return measure.mesh_surface_area(v, f), len(f), None
    from vtkmodules.vtkCommonCore import vtkSMPTools

    vtkSMPTools.Initialize(threads)
    img, _keep = _vtk_image(vol, spacing)
    if name == "vtk-flyingedges":
        from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

        alg = vtkFlyingEdges3D()
        alg.SetValue(0, 0.5)
    elif name == "vtk-discreteflyingedges":
        from vtkmodules.vtkFiltersGeneral import vtkDiscreteFlyingEdges3D

        alg = vtkDiscreteFlyingEdges3D()
        alg.SetValue(0, 1)
    elif name == "vtk-surfacenets":
        from vtkmodules.vtkFiltersCore import vtkSurfaceNets3D

        alg = vtkSurfaceNets3D()
        alg.SetValue(0, 1)
        alg.SetOutputMeshTypeToTriangles()
    else:
        raise ValueError(name)
    if hasattr(alg, "ComputeNormalsOff"):
        alg.ComputeNormalsOff()
        alg.ComputeGradientsOff()
        alg.ComputeScalarsOff()
    alg.SetInputData(img)
    alg.Update()
    area, ntri = _vtk_area(alg.GetOutput())
    return area, ntri, None


def warm_up():
    """Load numba's cache and VTK's/skimage's modules before timing."""
    small = ball_volume(24, 9.0)
    for name in METHODS:
        run_method(name, small, (1.0, 1.0, 1.0), 1)


# ------------------------------------------------------------------------------------------------
# measurements
# ------------------------------------------------------------------------------------------------
def time_inputs(specs, repeat, threads):
    rows = []
    for spec in specs:
        vol, sp = make_input(spec)
        # one untimed call of contourmesh per input: the warm-up's ball takes the compiled fast path
        # only, so the general mesher's kernels would load from numba's cache (or compile, after an
        # edit) inside the first timed call of a real input (a lobster call once timed 87 s)
        run_method("contourmesh", vol, sp, threads)
        res = {m: [] for m in METHODS}
        info = {}
        cnz = []
        for rep in range(repeat):
            order = METHODS[rep % len(METHODS):] + METHODS[: rep % len(METHODS)]
            for name in order:
                t = time.perf_counter()
                area, ntri, fast = run_method(name, vol, sp, threads)
                res[name].append(time.perf_counter() - t)
                info[name] = (area, ntri, fast)
            t = time.perf_counter()
            np.count_nonzero(vol)
            cnz.append(time.perf_counter() - t)
        base = float(np.median(res["contourmesh"]))
        floor = float(np.median(cnz))
        rows.append({"method": "count_nonzero (one read pass)", "input": spec, "shape": "x".join(map(str, vol.shape)),
                     "threads": threads, "median_s": floor, "min_s": min(cnz), "max_s": max(cnz),
                     "GB_per_s": vol.nbytes / floor / 1e9, "ratio_to_contourmesh": floor / base})
        for name in METHODS:
            ts = res[name]
            area, ntri, fast = info[name]
            rows.append({"method": name, "input": spec, "shape": "x".join(map(str, vol.shape)), "threads": threads,
                         "median_s": float(np.median(ts)), "min_s": min(ts), "max_s": max(ts),
                         "triangles": ntri, "area": area, "fast_path": fast,
                         "ratio_to_contourmesh": float(np.median(ts)) / base,
                         "x_count_nonzero": float(np.median(ts)) / floor})
        print_rows(rows[-len(METHODS) - 1:])
        del vol
    return rows


def peak_memory(spec, name, threads):
    """Peak RSS (MiB) of a fresh process while it runs one method once, and its RSS before the call
    (input volume resident, modules imported, numba cache loaded).  Linux: the high-water mark
    ``VmHWM`` is reset through ``/proc/self/clear_refs`` just before the call."""
    code = (
        "import sys, json; sys.path.insert(0, %r); sys.path.insert(0, %r);"
        "import volume_speed as vs; vol, sp = vs.make_input(%r);"
        "vs.run_method(%r, vs.ball_volume(16, 6.0), (1.0, 1.0, 1.0), %d);"
        "st = lambda key: [int(l.split()[1]) / 1024 for l in open('/proc/self/status') if l.startswith(key)][0];"
        "rss0 = st('VmRSS:'); open('/proc/self/clear_refs', 'w').write('5');"
        "r = vs.run_method(%r, vol, sp, %d);"
        "print(json.dumps({'rss_before': rss0, 'peak': st('VmHWM:'), 'vol_mib': vol.nbytes / 2**20}))"
    ) % (str(ROOT / "src"), str(Path(__file__).parent), spec, name, threads, name, threads)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800)
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1] if out.stderr else "failed"}
    return json.loads(out.stdout.strip().splitlines()[-1])


#: First calls timed by ``--cold``: ``contourmesh.mesh`` on a ball (the fast path), and on a small
#: random volume with holes and branching (the general mesher, where most real inputs go, then
#: the crossing-face check), plain and with ``refine="band"``.
COLD_CASES = {
    "fast": "import volume_speed as vs; v = vs.ball_volume(64, 25.0)\n"
            "f = lambda: contourmesh.mesh(v)",
    "general": "v = np.pad(np.random.default_rng(1).random((12, 14, 13)) < 0.35, 1)\n"
               "f = lambda: contourmesh.mesh(v)",
    "band": "v = np.pad(np.random.default_rng(1).random((12, 14, 13)) < 0.35, 1)\n"
            "f = lambda: contourmesh.mesh(v, refine='band')",
}


def cold_start(cases=tuple(COLD_CASES)):
    """First call in a fresh process with an empty numba cache (compilation included), then in a
    second process on the cache that the first one left, and the import of contourmesh (which
    must not compile anything); wall and CPU seconds (``time.process_time`` of the process)."""
    template = (
        "import time, sys\nsys.path.insert(0, %r); sys.path.insert(0, %r)\n"
        "t = time.perf_counter(); c = time.process_time()\nimport contourmesh\nfrom contourmesh import fastpath\n"
        "t1 = time.perf_counter(); c1 = time.process_time()\nimport numpy as np\n%s\n"
        "t2 = time.perf_counter(); c2 = time.process_time()\nm = f()\n"
        "t3 = time.perf_counter(); c3 = time.process_time()\nm = f()\nt4 = time.perf_counter()\n"
        "print(t1 - t, c1 - c, t3 - t2, c3 - c2, t4 - t3)\n"
    )
    res = {}
    for case in cases:
        code = template % (str(ROOT / "src"), str(Path(__file__).parent), COLD_CASES[case])
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
            for label in ("empty cache", "warm cache"):
                out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                                     timeout=1800, check=True)
                imp, imp_cpu, first, first_cpu, second = (float(x) for x in out.stdout.split())
                res[f"{case}, {label}"] = {"import_s": imp, "import_cpu_s": imp_cpu, "first_call_s": first,
                                           "first_call_cpu_s": first_cpu, "second_call_s": second}
                print("cold start", case, label, res[f"{case}, {label}"], flush=True)
    return res


def _all_kernels(x1, y1, x2, y2, o1, o2):
    from numba import njit

    from contourmesh.bands.wiederhold import _edges_to_faces, wiederhold_edges

    global _ALL_KERNELS
    if "_ALL_KERNELS" not in globals():
        @njit(cache=False)
        def run(x1, y1, x2, y2, o1, o2):
            tot = 0
            for b in range(o1.shape[0] - 1):
                n, m = o1[b + 1] - o1[b], o2[b + 1] - o2[b]
                e = wiederhold_edges(x1[o1[b]:o1[b + 1]], y1[o1[b]:o1[b + 1]], x2[o2[b]:o2[b + 1]], y2[o2[b]:o2[b + 1]])
                tot += _edges_to_faces(e, n, m, 0, 0, n, False).shape[0]
            return tot

        _ALL_KERNELS = run
    return _ALL_KERNELS(x1, y1, x2, y2, o1, o2)


def kernel_rate():
    """Polygon vertices per second of the paper's triangulation kernel alone (section 3.4 edge
    sequence + faces), and of the full band (initial edge, kernel, twist guard), on the rings of
    the 512^3 ball."""
    from contourmesh import fastpath as fp

    vol = ball_volume(512, 250)
    rings = []
    for k in range(512):
        if vol[k].any():
            polys, _ = fp.slice_polygons(vol[k])
            p = polys[0].astype(np.float64)
            rings.append(np.c_[p, np.full(len(p), float(k))])
    pairs = [(rings[i], rings[i + 1]) if len(rings[i]) <= len(rings[i + 1]) else (rings[i + 1], rings[i])
             for i in range(len(rings) - 1)]
    n1 = np.array([len(a) for a, _ in pairs])
    n2 = np.array([len(b) for _, b in pairs])
    o1 = np.r_[0, np.cumsum(n1)]
    o2 = np.r_[0, np.cumsum(n2)]
    c1 = np.concatenate([a for a, _ in pairs])
    c2 = np.concatenate([b for _, b in pairs])
    x1, y1 = np.ascontiguousarray(c1[:, 0]), np.ascontiguousarray(c1[:, 1])
    x2, y2 = np.ascontiguousarray(c2[:, 0]), np.ascontiguousarray(c2[:, 1])
    nverts = int(n1.sum() + n2.sum())
    _all_kernels(x1, y1, x2, y2, o1, o2)
    best_k = best_b = 1e9
    for _ in range(5):
        t = time.perf_counter()
        _all_kernels(x1, y1, x2, y2, o1, o2)
        best_k = min(best_k, time.perf_counter() - t)
        t = time.perf_counter()
        for a, b in pairs:
            fp._band(a, b, 32)
        best_b = min(best_b, time.perf_counter() - t)
    return {"bands": len(pairs), "polygon_vertices": nverts, "kernel_s": best_k, "kernel_vertices_per_s": nverts / best_k,
            "band_with_guard_s": best_b, "band_vertices_per_s": nverts / best_b}


def boundary_voxels(vol):
    """Object voxels with a 6-neighbour in the background, counted slice by slice."""
    tot = 0
    pad = np.zeros(vol.shape[1:], bool)
    for k in range(vol.shape[0]):
        s = vol[k]
        if not s.any():
            continue
        inner = s.copy()
        inner &= vol[k - 1] if k > 0 else pad
        inner &= vol[k + 1] if k + 1 < vol.shape[0] else pad
        inner[1:, :] &= s[:-1, :]
        inner[:-1, :] &= s[1:, :]
        inner[:, 1:] &= s[:, :-1]
        inner[:, :-1] &= s[:, 1:]
        inner[0, :] = inner[-1, :] = False
        inner[:, 0] = inner[:, -1] = False
        tot += int(np.count_nonzero(s) - np.count_nonzero(inner))
    return tot


def sweep(radii, repeat, threads):
    rows = []
    for r in radii:
        n = int(2 * r + 12)
        vol = ball_volume(n, r)
        ts = []
        for _ in range(repeat):
            t = time.perf_counter()
            m = ours(vol, (1.0, 1.0, 1.0), threads)
            ts.append(time.perf_counter() - t)
        t = time.perf_counter()
        np.count_nonzero(vol)
        cnz = time.perf_counter() - t
        rows.append({"r": r, "n": n, "median_s": float(np.median(ts)), "min_s": min(ts), "max_s": max(ts),
                     "count_nonzero_s": cnz, "vertices": len(m.vertices), "triangles": len(m.faces),
                     "boundary_voxels": boundary_voxels(vol)})
        print(rows[-1], flush=True)
        del vol
    lr = np.log([row["r"] for row in rows])
    lt = np.log([row["median_s"] for row in rows])
    slope = float(np.polyfit(lr, lt, 1)[0])
    return rows, slope


def loglog_slope(rows, x="boundary_voxels", y="median_s") -> float:
    """The least-squares slope of log ``y`` against log ``x`` over ``rows``."""
    return float(np.polyfit(np.log([r[x] for r in rows]), np.log([r[y] for r in rows]), 1)[0])


def sweep_rotated(names, sizes, repeat, threads):
    """``contourmesh.mesh`` on each rotated mesh (:func:`rotated_volume`) at each size: rows with
    the median seconds, ``np.count_nonzero``'s seconds and the boundary voxels, and per mesh the
    log-log slope of seconds against boundary voxels (1 = linear in the surface)."""
    rows, slopes = [], {}
    for name in names:
        mine = []
        for n in sizes:
            vol, sp = rotated_volume(name, n)
            ts = []
            for _ in range(repeat):
                t = time.perf_counter()
                m = ours(vol, sp, threads)
                ts.append(time.perf_counter() - t)
            t = time.perf_counter()
            np.count_nonzero(vol)
            cnz = time.perf_counter() - t
            mine.append({"mesh": name, "n": n, "shape": "x".join(map(str, vol.shape)), "median_s": float(np.median(ts)),
                         "min_s": min(ts), "max_s": max(ts), "count_nonzero_s": cnz, "triangles": len(m.faces),
                         "boundary_voxels": boundary_voxels(vol), "fast_path": bool(m.meta.get("fast_path", False))})
            print(mine[-1], flush=True)
            del vol
        slopes[name] = loglog_slope(mine)
        print(f"{name}: log-log slope of seconds against boundary voxels {slopes[name]:.2f}", flush=True)
        rows += mine
    return rows, slopes


# ------------------------------------------------------------------------------------------------
# output
# ------------------------------------------------------------------------------------------------
def print_rows(rows):
    for r in rows:
        extra = f"  {r['GB_per_s']:.1f} GB/s" if "GB_per_s" in r else \
            f"  tri={r['triangles']:>8}  x{r['ratio_to_contourmesh']:.2f} of contourmesh"
        print(f"{r['method']:<30} {r['input']:<14} t={r['threads']}  median {r['median_s']:.3f} s "
              f"[{r['min_s']:.3f}-{r['max_s']:.3f}]{extra}", flush=True)


def write_table(rows, mem, out: Path):
    out.mkdir(parents=True, exist_ok=True)
    keys = ["input", "shape", "threads", "method", "median_s", "min_s", "max_s", "peak_rss_mib", "rss_before_mib",
            "triangles", "area", "ratio_to_contourmesh", "x_count_nonzero", "fast_path"]
    for r in rows:
        m = mem.get((r["input"], r["method"], r["threads"]), {})
        r["peak_rss_mib"] = m.get("peak")
        r["rss_before_mib"] = m.get("rss_before")
    import io

    from contourmesh.meshes import atomic_write

    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    atomic_write(out / "volume_speed.csv", buf.getvalue().encode())
    lines = ["| input | threads | method | median s | min-max s | peak RSS MiB (before) | triangles | x contourmesh | x count_nonzero |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        pk = "" if r.get("peak_rss_mib") is None else f"{r['peak_rss_mib']:.0f} ({r['rss_before_mib']:.0f})"
        lines.append(
            f"| {r['input']} ({r['shape']}) | {r['threads']} | {r['method']} | {r['median_s']:.3f} | "
            f"{r['min_s']:.3f}-{r['max_s']:.3f} | {pk} | {r.get('triangles', '')} | "
            f"{r['ratio_to_contourmesh']:.3f} | {r.get('x_count_nonzero', 1.0):.1f} |")
    atomic_write(out / "volume_speed.md", ("\n".join(lines) + "\n").encode())


def plot(rows, sweep_rows, slope, out: Path, rot_rows=()):
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    two = bool(sweep_rows or rot_rows)
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(12 if two else 7, 5.2), squeeze=False)
    ax = axes[0, 0]
    inputs = sorted({(r["input"], r["threads"]) for r in rows if r["method"] in METHODS})
    width = 0.8 / len(METHODS)
    for i, m in enumerate(METHODS):
        vals = [next((r["median_s"] for r in rows if r["method"] == m and (r["input"], r["threads"]) == key), np.nan)
                for key in inputs]
        ax.bar(np.arange(len(inputs)) + i * width, vals, width, label=m)
    ax.set_xticks(np.arange(len(inputs)) + 0.4 - width / 2)
    ax.set_xticklabels([f"{a}\n{t} thr" for a, t in inputs], fontsize=7, rotation=20, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel("seconds (array -> mesh + area)")
    # below the axes, so that it hides no bar
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=4, frameon=False)
    ax.set_title("volume -> closed mesh + area, median")
    if sweep_rows or rot_rows:
        ax = axes[0, 1]
        groups = ([("ball r = 50-400", sweep_rows)] if sweep_rows else []) + \
            [(f"rotated {name}, {', '.join(str(r['n']) for r in rot_rows if r['mesh'] == name)} across",
              [r for r in rot_rows if r["mesh"] == name]) for name in dict.fromkeys(r["mesh"] for r in rot_rows)]
        for label, grp in groups:
            b = np.array([g["boundary_voxels"] for g in grp], dtype=float)
            t = np.array([g["median_s"] for g in grp])
            ax.loglog(b, t, "o-", label=f"{label} (slope {loglog_slope(grp):.2f})")
        allb = np.array([g["boundary_voxels"] for _, grp in groups for g in grp], dtype=float)
        allt = np.array([g["median_s"] for _, grp in groups for g in grp])
        lo = allb.min()
        ax.loglog([lo, allb.max()], [allt.min(), allt.min() * allb.max() / lo], ":", color="grey",
                  label="slope 1 (linear in the surface)")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("boundary voxels (object voxels with a background 6-neighbour)")
        ax.set_ylabel("seconds, contourmesh.mesh")
        ax.legend(fontsize=7)
        ax.set_title("time against surface size")
    fig.tight_layout()
    import io

    from contourmesh.meshes import atomic_write

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, metadata={"Software": None})
    atomic_write(out / "volume_speed.png", buf.getvalue())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", default="ball-256-120,ball-512-250")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", default="1,all")
    ap.add_argument("--sweep", action="store_true")
    ap.add_argument("--sweep-rotated", default="", metavar="NAMES",
                    help="rotated real meshes timed at --sweep-sizes (comma-separated: %s)" % ", ".join(ROTATED_MESHES))
    ap.add_argument("--sweep-sizes", default="128,256,512", help="voxels across for --sweep-rotated")
    ap.add_argument("--cold", action="store_true")
    ap.add_argument("--cold-cases", default=",".join(COLD_CASES),
                    help="first calls timed by --cold (comma-separated: %s)" % ", ".join(COLD_CASES))
    ap.add_argument("--real", action="store_true")
    ap.add_argument("--memory", action="store_true", help="peak RSS per method and input (fresh subprocesses)")
    ap.add_argument("--kernel", action="store_true")
    ap.add_argument("--all", action="store_true")
    ap.add_argument("--out", default=None, help="write volume_speed.{csv,md,png,json} here")
    a = ap.parse_args(argv)
    if a.all:
        a.sweep = a.cold = a.memory = a.kernel = True
    ncpu = os.cpu_count() or 1
    threads = [ncpu if t == "all" else int(t) for t in a.threads.split(",")]
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    print(f"machine: {ncpu} CPUs; load average {os.getloadavg()}", flush=True)
    summary = {"cpus": ncpu, "loadavg_start": os.getloadavg()}
    specs = [x for x in a.inputs.split(",") if x] + (REAL if a.real else [])
    if specs or a.sweep_rotated:
        warm_up()
    rows = []
    for th in threads:
        rows += time_inputs(specs, a.repeat, th)
    mem = {}
    if a.memory:
        for spec in specs:
            for name in METHODS:
                mem[(spec, name, threads[0])] = res = peak_memory(spec, name, threads[0])
                print("memory", spec, name, res, flush=True)
    if a.kernel:
        summary["kernel"] = kernel_rate()
        print("kernel", summary["kernel"], flush=True)
    if a.cold:
        summary["cold_start"] = cold_start(a.cold_cases.split(","))
        print("cold start", summary["cold_start"], flush=True)
    sweep_rows, slope = [], None
    if a.sweep:
        sweep_rows, slope = sweep([50, 71, 100, 141, 200, 283, 400], a.repeat, threads[0])
        summary["sweep"] = sweep_rows
        summary["sweep_loglog_slope"] = slope
        summary["sweep_loglog_slope_boundary"] = loglog_slope(sweep_rows)
        print("log-log slope of seconds against r:", slope, "; against boundary voxels:",
              summary["sweep_loglog_slope_boundary"], flush=True)
    rot_rows = []
    if a.sweep_rotated:
        names = [x for x in a.sweep_rotated.split(",") if x]
        unknown = sorted(set(names) - set(ROTATED_MESHES))
        if unknown:
            ap.error(f"--sweep-rotated: unknown mesh(es) {unknown}; expected some of {sorted(ROTATED_MESHES)}")
        rot_rows, slopes = sweep_rotated(names, [int(x) for x in a.sweep_sizes.split(",")], a.repeat, threads[0])
        summary["sweep_rotated"] = rot_rows
        summary["sweep_rotated_loglog_slope_boundary"] = slopes
    summary["loadavg_end"] = os.getloadavg()
    if a.out:
        out = Path(a.out)
        write_table(rows, mem, out)
        plot(rows, sweep_rows, slope, out, rot_rows)
        from contourmesh.meshes import atomic_write

        atomic_write(out / "volume_speed.json", (json.dumps(summary, indent=1, default=float) + "\n").encode())
        print("wrote", out, flush=True)


if __name__ == "__main__":
    main()
