"""The runner and its row store: the resume rule (a unit of work is done when its completion is
recorded), torn and bad lines, idempotent resume, Ctrl-C, and what `run` and `report` do with bad
folders and files; failures and missing dependencies as rows, the run going on. Fast: a do-nothing
adapter and a counting suite stand in for real ones."""

from __future__ import annotations

import json
import os
import sys
from dataclasses import replace
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

import solvers
from harness.cli import main
from harness.report.files import write_report
from harness.run.runner import run_suites
from harness.settings import QUICK, SolverSpec
from harness.store import RowStore
from harness.suites import SUITES, Suite
from solvers.base import AbstractSolver, SolveError
from systems.cases import CASES, SMIB_INFERENCE

SETTINGS = replace(QUICK, cache_dir=None)
KEY = {"suite": "s", "case": "c", "solver": "x", "config": "default", "variant": "", "seed": -1}


class Counting(AbstractSolver):
    """Fits by counting; registered only while a test runs. Its step `dt` (s) has numba-rk's rule:
    at most the case's horizon (20 s on the SMIB, 10 s on wscc9)."""

    name = "counting"
    OPTIONS: ClassVar = {"threads": 1, "dt": 0.1}
    takes_threads = True
    fits = 0

    def _check_options(self):
        if self.options["dt"] > self.case.t_final:
            raise ValueError(f"counting: option dt must be <= t_final of case {self.case.name}, "
                             f"got {self.options['dt']!r}")

    def _fit(self):
        type(self).fits += 1

    def _solve(self, t, P1):
        return np.zeros((P1.size, t.size)), np.zeros((P1.size, t.size))

    def _identify(self, obs):
        raise NotImplementedError


@pytest.fixture
def counting(monkeypatch):
    """The adapter `counting` and two suites, `one` (2 rows) and `two` (1 row), that count their calls."""
    calls: list[str] = []

    def suite(name: str, n: int):
        def run(solver, case, settings):
            calls.append(name)
            if getattr(run, "interrupt", None) is not None:
                raise run.interrupt
            return [{"value": float(i)} for i in range(n)]
        return run

    monkeypatch.setitem(solvers.SOLVERS, "counting", Counting)
    monkeypatch.setattr(Counting, "fits", 0)
    monkeypatch.setitem(SUITES, "one", Suite("one", suite("one", 2)))
    monkeypatch.setitem(SUITES, "two", Suite("two", suite("two", 1)))
    return calls


def _run(store: RowStore, resume: bool = False, suites=("one", "two")):
    return run_suites([SolverSpec("counting")], [SMIB_INFERENCE], list(suites), SETTINGS, store,
                      progress=False, resume=resume)


# ------------------------------------------------------------------------------------------- store

def test_a_unit_is_recorded_with_its_rows_and_a_completion_record(tmp_path):
    store = RowStore(tmp_path)
    store.record(KEY, [{**KEY, "v": np.float64(1.5)}, {**KEY, "v": (1, 2)}])
    lines = store.path.read_text().splitlines()
    assert len(lines) == 3 and json.loads(lines[-1]) == {"_complete": KEY, "rows": 2}
    contents = store.read()
    assert [r["v"] for r in contents.rows] == [1.5, [1, 2]]
    assert contents.completed == {tuple(KEY.values())} and contents.bad_lines == contents.incomplete_rows == 0


def test_a_torn_tail_is_set_aside_and_resume_is_idempotent(tmp_path):
    store = RowStore(tmp_path)
    store.record(KEY, [{**KEY, "v": 1}])
    whole = store.path.read_bytes()
    with open(store.path, "ab") as fh:  # a unit killed mid-write: a row and half of another
        fh.write(json.dumps({**KEY, "suite": "t", "v": 2}).encode() + b'\n{"suite": "t", "v')
    contents = store.read()
    assert contents.rows == [{**KEY, "v": 1}] and contents.incomplete_rows == 1 and contents.bad_lines == 1
    store.prepare_resume()
    assert store.path.read_bytes() == whole
    assert store.set_aside_path.read_text().count("\n") == 2  # nothing lost
    store.prepare_resume()
    assert store.path.read_bytes() == whole


def test_bad_lines_are_counted_and_skipped(tmp_path):
    store = RowStore(tmp_path)
    store.record(KEY, [{**KEY, "v": 1}])
    with open(store.path, "ab") as fh:
        fh.write(b"[1, 2]\n\xff\xfe garbage\nnot json\n")
    store.record({**KEY, "suite": "u"}, [{**KEY, "suite": "u", "v": 2}])
    contents = store.read()
    assert [r["v"] for r in contents.rows] == [1, 2] and contents.bad_lines == 3
    assert "skipped 3 line(s) that are not JSON rows" in contents.warning(store.path)


@pytest.mark.parametrize("replacement", [b'{"suite": "one", "val', None], ids=["spoilt", "lost"])
def test_a_completed_unit_that_lost_a_row_is_set_aside_and_measured_again(tmp_path, counting, capsys, replacement):
    """Its first row torn in place, or gone: the unit's record counts 2 rows, 1 is left."""
    argv = ["run", "--case", "smib-inference", "--solver", "counting", "--suite", "one", "two", "--quick", "--progress",
            "off", "--out", str(tmp_path)]
    assert main(argv) == 0
    store = RowStore(tmp_path)
    lines = store.path.read_bytes().splitlines()
    assert [json.loads(line).get("suite") for line in lines[2:5]] == ["one", "one", None]  # after fit's row and record
    lines[2:3] = [] if replacement is None else [replacement]
    unit = lines[2:4 if replacement is None else 5]  # what is left of unit `one`, up to its record
    store.path.write_bytes(b"".join(line + b"\n" for line in lines))
    contents = store.read()
    assert contents.damaged_units == 1 and [r["suite"] for r in contents.rows] == ["fit", "two"]
    assert "the rows of 1 unit(s) that lost a row" in contents.warning(store.path)
    capsys.readouterr()
    assert main([*argv, "--resume"]) == 0
    assert [r["suite"] for r in store.rows()] == ["fit", "two", "one", "one"] and counting == ["one", "two", "one"]
    assert store.set_aside_path.read_bytes().splitlines() == unit
    err = capsys.readouterr().err
    assert f"{store.path}: set aside " in err and "the rows of 1 unit(s) that lost a row in rows.jsonl.set-aside" in err
    before = store.path.read_bytes()
    store.prepare_resume()
    assert store.path.read_bytes() == before


def test_a_line_that_is_not_a_row_is_set_aside_and_its_unit_kept(tmp_path):
    store = RowStore(tmp_path)
    store.record(KEY, [{**KEY, "v": 1}])
    whole = store.path.read_bytes()
    store.path.write_bytes(b"not json\n" + whole)
    contents = store.prepare_resume()
    assert contents.bad_lines == 1 and contents.damaged_units == 0 and contents.rows == [{**KEY, "v": 1}]
    assert store.path.read_bytes() == whole and store.set_aside_path.read_bytes() == b"not json\n"


def test_rows_from_before_completion_records_are_read_but_not_resumed(tmp_path):
    store = RowStore(tmp_path)
    store.path.write_text(json.dumps({**KEY, "v": 1}) + "\n")
    assert store.read().legacy and store.rows() == [{**KEY, "v": 1}]
    with pytest.raises(ValueError, match="older swingbench"):
        store.prepare_resume()


def test_a_reader_does_not_create_the_folder(tmp_path):
    store = RowStore(tmp_path / "missing", create=False)
    assert store.rows() == [] and not (tmp_path / "missing").exists()


# ------------------------------------------------------------------------------------------ runner

def test_resuming_a_finished_run_changes_nothing(tmp_path, counting):
    store = RowStore(tmp_path)
    assert _run(store) == {"ok": 3, "skipped": 0, "failed": 0, "lost": 0}
    before = store.path.read_bytes()
    assert [r["suite"] for r in store.rows()] == ["fit", "one", "one", "two"]
    assert _run(store, resume=True) == {"ok": 0, "skipped": 0, "failed": 0, "lost": 0}
    assert store.path.read_bytes() == before and counting == ["one", "two"] and Counting.fits == 1


def test_resume_runs_only_what_is_not_recorded_and_never_repeats_the_fit_row(tmp_path, counting):
    store = RowStore(tmp_path)
    _run(store, suites=("one",))
    _run(store, resume=True)
    rows = store.rows()
    assert [r["suite"] for r in rows] == ["fit", "one", "one", "two"]
    assert counting == ["one", "two"]
    assert Counting.fits == 2  # the adapter is fitted again to run `two`, its fit row is not written again


def test_failed_units_are_results_and_are_kept(tmp_path, counting, monkeypatch):
    monkeypatch.setattr(Counting, "_fit", lambda self: 1 / 0)
    store = RowStore(tmp_path)
    assert _run(store) == {"ok": 0, "skipped": 0, "failed": 3, "lost": 0}
    assert {r["status"] for r in store.rows()} == {"failed: ZeroDivisionError: division by zero"}
    before = store.path.read_bytes()
    _run(store, resume=True)
    assert store.path.read_bytes() == before


def _raised(exc: BaseException, cause: BaseException | None = None, context: BaseException | None = None):
    exc.__cause__, exc.__context__ = cause, context
    return exc


NUMBA_INTERRUPT = "CPUDispatcher(<function points_2_0_3>) returned a result with an exception set"


@pytest.mark.parametrize("interrupt", [
    KeyboardInterrupt(),
    _raised(SystemError(NUMBA_INTERRUPT), cause=KeyboardInterrupt()),  # numba's dispatcher
    _raised(RuntimeError("while handling"), context=KeyboardInterrupt()),
    _raised(ValueError("wrapped twice"), cause=_raised(SystemError(NUMBA_INTERRUPT), context=KeyboardInterrupt())),
], ids=["plain", "numba-cause", "context", "nested"])
def test_ctrl_c_stops_with_one_line_and_exit_130(tmp_path, counting, capsys, interrupt):
    """However compiled code wraps the KeyboardInterrupt: no failed row, and --resume measures it."""
    SUITES["two"].run.interrupt = interrupt
    argv = ["run", "--case", "smib-inference", "--solver", "counting", "--suite", "one", "two", "--quick", "--progress", "off",
            "--out", str(tmp_path)]
    assert main(argv) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("[swingbench] interrupted: 2 completed unit(s) of work kept")
    assert err[0].endswith(" ".join(["swingbench", *argv, "--resume"]))
    assert [r["suite"] for r in RowStore(tmp_path).rows()] == ["fit", "one", "one"]
    SUITES["two"].run.interrupt = None
    assert main([*argv, "--resume"]) == 0
    assert [r["suite"] for r in RowStore(tmp_path).rows()] == ["fit", "one", "one", "two"]


# ------------------------------------------------------------------------- a folder that holds rows

AGAIN = ["run", "--case", "smib-inference", "--solver", "counting", "--suite", "one", "--quick", "--progress", "off"]


def test_a_rerun_into_a_folder_with_rows_is_refused_without_resume_or_overwrite(tmp_path, counting, capsys):
    assert main([*AGAIN, "--out", str(tmp_path)]) == 0
    before = sorted(p.name for p in tmp_path.iterdir())
    rows = (tmp_path / "rows.jsonl").read_bytes()
    capsys.readouterr()
    with pytest.raises(SystemExit) as info:
        main([*AGAIN, "--out", str(tmp_path)])
    assert info.value.code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        (f"swingbench run: --out {tmp_path} holds the rows of an earlier run (rows.jsonl): add --resume to continue "
         "it, or --overwrite to start again with its rows moved aside")]
    assert (tmp_path / "rows.jsonl").read_bytes() == rows and sorted(p.name for p in tmp_path.iterdir()) == before
    assert counting == ["one"]  # measured once


def test_overwrite_moves_the_earlier_rows_and_metadata_aside(tmp_path, counting, capsys):
    runs = []  # (rows.jsonl, metadata.json) of each run
    for again in ([], ["--overwrite"], ["--overwrite"]):  # within a second or not: a name of its own each
        assert main([*AGAIN, *again, "--out", str(tmp_path)]) == 0
        runs.append(((tmp_path / "rows.jsonl").read_bytes(), (tmp_path / "metadata.json").read_bytes()))
    aside = {p.read_bytes(): p for p in tmp_path.glob("rows.*.jsonl")}
    assert set(aside) == {rows for rows, _ in runs[:2]} and len(list(tmp_path.glob("*.*.json*"))) == 4
    for rows, meta in runs[:2]:
        stamp = aside[rows].name.removeprefix("rows.").removesuffix(".jsonl")
        assert (tmp_path / f"metadata.{stamp}.json").read_bytes() == meta
    assert [r["suite"] for r in RowStore(tmp_path).rows()] == ["fit", "one", "one"]  # the last run's only
    first = aside[runs[0][0]].name
    assert f"[swingbench] --overwrite: the earlier run's rows.jsonl moved to {first}" in capsys.readouterr().err


def test_ctrl_c_after_overwrite_is_continued_by_resume_alone(tmp_path, counting, capsys):
    assert main([*AGAIN, "--out", str(tmp_path)]) == 0
    SUITES["one"].run.interrupt = KeyboardInterrupt()
    assert main([*AGAIN, "--overwrite", "--out", str(tmp_path)]) == 130
    SUITES["one"].run.interrupt = None
    again = capsys.readouterr().err.strip().splitlines()[-1].split("continue with: ")[1]
    assert again == " ".join(["swingbench", *AGAIN, "--out", str(tmp_path), "--resume"])
    with pytest.raises(SystemExit) as info:
        main([*AGAIN, "--overwrite", "--resume", "--out", str(tmp_path)])
    assert info.value.code == 2  # argparse: not both


# --------------------------------------------------------------------------------------------- CLI

@pytest.mark.parametrize("argv,message", [
    (["--config", "default", "nope"], "unknown config(s) 'nope'"),
    (["--solver", "scipy-odeint", "nope"], "unknown solver(s) 'nope'"),
    (["--suite", "accuracy", "speed"], "unknown suite(s) 'speed'"),
    (["--case", "smib-inference", "ieee300"], "unknown case(s) 'ieee300'"),
])
def test_an_unknown_name_anywhere_in_a_list_is_an_error(argv, message, tmp_path):
    with pytest.raises(SystemExit, match=message.replace("(", r"\(").replace(")", r"\)")):
        main(["run", *argv, "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()


def test_an_unusable_out_is_one_line(tmp_path, counting):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    argv = ["run", "--case", "smib-inference", "--solver", "counting", "--suite", "one", "--quick", "--progress", "off"]
    with pytest.raises(SystemExit, match="is a file, not a folder"):
        main([*argv, "--out", str(a_file)])
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(SystemExit, match="cannot write to --out"):
            main([*argv, "--out", str(locked)])


def test_an_out_inside_a_folder_that_cannot_be_entered_is_one_line(tmp_path, counting, monkeypatch, capsys):
    """As a user without search permission on the parent finds it (root enters any folder, so the
    test makes stat refuse): exit 2 and one line, no PermissionError traceback."""
    import pathlib

    out = tmp_path / "closed" / "out"
    real_stat = pathlib.Path.stat

    def stat(self, *args, **kwargs):
        if str(self).startswith(str(tmp_path / "closed")):
            raise PermissionError(13, "Permission denied", str(self))
        return real_stat(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "stat", stat)
    argv = ["run", "--case", "smib-inference", "--solver", "counting", "--suite", "one", "--quick", "--progress", "off"]
    with pytest.raises(SystemExit) as info:
        main([*argv, "--out", str(out)])
    assert info.value.code == 2 and str(info.value) == (
        f"swingbench run: cannot write to --out {out}: Permission denied")


def test_report_skips_bad_lines_with_a_warning_and_survives_bad_metadata(tmp_path, counting, capsys):
    store = RowStore(tmp_path)
    _run(store)
    with open(store.path, "ab") as fh:
        fh.write(b"\xff\xfe\n42\n")
    (tmp_path / "metadata.json").write_bytes(b"{truncated")
    capsys.readouterr()
    assert main(["report", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "skipped 2 line(s) that are not JSON rows" in err and "metadata.json is unreadable" in err
    assert (tmp_path / "tables.md").exists()


def test_report_on_a_missing_folder_creates_nothing(tmp_path):
    with pytest.raises(SystemExit, match="is not a folder of results"):
        main(["report", str(tmp_path / "missing")])
    assert not (tmp_path / "missing").exists()


def test_resume_refuses_a_run_made_with_other_settings(tmp_path, counting):
    argv = ["run", "--case", "smib-inference", "--solver", "counting", "--suite", "one", "--progress", "off", "--out", str(tmp_path)]
    assert main([*argv, "--quick"]) == 0
    with pytest.raises(SystemExit, match="made with settings 'quick', not 'default'"):
        main([*argv, "--resume"])
    assert main([*argv, "--quick", "--resume"]) == 0


# ------------------------------------------------------------------------ checks and exit status

RUN = ["run", "--solver", "counting", "--suite", "one", "--quick", "--progress", "off"]


def test_an_option_invalid_on_one_case_stops_the_run_before_it_measures(tmp_path, counting, capsys):
    wscc9 = CASES["wscc9"]
    with pytest.raises(ValueError, match="^counting\\[default,dt=15\\] wscc9: counting: option dt must be <= "
                                         "t_final of case wscc9, got 15"):
        run_suites([SolverSpec("counting", options=(("dt", 15),))], [SMIB_INFERENCE, wscc9], ["one"], SETTINGS,
                   RowStore(tmp_path / "api"), progress=False)
    assert counting == [] and RowStore(tmp_path / "api").rows() == []

    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main([*RUN, "--case", "smib-inference", "wscc9", "--option", "dt=15", "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [("swingbench run: counting[default,dt=15] wscc9: counting: option dt must be <= t_final of "
                    "case wscc9, got 15")]
    assert counting == [] and not out.exists()  # nothing measured, no folder made (nor an old one cleared)
    assert main([*RUN, "--case", "smib-inference", "--option", "dt=15", "--out", str(out)]) == 0  # valid there


@pytest.mark.parametrize("argv", [
    ["--solver", "nope"],
    ["--option", "width=3"],
    ["--option", "dt"],
    ["--threads", "0"],
    ["--case", "smib-inference", "--update-readme", "missing.md"],
])
def test_bad_input_is_one_line_on_stderr_and_exit_status_2(argv, tmp_path, counting, capsys):
    with pytest.raises(SystemExit) as info:
        main([*RUN, *argv, "--out", str(tmp_path / "out")])
    assert info.value.code == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("swingbench run: ") and "Traceback" not in captured.err
    assert counting == [] and not (tmp_path / "out").exists()


def test_a_failed_unit_exits_1_with_one_line_naming_it_and_its_rows(tmp_path, counting, monkeypatch, capsys):
    argv = [*RUN, "--case", "smib-inference", "--out", str(tmp_path)]
    monkeypatch.setattr(Counting, "_fit", lambda self: 1 / 0)
    assert main(argv) == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == (f"[swingbench] 2 unit(s) of work failed, in 1 unit(s): counting[default] smib-inference "
                    f"(fit, one); their rows, with the reason in 'status', are in {tmp_path / 'rows.jsonl'}")
    assert main([*argv, "--resume"]) == 1  # the failure is a result of the run: kept, and still reported


def test_a_declared_skip_is_not_a_failure(tmp_path, counting, monkeypatch, capsys):
    monkeypatch.setitem(SUITES, "skips", Suite("skips", lambda solver, case, settings: [
        {"status": "skipped: not measured in this test"}]))
    argv = ["run", "--solver", "counting", "--suite", "one", "skips", "--quick", "--progress", "off",
            "--case", "smib-inference", "--out", str(tmp_path)]
    assert main(argv) == 0
    assert "failed" not in capsys.readouterr().err
    assert {r["status"] for r in RowStore(tmp_path).rows()} == {"ok", "skipped: not measured in this test"}


def test_every_suite_is_a_module_that_registers_itself_and_the_cli_lists_them_all():
    from harness.cli.run import _suite_names
    from harness.suites import DEFAULT_SUITES

    assert list(SUITES) == _suite_names() == ["accuracy", "cct", "identification", "latency", "scaling", "verdict",
                                               "work_precision"]
    assert all(SUITES[name].run.__module__ == f"harness.suites.{name}" for name in SUITES)
    assert DEFAULT_SUITES == ("accuracy", "cct", "identification", "latency", "verdict", "work_precision")  # scaling alone


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


def test_the_runner_says_an_executor_cannot_be_had_without_ending_the_process(monkeypatch):
    """`harness.run` raises its own error, not the command line's `SystemExit`: the CLI decides the
    exit status."""
    from harness.run import executors

    monkeypatch.setitem(sys.modules, "distributed", None)
    entering = executors.choose(None, True, workers=1)
    with pytest.raises(executors.ExecutorUnavailable, match=r"^--scheduler/--dask-local need dask\.distributed"):
        entering.__enter__()
