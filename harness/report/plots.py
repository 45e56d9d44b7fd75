"""Plots of a run (PNG and PDF): the paper's figure 3, work-precision, latency against t1,
identification error per pair, a fault case's trajectories either side of its CCT
(`harness.report.cct_plot`). Each function takes the suite frames and the names of their
configurations (`harness.report.labels.Labels`) and returns a figure or None."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from harness.measure.paired import CLASSICAL_FASTER
from harness.report.cct_plot import cct_plot
from harness.report.frames import identification_data, label, ok, trained
from harness.report.labels import Labels
from harness.report.plot_style import legend_beside as _legend_beside
from harness.report.plot_style import palette as _palette
from harness.report.verdicts import headline, verdicts
from systems.cases import CASES, standard_grid

__all__ = ["PLOTS", "SCALING_PLOTS", "VERDICT_PLOTS", "make_plots"]


def figure3(frames: dict, names: Labels):
    """Best and worst trajectory (delta and omega of every machine, one line each), predicted vs
    reference, for each PINN configuration's first seed (the paper's figure 3); none for a case
    this process has not registered (a `--case-file` case, whose reference it cannot integrate)."""
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
    for row, quantity in enumerate(("delta", "omega")):
        for col, which in enumerate(("best", "worst")):
            ax = axes[row, col]
            sel = acc[acc["quantity"] == quantity]
            ref_drawn = set()
            for spec, (_, r) in zip(specs, sel.iterrows()):
                key = (r[f"{which}_P1"],)
                if key not in ref_drawn:
                    ref = np.asarray(r[f"{which}_ref"], float).reshape(t.size, -1)
                    ax.plot(t, ref, color="black", lw=2.5, alpha=0.35,
                            label=[f"reference, {case.scenario.symbol}={r[f'{which}_P1']:.4g}"] + ["_"] * (ref.shape[1] - 1))
                    ref_drawn.add(key)
                pred = np.asarray(r[f"{which}_pred"], float).reshape(t.size, -1)
                lines = ax.plot(t, pred, lw=1.2, ls="--")
                for line in lines[1:]:
                    line.set_color(lines[0].get_color())
                lines[0].set_label(names(label(r.to_frame().T).iloc[0]))
            unit = "rad" if quantity == "delta" else "rad/s"
            ax.set_title(f"{which} trajectory: {quantity}")
            ax.set_ylabel(f"{quantity} ({unit})")
            ax.grid(alpha=0.3)
            if row == 1:
                ax.set_xlabel("t (s)")
    fig.suptitle("Predicted (dashed) against the reference: best and worst trajectory by rel. L2")
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
    fig, ax = plt.subplots(figsize=(8, 6))
    for name, g in wp[~trained(wp)].groupby("label", sort=False):
        g = g.sort_values("rel_l2_delta")
        ax.plot(g["rel_l2_delta"], g["median_s"], marker="o", ms=4, color=colour[name], label=names(name))
    for name, g in wp[trained(wp)].groupby("label", sort=False):
        ax.scatter(g["rel_l2_delta"], g["median_s"], marker="*", s=140, zorder=3, color=colour[name],
                   label=f"{names(name)} (PINN)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("rel. L2 error of delta on the 100 x 201 grid")
    ax.set_ylabel("warm query time of the grid (s)")
    ax.set_title("Work-precision: classical tolerance sweeps (lines) and PINNs (stars)")
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
    fig, ax = plt.subplots(figsize=(8, 5))
    for name, g in lat.groupby("label", sort=False):
        g = g.sort_values("t1_s")
        ax.errorbar(g["t1_s"], g["median_s"], yerr=[g["median_s"] - g["q25_s"], g["q75_s"] - g["median_s"]],
                    marker="o", ms=4, capsize=2, color=colour[name], label=names(name),
                    ls="--" if trained(g).any() else "-")
    ax.set_yscale("log")
    ax.set_xlabel("t1 (s)")
    ax.set_ylabel("warm query time of delta, omega at t1 (s)")
    ax.set_title("Single-time-point query: a classical solver integrates from 0, a PINN evaluates at t1")
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
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(x["t1_s"], 1e6 * x["classical_s"], marker="o", label=f"{names(x['classical'])} (classical, compiled)")
    ax.plot(x["t1_s"], 1e6 * x["pinn_s"], marker="*", ms=10, ls="--", label=f"{names(x['pinn'])} (PINN)")
    if x["how"] == "crossover":
        ax.axvline(x["t1_cross_s"], color="grey", lw=1)
        ax.annotate(f"crossover t1 = {x['t1_cross_s']:.3g} s", (x["t1_cross_s"], ax.get_ylim()[1]),
                    xytext=(4, -14), textcoords="offset points", fontsize=8)
    ax.set_yscale("log")
    ax.set_xlabel("t1 (s)")
    ax.set_ylabel("warm solve() of delta, omega at t1 (us)")
    ax.set_title(f"Single point: {x['how']}")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def identification_plot(frames: dict, names: Labels):
    """Error of m and d per pair: one colour per solver and config, one marker per data source and
    noise level, the solvers side by side within each pair; two legends beside the axes."""
    df = ok(frames.get("identification"))
    if df.empty or "m_rel_error" not in df:
        return None
    df = df.assign(label=label(df), data=identification_data(df))
    specs = list(dict.fromkeys(df["label"]))
    kinds = sorted(dict.fromkeys(zip(df["data"], df["noise"])))
    colour = _palette(specs)
    marker = {kind: m for kind, m in zip(kinds, "os^Dv<>")}
    width = 0.8 / len(specs)
    fig, axes = plt.subplots(1, 2, figsize=(14, 5.5), sharey=True)
    for ax, column, name in ((axes[0], "m_rel_error", "m"), (axes[1], "d_rel_error", "d")):
        for i, spec in enumerate(specs):
            g = df[df["label"] == spec]
            for kind, h in g.groupby(["data", "noise"]):
                ax.scatter(h["pair"] + width * (i - (len(specs) - 1) / 2), np.maximum(h[column], 1e-12),
                           marker=marker[kind], color=colour[spec], s=22)
        pairs = df.drop_duplicates("pair").sort_values("pair")
        ax.set_xticks(pairs["pair"], [f"{m:.3g}\n{d:.3g}" if np.isscalar(m) else "the case's\nown (m_k, d_k)"
                                      for m, d in zip(pairs["m_true"], pairs["d_true"])],
                      fontsize=7)
        ax.set_yscale("log")
        ax.set_xlabel("(m, d) pair: m above, d below")
        ax.set_title(f"relative error of {name}")
        ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.legend([Line2D([], [], ls="", marker="o", color=colour[spec]) for spec in specs], [names(s) for s in specs],
               fontsize=7, title="solver", title_fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 0.95))
    fig.legend([Line2D([], [], ls="", marker=marker[k], color="grey") for k in kinds],
               [f"{data}, noise {noise:.0%}" for data, noise in kinds],
               fontsize=7, title="data", title_fontsize=8, loc="lower left", bbox_to_anchor=(1.0, 0.1))
    return fig


def _log_log(frame: pd.DataFrame, column: str, ylabel: str, ax, names: Labels) -> None:
    """`column` against N, one line per adapter spec, log-log; the fitted slope in the legend."""
    from harness.report.scaling import log_log_slope

    colours = _palette(frame["label"])
    for name, g in frame.groupby("label", sort=False):
        g = g[np.isfinite(g[column].astype(float)) & (g[column].astype(float) > 0)]
        if g.empty:
            continue
        coupled = g["N"].to_numpy() >= 2  # as `exponents`: the SMIB's N = 1 has no coupling to scale
        slope, _ = log_log_slope(g["N"].to_numpy(float)[coupled], g[column].to_numpy(float)[coupled])
        tag = "" if np.isnan(slope) else f" (N^{slope:.2f})"
        ax.plot(g["N"], g[column], "o-" if not g["trains"].iloc[0] else "s--", color=colours[name],
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
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    for ax, (column, title) in zip(axes.ravel(), (("prep_s", "preparation (s)"), ("grid_s", "grid query (s)"),
                                                   ("point_s", "single point (s)"), ("peak_rss_mib", "peak memory (MiB)"))):
        _log_log(frame, column, title, ax, names)
    handles, labels = axes[0, 1].get_legend_handles_labels()
    fig.legend(handles, [lab.split(" (N^")[0] for lab in labels], fontsize=7, loc="upper left",
               bbox_to_anchor=(1.0, 0.95))
    fig.suptitle("Cost against the number of machines (fitted exponents in the scaling tables)")
    fig.tight_layout()
    return fig


def scaling_accuracy_plot(frames: dict, names: Labels):
    """Rel. L2 of the angles (COI-relative without an infinite bus) against N, every adapter."""
    frame = frames.get("scaling_frame")
    if frame is None or frame.empty:
        return None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    _log_log(frame.assign(label=frame["label"]), "rel_l2", "rel. L2 of the angles", ax, names)
    _legend_beside(ax)
    return fig


PLOTS = {"figure3": figure3, "work_precision": work_precision_plot, "latency_t1": latency_t1_plot,
         "crossover": crossover_plot, "identification": identification_plot, "cct": cct_plot}


SCALING_PLOTS = {"scaling_cost": scaling_cost_plot, "scaling_accuracy": scaling_accuracy_plot}


def verdict_plot(frames: dict, names: Labels):
    """The headline verdicts as a heat map: log10 of the ratio rival / PINN (worst seed; blue:
    the PINN faster, red: classical), case and PINN by row, query by column, each cell's label and
    ratio written in it; ties hatched under their text; a loss without a ratio (the PINN over the
    accuracy gate) drawn as the strongest loss."""
    v = verdicts(frames)
    v = v[headline(v)] if not v.empty else v
    if v.empty:
        return None
    rows = list(dict.fromkeys(zip(v["case"], v["pinn"])))
    cols = list(dict.fromkeys(v["query"]))
    at = [(rows.index((r["case"], r["pinn"])), cols.index(r["query"])) for _, r in v.iterrows()]
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
    ax.set_yticks(range(len(rows)), [f"{case}: {names(pinn)}" for case, pinn in rows], fontsize=8)
    fig.colorbar(image, ax=ax, label="log10(rival time / PINN time)")
    ax.set_title("Verdicts at matched accuracy (worst seed; hatched: tie)")
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
