"""The optimisers, shared by both backends: numpy/scipy driving the backend's compiled functions.

The backends only supply the residual vector, its Jacobian (Levenberg-Marquardt) or the loss and
its gradient (L-BFGS) as float64 numpy arrays of a flat float64 parameter vector. Keeping the
optimiser out of the frameworks makes the two backends run the same algorithm step for step, so a
comparison of the backends compares their autodiff and evaluation, not two L-BFGS implementations
(torch.optim.LBFGS and optax.lbfgs differ in line search, curvature-pair rules and stopping).

Measured while choosing (SMIB inference case, float64, hard initial conditions, one seed, 2 busy
cores, JAX): L-BFGS (the lead's runs: 5e-4 after 60 s, 1.9e-4 after 120 s) against
Levenberg-Marquardt on a 3 x 20 network with 2000 collocation points: 4e-4 after 10 s, 1e-4 after
28 s, 4e-5 after 40 s. A PINN loss is a sum of squares of smooth residuals; for a few hundred to a
thousand parameters the Gauss-Newton matrix J^T J is cheap (a (P x P) Cholesky per step) and
captures the curvature that L-BFGS has to rebuild from 50 gradient pairs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.optimize import minimize

__all__ = ["NormalEquations", "OptimResult", "Progress", "gauss_newton_cg", "lbfgs", "levenberg_marquardt"]

# progress(iteration, loss) -> None; called after every iteration
Progress = Callable[[int, float], None] | None
# (theta (P,), r (N,)) -> (J^T J (P, P), J^T r (P,)) at theta, r = residuals(theta)
NormalEquations = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class OptimResult:
    """The trained parameters (float64), final loss, iterations done, why it stopped, and
    whether it stopped by convergence or budget (True) rather than by a failure (False)."""

    theta: np.ndarray
    loss: float
    iterations: int
    message: str
    success: bool


def levenberg_marquardt(
    residuals: Callable[[np.ndarray], np.ndarray], jacobian: Callable[[np.ndarray], np.ndarray] | None,
    theta0: np.ndarray, *, max_iterations: int, deadline: float, progress: Progress = None,
    mu0: float = 1e-3, gtol: float = 1e-30, xtol: float = 1e-15, normal_equations: NormalEquations | None = None,
    ftol: float = 0.0, patience: int = 10,
) -> OptimResult:
    """Minimise ||r(theta)||^2 by Levenberg-Marquardt with Moré's diagonal scaling and
    Nielsen's damping update (H. B. Nielsen, IMM-REP-1999-05).

    residuals: theta (P,) -> r (N,); jacobian: theta -> dr/dtheta (N, P); both float64 numpy.
    `normal_equations` (theta, r) -> (J^T J, J^T r), where given, replaces the products of J
    (for a Jacobian with structure that makes them cheaper than J itself; `jacobian` may then be
    None). Each iteration solves (J^T J + mu D) h = -J^T r by Cholesky, D the running maximum of
    diag(J^T J), and evaluates r once; a step is kept when it lowers the loss, then J is evaluated
    again. Stops after `max_iterations`, when the next iteration would end after `deadline` (a
    `time.perf_counter()` value), when the gradient or the step is negligible, when the damping
    diverges, or (`ftol` > 0) when the last `patience` iterations lowered the loss by less than
    the fraction `ftol` of it."""
    theta = np.array(theta0, dtype=np.float64)
    r = residuals(theta)
    loss = float(r @ r)
    if not np.isfinite(loss):
        return OptimResult(theta, loss, 0, "Levenberg-Marquardt: non-finite initial loss", False)
    cost = {True: 0.0, False: 0.0}  # seconds of the last iteration with / without a Jacobian
    need_jacobian = True
    nu, mu = 2.0, mu0
    diag = None
    message, success, iteration = f"reached max_iterations={max_iterations}", True, 0
    history = [loss]
    while iteration < max_iterations:
        start = time.perf_counter()
        if start + cost[need_jacobian] > deadline:
            message = "reached the time budget"
            break
        if ftol > 0 and len(history) > patience and history[-patience - 1] - loss <= ftol * loss:
            message = f"loss fell by less than ftol={ftol:g} of it in {patience} iterations"
            break
        iteration += 1
        with_jacobian = need_jacobian
        if need_jacobian:
            if normal_equations is not None:
                A, g = normal_equations(theta, r)
            else:
                J = jacobian(theta)
                A = J.T @ J
                g = J.T @ r
            # Moré's scaling (MINPACK): D = running maximum of diag(J^T J). Measured on 3 seeds,
            # 2 x 20 net, 55 s: plain diag(J^T J) (Marquardt) left one seed with a local defect
            # (omega rel. L2 1e-3, others 3e-5), identity damping 3e-5..5e-5, Moré 2e-5..3e-5.
            diag = np.diag(A).copy() if diag is None else np.maximum(diag, np.diag(A))
            diag = np.maximum(diag, 1e-12 * max(float(diag.max()), 1e-300))
            need_jacobian = False
            if np.max(np.abs(g)) <= gtol:
                message = "gradient below gtol"
                break
        try:
            factor = scipy.linalg.cho_factor(A + mu * np.diag(diag), check_finite=False)
            h = -scipy.linalg.cho_solve(factor, g, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            mu, nu = mu * nu, 2.0 * nu
            continue
        if np.linalg.norm(h) <= xtol * (np.linalg.norm(theta) + xtol):
            message = "step below xtol"
            break
        r_new = residuals(theta + h)
        loss_new = float(r_new @ r_new)
        predicted = float(h @ (mu * diag * h - g))
        rho = (loss - loss_new) / predicted if predicted > 0 else -1.0
        if np.isfinite(loss_new) and rho > 0:
            theta, r, loss = theta + h, r_new, loss_new
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            need_jacobian = True
        else:
            mu, nu = mu * nu, 2.0 * nu
            if mu > 1e20:
                message, success = "damping diverged (no descent step found)", loss < np.inf
                break
        cost[with_jacobian] = time.perf_counter() - start
        history.append(loss)
        if progress is not None:
            progress(iteration, loss)
    return OptimResult(theta, loss, iteration, f"Levenberg-Marquardt: {message}", success)


def _pcg(product: Callable[[np.ndarray], np.ndarray], b: np.ndarray, inverse_diagonal: np.ndarray,
         max_iterations: int, tol: float) -> tuple[np.ndarray, int]:
    """x ~ A^-1 b by conjugate gradients preconditioned with diag(A)^-1 (`inverse_diagonal`), from
    x = 0, for a symmetric positive definite A given by `product(v) = A v`; stops after
    `max_iterations` products or when ||A x - b|| <= tol ||b||. Returns x and the products done."""
    x = np.zeros_like(b)
    res = b.copy()
    z = inverse_diagonal * res
    p = z.copy()
    rz = float(res @ z)
    bound = tol * float(np.linalg.norm(b))
    for k in range(1, max_iterations + 1):
        Ap = product(p)
        curvature = float(p @ Ap)
        if curvature <= 0.0:  # rounding on a (numerically) singular direction: keep what we have
            return x, k
        alpha = rz / curvature
        x += alpha * p
        res -= alpha * Ap
        if float(np.linalg.norm(res)) <= bound:
            return x, k
        z = inverse_diagonal * res
        rz_new = float(res @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, max_iterations


def gauss_newton_cg(
    residuals: Callable[[np.ndarray], np.ndarray], jvp: Callable[[np.ndarray, np.ndarray], np.ndarray],
    vjp: Callable[[np.ndarray, np.ndarray], np.ndarray], diagonal: Callable[[np.ndarray], np.ndarray],
    theta0: np.ndarray, *, max_iterations: int, deadline: float, cg_iterations: int, cg_tol: float,
    progress: Progress = None, mu0: float = 1e-3, gtol: float = 1e-30,
) -> OptimResult:
    """Minimise ||r(theta)||^2 by a matrix-free Levenberg-Marquardt: the step of
    `levenberg_marquardt` (Moré's scaling D, Nielsen's damping update) with the damped Gauss-Newton
    system (J^T J + mu D) h = -J^T r solved inexactly by Jacobi-preconditioned conjugate gradients
    on Jacobian-vector products, never forming J^T J.

    residuals: theta (P,) -> r (N,); jvp: (theta, v (P,)) -> J v (N,); vjp: (theta, u (N,)) ->
    J^T u (P,); diagonal: theta -> diag(J^T J) (P,), evaluated once, at theta0 (D, and the
    preconditioner diag(J^T J) + mu D with that D); all float64 numpy. Each iteration runs at most
    `cg_iterations` CG steps (each one jvp and one vjp), stopping when the system's residual is
    below `cg_tol` of its right-hand side, then evaluates r once; the predicted reduction is
    -2 g.h - ||J h||^2 (one more jvp). Stops like `levenberg_marquardt`: after `max_iterations`,
    when the next iteration would end after `deadline`, when the gradient is negligible, or when
    the damping diverges."""
    theta = np.array(theta0, dtype=np.float64)
    r = residuals(theta)
    loss = float(r @ r)
    if not np.isfinite(loss):
        return OptimResult(theta, loss, 0, "Gauss-Newton-CG: non-finite initial loss", False)
    diag = np.asarray(diagonal(theta), np.float64)
    diag = np.maximum(diag, 1e-12 * max(float(diag.max()), 1e-300))
    g = vjp(theta, r)
    nu, mu = 2.0, mu0
    last = 0.0  # seconds of the last iteration
    products = 0
    message, success, iteration = f"reached max_iterations={max_iterations}", True, 0
    while iteration < max_iterations:
        start = time.perf_counter()
        if start + last > deadline:
            message = "reached the time budget"
            break
        if np.max(np.abs(g)) <= gtol:
            message = "gradient below gtol"
            break
        iteration += 1

        def product(v: np.ndarray, point: np.ndarray = theta, damping: float = mu) -> np.ndarray:
            return vjp(point, jvp(point, v)) + damping * diag * v

        h, done = _pcg(product, -g, 1.0 / ((1.0 + mu) * diag), cg_iterations, cg_tol)
        products += done + 1
        Jh = jvp(theta, h)
        predicted = -2.0 * float(g @ h) - float(Jh @ Jh)
        r_new = residuals(theta + h)
        loss_new = float(r_new @ r_new)
        rho = (loss - loss_new) / predicted if predicted > 0 else -1.0
        if np.isfinite(loss_new) and rho > 0:
            theta, r, loss = theta + h, r_new, loss_new
            g = vjp(theta, r)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
        else:
            mu, nu = mu * nu, 2.0 * nu
            if mu > 1e20:
                message, success = "damping diverged (no descent step found)", loss < np.inf
                break
        last = time.perf_counter() - start
        if progress is not None:
            progress(iteration, loss)
    return OptimResult(theta, loss, iteration,
                       f"Gauss-Newton-CG: {message} ({products} Jacobian products)", success)


class _Stop(Exception):
    pass


def lbfgs(
    loss_and_grad: Callable[[np.ndarray], tuple[float, np.ndarray]], theta0: np.ndarray, *,
    history: int, max_iterations: int, deadline: float, progress: Progress = None,
) -> OptimResult:
    """Minimise the loss with scipy's L-BFGS-B, the settings of the paper's code (Raissi's
    ScipyOptimizerInterface: maxcor `history`, maxls 50, ftol = machine epsilon, so it runs until
    the line search fails or the budget ends). loss_and_grad: theta (P,) float64 -> (loss, gradient
    (P,) float64). Stops at `max_iterations` or when an iteration ends after `deadline`."""
    state = {"iterations": 0, "theta": np.array(theta0, np.float64), "loss": np.inf}

    def fun(theta: np.ndarray) -> tuple[float, np.ndarray]:
        loss, grad = loss_and_grad(theta)
        if loss < state["loss"]:
            state["theta"], state["loss"] = theta.copy(), loss
        return loss, grad

    def callback(intermediate_result) -> None:  # scipy passes the OptimizeResult by this name only
        state["iterations"] += 1
        if progress is not None:
            progress(state["iterations"], float(intermediate_result.fun))
        if time.perf_counter() > deadline:
            raise StopIteration

    result = minimize(
        fun, state["theta"], jac=True, method="L-BFGS-B", callback=callback,
        options={"maxiter": max_iterations, "maxfun": 10 * max_iterations, "maxcor": history,
                 "maxls": 50, "ftol": np.finfo(float).eps, "gtol": 0.0},
    )
    message = str(result.message)
    if time.perf_counter() > deadline and state["iterations"] < max_iterations:
        message = "reached the time budget"
    theta, loss = (state["theta"], state["loss"]) if np.isfinite(state["loss"]) else (result.x, float(result.fun))
    return OptimResult(theta, float(loss), state["iterations"], f"L-BFGS-B: {message}",
                       bool(np.isfinite(loss)))
