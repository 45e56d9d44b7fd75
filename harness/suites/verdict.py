"""Verdicts: each query of the latency suite, the PINN (trained from several seeds) against its
matched rival, timed paired and interleaved, with the ratio's 95 % interval and a label.

For every seed of `Settings.verdict_seeds` (the unit's adapter is the first; the others are
trained here, or loaded from the model cache) and every query (`harness.suites._matching.verdict_queries`):
the PINN's accuracy on that query (`harness.suites._matching.query_errors`, off its training points
included), its fastest query path there (`query_paths`: the framework's evaluator or the compiled
numba one, the same weights) and its rival (`harness.suites._matching.Rivals.best`: the fastest point of a compiled classical
adapter's precision sweep at least as accurate in the angles and the speeds). Then
`Settings.verdict_rounds` rounds, each over every query and seed in turn, of
`Settings.verdict_pairs` interleaved pairs of samples (`harness.measure.paired.interleaved`): the samples
of one verdict come from moments minutes apart. A seed whose errors are not finite or whose error
in the angles exceeds `Settings.verdict_gate` counts as a loss (the label "classical faster", as MLPerf counts a run
that missed its target), as does, with the label "no rival" and no ratio, a query where no sweep
point is as accurate or every such point is out of time (the row's `rivals_note` says which).
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from harness.measure.paired import (
    CLASSICAL_FASTER,
    NO_RIVAL,
    RUN_TO_RUN,
    calls_per_sample,
    interleaved,
    ratio_interval,
    verdict_label,
    warm_call_s,
)
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites._matching import Match, Query, Rivals, off_training_errors, query_errors, verdict_queries
from harness.suites._seeds import seed_models
from solvers.base import AbstractSolver
from systems.cases import Case

__all__ = ["query_paths", "verdict"]

_RIVALS: dict[tuple[str, int], Rivals] = {}  # one per case in a process: accuracies measured once


def _rivals(case: Case, settings: Settings) -> Rivals:
    key = (case.name, hash((settings.verdict_rtols, settings.omit_marks, settings.threads, settings.max_query_s)))
    if key not in _RIVALS:
        _RIVALS.clear()
        _RIVALS[key] = Rivals(case, settings)
    return _RIVALS[key]


def query_paths(solver: AbstractSolver) -> dict[str, AbstractSolver]:
    """The ways of querying the fitted `solver`'s model: path text ("query=numba") -> an adapter
    answering from the same weights, one per variant of its adapter made only of options that
    change how a model is queried (`VARIANTS` within `QUERY_OPTIONS`) and the path of none of
    them (those options at their defaults); the weights are passed by `save` / `load` (`can_save`).
    Just {its own options: solver} for an adapter without such variants."""
    cls = type(solver)
    variants = [dict(v) for v in cls.VARIANTS if set(v) <= cls.QUERY_OPTIONS]
    keys = sorted({key for variant in variants for key in variant})
    own = ",".join(f"{key}={solver.options[key]}" for key in keys)
    if not variants or not cls.can_save:
        return {own: solver}
    out = {}
    with tempfile.TemporaryDirectory() as folder:
        saved = Path(folder) / "model"
        solver.save(saved)
        for variant in ({}, *variants):
            options = {**solver.options, **{key: cls.OPTIONS[key] for key in keys}, **variant}
            path = ",".join(f"{key}={options[key]}" for key in keys)
            if path == own:
                out[path] = solver
            else:
                other = cls(solver.case, solver.config, **options)
                other.load(saved)
                out[path] = other
    return out


def _fastest_path(paths: dict[str, AbstractSolver], query: Query) -> str:
    """The path of `paths` whose warm call on `query` is fastest (`warm_call_s`)."""
    seconds = {path: warm_call_s(query.call(solver)) for path, solver in paths.items()}
    return min(seconds, key=seconds.__getitem__)


def verdict(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """One row per query and seed (`pinn_seed`; the row's `seed` stays the unit's, whose rows
    these are): the PINN's errors (angles, speeds), its rival and the rival's
    errors, the paired samples (s per call) of both, their medians, the ratio rival / PINN with its
    95 % interval, the label (of that ratio and interval) and the seed's training seconds and
    iterations. Beside the ratio, conservative (its rival at least as accurate), the matched one
    (`matched_ratio`): the ratio times the rival's family's warm seconds interpolated to the PINN's
    accuracy in the binding metric over the rival's own (`Rivals.match`), with the rival's margin
    (`rival_margin`, <= 1) and `nearest_factor` (>= 1: the PINN's error over the nearest sweep
    point's, or its inverse). A rival more accurate than needed would be faster at matched
    accuracy, so the conservative ratio overstates the PINN's lead; where the rival is its
    family's coarsest point, `matched_ratio` is NaN and `rivals_note` says the ratio is only an
    upper bound on that lead."""
    seeds = seed_models(solver, settings)
    rivals = _rivals(case, settings)
    plans: list[dict] = []
    paths = {seed: query_paths(pinn) for seed, (pinn, _, _) in seeds.items()}
    off = {seed: off_training_errors(pinn, case) for seed, (pinn, _, _) in seeds.items()}
    for query in verdict_queries(case, settings):
        for seed, (own, fit_s, iterations) in seeds.items():
            delta, omega = query_errors(own, case, query, off[seed])
            path = _fastest_path(paths[seed], query)
            pinn = paths[seed][path]
            base = {"pinn_seed": seed, "kind": query.kind, "query": query.name, "n_trajectories": query.P1.size,
                    "distinct_p1": query.distinct_p1, "pinn_path": path, "t1_s": float(query.t[0]) if query.kind == "single point"
                    else np.nan, "pinn_rel_l2_delta": delta, "pinn_rel_l2_omega": omega,
                    "fit_s": fit_s, "fit_iterations": iterations}
            gate = math.isfinite(delta) and math.isfinite(omega) and delta <= settings.verdict_gate
            rival, notes = rivals.best(query, delta, omega) if gate else (None, [])
            match = rivals.match(rival, query, delta, omega) if rival is not None else None
            plans.append({"base": base, "query": query, "pinn": pinn, "rival": rival, "notes": notes, "gate": gate,
                          "match": match, "samples": ([], [])})
        print(f"[swingbench] verdict {case.name} {query.name}: rivals chosen", file=sys.stderr)
    for plan in plans:
        if plan["rival"] is not None:
            pinn_call, rival_call = plan["query"].call(plan["pinn"]), plan["query"].call(plan["rival"].solver())
            plan["calls"] = (calls_per_sample(warm_call_s(pinn_call)), calls_per_sample(warm_call_s(rival_call)))
    for _ in range(settings.verdict_rounds):
        for plan in plans:
            if plan["rival"] is None:
                continue
            query: Query = plan["query"]
            a, b = interleaved(query.call(plan["pinn"]), query.call(plan["rival"].solver()), settings.verdict_pairs,
                               *plan["calls"])
            plan["samples"][0].extend(a)
            plan["samples"][1].extend(b)
    return [_row(plan, settings, rivals) for plan in plans]


def _row(plan: dict, settings: Settings, rivals: Rivals) -> dict:
    row = {**plan["base"], "rivals_note": "; ".join(plan["notes"]), "rounds": settings.verdict_rounds}
    if not plan["gate"]:
        return {**row, "label": CLASSICAL_FASTER, "rival": "", "gate": False,
                "rivals_note": f"the PINN's angle error is over the gate {settings.verdict_gate:g}: counted as a loss"}
    rival = plan["rival"]
    if rival is None:
        return {**row, "label": NO_RIVAL, "rival": "", "gate": True}
    pinn_s, rival_s = plan["samples"]
    ratio, low, high = ratio_interval(pinn_s, rival_s)
    rival_delta, rival_omega = rivals.errors(rival, plan["query"])
    match: Match = plan["match"]
    if match.note:
        row["rivals_note"] = "; ".join([*plan["notes"], match.note])
    return {**row, "gate": True, "matched_ratio": ratio * match.time_factor, "rival_margin": match.margin,
            "nearest_factor": match.nearest_factor, "rival": rival.label, "rival_rel_l2_delta": rival_delta,
            "rival_rel_l2_omega": rival_omega, "pinn_samples_s": pinn_s, "rival_samples_s": rival_s,
            "samples": len(pinn_s), "pinn_median_s": float(np.median(pinn_s)),
            "rival_median_s": float(np.median(rival_s)), "calls_per_sample": list(plan["calls"]),
            "ratio": ratio, "ratio_low": low, "ratio_high": high, "run_to_run": RUN_TO_RUN,
            "label": verdict_label(low, high)}


SUITE = Suite("verdict", verdict, trained_only=True, verdicts=True, own_query_path=True)
