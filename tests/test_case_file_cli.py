"""`swingbench run --case-file PATH [--machines CSV] [--fault BUS:A-B]`: the suites run on a grid
from a file like on a built-in case; a bad file, machine row or contingency is one line, exit 2."""

from __future__ import annotations

import pytest

from harness.cli import main
from harness.store import RowStore
from systems.cases import CASES
from tests.test_case_file import GOOD, WRITERS, case9, write_csv, write_json

RUN = ["run", "--quick", "--progress", "off", "--solver", "scipy-rk45", "--config", "default"]


@pytest.fixture(autouse=True)
def scratch_registry(monkeypatch):
    """The cases a test registers are gone after it."""
    monkeypatch.setattr(CASES, "_builders", dict(CASES._builders))
    monkeypatch.setattr(CASES, "_built", dict(CASES._built))


def rows(out) -> list[dict]:
    return RowStore(out, create=False).read().rows


# each file's accuracy suite integrates its new case's reference (100 P1 x 201 times at 1e-12): ~20 s
@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".json", ".m", ".mat"])
def test_accuracy_and_latency_run_on_a_case_file(tmp_path, suffix):
    path = WRITERS[suffix](case9(), tmp_path / f"mine{suffix}")
    out = tmp_path / "out"
    assert main([*RUN, "--case-file", str(path), "--suite", "accuracy", "latency", "--out", str(out)]) == 0
    ok = {(r["suite"], r["case"]) for r in rows(out) if r["status"] == "ok"}
    assert {("accuracy", "mine"), ("latency", "mine")} <= ok
    assert not [r for r in rows(out) if r["status"].startswith("failed")]


@pytest.mark.slow
def test_cct_runs_on_the_fault_cases_of_a_case_file(tmp_path):
    path = write_json(case9(), tmp_path / "grid.json")
    machines = write_csv(tmp_path / "machines.csv", GOOD)
    out = tmp_path / "out"
    assert main([*RUN, "--case-file", str(path), "--machines", str(machines), "--case-name", "g9", "--fault", "8:8-9",
                 "--suite", "cct", "--out", str(out)]) == 0
    cct = [r for r in rows(out) if r["suite"] == "cct" and r["case"] == "g9-bus8-line8-9"]
    assert cct and all(r["status"] == "ok" for r in cct)


@pytest.mark.parametrize(("extra", "message"), [
    (["--case-file", "{tmp}/absent.json"], "swingbench run: --case-file {tmp}/absent.json: no such file"),
    (["--case-file", "{tmp}/grid.txt"], "swingbench run: --case-file {tmp}/grid.txt: unknown suffix '.txt'"),
    (["--case-file", "{tmp}/grid.json", "--machines", "{tmp}/bad.csv"],
     "swingbench run: --case-file {tmp}/bad.csv:3: bus 5 has no in-service generator"),
    (["--case-file", "{tmp}/grid.json", "--fault", "8:8-9x"], "swingbench run: --fault '8:8-9x' is not BUS:A-B"),
    (["--case-file", "{tmp}/grid.json", "--fault", "8:4-5"],
     "swingbench run: --fault Contingency 'bus8-line4-5': line 4-5 does not touch the faulted bus 8"),
    (["--case-file", "{tmp}/grid.json", "--fault", "1:1-4"],
     "swingbench run: --case-file {tmp}/grid.json: Contingency 'bus1-line1-4': opening line 1-4 splits the network"),
    (["--case-file", "{tmp}/grid.json", "--case-name", "wscc9"], "swingbench run: --case-file: case name 'wscc9' is taken"),
    (["--machines", "{tmp}/bad.csv"], "swingbench run: --machines need(s) --case-file"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, extra, message):
    write_json(case9(), tmp_path / "grid.json")
    write_csv(tmp_path / "bad.csv", GOOD.replace("2,4,0.3,4", "5,4,0.3,4"))
    (tmp_path / "grid.txt").write_text("", encoding="utf-8")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main([*RUN, *(x.format(tmp=tmp_path) for x in extra), "--suite", "accuracy", "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(message.format(tmp=tmp_path))
    assert not out.exists()


def test_a_sweep_spec_names_the_case_of_a_case_file(tmp_path, capsys):
    path = write_json(case9(), tmp_path / "grid.json")
    spec = tmp_path / "spec.json"
    spec.write_text('{"solver": "scipy-rk45", "cases": ["swept"]}', encoding="utf-8")
    assert main(["sweep", str(spec), "--case-file", str(path), "--case-name", "swept", "--dry-run"]) == 0
    assert capsys.readouterr().out.split() == ["scipy-rk45[default]", "swept"]
