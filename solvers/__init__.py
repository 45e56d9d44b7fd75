"""The registry of solver adapters: one dict for the CLI, the tests and asv.

An adapter whose optional dependency is missing stays listed in `SOLVERS` (as None) with the reason
in `UNAVAILABLE`; `make_solver` then raises `SolverUnavailable` ("not installed") instead of crashing
the others. Adapter modules are imported on first use.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Iterator, MutableMapping
from typing import Any

from solvers.base import AbstractSolver
from systems.cases import Case

__all__ = ["INTERFACE", "SOLVERS", "UNAVAILABLE", "SolverUnavailable", "available_solvers", "make_solver",
           "solver_class"]

# name -> (module, class, the optional package it needs)
_ADAPTERS = {
    "scipy-rk45": ("solvers.scipy_rk45", "ScipyRK45", "scipy"),
    "scipy-odeint": ("solvers.scipy_odeint", "ScipyOdeint", "scipy"),
    "casadi-cvodes": ("solvers.casadi_cvodes", "CasadiCVODES", "casadi"),
    "numba-rk": ("solvers.numba_rk", "NumbaRK", "numba"),
    "diffrax": ("solvers.diffrax_ode", "DiffraxODE", "diffrax"),
    "torch-pinn": ("solvers.pinn.torch_pinn", "TorchPinn", "torch"),
    "jax-pinn": ("solvers.pinn.jax_pinn", "JaxPinn", "jax"),
}


class SolverUnavailable(RuntimeError):
    """The adapter's optional dependency is not installed."""


UNAVAILABLE: dict[str, str] = {}


class _Registry(MutableMapping[str, "type[AbstractSolver] | None"]):
    """name -> adapter class, or None when its optional package is missing (the reason in
    `UNAVAILABLE`). Presence is checked without importing (`importlib.util.find_spec`); an adapter's
    module is imported the first time its class is asked for, so a run of one adapter does not pay
    for importing torch and jax. A module that fails to import counts as unavailable, with why.
    Assigning a class (or None) registers an adapter directly (tests, plugins)."""

    def __init__(self, adapters: dict[str, tuple[str, str, str]]) -> None:
        self._adapters: dict[str, tuple[str, str, str] | None] = dict(adapters)
        self._classes: dict[str, type[AbstractSolver] | None] = {}
        for name, (_, _, package) in adapters.items():
            if importlib.util.find_spec(package) is None:
                self._classes[name] = None
                UNAVAILABLE[name] = f"skipped: {package} not installed"

    def __getitem__(self, name: str) -> type[AbstractSolver] | None:
        if name not in self._classes:
            adapter = self._adapters[name]  # KeyError for an unknown name, as a dict
            assert adapter is not None, name  # a class assigned directly is in _classes from then on
            module, cls, package = adapter
            try:
                self._classes[name] = getattr(importlib.import_module(module), cls)
            except ImportError as exc:
                self._classes[name] = None
                UNAVAILABLE[name] = f"skipped: {package} cannot be imported ({exc})"
        return self._classes[name]

    def __setitem__(self, name: str, cls: type[AbstractSolver] | None) -> None:
        self._adapters[name] = None
        self._classes[name] = cls

    def __delitem__(self, name: str) -> None:
        del self._adapters[name]
        self._classes.pop(name, None)

    def __iter__(self) -> Iterator[str]:
        return iter(self._adapters)

    def __len__(self) -> int:
        return len(self._adapters)

    def __contains__(self, name: object) -> bool:
        return name in self._adapters


SOLVERS = _Registry(_ADAPTERS)


# The do-nothing adapter that times the interface itself: runs make it (latency suite only), the
# registry does not list it, so the CLI, the contract tests and asv never take it for a solver.
INTERFACE = "interface-overhead"


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


def make_solver(name: str, case: Case, config: str = "default", **options: Any) -> AbstractSolver:
    """Instantiate the adapter `name` for `case` with a named `config` and option overrides."""
    cls = solver_class(name)
    if cls is None:
        raise SolverUnavailable(f"{name}: {UNAVAILABLE[name]}")
    return cls(case, config=config, **options)
