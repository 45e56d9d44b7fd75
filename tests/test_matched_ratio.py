"""The matched-accuracy ratio of a verdict: the rival's time interpolated on its family's
work-precision curve to the PINN's error, on synthetic sweeps of known errors and seconds."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from harness.report.verdicts import verdict_table
from harness.settings import DEFAULT, QUICK
from harness.suites._matching import Candidate, Rivals, interpolated_s, margin
from harness.suites._queries import Query
from harness.suites.verdict import _row
from solvers.base import COARSE_RTOL, AbstractSolver
from solvers.classical.trapezoid import COARSE_STEPS, STEPS
from systems.cases import SMIB_INFERENCE as CASE

QUERY = Query("grid", "grid 2x3", np.linspace(0.0, 1.0, 3), np.array([0.1, 0.2]))
FAMILY = ("numba-rk", "default", ())


def _rivals(sweep: list[tuple[float, tuple[float, float], float]]) -> Rivals:
    """A `Rivals` of one family whose points (rtol, (angle, speed errors), seconds) are given,
    coarsest first."""
    rivals = Rivals.__new__(Rivals)
    rivals.case, rivals.settings = CASE, replace(QUICK, max_query_s=math.inf)
    points = [Candidate(FAMILY, {"rtol": rtol}, CASE, 1) for rtol, _, _ in sweep]
    rivals.sweeps = {FAMILY: points}
    known = {c.label: (errors, seconds) for c, (_, errors, seconds) in zip(points, sweep)}
    rivals.errors = lambda c, q: known[c.label][0]  # type: ignore[method-assign]
    rivals.warm_call_s = lambda c, q: known[c.label][1]  # type: ignore[method-assign]
    return rivals


def _verdict_row(rivals: Rivals, delta: float, omega: float) -> dict:
    rival, notes = rivals.best(QUERY, delta, omega)
    assert rival is not None
    pinn_s, rival_s = [1e-3] * 8, [4e-3 * (1 + 0.01 * i) for i in range(8)]
    plan = {"base": {"pinn_seed": 0, "kind": QUERY.kind, "query": QUERY.name, "pinn_path": "",
                     "pinn_rel_l2_delta": delta, "pinn_rel_l2_omega": omega},
            "query": QUERY, "rival": rival, "notes": notes, "gate": True,
            "match": rivals.match(rival, QUERY, delta, omega), "samples": (pinn_s, rival_s), "calls": (1, 1)}
    return _row(plan, QUICK.verdict_rounds, QUICK, rivals)


def test_interpolation_is_linear_in_log_seconds_against_log_margin():
    assert interpolated_s((0.5, 2.0), (2.0, 1.0)) == pytest.approx(math.sqrt(2.0))  # halfway in log(margin)
    assert interpolated_s((1.0, 2.0), (4.0, 1.0)) == 2.0  # the chosen point at the PINN's accuracy
    assert math.isnan(interpolated_s((0.5, 2.0), (math.inf, 1.0)))
    assert margin((1e-3, 4e-3), 2e-3, 2e-3) == 2.0  # the binding metric: the speeds
    assert math.isnan(margin((math.nan, 1e-3), 1.0, 1.0))


def test_the_matched_ratio_interpolates_between_the_rival_and_the_next_coarser_point():
    # margins 4, 0.5, 0.05: the rival is the 1e-3 point (2 ms), the 1e-2 one (1 ms) is too coarse
    rivals = _rivals([(1e-2, (4e-3, 8e-3), 1e-3), (1e-3, (5e-4, 1e-3), 2e-3), (1e-4, (5e-5, 1e-4), 4e-3)])
    row = _verdict_row(rivals, 2e-3, 2e-3)
    assert row["rival"] == "numba-rk [default, rtol=0.001]"
    assert row["rival_margin"] == pytest.approx(0.5) and row["nearest_factor"] == pytest.approx(2.0)
    # w = log(2) / log(8) = 1/3 of the way to the coarser point: 2 ms ** (2/3) * 1 ms ** (1/3)
    t_matched = math.exp(2 / 3 * math.log(2e-3) + 1 / 3 * math.log(1e-3))
    assert row["matched_ratio"] == pytest.approx(row["ratio"] * t_matched / 2e-3)
    assert row["matched_ratio"] < row["ratio"]  # an over-accurate rival: the ratio overstates the PINN's lead
    assert "coarsest" not in row["rivals_note"]


def test_a_rival_at_the_coarsest_point_has_no_matched_ratio_and_its_note_says_the_ratio_is_an_upper_bound():
    rivals = _rivals([(1e-2, (1e-3, 2.5e-3), 1e-3), (1e-3, (1e-4, 2e-4), 2e-3)])
    row = _verdict_row(rivals, 1e-2, 1e-2)
    assert math.isnan(row["matched_ratio"]) and row["rival_margin"] == pytest.approx(0.25)
    assert row["nearest_factor"] == pytest.approx(4.0)
    assert "the coarsest sweep point is 4x more accurate: the ratio is an upper bound on the PINN's lead" \
        in row["rivals_note"]
    frame = pd.DataFrame([{"suite": "verdict", "case": CASE.name, "solver": "jax-pinn", "config": "default",
                           "variant": "", "status": "ok", "label": row["label"], **row}])
    table = verdict_table({"verdict": frame})
    assert table is not None and table["matched ratio"].tolist() == ["- (rival 4x more accurate)"]


def test_a_coarser_point_without_a_finite_answer_leaves_no_matched_ratio_and_says_why():
    rivals = _rivals([(3e-2, (math.nan, math.nan), 1e-3), (1e-2, (1e-3, 1e-3), 2e-3)])
    row = _verdict_row(rivals, 2e-3, 2e-3)
    assert math.isnan(row["matched_ratio"]) and "gives no finite answer" in row["rivals_note"]


def test_a_sweep_point_whose_integration_fails_has_errors_of_nan_not_a_crash():
    from solvers.base import SolveError

    class Failing:
        def solve(self, t, P1):
            raise SolveError("trapezoid: integration failed at t_c=0.1: Newton did not converge")

    rivals = Rivals.__new__(Rivals)
    rivals.case, rivals._errors = CASE, {}
    point = Candidate(FAMILY, {"rtol": 3e-2}, CASE, 1, _solver=Failing())  # type: ignore[arg-type]
    assert all(math.isnan(e) for e in rivals.errors(point, QUERY))


def test_a_verdict_sweep_coarser_than_ode45_adds_coarser_fixed_steps_and_leaves_the_work_precision_sweep():
    wide = (3e-2, 1e-2, 3e-3, *QUICK.wp_rtols)
    assert [p["dt"] for p in AbstractSolver.step_sweep(STEPS, wide, COARSE_STEPS)] == [*COARSE_STEPS, *STEPS[:4]]
    assert [p["dt"] for p in AbstractSolver.step_sweep(STEPS, (1e-2, 1e-4), COARSE_STEPS)] == [COARSE_STEPS[-1], STEPS[0]]
    assert AbstractSolver.step_sweep(STEPS, QUICK.wp_rtols, COARSE_STEPS) == AbstractSolver.step_sweep(STEPS, QUICK.wp_rtols)
    assert max(QUICK.wp_rtols) <= COARSE_RTOL

    assert max(DEFAULT.verdict_rtols) == 3e-2 and sum(r > COARSE_RTOL for r in DEFAULT.verdict_rtols) == 3
    sweep = [p["dt"] for p in AbstractSolver.step_sweep(STEPS, DEFAULT.verdict_rtols, COARSE_STEPS)]
    assert sweep == [*COARSE_STEPS, *STEPS]  # every step of the work-precision sweep stays in the verdict's


def test_a_gap_in_the_sweep_wider_than_3x_is_interpolated_across_and_the_note_says_so():
    # margins 10 and 0.1: both points 10x from the PINN's error
    rivals = _rivals([(1e-2, (1e-2, 1e-2), 1e-3), (1e-3, (1e-4, 1e-4), 4e-3)])
    row = _verdict_row(rivals, 1e-3, 1e-3)
    assert row["nearest_factor"] == pytest.approx(10.0)
    assert row["matched_ratio"] == pytest.approx(row["ratio"] * 2e-3 / 4e-3)  # halfway: sqrt(1 ms * 4 ms)
    assert "the nearest sweep point is 10x from the PINN's error, over 3x" in row["rivals_note"]


def test_rk4s_verdict_sweep_reaches_past_its_work_precision_steps():
    from solvers import make_solver
    from solvers.classical.numba_rk import RK4_COARSE_STEPS, RK4_STEPS

    rk4 = make_solver("numba-rk", CASE, method="rk4")
    assert [p["dt"] for p in rk4.precision_sweep(DEFAULT.verdict_rtols)] == [*RK4_COARSE_STEPS, *RK4_STEPS]
    assert [p["dt"] for p in rk4.precision_sweep(DEFAULT.wp_rtols)] == list(RK4_STEPS)
