"""trapezoid: second order against the reference (the SMIB and wscc9), agreement with numba-rk at a
small step, points and the parallel kernel against solve, Newton's failure, option checks, and
identification of the SMIB's m and d."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import check_points_as_solves

from harness.measure import metrics
from harness.settings import DEFAULT
from solvers import make_solver
from solvers.base import SolveError
from solvers.classical.trapezoid import HALF_CYCLE, STEPS
from systems.cases import CASES, SMIB_IDENTIFICATION, SMIB_INFERENCE, Observations, standard_grid
from systems.model import relative_angles
from systems.reference import reference

pytest.importorskip("numba")

WSCC9 = CASES["wscc9"]


def _fitted(case=SMIB_INFERENCE, **options):
    solver = make_solver("trapezoid", case, **options)
    solver.fit()
    return solver


@pytest.mark.parametrize(("case", "steps"), [(SMIB_INFERENCE, (0.04, 0.02, 0.01)), (WSCC9, (0.02, 0.01, 0.005))],
                         ids=["smib", "wscc9"])
def test_second_order(case, steps):
    """The largest angle error against the reference falls 4x each time dt halves, and the speeds'
    with it; Newton's tolerance is far below the truncation error."""
    t, P1 = standard_grid(case, n_p1=3, n_t=41)
    ref_delta, ref_omega = reference(case, t, P1)
    runs = [_fitted(case, dt=dt).solve(t, P1) for dt in steps]
    for key, ref in (("delta", ref_delta), ("omega", ref_omega)):
        errors = [metrics.max_abs(getattr(traj, key), ref) for traj in runs]
        for coarse, fine in itertools.pairwise(errors):
            assert 3.6 < coarse / fine < 4.4, (key, errors)


def test_small_step_agrees_with_numba_rk_tight():
    """At dt = 0.25 ms wscc9's centre-of-inertia angles and speeds agree with numba-rk's DOP853 at
    rtol 1e-10 (and so with the reference) to the trapezoid's truncation error."""
    t, P1 = standard_grid(WSCC9, n_p1=2, n_t=21)
    ours = _fitted(WSCC9, dt=2.5e-4).solve(t, P1)
    rk = make_solver("numba-rk", WSCC9, "tight")
    rk.fit()
    theirs = rk.solve(t, P1)
    assert metrics.rel_l2(relative_angles(WSCC9, ours.delta), relative_angles(WSCC9, theirs.delta)) < 1e-6
    assert metrics.rel_l2(ours.omega, theirs.omega) < 1e-6


@pytest.mark.parametrize("parallel", [False, True])
def test_points_and_parallel_have_the_bits_of_solve(parallel):
    """Pairs of distinct P1 have the bits of one-point solves, pairs sharing P1 those of one solve of
    that P1 at its pairs' times; the parallel kernel gives the serial one's bits."""
    solver = _fitted(WSCC9, parallel=parallel)
    check_points_as_solves(solver)
    t, P1 = np.array([7.5, 0.0, 2.0, 7.5]), np.linspace(WSCC9.p1_min, WSCC9.p1_max, 3)
    serial = _fitted(WSCC9).solve(t, P1)
    traj = solver.solve(t, P1)
    assert traj.delta.shape == (3, 4, WSCC9.n)
    np.testing.assert_array_equal(traj.delta, serial.delta)
    np.testing.assert_array_equal(traj.omega, serial.omega)


def test_newton_failure_and_overflow_raise_solve_error():
    """A step that needs more Newton iterations than max_newton fails, naming P1 and the step."""
    solver = _fitted(max_newton=1)
    with pytest.raises(SolveError, match=r"trapezoid: integration failed at P1=0\.13: Newton did not converge "
                                         r".*\(step from t=0 s\)"):
        solver.solve([1.0, 20.0], [0.13])
    with pytest.raises(SolveError, match=r"at P1=0\.15: Newton did not converge"):
        solver.solve_points(np.array([0.0, 20.0, 0.5]), np.array([0.1, 0.15, 0.15]))
    assert solver.stats.shape == (2, 4) and solver.stats[1, 1] == 1  # one iteration, then the error
    with pytest.raises(SolveError, match=r"failed at P1=1e\+308"), np.errstate(all="ignore"):
        _fitted().solve([1.0, 20.0], [0.1, 1e308])


@pytest.mark.parametrize(("option", "value"), [
    ("dt", 25.0), ("dt", 0.0), ("dt", -HALF_CYCLE), ("dt", float("nan")), ("newton_tol", 0.0),
    ("newton_tol", -1e-10), ("max_newton", 0), ("max_newton", 2.5), ("threads", 0), ("threads", 10_000),
    ("parallel", 1), ("m_bounds", (0.5, 0.1)),
])
def test_bad_options_raise_a_one_line_value_error(option, value):
    with pytest.raises(ValueError, match=f"^trapezoid: option {option} must be [^\n]*$"):
        make_solver("trapezoid", SMIB_INFERENCE, **{option: value})


def test_half_cycle_by_default_and_a_sweep_of_steps():
    solver = make_solver("trapezoid", SMIB_INFERENCE)
    assert solver.options["dt"] == HALF_CYCLE == 1 / 120
    assert solver.precision_sweep([1e-3] * len(STEPS)) == [{"dt": dt} for dt in STEPS]
    assert solver.precision_sweep([1e-3, 1e-6]) == [{"dt": dt} for dt in STEPS[:2]]  # the coarsest two
    assert STEPS == tuple(sorted(STEPS, reverse=True)) and len(STEPS) <= len(DEFAULT.wp_rtols)


def test_identify_recovers_m_and_d():
    """The SMIB's m and d from noise-free reference angles (3 P1 x 40 times), within the trapezoid's
    truncation error, and inside their 95 % intervals, which count that error (Richardson)."""
    case = SMIB_IDENTIFICATION
    t, P1 = np.meshgrid(np.linspace(0.5, case.t_final, 40), [0.1, 0.14, 0.18])
    delta, _ = reference(case, t[0], P1[:, 0])
    obs = Observations(t.ravel(), P1.ravel(), delta.reshape(-1, 1))
    est = make_solver("trapezoid", case).identify(obs)
    assert est.success, est.message
    assert metrics.rel_error(est.m[0], case.m[0]) < 1e-3
    assert metrics.rel_error(est.d[0], case.d[0]) < 1e-3
    assert est.m_ci95[0, 0] < case.m[0] < est.m_ci95[0, 1]
    assert est.d_ci95[0, 0] < case.d[0] < est.d_ci95[0, 1]
