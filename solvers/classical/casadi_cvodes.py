"""SUNDIALS CVODES (variable-order BDF/Adams) through CasADi, batched over P1 with `map`."""

from __future__ import annotations

from functools import lru_cache
from typing import ClassVar, Literal

import casadi as ca
import numpy as np

from solvers.base import LARGE_SYSTEMS, AbstractSolver, Estimate, SolveError, StepCount
from solvers.classical.common import (
    TOLERANCE_CONFIGS,
    TOLERANCE_MARKS,
    ObservationLayout,
    PointsByP1,
    ToleranceOptions,
    at_query_times,
    identify_least_squares,
    run_batch,
    search_boxes,
    which_p1,
)
from solvers.classical.fault_phases import switched_states
from solvers.options import PositiveInt
from systems.cases import Case, Observations
from systems.model import accelerations, coupling


class CVODESOptions(ToleranceOptions):
    threads: PositiveInt = 2
    method: Literal["bdf", "adams"] = "bdf"
    newton: Literal["direct", "functional"] = "direct"
    graph: Literal["auto", "sx", "mx"] = "auto"


# CVODES's options (CasADi's names) for each way of solving the implicit step: "direct", Newton
# iterations with the exact Jacobian factored by sparse LU (CasADi's default); "functional",
# fixed-point iterations, no Jacobian (for non-stiff problems, with Adams).
NEWTON_SCHEMES = {"direct": {}, "functional": {"nonlinear_solver_iteration": "functional"}}
# graph="auto": scalar expressions (SX) below this many machines, matrix expressions (MX) from it.
# CVODES's Newton iterations need the Jacobian, which CasADi derives when it builds an integrator:
# on an SX graph of the dense coupling (~4n^2 scalar nodes) that costs ~n^3, 32 s at 260 machines
# for each integrator (one per output grid), on the MX graph (four matrix-vector products) 0.1 s.
# Measured, 4 P1 x 101 times, BDF, rtol 1e-3 / 1e-10 (ms): SMIB 1 / 3 (SX) against 1 / 6 (MX);
# wscc9 3 / 11 against 2 / 16; kundur4 2 / 10 against 2 / 14; ieee39 6 / 38 against 6 / 28;
# case118 (54 machines) 57 against 29 at 1e-3; case1354pegase (260) 4.2 s against 3.5 s.
MX_FROM_MACHINES = 10


def swing_dae(case: Case, graph: Literal["sx", "mx"] = "sx") -> dict:
    """The n-machine swing equation of `case` as a CasADi ODE: x = [delta_1..n, omega_1..n] (2n,
    rad, rad/s), parameters p = [P_1..n, m_1..n, d_1..n] (3n, p.u.): every machine's mechanical
    power (`Case.powers` gives it: generator 1's P1, the others' p_m), inertia and damping, so one
    integrator serves every P1 and every trial (m, d) of identification. The coupling (E, G, B,
    infinite bus) is numeric in the expression: `systems.model.accelerations` on column vectors,
    as scalar expressions (`graph="sx"`) or matrix ones ("mx"; the same function)."""
    n = case.n
    k = coupling(case).map(ca.DM)  # (n, n) matrices and (n, 1) columns
    sym = {"sx": ca.SX, "mx": ca.MX}[graph].sym
    x, p = sym("x", 2 * n), sym("p", 3 * n)
    acc = accelerations(k, p[n:2 * n], p[2 * n:], x[:n], x[n:], p[:n],
                        sin=ca.sin, cos=ca.cos, matvec=ca.mtimes)
    return {"x": x, "p": p, "ode": ca.vertcat(x[n:], acc)}


class CasadiCVODES(PointsByP1, AbstractSolver):
    """CVODES on the n-machine swing equation, P, m and d parameters of one symbolic model (`swing_dae`).

    CVODES runs with its defaults: BDF, Newton iterations, and the exact Jacobian of the symbolic
    right-hand side (CasADi generates it) factored by CasADi's default sparse LU ("csparse"). The
    Jacobian [[0, I], [-dP_e/d delta / m, -diag(d / m)]] of a Kron-reduced network has n^2 + 2n
    nonzeros of 4n^2 (dP_e/d delta is dense), and CVODES refactors it rarely: measured on a random
    10-machine lossy case, one trajectory to 20 s with 201 outputs, csparse 2.7 ms at rtol 1e-3
    and 68 ms at 1e-10 (3573 steps, 221 factorisations), the dense "lapacklu" 2.8 and 68 ms. The
    linear algebra is not what a step costs there, so the default (sparse) solver stays. At scale
    it is: on 510 machines a 4 x 101 grid at rtol 1e-3 took 27 s with csparse and 7.1 s with
    lapacklu. The swing equation is not stiff, and the `adams` config (Adams with fixed-point
    iterations: no Jacobian at all) took 1.3 s there (0.32 s on 260 machines, against 3.5 s for
    BDF). Measured with the MX graph (`graph`), 2 threads, one probe each.

    `fit()` builds the model and the integrator of the standard grid (0..t_final s, 201 points);
    an integrator is built per distinct output grid and number of P1 values (CasADi fixes the output
    times at construction) and cached, so a warm query of a grid seen before pays no build.
    Trajectories are evaluated with `map(len(P1), "thread", threads)`.
    Options: rtol, atol (defaults 1e-3, 1e-6: MATLAB ode45's), threads (2), m_bounds, d_bounds
    (p.u., the search box of `identify`, default the case's per-machine boxes; `identify` uses
    CVODES forward sensitivities for d x / d(m_1..n, d_1..n)); method ("bdf", the default, or
    "adams"), newton ("direct": Newton iterations with the Jacobian; "functional": fixed-point
    iterations), graph ("sx", "mx" or "auto", the default: see `MX_FROM_MACHINES`).
    A fault case (P1 the clearing time t_c s): the fault-on phase once for every t_c of a query
    (output at the times before the largest t_c and at every t_c), then every post-fault phase
    from its state at t_c, mapped over the t_c at the union of their times since t_c
    (`solvers.classical.fault_phases`); each phase's integrator is cached per output grid as above.
    """

    name: ClassVar[str] = "casadi-cvodes"
    SCHEMA = CVODESOptions
    # adams: the non-stiff method at ode45's tolerances, for large systems (see above)
    CONFIGS: ClassVar[dict[str, dict]] = {**TOLERANCE_CONFIGS, "adams": {"method": "adams", "newton": "functional"}}
    CONFIG_MARKS: ClassVar[dict[str, frozenset[str]]] = {**TOLERANCE_MARKS, "adams": frozenset({LARGE_SYSTEMS})}
    has_tolerance = True
    takes_threads = True
    handles_faults = True
    counts_steps = True
    QUERY_OPTIONS = frozenset({"threads"})

    def _make_caches(self) -> None:
        self._integrators = lru_cache(maxsize=32)(self._build)
        self._identifiers = lru_cache(maxsize=4)(self._build_identifier)

    def _fit(self) -> None:
        self._make_caches()
        if self.case.fault is None:
            t = np.linspace(0.0, self.case.t_final, 201)
            self._integrators(tuple(t), 100)

    def _integrator(self, times: tuple[float, ...], case: Case | None = None):
        """CVODES on `case` (default the adapter's; a fault case's phase) with output at `times` (s)."""
        o = self.options
        opts = {"reltol": o["rtol"], "abstol": o["atol"], "max_num_steps": 100000,
                "linear_multistep_method": o["method"], **NEWTON_SCHEMES[o["newton"]]}
        return ca.integrator("cvodes", "cvodes", swing_dae(case or self.case, self.graph), 0.0, list(times), opts)

    @property
    def graph(self) -> Literal["sx", "mx"]:
        """The expression graph of the model: the `graph` option, or by the case's size for "auto"."""
        graph = self.options["graph"]
        if graph == "auto":
            return "mx" if self.case.n >= MX_FROM_MACHINES else "sx"
        return graph

    def _build(self, times: tuple[float, ...], n_p1: int, case: Case | None = None):
        return self._integrator(times, case).map(n_p1, "thread", self.options["threads"])

    def _run(self, fn, P1: np.ndarray, *args) -> list[np.ndarray]:
        try:
            return [np.asarray(out) for out in fn(*args)]
        except RuntimeError as exc:
            reason = str(exc).strip().splitlines()[-1]
            raise SolveError(f"{self.name}: CVODES failed at {which_p1(P1, self.case.scenario.symbol)}: "
                             f"{reason}") from exc

    def _x0(self, n_p: int) -> np.ndarray:
        """Initial states (2n, n_p), one column per trajectory."""
        return np.tile(np.array(self.case.delta0 + self.case.omega0)[:, None], (1, n_p))

    def _states(self, times: np.ndarray, P1: np.ndarray, m: np.ndarray, d: np.ndarray) -> np.ndarray:
        """States (len(P1), len(times), 2n) = [delta_1..n, omega_1..n] at sorted unique times (s),
        for inertias m and dampings d (n,) p.u."""
        n_p, n = P1.size, self.case.n
        fn = self._integrators(tuple(times), n_p)
        # (3n, n_p): one column [P; m; d] per trajectory
        params = np.vstack([self.case.powers(P1).T, np.repeat(np.concatenate([m, d])[:, None], n_p, axis=1)])
        (xf,) = self._run(lambda x0, p: [fn(x0=x0, p=p)["xf"]], P1, self._x0(n_p), params)
        # map concatenates the trajectories' (2n, n_t) outputs horizontally: column k * n_t + j
        return xf.reshape(2 * n, n_p, times.size).transpose(1, 2, 0)

    def _step_count(self, p1: float) -> StepCount:
        """CVODES's steps (`nsteps`) and right-hand side evaluations (`nfevals`; its Jacobian is
        CasADi's algorithmic derivative, not differences) of one trajectory to t_final, from the
        integrator's statistics."""
        case = self.case
        fn = self._integrator((case.t_final,))
        params = np.concatenate([case.powers(np.array([p1]))[0], case.m, case.d])
        self._run(lambda x0, p: [fn(x0=x0, p=p)["xf"]], np.array([p1]), self._x0(1), params)
        stats = fn.stats()
        return StepCount(int(stats["nsteps"]), int(stats["nfevals"]))

    def _phase(self, phase: Case, y0: np.ndarray, times: np.ndarray, T_c: np.ndarray) -> np.ndarray:
        """`solvers.classical.fault_phases.PhaseIntegrator`: one phase of a fault case from y0 (n_b, 2n)."""
        n_b, n = y0.shape[0], phase.n
        fn = self._integrators(tuple(times), n_b, phase)
        params = np.repeat(np.concatenate([phase.p_m, phase.m, phase.d])[:, None], n_b, axis=1)
        (xf,) = self._run(lambda x0, p: [fn(x0=x0, p=p)["xf"]], T_c, y0.T, params)
        return xf.reshape(2 * n, n_b, times.size).transpose(1, 2, 0)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        case = self.case
        if case.fault is not None:
            y = switched_states(self._phase, case, t, P1, stacked=True)
        else:
            m, d = np.asarray(case.m), np.asarray(case.d)
            y = at_query_times(lambda times: run_batch(lambda p1: self._states(times, p1, m, d), P1), t)
        return y[..., :case.n], y[..., case.n:]

    def _build_identifier(self, times: tuple[float, ...], n_p1: int):
        """(P (n, n_p), md (2n, n_p)) -> states (2n, n_p * n_t) and their forward sensitivities
        d vec(states) / d(m, d), (2n * n_t, n_p * 2n), one trajectory per column block."""
        n = self.case.n
        F = self._integrator(times)
        P, md = ca.MX.sym("P", n), ca.MX.sym("md", 2 * n)
        xf = F(x0=ca.DM(self.case.delta0 + self.case.omega0), p=ca.vertcat(P, md))["xf"]
        G = ca.Function("G", [P, md], [xf, ca.jacobian(xf, md)])
        return G.map(n_p1, "thread", self.options["threads"])

    def _identify(self, obs: Observations) -> Estimate:
        layout = ObservationLayout.of(obs)
        if not hasattr(self, "_identifiers"):
            self._make_caches()
        G = self._identifiers(tuple(layout.t), layout.P1.size)
        n_p, n_t, n = layout.P1.size, layout.t.size, self.case.n
        powers = self.case.powers(layout.P1).T  # (n, n_p)

        def simulate(m: np.ndarray, d: np.ndarray, with_jacobian: bool):
            if not with_jacobian:
                y = self._states(layout.t, layout.P1, m, d)
                return y[..., :n], y[..., n:], None, None
            md = np.repeat(np.concatenate([m, d])[:, None], n_p, axis=1)
            xf, jac = self._run(G, layout.P1, powers, md)
            y = xf.reshape(2 * n, n_p, n_t).transpose(1, 2, 0)
            # rows of jac: vec(xf) column-major, (time j, state i); columns: (P1 k, parameter l)
            j4 = jac.reshape(n_t, 2 * n, n_p, 2 * n).transpose(2, 0, 1, 3)  # (P1, time, state, parameter)
            return y[..., :n], y[..., n:], j4[:, :, :n], j4[:, :, n:]

        return identify_least_squares(
            simulate, obs, layout, *search_boxes(self.case, self.options),
            analytic_jacobian=True, rtol=self.options["rtol"],
        )
