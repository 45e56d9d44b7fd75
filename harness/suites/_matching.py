"""What a verdict compares: the PINN's rivals on a query (`harness.suites._queries`: the
queries and the accuracy of either side on one): the fastest point of a compiled classical
adapter's precision sweep that is at least as accurate as the PINN in both the angles and the
speeds, and likewise of a classical surrogate's (`Rivals(..., surrogates=True)`: a model with no
network fitted to a solver's trajectories)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from harness.measure.paired import warm_call_s
from harness.measure.timing import blas_threads
from harness.settings import Settings
from harness.suites._queries import Query, off_training_errors, query_errors
from solvers import SOLVERS
from solvers.base import SWEEP_POINT, AbstractSolver, SolveError
from systems.cases import Case

__all__ = ["NEAREST_WITHIN", "Candidate", "Match", "Rivals", "interpolated_s", "margin"]

SLOW_S = 0.5  # a candidate whose first call took longer is ranked by one warm call
PROBE_P1 = 10  # a query of more trajectories is first timed on this many, to refuse what would take too long
PROBE_MARGIN = 3.0  # refused unmeasured only when the probe's estimate is this far over max_query_s
NEAREST_WITHIN = 3.0  # a sweep point within this factor of every PINN's error: the sweeps' aim (issue 36)


def margin(errors: Sequence[float], delta: float, omega: float) -> float:
    """A sweep point's accuracy margin against a PINN with errors (`delta`, `omega`): the larger of
    its errors (angles, speeds) over the PINN's, the binding metric's factor (<= 1: as accurate in
    both; NaN or inf where an error is not finite)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.max(np.divide(np.asarray(errors, dtype=float), [delta, omega])))


def interpolated_s(chosen: tuple[float, float], coarser: tuple[float, float]) -> float:
    """Seconds at margin 1 on a family's work-precision curve: log(seconds) linear in log(margin)
    between the (margin, seconds) of the `chosen` point (margin <= 1) and of the next `coarser`
    one (margin > 1)."""
    (a0, s0), (a1, s1) = chosen, coarser
    if not 0 < a0 <= 1 < a1 < math.inf:
        return math.nan
    w = -math.log(a0) / (math.log(a1) - math.log(a0))
    return math.exp((1 - w) * math.log(s0) + w * math.log(s1))


@dataclass(frozen=True)
class Match:
    """How tight a rival's match to a PINN is: `margin` (the rival's, `margin`), `nearest_factor`
    (>= 1: between the PINN's error and the nearest sweep point's in that point's binding metric,
    max(a, 1 / a)), `time_factor` (the family's seconds interpolated to margin 1 over the rival's,
    `interpolated_s`; NaN without a coarser point to interpolate to) and `note` (why it is NaN, or
    that the nearest point is over `NEAREST_WITHIN` away)."""

    margin: float
    nearest_factor: float
    time_factor: float
    note: str = ""


@dataclass
class Candidate:
    """One point of a compiled classical adapter's precision sweep: `family` (adapter, config and
    variant), `overrides` (its rtol, atol, dt or a surrogate's snapshot count), built and prepared
    on first use; `fit_s`, the seconds of that preparation (NaN before it)."""

    family: tuple[str, str, tuple[tuple[str, Any], ...]]
    overrides: dict[str, Any]
    case: Case
    threads: int
    _solver: AbstractSolver | None = field(default=None, repr=False)
    fit_s: float = math.nan

    @property
    def label(self) -> str:
        solver, config, variant = self.family
        extra = ", ".join([*(f"{k}={v}" for k, v in variant), *(f"{k}={v:g}" for k, v in self.overrides.items())])
        return f"{solver} [{config}, {extra}]"

    def solver(self) -> AbstractSolver:
        if self._solver is None:
            name, config, variant = self.family
            cls = SOLVERS[name]
            assert cls is not None
            options = {**dict(variant), **self.overrides}
            if cls.takes_threads and "threads" not in options:
                options["threads"] = self.threads
            self._solver = cls(self.case, config, **options)
            self.fit_s = self._solver.fit().seconds
        return self._solver

    def blas(self) -> AbstractContextManager:
        """Where its queries are timed: on its adapter's BLAS thread count (`blas_threads`)."""
        cls = SOLVERS[self.family[0]]
        return blas_threads(cls.blas_threads if cls is not None else None)

    def accuracy_key(self) -> tuple:
        """What its accuracy depends on: the family without options that only change how fast it
        answers (`QUERY_OPTIONS`), and the overrides."""
        name, config, variant = self.family
        cls = SOLVERS[name]
        kept = tuple((k, v) for k, v in variant if cls is None or k not in cls.QUERY_OPTIONS)
        return name, config, kept, tuple(sorted(self.overrides.items()))


def _families(case: Case, settings: Settings, surrogates: bool = False) -> list[tuple[str, str, tuple]]:
    """Every compiled classical adapter (declared `compiled`, not `trains`; with `surrogates`,
    every `classical_surrogate`) installed, in each config made for `case` that is not a point of
    another config's sweep (`SWEEP_POINT`) nor omitted by `settings.omit_marks`, plain and in each
    of its `VARIANTS`."""
    out = []
    for name, cls in SOLVERS.items():
        if cls is None or not cls.compiled or not cls.does_work or not (
                cls.classical_surrogate if surrogates else not cls.trains):
            continue
        for config in cls.CONFIGS:
            marks = cls.marks(config)
            if not cls.made_for(config, case.kind, case.scenario) or SWEEP_POINT in marks or marks & set(settings.omit_marks):
                continue
            out.extend((name, config, tuple(sorted(v.items()))) for v in ({}, *cls.VARIANTS))
    return out


class Rivals:
    """The sweep points of every compiled classical family on `case` (`_families`; each family's
    points `precision_sweep(settings.verdict_rtols)`, listed from the coarsest), their accuracy on each
    query (measured once per point and query), and the rival of a PINN on a query (`best`).

    With `surrogates`, the families of the classical surrogates instead, and `absent`: why each
    of their configs has no sweep on `case` (not made for its kind or scenario, or refused by the
    adapter: a single P1 to interpolate over); each family is fitted once untimed before its points
    are, so that a point's `fit_s` leaves out the process's one-off compilation (numba's cache)."""

    def __init__(self, case: Case, settings: Settings, surrogates: bool = False) -> None:
        self.case, self.settings = case, settings
        self.sweeps: dict[tuple, list[Candidate]] = {}
        self.absent: list[str] = [
            f"{name} {config}: not made for {case.kind} cases of {case.scenario.meaning} ({case.scenario.symbol})"
            for name, cls in SOLVERS.items() if surrogates and cls is not None and cls.classical_surrogate
            for config in cls.CONFIGS if not cls.made_for(config, case.kind, case.scenario)]
        for family in _families(case, settings, surrogates):
            try:
                proto = SOLVERS[family[0]](case, family[1], **dict(family[2]))
                if surrogates:
                    proto.fit()
            except ValueError as exc:
                if not surrogates:
                    raise
                self.absent.append(f"{family[0]} {family[1]}: {exc}")
                continue
            points = proto.precision_sweep(settings.verdict_rtols) or [{}]
            self.sweeps[family] = [Candidate(family, p, case, settings.threads) for p in points]
        self._errors: dict[tuple, tuple[float, float]] = {}
        self._seconds: dict[tuple, float] = {}
        self._estimated: set[tuple] = set()  # keys of `_seconds` that are a probe's estimate, not a call

    def errors(self, candidate: Candidate, query: Query) -> tuple[float, float]:
        """(angles, speeds) of `candidate` on `query` (`query_errors`), measured once; NaN where
        its integration fails (`SolveError`: a coarse step's Newton iteration on a fault case) or its
        answer off the training points is not finite."""
        key = (candidate.accuracy_key(), query.name)
        if key not in self._errors:
            failed = (math.nan, math.nan)
            try:
                off = self._errors.get((candidate.accuracy_key(), None))
                if off is None:
                    off = self._errors[(candidate.accuracy_key(), None)] = off_training_errors(candidate.solver(),
                                                                                                self.case)
                finite = bool(np.isfinite(off).all())
                self._errors[key] = query_errors(candidate.solver(), self.case, query, off) if finite else failed
            except SolveError:
                self._errors[key] = failed
                self._errors.setdefault((candidate.accuracy_key(), None), failed)
        return self._errors[key]

    def warm_call_s(self, candidate: Candidate, query: Query) -> float:
        """Seconds of one warm call of `candidate` on `query` (`harness.measure.paired.warm_call_s`: one
        timed call only when the untimed first took over `SLOW_S`, none when it took over the run's
        `max_query_s`, which `best` refuses), measured once; on a query of many trajectories, no call
        at all when `_estimate_s` puts it over `PROBE_MARGIN` x `max_query_s` (the estimate stands
        for it: `best` refuses it)."""
        key = (candidate.label, query.name)
        if key not in self._seconds:
            limit = self.settings.max_query_s
            with candidate.blas():
                estimate = self._estimate_s(candidate, query)
                if estimate > PROBE_MARGIN * limit:
                    self._seconds[key] = estimate
                    self._estimated.add(key)
                else:
                    self._seconds[key] = warm_call_s(query.call(candidate.solver()), slow_s=SLOW_S, limit_s=limit)
        return self._seconds[key]

    def _estimate_s(self, candidate: Candidate, query: Query) -> float:
        """Seconds of `candidate`'s call on a query of many trajectories estimated from its first
        `PROBE_P1` (one warm call, scaled by the count): a fine fixed step on 54 machines takes
        minutes for 10,000 trajectories. A batch of points over more than `PROBE_P1` distinct P1 is
        probed on the points of its first `PROBE_P1` distinct values and scaled by the number of
        distinct values, as a solver integrates one trajectory per value (10,000 scattered points are
        10,000 trajectories). 0 for any other query (not probed)."""
        if query.points:
            _, at = np.unique(query.P1, return_index=True)
            if at.size <= PROBE_P1:
                return 0.0
            keep = np.isin(query.P1, query.P1[np.sort(at)[:PROBE_P1]])
            probe = Query(query.kind, query.name, query.t[keep], query.P1[keep])
            return warm_call_s(probe.call(candidate.solver()), calls=1) * at.size / PROBE_P1
        if query.P1.size <= PROBE_P1:
            return 0.0
        probe = Query(query.kind, query.name, query.t, query.P1[:PROBE_P1])
        return warm_call_s(probe.call(candidate.solver()), calls=1) * query.P1.size / PROBE_P1

    def best(self, query: Query, delta: float, omega: float) -> tuple[Candidate | None, list[str]]:
        """The rival on `query` of a PINN with errors (`delta`, `omega`): of each family the
        coarsest sweep point at least as accurate in both (its cheapest, as a coarser point takes
        fewer steps), the fastest of these by `warm_call_s`; and notes on the families without
        one (no point as accurate, or its call over `settings.max_query_s`: out of time)."""
        picks, notes = [], []
        for family, points in self.sweeps.items():
            match = next((c for c in points if all(e <= need for e, need in zip(self.errors(c, query), (delta, omega)))),
                         None)
            if match is None:
                notes.append(f"{family[0]} {family[1]}: no sweep point as accurate")
                continue
            seconds = self.warm_call_s(match, query)
            if seconds > self.settings.max_query_s:
                of = f"the points of {PROBE_P1} of its P1 values" if query.points else f"{PROBE_P1} of its trajectories"
                how = (f", estimated from {of}"
                       if (match.label, query.name) in self._estimated else "")
                notes.append(f"{match.label}: skipped, out of time ({seconds:.3g} s a call{how}, over "
                             f"{self.settings.max_query_s:g} s)")
                continue
            picks.append((seconds, match))
        if not picks:
            return None, notes
        return min(picks, key=lambda p: p[0])[1], notes

    def match(self, rival: Candidate, query: Query, delta: float, omega: float) -> Match:
        """How tight `rival` (a point `best` chose) matches a PINN with errors (`delta`, `omega`)
        on `query`, from the points of its family up to it (those `best` measured; the finer ones,
        more accurate still, are not): margins, the nearest point's factor, and the time factor
        that turns the conservative ratio into the matched one. A rival more accurate than needed
        would be faster at matched accuracy, so the conservative ratio overstates the PINN's lead;
        where the rival is its family's coarsest point (or the next coarser gives no finite
        answer) there is nothing to interpolate to and that ratio is only an upper bound on it."""
        points = self.sweeps[rival.family]
        at = next(i for i, c in enumerate(points) if c is rival)
        margins = [margin(self.errors(c, query), delta, omega) for c in points[:at + 1]]
        factors = [max(a, 1 / a) for a in margins if 0 < a < math.inf]
        nearest = min(factors, default=math.nan)
        a = margins[at]
        more = 1 / a if a > 0 else math.inf
        if at == 0:
            return Match(a, nearest, math.nan, f"the coarsest sweep point is {more:.3g}x more accurate: the ratio is "
                                               f"an upper bound on the PINN's lead")
        coarser = points[at - 1]
        if not margins[at - 1] < math.inf:
            return Match(a, nearest, math.nan, f"the next coarser sweep point ({coarser.label}) gives no finite answer "
                                               f"and the rival is {more:.3g}x more accurate: the ratio is an upper "
                                               f"bound on the PINN's lead")
        seconds = self.warm_call_s(rival, query)
        at_one = interpolated_s((a, seconds), (margins[at - 1], self.warm_call_s(coarser, query)))
        far = (f"the nearest sweep point is {nearest:.3g}x from the PINN's error, over {NEAREST_WITHIN:g}x: the "
               f"matched ratio spans a gap in the sweep") if nearest > NEAREST_WITHIN else ""
        return Match(a, nearest, at_one / seconds, far)
