"""What a run measures: solver specifications (adapter, named config, option overrides) and settings."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from harness.cases import Case
from solvers import SOLVERS, make_solver
from solvers.base import AbstractSolver

__all__ = ["Settings", "SolverSpec", "default_specs"]


@dataclass(frozen=True)
class SolverSpec:
    """One row label of the tables: an adapter name, one of its named configs, option overrides."""

    solver: str
    config: str = "default"
    options: tuple[tuple[str, Any], ...] = ()

    @property
    def variant(self) -> str:
        """The option overrides as text ("" when none), e.g. "batch=stacked"."""
        return ",".join(f"{k}={v}" for k, v in self.options)

    @property
    def label(self) -> str:
        return f"{self.solver}[{self.config}{',' + self.variant if self.options else ''}]"

    def make(self, case: Case, **extra: Any) -> AbstractSolver:
        return make_solver(self.solver, case, self.config, **dict(self.options), **extra)

    def key(self) -> dict[str, str]:
        """The columns that identify this spec in a row."""
        return {"solver": self.solver, "config": self.config, "variant": self.variant}


@dataclass(frozen=True)
class Settings:
    """Knobs of a run. `quick` shrinks budgets for a smoke test; timings are medians of repeats
    within `latency_budget_s` seconds per measurement; `threads` is recorded with the results."""

    quick: bool = False
    threads: int = 2
    latency_budget_s: float = 1.0
    min_repeats: int = 5
    seeds: tuple[int, ...] = (0,)
    extra: dict = field(default_factory=dict)


def default_specs(
    solvers: Iterable[str] | None = None, configs: Iterable[str] | None = None,
) -> list[SolverSpec]:
    """Every registered adapter (installed or not: missing ones become 'skipped' rows) in each of
    its named configs, and for adapters with a `batch` option also the stacked batch mode."""
    names = list(SOLVERS) if solvers is None else list(solvers)
    unknown = [n for n in names if n not in SOLVERS]
    if unknown:
        raise ValueError(f"unknown solver(s) {', '.join(unknown)}; known: {', '.join(SOLVERS)}")
    specs = []
    for name in names:
        cls = SOLVERS[name]
        if cls is None:
            specs.append(SolverSpec(name))
            continue
        for config in cls.CONFIGS:
            if configs is not None and config not in configs:
                continue
            specs.append(SolverSpec(name, config))
            if "batch" in cls.OPTIONS:
                specs.append(SolverSpec(name, config, (("batch", "stacked"),)))
    return specs
