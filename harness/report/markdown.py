"""The report's text, shared by `tables.md` (`harness.report.files`) and the documentation pages
(`harness.report.pages`): the run's lines (`header`, `work_minutes`), a case's section
(`section_markdown`: the options its names leave out, its verdicts, its tables) and the scaling
section (`scaling_markdown`).
"""

from __future__ import annotations

import pandas as pd

from harness.report.labels import Labels
from harness.report.ladder import verdict_lines
from harness.report.scaling import break_even_by_n, exponents, scaling_frame, scaling_table, status_by_n
from harness.store import unit_key

__all__ = ["LADDER_ABOUT", "LADDER_HEADING", "header", "scaling_labels", "scaling_markdown", "section_markdown", "table_markdown",
           "verdict_markdown", "work_minutes"]


def header(meta: dict) -> str:
    """The run's line: date, CPU, threads, commit, settings and library versions."""
    return f"Run of {meta.get('date', '?')} on {environment(meta)}.\n\n"


def environment(meta: dict, commit: bool = True) -> str:
    """The run's CPU, threads, commit (unless `commit` is False), settings and library versions."""
    get = lambda key: meta.get(key, "?")
    return (f"{get('cpu')} ({get('threads')} threads)" + (f", commit {get('commit')}" if commit else "")
            + f", settings {get('settings')}; numpy {get('version_numpy')}, scipy {get('version_scipy')}, "
            f"casadi {get('version_casadi')}, torch {get('version_torch')}, jax {get('version_jax')}, "
            f"numba {get('version_numba')}, diffrax {get('version_diffrax')}")


def work_minutes(rows: list[dict]) -> str:
    """One line: the wall time of the run's units of work (their rows' `work_s`, each unit once),
    by case and in all, in minutes; "" for rows without it (written before it was recorded)."""
    seconds: dict[str, float] = {}
    timed, units = set(), set()
    for row in rows:
        key = unit_key(row)
        units.add(key)
        if row.get("work_s") is not None and key not in timed:
            timed.add(key)
            seconds[row["case"]] = seconds.get(row["case"], 0.0) + float(row["work_s"])
    if not seconds:
        return ""
    parts = ", ".join(f"{case} {s / 60:.1f}" for case, s in seconds.items())
    some = "" if timed == units else f" (only {len(timed)} of its {len(units)} units recorded it: older rows have none)"
    return f"Wall time of its units of work, minutes: {parts}; {sum(seconds.values()) / 60:.1f} in all{some}.\n\n"


def table_markdown(level: str, heading: str, about: str, table: pd.DataFrame) -> str:
    """One table under a short heading of `level`, what it holds (`about`) in a paragraph between."""
    return f"{level} {heading}\n\n" + (f"{about}\n\n" if about else "") + f"{table.to_markdown(index=False)}\n"


def section_markdown(name: str, frames: dict, tables: dict, level: str = "###", heading: str | None = None) -> str:
    """A case's section: its heading (`heading`, default "Case <name>"), the options its names leave
    out, its verdicts and every table of `tables` (`build_tables`: heading, about, table), each
    configuration named by `harness.report.labels.Labels` of the case's rows."""
    labels = Labels(frames)
    return (f"{level[:-1]} {heading or f'Case {name}'}\n\n" + verdict_markdown(frames, labels, level)
            + "\n".join(table_markdown(level, title, about, labels.table(table))
                        for title, about, table in tables.values()))


# The ladder's sentences time each side once, in the latency suite: not the verdict suite's verdicts.
LADDER_HEADING = "Fastest of each side"
LADDER_ABOUT = "Timed once each in the latency suite: single timings, not verdicts."


def verdict_markdown(frames: dict, labels: Labels | None = None, level: str | None = "###") -> str:
    """The note on the options left out of the names, then the verdict sentences of a case as a
    list, under a heading of `level` (None: no heading); "" for a case with neither."""
    labels = labels or Labels(frames)
    note = labels.note()
    lines = verdict_lines(frames)
    head = f"{level} {LADDER_HEADING}\n\n{LADDER_ABOUT}\n\n" if lines and level else ""
    return ((f"{note}\n\n" if note else "")
            + (head + "".join(f"- {labels.text(line, '`{}`')}\n" for line in lines) + "\n" if lines else ""))


def scaling_labels(frames: dict) -> Labels:
    """The names of the scaling section: the options every scaling unit of a configuration shares
    (the suite's training budget) are left out."""
    return Labels({suite: df for suite, df in frames.items() if suite in ("scaling", "fit")})


def scaling_markdown(frames: dict, level: str = "###") -> str:
    """The scaling section ("" when the run has no scaling rows): cost, memory and accuracy per
    adapter and N, fitted exponents, break-even trajectories of each PINN, units that did not fit."""
    frame = scaling_frame(frames)
    tables = [("Cost, memory and accuracy", "Against the number of machines N.", scaling_table(frame)),
              ("Fitted exponents", "b of cost ~ N^b (least squares in log-log, N >= 2).", exponents(frame)),
              ("Break-even", "The trajectories after which a PINN's preparation pays off.", break_even_by_n(frame)),
              ("Unfinished units", "Units that did not run to the end.", status_by_n(frames))]
    tables = [table for table in tables if not table[2].empty]
    if not tables:
        return ""
    labels = scaling_labels(frames)
    scaling = frames.get("scaling", pd.DataFrame(columns=["solver", "config"]))
    note = labels.note(set(zip(scaling["solver"], scaling["config"])))
    return (f"\n{level[:-1]} Scaling\n\n" + (f"{note}\n\n" if note else "")
            + "\n".join(table_markdown(level, title, about, labels.table(table)) for title, about, table in tables))
