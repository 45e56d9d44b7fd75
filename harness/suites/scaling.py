"""Cost and accuracy against the size of the grid: one row per adapter and case.

The preparation cost (build, JIT compilation, training) is the unit's `fit` row, measured by the
runner; this suite times the queries of the fitted solver and measures its accuracy, on a grid
small enough for the largest cases: `scaling_n_p1` P1 values x `scaling_n_t` times over the
horizon. The reference (DOP853 at 1e-12) of that grid is stored on disk next to the model cache,
so that the units of one case, each in a process of its own, integrate it once.
"""

from __future__ import annotations

import hashlib
import re
import time
from pathlib import Path

import numpy as np

from harness.measure import metrics
from harness.measure.timing import time_call
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites.accuracy import COI_DELTA
from solvers.base import AbstractSolver
from systems.cases import Case, case_record
from systems.model import relative_angles
from systems.reference import REFERENCE_TOL, reference

__all__ = ["cached_reference", "scaling", "scaling_grid"]


def scaling_grid(case: Case, settings: Settings) -> tuple[np.ndarray, np.ndarray]:
    """(t, P1): `settings.scaling_n_t` evenly spaced times on [0, t_final] s and
    `settings.scaling_n_p1` evenly spaced P1 values on [p1_min, p1_max] p.u."""
    return (np.linspace(0.0, case.t_final, settings.scaling_n_t),
            np.linspace(case.p1_min, case.p1_max, settings.scaling_n_p1))


def _key(case: Case, t: np.ndarray, P1: np.ndarray) -> str:
    digest = hashlib.sha256(repr(tuple(case_record(case).values())).encode())
    for part in (t, P1, np.array([REFERENCE_TOL])):
        digest.update(np.ascontiguousarray(part, np.float64).tobytes())
    return f"{re.sub(r'[^A-Za-z0-9_.-]+', '_', case.name)[:40]}-{digest.hexdigest()[:16]}"


def cached_reference(case: Case, t: np.ndarray, P1: np.ndarray, folder: Path | None,
                     ) -> tuple[np.ndarray, np.ndarray, float]:
    """`systems.reference.reference(case, t, P1)` (delta, omega (n_P1, n_t, n)) and the seconds it
    took to integrate, read from `folder` when a run stored it there (keyed by every field of the
    case, the grid and the tolerance), else computed and stored (written atomically)."""
    path = None if folder is None else Path(folder) / f"{_key(case, t, P1)}.npz"
    if path is not None and path.exists():
        with np.load(path) as saved:
            return saved["delta"], saved["omega"], float(saved["seconds"])
    start = time.perf_counter()
    delta, omega = reference(case, t, P1)
    seconds = time.perf_counter() - start
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{time.time_ns()}.tmp.npz")
        np.savez(tmp, delta=delta, omega=omega, seconds=seconds)
        tmp.replace(path)
    return delta, omega, seconds


def _timed(call, settings: Settings, first_s: float):
    """Warm timings of `call` (already called once, in `first_s` s): one repeat when that took
    longer than `settings.max_call_s`, else as the latency suite times."""
    slow = first_s > settings.max_call_s
    return time_call(call, warmup=0, min_repeats=1 if slow else settings.min_repeats,
                     max_repeats=1 if slow else 1000, budget_s=settings.latency_budget_s)


def scaling(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """One row: the number of machines; the median (s) of warm grid queries (`scaling_grid`) and
    of a single point (t = t_final, the middle P1); the rel. L2 and max abs error (rad) of the
    angles against the reference on the grid, relative to the centre of inertia for a system
    without an infinite bus (`systems.model.relative_angles`); and what the reference cost. An
    adapter that `counts_steps` adds the single point's trajectory's `steps` and `rhs_evals`
    (`AbstractSolver.step_count`; NaN where not counted) and the single point's time per step
    and per evaluation, `step_s` and `rhs_s` (s, everything of the call included)."""
    t, P1 = scaling_grid(case, settings)
    folder = None if settings.cache_dir is None else Path(settings.cache_dir).parent / "reference"
    ref_delta, _, ref_s = cached_reference(case, t, P1, folder)

    start = time.perf_counter()
    delta = solver.solve(t, P1).delta
    first_s = time.perf_counter() - start
    grid = _timed(lambda: solver.solve(t, P1), settings, first_s)

    t1, p1 = np.array([case.t_final]), P1[P1.size // 2: P1.size // 2 + 1]
    start = time.perf_counter()
    solver.solve(t1, p1)
    point = _timed(lambda: solver.solve(t1, p1), settings, time.perf_counter() - start)

    work = {}
    if solver.counts_steps:
        count = solver.step_count(float(p1[0]))
        rhs = np.nan if count.rhs_evals is None else float(count.rhs_evals)
        work = {"steps": count.steps, "rhs_evals": rhs, "step_s": point.median_s / count.steps,
                "rhs_s": point.median_s / rhs}
    pred, ref = relative_angles(case, delta), relative_angles(case, ref_delta)
    return [{
        "machines": case.n, "n_trajectories": P1.size, "n_times": t.size, "horizon_s": case.t_final,
        "quantity": "delta" if case.has_infinite_bus else COI_DELTA,
        "rel_l2": metrics.rel_l2(pred, ref), "max_abs": metrics.max_abs(pred, ref),
        "grid_first_s": first_s, "grid_median_s": grid.median_s, "grid_repeats": grid.repeats,
        "point_median_s": point.median_s, "point_repeats": point.repeats, "reference_s": ref_s, **work,
    }]


SUITE = Suite("scaling", scaling, default=False)
