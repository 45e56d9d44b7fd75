"""scipy's explicit Runge-Kutta 5(4) (Dormand-Prince), `solve_ivp(method="RK45")`."""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np
from scipy.integrate import solve_ivp

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
)
from solvers.classical.fault_phases import switched_states
from systems.cases import Case, Observations
from systems.model import Coupling, accelerations


def _rhs(t: float, y: np.ndarray, k: Coupling, m: np.ndarray, d: np.ndarray, P: np.ndarray) -> np.ndarray:
    """y: (2n * n_batch,) as rows [delta_1..n, omega_1..n] of a (2n, n_batch) array; m, d (n,) p.u.;
    P: (n_batch, n) p.u."""
    n = m.size
    state = y.reshape(2 * n, -1)
    acc = accelerations(k, m, d, state[:n].T, state[n:].T, P)
    return np.concatenate([state[n:], acc.T]).ravel()


def stacked_states(integrate, case: Case, t: np.ndarray, P: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """States (n_b, len(t), 2n) from `integrate(y (2n * n_b,), args)` -> states (2n * n_b, len(t))
    of the stacked system of `_rhs` (rows [delta; omega] x trajectory): P (n_b, n) p.u. and y0
    (n_b, 2n) each trajectory's powers and initial state."""
    n, n_b = case.n, P.shape[0]
    args = rhs_args(case, P)
    y = integrate(np.ascontiguousarray(y0.T).ravel(), args).reshape(2 * n, n_b, t.size)
    return y.transpose(1, 2, 0)


class RK45Options(ToleranceOptions):
    batch: Literal["loop", "stacked"] = "loop"


class ScipyRK45(StackedStates, PointsByP1, AbstractSolver):
    """Adaptive explicit RK45 from scipy, one of two batch modes over P1.

    Options: rtol, atol (defaults 1e-3, 1e-6: MATLAB ode45's, which made the paper's data);
    batch: "loop" (one `solve_ivp` per P1, the default) or "stacked" (one system of 2 * len(P1)
    states; the step size then follows the hardest trajectory); m_bounds, d_bounds (p.u.): the
    search box of `identify`, which simulates every P1 in one stacked system whatever `batch`.
    A fault case (P1 the clearing time t_c s): the fault-on phase once for every t_c of a query,
    with dense output, then each post-fault phase from its state at t_c, looped or stacked as
    `batch` says (`solvers.classical.fault_phases`).
    """

    name: ClassVar[str] = "scipy-rk45"
    method: ClassVar[str] = "RK45"
    SCHEMA = RK45Options
    CONFIGS = TOLERANCE_CONFIGS
    CONFIG_MARKS = TOLERANCE_MARKS
    has_tolerance = True
    handles_faults = True
    counts_steps = True
    VARIANTS = ({"batch": "stacked"},)
    QUERY_OPTIONS = frozenset({"batch"})  # `identify` simulates stacked in either mode

    def _fit(self) -> None:
        pass

    def _states(self, case: Case, y0: np.ndarray, P: np.ndarray, t: np.ndarray, failed: str) -> np.ndarray:
        """States (n_b, len(t), 2n) at sorted unique times t (s) of the trajectories from y0 (n_b,
        2n) at time 0 with powers P (n_b, n) p.u., all in one stacked system; `failed` names them
        in a SolveError."""

        def integrate(y0_all: np.ndarray, args: tuple) -> np.ndarray:
            if t[-1] == 0.0:
                return np.repeat(y0_all[:, None], t.size, axis=1)
            return self._ivp(y0_all, args, t[-1], t, failed).y

        return stacked_states(integrate, case, t, P, y0)

    def _ivp(self, y0_all: np.ndarray, args: tuple, t_end: float, t_eval: np.ndarray | None, failed: str):
        """`solve_ivp` of the stacked system `_rhs` from 0 to t_end (s), saved at t_eval (None:
        at its steps); a failure is a SolveError naming `failed`."""
        sol = solve_ivp(_rhs, (0.0, t_end), y0_all, method=self.method, t_eval=t_eval,
                        rtol=self.options["rtol"], atol=self.options["atol"], args=args)
        if not sol.success:
            raise SolveError(f"{self.name}: integration failed at {failed}: {sol.message}")
        return sol

    def _step_count(self, p1: float) -> StepCount:
        """solve_ivp's accepted steps (its output at every step) and `nfev`."""
        case = self.case
        args = rhs_args(case, case.powers(np.array([p1])))
        sol = self._ivp(np.array(case.delta0 + case.omega0, float), args, case.t_final, None, f"P1={p1:g}")
        return StepCount(sol.t.size - 1, int(sol.nfev))

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        stacked = self.options["batch"] == "stacked"
        if self.case.fault is not None:
            y = switched_states(self._phase, self.case, t, P1, stacked)
        else:
            def states(times: np.ndarray) -> np.ndarray:  # (n_p, n_t, 2n)
                if stacked:
                    return np.concatenate(self._integrate(self.case, times, P1), axis=-1)
                return np.concatenate([np.concatenate(self._integrate(self.case, times, P1[i:i + 1]), axis=-1)
                                       for i in range(P1.size)])

            y = at_query_times(states, t)
        n = self.case.n
        return y[..., :n], y[..., n:]

    def _identify(self, obs: Observations) -> Estimate:
        return identify_by_simulation(self._integrate, self.case, obs, self.options)
