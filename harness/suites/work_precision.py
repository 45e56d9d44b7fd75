"""Work-precision: error on the 100 x 201 grid against the time of one warm grid query, and of
the single-time-point query at t1 = 10 s (the paper's two speed claims)."""

from __future__ import annotations

import re
from dataclasses import replace

from harness.measure import metrics
from harness.measure.timing import time_call
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites.latency import T1_S, queries
from solvers.base import AbstractSolver
from systems.cases import Case, standard_grid
from systems.model import relative_angles
from systems.reference import reference

T1_COLUMN = re.compile(r"point_t1=(?P<t1>[0-9.e+-]+)_median_s")


def t1_column(t1: float) -> str:
    """The work-precision column of the median single-point time (s) at `t1` (s), which compiled
    adapters record at every t1 (`T1_COLUMN` reads it back)."""
    return f"point_t1={t1:g}_median_s"


def _point(solver: AbstractSolver, case: Case, settings: Settings) -> dict:
    """Errors on the grid (for a system without an infinite bus also of the angles relative to the
    centre of inertia, `rel_l2_delta_coi`); median, quartiles and repeats (s) of the grid query and, as `point_*`,
    of the single-time-point query at t1 = 10 s: the latency suite's own two queries. For a
    compiled adapter also the single point at every t1 of the run (`t1_column`, a fifth of the
    timing budget each), so that the crossover in t1 can take any point of its sweep."""
    t, P1 = standard_grid(case)
    ref_delta, ref_omega = reference(case, t, P1)
    traj = solver.solve(t, P1)
    row = {"rel_l2_delta": metrics.rel_l2(traj.delta, ref_delta),
           "rel_l2_omega": metrics.rel_l2(traj.omega, ref_omega)}
    if not case.has_infinite_bus:  # the accuracy the verdicts of a multi-machine case compare at
        row["rel_l2_delta_coi"] = metrics.rel_l2(relative_angles(case, traj.delta), relative_angles(case, ref_delta))
    t1_values = settings.t1_values_s if solver.compiled else (T1_S,)
    for kind, _, tq, pq in queries(case, replace(settings, throughput_sizes=(), t1_values_s=t1_values,
                                                 points_batch=0)):
        t1 = float(tq[0]) if kind == "single point" else None
        paper_query = t1 is None or t1 == T1_S  # the grid and t1 = 10 s: the full budget
        timing = time_call(lambda tq=tq, pq=pq: solver.solve(tq, pq), min_repeats=settings.min_repeats,
                           budget_s=settings.latency_budget_s / (1 if paper_query else 5),
                           slow_s=settings.max_call_s)
        if t1 is not None and solver.compiled:
            row[t1_column(t1)] = timing.median_s
        if paper_query:
            prefix = "" if t1 is None else "point_"
            row.update({f"{prefix}median_s": timing.median_s, f"{prefix}q25_s": timing.q25_s,
                        f"{prefix}q75_s": timing.q75_s, f"{prefix}repeats": timing.repeats})
    return row


def setting_label(overrides: dict) -> str:
    """"rtol=1e-06, atol=1e-09" or "dt=0.05": a point of a sweep, as text."""
    return ", ".join(f"{key}={value:g}" for key, value in overrides.items())


def work_precision(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """An adapter with a precision sweep (`AbstractSolver.precision_sweep`: tolerances of an adaptive
    solver, steps of a fixed-step one) gives a curve, one point per setting, swept from its config
    (a config that only sets the swept options is a point of the default config's curve: declared
    `SWEEP_POINT`, the planner does not run this suite for it); any other adapter gives its own
    point. The tolerances are `Settings.sweep_rtols` (fewer for a Python-driven adapter on a
    multi-machine case). Each row has the overrides as columns (rtol, atol or dt) and as `setting`
    text."""
    sweep = solver.precision_sweep(settings.sweep_rtols(solver.compiled, case))
    if not sweep:
        return [{"setting": "", **_point(solver, case, settings)}]
    rows = []
    for overrides in sweep:
        tuned = type(solver)(case, solver.config, **{**solver.options, **overrides})
        tuned.fit()
        rows.append({**overrides, "setting": setting_label(overrides), **_point(tuned, case, settings)})
    return rows


SUITE = Suite("work_precision", work_precision, sweeps=True)
