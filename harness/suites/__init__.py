"""Suites: each a function (solver, case, settings) -> list of row dicts, no I/O.

A row holds the measurement's own columns; the runner adds suite, case, solver, config, variant,
seed and status, so every suite's rows form one tidy DataFrame. `Suite` says how the runner
treats each: whether it needs a fitted solver, whether it repeats for every training seed, and
whether it runs on a case of its own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from systems.cases import SMIB_IDENTIFICATION, Case
from harness.suites.accuracy import accuracy
from harness.suites.identification import identification, observations
from harness.suites.latency import latency
from harness.suites.work_precision import work_precision


@dataclass(frozen=True)
class Suite:
    name: str
    run: Callable
    needs_fit: bool = True
    every_seed: bool = False  # False: measured on the first seed of a trained adapter only
    case: Case | None = None  # None: the run's forward cases
    interface: bool = False  # also measured on the do-nothing adapter (the interface's own cost)
    queries: bool = True  # measures queries; False: a spec that differs only in how a trained model is
    #                       queried (`query=numba`) would repeat the same work, so it is not run for it

    def applies(self, cls: type) -> bool:
        """Whether this suite measures adapters of class `cls`."""
        return cls.does_work or self.interface


SUITES: dict[str, Suite] = {suite.name: suite for suite in (
    Suite("accuracy", accuracy, every_seed=True),
    Suite("latency", latency, interface=True),
    Suite("work_precision", work_precision),
    Suite("identification", identification, needs_fit=False, case=SMIB_IDENTIFICATION, queries=False),
)}

__all__ = ["SUITES", "Suite", "accuracy", "identification", "latency", "observations", "work_precision"]
