"""The runner, the row store, the report and the CLI, on cheap solvers."""

from __future__ import annotations

import json
import time
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

import solvers
from harness.cli import main
from harness.measure.timing import time_call
from harness.report.files import write_report
from harness.run.runner import run_suites
from harness.settings import DEFAULT, FULL, PAPER_PAIR, QUICK, SolverSpec, default_specs
from harness.store import RowStore
from solvers.atomic import atomic_write
from solvers.base import AbstractSolver, SolveError
from systems.cases import SMIB_INFERENCE


class Exploding(AbstractSolver):
    """Fits, then fails every query: the run must record it and go on."""

    name = "exploding"

    def _fit(self):
        return None

    def _solve(self, t, P1):
        raise SolveError(f"exploding: failed at P1={P1[0]:g}")

    def _identify(self, obs):
        raise SolveError("exploding: cannot identify")


@pytest.fixture
def with_exploding(monkeypatch):
    monkeypatch.setitem(solvers.SOLVERS, "exploding", Exploding)
    monkeypatch.setitem(solvers.SOLVERS, "not-installed", None)
    monkeypatch.setitem(solvers.UNAVAILABLE, "not-installed", "skipped: nothing not installed")


def test_failures_and_missing_dependencies_become_rows_and_the_run_goes_on(tmp_path, with_exploding):
    store = RowStore(tmp_path)
    specs = [SolverSpec("exploding"), SolverSpec("not-installed"), SolverSpec("casadi-cvodes")]
    settings = replace(QUICK, cache_dir=None, throughput_sizes=(1,), t1_values_s=(10.0,), points_batch=50,
                       points_distinct_p1=5)
    run_suites(specs, [SMIB_INFERENCE], ["accuracy", "latency"], settings, store, progress=False)
    df = store.frame()
    status = df.groupby(["solver", "suite"])["status"].first()
    assert status["exploding", "fit"] == "ok"
    assert status["exploding", "accuracy"].startswith("failed: SolveError: exploding: failed at P1=0.08")
    assert status["not-installed", "latency"] == "skipped: nothing not installed"
    ok = df[(df.solver == "casadi-cvodes") & (df.status == "ok")]
    assert set(ok.suite) == {"fit", "accuracy", "latency"}
    accuracy = ok[ok.suite == "accuracy"].set_index(["quantity", "against"])
    assert accuracy.loc[("delta", "reference"), "rel_l2"] < 1e-2
    assert accuracy.loc[("delta", "paper ode45 data"), "max_abs"] < 1e-2
    latency = ok[ok.suite == "latency"]
    assert set(latency["query"]) == {"grid 100x201", "1 trajectories x 201 times", "single point t1=10 s",
                                     "50 single points, one call", "50 single points over 5 P1, one call"}
    assert dict(zip(latency["query"], latency["distinct_p1"]))["50 single points over 5 P1, one call"] == 5
    assert (latency["median_s"] > 0).all()
    # every row of a unit of work carries that unit's wall time, at least what its queries took
    timed = ok.groupby("suite")["work_s"]
    assert (timed.nunique() == 1).all() and timed.first()["latency"] > latency["median_s"].sum()

    markdown = write_report(store.rows(), tmp_path, {"threads": 2})
    assert "casadi-cvodes default" in markdown and "Skipped or failed" in markdown
    assert "Wall time of its units of work, minutes: smib-inference " in markdown
    assert "skipped: nothing not installed" in markdown
    assert pd.read_csv(tmp_path / "accuracy.csv")["rel_l2"].notna().any()


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


def test_atomic_write_replaces_whole_files(tmp_path):
    target = tmp_path / "a" / "table.md"
    atomic_write(target, "one")
    atomic_write(target, "two")
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["table.md"]


def test_default_specs_cover_configs_and_batch_modes():
    labels = [spec.label for spec in default_specs(["scipy-rk45"])]
    assert labels == ["scipy-rk45[default]", "scipy-rk45[default,batch=stacked]",
                      "scipy-rk45[tight]", "scipy-rk45[tight,batch=stacked]"]
    with pytest.raises(ValueError, match="unknown solver"):
        default_specs(["nope"])


def test_omitted_configs_run_only_when_named():
    from solvers.base import IDENTIFIES_NETWORKS

    omitting = replace(DEFAULT, omit_marks=(IDENTIFIES_NETWORKS,))  # scipy-rk45's tight is marked so
    assert [s.config for s in default_specs(["scipy-rk45"], None, omitting)] == ["default", "default"]
    assert {s.config for s in default_specs(["scipy-rk45"], ["tight"], omitting)} == {"tight"}


def test_python_driven_adapters_sweep_fewer_tolerances_on_networks_only():
    from systems.cases import CASES

    settings = replace(DEFAULT, wp_rtols=(1e-3, 1e-4, 1e-5), network_wp_rtols=(1e-3,))
    assert settings.sweep_rtols(False, CASES["wscc9"]) == (1e-3,)
    assert settings.sweep_rtols(True, CASES["wscc9"]) == settings.wp_rtols
    assert settings.sweep_rtols(False, SMIB_INFERENCE) == settings.wp_rtols
    assert replace(settings, network_wp_rtols=None).sweep_rtols(False, CASES["wscc9"]) == settings.wp_rtols


def test_latency_estimates_a_query_from_the_last_measured_one_linearly_and_never_faster():
    from harness.suites.latency import _estimate

    assert _estimate("throughput", 1000, {}) is None
    assert _estimate("throughput", 1000, {"throughput": [(10, 0.1), (100, 0.5)]}) == pytest.approx(5.0)
    assert _estimate("throughput", 1000, {"throughput": [(10, 0.1), (100, 10.0)]}) == pytest.approx(100.0)
    # one call slowed by a busy machine (1 ms -> 0.1 s): 0.1 s x 100, not 0.1 s x 100^3
    assert _estimate("throughput", 1000, {"throughput": [(1, 1e-3), (10, 0.1)]}) == pytest.approx(10.0)
    assert _estimate("points batch", 100, {"single point": [(1, 0.01), (1, 0.02)]}) == pytest.approx(2.0)


def test_time_call_counts_repeats():
    calls = []
    timing = time_call(lambda: calls.append(1), warmup=2, min_repeats=4, budget_s=0.0)
    assert timing.repeats == 4 and len(calls) == 6
    assert 0 <= timing.min_s <= timing.median_s


def test_a_slow_call_is_timed_once_but_a_slow_cold_start_is_not():
    calls = []

    def cold_then_fast(cold_s: float = 0.05):
        calls.append(1)
        if len(calls) == 1:
            time.sleep(cold_s)

    assert time_call(cold_then_fast, min_repeats=4, budget_s=0.0, slow_s=0.02).repeats == 4
    assert time_call(lambda: time.sleep(0.03), min_repeats=4, budget_s=0.0, slow_s=0.02).repeats == 1


def test_cli_run_and_report(tmp_path, capsys):
    out = tmp_path / "results"
    readme = tmp_path / "README.md"
    readme.write_text("intro\n<!-- swingbench:tables:start -->\nold\n<!-- swingbench:tables:end -->\nend\n")
    assert main(["run", "--quick", "--case", "smib-inference", "--progress", "off", "--solver", "casadi-cvodes", "--config", "default",
                 "--suite", "accuracy", "--out", str(out), "--update-readme", str(readme)]) == 0
    printed = capsys.readouterr().out
    assert "casadi-cvodes default" in printed
    text = readme.read_text()
    assert text.startswith("intro\n") and text.endswith("end\n") and "old" not in text
    assert "[smib-inference](docs/results/smib-inference.md)" in text  # the verdicts link the case's page
    page = (tmp_path / "docs" / "results" / "smib-inference.md").read_text()
    assert "casadi-cvodes default" in page and "![" not in page  # an accuracy run draws no figure
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["threads"] == 2 and "version_numpy" in meta
    (out / "tables.md").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "tables.md").exists()


@pytest.mark.parametrize("argv,message", [
    (["run", "--solver", "rk4"], "unknown solver"),
    (["run", "--suite", "speed"], "unknown suite"),
    (["run", "--case", "ieee300"], "unknown case"),
])
def test_cli_rejects_unknown_names(argv, message, tmp_path):
    with pytest.raises(SystemExit, match=message):
        main([*argv, "--out", str(tmp_path)])


def test_cli_help(capsys):
    with pytest.raises(SystemExit) as info:
        main(["run", "--help"])
    assert info.value.code == 0
    assert "--quick" in capsys.readouterr().out


def test_top_level_help_says_what_is_measured_and_names_every_command(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert info.value.code == 0
    assert "single-machine infinite-bus" in text and "1445 machines" in text and "critical clearing time" in text
    assert all(f" {command} " in text for command in ("run", "report", "sweep", "compare", "list"))


def test_cli_version_is_the_one_in_pyproject(capsys):
    import tomllib
    from pathlib import Path

    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out == f"swingbench {pyproject['project']['version']}\n"


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


def test_git_commit_is_dirty_only_for_changes_the_run_did_not_write(tmp_path):
    import subprocess

    from harness.provenance import git_commit

    def git(*args):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=tmp_path, check=True,
                       capture_output=True)

    (tmp_path / "results").mkdir()
    for name in ("code.py", "README.md", "results/tables.md"):
        (tmp_path / name).write_text("one\n")
    git("init", "-q")
    git("add", ".")
    git("commit", "-q", "-m", "one")
    outputs = [tmp_path / "results", tmp_path / "README.md"]
    assert not git_commit(tmp_path, outputs).endswith("+dirty")
    (tmp_path / "results" / "tables.md").write_text("two\n")
    (tmp_path / "README.md").write_text("two\n")
    assert not git_commit(tmp_path, outputs).endswith("+dirty")
    assert git_commit(tmp_path).endswith("+dirty")
    (tmp_path / "code.py").write_text("two\n")
    assert git_commit(tmp_path, outputs).endswith("+dirty")
    assert git_commit(tmp_path / "results", outputs).endswith("+dirty")  # from a subfolder too
    assert git_commit(tmp_path.parent / "no-such-checkout") == "unknown"


def test_model_cache_key_covers_training_and_ignores_how_a_model_is_queried():
    from harness.model_cache import TRAINING_LIBRARIES, cache_key
    from harness.versions import library_versions

    pytest.importorskip("jax")
    base = solvers.make_solver("jax-pinn", SMIB_INFERENCE)
    same = [solvers.make_solver("jax-pinn", SMIB_INFERENCE, **{key: value})
            for key, value in (("query", "numba"), ("threads", 1), ("progress", False))]
    assert {cache_key(s) for s in same} == {cache_key(base)}
    other = [solvers.make_solver("jax-pinn", SMIB_INFERENCE, seed=1),
             solvers.make_solver("jax-pinn", SMIB_INFERENCE, max_iterations=10),
             solvers.make_solver("jax-pinn", SMIB_INFERENCE.with_params(0.3, 0.1))]
    assert len({cache_key(s) for s in other} | {cache_key(base)}) == 4
    assert set(library_versions(TRAINING_LIBRARIES)) >= {"numpy", "scipy", "jax"}


def test_pinn_training_is_bounded_by_iterations_unless_a_time_budget_is_given():
    from solvers.pinn.config import PinnConfig

    config = PinnConfig()
    assert config.max_seconds is None and config.deadline(5.0) == float("inf")
    assert PinnConfig(id_max_seconds=2.0).deadline(5.0, identification=True) == 7.0
    with pytest.raises(ValueError, match="max_seconds"):
        PinnConfig(max_seconds=0.0)


def test_query_path_variants_skip_identification_which_does_not_depend_on_them():
    from harness.run.plan import plan
    from harness.settings import default_specs
    from harness.suites import DEFAULT_SUITES, SUITES
    from systems.cases import SMIB_INFERENCE as forward

    specs = default_specs(["jax-pinn"], ["default"], replace(DEFAULT, seeds=(0,)))
    units = {(unit.case.name, unit.spec.variant): list(unit.suites)
             for unit in plan(specs, [forward], [SUITES[name] for name in DEFAULT_SUITES]).units}
    assert units[("smib-identification", "")] == ["identification"]
    assert ("smib-identification", "query=numba") not in units
    # cct is listed for the step case too: its unit records it as skipped (fault cases only)
    assert units[("smib-inference", "query=numba")] == ["accuracy", "cct", "latency", "work_precision"]
    assert units[("smib-inference", "")] == ["accuracy", "cct", "latency", "verdict", "work_precision"]
    # an adapter's own query options (scipy RK45's batch mode) likewise; diffrax's batch changes
    # its identification's error control, so its variant identifies
    specs = [SolverSpec("scipy-rk45", options=(("batch", "stacked"),)), SolverSpec("diffrax", options=(("batch", "vmap"),))]
    units = {(unit.case.name, unit.spec.solver): list(unit.suites)
             for unit in plan(specs, [forward], [SUITES[name] for name in DEFAULT_SUITES]).units}
    assert ("smib-identification", "scipy-rk45") not in units
    assert units[("smib-identification", "diffrax")] == ["identification"]


def test_a_case_s_training_budget_applies_to_its_pinn_units_only():
    from harness.run.plan import plan
    from harness.settings import default_specs
    from harness.suites import SUITES
    from systems.cases import CASES
    from systems.cases import SMIB_INFERENCE as forward

    settings = replace(DEFAULT, seeds=(0,), case_pinn_options={"wscc9": {"max_iterations": 90, "max_seconds": None}})
    specs = default_specs(["jax-pinn", "numba-rk"], ["marching", "default"], settings)
    units = plan(specs, [forward, CASES["wscc9"]], list(SUITES.values()), settings).units
    budget = {(u.case.name, u.spec.solver, u.spec.config): dict(u.spec.options).get("max_iterations") for u in units}
    assert budget[("wscc9", "jax-pinn", "marching")] == 90
    assert budget[("smib-inference", "jax-pinn", "default")] is None  # no budget named for the SMIB
    assert budget[("wscc9", "numba-rk", "default")] is None  # classical adapters do not train
    assert {u.spec.variant for u in units if u.case.name == "wscc9" and u.spec.solver == "jax-pinn"} == {
        "max_iterations=90,max_seconds=None", "max_iterations=90,max_seconds=None,query=numba"}


def test_make_bench_trains_every_network_pinn_for_iterations_not_seconds():
    from harness.run.plan import plan
    from harness.settings import default_specs
    from harness.suites import SUITES
    from systems.cases import CASES, NETWORK_CASES

    specs = default_specs(["jax-pinn", "torch-pinn"], settings=DEFAULT)
    units = plan(specs, [CASES[name] for name in NETWORK_CASES], list(SUITES.values()), DEFAULT).units
    assert units
    for unit in units:
        options = unit.spec.make(unit.case).options  # the config's own max_seconds included
        assert options["max_seconds"] is None and options["id_max_seconds"] is None, unit.label
        assert options["max_iterations"] == DEFAULT.case_pinn_options[unit.case.name]["max_iterations"]


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


def test_option_overrides_reach_the_adapters_that_have_them_and_are_validated():
    from harness.settings import parse_option, with_options

    assert parse_option("max_iterations=100") == ("max_iterations", 100)
    assert parse_option("optimizer=lbfgs") == ("optimizer", "lbfgs")
    assert parse_option("max_seconds=null") == ("max_seconds", None)
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_option("rtol")
    from harness.run.plan import plan
    from harness.run.runner import check_units
    from harness.suites import SUITES

    specs = default_specs(["scipy-rk45", "numba-rk"], ["default"])
    tuned = with_options(specs, {"batch": "stacked"})
    assert {s.variant for s in tuned if s.solver == "scipy-rk45"} == {"batch=stacked"}
    assert [s.variant for s in tuned if s.solver == "numba-rk"] == [s.variant for s in specs if s.solver == "numba-rk"]
    with pytest.raises(ValueError, match="none of the selected adapters"):
        with_options(specs, {"width": 3})
    units = plan(with_options(specs, {"batch": "sideways"}), [SMIB_INFERENCE], [SUITES["accuracy"]], QUICK).units
    with pytest.raises(ValueError, match=r"^scipy-rk45\[default,batch=sideways\] smib-inference: scipy-rk45: "
                                         "option batch must be one of"):
        check_units(units, QUICK)


@pytest.mark.parametrize(("argv", "message"), [
    (["--solver", "numba-rk", "--config", "rk4", "--option", "dt=15"],  # valid on the SMIB's 20 s, not on 10 s
     ("swingbench run: numba-rk[rk4,dt=15] wscc9: numba-rk: option dt must be <= t_final = 10.0 s, the horizon "
      "of case wscc9, got 15.0")),
    (["--solver", "torch-pinn", "--config", "default", "--option", "device=cuda"],
     "swingbench run: torch-pinn[default,device=cuda,"),
])
def test_cli_refuses_an_option_a_selected_case_or_this_machine_cannot_take_before_measuring(
        argv, message, tmp_path, capsys, monkeypatch):
    name = argv[1]
    if solvers.SOLVERS.get(name) is None:
        pytest.skip(f"{name} is not installed")
    if name == "torch-pinn":
        import torch

        monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main(["run", "--quick", "--progress", "off", "--case", "smib-inference", "wscc9", "--suite", "accuracy",
              *argv, "--out", str(out)])
    assert info.value.code == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(message) and "Traceback" not in captured.err
    assert not out.exists()  # refused before the first measurement


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
