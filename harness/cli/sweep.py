"""`swingbench sweep SPEC`: a grid of adapter options x seeds x cases, one accuracy run per point.

The paper chose its network size, N_u and N_f by an "extensive investigation"; a sweep runs such a
grid and writes one row per accuracy measurement of every run. Sweeps measure accuracy and
training cost only: several runs share the machine's cores, so no query latency is measured here
(the latency suite of `swingbench run` runs alone).

SPEC is a JSON file of a grid over one adapter's options (format and validation: `harness.run.sweep_spec`).

Each run is one unit of `harness.run.runner` (the runner of `swingbench run`: one row store, one
resume rule, one thread-pinning helper, one progress bar): the adapter is built, fitted
(`harness.model_cache.fit_or_load`: trained models come from the model cache unless --retrain) and its
accuracy measured (`harness.suites.accuracy`), in a worker process pinned to 1 thread. Its rows are a
`fit` row (fit_s, iterations, loss) and the accuracy rows, with the swept values as `p_<option>`
columns and the grid point's index as `point`. A run that raises gives `failed: ...` rows and the
sweep goes on.

Executors (`harness.run.executors`, only the executor differs): by default joblib's loky backend with
--workers processes of 1 thread each; with --scheduler ADDRESS an existing dask.distributed
cluster (its workers should run 1 thread each, e.g. `dask worker ADDRESS --nthreads 1`, and have
swingbench installed), with --dask-local a LocalCluster of --workers processes, 1 thread each.

Exit status: 0 when every run was measured (a declared skip counts as measured), 1 when a unit of
work failed (one line names the runs and where their rows are) or the executor lost some, 2 for a
bad spec or option or a Dask executor that cannot be had, 130 on Ctrl-C.

Output in --out: rows.jsonl (each run recorded as it finishes: an interrupted sweep keeps its
finished runs; --resume runs only the rest), then, written atomically, sweep.csv (tidy: every row),
sweep.md (per grid point and case: median and [min, max] over seeds of the relative L2 error of delta
and omega against the DOP853 reference, median fit seconds, runs ok/failed; both written by
`harness.report.sweep`) and metadata.json.

This module imports only the standard library at the top: the CLI imports it to build its parser.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness.cli.options import (
    add_case_file_options,
    add_shared_options,
    progress_setting,
    register_file_cases,
)
from harness.run.sweep_spec import SweepSpec, load_spec, parse_spec, sweep_settings

__all__ = ["SweepSpec", "add_parser", "cmd_sweep", "load_spec", "parse_spec"]


HELP = "run a grid of adapter options x seeds x cases (accuracy and training cost, no latency)"
EPILOG = """\
SPEC (JSON):
  {"solver": "torch-pinn", "config": "default", "cases": ["smib-inference"],
   "seeds": [0, 1, 2], "grid": {"width": [10, 20], "n_f": [2000, 8000]},
   "options": {"max_iterations": 500}}

  solver    a registered adapter (required)
  config    one of its named configs (default "default")
  cases     case names (default ["smib-inference"])
  seeds     integers, only for adapters that train (default [0])
  grid      option -> non-empty list of values; runs = product(grid) x seeds x cases
  options   option overrides fixed for every run
  description  free text
Keys of grid and options must be options of the adapter; "seed" and "threads" are set by the sweep.

Each run builds the adapter, fits it (from the model cache unless --retrain) and measures accuracy
on the 100 x 201 grid, in a worker process pinned to 1 thread. No latency is measured: runs share
the cores (run `swingbench run --suite latency` alone for that). Rows are appended to
OUT/rows.jsonl as runs finish; OUT/sweep.csv, OUT/sweep.md and OUT/metadata.json at the end."""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the `sweep` sub-command to `subparsers` (from `ArgumentParser.add_subparsers`)."""
    sweep = subparsers.add_parser(
        "sweep", help=HELP, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run SPEC's grid of option values x seeds x cases, one accuracy run per point, "
                    "locally with joblib (loky, --workers processes of 1 thread) or on Dask.")
    sweep.add_argument("spec", type=Path, metavar="SPEC", help="sweep specification, a JSON file (format below)")
    sweep.add_argument("--workers", type=int, default=2,
                       help="worker processes of 1 thread each, for joblib and --dask-local (default 2)")
    add_shared_options(
        sweep, out=Path("results/sweep"),
        resume_help="keep OUT/rows.jsonl and run only the runs it does not record as complete (a failed run is a "
                    "result: it is kept)",
        scheduler_help="run on this dask.distributed scheduler (e.g. tcp://host:8786) instead of joblib; give its "
                       "workers 1 thread each",
        dask_local_help="run on a local dask.distributed cluster of --workers processes, 1 thread each")
    add_case_file_options(sweep)
    sweep.add_argument("--dry-run", action="store_true", help="validate SPEC, print the runs and exit")
    return sweep


def cmd_sweep(args: argparse.Namespace) -> int:
    """`swingbench sweep`: 0 when every run was measured, 1 when a unit of work failed (its rows
    say why; one line names them) or the executor lost some (`--resume` runs them), 2 (a
    `UsageError`) for a bad spec or a Dask executor that cannot be had, 130 on Ctrl-C."""
    from harness.usage import UsageError

    if args.workers < 1:
        raise UsageError("swingbench sweep: --workers must be >= 1")
    register_file_cases(args, "sweep")  # SPEC's "cases" may name them
    try:
        spec = load_spec(args.spec)
    except ValueError as exc:
        raise UsageError(f"swingbench sweep: {exc}") from None
    units = spec.units()
    if args.dry_run:
        for unit in units:
            print(unit.label)
        print(f"[swingbench sweep] {len(units)} runs", file=sys.stderr)
        return 0

    from harness.cli.interrupts import answered_at_once
    from harness.cli.outcome import outcome
    from harness.cli.results_folder import interrupted_message, open_results
    from harness.provenance import metadata
    from harness.report.sweep import write_outputs
    from harness.run import executors
    from harness.run.runner import execute
    from solvers.atomic import atomic_write

    store, contents = open_results(args.out, args.resume, "sweep", same={"spec": spec.as_json()},
                                   overwrite=args.overwrite)
    settings = sweep_settings(args.retrain)
    executor = (f"dask scheduler {args.scheduler}" if args.scheduler else
                f"dask LocalCluster, {args.workers} worker process(es)" if args.dask_local else
                f"joblib loky, {args.workers} worker process(es)")
    meta = {**metadata(1), "command": "sweep", "spec": spec.as_json(), "spec_file": str(args.spec),
            "runs": len(units), "executor": executor, "workers": args.workers, "argv": getattr(args, "argv", sys.argv[1:])}
    atomic_write(args.out / "metadata.json", json.dumps(meta, indent=2, default=str))
    done = contents.completed if contents else set()
    print(f"[swingbench sweep] {len(units)} runs on {executor}"
          + (f"; {len(done)} unit(s) of work already recorded" if done else ""), file=sys.stderr)
    argv = getattr(args, "argv", sys.argv[1:])
    try:
        with answered_at_once(lambda: interrupted_message(store, argv)), \
                executors.choose(args.scheduler, args.dask_local, args.workers, local=executors.joblib(args.workers)) as run:
            counts = execute(units, settings, store, run, progress=progress_setting(args), done=done)
    except executors.ExecutorUnavailable as exc:
        raise UsageError(f"swingbench: {exc}") from None
    except KeyboardInterrupt:
        print(interrupted_message(store, argv), file=sys.stderr)
        return 130
    markdown = write_outputs(store, args.out, meta)
    print(markdown)
    print(f"[swingbench sweep] units of work: {counts['ok']} ok, {counts['skipped']} skipped, {counts['failed']} "
          f"failed, {counts['lost']} lost to the executor; wrote {args.out}/", file=sys.stderr)
    return outcome(store.rows(), store.path, counts["lost"])
