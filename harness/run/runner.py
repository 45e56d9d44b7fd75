"""One runner for `swingbench run` and `swingbench sweep`.

`harness.run.plan.plan` (or a sweep's grid) gives units: one solver specification on one case with the
suites to measure on it, built and fitted once (and those the run's settings leave out there,
recorded as skipped). `check_units` builds (does not fit) every unit's adapter before anything is
measured, so that an option value invalid on one of the cases stops the command at once.
`execute` skips the units of work (a suite of a unit, or its fit) whose completion the store
already records, runs the rest on an executor (in this process, joblib or Dask:
`harness.run.executors`) and records each unit of work as it completes, with its rows in one write
(`RowStore.record`). Failures and missing dependencies are rows (`failed` tells them); the run
goes on, and the command says afterwards which units failed, with its exit status
(`harness.cli.outcome`). An interrupt is no failure: one that compiled code wrapped in another
exception stops the run as a plain Ctrl-C does (`harness.usage.failure_status`).
"""

from __future__ import annotations

import os
import socket
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from dataclasses import replace

from harness.measure.timing import blas_threads, pinned_threads
from harness.model_cache import fit_or_load
from harness.run.isolation import OverLimit, call_isolated
from harness.run.plan import FIT, Unit, plan
from harness.settings import Settings, SolverSpec
from harness.store import RowStore
from harness.suites import SUITES
from harness.usage import failure_status
from solvers import UNAVAILABLE, solver_class
from solvers.progress import progress_enabled
from systems.cases import Case

__all__ = ["check_units", "execute", "failed", "inline", "run_suites", "run_unit"]

def check_units(units: Iterable[Unit], settings: Settings,
                describe: Callable[[Unit], str] = lambda unit: unit.label) -> None:
    """Build (not fit) the adapter of every unit as it would run, once per spec and case, so that an
    option value that one of the cases or this machine refuses (a step longer than the case's
    horizon, a device that is not there: the adapter's own rules) stops the command before anything
    is measured, instead of failing that unit after the others ran. Adapters that are not installed
    are not checked (their rows say 'skipped'). Raises ValueError, one line: `describe(unit)`, then
    the adapter's message, which names the option and the value."""
    seen = set()
    for unit in units:
        key = (unit.spec.label, unit.case.name)  # option values may be lists: labels hash, specs may not
        if key in seen or solver_class(unit.spec.solver) is None:
            continue
        seen.add(key)
        try:
            unit.make(settings)
        except (ValueError, TypeError) as exc:  # TypeError: an adapter's rule meeting a value of the wrong type
            raise ValueError(f"{describe(unit)}: {exc}") from None


def run_unit(unit: Unit, settings: Settings, todo: Iterable[str]) -> Iterator[tuple[str, list[dict]]]:
    """Measure the units of work `todo` (names from `unit.works()`) of `unit` and yield (work, rows)
    as each completes. The adapter is built and, when a suite needs it, fitted or loaded from the
    model cache even if its fit is already recorded. Never raises for a failing adapter: its units
    of work get one 'failed: ...' row each (a missing dependency 'skipped: ...'); an interrupt,
    wrapped or not, is raised as a KeyboardInterrupt.

    In this process, unless `settings.unit_limits` is set: then the whole unit runs in a fresh
    process under those limits (`harness.run.isolation`), every row gains `peak_rss_mib` (the peak
    resident memory of that process: imports, build, training, queries), and a unit that runs past
    a limit is killed and gets one 'skipped: out of time: ...' / 'skipped: out of memory: ...' row
    per unit of work."""
    if settings.unit_limits is None:
        yield from _run_unit_here(unit, settings, todo)
        return
    todo = tuple(todo)
    try:
        parts, peak_mib = call_isolated(run_unit_in_worker, unit, replace(settings, unit_limits=None), todo,
                                        limits=settings.unit_limits)
    except (OverLimit, RuntimeError) as exc:
        status = f"skipped: {exc}" if isinstance(exc, OverLimit) else failure_status(exc)
        print(f"[swingbench] {unit.label}: {status}", file=sys.stderr)
        base = {**unit.base(settings), "worker": f"{socket.gethostname()}:{os.getpid()}"}
        for work in (w for w in unit.works() if w in todo):
            yield work, [{"suite": work, **base, "status": status}]
        return
    for work, rows in parts:
        yield work, [{**row, "peak_rss_mib": peak_mib} for row in rows]


def _run_unit_here(unit: Unit, settings: Settings, todo: Iterable[str]) -> Iterator[tuple[str, list[dict]]]:
    todo = [w for w in unit.works() if w in set(todo)]
    base = {**unit.base(settings), "worker": f"{socket.gethostname()}:{os.getpid()}"}
    cls = solver_class(unit.spec.solver)
    if cls is None:
        for work in todo:
            yield work, [{"suite": work, **base, "status": UNAVAILABLE[unit.spec.solver]}]
        return
    skipped = dict(unit.skipped)  # the plan's: recorded, not measured
    if all(work in skipped for work in todo):  # nothing to measure: the adapter is not built
        for work in todo:
            yield work, [{"suite": work, **base, "status": skipped[work], "work_s": 0.0}]
        return
    suites = [w for w in todo if w != FIT]
    with blas_threads(cls.blas_threads):
        try:
            start = time.perf_counter()
            solver = unit.make(settings)
            if any(SUITES[s].needs_fit for s in suites if s not in skipped) or FIT in todo:
                report = fit_or_load(solver, settings)
                if FIT in todo:
                    yield FIT, [{"suite": FIT, **base, "status": "ok", "fit_s": report.seconds,
                                 "iterations": report.iterations, "loss": report.loss, "message": report.message,
                                 "work_s": time.perf_counter() - start}]
        except Exception as exc:  # noqa: BLE001 - recorded as rows, the run goes on
            status = failure_status(exc)
            print(f"[swingbench] {unit.label}: {status}", file=sys.stderr)
            traceback.print_exc()
            for work in todo:
                yield work, [{"suite": work, **base, "status": status}]
            return
        for suite in suites:
            start = time.perf_counter()
            try:
                rows = [{"status": skipped[suite]}] if suite in skipped else SUITES[suite].run(solver, unit.case, settings)
            except Exception as exc:  # noqa: BLE001
                rows = [{"status": failure_status(exc)}]
                print(f"[swingbench] {unit.label} {suite}: {rows[0]['status']}", file=sys.stderr)
                traceback.print_exc()
            work_s = time.perf_counter() - start
            yield suite, [{"suite": suite, **base, "status": "ok", **row, "work_s": work_s} for row in rows]


def run_unit_in_worker(unit: Unit, settings: Settings, todo: tuple[str, ...]) -> list[tuple[str, list[dict]]]:
    """`run_unit` in a worker process pinned to `settings.threads` threads; every part at once."""
    with pinned_threads(settings.threads):
        return list(run_unit(unit, settings, todo))


def inline(jobs: list[tuple[Unit, tuple[str, ...]]], settings: Settings
           ) -> Iterator[tuple[Unit, str, list[dict] | None]]:
    """The executor of this process (threads as pinned by the caller), each unit of work recorded
    as it ends: `execute`'s default. The executors of other processes are in `harness.run.executors`."""
    for unit, todo in jobs:
        for work, rows in run_unit(unit, settings, todo):
            yield unit, work, rows


def _progress_bar(total: int, enabled: bool | None):
    """A bar of units of work on stderr when `progress_enabled(enabled)` (solvers.progress)."""
    if not progress_enabled(enabled):
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="work", file=sys.stderr, dynamic_ncols=True)


def failed(row: dict) -> bool:
    """Whether `row` records a failure: a status that is neither "ok" nor a declared skip
    ("skipped: ...": a missing dependency, a unit out of time or memory, a query the settings do
    not measure), e.g. "failed: SolveError: ..."."""
    status = str(row.get("status"))
    return status != "ok" and not status.startswith("skipped")


def execute(units: Iterable[Unit], settings: Settings, store: RowStore, executor=None,
            progress: bool | None = None, done: set[tuple] | None = None) -> dict[str, int]:
    """Run every unit of work of `units` not in `done` (keys of completed units, e.g. from
    `RowStore.prepare_resume`) on `executor` (default: this process, `inline`)
    and record each as it completes. Returns counts of units of work: {"ok", "skipped", "failed",
    "lost"} (failed: a row of it `failed`; skipped: none failed, some declared a skip; lost: the
    executor broke before returning them; nothing is recorded, `--resume` runs them)."""
    done = set() if done is None else done
    jobs = []
    for unit in units:
        todo = tuple(w for w in unit.works() if unit.key(w) not in done)
        if todo:
            jobs.append((unit, todo))
    counts = {"ok": 0, "skipped": 0, "failed": 0, "lost": 0}
    bar = _progress_bar(sum(len(todo) for _, todo in jobs), progress)
    try:
        for unit, work, rows in (executor or inline)(jobs, settings):
            if rows is None:
                counts["lost"] += 1
            else:
                store.record(unit.work_key(work), rows)
                counts["failed" if any(map(failed, rows)) else
                       "ok" if all(r.get("status") == "ok" for r in rows) else "skipped"] += 1
            if bar:
                bar.set_description(f"{unit.label} {work}")
                bar.update(1)
    finally:
        if bar:
            bar.close()
    return counts


def run_suites(
    specs: Iterable[SolverSpec], cases: Iterable[Case], suites: Iterable[str], settings: Settings,
    store: RowStore, progress: bool | None = None, resume: bool = False,
) -> dict[str, int]:
    """`execute` the `plan` of `specs` x `cases` x `suites` in this process. With `resume`, what
    the store records as complete is not run again (see `RowStore.prepare_resume`). ValueError,
    before anything is measured, for an unknown suite or an option invalid on one of the cases
    (`check_units`)."""
    names = list(suites)
    unknown = [s for s in names if s not in SUITES]
    if unknown:
        raise ValueError(f"unknown suite(s) {', '.join(unknown)}; known: {', '.join(SUITES)}")
    units = plan(list(specs), list(cases), [SUITES[n] for n in names], settings).units
    check_units(units, settings)
    done = store.prepare_resume().completed if resume else set()
    return execute(units, settings, store, progress=progress, done=done)
