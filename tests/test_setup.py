"""scripts/setup.sh says what it is doing, and warms every kernel the README's commands use (issue 12, item 10)."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SETUP = ROOT / "scripts" / "setup.sh"
WARM = ROOT / "scripts" / "warm_kernels.py"

pytestmark = pytest.mark.skipif(not SETUP.is_file(), reason="needs the source checkout (scripts/setup.sh)")


def test_setup_says_each_step_on_stderr(tmp_path):
    # setup.sh ran for 47 s (71 s with --dev) without a word
    (tmp_path / "scripts").mkdir()
    script = tmp_path / "scripts" / "setup.sh"
    script.write_text(SETUP.read_text())
    (tmp_path / "scripts" / "warm_kernels.py").write_text("")
    log = tmp_path / "calls.log"
    venv_bin = tmp_path / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    stub = venv_bin / "python"  # stands in for the venv's python: records each call, does nothing
    stub.write_text(f"#!/bin/sh\necho \"$@\" >> {log}\n")
    stub.chmod(stub.stat().st_mode | stat.S_IXUSR)
    run = subprocess.run(["bash", str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout == ""
    lines = run.stderr.splitlines()
    assert all(line.startswith("setup: ") for line in lines), lines
    said = "\n".join(lines)
    calls = log.read_text().splitlines()
    assert calls == ["-m pip install -q --upgrade pip", "-m pip install -q -e .", "scripts/warm_kernels.py"]
    for words in ("upgrading pip", "installing contourmesh", "compiling the numba kernels", "ready in"):
        assert words in said, (words, said)
    assert said.count("done in") == 3  # one per step that ran


def test_warm_up_covers_the_kernels_of_the_readme_commands():
    # after set-up, the first reproduce / contour-file mesh / --refine band each still compiled ~10 s:
    # after the warm-up, the README's operations must not need a single new compiled signature
    probe = textwrap.dedent(f"""
        import gc, runpy, sys, warnings
        import numpy as np
        from numba.core.registry import CPUDispatcher

        def signatures():
            return {{(d.py_func.__module__, d.py_func.__qualname__, str(s))
                    for d in gc.get_objects() if isinstance(d, CPUDispatcher) for s in d.signatures}}

        warm = runpy.run_path({str(WARM)!r})
        assert warm["main"]() == 0
        before = signatures()
        warnings.simplefilter("ignore")
        import contourmesh
        from contourmesh.compare.paper import compute_table
        compute_table("sphere", sizes=(15, 20), progress=False)
        compute_table("spheroid", sizes=((10, 6),), progress=False)
        contourmesh.mesh("sphere:r=20", polygon="mlp", triangulation="optimal")
        contourmesh.mesh("torus:R=12,r=4,center=0.3;0.1;0.2")
        contourmesh.mesh("sphere:r=10", refine="band")
        v = np.zeros((10, 12, 12), np.uint8); v[2:8, 2:10, 3:9] = 127; v[4, 5:7, 5:7] = 0
        contourmesh.mesh(v, label=127, spacing=(0.667, 0.617, 0.617))
        zz, yy, xx = np.mgrid[:16, :16, :16]
        contourmesh.mesh((zz - 7.4) ** 2 / 1.3 + (yy - 7.7) ** 2 + (xx - 7.2) ** 2 < 30, refine="band")
        new = sorted(signatures() - before)
        print("NEW", new)
        sys.exit(1 if new else 0)
    """)
    env = {k: v for k, v in os.environ.items()}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src")] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=600, env=env)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
