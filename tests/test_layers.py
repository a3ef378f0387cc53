"""The package is layered: every module imports only from its own layer or below, with no cycle.

The scan reads every ``import`` in ``src/contourmesh`` (module level and inside functions; imports
under ``if TYPE_CHECKING:`` are annotations only and are skipped).  The layers are the table in
``docs/DESIGN.md``; a new module must be given a layer here.
"""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "contourmesh"

LAYERS = {
    0: ["errors", "_optional", "_files", "_heap", "_recent", "_cache_guard", "_kernels", "_workers", "geometry", "measure", "meshes", "types", "intersect", "topology"],
    1: ["shapes", "tracing", "polygons", "bands", "digitize", "rasterize", "repair", "stacks", "volume_input",
        "voxelize", "datasets", "cells"],
    2: ["surface", "fastpath", "volumes", "sections", "refine", "drawn"],
    3: ["io", "api", "trimesh_plugin", "scale", "seams", "parallel"],
    4: ["compare", "cli", "__main__", ""],
}
LAYER = {name: k for k, names in LAYERS.items() for name in names}


def _module(path: Path) -> str:
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_module(name: str) -> bool:
    base = SRC.joinpath(*name.split(".")) if name else SRC
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def _imports(path: Path):
    """Yield the package-internal modules ``path`` imports (dotted names relative to contourmesh)."""
    me = _module(path)
    pkg = me.split(".") if path.name == "__init__.py" else me.split(".")[:-1]
    pkg = [p for p in pkg if p]
    tree = ast.parse(path.read_text())
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - (node.level - 1)] if node.level > 1 else list(pkg)
            elif node.module and node.module.split(".")[0] == "contourmesh":
                base = []
            else:
                continue
            mod = node.module if node.level else (node.module or "").removeprefix("contourmesh").lstrip(".")
            target = ".".join(base + ([mod] if (mod and node.level) else []) + ([] if node.level or not mod else [mod]))
            for alias in node.names:  # "from . import shapes" names a module
                sub = f"{target}.{alias.name}" if target else alias.name
                if _is_module(sub):
                    yield sub
                    break
            else:
                yield target
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "contourmesh":
                    yield alias.name.removeprefix("contourmesh").lstrip(".")


def _layer(mod: str) -> int:
    top = mod.split(".")[0]
    if top not in LAYER:
        raise AssertionError(f"module contourmesh.{mod} has no layer: add it to LAYERS in tests/test_layers.py "
                             "and to the table in docs/DESIGN.md")
    return LAYER[top]


def _graph():
    edges = {}
    for path in SRC.rglob("*.py"):
        me = _module(path)
        edges[me] = {t for t in _imports(path) if t != me and not me.startswith(t + ".") and t != ""}
    return edges


def test_every_module_has_a_layer():
    for mod in _graph():
        _layer(mod)


def test_no_module_imports_a_higher_layer():
    bad = []
    for me, targets in _graph().items():
        for t in targets:
            if _layer(t) > _layer(me):
                bad.append(f"contourmesh.{me} (layer {_layer(me)}) imports contourmesh.{t} (layer {_layer(t)})")
    assert not bad, "\n".join(sorted(bad))


def test_no_import_cycles():
    edges = _graph()
    # a package's __init__ re-exporting its own submodules is not a cycle of concerns
    graph = {m: {t for t in ts if t in edges and not t.startswith(m + ".")} for m, ts in edges.items()}
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("name", ["types", "geometry", "errors", "meshes", "measure"])
def test_layer_zero_imports_nothing_heavy(name):
    """Layer 0 stays light: no trimesh, scipy, skimage or matplotlib at module level."""
    tree = ast.parse((SRC / f"{name}.py").read_text())
    top = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
    names = {(n.module or "") if isinstance(n, ast.ImportFrom) else a.name for n in top
             for a in (n.names if isinstance(n, ast.Import) else [None])}
    assert not {m.split(".")[0] for m in names if m} & {"trimesh", "scipy", "skimage", "matplotlib", "open3d"}


def test_ruff_is_clean():
    """The linter configured in pyproject.toml finds nothing (unused or undefined names, import order) in
    the package, its tests, benchmarks, comparisons and scripts."""
    import shutil
    import subprocess
    import sys

    ruff = shutil.which("ruff") or str(Path(sys.executable).parent / "ruff")
    if not Path(ruff).exists():
        pytest.skip("ruff is not installed (it comes with the [dev] extra)")
    root = SRC.parents[1]
    paths = [str(SRC)] + [str(root / d) for d in ("tests", "benchmarks", "comparisons", "scripts") if (root / d).is_dir()]
    r = subprocess.run([ruff, "check", *paths], capture_output=True, text=True, cwd=root)
    assert r.returncode == 0, r.stdout[-3000:]
