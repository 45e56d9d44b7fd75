"""Rows -> tidy CSV per suite, Markdown and LaTeX tables, plots, results/README.md.

Nothing here measures anything: every figure comes from the rows of one run, so `swingbench
report DIR` re-renders the same tables and plots from `DIR/rows.jsonl`. The tables are built by
`harness.report.tables`, the Markdown text by `harness.report.markdown`; this module writes the files.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from harness.report.frames import case_sections, suite_frames
from harness.report.labels import Labels
from harness.report.ladder import ladder_rows
from harness.report.markdown import header, scaling_labels, scaling_markdown, section_markdown, work_minutes
from harness.report.plots import SCALING_PLOTS
from harness.report.scaling import scaling_frame
from harness.report.step_claim import step_claim_markdown
from harness.report.tables import build_tables
from harness.report.verdicts import restated
from solvers.atomic import atomic_write

__all__ = ["write_report", "write_script_rows"]

TRAJECTORY_COLUMNS = ("best_pred", "best_ref", "worst_pred", "worst_ref", "traj_t", "traj_pred", "traj_ref")


def write_script_rows(out_dir: Path, stem: str, rows: list[dict], record: dict) -> None:
    """A script's rows as `out_dir/<stem>.csv` (tidy: the union of their keys, in order of first
    appearance; a missing value empty) and `record` (its command and what it fitted) as
    `out_dir/<stem>.json`, each atomically; out_dir made if missing."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write(out_dir / f"{stem}.csv", pd.DataFrame(rows).to_csv(index=False))
    atomic_write(out_dir / f"{stem}.json", json.dumps(record, indent=1) + "\n")


def write_report(rows: list[dict], out_dir: Path, meta: dict, plots: bool = True) -> str:
    """Write `<suite>.csv` (tidy, one row per measurement, every case; the verdicts' intervals and
    labels under the current rule, `restated`), `tables.md`, `tables.tex`,
    the plots (of each case, `<plot>-<case>.png` when the run has several), `README.md` and
    `metadata.json` to `out_dir`, each atomically; return the Markdown."""
    out_dir = Path(out_dir)
    frames = suite_frames(rows)
    for suite, df in frames.items():
        df = restated(df) if suite == "verdict" else df  # intervals and labels as the tables state them
        csv = df.drop(columns=[c for c in TRAJECTORY_COLUMNS if c in df])
        atomic_write(out_dir / f"{suite}.csv", csv.to_csv(index=False))
    sections = [(name, own, build_tables(own)) for name, own in case_sections(frames)]
    steps = pd.concat([ladder_rows(own, fastest_per_config=False).assign(case=name) for name, own, _ in sections]
                      or [pd.DataFrame()], ignore_index=True)
    if not steps.empty:
        atomic_write(out_dir / "ladder.csv", steps.to_csv(index=False))
    markdown = header(meta) + work_minutes(rows) + "\n".join(section_markdown(name, own, tables)
                                                        for name, own, tables in sections)
    markdown += scaling_markdown(frames) + step_claim_markdown(frames, out_dir)
    latex = "\n".join(_latex(name, Labels(own), tables) for name, own, tables in sections)
    atomic_write(out_dir / "tables.md", markdown)
    atomic_write(out_dir / "tables.tex", latex)
    atomic_write(out_dir / "metadata.json", json.dumps(meta, indent=2, default=str))
    figures = []
    if plots:
        from harness.report.plots import PLOTS, VERDICT_PLOTS, make_plots

        _remove_old_plots(out_dir, (*PLOTS, *SCALING_PLOTS, *VERDICT_PLOTS))
        for name, own, _ in sections:
            figures += make_plots(own, out_dir, suffix=f"-{name}" if len(sections) > 1 else "")
        figures += make_plots({"scaling_frame": scaling_frame(frames)}, out_dir, names=SCALING_PLOTS,
                              labels=scaling_labels(frames))
        figures += make_plots(frames, out_dir, names=VERDICT_PLOTS)
    atomic_write(out_dir / "README.md", _results_readme(meta, frames, markdown, figures))
    return markdown


def _remove_old_plots(out_dir: Path, names: tuple[str, ...]) -> None:
    """Delete the figures of the plots `names` in `out_dir` (`<plot>.png`, `<plot>-<case>.pdf`, ...):
    a previous run's, of cases this run may not have."""
    for old in (*out_dir.glob("*.png"), *out_dir.glob("*.pdf")):
        if old.stem.split("-", 1)[0] in names:
            old.unlink()


def _latex(name: str, labels: Labels, tables: dict) -> str:
    """A case's tables in LaTeX, each after a comment with its case and title; the options left
    out of the names in a comment first."""
    note = labels.note()
    return (f"% {name}: {note}\n" if note else "") + "\n".join(
        f"% {name}: {title}" + (f". {about}" if about else "") + f"\n{labels.table(table).to_latex(index=False, escape=True)}"
        for title, about, table in tables.values())


def _results_readme(meta: dict, frames: dict, markdown: str, figures: list[str]) -> str:
    lines = ["# swingbench results", "",
             "Generated by `swingbench run` (re-render with `swingbench report DIR`); do not edit by hand.",
             "", "## Run", ""]
    lines += [f"- {key}: {value}" for key, value in meta.items()]
    lines += ["", "## Files", "",
              "- `rows.jsonl`: every row as measured (the source of everything else)",
              *(f"- `{suite}.csv`: tidy rows of the {suite} suite" for suite in frames),
              "- `tables.md`, `tables.tex`: the tables below, Markdown and LaTeX",
              "- `ladder.csv`: the verdict ladder of every PINN spec, query and case",
              *(f"- `{name}.png`, `{name}.pdf`" for name in figures),
              "", "## Tables", "", markdown.split("\n\n", 1)[1] if "\n\n" in markdown else markdown]
    lines += [f"![{name}]({name}.png)" for name in figures]
    return "\n".join(lines) + "\n"
