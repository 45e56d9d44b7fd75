"""Who wins which query: the ladder table, the single-point crossover in t1, and the verdict
sentences of a run. Pure pandas on the rows of one run (see `harness.report.frames.ladder`)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from harness.report.frames import (
    GRID_QUERY,
    POINT_QUERY,
    RUNGS,
    compiled,
    crossover_t1,
    fastest_classical,
    first_seed,
    fmt,
    label,
    ladder,
    ok,
    trained,
    verdict_rows,
)
from harness.suites.work_precision import T1_COLUMN

__all__ = ["crossover", "ladder_queries", "ladder_rows", "ladder_table", "verdict_lines"]

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
    """`analysis.ladder` of every ladder query, one frame; with `fastest_per_config`, of each PINN
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
