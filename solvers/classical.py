"""Machinery shared by the ODE-solver adapters: time ordering and least-squares identification."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import NamedTuple, TypeVar

import numpy as np
from scipy.optimize import least_squares

from harness.cases import Case, Observations
from harness.model import SwingSystem, smib_system
from solvers.base import SolveError
from solvers.identification import Estimate, gauss_newton_covariance
from solvers.options import Bounds, OptionSchema, PositiveFloat

T = TypeVar("T")

__all__ = ["TOLERANCE_CONFIGS", "ObservationLayout", "ToleranceOptions", "identify_least_squares"]


class ToleranceOptions(OptionSchema):
    """The options every tolerance-controlled ODE adapter has: rtol, atol (defaults 1e-3, 1e-6:
    MATLAB ode45's, which made the paper's data) and m_bounds, d_bounds (p.u.), the search box of
    `identify`."""

    rtol: PositiveFloat = 1e-3
    atol: PositiveFloat = 1e-6
    m_bounds: Bounds = (0.02, 2.0)
    d_bounds: Bounds = (0.005, 1.0)


# "default" is the schema's defaults; "tight" is for identification and for comparing at high accuracy.
TOLERANCE_CONFIGS = {
    "default": {},
    "tight": {"rtol": 1e-10, "atol": 1e-12},
}


def run_batch(run: Callable[[np.ndarray], T], P1: np.ndarray) -> T:
    """`run(P1)` for the whole batch; if it raises SolveError, rerun one P1 at a time so that the
    error names the trajectory that fails (costs time only on failure)."""
    try:
        return run(P1)
    except SolveError:
        if P1.size == 1:
            raise
        for p1 in P1:
            run(P1[P1 == p1][:1])
        raise


class ObservationLayout(NamedTuple):
    """Scattered samples as a (P1, t) grid: sorted unique t (s) and P1, and the index of each
    sample in them, so one batched simulation on the grid serves every sample."""

    t: np.ndarray
    P1: np.ndarray
    t_index: np.ndarray
    p1_index: np.ndarray

    @classmethod
    def of(cls, obs: Observations) -> ObservationLayout:
        t, t_index = np.unique(obs.t, return_inverse=True)
        p1, p1_index = np.unique(obs.P1, return_inverse=True)
        return cls(t, p1, t_index, p1_index)

    def pick(self, grid: np.ndarray) -> np.ndarray:
        """Values at the samples from an array of shape (len(P1), len(t))."""
        return grid[self.p1_index, self.t_index]


# Simulator for identification: (m, d, with_jacobian) -> (delta, omega, d delta/d(m, d),
# d omega/d(m, d)) on the layout's grid, arrays (n_p, n_t) and (n_p, n_t, 2); jacobians None unless
# asked for.
Simulator = Callable[
    [float, float, bool], tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]
]


def identify_least_squares(
    simulate: Simulator, obs: Observations, layout: ObservationLayout,
    m_bounds: tuple[float, float], d_bounds: tuple[float, float], analytic_jacobian: bool,
    n_start: int = 6, xtol: float = 1e-12, diff_step: float | None = None,
    rank_starts: Simulator | None = None, rtol: float = 0.0,
) -> Estimate:
    """Least squares over theta = (log m, log d) of the misfit in delta (and omega when observed).

    The misfit of an oscillation over 20 s has local minima in m (the frequency), so the start is the
    best point of an `n_start` x `n_start` log-spaced grid over the bounds; then a trust-region
    Gauss-Newton (`scipy.optimize.least_squares`) refines it, with the simulator's sensitivities when
    `analytic_jacobian` (else finite differences with the relative step `diff_step`, scipy's
    default when None). `rank_starts` (default `simulate`) ranks the start grid: a cheaper,
    looser simulator may do, since only the order of the misfits matters there.
    Returns the `Estimate` (iterations: simulations) with the Gauss-Newton covariance of
    (log m, log d) from least squares' Jacobian at the solution (the analytic one, or the finite
    differences) and the misfit: s^2 (J^T J)^-1, s^2 = ||r||^2 / (n - 2) pooled over delta and omega,
    plus the simulator's own error taken as `rtol` (its relative tolerance) x ||observations||
    (`gauss_newton_covariance`'s model_error).
    """
    with_omega = obs.omega is not None
    target = np.concatenate([obs.delta, obs.omega]) if with_omega else obs.delta
    n_sim = 0

    def misfit(theta: np.ndarray, want_jac: bool = False, run: Simulator = simulate):
        nonlocal n_sim
        n_sim += 1
        m, d = np.exp(theta)
        delta, omega, jd, jo = run(m, d, want_jac)
        r = layout.pick(delta)
        if with_omega:
            r = np.concatenate([r, layout.pick(omega)])
        if not want_jac:
            return r - target
        jac = layout.pick(jd)
        if with_omega:
            jac = np.concatenate([jac, layout.pick(jo)])
        return jac * np.array([m, d])  # chain rule for the log parameters

    lower = np.log([m_bounds[0], d_bounds[0]])
    upper = np.log([m_bounds[1], d_bounds[1]])
    grid = [np.linspace(lo, hi, n_start + 2)[1:-1] for lo, hi in zip(lower, upper)]
    starts = [np.array([a, b]) for a in grid[0] for b in grid[1]]
    costs = [np.sum(misfit(theta, run=rank_starts or simulate) ** 2) for theta in starts]
    theta0 = starts[int(np.nanargmin(costs))]

    jac = (lambda theta: misfit(theta, want_jac=True)) if analytic_jacobian else "2-point"
    result = least_squares(
        misfit, theta0, jac=jac, bounds=(lower, upper), xtol=xtol, ftol=1e-15, gtol=1e-15,
        x_scale=1.0, max_nfev=200, diff_step=None if analytic_jacobian else diff_step,
    )
    m, d = np.exp(result.x)
    cov, dof, condition = gauss_newton_covariance(result.jac, result.fun, rtol * float(np.linalg.norm(target)))
    return Estimate(float(m), float(d), n_sim, bool(result.success), str(result.message), cov, dof, condition,
                    (tuple(m_bounds), tuple(d_bounds)))


def identify_by_simulation(
    integrate: Callable[[SwingSystem, np.ndarray, np.ndarray], np.ndarray], case: Case,
    obs: Observations, m_bounds: tuple[float, float], d_bounds: tuple[float, float], rtol: float,
) -> Estimate:
    """`identify_least_squares` around `integrate(system, t, P1)` -> states (2, len(P1), len(t)) at
    sorted unique times: the case's system with trial (m, d), Jacobian by finite differences.

    The difference step is sqrt(rtol) (relative, in log m and log d): a solution computed to
    `rtol` is a noisy function of (m, d), and a step of scipy's default 1.5e-8 turns that noise into
    a meaningless Jacobian (measured, scipy-odeint at rtol 1e-3, N_u = 100 noise-free samples:
    m and d off by 3 % and 18 %; with sqrt(rtol), 0.13 % and 0.08 %). A larger step would bias the
    fit of noisy data (the fixed point is where J_approx^T r = 0)."""
    layout = ObservationLayout.of(obs)
    system = smib_system(case)

    def simulate(m: float, d: float, with_jacobian: bool):
        y = integrate(dataclasses.replace(system, m=(m,), d=(d,)), layout.t, layout.P1)
        return y[0], y[1], None, None

    return identify_least_squares(simulate, obs, layout, m_bounds, d_bounds, analytic_jacobian=False,
                                  diff_step=float(np.sqrt(max(rtol, np.finfo(float).eps))), rtol=rtol)
