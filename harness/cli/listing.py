"""`swingbench list [SECTION]`: what a run can name, read from the registries: the cases
(`systems.cases.CASES`), the adapters and their capabilities (`solvers.SOLVERS`), their named
configs with marks and option overrides (`CONFIGS`, `CONFIG_MARKS`), their options with type,
range and default (`SCHEMA`, worded by `solvers.options.describe_option`) and the suites
(`harness.suites.SUITES`). Nothing here is written by hand: a new case, adapter or suite is listed
by itself.

This module imports only the standard library until the command runs: the CLI imports it to build
its parser."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Iterable, Iterator

from harness.usage import UsageError, check_known

__all__ = ["SECTIONS", "add_parser", "cmd_list", "section_lines"]

SECTIONS = ("cases", "solvers", "configs", "options", "suites")


def add_parser(sub) -> None:
    listing = sub.add_parser(
        "list", help="what a run can name: cases, solvers, configs, options, suites",
        description="Print what `swingbench run` can name, from the registries: cases (kind, machines, scenario "
                    "parameter and its range), solvers (capabilities, or why one is skipped), configs (marks and "
                    "option overrides), options (type and range from the adapter's schema, default) and suites "
                    "(what each measures, whether a run without --suite runs it). Without SECTION, all five.")
    listing.add_argument("section", nargs="?", default=None, metavar="SECTION",
                         help=f"one of {', '.join(SECTIONS)} (default: all)")
    listing.add_argument("--solver", nargs="+", default=None, metavar="NAME",
                         help="only these adapters in the solvers, configs and options sections")
    listing.add_argument("--case", nargs="+", default=None, metavar="NAME",
                         help="only these cases in the cases section (listing a case builds it: all of them "
                              "take about half a minute, the largest grids most of it)")


def _capabilities(cls: type) -> list[str]:
    """The capability markers (`AbstractSolver`'s `ClassVar[bool]` attributes) that `cls` declares
    true, in declaration order; `does_work` left out (true for every registered adapter)."""
    import typing

    from solvers.base import AbstractSolver

    hints = typing.get_type_hints(AbstractSolver)
    flags = [name for name, hint in hints.items()
             if typing.get_origin(hint) is typing.ClassVar and typing.get_args(hint) == (bool,)]
    return [name for name in flags if name != "does_work" and getattr(cls, name)]


def _options_text(options: dict) -> str:
    return ", ".join(f"{key}={value!r}" if isinstance(value, str) else f"{key}={value}"
                     for key, value in options.items()) or "the schema's defaults"


def _cases(names: Iterable[str]) -> Iterator[str]:
    from systems.cases import CASES

    yield "cases (kind, machines, scenario parameter over its range, horizon):"
    for name in names:
        case = CASES[name]
        scenario = case.scenario
        machines = f"{case.n} machine{'s' if case.n != 1 else ''}"
        fault = f", fault {case.fault.name}" if case.fault is not None else ""
        yield (f"  {name:<24} {case.kind:<8} {machines:<13} {scenario.symbol} ({scenario.meaning}) in "
               f"[{case.p1_min:.4g}, {case.p1_max:.4g}] {scenario.unit}, t in [0, {case.t_final:g}] s{fault}")


def _solvers(names: list[str]) -> Iterator[str]:
    from solvers import SOLVERS, UNAVAILABLE, plugin_distribution

    yield "solvers (capabilities they declare, solvers.base.AbstractSolver):"
    for name in names:
        cls = SOLVERS[name]
        source = f" (from {plugin_distribution(name)})" if plugin_distribution(name) else ""
        if cls is None:
            yield f"  {name:<16} {UNAVAILABLE[name]}{source}"
            continue
        variants = "; ".join(_options_text(dict(v)) for v in cls.VARIANTS)
        yield (f"  {name:<16} {', '.join(_capabilities(cls)) or 'no capability markers'}"
               + (f"; variants: {variants}" if variants else "") + source)


def _by_adapter(names: list[str], lines: Callable[[type], Iterator[str]]) -> Iterator[str]:
    """A heading line per adapter of `names`, then `lines(cls)` of its class, indented; or the
    reason it is skipped."""
    from solvers import SOLVERS, UNAVAILABLE

    for name in names:
        cls = SOLVERS[name]
        if cls is None:
            yield f"  {name}: {UNAVAILABLE[name]}"
            continue
        yield f"  {name}:"
        yield from (f"    {line}" for line in lines(cls))


def _config_lines(cls: type) -> Iterator[str]:
    for config, options in cls.CONFIGS.items():
        marks = f" [{', '.join(sorted(cls.marks(config)))}]" if cls.marks(config) else ""
        kinds, scenarios = cls.CASE_KINDS.get(config), cls.CASE_SCENARIOS.get(config)
        made = ([f"kind {' or '.join(sorted(kinds))}"] if kinds else []) + (
            [f"scenario {' or '.join(s.symbol for s in scenarios)}"] if scenarios else [])
        made_for = f"; made for cases of {', '.join(made)}" if made else ""
        yield f"{config:<20} {_options_text(dict(options))}{marks}{made_for}"


def _option_lines(cls: type) -> Iterator[str]:
    from solvers.options import describe_option

    for option, default in cls.OPTIONS.items():
        what = describe_option(cls.SCHEMA, option) if cls.SCHEMA is not None else "(no schema)"
        yield f"{option:<20} {what}; default {default!r}"


def _configs(names: list[str]) -> Iterator[str]:
    yield "configs (named option sets: overrides; [marks]; the cases they are made for, where not every one):"
    yield from _by_adapter(names, _config_lines)


def _options(names: list[str]) -> Iterator[str]:
    yield "options (--option KEY=VALUE: what the adapter's schema takes, and its default):"
    yield from _by_adapter(names, _option_lines)


def _suites() -> Iterator[str]:
    import importlib
    import re

    from harness.suites import SUITES

    yield "suites (default: run when --suite names none):"
    for name, suite in SUITES.items():
        doc = " ".join((importlib.import_module(f"harness.suites.{name}").__doc__ or "").split("\n\n")[0].split())
        first = re.split(r"(?<=\.)\s+(?=[A-Z])", doc, maxsplit=1)[0]  # its first sentence
        yield f"  {name:<16} {'default' if suite.default else 'named only'}: {first}"


def section_lines(section: str, solvers: list[str] | None = None, cases: list[str] | None = None) -> Iterator[str]:
    """The lines of one section of `swingbench list`, built as they are printed (a case is built
    when its line is due); `solvers` and `cases` None: every registered one."""
    from solvers import SOLVERS
    from systems.cases import CASES

    names = list(SOLVERS) if solvers is None else solvers
    makers: dict[str, Callable[[], Iterator[str]]] = {
        "cases": lambda: _cases(list(CASES) if cases is None else cases),
        "solvers": lambda: _solvers(names), "configs": lambda: _configs(names),
        "options": lambda: _options(names), "suites": _suites}
    return makers[section]()


def cmd_list(args: argparse.Namespace) -> int:
    from solvers import SOLVERS
    from systems.cases import CASES

    if args.section is not None and args.section not in SECTIONS:
        raise UsageError(f"swingbench list: unknown section {args.section!r}; known: {', '.join(SECTIONS)}")
    check_known("list", "solver(s)", args.solver, SOLVERS)
    check_known("list", "case(s)", args.case, CASES)
    try:
        for i, section in enumerate([args.section] if args.section else SECTIONS):
            if i:
                print()
            for line in section_lines(section, args.solver, args.case):
                print(line, flush=True)
    except BrokenPipeError:  # `swingbench list | head`: the reader has what it wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
    return 0
