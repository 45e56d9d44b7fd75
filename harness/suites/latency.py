"""Warm query latency: the paper's grid, batches of trajectories, one time point at several t1,
and a batch of single-point queries at scattered (t1, P1) in one call."""

from __future__ import annotations

import numpy as np

from harness.runs import Settings
from harness.timing import time_call
from solvers.base import AbstractSolver
from systems.cases import Case, standard_grid

T1_S = 10.0  # the paper's single-time-point query (its 87x claim)
POINTS_SEED = 2024  # the scattered single points: the same for every adapter


def scattered_points(case: Case, n: int) -> tuple[np.ndarray, np.ndarray]:
    """`n` seeded random (t1 s, P1 p.u.) pairs, uniform on (0, t_final] x [p1_min, p1_max]."""
    rng = np.random.default_rng(POINTS_SEED)
    return case.t_final * (1.0 - rng.random(n)), rng.uniform(case.p1_min, case.p1_max, n)


def queries(case: Case, settings: Settings) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(kind, name, t_query, P1): the 100 x 201 grid; `throughput_sizes` trajectories of 201 times
    (P1 evenly spaced over the case's range; the size of the grid is the grid); delta and omega at
    each t1 in `t1_values_s` within the horizon for the middle P1; and `points_batch` scattered single points
    (`scattered_points`) answered by one `solve_points` call (kind "points batch")."""
    t, P1 = standard_grid(case)
    mid = P1[P1.size // 2: P1.size // 2 + 1]
    out = [("grid", f"grid {P1.size}x{t.size}", t, P1)]
    for n in settings.throughput_sizes:
        if n == P1.size:  # the grid itself
            continue
        p = mid if n == 1 else np.linspace(case.p1_min, case.p1_max, n)
        out.append(("throughput", f"{n} trajectories x {t.size} times", t, p))
    for t1 in (t1 for t1 in settings.t1_values_s if t1 <= case.t_final):  # within the case's horizon
        out.append(("single point", f"single point t1={t1:g} s", np.array([t1]), mid))
    if settings.points_batch:
        t_points, p_points = scattered_points(case, settings.points_batch)
        out.append(("points batch", f"{settings.points_batch} single points, one call", t_points, p_points))
    return out


def _estimate(kind: str, n: int, last: dict[str, tuple[int, float]]) -> float | None:
    """Seconds a query of `kind` and size `n` should take, from the last timed one of its kind
    (a batch of points from the single point), or None when nothing of the kind was timed yet."""
    source = "single point" if kind == "points batch" else kind
    if source not in last:
        return None
    size, seconds = last[source]
    return seconds * n / size


def latency(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """Median, quartiles and minimum (s) of warm `solve` calls (delta and omega), and of one
    `solve_points` call for the batch of points; `per_query_s` = median / number of trajectories
    or points. A query whose cost, extrapolated from the previous query of its kind, exceeds
    10 x `max_call_s` is skipped with a row that says so, rather than left out silently."""
    rows = []
    last: dict[str, tuple[int, float]] = {}
    for kind, name, t, P1 in queries(case, settings):
        n = P1.size
        base = {"kind": kind, "query": name, "n_trajectories": n, "n_times": t.size if kind != "points batch" else 1,
                "t1_s": float(t[0]) if kind == "single point" else np.nan}
        estimate = _estimate(kind, n, last)
        if estimate is not None and estimate > 10 * settings.max_call_s:
            rows.append({**base, "status": f"skipped: estimated {estimate:.3g} s per call"})
            continue
        call = solver.solve_points if kind == "points batch" else solver.solve
        timing = time_call(lambda t=t, P1=P1, call=call: call(t, P1), min_repeats=settings.min_repeats,
                           budget_s=settings.latency_budget_s, slow_s=settings.max_call_s)
        last[kind] = (n, timing.median_s)  # single points: the last t1, the largest (conservative)
        rows.append({**base, **timing._asdict(), "per_query_s": timing.median_s / n})
    return rows
