"""Rows -> tidy CSV per suite, Markdown and LaTeX tables, plots, results/README.md.

Nothing here measures anything: every figure comes from the rows of one run, so `swingbench
report DIR` re-renders the same tables and plots from `DIR/rows.jsonl`.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import subprocess
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from harness.analysis import (
    COI_DELTA,
    GRID_QUERY,
    POINT_QUERY,
    break_even,
    fastest_classical,
    fmt,
    fmt_range,
    identification_data,
    label,
    ladder,
    matched_speedups,
    ok,
    trained,
)
from harness.labels import Labels
from harness.paper import paper_table
from harness.plots import SCALING_PLOTS
from harness.scaling_tables import break_even_by_n, exponents, scaling_frame, scaling_table, status_by_n
from harness.store import atomic_write, unit_key
from harness.verdict import ladder_rows, ladder_table, verdict_lines
from harness.versions import library_versions
from solvers import SOLVERS, plugin_distribution
from systems.cases import SMIB_CASES, SMIB_IDENTIFICATION
from systems.reference import OFF_TRAINING

__all__ = ["build_tables", "case_sections", "header", "metadata", "scaling_markdown", "section_markdown",
           "suite_frames", "verdict_markdown", "work_minutes", "write_report"]

LIBRARIES = ("numpy", "scipy", "pandas", "casadi", "torch", "jax", "jaxlib", "optax", "numba", "diffrax")
TRAJECTORY_COLUMNS = ("best_pred", "best_ref", "worst_pred", "worst_ref")


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def git_commit(repo: Path, outputs: Sequence[Path] = ()) -> str:
    """The short commit of `repo`, with "+dirty" when a tracked file differs from it, not counting
    `outputs` (what the run itself writes: its results folder, the README it updates); "unknown"
    outside a git checkout."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=repo, check=True).stdout.strip()
        top = Path(subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True,
                                  cwd=repo, check=True).stdout.strip())
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    excluded = []
    for path in outputs:
        try:
            excluded.append(f":(exclude){Path(path).resolve().relative_to(top.resolve()).as_posix()}")
        except ValueError:  # outside the checkout: git does not see it anyway
            continue
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", *excluded],
                           capture_output=True, text=True, cwd=top, check=False).stdout.strip()
    return commit + ("+dirty" if dirty else "")


def metadata(threads: int, outputs: Sequence[Path] = ()) -> dict:
    """Machine, CPU, threads, library versions (the distributions of adapters from outside the
    repository too), commit (see `git_commit`) and date of a run."""
    plugins = tuple(dict.fromkeys(dist for name in SOLVERS if (dist := plugin_distribution(name))))
    versions = library_versions(LIBRARIES + plugins)
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": platform.node(), "platform": platform.platform(), "cpu": _cpu(),
        "cpu_count": os.cpu_count(), "threads": threads, "python": platform.python_version(),
        "commit": git_commit(Path(__file__).parent, outputs),
        **{f"version_{k}": v for k, v in versions.items()},
    }


# ---------------------------------------------------------------------------------------------
# one function per table: frames by suite -> DataFrame ready to print

def _fit_table(frames: dict) -> pd.DataFrame:
    df = ok(frames.get("fit"))
    if df.empty:
        return df
    df = df.assign(label=label(df))
    rows = []
    for name, g in df.groupby("label", sort=False):
        rows.append({"case": g["case"].iloc[0], "solver": name, "seeds": int(trained(g).sum()) or "-",
                     "fit / build (s)": fmt_range(g["fit_s"]),
                     "iterations": fmt_range(g["iterations"].astype(float)) if trained(g).any() else "-",
                     "final loss": fmt_range(g["loss"]) if trained(g).any() else "-",
                     "from cache": "yes" if g["message"].fillna("").str.contains("cached").all() else "no"})
    return pd.DataFrame(rows)


def _accuracy_table(frames: dict) -> pd.DataFrame:
    df = ok(frames.get("accuracy"))
    if df.empty:
        return df
    df = df.assign(label=label(df))
    rows = []
    for (case, name), g in df.groupby(["case", "label"], sort=False):
        row = {"case": case, "solver": name}
        for quantity, against, title in (("delta", "reference", "delta"), (COI_DELTA, "reference", COI_DELTA),
                                         ("omega", "reference", "omega"),
                                         ("delta", OFF_TRAINING, "delta off the training points"),
                                         ("delta", "paper ode45 data", "delta vs paper data")):
            sel = g[(g["quantity"] == quantity) & (g["against"] == against)]
            if sel.empty:
                continue
            row[f"{title} rel. L2"] = fmt_range(sel["rel_l2"])
            if against == OFF_TRAINING:
                continue
            row[f"{title} max abs"] = fmt_range(sel["max_abs"])
            if against == "reference":
                row[f"{title} worst trajectory rel. L2"] = fmt_range(sel["worst_trajectory_rel_l2"])
        rows.append(row)
    return pd.DataFrame(rows)


def _latency_cell(row: pd.Series) -> str:
    """"median ±half-IQR%" in ms; "(1 run)" instead of a spread for a call timed once; the cost
    per point for a batch of single points; the status for a query that was not timed."""
    if row["status"] != "ok":
        return str(row["status"]).replace("skipped: ", "")
    cell = fmt(1e3 * row["median_s"])
    if row.get("repeats", 2) == 1:
        cell += " (1 run)"
    else:
        cell += f" ±{fmt(100 * (row['q75_s'] - row['q25_s']) / (2 * row['median_s']), 2)}%"
    if row.get("kind") == "points batch":
        cell += f" ({fmt(1e6 * row['median_s'] / row['n_trajectories'])} us/point)"
    return cell


def _latency_table(frames: dict) -> pd.DataFrame:
    df = frames.get("latency")
    if df is None or df.empty or "query" not in df:
        return pd.DataFrame()
    df = df[df["query"].notna()]
    df = df.assign(label=label(df), cell=[_latency_cell(r) for _, r in df.iterrows()])
    wide = df.pivot_table(index=["case", "label"], columns="query", values="cell", aggfunc="first", sort=False)
    wide.columns = [f"{c} (ms)" for c in wide.columns]
    return wide.reset_index().rename(columns={"label": "solver"})


def _identification_table(frames: dict) -> pd.DataFrame:
    df = ok(frames.get("identification"))
    if df.empty or "m_rel_error" not in df:
        return pd.DataFrame()
    df = df.assign(label=label(df), data=identification_data(df))
    rows = []
    for (name, data, noise), g in df.groupby(["label", "data", "noise"], sort=False):
        machines = int(g["machines"].max()) if "machines" in g and g["machines"].notna().any() else 1
        rows.append({"solver": name, "data": data, "noise": f"{noise:.0%}", "pairs": g["pair"].nunique(),
                     "machines": machines,
                     "m error mean (%)": fmt(100 * _mean_error(g, "m")),
                     "m error worst (%)": fmt(100 * g["m_rel_error"].max()),
                     "d error mean (%)": fmt(100 * _mean_error(g, "d")),
                     "d error worst (%)": fmt(100 * g["d_rel_error"].max()),
                     "time median (s)": fmt(g["identify_s"].median()), **_uncertainty_columns(g)})
    return pd.DataFrame(rows)


def _mean_error(g: pd.DataFrame, name: str) -> float:
    """The mean relative error of `name` over rows and machines (`{name}_rel_error` is a row's worst
    machine; rows of runs before multi-machine cases have one machine and no mean column)."""
    column = f"{name}_rel_error_mean"
    return float((g[column].fillna(g[f"{name}_rel_error"]) if column in g else g[f"{name}_rel_error"]).mean())


def _uncertainty_columns(g: pd.DataFrame) -> dict:
    """Successes, the median relative 95 % half-width ((high - low) / 2 / estimate) and how often the
    truth lies in the interval, for m and d; "n/a" for rows of runs made before these columns."""
    out = {"success": f"{int(g['success'].astype(bool).sum())}/{len(g)}" if "success" in g else "n/a"}
    for name in ("m", "d"):
        low, high = f"{name}_ci95_low", f"{name}_ci95_high"
        if low not in g or high not in g:
            out[f"{name} 95% half-width median (%)"] = out[f"{name} truth in 95% CI"] = "n/a"
            continue
        width = f"{name}_rel_half_width"  # worst machine; rows of runs before it: one machine's
        half = 100 * (g[width] if width in g else (g[high] - g[low]) / 2 / g[f"{name}_est"])
        inside = g[f"{name}_in_ci95"].dropna().astype(bool)
        out[f"{name} 95% half-width median (%)"] = fmt(half.median())
        out[f"{name} truth in 95% CI"] = f"{int(inside.sum())}/{inside.size}" if inside.size else "n/a"
        out[f"{name} 95% CI coverage"] = _coverage(g, name)
    return out


def _coverage(g: pd.DataFrame, name: str) -> str:
    """How many of the rows' per-machine 95 % intervals of `name` hold the truth, "k/n (p %)";
    "n/a" without intervals (or for rows of runs before the per-machine count)."""
    column = f"{name}_machines_in_ci95"
    if column not in g:
        return "n/a"
    known = g[g[column].notna()]
    total = int(known["machines"].fillna(1).sum()) if "machines" in known else len(known)
    if not total:
        return "n/a"
    inside = int(known[column].sum())
    return f"{inside}/{total} ({100 * inside / total:.0f} %)"


def _matched_table(frames: dict) -> pd.DataFrame:
    speed = matched_speedups(frames.get("work_precision"))
    if speed.empty:
        return speed
    rows = []
    for (pinn, seed), g in speed.groupby(["pinn", "seed"], sort=False):
        reached = g[g["match"] != "not reached"]
        best = reached.loc[reached["classical_query_s"].idxmin()] if not reached.empty else None
        rows.append({
            "PINN": pinn, "seed": seed, "PINN delta rel. L2": fmt(g["pinn_rel_l2_delta"].iloc[0]),
            "PINN grid query (ms)": fmt(1e3 * g["pinn_query_s"].iloc[0]),
            "fastest classical at that accuracy": "none" if best is None else best["classical"],
            "its time (ms)": "n/a" if best is None else
            ("<= " if best["match"] == "at most" else "") + fmt(1e3 * best["classical_query_s"]),
            "PINN speed-up": "n/a" if best is None else
            ("<= " if best["match"] == "at most" else "") + fmt(best["speedup"]) + "x",
        })
    return pd.DataFrame(rows)


def _break_even_table(frames: dict) -> pd.DataFrame:
    """Per PINN spec (first seed, the seed rule of every verdict) and the grid and t1 = 10 s
    queries: training time, the fastest classical option at least as accurate (any rung) and the
    number of queries after which training pays off."""
    rows = []
    for query in (GRID_QUERY, POINT_QUERY):
        for _, r in ladder(frames, query).iterrows():
            best = fastest_classical(frames, query, r["pinn_rel_l2"])
            n_star = break_even(r["fit_s"], best[1], r["pinn_s"]) if best else float("nan")
            rows.append({"PINN (first seed)": r["pinn"], "query": query, "training (s)": fmt(r["fit_s"]),
                         "delta rel. L2": fmt(r["pinn_rel_l2"]), "PINN query (ms)": fmt(1e3 * r["pinn_s"]),
                         "fastest classical at least as accurate": best[0] if best else "none",
                         "its query (ms)": fmt(1e3 * best[1]) if best else "n/a",
                         "break-even N* (queries)": "never" if n_star == float("inf") else
                         ("n/a" if np.isnan(n_star) else f"{n_star:,.0f}")})
    return pd.DataFrame(rows)


def _status_table(frames: dict) -> pd.DataFrame:
    everything = pd.concat([df for df in frames.values() if not df.empty], ignore_index=True) if frames else None
    if everything is None or everything.empty:
        return pd.DataFrame()
    bad = everything[everything["status"] != "ok"]
    bad = bad.assign(solver=label(bad))
    return bad[["suite", "case", "solver", "status"]].drop_duplicates()


def _smib_paper_table(frames: dict) -> pd.DataFrame | None:
    """The paper's table, for a SMIB case only (the paper's figures are of the SMIB)."""
    cases = {c for df in frames.values() if "case" in df for c in df["case"].dropna().unique()}
    return paper_table(frames) if cases and cases <= set(SMIB_FORWARD) else None


TABLES = {
    "paper": (("The paper's figures beside ours (same machine, same run; PINN figures of the first seed: "
               "error, fit time and query time of one model)"), _smib_paper_table),
    "ladder": (("Who wins each query at matched accuracy: each PINN configuration's fastest path (first "
                "seed; \"numba query\" is the compiled query path, `query=numba`) against the fastest classical "
                "option at least as accurate on each rung (every PINN spec: ladder.csv)"), ladder_table),
    "accuracy": (("Accuracy on the 100 x 201 grid, delta in rad, omega in rad/s "
                  "(median [min, max] over seeds for PINNs)"), _accuracy_table),
    "matched": (("Work-precision: PINN grid query against the fastest classical solver at the same "
                 "delta accuracy (interpolated on its tolerance sweep)"), _matched_table),
    "break_even": ("Cost of training: queries needed before a PINN pays off", _break_even_table),
    "latency": (("Warm query latency of delta and omega, ms: median of repeats ± half the interquartile "
                 "range (in % of the median)"), _latency_table),
    "identification": (("Identification of every machine's m and d from N_u = 100 samples of all angles: the "
                        "tight reference (SMIB: over the (m, d) pairs; multi-machine: the case's own values) or "
                        "the paper's ode45 data (its own case); errors: mean and worst over pairs and machines"),
                       _identification_table),
    "fit": ("Preparation cost, apart from queries: build, JIT, training", _fit_table),
    "status": ("Skipped or failed", _status_table),
}


SMIB_FORWARD = tuple(case.name for case in SMIB_CASES)


def _identification_case(name: str) -> str:
    """The case identification measures for forward case `name` (`harness.suites.identification_case`,
    by name: the report builds no case)."""
    return SMIB_IDENTIFICATION.name if name in SMIB_FORWARD else name


def case_sections(frames: dict[str, pd.DataFrame]) -> list[tuple[str, dict[str, pd.DataFrame]]]:
    """The frames of each forward case, in run order: its rows of every suite, and the
    identification rows of its identification case (the SMIB's own case for a SMIB). In a case
    without an infinite bus (any work-precision row with `rel_l2_delta_coi`) the verdicts compare
    at the accuracy of the angles relative to the centre of inertia: `rel_l2_delta` is replaced by
    it there (absolute angles drift together; their error says little about the swings)."""
    names: list[str] = []
    for suite, df in frames.items():
        if suite not in ("identification", "scaling", "fit") and "case" in df:
            names += [n for n in df["case"].dropna().unique() if n not in names]
    ident = frames.get("identification")
    if ident is not None and "case" in ident:
        covered = {_identification_case(n) for n in names}
        names += [n for n in ident["case"].dropna().unique() if n not in covered and n not in names]
    sections = []
    for name in names:
        own = {}
        for suite, df in frames.items():
            if suite == "scaling":  # across cases: its own section (`scaling_markdown`)
                continue
            case = _identification_case(name) if suite == "identification" else name
            part = df[df["case"] == case].dropna(axis=1, how="all").reset_index(drop=True) if "case" in df else df
            if suite == "work_precision" and "rel_l2_delta_coi" in part:
                part = part.assign(rel_l2_delta=part["rel_l2_delta_coi"].fillna(part["rel_l2_delta"]))
            if not part.empty:
                own[suite] = part
        sections.append((name, own))
    return sections


def suite_frames(rows: list[dict]) -> dict[str, pd.DataFrame]:
    frame = pd.DataFrame(rows)
    if frame.empty:
        return {}
    return {suite: g.dropna(axis=1, how="all").reset_index(drop=True)
            for suite, g in frame.groupby("suite", sort=False)}


def build_tables(frames: dict[str, pd.DataFrame]) -> dict[str, tuple[str, pd.DataFrame]]:
    """name -> (title, table) for every table that has content."""
    out = {}
    for name, (title, build) in TABLES.items():
        table = build(frames)
        if table is not None and not table.empty:
            out[name] = (title, table)
    return out


def header(meta: dict) -> str:
    """The run's line: date, CPU, threads, commit, settings and library versions."""
    get = lambda key: meta.get(key, "?")
    return (f"Run of {get('date')} on {get('cpu')} ({get('threads')} threads), commit {get('commit')}, "
            f"settings {get('settings')}; numpy {get('version_numpy')}, scipy {get('version_scipy')}, "
            f"casadi {get('version_casadi')}, torch {get('version_torch')}, jax {get('version_jax')}, "
            f"numba {get('version_numba')}, diffrax {get('version_diffrax')}.\n\n")


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


def section_markdown(name: str, frames: dict, tables: dict, level: str = "###", heading: str | None = None) -> str:
    """A case's section: its heading (`heading`, default "Case <name>"), the options its names leave
    out, its verdicts and every table of `tables` (`build_tables`), each configuration named by
    `harness.labels.Labels` of the case's rows."""
    labels = Labels(frames)
    return (f"{level[:-1]} {heading or f'Case {name}'}\n\n" + verdict_markdown(frames, labels, level)
            + "\n".join(f"{level} {title}\n\n{labels.table(table).to_markdown(index=False)}\n"
                        for title, table in tables.values()))


def verdict_markdown(frames: dict, labels: Labels | None = None, level: str | None = "###") -> str:
    """The note on the options left out of the names, then the verdict sentences of a case as a
    list, under a heading of `level` (None: no heading); "" for a case with neither."""
    labels = labels or Labels(frames)
    note = labels.note()
    lines = verdict_lines(frames)
    head = f"{level} Verdict of this case\n\n" if lines and level else ""
    return ((f"{note}\n\n" if note else "")
            + (head + "".join(f"- {labels.text(line, '`{}`')}\n" for line in lines) + "\n" if lines else ""))


def _scaling_labels(frames: dict) -> Labels:
    """The names of the scaling section: the options every scaling unit of a configuration shares
    (the suite's training budget) are left out."""
    return Labels({suite: df for suite, df in frames.items() if suite in ("scaling", "fit")})


def scaling_markdown(frames: dict, level: str = "###") -> str:
    """The scaling section ("" when the run has no scaling rows): cost, memory and accuracy per
    adapter and N, fitted exponents, break-even trajectories of each PINN, units that did not fit."""
    frame = scaling_frame(frames)
    tables = [("Cost, memory and accuracy against the number of machines N", scaling_table(frame)),
              ("Fitted exponents b of cost ~ N^b (least squares in log-log, N >= 2)", exponents(frame)),
              ("Break-even: trajectories after which a PINN's preparation pays off", break_even_by_n(frame)),
              ("Units that did not run to the end", status_by_n(frames))]
    tables = [(title, table) for title, table in tables if not table.empty]
    if not tables:
        return ""
    labels = _scaling_labels(frames)
    scaling = frames.get("scaling", pd.DataFrame(columns=["solver", "config"]))
    note = labels.note(set(zip(scaling["solver"], scaling["config"])))
    return (f"\n{level[:-1]} Scaling\n\n" + (f"{note}\n\n" if note else "")
            + "\n".join(f"{level} {title}\n\n{labels.table(table).to_markdown(index=False)}\n"
                        for title, table in tables))


def write_report(rows: list[dict], out_dir: Path, meta: dict, plots: bool = True) -> str:
    """Write `<suite>.csv` (tidy, one row per measurement, every case), `tables.md`, `tables.tex`,
    the plots (of each case, `<plot>-<case>.png` when the run has several), `README.md` and
    `metadata.json` to `out_dir`, each atomically; return the Markdown."""
    out_dir = Path(out_dir)
    frames = suite_frames(rows)
    for suite, df in frames.items():
        csv = df.drop(columns=[c for c in TRAJECTORY_COLUMNS if c in df])
        atomic_write(out_dir / f"{suite}.csv", csv.to_csv(index=False))
    sections = [(name, own, build_tables(own)) for name, own in case_sections(frames)]
    steps = pd.concat([ladder_rows(own, fastest_per_config=False).assign(case=name) for name, own, _ in sections]
                      or [pd.DataFrame()], ignore_index=True)
    if not steps.empty:
        atomic_write(out_dir / "ladder.csv", steps.to_csv(index=False))
    markdown = header(meta) + work_minutes(rows) + "\n".join(section_markdown(name, own, tables)
                                                        for name, own, tables in sections)
    markdown += scaling_markdown(frames)
    latex = "\n".join(_latex(name, Labels(own), tables) for name, own, tables in sections)
    atomic_write(out_dir / "tables.md", markdown)
    atomic_write(out_dir / "tables.tex", latex)
    atomic_write(out_dir / "metadata.json", json.dumps(meta, indent=2, default=str))
    figures = []
    if plots:
        from harness.plots import PLOTS, make_plots

        for old in (*out_dir.glob("*.png"), *out_dir.glob("*.pdf")):  # a previous run's plots, of other cases
            if old.stem.split("-", 1)[0] in (*PLOTS, *SCALING_PLOTS):
                old.unlink()

        for name, own, _ in sections:
            figures += make_plots(own, out_dir, suffix=f"-{name}" if len(sections) > 1 else "")
        figures += make_plots({"scaling_frame": scaling_frame(frames)}, out_dir, names=SCALING_PLOTS,
                              labels=_scaling_labels(frames))
    atomic_write(out_dir / "README.md", _results_readme(meta, frames, markdown, figures))
    return markdown


def _latex(name: str, labels: Labels, tables: dict) -> str:
    """A case's tables in LaTeX, each after a comment with its case and title; the options left
    out of the names in a comment first."""
    note = labels.note()
    return (f"% {name}: {note}\n" if note else "") + "\n".join(
        f"% {name}: {title}\n{labels.table(table).to_latex(index=False, escape=True)}" for title, table in tables.values())


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
