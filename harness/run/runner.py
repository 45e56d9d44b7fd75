"""One runner for `swingbench run` and `swingbench sweep`.

`harness.run.plan.plan` (or a sweep's grid) gives units: one solver specification on one case with the
suites to measure on it, built and fitted once (and those the run's settings leave out there,
recorded as skipped). `check_units` builds (does not fit) every unit's adapter before anything is
measured, so that an option value invalid on one of the cases stops the command at once.
`execute` skips the units of work (a suite of a unit, or its fit) whose completion the store
already records, runs the rest on an executor (in this process, joblib or Dask:
`harness.run.executors`) and records each unit of work as it completes, with its rows in one write
(`RowStore.record`). A unit of work of a suite marked `checkpoints` keeps its rows so far in the
store's `partial/` folder as it goes (`harness.store.write_partial`): stopped part-way by a limit or
a failure, it is recorded with those rows (each with `stopped`, saying how far it got and why);
where the whole process died (killed, Ctrl-C), the next run in the folder (`--resume`) records
them so instead of measuring it again. Failures and missing dependencies are rows (`failed` tells
them); the run goes on, and the command says afterwards which units failed, with its exit status
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
from typing import Any

from harness.measure.timing import blas_threads, pinned_threads
from harness.model_cache import fit_or_load
from harness.run.isolation import OverLimit, call_isolated
from harness.run.plan import FIT, Unit, plan
from harness.settings import Settings, SolverSpec
from harness.store import RowStore, partial_path, read_partial, write_partial
from harness.suites import SUITES
from harness.usage import failure_status
from solvers import UNAVAILABLE, solver_class
from solvers.progress import progress_enabled
from systems.cases import Case

__all__ = ["RESUMED", "check_units", "execute", "failed", "inline", "kept", "run_suites", "run_unit"]

# why the rows a unit of work kept stand for it when a later run in its folder finds them
RESUMED = "the run ended before this unit of work did; the next run in its folder kept them"


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
            yield work, kept(settings, unit.work_key(work), status) or [{"suite": work, **base, "status": status}]
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
                if suite in skipped:
                    rows = [{"status": skipped[suite]}]
                else:
                    checkpoint = (_checkpoint(settings, unit.work_key(suite), base)
                                  if SUITES[suite].checkpoints else None)
                    rows = SUITES[suite].run(solver, unit.case, settings,
                                             **({"checkpoint": checkpoint} if checkpoint else {}))
            except Exception as exc:  # noqa: BLE001
                status = failure_status(exc)
                print(f"[swingbench] {unit.label} {suite}: {status}", file=sys.stderr)
                traceback.print_exc()
                rows = kept(settings, unit.work_key(suite), status) or [{"status": status}]
            work_s = time.perf_counter() - start
            yield suite, [{"suite": suite, **base, "status": "ok", **row, "work_s": work_s} for row in rows]


def _checkpoint(settings: Settings, key: dict[str, Any], base: dict) -> Callable[[list[dict], str], None] | None:
    """The `checkpoint` given to a suite marked `checkpoints` for the unit of work `key` (None where
    the run keeps no partial rows, `settings.partial_dir`): each call replaces the unit's file there
    with its rows so far, as the unit would record them (`base` columns, status "ok")."""
    if settings.partial_dir is None:
        return None
    path = partial_path(settings.partial_dir, key)
    path.unlink(missing_ok=True)  # an earlier run's (`execute` adopted it where it should): never this unit's

    def checkpoint(rows: list[dict], progress: str) -> None:
        try:
            write_partial(path, key, [{"suite": key["suite"], **base, "status": "ok", **row} for row in rows], progress)
        except OSError as exc:  # a folder this worker cannot write (a Dask worker elsewhere): it measures on
            print(f"[swingbench] cannot keep the rows so far in {path}: {exc}", file=sys.stderr)

    return checkpoint


def kept(settings: Settings, key: dict[str, Any], why: str) -> list[dict] | None:
    """The rows the unit of work `key` kept as it went (`_checkpoint`), each with `stopped`: how far
    it got and `why` it stopped there, and, but for `RESUMED`, `stopped_status`: `why`, the status
    the unit would have had without them ("failed: ...", "skipped: out of time: ..."), which
    `failed` and the counts read as its status; None when it kept none."""
    if settings.partial_dir is None:
        return None
    found = read_partial(partial_path(settings.partial_dir, key), key)
    if not found or not found[0]:
        return None
    rows, progress = found
    print(f"[swingbench] {key['suite']} of {key['solver']}:{key['config']} on {key['case']}: {len(rows)} row(s) "
          f"kept after {progress} ({why})", file=sys.stderr)
    stop = {"stopped": f"after {progress}: {why}", **({} if why == RESUMED else {"stopped_status": why})}
    return [{**row, **stop} for row in rows]


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


def _status(row: dict) -> str:
    """A row's status as the counts read it: for the kept rows of a unit stopped part-way, the
    status it would have had without them (`stopped_status`, `kept`)."""
    return str(row.get("stopped_status") or row.get("status"))


def failed(row: dict) -> bool:
    """Whether `row` records a failure: a status (or, for the kept rows of a unit stopped part-way,
    `stopped_status`: `kept`) that is neither "ok" nor a declared skip ("skipped: ...": a missing
    dependency, a unit out of time or memory, a query the settings do not measure), e.g.
    "failed: SolveError: ..."."""
    status = _status(row)
    return status != "ok" and not status.startswith("skipped")


def execute(units: Iterable[Unit], settings: Settings, store: RowStore, executor=None,
            progress: bool | None = None, done: set[tuple] | None = None) -> dict[str, int]:
    """Run every unit of work of `units` not in `done` (keys of completed units, e.g. from
    `RowStore.prepare_resume`) on `executor` (default: this process, `inline`)
    and record each as it completes. Returns counts of units of work: {"ok", "skipped", "failed",
    "lost"} (failed: a row of it `failed`; skipped: none failed, some declared a skip; lost: the
    executor broke before returning them; nothing is recorded, `--resume` runs them). When resuming
    (`done` given), a unit of work that an earlier run in the store's folder stopped part-way, and
    that kept rows there (`kept`), is recorded with them instead of being run."""
    resuming, done = done is not None, set() if done is None else done
    if settings.partial_dir is None:
        settings = replace(settings, partial_dir=store.partial_dir)
    counts = {"ok": 0, "skipped": 0, "failed": 0, "lost": 0}

    def record(unit: Unit, work: str, rows: list[dict]) -> None:
        store.record(unit.work_key(work), rows)
        partial_path(settings.partial_dir, unit.work_key(work)).unlink(missing_ok=True)
        counts["failed" if any(map(failed, rows)) else
               "ok" if all(_status(r) == "ok" for r in rows) else "skipped"] += 1

    jobs = []
    for unit in units:
        todo = []
        for work in (w for w in unit.works() if unit.key(w) not in done):
            rows = kept(settings, unit.work_key(work), RESUMED) if resuming else None
            if rows:  # a unit of work an earlier run in this folder stopped part-way: what it measured stands
                record(unit, work, rows)
            else:
                todo.append(work)
        if todo:
            jobs.append((unit, tuple(todo)))
    bar = _progress_bar(sum(len(todo) for _, todo in jobs), progress)
    try:
        for unit, work, rows in (executor or inline)(jobs, settings):
            if rows is None:
                counts["lost"] += 1
            else:
                record(unit, work, rows)
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
    done = store.prepare_resume().completed if resume else None
    return execute(units, settings, store, progress=progress, done=done)
