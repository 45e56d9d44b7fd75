"""The cct suite (`harness.suites.cct`) on test-only adapters that integrate fault cases: one that
answers from the reference integrator (a classical adapter's search, bisection) and a surrogate
(`trains`, bounded to its domain) whose trajectories turn unstable 2 ms after the reference CCT
(the grid-then-bisection search); the planner and the report's CCT table."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import matplotlib.pyplot as plt
import numpy as np
import pytest

from harness.report.cct import cct_headline, cct_summary, cct_table
from harness.report.cct_plot import cct_plot
from harness.report.frames import case_sections, suite_frames
from harness.report.labels import Labels
from harness.report.tables import build_tables
from harness.run.plan import plan
from harness.run.runner import run_unit
from harness.settings import QUICK, SolverSpec
from harness.suites import SUITES
from harness.suites.accuracy import COI_DELTA, accuracy, answers, stability_classes
from harness.suites.cct import BRACKET_S, bisect, cct, criterion_times, grid_then_bisect
from solvers import SOLVERS
from solvers.base import AbstractSolver, FitReport, PartialSolveError, SolveError
from systems.cases import CASES, Case, standard_grid
from systems.reference import STABILITY_CLASSES, STABLE_CLEARING, UNSTABLE_CLEARING, reference
from systems.stability import ANGLE_LIMIT, reference_cct

CASE = "kundur4-bus7-line7-8a"
SHIFT_S = 2e-3  # the surrogate's CCT lies this much after the reference's
SETTINGS = replace(QUICK, min_repeats=1, latency_budget_s=0.0, cache_dir=None)


class ReferenceFaults(AbstractSolver):
    """The reference integrator behind the adapter interface (DOP853 at 1e-12, the switch exact)."""

    name: ClassVar[str] = "reference-faults"
    handles_faults: ClassVar[bool] = True

    def _fit(self):
        return None

    def _solve(self, t, P1):
        return reference(self.case, t, P1)

    def _identify(self, obs):
        raise NotImplementedError


class ShiftedSurrogate(AbstractSolver):
    """A stand-in for a trained surrogate, bounded to the case's domain: machines 1 and 2 swing apart
    about a centre of inertia at 0, the farther by ANGLE_LIMIT (t / t_final) (t_c / t*), t* = the
    reference CCT + SHIFT_S, so that its trajectories are unstable exactly for t_c > t*."""

    name: ClassVar[str] = "shifted-surrogate"
    OPTIONS: ClassVar[dict] = {"seed": 0}
    handles_faults: ClassVar[bool] = True
    trains: ClassVar[bool] = True
    bounded_domain: ClassVar[bool] = True

    def _fit(self):
        self._t_star = reference_cct(CASES[self.case.name]) + SHIFT_S  # the registered case's, whatever the range
        m = np.asarray(self.case.m)
        shape = np.zeros(self.case.n)
        shape[0], shape[1] = 1.0, -m[0] / m[1]  # no move of the centre of inertia
        self._shape = shape / np.abs(shape).max()
        return FitReport(seconds=0.0, iterations=1, loss=0.0)  # what a trained model reports

    def _solve(self, t, P1):
        amplitude = ANGLE_LIMIT * np.outer(P1 / self._t_star, t / self.case.t_final)
        delta = amplitude[..., None] * self._shape
        return delta, np.zeros_like(delta)

    def _identify(self, obs):
        raise NotImplementedError


class RefusingSurrogate(ShiftedSurrogate):
    """The same surrogate, refusing (SolveError, as pinnsim does when a machine leaves its trained
    domain) every call that holds a clearing time in (t* + REFUSED[0], t* + REFUSED[1]] s."""

    name: ClassVar[str] = "refusing-surrogate"
    REFUSED: ClassVar[tuple[float, float]] = (0.0, 0.025)

    def _solve(self, t, P1):
        low, high = self._t_star + self.REFUSED[0], self._t_star + self.REFUSED[1]
        if np.any((P1 > low) & (P1 <= high)):
            raise SolveError(f"{self.name}: refused t_c in {P1}")
        return super()._solve(t, P1)


class StoppingSurrogate(ShiftedSurrogate):
    """The same surrogate, stopping part-way (`PartialSolveError`, as pinnsim does) every trajectory
    cleared after t*: STOP_AFTER s after its crossing of the criterion for t_c <= t* + SEEN_S, and
    half-way to it above (a refusal with no crossing seen)."""

    name: ClassVar[str] = "stopping-surrogate"
    SEEN_S: ClassVar[float] = 0.015
    STOP_AFTER: ClassVar[float] = 0.05

    def _solve(self, t, P1):
        delta, omega = super()._solve(t, P1)
        crossing = self.case.t_final * self._t_star / P1  # ANGLE_LIMIT reached (s)
        held = np.where(P1 <= self._t_star, np.inf,
                        np.where(P1 <= self._t_star + self.SEEN_S, crossing + self.STOP_AFTER, 0.5 * crossing))
        if np.isinf(held).all():
            return delta, omega
        partial = np.where(t[None, :, None] < held[:, None, None], delta, np.nan)
        raise PartialSolveError(f"{self.name}: stopped at {held}", partial, held)


class StepsOnly(ReferenceFaults):
    """The same, declared not to integrate fault cases."""

    name: ClassVar[str] = "steps-only"
    handles_faults: ClassVar[bool] = False


def _fitted(cls: type[AbstractSolver], case: Case) -> AbstractSolver:
    solver = cls(case)
    solver.fit()
    return solver


def test_bisection_on_the_reference_finds_the_reference_cct_within_the_bracket():
    case = CASES[CASE]
    (row,) = cct(_fitted(ReferenceFaults, case), case, SETTINGS)
    assert row["method"] == "bisection" and row["contingency"] == "bus7-line7-8a"
    assert row["unstable_s"] - row["stable_s"] <= BRACKET_S * (1 + 1e-9)
    assert abs(row["cct_error_s"]) <= BRACKET_S
    assert row["solves"] == 10 and row["trajectories"] == 11  # the two ends together, then 9 halvings of 0.35 s
    assert row["median_s"] > 0 and row["repeats"] >= 1


def test_the_surrogate_search_narrows_a_batched_grid_to_the_bracket():
    """A grid 10 ms apart (36 clearing times, one query) narrowed by 4 single queries to 0.625 ms
    around the surrogate's own CCT, SHIFT_S after the reference's; a grid 1 ms apart needs none."""
    case = CASES[CASE]
    solver = _fitted(ShiftedSurrogate, case)
    coarse = grid_then_bisect(solver, 1e-2)
    assert (coarse.solves, coarse.trajectories) == (5, 40)
    assert coarse.stable_s <= reference_cct(case) + SHIFT_S <= coarse.unstable_s
    assert coarse.unstable_s - coarse.stable_s <= BRACKET_S
    (row,) = cct(solver, case, SETTINGS)
    assert row["method"] == "grid + bisection" and (row["solves"], row["trajectories"]) == (5, 40)
    assert abs(row["cct_error_s"] - SHIFT_S) <= BRACKET_S / 2
    fine = grid_then_bisect(solver, 1e-3)
    assert (fine.solves, fine.trajectories) == (1, 351) and abs(fine.cct_s - coarse.cct_s) <= BRACKET_S


def test_a_range_without_the_cct_gives_no_cct_and_says_why():
    """The searches say so (the suite, whose reference CCT lies outside such a range, too)."""
    case = CASES[CASE]
    early = replace(case, p1_max=0.1)
    found = grid_then_bisect(_fitted(ShiftedSurrogate, early), 1e-2)
    assert np.isnan(found.cct_s) and found.note == "stable at p1_max = 0.1 s: the CCT lies above the range"
    late = replace(case, p1_min=0.3)
    found = bisect(_fitted(ReferenceFaults, late))
    assert np.isnan(found.cct_s) and found.note == "unstable at p1_min = 0.3 s: the CCT lies below the range"
    assert (found.solves, found.trajectories) == (1, 2)
    with pytest.raises(ValueError, match="'kundur4-bus7-line7-8a': unstable at the shortest clearing time p1_min = 0.3 s"):
        cct(_fitted(ReferenceFaults, late), late, SETTINGS)
    with pytest.raises(ValueError, match="'kundur4' is no fault case: it has no CCT"):
        cct(_fitted(ReferenceFaults, CASES["kundur4"]), CASES["kundur4"], SETTINGS)


def test_refused_clearing_times_are_neither_side_and_leave_the_bracket_wide_where_they_fall():
    """A refused batch is asked one clearing time at a time; the bracket runs from the last stable to
    the first unstable clearing time over the refused ones between, bisection splits the widest
    interval between its ends and the refusals until none is wider than the bracket's width, and the
    row counts the refusals and says where the search stopped; refusals on the whole unstable side
    leave no CCT."""
    case = CASES[CASE]
    t_star = reference_cct(case) + SHIFT_S
    solver = _fitted(RefusingSurrogate, case)
    found = grid_then_bisect(solver, 1e-2)
    assert found.stable_s <= t_star < found.unstable_s and found.unstable_s > t_star + RefusingSurrogate.REFUSED[1]
    assert found.unstable_s - found.stable_s > BRACKET_S
    assert found.note == "40 refused t_c in the bracket (0.2125 to 0.236875 s): left at 25.6 ms"
    # the grid (10 ms from 0.05 s): stable to 0.21 s, 0.22 and 0.23 s refused, 0.24 s unstable; one
    # batch, then its 36 clearing times one at a time, then 41 midpoints, 38 of them refused: the
    # bracket's ends bisected up to the refused interval (t*, t* + 25 ms] from either side
    assert (found.solves, found.trajectories, found.refused) == (78, 113, 40)
    assert (found.unstable_s, round(found.stable_s, 9)) == (0.2375, 0.211875) and found.stable_s <= t_star
    (row,) = cct(solver, case, SETTINGS)
    assert row["refused"] == found.refused and row["note"] == found.note and "traj_pred" not in row
    assert abs(row["cct_error_s"]) < (row["unstable_s"] - row["stable_s"])

    class RefusesUnstable(RefusingSurrogate):
        REFUSED = (0.0, 1.0)

    found = grid_then_bisect(_fitted(RefusesUnstable, case), 1e-2)
    assert np.isnan(found.cct_s) and found.stable_s <= t_star and found.refused > 10
    assert found.note.startswith("no clearing time judged unstable up to p1_max = 0.4 s; ")
    assert bisect(_fitted(RefusesUnstable, case)).note.endswith("; 1 of 2 refused")


def test_a_trajectory_stopped_after_its_crossing_is_unstable_and_one_stopped_before_is_refused():
    """An adapter that says how far each trajectory held is judged on that part, batch and all: a
    crossing seen before it stopped makes it unstable (the bracket narrows to the surrogate's CCT
    with no batch asked again), one stopped before any crossing is refused and counted."""
    case = CASES[CASE]
    t_star = reference_cct(case) + SHIFT_S
    found = grid_then_bisect(_fitted(StoppingSurrogate, case), 1e-2)
    assert found.stable_s <= t_star < found.unstable_s and found.unstable_s - found.stable_s <= BRACKET_S * (1 + 1e-9)
    grid = np.linspace(case.p1_min, case.p1_max, 36)
    assert found.refused == int((grid > t_star + StoppingSurrogate.SEEN_S).sum()) > 0
    assert found.solves == 1 + (found.trajectories - grid.size)  # the batch once, then one midpoint a call


def test_a_bounded_adapter_refuses_a_clearing_time_outside_its_range():
    case = CASES[CASE]
    solver = _fitted(ShiftedSurrogate, case)
    t = criterion_times(case)
    with pytest.raises(ValueError, match=r"t_c spans \[0.45, 0.45\] s, outside the trained domain \[0.05, 0.4\] s"):
        solver.solve(t, np.array([0.45]))
    assert solver.solve(t, np.array([0.45]), extrapolate=True).delta.shape == (1, t.size, case.n)


def test_the_planner_runs_cct_on_fault_cases_with_adapters_that_integrate_them(monkeypatch):
    """On a fault case: the adapters with handles_faults (no unit for one without); on a step case
    the suite is recorded as skipped. The units run, and the fault case's section of the report
    has the CCT table and figure: the surrogate's break-even N* is where its training and N* searches
    cost N* searches of the classical adapter (never, when its search is not faster)."""
    monkeypatch.setitem(SOLVERS, ReferenceFaults.name, ReferenceFaults)
    monkeypatch.setitem(SOLVERS, ShiftedSurrogate.name, ShiftedSurrogate)
    monkeypatch.setitem(SOLVERS, StepsOnly.name, StepsOnly)
    specs = [SolverSpec(ReferenceFaults.name), SolverSpec(ShiftedSurrogate.name, seed=0), SolverSpec(StepsOnly.name)]
    fault, step = CASES[CASE], CASES["kundur4"]
    result = plan(specs, [fault, step], [SUITES["cct"]], SETTINGS)
    assert [(skip.case.name, skip.spec.solver, skip.reason) for skip in result.not_run] == [
        (CASE, StepsOnly.name, f"skipped: {StepsOnly.name} does not integrate fault cases (no handles_faults)")]
    on_step = [unit for unit in result.units if unit.case == step]
    assert {unit.spec.solver for unit in on_step} == {ReferenceFaults.name, ShiftedSurrogate.name, StepsOnly.name}
    no_fault = "skipped: cct measures fault cases only, and kundur4 has no fault"
    assert {unit.skipped for unit in on_step} == {(("cct", no_fault),)}
    rows = [row for unit in result.units for _, part in run_unit(unit, SETTINGS, unit.works()) for row in part]
    assert {row["status"] for row in rows if row["case"] == "kundur4"} == {no_fault}
    (name, frames), _ = case_sections(suite_frames(rows))
    assert name == CASE
    *_, table = build_tables(frames)["cct"]
    assert table["solver"].tolist() == [f"{ReferenceFaults.name} [default]", f"{ShiftedSurrogate.name} [default]"]
    by_method = frames["cct"].set_index("solver")
    classical_s, surrogate_s = by_method.loc[ReferenceFaults.name, "median_s"], by_method.loc[ShiftedSurrogate.name, "median_s"]
    fit_s = frames["fit"].set_index("solver").loc[ShiftedSurrogate.name, "fit_s"]
    figure = cct_plot(frames, Labels(frames))
    assert [ax.get_title() for ax in figure.axes][1:] == [
        f"unstable side: t_c = {1e3 * (reference_cct(fault) + 0.02):.4g} ms",  # clearing times ~0.1 s: in ms
        f"reference CCT {1e3 * reference_cct(fault):.4g} ms"]
    plt.close(figure)
    cell = table["break-even N* (CCT searches)"].iloc[1]
    if surrogate_s < classical_s:
        n_star = float(cell)
        assert fit_s + n_star * surrogate_s == pytest.approx(n_star * classical_s, rel=1e-2)
    else:  # the stand-in reference answers timed repeats from its cache
        assert cell == "never"


def _search(solver: str, error_ms: float, median_ms: float, spread: float = 0.01, **extra) -> dict:
    """A cct row of case kundur4's fault: the search's CCT error (ms) and its time (median, ms)."""
    ref = 0.2
    cct_s = ref + 1e-3 * error_ms
    return {"suite": "cct", "case": CASE, "solver": solver, "config": "default", "variant": "", "seed": -1,
            "status": "ok", "trains": False, "method": "bisection", "cct_s": cct_s,
            "reference_cct_s": ref, "cct_error_s": 1e-3 * error_ms, "note": "", "solves": 10, "trajectories": 11,
            "bracket_s": BRACKET_S, "stable_s": cct_s - BRACKET_S / 2, "unstable_s": cct_s + BRACKET_S / 2, "median_s": 1e-3 * median_ms, "q25_s": 1e-3 * median_ms * (1 - spread),
            "q75_s": 1e-3 * median_ms * (1 + spread), "repeats": 5, **extra}


def _surrogate(seed: int, error_ms: float, median_ms: float, fit_s: float, spread: float = 0.01) -> dict:
    return _search("pinn", error_ms, median_ms, spread, config="fault", seed=0, trains=True,
                   method="grid + bisection", pinn_seed=seed, seed_fit_s=fit_s)


def test_the_headline_matches_each_seed_with_a_rival_at_least_as_close_and_calls_a_side_on_every_seed_only():
    """The rival of a surrogate's seed is the fastest classical search at least as close to the
    reference CCT (within the 1 ms bracket counts as exact); a seed more than 5 ms off is a loss;
    a side is faster only beyond 1.2x with the quartiles apart, and wins only on every seed; the
    break-even is the worst seed's against its rival."""
    classical = [_search("coarse", 3.0, 0.1), _search("fine", 0.4, 1.0)]
    frames = suite_frames([*classical, _surrogate(0, -0.3, 0.5, 10.0), _surrogate(1, 2.0, 0.6, 12.0)])
    (row,) = cct_headline(frames).to_dict("records")
    assert row["fastest classical within 1 ms"] == "fine [default]" and row["seeds"] == 2
    # seed 0 (within the bracket): rival "fine", 1.0 / 0.5 = 2x, PINN faster; seed 1 (2 ms off): rival
    # "fine" again (0.4 ms), 1.0 / 0.6 = 1.7x, PINN faster: every seed, so the PINN wins
    assert row["verdict"] == "PINN faster (PINN faster on 2 of 2)"
    assert row["PINN CCT error (ms)"] == "2" and row["training (s)"] == "12"
    n_star = 12.0 / (1.0e-3 - 0.6e-3)  # the slowest seed (0.6 ms) against its rival
    assert float(row["break-even N* (CCT searches)"]) == pytest.approx(n_star, rel=1e-2)
    # a seed 6 ms off is a loss; one at 1.1x with overlapping quartiles a tie: the headline a tie
    frames = suite_frames([*classical, _surrogate(0, 6.0, 0.1, 1.0), _surrogate(1, 0.2, 0.9, 1.0, spread=0.2)])
    (row,) = cct_headline(frames).to_dict("records")
    assert row["verdict"] == "tie (classical faster on 1 of 2, tie on 1 of 2)"
    # a surrogate whose every seed is more accurate than any search but "coarse" and "fine" is faster
    frames = suite_frames([*classical, _surrogate(0, 0.1, 5.0, 1.0)])
    (row,) = cct_headline(frames).to_dict("records")
    assert row["verdict"] == "classical faster (classical faster on 1 of 1)"
    assert row["break-even N* (CCT searches)"] == "never"


def test_a_search_left_wide_by_refusals_is_no_rival_and_a_loss_and_shows_its_note():
    """A bracket wider than 1 ms has no error to match, however close its midpoint: a classical one
    is no rival, a surrogate's seed loses, and the cells give the error with the note; the table
    counts the refusals."""
    note = "2 refused t_c in the bracket (0.205 to 0.215 s): left at 20 ms"
    wide = {"stable_s": 0.19, "unstable_s": 0.21, "note": note, "refused": 3}
    classical = [_search("coarse", 3.0, 0.1), _search("fine", 0.4, 1.0), _search("wide", 0.2, 0.01, **wide)]
    frames = suite_frames([*classical, _surrogate(0, -0.3, 0.5, 10.0)])
    (row,) = cct_headline(frames).to_dict("records")
    assert row["fastest classical within 1 ms"] == "fine [default]"
    assert row["verdict"] == "PINN faster (PINN faster on 1 of 1)"
    assert f"wide 0.2; {note}" in row["each classical adapter: CCT error / time to CCT (ms)"]
    table = cct_table(frames)
    assert table.loc[table["solver"] == "wide [default]", "refused"].tolist() == [3]
    seed = {**_surrogate(0, 0.1, 0.01, 10.0), **wide}
    (row,) = cct_headline(suite_frames([*classical, seed])).to_dict("records")
    assert row["verdict"].startswith("classical faster") and row["PINN CCT error (ms)"] == f"0.1; {note}"


def test_a_verdict_pinn_searches_with_each_verdict_seed(monkeypatch):
    """The cct suite measures every seed of `verdict_seeds` of a verdict PINN (a row each, with its
    training), and one model of any other adapter."""
    monkeypatch.setitem(SOLVERS, ShiftedSurrogate.name, ShiftedSurrogate)
    case = CASES[CASE]
    settings = replace(SETTINGS, verdict_pinns=((ShiftedSurrogate.name, ("default",), ()),), verdict_seeds=(0, 1))
    unit = _fitted(ShiftedSurrogate, case)
    rows = cct(unit, case, settings)
    assert [row["pinn_seed"] for row in rows] == [0, 1]
    assert [row["cct_error_s"] for row in rows] == pytest.approx([SHIFT_S, SHIFT_S], abs=BRACKET_S / 2)
    assert rows[0]["seed_fit_s"] == unit.fit_report.seconds  # the unit's own seed: its fit's cost
    assert 0.0 <= rows[1]["seed_fit_s"] < 1.0  # seed 1 trained here
    assert "traj_pred" in rows[0] and "traj_pred" not in rows[1]
    assert len(cct(_fitted(ShiftedSurrogate, case), case, SETTINGS)) == 1


@pytest.mark.slow
def test_accuracy_on_a_fault_case_also_covers_the_stable_clearing_times_alone():
    """On a fault case the accuracy suite adds the angles from the centre of inertia and the speeds
    over the grid's clearing times below the reference CCT: the reference itself has no error there."""
    case = CASES[CASE]
    rows = accuracy(_fitted(ReferenceFaults, case), case, SETTINGS)
    stable = [row for row in rows if row["against"] == STABLE_CLEARING]
    assert [row["quantity"] for row in stable] == [COI_DELTA, "omega"]
    assert all(row["rel_l2"] == 0.0 for row in stable)
    unstable = [row for row in rows if row["against"] == UNSTABLE_CLEARING]
    assert [row["quantity"] for row in unstable] == [COI_DELTA, "omega"]
    assert all(row["rel_l2"] == 0.0 for row in unstable)
    (classes,) = [row for row in rows if row["against"] == STABILITY_CLASSES]
    assert classes["classified_correct"] == 1.0 and classes["misclassified"] == 0 and classes["clearing_times"] == 100


def test_accuracy_counts_the_clearing_times_a_surrogate_puts_on_the_wrong_side_of_the_cct():
    """The surrogate's CCT lies SHIFT_S after the reference's: the grid's clearing times between the
    two are unstable by the reference and stable by it."""
    case = CASES["wscc9-bus8-line8-9"]
    P1 = standard_grid(case)[1]
    classes = stability_classes(_fitted(ShiftedSurrogate, case), case, P1, P1 < reference_cct(case))
    between = P1[(P1 >= reference_cct(case)) & (P1 <= reference_cct(case) + SHIFT_S)]
    assert between.size == 1 and classes["misclassified"] == 1
    assert classes["classified_correct"] == 0.99 and classes["misclassified_t_c"] == f"{between[0]:.6g}"


def test_a_refused_grid_is_asked_one_clearing_time_at_a_time_and_the_refused_ones_are_nan():
    """`answers`: the surrogate refuses every call holding a clearing time in (t*, t* + 25 ms]; the
    grid's other clearing times get the trajectories the unrefusing surrogate gives them."""
    case = CASES[CASE]
    t, P1 = standard_grid(case)
    t_star = reference_cct(case) + SHIFT_S
    refused = (P1 > t_star) & (P1 <= t_star + RefusingSurrogate.REFUSED[1])
    got = answers(_fitted(RefusingSurrogate, case), t, P1)
    assert refused.sum() > 1 and (got.answered == ~refused).all() and len(got.refusals) == refused.sum()
    assert got.refusals[0].startswith(f"{RefusingSurrogate.name}: refused t_c in")
    whole = _fitted(ShiftedSurrogate, case).solve(t, P1)
    np.testing.assert_array_equal(got.delta[~refused], whole.delta[~refused])
    np.testing.assert_array_equal(got.omega[~refused], whole.omega[~refused])
    assert np.isnan(got.delta[refused]).all() and np.isnan(got.omega[refused]).all()
    assert answers(_fitted(ShiftedSurrogate, case), t, P1).answered.all()


def test_the_stability_classes_count_a_refused_clearing_time_on_neither_side():
    """Refused clearing times (past t*, where the reference is unstable) are not classified
    correctly and not misclassified: the row counts and lists them apart."""
    case = CASES[CASE]
    P1 = standard_grid(case)[1]
    t_star = reference_cct(case) + SHIFT_S
    refused = (P1 > t_star) & (P1 <= t_star + RefusingSurrogate.REFUSED[1])
    wrong = (P1 >= reference_cct(case)) & (P1 <= t_star)
    classes = stability_classes(_fitted(RefusingSurrogate, case), case, P1, P1 < reference_cct(case))
    assert (classes["refused"], classes["misclassified"]) == (refused.sum(), wrong.sum())
    assert classes["refused_t_c"] == " ".join(f"{x:.6g}" for x in P1[refused])
    assert classes["classified_correct"] == pytest.approx(1.0 - (refused.sum() + wrong.sum()) / P1.size)


@pytest.mark.slow
def test_accuracy_on_a_fault_case_measures_the_answered_clearing_times_and_says_how_many():
    """A fault case's errors are over the clearing times the adapter answered, and every error row
    and the report's accuracy table say how many of how many; an adapter that refuses every clearing
    time fails the unit with the first refusal."""
    case = CASES[CASE]
    t, P1 = standard_grid(case)
    t_star = reference_cct(case) + SHIFT_S
    refused = (P1 > t_star) & (P1 <= t_star + RefusingSurrogate.REFUSED[1])
    rows = accuracy(_fitted(RefusingSurrogate, case), case, SETTINGS)
    (grid,) = [row for row in rows if row["quantity"] == COI_DELTA and row["against"] == "reference"]
    assert (grid["trajectories"], grid["answered"]) == (P1.size, P1.size - refused.sum())
    assert grid["first_refusal"].startswith(f"{RefusingSurrogate.name}: refused")
    whole = {(row["quantity"], row["against"]): row for row in accuracy(_fitted(ShiftedSurrogate, case), case, SETTINGS)}
    (stable,) = [row for row in rows if row["quantity"] == COI_DELTA and row["against"] == STABLE_CLEARING]
    assert stable["answered"] == stable["trajectories"] == (P1 < reference_cct(case)).sum()
    assert stable["rel_l2"] == whole[COI_DELTA, STABLE_CLEARING]["rel_l2"]  # nothing refused there
    (unstable,) = [row for row in rows if row["quantity"] == "omega" and row["against"] == UNSTABLE_CLEARING]
    assert unstable["answered"] == unstable["trajectories"] - refused.sum()
    ref = reference(case, t, P1[~refused & (P1 >= reference_cct(case))])[1]
    assert unstable["max_abs"] == pytest.approx(np.abs(ref).max())  # the surrogate's speeds are 0
    base = {"suite": "accuracy", "case": CASE, "solver": RefusingSurrogate.name, "config": "default", "variant": "",
            "seed": 0, "threads": 1, "status": "ok"}
    ((_, frames),) = case_sections(suite_frames([{**base, **row} for row in rows]))
    *_, table = build_tables(frames)["accuracy"]
    assert table[f"{COI_DELTA} rel. L2"].iloc[0].endswith(f"({P1.size - refused.sum()} of {P1.size} answered)")

    class RefusesAll(RefusingSurrogate):
        REFUSED = (-1.0, 1.0)

    with pytest.raises(SolveError, match=f"refused every clearing time of {CASE}'s grid; the first: "):
        accuracy(_fitted(RefusesAll, case), case, SETTINGS)


def test_the_summary_counts_the_cases_a_pinn_finds_the_cct_on_and_its_time_against_the_classical_search():
    """One bullet per PINN configuration over its fault cases: found (with how far, and where
    refusals left the bracket wide), none (named), the fastest classical search within 1 ms over
    the PINN's slowest seed, and the break-even; nothing without a surrogate."""
    other = "wscc9-bus8-line8-9"
    classical = [_search("fine", 0.4, 1.0), {**_search("fine", 0.1, 2.0), "case": other}]
    wide = {"stable_s": 0.19, "unstable_s": 0.21, "note": "1 refused t_c in the bracket (at 0.2 s): left at 20 ms"}
    none = {"cct_s": float("nan"), "cct_error_s": float("nan"), "note": "no clearing time judged unstable"}
    pinns = [_surrogate(0, -0.3, 500.0, 10.0), _surrogate(1, 0.2, 400.0, 10.0),
             {**_surrogate(0, 2.0, 1000.0, 10.0), "case": other, **wide}]
    text = cct_summary(suite_frames([*classical, *pinns]))
    assert text == ("- **CCT of 2 fault cases**, `pinn fault`: found on 2, 0.3 ms to 2 ms from the reference (refusals "
                    "left the bracket wider than 1 ms on 1); its search 0.5 s to 1 s, the fastest classical search "
                    "within 1 ms 0.002x to 0.002x as long; break-even never on 1 of 2.\n")
    text = cct_summary(suite_frames([*classical, {**pinns[2], **none}]))
    assert "found on 0; none on 1 (wscc9-bus8-line8-9)" in text
    assert cct_summary(suite_frames(classical)) == ""
