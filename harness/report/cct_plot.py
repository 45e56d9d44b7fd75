"""A fault case's figure from its cct rows (`harness.suites.cct`): every machine's angle from the
centre of inertia for a clearing time either side of the reference CCT, the reference and each
adapter, and each adapter's CCT error; every time in it (the time axis, the clearing times, the
errors) in one unit, chosen from the clearing times (`harness.report.plot_style.time_unit`)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from harness.report.frames import label, ok, trained
from harness.report.labels import Labels
from harness.report.plot_style import palette, time_unit, title
from systems.stability import ANGLE_LIMIT

__all__ = ["cct_plot"]


def cct_plot(frames: dict, names: Labels):
    """Three panels: the trajectories (angles from the centre of inertia, rad) cleared before and
    after the reference CCT, the reference thick and grey, each adapter dashed (a surrogate's first
    seed), the limit +-pi dotted, one legend below; then each adapter's CCT error beside the
    bracket (+-1 ms).
    None without cct rows that carry trajectories."""
    df = ok(frames.get("cct"))
    if df.empty or "traj_pred" not in df:
        return None
    df = df[df["traj_pred"].notna()]
    df = df[~trained(df) | (df["seed"] == df.groupby(["solver", "config"])["seed"].transform("min"))]
    if df.empty:
        return None
    df = df.assign(label=label(df))
    colours = palette(df["label"])
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5), gridspec_kw={"width_ratios": [3, 3, 2]})
    first = df.iloc[0]
    unit = time_unit([*first["traj_t_c"], first["reference_cct_s"]])
    t = unit.per_s * np.asarray(first["traj_t"], float)
    for side, ax in enumerate(axes[:2]):
        ref = np.asarray(first["traj_ref"], float)[side]
        lines = ax.plot(t, ref, color="black", lw=2.5, alpha=0.3)
        lines[0].set_label("reference")
        for _, r in df.iterrows():
            pred = np.asarray(r["traj_pred"], float)[side]
            drawn = ax.plot(t, pred, color=colours[r["label"]], lw=1.0, ls="--")
            drawn[0].set_label(names(r["label"]))
        for limit in (-ANGLE_LIMIT, ANGLE_LIMIT):
            ax.axhline(limit, color="grey", ls=":", lw=1)
        ax.set_ylim(-2 * ANGLE_LIMIT, 2 * ANGLE_LIMIT)
        t_c = unit.per_s * first["traj_t_c"][side]
        ax.axvline(t_c, color="grey", lw=0.8)
        ax.set_title(f"{'stable' if side == 0 else 'unstable'} side: t_c = {t_c:.4g} {unit.name}")
        ax.set_xlabel(f"t ({unit.name})")
        ax.set_ylabel("delta - delta_COI (rad)")
        ax.grid(alpha=0.3)
    ax = axes[2]
    errors = unit.per_s * df["cct_error_s"].to_numpy(float)
    ax.barh(range(len(df)), np.nan_to_num(errors), color=[colours[name] for name in df["label"]])
    bracket = unit.per_s * first["bracket_s"]
    ax.axvspan(-bracket, bracket, color="green", alpha=0.1, label=f"within {bracket:g} {unit.name}")
    ax.set_yticks(range(len(df)), [names(name) for name in df["label"]], fontsize=7)
    ax.set_xlabel(f"CCT error ({unit.name}), adapter - reference")
    ax.set_title(f"reference CCT {unit.per_s * first['reference_cct_s']:.4g} {unit.name}")
    ax.grid(alpha=0.3, axis="x")
    title(fig, df["case"], "trajectories either side of the CCT", "reference grey, adapters dashed")
    fig.tight_layout()
    handles, texts = axes[0].get_legend_handles_labels()
    fig.legend(handles, texts, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=min(4, len(texts)), fontsize=7)
    return fig
