"""Speed-ups at matched accuracy: the Pareto front of a classical error-time curve and the time it
takes to reach a PINN's error (`time_at_accuracy`, `matched_speedups`), the queries after which
training pays off (`break_even`) and where a single-point cost crosses a PINN's in t1
(`crossover_t1`)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report.frames import label, ok, trained

__all__ = ["break_even", "crossover_t1", "matched_speedups", "pareto_front", "time_at_accuracy"]


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
