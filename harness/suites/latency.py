"""Warm query latency: the paper's grid, batches of trajectories, one time point at several t1,
and a batch of single-point queries at scattered (t1, P1) in one call."""

from __future__ import annotations

import os

import numpy as np

from harness.measure.timing import time_call
from harness.settings import Settings
from harness.suites._base import Suite
from solvers.base import AbstractSolver
from systems.cases import Case, standard_grid

T1_S = 10.0  # the paper's single-time-point query (its 87x claim)
POINTS_SEED = 2024  # the scattered single points: the same for every adapter
# A query is asked only when its answer (delta and omega, float64) takes at most this share of the
# machine's memory: an adapter holds the answer and its own work arrays at once (the reduced PINN
# about twice the answer), and a query over the memory ends the whole process.
ANSWER_MEMORY_SHARE = 1 / 3


def machine_memory_bytes() -> int:
    """The machine's physical memory (bytes)."""
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def too_large(case: Case, kind: str, t: np.ndarray, P1: np.ndarray, memory_bytes: int | None = None) -> str | None:
    """A "skipped: ..." status when the answer of the query (`kind`, times `t` s, scenarios `P1`)
    on `case`, 2 x 8 bytes x len(P1) x (1 for a batch of points, else len(t)) x n, is over
    `ANSWER_MEMORY_SHARE` of `memory_bytes` (default: this machine's memory); else None."""
    memory = machine_memory_bytes() if memory_bytes is None else memory_bytes
    size = 16 * P1.size * (1 if kind == "points batch" else t.size) * case.n
    if size <= ANSWER_MEMORY_SHARE * memory:
        return None
    return (f"skipped: its answer, {size / 2**30:.3g} GiB (delta and omega, float64), is over "
            f"{ANSWER_MEMORY_SHARE:.2g} of this machine's {memory / 2**30:.3g} GiB")


def scattered_points(case: Case, n: int, distinct: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`n` seeded random (t1 s, P1 p.u.) pairs, uniform on (0, t_final] x [p1_min, p1_max]; with
    `distinct`, P1 drawn uniformly from that many values evenly spaced over [p1_min, p1_max] (the
    same t1). Returns (t1, P1), each (n,)."""
    rng = np.random.default_rng(POINTS_SEED)
    t1, P1 = case.t_final * (1.0 - rng.random(n)), rng.uniform(case.p1_min, case.p1_max, n)
    if distinct is not None:
        P1 = np.linspace(case.p1_min, case.p1_max, distinct)[rng.integers(0, distinct, n)]
    return t1, P1


def queries(case: Case, settings: Settings) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(kind, name, t_query, P1): the 100 x 201 grid; `throughput_sizes` trajectories of 201 times
    (P1 evenly spaced over the case's range; the size of the grid is the grid); delta and omega at
    each t1 in `t1_values_s` within the horizon for the middle P1; and `points_batch` scattered single points
    (`scattered_points`) answered by one `solve_points` call (kind "points batch"), every P1
    distinct, then (with `points_distinct_p1`) the same times over that many distinct P1 values."""
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
        if settings.points_distinct_p1:
            t_points, p_points = scattered_points(case, settings.points_batch, settings.points_distinct_p1)
            out.append(("points batch", (f"{settings.points_batch} single points over {settings.points_distinct_p1} {case.scenario.symbol}, "
                                        "one call"), t_points, p_points))
    return out


def extrapolated_s(kind: str, n: int, timed: dict[str, list[tuple[int, float]]]) -> float | None:
    """Seconds a query of `kind` and size `n` (trajectories or points) should take: the last timed
    query of its kind (a batch of points: the last single point, the latest t1) times the ratio of
    the sizes, n / its size; None when nothing of the kind was timed yet. Linear in the work and
    never more, so an estimate is a measured time times that ratio: a time inflated by a busy
    machine cannot compound into a far larger one. A query whose cost grows faster (a stacked
    system's implicit solve) is underestimated and then measured: a call over `max_call_s` is
    timed once, and the next query is estimated from that measured time."""
    points = timed.get("single point" if kind == "points batch" else kind)
    if not points:
        return None
    size, seconds = points[-1]
    return seconds * n / size


def latency(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """Median, quartiles and minimum (s) of warm `solve` calls (delta and omega), and of one
    `solve_points` call for the batch of points; `per_query_s` = median / number of trajectories
    or points. A query whose cost, extrapolated from the earlier queries of its kind (`extrapolated_s`),
    exceeds `max_query_s`, or whose answer would not fit in memory (`too_large`), is skipped with a
    row that says so, rather than left out silently."""
    rows = []
    timed: dict[str, list[tuple[int, float]]] = {}
    for kind, name, t, P1 in queries(case, settings):
        n = P1.size
        base = {"kind": kind, "query": name, "n_trajectories": n, "n_times": t.size if kind != "points batch" else 1,
                "distinct_p1": int(np.unique(P1).size),
                "t1_s": float(t[0]) if kind == "single point" else np.nan}
        estimate = extrapolated_s(kind, n, timed)
        if (large := too_large(case, kind, t, P1)) is not None:
            rows.append({**base, "status": large})
            continue
        if estimate is not None and estimate > settings.max_query_s:
            rows.append({**base, "status": f"skipped: estimated {estimate:.3g} s per call, over "
                                           f"{settings.max_query_s:g} s"})
            continue
        call = solver.solve_points if kind == "points batch" else solver.solve
        timing = time_call(lambda t=t, P1=P1, call=call: call(t, P1), min_repeats=settings.min_repeats,
                           budget_s=settings.latency_budget_s, slow_s=settings.max_call_s)
        timed.setdefault(kind, []).append((n, timing.median_s))  # single points: by t1, the last the largest
        rows.append({**base, **timing._asdict(), "per_query_s": timing.median_s / n})
    return rows


SUITE = Suite("latency", latency, interface=True)
