"""The comparison runner: a spec file (TOML) -> rows -> ``results.csv``, ``summary.md`` and plots.

A spec is data (``comparisons/*.toml``)::

    title = "Spheres, Gauss digitization"
    seed = 20090823            # random placements: numpy default_rng sub-seeds (see compare.inputs)
    repeats = 5                # random placements per size
    h = 1.0                    # grid spacing of analytic shapes
    timeout = 600              # seconds per row (optional)
    methods = ["ours-mlp-wiederhold", "mc-lewiner", "surfels"]
    postprocess = ["none"]     # applied to every method unless the method says otherwise

    [[inputs]]                 # an analytic shape ...
    shape = "sphere"
    sizes = [10, 20, 40]       # scale parameter(s): numbers, or lists [a, b] for two-parameter shapes
    digitization = "gauss"     # or "outer-jordan"
    offset = true              # random sub-voxel centre per repeat
    rotate = false             # uniformly random rotation per repeat

    [[inputs]]                 # ... or a closed mesh from the data folder, voxelized
    mesh = "meshes/libigl-tutorial-data/bunny.off"
    name = "bunny"
    resolutions = [32, 64, 128]
    rotate = true              # optional: random rotation / sub-voxel offset per repeat, drawn
    offset = true              # per resolution (placement = "per-resolution", the default) or
    placement = "per-repeat"   # once per repeat for every resolution ("per-repeat")

    [method."o3d-poisson-d8"]  # per-method options
    max_size = 56              # larger inputs: status "skipped" with the reason
    timeout = 300
    postprocess = ["none", "merge-coplanar"]   # post-process chains: "none", "a", "a+b"

    [post."merge-coplanar"]    # per-post-process options
    max_size = 80              # larger inputs: the post-processed rows are "skipped"

Methods: names from the method registry (:func:`contourmesh.compare.methods.get_method`), ours
included as ``"ours-<polygon>-<triangulation>[-band]"``.  On a shape input a method that can mesh
the shape itself does so (``Method.shape_fn``: ours traces the outer Jordan contours around the
same grid points as the Gauss volume's slices); every other method, and every method on a mesh
input, reads the volume.  Every method runs through :func:`execute`: the same timing, time limit,
post-processes, mesh checks and error capture.

Rows, cache, restarts
---------------------
One row per input x method x post-process x repeat (columns :data:`~contourmesh.compare.report.COLUMNS`).
Each finished row is written at once as one small JSON file ``cache/<key>.json`` in the output
folder (atomically, :func:`contourmesh.meshes.atomic_write`), ``key`` = sha256 of the input's
identity, the method, its parameters, the post-process and the package version.  A re-run reuses
them (a corrupt or foreign file is ignored and its row recomputed); a killed run loses no
finished row.  ``results.csv``, ``summary.md`` and the PNGs are rebuilt from the cache at the end.
Rows that are ``skipped`` (``max_size``) or ``no-data`` (mesh file missing) are decided when
planning and never cached; ``not-installed`` rows are cached but re-tried on every run.

Parallelism and time limits
---------------------------
``jobs=1`` runs the rows in this process; ``jobs > 1`` in a ``ProcessPoolExecutor`` (fork start
method on Linux); ``scheduler=ADDRESS`` (or a ``distributed.Client``) on a Dask cluster.  A row's
``timeout`` is enforced by ``SIGALRM`` in the thread that runs it where that is the main thread
(this process, pool workers); a pool worker stuck in C code past ``timeout + grace`` writes the
``timeout`` row itself and exits, and the runner restarts the pool.  A worker that dies
(segmentation fault) while a row runs gets the row re-tried once, then recorded as ``failed``.
On Dask worker threads a timed row runs in a new Python process
(:func:`contourmesh.compare.execute.call_in_subprocess`, plain ``subprocess``, so it also works in
the daemonic process workers of a default ``distributed.LocalCluster``) that applies the limit
itself and is killed ``HARD_GRACE`` seconds later if stuck.

Before the rows, our methods run once on small inputs in this process (:func:`warm_up`, off with
``warm=False``): a row's ``seconds`` then holds no compiling or loading of their numba kernels (the
first row of each worker used to pay for it: over 100 s for the band refinement's rows after a
change of the sources).  Pool workers are forked from this process and inherit the kernels; Dask
workers and timed subprocesses load them from the refreshed disk cache in their first row.

Rows that the executor or the scheduler failed (a lost Dask worker, a process that could not
start) are reported but not cached, and ``contourmesh compare`` then exits with status 1.
Ctrl-C or SIGTERM stops a run: queued rows are dropped, worker processes are ended (on Linux they
also die with the run if it is killed outright), and the cache keeps only complete rows.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from .. import __version__
from ..measure import axis_wall_fraction, mesh_checks, relative_error, tradeoff
from ..meshes import atomic_write
from .execute import HARD_GRACE, ExecutorError, RowTimeout, call_in_subprocess, die_with_parent, time_limit
from .inputs import Input, mesh_inputs, shape_inputs
from .methods import Result, check_volume, get_method
from .postprocess import apply_postprocess, get_postprocess
from .report import COLUMNS, markdown_summary, plot_results, write_results_csv

__all__ = [
    "Spec",
    "Task",
    "load_spec",
    "plan",
    "execute",
    "run_spec",
    "import_rows",
    "cache_key",
    "warm_up",
]

#: How many pool crashes a row may be caught in before it is recorded as failed.
MAX_CRASHES = 2


# --- spec -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Task:
    """One row to produce: an input, a method, a post-process chain (``"none"`` or names joined by ``+``)."""

    input: Input
    method: str
    postprocess: str = "none"
    timeout: Optional[float] = None
    skip: Optional[str] = None
    key: str = ""


@dataclass
class Spec:
    """A parsed comparison spec (see the module docstring)."""

    path: Path
    title: str
    seed: int
    repeats: int
    h: float
    timeout: Optional[float]
    methods: list
    postprocess: list
    options: dict
    post_options: dict = field(default_factory=dict)
    inputs: list = field(default_factory=list)
    notes: str = ""


_TOP_KEYS = {"title", "notes", "seed", "repeats", "h", "timeout", "methods", "postprocess", "inputs", "method", "post"}
_SHAPE_KEYS = {"shape", "sizes", "digitization", "offset", "rotate", "repeats", "fixed", "h"}
_MESH_KEYS = {"mesh", "name", "resolutions", "offset", "rotate", "repeats", "placement"}
_OPTION_KEYS = {"max_size", "timeout", "postprocess"}


def _timeout(value, where):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ValueError(f"{where}: timeout must be a positive number of seconds; got {value!r}")
    return float(value)


def _post_list(value, where) -> list:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise ValueError(f"{where}: postprocess must be a list of names ('none' or post-process names); got {value!r}")
    for chain in value:
        if chain != "none":
            for step in chain.split("+"):
                get_postprocess(step)  # raises ValueError naming the valid ones
    return list(value)


def load_spec(path, *, data_root=None) -> Spec:
    """Read and validate a comparison spec (TOML); errors say what was expected and found."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"comparison spec {str(path)!r} does not exist")
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"comparison spec {str(path)!r} is not valid TOML: {exc}") from None
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise ValueError(f"{path.name}: unknown top-level keys {sorted(unknown)}; expected {sorted(_TOP_KEYS)}")
    seed = doc.get("seed", 0)
    repeats = doc.get("repeats", 1)
    h = doc.get("h", 1.0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"{path.name}: seed must be a non-negative integer; got {seed!r}")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"{path.name}: repeats must be a positive integer; got {repeats!r}")
    if isinstance(h, bool) or not isinstance(h, (int, float)) or not h > 0:
        raise ValueError(f"{path.name}: h must be a positive number; got {h!r}")
    methods = doc.get("methods")
    if not isinstance(methods, list) or not methods or not all(isinstance(m, str) for m in methods):
        raise ValueError(f"{path.name}: methods must be a non-empty list of method names; got {methods!r}")
    if len(set(methods)) != len(methods):
        raise ValueError(f"{path.name}: methods lists a name twice")
    for m in methods:
        get_method(m)  # unknown names raise ValueError listing the valid forms
    post = _post_list(doc.get("postprocess", ["none"]), path.name)
    options = doc.get("method", {})
    if not isinstance(options, dict):
        raise ValueError(f"{path.name}: [method.NAME] tables expected; got {options!r}")
    for name, opt in options.items():
        if name not in methods:
            raise ValueError(f"{path.name}: [method.{name!r}] is not in methods")
        bad = set(opt) - _OPTION_KEYS
        if bad:
            raise ValueError(f"{path.name}: [method.{name!r}] has unknown keys {sorted(bad)}; expected {sorted(_OPTION_KEYS)}")
        if "max_size" in opt and (isinstance(opt["max_size"], bool) or not isinstance(opt["max_size"], (int, float))):
            raise ValueError(f"{path.name}: [method.{name!r}] max_size must be a number; got {opt['max_size']!r}")
        _timeout(opt.get("timeout"), f"{path.name} [method.{name!r}]")
        if "postprocess" in opt:
            _post_list(opt["postprocess"], f"{path.name} [method.{name!r}]")
    post_options = doc.get("post", {})
    if not isinstance(post_options, dict):
        raise ValueError(f"{path.name}: [post.NAME] tables expected; got {post_options!r}")
    for name, opt in post_options.items():
        _post_list([name], f"{path.name} [post.{name!r}]")
        if set(opt) - {"max_size"} or not isinstance(opt.get("max_size"), (int, float)) or isinstance(opt.get("max_size"), bool):
            raise ValueError(f"{path.name}: [post.{name!r}] takes one key, max_size (a number); got {opt!r}")
    entries = doc.get("inputs")
    if not isinstance(entries, list) or not entries:
        raise ValueError(f"{path.name}: at least one [[inputs]] table is needed")
    inputs = []
    for n, e in enumerate(entries):
        where = f"{path.name} [[inputs]] #{n + 1}"
        reps = e.get("repeats", repeats)
        if "shape" in e:
            bad = set(e) - _SHAPE_KEYS
            if bad:
                raise ValueError(f"{where}: unknown keys {sorted(bad)}; a shape takes {sorted(_SHAPE_KEYS)}")
            if not isinstance(e.get("sizes"), list) or not e["sizes"]:
                raise ValueError(f"{where}: sizes must be a non-empty list; got {e.get('sizes')!r}")
            inputs += shape_inputs(e["shape"], e["sizes"], digitization=e.get("digitization", "gauss"),
                                   repeats=reps, seed=seed, offset=bool(e.get("offset", True)),
                                   rotate=bool(e.get("rotate", False)), h=float(e.get("h", h)), fixed=e.get("fixed"))
        elif "mesh" in e:
            bad = set(e) - _MESH_KEYS
            if bad:
                raise ValueError(f"{where}: unknown keys {sorted(bad)}; a mesh takes {sorted(_MESH_KEYS)}")
            if not isinstance(e.get("resolutions"), list) or not e["resolutions"]:
                raise ValueError(f"{where}: resolutions must be a non-empty list; got {e.get('resolutions')!r}")
            inputs += mesh_inputs(e["mesh"], e["resolutions"], name=e.get("name"), repeats=reps, seed=seed,
                                  offset=bool(e.get("offset", False)), rotate=bool(e.get("rotate", False)),
                                  root=data_root, placement=e.get("placement", "per-resolution"))
        else:
            raise ValueError(f"{where}: expected a 'shape' or a 'mesh' key; got keys {sorted(e)}")
    return Spec(path=path, title=str(doc.get("title", path.stem)), seed=seed, repeats=repeats, h=float(h),
                timeout=_timeout(doc.get("timeout"), path.name), methods=list(methods), postprocess=post,
                options=options, post_options=post_options, inputs=inputs, notes=str(doc.get("notes", "")))


def _jsonable(v):
    try:
        json.dumps(v)
        return v
    except TypeError:
        return repr(v)


def cache_key(inp: Input, method: str, postprocess: str) -> str:
    """sha256 of the input's identity, the method and its parameters, the post-process, the version."""
    try:
        params = {k: _jsonable(v) for k, v in get_method(method).params.items()}
    except ValueError:
        params = None
    blob = json.dumps({"input": inp.key, "method": method, "params": params, "postprocess": postprocess,
                       "version": __version__}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()


def plan(spec: Spec) -> list:
    """Every row of the spec as a :class:`Task`, in input order, then method, then post-process."""
    tasks = []
    for inp in spec.inputs:
        for m in spec.methods:
            opt = spec.options.get(m, {})
            timeout = _timeout(opt.get("timeout", spec.timeout), m)
            skip = None
            if "max_size" in opt and inp.size_value > float(opt["max_size"]):
                skip = f"size {inp.size_value:g} > max_size {opt['max_size']:g} set for {m} in the spec"
            for post in opt.get("postprocess", spec.postprocess):
                pskip = skip
                pmax = spec.post_options.get(post, {}).get("max_size")
                if pskip is None and pmax is not None and inp.size_value > float(pmax):
                    pskip = f"size {inp.size_value:g} > max_size {pmax:g} set for post-process {post} in the spec"
                tasks.append(Task(inp, m, post, timeout, pskip, cache_key(inp, m, post)))
    return tasks


# --- warm-up --------------------------------------------------------------------------------------------
def _warm_volumes() -> list:
    """Small binary volumes that take every route of our mesher: one contour per slice (the fast
    path; the stack route of ``refine="band"``), holes, branching and a cavity (the general volume
    mesher; its refined polygons), and thresholded smoothed noise (many components, bridged
    joins, crack rings, intermediate sections)."""
    import numpy as np
    from scipy.ndimage import gaussian_filter

    zz, yy, xx = np.mgrid[:14, :14, :14]
    ball = (zz - 6.6) ** 2 + (yy - 6.3) ** 2 + (xx - 6.8) ** 2 < 25
    general = np.zeros((9, 12, 12), dtype=bool)
    general[1:8, 2:10, 2:10] = True
    general[1:8, 5:7, 5:7] = False  # a tunnel: slices with holes
    general[4, 3:9, 3:9] = True  # ... closed in one slice: branching above and below
    general[2:4, 3, 8] = False  # a small cavity
    noise = gaussian_filter(np.random.default_rng(1).standard_normal((22, 22, 22)), 2.0) > 0.02
    return [ball, general, np.pad(noise, 1)]


def _warm_rare() -> None:
    """Kernels of paths that small volumes rarely take: the vertex-fan split of the manifold repair
    (two tetrahedra sharing a vertex), its split of four-face edges (two sharing an edge) and its
    copy of the kept faces, the crossing repair (two overlapping cubes
    pulled apart, and the crossing pairs recounted after one cube moved), the optimal band
    with its work bounded (large polygons) and the band refinement's crease gains."""
    import numpy as np

    from ..bands.optimal import triangulate_band_optimal
    from ..repair import _kept_and_added, crossing_pairs_after_change, resolve_crossings, split_nonmanifold_vertices
    from ..volumes import volume_to_mesh

    t = np.linspace(0, 2 * np.pi, 9, endpoint=False)
    ring = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
    triangulate_band_optimal(ring[:-1], ring + [0.1, 0.0, 1.0], max_work=10.0)

    # the band refinement's two-scale targets with and without a gain per vertex (the small
    # warm-up volumes take one of the two)
    from ..refine import _two_scale_targets

    xy, yes = np.zeros((3, 2)), np.ones(3, dtype=np.bool_)
    for gains in ((np.ones(3), np.ones(3)), (None, None)):
        _two_scale_targets(xy, xy + 0.2, yes, yes, 0.1, 0.2, 0.3, np.empty_like(xy), *gains)

    cube = volume_to_mesh(np.pad(np.ones((2, 2, 2), dtype=bool), 1))
    # two tetrahedra sharing a vertex: the vertex-fan split and its renumbering
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    split_nonmanifold_vertices(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0],
                                         [0, 0, -1.0]]), np.vstack([tet, np.where(tet > 0, tet + 3, 0)]),
                               1e-3, four_face=False)
    # ... and the split of four-face edges before it (two tetrahedra sharing an edge)
    split_nonmanifold_vertices(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0], [0, 0, -1.0]]),
                               np.vstack([tet, np.where(tet > 1, tet + 2, tet)]), 1e-3, side=np.repeat([1, 2], 4))
    # the manifold repair's copy of the kept faces (four-face edges, necks), with sides of both
    # widths (the volume mesher's carry tags in int32, the repair's own are int64)
    for dt in (np.int32, np.int64):
        _kept_and_added(np.zeros((2, 3), np.int64), np.zeros(2, dt), np.array([True, False]), [[0, 1, 2]], [0])
    V = np.vstack([cube.vertices, cube.vertices + 0.3])
    F = np.vstack([cube.faces, cube.faces + len(cube.vertices)])
    V1, info = resolve_crossings(V, F, 1e-3)
    V2 = V1.copy()
    V2[len(cube.vertices):] += 0.1
    crossing_pairs_after_change(V1, F, info["pairs"], V2, F)
    crossing_pairs_after_change(V1, F, info["pairs"], V1, F)  # (the faces matched in their order)
    # the bridged joins' rare paths (a polyline keyhole; bridge_tree's Python loop)
    from ..bands.bridges import warm_rare_paths
    from ..sections import warm_rare_kernels

    warm_rare_paths()
    warm_rare_kernels()


def warm_up(methods) -> list:
    """Run each of our methods (family ``ours``) once on small volumes and a small shape, untimed.

    Our mesher's kernels are compiled by numba on their first call in a process (or loaded from
    the on-disk cache, which goes stale when the sources change); without this step the first
    row of each worker that reaches a kernel pays for it: 70 s of CPU for the band refinement's
    kernels after a change of the sources, about 4 s for the stack route's MLP kernel, 0.1-0.5 s
    to load them.  Run in the parent before the rows, the warm-up also refreshes the disk cache,
    and pool workers (forked) inherit the compiled kernels.  Other families are not run: their
    compiled code comes built.  Returns the names warmed; a method that fails here is left to
    fail in its own rows, where the error is recorded.
    """
    from ..shapes import Sphere

    warmed = []
    for name in dict.fromkeys(methods):
        try:
            m = get_method(name)
        except ValueError:
            continue
        if m.family != "ours":
            continue
        try:
            for vol in _warm_volumes():
                m.fn(vol, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), **m.params)
            if m.shape_fn is not None:
                m.shape_fn(Sphere(5.2, center=(0.31, 0.17, 0.43)), 1.0, **m.params)
        except Exception:  # noqa: BLE001 - the method's own rows record its failure
            continue
        warmed.append(name)
    if warmed:
        try:
            _warm_rare()
        except Exception:  # noqa: BLE001 - the rows that need it compile it
            pass
    return warmed


# --- one row ----------------------------------------------------------------------------------------
def _base_row(task: Task) -> dict:
    inp = task.input
    row = {c: None for c in COLUMNS}
    row.update(method=task.method, postprocess=task.postprocess, shape=inp.name, size=inp.size, repeat=inp.repeat,
               area_true=inp.area_true, kind=inp.kind, digitization=inp.digitization, size_value=inp.size_value,
               key=task.key)
    try:
        row["family"] = get_method(task.method).family
    except ValueError:
        pass
    return row


def _measure(task: Task) -> dict:
    """Run the method and its post-processes on the task's input; the fields a run fills."""
    out = {}
    method = get_method(task.method)
    inp = task.input
    if inp.kind == "shape" and method.shape_fn is not None:  # ours meshes the shape's own slices
        shape, h = inp.shape(), inp.h
        t0 = time.perf_counter()
        res = method.shape_fn(shape, h, **method.params)
    else:
        vol, sp, org = check_volume(*inp.volume())
        t0 = time.perf_counter()
        res = method.fn(vol, sp, org, **method.params)
    if not isinstance(res, Result):
        raise TypeError(f"method {task.method!r} returned {type(res).__name__}, expected Result")
    mesh, P = res.mesh, res.P
    if task.postprocess != "none":
        if mesh is None:
            raise ValueError(f"method {task.method!r} makes no mesh; post-process {task.postprocess!r} needs one")
        for step in task.postprocess.split("+"):
            mesh, _ = apply_postprocess(step, mesh)
        P = int(len(mesh.vertices))
    out["seconds"] = time.perf_counter() - t0
    out["area"] = float(mesh.area) if mesh is not None else float(res.area)
    out["P"] = None if P is None else int(P)
    if mesh is not None:
        chk = mesh_checks(mesh.vertices, mesh.faces)
        out.update(faces=int(len(mesh.faces)), watertight=bool(chk["watertight"]),
                   winding_consistent=bool(chk["winding_consistent"]), volume=float(chk["volume"]))
        out["meta"] = _meta_text(res.mesh, mesh)
    return out


def _meta_text(made, final) -> str:
    """JSON text of the scalar entries of ``made.meta`` (when it has one) and the final mesh's
    :func:`~contourmesh.measure.axis_wall_fraction` (the row's ``meta`` column)."""
    meta = getattr(made, "meta", None)
    out = {}
    if isinstance(meta, dict):
        for k, v in meta.items():
            if getattr(v, "shape", None) == () and hasattr(v, "item"):  # a numpy scalar
                v = v.item()
            if isinstance(v, (bool, int, str)) or (isinstance(v, float) and v == v and abs(v) != float("inf")):
                out[str(k)] = v
    out["axis_wall_fraction"] = axis_wall_fraction(final.vertices, final.faces)
    return json.dumps(out, sort_keys=True)


def _finish(row: dict) -> dict:
    if row["status"] == "ok":
        row["e"] = relative_error(row["area"], row["area_true"])
        row["t"] = tradeoff(row["e"], row["P"])
    return row


_POOL = {"in_pool": False, "cache_dir": None}


def _pool_init(cache_dir):  # runs in every pool worker
    _POOL.update(in_pool=True, cache_dir=str(cache_dir))
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent()  # a run killed outright (SIGKILL) takes its workers with it


def _hard_timeout(task: Task, t0: float):  # pragma: no cover - runs in a stuck worker
    row = _base_row(task)
    row.update(status="timeout", seconds=time.perf_counter() - t0,
               error=f"no result within {task.timeout} s (the worker was stuck in compiled code and was ended "
                     f"{HARD_GRACE:g} s later)")
    try:
        _write_cache(Path(_POOL["cache_dir"]), row)
        _running_marker(Path(_POOL["cache_dir"]), task.key).unlink(missing_ok=True)
    finally:
        os._exit(3)


#: Row field that marks a row the executor or the scheduler failed (not the method): such a row
#: is reported and makes the run exit nonzero, but it is not cached.
EXECUTOR_FAILED = "_executor_failed"


def _executor_row(task: Task, message: str, seconds=None) -> dict:
    row = _base_row(task)
    row.update(status="failed", seconds=seconds, error=f"not run: {message}")
    row[EXECUTOR_FAILED] = True
    return row


def _in_subprocess(task: Task) -> dict:
    """Run a timed row in a new Python process (for threads other than the main one, e.g. Dask's).

    The child applies the time limit in its own main thread; it is killed ``HARD_GRACE`` seconds
    later if stuck in compiled code.  Each thread keeps its child for the next row (one
    interpreter start-up per thread, not per row).  ``subprocess`` (not ``multiprocessing``) works inside
    daemonic processes, such as the process workers of a default ``distributed.LocalCluster``.
    """
    try:
        status, value, seconds = call_in_subprocess(execute, task, kill_after=task.timeout + HARD_GRACE, reuse=True)
    except ExecutorError as exc:
        return _executor_row(task, str(exc))
    if status == "ok":
        return value
    row = _base_row(task)
    if status == "timeout":
        row.update(status="timeout", seconds=seconds,
                   error=f"no result within {task.timeout} s (the row's process was ended {HARD_GRACE:g} s later)")
    else:
        row.update(status="failed", seconds=seconds, error=value)
    return row


def execute(task: Task) -> dict:
    """Produce one row; never raises for the method's own failure.

    The row's ``status`` is ``ok``, ``not-installed`` (an optional package is missing; the error
    says what to install), ``failed`` (the error text), ``timeout``, ``skipped`` (``max_size``)
    or ``no-data`` (the input's file is missing).
    """
    row = _base_row(task)
    if task.skip:
        return row | {"status": "skipped", "error": task.skip}
    if task.input.error:
        return row | {"status": "no-data", "error": task.input.error}
    main = threading.current_thread() is threading.main_thread()
    if task.timeout is not None and not main:
        return _in_subprocess(task)
    t0 = time.perf_counter()
    watchdog = None
    if task.timeout is not None and _POOL["in_pool"]:
        watchdog = threading.Timer(task.timeout + HARD_GRACE, _hard_timeout, args=(task, t0))
        watchdog.daemon = True
        watchdog.start()
    try:
        with time_limit(task.timeout):
            row.update(_measure(task))
        row["status"] = "ok"
    except RowTimeout:
        row.update(status="timeout", seconds=time.perf_counter() - t0, error=f"no result within {task.timeout} s")
    except ImportError as exc:
        row.update(status="not-installed", seconds=time.perf_counter() - t0, error=str(exc))
    except Exception as exc:  # noqa: BLE001 - a method's failure is a row, not a crash
        last = traceback.extract_tb(exc.__traceback__)[-1:]
        where = f" [{Path(last[0].filename).name}:{last[0].lineno}]" if last else ""
        row.update(status="failed", seconds=time.perf_counter() - t0, error=f"{type(exc).__name__}: {exc}{where}")
    finally:
        if watchdog is not None:
            watchdog.cancel()
    return _finish(row)


# --- cache --------------------------------------------------------------------------------------------
def _cache_path(cache_dir: Path, key: str) -> Path:
    return cache_dir / f"{key}.json"


def _running_marker(cache_dir: Path, key: str) -> Path:
    return cache_dir / f"{key}.running"


def _write_cache(cache_dir: Path, row: dict) -> None:
    clean = {k: _jsonable(row.get(k)) for k in COLUMNS}
    atomic_write(_cache_path(cache_dir, row["key"]), json.dumps(clean, sort_keys=True).encode())


def _read_cache(cache_dir: Path, task: Task) -> Optional[dict]:
    """The cached row of a task, or None when absent, corrupt, foreign or to be re-tried."""
    p = _cache_path(cache_dir, task.key)
    try:
        row = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or row.get("key") != task.key or row.get("status") not in (
            "ok", "failed", "timeout") or set(COLUMNS) - set(row):
        return None
    if row["status"] == "ok" and not isinstance(row.get("area"), (int, float)):
        return None
    return row


def _pooled(task: Task) -> dict:
    """Pool-worker entry: mark the row as running (for crash accounting), run it, unmark."""
    marker = _running_marker(Path(_POOL["cache_dir"]), task.key)
    try:
        marker.write_text(str(os.getpid()))
    except OSError:
        pass
    try:
        return execute(task)
    finally:
        marker.unlink(missing_ok=True)


# --- the run ------------------------------------------------------------------------------------------
def _progress(total, initial, enabled):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, unit="row", desc="compare", disable=not enabled, dynamic_ncols=True)


def _end_workers(ex) -> None:
    """Stop a process pool at once: queued rows dropped, running rows' workers killed.

    A worker killed mid-row has written nothing (cache files are written whole, by rename), so
    the cache keeps only complete rows; its ``.running`` marker is cleared by the next run.
    """
    procs = list(getattr(ex, "_processes", {}).values())  # the pool's worker processes
    for proc in procs:
        try:
            proc.terminate()
        except (OSError, AttributeError):  # pragma: no cover - already gone
            pass
    ex.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        proc.join(5)
        if proc.is_alive():  # pragma: no cover - ignores SIGTERM while in compiled code
            proc.kill()
            proc.join(5)


#: Seconds between the main thread's wake-ups while it waits for pool rows (see :func:`_completed`).
SIGNAL_POLL = 0.25


def _completed(futures):
    """Yield futures as they finish, waking the main thread every :data:`SIGNAL_POLL` seconds.

    ``concurrent.futures.as_completed`` without a timeout blocks the main thread on a lock.  A
    signal that the kernel delivers to one of the executor's own threads (its manager or queue
    feeder thread) then only sets Python's flag: the main thread sleeps on until the next row
    finishes, so Ctrl-C or SIGTERM could go unanswered for as long as the running rows take.
    Waking up regularly lets the main thread run the signal handlers at once.
    """
    from concurrent.futures import FIRST_COMPLETED, wait

    left = set(futures)
    while left:
        finished, left = wait(left, timeout=SIGNAL_POLL, return_when=FIRST_COMPLETED)
        yield from finished


def _run_pool(todo, jobs, cache_dir, collect, mp_context=None):
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    ctx = mp.get_context(mp_context) if mp_context else (mp.get_context("fork") if os.name == "posix" else None)
    pending = list(todo)
    crashes: dict = {}
    for stale in Path(cache_dir).glob("*.running"):  # left by a run that was killed
        stale.unlink(missing_ok=True)
    while pending:
        broken = False
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_pool_init,
                                 initargs=(str(cache_dir),)) as ex:
            futs = {ex.submit(_pooled, t): t for t in pending}
            done = set()
            try:
                for fut in _completed(futs):
                    t = futs[fut]
                    try:
                        row = fut.result()
                    except BrokenProcessPool:
                        broken = True
                        break
                    collect(t, row)
                    done.add(t.key)
            except BaseException:  # Ctrl-C, SIGTERM: keep the finished rows, end the workers now
                _end_workers(ex)
                for marker in Path(cache_dir).glob("*.running"):  # those rows did not finish
                    marker.unlink(missing_ok=True)
                raise
            if broken:  # rows that finished before the pool broke are kept
                for fut, t in futs.items():
                    if t.key not in done and fut.done() and not fut.cancelled() and fut.exception() is None:
                        collect(t, fut.result())
                        done.add(t.key)
        if not broken:
            return
        rest = []
        for t in pending:
            if t.key in done:
                continue
            cached = _read_cache(cache_dir, t)  # a hard timeout wrote its own row
            marker = _running_marker(cache_dir, t.key)
            if cached is not None:
                collect(t, cached, written=True)
                marker.unlink(missing_ok=True)
                continue
            if marker.exists():
                marker.unlink(missing_ok=True)
                crashes[t.key] = crashes.get(t.key, 0) + 1
                if crashes[t.key] >= MAX_CRASHES:
                    row = _base_row(t)
                    row.update(status="failed", error="the worker process died while running this row "
                                                      f"({crashes[t.key]} times; a crash in compiled code?)")
                    collect(t, row)
                    continue
            rest.append(t)
        pending = rest


def _run_dask(todo, scheduler, collect):
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise ImportError("--scheduler needs Dask distributed: pip install distributed "
                          "(or pip install 'contourmesh[compare]')") from exc
    own = not isinstance(scheduler, Client)
    try:
        client = Client(scheduler, timeout=30) if own else scheduler
    except OSError as exc:
        raise ExecutorError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from exc
    futs = {}
    try:
        for t in todo:
            futs[client.submit(execute, t, key=f"row-{t.key}", pure=False)] = t
        for fut in as_completed(list(futs)):
            t = futs[fut]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker is the scheduler's failure, not the method's
                row = _executor_row(t, f"the Dask task failed: {type(exc).__name__}: {exc}")
            collect(t, row)
    finally:
        if futs:
            try:
                client.cancel(list(futs))
            except Exception:  # noqa: BLE001 - the client may already be gone
                pass
        if own:
            client.close()


def _selected(task: Task, sizes, methods, names) -> bool:
    return ((sizes is None or task.input.size in sizes) and (methods is None or task.method in methods)
            and (names is None or task.input.name in names))


def import_rows(spec_path, out, csv_path, *, data_root=None) -> int:
    """Put the finished rows of an earlier ``results.csv`` into ``out/cache`` (rows already cached are kept).

    Only rows whose ``key`` belongs to the spec's plan today (same input, method, parameters,
    post-process and package version) and whose status is ``ok``, ``failed`` or ``timeout`` are
    taken; the others are ignored.  So a committed ``results.csv`` lets a fresh checkout resume a
    partial run, or re-run one method, without recomputing the rest.  Returns the rows imported.
    """
    from .report import read_results_csv

    csv_path = Path(csv_path)
    if not csv_path.is_file():
        return 0
    keys = {t.key for t in plan(load_spec(spec_path, data_root=data_root)) if not t.skip}
    cache_dir = Path(out) / "cache"
    cache_dir.mkdir(parents=True, exist_ok=True)
    n = 0
    for row in read_results_csv(csv_path):
        if row.get("key") not in keys or row.get("status") not in ("ok", "failed", "timeout") or set(COLUMNS) - set(row):
            continue
        if _cache_path(cache_dir, row["key"]).exists():
            continue
        _write_cache(cache_dir, row)
        n += 1
    return n


def run_spec(spec_path, out=None, *, jobs: int = 1, scheduler=None, progress: bool = True, retry_failed: bool = False,
             data_root=None, mp_context: Optional[str] = None, sizes=None, methods=None, names=None,
             write: bool = True, warm: bool = True) -> dict:
    """Run a comparison spec; write ``results.csv``, ``summary.md`` and the PNGs into ``out``.

    Parameters
    ----------
    spec_path : path
        The TOML spec.
    out : path, optional
        Output folder; default ``./<spec stem>/`` in the current working directory (never next to
        the spec, so a checkout's committed results are not overwritten).  Rows are cached in
        ``out/cache``.
    jobs : int
        Worker processes (1: this process).
    scheduler : str or distributed.Client, optional
        Run the rows on this Dask cluster instead.
    progress : bool
        Show a tqdm progress bar (rows done / rows in all).
    retry_failed : bool
        Re-run cached rows whose status is ``failed`` or ``timeout``.
    data_root : path, optional
        The data folder for mesh inputs (default: :func:`contourmesh.compare.inputs.data_dir`).
    sizes, methods, names : collection of str, optional
        Run only the rows whose input size (``"128"``), method and input name are in these
        (None: all).  The other rows are reported when they are in the cache and left out
        otherwise, so a large spec can be run in parts (e.g. the small resolutions first).
    write : bool
        Write ``results.csv``, ``summary.md`` and the PNGs (False: only return the rows).
    warm : bool
        Before the rows, run our methods once on small inputs (:func:`warm_up`) so that no row's
        ``seconds`` includes compiling or loading our kernels.

    Returns
    -------
    dict
        ``rows`` (all rows, in plan order), ``ran`` (rows computed in this run), ``cached`` (rows
        reused), ``executor_failed`` (rows the executor or the scheduler could not run: not
        cached, re-tried by the next run), ``out`` (the folder) and ``files`` (paths written).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer; got {jobs!r}")
    spec = load_spec(spec_path, data_root=data_root)
    for what, given, known in (("sizes", sizes, {i.size for i in spec.inputs}), ("methods", methods, set(spec.methods)),
                               ("names", names, {i.name for i in spec.inputs})):
        if given is not None:
            if isinstance(given, str):
                raise ValueError(f"{what} must be a collection of strings, not the string {given!r}")
            given = {str(g) for g in given}
            if not given or given - known:
                raise ValueError(f"{what} {sorted(given - known) or '(none)'} not in the spec; it has {sorted(known)}")
    sizes = None if sizes is None else {str(x) for x in sizes}
    methods = None if methods is None else set(methods)
    names = None if names is None else set(names)
    out = Path(out) if out is not None else Path.cwd() / spec.path.stem
    cache_dir = out / "cache"
    cache_dir.mkdir(parents=True, exist_ok=True)
    tasks = plan(spec)
    rows: dict = {}
    todo = []
    cached = 0
    for t in tasks:
        chosen = _selected(t, sizes, methods, names)
        if t.skip or t.input.error:
            rows[t.key] = execute(t)
            continue
        row = _read_cache(cache_dir, t)
        if row is not None and not (chosen and retry_failed and row["status"] in ("failed", "timeout")):
            rows[t.key] = row
            cached += 1
        elif chosen:
            todo.append(t)
    todo_keys = {t.key for t in todo}
    tasks = [t for t in tasks if t.key in rows or t.key in todo_keys]
    # rows that share an input run one after another (each worker keeps its last volumes)
    bar = _progress(len(tasks), len(tasks) - len(todo), progress)
    ran = 0
    executor_failed = 0

    def collect(task, row, written=False):
        nonlocal ran, executor_failed
        if row.pop(EXECUTOR_FAILED, False):
            executor_failed += 1
        elif not written:
            _write_cache(cache_dir, row)
        rows[task.key] = row
        ran += 1
        bar.update(1)
        bar.set_postfix(left=len(tasks) - bar.n, refresh=False)

    if todo and warm:
        warm_up(t.method for t in todo)
    try:
        if not todo:
            pass
        elif scheduler is not None:
            _run_dask(todo, scheduler, collect)
        elif jobs == 1:
            for t in todo:
                collect(t, execute(t))
        else:
            _run_pool(todo, jobs, cache_dir, collect, mp_context)
    finally:
        bar.close()
    all_rows = [rows[t.key] for t in tasks if t.key in rows]
    files = []
    if write:
        files.append(write_results_csv(all_rows, out / "results.csv"))
        files.append(atomic_write(out / "summary.md",
                                  markdown_summary(all_rows, title=spec.title, notes=spec.notes).encode()))
        files += plot_results(all_rows, out)
    return {"rows": all_rows, "ran": ran, "cached": cached, "executor_failed": executor_failed, "out": out,
            "files": files}

