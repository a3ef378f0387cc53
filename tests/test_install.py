"""A non-editable install runs ``contourmesh reproduce`` from outside the checkout (issue 11).

The package is built from a copy of the sources and installed with ``--no-deps`` into a fresh
virtual environment that sees this interpreter's packages (through a ``.pth`` line), so nothing
is downloaded.  The installed package must find the paper's tables as package data.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _setuptools_ok() -> bool:
    try:
        import setuptools
    except ImportError:
        return False
    return int(setuptools.__version__.split(".")[0]) >= 77  # `license = "MIT"` (PEP 639)


@pytest.mark.slow
@pytest.mark.skipif(not (ROOT / "pyproject.toml").is_file(), reason="needs the source checkout (pyproject.toml)")
@pytest.mark.skipif(not _setuptools_ok(), reason="building offline needs setuptools>=77 in this environment")
def test_installed_package_reproduces_from_outside_the_checkout(tmp_path):
    src = tmp_path / "src-copy"
    src.mkdir()
    shutil.copytree(ROOT / "src", src / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          check=True, capture_output=True, text=True).stdout.strip()
    import sysconfig

    # this environment's packages (numpy, numba, ...) after the new venv's own, without its .pth files
    Path(site, "host_packages.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps",
                    "--no-build-isolation", "--no-index", str(src)], check=True, env=env, cwd=tmp_path)
    shutil.rmtree(src)  # the installed package must not need the sources
    out = tmp_path / "paper-out"
    script = textwrap.dedent(f"""
        import sys
        import contourmesh
        assert "site-packages" in contourmesh.__file__, contourmesh.__file__
        import contourmesh.compare.paper as paper
        real = paper.compute_table
        small = {{"sphere": (15,), "spheroid": ((10, 6),)}}
        paper.compute_table = lambda which, progress=True: real(which, sizes=small[which], progress=False)
        from contourmesh.cli import main
        sys.exit(main(["reproduce", "--out", {str(out)!r}, "--quiet"]))
    """)
    run = subprocess.run([str(py), "-c", script], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    for name in ("table1_sphere.csv", "table2_spheroid.csv", "figure2_sphere.png", "figure3_spheroid.png"):
        assert (out / name).stat().st_size > 0, name
    # the published values came along: the r = 15 row carries the paper's area
    assert "3305" in (out / "table1_sphere.csv").read_text()
    assert (venv / "bin" / "contourmesh").is_file()
