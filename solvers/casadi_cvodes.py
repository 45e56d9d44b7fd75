"""SUNDIALS CVODES (variable-order BDF/Adams) through CasADi, batched over P1 with `map`."""

from __future__ import annotations

from functools import lru_cache
from typing import ClassVar

import numpy as np

from systems.cases import Observations
from systems.model import accelerations, smib_system
from solvers.base import AbstractSolver, Estimate, SolveError
from solvers.classical import (
    TOLERANCE_CONFIGS,
    ObservationLayout,
    ToleranceOptions,
    identify_least_squares,
    run_batch,
)
from solvers.options import PositiveInt

try:
    import casadi as ca
except ImportError:  # pragma: no cover - the registry reports the adapter as not installed
    ca = None


class CVODESOptions(ToleranceOptions):
    threads: PositiveInt = 2


class CasadiCVODES(AbstractSolver):
    """CVODES with P1, m and d as parameters of one symbolic SMIB model.

    `fit()` builds the model and the integrator of the standard grid (0..t_final s, 201 points);
    an integrator is built per distinct output grid and number of P1 values (CasADi fixes the output
    times at construction) and cached, so a warm query of a grid seen before pays no build.
    Trajectories are evaluated with `map(len(P1), "thread", threads)`.
    Options: rtol, atol (defaults 1e-3, 1e-6: MATLAB ode45's), threads (2), m_bounds, d_bounds
    (p.u., the search box of `identify`, which uses CVODES forward sensitivities for d x / d(m, d)).
    """

    name: ClassVar[str] = "casadi-cvodes"
    SCHEMA = CVODESOptions
    CONFIGS = TOLERANCE_CONFIGS

    def _make_caches(self) -> None:
        self._integrators = lru_cache(maxsize=32)(self._build)
        self._identifiers = lru_cache(maxsize=4)(self._build_identifier)

    def _fit(self) -> None:
        self._make_caches()
        t = np.linspace(0.0, self.case.t_final, 201)
        self._integrators(tuple(t), 100)

    def _dae(self) -> dict:
        system = smib_system(self.case)
        x = ca.SX.sym("x", 2)
        p = ca.SX.sym("p", 3)  # P1, m, d
        (acc,) = accelerations(system, [x[0]], [x[1]], [p[0]], sin=ca.sin, m=[p[1]], d=[p[2]])
        return {"x": x, "p": p, "ode": ca.vertcat(x[1], acc)}

    def _integrator(self, times: tuple[float, ...]):
        opts = {"reltol": self.options["rtol"], "abstol": self.options["atol"], "max_num_steps": 100000}
        return ca.integrator("cvodes", "cvodes", self._dae(), 0.0, list(times), opts)

    def _build(self, times: tuple[float, ...], n_p1: int):
        return self._integrator(times).map(n_p1, "thread", self.options["threads"])

    def _run(self, fn, P1: np.ndarray, *args) -> list[np.ndarray]:
        try:
            return [np.asarray(out) for out in fn(*args)]
        except RuntimeError as exc:
            where = f"P1={P1[0]:g}" if P1.size == 1 else f"one of P1 in [{P1.min():g}, {P1.max():g}]"
            reason = str(exc).strip().splitlines()[-1]
            raise SolveError(f"{self.name}: CVODES failed at {where}: {reason}") from exc

    def _x0(self, n: int) -> np.ndarray:
        return np.tile([[self.case.delta0], [self.case.omega0]], (1, n))

    def _states(self, times: np.ndarray, P1: np.ndarray, m: float, d: float) -> np.ndarray:
        """States (2, len(P1), len(times)) at sorted unique times (s)."""
        fn = self._integrators(tuple(times), P1.size)
        params = np.vstack([P1, np.full(P1.size, m), np.full(P1.size, d)])
        (xf,) = self._run(lambda x0, p: [fn(x0=x0, p=p)["xf"]], P1, self._x0(P1.size), params)
        return xf.reshape(2, P1.size, times.size)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        times, order = np.unique(t, return_inverse=True)
        y = run_batch(lambda p1: self._states(times, p1, self.case.m, self.case.d), P1)
        return y[0][:, order], y[1][:, order]

    def _build_identifier(self, times: tuple[float, ...], n_p1: int):
        """(P1 (1, n), m, d) -> states (2, n_t * n) and their jacobian wrt (m, d), (2 n_t, 2 n)."""
        F = self._integrator(times)
        P1, md = ca.MX.sym("P1"), ca.MX.sym("md", 2)
        xf = F(x0=ca.DM([self.case.delta0, self.case.omega0]), p=ca.vertcat(P1, md))["xf"]
        G = ca.Function("G", [P1, md], [xf, ca.jacobian(xf, md)])
        return G.map(n_p1, "thread", self.options["threads"])

    def _identify(self, obs: Observations) -> Estimate:
        layout = ObservationLayout.of(obs)
        if not hasattr(self, "_identifiers"):
            self._make_caches()
        G = self._identifiers(tuple(layout.t), layout.P1.size)
        n_p, n_t = layout.P1.size, layout.t.size

        def simulate(m: float, d: float, with_jacobian: bool):
            if not with_jacobian:
                y = self._states(layout.t, layout.P1, m, d)
                return y[0], y[1], None, None
            md = np.tile([[m], [d]], (1, n_p))
            xf, jac = self._run(G, layout.P1, layout.P1[None, :], md)
            y = xf.reshape(2, n_p, n_t)
            # rows of jac: vec(xf) column-major, (time j, state i); columns: (P1 k, parameter l)
            j4 = jac.reshape(n_t, 2, n_p, 2).transpose(1, 2, 0, 3)  # (state, P1, time, parameter)
            return y[0], y[1], j4[0], j4[1]

        return identify_least_squares(
            simulate, obs, layout, self.options["m_bounds"], self.options["d_bounds"],
            analytic_jacobian=True, rtol=self.options["rtol"],
        )
