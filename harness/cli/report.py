"""`swingbench report DIR`: a results folder's tables, figures and README re-rendered from its rows
(`cmd_report`); with `--update-readme` and `--docs`, also the README's verdicts and the results
pages (`write_docs`, which `swingbench run` calls too); `swingbench report DIR ... --at-scale
README`: only the README's block of the verdict runs apart from the bench; `swingbench report DIR
--step-claim README`: only the README's block of pinnsim's step claim.

This module imports only the standard library until the command runs: the CLI imports it to build
its parser."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness.cli.readme import (
    AT_SCALE_END,
    AT_SCALE_START,
    README_END,
    README_START,
    STEP_CLAIM_END,
    STEP_CLAIM_START,
    around,
    replace_section,
)
from harness.usage import UsageError

__all__ = ["DOCS_HELP", "add_parser", "cmd_report", "write_docs"]

DOCS_HELP = ("write the documentation site's results pages into this folder: one page per case with its "
             "verdicts, tables and figures, and an index (default with --update-readme: docs/results beside the "
             "README)")


def add_parser(sub) -> None:
    report = sub.add_parser("report", help="re-render a results folder's tables, figures and pages from its rows",
                            description="Read DIR/rows.jsonl and rewrite DIR's CSV and Markdown tables and plots; "
                                        "with --update-readme and --docs, the README's verdicts and the results pages; "
                                        "with --at-scale, only the README's block of the verdict (or CCT) runs apart "
                                        "from the bench, from one or more DIRs.")
    report.add_argument("directory", type=Path, nargs="+", metavar="DIR")
    report.add_argument("--update-readme", type=Path, default=None, metavar="README",
                        help="also replace the generated verdicts section of this README (and write the results "
                             "pages, --docs)")
    report.add_argument("--docs", type=Path, default=None, metavar="PAGES", help=DOCS_HELP)
    report.add_argument("--at-scale", type=Path, default=None, metavar="README",
                        help="write only this README's generated block of verdict runs apart from make bench "
                             "(a scaling case's verdicts: too long for the bench), one paragraph per DIR in the "
                             "order given (a DIR of a PINN's CCT searches without verdicts: its CCT summary); "
                             "the folders' tables are left as they are")
    report.add_argument("--step-claim", type=Path, default=None, metavar="README",
                        help="write only this README's generated block of the step claim: per case, each "
                             "fixed-step method's largest step at COI rel. L2 <= 1e-3 and its grid time, from a "
                             "run that swept pinnsim's step beside the classical ones (one DIR); its tables are "
                             "left as they are")


def write_docs(args: argparse.Namespace, rows: list[dict], meta: dict, results: Path) -> None:
    """The results pages (`--docs`, or docs/results beside a README to update) and the README's
    verdicts, after the report wrote its tables and figures into `results`."""
    pages = args.docs or (args.update_readme.parent / "docs" / "results" if args.update_readme else None)
    if pages is None:
        return
    from harness.report.pages import readme_block, write_pages

    write_pages(rows, meta, pages, results)
    if args.update_readme:
        replace_section(args.update_readme, README_START, README_END,
                        readme_block(rows, meta, args.update_readme, pages, results), args.command)


def _read_run(directory: Path) -> tuple[list[dict], dict]:
    """(rows, metadata) of a results folder; UsageError when it is not one or holds no rows, a
    warning (and {}) for unreadable metadata."""
    from harness.cli.outcome import read_rows
    from harness.store import RowStore

    if not directory.is_dir():
        raise UsageError(f"swingbench report: {directory} is not a folder of results")
    store = RowStore(directory, create=False)
    rows = read_rows(store)
    if not rows:
        raise UsageError(f"swingbench report: no rows in {store.path}")
    meta_path = directory / "metadata.json"
    meta = {}
    if meta_path.exists():
        try:
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
            if not isinstance(meta, dict):
                raise ValueError("not a JSON object")  # noqa: TRY004 - reported as unreadable
        except (OSError, ValueError) as exc:
            print(f"[swingbench] warning: {meta_path} is unreadable ({exc}); the tables are written without it",
                  file=sys.stderr)
            meta = {}
    return rows, meta


def _readme_block(args: argparse.Namespace, flag: str) -> int:
    """`--at-scale` (the verdict runs of every DIR) or `--step-claim` (one DIR's step sweeps): only
    that generated block of the README the flag names, written from the folders' rows; a folder
    whose rows cannot make it, or a README without its markers, is one line (UsageError)."""
    from harness.report.pages import at_scale_block, step_claim_block

    if flag == "--at-scale":
        readme, start, end = args.at_scale, AT_SCALE_START, AT_SCALE_END
    else:
        readme, start, end = args.step_claim, STEP_CLAIM_START, STEP_CLAIM_END
        if len(args.directory) > 1:
            raise UsageError(f"swingbench report: {flag}: one DIR (the run of the step sweeps)")
    around(readme, start, end, "report", flag)
    runs = [(*_read_run(directory), directory) for directory in args.directory]
    try:
        block = at_scale_block(runs, readme) if flag == "--at-scale" else step_claim_block(*runs[0], readme)
    except ValueError as exc:
        raise UsageError(f"swingbench report: {flag}: {exc}") from None
    replace_section(readme, start, end, block, "report", flag)
    print(f"[swingbench] {readme}: {flag.removeprefix('--')} block from {len(runs)} run(s)")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from harness.report.files import write_report

    blocks = [flag for flag, value in (("--at-scale", args.at_scale), ("--step-claim", args.step_claim)) if value]
    if blocks:
        if args.update_readme or args.docs or len(blocks) > 1:
            raise UsageError(f"swingbench report: {blocks[0]} writes only its README block: leave out "
                             f"{', '.join(['--update-readme', '--docs', *blocks[1:]])}")
        return _readme_block(args, blocks[0])
    if len(args.directory) > 1:
        raise UsageError("swingbench report: one DIR at a time (several only with --at-scale)")
    args.directory = args.directory[0]
    rows, meta = _read_run(args.directory)
    if args.update_readme:
        around(args.update_readme, README_START, README_END, "report")
    try:
        print(write_report(rows, args.directory, meta))
        write_docs(args, rows, meta, args.directory)
    except OSError as exc:
        raise UsageError(f"swingbench report: cannot write to {args.directory}: {exc.strerror or exc}") from None
    return 0
