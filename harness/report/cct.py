"""The cct suite's tables (`harness.suites.cct`): every search of a fault case (`cct_table`) and the
headline per fault case and PINN (`cct_headline`, the README's and the results index's).

Within a case, a surrogate's rival is the fastest classical search whose CCT is at least as close
to the reference's as the surrogate's, or within the bracket (1 ms) when the surrogate is: the
bracket is the resolution a search narrows to. A search whose bracket stayed wider (the adapter
refused clearing times inside it, `harness.suites.cct`) or that found no CCT has no error to match:
it is no rival, it counts as a loss for a surrogate, and its cells give its note. Break-even N* = training / (rival's search -
surrogate's search) (`speedups.break_even`): the CCT searches after which training and N*
surrogate searches cost no more than N* rival searches ("never" when the surrogate's search is not
faster). A surrogate trained on one contingency answers that contingency: it pays off on its own
only for N* <= 1.

The verdict of a seed: the ratio of the medians (rival over surrogate, > 1: the surrogate is
faster), a side faster only beyond `TIE_FACTOR` (1.2x) with the interquartile ranges of the two
searches apart, otherwise tie; a seed whose CCT is more than `CCT_GATE_S` (5 ms) off counts as a
loss. A side wins the headline only when every seed says so. Each search is timed warm by the cct
suite on its own (median of repeats), not paired and interleaved as the verdict suite's queries are.
"""

from __future__ import annotations

import math

import pandas as pd

from harness.measure.paired import CLASSICAL_FASTER, NO_RIVAL, PINN_FASTER, TIE, TIE_FACTOR
from harness.report.format import fmt, latency_cell
from harness.report.frames import label, ok, trained
from harness.report.speedups import break_even

__all__ = ["CCT_ABOUT", "CCT_GATE_S", "CCT_HEADLINE", "CCT_TITLE", "cct_headline", "cct_summary", "cct_table"]

CCT_GATE_S = 5e-3  # s: a surrogate's CCT further than this from the reference's counts as a loss

CCT_TITLE = "Critical clearing time"
CCT_ABOUT = ("Each adapter's CCT to a bracket of 1 ms, or its note where the search stopped short (the criterion: a machine more than pi rad from the centre of "
             "inertia within the horizon, judged every 10 ms), its error against the reference's (bisection to 1e-6 s "
             "on DOP853 at 1e-12), the warm time of the whole search (median ± half the interquartile range) and, for "
             "a surrogate, its training and break-even against its rival: the fastest classical search at least as "
             "close to the reference (or within the 1 ms bracket).")
CCT_HEADLINE = ("Per fault case: the reference CCT; each classical adapter's CCT error and time to CCT (its fastest "
                "configuration); the fastest classical search within the 1 ms bracket; each PINN's "
                "CCT error, time to CCT and training (worst seed), its break-even in CCT searches against its rival "
                "and the verdict over its seeds (a side faster only beyond 1.2x with the quartiles of the two "
                "searches apart, on every seed; a CCT more than 5 ms off counts as a loss; searches timed warm, "
                "each on its own)")


def _frame(frames: dict) -> pd.DataFrame:
    df = ok(frames.get("cct"))
    if df.empty or "cct_s" not in df:
        return pd.DataFrame()
    seed = df["pinn_seed"].fillna(df["seed"]) if "pinn_seed" in df else df["seed"]
    df = df.assign(label=label(df), model_seed=seed.astype(int), surrogate=trained(df).to_numpy())
    fits = ok(frames.get("fit"))
    own = pd.Series(math.nan, index=df.index)
    if not fits.empty:
        key = ["solver", "config", "variant", "seed"]
        merged = df[key].merge(fits[[*key, "fit_s"]].drop_duplicates(key), on=key, how="left")
        own = pd.Series(merged["fit_s"].to_numpy(), index=df.index)
    fit_s = df["seed_fit_s"].fillna(own) if "seed_fit_s" in df else own
    # a bracket left wider than the suite's (refusals inside it) carries no error to match
    narrowed = (df["unstable_s"] - df["stable_s"]) <= df["bracket_s"] * (1 + 1e-9)
    return df.assign(training_s=fit_s.where(df["surrogate"]), raw_error_s=df["cct_error_s"],
                     cct_error_s=df["cct_error_s"].where(narrowed))


def _error_cell(r: pd.Series) -> str:
    """A search's CCT error (ms), with its note where it has one (the error only where the
    bracket stayed wide around a CCT)."""
    if r["note"] == "":
        return fmt(1e3 * r["cct_error_s"], 2)
    return r["note"] if math.isnan(r["raw_error_s"]) else f"{fmt(1e3 * r['raw_error_s'], 2)}; {r['note']}"


def _rival(classical: pd.DataFrame, error_s: float, bracket_s: float) -> pd.Series | None:
    """The fastest classical search at least as close to the reference as `error_s` (s), or within
    the bracket; None when there is none."""
    close = classical[classical["cct_error_s"].abs() <= max(abs(error_s), bracket_s)]
    return None if close.empty else close.loc[close["median_s"].idxmin()]


def _break_even(classical: pd.DataFrame, surrogate: pd.Series) -> tuple[pd.Series | None, float]:
    """A surrogate search's rival (`_rival`) and its break-even N* against it (NaN without one)."""
    rival = _rival(classical, surrogate["cct_error_s"], surrogate["bracket_s"])
    if rival is None:
        return None, math.nan
    return rival, break_even(surrogate["training_s"], rival["median_s"], surrogate["median_s"])


def _seed_verdict(pinn: pd.Series, rival: pd.Series | None) -> str:
    if not abs(pinn["cct_error_s"]) <= CCT_GATE_S:  # NaN (no CCT in the range) included
        return CLASSICAL_FASTER
    if rival is None:
        return NO_RIVAL
    ratio = rival["median_s"] / pinn["median_s"]
    if ratio > TIE_FACTOR and pinn["q75_s"] < rival["q25_s"]:
        return PINN_FASTER
    if ratio < 1 / TIE_FACTOR and rival["q75_s"] < pinn["q25_s"]:
        return CLASSICAL_FASTER
    return TIE


def _each_adapter(classical: pd.DataFrame) -> str:
    """One cell: each classical adapter's fastest search (any config or variant), its CCT error and
    time (ms), fastest first."""
    fastest = classical.loc[classical.groupby("solver")["median_s"].idxmin()].sort_values("median_s")
    return "; ".join(f"{r['solver']} {_error_cell(r)}" + (f" / {fmt(1e3 * r['median_s'])}" if r["note"] == "" else "")
                     for _, r in fastest.iterrows())


def cct_table(frames: dict) -> pd.DataFrame:
    """Every search of the run: per case, adapter and model seed, the CCT, the reference's, the
    error, the search's time, solves and trajectories (and the clearing times refused, where a search
    of the run had any); for a surrogate its training (s) and its
    break-even against its rival."""
    df = _frame(frames)
    if df.empty:
        return df
    rows = []
    for _, case in df.groupby("case", sort=False):
        classical = case[~case["surrogate"]]
        for _, r in case.iterrows():
            row = {"case": r["case"], "solver": r["label"], "seed": r["model_seed"] if r["surrogate"] else "-",
                   "search": r["method"], "CCT (s)": fmt(r["cct_s"], 5), "reference CCT (s)": fmt(r["reference_cct_s"], 7),
                   "CCT error (ms)": _error_cell(r),
                   "time to CCT (ms)": latency_cell(r), "solves": int(r["solves"]), "trajectories": int(r["trajectories"])}
            if r["surrogate"]:
                _, n_star = _break_even(classical, r)
                row["training (s)"] = fmt(r["training_s"])
                row["break-even N* (CCT searches)"] = "never" if n_star == math.inf else fmt(n_star)
            if r.get("refused", 0) > 0:  # rows written before the suite counted refusals have none
                row["refused"] = int(r["refused"])
            rows.append(row)
    return pd.DataFrame(rows)


def cct_headline(frames: dict) -> pd.DataFrame:
    """Per fault case and PINN configuration (its seeds on their fastest query path each): the
    reference CCT, each classical adapter's CCT error and time (its fastest search), the fastest
    classical search within the bracket, the PINN's CCT error, time to
    CCT and training of its worst seed (the slowest search), its break-even and the verdict."""
    df = _frame(frames)
    if df.empty:
        return df
    rows = []
    for name, case in df.groupby("case", sort=False):
        classical = case[~case["surrogate"]]
        best = _rival(classical, 0.0, float(case["bracket_s"].iloc[0]))
        head = {"case": name, "reference CCT (s)": fmt(case["reference_cct_s"].iloc[0], 7),
                "each classical adapter: CCT error / time to CCT (ms)": _each_adapter(classical),
                "fastest classical within 1 ms": best["label"] if best is not None else "none",
                "its time to CCT (ms)": latency_cell(best) if best is not None else "n/a"}
        pinns = case[case["surrogate"]]
        if pinns.empty:
            rows.append({**head, "PINN": "none in this run"})
            continue
        for pinn, runs in pinns.groupby(pinns["solver"] + " " + pinns["config"], sort=False):
            fastest = runs.loc[runs.groupby("model_seed")["median_s"].idxmin()]  # each seed's fastest path
            verdicts, worst, worst_n = [], None, -math.inf
            for _, r in fastest.iterrows():
                rival, n_star = _break_even(classical, r)
                verdicts.append(_seed_verdict(r, rival))
                if worst is None or r["median_s"] > worst["median_s"]:
                    worst, worst_n = r, n_star
            label_ = verdicts[0] if len(set(verdicts)) == 1 else TIE
            counts = ", ".join(f"{v} on {verdicts.count(v)} of {len(verdicts)}" for v in dict.fromkeys(verdicts))
            short = fastest[fastest["cct_error_s"].isna()]  # a seed without an error to match shows its note
            error = (_error_cell(short.iloc[0]) if not short.empty
                     else fmt(1e3 * fastest["cct_error_s"].iloc[fastest["cct_error_s"].abs().argmax()], 2))
            rows.append({**head, "PINN": pinn, "seeds": len(fastest), "PINN CCT error (ms)": error,
                         "PINN time to CCT (ms)": latency_cell(worst), "training (s)": fmt(fastest["training_s"].max()),
                         "break-even N* (CCT searches)": "never" if worst_n == math.inf else fmt(worst_n),
                         "verdict": f"{label_} ({counts})"})
    return pd.DataFrame(rows)


def cct_summary(frames: dict) -> str:
    """The CCT searches of a run in one bullet per PINN configuration (its worst seed on each fault
    case, as `cct_headline`): on how many cases it finds a CCT, how far from the reference's (ms; and
    on how many refusals left the bracket wider than the suite's), the cases where it finds none, the
    time of its search against the fastest classical search within the bracket (the ratio rival time
    over PINN time, as the verdicts give it), and its break-even; "" without a surrogate's search."""
    df = _frame(frames)
    if df.empty or not df["surrogate"].any():
        return ""
    out = []
    pinns = df[df["surrogate"]]
    for pinn, runs in pinns.groupby(pinns["solver"] + " " + pinns["config"], sort=False):
        worst = runs.loc[runs.groupby("case", sort=False)["median_s"].idxmax()]  # the slowest seed of each case
        found = worst[worst["raw_error_s"].notna()]
        missing = worst.loc[worst["raw_error_s"].isna(), "case"].tolist()
        ratios, never = [], 0
        for _, r in worst.iterrows():
            classical = df[(df["case"] == r["case"]) & ~df["surrogate"]]
            best = _rival(classical, 0.0, float(r["bracket_s"]))
            if best is not None:
                ratios.append(best["median_s"] / r["median_s"])
            never += _break_even(classical, r)[1] == math.inf
        errors = 1e3 * found["raw_error_s"].abs()
        wide = int(found["cct_error_s"].isna().sum())
        text = f"- **CCT of {len(worst)} fault cases**, `{pinn}`: found on {len(found)}"
        if len(found):
            text += f", {fmt(errors.min(), 2)} ms to {fmt(errors.max(), 2)} ms from the reference"
            text += f" (refusals left the bracket wider than 1 ms on {wide})" if wide else ""
        text += f"; none on {len(missing)} ({', '.join(missing)})" if missing else ""
        text += (f"; its search {fmt(worst['median_s'].min(), 2)} s to {fmt(worst['median_s'].max(), 2)} s, "
                 f"the fastest classical search within 1 ms {fmt(min(ratios), 2)}x to {fmt(max(ratios), 2)}x as long"
                 if ratios else "")
        text += f"; break-even never on {never} of {len(worst)}." if never else "."
        out.append(text)
    return "\n".join(out) + "\n"
