"""What a verdict asks and how accurate an answer is: its queries (`Query`, `verdict_queries`)
and the errors of an adapter on one (`query_errors`).

Accuracy on a query (`query_errors`): relative L2 against the reference (`systems.reference`) of
the angles relative to the system's reference (the infinite bus, else the centre of inertia) and
of the speeds, at the points the query asks, the larger of that and the same on a grid away from
a PINN's training points (`OFF_TRAINING_P1` of the accuracy suite's off-training grid). A query of
many trajectories is checked on `CHECK_TRAJECTORIES` of them (evenly chosen, both ends), a batch of
points on its first `CHECK_POINTS`, a single point at t1 on its trajectory up to t1 (the standard
times <= t1): a single number at one time can be near zero and is no measure.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.measure import metrics
from harness.settings import Settings
from harness.suites.accuracy import off_training_grid
from harness.suites.latency import queries
from solvers.base import AbstractSolver
from systems.cases import Case, standard_grid
from systems.model import relative_angles
from systems.reference import reference

__all__ = ["CHECK_POINTS", "CHECK_TRAJECTORIES", "OFF_TRAINING_P1", "Query", "off_training_errors", "query_errors",
           "verdict_queries"]

CHECK_TRAJECTORIES = 100
CHECK_POINTS = 100
OFF_TRAINING_P1 = 10  # P1 values of the off-training grid the accuracy is checked on (every ~10th)


@dataclass(frozen=True)
class Query:
    """One query of the verdicts: the latency suite's `kind` and `name`, its times t (s) and P1
    (p.u.): a grid of len(P1) trajectories at len(t) times, or (kind "points batch") the pairs
    (t[i], P1[i]), with `distinct_p1` distinct P1 values among them."""

    kind: str
    name: str
    t: np.ndarray
    P1: np.ndarray

    @property
    def points(self) -> bool:
        return self.kind == "points batch"

    @property
    def distinct_p1(self) -> int:
        return int(np.unique(self.P1).size)

    def call(self, solver: AbstractSolver) -> Callable[[], Any]:
        """The timed call: `solver.solve(t, P1)`, or `solve_points(t, P1)` for a batch of points."""
        if self.points:
            return lambda: solver.solve_points(self.t, self.P1)
        return lambda: solver.solve(self.t, self.P1)

    def check(self, case: Case) -> tuple[np.ndarray, np.ndarray]:
        """(t, P1) of the points its accuracy is measured at (see the module's docstring)."""
        if self.points:
            return self.t[:CHECK_POINTS], self.P1[:CHECK_POINTS]
        if self.kind == "single point":
            t_std, _ = standard_grid(case)
            return t_std[t_std <= self.t[0]], self.P1
        keep = np.unique(np.linspace(0, self.P1.size - 1, min(self.P1.size, CHECK_TRAJECTORIES)).round().astype(int))
        return self.t, self.P1[keep]


def verdict_queries(case: Case, settings: Settings) -> list[Query]:
    """The latency suite's queries of `case` under `settings` (`harness.suites.latency.queries`)."""
    return [Query(kind, name, t, P1) for kind, name, t, P1 in queries(case, settings)]


def _points_reference(case: Case, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reference at the pairs (t[i], P1[i]), each (len(t), n): one trajectory per distinct P1,
    integrated in one `reference` call at the distinct times (one cache entry, not one per P1,
    which 100 distinct P1 would cycle through the cache and recompute on every call)."""
    times, at_t = np.unique(t, return_inverse=True)
    values, at_p1 = np.unique(P1, return_inverse=True)
    delta, omega = reference(case, times, values)
    return delta[at_p1, at_t], omega[at_p1, at_t]


def _errors(case: Case, delta, omega, ref_delta, ref_omega) -> tuple[float, float]:
    return (metrics.rel_l2(relative_angles(case, delta), relative_angles(case, ref_delta)),
            metrics.rel_l2(omega, ref_omega))


def off_training_errors(solver: AbstractSolver, case: Case) -> tuple[float, float]:
    """(angles, speeds): relative L2 errors of `solver` on the off-training check grid (every
    ~10th P1 of the accuracy suite's grid away from a PINN's training points)."""
    t_off, p_off = off_training_grid(case)
    p_off = p_off[np.linspace(0, p_off.size - 1, OFF_TRAINING_P1).round().astype(int)]
    off = solver.solve(t_off, p_off)
    return _errors(case, off.delta, off.omega, *reference(case, t_off, p_off))


def query_errors(solver: AbstractSolver, case: Case, query: Query,
                 off: tuple[float, float] | None = None) -> tuple[float, float]:
    """(angles, speeds): relative L2 errors of `solver` on `query`, the larger of those at the
    query's check points (`Query.check`) and `off` (default: `off_training_errors`)."""
    t, P1 = query.check(case)
    if query.points:
        got = solver.solve_points(t, P1)
        at_query = _errors(case, got.delta, got.omega, *_points_reference(case, t, P1))
    else:
        got = solver.solve(t, P1)
        at_query = _errors(case, got.delta, got.omega, *reference(case, t, P1))
    off = off_training_errors(solver, case) if off is None else off
    return max(at_query[0], off[0]), max(at_query[1], off[1])
