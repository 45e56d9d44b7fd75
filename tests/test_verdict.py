"""The verdicts from synthetic rows (no measurement): the ladder's rungs, the seed rule, the
crossover in t1, the verdict sentences and the latency cells."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.report.files import write_report
from harness.report.frames import suite_frames
from harness.report.ladder import (
    COMPILED,
    GRID_QUERY,
    LITERATURE,
    POINT_QUERY,
    PYTHON_DRIVEN,
    crossover,
    ladder,
    ladder_table,
    verdict_lines,
)
from harness.report.markdown import LADDER_HEADING
from harness.report.speedups import crossover_t1

BASE = {"case": "smib-inference", "threads": 2, "status": "ok"}
PINN = {**BASE, "solver": "toy-pinn", "config": "default", "variant": "", "trains": True, "compiled": False}
RK45 = {**BASE, "solver": "scipy-rk45", "config": "default", "variant": "", "seed": -1, "compiled": False}
ODEINT = {**BASE, "solver": "scipy-odeint", "config": "tight", "variant": "", "seed": -1, "compiled": False}
NUMBA = {**BASE, "solver": "numba-rk", "config": "tight", "variant": "", "seed": -1, "compiled": True}
T1 = (1.0, 2.0, 5.0, 10.0, 20.0)


def _rows(pinn_error: float = 1e-5) -> list[dict]:
    """Seed 0 of the PINN: 1 ms grid, 10 us points at any t1; seed 1: more accurate and faster
    (never used: the verdicts take the first seed). Classical: RK45 at ode45 tolerances (1e-3),
    odeint and numba tight (1e-10); numba's single point grows with t1 (2 us per s)."""
    rows = []
    for seed, err, grid_s, point_s in ((0, pinn_error, 1e-3, 1e-5), (1, 1e-9, 1e-4, 1e-6)):
        spec = {**PINN, "seed": seed}
        rows += [{"suite": "fit", **spec, "fit_s": 50.0 + seed, "iterations": 100, "loss": 1e-9, "message": ""},
                 {"suite": "accuracy", **spec, "quantity": "delta", "against": "reference", "rel_l2": err,
                  "max_abs": err, "worst_trajectory_rel_l2": err},
                 {"suite": "latency", **spec, "kind": "grid", "query": GRID_QUERY, "median_s": grid_s,
                  "q25_s": grid_s, "q75_s": grid_s, "repeats": 5}]
        rows += [{"suite": "latency", **spec, "kind": "single point", "query": f"single point t1={t:g} s",
                  "t1_s": t, "median_s": point_s, "q25_s": point_s, "q75_s": point_s, "repeats": 5} for t in T1]
    for spec, err, grid_s, per_s in ((RK45, 1e-3, 0.5, 1e-3), (ODEINT, 1e-10, 0.02, 2e-4), (NUMBA, 1e-10, 2e-3, 2e-6)):
        rows += [{"suite": "accuracy", **spec, "quantity": "delta", "against": "reference", "rel_l2": err,
                  "max_abs": err, "worst_trajectory_rel_l2": err},
                 {"suite": "latency", **spec, "kind": "grid", "query": GRID_QUERY, "median_s": grid_s,
                  "q25_s": grid_s, "q75_s": grid_s, "repeats": 5}]
        rows += [{"suite": "latency", **spec, "kind": "single point", "query": f"single point t1={t:g} s",
                  "t1_s": t, "median_s": per_s * t, "q25_s": per_s * t, "q75_s": per_s * t, "repeats": 5}
                 for t in T1]
    # the literature baseline reaches 1e-6 only on its tolerance sweep: 0.9 s on the grid
    rows.append({"suite": "work_precision", **RK45, "rtol": 1e-7, "atol": 1e-10, "setting": "rtol=1e-07, atol=1e-10",
                 "rel_l2_delta": 1e-6, "median_s": 0.9, "point_median_s": 0.05})
    return rows


def test_ladder_ranks_each_rung_at_matched_accuracy_with_the_first_seed():
    steps = ladder(suite_frames(_rows()), GRID_QUERY).iloc[0]
    assert steps["pinn"] == "toy-pinn [default]" and steps["pinn_rel_l2"] == 1e-5 and steps["fit_s"] == 50.0
    assert steps[f"{LITERATURE}: option"] == "scipy-rk45 [default, rtol=1e-07, atol=1e-10]"
    assert steps[f"{LITERATURE}: speedup"] == pytest.approx(900.0)
    assert steps[f"{PYTHON_DRIVEN}: option"] == "scipy-odeint [tight]"
    assert steps[f"{PYTHON_DRIVEN}: speedup"] == pytest.approx(20.0)
    assert steps[f"{COMPILED}: option"] == "numba-rk [tight]"
    assert steps[f"{COMPILED}: speedup"] == pytest.approx(2.0)


def test_a_rung_with_nothing_as_accurate_says_so():
    steps = ladder(suite_frames(_rows(pinn_error=1e-12)), GRID_QUERY).iloc[0]
    assert all(math.isnan(steps[f"{rung}: speedup"]) for rung in (LITERATURE, PYTHON_DRIVEN, COMPILED))
    table = ladder_table(suite_frames(_rows(pinn_error=1e-12)))
    assert (table.iloc[:, -1] == "none as accurate").all()


def test_crossover_in_t1():
    assert crossover_t1(np.array([1.0, 10.0]), np.array([1.0, 3.0]), np.array([2.0, 2.0])) == ("crossover", 5.5)
    assert crossover_t1(np.array([1.0, 10.0]), np.array([1.0, 1.5]), np.array([2.0, 2.0]))[0] == \
        "classical cheaper everywhere"
    assert crossover_t1(np.array([1.0, 10.0]), np.array([3.0, 4.0]), np.array([2.0, 2.0]))[0] == "PINN cheaper everywhere"
    # numba costs 2 us per s of t1, the PINN 10 us: they cross at t1 = 5 s
    x = crossover(suite_frames(_rows()))
    assert x["classical"] == "numba-rk [tight]" and x["pinn"] == "toy-pinn [default]"
    assert x["how"] == "crossover" and x["t1_cross_s"] == pytest.approx(5.0)


def test_verdict_sentences_name_the_winner_of_each_query(tmp_path):
    lines = verdict_lines(suite_frames(_rows()))
    assert lines[0] == (f"{GRID_QUERY}: fastest PINN toy-pinn [default] 1 ms at rel. L2 1e-05; the PINN wins, "
                        "2x faster than numba-rk [tight] (2 ms).")
    assert lines[1].startswith(f"{POINT_QUERY}: fastest PINN toy-pinn [default] 0.01 ms")
    assert "classical wins: numba-rk [tight] 0.02 ms" not in lines[1] and "the PINN wins, 2x faster" in lines[1]
    assert "cheaper below t1 = 5 s" in lines[2]
    markdown = write_report(_rows(), tmp_path, {"threads": 2}, plots=True)
    assert f"### {LADDER_HEADING}" in markdown and "Who wins each query" in markdown
    assert (tmp_path / "crossover.png").exists()


def test_a_timing_measured_once_is_marked_and_a_points_batch_shows_its_cost_per_point(tmp_path):
    timed = {"suite": "latency", **NUMBA, "q25_s": 1.0, "q75_s": 1.0, "min_s": 1.0}
    rows = [{**timed, "kind": "grid", "query": GRID_QUERY, "median_s": 1.0, "repeats": 1},
            {**timed, "kind": "points batch", "query": "10000 single points, one call", "median_s": 0.02,
             "q25_s": 0.019, "q75_s": 0.021, "repeats": 9, "n_trajectories": 10000}]
    markdown = write_report(rows, tmp_path, {"threads": 2}, plots=False)
    assert "1e+03 (1 run)" in markdown and "±0%" not in markdown
    assert "20 ±5% (2 us/point)" in markdown


def test_crossover_takes_the_fastest_compiled_option_at_matched_accuracy_from_the_sweep_too():
    """A point of numba's tolerance sweep (error 1e-6 <= the PINN's 1e-5) is cheaper than its tight
    config (0.8 against 2 us per s of t1): the crossover uses it, at t1 = 12.5 s (the PINN: 10 us)."""
    sweep = {"suite": "work_precision", **NUMBA, "config": "default", "setting": "rtol=1e-05, atol=1e-08",
             "rtol": 1e-5, "atol": 1e-8, "rel_l2_delta": 1e-6, "median_s": 1e-3, "point_median_s": 5e-6,
             **{f"point_t1={t:g}_median_s": 0.8e-6 * t for t in T1}}
    x = crossover(suite_frames([*_rows(), sweep]))
    assert x["classical"] == "numba-rk [default, rtol=1e-05, atol=1e-08]"
    assert x["how"] == "crossover" and x["t1_cross_s"] == pytest.approx(12.5)


def test_verdicts_of_a_case_without_an_infinite_bus_compare_at_the_coi_accuracy():
    """Absolute angles drift together: their error is smaller than that of the swings. A PINN and
    its classical rivals are judged by one measure, the COI-relative one when the rows hold it."""
    import pandas as pd

    from harness.report.ladder import GRID_QUERY, ladder, verdict_rows
    from harness.suites.accuracy import COI_DELTA

    base = {"case": "wscc9", "config": "default", "variant": "", "status": "ok"}
    pinn = {**base, "solver": "toy-pinn", "seed": 0, "trains": True}
    ode = {**base, "solver": "ode", "seed": -1, "trains": False}
    acc = pd.DataFrame([
        {**pinn, "quantity": "delta", "against": "reference", "rel_l2": 1e-5},
        {**pinn, "quantity": COI_DELTA, "against": "reference", "rel_l2": 2e-5},
        {**ode, "quantity": "delta", "against": "reference", "rel_l2": 1e-6},
        {**ode, "quantity": COI_DELTA, "against": "reference", "rel_l2": 1.5e-5},
    ])
    assert set(verdict_rows(acc)["quantity"]) == {COI_DELTA}
    assert set(verdict_rows(acc[acc["quantity"] == "delta"])["quantity"]) == {"delta"}  # the SMIB
    lat = pd.DataFrame([{**r, "query": GRID_QUERY, "kind": "grid", "median_s": s}
                        for r, s in ((pinn, 0.002), (ode, 0.004))])
    (row,) = ladder({"accuracy": acc, "latency": lat}, GRID_QUERY).to_dict("records")
    assert row["pinn_rel_l2"] == 2e-5  # not the absolute 1e-5
    assert any(row[c] == 0.004 for c in row if c.endswith(": s"))  # ode's COI 1.5e-5 <= 2e-5: a rival


def test_the_units_own_seed_costs_what_its_fit_or_the_model_caches_load_reported():
    from types import SimpleNamespace
    from typing import ClassVar

    from harness.model_cache import fit_or_load
    from harness.suites._seeds import seed_models
    from solvers.null import NullSolver
    from systems.cases import CASES

    class Seeded(NullSolver):
        OPTIONS: ClassVar[dict] = {"seed": 0}

    settings = SimpleNamespace(cache_dir=None, retrain=False, verdict_seeds=(0, 1))
    unit = Seeded(CASES["wscc9"])
    report = fit_or_load(unit, settings)
    models = seed_models(unit, settings)
    assert models[0] == (unit, report.seconds, report.iterations) and report.seconds > 0
    assert models[1][0] is not unit and models[1][0].options["seed"] == 1 and models[1][1] > 0
    assert math.isnan(seed_models(Seeded(CASES["wscc9"]), settings)[0][1])  # not fitted: no cost known


def test_a_many_trajectory_query_is_estimated_from_one_trajectorys_call_before_it_is_made():
    import time
    from types import SimpleNamespace

    from harness.suites._queries import Query
    from harness.suites.verdict import probe_s

    calls = []

    class Slow:  # 10 ms a trajectory
        def solve(self, t, P1):
            calls.append(np.size(P1))
            time.sleep(0.01 * np.size(P1))

        def solve_points(self, t, P1):
            raise AssertionError("a batch of points is not probed")

    settings = SimpleNamespace(max_call_s=1.0, max_query_s=0.5)
    t = np.linspace(0.0, 1.0, 5)
    grid = Query("grid", "grid 100x5", t, np.linspace(0.1, 0.2, 100))
    assert 1.0 <= probe_s(Slow(), grid, settings) < 2.0  # 100 trajectories of 10 ms: over 0.5 s
    assert set(calls) == {1}  # only its first trajectory was called
    assert probe_s(Slow(), Query("trajectories", "1", t, grid.P1[:1]), settings) is None
    assert probe_s(Slow(), Query("points batch", "p", t, t), settings) is None
