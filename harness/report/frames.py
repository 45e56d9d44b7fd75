"""Derived comparisons from the rows of a run: pure pandas/numpy, no measurement, no I/O.

Trained adapters (PINNs) are the rows whose adapter declares it (`trains`), with their seed; the
others, classical adapters, have seed -1. Every comparison is between rows of the same run.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from harness.suites.accuracy import COI_DELTA
from solvers import INTERFACE, LITERATURE_BASELINE

__all__ = [
    "COMPILED",
    "GRID_QUERY",
    "LITERATURE",
    "POINT_QUERY",
    "PYTHON_DRIVEN",
    "RUNGS",
    "break_even",
    "compiled",
    "crossover_t1",
    "does_work",
    "fastest_classical",
    "first_seed",
    "fmt",
    "fmt_range",
    "identification_data",
    "label",
    "ladder",
    "matched_speedups",
    "ok",
    "pareto_front",
    "seed_summary",
    "time_at_accuracy",
    "trained",
    "verdict_rows",
]


# The latency suite's names of the paper's two timed queries; the work-precision suite times the first.
GRID_QUERY, POINT_QUERY = "grid 100x201", "single point t1=10 s"


def ok(df: pd.DataFrame | None) -> pd.DataFrame:
    """Rows with status "ok" (an empty frame when there are none)."""
    if df is None or df.empty or "status" not in df:
        return pd.DataFrame()
    return df[df["status"] == "ok"].copy()


def label(df: pd.DataFrame) -> pd.Series:
    """"solver [config, variant]": the spec without its seed, the unit seeds are summarised over."""
    variant = df["variant"].fillna("").astype(str).map(lambda v: f", {v}" if v else "")
    return df["solver"] + " [" + df["config"] + variant + "]"


def identification_data(df: pd.DataFrame) -> pd.Series:
    """The data source of identification rows ("reference" or "paper ode45"); rows of runs made
    before the column existed were all on the reference."""
    if "data" not in df:
        return pd.Series("reference", index=df.index)
    return df["data"].fillna("reference")


def trained(df: pd.DataFrame) -> pd.Series:
    """Rows of adapters that train (the rows' `trains`, as the adapter declares it). Runs before the
    column recorded a training seed >= 0 for exactly these adapters and -1 for the others, so their
    rows are read by that rule; a row without the declaration in a run that has the column (an
    adapter that is not installed) does not train."""
    if "trains" not in df:
        return df["seed"].fillna(-1).astype(int) >= 0 if "seed" in df else pd.Series(False, index=df.index)
    return df["trains"].eq(True)  # NaN (no declaration) is not True


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


def seed_summary(df: pd.DataFrame, column: str) -> pd.DataFrame:
    """Median, min, max and count of `column` per spec label, over seeds."""
    frame = df.assign(label=label(df))
    return frame.groupby("label", sort=False)[column].agg(["median", "min", "max", "count"])


def pareto_front(errors: np.ndarray, seconds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points of an error-time curve that no other point beats in both; sorted by error."""
    order = np.argsort(errors)
    front_e, front_t = [], []
    for e, t in zip(errors[order], seconds[order]):
        if not front_t or t < front_t[-1]:
            front_e.append(e)
            front_t.append(t)
    return np.array(front_e), np.array(front_t)


def time_at_accuracy(errors: np.ndarray, seconds: np.ndarray, target: float) -> tuple[float, str]:
    """Time for a classical curve to reach error <= `target`, log-log interpolated on its Pareto
    front. Returns (seconds, how): how is "interpolated"; "at most" when even the loosest
    tolerance is more accurate than `target` (its time is then an upper bound); "not reached"
    (NaN) when the tightest tolerance is still less accurate."""
    e, t = pareto_front(np.asarray(errors, float), np.asarray(seconds, float))
    if e.size == 0 or target < e[0]:
        return float("nan"), "not reached"
    if target >= e[-1]:
        return float(t[-1]), "at most"
    return float(np.exp(np.interp(np.log(target), np.log(e), np.log(t)))), "interpolated"


def matched_speedups(work_precision: pd.DataFrame) -> pd.DataFrame:
    """For each trained point (PINN) and each classical curve of the work-precision rows: the
    classical time at the PINN's delta error and the speed-up of the PINN (> 1: the PINN is faster)."""
    wp = ok(work_precision)
    if wp.empty:
        return pd.DataFrame()
    wp = wp.assign(label=label(wp))
    points = wp[trained(wp)]
    curves = {name: g for name, g in wp[~trained(wp)].groupby("label", sort=False)}
    rows = []
    for _, p in points.iterrows():
        for name, curve in curves.items():
            seconds, how = time_at_accuracy(curve["rel_l2_delta"].to_numpy(), curve["median_s"].to_numpy(),
                                            p["rel_l2_delta"])
            rows.append({"pinn": p["label"], "seed": p["seed"], "pinn_rel_l2_delta": p["rel_l2_delta"],
                         "pinn_query_s": p["median_s"], "classical": name, "classical_query_s": seconds,
                         "match": how, "speedup": seconds / p["median_s"]})
    return pd.DataFrame(rows)


def break_even(fit_s: float, classical_s: float, pinn_s: float) -> float:
    """Queries N* after which training pays off: fit / (classical - pinn) query time; inf (never)
    when the PINN is not faster per query."""
    gain = classical_s - pinn_s
    return fit_s / gain if gain > 0 else float("inf")


# The rungs of the verdict ladder: which classical options each one may pick from.
LITERATURE = "literature baseline (scipy RK45, one solve per P1)"
PYTHON_DRIVEN = "best Python-driven classical"
COMPILED = "best compiled classical"
RUNGS = (LITERATURE, PYTHON_DRIVEN, COMPILED)
LITERATURE_SOLVER = LITERATURE_BASELINE  # looped, as MATLAB ode45 was in the paper's 28x and 87x


def compiled(df: pd.DataFrame) -> pd.Series:
    """Rows of adapters whose queries run in compiled code (rows before the column: none)."""
    if "compiled" not in df:
        return pd.Series(False, index=df.index)
    return df["compiled"].fillna(False).astype(bool)


def does_work(df: pd.DataFrame) -> pd.Series:
    """Rows of real adapters, not of the do-nothing one that times the interface (`solvers.INTERFACE`;
    rows of runs before the `does_work` column are told by that name)."""
    by_name = df["solver"] != INTERFACE
    if "does_work" not in df:
        return by_name
    return df["does_work"].fillna(by_name).astype(bool)


def _on_rung(df: pd.DataFrame, rung: str | None) -> pd.Series:
    """Classical rows that rung `rung` may pick (None: every classical row)."""
    classical = ~trained(df) & does_work(df)
    if rung is None:
        return classical
    if rung == LITERATURE:
        return classical & (df["solver"] == LITERATURE_SOLVER) & (df["variant"].fillna("") == "")
    if rung == PYTHON_DRIVEN:
        return classical & ~compiled(df)
    if rung == COMPILED:
        return classical & compiled(df)
    raise ValueError(f"unknown rung {rung!r}; known: {', '.join(RUNGS)}")


def verdict_rows(acc: pd.DataFrame) -> pd.DataFrame:
    """The accuracy rows every verdict compares at: delta against the reference, or, when the rows
    hold it (a case without an infinite bus), the angles relative to the centre of inertia, the
    measure the work-precision points of such a case are read at (`harness.report.files.case_sections`):
    a PINN and its classical rivals judged by one measure."""
    acc = acc[acc["against"] == "reference"]
    quantity = COI_DELTA if (acc["quantity"] == COI_DELTA).any() else "delta"
    return acc[acc["quantity"] == quantity]


def fastest_classical(frames: dict, query: str, max_rel_l2: float, rung: str | None = None
                      ) -> tuple[str, float] | None:
    """The fastest classical option for `query` whose delta rel. L2 is at most `max_rel_l2`:
    (label, median seconds), or None. Candidates: each classical spec of the accuracy and latency
    suites and, for the grid and the t1 = 10 s query, each point of the work-precision sweeps
    (labelled with its setting), so that a PINN is compared with the strongest classical option
    measured; `rung` restricts them to one rung of the ladder (`RUNGS`; None: all)."""
    candidates: list[tuple[str, float]] = []
    acc, lat = ok(frames.get("accuracy")), ok(frames.get("latency"))
    if not acc.empty and not lat.empty:
        acc = verdict_rows(acc)
        acc = acc[_on_rung(acc, rung)]
        good = set(label(acc[acc["rel_l2"] <= max_rel_l2]))
        lat = lat[(lat["query"] == query) & _on_rung(lat, rung)]
        lat = lat.assign(label=label(lat))
        candidates += [(name, float(s)) for name, s in zip(lat["label"], lat["median_s"]) if name in good]
    wp = ok(frames.get("work_precision"))
    column = {GRID_QUERY: "median_s", POINT_QUERY: "point_median_s"}.get(query)
    if column in wp:  # rows of runs before the point timing have no point_median_s
        wp = wp[_on_rung(wp, rung) & (wp["rel_l2_delta"] <= max_rel_l2) & wp[column].notna()]
        for (_, row), name in zip(wp.iterrows(), label(wp)):
            setting = row.get("setting")
            if not isinstance(setting, str):  # runs before the column: tolerance sweeps only
                setting = f"rtol={row['rtol']:g}, atol={row['atol']:g}" if pd.notna(row.get("rtol")) else ""
            if setting:
                candidates.append((f"{name[:-1]}, {setting}]", float(row[column])))
    return min(candidates, key=lambda c: c[1]) if candidates else None


def first_seed(df: pd.DataFrame) -> pd.DataFrame:
    """Classical rows and, of each trained spec, the rows of its first (lowest) seed: the seed rule
    of every verdict (error, latency and fit time all from the one model that was timed)."""
    if df.empty:
        return df
    seed = df["seed"].fillna(-1).astype(int)
    lowest = seed.groupby(label(df)).transform("min")
    return df[seed == lowest]


def ladder(frames: dict, query: str) -> pd.DataFrame:
    """The verdict ladder of `query`: one row per PINN spec (configuration and query path, first
    seed): its delta rel. L2 on the grid, its query time, and for each rung of `RUNGS` the
    fastest classical option of that rung at least as accurate, its time and the PINN's speed-up
    (classical / PINN time; > 1: the PINN is faster; NaN when the rung has nothing as accurate)."""
    acc, lat = ok(frames.get("accuracy")), ok(frames.get("latency"))
    if acc.empty or lat.empty:
        return pd.DataFrame()
    acc = verdict_rows(acc)
    acc = first_seed(acc[trained(acc)])
    error = dict(zip(label(acc), acc["rel_l2"]))
    lat = first_seed(lat[(lat["query"] == query) & trained(lat)])
    fit = first_seed(ok(frames.get("fit")))
    fit_s = dict(zip(label(fit), fit["fit_s"])) if not fit.empty else {}
    rows = []
    for name, pinn_s in zip(label(lat), lat["median_s"]):
        err = error.get(name, float("nan"))
        row = {"query": query, "pinn": name, "pinn_rel_l2": err, "pinn_s": float(pinn_s),
               "fit_s": fit_s.get(name, float("nan"))}
        for rung in RUNGS:
            best = fastest_classical(frames, query, err, rung) if not math.isnan(err) else None
            row[f"{rung}: option"] = best[0] if best else "none as accurate"
            row[f"{rung}: s"] = best[1] if best else float("nan")
            row[f"{rung}: speedup"] = best[1] / pinn_s if best else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)


def crossover_t1(t1: np.ndarray, classical_s: np.ndarray, pinn_s: np.ndarray) -> tuple[str, float]:
    """Where a classical single-point cost (rising with t1: it integrates from 0) crosses a PINN's
    (about flat), from their medians at the same t1 values (s). Returns (how, t1 s): "classical
    cheaper everywhere" / "PINN cheaper everywhere" (NaN), or "crossover" at the t1 where the
    difference changes sign, linearly interpolated between the two measured t1 around it."""
    order = np.argsort(t1)
    t1, gap = np.asarray(t1, float)[order], (np.asarray(classical_s, float) - np.asarray(pinn_s, float))[order]
    if (gap < 0).all():
        return "classical cheaper everywhere", float("nan")
    if (gap > 0).all():
        return "PINN cheaper everywhere", float("nan")
    i = int(np.argmax(np.sign(gap[1:]) != np.sign(gap[:-1])))
    return "crossover", float(t1[i] - gap[i] * (t1[i + 1] - t1[i]) / (gap[i + 1] - gap[i]))
