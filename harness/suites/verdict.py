"""Verdicts: each query of the latency suite, the PINN (trained from several seeds) against its
matched rival, timed paired and interleaved, with the ratio's 95 % interval and a label.

For every seed of `Settings.verdict_seeds` (the unit's adapter is the first; the others are
trained here, or loaded from the model cache) and every query (`harness.suites._queries.verdict_queries`):
the PINN's accuracy on that query (`harness.suites._queries.query_errors`, off its training points
included), its fastest query path there (`query_paths`: the framework's evaluator or the compiled
numba one, the same weights) and its rival (`harness.suites._matching.Rivals.best`: the fastest point of a compiled classical
adapter's precision sweep at least as accurate in the angles and the speeds). Then
`Settings.verdict_rounds` rounds, each over every query and seed in turn, of
`Settings.verdict_pairs` interleaved pairs of samples (`harness.measure.paired.interleaved`): the samples
of one verdict come from moments minutes apart. A seed whose errors are not finite or whose error
in the angles exceeds `Settings.verdict_gate` counts as a loss (the label "classical faster", as MLPerf counts a run
that missed its target), as does, with the label "no rival" and no ratio, a query where no sweep
point is as accurate or every such point is out of time (the row's `rivals_note` says which).

The second rival, by the same rule beside the first: the fastest configuration of a classical
surrogate (`classical_surrogate`: no network; its points its `precision_sweep`), fitted once per
case and configuration before the timing, timed against the same PINN in the same rounds
(`surrogate_*` columns, `_side_columns`): the row says whether the PINN beats the solver and
whether it beats the surrogate, and gives both fit seconds (`fit_s`, `surrogate_fit_s`). Where
no surrogate is made for the case (a fault case) its label is "not applicable", with the reason.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from harness.measure.paired import (
    CLASSICAL_FASTER,
    INTERVAL,
    NO_RIVAL,
    NOT_APPLICABLE,
    RUN_TO_RUN,
    calls_per_sample,
    interleaved,
    ratio_interval,
    verdict_label,
    warm_call_s,
)
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites._matching import Match, Rivals
from harness.suites._queries import Query, off_training_errors, query_errors, verdict_queries
from harness.suites._seeds import seed_models
from harness.suites.latency import extrapolated_s, too_large
from harness.usage import failure_status
from solvers.base import AbstractSolver
from systems.cases import Case

__all__ = ["probe_s", "query_paths", "verdict"]

_RIVALS: dict[tuple[str, bool, int], Rivals] = {}  # one of each kind per case in a process: accuracies measured once


def _rivals(case: Case, settings: Settings, surrogates: bool = False) -> Rivals:
    key = (case.name, surrogates,
           hash((settings.verdict_rtols, settings.omit_marks, settings.threads, settings.max_query_s)))
    if key not in _RIVALS:
        for old in [k for k in _RIVALS if k[1] == surrogates]:
            del _RIVALS[old]
        _RIVALS[key] = Rivals(case, settings, surrogates)
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


def _fastest_path(paths: dict[str, AbstractSolver], query: Query, settings: Settings) -> tuple[str, float]:
    """The path of `paths` whose warm call on `query` is fastest (`warm_call_s`: one timed call
    past `max_call_s`, none past `max_query_s`), and that call's seconds."""
    seconds = {path: warm_call_s(query.call(solver), slow_s=settings.max_call_s, limit_s=settings.max_query_s)
               for path, solver in paths.items()}
    path = min(seconds, key=seconds.__getitem__)
    return path, seconds[path]


def probe_s(solver: AbstractSolver, query: Query, settings: Settings) -> float | None:
    """Seconds `query` should take `solver` when nothing of its kind was timed yet: one warm call
    of its first trajectory times their number (`extrapolated_s`'s linear rule), so a grid whose
    call would run for minutes is not first measured (its errors and its call) to learn it; None
    for a query of one trajectory or of points."""
    if query.points or query.P1.size == 1:
        return None
    one = Query(query.kind, query.name, query.t, query.P1[:1])
    return warm_call_s(one.call(solver), slow_s=settings.max_call_s, limit_s=settings.max_query_s) * query.P1.size


def verdict(solver: AbstractSolver, case: Case, settings: Settings,
            checkpoint: Callable[[list[dict], str], None] | None = None) -> list[dict]:
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
    upper bound on that lead. The same columns of the second rival, the classical surrogate, are
    prefixed `surrogate_` (`_side_columns`), with its fit seconds (`surrogate_fit_s`). A query
    whose answer would not fit in memory (`harness.suites.latency.too_large`), whose PINN call
    takes over `settings.max_query_s` (as a rival's may not; the fastest seed's warm call, or
    before it is made, extrapolated from the earlier queries of its kind as the latency suite does:
    `harness.suites.latency.extrapolated_s`, or, for the first of its kind, from one trajectory's
    call: `probe_s`), or whose errors, paths or rivals raise, is one row
    with its status ("skipped: ..." or "failed: ..."), and the other queries are measured. After
    each round but the last, `checkpoint` (the runner's, where it keeps a unit's rows so far) gets
    the rows as they stand then, with `rounds` the rounds done."""
    start = time.perf_counter()
    seeds = seed_models(solver, settings)
    rivals, surrogates = _rivals(case, settings), _rivals(case, settings, surrogates=True)
    plans: list[dict] = []
    not_asked: list[dict] = []
    paths = {seed: query_paths(pinn) for seed, (pinn, _, _) in seeds.items()}
    off = {seed: off_training_errors(pinn, case) for seed, (pinn, _, _) in seeds.items()}
    timed: dict[str, list[tuple[int, float]]] = {}  # the PINN's warm seconds by kind of query, as in latency
    for query in verdict_queries(case, settings):
        about = {"kind": query.kind, "query": query.name, "n_trajectories": query.P1.size,
                 "distinct_p1": query.distinct_p1}
        status = too_large(case, query.kind, query.t, query.P1)
        estimate = extrapolated_s(query.kind, query.P1.size, timed)
        how = ""
        if status is None and estimate is None:
            estimate, how = probe_s(solver, query, settings), " (one trajectory's call times their number)"
        if status is None and estimate is not None and estimate > settings.max_query_s:
            status = f"skipped: the PINN's call estimated {estimate:.3g} s{how}, over {settings.max_query_s:g} s"
        try:
            if status is None:
                planned = [_plan(query, about, seed, model, off[seed], paths[seed], case, settings)
                           for seed, model in seeds.items()]
                fastest = min(plan["pinn_s"] for plan in planned)
                timed.setdefault(query.kind, []).append((query.P1.size, fastest))
                if fastest > settings.max_query_s:  # before the rivals are chosen: they are not needed
                    status = f"skipped: the PINN's call took {fastest:.3g} s, over {settings.max_query_s:g} s"
                else:
                    for plan in planned:
                        _choose_rivals(plan, rivals, surrogates)
                        _calls(plan)
                    plans += planned
        except Exception as exc:  # noqa: BLE001 -- one query's failure is its row's, the others are still measured
            status = failure_status(exc)
        if status is not None:
            not_asked.append({**about, "status": status})
        print(f"[swingbench] verdict {case.name} {query.name}: {status or 'rivals chosen'} "
              f"({(time.perf_counter() - start) / 60:.1f} min into the unit)", file=sys.stderr)
    for done in range(1, settings.verdict_rounds + 1):
        for plan in plans:
            for side in (plan, plan["surrogate"]):
                if side["rival"] is None:
                    continue
                query: Query = plan["query"]
                a, b = interleaved(query.call(plan["pinn"]), query.call(side["rival"].solver()),
                                   settings.verdict_pairs, *side["calls"], context_b=side["rival"].blas)
                side["samples"][0].extend(a)
                side["samples"][1].extend(b)
        print(f"[swingbench] verdict {case.name}: round {done} of {settings.verdict_rounds} timed "
              f"({(time.perf_counter() - start) / 60:.1f} min into the unit)", file=sys.stderr)
        if checkpoint is not None and done < settings.verdict_rounds:
            checkpoint([*(_row(plan, done, settings, rivals, surrogates) for plan in plans), *not_asked],
                       f"{done} of {settings.verdict_rounds} rounds")
    return [*(_row(plan, settings.verdict_rounds, settings, rivals, surrogates) for plan in plans), *not_asked]


def _plan(query: Query, about: dict, seed: int, model: tuple[AbstractSolver, float, int], off: tuple[float, float],
          paths: dict[str, AbstractSolver], case: Case, settings: Settings) -> dict:
    """One seed's verdict on `query` (`about`: its row's columns that name it) before its rivals
    (`_choose_rivals`) and its timing: the PINN's errors (`off`: its off-training errors), its
    fastest path and that path's warm seconds (`pinn_s`), and the gate."""
    own, fit_s, iterations = model
    delta, omega = query_errors(own, case, query, off)
    path, pinn_s = _fastest_path(paths, query, settings)
    base = {"pinn_seed": seed, **about, "pinn_path": path,
            "t1_s": float(query.t[0]) if query.kind == "single point" else np.nan,
            "pinn_rel_l2_delta": delta, "pinn_rel_l2_omega": omega, "fit_s": fit_s, "fit_iterations": iterations}
    gate = math.isfinite(delta) and math.isfinite(omega) and delta <= settings.verdict_gate
    return {"base": base, "query": query, "pinn": paths[path], "pinn_s": pinn_s, "gate": gate}


def _choose_rivals(plan: dict, rivals: Rivals, surrogates: Rivals) -> None:
    """Add to `plan` (`_plan`) the two rivals' parts (`_side`): the ODE rival's, the surrogate's."""
    delta, omega = plan["base"]["pinn_rel_l2_delta"], plan["base"]["pinn_rel_l2_omega"]
    plan.update(_side(rivals, plan["query"], delta, omega, plan["gate"]),
                surrogate=_side(surrogates, plan["query"], delta, omega, plan["gate"]))


def _calls(plan: dict) -> None:
    """The calls per sample of the PINN and of each rival of `plan` (`calls_per_sample` of a warm call)."""
    for side in (plan, plan["surrogate"]):
        if side["rival"] is not None:
            pinn_call, rival_call = plan["query"].call(plan["pinn"]), plan["query"].call(side["rival"].solver())
            with side["rival"].blas():
                rival_s = warm_call_s(rival_call)
            side["calls"] = (calls_per_sample(warm_call_s(pinn_call)), calls_per_sample(rival_s))


def _side(rivals: Rivals, query: Query, delta: float, omega: float, gate: bool) -> dict[str, Any]:
    """A rival's part of a verdict's plan: the rival of `rivals` on `query` of a PINN with errors
    (`delta`, `omega`) (none over the gate), the notes, its `Match` and the samples to come."""
    rival, notes = rivals.best(query, delta, omega) if gate else (None, [])
    match = rivals.match(rival, query, delta, omega) if rival is not None else None
    return {"rival": rival, "notes": notes, "match": match, "samples": ([], [])}


def _row(plan: dict, rounds: int, settings: Settings, rivals: Rivals, surrogates: Rivals | None = None) -> dict:
    """A verdict's row after `rounds` rounds: the plan's base, the ODE rival's columns and, where
    the plan has one (`surrogates` given), the surrogate's (`_surrogate_columns`)."""
    row = {**plan["base"], "rounds": rounds, "gate": plan["gate"], "interval": INTERVAL,
           **_side_columns(plan, plan["gate"], settings, rivals, plan["query"])}
    if surrogates is None or "surrogate" not in plan:
        return row
    return {**row, **_surrogate_columns(plan["surrogate"], plan["gate"], settings, surrogates, plan["query"])}


def _side_columns(side: dict, gate: bool, settings: Settings, rivals: Rivals, query: Query) -> dict:
    """One rival's columns of a verdict's row, named as the ODE rival's: its label, `rivals_note`
    and, where it was timed, its errors, the paired samples, medians, ratio, interval and matched
    ratio. A PINN over the gate: "classical faster"; no rival: "no rival"."""
    notes = "; ".join(side["notes"])
    if not gate:
        return {"label": CLASSICAL_FASTER, "rival": "",
                "rivals_note": f"the PINN's angle error is over the gate {settings.verdict_gate:g}: counted as a loss"}
    rival = side["rival"]
    if rival is None:
        return {"label": NO_RIVAL, "rival": "", "rivals_note": notes}
    pinn_s, rival_s = side["samples"]
    ratio, low, high = ratio_interval(pinn_s, rival_s)
    rival_delta, rival_omega = rivals.errors(rival, query)
    match: Match = side["match"]
    return {"rivals_note": "; ".join([*side["notes"], match.note]) if match.note else notes,
            "matched_ratio": ratio * match.time_factor, "rival_margin": match.margin,
            "nearest_factor": match.nearest_factor, "rival": rival.label, "rival_rel_l2_delta": rival_delta,
            "rival_rel_l2_omega": rival_omega, "pinn_samples_s": list(pinn_s), "rival_samples_s": list(rival_s),
            "samples": len(pinn_s), "pinn_median_s": float(np.median(pinn_s)),
            "rival_median_s": float(np.median(rival_s)), "calls_per_sample": list(side["calls"]),
            "ratio": ratio, "ratio_low": low, "ratio_high": high, "run_to_run": RUN_TO_RUN,
            "label": verdict_label(low, high)}


def _surrogate_columns(side: dict, gate: bool, settings: Settings, surrogates: Rivals, query: Query) -> dict:
    """The surrogate's columns: `_side_columns` renamed ("rival" -> "surrogate", "rival_X" ->
    "surrogate_X", "rivals_note" -> "surrogate_note", any other X -> "surrogate_X"; the PINN's
    samples paired with the surrogate's are `surrogate_pinn_samples_s`) and `surrogate_fit_s`, the
    chosen configuration's fit seconds; "not applicable" where no surrogate is made for the case."""
    if not surrogates.sweeps:
        return {"surrogate": "", "surrogate_label": NOT_APPLICABLE, "surrogate_fit_s": math.nan,
                "surrogate_note": "; ".join(surrogates.absent) or "no classical surrogate made for this case"}
    columns = _side_columns(side, gate, settings, surrogates, query)
    renamed = {{"rival": "surrogate", "rivals_note": "surrogate_note"}.get(key, "surrogate_" + key.removeprefix("rival_")): value
               for key, value in columns.items() if key != "run_to_run"}
    return {**renamed, "surrogate_fit_s": side["rival"].fit_s if side["rival"] is not None else math.nan}


SUITE = Suite("verdict", verdict, trained_only=True, verdicts=True, own_query_path=True, checkpoints=True)
