"""pod-spline, the reduced-order surrogate (`solvers.classical.pod_spline`): accurate against the reference
away from its nodes and knots, exact at them, deterministic, and every bad input refused in one
line naming it. (The contract tests run it with every other adapter.)"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import per_group, per_pair, points_queries

from harness.measure import metrics
from solvers import make_solver
from solvers.classical.numba_rk import NumbaRK
from solvers.classical.pod_spline import ATOL_PER_RTOL
from systems.cases import CASES, SMIB_INFERENCE, standard_grid
from systems.model import relative_angles
from systems.reference import reference


@pytest.fixture(scope="module")
def wscc9():
    pytest.importorskip("pandapower")
    return CASES["wscc9"]


@pytest.fixture(scope="module")
def fitted(wscc9):
    solver = make_solver("pod-spline", wscc9)
    solver.fit()
    return solver


def _errors(solver, t: np.ndarray, P1: np.ndarray) -> tuple[float, float]:
    """rel. L2 of the angles (relative to the centre of inertia without an infinite bus, as the
    accuracy suite measures them) and of the speeds against the reference."""
    case = solver.case
    traj, (delta, omega) = solver.solve(t, P1), reference(case, t, P1)
    return (metrics.rel_l2(relative_angles(case, traj.delta), relative_angles(case, delta)),
            metrics.rel_l2(traj.omega, omega))


# Measured with the default options (17 snapshots, 2000 knots, rtol 1e-10) on every tenth P1 of
# the standard grid (none a node) at its 201 times (none a knot but 0 and t_final): wscc9 2.5e-10
# (COI) and 4.2e-10 (omega), at numba-rk's rtol; the SMIB 9.8e-7 and 2.2e-6, the polynomial in P1
# (its range ends near P1 = b = 0.2, where the equilibrium is lost).
@pytest.mark.parametrize(("name", "bound"), [("wscc9", 1e-8), ("smib-inference", 1e-5)])
def test_accurate_on_the_standard_grid_away_from_its_nodes_and_knots(wscc9, fitted, name, bound):
    solver = fitted if name == "wscc9" else make_solver("pod-spline", SMIB_INFERENCE)
    if not solver.fitted:
        solver.fit()
    t, P1 = standard_grid(solver.case)
    assert max(_errors(solver, t, P1[5::10])) < bound


def test_exact_at_the_snapshots_nodes_and_knots(wscc9, fitted):
    """With every mode kept (3 machines, 3 modes), the interpolant at a node and a knot is the
    trajectory it was fitted to (numba-rk's output at every knot: its steps may depend on the output
    times), up to rounding."""
    options = fitted.options
    rk = NumbaRK(wscc9, rtol=options["rtol"], atol=options["rtol"] * ATOL_PER_RTOL)
    rk.fit()
    knots = np.linspace(0.0, wscc9.t_final, options["n_times"])
    snap = rk.solve(knots, fitted._nodes)
    traj = fitted.solve(knots[::97], fitted._nodes)
    np.testing.assert_allclose(traj.delta, snap.delta[:, ::97], rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.omega, snap.omega[:, ::97], rtol=0, atol=1e-12)


def test_points_answer_as_solves_do(wscc9, fitted):
    """To rounding: another kernel, the same sums in another order (so t = 0 gives delta0 to
    rounding too, not to the bit as an integrator's points do)."""
    for pattern, expect in (("distinct", per_pair), ("shared", per_group)):
        t, P1 = points_queries(wscc9)[pattern]
        points, (delta, omega) = fitted.solve_points(t, P1), expect(fitted, t, P1)
        assert points.delta.shape == points.omega.shape == (t.size, wscc9.n)
        np.testing.assert_allclose(points.delta, delta, rtol=0, atol=1e-13)
        np.testing.assert_allclose(points.omega, omega, rtol=0, atol=1e-13)
        np.testing.assert_allclose(points.delta[t == 0.0], np.broadcast_to(wscc9.delta0, (1, wscc9.n)), atol=1e-14)


def test_two_fits_give_the_same_model(wscc9, fitted):
    again = make_solver("pod-spline", wscc9, seed=1)  # the seed changes nothing: no randomness
    again.fit()
    for mine, theirs in ((fitted._delta, again._delta), (fitted._omega, again._omega)):
        for a, b in zip(mine, theirs, strict=True):
            np.testing.assert_array_equal(a, b)
    t, P1 = standard_grid(wscc9, n_p1=7, n_t=13)
    np.testing.assert_array_equal(fitted.solve(t, P1).delta, again.solve(t, P1).delta)


def test_the_energy_rule_chooses_k_and_the_report_says_so(wscc9):
    solver = make_solver("pod-spline", wscc9, n_snapshots=5, n_times=200, energy=0.999)
    report = solver.fit()
    kept = solver._delta.basis_t.shape[0]
    assert 1 <= kept < wscc9.n
    assert f"delta {kept} modes" in report.message and 0.0 < report.loss <= 1e-3
    fixed = make_solver("pod-spline", wscc9, n_snapshots=5, n_times=200, k=2)
    fixed.fit()
    assert fixed._delta.basis_t.shape == fixed._omega.basis_t.shape == (2, wscc9.n)


def _one_line(info: pytest.ExceptionInfo) -> str:
    message = str(info.value)
    assert type(info.value) is ValueError and "\n" not in message
    return message


@pytest.mark.parametrize(("options", "expected"), [
    ({"k": 4}, "pod-spline: option k must be <= min(n machines, n_snapshots x n_times) = 3 on case wscc9, got 4"),
    ({"n_snapshots": 1}, "pod-spline: option n_snapshots must be an integer >= 2, got 1"),
    ({"n_times": 1}, "pod-spline: option n_times must be an integer >= 2, got 1"),
    ({"energy": 1.5}, "pod-spline: option energy must be a number in (0, 1], got 1.5"),
])
def test_bad_options_are_refused_in_one_line_naming_them(wscc9, options, expected):
    with pytest.raises(ValueError) as info:
        make_solver("pod-spline", wscc9, **options)
    assert _one_line(info) == expected


def test_a_case_without_a_range_of_p1_is_refused():
    single = dataclasses.replace(SMIB_INFERENCE, p1_max=SMIB_INFERENCE.p1_min)
    with pytest.raises(ValueError) as info:
        make_solver("pod-spline", single)
    assert _one_line(info).startswith("pod-spline: case smib-inference has a single P1 = 0.08 p.u.")


def test_queries_outside_the_fitted_domain_are_refused_unless_asked_for(wscc9, fitted):
    with pytest.raises(ValueError) as info:
        fitted.solve([1.0], wscc9.p1_max + 0.01)
    assert _one_line(info).startswith(f"P1 spans [{wscc9.p1_max + 0.01!r}, {wscc9.p1_max + 0.01!r}] p.u., "
                                      f"outside the trained domain [{wscc9.p1_min}, {wscc9.p1_max}] p.u.")
    with pytest.raises(ValueError) as info:
        fitted.solve_points([wscc9.t_final + 1.0], [wscc9.p1_min])
    assert _one_line(info).startswith(f"t_query reaches {wscc9.t_final + 1.0!r} s, outside the trained domain")
    assert np.isfinite(fitted.solve([wscc9.t_final + 0.1], wscc9.p1_max + 0.01, extrapolate=True).delta).all()


def test_it_does_not_identify(fitted):
    with pytest.raises(NotImplementedError, match="pod-spline does not identify"):
        fitted._identify(None)


def test_its_precision_sweep_is_a_sweep_of_the_snapshots(fitted):
    assert fitted.precision_sweep((1e-3, 1e-6, 1e-9)) == [{"n_snapshots": 5}, {"n_snapshots": 9},
                                                          {"n_snapshots": 17}]
