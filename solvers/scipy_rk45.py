"""scipy's explicit Runge-Kutta 5(4) (Dormand-Prince), `solve_ivp(method="RK45")`."""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np
from scipy.integrate import solve_ivp

from harness.cases import Observations
from harness.model import SwingSystem, accelerations, smib_system
from solvers.base import AbstractSolver, Estimate, SolveError
from solvers.classical import TOLERANCE_CONFIGS, ToleranceOptions, identify_by_simulation


def _rhs(t: float, y: np.ndarray, system: SwingSystem, P: np.ndarray) -> np.ndarray:
    """y: (2n * n_batch,) as rows [delta_1..n, omega_1..n] of a (2n, n_batch) array; P: (n, n_batch)."""
    n = system.n
    state = y.reshape(2 * n, -1)
    acc = accelerations(system, state[:n], state[n:], P)
    return np.concatenate([state[n:], np.stack(acc)]).ravel()


class RK45Options(ToleranceOptions):
    batch: Literal["loop", "stacked"] = "loop"


class ScipyRK45(AbstractSolver):
    """Adaptive explicit RK45 from scipy, one of two batch modes over P1.

    Options: rtol, atol (defaults 1e-3, 1e-6: MATLAB ode45's, which made the paper's data);
    batch: "loop" (one `solve_ivp` per P1, the default) or "stacked" (one system of 2 * len(P1)
    states; the step size then follows the hardest trajectory); m_bounds, d_bounds (p.u.): the
    search box of `identify`, which always simulates stacked.
    """

    name: ClassVar[str] = "scipy-rk45"
    method: ClassVar[str] = "RK45"
    SCHEMA = RK45Options
    CONFIGS = TOLERANCE_CONFIGS
    VARIANTS = ({"batch": "stacked"},)

    def _fit(self) -> None:
        self.system = smib_system(self.case)

    def _integrate(self, system: SwingSystem, t: np.ndarray, P1: np.ndarray) -> np.ndarray:
        """States (2, len(P1), len(t)) at sorted unique times t, all P1 in one stacked system."""
        y0 = np.repeat(np.array(system.delta0 + system.omega0)[:, None], P1.size, axis=1)
        if t[-1] == 0.0:
            return np.repeat(y0[:, :, None], t.size, axis=2)
        sol = solve_ivp(
            _rhs, (0.0, t[-1]), y0.ravel(), method=self.method, t_eval=t,
            rtol=self.options["rtol"], atol=self.options["atol"], args=(system, P1[None, :]),
        )
        if not sol.success:
            where = f"P1={P1[0]:g}" if P1.size == 1 else f"one of P1 in [{P1.min():g}, {P1.max():g}]"
            raise SolveError(f"{self.name}: integration failed at {where}: {sol.message}")
        return sol.y.reshape(2, P1.size, t.size)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        times, order = np.unique(t, return_inverse=True)
        if self.options["batch"] == "stacked":
            y = self._integrate(self.system, times, P1)
        else:
            y = np.concatenate([self._integrate(self.system, times, P1[i:i + 1]) for i in range(P1.size)], axis=1)
        return y[0][:, order], y[1][:, order]

    def _identify(self, obs: Observations) -> Estimate:
        return identify_by_simulation(
            self._integrate, self.case, obs, self.options["m_bounds"], self.options["d_bounds"],
            self.options["rtol"],
        )
