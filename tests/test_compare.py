"""`swingbench compare` of any two runs: each query both measured, its medians over seeds and B / A."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from harness.cli import main
from harness.cli.compare import _frames, queries_in_both
from harness.usage import EXIT_USAGE


def write_run(folder: Path, rows: list[dict]) -> Path:
    folder.mkdir()
    (folder / "rows.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    return folder


def latency(solver: str, query: str, median_s: float | None, seed: int = -1, status: str = "ok") -> dict:
    row = {"suite": "latency", "case": "wscc9", "solver": solver, "config": "default", "variant": "", "seed": seed,
           "status": status, "kind": "grid", "query": query}
    return {**row, "median_s": median_s} if median_s is not None else row


def accuracy(quantity: str, rel_l2: float) -> dict:
    return {"suite": "accuracy", "case": "wscc9", "solver": "numba-rk", "config": "default", "variant": "",
            "seed": -1, "status": "ok", "quantity": quantity, "against": "reference", "rel_l2": rel_l2}


@pytest.fixture
def runs(tmp_path) -> tuple[Path, Path]:
    a = write_run(tmp_path / "a", [
        latency("numba-rk", "grid 100x201", 0.01), latency("numba-rk", "single point t1=10 s", 0.002),
        latency("jax-pinn", "grid 100x201", 0.1, seed=0), latency("jax-pinn", "grid 100x201", 0.3, seed=1),
        latency("numba-rk", "only in A", 1.0), accuracy("delta", 1e-3)])
    b = write_run(tmp_path / "b", [
        latency("numba-rk", "grid 100x201", 0.02), latency("numba-rk", "single point t1=10 s", None, status="skipped: x"),
        latency("jax-pinn", "grid 100x201", 0.4, seed=0), latency("jax-pinn", "grid 100x201", 0.6, seed=1),
        accuracy("delta", 2e-3), accuracy("omega", 1e-2)])
    return a, b


def test_every_query_both_runs_measured_has_both_medians_over_seeds_and_the_ratio(runs):
    both = queries_in_both(_frames(runs[0]), _frames(runs[1]))
    got = {(r["suite"], r["configuration"], r["query"]): (r["median A"], r["median B"], r["ratio"])
           for _, r in both.iterrows()}
    assert got == {("latency", "numba-rk [default]", "grid 100x201"): (0.01, 0.02, pytest.approx(2.0)),
                   ("latency", "jax-pinn [default]", "grid 100x201"): (0.2, 0.5, pytest.approx(2.5)),
                   ("accuracy", "numba-rk [default]", "delta against reference"): (1e-3, 2e-3, pytest.approx(2.0))}


def test_compare_prints_the_queries_and_says_when_the_runs_have_no_verdicts(runs, capsys):
    assert main(["compare", str(runs[0]), str(runs[1])]) == 0
    out = capsys.readouterr().out
    assert "latency: 2 queries in both runs; B / A of the medians 2.25 (median), from 2 to 2.5." in out
    cells = [[cell.strip() for cell in line.strip("|").split("|")] for line in out.splitlines() if line.startswith("|")]
    assert ["latency", "wscc9", "jax-pinn default", "grid 100x201", "median_s", "0.2", "0.5", "2.5"] in cells
    assert "No verdicts in both runs (run A has no verdict rows)." in out


def test_runs_that_share_neither_queries_nor_verdicts_are_one_line_and_exit_2(tmp_path, capsys):
    a = write_run(tmp_path / "a", [latency("numba-rk", "grid 100x201", 0.01)])
    b = write_run(tmp_path / "b", [latency("numba-rk", "another query", 0.01)])
    with pytest.raises(SystemExit) as info:
        main(["compare", str(a), str(b)])
    err = capsys.readouterr().err
    assert info.value.code == EXIT_USAGE and err.count("\n") == 1 and "share no latency or accuracy query" in err


def test_update_readme_replaces_the_comparison_section_alone_and_refuses_a_readme_without_one(runs, tmp_path, capsys):
    from harness.cli.compare import COMPARE_END, COMPARE_START, compare_block

    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{COMPARE_START}\nold\n{COMPARE_END}\nend\n")
    assert main(["compare", str(runs[0]), str(runs[1]), "--update-readme", str(readme)]) == 0
    printed = capsys.readouterr().out[:-1]  # print's newline: the whole comparison, its tables too
    summary = compare_block(runs[0], runs[1], tmp_path, tables=False)  # the README gets the summary alone
    assert printed == compare_block(runs[0], runs[1], tmp_path) and summary != printed
    assert readme.read_text() == f"intro\n{COMPARE_START}{summary}{COMPARE_END}\nend\n"
    readme.write_text("no section\n")
    with pytest.raises(SystemExit) as info:
        main(["compare", str(runs[0]), str(runs[1]), "--update-readme", str(readme)])
    assert info.value.code == EXIT_USAGE and "has no <!-- swingbench:compare:start -->" in capsys.readouterr().err
