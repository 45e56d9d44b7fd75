"""Warm query latency: the paper's grid, throughput over batch sizes, one time point at several t1."""

from __future__ import annotations

import numpy as np

from harness.cases import Case, standard_grid
from harness.runs import Settings
from harness.timing import time_call
from solvers.base import AbstractSolver

T1_S = 10.0  # the paper's single-time-point query (its 87x claim)


def queries(case: Case, settings: Settings) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(kind, name, t_query, P1): the 100 x 201 grid; `throughput_sizes` trajectories of 201 times
    (P1 evenly spaced over the case's range; the size of the grid is the grid); delta and omega at each t1 in `t1_values_s` for the
    middle P1."""
    t, P1 = standard_grid(case)
    mid = P1[P1.size // 2: P1.size // 2 + 1]
    out = [("grid", f"grid {P1.size}x{t.size}", t, P1)]
    for n in settings.throughput_sizes:
        if n == P1.size:  # the grid itself
            continue
        p = mid if n == 1 else np.linspace(case.p1_min, case.p1_max, n)
        out.append(("throughput", f"{n} trajectories x {t.size} times", t, p))
    for t1 in settings.t1_values_s:
        out.append(("single point", f"single point t1={t1:g} s", np.array([t1]), mid))
    return out


def latency(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """Median, quartiles and minimum (s) of warm `solve` calls (delta and omega). A query whose
    cost, extrapolated from the previous size of its kind, exceeds 10 x `max_call_s` is skipped
    with a row that says so, rather than left out silently."""
    rows = []
    last: dict[str, tuple[int, float]] = {}
    for kind, name, t, P1 in queries(case, settings):
        base = {"kind": kind, "query": name, "n_trajectories": P1.size, "n_times": t.size,
                "t1_s": float(t[0]) if t.size == 1 else np.nan}
        if kind in last:
            size, seconds = last[kind]
            estimate = seconds * P1.size / size
            if estimate > 10 * settings.max_call_s:
                rows.append({**base, "status": f"skipped: estimated {estimate:.3g} s per call"})
                continue
        timing = time_call(
            lambda t=t, P1=P1: solver.solve(t, P1), min_repeats=settings.min_repeats,
            budget_s=settings.latency_budget_s, slow_s=settings.max_call_s,
        )
        last[kind] = (P1.size, timing.median_s)
        rows.append({**base, **timing._asdict()})
    return rows
