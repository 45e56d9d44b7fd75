"""What every figure of a run shares: the non-interactive backend, a colour per configuration and
the legend beside the axes."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

__all__ = ["legend_beside", "palette"]


def palette(labels) -> dict:
    """A distinct colour per label, in order: tab10 up to 10 labels, tab20 up to 20."""
    labels = list(dict.fromkeys(labels))
    cmap = plt.get_cmap("tab10" if len(labels) <= 10 else "tab20")
    return {name: cmap(i % cmap.N) for i, name in enumerate(labels)}


def legend_beside(ax) -> None:
    """The legend right of the axes, off the data (make_plots saves with a tight bounding box)."""
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
