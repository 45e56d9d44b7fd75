"""The README's verdicts and the site's results pages are generated from the rows; configurations
are named by one label function (`harness.report.labels.Labels`) in tables, plots and verdicts."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import pandas as pd
import pytest

from harness.cli import main
from harness.cli.compare import COMPARE_END, COMPARE_START, compare_block
from harness.cli.readme import (
    AT_SCALE_END,
    AT_SCALE_START,
    README_END,
    README_START,
    STEP_CLAIM_END,
    STEP_CLAIM_START,
)
from harness.report.files import write_report
from harness.report.labels import Labels, split_items
from harness.report.markdown import LADDER_HEADING
from harness.report.pages import GENERATED, at_scale_block, readme_block, step_claim_block, write_pages
from harness.store import RowStore

ROOT = Path(__file__).resolve().parent.parent


def _named_source(block: str) -> Path:
    """The results folder a generated block names as its source (its first `.../rows.jsonl`)."""
    return ROOT / re.search(r"`([^`]+)/rows\.jsonl`", block).group(1)


def test_the_readme_verdicts_are_what_the_report_writes_from_the_landed_rows():
    """No hand-typed figure can hide in the README's generated block: it must be, character for
    character, what `swingbench report DIR --update-readme README.md --docs PAGES` writes from the
    rows of the folder it names."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split(README_START, 1)[1].split(README_END, 1)[0]
    results = _named_source(block)
    rows = RowStore(results, create=False).read().rows
    meta = json.loads((results / "metadata.json").read_text(encoding="utf-8"))
    pages = ROOT / re.search(r"\]\(([^)]+)/[^/)]+\.md\)", block).group(1)  # the folder its case pages are in
    assert block == readme_block(rows, meta, ROOT / "README.md", pages, results)


def test_a_readme_block_with_verdicts_leaves_the_single_timing_sentences_to_the_case_pages():
    """The README's front door shows the matched, repeated verdicts only (their heat map and their
    summary): the latency suite's sentences (one timing a side) would contradict them, so they stay
    on the case pages under a heading that says what they are, beside the full verdict table."""
    results = ROOT / "results"
    rows = RowStore(results, create=False).read().rows
    meta = json.loads((results / "metadata.json").read_text(encoding="utf-8"))
    assert {row["suite"] for row in rows} >= {"verdict", "latency"}
    block = readme_block(rows, meta, ROOT / "README.md", ROOT / "docs" / "results", results)
    assert "figures/verdicts.png" in block and "- **wscc9**" in block
    assert "fastest PINN" not in block and LADDER_HEADING not in block
    assert "## Verdicts at matched accuracy" in (ROOT / "docs" / "results" / "index.md").read_text(encoding="utf-8")
    page = (ROOT / "docs" / "results" / "wscc9.md").read_text(encoding="utf-8")
    assert f"## {LADDER_HEADING}" in page and "fastest PINN" in page


def test_the_readme_comparison_of_two_runs_is_what_compare_writes():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split(COMPARE_START, 1)[1].split(COMPARE_END, 1)[0]
    run_a, run_b = (ROOT / source for source in re.findall(r"`([^`]+)/rows\.jsonl`", block))
    assert block == compare_block(run_a, run_b, ROOT, tables=False)


def test_the_readme_at_scale_verdicts_are_what_the_report_writes_from_their_rows():
    """The README's block of verdict runs apart from the bench is, character for character, what
    `swingbench report DIR ... --at-scale README.md` writes from the folders it names, in order."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split(AT_SCALE_START, 1)[1].split(AT_SCALE_END, 1)[0]
    folders = [ROOT / source for source in re.findall(r"From `([^`]+)/rows\.jsonl`", block)]
    assert folders
    runs = [(RowStore(f, create=False).read().rows, json.loads((f / "metadata.json").read_text(encoding="utf-8")), f)
            for f in folders]
    assert block == at_scale_block(runs, ROOT / "README.md")


def test_report_at_scale_writes_only_its_block_and_refuses_what_it_cannot_write(tmp_path, capsys):
    """`--at-scale` replaces its own block from several folders and touches nothing else; a folder
    without verdicts, several folders without it, or a README without its markers: one line, no write."""
    from harness.usage import EXIT_USAGE

    readme = tmp_path / "README.md"
    text = f"intro\n{README_START}\nbench\n{README_END}\n{AT_SCALE_START}\nold\n{AT_SCALE_END}\nend\n"
    readme.write_text(text)
    run = ROOT / "results" / "verdicts-case118"
    assert main(["report", str(run), str(run), "--at-scale", str(readme)]) == 0
    written = readme.read_text()
    assert written.startswith(f"intro\n{README_START}\nbench\n{README_END}\n") and written.endswith("end\n")
    assert "old" not in written and written.count("- **case118**, 11 queries") == 2
    (tmp_path / "bare.md").write_text("no markers\n")
    for argv, message in ((["report", str(ROOT / "results" / "pinnsim-claim"), "--at-scale", str(readme)],
                           "has no verdict rows and no PINN's CCT search"),
                          (["report", str(run), str(run)], "one DIR at a time"),
                          (["report", str(run), "--at-scale", str(tmp_path / "none.md")], "cannot read"),
                          (["report", str(run), "--at-scale", str(tmp_path / "bare.md")], "has no <!-- swingbench")):
        before = readme.read_text()
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == EXIT_USAGE and message in capsys.readouterr().err
        assert readme.read_text() == before


def test_the_at_scale_block_states_a_shared_machine_once_and_differing_ones_per_run():
    """Runs on the same machine, settings and libraries: their date and commit beside each answer and
    the rest once; runs on different machines: each run's whole line beside its answer."""
    folder = ROOT / "results" / "verdicts-case118"
    rows = RowStore(folder, create=False).read().rows
    meta = json.loads((folder / "metadata.json").read_text(encoding="utf-8"))
    shared = at_scale_block([(rows, meta, folder), (rows, meta, folder)], ROOT / "README.md")
    assert shared.count("Every run on ") == 1 and shared.count(f"commit {meta['commit']}.") == 2
    assert "Run of" not in shared
    (every,) = [line for line in shared.splitlines() if line.startswith("Every run on ")]
    assert meta["commit"] not in every and meta["date"] not in every and every.endswith(f"diffrax {meta['version_diffrax']}.")
    other = {**meta, "cpu": "another CPU"}
    apart = at_scale_block([(rows, meta, folder), (rows, other, folder)], ROOT / "README.md")
    assert "Every run on " not in apart and apart.count("Run of ") == 2 and "on another CPU" in apart


def test_the_readme_step_claim_is_what_the_report_writes_from_its_rows():
    """The README's step-claim block is, character for character, what `swingbench report DIR
    --step-claim README.md` writes from the folder it names: a bullet per case and the component
    network's one-step line."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split(STEP_CLAIM_START, 1)[1].split(STEP_CLAIM_END, 1)[0]
    (folder,) = [ROOT / source for source in re.findall(r"from `([^`]+)/rows\.jsonl`", block)]
    rows = RowStore(folder, create=False).read().rows
    meta = json.loads((folder / "metadata.json").read_text(encoding="utf-8"))
    assert block == step_claim_block(rows, meta, folder, ROOT / "README.md")
    assert "- **wscc9**: pinnsim" in block and "one-step error in delta" in block


def test_report_step_claim_writes_only_its_block_and_refuses_what_it_cannot_write(tmp_path, capsys):
    """`--step-claim` replaces its own block and nothing else; a folder without a trained step
    sweep, two folders, or the flag beside --at-scale: one line, no write."""
    from harness.usage import EXIT_USAGE

    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{STEP_CLAIM_START}\nold\n{STEP_CLAIM_END}\n{AT_SCALE_START}\n{AT_SCALE_END}\nend\n")
    claim, verdicts = ROOT / "results" / "pinnsim-claim", ROOT / "results" / "verdicts-case118"
    assert main(["report", str(claim), "--step-claim", str(readme)]) == 0
    written = readme.read_text()
    assert written.startswith(f"intro\n{STEP_CLAIM_START}\n_Generated") and written.endswith(f"{AT_SCALE_END}\nend\n")
    assert "old" not in written and "- **ieee39**: pinnsim" in written
    for argv, message in ((["report", str(verdicts), "--step-claim", str(readme)], "has no step sweep"),
                          (["report", str(claim), str(claim), "--step-claim", str(readme)], "one DIR"),
                          (["report", str(claim), "--step-claim", str(readme), "--at-scale", str(readme)],
                           "leave out")):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == EXIT_USAGE and message in capsys.readouterr().err
        assert readme.read_text() == written


def _frame(*specs: tuple[str, str, str]) -> pd.DataFrame:
    return pd.DataFrame([{"solver": s, "config": c, "variant": v} for s, c, v in specs])


def test_a_name_leaves_out_the_options_every_row_of_its_configuration_shares():
    rows = _frame(("jax-pinn", "marching", "id_max_seconds=120.0,max_seconds=120.0"),
                  ("jax-pinn", "marching", "id_max_seconds=120.0,max_seconds=120.0,query=numba"),
                  ("numba-rk", "rk4", ""), ("numba-rk", "rk4", "parallel=True"),
                  ("scipy-rk45", "default", ""), ("scipy-rk45", "default", "batch=stacked"))
    names = Labels({"latency": rows})
    assert names("jax-pinn [marching, id_max_seconds=120.0,max_seconds=120.0,query=numba]") == \
        "jax-pinn marching · numba query"
    assert names("jax-pinn [marching, id_max_seconds=120.0,max_seconds=120.0]") == "jax-pinn marching"
    assert names("numba-rk [rk4, parallel=True, dt=0.05]") == "numba-rk rk4 · parallel · dt=0.05"  # a sweep point
    assert names("scipy-rk45 [default, batch=stacked]") == "scipy-rk45 default · stacked batch"
    assert names("scipy-rk45 [default]") == "scipy-rk45 default"
    assert names.note() == ("Names leave out the options that every row of a configuration shares: "
                            "jax-pinn marching: id_max_seconds=120.0, max_seconds=120.0.")
    # keys inside text: ladder cells and verdict sentences; not a spec of these rows: as it is
    assert names.text("numba-rk [rk4, parallel=True]: 6 ms (PINN 1.4x faster)", "`{}`") == \
        "`numba-rk rk4 · parallel`: 6 ms (PINN 1.4x faster)"
    assert names.text("torch-pinn [default] 1 ms; median [min, max] 8.27e-06 [1e-06, 2e-05]") == \
        "torch-pinn [default] 1 ms; median [min, max] 8.27e-06 [1e-06, 2e-05]"
    table = names.table(pd.DataFrame({"solver": ["numba-rk [rk4]"], "ms": [1.5]}))
    assert table.to_dict("list") == {"solver": ["numba-rk rk4"], "ms": [1.5]}


def test_a_shared_option_is_kept_where_the_rows_differ_in_it_and_values_may_be_lists():
    rows = _frame(("torch-pinn", "default", "max_iterations=20,widths=[10, 20]"),
                  ("torch-pinn", "default", "max_iterations=50,widths=[10, 20],device=cuda"),
                  ("torch-pinn", "paper", "optimizer=lbfgs,max_seconds=None"))
    names = Labels(rows)
    assert split_items("max_iterations=20,widths=[10, 20]") == ["max_iterations=20", "widths=[10, 20]"]
    assert names("torch-pinn [default, max_iterations=50,widths=[10, 20],device=cuda]") == \
        "torch-pinn default · max_iterations=50 · cuda device"
    assert names("torch-pinn [paper, optimizer=lbfgs,max_seconds=None]") == "torch-pinn paper"
    assert "torch-pinn paper: max_seconds=None, optimizer=lbfgs" in names.note()


def test_the_report_writes_a_page_per_case_and_replaces_only_its_own_pages(tmp_path):
    base = {"variant": "", "threads": 2, "status": "ok", "seed": -1}
    rows = [{"suite": "accuracy", "case": case, "solver": "scipy-odeint", "config": "default", **base,
             "quantity": "delta", "against": "reference", "rel_l2": 1e-4, "max_abs": 1e-4,
             "worst_trajectory_rel_l2": 2e-4} for case in ("smib-inference", "wscc9")]
    results, pages = tmp_path / "results", tmp_path / "docs" / "results"
    pages.mkdir(parents=True)
    (pages / "ieee39.md").write_text(f"{GENERATED}\nan earlier run's case\n")
    (pages / "notes.md").write_text("written by hand\n")
    write_report(rows, results, {"threads": 2}, plots=False)
    written = write_pages(rows, {"threads": 2}, pages, results)
    assert sorted(p.name for p in written) == ["index.md", "smib-inference.md", "wscc9.md"]
    assert not (pages / "ieee39.md").exists() and (pages / "notes.md").exists()
    page = (pages / "wscc9.md").read_text()
    assert page.startswith(f"{GENERATED}\n# Results: wscc9\n") and "| wscc9  | scipy-odeint default |" in page
    assert "[wscc9](wscc9.md)" in (pages / "index.md").read_text()
    # the same through the command line, into the README's block
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{README_START}\nold\n{README_END}\n")
    (results / "rows.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    assert main(["report", str(results), "--update-readme", str(readme)]) == 0
    text = readme.read_text()
    assert "[smib-inference](docs/results/smib-inference.md)" in text and "old" not in text
    meta = json.loads((results / "metadata.json").read_text())
    assert text == f"intro\n{README_START}{readme_block(rows, meta, readme, pages, results)}{README_END}\n"



def test_a_verdict_s_rival_is_named_like_a_spec_of_the_rows_every_option_shown():
    rows = _frame(("jax-pinn", "marching", "max_iterations=100")).assign(rival="numba-rk [rk4, parallel=True, dt=0.2]")
    names = Labels({"verdict": rows})
    assert names("numba-rk [rk4, parallel=True, dt=0.2]") == "numba-rk rk4 · parallel · dt=0.2"
    assert names("jax-pinn [marching, max_iterations=100]") == "jax-pinn marching"


def test_the_coverage_table_of_the_methods_page_is_the_rows_of_its_csv():
    """docs/methods.md's table of interval coverage across runs quotes results/interval-coverage.csv
    (written by scripts/interval_coverage.py, whose --table prints the lines), row for row."""
    spec = importlib.util.spec_from_file_location("interval_coverage", ROOT / "scripts" / "interval_coverage.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    page = (ROOT / "docs" / "methods.md").read_text(encoding="utf-8")
    table = page.split("<!-- coverage rows:", 1)[1].split("\n\n", 1)[0].splitlines()[1:]
    rows = pd.read_csv(ROOT / "results" / "interval-coverage.csv")
    assert len(rows) >= 3 and table == script.table_lines(rows)


def _outside_generated(text: str) -> str:
    """`text` without its generated blocks (between swingbench's start and end markers) and code."""
    text = re.sub(r"<!-- swingbench:([\w-]+):start -->.*?<!-- swingbench:\1:end -->", "", text, flags=re.DOTALL)
    return re.sub(r"```.*?```", "", text, flags=re.DOTALL)


def test_the_readme_is_short_shows_the_verdicts_first_and_types_no_number():
    """The front door: at most 120 lines, the verdicts' heat map within the first 30, no line over
    120 characters and no number outside the generated blocks (inline code and link targets aside:
    a number there is a name, not a figure)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = readme.splitlines()
    assert len(lines) <= 120
    assert any("figures/verdicts.png" in line for line in lines[:30])
    prose = _outside_generated(readme)
    assert [line for line in prose.splitlines() if len(line) > 120] == []
    prose = re.sub(r"`[^`]*`", "", re.sub(r"\]\([^)]*\)", "]", prose))
    assert re.findall(r"(?<![\w.-])\d[\d.,]*", prose) == []
