"""The step claim, from the rows of one run: per case and fixed-step method (every spec whose
work-precision sweep sets a step, `STEP_OPTIONS`), the largest step whose error of the angles
relative to the centre of inertia is within a threshold, and the times of its queries there
(`step_claim_table`); beside it, the component network's own one-step error, from the
`component_error.csv` that `python -m solvers.pinn.component_error` writes (`one_step_table`).

The section (`step_claim_markdown`) is made only for a run with a trained adapter's step sweep
(a PINN that time-steps, as pinnsim does) or a folder holding `component_error.csv`: every other
run's report is as it was. Pure pandas; the only I/O is reading that CSV and its JSON.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from harness.report.format import fmt, latency_cell
from harness.report.frames import first_seed, label, ok, trained
from harness.report.labels import Labels
from harness.report.markdown import table_markdown

__all__ = ["COI_THRESHOLD", "COMPONENT_CSV", "STEP_OPTIONS", "one_step_line", "one_step_table", "step_claim_bullets",
           "step_claim_markdown", "step_claim_table", "step_rows"]

# The option (s) a fixed-step adapter's sweep sets: `dt` (`AbstractSolver.step_sweep`, the
# classical integrators), `h` (pinnsim's simulator step). A row sets at most one of them.
STEP_OPTIONS = ("dt", "h")
COI_THRESHOLD = 1e-3  # delta - delta_COI rel. L2 on the 100 x 201 grid
COMPONENT_CSV = "component_error.csv"
NONE = "none of its steps"


def step_rows(frames: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """The ok work-precision rows of step sweeps on cases without an infinite bus (those with
    `rel_l2_delta_coi`), first seed of a trained spec, with their step as `step_s` (s); an empty
    frame when there are none."""
    df = ok(frames.get("work_precision"))
    steps = [column for column in STEP_OPTIONS if column in df]
    if df.empty or not steps or "rel_l2_delta_coi" not in df:
        return pd.DataFrame()
    df = first_seed(df.assign(step_s=df[steps].bfill(axis=1).iloc[:, 0].astype(float)))
    return df[df["step_s"].notna() & df["rel_l2_delta_coi"].notna()]


def _time(row: pd.Series, prefix: str) -> str:
    """A query's median (ms) ± half its interquartile range, as the latency table writes it;
    `prefix` "" for the grid query, "point_" for the single point at t1 = 10 s."""
    if pd.isna(row.get(f"{prefix}median_s")):
        return "n/a"
    return latency_cell(pd.Series({"status": "ok", **{key: row.get(f"{prefix}{key}") for key in
                                                       ("median_s", "q25_s", "q75_s", "repeats")}}))


def step_claim_table(frames: dict[str, pd.DataFrame], threshold: float = COI_THRESHOLD) -> pd.DataFrame:
    """Per case and step-swept spec (first seed): the largest step h (s) with delta - delta_COI
    rel. L2 <= `threshold`, its COI and omega rel. L2 and its grid (100 x 201) and single-point
    (t1 = 10 s) query times (ms) from the same row; where no step qualifies, `NONE` with the finest
    step and its errors, no times. Empty unless a trained spec swept its step."""
    df = step_rows(frames)
    if df.empty or not trained(df).any():
        return pd.DataFrame()
    df = df.assign(label=label(df))
    rows = []
    for (case, name), g in df.groupby(["case", "label"], sort=False):
        good = g[g["rel_l2_delta_coi"] <= threshold]
        found = not good.empty
        row = good.loc[good["step_s"].idxmax()] if found else g.loc[g["step_s"].idxmin()]
        rows.append({"case": case, "solver": name,
                     f"largest step at COI rel. L2 <= {threshold:g} (s)":
                         fmt(row["step_s"]) if found else f"{NONE} (finest {fmt(row['step_s'])} s)",
                     "COI rel. L2": fmt(row["rel_l2_delta_coi"]), "omega rel. L2": fmt(row["rel_l2_omega"]),
                     "grid 100 x 201 (ms)": _time(row, "") if found else "n/a",
                     "single point t1 = 10 s (ms)": _time(row, "point_") if found else "n/a",
                     "steps swept (s)": f"{fmt(g['step_s'].max())} to {fmt(g['step_s'].min())} ({len(g)})"})
    return pd.DataFrame(rows)


def one_step_table(path: Path) -> pd.DataFrame:
    """`component_error.csv` at `path` as a table: one row per bin of t (s), then every statistic
    column it has ("delta_p99_rad" -> "delta p99 (rad)", "omega_max_rad_s" -> "omega max (rad/s)")."""
    data = pd.read_csv(path)
    out = pd.DataFrame({"t (s)": [f"{fmt(a)} - {fmt(b)}" for a, b in zip(data["t_from_s"], data["t_to_s"])]})
    for column in data.columns.drop(["t_from_s", "t_to_s"]):
        quantity, statistic, *unit = column.split("_")
        out[f"{quantity} {statistic} ({'/'.join(unit)})"] = [fmt(x) for x in data[column]]
    return out


def _one_step_about(folder: Path) -> str:
    """What the one-step table holds, with the counts of `component_error.json` where it is there."""
    about = ("The component network's error against the exact machine response (DOP853 at 1e-12), composed "
             "as the simulator composes it over one step, per bin of the time since the step's start: "
             "median, 99th percentile and max over the test inputs")
    record = folder / "component_error.json"
    if record.exists():
        meta = json.loads(record.read_text(encoding="utf-8"))
        about += (f"; {meta['measured']} of {meta['samples']} inputs measured, the rest leave the domain within "
                  f"the step (component_error.json); written by `{meta['command']}`")
    return about + "."


def step_claim_markdown(frames: dict[str, pd.DataFrame], folder: Path | None = None, level: str = "###",
                        threshold: float = COI_THRESHOLD) -> str:
    """The run's step-claim section ("" when it has neither table): `step_claim_table` of
    `frames`, and `one_step_table` when `folder` holds `COMPONENT_CSV`; headings of `level`."""
    claim = step_claim_table(frames, threshold)
    parts = []
    if not claim.empty:
        labels = Labels({suite: df for suite, df in frames.items() if suite == "work_precision"})
        note = labels.note(set(zip(frames["work_precision"]["solver"], frames["work_precision"]["config"])))
        about = (f"Per case and fixed-step method: the largest step of its work-precision sweep whose "
                 f"delta - delta_COI rel. L2 on the 100 x 201 grid is <= {threshold:g}, its errors there and the "
                 "times of its grid and single-point (t1 = 10 s) queries in the same row, ms: median ± half the "
                 "interquartile range; where no step qualifies, the finest step's errors."
                 + (f" {note}" if note else ""))
        parts.append(table_markdown(level, f"Largest step at COI rel. L2 <= {threshold:g}", about,
                                    labels.table(claim)))
    csv = Path(folder) / COMPONENT_CSV if folder is not None else None
    if csv is not None and csv.exists():
        parts.append(table_markdown(level, "The component network's one-step error", _one_step_about(csv.parent),
                                    one_step_table(csv)))
    return f"\n{level[:-1]} Step claim\n\n" + "\n".join(parts) if parts else ""


def step_claim_bullets(frames: dict[str, pd.DataFrame], threshold: float = COI_THRESHOLD) -> list[str]:
    """`step_claim_table` as one Markdown bullet per case: each method's largest step at COI
    rel. L2 <= `threshold` (s) and its grid query's median time there, or that none of its steps
    keeps it (with the finest step's error); [] when the table is empty."""
    claim = step_claim_table(frames, threshold)
    if claim.empty:
        return []
    step = f"largest step at COI rel. L2 <= {threshold:g} (s)"
    bullets = []
    for case, g in claim.groupby("case", sort=False):
        parts = []
        for _, r in g.iterrows():
            if r[step].startswith(NONE):
                parts.append(f"{r['solver']}: {r[step]}, COI rel. L2 {r['COI rel. L2']} there")
            else:
                parts.append(f"{r['solver']}: {r[step]} s, grid {r['grid 100 x 201 (ms)']} ms")
        bullets.append(f"- **{case}**: " + "; ".join(parts) + ".")
    return bullets


def one_step_line(folder: Path) -> str:
    """One sentence of the component network's one-step error in delta from `folder`'s
    `COMPONENT_CSV`: the median and max of its row over the whole span of t (rad), or without one
    the largest median and max over its bins; with the inputs measured (its JSON); "" without the CSV."""
    csv = Path(folder) / COMPONENT_CSV
    if not csv.exists():
        return ""
    data = pd.read_csv(csv)
    whole = data[(data["t_from_s"] == data["t_from_s"].min()) & (data["t_to_s"] == data["t_to_s"].max())]
    over = f"The component network's one-step error in delta over t <= {fmt(data['t_to_s'].max())} s"
    if len(whole):  # the CSV's row of the whole span: its own median and max
        line = f"{over}: median {fmt(whole['delta_median_rad'].iloc[0])} rad, max {fmt(whole['delta_max_rad'].iloc[0])} rad"
    else:
        line = (f"{over}: median at most {fmt(data['delta_median_rad'].max())} rad in any bin of t, max "
                f"{fmt(data['delta_max_rad'].max())} rad")
    record = csv.with_name("component_error.json")
    if record.exists():
        meta = json.loads(record.read_text(encoding="utf-8"))
        line += f" ({meta['measured']} of {meta['samples']} held-out inputs inside the domain)"
    return line + "."
