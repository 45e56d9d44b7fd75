"""The one planner: which adapter configuration runs on which case and suite, and why the rest
does not.

`plan` turns a run's solver specifications, cases and suites into units: one specification on one
case with the suites measured there, built (and fitted) once. It decides from declarations only,
never from names: what each adapter can do and what its named configs are for
(`solvers.base.AbstractSolver`: `trains`, `does_work`, `QUERY_OPTIONS`, `CASE_KINDS`,
`CONFIG_MARKS`), each case's `Case.kind`, each suite's `harness.suites.Suite` flags and the run's
`Settings`. What it does not run, it says why, at one of three levels:

- a specification on a case (`not_on_case`): a config made for another kind of case, a trained
  adapter's later seeds on a multi-machine case, an adapter that does not integrate fault cases
  (`handles_faults`) on a fault case. No run measures these: no unit, no row.
- a suite of a unit that would repeat a measurement of another unit or that the adapter cannot
  take (`_repeats`): a suite measured on the first seed only, a variant that changes only how a
  model is queried for a suite that measures no queries, a config that is a point of its adapter's
  precision sweep for the suite that sweeps, a suite of work for the do-nothing adapter. No row.
- a suite the run's settings leave out on that case, or one that measures fault cases only on a
  step case (`left_out`): the unit records one `skipped: ...` row for it without measuring
  (another run, e.g. --full, measures it).

The first two are `Plan.not_run`; the third is each unit's `Unit.skipped`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from harness.settings import Settings, SolverSpec
from harness.store import unit_key
from harness.suites import SUITES, Suite
from solvers import solver_class
from solvers.base import IDENTIFIES_NETWORKS, SWEEP_POINT, AbstractSolver
from systems.cases import NETWORK, Case

__all__ = ["FIT", "Plan", "Skip", "Unit", "left_out", "not_on_case", "plan"]

FIT = "fit"  # the unit of work that records a trained (or built) adapter's preparation cost


@dataclass(frozen=True)
class Unit:
    """One solver specification on one case and the suites to measure on it, in one process: the
    adapter is built (and fitted) once. `columns` are extra constant columns of its rows (a sweep's
    grid point); `skipped` (suite, "skipped: ...") the suites of it that the run's settings leave
    out, each recorded as one row with that status and not measured. Plain, picklable values:
    executors ship units to worker processes."""

    case: Case
    spec: SolverSpec
    suites: tuple[str, ...]
    columns: tuple[tuple[str, Any], ...] = ()
    skipped: tuple[tuple[str, str], ...] = ()

    def works(self) -> list[str]:
        """Its units of work, in run order: the fit (when a suite it measures needs a fitted adapter
        that is installed), then the suites."""
        measured = [s for s in self.suites if s not in dict(self.skipped)]
        needs_fit = solver_class(self.spec.solver) is not None and any(SUITES[s].needs_fit for s in measured)
        return [FIT, *self.suites] if needs_fit else list(self.suites)

    def base(self, settings: Settings) -> dict:
        """The columns every row of this unit carries (without `suite`)."""
        base = {"case": self.case.name, **self.spec.key(), "threads": settings.threads, **dict(self.columns)}
        cls = solver_class(self.spec.solver)
        if cls is not None:
            base.update(trains=cls.trains, compiled=cls.compiled, does_work=cls.does_work,
                        blas_threads=cls.blas_threads or settings.threads)
        return base

    def work_key(self, work: str) -> dict[str, Any]:
        """The columns that name its unit of work `work` (`harness.store.UNIT_COLUMNS`)."""
        return {"suite": work, "case": self.case.name, **self.spec.key()}

    def key(self, work: str) -> tuple:
        return unit_key(self.work_key(work))

    @property
    def label(self) -> str:
        return f"{self.spec.label} {self.case.name}"

    def make(self, settings: Settings) -> AbstractSolver:
        """Its adapter, built on its case (not fitted), as every unit of work of it runs: an adapter
        that `takes_threads` gets the run's thread count unless the spec sets one. Raises the
        adapter's ValueError for an option invalid on the case or on this machine."""
        cls = solver_class(self.spec.solver)
        given = dict(self.spec.options)
        extra = {"threads": settings.threads} if cls is not None and cls.takes_threads and "threads" not in given \
            else {}
        return self.spec.make(self.case, **extra)


@dataclass(frozen=True)
class Skip:
    """What a plan does not run, and why: `spec` on `case`, `suite` of it (None: every suite)."""

    case: Case
    spec: SolverSpec
    suite: str | None
    reason: str  # "skipped: ..."


@dataclass(frozen=True)
class Plan:
    """The units a run measures, in run order, and what it does not run without a row (`Skip`s)."""

    units: list[Unit]
    not_run: list[Skip]


def not_on_case(spec: SolverSpec, case: Case, settings: Settings) -> str | None:
    """Why no run measures `spec` on `case` ("skipped: ..."), or None when runs do. A config runs
    on the kinds of case and scenarios it is made for (`AbstractSolver.made_for`); a multi-machine case costs an
    adapter that trains minutes a model, so there it runs the run's first seed only. Adapters that
    are not installed run everywhere: their rows say so; a fault case runs the adapters that
    integrate one (`handles_faults`)."""
    cls = solver_class(spec.solver)
    if cls is None:
        return None
    if not cls.made_for(spec.config, case.kind, case.scenario):
        what = case.kind if case.fault is None else f"fault ({case.scenario.symbol})"
        return f"skipped: config {spec.config} of {spec.solver} is not made for {what} cases"
    if case.fault is not None and not cls.handles_faults:
        return f"skipped: {spec.solver} does not integrate fault cases (no handles_faults)"
    if cls.trains and case.kind == NETWORK and spec.seed not in (None, settings.seeds[0]):
        return f"skipped: an adapter that trains runs its first seed only on {case.kind} cases"
    return None


def _repeats(spec: SolverSpec, cls: type[AbstractSolver] | None, suite: Suite, first_seed: bool) -> str | None:
    """Why `suite` of `spec` would repeat another unit's measurement or cannot measure the adapter
    `cls` ("skipped: ..."), or None."""
    if cls is not None and not suite.applies(cls):
        return f"skipped: {suite.name} does not measure {spec.solver}, which does no work"
    if not (suite.every_seed or first_seed):
        return f"skipped: {suite.name} is measured on the first seed only"
    query_options = cls.QUERY_OPTIONS if cls is not None else frozenset()
    if not suite.queries and any(key in query_options for key, _ in spec.options):
        return f"skipped: {suite.name} measures no queries, and {spec.variant} changes only how a model is queried"
    if suite.own_query_path and cls is not None and any(key in query_options for key, _ in spec.options):
        return f"skipped: {suite.name} times every query path of a model itself, {spec.variant} is one of them"
    if suite.sweeps and cls is not None and SWEEP_POINT in cls.marks(spec.config):
        return f"skipped: config {spec.config} is a point of the precision sweep of {spec.solver}'s default config"
    return None


def left_out(spec: SolverSpec, case: Case, suite: Suite, settings: Settings,
             identifiers: Sequence[str] = ()) -> str | None:
    """Why the run's `settings` leave `suite` of `spec` out on `case` ("skipped: ...", recorded as
    its row), or None when it runs. Identification leaves out the configs with a mark in
    `settings.skip_identify_marks`, every adapter that does not identify (`identifies`), the multi-machine cases not in
    `settings.network_identify_cases`, and there every config not declared to identify networks
    (`IDENTIFIES_NETWORKS`; `identifiers`, the configs that are, for the message). A suite of fault
    cases (`Suite.fault_cases`) leaves out every step case. On a fault case, every suite leaves
    out the configs with a mark in `settings.fault_omit_marks` and every adapter in
    `settings.fault_omit_solvers`."""
    if suite.fault_cases and case.fault is None:
        return f"skipped: {suite.name} measures fault cases only, and {case.name} has no fault"
    cls = solver_class(spec.solver)
    if case.fault is not None and spec.solver in settings.fault_omit_solvers:
        return (f"skipped: {spec.solver} not run on fault cases in the {settings.name} run "
                f"(not a PINN of the verdicts; --full or --solver {spec.solver} runs it)")
    omitted = cls.marks(spec.config) & set(settings.fault_omit_marks) if case.fault is not None and cls else set()
    if omitted:
        return (f"skipped: config {spec.config} ({', '.join(sorted(omitted))}) not run on fault cases in the "
                f"{settings.name} run (--full runs it)")
    if not suite.identifies or cls is None:
        return None
    if not cls.identifies:
        return f"skipped: {spec.solver} does not identify (its model is fitted to the case's own m and d)"
    marks = cls.marks(spec.config)
    if marks & set(settings.skip_identify_marks):
        return f"skipped: config {spec.config} not identified in the {settings.name} run (--full runs it)"
    if case.kind == NETWORK and case.name not in settings.network_identify_cases:
        return f"skipped: {case.name} not identified in the {settings.name} run (--full runs it)"
    if case.kind == NETWORK and IDENTIFIES_NETWORKS not in marks:
        return f"skipped: config {spec.config} not identified on multi-machine cases (only {', '.join(identifiers)})"
    return None


def _first_seed(spec: SolverSpec, specs: list[SolverSpec]) -> bool:
    seeds = [s.seed for s in specs if (s.solver, s.config, s.options) == (spec.solver, spec.config, spec.options)]
    return spec.seed is None or spec.seed == min(seeds)


def _budgeted(spec: SolverSpec, case: Case, settings: Settings) -> SolverSpec:
    """`spec` with the training budget `settings.case_pinn_options` gives `case` (iterations
    per window, so that a seed gives the same network on any machine; the options show in the
    row's variant), for adapters that train a model per case (`trained_per_case`): each option the adapter has, unless the spec sets it
    to another value than the run-wide `settings.pinn_options` (an option of the command line);
    otherwise `spec`."""
    budget = settings.case_pinn_options.get(case.name)
    cls = solver_class(spec.solver)
    if not budget or cls is None or not cls.trains or not cls.trained_per_case:
        return spec
    own = {key: value for key, value in spec.options
           if key not in settings.pinn_options or settings.pinn_options[key] != value}
    options = {**dict(spec.options), **{key: value for key, value in budget.items()
                                        if key in cls.OPTIONS and key not in own}}
    return replace(spec, options=tuple(sorted(options.items())))


def _verdict_pinns(settings: Settings) -> str:
    return "; ".join(f"{solver} {' or '.join(configs)} with {', '.join(f'{k}={v}' for k, v in options) or 'any options'}"
                     for solver, configs, options in settings.verdict_pinns)


def _network_identifiers(specs: list[SolverSpec]) -> list[str]:
    """The configs of the adapters of `specs` declared to identify networks, each name once."""
    names: dict[str, None] = {}
    for cls in dict.fromkeys(solver_class(spec.solver) for spec in specs):
        if cls is not None:
            names.update((config, None) for config in cls.CONFIGS if IDENTIFIES_NETWORKS in cls.marks(config))
    return list(names)


def plan(specs: list[SolverSpec], cases: list[Case], suites: list[Suite], settings: Settings | None = None,
         ) -> Plan:
    """The units of `swingbench run` in run order: the forward cases first, then suites with a case
    of their own (`Suite.own_case`, e.g. the SMIB's identification case), each case once; on each,
    the specs that runs measure there (`not_on_case`) with the training budget `settings` give that
    case, each with the suites it measures (not `_repeats`), the ones `left_out` recorded as
    skipped. `settings` None: `Settings()`, a run without cuts."""
    settings = Settings() if settings is None else settings
    targets: dict[Case, list[Suite]] = {case: [s for s in suites if s.own_case is None] for case in cases}
    for suite in suites:
        if suite.own_case is not None:
            for case in cases:
                group = targets.setdefault(suite.own_case(case), [])
                if suite not in group:
                    group.append(suite)
    identifiers = _network_identifiers(specs)
    units, not_run = [], []
    for case, group in targets.items():
        for spec in specs:
            budgeted = _budgeted(spec, case, settings)
            reason = not_on_case(spec, case, settings)
            if reason is not None:
                not_run.append(Skip(case, budgeted, None, reason))
                continue
            cls = solver_class(spec.solver)
            first = _first_seed(spec, specs)
            chosen, skipped = [], []
            for suite in group:
                reason = _repeats(spec, cls, suite, first)
                if reason is None and suite.verdicts and not settings.verdict_pinn(spec):
                    reason = f"skipped: {suite.name} measures the run's verdict PINNs only ({_verdict_pinns(settings)})"
                if reason is not None:
                    not_run.append(Skip(case, budgeted, suite.name, reason))
                    continue
                chosen.append(suite.name)
                reason = left_out(spec, case, suite, settings, identifiers)
                if reason is not None:
                    skipped.append((suite.name, reason))
            if chosen:
                units.append(Unit(case, budgeted, tuple(chosen), skipped=tuple(skipped)))
    return Plan(units, not_run)
