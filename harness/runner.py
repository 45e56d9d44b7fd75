"""Run suites over solver specifications and cases, one row at a time into a RowStore."""

from __future__ import annotations

import traceback
from collections.abc import Callable, Iterable

from harness.cases import Case
from harness.runs import Settings, SolverSpec
from harness.store import RowStore
from harness.suites import SUITES
from solvers import SOLVERS, UNAVAILABLE

__all__ = ["run_suites"]


def _failure(exc: BaseException) -> str:
    return f"failed: {type(exc).__name__}: {exc}"


def run_suites(
    specs: Iterable[SolverSpec], cases: Iterable[Case], suites: Iterable[str], settings: Settings,
    store: RowStore, progress: Callable[[str], None] | None = None,
) -> None:
    """For each case and spec: build and `fit()` once (a 'fit' row with its cost), then run each
    suite on the fitted solver. A missing dependency gives 'skipped' rows and a failure gives
    'failed' rows; either way the run goes on and no finished row is lost."""
    suites = list(suites)
    unknown = [s for s in suites if s not in SUITES]
    if unknown:
        raise ValueError(f"unknown suite(s) {', '.join(unknown)}; known: {', '.join(SUITES)}")
    say = progress or (lambda _msg: None)
    for case in cases:
        for spec in specs:
            base = {"case": case.name, **spec.key(), "threads": settings.threads}
            if SOLVERS.get(spec.solver) is None:
                for suite in ["fit", *suites]:
                    store.add({"suite": suite, **base, "status": UNAVAILABLE[spec.solver]})
                continue
            say(f"{case.name} {spec.label}: fit")
            try:
                solver = spec.make(case)
                report = solver.fit()
            except Exception as exc:  # noqa: BLE001 - recorded as a row, the run goes on
                traceback.print_exc()
                for suite in ["fit", *suites]:
                    store.add({"suite": suite, **base, "status": _failure(exc)})
                continue
            store.add({"suite": "fit", **base, "status": "ok", "fit_s": report.seconds,
                       "iterations": report.iterations, "loss": report.loss, "message": report.message})
            for suite in suites:
                say(f"{case.name} {spec.label}: {suite}")
                try:
                    rows = SUITES[suite](solver, case, settings)
                except Exception as exc:  # noqa: BLE001
                    traceback.print_exc()
                    store.add({"suite": suite, **base, "status": _failure(exc)})
                    continue
                for row in rows:
                    store.add({"suite": suite, **base, "status": "ok", **row})
