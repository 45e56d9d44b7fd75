"""Shared fixtures: every registered adapter, fitted once per session on a small budget."""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "2")

import pytest

from solvers import SOLVERS, UNAVAILABLE, make_solver
from systems.cases import SMIB_INFERENCE

ALL_SOLVERS = tuple(SOLVERS)

# Small budgets for the adapters that train: the contract tests check behaviour, not accuracy.
SMALL_BUDGET = {"max_iterations": 30, "n_f": 300, "progress": False}


def small_options(name: str) -> dict:
    cls = SOLVERS[name]
    return {k: v for k, v in SMALL_BUDGET.items() if k in cls.OPTIONS}


def fit_for_tests(solver) -> None:
    """`fit()`, with diffrax compiling one small shape instead of the benchmark's (its JIT is slow)."""
    if hasattr(solver, "FIT_SHAPES"):
        solver.FIT_SHAPES = ((7, 3),)
    solver.fit()


def require(name: str) -> None:
    if SOLVERS[name] is None:
        pytest.skip(UNAVAILABLE[name])


@pytest.fixture(scope="session")
def fitted_solvers() -> dict:
    """name -> a fitted adapter on SMIB_INFERENCE (built lazily, once per session)."""
    cache: dict = {}

    class Lazy(dict):
        def __missing__(self, name):
            require(name)
            solver = make_solver(name, SMIB_INFERENCE, **small_options(name))
            fit_for_tests(solver)
            self[name] = solver
            return solver

    return Lazy(cache)
