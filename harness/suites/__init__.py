"""Suites: each a function (solver, case, settings) -> list of row dicts, no I/O.

A row holds the measurement's own columns; the runner adds suite, case, solver, config, variant,
seed and status, so every suite's rows form one tidy DataFrame. `Suite` says how the runner
treats each: whether it needs a fitted solver, whether it repeats for every training seed, and
whether it runs on a case of its own; `harness.plan` reads them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from harness.suites.accuracy import accuracy
from harness.suites.identification import identification, observations
from harness.suites.latency import latency
from harness.suites.scaling import scaling
from harness.suites.work_precision import work_precision
from systems.cases import SMIB, SMIB_IDENTIFICATION, Case


def identification_case(case: Case) -> Case:
    """The case identification measures for a forward case: the paper's own identification case
    (m = 0.25, with the (m, d) pairs) for a SMIB case (`Case.kind`), the case itself otherwise."""
    return SMIB_IDENTIFICATION if case.kind == SMIB else case


@dataclass(frozen=True)
class Suite:
    name: str
    run: Callable
    needs_fit: bool = True
    every_seed: bool = False  # False: measured on the first seed of a trained adapter only
    own_case: Callable[[Case], Case] | None = None  # the case it measures for a forward case; None: that case
    interface: bool = False  # also measured on the do-nothing adapter (the interface's own cost)
    queries: bool = True  # measures queries; False: a spec that differs only in how a trained model is
    #                       queried (`query=numba`) would repeat the same work, so it is not run for it
    default: bool = True  # run when the command line names no suite
    identifies: bool = False  # identifies m and d: the run's settings say with which configs, on which cases
    sweeps: bool = False  # sweeps each adapter's precision: a config that is a point of the sweep repeats it

    def applies(self, cls: type) -> bool:
        """Whether this suite measures adapters of class `cls`."""
        return cls.does_work or self.interface


SUITES: dict[str, Suite] = {suite.name: suite for suite in (
    Suite("accuracy", accuracy, every_seed=True),
    Suite("latency", latency, interface=True),
    Suite("work_precision", work_precision, sweeps=True),
    Suite("identification", identification, needs_fit=False, own_case=identification_case, queries=False,
          identifies=True),
    Suite("scaling", scaling, default=False),
)}
DEFAULT_SUITES = tuple(name for name, suite in SUITES.items() if suite.default)

__all__ = ["DEFAULT_SUITES", "SUITES", "Suite", "accuracy", "identification", "identification_case", "latency", "observations", "scaling", "work_precision"]
