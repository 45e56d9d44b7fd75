"""Command line: a module per command, each with its subparser (`add_parser`) and its command:
`swingbench run` measures (`harness.cli.run`), `report` re-renders a results folder
(`harness.cli.report`), `sweep`, `compare` and `list` (`harness.cli.sweep`, `harness.cli.compare`,
`harness.cli.listing`) do what their modules say.

Exit status (`run` and `sweep`): 0 when every unit of work was measured or declared a skip; 1 when
some failed (one line names them and where their rows are) or were lost (`harness.cli.outcome.outcome`);
2 for bad input, found before anything is measured (`harness.usage.UsageError`: one line on
stderr, no traceback); 130 on Ctrl-C."""

from __future__ import annotations

import argparse
import sys

from harness.cli import compare, listing, report, run, sweep  # only the standard library until they run
from harness.usage import UsageError


def _version() -> str:
    """The installed distribution's version (pyproject.toml's, as of the last `pip install`)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("swingbench")
    except PackageNotFoundError:
        return "(not installed: no version)"


DESCRIPTION = """\
swingbench: physics-informed neural networks (PINNs, in PyTorch and JAX) against classical ODE
solvers (scipy, CasADi CVODES, numba, diffrax, the implicit trapezoidal rule) on power-system swing
dynamics: the single-machine infinite-bus case of Misyris et al. (PESGM 2020), multi-machine grids
from 3 to 1445 machines (wscc9, kundur4, ieee39, MATPOWER's case118 ... case9241pegase) and
three-phase fault cases with their critical clearing time.

Every measurement is taken on this machine, in one run, warm, with pinned threads, against a tight
DOP853 reference (rtol = atol = 1e-12); preparation (build, JIT, training) is reported apart from
query time. Every speed verdict compares a PINN with the fastest classical option at least as
accurate, timed paired and interleaved, over several seeds."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swingbench", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"swingbench {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, title="commands", metavar="COMMAND")
    run.add_parser(sub)
    report.add_parser(sub)
    sweep.add_parser(sub)
    compare.add_parser(sub)
    listing.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = _parser().parse_args(argv)
    args.argv = argv  # for metadata and the command that resumes
    try:
        return {"run": run.cmd_run, "report": report.cmd_report, "sweep": sweep.cmd_sweep,
                "compare": compare.cmd_compare, "list": listing.cmd_list}[args.command](args)
    except UsageError as exc:  # one line, no traceback; the interpreter exits with its code and prints nothing
        print(exc, file=sys.stderr)
        raise
    except KeyboardInterrupt:  # before or after the measurements (during them, the commands say more)
        print("[swingbench] interrupted; what was recorded is kept: add --resume to continue", file=sys.stderr)
        return 130
