"""The report from synthetic rows (no measurement): matched speed-ups, the verdicts, the paper's
table, the wall time of the units; two reports of the same rows are the same bytes."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

from harness.report.files import write_report


def test_time_at_accuracy_interpolates_on_the_pareto_front():
    from harness.report.speedups import break_even, pareto_front, time_at_accuracy

    errors = np.array([1e-3, 1e-5, 1e-7, 1e-6])
    seconds = np.array([0.01, 0.1, 1.0, 2.0])  # the last point is dominated by 1e-7 in 1.0 s
    e, t = pareto_front(errors, seconds)
    np.testing.assert_array_equal(e, [1e-7, 1e-5, 1e-3])
    np.testing.assert_array_equal(t, [1.0, 0.1, 0.01])
    assert time_at_accuracy(errors, seconds, 1e-4) == (pytest.approx(np.sqrt(0.1 * 0.01)), "interpolated")
    assert time_at_accuracy(errors, seconds, 1e-2) == (0.01, "at most")
    assert np.isnan(time_at_accuracy(errors, seconds, 1e-9)[0])
    assert break_even(10.0, 0.5, 0.1) == pytest.approx(25.0)
    assert break_even(10.0, 0.1, 0.5) == float("inf")


def _report_rows() -> list[dict]:
    """Synthetic rows of a trained adapter and a classical one on the SMIB: fit, accuracy, latency
    and work-precision."""
    base = {"case": "smib-inference", "variant": "", "threads": 2, "status": "ok"}
    pinn = {**base, "solver": "toy-pinn", "config": "default", "seed": 0, "trains": True}
    ode = {**base, "solver": "scipy-odeint", "config": "default", "seed": -1, "trains": False}
    return [
        {"suite": "fit", **pinn, "fit_s": 50.0, "iterations": 100, "loss": 1e-6, "message": ""},
        {"suite": "fit", **ode, "fit_s": 1e-5, "iterations": 0, "loss": np.nan, "message": ""},
        {"suite": "accuracy", **pinn, "quantity": "delta", "against": "reference", "rel_l2": 1e-3, "max_abs": 1e-3,
         "worst_trajectory_rel_l2": 2e-3},
        {"suite": "accuracy", **ode, "quantity": "delta", "against": "reference", "rel_l2": 1e-4, "max_abs": 1e-4,
         "worst_trajectory_rel_l2": 2e-4},
        {"suite": "latency", **pinn, "kind": "grid", "query": "grid 100x201", "median_s": 0.002, "q25_s": 0.002,
         "q75_s": 0.002, "min_s": 0.002, "repeats": 5},
        {"suite": "latency", **ode, "kind": "grid", "query": "grid 100x201", "median_s": 0.004, "q25_s": 0.004,
         "q75_s": 0.004, "min_s": 0.004, "repeats": 5},
        {"suite": "work_precision", **pinn, "rel_l2_delta": 1e-3, "median_s": 0.002},
        *({"suite": "work_precision", **ode, "rtol": r, "atol": r * 1e-3, "rel_l2_delta": e, "median_s": s}
          for r, e, s in ((1e-3, 1e-2, 0.001), (1e-6, 1e-5, 0.004))),
    ]


def test_report_compares_a_trained_adapter_with_the_classical_ones(tmp_path):
    """Synthetic rows (no measurement): the report's verdicts follow the numbers."""
    rows = _report_rows()
    (tmp_path / "figure3-wscc9.png").write_bytes(b"a plot of an earlier run's case")
    (tmp_path / "notes.png").write_bytes(b"not a plot of ours")
    markdown = write_report(rows, tmp_path, {"threads": 2}, plots=True)
    assert not (tmp_path / "figure3-wscc9.png").exists() and (tmp_path / "notes.png").exists()
    # PINN query 2 ms vs 4 ms classical at least as accurate: N* = 50 / (0.004 - 0.002) = 25,000
    assert "25,000" in markdown
    # on the work-precision curve the classical time at 1e-3 is 4 ms * 4^(-2/3) = 1.59 ms: 0.794x
    assert "0.794x" in markdown
    assert "toy-pinn default" in markdown and "scipy-odeint default" in markdown
    assert (tmp_path / "work_precision.png").exists() and (tmp_path / "tables.tex").exists()
    assert "![work_precision](work_precision.png)" in (tmp_path / "README.md").read_text()


def test_two_reports_of_the_same_rows_are_the_same_bytes(tmp_path):
    """PDFs included: they carry no creation date (PDF dates have whole seconds: the reports are
    written more than a second apart)."""
    def report(folder):
        write_report(_report_rows(), folder, {"threads": 2}, plots=True)
        return {p.name: p.read_bytes() for p in folder.iterdir()}

    first = report(tmp_path / "a")
    time.sleep(1.1)
    assert {"work_precision.pdf", "work_precision.png", "tables.md"} <= set(first)
    assert report(tmp_path / "b") == first


@pytest.mark.parametrize("classical_s,verdict", [
    (0.004, "2x faster than best Python-driven (scipy-odeint [default])"),
    (0.001, "2x slower than best Python-driven (scipy-odeint [default])"),
])
def test_paper_table_says_who_wins_at_matched_accuracy(classical_s, verdict):
    from harness.report.frames import suite_frames
    from harness.report.paper import paper_table

    base = {"case": "smib-inference", "variant": "", "threads": 2, "status": "ok"}
    pinn = {**base, "solver": "toy-pinn", "config": "default", "seed": 0, "trains": True}
    ode = {**base, "solver": "scipy-odeint", "config": "default", "seed": -1, "trains": False}
    rows = [
        {"suite": "accuracy", **pinn, "quantity": "delta", "against": "reference", "rel_l2": 1e-3},
        {"suite": "accuracy", **ode, "quantity": "delta", "against": "reference", "rel_l2": 1e-4},
        {"suite": "latency", **pinn, "kind": "grid", "query": "grid 100x201", "median_s": 0.002},
        {"suite": "latency", **ode, "kind": "grid", "query": "grid 100x201", "median_s": classical_s},
    ]
    table = paper_table(suite_frames(rows)).set_index("claim")
    shows = table.loc["100 trajectories, delta and omega on 100 x 201, warm", "what it shows"]
    assert shows.startswith("at matched accuracy (seed 0): toy-pinn [default] (0.002 s at rel. L2 0.001)")
    assert verdict in shows
    assert "literature baseline: none as accurate" in shows and "best compiled: none as accurate" in shows


def test_fastest_classical_includes_the_tolerance_sweep():
    """The rival of a PINN is the fastest classical option at least as accurate: a named config
    or any point of the work-precision sweep, for the grid and for the single-point query."""
    from harness.report.frames import suite_frames
    from harness.report.ladder import GRID_QUERY, POINT_QUERY, fastest_classical

    base = {"case": "smib-inference", "threads": 2, "status": "ok", "seed": -1}
    ode = {**base, "solver": "scipy-odeint", "config": "default", "variant": ""}
    rk = {**base, "solver": "scipy-rk45", "config": "tight", "variant": "batch=stacked"}
    rows = [
        {"suite": "accuracy", **ode, "quantity": "delta", "against": "reference", "rel_l2": 3e-4},
        {"suite": "accuracy", **rk, "quantity": "delta", "against": "reference", "rel_l2": 1e-11},
        *({"suite": "latency", **spec, "query": q, "median_s": s}
          for spec, q, s in ((ode, GRID_QUERY, 0.006), (ode, POINT_QUERY, 5e-4),
                             (rk, GRID_QUERY, 0.030), (rk, POINT_QUERY, 1e-2))),
        *({"suite": "work_precision", **rk, "rtol": r, "atol": r * 1e-3, "rel_l2_delta": e, "median_s": s,
           "point_median_s": p}
          for r, e, s, p in ((1e-4, 3e-5, 0.003, 2e-3), (1e-6, 1.5e-7, 0.006, 4e-3))),
    ]
    frames = suite_frames(rows)
    assert fastest_classical(frames, GRID_QUERY, 1e-3) == ("scipy-rk45 [tight, batch=stacked, rtol=0.0001, atol=1e-07]",
                                                           0.003)
    assert fastest_classical(frames, GRID_QUERY, 1e-6) == ("scipy-rk45 [tight, batch=stacked, rtol=1e-06, atol=1e-09]",
                                                           0.006)
    assert fastest_classical(frames, GRID_QUERY, 1e-9) == ("scipy-rk45 [tight, batch=stacked]", 0.030)
    assert fastest_classical(frames, POINT_QUERY, 1e-3) == ("scipy-odeint [default]", 5e-4)
    assert fastest_classical(frames, POINT_QUERY, 1e-4) == ("scipy-rk45 [tight, batch=stacked, rtol=0.0001, atol=1e-07]",
                                                            2e-3)
    assert fastest_classical(frames, POINT_QUERY, 1e-12) is None


def test_work_minutes_sums_each_unit_once_and_says_when_some_have_no_time():
    from harness.report.markdown import work_minutes

    unit = {"suite": "latency", "solver": "a", "config": "default", "variant": "", "seed": -1}
    rows = [{**unit, "case": "x", "work_s": 60.0}, {**unit, "case": "x", "work_s": 60.0},  # one unit, two rows
            {**unit, "case": "y", "work_s": 30.0}]
    assert work_minutes(rows) == "Wall time of its units of work, minutes: x 1.0, y 0.5; 1.5 in all.\n\n"
    older = {**unit, "solver": "b", "case": "x"}
    assert "(only 2 of its 3 units recorded it" in work_minutes([*rows, older])
    assert work_minutes([older]) == ""


def test_rows_of_runs_before_the_trains_column_are_read_by_their_seeds():
    """Runs before rows declared `trains` gave trained adapters seeds >= 0 and the others -1: their
    tables (results/full-identification) must read as they did."""
    from harness.report.frames import trained

    old = pd.DataFrame({"solver": ["jax-pinn", "numba-rk"], "seed": [0, -1]})
    assert trained(old).tolist() == [True, False]
    new = pd.DataFrame({"solver": ["jax-pinn", "numba-rk", "gone"], "seed": [0, -1, 0], "trains": [True, False, None]})
    assert trained(new).tolist() == [True, False, False]
