"""The registry of solver adapters: one dict for the CLI, the tests and asv.

An adapter whose optional dependency is missing stays listed in `SOLVERS` with the reason in
`UNAVAILABLE`; `make_solver` then raises `SolverUnavailable` ("not installed") instead of crashing
the others.
"""

from __future__ import annotations

import importlib
from typing import Any

from harness.cases import Case
from solvers.base import AbstractSolver

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


SOLVERS: dict[str, type[AbstractSolver] | None] = {}
UNAVAILABLE: dict[str, str] = {}
for _name, (_module, _cls, _package) in _ADAPTERS.items():
    try:
        importlib.import_module(_package)
    except ImportError:
        SOLVERS[_name] = None
        UNAVAILABLE[_name] = f"skipped: {_package} not installed"
        continue
    SOLVERS[_name] = getattr(importlib.import_module(_module), _cls)


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
