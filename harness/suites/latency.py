"""Warm query latency: the paper's grid, one trajectory, one time point."""

from __future__ import annotations

import numpy as np

from harness.cases import Case, standard_grid
from harness.runs import Settings
from harness.timing import time_call
from solvers.base import AbstractSolver

T1_S = 10.0  # the paper's single-time-point query (its 87x claim)


def queries(case: Case) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Named (t_query, P1) pairs: the 100 x 201 grid, one trajectory (middle P1, 201 times), and
    delta at t1 = 10 s for the middle P1."""
    t, P1 = standard_grid(case)
    mid = P1[P1.size // 2: P1.size // 2 + 1]
    return {
        f"grid {P1.size}x{t.size}": (t, P1),
        f"one trajectory ({t.size} points)": (t, mid),
        f"single point t1={T1_S:g} s": (np.array([T1_S]), mid),
    }


def latency(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """Median, quartiles and minimum (s) of warm `solve` calls (delta and omega) for each query."""
    rows = []
    for name, (t, P1) in queries(case).items():
        timing = time_call(
            lambda t=t, P1=P1: solver.solve(t, P1), min_repeats=settings.min_repeats,
            budget_s=settings.latency_budget_s,
        )
        rows.append({"query": name, "n_trajectories": P1.size, "n_times": t.size, **timing._asdict()})
    return rows
