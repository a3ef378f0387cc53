"""``contourmesh compare SPEC.toml``: the sub-command's parser and its action.

Kept apart from :mod:`contourmesh.compare.runner` so that building the command line (``--help``,
``--version``) imports nothing heavy; the runner is imported when the command runs.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

__all__ = ["add_compare_parser", "RunInterrupted", "SCHEDULER_HELP"]

SCHEDULER_HELP = ("run the rows on a Dask distributed cluster at this scheduler address (e.g. tcp://127.0.0.1:8786; "
                  "start one with `dask scheduler` and `dask worker tcp://127.0.0.1:8786`)")


class RunInterrupted(KeyboardInterrupt):
    """SIGTERM arrived: the run stops as on Ctrl-C (workers ended, finished rows kept)."""


def _on_sigterm(signum, frame):
    raise RunInterrupted(f"stopped by signal {signum}")


def _cmd_compare(args) -> int:
    from .runner import run_spec

    old = None
    if threading.current_thread() is threading.main_thread():
        old = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        res = run_spec(args.spec, args.out, jobs=args.jobs, scheduler=args.scheduler, progress=not args.quiet,
                       retry_failed=args.retry_failed)
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)
    counts: dict = {}
    for r in res["rows"]:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    out = Path(res["out"]).resolve()
    print(f"wrote {out}: {len(res['rows'])} rows ({res['ran']} run, {res['cached']} from the cache; "
          + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + "); "
          + ", ".join(Path(f).name for f in res["files"]))
    if res["executor_failed"]:
        print(f"contourmesh: error: {res['executor_failed']} rows were not run (the executor or the scheduler "
              "failed, not the method; see summary.md); they are not cached and a re-run retries them",
              file=sys.stderr)
        return 1
    return 0


def add_compare_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``contourmesh compare SPEC.toml [--out DIR] [--jobs N] [--scheduler ADDRESS]`` to a CLI.

    ``subparsers`` is the object ``ArgumentParser.add_subparsers()`` returned; the new parser's
    ``func(args)`` runs the comparison and returns the exit status: 0, or 1 when rows could not
    be run for a reason that is not the method's (the executor, the scheduler).
    """
    p = subparsers.add_parser(
        "compare", help="run a comparison spec (comparisons/*.toml): results.csv, summary.md, plots",
        description="Run every input x method x post-process x repeat of a comparison spec; finished rows are "
                    "cached, so an interrupted run resumes where it stopped. Ctrl-C or SIGTERM stops the run "
                    "and its workers; finished rows are kept.")
    p.add_argument("spec", help="the comparison spec, a TOML file (e.g. comparisons/quick.toml)")
    p.add_argument("--out", default=None, help="output folder (default: ./<spec stem>/ in the current directory)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default: 1, this process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help=SCHEDULER_HELP)
    p.add_argument("--retry-failed", action="store_true", help="re-run cached rows that failed or timed out")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_compare)
    return p
