"""A long unit of work keeps its rows so far (a suite marked `checkpoints`, as the verdict suite):
stopped part-way by a failure, a limit, Ctrl-C or a killed process, its finished rounds are
recorded, each row saying how far it got and why, and never measured again by --resume. Fast: a
do-nothing adapter and a suite of two "rounds" stand in for real ones."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import numpy as np
import pytest

import solvers
from harness.cli import main
from harness.run import runner
from harness.run.isolation import OverLimit
from harness.run.runner import RESUMED, failed, run_suites
from harness.settings import QUICK, Limits, SolverSpec
from harness.store import RowStore, partial_path, read_partial, write_partial
from harness.suites import SUITES, Suite
from solvers.base import AbstractSolver
from systems.cases import SMIB_INFERENCE

SETTINGS = replace(QUICK, cache_dir=None)
ARGV = ["run", "--case", "smib-inference", "--solver", "idle", "--suite", "rounds", "--quick", "--progress", "off"]
KEY = {"suite": "rounds", "case": SMIB_INFERENCE.name, "solver": "idle", "config": "default", "variant": "", "seed": 0}


class Idle(AbstractSolver):
    """Fits and answers with nothing; registered only while a test runs."""

    name = "idle"
    OPTIONS: ClassVar = {"threads": 1}
    takes_threads = True

    def _fit(self):
        pass

    def _solve(self, t, P1):
        return np.zeros((P1.size, t.size)), np.zeros((P1.size, t.size))

    def _identify(self, obs):
        raise NotImplementedError


@pytest.fixture
def rounds(monkeypatch):
    """The adapter `idle` and the suite `rounds`: two rows, measured in two rounds, handing its
    checkpoint the rows after the first; `stop` (an exception) is raised after that checkpoint.
    Returns the list of its calls."""
    calls: list[str] = []

    def run(solver, case, settings, checkpoint=None):
        calls.append("rounds")
        if checkpoint is not None:
            checkpoint([{"query": q, "rounds": 1} for q in ("a", "b")], "1 of 2 rounds")
        if run.stop is not None:
            raise run.stop
        return [{"query": q, "rounds": 2} for q in ("a", "b")]

    run.stop = None
    monkeypatch.setitem(solvers.SOLVERS, "idle", Idle)
    monkeypatch.setitem(SUITES, "rounds", Suite("rounds", run, checkpoints=True))
    return calls


def _run(store: RowStore, settings=SETTINGS, resume: bool = False):
    return run_suites([SolverSpec("idle")], [SMIB_INFERENCE], ["rounds"], settings, store, progress=False,
                      resume=resume)


def _measured(store: RowStore) -> list[dict]:
    return [r for r in store.rows() if r["suite"] == "rounds"]


def test_a_unit_that_ends_records_its_rows_and_leaves_no_partial_file(tmp_path, rounds):
    store = RowStore(tmp_path)
    assert _run(store)["ok"] == 2
    assert [(r["query"], r["rounds"], r["status"]) for r in _measured(store)] == [("a", 2, "ok"), ("b", 2, "ok")]
    assert not any("stopped" in r for r in store.rows())
    assert list(store.partial_dir.iterdir()) == []


def test_a_unit_that_fails_part_way_records_the_rounds_it_finished(tmp_path, rounds):
    SUITES["rounds"].run.stop = MemoryError("out of memory")
    store = RowStore(tmp_path)
    counts = _run(store)
    rows = _measured(store)
    assert [(r["query"], r["rounds"], r["status"]) for r in rows] == [("a", 1, "ok"), ("b", 1, "ok")]
    assert {r["stopped"] for r in rows} == {"after 1 of 2 rounds: failed: MemoryError: out of memory"}
    assert {r["stopped_status"] for r in rows} == {"failed: MemoryError: out of memory"}
    assert {r["solver"] for r in rows} == {"idle"}  # the unit's columns, as measured rows
    assert counts["failed"] == 1 and counts["ok"] == 1 and all(map(failed, rows))  # still a failure: exit 1
    assert list(store.partial_dir.iterdir()) == []


def test_an_earlier_runs_partial_file_is_never_taken_for_this_units_rows(tmp_path, rounds, monkeypatch):
    """Left by a run that was not resumed (or by a worker elsewhere), it is replaced, never read."""
    store = RowStore(tmp_path)
    _run(store)  # a first run: the keys of its units
    key = next({c: r[c] for c in ("suite", "case", "solver", "config", "variant", "seed")}
               for r in store.rows() if r["suite"] == "rounds")
    write_partial(partial_path(store.partial_dir, key), key, [{**key, "status": "ok", "query": "old"}], "1 of 2 rounds")
    monkeypatch.setitem(SUITES, "rounds", Suite("rounds", lambda solver, case, settings, checkpoint=None: 1 / 0,
                                                checkpoints=True))
    _run(RowStore(tmp_path / "again"), replace(SETTINGS, partial_dir=store.partial_dir))
    rows = _measured(RowStore(tmp_path / "again"))
    assert [r["status"] for r in rows] == ["failed: ZeroDivisionError: division by zero"]
    assert not partial_path(store.partial_dir, key).exists()


def test_a_unit_killed_by_its_limit_records_the_rounds_it_finished(tmp_path, rounds, monkeypatch):
    """The isolated child wrote its checkpoint, then ran past --unit-seconds."""
    def killed(fn, unit, settings, todo, limits):
        key = unit.work_key("rounds")
        write_partial(partial_path(settings.partial_dir, key), key,
                      [{**key, "status": "ok", "query": "a", "rounds": 1}], "1 of 2 rounds")
        raise OverLimit("out of time: still running after 5 s (killed)")

    monkeypatch.setattr(runner, "call_isolated", killed)
    store = RowStore(tmp_path)
    counts = _run(store, replace(SETTINGS, unit_limits=Limits(seconds=5.0)))
    fit, *rows = store.rows()
    assert fit["status"] == "skipped: out of time: still running after 5 s (killed)"  # nothing kept: as before
    assert [(r["query"], r["rounds"], r["stopped"]) for r in rows] == [
        ("a", 1, "after 1 of 2 rounds: skipped: out of time: still running after 5 s (killed)")]
    assert counts["skipped"] == 2 and not any(map(failed, rows))


def test_ctrl_c_keeps_the_finished_rounds_and_resume_records_them_without_measuring_again(tmp_path, rounds, capsys):
    SUITES["rounds"].run.stop = KeyboardInterrupt()
    argv = [*ARGV, "--out", str(tmp_path)]
    assert main(argv) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the rows so far of 1 unit(s) stopped part-way" in err[0]
    store = RowStore(tmp_path)
    assert _measured(store) == [] and len(list(store.partial_dir.glob("rounds-*.json"))) == 1
    SUITES["rounds"].run.stop = None
    assert main([*argv, "--resume"]) == 0
    rows = _measured(store)
    assert [(r["query"], r["rounds"], r["stopped"]) for r in rows] == [
        (q, 1, f"after 1 of 2 rounds: {RESUMED}") for q in ("a", "b")]
    assert not any("stopped_status" in r for r in rows)  # measured rows of fewer rounds: ok
    assert rounds == ["rounds"]  # measured once: the resumed run recorded what the first kept
    assert list(store.partial_dir.iterdir()) == []


def test_a_fresh_run_moves_an_earlier_runs_partial_rows_aside(tmp_path, rounds, capsys):
    write_partial(partial_path(tmp_path / "partial", KEY), KEY, [{"query": "old", "rounds": 1}], "1 of 2 rounds")
    assert main([*ARGV, "--out", str(tmp_path)]) == 0
    assert [r["query"] for r in _measured(RowStore(tmp_path))] == ["a", "b"]  # measured, not the old rows
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("partial.")]
    assert len(aside) == 1 and len(list(aside[0].iterdir())) == 1
    assert "an earlier run that recorded no unit: its partial moved to" in capsys.readouterr().err


def test_a_damaged_or_foreign_partial_file_is_not_read(tmp_path):
    path = partial_path(tmp_path, KEY)
    write_partial(path, KEY, [{"query": "a"}], "1 of 2 rounds")
    assert read_partial(path, KEY) == ([{"query": "a"}], "1 of 2 rounds")
    assert read_partial(path, {**KEY, "seed": 1}) is None  # another unit's
    path.write_bytes(path.read_bytes()[:-5])
    assert read_partial(path, KEY) is None and path.exists()  # torn: left where it is
    assert partial_path(tmp_path, KEY) != partial_path(tmp_path, {**KEY, "config": "other"})


def test_the_verdict_tables_note_a_unit_stopped_part_way():
    import pandas as pd

    from harness.report.verdicts import verdicts

    row = {"suite": "verdict", "status": "ok", "case": "wscc9", "solver": "jax-pinn", "config": "default", "variant": "",
           "seed": 0, "query": "grid", "kind": "grid", "label": "no rival", "rivals_note": "none as accurate",
           "pinn_rel_l2_delta": 1e-3, "pinn_rel_l2_omega": 1e-3}
    frame = pd.DataFrame([{**row, "pinn_seed": 0, "stopped": f"after 1 of 2 rounds: {RESUMED}"},
                          {**row, "pinn_seed": 1, "stopped": f"after 1 of 2 rounds: {RESUMED}"}])
    assert verdicts({"verdict": frame})["note"].tolist() == [
        f"none as accurate; the unit stopped after 1 of 2 rounds: {RESUMED}"]
    assert verdicts({"verdict": frame.drop(columns="stopped")})["note"].tolist() == ["none as accurate"]
