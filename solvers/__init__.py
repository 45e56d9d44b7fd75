"""The registry of solver adapters: one mapping for the CLI, the tests and asv.

Adapters are entry points of the group `swingbench.solvers` (name = "module:Class"): the built-in
ones are declared in this project's pyproject.toml, an adapter from outside the repository in its
own distribution's metadata. Reading the names imports nothing; an adapter's module is imported the
first time its class is asked for, so a run of one adapter does not pay for importing torch and jax.

An adapter whose module cannot be imported (its optional dependency is missing) stays listed in
`SOLVERS` (as None) with the reason in `UNAVAILABLE` ("skipped: torch not installed");
`make_solver` then raises `SolverUnavailable` instead of crashing the others.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
import re
import sys
import tomllib
from collections.abc import Iterator, MutableMapping
from importlib.metadata import EntryPoint
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # annotations only: the registry itself imports nothing but the standard library
    from solvers.base import AbstractSolver
    from systems.cases import Case

__all__ = ["ENTRY_POINT_GROUP", "INTERFACE", "LITERATURE_BASELINE", "SOLVERS", "UNAVAILABLE", "SolverUnavailable", "available_solvers",
           "fault_adapters", "make_solver", "plugin_distribution", "solver_class"]

ENTRY_POINT_GROUP = "swingbench.solvers"
_PROJECT = "swingbench"
# The do-nothing adapter that times the interface itself: runs make it (latency suite only), the
# registry does not list it, so the CLI, the contract tests and asv never take it for a solver.
INTERFACE = "interface-overhead"

# The adapter that stands for the paper's baseline, MATLAB ode45 looped over P1 (its 28x and 87x):
# the first rung of every verdict.
LITERATURE_BASELINE = "scipy-rk45"


class SolverUnavailable(RuntimeError):
    """The adapter's optional dependency is not installed."""


UNAVAILABLE: dict[str, str] = {}


def _normalise(distribution: str) -> str:
    return re.sub(r"[-_.]+", "-", distribution).lower()


def _builtin_entry_points() -> list[EntryPoint]:
    """The project's own adapters. From the source tree's pyproject.toml when this code runs from a
    checkout: an editable install's metadata is written at install time and may belong to another
    checkout or predate an adapter added since. Installed from a wheel (no pyproject.toml beside
    the packages), from the distribution's metadata, which was written from that same table."""
    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    if pyproject.is_file():
        project = tomllib.loads(pyproject.read_text(encoding="utf-8")).get("project", {})
        if project.get("name") == _PROJECT:
            table = project.get("entry-points", {}).get(ENTRY_POINT_GROUP, {})
            return [EntryPoint(name, value, ENTRY_POINT_GROUP) for name, value in table.items()]
    try:
        return list(importlib.metadata.distribution(_PROJECT).entry_points.select(group=ENTRY_POINT_GROUP))
    except importlib.metadata.PackageNotFoundError:
        return []


def _plugin_entry_points() -> list[tuple[EntryPoint, str]]:
    """(entry point, distribution name) of every other installed distribution's adapters, by name."""
    found = []
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist.name if ep.dist is not None else "unknown"
        if _normalise(dist) != _PROJECT:  # our own (possibly stale) metadata: the built-ins above
            found.append((ep, dist))
    return sorted(found, key=lambda item: item[0].name)


def _discover() -> tuple[dict[str, EntryPoint], dict[str, str]]:
    """name -> entry point, built-ins first in their declared order, then outside adapters by name;
    and name -> the distribution of each outside adapter. A name taken already is not replaced: the
    later claim is reported on stderr and ignored."""
    adapters = {ep.name: ep for ep in _builtin_entry_points()}
    plugins: dict[str, str] = {}
    for ep, dist in _plugin_entry_points():
        if ep.name in adapters or ep.name == INTERFACE:
            taken = "the interface's own adapter" if ep.name == INTERFACE else adapters[ep.name].value
            print(f"[swingbench] solver {ep.name!r} of {dist} ignored: the name is taken by {taken}",
                  file=sys.stderr)
            continue
        adapters[ep.name] = ep
        plugins[ep.name] = dist
    return adapters, plugins


def _import_failure(module: str, exc: ImportError) -> str:
    """The status of an adapter whose module does not import: "not installed" when a top-level
    package it imports is absent, otherwise the error."""
    missing = (getattr(exc, "name", None) or "").partition(".")[0]
    if isinstance(exc, ModuleNotFoundError) and missing and importlib.util.find_spec(missing) is None:
        return f"skipped: {missing} not installed"
    return f"skipped: {module} cannot be imported ({type(exc).__name__}: {exc})"


def _load(name: str, ep: EntryPoint) -> tuple[type[AbstractSolver] | None, str]:
    """The class of entry point `ep`, or None and why not."""
    try:
        module = importlib.import_module(ep.module)
    except ImportError as exc:
        return None, _import_failure(ep.module, exc)
    cls = getattr(module, ep.attr, None) if ep.attr else None
    from solvers.base import AbstractSolver

    if not (isinstance(cls, type) and issubclass(cls, AbstractSolver)):
        return None, f"skipped: {ep.value} is not an adapter class (solvers.base.AbstractSolver)"
    if getattr(cls, "name", None) != name:
        return None, f"skipped: {ep.value} is registered as {name!r} but its name is {getattr(cls, 'name', None)!r}"
    return cls, ""


class _Registry(MutableMapping[str, "type[AbstractSolver] | None"]):
    """name -> adapter class, or None when it cannot be imported (the reason in `UNAVAILABLE`).
    Listing, iterating and `in` read names only; indexing imports the adapter's module once.
    Assigning a class (or None) registers an adapter directly (tests)."""

    def __init__(self, adapters: dict[str, EntryPoint], plugins: dict[str, str]) -> None:
        self._entry_points: dict[str, EntryPoint | None] = dict(adapters)
        self._plugins = dict(plugins)
        self._classes: dict[str, type[AbstractSolver] | None] = {}

    def __getitem__(self, name: str) -> type[AbstractSolver] | None:
        if name not in self._classes:
            ep = self._entry_points[name]  # KeyError for an unknown name, as a dict
            assert ep is not None  # assigned entries are in _classes
            cls, why = _load(name, ep)
            self._classes[name] = cls
            if cls is None:
                UNAVAILABLE[name] = why
        return self._classes[name]

    def __setitem__(self, name: str, cls: type[AbstractSolver] | None) -> None:
        self._entry_points[name] = None
        self._plugins.pop(name, None)
        self._classes[name] = cls

    def __delitem__(self, name: str) -> None:
        del self._entry_points[name]
        self._plugins.pop(name, None)
        self._classes.pop(name, None)

    def __iter__(self) -> Iterator[str]:
        return iter(self._entry_points)

    def __len__(self) -> int:
        return len(self._entry_points)

    def __contains__(self, name: object) -> bool:
        return name in self._entry_points

    def distribution(self, name: str) -> str | None:
        """The installed distribution that provides adapter `name` from outside the repository;
        None for a built-in one (or one assigned directly)."""
        return self._plugins.get(name)


SOLVERS = _Registry(*_discover())


def plugin_distribution(name: str) -> str | None:
    """The distribution of an adapter from outside the repository (its version belongs in a run's
    record and a trained model's key); None for a built-in adapter."""
    return SOLVERS.distribution(name) if name in SOLVERS else None


def solver_class(name: str) -> type[AbstractSolver] | None:
    """The adapter class of `name` (registered or the interface's own), None when not installed."""
    if name == INTERFACE:
        from solvers.null import NullSolver

        return NullSolver
    if name not in SOLVERS:
        raise ValueError(f"unknown solver {name!r}; known: {', '.join(SOLVERS)}")
    return SOLVERS[name]


def available_solvers() -> list[str]:
    """Names of the adapters whose dependencies are installed, in registry order."""
    return [name for name, cls in SOLVERS.items() if cls is not None]


def fault_adapters() -> list[str]:
    """Names of the installed adapters that integrate fault cases (`AbstractSolver.handles_faults`),
    in registry order. Imports every adapter's module (seconds with torch and JAX)."""
    return [name for name, cls in SOLVERS.items() if cls is not None and cls.handles_faults]


def make_solver(name: str, case: Case | str, config: str = "default", **options: Any) -> AbstractSolver:
    """Instantiate the adapter `name` for `case` (a `Case`, or the name of one in
    `systems.cases.CASES`) with a named `config` and option overrides. An unknown case name is a
    ValueError listing the known ones; an adapter without `handles_faults` refuses a fault case
    (ValueError naming those that do)."""
    cls = solver_class(name)
    if cls is None:
        raise SolverUnavailable(f"{name}: {UNAVAILABLE[name]}")
    if isinstance(case, str):
        from systems.cases import CASES  # importing systems registers every case

        if case not in CASES:
            raise ValueError(f"unknown case {case!r}; known: {', '.join(CASES)}")
        case = CASES[case]
    if case.fault is not None and not cls.handles_faults:
        raise ValueError(f"{name} does not integrate fault cases (case {case.name!r} switches its network at the "
                         f"clearing time); adapters that do: {', '.join(fault_adapters()) or 'none'}")
    return cls(case, config=config, **options)
