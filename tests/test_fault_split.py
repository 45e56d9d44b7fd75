"""The fault PINN split at its own CCT (`PinnConfig.split`, `solvers.pinn.split`): the pieces of
clearing times either side of the estimate, a query's route to its side, the same model from the
same seed, one-line errors for bad options. Tiny budgets: the machinery, not the accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from solvers import SOLVERS, make_solver
from solvers.pinn import split
from systems.cases import CASES

pytestmark = pytest.mark.skipif(SOLVERS["jax-pinn"] is None, reason="jax-pinn is not installed")

CASE = CASES["wscc9-bus8-line8-9"]
# 1 fault-on and 2 post-fault windows a chain, one piece a side: 5 windows of 2 LM iterations
TINY = {"max_iterations": 2, "max_seconds": None, "n_f": 20, "window": 1.5, "pieces": 1, "screen_n_f": 10,
        "screen_iterations": 2, "screen_tol": 0.05, "threads": 1}


def test_split_pieces_are_graded_towards_the_estimate_on_both_sides():
    edges = split.split_pieces(CASE, 0.18, 3, 2.0)
    assert edges[0] == CASE.p1_min and edges[3] == 0.18 and edges[-1] == CASE.p1_max
    widths = np.diff(edges)
    assert (widths[:3] > 0).all() and (np.diff(widths[:3]) < 0).all()  # narrower towards the estimate
    assert (widths[3:] > 0).all() and (np.diff(widths[3:]) > 0).all()
    np.testing.assert_allclose(split.split_pieces(CASE, float("nan"), 2, 2.0), np.linspace(0.05, 0.40, 5))


@pytest.mark.slow
def test_a_split_model_routes_each_clearing_time_to_its_side(monkeypatch):
    # the screen's estimate fixed, so that the test does not hang on what tiny budgets train
    monkeypatch.setattr(split, "screen_cct", lambda *args: split.Screen(0.17, 0.172, 1, 1, 1, 0.0))
    solver = make_solver("jax-pinn", CASE, "fault-split", **TINY)
    report = solver.fit()
    assert solver.split_s == pytest.approx(0.171) and "CCT estimate 0.171000 s" in report.message
    t = np.linspace(0.0, 3.0, 31)
    t_c = np.array([0.06, 0.1705, 0.171, 0.1715, 0.39])
    before = solver.solve(t, t_c).delta
    theta = solver.theta.copy()
    theta[1 + 2:] += 0.01  # the unstable side's post-fault windows (after 1 fault-on, 2 stable-side)
    solver._set_model(solver.arch, theta)
    after = solver.solve(t, t_c).delta
    changed = np.abs(after - before).max(axis=(1, 2)) > 0
    assert changed.tolist() == [False, False, True, True, True]  # t_c >= split_s: the unstable side
    np.testing.assert_array_equal(after[:, t < 0.06], before[:, t < 0.06])  # the fault-on chain is shared


@pytest.mark.slow
def test_the_same_seed_gives_the_same_split_model():
    first, second = (make_solver("jax-pinn", CASE, "fault-split", **TINY) for _ in range(2))
    messages = [solver.fit().message for solver in (first, second)]
    assert "screen of" in messages[0]
    np.testing.assert_array_equal(first.theta, second.theta)
    np.testing.assert_array_equal(first.windows.pieces, second.windows.pieces)


@pytest.mark.parametrize(("config", "options", "words"), [
    ("marching", {"split": True}, "option split"),
    ("fault-marching", {"unstable_scale": 10.0}, "option unstable_scale"),
    ("fault-marching", {"near_weight": 4.0}, "option near_weight"),
    ("fault-split", {"split_grading": 0.0}, "split_grading"),
    ("fault-split", {"screen_tol": -1.0}, "screen_tol"),
])
def test_bad_split_options_get_a_one_line_error(config, options, words):
    case = CASE if config != "marching" else CASES["wscc9"]
    with pytest.raises(ValueError) as error:
        make_solver("jax-pinn", case, config, **options)
    assert words in str(error.value) and "\n" not in str(error.value)


def test_a_split_config_on_a_step_case_and_an_estimate_outside_the_range_are_refused():
    with pytest.raises(ValueError, match="option phases must be False") as error:
        make_solver("jax-pinn", CASES["wscc9"], "fault-split")
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="outside the clearing times"):
        split.split_pieces(CASE, 0.45, 2, 1.0)
