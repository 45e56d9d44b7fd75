"""Suites: each a function (solver, case, settings) -> list of row dicts, no I/O.

A row holds the measurement's own columns; the runner adds suite, case, solver, config, variant,
seed and status, so every suite's rows form one tidy DataFrame. `Suite` says how the runner
treats each: whether it needs a fitted solver, whether it repeats for every training seed, and
whether it runs on a case of its own; `harness.run.plan` reads them.

A suite is one module of this package, `<name>.py`, that defines `SUITE = Suite("<name>", ...)`:
`SUITES` is filled from every such module (modules whose names start with "_" are helpers), in the
order of their names, so adding a suite is adding its file.
"""

from __future__ import annotations

import importlib
import pkgutil

from harness.suites._base import Suite
from harness.suites.identification import identification_case


def _discover() -> dict[str, Suite]:
    found = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda info: info.name):
        if info.name.startswith("_"):
            continue
        suite = getattr(importlib.import_module(f"{__name__}.{info.name}"), "SUITE", None)
        if not isinstance(suite, Suite) or suite.name != info.name:
            raise TypeError(f"{__name__}.{info.name} must define SUITE = Suite({info.name!r}, ...)")
        found[suite.name] = suite
    return found


SUITES: dict[str, Suite] = _discover()
DEFAULT_SUITES = tuple(name for name, suite in SUITES.items() if suite.default)

__all__ = ["DEFAULT_SUITES", "SUITES", "Suite", "identification_case"]
