"""The identification figure: the relative error of m and d per (m, d) pair and adapter, with the
95 % interval that each row's estimate carries (`harness.suites.identification`: `m_ci95_low`,
`m_ci95_high`, per machine) drawn as the range of relative errors it allows."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from harness.report.frames import identification_data, label, ok
from harness.report.labels import Labels
from harness.report.plot_style import palette, title

__all__ = ["error_interval", "identification_plot"]

_FLOOR = 1e-12  # the log axis's floor for an error (or an interval's end) of 0


def error_interval(row: pd.Series, name: str) -> tuple[float, float]:
    """The range of the row's relative error of `name` (its worst machine, `<name>_rel_error`) that
    its 95 % intervals allow: per machine k, |x - x_k| / x_k over x in [low_k, high_k] (0 at the
    low end when the interval holds the truth), the worst machine's range [max_k low end, max_k
    high end]; (nan, nan) for a row without intervals (runs before them, or an adapter that has
    none) or with a machine's interval missing."""
    columns = [f"{name}_true", f"{name}_ci95_low", f"{name}_ci95_high"]
    if any(column not in row.index for column in columns):
        return float("nan"), float("nan")
    truth, low, high = (np.atleast_1d(np.asarray(row[column], dtype=float)) for column in columns)
    if truth.size != low.size or truth.size != high.size or np.isnan(low).any() or np.isnan(high).any():
        return float("nan"), float("nan")
    far = np.maximum(np.abs(low - truth), np.abs(high - truth)) / np.abs(truth)
    near = np.where((low <= truth) & (truth <= high), 0.0, np.minimum(np.abs(low - truth), np.abs(high - truth)))
    return float((near / np.abs(truth)).max()), float(far.max())


def identification_plot(frames: dict, names: Labels):
    """Error of m and d per pair: one colour per solver and config, one marker per data source and
    noise level, the solvers side by side within each pair, each point's 95 % interval as a bar
    (`error_interval`: up to its largest error, down to its smallest where the interval excludes the
    truth; none where the row has no interval); two legends beside the axes."""
    df = ok(frames.get("identification"))
    if df.empty or "m_rel_error" not in df:
        return None
    df = df.assign(label=label(df), data=identification_data(df))
    specs = list(dict.fromkeys(df["label"]))
    kinds = sorted(dict.fromkeys(zip(df["data"], df["noise"])))
    colour = palette(specs)
    marker = {kind: m for kind, m in zip(kinds, "os^Dv<>")}
    width = 0.8 / len(specs)
    fig, axes = plt.subplots(1, 2, figsize=(14, 5.5), sharey=True)
    for ax, name in zip(axes, ("m", "d")):
        column = f"{name}_rel_error"
        for i, spec in enumerate(specs):
            g = df[df["label"] == spec]
            for kind, h in g.groupby(["data", "noise"]):
                x = h["pair"] + width * (i - (len(specs) - 1) / 2)
                y = np.maximum(h[column].to_numpy(float), _FLOOR)
                ax.scatter(x, y, marker=marker[kind], color=colour[spec], s=22, zorder=3)
                ends = np.array([error_interval(r, name) for _, r in h.iterrows()]).reshape(-1, 2)
                has = np.isfinite(ends).all(axis=1)
                if has.any():  # an interval that holds the truth allows 0: its bar is open below, not to the floor
                    low = np.where(ends[has, 0] > 0, ends[has, 0], y[has])
                    high = np.maximum(ends[has, 1], _FLOOR)
                    ax.errorbar(x[has], y[has], yerr=[np.maximum(y[has] - low, 0), np.maximum(high - y[has], 0)],
                                ls="", color=colour[spec], capsize=2, lw=0.8)
        pairs = df.drop_duplicates("pair").sort_values("pair")
        ax.set_xticks(pairs["pair"], [f"{m:.3g}\n{d:.3g}" if np.isscalar(m) else "the case's\nown (m_k, d_k)"
                                      for m, d in zip(pairs["m_true"], pairs["d_true"])],
                      fontsize=7)
        ax.set_yscale("log")
        ax.set_xlabel("(m, d) pair: m above, d below")
        ax.set_ylabel("relative error (worst machine)")
        ax.set_title(f"relative error of {name}")
        ax.grid(alpha=0.3, which="both")
    title(fig, df["case"], "identification error of m and d",
          "bars: the errors the estimate's 95 % interval allows (none below the point: it holds the truth)")
    fig.tight_layout()
    fig.legend([Line2D([], [], ls="", marker="o", color=colour[spec]) for spec in specs], [names(s) for s in specs],
               fontsize=7, title="solver", title_fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 0.95))
    fig.legend([Line2D([], [], ls="", marker=marker[k], color="grey") for k in kinds],
               [f"{data}, noise {noise:.0%}" for data, noise in kinds],
               fontsize=7, title="data", title_fontsize=8, loc="lower left", bbox_to_anchor=(1.0, 0.1))
    return fig
