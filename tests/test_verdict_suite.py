"""The verdict suite: every query matched from a sweep, paired samples, intervals, labels, seeds;
the classical surrogate beside the ODE solver, timed in the same rounds."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from harness.measure.paired import CLASSICAL_FASTER, INTERVAL, NO_RIVAL, verdict_label
from harness.report.comparison import compare_runs
from harness.report.verdicts import verdicts
from harness.settings import QUICK
from harness.suites import _matching
from harness.suites._matching import Rivals
from harness.suites._queries import query_errors, verdict_queries
from harness.suites.verdict import _rivals, query_paths, verdict
from solvers import SOLVERS, make_solver
from systems.cases import SMIB_INFERENCE as CASE
from tests.conftest import require

SETTINGS = replace(QUICK, cache_dir=None, verdict_seeds=(0, 1), verdict_rounds=2, verdict_pairs=4,
                   throughput_sizes=(1,), t1_values_s=(10.0,), points_batch=30, points_distinct_p1=5,
                   verdict_rtols=(1e-2, 1e-4, 1e-6, 1e-8), verdict_gate=1.0)
PINN = {"hidden_layers": 2, "width": 8, "n_f": 200, "max_iterations": 40, "progress": False}


@pytest.fixture(scope="module")
def pinn():
    require("jax-pinn")
    require("numba-rk")
    solver = make_solver("jax-pinn", CASE, **PINN)
    solver.fit()
    return solver


@pytest.fixture(scope="module")
def checkpoints() -> list[tuple[list[dict], str]]:
    """What the `rows` run handed its checkpoint: (rows so far, progress), one per call."""
    return []


@pytest.fixture(scope="module")
def rows(pinn, checkpoints):
    return verdict(pinn, CASE, SETTINGS, checkpoint=lambda rows, progress: checkpoints.append((rows, progress)))


@pytest.mark.slow
def test_every_query_and_seed_has_a_row_with_enough_paired_samples_an_interval_and_a_label(rows):
    queries = [q.name for q in verdict_queries(CASE, SETTINGS)]
    assert [r["query"] for r in rows] == [q for q in queries for _ in (0, 1)]
    assert [r["pinn_seed"] for r in rows] == [0, 1] * len(queries)
    assert {"30 single points, one call", "30 single points over 5 P1, one call"} <= set(queries)
    points = [r for r in rows if r["query"] == "30 single points over 5 P1, one call"]
    assert points and all(r["distinct_p1"] == 5 for r in points)
    assert {r["pinn_path"] for r in rows} <= {"query=framework", "query=numba"}
    for r in rows:
        assert r["label"] != NO_RIVAL, r
        assert r["samples"] == len(r["pinn_samples_s"]) == len(r["rival_samples_s"]) == 8  # >= 7: the floor
        assert r["ratio_low"] <= r["ratio"] <= r["ratio_high"]
        assert r["label"] == verdict_label(r["ratio_low"], r["ratio_high"])
        assert r["ratio"] == pytest.approx(np.median(r["rival_samples_s"]) / np.median(r["pinn_samples_s"]))
        assert r["interval"] == INTERVAL  # the rule the interval was stated under


@pytest.mark.slow
def test_the_rival_is_as_accurate_in_angles_and_speeds_and_the_coarsest_such_point_of_its_sweep(rows):
    rivals = Rivals(CASE, SETTINGS)
    queries = {q.name: q for q in verdict_queries(CASE, SETTINGS)}
    for r in rows:
        assert r["rival_rel_l2_delta"] <= r["pinn_rel_l2_delta"] and r["rival_rel_l2_omega"] <= r["pinn_rel_l2_omega"]
        family = next(points for points in rivals.sweeps.values() if any(c.label == r["rival"] for c in points))
        at = [c.label for c in family].index(r["rival"])
        assert r["rival_margin"] <= 1 <= r["nearest_factor"]
        if at == 0:  # nothing coarser to interpolate to: the ratio is only an upper bound on the PINN's lead
            assert np.isnan(r["matched_ratio"]) and "the coarsest sweep point is" in r["rivals_note"]
        else:
            assert np.isnan(r["matched_ratio"]) == ("gives no finite answer" in r["rivals_note"])
        if at > 0:  # the coarser point before it is not as accurate on this query
            coarser = rivals.errors(family[at - 1], queries[r["query"]])
            assert coarser[0] > r["pinn_rel_l2_delta"] or coarser[1] > r["pinn_rel_l2_omega"]


@pytest.mark.slow
def test_the_surrogate_is_a_second_rival_timed_and_labelled_by_the_same_rule(rows):
    surrogates = _rivals(CASE, SETTINGS, surrogates=True)
    assert len(surrogates.sweeps) == 1 and all(2 <= len(points) <= 4 for points in surrogates.sweeps.values())
    (points,) = surrogates.sweeps.values()
    queries = {q.name: q for q in verdict_queries(CASE, SETTINGS)}
    assert any(r["surrogate_label"] != NO_RIVAL for r in rows)
    for r in rows:
        # the PINN's training seconds beside the surrogate's (the unit's own seed's: its fit's report)
        assert r["fit_s"] > 0
        if r["surrogate_label"] == NO_RIVAL:
            assert "no sweep point as accurate" in r["surrogate_note"] and math.isnan(r["surrogate_fit_s"])
            continue
        assert r["surrogate_rel_l2_delta"] <= r["pinn_rel_l2_delta"]
        assert r["surrogate_rel_l2_omega"] <= r["pinn_rel_l2_omega"]
        assert r["surrogate_samples"] == len(r["surrogate_pinn_samples_s"]) == len(r["surrogate_samples_s"]) == 8
        assert r["surrogate_ratio_low"] <= r["surrogate_ratio"] <= r["surrogate_ratio_high"]
        assert r["surrogate_label"] == verdict_label(r["surrogate_ratio_low"], r["surrogate_ratio_high"])
        assert r["surrogate_ratio"] == pytest.approx(np.median(r["surrogate_samples_s"])
                                                     / np.median(r["surrogate_pinn_samples_s"]))
        at = [c.label for c in points].index(r["surrogate"])
        assert 0 < r["surrogate_fit_s"] == points[at].fit_s < math.inf
        if at > 0:  # the configuration before it is not as accurate on this query
            coarser = surrogates.errors(points[at - 1], queries[r["query"]])
            assert coarser[0] > r["pinn_rel_l2_delta"] or coarser[1] > r["pinn_rel_l2_omega"]


@pytest.mark.slow
def test_the_seeds_are_trained_apart_and_the_table_says_how_many_agree(rows):
    by_seed = {r["pinn_seed"]: r["pinn_rel_l2_delta"] for r in rows if r["query"] == "grid 100x201"}
    assert by_seed[0] != by_seed[1]
    frames = {"verdict": _frame(rows)}
    table = verdicts(frames)
    assert len(table) == len(verdict_queries(CASE, SETTINGS)) and (table["seeds"] == 2).all()
    for _, v in table.iterrows():
        labels = {r["label"] for r in rows if r["query"] == v["query"]}
        assert v["verdict"] == (labels.pop() if len(labels) == 1 else "tie")
    same = compare_runs(frames, frames)
    assert (same["agreement"] == "agree").all()


@pytest.mark.slow
def test_a_seed_over_the_accuracy_gate_is_a_loss_and_a_query_without_an_accurate_point_says_so(pinn, monkeypatch):
    solver = pinn
    small = replace(SETTINGS, verdict_seeds=(0,), throughput_sizes=(), points_batch=0)
    gated = verdict(solver, CASE, replace(small, verdict_gate=1e-12))
    assert gated and all(r["label"] == r["surrogate_label"] == CLASSICAL_FASTER and r["gate"] is False for r in gated)
    monkeypatch.setattr(_matching.Rivals, "errors", lambda self, c, q: (np.inf, np.inf))
    _matching_cache_clear()
    none = verdict(solver, CASE, replace(small, verdict_gate=1.0))
    assert all(r["label"] == NO_RIVAL and "no sweep point as accurate" in r["rivals_note"] for r in none)
    assert all(r["surrogate_label"] == NO_RIVAL and "pod-spline default: no sweep point as accurate" in r["surrogate_note"]
               for r in none)


@pytest.mark.slow
def test_a_query_that_fails_or_does_not_fit_is_its_own_row_and_the_others_are_measured(pinn, monkeypatch):
    """One query's failure (here its errors raise) and one query too large for memory are a row
    each with the status; every other query gets its verdict."""
    from harness.suites import verdict as suite

    small = replace(SETTINGS, verdict_seeds=(0,), points_batch=0)  # the grid, 1 trajectory, 1 point
    queries = verdict_queries(CASE, small)
    large = next(q.name for q in queries if q.P1.size > 1)
    failing = next(q.name for q in queries if q.kind == "single point")
    errors = suite.query_errors

    def fail_one(solver, case, query, off=None):
        if query.name == failing:
            raise MemoryError("out of memory")
        return errors(solver, case, query, off)

    monkeypatch.setattr(suite, "query_errors", fail_one)
    monkeypatch.setattr(suite, "too_large", lambda case, kind, t, P1: "skipped: too large" if P1.size > 1 else None)
    rows = {r["query"]: r for r in verdict(pinn, CASE, small)}
    assert set(rows) == {q.name for q in queries} and len(rows) == 3
    assert rows[failing]["status"] == "failed: MemoryError: out of memory"
    assert rows[large]["status"] == "skipped: too large"
    measured = [r for name, r in rows.items() if "status" not in r]
    assert measured and all(r["samples"] > 0 for r in measured)


@pytest.mark.slow
def test_a_query_whose_pinn_call_takes_or_is_estimated_over_max_query_s_is_skipped(pinn):
    """As the latency suite: the first query of each kind is called (once: over the limit, no timed
    repeat) and skipped when its call took over the limit, a later one estimated from it; the first
    of many trajectories (the grid) is estimated from one trajectory's call (`probe_s`)."""
    small = replace(SETTINGS, verdict_seeds=(0,), max_query_s=1e-9)
    rows = {r["query"]: r for r in verdict(pinn, CASE, small)}
    points = [name for name in rows if "single points" in name]
    assert len(points) == 2 and len(rows) == 5
    for name, row in rows.items():  # the points estimated from the single point's time x 30
        said = "estimated" if name in points or row["kind"] == "grid" else "took"
        assert row["status"].startswith(f"skipped: the PINN's call {said} "), row
        assert ("one trajectory's call times their number" in row["status"]) == (row["kind"] == "grid")
        assert row["status"].endswith(", over 1e-09 s") and "samples" not in row


@pytest.mark.slow
def test_after_each_round_but_the_last_the_rows_so_far_go_to_the_checkpoint(rows, checkpoints):
    assert [progress for _, progress in checkpoints] == ["1 of 2 rounds"]
    kept = checkpoints[0][0]
    assert [(r["query"], r["pinn_seed"]) for r in kept] == [(r["query"], r["pinn_seed"]) for r in rows]
    for before, after in zip(kept, rows):
        assert before["rounds"] == 1 and after["rounds"] == 2
        assert before["samples"] == 4 and after["samples"] == 8  # one round of 4 pairs, then two
        assert after["pinn_samples_s"][:4] == before["pinn_samples_s"]  # the same samples, extended
        assert before["label"] == verdict_label(before["ratio_low"], before["ratio_high"])


@pytest.mark.slow
def test_the_query_paths_of_a_model_answer_alike_from_the_same_weights(pinn):
    solver = pinn
    paths = query_paths(solver)
    assert set(paths) == {"query=framework", "query=numba"} and paths["query=framework"] is solver
    t, P1 = np.linspace(0.0, CASE.t_final, 11), np.linspace(CASE.p1_min, CASE.p1_max, 3)
    np.testing.assert_allclose(paths["query=numba"].solve(t, P1).delta, solver.solve(t, P1).delta, atol=1e-10)


def test_query_errors_include_the_off_training_grid():
    require("numba-rk")
    solver = make_solver("numba-rk", CASE, rtol=1e-3, atol=1e-6)
    solver.fit()
    query = verdict_queries(CASE, SETTINGS)[0]
    off = (1.0, 2.0)
    assert query_errors(solver, CASE, query, off) == (1.0, 2.0)
    assert max(query_errors(solver, CASE, query)) < 1e-2
    assert SOLVERS["numba-rk"].compiled


def test_the_reference_of_scattered_points_is_each_points_own_and_one_cache_entry():
    from harness.suites._queries import _points_reference
    from systems.reference import _reference, reference

    t, P1 = np.array([0.3, 0.1, 0.3, 0.7]), np.array([CASE.p1_max, CASE.p1_min, CASE.p1_min, CASE.p1_max])
    _reference.cache_clear()
    delta, omega = _points_reference(CASE, t, P1)
    assert _reference.cache_info().misses == 1 and delta.shape == omega.shape == (4, CASE.n)
    for i in range(t.size):
        d, o = reference(CASE, t[i:i + 1], P1[i:i + 1])
        np.testing.assert_allclose((delta[i], omega[i]), (d[0, 0], o[0, 0]), rtol=0, atol=1e-12)


def _frame(rows):
    import pandas as pd

    return pd.DataFrame([{"suite": "verdict", "case": CASE.name, "solver": "jax-pinn", "config": "default",
                          "variant": "query=numba", "status": "ok", **r} for r in rows])


def _matching_cache_clear():
    from harness.suites import verdict as module

    module._RIVALS.clear()


def test_two_runs_agree_flip_or_tie_in_one_and_compare_exits_1_on_a_flip(monkeypatch):
    import argparse

    import pandas as pd

    from harness.cli import compare
    def run(*labels):
        return {"verdict": pd.DataFrame([
            {"suite": "verdict", "case": "wscc9", "solver": "jax-pinn", "config": "marching", "variant": "",
             "status": "ok", "query": f"q{i}", "kind": "grid", "pinn_seed": 0, "label": label,
             "ratio": ratio, "ratio_low": ratio / 1.1, "ratio_high": ratio * 1.1,
             "pinn_rel_l2_delta": 1e-4, "pinn_rel_l2_omega": 1e-3}
            for i, (label, ratio) in enumerate(labels)])}

    a = run(("PINN faster", 3.0), ("tie", 1.0), ("classical faster", 0.3))
    b = run(("classical faster", 0.3), ("PINN faster", 3.0), ("classical faster", 0.4))
    assert compare_runs(a, b)["agreement"].tolist() == ["FLIP", "tie in one run", "agree"]
    runs = {"A": a, "B": b}
    monkeypatch.setattr(compare, "_frames", lambda directory: runs[str(directory)])
    args = argparse.Namespace(run_a=Path("A"), run_b=Path("B"), update_readme=None)
    assert compare.cmd_compare(args) == 1
    assert "Of the 3 ratios of run B, 0 (0 %) lie inside run A's 95 % interval" in compare.compare_block(Path("A"), Path("B"))
    runs["B"] = a
    assert compare.cmd_compare(args) == 0


def test_compare_says_how_the_surrogates_verdicts_held_and_exits_1_on_their_flip(monkeypatch):
    import argparse

    import pandas as pd

    from harness.cli import compare

    def run(*surrogate):
        return {"verdict": pd.DataFrame([
            {"suite": "verdict", "case": "wscc9", "solver": "jax-pinn", "config": "marching", "variant": "",
             "status": "ok", "query": f"q{i}", "kind": "grid", "pinn_seed": 0, "label": "tie",
             "ratio": 1.0, "ratio_low": 0.9, "ratio_high": 1.1, "pinn_rel_l2_delta": 1e-4, "pinn_rel_l2_omega": 1e-3,
             "surrogate_label": label, "surrogate_ratio": ratio, "surrogate_ratio_low": ratio / 1.5,
             "surrogate_ratio_high": ratio * 1.5}
            for i, (label, ratio) in enumerate(surrogate)])}

    a = run(("classical faster", 0.1), ("tie", 1.0), ("not applicable", np.nan))
    b = run(("classical faster", 0.2), ("tie", 1.2), ("not applicable", np.nan))
    both = compare_runs(a, b)
    assert both["agreement"].tolist() == ["agree"] * 3 and both["surrogate agreement"].tolist() == ["agree"] * 3
    runs = {"A": a, "B": b}
    monkeypatch.setattr(compare, "_frames", lambda directory: runs[str(directory)])
    block = compare.compare_block(Path("A"), Path("B"))
    assert ("Against the classical surrogate, 3 verdicts in both runs: 3 agree, 0 flip, 0 are a tie in one run and "
            "not in the other; 1 of run B's 2 ratios (50 %) inside run A's interval.") in block
    args = argparse.Namespace(run_a=Path("A"), run_b=Path("B"), update_readme=None)
    assert compare.cmd_compare(args) == 0
    runs["B"] = run(("PINN faster", 5.0), ("tie", 1.0), ("not applicable", np.nan))
    assert compare.cmd_compare(args) == 1  # the PINN's own verdicts agree; the surrogate's flip


def test_a_rival_whose_first_call_is_over_the_limit_is_refused_after_that_call_alone(monkeypatch):
    """`Rivals.best` refuses a sweep point whose call takes over the run's `max_query_s`; the
    untimed first call tells, so no timed call follows it (a fine fixed step on a large grid took
    minutes a call)."""
    rivals = Rivals(CASE, replace(SETTINGS, max_query_s=0.005))
    monkeypatch.setattr(rivals, "errors", lambda candidate, query: (0.0, 0.0))
    calls: dict[str, int] = {}

    class Slow:
        name = "slow query"
        points = True  # a batch of points over one P1: not probed on a few of its P1 values
        P1 = np.zeros(3)

        def call(self, solver):
            def run():
                calls[solver] = calls.get(solver, 0) + 1
                time.sleep(0.02)
            return run

    for family, points in rivals.sweeps.items():
        points[0]._solver = family  # no adapter built: the fake query only counts its calls
    rival, notes = rivals.best(Slow(), 1.0, 1.0)
    assert rival is None and len(notes) == len(rivals.sweeps) > 0
    assert all("skipped, out of time" in note for note in notes)
    assert calls == dict.fromkeys(rivals.sweeps, 1)


def test_a_rival_of_many_trajectories_is_probed_on_a_few_and_refused_unrun_when_far_over_the_limit(monkeypatch):
    """A query of many trajectories is timed first on `PROBE_P1` of them; a point whose estimate
    is over `PROBE_MARGIN` x `max_query_s` is refused without its full call (case118's 10,000
    trajectories: minutes a call of the trapezoid), one under it is called as before."""
    from harness.suites._matching import PROBE_MARGIN, PROBE_P1
    from harness.suites._queries import Query

    limit = 0.01
    rivals = Rivals(CASE, replace(SETTINGS, max_query_s=limit))
    monkeypatch.setattr(rivals, "errors", lambda candidate, query: (0.0, 0.0))
    sizes: list[int] = []

    class Linear:  # a solver whose call takes `each` seconds a trajectory
        def __init__(self, each: float) -> None:
            self.each = each

        def solve(self, t, P1):
            sizes.append(P1.size)
            time.sleep(self.each * P1.size)

    family, points = next(iter(rivals.sweeps.items()))
    many = Query("trajectories", "many", np.linspace(0.0, 1.0, 3), np.linspace(0.1, 0.2, 100 * PROBE_P1))
    points[0]._solver = Linear(PROBE_MARGIN * limit / PROBE_P1)  # the estimate: 100 x 3 x limit
    assert rivals.warm_call_s(points[0], many) > PROBE_MARGIN * limit
    assert sizes == [PROBE_P1, PROBE_P1]  # the probe's untimed and timed calls, never the query's own
    monkeypatch.setattr(rivals, "sweeps", {family: points})
    rival, notes = rivals.best(many, 1.0, 1.0)  # the row's note says the seconds are an estimate
    expected = (f"{points[0].label}: skipped, out of time ({rivals.warm_call_s(points[0], many):.3g} s a call, "
                f"estimated from {PROBE_P1} of its trajectories, over {limit:g} s)")
    assert rival is None and notes == [expected]
    sizes.clear()
    few = Query("trajectories", "few", many.t, many.P1[:2 * PROBE_P1])
    points[1]._solver = Linear(1e-5)
    rivals.warm_call_s(points[1], few)
    assert sizes[:2] == [PROBE_P1, PROBE_P1] and set(sizes[2:]) == {2 * PROBE_P1} and len(sizes) > 2


def test_a_rival_of_points_over_many_p1_is_probed_on_the_points_of_a_few_p1(monkeypatch):
    """A batch of points over more than `PROBE_P1` distinct P1 is probed on the points of its first
    `PROBE_P1` values (a solver integrates one trajectory per value) and refused unrun when the
    estimate is over `PROBE_MARGIN` x `max_query_s`; one over fewer values is called as it is."""
    from harness.suites._matching import PROBE_MARGIN, PROBE_P1
    from harness.suites._queries import Query

    limit = 0.01
    rivals = Rivals(CASE, replace(SETTINGS, max_query_s=limit))
    monkeypatch.setattr(rivals, "errors", lambda candidate, query: (0.0, 0.0))
    distinct: list[int] = []

    class PerTrajectory:  # a solver whose call takes `each` seconds a distinct P1
        def __init__(self, each: float) -> None:
            self.each = each

        def solve_points(self, t, P1):
            distinct.append(np.unique(P1).size)
            time.sleep(self.each * np.unique(P1).size)

    family, points = next(iter(rivals.sweeps.items()))
    rng = np.random.default_rng(0)
    values = np.linspace(0.1, 0.2, 100 * PROBE_P1)
    P1 = np.concatenate([values, rng.choice(values, 2000)])  # every value, then repeats
    many = Query("points batch", "many", rng.uniform(0.1, 1.0, P1.size), P1)
    points[0]._solver = PerTrajectory(PROBE_MARGIN * limit / PROBE_P1)  # the estimate: 100 x 3 x limit
    assert rivals.warm_call_s(points[0], many) > PROBE_MARGIN * limit
    assert distinct == [PROBE_P1, PROBE_P1]  # the probe's untimed and timed calls only
    monkeypatch.setattr(rivals, "sweeps", {family: points})
    rival, notes = rivals.best(many, 1.0, 1.0)
    assert rival is None and notes[0].endswith(f"estimated from the points of {PROBE_P1} of its P1 values, "
                                               f"over {limit:g} s)")
    distinct.clear()
    few = Query("points batch", "few", np.linspace(0.1, 1.0, 50), np.repeat(values[:PROBE_P1], 5))
    points[1]._solver = PerTrajectory(1e-5)
    rivals.warm_call_s(points[1], few)
    assert set(distinct) == {PROBE_P1} and len(distinct) > 1  # the query's own calls, no probe
