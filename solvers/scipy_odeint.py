"""ODEPACK's LSODA through `scipy.integrate.odeint`, all P1 stacked into one system."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from scipy.integrate import odeint

from harness.cases import Observations
from harness.model import SwingSystem, smib_system
from solvers.base import AbstractSolver, Estimate, SolveError
from solvers.classical import TOLERANCE_CONFIGS, ToleranceOptions, identify_by_simulation, run_batch
from solvers.scipy_rk45 import _rhs


class ScipyOdeint(AbstractSolver):
    """LSODA (Adams / BDF with automatic switching, compiled Fortran) on one system of
    2 * len(P1) states: the Python right-hand side is called once per step for every trajectory,
    which is what makes a batch cheap. Options: rtol, atol (defaults 1e-3, 1e-6, ode45's);
    m_bounds, d_bounds (p.u.), the search box of `identify`."""

    name: ClassVar[str] = "scipy-odeint"
    SCHEMA = ToleranceOptions
    CONFIGS = TOLERANCE_CONFIGS
    # LSODA's stiff (BDF) phases factor the stacked system's Jacobian with LAPACK. With OpenBLAS on
    # 2 threads beside the XLA and OpenMP pools its threads spin-wait on 2 cores (measured, 2 cores,
    # the 100 x 201 grid, rtol 1e-3: 97-216 ms on 2 BLAS threads, 20-32 ms on 1; at 1e-10, 12.7 ms
    # either way): the harness times this adapter with 1.
    blas_threads = 1

    def _fit(self) -> None:
        self.system = smib_system(self.case)

    def _integrate(self, system: SwingSystem, t: np.ndarray, P1: np.ndarray) -> np.ndarray:
        """States (2, len(P1), len(t)) at sorted unique times t >= 0 (s)."""
        y0 = np.repeat(np.array(system.delta0 + system.omega0)[:, None], P1.size, axis=1)
        if t[-1] == 0.0:
            return np.repeat(y0[:, :, None], t.size, axis=2)
        grid = t if t[0] == 0.0 else np.concatenate([[0.0], t])  # odeint starts at its first time
        y, info = odeint(
            _rhs, y0.ravel(), grid, args=(system, P1[None, :]), rtol=self.options["rtol"],
            atol=self.options["atol"], tfirst=True, full_output=True, mxstep=100000,
        )
        if info["message"] != "Integration successful.":
            where = f"P1={P1[0]:g}" if P1.size == 1 else f"one of P1 in [{P1.min():g}, {P1.max():g}]"
            raise SolveError(f"{self.name}: integration failed at {where}: {info['message']}")
        y = y[grid.size - t.size:]  # drop the prepended t = 0
        return y.T.reshape(2, P1.size, t.size)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        times, order = np.unique(t, return_inverse=True)
        y = run_batch(lambda p1: self._integrate(self.system, times, p1), P1)
        return y[0][:, order], y[1][:, order]

    def _identify(self, obs: Observations) -> Estimate:
        return identify_by_simulation(
            self._integrate, self.case, obs, self.options["m_bounds"], self.options["d_bounds"],
            self.options["rtol"],
        )
