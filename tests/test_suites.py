"""The suites on cheap solvers: work-precision, latency's estimate of a query it skips, and
identification from the reference or the paper's data, with noise draws."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

import solvers
from harness.report.files import write_report
from harness.settings import DEFAULT, FULL, PAPER_PAIR, QUICK
from systems.cases import SMIB_INFERENCE


def test_work_precision_times_the_grid_and_the_papers_single_point():
    from harness.suites.work_precision import work_precision

    settings = replace(QUICK, wp_rtols=(1e-3, 1e-6), latency_budget_s=0.01, min_repeats=2)
    solver = solvers.make_solver("casadi-cvodes", SMIB_INFERENCE)
    rows = work_precision(solver, SMIB_INFERENCE, settings)
    assert [r["rtol"] for r in rows] == [1e-3, 1e-6]
    assert rows[1]["rel_l2_delta"] < rows[0]["rel_l2_delta"] < 1e-2
    for r in rows:
        assert r["point_median_s"] > 0 and r["median_s"] > 0
        assert r["point_repeats"] >= 2 and r["repeats"] >= 2


def test_work_precision_times_a_compiled_adapter_at_every_t1_once():
    from harness.suites.work_precision import T1_COLUMN, work_precision

    if solvers.SOLVERS.get("numba-rk") is None:
        pytest.skip("numba not installed")
    settings = replace(QUICK, wp_rtols=(1e-6,), latency_budget_s=0.01, min_repeats=2)
    (row,) = work_precision(solvers.make_solver("numba-rk", SMIB_INFERENCE), SMIB_INFERENCE, settings)
    times = {float(m["t1"]): row[c] for c in row if (m := T1_COLUMN.fullmatch(c))}
    assert sorted(times) == list(settings.t1_values_s)
    assert row["point_median_s"] > 0 and all(s > 0 for s in times.values())
    assert row["setting"] == "rtol=1e-06, atol=1e-09" and row["rel_l2_delta"] < 1e-5


def test_latency_estimates_a_query_from_the_last_measured_one_linearly_and_never_faster():
    from harness.suites.latency import extrapolated_s

    assert extrapolated_s("throughput", 1000, {}) is None
    assert extrapolated_s("throughput", 1000, {"throughput": [(10, 0.1), (100, 0.5)]}) == pytest.approx(5.0)
    assert extrapolated_s("throughput", 1000, {"throughput": [(10, 0.1), (100, 10.0)]}) == pytest.approx(100.0)
    # one call slowed by a busy machine (1 ms -> 0.1 s): 0.1 s x 100, not 0.1 s x 100^3
    assert extrapolated_s("throughput", 1000, {"throughput": [(1, 1e-3), (10, 0.1)]}) == pytest.approx(10.0)
    assert extrapolated_s("points batch", 100, {"single point": [(1, 0.01), (1, 0.02)]}) == pytest.approx(2.0)


def test_a_query_whose_answer_does_not_fit_in_memory_is_skipped_with_its_size(monkeypatch):
    """10,000 trajectories of 201 times of 1445 machines are 43 GiB of answer, over a third of 24
    GiB; of 260 machines 7.8 GiB, under it; the latency suite writes the skip as the query's row
    and asks the adapter nothing."""
    from types import SimpleNamespace

    from harness.suites import latency

    t, P1 = np.linspace(0.0, 20.0, 201), np.linspace(0.0, 1.0, 10_000)
    memory = 24 * 2**30
    status = latency.too_large(SimpleNamespace(n=1445), "throughput", t, P1, memory)
    assert status == "skipped: its answer, 43.3 GiB (delta and omega, float64), is over 0.33 of this machine's 24 GiB"
    assert latency.too_large(SimpleNamespace(n=260), "throughput", t, P1, memory) is None
    assert latency.too_large(SimpleNamespace(n=1445), "points batch", t, P1, memory) is None  # one time a point

    class Unasked:
        def solve(self, *_):
            raise AssertionError("a skipped query was asked")

        solve_points = solve

    monkeypatch.setattr(latency, "machine_memory_bytes", lambda: 1)
    rows = latency.latency(Unasked(), SMIB_INFERENCE, QUICK)
    assert rows and all(r["status"].startswith("skipped: its answer, ") for r in rows)


def test_identification_observations_from_the_reference_or_the_papers_data():
    from harness.suites.identification import observations
    from systems.cases import SMIB_IDENTIFICATION
    from systems.reference import SEED_DIR, load_seed_reference, reference

    tight = observations(SMIB_IDENTIFICATION, 50, seed=3)
    paper = observations(SMIB_IDENTIFICATION, 50, seed=3, data="paper ode45")
    # the same grid points from either source (MATLAB's 0:0.1:20 and linspace differ in rounding)
    np.testing.assert_allclose(paper.t, tight.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(paper.P1, tight.P1, rtol=0, atol=1e-12)
    t, P1, delta = load_seed_reference(SEED_DIR / "swingEquation_identification.mat")
    i, j = np.abs(P1 - paper.P1[0]).argmin(), np.abs(t - paper.t[0]).argmin()
    assert paper.delta[0] == delta[i, j]
    assert tight.delta[0] == pytest.approx(reference(SMIB_IDENTIFICATION, [tight.t[0]], [tight.P1[0]])[0][0, 0], abs=1e-10)
    assert 0 < np.max(np.abs(paper.delta - tight.delta)) < 2e-3  # ode45's own error
    with pytest.raises(ValueError, match="published no data"):
        observations(SMIB_IDENTIFICATION.with_params(0.3, 0.1), 10, data="paper ode45")
    with pytest.raises(ValueError, match="data must be"):
        observations(SMIB_IDENTIFICATION, 10, data="matlab")


@pytest.mark.parametrize("settings", [DEFAULT, FULL], ids=["default", "full"])
def test_default_and_full_runs_identify_from_the_papers_data(settings):
    """--full is a superset of make bench: both identify the paper's own case, also from its data."""
    from harness.suites.identification import _runs
    from systems.cases import IDENTIFICATION_PAIRS, SMIB_IDENTIFICATION

    assert settings.pairs[0] == PAPER_PAIR == (0.25, 0.15)
    assert (0, 0.0, "paper ode45", 0) in _runs(SMIB_IDENTIFICATION, settings)
    assert set(DEFAULT.pairs) <= set(FULL.pairs) == {PAPER_PAIR, *IDENTIFICATION_PAIRS}
    # and a multi-machine case at every noise level the SMIB has (make bench: noise-free only)
    from systems.cases import CASES

    levels = {noise for _, noise, _, _ in _runs(CASES["wscc9"], settings)}
    assert levels == ({0.0} if settings is DEFAULT else set(FULL.noise_levels))


@pytest.mark.slow
def test_identification_suite_adds_the_papers_data_for_its_own_pair(tmp_path):
    from harness.suites.identification import identification
    from systems.cases import SMIB_IDENTIFICATION

    settings = replace(QUICK, pairs=((0.25, 0.15), (0.1, 0.05)), noise_levels=(0.0, 0.01), n_u=60)
    fast = "numba-rk" if solvers.SOLVERS.get("numba-rk") is not None else "scipy-odeint"  # 0.07 s vs 0.5 s each
    solver = solvers.make_solver(fast, SMIB_IDENTIFICATION, "tight")
    rows = identification(solver, SMIB_IDENTIFICATION, settings)
    runs = [(r["pair"], r["noise"], r["data"]) for r in rows]
    assert runs == [(0, 0.0, "reference"), (0, 0.01, "reference"), (0, 0.0, "paper ode45"),
                    (1, 0.0, "reference"), (1, 0.01, "reference")]
    by_run = dict(zip(runs, rows))
    assert by_run[0, 0.0, "reference"]["m_rel_error"] < 1e-6
    # the paper's ode45 data carry ~1e-3 rad of error: that, not the method, limits the estimate
    assert 0 < by_run[0, 0.0, "paper ode45"]["m_rel_error"] < 2e-3
    base = {"suite": "identification", "case": "smib-identification", "solver": fast,
            "config": "tight", "variant": "", "seed": -1, "threads": 2, "status": "ok"}
    write_report([{**base, **row} for row in rows], tmp_path, {}, plots=False)
    table = pd.read_csv(tmp_path / "identification.csv")
    assert set(table["data"]) == {"reference", "paper ode45"}
    markdown = (tmp_path / "tables.md").read_text()
    assert "identification from the paper's ode45 data (m = 0.25, d = 0.15)" in markdown
    assert "mean error of m / d over 2 (m, d) pair(s)" in markdown


def test_noise_draws_repeat_each_noisy_identification_and_the_table_counts_coverage(tmp_path):
    """--noise-draws K: K draws of the noise at each level above 0 (draw 0 the samples of a run
    without draws), and the table's coverage column counts every machine's interval over them."""
    from harness.suites.identification import identification, pair_observations
    from systems.cases import SMIB_IDENTIFICATION

    settings = replace(QUICK, pairs=((0.25, 0.15),), noise_levels=(0.0, 0.01), n_u=60, noise_draws=4)
    fast = "numba-rk" if solvers.SOLVERS.get("numba-rk") is not None else "scipy-odeint"
    rows = identification(solvers.make_solver(fast, SMIB_IDENTIFICATION, "tight"), SMIB_IDENTIFICATION, settings)
    assert [(r["noise"], r["data"], r["draw"]) for r in rows] == [
        (0.0, "reference", 0), *[(0.01, "reference", k) for k in range(4)], (0.0, "paper ode45", 0)]
    first = pair_observations(SMIB_IDENTIFICATION, replace(settings, noise_draws=1), 0, 0.01)
    np.testing.assert_array_equal(pair_observations(SMIB_IDENTIFICATION, settings, 0, 0.01, draw=0).delta, first.delta)
    assert len({r["m_est"] for r in rows if r["noise"] > 0}) == 4  # four different draws
    base = {"suite": "identification", "case": "smib-identification", "solver": fast,
            "config": "tight", "variant": "", "seed": -1, "threads": 2, "status": "ok"}
    write_report([{**base, **row} for row in rows], tmp_path, {}, plots=False)
    markdown = (tmp_path / "tables.md").read_text()
    inside = sum(r["m_ci95_low"] <= r["m_true"] <= r["m_ci95_high"] for r in rows if r["noise"] > 0)
    assert "m 95% CI coverage" in markdown and f"{inside}/4 ({100 * inside / 4:.0f} %)" in markdown
