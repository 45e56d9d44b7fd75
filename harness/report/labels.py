"""Names a reader can read: how tables, plot legends and verdicts name a configuration.

The analysis keys a spec by `harness.report.frames.label`, "solver [config, k=v,k=v]" with the rows'
full variant (and, for a point of a tolerance sweep, its setting: "..., rtol=1e-05, atol=1e-08]");
the rows and the CSVs keep that. What a reader sees is `Labels`: "solver config · option · ...",
the options written as words ("numba query", "parallel", "dt=0.05"), without those that every row
of that adapter and configuration shares in the rows at hand. Such an option (a run's training
budget, `max_seconds=120.0` on every PINN unit of a case) tells no two rows apart; it is stated
once beside the tables (`Labels.note`) instead of in every name.

Nothing here changes a key: the analysis groups and matches on keys, and `Labels` renders them
last, so a table's figures are the same whatever its names read.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

import pandas as pd

__all__ = ["Labels", "split_items"]

SEPARATOR = " · "
# Columns whose text names a spec of another adapter than the row's own (the verdict suite's rival,
# "numba-rk [rk4, parallel=True, dt=0.2]"): their specs are named too, every option shown.
SPEC_COLUMNS = ("rival",)


def split_items(text: str) -> list[str]:
    """`text` split at its commas outside brackets, each part stripped ("a=1,b=[1, 2]" -> two
    parts): option values read as JSON may be lists."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        depth += char in "[{("
        depth -= char in "]})"
        if char == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    parts.append(text[start:].strip())
    return [part for part in parts if part]


def _words(item: str) -> str:
    """One option as words: "parallel" for `parallel=True`, "no parallel" for False or None,
    "numba query" for a word value, "dt=0.05" for a number or anything else."""
    key, sep, value = item.partition("=")
    if not sep:
        return item
    if value == "True":
        return key
    if value in ("False", "None", "null"):
        return f"no {key}"
    if re.fullmatch(r"[A-Za-z][\w.-]*", value):
        return f"{value} {key}"
    return item


class Labels:
    """The readable names of the specs in `frames` (suite -> rows, or one frame of rows).

    `labels(key)` renders one key of `harness.report.frames.label`; `labels.text(s)` every key in a
    sentence or cell; `labels.table(df)` every text cell of a table; `labels.note()` says which
    options were left out. Options are left out per (solver, config) when every row of it in
    `frames` has them, with the same value."""

    def __init__(self, frames: Mapping[str, pd.DataFrame] | pd.DataFrame) -> None:
        parts = [frames] if isinstance(frames, pd.DataFrame) else list(frames.values())
        variants: dict[tuple[str, str], list[set[str]]] = {}
        for df in parts:
            if df is None or df.empty or not {"solver", "config"} <= set(df.columns):
                continue
            variant = df["variant"] if "variant" in df else pd.Series("", index=df.index)
            for solver, config, text in dict.fromkeys(zip(df["solver"], df["config"], variant.fillna("").astype(str))):
                variants.setdefault((str(solver), str(config)), []).append(set(split_items(text)))
            for column in (c for c in SPEC_COLUMNS if c in df):
                for text in dict.fromkeys(df[column].dropna().astype(str)):
                    named = re.match(r"([\w.-]+) \[([^,\]]+)", text)
                    if named:
                        variants.setdefault((named.group(1), named.group(2).strip()), []).append(set())
        self.shared = {spec: set.intersection(*sets) for spec, sets in variants.items()}
        names = sorted({solver for solver, _ in variants}, key=len, reverse=True)  # longest first
        self._key = re.compile(rf"(?<![\w-])({'|'.join(map(re.escape, names))}) \[([^\[\]]*(?:\[[^\[\]]*\][^\[\]]*)*)\]"
                               ) if names else None

    def __call__(self, key: str) -> str:
        """The name of one key ("solver [config, k=v, ...]"); a string of another form as it is."""
        match = self._key.fullmatch(key) if self._key else None
        return self._render(match) if match else key

    def _render(self, match: re.Match) -> str:
        solver, (config, *items) = match.group(1), split_items(match.group(2))
        if (solver, config) not in self.shared:  # not a spec of these rows: leave the text alone
            return match.group(0)
        shown = [_words(item) for item in dict.fromkeys(items) if item not in self.shared[(solver, config)]]
        return SEPARATOR.join([f"{solver} {config}", *shown])

    def text(self, text: str, wrap: str = "{}") -> str:
        """`text` with every key in it renamed (ladder cells, legends, verdict sentences), each name
        put into `wrap` (e.g. "`{}`": a Markdown sentence where a name ends before a number)."""
        if not (self._key and isinstance(text, str)):
            return text
        return self._key.sub(lambda match: wrap.format(self._render(match)), text)

    def table(self, df: pd.DataFrame) -> pd.DataFrame:
        """`df` with every key in its text cells renamed; numbers and headers as they are."""
        return df.apply(lambda column: column.map(self.text) if column.dtype == object else column)

    def note(self, specs: Iterable[tuple[str, str]] | None = None) -> str:
        """One sentence naming the options left out of the names ("" when none were), of every
        spec or of those in `specs` ((solver, config) pairs)."""
        groups: dict[str, list[str]] = {}
        for (solver, config), items in self.shared.items():
            if items and (specs is None or (solver, config) in specs):
                groups.setdefault(", ".join(sorted(items)), []).append(f"{solver} {config}")
        if not groups:
            return ""
        parts = "; ".join(f"{', '.join(names)}: {items}" for items, names in groups.items())
        return f"Names leave out the options that every row of a configuration shares: {parts}."
