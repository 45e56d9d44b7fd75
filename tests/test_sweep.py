"""`swingbench sweep`: spec parsing and validation, the joblib and Dask executors on the cheap
casadi-cvodes adapter, failed runs as rows, the summary table."""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import ClassVar

import pandas as pd
import pytest

from harness.cli import sweep
from harness.measure.timing import pinned_threads
from harness.report.sweep import summary_markdown, summary_table
from harness.run.plan import Unit
from harness.run.runner import run_unit_in_worker
from harness.settings import Settings, SolverSpec
from harness.store import RowStore
from solvers import SOLVERS
from solvers.base import AbstractSolver
from systems.cases import SMIB_INFERENCE

pytestmark = pytest.mark.skipif(SOLVERS.get("casadi-cvodes") is None, reason="casadi not installed")

CHEAP = {"solver": "casadi-cvodes", "grid": {"rtol": [1e-3, 1e-6]}, "options": {"atol": 1e-8}}


class FakeTrainer(AbstractSolver):
    """Registered only while a test runs: an adapter with a seed, for the seed rules."""

    name = "fake-trainer"
    OPTIONS: ClassVar = {"seed": 0, "width": 10, "threads": 1, "progress": True}
    trains = True
    takes_threads = True

    def _check_options(self):
        if self.options["width"] < 1:
            raise ValueError(f"option width must be >= 1, got {self.options['width']!r}")

    def _fit(self):
        return None

    def _solve(self, t, P1):
        raise NotImplementedError

    def _identify(self, obs):
        raise NotImplementedError


@pytest.fixture
def fake(monkeypatch):
    monkeypatch.setitem(SOLVERS, "fake-trainer", FakeTrainer)
    return "fake-trainer"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swingbench")
    sweep.add_parser(parser.add_subparsers(dest="command", required=True))
    return parser


def _cli(*argv: str) -> int:
    return sweep.cmd_sweep(_parser().parse_args(["sweep", *argv]))


def _write(tmp_path: Path, spec: dict) -> Path:
    path = tmp_path / "spec.json"
    path.write_text(json.dumps(spec))
    return path


# ------------------------------------------------------------------------------------- parsing

def test_spec_expands_to_grid_x_seeds_x_cases(fake):
    spec = sweep.parse_spec({"solver": fake, "cases": ["smib-inference", "smib-identification"],
                             "seeds": [0, 1, 2], "grid": {"width": [5, 10]}})
    units = spec.units()
    assert len(units) == 2 * 3 * 2
    assert {(u.case.name, dict(u.spec.options)["width"], u.spec.seed) for u in units} == {
        (c, w, s) for c in ("smib-inference", "smib-identification") for w in (5, 10) for s in (0, 1, 2)}
    assert all(u.suites == ("accuracy",) for u in units)
    row = units[0].base(Settings(threads=1))
    assert row["p_width"] == 5 and row["seed"] == 0 and row["threads"] == 1 and row["variant"] == "width=5"


def test_spec_defaults_and_classical_seedless():
    spec = sweep.parse_spec(CHEAP)
    assert spec.config == "default" and spec.cases == ("smib-inference",) and spec.seeds == (None,)
    units = spec.units()
    assert [u.spec.variant for u in units] == ["atol=1e-08,rtol=0.001", "atol=1e-08,rtol=1e-06"]
    assert [u.base(Settings())["seed"] for u in units] == [-1, -1]
    assert [dict(u.columns)["point"] for u in units] == [0, 1]


def test_no_grid_is_one_point():
    assert len(sweep.parse_spec({"solver": "casadi-cvodes"}).units()) == 1


@pytest.mark.parametrize(("spec", "message"), [
    ([1, 2], "must be a JSON object"),
    ({"solver": "casadi-cvodes", "grids": {}}, "unknown key(s) 'grids'"),
    ({}, "'solver' must be"),
    ({"solver": "no-such-solver"}, "'solver': unknown solver 'no-such-solver'"),
    ({"solver": "casadi-cvodes", "config": "nope"}, "'config': unknown config 'nope'"),
    ({"solver": "casadi-cvodes", "cases": ["smib-nowhere"]}, "'cases': unknown case 'smib-nowhere'"),
    ({"solver": "casadi-cvodes", "cases": []}, "'cases' must be a non-empty list"),
    ({"solver": "casadi-cvodes", "grid": {"width": [10]}}, "'grid': unknown option 'width' for casadi-cvodes"),
    ({"solver": "casadi-cvodes", "options": {"n_f": 10}}, "'options': unknown option 'n_f'"),
    ({"solver": "casadi-cvodes", "grid": {"rtol": []}}, "'grid': 'rtol' must be a non-empty list"),
    ({"solver": "casadi-cvodes", "grid": {"rtol": 1e-3}}, "'grid': 'rtol' must be a non-empty list"),
    ({"solver": "casadi-cvodes", "grid": {"rtol": [1e-3, 1e-3]}}, "'grid': 'rtol' lists a value twice"),
    ({"solver": "casadi-cvodes", "grid": {"rtol": [1e-3]}, "options": {"rtol": 1e-4}}, "also fixed in 'options'"),
    ({"solver": "casadi-cvodes", "grid": {"threads": [1, 2]}}, "option 'threads' cannot be set"),
    ({"solver": "casadi-cvodes", "seeds": [0]}, "'seeds': casadi-cvodes takes no seed"),
    ({"solver": "casadi-cvodes", "grid": {"rtol": [1e-3, -1.0]}}, "'grid' point rtol=-1.0: casadi-cvodes: option rtol must be"),
])
def test_spec_errors_name_the_key(spec, message):
    with pytest.raises(ValueError) as info:
        sweep.parse_spec(spec)
    assert message in str(info.value)


@pytest.mark.parametrize(("extra", "message"), [
    ({"seeds": []}, "'seeds' must be a non-empty list"),
    ({"seeds": [0, "1"]}, "'seeds': each seed must be an integer"),
    ({"seeds": [1, 1]}, "'seeds' lists a seed twice"),
    ({"grid": {"seed": [0, 1]}}, "option 'seed' cannot be set in a sweep (set seeds with"),
    ({"grid": {"width": [10, 0]}}, "'grid' point width=0: option width must be >= 1"),
])
def test_seed_rules(fake, extra, message):
    with pytest.raises(ValueError) as info:
        sweep.parse_spec({"solver": fake, **extra})
    assert message in str(info.value)
    assert sweep.parse_spec({"solver": fake}).seeds == (0,)


def test_cli_errors_are_system_exits(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(SystemExit, match="not valid JSON"):
        _cli(str(bad), "--out", str(tmp_path / "out"))
    with pytest.raises(SystemExit, match="cannot read"):
        _cli(str(tmp_path / "missing.json"))
    spec = _write(tmp_path, {"solver": "casadi-cvodes", "grid": {"bogus": [1]}})
    with pytest.raises(SystemExit, match="'grid': unknown option 'bogus'"):
        _cli(str(spec), "--out", str(tmp_path / "out"))
    assert not (tmp_path / "out").exists()
    with pytest.raises(SystemExit, match="--workers must be >= 1"):
        _cli(str(spec), "--workers", "0")


def test_a_bad_spec_is_one_line_and_exit_status_2(tmp_path, capsys):
    from harness.cli import main

    spec = _write(tmp_path, {"solver": "casadi-cvodes", "grid": {"bogus": [1]}})
    with pytest.raises(SystemExit) as info:
        main(["sweep", str(spec), "--out", str(tmp_path / "out")])
    assert info.value.code == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"swingbench sweep: {spec}: 'grid': unknown option 'bogus'")
    assert "Traceback" not in captured.err and not (tmp_path / "out").exists()


STEP_ON_TWO_HORIZONS = {"solver": "numba-rk", "config": "rk4", "cases": ["smib-inference", "wscc9"],
                        "grid": {"dt": [0.1, 15]}}  # 15 s: within the SMIB's 20 s, past wscc9's 10 s


def test_a_grid_value_invalid_on_one_case_only_is_refused_before_any_run(tmp_path, capsys):
    if SOLVERS.get("numba-rk") is None:
        pytest.skip("numba is not installed")
    with pytest.raises(ValueError) as info:
        sweep.parse_spec(STEP_ON_TWO_HORIZONS)
    assert str(info.value) == ("'grid' point dt=15 on case wscc9: numba-rk: option dt must be <= t_final = "
                               "10.0 s, the horizon of case wscc9, got 15.0")
    spec = _write(tmp_path, STEP_ON_TWO_HORIZONS)
    for extra in (["--dry-run"], []):
        with pytest.raises(SystemExit, match="'grid' point dt=15 on case wscc9") as info:
            _cli(str(spec), *extra, "--out", str(tmp_path / "out"))
        assert info.value.code == 2
    assert capsys.readouterr().out == "" and not (tmp_path / "out").exists()


def test_a_failed_run_exits_1_with_one_line_naming_it_and_its_rows(tmp_path, fake, monkeypatch, capsys):
    from harness.run import executors
    monkeypatch.setattr(executors, "joblib", lambda workers: executors.inline)  # in this process: the fake is here
    out = tmp_path / "out"
    assert _cli(str(_write(tmp_path, {"solver": fake, "grid": {"width": [5]}})), "--out", str(out)) == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == ("[swingbench] 1 unit(s) of work failed, in 1 unit(s): fake-trainer[default,width=5,seed=0] "
                    f"smib-inference (accuracy); their rows, with the reason in 'status', are in {out / 'rows.jsonl'}")
    assert [r["status"].split(":")[0] for r in RowStore(out).rows()] == ["ok", "failed"]  # the fit, the accuracy


def test_help_documents_the_format(capsys):
    with pytest.raises(SystemExit) as info:
        _parser().parse_args(["sweep", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for word in ("SPEC (JSON)", '"grid"', "seeds", "--scheduler", "--dask-local", "--workers", "No latency"):
        assert word in text


def test_dry_run_lists_runs(tmp_path, capsys):
    assert _cli(str(_write(tmp_path, CHEAP)), "--dry-run", "--out", str(tmp_path / "out")) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["casadi-cvodes[default,atol=1e-08,rtol=0.001] smib-inference",
                   "casadi-cvodes[default,atol=1e-08,rtol=1e-06] smib-inference"]
    assert not (tmp_path / "out").exists()


def test_example_spec_parses():
    path = Path(__file__).resolve().parents[1] / "sweeps" / "example.json"
    raw = json.loads(path.read_text())
    if SOLVERS.get(raw["solver"]) is None:
        pytest.skip(f"{raw['solver']} is not available here")
    assert len(sweep.load_spec(path).units()) == 12


# -------------------------------------------------------------------------------------- worker

def test_pinned_threads_sets_and_restores_environment(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "7")
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x --xla_cpu_multi_thread_eigen=true")
    monkeypatch.delenv("PJRT_NPROC", raising=False)
    with pinned_threads(1):
        assert os.environ["OMP_NUM_THREADS"] == os.environ["OPENBLAS_NUM_THREADS"] == "1"
        assert os.environ["PJRT_NPROC"] == "1"
        assert os.environ["XLA_FLAGS"].split() == ["--xla_dump_to=/tmp/x", "--xla_cpu_multi_thread_eigen=false"]
    assert os.environ["OMP_NUM_THREADS"] == "7"
    assert "PJRT_NPROC" not in os.environ
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x --xla_cpu_multi_thread_eigen=true"


def test_failing_run_is_a_failed_row():
    unit = Unit(SMIB_INFERENCE, SolverSpec("casadi-cvodes", "default", (("rtol", -1.0),)), ("accuracy",),
                (("point", 3), ("p_rtol", -1.0)))
    parts = run_unit_in_worker(unit, Settings(threads=1, cache_dir=None), ("fit", "accuracy"))
    assert [work for work, _ in parts] == ["fit", "accuracy"]
    for _, (row,) in parts:
        assert row["status"].startswith("failed: ValueError:") and "rtol" in row["status"]
        assert row["p_rtol"] == -1.0 and row["point"] == 3 and row["case"] == "smib-inference"
        json.dumps(row)  # plain values


# ----------------------------------------------------------------------------------- executors

def _check_outputs(out: Path, n_runs: int) -> pd.DataFrame:
    rows = RowStore(out).rows()
    assert {r["status"] for r in rows} == {"ok"}
    runs = {(r["case"], r["variant"], r["seed"]) for r in rows}
    assert len(runs) == n_runs
    fits = [r for r in rows if r["suite"] == "fit"]
    assert len(fits) == n_runs and all(r["fit_s"] >= 0 and r["iterations"] == 0 for r in fits)
    ref = [r for r in rows if r.get("against") == "reference"]
    assert len(ref) == 2 * n_runs and {r["quantity"] for r in ref} == {"delta", "omega"}
    for r in rows:
        assert r["suite"] in ("fit", "accuracy") and r["solver"] == "casadi-cvodes" and r["threads"] == 1
        assert r["blas_threads"] == 1 and r["suite"] == "fit" or math.isfinite(r["rel_l2"])
        assert not any("median_s" in key for key in r)  # no latency in a sweep
    # tighter tolerance, smaller error
    err = {r["p_rtol"]: r["rel_l2"] for r in ref if r["quantity"] == "delta"}
    assert err[1e-6] < err[1e-3] < 1e-2

    csv = pd.read_csv(out / "sweep.csv")
    assert len(csv) == len(rows) and "p_rtol" in csv.columns and set(csv["p_rtol"]) == {1e-3, 1e-6}
    assert not any(c.endswith(("_pred", "_ref")) for c in csv.columns)
    md = (out / "sweep.md").read_text()
    assert "delta rel. L2, median [min, max]" in md and "rtol" in md and "1 / 0" in md
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["command"] == "sweep" and meta["runs"] == n_runs and meta["spec"]["grid"] == {"rtol": [1e-3, 1e-6]}
    return csv


@pytest.mark.slow
def test_joblib_sweep(tmp_path, capsys):
    out = tmp_path / "out"
    assert _cli(str(_write(tmp_path, CHEAP)), "--out", str(out), "--workers", "2") == 0
    _check_outputs(out, 2)
    assert "rtol" in capsys.readouterr().out  # the table is printed
    assert all(r["worker"].split(":")[1] != str(os.getpid()) for r in RowStore(out).rows())  # in workers

    # --resume runs nothing that is done
    before = (out / "rows.jsonl").read_text()
    assert _cli(str(_write(tmp_path, CHEAP)), "--out", str(out), "--resume") == 0
    assert (out / "rows.jsonl").read_text() == before


def test_failed_run_does_not_stop_the_sweep(tmp_path):
    from harness.run import executors
    from harness.run.runner import execute

    units = sweep.parse_spec(CHEAP).units()
    bad = Unit(SMIB_INFERENCE, SolverSpec("casadi-cvodes", "default", (("atol", 1e-8), ("rtol", -1.0))),
               ("accuracy",), (("point", 2), ("p_rtol", -1.0)))
    store = RowStore(tmp_path)
    counts = execute([units[0], bad, units[1]], Settings(threads=1), store, executors.joblib(2), progress=False)
    assert counts == {"ok": 4, "skipped": 0, "failed": 2, "lost": 0}  # units of work: a fit and an accuracy each
    rows = store.rows()
    failed = [r for r in rows if r["status"] != "ok"]
    assert len(failed) == 2 and {r["p_rtol"] for r in failed} == {-1.0}
    assert all(r["status"].startswith("failed: ValueError") for r in failed)
    table = summary_table(pd.DataFrame(rows))
    assert list(table["p_rtol"]) == [1e-3, 1e-6, -1.0]
    assert list(table["runs_ok"]) == [1, 1, 0] and list(table["failed"]) == [0, 0, 1]
    assert math.isnan(table["delta_rel_l2_median"].iloc[2])


@pytest.mark.slow
def test_dask_sweep_on_a_local_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster:
        out = tmp_path / "out"
        assert _cli(str(_write(tmp_path, CHEAP)), "--out", str(out), "--scheduler", cluster.scheduler_address) == 0
        _check_outputs(out, 2)
        assert len({r["worker"] for r in RowStore(out).rows()}) == 1  # the cluster's one worker process
        assert all(r["worker"].split(":")[1] != str(os.getpid()) for r in RowStore(out).rows())


# ------------------------------------------------------------------------------------- summary

def test_summary_statistics_over_seeds():
    rows = []
    for point, width in enumerate((10, 20)):
        for seed in (0, 1, 2):
            base = {"suite": "accuracy", "case": "c", "solver": "s", "config": "default",
                    "variant": f"width={width}", "seed": seed, "point": point, "p_width": width, "status": "ok"}
            err = (seed + 1) * (1e-3 if width == 10 else 1e-4)
            rows += [{**base, "suite": "fit", "fit_s": 10.0 * (seed + 1)},
                     {**base, "quantity": "delta", "against": "reference", "rel_l2": err},
                     {**base, "quantity": "omega", "against": "reference", "rel_l2": 2 * err},
                     {**base, "quantity": "delta", "against": "paper ode45 data", "rel_l2": 99.0}]
    rows.append({"suite": "accuracy", "case": "c", "solver": "s", "config": "default", "variant": "width=20",
                 "seed": 3, "point": 1, "p_width": 20, "status": "failed: RuntimeError: diverged"})
    table = summary_table(pd.DataFrame(rows))
    assert list(table["p_width"]) == [10, 20]
    first, second = table.iloc[0], table.iloc[1]
    assert (first["runs_ok"], first["failed"], second["runs_ok"], second["failed"]) == (3, 0, 3, 1)
    assert first["delta_rel_l2_median"] == pytest.approx(2e-3)
    assert (first["delta_rel_l2_min"], first["delta_rel_l2_max"]) == pytest.approx((1e-3, 3e-3))
    assert second["omega_rel_l2_median"] == pytest.approx(4e-4)
    assert first["fit_s_median"] == pytest.approx(20.0)
    md = summary_markdown(table, {"runs": 7})
    assert "0.002 [0.001, 0.003]" in md and "3 / 1" in md and "No latency" in md


def test_ctrl_c_stops_a_sweep_with_one_line_and_resume_finishes_it(tmp_path, monkeypatch, capsys):
    from harness.run import executors
    def interrupted_after_one_run(workers):
        def run(jobs, settings):
            yield from executors.inline(jobs[:1], settings)
            raise KeyboardInterrupt
        return run

    monkeypatch.setattr(executors, "joblib", interrupted_after_one_run)
    spec, out = str(_write(tmp_path, CHEAP)), tmp_path / "out"
    assert _cli(spec, "--out", str(out)) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("[swingbench] interrupted: 2 completed unit(s) of work kept") and "--resume" in err[-1]
    monkeypatch.setattr(executors, "joblib", lambda workers: executors.inline)
    assert _cli(spec, "--out", str(out), "--resume") == 0
    rows = RowStore(out).rows()
    assert sorted((r["suite"], r["p_rtol"]) for r in rows if r["suite"] == "fit") == [("fit", 1e-6), ("fit", 1e-3)]
    with pytest.raises(SystemExit, match="made with spec"):
        _cli(str(_write(tmp_path, {**CHEAP, "options": {"atol": 1e-9}})), "--out", str(out), "--resume")
