"""The command line: its parser, its help, and what `run` and `report` do end to end on cheap solvers."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import solvers
from harness.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_building_the_parser_imports_no_numerical_library():
    """`swingbench --help` and every command's parser need the standard library, the CLI's modules and
    the solver registry's names only: none of numpy, pandas, scipy or matplotlib (a fresh interpreter)."""
    code = ("import sys\nfrom harness.cli import _parser\n_parser()\n"
            "print(sorted({'numpy', 'pandas', 'scipy', 'matplotlib'} & set(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


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


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_an_executor_that_cannot_be_had_is_a_usage_error(command, tmp_path, capsys, monkeypatch):
    """The runner says why Dask cannot be had (`ExecutorUnavailable`); the command says it as one
    line on stderr and exits 2, before any unit runs."""
    if solvers.SOLVERS.get("casadi-cvodes") is None:
        pytest.skip("casadi-cvodes is not installed")
    monkeypatch.setitem(sys.modules, "distributed", None)  # `from distributed import ...` raises ImportError
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"solver": "casadi-cvodes", "grid": {"rtol": [1e-6]}}))
    out = tmp_path / "out"
    argv = {"run": ["run", "--quick", "--progress", "off", "--case", "smib-inference", "--solver", "casadi-cvodes",
                    "--config", "default", "--suite", "accuracy"],
            "sweep": ["sweep", str(spec), "--progress", "off"]}[command]
    with pytest.raises(SystemExit) as info:
        main([*argv, "--dask-local", "--out", str(out)])
    assert info.value.code == 2
    captured = capsys.readouterr()
    assert captured.err.strip().splitlines()[-1] == ("swingbench: --scheduler/--dask-local need dask.distributed: "
                                                     "pip install 'swingbench[dask]'")
    assert "Traceback" not in captured.err and not (out / "rows.jsonl").exists()  # nothing measured
