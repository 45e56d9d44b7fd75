"""What a suite declares: its name, its function and how the runner treats it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from systems.cases import Case

__all__ = ["Suite"]


@dataclass(frozen=True)
class Suite:
    """A suite's declaration: `SUITE = Suite("<name>", <function>, ...)` in harness/suites/<name>.py."""

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
    trained_only: bool = False  # measures adapters that train only
    verdicts: bool = False  # measures the run's verdict PINNs only (`Settings.verdict_pinn`)
    own_query_path: bool = False  # times every query path of a model itself: not run for a query variant
    fault_cases: bool = False  # measures fault cases only (`Case.fault`): a step case gets a skipped row
    checkpoints: bool = False  # takes `checkpoint=`, a callable (rows so far, progress in words) it calls as it
    #                            goes: a unit stopped part-way keeps those rows (`harness.run.runner`)

    def applies(self, cls: type) -> bool:
        """Whether this suite measures adapters of class `cls`."""
        if self.trained_only:
            return cls.trains
        return cls.does_work or self.interface
