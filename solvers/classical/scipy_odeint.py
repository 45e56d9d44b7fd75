"""ODEPACK's LSODA through `scipy.integrate.odeint`, all P1 stacked into one banded system."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from scipy.integrate import odeint

from solvers.base import AbstractSolver, Estimate, SolveError, StepCount
from solvers.classical.common import (
    TOLERANCE_CONFIGS,
    TOLERANCE_MARKS,
    PointsByP1,
    StackedStates,
    ToleranceOptions,
    at_query_times,
    identify_by_simulation,
    rhs_args,
    run_batch,
)
from solvers.classical.fault_phases import switched_states
from systems.cases import Case, Observations
from systems.model import Coupling, accelerations


def _rhs(t: float, y: np.ndarray, k: Coupling, m: np.ndarray, d: np.ndarray, P: np.ndarray) -> np.ndarray:
    """y: (n_batch * 2n,), each trajectory's [delta_1..n, omega_1..n] contiguous; m, d (n,) p.u.;
    P: (n_batch, n) p.u. Trajectories do not couple, so the Jacobian is block diagonal: banded,
    with 2n - 1 diagonals on each side."""
    n = m.size
    state = y.reshape(-1, 2 * n)
    acc = accelerations(k, m, d, state[:, :n], state[:, n:], P)
    return np.concatenate([state[:, n:], acc], axis=1).ravel()


class ScipyOdeint(StackedStates, PointsByP1, AbstractSolver):
    """LSODA (Adams / BDF with automatic switching, compiled Fortran) on one system of
    2n * len(P1) states: the Python right-hand side is called once per step for every trajectory,
    which is what makes a batch cheap. Each trajectory's states are contiguous, so LSODA's stiff
    phases difference and factor a banded Jacobian (bandwidth 2n - 1 each side: 4n - 1 right-hand
    side calls per Jacobian, linear cost in the batch) instead of a dense one (2n * len(P1) calls and
    a cubic factorisation: 12 minutes and 4 GB for 1000 trajectories of ieee39, measured).
    Options: rtol, atol (defaults 1e-3, 1e-6, ode45's); m_bounds, d_bounds (p.u.), the search box
    of `identify`. A fault case (P1 the clearing time t_c s): the fault-on phase once for every
    t_c of a query (LSODA's output at the times before the largest t_c and at every t_c), then
    every post-fault phase in one stacked system from its state at t_c (`solvers.classical.fault_phases`)."""

    name: ClassVar[str] = "scipy-odeint"
    SCHEMA = ToleranceOptions
    CONFIGS = TOLERANCE_CONFIGS
    CONFIG_MARKS = TOLERANCE_MARKS
    has_tolerance = True
    handles_faults = True
    counts_steps = True
    # LSODA's stiff (BDF) phases factor the stacked system's Jacobian with LAPACK. With OpenBLAS on
    # 2 threads beside the XLA and OpenMP pools its threads spin-wait on 2 cores (measured, 2 cores,
    # the 100 x 201 grid, rtol 1e-3: 97-216 ms on 2 BLAS threads, 20-32 ms on 1; at 1e-10, 12.7 ms
    # either way): the harness times this adapter with 1.
    blas_threads = 1

    def _fit(self) -> None:
        pass

    def _states(self, case: Case, y0: np.ndarray, P: np.ndarray, t: np.ndarray, failed: str) -> np.ndarray:
        """States (n_b, len(t), 2n) at sorted unique times t >= 0 (s) of the trajectories from y0
        (n_b, 2n) at time 0 with powers P (n_b, n) p.u., in one stacked system; `failed` names
        them in a SolveError."""
        n, n_b = case.n, y0.shape[0]
        args = rhs_args(case, P)
        grid = t if t[0] == 0.0 else np.concatenate([[0.0], t])  # odeint starts at its first time
        if t[-1] == 0.0:
            y = np.repeat(y0.reshape(1, -1), t.size, axis=0)
        else:
            y = self._lsoda(y0.ravel(), grid, args, n, failed)[0][grid.size - t.size:]  # drop the prepended t = 0
        return y.reshape(t.size, n_b, 2 * n).transpose(1, 0, 2)

    def _lsoda(self, y0: np.ndarray, grid: np.ndarray, args: tuple, n: int, failed: str) -> tuple[np.ndarray, dict]:
        """odeint's states at `grid` (s, from 0) of the stacked system `_rhs` from y0, and its
        counters (`full_output`); a failure is a SolveError naming `failed`."""
        y, info = odeint(
            _rhs, y0, grid, args=args, rtol=self.options["rtol"], atol=self.options["atol"],
            tfirst=True, full_output=True, mxstep=100000, ml=2 * n - 1, mu=2 * n - 1,
        )
        if info["message"] != "Integration successful.":
            raise SolveError(f"{self.name}: integration failed at {failed}: {info['message']}")
        return y, info

    def _step_count(self, p1: float) -> StepCount:
        """LSODA's steps (`nst`) and right-hand side evaluations (`nfe`, the banded Jacobian's
        differences included) of the one-point query at t_final."""
        case = self.case
        args = rhs_args(case, case.powers(np.array([p1])))
        _, info = self._lsoda(np.array(case.delta0 + case.omega0, float), np.array([0.0, case.t_final]), args,
                              case.n, f"P1={p1:g}")
        return StepCount(int(info["nst"][-1]), int(info["nfe"][-1]))

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.case.fault is not None:
            y = switched_states(self._phase, self.case, t, P1, stacked=True)
        else:
            y = at_query_times(lambda times: np.concatenate(
                run_batch(lambda p1: self._integrate(self.case, times, p1), P1), axis=-1), t)
        n = self.case.n
        return y[..., :n], y[..., n:]

    def _identify(self, obs: Observations) -> Estimate:
        return identify_by_simulation(self._integrate, self.case, obs, self.options)
