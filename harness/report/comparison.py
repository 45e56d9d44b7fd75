"""Two runs' verdicts side by side: each verdict of run A beside run B's, whether they agree, one
is a tie or they flip (`compare_runs`, `compare_table`), and the spread of log(ratio) from one run
to the other beyond each run's own samples (`run_to_run_sigma`). Pure pandas, no measurement."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from harness.measure.paired import CLASSICAL_FASTER, CONFIDENCE, PINN_FASTER, ratio_interval
from harness.report.frames import label, ok
from harness.report.verdicts import ratio_text, verdicts

__all__ = ["AGREE", "FLIP", "TIE_IN_ONE", "compare_runs", "compare_table", "run_to_run_sigma"]

AGREE, FLIP, TIE_IN_ONE = "agree", "FLIP", "tie in one run"


def compare_runs(frames_a: dict, frames_b: dict) -> pd.DataFrame:
    """Every verdict of run A beside run B's of the same case, PINN and query: both labels,
    ratios and intervals, and whether they agree (the same label), one is a tie (`TIE_IN_ONE`)
    or they flip (opposite sides); where both runs have the classical surrogate's verdicts, the same
    of those ("surrogate agreement", "" where one run has none)."""
    a, b = verdicts(frames_a), verdicts(frames_b)
    if a.empty or b.empty:
        return pd.DataFrame()
    both = a.merge(b, on=["case", "pinn", "query"], suffixes=(" A", " B"))
    both = both.assign(agreement=[_agreement(la, lb) for la, lb in zip(both["verdict A"], both["verdict B"])])
    if {"surrogate verdict A", "surrogate verdict B"} <= set(both.columns):
        both["surrogate agreement"] = [_agreement(la, lb) if isinstance(la, str) and isinstance(lb, str) else ""
                                       for la, lb in zip(both["surrogate verdict A"], both["surrogate verdict B"])]
    return both


def _agreement(label_a: str, label_b: str) -> str:
    """`AGREE` (the same label), `FLIP` (opposite sides) or `TIE_IN_ONE`."""
    if label_a == label_b:
        return AGREE
    return FLIP if {label_a, label_b} == {PINN_FASTER, CLASSICAL_FASTER} else TIE_IN_ONE


def compare_table(frames_a: dict, frames_b: dict) -> pd.DataFrame:
    """`compare_runs` as text: case, query, PINN, each run's verdict and ratio [95 % CI], agreement."""
    c = compare_runs(frames_a, frames_b)
    return pd.DataFrame([{"case": r["case"], "query": r["query"], "PINN": r["pinn"],
                          "run A": f"{r['verdict A']}, {ratio_text(r, ' A')}", "run B": f"{r['verdict B']}, {ratio_text(r, ' B')}",
                          "agreement": r["agreement"]} for _, r in c.iterrows()])


def run_to_run_sigma(frames_a: dict, frames_b: dict) -> tuple[float, int]:
    """(sigma, n): the standard deviation of log(ratio) from one run to the other beyond what each
    run's paired samples show, from the n seed rows both runs timed (same case, PINN, query and
    seed): with d the difference of the two log ratios and s_A, s_B the standard errors of each
    within its run (the bootstrap alone, `ratio_interval(..., run_to_run=0)`, half its log width
    over the normal quantile), E[d**2] = s_A**2 + s_B**2 + 2 sigma**2; sigma from the means, 0 when
    the within-run spread explains all of it; (nan, 0) without such rows."""
    z = float(stats.norm.ppf(0.5 + CONFIDENCE / 2))
    key = ["case", "pinn", "query", "pinn_seed"]

    def timed(frames: dict) -> pd.DataFrame:
        rows = ok(frames.get("verdict"))
        if rows.empty or "pinn_samples_s" not in rows:
            return pd.DataFrame(columns=[*key, "log_ratio", "se"])
        rows = rows[rows["pinn_samples_s"].map(lambda x: isinstance(x, list) and len(x) >= 2)]
        intervals = [ratio_interval(p, r, run_to_run=0, repeat=False) for p, r in zip(rows["pinn_samples_s"], rows["rival_samples_s"])]
        return pd.DataFrame({**{k: rows[k].to_numpy() for k in key[:-1] if k != "pinn"}, "pinn": label(rows).to_numpy(),
                             "pinn_seed": rows["pinn_seed"].to_numpy(),
                             "log_ratio": [math.log(r) for r, _, _ in intervals],
                             "se": [math.log(high / low) / (2 * z) for _, low, high in intervals]})

    both = timed(frames_a).merge(timed(frames_b), on=key, suffixes=("_a", "_b"))
    if both.empty:
        return math.nan, 0
    excess = float(np.mean((both["log_ratio_a"] - both["log_ratio_b"]) ** 2) - np.mean(both["se_a"] ** 2 + both["se_b"] ** 2))
    return math.sqrt(max(excess, 0.0) / 2), len(both)
