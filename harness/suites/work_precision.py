"""Work-precision: error on the 100 x 201 grid against the time of one warm grid query, and of
the single-time-point query at t1 = 10 s (the paper's two speed claims)."""

from __future__ import annotations

from dataclasses import replace

from harness import metrics
from harness.cases import Case, standard_grid
from harness.reference import reference
from harness.runs import Settings
from harness.suites.latency import T1_S, queries
from harness.timing import time_call
from solvers.base import AbstractSolver


def _point(solver: AbstractSolver, case: Case, settings: Settings) -> dict:
    """Errors on the grid; median, quartiles and repeats (s) of the grid query and, as `point_*`,
    of the single-time-point query at t1 = 10 s: the latency suite's own two queries."""
    t, P1 = standard_grid(case)
    ref_delta, ref_omega = reference(case, t, P1)
    traj = solver.solve(t, P1)
    row = {"rel_l2_delta": metrics.rel_l2(traj.delta, ref_delta),
           "rel_l2_omega": metrics.rel_l2(traj.omega, ref_omega)}
    for kind, _, tq, pq in queries(case, replace(settings, throughput_sizes=(), t1_values_s=(T1_S,))):
        prefix = "point_" if kind == "single point" else ""
        timing = time_call(lambda tq=tq, pq=pq: solver.solve(tq, pq), min_repeats=settings.min_repeats,
                           budget_s=settings.latency_budget_s, slow_s=settings.max_call_s)
        row.update({f"{prefix}median_s": timing.median_s, f"{prefix}q25_s": timing.q25_s,
                    f"{prefix}q75_s": timing.q75_s, f"{prefix}repeats": timing.repeats})
    return row


def work_precision(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """An ODE solver (an adapter with an `rtol` option) gives a curve: one point per rtol of
    `settings.wp_rtols` (atol = rtol * 1e-3), swept from its "default" config only (the sweep
    covers the other tolerance configs); any other adapter gives its own point."""
    if "rtol" in solver.OPTIONS and solver.config != "default":
        return []
    if "rtol" not in solver.OPTIONS:
        return [{"rtol": float("nan"), "atol": float("nan"), **_point(solver, case, settings)}]
    rows = []
    for rtol in settings.wp_rtols:
        tuned = type(solver)(case, solver.config, **{**solver.options, "rtol": rtol, "atol": rtol * 1e-3})
        tuned.fit()
        rows.append({"rtol": rtol, "atol": rtol * 1e-3, **_point(tuned, case, settings)})
    return rows
