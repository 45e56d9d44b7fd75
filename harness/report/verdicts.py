"""The verdict suite's rows -> the verdict of each case, PINN and query over its seeds, its tables
(the comparison of two runs: `harness.report.comparison`). Pure pandas, no measurement.

A verdict over seeds: "PINN faster" when every seed's label is (each seed against the rival matched
to its own accuracy), "classical faster" when every seed's is (a seed that missed the accuracy
gate counts so), "no rival" when no seed had one, else "tie"; it quotes how many seeds say what
and the worst seed for the PINN (the least ratio; a seed without a ratio, as a loss, first).
Rows that carry the second rival, the classical surrogate (`surrogate_*`), get its verdict over
seeds by the same rule ("not applicable" when no seed had one made for the case), its worst seed
and both fit seconds; rows without those columns give the tables they gave.
"""

from __future__ import annotations

import functools
import math
import re

import numpy as np
import pandas as pd

from harness.measure.paired import (
    CLASSICAL_FASTER,
    INTERVAL,
    NO_RIVAL,
    NOT_APPLICABLE,
    PINN_FASTER,
    TIE,
    TIE_FACTOR,
    ratio_interval,
    verdict_label,
)
from harness.report.format import fmt
from harness.report.frames import label, ok
from harness.report.ladder import GRID_QUERY, POINT_QUERY

__all__ = ["HEADLINE", "RULE_SHORT", "RULE_SURROGATE", "headline", "headline_table", "ratio_text", "restated",
           "verdict_summary", "verdict_table", "verdicts"]

# The README's queries: the paper's grid and single point, one trajectory, and the batches of points.
HEADLINE = (GRID_QUERY, "1 trajectories x 201 times", POINT_QUERY)
RULE = (f"Ratio: the rival's median time over the PINN's (> 1: the PINN is faster), from paired samples "
        f"taken interleaved in rounds minutes apart; the 95 % interval of a repeat run's ratio (paired bootstrap "
        f"and the spread between runs). A side is called "
        f"faster only when the whole interval lies beyond {TIE_FACTOR:g}x, and only when every seed says so; "
        f"otherwise tie. The rival: the fastest point of a compiled classical solver's precision sweep at "
        f"least as accurate as that seed's PINN in the angles (centre-of-inertia relative on the networks) and "
        f"the speeds, on that query and off the training points; the PINN on its fastest query path there (its "
        f"framework's evaluator or the compiled numba one). Figures of the worst seed for the PINN.")


RULE_SHORT = (f"A side wins only where the whole 95 % interval of a repeat run's ratio (rival time over PINN time, "
              f"from paired samples) lies beyond {TIE_FACTOR:g}x on every seed, against the fastest "
              f"compiled classical solver at least as accurate; otherwise tie.")


RULE_SURROGATE = ("The surrogate: the second rival by the same rule, the fastest configuration of a classical "
                  "surrogate with no network (a model fitted to a solver's trajectories; its precision sweep) at "
                  "least as accurate, fitted once per case; fit seconds, PINN / surrogate, of its worst seed.")


def over_seeds(labels: list[str]) -> str:
    """A verdict over seeds: the label every seed has, else "tie"."""
    for side in (PINN_FASTER, CLASSICAL_FASTER, NO_RIVAL, NOT_APPLICABLE):
        if all(x == side for x in labels):
            return side
    return TIE


def _by_seed(labels: list[str]) -> str:
    return ", ".join(f"{x} on {labels.count(x)} of {len(labels)}" for x in dict.fromkeys(labels))


def _surrogate(g: pd.DataFrame) -> dict:
    """The surrogate's verdict of one case, PINN and query's seed rows `g` (none without its
    columns): label over seeds, the worst seed's surrogate, ratio, interval, median and fit
    seconds beside that seed's PINN's, and the note."""
    if "surrogate_label" not in g or g["surrogate_label"].isna().all():
        return {}
    labels = g["surrogate_label"].tolist()
    ratios = g["surrogate_ratio"] if "surrogate_ratio" in g else pd.Series(np.nan, index=g.index)
    worst = g.loc[ratios.fillna(-math.inf).idxmin()]
    return {"surrogate verdict": over_seeds(labels), "surrogate by seed": _by_seed(labels),
            "surrogate": worst.get("surrogate", "") or "", "surrogate_note": worst.get("surrogate_note", "") or "",
            "pinn_fit_s": worst.get("fit_s", np.nan),
            **{key: worst.get(key, np.nan) for key in ("surrogate_ratio", "surrogate_ratio_low", "surrogate_ratio_high",
                                                        "surrogate_median_s", "surrogate_fit_s")}}


def headline(v: pd.DataFrame) -> pd.Series:
    """Which verdicts (rows of `verdicts`) are the README's: the queries of `HEADLINE` and the
    batches of points."""
    return v["query"].isin(HEADLINE) | (v["kind"] == "points batch")


@functools.cache
def _current_interval(pinn_s: tuple[float, ...], rival_s: tuple[float, ...]) -> tuple[float, float]:
    """(low, high): the interval of paired samples (s) under the current rule (`ratio_interval`,
    seeded: the same samples give the same interval), kept for the process, since one report states
    the same rows several times (each case's table, the heat map, the index, the README's bullets;
    `swingbench compare` each run's more than once)."""
    _, low, high = ratio_interval(pinn_s, rival_s)
    return low, high


def restated(rows: pd.DataFrame) -> pd.DataFrame:
    """Verdict seed rows with each interval and label stated under the current rule (`INTERVAL`):
    a row stored under another (or, written before the rule was recorded, none) has them recomputed
    from its paired samples, the ODE rival's and the surrogate's; rows without samples (a loss by
    the gate, no rival) as they are. The rows on disk are not changed."""
    if rows.empty or "pinn_samples_s" not in rows:
        return rows
    rows = rows.copy()
    stale = rows["interval"] != INTERVAL if "interval" in rows else pd.Series(True, index=rows.index)
    sides = (("pinn_samples_s", "rival_samples_s", ""), ("surrogate_pinn_samples_s", "surrogate_samples_s", "surrogate_"))
    for pinn, rival, prefix in sides:
        if pinn not in rows or rival not in rows:
            continue
        timed = stale & rows[pinn].map(lambda x: isinstance(x, list) and len(x) >= 2)
        for i in rows.index[timed]:
            low, high = _current_interval(tuple(rows.at[i, pinn]), tuple(rows.at[i, rival]))
            rows.loc[i, [f"{prefix}ratio_low", f"{prefix}ratio_high", f"{prefix}label"]] = [low, high, verdict_label(low, high)]
    return rows.assign(interval=INTERVAL)


def _stopped(g: pd.DataFrame) -> str:
    """The note on seed rows `g` of a unit stopped part-way (their `stopped`: `harness.run.runner.kept`):
    fewer rounds than asked, so fewer samples; "" for whole ones."""
    if "stopped" not in g:
        return ""
    stops = [s for s in dict.fromkeys(g["stopped"].dropna()) if s]
    return "; ".join(f"the unit stopped {s}" for s in stops)


def verdicts(frames: dict) -> pd.DataFrame:
    """One row per case, PINN (spec without seed) and query, in the run's order: the overall
    label, seeds by label, and the worst seed's rival, errors, medians, ratio and interval (stated
    under the current rule, `restated`)."""
    rows = restated(ok(frames.get("verdict")))
    if rows.empty:
        return pd.DataFrame()
    rows = rows.assign(pinn=label(rows), _order=range(len(rows)))
    out = []
    for (case, pinn, query), g in rows.groupby(["case", "pinn", "query"], sort=False):
        labels = g["label"].tolist()
        ratios = g["ratio"] if "ratio" in g else pd.Series(np.nan, index=g.index)
        worst = g.loc[ratios.fillna(-math.inf).idxmin()]
        out.append({"case": case, "pinn": pinn, "query": query, "kind": worst["kind"], "verdict": over_seeds(labels),
                    "seeds": len(labels), "by seed": _by_seed(labels),
                    "worst seed": int(worst["pinn_seed"]), "path": worst.get("pinn_path", ""), "rival": worst.get("rival", ""),
                    "pinn_rel_l2_delta": worst["pinn_rel_l2_delta"], "pinn_rel_l2_omega": worst["pinn_rel_l2_omega"],
                    "rival_rel_l2_delta": worst.get("rival_rel_l2_delta", np.nan),
                    "rival_rel_l2_omega": worst.get("rival_rel_l2_omega", np.nan),
                    "pinn_median_s": worst.get("pinn_median_s", np.nan),
                    "rival_median_s": worst.get("rival_median_s", np.nan),
                    "ratio": worst.get("ratio", np.nan), "ratio_low": worst.get("ratio_low", np.nan),
                    "ratio_high": worst.get("ratio_high", np.nan), "samples": worst.get("samples", np.nan),
                    **{key: worst.get(key, np.nan) for key in ("matched_ratio", "rival_margin", "nearest_factor")},
                    "note": "; ".join(filter(None, (worst.get("rivals_note", "") or "", _stopped(g)))),
                    **_surrogate(g), "_order": g["_order"].min()})
    return pd.DataFrame(out).sort_values("_order").drop(columns="_order").reset_index(drop=True)


def ratio_text(row: pd.Series, suffix: str = "", prefix: str = "") -> str:
    """A verdict's ratio and interval as text, "2.5x [1.9, 3.2]" ("-" without one), from the columns
    `prefix` + "ratio" / "ratio_low" / "ratio_high" + `suffix`."""
    ratio, low, high = (row[f"{prefix}{key}{suffix}"] for key in ("ratio", "ratio_low", "ratio_high"))
    return "-" if pd.isna(ratio) else f"{fmt(ratio, 2)}x [{fmt(low, 2)}, {fmt(high, 2)}]"


def _matched(row: pd.Series) -> str:
    """The matched-accuracy ratio; where there is none but a rival, how much more accurate the
    rival is (the conservative ratio then only an upper bound on the PINN's lead)."""
    matched, margin = row["matched_ratio"], row["rival_margin"]
    if not pd.isna(matched):
        return f"{fmt(matched, 2)}x"
    return "-" if pd.isna(margin) or margin <= 0 else f"- (rival {fmt(1 / margin, 2)}x more accurate)"


def _ms(seconds: float) -> str:
    return "-" if pd.isna(seconds) else fmt(1e3 * seconds)


def _errors(row: pd.Series, side: str) -> str:
    delta, omega = row[f"{side}_rel_l2_delta"], row[f"{side}_rel_l2_omega"]
    return "-" if pd.isna(delta) else f"{fmt(delta)} / {fmt(omega)}"


def _surrogate_cells(r: pd.Series) -> dict[str, str]:
    """The surrogate's cells of a verdict (`RULE_SURROGATE`): its verdict over seeds, the worst
    seed's ratio [95 % CI], the surrogate (or why none) and the fit seconds, PINN / surrogate."""
    if pd.isna(r["surrogate verdict"]):
        return {key: "-" for key in ("surrogate verdict", "surrogate ratio [95 % CI]", "surrogate",
                                     "fit s, PINN / surrogate")}
    return {"surrogate verdict": f"{r['surrogate verdict']} ({r['surrogate by seed']})",
            "surrogate ratio [95 % CI]": ratio_text(r, prefix="surrogate_"),
            "surrogate": r["surrogate"] or r["surrogate_note"],
            "fit s, PINN / surrogate": f"{fmt(r['pinn_fit_s'])} / {fmt(r['surrogate_fit_s'])}"}


def _table(v: pd.DataFrame, with_case: bool) -> pd.DataFrame:
    """The verdicts `v` as text; the column "matched ratio" (`_matched`) where the rows carry it
    (rows written before it have no margin), the surrogate's (`_surrogate_cells`) where they carry it."""
    matched = bool(v["rival_margin"].notna().any())
    surrogate = "surrogate verdict" in v and bool(v["surrogate verdict"].notna().any())
    return pd.DataFrame([{**({"case": r["case"]} if with_case else {}), "query": r["query"], "PINN": r["pinn"],
                          "PINN query path": str(r["path"] or "").replace("query=", "") or "-",
                          "verdict": f"{r['verdict']} ({r['by seed']})",
                          "ratio [95 % CI]": ratio_text(r), **({"matched ratio": _matched(r)} if matched else {}), "PINN ms": _ms(r["pinn_median_s"]),
                          "rival": r["rival"] or r["note"], "rival ms": _ms(r["rival_median_s"]),
                          "rel. L2 angles / speeds, PINN": _errors(r, "pinn"), "rel. L2, rival": _errors(r, "rival"),
                          "samples": "-" if pd.isna(r["samples"]) else int(r["samples"]),
                          **(_surrogate_cells(r) if surrogate else {})}
                         for _, r in v.iterrows()])


def verdict_table(frames: dict) -> pd.DataFrame | None:
    """Every query's verdict of the run's (or a case's) rows (`verdicts`), as text."""
    v = verdicts(frames)
    return None if v.empty else _table(v, with_case=v["case"].nunique() > 1)


def headline_table(frames: dict) -> pd.DataFrame | None:
    """The verdicts of the README's queries (`headline`), every case."""
    v = verdicts(frames)
    if v.empty:
        return None
    v = v[headline(v)]
    return None if v.empty else _table(v, with_case=True)


def _tally(g: pd.DataFrame, verdict: str, ratio: str, sides: tuple[tuple[str, str], ...]) -> list[str]:
    """How many of the verdicts `g` (column `verdict`) each of `sides` ((label, words)) has, with
    the range of the worst seed's ratio (column `ratio`), the count over the accuracy gate and
    where the PINN wins; the rest as "no rival on N" and "not applicable on N"."""
    parts = []
    for name, side in sides:
        won = g[g[verdict] == name]
        if won.empty:
            continue
        ratios = won[ratio].dropna()
        spread = "" if ratios.empty else f" ({fmt(ratios.min(), 2)}x" + (
            "" if len(ratios) == 1 else f" to {fmt(ratios.max(), 2)}x") + ")"
        gated = int(won[ratio].isna().sum()) if name == CLASSICAL_FASTER else 0
        if gated:
            spread += f", {gated} of them over the accuracy gate"
        where = ""
        if name == PINN_FASTER:
            where = ": " + ", ".join(won["query"].head(3)) + (", ..." if len(won) > 3 else "")
        parts.append(f"{side} {len(won)}{spread}{where}")
    for name in (NO_RIVAL, NOT_APPLICABLE):
        rest = int((g[verdict] == name).sum())
        if rest:
            parts.append(f"{name} on {rest}")
    return parts


def _not_timed(frames: dict) -> dict[str, str]:
    """case -> "; not timed on N (why)": the queries whose verdict rows were skipped or failed (the
    PINN's call over the time limit, an answer over memory, an error), each query once; the reason
    with its figures left out where every such row gives the same one."""
    rows = frames.get("verdict")
    if rows is None or rows.empty or "status" not in rows:
        return {}
    bad = rows[rows["status"].astype(str) != "ok"]
    out = {}
    for case, g in bad.groupby("case", sort=False):
        reasons = {re.sub(r"estimated [^,]+, over", "estimated over", str(s).split(": ", 1)[-1])
                   for s in g["status"]}
        why = reasons.pop() if len(reasons) == 1 else "skipped or failed, see its table"
        out[case] = f"; not timed on {g['query'].nunique()} ({why})"
    return out


def verdict_summary(frames: dict) -> str:
    """The answer in a few bullets, from the verdicts (`verdicts`): per case, how many queries each
    side wins and by how much (the range of the worst seed's ratio), the ties, where the PINN wins,
    the queries not timed (`_not_timed`), and the PINN's error in the angles; and, where the rows
    carry it, the same against the classical surrogate; "" without verdicts."""
    v = verdicts(frames)
    if v.empty:
        return ""
    out = []
    skipped = _not_timed(frames)
    for case, g in v.groupby("case", sort=False):
        parts = _tally(g, "verdict", "ratio", ((PINN_FASTER, "the PINN wins"), (CLASSICAL_FASTER, "the solver wins"),
                                               (TIE, "a tie on")))
        errors = g["pinn_rel_l2_delta"].dropna()
        accuracy = "" if errors.empty else (f"; the PINN's rel. L2 in the angles {fmt(errors.min())}"
                                            + ("" if errors.min() == errors.max() else f" to {fmt(errors.max())}"))
        against = ""
        if "surrogate verdict" in g and g["surrogate verdict"].notna().any():
            against = ". Against the classical surrogate: " + "; ".join(_tally(
                g, "surrogate verdict", "surrogate_ratio",
                ((PINN_FASTER, "the PINN wins"), (CLASSICAL_FASTER, "the surrogate wins"), (TIE, "a tie on"))))
        out.append(f"- **{case}**, {len(g)} queries: " + "; ".join(parts) + skipped.get(case, "") + accuracy
                   + against + ".")
    return "\n".join(out) + "\n"
