"""`swingbench compare DIR_A DIR_B`: two runs side by side. First every query both measured (a
latency query, an accuracy quantity; `MEASURES`) for the same case and spec: the median over seeds
in each run and the ratio B / A (`queries_in_both`). Then, where both runs have verdict rows,
every verdict of both and whether they agree.

Each run's verdicts are its verdict suite's rows over seeds (`harness.report.verdicts.verdicts`);
two verdicts agree when their labels are the same, flip when they name opposite sides, and
otherwise one of them is a tie. With `--update-readme`, the comparison replaces the README's
section between `COMPARE_START` and `COMPARE_END`.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from harness.usage import UsageError

__all__ = ["COMPARE_END", "COMPARE_START", "add_parser", "cmd_compare", "compare_block"]

COMPARE_START, COMPARE_END = "<!-- swingbench:compare:start -->", "<!-- swingbench:compare:end -->"


def add_parser(sub) -> None:
    compare = sub.add_parser(
        "compare", help="compare two runs: each query's medians and B / A, then the verdicts",
        description="Read the rows of two results folders and print, for every query both measured (latency: the "
                    "median time of a query; accuracy: the relative L2 error of a quantity) for the same case, "
                    "solver, config and variant, both runs' medians over seeds and the ratio B / A. Then, where both "
                    "runs have verdict rows, for every case, PINN and query both runs' verdicts with their ratios and "
                    "95 % intervals, and whether they agree (the same label), one is a tie, or they flip (opposite "
                    "sides). Exit status 1 when a verdict flips; 2 when the runs share neither queries nor verdicts.")
    compare.add_argument("run_a", type=Path, metavar="DIR_A")
    compare.add_argument("run_b", type=Path, metavar="DIR_B")
    compare.add_argument("--update-readme", type=Path, default=None, metavar="README",
                         help=f"also replace the README's section between {COMPARE_START} and {COMPARE_END} "
                              "with the summary (the tables stay in the printed comparison)")


def _frames(directory: Path) -> dict:
    """The rows of the results folder `directory`, by suite (`harness.report.frames.suite_frames`)."""
    from harness.report.frames import suite_frames
    from harness.store import RowStore

    if not directory.is_dir():
        raise UsageError(f"swingbench compare: {directory} is not a folder of results")
    return suite_frames(RowStore(directory, create=False).read().rows)


def _sources(run_a: Path, run_b: Path, start: Path) -> str:
    """Both runs' rows files, relative to `start`, as the block names them."""
    a, b = (f"`{Path(os.path.relpath(d.resolve(), start.resolve())).as_posix()}/rows.jsonl`" for d in (run_a, run_b))
    return f"{a} (run A) and {b} (run B)"


# suite -> (the columns that name a query besides case and spec, joined by " against ", and its measure)
MEASURES = {"latency": (("query",), "median_s"), "accuracy": (("quantity", "against"), "rel_l2")}


def _medians(frames: dict, suite: str):
    """The median over seeds of `suite`'s measure for each (case, spec, query) of one run: a frame
    of suite, case, configuration (`harness.report.frames.label`), query, measure and median; the rows
    without the measure (skipped, failed) left out."""
    import pandas as pd

    from harness.report.frames import label

    names, measure = MEASURES[suite]
    df = frames.get(suite)
    if df is None or measure not in df or not set(names) <= set(df.columns):
        return pd.DataFrame(columns=["suite", "case", "configuration", "query", "measure", "median"])
    df = df.dropna(subset=[measure]).assign(variant=lambda d: d["variant"].fillna("") if "variant" in d else "")
    keyed = pd.DataFrame({"suite": suite, "case": df["case"], "configuration": label(df),
                          "query": df[list(names)].astype(str).agg(" against ".join, axis=1),
                          "measure": measure, "median": df[measure].astype(float)})
    return keyed.groupby(["suite", "case", "configuration", "query", "measure"], sort=False,
                         as_index=False)["median"].median()


def queries_in_both(frames_a: dict, frames_b: dict):
    """Every query (`MEASURES`: a latency query, an accuracy quantity against its reference) that
    both runs measured for the same case and spec (solver, config, variant): the median over seeds
    in each run (s, or the relative L2 error) and the ratio B / A; in run A's order."""
    import pandas as pd

    key = ["suite", "case", "configuration", "query", "measure"]
    parts = [_medians(frames_a, suite).merge(_medians(frames_b, suite), on=key, suffixes=(" A", " B"))
             for suite in MEASURES]
    parts = [part for part in parts if not part.empty]
    if not parts:
        return pd.DataFrame(columns=[*key, "median A", "median B", "ratio"])
    both = pd.concat(parts, ignore_index=True)
    return both.assign(ratio=both["median B"] / both["median A"])


def _queries_markdown(both, names) -> str:
    """The summary line per suite (how many queries, the spread of B / A) and the table; "" for none."""
    if both.empty:
        return ""
    lines = []
    for suite, group in both.groupby("suite", sort=False):
        ratio = group["ratio"]
        lines.append(f"{suite}: {len(group)} queries in both runs; B / A of the medians {ratio.median():.3g} (median), "
                     f"from {ratio.min():.3g} to {ratio.max():.3g}.")
    table = both.assign(**{column: both[column].map(lambda x: f"{x:.3g}") for column in ("median A", "median B", "ratio")})
    table = table.rename(columns={"median A": "run A", "median B": "run B", "ratio": "B / A"})
    return " ".join(lines) + "\n\n" + names.table(table).to_markdown(index=False) + "\n\n"


def _block(frames_a: dict, frames_b: dict, sources: str, tables: bool = True) -> str:
    """The comparison as Markdown: the queries both runs measured (`queries_in_both`), then the
    verdicts where both runs have them; without `tables`, the summary sentences alone (the README's
    block); UsageError when they share neither."""
    import pandas as pd

    from harness.report.comparison import compare_runs, compare_table
    from harness.report.labels import Labels

    frames = {suite: pd.concat([f[suite] for f in (frames_a, frames_b) if suite in f])
              for suite in {**frames_a, **frames_b}}
    names = Labels(frames)
    queries = _queries_markdown(queries_in_both(frames_a, frames_b), names)
    if not tables:
        queries = queries.split("\n\n", 1)[0] + "\n\n" if queries else ""
    head = f"\n_Generated by `swingbench compare` from {sources}; do not edit by hand._\n\n{queries}"
    if "verdict" not in frames_a or "verdict" not in frames_b:
        if not queries:
            raise UsageError(f"swingbench compare: the two runs ({sources}) share no latency or accuracy query and "
                             "do not both have verdict rows (swingbench run --suite verdict)")
        return head + f"No verdicts in both runs (run {'B' if 'verdict' in frames_a else 'A'} has no verdict rows).\n"
    both = compare_runs(frames_a, frames_b)
    table = compare_table(frames_a, frames_b)
    summary = (_agreement(both["agreement"] if not both.empty else pd.Series(dtype=str)) + "."
               + _spread(both) + _sigma(frames_a, frames_b) + _surrogates(both))
    if not tables:
        return head + f"{summary} Every query and verdict of both: `swingbench compare` of the two folders.\n"
    return head + f"{summary}\n\n" + (names.table(table).to_markdown(index=False) if not table.empty else "") + "\n"


def compare_block(run_a: Path, run_b: Path, start: Path = Path(), tables: bool = True) -> str:
    """The comparison of the runs in folders `run_a` and `run_b` as Markdown (`_block`), its
    sources named relative to `start`."""
    return _block(_frames(run_a), _frames(run_b), _sources(run_a, run_b, start), tables)


def _spread(both) -> str:
    """How far the worst-seed ratios moved between the runs, against run A's intervals: "" when
    no verdict has a ratio in both."""
    timed = both.dropna(subset=["ratio A", "ratio B"])
    if timed.empty:
        return ""
    inside = _inside(timed)
    factor = (timed["ratio A"] / timed["ratio B"]).map(lambda x: max(x, 1 / x))
    top = timed.loc[factor.idxmax()]
    return (f" Of the {len(timed)} ratios of run B, {inside} ({100 * inside / len(timed):.0f} %) lie inside run A's 95 % "
            f"interval; between the runs a ratio moved by a factor of {factor.median():.2f} (median), at most "
            f"{factor.max():.2f} ({top['case']}, {top['query']}).")


def _surrogates(both) -> str:
    """The classical surrogate's verdicts in both runs: agreement, and how many of run B's
    surrogate ratios lie inside run A's intervals; "" where no verdict has them in both runs."""
    if "surrogate agreement" not in both:
        return ""
    paired = both[both["surrogate agreement"] != ""]
    if paired.empty:
        return ""
    text = " Against the classical surrogate, " + _agreement(paired["surrogate agreement"])
    timed = paired.dropna(subset=["surrogate_ratio A", "surrogate_ratio B"])
    if not timed.empty:
        inside = _inside(timed, "surrogate_")
        text += f"; {inside} of run B's {len(timed)} ratios ({100 * inside / len(timed):.0f} %) inside run A's interval"
    return text + "."


def _agreement(agreement) -> str:
    """"N verdicts in both runs: a agree, f flip, t are a tie in one run and not in the other" of
    the column `agreement` of `compare_runs`."""
    from harness.report.comparison import AGREE, FLIP

    counts = agreement.value_counts()
    agree, flip = counts.get(AGREE, 0), counts.get(FLIP, 0)
    return (f"{len(agreement)} verdicts in both runs: {agree} agree, {flip} flip, "
            f"{len(agreement) - agree - flip} are a tie in one run and not in the other")


def _inside(timed, prefix: str = "") -> int:
    """How many of run B's ratios (`{prefix}ratio B`) lie inside run A's interval."""
    ratio, low, high = (timed[f"{prefix}{key}"] for key in ("ratio B", "ratio_low A", "ratio_high A"))
    return int(((ratio >= low) & (ratio <= high)).sum())


def _sigma(frames_a: dict, frames_b: dict) -> str:
    """The run-to-run spread of the two runs (`run_to_run_sigma`) beside the one the intervals
    assume (`RUN_TO_RUN`): "" without seed rows timed in both."""
    from harness.measure.paired import RUN_TO_RUN
    from harness.report.comparison import run_to_run_sigma

    sigma, n = run_to_run_sigma(frames_a, frames_b)
    if not n:
        return ""
    return (f" From the {n} seed rows both runs timed, the spread of log(ratio) between the runs beyond each run's "
            f"own samples is {sigma:.3f} (the intervals assume {RUN_TO_RUN:g}).")


def cmd_compare(args: argparse.Namespace) -> int:
    from harness.cli.readme import replace_section
    from harness.report.comparison import FLIP, compare_runs

    start = args.update_readme.resolve().parent if args.update_readme else Path()
    frames_a, frames_b = _frames(args.run_a), _frames(args.run_b)
    block = _block(frames_a, frames_b, _sources(args.run_a, args.run_b, start))
    print(block)
    if args.update_readme:
        summary = _block(frames_a, frames_b, _sources(args.run_a, args.run_b, start), tables=False)
        replace_section(args.update_readme, COMPARE_START, COMPARE_END, summary, "compare")
    both = compare_runs(frames_a, frames_b) if "verdict" in frames_a and "verdict" in frames_b else None
    if both is None or both.empty:
        return 0
    flips = both["agreement"] == FLIP
    if "surrogate agreement" in both:
        flips |= both["surrogate agreement"] == FLIP
    return 1 if flips.any() else 0
