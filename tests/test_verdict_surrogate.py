"""The classical surrogate as the verdicts' second rival, from synthetic rows and without a PINN:
its columns in the table and the summary beside the ODE solver's, rows written before them read
as they did, and "not applicable" on a case no surrogate is made for."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from harness.measure.paired import CLASSICAL_FASTER, NO_RIVAL, NOT_APPLICABLE, PINN_FASTER, TIE
from harness.report.tables import build_tables
from harness.report.verdicts import RULE_SURROGATE, verdict_summary, verdict_table, verdicts
from harness.settings import QUICK
from harness.suites._matching import Rivals
from harness.suites._queries import verdict_queries
from harness.suites.verdict import _surrogate_columns
from solvers import SOLVERS
from systems.cases import CASES
from systems.faults import FAULT_CASES

SETTINGS = replace(QUICK, cache_dir=None)
SURROGATE_CELLS = ["surrogate verdict", "surrogate ratio [95 % CI]", "surrogate", "fit s, PINN / surrogate"]


def _rows(with_surrogate: bool) -> list[dict]:
    """Two queries of two seeds: the grid (the ODE solver wins, the PINN beats the surrogate on
    both seeds) and the single point (ties against the solver; no surrogate as accurate on seed 1)."""
    rows = []
    for query, kind, ratio, sur in (("grid 100x201", "grid", 0.5, (3.0, 4.0)),
                                    ("single point t1=10 s", "single point", 1.0, (2.0, None))):
        for seed in (0, 1):
            row = {"suite": "verdict", "case": "wscc9", "solver": "jax-pinn", "config": "marching",
                   "variant": "query=numba", "status": "ok", "query": query, "kind": kind, "pinn_seed": seed,
                   "pinn_path": "query=numba", "label": CLASSICAL_FASTER if ratio < 1 else TIE, "ratio": ratio + seed / 10,
                   "ratio_low": ratio / 2, "ratio_high": ratio * 1.1, "rival": "numba-rk [default, rtol=1e-05]",
                   "rivals_note": "", "pinn_rel_l2_delta": 1e-4, "pinn_rel_l2_omega": 1e-3,
                   "rival_rel_l2_delta": 5e-5, "rival_rel_l2_omega": 5e-4, "pinn_median_s": 1e-3,
                   "rival_median_s": ratio * 1e-3, "samples": 8, "matched_ratio": np.nan, "rival_margin": 0.5,
                   "nearest_factor": 2.0, "fit_s": 100.0 + seed}
            s = sur[seed]
            if with_surrogate:
                row |= ({"surrogate": f"pod-spline [default, n_snapshots={9 + 8 * seed}]", "surrogate_label": PINN_FASTER,
                         "surrogate_ratio": s, "surrogate_ratio_low": s / 1.5, "surrogate_ratio_high": s * 1.5,
                         "surrogate_median_s": s * 1e-3, "surrogate_fit_s": 0.03, "surrogate_note": ""} if s else
                        {"surrogate": "", "surrogate_label": NO_RIVAL, "surrogate_fit_s": np.nan,
                         "surrogate_note": "pod-spline default: no sweep point as accurate"})
            rows.append(row)
    return rows


def _frames(with_surrogate: bool) -> dict:
    return {"verdict": pd.DataFrame(_rows(with_surrogate))}


def test_rows_without_the_surrogate_render_as_before_and_with_it_gain_its_columns_beside():
    old, new = verdict_table(_frames(False)), verdict_table(_frames(True))
    assert not set(SURROGATE_CELLS) & set(old.columns)
    assert list(new.columns) == [*old.columns, *SURROGATE_CELLS]
    pd.testing.assert_frame_equal(new[old.columns], old)  # the ODE solver's verdicts untouched
    grid, point = new.iloc[0], new.iloc[1]
    assert grid["surrogate verdict"] == "PINN faster (PINN faster on 2 of 2)"
    assert grid["surrogate ratio [95 % CI]"] == "3x [2, 4.5]"  # the worst seed: the least ratio
    assert grid["surrogate"] == "pod-spline [default, n_snapshots=9]"
    assert grid["fit s, PINN / surrogate"] == "100 / 0.03"  # that seed's PINN beside its surrogate
    assert point["surrogate verdict"] == "tie (PINN faster on 1 of 2, no rival on 1 of 2)"
    assert point["surrogate"] == "pod-spline default: no sweep point as accurate"  # the seed without a ratio
    about = {name: text for name, (_, text, _) in build_tables(_frames(True)).items()}
    assert about["verdicts"].endswith(RULE_SURROGATE)
    assert RULE_SURROGATE not in build_tables(_frames(False))["verdicts"][1]


def test_the_summary_adds_the_surrogate_only_where_the_rows_carry_it():
    old, new = verdict_summary(_frames(False)), verdict_summary(_frames(True))
    assert old == ("- **wscc9**, 2 queries: the solver wins 1 (0.5x); a tie on 1 (1x); the PINN's rel. L2 in the "
                   "angles 0.0001.\n")
    assert new == old.replace(".\n", ". Against the classical surrogate: the PINN wins 1 (3x): grid 100x201; a tie on "
                                     "1.\n")
    assert (verdicts(_frames(True))["surrogate verdict"] == [PINN_FASTER, TIE]).all()


def test_the_summary_counts_the_queries_not_timed_each_once_with_their_reason():
    skipped = [{"suite": "verdict", "case": "wscc9", "solver": "jax-pinn", "config": "marching", "query": query,
                "status": f"skipped: the PINN's call estimated {s} s, over 10 s"}
               for query, s in (("1000 trajectories x 201 times", 11.2), ("10000 single points, one call", 122))]
    frames = {"verdict": pd.DataFrame(_rows(False) + skipped)}
    assert verdict_summary(frames) == verdict_summary(_frames(False)).replace(
        "(1x);", "(1x); not timed on 2 (the PINN's call estimated over 10 s);")
    failed = {**skipped[0], "query": "10 trajectories x 201 times", "status": "failed: SolveError: step 3"}
    frames = {"verdict": pd.DataFrame(_rows(False) + skipped + [failed])}
    assert "; not timed on 3 (skipped or failed, see its table);" in verdict_summary(frames)


def test_a_case_no_surrogate_is_made_for_is_not_applicable_with_the_reason():
    fault = CASES[FAULT_CASES["wscc9"][0]]
    surrogates = Rivals(fault, SETTINGS, surrogates=True)
    assert not surrogates.sweeps
    query = verdict_queries(fault, SETTINGS)[0]
    columns = _surrogate_columns({"rival": None, "notes": []}, True, SETTINGS, surrogates, query)
    assert columns["surrogate_label"] == NOT_APPLICABLE and columns["surrogate"] == ""
    if SOLVERS["pod-spline"] is not None:
        assert "pod-spline default: not made for network cases of clearing time (t_c)" in columns["surrogate_note"]
    table = verdict_table({"verdict": pd.DataFrame([{**_rows(False)[0], **columns}])})
    assert table.iloc[0]["surrogate verdict"].startswith(NOT_APPLICABLE)


def test_the_heat_map_has_a_row_against_the_surrogate_only_where_the_rows_carry_it():
    import matplotlib.pyplot as plt

    from harness.report.plots import verdict_plot

    def rows_of(frames: dict) -> tuple[list[str], list[str]]:
        fig = verdict_plot(frames, lambda name: name)
        labels = [t.get_text() for t in fig.axes[0].get_yticklabels()]
        cells = sorted(t.get_text() for t in fig.axes[0].texts)
        plt.close(fig)
        return labels, cells

    old_labels, old_cells = rows_of(_frames(False))
    new_labels, new_cells = rows_of(_frames(True))
    assert [label.split("\n")[1] for label in old_labels] == ["against the ODE solver"]
    assert [label.split("\n")[1] for label in new_labels] == ["against the ODE solver", "against the surrogate"]
    # the solver's cells as before, and the surrogate's beside them: the grid's worst seed with its
    # ratio; the point's label over seeds alone, its worst seed having no surrogate as accurate
    assert sorted(new_cells) == sorted([*old_cells, f"3x\n{PINN_FASTER}", TIE])


def test_rows_stored_under_another_interval_rule_are_restated_from_their_samples():
    """A seed row written before the repeat-run interval (no `interval` column, the narrower
    interval and its label stored) is read with the interval and label its samples give under the
    current rule, the ODE rival's and the surrogate's; a row under the current rule is read as
    stored, and a row without samples (a loss by the gate) keeps its label."""
    from harness.measure.paired import INTERVAL, ratio_interval, verdict_label
    from harness.report.verdicts import restated

    pinn = [1e-3, 1.01e-3, 0.99e-3, 1.02e-3]
    rival = [1.6e-3, 1.62e-3, 1.58e-3, 1.61e-3]
    narrow = ratio_interval(pinn, rival, repeat=False)
    assert verdict_label(*narrow[1:]) == PINN_FASTER
    old = {"label": PINN_FASTER, "ratio": narrow[0], "ratio_low": narrow[1], "ratio_high": narrow[2],
           "pinn_samples_s": pinn, "rival_samples_s": rival, "surrogate_label": PINN_FASTER,
           "surrogate_pinn_samples_s": pinn, "surrogate_samples_s": rival, "surrogate_ratio_low": narrow[1],
           "surrogate_ratio_high": narrow[2]}
    gated = {"label": CLASSICAL_FASTER, "pinn_samples_s": np.nan, "rival_samples_s": np.nan}
    rows = restated(pd.DataFrame([old, gated]))
    _, low, high = ratio_interval(pinn, rival)
    assert low < narrow[1] and high > narrow[2] and verdict_label(low, high) == TIE
    assert rows.loc[0, ["ratio_low", "ratio_high", "label"]].tolist() == [low, high, TIE]
    assert rows.loc[0, ["surrogate_ratio_low", "surrogate_ratio_high", "surrogate_label"]].tolist() == [low, high, TIE]
    assert rows.loc[1, "label"] == CLASSICAL_FASTER and set(rows["interval"]) == {INTERVAL}
    current = pd.DataFrame([{**old, "interval": INTERVAL}])
    assert restated(current).loc[0, "label"] == PINN_FASTER  # stored under the current rule: as stored


def test_restating_the_same_rows_again_reuses_their_intervals():
    """One report restates the same stored rows several times: the second time takes each interval
    from the first (the same samples give the same interval), with the same result."""
    from harness.report.verdicts import _current_interval, restated

    pinn, rival = [1e-3, 1.01e-3, 0.98e-3], [2e-3, 2.03e-3, 1.97e-3]
    rows = pd.DataFrame([{"label": PINN_FASTER, "pinn_samples_s": pinn, "rival_samples_s": rival}])
    first = restated(rows)
    hits = _current_interval.cache_info().hits
    again = restated(rows)
    assert _current_interval.cache_info().hits == hits + 1
    pd.testing.assert_frame_equal(first, again)


def test_the_verdict_csv_states_the_intervals_and_labels_the_tables_do(tmp_path):
    """`verdict.csv` beside the tables: a row stored under another interval rule is written with
    the interval and label the tables state (`restated`), not the stored ones."""
    from harness.measure.paired import INTERVAL, ratio_interval
    from harness.report.files import write_report

    pinn, rival = [1e-3, 1.01e-3, 0.99e-3, 1.02e-3], [1.6e-3, 1.62e-3, 1.58e-3, 1.61e-3]
    narrow = ratio_interval(pinn, rival, repeat=False)
    row = {"suite": "verdict", "case": "smib-inference", "solver": "toy-pinn", "config": "default", "variant": "",
           "seed": 0, "trains": True, "status": "ok", "query": "grid 100x201", "kind": "grid", "pinn_seed": 0,
           "label": PINN_FASTER, "ratio": narrow[0], "ratio_low": narrow[1], "ratio_high": narrow[2],
           "pinn_samples_s": pinn, "rival_samples_s": rival, "pinn_rel_l2_delta": 1e-3, "pinn_rel_l2_omega": 1e-3}
    write_report([row], tmp_path, {"threads": 2}, plots=False)
    csv = pd.read_csv(tmp_path / "verdict.csv")
    _, low, high = ratio_interval(pinn, rival)
    assert csv.loc[0, ["label", "interval"]].tolist() == [TIE, INTERVAL]
    assert np.allclose(csv.loc[0, ["ratio_low", "ratio_high"]].astype(float), [low, high])
