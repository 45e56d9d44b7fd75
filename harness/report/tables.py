"""The report's tables: one function per table, frames by suite -> a DataFrame ready to print
(`TABLES`, each under its title; `build_tables`).

Nothing here measures anything: every cell comes from the rows of one run.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import pandas as pd

from harness.report.cct import CCT_ABOUT, CCT_TITLE, cct_table
from harness.report.format import fmt, fmt_range, latency_cell
from harness.report.frames import identification_data, label, ok, trained
from harness.report.ladder import GRID_QUERY, POINT_QUERY, fastest_classical, ladder, ladder_table
from harness.report.paper import paper_table
from harness.report.speedups import break_even, matched_speedups
from harness.report.verdicts import RULE, RULE_SURROGATE, verdict_table
from harness.suites.accuracy import COI_DELTA
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE
from systems.reference import OFF_TRAINING, STABLE_CLEARING

__all__ = ["TABLES", "Table", "build_tables"]


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
                                         (COI_DELTA, STABLE_CLEARING, f"{COI_DELTA}, stable t_c"),
                                         ("omega", STABLE_CLEARING, "omega, stable t_c"),
                                         ("delta", "paper ode45 data", "delta vs paper data")):
            sel = g[(g["quantity"] == quantity) & (g["against"] == against)]
            if sel.empty:
                continue
            row[f"{title} rel. L2"] = fmt_range(sel["rel_l2"])
            if "answered" in sel and (sel["answered"] < sel["trajectories"]).any():  # refusals (a fault case)
                worst = sel.loc[sel["answered"].idxmin()]
                row[f"{title} rel. L2"] += f" ({int(worst['answered'])} of {int(worst['trajectories'])} answered)"
            if against in (OFF_TRAINING, STABLE_CLEARING):
                continue
            row[f"{title} max abs"] = fmt_range(sel["max_abs"])
            if against == "reference":
                row[f"{title} worst trajectory rel. L2"] = fmt_range(sel["worst_trajectory_rel_l2"])
        rows.append(row)
    return pd.DataFrame(rows)


def _latency_table(frames: dict) -> pd.DataFrame:
    df = frames.get("latency")
    if df is None or df.empty or "query" not in df:
        return pd.DataFrame()
    df = df[df["query"].notna()]
    df = df.assign(label=label(df), cell=[latency_cell(r) for _, r in df.iterrows()])
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
    """How many of the rows' per-machine 95 % intervals of `name` hold the truth, "k/n (p %)", from
    the rows' intervals and true values (an unbounded interval holds it); machines with no
    interval (NaN) are counted apart ("..., j without"); "n/a" for rows without interval columns."""
    columns = [f"{name}_true", f"{name}_ci95_low", f"{name}_ci95_high"]
    if any(column not in g for column in columns):
        return "n/a"
    inside = total = missing = 0
    for truth, low, high in g[columns].itertuples(index=False):
        truth, low, high = (np.atleast_1d(np.asarray(x, np.float64)) for x in (truth, low, high))
        known = ~(np.isnan(low) | np.isnan(high))
        missing += int((~known).sum())
        total += int(known.sum())
        inside += int(((low <= truth) & (truth <= high))[known].sum())
    if not total:
        return "n/a" if not missing else f"0/0, {missing} without"
    return f"{inside}/{total} ({100 * inside / total:.0f} %)" + (f", {missing} without" if missing else "")


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


# The paper's own cases: its figures are of these, not of any other SMIB.
PAPER_CASES = (SMIB_INFERENCE.name, SMIB_IDENTIFICATION.name)


def _smib_paper_table(frames: dict) -> pd.DataFrame | None:
    """The paper's table, for the paper's own cases only (its figures are of them)."""
    cases = {c for df in frames.values() if "case" in df for c in df["case"].dropna().unique()}
    return paper_table(frames) if cases and cases <= set(PAPER_CASES) else None


class Table(NamedTuple):
    """A table of a case's section: a heading of a few words, the paragraph under it that says what
    the table holds (units, seeds, rules; "" for none; a function of the table where its text
    depends on the columns the table has) and the function that builds it from the frames (None
    or an empty frame: no such table)."""

    heading: str
    about: str | Callable[[pd.DataFrame], str]
    build: Callable[[dict], pd.DataFrame | None]


TABLES = {
    "verdicts": Table("Verdicts, every query", lambda table: f"At matched accuracy. {RULE}" + (
        f" {RULE_SURROGATE}" if "surrogate verdict" in table else ""), verdict_table),
    "paper": Table("The paper's figures beside ours",
                   "Same machine, same run; PINN figures of the first seed: error, fit time and query time of one "
                   "model.", _smib_paper_table),
    "ladder": Table("Who wins each query",
                    "At matched accuracy: each PINN configuration's fastest path (first seed; \"numba query\" is the "
                    "compiled query path, `query=numba`) against the fastest classical option at least as accurate on "
                    "each rung (every PINN spec: ladder.csv).", ladder_table),
    "accuracy": Table("Accuracy", "On the 100 x 201 grid, delta in rad, omega in rad/s (median [min, max] over seeds "
                                  "for PINNs).", _accuracy_table),
    "matched": Table("Work-precision",
                     "The PINN's grid query against the fastest classical solver at the same delta accuracy "
                     "(interpolated on its tolerance sweep).", _matched_table),
    "break_even": Table("Cost of training", "The queries needed before a PINN pays off.", _break_even_table),
    "latency": Table("Warm query latency",
                     "Of delta and omega, ms: median of repeats ± half the interquartile range (in % of the "
                     "median).", _latency_table),
    "identification": Table("Identification",
                            "Of every machine's m and d from N_u = 100 samples of all angles: the tight reference "
                            "(SMIB: over the (m, d) pairs; multi-machine: the case's own values) or the paper's ode45 "
                            "data (its own case); errors: mean and worst over pairs and machines.",
                            _identification_table),
    "cct": Table(CCT_TITLE, CCT_ABOUT, cct_table),
    "fit": Table("Preparation cost", "Apart from queries: build, JIT, training.", _fit_table),
    "status": Table("Skipped or failed", "", _status_table),
}


def build_tables(frames: dict[str, pd.DataFrame]) -> dict[str, tuple[str, str, pd.DataFrame]]:
    """name -> (heading, about, table) for every table of `TABLES` that has content."""
    out = {}
    for name, spec in TABLES.items():
        table = spec.build(frames)
        if table is not None and not table.empty:
            out[name] = (spec.heading, spec.about(table) if callable(spec.about) else spec.about, table)
    return out
