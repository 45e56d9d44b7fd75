"""`swingbench list`: every section lists what the registries hold; bad names are one line, exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import solvers
from harness.cli import main
from harness.usage import EXIT_USAGE

ROOT = Path(__file__).resolve().parents[1]


def listed(capsys, *argv: str) -> list[str]:
    assert main(["list", *argv]) == 0
    return capsys.readouterr().out.splitlines()


def line_of(lines: list[str], name: str) -> str:
    return next(line for line in lines if line.split()[:1] == [name])


def test_cases_give_kind_machines_scenario_and_range(capsys):
    lines = listed(capsys, "cases", "--case", "smib-inference", "wscc9", "wscc9-bus8-line8-9")
    assert line_of(lines, "wscc9").split()[1:4] == ["network", "3", "machines"]
    assert "P1 (generator 1's mechanical power) in [0.08, 0.18] p.u." in line_of(lines, "smib-inference")
    assert line_of(lines, "smib-inference").split()[1:4] == ["smib", "1", "machine"]
    fault = line_of(lines, "wscc9-bus8-line8-9")
    assert "t_c (clearing time) in [0.05, 0.4] s" in fault and "fault bus8-line8-9" in fault


def test_solvers_give_capabilities_and_why_one_is_skipped(capsys, monkeypatch):
    monkeypatch.setitem(solvers.SOLVERS, "not-installed", None)
    monkeypatch.setitem(solvers.UNAVAILABLE, "not-installed", "skipped: nothing not installed")
    lines = listed(capsys, "solvers", "--solver", "numba-rk", "not-installed")
    capabilities = line_of(lines, "numba-rk").split("; ")[0].split(None, 1)[1].split(", ")
    assert {"has_tolerance", "compiled", "handles_faults"} <= set(capabilities) and "trains" not in capabilities
    assert line_of(lines, "not-installed").endswith("skipped: nothing not installed")


def test_configs_give_overrides_and_marks(capsys):
    lines = listed(capsys, "configs", "--solver", "numba-rk")
    assert line_of(lines, "tight").split(None, 1)[1] == "rtol=1e-10, atol=1e-12 [identifies networks, sweep point]"
    assert line_of(lines, "rk4").split(None, 1)[1] == "method='rk4'"
    assert line_of(lines, "default").split(None, 1)[1] == "the schema's defaults"


def test_options_give_type_range_and_default_from_the_schema(capsys):
    lines = listed(capsys, "options", "--solver", "numba-rk")
    assert line_of(lines, "rtol").split(None, 1)[1] == "a positive finite number; default 0.001"
    assert line_of(lines, "method").split(None, 1)[1] == "one of 'rk4', 'dopri5', 'dop853'; default 'dop853'"
    assert [line.split()[0] for line in lines[2:]] == list(solvers.SOLVERS["numba-rk"].OPTIONS)


def test_suites_say_whether_they_are_default_with_their_first_sentence(capsys):
    from harness.suites import SUITES

    lines = listed(capsys, "suites")
    assert [line.split()[0] for line in lines[1:]] == list(SUITES)
    assert line_of(lines, "scaling").split(None, 1)[1] == (
        "named only: Cost and accuracy against the size of the grid: one row per adapter and case.")
    assert line_of(lines, "accuracy").split()[1] == "default:"


@pytest.mark.parametrize("argv,message", [
    (["bogus"], "swingbench list: unknown section 'bogus'; known: cases, solvers, configs, options, suites"),
    (["options", "--solver", "rk4"], "swingbench list: unknown solver(s) 'rk4'; known: scipy-rk45"),
    (["cases", "--case", "ieee300"], "swingbench list: unknown case(s) 'ieee300'; known: smib-inference"),
])
def test_an_unknown_section_or_name_is_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as info:
        main(["list", *argv])
    err = capsys.readouterr().err
    assert info.value.code == EXIT_USAGE and err.count("\n") == 1 and err.startswith(message)


def test_building_the_parser_imports_no_numpy_pandas_or_matplotlib():
    probe = ("import sys; from harness.cli import _parser; _parser(); "
             "print(sorted(m for m in ('numpy', 'pandas', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    assert out == "[]\n"
