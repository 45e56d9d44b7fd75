"""The trained models of a verdict PINN's seeds (`Settings.verdict_seeds`), for the suites that
measure each seed: the verdict suite and the cct suite."""

from __future__ import annotations

import math

from harness.model_cache import fit_or_load
from harness.settings import Settings
from solvers.base import AbstractSolver

__all__ = ["seed_models"]


def seed_models(solver: AbstractSolver, settings: Settings) -> dict[int, tuple[AbstractSolver, float, int]]:
    """seed -> (fitted adapter, training seconds, iterations): the unit's own, then each other
    seed of `settings.verdict_seeds`, trained (or loaded from the model cache) here. The unit's own
    seed's cost is its `fit_report` (its fit's, or the model cache's load's; NaN and -1 without one)."""
    own = int(solver.options["seed"])
    report = solver.fit_report
    out = {own: (solver, math.nan if report is None else report.seconds, -1 if report is None else report.iterations)}
    for seed in settings.verdict_seeds:
        if seed in out:
            continue
        other = type(solver)(solver.case, solver.config, **{**solver.options, "seed": seed})
        report = fit_or_load(other, settings)
        out[seed] = (other, report.seconds, report.iterations)
    return out
