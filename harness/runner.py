"""Run suites over solver specifications and cases, one row at a time into a RowStore."""

from __future__ import annotations

import sys
import traceback
from collections.abc import Iterable, Iterator

from harness.cases import Case
from harness.model_cache import QUERY_ONLY_OPTIONS, Persistable, load_cached, store_cached
from harness.runs import Settings, SolverSpec
from harness.store import RowStore
from harness.suites import SUITES, Suite
from harness.timing import blas_threads
from solvers import UNAVAILABLE, solver_class
from solvers.base import AbstractSolver, FitReport

__all__ = ["plan", "run_suites"]


def _failure(exc: BaseException) -> str:
    return f"failed: {type(exc).__name__}: {exc}"


def _first_seed(spec: SolverSpec, specs: list[SolverSpec]) -> bool:
    seeds = [s.seed for s in specs if (s.solver, s.config, s.options) == (spec.solver, spec.config, spec.options)]
    return spec.seed is None or spec.seed == min(seeds)


def _query_variant(spec: SolverSpec) -> bool:
    """Whether `spec` sets an option that only changes how a trained model is queried."""
    return any(key in QUERY_ONLY_OPTIONS for key, _ in spec.options)


def plan(specs: list[SolverSpec], cases: list[Case], suites: list[Suite]) -> Iterator[tuple[Case, SolverSpec, list[Suite]]]:
    """(case, spec, suites) units in run order: the forward cases first, then suites with a case of
    their own; suites that are not measured for every seed run on the first seed only."""
    targets = [(case, [s for s in suites if s.case is None]) for case in cases]
    own = {}
    for suite in suites:
        if suite.case is not None:
            own.setdefault(suite.case, []).append(suite)
    targets += list(own.items())
    for case, group in targets:
        for spec in specs:
            cls = solver_class(spec.solver)
            chosen = [s for s in group if (s.every_seed or _first_seed(spec, specs))
                      and (cls is None or s.applies(cls)) and (s.queries or not _query_variant(spec))]
            if chosen:
                yield case, spec, chosen


def _unit_key(row: dict) -> tuple:
    return (row["suite"], row["case"], row["solver"], row["config"], row["variant"], row["seed"])


def _progress_bar(total: int, enabled: bool | None):
    enabled = sys.stderr.isatty() if enabled is None else enabled
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="step", file=sys.stderr, dynamic_ncols=True)


def fit_or_load(solver: AbstractSolver, settings: Settings) -> FitReport:
    """`fit()`, or load the trained model from the cache (with the training cost it had)."""
    cacheable = Persistable(solver) and settings.cache_dir is not None
    if cacheable and not settings.retrain:
        report = load_cached(solver, settings.cache_dir)
        if report is not None:
            return report._replace(message=f"{report.message} (cached model)".strip())
    report = solver.fit()
    if cacheable:
        store_cached(solver, report, settings.cache_dir)
    return report


def run_suites(
    specs: Iterable[SolverSpec], cases: Iterable[Case], suites: Iterable[str], settings: Settings,
    store: RowStore, progress: bool | None = None, resume: bool = False,
) -> None:
    """For each unit of `plan`: build the adapter, `fit()` it once if a suite needs it (a 'fit' row
    with its cost; trained models come from the cache unless `settings.retrain`), then run the
    suites. A missing dependency gives 'skipped' rows and a failure 'failed' rows; the run goes on
    and no finished row is lost. With `resume`, units already in `store` are not run again."""
    names = list(suites)
    unknown = [s for s in names if s not in SUITES]
    if unknown:
        raise ValueError(f"unknown suite(s) {', '.join(unknown)}; known: {', '.join(SUITES)}")
    specs, cases = list(specs), list(cases)
    units = list(plan(specs, cases, [SUITES[n] for n in names]))
    done = {_unit_key(r) for r in store.rows() if not str(r.get("status", "")).startswith("failed")} if resume else set()
    bar = _progress_bar(sum(len(group) + 1 for _, _, group in units), progress)
    for case, spec, group in units:
        cls = solver_class(spec.solver)
        base = {"case": case.name, **spec.key(), "threads": settings.threads}
        if cls is not None:
            base.update(trains=cls.trains, compiled=cls.compiled, does_work=cls.does_work,
                        blas_threads=cls.blas_threads or settings.threads)
        todo = [s for s in group if _unit_key({"suite": s.name, **base}) not in done]
        if bar:
            bar.set_description(f"{spec.label} {case.name}")
            bar.update(1 + len(group) - len(todo))
        if not todo:
            continue
        if cls is None:
            for suite in todo:
                store.add({"suite": suite.name, **base, "status": UNAVAILABLE[spec.solver]})
            continue
        with blas_threads(cls.blas_threads):
            _run_unit(spec, case, todo, base, settings, store, bar)
    if bar:
        bar.close()


def _run_unit(spec: SolverSpec, case: Case, todo: list[Suite], base: dict, settings: Settings,
              store: RowStore, bar) -> None:
    """Build, fit (or load) and run the suites `todo` of one (spec, case); failures become rows."""
    try:
        solver = spec.make(case)
        if any(s.needs_fit for s in todo):
            report = fit_or_load(solver, settings)
            store.add({"suite": "fit", **base, "status": "ok", "fit_s": report.seconds,
                       "iterations": report.iterations, "loss": report.loss, "message": report.message})
    except Exception as exc:  # noqa: BLE001 - recorded as a row, the run goes on
        traceback.print_exc()
        for suite in ["fit", *(s.name for s in todo)]:
            store.add({"suite": suite, **base, "status": _failure(exc)})
        if bar:
            bar.update(len(todo))
        return
    for suite in todo:
        if bar:
            bar.set_description(f"{spec.label} {case.name} {suite.name}")
        try:
            rows = suite.run(solver, case, settings)
        except Exception as exc:  # noqa: BLE001
            traceback.print_exc()
            rows = [{"status": _failure(exc)}]
        for row in rows:
            store.add({"suite": suite.name, **base, "status": "ok", **row})
        if bar:
            bar.update(1)
