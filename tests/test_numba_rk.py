"""numba-rk: accuracy of each method against the reference and a closed form, RK4's order, the
sensitivities, identification, option checks and failures."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from harness import metrics
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, standard_grid
from systems.reference import reference
from harness.suites.identification import observations
from solvers import make_solver
from solvers import numba_kernels as kernels
from solvers.base import SolveError

pytest.importorskip("numba")

TIGHT = {"dop853": {}, "dopri5": {"method": "dopri5"}, "rk4": {"method": "rk4", "dt": 0.002}}


def _fitted(config: str = "default", case=SMIB_INFERENCE, **options):
    solver = make_solver("numba-rk", case, config, **options)
    solver.fit()
    return solver


@pytest.mark.parametrize("method", TIGHT)
def test_tight_matches_reference(method):
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=12)
    traj = _fitted("tight", **TIGHT[method]).solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    assert metrics.rel_l2(traj.delta, ref_delta) <= 1e-9
    assert metrics.rel_l2(traj.omega, ref_omega) <= 1e-9


@pytest.mark.parametrize("method", TIGHT)
def test_linear_case_matches_closed_form(method):
    case = dataclasses.replace(SMIB_INFERENCE, b=0.0)
    m, d, delta0, omega0 = case.m, case.d, case.delta0, case.omega0
    t, P1 = np.array([7.3, 0.0, 20.0, 2.5]), np.array([0.08, 0.18])
    traj = _fitted("tight", case=case, **TIGHT[method]).solve(t, P1)
    v = P1[:, None] / d
    decay = np.exp(-d * t / m)
    np.testing.assert_allclose(traj.delta, delta0 + v * t + (omega0 - v) * (m / d) * (1 - decay),
                               rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(traj.omega, v + (omega0 - v) * decay, rtol=1e-9, atol=1e-11)


def test_rk4_is_fourth_order():
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=3, n_t=41)
    ref = reference(SMIB_INFERENCE, t, P1)[0]
    errors = [metrics.max_abs(_fitted("rk4", dt=dt).solve(t, P1).delta, ref) for dt in (0.2, 0.1, 0.05)]
    for coarse, fine in itertools.pairwise(errors):
        assert 12.0 < coarse / fine < 20.0


def test_precision_sweep():
    assert _fitted("rk4").precision_sweep([1e-3]) == [{"dt": dt} for dt in (0.2, 0.1, 0.05, 0.02, 0.01,
                                                                             0.005, 0.002, 0.001)]
    assert make_solver("numba-rk", SMIB_INFERENCE).precision_sweep([1e-4]) == [{"rtol": 1e-4, "atol": 1e-4 * 1e-3}]


@pytest.mark.parametrize("method", TIGHT)
def test_sensitivities_equal_finite_differences(method):
    solver = _fitted("tight", **TIGHT[method])
    t, P1 = np.linspace(0.0, 20.0, 9), np.array([0.1, 0.17])
    run = solver._sensitivities

    def states(m, d):
        system = solver._system.copy()
        system[0, :2] = m, d
        out, failed, _ = run(t, P1[:, None], system, solver._options)
        assert failed == -1
        return out

    m, d = 0.3, 0.12
    base = states(m, d)
    for row, (dm, dd) in ((2, (1e-6, 0.0)), (4, (0.0, 1e-6))):
        fd = (states(m + dm, d + dd)[:2] - states(m - dm, d - dd)[:2]) / (2e-6)
        np.testing.assert_allclose(base[row:row + 2], fd, rtol=1e-5, atol=1e-5)


def test_identify_recovers_m_and_d():
    obs = observations(SMIB_IDENTIFICATION.with_params(0.25, 0.15), 100, 0.0, seed=1000)
    est = make_solver("numba-rk", SMIB_INFERENCE, "tight").identify(obs)
    assert est.success, est.message
    assert metrics.rel_error(est.m, 0.25) < 1e-4
    assert metrics.rel_error(est.d, 0.15) < 1e-4


def test_repeated_and_shuffled_times_and_parallel():
    t = np.array([12.0, 0.5, 7.25, 12.0, 0.0, 3.0])
    P1 = np.linspace(0.08, 0.18, 5)
    solver = _fitted("tight")
    serial = solver.solve(t, P1)
    parallel = kernels.kernel(kernels.DOP853, False, True)  # the kernel of parallel=True (compiles ~5 s)
    states, failed, _ = parallel(t, P1[:, None], solver._system, solver._options)
    assert failed == -1
    np.testing.assert_array_equal(serial.delta, states[0])
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    np.testing.assert_allclose(serial.delta, ref_delta, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(serial.omega, ref_omega, rtol=1e-9, atol=1e-11)


BAD_OPTIONS = [
    ("rtol", 0.0), ("rtol", -1e-3), ("rtol", float("nan")), ("rtol", True), ("rtol", "1e-3"),
    ("atol", float("inf")), ("atol", None), ("dt", 0.0), ("dt", 25.0), ("dt", False),
    ("method", "euler"), ("max_steps", 0), ("max_steps", 1.5), ("threads", 0), ("threads", 10_000),
    ("parallel", 1), ("m_bounds", (0.5, 0.1)), ("m_bounds", (0.0, 1.0)), ("d_bounds", (0.1,)),
    ("d_bounds", (0.1, float("inf"))), ("d_bounds", "ab"),
]


@pytest.mark.parametrize("option,value", BAD_OPTIONS)
def test_bad_options_raise_value_error_naming_the_option(option, value):
    with pytest.raises(ValueError, match=f"option {option}"):
        make_solver("numba-rk", SMIB_INFERENCE, **{option: value})


@pytest.mark.parametrize("method", TIGHT)
def test_too_few_steps_raises_solve_error_naming_p1(method):
    solver = _fitted(method=method, max_steps=5)
    with pytest.raises(SolveError, match=r"numba-rk: integration failed at P1=0\.13: more than max_steps"):
        solver.solve([1.0, 20.0], [0.13])
    with pytest.raises(SolveError, match=r"at P1=0\.15"):
        solver.solve([20.0], [0.15, 0.1])


def test_overflow_raises_solve_error():
    with pytest.raises(SolveError, match=r"failed at P1=1e\+308"), np.errstate(all="ignore"):
        _fitted().solve([1.0, 20.0], [0.1, 1e308])
