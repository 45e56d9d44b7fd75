"""What every figure of a run shares: the non-interactive backend, a colour per configuration,
the legend beside the axes, a title that names the case(s) of its rows (`title`) and one unit for
the durations a figure shows, chosen from its data (`time_unit`)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

__all__ = ["TimeUnit", "cases_text", "legend_beside", "palette", "time_unit", "title"]


def palette(labels) -> dict:
    """A distinct colour per label, in order: tab10 up to 10 labels, tab20 up to 20."""
    labels = list(dict.fromkeys(labels))
    cmap = plt.get_cmap("tab10" if len(labels) <= 10 else "tab20")
    return {name: cmap(i % cmap.N) for i, name in enumerate(labels)}


def legend_beside(ax) -> None:
    """The legend right of the axes, off the data (make_plots saves with a tight bounding box)."""
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))


def cases_text(cases: Iterable[str]) -> str:
    """The cases of a figure's rows, in their order: "wscc9", "wscc9, kundur4 and ieee39", or, past
    three, "7 cases, case9 to case9241pegase" (first and last)."""
    names = [str(case) for case in dict.fromkeys(cases) if isinstance(case, str) and case]
    if len(names) <= 1:
        return names[0] if names else "no case"
    if len(names) <= 3:
        return f"{', '.join(names[:-1])} and {names[-1]}"
    return f"{len(names)} cases, {names[0]} to {names[-1]}"


def title(target, cases: Iterable[str], what: str, detail: str = "") -> None:
    """Title `target` (a figure: its suptitle; axes: their title) "<cases>: <what>", `detail` on a
    second line: every figure says which case(s) its rows are of (`cases_text`)."""
    text = f"{cases_text(cases)}: {what}" + (f"\n{detail}" if detail else "")
    if isinstance(target, Figure):
        target.suptitle(text)
    else:
        target.set_title(text)


class TimeUnit(NamedTuple):
    """A unit of time: its symbol and how many of it make a second (a value in s times `per_s`)."""

    name: str
    per_s: float


_UNITS = (TimeUnit("s", 1.0), TimeUnit("ms", 1e3), TimeUnit("µs", 1e6))


def time_unit(seconds) -> TimeUnit:
    """The one unit (s, ms or µs) for durations `seconds` (any shape, s): the largest in which their
    median magnitude (finite, non-zero values) is at least 1; s without such values."""
    values = np.abs(np.asarray(seconds, dtype=float).ravel())
    values = values[np.isfinite(values) & (values > 0)]
    if values.size == 0:
        return _UNITS[0]
    typical = float(np.median(values))
    return next((unit for unit in _UNITS if typical * unit.per_s >= 1.0), _UNITS[-1])
