"""Cases from other packages: entry points of the group `swingbench.cases`, as adapters come from
`swingbench.solvers` (`solvers/__init__.py`).

An entry point `name = "module:builder"` names a function that takes no arguments and returns the
`Case` called `name` (a `systems.case_file.case_from_file(...)` of a file the package ships, or any
builder of `systems.network`). It is registered in `systems.cases.CASES` like a built-in case: listing
it imports nothing, the first `CASES[name]` imports the module and builds the case (once per
process). A name a built-in (or an earlier plugin, by name order) already has is ignored with one
line on stderr; a module that does not import, or a builder that fails, is a ValueError naming the
case and its distribution when the case is built.

Only the standard library (importlib.metadata) and `systems.cases`: nothing of the harness.
"""

from __future__ import annotations

import importlib.metadata
import sys
from importlib.metadata import EntryPoint

from systems.cases import CASES, Case, CaseBuilder, register_case

__all__ = ["CASE_ENTRY_POINT_GROUP", "register_plugin_cases"]

CASE_ENTRY_POINT_GROUP = "swingbench.cases"


def _builder(ep: EntryPoint, dist: str) -> CaseBuilder:
    def build() -> Case:
        try:
            builder = ep.load()
        except Exception as exc:  # noqa: BLE001 - any import failure of a plugin is one line naming it
            raise ValueError(f"case {ep.name!r} of {dist}: {ep.value} cannot be imported "
                             f"({type(exc).__name__}: {exc})") from None
        case = builder()
        if not isinstance(case, Case):
            raise ValueError(f"case {ep.name!r} of {dist}: {ep.value} returned {type(case).__name__}, not a Case")  # noqa: TRY004 - the contract is ValueError
        return case

    return build


def register_plugin_cases() -> list[str]:
    """Register every installed distribution's `swingbench.cases` entry points in `CASES`, by name;
    the names registered."""
    found = []
    for ep in sorted(importlib.metadata.entry_points(group=CASE_ENTRY_POINT_GROUP), key=lambda ep: ep.name):
        dist = ep.dist.name if ep.dist is not None else "unknown"
        if ep.name in CASES:
            print(f"[swingbench] case {ep.name!r} of {dist} ignored: the name is taken", file=sys.stderr)
            continue
        register_case(ep.name)(_builder(ep, dist))
        found.append(ep.name)
    return found
