"""`swingbench report DIR`: a results folder's tables, figures and README re-rendered from its rows
(`cmd_report`); with `--update-readme` and `--docs`, also the README's verdicts and the results
pages (`write_docs`, which `swingbench run` calls too).

This module imports only the standard library until the command runs: the CLI imports it to build
its parser."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness.cli.readme import README_END, README_START, around, replace_section
from harness.usage import UsageError

__all__ = ["DOCS_HELP", "add_parser", "cmd_report", "write_docs"]

DOCS_HELP = ("write the documentation site's results pages into this folder: one page per case with its "
             "verdicts, tables and figures, and an index (default with --update-readme: docs/results beside the "
             "README)")


def add_parser(sub) -> None:
    report = sub.add_parser("report", help="re-render a results folder's tables, figures and pages from its rows",
                            description="Read DIR/rows.jsonl and rewrite DIR's CSV and Markdown tables and plots; "
                                        "with --update-readme and --docs, the README's verdicts and the results pages.")
    report.add_argument("directory", type=Path)
    report.add_argument("--update-readme", type=Path, default=None, metavar="README",
                        help="also replace the generated verdicts section of this README (and write the results "
                             "pages, --docs)")
    report.add_argument("--docs", type=Path, default=None, metavar="PAGES", help=DOCS_HELP)


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


def cmd_report(args: argparse.Namespace) -> int:
    from harness.cli.outcome import read_rows
    from harness.report.files import write_report
    from harness.store import RowStore

    if not args.directory.is_dir():
        raise UsageError(f"swingbench report: {args.directory} is not a folder of results")
    store = RowStore(args.directory, create=False)
    rows = read_rows(store)
    if not rows:
        raise UsageError(f"swingbench report: no rows in {store.path}")
    meta_path = args.directory / "metadata.json"
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
    if args.update_readme:
        around(args.update_readme, README_START, README_END, "report")
    try:
        print(write_report(rows, args.directory, meta))
        write_docs(args, rows, meta, args.directory)
    except OSError as exc:
        raise UsageError(f"swingbench report: cannot write to {args.directory}: {exc.strerror or exc}") from None
    return 0
