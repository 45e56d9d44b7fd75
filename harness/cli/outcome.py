"""How a command that measured ends: the rows it reads back, with one warning line for what had to
be skipped (`read_rows`); one line on the units of work that failed (`failure_summary`); and the
exit status (`outcome`): 0, or `harness.usage.EXIT_FAILED` when a unit of work failed or was lost."""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path

from harness.run.runner import failed
from harness.usage import EXIT_FAILED

__all__ = ["failure_summary", "outcome", "read_rows"]


def read_rows(store) -> list[dict]:
    """The store's rows, with one warning line on stderr for what had to be skipped."""
    contents = store.read()
    warning = contents.warning(store.path)
    if warning:
        print(f"[swingbench] warning: {warning}", file=sys.stderr)
    return contents.rows


def _unit_label(row: dict) -> str:
    """`Unit.label` of the unit a row belongs to, from the row's columns."""
    seed = row.get("seed")
    extra = "".join(f",{part}" for part in (row.get("variant") or "", "" if seed in (None, -1) else f"seed={seed}")
                    if part)
    return f"{row.get('solver')}[{row.get('config')}{extra}] {row.get('case')}"


def failure_summary(rows: Iterable[dict], where: Path, shown: int = 5) -> str | None:
    """One line on the units of work in `rows` that `failed` (declared skips are not failures): how
    many, in which units (solver, config, variant and case; the first `shown` of them) and which
    of their units of work, and `where` their rows are. None when nothing failed."""
    works: dict[str, list[str]] = {}
    for row in rows:
        if failed(row):
            suites = works.setdefault(_unit_label(row), [])
            if row.get("suite") not in suites:
                suites.append(row.get("suite"))
    if not works:
        return None
    listed = "; ".join(f"{label} ({', '.join(map(str, suites))})" for label, suites in list(works.items())[:shown])
    more = f"; and {len(works) - shown} more unit(s)" if len(works) > shown else ""
    return (f"{sum(map(len, works.values()))} unit(s) of work failed, in {len(works)} unit(s): {listed}{more}; "
            f"their rows, with the reason in 'status', are in {where}")


def outcome(rows: list[dict], where: Path, lost: int = 0) -> int:
    """The exit status of a command that measured: 0 when no unit of work in `rows` failed and
    none was lost; else one line on stderr for each (`failure_summary`; lost units are run by
    --resume) and `EXIT_FAILED`. `rows` are those of the whole output folder: a resumed run's
    earlier failures are results of the run too, kept, not run again."""
    summary = failure_summary(rows, where)
    if summary:
        print(f"[swingbench] {summary}", file=sys.stderr)
    if lost:
        print(f"[swingbench] {lost} unit(s) of work lost to the executor, not recorded: add --resume to run them",
              file=sys.stderr)
    return EXIT_FAILED if summary or lost else 0
