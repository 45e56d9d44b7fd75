"""Do the verdicts' intervals hold across runs? For pairs of results folders, each verdict's interval
recomputed from its stored paired samples under each rule (`RULES`: the bootstrap alone; with the
run-to-run term `RUN_TO_RUN`; the interval of a repeat run's ratio, the verdicts' `INTERVAL`), then:
how many of run B's ratios lie inside run A's interval, and how many labels agree, flip or are a
tie in one run only. One CSV row per pair and rule:

    python scripts/interval_coverage.py results results/verdicts results/verdicts-rerun \
        --out results/interval-coverage.csv

compares the first folder with each of the others (and the others among themselves). With
`--append` the rows of these pairs are added to the CSV's (a pair already there is replaced), so a
new pair of runs joins the stored ones without comparing runs of different machines:

    python scripts/interval_coverage.py results/verdicts-retrain results/verdicts-retrain-2 \
        --out results/interval-coverage.csv --append

`--table` prints the CSV's rows as docs/methods.md's table lines (a test holds the page to them).
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import pandas as pd

from harness.measure.paired import INTERVAL, RUN_TO_RUN, ratio_interval, verdict_label
from harness.report.comparison import AGREE, FLIP, compare_runs, run_to_run_sigma
from harness.report.frames import suite_frames
from harness.store import RowStore

# rule name -> (run-to-run term, repeat): the interval of the ratio within one run, over runs, of a repeat run
RULES = {"bootstrap": (0.0, False), "over runs": (RUN_TO_RUN, False), "repeat run": (RUN_TO_RUN, True)}


def _frames(folder: Path, run_to_run: float, repeat: bool) -> dict:
    """The folder's rows by suite, the verdict rows' ratio, interval and label recomputed from their
    samples under the rule (rows without samples as they are), marked as stated under the verdicts'
    own rule so that the report does not restate them."""
    frames = suite_frames(RowStore(folder, create=False).read().rows)
    v = frames["verdict"].copy()
    timed = v["pinn_samples_s"].map(lambda x: isinstance(x, list) and len(x) >= 2)
    for i in v.index[timed]:
        ratio, low, high = ratio_interval(v.at[i, "pinn_samples_s"], v.at[i, "rival_samples_s"], run_to_run=run_to_run,
                                          repeat=repeat)
        v.loc[i, ["ratio", "ratio_low", "ratio_high", "label"]] = [ratio, low, high, verdict_label(low, high)]
    return {**frames, "verdict": v.assign(interval=INTERVAL)}


def coverage(run_a: Path, run_b: Path, rule: str) -> dict:
    run_to_run, repeat = RULES[rule]
    a, b = _frames(run_a, run_to_run, repeat), _frames(run_b, run_to_run, repeat)
    both = compare_runs(a, b)
    timed = both.dropna(subset=["ratio A", "ratio B"])
    inside = int(((timed["ratio B"] >= timed["ratio_low A"]) & (timed["ratio B"] <= timed["ratio_high A"])).sum())
    sigma, pairs = run_to_run_sigma(a, b)
    counts = both["agreement"].value_counts()
    return {"run_a": run_a.as_posix(), "run_b": run_b.as_posix(), "run_to_run": run_to_run, "interval": rule,
            "verdicts": len(both),
            "timed_in_both": len(timed), "b_inside_a": inside, "b_inside_a_pct": round(100 * inside / len(timed), 1),
            "agree": int(counts.get(AGREE, 0)), "flip": int(counts.get(FLIP, 0)),
            "tie_in_one": int(len(both) - counts.get(AGREE, 0) - counts.get(FLIP, 0)),
            "sigma_measured": round(sigma, 4), "seed_rows_in_both": pairs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", type=Path, nargs="*", metavar="DIR")
    parser.add_argument("--out", type=Path, required=True, help="the CSV to write (with --table: to read)")
    parser.add_argument("--append", action="store_true", help="add the rows to the CSV's, replacing the same pairs")
    parser.add_argument("--table", action="store_true", help="print the CSV's rows as docs/methods.md's table lines")
    args = parser.parse_args()
    if args.table:
        print("\n".join(table_lines(pd.read_csv(args.out))))
        return
    if len(args.folders) < 2:
        parser.error("give at least two results folders (or --table)")
    rows = [coverage(a, b, rule) for a, b in itertools.combinations(args.folders, 2) for rule in RULES]
    table = pd.DataFrame(rows)
    if args.append and args.out.exists():
        old = pd.read_csv(args.out)
        pairs = set(zip(table["run_a"], table["run_b"]))
        table = pd.concat([old[[pair not in pairs for pair in zip(old["run_a"], old["run_b"])]], table],
                          ignore_index=True)
    table.to_csv(args.out, index=False)
    print(table.to_string(index=False))


def table_lines(table: pd.DataFrame) -> list[str]:
    """The coverage rows as the lines of docs/methods.md's table: pair, rule, run-to-run term,
    B's ratios inside A's interval, labels agree / flip / tie in one."""
    return [f"| {r.run_a} | {r.run_b} | {r.interval} | {r.run_to_run:g} | {r.b_inside_a} of {r.timed_in_both} "
            f"({r.b_inside_a_pct:.1f} %) | {r.agree} / {r.flip} / {r.tie_in_one} |" for r in table.itertuples()]


if __name__ == "__main__":
    main()
