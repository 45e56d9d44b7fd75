"""The rows of a run as frames: by suite (`suite_frames`) and by case (`case_sections`), and the
selections every table and verdict makes of them (`ok`, `trained`, `compiled`, `does_work`,
`first_seed`; `label`, the spec without its seed). Pure pandas, no measurement, no I/O.

Trained adapters (PINNs) are the rows whose adapter declares it (`trains`), with their seed; the
others, classical adapters, have seed -1. Every comparison is between rows of the same run.
"""

from __future__ import annotations

import pandas as pd

from harness.suites import identification_case
from solvers import INTERFACE
from systems.cases import CASES

__all__ = ["case_sections", "compiled", "does_work", "first_seed", "identification_data", "label", "ok",
           "suite_frames", "trained"]


def ok(df: pd.DataFrame | None) -> pd.DataFrame:
    """Rows with status "ok" (an empty frame when there are none)."""
    if df is None or df.empty or "status" not in df:
        return pd.DataFrame()
    return df[df["status"] == "ok"].copy()


def label(df: pd.DataFrame) -> pd.Series:
    """"solver [config, variant]": the spec without its seed, the unit seeds are summarised over."""
    variant = df["variant"].fillna("").astype(str).map(lambda v: f", {v}" if v else "")
    return df["solver"] + " [" + df["config"] + variant + "]"


def identification_data(df: pd.DataFrame) -> pd.Series:
    """The data source of identification rows ("reference" or "paper ode45"); rows of runs made
    before the column existed were all on the reference."""
    if "data" not in df:
        return pd.Series("reference", index=df.index)
    return df["data"].fillna("reference")


def trained(df: pd.DataFrame) -> pd.Series:
    """Rows of adapters that train (the rows' `trains`, as the adapter declares it). Runs before the
    column recorded a training seed >= 0 for exactly these adapters and -1 for the others, so their
    rows are read by that rule; a row without the declaration in a run that has the column (an
    adapter that is not installed) does not train."""
    if "trains" not in df:
        return df["seed"].fillna(-1).astype(int) >= 0 if "seed" in df else pd.Series(False, index=df.index)
    return df["trains"].eq(True)  # NaN (no declaration) is not True


def compiled(df: pd.DataFrame) -> pd.Series:
    """Rows of adapters whose queries run in compiled code (rows before the column: none)."""
    if "compiled" not in df:
        return pd.Series(False, index=df.index)
    return df["compiled"].eq(True)  # NaN (no column in that run's rows) is not True


def does_work(df: pd.DataFrame) -> pd.Series:
    """Rows of real adapters, not of the do-nothing one that times the interface (`solvers.INTERFACE`;
    rows of runs before the `does_work` column are told by that name)."""
    by_name = df["solver"] != INTERFACE
    if "does_work" not in df:
        return by_name
    return df["does_work"].where(df["does_work"].notna(), by_name).eq(True)


def first_seed(df: pd.DataFrame) -> pd.DataFrame:
    """Classical rows and, of each trained spec, the rows of its first (lowest) seed: the seed rule
    of every verdict (error, latency and fit time all from the one model that was timed)."""
    if df.empty:
        return df
    seed = df["seed"].fillna(-1).astype(int)
    lowest = seed.groupby(label(df)).transform("min")
    return df[seed == lowest]


def _identification_case(name: str, identified: set[str]) -> str:
    """The case identification measures for forward case `name`: the planner's rule
    (`harness.suites.identification_case`, from the case's kind) on the registered case. A case
    that has identification rows of its own (`identified`) is its own identification case by that
    rule, and an unregistered name is taken as its own: then no network is built to say so."""
    if name in identified or name not in CASES:
        return name
    return identification_case(CASES[name]).name


def case_sections(frames: dict[str, pd.DataFrame]) -> list[tuple[str, dict[str, pd.DataFrame]]]:
    """The frames of each forward case, in run order: its rows of every suite, and the
    identification rows of its identification case (the SMIB's own case for a SMIB). In a case
    without an infinite bus (any work-precision row with `rel_l2_delta_coi`) the verdicts compare
    at the accuracy of the angles relative to the centre of inertia: `rel_l2_delta` is replaced by
    it there (absolute angles drift together; their error says little about the swings)."""
    names: list[str] = []
    for suite, df in frames.items():
        if suite not in ("identification", "scaling", "fit") and "case" in df:
            names += [n for n in df["case"].dropna().unique() if n not in names]
    ident = frames.get("identification")
    identified = set(ident["case"].dropna()) if ident is not None and "case" in ident else set()
    if ident is not None and "case" in ident:
        covered = {_identification_case(n, identified) for n in names}
        names += [n for n in ident["case"].dropna().unique() if n not in covered and n not in names]
    sections = []
    for name in names:
        own = {}
        for suite, df in frames.items():
            if suite == "scaling":  # across cases: its own section (`scaling_markdown`)
                continue
            case = _identification_case(name, identified) if suite == "identification" else name
            part = df[df["case"] == case].dropna(axis=1, how="all").reset_index(drop=True) if "case" in df else df
            if suite == "work_precision" and "rel_l2_delta_coi" in part:
                part = part.assign(rel_l2_delta=part["rel_l2_delta_coi"].fillna(part["rel_l2_delta"]))
            if not part.empty:
                own[suite] = part
        sections.append((name, own))
    return sections


def suite_frames(rows: list[dict]) -> dict[str, pd.DataFrame]:
    """The rows of each suite, in run order, as a frame without the columns none of them fills."""
    frame = pd.DataFrame(rows)
    if frame.empty:
        return {}
    return {suite: g.dropna(axis=1, how="all").reset_index(drop=True)
            for suite, g in frame.groupby("suite", sort=False)}
