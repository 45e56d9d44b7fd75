"""`swingbench run`: the suites for solvers x configs x seeds on cases, measured into a results
folder (`cmd_run`), then the report of its rows. What a run may name is checked before anything is
measured (`harness.usage.UsageError`); how it ends is `harness.cli.outcome.outcome`'s.

This module imports only the standard library until the command runs: the CLI imports it to build
its parser."""

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
from harness.cli.readme import README_END, README_START, around
from harness.cli.report import DOCS_HELP, write_docs
from harness.usage import UsageError, check_known

__all__ = ["add_parser", "cmd_run"]


def _suite_names() -> list[str]:
    """The suites, by name, without importing them (importing the suites takes a second): one
    module of `harness.suites` each, as `harness.suites.SUITES` finds them."""
    import pkgutil
    from importlib.util import find_spec

    spec = find_spec("harness.suites")
    where = spec.submodule_search_locations if spec is not None else None
    return sorted(m.name for m in pkgutil.iter_modules(where or []) if not m.name.startswith("_"))


def add_parser(sub) -> None:
    from solvers import SOLVERS  # names only: no adapter is imported

    run = sub.add_parser(
        "run", help="measure: the suites for solvers x configs x seeds on cases, into --out",
        description="Run suites for solvers x configs x seeds; append each row to OUT/rows.jsonl as it is "
                    "measured; write tidy CSV, Markdown and LaTeX tables, plots and OUT/README.md; print the "
                    "tables. Trained models are cached in .cache/models by configuration, seed and code version.")
    run.add_argument("--suite", nargs="+", default=None, metavar="NAME",
                     help=f"suites to run (default: all but scaling): {', '.join(_suite_names())}; "
                          "scaling measures cost, memory and accuracy against the number of machines, each unit in "
                          "a process of its own under --unit-seconds and --unit-memory, on the scaling cases "
                          "(wscc9 ... case2869pegase) unless --case names others; cct finds each fault case's "
                          "critical clearing time with every adapter that integrates fault cases (fault cases "
                          "only), when run alone on the 12 fault cases ('<case>-<contingency>'; --quick: "
                          "wscc9's and kundur4's) unless --case names others")
    run.add_argument("--solver", nargs="+", default=None, metavar="NAME",
                     help=f"adapters to run (default: every registered one): {', '.join(SOLVERS)}")
    run.add_argument("--config", nargs="+", default=None, metavar="NAME",
                     help="named configurations to run (default: every config of each adapter but those the "
                          "run leaves out: make bench the ablations, such as the two-output PINNs, and the configs "
                          "for large systems, which the scaling suite runs; on the fault cases also the configs that are "
                          "a point of the precision sweep, such as tight)")
    run.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                     help="set an adapter option in every selected adapter that has it (repeatable; VALUE "
                          "read as JSON where it is, e.g. --option optimizer=lbfgs --option max_iterations=100); "
                          "the rows' variant shows it")
    run.add_argument("--case", nargs="+", default=None, metavar="NAME",
                     help="cases (default: smib-inference, the multi-machine wscc9, kundur4, ieee39 and the fault "
                          "cases wscc9-bus8-line8-9, kundur4-bus7-line7-8a; --quick: smib-inference, wscc9 and "
                          "wscc9-bus8-line8-9); identification of a SMIB case uses smib-identification with "
                          "the (m, d) pairs, of a multi-machine case the case's own parameters")
    add_case_file_options(run)
    size = run.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true",
                      help="smoke test, a few minutes: one seed, 150 PINN iterations, small timing budgets")
    size.add_argument("--full", action="store_true",
                      help="every seed (5), the paper's (m, d) and the 10 pairs, both noise levels; long")
    run.add_argument("--noise-draws", type=int, default=None, metavar="K",
                     help="identify from K draws of the noise at each noise level above 0 (default 1): the "
                          "identification table then counts how often each 95 %% interval holds the truth")
    run.add_argument("--verdict-pinn", action="append", default=[], metavar="NAME[:CONFIG]",
                     help="measure this trained adapter (a plugin's too), in CONFIG or every named config of its own, "
                          "in the verdict suite and the cct suite's search over the verdict seeds, in place of the JAX "
                          "PINN's default, marching and fault-marching (repeatable); it must be among the selected "
                          "solvers and configs")
    run.add_argument("--threads", type=int, default=2, help="threads for BLAS, torch and XLA (default 2)")
    run.add_argument("--update-readme", type=Path, default=None, metavar="README",
                     help="also replace the generated verdicts section of this README (and write the results "
                          "pages, --docs)")
    run.add_argument("--docs", type=Path, default=None, metavar="PAGES", help=DOCS_HELP)
    run.add_argument("--unit-seconds", type=float, default=None, metavar="S",
                     help="run each unit (an adapter on a case: build, fit, suites) in a fresh process and "
                          "stop it after S seconds with a 'skipped: out of time' row (scaling: 1800)")
    run.add_argument("--unit-memory", type=float, default=None, metavar="MIB",
                     help="likewise, stop a unit whose resident memory exceeds MIB MiB (scaling: 16384)")
    add_shared_options(
        run, out=Path("results"),
        resume_help="keep OUT/rows.jsonl and run only the units of work it does not record as complete (what an "
                    "interrupted unit left, and a completed unit that lost a row, are set aside in "
                    "OUT/rows.jsonl.set-aside and measured again; failed units are results and are kept); resuming "
                    "a finished run changes nothing",
        scheduler_help="run the units on this dask.distributed scheduler (e.g. tcp://127.0.0.1:8786) instead of in "
                       "this process; its workers need swingbench installed and run one unit at a time (dask worker "
                       "ADDRESS --nthreads 1)",
        dask_local_help="run the units on a local dask.distributed cluster of one worker process")


def cmd_run(args: argparse.Namespace) -> int:
    from harness.measure.timing import pin_threads

    if args.threads < 1:
        raise UsageError("swingbench run: --threads must be >= 1")
    pin_threads(args.threads)  # before numpy's BLAS, torch or XLA start their pools

    from dataclasses import replace

    from harness.cli.interrupts import answered_at_once
    from harness.cli.outcome import outcome, read_rows
    from harness.cli.results_folder import interrupted_message, open_results
    from harness.provenance import metadata
    from harness.report.files import write_report
    from harness.run import executors
    from harness.run.plan import plan
    from harness.run.runner import check_units, execute
    from harness.run.selection import default_specs, parse_option, parse_verdict_pinns, with_options
    from harness.settings import DEFAULT, FULL, QUICK, Limits
    from harness.suites import DEFAULT_SUITES, SUITES
    from solvers import SOLVERS, solver_class
    from solvers.atomic import atomic_write
    from systems.cases import CASES

    check_known("run", "suite(s)", args.suite, SUITES)
    check_known("run", "case(s)", args.case, CASES)
    args.case = (args.case or []) + register_file_cases(args, "run") or None
    check_known("run", "solver(s)", args.solver, SOLVERS)
    configs = sorted({c for name in args.solver or SOLVERS if SOLVERS[name] for c in SOLVERS[name].CONFIGS})
    check_known("run", "config(s)", args.config, configs)
    suites = args.suite or list(DEFAULT_SUITES)
    settings = replace(QUICK if args.quick else FULL if args.full else DEFAULT,
                       threads=args.threads, retrain=args.retrain)
    if args.verdict_pinn:
        try:
            settings = replace(settings, verdict_pinns=parse_verdict_pinns(args.verdict_pinn))
        except ValueError as exc:
            raise UsageError(f"swingbench run: --verdict-pinn {exc}") from None
    if args.config:  # a config named runs on the fault cases too
        settings = replace(settings, fault_omit_marks=())
    if args.solver:  # and so does an adapter named
        settings = replace(settings, fault_omit_solvers=tuple(s for s in settings.fault_omit_solvers if s not in args.solver))
    if args.noise_draws is not None:
        if args.noise_draws < 1:
            raise UsageError(f"swingbench run: --noise-draws must be >= 1, got {args.noise_draws}")
        settings = replace(settings, noise_draws=args.noise_draws)
    if "scaling" in suites and suites != ["scaling"]:
        raise UsageError("swingbench run: --suite scaling runs alone (its units run in processes of their own, "
                         "its PINNs on an iteration budget)")
    if suites == ["scaling"]:
        settings = settings.for_scaling()
    limits = settings.unit_limits
    if args.unit_seconds is not None or args.unit_memory is not None:
        if any(x is not None and not x > 0 for x in (args.unit_seconds, args.unit_memory)):
            raise UsageError("swingbench run: --unit-seconds and --unit-memory must be > 0")
        given = {"seconds": args.unit_seconds, "rss_mb": args.unit_memory}
        limits = (limits or Limits())._replace(**{k: v for k, v in given.items() if v is not None})
    settings = replace(settings, unit_limits=limits)
    alone = {"scaling": settings.scaling_cases, "cct": settings.cct_cases}  # a suite run alone: its own cases
    default_cases = alone.get(suites[0], settings.cases) if len(suites) == 1 else settings.cases
    cases = [CASES[name] for name in args.case or default_cases]
    specs = default_specs(args.solver, args.config, settings)
    if not specs:
        raise UsageError("swingbench run: no solver/config combination selected")
    if args.verdict_pinn and {"verdict", "cct"} & set(suites):
        _check_verdict_pinns(specs, settings)
    if args.option:
        try:
            given = dict(parse_option(text) for text in args.option)
            specs = with_options(specs, given)
        except ValueError as exc:
            raise UsageError(f"swingbench run: --option: {exc}") from None
        settings = settings.given(given)
    units = plan(specs, cases, [SUITES[name] for name in suites], settings).units
    try:  # every option on every case it runs on, before the first measurement
        check_units(units, settings)
    except ValueError as exc:
        raise UsageError(f"swingbench run: {exc}") from None
    if args.update_readme:
        around(args.update_readme, README_START, README_END, "run")
    store, contents = open_results(args.out, args.resume, "run", overwrite=args.overwrite,
                                   same={"settings": settings.name, "threads": args.threads})
    outputs = [args.out] + ([args.update_readme] if args.update_readme else [])
    classes = {spec.solver: solver_class(spec.solver) for spec in specs}
    blas = {name: cls.blas_threads for name, cls in classes.items() if cls is not None and cls.blas_threads}
    argv = getattr(args, "argv", sys.argv[1:])
    meta = {**metadata(args.threads, outputs), "settings": settings.name, "argv": argv,
            "blas_threads_by_adapter": blas or "as pinned"}
    atomic_write(args.out / "metadata.json", json.dumps(meta, indent=2, default=str))
    try:
        with answered_at_once(lambda: interrupted_message(store, argv)), \
                executors.choose(args.scheduler, args.dask_local, workers=1, threads=1) as executor:  # a unit at a time
            counts = execute(units, settings, store, executor, progress=progress_setting(args),
                             done=contents.completed if contents else None)  # resume prepared
    except executors.ExecutorUnavailable as exc:
        raise UsageError(f"swingbench: {exc}") from None
    except KeyboardInterrupt:
        print(interrupted_message(store, argv), file=sys.stderr)
        return 130
    rows = read_rows(store)
    markdown = write_report(rows, args.out, meta)
    print(markdown)
    write_docs(args, rows, meta, args.out)
    print(f"[swingbench] wrote {args.out}/", file=sys.stderr)
    return outcome(rows, store.path, counts["lost"])


def _check_verdict_pinns(specs: list, settings) -> None:
    """UsageError unless every adapter of `settings.verdict_pinns` runs in one of its configs among `specs`."""
    for name, configs, _ in settings.verdict_pinns:
        if not any(spec.solver == name and spec.config in configs for spec in specs):
            raise UsageError(f"swingbench run: --verdict-pinn {name} ({', '.join(configs)}) is not among the selected "
                             "solvers and configs (--solver, --config; a run leaves out the configs marked ablation or "
                             "large systems unless --config names them)")
