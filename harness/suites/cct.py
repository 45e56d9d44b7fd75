"""Critical clearing time: each adapter that integrates fault cases finds each fault case's CCT to a
bracket of `BRACKET_S` (1 ms), through the adapter interface alone, with the stability criterion of
`systems.stability` (`is_unstable`: some machine more than pi rad from the centre of inertia within
the horizon) judged on the time grid `criterion_times` (every `CRITERION_DT_S` = 10 ms over
[0, t_final]). The reference CCT is `systems.stability.reference_cct` (bisection to 1e-6 s on the
reference integrator).

- An adapter that does not train: bisection over t_c from the case's range [p1_min, p1_max], each
  evaluation one `solve(criterion_times, [t_c])` and the criterion on it (the interface has no
  early stop, so each evaluation integrates the whole horizon): 2 + ceil(log2(range / 1 ms))
  evaluations, 11 on [0.05, 0.40] s.
- An adapter that trains (a surrogate): one batched `solve` over a grid of t_c every
  `Settings.cct_surrogate_step_s` across the range, the criterion on each trajectory, the bracket
  [last stable, first unstable] taken where the grid first turns unstable, then bisection with
  single queries down to 1 ms (none when the grid is 1 ms apart).

The CCT is the bracket's midpoint; a method whose trajectories are unstable at p1_min (or stable at
p1_max) has no CCT inside the range (NaN, the row's `note` says which).

An adapter may refuse a clearing time (`SolveError`: pinnsim, for one, when a machine leaves its
network's trained domain or Gauss-Newton does not converge). A refused batch is asked again one
clearing time at a time; a refused clearing time is neither stable nor unstable. An adapter that
says how far each trajectory held (`PartialSolveError`: pinnsim does) is judged on that part: a
trajectory that crossed the criterion before it stopped is unstable (the reference, too, stops at
its first crossing), one that stopped before any crossing is refused, and no batch is asked again.

The bracket is then [the last clearing time judged stable, the first judged unstable above it];
bisection splits the widest interval between its ends and the refused clearing times inside it
(the CCT still lies in the bracket, so a clearing time judged on either side of a refusal still
narrows it); where refusals leave nothing wider than `BRACKET_S` to bisect, the bracket stays wider.
The row counts the distinct clearing times refused (`refused`) and its `note` says where the search
stopped and why; with no clearing time judged stable (or unstable) the CCT is NaN.

The search is timed whole, warm, as the latency suite times a query (`harness.measure.timing.time_call`; a search over
`Settings.max_call_s` is timed once).

Each row holds what its unit measures; the training cost of a surrogate is its unit's `fit` row,
and the break-even, which needs the other adapters' searches, is computed by the report
(`harness.report.cct`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from harness.measure.timing import time_call
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites._seeds import seed_models
from solvers.base import AbstractSolver, PartialSolveError, SolveError
from systems.cases import Case
from systems.model import relative_angles
from systems.reference import reference
from systems.stability import ANGLE_LIMIT, is_unstable, reference_cct

__all__ = ["BRACKET_S", "CRITERION_DT_S", "Search", "bisect", "cct", "criterion_times", "grid_then_bisect",
           "partial_labels", "stability_labels"]

BRACKET_S = 1e-3  # s: the width of the bracket every method narrows the CCT to
CRITERION_DT_S = 0.01  # s: the spacing of the times the criterion is judged at
# The clearing times of the trajectories a row keeps for the figure: this far (s) either side of the
# reference CCT, within the case's range, every `TRAJECTORY_EVERY`-th time of `criterion_times`.
TRAJECTORY_OFFSET_S = 0.02
TRAJECTORY_EVERY = 2


@dataclass(frozen=True)
class Search:
    """The outcome of one CCT search: the final bracket [stable, unstable] of clearing times (s;
    NaN on the side the range does not reach), `solves` calls to `solve` holding `trajectories`
    clearing times in all, `note` ("" or why there is no CCT in the range, or why the bracket is
    wider than `BRACKET_S`) and the clearing times the adapter refused (`refused`)."""

    stable_s: float
    unstable_s: float
    solves: int
    trajectories: int
    note: str = ""
    refused: int = 0

    @property
    def cct_s(self) -> float:
        """The midpoint of the bracket (s); NaN when the range holds no CCT."""
        return 0.5 * (self.stable_s + self.unstable_s)


def criterion_times(case: Case) -> np.ndarray:
    """Every `CRITERION_DT_S` s on [0, t_final] (t_final included): the times the criterion is
    judged at, (n_t,) s."""
    return np.linspace(0.0, case.t_final, round(case.t_final / CRITERION_DT_S) + 1)


@dataclass
class _Judge:
    """The criterion on `solver`'s trajectories on the times `t` (s), counting the `solve` calls,
    the clearing times asked and the distinct ones refused (a refused one is not asked again)."""

    solver: AbstractSolver
    t: np.ndarray
    solves: int = 0
    trajectories: int = 0
    refused_t_c: set[float] = field(default_factory=set)

    def __call__(self, t_c: np.ndarray) -> np.ndarray:
        """(len(t_c),) float: 1.0 where the trajectory cleared at t_c (s) is unstable, 0.0 stable,
        NaN refused; a refused batch is asked again one clearing time at a time."""
        if t_c.size == 1 and _key(t_c[0]) in self.refused_t_c:
            return np.array([math.nan])
        self.solves += 1
        self.trajectories += t_c.size
        try:
            return is_unstable(self.solver.case, self.solver.solve(self.t, t_c).delta).astype(float)
        except PartialSolveError as error:
            labels = partial_labels(self.solver.case, error)
            self.refused_t_c.update(_key(x) for x in t_c[np.isnan(labels)])
            return labels
        except SolveError:
            if t_c.size == 1:
                self.refused_t_c.add(_key(t_c[0]))
                return np.array([math.nan])
        return np.concatenate([self(t_c[i:i + 1]) for i in range(t_c.size)])

    def one(self, t_c: float) -> float:
        return float(self(np.array([t_c]))[0])

    def search(self, stable_s: float, unstable_s: float, note: str = "") -> Search:
        return Search(stable_s, unstable_s, self.solves, self.trajectories, note, len(self.refused_t_c))


def stability_labels(solver: AbstractSolver, t_c: np.ndarray) -> np.ndarray:
    """(len(t_c),) float: 1.0 where `solver`'s trajectory cleared at t_c (s) is unstable by the
    criterion at `criterion_times`, 0.0 stable, NaN refused, judged as a search judges them (a
    refused batch asked again one clearing time at a time, a stopped trajectory on the part that
    held)."""
    return _Judge(solver, criterion_times(solver.case))(np.asarray(t_c, np.float64))


def partial_labels(case: Case, error: PartialSolveError) -> np.ndarray:
    """(len(t_c),) float of a call the adapter stopped part-way: 1.0 where the criterion is crossed at
    a time the trajectory still held (as the reference stops at its first crossing), 0.0 or 1.0 by
    the criterion where it held throughout, NaN (refused) where it stopped before any crossing."""
    labels = []
    for delta, held in zip(error.delta, error.held):
        part = delta[~np.isnan(delta).any(axis=-1)]  # the times the trajectory still held
        crossed = part.shape[0] > 0 and bool(is_unstable(case, part))
        labels.append(1.0 if crossed else 0.0 if np.isinf(held) else math.nan)
    return np.array(labels)


def _key(t_c: float) -> float:
    """A clearing time (s) as the judge remembers a refusal: a bisection midpoint may differ from a
    grid point by an ulp."""
    return round(float(t_c), 12)


def _narrow(judge: _Judge, lo: float, hi: float) -> Search:
    """Bisection of the bracket [lo stable, hi unstable] (s) down to `BRACKET_S`. A refused clearing
    time inside it is neither side: the widest of the intervals between lo, the refused clearing
    times inside and hi is bisected next, a clearing time judged stable moving lo up and one judged
    unstable moving hi down (the CCT lies in [lo, hi]). When every such interval is narrower than
    `BRACKET_S` and [lo, hi] is not, the bracket stays wide and the note says how many refused
    clearing times are left in it."""
    wide = BRACKET_S * (1 + 1e-9)
    refused = {t_c for t_c in judge.refused_t_c if lo < t_c < hi}
    while hi - lo > wide:
        edges = np.array([lo, *sorted(t_c for t_c in refused if lo < t_c < hi), hi])
        gaps = np.diff(edges)
        j = int(np.argmax(gaps))
        if gaps[j] <= wide:
            inside = edges[1:-1]
            where = f"at {inside[0]:.6g} s" if inside.size == 1 else f"{inside[0]:.6g} to {inside[-1]:.6g} s"
            return judge.search(lo, hi, f"{inside.size} refused t_c in the bracket ({where}): left at "
                                        f"{1e3 * (hi - lo):.3g} ms")
        mid = 0.5 * (edges[j] + edges[j + 1])
        verdict = judge.one(mid)
        if math.isnan(verdict):
            refused.add(_key(mid))
        elif verdict:
            hi = mid
        else:
            lo = mid
    return judge.search(lo, hi)


def _bracket(judge: _Judge, grid: np.ndarray, labels: np.ndarray) -> Search:
    """From the labels (1 unstable, 0 stable, NaN refused) of the clearing times `grid` (s,
    increasing): no CCT in the range (`_outside`), none found for want of a clearing time judged on
    one side, or the bracket [the last stable, the first unstable above it] narrowed (`_narrow`)."""
    case = judge.solver.case
    unstable, stable = labels == 1, labels == 0
    if unstable[0] or (stable[-1] and not unstable.any()):
        return _outside(judge, stable_at_max=not unstable.any())
    refused = f"; {int(np.isnan(labels).sum())} of {labels.size} refused"
    if not unstable.any():
        last = float(grid[stable][-1]) if stable.any() else math.nan
        return judge.search(last, math.nan, f"no clearing time judged unstable up to p1_max = {case.p1_max} s{refused}")
    first = int(np.argmax(unstable))
    if not stable[:first].any():
        return judge.search(math.nan, float(grid[first]), f"no clearing time judged stable below the first unstable, "
                                                          f"{grid[first]:.6g} s{refused}")
    return _narrow(judge, float(grid[:first][stable[:first]][-1]), float(grid[first]))


def _outside(judge: _Judge, stable_at_max: bool) -> Search:
    """The search's outcome when the range holds no CCT."""
    lo, hi = judge.solver.case.p1_min, judge.solver.case.p1_max
    if stable_at_max:
        return judge.search(hi, math.nan, f"stable at p1_max = {hi} s: the CCT lies above the range")
    return judge.search(math.nan, lo, f"unstable at p1_min = {lo} s: the CCT lies below the range")


def bisect(solver: AbstractSolver) -> Search:
    """The CCT search of an adapter that does not train: the range's ends, then bisection, each
    evaluation one trajectory on `criterion_times`."""
    case = solver.case
    judge = _Judge(solver, criterion_times(case))
    ends = np.array([case.p1_min, case.p1_max])
    return _bracket(judge, ends, judge(ends))


def grid_then_bisect(solver: AbstractSolver, step_s: float) -> Search:
    """The CCT search of a surrogate: one batched query over t_c every `step_s` s across the range
    (both ends included), the bracket where the criterion first turns unstable, then bisection with
    single queries."""
    case = solver.case
    if not step_s > 0:
        raise ValueError(f"the surrogate's grid step must be > 0 s, got {step_s!r}")
    judge = _Judge(solver, criterion_times(case))
    grid = np.linspace(case.p1_min, case.p1_max, math.ceil(round((case.p1_max - case.p1_min) / step_s, 9)) + 1)
    return _bracket(judge, grid, judge(grid))


def _trajectories(solver: AbstractSolver, ref_cct: float) -> dict:
    """The figure's data (`harness.report.cct_plot`): `traj_t_c` [stable, unstable] clearing times (s)
    `TRAJECTORY_OFFSET_S` either side of the reference CCT `ref_cct` (s), clamped to the case's range;
    `traj_t` (n_t,) s; `traj_pred` and `traj_ref` (2, n_t, n): the adapter's and the reference's
    angles from the centre of inertia (rad), as lists; {} where the adapter refuses either clearing
    time. Not timed."""
    case = solver.case
    t_c = np.clip([ref_cct - TRAJECTORY_OFFSET_S, ref_cct + TRAJECTORY_OFFSET_S], case.p1_min, case.p1_max)
    t = criterion_times(case)[::TRAJECTORY_EVERY]
    try:
        pred = relative_angles(case, solver.solve(t, t_c).delta)
    except SolveError:  # a refused clearing time: no figure of this model
        return {}
    ref = relative_angles(case, reference(case, t, t_c)[0])
    return {"traj_t_c": t_c.tolist(), "traj_t": t.tolist(), "traj_pred": pred.tolist(), "traj_ref": ref.tolist()}


def _search_row(solver: AbstractSolver, settings: Settings, ref_cct: float) -> dict:
    """The search of one model, timed (see `cct`), and its row's measurements."""
    if solver.trains:
        method, run = "grid + bisection", lambda: grid_then_bisect(solver, settings.cct_surrogate_step_s)
    else:
        method, run = "bisection", lambda: bisect(solver)
    last: list[Search] = []

    def search() -> None:
        last[:] = [run()]

    timing = time_call(search, warmup=1, min_repeats=settings.min_repeats, budget_s=settings.latency_budget_s,
                       slow_s=settings.max_call_s)
    (result,) = last
    return {
        "method": method, "cct_s": result.cct_s, "reference_cct_s": ref_cct, "cct_error_s": result.cct_s - ref_cct,
        "stable_s": result.stable_s, "unstable_s": result.unstable_s, "note": result.note,
        "solves": result.solves, "trajectories": result.trajectories, "refused": result.refused,
        "median_s": timing.median_s, "q25_s": timing.q25_s, "q75_s": timing.q75_s, "repeats": timing.repeats,
    }


def cct(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """One row per model: the fault case's contingency, the adapter's CCT (s) and the reference's,
    the error (s, the adapter's minus the reference's), the final bracket, the search's `solve`
    calls and trajectories, and the warm time of the whole search (`median_s`, `q25_s`, `q75_s`
    over `repeats` searches, s, named as the latency suite names a query's); the trajectories of
    the figure (`_trajectories`, the unit's own model). A verdict PINN (`Settings.verdict_model`)
    searches with each seed of `Settings.verdict_seeds` (`pinn_seed`, its training `seed_fit_s`,
    NaN for the unit's own seed without a model cache: its fit row has it), as the verdict suite
    times it; any other model, once."""
    if case.fault is None:
        raise ValueError(f"case {case.name!r} is no fault case: it has no CCT")
    ref_cct = reference_cct(case)
    base = {"contingency": case.fault.name, "machines": case.n, "bracket_s": BRACKET_S,
            "criterion_dt_s": CRITERION_DT_S, "angle_limit_rad": ANGLE_LIMIT}
    figure = _trajectories(solver, ref_cct)
    if not (solver.trains and settings.verdict_model(solver)):
        return [{**base, **_search_row(solver, settings, ref_cct), **figure}]
    return [{**base, **_search_row(model, settings, ref_cct), "pinn_seed": seed, "seed_fit_s": fit_s,
             **(figure if model is solver else {})}
            for seed, (model, fit_s, _iterations) in seed_models(solver, settings).items()]


SUITE = Suite("cct", cct, fault_cases=True)
