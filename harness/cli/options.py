"""The options `swingbench run` and `swingbench sweep` share, each defined once: both commands run
units of work through `harness.run.runner` into one results folder, so these options mean the same in
both; what differs (the default folder, what a unit of work is called, how many workers) is passed in.

This module imports only the standard library: the CLI imports it to build its parser."""

from __future__ import annotations

import argparse
import functools
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


def add_case_file_options(parser: argparse.ArgumentParser) -> None:
    """Add --case-file, --machines, --case-name, --f-hz and --fault (`register_file_cases`) to `parser`."""
    parser.add_argument("--case-file", type=Path, default=None, metavar="PATH",
                        help="your own grid: a pandapower JSON, MATPOWER .m or .mat file, made a classical swing case "
                             "by the scaling family's rule (systems/case_file.py) and registered under its file stem "
                             "(--case-name), so every suite runs on it like a built-in case")
    parser.add_argument("--machines", type=Path, default=None, metavar="CSV",
                        help="machine data for --case-file: rows bus,H,xd_prime,D (H s, xd_prime p.u., D p.u., on each "
                             "machine's rating), one per generator bus (default: H = 4 s, x'd = 0.3 p.u., d = 0.5 m)")
    parser.add_argument("--case-name", default=None, metavar="NAME", help="the name of --case-file's case "
                                                                          "(default: the file's stem)")
    parser.add_argument("--f-hz", type=float, default=None, metavar="HZ",
                        help="system frequency of --case-file (default: a JSON's own, 60 Hz for MATPOWER files)")
    parser.add_argument("--fault", action="append", default=[], metavar="BUS:A-B[:CIRCUIT]",
                        help="a fault case of --case-file (repeatable): a bolted fault at bus BUS cleared by opening "
                             "the line A-B (CIRCUIT 0, the first, by default), named '<case>-busBUS-lineA-B'")


def _contingency(text: str):
    """The `systems.faults.Contingency` of --fault's BUS:A-B[:CIRCUIT], or a ValueError naming it."""
    from systems.faults import Contingency

    parts = text.split(":")
    ends = parts[1].split("-") if len(parts) in (2, 3) else []
    try:
        bus, a, b = int(parts[0]), int(ends[0]), int(ends[1])
        circuit = int(parts[2]) if len(parts) == 3 else 0
    except (ValueError, IndexError):
        raise ValueError(f"{text!r} is not BUS:A-B[:CIRCUIT] (bus numbers, e.g. 8:8-9)") from None
    if len(ends) != 2:
        raise ValueError(f"{text!r} is not BUS:A-B[:CIRCUIT] (bus numbers, e.g. 8:8-9)")
    return Contingency(f"bus{bus}-line{a}-{b}" + (f"-c{circuit}" if circuit else ""), bus, (a, b), circuit)


def register_file_cases(args: argparse.Namespace, command: str) -> list[str]:
    """Build the cases of --case-file (the step case, then one per --fault) and register them in
    `systems.cases.CASES`; their names, [] without --case-file. A bad file, machine row or
    contingency, or a name already taken, is a `UsageError` of one line."""
    from harness.usage import UsageError

    if args.case_file is None:
        given = [flag for flag, value in (("--machines", args.machines), ("--case-name", args.case_name),
                                          ("--f-hz", args.f_hz), ("--fault", args.fault)) if value]
        if given:
            raise UsageError(f"swingbench {command}: {', '.join(given)} need(s) --case-file")
        return []
    from systems.case_file import file_cases
    from systems.cases import CASES, register_case

    try:
        faults = tuple(_contingency(text) for text in args.fault)
    except ValueError as exc:
        raise UsageError(f"swingbench {command}: --fault {exc}") from None
    name = args.case_name or args.case_file.stem
    taken = [n for n in (name, *(f"{name}-{c.name}" for c in faults)) if n in CASES]
    if taken:
        raise UsageError(f"swingbench {command}: --case-file: case name {taken[0]!r} is taken (give --case-name)")
    try:
        cases = file_cases(args.case_file, args.machines, name, faults, args.f_hz)
    except ValueError as exc:
        raise UsageError(f"swingbench {command}: --case-file {exc}") from None
    for case in cases:
        register_case(case.name)(functools.partial(_same, case))
    return [case.name for case in cases]


def _same(case):
    """`case` itself: a registered builder of a case built already."""
    return case
