"""Run the real-shapes comparison (``real.toml`` beside this file), or a part of it.

    nice -n 10 python comparisons/real/run.py --jobs 2 --resolutions 64,128
    nice -n 10 python comparisons/real/run.py --jobs 2 --resolutions 256
    python comparisons/real/run.py --report-only
    python comparisons/real/run.py --methods ours-mlp-optimal-band --retry-failed   (re-run one method)

Finished rows are cached in ``comparisons/real/cache`` (not committed) and the rows of the committed
``results.csv`` are re-imported first, so a run resumes and only missing rows are computed.  Writes
``results.csv``, ``summary.md``, ``error.png`` and ``runs.csv`` here, atomically.  The meshes come
from the shared data folder (env ``CONTOURMESH_DATA``, default ``../shared/data`` beside the checkout).
See :mod:`contourmesh.compare.real`.
"""

import sys
from pathlib import Path

from contourmesh.compare.real import main

if __name__ == "__main__":
    sys.exit(main(default_spec=str(Path(__file__).resolve().parent / "real.toml")))
