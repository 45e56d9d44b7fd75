"""ODEPACK's LSODA through `scipy.integrate.odeint`, all P1 stacked into one banded system."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from scipy.integrate import odeint

from solvers.base import AbstractSolver, Estimate, SolveError
from solvers.classical import (
    TOLERANCE_CONFIGS,
    TOLERANCE_MARKS,
    PointsByP1,
    ToleranceOptions,
    at_query_times,
    identify_by_simulation,
    run_batch,
    which_p1,
)
from systems.cases import Case, Observations
from systems.model import Coupling, accelerations, coupling


def _rhs(t: float, y: np.ndarray, k: Coupling, m: np.ndarray, d: np.ndarray, P: np.ndarray) -> np.ndarray:
    """y: (n_batch * 2n,), each trajectory's [delta_1..n, omega_1..n] contiguous; m, d (n,) p.u.;
    P: (n_batch, n) p.u. Trajectories do not couple, so the Jacobian is block diagonal: banded,
    with 2n - 1 diagonals on each side."""
    n = m.size
    state = y.reshape(-1, 2 * n)
    acc = accelerations(k, m, d, state[:, :n], state[:, n:], P)
    return np.concatenate([state[:, n:], acc], axis=1).ravel()


class ScipyOdeint(PointsByP1, AbstractSolver):
    """LSODA (Adams / BDF with automatic switching, compiled Fortran) on one system of
    2n * len(P1) states: the Python right-hand side is called once per step for every trajectory,
    which is what makes a batch cheap. Each trajectory's states are contiguous, so LSODA's stiff
    phases difference and factor a banded Jacobian (bandwidth 2n - 1 each side: 4n - 1 right-hand
    side calls per Jacobian, linear cost in the batch) instead of a dense one (2n * len(P1) calls and
    a cubic factorisation: 12 minutes and 4 GB for 1000 trajectories of ieee39, measured).
    Options: rtol, atol (defaults 1e-3, 1e-6, ode45's); m_bounds, d_bounds (p.u.), the search box
    of `identify`."""

    name: ClassVar[str] = "scipy-odeint"
    SCHEMA = ToleranceOptions
    CONFIGS = TOLERANCE_CONFIGS
    CONFIG_MARKS = TOLERANCE_MARKS
    has_tolerance = True
    # LSODA's stiff (BDF) phases factor the stacked system's Jacobian with LAPACK. With OpenBLAS on
    # 2 threads beside the XLA and OpenMP pools its threads spin-wait on 2 cores (measured, 2 cores,
    # the 100 x 201 grid, rtol 1e-3: 97-216 ms on 2 BLAS threads, 20-32 ms on 1; at 1e-10, 12.7 ms
    # either way): the harness times this adapter with 1.
    blas_threads = 1

    def _fit(self) -> None:
        pass

    def _integrate(self, case: Case, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega), each (len(P1), len(t), n), at sorted unique times t >= 0 (s)."""
        n = case.n
        args = (coupling(case), np.asarray(case.m), np.asarray(case.d), case.powers(P1))
        y0 = np.tile(np.array(case.delta0 + case.omega0), P1.size)
        grid = t if t[0] == 0.0 else np.concatenate([[0.0], t])  # odeint starts at its first time
        if t[-1] == 0.0:
            y = np.repeat(y0[None], t.size, axis=0)
        else:
            y, info = odeint(
                _rhs, y0, grid, args=args, rtol=self.options["rtol"], atol=self.options["atol"],
                tfirst=True, full_output=True, mxstep=100000, ml=2 * n - 1, mu=2 * n - 1,
            )
            if info["message"] != "Integration successful.":
                raise SolveError(f"{self.name}: integration failed at {which_p1(P1)}: {info['message']}")
            y = y[grid.size - t.size:]  # drop the prepended t = 0
        y = y.reshape(t.size, P1.size, 2 * n).transpose(1, 0, 2)  # (n_p, n_t, 2n)
        return y[..., :n], y[..., n:]

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        y = at_query_times(lambda times: np.concatenate(
            run_batch(lambda p1: self._integrate(self.case, times, p1), P1), axis=-1), t)
        n = self.case.n
        return y[..., :n], y[..., n:]

    def _identify(self, obs: Observations) -> Estimate:
        return identify_by_simulation(self._integrate, self.case, obs, self.options)
