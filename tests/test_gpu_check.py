"""scripts/gpu_check.sh, which CI never runs (it needs a GPU): its shell parses, and the harness
commands it would run (`--dry-run`), on the GPU and in its CPU test mode, are what
`swingbench run` accepts: its parser, and suites, adapters, configs, cases and options it knows."""

from __future__ import annotations

import os
import shlex
import subprocess
from pathlib import Path

import pytest

from harness.cli import _parser
from harness.cli.run import _suite_names
from harness.run.selection import default_specs, parse_option, with_options
from solvers import SOLVERS
from systems.cases import CASES

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "gpu_check.sh"


def _dry_run(*flags: str, **env: str) -> list[list[str]]:
    """The harness command lines `gpu_check.sh --dry-run` prints, each as argv after `harness`."""
    done = subprocess.run(["bash", str(SCRIPT), "--dry-run", *flags], cwd=ROOT, capture_output=True, text=True,
                          check=True, env={**os.environ, **env})
    lines = [shlex.split(line) for line in done.stdout.splitlines()]
    assert lines and all(line[0] == "harness" for line in lines), done.stdout
    return [line[1:] for line in lines]


@pytest.mark.parametrize("script", ["gpu_check.sh", "gpu_wheels.sh"])
def test_the_scripts_parse(script):
    subprocess.run(["bash", "-n", str(ROOT / "scripts" / script)], check=True)


@pytest.mark.parametrize("flags, folder", [((), "results/gpu/"), (("--cpu", "--quick"), ".cache/gpu-check-cpu/")])
def test_each_planned_run_is_one_the_harness_accepts(flags, folder):
    runs = _dry_run(*flags)
    assert [args.solver for args in map(_parser().parse_args, runs)] == [["jax-pinn"], ["reduced-pinn"]]
    for argv in runs:
        args = _parser().parse_args(argv)
        assert args.command == "run" and args.unit_seconds > 0 and args.overwrite
        assert set(args.suite) <= set(_suite_names()) and set(args.case) <= set(CASES)
        assert set(args.config) <= set(SOLVERS[args.solver[0]].CONFIGS)
        specs = with_options(default_specs(args.solver, args.config), dict(map(parse_option, args.option)))
        assert specs  # every option belongs to the adapter (with_options raises otherwise)
        assert str(args.out).startswith(folder)
    gpu = "--cpu" not in flags
    assert ("device=gpu" in runs[0]) is gpu  # jax-pinn trains on the GPU; reduced-pinn computes on JAX's default


def test_the_cpu_mode_writes_no_rows_into_the_gpu_folder():
    done = subprocess.run(["bash", str(SCRIPT), "--cpu", "--dry-run"], cwd=ROOT, capture_output=True, text=True, check=False,
                          env={**os.environ, "GPU_CHECK_OUT": "results/gpu"})
    assert done.returncode == 2 and "results/gpu/" in done.stderr


def test_the_docs_gpu_table_is_the_one_the_rows_give():
    """docs/scaling.md's table of the GPU check is what `gpu_check_rows.py table` writes from the
    committed rows (the command is on the page)."""
    import importlib.util
    import re

    spec = importlib.util.spec_from_file_location("gpu_check_rows", ROOT / "scripts" / "gpu_check_rows.py")
    rows = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rows)
    page = (ROOT / "docs" / "scaling.md").read_text(encoding="utf-8")
    block = page.split(rows.GPU_START, 1)[1].split(rows.GPU_END, 1)[0]
    command = re.search(r"`python scripts/gpu_check_rows.py table (.*?) --update", page, flags=re.DOTALL).group(1)
    gpu, cpu = command.split(" --cpu ")
    expected = rows.table([ROOT / f for f in gpu.split()], [ROOT / f for f in cpu.split()])
    assert block == "\n" + expected
    assert "NVIDIA H200" in block
