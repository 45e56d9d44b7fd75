"""The shared PINN optimisers (`solvers.pinn.optim`) on small problems with known minima."""

from __future__ import annotations

import time

import numpy as np
import pytest

from solvers.pinn.optim import _pcg, gauss_newton_cg, lbfgs, levenberg_marquardt

NO_DEADLINE = float("inf")


def _linear(consistent: bool):
    """r = A theta - b for a (20 x 3) A, with b = A (0.5, -1, 2) (zero residual at the solution)
    or random (inconsistent); residuals, jacobian, loss_and_grad and the least-squares solution."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(20, 3))
    b = A @ np.array([0.5, -1.0, 2.0]) if consistent else rng.normal(size=20)

    def loss_and_grad(theta):
        r = A @ theta - b
        return float(r @ r), 2.0 * A.T @ r

    return ((lambda theta: A @ theta - b), (lambda theta: A), loss_and_grad,
            np.linalg.lstsq(A, b, rcond=None)[0])


def _rosenbrock_residuals(theta):
    return np.array([10.0 * (theta[1] - theta[0] ** 2), 1.0 - theta[0]])


def _rosenbrock_jacobian(theta):
    return np.array([[-20.0 * theta[0], 10.0], [-1.0, 0.0]])


def _rosenbrock_loss_and_grad(theta):
    r, J = _rosenbrock_residuals(theta), _rosenbrock_jacobian(theta)
    return float(r @ r), 2.0 * J.T @ r


def _exp_decay():
    """Fit y = a exp(-k t) to exact data of a = 2, k = 0.7."""
    t = np.linspace(0.0, 5.0, 30)
    y = 2.0 * np.exp(-0.7 * t)

    def residuals(theta):
        return theta[0] * np.exp(-theta[1] * t) - y

    def jacobian(theta):
        e = np.exp(-theta[1] * t)
        return np.stack([e, -theta[0] * t * e], axis=1)

    return residuals, jacobian


ROSENBROCK_START = np.array([-1.2, 1.0])


# ---- Levenberg-Marquardt ---------------------------------------------------------------------


def test_lm_solves_linear_least_squares_to_machine_precision():
    residuals, jacobian, _, solution = _linear(consistent=True)
    result = levenberg_marquardt(residuals, jacobian, np.zeros(3), max_iterations=100, deadline=NO_DEADLINE)
    np.testing.assert_allclose(result.theta, solution, rtol=1e-14)
    assert result.iterations <= 10 and result.loss < 1e-28  # damping / 3 each exact-model step
    assert result.success and result.message == "Levenberg-Marquardt: gradient below gtol"


def test_lm_solves_an_inconsistent_linear_system_as_far_as_the_loss_resolves():
    """At a nonzero minimum a step is kept only if the loss drops, so theta is resolved to about
    sqrt(machine epsilon), not to machine precision; the loss itself is the minimum."""
    residuals, jacobian, _, solution = _linear(consistent=False)
    result = levenberg_marquardt(residuals, jacobian, np.zeros(3), max_iterations=100, deadline=NO_DEADLINE)
    np.testing.assert_allclose(result.theta, solution, rtol=1e-8)
    minimum = float(residuals(solution) @ residuals(solution))
    assert result.loss == pytest.approx(minimum, rel=1e-14) and result.loss > 1.0
    assert result.iterations < 100 and result.success
    assert "max_iterations" not in result.message  # it stopped by itself


@pytest.mark.parametrize("problem", ["exp-decay", "rosenbrock"])
def test_lm_converges_on_nonlinear_problems(problem):
    if problem == "exp-decay":
        (residuals, jacobian), theta0, minimum = _exp_decay(), np.array([1.0, 0.1]), np.array([2.0, 0.7])
    else:
        residuals, jacobian, theta0, minimum = (_rosenbrock_residuals, _rosenbrock_jacobian,
                                                ROSENBROCK_START, np.ones(2))
    result = levenberg_marquardt(residuals, jacobian, theta0, max_iterations=200, deadline=NO_DEADLINE)
    np.testing.assert_allclose(result.theta, minimum, rtol=1e-10)
    assert result.loss < 1e-20 and result.success
    assert result.iterations < 200


def test_lm_respects_max_iterations_and_reports_progress():
    seen = []
    result = levenberg_marquardt(_rosenbrock_residuals, _rosenbrock_jacobian, ROSENBROCK_START,
                                 max_iterations=4, deadline=NO_DEADLINE,
                                 progress=lambda i, loss: seen.append((i, loss)))
    assert result.iterations == 4 and result.success
    assert result.message == "Levenberg-Marquardt: reached max_iterations=4"
    assert [i for i, _ in seen] == [1, 2, 3, 4]
    losses = [loss for _, loss in seen]
    assert losses == sorted(losses, reverse=True) and losses[-1] == result.loss  # only descent kept
    start_loss = float(_rosenbrock_residuals(ROSENBROCK_START) @ _rosenbrock_residuals(ROSENBROCK_START))
    assert result.loss < start_loss


def test_lm_respects_the_deadline():
    def slow(theta):
        time.sleep(0.01)
        return _rosenbrock_residuals(theta)

    past = levenberg_marquardt(slow, _rosenbrock_jacobian, ROSENBROCK_START, max_iterations=100,
                               deadline=time.perf_counter() - 1.0)
    assert past.iterations == 0 and past.success
    assert past.message == "Levenberg-Marquardt: reached the time budget"
    np.testing.assert_array_equal(past.theta, ROSENBROCK_START)

    deadline = time.perf_counter() + 0.1
    result = levenberg_marquardt(slow, _rosenbrock_jacobian, ROSENBROCK_START, max_iterations=10_000,
                                 deadline=deadline)
    assert 0 < result.iterations < 10_000 and result.success
    assert result.message == "Levenberg-Marquardt: reached the time budget"
    assert time.perf_counter() < deadline + 0.5  # it predicts the next iteration's cost; slack for a busy machine


def test_lm_non_finite_initial_loss_fails_without_iterating():
    calls = []
    result = levenberg_marquardt(lambda theta: np.array([np.nan, 1.0]),
                                 lambda theta: calls.append(theta) or np.eye(2), np.zeros(2),
                                 max_iterations=10, deadline=NO_DEADLINE)
    assert not result.success and result.iterations == 0 and not calls
    assert "non-finite initial loss" in result.message


def test_lm_rejects_non_finite_trial_steps_and_recovers():
    """r = sqrt(theta) - 0.5 from theta = 4: the Gauss-Newton step lands at theta = -2 (r is nan
    there); that step is rejected, the damping grows, and the run still reaches theta = 0.25."""
    trials = []

    def residuals(theta):
        with np.errstate(invalid="ignore"):
            r = np.sqrt(theta) - 0.5
        trials.append(theta[0])
        return r

    result = levenberg_marquardt(residuals, lambda theta: np.array([[0.5 / np.sqrt(theta[0])]]),
                                 np.array([4.0]), max_iterations=100, deadline=NO_DEADLINE)
    assert min(trials) < 0  # the premise: a non-finite trial happened
    assert result.success and result.theta[0] == pytest.approx(0.25, rel=1e-12)
    assert np.isfinite(result.loss)


@pytest.mark.parametrize("theta0, reason", [([1.0, 2.0], "step below xtol"),
                                             ([0.0, 0.0], "damping diverged (no descent step found)")])
def test_lm_stops_when_no_step_descends(theta0, reason):
    """Every trial point is non-finite: the damping grows until the step is negligible relative to
    theta (xtol), or, at theta = 0, until the damping passes its limit; theta0 is kept."""
    theta0 = np.array(theta0)

    def residuals(theta):
        return theta - 3.0 if np.array_equal(theta, theta0) else np.full(2, np.nan)

    result = levenberg_marquardt(residuals, lambda theta: np.eye(2), theta0, max_iterations=1000,
                                 deadline=NO_DEADLINE)
    assert result.message == f"Levenberg-Marquardt: {reason}" and 0 < result.iterations < 1000
    np.testing.assert_array_equal(result.theta, theta0)
    assert result.loss == float((theta0 - 3.0) @ (theta0 - 3.0))


# ---- matrix-free Gauss-Newton (Levenberg-Marquardt by conjugate gradients) --------------------


def _gn_cg(residuals, jacobian, theta0, **options):
    """gauss_newton_cg on an explicit Jacobian: J v, J^T u and diag(J^T J) from `jacobian`."""
    options = {"max_iterations": 200, "deadline": NO_DEADLINE, "cg_iterations": 50, "cg_tol": 1e-12, **options}
    return gauss_newton_cg(residuals, lambda theta, v: jacobian(theta) @ v, lambda theta, u: jacobian(theta).T @ u,
                           lambda theta: np.sum(jacobian(theta) ** 2, axis=0), theta0, **options)


def test_pcg_solves_a_symmetric_positive_definite_system_in_n_products():
    rng = np.random.default_rng(1)
    B = rng.normal(size=(8, 6))
    A = B.T @ B + np.diag(rng.uniform(0.1, 10.0, 6))  # SPD, unevenly scaled rows
    b = rng.normal(size=6)
    x, products = _pcg(lambda v: A @ v, b, 1.0 / np.diag(A), max_iterations=50, tol=1e-13)
    np.testing.assert_allclose(A @ x, b, rtol=1e-10, atol=1e-12)
    assert products <= 7  # n = 6 in exact arithmetic, one more for rounding
    x2, products2 = _pcg(lambda v: A @ v, b, 1.0 / np.diag(A), max_iterations=2, tol=1e-13)
    assert products2 == 2 and np.linalg.norm(A @ x2 - b) < np.linalg.norm(b)  # a partial solve still reduces


@pytest.mark.parametrize("problem", ["linear", "exp-decay", "rosenbrock"])
def test_gn_cg_reaches_the_minimum_levenberg_marquardt_reaches(problem):
    if problem == "linear":
        residuals, jacobian, _, _ = _linear(consistent=True)
        theta0 = np.zeros(3)
    elif problem == "exp-decay":
        (residuals, jacobian), theta0 = _exp_decay(), np.array([1.0, 0.1])
    else:
        residuals, jacobian, theta0 = _rosenbrock_residuals, _rosenbrock_jacobian, ROSENBROCK_START
    lm = levenberg_marquardt(residuals, jacobian, theta0, max_iterations=200, deadline=NO_DEADLINE)
    result = _gn_cg(residuals, jacobian, theta0)
    np.testing.assert_allclose(result.theta, lm.theta, rtol=1e-10)
    assert result.loss < 1e-20 and result.success and result.iterations < 200
    assert result.message.startswith("Gauss-Newton-CG: gradient below gtol")


def test_gn_cg_with_truncated_conjugate_gradients_still_descends_to_the_minimum():
    """Two CG products per step on a 12-parameter linear problem: every step is inexact, each kept
    step lowers the loss, and the iteration still reaches the least-squares solution."""
    rng = np.random.default_rng(2)
    A = rng.normal(size=(40, 12)) * np.logspace(0, 2, 12)  # columns scaled over two decades
    b = rng.normal(size=40)
    seen = []
    result = _gn_cg(lambda theta: A @ theta - b, lambda theta: A, np.zeros(12), max_iterations=2000,
                    cg_iterations=2, progress=lambda i, loss: seen.append(loss))
    np.testing.assert_allclose(result.theta, np.linalg.lstsq(A, b, rcond=None)[0], rtol=1e-6)
    assert seen == sorted(seen, reverse=True) and result.success


def test_gn_cg_respects_max_iterations_the_deadline_and_a_non_finite_start():
    seen = []
    result = _gn_cg(_rosenbrock_residuals, _rosenbrock_jacobian, ROSENBROCK_START, max_iterations=3,
                    progress=lambda i, loss: seen.append(i))
    assert result.iterations == 3 and seen == [1, 2, 3]
    assert result.message.startswith("Gauss-Newton-CG: reached max_iterations=3")
    past = _gn_cg(_rosenbrock_residuals, _rosenbrock_jacobian, ROSENBROCK_START,
                  deadline=time.perf_counter() - 1.0)
    assert past.iterations == 0 and past.message.startswith("Gauss-Newton-CG: reached the time budget")
    np.testing.assert_array_equal(past.theta, ROSENBROCK_START)
    bad = _gn_cg(lambda theta: np.array([np.nan, 1.0]), lambda theta: np.eye(2), np.zeros(2))
    assert not bad.success and bad.iterations == 0 and "non-finite initial loss" in bad.message


# ---- L-BFGS --------------------------------------------------------------------------------


@pytest.mark.parametrize("consistent", [True, False], ids=["consistent", "inconsistent"])
def test_lbfgs_solves_linear_least_squares(consistent):
    """ftol = machine epsilon: it runs until the loss stops dropping, which resolves theta to
    about sqrt(epsilon) relative (measured 4e-11 consistent, 3e-8 inconsistent) and the loss to the
    minimum."""
    residuals, _, loss_and_grad, solution = _linear(consistent)
    result = lbfgs(loss_and_grad, np.zeros(3), history=10, max_iterations=100, deadline=NO_DEADLINE)
    np.testing.assert_allclose(result.theta, solution, rtol=1e-7)
    minimum = float(residuals(solution) @ residuals(solution))
    assert result.loss == pytest.approx(minimum, rel=1e-14, abs=1e-18)
    assert result.iterations < 30 and result.success and result.message.startswith("L-BFGS-B: ")
    assert result.loss == loss_and_grad(result.theta)[0]  # theta and loss belong together


def test_lbfgs_converges_on_rosenbrock():
    result = lbfgs(_rosenbrock_loss_and_grad, ROSENBROCK_START, history=10, max_iterations=500,
                   deadline=NO_DEADLINE)
    np.testing.assert_allclose(result.theta, np.ones(2), rtol=1e-7)
    assert result.loss < 1e-14 and result.success and 1 < result.iterations < 500
    assert result.loss == _rosenbrock_loss_and_grad(result.theta)[0]


def test_lbfgs_reports_progress():
    seen = []
    result = lbfgs(_rosenbrock_loss_and_grad, ROSENBROCK_START, history=10, max_iterations=500,
                   deadline=NO_DEADLINE, progress=lambda i, loss: seen.append((i, loss)))
    assert [i for i, _ in seen] == list(range(1, result.iterations + 1))
    assert result.loss <= seen[-1][1]


def test_lbfgs_respects_max_iterations():
    result = lbfgs(_rosenbrock_loss_and_grad, ROSENBROCK_START, history=10, max_iterations=5,
                   deadline=NO_DEADLINE)
    assert result.iterations == 5 and result.success
    assert result.loss < _rosenbrock_loss_and_grad(ROSENBROCK_START)[0]


def test_lbfgs_respects_the_deadline():
    past = lbfgs(_rosenbrock_loss_and_grad, ROSENBROCK_START, history=10, max_iterations=500,
                 deadline=time.perf_counter() - 1.0)
    assert past.iterations == 1  # it checks the clock after each iteration
    assert past.message == "L-BFGS-B: reached the time budget" and past.success

    def slow(theta):
        time.sleep(0.01)
        return _rosenbrock_loss_and_grad(theta)

    deadline = time.perf_counter() + 0.1
    result = lbfgs(slow, ROSENBROCK_START, history=10, max_iterations=500, deadline=deadline)
    assert 1 <= result.iterations < 500 and result.message == "L-BFGS-B: reached the time budget"
    assert time.perf_counter() < deadline + 0.5


def test_lbfgs_without_a_finite_loss_fails():
    result = lbfgs(lambda theta: (np.nan, np.zeros_like(theta)), np.zeros(2), history=5, max_iterations=10,
                   deadline=NO_DEADLINE)
    assert not result.success and not np.isfinite(result.loss)
