"""The scaling suite's tables: cost, memory and accuracy against the number of machines N, fitted
power laws, and the break-even number of trajectories of each PINN against N. Pure pandas/numpy
on the rows of one run (the `scaling` rows and the `fit` rows of the same units); no I/O."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report.format import fmt
from harness.report.frames import label, ok, trained
from harness.report.speedups import break_even

__all__ = ["COSTS", "LARGE_N_POINTS", "break_even_by_n", "exponents", "log_log_slope", "scaling_frame",
           "scaling_table", "status_by_n"]

# The cost columns of `scaling_frame`, with their names in the tables.
COSTS = {"prep_s": "preparation (s)", "grid_s": "grid query (s)", "point_s": "single point (s)",
         "peak_rss_mib": "peak memory (MiB)", "steps": "steps (one trajectory)", "step_s": "s per step",
         "rhs_s": "s per right-hand side"}
_KEYS = ["case", "solver", "config", "variant", "seed"]
# The growth at scale: the slope over this many of the largest N measured, beside the global fit
# (which the small-N overhead dominates).
LARGE_N_POINTS = 3
# The scaling family's horizon (s), for rows written before the suite recorded `horizon_s`
_DEFAULT_HORIZON_S = 10.0
# A PINN this far off (rel. L2 of the angles) has not learnt the trajectories: no break-even is
# computed for it (any classical solver is "as accurate" and slower than a network's forward pass).
UNCONVERGED_REL_L2 = 0.1


def scaling_frame(frames: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """One row per adapter spec and case measured by the scaling suite: N (`machines`), the spec's
    `label`, preparation (its fit row's `fit_s`, s), grid and single-point query medians (s), peak
    resident memory (MiB, when the unit ran in a process of its own), rel. L2 and the grid size;
    `trains` for PINNs; `per_sim_s`, the grid query's seconds per trajectory per simulated second
    (grid median / trajectories / horizon); `steps`, `step_s` and `rhs_s`, the single point's
    trajectory's steps and its time per step and per right-hand side evaluation (NaN for an adapter
    that does not count them, `AbstractSolver.counts_steps`). Only the first seed of a trained spec is measured by
    the suite."""
    scaling = ok(frames.get("scaling"))
    if scaling.empty:
        return pd.DataFrame()
    fits = ok(frames.get("fit"))
    if not fits.empty:
        scaling = scaling.merge(fits[[*_KEYS, "fit_s"]], on=_KEYS, how="left")
    else:
        scaling = scaling.assign(fit_s=np.nan)
    out = pd.DataFrame({
        "case": scaling["case"], "N": scaling["machines"].astype(int), "label": label(scaling),
        "solver": scaling["solver"], "trains": trained(scaling),
        "prep_s": scaling["fit_s"], "grid_s": scaling["grid_median_s"], "point_s": scaling["point_median_s"],
        "peak_rss_mib": scaling.get("peak_rss_mib", pd.Series(np.nan, index=scaling.index)),
        "rel_l2": scaling["rel_l2"], "n_trajectories": scaling["n_trajectories"],
        **{column: scaling.get(column, pd.Series(np.nan, index=scaling.index)).astype(float)
           for column in ("steps", "step_s", "rhs_s")},
    })
    horizon = scaling["horizon_s"] if "horizon_s" in scaling else pd.Series(np.nan, index=scaling.index)
    out["per_sim_s"] = out["grid_s"] / out["n_trajectories"] / horizon.fillna(_DEFAULT_HORIZON_S)
    return out.sort_values(["label", "N"]).reset_index(drop=True)


def scaling_table(frame: pd.DataFrame) -> pd.DataFrame:
    """The scaling rows for reading: per adapter spec and N, every cost and the accuracy."""
    if frame.empty:
        return frame
    table = frame[["label", "N", "case", *COSTS, "per_sim_s", "rel_l2"]].copy()
    for column in (*COSTS, "per_sim_s", "rel_l2"):
        table[column] = table[column].map(fmt)
    return table.rename(columns={**COSTS, "label": "adapter", "rel_l2": "rel. L2 (angles)",
                                 "per_sim_s": "s per simulated s (one trajectory)"})


def log_log_slope(n: np.ndarray, cost: np.ndarray) -> tuple[float, int]:
    """Least-squares slope of log(cost) against log(n) over the finite positive points, and their
    number; NaN when fewer than 3 points or fewer than 2 distinct N."""
    keep = np.isfinite(cost) & (cost > 0) & (n > 0)
    n, cost = n[keep], cost[keep]
    if n.size < 3 or np.unique(n).size < 2:
        return float("nan"), int(n.size)
    return float(np.polyfit(np.log(n), np.log(cost), 1)[0]), int(n.size)


def exponents(frame: pd.DataFrame, min_n: int = 2) -> pd.DataFrame:
    """Fitted exponents b of cost ~ N^b per adapter spec and cost (least squares in log-log over the
    cases with N >= `min_n`: the SMIB's N = 1 has no coupling to scale), the N range fitted; beside
    each, the slope over the `LARGE_N_POINTS` largest N measured (the growth at scale, which the
    global fit understates when small-N overhead dominates it) and that N range."""
    if frame.empty:
        return pd.DataFrame()
    rows = []
    for name, g in frame.groupby("label", sort=False):
        g = g[g["N"] >= min_n]
        if g.empty:
            continue
        row = {"adapter": name, "N range": f"{g['N'].min()}-{g['N'].max()}"}
        for column, title in COSTS.items():
            kind = title.split(" (")[0]
            measured = g[np.isfinite(g[column]) & (g[column] > 0)]
            slope, points = log_log_slope(measured["N"].to_numpy(float), measured[column].to_numpy(float))
            row[f"{kind} exponent"] = "-" if np.isnan(slope) else f"{slope:.2f} ({points} N)"
            largest = measured.nlargest(LARGE_N_POINTS, "N")
            slope, points = log_log_slope(largest["N"].to_numpy(float), largest[column].to_numpy(float))
            row[f"{kind} exponent, largest {LARGE_N_POINTS} N"] = (
                "-" if np.isnan(slope) else f"{slope:.2f} (N {largest['N'].min()}-{largest['N'].max()})")
        rows.append(row)
    return pd.DataFrame(rows)


def status_by_n(frames: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Units of the scaling suite that did not end ok (out of time, out of memory, failed), with
    their case and status: what each adapter could not reach."""
    rows = frames.get("scaling")
    if rows is None or rows.empty or "status" not in rows:
        return pd.DataFrame()
    bad = rows[rows["status"] != "ok"]
    if bad.empty:
        return pd.DataFrame()
    return pd.DataFrame({"adapter": label(bad), "case": bad["case"], "status": bad["status"]}).reset_index(drop=True)


def break_even_by_n(frame: pd.DataFrame) -> pd.DataFrame:
    """Per PINN spec and N: the fastest classical adapter at least as accurate there (grid query
    time per trajectory) and the number of trajectories after which the PINN's preparation pays
    off against it (`speedups.break_even`, preparation minus the classical one's); "never" when
    the PINN is not faster per trajectory, and no rival when no classical adapter is as accurate;
    none either for a PINN at rel. L2 >= `UNCONVERGED_REL_L2` ("not converged")."""
    if frame.empty:
        return pd.DataFrame()
    rows = []
    for n, at_n in frame.groupby("N"):
        classical = at_n[~at_n["trains"]].dropna(subset=["grid_s", "rel_l2"])
        for _, pinn in at_n[at_n["trains"]].dropna(subset=["grid_s", "rel_l2"]).iterrows():
            pinn_s = pinn["grid_s"] / pinn["n_trajectories"]
            rivals = classical[classical["rel_l2"] <= pinn["rel_l2"]]
            row = {"N": int(n), "PINN": pinn["label"], "PINN rel. L2": fmt(pinn["rel_l2"]),
                   "PINN per trajectory (s)": fmt(pinn_s), "PINN preparation (s)": fmt(pinn["prep_s"])}
            if pinn["rel_l2"] >= UNCONVERGED_REL_L2:
                rows.append({**row, "fastest classical at least as accurate": "-",
                             "break-even trajectories": f"not converged (rel. L2 >= {UNCONVERGED_REL_L2:g})"})
                continue
            if rivals.empty:
                rows.append({**row, "fastest classical at least as accurate": "none", "break-even trajectories": "-"})
                continue
            per_traj = rivals["grid_s"] / rivals["n_trajectories"]
            best = rivals.loc[per_traj.idxmin()]
            classical_s = float(per_traj.min())
            prep = float(pinn["prep_s"]) - (0.0 if np.isnan(best["prep_s"]) else float(best["prep_s"]))
            n_star = break_even(max(prep, 0.0), classical_s, pinn_s)
            rows.append({**row, "fastest classical at least as accurate": f"{best['label']} ({fmt(classical_s)} s)",
                         "break-even trajectories": "never" if np.isinf(n_star) else f"{n_star:.3g}"})
    return pd.DataFrame(rows)
