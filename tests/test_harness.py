"""The runner, the row store, the report and the CLI, on cheap solvers."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

import solvers
from harness.cases import SMIB_INFERENCE
from harness.cli import main
from harness.report import write_report
from harness.runner import run_suites
from harness.runs import QUICK, SolverSpec, default_specs
from harness.store import RowStore, atomic_write
from harness.timing import time_call
from solvers.base import AbstractSolver, SolveError


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
    settings = replace(QUICK, cache_dir=None, throughput_sizes=(1,), t1_values_s=(10.0,))
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
    assert set(latency["query"]) == {"grid 100x201", "1 trajectories x 201 times", "single point t1=10 s"}
    assert (latency["median_s"] > 0).all()

    markdown = write_report(store.rows(), tmp_path, {"threads": 2})
    assert "casadi-cvodes [default]" in markdown and "Skipped or failed" in markdown
    assert "skipped: nothing not installed" in markdown
    assert pd.read_csv(tmp_path / "accuracy.csv")["rel_l2"].notna().any()


def test_row_store_survives_a_torn_last_line(tmp_path):
    store = RowStore(tmp_path)
    store.add({"suite": "fit", "value": np.float64(1.5)})
    with open(store.path, "a") as fh:
        fh.write('{"suite": "acc')  # an interrupted write
    assert store.rows() == [{"suite": "fit", "value": 1.5}]


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


def test_time_call_counts_repeats():
    calls = []
    timing = time_call(lambda: calls.append(1), warmup=2, min_repeats=4, budget_s=0.0)
    assert timing.repeats == 4 and len(calls) == 6
    assert 0 <= timing.min_s <= timing.median_s


def test_cli_run_and_report(tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["run", "--quick", "--progress", "off", "--solver", "casadi-cvodes", "--config", "default",
                 "--suite", "accuracy", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "casadi-cvodes [default]" in printed
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["threads"] == 2 and "version_numpy" in meta
    (out / "tables.md").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "tables.md").exists()


@pytest.mark.parametrize("argv,message", [
    (["run", "--solver", "rk4"], "unknown solver"),
    (["run", "--suite", "speed"], "unknown suite"),
    (["run", "--case", "ieee39"], "unknown case"),
])
def test_cli_rejects_unknown_names(argv, message, tmp_path):
    with pytest.raises(SystemExit, match=message):
        main([*argv, "--out", str(tmp_path)])


def test_cli_help(capsys):
    with pytest.raises(SystemExit) as info:
        main(["run", "--help"])
    assert info.value.code == 0
    assert "--quick" in capsys.readouterr().out
