"""The scaling suite on two tiny sizes: rows, limits, the report, and the same rows on Dask."""

from __future__ import annotations

import math
import os
import socket

import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.report.frames import suite_frames
from harness.report.scaling import break_even_by_n, exponents, log_log_slope, scaling_frame, scaling_table
from harness.store import RowStore

TINY = ["--suite", "scaling", "--case", "smib-inference", "wscc9", "--solver", "scipy-odeint", "--config", "default",
        "--quick", "--progress", "off"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """The scaling suite on N = 1 and N = 3, each unit in a process of its own (the default)."""
    out = tmp_path_factory.mktemp("scaling")
    assert main(["run", *TINY, "--out", str(out)]) == 0
    return out, RowStore(out).rows()


@pytest.mark.slow
def test_scaling_rows_on_two_sizes_each_unit_in_its_own_process(tiny_run):
    out, rows = tiny_run
    scaling = [r for r in rows if r["suite"] == "scaling"]
    assert sorted(r["case"] for r in scaling) == ["smib-inference", "wscc9"]
    for r in scaling:
        assert r["status"] == "ok" and r["machines"] == (1 if r["case"] == "smib-inference" else 3)
        assert r["quantity"] == ("delta" if r["case"] == "smib-inference" else "delta - delta_COI")
        assert 0 < r["rel_l2"] < 5e-2  # ode45's tolerances against the 1e-12 reference
        assert r["grid_median_s"] > 0 and r["point_median_s"] > 0 and r["reference_s"] > 0
        assert r["n_trajectories"] == 4 and r["n_times"] == 101  # the scaling grid
        assert 20 < r["peak_rss_mib"] < 8000  # measured in the unit's own process
        assert 0 < r["steps"] <= r["rhs_evals"]  # LSODA's counters (`step_count`)
        assert r["step_s"] == pytest.approx(r["point_median_s"] / r["steps"])
    workers = {r["worker"] for r in rows}
    assert len(workers) == 2 and f"{socket.gethostname()}:{os.getpid()}" not in workers  # one process per unit
    fits = [r for r in rows if r["suite"] == "fit"]
    assert len(fits) == 2 and all(r["peak_rss_mib"] > 0 for r in fits)
    md = (out / "tables.md").read_text()
    assert "## Scaling" in md and "Fitted exponents" in md and "Case smib-inference" not in md
    assert (out / "scaling_cost.png").exists() and (out / "scaling_accuracy.png").exists()


def test_the_reference_of_a_case_is_integrated_once_and_stored(tmp_path):
    from harness.suites.scaling import cached_reference
    from systems.cases import CASES

    case = CASES["wscc9"]
    t, P1 = np.linspace(0.0, 1.0, 5), np.array([case.p1_min])
    delta, _, seconds = cached_reference(case, t, P1, tmp_path)
    again = cached_reference(case, t, P1, tmp_path)
    assert len(list(tmp_path.glob("wscc9-*.npz"))) == 1
    np.testing.assert_array_equal(again[0], delta)
    assert again[2] == seconds  # the stored cost of the integration, not a new one
    other = cached_reference(case.with_params(np.array(case.m) * 2, case.d), t, P1, tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 2 and not np.array_equal(other[0], delta)


def test_a_unit_past_its_time_limit_is_a_row_that_says_so(tmp_path):
    out = tmp_path / "out"
    argv = ["run", "--suite", "scaling", "--case", "wscc9", "--solver", "scipy-odeint", "--config", "default",
            "--quick", "--progress", "off", "--unit-seconds", "0.2", "--out", str(out)]
    assert main(argv) == 0
    rows = RowStore(out).rows()
    assert {r["suite"] for r in rows} == {"fit", "scaling"}
    assert all(r["status"] == "skipped: out of time: still running after 0.2 s (killed)" for r in rows)
    assert "Units that did not run to the end" in (out / "tables.md").read_text()


def test_bad_limits_are_one_line_errors(tmp_path):
    with pytest.raises(SystemExit, match="--unit-seconds and --unit-memory must be > 0"):
        main(["run", "--suite", "scaling", "--unit-memory", "0", "--out", str(tmp_path / "out")])
    with pytest.raises(SystemExit, match="--suite scaling runs alone"):
        main(["run", "--suite", "scaling", "accuracy", "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()


def test_scaling_settings_budget_pinns_by_iterations():
    from harness.settings import DEFAULT, SCALING_PINN_OPTIONS

    settings = DEFAULT.for_scaling()
    assert settings.unit_limits == DEFAULT.scaling_unit_limits and settings.case_pinn_options == {}
    assert settings.pinn_options == SCALING_PINN_OPTIONS and SCALING_PINN_OPTIONS["max_seconds"] is None


@pytest.mark.slow
def test_dask_gives_the_same_rows(tiny_run, tmp_path):
    pytest.importorskip("distributed")
    _, rows = tiny_run
    out = tmp_path / "dask"
    assert main(["run", *TINY, "--dask-local", "--out", str(out)]) == 0
    key = lambda r: (r["suite"], r["case"], r["solver"], r["status"], r.get("machines"), r.get("rel_l2"))
    assert sorted(map(key, RowStore(out).rows())) == sorted(map(key, rows))  # only timings differ


def _frame(rows: list[dict]) -> pd.DataFrame:
    base = {"config": "default", "variant": "", "status": "ok"}
    full = []
    for r in rows:
        common = {**base, "case": f"n{r['N']}", "solver": r["solver"], "seed": r.get("seed", -1),
                  "trains": "seed" in r}  # as the adapter declares it: the rows with a seed train
        full.append({**common, "suite": "fit", "fit_s": r["fit_s"]})
        full.append({**common, "suite": "scaling", "machines": r["N"], "grid_median_s": r["grid_s"],
                     "point_median_s": r["grid_s"] / 10, "rel_l2": r["rel_l2"], "n_trajectories": 4})
    return scaling_frame(suite_frames(full))


def test_exponents_recover_a_power_law():
    n = np.array([3.0, 10.0, 100.0, 1000.0])
    assert log_log_slope(n, 2e-3 * n**1.7)[0] == pytest.approx(1.7)
    assert math.isnan(log_log_slope(n[:2], n[:2])[0])  # two points: no fit
    frame = _frame([{"N": int(k), "solver": "ode", "fit_s": 0.0, "grid_s": 1e-3 * k**2, "rel_l2": 1e-6} for k in n])
    (row,) = exponents(frame).to_dict("records")
    assert row["grid query exponent"] == "2.00 (4 N)" and row["N range"] == "3-1000"


def test_the_slope_over_the_largest_n_shows_the_growth_the_global_fit_hides():
    """Overhead at small N, N^2 at scale: the global fit reads ~1, the last three sizes 2."""
    n = np.array([3, 10, 39, 54, 118, 510, 1445])
    frame = _frame([{"N": int(k), "solver": "ode", "fit_s": 0.0, "grid_s": 1e-3 + 1e-7 * k**2, "rel_l2": 1e-6}
                    for k in n])
    (row,) = exponents(frame).to_dict("records")
    large = row["grid query exponent, largest 3 N"]
    assert large.endswith("(N 118-1445)") and 1.7 < float(large.split()[0]) < 2.0
    assert float(row["grid query exponent"].split()[0]) < 1.0


def test_cost_per_simulated_second_of_one_trajectory():
    frame = _frame([{"N": 3, "solver": "ode", "fit_s": 0.0, "grid_s": 0.8, "rel_l2": 1e-6}])
    assert frame["per_sim_s"].iloc[0] == pytest.approx(0.8 / 4 / 10.0)  # 4 trajectories, 10 s (no horizon_s)
    rows = suite_frames([{"suite": "scaling", "case": "n3", "solver": "ode", "config": "default", "variant": "",
                          "seed": -1, "status": "ok", "machines": 3, "grid_median_s": 0.8,
                          "point_median_s": 0.1, "rel_l2": 1e-6, "n_trajectories": 4, "horizon_s": 20.0}])
    assert scaling_frame(rows)["per_sim_s"].iloc[0] == pytest.approx(0.8 / 4 / 20.0)
    assert "s per simulated s (one trajectory)" in scaling_table(frame)


def test_break_even_against_the_fastest_classical_at_least_as_accurate():
    frame = _frame([
        {"N": 10, "solver": "pinn", "seed": 0, "fit_s": 100.0, "grid_s": 0.4, "rel_l2": 1e-5},
        {"N": 10, "solver": "slow", "fit_s": 0.0, "grid_s": 8.0, "rel_l2": 1e-9},
        {"N": 10, "solver": "fast", "fit_s": 0.0, "grid_s": 4.4, "rel_l2": 1e-6},
        {"N": 10, "solver": "loose", "fit_s": 0.0, "grid_s": 0.04, "rel_l2": 1e-3},  # not as accurate
    ])
    (row,) = break_even_by_n(frame).to_dict("records")
    assert row["fastest classical at least as accurate"].startswith("fast [default]")
    assert row["break-even trajectories"] == "100"  # 100 s / (1.1 - 0.1 s per trajectory)


def test_no_break_even_for_a_pinn_that_has_not_learnt_the_trajectories():
    frame = _frame([
        {"N": 54, "solver": "pinn", "seed": 0, "fit_s": 50.0, "grid_s": 0.001, "rel_l2": 2.0},
        {"N": 54, "solver": "ode", "fit_s": 0.0, "grid_s": 0.01, "rel_l2": 1e-3},
    ])
    (row,) = break_even_by_n(frame).to_dict("records")
    assert row["break-even trajectories"].startswith("not converged")
