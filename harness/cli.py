"""Command line: `swingbench run` measures, `swingbench report DIR` re-renders tables from CSV rows."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness import sweep  # imports only the standard library until a sweep runs

SUITE_NAMES = ("accuracy", "latency", "work_precision", "identification")

DESCRIPTION = """\
swingbench: physics-informed neural networks against classical ODE solvers on the
single-machine infinite-bus swing equation (Misyris et al., PESGM 2020).

Every measurement is taken on this machine, in one run, warm, with pinned threads, against a tight
DOP853 reference (rtol = atol = 1e-12); preparation (build, JIT, training) is reported apart from
query time. Every speed verdict compares a PINN with the fastest classical option at least as
accurate, on three rungs: the literature's baseline (scipy RK45 looped), the best Python-driven and
the best compiled (numba, diffrax) classical solver."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swingbench", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser(
        "run", help="run suites and write tables to --out",
        description="Run suites for solvers x configs x seeds; append each row to OUT/rows.jsonl as it is "
                    "measured; write tidy CSV, Markdown and LaTeX tables, plots and OUT/README.md; print the "
                    "tables. Trained models are cached in .cache/models by configuration, seed and code version.")
    run.add_argument("--suite", nargs="+", default=None, metavar="NAME",
                     help=f"suites to run (default: all): {', '.join(SUITE_NAMES)}")
    run.add_argument("--solver", nargs="+", default=None, metavar="NAME",
                     help="adapters to run (default: every registered one)")
    run.add_argument("--config", nargs="+", default=None, metavar="NAME",
                     help="named configurations to run (default: every config of each adapter)")
    run.add_argument("--case", nargs="+", default=["smib-inference"], metavar="NAME",
                     help="cases of the forward suites (default: smib-inference); identification always "
                          "uses smib-identification with the (m, d) pairs")
    size = run.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true",
                      help="smoke test, a few minutes: one seed, 150 PINN iterations, small timing budgets")
    size.add_argument("--full", action="store_true",
                      help="every seed (5), the paper's (m, d) and the 10 pairs, both noise levels; long")
    run.add_argument("--resume", action="store_true",
                     help="keep OUT/rows.jsonl and run only what it does not hold yet")
    run.add_argument("--retrain", action="store_true", help="train again even if a cached model exists")
    run.add_argument("--threads", type=int, default=2, help="threads for BLAS, torch and XLA (default 2)")
    run.add_argument("--out", type=Path, default=Path("results"), help="output folder (default results/)")
    run.add_argument("--update-readme", type=Path, default=None, metavar="README",
                     help="also replace the generated tables section of this README")
    run.add_argument("--progress", choices=["auto", "on", "off"], default="auto",
                     help="progress bar on stderr (auto: only on a terminal)")

    report = sub.add_parser("report", help="re-render tables from a results folder without running",
                            description="Read DIR/rows.jsonl and rewrite DIR's CSV and Markdown tables.")
    report.add_argument("directory", type=Path)
    sweep.add_parser(sub)
    return parser


def cmd_run(args: argparse.Namespace) -> int:
    from harness.timing import pin_threads

    if args.threads < 1:
        raise SystemExit("--threads must be >= 1")
    pin_threads(args.threads)  # before numpy's BLAS, torch or XLA start their pools

    from dataclasses import replace

    from harness.cases import CASES
    from harness.report import metadata, write_report
    from harness.runner import run_suites
    from harness.runs import DEFAULT, FULL, QUICK, default_specs
    from harness.store import RowStore, atomic_write
    from harness.suites import SUITES

    suites = args.suite or list(SUITES)
    for name in suites:
        if name not in SUITES:
            raise SystemExit(f"unknown suite {name!r}; known: {', '.join(SUITES)}")
    cases = []
    for name in args.case:
        if name not in CASES:
            raise SystemExit(f"unknown case {name!r}; known: {', '.join(CASES)}")
        cases.append(CASES[name])
    settings = replace(QUICK if args.quick else FULL if args.full else DEFAULT,
                       threads=args.threads, retrain=args.retrain)
    try:
        specs = default_specs(args.solver, args.config, settings)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    if not specs:
        raise SystemExit("no solver/config combination selected")
    store = RowStore(args.out)
    if not args.resume:
        store.clear()
    outputs = [args.out] + ([args.update_readme] if args.update_readme else [])
    from solvers import SOLVERS

    blas = {name: cls.blas_threads for name, cls in SOLVERS.items() if cls is not None and cls.blas_threads}
    meta = {**metadata(args.threads, outputs), "settings": settings.name, "argv": sys.argv[1:],
            "blas_threads_by_adapter": blas or "as pinned"}
    atomic_write(args.out / "metadata.json", json.dumps(meta, indent=2, default=str))
    progress = {"auto": None, "on": True, "off": False}[args.progress]
    run_suites(specs, cases, suites, settings, store, progress=progress, resume=args.resume)
    markdown = write_report(store.rows(), args.out, meta)
    print(markdown)
    if args.update_readme:
        from harness.report import headline_markdown

        update_readme(args.update_readme, headline_markdown(store.rows(), meta), args.out)
    print(f"[swingbench] wrote {args.out}/", file=sys.stderr)
    return 0


README_START, README_END = "<!-- swingbench:tables:start -->", "<!-- swingbench:tables:end -->"


def update_readme(path: Path, markdown: str, out: Path) -> None:
    """Replace the text between the README's table markers with the run's tables."""
    from harness.store import atomic_write

    text = path.read_text(encoding="utf-8")
    if README_START not in text or README_END not in text:
        raise SystemExit(f"{path} has no {README_START} ... {README_END} section to update")
    head, rest = text.split(README_START, 1)
    _, tail = rest.split(README_END, 1)
    body = (f"\n_Generated by `swingbench run` into `{out}/` (all tables and plots: `{out}/README.md`); "
            f"do not edit by hand._\n\n{markdown}\n![work-precision]({out}/work_precision.png)\n")
    atomic_write(path, head + README_START + body + README_END + tail)


def cmd_report(args: argparse.Namespace) -> int:
    from harness.report import write_report
    from harness.store import RowStore

    store = RowStore(args.directory)
    rows = store.rows()
    if not rows:
        raise SystemExit(f"no rows in {store.path}")
    meta_path = args.directory / "metadata.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    print(write_report(rows, args.directory, meta))
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    return {"run": cmd_run, "report": cmd_report, "sweep": sweep.cmd_sweep}[args.command](args)


if __name__ == "__main__":
    raise SystemExit(main())
