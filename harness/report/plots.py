"""Plots of a run (PNG and PDF): the paper's figure 3, work-precision, latency against t1,
identification error per pair (`harness.report.identification_plot`), a fault case's trajectories
either side of its CCT (`harness.report.cct_plot`). Each function takes the suite frames and the
names of their configurations (`harness.report.labels.Labels`) and returns a figure or None. Every
figure names the case(s) of its rows in its title and shows its durations in one unit chosen from
them (`harness.report.plot_style`); simulated time (t, t1) is in s."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from harness.measure.paired import CLASSICAL_FASTER
from harness.report.cct_plot import cct_plot
from harness.report.frames import label, ok, trained
from harness.report.identification_plot import identification_plot
from harness.report.labels import Labels
from harness.report.plot_style import legend_beside as _legend_beside
from harness.report.plot_style import palette as _palette
from harness.report.plot_style import time_unit, title
from harness.report.verdicts import headline, verdicts
from systems.cases import CASES, standard_grid
from systems.model import relative_angles

__all__ = ["PLOTS", "SCALING_PLOTS", "VERDICT_PLOTS", "make_plots"]


def figure3(frames: dict, names: Labels):
    """Best and worst trajectory (delta and omega of every machine, one line each), predicted vs
    reference, for each PINN configuration's first seed (the paper's figure 3); on a case without
    an infinite bus the angles from its centre of inertia (`systems.model.relative_angles`: the
    absolute angles drift together); none for a case this process has not registered (a
    `--case-file` case, whose reference it cannot integrate)."""
    acc = ok(frames.get("accuracy"))
    if acc.empty or "best_pred" not in acc:
        return None
    acc = acc[trained(acc) & (acc["against"] == "reference") & acc["best_pred"].notna()]
    if acc.empty:
        return None
    acc = acc[acc["seed"] == acc.groupby(["solver", "config"])["seed"].transform("min")]
    if acc["case"].iloc[0] not in CASES:
        return None
    specs = list(dict.fromkeys(label(acc)))
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    case = CASES[acc["case"].iloc[0]]
    t, _ = standard_grid(case)

    def shown(values, quantity: str) -> np.ndarray:  # (n_t, n): the angles against the case's reference
        values = np.asarray(values, float).reshape(t.size, -1)
        return relative_angles(case, values) if quantity == "delta" else values

    for row, quantity in enumerate(("delta", "omega")):
        for col, which in enumerate(("best", "worst")):
            ax = axes[row, col]
            sel = acc[acc["quantity"] == quantity]
            ref_drawn = set()
            for spec, (_, r) in zip(specs, sel.iterrows()):
                key = (r[f"{which}_P1"],)
                if key not in ref_drawn:
                    ref = shown(r[f"{which}_ref"], quantity)
                    ax.plot(t, ref, color="black", lw=2.5, alpha=0.35,
                            label=[f"reference, {case.scenario.symbol}={r[f'{which}_P1']:.4g}"] + ["_"] * (ref.shape[1] - 1))
                    ref_drawn.add(key)
                pred = shown(r[f"{which}_pred"], quantity)
                lines = ax.plot(t, pred, lw=1.2, ls="--")
                for line in lines[1:]:
                    line.set_color(lines[0].get_color())
                lines[0].set_label(names(label(r.to_frame().T).iloc[0]))
            name = quantity if quantity != "delta" or case.has_infinite_bus else "delta - delta_COI"
            ax.set_title(f"{which} trajectory: {name}")
            ax.set_ylabel(f"{name} ({'rad' if quantity == 'delta' else 'rad/s'})")
            ax.grid(alpha=0.3)
            if row == 1:
                ax.set_xlabel("t (s)")
    title(fig, [case.name], "predicted (dashed) against the reference",
          "best and worst trajectory by rel. L2")
    fig.tight_layout()
    fig.legend(*axes[0, 0].get_legend_handles_labels(), fontsize=7, title="best trajectory (left)",
               title_fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 0.93))
    return fig


def work_precision_plot(frames: dict, names: Labels):
    wp = ok(frames.get("work_precision"))
    if wp.empty:
        return None
    wp = wp.assign(label=label(wp))
    colour = _palette(list(wp.loc[~trained(wp), "label"]) + list(wp.loc[trained(wp), "label"]))
    unit = time_unit(wp["median_s"])
    wp = wp.assign(shown=wp["median_s"] * unit.per_s)
    fig, ax = plt.subplots(figsize=(8, 6))
    for name, g in wp[~trained(wp)].groupby("label", sort=False):
        g = g.sort_values("rel_l2_delta")
        ax.plot(g["rel_l2_delta"], g["shown"], marker="o", ms=4, color=colour[name], label=names(name))
    for name, g in wp[trained(wp)].groupby("label", sort=False):
        ax.scatter(g["rel_l2_delta"], g["shown"], marker="*", s=140, zorder=3, color=colour[name],
                   label=f"{names(name)} (PINN)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("rel. L2 error of delta on the 100 x 201 grid")
    ax.set_ylabel(f"warm query time of the grid ({unit.name})")
    title(ax, wp["case"], "work-precision", "classical tolerance sweeps (lines) and PINNs (stars)")
    ax.grid(alpha=0.3, which="both")
    _legend_beside(ax)
    fig.tight_layout()
    return fig


def latency_t1_plot(frames: dict, names: Labels):
    lat = ok(frames.get("latency"))
    if lat.empty or "kind" not in lat:
        return None
    lat = lat[lat["kind"] == "single point"]
    if lat.empty:
        return None
    lat = lat.assign(label=label(lat))
    colour = _palette(lat["label"])
    unit = time_unit(lat["median_s"])
    fig, ax = plt.subplots(figsize=(8, 5))
    for name, g in lat.groupby("label", sort=False):
        g = g.sort_values("t1_s")
        median, q25, q75 = (unit.per_s * g[column] for column in ("median_s", "q25_s", "q75_s"))
        ax.errorbar(g["t1_s"], median, yerr=[median - q25, q75 - median],
                    marker="o", ms=4, capsize=2, color=colour[name], label=names(name),
                    ls="--" if trained(g).any() else "-")
    ax.set_yscale("log")
    ax.set_xlabel("t1, simulated (s)")
    ax.set_ylabel(f"warm query time of delta, omega at t1 ({unit.name})")
    title(ax, lat["case"], "latency at t1", "a classical solver integrates from 0, a PINN evaluates at t1")
    ax.grid(alpha=0.3, which="both")
    _legend_beside(ax)
    fig.tight_layout()
    return fig


def crossover_plot(frames: dict, names: Labels):
    """Single-point cost against t1 for the fastest PINN path and the fastest compiled classical
    option at least as accurate (`harness.report.ladder.crossover`), with the crossover if there is one."""
    from harness.report.ladder import crossover

    x = crossover(frames)
    if x is None:
        return None
    unit = time_unit(np.concatenate([x["classical_s"], x["pinn_s"]]))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(x["t1_s"], unit.per_s * x["classical_s"], marker="o",
            label=f"{names(x['classical'])} (classical, compiled)")
    ax.plot(x["t1_s"], unit.per_s * x["pinn_s"], marker="*", ms=10, ls="--", label=f"{names(x['pinn'])} (PINN)")
    if x["how"] == "crossover":
        ax.axvline(x["t1_cross_s"], color="grey", lw=1)
        ax.annotate(f"crossover at simulated t1 = {x['t1_cross_s']:.3g} s", (x["t1_cross_s"], ax.get_ylim()[1]),
                    xytext=(4, -14), textcoords="offset points", fontsize=8)
    ax.set_yscale("log")
    ax.set_xlabel("t1, simulated (s)")
    ax.set_ylabel(f"warm solve() of delta, omega at t1 ({unit.name})")
    title(ax, ok(frames.get("latency"))["case"], "single point against t1", x["how"])
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _log_log(frame: pd.DataFrame, column: str, ylabel: str, ax, names: Labels, per: float = 1.0) -> None:
    """`column` (times `per`: a unit) against N, one line per adapter spec, log-log; the fitted
    slope in the legend."""
    from harness.report.scaling import log_log_slope

    colours = _palette(frame["label"])
    for name, g in frame.groupby("label", sort=False):
        g = g[np.isfinite(g[column].astype(float)) & (g[column].astype(float) > 0)]
        if g.empty:
            continue
        coupled = g["N"].to_numpy() >= 2  # as `exponents`: the SMIB's N = 1 has no coupling to scale
        slope, _ = log_log_slope(g["N"].to_numpy(float)[coupled], g[column].to_numpy(float)[coupled])
        tag = "" if np.isnan(slope) else f" (N^{slope:.2f})"
        ax.plot(g["N"], per * g[column].astype(float), "o-" if not g["trains"].iloc[0] else "s--", color=colours[name],
                label=f"{names(name)}{tag}", ms=4)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("machines N")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)


def scaling_cost_plot(frames: dict, names: Labels):
    """Preparation, grid query, single point and peak memory against N (log-log), every adapter."""
    frame = frames.get("scaling_frame")
    if frame is None or frame.empty:
        return None
    unit = time_unit(frame[["prep_s", "grid_s", "point_s"]].to_numpy(float))
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    for ax, (column, ylabel, per) in zip(axes.ravel(), (
            ("prep_s", f"preparation ({unit.name})", unit.per_s), ("grid_s", f"grid query ({unit.name})", unit.per_s),
            ("point_s", f"single point ({unit.name})", unit.per_s), ("peak_rss_mib", "peak memory (MiB)", 1.0))):
        _log_log(frame, column, ylabel, ax, names, per)
    handles, labels = axes[0, 1].get_legend_handles_labels()
    fig.legend(handles, [lab.split(" (N^")[0] for lab in labels], fontsize=7, loc="upper left",
               bbox_to_anchor=(1.0, 0.95))
    title(fig, frame["case"], "cost against the number of machines", "fitted exponents in the scaling tables")
    fig.tight_layout()
    return fig


def scaling_accuracy_plot(frames: dict, names: Labels):
    """Rel. L2 of the angles (COI-relative without an infinite bus) against N, every adapter."""
    frame = frames.get("scaling_frame")
    if frame is None or frame.empty:
        return None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    _log_log(frame.assign(label=frame["label"]), "rel_l2", "rel. L2 of the angles", ax, names)
    title(ax, frame["case"], "accuracy against the number of machines")
    _legend_beside(ax)
    return fig


PLOTS = {"figure3": figure3, "work_precision": work_precision_plot, "latency_t1": latency_t1_plot,
         "crossover": crossover_plot, "identification": identification_plot, "cct": cct_plot}


SCALING_PLOTS = {"scaling_cost": scaling_cost_plot, "scaling_accuracy": scaling_accuracy_plot}


def verdict_plot(frames: dict, names: Labels):
    """The headline verdicts as a heat map: log10 of the ratio rival / PINN (worst seed; blue:
    the PINN faster, red: classical), case and PINN by row, query by column, each cell's label and
    ratio written in it; ties hatched under their text; a loss without a ratio (the PINN over the
    accuracy gate) drawn as the strongest loss. Where the run has the classical surrogate's verdicts,
    each case and PINN has a second row: the same against the surrogate without a network."""
    v = verdicts(frames)
    v = v[headline(v)] if not v.empty else v
    if v.empty:
        return None
    v = v.assign(against="ODE solver")
    if "surrogate verdict" in v:
        s = v[v["surrogate verdict"].map(lambda x: isinstance(x, str))]
        v = pd.concat([v, s.assign(verdict=s["surrogate verdict"], ratio=s["surrogate_ratio"], against="surrogate")])
    present = set(zip(v["case"], v["pinn"], v["against"]))
    rows = [(case, pinn, against) for case, pinn in dict.fromkeys(zip(v["case"], v["pinn"]))
            for against in ("ODE solver", "surrogate") if (case, pinn, against) in present]
    cols = list(dict.fromkeys(v["query"]))
    at = [(rows.index((r["case"], r["pinn"], r["against"])), cols.index(r["query"])) for _, r in v.iterrows()]
    grid = np.full((len(rows), len(cols)), np.nan)
    for (i, j), ratio in zip(at, v["ratio"]):
        grid[i, j] = np.log10(ratio) if ratio > 0 else np.nan
    bound = max(1.0, float(np.nanmax(np.abs(grid)))) if np.isfinite(grid).any() else 1.0
    for (i, j), (_, r) in zip(at, v.iterrows()):
        if np.isnan(grid[i, j]) and r["verdict"] == CLASSICAL_FASTER:
            grid[i, j] = -bound
    fig, ax = plt.subplots(figsize=(1.9 * len(cols) + 3, 0.6 * len(rows) + 1.5))
    image = ax.imshow(grid, cmap="RdBu", vmin=-bound, vmax=bound, aspect="auto")
    for (i, j), (_, r) in zip(at, v.iterrows()):
        text = f"{r['verdict']}\n(accuracy gate)" if np.isnan(r["ratio"]) and r["verdict"] == CLASSICAL_FASTER \
            else r["verdict"] if np.isnan(r["ratio"]) else f"{r['ratio']:.2g}x\n{r['verdict']}"
        tie = r["verdict"] == "tie"
        dark = not tie and np.isfinite(grid[i, j]) and abs(grid[i, j]) > 0.6 * bound
        ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white" if dark else "black", zorder=3,
                bbox={"facecolor": "white", "alpha": 0.8, "lw": 0, "pad": 1} if tie else None)
        if tie:
            ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="///", lw=0, zorder=2))
    ax.set_xticks(range(len(cols)), [c.replace(", one call", "") for c in cols], rotation=20, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), [f"{case}: {names(pinn)}\nagainst the {against}" for case, pinn, against in rows],
                  fontsize=8)
    fig.colorbar(image, ax=ax, label="log10(rival time / PINN time)")
    title(ax, v["case"], "verdicts at matched accuracy", "worst seed; hatched: tie")
    return fig


VERDICT_PLOTS = {"verdicts": verdict_plot}


# No creation date in a PDF: the same rows give the same bytes (PNGs carry only "Software").
_FILE_METADATA: dict[str, dict] = {"png": {}, "pdf": {"CreationDate": None}}


def make_plots(frames: dict[str, pd.DataFrame], out_dir: Path, suffix: str = "", names: dict | None = None,
               labels: Labels | None = None) -> list[str]:
    """Write every plot of `names` (default `PLOTS`) that has data as `<name><suffix>.png` and `.pdf`,
    configurations named by `labels` (default: `Labels` of `frames`, as in the tables); return the
    file stems. Written twice from the same frames, with the same matplotlib, they are the same bytes."""
    import io

    from solvers.atomic import atomic_write

    labels = labels or Labels(frames)
    written = []
    for name, build in (PLOTS if names is None else names).items():
        fig = build(frames, labels)
        if fig is None:
            continue
        for ext in ("png", "pdf"):
            buffer = io.BytesIO()
            fig.savefig(buffer, format=ext, dpi=130, bbox_inches="tight",  # legends beside the axes
                        metadata=_FILE_METADATA[ext])
            atomic_write(Path(out_dir) / f"{name}{suffix}.{ext}", buffer.getvalue())
        plt.close(fig)
        written.append(f"{name}{suffix}")
    return written
