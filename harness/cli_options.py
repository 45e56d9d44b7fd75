"""The options `swingbench run` and `swingbench sweep` share, each defined once: both commands run
units of work through `harness.runner` into one results folder, so these options mean the same in
both; what differs (the default folder, what a unit of work is called, how many workers) is passed in.

This module imports only the standard library: the CLI imports it to build its parser."""

from __future__ import annotations

import argparse
from pathlib import Path

PROGRESS = {"auto": None, "on": True, "off": False}  # --progress -> `solvers.progress.progress_enabled`


def add_shared_options(parser: argparse.ArgumentParser, *, out: Path, resume_help: str, scheduler_help: str,
                       dask_local_help: str) -> None:
    """Add --out (default `out`), the mutually exclusive --resume / --overwrite, --retrain,
    --progress and the mutually exclusive --scheduler / --dask-local to `parser`."""
    parser.add_argument("--out", type=Path, default=out,
                        help=f"output folder (default {out}/); one that holds the rows of a run needs --resume or "
                             "--overwrite")
    again = parser.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true", help=resume_help)
    again.add_argument("--overwrite", action="store_true",
                       help="start again in an OUT that holds the rows of a run: OUT/rows.jsonl and OUT/metadata.json "
                            "are renamed to rows.<UTC time>.jsonl and metadata.<UTC time>.json beside them (git "
                            "ignores those names; delete them when they are no longer wanted), never deleted")
    parser.add_argument("--retrain", action="store_true", help="train again even if a cached model exists")
    parser.add_argument("--progress", choices=list(PROGRESS), default="auto",
                        help="progress bar on stderr (auto: only on a terminal, not under pytest or CI)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", default=None, help=scheduler_help)
    where.add_argument("--dask-local", action="store_true", help=dask_local_help)


def progress_setting(args: argparse.Namespace) -> bool | None:
    """--progress as `progress_enabled` takes it: None (auto), True or False."""
    return PROGRESS[args.progress]
