"""Command line: `swingbench run` measures, `swingbench report DIR` re-renders tables from CSV rows."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

DESCRIPTION = """\
swingbench: physics-informed neural networks against classical ODE solvers on the
single-machine infinite-bus swing equation (Misyris et al., PESGM 2020).

Every measurement is taken on this machine, in one run, warm, with pinned threads, against a tight
DOP853 reference (rtol = atol = 1e-12); preparation (build, JIT, training) is reported apart from
query time."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swingbench", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="run suites and write tables to --out",
                         description="Run suites for solvers x configs x cases; write tidy CSV, Markdown "
                                     "tables and metadata to --out and print the tables.")
    run.add_argument("--suite", nargs="+", default=None, metavar="NAME",
                     help="suites to run (default: all): accuracy, latency")
    run.add_argument("--solver", nargs="+", default=None, metavar="NAME",
                     help="adapters to run (default: every registered one)")
    run.add_argument("--config", nargs="+", default=None, metavar="NAME",
                     help="named configurations to run (default: every config of each adapter)")
    run.add_argument("--case", nargs="+", default=["smib-inference"], metavar="NAME",
                     help="cases (default: smib-inference); known: smib-inference, smib-identification")
    run.add_argument("--quick", action="store_true", help="small timing budgets: a smoke test")
    run.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    run.add_argument("--threads", type=int, default=2, help="threads for BLAS, torch and XLA (default 2)")
    run.add_argument("--out", type=Path, default=Path("results"), help="output folder (default results/)")
    run.add_argument("--update-readme", type=Path, default=None, metavar="README",
                     help="also replace the generated tables section of this README")

    report = sub.add_parser("report", help="re-render tables from a results folder without running",
                            description="Read DIR/rows.jsonl and rewrite DIR's CSV and Markdown tables.")
    report.add_argument("directory", type=Path)
    return parser


def _progress(quiet: bool):
    if quiet:
        return None
    return lambda msg: print(f"[swingbench] {msg}", file=sys.stderr, flush=True)


def cmd_run(args: argparse.Namespace) -> int:
    from harness.timing import pin_threads

    if args.threads < 1:
        raise SystemExit("--threads must be >= 1")
    pin_threads(args.threads)  # before numpy's BLAS, torch or XLA start their pools

    from harness.cases import CASES
    from harness.report import metadata, write_report
    from harness.runner import run_suites
    from harness.runs import Settings, default_specs
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
    try:
        specs = default_specs(args.solver, args.config)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    if not specs:
        raise SystemExit("no solver/config combination selected")
    settings = Settings(quick=args.quick, threads=args.threads,
                        latency_budget_s=0.2 if args.quick else 1.0, min_repeats=3 if args.quick else 5)
    store = RowStore(args.out)
    store.clear()
    meta = metadata(args.threads)
    atomic_write(args.out / "metadata.json", json.dumps(meta, indent=2))
    run_suites(specs, cases, suites, settings, store, progress=_progress(args.quiet))
    markdown = write_report(store.rows(), args.out, meta)
    print(markdown)
    if args.update_readme:
        update_readme(args.update_readme, markdown, args.out)
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
    body = f"\n_Generated by `swingbench run` into `{out}/`; do not edit by hand._\n\n{markdown}\n"
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
    return {"run": cmd_run, "report": cmd_report}[args.command](args)


if __name__ == "__main__":
    raise SystemExit(main())
