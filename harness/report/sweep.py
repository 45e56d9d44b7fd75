"""A sweep's rows -> its files: `sweep.csv` (tidy: every row, swept options as `p_<option>` columns)
and `sweep.md` (per grid point and case: runs ok/failed, median and [min, max] over seeds of the
relative L2 error of delta and omega against the DOP853 reference, median fit seconds).

`swingbench sweep` (`harness.cli.sweep`) measures the rows; nothing here measures anything.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pandas as pd

from harness.store import UNIT_COLUMNS, RowStore
from solvers.atomic import atomic_write

__all__ = ["summary_markdown", "summary_table", "write_outputs"]


def summary_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Per case and grid point: runs ok/failed, median and [min, max] over seeds of rel. L2 of delta
    and omega against the reference, median fit seconds. A pandas DataFrame in grid order."""
    if frame.empty:
        return pd.DataFrame()
    params = [c for c in frame.columns if c.startswith("p_")]
    groups = ["case", "solver", "config", "point"]
    accuracy = frame[frame["suite"] == "accuracy"]
    runs = accuracy.groupby([*groups, "variant", "seed"], sort=False, dropna=False)["status"].agg(
        lambda s: (s == "ok").all()).rename("ok").reset_index()
    fits = frame[(frame["suite"] == "fit") & (frame["status"] == "ok")].reindex(columns=[*groups, "fit_s"])
    table = runs.groupby(groups, sort=False).agg(runs_ok=("ok", "sum"), failed=("ok", lambda s: int((~s).sum())))
    table = frame.groupby(groups, sort=False)[params].first().join(table, how="right")
    table = table.join(fits.groupby(groups, sort=False)["fit_s"].median().rename("fit_s_median"), how="left")
    good = accuracy[accuracy["status"] == "ok"].reindex(columns=[*groups, "quantity", "against", "rel_l2"])
    good = good[good["against"] == "reference"]
    for quantity in ("delta", "omega"):
        stats = good[good["quantity"] == quantity].groupby(groups, sort=False)["rel_l2"].agg(
            ["median", "min", "max"])
        stats.columns = [f"{quantity}_rel_l2_{s}" for s in stats.columns]
        table = table.join(stats, how="left")
    table = table.reset_index().sort_values(["case", "point"], kind="stable")
    return table.drop(columns=["point"]).reset_index(drop=True)


def summary_markdown(table: pd.DataFrame, meta: dict) -> str:
    """sweep.md's text: a header from the run's metadata `meta` (date, cpu, commit, runs, executor),
    then `table` (`summary_table`'s) as Markdown, errors and seconds to 3 significant digits."""
    if table.empty:
        return "No rows.\n"

    def fmt(x: Any) -> str:
        return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.3g}"

    keep = [c for c in table.columns if c in ("case", "solver", "config") or c.startswith("p_")]
    shown = table[keep].copy()
    shown.columns = [c.removeprefix("p_") for c in shown.columns]
    shown["runs ok / failed"] = [f"{int(a)} / {int(b)}" for a, b in zip(table["runs_ok"], table["failed"])]
    for quantity in ("delta", "omega"):
        cols = [f"{quantity}_rel_l2_{s}" for s in ("median", "min", "max")]
        shown[f"{quantity} rel. L2, median [min, max]"] = [
            f"{fmt(m)} [{fmt(lo)}, {fmt(hi)}]" if not math.isnan(m) else ""
            for m, lo, hi in table[cols].itertuples(index=False)]
    shown["fit (s), median"] = [fmt(x) for x in table["fit_s_median"]]
    header = (f"Sweep of {meta.get('date', '?')} on {meta.get('cpu', '?')}, commit {meta.get('commit', '?')}: "
              f"{meta.get('runs', '?')} runs on {meta.get('executor', '?')}, 1 thread per run. Relative L2 on "
              "the 100 x 201 grid against DOP853 at 1e-12, over seeds; fit seconds measured with other runs "
              "sharing the cores (cached models report the cost recorded when trained). No latency is "
              "measured in a sweep.\n\n")
    return header + shown.to_markdown(index=False) + "\n"


def write_outputs(store: RowStore, out: Path, meta: dict) -> str:
    """sweep.csv (every row, tidy) and sweep.md from `store`, atomically; returns the Markdown."""
    frame = pd.DataFrame(store.rows())
    if not frame.empty:
        # tidy: scalars only; list-valued measurements (whole trajectories) stay in rows.jsonl,
        # list-valued swept options become their JSON text
        listy = [c for c in frame.columns if frame[c].map(lambda v: isinstance(v, (list, tuple, dict))).any()]
        frame = frame.drop(columns=[c for c in listy if not c.startswith("p_")]).assign(**{
            c: frame[c].map(lambda v: json.dumps(v) if isinstance(v, (list, tuple)) else v)
            for c in listy if c.startswith("p_")})
        front = [c for c in (*UNIT_COLUMNS, "point") if c in frame.columns]
        params = sorted(c for c in frame.columns if c.startswith("p_"))
        rest = [c for c in frame.columns if c not in front and c not in params]
        frame = frame[[*front, *params, *rest]]
    atomic_write(out / "sweep.csv", frame.to_csv(index=False))
    markdown = summary_markdown(summary_table(frame), meta)
    atomic_write(out / "sweep.md", markdown)
    return markdown
