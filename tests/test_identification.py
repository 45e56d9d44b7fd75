"""Identification that says when it does not know: the rules of `solvers.identification` and the
uncertainty every adapter reports, on data that cannot support an estimate and on data that can."""

from __future__ import annotations

import numpy as np
import pytest

from harness.suites.identification import observations
from solvers import make_solver
from solvers.identification import (
    MAX_CONDITION,
    Estimate,
    assess,
    gauss_newton_covariance,
    linearised_covariance,
)
from systems.cases import SMIB_IDENTIFICATION, Observations

CASE = SMIB_IDENTIFICATION
# casadi-cvodes at "tight" takes 15-30 s an identification of 100 samples on a busy 2-core machine:
# it only meets one repeated sample here
FAST = ("numba-rk", "scipy-odeint")
_FITTED: dict = {}


def _solver(name: str):
    pytest.importorskip({"numba-rk": "numba", "casadi-cvodes": "casadi"}.get(name, "scipy"))
    if name not in _FITTED:
        _FITTED[name] = make_solver(name, CASE, "tight")
        _FITTED[name].fit()
    return _FITTED[name]


@pytest.fixture(scope="module")
def good():
    return observations(CASE, 100)


def _noisy(obs: Observations, noise: float, seed: int) -> Observations:
    """The same points, delta times (1 + noise N(0, 1)): the suite's relative noise."""
    rng = np.random.default_rng(seed)
    return Observations(obs.t, obs.P1, obs.delta * (1.0 + noise * rng.standard_normal(obs.delta.shape)))


def _inside(ci: np.ndarray, value: tuple[float, ...]) -> bool:
    """Whether every machine's value lies in its interval (rows (low, high))."""
    return bool(np.all((ci[:, 0] <= value) & (value <= ci[:, 1])))


# ---- data that cannot support an estimate --------------------------------------------------------


@pytest.mark.parametrize("name", [*FAST, "casadi-cvodes"])
def test_repeated_sample_fails(name, good):
    obs = Observations(np.full(20, good.t[0]), np.full(20, good.P1[0]), np.full((20, 1), good.delta[0, 0]))
    est = _solver(name).identify(obs)
    assert not est.success and "distinct samples" in est.message


def test_three_samples_fail(good):
    """The rule: at least 5 distinct (t, P1) samples (3 residual degrees of freedom)."""
    est = _solver("numba-rk").identify(Observations(good.t[:3], good.P1[:3], good.delta[:3]))
    assert not est.success and "distinct samples" in est.message


def test_pure_noise_fails(good):
    rng = np.random.default_rng(0)
    est = _solver("numba-rk").identify(Observations(good.t, good.P1, rng.normal(0.7, 0.3, (len(good), 1))))
    assert not est.success
    assert any(word in est.message for word in ("bound", "ill-conditioned", "wider than the estimate"))


def test_data_from_outside_the_box_fails_on_its_bound():
    est = _solver("numba-rk").identify(observations(CASE.with_params(5.0, 0.15), 100))
    assert not est.success and "upper bound" in est.message and est.m[0] == pytest.approx(2.0)


# ---- data that can -----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", FAST)
def test_good_data_interval_contains_the_truth_and_widens_with_noise(name, good):
    solver = _solver(name)
    clean = solver.identify(good)
    noisy = solver.identify(_noisy(good, 0.01, seed=1))
    for est in (clean, noisy):
        assert est.success, est.message
        assert _inside(est.m_ci95, CASE.m) and _inside(est.d_ci95, CASE.d)
        assert np.isfinite([est.m_se, est.d_se]).all() and (est.m_se > 0).all() and (est.d_se > 0).all()
    width = lambda ci: ci[0, 1] - ci[0, 0]
    assert width(noisy.m_ci95) > width(clean.m_ci95) and width(noisy.d_ci95) > width(clean.d_ci95)


def test_standard_errors_match_a_monte_carlo_spread(good):
    solver = _solver("numba-rk")
    runs = [solver.identify(_noisy(good, 0.01, seed)) for seed in range(8)]
    spread = np.std([[r.m[0], r.d[0]] for r in runs], axis=0, ddof=1)
    se = np.mean([[r.m_se[0], r.d_se[0]] for r in runs], axis=0)
    assert np.all(se / spread < 2.0) and np.all(spread / se < 2.0), (se, spread)


# ---- the rules, on their own ----------------------------------------------------------------------------


def test_gauss_newton_covariance_is_the_linear_regression_one():
    rng = np.random.default_rng(0)
    x = np.linspace(0.0, 1.0, 30)
    y = 2.0 * x + 1.0 + 0.1 * rng.standard_normal(30)
    coef, expected = np.polyfit(x, y, 1, cov=True)
    J = np.stack([x, np.ones_like(x)], axis=1)
    cov, dof, condition = gauss_newton_covariance(J, J @ coef - y)
    np.testing.assert_allclose(cov, expected, rtol=1e-10)
    assert dof == 28 and condition == pytest.approx(np.linalg.cond(J.T @ J))


def _slope_problem(x: np.ndarray, y: np.ndarray, degree: int, weight: float):
    """A PINN in miniature, linear: a polynomial u(x) = sum_j w_j x^j (the network, degree + 1
    weights) fitted to data y, and the "physics" u'(x_f) = c on 40 collocation points (weight
    `weight`) with the slope c the last parameter. Returns J (rows: data, then physics) and the
    least-squares solution theta."""
    x_f = np.linspace(0.0, 1.0, 40)
    powers = np.arange(degree + 1)
    data = np.hstack([x[:, None] ** powers, np.zeros((x.size, 1))])
    slope = powers * np.where(powers > 0, x_f[:, None] ** np.maximum(powers - 1, 0), 0.0)
    physics = weight * np.hstack([slope, -np.ones((x_f.size, 1))])
    J = np.vstack([data, physics])
    target = np.concatenate([y, np.zeros(x_f.size)])
    theta = np.linalg.lstsq(J, target, rcond=None)[0]
    return J, J @ theta - target, theta


def test_linearised_covariance_of_a_hard_constraint_is_the_regression_one():
    """With the physics enforced (a large weight), u is a line of slope c: the slope's variance is
    the straight-line regression's, (s^2 from the leave-one-out residuals, which a line's small
    leverages leave close to the in-sample ones)."""
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, 1.0, 50)
    y = 0.5 + 2.0 * x + 0.05 * rng.standard_normal(x.size)
    J, r, theta = _slope_problem(x, y, degree=6, weight=1e4)
    cov, dof, _ = linearised_covariance(J, r, x.size, 1, rcond=1e-15)
    (slope, _), expected = np.polyfit(x, y, 1, cov=True)
    assert theta[-1] == pytest.approx(slope, rel=1e-6)
    assert dof == x.size - 1
    assert cov[0, 0] == pytest.approx(expected[0, 0], rel=0.1)


def test_linearised_intervals_of_a_soft_constraint_hold_the_truth_at_least_90_percent():
    """The regime of a PINN: more weights than samples, a soft physics residual, samples nearly
    interpolated (the data's leverages sum to 18 of 24). Over 400 noise draws the 95 % interval of
    the slope holds the true slope at least 90 % of the time (97 % measured)."""
    from scipy.stats import t as student

    rng = np.random.default_rng(2)
    x = np.sort(rng.uniform(0.0, 1.0, 24))
    hits = 0
    for _ in range(400):
        y = 0.5 + 2.0 * x + 0.05 * rng.standard_normal(x.size)
        J, r, theta = _slope_problem(x, y, degree=14, weight=0.05)
        cov, dof, _ = linearised_covariance(J, r, x.size, 1)
        hits += abs(theta[-1] - 2.0) <= student.ppf(0.975, dof) * np.sqrt(cov[0, 0])
    assert hits / 400 >= 0.90


def test_assess_rules():
    cov = np.diag([1e-4, 1e-4])
    fine = Estimate(0.25, 0.15, 5, True, "ok", cov, 98, 3.0, (((0.02, 2.0),), ((0.005, 1.0),)))
    verdict = assess(fine)
    assert verdict.success and verdict.message == "ok"
    assert verdict.m_se[0] == pytest.approx(0.25 * 1e-2)
    low, high = verdict.m_ci95[0]
    assert low < 0.25 < high and np.log(high / 0.25) == pytest.approx(np.log(0.25 / low))  # log-symmetric
    assert not assess(fine._replace(m=2.0 * (1 - 1e-5))).success
    ill = assess(fine._replace(condition=10 * MAX_CONDITION))
    assert not ill.success and "ill-conditioned" in ill.message
    wide = assess(fine._replace(cov_log=np.diag([1.0, 1e-4])))
    assert not wide.success and "wider than the estimate" in wide.message
    assert not assess(fine._replace(d=float("nan"))).success
    huge = assess(fine._replace(cov_log=np.diag([1e6, 1e-4])))  # exp(q se_log) overflows: no interval, no crash
    assert not huge.success and "no finite 95 % interval for m" in huge.message
    assert assess(Estimate(0.25, 0.15, 5, True, "no uncertainty")).success  # NaN fields, no rule applies


def test_assess_judges_every_machine_and_names_the_one_that_fails():
    """Two machines: cov over (log m_1, log m_2, log d_1, log d_2); machine 2's d on its bound."""
    cov = np.diag([1e-4] * 4)
    boxes = (((0.02, 2.0), (0.02, 2.0)), ((0.005, 1.0), (0.005, 1.0)))
    two = Estimate(np.array([0.25, 0.5]), np.array([0.15, 0.3]), 5, True, "ok", cov, 98, 3.0, boxes)
    verdict = assess(two)
    assert verdict.success and verdict.m_ci95.shape == (2, 2) and verdict.d_se.shape == (2,)
    assert verdict.d_se[1] == pytest.approx(0.3 * 1e-2)
    on_bound = assess(two._replace(d=np.array([0.15, 1.0])))
    assert not on_bound.success and "d_2=1 is on the upper bound" in on_bound.message
    wide = assess(two._replace(cov_log=np.diag([1e-4, 1e-4, 1e-4, 1.0])))
    assert not wide.success and "95 % interval of d_2" in wide.message


# ---- PINNs -------------------------------------------------------------------------------------------------

PINN_SMALL = {"threads": 1, "id_hidden_layers": 2, "id_width": 8, "id_n_f": 100, "id_max_iterations": 5}


def test_pinn_reports_its_uncertainty_and_refuses_one_repeated_sample(good):
    """Five iterations leave the network far from the data: the interval says so (it spans more than
    the estimate, up to (0, inf)) and the estimate is not called a success."""
    pytest.importorskip("torch")
    solver = make_solver("torch-pinn", CASE, **PINN_SMALL)
    est = solver.identify(Observations(good.t[:30], good.P1[:30], good.delta[:30]))
    assert np.isfinite([est.m, est.d]).all() and not np.isnan([est.m_ci95, est.d_ci95]).any()
    assert _inside(est.m_ci95, est.m) and _inside(est.d_ci95, est.d)
    assert not est.success and "95 % interval" in est.message
    repeated = solver.identify(Observations(np.full(20, 3.0), np.full(20, 0.14), np.full((20, 1), 0.8)))
    assert not repeated.success and "distinct samples" in repeated.message
