"""Every code block of the README runs, exactly as written.

Blocks run in order in one scratch folder (so a file one block writes is there for the next),
with the virtual environment's ``bin`` first on ``PATH`` (as after ``source .venv/bin/activate``)
and ``comparisons/`` linked in.  ``python`` blocks run with this interpreter, ``bash`` blocks with
``bash -e``; ``text`` blocks are output samples, not code.  The set-up block is the two commands
that ``.ci/run`` itself runs; the test checks that it does, rather than running set-up inside the
suite it sets up.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
BLOCKS = [(m.group(1), m.group(2)) for m in re.finditer(r"^```(\w*)\n(.*?)^```", README, re.S | re.M)]
SETUP = BLOCKS[0][1]


def test_every_block_has_a_language():
    assert BLOCKS and all(lang in ("python", "bash", "text") for lang, _ in BLOCKS), [b[0] for b in BLOCKS]


def test_the_setup_block_is_what_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text()
    lines = [ln for ln in SETUP.strip().splitlines() if ln.strip()]
    assert len(lines) == 2, "the README's set-up is two commands"
    for line in lines:
        assert line in ci.splitlines(), f".ci/run must run {line!r} as written"


@pytest.mark.slow
def test_readme_code_blocks_run(tmp_path):
    (tmp_path / "comparisons").symlink_to(ROOT / "comparisons")
    env = dict(os.environ, PATH=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""),
               MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    env["PYTHONPATH"] = str(ROOT / "src")
    ran = 0
    for k, (lang, code) in enumerate(BLOCKS):
        if code == SETUP or lang == "text":
            continue
        if lang == "python":
            cmd = [sys.executable, "-c", code]
        else:
            cmd = ["bash", "-e", "-c", code]
        r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, f"README block {k} ({lang}) failed:\n{code}\n--- stderr ---\n{r.stderr[-3000:]}"
        ran += 1
    assert ran >= 2
    assert (tmp_path / "sphere.ply").is_file() and (tmp_path / "labels.ply").is_file()
    assert (tmp_path / "every-label" / "labels.csv").is_file()
