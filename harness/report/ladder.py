"""Who wins which query. The verdict ladder (`ladder`): for each PINN spec, its error and query
time, and on each rung (`RUNGS`) the fastest classical option at least as accurate
(`fastest_classical`); the ladder table, the single-point crossover in t1 (`crossover`) and the
verdict sentences of a run (`verdict_lines`). Pure pandas on the rows of one run."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from harness.report.format import fmt
from harness.report.frames import compiled, does_work, first_seed, label, ok, trained
from harness.report.speedups import crossover_t1
from harness.suites.accuracy import COI_DELTA
from harness.suites.work_precision import T1_COLUMN
from solvers import LITERATURE_BASELINE

__all__ = ["COMPILED", "GRID_QUERY", "LITERATURE", "POINT_QUERY", "PYTHON_DRIVEN", "RUNGS", "crossover",
           "fastest_classical", "ladder", "ladder_queries", "ladder_rows", "ladder_table", "verdict_lines",
           "verdict_rows"]


# The latency suite's names of the paper's two timed queries; the work-precision suite times the first.
GRID_QUERY, POINT_QUERY = "grid 100x201", "single point t1=10 s"


# The rungs of the verdict ladder: which classical options each one may pick from.
LITERATURE = "literature baseline (scipy RK45, one solve per P1)"
PYTHON_DRIVEN = "best Python-driven classical"
COMPILED = "best compiled classical"
RUNGS = (LITERATURE, PYTHON_DRIVEN, COMPILED)
LITERATURE_SOLVER = LITERATURE_BASELINE  # looped, as MATLAB ode45 was in the paper's 28x and 87x


def _on_rung(df: pd.DataFrame, rung: str | None) -> pd.Series:
    """Classical rows that rung `rung` may pick (None: every classical row)."""
    classical = ~trained(df) & does_work(df)
    if rung is None:
        return classical
    if rung == LITERATURE:
        return classical & (df["solver"] == LITERATURE_SOLVER) & (df["variant"].fillna("") == "")
    if rung == PYTHON_DRIVEN:
        return classical & ~compiled(df)
    if rung == COMPILED:
        return classical & compiled(df)
    raise ValueError(f"unknown rung {rung!r}; known: {', '.join(RUNGS)}")


def verdict_rows(acc: pd.DataFrame) -> pd.DataFrame:
    """The accuracy rows every verdict compares at: delta against the reference, or, when the rows
    hold it (a case without an infinite bus), the angles relative to the centre of inertia, the
    measure the work-precision points of such a case are read at (`harness.report.frames.case_sections`):
    a PINN and its classical rivals judged by one measure."""
    acc = acc[acc["against"] == "reference"]
    quantity = COI_DELTA if (acc["quantity"] == COI_DELTA).any() else "delta"
    return acc[acc["quantity"] == quantity]


def fastest_classical(frames: dict, query: str, max_rel_l2: float, rung: str | None = None
                      ) -> tuple[str, float] | None:
    """The fastest classical option for `query` whose delta rel. L2 is at most `max_rel_l2`:
    (label, median seconds), or None. Candidates: each classical spec of the accuracy and latency
    suites and, for the grid and the t1 = 10 s query, each point of the work-precision sweeps
    (labelled with its setting), so that a PINN is compared with the strongest classical option
    measured; `rung` restricts them to one rung of the ladder (`RUNGS`; None: all)."""
    candidates: list[tuple[str, float]] = []
    acc, lat = ok(frames.get("accuracy")), ok(frames.get("latency"))
    if not acc.empty and not lat.empty:
        acc = verdict_rows(acc)
        acc = acc[_on_rung(acc, rung)]
        good = set(label(acc[acc["rel_l2"] <= max_rel_l2]))
        lat = lat[(lat["query"] == query) & _on_rung(lat, rung)]
        lat = lat.assign(label=label(lat))
        candidates += [(name, float(s)) for name, s in zip(lat["label"], lat["median_s"]) if name in good]
    wp = ok(frames.get("work_precision"))
    column = {GRID_QUERY: "median_s", POINT_QUERY: "point_median_s"}.get(query)
    if column in wp:  # rows of runs before the point timing have no point_median_s
        wp = wp[_on_rung(wp, rung) & (wp["rel_l2_delta"] <= max_rel_l2) & wp[column].notna()]
        for (_, row), name in zip(wp.iterrows(), label(wp)):
            setting = row.get("setting")
            if not isinstance(setting, str):  # runs before the column: tolerance sweeps only
                setting = f"rtol={row['rtol']:g}, atol={row['atol']:g}" if pd.notna(row.get("rtol")) else ""
            if setting:
                candidates.append((f"{name[:-1]}, {setting}]", float(row[column])))
    return min(candidates, key=lambda c: c[1]) if candidates else None


def ladder(frames: dict, query: str) -> pd.DataFrame:
    """The verdict ladder of `query`: one row per PINN spec (configuration and query path, first
    seed): its delta rel. L2 on the grid, its query time, and for each rung of `RUNGS` the
    fastest classical option of that rung at least as accurate, its time and the PINN's speed-up
    (classical / PINN time; > 1: the PINN is faster; NaN when the rung has nothing as accurate)."""
    acc, lat = ok(frames.get("accuracy")), ok(frames.get("latency"))
    if acc.empty or lat.empty:
        return pd.DataFrame()
    acc = verdict_rows(acc)
    acc = first_seed(acc[trained(acc)])
    error = dict(zip(label(acc), acc["rel_l2"]))
    lat = first_seed(lat[(lat["query"] == query) & trained(lat)])
    fit = first_seed(ok(frames.get("fit")))
    fit_s = dict(zip(label(fit), fit["fit_s"])) if not fit.empty else {}
    rows = []
    for name, pinn_s in zip(label(lat), lat["median_s"]):
        err = error.get(name, float("nan"))
        row = {"query": query, "pinn": name, "pinn_rel_l2": err, "pinn_s": float(pinn_s),
               "fit_s": fit_s.get(name, float("nan"))}
        for rung in RUNGS:
            best = fastest_classical(frames, query, err, rung) if not math.isnan(err) else None
            row[f"{rung}: option"] = best[0] if best else "none as accurate"
            row[f"{rung}: s"] = best[1] if best else float("nan")
            row[f"{rung}: speedup"] = best[1] / pinn_s if best else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)


RUNG_TITLES = dict(zip(RUNGS, ("literature baseline: scipy RK45 looped, as ode45 in the paper",
                               "best Python-driven classical", "best compiled classical")))


def ladder_queries(frames: dict) -> list[str]:
    """The queries of the ladder, in order: the grid, one trajectory, the single point at
    t1 = 10 s, and the batch of scattered single points, those the run timed."""
    lat = ok(frames.get("latency"))
    if lat.empty:
        return []
    timed = list(dict.fromkeys(lat["query"]))
    one = [q for q in timed if q.startswith("1 trajectories")]
    batch = [q for q in timed if str(q).endswith("single points, one call")]
    return [q for q in (GRID_QUERY, *one, POINT_QUERY, *batch) if q in timed]


def _cell(row: pd.Series, rung: str) -> str:
    speedup = row[f"{rung}: speedup"]
    if math.isnan(speedup):
        return "none as accurate"
    verdict = f"PINN {fmt(speedup, 2)}x faster" if speedup >= 1 else f"classical {fmt(1 / speedup, 2)}x faster"
    return f"{row[f'{rung}: option']}: {fmt(1e3 * row[f'{rung}: s'])} ms ({verdict})"


def ladder_rows(frames: dict, fastest_per_config: bool = True) -> pd.DataFrame:
    """`ladder` of every ladder query, one frame; with `fastest_per_config`, of each PINN
    configuration only its fastest spec (backend and query path) per query."""
    steps = [ladder(frames, query) for query in ladder_queries(frames)]
    steps = pd.concat([s for s in steps if not s.empty], ignore_index=True) if any(not s.empty for s in steps) \
        else pd.DataFrame()
    if steps.empty or not fastest_per_config:
        return steps
    config = steps["pinn"].str.extract(r"\[([^,\]]+)")[0]
    return steps.loc[steps.assign(config=config).groupby(["query", "config"], sort=False)["pinn_s"].idxmin()]


def ladder_table(frames: dict) -> pd.DataFrame:
    """Per query and PINN configuration, its fastest spec (first seed): its error and time, and
    each rung's fastest classical option at least as accurate, with who is faster by how much
    (every spec: `ladder_rows(frames, fastest_per_config=False)`, written to ladder.csv)."""
    return pd.DataFrame([{"query": r["query"], "PINN (first seed, fastest path)": r["pinn"],
                          "delta rel. L2": fmt(r["pinn_rel_l2"]), "PINN (ms)": fmt(1e3 * r["pinn_s"]),
                          **{RUNG_TITLES[rung]: _cell(r, rung) for rung in RUNGS}}
                         for _, r in ladder_rows(frames).iterrows()])


def _fastest_pinn(steps: pd.DataFrame) -> pd.Series | None:
    return None if steps.empty else steps.loc[steps["pinn_s"].idxmin()]


def _compiled_curves(frames: dict, max_rel_l2: float) -> list[tuple[str, dict[float, float]]]:
    """(label, {t1 s: median s}) of each compiled classical option at least as accurate as
    `max_rel_l2`: its named configs (latency suite) and each point of its sweep (work precision)."""
    curves = []
    lat, acc = ok(frames.get("latency")), ok(frames.get("accuracy"))
    if not lat.empty and not acc.empty:
        acc = verdict_rows(acc)
        acc = acc[compiled(acc) & ~trained(acc)]
        good = set(label(acc[acc["rel_l2"] <= max_rel_l2]))
        lat = lat[(lat["kind"] == "single point") & compiled(lat) & ~trained(lat)]
        for name, g in lat.groupby(label(lat), sort=False):
            if name in good:
                curves.append((name, dict(zip(g["t1_s"], g["median_s"]))))
    wp = ok(frames.get("work_precision"))
    if not wp.empty:
        wp = wp[compiled(wp) & ~trained(wp) & (wp["rel_l2_delta"] <= max_rel_l2)]
        columns = {c: float(m["t1"]) for c in wp if (m := T1_COLUMN.fullmatch(str(c)))}
        for (_, row), name in zip(wp.iterrows(), label(wp)):
            curve = {t1: row[c] for c, t1 in columns.items() if pd.notna(row[c])}
            if curve and isinstance(row.get("setting"), str) and row["setting"]:
                curves.append((f"{name[:-1]}, {row['setting']}]", curve))
    return curves


def crossover(frames: dict) -> dict | None:
    """The single-point query against t1 for the fastest PINN path at t1 = 10 s (first seed) and
    the compiled classical option at least as accurate that is fastest at t1 = 10 s (a named
    config or any point of a sweep): their labels, the t1 values (s), both medians (s), and
    `crossover_t1`'s verdict."""
    pinn = _fastest_pinn(ladder(frames, POINT_QUERY))
    if pinn is None:
        return None
    curves = [(name, curve) for name, curve in _compiled_curves(frames, pinn["pinn_rel_l2"]) if 10.0 in curve]
    if not curves:
        return None
    best, curve = min(curves, key=lambda c: c[1][10.0])
    lat = ok(frames.get("latency"))
    lat = first_seed(lat[lat["kind"] == "single point"])
    p = lat[label(lat) == pinn["pinn"]].set_index("t1_s")["median_s"]
    t1 = np.array(sorted(set(p.index) & set(curve)))
    if t1.size == 0:
        return None
    classical_s = np.array([curve[t] for t in t1])
    how, where = crossover_t1(t1, classical_s, p[t1].to_numpy())
    return {"pinn": pinn["pinn"], "classical": best, "t1_s": t1, "pinn_s": p[t1].to_numpy(),
            "classical_s": classical_s, "how": how, "t1_cross_s": where}


def _crossover_sentence(frames: dict) -> str | None:
    x = crossover(frames)
    if x is None:
        return None
    pair = f"{x['classical']} against {x['pinn']}"
    if x["how"] == "crossover":
        return (f"Single point against t1 ({pair}): the classical solver, which integrates from 0, is "
                f"cheaper below t1 = {fmt(x['t1_cross_s'])} s and the PINN above it.")
    span = f"t1 in [{fmt(x['t1_s'].min())}, {fmt(x['t1_s'].max())}] s"
    return f"Single point against t1 ({pair}): {x['how']} on the measured {span}, no crossover."


def verdict_lines(frames: dict) -> list[str]:
    """One sentence per ladder query: the fastest PINN path (first seed) against the fastest
    classical option of any rung at least as accurate; then the crossover in t1."""
    lines = []
    for query in ladder_queries(frames):
        pinn = _fastest_pinn(ladder(frames, query))
        if pinn is None:
            continue
        best = fastest_classical(frames, query, pinn["pinn_rel_l2"])
        head = f"{query}: fastest PINN {pinn['pinn']} {fmt(1e3 * pinn['pinn_s'])} ms at rel. L2 {fmt(pinn['pinn_rel_l2'])}"
        if best is None:
            lines.append(f"{head}; no classical option as accurate was measured.")
        elif best[1] < pinn["pinn_s"]:
            lines.append(f"{head}; classical wins: {best[0]} {fmt(1e3 * best[1])} ms, "
                         f"{fmt(pinn['pinn_s'] / best[1], 2)}x faster.")
        else:
            lines.append(f"{head}; the PINN wins, {fmt(best[1] / pinn['pinn_s'], 2)}x faster than "
                         f"{best[0]} ({fmt(1e3 * best[1])} ms).")
    sentence = _crossover_sentence(frames)
    if sentence:
        lines.append(sentence)
    trained_fit = ok(frames.get("fit"))
    if lines and not trained_fit.empty and trained(trained_fit).any():  # a run of the ladder's suites
        lines.append("Training cost is apart from these query times: see the break-even table.")
    return lines
