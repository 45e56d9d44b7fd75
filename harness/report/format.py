"""Numbers as the report's cells: three significant digits, "n/a" for none (`fmt`), a range over
seeds (`fmt_range`), a latency with its spread (`latency_cell`)."""

from __future__ import annotations

import math

import pandas as pd

__all__ = ["fmt", "fmt_range", "latency_cell"]


def fmt(x: float, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    return f"{x:.{digits}g}"


def latency_cell(row: pd.Series) -> str:
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


def fmt_range(values: pd.Series) -> str:
    """"median" or "median [min, max]" over seeds."""
    values = values.dropna()
    if values.empty:
        return "n/a"
    if values.size == 1:
        return fmt(values.iloc[0])
    return f"{fmt(values.median())} [{fmt(values.min())}, {fmt(values.max())}] (n={values.size})"
